//! Known answers from ship-wave physics, measured on the wake the simulation leaves behind a body
//! gliding steadily across the water: Kelvin's cusp lines over deep water, the Mach wedge over
//! shallow water at supercritical speed.
//!
//! **The run.** The body is a smooth hull (`cos^2` along and across, length `L`, beam `L / 2`)
//! whose occupancy moves along z = 0 at speed `U`; the production path turns it into ripples:
//! [`Simulation::state_at`] takes the occupancy change of every frame through
//! [`super::coupling::displacement`] (the bodies' source) and [`super::RippleStepper`] (the exact
//! per-mode step, band limit and source taper included). The walls are far enough not to matter
//! (Kelvin: walls 8 instead of 6 wavelengths from the track moved no ridge angle by more than
//! 0.02 degrees; 32 instead of 22 wavelengths of travel, the start further away, by 0.13 at most).
//!
//! **The measurement.** A steady wake is made only of waves whose crests cross the track (a wave
//! stands still behind the body where its phase speed is `U cos theta`, so `k_x != 0`): keeping
//! the `k_x > 0` half of each row's spectrum (the analytic signal along the track) gives the
//! complex wave pattern, whose modulus is the local amplitude, of both wave systems together
//! where they cross ([`Wake::envelope`]). Along arcs of radius `r` behind the
//! body's centre, the outermost maximum of that envelope is the wake's ridge: outside it the
//! pattern decays (exponentially past a caustic), inside it the wave systems beat. Its angle from
//! the track is read at many radii, on both sides.
//!
//! **Kelvin.** Over deep water, waves whose crests make an angle `theta` with the track stand still
//! behind the body at `k = (g / U^2) sec^2 theta`, and (stationary phase) their energy lies on the
//! ray at `tan phi = tan theta / (1 + 2 tan^2 theta)` from the track. `phi` has a maximum, arcsin
//! (1/3) = 19.47 degrees at `tan theta = 1 / sqrt 2`: there the transverse and diverging waves
//! merge in a caustic, the cusp line. Across a caustic the amplitude is an Airy function
//! whose main lobe lies *inside* the line, by `0.480 (k0 r)^(-2/3)` rad for a point source
//! (`k0 = g / U^2`: 1.7 degrees at 10 wavelengths), a little less for this body (a stationary-phase
//! integral over its spectrum gave 18.4 degrees at 10 wavelengths, the simulation 18.5). So the
//! ridge's angle approaches the cusp line's slowly, and the test fits
//! `phi_ridge(r) = phi_cusp - c (k0 r)^(-2/3)` over the radii and checks the intercept, the cusp
//! line's angle, and that the ridge lies inside it and approaches it (`c > 0`). The conditions:
//! deep water (`U / sqrt(g h)` 0.13), a body long enough not to favour short diverging waves over
//! the cusp's (`U / sqrt(g L)` 0.40, the issue's <= 0.5), no surface tension to speak of at the
//! cusp's wavelength (33 cm: 0.3 % of gravity's restoring force), and a grid on which the band
//! limit keeps the cusp's waves (`k = 1.5 k0`) below half the cutoff, where the source taper
//! begins: 12 nodes a transverse wavelength. On 9 nodes the taper eats the cusp's waves and the
//! ridge creeps from 15 to 18.3 degrees between 3 and 11 wavelengths (the fit then says 20.6).
//!
//! **Mach.** Over shallow water (waves long against the depth) every wave travels at about
//! `c0 = sqrt(g h)`; a body faster than that outruns them all, and the disturbance it leaves
//! fills a wedge of half-angle `arcsin(c0 / U)` whose edge carries it (the Mach line). Dispersion
//! bends a wave of `k h` inward by `mu - phi(k)` (stationary phase as above with `c(k)` and
//! `c_g(k)`): 0.2 degrees at `k h = 0.1`, 0.8 at 0.2, 1.7 at 0.3 for `U / sqrt(g h)` = 1.75. So
//! the wedge is a Mach wedge when the body makes long waves, here `L = 60 h`, on a grid whose band
//! limit is `k h = 0.31`: the ridge of the envelope is the wedge's edge, at every radius.

use rustdct::rustfft::num_complex::Complex;
use rustdct::rustfft::FftPlannerScalar;

use super::checkpoint::KeyHasher;
use super::ripples::{RippleSettings, RippleState};
use super::spectral::tests::settings;
use super::Simulation;
use crate::water::GRAVITY_M_PER_S2;

const PI: f64 = std::f64::consts::PI;

/// A body gliding along +x on the line z = 0, and the pool it crosses (reflecting walls).
#[derive(Clone, Copy, Debug)]
struct Run {
    speed_m_per_s: f64,
    depth_m: f64,
    /// Length (along the track) of the body's footprint; its beam is half of it.
    length_m: f64,
    spacing_m: f64,
    fps: f64,
    /// How far the body travels, metres.
    travel_m: f64,
    /// Water kept behind the start, ahead of the end and on each side of the track, metres.
    behind_m: f64,
    ahead_m: f64,
    half_width_m: f64,
}

struct Wake {
    settings: RippleSettings,
    state: RippleState,
    /// x of the body's centre at the last frame.
    source_x: f64,
}

impl Run {
    /// The pool: deep water helpers' defaults (no damping, band limit at the membrane's Nyquist,
    /// half the grid's, as in production), the start of the track at x = 0.
    fn pool(&self) -> RippleSettings {
        let length = self.behind_m + self.travel_m + self.ahead_m;
        let nx = (length / self.spacing_m).ceil() as u32 + 1;
        let nz = (2.0 * self.half_width_m / self.spacing_m).ceil() as u32 + 1;
        RippleSettings {
            depth_m: self.depth_m,
            min_x: -self.behind_m,
            ..settings(nx, nz, self.spacing_m)
        }
    }

    /// The frame at which the body has travelled `travel_m` (it starts at frame 1).
    fn last_frame(&self) -> u32 {
        (self.travel_m * self.fps / self.speed_m_per_s).round() as u32 + 1
    }

    fn centre_x(&self, frame: u32) -> f64 {
        (frame - 1) as f64 * self.speed_m_per_s / self.fps
    }

    /// The body's occupancy at `frame`: submerged depth per node, 2 cm at the middle.
    fn occupancy(&self, s: &RippleSettings, frame: u32) -> Vec<f32> {
        let nx = s.nodes_x as usize;
        let centre = self.centre_x(frame);
        (0..s.node_count())
            .map(|at| {
                let x = s.min_x + (at % nx) as f64 * s.spacing_m - centre;
                let z = s.min_z + (at / nx) as f64 * s.spacing_m;
                let (u, v) = (x / self.length_m, z / (0.5 * self.length_m));
                if u.abs() >= 0.5 || v.abs() >= 0.5 {
                    return 0.0;
                }
                (0.02 * (PI * u).cos().powi(2) * (PI * v).cos().powi(2)) as f32
            })
            .collect()
    }

    fn simulate(&self) -> Wake {
        let s = self.pool();
        let key = KeyHasher::new("wake test").finish();
        let simulation = Simulation::new(s, 1.0, 1, self.fps, key);
        let last = self.last_frame();
        let state = simulation
            .state_at(last, &|f| self.occupancy(&s, f))
            .unwrap();
        Wake {
            settings: s,
            state: (*state).clone(),
            source_x: self.centre_x(last),
        }
    }
}

impl Wake {
    /// The wave envelope per node: per row (constant z), the modulus of the heights' analytic
    /// signal along x, the row zero-padded to twice its length so its ends do not wrap around.
    fn envelope(&self) -> Vec<f64> {
        let s = &self.settings;
        let (nx, nz) = (s.nodes_x as usize, s.nodes_z as usize);
        let n = 2 * nx;
        let mut planner = FftPlannerScalar::<f64>::new();
        let (forward, inverse) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
        let mut out = vec![0.0; nx * nz];
        for iz in 0..nz {
            let row = &self.state.height_m[iz * nx..(iz + 1) * nx];
            let mut line: Vec<Complex<f64>> = (0..n)
                .map(|i| Complex::new(row.get(i).map_or(0.0, |&h| h as f64), 0.0))
                .collect();
            forward.process(&mut line);
            // Positive wavenumbers twice, the mean and Nyquist once, negative ones not at all.
            for (j, value) in line.iter_mut().enumerate() {
                *value *= match j {
                    0 => 1.0,
                    j if j == n / 2 => 1.0,
                    j if j < n / 2 => 2.0,
                    _ => 0.0,
                };
            }
            inverse.process(&mut line);
            for (ix, value) in out[iz * nx..(iz + 1) * nx].iter_mut().enumerate() {
                *value = line[ix].norm() / n as f64;
            }
        }
        out
    }

    /// Bilinear sample of `values` (one per node) at (x, z), which must lie inside the grid.
    fn sample(&self, values: &[f64], x: f64, z: f64) -> f64 {
        let s = &self.settings;
        let nx = s.nodes_x as usize;
        let gx = (x - s.min_x) / s.spacing_m;
        let gz = (z - s.min_z) / s.spacing_m;
        assert!(
            gx >= 0.0 && gz >= 0.0 && gx < (nx - 1) as f64 && gz < (s.nodes_z - 1) as f64,
            "({x}, {z}) is outside the pool"
        );
        let (ix, iz) = (gx as usize, gz as usize);
        let (tx, tz) = (gx - ix as f64, gz - iz as f64);
        let at = |i: usize, j: usize| values[j * nx + i];
        (1.0 - tz) * ((1.0 - tx) * at(ix, iz) + tx * at(ix + 1, iz))
            + tz * ((1.0 - tx) * at(ix, iz + 1) + tx * at(ix + 1, iz + 1))
    }

    /// The envelope along the arc of radius `r` behind the body's centre, at `degrees` from the
    /// track, on the side `side` (+1 or -1) of it.
    fn arc(&self, envelope: &[f64], r: f64, side: f64, degrees: &[f64]) -> Vec<f64> {
        degrees
            .iter()
            .map(|d| {
                let a = d.to_radians();
                self.sample(envelope, self.source_x - r * a.cos(), side * r * a.sin())
            })
            .collect()
    }

    /// The ridge's angle (degrees, the mean of both sides) at each radius of `radii`, searched
    /// over `degrees`, and a report of both sides' angles with the radii in units of `unit`
    /// (metres, name). The run is symmetric about the track: the two sides must agree.
    fn ridges(
        &self,
        radii: &[f64],
        degrees: &[f64],
        unit: (f64, &str),
    ) -> (Vec<(f64, f64)>, String) {
        let envelope = self.envelope();
        let mut report = String::new();
        let ridges = radii
            .iter()
            .map(|&r| {
                let [left, right] = [1.0, -1.0].map(|side| {
                    let arc = self.arc(&envelope, r, side, degrees);
                    outermost_peak(degrees, &arc, 0.5)
                        .unwrap_or_else(|| panic!("no ridge at r = {r} m, side {side}"))
                });
                report += &format!(
                    "\n  r {:4.1} {}: ridge {left:.2} / {right:.2} deg",
                    r / unit.0,
                    unit.1
                );
                assert!((left - right).abs() < 0.05, "asymmetric wake:{report}");
                (r, 0.5 * (left + right))
            })
            .collect();
        (ridges, report)
    }
}

/// The outermost local maximum of `values` over `degrees` (ascending, evenly spaced) that reaches
/// `fraction` of the largest value: its angle, refined by a parabola through its neighbours.
fn outermost_peak(degrees: &[f64], values: &[f64], fraction: f64) -> Option<f64> {
    let largest = values.iter().fold(0.0f64, |m, v| m.max(*v));
    (1..values.len() - 1).rev().find_map(|i| {
        let (l, c, r) = (values[i - 1], values[i], values[i + 1]);
        (c >= l && c >= r && c >= fraction * largest).then(|| {
            let offset = 0.5 * (l - r) / (l - 2.0 * c + r);
            degrees[i] + offset * (degrees[i + 1] - degrees[i])
        })
    })
}

/// Least squares `y = a + b x` through `points`: (a, b).
fn line_fit(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let b = sxy / sxx;
    (my - b * mx, b)
}

/// Angles from 1 degree up to `to`, every 0.05 degrees.
fn angles(to: f64) -> Vec<f64> {
    (0..=((to - 1.0) * 20.0) as usize)
        .map(|i| 1.0 + i as f64 * 0.05)
        .collect()
}

#[test]
fn a_body_over_deep_water_leaves_kelvin_cusp_lines_at_19_47_degrees() {
    // A transverse wavelength of 50 cm: U = 0.88 m/s over 5 m of water.
    let wavelength = 0.5;
    let speed = (GRAVITY_M_PER_S2 * wavelength / (2.0 * PI)).sqrt();
    let k0 = 2.0 * PI / wavelength;
    let run = Run {
        speed_m_per_s: speed,
        depth_m: 5.0,
        length_m: wavelength,
        spacing_m: wavelength / 12.0,
        // 12 frames a second: the body moves 1.8 nodes a frame (at 12, 24 and 48 fps the ridges
        // agreed within 0.15 degrees and the cusp lines read 18.92, 18.86 and 18.94 degrees).
        fps: 12.0,
        // The ridge at r was made while the body travelled the last 1.41 r (Kelvin's
        // construction); r goes to 11 wavelengths.
        travel_m: 22.0 * wavelength,
        behind_m: 2.0 * wavelength,
        ahead_m: 3.0 * wavelength,
        half_width_m: 6.0 * wavelength,
    };
    let g = GRAVITY_M_PER_S2;
    assert!(speed / (g * run.depth_m).sqrt() <= 0.4);
    assert!(speed / (g * run.length_m).sqrt() <= 0.5);
    // The cusp's waves (1.5 k0) below half the band limit, where the source taper begins.
    assert!(1.5 * k0 <= 0.5 * run.pool().cutoff_per_m);
    let radii: Vec<f64> = (0..=16)
        .map(|i| (3.0 + 0.5 * i as f64) * wavelength)
        .collect();
    let (ridges, mut report) =
        run.simulate()
            .ridges(&radii, &angles(28.0), (wavelength, "wavelengths"));
    let kelvin = (1.0f64 / 3.0).asin().to_degrees();
    let points: Vec<(f64, f64)> = ridges
        .iter()
        .map(|&(r, angle)| ((k0 * r).powf(-2.0 / 3.0), angle))
        .collect();
    let (cusp, slope) = line_fit(&points);
    let offset = -slope.to_radians();
    report += &format!(
        "\n  cusp line {cusp:.2} deg (Kelvin {kelvin:.2}); the ridge lies {offset:.3} (k0 r)^(-2/3) rad \
         inside it (a point source's Airy lobe: 0.480)"
    );
    eprintln!("{report}");
    assert!((cusp - kelvin).abs() <= 1.5, "{report}");
    // The ridge lies inside the cusp line and approaches it with distance.
    assert!(offset > 0.0, "{report}");
    assert!(points.iter().all(|p| p.1 < kelvin), "{report}");
}

#[test]
fn a_body_faster_than_shallow_water_waves_leaves_a_mach_wedge() {
    // 2 cm of water, U = 1.75 sqrt(g h) = 0.78 m/s; a body 60 depths long makes long waves.
    let depth = 0.02;
    let froude = 1.75;
    let speed = froude * (GRAVITY_M_PER_S2 * depth).sqrt();
    let length = 60.0 * depth;
    let run = Run {
        speed_m_per_s: speed,
        depth_m: depth,
        length_m: length,
        spacing_m: length / 12.0,
        fps: 12.0,
        // The edge at r was made while the body travelled the last r / cos(mu) = 1.22 r.
        travel_m: 12.0 * length,
        behind_m: length,
        ahead_m: 2.0 * length,
        half_width_m: 7.0 * length,
    };
    assert!((1.5..=2.0).contains(&froude));
    // The band limit keeps only long waves, k h <= 0.31 (see the module's notes).
    assert!(run.pool().cutoff_per_m * depth < 0.32);
    let radii: Vec<f64> = (0..13).map(|i| (3.0 + 0.5 * i as f64) * length).collect();
    let (ridges, mut report) = run
        .simulate()
        .ridges(&radii, &angles(48.0), (length, "lengths"));
    let mach = (1.0 / froude).asin().to_degrees();
    // A wedge: its edge at the Mach angle at every radius.
    for &(_, edge) in &ridges {
        assert!((edge - mach).abs() <= 2.0, "Mach {mach:.2} deg:{report}");
    }
    let sum: f64 = ridges.iter().map(|r| r.1).sum();
    let mean = sum / ridges.len() as f64;
    report += &format!("\n  wedge half-angle {mean:.2} deg (Mach {mach:.2})");
    eprintln!("{report}");
    assert!((mean - mach).abs() <= 2.0, "{report}");
}
