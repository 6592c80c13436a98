//! `snell locate`, `snell compare` and `snell export` as the command line sees them: parsed
//! arguments in, output on stdout (notes on stderr), and the exit code: 0 done, 2 bad input (a
//! file that cannot be read or parsed, a bad argument, an output directory that cannot be
//! written), 1 anything else.

use std::path::PathBuf;

use super::{compare, export, locate, ToolError};
use crate::frame::{parse_size, Method, RenderJob, SnellError};
use crate::output::position_error::Side;

/// `snell locate SCENE --frame N --points FILE.csv`.
#[derive(clap::Args, Clone, Debug)]
pub struct LocateArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// The frame whose water the points are seen through.
    #[arg(long, value_name = "N")]
    pub frame: u32,
    /// World points, one `x,y,z` per line in metres (a first line `x,y,z` is a header; blank
    /// lines and lines starting with # are skipped).
    #[arg(long, value_name = "FILE.csv")]
    pub points: PathBuf,
    /// Which refraction cells find the images: equal-t (the default) or thesis-plane; exact
    /// prints the exact images Newton reaches from the equal-t ones (as `render --method exact`).
    #[arg(long, default_value = "equal-t", value_name = "METHOD")]
    pub method: String,
}

/// `snell compare A.exr B.exr`.
#[derive(clap::Args, Clone, Debug)]
pub struct CompareArgs {
    /// The reference frame (e.g. a `--method raytrace` render): the fold band comes from its map.
    pub a: PathBuf,
    /// The frame measured against it, of the same shot and size (e.g. a `--method exact` render).
    pub b: PathBuf,
    /// Which file's flags define "flagged" (A or B). By default the one a rasterising method
    /// made, read from the headers (the ray tracers flag nothing), and B when that does not
    /// decide. The report says which it used and why.
    #[arg(long, value_name = "A|B", value_parser = parse_side)]
    pub flags_from: Option<Side>,
    /// Print the figures as one JSON object instead of a table: a_to_b, b_to_a and both, each
    /// with all, outside_flagged and outside_fold_band, each with mean_px, p99_px, max_px,
    /// over_1px_fraction, counted and unseen; flags_from, flags_reason, flagged_pixels,
    /// flagged_water_fraction; fold_edges, fold_band_pixels, fold_band_water_fraction,
    /// water_pixels; flip_mean; object_mismatch_fraction, object_mismatch_pixels, pixels.
    #[arg(long)]
    pub json: bool,
}

fn parse_side(text: &str) -> Result<Side, String> {
    match text.trim() {
        "A" | "a" => Ok(Side::A),
        "B" | "b" => Ok(Side::B),
        other => Err(format!(
            "{other:?}: choose A (the first file) or B (the second)"
        )),
    }
}

/// `snell export SCENE --frame N --out DIR`.
#[derive(clap::Args, Clone, Debug)]
pub struct ExportArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// The frame to export (characters posed and water as at that frame).
    #[arg(long, value_name = "N")]
    pub frame: u32,
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// obj: one OBJ with an object per scene object, an MTL and PNG textures; ply: one ASCII PLY
    /// per object.
    #[arg(long, default_value = "obj", value_name = "FORMAT")]
    pub format: String,
    /// Image size the camera's aspect ratio and clip matrix in camera.json are for.
    #[arg(long, value_name = "WxH", default_value = "1280x720")]
    pub size: String,
}

/// Prints the error and returns the exit code.
fn exit_code(result: Result<(), ToolError>) -> u8 {
    match result {
        Ok(()) => 0,
        Err(error) => {
            errln!("error: {error}");
            if error.is_bad_input() {
                2
            } else {
                1
            }
        }
    }
}

fn prepare(scene: &std::path::Path, method: Option<&str>) -> Result<RenderJob, ToolError> {
    let mut job = RenderJob::prepare(scene)?;
    if let Some(method) = method {
        job.method =
            Method::parse(method).map_err(|e| SnellError::Argument(format!("--method: {e}")))?;
    }
    Ok(job)
}

pub fn run_locate(args: &LocateArgs) -> u8 {
    exit_code(locate_command(args))
}

fn locate_command(args: &LocateArgs) -> Result<(), ToolError> {
    // The points first: a typo there is found without loading the scene.
    let points = locate::read_points_csv(&args.points)?;
    let job = prepare(&args.scene, Some(&args.method))?;
    let located = locate::locate(&job, args.frame, &points)?;
    let (csv, notes) = locate::format_located(&located);
    out!("{csv}");
    for note in notes {
        errln!("note: {note}");
    }
    Ok(())
}

pub fn run_compare(args: &CompareArgs) -> u8 {
    exit_code(compare_command(args))
}

fn compare_command(args: &CompareArgs) -> Result<(), ToolError> {
    let comparison = compare::compare_files(&args.a, &args.b, args.flags_from)?;
    if args.json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&comparison).expect("comparison serialises")
        );
    } else {
        out!("{}", comparison.to_text());
    }
    Ok(())
}

pub fn run_export(args: &ExportArgs) -> u8 {
    exit_code(export_command(args))
}

fn export_command(args: &ExportArgs) -> Result<(), ToolError> {
    let format = export::ExportFormat::parse(&args.format)?;
    let size = parse_size(&args.size)?;
    let job = prepare(&args.scene, None)?;
    let summary = export::export_frame(&job, args.frame, &args.out, format, size)?;
    for file in &summary.files {
        outln!("{}", file.display());
    }
    errln!(
        "exported frame {} of {}: {} objects (water included), {} vertices, {} triangles into {}",
        args.frame,
        job.scene_name(),
        summary.objects,
        summary.vertices,
        summary.triangles,
        args.out.display()
    );
    Ok(())
}
