//! The accelerated search against brute force, the merge and the crest check.

use super::test_support::*;
use glam::{DVec3, Vec3};

use super::*;
use crate::seeded::SplitMix64 as Rng;
use crate::water::HeightField;

fn setup(eye: Vec3) -> RefractionSetup {
    RefractionSetup {
        eye,
        n_above: 1.0,
        n_below: 1.333,
        cell_mode: CellMode::EqualT,
    }
}

/// A point with x and z in `[-half_m, half_m]` and y in `y_m` (drawn x, y, z).
fn random_point(rng: &mut Rng, half_m: f64, y_m: (f64, f64)) -> Vec3 {
    let x = rng.range(-half_m, half_m);
    let y = rng.range(y_m.0, y_m.1);
    Vec3::new(x as f32, y as f32, rng.range(-half_m, half_m) as f32)
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
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(-3.0, 2.0, 0.5);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-2.0, 0.0));
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
    let mut rng = Rng::new(0x5EED_0001);
    let mut multi_image_points = 0;
    let mut total_images = 0;
    for case in 0..12 {
        let steepness = if case % 3 == 0 { 0.5 } else { 0.15 };
        let surface = random_waves(&mut rng, 1 + case % 4, steepness);
        let membrane = membrane_from(&surface, square_grid(2.0, 12 + (case as u32 % 3) * 4));
        let water = surface.exact(membrane.grid);
        // Eyes from overhead to grazing (elevation down to ~3 degrees).
        let elevation = rng.range(0.05, 1.5);
        let azimuth = rng.range(0.0, std::f64::consts::TAU);
        let distance = rng.range(2.0, 8.0);
        let eye = Vec3::new(
            (distance * elevation.cos() * azimuth.cos()) as f32,
            (distance * elevation.sin()).max(0.3) as f32,
            (distance * elevation.cos() * azimuth.sin()) as f32,
        );
        let field = RefractionField::build(&membrane, &water, setup(eye), (-2.5, 0.2));
        for _ in 0..300 {
            let p = random_point(&mut rng, 3.0, (-2.5, -0.05));
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
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(-2.5, 2.5, -1.5);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-2.0, 0.1));
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
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(-1.0, 3.0, 0.1);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-3.0, 0.2));
    let mut rng = Rng::new(77);
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
    let (slope, curvature) = gaussian_ridge_bounds(0.4, 0.02f64.sqrt());
    let water = exact(&Ridge, membrane.grid, (0.0, 0.4), slope, curvature);
    let eye = Vec3::new(-3.0, 0.5, 0.0);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-2.0, 0.5));
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
    let mut rng = Rng::new(0x5EED_C2E5);
    let (mut paths, mut blocked, mut proven) = (0, 0, 0);
    for case in 0..12 {
        let steepness = [0.1, 0.4, 0.9][case % 3];
        let surface = random_waves(&mut rng, 1 + case % 4, steepness);
        let membrane = membrane_from(&surface, square_grid(2.0, 16 + 8 * (case as u32 % 3)));
        let water = surface.exact(membrane.grid);
        let elevation = rng.range(0.03, 1.5);
        let azimuth = rng.range(0.0, std::f64::consts::TAU);
        let eye = DVec3::new(
            3.0 * elevation.cos() * azimuth.cos(),
            (3.0 * elevation.sin()).max(0.2),
            3.0 * elevation.cos() * azimuth.sin(),
        );
        let field = RefractionField::build(&membrane, &water, setup(eye.as_vec3()), (-2.0, 0.2));
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
            // The walk alone, without the slope proof.
            let check = field.crest.check;
            let walk_clear = |to: DVec3, side: f64| {
                let d = to - sight;
                let horizontal = d.x.hypot(d.z);
                horizontal <= check.guard_m
                    || water.segment_on_side(
                        sight,
                        d,
                        check.guard_m / horizontal,
                        side,
                        check.tolerance_m,
                    )
            };
            let walked = !(walk_clear(eye, 1.0) && walk_clear(point, -1.0));
            assert_eq!(
                field.crest_blocks(sight, point),
                walked,
                "case {case}: sight point {sight}, point {point}"
            );
            paths += 1;
            blocked += walked as usize;
            proven += water.segment_clear_by_slope(sight, point - sight, -1.0, &check) as usize
                + water.segment_clear_by_slope(sight, eye - sight, 1.0, &check) as usize;
        }
    }
    assert!(
        blocked > 0 && blocked < paths,
        "{blocked} of {paths} blocked"
    );
    assert!(proven > paths / 4, "{proven} proofs over {paths} paths");
}
#[test]
fn thesis_mode_matches_its_brute_force_and_equal_t_on_flat_water() {
    let surface = Waves::default();
    let membrane = membrane_from(&surface, square_grid(2.0, 10));
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(0.5, 3.0, 0.2);
    let mut s = setup(eye);
    s.cell_mode = CellMode::Thesis;
    let thesis = RefractionField::build(&membrane, &water, s, (-2.0, 0.0));
    let equal_t = RefractionField::build(&membrane, &water, setup(eye), (-2.0, 0.0));
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
    let mut rng = Rng::new(0x5EED_0002);
    let surface = random_waves(&mut rng, 3, 0.1);
    let membrane = membrane_from(&surface, square_grid(2.0, 32));
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(-2.5, 0.15, 0.3);
    let setup = RefractionSetup {
        n_below: 1.0,
        ..setup(eye)
    };
    let field = RefractionField::build(&membrane, &water, setup, (-2.0, 0.0));
    let expected: Vec<u32> = (0..membrane.triangles.len() as u32)
        .filter(|&facet| {
            membrane.triangles[facet as usize]
                .iter()
                .any(|&i| field.rays[i as usize].direction.y > -blocks::MIN_DESCENT)
        })
        .collect();
    assert!(!expected.is_empty() && expected.len() < membrane.triangles.len() / 2);
    assert_eq!(field.structure.unbounded_facets(), &expected[..]);
    let (mut images, mut through_unbounded) = (0, 0);
    for _ in 0..400 {
        let p = random_point(&mut rng, 2.0, (-0.3, -0.01));
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
    let water = surface.exact(membrane.grid);
    let eye = Vec3::new(-4.0, 0.4, 0.0);
    let field = RefractionField::build(&membrane, &water, setup(eye), (-2.0, 0.2));
    let back_facing = field
        .rays
        .iter()
        .filter(|r| r.extrapolation.is_extrapolated())
        .count();
    assert!(back_facing > 0);
    assert!(field.facet_extrapolated.iter().any(|&e| e));
    let mut rng = Rng::new(3);
    for _ in 0..500 {
        let p = random_point(&mut rng, 2.0, (-2.0, -0.1));
        for image in assert_same(&field, p, "grazing") {
            assert_eq!(
                image.extrapolated,
                field.facet_extrapolated[image.facet as usize]
            );
        }
    }
}
