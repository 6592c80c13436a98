//! `snell compare A.exr B.exr`: receives two EXR frames of the same shot (e.g. a linear-method
//! render and the ray-traced reference) and returns how far apart they are: the screen-space
//! position error of B against A ([`crate::output::position_error`]) over the pixels where both
//! see the same object and again outside A's flagged pixels, the mean FLIP of the tone-mapped
//! beauty, and the share of pixels whose seen object differs. A measurement, not a verdict:
//! `snell diff` / `snell check` judge frames against thresholds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::ToolError;
use crate::draw::RenderedFrame;
use crate::output::position_error::{compare_positions, PositionComparison, PositionErrorInput};
use crate::output::{flip_ldr, read_frame_exr, tonemap_srgb8};

/// What `snell compare` measures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    pub a: PathBuf,
    pub b: PathBuf,
    pub width: u32,
    pub height: u32,
    pub window_px: u32,
    /// Over every pixel where A and B see the same object.
    pub position_error: crate::output::position_error::PositionError,
    /// The same, leaving out the pixels flagged in A (any of its `flags.*` set).
    pub position_error_outside_flagged: crate::output::position_error::PositionError,
    /// Mean FLIP of B's tone-mapped beauty against A's (0 = identical).
    pub flip_mean: f32,
    /// Pixels whose seen object (or nothing) differs, over all pixels.
    pub object_mismatch_fraction: f64,
    pub object_mismatch_pixels: usize,
}

/// Reads a frame; a missing file or a file that is not one of snell's EXR frames is bad input.
pub fn read_frame(path: &Path) -> Result<RenderedFrame, ToolError> {
    if !path.is_file() {
        return Err(ToolError::InputFile {
            path: path.to_path_buf(),
            problem: if path.exists() {
                "is not a file (give an EXR frame written by snell render)".to_string()
            } else {
                "no such file (give an EXR frame written by snell render)".to_string()
            },
        });
    }
    read_frame_exr(path)
        .map(|(frame, _)| frame)
        .map_err(|error| ToolError::InputFile {
            path: path.to_path_buf(),
            problem: format!(
                "cannot be read as a snell EXR frame: {}",
                error
                    .to_string()
                    .trim_start_matches(&format!("cannot read {}: ", path.display()))
            ),
        })
}

/// Compares two frames in memory (`a_path`, `b_path` only name them in messages and the report).
pub fn compare_frames(
    a: &RenderedFrame,
    b: &RenderedFrame,
    a_path: &Path,
    b_path: &Path,
    window_px: u32,
) -> Result<Comparison, ToolError> {
    let PositionComparison {
        all,
        outside_flagged,
    } = compare_positions(a, b, window_px).map_err(|error| match error {
        PositionErrorInput::Size(size) => ToolError::Mismatch(format!(
            "{} is {}x{} but {} is {}x{}: only frames of the same size can be compared",
            a_path.display(),
            size.reference_width,
            size.reference_height,
            b_path.display(),
            size.test_width,
            size.test_height
        )),
        PositionErrorInput::ObjectLayer { which, .. } => ToolError::InputFile {
            path: if which == "A" { a_path } else { b_path }.to_path_buf(),
            problem: error.to_string().replacen(which, "the frame", 1),
        },
    })?;
    let flip = flip_ldr(&tonemap_srgb8(a, 0.0), &tonemap_srgb8(b, 0.0))
        .expect("sizes were checked equal above");
    let pixels = a.width as usize * a.height as usize;
    Ok(Comparison {
        a: a_path.to_path_buf(),
        b: b_path.to_path_buf(),
        width: a.width,
        height: a.height,
        window_px,
        position_error: all,
        position_error_outside_flagged: outside_flagged,
        flip_mean: flip.mean,
        object_mismatch_fraction: all.object_mismatch_fraction,
        object_mismatch_pixels: (all.object_mismatch_fraction * pixels as f64).round() as usize,
    })
}

/// Reads and compares two EXR frames.
pub fn compare_files(a: &Path, b: &Path, window_px: u32) -> Result<Comparison, ToolError> {
    let frame_a = read_frame(a)?;
    let frame_b = read_frame(b)?;
    compare_frames(&frame_a, &frame_b, a, b, window_px)
}

impl Comparison {
    /// The report as `snell compare` prints it.
    pub fn to_text(&self) -> String {
        let mut text = String::new();
        let _ = writeln!(
            text,
            "A {}\nB {}\n{}x{}, search window {} px",
            self.a.display(),
            self.b.display(),
            self.width,
            self.height,
            self.window_px
        );
        let row = |label: &str, e: &crate::output::position_error::PositionError| {
            format!(
                "{label:<36} mean {:.4} px  p99 {:.4} px  max {:.4} px  ({} px)\n",
                e.mean_px, e.p99_px, e.max_px, e.counted
            )
        };
        text.push_str("screen-space position error of B against A:\n");
        text.push_str(&row(
            "  where both see the same object",
            &self.position_error,
        ));
        text.push_str(&row(
            "  ... outside flagged pixels",
            &self.position_error_outside_flagged,
        ));
        let _ = writeln!(
            text,
            "beauty FLIP mean (tone-mapped)       {:.5}",
            self.flip_mean
        );
        let _ = writeln!(
            text,
            "pixels whose seen object differs     {:.4} % ({} of {})",
            100.0 * self.object_mismatch_fraction,
            self.object_mismatch_pixels,
            self.width as u64 * self.height as u64
        );
        text
    }
}
