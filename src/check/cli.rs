//! `snell diff` and `snell check` as the command line sees them: receives parsed arguments, prints
//! the per-frame table to stdout and notes to stderr, writes heat maps and the JUnit report, and
//! returns the exit code of OpenImageIO's idiff: 0 pass, 1 warn, 2 fail, 4 an input that cannot be
//! found or read (2 for the other errors: a bad option, a render that failed).

use std::path::{Path, PathBuf};

use super::scene::{choose_size, SceneCheck};
use super::{defaults, diff_paths, junit, CheckError, DiffReport, Thresholds, Verdict};
use crate::frame::{parse_size, FrameRange, RenderJob};

/// Where `snell diff` writes heat maps unless told: beside the renders (`output/` is where
/// `snell render` writes), never next to either input, which may be goldens.
pub const DEFAULT_DIFF_HEATMAP_DIR: &str = "output/diff";

/// Thresholds shared by `snell diff` and `snell check`. A value above a warn level warns (exit 1),
/// above a fail level fails (exit 2).
#[derive(clap::Args, Clone, Debug)]
pub struct ThresholdArgs {
    /// Mean FLIP (0 = identical, 1 = black vs white) of the tone-mapped beauty above which a frame
    /// warns. The default is twice the largest difference between a Vulkan (lavapipe) and a GL
    /// (llvmpipe) render of the same frame, mean 0.0042-0.0051.
    #[arg(long, value_name = "FLIP", default_value_t = defaults::FLIP_MEAN_WARN)]
    pub flip_mean_warn: f32,
    /// Mean FLIP above which a frame fails. The default is three times the Vulkan-vs-GL figure
    /// and well below the smallest difference between two consecutive frames of the project's
    /// scenes (0.026 and up).
    #[arg(long, value_name = "FLIP", default_value_t = defaults::FLIP_MEAN_FAIL)]
    pub flip_mean_fail: f32,
    /// 99th-percentile FLIP above which a frame warns: catches a small object moved, which the mean
    /// dilutes. The default is twice the Vulkan-vs-GL figure (p99 up to 0.030).
    #[arg(long, value_name = "FLIP", default_value_t = defaults::FLIP_P99_WARN)]
    pub flip_p99_warn: f32,
    /// 99th-percentile FLIP above which a frame fails. The default is half the smallest p99 between
    /// consecutive frames (0.24); a single changed pixel leaves the p99 near 0.
    #[arg(long, value_name = "FLIP", default_value_t = defaults::FLIP_P99_FAIL)]
    pub flip_p99_fail: f32,
    /// Tolerance on Z (depth along the view axis), metres, per pixel. Sky matches sky.
    /// Vulkan vs GL renders agree to 1.1e-5 m.
    #[arg(long = "z-tolerance", value_name = "M", default_value_t = defaults::DEPTH_TOLERANCE_M)]
    pub depth_tolerance_m: f32,
    /// Tolerance on P (true world position), metres (Euclidean), per pixel. Pixels seeing no
    /// object on both sides match.
    #[arg(long = "p-tolerance", value_name = "M", default_value_t = defaults::POSITION_TOLERANCE_M)]
    pub position_tolerance_m: f32,
    /// Fraction of the pixels whose Z or P may be off by more than the tolerance before a frame
    /// warns. Vulkan vs GL (both Mesa): 0 pixels; other rasterisers may
    /// cover silhouette pixels differently, so 0.1 % (an outline) only warns.
    #[arg(long = "exceed-warn", value_name = "FRACTION", default_value_t = defaults::EXCEEDING_FRACTION_WARN)]
    pub exceeding_fraction_warn: f64,
    /// Fraction of the pixels off in Z or P at which a frame fails. Consecutive frames: 37 % and up.
    #[arg(long = "exceed-fail", value_name = "FRACTION", default_value_t = defaults::EXCEEDING_FRACTION_FAIL)]
    pub exceeding_fraction_fail: f64,
}

impl ThresholdArgs {
    pub fn thresholds(&self) -> Thresholds {
        Thresholds {
            flip_mean_warn: self.flip_mean_warn,
            flip_mean_fail: self.flip_mean_fail,
            flip_p99_warn: self.flip_p99_warn,
            flip_p99_fail: self.flip_p99_fail,
            depth_tolerance_m: self.depth_tolerance_m,
            position_tolerance_m: self.position_tolerance_m,
            exceeding_fraction_warn: self.exceeding_fraction_warn,
            exceeding_fraction_fail: self.exceeding_fraction_fail,
        }
    }
}

/// `snell diff A B`.
#[derive(clap::Args, Clone, Debug)]
pub struct DiffArgs {
    /// The reference: an EXR frame, or a directory of frames (e.g. goldens).
    pub reference: PathBuf,
    /// The frame(s) to judge: an EXR file, or a directory matched to the reference by file name.
    pub test: PathBuf,
    /// Also write a JUnit XML report (one testcase per frame) to FILE.
    #[arg(long, value_name = "FILE")]
    pub junit: Option<PathBuf>,
    /// Where `<frame>-difference.png` FLIP heat maps of frames that warn or fail are written.
    #[arg(long, value_name = "DIR", default_value = DEFAULT_DIFF_HEATMAP_DIR)]
    pub heatmaps: PathBuf,
    #[command(flatten)]
    pub thresholds: ThresholdArgs,
}

/// `snell check SCENE --golden DIR`.
#[derive(clap::Args, Clone, Debug)]
pub struct CheckArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Directory of golden frames, DIR/<scene>.NNNN.exr.
    #[arg(long, value_name = "DIR")]
    pub golden: PathBuf,
    /// Frames to check: "A-B" or "N" (default: the scene's whole timeline).
    #[arg(long, value_name = "A-B")]
    pub frames: Option<String>,
    /// Render the frames and (re)write them as the goldens instead of comparing; exits 0.
    #[arg(long)]
    pub bless: bool,
    /// Render size. Default: the size of the existing goldens (the first one found in the range),
    /// else 320x180 (about a second per frame on a CPU-only CI machine).
    #[arg(long, value_name = "WxH")]
    pub size: Option<String>,
    /// Where the frames are rendered; heat maps of frames that warn or fail go there too.
    /// Default: output/<scene>/check/.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also write a JUnit XML report (one testcase per frame) to FILE.
    #[arg(long, value_name = "FILE")]
    pub junit: Option<PathBuf>,
    #[command(flatten)]
    pub thresholds: ThresholdArgs,
}

/// Runs `snell diff`; returns the exit code.
pub fn run_diff(args: &DiffArgs) -> u8 {
    let thresholds = args.thresholds.thresholds();
    let result = diff_paths(
        &args.reference,
        &args.test,
        &thresholds,
        Some(&args.heatmaps),
    );
    finish(result, "snell diff", args.junit.as_deref(), &args.heatmaps)
}

/// Runs `snell check`; returns the exit code.
pub fn run_check(args: &CheckArgs) -> u8 {
    match check(args) {
        Ok(code) => code,
        Err(error) => {
            errln!("error: {error}");
            error.exit_code()
        }
    }
}

fn check(args: &CheckArgs) -> Result<u8, CheckError> {
    let thresholds = args.thresholds.thresholds();
    thresholds.validate()?;
    let requested_size = args.size.as_deref().map(parse_size).transpose()?;
    let job = RenderJob::prepare(&args.scene)?;
    let range = match &args.frames {
        Some(text) => FrameRange::parse(text, job.timeline())?,
        None => FrameRange::whole(job.timeline()),
    };
    let frames: Vec<u32> = range.frames().collect();
    let size = choose_size(requested_size, &args.golden, job.scene_name(), &frames)?;
    let work_dir = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("output").join(job.scene_name()).join("check"));
    let request = SceneCheck {
        job: &job,
        frames,
        size,
        golden_dir: &args.golden,
        work_dir: &work_dir,
        thresholds,
        progress: true,
    };
    if args.bless {
        let written = request.bless()?;
        errln!(
            "blessed {} golden frame(s) of {} at {}x{} in {}",
            written.len(),
            job.scene_name(),
            size.0,
            size.1,
            args.golden.display()
        );
        return Ok(Verdict::Pass.exit_code());
    }
    errln!(
        "checking {} frame(s) of {} at {}x{} against {}",
        range.len(),
        job.scene_name(),
        size.0,
        size.1,
        args.golden.display()
    );
    let report = request.check(Some(&work_dir));
    let suite = format!("snell check {}", job.scene_name());
    Ok(finish(report, &suite, args.junit.as_deref(), &work_dir))
}

/// Prints the table and summary, writes the JUnit report, returns the exit code.
fn finish(
    result: Result<DiffReport, CheckError>,
    suite_name: &str,
    junit_path: Option<&Path>,
    heatmap_dir: &Path,
) -> u8 {
    let report = match result {
        Ok(report) => report,
        Err(error) => {
            errln!("error: {error}");
            return error.exit_code();
        }
    };
    out!("{}", report.table());
    let mut summary = report.summary();
    if report.frames.iter().any(|frame| frame.heatmap.is_some()) {
        summary.push_str(&format!("; FLIP heat maps in {}", heatmap_dir.display()));
    }
    outln!("{summary}");
    if let Some(path) = junit_path {
        if let Err(error) = junit::write_junit(path, suite_name, &report) {
            errln!("error: {error}");
            return Verdict::Fail.exit_code();
        }
    }
    report.exit_code()
}
