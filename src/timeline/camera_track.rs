//! The camera track: keyframes of eye, target and vertical fov, interpolated by cubic Hermite
//! segments whose tangents make the path C1 in time. Eye and target use non-uniform Catmull-Rom
//! tangents (rounded corners on orbits); the fov uses monotone (Fritsch-Carlson/PCHIP) tangents so
//! it never overshoots its keys into an invalid angle. The end keys have zero velocity, which makes
//! the clamped extension before the first and after the last key C1 as well (the camera eases in
//! and out).

use glam::{DVec3, Vec3};

use super::CameraKey;
use crate::camera::Camera;

/// A camera key list that cannot be interpolated, with the key at fault.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraTrackError {
    #[error("a camera track needs at least one key")]
    NoKeys,
    #[error("camera key {index}: {reason}")]
    InvalidKey { index: usize, reason: String },
    #[error(
        "camera keys {first} and {second} are both at t = {time_secs} s; key times must differ"
    )]
    DuplicateTime {
        first: usize,
        second: usize,
        time_secs: f64,
    },
}

/// Velocities (per second) at a key.
#[derive(Clone, Copy, Debug, PartialEq)]
struct KeyTangents {
    eye: DVec3,
    target: DVec3,
    fov_y_deg: f64,
}

/// The camera state in f64 (interpolation precision; cast to f32 only in the returned camera).
#[derive(Clone, Copy, Debug, PartialEq)]
struct CameraState {
    eye: DVec3,
    target: DVec3,
    fov_y_deg: f64,
}

/// Keyframes sorted by time with their tangents; sampled at any time, clamped outside the keys.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraTrack {
    keys: Vec<CameraKey>,
    tangents: Vec<KeyTangents>,
}

impl CameraTrack {
    /// Sorts `keys` by time and prepares the interpolation.
    ///
    /// # Panics
    /// When [`Self::try_new`] would fail: validate scene input with `try_new`.
    pub fn new(keys: Vec<CameraKey>) -> CameraTrack {
        match Self::try_new(keys) {
            Ok(track) => track,
            Err(error) => panic!("invalid camera track: {error}"),
        }
    }

    /// Sorts `keys` by time and prepares the interpolation; rejects no keys, non-finite values, a
    /// fov outside (0, 180) degrees, an eye on its target or looking straight up or down (up is
    /// +y), and two keys at the same time.
    pub fn try_new(mut keys: Vec<CameraKey>) -> Result<CameraTrack, CameraTrackError> {
        if keys.is_empty() {
            return Err(CameraTrackError::NoKeys);
        }
        for (index, key) in keys.iter().enumerate() {
            validate_key(key).map_err(|reason| CameraTrackError::InvalidKey { index, reason })?;
        }
        // Stable sort keeps the original indices meaningful in the duplicate-time error below.
        let mut order: Vec<usize> = (0..keys.len()).collect();
        order.sort_by(|&a, &b| keys[a].time_secs.total_cmp(&keys[b].time_secs));
        for pair in order.windows(2) {
            if keys[pair[0]].time_secs == keys[pair[1]].time_secs {
                return Err(CameraTrackError::DuplicateTime {
                    first: pair[0].min(pair[1]),
                    second: pair[0].max(pair[1]),
                    time_secs: keys[pair[0]].time_secs,
                });
            }
        }
        keys = order.iter().map(|&index| keys[index]).collect();
        let tangents = key_tangents(&keys);
        Ok(CameraTrack { keys, tangents })
    }

    /// The keys, sorted by time.
    pub fn keys(&self) -> &[CameraKey] {
        &self.keys
    }

    /// The camera at `time_secs` (up = +y): the first key before it, the last key after it.
    pub fn sample(&self, time_secs: f64) -> Camera {
        let state = self.sample_state(time_secs);
        Camera::looking_at(
            state.eye.as_vec3(),
            state.target.as_vec3(),
            state.fov_y_deg as f32,
        )
    }

    fn sample_state(&self, time_secs: f64) -> CameraState {
        let first = &self.keys[0];
        let last = &self.keys[self.keys.len() - 1];
        if self.keys.len() == 1 || time_secs <= first.time_secs {
            return key_state(first);
        }
        if time_secs >= last.time_secs {
            return key_state(last);
        }
        // Segment i runs from key i to key i + 1; time is strictly inside (first, last) here.
        let segment = self.keys.partition_point(|key| key.time_secs <= time_secs) - 1;
        let (k0, k1) = (&self.keys[segment], &self.keys[segment + 1]);
        let (m0, m1) = (&self.tangents[segment], &self.tangents[segment + 1]);
        let duration_secs = k1.time_secs - k0.time_secs;
        let s = (time_secs - k0.time_secs) / duration_secs;
        let basis = hermite_basis(s);
        let blend = |p0: f64, v0: f64, p1: f64, v1: f64| {
            basis[0] * p0
                + basis[1] * duration_secs * v0
                + basis[2] * p1
                + basis[3] * duration_secs * v1
        };
        let blend3 = |p0: Vec3, v0: DVec3, p1: Vec3, v1: DVec3| {
            let (p0, p1) = (p0.as_dvec3(), p1.as_dvec3());
            DVec3::new(
                blend(p0.x, v0.x, p1.x, v1.x),
                blend(p0.y, v0.y, p1.y, v1.y),
                blend(p0.z, v0.z, p1.z, v1.z),
            )
        };
        CameraState {
            eye: blend3(k0.eye, m0.eye, k1.eye, m1.eye),
            target: blend3(k0.target, m0.target, k1.target, m1.target),
            fov_y_deg: blend(
                k0.fov_y_deg as f64,
                m0.fov_y_deg,
                k1.fov_y_deg as f64,
                m1.fov_y_deg,
            ),
        }
    }
}

fn validate_key(key: &CameraKey) -> Result<(), String> {
    let values = [key.eye.to_array(), key.target.to_array()].concat();
    if !key.time_secs.is_finite()
        || !key.fov_y_deg.is_finite()
        || values.iter().any(|v| !v.is_finite())
    {
        return Err("time, eye, target and fov must be finite numbers".to_string());
    }
    if !(key.fov_y_deg > 0.0 && key.fov_y_deg < 180.0) {
        return Err(format!(
            "fov_y_deg must be between 0 and 180 degrees, got {}",
            key.fov_y_deg
        ));
    }
    let view = key.target - key.eye;
    if view.length() < 1e-6 {
        return Err("eye and target are the same point".to_string());
    }
    // A view along +y (straight up or down) takes the camera's stated fallback up vector.
    Ok(())
}

fn key_state(key: &CameraKey) -> CameraState {
    CameraState {
        eye: key.eye.as_dvec3(),
        target: key.target.as_dvec3(),
        fov_y_deg: key.fov_y_deg as f64,
    }
}

/// Cubic Hermite basis (h00, h10, h01, h11) at s in [0, 1].
fn hermite_basis(s: f64) -> [f64; 4] {
    let s2 = s * s;
    let s3 = s2 * s;
    [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    ]
}

/// Velocity at each key: zero at the ends, Catmull-Rom (the slope of the parabola through the key
/// and its neighbours, exact for quadratic motion on uneven key spacing) for eye and target,
/// PCHIP for the fov.
fn key_tangents(keys: &[CameraKey]) -> Vec<KeyTangents> {
    let zero = KeyTangents {
        eye: DVec3::ZERO,
        target: DVec3::ZERO,
        fov_y_deg: 0.0,
    };
    let mut tangents = vec![zero; keys.len()];
    for index in 1..keys.len().saturating_sub(1) {
        let (before, key, after) = (&keys[index - 1], &keys[index], &keys[index + 1]);
        let h0 = key.time_secs - before.time_secs;
        let h1 = after.time_secs - key.time_secs;
        let catmull_rom = |p0: Vec3, p1: Vec3, p2: Vec3| {
            let d0 = (p1.as_dvec3() - p0.as_dvec3()) / h0;
            let d1 = (p2.as_dvec3() - p1.as_dvec3()) / h1;
            (d0 * h1 + d1 * h0) / (h0 + h1)
        };
        tangents[index] = KeyTangents {
            eye: catmull_rom(before.eye, key.eye, after.eye),
            target: catmull_rom(before.target, key.target, after.target),
            fov_y_deg: monotone_tangent(
                (
                    before.fov_y_deg as f64,
                    key.fov_y_deg as f64,
                    after.fov_y_deg as f64,
                ),
                h0,
                h1,
            ),
        };
    }
    tangents
}

/// Fritsch-Butland weighted harmonic mean of the neighbouring slopes (as PCHIP): zero at an
/// extremum, never large enough to overshoot, so the curve stays within its keys' range.
fn monotone_tangent((p0, p1, p2): (f64, f64, f64), h0: f64, h1: f64) -> f64 {
    let d0 = (p1 - p0) / h0;
    let d1 = (p2 - p1) / h1;
    if d0 * d1 <= 0.0 {
        return 0.0;
    }
    let w0 = 2.0 * h1 + h0;
    let w1 = h1 + 2.0 * h0;
    (w0 + w1) / (w0 / d0 + w1 / d1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time_secs: f64, eye: [f32; 3], target: [f32; 3], fov_y_deg: f32) -> CameraKey {
        CameraKey {
            time_secs,
            eye: Vec3::from(eye),
            target: Vec3::from(target),
            fov_y_deg,
        }
    }

    /// Unevenly spaced keys, out of order, with a fov that rises then falls sharply.
    fn orbit_keys() -> Vec<CameraKey> {
        vec![
            key(2.5, [-6.0, 2.5, 4.0], [0.5, -1.0, 0.0], 38.0),
            key(0.0, [6.0, 3.0, 6.0], [0.0, -1.5, 0.0], 40.0),
            key(1.0, [0.0, 4.0, 8.5], [0.0, -1.2, 0.5], 55.0),
            key(4.0, [-7.0, 1.5, -3.0], [1.0, -0.8, -0.5], 30.0),
        ]
    }

    fn as_array(state: CameraState) -> [f64; 7] {
        [
            state.eye.x,
            state.eye.y,
            state.eye.z,
            state.target.x,
            state.target.y,
            state.target.z,
            state.fov_y_deg,
        ]
    }

    #[test]
    fn passes_through_every_key_exactly() {
        let track = CameraTrack::new(orbit_keys());
        let times: Vec<f64> = track.keys().iter().map(|key| key.time_secs).collect();
        assert_eq!(times, vec![0.0, 1.0, 2.5, 4.0]);
        for key in orbit_keys() {
            let camera = track.sample(key.time_secs);
            assert_eq!(camera.eye, key.eye);
            assert_eq!(camera.target, key.target);
            assert_eq!(camera.fov_y_deg, key.fov_y_deg);
            assert_eq!(camera.up, Vec3::Y);
        }
    }

    /// Left and right one-sided difference quotients at a time (f64 interpolation).
    fn one_sided_velocities(
        track: &CameraTrack,
        time_secs: f64,
        step_secs: f64,
    ) -> ([f64; 7], [f64; 7]) {
        let at = as_array(track.sample_state(time_secs));
        let before = as_array(track.sample_state(time_secs - step_secs));
        let after = as_array(track.sample_state(time_secs + step_secs));
        (
            std::array::from_fn(|i| (at[i] - before[i]) / step_secs),
            std::array::from_fn(|i| (after[i] - at[i]) / step_secs),
        )
    }

    #[test]
    fn velocity_is_continuous_at_every_key() {
        let track = CameraTrack::new(orbit_keys());
        let step_secs = 1e-6;
        let mut largest_interior_speed: f64 = 0.0;
        for key in track.keys() {
            let (left, right) = one_sided_velocities(&track, key.time_secs, step_secs);
            for component in 0..7 {
                // One-sided quotients differ from the velocity by ~ step * |acceleration| (< 1e-4 here).
                let jump = (left[component] - right[component]).abs();
                assert!(
                    jump < 1e-3,
                    "t = {}: component {component} velocity {} vs {}",
                    key.time_secs,
                    left[component],
                    right[component]
                );
                largest_interior_speed = largest_interior_speed.max(left[component].abs());
            }
        }
        // The check can fail: keys are passed at speed, not at rest.
        assert!(largest_interior_speed > 1.0);
        // And it detects a kink: piecewise-linear motion through the same keys jumps by metres/s.
        let k = &track.keys()[1..4];
        let slope_in = (k[1].eye.x - k[0].eye.x) as f64 / (k[1].time_secs - k[0].time_secs);
        let slope_out = (k[2].eye.x - k[1].eye.x) as f64 / (k[2].time_secs - k[1].time_secs);
        assert!((slope_in - slope_out).abs() > 1e-3);
    }

    #[test]
    fn catmull_rom_tangents_are_exact_for_quadratic_motion() {
        // eye.x = t^2 sampled at uneven times: the key velocity must be 2 t.
        let keys: Vec<CameraKey> = [0.0, 0.7, 2.0, 2.4]
            .iter()
            .map(|&t: &f64| key(t, [(t * t) as f32, 1.0, 0.0], [0.0, 0.0, -5.0], 45.0))
            .collect();
        let track = CameraTrack::new(keys);
        for &t in &[0.7, 2.0] {
            let (left, right) = one_sided_velocities(&track, t, 1e-6);
            assert!(
                ((left[0] + right[0]) / 2.0 - 2.0 * t).abs() < 1e-4,
                "t = {t}: {}",
                left[0]
            );
        }
    }

    #[test]
    fn fov_stays_between_its_keys() {
        let track = CameraTrack::new(orbit_keys());
        let keys = track.keys().to_vec();
        for pair in keys.windows(2) {
            let (low, high) = (
                pair[0].fov_y_deg.min(pair[1].fov_y_deg),
                pair[0].fov_y_deg.max(pair[1].fov_y_deg),
            );
            for step in 0..=100 {
                let t = pair[0].time_secs
                    + (pair[1].time_secs - pair[0].time_secs) * step as f64 / 100.0;
                let fov = track.sample(t).fov_y_deg;
                assert!(
                    fov >= low - 1e-4 && fov <= high + 1e-4,
                    "fov {fov} at t = {t} outside {low}..{high}"
                );
            }
        }
    }

    #[test]
    fn clamps_before_the_first_and_after_the_last_key_and_eases_there() {
        let track = CameraTrack::new(orbit_keys());
        let first = track.keys()[0];
        let last = track.keys()[3];
        assert_eq!(track.sample(-5.0), track.sample(first.time_secs));
        assert_eq!(track.sample(-5.0).eye, first.eye);
        assert_eq!(track.sample(100.0).eye, last.eye);
        assert_eq!(track.sample(100.0).fov_y_deg, last.fov_y_deg);
        // C1 at the ends too: the clamped side is at rest, so the inner side must start at rest.
        for time_secs in [first.time_secs, last.time_secs] {
            let (left, right) = one_sided_velocities(&track, time_secs, 1e-6);
            for component in 0..7 {
                assert!((left[component] - right[component]).abs() < 1e-3);
            }
        }
    }

    /// Two legal keys on either side of the target: half way the eye passes straight over it,
    /// looking down. Every matrix on the way is finite and the picture's top points along +z
    /// there (the stated fallback), never a NaN camera.
    #[test]
    fn keys_passing_over_the_target_never_give_a_nan_matrix() {
        for (from, to) in [
            ([-3.0, 3.0, 0.0], [3.0, 3.0, 0.0]),
            ([0.0, 3.0, -3.0], [0.0, 3.0, 3.0]),
            ([-2.0, 3.0, -2.0], [2.0, 3.0, 2.0]),
        ] {
            let track = CameraTrack::new(vec![
                key(0.0, from, [0.0, -1.0, 0.0], 50.0),
                key(2.0, to, [0.0, -1.0, 0.0], 50.0),
            ]);
            let middle = track.sample(1.0);
            assert!(
                middle.eye.x.abs() < 1e-6 && middle.eye.z.abs() < 1e-6,
                "the path passes over the target: {middle:?}"
            );
            assert_eq!(middle.up, Vec3::Z);
            for step in 0..=2000 {
                let camera = track.sample(step as f64 / 1000.0);
                let matrix = camera.clip_from_world(1280, 720);
                assert!(
                    matrix.is_finite(),
                    "t = {}: {camera:?}",
                    step as f64 / 1000.0
                );
                let pixel = camera
                    .pixel_of(Vec3::new(0.0, -1.0, 0.0), 1280, 720)
                    .unwrap();
                assert!(
                    (pixel - glam::Vec2::new(640.0, 360.0)).length() < 1e-2,
                    "{pixel}"
                );
            }
        }
    }

    #[test]
    fn one_key_is_a_static_camera() {
        let only = key(3.0, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0], 50.0);
        let track = CameraTrack::new(vec![only]);
        for t in [-1.0, 3.0, 3.5, 1e6] {
            let camera = track.sample(t);
            assert_eq!(
                (camera.eye, camera.target, camera.fov_y_deg),
                (only.eye, only.target, only.fov_y_deg)
            );
        }
    }

    #[test]
    fn invalid_tracks_are_rejected_with_the_key_at_fault() {
        assert_eq!(CameraTrack::try_new(vec![]), Err(CameraTrackError::NoKeys));
        let mut keys = orbit_keys();
        keys[3].time_secs = 1.0;
        assert_eq!(
            CameraTrack::try_new(keys).unwrap_err(),
            CameraTrackError::DuplicateTime {
                first: 2,
                second: 3,
                time_secs: 1.0
            }
        );
        let mut keys = orbit_keys();
        keys[1].fov_y_deg = 0.0;
        assert!(CameraTrack::try_new(keys)
            .unwrap_err()
            .to_string()
            .starts_with("camera key 1: fov_y_deg"));
        let mut keys = orbit_keys();
        keys[2].eye.y = f32::NAN;
        assert!(CameraTrack::try_new(keys)
            .unwrap_err()
            .to_string()
            .contains("finite"));
        // Looking straight down is no error: the camera takes its stated fallback up vector.
        let mut keys = orbit_keys();
        keys[0].target = keys[0].eye - Vec3::Y;
        let track = CameraTrack::try_new(keys).unwrap();
        assert_eq!(track.sample(2.5).up, Vec3::Z);
        let mut keys = orbit_keys();
        keys[0].target = keys[0].eye;
        assert!(CameraTrack::try_new(keys)
            .unwrap_err()
            .to_string()
            .contains("same point"));
    }
}
