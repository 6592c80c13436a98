//! Image comparison for golden tests: receives two 8-bit sRGB images (tone-mapped previews) and
//! returns NVIDIA's FLIP error (per-pixel perceptual difference in [0, 1], its mean and
//! percentiles, a magma heat map); [`check_golden`] compares a rendered image with the golden PNG
//! and explains every failure.
//!
//! Goldens are written only when `SNELL_BLESS=1` is set; a missing golden fails (a test that
//! writes its own expectation and passes checks nothing). A failed comparison writes
//! `<name>-actual.png` and `<name>-difference.png` beside the golden. FLIP compares RGB only:
//! previews are opaque, so alpha is ignored.

use std::path::{Path, PathBuf};

use image::RgbaImage;

use super::save_png_atomic;

/// The environment variable that makes [`check_golden`] (re)write goldens instead of comparing.
pub const BLESS_ENV: &str = "SNELL_BLESS";

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

fn percentile_of_sorted(sorted: &[f32], p: f32) -> f32 {
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

/// When a comparison passes. Each use should carry a comment giving the cause of its tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlipThreshold {
    /// The mean FLIP error is at most this.
    Mean(f32),
    /// At least a fraction `p` (in [0, 1]) of the pixels have a FLIP error at most `t`.
    Percentile { p: f32, t: f32 },
}

impl FlipThreshold {
    fn passes(&self, result: &FlipResult) -> bool {
        match *self {
            FlipThreshold::Mean(limit) => result.mean <= limit,
            FlipThreshold::Percentile { p, t } => result.percentile(p) <= t,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum GoldenOutcome {
    /// The image matched the golden within the threshold.
    Passed { mean: f32, p99: f32 },
    /// `SNELL_BLESS=1`: the golden was (re)written from the image.
    Blessed { path: PathBuf },
}

#[derive(Debug, thiserror::Error)]
pub enum GoldenError {
    #[error("golden {path} does not exist; render it, look at it, and bless it by rerunning with {BLESS_ENV}=1")]
    Missing { path: PathBuf },
    #[error("cannot read golden {path}: {cause}")]
    Unreadable { path: PathBuf, cause: String },
    #[error(
        "{path}: {mismatch}; the rendered image is in {actual}. If the new size is intended, rerun with {BLESS_ENV}=1"
    )]
    SizeDiffers {
        path: PathBuf,
        mismatch: SizeMismatch,
        actual: PathBuf,
    },
    #[error(
        "{path}: FLIP mean {mean:.5}, 99th percentile {p99:.5}, fails {threshold:?}; see {actual} and {difference}. \
         If the change is intended, rerun with {BLESS_ENV}=1"
    )]
    AboveThreshold {
        path: PathBuf,
        mean: f32,
        p99: f32,
        threshold: FlipThreshold,
        actual: PathBuf,
        difference: PathBuf,
    },
    #[error(transparent)]
    Output(#[from] super::OutputError),
}

/// Compares `actual` with `<golden_dir>/<name>.png`, or (re)writes that golden when the
/// environment has `SNELL_BLESS=1`.
pub fn check_golden(
    golden_dir: &Path,
    name: &str,
    actual: &RgbaImage,
    threshold: FlipThreshold,
) -> Result<GoldenOutcome, GoldenError> {
    let bless = std::env::var(BLESS_ENV).is_ok_and(|value| value == "1");
    check_golden_with(golden_dir, name, actual, threshold, bless)
}

/// [`check_golden`] with the bless decision made by the caller (tests cannot set the environment
/// safely while other tests run).
pub fn check_golden_with(
    golden_dir: &Path,
    name: &str,
    actual: &RgbaImage,
    threshold: FlipThreshold,
    bless: bool,
) -> Result<GoldenOutcome, GoldenError> {
    let golden_path = golden_dir.join(format!("{name}.png"));
    let actual_path = golden_dir.join(format!("{name}-actual.png"));
    let difference_path = golden_dir.join(format!("{name}-difference.png"));
    let remove_stale_failure_images = || {
        // Left from an earlier failing run; they would only mislead now.
        let _ = std::fs::remove_file(&actual_path);
        let _ = std::fs::remove_file(&difference_path);
    };
    if bless {
        save_png_atomic(&golden_path, actual)?;
        remove_stale_failure_images();
        return Ok(GoldenOutcome::Blessed { path: golden_path });
    }
    if !golden_path.exists() {
        return Err(GoldenError::Missing { path: golden_path });
    }
    let golden = image::open(&golden_path)
        .map_err(|error| GoldenError::Unreadable {
            path: golden_path.clone(),
            cause: error.to_string(),
        })?
        .to_rgba8();
    let result = match flip_ldr(&golden, actual) {
        Ok(result) => result,
        Err(mismatch) => {
            save_png_atomic(&actual_path, actual)?;
            return Err(GoldenError::SizeDiffers {
                path: golden_path,
                mismatch,
                actual: actual_path,
            });
        }
    };
    if threshold.passes(&result) {
        remove_stale_failure_images();
        return Ok(GoldenOutcome::Passed {
            mean: result.mean,
            p99: result.p99,
        });
    }
    save_png_atomic(&actual_path, actual)?;
    save_png_atomic(&difference_path, &result.error_map_png)?;
    Err(GoldenError::AboveThreshold {
        path: golden_path,
        mean: result.mean,
        p99: result.p99,
        threshold,
        actual: actual_path,
        difference: difference_path,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded pattern: smooth gradients plus a checker, like tiles seen through water.
    fn pattern(width: u32, height: u32, seed: u32) -> RgbaImage {
        RgbaImage::from_fn(width, height, |x, y| {
            let checker: u32 = if ((x / 8) + (y / 8) + seed) % 2 == 0 {
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
    fn identical_images_have_zero_error_and_pass() {
        let image = pattern(64, 48, 0);
        let result = flip_ldr(&image, &image).unwrap();
        assert_eq!(result.mean, 0.0);
        assert_eq!(result.p99, 0.0);
        assert_eq!(result.error_map_png.dimensions(), (64, 48));

        let temp = tempfile::tempdir().unwrap();
        image.save(temp.path().join("tiles.png")).unwrap();
        let outcome = check_golden_with(
            temp.path(),
            "tiles",
            &image,
            FlipThreshold::Mean(0.0),
            false,
        )
        .unwrap();
        assert_eq!(
            outcome,
            GoldenOutcome::Passed {
                mean: 0.0,
                p99: 0.0
            }
        );
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

    #[test]
    fn missing_golden_fails_and_says_how_to_bless() {
        let temp = tempfile::tempdir().unwrap();
        let error = check_golden_with(
            temp.path(),
            "absent",
            &pattern(8, 8, 0),
            FlipThreshold::Mean(0.01),
            false,
        )
        .unwrap_err();
        assert!(matches!(error, GoldenError::Missing { .. }));
        assert!(error.to_string().contains("SNELL_BLESS=1"), "{error}");
        assert!(
            !temp.path().join("absent.png").exists(),
            "a missing golden must not be written"
        );
    }

    #[test]
    fn very_different_image_fails_and_writes_actual_and_difference() {
        let temp = tempfile::tempdir().unwrap();
        pattern(64, 48, 0)
            .save(temp.path().join("tiles.png"))
            .unwrap();
        let actual = pattern(64, 48, 1);
        // Would pass a threshold of 1 (FLIP's maximum); fails any meaningful one.
        let error = check_golden_with(
            temp.path(),
            "tiles",
            &actual,
            FlipThreshold::Mean(0.01),
            false,
        )
        .unwrap_err();
        let GoldenError::AboveThreshold { mean, .. } = &error else {
            panic!("unexpected {error}")
        };
        assert!(*mean > 0.01);
        let message = error.to_string();
        assert!(
            message.contains("FLIP mean") && message.contains("SNELL_BLESS=1"),
            "{message}"
        );
        let written_actual = image::open(temp.path().join("tiles-actual.png"))
            .unwrap()
            .to_rgba8();
        assert_eq!(written_actual, actual);
        let difference = image::open(temp.path().join("tiles-difference.png"))
            .unwrap()
            .to_rgba8();
        assert_eq!(difference.dimensions(), (64, 48));

        let percentile = FlipThreshold::Percentile { p: 0.5, t: 0.001 };
        assert!(check_golden_with(temp.path(), "tiles", &actual, percentile, false).is_err());
    }

    #[test]
    fn size_difference_fails() {
        let temp = tempfile::tempdir().unwrap();
        pattern(64, 48, 0)
            .save(temp.path().join("tiles.png"))
            .unwrap();
        let error = check_golden_with(
            temp.path(),
            "tiles",
            &pattern(32, 48, 0),
            FlipThreshold::Mean(1.0),
            false,
        )
        .unwrap_err();
        assert!(matches!(error, GoldenError::SizeDiffers { .. }), "{error}");
        assert!(
            error.to_string().contains("64x48") && error.to_string().contains("32x48"),
            "{error}"
        );
        assert!(temp.path().join("tiles-actual.png").exists());
    }

    #[test]
    fn blessing_writes_the_golden_then_it_passes_and_stale_failures_go() {
        let temp = tempfile::tempdir().unwrap();
        let image = pattern(16, 16, 0);
        std::fs::write(temp.path().join("tiles-actual.png"), b"stale").unwrap();
        let outcome =
            check_golden_with(temp.path(), "tiles", &image, FlipThreshold::Mean(0.0), true)
                .unwrap();
        assert_eq!(
            outcome,
            GoldenOutcome::Blessed {
                path: temp.path().join("tiles.png")
            }
        );
        assert!(!temp.path().join("tiles-actual.png").exists());
        let outcome = check_golden_with(
            temp.path(),
            "tiles",
            &image,
            FlipThreshold::Mean(0.0),
            false,
        )
        .unwrap();
        assert!(matches!(outcome, GoldenOutcome::Passed { .. }));
    }
}
