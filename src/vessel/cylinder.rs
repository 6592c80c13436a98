//! A cylindrical glass (Mukai et al. §2.3): every path from the eye to a point through the wall,
//! with water or air inside, in 3-D (skew rays included), and the direct view over or past it.
//!
//! ## Derivation
//! Frame: the axis `A` through the base, transverse coordinates `(u, w)` across it, `y` along it.
//! Media by radius: outside (air, `n_0`), glass (`n_1`) between the inner radius `r_1` and the
//! outer `r_2`, inside (`n_2`: air or water) within `r_1`. Every wall normal is radial, so at a
//! crossing the tangential part of `n D` is conserved along two tangents:
//!
//! 1. along the axis: `beta = n_k (D_k . A)` is the same in every medium (the skew invariant);
//! 2. across it: write `D_k = (beta / n_k) A + sqrt(1 - (beta / n_k)^2) q_k` with `q_k` the unit
//!    transverse direction. The tangential transverse part of `n_k D_k` is `m_k (q_k . t)` with
//!    the *effective index* `m_k = sqrt(n_k^2 - beta^2)`: the path's projection on the cross-section
//!    obeys Snell's law in 2-D with the indices `m_k` (transmission exists exactly when it exists
//!    there, so total internal reflection is the 2-D one).
//!
//! In 2-D the walls are concentric circles, so the angular momentum `J = m_k b_k` is conserved,
//! `b_k` the signed distance from the axis to the segment's line (Bouguer's invariant; it is (2) at
//! a crossing point, where `b = r (r^ x q)`). A segment is then known in closed form: with `s`
//! the signed distance along it from its closest approach to the axis, a point is at radius
//! `sqrt(b^2 + s^2)` and polar angle `phi = psi + atan2(-b, s)` (`psi` the direction's angle), so
//! between `s_a` and `s_b` it sweeps `atan2(-b, s_b) - atan2(-b, s_a)`; its transverse length is
//! `s_b - s_a` and its axial advance `(beta / m_k)(s_b - s_a)`. Walls are met at
//! `s = -sqrt(r^2 - b^2)` going in and `+sqrt(r^2 - b^2)` going out. From an eye outside, the
//! path for a given `J` (`|J| < m_0 r_2`, else it misses) is fixed:
//!
//! - `|J| < m_1 r_1`: outer wall in, inner wall in (if `|J| < m_2 r_1`; else total internal
//!   reflection ends it, water being less dense than glass), across the inside, inner wall out,
//!   outer wall out: four refractions;
//! - otherwise through the glass only, in and out of the outer wall: two refractions ("the verge").
//!
//! A point at radius `rho_V` in one region is passed where a segment in that region has
//! `s = +-sqrt(rho_V^2 - b^2)`: the image's *label* is (crossings before it, sign). Inside: 2
//! refractions, either sign; in the glass: 1 (either sign) or 3; outside, behind: 2 or 4. An image
//! is a root of two equations in `(J, beta)`:
//!
//! ```text
//! phi_E + sum (swept angles) = phi_V  (mod 2 pi)          (depends on beta through m_k only)
//! beta * sum_k l_k / m_k     = y_V - y_E                   (l_k: transverse lengths)
//! ```
//!
//! With water inside the paper's four-refraction chain (its eqs. 6-8 per wall, air inside) just
//! takes `n_2 = 1.333`: the derivation above never assumed the inside's index.
//!
//! **Solver.** `beta` starts at the straight line's `n_0 (V - E) . A / |V - E|`. At that `beta`
//! every root in `J` of every label is bracketed by a scan ([`SCAN_SAMPLES`] samples on each piece
//! of the `J` range that can reach the point's radius, cut where a label appears or the path
//! changes: `+-m_1 r_1`, `+-m_2 r_1`, `+-m rho_V`) and refined by the Illinois method to `|phi
//! error| <= 1e-13`. Each root then takes Newton steps on `(J, beta)` together (Jacobian by
//! forward differences, steps halved until the residual drops) until both equations hold to
//! 1e-4 of [`super::position_tolerance_m`]; where Newton stalls, the alternating fixed point
//! (Newton on `beta` with the lengths held, then on `J`, until `beta` moves less than 1e-14)
//! finishes. The image is converged when the end of its rebuilt 3-D path is within that
//! tolerance of the point. At most [`MAX_ROUNDS`] steps of each (none when the eye and the point
//! are level: `beta = 0` exactly). Two roots closer than one scan step in `J` (a
//! caustic) can be missed: the brute-force count
//! in the tests measures how often at the default sampling. A path with a crossing above the
//! wall's height or under its base is no image (the rims absorb).

use glam::{DVec2, DVec3};

use super::{image_from_path, position_tolerance_m, Image, Medium, AIR_INDEX, MAX_CROSSINGS};

/// Samples per piece of the `J` range when bracketing the roots.
pub const SCAN_SAMPLES: usize = 24;
/// Most Newton steps in `(J, beta)` for one image.
pub const MAX_ROUNDS: u32 = 40;
/// Most Illinois steps when refining one bracketed root.
const MAX_BRACKET_STEPS: u32 = 100;
/// Polar-angle tolerance of a root, radians.
const ANGLE_TOLERANCE: f64 = 1e-13;

/// A cylindrical glass: the wall `inner_radius <= distance from the axis <= outer_radius`,
/// `0 <= dot(P - base, axis) <= height`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// The centre of the base.
    pub base: DVec3,
    /// Unit axis from the base up.
    pub axis: DVec3,
    pub inner_radius_m: f64,
    pub outer_radius_m: f64,
    pub height_m: f64,
    pub glass_index: f64,
    pub inside: Medium,
}

/// Where a point is, by radius.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Region {
    Outside = 0,
    Glass = 1,
    Inside = 2,
}

/// One straight piece of a 2-D path (see the module's doc).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Segment {
    region: usize,
    /// Signed distance from the axis to the line, `J / m_region`.
    b: f64,
    s_start: f64,
    /// +inf for the last piece outside.
    s_end: f64,
    /// Polar angle at `s_start`.
    phi_start: f64,
}

impl Segment {
    /// The polar angle at `s`: `phi_start` plus the angle from `(s_start, -b)` to `(s, -b)`, one
    /// `atan2` of their cross and dot products (the angle a line sweeps is under pi).
    fn phi_at(&self, s: f64) -> f64 {
        let b = self.b;
        self.phi_start + (b * (s - self.s_start)).atan2(self.s_start * s + b * b)
    }
}

/// The 2-D path for one `J`: up to five pieces (out, glass, in, glass, out).
#[derive(Clone, Copy, Debug, Default)]
struct Walk {
    segments: [Segment; 5],
    count: usize,
}

/// Where a label's path passes the point's radius.
#[derive(Clone, Copy, Debug)]
struct Passage {
    residual: f64,
    walk: Walk,
    s: f64,
}

/// An image's label: (crossings before the point, which side of the closest approach).
type Label = (usize, f64);

impl Cylinder {
    fn indices(&self) -> [f64; 3] {
        [AIR_INDEX, self.glass_index, self.inside.index()]
    }

    fn frame(&self) -> (DVec3, DVec3) {
        let u = self.axis.any_orthonormal_vector();
        (u, self.axis.cross(u))
    }

    /// Transverse coordinates and height of a point.
    fn local(&self, point: DVec3) -> (DVec2, f64) {
        let (u, w) = self.frame();
        let d = point - self.base;
        (DVec2::new(d.dot(u), d.dot(w)), d.dot(self.axis))
    }

    pub fn region_of(&self, point: DVec3) -> Region {
        self.region_of_radius(self.local(point).0.length())
    }

    /// The parameter interval of `a + t (b - a)` within `[0, 1]` where the distance from the axis is
    /// below `radius` and the height within the wall's.
    fn within(&self, a: DVec3, b: DVec3, radius: f64) -> Option<(f64, f64)> {
        let ((pa, ya), (pb, yb)) = (self.local(a), self.local(b));
        let d = pb - pa;
        let (qa, qb, qc) = (d.dot(d), pa.dot(d), pa.dot(pa) - radius * radius);
        let (mut t0, mut t1) = if qa < 1e-300 {
            if qc > 0.0 {
                return None;
            }
            (0.0f64, 1.0f64)
        } else {
            let disc = qb * qb - qa * qc;
            if disc < 0.0 {
                return None;
            }
            let root = disc.sqrt();
            ((-qb - root) / qa, (-qb + root) / qa)
        };
        let dy = yb - ya;
        if dy.abs() < 1e-300 {
            if ya < 0.0 || ya > self.height_m {
                return None;
            }
        } else {
            let (ha, hb) = ((0.0 - ya) / dy, (self.height_m - ya) / dy);
            t0 = t0.max(ha.min(hb));
            t1 = t1.min(ha.max(hb));
        }
        let (t0, t1) = (t0.max(0.0), t1.min(1.0));
        (t0 < t1).then_some((t0, t1))
    }

    /// Whether the segment `a -> b` passes through the glass wall.
    pub fn segment_meets_glass(&self, a: DVec3, b: DVec3) -> bool {
        let Some((c0, c1)) = self.within(a, b, self.outer_radius_m) else {
            return false;
        };
        match self.within(a, b, self.inner_radius_m) {
            None => true,
            Some((i0, i1)) => c0 < i0 || c1 > i1,
        }
    }

    /// Every image of `point` seen from `eye` (see the module's doc), with the default scan.
    pub fn images(&self, eye: DVec3, point: DVec3, out: &mut Vec<Image>) {
        self.images_with_samples(eye, point, SCAN_SAMPLES, out);
    }

    /// [`Self::images`] with `samples` scan samples per piece of the `J` range.
    pub fn images_with_samples(
        &self,
        eye: DVec3,
        point: DVec3,
        samples: usize,
        out: &mut Vec<Image>,
    ) {
        let ((pe, ye), (pv, yv)) = (self.local(eye), self.local(point));
        let rho_e = pe.length();
        if rho_e <= self.outer_radius_m {
            return;
        }
        let region = self.region_of(point);
        // The direct view: the straight segment misses the glass (and, with water inside, does
        // not pass through the water, whose surface is the water stage's).
        let through_water =
            self.inside == Medium::Water && self.within(eye, point, self.inner_radius_m).is_some();
        if !(self.segment_meets_glass(eye, point) || through_water) {
            out.push(image_from_path(eye, &[], point, &[AIR_INDEX], true, 0));
        }
        let problem = Problem {
            cylinder: self,
            indices: self.indices(),
            rho_e,
            phi_e: pe.y.atan2(pe.x),
            rho_v: pv.length(),
            phi_v: pv.y.atan2(pv.x),
            rise: yv - ye,
        };
        let labels: &[Label] = match region {
            Region::Outside => &[(2, 1.0), (4, 1.0)],
            Region::Glass => &[(1, -1.0), (1, 1.0), (3, 1.0)],
            Region::Inside => &[(2, -1.0), (2, 1.0)],
        };
        let beta_start = AIR_INDEX * (yv - ye) / (point - eye).length().max(1e-300);
        let mut roots = Vec::new();
        problem.bracket_roots(labels, beta_start, samples.max(2), &mut roots);
        for (label, j) in roots {
            if let Some(image) = problem.solve(label, j, beta_start, eye, point, ye) {
                out.push(image);
            }
        }
    }
}

/// One eye and point against one cylinder.
struct Problem<'a> {
    cylinder: &'a Cylinder,
    indices: [f64; 3],
    rho_e: f64,
    phi_e: f64,
    rho_v: f64,
    phi_v: f64,
    rise: f64,
}

fn wrap_angle(angle: f64) -> f64 {
    angle - std::f64::consts::TAU * (angle / std::f64::consts::TAU).round()
}

impl Problem<'_> {
    fn effective(&self, beta: f64) -> [f64; 3] {
        self.indices.map(|n| (n * n - beta * beta).sqrt())
    }

    /// The 2-D path for angular momentum `j` (see the module's doc); None when it misses the glass.
    fn walk(&self, m: &[f64; 3], j: f64) -> Option<Walk> {
        let (r1, r2) = (self.cylinder.inner_radius_m, self.cylinder.outer_radius_m);
        let b0 = j / m[0];
        if b0.abs() >= r2 {
            return None;
        }
        let inward = |r: f64, b: f64| -(r * r - b * b).sqrt();
        let mut walk = Walk::default();
        let push = |walk: &mut Walk, region: usize, b: f64, s_start: f64, s_end: f64| {
            let phi_start = if walk.count == 0 {
                self.phi_e
            } else {
                let previous = walk.segments[walk.count - 1];
                previous.phi_at(previous.s_end)
            };
            walk.segments[walk.count] = Segment {
                region,
                b,
                s_start,
                s_end,
                phi_start,
            };
            walk.count += 1;
        };
        push(&mut walk, 0, b0, inward(self.rho_e, b0), inward(r2, b0));
        let bg = j / m[1];
        if bg.abs() < r1 {
            push(&mut walk, 1, bg, inward(r2, bg), inward(r1, bg));
            let bi = j / m[2];
            if bi.abs() >= r1 {
                return Some(walk); // total internal reflection at the inner wall ends the path
            }
            push(&mut walk, 2, bi, inward(r1, bi), -inward(r1, bi));
            push(&mut walk, 1, bg, -inward(r1, bg), -inward(r2, bg));
        } else {
            push(&mut walk, 1, bg, inward(r2, bg), -inward(r2, bg));
        }
        push(&mut walk, 0, b0, -inward(r2, b0), f64::INFINITY);
        Some(walk)
    }

    /// The polar-angle error where `label`'s path passes the point's radius, if it does.
    fn passage(&self, walk: &Walk, label: Label, region: usize) -> Option<Passage> {
        let (k, sign) = label;
        if k >= walk.count {
            return None;
        }
        let segment = walk.segments[k];
        if segment.region != region || self.rho_v < segment.b.abs() {
            return None;
        }
        let s = sign * (self.rho_v * self.rho_v - segment.b * segment.b).sqrt();
        if s < segment.s_start || s > segment.s_end {
            return None;
        }
        Some(Passage {
            residual: wrap_angle(segment.phi_at(s) - self.phi_v),
            walk: *walk,
            s,
        })
    }

    fn region(&self) -> usize {
        self.cylinder.region_of_radius(self.rho_v) as usize
    }

    fn residual(&self, label: Label, j: f64, beta: f64) -> Option<Passage> {
        let m = self.effective(beta);
        let walk = self.walk(&m, j)?;
        self.passage(&walk, label, self.region())
    }

    /// The `J` range's pieces: between the points where a label appears or the path changes, up
    /// to the largest `|J|` at which a path can pass the point's radius in its region.
    fn pieces(&self, beta: f64) -> Vec<f64> {
        let m = self.effective(beta);
        let (r1, r2) = (self.cylinder.inner_radius_m, self.cylinder.outer_radius_m);
        let j_max = m[0] * r2;
        let region = self.region();
        let top = match region {
            // Into the inside (|b_glass| < r1, no total reflection) and down to rho_V there.
            2 => j_max.min(m[1] * r1).min(m[2] * r1).min(m[2] * self.rho_v),
            // Down to rho_V in the glass.
            1 => j_max.min(m[1] * self.rho_v),
            _ => j_max,
        };
        let mut cuts = vec![-top, 0.0, top];
        for c in [m[1] * r1, m[2] * r1, m[region] * self.rho_v] {
            if c < top {
                cuts.extend([-c, c]);
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts
    }

    /// Every root in `J` of every label at `beta`, bracketed by the scan and refined.
    fn bracket_roots(
        &self,
        labels: &[Label],
        beta: f64,
        samples: usize,
        roots: &mut Vec<(Label, f64)>,
    ) {
        let m = self.effective(beta);
        let region = self.region();
        let cuts = self.pieces(beta);
        const INSET: f64 = 1e-9;
        for piece in cuts.windows(2) {
            let (a, b) = (piece[0], piece[1]);
            let mut previous: [Option<(f64, f64)>; 3] = [None; 3];
            for i in 0..samples {
                let t = INSET + (1.0 - 2.0 * INSET) * i as f64 / (samples - 1) as f64;
                let j = a + (b - a) * t;
                let walk = self.walk(&m, j);
                for (l, &label) in labels.iter().enumerate() {
                    let now = walk
                        .as_ref()
                        .and_then(|w| self.passage(w, label, region))
                        .map(|p| (j, p.residual));
                    if let (Some((j0, r0)), Some((j1, r1))) = (previous[l], now) {
                        if r0 == 0.0 {
                            roots.push((label, j0));
                        } else if r0 * r1 < 0.0 && (r0 - r1).abs() < std::f64::consts::PI {
                            if let Some(root) = self.refine(label, beta, (j0, r0), (j1, r1)) {
                                roots.push((label, root));
                            }
                        }
                    }
                    previous[l] = now;
                }
            }
            // A root exactly on the last sample.
            for (l, &label) in labels.iter().enumerate() {
                if let Some((j, r)) = previous[l] {
                    if r == 0.0 {
                        roots.push((label, j));
                    }
                }
            }
        }
    }

    /// The Illinois method on a bracket of one label's polar-angle error.
    fn refine(&self, label: Label, beta: f64, a: (f64, f64), b: (f64, f64)) -> Option<f64> {
        let ((mut ja, mut ra), (mut jb, mut rb)) = (a, b);
        for _ in 0..MAX_BRACKET_STEPS {
            let j = (ja * rb - jb * ra) / (rb - ra);
            let r = self.residual(label, j, beta)?.residual;
            if r.abs() <= ANGLE_TOLERANCE || (jb - ja).abs() <= 1e-15 * ja.abs().max(jb.abs()) {
                return Some(j);
            }
            if r * rb < 0.0 {
                (ja, ra) = (jb, rb);
            } else {
                // The end kept twice: halve its weight (Illinois), so the bracket shrinks from both sides.
                ra *= 0.5;
            }
            (jb, rb) = (j, r);
        }
        Some((ja + jb) * 0.5)
    }

    /// Transverse lengths of the pieces up to the passage, and their regions.
    fn lengths(passage: &Passage, k: usize) -> [(f64, usize); 5] {
        let mut out = [(0.0, 0); 5];
        for (i, item) in out.iter_mut().enumerate().take(k + 1) {
            let segment = passage.walk.segments[i];
            let end = if i == k { passage.s } else { segment.s_end };
            *item = (end - segment.s_start, segment.region);
        }
        out
    }

    /// Refines one root in `(J, beta)` and rebuilds its 3-D path; None when the path leaves the
    /// wall's height (the rims absorb) or its label vanishes.
    /// The two equations of an image at `(j, beta)`, both in metres: the polar-angle error times
    /// the point's radius, and the axial rise's error.
    fn equations(&self, label: Label, j: f64, beta: f64) -> Option<([f64; 2], Passage)> {
        let passage = self.residual(label, j, beta)?;
        let m = self.effective(beta);
        let k = label.0;
        let rise: f64 = Self::lengths(&passage, k)[..=k]
            .iter()
            .map(|&(l, region)| beta * l / m[region])
            .sum();
        Some((
            [passage.residual * self.rho_v.max(1e-300), rise - self.rise],
            passage,
        ))
    }

    fn solve(
        &self,
        label: Label,
        j_start: f64,
        beta_start: f64,
        eye: DVec3,
        point: DVec3,
        eye_height: f64,
    ) -> Option<Image> {
        let k = label.0;
        let n = self.indices;
        let beta_max = n.iter().fold(f64::INFINITY, |a, &b| a.min(b)) * (1.0 - 1e-12);
        let (mut j, mut beta) = (j_start, beta_start);
        let tolerance = position_tolerance_m(eye, point);
        let (mut f, mut passage) = self.equations(label, j, beta)?;
        let norm = |f: [f64; 2]| f[0].abs().max(f[1].abs());
        let h_j = 1e-8 * self.cylinder.outer_radius_m;
        const H_BETA: f64 = 1e-8;
        let mut iterations = 0;
        // Newton on both unknowns at once, the Jacobian by forward differences (stepping the
        // other way at the edge of the label's range), each step halved until the equations
        // hold less badly.
        let target = 1e-4 * tolerance;
        while iterations < MAX_ROUNDS && norm(f) > target {
            iterations += 1;
            let column = |dj: f64, db: f64| {
                self.equations(label, j + dj, beta + db)
                    .map(|(g, _)| [(g[0] - f[0]) / (dj + db), (g[1] - f[1]) / (dj + db)])
            };
            let (Some(cj), Some(cb)) = (
                column(h_j, 0.0).or_else(|| column(-h_j, 0.0)),
                column(0.0, H_BETA).or_else(|| column(0.0, -H_BETA)),
            ) else {
                break;
            };
            let det = cj[0] * cb[1] - cb[0] * cj[1];
            if det == 0.0 || !det.is_finite() {
                break;
            }
            let step_j = -(f[0] * cb[1] - cb[0] * f[1]) / det;
            let step_beta = -(cj[0] * f[1] - f[0] * cj[1]) / det;
            let mut t = 1.0;
            let accepted = loop {
                let (jt, bt) = (
                    j + t * step_j,
                    (beta + t * step_beta).clamp(-beta_max, beta_max),
                );
                if let Some((ft, pt)) = self.equations(label, jt, bt) {
                    if norm(ft) < norm(f) {
                        break Some((jt, bt, ft, pt));
                    }
                }
                t *= 0.5;
                if t < 1e-6 {
                    break None;
                }
            };
            let Some((jt, bt, ft, pt)) = accepted else {
                break;
            };
            (j, beta, f, passage) = (jt, bt, ft, pt);
        }
        if norm(f) > target {
            // Newton stalled (a few vertices in 10,000, near the edge of a label's range): the
            // alternating fixed point finishes from where it stopped.
            let (rounds, alternated) = self.alternate(label, j, beta)?;
            iterations += rounds;
            (j, beta) = alternated;
            passage = self.residual(label, j, beta)?;
        }
        let (crossings, end) = self.rebuild(&passage, k, beta, eye_height);
        let height = self.cylinder.height_m;
        let crossings = &crossings[..k];
        if crossings.iter().any(|&c| {
            let y = (c - self.cylinder.base).dot(self.cylinder.axis);
            !(0.0..=height).contains(&y)
        }) {
            return None;
        }
        let mut indices = [0.0; MAX_CROSSINGS + 1];
        for (i, index) in indices.iter_mut().enumerate().take(k + 1) {
            *index = n[passage.walk.segments[i].region];
        }
        let converged = (end - point).length() <= tolerance;
        Some(image_from_path(
            eye,
            crossings,
            point,
            &indices[..=k],
            converged,
            iterations,
        ))
    }

    /// The alternating fixed point: Newton on `beta` with the lengths held, then Newton on `J`
    /// (central difference) at that `beta`, until `beta` moves less than 1e-14 and the angle
    /// holds to [`ANGLE_TOLERANCE`]; rounds spent and the result, None if the label vanishes.
    fn alternate(&self, label: Label, j: f64, beta: f64) -> Option<(u32, (f64, f64))> {
        let k = label.0;
        let n = self.indices;
        let beta_max = n.iter().fold(f64::INFINITY, |a, &b| a.min(b)) * (1.0 - 1e-12);
        let (mut j, mut beta) = (j, beta);
        let mut passage = self.residual(label, j, beta)?;
        for round in 1..=MAX_ROUNDS {
            let lengths = Self::lengths(&passage, k);
            let beta_before = beta;
            for _ in 0..30 {
                let (mut rise, mut slope) = (0.0, 0.0);
                for &(l, region) in &lengths[..=k] {
                    let q = n[region] * n[region] - beta * beta;
                    rise += beta * l / q.sqrt();
                    slope += l * n[region] * n[region] / (q * q.sqrt());
                }
                let step = (rise - self.rise) / slope;
                beta = (beta - step).clamp(-beta_max, beta_max);
                if step.abs() <= 1e-15 {
                    break;
                }
            }
            let h = 1e-7 * self.effective(beta)[0] * self.cylinder.outer_radius_m;
            for _ in 0..30 {
                passage = self.residual(label, j, beta)?;
                if passage.residual.abs() <= ANGLE_TOLERANCE {
                    break;
                }
                // Central difference, one-sided at the edge of the label's range.
                let at = |j: f64| self.residual(label, j, beta).map(|p| p.residual);
                let slope = match (at(j + h), at(j - h)) {
                    (Some(plus), Some(minus)) => (plus - minus) / (2.0 * h),
                    (Some(plus), None) => (plus - passage.residual) / h,
                    (None, Some(minus)) => (passage.residual - minus) / h,
                    (None, None) => break,
                };
                if slope == 0.0 || !slope.is_finite() {
                    break;
                }
                j -= passage.residual / slope;
            }
            passage = self.residual(label, j, beta)?;
            if (beta - beta_before).abs() <= 1e-14 && passage.residual.abs() <= ANGLE_TOLERANCE {
                return Some((round, (j, beta)));
            }
        }
        Some((MAX_ROUNDS, (j, beta)))
    }

    /// The 3-D crossings of a passage's path and the path's end at the passage.
    fn rebuild(
        &self,
        passage: &Passage,
        k: usize,
        beta: f64,
        eye_height: f64,
    ) -> ([DVec3; MAX_CROSSINGS], DVec3) {
        let (u, w) = self.cylinder.frame();
        let m = self.effective(beta);
        let to_world = |b: f64, s: f64, phi: f64, y: f64| {
            let rho = b.hypot(s);
            self.cylinder.base + rho * (phi.cos() * u + phi.sin() * w) + y * self.cylinder.axis
        };
        let mut crossings = [DVec3::ZERO; MAX_CROSSINGS];
        let mut y = eye_height;
        for (crossing, segment) in crossings.iter_mut().zip(&passage.walk.segments).take(k) {
            y += beta / m[segment.region] * (segment.s_end - segment.s_start);
            *crossing = to_world(segment.b, segment.s_end, segment.phi_at(segment.s_end), y);
        }
        let last = passage.walk.segments[k];
        y += beta / m[last.region] * (passage.s - last.s_start);
        (
            crossings,
            to_world(last.b, passage.s, last.phi_at(passage.s), y),
        )
    }
}

impl Cylinder {
    fn region_of_radius(&self, rho: f64) -> Region {
        if rho < self.inner_radius_m {
            Region::Inside
        } else if rho <= self.outer_radius_m {
            Region::Glass
        } else {
            Region::Outside
        }
    }
}
