//! `snell farm slurm`, `snell farm check` as the command line sees them. Exit codes: 0 done,
//! 2 bad scene or arguments, 1 other failures (sbatch failing; for check, a missing or bad frame).

use std::path::{Path, PathBuf};
use std::process::Command;

use super::{array_list, chunk_frames, frames_arg, Shot};
use crate::frame::resume::{frame_list, plan_resume, ResumePlan};
use crate::frame::{parse_frame_list, parse_size, FrameRange, RenderJob, SnellError};
use crate::output::pattern::OutputPattern;
use crate::output::report::ReportWriter;

/// The shot a farm command works on: the same scene, frames, output and size as `snell render`.
#[derive(clap::Args, Clone, Debug)]
pub struct ShotArgs {
    /// The scene file (TOML), as the farm nodes see it (a path on shared storage).
    pub scene: PathBuf,
    /// Frames of the shot, as `snell render --frames` (default: the scene's whole timeline).
    #[arg(long, value_name = "LIST")]
    pub frames: Option<String>,
    /// The shared output folder (or file pattern) every node writes to, as `snell render --out`
    /// (default: output/<scene name>/). It must be the same path on every node.
    #[arg(long, value_name = "DIR|PATTERN")]
    pub out: Option<PathBuf>,
    /// Image size in pixels.
    #[arg(long, value_name = "WxH", default_value = "1280x720")]
    pub size: String,
}

/// `snell farm slurm SCENE ...`.
#[derive(clap::Args, Clone, Debug)]
pub struct SlurmArgs {
    #[command(flatten)]
    pub shot: ShotArgs,
    /// Frames per array task.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub chunk: usize,
    /// The Slurm partition of all three jobs (default: the cluster's default partition).
    #[arg(long, value_name = "P")]
    pub partition: Option<String>,
    /// Write the scripts to OUT/farm/ and submit them with sbatch, chained by dependencies.
    #[arg(long, conflicts_with = "dry_run")]
    pub submit: bool,
    /// Print the three scripts instead of writing them; submits nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// With --submit: submit only the chunks holding a missing or stale frame (the same test as
    /// `snell render --resume`); nothing when no chunk needs it. The simulation job is submitted
    /// again with them (the array depends on it).
    #[arg(long)]
    pub resume: bool,
    /// The snell binary the nodes run (default: this one). It must be reachable on every node.
    #[arg(long, value_name = "PATH")]
    pub snell: Option<PathBuf>,
}

/// `snell farm check SCENE ...`.
#[derive(clap::Args, Clone, Debug)]
pub struct CheckArgs {
    #[command(flatten)]
    pub shot: ShotArgs,
}

struct Loaded {
    scene_path: PathBuf,
    job: RenderJob,
    frames: Vec<u32>,
    output: OutputPattern,
    out: PathBuf,
    width: u32,
    height: u32,
}

fn load(args: &ShotArgs) -> Result<Loaded, SnellError> {
    let (width, height) = parse_size(&args.size)?;
    let job = RenderJob::prepare(&args.scene)?;
    let frames = match &args.frames {
        Some(text) => parse_frame_list(text, job.timeline())?,
        None => FrameRange::whole(job.timeline()).frames().collect(),
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("output").join(job.scene_name()));
    let out = std::path::absolute(&out).unwrap_or(out);
    let output = match OutputPattern::parse(&out).map_err(SnellError::Argument)? {
        Some(pattern) => pattern,
        None => OutputPattern::for_scene(&out, job.scene_name()),
    };
    Ok(Loaded {
        // The nodes run the scripts from their own folder: absolute paths.
        scene_path: std::fs::canonicalize(&args.scene).unwrap_or_else(|_| args.scene.clone()),
        job,
        frames,
        output,
        out,
        width,
        height,
    })
}

fn plan(loaded: &Loaded) -> Result<ResumePlan, SnellError> {
    let report = ReportWriter::create(loaded.output.dir())?;
    Ok(plan_resume(
        &loaded.job,
        &loaded.frames,
        loaded.width,
        loaded.height,
        &loaded.output,
        &report,
    ))
}

fn exit_code(result: Result<u8, SnellError>) -> u8 {
    match result {
        Ok(code) => code,
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

/// `snell farm check`: 0 when every frame is whole, current and in the report; 1 naming the
/// others and printing the command that re-renders exactly those.
pub fn run_check(args: &CheckArgs) -> u8 {
    exit_code((|| {
        let loaded = load(&args.shot)?;
        let plan = plan(&loaded)?;
        if plan.render.is_empty() {
            outln!(
                "check: all {} frame(s) whole and current ({})",
                plan.skip.len(),
                frame_list(&plan.skip)
            );
            return Ok(0);
        }
        outln!("check: {}", plan.summary());
        let bad: Vec<u32> = plan.render.iter().map(|(frame, _)| *frame).collect();
        let shot = shot(&loaded, 1, None, None)?;
        outln!("re-render with: {}", shot.render_command(&frames_arg(&bad)));
        Ok(1)
    })())
}

fn shot(
    loaded: &Loaded,
    chunk: usize,
    partition: Option<String>,
    snell: Option<PathBuf>,
) -> Result<Shot, SnellError> {
    let snell = match snell {
        Some(path) => path,
        None => std::env::current_exe().map_err(|error| {
            SnellError::Argument(format!(
                "cannot find this snell binary ({error}); give --snell PATH"
            ))
        })?,
    };
    Ok(Shot {
        snell,
        scene: loaded.scene_path.clone(),
        out: loaded.out.clone(),
        out_dir: loaded.output.dir().to_path_buf(),
        size: format!("{}x{}", loaded.width, loaded.height),
        chunks: chunk_frames(&loaded.frames, chunk),
        frames: loaded.frames.clone(),
        partition,
    })
}

/// `snell farm slurm`.
pub fn run_slurm(args: &SlurmArgs) -> u8 {
    exit_code((|| {
        if args.chunk == 0 {
            return Err(SnellError::Argument(
                "--chunk 0: a chunk needs frames, e.g. --chunk 10".into(),
            ));
        }
        if args.resume && !args.submit {
            return Err(SnellError::Argument(
                "--resume resubmits: give it with --submit".into(),
            ));
        }
        let loaded = load(&args.shot)?;
        let shot = shot(
            &loaded,
            args.chunk,
            args.partition.clone(),
            args.snell.clone(),
        )?;
        let scripts = [
            ("simulation.sbatch", shot.simulation_script()),
            ("chunks.sbatch", shot.chunks_script()),
            ("check.sbatch", shot.check_script()),
        ];
        if !args.submit {
            for (name, text) in &scripts {
                outln!("### {name}\n{text}");
            }
            if !args.dry_run {
                errln!("note: nothing written or submitted; give --submit to submit, --dry-run to only print");
            }
            return Ok(0);
        }
        let chunks: Vec<usize> = if args.resume {
            let plan = plan(&loaded)?;
            let bad: Vec<u32> = plan.render.iter().map(|(frame, _)| *frame).collect();
            errln!("{}", plan.summary());
            shot.chunks_holding(&bad)
        } else {
            (0..shot.chunks.len()).collect()
        };
        if chunks.is_empty() {
            outln!("nothing to submit: every frame is whole and current");
            return Ok(0);
        }
        let dir = shot.job_dir();
        std::fs::create_dir_all(shot.log_dir()).map_err(|error| {
            SnellError::Argument(format!(
                "{}: cannot create: {error}",
                shot.log_dir().display()
            ))
        })?;
        for (name, text) in &scripts {
            let path = dir.join(name);
            std::fs::write(&path, text).map_err(|error| {
                SnellError::Argument(format!("{}: cannot write: {error}", path.display()))
            })?;
        }
        let submitted = (|| -> Result<(String, String, String), String> {
            let simulation = sbatch(&[], &dir.join("simulation.sbatch"))?;
            let array = sbatch(
                &[
                    format!("--dependency=afterok:{simulation}"),
                    format!("--array={}", array_list(&chunks)),
                ],
                &dir.join("chunks.sbatch"),
            )?;
            let check = sbatch(
                &[format!("--dependency=afterany:{array}")],
                &dir.join("check.sbatch"),
            )?;
            Ok((simulation, array, check))
        })();
        let (simulation, array, check) = match submitted {
            Ok(ids) => ids,
            Err(message) => {
                errln!("error: {message}");
                return Ok(1);
            }
        };
        outln!("simulation job {simulation}");
        outln!("chunk array job {array} (tasks {})", array_list(&chunks));
        outln!("check job {check}");
        outln!("logs: {}", shot.log_dir().display());
        Ok(0)
    })())
}

/// Submits `script` with `sbatch --parsable`, returning the job id.
fn sbatch(options: &[String], script: &Path) -> Result<String, String> {
    let output = Command::new("sbatch")
        .arg("--parsable")
        .args(options)
        .arg(script)
        .output()
        .map_err(|error| {
            format!("cannot run sbatch ({error}): is Slurm's client installed and on PATH?")
        })?;
    if !output.status.success() {
        return Err(format!(
            "sbatch {}: {}",
            script.display(),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let text = String::from_utf8_lossy(&output.stdout);
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() {
        return Err(format!("sbatch {}: printed no job id", script.display()));
    }
    Ok(id)
}
