//! Refraction cells and the containment test (ALGORITHM §5): receives a facet's three vertices with
//! their refraction rays and a true vertex V; returns every way V lies in the facet's cell (ray
//! parameter t, barycentrics, sight point). Equal-t cells solve the cubic
//! `det[(P1-P0) + t(T1-T0), (P2-P0) + t(T2-T0), V - P0 - t T0] = 0` for all roots t >= 0 (several
//! roots = several images); the thesis's per-facet plane test is kept as a mode.
//! Everything inside is f64: the cubic's coefficients cancel heavily for nearly parallel rays.

use glam::{DVec3, Vec3};

/// Barycentric slack: a point with all barycentrics `>= -CONTAINMENT_EPS` is inside. It must exceed
/// the f32 rounding of the inputs relative to a facet (positions ~1e2 m carry ~1e-5 m of rounding,
/// facets are >= ~1e-2 m), so points on shared faces are never lost between two cells; the
/// duplicates this creates are merged by sight point in the search.
pub const CONTAINMENT_EPS: f64 = 1e-4;

/// A cell: the facet's vertices `P_i` and unit refraction directions `T_i`, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub origins: [DVec3; 3],
    pub directions: [DVec3; 3],
}

impl Cell {
    pub fn new(origins: [Vec3; 3], directions: [Vec3; 3]) -> Self {
        Self {
            origins: origins.map(|p| p.as_dvec3()),
            directions: directions.map(|d| d.as_dvec3()),
        }
    }

    /// Cross-section vertex `P_i + t T_i`.
    pub fn cross_section(&self, t: f64) -> [DVec3; 3] {
        [0, 1, 2].map(|i| self.origins[i] + t * self.directions[i])
    }
}

/// One way a point lies in a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Containment {
    /// Ray parameter (equal-t: of the cross-section; thesis: barycentric mean of the t_i).
    pub t: f64,
    pub barycentric: [f64; 3],
    /// `b0 P0 + b1 P1 + b2 P2`.
    pub sight_point: DVec3,
}

/// Up to three containments (one per root of the cubic); allocation-free.
#[derive(Clone, Copy, Debug, Default)]
pub struct Containments {
    items: [Option<Containment>; 3],
    len: usize,
}

impl Containments {
    fn push(&mut self, c: Containment) {
        if self.len < 3 {
            self.items[self.len] = Some(c);
            self.len += 1;
        }
    }
    pub fn len(&self) -> usize {
        self.len
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    pub fn iter(&self) -> impl Iterator<Item = &Containment> {
        self.items[..self.len].iter().flatten()
    }
}

/// Coefficients `[c0, c1, c2, c3]` of `det(t) = c0 + c1 t + c2 t^2 + c3 t^3`.
pub fn containment_cubic(cell: &Cell, point: DVec3) -> [f64; 4] {
    let [p0, p1, p2] = cell.origins;
    let [t0, t1, t2] = cell.directions;
    let (a0, a1) = (p1 - p0, t1 - t0);
    let (b0, b1) = (p2 - p0, t2 - t0);
    let (c0, c1) = (point - p0, -t0);
    let triple = |a: DVec3, b: DVec3, c: DVec3| a.dot(b.cross(c));
    [
        triple(a0, b0, c0),
        triple(a1, b0, c0) + triple(a0, b1, c0) + triple(a0, b0, c1),
        triple(a1, b1, c0) + triple(a1, b0, c1) + triple(a0, b1, c1),
        triple(a1, b1, c1),
    ]
}

fn eval_cubic(c: &[f64; 4], t: f64) -> f64 {
    ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
}

fn eval_derivative(c: &[f64; 4], t: f64) -> f64 {
    (3.0 * c[3] * t + 2.0 * c[2]) * t + c[1]
}

/// Real roots of `a t^2 + b t + c` (any of a, b may be zero), sorted; no roots if all vanish.
fn quadratic_roots(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    if a == 0.0 {
        if b == 0.0 {
            return ([0.0; 2], 0);
        }
        return ([-c / b, 0.0], 1);
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return ([0.0; 2], 0);
    }
    // Numerically stable form: no cancellation between -b and the root.
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        return ([0.0, 0.0], 1);
    }
    let (r1, r2) = (q / a, c / q);
    if r1 <= r2 {
        ([r1, r2], 2)
    } else {
        ([r2, r1], 2)
    }
}

/// A root of the cubic in `[low, high]` where it changes sign (safeguarded Newton with bisection),
/// started at `hint` when it lies inside.
fn bracketed_root(
    c: &[f64; 4],
    mut low: f64,
    mut high: f64,
    mut f_low: f64,
    f_high: f64,
    hint: f64,
) -> f64 {
    // Start at the hint (the caller's estimate of the root), else at the secant point.
    let mut t = if hint > low && hint < high {
        hint
    } else {
        low + (high - low) * (f_low / (f_low - f_high))
    };
    if !(t > low && t < high) {
        t = 0.5 * (low + high);
    }
    for _ in 0..100 {
        let f = eval_cubic(c, t);
        if f == 0.0 {
            return t;
        }
        if (f < 0.0) == (f_low < 0.0) {
            low = t;
            f_low = f;
        } else {
            high = t;
        }
        let d = eval_derivative(c, t);
        let newton = t - f / d;
        // Converged: the Newton step is below the resolution (it may round to no step at all, so
        // this must come before the bracket test, which would otherwise bisect a converged root).
        // Or the step is small enough that Newton's quadratic convergence (error after the step
        // about |f''/2f'| step^2) leaves less than the tolerance.
        let step = (newton - t).abs();
        let tolerance = 1e-14 * (1.0 + t.abs());
        if step <= tolerance
            || (step <= 1e-6 * (1.0 + t.abs())
                && (c[2] + 3.0 * c[3] * t).abs() * step * step <= 0.1 * tolerance * d.abs())
        {
            return newton.clamp(low, high);
        }
        let next = if d != 0.0 && newton > low && newton < high {
            newton
        } else {
            0.5 * (low + high)
        };
        // 1e-14 relative in t is far below anything f32 outputs can show, and reachable in f64.
        if (next - t).abs() <= 1e-14 * (1.0 + t.abs()) || high - low <= 1e-14 * (1.0 + high.abs()) {
            return next;
        }
        t = next;
    }
    t
}

/// Every real root of the cubic in `[low, high]`, ascending, into `roots`. Splits the interval at the
/// critical points (so each piece is monotone), root-finds pieces with a sign change, and keeps a
/// critical point that touches zero (a double root: the point is tangent to a cross-section plane).
/// Works unchanged when the leading coefficients vanish (quadratic, linear cases).
// `!(low <= high)` deliberately also rejects a NaN bound; `low > high` would let it through.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn cubic_roots_in(c: &[f64; 4], low: f64, high: f64, hint: f64, roots: &mut [f64; 3]) -> usize {
    let mut count = 0;
    let scale = c.iter().map(|x| x.abs()).fold(0.0, f64::max);
    if scale == 0.0 || !(low <= high) {
        return 0;
    }
    // Monotone on the interval when the linear term of the derivative outweighs the others at
    // every |t| <= reach: no critical point to look for (the common, nearly linear case).
    let reach = low.abs().max(high.abs());
    let bend = 2.0 * c[2].abs() * reach + 3.0 * c[3].abs() * reach * reach;
    let (critical, n_critical) = if c[1].abs() > bend * (1.0 + 1e-9) {
        ([0.0; 2], 0)
    } else {
        quadratic_roots(3.0 * c[3], 2.0 * c[2], c[1])
    };
    let mut knots = [low, 0.0, 0.0, high];
    let mut n_knots = 1;
    for &k in &critical[..n_critical] {
        if k > low && k < high {
            knots[n_knots] = k;
            n_knots += 1;
        }
    }
    knots[n_knots] = high;
    n_knots += 1;
    // "Touches zero" tolerance for double roots, relative to the size of the terms.
    let magnitude = |t: f64| {
        let at = t.abs();
        c[0].abs() + c[1].abs() * at + c[2].abs() * at * at + c[3].abs() * at * at * at
    };
    let mut push = |r: f64, count: &mut usize| {
        if *count > 0 && (r - roots[*count - 1]).abs() <= 1e-12 * (1.0 + r.abs()) {
            return;
        }
        if *count < 3 {
            roots[*count] = r;
            *count += 1;
        }
    };
    for w in 0..n_knots - 1 {
        let (a, b) = (knots[w], knots[w + 1]);
        let (fa, fb) = (eval_cubic(c, a), eval_cubic(c, b));
        if fa == 0.0 {
            push(a, &mut count);
        } else if w > 0 && fa.abs() <= 1e-13 * magnitude(a) {
            // An interior critical point at zero: a double root.
            push(a, &mut count);
        }
        if fa != 0.0 && fb != 0.0 && (fa < 0.0) != (fb < 0.0) {
            push(bracketed_root(c, a, b, fa, fb, hint), &mut count);
        }
        if w == n_knots - 2 && fb == 0.0 {
            push(b, &mut count);
        }
    }
    count
}

/// Barycentrics of `point` in the triangle `q` (point assumed in its plane); None if degenerate.
fn barycentrics_in(q: &[DVec3; 3], point: DVec3) -> Option<[f64; 3]> {
    let e1 = q[1] - q[0];
    let e2 = q[2] - q[0];
    let w = point - q[0];
    let n = e1.cross(e2);
    let n2 = n.length_squared();
    // A NaN `n2` fails `is_finite`, so this rejects it just as `!(n2 > 0.0)` did.
    if n2 <= 0.0 || !n2.is_finite() {
        return None;
    }
    let b1 = w.cross(e2).dot(n) / n2;
    let b2 = e1.cross(w).dot(n) / n2;
    Some([1.0 - b1 - b2, b1, b2])
}

fn sight_point_of(cell: &Cell, b: [f64; 3]) -> DVec3 {
    b[0] * cell.origins[0] + b[1] * cell.origins[1] + b[2] * cell.origins[2]
}

/// Upper bound on the ray parameter of any cross-section containing `point`: a point of the cell at
/// parameter t is `S + t sum(b_i T_i)`, so `t <= |V - S| / |sum(b_i T_i)|`, and
/// `|sum(b_i T_i)| >= sum(b_i (T_i . m))` for the unit mean direction m. Generous slack for eps.
fn t_upper_bound(cell: &Cell, point: DVec3) -> f64 {
    let [t0, t1, t2] = cell.directions;
    let m = (t0 + t1 + t2).normalize_or_zero();
    let min_along = cell
        .directions
        .iter()
        .map(|t| t.dot(m))
        .fold(f64::INFINITY, f64::min);
    // One square root of the largest square: the same value as the largest root (sqrt is
    // correctly rounded and monotone), fewer long-latency operations on the query path.
    let reach = cell
        .origins
        .iter()
        .map(|p| (point - *p).length_squared())
        .fold(0.0, f64::max)
        .sqrt();
    let facet_size = (cell.origins[1] - cell.origins[0])
        .length_squared()
        .max((cell.origins[2] - cell.origins[0]).length_squared())
        .sqrt();
    let denominator = min_along - 3.0 * CONTAINMENT_EPS * 2.0;
    if denominator > 1e-3 {
        (reach + facet_size) * 1.01 / denominator
    } else {
        // Rays spread over more than ~180°: only extrapolated cells do this; search far.
        1e3 * (reach + facet_size)
    }
}

/// Where the root usually is: the ray parameter at which the mean of the three rays reaches the
/// point's height (a cross-section through the point is near that height). Only a starting point
/// for the root finder: any value, even NaN, gives the same roots.
fn depth_parameter(cell: &Cell, point: DVec3) -> f64 {
    let [p0, p1, p2] = cell.origins;
    let [t0, t1, t2] = cell.directions;
    ((p0.y + p1.y + p2.y) - 3.0 * point.y) / -(t0.y + t1.y + t2.y)
}

/// Equal-t containment (ALGORITHM §5.3, default): every root `t >= 0` of the cubic at which the
/// barycentrics of `point` in the cross-section are all `>= -CONTAINMENT_EPS`.
pub fn equal_t_containments(cell: &Cell, point: DVec3) -> Containments {
    let mut out = Containments::default();
    let coefficients = containment_cubic(cell, point);
    let mut roots = [0.0; 3];
    let n = cubic_roots_in(
        &coefficients,
        0.0,
        t_upper_bound(cell, point),
        depth_parameter(cell, point),
        &mut roots,
    );
    for &t in &roots[..n] {
        let q = cell.cross_section(t);
        if let Some(b) = barycentrics_in(&q, point) {
            if b.iter().all(|&x| x >= -CONTAINMENT_EPS) {
                out.push(Containment {
                    t,
                    barycentric: b,
                    sight_point: sight_point_of(cell, b),
                });
            }
        }
    }
    out
}

/// The thesis's containment (ALGORITHM §5.3, thesis mode): the plane through `point` normal to the
/// mean ray direction m cuts the three rays at `Q_i`; inside iff the barycentrics of `point` in
/// `Q0 Q1 Q2` are all `>= -CONTAINMENT_EPS` and the point is in front of the sight point.
pub fn thesis_containment(cell: &Cell, point: DVec3) -> Option<Containment> {
    let [t0, t1, t2] = cell.directions;
    let m = (t0 + t1 + t2).normalize_or_zero();
    if m == DVec3::ZERO {
        return None;
    }
    let mut ts = [0.0; 3];
    for ((t, direction), origin) in ts.iter_mut().zip(cell.directions).zip(cell.origins) {
        let along = m.dot(direction);
        if along.abs() < 1e-12 {
            return None;
        }
        *t = m.dot(point - origin) / along;
    }
    let q = [0, 1, 2].map(|i| cell.origins[i] + ts[i] * cell.directions[i]);
    let b = barycentrics_in(&q, point)?;
    if b.iter().any(|&x| x < -CONTAINMENT_EPS) {
        return None;
    }
    let sight_point = sight_point_of(cell, b);
    let mean_direction = b[0] * t0 + b[1] * t1 + b[2] * t2;
    if (point - sight_point).dot(mean_direction) < 0.0 {
        return None;
    }
    Some(Containment {
        t: b[0] * ts[0] + b[1] * ts[1] + b[2] * ts[2],
        barycentric: b,
        sight_point,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slightly skewed facet with diverging rays (a crest-like cell).
    fn test_cell() -> Cell {
        Cell::new(
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.1, 0.0),
                Vec3::new(0.0, -0.05, 1.0),
            ],
            [
                Vec3::new(0.1, -1.0, 0.05).normalize(),
                Vec3::new(0.4, -1.0, 0.0).normalize(),
                Vec3::new(0.0, -1.0, 0.3).normalize(),
            ],
        )
    }

    fn point_at(cell: &Cell, t: f64, b: [f64; 3]) -> DVec3 {
        let q = cell.cross_section(t);
        b[0] * q[0] + b[1] * q[1] + b[2] * q[2]
    }

    #[test]
    fn quadratic_and_degenerate_roots() {
        assert_eq!(quadratic_roots(0.0, 0.0, 1.0).1, 0);
        let (r, n) = quadratic_roots(0.0, 2.0, -4.0);
        assert_eq!((n, r[0]), (1, 2.0));
        let (r, n) = quadratic_roots(1.0, -3.0, 2.0);
        assert_eq!(n, 2);
        assert!((r[0] - 1.0).abs() < 1e-15 && (r[1] - 2.0).abs() < 1e-15);
        let mut roots = [0.0; 3];
        // (t-1)(t-2)(t-3)
        let n = cubic_roots_in(&[-6.0, 11.0, -6.0, 1.0], 0.0, 10.0, f64::NAN, &mut roots);
        assert_eq!(n, 3);
        for (r, e) in roots.iter().zip([1.0, 2.0, 3.0]) {
            assert!((r - e).abs() < 1e-12);
        }
        // Leading coefficient zero: linear.
        let n = cubic_roots_in(&[-1.0, 2.0, 0.0, 0.0], 0.0, 10.0, f64::NAN, &mut roots);
        assert_eq!((n, roots[0]), (1, 0.5));
        // Tiny leading coefficient: the small roots are still found accurately.
        let n = cubic_roots_in(&[-6.0, 5.0, 1.0, 1e-14], 0.0, 10.0, f64::NAN, &mut roots);
        assert_eq!(n, 1);
        assert!((roots[0] - 1.0).abs() < 1e-9, "{}", roots[0]);
        // Double root (t-2)^2 (t+1) = t^3 - 3t^2 + 4
        let n = cubic_roots_in(&[4.0, 0.0, -3.0, 1.0], 0.0, 10.0, f64::NAN, &mut roots);
        assert_eq!(n, 1);
        assert!((roots[0] - 2.0).abs() < 1e-9);
    }

    /// The hint only picks where Newton starts: any hint, inside or outside the interval, on a
    /// root, on a critical point or NaN, gives the same roots.
    #[test]
    fn the_root_finder_hint_does_not_change_the_roots() {
        let cubics: [[f64; 4]; 5] = [
            [-6.0, 11.0, -6.0, 1.0],
            [-6.0, 5.0, 1.0, 1e-14],
            [4.0, 0.0, -3.0, 1.0],
            [
                -0.009433435015671399,
                0.0008202018926952801,
                0.0005637721898486885,
                3.7e-5,
            ],
            [
                -0.008245528364004134,
                0.006763817322168615,
                -0.0010756909461731834,
                -7.8e-5,
            ],
        ];
        for c in cubics {
            let mut reference = [0.0; 3];
            let n = cubic_roots_in(&c, 0.0, 10.0, f64::NAN, &mut reference);
            for hint in [
                -1.0,
                0.0,
                0.5,
                1.0,
                1.5,
                2.0,
                2.5,
                3.0,
                3.17,
                9.99,
                10.0,
                50.0,
                f64::INFINITY,
            ] {
                let mut roots = [0.0; 3];
                assert_eq!(
                    cubic_roots_in(&c, 0.0, 10.0, hint, &mut roots),
                    n,
                    "{c:?} hint {hint}"
                );
                for (r, e) in roots[..n].iter().zip(&reference[..n]) {
                    assert!(
                        (r - e).abs() <= 1e-9 * (1.0 + e.abs()),
                        "{c:?} hint {hint}: {r} vs {e}"
                    );
                }
            }
        }
    }

    #[test]
    fn points_built_inside_the_cell_are_found_with_their_parameters() {
        let cell = test_cell();
        for &t in &[0.0, 0.01, 0.5, 2.0, 7.5] {
            for &b in &[
                [0.2, 0.3, 0.5],
                [1.0, 0.0, 0.0],
                [0.0, 0.5, 0.5],
                [0.6, 0.4, 0.0],
                [1.0 / 3.0; 3],
            ] {
                let v = point_at(&cell, t, b);
                let found = equal_t_containments(&cell, v);
                let hit = found
                    .iter()
                    .find(|c| (c.t - t).abs() < 1e-7)
                    .unwrap_or_else(|| panic!("t {t} b {b:?}: {found:?}"));
                for (found_b, expected_b) in hit.barycentric.iter().zip(b) {
                    assert!((found_b - expected_b).abs() < 1e-7);
                }
                let s = sight_point_of(&cell, b);
                assert!((hit.sight_point - s).length() < 1e-7);
            }
        }
    }

    #[test]
    fn points_outside_and_above_are_rejected() {
        let cell = test_cell();
        // Outside a face.
        assert!(equal_t_containments(&cell, point_at(&cell, 1.0, [-0.05, 0.5, 0.55])).is_empty());
        assert!(equal_t_containments(&cell, point_at(&cell, 3.0, [0.5, 0.6, -0.1])).is_empty());
        // Above the facet (t < 0).
        assert!(equal_t_containments(&cell, point_at(&cell, -0.5, [0.3, 0.3, 0.4])).is_empty());
    }

    #[test]
    fn parallel_rays_reduce_to_a_linear_equation() {
        let d = Vec3::new(0.3, -1.0, 0.1).normalize();
        let cell = Cell::new([Vec3::ZERO, Vec3::X, Vec3::Z], [d, d, d]);
        let c = containment_cubic(&cell, point_at(&cell, 2.0, [0.2, 0.2, 0.6]));
        assert_eq!(c[3], 0.0);
        assert_eq!(c[2], 0.0);
        let found = equal_t_containments(&cell, point_at(&cell, 2.0, [0.2, 0.2, 0.6]));
        assert_eq!(found.len(), 1);
        assert!((found.iter().next().unwrap().t - 2.0).abs() < 1e-9);
    }

    #[test]
    fn thesis_mode_agrees_inside_and_accepts_points_near_the_surface() {
        let d = Vec3::new(0.2, -1.0, 0.0).normalize();
        let cell = Cell::new([Vec3::ZERO, Vec3::X, Vec3::Z], [d, d, d]);
        // With parallel rays both definitions coincide.
        let v = point_at(&cell, 1.5, [0.2, 0.5, 0.3]);
        let thesis = thesis_containment(&cell, v).expect("inside");
        assert!((thesis.barycentric[1] - 0.5).abs() < 1e-9);
        assert!((thesis.t - 1.5).abs() < 1e-9);
        // Near the surface some t_i are negative but the point is in front: accepted.
        let tilted = Cell::new([Vec3::ZERO, Vec3::new(1.0, 0.3, 0.0), Vec3::Z], [d, d, d]);
        let v = point_at(&tilted, 0.01, [0.1, 0.1, 0.8]);
        assert!(thesis_containment(&tilted, v).is_some());
        assert!(thesis_containment(&tilted, point_at(&tilted, -0.3, [0.3, 0.3, 0.4])).is_none());
    }
}
