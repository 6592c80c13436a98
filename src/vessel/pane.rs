//! A parallel glass pane (Mukai et al. §2.1-2.2): the two-refraction displacement of a point
//! behind it, and the direct view around it.
//!
//! ## Derivation
//! Both faces share the normal, so Snell's law keeps the whole path in the plane through the eye
//! spanned by the normal and the point (the paper's rotation of the system, §2.2, is this choice
//! of frame). In that plane let `z` run from the eye away from the pane along the normal and `x`
//! across it, toward the point. The path crosses layers of depth `h_k` and index `n_k`: the eye's
//! medium down to the near face (`h_0 = a`), the glass (`h_1 = W`, the thickness), the medium
//! behind down to the point. With `s = sin(theta)` in the eye's medium, Snell gives
//! `n_0 s = n_k sin(theta_k)`, so with `mu_k = n_k / n_0`
//!
//! ```text
//! tan(theta_k) = s / sqrt(mu_k^2 - s^2)
//! x(s) = sum_k h_k s / sqrt(mu_k^2 - s^2) = x_V          (the paper's eq. 5, for any stack)
//! ```
//!
//! Each term increases and is convex on `0 <= s < min(1, min_k mu_k)`, from 0 to infinity (the
//! eye's layer alone goes to infinity at grazing; a less dense layer at its critical angle), so
//! exactly one `s` solves it: the pane has at most one refracted image of a point.
//!
//! **Solver**: Newton on `s` with `x'(s) = sum_k h_k mu_k^2 / (mu_k^2 - s^2)^(3/2)`, safeguarded by
//! a bracket (a step that leaves it bisects), from the straight line's sine. Tolerance: `|x(s) -
//! x_V| <= 1e-12 (x_V + z_V)`, at most [`MAX_ITERATIONS`] steps; typically 3 to 5.
//!
//! The path is then exact: the crossings are `E + a (n + tan(theta_0) u)` and the next face `W`
//! further on along `n + tan(theta_1) u`. A path counts only when both crossings lie on the
//! pane's rectangle (the edge faces absorb); the direct view counts when the straight segment
//! misses the pane's box.

use glam::DVec3;

use super::{image_from_path, position_tolerance_m, Image, Medium, AIR_INDEX};

/// Most Newton steps for the incidence sine (it needs 3-5; bisection fallback bounds the worst case).
pub const MAX_ITERATIONS: u32 = 100;

/// A parallel glass pane: the slab `|dot(P - center, normal)| <= thickness / 2` clipped to the
/// rectangle `|dot(P - center, u)| <= half_size[0]`, `|dot(P - center, w)| <= half_size[1]`,
/// `w = normal x u`. The `normal` side is outside (air); the other side is the vessel's inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pane {
    pub center: DVec3,
    /// Unit normal pointing outside (to the air).
    pub normal: DVec3,
    /// Unit axis in the pane's plane (perpendicular to `normal`) along which `half_size[0]` runs.
    pub u_axis: DVec3,
    pub half_size_m: [f64; 2],
    pub thickness_m: f64,
    pub glass_index: f64,
    /// What is on the side opposite the normal.
    pub inside: Medium,
}

impl Pane {
    pub fn w_axis(&self) -> DVec3 {
        self.normal.cross(self.u_axis)
    }

    /// The point in the pane's frame (u, w, along the normal).
    fn local(&self, point: DVec3) -> DVec3 {
        let d = point - self.center;
        DVec3::new(d.dot(self.u_axis), d.dot(self.w_axis()), d.dot(self.normal))
    }

    /// Whether a point on one of the faces (within round-off) lies on the rectangle.
    fn on_rectangle(&self, point: DVec3) -> bool {
        let local = self.local(point);
        local.x.abs() <= self.half_size_m[0] && local.y.abs() <= self.half_size_m[1]
    }

    /// Whether the segment `a -> b` meets the pane's box (slab test in the pane's frame).
    pub fn segment_meets_glass(&self, a: DVec3, b: DVec3) -> bool {
        let (la, lb) = (self.local(a), self.local(b));
        let half = DVec3::new(
            self.half_size_m[0],
            self.half_size_m[1],
            0.5 * self.thickness_m,
        );
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for axis in 0..3 {
            let (p, d) = (la[axis], lb[axis] - la[axis]);
            if d.abs() < 1e-300 {
                if p.abs() > half[axis] {
                    return false;
                }
                continue;
            }
            let (mut ta, mut tb) = ((-half[axis] - p) / d, (half[axis] - p) / d);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
        true
    }

    /// Every image of `point` seen from `eye`: the direct view if the segment misses the pane, and
    /// the path through it (one refraction for a point in the glass, two behind it) if both its
    /// crossings lie on the rectangle. An eye in the glass sees nothing here.
    pub fn images(&self, eye: DVec3, point: DVec3, out: &mut Vec<Image>) {
        let half_thickness = 0.5 * self.thickness_m;
        let eye_height = (eye - self.center).dot(self.normal);
        if eye_height.abs() <= half_thickness {
            return;
        }
        let side = eye_height.signum();
        let (n_eye, n_far) = if side > 0.0 {
            (AIR_INDEX, self.inside.index())
        } else {
            (self.inside.index(), AIR_INDEX)
        };
        if !self.segment_meets_glass(eye, point) {
            out.push(image_from_path(eye, &[], point, &[n_eye], true, 0));
        }
        // Depths from the eye along `away`, the normal pointing away from the eye.
        let away = -side * self.normal;
        let depth_point = (point - eye).dot(away);
        let depth_near_face = side * eye_height - half_thickness;
        let depth_far_face = depth_near_face + self.thickness_m;
        if depth_point <= depth_near_face {
            return;
        }
        let beyond = depth_point > depth_far_face;
        let mu_glass = self.glass_index / n_eye;
        let mu_far = n_far / n_eye;
        let layers_beyond = [
            (depth_near_face, 1.0),
            (self.thickness_m, mu_glass),
            (depth_point - depth_far_face, mu_far),
        ];
        let layers_in_glass = [
            (depth_near_face, 1.0),
            (depth_point - depth_near_face, mu_glass),
        ];
        let layers: &[(f64, f64)] = if beyond {
            &layers_beyond
        } else {
            &layers_in_glass
        };
        let across = (point - eye) - depth_point * away;
        let lateral = across.length();
        let u = if lateral > 1e-15 * depth_point {
            across / lateral
        } else {
            self.u_axis
        };
        let solve = solve_incidence_sine(layers, lateral, lateral + depth_point);
        let near = eye + depth_near_face * (away + tan_in_layer(solve.sine, 1.0) * u);
        let mut crossings = [near, DVec3::ZERO];
        let indices = [n_eye, self.glass_index, n_far];
        let count = if beyond {
            crossings[1] =
                near + self.thickness_m * (away + tan_in_layer(solve.sine, mu_glass) * u);
            2
        } else {
            1
        };
        let crossings = &crossings[..count];
        if !crossings.iter().all(|&c| self.on_rectangle(c)) {
            return;
        }
        let mut image = image_from_path(
            eye,
            crossings,
            point,
            &indices[..count + 1],
            solve.converged,
            solve.iterations,
        );
        // The path's end, rebuilt from the crossings along the last layer's direction, must meet
        // the point: the check that makes `converged` mean what it says.
        let last = crossings[count - 1];
        let last_mu = layers[layers.len() - 1].1;
        let end = last
            + (depth_point - (last - eye).dot(away))
                * (away + tan_in_layer(solve.sine, last_mu) * u);
        image.converged &= (end - point).length() <= position_tolerance_m(eye, point);
        out.push(image);
    }
}

/// `tan(theta_k)` in a layer of relative index `mu` for the eye-medium sine `s`.
fn tan_in_layer(sine: f64, mu: f64) -> f64 {
    sine / (mu * mu - sine * sine).sqrt()
}

/// The incidence sine that solves `x(s) = lateral`, how many steps it took, and whether it met
/// the tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SineSolve {
    pub sine: f64,
    pub iterations: u32,
    pub converged: bool,
}

/// Safeguarded Newton on `x(s) = sum_k h_k s / sqrt(mu_k^2 - s^2) = lateral` (see the module's doc);
/// `scale_m` sets the tolerance `1e-12 scale_m`.
pub fn solve_incidence_sine(layers: &[(f64, f64)], lateral: f64, scale_m: f64) -> SineSolve {
    let sine_max = layers.iter().fold(1.0f64, |m, &(_, mu)| m.min(mu));
    let tolerance = 1e-12 * scale_m.max(1e-12);
    if lateral <= tolerance {
        return SineSolve {
            sine: 0.0,
            iterations: 0,
            converged: true,
        };
    }
    let depth: f64 = layers.iter().map(|&(h, _)| h).sum();
    let (mut lo, mut hi) = (0.0f64, sine_max);
    let mut sine = (lateral / lateral.hypot(depth)).min(sine_max * (1.0 - 1e-12));
    for iteration in 1..=MAX_ITERATIONS {
        let (mut x, mut slope) = (0.0, 0.0);
        for &(h, mu) in layers {
            let q = mu * mu - sine * sine;
            let root = q.sqrt();
            x += h * sine / root;
            slope += h * mu * mu / (q * root);
        }
        let residual = x - lateral;
        if residual.abs() <= tolerance {
            return SineSolve {
                sine,
                iterations: iteration,
                converged: true,
            };
        }
        if residual > 0.0 {
            hi = sine;
        } else {
            lo = sine;
        }
        let newton = sine - residual / slope;
        sine = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo <= 1e-16 {
            break;
        }
    }
    SineSolve {
        sine,
        iterations: MAX_ITERATIONS,
        converged: false,
    }
}
