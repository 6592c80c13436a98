//! The `snell` command line: thin wrappers over the library's stages. anyhow lives only here.
//! Exit codes: 0 success, 2 bad input (scene, arguments, output path), 1 anything else.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use snell::frame::{self, FrameRange, Method, RenderJob, SnellError};
use snell::{errln, out, outln};

#[derive(Parser)]
#[command(
    name = "snell",
    version,
    about = "Render objects seen through moving water, with geometric refraction you can trust",
    long_about = "snell renders animated scenes of objects seen through a moving water surface. \
For every frame it simulates the water, computes each under-water vertex's virtual position (where \
the eye sees it through the refracting surface), renders with wgpu and writes multi-layer OpenEXR \
frames plus a per-frame report of where the method is known to be wrong (convergence zones, \
boundary triangles, popping, extrapolated rays).\n\n\
Start with:  snell render scenes/pool.toml"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// `snell farm ...`.
#[derive(Subcommand)]
enum FarmCommand {
    /// Write the shot's three Slurm jobs as #SBATCH scripts in OUT/farm/ and, with --submit,
    /// submit them with sbatch: a simulation job (steps the ripples once and writes their
    /// checkpoints), a job array of chunks `afterok` on it (task i renders chunk i into --out,
    /// its log in OUT/farm/logs/chunk-<i>.log), and a check job `afterany` on the array (runs
    /// after failures too; `snell farm check`). --dry-run prints the scripts. After failed or
    /// cancelled tasks, --submit --resume submits only the chunks holding a missing or stale
    /// frame. Example: snell farm slurm scenes/fox_wading.toml --chunk 12 --out /shared/fox --submit
    Slurm(snell::farm::cli::SlurmArgs),
    /// Check every frame of a shot: each EXR whole, made from this scene's inputs (the input
    /// hash `snell render --resume` checks) and its report row present. Exit 0 when all are;
    /// 1 naming each missing or bad frame and printing the command that re-renders exactly those.
    Check(snell::farm::cli::CheckArgs),
    /// Write the shot as an Open Job Description job template (jobtemplate-2023-09, as AWS
    /// Deadline Cloud runs): steps Simulate, Render (one task per chunk, its frames the task
    /// parameter Frames; depends on Simulate) and Check (depends on Render), into
    /// OUT/farm/job.template.json. Validate with `openjd check FILE`; run here with
    /// `openjd run FILE --run-dependencies --step Check`.
    Openjd(snell::farm::cli::OpenjdArgs),
    /// The farm's first job: step the scene's ripple simulation once, from the timeline's first
    /// frame to the shot's last, and write every frame's checkpoint into the output folder
    /// (OUT/.snell-sim/), rendering nothing. Chunks rendered into OUT then read their ripple states
    /// there instead of each stepping from the first frame (their `snell render` says how many
    /// frames it stepped: 0).
    Simulate(snell::farm::cli::SimulateArgs),
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene's frames to OpenEXR (beauty, Z, true position P, flag masks) and a report.
    ///
    /// Frames land in DIR/<scene>.<frame>.exr (4-digit frame numbers) or where --out's pattern
    /// says; DIR/report.jsonl gets one JSON line per frame with flag counts and seconds per stage.
    /// Each frame is written under a temporary name and renamed, so an interrupted render never
    /// leaves a truncated frame.
    ///
    /// Any number of renders may write one folder at once, on one machine or several (a farm's
    /// chunks, overlapping or not): the report is updated under a lock so no row is lost, each
    /// version of a scene keeps its own simulation checkpoints, and --resume afterwards keeps
    /// every whole frame. With stdout not a terminal, each written frame is one line there
    /// (frame, seconds, flag counts); --log-json makes it JSON.
    ///
    /// Ctrl-C (or SIGTERM) stops after the frame in flight is written, prints the frames done and
    /// the command that finishes the render, and exits with 130 (143 for SIGTERM); a second Ctrl-C
    /// stops at once. Temporary files a killed render left behind are removed by the next render
    /// into the same directory. Exit codes: 0 done, 2 bad scene, arguments or output directory,
    /// 1 other failures (e.g. a full disk mid-render).
    Render {
        /// The scene file (TOML), e.g. scenes/pool.toml.
        scene: PathBuf,
        /// Frames to render: a frame "N", a range "A-B", a range with a step "A-BxS" (A, A+S, ...
        /// up to B), or a comma-separated list of these, e.g. "1-48x4,50" (default: the scene's
        /// whole timeline). Frames are rendered in order, each once.
        #[arg(long, value_name = "LIST")]
        frames: Option<String>,
        /// Output folder (default: output/<scene name>/), or a file pattern whose `#` run is the
        /// frame number padded to that many digits, e.g. shots/pool/render.####.exr; husk's
        /// $F4 works too ($F: no padding). The report and the checkpoints go in its folder.
        #[arg(long, value_name = "DIR|PATTERN")]
        out: Option<PathBuf>,
        /// Image size in pixels.
        #[arg(long, value_name = "WxH", default_value = "1280x720")]
        size: String,
        /// Also write a tone-mapped PNG next to each EXR.
        #[arg(long)]
        png: bool,
        /// How under-water geometry is placed: equal-t (refraction cells without gaps or
        /// overlaps, the default), thesis-plane (the thesis's plane-test cells, for comparison) or
        /// exact (Newton on Fermat's principle from each equal-t image, exact to ~1e-12, with
        /// adaptive subdivision of under-water triangles; vertices where Newton fails are drawn
        /// at the equal-t point and counted as newton_fallback in the report).
        /// Or trace the frame on the CPU instead (no GPU needed): raytrace, the reference (the
        /// exact wave surface by root finding, refracted rays through a BVH, the same shading),
        /// or raytrace-membrane (the same tracer through the triangulated membrane with
        /// interpolated normals, the surface the rasteriser draws). The ray-traced methods have
        /// no virtual vertices: their flag counts are all 0 and the flag layers empty.
        /// When the scene states `[quality] max_error_px` and no --method is given, snell measures
        /// the shot and picks the coarsest membrane and cheapest method that meet the budget
        /// (see `snell chart --help`); --method overrides that choice.
        #[arg(long, value_name = "METHOD")]
        method: Option<String>,
        /// --method exact only: split an under-water edge (recursively, at most 4 levels) while
        /// the exact image of its midpoint is farther than this many pixels from the straight
        /// virtual edge. Smaller is more accurate and slower; the report counts the triangles
        /// subdivided.
        #[arg(long, value_name = "PX", default_value_t = snell::refraction::subdivision::DEFAULT_TOLERANCE_PX)]
        subdivision_px: f32,
        /// Keep frames already complete from the same inputs and render only the rest. A frame is
        /// kept when its EXR reads back whole and its header's input hash (of the scene file,
        /// every file it references, the size and the method) and its report row match this
        /// render's; the command says how many it kept and why it renders the others (missing,
        /// unreadable, made from other inputs).
        #[arg(long)]
        resume: bool,
        /// Print one JSON object per written frame on stdout: {"frame", "secs" (its stages, the
        /// write included), "path", "counts" (flag counts per vertex and per triangle)}. Without
        /// it, when stdout is not a terminal (a farm's log), the same is printed as one line of
        /// text per frame.
        #[arg(long)]
        log_json: bool,
        /// Draw and read back each frame in horizontal strips of this many rows (a multiple of
        /// 32; rounded down). Without it a frame is drawn whole when its readback fits 256 MiB
        /// (2560x1440 does) and in strips of as many rows as fit otherwise, so that any size
        /// renders without holding the whole frame. Strips give the whole frame's pixels in every
        /// layer (within 1e-5, tested; bit for bit on Mesa's Vulkan and GL). This option is for
        /// tests and measurements.
        #[arg(long, value_name = "ROWS")]
        strip_rows: Option<u32>,
        #[command(flatten)]
        exr: snell::output::exr::cli::ExrArgs,
    },
    /// Scrub a scene's timeline, or a folder of rendered EXRs, in the browser: a local web page
    /// with the frame, a timeline slider, play/pause, J/K/L shuttle, a loop range, a frame number
    /// to type, exposure, flag overlays, zoom and pan (wheel, drag, fit, 1:1), any layer of the
    /// channel map as an image, a pixel inspector (every channel's value under the cursor, the
    /// object's name, the flags, the position error against the ray-traced reference), an A/B
    /// compare of two methods or folders (A, B, wipe, difference), and a strip of per-frame flag
    /// counts.
    ///
    /// Serves on 127.0.0.1 only. Frames render on demand at the preview size and are cached;
    /// neighbours are prefetched. Edit the scene file (or any file it uses) and the page reloads
    /// it; a scene error is shown on the page, and the last version that loaded stays
    /// scrubbable until the error is fixed. Ripple simulations use the checkpoints of
    /// `snell render` (in output/<scene>/ unless --out says otherwise). Stop with Ctrl-C.
    ///
    /// Examples:
    ///   snell preview scenes/pool.toml
    ///   snell preview --frames-dir output/pool
    ///   snell preview --frames-dir renders/equal-t --frames-dir renders/raytrace   (A/B, and the
    ///     inspector's position error against the raytrace folder)
    Preview {
        /// The scene file (TOML). Not with --frames-dir.
        #[arg(required_unless_present = "frames_dir", conflicts_with = "frames_dir")]
        scene: Option<PathBuf>,
        /// Play back a folder of rendered EXR frames (files with the frame number before .exr, such
        /// as pool.0001.exr) instead of rendering a scene; frames are decoded ahead of the
        /// playhead. Give it again for more folders: each is a source to choose as A or B (named by
        /// its folder), and one rendered with `--method raytrace` is the inspector's reference.
        #[arg(long, value_name = "DIR", conflicts_with_all = ["size", "out"])]
        frames_dir: Vec<PathBuf>,
        /// TCP port on 127.0.0.1 (0 picks a free one).
        #[arg(long, default_value_t = 8080)]
        port: u16,
        /// Preview image size in pixels.
        #[arg(long, value_name = "WxH", default_value = "640x360")]
        size: String,
        /// Where simulation checkpoints are kept (default: output/<scene name>/).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Print what a scene contains (objects, vertices, triangles, membrane, frame range) and the GPU
    /// adapter a render would use.
    Info {
        /// The scene file (TOML).
        scene: PathBuf,
    },
    /// Measure speed: refraction search throughput and speed-up over brute force, per-stage
    /// frame times of a scene (default scenes/pool.toml) at 1280x720, and the ray-traced
    /// reference's refracted rays per second and seconds per frame on the same scene and size,
    /// and the refraction stage of a wake (default scenes/hard/wading_wake.toml frames 40-48)
    /// beside the same frames with ripples off; the whole `snell render` per written frame
    /// of the scene at 1280x720 (`written`: frames 1-8 unwritten, then written with `--layers
    /// comp` and with `all`, alternating over 3 passes; wall-clock and CPU per frame and the
    /// ratios written / unwritten, targets at most 1.3x for `comp` and 2.5x for `all`);
    /// and the vessel displacement (Mukai et al.) of 100,000 vertices through a glass of water
    /// and an aquarium pane, in vertices per second beside the paper's GPU figures and the
    /// water's refraction stage on as many vertices.
    Bench {
        /// Print the figures as one JSON object.
        #[arg(long)]
        json: bool,
        /// Measure only the written-frame figures (`written`, about 20 s on an idle 2-core
        /// machine) and none of the others.
        #[arg(long)]
        written_only: bool,
        /// Scene whose frame times are measured.
        #[arg(long, default_value = "scenes/pool.toml")]
        scene: PathBuf,
        /// Scene with characters whose skinning and ripple share of the frame is measured.
        #[arg(long, default_value = "scenes/fox_wading.toml")]
        characters_scene: PathBuf,
        /// glTF model whose skinning throughput is measured.
        #[arg(long, default_value = "scenes/assets/Fox.glb")]
        skinning_model: PathBuf,
        /// Frames rendered for the frame-time figures (after one warm-up frame).
        #[arg(long, default_value_t = 8)]
        frames: u32,
        /// Scene with a character's wake whose refraction stage is measured beside a calm copy
        /// of it (the same scene with ripples off: same membrane, characters and camera).
        #[arg(long, default_value = "scenes/hard/wading_wake.toml")]
        wake_scene: PathBuf,
        /// Frames of the wake scene measured, "A-B" (after a warm-up frame before A).
        #[arg(long, default_value = "40-48")]
        wake_frames: String,
    },
    /// Compare two EXR frames, or two directories of frames matched by file name: FLIP on the
    /// tone-mapped beauty (mean and 99th percentile), Z and P within tolerances, flag counts exactly.
    ///
    /// Prints a table per frame and exits like OpenImageIO's idiff: 0 every frame passes, 1 some
    /// frame warns, 2 some frame fails (a frame on one side only fails) or an option is bad, 4 an
    /// input cannot be found or read (a missing or unreadable file, an empty directory).
    /// Frames that warn or fail get a FLIP heat map, <frame>-difference.png (black = equal,
    /// yellow = very different).
    Diff(snell::check::cli::DiffArgs),
    /// Render a scene's frames and compare them with golden EXR frames (as `snell diff` does):
    /// a CI frame-diff test. A missing golden fails; --bless writes the goldens.
    ///
    /// Typical use: `snell check scenes/pool.toml --golden ci/golden --frames 1-3 --bless` once,
    /// commit the goldens, then run the same line without --bless in CI (no GPU needed: Mesa's
    /// lavapipe or llvmpipe render on the CPU). Exit codes as for `snell diff`.
    Check(snell::check::cli::CheckArgs),
    /// Reproduce the thesis's accuracy study: error volumes of every row of its Tables 4.1, 4.2
    /// and 4.5, for the linear method (the thesis's cells) and the exact one (Newton on Fermat's
    /// principle), beside the published means, as a Markdown table.
    ///
    /// Each row is a refractor (flat disk of planar radius 142, membranes conforming to spheres as
    /// bowls and as caps, square grids 284 a side) with the eye above it, n1 = 1.0, n2 = 1.51, and
    /// a 400-unit cube of samples under it. For each sample V the method gives a virtual vertex V';
    /// the computed vertex C is where V must be for the eye to see it at V' (exact intersection of
    /// the ray E -> V' with the exact surface, exact refraction, foreshortening undone); the error
    /// is |C - V|. Samples with no image, an extrapolated cell or several images are excluded and
    /// counted. The output states every setup choice. Exit codes: 0 done, 2 bad option or CSV
    /// path, 1 a write that failed.
    Accuracy(snell::accuracy::cli::AccuracyArgs),
    /// Print every image of given world points through a frame's water: where each appears
    /// (virtual vertex), where its sight ray crosses the water (sight point), through which
    /// membrane facet, and whether an extrapolated ray made it.
    ///
    /// Prints CSV on stdout with the columns point,image,vx,vy,vz,sx,sy,sz,facet,extrapolated
    /// (point = 0-based row of the points file, image = 0-based, ordered by facet). The images are
    /// the ones a render of that frame computes (same water, cells and search). A point with no
    /// image has no row: a note on stderr says why (above the water, outside its extent, or
    /// under it but outside the visible volume). Several rows for one point = a zone of
    /// convergence. Example: printf 'x,y,z\n0.2,-0.6,0.1\n' > p.csv;
    /// snell locate scenes/tiny.toml --frame 1 --points p.csv
    Locate(snell::tools::cli::LocateArgs),
    /// Measure how far apart two EXR frames of the same shot are: screen-space position error
    /// both ways, beauty FLIP and object mismatch.
    ///
    /// Position error, A -> B: for each pixel of A that sees an object B sees at that pixel too,
    /// the distance in pixels (sub-pixel) to the nearest place in B that sees the same world
    /// point: B's map pixel -> true position P, interpolated over the pixel grid, is searched
    /// over the whole frame (no window), so errors of any size count; where B does not see the
    /// point at all, the place of the nearest point it sees counts and the pixel is "unseen".
    /// B -> A the same the other way; "both" pools them. With A the reference, A -> B makes an
    /// image the method did not draw cost its distance, and B -> A an image drawn where the truth
    /// has none. Each as mean, 99th percentile, max and share over 1 px, over every pixel where
    /// both see the same object, outside flagged pixels (--flags-from; the report says whose), and
    /// outside the fold band: pixels within 1.5 px of a fold of A's map (a caustic line in screen
    /// space, where two neighbouring triangles of the map face opposite ways), where one sample
    /// per pixel cannot place the images. Then the mean FLIP of the tone-mapped beauty and the
    /// share of pixels whose seen object differs. Typical use: A = a --method raytrace render,
    /// B = the same frame by a faster method. Needs frames with the object layer. Exit 2 for a
    /// missing or unreadable file or frames of different sizes.
    Compare(snell::tools::cli::CompareArgs),
    /// Write a frame's world-space geometry (water membrane, every object, posed characters) as
    /// OBJ (+ MTL + PNG textures) or PLY, and its camera as camera.json.
    ///
    /// OBJ: DIR/<scene>.<frame>.obj with one object per scene object (the membrane is `water`),
    /// texture coordinates (OBJ convention, bottom-left origin) and normals. camera.json: eye,
    /// target, up, vertical field of view in degrees, image size, near/far and the view and clip
    /// matrices. PLY (--format ply): DIR/<scene>.<frame>.<k>_<object>.ply, one ASCII file per
    /// object, in the same order. Every file is written atomically. Load the OBJ in Blender or any
    /// DCC tool, or render it elsewhere with the camera, to check snell's frames. Example:
    /// snell export scenes/pool.toml --frame 24 --out output/pool/export
    Export(snell::tools::cli::ExportArgs),
    /// Render a shot on a farm: write (and submit) the scheduler's jobs, or check their frames.
    ///
    /// snell talks to no scheduler itself: it writes plain job files and calls the scheduler's
    /// own commands (sbatch, openjd). `snell farm slurm --help` says what the three jobs do;
    /// the README's "On a render farm" section how to point them at shared storage.
    #[command(subcommand)]
    Farm(FarmCommand),
    /// Chart speed against accuracy: render one frame with every method and several membrane
    /// resolutions, time each and measure its position error against the ray-traced reference.
    ///
    /// Renders the frame with the linear method (equal-t) at 32x32, 64x64, 128x128, 256x256 and
    /// 512x512 membrane cells and the scene's own resolution, the exact method at 32x32, 64x64
    /// and the scene's own resolution,
    /// and the ray-traced reference (exact surface), all in this process on the same renderer.
    /// Seconds per frame: the CPU stages (water, refraction, virtual geometry; the tracer's own
    /// work for the reference) plus the render with readback, wall clock, median of up to 5
    /// repetitions (fewer once a configuration has taken 1.5 s), after one untimed warm-up render.
    /// Position error: for each pixel, how far in pixels the reference shows the same world
    /// point (sub-pixel, over pixels where both see the same object; see `snell compare`).
    ///
    /// Writes into DIR: speed_accuracy.csv (columns method,resolution,secs_per_frame,mean_px,
    /// p99_px; errors over every pixel where both see the same object), speed_accuracy_detail.csv
    /// (also maxima, pixel counts, the errors outside flagged pixels, the share of pixels that see
    /// another object), and the chart as speed_accuracy.svg and speed_accuracy.png (seconds per
    /// frame against mean error, log axes). Prints the table and, for the exact method at the
    /// scene's resolution, its error outside flagged pixels and its speed-up over the reference.
    ///
    /// The same measurement drives a scene's budget: with `[quality] max_error_px = E` in the
    /// scene, `snell render` tries membrane resolutions from the coarsest up (linear, then exact,
    /// at each) and renders with the first whose 99th-percentile position error, worst of the
    /// timeline's first, middle and last frames, is at most E pixels (the reference if none is);
    /// the choice is printed, written into report.jsonl and the EXR headers, and cached in
    /// DIR/quality_choice.json under the hash of the inputs.
    Chart {
        /// The scene file (TOML), e.g. scenes/pool.toml.
        scene: PathBuf,
        /// The frame to render (default: the middle of the scene's timeline).
        #[arg(long, value_name = "N")]
        frame: Option<u32>,
        /// Image size in pixels.
        #[arg(long, value_name = "WxH", default_value = "1280x720")]
        size: String,
        /// Output directory (default: output/<scene name>/chart/).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Measure every method against the ray-traced reference over time: render each frame with
    /// each method and with the reference, and compare them frame by frame.
    ///
    /// Per frame and method (at the scene's own membrane resolution), against the reference
    /// (--method raytrace) rendered in the same run: the screen-space position error both ways
    /// (see `snell compare`: no search window; reference -> method makes undrawn images count,
    /// method -> reference images drawn where the truth has none), as mean, p99, max and share
    /// over 1 px, over all same-object pixels, outside the method's flagged pixels and outside the
    /// reference's fold band; the fold band's and the flagged pixels' share of the water pixels;
    /// the share of pixels seeing another object; temporal stability: for each point of a static
    /// object the reference shows, |dx_method - dx_reference| between a frame and the one before
    /// (how differently the method moves it on screen than the truth does), mean and p99 (from
    /// the range's second frame); and the popping counts.
    ///
    /// Per frame, how hard it is by the truth: the share of the under-water vertices with two or
    /// more images by the independent image oracle (a Lipschitz-bounded scan plus Newton on
    /// Fermat's principle, sharing only the height field with the methods), over a systematic
    /// sample of --oracle-samples vertices, with its 95 % interval (stability_oracle.csv; the
    /// summary gives the lowest frame). --oracle-only measures just that, without rendering.
    ///
    /// Writes into DIR: stability.csv (one row per frame and method, every figure),
    /// stability_summary.txt (printed too: the worst frame per figure and method) and the chart
    /// over time as stability.svg and stability.png (one line per method). The reference costs
    /// seconds a frame at 1280x720 on a CPU: try a few frames at a small size first. Example:
    /// snell stability scenes/fox_wading.toml --frames 30-40 --size 640x360
    Stability {
        /// The scene file (TOML), e.g. scenes/fox_wading.toml.
        scene: PathBuf,
        /// Frames to measure, e.g. 30-40 or 36 (default: the whole timeline).
        #[arg(long, value_name = "A-B")]
        frames: Option<String>,
        /// Image size in pixels.
        #[arg(long, value_name = "WxH", default_value = "1280x720")]
        size: String,
        /// Methods to measure, comma-separated: equal-t, thesis-plane, exact, raytrace-membrane
        /// (raytrace, the reference itself, measures 0).
        #[arg(long, value_name = "LIST", default_value = "equal-t,exact")]
        methods: String,
        /// Output directory (default: output/<scene name>/stability/).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Under-water vertices per frame the image oracle measures, a systematic sample (every
        /// k-th); 0 measures all of them (seconds to minutes a frame in a wake).
        #[arg(long, value_name = "N", default_value_t = snell::stability::oracle_share::DEFAULT_SAMPLES)]
        oracle_samples: usize,
        /// Only the oracle's multi-image share per frame: no renders (no GPU needed), writes
        /// stability_oracle.csv and the summary.
        #[arg(long)]
        oracle_only: bool,
    },
}

fn main() -> ExitCode {
    // wgpu probes EGL before falling back to the surfaceless platform and logs that probe as an
    // error; it is harmless (ENVIRONMENT.md), so it is hidden unless RUST_LOG asks for it.
    env_logger::Builder::from_env(
        env_logger::Env::default().default_filter_or("error,wgpu_hal::gles::egl=off"),
    )
    .init();
    quiet_vulkan_runtime_dir();
    snell::panics::install_hook();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // --help and --version print to stdout, usage errors to stderr (exit 2), each through
        // the console so a closed pipe or a full disk is no panic.
        Err(error) if error.use_stderr() => {
            snell::err!("{}", error.render());
            return ExitCode::from(error.exit_code().clamp(0, 255) as u8);
        }
        Err(error) => {
            out!("{}", error.render());
            return finish(0, true);
        }
    };
    // Whether the command's product is what it prints (then a failed stdout fails it).
    let prints_its_product = !matches!(
        cli.command,
        Command::Render { .. } | Command::Preview { .. } | Command::Chart { .. }
    );
    let code = match snell::panics::catch(|| run(cli)) {
        Ok(code) => code,
        Err(message) => {
            let error = SnellError::Internal {
                frame: None,
                message,
            };
            errln!("error: {error}");
            1
        }
    };
    finish(code, prints_its_product)
}

/// The exit code once stdout's fate is known: a command whose output could not be written
/// (a closed pipe, a full disk) did not do its work and exits 1, quietly for a closed pipe; a
/// render whose frames are written keeps its code.
fn finish(code: u8, prints_its_product: bool) -> ExitCode {
    match snell::console::stdout_failure() {
        Some(kind) if prints_its_product && code == 0 => {
            if kind != std::io::ErrorKind::BrokenPipe {
                errln!("error: cannot write the output to stdout: {kind}");
            }
            ExitCode::from(1)
        }
        _ => ExitCode::from(code),
    }
}

fn run(cli: Cli) -> u8 {
    let result = match cli.command {
        Command::Diff(args) => return snell::check::cli::run_diff(&args),
        Command::Check(args) => return snell::check::cli::run_check(&args),
        Command::Accuracy(args) => return snell::accuracy::cli::run(&args),
        Command::Locate(args) => return snell::tools::cli::run_locate(&args),
        Command::Compare(args) => return snell::tools::cli::run_compare(&args),
        Command::Export(args) => return snell::tools::cli::run_export(&args),
        Command::Farm(FarmCommand::Slurm(args)) => return snell::farm::cli::run_slurm(&args),
        Command::Farm(FarmCommand::Check(args)) => return snell::farm::cli::run_check(&args),
        Command::Farm(FarmCommand::Openjd(args)) => return snell::farm::cli::run_openjd(&args),
        Command::Farm(FarmCommand::Simulate(args)) => return snell::farm::cli::run_simulate(&args),
        Command::Render {
            scene,
            frames,
            out,
            size,
            png,
            method,
            subdivision_px,
            resume,
            log_json,
            strip_rows,
            exr,
        } => render(
            &scene,
            frames.as_deref(),
            out,
            &size,
            png,
            (method.as_deref(), subdivision_px),
            (resume, log_json, strip_rows),
            &exr,
        ),
        Command::Chart {
            scene,
            frame,
            size,
            out,
        } => chart(&scene, frame, &size, out),
        Command::Stability {
            scene,
            frames,
            size,
            methods,
            out,
            oracle_samples,
            oracle_only,
        } => stability(
            &scene,
            frames.as_deref(),
            &size,
            &methods,
            out,
            (oracle_samples, oracle_only),
        ),
        Command::Preview {
            scene,
            frames_dir,
            port,
            size,
            out,
        } => match scene {
            Some(scene) => preview(&scene, port, &size, out),
            None => preview_frames(frames_dir, port),
        },
        Command::Info { scene } => info(&scene),
        Command::Bench {
            json,
            written_only: true,
            scene,
            ..
        } => written_bench(json, &scene),
        Command::Bench {
            json,
            written_only: false,
            scene,
            characters_scene,
            skinning_model,
            frames,
            wake_scene,
            wake_frames,
        } => bench(
            json,
            &scene,
            &characters_scene,
            &skinning_model,
            frames,
            (&wake_scene, &wake_frames),
        ),
    };
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

/// Mesa's Vulkan driver prints an error on every start when XDG_RUNTIME_DIR is unset (as on CI and
/// in containers). Give it a private directory instead, as a desktop session would.
fn quiet_vulkan_runtime_dir() {
    let usable = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|dir| Path::new(&dir).is_dir());
    if usable {
        return;
    }
    let dir = std::env::temp_dir().join("snell-xdg-runtime");
    if std::fs::create_dir_all(&dir).is_ok() {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
        // Single-threaded here: nothing else reads the environment yet.
        std::env::set_var("XDG_RUNTIME_DIR", &dir);
    }
}

// The command's arguments, passed on as they were parsed.
#[allow(clippy::too_many_arguments)]
fn render(
    scene_path: &Path,
    frames: Option<&str>,
    out: Option<PathBuf>,
    size: &str,
    png: bool,
    (method_arg, subdivision_px): (Option<&str>, f32),
    (resume, log_json, strip_rows): (bool, bool, Option<u32>),
    exr: &snell::output::exr::cli::ExrArgs,
) -> Result<(), SnellError> {
    let (width, height) = frame::parse_size(size)?;
    let method = match method_arg {
        Some(text) => {
            Method::parse(text).map_err(|e| SnellError::Argument(format!("--method: {e}")))?
        }
        None => Method::default(),
    };
    if !(subdivision_px.is_finite() && subdivision_px > 0.0) {
        return Err(SnellError::Argument(format!(
            "--subdivision-px {subdivision_px}: expected a number of pixels > 0, e.g. --subdivision-px 0.25"
        )));
    }
    let stamp = exr.stamp()?;
    let mut job = RenderJob::prepare(scene_path)?;
    job.method = method;
    job.subdivision.tolerance_px = subdivision_px;
    job.stamp = stamp;
    job.write = exr.write_options();
    if strip_rows == Some(0) {
        return Err(SnellError::Argument(
            "--strip-rows 0: a strip needs rows; give a multiple of 32, e.g. --strip-rows 64"
                .into(),
        ));
    }
    job.strip_rows = strip_rows;
    let frame_list: Vec<u32> = match frames {
        Some(text) => frame::parse_frame_list(text, job.timeline())?,
        None => FrameRange::whole(job.timeline()).frames().collect(),
    };
    // `--out` names a folder, or a file pattern whose folder holds the report and checkpoints.
    let out_arg = out.unwrap_or_else(|| PathBuf::from("output").join(job.scene_name()));
    let output = match snell::output::pattern::OutputPattern::parse(&out_arg)
        .map_err(SnellError::Argument)?
    {
        Some(pattern) => pattern,
        None => snell::output::pattern::OutputPattern::for_scene(&out_arg, job.scene_name()),
    };
    let out_dir = output.dir().to_path_buf();
    if let Some(max_error_px) = job.scene.quality.max_error_px {
        if method_arg.is_some() {
            errln!(
                "note: --method {} given: the scene's max_error_px = {max_error_px} is not applied",
                method.name()
            );
        } else {
            // Checked before measuring, so an unusable output directory fails before any work.
            snell::output::ensure_output_dir(&out_dir)?;
            snell::output::check_writable(&out_dir)?;
            if let Some(choice) =
                snell::chart::budget::apply_budget(&mut job, width, height, &out_dir, true)?
            {
                outln!("{}", choice.describe());
            }
        }
    }
    // The resume command names a method only when this one was given one: otherwise the resumed
    // render applies the same budget (read from the cache) and renders what this one did.
    let stated_method = method_arg.map(|_| job.method);
    let mut resume_command = resume_command_line(
        scene_path,
        frames,
        &out_arg,
        width,
        height,
        png,
        stated_method,
    );
    if job.method == Method::Exact
        && subdivision_px != snell::refraction::subdivision::DEFAULT_TOLERANCE_PX
    {
        resume_command.push_str(&format!(" --subdivision-px {subdivision_px}"));
    }
    if log_json {
        resume_command.push_str(" --log-json");
    }
    for word in exr.command_words() {
        resume_command.push(' ');
        resume_command.push_str(&snell::farm::shell_word(&word));
    }
    let stop = match snell::interrupt::install(resume_command.clone()) {
        Ok(flag) => Some(flag),
        Err(error) => {
            errln!("warning: cannot handle Ctrl-C ({error}): it will stop the render at once");
            None
        }
    };
    let outcome = job.render_sequence(&frame::resume::SequenceOptions {
        frames: &frame_list,
        width,
        height,
        output: &output,
        write_png: png,
        progress: true,
        log: if log_json {
            frame::resume::FrameLog::Json
        } else if std::io::IsTerminal::is_terminal(&std::io::stdout()) {
            frame::resume::FrameLog::Quiet
        } else {
            frame::resume::FrameLog::Text
        },
        resume,
        stop,
    })?;
    if outcome.interrupted {
        let done = outcome.done();
        errln!(
            "interrupted: {} of {} frame(s) done in {} ({}); not rendered: {}",
            done.len(),
            frame_list.len(),
            out_dir.display(),
            frame::resume::frame_list(&done),
            frame::resume::frame_list(&outcome.remaining)
        );
        errln!("to finish: {resume_command}");
        // Every file is closed and renamed into place: nothing is lost by exiting here.
        std::process::exit(snell::interrupt::exit_code().unwrap_or(130).into());
    }
    if outcome.rendered.is_empty() {
        errln!(
            "nothing to render: the {} frame(s) of {} at {width}x{height} in {} are complete",
            outcome.skipped.len(),
            job.scene_name(),
            out_dir.display()
        );
    } else {
        errln!(
            "rendered {} frame(s) of {} at {width}x{height} into {} ({:.2} s per frame){}",
            outcome.rendered.len(),
            job.scene_name(),
            out_dir.display(),
            outcome.secs_per_frame,
            if outcome.skipped.is_empty() {
                String::new()
            } else {
                format!("; kept {} complete frame(s)", outcome.skipped.len())
            }
        );
    }
    if let Some(simulation) = &job.dynamics.simulation {
        // What the checkpoints saved: on a farm, chunks after `snell farm simulate` step none.
        errln!(
            "ripples: stepped {} frame(s) of the simulation; every other state was read from the checkpoints in {}",
            simulation.frames_stepped(),
            simulation
                .store()
                .map_or_else(|| out_dir.display().to_string(), |s| s.dir().display().to_string())
        );
    }
    Ok(())
}

fn preview(
    scene_path: &Path,
    port: u16,
    size: &str,
    out: Option<PathBuf>,
) -> Result<(), SnellError> {
    let (width, height) = frame::parse_size(size)?;
    // A scene that is not a regular file of a sensible size (a device such as /dev/zero, a FIFO, a
    // folder) is refused here with exit 2, as `snell render` refuses it; a regular scene with
    // errors is served, so that fixing it in an editor reloads the page.
    snell::files::check_regular(scene_path, snell::files::MAX_SCENE_BYTES)
        .map_err(snell::scene::SceneError::File)?;
    let mut options = snell::preview::PreviewOptions::new(scene_path);
    options.port = port;
    options.width = width;
    options.height = height;
    options.out_dir = out;
    serve_preview(options, &scene_path.display().to_string())
}

/// `snell preview --frames-dir DIR...`: plays back rendered frames.
fn preview_frames(dirs: Vec<PathBuf>, port: u16) -> Result<(), SnellError> {
    let mut options = snell::preview::PreviewOptions::new(Path::new(""));
    options.port = port;
    let shown: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    options.frames_dirs = dirs;
    serve_preview(options, &shown.join(", "))
}

/// Serves `options` until SIGINT or SIGTERM, printing the address first.
fn serve_preview(options: snell::preview::PreviewOptions, what: &str) -> Result<(), SnellError> {
    let signals = snell::interrupt::catch_stop_signals()
        .map_err(|error| SnellError::Argument(format!("cannot handle Ctrl-C: {error}")))?;
    let server = snell::preview::PreviewServer::start(options)?;
    // The first line on stdout is the address (tests and scripts read it); flushed at once.
    outln!("snell preview: {what} on {}", server.url());
    use std::io::Write;
    let _ = std::io::stdout().flush();
    errln!(
        "open {} in a browser; Ctrl-C stops the preview",
        server.url()
    );
    // Serves until SIGINT or SIGTERM; the process exits from there.
    snell::interrupt::exit_at_first_signal(signals, "the preview")
}

/// The `snell render ... --resume` command line that finishes this render, quoted for a POSIX
/// shell.
fn resume_command_line(
    scene_path: &Path,
    frames: Option<&str>,
    out_dir: &Path,
    width: u32,
    height: u32,
    png: bool,
    method: Option<Method>,
) -> String {
    let program = std::env::args().next().unwrap_or_else(|| "snell".into());
    let mut words = vec![program, "render".into(), scene_path.display().to_string()];
    if let Some(frames) = frames {
        words.extend(["--frames".into(), frames.to_string()]);
    }
    words.extend([
        "--out".into(),
        out_dir.display().to_string(),
        "--size".into(),
        format!("{width}x{height}"),
    ]);
    if png {
        words.push("--png".into());
    }
    if let Some(method) = method {
        words.extend(["--method".into(), method.name().to_string()]);
    }
    words.push("--resume".into());
    words
        .iter()
        .map(|word| snell::farm::shell_word(word))
        .collect::<Vec<_>>()
        .join(" ")
}

fn chart(
    scene_path: &Path,
    frame: Option<u32>,
    size: &str,
    out: Option<PathBuf>,
) -> Result<(), SnellError> {
    let (width, height) = frame::parse_size(size)?;
    let mut job = RenderJob::prepare(scene_path)?;
    let timeline = *job.timeline();
    let frame =
        frame.unwrap_or(timeline.first_frame + (timeline.last_frame - timeline.first_frame) / 2);
    let out_dir =
        out.unwrap_or_else(|| PathBuf::from("output").join(job.scene_name()).join("chart"));
    let scene_resolution = job.scene.water.resolution;
    let outcome = snell::chart::run_chart(
        &mut job,
        &snell::chart::ChartOptions {
            frame,
            width,
            height,
            out_dir,
            progress: true,
        },
    )?;
    out!("{}", outcome.summary(scene_resolution));
    Ok(())
}

fn stability(
    scene_path: &Path,
    frames: Option<&str>,
    size: &str,
    methods: &str,
    out: Option<PathBuf>,
    (oracle_samples, oracle_only): (usize, bool),
) -> Result<(), SnellError> {
    let (width, height) = frame::parse_size(size)?;
    let methods = snell::stability::parse_methods(methods)?;
    let mut job = RenderJob::prepare(scene_path)?;
    let timeline = *job.timeline();
    let frames = match frames {
        Some(text) => frame::FrameRange::parse(text, &timeline)?,
        None => frame::FrameRange::whole(&timeline),
    };
    let out_dir = out.unwrap_or_else(|| {
        PathBuf::from("output")
            .join(job.scene_name())
            .join("stability")
    });
    let outcome = snell::stability::run_stability(
        &mut job,
        &snell::stability::StabilityOptions {
            frames,
            width,
            height,
            methods: methods.clone(),
            out_dir,
            progress: true,
            oracle_samples,
            oracle_only,
        },
    )?;
    if oracle_only {
        out!("{}", outcome.summary_text(&[]));
        outln!(
            "wrote {} and {}",
            outcome.oracle_csv.display(),
            outcome.summary.display()
        );
        return Ok(());
    }
    out!("{}", outcome.summary_text(&methods));
    outln!(
        "wrote {}, {}, {}, {} and {}",
        outcome.oracle_csv.display(),
        outcome.csv.display(),
        outcome.summary.display(),
        outcome.svg.display(),
        outcome.png.display()
    );
    Ok(())
}

fn info(scene_path: &Path) -> Result<(), SnellError> {
    let job = RenderJob::prepare(scene_path)?;
    out!("{}", job.describe());
    Ok(())
}

/// Frames whose scrub latency `snell bench` measures (spread over the timeline).
const SCRUB_FRAMES: usize = 8;

/// `snell bench --written-only`: the written-frame figures alone.
fn written_bench(json: bool, scene_path: &Path) -> Result<(), SnellError> {
    let figures = snell::frame::bench::written_times(
        scene_path,
        snell::frame::bench::WRITTEN_FRAMES,
        snell::frame::bench::WRITTEN_PASSES,
    )?;
    if json {
        let value = serde_json::json!({ "written": figures });
        outln!(
            "{}",
            serde_json::to_string_pretty(&value).expect("figures serialise")
        );
    } else {
        out!("{}", figures.to_text());
    }
    Ok(())
}

fn bench(
    json: bool,
    scene_path: &Path,
    characters_scene_path: &Path,
    skinning_model: &Path,
    frames: u32,
    (wake_scene_path, wake_frames): (&Path, &str),
) -> Result<(), SnellError> {
    let figures = snell::frame::bench::run(
        scene_path,
        characters_scene_path,
        skinning_model,
        frames,
        wake_scene_path,
        wake_frames,
    )?;
    let scrub = snell::preview::bench::scrub_latency(scene_path, SCRUB_FRAMES)?;
    let vessels = snell::vessel::bench::run(snell::vessel::bench::VERTICES_DEFAULT, 5);
    if json {
        let mut value = serde_json::to_value(&figures).expect("figures serialise");
        value["preview"] = serde_json::to_value(&scrub).expect("figures serialise");
        value["vessels"] = serde_json::to_value(vessels).expect("figures serialise");
        outln!(
            "{}",
            serde_json::to_string_pretty(&value).expect("figures serialise")
        );
    } else {
        out!(
            "{}{}{}",
            figures.to_text(),
            scrub.to_text(),
            vessels.to_text()
        );
    }
    Ok(())
}
