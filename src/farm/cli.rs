//! `snell farm slurm`, `snell farm openjd`, `snell farm simulate` and `snell farm check` as the
//! command line sees them. Exit codes: 0 done, 2 bad scene or arguments, 1 other failures (sbatch
//! failing; for check, a missing or bad frame).

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

/// `snell farm openjd SCENE ...`.
#[derive(clap::Args, Clone, Debug)]
pub struct OpenjdArgs {
    #[command(flatten)]
    pub shot: ShotArgs,
    /// Frames per task of the Render step.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub chunk: usize,
    /// The snell binary the workers run (default: this one). It must be reachable on every worker.
    #[arg(long, value_name = "PATH")]
    pub snell: Option<PathBuf>,
    /// Where to write the template (default: OUT/farm/job.template.json); `-` prints it.
    #[arg(long, value_name = "FILE")]
    pub template: Option<PathBuf>,
}

/// `snell farm simulate SCENE ...`.
#[derive(clap::Args, Clone, Debug)]
pub struct SimulateArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Frames of the shot, as `snell render --frames`: the ripples are stepped from the timeline's
    /// first frame to the last of these (default: the scene's whole timeline).
    #[arg(long, value_name = "LIST")]
    pub frames: Option<String>,
    /// The shared output folder (or file pattern) the chunks render into, as `snell render
    /// --out`; the checkpoints go in its folder's .snell-sim/ (default: output/<scene name>/).
    #[arg(long, value_name = "DIR|PATTERN")]
    pub out: Option<PathBuf>,
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

/// Which frames are missing or stale; reads the folder, creates nothing in it.
fn plan(loaded: &Loaded) -> Result<ResumePlan, SnellError> {
    let report = ReportWriter::read(loaded.output.dir())?;
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
        outln!(
            "check: {} of {} frame(s) missing or bad: {}",
            plan.render.len(),
            plan.render.len() + plan.skip.len(),
            plan.reasons()
        );
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
            write_file(&dir.join(name), text)?;
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

/// `snell farm openjd`: writes the shot's job template (see [`super::openjd`]).
pub fn run_openjd(args: &OpenjdArgs) -> u8 {
    exit_code((|| {
        if args.chunk == 0 {
            return Err(SnellError::Argument(
                "--chunk 0: a chunk needs frames, e.g. --chunk 10".into(),
            ));
        }
        let loaded = load(&args.shot)?;
        let shot = shot(&loaded, args.chunk, None, args.snell.clone())?;
        let text = serde_json::to_string_pretty(&shot.openjd_template())
            .expect("a JSON value serialises")
            + "\n";
        let path = match &args.template {
            Some(path) if path.as_os_str() == "-" => {
                outln!("{}", text.trim_end());
                return Ok(0);
            }
            Some(path) => path.clone(),
            None => shot.job_dir().join("job.template.json"),
        };
        write_file(&path, &text)?;
        outln!(
            "wrote {} (steps Simulate, Render: {} chunk(s) as task parameter Frames, Check)",
            path.display(),
            shot.chunks.len()
        );
        outln!("check it with: openjd check {}", shell_path(&path));
        outln!(
            "run it here with: openjd run {} --run-dependencies --step Check",
            shell_path(&path)
        );
        Ok(0)
    })())
}

/// Writes `text` to `path` whole or not at all (a temporary file renamed into place).
fn write_file(path: &Path, text: &str) -> Result<(), SnellError> {
    use std::io::Write;
    crate::output::write_atomically(path, |file| {
        file.write_all(text.as_bytes())
            .map_err(|error| error.to_string())
    })?;
    Ok(())
}

fn shell_path(path: &Path) -> String {
    super::shell_word(&path.to_string_lossy())
}

/// `snell farm simulate`: steps the scene's ripples from the timeline's first frame to the shot's
/// last and writes the checkpoint of every frame into the output folder, rendering nothing.
pub fn run_simulate(args: &SimulateArgs) -> u8 {
    exit_code((|| {
        let loaded = load(&ShotArgs {
            scene: args.scene.clone(),
            frames: args.frames.clone(),
            out: args.out.clone(),
            size: "1x1".into(),
        })?;
        let job = &loaded.job;
        let Some(simulation) = &job.dynamics.simulation else {
            outln!(
                "simulate: {} has no ripples (water.ripples is off): nothing to step, the chunks need no checkpoints",
                job.scene_name()
            );
            return Ok(0);
        };
        let out_dir = loaded.output.dir();
        crate::output::ensure_output_dir(out_dir)?;
        crate::output::check_writable(out_dir)?;
        if let Some(text) = job.use_checkpoints(out_dir)? {
            errln!("note: {text}");
        }
        // Frames come within the timeline, so from its first frame to the last of them.
        let first = job.timeline().first_frame;
        let last = loaded
            .frames
            .iter()
            .copied()
            .max()
            .unwrap_or(first)
            .max(first);
        let started = std::time::Instant::now();
        let bar = crate::frame::progress_bar(u64::from(last - first) + 1, true);
        bar.set_message("ripples");
        // Frame by frame (each step from the state in memory), so the bar moves; every state
        // stepped is written as a checkpoint, and one already there is read instead.
        for frame in first..=last {
            let time_secs = job.scene.timeline.time_secs(frame);
            let posed = job.dynamics.posed_objects(time_secs);
            job.dynamics
                .ripples_at(&job.scene, &job.waves, frame, &posed)?;
            bar.inc(1);
        }
        bar.finish_and_clear();
        let dir = simulation
            .store()
            .map_or_else(|| out_dir.to_path_buf(), |store| store.dir().to_path_buf());
        outln!(
            "simulate: ripples of {} at frames {first}-{last} checkpointed in {} ({} frame(s) stepped, the rest already there; {:.1} s)",
            job.scene_name(),
            dir.display(),
            simulation.frames_stepped(),
            started.elapsed().as_secs_f64()
        );
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
