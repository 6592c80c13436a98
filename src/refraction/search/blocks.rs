//! The accelerated search's structure (see the [`super`] module docs for the bound it rests on):
//! membrane facets grouped in blocks of `BLOCK_CELLS x BLOCK_CELLS` grid cells, each block's
//! conservative footprint bound ([`BlockBound`], and [`BlockQuery`], the same bound without
//! divisions) and its facets' footprint lines in lane chunks of eight ([`LaneChunk`]), and the
//! query height range cut in depth slabs, each a uniform 2-D grid of the blocks that can cover
//! its bins ([`Slab`]). Receives the membrane, its refraction rays and the query heights; answers
//! which facets' cells can contain a point ([`SearchStructure::for_each_candidate`]).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::super::cells::CONTAINMENT_EPS;
use super::super::rays::RefractionRay;
use crate::water::Membrane;

/// Facets are grouped in blocks of this many grid cells on a side for the accelerated search.
pub(super) const BLOCK_CELLS: usize = 2;
/// Facets a block holds at most: two per cell.
const BLOCK_FACETS: usize = 2 * BLOCK_CELLS * BLOCK_CELLS;
/// Lane chunks a block holds at most.
const BLOCK_CHUNKS: usize = BLOCK_FACETS.div_ceil(LANES);
/// Rays descending less steeply than this (`T.y > -MIN_DESCENT`) get no footprint bound.
pub(super) const MIN_DESCENT: f32 = 0.05;
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
pub(crate) struct LaneChunk {
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
pub(crate) struct Slab {
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

/// The blocks, their bounds and lane chunks, and the depth slabs of one frame.
pub(crate) struct SearchStructure {
    /// The regular facets of each block with their footprint lines, in chunks of [`LANES`]
    /// (ascending facet index, unused lanes NaN), so the hot loop reads one contiguous run per
    /// block instead of chasing triangle and vertex indices.
    pub(crate) block_chunks: Vec<[LaneChunk; BLOCK_CHUNKS]>,
    block_bounds: Vec<BlockBound>,
    block_queries: Vec<BlockQuery>,
    /// Facets with a ray that gets no footprint bound: always tested.
    unbounded_facets: Vec<u32>,
    slab_y_low: f32,
    slab_thickness_m: f32,
    slabs: Vec<Slab>,
    /// Absolute f32 rounding slack for per-facet footprint tests.
    footprint_slack: f32,
}

impl SearchStructure {
    /// No structure: every query tests every cell.
    pub(super) fn empty() -> Self {
        Self {
            block_chunks: Vec::new(),
            block_bounds: Vec::new(),
            block_queries: Vec::new(),
            unbounded_facets: Vec::new(),
            slab_y_low: 0.0,
            slab_thickness_m: 1.0,
            slabs: Vec::new(),
            footprint_slack: 0.0,
        }
    }

    /// The structure for query points with heights in `query_y_range` over `membrane`, whose
    /// vertices' refraction rays are `rays`; `spacing_m` is the grid spacing.
    pub(super) fn build(
        membrane: &Membrane,
        rays: &[RefractionRay],
        spacing_m: f64,
        query_y_range: (f32, f32),
    ) -> Self {
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
        let coordinate_scale = membrane
            .positions
            .iter()
            .fold(1.0_f32, |m, p| m.max(p.abs().max_element()))
            .max(query_y_range.0.abs())
            .max(query_y_range.1.abs());
        let mut structure = Self::empty();
        structure.build_blocks(membrane, rays, &footprints, coordinate_scale);
        structure.build_slabs(spacing_m, query_y_range);
        structure
    }

    /// Whether queries can use the structure (else they test every cell).
    pub(super) fn is_built(&self) -> bool {
        !self.slabs.is_empty()
    }

    /// Facets tested for every point: those with a ray too gentle for a footprint bound.
    pub(super) fn unbounded_facets(&self) -> &[u32] {
        &self.unbounded_facets
    }

    /// Groups regular facets into blocks and computes each block's bound and lane chunks, one
    /// block per task: a block's facets follow from the membrane's layout (cell `c` owns facets
    /// `2c` and `2c + 1`, see [`Membrane`]), so no facet has to be sorted into its block first.
    fn build_blocks(
        &mut self,
        membrane: &Membrane,
        rays: &[RefractionRay],
        footprints: &[Footprint],
        coordinate_scale: f32,
    ) {
        let grid = membrane.grid;
        let (cells_x, cells_z) = (grid.cells_x as usize, grid.cells_z as usize);
        let blocks_x = cells_x.div_ceil(BLOCK_CELLS).max(1);
        let blocks_z = cells_z.div_ceil(BLOCK_CELLS).max(1);
        let block_count = blocks_x * blocks_z;
        let triangles = &membrane.triangles;
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
    fn build_slabs(&mut self, spacing_m: f64, query_y_range: (f32, f32)) {
        let (y_low, y_high) = (
            query_y_range.0.min(query_y_range.1),
            query_y_range.0.max(query_y_range.1),
        );
        if !(y_low.is_finite() && y_high.is_finite()) || self.block_bounds.is_empty() {
            return;
        }
        let block_m = (BLOCK_CELLS as f64 * spacing_m) as f32;
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

    /// The depth slab holding height `y`; None outside the range the structure was built for.
    pub(crate) fn slab_at(&self, y: f32) -> Option<&Slab> {
        let slab_f = (y - self.slab_y_low) / self.slab_thickness_m;
        (slab_f >= 0.0 && slab_f <= self.slabs.len() as f32)
            .then(|| &self.slabs[(slab_f as usize).min(self.slabs.len() - 1)])
    }

    /// Calls `visit` with every regular facet whose footprint test `point` passes in `slab`'s
    /// bin: the blocks listed there whose box at the point's height holds it, then their facets'
    /// grown footprint triangles, [`LANES`] at a time.
    #[inline(always)]
    pub(crate) fn for_each_candidate(&self, slab: &Slab, point: Vec3, mut visit: impl FnMut(u32)) {
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
    pub(super) fn structure_size(&self) -> [usize; 4] {
        [
            self.slabs.len(),
            self.slabs.iter().map(|s| s.bins_x * s.bins_z).sum(),
            self.slabs.iter().map(|s| s.blocks.len()).sum(),
            self.block_bounds.len(),
        ]
    }

    /// Work counters of one accelerated query: (blocks in the bin, blocks passing their box,
    /// facets tested by footprint, facets passing it, unbounded facets). For tuning.
    pub(super) fn search_work(&self, point: Vec3) -> [usize; 5] {
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
pub(crate) fn lanes_may_contain(chunk: &LaneChunk, v: Vec2, y: f32, delta: f32, slack: f32) -> u32 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeded::SplitMix64 as Rng;

    /// The lane test is the scalar footprint test, lane for lane, on random footprints (all
    /// orientations, thin and degenerate ones included), points, heights and radii.
    #[test]
    fn lane_footprint_test_matches_the_scalar_one() {
        let mut rng = Rng::new(0x5EED_1A4E);
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
        let mut rng = Rng::new(0x5EED_B0C5);
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
}
