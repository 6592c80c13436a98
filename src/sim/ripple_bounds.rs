//! Bounds of the ripple field per part of the plane: the largest |height|, |grad h| and second
//! directional derivative over any axis-aligned box, from the largest |node height| the field
//! weighs inside it. A wake makes the field steep where the character walks and leaves it almost
//! flat elsewhere; the bounds over the whole plane
//! ([`super::RippleField::slope_and_curvature_bounds`]) take the wake's everywhere, so a walk
//! along a ray far from the wake would step as if it were in it.
//!
//! The grid's cells (between neighbouring nodes) are grouped in tiles of [`TILE_CELLS`] x
//! [`TILE_CELLS`]. The field in a cell is a weighted sum of the 4 x 4 nodes around it (the cell's
//! corners and one more on each side, mirrored at the walls), so a tile's value is the largest
//! |node height| over its nodes widened by one node on each side. A max-pyramid over the tiles
//! (each level the max of 2 x 2 blocks of the one below) answers a box with at most four
//! look-ups, at the level where the box spans at most two blocks along each axis: a box covers
//! more than it needs, never less. The bounds follow from that node height by the one formula
//! [`super::ripples::bounds_for_node_height`]. Outside the grid the field is zero.

use super::ripples::{bounds_for_node_height, RippleField};

/// Cells per side of a tile.
pub const TILE_CELLS: usize = 4;

/// Bounds of the field over a box: (largest |height|, largest |grad h|, largest |second
/// derivative along a unit horizontal direction|).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldBounds {
    pub reach_m: f64,
    pub slope: f64,
    pub curvature_per_m: f64,
}

/// Per-tile largest |node height| of one ripple state, with its max-pyramid.
#[derive(Clone, Debug)]
pub struct RippleBounds {
    min_x: f64,
    min_z: f64,
    spacing_m: f64,
    /// Cells along x and z (nodes minus one).
    cells_x: usize,
    cells_z: usize,
    /// Level k: (blocks along x, blocks along z, largest |node height| per block of 2^k x 2^k
    /// tiles, row-major). Level 0 is the tiles; the last level is one block.
    levels: Vec<(usize, usize, Vec<f32>)>,
}

impl RippleBounds {
    /// The tiles and pyramid of `field`'s nodes.
    pub fn new(field: &RippleField) -> Self {
        let state = field.state();
        let s = &state.settings;
        let (nx, nz) = (s.nodes_x as usize, s.nodes_z as usize);
        let (cells_x, cells_z) = (nx.saturating_sub(1).max(1), nz.saturating_sub(1).max(1));
        let (tiles_x, tiles_z) = (cells_x.div_ceil(TILE_CELLS), cells_z.div_ceil(TILE_CELLS));
        // Largest |node| per tile row band first (along x), then over the bands (along z).
        let node_range = |tile: usize, nodes: usize| {
            // Cells tile*T .. (tile+1)*T - 1 weigh nodes from the first cell's - 1 to the last's + 2.
            let first = (tile * TILE_CELLS).saturating_sub(1);
            let last = ((tile + 1) * TILE_CELLS + 1).min(nodes - 1);
            first..=last
        };
        let mut per_row = vec![0.0f32; tiles_x * nz];
        for iz in 0..nz {
            let row = &state.height_m[iz * nx..(iz + 1) * nx];
            for tx in 0..tiles_x {
                per_row[iz * tiles_x + tx] = row[node_range(tx, nx)]
                    .iter()
                    .fold(0.0f32, |m, h| m.max(h.abs()));
            }
        }
        let mut tiles = vec![0.0f32; tiles_x * tiles_z];
        for tz in 0..tiles_z {
            for tx in 0..tiles_x {
                tiles[tz * tiles_x + tx] = node_range(tz, nz)
                    .map(|iz| per_row[iz * tiles_x + tx])
                    .fold(0.0f32, f32::max);
            }
        }
        let mut levels = vec![(tiles_x, tiles_z, tiles)];
        while {
            let (bx, bz, _) = levels.last().unwrap();
            *bx > 1 || *bz > 1
        } {
            let (bx, bz, below) = levels.last().unwrap();
            let (ux, uz) = (bx.div_ceil(2), bz.div_ceil(2));
            let mut up = vec![0.0f32; ux * uz];
            for j in 0..*bz {
                for i in 0..*bx {
                    let k = (j / 2) * ux + i / 2;
                    up[k] = up[k].max(below[j * bx + i]);
                }
            }
            levels.push((ux, uz, up));
        }
        RippleBounds {
            min_x: s.min_x,
            min_z: s.min_z,
            spacing_m: s.spacing_m,
            cells_x,
            cells_z,
            levels,
        }
    }

    /// Width of a tile, metres.
    pub fn tile_m(&self) -> f64 {
        TILE_CELLS as f64 * self.spacing_m
    }

    /// The largest |node height| the field weighs anywhere in the box `[x0, x1] x [z0, z1]`
    /// (borders included); 0 when the box misses the grid.
    pub fn node_height_over(&self, x0: f64, z0: f64, x1: f64, z1: f64) -> f64 {
        // Cells as the field picks them (floor of the grid coordinate, clamped to the last
        // cell), then their tiles. A box past the grid's end along an axis misses it; NaN
        // corners give the whole grid's bound.
        let tiles = |lo: f64, hi: f64, min: f64, cells: usize| {
            let (a, b) = ((lo - min) / self.spacing_m, (hi - min) / self.spacing_m);
            if a.is_nan() || b.is_nan() {
                return Some((0, (cells - 1) / TILE_CELLS));
            }
            if b < 0.0 || a > cells as f64 {
                return None;
            }
            let cell = |g: f64| (g.max(0.0) as usize).min(cells - 1);
            Some((cell(a) / TILE_CELLS, cell(b) / TILE_CELLS))
        };
        let (Some((tx0, tx1)), Some((tz0, tz1))) = (
            tiles(x0, x1, self.min_x, self.cells_x),
            tiles(z0, z1, self.min_z, self.cells_z),
        ) else {
            return 0.0;
        };
        // The level where the box spans at most two blocks along each axis (the top level is
        // one block, so the loop ends there at the latest).
        let mut k = 0;
        while (tx1 >> k) - (tx0 >> k) > 1 || (tz1 >> k) - (tz0 >> k) > 1 {
            k += 1;
        }
        let (bx, _, blocks) = &self.levels[k];
        let mut largest = 0.0f32;
        for j in (tz0 >> k)..=(tz1 >> k) {
            for i in (tx0 >> k)..=(tx1 >> k) {
                largest = largest.max(blocks[j * bx + i]);
            }
        }
        largest as f64
    }

    /// The field's bounds over the box `[x0, x1] x [z0, z1]`.
    pub fn over(&self, x0: f64, z0: f64, x1: f64, z1: f64) -> FieldBounds {
        let (reach_m, slope, curvature_per_m) =
            bounds_for_node_height(self.node_height_over(x0, z0, x1, z1), self.spacing_m);
        FieldBounds {
            reach_m,
            slope,
            curvature_per_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeded::SplitMix64;
    use crate::sim::RippleState;
    use crate::water::HeightField;

    /// A field of a few narrow bumps of very different heights on a 61 x 41 grid over
    /// [-1.5, 1.5] x [-1, 1]: tiles near the tall bump are steep, far ones almost flat.
    fn bumpy() -> RippleState {
        let s = crate::sim::spectral::tests::settings(61, 41, 0.05);
        let mut state = crate::sim::spectral::tests::bump(s, 0.4, -0.3, 0.06);
        for (x, z, scale) in [(-0.9, 0.5, 0.05), (0.0, 0.7, 0.01), (1.3, -0.9, 0.2)] {
            let other = crate::sim::spectral::tests::bump(s, x, z, 0.04);
            for (h, o) in state.height_m.iter_mut().zip(&other.height_m) {
                *h += scale * o;
            }
        }
        state
    }

    /// The bounds over random boxes hold at dense samples inside them: |h|, |grad h| and the
    /// second difference along random directions (points and their +-e neighbours inside the box,
    /// and inside one cell, where the bicubic is smooth). The slope bound must also come within a
    /// factor of 8 of what is sampled in some box (the curvature's within 40: its weight sums are
    /// the global bound's, and as loose), and boxes far from the tall bump must get bounds far
    /// under the whole grid's, so neither a bound that is far too loose nor one that is global
    /// passes.
    #[test]
    fn tile_bounds_hold_at_dense_samples_in_every_box() {
        let state = bumpy();
        let field = state.field();
        let bounds = RippleBounds::new(&field);
        let s = state.settings;
        let global_slope = field.slope_and_curvature_bounds().0;
        let mut rng = SplitMix64::new(0x711e_b0d5);
        let e = 1e-5;
        let (mut tightest_slope, mut tightest_curvature) = (f64::INFINITY, f64::INFINITY);
        let mut local_boxes = 0;
        for case in 0..300 {
            // Boxes from a fraction of a cell to half the grid, some reaching past its edge.
            let size_x = rng.range(0.01, 1.6);
            let size_z = rng.range(0.01, 1.0);
            let x0 = rng.range(-1.7, 1.6 - size_x);
            let z0 = rng.range(-1.2, 1.1 - size_z);
            let (x1, z1) = (x0 + size_x, z0 + size_z);
            let b = bounds.over(x0, z0, x1, z1);
            let (mut height, mut slope, mut curvature) = (0.0f64, 0.0f64, 0.0f64);
            for _ in 0..400 {
                let x = rng.range(x0 + e, x1 - e);
                let z = rng.range(z0 + e, z1 - e);
                height = height.max(field.height(x, z).abs());
                let (gx, gz) = field.gradient(x, z);
                slope = slope.max(gx.hypot(gz));
                // The second difference inside one cell of the bicubic.
                let (fx, fz) = ((x - s.min_x) / s.spacing_m, (z - s.min_z) / s.spacing_m);
                let inside = |f: f64| (f - f.round()).abs() > 2.0 * e / s.spacing_m;
                if inside(fx) && inside(fz) {
                    let angle = rng.range(0.0, std::f64::consts::TAU);
                    let (ux, uz) = (angle.cos(), angle.sin());
                    let along = |d: f64| field.height(x + d * ux, z + d * uz);
                    let second = (along(e) - 2.0 * along(0.0) + along(-e)) / (e * e);
                    curvature = curvature.max(second.abs());
                }
            }
            assert!(
                height <= b.reach_m,
                "case {case}: |h| {height} > {}",
                b.reach_m
            );
            assert!(slope <= b.slope, "case {case}: slope {slope} > {}", b.slope);
            assert!(
                curvature <= b.curvature_per_m * 1.001 + 1e-3,
                "case {case}: curvature {curvature} > {}",
                b.curvature_per_m
            );
            if slope > 0.0 && curvature > 0.0 {
                tightest_slope = tightest_slope.min(b.slope / slope);
                tightest_curvature = tightest_curvature.min(b.curvature_per_m / curvature);
            }
            if b.slope < 0.1 * global_slope {
                local_boxes += 1;
            }
        }
        eprintln!(
            "tightest: slope bound {tightest_slope:.2}x, curvature bound {tightest_curvature:.2}x \
             the largest sampled; {local_boxes} of 300 boxes under a tenth of the global slope"
        );
        // The formula's own slack (the sums of |weights|) is the global bound's too: the slope
        // bound comes within 8x of a sampled slope somewhere; the curvature's sums are looser.
        assert!(
            tightest_slope < 8.0,
            "slope bounds loose: {tightest_slope}x"
        );
        assert!(
            tightest_curvature < 40.0,
            "curvature bounds loose: {tightest_curvature}x"
        );
        assert!(
            local_boxes > 30,
            "only {local_boxes} boxes had local bounds"
        );
        // A box outside the grid sees no ripples; the whole grid's box gets the global bounds.
        assert_eq!(bounds.over(5.0, 5.0, 6.0, 6.0).slope, 0.0);
        let whole = bounds.over(-2.0, -2.0, 2.0, 2.0);
        assert_eq!(whole.slope, global_slope);
        assert_eq!(whole.reach_m, field.max_abs_height_m());
    }

    /// Every tile's value against a brute-force scan of the nodes the field weighs in its cells,
    /// including the mirrored ones at the walls.
    #[test]
    fn tiles_hold_the_largest_node_each_of_their_cells_weighs() {
        let state = bumpy();
        let field = state.field();
        let bounds = RippleBounds::new(&field);
        let s = state.settings;
        let (nx, nz) = (s.nodes_x as i64, s.nodes_z as i64);
        let mirrored = |i: i64, n: i64| {
            let i = i.abs();
            (if i > n - 1 { 2 * (n - 1) - i } else { i }) as usize
        };
        for cz in 0..(nz - 1) {
            for cx in 0..(nx - 1) {
                let mut largest = 0.0f32;
                for j in -1..=2 {
                    for i in -1..=2 {
                        let node = mirrored(cz + j, nz) * nx as usize + mirrored(cx + i, nx);
                        largest = largest.max(state.height_m[node].abs());
                    }
                }
                // A point inside the cell: the box of just that point.
                let x = s.min_x + (cx as f64 + 0.5) * s.spacing_m;
                let z = s.min_z + (cz as f64 + 0.5) * s.spacing_m;
                let tile = bounds.node_height_over(x, z, x, z);
                assert!(
                    tile >= largest as f64,
                    "cell ({cx}, {cz}): {tile} < {largest}"
                );
            }
        }
    }
}
