//! The analytic wave field: a still level plus a sum of travelling cosine height waves, and its
//! frozen view at one instant ([`WaterSurface`]), which is the exact [`HeightField`] of that frame.

use std::f64::consts::TAU;

use super::{HeightField, WaterError};

/// Standard gravity, m/s^2: the deep-water dispersion relation `omega^2 = g k` uses it.
pub const GRAVITY_M_PER_S2: f64 = 9.81;

/// One travelling height wave: displacement `a * cos(k (d . x) - omega t + phase)` with
/// `k = 2 pi / wavelength`, `d` the unit direction of travel in the xz plane and `x = (x, z)`.
/// `omega` follows deep-water dispersion `omega^2 = g k` unless `speed_m_per_s` gives the phase
/// speed (`omega = k * speed`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wave {
    pub amplitude_m: f64,
    pub wavelength_m: f64,
    /// Direction of travel (x, z). Meant to be unit; it is normalised before use so a scene that
    /// writes (1, 1) still gets the stated wavelength.
    pub direction: [f64; 2],
    pub phase_rad: f64,
    pub speed_m_per_s: Option<f64>,
}

impl Wave {
    pub fn wavenumber_rad_per_m(&self) -> f64 {
        TAU / self.wavelength_m
    }

    /// `omega`: from the given phase speed, else from deep-water dispersion `sqrt(g k)`.
    pub fn angular_frequency_rad_per_s(&self) -> f64 {
        let k = self.wavenumber_rad_per_m();
        match self.speed_m_per_s {
            Some(speed) => k * speed,
            None => (GRAVITY_M_PER_S2 * k).sqrt(),
        }
    }

    /// Speed at which crests advance along `direction`: `omega / k`.
    pub fn phase_speed_m_per_s(&self) -> f64 {
        self.angular_frequency_rad_per_s() / self.wavenumber_rad_per_m()
    }

    /// The unit direction of travel.
    pub fn unit_direction(&self) -> [f64; 2] {
        let [dx, dz] = self.direction;
        let length = dx.hypot(dz);
        [dx / length, dz / length]
    }

    /// Checks that the wave can be evaluated: finite numbers, positive wavelength, a direction.
    pub fn validate(&self) -> Result<(), String> {
        let finite = [
            ("amplitude_m", self.amplitude_m),
            ("wavelength_m", self.wavelength_m),
            ("direction[0]", self.direction[0]),
            ("direction[1]", self.direction[1]),
            ("phase_rad", self.phase_rad),
        ];
        for (name, value) in finite {
            if !value.is_finite() {
                return Err(format!("{name} must be a finite number, got {value}"));
            }
        }
        if self.wavelength_m <= 0.0 {
            return Err(format!(
                "wavelength_m must be > 0, got {}",
                self.wavelength_m
            ));
        }
        if self.direction[0].hypot(self.direction[1]) < 1e-9 {
            return Err("direction must be a non-zero (x, z) vector".to_string());
        }
        if let Some(speed) = self.speed_m_per_s {
            if !speed.is_finite() {
                return Err(format!(
                    "speed_m_per_s must be a finite number, got {speed}"
                ));
            }
        }
        Ok(())
    }
}

/// The water of a scene: the still level and the waves on it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WaveField {
    pub level_m: f64,
    pub waves: Vec<Wave>,
}

impl WaveField {
    /// Every wave valid and the level finite; the first problem found is reported.
    pub fn validate(&self) -> Result<(), WaterError> {
        if !self.level_m.is_finite() {
            return Err(WaterError::InvalidLevel {
                level_m: self.level_m,
            });
        }
        for (index, wave) in self.waves.iter().enumerate() {
            wave.validate()
                .map_err(|reason| WaterError::InvalidWave { index, reason })?;
        }
        Ok(())
    }

    /// The surface frozen at `time_secs`: the exact height field of that frame.
    pub fn at(&self, time_secs: f64) -> WaterSurface {
        let terms = self
            .waves
            .iter()
            .map(|wave| {
                let k = wave.wavenumber_rad_per_m();
                let [dx, dz] = wave.unit_direction();
                WaveTerm {
                    amplitude_m: wave.amplitude_m,
                    kx: k * dx,
                    kz: k * dz,
                    phase_now_rad: wave.phase_rad - wave.angular_frequency_rad_per_s() * time_secs,
                }
            })
            .collect();
        WaterSurface {
            level_m: self.level_m,
            time_secs,
            terms,
        }
    }

    /// Lowest and highest heights the surface can ever reach: level -/+ the sum of |amplitudes|.
    pub fn height_bounds_m(&self) -> (f64, f64) {
        let reach: f64 = self.waves.iter().map(|wave| wave.amplitude_m.abs()).sum();
        (self.level_m - reach, self.level_m + reach)
    }
}

/// One wave at a fixed time: `a cos(kx x + kz z + phase_now)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct WaveTerm {
    amplitude_m: f64,
    kx: f64,
    kz: f64,
    /// `phase - omega t`, folded in once per frame so evaluation is one cosine per wave.
    phase_now_rad: f64,
}

/// The wave field at one instant, as an exact [`HeightField`] (owned, so it can outlive the field).
#[derive(Clone, Debug, PartialEq)]
pub struct WaterSurface {
    level_m: f64,
    time_secs: f64,
    terms: Vec<WaveTerm>,
}

impl WaterSurface {
    pub fn time_secs(&self) -> f64 {
        self.time_secs
    }

    pub fn level_m(&self) -> f64 {
        self.level_m
    }
}

/// `(sin x, cos x)` of a wave's phase, within 2e-16 of the true values (tested against the
/// standard library's): every evaluation of the waves goes through it, so the height, its
/// derivatives and every query of the surface agree bit for bit. The phase is reduced by the
/// nearest multiple of pi/2 (Cody-Waite, pi/2 in two parts: exact products for |x| < 2^19 pi/2),
/// then the fdlibm minimax kernels on [-pi/4, pi/4]. Several times cheaper than the library's
/// `sin_cos` (which reduces for any argument and rounds correctly); beyond the reduction's range,
/// and for non-finite phases, the library's. The visibility walks evaluate the waves at every
/// step, so this is most of their cost on calm water.
// The constants are fdlibm's as published; each decimal rounds to the double fdlibm means.
#[allow(clippy::excessive_precision)]
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    // pi/2 = PIO2_HI + PIO2_LO: the high part has 33 significant bits (fdlibm's pio2_1, pio2_1t).
    const PIO2_HI: f64 = 1.570_796_326_734_125_614_17;
    const PIO2_LO: f64 = 6.077_100_506_506_192_249_32e-11;
    const S: [f64; 6] = [
        -1.666_666_666_666_663_243_48e-1,
        8.333_333_333_322_489_461_24e-3,
        -1.984_126_982_985_794_931_34e-4,
        2.755_731_370_707_006_767_89e-6,
        -2.505_076_025_340_686_341_95e-8,
        1.589_690_995_211_550_102_21e-10,
    ];
    const C: [f64; 6] = [
        4.166_666_666_666_660_190_37e-2,
        -1.388_888_888_887_410_957_49e-3,
        2.480_158_728_947_672_941_78e-5,
        -2.755_731_435_139_066_330_35e-7,
        2.087_572_321_298_174_827_90e-9,
        -1.135_964_755_778_819_482_65e-11,
    ];
    if x.is_nan() || x.abs() >= 823_549.6 {
        return x.sin_cos();
    }
    // Round to the nearest integer (ties to even) by adding and subtracting 1.5 * 2^52, exact
    // for |y| < 2^51 (here |y| < 2^19): two additions, where `f64::round` is a library call on
    // baseline x86-64 (no SSE4.1), a fifth of this function's time. A tie gives r = +-pi/4
    // either way, inside the kernels' range.
    const ROUNDING_SHIFT: f64 = 6_755_399_441_055_744.0;
    let n = (x * std::f64::consts::FRAC_2_PI + ROUNDING_SHIFT) - ROUNDING_SHIFT;
    let r = (x - n * PIO2_HI) - n * PIO2_LO;
    let z = r * r;
    let sin = r + r * z * (S[0] + z * (S[1] + z * (S[2] + z * (S[3] + z * (S[4] + z * S[5])))));
    let tail = z * (C[0] + z * (C[1] + z * (C[2] + z * (C[3] + z * (C[4] + z * C[5])))));
    let half = 0.5 * z;
    let w = 1.0 - half;
    let cos = w + (((1.0 - w) - half) + z * tail);
    match (n as i64) & 3 {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

impl HeightField for WaterSurface {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.level_m
            + self
                .terms
                .iter()
                .map(|term| {
                    term.amplitude_m * sin_cos(term.kx * x + term.kz * z + term.phase_now_rad).1
                })
                .sum::<f64>()
    }

    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        self.terms.iter().fold((0.0, 0.0), |(gx, gz), term| {
            let slope =
                -term.amplitude_m * sin_cos(term.kx * x + term.kz * z + term.phase_now_rad).0;
            (gx + slope * term.kx, gz + slope * term.kz)
        })
    }

    fn height_and_gradient(&self, x: f64, z: f64) -> (f64, (f64, f64)) {
        let (mut h, mut gx, mut gz) = (self.level_m, 0.0, 0.0);
        for term in &self.terms {
            let (sin, cos) = sin_cos(term.kx * x + term.kz * z + term.phase_now_rad);
            h += term.amplitude_m * cos;
            let slope = -term.amplitude_m * sin;
            gx += slope * term.kx;
            gz += slope * term.kz;
        }
        (h, (gx, gz))
    }

    /// One `sin_cos` per wave for all three.
    fn height_derivatives(&self, x: f64, z: f64) -> (f64, (f64, f64), (f64, f64, f64)) {
        let (mut h, mut gx, mut gz) = (self.level_m, 0.0, 0.0);
        let (mut xx, mut xz, mut zz) = (0.0, 0.0, 0.0);
        for term in &self.terms {
            let (sin, cos) = sin_cos(term.kx * x + term.kz * z + term.phase_now_rad);
            let (value, slope) = (term.amplitude_m * cos, -term.amplitude_m * sin);
            h += value;
            gx += slope * term.kx;
            gz += slope * term.kz;
            xx -= value * term.kx * term.kx;
            xz -= value * term.kx * term.kz;
            zz -= value * term.kz * term.kz;
        }
        (h, (gx, gz), (xx, xz, zz))
    }

    /// Analytic: each term `a cos(phi)` contributes `-a cos(phi) (kx^2, kx kz, kz^2)`.
    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        self.terms
            .iter()
            .fold((0.0, 0.0, 0.0), |(xx, xz, zz), term| {
                let curvature =
                    -term.amplitude_m * sin_cos(term.kx * x + term.kz * z + term.phase_now_rad).1;
                (
                    xx + curvature * term.kx * term.kx,
                    xz + curvature * term.kx * term.kz,
                    zz + curvature * term.kz * term.kz,
                )
            })
    }
}

impl WaterSurface {
    /// Bounds over the whole plane: the largest |grad h| and the largest second directional
    /// derivative `|u^T H u|` for unit horizontal `u` (sum of `a k` and of `a k^2` over the waves).
    /// What a root finder needs to step along a ray without ever stepping over the surface.
    pub fn slope_and_curvature_bounds(&self) -> (f64, f64) {
        self.terms
            .iter()
            .fold((0.0, 0.0), |(slope, curvature), term| {
                let k = term.kx.hypot(term.kz);
                let a = term.amplitude_m.abs();
                (slope + a * k, curvature + a * k * k)
            })
    }

    /// Lowest and highest heights this surface can reach: level -/+ the sum of |amplitudes|.
    pub fn height_bounds_m(&self) -> (f64, f64) {
        let reach: f64 = self.terms.iter().map(|term| term.amplitude_m.abs()).sum();
        (self.level_m - reach, self.level_m + reach)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wave(amplitude_m: f64, wavelength_m: f64, direction: [f64; 2], phase_rad: f64) -> Wave {
        Wave {
            amplitude_m,
            wavelength_m,
            direction,
            phase_rad,
            speed_m_per_s: None,
        }
    }

    fn choppy_field() -> WaveField {
        WaveField {
            level_m: -0.25,
            waves: vec![
                wave(0.05, 3.0, [1.0, 0.0], 0.3),
                wave(0.02, 1.3, [0.6, 0.8], 1.7),
                wave(0.012, 0.7, [-0.28, 0.96], -2.0),
                Wave {
                    speed_m_per_s: Some(0.4),
                    ..wave(0.008, 2.2, [0.0, -1.0], 0.0)
                },
            ],
        }
    }

    /// Seeded points, so the test repeats exactly.
    fn seeded_points(count: usize, half_extent_m: f64) -> Vec<(f64, f64)> {
        let mut rng = crate::seeded::SplitMix64::new(0x5eed_1234_abcd_0001);
        let mut next = move || rng.range(-1.0, 1.0);
        (0..count)
            .map(|_| (next() * half_extent_m, next() * half_extent_m))
            .collect()
    }

    #[test]
    fn gradient_matches_central_differences() {
        let surface = choppy_field().at(3.7);
        let step_m = 1e-5;
        for (x, z) in seeded_points(200, 8.0) {
            let (gx, gz) = surface.gradient(x, z);
            let fd_x =
                (surface.height(x + step_m, z) - surface.height(x - step_m, z)) / (2.0 * step_m);
            let fd_z =
                (surface.height(x, z + step_m) - surface.height(x, z - step_m)) / (2.0 * step_m);
            // Central differences: truncation ~ h^2 |h'''| / 6 ~ 1e-10 * (a k^3 ~ 10), round-off
            // ~ 1e-16 / 1e-5 = 1e-11; slopes themselves are ~0.1.
            assert!(
                (gx - fd_x).abs() < 1e-8,
                "dh/dx at ({x}, {z}): {gx} vs {fd_x}"
            );
            assert!(
                (gz - fd_z).abs() < 1e-8,
                "dh/dz at ({x}, {z}): {gz} vs {fd_z}"
            );
        }
    }

    #[test]
    fn hessian_matches_differences_of_the_gradient() {
        let surface = choppy_field().at(2.1);
        let step_m = 1e-5;
        for (x, z) in seeded_points(200, 8.0) {
            let (xx, xz, zz) = surface.hessian(x, z);
            let (gx_p, gz_p) = surface.gradient(x + step_m, z);
            let (gx_m, gz_m) = surface.gradient(x - step_m, z);
            let (zx_p, zz_p) = surface.gradient(x, z + step_m);
            let (zx_m, zz_m) = surface.gradient(x, z - step_m);
            // Same error budget as the gradient test, one derivative higher (a k^4 ~ 1e2 times
            // h^2 / 6 ~ 2e-9); curvatures themselves are ~1.
            let fd = [
                (gx_p - gx_m) / (2.0 * step_m),
                (gz_p - gz_m) / (2.0 * step_m),
                (zx_p - zx_m) / (2.0 * step_m),
                (zz_p - zz_m) / (2.0 * step_m),
            ];
            assert!(
                (xx - fd[0]).abs() < 1e-7,
                "h_xx at ({x}, {z}): {xx} vs {}",
                fd[0]
            );
            assert!(
                (xz - fd[1]).abs() < 1e-7,
                "h_xz at ({x}, {z}): {xz} vs {}",
                fd[1]
            );
            assert!(
                (xz - fd[2]).abs() < 1e-7,
                "h_zx at ({x}, {z}): {xz} vs {}",
                fd[2]
            );
            assert!(
                (zz - fd[3]).abs() < 1e-7,
                "h_zz at ({x}, {z}): {zz} vs {}",
                fd[3]
            );
            // The trait's default (differences of the gradient) agrees with the analytic form.
            let default = DefaultHessian(&surface).hessian(x, z);
            assert!((default.0 - xx).abs() < 1e-6 && (default.1 - xz).abs() < 1e-6);
            assert!((default.2 - zz).abs() < 1e-6, "{default:?} vs {zz}");
        }
    }

    /// The fused evaluation Newton uses is the three separate ones.
    #[test]
    fn fused_derivatives_equal_the_separate_ones() {
        let surface = choppy_field().at(0.4);
        for (x, z) in seeded_points(100, 8.0) {
            let (h, g, hessian) = surface.height_derivatives(x, z);
            assert!((h - surface.height(x, z)).abs() < 1e-15);
            let (gx, gz) = surface.gradient(x, z);
            assert!((g.0 - gx).abs() < 1e-15 && (g.1 - gz).abs() < 1e-15);
            let (xx, xz, zz) = surface.hessian(x, z);
            assert!((hessian.0 - xx).abs() < 1e-14 && (hessian.1 - xz).abs() < 1e-14);
            assert!((hessian.2 - zz).abs() < 1e-14);
        }
    }

    /// The surface with the trait's default `hessian`.
    struct DefaultHessian<'a>(&'a WaterSurface);
    impl HeightField for DefaultHessian<'_> {
        fn height(&self, x: f64, z: f64) -> f64 {
            self.0.height(x, z)
        }
        fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
            self.0.gradient(x, z)
        }
    }

    #[test]
    fn normals_are_unit_point_up_and_are_perpendicular_to_the_surface() {
        let surface = choppy_field().at(1.25);
        let step_m = 1e-4;
        for (x, z) in seeded_points(200, 8.0) {
            let normal = surface.normal(x, z);
            assert!((normal.length() - 1.0).abs() < 1e-12);
            assert!(normal.y > 0.0);
            let point = glam::DVec3::new(x, surface.height(x, z), z);
            let along_x = glam::DVec3::new(x + step_m, surface.height(x + step_m, z), z) - point;
            let along_z = glam::DVec3::new(x, surface.height(x, z + step_m), z + step_m) - point;
            // Tangents from finite steps differ from the exact ones by O(step^2 * curvature).
            assert!(normal.dot(along_x.normalize()).abs() < 1e-3);
            assert!(normal.dot(along_z.normalize()).abs() < 1e-3);
        }
    }

    #[test]
    fn deep_water_period_is_the_textbook_value() {
        // T = sqrt(2 pi lambda / g): for 10 m waves about 2.53 s.
        let w = wave(0.1, 10.0, [1.0, 0.0], 0.0);
        let period_secs = TAU / w.angular_frequency_rad_per_s();
        let expected = (TAU * 10.0 / GRAVITY_M_PER_S2).sqrt();
        assert!((period_secs - expected).abs() < 1e-12);
        assert!((period_secs - 2.531).abs() < 1e-3);
        let field = WaveField {
            level_m: 0.0,
            waves: vec![w],
        };
        for (x, z) in seeded_points(20, 5.0) {
            let now = field.at(0.8).height(x, z);
            let one_period_later = field.at(0.8 + period_secs).height(x, z);
            assert!((now - one_period_later).abs() < 1e-12);
        }
    }

    #[test]
    fn crests_advance_at_the_deep_water_phase_speed_along_the_direction() {
        let w = wave(0.05, 2.5, [0.6, -0.8], 0.9);
        let field = WaveField {
            level_m: 0.3,
            waves: vec![w],
        };
        let k = TAU / 2.5;
        let speed = (GRAVITY_M_PER_S2 / k).sqrt();
        assert!((w.phase_speed_m_per_s() - speed).abs() < 1e-12);
        let elapsed_secs = 0.37;
        let (shift_x, shift_z) = (0.6 * speed * elapsed_secs, -0.8 * speed * elapsed_secs);
        let before = field.at(1.0);
        let after = field.at(1.0 + elapsed_secs);
        let mut largest_mismatch_if_too_fast: f64 = 0.0;
        for (x, z) in seeded_points(50, 4.0) {
            let moved = after.height(x + shift_x, z + shift_z);
            assert!(
                (before.height(x, z) - moved).abs() < 1e-12,
                "pattern did not translate"
            );
            let too_far = after.height(x + 1.1 * shift_x, z + 1.1 * shift_z);
            largest_mismatch_if_too_fast =
                largest_mismatch_if_too_fast.max((before.height(x, z) - too_far).abs());
        }
        // The check above can fail: 10 % too fast a speed shifts the pattern by 0.1 c t = 7 cm, a
        // mismatch up to a k 0.07 m ~ 9 mm, far above the 1e-12 tolerance.
        assert!(
            largest_mismatch_if_too_fast > 1e-3,
            "{largest_mismatch_if_too_fast}"
        );
    }

    #[test]
    fn given_speed_overrides_dispersion() {
        let w = Wave {
            speed_m_per_s: Some(0.5),
            ..wave(0.02, 1.0, [0.0, 1.0], 0.0)
        };
        assert!((w.phase_speed_m_per_s() - 0.5).abs() < 1e-12);
        assert!((w.angular_frequency_rad_per_s() - TAU * 0.5).abs() < 1e-12);
        let field = WaveField {
            level_m: 0.0,
            waves: vec![w],
        };
        for (x, z) in seeded_points(20, 3.0) {
            let moved = field.at(2.0).height(x, z + 0.5 * 2.0);
            assert!((field.at(0.0).height(x, z) - moved).abs() < 1e-12);
        }
    }

    /// The waves' `sin_cos` against the standard library's, over phases a scene reaches (waves of
    /// millimetres to metres, pools of metres, minutes of time) and beyond its reduction's range.
    #[test]
    fn wave_sin_cos_matches_the_library() {
        let mut rng = crate::seeded::SplitMix64::new(0x51_4C05);
        let mut worst: f64 = 0.0;
        for i in 0..1_000_000 {
            let scale = [1.0, 10.0, 1e3, 1e5, 1e6, 1e8][i % 6];
            let x = rng.range(-scale, scale);
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            worst = worst.max((s - s0).abs()).max((c - c0).abs());
        }
        for x in [
            0.0,
            -0.0,
            1e-300,
            std::f64::consts::FRAC_PI_4,
            823_549.5,
            823_549.7,
        ] {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            worst = worst.max((s - s0).abs()).max((c - c0).abs());
        }
        assert!(worst <= 2e-16, "worst difference {worst:e}");
        assert!(sin_cos(f64::NAN).0.is_nan() && sin_cos(f64::INFINITY).1.is_nan());
    }

    #[test]
    fn height_is_the_formula_and_direction_is_normalised() {
        let unnormalised = wave(0.07, 4.0, [3.0, 4.0], 0.5);
        let field = WaveField {
            level_m: 1.0,
            waves: vec![unnormalised],
        };
        let (x, z, t) = (1.3, -0.4, 2.2);
        let k = TAU / 4.0;
        let omega = (GRAVITY_M_PER_S2 * k).sqrt();
        let expected = 1.0 + 0.07 * (k * (0.6 * x + 0.8 * z) - omega * t + 0.5).cos();
        assert!((field.at(t).height(x, z) - expected).abs() < 1e-14);
        assert_eq!(field.height_bounds_m(), (1.0 - 0.07, 1.0 + 0.07));
    }

    #[test]
    fn validation_names_the_wave_and_the_problem() {
        let mut field = choppy_field();
        assert_eq!(field.validate(), Ok(()));
        field.waves[2].wavelength_m = 0.0;
        let message = field.validate().unwrap_err().to_string();
        assert!(
            message.contains("wave 2") && message.contains("wavelength_m"),
            "{message}"
        );
        field.waves[2].wavelength_m = 1.0;
        field.waves[1].direction = [0.0, 0.0];
        assert!(field
            .validate()
            .unwrap_err()
            .to_string()
            .contains("direction"));
        field.waves[1].direction = [1.0, 0.0];
        field.waves[0].amplitude_m = f64::NAN;
        assert!(field
            .validate()
            .unwrap_err()
            .to_string()
            .contains("amplitude_m"));
        field.waves[0].amplitude_m = 0.1;
        field.level_m = f64::INFINITY;
        assert!(matches!(
            field.validate(),
            Err(WaterError::InvalidLevel { .. })
        ));
    }
}
