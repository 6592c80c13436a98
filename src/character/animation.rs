//! Animation sampling: receives a channel's key times and values and a time in seconds; returns
//! the animated translation, rotation or scale at that time, following the glTF 2.0 spec
//! (appendix C): the time is clamped to the channel's key range, STEP holds the key at or before
//! t, LINEAR lerps (rotations: shortest-path slerp), CUBICSPLINE is the cubic Hermite spline with
//! the stored tangents scaled by the key interval. At a key time the key value is returned exactly.

use glam::{DQuat, DVec4, Quat, Vec3, Vec4};

/// How a channel interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// The node property a channel drives. Morph-target weights are not sampled (skipped at load).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Property {
    Translation,
    Rotation,
    Scale,
}

/// One validated channel: at least one key, finite non-decreasing times, finite values,
/// `values.len() == times.len()` (or `3 * times.len()` for CUBICSPLINE, stored as the spec's
/// in-tangent, value, out-tangent triples). Translation and scale use xyz of each `Vec4`,
/// rotations are quaternions (x, y, z, w).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Channel {
    pub node: usize,
    pub property: Property,
    pub interpolation: Interpolation,
    pub times_secs: Vec<f32>,
    pub values: Vec<Vec4>,
}

/// One animation: its channels in file order (a later channel on the same node property wins).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Animation {
    pub channels: Vec<Channel>,
}

/// A sampled channel value, ready to replace the node's own component.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Sampled {
    Translation(Vec3),
    Rotation(Quat),
    Scale(Vec3),
}

impl Channel {
    /// The value of key `k` (for CUBICSPLINE the middle element of its triple).
    fn key_value(&self, k: usize) -> Vec4 {
        match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        }
    }

    /// The raw sampled 4-vector at `time_secs` (xyz only meaningful for translation/scale).
    pub fn sample_raw(&self, time_secs: f32) -> Vec4 {
        let times = &self.times_secs;
        let last = times.len() - 1;
        // Clamp to the key range: hold the first value before it and the last value after it.
        // NaN also goes to the first key rather than poisoning the pose.
        if time_secs.is_nan() || time_secs <= times[0] {
            return self.key_value(0);
        }
        if time_secs >= times[last] {
            return self.key_value(last);
        }
        // k: the last key at or before t (so t_k <= t < t_{k+1}, and t_{k+1} > t_k strictly, even
        // with repeated key times, because equal times all sit at or before t).
        let k = times.partition_point(|&key| key <= time_secs) - 1;
        if times[k] == time_secs {
            return self.key_value(k);
        }
        let t0 = f64::from(times[k]);
        let t1 = f64::from(times[k + 1]);
        let interval_secs = t1 - t0;
        let s = (f64::from(time_secs) - t0) / interval_secs;
        match self.interpolation {
            Interpolation::Step => self.key_value(k),
            Interpolation::Linear => {
                let a = self.values[k].as_dvec4();
                let b = self.values[k + 1].as_dvec4();
                match self.property {
                    Property::Rotation => slerp_shortest(a, b, s).as_vec4(),
                    _ => (a + (b - a) * s).as_vec4(),
                }
            }
            Interpolation::CubicSpline => {
                // Spec: p(s) = h00 v_k + h10 td b_k + h01 v_{k+1} + h11 td a_{k+1}, with b_k the
                // out-tangent of key k, a_{k+1} the in-tangent of key k+1, td = t_{k+1} - t_k.
                let v0 = self.values[3 * k + 1].as_dvec4();
                let out0 = self.values[3 * k + 2].as_dvec4();
                let in1 = self.values[3 * (k + 1)].as_dvec4();
                let v1 = self.values[3 * (k + 1) + 1].as_dvec4();
                let s2 = s * s;
                let s3 = s2 * s;
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                let p = v0 * h00
                    + out0 * (h10 * interval_secs)
                    + v1 * h01
                    + in1 * (h11 * interval_secs);
                match self.property {
                    Property::Rotation => normalize_or_identity(p).as_vec4(),
                    _ => p.as_vec4(),
                }
            }
        }
    }

    /// The channel's value at `time_secs`, typed by the property it drives.
    pub fn sample(&self, time_secs: f32) -> Sampled {
        let v = self.sample_raw(time_secs);
        match self.property {
            Property::Translation => Sampled::Translation(v.truncate()),
            Property::Rotation => Sampled::Rotation(Quat::from_vec4(v)),
            Property::Scale => Sampled::Scale(v.truncate()),
        }
    }
}

/// Spherical interpolation along the shorter arc (q and -q are the same rotation, so the end is
/// negated when the two point into opposite half-spaces). Done in f64 and normalised so that the
/// result is a unit quaternion even when the keys are only nearly unit.
fn slerp_shortest(a: DVec4, b: DVec4, s: f64) -> DVec4 {
    let a = normalize_or_identity(a);
    let mut b = normalize_or_identity(b);
    let mut cos_theta = a.dot(b);
    if cos_theta < 0.0 {
        b = -b;
        cos_theta = -cos_theta;
    }
    // Nearly equal keys: sin(theta) -> 0, the weights become 0/0; the chord is the arc there.
    if cos_theta > 1.0 - 1e-12 {
        return normalize_or_identity(a + (b - a) * s);
    }
    let theta = cos_theta.min(1.0).acos();
    let sin_theta = theta.sin();
    let wa = ((1.0 - s) * theta).sin() / sin_theta;
    let wb = (s * theta).sin() / sin_theta;
    normalize_or_identity(a * wa + b * wb)
}

fn normalize_or_identity(q: DVec4) -> DVec4 {
    let length = q.length();
    if length > 0.0 && length.is_finite() {
        q / length
    } else {
        DQuat::IDENTITY.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f32 = 1e-6;

    fn channel(
        property: Property,
        interpolation: Interpolation,
        times: &[f32],
        values: &[[f32; 4]],
    ) -> Channel {
        Channel {
            node: 0,
            property,
            interpolation,
            times_secs: times.to_vec(),
            values: values.iter().map(|v| Vec4::from_array(*v)).collect(),
        }
    }

    fn assert_close(actual: Vec4, expected: [f32; 4], what: &str) {
        let expected = Vec4::from_array(expected);
        assert!(
            (actual - expected).abs().max_element() < EPS,
            "{what}: got {actual:?}, expected {expected:?}"
        );
    }

    #[test]
    fn linear_translation_clamps_and_interpolates() {
        // Keys (1 s -> (0,0,0)), (3 s -> (2,4,-6)), (4 s -> (2,4,0)).
        let c = channel(
            Property::Translation,
            Interpolation::Linear,
            &[1.0, 3.0, 4.0],
            &[
                [0.0, 0.0, 0.0, 0.0],
                [2.0, 4.0, -6.0, 0.0],
                [2.0, 4.0, 0.0, 0.0],
            ],
        );
        assert_close(c.sample_raw(0.0), [0.0, 0.0, 0.0, 0.0], "before first key");
        assert_close(c.sample_raw(1.0), [0.0, 0.0, 0.0, 0.0], "at first key");
        // t = 1.5: s = 0.5 / 2 = 0.25 -> 0.25 * (2, 4, -6).
        assert_close(
            c.sample_raw(1.5),
            [0.5, 1.0, -1.5, 0.0],
            "between keys 0 and 1",
        );
        assert_eq!(
            c.sample_raw(3.0),
            Vec4::new(2.0, 4.0, -6.0, 0.0),
            "exact at a key"
        );
        // t = 3.75: s = 0.75 -> z = -6 + 0.75 * 6 = -1.5.
        assert_close(
            c.sample_raw(3.75),
            [2.0, 4.0, -1.5, 0.0],
            "between keys 1 and 2",
        );
        assert_close(c.sample_raw(10.0), [2.0, 4.0, 0.0, 0.0], "after last key");
    }

    #[test]
    fn linear_scale_between_keys() {
        let c = channel(
            Property::Scale,
            Interpolation::Linear,
            &[0.0, 2.0],
            &[[1.0, 1.0, 1.0, 0.0], [3.0, 0.5, 1.0, 0.0]],
        );
        // s = 0.5: (1 + 0.5 * 2, 1 - 0.5 * 0.5, 1).
        assert_close(c.sample_raw(1.0), [2.0, 0.75, 1.0, 0.0], "middle");
        assert_close(c.sample_raw(-1.0), [1.0, 1.0, 1.0, 0.0], "before");
        assert_close(c.sample_raw(5.0), [3.0, 0.5, 1.0, 0.0], "after");
    }

    #[test]
    fn linear_rotation_is_shortest_path_slerp() {
        // Key 0: identity. Key 1: 90 degrees about z, stored *negated* (-sin45 z, -cos45 w) so a
        // plain lerp would take the long way. Halfway must be 45 degrees about +z:
        // (0, 0, sin 22.5, cos 22.5) = (0, 0, 0.38268343, 0.92387953).
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let c = channel(
            Property::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, -h, -h]],
        );
        assert_close(
            c.sample_raw(0.5),
            [0.0, 0.0, 0.382_683_43, 0.923_879_5],
            "halfway",
        );
        // A quarter of the way: 22.5 degrees -> (0, 0, sin 11.25, cos 11.25).
        assert_close(
            c.sample_raw(0.25),
            [0.0, 0.0, 0.195_090_32, 0.980_785_3],
            "quarter",
        );
        // At and after the last key the stored value comes back unchanged (same rotation).
        assert_eq!(c.sample_raw(1.0), Vec4::new(0.0, 0.0, -h, -h));
        assert_eq!(c.sample_raw(2.0), Vec4::new(0.0, 0.0, -h, -h));
        assert_eq!(c.sample_raw(-2.0), Vec4::new(0.0, 0.0, 0.0, 1.0));
    }

    #[test]
    fn step_holds_the_key_at_or_before_t() {
        let t = channel(
            Property::Translation,
            Interpolation::Step,
            &[0.5, 1.0, 2.0],
            &[
                [1.0, 0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0, 0.0],
                [3.0, 0.0, 0.0, 0.0],
            ],
        );
        assert_eq!(t.sample_raw(0.0).x, 1.0, "before first key");
        assert_eq!(t.sample_raw(0.5).x, 1.0, "at key 0");
        assert_eq!(t.sample_raw(0.99).x, 1.0, "just before key 1");
        assert_eq!(t.sample_raw(1.0).x, 2.0, "at key 1");
        assert_eq!(t.sample_raw(1.7).x, 2.0, "between keys 1 and 2");
        assert_eq!(t.sample_raw(2.0).x, 3.0, "at last key");
        assert_eq!(t.sample_raw(9.0).x, 3.0, "after last key");

        let h = std::f32::consts::FRAC_1_SQRT_2;
        let r = channel(
            Property::Rotation,
            Interpolation::Step,
            &[0.0, 1.0],
            &[[0.0, 0.0, 0.0, 1.0], [h, 0.0, 0.0, h]],
        );
        assert_eq!(r.sample_raw(0.999), Vec4::new(0.0, 0.0, 0.0, 1.0));
        assert_eq!(r.sample_raw(1.0), Vec4::new(h, 0.0, 0.0, h));

        let s = channel(
            Property::Scale,
            Interpolation::Step,
            &[0.0, 1.0],
            &[[1.0, 1.0, 1.0, 0.0], [2.0, 2.0, 2.0, 0.0]],
        );
        assert_eq!(s.sample_raw(0.5), Vec4::new(1.0, 1.0, 1.0, 0.0));
        assert_eq!(s.sample_raw(1.5), Vec4::new(2.0, 2.0, 2.0, 0.0));
    }

    #[test]
    fn repeated_key_times_jump() {
        // Two keys at t = 1 (a discontinuity): at t = 1 the later one holds, before it the earlier.
        let c = channel(
            Property::Translation,
            Interpolation::Linear,
            &[0.0, 1.0, 1.0, 2.0],
            &[
                [0.0; 4],
                [1.0, 0.0, 0.0, 0.0],
                [5.0, 0.0, 0.0, 0.0],
                [7.0, 0.0, 0.0, 0.0],
            ],
        );
        assert_close(c.sample_raw(0.5), [0.5, 0.0, 0.0, 0.0], "before the jump");
        assert_eq!(c.sample_raw(1.0).x, 5.0);
        assert_close(c.sample_raw(1.5), [6.0, 0.0, 0.0, 0.0], "after the jump");
    }

    #[test]
    fn cubic_spline_translation_and_scale() {
        // Keys at 0 s and 2 s (td = 2): value 0 -> 10 in x; out-tangent of key 0 = 3/s,
        // in-tangent of key 1 = -1/s. Stored triples are (in, value, out).
        // At s = 0.5: h00 = 0.5, h10 = 0.125, h01 = 0.5, h11 = -0.125
        //   x = 0.5*0 + 0.125*2*3 + 0.5*10 + (-0.125)*2*(-1) = 0.75 + 5 + 0.25 = 6.
        // At t = 0.5 (s = 0.25): h00 = 0.84375, h10 = 0.140625, h01 = 0.15625, h11 = -0.046875
        //   x = 0.140625*2*3 + 0.15625*10 + (-0.046875)*2*(-1) = 0.84375 + 1.5625 + 0.09375 = 2.5.
        let values = [
            [99.0, 99.0, 99.0, 0.0], // in-tangent of key 0: never used
            [0.0, 1.0, 1.0, 0.0],
            [3.0, 0.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0, 0.0],
            [10.0, 1.0, 1.0, 0.0],
            [99.0, 99.0, 99.0, 0.0], // out-tangent of the last key: never used
        ];
        for property in [Property::Translation, Property::Scale] {
            let c = channel(property, Interpolation::CubicSpline, &[0.0, 2.0], &values);
            assert_close(c.sample_raw(1.0), [6.0, 1.0, 1.0, 0.0], "s = 0.5");
            assert_close(c.sample_raw(0.5), [2.5, 1.0, 1.0, 0.0], "s = 0.25");
            assert_eq!(c.sample_raw(0.0), Vec4::new(0.0, 1.0, 1.0, 0.0), "at key 0");
            assert_eq!(
                c.sample_raw(2.0),
                Vec4::new(10.0, 1.0, 1.0, 0.0),
                "at key 1"
            );
            assert_eq!(c.sample_raw(-1.0), Vec4::new(0.0, 1.0, 1.0, 0.0), "before");
            assert_eq!(c.sample_raw(3.0), Vec4::new(10.0, 1.0, 1.0, 0.0), "after");
        }
    }

    #[test]
    fn cubic_spline_rotation_is_normalised() {
        // Identity -> 90 degrees about z over 1 s, zero tangents: halfway the Hermite blend is
        // 0.5 * (0,0,0,1) + 0.5 * (0,0,h,h) = (0, 0, h/2, (1+h)/2); normalised
        // (0, 0, 0.38268343, 0.92387953) — here equal to the slerp because the keys are symmetric.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let c = channel(
            Property::Rotation,
            Interpolation::CubicSpline,
            &[0.0, 1.0],
            &[
                [0.0; 4],
                [0.0, 0.0, 0.0, 1.0],
                [0.0; 4],
                [0.0; 4],
                [0.0, 0.0, h, h],
                [0.0; 4],
            ],
        );
        let q = c.sample_raw(0.5);
        assert_close(q, [0.0, 0.0, 0.382_683_43, 0.923_879_5], "halfway");
        assert!((q.length() - 1.0).abs() < 1e-6);
        // s = 0.25: h00 = 0.84375, h01 = 0.15625 -> (0, 0, 0.15625 h, 0.84375 + 0.15625 h)
        // = (0, 0, 0.110485, 0.953235), length 0.959617 -> (0, 0, 0.115016, 0.993364).
        assert_close(
            c.sample_raw(0.25),
            [0.0, 0.0, 0.115_015_87, 0.993_363_7],
            "quarter",
        );
    }

    #[test]
    fn single_key_is_constant() {
        let c = channel(
            Property::Translation,
            Interpolation::Linear,
            &[0.3],
            &[[1.0, 2.0, 3.0, 0.0]],
        );
        for t in [-1.0, 0.3, 5.0, f32::NAN] {
            assert_eq!(c.sample_raw(t), Vec4::new(1.0, 2.0, 3.0, 0.0));
        }
    }
}
