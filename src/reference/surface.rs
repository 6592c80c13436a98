//! Where a sight ray meets the water, in the two models the reference offers: the exact surface
//! (the frame's analytic height field, root found along the ray) and the triangulated membrane
//! with interpolated vertex normals (what the rasteriser draws). Water exists only over the
//! membrane's horizontal extent, as in the rasteriser (`refraction::split`): outside it there is
//! no surface to meet.
//!
//! The root finder never steps over the surface. Along the ray `p(t) = o + t d` the clearance
//! `f(t) = p_y(t) - h(p_x(t), p_z(t))` has `|f'| <= L = |d_y| + G |d_xz|` and `|f''| <= K =
//! C |d_xz|^2`, where G and C bound the surface's slope and curvature over the whole plane. From a
//! point with `f > 0`, the parabola `f + f' s - K s^2 / 2` and the line `f - L s` are lower bounds
//! of `f(t + s)`, so no root lies before the larger of their first zeros: the next step. Near a
//! crossing this is a Newton step that stops short of the root; past a crest it takes long strides;
//! on a ray grazing a crest the steps shrink like `sqrt(2 f / K)` but never jump over it. A sign
//! change after a step (a jump in the field, or round-off) is refined by bisection.

use glam::{DVec3, Vec3};

use super::bvh::{Bvh, Ray};
use crate::water::{HeightField, Membrane, MembraneGrid};

/// `f` below which the ray is on the surface, metres (far under a pixel at any useful distance).
pub const SURFACE_HIT_TOLERANCE_M: f64 = 1e-7;
/// Steps after which a ray that keeps grazing the surface within this many metres counts as
/// touching it; rays that graze farther are misses. Reached only within a hair of tangency.
const MAX_STEPS: u32 = 10_000;
const GRAZING_TOUCH_M: f64 = 1e-5;

/// Where a ray meets the water.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Ray parameter (the direction's length is the unit).
    pub t: f64,
    pub position: DVec3,
    /// Unit normal pointing up (to the air side).
    pub normal: DVec3,
}

/// The frame's exact water surface over the membrane's extent, with the bounds the root finder
/// steps by.
pub struct ExactSurface<'a> {
    pub field: &'a dyn HeightField,
    pub extent: MembraneGrid,
    /// Lowest and highest height the field reaches, metres.
    pub height_range_m: (f64, f64),
    /// Largest |grad h| and largest |second derivative along a unit horizontal direction|.
    pub slope_bound: f64,
    pub curvature_bound: f64,
}

/// Counts of the root finder's work on one ray (for the bench and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RootSteps {
    /// Height-field evaluations.
    pub evaluations: u32,
}

/// Parameters `(t0, t1)` over which the ray is inside the box `[min, max]`, clipped to
/// `[t_min, t_max]`; `None` when it misses the box there.
pub fn clip_to_box(
    origin: DVec3,
    direction: DVec3,
    min: DVec3,
    max: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (t_min, t_max);
    for axis in 0..3 {
        let (o, d) = (origin[axis], direction[axis]);
        if d == 0.0 {
            if o < min[axis] || o > max[axis] {
                return None;
            }
            continue;
        }
        let (a, b) = ((min[axis] - o) / d, (max[axis] - o) / d);
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        t0 = t0.max(near);
        t1 = t1.min(far);
    }
    (t0 <= t1).then_some((t0, t1))
}

impl ExactSurface<'_> {
    /// Whether (x, z) is over the water (inside the membrane's extent, borders included, widened
    /// by `slack_m`).
    pub fn covers(&self, x: f64, z: f64, slack_m: f64) -> bool {
        let e = &self.extent;
        x >= e.min_x - slack_m
            && x <= e.max_x + slack_m
            && z >= e.min_z - slack_m
            && z <= e.max_z + slack_m
    }

    /// Whether `point` is in the water: over the extent and under the exact surface, each test
    /// widened by `slack_m` (points on the surface or on the extent's border count as in).
    pub fn contains(&self, point: DVec3, slack_m: f64) -> bool {
        if point.y > self.height_range_m.1 + slack_m || !self.covers(point.x, point.z, slack_m) {
            return false;
        }
        // Under the lowest trough: in the water wherever the field is (pool floors and walls).
        point.y <= self.height_range_m.0 + slack_m
            || point.y <= self.field.height(point.x, point.z) + slack_m
    }

    /// The first point with `t` in `[t_min, t_max]` where the ray passes from above the surface to
    /// under it, over the extent. A ray that starts under the surface (it came in through the
    /// extent's side) must first come up above it; that is not a crossing seen by the eye.
    pub fn first_crossing(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        steps: &mut RootSteps,
    ) -> Option<SurfaceHit> {
        let e = &self.extent;
        let (low, high) = self.height_range_m;
        let (t0, t1) = clip_to_box(
            origin,
            direction,
            DVec3::new(e.min_x, low, e.min_z),
            DVec3::new(e.max_x, high, e.max_z),
            t_min,
            t_max,
        )?;
        let horizontal = direction.x.hypot(direction.z);
        let lipschitz = direction.y.abs() + self.slope_bound * horizontal;
        let curvature = self.curvature_bound * horizontal * horizontal;
        let clearance = |t: f64, steps: &mut RootSteps| {
            steps.evaluations += 1;
            let p = origin + direction * t;
            let (h, (gx, gz)) = self.field.height_and_gradient(p.x, p.z);
            let slope = direction.y - gx * direction.x - gz * direction.z;
            (p.y - h, slope, (gx, gz))
        };
        let mut t = t0;
        let (mut f, mut df, mut gradient) = clearance(t, steps);
        // Below the surface at entry: march (by |f| / L, which cannot skip a crossing) until above.
        while f < 0.0 {
            let next = t + (-f / lipschitz).max(1e-9);
            if next > t1 {
                return None;
            }
            t = next;
            (f, df, gradient) = clearance(t, steps);
        }
        for _ in 0..MAX_STEPS {
            if f <= SURFACE_HIT_TOLERANCE_M {
                return Some(self.hit_at(origin, direction, t, gradient));
            }
            let linear = f / lipschitz;
            // First zero of f + df s - K s^2 / 2 (the rationalised root, stable as K -> 0).
            let root = (df * df + 2.0 * curvature * f).sqrt();
            let parabola = if root - df > 0.0 {
                2.0 * f / (root - df)
            } else {
                f64::INFINITY
            };
            let step = linear.max(parabola);
            let next = t + step;
            if next > t1 {
                return None;
            }
            let (f_next, df_next, gradient_next) = clearance(next, steps);
            if f_next < 0.0 {
                return Some(self.bisect(origin, direction, t, next, steps));
            }
            (t, f, df, gradient) = (next, f_next, df_next, gradient_next);
        }
        (f <= GRAZING_TOUCH_M).then(|| self.hit_at(origin, direction, t, gradient))
    }

    /// Refines a bracket `f(above) > 0 > f(below)` by bisection to the surface tolerance.
    fn bisect(
        &self,
        origin: DVec3,
        direction: DVec3,
        mut above: f64,
        mut below: f64,
        steps: &mut RootSteps,
    ) -> SurfaceHit {
        let mut gradient = (0.0, 0.0);
        for _ in 0..80 {
            let mid = 0.5 * (above + below);
            if mid <= above || mid >= below {
                break;
            }
            steps.evaluations += 1;
            let p = origin + direction * mid;
            let (h, g) = self.field.height_and_gradient(p.x, p.z);
            gradient = g;
            let f = p.y - h;
            if f.abs() <= SURFACE_HIT_TOLERANCE_M {
                return self.hit_at(origin, direction, mid, g);
            }
            if f > 0.0 {
                above = mid;
            } else {
                below = mid;
            }
        }
        self.hit_at(origin, direction, above, gradient)
    }

    fn hit_at(&self, origin: DVec3, direction: DVec3, t: f64, gradient: (f64, f64)) -> SurfaceHit {
        let (gx, gz) = gradient;
        SurfaceHit {
            t,
            position: origin + direction * t,
            normal: DVec3::new(-gx, 1.0, -gz).normalize(),
        }
    }
}

/// The membrane as triangles with interpolated vertex normals.
pub struct MembraneSurface<'a> {
    pub membrane: &'a Membrane,
    bvh: Bvh,
}

impl<'a> MembraneSurface<'a> {
    pub fn new(membrane: &'a Membrane) -> Self {
        let triangles: Vec<[Vec3; 3]> = membrane
            .triangles
            .iter()
            .map(|t| t.map(|i| membrane.positions[i as usize]))
            .collect();
        MembraneSurface {
            membrane,
            bvh: Bvh::build(&triangles),
        }
    }

    /// The nearest facet the ray meets in `(t_min, t_max)` (either side), with the normal
    /// interpolated from its vertices' as the rasteriser interpolates it.
    pub fn first_hit(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<SurfaceHit> {
        let ray = Ray::new(origin, direction);
        let hit = self.bvh.closest_hit(&ray, t_min, t_max, |_| true)?;
        let [a, b, c] = self.membrane.triangles[hit.triangle as usize];
        let w = 1.0 - hit.u - hit.v;
        let n = &self.membrane.normals;
        let normal = n[a as usize] * w + n[b as usize] * hit.u + n[c as usize] * hit.v;
        Some(SurfaceHit {
            t: hit.t as f64,
            position: ray.at(hit.t).as_dvec3(),
            normal: normal.normalize().as_dvec3(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::water::FnHeightField;

    /// The membrane extents these tests use: squares of 8 x 8 cells.
    fn extent(half_m: f64) -> MembraneGrid {
        crate::refraction::search::test_support::square_grid(half_m, 8)
    }

    /// A single crest `h = a exp(-x^2 / w^2)` along z (a Gaussian ridge), with exact bounds.
    fn ridge(a: f64, w: f64) -> (FnHeightField, f64, f64) {
        let field = FnHeightField::new(move |x, _| a * (-(x * x) / (w * w)).exp())
            .with_gradient(move |x, _| (-2.0 * a * x / (w * w) * (-(x * x) / (w * w)).exp(), 0.0));
        // max |h'| = a sqrt(2/e) / w at x = w / sqrt(2); max |h''| = 2 a / w^2 at x = 0.
        (
            field,
            a * (2.0f64 / std::f64::consts::E).sqrt() / w,
            2.0 * a / (w * w),
        )
    }

    fn surface<'a>(
        field: &'a FnHeightField,
        slope: f64,
        curvature: f64,
        a: f64,
    ) -> ExactSurface<'a> {
        ExactSurface {
            field,
            extent: extent(10.0),
            height_range_m: (0.0, a),
            slope_bound: slope,
            curvature_bound: curvature,
        }
    }

    #[test]
    fn a_ray_grazing_a_crest_hits_it_and_one_passing_over_does_not_stop_early() {
        let a = 0.1;
        let w = 0.3;
        let (field, slope, curvature) = ridge(a, w);
        let water = surface(&field, slope, curvature, a);
        let mut steps = RootSteps::default();
        // Horizontal rays along x at height y, from x = -5: the crest (x = 0) is the only place
        // where the ridge reaches y when y is close to a; beyond it the surface falls away and
        // the flat water (h ~ 0) lies below the ray, so the ray can only meet the crest.
        let direction = DVec3::X;
        // 0.1 mm under the crest top: must hit, on the near flank of the crest.
        let origin = DVec3::new(-5.0, a - 1e-4, 0.3);
        let hit = water
            .first_crossing(origin, direction, 0.0, 20.0, &mut steps)
            .expect("a ray 0.1 mm under the crest top must meet it");
        // Where the near flank reaches y: x = -w sqrt(ln(a / y)).
        let expected_x = -w * (a / (a - 1e-4)).ln().sqrt();
        assert!(
            (hit.position.x - expected_x).abs() < 1e-6,
            "{hit:?} vs {expected_x}"
        );
        assert!((hit.position.y - field.height(hit.position.x, 0.3)).abs() < 1e-6);
        // 0.1 mm over the crest: no hit, and not stopped early.
        let over = DVec3::new(-5.0, a + 1e-4, 0.3);
        assert_eq!(
            water.first_crossing(over, direction, 0.0, 20.0, &mut steps),
            None
        );
        // A descending ray that passes just over the crest, then meets the flat water behind it:
        // the hit is behind the crest, not on it.
        let descending = DVec3::new(1.0, -0.02, 0.0).normalize();
        let start = DVec3::new(-5.0, a + 1e-4 + 0.1, 0.0);
        let hit = water
            .first_crossing(start, descending, 0.0, 100.0, &mut steps)
            .expect("meets the water behind the crest");
        assert!(hit.position.x > 0.5, "stopped at the crest: {hit:?}");
        assert!((hit.position.y - field.height(hit.position.x, 0.0)).abs() < 1e-6);
    }

    #[test]
    fn a_flat_surface_is_met_where_the_plane_is() {
        let field = FnHeightField::new(|_, _| -0.25).with_gradient(|_, _| (0.0, 0.0));
        let water = ExactSurface {
            field: &field,
            extent: extent(2.0),
            height_range_m: (-0.25, -0.25),
            slope_bound: 0.0,
            curvature_bound: 0.0,
        };
        let mut steps = RootSteps::default();
        let origin = DVec3::new(0.0, 1.0, -1.0);
        let direction = DVec3::new(0.3, -1.0, 0.4);
        let hit = water
            .first_crossing(origin, direction, 0.0, 100.0, &mut steps)
            .unwrap();
        assert!((hit.t - 1.25).abs() < 1e-12);
        assert_eq!(hit.normal, DVec3::Y);
        // Outside the extent there is no water: a ray meeting the plane at x = 3 misses.
        let far = DVec3::new(3.0 / 1.25, -1.0, 0.0);
        assert_eq!(
            water.first_crossing(origin, far, 0.0, 100.0, &mut steps),
            None
        );
    }

    #[test]
    fn random_rays_on_waves_agree_with_dense_sampling() {
        // Two crossing waves; the first crossing found must have no earlier sign change on a
        // dense sampling of the ray (no crest skipped), and lie on the surface.
        let field = FnHeightField::new(|x, z| {
            0.05 * (3.0 * x + 1.0).cos() + 0.02 * (7.0 * z - 2.0 * x).cos()
        });
        let slope = 0.05 * 3.0 + 0.02 * (49.0f64 + 4.0).sqrt();
        let curvature = 0.05 * 9.0 + 0.02 * 53.0;
        let water = ExactSurface {
            field: &field,
            extent: extent(3.0),
            height_range_m: (-0.07, 0.07),
            slope_bound: slope,
            curvature_bound: curvature,
        };
        let mut steps = RootSteps::default();
        let mut hits = 0;
        for i in 0..400 {
            let a = i as f64 * 0.7;
            let origin = DVec3::new(
                -3.5 + (a * 1.3).sin(),
                0.3 + 0.2 * (a * 0.9).cos(),
                -3.5 + (a * 0.7).cos(),
            );
            let direction = DVec3::new(
                1.0 + 0.5 * a.sin(),
                -0.05 - 0.2 * (a * 1.7).cos().abs(),
                1.0,
            )
            .normalize();
            let found = water.first_crossing(origin, direction, 0.0, 20.0, &mut steps);
            let limit = found.map_or(20.0, |h| h.t);
            let samples = 20_000;
            // A crossing seen by the eye: from over the water to under it, both over the extent
            // (a ray coming in through the extent's side under the surface is not one).
            let mut crossed_before = None;
            let mut was_above = false;
            for k in 0..samples {
                let t = limit * k as f64 / samples as f64;
                let p = origin + direction * t;
                let covered = water.covers(p.x, p.z, 0.0);
                let clearance = p.y - field.height(p.x, p.z);
                if covered && was_above && clearance < -1e-9 {
                    crossed_before = Some(t);
                    break;
                }
                was_above = covered && clearance > 0.0;
            }
            assert_eq!(
                crossed_before, None,
                "ray {i}: a crossing before {limit} was skipped"
            );
            if let Some(hit) = found {
                hits += 1;
                assert!(
                    (hit.position.y - field.height(hit.position.x, hit.position.z)).abs() < 1e-6
                );
            }
        }
        assert!(hits > 100, "only {hits} rays met the water");
    }
}
