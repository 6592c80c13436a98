//! The CPU mirror of the shading model in `shaders/common.inc.wgsl` (ALGORITHM §7): sky, sun disk,
//! Schlick reflectance, Lambert above and under water, Beer-Lambert along the view path. The GPU
//! tests compare rendered pixels against these, and a ray-traced reference can shade with them so
//! both see the same model.

use glam::Vec3;

use crate::draw::{Lighting, WaterOptics};

/// The largest radiance any shading function returns: the largest finite half float. GL's beauty
/// target is half float (llvmpipe renders no float32), where a larger value would become
/// infinite; on float32 targets the same limit keeps the two backends alike. Reached only by the
/// sun disk itself with a sun brighter than about 1.4 (its colour times intensity) and by glints
/// near grazing.
pub const RADIANCE_MAX: f32 = 65504.0;

/// Cosine of the sun disk's angular radius: directions with `dot(dir, sun) >= this` see the disk.
pub fn sun_disk_cos_radius(lighting: &Lighting) -> f32 {
    (lighting.sun_size_deg.max(0.0) * 0.5).to_radians().cos()
}

/// Radiance of the sun disk per unit of `sun_color_linear`: pi / (the disk's solid angle), so that
/// the disk's irradiance on a surface facing it is pi times the sun colour (E = L x solid angle),
/// the irradiance Lambert's `albedo * sun_color * cos` stands for (radiance = albedo / pi * E cos).
/// The real sun's 0.53 degrees: 46,200. The product with the colour is capped at [`RADIANCE_MAX`]
/// where it is used.
pub fn sun_disk_gain(lighting: &Lighting) -> f32 {
    let solid_angle_sr = sun_solid_angle_sr(lighting);
    if solid_angle_sr <= 0.0 {
        return 0.0;
    }
    std::f32::consts::PI / solid_angle_sr
}

/// Solid angle of the sun disk, steradians.
fn sun_solid_angle_sr(lighting: &Lighting) -> f32 {
    let half_angle_rad = (lighting.sun_size_deg.max(0.0) * 0.5).to_radians();
    2.0 * std::f32::consts::PI * (1.0 - half_angle_rad.cos())
}

/// Irradiance of the sun on a surface facing it, per channel: pi times the sun colour.
pub fn sun_irradiance(lighting: &Lighting) -> Vec3 {
    std::f32::consts::PI * lighting.sun_color_linear
}

/// Radiance of the sky along unit `direction` without the sun: a zenith-horizon gradient (the
/// horizon colour below the horizon).
pub fn sky_gradient(direction: Vec3, lighting: &Lighting) -> Vec3 {
    let up = direction.y.clamp(0.0, 1.0);
    let toward_horizon = 1.0 - up;
    let horizon_weight = toward_horizon * toward_horizon * toward_horizon;
    lighting.sky_zenith_linear * (1.0 - horizon_weight)
        + lighting.sky_horizon_linear * horizon_weight
}

/// Radiance of the sky along unit `direction`: [`sky_gradient`] plus the sun disk (capped at
/// [`RADIANCE_MAX`]).
pub fn sky_radiance(direction: Vec3, lighting: &Lighting) -> Vec3 {
    let mut radiance = sky_gradient(direction, lighting);
    if direction.dot(lighting.sun_direction) >= sun_disk_cos_radius(lighting) {
        radiance += lighting.sun_color_linear * sun_disk_gain(lighting);
    }
    radiance.min(Vec3::splat(RADIANCE_MAX))
}

/// Beckmann roughness (the rms slope) that stands for the sun disk's own size in the glint's
/// distribution of facet normals: a facet reflects the sun's centre toward the eye where its
/// normal is the half vector, and a sun of angular radius r moves the half vector by up to r / 2.
/// A uniform disk of radius `rho = tan(r / 2)` in slope space has the per-axis variance rho^2 / 4 of
/// a Beckmann distribution of roughness `rho / sqrt 2`; the glint's distribution is the facets'
/// convolved with it, roughness^2 adding.
pub fn sun_slope_roughness(lighting: &Lighting) -> f32 {
    let rho = (lighting.sun_size_deg.max(0.0) * 0.25).to_radians().tan();
    rho * std::f32::consts::FRAC_1_SQRT_2
}

/// The square of the glint's Beckmann roughness: the water's (`water.roughness`) and the sun
/// disk's ([`sun_slope_roughness`]) added in quadrature; never 0 (a point sun on a mirror).
pub fn glint_roughness2(lighting: &Lighting, water: &WaterOptics) -> f32 {
    let sun_alpha = sun_slope_roughness(lighting);
    (water.roughness * water.roughness + sun_alpha * sun_alpha).max(1e-12)
}

/// Smith's masking of one direction at cosine `cos` to the macro normal, for a Beckmann surface
/// of roughness `alpha` (Walter et al. 2007's rational approximation).
fn smith_beckmann(cos: f32, alpha: f32) -> f32 {
    let cos = cos.clamp(1e-6, 1.0);
    let tan = (1.0 - cos * cos).max(0.0).sqrt() / cos;
    let a = 1.0 / (alpha * tan).max(1e-30);
    if a >= 1.6 {
        return 1.0;
    }
    (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
}

/// The sun's glint: radiance the water sends along `-incident` from the sun by specular
/// reflection off facets finer than the membrane. Cook-Torrance with Beckmann's distribution of
/// facet normals about the membrane's `normal` (roughness `water.roughness`, the rms slope of the
/// unresolved waves, convolved with the sun disk: [`sun_slope_roughness`]), Smith's masking and
/// Schlick's F at the facet:
/// `L = E_sun F(h) D(h) G / (4 cos_view)` (the facets' share of the sun's irradiance
/// `E_sun cos_sun` reflected toward the eye; D integrates to 1 over projected facet area, so as
/// the roughness goes to 0 the glint tends to the sun disk seen in a mirror, with its energy).
/// Zero where the sun or the eye is behind the membrane; capped at [`RADIANCE_MAX`].
pub fn sun_glint(incident: Vec3, normal: Vec3, lighting: &Lighting, water: &WaterOptics) -> Vec3 {
    let to_eye = -incident;
    let to_sun = lighting.sun_direction;
    let cos_view = normal.dot(to_eye);
    let cos_sun = normal.dot(to_sun);
    if cos_view <= 0.0 || cos_sun <= 0.0 {
        return Vec3::ZERO;
    }
    let half = (to_eye + to_sun).normalize_or_zero();
    let cos_half = normal.dot(half);
    if cos_half <= 0.0 {
        return Vec3::ZERO;
    }
    let alpha2 = glint_roughness2(lighting, water);
    let alpha = alpha2.sqrt();
    let cos2 = cos_half * cos_half;
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    let distribution = (-tan2 / alpha2).exp() / (std::f32::consts::PI * alpha2 * cos2 * cos2);
    let masking = smith_beckmann(cos_view, alpha) * smith_beckmann(cos_sun, alpha);
    let fresnel = schlick_reflectance(incident, half, water.n_above, water.n_below);
    let glint = sun_irradiance(lighting) * (fresnel * distribution * masking / (4.0 * cos_view));
    glint.min(Vec3::splat(RADIANCE_MAX))
}

/// What the water reflects toward the eye along `incident` at a membrane point of unit `normal`
/// (pointing to the eye's side): Schlick's F times the sky reflected (without the sun disk) plus
/// the sun's [`sun_glint`], capped at [`RADIANCE_MAX`]; and F. The one model of the water's
/// reflection, the rasteriser's (`water_reflection` in shaders/common.inc.wgsl) and the
/// reference's.
pub fn water_reflection(
    incident: Vec3,
    normal: Vec3,
    lighting: &Lighting,
    water: &WaterOptics,
) -> (Vec3, f32) {
    let reflectance = schlick_reflectance(incident, normal, water.n_above, water.n_below);
    let reflected = incident - 2.0 * incident.dot(normal) * normal;
    let radiance = reflectance * sky_gradient(reflected, lighting)
        + sun_glint(incident, normal, lighting, water);
    (radiance.min(Vec3::splat(RADIANCE_MAX)), reflectance)
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

    /// The glint's energy, integrated numerically over the directions it leaves in (a polar grid
    /// about the mirror direction): the exitance `∫ L cos_view dω` of a smooth-ish surface is the
    /// sun's irradiance on it, `E_sun cos_sun`, times Fresnel's reflectance at the mirror angle
    /// (facets integrate to one; Smith's masking takes a little at these slopes). And the glint
    /// is zero with the sun or the eye behind the surface.
    #[test]
    fn the_glint_reflects_f_times_the_suns_irradiance() {
        let mut light = lighting();
        let elevation = 40f32.to_radians();
        light.sun_direction = Vec3::new(0.0, elevation.sin(), elevation.cos());
        let mut water = pool_water();
        for roughness in [0.02f32, 0.05, 0.1] {
            water.roughness = roughness;
            let mirror = Vec3::new(0.0, elevation.sin(), -elevation.cos());
            // A frame about the mirror direction.
            let side = Vec3::X;
            let up = side.cross(mirror);
            let (rings, spokes) = (800, 256);
            let max_angle = (8.0 * roughness).min(1.2);
            let mut exitance = Vec3::ZERO;
            for i in 0..rings {
                let theta = (i as f32 + 0.5) / rings as f32 * max_angle;
                let d_theta = max_angle / rings as f32;
                for j in 0..spokes {
                    let phi = (j as f32 + 0.5) / spokes as f32 * std::f32::consts::TAU;
                    let out = (mirror * theta.cos()
                        + (side * phi.cos() + up * phi.sin()) * theta.sin())
                    .normalize();
                    if out.y <= 0.0 {
                        continue;
                    }
                    let solid_angle = theta.sin() * d_theta * std::f32::consts::TAU / spokes as f32;
                    exitance += sun_glint(-out, Vec3::Y, &light, &water) * out.y * solid_angle;
                }
            }
            let cos_sun = light.sun_direction.y;
            let fresnel = schlick_reflectance(-mirror, Vec3::Y, 1.0, 1.333);
            let expected = sun_irradiance(&light) * cos_sun * fresnel;
            let ratio = exitance / expected;
            assert!(
                (ratio - Vec3::ONE).abs().max_element() < 0.05,
                "roughness {roughness}: exitance {exitance} against F E cos {expected}"
            );
        }
        // Sun or eye behind the surface: nothing.
        assert_eq!(
            sun_glint(Vec3::Y, Vec3::Y, &light, &water),
            Vec3::ZERO,
            "eye under the surface"
        );
        light.sun_direction = -light.sun_direction;
        let down = Vec3::new(0.0, -elevation.sin(), elevation.cos());
        assert_eq!(sun_glint(down, Vec3::Y, &light, &water), Vec3::ZERO);
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
            roughness: 0.05,
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
