//! The CPU mirror of the shading model in `shaders/common.inc.wgsl` (ALGORITHM §7): sky, sun disk,
//! Schlick reflectance, Lambert above and under water, Beer-Lambert along the view path. The GPU
//! tests compare rendered pixels against these, and a ray-traced reference can shade with them so
//! both see the same model.

use glam::Vec3;

use crate::draw::{Lighting, WaterOptics};

/// Largest radiance of the sun disk per unit of sun colour. Energy conservation alone would give
/// pi / (solid angle of the disk), about 46,000 for the real sun; that overflows a half-float
/// beauty target (GL, max 65,504) once the colour exceeds ~1.4, and any tone mapping shows
/// 1,000 as white already.
pub const SUN_DISK_GAIN_MAX: f32 = 1000.0;

/// Cosine of the sun disk's angular radius: directions with `dot(dir, sun) >= this` see the disk.
pub fn sun_disk_cos_radius(lighting: &Lighting) -> f32 {
    (lighting.sun_size_deg.max(0.0) * 0.5).to_radians().cos()
}

/// Radiance of the sun disk per unit of `sun_color_linear`.
pub fn sun_disk_gain(lighting: &Lighting) -> f32 {
    let half_angle_rad = (lighting.sun_size_deg.max(0.0) * 0.5).to_radians();
    let solid_angle_sr = 2.0 * std::f32::consts::PI * (1.0 - half_angle_rad.cos());
    if solid_angle_sr <= 0.0 {
        return 0.0;
    }
    (std::f32::consts::PI / solid_angle_sr).min(SUN_DISK_GAIN_MAX)
}

/// Radiance of the sky along unit `direction`: a zenith-horizon gradient (horizon colour below the
/// horizon) plus the sun disk.
pub fn sky_radiance(direction: Vec3, lighting: &Lighting) -> Vec3 {
    let up = direction.y.clamp(0.0, 1.0);
    let toward_horizon = 1.0 - up;
    let horizon_weight = toward_horizon * toward_horizon * toward_horizon;
    let mut radiance = lighting.sky_zenith_linear * (1.0 - horizon_weight)
        + lighting.sky_horizon_linear * horizon_weight;
    if direction.dot(lighting.sun_direction) >= sun_disk_cos_radius(lighting) {
        radiance += lighting.sun_color_linear * sun_disk_gain(lighting);
    }
    radiance
}

/// Schlick's fraction reflected (ALGORITHM §3) for a sight ray `incident` meeting a membrane of unit
/// `normal` pointing to the eye's side, with `n_above` on the eye's side.
pub fn schlick_reflectance(incident: Vec3, normal: Vec3, n_above: f32, n_below: f32) -> f32 {
    // The shader clamps the cosine before the radicand (a back-facing pixel counts as grazing).
    let cos_incidence = (-incident.dot(normal)).clamp(0.0, 1.0);
    let eta = n_above / n_below;
    let radicand = 1.0 - eta * eta * (1.0 - cos_incidence * cos_incidence);
    crate::refraction::rays::schlick_reflectance(cos_incidence, radicand, n_above, n_below)
}

/// Unit vector toward the sun as seen under the flat mean water plane (sunlight refracted into the
/// water by Snell's law), or `None` when the sun is at or below the horizon or totally reflected.
pub fn sun_direction_in_water(lighting: &Lighting, water: &WaterOptics) -> Option<Vec3> {
    let toward_sun = lighting.sun_direction.normalize_or_zero();
    let cos_incidence = toward_sun.y;
    if cos_incidence <= 0.0 {
        return None;
    }
    let eta = water.n_above / water.n_below;
    let k = 1.0 - eta * eta * (1.0 - cos_incidence * cos_incidence);
    if k < 0.0 {
        return None;
    }
    // Light travels along -toward_sun; the plane's normal is +Y (toward the air).
    let transmitted = eta * -toward_sun + (eta * cos_incidence - k.sqrt()) * Vec3::Y;
    Some(-transmitted.normalize())
}

/// Radiance leaving a surface on the eye's side of the water: Lambert from the sun plus ambient.
pub fn shade_above(albedo_linear: Vec3, normal: Vec3, lighting: &Lighting) -> Vec3 {
    let sun = lighting.sun_color_linear * normal.dot(lighting.sun_direction).max(0.0);
    albedo_linear * (sun + lighting.ambient_linear)
}

/// Radiance reaching the membrane from an under-water point at `true_position` with unit `normal`,
/// seen along a true water path of `water_path_m` metres.
pub fn shade_under(
    albedo_linear: Vec3,
    normal: Vec3,
    true_position: Vec3,
    water_path_m: f32,
    lighting: &Lighting,
    water: &WaterOptics,
) -> Vec3 {
    let sigma = water.absorption_per_m;
    let depth_m = (water.mean_level_m - true_position.y).max(0.0);
    let sun = match sun_direction_in_water(lighting, water) {
        Some(toward_sun) => {
            let sun_path_m = depth_m / toward_sun.y;
            lighting.sun_color_linear
                * beer_lambert(sigma, sun_path_m)
                * normal.dot(toward_sun).max(0.0)
        }
        None => Vec3::ZERO,
    };
    let ambient = lighting.ambient_linear * beer_lambert(sigma, depth_m);
    let lit = albedo_linear * (sun + ambient);
    let transmittance = beer_lambert(sigma, water_path_m.max(0.0));
    lit * transmittance + water.scatter_color_linear * (Vec3::ONE - transmittance)
}

/// Per-channel transmittance `exp(-sigma * path)`; a negative path (round-off at the surface)
/// counts as zero, as in the shaders' callers.
pub fn beer_lambert(absorption_per_m: Vec3, path_m: f32) -> Vec3 {
    (-absorption_per_m * path_m.max(0.0)).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lighting() -> Lighting {
        Lighting {
            sky_zenith_linear: Vec3::new(0.2, 0.4, 0.9),
            sky_horizon_linear: Vec3::new(0.8, 0.85, 0.9),
            sun_direction: Vec3::new(0.3, 0.8, 0.2).normalize(),
            sun_color_linear: Vec3::new(3.0, 2.9, 2.7),
            sun_size_deg: 0.53,
            ambient_linear: Vec3::splat(0.3),
        }
    }

    #[test]
    fn sky_is_zenith_overhead_and_horizon_at_and_below_the_horizon() {
        let light = lighting();
        assert_eq!(sky_radiance(Vec3::Y, &light), light.sky_zenith_linear);
        assert_eq!(sky_radiance(Vec3::X, &light), light.sky_horizon_linear);
        assert_eq!(sky_radiance(-Vec3::Y, &light), light.sky_horizon_linear);
        let at_sun = sky_radiance(light.sun_direction, &light);
        assert!(
            at_sun.x > 100.0 * light.sky_zenith_linear.x,
            "sun disk missing: {at_sun}"
        );
    }

    #[test]
    fn schlick_is_r0_at_normal_incidence_and_one_at_grazing() {
        let r0 = ((1.0f32 - 1.333) / (1.0 + 1.333)).powi(2);
        let f = schlick_reflectance(-Vec3::Y, Vec3::Y, 1.0, 1.333);
        assert!((f - r0).abs() < 1e-7, "{f} vs {r0}");
        let grazing = schlick_reflectance(Vec3::X, Vec3::Y, 1.0, 1.333);
        assert!((grazing - 1.0).abs() < 1e-6);
        // Eye under water beyond the critical angle: total internal reflection.
        let steep = Vec3::new(0.9, -0.1, 0.0).normalize();
        assert_eq!(schlick_reflectance(steep, Vec3::Y, 1.333, 1.0), 1.0);
    }

    fn pool_water() -> WaterOptics {
        WaterOptics {
            n_above: 1.0,
            n_below: 1.333,
            absorption_per_m: Vec3::new(0.4, 0.1, 0.05),
            scatter_color_linear: Vec3::new(0.0, 0.05, 0.08),
            mean_level_m: 0.0,
        }
    }

    #[test]
    fn refracted_sun_obeys_snell() {
        let light = lighting();
        let water = pool_water();
        let in_water = sun_direction_in_water(&light, &water).unwrap();
        let sin_above = (1.0 - light.sun_direction.y.powi(2)).sqrt();
        let sin_below = (1.0 - in_water.y.powi(2)).sqrt();
        assert!((sin_above * 1.0 - sin_below * 1.333).abs() < 1e-5);
        assert!((in_water.length() - 1.0).abs() < 1e-6);
        // Same azimuth: horizontal components are parallel.
        let cross = light.sun_direction.x * in_water.z - light.sun_direction.z * in_water.x;
        assert!(cross.abs() < 1e-6);
        let mut set = light;
        set.sun_direction = Vec3::new(1.0, -0.1, 0.0).normalize();
        assert!(sun_direction_in_water(&set, &water).is_none());
    }

    #[test]
    fn deep_view_path_shows_the_scatter_colour_and_zero_path_the_lit_colour() {
        let light = lighting();
        let water = pool_water();
        let deep = shade_under(
            Vec3::ONE,
            Vec3::Y,
            Vec3::new(0.0, -1.0, 0.0),
            1e4,
            &light,
            &water,
        );
        assert!((deep - water.scatter_color_linear).length() < 1e-6);
        let at_surface = shade_under(Vec3::ONE, Vec3::Y, Vec3::ZERO, 0.0, &light, &water);
        let toward_sun = sun_direction_in_water(&light, &water).unwrap();
        let expected = light.sun_color_linear * toward_sun.y + light.ambient_linear;
        assert!(
            (at_surface - expected).length() < 1e-5,
            "{at_surface} vs {expected}"
        );
    }
}
