//! Screen-space position error between two frames of the same shot: receives two
//! [`RenderedFrame`]s (their true-position `P` and object-id layers) and returns, for the pixels of
//! A that see an object, how far in pixels the place in B that sees the same world point is —
//! as mean, 99th percentile and maximum — and the share of pixels whose seen object differs.
//!
//! Per pixel of A: among B's pixels in a square window around it that see the SAME object, the one
//! whose `P` is nearest A's `P`; then sub-pixel refinement on B's local map pixel -> `P`: its
//! Jacobian is fitted by least squares from the neighbours (3x3) that see the same object, pinned
//! at the pixel's own `P`, and the offset where the linear map equals A's `P` (least squares in the
//! three coordinates) is the sub-pixel position; when that offset leaves the pixel the fit moves to
//! the neighbour and repeats (Gauss-Newton on the piecewise-linear field; at most
//! [`MAX_REFINEMENT_STEPS`] moves, so a match may be found a few pixels beyond the window). A smooth field shifted
//! by 0.3 px measures 0.3 px to well under 0.01 px (tested), so errors far below the 0.1 px the
//! method aims at are resolved.

use rayon::prelude::*;

use super::compare::{percentile_of_sorted, SizeMismatch};
use crate::draw::RenderedFrame;

/// Window half-size, in pixels, `snell compare` searches unless told otherwise: the images of a
/// linear method are expected within a pixel or two of the reference's; 8 px leaves room for
/// popping vertices and coarse membranes without making the search slow (17 x 17 candidates).
pub const DEFAULT_WINDOW_PX: u32 = 8;

/// Refinement steps from the nearest pixel to a neighbour and back at most; the field is
/// piecewise linear per triangle, so one or two steps settle.
const MAX_REFINEMENT_STEPS: usize = 4;

/// A neighbour whose P is further from the pixel's than this many times the median neighbour's
/// (per pixel of distance) is across a jump (the object hiding part of itself) and left out of
/// the fit. A smooth map in perspective varies its step far less between neighbours.
const JUMP_FACTOR: f64 = 4.0;

/// Summary of the per-pixel position error.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PositionError {
    pub mean_px: f64,
    pub p99_px: f64,
    pub max_px: f64,
    /// Pixels measured: A and B see the same object there (and, with `skip_flagged`, A's flags
    /// are 0).
    pub counted: usize,
    /// Pixels whose seen object (or nothing) differs between A and B, over all pixels.
    pub object_mismatch_fraction: f64,
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

/// Both summaries `snell compare` prints: every pixel where both see the same object, and only
/// those of them outside A's flagged pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PositionComparison {
    pub all: PositionError,
    pub outside_flagged: PositionError,
}

/// The position error of `b` against `a` (see the module documentation). `window_px` is the
/// half-size of the search window; `skip_flagged` leaves out the pixels whose flags are set in A.
pub fn position_error(
    a: &RenderedFrame,
    b: &RenderedFrame,
    window_px: u32,
    skip_flagged: bool,
) -> Result<PositionError, PositionErrorInput> {
    let comparison = compare_positions(a, b, window_px)?;
    Ok(if skip_flagged {
        comparison.outside_flagged
    } else {
        comparison.all
    })
}

/// [`position_error`] with and without A's flagged pixels, from one search.
pub fn compare_positions(
    a: &RenderedFrame,
    b: &RenderedFrame,
    window_px: u32,
) -> Result<PositionComparison, PositionErrorInput> {
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
    let mismatched = a
        .object
        .iter()
        .zip(&b.object)
        .filter(|(x, y)| x != y)
        .count();
    let object_mismatch_fraction = if pixels == 0 {
        0.0
    } else {
        mismatched as f64 / pixels as f64
    };
    let errors = pixel_errors(a, b, window_px);
    let flags_clear = |index: usize| a.flags.get(index).is_none_or(|&f| f == 0);
    let all: Vec<f32> = errors.iter().flatten().map(|&(_, e)| e).collect();
    let outside: Vec<f32> = errors
        .iter()
        .flatten()
        .filter(|&&(index, _)| flags_clear(index))
        .map(|&(_, e)| e)
        .collect();
    Ok(PositionComparison {
        all: summarise(all, object_mismatch_fraction),
        outside_flagged: summarise(outside, object_mismatch_fraction),
    })
}

fn summarise(mut errors: Vec<f32>, object_mismatch_fraction: f64) -> PositionError {
    let counted = errors.len();
    if counted == 0 {
        return PositionError {
            mean_px: 0.0,
            p99_px: 0.0,
            max_px: 0.0,
            counted,
            object_mismatch_fraction,
        };
    }
    // Sorted first so the sum's order (and so its last bits) does not depend on thread timing.
    errors.sort_by(f32::total_cmp);
    let mean_px = errors.iter().map(|&e| e as f64).sum::<f64>() / counted as f64;
    PositionError {
        mean_px,
        p99_px: percentile_of_sorted(&errors, 0.99) as f64,
        max_px: *errors.last().expect("not empty") as f64,
        counted,
        object_mismatch_fraction,
    }
}

/// Per row, the (pixel index, error in px) of every pixel where A and B see the same object.
fn pixel_errors(a: &RenderedFrame, b: &RenderedFrame, window_px: u32) -> Vec<Vec<(usize, f32)>> {
    let (width, height) = (a.width as usize, a.height as usize);
    (0..height)
        .into_par_iter()
        .map(|y| {
            let mut row = Vec::new();
            for x in 0..width {
                let index = y * width + x;
                let object = a.object[index];
                if object == crate::draw::NO_OBJECT || b.object[index] != object {
                    continue;
                }
                let target = a.position[index];
                if !is_finite(target) {
                    continue;
                }
                let field = PositionField { frame: b, object };
                if let Some(place) = field.place_of(target, x, y, window_px as usize) {
                    let error =
                        ((place[0] - x as f64).powi(2) + (place[1] - y as f64).powi(2)).sqrt();
                    row.push((index, error as f32));
                }
            }
            row
        })
        .collect()
}

fn is_finite(p: [f32; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

fn squared_distance(p: [f32; 3], q: [f32; 3]) -> f64 {
    (0..3).map(|i| (p[i] as f64 - q[i] as f64).powi(2)).sum()
}

/// B's map pixel -> true position, restricted to the pixels that see one object.
struct PositionField<'a> {
    frame: &'a RenderedFrame,
    object: u32,
}

impl PositionField<'_> {
    fn at(&self, x: isize, y: isize) -> Option<[f32; 3]> {
        let (width, height) = (self.frame.width as isize, self.frame.height as isize);
        if x < 0 || y < 0 || x >= width || y >= height {
            return None;
        }
        let index = (y * width + x) as usize;
        let p = self.frame.position[index];
        (self.frame.object[index] == self.object && is_finite(p)).then_some(p)
    }

    /// Sub-pixel coordinates (in the pixel grid, pixel (x, y) at (x, y)) where B sees `target`,
    /// searched around (x, y); `None` when no pixel of the object is in the window.
    fn place_of(&self, target: [f32; 3], x: usize, y: usize, window: usize) -> Option<[f64; 2]> {
        let (cx, cy) = (x as isize, y as isize);
        let w = window as isize;
        if self.at(cx, cy) == Some(target) {
            // The same point at the same pixel: nothing nearer exists (frames compared with
            // themselves, or regions that did not change).
            return Some([x as f64, y as f64]);
        }
        let mut best: Option<(f64, isize, isize)> = None;
        for py in cy - w..=cy + w {
            for px in cx - w..=cx + w {
                if let Some(p) = self.at(px, py) {
                    let d = squared_distance(p, target);
                    // Ties go to the candidate nearest the window's centre, then scan order.
                    let closer = match best {
                        None => true,
                        Some((bd, bx, by)) => {
                            d < bd
                                || (d == bd
                                    && (px - cx).pow(2) + (py - cy).pow(2)
                                        < (bx - cx).pow(2) + (by - cy).pow(2))
                        }
                    };
                    if closer {
                        best = Some((d, px, py));
                    }
                }
            }
        }
        let (distance, mut px, mut py) = best?;
        if distance == 0.0 {
            return Some([px as f64, py as f64]);
        }
        let mut place = (px, py, [0.0, 0.0]);
        let mut moves = 0;
        while let Some(step) = self.linear_offset(target, px, py) {
            place = (px, py, step);
            // Outside this pixel's cell: refit around the neighbour it points to.
            let (sx, sy) = (
                (step[0].round() as isize).clamp(-1, 1),
                (step[1].round() as isize).clamp(-1, 1),
            );
            if (sx, sy) == (0, 0)
                || moves == MAX_REFINEMENT_STEPS
                || self.at(px + sx, py + sy).is_none()
            {
                break;
            }
            px += sx;
            py += sy;
            moves += 1;
        }
        // Never trust an extrapolation beyond the neighbouring pixel.
        let (px, py, offset) = place;
        let offset = offset.map(|o| o.clamp(-1.0, 1.0));
        Some([px as f64 + offset[0], py as f64 + offset[1]])
    }

    /// The offset d from pixel (x, y) where `P(x, y) + J d` is nearest `target`, with the Jacobian
    /// J fitted by least squares on the 3x3 neighbours of the same object (pinned at the pixel's
    /// own P). `None` when the neighbours do not span both directions.
    fn linear_offset(&self, target: [f32; 3], x: isize, y: isize) -> Option<[f64; 2]> {
        let centre = self.at(x, y)?;
        let mut neighbours: Vec<([f64; 2], [f64; 3])> = Vec::with_capacity(8);
        for dy in -1..=1isize {
            for dx in -1..=1isize {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                if let Some(p) = self.at(x + dx, y + dy) {
                    let dp = std::array::from_fn(|k| p[k] as f64 - centre[k] as f64);
                    neighbours.push(([dx as f64, dy as f64], dp));
                }
            }
        }
        // An object can hide part of itself (a deck's lip over its wall): neighbours across such a
        // jump in P are not on the local map. Keep those within a few times the median step.
        let mut steps: Vec<f64> = neighbours
            .iter()
            .map(|(d, dp)| length(dp) / length(d))
            .collect();
        steps.sort_by(f64::total_cmp);
        let median_step = steps.get(steps.len() / 2).copied().unwrap_or(0.0);
        let jump = JUMP_FACTOR * median_step;
        // Normal equations of min sum |(P_n - P_c) - J d_n|^2 over the neighbours: J = S_pd S_dd^-1.
        let mut s_dd = [[0.0f64; 2]; 2];
        let mut s_pd = [[0.0f64; 2]; 3];
        for (d, dp) in neighbours
            .iter()
            .filter(|(d, dp)| length(dp) <= jump * length(d))
        {
            for i in 0..2 {
                for j in 0..2 {
                    s_dd[i][j] += d[i] * d[j];
                }
            }
            for (k, row) in s_pd.iter_mut().enumerate() {
                row[0] += dp[k] * d[0];
                row[1] += dp[k] * d[1];
            }
        }
        let inverse_dd = inverse_2x2(s_dd)?;
        let jacobian: [[f64; 2]; 3] = s_pd.map(|row| {
            [
                row[0] * inverse_dd[0][0] + row[1] * inverse_dd[1][0],
                row[0] * inverse_dd[0][1] + row[1] * inverse_dd[1][1],
            ]
        });
        // min |J d - r|^2: d = (J^T J)^-1 J^T r.
        let r: [f64; 3] = std::array::from_fn(|k| target[k] as f64 - centre[k] as f64);
        let mut jtj = [[0.0f64; 2]; 2];
        let mut jtr = [0.0f64; 2];
        for k in 0..3 {
            for i in 0..2 {
                jtr[i] += jacobian[k][i] * r[k];
                for j in 0..2 {
                    jtj[i][j] += jacobian[k][i] * jacobian[k][j];
                }
            }
        }
        let inverse_jtj = inverse_2x2(jtj)?;
        Some([
            inverse_jtj[0][0] * jtr[0] + inverse_jtj[0][1] * jtr[1],
            inverse_jtj[1][0] * jtr[0] + inverse_jtj[1][1] * jtr[1],
        ])
    }
}

fn length<const N: usize>(v: &[f64; N]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

/// The inverse of a 2x2 matrix, or `None` when it is (nearly) singular relative to its size.
// `!(det.abs() > ..)` also returns `None` for a NaN determinant; `<=` would invert it.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn inverse_2x2(m: [[f64; 2]; 2]) -> Option<[[f64; 2]; 2]> {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let scale = m[0][0].abs().max(m[1][1].abs()).max(m[0][1].abs());
    if !(det.abs() > 1e-12 * scale * scale) {
        return None;
    }
    Some([
        [m[1][1] / det, -m[0][1] / det],
        [-m[1][0] / det, m[0][0] / det],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    const OBJECT: u32 = 3;

    /// A smooth, curved map pixel -> P (metres): what a pool floor seen in perspective looks like.
    fn smooth_position(x: f64, y: f64) -> [f32; 3] {
        [
            (0.01 * x + 2e-5 * x * x) as f32,
            (-0.5 - 0.004 * y + 1e-5 * x * y) as f32,
            (1.0 + 0.012 * y + 3e-5 * y * y) as f32,
        ]
    }

    /// A frame whose pixel (x, y) sees `position(x, y)` on object `OBJECT`.
    fn frame_of(width: u32, height: u32, position: impl Fn(f64, f64) -> [f32; 3]) -> RenderedFrame {
        let pixels = (width * height) as usize;
        let mut frame = RenderedFrame {
            width,
            height,
            beauty_rgba: vec![[0.5, 0.5, 0.5, 1.0]; pixels],
            distance_m: vec![3.0; pixels],
            position: Vec::with_capacity(pixels),
            flags: vec![0; pixels],
            object: vec![OBJECT; pixels],
        };
        for y in 0..height {
            for x in 0..width {
                frame.position.push(position(x as f64, y as f64));
            }
        }
        frame
    }

    #[test]
    fn a_frame_against_itself_is_exactly_zero() {
        let frame = frame_of(48, 32, smooth_position);
        let comparison = compare_positions(&frame, &frame, DEFAULT_WINDOW_PX).unwrap();
        for summary in [comparison.all, comparison.outside_flagged] {
            assert_eq!(summary.mean_px, 0.0);
            assert_eq!(summary.p99_px, 0.0);
            assert_eq!(summary.max_px, 0.0);
            assert_eq!(summary.object_mismatch_fraction, 0.0);
            assert_eq!(summary.counted, 48 * 32);
        }
    }

    /// B sees at (x, y) what A sees at (x + shift, y): every pixel of A is found `shift` px away.
    #[test]
    fn a_known_sub_pixel_shift_is_measured() {
        for (shift_x, shift_y) in [(0.3, 0.0), (0.0, -0.3), (0.21, 0.17), (1.6, 0.0)] {
            let a = frame_of(64, 48, smooth_position);
            let b = frame_of(64, 48, |x, y| smooth_position(x + shift_x, y + shift_y));
            let expected = f64::hypot(shift_x, shift_y);
            // Only pixels whose match lies inside B's image (not at its border) are exact.
            let error = position_error(&a, &b, DEFAULT_WINDOW_PX, false).unwrap();
            assert_eq!(error.counted, 64 * 48);
            assert!(
                (error.p99_px - expected).abs() < 0.01,
                "shift ({shift_x}, {shift_y}): p99 {} vs {expected}",
                error.p99_px
            );
            let interior: Vec<f64> = pixel_errors(&a, &b, DEFAULT_WINDOW_PX)
                .into_iter()
                .flatten()
                .filter(|&(index, _)| {
                    let (x, y) = ((index % 64) as f64, (index / 64) as f64);
                    let (bx, by) = (x - shift_x, y - shift_y);
                    bx >= 1.0 && by >= 1.0 && bx <= 62.0 && by <= 46.0
                })
                .map(|(_, e)| e as f64)
                .collect();
            let worst = interior
                .iter()
                .map(|e| (e - expected).abs())
                .fold(0.0, f64::max);
            assert!(
                worst < 0.01,
                "shift ({shift_x}, {shift_y}): worst interior error off by {worst}"
            );
        }
    }

    /// Pixels seeing another object in B are not measured but counted as mismatched; flagged
    /// pixels of A are left out of the second summary only.
    #[test]
    fn object_mismatch_and_flags_are_counted() {
        let a = frame_of(20, 10, smooth_position);
        let mut b = a.clone();
        for index in 0..20 {
            b.object[index] = OBJECT + 1; // the top row sees another object
        }
        b.object[25] = crate::draw::NO_OBJECT;
        let mut a_flagged = a.clone();
        for index in 40..50 {
            a_flagged.flags[index] = crate::draw::flag_bits::CONVERGENCE;
        }
        let comparison = compare_positions(&a_flagged, &b, 4).unwrap();
        assert_eq!(comparison.all.object_mismatch_fraction, 21.0 / 200.0);
        assert_eq!(comparison.all.counted, 200 - 21);
        assert_eq!(comparison.outside_flagged.counted, 200 - 21 - 10);
        assert_eq!(comparison.all.max_px, 0.0);
    }

    /// A frame with nothing seen and differently sized or layer-less frames.
    #[test]
    fn bad_inputs_are_errors_and_empty_frames_count_nothing() {
        let a = frame_of(8, 6, smooth_position);
        let b = frame_of(8, 5, smooth_position);
        assert!(matches!(
            compare_positions(&a, &b, 2),
            Err(PositionErrorInput::Size(_))
        ));
        let mut old = a.clone();
        old.object.clear();
        let message = compare_positions(&a, &old, 2).unwrap_err().to_string();
        assert!(
            message.starts_with("B has no usable object-id layer"),
            "{message}"
        );
        let mut sky = a.clone();
        sky.object.fill(crate::draw::NO_OBJECT);
        let error = position_error(&sky, &sky, 2, true).unwrap();
        assert_eq!(error.counted, 0);
        assert_eq!(error.mean_px, 0.0);
    }

    /// A pixel far from its match is found anywhere in the window; beyond it only as far as the
    /// refinement walks (MAX_REFINEMENT_STEPS pixels, then at most one more).
    #[test]
    fn the_window_bounds_the_search() {
        let a = frame_of(40, 20, smooth_position);
        let b = frame_of(40, 20, |x, y| smooth_position(x + 8.0, y));
        let near = position_error(&a, &b, 8, false).unwrap();
        assert!((near.p99_px - 8.0).abs() < 0.01, "{}", near.p99_px);
        let narrow = position_error(&a, &b, 0, false).unwrap();
        let reach = (MAX_REFINEMENT_STEPS + 1) as f64;
        assert!(
            narrow.max_px <= reach + 1e-4 && // P is f32
            narrow.p99_px > reach - 0.5,
            "a window of 0 px reaches {reach} px by refinement: {:?}",
            narrow
        );
    }
    /// Part of the object hidden behind itself: P jumps between two rows of the same object. The
    /// pixels next to the jump are still measured from the side they belong to.
    #[test]
    fn a_jump_in_p_within_one_object_does_not_spoil_the_fit() {
        let fold = |x: f64, y: f64| {
            let p = smooth_position(x, y);
            if y >= 20.0 {
                [p[0] + 0.05, p[1], p[2] + 0.3]
            } else {
                p
            }
        };
        let a = frame_of(48, 40, fold);
        let b = frame_of(48, 40, |x, y| {
            // The same shift on both sides, the fold staying put.
            let p = smooth_position(x, y + 0.3);
            if y >= 20.0 {
                [p[0] + 0.05, p[1], p[2] + 0.3]
            } else {
                p
            }
        });
        let worst = pixel_errors(&a, &b, DEFAULT_WINDOW_PX)
            .into_iter()
            .flatten()
            .filter(|&(index, _)| {
                let (x, y) = (index % 48, index / 48);
                (1..47).contains(&x) && (18..22).contains(&y)
            })
            .map(|(_, e)| (e as f64 - 0.3).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "rows beside the jump off by {worst} px");
    }
}
