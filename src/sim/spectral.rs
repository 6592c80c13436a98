//! The ripples' dynamics: linear water waves over a flat floor, solved on the whole grid in the
//! modes of a cosine transform and integrated exactly, mode by mode, over each frame interval.
//!
//! **The model.** Small waves on water of still depth `h` (inviscid, irrotational): a mode of
//! horizontal wavenumber `k` has the surface height `a` and the flow's part `b` of its vertical
//! velocity, with
//!
//! ```text
//! a' = b + q            (kinematic condition; q: the bodies' volume source, m/s)
//! b' = -omega^2 a - gamma b
//! omega^2 = (g k + sigma k^3 / rho) tanh(k h)
//! ```
//!
//! (gravity and surface tension restore the surface, the depth sets how much water a mode moves;
//! `gamma` is the scene's damping, the same for every mode). Long waves in the shallow pool travel
//! at `sqrt(g h)`, short gravity waves at `sqrt(g / k)`, ripples under 1.7 cm faster again as
//! surface tension takes over: the dispersion that makes a wake a wake.
//!
//! **Why a cosine transform (DCT-I).** The ripple grid's first and last nodes lie on the pool's
//! walls, where water cannot flow through: the surface's slope across a wall is zero. The modes
//! `cos(pi m x / L_x) cos(pi n z / L_z)` satisfy exactly that, and the type-I DCT over the nodes,
//! walls included, is the transform to them. So the walls reflect exactly, and every mode from the
//! pool-long seiche to the band limit moves with its own `omega`: nothing is truncated, as a local
//! (iWave-like) kernel must truncate the long waves. An FFT would make the pool periodic (a wave
//! leaving one wall would enter at the opposite one), which no pool is.
//!
//! **Absorbing borders.** A box with absorbing walls has no such modes, so `border = "absorb"`
//! keeps the reflecting box and adds a sponge layer along its edge: once per frame the heights and
//! velocities in the layer are multiplied by `exp(-sponge(x) T)`, the sponge's damping rising
//! quadratically to the edge (a split step: the exact wave step, then the exact damping step).
//! What reaches the wall through the layer and comes back is small (about 7 %).
//!
//! **Exact per-mode integration.** Over a frame interval `T` the pair `(a, b)` follows the 2 x 2
//! linear equation above with `q` constant (the frame's displacement spread evenly over it, as a
//! body pushes water aside while it moves), whose solution is closed-form:
//! `(a, b)(T) = Phi(T) (a, b)(0) + Psi(T) (q, 0)`. No time step, no stability limit at any frame
//! rate, no numerical dispersion; without damping and source each mode's energy
//! `(b^2 + omega^2 a^2) / 2` is kept to rounding.
//!
//! **Band limit.** The membrane that draws the water cannot show a wave shorter than two of its
//! cells; a ripple it cannot resolve only makes facets and false convergence zones. So no mode of
//! wavenumber above `cutoff_per_m` (the membrane's Nyquist wavenumber, or half the ripple grid's if
//! that is lower) carries energy: those modes are zeroed every frame, and the bodies' source is
//! weighted by a taper `W(k)`, 1 up to half the cutoff and `cos^2` down to 0 at it, so a body does
//! not ring at the cutoff. The membrane's vertices are every other ripple node by default, so the
//! membrane samples this band-limited field without aliasing, and the refraction, the exact method
//! and the reference all sample the same smooth field through the nodes
//! ([`super::ripples::RippleField`]).
//!
//! **Determinism.** The transforms use rustfft's scalar planner, so the bits do not depend on the
//! CPU's vector units; rows and columns are transformed in parallel, each one alone, so the result
//! does not depend on the thread count either.

use std::sync::Arc;

use rayon::prelude::*;
use rustdct::algorithm::Dct1ConvertToFft;
use rustdct::rustfft::FftPlannerScalar;
use rustdct::Dct1;

use super::ripples::{RippleSettings, RippleState};

/// The dispersion relation of linear gravity-capillary waves on water of constant depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dispersion {
    pub gravity_m_per_s2: f64,
    /// Surface tension over density, `sigma / rho`, m^3/s^2.
    pub tension_over_density_m3_per_s2: f64,
    pub depth_m: f64,
}

impl Dispersion {
    /// Angular frequency of wavenumber `k` (rad/m), rad/s.
    pub fn omega(&self, k: f64) -> f64 {
        let restoring = self.gravity_m_per_s2 * k + self.tension_over_density_m3_per_s2 * k * k * k;
        (restoring * (k * self.depth_m).tanh()).sqrt()
    }

    /// Speed of the crests, `omega / k`.
    pub fn phase_speed(&self, k: f64) -> f64 {
        self.omega(k) / k
    }

    /// Speed of a packet's envelope, `d omega / d k`:
    /// `[(g + 3 s k^2) tanh(kh) + (g k + s k^3) h sech^2(kh)] / (2 omega)` with `s = sigma / rho`.
    pub fn group_speed(&self, k: f64) -> f64 {
        let (g, s, h) = (
            self.gravity_m_per_s2,
            self.tension_over_density_m3_per_s2,
            self.depth_m,
        );
        let sech = 1.0 / (k * h).cosh();
        ((g + 3.0 * s * k * k) * (k * h).tanh() + (g * k + s * k * k * k) * h * sech * sech)
            / (2.0 * self.omega(k))
    }

    /// The fastest group speed of any wavenumber in `(0, k_max]` (sampled finely; for sizing the
    /// sponge of an absorbing border).
    pub fn fastest_group_speed(&self, k_max: f64) -> f64 {
        (1..=2000)
            .map(|i| self.group_speed(k_max * i as f64 / 2000.0))
            .fold(0.0, f64::max)
    }
}

/// The bodies' source taper at wavenumber `k` for the band limit `cutoff`: 1 up to half of it,
/// `cos^2` down to 0 at it, 0 beyond.
pub fn source_taper(k: f64, cutoff: f64) -> f64 {
    let x = k / cutoff;
    if x <= 0.5 {
        1.0
    } else if x >= 1.0 {
        0.0
    } else {
        let c = (std::f64::consts::PI * (x - 0.5)).cos();
        c * c
    }
}

/// One mode's propagator over a frame: `a' = p[0] a + p[1] b + g[0] P`, `b' = p[2] a + p[3] b +
/// g[1] P`, with `P` the frame's displacement coefficient; the transform's normalisation is folded
/// in. All zero above the band limit.
#[derive(Clone, Copy, Debug, Default)]
struct Mode {
    p: [f64; 4],
    g: [f64; 2],
}

/// The exact solution over `t` of `a' = b + q, b' = -omega2 a - gamma b`: `Phi` (row-major) and
/// the first column of `Psi = int_0^t Phi`, which multiplies `q`.
fn propagator(omega2: f64, gamma: f64, t: f64) -> ([f64; 4], [f64; 2]) {
    let delta = 0.5 * gamma;
    let damped2 = omega2 - delta * delta;
    // c = cos(w t), s = sin(w t) / w with w^2 = damped2 (cosh and sinh when overdamped).
    let (c, s) = if damped2 > 0.0 {
        let w = damped2.sqrt();
        ((w * t).cos(), (w * t).sin() / w)
    } else if damped2 < 0.0 {
        let w = (-damped2).sqrt();
        ((w * t).cosh(), (w * t).sinh() / w)
    } else {
        (1.0, t)
    };
    let decay = (-delta * t).exp();
    let phi = [
        decay * (c + delta * s),
        decay * s,
        -omega2 * decay * s,
        decay * (c - delta * s),
    ];
    // int a = (-(a'(t) - a'(0)) - gamma (a(t) - a(0))) / omega^2 for a(0) = 1, a'(0) = 0; the
    // mean level (omega = 0) just accumulates the source.
    let psi = if omega2 > 0.0 {
        [decay * s - gamma * (phi[0] - 1.0) / omega2, phi[0] - 1.0]
    } else {
        [t, 0.0]
    };
    (phi, psi)
}

/// The type-I DCT over a row-major `nz x nx` grid (rows, then columns), unnormalised: applied
/// twice it multiplies by `(nx - 1)(nz - 1) / 4`.
struct Transform2 {
    nx: usize,
    nz: usize,
    rows: Arc<dyn Dct1<f64>>,
    columns: Arc<dyn Dct1<f64>>,
}

impl Transform2 {
    fn new(nx: usize, nz: usize) -> Self {
        let mut planner = FftPlannerScalar::new();
        let mut plan = |n: usize| -> Arc<dyn Dct1<f64>> {
            Arc::new(Dct1ConvertToFft::new(planner.plan_fft_forward(2 * (n - 1))))
        };
        Transform2 {
            nx,
            nz,
            rows: plan(nx),
            columns: plan(nz),
        }
    }

    fn along(dct: &Arc<dyn Dct1<f64>>, data: &mut [f64], len: usize) {
        data.par_chunks_mut(len).for_each_init(
            || vec![0.0; dct.get_scratch_len()],
            |scratch, line| dct.process_dct1_with_scratch(line, scratch),
        );
    }

    fn transpose(data: &[f64], rows: usize, columns: usize) -> Vec<f64> {
        let mut out = vec![0.0; data.len()];
        out.par_chunks_mut(rows).enumerate().for_each(|(c, line)| {
            for (r, value) in line.iter_mut().enumerate() {
                *value = data[r * columns + c];
            }
        });
        out
    }

    /// In place.
    fn apply(&self, data: &mut Vec<f64>) {
        Self::along(&self.rows, data, self.nx);
        let mut columns = Self::transpose(data, self.nz, self.nx);
        Self::along(&self.columns, &mut columns, self.nz);
        *data = Self::transpose(&columns, self.nx, self.nz);
    }
}

/// Steps [`RippleState`]s by whole frame intervals: the settings' transform and every mode's
/// propagator over one frame, precomputed.
pub struct RippleStepper {
    settings: RippleSettings,
    frame_secs: f64,
    transform: Transform2,
    modes: Vec<Mode>,
    /// Per node, the sponge's factor over one frame (empty when the border reflects).
    sponge: Vec<f64>,
}

impl RippleStepper {
    /// A stepper for frame intervals of `frame_secs`.
    pub fn new(settings: RippleSettings, frame_secs: f64) -> Self {
        let (nx, nz) = (settings.nodes_x as usize, settings.nodes_z as usize);
        let dispersion = settings.dispersion();
        // Applying the DCT-I twice scales by (nx - 1)(nz - 1) / 4: undone here, once.
        let scale = 4.0 / ((nx - 1) * (nz - 1)) as f64;
        let modes = (0..nx * nz)
            .map(|at| {
                let k = wavenumber(&settings, at % nx, at / nx);
                if k > settings.cutoff_per_m {
                    return Mode::default();
                }
                let omega = dispersion.omega(k);
                let (phi, psi) = propagator(omega * omega, settings.damping_per_s, frame_secs);
                let source = scale * source_taper(k, settings.cutoff_per_m) / frame_secs;
                Mode {
                    p: phi.map(|v| v * scale),
                    g: psi.map(|v| v * source),
                }
            })
            .collect();
        let sponge = if settings.border == super::Border::Absorb && settings.sponge_nodes > 0 {
            settings
                .sponge_per_node()
                .iter()
                .map(|damping| (-damping * frame_secs).exp())
                .collect()
        } else {
            Vec::new()
        };
        RippleStepper {
            settings,
            frame_secs,
            transform: Transform2::new(nx, nz),
            modes,
            sponge,
        }
    }

    pub fn settings(&self) -> &RippleSettings {
        &self.settings
    }

    pub fn frame_secs(&self) -> f64 {
        self.frame_secs
    }

    /// Advances `state` one frame interval, with the bodies displacing `displacement_m` (per
    /// node, metres over the frame; may be empty) evenly over it.
    pub fn advance_frame(&self, state: &mut RippleState, displacement_m: &[f32]) {
        let widen = |values: &[f32]| -> Vec<f64> { values.iter().map(|&v| v as f64).collect() };
        let mut height = widen(&state.height_m);
        let mut velocity = widen(&state.velocity_m_per_s);
        if !self.sponge.is_empty() {
            for ((h, v), factor) in height.iter_mut().zip(&mut velocity).zip(&self.sponge) {
                *h *= factor;
                *v *= factor;
            }
        }
        self.transform.apply(&mut height);
        self.transform.apply(&mut velocity);
        let push = if displacement_m.is_empty() {
            None
        } else {
            let mut push = widen(displacement_m);
            self.transform.apply(&mut push);
            Some(push)
        };
        height
            .par_chunks_mut(4096)
            .zip(velocity.par_chunks_mut(4096))
            .enumerate()
            .for_each(|(chunk, (heights, velocities))| {
                let first = chunk * 4096;
                for (i, (a, b)) in heights.iter_mut().zip(velocities.iter_mut()).enumerate() {
                    let mode = &self.modes[first + i];
                    let p = push.as_ref().map_or(0.0, |push| push[first + i]);
                    let (a0, b0) = (*a, *b);
                    *a = mode.p[0] * a0 + mode.p[1] * b0 + mode.g[0] * p;
                    *b = mode.p[2] * a0 + mode.p[3] * b0 + mode.g[1] * p;
                }
            });
        self.transform.apply(&mut height);
        self.transform.apply(&mut velocity);
        for (out, value) in state.height_m.iter_mut().zip(&height) {
            *out = *value as f32;
        }
        for (out, value) in state.velocity_m_per_s.iter_mut().zip(&velocity) {
            *out = *value as f32;
        }
    }

    /// The state's wave energy per unit density, `sum over modes (b^2 + omega^2 a^2) / 2`, as an
    /// integral over the grid (trapezoid weights at the walls), m^4/s^2. Conserved by a frame
    /// step without damping, sponge or source.
    pub fn energy(&self, state: &RippleState) -> f64 {
        let s = &self.settings;
        let (nx, nz) = (s.nodes_x as usize, s.nodes_z as usize);
        let dispersion = s.dispersion();
        let widen = |values: &[f32]| -> Vec<f64> { values.iter().map(|&v| v as f64).collect() };
        let (mut a, mut b) = (widen(&state.height_m), widen(&state.velocity_m_per_s));
        self.transform.apply(&mut a);
        self.transform.apply(&mut b);
        let edge = |i: usize, n: usize| if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
        let mut sum = 0.0;
        for (at, (a, b)) in a.iter().zip(&b).enumerate() {
            let (m, n) = (at % nx, at / nx);
            let omega = dispersion.omega(wavenumber(s, m, n));
            sum += edge(m, nx) * edge(n, nz) * (b * b + omega * omega * a * a);
        }
        // Parseval for the DCT-I with trapezoid weights: sum'' x^2 = 2 / (n - 1) sum'' X^2 per axis.
        0.5 * sum * 4.0 / ((nx - 1) * (nz - 1)) as f64 * s.spacing_m * s.spacing_m
    }
}

/// Wavenumber (rad/m) of the DCT-I mode (m, n) of the grid.
pub fn wavenumber(settings: &RippleSettings, m: usize, n: usize) -> f64 {
    let pi = std::f64::consts::PI;
    let kx = pi * m as f64 / ((settings.nodes_x - 1) as f64 * settings.spacing_m);
    let kz = pi * n as f64 / ((settings.nodes_z - 1) as f64 * settings.spacing_m);
    kx.hypot(kz)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::sim::ripples::{Border, WATER_DENSITY_KG_PER_M3, WATER_SURFACE_TENSION_N_PER_M};

    /// A grid of `nx x nz` nodes `spacing_m` apart centred on the origin: deep water, no damping,
    /// reflecting walls, the band limit at half the grid's Nyquist wavenumber.
    pub(crate) fn settings(nx: u32, nz: u32, spacing_m: f64) -> RippleSettings {
        RippleSettings {
            nodes_x: nx,
            nodes_z: nz,
            min_x: -0.5 * (nx - 1) as f64 * spacing_m,
            min_z: -0.5 * (nz - 1) as f64 * spacing_m,
            spacing_m,
            depth_m: 2.0,
            surface_tension_n_per_m: WATER_SURFACE_TENSION_N_PER_M,
            density_kg_per_m3: WATER_DENSITY_KG_PER_M3,
            damping_per_s: 0.0,
            cutoff_per_m: 0.5 * std::f64::consts::PI / spacing_m,
            border: Border::Reflect,
            sponge_nodes: 0,
            sponge_damping_per_s: 0.0,
        }
    }

    /// A Gaussian bump of height 1 cm and width `sigma_m` at (x, z), at rest.
    pub(crate) fn bump(settings: RippleSettings, x: f64, z: f64, sigma_m: f64) -> RippleState {
        let mut state = RippleState::calm(settings);
        let nx = settings.nodes_x as usize;
        for (at, height) in state.height_m.iter_mut().enumerate() {
            let px = settings.min_x + (at % nx) as f64 * settings.spacing_m;
            let pz = settings.min_z + (at / nx) as f64 * settings.spacing_m;
            let r2 = (px - x).powi(2) + (pz - z).powi(2);
            *height = (0.01 * (-r2 / (2.0 * sigma_m * sigma_m)).exp()) as f32;
        }
        state
    }

    #[test]
    fn the_propagator_is_the_solution_of_its_equation() {
        // Against a fine RK4 integration of a' = b + q, b' = -w2 a - gamma b, for under-, critically
        // and over-damped modes and the mean level.
        for (omega2, gamma) in [
            (40.0, 0.4),
            (4.0, 4.0),
            (1.0, 6.0),
            (0.0, 0.5),
            (900.0, 0.0),
        ] {
            let t = 0.07;
            let (phi, psi) = propagator(omega2, gamma, t);
            for (a0, b0, q) in [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.3, -0.2, 0.7)] {
                let f = |a: f64, b: f64| (b + q, -omega2 * a - gamma * b);
                let (mut a, mut b) = (a0, b0);
                let steps = 20_000;
                let h = t / steps as f64;
                for _ in 0..steps {
                    let k1 = f(a, b);
                    let k2 = f(a + 0.5 * h * k1.0, b + 0.5 * h * k1.1);
                    let k3 = f(a + 0.5 * h * k2.0, b + 0.5 * h * k2.1);
                    let k4 = f(a + h * k3.0, b + h * k3.1);
                    a += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                    b += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
                }
                let exact_a = phi[0] * a0 + phi[1] * b0 + psi[0] * q;
                let exact_b = phi[2] * a0 + phi[3] * b0 + psi[1] * q;
                assert!(
                    (exact_a - a).abs() < 1e-9 && (exact_b - b).abs() < 1e-9,
                    "omega2 {omega2} gamma {gamma}: ({exact_a}, {exact_b}) vs ({a}, {b})"
                );
            }
        }
    }

    /// Without damping the wave energy is kept over 2,400 frames (100 s) (f32 state: rounding only); with
    /// damping or an absorbing border it falls; it never grows beyond rounding.
    #[test]
    fn energy_is_kept_without_damping_and_never_grows() {
        for border in [Border::Reflect, Border::Absorb] {
            for damping_per_s in [0.0, 0.5] {
                let mut s = settings(65, 49, 0.03);
                s.damping_per_s = damping_per_s;
                s.border = border;
                s.sponge_nodes = 8;
                s.sponge_damping_per_s = 20.0;
                let stepper = RippleStepper::new(s, 1.0 / 24.0);
                let mut state = bump(s, 0.2, -0.1, 0.08);
                // One step first: the bump itself has energy above the band limit.
                stepper.advance_frame(&mut state, &[]);
                let start = stepper.energy(&state);
                assert!(start > 0.0);
                let mut previous = start;
                for frame in 0..2_400 {
                    stepper.advance_frame(&mut state, &[]);
                    if frame % 10 != 0 {
                        continue;
                    }
                    let energy = stepper.energy(&state);
                    assert!(
                        energy <= previous * (1.0 + 1e-4) + 1e-12 * start,
                        "{border:?} damping {damping_per_s}: energy rose at frame {frame}: {previous:e} -> {energy:e}"
                    );
                    previous = energy;
                }
                let ratio = previous / start;
                if damping_per_s == 0.0 && border == Border::Reflect {
                    assert!((ratio - 1.0).abs() < 1e-3, "kept without damping: {ratio}");
                } else {
                    assert!(ratio < 0.05, "{border:?} {damping_per_s}: kept {ratio}");
                }
            }
        }
    }

    #[test]
    fn stepping_is_deterministic_and_symmetric() {
        let s = settings(41, 41, 0.05);
        let run = || {
            let stepper = RippleStepper::new(s, 1.0 / 24.0);
            let mut state = bump(s, 0.0, 0.0, 0.1);
            for _ in 0..50 {
                stepper.advance_frame(&mut state, &[]);
            }
            state
        };
        let (a, b) = (run(), run());
        assert_eq!(a.height_m, b.height_m);
        assert_eq!(a.velocity_m_per_s, b.velocity_m_per_s);
        // On one thread: the same bits.
        let single = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(run);
        assert_eq!(a.height_m, single.height_m);
        // A centred bump stays mirror-symmetric in x.
        let nx = 41;
        let largest = a.max_abs_height_m();
        assert!(largest > 0.0);
        for iz in 0..nx {
            for ix in 0..nx {
                let (p, q) = (a.height_m[iz * nx + ix], a.height_m[iz * nx + nx - 1 - ix]);
                assert!((p - q).abs() <= 1e-5 * largest);
            }
        }
    }

    /// No energy above the band limit, measured by an independent transform (direct cosine sums
    /// over a small grid): a point push, the sharpest source there is, leaves nothing above the
    /// cutoff, while the band below it is filled.
    #[test]
    fn a_point_source_leaves_no_energy_above_the_band_limit() {
        let mut s = settings(33, 21, 0.02);
        s.cutoff_per_m = 0.6 * std::f64::consts::PI / s.spacing_m;
        let stepper = RippleStepper::new(s, 1.0 / 30.0);
        let (nx, nz) = (33usize, 21usize);
        let mut push = vec![0.0f32; nx * nz];
        push[10 * nx + 13] = 0.01;
        push[10 * nx + 14] = -0.01;
        let mut state = RippleState::calm(s);
        for frame in 0..6 {
            stepper.advance_frame(&mut state, if frame < 2 { &push } else { &[] });
        }
        let (mut above, mut below) = (0.0f64, 0.0f64);
        let pi = std::f64::consts::PI;
        for n in 0..nz {
            for m in 0..nx {
                let mut coefficient = 0.0f64;
                for iz in 0..nz {
                    for ix in 0..nx {
                        let w =
                            |i: usize, len: usize| if i == 0 || i == len - 1 { 0.5 } else { 1.0 };
                        coefficient += w(ix, nx)
                            * w(iz, nz)
                            * state.height_m[iz * nx + ix] as f64
                            * (pi * (m * ix) as f64 / (nx - 1) as f64).cos()
                            * (pi * (n * iz) as f64 / (nz - 1) as f64).cos();
                    }
                }
                let k = wavenumber(&s, m, n);
                if k > s.cutoff_per_m * (1.0 + 1e-9) {
                    above += coefficient * coefficient;
                } else {
                    below += coefficient * coefficient;
                }
            }
        }
        assert!(below > 0.0);
        assert!(above < 1e-10 * below, "above {above:e}, below {below:e}");
    }

    #[test]
    fn the_group_speed_is_the_derivative_of_omega() {
        for depth_m in [0.05, 0.3, 5.0] {
            let d = Dispersion {
                gravity_m_per_s2: 9.81,
                tension_over_density_m3_per_s2: 7.28e-5,
                depth_m,
            };
            for k in [3.0, 60.0, 400.0, 2000.0] {
                let e = 1e-6 * k;
                let numeric = (d.omega(k + e) - d.omega(k - e)) / (2.0 * e);
                assert!(((d.group_speed(k) - numeric) / numeric).abs() < 1e-7);
            }
        }
    }
}
