//! Refraction rays (ALGORITHM §1-§4): receives the membrane, the eye and the two indices of
//! refraction; returns one refraction ray per membrane vertex (origin, unit direction, and whether
//! it had to be extrapolated), and Schlick's Fresnel reflectance, which the shading model
//! ([`crate::gpu::shading`]) evaluates per pixel. Every vertex gets a ray: back-facing
//! and totally internally reflected vertices get the extrapolations of §2, continuous at their
//! borders, so cells exist for every facet and rays never jump as the eye moves.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::water::Membrane;

/// How a refraction ray was obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Extrapolation {
    /// Snell's law applies as is.
    #[default]
    None,
    /// The sight ray hits the facet from behind (`c < 0`), an artefact of faceting: evaluated as if `c = 0`.
    BackFacing,
    /// Total internal reflection (`k < 0`, only when the eye's medium is the denser one).
    TotalInternalReflection,
}

impl Extrapolation {
    pub fn is_extrapolated(self) -> bool {
        self != Extrapolation::None
    }
}

/// The refraction ray of one membrane vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefractionRay {
    /// The membrane vertex `P_i`.
    pub origin: Vec3,
    /// Unit direction `T_i` of the refracted ray.
    pub direction: Vec3,
    pub extrapolation: Extrapolation,
}

/// A refracted direction and how it was obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refraction {
    /// Unit refracted direction.
    pub direction: Vec3,
    /// `c = -dot(I, N)`, cosine of the incidence angle as given (negative when back-facing).
    pub cos_incidence: f32,
    /// `k = 1 - eta^2 (1 - c^2)` for the `c` actually used (`c` clamped to 0 when back-facing);
    /// `sqrt(k)` is the cosine of the transmitted angle when `k >= 0`.
    pub radicand: f32,
    pub extrapolation: Extrapolation,
}

/// Snell's law in vector form with the two extrapolations of ALGORITHM §2.
///
/// `incident` is the unit sight direction travelling toward the membrane, `normal` the unit normal
/// pointing to the incident side, `eta = n1 / n2` (incident side over far side).
pub fn refract(incident: Vec3, normal: Vec3, eta: f32) -> Refraction {
    let c_given = -incident.dot(normal);
    let back_facing = c_given < 0.0;
    // Back-facing: evaluate as if the sight ray grazed the facet (c = 0); I still has a component
    // along N then, so the result is normalised. This is continuous at c = 0 from both sides.
    let c = c_given.max(0.0);
    let k = 1.0 - eta * eta * (1.0 - c * c);
    let (direction, extrapolation) = if k >= 0.0 {
        let t = eta * incident + (eta * c - k.sqrt()) * normal;
        let kind = if back_facing {
            Extrapolation::BackFacing
        } else {
            Extrapolation::None
        };
        (t, kind)
    } else {
        // Total internal reflection: negate the radicand and the root. At k = 0 both branches give
        // eta (I + c N), so the ray is continuous across the TIR border; it points back to the eye's side.
        let t = eta * (incident + c * normal) + (-k).sqrt() * normal;
        let kind = if back_facing {
            Extrapolation::BackFacing
        } else {
            Extrapolation::TotalInternalReflection
        };
        (t, kind)
    };
    Refraction {
        direction: direction.normalize(),
        cos_incidence: c_given,
        radicand: k,
        extrapolation,
    }
}

/// Snell's law in f64 without extrapolation (ALGORITHM §1), for exact work (computed vertices,
/// checks of exact sight points): None when the ray meets the surface from behind (`c < 0`) or is
/// totally reflected (`k < 0`), where no refracted ray exists.
pub fn refract_exact(incident: DVec3, normal: DVec3, eta: f64) -> Option<DVec3> {
    let c = -incident.dot(normal);
    let k = 1.0 - eta * eta * (1.0 - c * c);
    if c < 0.0 || k < 0.0 {
        return None;
    }
    Some((eta * incident + (eta * c - k.sqrt()) * normal).normalize())
}

/// Schlick's approximation of the reflected fraction (ALGORITHM §3). `cos_incidence` is `c`,
/// `radicand` is `k` from [`refract`]. When the eye's medium is the denser one (`n1 > n2`) the
/// cosine of the transmitted angle (`sqrt(k)`) is used, and total internal reflection reflects all.
pub fn schlick_reflectance(cos_incidence: f32, radicand: f32, n1: f32, n2: f32) -> f32 {
    let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
    let x = if n1 <= n2 {
        cos_incidence.clamp(0.0, 1.0)
    } else if radicand < 0.0 {
        return 1.0;
    } else {
        radicand.sqrt().min(1.0)
    };
    r0 + (1.0 - r0) * (1.0 - x).powi(5)
}

/// The refraction ray of one membrane vertex seen from `eye`.
pub fn refraction_ray(
    position: Vec3,
    normal: Vec3,
    eye: Vec3,
    n_above: f32,
    n_below: f32,
) -> RefractionRay {
    let incident = (position - eye).normalize_or(Vec3::NEG_Y);
    let refraction = refract(incident, normal, n_above / n_below);
    RefractionRay {
        origin: position,
        direction: refraction.direction,
        extrapolation: refraction.extrapolation,
    }
}

/// One refraction ray per membrane vertex (same order as `membrane.positions`), in parallel.
///
/// The eye is taken to be on the `n_above` side; the membrane normals point up, to that side.
pub fn refraction_rays(
    membrane: &Membrane,
    eye: Vec3,
    n_above: f32,
    n_below: f32,
) -> Vec<RefractionRay> {
    membrane
        .positions
        .par_iter()
        .zip(membrane.normals.par_iter())
        .with_min_len(1024)
        .map(|(&position, &normal)| refraction_ray(position, normal, eye, n_above, n_below))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const AIR: f32 = 1.0;
    const WATER: f32 = 1.333;

    fn direction_at_deg(incidence_deg: f32) -> Vec3 {
        // Travelling down (toward a membrane with normal +y), tilted toward +x.
        let a = incidence_deg.to_radians();
        Vec3::new(a.sin(), -a.cos(), 0.0)
    }

    #[test]
    fn snell_45_degrees_air_to_water_matches_known_angle() {
        let r = refract(direction_at_deg(45.0), Vec3::Y, AIR / WATER);
        assert_eq!(r.extrapolation, Extrapolation::None);
        // sin(theta_t) = sin(45°) / 1.333 -> theta_t = 32.027°.
        let expected_deg = ((45.0_f32).to_radians().sin() / WATER).asin().to_degrees();
        assert!((expected_deg - 32.027).abs() < 1e-2);
        let theta_t_deg = r.direction.x.atan2(-r.direction.y).to_degrees();
        assert!((theta_t_deg - expected_deg).abs() < 1e-4, "{theta_t_deg}");
        assert!(r.direction.z.abs() < 1e-7);
    }

    #[test]
    fn snell_normal_incidence_goes_straight_and_all_directions_are_unit() {
        let r = refract(Vec3::NEG_Y, Vec3::Y, AIR / WATER);
        assert!((r.direction - Vec3::NEG_Y).length() < 1e-6);
        for i in 0..=90 {
            for &eta in &[AIR / WATER, WATER / AIR, 1.0 / 1.51, 1.0] {
                let normal = Vec3::new(0.3, 1.0, -0.2).normalize();
                let incident = (direction_at_deg(i as f32)
                    + Vec3::new(0.0, 0.0, 0.1 * i as f32 / 90.0))
                .normalize();
                let r = refract(incident, normal, eta);
                assert!((r.direction.length() - 1.0).abs() < 1e-5);
                // Unextrapolated rays obey sin(theta_t) = eta sin(theta_i).
                if r.extrapolation == Extrapolation::None {
                    let sin_i = incident.cross(normal).length();
                    let sin_t = r.direction.cross(normal).length();
                    assert!((sin_t - eta * sin_i).abs() < 1e-5, "eta {eta} i {i}");
                    assert!(r.direction.dot(normal) <= 0.0);
                }
            }
        }
    }

    /// A sight direction whose cosine against +y is exactly `c` (may be negative: back-facing).
    fn incident_with_cos(c: f32) -> Vec3 {
        Vec3::new((1.0 - c * c).max(0.0).sqrt(), -c, 0.0)
    }

    #[test]
    fn back_facing_extrapolation_is_continuous_at_its_border() {
        for &eta in &[AIR / WATER, WATER / AIR] {
            let at_border = refract(incident_with_cos(0.0), Vec3::Y, eta).direction;
            let mut previous_gap = f32::INFINITY;
            for step in 1..=6 {
                let c = 10f32.powi(-step);
                let front = refract(incident_with_cos(c), Vec3::Y, eta);
                let back = refract(incident_with_cos(-c), Vec3::Y, eta);
                assert_eq!(back.extrapolation, Extrapolation::BackFacing);
                assert!(front.extrapolation != Extrapolation::BackFacing);
                let gap = (front.direction - back.direction).length();
                assert!(
                    (back.direction - at_border).length() <= 4.0 * c + 1e-6,
                    "eta {eta} c {c}"
                );
                assert!(gap <= previous_gap + 1e-6);
                previous_gap = gap;
            }
            assert!(previous_gap < 1e-3, "eta {eta}: gap {previous_gap}");
        }
        // For eta < 1 the border ray is eta I - sqrt(1 - eta^2) N; for eta > 1, eta I + sqrt(eta^2 - 1) N.
        let eta = AIR / WATER;
        let i = incident_with_cos(0.0);
        let expected = (eta * i - (1.0 - eta * eta).sqrt() * Vec3::Y).normalize();
        let back = refract(incident_with_cos(-0.3), Vec3::Y, eta).direction;
        let tilted =
            (eta * incident_with_cos(-0.3) - (1.0 - eta * eta).sqrt() * Vec3::Y).normalize();
        assert!((back - tilted).length() < 1e-6);
        assert!((refract(i, Vec3::Y, eta).direction - expected).length() < 1e-6);
        let eta = WATER / AIR;
        let expected =
            (eta * incident_with_cos(-0.3) + (eta * eta - 1.0).sqrt() * Vec3::Y).normalize();
        assert!(
            (refract(incident_with_cos(-0.3), Vec3::Y, eta).direction - expected).length() < 1e-6
        );
    }

    #[test]
    fn total_internal_reflection_extrapolation_is_continuous_at_its_border() {
        let eta = WATER / AIR;
        // k = 0 at c_crit = sqrt(1 - 1/eta^2).
        let c_crit = (1.0 - 1.0 / (eta * eta)).sqrt();
        let mut last_gap = f32::INFINITY;
        for step in 2..=6 {
            let dc = 10f32.powi(-step);
            let refracted = refract(incident_with_cos(c_crit + dc), Vec3::Y, eta);
            let reflected = refract(incident_with_cos(c_crit - dc), Vec3::Y, eta);
            assert_eq!(refracted.extrapolation, Extrapolation::None);
            assert_eq!(
                reflected.extrapolation,
                Extrapolation::TotalInternalReflection
            );
            assert!(refracted.radicand > 0.0 && reflected.radicand < 0.0);
            let gap = (refracted.direction - reflected.direction).length();
            // The root makes the approach sqrt-like: gap ~ 2 sqrt(|k|) ~ sqrt(dc).
            assert!(
                gap < 4.0 * (eta * eta * 2.0 * c_crit * dc).sqrt() + 1e-5,
                "dc {dc} gap {gap}"
            );
            assert!(gap <= last_gap + 1e-6);
            last_gap = gap;
        }
        assert!(last_gap < 1e-2);
        // Under TIR the extrapolated ray points back to the eye's side.
        let deep = refract(incident_with_cos(0.1), Vec3::Y, eta);
        assert!(deep.direction.y > 0.0);
    }

    #[test]
    fn exact_refraction_agrees_with_the_f32_ray_and_refuses_where_it_extrapolates() {
        for incidence_deg in [0.0f32, 20.0, 45.0, 70.0, 89.0] {
            let incident = direction_at_deg(incidence_deg);
            let expected = refract(incident, Vec3::Y, AIR / WATER).direction;
            let exact = refract_exact(incident.as_dvec3(), DVec3::Y, (AIR / WATER) as f64).unwrap();
            assert!(
                (exact.as_vec3() - expected).length() < 1e-6,
                "{incidence_deg} deg"
            );
        }
        // Back-facing (the ray meets the surface from below) and total internal reflection.
        assert_eq!(refract_exact(DVec3::Y, DVec3::Y, 0.75), None);
        let grazing_out_of_water = direction_at_deg(80.0).as_dvec3();
        assert_eq!(refract_exact(grazing_out_of_water, DVec3::Y, 1.333), None);
    }

    #[test]
    fn schlick_normal_incidence_is_r0_and_grazing_is_one() {
        let r0 = ((AIR - WATER) / (AIR + WATER)).powi(2);
        assert!((schlick_reflectance(1.0, 1.0, AIR, WATER) - r0).abs() < 1e-7);
        assert!(
            (schlick_reflectance(0.0, 1.0 - (AIR / WATER).powi(2), AIR, WATER) - 1.0).abs() < 1e-7
        );
        assert!((r0 - 0.02037).abs() < 1e-4);
        // n1 > n2 uses the transmitted cosine; TIR reflects everything.
        assert!((schlick_reflectance(1.0, 1.0, WATER, AIR) - r0).abs() < 1e-7);
        assert_eq!(schlick_reflectance(0.5, -0.1, WATER, AIR), 1.0);
        // Monotone: more grazing reflects more.
        let mut last = 0.0;
        for i in 0..=20 {
            let c = 1.0 - i as f32 / 20.0;
            let f = schlick_reflectance(c, 0.0, AIR, WATER);
            assert!(f >= last);
            last = f;
        }
    }
}
