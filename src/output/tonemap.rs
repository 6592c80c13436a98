//! Display previews: receives a frame's linear HDR beauty and returns an 8-bit sRGB image
//! (exposure, then the ACES filmic curve as fitted by Stephen Hill, then the sRGB transfer
//! function), and saves PNGs atomically.
//!
//! Why ACES-fitted rather than Reinhard-extended: pool frames hold sun glints on the water that
//! are hundreds of times brighter than the tiles. Reinhard-extended needs a white point, and a
//! per-frame white point (the brightest pixel) would make the tiles' brightness depend on whether
//! a glint happens to be in view, which flickers across an animation and makes goldens fragile; a
//! fixed one clips glints to flat patches. The fitted ACES curve is fixed (no per-frame input),
//! rolls highlights off smoothly to white, and its input and output matrices desaturate very
//! bright colours the way film does, so a glint turns white instead of a saturated primary.

use std::io::Write;
use std::path::Path;

use image::{ImageEncoder, RgbaImage};

use super::{write_atomically, OutputError};
use crate::draw::RenderedFrame;

/// Inputs above this (the largest finite half float) are clamped before the curve: the curve is
/// at 1 long before, and larger values would overflow its quadratic terms to inf/inf = NaN.
const LARGEST_TONEMAPPED_RADIANCE: f32 = 65504.0;

/// sRGB linear -> ACES AP1 with the RRT's saturation adjustment folded in (Hill, BakingLab).
const ACES_INPUT: [[f32; 3]; 3] = [
    [0.59719, 0.35458, 0.04823],
    [0.07600, 0.90834, 0.01566],
    [0.02840, 0.13383, 0.83777],
];
/// ODT output back to sRGB linear (Hill, BakingLab).
const ACES_OUTPUT: [[f32; 3]; 3] = [
    [1.60475, -0.53108, -0.07367],
    [-0.10208, 1.10813, -0.00605],
    [-0.00327, -0.07276, 1.07602],
];

fn multiply(matrix: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    matrix.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2])
}

/// Rational fit of the ACES reference rendering transform followed by the output transform.
fn rrt_and_odt_fit(v: f32) -> f32 {
    let a = v * (v + 0.0245786) - 0.000090537;
    let b = v * (0.983729 * v + 0.432951) + 0.238081;
    a / b
}

/// The ACES-fitted curve on linear sRGB radiance; returns display-linear values in [0, 1].
pub fn aces_fitted(linear_rgb: [f32; 3]) -> [f32; 3] {
    let sanitised = linear_rgb.map(|c| {
        if c.is_nan() {
            0.0
        } else {
            c.clamp(0.0, LARGEST_TONEMAPPED_RADIANCE)
        }
    });
    let curved = multiply(&ACES_INPUT, sanitised).map(rrt_and_odt_fit);
    multiply(&ACES_OUTPUT, curved).map(|c| c.clamp(0.0, 1.0))
}

/// The sRGB transfer function (IEC 61966-2-1) on a display-linear value in [0, 1].
pub fn srgb_encode(linear: f32) -> f32 {
    crate::color::linear_to_srgb(linear as f64) as f32
}

fn to_u8(unit: f32) -> u8 {
    (unit.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// One linear colour as the tone-mapped images show it: times `exposure_scale`, [`aces_fitted`],
/// sRGB-encoded bytes.
pub fn display_srgb8(linear_rgb: [f32; 3], exposure_scale: f32) -> [u8; 3] {
    aces_fitted(linear_rgb.map(|c| c * exposure_scale)).map(|c| to_u8(srgb_encode(c)))
}

/// Tone-maps the beauty of `frame`: multiplies by `2^exposure_stops`, applies [`aces_fitted`],
/// encodes sRGB. Alpha is copied (clamped to [0, 1]) without a curve. NaN counts as black.
pub fn tonemap_srgb8(frame: &RenderedFrame, exposure_stops: f32) -> RgbaImage {
    let exposure_scale = exposure_stops.exp2();
    let pixel_count = frame.width as usize * frame.height as usize;
    let mut bytes = Vec::with_capacity(pixel_count * 4);
    for rgba in frame.beauty_rgba.iter().take(pixel_count) {
        bytes.extend(display_srgb8([rgba[0], rgba[1], rgba[2]], exposure_scale));
        bytes.push(to_u8(if rgba[3].is_nan() { 0.0 } else { rgba[3] }));
    }
    // A short beauty buffer is a contract violation upstream; pad with transparent black rather
    // than panic in a preview.
    bytes.resize(pixel_count * 4, 0);
    RgbaImage::from_raw(frame.width, frame.height, bytes)
        .expect("buffer sized to width * height * 4")
}

/// Saves `image` as a PNG at `path` via a synced temporary file and a rename.
pub fn save_png_atomic(path: &Path, image: &RgbaImage) -> Result<(), OutputError> {
    write_atomically(path, |file| {
        let mut writer = std::io::BufWriter::new(file);
        image::codecs::png::PngEncoder::new(&mut writer)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ExtendedColorType::Rgba8,
            )
            .map_err(|error| format!("PNG encoding: {error}"))?;
        // Flush explicitly: dropping a BufWriter would swallow a failed final write.
        writer.flush().map_err(|error| error.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey_frame(values: &[f32]) -> RenderedFrame {
        RenderedFrame {
            width: values.len() as u32,
            height: 1,
            beauty_rgba: values.iter().map(|&v| [v, v, v, 1.0]).collect(),
            depth_m: vec![1.0; values.len()],
            position: vec![[0.0; 3]; values.len()],
            flags: vec![0; values.len()],
            object: vec![0; values.len()],
            ..Default::default()
        }
    }

    #[test]
    fn srgb_encode_matches_known_values() {
        assert_eq!(to_u8(srgb_encode(0.0)), 0);
        assert_eq!(to_u8(srgb_encode(1.0)), 255);
        // 18% grey encodes to 118 in sRGB (the standard figure).
        assert_eq!(to_u8(srgb_encode(0.18)), 118);
        // Continuity at the knee of the piecewise function.
        assert!(
            (0.0031308f32 * 12.92 - (1.055 * 0.0031308f32.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6
        );
    }

    #[test]
    fn curve_is_monotonic_black_at_zero_and_white_at_glints() {
        assert_eq!(aces_fitted([0.0; 3]), [0.0; 3]);
        let mut previous = -1.0;
        for step in 0..400 {
            let radiance = 1e-4 * 1.05f32.powi(step);
            let value = aces_fitted([radiance; 3])[1];
            assert!(
                value >= previous,
                "not monotonic at {radiance}: {value} < {previous}"
            );
            previous = value;
        }
        // A glint hundreds of times the diffuse level saturates to white, in every channel.
        let glint = aces_fitted([300.0, 250.0, 200.0]);
        assert!(glint.iter().all(|&c| c > 0.99), "{glint:?}");
    }

    #[test]
    fn non_finite_inputs_do_not_produce_garbage() {
        let image = tonemap_srgb8(&grey_frame(&[f32::NAN, f32::INFINITY, -5.0, 1e30]), 0.0);
        let pixels: Vec<[u8; 4]> = image.pixels().map(|p| p.0).collect();
        assert_eq!(pixels[0], [0, 0, 0, 255]);
        assert_eq!(pixels[1], [255, 255, 255, 255]);
        assert_eq!(pixels[2], [0, 0, 0, 255]);
        assert_eq!(pixels[3], [255, 255, 255, 255]);
    }

    #[test]
    fn one_stop_of_exposure_equals_doubling_radiance() {
        let brighter = tonemap_srgb8(&grey_frame(&[0.05, 0.2, 0.8]), 1.0);
        let doubled = tonemap_srgb8(&grey_frame(&[0.1, 0.4, 1.6]), 0.0);
        assert_eq!(brighter, doubled);
        let darker = tonemap_srgb8(&grey_frame(&[0.05, 0.2, 0.8]), 0.0);
        assert!(darker
            .pixels()
            .zip(brighter.pixels())
            .all(|(d, b)| d.0[0] < b.0[0]));
    }

    #[test]
    fn png_round_trip_and_no_temporary_left() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("previews").join("pool.0001.png");
        let image = tonemap_srgb8(&grey_frame(&[0.0, 0.1, 1.0, 10.0]), 0.0);
        save_png_atomic(&path, &image).unwrap();
        assert_eq!(image::open(&path).unwrap().to_rgba8(), image);
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("pool.0001.png")]);
    }
}
