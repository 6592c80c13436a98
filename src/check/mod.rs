//! Frame diffs for CI: receives pairs of frames written by `snell render` (OpenEXR files, or two
//! directories of them matched by file name) and returns a verdict per frame — pass, warn or fail,
//! with the metric, its value and the threshold it crossed — plus FLIP heat maps of the frames that
//! did not pass. [`scene`] renders a scene's frames and compares them with goldens through the same
//! code; [`junit`] writes the result as a JUnit XML report; [`cli`] is `snell diff` and `snell check`.
//!
//! What is compared, and why so:
//! - beauty: FLIP (LDR) after the same tone mapping as the PNG previews, because rasterisers differ
//!   in sub-visible ways (half-float targets on GL, texture filtering) that a per-pixel tolerance on
//!   HDR radiance would either miss or flag everywhere; the mean catches broad change, the 99th
//!   percentile catches a small object moved or missing.
//! - `Z` (distance, m) and `P` (true world position, m): per pixel against an absolute tolerance;
//!   a fraction of the pixels may exceed it, because two rasterisers cover silhouette pixels
//!   differently and there a pixel flips between foreground and background.
//! - flag counts (the `snell.extra.flagCounts` header attribute): exactly, because the refraction
//!   stage runs on the CPU and is deterministic; any change there is a change of the method.

pub mod cli;
pub mod junit;
pub mod scene;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use crate::draw::RenderedFrame;
use crate::frame::SnellError;
use crate::output::compare::flip_ldr;
use crate::output::tonemap::{save_png_atomic, tonemap_srgb8};
use crate::output::{read_frame_exr, OutputError};

/// The header attribute (under `snell.extra.`) holding a frame's flag counts as compact JSON.
pub const FLAG_COUNTS_ATTRIBUTE: &str = "flagCounts";

/// Default thresholds, with the measurements behind them (320x180, Mesa 22.3.6, debug build of
/// `snell render`). "GL vs Vulkan": the same frames rendered with `WGPU_BACKEND=gl` (llvmpipe,
/// Rgba16Float beauty) and with the default adapter (lavapipe, Rgba32Float beauty): the largest
/// difference two correct renders show. "Next frame": frames N and N+1 of the same shot, the
/// smallest real change a golden must catch. Frames measured: pool 1, 2, 24, 25, 47, 48 and
/// fox_wading 12, 13, 36, 37.
pub mod defaults {
    /// Mean FLIP warn level. GL vs Vulkan: 0.0042-0.0051. Twice the largest leaves room for
    /// another Mesa version or a real GPU's texture filtering.
    pub const FLIP_MEAN_WARN: f32 = 0.01;
    /// Mean FLIP fail level. Next frame: 0.026 (pool 1/2) to 0.081 (fox_wading 36/37). Three
    /// times the GL-vs-Vulkan difference and still well below the smallest next-frame change.
    pub const FLIP_MEAN_FAIL: f32 = 0.015;
    /// 99th-percentile FLIP warn level. GL vs Vulkan: 0.019-0.030; twice the largest.
    pub const FLIP_P99_WARN: f32 = 0.06;
    /// 99th-percentile FLIP fail level. Next frame: 0.24-0.44; half the smallest. The percentile
    /// catches a small object moved, which the mean dilutes; one changed pixel leaves it near 0
    /// (FLIP spreads a pixel over a few neighbours, far fewer than 1 % of a frame).
    pub const FLIP_P99_FAIL: f32 = 0.12;
    /// Tolerance on `Z` (distance from the eye), metres. GL vs Vulkan: at most 1.1e-5 m apart
    /// (the distance target is 32-bit float on both); 1 mm is far below any modelling change.
    pub const DEPTH_TOLERANCE_M: f32 = 1e-3;
    /// Tolerance on `P` (true world position, Euclidean), metres. GL vs Vulkan: at most 1.2e-5 m.
    pub const POSITION_TOLERANCE_M: f32 = 1e-3;
    /// Fraction of the pixels whose `Z` or `P` may exceed its tolerance before a warning.
    /// GL vs Vulkan: 0 pixels (both are Mesa and share rasterisation rules), but another
    /// rasteriser may cover silhouette pixels differently, and there a pixel flips between
    /// foreground and background: 0.1 % is a one-pixel-wide outline around a few objects.
    pub const EXCEEDING_FRACTION_WARN: f64 = 0.001;
    /// The fraction at which `Z`/`P` fail. Next frame: 37-64 % of the pixels exceed 1 mm in `Z`,
    /// 82-91 % in `P` (the water moves, and every pixel seen through it).
    pub const EXCEEDING_FRACTION_FAIL: f64 = 0.01;
}

/// Everything that stops a diff before it can give a verdict; each names the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    #[error("{path}: no such file or directory")]
    Missing { path: PathBuf },
    #[error("{0}")]
    Output(#[from] OutputError),
    #[error("{0}")]
    Render(#[from] SnellError),
    #[error(
        "{reference} and {test}: give two EXR files or two directories of frames, not one of each"
    )]
    MixedKinds { reference: PathBuf, test: PathBuf },
    #[error("{dir}: no EXR frames in this directory")]
    NoFrames { dir: PathBuf },
    #[error("cannot list {dir}: {cause}")]
    ListDir { dir: PathBuf, cause: String },
    /// A threshold or option that cannot be used; the message says which.
    #[error("{0}")]
    Argument(String),
}

/// idiff's exit code for input it could not find or read (`ErrFile`).
pub const EXIT_UNREADABLE: u8 = 4;

impl CheckError {
    /// The exit code this error ends `snell diff` or `snell check` with, as idiff's: 4 when an
    /// input cannot be found or read (a missing or unreadable file, a directory that cannot be
    /// listed or holds no frames), 2 for everything else (a bad option, a render that failed, a
    /// report that cannot be written).
    pub fn exit_code(&self) -> u8 {
        match self {
            CheckError::Missing { .. }
            | CheckError::ListDir { .. }
            | CheckError::NoFrames { .. }
            | CheckError::Output(OutputError::Read { .. }) => EXIT_UNREADABLE,
            _ => Verdict::Fail.exit_code(),
        }
    }
}

/// A frame's (or a whole diff's) outcome. Ordered: the worst finding wins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Verdict {
    Pass,
    Warn,
    Fail,
}

impl Verdict {
    /// The exit code of OpenImageIO's idiff: 0 pass, 1 warn, 2 fail.
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Pass => 0,
            Verdict::Warn => 1,
            Verdict::Fail => 2,
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Warn => "warn",
            Verdict::Fail => "FAIL",
        }
    }
}

/// When a frame warns or fails. Every level is inclusive on the passing side: a value equal to
/// a warn level passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    pub flip_mean_warn: f32,
    pub flip_mean_fail: f32,
    pub flip_p99_warn: f32,
    pub flip_p99_fail: f32,
    pub depth_tolerance_m: f32,
    pub position_tolerance_m: f32,
    /// Fraction in [0, 1] of the pixels whose `Z` or `P` may exceed its tolerance.
    pub exceeding_fraction_warn: f64,
    pub exceeding_fraction_fail: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            flip_mean_warn: defaults::FLIP_MEAN_WARN,
            flip_mean_fail: defaults::FLIP_MEAN_FAIL,
            flip_p99_warn: defaults::FLIP_P99_WARN,
            flip_p99_fail: defaults::FLIP_P99_FAIL,
            depth_tolerance_m: defaults::DEPTH_TOLERANCE_M,
            position_tolerance_m: defaults::POSITION_TOLERANCE_M,
            exceeding_fraction_warn: defaults::EXCEEDING_FRACTION_WARN,
            exceeding_fraction_fail: defaults::EXCEEDING_FRACTION_FAIL,
        }
    }
}

impl Thresholds {
    /// Rejects negative or non-finite values and warn levels above their fail levels.
    pub fn validate(&self) -> Result<(), CheckError> {
        let pairs = [
            (
                "--flip-mean-warn",
                self.flip_mean_warn as f64,
                "--flip-mean-fail",
                self.flip_mean_fail as f64,
            ),
            (
                "--flip-p99-warn",
                self.flip_p99_warn as f64,
                "--flip-p99-fail",
                self.flip_p99_fail as f64,
            ),
            (
                "--exceed-warn",
                self.exceeding_fraction_warn,
                "--exceed-fail",
                self.exceeding_fraction_fail,
            ),
        ];
        let tolerances = [
            ("--z-tolerance", self.depth_tolerance_m as f64),
            ("--p-tolerance", self.position_tolerance_m as f64),
        ];
        let all_values = pairs
            .iter()
            .flat_map(|&(warn_name, warn, fail_name, fail)| [(warn_name, warn), (fail_name, fail)])
            .chain(tolerances);
        for (name, value) in all_values {
            if !value.is_finite() || value < 0.0 {
                return Err(CheckError::Argument(format!(
                    "{name} {value}: must be a finite number >= 0"
                )));
            }
        }
        for (warn_name, warn, fail_name, fail) in pairs {
            if warn > fail {
                return Err(CheckError::Argument(format!(
                    "{warn_name} {warn} is above {fail_name} {fail}: a warning level must not exceed its failure level"
                )));
            }
        }
        Ok(())
    }
}

/// One reason a frame did not pass (or a note that something could not be compared).
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    pub verdict: Verdict,
    pub message: String,
}

/// How many pixels of a layer (`Z` or `P`) differ by more than the tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerDifference {
    pub exceeding_pixels: usize,
    pub pixels: usize,
    /// The largest difference among pixels finite on both sides, metres (0 when there is none).
    pub max_finite_difference_m: f32,
}

impl LayerDifference {
    pub fn exceeding_fraction(&self) -> f64 {
        if self.pixels == 0 {
            0.0
        } else {
            self.exceeding_pixels as f64 / self.pixels as f64
        }
    }
}

/// Flag counts of the two frames: equal, or each field that differs as `path: reference -> test`.
#[derive(Clone, Debug, PartialEq)]
pub enum CountsComparison {
    Equal,
    Differ(Vec<String>),
    /// One side has no (readable) counts; the reason says which file.
    Unavailable(String),
}

/// The pixel metrics of two frames of the same size.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMetrics {
    pub flip_mean: f32,
    pub flip_p99: f32,
    pub depth: LayerDifference,
    pub position: LayerDifference,
}

/// The comparison of one frame.
#[derive(Clone, Debug)]
pub struct FrameComparison {
    /// The frame's file name, e.g. `pool.0001.exr`.
    pub name: String,
    pub reference: PathBuf,
    pub test: PathBuf,
    /// None when the frames could not be compared pixel by pixel (missing, unreadable, sizes differ).
    pub metrics: Option<FrameMetrics>,
    pub counts: Option<CountsComparison>,
    pub findings: Vec<Finding>,
    /// The FLIP heat map written for this frame, if any.
    pub heatmap: Option<PathBuf>,
    pub elapsed_secs: f64,
    /// One of its files exists but cannot be read as a frame (the diff then exits with
    /// [`EXIT_UNREADABLE`]); a frame on one side only is a failing frame, not this.
    pub unreadable: bool,
}

impl FrameComparison {
    pub fn verdict(&self) -> Verdict {
        self.findings
            .iter()
            .map(|finding| finding.verdict)
            .max()
            .unwrap_or(Verdict::Pass)
    }

    /// The findings as one line, e.g. `FLIP mean 0.031 > fail level 0.015; flag counts differ: ...`.
    pub fn reasons(&self) -> String {
        self.findings
            .iter()
            .map(|finding| finding.message.as_str())
            .collect::<Vec<_>>()
            .join("; ")
    }

    fn failed(
        name: String,
        (reference, test): (PathBuf, PathBuf),
        message: String,
        unreadable: bool,
    ) -> Self {
        FrameComparison {
            name,
            reference,
            test,
            metrics: None,
            counts: None,
            findings: vec![Finding {
                verdict: Verdict::Fail,
                message,
            }],
            heatmap: None,
            elapsed_secs: 0.0,
            unreadable,
        }
    }
}

/// Every frame of a diff, in name order.
#[derive(Clone, Debug, Default)]
pub struct DiffReport {
    pub frames: Vec<FrameComparison>,
}

impl DiffReport {
    /// idiff's exit code: [`EXIT_UNREADABLE`] when a frame's file could not be read, else the
    /// verdict's (0 pass, 1 warn, 2 fail).
    pub fn exit_code(&self) -> u8 {
        if self.frames.iter().any(|frame| frame.unreadable) {
            EXIT_UNREADABLE
        } else {
            self.verdict().exit_code()
        }
    }

    pub fn verdict(&self) -> Verdict {
        self.frames
            .iter()
            .map(FrameComparison::verdict)
            .max()
            .unwrap_or(Verdict::Pass)
    }

    pub fn count(&self, verdict: Verdict) -> usize {
        self.frames
            .iter()
            .filter(|frame| frame.verdict() == verdict)
            .count()
    }

    /// The per-frame table, then one line per frame that did not pass giving the reasons.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let name_width = self
            .frames
            .iter()
            .map(|frame| frame.name.len())
            .max()
            .unwrap_or(0)
            .max("frame".len());
        let mut text = String::new();
        let _ = writeln!(
            text,
            "{:<name_width$}  {:>9}  {:>9}  {:>16}  {:>16}  {:<7}  verdict",
            "frame", "FLIP mean", "FLIP p99", "Z >tol (max m)", "P >tol (max m)", "counts"
        );
        for frame in &self.frames {
            let (mean, p99, depth, position) = match &frame.metrics {
                Some(metrics) => (
                    format!("{:.5}", metrics.flip_mean),
                    format!("{:.5}", metrics.flip_p99),
                    layer_cell(&metrics.depth),
                    layer_cell(&metrics.position),
                ),
                None => ("-".into(), "-".into(), "-".into(), "-".into()),
            };
            let counts = match &frame.counts {
                Some(CountsComparison::Equal) => "equal",
                Some(CountsComparison::Differ(_)) => "DIFFER",
                Some(CountsComparison::Unavailable(_)) => "n/a",
                None => "-",
            };
            let _ = writeln!(
                text,
                "{:<name_width$}  {mean:>9}  {p99:>9}  {depth:>16}  {position:>16}  {counts:<7}  {}",
                frame.name,
                frame.verdict().label()
            );
        }
        for frame in self
            .frames
            .iter()
            .filter(|frame| !frame.findings.is_empty())
        {
            let _ = writeln!(
                text,
                "{} {}: {}",
                frame.verdict().label(),
                frame.name,
                frame.reasons()
            );
        }
        text
    }

    /// `N frame(s): a pass, b warn, c fail`.
    pub fn summary(&self) -> String {
        format!(
            "{} frame(s): {} pass, {} warn, {} fail",
            self.frames.len(),
            self.count(Verdict::Pass),
            self.count(Verdict::Warn),
            self.count(Verdict::Fail)
        )
    }
}

fn layer_cell(layer: &LayerDifference) -> String {
    format!(
        "{} ({:.1e})",
        layer.exceeding_pixels, layer.max_finite_difference_m
    )
}

/// A frame read for comparison: pixels and its flag counts (or why it has none).
pub struct LoadedFrame {
    pub frame: RenderedFrame,
    pub flag_counts: Result<serde_json::Value, String>,
}

/// Reads an EXR frame written by `snell render`; the error names the file.
pub fn load_frame(path: &Path) -> Result<LoadedFrame, CheckError> {
    if !path.exists() {
        return Err(CheckError::Missing {
            path: path.to_path_buf(),
        });
    }
    let (frame, meta) = read_frame_exr(path)?;
    let flag_counts = match meta
        .text_attributes
        .iter()
        .find(|(key, _)| key == FLAG_COUNTS_ATTRIBUTE)
    {
        None => Err(format!(
            "{} has no snell.extra.{FLAG_COUNTS_ATTRIBUTE} attribute (rendered by an older snell?): flag counts not compared",
            path.display()
        )),
        Some((_, text)) => serde_json::from_str(text).map_err(|error| {
            format!(
                "{}: snell.extra.{FLAG_COUNTS_ATTRIBUTE} is not JSON ({error}): flag counts not compared",
                path.display()
            )
        }),
    };
    Ok(LoadedFrame { frame, flag_counts })
}

/// Compares two loaded frames; returns the metrics (None if the sizes differ), the counts
/// comparison, the findings and the FLIP heat map.
pub fn compare_frames(
    reference: &LoadedFrame,
    test: &LoadedFrame,
    thresholds: &Thresholds,
) -> (
    Option<FrameMetrics>,
    CountsComparison,
    Vec<Finding>,
    Option<image::RgbaImage>,
) {
    let mut findings = Vec::new();
    let counts = compare_counts(&reference.flag_counts, &test.flag_counts);
    match &counts {
        CountsComparison::Equal => {}
        CountsComparison::Differ(fields) => findings.push(Finding {
            verdict: Verdict::Fail,
            message: format!("flag counts differ: {}", fields.join(", ")),
        }),
        CountsComparison::Unavailable(reason) => findings.push(Finding {
            verdict: Verdict::Warn,
            message: reason.clone(),
        }),
    }
    let (r, t) = (&reference.frame, &test.frame);
    if (r.width, r.height) != (t.width, t.height) {
        findings.push(Finding {
            verdict: Verdict::Fail,
            message: format!(
                "sizes differ: reference {}x{}, test {}x{}",
                r.width, r.height, t.width, t.height
            ),
        });
        return (None, counts, findings, None);
    }
    if let Some(finding) = new_non_finite(r, t) {
        findings.push(finding);
    }
    findings.extend(missing_layers(r, t));
    let flip = flip_ldr(&tonemap_srgb8(r, 0.0), &tonemap_srgb8(t, 0.0))
        .expect("sizes were checked equal above");
    let depth = layer_difference(seen_depths(r), seen_depths(t), thresholds.depth_tolerance_m);
    let position = layer_difference(
        seen_positions(r),
        seen_positions(t),
        thresholds.position_tolerance_m,
    );
    let mut judge = |name: &str, value: f64, warn: f64, fail: f64, shown: String| {
        let (verdict, level, limit) = if value > fail {
            (Verdict::Fail, "fail", fail)
        } else if value > warn {
            (Verdict::Warn, "warn", warn)
        } else {
            return;
        };
        findings.push(Finding {
            verdict,
            // Levels arrive as f32 or f64; shown as the f32 they were typed as (0.015, not 0.01499..).
            message: format!("{name} {shown} > {level} level {}", limit as f32),
        });
    };
    judge(
        "FLIP mean",
        flip.mean as f64,
        thresholds.flip_mean_warn as f64,
        thresholds.flip_mean_fail as f64,
        format!("{:.5}", flip.mean),
    );
    judge(
        "FLIP p99",
        flip.p99 as f64,
        thresholds.flip_p99_warn as f64,
        thresholds.flip_p99_fail as f64,
        format!("{:.5}", flip.p99),
    );
    for (name, layer, tolerance) in [
        ("Z", &depth, thresholds.depth_tolerance_m),
        ("P", &position, thresholds.position_tolerance_m),
    ] {
        judge(
            &format!("fraction of pixels with {name} off by more than {tolerance} m"),
            layer.exceeding_fraction(),
            thresholds.exceeding_fraction_warn,
            thresholds.exceeding_fraction_fail,
            format!(
                "{:.5} ({} of {} px, largest finite difference {:.3e} m)",
                layer.exceeding_fraction(),
                layer.exceeding_pixels,
                layer.pixels,
                layer.max_finite_difference_m
            ),
        );
    }
    let metrics = FrameMetrics {
        flip_mean: flip.mean,
        flip_p99: flip.p99,
        depth,
        position,
    };
    (Some(metrics), counts, findings, Some(flip.error_map_png))
}

/// `Z` and `P` are compared only where both frames have them (`--layers` may leave them out): a
/// layer the reference has and the test lacks fails, one the reference lacks is not compared (a
/// warning).
fn missing_layers(reference: &RenderedFrame, test: &RenderedFrame) -> Vec<Finding> {
    [
        ("Z", reference.depth_m.is_empty(), test.depth_m.is_empty()),
        ("P", reference.position.is_empty(), test.position.is_empty()),
    ]
    .into_iter()
    .filter_map(|(layer, reference_lacks, test_lacks)| match (reference_lacks, test_lacks) {
        (false, false) => None,
        (false, true) => Some(Finding {
            verdict: Verdict::Fail,
            message: format!(
                "the test frame has no `{layer}` layer (written with --layers that leaves it out?) but the reference has one: {layer} not compared"
            ),
        }),
        (true, test_lacks) => Some(Finding {
            verdict: Verdict::Warn,
            message: format!(
                "the reference has no `{layer}` layer{}: {layer} not compared (render with --layers all to compare it)",
                if test_lacks { " and neither has the test frame" } else { "" }
            ),
        }),
    })
    .collect()
}

/// NaN or infinite samples in `test` where `reference` has finite ones: always a failure, however
/// few (tone mapping and the tolerance fractions would let a single NaN pixel pass).
fn new_non_finite(
    reference: &crate::draw::RenderedFrame,
    test: &crate::draw::RenderedFrame,
) -> Option<Finding> {
    let finite = |values: &[f32]| values.iter().all(|v| v.is_finite());
    let mut counts = [0usize; 3];
    let mut first = None;
    for i in 0..reference.beauty_rgba.len().min(test.beauty_rgba.len()) {
        let layers = [
            finite(&reference.beauty_rgba[i]) && !finite(&test.beauty_rgba[i]),
            reference.depth_m.get(i).is_some_and(|z| z.is_finite())
                && test.depth_m.get(i).is_some_and(|z| !z.is_finite()),
            reference.position.get(i).is_some_and(|p| finite(p))
                && test.position.get(i).is_some_and(|p| !finite(p)),
        ];
        for (count, bad) in counts.iter_mut().zip(layers) {
            if bad {
                *count += 1;
                first.get_or_insert(i);
            }
        }
    }
    let first = first?;
    let width = test.width.max(1) as usize;
    Some(Finding {
        verdict: Verdict::Fail,
        message: format!(
            "non-finite values where the reference has finite ones: {} beauty, {} Z and {} P pixel(s), \
             the first at ({}, {})",
            counts[0],
            counts[1],
            counts[2],
            first % width,
            first / width
        ),
    })
}

/// Per-pixel difference of a layer of `N` components: Euclidean distance against `tolerance_m`.
/// `None` is a pixel that sees nothing (sky, water with nothing behind it: the channel map's
/// values there are not positions): two such pixels agree, and a pixel seeing something on one
/// side only always exceeds. A non-finite value agrees only with the same value.
fn layer_difference<const N: usize>(
    reference: impl Iterator<Item = Option<[f32; N]>>,
    test: impl Iterator<Item = Option<[f32; N]>>,
    tolerance_m: f32,
) -> LayerDifference {
    let mut result = LayerDifference {
        exceeding_pixels: 0,
        pixels: 0,
        max_finite_difference_m: 0.0,
    };
    for (a, b) in reference.zip(test) {
        result.pixels += 1;
        let (a, b) = match (a, b) {
            (None, None) => continue,
            (Some(a), Some(b)) => (a, b),
            _ => {
                result.exceeding_pixels += 1;
                continue;
            }
        };
        let finite = a.iter().chain(&b).all(|c| c.is_finite());
        if finite {
            let distance = a
                .iter()
                .zip(&b)
                .map(|(x, y)| ((x - y) as f64).powi(2))
                .sum::<f64>()
                .sqrt() as f32;
            result.max_finite_difference_m = result.max_finite_difference_m.max(distance);
            if distance > tolerance_m {
                result.exceeding_pixels += 1;
            }
        } else {
            let same_non_finite = a
                .iter()
                .zip(&b)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()));
            if !same_non_finite {
                result.exceeding_pixels += 1;
            }
        }
    }
    result
}

/// A frame's `Z` per pixel, `None` where it sees nothing.
fn seen_depths(frame: &RenderedFrame) -> impl Iterator<Item = Option<[f32; 1]>> + '_ {
    frame
        .depth_m
        .iter()
        .map(|&d| (d < crate::draw::SKY_DEPTH_M).then_some([d]))
}

/// A frame's `P` per pixel, `None` where it sees no object (by its object layer; frames without
/// one: where `P` is 0 or not finite).
fn seen_positions(frame: &RenderedFrame) -> impl Iterator<Item = Option<[f32; 3]>> + '_ {
    frame.position.iter().enumerate().map(|(i, &p)| {
        let seen = match frame.object.get(i) {
            Some(&object) => object != crate::draw::NO_OBJECT,
            None => p != [0.0; 3] && p.iter().all(|c| c.is_finite()),
        };
        seen.then_some(p)
    })
}

fn compare_counts(
    reference: &Result<serde_json::Value, String>,
    test: &Result<serde_json::Value, String>,
) -> CountsComparison {
    let (reference, test) = match (reference, test) {
        (Ok(reference), Ok(test)) => (reference, test),
        (Err(reason), _) | (_, Err(reason)) => {
            return CountsComparison::Unavailable(reason.clone())
        }
    };
    let mut reference_fields = BTreeMap::new();
    let mut test_fields = BTreeMap::new();
    flatten_json("", reference, &mut reference_fields);
    flatten_json("", test, &mut test_fields);
    let keys: std::collections::BTreeSet<&String> =
        reference_fields.keys().chain(test_fields.keys()).collect();
    let differing: Vec<String> = keys
        .into_iter()
        .filter_map(|key| {
            let (a, b) = (reference_fields.get(key), test_fields.get(key));
            (a != b).then(|| {
                let show = |value: Option<&String>| value.cloned().unwrap_or("absent".into());
                format!("{key} {} -> {}", show(a), show(b))
            })
        })
        .collect();
    if differing.is_empty() {
        CountsComparison::Equal
    } else {
        CountsComparison::Differ(differing)
    }
}

/// `{"vertices": {"popping": 3}}` -> `vertices.popping = "3"`.
fn flatten_json(prefix: &str, value: &serde_json::Value, into: &mut BTreeMap<String, String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (key, child) in map {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten_json(&path, child, into);
            }
        }
        other => {
            into.insert(prefix.to_string(), other.to_string());
        }
    }
}

/// Two frames to compare: `reference` (golden, or A) and `test` (new, or B).
#[derive(Clone, Debug)]
pub struct FramePair {
    pub name: String,
    pub reference: PathBuf,
    pub test: PathBuf,
    /// Appended to the failure when the reference does not exist (e.g. how to bless it).
    pub missing_reference_hint: String,
}

/// Compares one pair of files. A missing or unreadable file is an `Err` naming it; the heat map is
/// written to `heatmap_dir/<stem>-difference.png` when the frame warns or fails.
pub fn compare_pair(
    pair: &FramePair,
    thresholds: &Thresholds,
    heatmap_dir: Option<&Path>,
) -> Result<FrameComparison, CheckError> {
    let clock = Instant::now();
    let reference = load_frame(&pair.reference)?;
    let test = load_frame(&pair.test)?;
    let (metrics, counts, findings, heat) = compare_frames(&reference, &test, thresholds);
    let mut comparison = FrameComparison {
        name: pair.name.clone(),
        reference: pair.reference.clone(),
        test: pair.test.clone(),
        metrics,
        counts: Some(counts),
        findings,
        heatmap: None,
        elapsed_secs: 0.0,
        unreadable: false,
    };
    if let (Some(dir), Some(heat)) = (heatmap_dir, heat) {
        if comparison.verdict() != Verdict::Pass {
            let stem = pair.name.strip_suffix(".exr").unwrap_or(&pair.name);
            let path = dir.join(format!("{stem}-difference.png"));
            save_png_atomic(&path, &heat)?;
            comparison.heatmap = Some(path);
        }
    }
    comparison.elapsed_secs = clock.elapsed().as_secs_f64();
    Ok(comparison)
}

/// Compares every pair (in parallel); a pair that cannot be compared becomes a failing row whose
/// message names the file, so one bad frame does not hide the verdicts of the others.
pub fn compare_pairs(
    pairs: &[FramePair],
    thresholds: &Thresholds,
    heatmap_dir: Option<&Path>,
) -> DiffReport {
    let frames = pairs
        .par_iter()
        .map(|pair| {
            compare_pair(pair, thresholds, heatmap_dir).unwrap_or_else(|error| {
                let mut message = error.to_string();
                if matches!(&error, CheckError::Missing { path } if *path == pair.reference) {
                    message.push_str(&pair.missing_reference_hint);
                }
                let unreadable = !matches!(&error, CheckError::Missing { .. });
                FrameComparison::failed(
                    pair.name.clone(),
                    (pair.reference.clone(), pair.test.clone()),
                    message,
                    unreadable,
                )
            })
        })
        .collect();
    DiffReport { frames }
}

/// The `*.exr` file names in `dir` (hidden temporaries of an interrupted write are skipped).
fn exr_names(dir: &Path) -> Result<std::collections::BTreeSet<String>, CheckError> {
    let list_error = |cause: String| CheckError::ListDir {
        dir: dir.to_path_buf(),
        cause,
    };
    let mut names = std::collections::BTreeSet::new();
    for entry in std::fs::read_dir(dir).map_err(|error| list_error(error.to_string()))? {
        let entry = entry.map_err(|error| list_error(error.to_string()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.to_ascii_lowercase().ends_with(".exr") && !name.starts_with('.') {
            names.insert(name);
        }
    }
    Ok(names)
}

/// `snell diff A B`: two EXR files, or two directories whose frames are matched by file name (a
/// frame on one side only fails). Heat maps of frames that warn or fail go to `heatmap_dir`.
pub fn diff_paths(
    reference: &Path,
    test: &Path,
    thresholds: &Thresholds,
    heatmap_dir: Option<&Path>,
) -> Result<DiffReport, CheckError> {
    thresholds.validate()?;
    for path in [reference, test] {
        if !path.exists() {
            return Err(CheckError::Missing {
                path: path.to_path_buf(),
            });
        }
    }
    match (reference.is_dir(), test.is_dir()) {
        (false, false) => {
            let name = file_name(test);
            let pair = FramePair {
                name: if file_name(reference) == name {
                    name
                } else {
                    format!("{} vs {name}", file_name(reference))
                },
                reference: reference.to_path_buf(),
                test: test.to_path_buf(),
                missing_reference_hint: String::new(),
            };
            Ok(DiffReport {
                frames: vec![compare_pair(&pair, thresholds, heatmap_dir)?],
            })
        }
        (true, true) => {
            let reference_names = exr_names(reference)?;
            let test_names = exr_names(test)?;
            if reference_names.is_empty() && test_names.is_empty() {
                return Err(CheckError::NoFrames {
                    dir: reference.to_path_buf(),
                });
            }
            let pairs: Vec<FramePair> = reference_names
                .union(&test_names)
                .map(|name| FramePair {
                    name: name.clone(),
                    reference: reference.join(name),
                    test: test.join(name),
                    missing_reference_hint: format!(" (the frame is only in {})", test.display()),
                })
                .collect();
            let mut report = compare_pairs(&pairs, thresholds, heatmap_dir);
            for frame in &mut report.frames {
                if !test_names.contains(&frame.name) {
                    frame.findings = vec![Finding {
                        verdict: Verdict::Fail,
                        message: format!(
                            "{}: no such file (the frame is only in {})",
                            frame.test.display(),
                            reference.display()
                        ),
                    }];
                }
            }
            Ok(report)
        }
        _ => Err(CheckError::MixedKinds {
            reference: reference.to_path_buf(),
            test: test.to_path_buf(),
        }),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|name| name.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(width: u32, height: u32) -> RenderedFrame {
        let pixels = (width * height) as usize;
        RenderedFrame {
            width,
            height,
            beauty_rgba: (0..pixels)
                .map(|i| {
                    let x = (i % width as usize) as f32 / width as f32;
                    [x, 0.3, 1.0 - x, 1.0]
                })
                .collect(),
            depth_m: (0..pixels)
                .map(|i| {
                    if i % 7 == 0 {
                        crate::draw::SKY_DEPTH_M
                    } else {
                        5.0
                    }
                })
                .collect(),
            position: (0..pixels)
                .map(|i| {
                    if i % 7 == 0 {
                        [0.0; 3]
                    } else {
                        [1.0, -0.5, i as f32 * 0.01]
                    }
                })
                .collect(),
            flags: vec![0; pixels],
            object: (0..pixels).map(|i| u32::from(i % 7 != 0)).collect(),
            ..Default::default()
        }
    }

    fn loaded(frame: RenderedFrame, counts: serde_json::Value) -> LoadedFrame {
        LoadedFrame {
            frame,
            flag_counts: Ok(counts),
        }
    }

    #[test]
    fn identical_frames_pass_with_zero_metrics() {
        let counts = serde_json::json!({"vertices": {"popping": 0}});
        let a = loaded(frame(32, 16), counts.clone());
        let b = loaded(frame(32, 16), counts);
        let (metrics, counts, findings, _) = compare_frames(&a, &b, &Thresholds::default());
        let metrics = metrics.unwrap();
        assert_eq!((metrics.flip_mean, metrics.flip_p99), (0.0, 0.0));
        assert_eq!(metrics.depth.exceeding_pixels, 0);
        assert_eq!(
            metrics.position.exceeding_pixels, 0,
            "sky pixels agree: both see nothing"
        );
        assert_eq!(counts, CountsComparison::Equal);
        assert!(findings.is_empty(), "{findings:?}");
    }

    /// One NaN beauty pixel in 512 passes every FLIP and fraction threshold, yet must fail.
    #[test]
    fn a_single_nan_where_the_reference_is_finite_fails() {
        let counts = serde_json::json!({"vertices": {"popping": 0}});
        let a = loaded(frame(32, 16), counts.clone());
        for layer in 0..3 {
            let mut bad = frame(32, 16);
            match layer {
                0 => bad.beauty_rgba[37][2] = f32::NAN,
                1 => bad.depth_m[37] = f32::NAN,
                _ => bad.position[37][0] = f32::INFINITY,
            }
            let b = loaded(bad, counts.clone());
            let (_, _, findings, _) = compare_frames(&a, &b, &Thresholds::default());
            let failure = findings
                .iter()
                .find(|f| f.verdict == Verdict::Fail)
                .unwrap_or_else(|| panic!("layer {layer}: {findings:?}"));
            assert!(
                failure.message.contains("non-finite") && failure.message.contains("(5, 1)"),
                "{}",
                failure.message
            );
        }
        // Sky stays sky: +inf and NaN on both sides are no failure (the identical-frames test).
    }

    #[test]
    fn seen_on_one_side_only_exceeds_and_is_not_the_max() {
        let layer = layer_difference(
            [
                None,
                Some([5.0]),
                Some([f32::NAN]),
                Some([1.0]),
                Some([2.0]),
            ]
            .into_iter(),
            [
                None,
                None,
                Some([f32::NAN]),
                Some([1.5]),
                Some([f32::INFINITY]),
            ]
            .into_iter(),
            0.1,
        );
        assert_eq!(layer.exceeding_pixels, 3);
        assert_eq!(layer.pixels, 5);
        assert_eq!(layer.max_finite_difference_m, 0.5);
        // Sky as the channel map writes it is "nothing seen", whatever its depth value.
        let mut a = frame(4, 4);
        let mut b = a.clone();
        a.depth_m[0] = crate::draw::SKY_DEPTH_M;
        b.depth_m[0] = 3.0;
        b.object[0] = 1;
        b.position[0] = [0.0, 0.0, 3.0];
        let depth = layer_difference(seen_depths(&a), seen_depths(&b), 0.001);
        assert_eq!(depth.exceeding_pixels, 1);
        assert!(
            depth.max_finite_difference_m < 1.0,
            "no 1e10 m difference is reported"
        );
    }

    #[test]
    fn counts_name_each_differing_field_and_missing_counts_warn() {
        let a = serde_json::json!({"vertices": {"popping": 0, "outside": 3}});
        let b = serde_json::json!({"vertices": {"popping": 2, "outside": 3}});
        assert_eq!(
            compare_counts(&Ok(a.clone()), &Ok(b)),
            CountsComparison::Differ(vec!["vertices.popping 0 -> 2".into()])
        );
        let without = LoadedFrame {
            frame: frame(8, 8),
            flag_counts: Err("x.exr has no counts".into()),
        };
        let (_, counts, findings, _) =
            compare_frames(&loaded(frame(8, 8), a), &without, &Thresholds::default());
        assert!(matches!(counts, CountsComparison::Unavailable(_)));
        assert_eq!(findings.len(), 1);
        assert_eq!(findings[0].verdict, Verdict::Warn);
        assert!(findings[0].message.contains("x.exr"));
    }

    #[test]
    fn size_difference_fails_without_metrics() {
        let counts = serde_json::json!({});
        let (metrics, _, findings, heat) = compare_frames(
            &loaded(frame(8, 8), counts.clone()),
            &loaded(frame(8, 4), counts),
            &Thresholds::default(),
        );
        assert!(metrics.is_none() && heat.is_none());
        assert_eq!(findings[0].verdict, Verdict::Fail);
        assert!(findings[0].message.contains("8x8") && findings[0].message.contains("8x4"));
    }

    #[test]
    fn thresholds_reject_warn_above_fail_and_negative_values() {
        assert!(Thresholds::default().validate().is_ok());
        let inverted = Thresholds {
            flip_mean_warn: 0.5,
            flip_mean_fail: 0.1,
            ..Thresholds::default()
        };
        let message = inverted.validate().unwrap_err().to_string();
        assert!(message.contains("--flip-mean-warn"), "{message}");
        let negative = Thresholds {
            depth_tolerance_m: -1.0,
            ..Thresholds::default()
        };
        assert!(negative
            .validate()
            .unwrap_err()
            .to_string()
            .contains("--z-tolerance"));
    }

    #[test]
    fn verdicts_order_and_exit_codes_follow_idiff() {
        assert!(Verdict::Pass < Verdict::Warn && Verdict::Warn < Verdict::Fail);
        assert_eq!(
            [Verdict::Pass, Verdict::Warn, Verdict::Fail].map(Verdict::exit_code),
            [0, 1, 2]
        );
    }
}
