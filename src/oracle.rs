//! An independent image oracle: every image of a point under the exact water surface, found by
//! scanning the whole region where a sight point can lie and solving Newton's method on Fermat's
//! principle wherever the scan cannot rule an image out (ALGORITHM §6). It is the truth the
//! renderer's methods are measured against (`snell stability`'s multi-image share, the image
//! tests), so it shares nothing with them but the surface's height function, its derivatives and
//! its stated bounds: no cell, no search, no merge, no crest check, no intersection code (a test
//! reads this file's imports to hold it to that).
//!
//! # Why the scan finds every image
//! An image of `V` seen from `E` is a stationary point of the optical path
//! `L(x, z) = n1 |S - E| + n2 |V - S|`, `S = (x, h(x, z), z)`, with an unobstructed path. Its
//! gradient `F = grad L` is Lipschitz: `|F(p) - F(q)| <= Lambda |p - q|` with
//! `Lambda = (1 + G^2)(n1 / d_E + n2 / d_V) + (n1 + n2) C`, from `Hess L = S_i^T M S_j + a_y h_ij`
//! (`|S_i|^2 <= 1 + G^2`, `|M| <= n1 / |S - E| + n2 / |S - V|`, `|a_y| <= n1 + n2`,
//! `|h_ij| <= C`), where `G` and `C` bound the surface's slope and curvature and `d_E`, `d_V`
//! bound the distances of the eye and the point from any surface point from below. So a square
//! cell of half-diagonal `r` whose centre has `|F| > Lambda r` holds no stationary point. The scan
//! starts from one square holding every possible sight point (the refracted ray leaves `S` at most
//! `asin(n1 / n2)` from the normal, which tilts at most `atan G` from the vertical, so `S` lies
//! within `(y_max - V.y) tan(asin(n1 / n2) + atan G)` of `V` horizontally) and splits every cell
//! it cannot rule out, down to cells of [`LEAF_HALF_SIZE_M`]: every stationary point lies in one
//! of those leaves. The argument needs the bounds only over the cell it rules out: where the
//! surface states them region by region ([`LocalBounds`]: a wake is steep only near the body that
//! makes it), each cell's `Lambda` takes `G`, `C` and the height range over the cell itself, and
//! `d_E`, `d_V` also from below by the vertical clearance to that height range and the horizontal
//! gap between the cell and the eye or the point, so calm water is ruled out in large cells; and
//! a cell farther from the point horizontally than `(y_max - V.y) tan(asin(n1 / n2) + atan G)`
//! with the cell's own `y_max` and `G` holds no sight point at all.
//! Newton's method from each leaf's centre, within a micrometre of the
//! stationary point, converges to it unless the point is degenerate (`det Hess L = 0`: a fold,
//! or caustic, where two images meet); a leaf whose solve fails is counted as unresolved
//! ([`OracleImages::unresolved_leaves`]): there `|F|` is within `Lambda` times a micrometre of
//! zero and Newton cannot settle, which is what a point on a fold looks like.
//!
//! Each stationary point is then checked as an image: over the water's extent, the sight ray
//! arriving from the air side and leaving into the water, and the path clear: the segment from
//! the eye above the surface and the one to the point below it, proven by splitting each segment
//! until, on every piece, the clearance at its ends exceeds what the slope bound lets it lose in
//! between.

use glam::{DMat2, DVec2, DVec3};

use crate::water::{HeightField, MembraneGrid};

/// Leaves of the scan: squares of this half-size (metres). Two stationary points closer than
/// this are one image (they are a fold's two images about to merge).
pub const LEAF_HALF_SIZE_M: f64 = 5e-7;
/// Newton converged: `|grad L| <= this * (n1 + n2)`.
const GRADIENT_TOLERANCE: f64 = 1e-11;
const NEWTON_ITERATIONS: u32 = 60;
/// Cells the scan may visit before it gives up on a point (it then reports the point unscanned).
const MAX_CELLS: usize = 4_000_000;

/// The water as the oracle sees it: a height field over an extent, with bounds that hold over the
/// whole plane.
#[derive(Clone, Copy)]
pub struct OracleWater<'a> {
    pub height_field: &'a dyn HeightField,
    /// Water exists only over this rectangle (its grid resolution is not used).
    pub extent: MembraneGrid,
    /// Lowest and highest surface height, metres.
    pub height_range_m: (f64, f64),
    /// Largest |grad h|, largest |second derivative along a horizontal direction|.
    pub slope_bound: f64,
    pub curvature_bound: f64,
    /// Indices of refraction above (the eye's side) and below.
    pub n_above: f64,
    pub n_below: f64,
    /// Tighter bounds region by region, where the surface knows them (a wake's steepest node sets
    /// the global ones; calm water elsewhere need not be scanned as finely as the wake).
    pub local_bounds: Option<&'a dyn LocalBounds>,
}

/// Bounds of the surface over one rectangle of the plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionBounds {
    /// Lowest and highest height over the rectangle, metres.
    pub height_range_m: (f64, f64),
    /// Largest |grad h| and largest |second derivative along a horizontal direction| over it.
    pub slope_bound: f64,
    pub curvature_bound: f64,
}

/// A surface's bounds region by region. Each answer must hold at every point of the rectangle
/// asked about (the scan's proof that a cell holds no image rests on it).
pub trait LocalBounds: Sync {
    /// Bounds over `[min, max]` (x, z).
    fn over(&self, min: DVec2, max: DVec2) -> RegionBounds;
}

/// One image the oracle found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleImage {
    pub sight_point: DVec3,
    /// `n1 |S - E| + n2 |V - S|`.
    pub optical_path_m: f64,
    /// Determinant of `Hess L` at the sight point (near zero: close to a fold).
    pub hessian_determinant: f64,
}

/// Every image of a point, ordered by optical path.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OracleImages {
    pub images: Vec<OracleImage>,
    /// Leaves of the scan where no Newton solve landed (the point is on a fold; see the module
    /// docs); 0 almost everywhere.
    pub unresolved_leaves: u32,
    /// The scan gave up (more than its cell budget): the images are not known.
    pub unscanned: bool,
    /// Cells the scan visited (its cost).
    pub cells: usize,
}

impl OracleImages {
    /// Whether the answer is complete: scanned, with no fold left unresolved.
    pub fn is_certain(&self) -> bool {
        !self.unscanned && self.unresolved_leaves == 0
    }
}

impl OracleWater<'_> {
    fn covers(&self, x: f64, z: f64) -> bool {
        let e = &self.extent;
        x >= e.min_x && x <= e.max_x && z >= e.min_z && z <= e.max_z
    }

    /// The bounds over `[min, max]`: the global ones, tightened by the local ones where given.
    fn region(&self, min: DVec2, max: DVec2) -> RegionBounds {
        let global = RegionBounds {
            height_range_m: self.height_range_m,
            slope_bound: self.slope_bound,
            curvature_bound: self.curvature_bound,
        };
        let Some(local) = self.local_bounds else {
            return global;
        };
        let l = local.over(min, max);
        RegionBounds {
            height_range_m: (
                l.height_range_m.0.max(global.height_range_m.0),
                l.height_range_m.1.min(global.height_range_m.1),
            ),
            slope_bound: l.slope_bound.min(global.slope_bound),
            curvature_bound: l.curvature_bound.min(global.curvature_bound),
        }
    }

    fn surface_point(&self, xz: DVec2) -> DVec3 {
        DVec3::new(xz.x, self.height_field.height(xz.x, xz.y), xz.y)
    }

    /// `grad L` and `Hess L` at `xz`.
    fn derivatives(&self, eye: DVec3, point: DVec3, xz: DVec2) -> (DVec2, DMat2) {
        let (h, (hx, hz), (hxx, hxz, hzz)) = self.height_field.height_derivatives(xz.x, xz.y);
        let s = DVec3::new(xz.x, h, xz.y);
        let (to_eye, to_point) = (s - eye, s - point);
        let (de, dv) = (to_eye.length(), to_point.length());
        let (u, w) = (to_eye / de, to_point / dv);
        let (n1, n2) = (self.n_above, self.n_below);
        let a = n1 * u + n2 * w;
        let tangent_x = DVec3::new(1.0, hx, 0.0);
        let tangent_z = DVec3::new(0.0, hz, 1.0);
        // M q = n1 (q - u (u.q)) / de + n2 (q - w (w.q)) / dv.
        let m = |q: DVec3| n1 * (q - u * u.dot(q)) / de + n2 * (q - w * w.dot(q)) / dv;
        let (mx, mz) = (m(tangent_x), m(tangent_z));
        let xx = tangent_x.dot(mx) + a.y * hxx;
        let xz_ = tangent_x.dot(mz) + a.y * hxz;
        let zz = tangent_z.dot(mz) + a.y * hzz;
        (
            DVec2::new(a.dot(tangent_x), a.dot(tangent_z)),
            DMat2::from_cols(DVec2::new(xx, xz_), DVec2::new(xz_, zz)),
        )
    }

    fn optical_path(&self, eye: DVec3, point: DVec3, s: DVec3) -> f64 {
        self.n_above * (s - eye).length() + self.n_below * (point - s).length()
    }

    /// Plain Newton on `grad L` from `start`, each step capped at `cap_m`; the root or None.
    fn newton(&self, eye: DVec3, point: DVec3, start: DVec2, cap_m: f64) -> Option<DVec2> {
        let tolerance = GRADIENT_TOLERANCE * (self.n_above + self.n_below);
        let mut xz = start;
        for _ in 0..NEWTON_ITERATIONS {
            let (g, h) = self.derivatives(eye, point, xz);
            if !(g.is_finite() && h.is_finite()) {
                return None;
            }
            if g.length() <= tolerance {
                return Some(xz);
            }
            if h.determinant().abs() < 1e-300 {
                return None;
            }
            let mut step = -(h.inverse() * g);
            if step.length() > cap_m {
                step *= cap_m / step.length();
            }
            xz += step;
        }
        let (g, _) = self.derivatives(eye, point, xz);
        (g.length() <= tolerance).then_some(xz)
    }

    /// The part `[s0, s1]` of `from + s d`, s in `[0, 1]`, over the extent (a straight segment
    /// meets a rectangle in one interval); None when it misses it.
    fn over_extent(&self, from: DVec3, d: DVec3) -> Option<(f64, f64)> {
        let e = &self.extent;
        let (mut s0, mut s1) = (0.0_f64, 1.0_f64);
        for (o, v, lo, hi) in [
            (from.x, d.x, e.min_x, e.max_x),
            (from.z, d.z, e.min_z, e.max_z),
        ] {
            if v == 0.0 {
                if o < lo || o > hi {
                    return None;
                }
            } else {
                let (a, b) = ((lo - o) / v, (hi - o) / v);
                s0 = s0.max(a.min(b));
                s1 = s1.min(a.max(b));
            }
        }
        (s0 <= s1).then_some((s0, s1))
    }

    /// Whether the segment from the sight point `from` (on the surface) to `to` stays above
    /// (`side = 1`) or below (`side = -1`) the surface within `tolerance_m` wherever it is over
    /// the extent. Near `from` the clearance `f` starts at the tolerance and rises with slope
    /// `f'(0) > 0` (the caller checked the sight ray's side), so `f >= f(0) + f'(0) s - K s^2 / 2`
    /// (`K = C |d_xz|^2`) keeps it positive up to `s = 2 f'(0) / K`; beyond, pieces are split
    /// until on each the clearance at its ends exceeds what the Lipschitz bound
    /// `|d_y| + G |d_xz|` lets it lose between them. A piece that cannot be proven clear by the
    /// time it is 1e-12 of the segment long grazes the surface: blocked.
    fn segment_clear(&self, from: DVec3, to: DVec3, side: f64, tolerance_m: f64) -> bool {
        let d = to - from;
        let Some((start, end)) = self.over_extent(from, d) else {
            return true;
        };
        let horizontal = d.x.hypot(d.z);
        let lipschitz = d.y.abs() + self.slope_bound * horizontal;
        let curvature = self.curvature_bound * horizontal * horizontal;
        let clearance = |s: f64| {
            let p = from + d * s;
            side * (p.y - self.height_field.height(p.x, p.z)) + tolerance_m
        };
        let (_, (hx, hz)) = self.height_field.height_and_gradient(from.x, from.z);
        let rise = side * (d.y - hx * d.x - hz * d.z);
        let near_end = if start > 0.0 {
            // `from` is off the extent (it never is for an image): nothing proven near it.
            start
        } else if rise > 0.0 && curvature > 0.0 {
            (2.0 * rise / curvature).min(end)
        } else if rise > 0.0 {
            end
        } else {
            return false;
        };
        if near_end >= end {
            return true;
        }
        let mut pieces = vec![(near_end, end, clearance(near_end), clearance(end))];
        while let Some((s0, s1, f0, f1)) = pieces.pop() {
            if f0 < 0.0 || f1 < 0.0 {
                return false;
            }
            if f0 + f1 >= lipschitz * (s1 - s0) {
                continue;
            }
            if self.local_bounds.is_some() {
                // The piece's own slope bound, over the box its horizontal part spans.
                let (a, b) = (from + d * s0, from + d * s1);
                let slope = self
                    .region(
                        DVec2::new(a.x.min(b.x), a.z.min(b.z)),
                        DVec2::new(a.x.max(b.x), a.z.max(b.z)),
                    )
                    .slope_bound;
                if f0 + f1 >= (d.y.abs() + slope * horizontal) * (s1 - s0) {
                    continue;
                }
            }
            if s1 - s0 < 1e-12 {
                return false;
            }
            let mid = 0.5 * (s0 + s1);
            let fm = clearance(mid);
            pieces.push((s0, mid, f0, fm));
            pieces.push((mid, s1, fm, f1));
        }
        true
    }

    /// Every image of `point` seen from `eye`.
    pub fn images(&self, eye: DVec3, point: DVec3) -> OracleImages {
        let mut out = OracleImages::default();
        if !self.covers(point.x, point.z) {
            return out;
        }
        let depth_m = self.height_field.height(point.x, point.z) - point.y;
        if depth_m <= 0.0 {
            return out;
        }
        let (n1, n2) = (self.n_above, self.n_below);
        let g = self.slope_bound;
        // Where the sight point can be (module docs); the whole extent if the bound says nothing.
        let refracted_angle = (n1 / n2).min(1.0).asin();
        let angle = refracted_angle + g.atan();
        let reach_m = if angle < 0.5 * std::f64::consts::PI - 1e-9 {
            (self.height_range_m.1 - point.y) * angle.tan()
        } else {
            f64::INFINITY
        };
        let e = &self.extent;
        let lo = DVec2::new(
            (point.x - reach_m).max(e.min_x),
            (point.z - reach_m).max(e.min_z),
        );
        let hi = DVec2::new(
            (point.x + reach_m).min(e.max_x),
            (point.z + reach_m).min(e.max_z),
        );
        // Distance bounds: from a point at vertical clearance c over (under) the surface, every
        // surface point is at least c / sqrt(1 + G^2) away.
        let tilt = (1.0 + g * g).sqrt();
        let d_v = depth_m / tilt;
        let eye_clearance =
            (eye.y - self.height_field.height(eye.x, eye.z)).max(eye.y - self.height_range_m.1);
        if eye_clearance <= 0.0 {
            out.unscanned = true;
            return out;
        }
        let d_e = eye_clearance / tilt;
        let half = 0.5 * (hi - lo).max_element();
        let centre = 0.5 * (lo + hi);
        // Cells (centre, half-size) still to examine; leaves (centres) left after the scan.
        let mut cells = vec![(centre, half)];
        let mut leaves: Vec<(DVec2, f64)> = Vec::new();
        while let Some((c, r)) = cells.pop() {
            out.cells += 1;
            if out.cells > MAX_CELLS {
                out.unscanned = true;
                return out;
            }
            // Cells reaching past the region are clipped by the region test of the solutions.
            let (grad, _) = self.derivatives(eye, point, c);
            if !grad.is_finite() {
                out.unscanned = true;
                return out;
            }
            // Lambda over this cell: the bounds over it, and the distances from the eye and the
            // point to its surface points bounded from below by the global bound, the vertical
            // clearance to the cell's height range and the horizontal gap to the cell.
            let b = self.region(c - DVec2::splat(r), c + DVec2::splat(r));
            let gap = |q: DVec3| (DVec2::new(q.x, q.z) - c).abs() - DVec2::splat(r);
            let gap = |q: DVec3| gap(q).max(DVec2::ZERO).length();
            let d_e_cell = d_e.max(eye.y - b.height_range_m.1).max(gap(eye));
            let d_v_cell = d_v.max(b.height_range_m.0 - point.y).max(gap(point));
            // No sight point in a cell farther from the point than a refracted ray leaving it can
            // travel sideways on its way down (the module docs' region, with the cell's bounds).
            let cell_angle = refracted_angle + b.slope_bound.atan();
            if cell_angle < 0.5 * std::f64::consts::PI - 1e-9
                && gap(point) > (b.height_range_m.1 - point.y) * cell_angle.tan()
            {
                continue;
            }
            let lambda = (1.0 + b.slope_bound * b.slope_bound) * (n1 / d_e_cell + n2 / d_v_cell)
                + (n1 + n2) * b.curvature_bound;
            if grad.length() > lambda * r * std::f64::consts::SQRT_2 {
                continue;
            }
            if r <= LEAF_HALF_SIZE_M {
                leaves.push((c, r));
                continue;
            }
            let q = 0.5 * r;
            for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                cells.push((c + DVec2::new(sx, sz) * q, q));
            }
        }
        // Newton from each leaf. A leaf holding a stationary point is within a micrometre of it,
        // where Newton converges unless the point is degenerate (a fold); a leaf whose solve
        // fails is unresolved. (Leaves near a root that hold none converge to it, or to another.)
        let mut roots: Vec<DVec2> = Vec::new();
        for &(c, r) in &leaves {
            match self.newton(eye, point, c, 8.0 * r) {
                Some(root) => {
                    if !roots
                        .iter()
                        .any(|q| (*q - root).length() <= 2.0 * LEAF_HALF_SIZE_M)
                    {
                        roots.push(root);
                    }
                }
                None => out.unresolved_leaves += 1,
            }
        }
        for xz in roots {
            if !(xz.x >= lo.x && xz.x <= hi.x && xz.y >= lo.y && xz.y <= hi.y) {
                continue;
            }
            let s = self.surface_point(xz);
            let (hx, hz) = self.height_field.gradient(xz.x, xz.y);
            let up = DVec3::new(-hx, 1.0, -hz);
            if (s - eye).dot(up) >= 0.0 || (point - s).dot(up) >= 0.0 {
                continue;
            }
            let tolerance_m = 1e-9 * (1.0 + (eye - point).length() + s.abs().max_element());
            if !(self.segment_clear(s, eye, 1.0, tolerance_m)
                && self.segment_clear(s, point, -1.0, tolerance_m))
            {
                continue;
            }
            let (_, hessian) = self.derivatives(eye, point, xz);
            out.images.push(OracleImage {
                sight_point: s,
                optical_path_m: self.optical_path(eye, point, s),
                hessian_determinant: hessian.determinant(),
            });
        }
        out.images
            .sort_by(|a, b| a.optical_path_m.total_cmp(&b.optical_path_m));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refraction::flat::flat_sight_point;
    use crate::refraction::rays::refract_exact;
    use crate::water::{FlatHeightField, FnHeightField};

    const N_AIR: f64 = 1.0;
    const N_WATER: f64 = 1.333;

    fn extent(half_m: f64) -> MembraneGrid {
        MembraneGrid {
            min_x: -half_m,
            min_z: -half_m,
            max_x: half_m,
            max_z: half_m,
            cells_x: 1,
            cells_z: 1,
        }
    }

    fn water<'a>(field: &'a dyn HeightField, range: (f64, f64), g: f64, c: f64) -> OracleWater<'a> {
        OracleWater {
            height_field: field,
            extent: extent(5.0),
            height_range_m: range,
            slope_bound: g,
            curvature_bound: c,
            n_above: N_AIR,
            n_below: N_WATER,
            local_bounds: None,
        }
    }

    /// A Gaussian ridge `a exp(-(x / w)^2)` along z with its exact bounds.
    fn ridge(a: f64, w: f64) -> (FnHeightField, f64, f64) {
        let field = FnHeightField::new(move |x, _| a * (-(x * x) / (w * w)).exp())
            .with_gradient(move |x, _| (-2.0 * a * x / (w * w) * (-(x * x) / (w * w)).exp(), 0.0));
        (
            field,
            a * (2.0f64 / std::f64::consts::E).sqrt() / w,
            2.0 * a / (w * w),
        )
    }

    /// Snell's law at S in vector form (ALGORITHM §1): the refracted sight ray points at V.
    fn snell_mismatch(field: &dyn HeightField, eye: DVec3, point: DVec3, s: DVec3) -> f64 {
        let normal = field.normal(s.x, s.z);
        refract_exact((s - eye).normalize(), normal, N_AIR / N_WATER)
            .map_or(f64::INFINITY, |t| (t - (point - s).normalize()).length())
    }

    /// The oracle shares nothing with the code it checks: its only imports are glam and the
    /// height field's definition.
    #[test]
    fn imports_nothing_from_the_renderer() {
        let source = include_str!("oracle.rs");
        let code = &source[..source.find("#[cfg(test)]").unwrap()];
        let imports: Vec<&str> = code.lines().filter(|l| l.starts_with("use ")).collect();
        assert_eq!(
            imports,
            [
                "use glam::{DMat2, DVec2, DVec3};",
                "use crate::water::{HeightField, MembraneGrid};"
            ]
        );
        assert!(!code.contains("crate::refraction") && !code.contains("crate::reference"));
    }

    /// Flat water: one image, the bisection oracle's sight point.
    #[test]
    fn flat_water_has_the_one_image_bisection_finds() {
        let flat = FlatHeightField { level_m: 0.0 };
        let w = water(&flat, (0.0, 0.0), 0.0, 0.0);
        let mut rng = crate::seeded::SplitMix64::new(0x0_4AC1E);
        for _ in 0..50 {
            let eye = DVec3::new(rng.range(-6.0, 6.0), rng.range(0.3, 4.0), -6.0);
            let point = DVec3::new(
                rng.range(-4.0, 4.0),
                rng.range(-3.0, -0.05),
                rng.range(-4.0, 4.0),
            );
            let found = w.images(eye, point);
            assert!(found.is_certain(), "{found:?}");
            assert_eq!(found.images.len(), 1, "{found:?}");
            let expected = flat_sight_point(eye, point, 0.0, N_AIR, N_WATER);
            assert!((found.images[0].sight_point - expected).length() < 1e-9);
        }
    }

    /// Under a steep ridge, a deep point has three images (the ridge is a lens); each obeys
    /// Snell's law; a point beside it has one. A point behind the ridge seen from a low eye has
    /// no image through the ridge's far flank: the crest blocks the path.
    #[test]
    fn a_ridge_gives_three_images_under_it_and_blocks_behind_it() {
        let (field, g, c) = ridge(0.3, 0.3);
        let w = water(&field, (0.0, 0.3), g, c);
        let eye = DVec3::new(0.0, 2.5, -1.5);
        let deep = DVec3::new(0.0, -2.0, 0.4);
        let found = w.images(eye, deep);
        assert!(found.is_certain(), "{found:?}");
        assert_eq!(found.images.len(), 3, "{found:?}");
        for image in &found.images {
            let mismatch = snell_mismatch(&field, eye, deep, image.sight_point);
            assert!(mismatch < 1e-9, "{image:?}: {mismatch}");
        }
        let beside = w.images(eye, DVec3::new(-3.0, -0.5, 0.4));
        assert_eq!(beside.images.len(), 1, "{beside:?}");
        // A low eye on the -x side: the far flank's sight points are hidden by the crest.
        let low_eye = DVec3::new(-4.0, 0.35, 0.0);
        let behind = DVec3::new(1.0, -0.3, 0.0);
        for image in &w.images(low_eye, behind).images {
            assert!(image.sight_point.x < 0.0, "seen past the crest: {image:?}");
        }
    }
}
