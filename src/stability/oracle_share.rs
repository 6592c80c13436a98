//! How hard a frame is, by the truth: the share of the frame's under-water vertices that have two
//! or more images by the independent image oracle ([`crate::oracle`]), which shares only the
//! height field and the water's stated bounds (the waves' and the ripples', taken here from the
//! water itself, not from the renderer's exact surface) with the methods measured. Receives a loaded job and a frame; returns
//! [`OracleShare`]. `snell stability` reports it per frame, so a hard scene that stopped being
//! hard (smoothed water, a camera that no longer looks through the crests) shows.
//!
//! The oracle costs thousands of height evaluations per vertex, so by default a deterministic
//! systematic sample is measured: every k-th under-water vertex in (object, vertex) order, k
//! chosen so that at most `max_samples` are (all of them when there are fewer). The share's 95 %
//! confidence interval is Wilson's score interval for a binomial proportion: for a share near 1 %
//! from 2,000 vertices it is about 0.6-1.6 %, near 5 % about 4.1-6.0 %.

use std::time::Instant;

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::frame::{RenderJob, SnellError};
use crate::oracle::{LocalBounds, OracleWater, RegionBounds};
use crate::refraction::split::{Side, WaterVolume};
use crate::sim::ripple_bounds::RippleBounds;
use crate::sim::RippleField;
use crate::water::WaterSurface;

/// Under-water vertices measured per frame unless asked otherwise.
pub const DEFAULT_SAMPLES: usize = 2_000;

/// One frame's multi-image share by the oracle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleShare {
    pub frame: u32,
    /// The frame's under-water vertices (every object's, seen or not).
    pub under_water_vertices: usize,
    /// Of which the oracle measured (a systematic sample, or all).
    pub sampled: usize,
    /// Sampled vertices the oracle answered for certain, and of those, with two or more images.
    pub certain: usize,
    pub multi_image: usize,
    /// Sampled vertices the oracle could not settle: on a fold (a Newton solve that did not land)
    /// or past its cell budget. Left out of the share; reported so they are seen.
    pub uncertain: usize,
    /// Seconds the oracle took (both cores).
    pub seconds: f64,
}

impl OracleShare {
    /// Multi-image vertices over the certain ones (0 when there are none).
    pub fn fraction(&self) -> f64 {
        if self.certain == 0 {
            0.0
        } else {
            self.multi_image as f64 / self.certain as f64
        }
    }

    /// Wilson's 95 % score interval for [`Self::fraction`]; exact (a point) when every vertex
    /// was measured.
    pub fn interval95(&self) -> (f64, f64) {
        let p = self.fraction();
        if self.sampled >= self.under_water_vertices || self.certain == 0 {
            return (p, p);
        }
        let (n, z) = (self.certain as f64, 1.96f64);
        let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
        let half = z / (1.0 + z * z / n) * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
        // The score interval contains p; clamping to it removes round-off (at p = 0 the lower
        // end came out 7e-18).
        ((centre - half).clamp(0.0, p), (centre + half).clamp(p, 1.0))
    }
}

/// The surface's bounds as the water states them, taken from the water itself and not from the
/// renderer's exact surface ([`crate::refraction::surface`]): the analytic waves' height range,
/// slope and curvature bounds (they hold over the whole plane), plus, on water with ripples, the
/// ripple field's, over the whole plane ([`crate::sim::RippleField::max_abs_height_m`],
/// [`crate::sim::RippleField::slope_and_curvature_bounds`]) and per tile of its grid
/// ([`RippleBounds`]). The sum of two fields' bounds bounds the sum (`|a + b| <= |a| + |b|`, for
/// the heights and every derivative alike).
struct StatedBounds {
    waves_height_range_m: (f64, f64),
    waves_slope: f64,
    waves_curvature: f64,
    ripples: Option<RippleBounds>,
}

impl StatedBounds {
    fn of(waves: &WaterSurface, ripples: Option<&RippleField<'_>>) -> (Self, RegionBounds) {
        let (waves_slope, waves_curvature) = waves.slope_and_curvature_bounds();
        let stated = StatedBounds {
            waves_height_range_m: waves.height_bounds_m(),
            waves_slope,
            waves_curvature,
            ripples: ripples.map(RippleBounds::new),
        };
        let (reach, (slope, curvature)) = ripples.map_or((0.0, (0.0, 0.0)), |field| {
            (field.max_abs_height_m(), field.slope_and_curvature_bounds())
        });
        let whole_plane = stated.with_ripples(reach, slope, curvature);
        (stated, whole_plane)
    }

    /// The waves' bounds plus the ripples' `reach` (largest |height|), `slope` and `curvature`.
    fn with_ripples(&self, reach: f64, slope: f64, curvature: f64) -> RegionBounds {
        let (low, high) = self.waves_height_range_m;
        RegionBounds {
            height_range_m: (low - reach, high + reach),
            slope_bound: self.waves_slope + slope,
            curvature_bound: self.waves_curvature + curvature,
        }
    }
}

impl LocalBounds for StatedBounds {
    fn over(&self, min: DVec2, max: DVec2) -> RegionBounds {
        match &self.ripples {
            Some(ripples) => {
                let b = ripples.over(min.x, min.y, max.x, max.y);
                self.with_ripples(b.reach_m, b.slope, b.curvature_per_m)
            }
            None => self.with_ripples(0.0, 0.0, 0.0),
        }
    }
}

/// The oracle's multi-image share of `frame`'s under-water vertices, over at most `max_samples`
/// of them (0: all), as the module documentation describes.
pub fn oracle_share(
    job: &RenderJob,
    frame: u32,
    max_samples: usize,
) -> Result<OracleShare, SnellError> {
    let clock = Instant::now();
    let mut stage_secs = Default::default();
    let water = job.frame_water(frame, &mut stage_secs)?;
    let heights = water.surface();
    let (stated, whole_plane) = StatedBounds::of(&water.waves_now, heights.ripples.as_ref());
    let volume = WaterVolume {
        surface: &heights,
        extent: water.membrane.grid,
    };
    let points: Vec<DVec3> = water
        .objects
        .iter()
        .flat_map(|object| object.mesh.positions.iter())
        .map(|p| p.as_dvec3())
        .filter(|&p| volume.side_of(p) == Side::Below)
        .collect();
    let oracle = OracleWater {
        height_field: &heights,
        extent: water.membrane.grid,
        height_range_m: whole_plane.height_range_m,
        slope_bound: whole_plane.slope_bound,
        curvature_bound: whole_plane.curvature_bound,
        n_above: job.scene.water.n_above,
        n_below: job.scene.water.n_below,
        local_bounds: stated
            .ripples
            .is_some()
            .then_some(&stated as &dyn LocalBounds),
    };
    let stride = if max_samples == 0 {
        1
    } else {
        points.len().div_ceil(max_samples).max(1)
    };
    let eye = water.camera.eye.as_dvec3();
    let sample: Vec<DVec3> = points.iter().step_by(stride).copied().collect();
    let (certain, multi_image, uncertain) = sample
        .par_iter()
        .with_min_len(8)
        .map(|&point| {
            let found = oracle.images(eye, point);
            if found.is_certain() {
                (1, usize::from(found.images.len() >= 2), 0)
            } else {
                (0, 0, 1)
            }
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    Ok(OracleShare {
        frame,
        under_water_vertices: points.len(),
        sampled: sample.len(),
        certain,
        multi_image,
        uncertain,
        seconds: clock.elapsed().as_secs_f64(),
    })
}
