//! Ripples: the state of the simulated water waves on a grid of nodes over the water (height and
//! vertical velocity per node), their settings, and the smooth height field through the nodes that
//! the membrane, the refraction and the reference all sample (one surface for every method).
//! The waves' dynamics — linear water waves with their dispersion relation, integrated exactly
//! per mode of a cosine transform — are in [`super::spectral`].

use crate::water::HeightField;

pub use super::spectral::RippleStepper;

/// What happens to ripples at the edge of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Border {
    /// The pool's walls: zero normal flux, so ripples bounce off them (exact: the cosine modes of
    /// the transform are the walls' own modes).
    Reflect,
    /// A sponge layer whose damping rises quadratically toward the edge: ripples leave the grid
    /// (about 7 % comes back from the walls behind it).
    Absorb,
}

/// Surface tension of clean water against air at about 20 C, N/m.
pub const WATER_SURFACE_TENSION_N_PER_M: f64 = 0.0728;
/// Density of water, kg/m^3.
pub const WATER_DENSITY_KG_PER_M3: f64 = 1000.0;

/// The simulation's settings as the scene states them (all in SI units).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RippleSettings {
    /// Nodes along x and z of the ripple grid (a node every `spacing_m`, the first and last ones on
    /// the walls).
    pub nodes_x: u32,
    pub nodes_z: u32,
    /// (x, z) of the node (0, 0), metres.
    pub min_x: f64,
    pub min_z: f64,
    pub spacing_m: f64,
    /// Still-water depth (the pool's), metres: the `h` of the dispersion relation.
    pub depth_m: f64,
    pub surface_tension_n_per_m: f64,
    pub density_kg_per_m3: f64,
    /// Amplitudes fall as `exp(-damping_per_s t / 2)` (the equation's `gamma`), every wavelength alike.
    pub damping_per_s: f64,
    /// The band limit, rad/m: no mode of wavenumber above it carries energy, and the bodies' source
    /// is tapered to zero there (see [`super::spectral`]).
    pub cutoff_per_m: f64,
    pub border: Border,
    /// Width of the sponge layer of an absorbing border, in nodes.
    pub sponge_nodes: u32,
    /// Extra damping at the very edge of an absorbing border, per second.
    pub sponge_damping_per_s: f64,
}

impl RippleSettings {
    pub fn node_count(&self) -> usize {
        self.nodes_x as usize * self.nodes_z as usize
    }

    /// The dispersion relation of these waves.
    pub fn dispersion(&self) -> super::spectral::Dispersion {
        super::spectral::Dispersion {
            gravity_m_per_s2: crate::water::GRAVITY_M_PER_S2,
            tension_over_density_m3_per_s2: self.surface_tension_n_per_m / self.density_kg_per_m3,
            depth_m: self.depth_m,
        }
    }

    /// The sponge's damping per node (per second; zero outside the layer and when reflecting).
    pub(crate) fn sponge_per_node(&self) -> Vec<f64> {
        let (nx, nz) = (self.nodes_x as usize, self.nodes_z as usize);
        let mut damping = vec![0.0; nx * nz];
        if self.border == Border::Absorb && self.sponge_nodes > 0 {
            let width = self.sponge_nodes as f64;
            for iz in 0..nz {
                for ix in 0..nx {
                    let to_edge = ix.min(nx - 1 - ix).min(iz).min(nz - 1 - iz) as f64;
                    if to_edge < width {
                        let depth_into_sponge = (width - to_edge) / width;
                        damping[iz * nx + ix] =
                            self.sponge_damping_per_s * depth_into_sponge * depth_into_sponge;
                    }
                }
            }
        }
        damping
    }
}

/// The ripple field at one instant: height and vertical velocity per node, row-major (z then x).
/// The velocity is the part of the surface's vertical velocity the flow carries (the mode
/// variable `b` of [`super::spectral`]); a body's source adds to it while it pushes.
#[derive(Clone, Debug, PartialEq)]
pub struct RippleState {
    pub settings: RippleSettings,
    pub height_m: Vec<f32>,
    pub velocity_m_per_s: Vec<f32>,
}

impl RippleState {
    /// Still water.
    pub fn calm(settings: RippleSettings) -> Self {
        RippleState {
            settings,
            height_m: vec![0.0; settings.node_count()],
            velocity_m_per_s: vec![0.0; settings.node_count()],
        }
    }

    /// Largest |height| over the grid, metres.
    pub fn max_abs_height_m(&self) -> f32 {
        self.height_m.iter().fold(0.0f32, |m, h| m.max(h.abs()))
    }

    /// The ripple height field: Catmull-Rom bicubic through the nodes (C1, so normals are
    /// continuous), zero outside the grid.
    pub fn field(&self) -> RippleField<'_> {
        RippleField { state: self }
    }
}

/// [`RippleState`] as a smooth height field (ripple part only; add the waves to it).
#[derive(Clone, Copy)]
pub struct RippleField<'a> {
    state: &'a RippleState,
}

/// Catmull-Rom weights and their derivatives (per unit parameter) at fraction `t` in [0, 1).
fn catmull_rom(t: f64) -> ([f64; 4], [f64; 4]) {
    let (t2, t3) = (t * t, t * t * t);
    (
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ],
        [
            0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
            0.5 * (9.0 * t2 - 10.0 * t),
            0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
            0.5 * (3.0 * t2 - 2.0 * t),
        ],
    )
}

/// Node index `i` of `n` along an axis, mirrored about the edge nodes (-1 -> 1, n -> n - 2): the
/// even extension at a wall, the symmetry of the cosine modes the simulation is made of, so the
/// field's slope across a wall is zero as the walls' boundary condition says.
fn mirrored(i: i64, n: i64) -> usize {
    let last = n - 1;
    let i = if i < 0 { -i } else { i };
    let i = if i > last { 2 * last - i } else { i };
    i.clamp(0, last) as usize
}

/// Second derivatives (per unit parameter squared) of the Catmull-Rom weights at fraction `t`.
fn catmull_rom_second(t: f64) -> [f64; 4] {
    [2.0 - 3.0 * t, 9.0 * t - 5.0, 4.0 - 9.0 * t, 3.0 * t - 1.0]
}

impl RippleField<'_> {
    /// The cell of the grid holding (x, z): the 4 x 4 nodes its bicubic weighs (indices into the
    /// row-major heights, mirrored at the walls: x offsets and z row starts) and the fractions
    /// within the cell; None outside the grid (the field is zero there).
    #[inline(always)]
    fn cell(&self, x: f64, z: f64) -> Option<([usize; 4], [usize; 4], f64, f64)> {
        let s = &self.state.settings;
        let (nx, nz) = (s.nodes_x as i64, s.nodes_z as i64);
        let gx = (x - s.min_x) / s.spacing_m;
        let gz = (z - s.min_z) / s.spacing_m;
        if !(gx >= 0.0 && gz >= 0.0 && gx <= (nx - 1) as f64 && gz <= (nz - 1) as f64) {
            return None;
        }
        // Truncation is the floor here: both are >= 0.
        let (cx, cz) = (
            (gx as i64).min(nx - 2).max(0),
            (gz as i64).min(nz - 2).max(0),
        );
        let columns = std::array::from_fn(|i| mirrored(cx - 1 + i as i64, nx));
        let rows = std::array::from_fn(|j| mirrored(cz - 1 + j as i64, nz) * nx as usize);
        Some((columns, rows, gx - cx as f64, gz - cz as f64))
    }

    /// The 4 nodes of row `row` (a row start) at `columns`.
    #[inline(always)]
    fn row(&self, row: usize, columns: &[usize; 4]) -> [f64; 4] {
        let heights = &self.state.height_m[row..];
        columns.map(|c| heights[c] as f64)
    }

    /// Height, gradient and Hessian at (x, z) in one pass over the 4 x 4 nodes: per row the x
    /// weights' sums, then the z weights over the rows. The bicubic is C1: the Hessian is that of
    /// the cell containing (x, z) (it jumps across node lines).
    fn sample_derivatives(&self, x: f64, z: f64) -> (f64, (f64, f64), (f64, f64, f64)) {
        let Some((columns, rows, tx, tz)) = self.cell(x, z) else {
            return (0.0, (0.0, 0.0), (0.0, 0.0, 0.0));
        };
        let ((wx, dwx), ddwx) = (catmull_rom(tx), catmull_rom_second(tx));
        let ((wz, dwz), ddwz) = (catmull_rom(tz), catmull_rom_second(tz));
        let mut sums = [0.0; 6];
        for j in 0..4 {
            let u = self.row(rows[j], &columns);
            let dot = |w: &[f64; 4]| w[0] * u[0] + w[1] * u[1] + w[2] * u[2] + w[3] * u[3];
            let (value, slope, curvature) = (dot(&wx), dot(&dwx), dot(&ddwx));
            sums[0] += wz[j] * value;
            sums[1] += wz[j] * slope;
            sums[2] += dwz[j] * value;
            sums[3] += wz[j] * curvature;
            sums[4] += dwz[j] * slope;
            sums[5] += ddwz[j] * value;
        }
        // Divided as `sample` divides, so the two agree to the bit.
        let (d, d2) = (
            self.state.settings.spacing_m,
            self.state.settings.spacing_m * self.state.settings.spacing_m,
        );
        (
            sums[0],
            (sums[1] / d, sums[2] / d),
            (sums[3] / d2, sums[4] / d2, sums[5] / d2),
        )
    }

    /// (height, d/dx, d/dz) at (x, z), summed as [`Self::sample_derivatives`] sums them.
    fn sample(&self, x: f64, z: f64) -> (f64, f64, f64) {
        let Some((columns, rows, tx, tz)) = self.cell(x, z) else {
            return (0.0, 0.0, 0.0);
        };
        let (wx, dwx) = catmull_rom(tx);
        let (wz, dwz) = catmull_rom(tz);
        let (mut height, mut ddx, mut ddz) = (0.0, 0.0, 0.0);
        for j in 0..4 {
            let u = self.row(rows[j], &columns);
            let dot = |w: &[f64; 4]| w[0] * u[0] + w[1] * u[1] + w[2] * u[2] + w[3] * u[3];
            let (value, slope) = (dot(&wx), dot(&dwx));
            height += wz[j] * value;
            ddx += wz[j] * slope;
            ddz += dwz[j] * value;
        }
        let d = self.state.settings.spacing_m;
        (height, ddx / d, ddz / d)
    }
}

impl HeightField for RippleField<'_> {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.sample(x, z).0
    }
    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        let (_, gx, gz) = self.sample(x, z);
        (gx, gz)
    }
    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        self.sample_derivatives(x, z).2
    }
    fn height_derivatives(&self, x: f64, z: f64) -> (f64, (f64, f64), (f64, f64, f64)) {
        self.sample_derivatives(x, z)
    }
    fn height_and_gradient(&self, x: f64, z: f64) -> (f64, (f64, f64)) {
        let (h, gx, gz) = self.sample(x, z);
        (h, (gx, gz))
    }
}

/// Largest over t in [0, 1] of the sums of |Catmull-Rom weights|, of |first-derivative weights|
/// and of |second-derivative weights|, rounded up (checked by a test against a fine sampling).
const CATMULL_ROM_ABS_SUMS: (f64, f64, f64) = (1.25, 3.0, 12.0);

/// Bounds of the field wherever every node its bicubic weighs there has |height| <= `u`
/// (metres), on a grid of `spacing_m`: (largest |height|, largest |grad h|, largest second
/// derivative along a unit horizontal direction). The field is a weighted sum of 4 x 4 nodes, so
/// each derivative is at most the sum of |weights| times `u`:
/// - |h| <= w^2 u (Catmull-Rom overshoots the nodes by at most a quarter per axis);
/// - |d/dx| <= dw w u / spacing, so |grad| <= sqrt(2) of that;
/// - |u^T H u| <= |h_xx| + 2 |h_xz| + |h_zz| <= (2 ddw w + 2 dw^2) u / spacing^2.
///
/// One formula for the whole plane ([`RippleField::slope_and_curvature_bounds`]) and for its
/// tiles ([`super::ripple_bounds::RippleBounds`]).
pub(crate) fn bounds_for_node_height(u: f64, spacing_m: f64) -> (f64, f64, f64) {
    let (w, dw, ddw) = CATMULL_ROM_ABS_SUMS;
    (
        w * w * u,
        std::f64::consts::SQRT_2 * dw * w * u / spacing_m,
        (2.0 * ddw * w + 2.0 * dw * dw) * u / (spacing_m * spacing_m),
    )
}

impl RippleField<'_> {
    /// The state the field interpolates.
    pub fn state(&self) -> &RippleState {
        self.state
    }

    /// Largest |height| of the field, metres (the nodes': Catmull-Rom overshoots them by at most
    /// a quarter, see [`bounds_for_node_height`]).
    pub fn max_abs_height_m(&self) -> f64 {
        bounds_for_node_height(
            self.state.max_abs_height_m() as f64,
            self.state.settings.spacing_m,
        )
        .0
    }

    /// Bounds over the whole plane: the largest |grad h| and the largest second directional
    /// derivative along a unit horizontal direction, from the largest |node height|
    /// ([`bounds_for_node_height`]). Conservative, which is what a root finder stepping along a
    /// ray needs; [`super::ripple_bounds::RippleBounds`] gives them per part of the plane.
    pub fn slope_and_curvature_bounds(&self) -> (f64, f64) {
        let (_, slope, curvature) = bounds_for_node_height(
            self.state.max_abs_height_m() as f64,
            self.state.settings.spacing_m,
        );
        (slope, curvature)
    }
}

/// Two height fields added: the analytic waves plus the ripples.
pub struct SumHeightField<'a> {
    pub base: &'a dyn HeightField,
    pub ripples: Option<RippleField<'a>>,
}

impl HeightField for SumHeightField<'_> {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.base.height(x, z) + self.ripples.map_or(0.0, |r| r.height(x, z))
    }
    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        let (bx, bz) = self.base.gradient(x, z);
        let (rx, rz) = self.ripples.map_or((0.0, 0.0), |r| r.gradient(x, z));
        (bx + rx, bz + rz)
    }
    fn height_and_gradient(&self, x: f64, z: f64) -> (f64, (f64, f64)) {
        let (bh, (bx, bz)) = self.base.height_and_gradient(x, z);
        match self.ripples {
            None => (bh, (bx, bz)),
            Some(r) => {
                let (rh, (rx, rz)) = r.height_and_gradient(x, z);
                (bh + rh, (bx + rx, bz + rz))
            }
        }
    }

    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        // Both analytic: the waves' and the ripples' bicubic's (per cell).
        let (bxx, bxz, bzz) = self.base.hessian(x, z);
        let (rxx, rxz, rzz) = self.ripples.map_or((0.0, 0.0, 0.0), |r| r.hessian(x, z));
        (bxx + rxx, bxz + rxz, bzz + rzz)
    }
    fn height_derivatives(&self, x: f64, z: f64) -> (f64, (f64, f64), (f64, f64, f64)) {
        let (h, (gx, gz), (xx, xz, zz)) = self.base.height_derivatives(x, z);
        match self.ripples {
            None => (h, (gx, gz), (xx, xz, zz)),
            Some(r) => {
                let (rh, (rgx, rgz), (rxx, rxz, rzz)) = r.height_derivatives(x, z);
                (h + rh, (gx + rgx, gz + rgz), (xx + rxx, xz + rxz, zz + rzz))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `nodes x nodes` over [-1, 1]^2.
    fn settings(nodes: u32) -> RippleSettings {
        crate::sim::spectral::tests::settings(nodes, nodes, 2.0 / (nodes - 1) as f64)
    }

    /// A narrow Gaussian bump of height 1 cm and width `sigma_m` at (x, z), at rest (the spectral
    /// solver's tests build theirs the same way).
    fn impulse(settings: RippleSettings, x: f64, z: f64, sigma_m: f64) -> RippleState {
        crate::sim::spectral::tests::bump(settings, x, z, sigma_m)
    }

    #[test]
    fn catmull_rom_weight_sums_bound_every_fraction() {
        let (w, dw, ddw) = CATMULL_ROM_ABS_SUMS;
        let mut largest = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..=10_000 {
            let t = i as f64 / 10_000.0;
            let (weights, slopes) = catmull_rom(t);
            let curvatures = [
                0.5 * (-6.0 * t + 4.0),
                0.5 * (18.0 * t - 10.0),
                0.5 * (-18.0 * t + 8.0),
                0.5 * (6.0 * t - 2.0),
            ];
            // The second-derivative weights are the derivative of the slope weights.
            let e = 1e-6;
            let (_, ahead) = catmull_rom(t + e);
            for k in 0..4 {
                assert!(((ahead[k] - slopes[k]) / e - curvatures[k]).abs() < 1e-4);
            }
            let sum = |v: [f64; 4]| v.iter().map(|x| x.abs()).sum::<f64>();
            largest.0 = largest.0.max(sum(weights));
            largest.1 = largest.1.max(sum(slopes));
            largest.2 = largest.2.max(sum(curvatures));
        }
        assert!(
            largest.0 <= w && largest.1 <= dw && largest.2 <= ddw,
            "{largest:?}"
        );
        // Tight, so the root finder's steps are not needlessly short.
        assert!(largest.0 > 0.99 * w && largest.1 > 0.99 * dw && largest.2 > 0.99 * ddw);
    }

    #[test]
    fn ripple_bounds_hold_on_a_bumpy_field() {
        let s = settings(41);
        let state = impulse(s, 0.1, -0.2, 0.12);
        let field = state.field();
        let (slope, curvature) = field.slope_and_curvature_bounds();
        let e = 1e-5;
        for i in 0..2_000 {
            let x = -0.95 + 1.9 * ((i * 37 % 2000) as f64 / 2000.0);
            let z = -0.95 + 1.9 * ((i * 91 % 2000) as f64 / 2000.0);
            let (gx, gz) = field.gradient(x, z);
            assert!(gx.hypot(gz) <= slope);
            let u = glam::DVec2::new((i as f64).cos(), (i as f64).sin());
            let along = |d: f64| field.height(x + d * u.x, z + d * u.y);
            let second = (along(e) - 2.0 * along(0.0) + along(-e)) / (e * e);
            assert!(
                second.abs() <= curvature * 1.001 + 1e-3,
                "{second} vs {curvature}"
            );
        }
    }

    #[test]
    fn the_field_interpolates_nodes_and_its_gradient_is_the_derivative() {
        let s = settings(21);
        let state = impulse(s, 0.1, 0.05, 0.3);
        let field = state.field();
        // Through the nodes exactly.
        for at in [0usize, 17, 220, 440] {
            let x = s.min_x + (at % 21) as f64 * s.spacing_m;
            let z = s.min_z + (at / 21) as f64 * s.spacing_m;
            assert!((field.height(x, z) - state.height_m[at] as f64).abs() < 1e-9);
        }
        // Gradient against central differences, away from nodes.
        for (x, z) in [(0.013, -0.27), (0.5, 0.61), (-0.77, 0.33)] {
            let e = 1e-6;
            let (gx, gz) = field.gradient(x, z);
            let fx = (field.height(x + e, z) - field.height(x - e, z)) / (2.0 * e);
            let fz = (field.height(x, z + e) - field.height(x, z - e)) / (2.0 * e);
            assert!(
                (gx - fx).abs() < 1e-6 && (gz - fz).abs() < 1e-6,
                "{gx} {fx} {gz} {fz}"
            );
        }
        // Zero outside.
        assert_eq!(field.height(5.0, 0.0), 0.0);
    }

    /// The analytic Hessian (and the fused evaluation) against differences of the gradient,
    /// inside cells (the C1 bicubic's second derivatives jump across node lines).
    #[test]
    fn the_hessian_is_the_derivative_of_the_gradient_inside_a_cell() {
        let s = settings(21);
        let state = impulse(s, 0.1, 0.05, 0.3);
        let field = state.field();
        // Node spacing 0.1 m from -1: these points are >= 0.02 m from every node line.
        for (x, z) in [(0.035, -0.265), (0.55, 0.645), (-0.775, 0.33), (0.14, 0.07)] {
            let e = 1e-6;
            let (xx, xz, zz) = field.hessian(x, z);
            let (px, pz) = field.gradient(x + e, z);
            let (mx, mz) = field.gradient(x - e, z);
            let (qx, qz) = field.gradient(x, z + e);
            let (rx, rz) = field.gradient(x, z - e);
            let fd = [
                (px - mx) / (2.0 * e),
                (pz - mz) / (2.0 * e),
                (qx - rx) / (2.0 * e),
                (qz - rz) / (2.0 * e),
            ];
            // Curvatures here reach ~1 per m (0.01 m bump of width 0.3 m); differences of f32
            // node heights are good to ~1e-6.
            let close = |a: f64, b: f64| (a - b).abs() < 1e-5 * (1.0 + a.abs());
            assert!(close(xx, fd[0]) && close(xz, fd[1]), "{xx} {xz} vs {fd:?}");
            assert!(close(xz, fd[2]) && close(zz, fd[3]), "{xz} {zz} vs {fd:?}");
            let (h, (gx, gz), hessian) = field.height_derivatives(x, z);
            assert_eq!(
                (h, gx, gz),
                (
                    field.height(x, z),
                    field.gradient(x, z).0,
                    field.gradient(x, z).1
                )
            );
            assert_eq!(hessian, (xx, xz, zz));
        }
        // Not trivially zero: the bump is curved there.
        assert!(field.hessian(0.14, 0.07).0.abs() > 1e-3);
    }
}
