//! The membrane: the height field sampled on a regular grid and cut into triangles (layout on
//! [`Membrane`]), with the analytic normal at every vertex; plus O(1) lookups that follow from the
//! layout (vertex index, facet vertices, neighbours, the facet above a point).

use glam::Vec3;
use rayon::prelude::*;

use super::{HeightField, Membrane, MembraneGrid, WaterError};

/// Samples `surface` at every grid vertex (heights and analytic normals, computed in f64) and
/// triangulates with the fixed layout documented on [`Membrane`]. Rows are built in parallel.
/// The grid must satisfy [`MembraneGrid::validate`].
pub fn build_membrane(surface: &dyn HeightField, grid: &MembraneGrid) -> Membrane {
    debug_assert_eq!(grid.validate(), Ok(()), "build_membrane needs a valid grid");
    let row_len = grid.vertices_x() as usize;
    let vertex_count = grid.vertex_count();
    let mut positions = vec![Vec3::ZERO; vertex_count];
    let mut normals = vec![Vec3::ZERO; vertex_count];
    positions
        .par_chunks_mut(row_len)
        .zip(normals.par_chunks_mut(row_len))
        .enumerate()
        .for_each(|(iz, (position_row, normal_row))| {
            for (ix, (position, normal)) in position_row
                .iter_mut()
                .zip(normal_row.iter_mut())
                .enumerate()
            {
                let (x, z) = grid.vertex_xz(ix as u32, iz as u32);
                *position = Vec3::new(x as f32, surface.height(x, z) as f32, z as f32);
                *normal = surface.normal(x, z).as_vec3();
            }
        });

    let cells_x = grid.cells_x as usize;
    let mut triangles = vec![[0u32; 3]; grid.triangle_count()];
    triangles
        .par_chunks_mut(2 * cells_x)
        .enumerate()
        .for_each(|(iz, triangle_row)| {
            for (ix, pair) in triangle_row.chunks_exact_mut(2).enumerate() {
                let facet = 2 * (iz * cells_x + ix) as u32;
                pair[0] = grid.facet_vertices(facet);
                pair[1] = grid.facet_vertices(facet + 1);
            }
        });

    Membrane {
        grid: *grid,
        positions,
        normals,
        triangles,
    }
}

/// Which half of a cell a facet is: `Upper` = [v00, v01, v11], `Lower` = [v00, v11, v10].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CellHalf {
    Upper,
    Lower,
}

impl MembraneGrid {
    /// A grid with at least one cell each way over a non-empty, finite rectangle.
    pub fn validate(&self) -> Result<(), WaterError> {
        let fail = |reason: String| Err(WaterError::InvalidGrid { reason });
        for (name, value) in [
            ("min_x", self.min_x),
            ("min_z", self.min_z),
            ("max_x", self.max_x),
            ("max_z", self.max_z),
        ] {
            if !value.is_finite() {
                return fail(format!("{name} must be a finite number, got {value}"));
            }
        }
        if self.min_x >= self.max_x || self.min_z >= self.max_z {
            return fail(format!(
                "extent must have min < max on both axes, got x {}..{} and z {}..{}",
                self.min_x, self.max_x, self.min_z, self.max_z
            ));
        }
        if self.cells_x == 0 || self.cells_z == 0 {
            return fail(format!(
                "resolution must be at least 1x1 cells, got {}x{}",
                self.cells_x, self.cells_z
            ));
        }
        // Indices are u32: the vertex count must fit.
        if (self.cells_x as u64 + 1) * (self.cells_z as u64 + 1) > u32::MAX as u64 {
            return fail(format!(
                "{}x{} cells is too many vertices for u32 indices",
                self.cells_x, self.cells_z
            ));
        }
        Ok(())
    }

    pub fn vertices_x(&self) -> u32 {
        self.cells_x + 1
    }

    pub fn vertices_z(&self) -> u32 {
        self.cells_z + 1
    }

    pub fn vertex_count(&self) -> usize {
        self.vertices_x() as usize * self.vertices_z() as usize
    }

    pub fn cell_count(&self) -> usize {
        self.cells_x as usize * self.cells_z as usize
    }

    pub fn triangle_count(&self) -> usize {
        2 * self.cell_count()
    }

    pub fn cell_size_x_m(&self) -> f64 {
        (self.max_x - self.min_x) / self.cells_x as f64
    }

    pub fn cell_size_z_m(&self) -> f64 {
        (self.max_z - self.min_z) / self.cells_z as f64
    }

    /// Index of vertex (ix, iz) in `Membrane::positions`.
    pub fn vertex_index(&self, ix: u32, iz: u32) -> u32 {
        iz * self.vertices_x() + ix
    }

    /// Horizontal position of vertex (ix, iz). Computed as a fraction of the extent so the last
    /// vertex lands exactly on `max_x` / `max_z`.
    pub fn vertex_xz(&self, ix: u32, iz: u32) -> (f64, f64) {
        let fraction_x = ix as f64 / self.cells_x as f64;
        let fraction_z = iz as f64 / self.cells_z as f64;
        (
            self.min_x + (self.max_x - self.min_x) * fraction_x,
            self.min_z + (self.max_z - self.min_z) * fraction_z,
        )
    }

    /// Whether (x, z) lies on the covered rectangle, edges included. The tolerance (1e-6 relative
    /// to the coordinates' size) lets f32 vertex positions on the rim count as inside.
    pub fn contains_xz(&self, x: f64, z: f64) -> bool {
        let tolerance_x = 1e-6 * (1.0 + self.min_x.abs().max(self.max_x.abs()));
        let tolerance_z = 1e-6 * (1.0 + self.min_z.abs().max(self.max_z.abs()));
        x >= self.min_x - tolerance_x
            && x <= self.max_x + tolerance_x
            && z >= self.min_z - tolerance_z
            && z <= self.max_z + tolerance_z
    }

    /// The cell (ix, iz) containing (x, z); points on the rim belong to the edge cells.
    pub fn cell_of_xz(&self, x: f64, z: f64) -> Option<(u32, u32)> {
        if !self.contains_xz(x, z) {
            return None;
        }
        let (_, _, ix, iz) = self.local_cell_coordinates(x, z);
        Some((ix, iz))
    }

    /// Index of the facet whose horizontal projection contains (x, z) (on the diagonal: the upper one).
    pub fn facet_at_xz(&self, x: f64, z: f64) -> Option<u32> {
        if !self.contains_xz(x, z) {
            return None;
        }
        let (u, v, ix, iz) = self.local_cell_coordinates(x, z);
        let first = 2 * (iz * self.cells_x + ix);
        Some(if v >= u { first } else { first + 1 })
    }

    /// (fraction x, fraction z) inside the clamped cell, and the cell.
    fn local_cell_coordinates(&self, x: f64, z: f64) -> (f64, f64, u32, u32) {
        let grid_x = (x - self.min_x) / self.cell_size_x_m();
        let grid_z = (z - self.min_z) / self.cell_size_z_m();
        let ix = (grid_x.floor().max(0.0) as u32).min(self.cells_x - 1);
        let iz = (grid_z.floor().max(0.0) as u32).min(self.cells_z - 1);
        (
            (grid_x - ix as f64).clamp(0.0, 1.0),
            (grid_z - iz as f64).clamp(0.0, 1.0),
            ix,
            iz,
        )
    }

    fn facet_cell(&self, facet: u32) -> (u32, u32, CellHalf) {
        let cell = facet / 2;
        let half = if facet.is_multiple_of(2) {
            CellHalf::Upper
        } else {
            CellHalf::Lower
        };
        (cell % self.cells_x, cell / self.cells_x, half)
    }

    /// The three vertex indices of `facet`, counter-clockwise seen from above (as in `triangles`).
    pub fn facet_vertices(&self, facet: u32) -> [u32; 3] {
        let (ix, iz, half) = self.facet_cell(facet);
        let v00 = self.vertex_index(ix, iz);
        let v10 = v00 + 1;
        let v01 = v00 + self.vertices_x();
        let v11 = v01 + 1;
        match half {
            CellHalf::Upper => [v00, v01, v11],
            CellHalf::Lower => [v00, v11, v10],
        }
    }

    /// Whether two facets have at least one vertex in common (a facet shares vertices with itself).
    /// O(1) from the layout; out-of-range facets share nothing.
    pub fn facets_share_vertex(&self, a: u32, b: u32) -> bool {
        let count = self.triangle_count() as u64;
        if a as u64 >= count || b as u64 >= count {
            return false;
        }
        let vertices_b = self.facet_vertices(b);
        self.facet_vertices(a)
            .iter()
            .any(|vertex| vertices_b.contains(vertex))
    }

    /// The facets across each edge of `facet`, in edge order (v0-v1, v1-v2, v2-v0) of
    /// [`Self::facet_vertices`]; `None` on the rim of the grid.
    pub fn edge_neighbours(&self, facet: u32) -> [Option<u32>; 3] {
        let (ix, iz, half) = self.facet_cell(facet);
        let first_of = |cx: u32, cz: u32| 2 * (cz * self.cells_x + cx);
        match half {
            // [v00, v01, v11]: the left edge (x = ix), the far edge (z = iz + 1), the diagonal.
            CellHalf::Upper => [
                (ix > 0).then(|| first_of(ix - 1, iz) + 1),
                (iz + 1 < self.cells_z).then(|| first_of(ix, iz + 1) + 1),
                Some(facet + 1),
            ],
            // [v00, v11, v10]: the diagonal, the right edge (x = ix + 1), the near edge (z = iz).
            CellHalf::Lower => [
                Some(facet - 1),
                (ix + 1 < self.cells_x).then(|| first_of(ix + 1, iz)),
                (iz > 0).then(|| first_of(ix, iz - 1)),
            ],
        }
    }
}

impl Membrane {
    pub fn contains_xz(&self, x: f64, z: f64) -> bool {
        self.grid.contains_xz(x, z)
    }

    pub fn vertex_index(&self, ix: u32, iz: u32) -> u32 {
        self.grid.vertex_index(ix, iz)
    }

    pub fn facets_share_vertex(&self, a: u32, b: u32) -> bool {
        self.grid.facets_share_vertex(a, b)
    }

    pub fn facet_at_xz(&self, x: f64, z: f64) -> Option<u32> {
        self.grid.facet_at_xz(x, z)
    }

    /// Height of the faceted (piecewise-linear) surface above (x, z), or `None` off the grid.
    /// Differs from the exact height field by O(cell size^2 * curvature).
    pub fn faceted_height_at_xz(&self, x: f64, z: f64) -> Option<f64> {
        let facet = self.facet_at_xz(x, z)?;
        let [p0, p1, p2] =
            self.triangles[facet as usize].map(|vertex| self.positions[vertex as usize].as_dvec3());
        // Barycentrics in the horizontal projection.
        let (e1x, e1z) = (p1.x - p0.x, p1.z - p0.z);
        let (e2x, e2z) = (p2.x - p0.x, p2.z - p0.z);
        let (qx, qz) = (x - p0.x, z - p0.z);
        let det = e1x * e2z - e2x * e1z;
        let b1 = (qx * e2z - e2x * qz) / det;
        let b2 = (e1x * qz - qx * e1z) / det;
        Some(p0.y + b1 * (p1.y - p0.y) + b2 * (p2.y - p0.y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::water::{FlatHeightField, FnHeightField, Wave, WaveField};

    fn grid(cells_x: u32, cells_z: u32) -> MembraneGrid {
        MembraneGrid {
            min_x: -2.0,
            min_z: -1.0,
            max_x: 3.0,
            max_z: 2.5,
            cells_x,
            cells_z,
        }
    }

    fn wavy_field() -> WaveField {
        let wave = |amplitude_m, wavelength_m, direction, phase_rad| Wave {
            amplitude_m,
            wavelength_m,
            direction,
            phase_rad,
            speed_m_per_s: None,
        };
        WaveField {
            level_m: 0.4,
            waves: vec![
                wave(0.08, 2.0, [0.8, 0.6], 0.1),
                wave(0.03, 0.9, [-1.0, 0.0], 2.0),
            ],
        }
    }

    #[test]
    fn vertex_count_layout_and_heights_follow_the_surface() {
        let grid = grid(7, 5);
        let surface = wavy_field().at(2.5);
        let membrane = build_membrane(&surface, &grid);
        assert_eq!(membrane.positions.len(), 8 * 6);
        assert_eq!(membrane.normals.len(), 8 * 6);
        assert_eq!(membrane.triangles.len(), 2 * 7 * 5);
        for iz in 0..=5 {
            for ix in 0..=7 {
                let index = membrane.vertex_index(ix, iz) as usize;
                assert_eq!(index, iz as usize * 8 + ix as usize);
                let x = -2.0 + 5.0 * ix as f64 / 7.0;
                let z = -1.0 + 3.5 * iz as f64 / 5.0;
                let p = membrane.positions[index];
                assert_eq!(
                    p,
                    Vec3::new(x as f32, surface.height(x, z) as f32, z as f32)
                );
                assert_eq!(membrane.normals[index], surface.normal(x, z).as_vec3());
            }
        }
        // The rim lands exactly on the extent.
        let last = membrane.positions[membrane.vertex_index(7, 5) as usize];
        assert_eq!((last.x, last.z), (3.0, 2.5));
    }

    #[test]
    fn facets_are_counter_clockwise_from_above_and_cut_along_one_diagonal() {
        // Fine enough (cells ~1/5 of the shortest wavelength) that facets follow the surface.
        let grid = grid(30, 20);
        let membrane = build_membrane(&wavy_field().at(0.3), &grid);
        for (facet, triangle) in membrane.triangles.iter().enumerate() {
            let [p0, p1, p2] = triangle.map(|vertex| membrane.positions[vertex as usize]);
            let facet_normal = (p1 - p0).cross(p2 - p0).normalize();
            // Counter-clockwise from above <=> the geometric normal points up.
            assert!(facet_normal.y > 0.0, "facet {facet} normal {facet_normal}");
            // The analytic normals at its vertices agree with the facet's (slopes up to ~0.45).
            for vertex in triangle {
                let agreement = membrane.normals[*vertex as usize].dot(facet_normal);
                assert!(agreement > 0.95, "facet {facet}: {agreement}");
            }
            assert_eq!(*triangle, grid.facet_vertices(facet as u32));
        }
        // Diagonal v00-v11 in every cell: both triangles of cell c contain v00 and v11.
        for cell in 0..grid.cell_count() as u32 {
            let (ix, iz) = (cell % 30, cell / 30);
            let (v00, v11) = (grid.vertex_index(ix, iz), grid.vertex_index(ix + 1, iz + 1));
            for facet in [2 * cell, 2 * cell + 1] {
                let t = membrane.triangles[facet as usize];
                assert!(t.contains(&v00) && t.contains(&v11));
            }
        }
    }

    #[test]
    fn normals_are_unit_and_up() {
        let membrane = build_membrane(&wavy_field().at(7.0), &grid(9, 9));
        for normal in &membrane.normals {
            assert!((normal.length() - 1.0).abs() < 1e-6);
            assert!(normal.y > 0.0);
        }
    }

    #[test]
    fn sharing_and_neighbours_match_a_brute_force_over_the_triangle_list() {
        let grid = grid(5, 4);
        let membrane = build_membrane(&FlatHeightField { level_m: 0.0 }, &grid);
        let count = membrane.triangles.len() as u32;
        for a in 0..count {
            let ta = membrane.triangles[a as usize];
            let mut expected_neighbours = [None; 3];
            for b in 0..count {
                let tb = membrane.triangles[b as usize];
                let shared = ta.iter().filter(|vertex| tb.contains(vertex)).count();
                assert_eq!(
                    membrane.facets_share_vertex(a, b),
                    shared > 0,
                    "facets {a} {b}"
                );
                if a != b && shared == 2 {
                    for edge in 0..3 {
                        let (u, w) = (ta[edge], ta[(edge + 1) % 3]);
                        if tb.contains(&u) && tb.contains(&w) {
                            expected_neighbours[edge] = Some(b);
                        }
                    }
                }
            }
            assert_eq!(grid.edge_neighbours(a), expected_neighbours, "facet {a}");
        }
        assert!(!membrane.facets_share_vertex(0, count));
    }

    #[test]
    fn point_lookups_find_the_facet_under_the_point() {
        let grid = grid(6, 3);
        // A tilted plane is reproduced exactly by the facets, so the faceted height is the plane.
        let plane =
            FnHeightField::new(|x, z| 0.3 * x - 0.2 * z + 1.0).with_gradient(|_, _| (0.3, -0.2));
        let membrane = build_membrane(&plane, &grid);
        let mut rng = crate::seeded::SplitMix64::new(42);
        for _ in 0..500 {
            let (fx, fz) = (rng.unit(), rng.unit());
            let (x, z) = (-2.0 + 5.0 * fx, -1.0 + 3.5 * fz);
            let facet = membrane.facet_at_xz(x, z).expect("inside");
            let [p0, p1, p2] = membrane.triangles[facet as usize]
                .map(|v| membrane.positions[v as usize].as_dvec3());
            // Oracle: the point is inside the facet's projection (sign tests on each edge).
            let side =
                |a: glam::DVec3, b: glam::DVec3| (b.x - a.x) * (z - a.z) - (b.z - a.z) * (x - a.x);
            let signs = [side(p0, p1), side(p1, p2), side(p2, p0)];
            assert!(
                signs.iter().all(|s| *s <= 1e-12) || signs.iter().all(|s| *s >= -1e-12),
                "facet {facet}"
            );
            let height = membrane.faceted_height_at_xz(x, z).unwrap();
            // f32 vertex positions: ~1e-6 relative.
            assert!(
                (height - plane.height(x, z)).abs() < 1e-5,
                "{height} vs {}",
                plane.height(x, z)
            );
        }
        assert!(membrane.contains_xz(3.0, 2.5) && membrane.contains_xz(-2.0, -1.0));
        assert!(membrane.contains_xz(3.0_f32 as f64, 2.5_f32 as f64));
        assert!(!membrane.contains_xz(3.001, 0.0) && !membrane.contains_xz(0.0, -1.001));
        assert_eq!(grid.cell_of_xz(3.0, 2.5), Some((5, 2)));
        assert_eq!(grid.facet_at_xz(-2.0, -1.0), Some(0));
        assert_eq!(grid.cell_of_xz(3.5, 0.0), None);
        assert!((grid.cell_size_x_m() - 5.0 / 6.0).abs() < 1e-15);
        assert!((grid.cell_size_z_m() - 3.5 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn grid_validation_rejects_unusable_grids() {
        assert_eq!(grid(1, 1).validate(), Ok(()));
        assert!(grid(0, 4)
            .validate()
            .unwrap_err()
            .to_string()
            .contains("resolution"));
        let inverted = MembraneGrid {
            max_x: -5.0,
            ..grid(2, 2)
        };
        assert!(inverted
            .validate()
            .unwrap_err()
            .to_string()
            .contains("min < max"));
        let nan = MembraneGrid {
            min_z: f64::NAN,
            ..grid(2, 2)
        };
        assert!(nan.validate().unwrap_err().to_string().contains("min_z"));
    }
}
