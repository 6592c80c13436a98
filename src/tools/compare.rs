//! `snell compare A.exr B.exr`: receives two EXR frames of the same shot (the ray-traced reference
//! first, a method's render second) and returns how far apart they are: the screen-space position
//! error both ways ([`crate::output::position_error`]: per pixel of A where B sees its point, per
//! pixel of B where A sees its point, and both together), each over every pixel where both see the
//! same object, outside flagged pixels and outside A's fold band; the mean FLIP of the tone-mapped
//! beauty; and the share of pixels whose seen object differs. A measurement, not a verdict:
//! `snell diff` / `snell check` judge frames against thresholds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::ToolError;
use crate::draw::RenderedFrame;
use crate::output::exr::ReadMeta;
use crate::output::position_error::{
    compare_positions, CompareOptions, ErrorSubsets, PositionComparison, PositionError,
    PositionErrorInput, Side, FOLD_BAND_PX,
};
use crate::output::{flip_ldr, read_frame_exr, tonemap_srgb8};

/// What `snell compare` measures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    pub a: PathBuf,
    pub b: PathBuf,
    /// The methods the frames' headers name (empty when a header names none).
    pub a_method: String,
    pub b_method: String,
    pub width: u32,
    pub height: u32,
    /// Why the flags come from the file they come from.
    pub flags_reason: String,
    #[serde(flatten)]
    pub positions: PositionComparison,
    /// Mean FLIP of B's tone-mapped beauty against A's (0 = identical).
    pub flip_mean: f32,
}

/// Reads a frame; a missing file or a file that is not one of snell's EXR frames is bad input.
pub fn read_frame(path: &Path) -> Result<(RenderedFrame, ReadMeta), ToolError> {
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
    read_frame_exr(path).map_err(|error| ToolError::InputFile {
        path: path.to_path_buf(),
        problem: format!(
            "cannot be read as a snell EXR frame: {}",
            error
                .to_string()
                .trim_start_matches(&format!("cannot read {}: ", path.display()))
        ),
    })
}

/// Whether a header's method is one of the ray tracers, which flag nothing.
fn is_traced(method: &str) -> bool {
    method.starts_with("raytrace")
}

/// The frame whose flags define "flagged" when `--flags-from` is not given: the one a rasterising
/// method made (the tracers flag nothing), B when that does not decide; with the reason in words.
pub fn default_flags_side(a_method: &str, b_method: &str) -> (Side, String) {
    match (is_traced(a_method), is_traced(b_method)) {
        (false, true) => (
            Side::A,
            format!("A's flags: B is ray-traced ({b_method}) and flags nothing"),
        ),
        (true, false) => (
            Side::B,
            format!("B's flags: A is ray-traced ({a_method}) and flags nothing"),
        ),
        _ => (
            Side::B,
            "B's flags (the frame measured against the reference A)".to_string(),
        ),
    }
}

/// Compares two frames in memory (`a_path`, `b_path` only name them in messages and the report).
/// `flags_from` None picks [`default_flags_side`].
pub fn compare_frames(
    (a, a_meta): (&RenderedFrame, Option<&ReadMeta>),
    (b, b_meta): (&RenderedFrame, Option<&ReadMeta>),
    (a_path, b_path): (&Path, &Path),
    flags_from: Option<Side>,
) -> Result<Comparison, ToolError> {
    let method = |meta: Option<&ReadMeta>| meta.map(|m| m.method.clone()).unwrap_or_default();
    let (a_method, b_method) = (method(a_meta), method(b_meta));
    let (flags_side, flags_reason) = match flags_from {
        Some(side) => (
            side,
            format!("{}'s flags (--flags-from {})", side.name(), side.name()),
        ),
        None => default_flags_side(&a_method, &b_method),
    };
    // What the measurement needs, by name, before it says something vaguer about it.
    let flags_frame = match flags_side {
        Side::A => (a, a_path),
        Side::B => (b, b_path),
    };
    for (frame, path) in [(a, a_path), (b, b_path)] {
        let mut lacking = Vec::new();
        if frame.position.is_empty() {
            lacking.push("no `P` layer (P.X, P.Y, P.Z)");
        }
        if frame.object.is_empty() {
            lacking.push("no `IndexOB` layer (IndexOB.X)");
        }
        if std::ptr::eq(frame, flags_frame.0) && frame.flags.is_empty() {
            lacking.push("no flag layers (FlagConvergence.X, ...: they define \"flagged\")");
        }
        if !lacking.is_empty() {
            return Err(ToolError::InputFile {
                path: path.to_path_buf(),
                problem: format!(
                    "has {}: snell compare measures positions by P and IndexOB and leaves out flagged pixels; render the frame again with --layers all (or a list with P,IndexOB and the Flag layers)",
                    lacking.join(", ")
                ),
            });
        }
    }
    let options = CompareOptions {
        flags_from: flags_side,
        eyes: a_meta
            .zip(b_meta)
            .map(|(a, b)| (a.camera.eye, b.camera.eye)),
    };
    let positions = compare_positions(a, b, &options).map_err(|error| match error {
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
    Ok(Comparison {
        a: a_path.to_path_buf(),
        b: b_path.to_path_buf(),
        a_method,
        b_method,
        width: a.width,
        height: a.height,
        flags_reason,
        positions,
        flip_mean: flip.mean,
    })
}

/// Reads and compares two EXR frames.
pub fn compare_files(
    a: &Path,
    b: &Path,
    flags_from: Option<Side>,
) -> Result<Comparison, ToolError> {
    let (frame_a, meta_a) = read_frame(a)?;
    let (frame_b, meta_b) = read_frame(b)?;
    compare_frames(
        (&frame_a, Some(&meta_a)),
        (&frame_b, Some(&meta_b)),
        (a, b),
        flags_from,
    )
}

fn percent(fraction: Option<f64>) -> String {
    fraction.map_or("-".to_string(), |f| format!("{:.3} %", 100.0 * f))
}

impl Comparison {
    /// The report as `snell compare` prints it.
    pub fn to_text(&self) -> String {
        let p = &self.positions;
        let named = |path: &Path, method: &str| {
            if method.is_empty() {
                path.display().to_string()
            } else {
                format!("{} ({method})", path.display())
            }
        };
        let mut text = String::new();
        let _ = writeln!(
            text,
            "A {}\nB {}\n{}x{}; flagged pixels: {}",
            named(&self.a, &self.a_method),
            named(&self.b, &self.b_method),
            self.width,
            self.height,
            self.flags_reason
        );
        let _ = writeln!(
            text,
            "fold band (pixels within {FOLD_BAND_PX} px of a fold of A's map): {} fold edges, {} px, {} of A's water pixels",
            p.fold_edges,
            p.fold_band_pixels,
            percent(p.fold_band_water_fraction)
        );
        let _ = writeln!(
            text,
            "flagged: {} px, {} of the water pixels",
            p.flagged_pixels,
            percent(p.flagged_water_fraction)
        );
        text.push_str(
            "screen-space position error in px, where both see the same object (no search window):\n",
        );
        let _ = writeln!(
            text,
            "  {:<26} {:>9} {:>9} {:>9} {:>8} {:>9} {:>7}",
            "", "mean", "p99", "max", "> 1 px", "pixels", "unseen"
        );
        let row = |label: &str, e: &PositionError| {
            format!(
                "  {label:<26} {:>9.4} {:>9.4} {:>9.4} {:>7.3}% {:>9} {:>7}\n",
                e.mean_px,
                e.p99_px,
                e.max_px,
                100.0 * e.over_1px_fraction,
                e.counted,
                e.unseen
            )
        };
        let block = |text: &mut String, name: &str, s: &ErrorSubsets| {
            text.push_str(&row(&format!("{name} all"), &s.all));
            text.push_str(&row("   outside flagged pixels", &s.outside_flagged));
            text.push_str(&row("   outside the fold band", &s.outside_fold_band));
        };
        block(&mut text, "A -> B", &p.a_to_b);
        block(&mut text, "B -> A", &p.b_to_a);
        block(&mut text, "both  ", &p.both);
        text.push_str(
            "  (A -> B: per pixel of A, to where B sees its point; B -> A the other way; unseen: \
             the point is not seen at all, measured to the object's nearest point seen)\n",
        );
        let _ = writeln!(
            text,
            "beauty FLIP mean (tone-mapped)       {:.5}",
            self.flip_mean
        );
        let _ = writeln!(
            text,
            "pixels whose seen object differs     {:.4} % ({} of {})",
            100.0 * p.object_mismatch_fraction,
            p.object_mismatch_pixels,
            p.pixels
        );
        text
    }
}
