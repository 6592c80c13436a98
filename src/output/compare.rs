//! Image comparison: receives two 8-bit sRGB images (tone-mapped previews) and returns NVIDIA's
//! FLIP error (per-pixel perceptual difference in [0, 1], its mean and percentiles, a magma heat
//! map). FLIP compares RGB only: previews are opaque, so alpha is ignored. Verdicts on frames
//! (thresholds, goldens, reports) are the business of [`crate::check`].

use image::RgbaImage;

/// FLIP of a test image against a reference.
#[derive(Clone, Debug)]
pub struct FlipResult {
    pub mean: f32,
    /// The 99th percentile of the per-pixel error.
    pub p99: f32,
    /// The per-pixel error rendered with the magma colour map (black = equal, yellow = 1).
    pub error_map_png: RgbaImage,
    /// Per-pixel FLIP errors in [0, 1], sorted ascending (for [`FlipResult::percentile`]).
    sorted_errors: Vec<f32>,
}

impl FlipResult {
    /// The error at fraction `p` in [0, 1] of the pixels (nearest rank: at least a fraction `p`
    /// of the pixels have an error at most this).
    pub fn percentile(&self, p: f32) -> f32 {
        percentile_of_sorted(&self.sorted_errors, p)
    }
}

pub(crate) fn percentile_of_sorted(sorted: &[f32], p: f32) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    // p arrives as f32 (0.99 is stored as 0.99000001): without the relative slack, 0.99 of 100
    // pixels would round up to rank 100.
    let exact_rank = p.clamp(0.0, 1.0) as f64 * sorted.len() as f64;
    let rank = (exact_rank * (1.0 - 1e-6)).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// Two images of different sizes cannot be compared pixel by pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("image sizes differ: reference {reference_width}x{reference_height}, test {test_width}x{test_height}")]
pub struct SizeMismatch {
    pub reference_width: u32,
    pub reference_height: u32,
    pub test_width: u32,
    pub test_height: u32,
}

fn rgb_bytes(image: &RgbaImage) -> Vec<u8> {
    image
        .pixels()
        .flat_map(|pixel| [pixel.0[0], pixel.0[1], pixel.0[2]])
        .collect()
}

/// FLIP (LDR) of `test` against `reference` at the default viewing conditions (a 0.7 m distant
/// 24" 4K monitor, about 67 pixels per degree).
pub fn flip_ldr(reference: &RgbaImage, test: &RgbaImage) -> Result<FlipResult, SizeMismatch> {
    if reference.dimensions() != test.dimensions() {
        return Err(SizeMismatch {
            reference_width: reference.width(),
            reference_height: reference.height(),
            test_width: test.width(),
            test_height: test.height(),
        });
    }
    let (width, height) = reference.dimensions();
    if width == 0 || height == 0 {
        return Ok(FlipResult {
            mean: 0.0,
            p99: 0.0,
            error_map_png: RgbaImage::new(width, height),
            sorted_errors: vec![],
        });
    }
    let reference_flip = nv_flip::FlipImageRgb8::with_data(width, height, &rgb_bytes(reference));
    let test_flip = nv_flip::FlipImageRgb8::with_data(width, height, &rgb_bytes(test));
    let error_map = nv_flip::flip(
        reference_flip,
        test_flip,
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );

    let mut sorted_errors = error_map.to_vec();
    let mean =
        (sorted_errors.iter().map(|&e| e as f64).sum::<f64>() / sorted_errors.len() as f64) as f32;
    sorted_errors.sort_by(f32::total_cmp);
    let magma_rgb = error_map.apply_color_lut(&nv_flip::magma_lut()).to_vec();
    let magma_rgba = magma_rgb
        .chunks_exact(3)
        .flat_map(|rgb| [rgb[0], rgb[1], rgb[2], 255])
        .collect();
    let error_map_png =
        RgbaImage::from_raw(width, height, magma_rgba).expect("magma map sized to the image");
    Ok(FlipResult {
        mean,
        p99: percentile_of_sorted(&sorted_errors, 0.99),
        error_map_png,
        sorted_errors,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded pattern: smooth gradients plus a checker, like tiles seen through water.
    fn pattern(width: u32, height: u32, seed: u32) -> RgbaImage {
        RgbaImage::from_fn(width, height, |x, y| {
            let checker: u32 = if ((x / 8) + (y / 8) + seed).is_multiple_of(2) {
                40
            } else {
                0
            };
            let channel = |value: u32| value.min(255) as u8;
            image::Rgba([
                channel(x * 255 / width),
                channel(y * 200 / height + checker / 2),
                channel(128 + checker),
                255,
            ])
        })
    }

    #[test]
    fn identical_images_have_zero_error() {
        let image = pattern(64, 48, 0);
        let result = flip_ldr(&image, &image).unwrap();
        assert_eq!(result.mean, 0.0);
        assert_eq!(result.p99, 0.0);
        assert_eq!(result.error_map_png.dimensions(), (64, 48));
    }

    #[test]
    fn error_grows_with_the_difference() {
        let reference = pattern(64, 48, 0);
        let slightly = RgbaImage::from_fn(64, 48, |x, y| {
            let mut pixel = *reference.get_pixel(x, y);
            pixel.0[0] = pixel.0[0].saturating_add(6);
            pixel
        });
        let very = pattern(64, 48, 1);
        let small = flip_ldr(&reference, &slightly).unwrap();
        let large = flip_ldr(&reference, &very).unwrap();
        assert!(
            small.mean > 0.0 && small.mean < large.mean,
            "{} vs {}",
            small.mean,
            large.mean
        );
        assert!(large.p99 >= large.mean);
        assert!(large.percentile(1.0) >= large.p99 && large.percentile(0.0) <= large.mean);
    }

    #[test]
    fn percentile_is_nearest_rank() {
        let sorted: Vec<f32> = (1..=100).map(|i| i as f32).collect();
        assert_eq!(percentile_of_sorted(&sorted, 0.99), 99.0);
        assert_eq!(percentile_of_sorted(&sorted, 0.5), 50.0);
        assert_eq!(percentile_of_sorted(&sorted, 0.0), 1.0);
        assert_eq!(percentile_of_sorted(&sorted, 1.0), 100.0);
    }
}
