//! The sRGB transfer function (IEC 61966-2-1), in one place for every stage that moves colours
//! between sRGB-encoded values (scene files, texture bytes, PNG previews) and linear light.

/// sRGB-encoded component in [0, 1] to linear light.
pub fn srgb_to_linear(encoded: f64) -> f64 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light to an sRGB-encoded component, clamped to [0, 1] first.
pub fn linear_to_srgb(linear: f64) -> f64 {
    let c = linear.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// An 8-bit sRGB byte to linear light.
pub fn srgb8_to_linear(encoded: u8) -> f32 {
    srgb_to_linear(encoded as f64 / 255.0) as f32
}

/// Linear light to the nearest 8-bit sRGB byte.
pub fn linear_to_srgb8(linear: f32) -> u8 {
    (linear_to_srgb(linear as f64) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_round_trips_and_known_values_hold() {
        for byte in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(byte)), byte);
        }
        // 18 % grey encodes to 118; the linear segment meets the power segment continuously.
        assert_eq!(linear_to_srgb8(0.18), 118);
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-12);
        let knee: f64 = 0.003_130_8;
        assert!((knee * 12.92 - (1.055 * knee.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
        assert!((linear_to_srgb(2.0) - 1.0).abs() < 1e-12, "clamped above");
        assert_eq!(linear_to_srgb(-1.0), 0.0);
    }
}
