//! A character's root path: keyframes of position and heading, sampled at any time. Positions
//! follow non-uniform Catmull-Rom Hermite segments (C1, through every key) whose end tangents are
//! the one-sided differences, so a path of two keys is a straight walk at constant speed; headings
//! are interpolated linearly (write 370 degrees to turn past north, not -350). Clamped outside the
//! keys: the character stands at its first key before it and at its last key after it.

use glam::{DMat4, DVec3};

/// One root keyframe (times strictly increasing along a path).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RootKey {
    pub time_secs: f64,
    pub position_m: DVec3,
    /// The direction the model's +z faces, degrees from +z toward +x.
    pub heading_deg: f64,
}

/// A validated root path (at least one key, times strictly increasing).
#[derive(Clone, Debug, PartialEq)]
pub struct RootPath {
    keys: Vec<RootKey>,
    /// Velocity at each key, m/s.
    tangents: Vec<DVec3>,
}

impl RootPath {
    /// # Panics
    /// With no keys or times not strictly increasing (the scene stage refuses those with a located
    /// error before this is built).
    pub fn new(keys: Vec<RootKey>) -> RootPath {
        assert!(!keys.is_empty(), "a root path needs a key");
        assert!(
            keys.windows(2).all(|w| w[0].time_secs < w[1].time_secs),
            "root keys must be in increasing time"
        );
        let n = keys.len();
        let tangents = (0..n)
            .map(|i| {
                if n == 1 {
                    return DVec3::ZERO;
                }
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                (keys[b].position_m - keys[a].position_m) / (keys[b].time_secs - keys[a].time_secs)
            })
            .collect();
        RootPath { keys, tangents }
    }

    /// (position, heading in degrees) at `time_secs`.
    pub fn sample(&self, time_secs: f64) -> (DVec3, f64) {
        let keys = &self.keys;
        let first = keys[0];
        let last = keys[keys.len() - 1];
        if time_secs <= first.time_secs {
            return (first.position_m, first.heading_deg);
        }
        if time_secs >= last.time_secs {
            return (last.position_m, last.heading_deg);
        }
        let i = keys.partition_point(|k| k.time_secs <= time_secs) - 1;
        let (k0, k1) = (keys[i], keys[i + 1]);
        let span = k1.time_secs - k0.time_secs;
        let s = (time_secs - k0.time_secs) / span;
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let position = h00 * k0.position_m
            + h10 * span * self.tangents[i]
            + h01 * k1.position_m
            + h11 * span * self.tangents[i + 1];
        let heading = k0.heading_deg + s * (k1.heading_deg - k0.heading_deg);
        (position, heading)
    }

    /// `world_from_character` at `time_secs` for a model of uniform `scale`: translate, then turn
    /// about +y by the heading, then scale.
    pub fn world_from_character(&self, time_secs: f64, scale: f64) -> DMat4 {
        let (position, heading_deg) = self.sample(time_secs);
        DMat4::from_translation(position)
            * DMat4::from_rotation_y(heading_deg.to_radians())
            * DMat4::from_scale(DVec3::splat(scale))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: f64, x: f64, z: f64, heading_deg: f64) -> RootKey {
        RootKey {
            time_secs: t,
            position_m: DVec3::new(x, 0.0, z),
            heading_deg,
        }
    }

    #[test]
    fn two_keys_walk_straight_at_constant_speed_and_clamp_outside() {
        let path = RootPath::new(vec![key(1.0, 0.0, 0.0, 90.0), key(3.0, 4.0, 2.0, 90.0)]);
        for (t, x) in [(1.0, 0.0), (1.5, 1.0), (2.0, 2.0), (2.75, 3.5), (3.0, 4.0)] {
            let (p, h) = path.sample(t);
            assert!(
                (p.x - x).abs() < 1e-12 && (p.z - x / 2.0).abs() < 1e-12,
                "{t}: {p}"
            );
            assert_eq!(h, 90.0);
        }
        assert_eq!(path.sample(0.0).0, DVec3::ZERO);
        assert_eq!(path.sample(9.0).0, DVec3::new(4.0, 0.0, 2.0));
    }

    #[test]
    fn passes_through_every_key_and_is_c1() {
        let path = RootPath::new(vec![
            key(0.0, 0.0, 0.0, 0.0),
            key(1.0, 1.0, 0.5, 30.0),
            key(2.5, 1.5, 2.0, 90.0),
            key(3.0, 3.0, 2.0, 120.0),
        ]);
        for k in &path.keys {
            let (p, h) = path.sample(k.time_secs);
            assert!((p - k.position_m).length() < 1e-12);
            assert!((h - k.heading_deg).abs() < 1e-12);
        }
        // Velocity continuous across the inner keys.
        for t in [1.0, 2.5] {
            let e = 1e-6;
            let before = (path.sample(t).0 - path.sample(t - e).0) / e;
            let after = (path.sample(t + e).0 - path.sample(t).0) / e;
            assert!((before - after).length() < 1e-4, "{t}: {before} vs {after}");
        }
    }

    #[test]
    fn heading_turns_the_model_forward_axis() {
        let path = RootPath::new(vec![key(0.0, 1.0, 2.0, 90.0)]);
        let m = path.world_from_character(0.0, 0.5);
        // Heading 90: the model's +z (forward) faces +x; scale 0.5; origin at the key.
        let forward = m.transform_vector3(DVec3::Z);
        assert!(
            (forward - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12,
            "{forward}"
        );
        assert!((m.transform_point3(DVec3::ZERO) - DVec3::new(1.0, 0.0, 2.0)).length() < 1e-12);
    }
}
