//! Built-in primitives as finely tessellated meshes with unit normals and uvs in metres: box, UV
//! sphere, quad and a tiled pool (floor, four inner walls, deck). Tessellation is fine on purpose:
//! virtual vertices are computed per vertex, so an under-water surface bends only where it has
//! vertices; `max_edge_m` bounds the grid spacing (default 0.1 m).

use glam::{DQuat, DVec3, Vec2, Vec3};

use crate::mesh::Mesh;

/// The grid spacing used when a scene does not say.
pub const DEFAULT_MAX_EDGE_M: f64 = 0.1;

/// The deck never goes under water, so it only needs fine vertices along the rim (to meet the
/// walls without T-junction cracks); outwards it is coarse.
const DECK_OUTWARD_EDGE_M: f64 = 0.5;

fn segments(length_m: f64, max_edge_m: f64) -> u32 {
    // Saturates (as `as` does) for lengths no scene within its limits has.
    (length_m / max_edge_m).ceil().max(1.0) as u32
}

/// Vertices and triangles of [`add_grid`] over edges of these lengths (the meshes' counts known
/// before they are built, for the scene's resource estimate).
fn grid_counts(len_u: f64, len_v: f64, max_edge_m: [f64; 2]) -> (u64, u64) {
    let (nu, nv) = (
        segments(len_u, max_edge_m[0]) as u64,
        segments(len_v, max_edge_m[1]) as u64,
    );
    ((nu + 1) * (nv + 1), 2 * nu * nv)
}

/// (vertices, triangles) [`box_mesh`] builds, computed without building it; saturates instead
/// of overflowing for absurd sizes.
pub fn box_counts(size_m: DVec3, max_edge_m: f64) -> (u64, u64) {
    let faces = [
        (size_m.z, size_m.y),
        (size_m.x, size_m.z),
        (size_m.x, size_m.y),
    ];
    faces.iter().fold((0, 0), |(v, t), &(u, w)| {
        let (fv, ft) = grid_counts(u, w, [max_edge_m; 2]);
        (v.saturating_add(2 * fv), t.saturating_add(2 * ft))
    })
}

/// (vertices, triangles) of [`sphere_mesh`].
pub fn sphere_counts(radius_m: f64, max_edge_m: f64) -> (u64, u64) {
    use std::f64::consts::PI;
    let rings = segments(PI * radius_m, max_edge_m).max(4) as u64;
    let segs = segments(2.0 * PI * radius_m, max_edge_m).max(8) as u64;
    (
        (rings - 1) * (segs + 1) + 2 * segs,
        2 * segs + 2 * (rings - 2) * segs,
    )
}

/// (vertices, triangles) of [`quad_mesh`].
pub fn quad_counts(size_m: [f64; 2], max_edge_m: f64) -> (u64, u64) {
    grid_counts(size_m[0], size_m[1], [max_edge_m; 2])
}

/// (vertices, triangles) of all three parts of [`pool_meshes`].
pub fn pool_counts(dims: &PoolDims, max_edge_m: f64) -> (u64, u64) {
    let (length_x, length_z) = (
        dims.max_xz[0] - dims.min_xz[0],
        dims.max_xz[1] - dims.min_xz[1],
    );
    let wall_height = dims.depth_m + dims.coping_height_m;
    let w = dims.deck_width_m;
    let outward = DECK_OUTWARD_EDGE_M.max(max_edge_m);
    let fine = [max_edge_m; 2];
    let grids = [
        grid_counts(length_x, length_z, fine),
        grid_counts(length_x, wall_height, fine),
        grid_counts(length_x, wall_height, fine),
        grid_counts(length_z, wall_height, fine),
        grid_counts(length_z, wall_height, fine),
        grid_counts(length_x, w, [max_edge_m, outward]),
        grid_counts(length_x, w, [max_edge_m, outward]),
        grid_counts(w, length_z, [outward, max_edge_m]),
        grid_counts(w, length_z, [outward, max_edge_m]),
        grid_counts(w, w, [outward; 2]),
        grid_counts(w, w, [outward; 2]),
        grid_counts(w, w, [outward; 2]),
        grid_counts(w, w, [outward; 2]),
    ];
    grids.iter().fold((0, 0), |(v, t), &(gv, gt)| {
        (v.saturating_add(gv), t.saturating_add(gt))
    })
}

fn push_vertex(mesh: &mut Mesh, position: DVec3, normal: DVec3, uv_m: [f64; 2]) -> u32 {
    let index = mesh.positions.len() as u32;
    mesh.positions.push(position.as_vec3());
    mesh.normals.push(normal.normalize().as_vec3());
    mesh.uvs.push(Vec2::new(uv_m[0] as f32, uv_m[1] as f32));
    index
}

/// Pushes a triangle, ordered counter-clockwise as seen from the side its vertex normals face.
fn push_triangle_facing(mesh: &mut Mesh, [a, b, c]: [u32; 3]) {
    let p = |i: u32| mesh.positions[i as usize];
    let geometric = (p(b) - p(a)).cross(p(c) - p(a));
    let facing: Vec3 = [a, b, c].iter().map(|&i| mesh.normals[i as usize]).sum();
    if geometric.dot(facing) >= 0.0 {
        mesh.triangles.push([a, b, c]);
    } else {
        mesh.triangles.push([a, c, b]);
    }
}

/// A planar grid over the parallelogram `corner + s * edge_u + t * edge_v` (s, t in [0, 1]), cells no
/// longer than `max_edge_m[0]` along u and `max_edge_m[1]` along v; uvs in metres from `uv_corner_m`.
fn add_grid(
    mesh: &mut Mesh,
    corner: DVec3,
    edge_u: DVec3,
    edge_v: DVec3,
    normal: DVec3,
    uv_corner_m: [f64; 2],
    max_edge_m: [f64; 2],
) {
    let (len_u, len_v) = (edge_u.length(), edge_v.length());
    let (nu, nv) = (
        segments(len_u, max_edge_m[0]),
        segments(len_v, max_edge_m[1]),
    );
    let first = mesh.positions.len() as u32;
    for j in 0..=nv {
        let t = j as f64 / nv as f64;
        for i in 0..=nu {
            let s = i as f64 / nu as f64;
            let position = corner + edge_u * s + edge_v * t;
            push_vertex(
                mesh,
                position,
                normal,
                [uv_corner_m[0] + s * len_u, uv_corner_m[1] + t * len_v],
            );
        }
    }
    let index = |i: u32, j: u32| first + j * (nu + 1) + i;
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            push_triangle_facing(mesh, [a, b, c]);
            push_triangle_facing(mesh, [a, c, d]);
        }
    }
}

/// An axis-aligned box of `size_m`, centred at the origin, normals outward; each face a grid.
pub fn box_mesh(size_m: DVec3, max_edge_m: f64) -> Mesh {
    let mut mesh = Mesh::default();
    let h = size_m * 0.5;
    // (outward normal, the face's two in-plane axes)
    let faces = [
        (DVec3::X, DVec3::Z, DVec3::Y),
        (DVec3::NEG_X, DVec3::Z, DVec3::Y),
        (DVec3::Y, DVec3::X, DVec3::Z),
        (DVec3::NEG_Y, DVec3::X, DVec3::Z),
        (DVec3::Z, DVec3::X, DVec3::Y),
        (DVec3::NEG_Z, DVec3::X, DVec3::Y),
    ];
    for (normal, axis_u, axis_v) in faces {
        let centre = normal * h;
        let (edge_u, edge_v) = (axis_u * size_m, axis_v * size_m);
        let corner = centre - edge_u * 0.5 - edge_v * 0.5;
        add_grid(
            &mut mesh,
            corner,
            edge_u,
            edge_v,
            normal,
            [0.0, 0.0],
            [max_edge_m, max_edge_m],
        );
    }
    mesh
}

/// A UV sphere of `radius_m` centred at the origin; uvs are metres along the equator and meridian.
/// Each pole is a fan of distinct vertices (one per segment, for their uvs), so no triangle is degenerate.
pub fn sphere_mesh(radius_m: f64, max_edge_m: f64) -> Mesh {
    use std::f64::consts::PI;
    let rings = segments(PI * radius_m, max_edge_m).max(4);
    let segs = segments(2.0 * PI * radius_m, max_edge_m).max(8);
    let mut mesh = Mesh::default();
    let point = |theta: f64, phi: f64| {
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        )
    };
    // Rings 1..rings-1, each with a duplicated seam vertex.
    let ring_index = |k: u32, j: u32| (k - 1) * (segs + 1) + j;
    for k in 1..rings {
        let theta = PI * k as f64 / rings as f64;
        for j in 0..=segs {
            let phi = 2.0 * PI * j as f64 / segs as f64;
            let n = point(theta, phi);
            push_vertex(
                &mut mesh,
                n * radius_m,
                n,
                [phi * radius_m, theta * radius_m],
            );
        }
    }
    for (pole_theta, ring) in [(0.0, 1), (PI, rings - 1)] {
        for j in 0..segs {
            let phi = 2.0 * PI * (j as f64 + 0.5) / segs as f64;
            let n = point(pole_theta, 0.0);
            let pole = push_vertex(
                &mut mesh,
                n * radius_m,
                n,
                [phi * radius_m, pole_theta * radius_m],
            );
            push_triangle_facing(
                &mut mesh,
                [pole, ring_index(ring, j), ring_index(ring, j + 1)],
            );
        }
    }
    for k in 1..rings - 1 {
        for j in 0..segs {
            let (a, b) = (ring_index(k, j), ring_index(k, j + 1));
            let (c, d) = (ring_index(k + 1, j + 1), ring_index(k + 1, j));
            push_triangle_facing(&mut mesh, [a, b, c]);
            push_triangle_facing(&mut mesh, [a, c, d]);
        }
    }
    mesh
}

/// A horizontal rectangle `size_m` = [x, z] centred at the origin, normal +y.
pub fn quad_mesh(size_m: [f64; 2], max_edge_m: f64) -> Mesh {
    let mut mesh = Mesh::default();
    let (edge_u, edge_v) = (DVec3::X * size_m[0], DVec3::Z * size_m[1]);
    let corner = -(edge_u + edge_v) * 0.5;
    add_grid(
        &mut mesh,
        corner,
        edge_u,
        edge_v,
        DVec3::Y,
        [0.0, 0.0],
        [max_edge_m, max_edge_m],
    );
    mesh
}

/// A pool basin: its inner faces are the rectangle `min_xz`..`max_xz` (the water membrane's extent).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoolDims {
    pub min_xz: [f64; 2],
    pub max_xz: [f64; 2],
    pub water_level_m: f64,
    /// Floor below the water level.
    pub depth_m: f64,
    /// Top of the walls and the deck above the water level.
    pub coping_height_m: f64,
    /// How far the deck reaches outwards from the rim.
    pub deck_width_m: f64,
}

/// The pool's parts, kept apart so each can carry its own texture.
#[derive(Clone, Debug, PartialEq)]
pub struct PoolMeshes {
    pub floor: Mesh,
    pub walls: Mesh,
    pub deck: Mesh,
}

/// Floor, four inner walls (normals into the pool) and the deck ring around the rim (normal up).
/// Uvs in metres: floor and deck by (x, z) from the pool's min corner, walls by (distance along the
/// wall, height above the floor), so tiles line up where walls meet the floor.
pub fn pool_meshes(dims: &PoolDims, max_edge_m: f64) -> PoolMeshes {
    let [x0, z0] = dims.min_xz;
    let [x1, z1] = dims.max_xz;
    let floor_y = dims.water_level_m - dims.depth_m;
    let top_y = dims.water_level_m + dims.coping_height_m;
    let wall_height = top_y - floor_y;
    let (length_x, length_z) = (x1 - x0, z1 - z0);

    let mut floor = Mesh::default();
    add_grid(
        &mut floor,
        DVec3::new(x0, floor_y, z0),
        DVec3::X * length_x,
        DVec3::Z * length_z,
        DVec3::Y,
        [0.0, 0.0],
        [max_edge_m, max_edge_m],
    );

    let mut walls = Mesh::default();
    let up = DVec3::Y * wall_height;
    // (corner at floor level, direction along the wall, inward normal, uv distance offset)
    let wall_specs = [
        (DVec3::new(x0, floor_y, z0), DVec3::X * length_x, DVec3::Z),
        (
            DVec3::new(x0, floor_y, z1),
            DVec3::X * length_x,
            DVec3::NEG_Z,
        ),
        (DVec3::new(x0, floor_y, z0), DVec3::Z * length_z, DVec3::X),
        (
            DVec3::new(x1, floor_y, z0),
            DVec3::Z * length_z,
            DVec3::NEG_X,
        ),
    ];
    for (corner, along, inward) in wall_specs {
        add_grid(
            &mut walls,
            corner,
            along,
            up,
            inward,
            [0.0, 0.0],
            [max_edge_m, max_edge_m],
        );
    }

    let mut deck = Mesh::default();
    let w = dims.deck_width_m;
    let outward = DECK_OUTWARD_EDGE_M.max(max_edge_m);
    let deck_uv = |p: DVec3| [p.x - x0, p.z - z0];
    // Four strips along the rim (fine along it, to match the walls' top edges)...
    let strips = [
        (
            DVec3::new(x0, top_y, z0 - w),
            DVec3::X * length_x,
            DVec3::Z * w,
            max_edge_m,
            outward,
        ),
        (
            DVec3::new(x0, top_y, z1),
            DVec3::X * length_x,
            DVec3::Z * w,
            max_edge_m,
            outward,
        ),
        (
            DVec3::new(x0 - w, top_y, z0),
            DVec3::X * w,
            DVec3::Z * length_z,
            outward,
            max_edge_m,
        ),
        (
            DVec3::new(x1, top_y, z0),
            DVec3::X * w,
            DVec3::Z * length_z,
            outward,
            max_edge_m,
        ),
    ];
    // ...and four corner squares.
    let corners = [(x0 - w, z0 - w), (x1, z0 - w), (x0 - w, z1), (x1, z1)].map(|(x, z)| {
        (
            DVec3::new(x, top_y, z),
            DVec3::X * w,
            DVec3::Z * w,
            outward,
            outward,
        )
    });
    for (corner, edge_u, edge_v, max_u, max_v) in strips.into_iter().chain(corners) {
        add_grid(
            &mut deck,
            corner,
            edge_u,
            edge_v,
            DVec3::Y,
            deck_uv(corner),
            [max_u, max_v],
        );
    }

    PoolMeshes { floor, walls, deck }
}

/// Applies scale, then rotation, then translation (world_from_local = T * R * S) to positions, and
/// the inverse-transpose to normals.
pub fn transformed(mut mesh: Mesh, translate: DVec3, rotation: DQuat, scale: DVec3) -> Mesh {
    for p in &mut mesh.positions {
        *p = (rotation * (p.as_dvec3() * scale) + translate).as_vec3();
    }
    for n in &mut mesh.normals {
        *n = (rotation * (n.as_dvec3() / scale)).normalize().as_vec3();
    }
    mesh
}

/// Yaw about +y, then pitch about +x, then roll about +z, applied to the object in the order roll,
/// pitch, yaw (R = Ry * Rx * Rz), angles in degrees.
pub fn rotation_from_yaw_pitch_roll_deg([yaw, pitch, roll]: [f64; 3]) -> DQuat {
    DQuat::from_euler(
        glam::EulerRot::YXZ,
        yaw.to_radians(),
        pitch.to_radians(),
        roll.to_radians(),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// pool.toml's pool: 10 m x 5 m, 1.6 m deep, a 3 m deck.
    fn pool_dims() -> PoolDims {
        PoolDims {
            min_xz: [-5.0, -2.5],
            max_xz: [5.0, 2.5],
            water_level_m: 0.0,
            depth_m: 1.6,
            coping_height_m: 0.25,
            deck_width_m: 3.0,
        }
    }

    #[test]
    fn counts_known_before_building_equal_the_built_meshes() {
        let count = |mesh: &Mesh| (mesh.positions.len() as u64, mesh.triangles.len() as u64);
        for (size, edge) in [
            (DVec3::new(1.0, 0.5, 0.8), 0.1),
            (DVec3::new(3.3, 0.01, 2.0), 0.07),
            (DVec3::new(0.2, 0.2, 0.2), 1.0),
        ] {
            assert_eq!(box_counts(size, edge), count(&box_mesh(size, edge)));
            assert_eq!(
                quad_counts([size.x, size.z], edge),
                count(&quad_mesh([size.x, size.z], edge))
            );
            assert_eq!(
                sphere_counts(size.x, edge),
                count(&sphere_mesh(size.x, edge))
            );
        }
        let dims = pool_dims();
        for edge in [0.1, 0.33, 0.7] {
            let pool = pool_meshes(&dims, edge);
            let (v, t) = [&pool.floor, &pool.walls, &pool.deck]
                .iter()
                .map(|m| count(m))
                .fold((0, 0), |(v, t), (mv, mt)| (v + mv, t + mt));
            assert_eq!(pool_counts(&dims, edge), (v, t), "edge {edge}");
        }
    }

    /// Checks what every mesh must satisfy: matching attribute lengths, valid indices, unit normals,
    /// no degenerate triangles, and each triangle's winding agreeing with its vertex normals.
    pub(crate) fn assert_well_formed(mesh: &Mesh) {
        let n = mesh.positions.len();
        assert_eq!(mesh.normals.len(), n);
        assert_eq!(mesh.uvs.len(), n);
        assert!(!mesh.triangles.is_empty());
        for normal in &mesh.normals {
            assert!(
                (normal.length() - 1.0).abs() < 1e-5,
                "normal {normal} is not unit"
            );
        }
        for tri in &mesh.triangles {
            assert!(
                tri.iter().all(|&i| (i as usize) < n),
                "index out of range in {tri:?}"
            );
            let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
            let geometric = (b - a).cross(c - a);
            assert!(
                geometric.length() > 1e-7,
                "degenerate triangle {tri:?}: {a} {b} {c}"
            );
            for &i in tri {
                let agree = geometric.normalize().dot(mesh.normals[i as usize]);
                assert!(
                    agree > 0.5,
                    "triangle {tri:?} winds against its normals ({agree})"
                );
            }
        }
    }

    fn max_edge(mesh: &Mesh) -> f32 {
        mesh.triangles
            .iter()
            .flat_map(|t| {
                let p = t.map(|i| mesh.positions[i as usize]);
                [
                    (p[0] - p[1]).length(),
                    (p[1] - p[2]).length(),
                    (p[2] - p[0]).length(),
                ]
            })
            .fold(0.0, f32::max)
    }

    /// Summed in f64: thousands of f32 additions would drift by more than the geometry's error.
    fn surface_area_m2(mesh: &Mesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| mesh.positions[i as usize].as_dvec3());
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum()
    }

    fn bounds(mesh: &Mesh) -> (Vec3, Vec3) {
        let min = mesh
            .positions
            .iter()
            .fold(Vec3::splat(f32::INFINITY), |m, p| m.min(*p));
        let max = mesh
            .positions
            .iter()
            .fold(Vec3::splat(f32::NEG_INFINITY), |m, p| m.max(*p));
        (min, max)
    }

    #[test]
    fn box_is_closed_outward_and_finely_gridded() {
        let mesh = box_mesh(DVec3::new(1.0, 0.5, 0.3), 0.1);
        assert_well_formed(&mesh);
        let (min, max) = bounds(&mesh);
        assert!((max - min - Vec3::new(1.0, 0.5, 0.3)).abs().max_element() < 1e-6);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            assert!(p.dot(*n) > 0.0, "normal {n} at {p} points inward");
        }
        // Grid spacing 0.1 m: cell diagonals at most 0.1 * sqrt(2).
        assert!(max_edge(&mesh) <= 0.1 * 2f32.sqrt() + 1e-5);
        // Faces 10x5 (two), 10x3 (two), 5x3 (two) cells, two triangles each.
        assert_eq!(mesh.triangle_count(), 2 * 2 * (50 + 30 + 15));
        // Surface area is the box's.
        let area = surface_area_m2(&mesh);
        assert!(
            (area - 2.0 * (0.5 + 0.3 + 0.15)).abs() < 1e-5,
            "area {area}"
        );
    }

    #[test]
    fn sphere_vertices_on_the_surface_normals_radial() {
        let radius = 0.3;
        let mesh = sphere_mesh(radius, 0.1);
        assert_well_formed(&mesh);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            assert!((p.length() - radius as f32).abs() < 1e-6);
            assert!(
                (*p / radius as f32 - *n).length() < 1e-5,
                "normal {n} at {p} not radial"
            );
        }
        assert!(max_edge(&mesh) <= 0.1 * 1.5, "edge {}", max_edge(&mesh));
    }

    #[test]
    fn quad_faces_up_with_metre_uvs() {
        let mesh = quad_mesh([2.0, 1.0], 0.1);
        assert_well_formed(&mesh);
        assert!(mesh.normals.iter().all(|n| *n == Vec3::Y));
        let (min, max) = bounds(&mesh);
        assert_eq!(
            (min, max),
            (Vec3::new(-1.0, 0.0, -0.5), Vec3::new(1.0, 0.0, 0.5))
        );
        let uv_max = mesh.uvs.iter().fold(Vec2::ZERO, |m, uv| m.max(*uv));
        assert!((uv_max - Vec2::new(2.0, 1.0)).length() < 1e-6);
    }

    #[test]
    fn transform_moves_rotates_scales_and_keeps_normals_outward() {
        let mesh = sphere_mesh(1.0, 0.3);
        let rotation = rotation_from_yaw_pitch_roll_deg([30.0, 20.0, 10.0]);
        let centre = DVec3::new(1.0, -1.0, 2.0);
        let moved = transformed(mesh, centre, rotation, DVec3::new(2.0, 1.0, 0.5));
        assert_well_formed(&moved);
        for (p, n) in moved.positions.iter().zip(&moved.normals) {
            assert!((p.as_dvec3() - centre).dot(n.as_dvec3()) > 0.0);
        }
        // Yaw 90 deg turns +x into -z (right-handed, about +y).
        let yaw = rotation_from_yaw_pitch_roll_deg([90.0, 0.0, 0.0]);
        assert!((yaw * DVec3::X - DVec3::NEG_Z).length() < 1e-12);
    }

    #[test]
    fn pool_walls_sit_exactly_on_the_water_extent() {
        let dims = pool_dims();
        let pool = pool_meshes(&dims, 0.1);
        for mesh in [&pool.floor, &pool.walls, &pool.deck] {
            assert_well_formed(mesh);
        }
        assert!(pool.floor.positions.iter().all(|p| p.y == -1.6));
        assert!(pool.floor.normals.iter().all(|n| *n == Vec3::Y));
        let (min, max) = bounds(&pool.floor);
        assert_eq!((min.x, min.z, max.x, max.z), (-5.0, -2.5, 5.0, 2.5));
        // Every wall vertex is on one of the four extent edges, its normal pointing into the pool.
        for (p, n) in pool.walls.positions.iter().zip(&pool.walls.normals) {
            let on_edge = p.x == -5.0 || p.x == 5.0 || p.z == -2.5 || p.z == 2.5;
            assert!(on_edge, "wall vertex {p} is off the extent");
            assert!(
                Vec3::new(-p.x, 0.0, -p.z).dot(*n) > 0.0,
                "wall normal {n} at {p} points out"
            );
            assert!(n.y == 0.0);
            assert!(p.y >= -1.6 && p.y <= 0.25);
        }
        let (min, max) = bounds(&pool.walls);
        assert_eq!((min.y, max.y), (-1.6, 0.25));
        // The wall's area is the pool's perimeter times its height.
        let area = surface_area_m2(&pool.walls);
        assert!((area - 30.0 * 1.85).abs() < 1e-4, "wall area {area}");
        // The deck is a flat ring at the coping height, outside the pool, 3 m wide.
        assert!(pool.deck.positions.iter().all(|p| p.y == 0.25));
        assert!(pool
            .deck
            .positions
            .iter()
            .all(|p| p.x <= -5.0 || p.x >= 5.0 || p.z <= -2.5 || p.z >= 2.5));
        let (min, max) = bounds(&pool.deck);
        assert_eq!((min.x, min.z, max.x, max.z), (-8.0, -5.5, 8.0, 5.5));
        // Under-water parts are fine: no edge longer than a 0.1 m cell's diagonal.
        assert!(max_edge(&pool.floor) <= 0.1 * 2f32.sqrt() + 1e-5);
        assert!(max_edge(&pool.walls) <= 0.1 * 2f32.sqrt() + 1e-5);
    }
}
