//! Known answers from water-wave physics, measured on the simulated field: crests at the phase
//! speed and packets at the group speed (three wavelengths, one capillary), and the volume a
//! body's source adds kept exactly while the waves run.
//!
//! Every figure is read off the simulated heights by image analysis, never from the formula it is
//! checked against:
//! - crest speed: the crest nearest the middle of a long wave train, tracked frame by frame as the
//!   local maximum of the heights (refined by a parabola through the three nodes around it);
//! - group speed: the centroid of the squared heights of a packet, at the start and the end;
//! - volume: the trapezoid integral of the node heights over the pool.

use super::ripples::{RippleSettings, RippleState};
use super::spectral::{tests::settings, RippleStepper};

const PI: f64 = std::f64::consts::PI;

/// A narrow strip of water (3 nodes across, so every wave runs along x) of `nodes` nodes.
fn strip(nodes: u32, spacing_m: f64, depth_m: f64) -> RippleSettings {
    RippleSettings {
        depth_m,
        ..settings(nodes, 3, spacing_m)
    }
}

fn node_x(s: &RippleSettings, ix: usize) -> f64 {
    s.min_x + ix as f64 * s.spacing_m
}

/// A wave train or packet `envelope(x) cos(k x)` travelling toward +x, set on the strip.
fn travelling(s: &RippleSettings, k: f64, envelope: &dyn Fn(f64) -> f64) -> RippleState {
    let omega = s.dispersion().omega(k);
    let mut state = RippleState::calm(*s);
    let nx = s.nodes_x as usize;
    for at in 0..s.node_count() {
        let x = node_x(s, at % nx);
        let amplitude = 0.001 * envelope(x);
        state.height_m[at] = (amplitude * (k * x).cos()) as f32;
        // a = A cos(kx - wt): da/dt = A w sin(kx - wt).
        state.velocity_m_per_s[at] = (amplitude * omega * (k * x).sin()) as f32;
    }
    state
}

/// The middle row of the strip.
fn middle_row(state: &RippleState) -> &[f32] {
    let nx = state.settings.nodes_x as usize;
    &state.height_m[nx..2 * nx]
}

/// x of the local maximum of `row` nearest `near` (searched within `reach` of it), refined by a
/// parabola through the three nodes around it.
fn crest_near(s: &RippleSettings, row: &[f32], near: f64, reach: f64) -> f64 {
    let first = (((near - reach - s.min_x) / s.spacing_m).floor().max(1.0)) as usize;
    let last = ((((near + reach - s.min_x) / s.spacing_m).ceil()) as usize).min(row.len() - 2);
    let best = (first..=last)
        .filter(|&i| row[i] >= row[i - 1] && row[i] >= row[i + 1])
        .min_by(|&a, &b| {
            (node_x(s, a) - near)
                .abs()
                .total_cmp(&(node_x(s, b) - near).abs())
        })
        .expect("a crest within reach");
    let (l, c, r) = (row[best - 1] as f64, row[best] as f64, row[best + 1] as f64);
    let offset = 0.5 * (l - r) / (l - 2.0 * c + r);
    node_x(s, best) + offset * s.spacing_m
}

/// The crest speed and the packet speed measured at wavelength `wavelength_m` over `depth_m`, and
/// the theory's phase and group speeds.
fn measured_speeds(wavelength_m: f64, depth_m: f64) -> ([f64; 2], [f64; 2]) {
    let k = 2.0 * PI / wavelength_m;
    let per_wave = 16;
    let spacing = wavelength_m / per_wave as f64;
    let waves = 60;
    let s = strip((waves * per_wave + 1) as u32, spacing, depth_m);
    let dispersion = s.dispersion();
    let (phase, group) = (dispersion.phase_speed(k), dispersion.group_speed(k));
    let half_length = 0.5 * waves as f64 * wavelength_m;

    // Phase: a train flat over the middle 60 %, two periods, a crest tracked every 1/20 period.
    let period = 2.0 * PI / dispersion.omega(k);
    let stepper = RippleStepper::new(s, period / 20.0);
    let flat_top = |x: f64| {
        let u = (x.abs() / half_length - 0.6) / 0.3;
        if u <= 0.0 {
            1.0
        } else if u >= 1.0 {
            0.0
        } else {
            (0.5 * PI * u).cos().powi(2)
        }
    };
    let mut state = travelling(&s, k, &flat_top);
    let start = crest_near(&s, middle_row(&state), 0.0, 0.3 * wavelength_m);
    let mut crest = start;
    let frames = 40;
    for _ in 0..frames {
        stepper.advance_frame(&mut state, &[]);
        // A crest moves about a twentieth of a wavelength a frame: the next one is far.
        crest = crest_near(&s, middle_row(&state), crest, 0.3 * wavelength_m);
    }
    let crest_speed = (crest - start) / (frames as f64 * stepper.frame_secs());

    // Group: a Gaussian packet (5 wavelengths wide) from a quarter of the strip, moved by about
    // 15 wavelengths.
    let centre = -0.5 * half_length;
    let width = 5.0 * wavelength_m;
    let envelope = |x: f64| (-(x - centre).powi(2) / (2.0 * width * width)).exp();
    let travel_secs = 15.0 * wavelength_m / group;
    let frames = 30;
    let stepper = RippleStepper::new(s, travel_secs / frames as f64);
    let mut state = travelling(&s, k, &envelope);
    let centroid = |state: &RippleState| {
        let row = middle_row(state);
        let (mut moment, mut total) = (0.0, 0.0);
        for (i, h) in row.iter().enumerate() {
            let e = (*h as f64).powi(2);
            moment += e * node_x(&s, i);
            total += e;
        }
        moment / total
    };
    let before = centroid(&state);
    for _ in 0..frames {
        stepper.advance_frame(&mut state, &[]);
    }
    let packet_speed = (centroid(&state) - before) / travel_secs;
    ([crest_speed, packet_speed], [phase, group])
}

#[test]
fn crests_move_at_the_phase_speed_and_packets_at_the_group_speed() {
    // A capillary ripple (1.5 cm: surface tension dominates, its group outruns its crests), a
    // short gravity wave over deep water, and a long wave in a shallow pool (k h = 0.84, where
    // tanh and the sech^2 term matter).
    for (wavelength_m, depth_m) in [(0.015, 2.0), (0.08, 2.0), (0.6, 0.08)] {
        let (measured, theory) = measured_speeds(wavelength_m, depth_m);
        for (what, m, t) in [
            ("phase", measured[0], theory[0]),
            ("group", measured[1], theory[1]),
        ] {
            assert!(
                ((m - t) / t).abs() <= 0.03,
                "wavelength {wavelength_m} m, depth {depth_m} m: {what} speed {m:.5} m/s, theory {t:.5} m/s"
            );
        }
        if wavelength_m < 0.017 {
            assert!(
                theory[1] > theory[0],
                "capillary: the group outruns the crests"
            );
        } else {
            assert!(
                theory[1] < theory[0],
                "gravity: the crests outrun the group"
            );
        }
    }
}

/// The water's volume above the still level, m^3: the trapezoid integral of the node heights
/// (the first and last nodes lie on the walls).
fn volume_m3(state: &RippleState) -> f64 {
    let s = &state.settings;
    let (nx, nz) = (s.nodes_x as usize, s.nodes_z as usize);
    let edge = |i: usize, n: usize| if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
    let mut sum = 0.0;
    for (at, h) in state.height_m.iter().enumerate() {
        sum += edge(at % nx, nx) * edge(at / nx, nz) * *h as f64;
    }
    sum * s.spacing_m * s.spacing_m
}

/// A body's source adds exactly the volume it pushes (a sharp push: its band-limited part carries
/// the same volume, the taper being 1 at the mean level), and the waves then move that water
/// around a walled pool without creating or losing any, damped or not.
#[test]
fn a_push_adds_its_volume_and_the_waves_keep_it() {
    for damping_per_s in [0.0, 0.8] {
        let s = RippleSettings {
            depth_m: 0.3,
            damping_per_s,
            ..settings(61, 41, 0.02)
        };
        let (nx, nz) = (s.nodes_x as usize, s.nodes_z as usize);
        // A sharp 3 x 3-node push of 1 mm per node near a corner, off every symmetry line.
        let mut push = vec![0.0f32; nx * nz];
        for iz in 8..11 {
            for ix in 12..15 {
                push[iz * nx + ix] = 0.001;
            }
        }
        let pushed_m3 = 9.0 * 0.001 * s.spacing_m * s.spacing_m;
        let stepper = RippleStepper::new(s, 1.0 / 24.0);
        let mut state = RippleState::calm(s);
        for _ in 0..3 {
            stepper.advance_frame(&mut state, &push);
        }
        let after_push = volume_m3(&state);
        assert!(
            ((after_push - 3.0 * pushed_m3) / pushed_m3).abs() < 1e-4,
            "pushed {:e} m^3, the water holds {after_push:e}",
            3.0 * pushed_m3
        );
        let heights_then = state.height_m.clone();
        for _ in 0..240 {
            stepper.advance_frame(&mut state, &[]);
        }
        let later = volume_m3(&state);
        assert!(
            ((later - after_push) / pushed_m3).abs() < 1e-4,
            "damping {damping_per_s}: volume {after_push:e} -> {later:e} m^3 over 10 s"
        );
        // The water did move: the heights are not those after the push.
        let moved = heights_then
            .iter()
            .zip(&state.height_m)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(moved > 1e-5, "the waves did not move: {moved:e}");
    }
}
