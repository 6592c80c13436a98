//! The exact water surface, as every part of snell that meets it or looks past it sees it: the
//! frame's height field `y = h(x, z)` (the analytic waves plus the ripples) over the membrane's
//! horizontal extent, with the bounds its queries step by. Water exists only over the extent, as
//! in the rasteriser: outside it there is no surface to meet or to be blocked by.
//!
//! Its users: the ray-traced reference (where a sight ray meets the water,
//! [`ExactSurface::first_crossing`]), and the visibility of a light path eye -> sight point ->
//! point ([`ExactSurface::path_is_clear`]) for the exact method (through an exact sight point) and
//! the linear methods' crest check (through a cell's sight point on a facet). The image oracle of
//! the tests shares only the height field and its derivatives with it.
//!
//! # The guarantee
//! Every query walks its ray or segment `p(s) = o + s d` by steps that cannot pass the surface.
//! The clearance `f(s) = +-(p_y(s) - h(p_x(s), p_z(s)))` (positive on the side the query wants)
//! has `|f'| <= L = |d_y| + G |d_xz|` and `|f''| <= K = C |d_xz|^2`, where `G` bounds `|grad h|`
//! and `C` bounds the second derivative of `h` along any horizontal direction, over the part of
//! the plane under the piece of the walk ahead: the whole plane's bounds
//! ([`ExactSurface::slope_bound`], [`ExactSurface::curvature_bound`]), or, on water with ripples,
//! the bounds over the piece's horizontal footprint ([`ExactSurface::bounds_over`], per tile of
//! the ripple grid), so a wake slows only the walks that pass over it. From a point with
//! `f > 0`, the line `f - L s` and the parabola `f + f' s - K s^2 / 2` are lower bounds of `f`
//! ahead (within the piece), so no zero of `f` lies before the larger of their first zeros, or
//! the piece's end: that is the next step. Near a crossing it is a Newton step that stops short
//! of the root; far from the surface it takes long strides; grazing the surface the steps shrink
//! like `sqrt(2 f / K)` but never jump over it. Only the part of a segment inside the box of the
//! extent and the surface's height range ([`ExactSurface::height_range_m`]) is walked: nothing
//! outside it can meet the surface; a piece that passes over (or under) the surface's height
//! range over its footprint is crossed in one step.
//!
//! So no crossing is ever missed, whatever the surface's features: [`ExactSurface::first_crossing`]
//! returns the first point where a ray passes from above the surface to under it (within
//! [`SURFACE_HIT_TOLERANCE_M`]), and [`ExactSurface::path_is_clear`] says a path is clear only if
//! no point of it (beyond the caller's guard distance) is on the wrong side of the surface by more
//! than the caller's tolerance; a path that comes within [`SURFACE_HIT_TOLERANCE_M`] of that, or
//! keeps grazing it, counts as blocked. The bounds must hold: a field with wrong bounds gets no
//! guarantee.

use glam::DVec3;

use crate::sim::ripple_bounds::RippleBounds;
use crate::water::{HeightField, MembraneGrid};

/// `f` below which a ray is on the surface, metres (far under a pixel at any useful distance).
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

/// The frame's exact water surface over the membrane's extent, with the bounds the queries step
/// by (see the module docs: they must hold over the whole plane).
pub struct ExactSurface<'a> {
    pub height_field: &'a dyn HeightField,
    pub extent: MembraneGrid,
    /// Lowest and highest height the field reaches, metres.
    pub height_range_m: (f64, f64),
    /// Largest |grad h| and largest |second derivative along a unit horizontal direction|.
    pub slope_bound: f64,
    pub curvature_bound: f64,
    /// Bounds per part of the plane, finer than the three above where the surface is calmer than
    /// at its steepest; None: those hold everywhere ([`ExactSurface::bounds_over`]).
    pub local_bounds: Option<LocalBounds>,
}

/// The bounds of a surface that is analytic waves (bounds over the whole plane) plus ripples
/// (bounds per tile of their grid, [`RippleBounds`]).
#[derive(Clone, Debug)]
pub struct LocalBounds {
    /// The waves' height range, slope and curvature bounds (they hold everywhere).
    pub waves_height_range_m: (f64, f64),
    pub waves_slope: f64,
    pub waves_curvature: f64,
    pub ripples: RippleBounds,
}

/// Bounds of the surface over a horizontal box ([`ExactSurface::bounds_over`]): its height range,
/// largest |grad h| and second directional derivative there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxBounds {
    pub height_range_m: (f64, f64),
    pub slope: f64,
    pub curvature: f64,
}

/// Counts of the root finder's work on one ray (for the bench and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RootSteps {
    /// Height-field evaluations.
    pub evaluations: u32,
}

/// How a light path is checked by [`ExactSurface::path_is_clear`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathCheck {
    /// Points of the path closer to the sight point than this (horizontally) are not checked.
    pub guard_m: f64,
    /// A point counts as blocking only if it is on the wrong side of the surface by more than this.
    pub tolerance_m: f64,
    /// How far the sight point may be from the surface, vertically (0 for an exact sight point up
    /// to round-off; the faceting error for a sight point on a facet): what the shortcut that
    /// proves a path clear without walking it must allow for.
    pub sight_point_gap_m: f64,
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

/// The frame's water as a scene describes it: the analytic waves at the frame's time, plus the
/// ripples when there are any, summed in `height_field`.
pub fn of_water<'a>(
    waves: &'a crate::water::WaterSurface,
    ripples: Option<crate::sim::RippleField<'a>>,
    height_field: &'a dyn HeightField,
    extent: MembraneGrid,
) -> ExactSurface<'a> {
    let waves_height_range_m = waves.height_bounds_m();
    let (waves_slope, waves_curvature) = waves.slope_and_curvature_bounds();
    let (mut low, mut high) = waves_height_range_m;
    let (mut slope, mut curvature) = (waves_slope, waves_curvature);
    let mut local_bounds = None;
    if let Some(ripples) = ripples {
        let reach = ripples.max_abs_height_m();
        low -= reach;
        high += reach;
        let (s, c) = ripples.slope_and_curvature_bounds();
        slope += s;
        curvature += c;
        local_bounds = Some(LocalBounds {
            waves_height_range_m,
            waves_slope,
            waves_curvature,
            ripples: RippleBounds::new(&ripples),
        });
    }
    ExactSurface {
        height_field,
        extent,
        height_range_m: (low, high),
        slope_bound: slope,
        curvature_bound: curvature,
        local_bounds,
    }
}

/// `|(d.x, d.z)|`: a square root, not `hypot` (whose care for overflow costs several times as
/// much, and a walk asks for it at every start; metres never come near overflow).
#[inline(always)]
fn horizontal_length(d: DVec3) -> f64 {
    (d.x * d.x + d.z * d.z).sqrt()
}

/// The first zero of the lower bound `f + df s - k s^2 / 2` (f >= 0), infinite when it has none.
#[inline]
fn parabola_zero(f: f64, df: f64, k: f64) -> f64 {
    let root = (df * df + 2.0 * k * f).sqrt();
    if df > 0.0 {
        // Rising: (df + root) / k, which needs no cancellation here.
        if k > 0.0 {
            (df + root) / k
        } else {
            f64::INFINITY
        }
    } else if root - df > 0.0 {
        // The rationalised form of the same root, stable as k -> 0.
        2.0 * f / (root - df)
    } else {
        f64::INFINITY
    }
}

impl HeightField for ExactSurface<'_> {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.height_field.height(x, z)
    }
    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        self.height_field.gradient(x, z)
    }
    fn height_and_gradient(&self, x: f64, z: f64) -> (f64, (f64, f64)) {
        self.height_field.height_and_gradient(x, z)
    }
    fn normal(&self, x: f64, z: f64) -> DVec3 {
        self.height_field.normal(x, z)
    }
    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        self.height_field.hessian(x, z)
    }
    fn height_derivatives(&self, x: f64, z: f64) -> (f64, (f64, f64), (f64, f64, f64)) {
        self.height_field.height_derivatives(x, z)
    }
}

impl ExactSurface<'_> {
    /// The surface's bounds over the horizontal box `[x0, x1] x [z0, z1]`: the whole plane's
    /// without [`LocalBounds`], else the waves' plus the ripples' over the box.
    pub fn bounds_over(&self, x0: f64, z0: f64, x1: f64, z1: f64) -> BoxBounds {
        match &self.local_bounds {
            None => BoxBounds {
                height_range_m: self.height_range_m,
                slope: self.slope_bound,
                curvature: self.curvature_bound,
            },
            Some(local) => {
                let ripples = local.ripples.over(x0, z0, x1, z1);
                let (low, high) = local.waves_height_range_m;
                BoxBounds {
                    height_range_m: (low - ripples.reach_m, high + ripples.reach_m),
                    slope: local.waves_slope + ripples.slope,
                    curvature: local.waves_curvature + ripples.curvature_per_m,
                }
            }
        }
    }

    /// [`Self::bounds_over`] the horizontal footprint of the segment `a`-`b`.
    fn bounds_between(&self, a: DVec3, b: DVec3) -> BoxBounds {
        self.bounds_over(a.x.min(b.x), a.z.min(b.z), a.x.max(b.x), a.z.max(b.z))
    }

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
            || point.y <= self.height_field.height(point.x, point.z) + slack_m
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
        let horizontal = horizontal_length(direction);
        let lipschitz = direction.y.abs() + self.slope_bound * horizontal;
        let clearance = |t: f64, steps: &mut RootSteps| {
            steps.evaluations += 1;
            let p = origin + direction * t;
            let (h, (gx, gz)) = self.height_field.height_and_gradient(p.x, p.z);
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
        let mut walk = Walk::new(self, origin, direction, t, t1, 1.0, 0.0);
        for _ in 0..MAX_STEPS {
            if f <= SURFACE_HIT_TOLERANCE_M {
                return Some(self.hit_at(origin, direction, t, gradient));
            }
            let next = walk.next(t, f, df)?;
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
            let (h, g) = self.height_field.height_and_gradient(p.x, p.z);
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

    /// Whether the light path `eye -> sight_point -> point` is unobstructed (ALGORITHM §6): the
    /// segment from the eye stays above the surface and the one to the point below it, each
    /// beyond `check.guard_m` of the sight point and within `check.tolerance_m`, over the
    /// extent. Says nothing about the sight point itself (whether the ray refracts there).
    pub fn path_is_clear(
        &self,
        eye: DVec3,
        sight_point: DVec3,
        point: DVec3,
        check: &PathCheck,
    ) -> bool {
        self.segment_stays(sight_point, eye, 1.0, check)
            && self.segment_stays(sight_point, point, -1.0, check)
    }

    /// Whether `from + s (to - from)` for s in (0, 1], beyond `check.guard_m` of `from`, stays on
    /// its side of the surface: above it (`side = 1`) or below it (`side = -1`), within
    /// `check.tolerance_m`. First the shortcut [`Self::segment_clear_by_slope`], then the walk.
    pub fn segment_stays(&self, from: DVec3, to: DVec3, side: f64, check: &PathCheck) -> bool {
        let d = to - from;
        let horizontal = horizontal_length(d);
        if horizontal <= check.guard_m {
            // Every point of the segment is within the guard.
            return true;
        }
        if self.segment_clear_by_slope(from, d, side, check) {
            return true;
        }
        let start = check.guard_m / horizontal;
        self.segment_on_side(from, d, start, side, check.tolerance_m)
    }

    /// Proves, without walking, that no point `from + s d` with horizontal distance `r >= guard`
    /// from `from` is on the wrong side by more than the tolerance: false means "not proven".
    ///
    /// The segment's height moves away from `from.y` by `side * rise * r` (`rise` its slope),
    /// while the surface moves by at most `G r` from its height under `from`, which is within
    /// `sight_point_gap_m` (plus rounding) of `from.y`. A point past the tolerance needs
    /// `(rise - G) r < gap - tolerance`; with `rise >= G` that is impossible for every `r >= guard`
    /// once `(rise - G) guard >= gap - tolerance`.
    pub fn segment_clear_by_slope(
        &self,
        from: DVec3,
        d: DVec3,
        side: f64,
        check: &PathCheck,
    ) -> bool {
        let horizontal = horizontal_length(d);
        // G over the segment's footprint (which holds `from` and every point compared).
        let slope = if self.local_bounds.is_none() {
            self.slope_bound
        } else {
            self.bounds_between(from, from + d).slope
        };
        // `from` may be stored in f32: its height may be off by the rounding of its coordinates.
        let rounding_m =
            4.0 * f32::EPSILON as f64 * (1.0 + from.abs().max_element()) * (1.0 + slope);
        let excess_m = check.sight_point_gap_m + rounding_m - check.tolerance_m;
        // (rise - G) * guard >= excess, times `horizontal` (>= 0) to avoid dividing.
        side * d.y * check.guard_m
            >= slope * check.guard_m * horizontal + excess_m.max(0.0) * horizontal
            && side * d.y >= slope * horizontal
    }

    /// Walks `from + s d`, s in `[start, 1]`, and whether every point over the extent is on
    /// `side` of the surface (1 above, -1 below) within `tolerance_m` (module docs: the steps never
    /// pass the surface, so no violating point is skipped).
    pub fn segment_on_side(
        &self,
        from: DVec3,
        d: DVec3,
        start: f64,
        side: f64,
        tolerance_m: f64,
    ) -> bool {
        let e = &self.extent;
        let (low, high) = self.height_range_m;
        // Only inside the box of the extent and the surface's heights (widened by the tolerance)
        // can a point be on the wrong side.
        let Some((s0, s1)) = clip_to_box(
            from,
            d,
            DVec3::new(e.min_x, low - tolerance_m, e.min_z),
            DVec3::new(e.max_x, high + tolerance_m, e.max_z),
            start,
            1.0,
        ) else {
            return true;
        };
        let clearance = |s: f64| {
            #[cfg(test)]
            super::work::count(|w, k| w.walk_evaluations[k] += 1);
            let p = from + d * s;
            let (h, (gx, gz)) = self.height_field.height_and_gradient(p.x, p.z);
            (
                side * (p.y - h) + tolerance_m,
                side * (d.y - gx * d.x - gz * d.z),
            )
        };
        let mut s = s0;
        let (mut f, mut df) = clearance(s);
        let mut walk = Walk::new(self, from, d, s0, s1, side, tolerance_m);
        for _ in 0..MAX_STEPS {
            // Past the tolerance, or touching it on the way there.
            if f < 0.0 || (f <= SURFACE_HIT_TOLERANCE_M && df <= 0.0) {
                return false;
            }
            let Some(next) = walk.next(s, f, df) else {
                return true;
            };
            s = next;
            (f, df) = clearance(s);
        }
        // Grazing for ever: touching.
        false
    }
}

/// The steps of one walk along `p(s) = origin + s d` for s up to `end` (the module docs'
/// guarantee), on the clearance `f(s) = side (p_y(s) - h) + tolerance`: from a point with `f > 0`
/// and slope `df`, where to evaluate `f` next, or None when no zero of `f` lies before `end`.
///
/// The bounds `L` and `K` hold over a piece `[start, piece_end]` of the walk: the whole rest of it
/// with bounds over the whole plane, else (with [`LocalBounds`]) the surface's bounds over the
/// piece's horizontal footprint ([`ExactSurface::bounds_over`]). A step that would pass the
/// piece's end (its lower bounds have no zero in the piece) stops there, where the next piece
/// starts. Pieces start as long as the rest of the walk and shrink toward twice the step the
/// bounds give (at least a ripple tile across), so near a wake they see only the wake's tiles they
/// cross, and grow again (doubling) where the surface is calm. Over a piece the surface's local
/// height range alone may prove `f > 0` (the segment passes over or under every ripple there):
/// then the walk goes to the piece's end without a step inside.
struct Walk<'s, 'a> {
    surface: &'s ExactSurface<'a>,
    origin: DVec3,
    d: DVec3,
    end: f64,
    side: f64,
    tolerance: f64,
    /// Whether pieces shorter than the rest get their own bounds.
    local: bool,
    /// Shortest piece: a ripple tile across, as a parameter length.
    min_len: f64,
    /// The length the next piece is first tried at.
    next_len: f64,
    /// The current piece and its bounds on `|f'|` and `|f''|`.
    piece_end: f64,
    lipschitz: f64,
    curvature: f64,
    /// The local height range proves `f > 0` over the whole piece.
    piece_clear: bool,
}

impl<'s, 'a> Walk<'s, 'a> {
    #[inline(always)]
    fn new(
        surface: &'s ExactSurface<'a>,
        origin: DVec3,
        d: DVec3,
        start: f64,
        end: f64,
        side: f64,
        tolerance: f64,
    ) -> Self {
        let horizontal = horizontal_length(d);
        let tile_m = surface.local_bounds.as_ref().map(|l| l.ripples.tile_m());
        let mut walk = Walk {
            surface,
            origin,
            d,
            end,
            side,
            tolerance,
            local: tile_m.is_some(),
            min_len: tile_m.map_or(f64::INFINITY, |t| t / horizontal),
            next_len: f64::INFINITY,
            piece_end: end,
            lipschitz: d.y.abs() + surface.slope_bound * horizontal,
            curvature: surface.curvature_bound * horizontal * horizontal,
            piece_clear: false,
        };
        if walk.local {
            // Made at the first step, which knows f there.
            walk.piece_end = start;
        }
        walk
    }

    /// The next parameter to evaluate the clearance at, from `s` where it is `f > 0` with slope
    /// `df`; None when the walk reaches `end` with no zero of it.
    #[inline(always)]
    fn next(&mut self, s: f64, f: f64, df: f64) -> Option<f64> {
        if self.local && s >= self.piece_end {
            self.start_piece(s, f, df);
        }
        let step = if self.piece_clear {
            f64::INFINITY
        } else {
            (f / self.lipschitz).max(parabola_zero(f, df, self.curvature))
        };
        if s + step <= self.piece_end {
            Some(s + step)
        } else if self.piece_end < self.end {
            Some(self.piece_end)
        } else {
            None
        }
    }

    /// A piece from `s`: bounds over its footprint, shorter pieces tried while they give a step
    /// that is much longer than the longer piece's.
    #[inline(never)]
    fn start_piece(&mut self, s: f64, f: f64, df: f64) {
        let horizontal = horizontal_length(self.d);
        let mut len = (self.end - s).min(self.next_len.max(self.min_len));
        loop {
            let (a, b) = (self.origin + self.d * s, self.origin + self.d * (s + len));
            let bounds = self.surface.bounds_between(a, b);
            self.piece_end = s + len;
            self.lipschitz = self.d.y.abs() + bounds.slope * horizontal;
            self.curvature = bounds.curvature * horizontal * horizontal;
            // f >= side (p_y - h) + tolerance with h within the range, linear along the piece.
            let (low, high) = bounds.height_range_m;
            let above = |y: f64| {
                if self.side > 0.0 {
                    y - high
                } else {
                    low - y
                }
            };
            self.piece_clear = above(a.y).min(above(b.y)) + self.tolerance > 0.0;
            if self.piece_clear || len <= self.min_len {
                break;
            }
            let step = (f / self.lipschitz).max(parabola_zero(f, df, self.curvature));
            let shorter = (2.0 * step).max(self.min_len);
            if step >= len || shorter >= 0.5 * len {
                break;
            }
            len = shorter;
        }
        self.next_len = 2.0 * len;
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
            height_field: field,
            extent: extent(10.0),
            height_range_m: (0.0, a),
            slope_bound: slope,
            curvature_bound: curvature,
            local_bounds: None,
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
            height_field: &field,
            extent: extent(2.0),
            height_range_m: (-0.25, -0.25),
            slope_bound: 0.0,
            curvature_bound: 0.0,
            local_bounds: None,
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
            height_field: &field,
            extent: extent(3.0),
            height_range_m: (-0.07, 0.07),
            slope_bound: slope,
            curvature_bound: curvature,
            local_bounds: None,
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

    /// The visibility walk against dense sampling: segments from points on two crossing waves to
    /// points above (side 1) and below (side -1), some grazing the crests. Where a dense sampling
    /// finds a point past the tolerance, the walk must say so; where every sample clears it by a
    /// micrometre, the walk must find the segment clear. Both kinds of segment must occur.
    #[test]
    fn segments_on_side_agree_with_dense_sampling() {
        let field = FnHeightField::new(|x, z| {
            0.05 * (3.0 * x + 1.0).cos() + 0.02 * (7.0 * z - 2.0 * x).cos()
        });
        let water = ExactSurface {
            height_field: &field,
            extent: extent(3.0),
            height_range_m: (-0.07, 0.07),
            slope_bound: 0.05 * 3.0 + 0.02 * (49.0f64 + 4.0).sqrt(),
            curvature_bound: 0.05 * 9.0 + 0.02 * 53.0,
            local_bounds: None,
        };
        let mut rng = crate::seeded::SplitMix64::new(0x5EED_5EE5);
        let tolerance_m = 1e-3;
        let (mut clear, mut blocked) = (0, 0);
        for case in 0..600 {
            let (x, z) = (rng.range(-2.5, 2.5), rng.range(-2.5, 2.5));
            let from = DVec3::new(x, field.height(x, z), z);
            let side = if case % 2 == 0 { 1.0 } else { -1.0 };
            // Shallow segments (slopes of 0.01 to 0.3) so that many meet the waves.
            let length = rng.range(0.5, 4.0);
            let angle = rng.range(0.0, std::f64::consts::TAU);
            let to = from
                + DVec3::new(
                    length * angle.cos(),
                    side * length * rng.range(0.01, 0.3),
                    length * angle.sin(),
                );
            let start = 0.05;
            let walked = water.segment_on_side(from, to - from, start, side, tolerance_m);
            let samples = 20_000;
            let worst = (0..=samples)
                .map(|k| start + (1.0 - start) * k as f64 / samples as f64)
                .map(|s| from + (to - from) * s)
                .filter(|p| water.covers(p.x, p.z, 0.0))
                .map(|p| side * (p.y - field.height(p.x, p.z)) + tolerance_m)
                .fold(f64::INFINITY, f64::min);
            if worst < 0.0 {
                assert!(!walked, "case {case}: a point {worst} m past the tolerance");
            } else if worst > 1e-6 {
                assert!(walked, "case {case}: clear by {worst} m, walked as blocked");
            }
            if walked {
                clear += 1;
            } else {
                blocked += 1;
            }
        }
        assert!(
            clear > 100 && blocked > 50,
            "{clear} clear, {blocked} blocked"
        );
    }

    /// A light path through a sight point on a Gaussian ridge's far flank, seen from low on the
    /// near side, is blocked by the crest; through the near flank it is clear; the slope proof
    /// clears steep paths without a walk and never a blocked one.
    #[test]
    fn a_crest_in_front_blocks_the_path_and_the_slope_proof_never_hides_it() {
        let (a, w) = (0.1, 0.3);
        let (field, slope, curvature) = ridge(a, w);
        let water = surface(&field, slope, curvature, a);
        let check = PathCheck {
            guard_m: 0.0,
            tolerance_m: 1e-9,
            sight_point_gap_m: 0.0,
        };
        let eye = DVec3::new(-4.0, 0.3, 0.0);
        let on = |x: f64| DVec3::new(x, field.height(x, 0.0), 0.0);
        let below = |x: f64| DVec3::new(x + 0.1, -0.5, 0.0);
        assert!(!water.path_is_clear(eye, on(0.6), below(0.6), &check));
        assert!(water.path_is_clear(eye, on(-0.6), below(-0.6), &check));
        // Straight down from overhead: steeper than any slope, proven without a walk.
        let overhead = DVec3::new(0.6, 3.0, 0.0);
        assert!(water.segment_clear_by_slope(on(0.6), overhead - on(0.6), 1.0, &check));
        assert!(!water.segment_clear_by_slope(on(0.6), eye - on(0.6), 1.0, &check));
    }
}
