//! Exact refraction through FLAT water (ALGORITHM §6): receives an eye, a point on the other side of
//! a horizontal water plane and the two indices of refraction; returns the exact sight point (by
//! bisection on dL/ds, to machine precision in f64) and the exact virtual vertex built from it.
//! This is the test oracle for the cell method on flat membranes, and the position used for an
//! under-water vertex of a boundary triangle that has no image (see `virtual_geometry`).

use glam::{DVec2, DVec3};

/// The sight point of `point` seen from `eye` through the flat water plane `y = level_m`: the point
/// S on the plane where the optical path `n_above |S - E| + n_below |V - S|` is stationary.
///
/// The eye and the point are expected on opposite sides of the plane (either way round: the index on
/// the eye's side is `n_above`). A point ON the plane is its own sight point. Distances to the plane
/// are taken as absolute values, so a point on the eye's side gets the mirrored answer rather than
/// a panic; callers classify above/below water before asking.
pub fn flat_sight_point(
    eye: DVec3,
    point: DVec3,
    level_m: f64,
    n_above: f64,
    n_below: f64,
) -> DVec3 {
    let eye_height_m = (eye.y - level_m).abs();
    let point_depth_m = (point.y - level_m).abs();
    let eye_xz = DVec2::new(eye.x, eye.z);
    let offset_xz = DVec2::new(point.x, point.z) - eye_xz;
    let horizontal_m = offset_xz.length();
    if horizontal_m == 0.0 {
        // Straight down: the sight point is directly above/below the eye.
        return DVec3::new(eye.x, level_m, eye.z);
    }
    if point_depth_m == 0.0 {
        return DVec3::new(point.x, level_m, point.z);
    }
    // L(s) = n_above sqrt(s^2 + a^2) + n_below sqrt((D - s)^2 + b^2) is strictly convex in s, with
    // dL/ds < 0 at s = 0 and > 0 at s = D: exactly one root of dL/ds in [0, D]. Newton on dL/ds
    // (its derivative, the curvature of L, is positive), kept inside the shrinking bracket with
    // bisection, from where the straight line from the eye to the point crosses the plane; it
    // stops when a step no longer moves s by more than rounding: machine precision, which is what
    // an oracle needs, in a handful of steps instead of ~60 halvings.
    let (a2, b2) = (eye_height_m * eye_height_m, point_depth_m * point_depth_m);
    let slope_and_curvature = |s: f64| {
        let (near, far) = (
            (s * s + a2).sqrt(),
            ((horizontal_m - s).powi(2) + b2).sqrt(),
        );
        (
            n_above * s / near - n_below * (horizontal_m - s) / far,
            n_above * a2 / (near * near * near) + n_below * b2 / (far * far * far),
        )
    };
    let (mut low, mut high) = (0.0_f64, horizontal_m);
    let mut s = horizontal_m * eye_height_m / (eye_height_m + point_depth_m);
    for _ in 0..200 {
        let (slope, curvature) = slope_and_curvature(s);
        if slope == 0.0 {
            break;
        }
        if slope < 0.0 {
            low = s;
        } else {
            high = s;
        }
        let newton = s - slope / curvature;
        let next = if newton > low && newton < high {
            newton
        } else {
            0.5 * (low + high)
        };
        let settled = (next - s).abs() <= 4.0 * f64::EPSILON * horizontal_m;
        s = next;
        if settled || next <= low || next >= high {
            break;
        }
    }
    let sight_xz = eye_xz + offset_xz * (s / horizontal_m);
    DVec3::new(sight_xz.x, level_m, sight_xz.y)
}

/// The virtual vertex `V' = E + normalize(S - E) (|S - E| + eta |V - S|)`, `eta = n_above / n_below`
/// (ALGORITHM §5.5), for any sight point S.
pub fn virtual_vertex(
    eye: DVec3,
    sight_point: DVec3,
    point: DVec3,
    n_above: f64,
    n_below: f64,
) -> DVec3 {
    let eta = n_above / n_below;
    let to_sight = sight_point - eye;
    let eye_to_sight_m = to_sight.length();
    if eye_to_sight_m == 0.0 {
        return point;
    }
    eye + to_sight / eye_to_sight_m * (eye_to_sight_m + eta * (point - sight_point).length())
}

/// The exact virtual vertex of `point` through flat water at `level_m`, and its true water path
/// length `|V - S|` in metres.
pub fn flat_virtual_vertex(
    eye: DVec3,
    point: DVec3,
    level_m: f64,
    n_above: f64,
    n_below: f64,
) -> (DVec3, f64) {
    let sight_point = flat_sight_point(eye, point, level_m, n_above, n_below);
    (
        virtual_vertex(eye, sight_point, point, n_above, n_below),
        (point - sight_point).length(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const N_AIR: f64 = 1.0;
    const N_WATER: f64 = 1.333;

    /// The safeguarded Newton solve lands where plain bisection of dL/ds to the last bit does,
    /// for eyes and points from grazing to straight down, shallow to deep.
    #[test]
    fn newton_agrees_with_bisection_to_the_last_bits() {
        let mut rng = crate::seeded::SplitMix64::new(0x5EED_F1A7);
        let mut unit = || rng.unit();
        for _ in 0..2000 {
            let eye = DVec3::new(
                40.0 * unit() - 20.0,
                0.01 + 10.0 * unit(),
                40.0 * unit() - 20.0,
            );
            let point = DVec3::new(
                40.0 * unit() - 20.0,
                -0.001 - 5.0 * unit(),
                40.0 * unit() - 20.0,
            );
            let (a, b) = (eye.y, -point.y);
            let offset = DVec2::new(point.x - eye.x, point.z - eye.z);
            let d = offset.length();
            let slope = |s: f64| {
                N_AIR * s / (s * s + a * a).sqrt()
                    - N_WATER * (d - s) / ((d - s).powi(2) + b * b).sqrt()
            };
            let (mut low, mut high) = (0.0_f64, d);
            loop {
                let mid = 0.5 * (low + high);
                if mid <= low || mid >= high {
                    break;
                }
                if slope(mid) < 0.0 {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            let bisected = DVec2::new(eye.x, eye.z) + offset * (0.5 * (low + high) / d);
            let sight = flat_sight_point(eye, point, 0.0, N_AIR, N_WATER);
            let gap = (DVec2::new(sight.x, sight.z) - bisected).length();
            assert!(gap <= 1e-13 * (1.0 + d), "{eye} {point}: {gap:e}");
        }
    }

    /// Snell's law holds at the sight point: n1 sin(theta1) = n2 sin(theta2), to f64 precision.
    #[test]
    fn sight_point_obeys_snell() {
        let eye = DVec3::new(-1.3, 2.7, 0.4);
        for (i, point) in [
            DVec3::new(2.0, -1.5, 1.1),
            DVec3::new(0.2, -0.01, -3.0),
            DVec3::new(-1.2, -4.0, 0.45),
            DVec3::new(30.0, -0.5, 12.0),
        ]
        .into_iter()
        .enumerate()
        {
            let level = 0.25;
            let s = flat_sight_point(eye, point, level, N_AIR, N_WATER);
            assert_eq!(s.y, level);
            let incoming = (s - eye).normalize();
            let outgoing = (point - s).normalize();
            let sin_in = DVec2::new(incoming.x, incoming.z).length();
            let sin_out = DVec2::new(outgoing.x, outgoing.z).length();
            assert!(
                (N_AIR * sin_in - N_WATER * sin_out).abs() < 1e-13,
                "case {i}: {} vs {}",
                N_AIR * sin_in,
                N_WATER * sin_out
            );
            // In the vertical plane through eye and point: the three are coplanar.
            let normal = (point - eye).cross(DVec3::Y);
            assert!(
                (s - eye).dot(normal).abs() < 1e-12 * normal.length().max(1.0),
                "case {i}"
            );
        }
    }

    /// The virtual vertex lies on the sight ray, at eta times the water path beyond the surface:
    /// foreshortening (ALGORITHM §4); straight down it is the classic apparent depth d * n1/n2.
    #[test]
    fn virtual_vertex_is_foreshortened() {
        let eye = DVec3::new(0.0, 3.0, 0.0);
        let point = DVec3::new(0.0, -2.0, 0.0);
        let (virtual_position, path_m) = flat_virtual_vertex(eye, point, 0.0, N_AIR, N_WATER);
        assert!((path_m - 2.0).abs() < 1e-15);
        assert!((virtual_position - DVec3::new(0.0, -2.0 / N_WATER, 0.0)).length() < 1e-14);

        let point = DVec3::new(4.0, -1.0, -2.0);
        let s = flat_sight_point(eye, point, 0.0, N_AIR, N_WATER);
        let (virtual_position, path_m) = flat_virtual_vertex(eye, point, 0.0, N_AIR, N_WATER);
        let along = (virtual_position - s).length();
        assert!((along - path_m * N_AIR / N_WATER).abs() < 1e-12);
        let sight_dir = (s - eye).normalize();
        assert!(((virtual_position - eye).normalize() - sight_dir).length() < 1e-14);
    }

    /// A point on the surface is its own sight point and its own virtual vertex.
    #[test]
    fn point_on_surface_is_its_own_image() {
        let eye = DVec3::new(1.0, 2.0, 3.0);
        let point = DVec3::new(-2.0, 0.5, 0.25);
        let (virtual_position, path_m) = flat_virtual_vertex(eye, point, 0.5, N_AIR, N_WATER);
        assert_eq!(path_m, 0.0);
        assert!((virtual_position - point).length() < 1e-15);
    }

    /// The stationary point is the minimum of the optical path: brute-force sampling along the line
    /// never finds a shorter path.
    #[test]
    fn sight_point_minimises_optical_path() {
        let eye = DVec3::new(0.3, 1.1, -0.7);
        let point = DVec3::new(2.5, -0.8, 1.9);
        let s = flat_sight_point(eye, point, 0.0, N_AIR, N_WATER);
        let path = |q: DVec3| N_AIR * (q - eye).length() + N_WATER * (point - q).length();
        let best = path(s);
        let start = DVec3::new(eye.x, 0.0, eye.z);
        let end = DVec3::new(point.x, 0.0, point.z);
        for i in 0..=10_000 {
            let q = start.lerp(end, i as f64 / 10_000.0);
            assert!(
                path(q) >= best - 1e-14,
                "sample {i} shorter: {} < {best}",
                path(q)
            );
        }
    }
}
