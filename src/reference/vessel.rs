//! Sight rays through glass vessels, traced exactly: receives the vessels and a ray; returns the
//! ray's pieces from wall to wall, Schlick's transmitted fraction over the walls crossed, and how
//! the path ended. Analytic intersection with the pane's two faces (within its rectangle) and the
//! cylinder's two walls (within its height); Snell's law at each ([`refract_exact`]); a ray that
//! meets a pane's edge face or a cylinder's rim stops there (they absorb, as in [`crate::vessel`]);
//! total internal reflection ends the transmitted path (the reflected ray is not followed). The
//! medium after a wall is the one on the wall's far side, so a ray leaving a pane's inside face is
//! in the pane's inside medium from then on, as the displacement assumes. Pure CPU, f64.

use glam::{DVec2, DVec3};

use crate::refraction::rays::{refract_exact, schlick_reflectance};
use crate::vessel::{Cylinder, Pane, Vessel, AIR_INDEX};

/// Most walls a traced ray crosses (four per cylinder; more only through several vessels).
pub const MAX_WALLS: usize = 16;

/// One straight piece of a traced ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    pub origin: DVec3,
    /// Unit.
    pub direction: DVec3,
    /// To the next wall; +inf for the last piece of an escaped ray.
    pub length_m: f64,
    /// Index of the medium it runs in.
    pub index: f64,
}

/// How a traced ray ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PathEnd {
    /// It left every vessel: the last piece runs to infinity.
    Escaped,
    /// Total internal reflection at the end of the last piece.
    TotalInternalReflection,
    /// It met a pane's edge face or a cylinder's rim at the end of the last piece.
    Absorbed,
    /// More than [`MAX_WALLS`] walls.
    TooManyWalls,
}

#[derive(Clone, Debug, PartialEq)]
pub struct VesselPath {
    pub pieces: Vec<Piece>,
    /// Product over the walls crossed of `1 - F` (Schlick, ALGORITHM §3).
    pub transmittance: f64,
    pub end: PathEnd,
}

impl VesselPath {
    /// Walls crossed (refractions).
    pub fn refractions(&self) -> usize {
        self.pieces.len() - 1
    }
}

/// A surface met by a ray.
#[derive(Clone, Copy, Debug)]
struct WallHit {
    t: f64,
    /// Unit normal of the surface; `front` is the index on the side it points to.
    normal: DVec3,
    front: f64,
    back: f64,
    absorbs: bool,
}

fn nearer(best: &mut Option<WallHit>, candidate: WallHit, t_min: f64) {
    if candidate.t > t_min && best.is_none_or(|b| candidate.t < b.t) {
        *best = Some(candidate);
    }
}

fn pane_hit(pane: &Pane, origin: DVec3, direction: DVec3, t_min: f64) -> Option<WallHit> {
    let w_axis = pane.w_axis();
    let axes = [pane.u_axis, w_axis, pane.normal];
    let half = [
        pane.half_size_m[0],
        pane.half_size_m[1],
        0.5 * pane.thickness_m,
    ];
    let local = |p: DVec3| axes.map(|a| (p - pane.center).dot(a));
    let o = local(origin);
    let d = axes.map(|a| direction.dot(a));
    let mut best = None;
    for axis in 0..3 {
        if d[axis].abs() < 1e-300 {
            continue;
        }
        for sign in [-1.0, 1.0] {
            let t = (sign * half[axis] - o[axis]) / d[axis];
            let inside = (0..3)
                .filter(|&other| other != axis)
                .all(|other| (o[other] + t * d[other]).abs() <= half[other]);
            if !inside {
                continue;
            }
            let (front, back) = match (axis, sign > 0.0) {
                (2, true) => (AIR_INDEX, pane.glass_index),
                // The inside face's normal points into the inside medium.
                (2, false) => (pane.inside.index(), pane.glass_index),
                _ => (0.0, 0.0),
            };
            let normal = sign * axes[axis];
            nearer(
                &mut best,
                WallHit {
                    t,
                    normal,
                    front,
                    back,
                    absorbs: axis != 2,
                },
                t_min,
            );
        }
    }
    best
}

fn cylinder_hit(
    cylinder: &Cylinder,
    origin: DVec3,
    direction: DVec3,
    t_min: f64,
) -> Option<WallHit> {
    let u = cylinder.axis.any_orthonormal_vector();
    let w = cylinder.axis.cross(u);
    let rel = origin - cylinder.base;
    let (p, q) = (
        DVec2::new(rel.dot(u), rel.dot(w)),
        DVec2::new(direction.dot(u), direction.dot(w)),
    );
    let (y, dy) = (rel.dot(cylinder.axis), direction.dot(cylinder.axis));
    let mut best = None;
    let walls = [
        (cylinder.outer_radius_m, AIR_INDEX, cylinder.glass_index),
        (
            cylinder.inner_radius_m,
            cylinder.glass_index,
            cylinder.inside.index(),
        ),
    ];
    let a = q.length_squared();
    if a > 1e-300 {
        for (radius, front, back) in walls {
            let (b, c) = (p.dot(q), p.length_squared() - radius * radius);
            let disc = b * b - a * c;
            if disc < 0.0 {
                continue;
            }
            let root = disc.sqrt();
            for t in [(-b - root) / a, (-b + root) / a] {
                let height = y + t * dy;
                if !(0.0..=cylinder.height_m).contains(&height) {
                    continue;
                }
                let at = p + t * q;
                let radial = (at.x * u + at.y * w) / radius;
                nearer(
                    &mut best,
                    WallHit {
                        t,
                        normal: radial,
                        front,
                        back,
                        absorbs: false,
                    },
                    t_min,
                );
            }
        }
    }
    if dy.abs() > 1e-300 {
        for (level, sign) in [(0.0, -1.0), (cylinder.height_m, 1.0)] {
            let t = (level - y) / dy;
            let rho = (p + t * q).length();
            if rho >= cylinder.inner_radius_m && rho <= cylinder.outer_radius_m {
                nearer(
                    &mut best,
                    WallHit {
                        t,
                        normal: sign * cylinder.axis,
                        front: 0.0,
                        back: 0.0,
                        absorbs: true,
                    },
                    t_min,
                );
            }
        }
    }
    best
}

/// Traces the ray from `origin` along unit `direction`, starting in a medium of index
/// `start_index`, through `vessels`.
pub fn trace(vessels: &[Vessel], origin: DVec3, direction: DVec3, start_index: f64) -> VesselPath {
    let mut pieces = Vec::new();
    let (mut origin, mut direction, mut index) = (origin, direction.normalize(), start_index);
    let mut transmittance = 1.0;
    for _ in 0..=MAX_WALLS {
        // A new piece starts on a wall: hits closer than this are that wall again.
        let t_min = 1e-9 * (1.0 + origin.length());
        let mut best: Option<WallHit> = None;
        for vessel in vessels {
            let hit = match vessel {
                Vessel::Pane(pane) => pane_hit(pane, origin, direction, t_min),
                Vessel::Cylinder(cylinder) => cylinder_hit(cylinder, origin, direction, t_min),
            };
            if let Some(hit) = hit {
                nearer(&mut best, hit, t_min);
            }
        }
        let Some(hit) = best else {
            pieces.push(Piece {
                origin,
                direction,
                length_m: f64::INFINITY,
                index,
            });
            return VesselPath {
                pieces,
                transmittance,
                end: PathEnd::Escaped,
            };
        };
        pieces.push(Piece {
            origin,
            direction,
            length_m: hit.t,
            index,
        });
        if hit.absorbs {
            return VesselPath {
                pieces,
                transmittance,
                end: PathEnd::Absorbed,
            };
        }
        let from_front = direction.dot(hit.normal) < 0.0;
        let (facing, n1, n2) = if from_front {
            (hit.normal, hit.front, hit.back)
        } else {
            (-hit.normal, hit.back, hit.front)
        };
        let Some(refracted) = refract_exact(direction, facing, n1 / n2) else {
            return VesselPath {
                pieces,
                transmittance,
                end: PathEnd::TotalInternalReflection,
            };
        };
        let cos_incidence = -direction.dot(facing);
        let eta = n1 / n2;
        let radicand = 1.0 - eta * eta * (1.0 - cos_incidence * cos_incidence);
        transmittance *= 1.0
            - schlick_reflectance(cos_incidence as f32, radicand as f32, n1 as f32, n2 as f32)
                as f64;
        origin += hit.t * direction;
        direction = refracted;
        index = n2;
    }
    VesselPath {
        pieces,
        transmittance,
        end: PathEnd::TooManyWalls,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeded::SplitMix64;
    use crate::vessel::{Image, Medium};

    const GLASS: f64 = 1.5;

    fn cylinder(inside: Medium) -> Cylinder {
        Cylinder {
            base: DVec3::new(0.05, -0.4, -0.1),
            axis: DVec3::new(-0.1, 1.0, 0.15).normalize(),
            inner_radius_m: 0.046,
            outer_radius_m: 0.05,
            height_m: 0.3,
            glass_index: GLASS,
            inside,
        }
    }

    fn pane(inside: Medium) -> Pane {
        let normal = DVec3::new(0.2, 0.1, 1.0).normalize();
        Pane {
            center: DVec3::new(0.0, 0.1, -0.3),
            normal,
            u_axis: normal.any_orthonormal_vector(),
            half_size_m: [0.4, 0.25],
            thickness_m: 0.01,
            glass_index: GLASS,
            inside,
        }
    }

    /// The traced ray along an image's first segment passes the point after exactly the image's
    /// walls, through the same crossings.
    fn check_image(vessel: &Vessel, eye: DVec3, point: DVec3, image: &Image) -> f64 {
        let first = image.crossings().first().copied().unwrap_or(point);
        let path = trace(
            std::slice::from_ref(vessel),
            eye,
            (first - eye).normalize(),
            AIR_INDEX,
        );
        let k = image.refractions as usize;
        assert!(
            path.pieces.len() > k,
            "traced ray ended ({:?}) after {} walls, the image has {k}",
            path.end,
            path.refractions()
        );
        for (i, &c) in image.crossings().iter().enumerate() {
            let traced = path.pieces[i + 1].origin;
            assert!(
                (traced - c).length() < 1e-8,
                "crossing {i}: traced {traced} vs solved {c}"
            );
        }
        let piece = path.pieces[k];
        let along = (point - piece.origin).dot(piece.direction);
        assert!(along > 0.0 && along <= piece.length_m + 1e-9);
        (piece.origin + along * piece.direction - point).length()
    }

    #[test]
    fn traced_rays_along_every_displaced_image_pass_through_the_point() {
        let mut rng = SplitMix64::new(1802);
        let mut per_count = [0usize; 5];
        let mut worst_m = 0.0f64;
        for inside in [Medium::Water, Medium::Air] {
            for vessel in [
                Vessel::Cylinder(cylinder(inside)),
                Vessel::Pane(pane(inside)),
            ] {
                for _ in 0..300 {
                    let eye = DVec3::new(
                        rng.range(-0.6, 0.6),
                        rng.range(-0.3, 0.5),
                        rng.range(0.3, 0.9),
                    );
                    let point = match vessel {
                        Vessel::Cylinder(c) => {
                            let u = c.axis.any_orthonormal_vector();
                            let w = c.axis.cross(u);
                            let a = rng.range(0.0, std::f64::consts::TAU);
                            c.base
                                + rng.range(0.0, 0.09) * (a.cos() * u + a.sin() * w)
                                + rng.range(0.02, 0.28) * c.axis
                        }
                        Vessel::Pane(p) => {
                            p.center - rng.range(-0.02, 0.5) * p.normal
                                + rng.range(-0.5, 0.5) * p.u_axis
                                + rng.range(-0.3, 0.3) * p.w_axis()
                        }
                    };
                    let mut images = Vec::new();
                    vessel.images(eye, point, &mut images);
                    for image in images.iter().filter(|i| i.converged) {
                        per_count[image.refractions as usize] += 1;
                        let miss_m = check_image(&vessel, eye, point, image);
                        assert!(
                            miss_m < 1e-8,
                            "{vessel:?} eye {eye} point {point}: the traced ray misses by {miss_m} m; {image:?}"
                        );
                        worst_m = worst_m.max(miss_m);
                    }
                }
            }
        }
        // 1e-9 of the scene's size is the solver's tolerance; the tracer adds f64 round-off.
        assert!(
            worst_m < 1e-8,
            "a traced ray misses its point by {worst_m} m"
        );
        for count in [0, 1, 2, 4] {
            assert!(per_count[count] > 10, "{per_count:?}");
        }
    }

    #[test]
    fn fresnel_at_normal_incidence_through_a_pane_and_total_internal_reflection_in_a_glass() {
        let pane = pane(Medium::Air);
        let path = trace(
            &[Vessel::Pane(pane)],
            pane.center + pane.normal,
            -pane.normal,
            AIR_INDEX,
        );
        assert_eq!(path.end, PathEnd::Escaped);
        assert_eq!(path.refractions(), 2);
        let r0 = ((1.0 - GLASS) / (1.0 + GLASS)).powi(2);
        assert!((path.transmittance - (1.0 - r0) * (1.0 - r0)).abs() < 1e-6);
        // Aimed between the two radii, a ray meets the inner wall at sin = b0 / r1 > 1 / 1.5:
        // with air inside it is totally reflected, with water inside (1.5 / 1.333) it gets in.
        for (inside, end, walls) in [
            (Medium::Air, PathEnd::TotalInternalReflection, 1),
            (Medium::Water, PathEnd::Escaped, 4),
        ] {
            let c = Cylinder {
                base: DVec3::ZERO,
                axis: DVec3::Y,
                height_m: 1.0,
                ..cylinder(inside)
            };
            let origin = DVec3::new(1.0, 0.5, 0.048);
            let path = trace(&[Vessel::Cylinder(c)], origin, -DVec3::X, AIR_INDEX);
            assert_eq!((path.end, path.refractions()), (end, walls), "{inside:?}");
        }
        // Through the rim of the glass: absorbed.
        let c = Cylinder {
            base: DVec3::ZERO,
            axis: DVec3::Y,
            height_m: 1.0,
            ..cylinder(Medium::Air)
        };
        let path = trace(
            &[Vessel::Cylinder(c)],
            DVec3::new(0.048, 2.0, 0.0),
            -DVec3::Y,
            AIR_INDEX,
        );
        assert_eq!(path.end, PathEnd::Absorbed);
    }
}
