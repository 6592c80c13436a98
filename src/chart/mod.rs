//! Speed against accuracy (`snell chart`, and a scene's `max_error_px`). Receives a loaded
//! [`RenderJob`], a frame and an image size; renders that frame with each method and membrane
//! resolution ([`Configuration`]), times each render and measures its screen-space position error
//! against the ray-traced reference rendered in the same run; returns the [`Measurement`]s, which
//! [`write_chart`] writes as `speed_accuracy.csv` and draws with [`plot`]. [`budget`] uses the same
//! measurements to pick the cheapest configuration that meets a scene's `max_error_px`.
//!
//! What is timed, per configuration: the frame's CPU stages ([`RenderJob::refract`]: skinning,
//! ripples, water membrane, refraction and virtual geometry — or, for the reference, whatever its
//! method does there) plus its render ([`RenderJob::render_refracted`]: the GPU passes with readback,
//! or the CPU tracer), wall clock, in this process. Not timed: loading the scene, the previous
//! frame's tracking for the popping test (a sequence has it from the frame before), writing files.

pub mod budget;
pub mod plot;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::draw::RenderedFrame;
use crate::frame::{progress_bar, Method, RenderJob, SnellError};
use crate::gpu::Renderer;
use crate::output::position_error::{compare_positions, CompareOptions, PositionComparison, Side};
use crate::refraction::flags::FlagCounts;
use crate::stats::median;

/// Membrane resolutions the linear method is charted at (cells along x and along z).
pub const LINEAR_RESOLUTIONS: [u32; 5] = [32, 64, 128, 256, 512];

/// The method everything is measured against: the ray tracer on the exact (analytic) surface.
pub const REFERENCE_METHOD: Method = Method::Raytrace;

/// Repetitions of a configuration: at least one; more while the configuration's renders so far
/// took under [`REPEAT_BUDGET_SECS`], up to [`MAX_REPETITIONS`]. The median is reported, so the fast
/// configurations (tens of milliseconds, where a busy machine's noise matters) get five samples and
/// the reference (seconds) gets one or two.
pub const MAX_REPETITIONS: usize = 5;
pub const REPEAT_BUDGET_SECS: f64 = 1.5;

/// A method at a membrane resolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Configuration {
    pub method: Method,
    /// Membrane cells along x and z.
    pub resolution: [u32; 2],
}

impl Configuration {
    pub fn is_reference(&self) -> bool {
        self.method == REFERENCE_METHOD
    }

    /// The CSV's `resolution` column: `64x64`, or `exact-surface` for the reference, which
    /// intersects the analytic surface and uses no membrane.
    pub fn resolution_label(&self) -> String {
        if self.is_reference() {
            "exact-surface".to_string()
        } else {
            format!("{}x{}", self.resolution[0], self.resolution[1])
        }
    }

    /// `equal-t 64x64`, for messages.
    pub fn describe(&self) -> String {
        if self.is_reference() {
            format!("{} (reference, exact surface)", self.method.name())
        } else {
            format!(
                "{} at {} cells",
                self.method.name(),
                self.resolution_label()
            )
        }
    }
}

/// What the chart renders for a scene whose own membrane has `scene_resolution` cells: the linear
/// method at [`LINEAR_RESOLUTIONS`] and at the scene's resolution, the exact method at the two
/// coarsest linear ones (exact vertices move less with the membrane, so coarse membranes are where
/// it could pay off) and at the scene's resolution, then the reference. Each method's resolutions
/// go from the fewest cells up. The reference comes first in the run (everything is measured
/// against it), last in the file.
pub fn chart_configurations(scene_resolution: [u32; 2]) -> Vec<Configuration> {
    let square = |cells: u32| [cells, cells];
    let by_cells = |resolutions: &mut Vec<[u32; 2]>| {
        resolutions.sort_by_key(|r| (r[0] as u64 * r[1] as u64, r[0]));
        resolutions.dedup();
    };
    let mut linear: Vec<[u32; 2]> = LINEAR_RESOLUTIONS.iter().map(|&n| square(n)).collect();
    linear.push(scene_resolution);
    by_cells(&mut linear);
    let mut exact: Vec<[u32; 2]> = vec![square(32), square(64), scene_resolution];
    by_cells(&mut exact);
    let mut configurations: Vec<Configuration> = linear
        .into_iter()
        .map(|resolution| Configuration {
            method: Method::EqualT,
            resolution,
        })
        .collect();
    configurations.extend(exact.into_iter().map(|resolution| Configuration {
        method: Method::Exact,
        resolution,
    }));
    configurations.push(Configuration {
        method: REFERENCE_METHOD,
        resolution: scene_resolution,
    });
    configurations
}

/// One configuration measured.
#[derive(Clone, Debug)]
pub struct Measurement {
    pub configuration: Configuration,
    /// Median over the repetitions.
    pub secs_per_frame: f64,
    /// Median seconds of the render stage alone ([`RenderJob::render_refracted`]: the GPU passes
    /// with readback, or the tracer for the reference).
    pub render_secs: f64,
    pub repetitions: usize,
    /// Against the reference: over every pixel where both see the same object, and over those of
    /// them that the configuration did not flag.
    pub error: PositionComparison,
}

/// Renders frames of one job under different configurations on one renderer, timing them.
pub struct Measurer<'a> {
    job: &'a mut RenderJob,
    renderer: Renderer,
    pub width: u32,
    pub height: u32,
    /// The job's own method and resolution, restored when the measurer is dropped.
    original: Configuration,
    /// The job's own [`RenderJob::frames_held`], restored when the measurer is dropped.
    original_frames_held: u32,
    original_reference_grid: u32,
}

impl<'a> Measurer<'a> {
    /// A measurer of `job` at `width` x `height` for a command that keeps `frames_held` whole
    /// frames at once (the reference and what is compared with it), so that each frame's memory
    /// estimate counts them ([`RenderJob::frames_held`]).
    pub fn new(
        job: &'a mut RenderJob,
        width: u32,
        height: u32,
        frames_held: u32,
    ) -> Result<Self, SnellError> {
        let original_frames_held = std::mem::replace(&mut job.frames_held, frames_held);
        // The reference's positions are its pixel centres' whatever its grid: only the centre
        // rays are traced for them (the beauty stays unfiltered; nothing here measures it).
        let original_reference_grid = std::mem::replace(&mut job.scene.antialias.reference_grid, 1);
        let mut renderer = Renderer::new()?;
        job.upload_textures(&mut renderer)?;
        let original = Configuration {
            method: job.method,
            resolution: job.scene.water.resolution,
        };
        Ok(Measurer {
            job,
            renderer,
            width,
            height,
            original,
            original_frames_held,
            original_reference_grid,
        })
    }

    pub fn adapter(&self) -> String {
        self.renderer.adapter_summary()
    }

    fn configure(&mut self, configuration: Configuration) {
        self.job.method = configuration.method;
        self.job.scene.water.resolution = configuration.resolution;
    }

    /// Renders `frame` with `configuration`, repeated as [`MAX_REPETITIONS`] and [`REPEAT_BUDGET_SECS`] say; returns the last
    /// render and the seconds of each.
    pub fn render(
        &mut self,
        configuration: Configuration,
        frame: u32,
    ) -> Result<(RenderedFrame, Timings), SnellError> {
        self.render_repeated(configuration, frame, MAX_REPETITIONS)
    }

    /// One render of `frame` with `configuration`, untimed (for measuring errors only).
    pub fn render_once(
        &mut self,
        configuration: Configuration,
        frame: u32,
    ) -> Result<RenderedFrame, SnellError> {
        Ok(self.render_repeated(configuration, frame, 1)?.0)
    }

    /// One untimed render of `frame` with `configuration`, with the frame's flag counts (popping
    /// judged against frame - 1, recomputed, as a frame rendered alone is).
    pub fn render_counted(
        &mut self,
        configuration: Configuration,
        frame: u32,
    ) -> Result<(RenderedFrame, FlagCounts), SnellError> {
        let (rendered, timings) = self.render_repeated(configuration, frame, 1)?;
        Ok((rendered, timings.counts))
    }

    /// The job rendered.
    pub fn job(&self) -> &RenderJob {
        self.job
    }

    /// One untimed GPU render of `frame`: the first render of a renderer compiles pipelines and
    /// allocates targets, which is not a frame's cost.
    pub fn warm_up(&mut self, frame: u32) -> Result<(), SnellError> {
        let configuration = Configuration {
            method: Method::EqualT,
            resolution: self.original.resolution,
        };
        self.render_once(configuration, frame)?;
        Ok(())
    }

    fn render_repeated(
        &mut self,
        configuration: Configuration,
        frame: u32,
        max_repetitions: usize,
    ) -> Result<(RenderedFrame, Timings), SnellError> {
        self.configure(configuration);
        let (width, height) = (self.width, self.height);
        let previous = self.job.previous_tracking(frame, width, height)?;
        let mut timings = Timings::default();
        loop {
            let clock = Instant::now();
            let mut refracted = self.job.refract(frame, width, height, previous.as_ref())?;
            let rendered =
                self.job
                    .render_refracted(&mut self.renderer, &mut refracted, width, height)?;
            timings.total_secs.push(clock.elapsed().as_secs_f64());
            timings
                .render_secs
                .push(refracted.stage_secs.get("render").copied().unwrap_or(0.0));
            timings.counts = refracted.counts;
            let spent: f64 = timings.total_secs.iter().sum();
            if timings.total_secs.len() >= max_repetitions || spent >= REPEAT_BUDGET_SECS {
                return Ok((rendered, timings));
            }
        }
    }

    /// Renders `configuration` at `frame` and measures it against `reference` (a render of the same
    /// frame by [`REFERENCE_METHOD`]).
    pub fn measure(
        &mut self,
        configuration: Configuration,
        frame: u32,
        reference: &RenderedFrame,
    ) -> Result<(Measurement, RenderedFrame), SnellError> {
        let (rendered, timings) = self.render(configuration, frame)?;
        let error = position_error_against(&rendered, reference, frame, self.job)?;
        Ok((timings.measurement(configuration, error), rendered))
    }
}

impl Drop for Measurer<'_> {
    fn drop(&mut self) {
        let original = self.original;
        self.configure(original);
        self.job.frames_held = self.original_frames_held;
        self.job.scene.antialias.reference_grid = self.original_reference_grid;
    }
}

/// Seconds of each repetition of a configuration: the whole frame, and its render stage.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    pub total_secs: Vec<f64>,
    pub render_secs: Vec<f64>,
    /// The last render's flag counts.
    pub counts: FlagCounts,
}

impl Timings {
    fn measurement(
        mut self,
        configuration: Configuration,
        error: PositionComparison,
    ) -> Measurement {
        Measurement {
            configuration,
            secs_per_frame: median(&mut self.total_secs),
            render_secs: median(&mut self.render_secs),
            repetitions: self.total_secs.len(),
            error,
        }
    }
}

/// The position error of `test` against `reference`, both ways (A the reference, B the test,
/// flags taken from the test, the fold band from the reference).
pub(crate) fn position_error_against(
    test: &RenderedFrame,
    reference: &RenderedFrame,
    frame: u32,
    job: &RenderJob,
) -> Result<PositionComparison, SnellError> {
    let eye = job.camera_at(frame).eye;
    let options = CompareOptions {
        flags_from: Side::B,
        eyes: Some((eye, eye)),
    };
    compare_positions(reference, test, &options).map_err(|error| SnellError::Frame {
        scene: job.scene.path.clone(),
        frame,
        problem: format!("cannot measure the position error against the reference: {error}"),
    })
}

/// What `snell chart` does.
pub struct ChartOptions {
    pub frame: u32,
    pub width: u32,
    pub height: u32,
    pub out_dir: PathBuf,
    pub progress: bool,
}

/// What `snell chart` produced.
pub struct ChartOutcome {
    pub scene: String,
    pub frame: u32,
    pub size: (u32, u32),
    pub adapter: String,
    /// In [`chart_configurations`] order (the reference last).
    pub measurements: Vec<Measurement>,
    pub csv: PathBuf,
    pub detail_csv: PathBuf,
    pub svg: PathBuf,
    pub png: PathBuf,
}

/// The CSV's header: exactly these columns.
pub const CSV_HEADER: &str = "method,resolution,secs_per_frame,mean_px,p99_px";
/// The detailed CSV's header: every figure of every configuration.
pub const DETAIL_CSV_HEADER: &str = "method,resolution,secs_per_frame,repetitions,\
mean_px,p99_px,max_px,counted,mean_px_unflagged,p99_px_unflagged,max_px_unflagged,counted_unflagged,\
mean_px_outside_fold_band,p99_px_outside_fold_band,max_px_outside_fold_band,counted_outside_fold_band,\
object_mismatch_fraction,render_secs";

pub const CSV_FILE_NAME: &str = "speed_accuracy.csv";
pub const DETAIL_CSV_FILE_NAME: &str = "speed_accuracy_detail.csv";
pub const SVG_FILE_NAME: &str = "speed_accuracy.svg";
pub const PNG_FILE_NAME: &str = "speed_accuracy.png";

/// Renders and measures every [`chart_configurations`] entry at `options.frame`, then writes the
/// CSVs and the chart into `options.out_dir`.
pub fn run_chart(job: &mut RenderJob, options: &ChartOptions) -> Result<ChartOutcome, SnellError> {
    let timeline = *job.timeline();
    if !(timeline.first_frame..=timeline.last_frame).contains(&options.frame) {
        return Err(SnellError::Argument(format!(
            "--frame {}: the scene's timeline runs from frame {} to {}; choose a frame inside it",
            options.frame, timeline.first_frame, timeline.last_frame
        )));
    }
    crate::output::ensure_output_dir(&options.out_dir)?;
    crate::output::check_writable(&options.out_dir)?;
    let configurations = chart_configurations(job.scene.water.resolution);
    let scene = job.scene_name().to_string();
    // The reference, the configuration measured against it and the frame in the making.
    let mut measurer = Measurer::new(job, options.width, options.height, 3)?;
    let adapter = measurer.adapter();
    let bar = progress_bar(configurations.len() as u64, options.progress);
    bar.set_message("warm-up render");
    measurer.warm_up(options.frame)?;

    let reference_configuration = *configurations
        .iter()
        .find(|c| c.is_reference())
        .expect("the configurations include the reference");
    bar.set_message(reference_configuration.describe());
    let (reference, reference_timings) = measurer.render(reference_configuration, options.frame)?;
    bar.inc(1);
    let mut measurements = Vec::new();
    for &configuration in &configurations {
        let measurement = if configuration.is_reference() {
            // Measured against itself like every other row, so its zero is computed, not assumed.
            let error =
                position_error_against(&reference, &reference, options.frame, measurer.job)?;
            reference_timings.clone().measurement(configuration, error)
        } else {
            bar.set_message(configuration.describe());
            let (measurement, _) = measurer.measure(configuration, options.frame, &reference)?;
            bar.inc(1);
            measurement
        };
        measurements.push(measurement);
    }
    bar.finish_and_clear();
    drop(measurer);

    let outcome = ChartOutcome {
        scene,
        frame: options.frame,
        size: (options.width, options.height),
        adapter,
        measurements,
        csv: options.out_dir.join(CSV_FILE_NAME),
        detail_csv: options.out_dir.join(DETAIL_CSV_FILE_NAME),
        svg: options.out_dir.join(SVG_FILE_NAME),
        png: options.out_dir.join(PNG_FILE_NAME),
    };
    write_chart(&outcome)?;
    Ok(outcome)
}

/// Shortest decimal that round-trips (the CSV keeps full precision).
fn number(value: f64) -> String {
    format!("{value}")
}

impl ChartOutcome {
    /// `speed_accuracy.csv`: one row per configuration, errors over every pixel where the
    /// configuration and the reference see the same object.
    pub fn csv_text(&self) -> String {
        let mut text = format!("{CSV_HEADER}\n");
        for m in &self.measurements {
            text.push_str(&format!(
                "{},{},{},{},{}\n",
                m.configuration.method.name(),
                m.configuration.resolution_label(),
                number(m.secs_per_frame),
                number(m.error.both.all.mean_px),
                number(m.error.both.all.p99_px),
            ));
        }
        text
    }

    /// `speed_accuracy_detail.csv`: also the maxima, the pixel counts, the figures outside
    /// flagged pixels and the share of pixels that see another object than the reference.
    pub fn detail_csv_text(&self) -> String {
        let mut text = format!("{DETAIL_CSV_HEADER}\n");
        for m in &self.measurements {
            let (all, unflagged, unfolded) = (
                &m.error.both.all,
                &m.error.both.outside_flagged,
                &m.error.both.outside_fold_band,
            );
            text.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
                m.configuration.method.name(),
                m.configuration.resolution_label(),
                number(m.secs_per_frame),
                m.repetitions,
                number(all.mean_px),
                number(all.p99_px),
                number(all.max_px),
                all.counted,
                number(unflagged.mean_px),
                number(unflagged.p99_px),
                number(unflagged.max_px),
                unflagged.counted,
                number(unfolded.mean_px),
                number(unfolded.p99_px),
                number(unfolded.max_px),
                unfolded.counted,
                number(m.error.object_mismatch_fraction),
                number(m.render_secs),
            ));
        }
        text
    }

    pub fn reference(&self) -> &Measurement {
        self.measurements
            .iter()
            .find(|m| m.configuration.is_reference())
            .expect("the reference is measured")
    }

    /// The exact method at the scene's own resolution, the row the targets are about.
    pub fn exact_at(&self, resolution: [u32; 2]) -> Option<&Measurement> {
        self.measurements.iter().find(|m| {
            m.configuration.method == Method::Exact && m.configuration.resolution == resolution
        })
    }

    /// The table printed on stdout, with the two figures for the exact method at the
    /// scene's resolution: its error outside flagged pixels and how much faster than the
    /// reference it is.
    pub fn summary(&self, scene_resolution: [u32; 2]) -> String {
        let mut text = format!(
            "speed vs accuracy of {} frame {} at {}x{} on {} (seconds: median of up to {MAX_REPETITIONS} \
             renders, CPU stages + render with readback; errors against the ray-traced reference, over \
             pixels where both see the same object)\n",
            self.scene, self.frame, self.size.0, self.size.1, self.adapter
        );
        text.push_str(&format!(
            "  {:<9} {:<14} {:>10} {:>9} {:>9} {:>9} {:>16} {:>9}\n",
            "method",
            "resolution",
            "s/frame",
            "mean px",
            "p99 px",
            "max px",
            "mean/p99 unflag",
            "mismatch"
        ));
        for m in &self.measurements {
            let (all, unflagged) = (&m.error.both.all, &m.error.both.outside_flagged);
            text.push_str(&format!(
                "  {:<9} {:<14} {:>10.4} {:>9.4} {:>9.4} {:>9.3} {:>7.4}/{:<8.4} {:>8.3}%\n",
                m.configuration.method.name(),
                m.configuration.resolution_label(),
                m.secs_per_frame,
                all.mean_px,
                all.p99_px,
                all.max_px,
                unflagged.mean_px,
                unflagged.p99_px,
                100.0 * m.error.object_mismatch_fraction
            ));
        }
        let reference = self.reference();
        match self.exact_at(scene_resolution) {
            Some(exact) => {
                let unflagged = &exact.error.both.outside_flagged;
                let ratio = reference.secs_per_frame / exact.secs_per_frame;
                let verdict = |met: bool| if met { "met" } else { "NOT met" };
                text.push_str(&format!(
                    "exact at the scene's {}x{} cells, outside flagged pixels: mean {:.4} px (target < 0.1: {}), \
                     p99 {:.4} px (target < 1: {}) over {} pixels\n",
                    scene_resolution[0],
                    scene_resolution[1],
                    unflagged.mean_px,
                    verdict(unflagged.mean_px < 0.1),
                    unflagged.p99_px,
                    verdict(unflagged.p99_px < 1.0),
                    unflagged.counted,
                ));
                text.push_str(&format!(
                    "exact is {ratio:.1}x faster than the reference ({:.4} s vs {:.4} s per frame; target >= 20x: {})\n",
                    exact.secs_per_frame,
                    reference.secs_per_frame,
                    verdict(ratio >= 20.0)
                ));
                text.push_str(&format!(
                    "  of exact's {:.4} s, the render stage (GPU passes with readback) takes {:.4} s: \
                     at most {:.1}x is possible on this adapter while that stays\n",
                    exact.secs_per_frame,
                    exact.render_secs,
                    reference.secs_per_frame / exact.render_secs.max(1e-9),
                ));
            }
            None => text.push_str("the exact method was not measured at the scene's resolution\n"),
        }
        text.push_str(&format!(
            "wrote {}, {}, {} and {}\n",
            self.csv.display(),
            self.detail_csv.display(),
            self.svg.display(),
            self.png.display()
        ));
        text
    }

    /// The points of the chart: every configuration but the reference, which is its line.
    pub fn chart_input(&self) -> plot::ChartInput {
        let reference = self.reference();
        plot::ChartInput {
            title: format!(
                "snell: speed vs accuracy, {} frame {} at {}x{}",
                self.scene, self.frame, self.size.0, self.size.1
            ),
            caption: format!(
                "seconds per frame: median of up to {MAX_REPETITIONS} renders, CPU stages + render with readback, on {}\n\
                 error: mean screen-space position error against the ray-traced reference, over pixels where both see the same object",
                short_adapter(&self.adapter)
            ),
            points: self
                .measurements
                .iter()
                .filter(|m| !m.configuration.is_reference())
                .map(|m| plot::ChartPoint {
                    series: m.configuration.method.name().to_string(),
                    label: m.configuration.resolution_label(),
                    secs_per_frame: m.secs_per_frame,
                    mean_px: m.error.both.all.mean_px,
                })
                .collect(),
            reference: Some((
                format!(
                    "ray-traced reference ({:.2} s; error 0 by definition)",
                    reference.secs_per_frame
                ),
                reference.secs_per_frame,
            )),
            error_target: Some(("0.1 px".to_string(), 0.1)),
        }
    }
}

/// The adapter's name without the driver details in parentheses (`llvmpipe (LLVM 15.0.6, 256
/// bits) (Vulkan, Cpu, ...)` -> `llvmpipe, Vulkan`), to fit a chart's caption.
pub(crate) fn short_adapter(adapter: &str) -> String {
    let name = adapter.split(" (").next().unwrap_or(adapter).trim();
    let backend = adapter
        .find(") (")
        .and_then(|at| adapter[at + 3..].split(',').next())
        .map(str::trim)
        .filter(|b| !b.is_empty());
    match backend {
        Some(backend) => format!("{name}, {backend}"),
        None => name.to_string(),
    }
}

/// Writes the CSVs, the SVG and the PNG of `outcome`, each atomically.
pub fn write_chart(outcome: &ChartOutcome) -> Result<(), SnellError> {
    write_text(&outcome.csv, &outcome.csv_text())?;
    write_text(&outcome.detail_csv, &outcome.detail_csv_text())?;
    let input = outcome.chart_input();
    let drawing_error = |path: &Path, cause: String| {
        SnellError::Output(crate::output::OutputError::Write {
            path: path.to_path_buf(),
            cause: format!("drawing the chart: {cause}"),
        })
    };
    let svg = plot::chart_svg(&input).map_err(|cause| drawing_error(&outcome.svg, cause))?;
    write_text(&outcome.svg, &svg)?;
    let image = plot::chart_image(&input).map_err(|cause| drawing_error(&outcome.png, cause))?;
    crate::output::save_png_atomic(&outcome.png, &image)?;
    Ok(())
}

pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), SnellError> {
    use std::io::Write;
    crate::output::write_atomically(path, |file| {
        file.write_all(text.as_bytes())
            .map_err(|error| error.to_string())
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adapter_names_are_shortened_for_captions() {
        assert_eq!(
            short_adapter("llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu, llvmpipe Mesa 22.3.6 (LLVM 15.0.6))"),
            "llvmpipe, Vulkan"
        );
        assert_eq!(short_adapter("some GPU"), "some GPU");
    }

    #[test]
    fn configurations_cover_every_method_and_resolution_once() {
        let configurations = chart_configurations([160, 80]);
        let linear: Vec<[u32; 2]> = configurations
            .iter()
            .filter(|c| c.method == Method::EqualT)
            .map(|c| c.resolution)
            .collect();
        assert_eq!(
            linear,
            [
                [32, 32],
                [64, 64],
                [160, 80],
                [128, 128],
                [256, 256],
                [512, 512]
            ]
        );
        assert!(configurations
            .iter()
            .any(|c| c.method == Method::Exact && c.resolution == [160, 80]));
        assert_eq!(
            configurations.iter().filter(|c| c.is_reference()).count(),
            1
        );
        assert_eq!(
            configurations.last().unwrap().resolution_label(),
            "exact-surface"
        );
        // A scene whose own membrane is one of the charted ones is not measured twice.
        let configurations = chart_configurations([64, 64]);
        assert_eq!(
            configurations
                .iter()
                .filter(|c| c.method == Method::EqualT)
                .count(),
            5
        );
        assert_eq!(
            configurations
                .iter()
                .filter(|c| c.method == Method::Exact)
                .count(),
            2
        );
    }
}
