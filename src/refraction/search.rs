//! The sight-facet search: per frame, the refraction cells of every membrane facet and a search
//! structure over them; per query point, EVERY image (facet, ray parameter, barycentrics, sight
//! point), merged where sight points coincide and with crest-blocked paths rejected.
//!
//! Receives the membrane, the exact surface, the optical setup and the height range of the query
//! points; returns a [`RefractionField`] answering [`RefractionField::images`] (accelerated) and
//! [`RefractionField::images_brute_force`] (every cell tested: the oracle). Both run the same f64
//! containment test on the cells they consider and the same merge and crest check afterwards; the
//! accelerated search only skips cells that provably cannot contain the point, so the two return
//! identical image sets.
//!
//! # The acceleration structure
//! For a ray going down (`T.y < 0`) the point at height y has horizontal position
//! `F_i(y) = A_i + y B_i` with `B_i = T.xz / T.y`, `A_i = P.xz - P.y B_i`: linear in y. A point of an
//! equal-t cell at height y is `sum b_j Q_j(t)` with `Q_j(t)` on ray j at height `y_j(t)`, so its
//! horizontal position is `sum b_j F_j(y) + sum b_j (y_j(t) - y) B_j`: inside the footprint triangle
//! `F_0 F_1 F_2 (y)` grown by `Delta * max|B_j - B|` for any common B (the `y_j(t) - y` average to
//! zero with the weights `b_j`), where `Delta` bounds how far the rays' heights at one t differ from
//! y (the facet's height span plus the spread of the `T.y`, times the largest t that can reach
//! height y). Membrane facets are grouped in blocks of `BLOCK_CELLS x BLOCK_CELLS` grid cells;
//! each block keeps boxes of its `A` and `B` and the `Delta` ingredients. `query_y_range` is cut in
//! depth slabs; per slab a uniform 2-D grid (CSR, counting sort, slabs built in parallel) lists the
//! blocks whose footprint over the slab can cover each bin. A query visits one bin, re-tests each
//! listed block's box at its exact height (in a form without divisions, `BlockQuery`), tests each
//! facet's footprint triangle grown by the block's `Delta` times the facet's own `B` spread (f32,
//! padded for rounding; the footprint lines of a block's facets are stored in structure-of-arrays
//! chunks of eight, `LaneChunk`, tested together) and runs the f64 cubic only on the survivors.
//! The crest check afterwards skips the walk under water when a slope bound proves it clear.
//! Slabs are a few blocks of footprint slide thick: a block listed in a bin but not covering the
//! point at its height costs one box test, far less than the build pass each extra slab costs. Facets with a ray that does not go
//! down steeply enough (`T.y > -MIN_DESCENT`: extrapolated or near-grazing) are always tested.
//! Thesis cells use a different geometry with no cheap bound here: in [`CellMode::Thesis`] the
//! accelerated search tests every cell (it exists to reproduce the thesis's tables, not for speed).

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::cells::{equal_t_containments, thesis_containment, Cell, CONTAINMENT_EPS};
use super::rays::{refraction_rays, RefractionRay};
use crate::water::{HeightField, Membrane};

/// Which containment test defines a cell (ALGORITHM §5.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellMode {
    /// Equal-t cells: no gaps, no overlaps. The default.
    #[default]
    EqualT,
    /// The thesis's per-facet plane test, kept to reproduce its tables.
    Thesis,
}

/// The optical setup of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefractionSetup {
    pub eye: Vec3,
    /// Index of refraction on the eye's side (air) and on the far side (water).
    pub n_above: f32,
    pub n_below: f32,
    pub cell_mode: CellMode,
}

/// One image of a point: the facet it is seen through and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Image {
    /// Index into `Membrane::triangles`.
    pub facet: u32,
    /// Ray parameter of the cell cross-section through the point.
    pub t: f32,
    /// Barycentrics of the point in that cross-section (= of the sight point in the facet).
    pub barycentric: [f32; 3],
    /// `S = b0 P0 + b1 P1 + b2 P2` on the facet.
    pub sight_point: Vec3,
    /// Any of the facet's three refraction rays is extrapolated (back-facing or TIR).
    pub extrapolated: bool,
}

/// Two images are one when their sight points are closer than this fraction of the longer facet's
/// longest edge. Duplicates come from the containment slack (`CONTAINMENT_EPS = 1e-4` of a facet)
/// on shared faces, edges and rays, so they lie ~1e-4 facets apart; distinct images of a
/// convergence zone are seen through different parts of the surface, typically facets apart.
pub const MERGE_DISTANCE_PER_FACET_SIZE: f32 = 1e-3;

/// Crest check: sample step along a path, as a fraction of the membrane grid spacing. The membrane
/// does not resolve features narrower than its spacing, so neither does this check.
pub const CREST_SAMPLE_STEP_PER_SPACING: f64 = 0.5;
/// Crest check: samples closer to the sight point than this fraction of the spacing (horizontally)
/// are skipped: there the faceted surface the sight point lies on and the check's surface differ by
/// the faceting error, which says nothing about a crest.
pub const CREST_GUARD_PER_SPACING: f64 = 0.5;

/// Facets are grouped in blocks of this many grid cells on a side for the accelerated search.
const BLOCK_CELLS: usize = 2;
/// Facets a block holds at most: two per cell.
const BLOCK_FACETS: usize = 2 * BLOCK_CELLS * BLOCK_CELLS;
/// Lane chunks a block holds at most.
const BLOCK_CHUNKS: usize = BLOCK_FACETS.div_ceil(LANES);
/// Rays descending less steeply than this (`T.y > -MIN_DESCENT`) get no footprint bound.
const MIN_DESCENT: f32 = 0.05;
/// How many blocks a block's footprint may slide across one depth slab.
const SLAB_SLIDE_BLOCKS: f32 = 4.0;
/// At most this many depth slabs.
const MAX_SLABS: usize = 96;

/// Per-vertex footprint line `F(y) = A + y B` (x, z components).
#[derive(Clone, Copy, Debug, Default)]
struct Footprint {
    a: Vec2,
    b: Vec2,
}

/// A regular facet's three footprint lines and the spread of their `B` (see
/// [`growth_radius_from`]).
#[derive(Clone, Copy, Debug)]
struct FacetFootprint {
    lines: [Footprint; 3],
    b_deviation: f32,
}

/// Facets tested together by [`lanes_may_contain`]: the lanes of one chunk.
const LANES: usize = 8;

/// Up to [`LANES`] facets of one block in structure-of-arrays form, so the footprint test of all
/// of them compiles to a few vector instructions. Unused lanes hold NaN footprints (they never
/// pass: every comparison with NaN is false) and facet `u32::MAX`.
#[derive(Clone, Copy, Debug)]
struct LaneChunk {
    /// Per corner k: `A.x`, `A.z`, `B.x`, `B.z` of each lane's footprint line k.
    ax: [[f32; LANES]; 3],
    az: [[f32; LANES]; 3],
    bx: [[f32; LANES]; 3],
    bz: [[f32; LANES]; 3],
    /// Per lane: the spread of the facet's three `B` (see [`FacetFootprint::b_deviation`]).
    b_deviation: [f32; LANES],
    facet: [u32; LANES],
}

impl LaneChunk {
    fn new(facets: impl IntoIterator<Item = (u32, FacetFootprint)>) -> Self {
        let mut chunk = Self {
            ax: [[f32::NAN; LANES]; 3],
            az: [[f32::NAN; LANES]; 3],
            bx: [[f32::NAN; LANES]; 3],
            bz: [[f32::NAN; LANES]; 3],
            b_deviation: [f32::NAN; LANES],
            facet: [u32::MAX; LANES],
        };
        for (lane, (facet, footprint)) in facets.into_iter().enumerate().take(LANES) {
            for k in 0..3 {
                let line = footprint.lines[k];
                chunk.ax[k][lane] = line.a.x;
                chunk.az[k][lane] = line.a.y;
                chunk.bx[k][lane] = line.b.x;
                chunk.bz[k][lane] = line.b.y;
            }
            chunk.b_deviation[lane] = footprint.b_deviation;
            chunk.facet[lane] = facet;
        }
        chunk
    }
}

/// What a query evaluates of a block: `BlockBound::box_at` (the tests' reference) and
/// [`BlockBound::height_delta`] rearranged so they need no division (the one division is done
/// once, in the build, and padded for its rounding).
#[derive(Clone, Copy, Debug)]
struct BlockQuery {
    a_min: Vec2,
    a_max: Vec2,
    b_min: Vec2,
    b_max: Vec2,
    /// `Delta(y) = delta_base + delta_slope * max(0, reach_top - y)`.
    delta_base: f32,
    delta_slope: f32,
    reach_top: f32,
    b_deviation_max: f32,
    slack: f32,
}

impl BlockQuery {
    fn new(bound: &BlockBound) -> Self {
        let eps = CONTAINMENT_EPS as f32;
        let widen = 1.0 + 8.0 * eps;
        let denominator = bound.min_descent - 6.0 * eps * bound.facet_descent_spread;
        Self {
            a_min: bound.a_min,
            a_max: bound.a_max,
            b_min: bound.b_min,
            b_max: bound.b_max,
            delta_base: bound.facet_height_span * widen * (1.0 + 1e-6),
            // The quotient of `height_delta`, with a few ulps for the reciprocal's rounding.
            delta_slope: bound.facet_descent_spread / denominator * widen * (1.0 + 1e-6),
            reach_top: bound.top_y + 6.0 * eps * bound.facet_height_span,
            b_deviation_max: bound.b_deviation_max,
            slack: bound.slack,
        }
    }

    /// At least [`BlockBound::height_delta`]`(y)`.
    #[inline(always)]
    fn height_delta(&self, y: f32) -> f32 {
        self.delta_base + self.delta_slope * (self.reach_top - y).max(0.0)
    }

    /// Can a cell of the block contain a point at height `y`, horizontal position `v`? The test
    /// of `BlockBound::box_at` (its box, at least as large).
    #[inline(always)]
    fn may_contain(&self, v: Vec2, y: f32, delta: f32) -> bool {
        let (p, q) = (self.b_min * y, self.b_max * y);
        let lo = self.a_min + p.min(q);
        let hi = self.a_max + p.max(q);
        let pad = Vec2::splat(growth_radius_from(delta, self.b_deviation_max) + self.slack)
            + (hi - lo).max(Vec2::ZERO) * (4.0 * CONTAINMENT_EPS as f32 * (1.0 + 1e-6));
        (v.x >= lo.x - pad.x)
            & (v.y >= lo.y - pad.y)
            & (v.x <= hi.x + pad.x)
            & (v.y <= hi.y + pad.y)
    }
}

/// What a block of facets needs for its conservative bound.
#[derive(Clone, Copy, Debug)]
struct BlockBound {
    a_min: Vec2,
    a_max: Vec2,
    b_min: Vec2,
    b_max: Vec2,
    /// Largest |B| (L1 norm, >= Euclidean) over the block's rays.
    b_len_max: f32,
    /// Largest |B - centre of the B box| (L1 norm) over the block's rays.
    b_deviation_max: f32,
    /// Largest height span of one facet.
    facet_height_span: f32,
    /// Largest spread of T.y within one facet.
    facet_descent_spread: f32,
    /// Highest vertex.
    top_y: f32,
    /// Smallest |T.y|.
    min_descent: f32,
    /// Absolute rounding slack for this block's f32 footprints.
    slack: f32,
    /// How many regular facets the block holds.
    facets: u32,
}

impl BlockBound {
    fn empty() -> Self {
        Self {
            facets: 0,
            a_min: Vec2::splat(f32::INFINITY),
            a_max: Vec2::splat(f32::NEG_INFINITY),
            b_min: Vec2::splat(f32::INFINITY),
            b_max: Vec2::splat(f32::NEG_INFINITY),
            b_len_max: 0.0,
            b_deviation_max: 0.0,
            facet_height_span: 0.0,
            facet_descent_spread: 0.0,
            top_y: f32::NEG_INFINITY,
            min_descent: f32::INFINITY,
            slack: 0.0,
        }
    }

    /// How far the rays' heights at one ray parameter may differ from a point's height `y` in any of
    /// the block's cells (`Delta`), times how far the rays' `B` may differ from a common `B`: the
    /// radius by which footprint triangles must grow. (The common part drops out: with
    /// `delta_j = y_j(t) - y`, `sum b_j delta_j = 0`, so `sum b_j delta_j B_j = sum b_j delta_j (B_j - B)`
    /// for any fixed B; the block's B-box centre is used.)
    fn growth_radius(&self, y: f32) -> f32 {
        growth_radius_from(self.height_delta(y), self.b_deviation_max)
    }

    /// `Delta` at height `y` for every cell of the block (with the barycentric slack).
    #[inline(always)]
    fn height_delta(&self, y: f32) -> f32 {
        let eps = CONTAINMENT_EPS as f32;
        let reach_m = (self.top_y - y + 6.0 * eps * self.facet_height_span).max(0.0);
        let t_max = reach_m / (self.min_descent - 6.0 * eps * self.facet_descent_spread);
        (self.facet_height_span + self.facet_descent_spread * t_max) * (1.0 + 8.0 * eps)
    }

    /// The reference for [`BlockQuery::may_contain`] (tests).
    /// [`Self::box_between`]`(y, y)` with the duplicate products dropped: the same values (min and
    /// max over the same set), fewer operations on the query path.
    #[cfg(test)]
    fn box_at(&self, y: f32) -> (Vec2, Vec2) {
        let (p, q) = (self.b_min * y, self.b_max * y);
        let mut lo = self.a_min + Vec2::splat(f32::INFINITY).min(p).min(q);
        let mut hi = self.a_max + Vec2::splat(f32::NEG_INFINITY).max(p).max(q);
        let extent = (hi - lo).max(Vec2::ZERO);
        let pad = Vec2::splat(self.growth_radius(y) + self.slack)
            + extent * (4.0 * CONTAINMENT_EPS as f32);
        lo -= pad;
        hi += pad;
        (lo, hi)
    }

    /// Conservative horizontal box of every cell point of the block with height in `[y_low, y_high]`.
    fn box_between(&self, y_low: f32, y_high: f32) -> (Vec2, Vec2) {
        let products = [
            self.b_min * y_low,
            self.b_min * y_high,
            self.b_max * y_low,
            self.b_max * y_high,
        ];
        let low = products
            .iter()
            .fold(Vec2::splat(f32::INFINITY), |m, p| m.min(*p));
        let high = products
            .iter()
            .fold(Vec2::splat(f32::NEG_INFINITY), |m, p| m.max(*p));
        let mut lo = self.a_min + low;
        let mut hi = self.a_max + high;
        let extent = (hi - lo).max(Vec2::ZERO);
        let pad = Vec2::splat(self.growth_radius(y_low) + self.slack)
            + extent * (4.0 * CONTAINMENT_EPS as f32);
        lo -= pad;
        hi += pad;
        (lo, hi)
    }
}

/// One depth slab's 2-D grid of blocks (CSR).
#[derive(Debug)]
struct Slab {
    origin: Vec2,
    inverse_bin_m: f32,
    bins_x: usize,
    bins_z: usize,
    bin_starts: Vec<u32>,
    blocks: Vec<u32>,
}

impl Slab {
    /// The blocks listed in the bin holding horizontal position `v` (none outside the grid).
    #[inline(always)]
    fn entries_at(&self, v: Vec2) -> &[u32] {
        let bx = (v.x - self.origin.x) * self.inverse_bin_m;
        let bz = (v.y - self.origin.y) * self.inverse_bin_m;
        // Truncation is the floor for the non-negative values that pass (NaN fails), without
        // the libm call `floor` is on the baseline x86-64 target.
        if !(bx >= 0.0 && bz >= 0.0 && (bx as usize) < self.bins_x && (bz as usize) < self.bins_z) {
            return &[];
        }
        let bin = bz as usize * self.bins_x + bx as usize;
        &self.blocks[self.bin_starts[bin] as usize..self.bin_starts[bin + 1] as usize]
    }
}

/// The refraction cells of one frame and the structure that searches them.
pub struct RefractionField<'a> {
    pub membrane: &'a Membrane,
    pub surface: &'a dyn HeightField,
    pub setup: RefractionSetup,
    /// One ray per membrane vertex.
    pub rays: Vec<RefractionRay>,
    /// Per facet: any of its rays is extrapolated.
    pub facet_extrapolated: Vec<bool>,
    footprints: Vec<Footprint>,
    /// The regular facets of each block with their footprint lines, in chunks of [`LANES`]
    /// (ascending facet index, unused lanes NaN), so the hot loop reads one contiguous run per
    /// block instead of chasing triangle and vertex indices.
    block_chunks: Vec<[LaneChunk; BLOCK_CHUNKS]>,
    block_bounds: Vec<BlockBound>,
    block_queries: Vec<BlockQuery>,
    /// Facets with a ray that gets no footprint bound: always tested.
    unbounded_facets: Vec<u32>,
    slab_y_low: f32,
    slab_thickness_m: f32,
    slabs: Vec<Slab>,
    /// Absolute f32 rounding slack for per-facet footprint tests.
    footprint_slack: f32,
    /// Crest check parameters: grid spacing, faceting tolerance, surface height range.
    spacing_m: f64,
    crest_tolerance_m: f64,
    surface_y_min: f64,
    surface_y_max: f64,
    /// Crest check prefilter ([`TileLevel`]).
    tiles: Option<TileLevel>,
    /// The height the crest check compares against (see [`CrestHeights`]).
    crest_heights: CrestHeights,
}

impl<'a> RefractionField<'a> {
    /// Builds rays, cells and the search structure for query points whose heights lie in
    /// `query_y_range` (min, max) — points outside it may be missed by `images` (not by brute force).
    /// (Here they are not missed either: `images` falls back to testing every cell for them.)
    pub fn build(
        membrane: &'a Membrane,
        surface: &'a dyn HeightField,
        setup: RefractionSetup,
        query_y_range: (f32, f32),
    ) -> Self {
        Self::build_with(membrane, surface, setup, Some(query_y_range))
    }

    /// Rays and cells only, no search structure: what the brute-force oracle needs (`images` then
    /// tests every cell too). For benchmarks comparing the two.
    pub fn build_unaccelerated(
        membrane: &'a Membrane,
        surface: &'a dyn HeightField,
        setup: RefractionSetup,
    ) -> Self {
        Self::build_with(membrane, surface, setup, None)
    }

    fn build_with(
        membrane: &'a Membrane,
        surface: &'a dyn HeightField,
        setup: RefractionSetup,
        query_y_range: Option<(f32, f32)>,
    ) -> Self {
        let rays = refraction_rays(membrane, setup.eye, setup.n_above, setup.n_below);
        let facet_extrapolated: Vec<bool> = membrane
            .triangles
            .par_iter()
            .with_min_len(4096)
            .map(|tri| {
                tri.iter()
                    .any(|&i| rays[i as usize].extrapolation.is_extrapolated())
            })
            .collect();
        let footprints: Vec<Footprint> = rays
            .par_iter()
            .with_min_len(4096)
            .map(|ray| {
                let t = ray.direction;
                if t.y <= -MIN_DESCENT {
                    let b = Vec2::new(t.x / t.y, t.z / t.y);
                    let a = Vec2::new(ray.origin.x, ray.origin.z) - ray.origin.y * b;
                    Footprint { a, b }
                } else {
                    Footprint {
                        a: Vec2::splat(f32::NAN),
                        b: Vec2::splat(f32::NAN),
                    }
                }
            })
            .collect();
        let grid = membrane.grid;
        let spacing_m = ((grid.max_x - grid.min_x) / grid.cells_x.max(1) as f64)
            .min((grid.max_z - grid.min_z) / grid.cells_z.max(1) as f64)
            .max(1e-9);
        let mut field = Self {
            membrane,
            surface,
            setup,
            rays,
            facet_extrapolated,
            footprints,
            block_chunks: Vec::new(),
            block_bounds: Vec::new(),
            block_queries: Vec::new(),
            unbounded_facets: Vec::new(),
            slab_y_low: 0.0,
            slab_thickness_m: 1.0,
            slabs: Vec::new(),
            footprint_slack: 0.0,
            tiles: None,
            spacing_m,
            crest_tolerance_m: 0.0,
            crest_heights: CrestHeights::empty(),
            surface_y_min: 0.0,
            surface_y_max: 0.0,
        };
        // The crest check's data and the search structure need nothing of each other: built side
        // by side, so the sequential parts of one overlap the other.
        let (crest, ()) = rayon::join(
            || {
                let (y_min, y_max) = membrane
                    .positions
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p.y as f64), hi.max(p.y as f64))
                    });
                let crest_heights = CrestHeights::new(membrane);
                let tolerance_m = faceting_tolerance(membrane, surface, &crest_heights);
                (
                    y_min,
                    y_max,
                    crest_heights,
                    tolerance_m,
                    tile_level(membrane),
                )
            },
            || {
                if let (CellMode::EqualT, Some(range)) = (setup.cell_mode, query_y_range) {
                    let coordinate_scale = membrane
                        .positions
                        .iter()
                        .fold(1.0_f32, |m, p| m.max(p.abs().max_element()))
                        .max(range.0.abs())
                        .max(range.1.abs());
                    field.build_blocks(coordinate_scale);
                    field.build_slabs(range);
                }
            },
        );
        let (y_min, y_max, crest_heights, tolerance_m, tiles) = crest;
        field.surface_y_min = if y_min.is_finite() { y_min } else { 0.0 };
        field.surface_y_max = if y_max.is_finite() { y_max } else { 0.0 };
        field.crest_heights = crest_heights;
        field.crest_tolerance_m = tolerance_m;
        field.tiles = tiles;
        field
    }

    /// Groups regular facets into blocks and computes each block's bound and lane chunks, one
    /// block per task: a block's facets follow from the membrane's layout (cell `c` owns facets
    /// `2c` and `2c + 1`, see [`Membrane`]), so no facet has to be sorted into its block first.
    fn build_blocks(&mut self, coordinate_scale: f32) {
        let grid = self.membrane.grid;
        let (cells_x, cells_z) = (grid.cells_x as usize, grid.cells_z as usize);
        let blocks_x = cells_x.div_ceil(BLOCK_CELLS).max(1);
        let blocks_z = cells_z.div_ceil(BLOCK_CELLS).max(1);
        let block_count = blocks_x * blocks_z;
        let footprints = &self.footprints;
        let triangles = &self.membrane.triangles;
        let rays = &self.rays;
        // Facets past the grid's (none from `build_membrane`) belong to no block: always tested.
        let grid_facets = (2 * cells_x * cells_z).min(triangles.len());
        let bounded = |facet: usize| {
            triangles[facet]
                .iter()
                .all(|&i| footprints[i as usize].b.x.is_finite())
        };
        // The facets of block `b`'s cells, ascending.
        let cells_of = |b: usize| {
            let (bx, bz) = (b % blocks_x, b / blocks_x);
            (bz * BLOCK_CELLS..((bz + 1) * BLOCK_CELLS).min(cells_z)).flat_map(move |iz| {
                (bx * BLOCK_CELLS..((bx + 1) * BLOCK_CELLS).min(cells_x))
                    .flat_map(move |ix| [2 * (iz * cells_x + ix), 2 * (iz * cells_x + ix) + 1])
                    .filter(move |&facet| facet < grid_facets)
            })
        };
        let footprint_of = |facet: u32| {
            let lines = triangles[facet as usize].map(|i| footprints[i as usize]);
            let b_min = lines[0].b.min(lines[1].b).min(lines[2].b);
            let b_max = lines[0].b.max(lines[1].b).max(lines[2].b);
            FacetFootprint {
                lines,
                b_deviation: b_deviation(b_min, b_max),
            }
        };
        let (bounds, chunks): (Vec<BlockBound>, Vec<[LaneChunk; BLOCK_CHUNKS]>) = (0..block_count)
            .into_par_iter()
            .with_min_len(256)
            .map(|b| {
                // The block's regular facets, ascending.
                let mut facets = [0u32; BLOCK_FACETS];
                let mut count = 0;
                for facet in cells_of(b).filter(|&facet| bounded(facet)) {
                    facets[count] = facet as u32;
                    count += 1;
                }
                let facets = &facets[..count];
                let mut bound = BlockBound::empty();
                bound.facets = count as u32;
                for &facet in facets {
                    let tri = triangles[facet as usize];
                    let (mut y_lo, mut y_hi) = (f32::INFINITY, f32::NEG_INFINITY);
                    let (mut d_lo, mut d_hi) = (f32::INFINITY, f32::NEG_INFINITY);
                    for &i in &tri {
                        let fp = footprints[i as usize];
                        let ray = rays[i as usize];
                        bound.a_min = bound.a_min.min(fp.a);
                        bound.a_max = bound.a_max.max(fp.a);
                        bound.b_min = bound.b_min.min(fp.b);
                        bound.b_max = bound.b_max.max(fp.b);
                        bound.b_len_max = bound.b_len_max.max(fp.b.x.abs() + fp.b.y.abs());
                        bound.top_y = bound.top_y.max(ray.origin.y);
                        bound.min_descent = bound.min_descent.min(-ray.direction.y);
                        y_lo = y_lo.min(ray.origin.y);
                        y_hi = y_hi.max(ray.origin.y);
                        d_lo = d_lo.min(ray.direction.y);
                        d_hi = d_hi.max(ray.direction.y);
                    }
                    bound.facet_height_span = bound.facet_height_span.max(y_hi - y_lo);
                    bound.facet_descent_spread = bound.facet_descent_spread.max(d_hi - d_lo);
                }
                bound.b_deviation_max = b_deviation(bound.b_min, bound.b_max);
                // f32 rounding of A, B, F = A + yB and the box arithmetic: a few ulps of the largest
                // magnitude involved, generously.
                let magnitude = coordinate_scale * (1.0 + bound.b_len_max);
                bound.slack = 64.0 * f32::EPSILON * magnitude;
                let chunks = std::array::from_fn(|k| {
                    let lanes = facets.iter().skip(k * LANES).take(LANES);
                    LaneChunk::new(lanes.map(|&facet| (facet, footprint_of(facet))))
                });
                (bound, chunks)
            })
            .unzip();
        let b_len_global = bounds.iter().fold(0.0_f32, |m, b| m.max(b.b_len_max));
        self.footprint_slack = 64.0 * f32::EPSILON * coordinate_scale * (1.0 + b_len_global);
        // The rare unbounded facets, from the blocks that hold fewer facets than their cells;
        // sorted, since a block's facets interleave with the next block's (rows of cells).
        let mut unbounded: Vec<u32> = bounds
            .iter()
            .enumerate()
            .filter(|(b, bound)| bound.facets as usize != cells_of(*b).count())
            .flat_map(|(b, _)| cells_of(b).filter(|&facet| !bounded(facet)))
            .map(|facet| facet as u32)
            .chain(grid_facets as u32..triangles.len() as u32)
            .collect();
        unbounded.sort_unstable();
        self.unbounded_facets = unbounded;
        self.block_chunks = chunks;
        self.block_queries = bounds.iter().map(BlockQuery::new).collect();
        self.block_bounds = bounds;
    }

    /// Cuts the query range into depth slabs and bins the blocks of each (in parallel).
    fn build_slabs(&mut self, query_y_range: (f32, f32)) {
        let (y_low, y_high) = (
            query_y_range.0.min(query_y_range.1),
            query_y_range.0.max(query_y_range.1),
        );
        if !(y_low.is_finite() && y_high.is_finite()) || self.block_bounds.is_empty() {
            return;
        }
        let block_m = (BLOCK_CELLS as f64 * self.spacing_m) as f32;
        let b_len_max = self
            .block_bounds
            .iter()
            .fold(0.0_f32, |m, b| m.max(b.b_len_max));
        // A slab lets a block's footprint slide by thickness * |B|: a few blocks. A query re-tests
        // each listed block's box at its own height (exact, cheap), so thick slabs only add cheap
        // box tests, while each slab costs a pass over every block in the build (measured on the
        // pool: 35 -> 9 slabs cut the entries 2.1 M -> 0.8 M for 12 -> 17 box tests per query).
        let ideal_thickness = SLAB_SLIDE_BLOCKS * block_m / b_len_max.max(1e-3);
        let depth = (y_high - y_low).max(1e-6);
        let slab_count = ((depth / ideal_thickness).ceil() as usize).clamp(1, MAX_SLABS);
        let thickness = depth / slab_count as f32;
        let bounds = &self.block_bounds;
        let slabs: Vec<Slab> = (0..slab_count)
            .into_par_iter()
            .map(|k| {
                let y0 = y_low + k as f32 * thickness;
                // Overlap a little so a point on a slab border is covered by either slab.
                let (lo_y, hi_y) = (y0 - 1e-3 * thickness, y0 + thickness * (1.0 + 1e-3));
                let boxes: Vec<(Vec2, Vec2)> = bounds
                    .iter()
                    .map(|bound| {
                        if bound.facets == 0 {
                            (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY))
                        } else {
                            bound.box_between(lo_y, hi_y)
                        }
                    })
                    .collect();
                // Bins of two blocks: half the entries of one-block bins at the same query speed (measured).
                bin_blocks(&boxes, 2.0 * block_m)
            })
            .collect();
        self.slab_y_low = y_low;
        self.slab_thickness_m = thickness;
        self.slabs = slabs;
    }

    /// Every image of `point` (cleared into `out`), ordered by facet index, coincident sight points
    /// merged, crest-blocked paths rejected. Accelerated.
    pub fn images(&self, point: Vec3, out: &mut Vec<Image>) {
        out.clear();
        if self.setup.cell_mode == CellMode::Thesis || self.slabs.is_empty() {
            self.images_brute_force(point, out);
            return;
        }
        let Some(slab) = self.slab_at(point.y) else {
            // Outside the range the structure was built for: test everything rather than miss.
            self.images_brute_force(point, out);
            return;
        };
        let point64 = point.as_dvec3();
        self.for_each_candidate(slab, point, |facet| {
            self.push_containments(facet, point64, out)
        });
        for &facet in &self.unbounded_facets {
            self.push_containments(facet, point64, out);
        }
        out.sort_unstable_by(|a, b| a.facet.cmp(&b.facet).then(a.t.total_cmp(&b.t)));
        self.merge_and_check_crests(point64, out);
    }

    /// The depth slab holding height `y`; None outside the range the structure was built for.
    fn slab_at(&self, y: f32) -> Option<&Slab> {
        let slab_f = (y - self.slab_y_low) / self.slab_thickness_m;
        (slab_f >= 0.0 && slab_f <= self.slabs.len() as f32)
            .then(|| &self.slabs[(slab_f as usize).min(self.slabs.len() - 1)])
    }

    /// Calls `visit` with every regular facet whose footprint test `point` passes in `slab`'s
    /// bin: the blocks listed there whose box at the point's height holds it, then their facets'
    /// grown footprint triangles, [`LANES`] at a time.
    #[inline(always)]
    fn for_each_candidate(&self, slab: &Slab, point: Vec3, mut visit: impl FnMut(u32)) {
        let v = Vec2::new(point.x, point.z);
        for &block in slab.entries_at(v) {
            let query = &self.block_queries[block as usize];
            let delta = query.height_delta(point.y);
            if !query.may_contain(v, point.y, delta) {
                continue;
            }
            // Every chunk, also those a block at the grid's edge leaves empty: their NaN lanes
            // never pass, and no count has to be loaded.
            for chunk in &self.block_chunks[block as usize] {
                let mut mask = lanes_may_contain(chunk, v, point.y, delta, self.footprint_slack);
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    visit(chunk.facet[lane]);
                }
            }
        }
    }

    /// Size of the search structure: (slabs, bins, block entries, blocks). For tuning.
    pub fn structure_size(&self) -> [usize; 4] {
        [
            self.slabs.len(),
            self.slabs.iter().map(|s| s.bins_x * s.bins_z).sum(),
            self.slabs.iter().map(|s| s.blocks.len()).sum(),
            self.block_bounds.len(),
        ]
    }

    /// Work counters of one accelerated query: (blocks in the bin, blocks passing their box,
    /// facets tested by footprint, facets passing it, unbounded facets). For tuning.
    pub fn search_work(&self, point: Vec3) -> [usize; 5] {
        let mut work = [0, 0, 0, 0, self.unbounded_facets.len()];
        if self.slabs.is_empty() {
            return work;
        }
        let Some(slab) = self.slab_at(point.y) else {
            return work;
        };
        let v = Vec2::new(point.x, point.z);
        let entries = slab.entries_at(v);
        work[0] = entries.len();
        for &block in entries {
            let query = &self.block_queries[block as usize];
            if query.may_contain(v, point.y, query.height_delta(point.y)) {
                work[1] += 1;
                work[2] += self.block_bounds[block as usize].facets as usize;
            }
        }
        self.for_each_candidate(slab, point, |_| work[3] += 1);
        work
    }

    /// The same answer as [`Self::images`], by testing every cell: the test oracle.
    pub fn images_brute_force(&self, point: Vec3, out: &mut Vec<Image>) {
        out.clear();
        let point64 = point.as_dvec3();
        for facet in 0..self.membrane.triangles.len() as u32 {
            self.push_containments(facet, point64, out);
        }
        self.merge_and_check_crests(point64, out);
    }

    /// The membrane's grid spacing (the smaller of the two directions), metres: the finest
    /// feature the membrane resolves.
    pub fn spacing_m(&self) -> f64 {
        self.spacing_m
    }

    /// Heights (min, max) the exact surface stays within: the membrane vertices' range widened
    /// by the crest check's faceting tolerance (the same bound the crest check relies on).
    pub fn surface_height_bounds_m(&self) -> (f64, f64) {
        (
            self.surface_y_min - self.crest_tolerance_m,
            self.surface_y_max + self.crest_tolerance_m,
        )
    }

    /// The cell of one facet.
    #[inline]
    pub fn cell(&self, facet: u32) -> Cell {
        let tri = self.membrane.triangles[facet as usize];
        let r = tri.map(|i| self.rays[i as usize]);
        Cell::new(r.map(|r| r.origin), r.map(|r| r.direction))
    }

    fn push_containments(&self, facet: u32, point: DVec3, out: &mut Vec<Image>) {
        let cell = self.cell(facet);
        let extrapolated = self.facet_extrapolated[facet as usize];
        let mut push = |c: &super::cells::Containment| {
            out.push(Image {
                facet,
                t: c.t as f32,
                barycentric: c.barycentric.map(|b| b as f32),
                sight_point: c.sight_point.as_vec3(),
                extrapolated,
            })
        };
        match self.setup.cell_mode {
            CellMode::EqualT => equal_t_containments(&cell, point)
                .iter()
                .for_each(&mut push),
            CellMode::Thesis => {
                if let Some(c) = thesis_containment(&cell, point) {
                    push(&c)
                }
            }
        }
    }

    fn facet_size_m(&self, facet: u32) -> f32 {
        let p =
            self.membrane.triangles[facet as usize].map(|i| self.membrane.positions[i as usize]);
        (p[1] - p[0])
            .length()
            .max((p[2] - p[1]).length())
            .max((p[0] - p[2]).length())
    }

    /// Drops images whose sight point coincides with an earlier (lower-facet) one, then those whose
    /// path is blocked by a crest. `images` must be sorted by facet.
    fn merge_and_check_crests(&self, point: DVec3, images: &mut Vec<Image>) {
        let mut kept = 0;
        for i in 0..images.len() {
            let candidate = images[i];
            // Most points have one image: nothing to compare it with, no facet size needed.
            let duplicate = kept > 0 && {
                let size = self.facet_size_m(candidate.facet);
                images[..kept].iter().any(|k| {
                    let tolerance =
                        MERGE_DISTANCE_PER_FACET_SIZE * size.max(self.facet_size_m(k.facet));
                    (k.sight_point - candidate.sight_point).length() <= tolerance
                })
            };
            if !duplicate {
                images[kept] = candidate;
                kept += 1;
            }
        }
        images.truncate(kept);
        images.retain(|image| !self.crest_blocks(image.sight_point.as_dvec3(), point));
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
    pub fn crest_blocks(&self, sight_point: DVec3, point: DVec3) -> bool {
        self.crest_blocks_with(sight_point, point, true)
    }

    /// [`Self::crest_blocks`], with the slope proof (`prove`) or walking every segment.
    fn crest_blocks_with(&self, sight_point: DVec3, point: DVec3, prove: bool) -> bool {
        let eye = self.setup.eye.as_dvec3();
        let tolerance = self.crest_tolerance_m;
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
            if x.y < self.crest_height(x.x, x.z) - tolerance {
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
            if x.y > self.crest_height(x.x, x.z) + tolerance {
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
    fn segment_clear_by_slope(&self, start: DVec3, direction: DVec3, end: f64, side: f64) -> bool {
        let heights = &self.crest_heights;
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
        let excess_m = heights.facet_gap_bound + rounding_m - self.crest_tolerance_m;
        // (rise - slope_bound) * guard >= excess, times `horizontal` (>= 0) to avoid dividing.
        side * direction.y * guard_m
            >= heights.slope_bound * guard_m * horizontal + excess_m.max(0.0) * horizontal
    }

    /// The surface height the crest check uses at (x, z): the membrane vertices' bilinear
    /// interpolation inside a grid membrane, the exact surface elsewhere.
    #[inline]
    fn crest_height(&self, x: f64, z: f64) -> f64 {
        self.crest_heights
            .height(x, z)
            .unwrap_or_else(|| self.surface.height(x, z))
    }

    /// How far around `x` (horizontally) the tiles prove the surface clear: the tile reach if
    /// the range of the tile holding `x` passes `clear`.
    #[inline]
    fn clear_reach(&self, x: DVec3, clear: impl Fn([f32; 2]) -> bool) -> Option<f64> {
        let tiles = self.tiles.as_ref()?;
        let grid = self.membrane.grid;
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

/// Can the cell with the footprint lines `lines` (of its facet's three vertices) contain a point at
/// height `y` with horizontal position `v`? Never false for a point the exact test accepts (see
/// the module docs for the bound).
/// The scalar reference of [`lanes_may_contain`] (tests).
#[cfg(test)]
fn footprint_may_contain(lines: &[Footprint; 3], v: Vec2, y: f32, radius: f32) -> bool {
    let f = lines.map(|fp| fp.a + y * fp.b);
    let twice_area = (f[1] - f[0]).perp_dot(f[2] - f[0]);
    let sign = if twice_area >= 0.0 { 1.0 } else { -1.0 };
    let area_slack = CONTAINMENT_EPS as f32 * 1.01 * twice_area.abs();
    for k in 0..3 {
        let (from, to) = (f[(k + 1) % 3], f[(k + 2) % 3]);
        let edge = to - from;
        let side = sign * edge.perp_dot(v - from);
        // An L1 edge length bounds the Euclidean one from above: conservative.
        let margin = area_slack + (edge.x.abs() + edge.y.abs()) * radius;
        if side < -margin {
            return false;
        }
    }
    true
}

/// `footprint_may_contain` (the tests' scalar reference) for every lane of `chunk` at once (bit i
/// of the result: lane i may contain the point), with each lane's radius `growth_radius_from(delta, b_deviation) + slack`.
/// The same arithmetic lane by lane, written without branches so it vectorises; a NaN lane
/// fails every comparison and never passes.
#[inline(always)]
fn lanes_may_contain(chunk: &LaneChunk, v: Vec2, y: f32, delta: f32, slack: f32) -> u32 {
    let area_eps = CONTAINMENT_EPS as f32 * 1.01;
    let mut inside = [false; LANES];
    // Indexing every array by lane (not iterating one of them) is what vectorises.
    #[allow(clippy::needless_range_loop)]
    for lane in 0..LANES {
        let radius = growth_radius_from(delta, chunk.b_deviation[lane]) + slack;
        // Written out, not by `array::map`: that is not always inlined, and a call in this loop
        // keeps it from vectorising (measured: twice the query time).
        let fx = [
            chunk.ax[0][lane] + y * chunk.bx[0][lane],
            chunk.ax[1][lane] + y * chunk.bx[1][lane],
            chunk.ax[2][lane] + y * chunk.bx[2][lane],
        ];
        let fz = [
            chunk.az[0][lane] + y * chunk.bz[0][lane],
            chunk.az[1][lane] + y * chunk.bz[1][lane],
            chunk.az[2][lane] + y * chunk.bz[2][lane],
        ];
        let twice_area = (fx[1] - fx[0]) * (fz[2] - fz[0]) - (fz[1] - fz[0]) * (fx[2] - fx[0]);
        let sign = if twice_area >= 0.0 { 1.0 } else { -1.0 };
        let area_slack = area_eps * twice_area.abs();
        let mut all = true;
        for k in 0..3 {
            let (from, to) = ((k + 1) % 3, (k + 2) % 3);
            let (ex, ez) = (fx[to] - fx[from], fz[to] - fz[from]);
            let side = sign * (ex * (v.y - fz[from]) - ez * (v.x - fx[from]));
            let margin = area_slack + (ex.abs() + ez.abs()) * radius;
            all &= side >= -margin;
        }
        inside[lane] = all;
    }
    inside
        .iter()
        .enumerate()
        .fold(0, |mask, (lane, &is)| mask | ((is as u32) << lane))
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
struct CrestHeights {
    heights: Vec<f64>,
    cells: [usize; 2],
    origin_m: [f64; 2],
    inverse_cell_m: [f64; 2],
    /// Lipschitz bound of the interpolated heights over the grid (m per horizontal m): inside a
    /// cell the bilinear gradient is linear in (u, w), so its components are bounded by the
    /// cell's edge differences; the largest over all cells bounds every straight path.
    slope_bound: f64,
    /// Largest gap between the bilinear heights and either triangle of a cell: a facet of cell
    /// `h00 h10 h01 h11` differs from the bilinear patch by `u w tau` (or `(1-u)(1-w) tau`) with
    /// `tau = h00 + h11 - h10 - h01`, at most `|tau| / 4`.
    facet_gap_bound: f64,
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

/// The growth radius from `Delta` (`height_delta`) and a bound `b_deviation` on how far the rays'
/// `B` lie from a common `B`. For a whole block: its B box. For one facet of a block
/// ([`FacetFootprint::b_deviation`]): its own three `B` around their box centre — the same
/// argument with that centre as the common `B` (any fixed B will do) and the block's `Delta`,
/// which bounds every one of its facets' `Delta`.
#[inline(always)]
fn growth_radius_from(height_delta: f32, b_deviation: f32) -> f32 {
    height_delta * b_deviation * (1.0 + 8.0 * CONTAINMENT_EPS as f32)
}

/// Largest L1 distance of a `B` in the box `[b_min, b_max]` from the box centre: every B in the
/// box is within the half-diagonal of the centre; the rounding of the centre itself is padded.
fn b_deviation(b_min: Vec2, b_max: Vec2) -> f32 {
    let centre = (b_min + b_max) * 0.5;
    let half = (b_max - b_min) * 0.5;
    (half.x + half.y) * (1.0 + 1e-5) + 4.0 * f32::EPSILON * (centre.x.abs() + centre.y.abs())
}

/// Bins block boxes into a uniform grid of `bin_m` bins (CSR by counting sort).
// `!(lo.x <= hi.x)` treats a NaN extent like an empty one; `lo.x > hi.x` would not.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn bin_blocks(boxes: &[(Vec2, Vec2)], bin_m: f32) -> Slab {
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for (l, h) in boxes {
        if l.x <= h.x {
            lo = lo.min(*l);
            hi = hi.max(*h);
        }
    }
    if !(lo.x <= hi.x) {
        return Slab {
            origin: Vec2::ZERO,
            inverse_bin_m: 1.0,
            bins_x: 0,
            bins_z: 0,
            bin_starts: vec![0],
            blocks: Vec::new(),
        };
    }
    // Cap the bin count near the block count: bins far smaller than blocks only duplicate entries.
    let extent = (hi - lo).max(Vec2::splat(1e-6));
    let max_bins = (boxes.len() * 4).max(16) as f32;
    let mut bin = bin_m.max(1e-6);
    while (extent.x / bin).ceil() * (extent.y / bin).ceil() > max_bins {
        bin *= 1.5;
    }
    let inverse_bin_m = 1.0 / bin;
    let bins_x = ((extent.x * inverse_bin_m).floor() as usize + 1).max(1);
    let bins_z = ((extent.y * inverse_bin_m).floor() as usize + 1).max(1);
    let (last_x, last_z) = ((bins_x - 1) as f32, (bins_z - 1) as f32);
    // Bin coordinate of an offset from `lo`: clamped in f32 first (`max` then `min` also turn a
    // NaN into 0), so the truncation to an integer is in range and needs no saturation checks.
    let bin_of = |offset: f32, last: f32| {
        let clamped = (offset * inverse_bin_m).max(0.0).min(last);
        // SAFETY: `clamped` is finite and in [0, last], last < bins <= u32::MAX.
        unsafe { clamped.to_int_unchecked::<u32>() }
    };
    // Each box's bin range, computed once for both passes (u32::MAX: empty box).
    let ranges: Vec<[u32; 4]> = boxes
        .iter()
        .map(|(l, h)| {
            if l.x <= h.x {
                [
                    bin_of(l.x - lo.x, last_x),
                    bin_of(l.y - lo.y, last_z),
                    bin_of(h.x - lo.x, last_x),
                    bin_of(h.y - lo.y, last_z),
                ]
            } else {
                [u32::MAX; 4]
            }
        })
        .collect();
    let mut starts = vec![0u32; bins_x * bins_z + 1];
    for &[x0, z0, x1, z1] in &ranges {
        if x0 != u32::MAX {
            for z in z0 as usize..=z1 as usize {
                for slot in &mut starts[z * bins_x + x0 as usize + 1..=z * bins_x + x1 as usize + 1]
                {
                    *slot += 1;
                }
            }
        }
    }
    for i in 0..bins_x * bins_z {
        starts[i + 1] += starts[i];
    }
    let mut cursor = starts.clone();
    let mut blocks = vec![0u32; starts[bins_x * bins_z] as usize];
    for (b, &[x0, z0, x1, z1]) in ranges.iter().enumerate() {
        if x0 != u32::MAX {
            for z in z0 as usize..=z1 as usize {
                for slot in &mut cursor[z * bins_x + x0 as usize..=z * bins_x + x1 as usize] {
                    blocks[*slot as usize] = b as u32;
                    *slot += 1;
                }
            }
        }
    }
    Slab {
        origin: lo,
        inverse_bin_m,
        bins_x,
        bins_z,
        bin_starts: starts,
        blocks,
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

/// Test helpers: membranes and height fields built from wave sums, shared by the refraction tests.
#[cfg(test)]
pub mod test_support {
    use glam::Vec3;

    use crate::water::{HeightField, Membrane, MembraneGrid};

    /// A sum of sine waves `amplitude * sin(k . (x, z) + phase)`.
    #[derive(Clone, Debug, Default)]
    pub struct Waves {
        /// (amplitude_m, kx, kz, phase)
        pub waves: Vec<(f64, f64, f64, f64)>,
        pub level_m: f64,
    }

    impl HeightField for Waves {
        fn height(&self, x: f64, z: f64) -> f64 {
            self.level_m
                + self
                    .waves
                    .iter()
                    .map(|&(a, kx, kz, ph)| a * (kx * x + kz * z + ph).sin())
                    .sum::<f64>()
        }
        fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
            self.waves
                .iter()
                .fold((0.0, 0.0), |(gx, gz), &(a, kx, kz, ph)| {
                    let c = a * (kx * x + kz * z + ph).cos();
                    (gx + c * kx, gz + c * kz)
                })
        }
    }

    /// A grid membrane over the rectangle, sampled from the height field (analytic normals).
    pub fn membrane_from(surface: &dyn HeightField, grid: MembraneGrid) -> Membrane {
        let (cx, cz) = (grid.cells_x as usize, grid.cells_z as usize);
        let mut positions = Vec::with_capacity((cx + 1) * (cz + 1));
        let mut normals = Vec::with_capacity((cx + 1) * (cz + 1));
        for iz in 0..=cz {
            for ix in 0..=cx {
                let x = grid.min_x + (grid.max_x - grid.min_x) * ix as f64 / cx as f64;
                let z = grid.min_z + (grid.max_z - grid.min_z) * iz as f64 / cz as f64;
                positions.push(Vec3::new(x as f32, surface.height(x, z) as f32, z as f32));
                normals.push(surface.normal(x, z).as_vec3());
            }
        }
        let mut triangles = Vec::with_capacity(2 * cx * cz);
        for iz in 0..cz {
            for ix in 0..cx {
                let v00 = (iz * (cx + 1) + ix) as u32;
                let v10 = v00 + 1;
                let v01 = v00 + cx as u32 + 1;
                let v11 = v01 + 1;
                // Counter-clockwise seen from above (+y).
                triangles.push([v00, v01, v10]);
                triangles.push([v10, v01, v11]);
            }
        }
        Membrane {
            grid,
            positions,
            normals,
            triangles,
        }
    }

    pub fn square_grid(half_m: f64, cells: u32) -> MembraneGrid {
        MembraneGrid {
            min_x: -half_m,
            min_z: -half_m,
            max_x: half_m,
            max_z: half_m,
            cells_x: cells,
            cells_z: cells,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::*;
    use super::*;

    fn setup(eye: Vec3) -> RefractionSetup {
        RefractionSetup {
            eye,
            n_above: 1.0,
            n_below: 1.333,
            cell_mode: CellMode::EqualT,
        }
    }

    /// Small deterministic generator (SplitMix64) so the tests need no extra crate.
    struct Rng(u64);
    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn unit(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
        /// A point with x and z in `[-half_m, half_m]` and y in `y_m` (drawn x, y, z).
        fn point(&mut self, half_m: f64, y_m: (f64, f64)) -> Vec3 {
            let x = self.range(-half_m, half_m);
            let y = self.range(y_m.0, y_m.1);
            Vec3::new(x as f32, y as f32, self.range(-half_m, half_m) as f32)
        }
    }

    fn random_waves(rng: &mut Rng, count: usize, steepness: f64) -> Waves {
        let waves = (0..count)
            .map(|_| {
                let wavelength = rng.range(0.8, 4.0);
                let k = std::f64::consts::TAU / wavelength;
                let angle = rng.range(0.0, std::f64::consts::TAU);
                let amplitude = steepness * rng.range(0.3, 1.0) / k / count as f64;
                (
                    amplitude,
                    k * angle.cos(),
                    k * angle.sin(),
                    rng.range(0.0, 6.3),
                )
            })
            .collect();
        Waves {
            waves,
            level_m: 0.0,
        }
    }

    fn assert_same(field: &RefractionField, point: Vec3, context: &str) -> Vec<Image> {
        let (mut fast, mut slow) = (Vec::new(), Vec::new());
        field.images(point, &mut fast);
        field.images_brute_force(point, &mut slow);
        assert_eq!(fast, slow, "{context}: point {point:?}");
        fast
    }

    #[test]
    fn flat_water_single_image_with_the_exact_sight_point_direction() {
        let surface = Waves::default();
        let membrane = membrane_from(&surface, square_grid(2.0, 16));
        let eye = Vec3::new(-3.0, 2.0, 0.5);
        let field = RefractionField::build(&membrane, &surface, setup(eye), (-2.0, 0.0));
        let point = Vec3::new(0.3, -1.0, 0.2);
        let images = assert_same(&field, point, "flat");
        assert_eq!(images.len(), 1, "{images:?}");
        let exact = crate::refraction::flat::flat_sight_point(
            eye.as_dvec3(),
            point.as_dvec3(),
            0.0,
            1.0,
            1.333,
        );
        // Linear cells on flat water with a curved ray fan: a small but nonzero error.
        assert!(
            (images[0].sight_point.as_dvec3() - exact).length() < 5e-3,
            "{images:?} {exact}"
        );
    }

    #[test]
    fn accelerated_equals_brute_force_on_random_membranes_eyes_and_points() {
        let mut rng = Rng(0x5EED_0001);
        let mut multi_image_points = 0;
        let mut total_images = 0;
        for case in 0..12 {
            let steepness = if case % 3 == 0 { 0.5 } else { 0.15 };
            let surface = random_waves(&mut rng, 1 + case % 4, steepness);
            let membrane = membrane_from(&surface, square_grid(2.0, 12 + (case as u32 % 3) * 4));
            // Eyes from overhead to grazing (elevation down to ~3 degrees).
            let elevation = rng.range(0.05, 1.5);
            let azimuth = rng.range(0.0, std::f64::consts::TAU);
            let distance = rng.range(2.0, 8.0);
            let eye = Vec3::new(
                (distance * elevation.cos() * azimuth.cos()) as f32,
                (distance * elevation.sin()).max(0.3) as f32,
                (distance * elevation.cos() * azimuth.sin()) as f32,
            );
            let field = RefractionField::build(&membrane, &surface, setup(eye), (-2.5, 0.2));
            for _ in 0..300 {
                let p = rng.point(3.0, (-2.5, -0.05));
                let images = assert_same(&field, p, &format!("case {case}"));
                total_images += images.len();
                if images.len() > 1 {
                    multi_image_points += 1;
                }
            }
        }
        assert!(
            total_images > 1000,
            "the random points must mostly be seen: {total_images}"
        );
        let _ = multi_image_points;
    }

    /// Points exactly on bounding rays, on shared faces and edges, at membrane corners: ONE image each
    /// (merged), identical in both searches.
    #[test]
    fn points_on_rays_shared_faces_and_corners_give_one_merged_image() {
        let surface = Waves {
            waves: vec![(0.03, 2.5, 0.7, 0.3), (0.02, -1.1, 3.0, 1.0)],
            level_m: 0.0,
        };
        let membrane = membrane_from(&surface, square_grid(2.0, 16));
        let eye = Vec3::new(-2.5, 2.5, -1.5);
        let field = RefractionField::build(&membrane, &surface, setup(eye), (-2.0, 0.1));
        let mut checked = 0;
        for (facet, tri) in membrane.triangles.iter().enumerate().step_by(7) {
            let cell = field.cell(facet as u32);
            for &t in &[0.3, 1.2] {
                let q = cell.cross_section(t);
                // On a bounding ray, on the middle of each face, and inside.
                let candidates = [
                    q[0],
                    (q[0] + q[1]) * 0.5,
                    (q[1] + q[2]) * 0.5,
                    (q[2] + q[0]) * 0.5,
                    (q[0] + q[1] + q[2]) / 3.0,
                ];
                for point in candidates {
                    let point = point.as_vec3();
                    if point.y > -0.05 {
                        continue;
                    }
                    let images = assert_same(&field, point, "on a face");
                    // These points are on the facet's cell by construction; interior vertices of
                    // the grid see them once; a second image would be a convergence zone, which
                    // this gentle wave does not have.
                    assert_eq!(images.len(), 1, "facet {facet} {tri:?} t {t}: {images:?}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 200);
        // Membrane corners: points straight down the corner rays.
        for &corner in &[0usize, 16, 17 * 16, 17 * 17 - 1] {
            let ray = field.rays[corner];
            let point = ray.origin + ray.direction * 0.7;
            let images = assert_same(&field, point, "corner");
            assert_eq!(images.len(), 1, "corner {corner}: {images:?}");
        }
    }

    /// A steep crest focuses rays: some points lie in several cells (a convergence zone).
    #[test]
    fn convergence_zones_under_a_steep_crest_give_several_images() {
        let surface = Waves {
            waves: vec![(0.08, 6.0, 0.0, 0.0)],
            level_m: 0.0,
        };
        let membrane = membrane_from(&surface, square_grid(2.0, 64));
        let eye = Vec3::new(-1.0, 3.0, 0.1);
        let field = RefractionField::build(&membrane, &surface, setup(eye), (-3.0, 0.2));
        let mut rng = Rng(77);
        let mut several = 0;
        for _ in 0..4000 {
            let p = Vec3::new(
                rng.range(-1.5, 1.5) as f32,
                rng.range(-3.0, -0.2) as f32,
                rng.range(-1.0, 1.0) as f32,
            );
            let images = assert_same(&field, p, "crest");
            if images.len() > 1 {
                several += 1;
                // Distinct images are seen through clearly different sight points.
                assert!((images[0].sight_point - images[1].sight_point).length() > 1e-3);
            }
        }
        assert!(
            several > 10,
            "a steep crest must make convergence zones: {several}"
        );
    }

    /// A point whose only path passes under a crest in front of it is rejected.
    #[test]
    fn crest_blocked_paths_are_rejected() {
        // A single tall crest at x = 0 (a Gaussian ridge), eye low on the -x side.
        struct Ridge;
        impl HeightField for Ridge {
            fn height(&self, x: f64, _z: f64) -> f64 {
                0.4 * (-(x * x) / 0.02).exp()
            }
            fn gradient(&self, x: f64, _z: f64) -> (f64, f64) {
                (-0.4 * 2.0 * x / 0.02 * (-(x * x) / 0.02).exp(), 0.0)
            }
        }
        // 128 cells resolve the ridge well enough that the crest tolerance (twice the largest
        // faceting gap, ~1 cm here) is below the 2 cm by which the oracle below calls a path blocked.
        let membrane = membrane_from(&Ridge, square_grid(2.0, 128));
        let eye = Vec3::new(-3.0, 0.5, 0.0);
        let field = RefractionField::build(&membrane, &Ridge, setup(eye), (-2.0, 0.5));
        // Directly: a sight point behind the ridge, seen from the low eye, is blocked.
        let behind = DVec3::new(0.8, 0.0, 0.0);
        assert!(field.crest_blocks(behind, DVec3::new(1.0, -0.5, 0.0)));
        // In front of the ridge: not blocked.
        assert!(!field.crest_blocks(DVec3::new(-0.8, 0.0, 0.0), DVec3::new(-0.6, -0.5, 0.0)));
        // Points below, behind the ridge, whose every raw containment is seen through a facet
        // behind the crest (so the only cell paths pass through it): all rejected. Such points
        // must exist in this setup, and a point in front of the ridge must stay visible.
        let mut only_blocked_paths = 0;
        for ix in 0..15 {
            for iy in 0..8 {
                let point = Vec3::new(0.4 + 0.1 * ix as f32, -0.05 - 0.1 * iy as f32, 0.0);
                let mut raw = Vec::new();
                for facet in 0..membrane.triangles.len() as u32 {
                    field.push_containments(facet, point.as_dvec3(), &mut raw);
                }
                let images = assert_same(&field, point, "behind the ridge");
                // An independent oracle of blocking for this ridge: the sight ray from the eye
                // passes under the ridge's top, or the path in the water rises 2 cm above the
                // surface somewhere behind the top (sampled every millimetre).
                let blocked_by_ridge = |image: &Image| {
                    let s = image.sight_point.as_dvec3();
                    let e = eye.as_dvec3();
                    let under_top = s.x > 0.0 && {
                        let f = (0.0 - s.x) / (e.x - s.x);
                        s.y + f * (e.y - s.y) < 0.4 - 0.02
                    };
                    let v = point.as_dvec3();
                    let exits = (0..=1000).any(|k| {
                        let x = s + (v - s) * (k as f64 / 1000.0);
                        x.x > 0.05 && x.y > Ridge.height(x.x, x.z) + 0.02
                    });
                    under_top || exits
                };
                if !raw.is_empty() && raw.iter().all(blocked_by_ridge) {
                    assert!(images.is_empty(), "{point}: {images:?}");
                    only_blocked_paths += 1;
                }
            }
        }
        assert!(
            only_blocked_paths > 0,
            "the setup must have points seen only past the crest"
        );
        assert!(!assert_same(&field, Vec3::new(-1.5, -0.3, 0.0), "in front").is_empty());
    }

    /// The slope proof only skips walks that would find nothing: on random membranes (steep ones
    /// included), eyes from grazing to overhead and paths through random points, the crest check
    /// with the proof gives the walk's answer for every path, and the proof does skip walks.
    #[test]
    fn slope_proof_never_changes_the_crest_answer() {
        let mut rng = Rng(0x5EED_C2E5);
        let (mut paths, mut blocked, mut proven) = (0, 0, 0);
        for case in 0..12 {
            let steepness = [0.1, 0.4, 0.9][case % 3];
            let surface = random_waves(&mut rng, 1 + case % 4, steepness);
            let membrane = membrane_from(&surface, square_grid(2.0, 16 + 8 * (case as u32 % 3)));
            let elevation = rng.range(0.03, 1.5);
            let azimuth = rng.range(0.0, std::f64::consts::TAU);
            let eye = DVec3::new(
                3.0 * elevation.cos() * azimuth.cos(),
                (3.0 * elevation.sin()).max(0.2),
                3.0 * elevation.cos() * azimuth.sin(),
            );
            let field =
                RefractionField::build(&membrane, &surface, setup(eye.as_vec3()), (-2.0, 0.2));
            for _ in 0..400 {
                // A sight point on a random facet, a point anywhere below.
                let facet = (rng.unit() * membrane.triangles.len() as f64) as usize;
                let corners = membrane.triangles[facet].map(|i| membrane.positions[i as usize]);
                let (u, w) = (rng.unit(), rng.unit());
                let (u, w) = if u + w > 1.0 {
                    (1.0 - u, 1.0 - w)
                } else {
                    (u, w)
                };
                let sight = (corners[0].as_dvec3() * (1.0 - u - w)
                    + corners[1].as_dvec3() * u
                    + corners[2].as_dvec3() * w)
                    .as_vec3()
                    .as_dvec3();
                let point = DVec3::new(
                    rng.range(-2.5, 2.5),
                    rng.range(-2.0, -0.01),
                    rng.range(-2.5, 2.5),
                );
                let walked = field.crest_blocks_with(sight, point, false);
                assert_eq!(
                    field.crest_blocks(sight, point),
                    walked,
                    "case {case}: sight point {sight}, point {point}"
                );
                paths += 1;
                blocked += walked as usize;
                proven += field.segment_clear_by_slope(sight, point - sight, 1.0, -1.0) as usize
                    + field.segment_clear_by_slope(sight, eye - sight, 1.0, 1.0) as usize;
            }
        }
        assert!(
            blocked > 0 && blocked < paths,
            "{blocked} of {paths} blocked"
        );
        assert!(proven > paths / 4, "{proven} proofs over {paths} paths");
    }

    /// The lane test is the scalar footprint test, lane for lane, on random footprints (all
    /// orientations, thin and degenerate ones included), points, heights and radii.
    #[test]
    fn lane_footprint_test_matches_the_scalar_one() {
        let mut rng = Rng(0x5EED_1A4E);
        let mut passed = 0;
        for _ in 0..4000 {
            let lanes: Vec<(u32, FacetFootprint)> = (0..1 + (rng.unit() * 8.0) as usize)
                .map(|i| {
                    let base = Vec2::new(rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32);
                    let lines = [0, 1, 2].map(|_| Footprint {
                        a: base
                            + Vec2::new(rng.range(-0.1, 0.1) as f32, rng.range(-0.1, 0.1) as f32),
                        b: Vec2::new(rng.range(-1.0, 1.0) as f32, rng.range(-1.0, 1.0) as f32),
                    });
                    let lines = if i == 3 { [lines[0]; 3] } else { lines };
                    let b_min = lines[0].b.min(lines[1].b).min(lines[2].b);
                    let b_max = lines[0].b.max(lines[1].b).max(lines[2].b);
                    let footprint = FacetFootprint {
                        lines,
                        b_deviation: b_deviation(b_min, b_max),
                    };
                    (i as u32, footprint)
                })
                .collect();
            let chunk = LaneChunk::new(lanes.iter().copied());
            let y = rng.range(-2.0, 0.0) as f32;
            let v = Vec2::new(rng.range(-1.5, 1.5) as f32, rng.range(-1.5, 1.5) as f32);
            let (delta, slack) = (rng.range(0.0, 0.05) as f32, 1e-6);
            let mask = lanes_may_contain(&chunk, v, y, delta, slack);
            for lane in 0..LANES {
                let expected = lanes.get(lane).is_some_and(|(_, f)| {
                    let radius = growth_radius_from(delta, f.b_deviation) + slack;
                    footprint_may_contain(&f.lines, v, y, radius)
                });
                assert_eq!(mask >> lane & 1 == 1, expected, "lane {lane} of {lanes:?}");
                passed += expected as usize;
            }
        }
        assert!(passed > 100, "{passed}");
    }

    /// A block's query box holds its reference box (`BlockBound::box_at`) at every height: the
    /// corners of the reference box pass `BlockQuery::may_contain`.
    #[test]
    fn block_query_box_holds_the_reference_box() {
        let mut rng = Rng(0x5EED_B0C5);
        for _ in 0..20_000 {
            let a = Vec2::new(rng.range(-20.0, 20.0) as f32, rng.range(-20.0, 20.0) as f32);
            let b = Vec2::new(rng.range(-3.0, 3.0) as f32, rng.range(-3.0, 3.0) as f32);
            let (da, db) = (rng.range(0.0, 0.3) as f32, rng.range(0.0, 0.2) as f32);
            let mut bound = BlockBound::empty();
            bound.a_min = a;
            bound.a_max = a + Vec2::new(da, 0.7 * da);
            bound.b_min = b;
            bound.b_max = b + Vec2::new(0.5 * db, db);
            bound.b_len_max = (b.abs() + Vec2::splat(db)).element_sum();
            bound.b_deviation_max = b_deviation(bound.b_min, bound.b_max);
            bound.facet_height_span = rng.range(0.0, 0.05) as f32;
            bound.facet_descent_spread = rng.range(0.0, 0.1) as f32;
            bound.top_y = rng.range(-0.2, 0.2) as f32;
            bound.min_descent = rng.range(MIN_DESCENT as f64, 1.0) as f32;
            bound.slack = 64.0 * f32::EPSILON * 30.0;
            let query = BlockQuery::new(&bound);
            let y = rng.range(-3.0, 0.5) as f32;
            let delta = query.height_delta(y);
            assert!(delta >= bound.height_delta(y), "{bound:?} at {y}");
            let (lo, hi) = bound.box_at(y);
            for corner in [lo, hi, Vec2::new(lo.x, hi.y), Vec2::new(hi.x, lo.y)] {
                assert!(
                    query.may_contain(corner, y, delta),
                    "{corner} of {bound:?} at {y}"
                );
            }
        }
    }

    #[test]
    fn thesis_mode_matches_its_brute_force_and_equal_t_on_flat_water() {
        let surface = Waves::default();
        let membrane = membrane_from(&surface, square_grid(2.0, 10));
        let eye = Vec3::new(0.5, 3.0, 0.2);
        let mut s = setup(eye);
        s.cell_mode = CellMode::Thesis;
        let thesis = RefractionField::build(&membrane, &surface, s, (-2.0, 0.0));
        let equal_t = RefractionField::build(&membrane, &surface, setup(eye), (-2.0, 0.0));
        let point = Vec3::new(0.33, -1.0, 0.21);
        let a = assert_same(&thesis, point, "thesis");
        let b = assert_same(&equal_t, point, "equal-t");
        assert_eq!(a.len(), 1);
        assert_eq!(b.len(), 1);
        assert!((a[0].sight_point - b[0].sight_point).length() < 2e-3);
    }

    /// Facets whose rays descend too gently for a footprint bound are listed apart and tested
    /// for every point: exactly those facets, and the answers stay the brute force's. Index-
    /// matched water (the rays go straight on) seen from an eye just above it makes the far
    /// facets' rays nearly level.
    #[test]
    fn facets_without_a_footprint_bound_are_tested_for_every_point() {
        let mut rng = Rng(0x5EED_0002);
        let surface = random_waves(&mut rng, 3, 0.1);
        let membrane = membrane_from(&surface, square_grid(2.0, 32));
        let eye = Vec3::new(-2.5, 0.15, 0.3);
        let setup = RefractionSetup {
            n_below: 1.0,
            ..setup(eye)
        };
        let field = RefractionField::build(&membrane, &surface, setup, (-2.0, 0.0));
        let expected: Vec<u32> = (0..membrane.triangles.len() as u32)
            .filter(|&facet| {
                membrane.triangles[facet as usize]
                    .iter()
                    .any(|&i| field.rays[i as usize].direction.y > -MIN_DESCENT)
            })
            .collect();
        assert!(!expected.is_empty() && expected.len() < membrane.triangles.len() / 2);
        assert_eq!(field.unbounded_facets, expected);
        let (mut images, mut through_unbounded) = (0, 0);
        for _ in 0..400 {
            let p = rng.point(2.0, (-0.3, -0.01));
            for image in assert_same(&field, p, "nearly level rays") {
                images += 1;
                through_unbounded += usize::from(expected.binary_search(&image.facet).is_ok());
            }
        }
        // Both kinds of facet answer: the test reaches the list as well as the blocks.
        assert!(
            images > 100 && through_unbounded > 0 && through_unbounded < images,
            "{images} images, {through_unbounded} through unbounded facets"
        );
    }

    #[test]
    fn extrapolated_flag_marks_facets_with_back_facing_rays() {
        // A steep wave seen from a low eye has back-facing vertices.
        let surface = Waves {
            waves: vec![(0.15, 5.0, 0.0, 0.0)],
            level_m: 0.0,
        };
        let membrane = membrane_from(&surface, square_grid(2.0, 40));
        let eye = Vec3::new(-4.0, 0.4, 0.0);
        let field = RefractionField::build(&membrane, &surface, setup(eye), (-2.0, 0.2));
        let back_facing = field
            .rays
            .iter()
            .filter(|r| r.extrapolation.is_extrapolated())
            .count();
        assert!(back_facing > 0);
        assert!(field.facet_extrapolated.iter().any(|&e| e));
        let mut rng = Rng(3);
        for _ in 0..500 {
            let p = rng.point(2.0, (-2.0, -0.1));
            for image in assert_same(&field, p, "grazing") {
                assert_eq!(
                    image.extrapolated,
                    field.facet_extrapolated[image.facet as usize]
                );
            }
        }
    }
}

/// Tuning aids (ignored tests, single-threaded, fastest of several runs) timing the query's
/// stages on the benchmark's pool scenario:
/// `cargo test --release --lib search::tuning -- --ignored --nocapture`.
#[cfg(test)]
mod tuning {
    use super::*;
    use std::time::Instant;

    fn slab_of<'a>(field: &'a RefractionField, p: Vec3) -> &'a Slab {
        field.slab_at(p.y).unwrap()
    }

    /// The benchmark's pool scenario (`refraction::bench`).
    struct Pool {
        surface: crate::water::WaterSurface,
        membrane: Membrane,
        points: Vec<Vec3>,
        setup: RefractionSetup,
    }

    impl Pool {
        fn new() -> Self {
            let (surface, membrane, points, setup) =
                crate::refraction::bench::pool_scenario_for_tests();
            Self {
                surface,
                membrane,
                points,
                setup,
            }
        }

        /// The field a frame builds, for the benchmark's query height range.
        fn field(&self) -> RefractionField<'_> {
            RefractionField::build(&self.membrane, &self.surface, self.setup, (-2.0, 0.0))
        }
    }

    fn gather() -> Vec<(Cell, DVec3)> {
        let pool = Pool::new();
        let (field, points) = (pool.field(), &pool.points);
        let mut cells = Vec::new();
        for p in points {
            field.for_each_candidate(slab_of(&field, *p), *p, |f| {
                cells.push((field.cell(f), p.as_dvec3()))
            });
        }
        cells
    }

    #[test]
    #[ignore]
    fn containment_only() {
        let cells = gather();
        let mut best = f64::INFINITY;
        let mut n = 0;
        let mut t = 0.0;
        for _ in 0..40 {
            let s = Instant::now();
            n = 0;
            t = 0.0;
            for (c, p) in &cells {
                let r = super::super::cells::equal_t_containments(c, *p);
                n += r.len();
                for x in r.iter() {
                    t += x.t;
                }
            }
            best = best.min(s.elapsed().as_secs_f64());
        }
        println!(
            "CONTAINMENT {} calls {:.1} ns/call n {n} sum t {t:.12}",
            cells.len(),
            best / cells.len() as f64 * 1e9
        );
    }

    #[test]
    #[ignore]
    fn crest_only() {
        let pool = Pool::new();
        let (field, points) = (pool.field(), &pool.points);
        let mut pairs = Vec::new();
        let mut out = Vec::new();
        for p in points {
            field.images(*p, &mut out);
            for im in &out {
                pairs.push((im.sight_point.as_dvec3(), p.as_dvec3()));
            }
        }
        let eye = field.setup.eye.as_dvec3();
        let (mut a, mut b) = (0, 0);
        for (sp, p) in &pairs {
            if field.segment_clear_by_slope(*sp, eye - *sp, 1.0, 1.0) {
                a += 1;
            }
            if field.segment_clear_by_slope(*sp, *p - *sp, 1.0, -1.0) {
                b += 1;
            }
        }
        println!(
            "CREST pairs {} eye proven {a} point proven {b} slope {} gap {} tol {}",
            pairs.len(),
            field.crest_heights.slope_bound,
            field.crest_heights.facet_gap_bound,
            field.crest_tolerance_m
        );
        let mut best = f64::INFINITY;
        let mut n = 0;
        for _ in 0..20 {
            let s = Instant::now();
            n = 0;
            for (sp, p) in &pairs {
                n += field.crest_blocks(*sp, *p) as usize;
            }
            best = best.min(s.elapsed().as_secs_f64());
        }
        println!(
            "CREST {:.1} ns/call blocked {n}",
            best / pairs.len() as f64 * 1e9
        );
    }

    /// The benchmark's pool figure alone (both cores): fastest and median of 15 frames.
    #[test]
    #[ignore]
    fn pool_frame() {
        use rayon::prelude::*;
        let pool = Pool::new();
        let mut frames = Vec::new();
        let mut builds = Vec::new();
        for _ in 0..15 {
            let s = Instant::now();
            let field = pool.field();
            builds.push(s.elapsed().as_secs_f64());
            let n: usize = pool
                .points
                .par_iter()
                .with_min_len(256)
                .map_init(Vec::new, |out, &p| {
                    field.images(p, out);
                    out.len()
                })
                .sum();
            frames.push(s.elapsed().as_secs_f64());
            assert!(n > 90_000);
        }
        frames.sort_by(f64::total_cmp);
        builds.sort_by(f64::total_cmp);
        println!(
            "POOL frame fastest {:.2} ms median {:.2} ms ({:.2} M/s median); build fastest {:.2} median {:.2} ms; size {:?}",
            frames[0] * 1e3,
            frames[7] * 1e3,
            pool.points.len() as f64 / frames[7] / 1e6,
            builds[0] * 1e3,
            builds[7] * 1e3,
            pool.field().structure_size()
        );
    }

    #[test]
    #[ignore]
    fn lanes_only() {
        let pool = Pool::new();
        let (field, points) = (pool.field(), &pool.points);
        let chunks = &field.block_chunks.as_flattened()[..4096];
        let mut best = f64::INFINITY;
        let mut n = 0;
        for _ in 0..20 {
            let s = Instant::now();
            n = 0;
            for (i, c) in chunks.iter().enumerate() {
                let p = points[i * 7];
                n += lanes_may_contain(c, Vec2::new(p.x, p.z), p.y, 0.01, 1e-6).count_ones()
                    as usize;
            }
            best = best.min(s.elapsed().as_secs_f64());
        }
        println!(
            "LANES {:.1} ns/chunk ({n})",
            best / chunks.len() as f64 * 1e9
        );
    }

    #[test]
    #[ignore]
    fn build_only() {
        let pool = Pool::new();
        let s = Instant::now();
        for _ in 0..100 {
            let f = pool.field();
            drop(f);
        }
        println!("build {:.2} ms", s.elapsed().as_secs_f64() * 10.0);
    }

    #[test]
    #[ignore]
    fn breakdown() {
        let pool = Pool::new();
        let (field, points) = (pool.field(), &pool.points);
        let pts: Vec<Vec3> = points.clone();
        let time = |name: &str, f: &dyn Fn(Vec3) -> usize| {
            let mut best = f64::INFINITY;
            let mut n = 0;
            for _ in 0..7 {
                let s = Instant::now();
                n = 0;
                for p in &pts {
                    n += f(*p);
                }
                best = best.min(s.elapsed().as_secs_f64());
            }
            println!(
                "{name}: {:.1} ns/query ({n})",
                best / pts.len() as f64 * 1e9
            );
        };
        let mut work = [0usize; 5];
        for p in &pts {
            let w = field.search_work(*p);
            for k in 0..5 {
                work[k] += w[k];
            }
        }
        println!(
            "work per query {:?}, structure {:?}",
            work.map(|w| w as f64 / pts.len() as f64),
            field.structure_size()
        );
        let out = std::cell::RefCell::new(Vec::new());
        time("candidates", &|p| {
            let mut n = 0;
            field.for_each_candidate(slab_of(&field, p), p, |_| n += 1);
            n
        });
        time("candidates+containment", &|p| {
            let o = &mut out.borrow_mut();
            o.clear();
            field.for_each_candidate(slab_of(&field, p), p, |f| {
                field.push_containments(f, p.as_dvec3(), o)
            });
            o.len()
        });
        time("images", &|p| {
            field.images(p, &mut out.borrow_mut());
            out.borrow().len()
        });
        let mut best = f64::INFINITY;
        for _ in 0..10 {
            let s = Instant::now();
            let f = pool.field();
            best = best.min(s.elapsed().as_secs_f64());
            drop(f);
        }
        println!("build {:.2} ms (2 threads)", best * 1e3);
    }
}
