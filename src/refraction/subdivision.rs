//! Adaptive subdivision of under-water triangles in the exact method (thesis §4.7: exact vertices
//! alone leave triangle interiors linear). Receives a triangle's three vertices with their exact
//! virtual positions; returns the triangles it is drawn as, split where the exact image of an
//! edge's midpoint strays from the straight virtual edge by more than a screen tolerance.
//!
//! Splits are decided per EDGE by a function of the edge alone (its two end vertices, taken in a
//! canonical order, and the frame): the two triangles sharing an edge split it identically, at
//! bit-identical midpoints, so no cracks (T-junctions) appear. A triangle with 1, 2 or 3 split
//! edges becomes 2, 3 or 4 triangles, each processed again one level deeper, up to the depth
//! limit. New vertices get the true edge's midpoint, interpolated normal and uv, and their own
//! exact virtual position. Pure CPU.

use glam::{DVec2, DVec3, Vec2, Vec3};

use super::exact::{
    path_is_clear, solve_sight_point_within, FermatProblem, SolveLimits, MIDPOINT_MAX_EVALUATIONS,
};
use super::flat::virtual_vertex;
use super::search::RefractionField;
use super::split::{WaterVolume, SURFACE_TOLERANCE_M};
use crate::camera::Camera;

/// Default screen tolerance: an edge whose midpoint's exact image is farther than this from the
/// straight virtual edge is split.
pub const DEFAULT_TOLERANCE_PX: f32 = 0.25;
/// Default depth limit: an original edge becomes at most 2^4 = 16 segments.
pub const DEFAULT_MAX_DEPTH: u32 = 4;

/// How finely the exact method subdivides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubdivisionSettings {
    /// Largest allowed distance, in pixels, of an edge midpoint's exact image from the straight
    /// virtual edge.
    pub tolerance_px: f32,
    /// Recursion limit (0: no subdivision, exact vertices only).
    pub max_depth: u32,
}

impl Default for SubdivisionSettings {
    fn default() -> Self {
        Self {
            tolerance_px: DEFAULT_TOLERANCE_PX,
            max_depth: DEFAULT_MAX_DEPTH,
        }
    }
}

/// A vertex of an under-water triangle as the subdivision sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubdivisionVertex {
    /// True attributes.
    pub position: Vec3,
    pub normal: Vec3,
    pub uv: Vec2,
    pub virtual_position: Vec3,
    /// Where the vertex was drawn at frame t-1 (motion vectors): a split edge's midpoint takes
    /// the mean of its ends', a linear estimate.
    pub previous_position: Vec3,
    pub water_path_m: f32,
    /// The exact sight point's (x, z); `None` when the drawn position is not exact (a Newton
    /// fallback or no image): edges ending there are never split.
    pub sight_xz: Option<DVec2>,
    /// On the water surface (a water-line vertex, its own virtual vertex). An edge between two
    /// of them is shared with the part above the water, drawn straight at true positions, so it
    /// is never split (that would open a crack along the water line).
    pub on_surface: bool,
}

/// What the subdivision did to one triangle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SubdivisionStats {
    /// Triangles output.
    pub pieces: u32,
    /// Deepest level at which an edge was split (0: none split).
    pub deepest_level: u32,
}

/// The frame's context for subdividing: the optics, the screen and the water.
pub struct Subdivider<'a> {
    pub field: &'a RefractionField<'a>,
    pub camera: Camera,
    pub image_size: (u32, u32),
    pub settings: SubdivisionSettings,
}

impl Subdivider<'_> {
    /// The triangles `triangle` is drawn as (appended to `out`, winding kept), given the answers
    /// of [`Self::split_edge`] for its own edges (`first[k]` for `triangle[k]`-`triangle[k + 1]`):
    /// a frame computes them once per edge, shared by the two triangles on it.
    pub fn subdivide_from(
        &self,
        triangle: [SubdivisionVertex; 3],
        first: [Option<SubdivisionVertex>; 3],
        out: &mut Vec<[SubdivisionVertex; 3]>,
    ) -> SubdivisionStats {
        let mut stats = SubdivisionStats::default();
        let before = out.len();
        if self.settings.max_depth == 0 {
            out.push(triangle);
        } else {
            let mut memo = EdgeMemo::default();
            self.split_with(triangle, first, 0, out, &mut stats, &mut memo);
        }
        stats.pieces = (out.len() - before) as u32;
        stats
    }

    /// `unsplit[k]`: edge k (`t[k]`-`t[k+1]`) is known not to split (it was tested one level up
    /// and is inherited whole; testing it again gives the same answer, it is a function of the
    /// edge alone).
    fn subdivide_at(
        &self,
        t: [SubdivisionVertex; 3],
        unsplit: [bool; 3],
        level: u32,
        out: &mut Vec<[SubdivisionVertex; 3]>,
        stats: &mut SubdivisionStats,
        memo: &mut EdgeMemo,
    ) {
        if level >= self.settings.max_depth {
            out.push(t);
            return;
        }
        let mids: [Option<SubdivisionVertex>; 3] = std::array::from_fn(|k| {
            if unsplit[k] {
                None
            } else {
                let (a, b) = (&t[k], &t[(k + 1) % 3]);
                *memo
                    .entry(edge_key(a, b))
                    .or_insert_with(|| self.split_edge(a, b))
            }
        });
        self.split_with(t, mids, level, out, stats, memo);
    }

    /// Splits `t` at the midpoints `mids` (of edges k = `t[k]`-`t[k+1]`) and goes on with the
    /// pieces one level deeper.
    fn split_with(
        &self,
        t: [SubdivisionVertex; 3],
        mids: [Option<SubdivisionVertex>; 3],
        level: u32,
        out: &mut Vec<[SubdivisionVertex; 3]>,
        stats: &mut SubdivisionStats,
        memo: &mut EdgeMemo,
    ) {
        let count = mids.iter().filter(|m| m.is_some()).count();
        if count == 0 {
            out.push(t);
            return;
        }
        stats.deepest_level = stats.deepest_level.max(level + 1);
        let next = level + 1;
        match count {
            1 => {
                let k = (0..3).find(|&k| mids[k].is_some()).expect("one split edge");
                let m = mids[k].expect("split");
                let (p, q, r) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                // Edges of [p, m, r]: p-m half, m-r new, r-p inherited whole.
                self.subdivide_at([p, m, r], [false, false, true], next, out, stats, memo);
                // Edges of [m, q, r]: m-q half, q-r inherited whole, r-m new.
                self.subdivide_at([m, q, r], [false, true, false], next, out, stats, memo);
            }
            2 => {
                let k = (0..3).find(|&k| mids[k].is_none()).expect("one whole edge");
                let (p, q, r) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let (m1, m2) = (
                    mids[(k + 1) % 3].expect("split"),
                    mids[(k + 2) % 3].expect("split"),
                );
                // p-q whole; m1 on q-r, m2 on r-p.
                self.subdivide_at([p, q, m1], [true, false, false], next, out, stats, memo);
                self.subdivide_at([m1, r, m2], [false, false, false], next, out, stats, memo);
                self.subdivide_at([p, m1, m2], [false, false, false], next, out, stats, memo);
            }
            _ => {
                let [m0, m1, m2] = mids.map(|m| m.expect("split"));
                let [p, q, r] = t;
                self.subdivide_at([p, m0, m2], [false; 3], next, out, stats, memo);
                self.subdivide_at([m0, q, m1], [false; 3], next, out, stats, memo);
                self.subdivide_at([m2, m1, r], [false; 3], next, out, stats, memo);
                self.subdivide_at([m0, m1, m2], [false; 3], next, out, stats, memo);
            }
        }
    }

    /// The midpoint vertex if the edge a-b must be split, else None. A function of the edge alone:
    /// the ends are put in a canonical order first, so (a, b) and (b, a) give the same bits.
    pub fn split_edge(
        &self,
        a: &SubdivisionVertex,
        b: &SubdivisionVertex,
    ) -> Option<SubdivisionVertex> {
        let (a, b) = canonical(a, b);
        if a.on_surface && b.on_surface {
            return None;
        }
        let (sight_a, sight_b) = (a.sight_xz?, b.sight_xz?);
        #[cfg(test)]
        let _source = super::work::source(super::work::Source::Midpoint);
        #[cfg(test)]
        super::work::count(|w, _| w.edge_tests += 1);
        let position = (0.5 * (a.position.as_dvec3() + b.position.as_dvec3())).as_vec3();
        let (width, height) = self.image_size;
        let pixels = self.camera.pixels(width, height);
        let (pa, pb) = (
            pixels.pixel_of(a.virtual_position)?,
            pixels.pixel_of(b.virtual_position)?,
        );
        // The solve may stop once the midpoint's image is certainly within the tolerance: the
        // edge stays whole, as the converged solve would say. The virtual vertex is on the sight
        // ray through the sight point, so their pixels agree (to f32 rounding: the 0.01 px). A
        // sight point within `error_m` horizontally of the solution is within `error_m (1 + G)`
        // of it, which moves its pixel by at most `f / depth / cos(off-axis angle)` times that
        // (f the focal length in pixels: the largest singular value of the projection's
        // derivative there).
        let focal_px =
            0.5 * height as f64 / (0.5 * self.camera.fov_y_deg.to_radians() as f64).tan();
        let centre = glam::DVec2::new(0.5 * width as f64, 0.5 * height as f64);
        let slope = self.field.surface.slope_bound;
        let tolerance_px = self.settings.tolerance_px as f64;
        let within_tolerance = |s: DVec3, error_m: f64| {
            let depth_m = self.camera.view_depth(s.as_vec3()) as f64;
            let Some(pm) = pixels.pixel_of(s.as_vec3()) else {
                return false;
            };
            let off_axis = (pm.as_dvec2() - centre) / focal_px;
            let stretch = (1.0 + off_axis.length_squared()).sqrt();
            let margin_px = focal_px / depth_m * stretch * error_m * (1.0 + slope) + 0.01;
            depth_m > 1e-3 && distance_to_segment(pm, pa, pb) as f64 + margin_px < tolerance_px
        };
        let (virtual_position, water_path_m, sight_xz) = self.exact_vertex_unchecked(
            position,
            0.5 * (sight_a + sight_b),
            Some(&within_tolerance),
        )?;
        let stray_px = self.stray_px(a.virtual_position, b.virtual_position, virtual_position)?;
        // The path check only matters for a vertex that will exist: most edges stay whole.
        let sight_point = DVec3::new(sight_xz.x, 0.0, sight_xz.y);
        let keep =
            stray_px > self.settings.tolerance_px && self.path_is_clear(position, sight_point);
        #[cfg(test)]
        super::work::count(|w, _| w.edge_splits += u64::from(keep));
        keep.then(|| SubdivisionVertex {
            position,
            normal: (a.normal + b.normal).normalize_or(a.normal),
            uv: 0.5 * (a.uv + b.uv),
            virtual_position,
            previous_position: 0.5 * (a.previous_position + b.previous_position),
            water_path_m,
            sight_xz: Some(sight_xz),
            on_surface: false,
        })
    }

    /// The exact virtual vertex of a point strictly under the water, Newton started at
    /// `start_xz`, with its water path and sight point, without the path check; the solve within
    /// the midpoints' limits ([`MIDPOINT_MAX_EVALUATIONS`], and `enough`:
    /// [`SolveLimits::enough`]).
    fn exact_vertex_unchecked(
        &self,
        position: Vec3,
        start_xz: DVec2,
        enough: Option<&dyn Fn(DVec3, f64) -> bool>,
    ) -> Option<(Vec3, f32, DVec2)> {
        let field = self.field;
        let point = position.as_dvec3();
        let water = WaterVolume {
            surface: field.surface.height_field,
            extent: field.membrane.grid,
        };
        if water.height_above_surface_m(point)? >= -SURFACE_TOLERANCE_M {
            return None;
        }
        let problem = self.problem(point);
        let limits = SolveLimits {
            max_evaluations: MIDPOINT_MAX_EVALUATIONS,
            enough,
        };
        let s = solve_sight_point_within(&problem, start_xz, &limits)?.sight_point;
        let virtual_position =
            virtual_vertex(problem.eye, s, point, problem.n_above, problem.n_below);
        Some((
            virtual_position.as_vec3(),
            (point - s).length() as f32,
            DVec2::new(s.x, s.z),
        ))
    }

    fn problem(&self, point: DVec3) -> FermatProblem<'_> {
        let field = self.field;
        FermatProblem {
            surface: field.surface.height_field,
            eye: field.setup.eye.as_dvec3(),
            point,
            n_above: field.setup.n_above as f64,
            n_below: field.setup.n_below as f64,
        }
    }

    /// Whether the path from the eye through the sight point above `sight_point`'s (x, z) to
    /// `position` is clear ([`path_is_clear`]).
    fn path_is_clear(&self, position: Vec3, sight_point: DVec3) -> bool {
        let field = self.field;
        let problem = self.problem(position.as_dvec3());
        let s = problem.surface_point(DVec2::new(sight_point.x, sight_point.z));
        path_is_clear(field.surface, &problem, s)
    }

    /// Screen distance, in pixels, of `m` from the segment a-b (all virtual positions); None when
    /// one is behind the eye.
    pub fn stray_px(&self, a: Vec3, b: Vec3, m: Vec3) -> Option<f32> {
        let (width, height) = self.image_size;
        let pixels = self.camera.pixels(width, height);
        let pa = pixels.pixel_of(a)?;
        let pb = pixels.pixel_of(b)?;
        let pm = pixels.pixel_of(m)?;
        Some(distance_to_segment(pm, pa, pb))
    }
}

/// Distance from `p` to the segment a-b.
pub fn distance_to_segment(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let along = b - a;
    let length_squared = along.length_squared();
    let s = if length_squared > 0.0 {
        ((p - a).dot(along) / length_squared).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + along * s)
}

/// The split answers of the edges one triangle's pieces have tested, by [`edge_key`]: inside a
/// triangle split in four, each edge of the middle piece is also an edge of a corner piece, so
/// without it half the tests of a deep subdivision are repeats (measured on
/// `scenes/hard/wading_wake.toml` frame 44 at 1280x720: 52.0 edge tests per under-water vertex).
/// [`Subdivider::split_edge`] is a function of the edge alone, so a repeat gives the same answer.
type EdgeMemo = std::collections::HashMap<[u32; 6], Option<SubdivisionVertex>>;

/// An edge's two ends' true positions, in [`canonical`] order, as bits.
fn edge_key(a: &SubdivisionVertex, b: &SubdivisionVertex) -> [u32; 6] {
    let (a, b) = canonical(a, b);
    let (p, q) = (a.position.to_array(), b.position.to_array());
    [p[0], p[1], p[2], q[0], q[1], q[2]].map(f32::to_bits)
}

/// The two ends ordered by their true positions (x, then y, then z, compared as numbers).
fn canonical<'v>(
    a: &'v SubdivisionVertex,
    b: &'v SubdivisionVertex,
) -> (&'v SubdivisionVertex, &'v SubdivisionVertex) {
    let key = |v: &SubdivisionVertex| v.position.to_array();
    let (ka, kb) = (key(a), key(b));
    let order = ka[0]
        .total_cmp(&kb[0])
        .then(ka[1].total_cmp(&kb[1]))
        .then(ka[2].total_cmp(&kb[2]));
    if order.is_le() {
        (a, b)
    } else {
        (b, a)
    }
}
