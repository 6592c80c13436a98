//! The crest check of the linear methods (ALGORITHM §6): is the path eye -> sight point -> point
//! blocked by the water surface, a wave crest in front of the sight point or a trough the path
//! under water rises out of? It is [`ExactSurface::path_is_clear`] (with its guarantee: no crest
//! is stepped over) with what a sight point on a facet needs: a guard around the sight point, a
//! tolerance of the faceting error, and a bound on how far the facet lies from the exact surface.
//! Built once per frame ([`CrestCheck::new`]); asked once per image the search keeps.

use glam::DVec3;
use rayon::prelude::*;

use super::super::cells::CONTAINMENT_EPS;
use super::super::surface::{ExactSurface, PathCheck};
use crate::water::{HeightField, Membrane};

/// Crest check: points of the path closer to the sight point than this fraction of the membrane
/// spacing (horizontally) are not checked: there the facet the sight point lies on and the exact
/// surface differ by the faceting error, which says nothing about a crest.
pub const CREST_GUARD_PER_SPACING: f64 = 0.5;

/// What the crest check needs of one frame.
pub(crate) struct CrestCheck {
    /// The membrane grid's spacing (the smaller direction).
    pub(super) spacing_m: f64,
    /// The path check: the guard, the faceting tolerance ([`faceting_tolerance`]) and the bound
    /// on a facet's distance from the exact surface ([`facet_gap_bound_m`]).
    pub(crate) check: PathCheck,
    /// The membrane cell's squared diagonal and the largest coordinate of its vertices: what
    /// [`facet_gap_m`] needs for a gap from the bounds near one sight point.
    diagonal_squared_m2: f64,
    scale_m: f64,
}

impl CrestCheck {
    pub(super) fn new(membrane: &Membrane, surface: &ExactSurface, spacing_m: f64) -> Self {
        let grid = membrane.grid;
        let diagonal_squared_m2 = grid.cell_size_x_m().powi(2) + grid.cell_size_z_m().powi(2);
        let scale_m = membrane
            .positions
            .iter()
            .fold(1.0_f64, |m, p| m.max(p.abs().max_element() as f64));
        Self {
            spacing_m,
            check: PathCheck {
                guard_m: CREST_GUARD_PER_SPACING * spacing_m,
                tolerance_m: faceting_tolerance(membrane, surface),
                sight_point_gap_m: facet_gap_m(
                    surface.curvature_bound,
                    surface.slope_bound,
                    diagonal_squared_m2,
                    scale_m,
                ),
            },
            diagonal_squared_m2,
            scale_m,
        }
    }

    /// Whether the path `eye -> sight_point -> point` is blocked (the sight point on a facet).
    /// With bounds per part of the plane, the facet's gap is bounded by the surface's bounds
    /// within a cell diagonal of the sight point (the facet holding it lies there).
    pub(crate) fn blocks(
        &self,
        surface: &ExactSurface,
        eye: DVec3,
        sight_point: DVec3,
        point: DVec3,
    ) -> bool {
        if surface.local_bounds.is_none() {
            return !surface.path_is_clear(eye, sight_point, point, &self.check);
        }
        let r = self.diagonal_squared_m2.sqrt();
        let s = sight_point;
        let near = surface.bounds_over(s.x - r, s.z - r, s.x + r, s.z + r);
        let check = PathCheck {
            sight_point_gap_m: facet_gap_m(
                near.curvature,
                near.slope,
                self.diagonal_squared_m2,
                self.scale_m,
            ),
            ..self.check
        };
        !surface.path_is_clear(eye, sight_point, point, &check)
    }
}

/// How far a point of a facet (barycentrics down to `-CONTAINMENT_EPS`, as the cells accept) may
/// lie from the exact surface, vertically: a proven bound. With the vertices `x_i` on the surface
/// and `x = sum b_i x_i`, Taylor's theorem at `x` gives `h(x) - sum b_i h(x_i) =
/// -1/2 sum b_i (x_i - x)^T H (x_i - x)`, at most `C/2 sum |b_i| |x_i - x|^2` with `C` the
/// surface's curvature bound. For a membrane cell's right triangle `sum b_i |x_i - x|^2 =
/// R^2 - |x - c|^2 <= R^2` (c, R: circumcentre and radius, `R` half the cell's diagonal), and the
/// negative barycentrics add at most `2 * 3 eps` of the squared diagonal. Plus the f32 rounding of
/// the vertex heights and positions (coordinates up to `scale_m`). `curvature` and `slope`: the
/// surface's bounds over the facet.
fn facet_gap_m(curvature: f64, slope: f64, diagonal_squared_m2: f64, scale_m: f64) -> f64 {
    0.5 * curvature * diagonal_squared_m2 * (0.25 + 7.0 * CONTAINMENT_EPS)
        + 8.0 * f32::EPSILON as f64 * scale_m * (1.0 + slope)
}

/// Twice the largest gap between the faceted membrane and the exact surface, sampled at facet
/// centroids and edge midpoints of at most ~2,000 facets (evenly strided), plus rounding: the
/// height tolerance of the crest check. The sight point lies on a facet, so the straight path
/// through it may pass the exact surface by about the faceting gap without any crest there.
fn faceting_tolerance(membrane: &Membrane, surface: &dyn HeightField) -> f64 {
    let n = membrane.triangles.len();
    if n == 0 {
        return 0.0;
    }
    let stride = n.div_ceil(2048).max(1);
    let gap = membrane
        .triangles
        .par_iter()
        .step_by(stride)
        .map(|tri| {
            let p = tri.map(|i| membrane.positions[i as usize].as_dvec3());
            let samples = [
                (p[0] + p[1] + p[2]) / 3.0,
                (p[0] + p[1]) * 0.5,
                (p[1] + p[2]) * 0.5,
                (p[2] + p[0]) * 0.5,
            ];
            samples
                .iter()
                .map(|s| (s.y - surface.height(s.x, s.z)).abs())
                .fold(0.0, f64::max)
        })
        .reduce(|| 0.0, f64::max);
    let scale = membrane
        .positions
        .iter()
        .fold(1.0_f64, |m, p| m.max(p.abs().max_element() as f64));
    2.0 * gap + 1e-6 * scale
}
