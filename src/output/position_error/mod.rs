//! Screen-space position error between two frames of the same shot, both ways. Receives two
//! [`RenderedFrame`]s (their true-position `P` and object-id layers, their flags) and returns, for
//! every pixel of A that sees an object which B sees at the same pixel too, how far in pixels the
//! nearest place where B sees the same world point is — and the same for every such pixel of B
//! against A — as mean, 99th percentile, maximum and share over 1 px; over all those pixels,
//! outside flagged pixels and outside the fold band of A; plus the share of pixels whose seen
//! object differs.
//!
//! **Where B sees a point**: B's map pixel -> `P` of one object as a piecewise-linear surface over
//! the pixel grid, indexed by a bounding-volume hierarchy over all of it ([`map`]): every place
//! in the whole frame where that surface passes through the point (within a quarter of the local
//! pixel footprint, [`map::CONTAINMENT_TOLERANCE`]) is an image; the error is the distance to the
//! nearest image. There is no search window, so an error of any size is measured. Where B does
//! not see the point at all, the place where it sees the object's nearest point counts (and the
//! pixel is counted as `unseen`).
//!
//! **Both ways**: with A the reference and B a method, A -> B (per pixel of the reference) makes an
//! image the method failed to draw cost the distance to the image it did draw; B -> A (per pixel of
//! the method) makes an image drawn where the truth has none cost the distance to the truth.
//! `both` pools the two.
//!
//! **Fold band** ([`fold`]): pixels within [`fold::FOLD_BAND_PX`] of a fold of A's map (a caustic
//! line in screen space), where one sample per pixel cannot place the images. A measured pair
//! (a pixel and the place matched to it) is outside the fold band, or outside flagged pixels, when
//! neither of its two ends is in the band, or flagged.

pub mod fold;
pub mod map;

use glam::Vec3;
use rayon::prelude::*;

use super::compare::{percentile_of_sorted, SizeMismatch};
use crate::draw::RenderedFrame;
pub use fold::{FoldBand, FOLD_BAND_PX};
pub use map::{Place, PositionMap};

/// Summary of the per-pixel position error over a set of pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PositionError {
    pub mean_px: f64,
    pub p99_px: f64,
    pub max_px: f64,
    /// Share of the counted pixels whose error exceeds 1 px.
    pub over_1px_fraction: f64,
    /// Pixels measured.
    pub counted: usize,
    /// Of them, pixels whose point the other frame does not see at all (measured to where it sees
    /// the nearest point of the object).
    pub unseen: usize,
}

/// One direction's (or both directions') errors over the three pixel sets.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ErrorSubsets {
    /// Every pixel where both frames see the same object.
    pub all: PositionError,
    /// Leaving out pairs with an end on a flagged pixel (of the frame the flags come from).
    pub outside_flagged: PositionError,
    /// Leaving out pairs with an end in A's fold band.
    pub outside_fold_band: PositionError,
}

/// Which of the two frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub enum Side {
    A,
    #[default]
    B,
}

impl Side {
    pub fn name(self) -> &'static str {
        match self {
            Side::A => "A",
            Side::B => "B",
        }
    }
}

/// What [`compare_positions`] needs besides the frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompareOptions {
    /// The frame whose flags define "flagged" (a method's; the reference has none).
    pub flags_from: Side,
    /// The eyes of A's and B's cameras, to tell the pixels seen through the water
    /// ([`water_pixels`]); without them the water shares are not computed.
    pub eyes: Option<(Vec3, Vec3)>,
}

/// Everything [`compare_positions`] measures.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PositionComparison {
    /// Per pixel of A: where B sees its point.
    pub a_to_b: ErrorSubsets,
    /// Per pixel of B: where A sees its point.
    pub b_to_a: ErrorSubsets,
    /// Both directions' pixels together.
    pub both: ErrorSubsets,
    /// Pixels whose seen object (or nothing) differs between A and B, over all pixels.
    pub object_mismatch_fraction: f64,
    pub object_mismatch_pixels: usize,
    pub pixels: usize,
    pub flags_from: Side,
    /// Pixels flagged in the frame the flags come from.
    pub flagged_pixels: usize,
    /// Fold edges of A's map and the pixels of its fold band.
    pub fold_edges: usize,
    pub fold_band_pixels: usize,
    /// Pixels seen through the water in A, when the eyes are known.
    pub water_pixels: Option<usize>,
    /// A's fold band over A's water pixels.
    pub fold_band_water_fraction: Option<f64>,
    /// Flagged pixels over the water pixels of the frame the flags come from.
    pub flagged_water_fraction: Option<f64>,
}

/// Why two frames cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum PositionErrorInput {
    #[error(transparent)]
    Size(#[from] SizeMismatch),
    /// A frame read from an EXR written before the object layer existed, or a buffer of the wrong
    /// length.
    #[error("{which} has no usable object-id layer ({found} values for {pixels} pixels): render it again with this snell, which writes the `object` channel")]
    ObjectLayer {
        which: &'static str,
        found: usize,
        pixels: usize,
    },
}

/// The pixels whose first surface is the water: the frame's water matte (the EXR's
/// `WaterMatte.X`; for frames read from the first layout, derived from its `Z` and `P` by
/// [`crate::output::exr::read_frame_exr`]). A frame without one has no water pixels. `_eye` is
/// the frame's camera position, which the matte no longer needs.
pub fn water_pixels(frame: &RenderedFrame, _eye: Vec3) -> Vec<bool> {
    if frame.water_matte.is_empty() {
        return vec![false; frame.position.len()];
    }
    frame.water_matte.par_iter().map(|&m| m > 0.5).collect()
}

fn check_inputs(a: &RenderedFrame, b: &RenderedFrame) -> Result<(), PositionErrorInput> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(SizeMismatch {
            reference_width: a.width,
            reference_height: a.height,
            test_width: b.width,
            test_height: b.height,
        }
        .into());
    }
    let pixels = a.width as usize * a.height as usize;
    for (which, frame) in [("A", a), ("B", b)] {
        if frame.object.len() != pixels || frame.position.len() != pixels {
            return Err(PositionErrorInput::ObjectLayer {
                which,
                found: frame.object.len(),
                pixels,
            });
        }
    }
    Ok(())
}

/// One measured pixel: its error and whether its pair touches a flagged pixel or the fold band.
#[derive(Clone, Copy, Debug)]
struct Measured {
    error_px: f32,
    flagged: bool,
    in_fold_band: bool,
    seen: bool,
}

/// Screen masks a pair is checked against.
struct Masks<'m> {
    width: usize,
    height: usize,
    flagged: &'m [bool],
    fold_band: &'m [bool],
}

impl Masks<'_> {
    fn index_near(&self, screen: [f64; 2]) -> usize {
        let x = (screen[0].round().max(0.0) as usize).min(self.width - 1);
        let y = (screen[1].round().max(0.0) as usize).min(self.height - 1);
        y * self.width + x
    }
}

/// Per pixel of `from` that sees an object `to` sees at the same pixel: where `to` sees its point.
fn measure_direction(
    from: &RenderedFrame,
    to: &RenderedFrame,
    to_map: &PositionMap<'_>,
    masks: &Masks<'_>,
) -> Vec<Measured> {
    let width = from.width as usize;
    (0..from.height as usize)
        .into_par_iter()
        .flat_map_iter(|y| {
            let mut row = Vec::new();
            for x in 0..width {
                let index = y * width + x;
                let object = from.object[index];
                let target = from.position[index];
                if object == crate::draw::NO_OBJECT
                    || to.object[index] != object
                    || !target.iter().all(|c| c.is_finite())
                {
                    continue;
                }
                let here = [x as f64, y as f64];
                let place = if to.position[index] == target {
                    // The same point at the same pixel: nothing nearer exists.
                    Some(Place {
                        screen: here,
                        seen: true,
                    })
                } else {
                    to_map.place_of(target, object, here)
                };
                let Some(place) = place else { continue };
                let error = (place.screen[0] - here[0]).hypot(place.screen[1] - here[1]);
                let there = masks.index_near(place.screen);
                row.push(Measured {
                    error_px: error as f32,
                    flagged: masks.flagged[index] || masks.flagged[there],
                    in_fold_band: masks.fold_band[index] || masks.fold_band[there],
                    seen: place.seen,
                });
            }
            row
        })
        .collect()
}

fn summarise<'m>(measured: impl Iterator<Item = &'m Measured>) -> PositionError {
    let mut errors: Vec<f32> = Vec::new();
    let mut unseen = 0;
    for m in measured {
        errors.push(m.error_px);
        unseen += usize::from(!m.seen);
    }
    let counted = errors.len();
    if counted == 0 {
        return PositionError::default();
    }
    // Sorted first so the sum's order (and so its last bits) does not depend on thread timing.
    errors.sort_by(f32::total_cmp);
    let mean_px = errors.iter().map(|&e| e as f64).sum::<f64>() / counted as f64;
    let over = errors.len() - errors.partition_point(|&e| e <= 1.0);
    PositionError {
        mean_px,
        p99_px: percentile_of_sorted(&errors, 0.99) as f64,
        max_px: *errors.last().expect("not empty") as f64,
        over_1px_fraction: over as f64 / counted as f64,
        counted,
        unseen,
    }
}

fn subsets(measured: &[&[Measured]]) -> ErrorSubsets {
    let all = || measured.iter().flat_map(|m| m.iter());
    ErrorSubsets {
        all: summarise(all()),
        outside_flagged: summarise(all().filter(|m| !m.flagged)),
        outside_fold_band: summarise(all().filter(|m| !m.in_fold_band)),
    }
}

/// Measures A and B against each other (see the module documentation).
pub fn compare_positions(
    a: &RenderedFrame,
    b: &RenderedFrame,
    options: &CompareOptions,
) -> Result<PositionComparison, PositionErrorInput> {
    check_inputs(a, b)?;
    let (width, height) = (a.width as usize, a.height as usize);
    let pixels = width * height;
    let object_mismatch_pixels = a
        .object
        .iter()
        .zip(&b.object)
        .filter(|(x, y)| x != y)
        .count();
    let flag_frame = match options.flags_from {
        Side::A => a,
        Side::B => b,
    };
    let flagged: Vec<bool> = (0..pixels)
        .map(|i| flag_frame.flags.get(i).is_some_and(|&f| f != 0))
        .collect();
    let (map_a, map_b) = rayon::join(|| PositionMap::build(a), || PositionMap::build(b));
    let band = fold::fold_band(&map_a, a.width, a.height);
    let masks = Masks {
        width: width.max(1),
        height: height.max(1),
        flagged: &flagged,
        fold_band: &band.mask,
    };
    let (a_to_b, b_to_a) = if pixels == 0 {
        (Vec::new(), Vec::new())
    } else {
        rayon::join(
            || measure_direction(a, b, &map_b, &masks),
            || measure_direction(b, a, &map_a, &masks),
        )
    };
    let (water_pixels, fold_band_water_fraction, flagged_water_fraction) = match options.eyes {
        Some((eye_a, eye_b)) => {
            let water_a = water_pixels(a, eye_a);
            let water_flags = match options.flags_from {
                Side::A => water_a.clone(),
                Side::B => water_pixels(b, eye_b),
            };
            let share = |mask: &[bool], water: &[bool]| {
                let total = water.iter().filter(|&&w| w).count();
                let inside = mask.iter().zip(water).filter(|(&m, &w)| m && w).count();
                if total == 0 {
                    0.0
                } else {
                    inside as f64 / total as f64
                }
            };
            (
                Some(water_a.iter().filter(|&&w| w).count()),
                Some(share(&band.mask, &water_a)),
                Some(share(&flagged, &water_flags)),
            )
        }
        None => (None, None, None),
    };
    Ok(PositionComparison {
        a_to_b: subsets(&[&a_to_b]),
        b_to_a: subsets(&[&b_to_a]),
        both: subsets(&[&a_to_b, &b_to_a]),
        object_mismatch_fraction: if pixels == 0 {
            0.0
        } else {
            object_mismatch_pixels as f64 / pixels as f64
        },
        object_mismatch_pixels,
        pixels,
        flags_from: options.flags_from,
        flagged_pixels: flagged.iter().filter(|&&f| f).count(),
        fold_edges: band.fold_edges,
        fold_band_pixels: band.pixels(),
        water_pixels,
        fold_band_water_fraction,
        flagged_water_fraction,
    })
}

/// Only the error of B against A, per pixel of A, over every pixel where both see the same object
/// (the figure a quick check wants; [`compare_positions`] gives everything).
pub fn position_error(
    a: &RenderedFrame,
    b: &RenderedFrame,
) -> Result<PositionError, PositionErrorInput> {
    Ok(compare_positions(a, b, &CompareOptions::default())?
        .a_to_b
        .all)
}

#[cfg(test)]
mod tests;
