//! CPU reference of the water's shading terms (ALGORITHM §7), so the ray-traced reference and the
//! tests compute exactly what the shaders compute: the sun's direction under the mean water plane
//! and Beer-Lambert transmittance along a path in water.

use glam::Vec3;

/// Direction sunlight travels in the water after refraction through the flat mean plane (normal +y).
/// `sun_dir_to_sun` points from the scene toward the sun (any length); `n_above`/`n_below` are the
/// indices of refraction of air and water. Returns a unit vector pointing down.
///
/// A sun at or below the horizon is treated as grazing (incidence 90 degrees): the light enters at
/// the critical angle, continuous with a sun just above the horizon (ALGORITHM §2's back-facing
/// rule). Should n_above exceed n_below and the sun be past the critical angle, the transmitted
/// direction is clamped to horizontal rather than reflected, since no light would enter at all.
pub fn refracted_sun_direction(sun_dir_to_sun: Vec3, n_above: f32, n_below: f32) -> Vec3 {
    let incident = -sun_dir_to_sun.normalize();
    let eta = n_above / n_below;
    // cos of incidence against the up normal; grazing when the sun is at or below the horizon.
    let cos_incidence = (-incident.y).max(0.0);
    let horizontal = Vec3::new(incident.x, 0.0, incident.z);
    // Rebuild the incident ray at the clamped angle so its horizontal part is sin(incidence).
    let sin_incidence = (1.0 - cos_incidence * cos_incidence).max(0.0).sqrt();
    let horizontal_unit = horizontal.try_normalize().unwrap_or(Vec3::ZERO);
    let transmitted_horizontal = horizontal_unit * (eta * sin_incidence).min(1.0);
    let cos_transmitted = (1.0 - transmitted_horizontal.length_squared())
        .max(0.0)
        .sqrt();
    (transmitted_horizontal - Vec3::Y * cos_transmitted).normalize()
}

/// Beer-Lambert transmittance `exp(-absorption * path)` per channel; `absorption` in 1/m. A
/// negative path (round-off at the surface) counts as zero.
pub fn beer_lambert(absorption: Vec3, path_m: f32) -> Vec3 {
    (-absorption * path_m.max(0.0)).exp()
}

/// Length of the sun's path through water down to a point `depth_below_surface_m` under the mean
/// plane, along `refracted_sun` (from [`refracted_sun_direction`]): depth / cos.
pub fn sun_path_in_water_m(refracted_sun: Vec3, depth_below_surface_m: f32) -> f32 {
    // A refracted sun is never flatter than the critical angle for n_above < n_below; the floor
    // only guards the degenerate n_above >= n_below grazing case.
    depth_below_surface_m.max(0.0) / (-refracted_sun.y).max(1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;

    const AIR: f32 = 1.0;
    const WATER: f32 = 1.333;

    #[test]
    fn overhead_sun_goes_straight_down() {
        let d = refracted_sun_direction(Vec3::Y * 3.0, AIR, WATER);
        assert!((d - Vec3::NEG_Y).length() < 1e-6, "{d}");
    }

    #[test]
    fn refraction_obeys_snells_law_and_stays_in_the_plane_of_incidence() {
        for elevation_deg in [5.0_f32, 20.0, 45.0, 70.0, 89.0] {
            let azimuth = 0.7_f32;
            let elevation = elevation_deg.to_radians();
            let to_sun = Vec3::new(
                elevation.cos() * azimuth.cos(),
                elevation.sin(),
                elevation.cos() * azimuth.sin(),
            );
            let d = refracted_sun_direction(to_sun, AIR, WATER);
            assert!((d.length() - 1.0).abs() < 1e-6);
            assert!(d.y < 0.0);
            let sin_incidence = elevation.cos();
            let sin_transmitted = (d.x * d.x + d.z * d.z).sqrt();
            assert!(
                (AIR * sin_incidence - WATER * sin_transmitted).abs() < 1e-5,
                "at {elevation_deg} deg"
            );
            // Light travels away from the sun: its horizontal part points opposite to the sun's.
            let along_sun = d.x * azimuth.cos() + d.z * azimuth.sin();
            assert!((along_sun + sin_transmitted).abs() < 1e-5);
        }
    }

    #[test]
    fn equal_indices_do_not_bend_and_a_low_sun_enters_near_the_critical_angle() {
        let to_sun = Vec3::new(0.5, 0.3, -0.2);
        let d = refracted_sun_direction(to_sun, 1.0, 1.0);
        assert!((d + to_sun.normalize()).length() < 1e-6);
        let critical_sin = AIR / WATER;
        for to_sun in [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, -0.5, 0.0),
            Vec3::new(1.0, 1e-4, 0.0),
        ] {
            let d = refracted_sun_direction(to_sun, AIR, WATER);
            let sin_transmitted = (d.x * d.x + d.z * d.z).sqrt();
            assert!(
                (sin_transmitted - critical_sin).abs() < 1e-4,
                "{to_sun}: {sin_transmitted}"
            );
            assert!(d.x < 0.0);
        }
    }

    #[test]
    fn beer_lambert_is_exponential_in_path_length_per_channel() {
        let absorption = Vec3::new(0.45, 0.07, 0.02);
        assert_eq!(beer_lambert(absorption, 0.0), Vec3::ONE);
        assert_eq!(beer_lambert(absorption, -0.01), Vec3::ONE);
        let one_over_red = beer_lambert(absorption, 1.0 / 0.45);
        assert!((one_over_red.x - (-1.0_f32).exp()).abs() < 1e-6);
        let split = beer_lambert(absorption, 1.2) * beer_lambert(absorption, 2.3);
        assert!((split - beer_lambert(absorption, 3.5)).length() < 1e-6);
        // Red goes first in water.
        let deep = beer_lambert(absorption, 5.0);
        assert!(deep.x < deep.y && deep.y < deep.z);
    }

    #[test]
    fn sun_path_is_depth_over_cosine() {
        let d = refracted_sun_direction(Vec3::new(1.0, 1.0, 0.0), AIR, WATER);
        let path_m = sun_path_in_water_m(d, 2.0);
        assert!((path_m * -d.y - 2.0).abs() < 1e-5);
        assert_eq!(sun_path_in_water_m(d, -0.5), 0.0);
    }
}
