//! Tests of the exact method as the frame uses it: every image under a focusing crest, the Newton
//! fallback, exactness on flat water against the bisection oracle, and the adaptive subdivision
//! (midpoint images within tolerance, no T-junctions, the water line kept).

use std::collections::HashMap;

use glam::{DVec2, Vec2, Vec3};

use super::exact::{path_is_clear, ExactImage, FermatProblem};
use super::flat::{flat_virtual_vertex, virtual_vertex};
use super::search::test_support::{flat, membrane_from, Bounded};
use super::search::{Image, RefractionField};
use super::subdivision::{distance_to_segment, SubdivisionSettings};
use super::surface::ExactSurface;
use super::virtual_geometry::tests::{assert_water_line_vertex, grid, setup, Crest};
use super::virtual_geometry::{
    build_virtual_geometry, build_virtual_geometry_with, exact_vertex_images, query_height_range,
    ImageSearch, Placement, VirtualGeometry, VirtualGeometryRequest, WaterlineSkirt,
};
use crate::camera::Camera;
use crate::draw::flag_bits;
use crate::mesh::{Material, Mesh, Object};
use crate::water::{FlatHeightField, HeightField, Membrane};

const N_AIR: f32 = 1.0;
const N_WATER: f32 = 1.333;

/// The virtual-geometry tests' steep Gaussian ridge, at x = 0: a lens that focuses rays, so
/// points deep under it have several images.
const CREST: Crest = Crest { centre_x_m: 0.0 };

/// Flat water whose second derivatives are undefined: the cells (heights, slopes) work, Newton
/// (which needs the Hessian) cannot. Forces the fallback.
struct NoHessian;
impl HeightField for NoHessian {
    fn height(&self, _: f64, _: f64) -> f64 {
        0.0
    }
    fn gradient(&self, _: f64, _: f64) -> (f64, f64) {
        (0.0, 0.0)
    }
    fn hessian(&self, _: f64, _: f64) -> (f64, f64, f64) {
        (f64::NAN, f64::NAN, f64::NAN)
    }
}
impl Bounded for NoHessian {
    fn exact(&self, extent: crate::water::MembraneGrid) -> ExactSurface<'_> {
        flat(self, 0.0, extent)
    }
}

fn object(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Object {
    let n = positions.len();
    Object {
        name: "test".into(),
        mesh: Mesh {
            uvs: positions.iter().map(|p| Vec2::new(p.x, p.z)).collect(),
            positions,
            normals: vec![Vec3::Y; n],
            triangles,
        },
        material: Material {
            texture: 0,
            tint_linear: Vec3::ONE,
        },
    }
}

/// A square grid of `n` x `n` quads over [x0, x1] x [z0, z1], its height given per (x, z).
fn sheet(
    n: u32,
    (x0, x1): (f32, f32),
    (z0, z1): (f32, f32),
    y: impl Fn(f32, f32) -> f32,
) -> Object {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let x = x0 + (x1 - x0) * i as f32 / n as f32;
            let z = z0 + (z1 - z0) * j as f32 / n as f32;
            positions.push(Vec3::new(x, y(x, z), z));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            triangles.push([a, a + n + 1, a + n + 2]);
            triangles.push([a, a + n + 2, a + 1]);
        }
    }
    object(positions, triangles)
}

fn geometry(
    membrane: &Membrane,
    surface: &impl Bounded,
    camera: Camera,
    image_size: (u32, u32),
    objects: &[Object],
    placement: Placement,
) -> VirtualGeometry {
    let water = surface.exact(membrane.grid);
    let field = RefractionField::build(
        membrane,
        &water,
        setup(camera.eye),
        query_height_range(objects, membrane),
    );
    let request = VirtualGeometryRequest {
        field: &field,
        camera,
        image_size,
        objects,
        mean_level_m: 0.0,
        search: ImageSearch::Accelerated,
    };
    build_virtual_geometry_with(&request, None, placement)
}

/// Under the crest, a point the linear method sees several times: the exact method finds as many
/// exact images, each a stationary point of L (|grad L| ~ 0) with a clear path, all distinct,
/// none a fallback; the frame flags the convergence zone and draws the least-optical-path one.
#[test]
fn exact_mode_finds_every_image_under_a_crest() {
    let membrane = membrane_from(&CREST, grid((-1.5, -1.0), (1.5, 1.0), (96, 16)));
    let eye = Vec3::new(0.0, 2.5, -1.5);
    let water = CREST.exact(membrane.grid);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-2.5, 0.4));
    let mut linear: Vec<Image> = Vec::new();
    let point = [-1.2_f32, -1.6, -2.0]
        .into_iter()
        .flat_map(|y| (0..9).map(move |i| Vec3::new(-0.08 + 0.02 * i as f32, y, 0.4)))
        .find(|&p| {
            field.images_brute_force(p, &mut linear);
            linear.len() > 1
        })
        .expect("a point under the crest with several linear images");
    let mut exact: Vec<ExactImage> = Vec::new();
    let (images, chosen) = exact_vertex_images(
        &field,
        point,
        ImageSearch::Accelerated,
        &mut linear,
        &mut exact,
    );
    eprintln!(
        "point {point}: {} linear images, exact {:?}",
        linear.len(),
        exact
    );
    assert_eq!(exact.len(), linear.len(), "{exact:?} from {linear:?}");
    assert_eq!(images.image_count as usize, exact.len());
    let problem = FermatProblem {
        surface: &CREST,
        eye: eye.as_dvec3(),
        point: point.as_dvec3(),
        n_above: N_AIR as f64,
        n_below: N_WATER as f64,
    };
    for image in &exact {
        assert!(!image.newton_fallback);
        let s = image.sight_point;
        assert!((s.y - CREST.height(s.x, s.z)).abs() < 1e-15);
        let g = problem.optical_gradient(DVec2::new(s.x, s.z));
        assert!(g.length() < 1e-11, "{image:?}: |grad L| {}", g.length());
        assert!(path_is_clear(&water, &problem, s), "{image:?}");
    }
    for (i, a) in exact.iter().enumerate() {
        for b in &exact[i + 1..] {
            // Distinct images, more than a facet (3 / 96 m) apart.
            assert!(
                (a.sight_point - b.sight_point).length() > 3.0 / 96.0,
                "{a:?} {b:?}"
            );
        }
    }
    // The chosen one has the least optical path.
    let least = exact
        .iter()
        .map(|i| problem.optical_path(DVec2::new(i.sight_point.x, i.sight_point.z)))
        .fold(f64::INFINITY, f64::min);
    let chosen = chosen.expect("an image");
    assert_eq!(
        problem.optical_path(DVec2::new(chosen.sight_point.x, chosen.sight_point.z)),
        least
    );

    // The frame: vertex and triangle flagged as a convergence zone, no fallback.
    let objects = [object(
        vec![
            point,
            point + Vec3::new(0.01, 0.0, 0.0),
            point + Vec3::new(0.0, 0.0, 0.01),
        ],
        vec![[0, 2, 1]],
    )];
    let camera = Camera {
        eye,
        target: point,
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near_m: crate::camera::NEAR_M,
        far_m: crate::camera::FAR_M,
    };
    let frame = geometry(
        &membrane,
        &CREST,
        camera,
        (640, 480),
        &objects,
        Placement::Exact(SubdivisionSettings::default()),
    );
    assert!(frame.counts.vertices.convergence >= 1, "{:?}", frame.counts);
    assert_eq!(frame.counts.vertices.newton_fallback, 0);
    assert_eq!(frame.counts.triangles.convergence, 1);
    assert!(frame
        .under_vertices
        .iter()
        .all(|v| v.flags & flag_bits::CONVERGENCE != 0));
    let drawn = frame
        .under_vertices
        .iter()
        .find(|v| Vec3::from(v.true_position) == point)
        .unwrap();
    let expected = virtual_vertex(
        eye.as_dvec3(),
        chosen.sight_point,
        point.as_dvec3(),
        N_AIR as f64,
        N_WATER as f64,
    );
    assert_eq!(Vec3::from(drawn.virtual_position), expected.as_vec3());
}

/// Where Newton cannot run, every vertex falls back to the linear point: counted per vertex as
/// `newton_fallback`, drawn exactly where the equal-t method draws it. The linear methods never
/// count it, and their reports do not even carry the key (old goldens stay valid).
#[test]
fn newton_failure_falls_back_to_the_linear_point_and_is_counted() {
    let membrane = membrane_from(&NoHessian, grid((-2.0, -2.0), (2.0, 2.0), (32, 32)));
    let eye = Vec3::new(0.2, 1.0, -1.7);
    let camera = Camera {
        eye,
        target: Vec3::new(0.0, -1.0, 0.3),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        near_m: crate::camera::NEAR_M,
        far_m: crate::camera::FAR_M,
    };
    let objects = [sheet(6, (-1.0, 1.0), (-1.0, 1.2), |x, _| -0.8 - 0.2 * x)];
    let linear = geometry(
        &membrane,
        &NoHessian,
        camera,
        (640, 480),
        &objects,
        Placement::Linear,
    );
    let exact = geometry(
        &membrane,
        &NoHessian,
        camera,
        (640, 480),
        &objects,
        Placement::Exact(SubdivisionSettings::default()),
    );
    assert_eq!(exact.counts.vertices.under_water, 49);
    assert_eq!(exact.counts.vertices.outside, 0);
    assert_eq!(exact.counts.vertices.newton_fallback, 49);
    assert_eq!(linear.counts.vertices.newton_fallback, 0);
    // Fallback vertices are never subdivided around: the geometry is the linear one.
    assert_eq!(exact.counts.triangles.subdivided, 0);
    assert_eq!(exact.under_vertices, linear.under_vertices);
    let mut expected_counts = linear.counts;
    expected_counts.vertices.newton_fallback = 49;
    assert_eq!(exact.counts, expected_counts);

    let linear_json = serde_json::to_string(&linear.counts).unwrap();
    assert!(!linear_json.contains("newton_fallback"), "{linear_json}");
    assert!(!linear_json.contains("subdivi"), "{linear_json}");
    let exact_json = serde_json::to_string(&exact.counts).unwrap();
    assert!(
        exact_json.contains("\"newton_fallback\":49"),
        "{exact_json}"
    );
}

/// The test camera of the flat-water cases: eye 1 m above the water, looking down into it (the
/// refraction bends sight lines strongly across the view).
fn flat_camera() -> Camera {
    Camera {
        eye: Vec3::new(0.2, 1.0, -1.7),
        target: Vec3::new(0.0, -1.0, 0.3),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        near_m: crate::camera::NEAR_M,
        far_m: crate::camera::FAR_M,
    }
}
const IMAGE_SIZE: (u32, u32) = (1920, 1080);

/// On flat water the exact method's vertices are the bisection oracle's, on screen, to far below
/// a pixel, where the equal-t cells are off by a measurable fraction of one.
#[test]
fn exact_vertices_match_the_flat_water_oracle() {
    let surface = FlatHeightField { level_m: 0.0 };
    let membrane = membrane_from(&surface, grid((-2.0, -2.0), (2.0, 2.0), (16, 16)));
    let objects = [sheet(12, (-1.4, 1.4), (-1.3, 1.6), |x, z| {
        -0.3 - 0.5 * (1.0 + x) - 0.2 * z * z
    })];
    let camera = flat_camera();
    let worst_px = |g: &VirtualGeometry| {
        g.under_vertices
            .iter()
            .map(|v| {
                let (exact, _) = flat_virtual_vertex(
                    camera.eye.as_dvec3(),
                    Vec3::from(v.true_position).as_dvec3(),
                    0.0,
                    N_AIR as f64,
                    N_WATER as f64,
                );
                let at = |p: Vec3| camera.pixel_of(p, IMAGE_SIZE.0, IMAGE_SIZE.1).unwrap();
                at(Vec3::from(v.virtual_position)).distance(at(exact.as_vec3()))
            })
            .fold(0.0_f32, f32::max)
    };
    let linear = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Linear,
    );
    let exact = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Exact(SubdivisionSettings {
            max_depth: 0,
            ..Default::default()
        }),
    );
    let (linear_px, exact_px) = (worst_px(&linear), worst_px(&exact));
    eprintln!(
        "flat water, 16 x 16 cells: worst screen error linear {linear_px} px, exact {exact_px} px"
    );
    assert_eq!(exact.counts.vertices.newton_fallback, 0);
    assert_eq!(exact.counts.vertices.outside, 0);
    // f32 positions at ~2 m and a 935 px focal length: ~1e-4 px of rounding.
    assert!(exact_px < 2e-3, "{exact_px} px");
    // The linear cells are measurably worse at this spacing: the comparison means something.
    assert!(linear_px > 0.5, "{linear_px} px");
}

/// The corners of an object's bounding box (the sheets' border vertices lie on it exactly).
fn extent(object: &Object) -> (Vec3, Vec3) {
    let positions = &object.mesh.positions;
    (
        positions.iter().copied().fold(Vec3::INFINITY, Vec3::min),
        positions
            .iter()
            .copied()
            .fold(Vec3::NEG_INFINITY, Vec3::max),
    )
}

/// Every edge of the drawn under-water triangles, as exact (bit) positions, each way once.
type EdgeKey = ([u32; 3], [u32; 3]);
fn edge_key(a: Vec3, b: Vec3) -> EdgeKey {
    let (ka, kb) = (
        a.to_array().map(f32::to_bits),
        b.to_array().map(f32::to_bits),
    );
    if ka <= kb {
        (ka, kb)
    } else {
        (kb, ka)
    }
}

/// Triangles of the drawn under-water geometry as (true, virtual) corner triples.
fn drawn_triangles(g: &VirtualGeometry) -> Vec<[(Vec3, Vec3); 3]> {
    g.under_vertices
        .chunks_exact(3)
        .map(|t| {
            std::array::from_fn(|k| {
                (
                    Vec3::from(t[k].true_position),
                    Vec3::from(t[k].virtual_position),
                )
            })
        })
        .collect()
}

/// Screen distance of each drawn edge's midpoint's exact image (by the flat-water oracle, not by
/// the code under test) from the straight drawn edge.
fn midpoint_strays_px(g: &VirtualGeometry, camera: Camera) -> Vec<f32> {
    let at = |p: Vec3| camera.pixel_of(p, IMAGE_SIZE.0, IMAGE_SIZE.1).unwrap();
    drawn_triangles(g)
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
        .map(|((true_a, virtual_a), (true_b, virtual_b))| {
            let mid = (0.5 * (true_a.as_dvec3() + true_b.as_dvec3())).as_vec3();
            let (image, _) = flat_virtual_vertex(
                camera.eye.as_dvec3(),
                mid.as_dvec3(),
                0.0,
                N_AIR as f64,
                N_WATER as f64,
            );
            distance_to_segment(at(image.as_vec3()), at(virtual_a), at(virtual_b))
        })
        .collect()
}

/// Adaptive subdivision on flat water seen steeply: big floor triangles whose straight virtual
/// edges miss the curved exact image by pixels. After subdivision every drawn edge's midpoint
/// image is within the tolerance (measured with the bisection oracle), only some triangles were
/// split, and the drawn mesh has no T-junctions: every edge inside the floor is shared by exactly
/// two drawn triangles, bit for bit.
#[test]
fn subdivision_brings_every_edge_within_tolerance_without_cracks() {
    let surface = FlatHeightField { level_m: 0.0 };
    let membrane = membrane_from(&surface, grid((-2.0, -2.0), (2.0, 2.0), (32, 32)));
    let (x_range, z_range) = ((-1.4, 1.4), (-1.3, 1.6));
    let objects = [sheet(4, x_range, z_range, |x, z| {
        -0.4 - 0.3 * (1.0 + x) - 0.1 * z * z
    })];
    let camera = flat_camera();
    let tolerance_px = 0.25;
    let unsplit = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Exact(SubdivisionSettings {
            tolerance_px,
            max_depth: 0,
        }),
    );
    let before = midpoint_strays_px(&unsplit, camera);
    let before_worst = before.iter().copied().fold(0.0, f32::max);
    assert!(
        before_worst > 4.0 * tolerance_px,
        "{before_worst} px: nothing to subdivide"
    );

    let settings = SubdivisionSettings {
        tolerance_px,
        max_depth: 8,
    };
    let split = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Exact(settings),
    );
    let after = midpoint_strays_px(&split, camera);
    let after_worst = after.iter().copied().fold(0.0, f32::max);
    let triangles = split.under_vertices.len() / 3;
    eprintln!(
        "subdivision: worst midpoint stray {before_worst} px -> {after_worst} px; {} of {} triangles split into {} ({} drawn)",
        split.counts.triangles.subdivided,
        split.counts.triangles.under_water,
        split.counts.triangles.subdivision_pieces,
        triangles
    );
    // The criterion is tested in screen f32 arithmetic; allow its rounding (~1e-3 px) only.
    assert!(after_worst <= tolerance_px + 1e-3, "{after_worst} px");
    assert!(split.counts.triangles.subdivided > 0);
    // Only where needed: the depth limit was not what stopped it (far from 4^8 pieces) ...
    assert!(triangles < 32 * 256, "{triangles} triangles");
    // ... and a coarser tolerance splits less.
    let coarse = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Exact(SubdivisionSettings {
            tolerance_px: 2.0,
            max_depth: 8,
        }),
    );
    eprintln!(
        "at 2 px: {} of {} triangles split",
        coarse.counts.triangles.subdivided, coarse.counts.triangles.under_water
    );
    assert!(coarse.under_vertices.len() < split.under_vertices.len());
    assert!(coarse.counts.triangles.subdivided < coarse.counts.triangles.under_water);
    assert_eq!(
        split.counts.triangles.subdivision_pieces as usize
            + (split.counts.triangles.under_water - split.counts.triangles.subdivided) as usize,
        triangles
    );

    // No T-junctions: an edge inside the floor is shared by two drawn triangles.
    let mut uses: HashMap<EdgeKey, u32> = HashMap::new();
    for t in drawn_triangles(&split) {
        for k in 0..3 {
            *uses.entry(edge_key(t[k].0, t[(k + 1) % 3].0)).or_default() += 1;
        }
    }
    let (low, high) = extent(&objects[0]);
    // Both ends on the same side of the sheet's border.
    let on_border = |a: [u32; 3], b: [u32; 3]| {
        let (a, b) = (a.map(f32::from_bits), b.map(f32::from_bits));
        [(0, low.x), (0, high.x), (2, low.z), (2, high.z)]
            .iter()
            .any(|&(axis, at)| a[axis] == at && b[axis] == at)
    };
    for (&(a, b), &count) in &uses {
        let border = on_border(a, b);
        if border {
            assert_eq!(count, 1, "border edge {a:?}-{b:?}");
        } else {
            assert_eq!(count, 2, "edge {a:?}-{b:?} used {count} times: a crack");
        }
    }
    // New vertices lie on the true edges they split, with their own exact virtual position.
    let eye = camera.eye.as_dvec3();
    for t in drawn_triangles(&split) {
        for (true_position, virtual_position) in t {
            let (exact, _) = flat_virtual_vertex(
                eye,
                true_position.as_dvec3(),
                0.0,
                N_AIR as f64,
                N_WATER as f64,
            );
            assert!((virtual_position.as_dvec3() - exact).length() < 1e-5);
        }
    }
}

/// A sheet crossing the water: subdivision never splits the water line (shared with the part
/// above, drawn at true positions), surface vertices stay their own images, and the only edges of
/// the under-water part used once are on the sheet's border or on the water line.
#[test]
fn subdivision_keeps_the_water_line_closed() {
    let surface = FlatHeightField { level_m: 0.0 };
    let membrane = membrane_from(&surface, grid((-2.0, -2.0), (2.0, 2.0), (32, 32)));
    let (x_range, z_range) = ((-1.4, 1.4), (-1.3, 1.6));
    // Rises from 1.1 m deep at x = -1.4 to 0.3 m above the water at x = 1.4.
    let objects = [sheet(5, x_range, z_range, |x, _| -0.4 + 0.5 * x)];
    let camera = flat_camera();
    let split = geometry(
        &membrane,
        &surface,
        camera,
        IMAGE_SIZE,
        &objects,
        Placement::Exact(SubdivisionSettings::default()),
    );
    assert!(split.counts.triangles.subdivided > 0, "{:?}", split.counts);
    let water = surface.exact(membrane.grid);
    let field = RefractionField::build(
        &membrane,
        &water,
        setup(camera.eye),
        query_height_range(&objects, &membrane),
    );
    let skirt = WaterlineSkirt::new(&field);
    let mut uses: HashMap<EdgeKey, u32> = HashMap::new();
    for t in drawn_triangles(&split) {
        for k in 0..3 {
            *uses.entry(edge_key(t[k].0, t[(k + 1) % 3].0)).or_default() += 1;
        }
    }
    // Surface vertices stay their own images, raised by the water-line skirt, with their twins in
    // the part above water.
    let water_line: Vec<_> = split
        .under_vertices
        .iter()
        .filter(|v| v.true_position[1].abs() < 1e-5)
        .collect();
    assert!(!water_line.is_empty());
    for v in water_line {
        assert_water_line_vertex(&skirt, v, &split.above_vertices);
    }
    let (low, high) = extent(&objects[0]);
    let water_line_or_border = |p: [u32; 3]| {
        let p = p.map(f32::from_bits);
        p[1].abs() < 1e-5 || p[0] == low.x || p[2] == low.z || p[2] == high.z
    };
    for (&(a, b), &count) in &uses {
        if count == 1 {
            assert!(
                water_line_or_border(a) && water_line_or_border(b),
                "edge {a:?}-{b:?} used once, off the border and the water line: a crack"
            );
        } else {
            assert_eq!(count, 2);
        }
    }
    // Each water-line edge of the under-water part is one of the above part's edges, which draws
    // it lowered by the skirt.
    let above: Vec<Vec3> = split
        .above_indices
        .iter()
        .map(|&i| Vec3::from(split.above_vertices[i as usize].position))
        .collect();
    let mut above_edges: HashMap<EdgeKey, u32> = HashMap::new();
    for t in above.chunks_exact(3) {
        for k in 0..3 {
            *above_edges
                .entry(edge_key(t[k], t[(k + 1) % 3]))
                .or_default() += 1;
        }
    }
    let mut water_line_edges = 0;
    for (&(a, b), &count) in &uses {
        let (pa, pb) = (a.map(f32::from_bits), b.map(f32::from_bits));
        if count == 1 && pa[1].abs() < 1e-5 && pb[1].abs() < 1e-5 {
            let lowered = |p: [f32; 3]| {
                let p = Vec3::from(p);
                p - Vec3::Y * skirt.below_m(p)
            };
            assert!(
                above_edges.contains_key(&edge_key(lowered(pa), lowered(pb))),
                "water-line edge {pa:?}-{pb:?}"
            );
            water_line_edges += 1;
        }
    }
    // The sheet crosses the water along 5 quads: at least one water-line edge per quad.
    assert!(water_line_edges >= 5, "{water_line_edges} water-line edges");
}

/// The linear placement of `build_virtual_geometry_with` is `build_virtual_geometry`.
#[test]
fn linear_placement_is_the_cell_method() {
    let surface = CREST;
    let membrane = membrane_from(&surface, grid((-1.5, -1.0), (1.5, 1.0), (48, 16)));
    let objects = [sheet(8, (-1.2, 1.2), (-0.8, 0.8), |x, _| -0.8 + 0.1 * x)];
    let camera = flat_camera();
    let water = surface.exact(membrane.grid);
    let field = RefractionField::build(
        &membrane,
        &water,
        setup(camera.eye),
        query_height_range(&objects, &membrane),
    );
    let request = VirtualGeometryRequest {
        field: &field,
        camera,
        image_size: IMAGE_SIZE,
        objects: &objects,
        mean_level_m: 0.0,
        search: ImageSearch::Accelerated,
    };
    let a = build_virtual_geometry(&request, None);
    let b = build_virtual_geometry_with(&request, None, Placement::Linear);
    assert_eq!(a.under_vertices, b.under_vertices);
    assert_eq!(a.counts, b.counts);
    // And the exact method differs from it (it moves vertices to the exact image).
    let c = build_virtual_geometry_with(
        &request,
        None,
        Placement::Exact(SubdivisionSettings::default()),
    );
    assert_ne!(a.under_vertices, c.under_vertices);
    // Every exact image the frame drew is a converged solve (no fallback on this smooth crest).
    assert_eq!(c.counts.vertices.newton_fallback, 0);
}
