//! Splitting object triangles at the EXACT water surface (ALGORITHM §7): receives a world-space mesh,
//! the exact height field and the membrane's horizontal extent; returns the mesh's vertices (each
//! classified above / below / on the surface) plus the new vertices where edges cross the surface,
//! and two triangle lists: the part above the water (drawn with true positions) and the part below
//! (drawn with virtual positions).
//!
//! Water exists only inside the membrane's xz extent: a vertex outside it is above water, whatever
//! its height. An edge whose sign change is caused by leaving the extent, not by crossing the
//! surface, is cut where it leaves the extent (the root finder finds that discontinuity like any
//! other sign change); that cut vertex is NOT on the surface — it is under water and gets a virtual
//! position like any other under-water vertex, so the picture shows a step there. This is the
//! honest rendering of a scene that has water without a wall: the membrane should cover every
//! object that goes under it.
//!
//! Classification is per vertex, so each edge is cut at most once and each triangle by one straight
//! line: object tessellation must be finer than the waves' features (an edge whose two ends are
//! above water but which dips under a trough between them is not cut).

use glam::{DVec3, Vec2, Vec3};

use crate::mesh::Mesh;
use crate::water::{HeightField, MembraneGrid};

/// Vertices within this height of the exact surface are ON it (shared by both parts, their own
/// virtual vertex). It is also the accuracy the edge crossings are solved to: far below anything
/// visible at pool scale, far above f32 position noise of the meshes (~1e-7 m per metre).
pub const SURFACE_TOLERANCE_M: f64 = 1e-6;

/// Where a vertex is relative to the water.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// On the eye's side of the water, or outside the membrane's extent (no water there).
    Above,
    /// Under the water: drawn at a virtual position.
    Below,
    /// On the exact surface (within [`SURFACE_TOLERANCE_M`]): its own virtual vertex.
    Surface,
}

/// A vertex of the split mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitVertex {
    pub position: Vec3,
    pub normal: Vec3,
    pub uv: Vec2,
    pub side: Side,
}

/// A mesh split at the water surface. `vertices[..original_vertex_count]` are the mesh's own
/// vertices in their order (so tracking per original vertex is by index); the rest are crossings.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitMesh {
    pub vertices: Vec<SplitVertex>,
    pub original_vertex_count: usize,
    /// For each crossing `vertices[original_vertex_count + i]`: the edge it cuts, as (under-water
    /// end, other end, s), the crossing being at `lerp(under, other, s)` (motion vectors carry a
    /// crossing's previous position along the same edge).
    pub crossing_edges: Vec<(u32, u32, f32)>,
    /// Counter-clockwise as in the source mesh.
    pub above_triangles: Vec<[u32; 3]>,
    pub below_triangles: Vec<[u32; 3]>,
}

/// The exact water as the splitter sees it: a height field, present only inside the grid's extent.
#[derive(Clone, Copy)]
pub struct WaterVolume<'a> {
    pub surface: &'a dyn HeightField,
    pub extent: MembraneGrid,
}

impl WaterVolume<'_> {
    fn contains_xz(&self, x: f64, z: f64) -> bool {
        x >= self.extent.min_x
            && x <= self.extent.max_x
            && z >= self.extent.min_z
            && z <= self.extent.max_z
    }

    /// Height above the water surface (negative: under water); `None` outside the extent.
    pub fn height_above_surface_m(&self, point: DVec3) -> Option<f64> {
        self.contains_xz(point.x, point.z)
            .then(|| point.y - self.surface.height(point.x, point.z))
    }

    pub fn side_of(&self, point: DVec3) -> Side {
        match self.height_above_surface_m(point) {
            None => Side::Above,
            Some(h) if h > SURFACE_TOLERANCE_M => Side::Above,
            Some(h) if h < -SURFACE_TOLERANCE_M => Side::Below,
            Some(_) => Side::Surface,
        }
    }

    /// Whether the point is strictly under water (for the root finder: a sign test, no tolerance).
    fn is_under(&self, point: DVec3) -> bool {
        self.height_above_surface_m(point).is_some_and(|h| h < 0.0)
    }

    /// The point on segment `under`–`over` where the water ends, by bisection on the sign of
    /// `y - h(x, z)` (outside the extent counts as over) to [`SURFACE_TOLERANCE_M`] along the edge.
    /// Bisection, not secant: the sign function jumps at the extent's boundary, and bisection is the
    /// one method that is guaranteed to converge there too. Returns the edge parameter from `under`
    /// of the last point found UNDER water, so a cut at the extent's boundary stays inside it.
    fn crossing(&self, under: DVec3, over: DVec3) -> f64 {
        let length_m = (over - under).length();
        let (mut low, mut high) = (0.0_f64, 1.0_f64);
        // Stop at a tenth of the tolerance along the edge so the found point is within tolerance of
        // the surface even on edges steeper than 45 degrees to it... up to a slope of 10.
        while (high - low) * length_m > 0.1 * SURFACE_TOLERANCE_M {
            let mid = 0.5 * (low + high);
            if mid <= low || mid >= high {
                break;
            }
            if self.is_under(under.lerp(over, mid)) {
                low = mid;
            } else {
                high = mid;
            }
        }
        low
    }
}

/// Splits every triangle of `mesh` that has vertices both above and below the water.
/// A triangle with no vertex below is above (also one lying on the surface); one with no vertex
/// above is below. Surface vertices belong to both parts. Each crossing edge gets ONE new vertex,
/// shared by the triangles on both sides of the edge, so the split mesh has no cracks.
pub fn split_mesh(mesh: &Mesh, water: &WaterVolume) -> SplitMesh {
    let mut vertices: Vec<SplitVertex> = (0..mesh.positions.len())
        .map(|i| SplitVertex {
            position: mesh.positions[i],
            normal: mesh.normals.get(i).copied().unwrap_or(Vec3::Y),
            uv: mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO),
            side: water.side_of(mesh.positions[i].as_dvec3()),
        })
        .collect();
    let original_vertex_count = vertices.len();
    let mut above_triangles = Vec::with_capacity(mesh.triangles.len());
    let mut below_triangles = Vec::new();
    // Crossing vertex per edge (smaller index first), so both triangles on an edge share it.
    let mut crossings: std::collections::HashMap<(u32, u32), u32> = Default::default();
    let mut crossing_edges = Vec::new();

    for &triangle in &mesh.triangles {
        let sides = triangle.map(|i| vertices[i as usize].side);
        let any_above = sides.contains(&Side::Above);
        let any_below = sides.contains(&Side::Below);
        if !any_below {
            above_triangles.push(triangle);
            continue;
        }
        if !any_above {
            below_triangles.push(triangle);
            continue;
        }
        // Walk the triangle's boundary, building the two polygons (triangle clipped by the water).
        let mut above_polygon: Vec<u32> = Vec::with_capacity(4);
        let mut below_polygon: Vec<u32> = Vec::with_capacity(4);
        for corner in 0..3 {
            let (a, b) = (triangle[corner], triangle[(corner + 1) % 3]);
            let side_a = vertices[a as usize].side;
            let side_b = vertices[b as usize].side;
            match side_a {
                Side::Above => above_polygon.push(a),
                Side::Below => below_polygon.push(a),
                Side::Surface => {
                    above_polygon.push(a);
                    below_polygon.push(a);
                }
            }
            let crosses = matches!(
                (side_a, side_b),
                (Side::Above, Side::Below) | (Side::Below, Side::Above)
            );
            if crosses {
                let key = (a.min(b), a.max(b));
                let crossing = *crossings.entry(key).or_insert_with(|| {
                    // Always solve from the under-water end so both triangles get the same bits.
                    let (under, over) = if side_a == Side::Below {
                        (a, b)
                    } else {
                        (b, a)
                    };
                    let (under_index, over_index) = (under, over);
                    let (under, over) = (vertices[under as usize], vertices[over as usize]);
                    let s = water.crossing(under.position.as_dvec3(), over.position.as_dvec3());
                    let position = under.position.as_dvec3().lerp(over.position.as_dvec3(), s);
                    let s = s as f32;
                    let new_vertex = SplitVertex {
                        position: position.as_vec3(),
                        normal: under.normal.lerp(over.normal, s).normalize_or(under.normal),
                        uv: under.uv.lerp(over.uv, s),
                        // Under water by less than the tolerance (a surface crossing: Surface) or
                        // deeper (a cut at the extent's boundary: Below); never Above.
                        side: water.side_of(position),
                    };
                    vertices.push(new_vertex);
                    crossing_edges.push((under_index, over_index, s));
                    (vertices.len() - 1) as u32
                });
                above_polygon.push(crossing);
                below_polygon.push(crossing);
            }
        }
        fan_triangulate(&above_polygon, &mut above_triangles);
        fan_triangulate(&below_polygon, &mut below_triangles);
    }
    SplitMesh {
        vertices,
        original_vertex_count,
        crossing_edges,
        above_triangles,
        below_triangles,
    }
}

/// A triangle clipped by a straight cut is convex (3 or 4 corners), so a fan keeps the winding.
fn fan_triangulate(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for i in 1..polygon.len().saturating_sub(1) {
        out.push([polygon[0], polygon[i], polygon[i + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tilted, wavy analytic surface: y = 0.1 + 0.3 sin(1.7 x) cos(1.1 z).
    struct Wavy;
    impl HeightField for Wavy {
        fn height(&self, x: f64, z: f64) -> f64 {
            0.1 + 0.3 * (1.7 * x).sin() * (1.1 * z).cos()
        }
        fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
            (
                0.3 * 1.7 * (1.7 * x).cos() * (1.1 * z).cos(),
                -0.3 * 1.1 * (1.7 * x).sin() * (1.1 * z).sin(),
            )
        }
    }

    /// The membrane extents these tests use: squares of 8 x 8 cells.
    fn extent(half_m: f64) -> MembraneGrid {
        crate::refraction::search::test_support::square_grid(half_m, 8)
    }

    /// A vertical wall (x from -2 to 2, y from -1.5 to 1.5 at z = 0.3) tessellated n x n: it crosses the
    /// wavy surface along a curve, so many triangles are split, some through a vertex.
    fn wall(n: u32) -> Mesh {
        let mut mesh = Mesh::default();
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                mesh.positions
                    .push(Vec3::new(-2.0 + 4.0 * u, -1.5 + 3.0 * v, 0.3));
                mesh.normals.push(Vec3::Z);
                mesh.uvs.push(Vec2::new(u, v));
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                mesh.triangles.push([a, a + 1, a + n + 2]);
                mesh.triangles.push([a, a + n + 2, a + n + 1]);
            }
        }
        mesh
    }

    fn area(mesh_vertices: &[SplitVertex], triangle: [u32; 3]) -> f64 {
        let p = triangle.map(|i| mesh_vertices[i as usize].position.as_dvec3());
        0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
    }

    #[test]
    fn areas_are_conserved_and_sides_are_right() {
        let mesh = wall(13);
        let water = WaterVolume {
            surface: &Wavy,
            extent: extent(10.0),
        };
        let split = split_mesh(&mesh, &water);
        assert!(
            split.vertices.len() > split.original_vertex_count,
            "the wall must cross the water"
        );
        let original: f64 = mesh
            .triangles
            .iter()
            .map(|&t| {
                let p = t.map(|i| mesh.positions[i as usize].as_dvec3());
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum();
        let above: f64 = split
            .above_triangles
            .iter()
            .map(|&t| area(&split.vertices, t))
            .sum();
        let below: f64 = split
            .below_triangles
            .iter()
            .map(|&t| area(&split.vertices, t))
            .sum();
        assert!(
            ((above + below) - original).abs() < 1e-5 * original,
            "{above} + {below} != {original}"
        );
        // Classification: every vertex of an above triangle is above or on the surface (within the
        // tolerance), every vertex of a below triangle below or on it.
        for &t in &split.above_triangles {
            for i in t {
                let v = split.vertices[i as usize];
                assert_ne!(v.side, Side::Below, "{v:?} in an above triangle");
                let h = water.height_above_surface_m(v.position.as_dvec3()).unwrap();
                assert!(h > -2e-6, "above-part vertex {h} m under water");
            }
        }
        for &t in &split.below_triangles {
            for i in t {
                let v = split.vertices[i as usize];
                assert_ne!(v.side, Side::Above, "{v:?} in a below triangle");
                let h = water.height_above_surface_m(v.position.as_dvec3()).unwrap();
                assert!(h < 2e-6, "below-part vertex {h} m above water");
            }
        }
        // Interpolated attributes: crossings on this planar wall keep its normal and a uv that maps
        // back to the position.
        for v in &split.vertices[split.original_vertex_count..] {
            assert_eq!(v.side, Side::Surface);
            assert!((v.normal - Vec3::Z).length() < 1e-6);
            let expected_uv = Vec2::new((v.position.x + 2.0) / 4.0, (v.position.y + 1.5) / 3.0);
            assert!((v.uv - expected_uv).length() < 1e-5, "{v:?}");
        }
        // The area below equals the integral of the wall under the surface, to the accuracy of the
        // straight cut across each triangle (second order in the tessellation).
        let exact_below: f64 = (0..4000)
            .map(|k| {
                let x = -2.0 + 4.0 * (k as f64 + 0.5) / 4000.0;
                (Wavy.height(x, 0.3) + 1.5).clamp(0.0, 3.0) * 4.0 / 4000.0
            })
            .sum();
        assert!(
            (below - exact_below).abs() < 0.01 * exact_below,
            "{below} vs {exact_below}"
        );
    }

    /// No seam: the crossing vertex of an edge is ONE vertex, referenced by the above and the below
    /// parts of both triangles sharing the edge; and every surface vertex is really on the surface.
    #[test]
    fn surface_vertices_are_shared_by_both_parts() {
        let mesh = wall(9);
        let water = WaterVolume {
            surface: &Wavy,
            extent: extent(10.0),
        };
        let split = split_mesh(&mesh, &water);
        let count_uses =
            |triangles: &[[u32; 3]], i: u32| triangles.iter().filter(|t| t.contains(&i)).count();
        let mut crossing_count = 0;
        for i in split.original_vertex_count..split.vertices.len() {
            let v = split.vertices[i];
            let h = water.height_above_surface_m(v.position.as_dvec3()).unwrap();
            assert!(h.abs() <= 1e-6, "crossing {i} is {h} m off the surface");
            assert!(count_uses(&split.above_triangles, i as u32) >= 1);
            assert!(count_uses(&split.below_triangles, i as u32) >= 1);
            crossing_count += 1;
        }
        assert!(crossing_count >= 9);
        // No two crossing vertices at the same position (a duplicate would mean an edge solved twice).
        let crossings = &split.vertices[split.original_vertex_count..];
        for (i, a) in crossings.iter().enumerate() {
            for b in &crossings[i + 1..] {
                assert_ne!(a.position, b.position);
            }
        }
        // Every edge of the split mesh used by exactly one triangle lies on the mesh border: a crack
        // would show up as an interior edge used once.
        let mut edge_uses: std::collections::HashMap<(u32, u32), u32> = Default::default();
        for t in split.above_triangles.iter().chain(&split.below_triangles) {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edge_uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        for (&(a, b), &uses) in &edge_uses {
            if uses == 1 {
                let (pa, pb) = (
                    split.vertices[a as usize].position,
                    split.vertices[b as usize].position,
                );
                let on_border =
                    |p: Vec3| (p.x.abs() - 2.0).abs() < 1e-5 || (p.y.abs() - 1.5).abs() < 1e-5;
                assert!(on_border(pa) && on_border(pb), "crack along {pa} - {pb}");
            } else {
                assert_eq!(uses, 2);
            }
        }
    }

    /// A vertex exactly on the surface is shared, not duplicated: the triangle splits into one
    /// above and one below triangle through it.
    #[test]
    fn vertex_on_surface_splits_through_it() {
        let mesh = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 3],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE],
            triangles: vec![[0, 1, 2]],
        };
        let water = WaterVolume {
            surface: &crate::water::FlatHeightField { level_m: 0.0 },
            extent: extent(5.0),
        };
        let split = split_mesh(&mesh, &water);
        assert_eq!(split.vertices[0].side, Side::Surface);
        assert_eq!(split.vertices.len(), 4);
        assert_eq!(split.above_triangles.len(), 1);
        assert_eq!(split.below_triangles.len(), 1);
        let crossing = split.vertices[3];
        assert!((crossing.position - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-6);
        assert!((crossing.uv - Vec2::new(1.0, 0.5)).length() < 1e-6);
        assert!(split.above_triangles[0].contains(&0) && split.below_triangles[0].contains(&0));
        assert!(split.above_triangles[0].contains(&2) && split.below_triangles[0].contains(&1));
        // Winding kept: both parts face the same way as the original (+z).
        for t in split.above_triangles.iter().chain(&split.below_triangles) {
            let p = t.map(|i| split.vertices[i as usize].position);
            assert!((p[1] - p[0]).cross(p[2] - p[0]).z > 0.0);
        }
    }

    /// Outside the membrane's extent there is no water: a deep vertex there is above. An edge from
    /// under water inside to outside is cut at the extent's boundary, and that cut is under water.
    #[test]
    fn outside_the_extent_is_above() {
        let mesh = Mesh {
            positions: vec![
                Vec3::new(0.0, -1.0, 0.0),
                Vec3::new(3.0, -1.0, 0.0),
                Vec3::new(0.0, -1.0, 1.0),
            ],
            normals: vec![Vec3::Y; 3],
            uvs: vec![Vec2::ZERO; 3],
            triangles: vec![[0, 2, 1]],
        };
        let water = WaterVolume {
            surface: &crate::water::FlatHeightField { level_m: 0.0 },
            extent: extent(2.0),
        };
        let split = split_mesh(&mesh, &water);
        assert_eq!(split.vertices[1].side, Side::Above);
        assert_eq!(split.vertices.len(), 5);
        for cut in &split.vertices[3..] {
            assert!((cut.position.x - 2.0).abs() < 1e-6, "{cut:?}");
            assert_eq!(cut.side, Side::Below);
        }
    }
}
