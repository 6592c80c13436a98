//! The crest check of the linear methods (ALGORITHM §6): is the path eye -> sight point -> point
//! blocked by the water surface, a wave crest in front of the sight point or a trough the path
//! under water rises out of? Built once per frame from the membrane and the exact surface
//! ([`CrestCheck::new`]); asked once per image the search keeps.

use glam::DVec3;
use rayon::prelude::*;

use super::super::cells::CONTAINMENT_EPS;
use super::blocks::BLOCK_CELLS;
use crate::water::{HeightField, Membrane, MembraneGrid};

/// Crest check: sample step along a path, as a fraction of the membrane grid spacing. The membrane
/// does not resolve features narrower than its spacing, so neither does this check.
pub const CREST_SAMPLE_STEP_PER_SPACING: f64 = 0.5;
/// Crest check: samples closer to the sight point than this fraction of the spacing (horizontally)
/// are skipped: there the faceted surface the sight point lies on and the check's surface differ by
/// the faceting error, which says nothing about a crest.
pub const CREST_GUARD_PER_SPACING: f64 = 0.5;

/// What the crest check needs of one frame: the membrane's spacing and height range, the
/// faceting tolerance, the interpolated heights it compares against and their tiles.
pub(crate) struct CrestCheck {
    /// The membrane grid's spacing (the smaller direction).
    pub(super) spacing_m: f64,
    /// The faceting tolerance ([`faceting_tolerance`]).
    pub(crate) tolerance_m: f64,
    /// The membrane vertices' height range.
    surface_y_min: f64,
    surface_y_max: f64,
    /// Prefilter ([`TileLevel`]).
    tiles: Option<TileLevel>,
    /// The height the check compares against (see [`CrestHeights`]).
    pub(crate) heights: CrestHeights,
    grid: MembraneGrid,
}

impl CrestCheck {
    pub(super) fn new(membrane: &Membrane, surface: &dyn HeightField, spacing_m: f64) -> Self {
        let (y_min, y_max) = membrane
            .positions
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.y as f64), hi.max(p.y as f64))
            });
        let heights = CrestHeights::new(membrane);
        let tolerance_m = faceting_tolerance(membrane, surface, &heights);
        Self {
            spacing_m,
            tolerance_m,
            surface_y_min: if y_min.is_finite() { y_min } else { 0.0 },
            surface_y_max: if y_max.is_finite() { y_max } else { 0.0 },
            tiles: tile_level(membrane),
            heights,
            grid: membrane.grid,
        }
    }

    /// Heights (min, max) the exact surface stays within: the membrane vertices' range widened
    /// by the faceting tolerance (the same bound the check relies on).
    pub(super) fn surface_height_bounds_m(&self) -> (f64, f64) {
        (
            self.surface_y_min - self.tolerance_m,
            self.surface_y_max + self.tolerance_m,
        )
    }

    /// Is the path eye -> sight point -> point blocked by the surface (ALGORITHM §6)? The
    /// segment from the eye must stay above the surface and the one to the point below it, except
    /// within `CREST_GUARD_PER_SPACING` spacings of the sight point, with a tolerance of the
    /// faceting error (`crest_tolerance_m`). The surface is the membrane's vertex heights
    /// interpolated bilinearly ([`CrestHeights`]; the exact surface outside a grid membrane): a
    /// sample costs four loads instead of an evaluation of the height field, and the tolerance
    /// covers both this interpolation's and the facets' distance from the exact surface. Sampled
    /// every `CREST_SAMPLE_STEP_PER_SPACING` spacings, only on the parts of the segments inside the
    /// surface's height range.
    pub(super) fn blocks(
        &self,
        surface: &dyn HeightField,
        eye: DVec3,
        sight_point: DVec3,
        point: DVec3,
    ) -> bool {
        self.blocks_with(surface, eye, sight_point, point, true)
    }

    /// [`Self::blocks`], with the slope proof (`prove`) or walking every segment.
    pub(super) fn blocks_with(
        &self,
        surface: &dyn HeightField,
        eye: DVec3,
        sight_point: DVec3,
        point: DVec3,
        prove: bool,
    ) -> bool {
        let tolerance = self.tolerance_m;
        // The proof that lets most paths skip the walk: a segment from S whose slope beats the
        // interpolated surface's Lipschitz bound by enough, from the guard distance on, cannot
        // meet it (see `segment_clear_by_slope`).
        // Eye side: points above surface_y_max + tolerance cannot be under the surface.
        let to_eye = eye - sight_point;
        let eye_end = if to_eye.y > 0.0 {
            ((self.surface_y_max + tolerance - sight_point.y) / to_eye.y).clamp(0.0, 1.0)
        } else {
            1.0
        };
        // Where the sample is above every membrane vertex of the 3 x 3 tiles around it, the
        // interpolated surface (within its cell's vertex heights) cannot be above it here or
        // anywhere within a tile ahead (the segment only rises toward the eye): skip a tile.
        let under = |x: DVec3| {
            if let Some(reach_m) = self.clear_reach(x, |[_, high]| x.y >= high as f64) {
                return Probe::ClearAhead(reach_m);
            }
            if x.y < self.height(surface, x.x, x.z) - tolerance {
                Probe::Hit
            } else {
                Probe::Clear
            }
        };
        if !(prove && self.segment_clear_by_slope(sight_point, to_eye, eye_end, 1.0))
            && self.segment_hits(sight_point, to_eye, eye_end, to_eye.y >= 0.0, under)
        {
            return true;
        }
        let to_point = point - sight_point;
        let point_end = if to_point.y < 0.0 {
            ((sight_point.y - (self.surface_y_min - tolerance)) / -to_point.y).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let over = |x: DVec3| {
            if let Some(reach_m) = self.clear_reach(x, |[low, _]| x.y <= low as f64) {
                return Probe::ClearAhead(reach_m);
            }
            if x.y > self.height(surface, x.x, x.z) + tolerance {
                Probe::Hit
            } else {
                Probe::Clear
            }
        };
        !(prove && self.segment_clear_by_slope(sight_point, to_point, point_end, -1.0))
            && self.segment_hits(sight_point, to_point, point_end, to_point.y <= 0.0, over)
    }

    /// Proves that no sample of [`Self::segment_hits`] on `start + s * direction`, s in
    /// (guard, end], can report a crest, without sampling: true only when that holds (false
    /// means "not proven", and the walk decides). `side` is +1 for the eye segment (a hit is a
    /// sample below the surface less the tolerance) and -1 for the segment under water (above
    /// it plus the tolerance).
    ///
    /// With `d` the horizontal distance of a sample from S (`d >= guard`), the segment's height
    /// moves away from `S.y` by `side * rise * d` (`rise` = its slope), while the interpolated
    /// surface moves by at most `slope_bound * d` from its height at S, which is within
    /// `facet_gap_bound` (plus rounding) of `S.y` (S lies on a facet of the same cell). A hit
    /// needs `(rise - slope_bound) * d < gap - tolerance`; with `rise >= slope_bound` that is
    /// impossible once `(rise - slope_bound) * guard >= gap - tolerance`. Only inside the grid:
    /// elsewhere the check's surface is the exact one, with no bound at hand.
    pub(crate) fn segment_clear_by_slope(
        &self,
        start: DVec3,
        direction: DVec3,
        end: f64,
        side: f64,
    ) -> bool {
        let heights = &self.heights;
        let stop = start + direction * end.max(0.0);
        if !(heights.covers(start.x, start.z) && heights.covers(stop.x, stop.z)) {
            return false;
        }
        let horizontal = (direction.x * direction.x + direction.z * direction.z).sqrt();
        let guard_m = CREST_GUARD_PER_SPACING * self.spacing_m;
        // S is stored in f32: its height may be off by the rounding of its coordinates. And its
        // barycentrics may be down to -CONTAINMENT_EPS, so it may lie just outside its facet
        // (a few eps of a cell diagonal), where the facet's plane and the interpolated heights
        // part at up to twice the slope bound.
        let rounding_m = 4.0 * f32::EPSILON as f64 * (1.0 + start.abs().max_element())
            + 2.0 * heights.slope_bound * 4.0 * CONTAINMENT_EPS * heights.cell_diagonal_m;
        let excess_m = heights.facet_gap_bound + rounding_m - self.tolerance_m;
        // (rise - slope_bound) * guard >= excess, times `horizontal` (>= 0) to avoid dividing.
        side * direction.y * guard_m
            >= heights.slope_bound * guard_m * horizontal + excess_m.max(0.0) * horizontal
    }

    /// The surface height the crest check uses at (x, z): the membrane vertices' bilinear
    /// interpolation inside a grid membrane, the exact surface elsewhere.
    #[inline]
    fn height(&self, surface: &dyn HeightField, x: f64, z: f64) -> f64 {
        self.heights
            .height(x, z)
            .unwrap_or_else(|| surface.height(x, z))
    }

    /// How far around `x` (horizontally) the tiles prove the surface clear: the tile reach if
    /// the range of the tile holding `x` passes `clear`.
    #[inline]
    fn clear_reach(&self, x: DVec3, clear: impl Fn([f32; 2]) -> bool) -> Option<f64> {
        let tiles = self.tiles.as_ref()?;
        let grid = self.grid;
        let (dx, dz) = (x.x - grid.min_x, x.z - grid.min_z);
        if !(dx >= 0.0 && dz >= 0.0) {
            return None;
        }
        let (tx, tz) = (
            (dx * tiles.inverse_size_m[0]) as usize,
            (dz * tiles.inverse_size_m[1]) as usize,
        );
        (tx < tiles.tiles_x && tz < tiles.tiles_z && clear(tiles.ranges[tz * tiles.tiles_x + tx]))
            .then_some(tiles.reach_m)
    }

    /// Walks `start + s * direction` for s in (guard, end] every `CREST_SAMPLE_STEP_PER_SPACING`
    /// spacings (a tile at a time where `probe` says so and `can_skip`: the segment's height moves
    /// away from the surface bound along it) and reports whether `probe` hits anywhere.
    fn segment_hits(
        &self,
        start: DVec3,
        direction: DVec3,
        end: f64,
        can_skip: bool,
        probe: impl Fn(DVec3) -> Probe,
    ) -> bool {
        let horizontal_m = (direction.x * direction.x + direction.z * direction.z).sqrt() * end;
        let guard_m = CREST_GUARD_PER_SPACING * self.spacing_m;
        if horizontal_m <= guard_m || end <= 0.0 {
            return false;
        }
        let step_m = CREST_SAMPLE_STEP_PER_SPACING * self.spacing_m;
        let per_m = end / horizontal_m;
        let mut along_m = guard_m;
        loop {
            let at_m = along_m.min(horizontal_m);
            let advance_m = match probe(start + direction * (at_m * per_m)) {
                Probe::Hit => return true,
                // Clear for `reach` ahead: nothing left to sample if that passes the end.
                Probe::ClearAhead(reach_m) if can_skip => {
                    if at_m + reach_m >= horizontal_m {
                        return false;
                    }
                    reach_m.max(step_m)
                }
                _ => step_m,
            };
            if at_m >= horizontal_m {
                return false;
            }
            along_m = at_m + advance_m;
        }
    }
}

/// One sample of the crest walk.
enum Probe {
    /// The path crosses the surface here.
    Hit,
    /// Not here.
    Clear,
    /// Not here, nor within this horizontal distance ahead if the path moves away from the
    /// surface.
    ClearAhead(f64),
}

/// The crest check's tiles: per tile of `BLOCK_CELLS x BLOCK_CELLS` cells, the (min, max) vertex
/// height over the 3 x 3 tiles around it, so the bound holds within one tile of any point of the
/// tile. Tiles whose 3 x 3 neighbourhood reaches past the grid hold `[-inf, inf]` (no bound: past
/// the grid the check's surface is the exact one).
#[derive(Debug)]
struct TileLevel {
    ranges: Vec<[f32; 2]>,
    tiles_x: usize,
    tiles_z: usize,
    inverse_size_m: [f64; 2],
    /// The smaller side: how far a bound of this level reaches from any point of its tile.
    reach_m: f64,
}

/// The tiles of `BLOCK_CELLS x BLOCK_CELLS` grid cells; None when the membrane is not the grid
/// its `grid` describes (the crest check then evaluates every sample).
fn tile_level(membrane: &Membrane) -> Option<TileLevel> {
    let grid = membrane.grid;
    let (cx, cz) = (grid.cells_x as usize, grid.cells_z as usize);
    if cx == 0 || cz == 0 || membrane.positions.len() != (cx + 1) * (cz + 1) {
        return None;
    }
    let (tiles_x, tiles_z) = (cx.div_ceil(BLOCK_CELLS), cz.div_ceil(BLOCK_CELLS));
    let size_m = [
        (grid.max_x - grid.min_x) / cx as f64 * BLOCK_CELLS as f64,
        (grid.max_z - grid.min_z) / cz as f64 * BLOCK_CELLS as f64,
    ];
    let raw = (0..tiles_x * tiles_z)
        .into_par_iter()
        .with_min_len(1024)
        .map(|tile| {
            let (tx, tz) = (tile % tiles_x, tile / tiles_x);
            let mut range = [f32::INFINITY, f32::NEG_INFINITY];
            for iz in tz * BLOCK_CELLS..=((tz + 1) * BLOCK_CELLS).min(cz) {
                for ix in tx * BLOCK_CELLS..=((tx + 1) * BLOCK_CELLS).min(cx) {
                    let y = membrane.positions[iz * (cx + 1) + ix].y;
                    range = [range[0].min(y), range[1].max(y)];
                }
            }
            range
        })
        .collect::<Vec<[f32; 2]>>();
    // Dilate to the 3 x 3 neighbourhood: a bound valid a whole tile around any point of the tile.
    let ranges = (0..tiles_x * tiles_z)
        .into_par_iter()
        .with_min_len(1024)
        .map(|tile| {
            let (tx, tz) = (tile % tiles_x, tile / tiles_x);
            if tx == 0 || tz == 0 || tx + 1 >= tiles_x || tz + 1 >= tiles_z {
                return [f32::NEG_INFINITY, f32::INFINITY];
            }
            let mut range = [f32::INFINITY, f32::NEG_INFINITY];
            for nz in tz - 1..=tz + 1 {
                for nx in tx - 1..=tx + 1 {
                    let r = raw[nz * tiles_x + nx];
                    range = [range[0].min(r[0]), range[1].max(r[1])];
                }
            }
            range
        })
        .collect();
    Some(TileLevel {
        ranges,
        tiles_x,
        tiles_z,
        inverse_size_m: [1.0 / size_m[0], 1.0 / size_m[1]],
        reach_m: size_m[0].min(size_m[1]),
    })
}

/// The membrane's vertex heights on its grid, interpolated bilinearly: the surface of the crest
/// check. Empty (every query None) when the membrane is not the row-major vertex grid its `grid`
/// describes.
#[derive(Debug)]
pub(crate) struct CrestHeights {
    heights: Vec<f64>,
    cells: [usize; 2],
    origin_m: [f64; 2],
    inverse_cell_m: [f64; 2],
    /// Lipschitz bound of the interpolated heights over the grid (m per horizontal m): inside a
    /// cell the bilinear gradient is linear in (u, w), so its components are bounded by the
    /// cell's edge differences; the largest over all cells bounds every straight path.
    pub(crate) slope_bound: f64,
    /// Largest gap between the bilinear heights and either triangle of a cell: a facet of cell
    /// `h00 h10 h01 h11` differs from the bilinear patch by `u w tau` (or `(1-u)(1-w) tau`) with
    /// `tau = h00 + h11 - h10 - h01`, at most `|tau| / 4`.
    pub(crate) facet_gap_bound: f64,
    cell_diagonal_m: f64,
}

impl CrestHeights {
    /// No grid: every query None, no bounds.
    fn empty() -> Self {
        Self {
            heights: Vec::new(),
            cells: [0, 0],
            origin_m: [0.0, 0.0],
            inverse_cell_m: [1.0, 1.0],
            slope_bound: f64::INFINITY,
            facet_gap_bound: f64::INFINITY,
            cell_diagonal_m: f64::INFINITY,
        }
    }

    fn new(membrane: &Membrane) -> Self {
        let grid = membrane.grid;
        let (cx, cz) = (grid.cells_x as usize, grid.cells_z as usize);
        let cell_m = [
            (grid.max_x - grid.min_x) / cx.max(1) as f64,
            (grid.max_z - grid.min_z) / cz.max(1) as f64,
        ];
        let empty = Self::empty();
        if cx == 0
            || cz == 0
            || membrane.positions.len() != (cx + 1) * (cz + 1)
            || !(cell_m[0] > 0.0 && cell_m[1] > 0.0)
        {
            return empty;
        }
        // Interpolating between grid points is only the membrane if the vertices sit on them.
        let on_grid = membrane.positions.par_iter().enumerate().all(|(i, p)| {
            let (ix, iz) = (i % (cx + 1), i / (cx + 1));
            let x = grid.min_x + cell_m[0] * ix as f64;
            let z = grid.min_z + cell_m[1] * iz as f64;
            (p.x as f64 - x).abs() <= 1e-3 * cell_m[0] && (p.z as f64 - z).abs() <= 1e-3 * cell_m[1]
        });
        if !on_grid {
            return empty;
        }
        let heights: Vec<f64> = membrane.positions.iter().map(|p| p.y as f64).collect();
        // Per row of cells: (largest |x-edge difference|, largest |z-edge difference|, largest |tau|).
        let (dx, dz, twist) = (0..cz)
            .into_par_iter()
            .with_min_len(16)
            .map(|iz| {
                let row = &heights[iz * (cx + 1)..(iz + 2) * (cx + 1)];
                let (near, far) = row.split_at(cx + 1);
                let mut m = (0.0_f64, 0.0_f64, 0.0_f64);
                for ix in 0..cx {
                    let (h00, h10, h01, h11) = (near[ix], near[ix + 1], far[ix], far[ix + 1]);
                    m.0 = m.0.max((h10 - h00).abs()).max((h11 - h01).abs());
                    m.1 = m.1.max((h01 - h00).abs()).max((h11 - h10).abs());
                    m.2 = m.2.max((h00 + h11 - h10 - h01).abs());
                }
                m
            })
            .reduce(
                || (0.0, 0.0, 0.0),
                |a, b| (a.0.max(b.0), a.1.max(b.1), a.2.max(b.2)),
            );
        let (gx, gz) = (dx / cell_m[0], dz / cell_m[1]);
        Self {
            heights,
            cells: [cx, cz],
            origin_m: [grid.min_x, grid.min_z],
            inverse_cell_m: [1.0 / cell_m[0], 1.0 / cell_m[1]],
            // Padded for the rounding of the differences and of the interpolation itself.
            slope_bound: (gx * gx + gz * gz).sqrt() * (1.0 + 1e-9),
            facet_gap_bound: twist * 0.25 * (1.0 + 1e-9),
            cell_diagonal_m: cell_m[0].hypot(cell_m[1]),
        }
    }

    /// Is (x, z) inside the grid (where `height` interpolates)?
    #[inline]
    fn covers(&self, x: f64, z: f64) -> bool {
        let fx = (x - self.origin_m[0]) * self.inverse_cell_m[0];
        let fz = (z - self.origin_m[1]) * self.inverse_cell_m[1];
        !self.heights.is_empty()
            && fx >= 0.0
            && fz >= 0.0
            && fx <= self.cells[0] as f64
            && fz <= self.cells[1] as f64
    }

    /// Bilinear height at (x, z); None outside the grid (or without one).
    #[inline]
    fn height(&self, x: f64, z: f64) -> Option<f64> {
        let fx = (x - self.origin_m[0]) * self.inverse_cell_m[0];
        let fz = (z - self.origin_m[1]) * self.inverse_cell_m[1];
        let [cx, cz] = self.cells;
        if !(fx >= 0.0 && fz >= 0.0 && fx <= cx as f64 && fz <= cz as f64)
            || self.heights.is_empty()
        {
            return None;
        }
        let (ix, iz) = ((fx as usize).min(cx - 1), (fz as usize).min(cz - 1));
        let (u, w) = (fx - ix as f64, fz - iz as f64);
        let row = iz * (cx + 1) + ix;
        let h = &self.heights;
        let near = h[row] + u * (h[row + 1] - h[row]);
        let far = h[row + cx + 1] + u * (h[row + cx + 2] - h[row + cx + 1]);
        Some(near + w * (far - near))
    }
}

/// Twice the largest gap between the faceted membrane (or the crest check's interpolated heights)
/// and the exact surface, sampled at facet centroids and edge midpoints of at most ~2,000 facets
/// (evenly strided), plus rounding: the height tolerance of the crest check. Twice, so that it
/// also covers the distance between the facets (where sight points lie) and the interpolated
/// heights (the check's surface): both are within the gap of the exact surface.
fn faceting_tolerance(
    membrane: &Membrane,
    surface: &dyn HeightField,
    crest_heights: &CrestHeights,
) -> f64 {
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
                .map(|s| {
                    let exact = surface.height(s.x, s.z);
                    // The crest check's interpolated height must be as close to the exact one.
                    let interpolated = crest_heights.height(s.x, s.z).unwrap_or(exact);
                    (s.y - exact).abs().max((interpolated - exact).abs())
                })
                .fold(0.0, f64::max)
        })
        .reduce(|| 0.0, f64::max);
    let scale = membrane
        .positions
        .iter()
        .fold(1.0_f64, |m, p| m.max(p.abs().max_element() as f64));
    2.0 * gap + 1e-6 * scale
}
