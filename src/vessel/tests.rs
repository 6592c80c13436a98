//! Known answers for the vessels (issue 18): the pane's parallel shift and its media law, a
//! point in a cylinder of water against paraxial optics wall by wall, Snell's law at every
//! crossing of skew paths, and image counts against a brute-force fan of traced rays that shares
//! no code with the solvers.

use glam::{DVec2, DVec3};

use super::*;
use crate::refraction::rays::refract_exact;
use crate::seeded::SplitMix64;

const GLASS: f64 = 1.5;

fn pane(normal: DVec3, inside: Medium, thickness_m: f64, glass_index: f64) -> Pane {
    let normal = normal.normalize();
    Pane {
        center: DVec3::ZERO,
        normal,
        u_axis: normal.any_orthonormal_vector(),
        half_size_m: [50.0, 50.0],
        thickness_m,
        glass_index,
        inside,
    }
}

fn refracted(images: &[Image]) -> Vec<Image> {
    images
        .iter()
        .copied()
        .filter(|i| i.refractions > 0)
        .collect()
}

/// Sine of the angle between a unit direction and a unit normal.
fn sine_to(direction: DVec3, normal: DVec3) -> f64 {
    direction.cross(normal).length()
}

#[test]
fn pane_with_air_both_sides_shifts_the_ray_parallel_by_the_known_distance() {
    let mut rng = SplitMix64::new(18);
    let mut checked = 0;
    for normal in [
        DVec3::Z,
        DVec3::new(0.3, -0.2, 1.0),
        DVec3::new(-1.0, 0.1, 0.4),
    ] {
        let pane = pane(normal, Medium::Air, 0.03, GLASS);
        let n = pane.normal;
        let eye = 1.2 * n + 0.3 * pane.u_axis;
        for _ in 0..200 {
            let lateral = DVec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 0.0);
            let point =
                -rng.range(0.05, 4.0) * n + lateral.x * pane.u_axis + lateral.y * pane.w_axis();
            let mut images = Vec::new();
            pane.images(eye, point, &mut images);
            let through = refracted(&images);
            assert_eq!(
                images.len(),
                1,
                "the pane blocks the straight view: {images:?}"
            );
            assert_eq!(through.len(), 1);
            let image = through[0];
            assert!(image.converged);
            assert_eq!(image.refractions, 2);
            let [c1, c2] = [image.crossings[0], image.crossings[1]];
            let entry = (c1 - eye).normalize();
            let exit = (point - c2).normalize();
            assert!(
                entry.cross(exit).length() < 1e-10,
                "exit not parallel to entry: {entry} {exit}"
            );
            let theta = sine_to(entry, n).asin();
            let theta_t = (theta.sin() / GLASS).asin();
            let expected = pane.thickness_m * (theta - theta_t).sin() / theta_t.cos();
            // Perpendicular distance between the entry line and the exit line.
            let shift = (point - eye).cross(entry).length();
            assert!(
                (shift - expected).abs() <= 1e-12 + 1e-9 * expected,
                "shift {shift} vs d sin(theta - theta_t) / cos(theta_t) = {expected} at theta {theta}"
            );
            // The displaced vertex is on the entry line, at the apparent distance.
            let seen = image.displaced - eye;
            assert!(seen.cross(entry).length() < 1e-9 * seen.length());
            let reduced = (c1 - eye).length() + (c2 - c1).length() / GLASS + (point - c2).length();
            assert!((seen.length() - reduced).abs() < 1e-9 * reduced);
            checked += 1;
        }
    }
    assert_eq!(checked, 600);
}

#[test]
fn pane_between_air_and_water_obeys_n_air_sin_air_equals_n_water_sin_water_whatever_the_glass() {
    let mut rng = SplitMix64::new(1818);
    for glass in [1.2, 1.5, 1.9] {
        let pane = pane(DVec3::new(0.1, 1.0, -0.3), Medium::Water, 0.012, glass);
        let n = pane.normal;
        let eye = 0.8 * n - 0.2 * pane.w_axis();
        for _ in 0..200 {
            let point = -rng.range(0.02, 2.0) * n
                + rng.range(-2.0, 2.0) * pane.u_axis
                + rng.range(-2.0, 2.0) * pane.w_axis();
            let mut images = Vec::new();
            pane.images(eye, point, &mut images);
            assert_eq!(images.len(), 1);
            let image = images[0];
            assert!(image.converged && image.refractions == 2);
            let [c1, c2] = [image.crossings[0], image.crossings[1]];
            let (air, inside_glass, water) = (
                (c1 - eye).normalize(),
                (c2 - c1).normalize(),
                (point - c2).normalize(),
            );
            let (sin_air, sin_water) = (sine_to(air, n), sine_to(water, n));
            assert!(
                (AIR_INDEX * sin_air - WATER_INDEX * sin_water).abs() < 1e-10,
                "glass {glass}: {sin_air} vs {sin_water}"
            );
            assert!((AIR_INDEX * sin_air - glass * sine_to(inside_glass, n)).abs() < 1e-10);
            // The three directions lie in one plane with the normal.
            assert!(air.cross(n).dot(water).abs() < 1e-10);
        }
    }
}

#[test]
fn pane_seen_from_the_water_side_and_a_point_in_the_glass() {
    // Eye in the water looking out to air: a less dense far side, with a critical angle.
    let pane = pane(DVec3::Y, Medium::Water, 0.02, GLASS);
    let eye = DVec3::new(0.0, -0.5, 0.0);
    let point = DVec3::new(0.4, 0.7, 0.0);
    let mut images = Vec::new();
    pane.images(eye, point, &mut images);
    assert_eq!(images.len(), 1);
    let [c1, c2] = [images[0].crossings[0], images[0].crossings[1]];
    let (water, air) = ((c1 - eye).normalize(), (point - c2).normalize());
    assert!((WATER_INDEX * sine_to(water, DVec3::Y) - sine_to(air, DVec3::Y)).abs() < 1e-10);
    // A point inside the glass: one refraction.
    let mut images = Vec::new();
    pane.images(
        DVec3::new(0.0, 0.5, 0.0),
        DVec3::new(0.3, 0.001, 0.1),
        &mut images,
    );
    assert_eq!(images.len(), 1);
    assert_eq!(images[0].refractions, 1);
    assert!(images[0].converged);
    // A point past the rectangle's edge, seen around it: the direct view only.
    let small = Pane {
        half_size_m: [0.2, 0.2],
        ..pane
    };
    let mut images = Vec::new();
    small.images(
        DVec3::new(0.0, 0.5, 0.0),
        DVec3::new(1.0, -0.5, 0.0),
        &mut images,
    );
    assert_eq!(images.len(), 1);
    assert_eq!(images[0].refractions, 0);
    assert_eq!(images[0].displaced, DVec3::new(1.0, -0.5, 0.0));
}

/// A 10 cm glass, 4 mm wall, water inside, axis vertical, from y = -1 to 1.
fn glass_of_water(inside: Medium) -> Cylinder {
    Cylinder {
        base: DVec3::new(0.0, -1.0, 0.0),
        axis: DVec3::Y,
        inner_radius_m: 0.046,
        outer_radius_m: 0.05,
        height_m: 2.0,
        glass_index: GLASS,
        inside,
    }
}

/// Paraxial refraction at a spherical (here cylindrical) surface: object at distance `s` before
/// the vertex (positive: real, on the incoming side), radius `r` (positive: centre on the outgoing
/// side); returns the image distance after the vertex and the lateral magnification.
fn paraxial(n1: f64, n2: f64, r: f64, s: f64) -> (f64, f64) {
    // n1 / s + n2 / s' = (n2 - n1) / R
    let s_image = n2 / ((n2 - n1) / r - n1 / s);
    (s_image, -(n1 * s_image) / (n2 * s))
}

#[test]
fn off_axis_point_in_a_cylinder_of_water_is_seen_where_paraxial_refraction_wall_by_wall_puts_it() {
    let cylinder = glass_of_water(Medium::Water);
    let (r1, r2) = (cylinder.inner_radius_m, cylinder.outer_radius_m);
    let eye_distance = 0.6;
    let eye = DVec3::new(eye_distance, 0.0, 0.0);
    let mut checked = 0;
    // Points off the axis along the line of sight (in front of and behind it), slightly aside.
    for x0 in [-0.03, -0.015, 0.012, 0.025] {
        for z0 in [-0.002, 0.001, 0.0025] {
            let point = DVec3::new(x0, 0.0, z0);
            // Light goes +x toward the eye. Inner wall: vertex at x = r1, centre of curvature on
            // the incoming side (R = -r1), water to glass.
            let (s1, m1) = paraxial(WATER_INDEX, GLASS, -r1, r1 - x0);
            let image1_x = r1 + s1;
            // Outer wall: vertex at x = r2, R = -r2, glass to air.
            let (s2, m2) = paraxial(GLASS, AIR_INDEX, -r2, r2 - image1_x);
            let image_x = r2 + s2;
            let image_z = z0 * m1 * m2;
            let expected = (image_z / (eye_distance - image_x)).atan();

            let mut images = Vec::new();
            cylinder.images(eye, point, &mut images);
            let through = refracted(&images);
            assert_eq!(through.len(), 1, "{point}: {images:?}");
            assert!(through[0].converged && through[0].refractions == 2);
            let sight = through[0].crossings[0] - eye;
            let seen = (sight.z / -sight.x).atan();
            assert!(
                (seen - expected).abs() <= 0.01 * expected.abs(),
                "{point}: seen at {seen} rad, paraxial {expected} rad"
            );
            // And not where the straight line would put it (the test can tell them apart).
            let straight = (z0 / (eye_distance - x0)).atan();
            assert!((straight - expected).abs() > 0.05 * expected.abs());
            checked += 1;
        }
    }
    assert_eq!(checked, 12);
}

/// Which region of the cylinder's cross-section a radius is in (0 outside, 1 glass, 2 inside).
fn region_by_radius(cylinder: &Cylinder, rho: f64) -> usize {
    if rho < cylinder.inner_radius_m {
        2
    } else if rho <= cylinder.outer_radius_m {
        1
    } else {
        0
    }
}

fn transverse(cylinder: &Cylinder, p: DVec3) -> DVec3 {
    let d = p - cylinder.base;
    d - d.dot(cylinder.axis) * cylinder.axis
}

#[test]
fn skew_paths_through_a_cylinder_obey_snell_in_3d_at_every_crossing() {
    let mut rng = SplitMix64::new(1800);
    let mut per_count = [0usize; 5];
    for inside in [Medium::Water, Medium::Air] {
        let cylinder = Cylinder {
            base: DVec3::new(0.1, -0.3, 0.2),
            axis: DVec3::new(0.2, 1.0, -0.1).normalize(),
            ..glass_of_water(inside)
        };
        let n = [AIR_INDEX, GLASS, inside.index()];
        for i in 0..600 {
            let azimuth = rng.range(0.0, std::f64::consts::TAU);
            let (u, w) = (
                cylinder.axis.any_orthonormal_vector(),
                cylinder.axis.cross(cylinder.axis.any_orthonormal_vector()),
            );
            let eye = cylinder.base
                + rng.range(0.2, 0.8) * (azimuth.cos() * u + azimuth.sin() * w)
                + rng.range(-0.3, 2.3) * cylinder.axis;
            // Inside, in the (thin) glass and outside, in turn.
            let rho = match i % 3 {
                0 => rng.range(0.0, cylinder.inner_radius_m),
                1 => rng.range(cylinder.inner_radius_m, cylinder.outer_radius_m),
                _ => rng.range(cylinder.outer_radius_m, 0.09),
            };
            let angle = rng.range(0.0, std::f64::consts::TAU);
            let point = cylinder.base
                + rho * (angle.cos() * u + angle.sin() * w)
                + rng.range(0.3, 1.7) * cylinder.axis;
            let mut images = Vec::new();
            cylinder.images(eye, point, &mut images);
            for image in &images {
                per_count[image.refractions as usize] += 1;
                assert!(image.converged, "{eye} {point}: {image:?}");
                let mut path = vec![eye];
                path.extend_from_slice(image.crossings());
                path.push(point);
                for (i, &c) in image.crossings().iter().enumerate() {
                    let (before, after) = (path[i], path[i + 2]);
                    let radial = transverse(&cylinder, c);
                    let rho = radial.length();
                    let on_wall = (rho - cylinder.inner_radius_m)
                        .abs()
                        .min((rho - cylinder.outer_radius_m).abs());
                    assert!(on_wall < 1e-10, "crossing off the walls by {on_wall}");
                    let mid_before = transverse(&cylinder, 0.5 * (before + c)).length();
                    let mid_after = transverse(&cylinder, 0.5 * (after + c)).length();
                    let (r_before, r_after) = (
                        region_by_radius(&cylinder, mid_before),
                        region_by_radius(&cylinder, mid_after),
                    );
                    assert_ne!(r_before, r_after, "a crossing that changes no medium");
                    let outward = radial / rho;
                    let normal = if mid_before > rho { outward } else { -outward };
                    let incident = (c - before).normalize();
                    let expected = refract_exact(incident, normal, n[r_before] / n[r_after])
                        .expect("a transmitted ray exists");
                    let actual = (after - c).normalize();
                    assert!(
                        (expected - actual).length() < 1e-8,
                        "Snell broken at crossing {i}: {expected} vs {actual}"
                    );
                }
                let first = (path[1] - eye).normalize();
                let seen = image.displaced - eye;
                assert!(seen.cross(first).length() < 1e-9 * seen.length());
            }
        }
    }
    // The property loop must have met every kind of path.
    for (count, &seen) in per_count.iter().enumerate() {
        assert!(
            seen > 20,
            "only {seen} images with {count} refractions: {per_count:?}"
        );
    }
}

/// The brute-force count: a fan of eye rays in the cross-section through the eye, each traced
/// through the two circles by plain 2-D Snell, and per point the number of times, walking the
/// fan, the ray's piece after `k` crossings passes from one side of the point to the other.
mod fan {
    use super::DVec2;

    pub struct Piece {
        pub origin: DVec2,
        pub direction: DVec2,
        pub length: f64,
        pub region: usize,
        pub crossings: usize,
    }

    fn hit(origin: DVec2, direction: DVec2, radius: f64) -> Option<f64> {
        let b = origin.dot(direction);
        let c = origin.length_squared() - radius * radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        [-b - root, -b + root].into_iter().find(|&t| t > 1e-12)
    }

    /// `radii = [inner, outer]`, `indices = [outside, glass, inside]`.
    pub fn trace(
        mut origin: DVec2,
        mut direction: DVec2,
        radii: [f64; 2],
        indices: [f64; 3],
    ) -> Vec<Piece> {
        let mut pieces = Vec::new();
        let mut region = 0usize;
        for crossings in 0..8 {
            let candidates = [
                (hit(origin, direction, radii[0]), 0),
                (hit(origin, direction, radii[1]), 1),
            ];
            let next = candidates
                .iter()
                .filter_map(|&(t, wall)| t.map(|t| (t, wall)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((t, wall)) = next else {
                pieces.push(Piece {
                    origin,
                    direction,
                    length: f64::INFINITY,
                    region,
                    crossings,
                });
                break;
            };
            pieces.push(Piece {
                origin,
                direction,
                length: t,
                region,
                crossings,
            });
            let at = origin + t * direction;
            let across = match (region, wall) {
                (0, 1) => 1,
                (1, 1) => 0,
                (1, 0) => 2,
                (2, 0) => 1,
                _ => unreachable!("region {region} meets wall {wall}"),
            };
            let mut normal = at.normalize();
            if normal.dot(direction) > 0.0 {
                normal = -normal;
            }
            let eta = indices[region] / indices[across];
            let cos_i = -direction.dot(normal);
            let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
            if sin2_t > 1.0 {
                break; // total internal reflection: a reflected path, counted by neither side
            }
            direction =
                (eta * direction + (eta * cos_i - (1.0 - sin2_t).sqrt()) * normal).normalize();
            origin = at;
            region = across;
        }
        pieces
    }
}

#[test]
fn image_counts_per_point_match_a_brute_force_fan_of_traced_rays() {
    let mut rng = SplitMix64::new(180);
    for inside in [Medium::Water, Medium::Air] {
        let cylinder = glass_of_water(inside);
        let radii = [cylinder.inner_radius_m, cylinder.outer_radius_m];
        let indices = [AIR_INDEX, GLASS, inside.index()];
        let eye2 = DVec2::new(0.35, 0.04);
        let eye = DVec3::new(eye2.x, 0.0, eye2.y);
        // The fan: every direction that meets the outer circle, evenly spaced, and denser near
        // the rays that graze a wall (the outer one from outside, the inner one from the glass,
        // and from inside for total internal reflection), where the outgoing direction turns
        // as the square root of the distance to the grazing ray and an even fan leaves gaps. Impact
        // distances `b` there: r2 and r1 outside; r1 in the glass (b = n_glass r1 outside) and
        // inside (b = n_inside r1 outside); a fan angle `a` has b = |eye| sin(a).
        let toward = -eye2.normalize();
        let half_angle = (radii[1] / eye2.length()).asin();
        const RAYS: usize = 400_000;
        const EDGE_RAYS: usize = 40_000;
        const EDGE_BAND_RAD: f64 = 2e-3;
        let mut angles: Vec<f64> = (0..RAYS)
            .map(|i| half_angle * (2.0 * (i as f64 + 0.5) / RAYS as f64 - 1.0))
            .collect();
        for b in [
            radii[1],
            radii[0],
            GLASS * radii[0],
            inside.index() * radii[0],
        ] {
            if b > radii[1] {
                continue;
            }
            let edge = (b / eye2.length()).asin();
            for i in 1..EDGE_RAYS {
                let offset = EDGE_BAND_RAD * (i as f64 / EDGE_RAYS as f64).powi(2);
                for a in [edge - offset, edge + offset, -edge - offset, -edge + offset] {
                    if a.abs() < half_angle {
                        angles.push(a);
                    }
                }
            }
        }
        angles.sort_by(f64::total_cmp);
        let fans: Vec<Vec<fan::Piece>> = angles
            .iter()
            .map(|&a| {
                let d = DVec2::from_angle(a).rotate(toward);
                fan::trace(eye2, d, radii, indices)
            })
            .collect();
        const POINTS: usize = 450;
        let mut points = Vec::new();
        for _ in 0..POINTS {
            // Inside, in the glass, and behind the glass (where 2 and 4 refraction paths meet).
            let rho = match points.len() % 3 {
                0 => rng.range(0.0, radii[0]),
                1 => rng.range(radii[0], radii[1]),
                _ => rng.range(radii[1], 0.09),
            };
            let angle = rng.range(0.0, std::f64::consts::TAU);
            points.push(DVec2::from_angle(angle) * rho);
        }
        let (mut compared, mut with_several) = (0, 0);
        const OTHER_SAMPLES: [usize; 4] = [4, 6, 12, 48];
        let mut other_mismatches = [0usize; 4];
        for &p in &points {
            // Only points the fan can see past the glass's far side matter for "behind"; all count.
            let mut brute = [0usize; 5];
            let mut previous: Vec<Option<(usize, f64)>> = vec![None; 5];
            for (i, pieces) in fans.iter().enumerate() {
                let mut now: Vec<Option<(usize, f64)>> = vec![None; 5];
                for piece in pieces.iter().filter(|piece| piece.crossings > 0) {
                    let region = if p.length() < radii[0] {
                        2
                    } else if p.length() <= radii[1] {
                        1
                    } else {
                        0
                    };
                    if piece.region != region || piece.crossings > 4 {
                        continue;
                    }
                    let along = (p - piece.origin).dot(piece.direction);
                    if along > 0.0 && along < piece.length {
                        now[piece.crossings] =
                            Some((i, piece.direction.perp_dot(p - piece.origin)));
                    }
                }
                for k in 0..5 {
                    if let (Some((i0, d0)), Some((_, d1))) = (previous[k], now[k]) {
                        if i0 + 1 == i && d0 * d1 < 0.0 {
                            brute[k] += 1;
                        }
                    }
                }
                previous = now;
            }
            // Other scan densities, for the record (printed, not asserted).
            for (slot, &samples) in OTHER_SAMPLES.iter().enumerate() {
                let mut images = Vec::new();
                cylinder.images_with_samples(eye, DVec3::new(p.x, 0.0, p.y), samples, &mut images);
                let mut counts = [0usize; 5];
                for image in images.iter().filter(|i| i.refractions > 0) {
                    counts[image.refractions as usize] += 1;
                }
                other_mismatches[slot] += usize::from(counts != brute);
            }
            let mut images = Vec::new();
            cylinder.images(eye, DVec3::new(p.x, 0.0, p.y), &mut images);
            let mut solved = [0usize; 5];
            for image in images.iter().filter(|i| i.refractions > 0) {
                assert!(image.converged);
                solved[image.refractions as usize] += 1;
            }
            assert_eq!(
                solved,
                brute,
                "{inside:?} point {p} (radius {}): solver {solved:?} vs fan {brute:?}",
                p.length()
            );
            compared += 1;
            if solved.iter().sum::<usize>() > 1 {
                with_several += 1;
            }
        }
        assert_eq!(compared, POINTS);
        // The comparison must include points where paths of different kinds meet.
        assert!(
            with_several > 10,
            "{inside:?}: only {with_several} points with several images"
        );
        println!(
            "{inside:?}: points the solver miscounts with {OTHER_SAMPLES:?} scan samples per piece: {other_mismatches:?} (default {})",
            super::cylinder::SCAN_SAMPLES
        );
        println!(
            "{inside:?}: {compared} points agree with the fan, {with_several} with several images"
        );
    }
}
