//! `snell bench`: the speed figures the README quotes, from one run. Refraction search throughput
//! and speed-up over brute force (the refraction stage's own benchmark), and per-stage frame times
//! of a scene at 1280x720 (refraction + render with readback being the figure with a target).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use super::{RenderJob, SnellError};
use crate::gpu::Renderer;
use crate::stats::median;

#[derive(Debug, Serialize)]
pub struct BenchFigures {
    pub refraction: RefractionFigures,
    pub frame: FrameFigures,
    pub characters: CharacterFigures,
    pub reference: ReferenceFigures,
    pub exact: ExactFigures,
    pub wake: WakeFigures,
    pub written: WrittenFigures,
}

/// The whole `snell render` per frame, written and not, of the frame-time scene at 1280x720: the
/// figure with the targets of issue 14 point 4 (a written frame at most 1.3x an unwritten one with
/// `--layers comp`, 2.5x with `all`). Each pass renders the same frames three times, amortised
/// per frame: unwritten (renderer set up, textures uploaded, then refraction and render with
/// readback of each frame in sequence, nothing encoded), then [`RenderJob::render_sequence`] into
/// a temporary folder (the renderer set-up too, then what `snell render` does: checkpoints, EXR
/// encoding, compression, write, fsync and rename on the writer thread, the report row) with
/// `--layers comp` (half beauty) and with `all` (the default float32 beauty), default `zip`
/// compression. The three alternate pass by pass, so a busy machine slows them alike; each ratio is
/// the median of the per-pass ratios.
#[derive(Debug, Serialize)]
pub struct WrittenFigures {
    pub scene: String,
    pub size: [u32; 2],
    /// The frames rendered in each pass (inclusive), and the passes.
    pub frames: [u32; 2],
    pub passes: u32,
    /// Median wall-clock milliseconds per frame, amortised over a pass.
    pub unwritten_ms: f64,
    pub comp_ms: f64,
    pub all_ms: f64,
    /// Median over the passes of written / unwritten (targets: at most 1.3 and 2.5).
    pub comp_ratio: f64,
    pub all_ratio: f64,
    /// One frame's file size, MB (10^6 bytes), of each preset.
    pub comp_file_mb: f64,
    pub all_file_mb: f64,
    /// Median over the frames of the report's `write` stage (encode, compress, write, fsync,
    /// rename: the writer thread's time on the frame, waiting for strips excluded), ms.
    pub comp_write_stage_ms: f64,
    pub all_write_stage_ms: f64,
    /// Median process CPU milliseconds (user + system, every thread: the CPU drivers' too) per
    /// frame, and the median of the per-pass ratios written / unwritten: the cost in CPU, which a
    /// machine shared with other work (where wall clock measures the others' load as well) still
    /// measures. On an idle machine of N cores a frame needs at least CPU / N of wall clock.
    pub unwritten_cpu_ms: f64,
    pub comp_cpu_ms: f64,
    pub all_cpu_ms: f64,
    pub comp_cpu_ratio: f64,
    pub all_cpu_ratio: f64,
}

impl WrittenFigures {
    pub fn to_text(&self) -> String {
        format!(
            "whole `snell render` of {} frames {}-{} at {}x{}, per frame (amortised; median of {} passes):\n\
             \x20 unwritten {:.0} ms; --layers comp {:.0} ms ({:.2}x; target at most 1.3x; {:.1} MB, write stage {:.0} ms); \
             all {:.0} ms ({:.2}x; target at most 2.5x; {:.1} MB, write stage {:.0} ms)\n\
             \x20 CPU per frame: unwritten {:.0} ms; comp {:.0} ms ({:.2}x); all {:.0} ms ({:.2}x)\n",
            self.scene,
            self.frames[0],
            self.frames[1],
            self.size[0],
            self.size[1],
            self.passes,
            self.unwritten_ms,
            self.comp_ms,
            self.comp_ratio,
            self.comp_file_mb,
            self.comp_write_stage_ms,
            self.all_ms,
            self.all_ratio,
            self.all_file_mb,
            self.all_write_stage_ms,
            self.unwritten_cpu_ms,
            self.comp_cpu_ms,
            self.comp_cpu_ratio,
            self.all_cpu_ms,
            self.all_cpu_ratio,
        )
    }
}

/// [`WrittenFigures`] of `frames` frames of `scene_path` from its first frame, `passes` passes.
pub fn written_times(
    scene_path: &Path,
    frames: u32,
    passes: u32,
) -> Result<WrittenFigures, SnellError> {
    use crate::output::exr::channels::LayerSet;
    use crate::output::exr::WriteOptions;
    let (width, height) = (1280, 720);
    let mut job = RenderJob::prepare(scene_path)?;
    let timeline = *job.timeline();
    let first = timeline.first_frame;
    let last = (first + frames.max(1) - 1).min(timeline.last_frame);
    let list: Vec<u32> = (first..=last).collect();
    let count = list.len() as f64;
    let unwritten = |job: &RenderJob| -> Result<f64, SnellError> {
        let start = Instant::now();
        let mut renderer = Renderer::new()?;
        renderer.set_strip_rows(job.strip_rows);
        job.upload_textures(&mut renderer)?;
        let mut previous = None;
        for &frame in &list {
            let mut refracted = job.refract(frame, width, height, previous.as_ref())?;
            // Read back strip by strip and dropped: nothing of the frame is kept.
            job.render_refracted_strips(
                &mut renderer,
                &mut refracted,
                width,
                height,
                &mut |_, _| Ok(()),
            )?;
            previous = Some(refracted.tracking);
        }
        Ok(start.elapsed().as_secs_f64() * 1e3 / count)
    };
    let presets = [
        WriteOptions {
            half_beauty: true,
            layers: LayerSet::COMP,
            ..WriteOptions::default()
        },
        WriteOptions::default(),
    ];
    // Per preset: ms per frame of each pass, file MB, write-stage ms of each frame.
    let mut written_ms = [Vec::new(), Vec::new()];
    let mut ratios = [Vec::new(), Vec::new()];
    let mut file_mb = [0.0; 2];
    let mut write_stage_ms = [Vec::new(), Vec::new()];
    let mut unwritten_ms = Vec::new();
    let (mut cpu_ms, mut cpu_ratios, mut unwritten_cpu_ms) = (
        [Vec::new(), Vec::new()],
        [Vec::new(), Vec::new()],
        Vec::new(),
    );
    for _ in 0..passes.max(1) {
        let cpu_start = process_cpu_secs();
        let plain = unwritten(&job)?;
        let plain_cpu = (process_cpu_secs() - cpu_start) * 1e3 / count;
        unwritten_ms.push(plain);
        unwritten_cpu_ms.push(plain_cpu);
        for (k, write) in presets.iter().enumerate() {
            job.write = *write;
            let dir = tempfile::tempdir().map_err(|error| {
                SnellError::Argument(format!("bench: cannot make a temporary folder: {error}"))
            })?;
            let output =
                crate::output::pattern::OutputPattern::for_scene(dir.path(), job.scene_name());
            let (start, cpu_start) = (Instant::now(), process_cpu_secs());
            job.render_sequence(&super::resume::SequenceOptions {
                frames: &list,
                width,
                height,
                output: &output,
                write_png: false,
                progress: false,
                log: super::resume::FrameLog::Quiet,
                resume: false,
                stop: None,
            })?;
            let ms = start.elapsed().as_secs_f64() * 1e3 / count;
            let cpu = (process_cpu_secs() - cpu_start) * 1e3 / count;
            written_ms[k].push(ms);
            ratios[k].push(ms / plain);
            cpu_ms[k].push(cpu);
            cpu_ratios[k].push(cpu / plain_cpu);
            file_mb[k] = std::fs::metadata(output.path(first))
                .map(|m| m.len() as f64 / 1e6)
                .unwrap_or(f64::NAN);
            let report =
                std::fs::read_to_string(dir.path().join("report.jsonl")).unwrap_or_default();
            for line in report.lines() {
                let row: serde_json::Value = serde_json::from_str(line).unwrap_or_default();
                if let Some(secs) = row["stage_secs"]["write"].as_f64() {
                    write_stage_ms[k].push(secs * 1e3);
                }
            }
        }
        job.write = WriteOptions::default();
    }
    let [comp_ms, all_ms] = written_ms.map(|mut v| median(&mut v));
    let [comp_ratio, all_ratio] = ratios.map(|mut v| median(&mut v));
    let [comp_write_stage_ms, all_write_stage_ms] = write_stage_ms.map(|mut v| median(&mut v));
    let [comp_cpu_ms, all_cpu_ms] = cpu_ms.map(|mut v| median(&mut v));
    let [comp_cpu_ratio, all_cpu_ratio] = cpu_ratios.map(|mut v| median(&mut v));
    Ok(WrittenFigures {
        scene: job.scene_name().to_string(),
        size: [width, height],
        frames: [first, last],
        passes: passes.max(1),
        unwritten_ms: median(&mut unwritten_ms),
        comp_ms,
        all_ms,
        comp_ratio,
        all_ratio,
        comp_file_mb: file_mb[0],
        all_file_mb: file_mb[1],
        comp_write_stage_ms,
        all_write_stage_ms,
        unwritten_cpu_ms: median(&mut unwritten_cpu_ms),
        comp_cpu_ms,
        all_cpu_ms,
        comp_cpu_ratio,
        all_cpu_ratio,
    })
}

/// The refraction stage on frames with a character's wake beside a calm copy of the same scene
/// (ripples off; the same membrane grid, characters, objects and camera), at 1280x720, with the
/// equal-t and exact methods. Wake and calm frames alternate, frame by frame, so a busy machine
/// slows both alike; each ratio is the median of the per-frame ratios.
#[derive(Debug, Serialize)]
pub struct WakeFigures {
    pub scene: String,
    pub size: [u32; 2],
    /// The measured frames (inclusive), after a warm-up frame before the first.
    pub frames: [u32; 2],
    /// Median refraction-stage milliseconds per frame.
    pub equal_t_wake_ms: f64,
    pub equal_t_calm_ms: f64,
    /// Median over the frames of wake ms / calm ms (target: at most 3).
    pub equal_t_ratio: f64,
    pub exact_wake_ms: f64,
    pub exact_calm_ms: f64,
    /// Median over the frames of wake ms / calm ms (target: at most 5, and the wake under 150 ms).
    pub exact_ratio: f64,
    /// Exact method on the wake frames, summed over the measured frames: vertices whose Newton
    /// solve failed (drawn at the linear point), of the under-water vertices.
    pub exact_newton_fallbacks: u64,
    pub under_water_vertices: u64,
    /// Exact method, median per frame: vertices with more than one image, wake and calm.
    pub exact_convergence_vertices_wake: f64,
    pub exact_convergence_vertices_calm: f64,
}

impl WakeFigures {
    fn to_text(&self) -> String {
        format!(
            "refraction stage of {} frames {}-{} at {}x{}, wake vs calm copy (ripples off), medians:\n\
             \x20 equal-t {:.2} vs {:.2} ms ({:.2}x; target at most 3x)\n\
             \x20 exact   {:.2} vs {:.2} ms ({:.2}x; target at most 5x and under 150 ms)\n\
             \x20 exact on the wake: {} Newton fallbacks of {} under-water vertices ({:.3} %); \
             {:.0} vs {:.0} convergence vertices per frame\n",
            self.scene,
            self.frames[0],
            self.frames[1],
            self.size[0],
            self.size[1],
            self.equal_t_wake_ms,
            self.equal_t_calm_ms,
            self.equal_t_ratio,
            self.exact_wake_ms,
            self.exact_calm_ms,
            self.exact_ratio,
            self.exact_newton_fallbacks,
            self.under_water_vertices,
            100.0 * self.exact_newton_fallbacks as f64 / self.under_water_vertices.max(1) as f64,
            self.exact_convergence_vertices_wake,
            self.exact_convergence_vertices_calm,
        )
    }
}

/// [`WakeFigures`] of `frames` of `scene_path` (a scene whose characters make ripples).
pub fn wake_times(scene_path: &Path, frames: &str) -> Result<WakeFigures, SnellError> {
    let (width, height) = (1280, 720);
    let scene = crate::scene::Scene::load(scene_path)?;
    if !scene.water.ripples.enabled {
        return Err(SnellError::Argument(format!(
            "--wake-scene {}: the scene has no ripples (no character, or ripples disabled); \
             give a scene whose characters make a wake, e.g. scenes/hard/wading_wake.toml",
            scene_path.display()
        )));
    }
    let mut calm_scene = scene.clone();
    calm_scene.water.ripples.enabled = false;
    let mut wake = RenderJob::from_scene(scene)?;
    let mut calm = RenderJob::from_scene(calm_scene)?;
    let range = super::FrameRange::parse(frames, wake.timeline())?;
    let warm_up = range
        .first
        .saturating_sub(1)
        .max(wake.timeline().first_frame);
    // Per method: (wake ms, calm ms, ratio) per frame; exact: fallbacks, under water, convergence.
    let mut figures = Vec::new();
    let (mut fallbacks, mut under_water) = (0, 0);
    let (mut converging_wake, mut converging_calm) = (Vec::new(), Vec::new());
    for method in [super::Method::EqualT, super::Method::Exact] {
        wake.method = method;
        calm.method = method;
        let (mut wake_ms, mut calm_ms, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
        let mut previous_wake = Some(wake.refract(warm_up, width, height, None)?.tracking);
        let mut previous_calm = Some(calm.refract(warm_up, width, height, None)?.tracking);
        for frame in range.frames() {
            let w = wake.refract(frame, width, height, previous_wake.as_ref())?;
            let c = calm.refract(frame, width, height, previous_calm.as_ref())?;
            let (w_ms, c_ms) = (
                w.stage_secs["refraction"] * 1e3,
                c.stage_secs["refraction"] * 1e3,
            );
            wake_ms.push(w_ms);
            calm_ms.push(c_ms);
            ratios.push(w_ms / c_ms);
            if method == super::Method::Exact {
                fallbacks += w.counts.vertices.newton_fallback;
                under_water += w.counts.vertices.under_water;
                converging_wake.push(w.counts.vertices.convergence as f64);
                converging_calm.push(c.counts.vertices.convergence as f64);
            }
            previous_wake = Some(w.tracking);
            previous_calm = Some(c.tracking);
        }
        figures.push((
            median(&mut wake_ms),
            median(&mut calm_ms),
            median(&mut ratios),
        ));
    }
    Ok(WakeFigures {
        scene: wake.scene_name().to_string(),
        size: [width, height],
        frames: [range.first, range.last],
        equal_t_wake_ms: figures[0].0,
        equal_t_calm_ms: figures[0].1,
        equal_t_ratio: figures[0].2,
        exact_wake_ms: figures[1].0,
        exact_calm_ms: figures[1].1,
        exact_ratio: figures[1].2,
        exact_newton_fallbacks: fallbacks,
        under_water_vertices: under_water,
        exact_convergence_vertices_wake: median(&mut converging_wake),
        exact_convergence_vertices_calm: median(&mut converging_calm),
    })
}

/// The ray-traced reference (`--method raytrace`, CPU) on the frame-time scene at 1280x720.
#[derive(Debug, Serialize)]
pub struct ReferenceFigures {
    pub scene: String,
    pub size: [u32; 2],
    pub frames_measured: u32,
    /// Rayon threads the tracer ran on.
    pub threads: usize,
    /// Refracted rays per second of wall-clock trace time, median over the frames. A refracted ray
    /// is a pixel's sight ray that met the water surface (the exact one, by root finding) and was
    /// refracted and traced on through the BVH to what it sees under water (or to nothing);
    /// the time divided is the whole frame's trace: BVH build, every primary ray (those that see
    /// objects or sky above water too), root finding, refracted rays and shading.
    pub refracted_rays_per_sec: f64,
    /// Median wall-clock seconds of the whole traced frame (the tracer only: the water membrane
    /// and posing before it are in the frame-time figures' stages).
    pub secs_per_frame: f64,
    /// Median process CPU seconds (user + system, every thread) of the traced frame.
    pub cpu_secs_per_frame: f64,
    /// Refracted rays per second had every one of the `threads` threads a core of its own:
    /// refracted rays / (CPU seconds / threads). Equals `refracted_rays_per_sec` on an idle
    /// machine; on a machine shared with other work it says what the tracer itself achieves.
    pub refracted_rays_per_sec_unshared: f64,
    /// Refracted rays in a frame (median frame), of `size[0] * size[1]` primary rays.
    pub refracted_rays_per_frame: u64,
    /// Triangles in the frame's BVH and its build time (median), milliseconds.
    pub triangles: usize,
    pub bvh_build_ms: f64,
    /// Exact-surface height-field evaluations per refracted ray (root finding cost).
    pub surface_evaluations_per_refracted_ray: f64,
}

impl ReferenceFigures {
    fn to_text(&self) -> String {
        format!(
            "ray-traced reference (raytrace, CPU, {} threads) of {} at {}x{} (median of {} frames):\n\
             \x20 {:.2} M refracted rays/s, {:.3} s per frame ({} refracted rays; {} triangles, BVH build {:.1} ms; {:.1} surface evaluations per refracted ray)\n\
             \x20 {:.3} CPU s per frame: {:.2} M refracted rays/s with a core per thread\n",
            self.threads,
            self.scene,
            self.size[0],
            self.size[1],
            self.frames_measured,
            self.refracted_rays_per_sec / 1e6,
            self.secs_per_frame,
            self.refracted_rays_per_frame,
            self.triangles,
            self.bvh_build_ms,
            self.surface_evaluations_per_refracted_ray,
            self.cpu_secs_per_frame,
            self.refracted_rays_per_sec_unshared / 1e6,
        )
    }
}

/// The exact method's CPU cost beside the equal-t method's, on the frame-time scene at 1280x720:
/// the refraction stage (search, Newton, subdivision, virtual geometry), no GPU.
#[derive(Debug, Serialize)]
pub struct ExactFigures {
    pub scene: String,
    pub size: [u32; 2],
    pub frames_measured: u32,
    /// Median refraction-stage milliseconds per frame, equal-t method.
    pub equal_t_refraction_ms: f64,
    /// The same for the exact method (default subdivision settings).
    pub exact_refraction_ms: f64,
    /// Median per frame, exact method: triangles subdivided, and vertices whose Newton solve
    /// failed (drawn at the linear point).
    pub subdivided_triangles: f64,
    pub newton_fallback_vertices: f64,
}

impl ExactFigures {
    fn to_text(&self) -> String {
        format!(
            "refraction stage of {} at {}x{} (median of {} frames): equal-t {:.2} ms, exact {:.2} ms \
             ({:.1}x; {:.0} triangles subdivided, {:.0} Newton fallbacks per frame)\n",
            self.scene,
            self.size[0],
            self.size[1],
            self.frames_measured,
            self.equal_t_refraction_ms,
            self.exact_refraction_ms,
            self.exact_refraction_ms / self.equal_t_refraction_ms,
            self.subdivided_triangles,
            self.newton_fallback_vertices,
        )
    }
}

/// Refraction-stage times of the equal-t and exact methods, frame by frame in sequence from the
/// first frame (after one warm-up frame each). CPU only.
fn exact_times(scene_path: &Path, frames: u32) -> Result<ExactFigures, SnellError> {
    let (width, height) = (1280, 720);
    let mut job = RenderJob::prepare(scene_path)?;
    let timeline = *job.timeline();
    let frames = frames
        .max(1)
        .min(timeline.last_frame - timeline.first_frame + 1);
    // Per measured frame: refraction ms, subdivided triangles, fallbacks.
    type Samples = (Vec<f64>, Vec<f64>, Vec<f64>);
    let measure = |job: &RenderJob| -> Result<Samples, SnellError> {
        let (mut ms, mut subdivided, mut fallbacks) = (Vec::new(), Vec::new(), Vec::new());
        let mut previous = None;
        for (i, frame) in (timeline.first_frame..timeline.first_frame + frames + 1).enumerate() {
            let frame = frame.min(timeline.last_frame);
            let refracted = job.refract(frame, width, height, previous.as_ref())?;
            if i > 0 {
                ms.push(refracted.stage_secs["refraction"] * 1e3);
                subdivided.push(refracted.counts.triangles.subdivided as f64);
                fallbacks.push(refracted.counts.vertices.newton_fallback as f64);
            }
            previous = Some(refracted.tracking);
        }
        Ok((ms, subdivided, fallbacks))
    };
    job.method = super::Method::EqualT;
    let (mut equal_t, _, _) = measure(&job)?;
    job.method = super::Method::Exact;
    let (mut exact, mut subdivided, mut fallbacks) = measure(&job)?;
    Ok(ExactFigures {
        scene: job.scene_name().to_string(),
        size: [width, height],
        frames_measured: frames,
        equal_t_refraction_ms: median(&mut equal_t),
        exact_refraction_ms: median(&mut exact),
        subdivided_triangles: median(&mut subdivided),
        newton_fallback_vertices: median(&mut fallbacks),
    })
}

/// Skinning and ripples: their throughput, and their share of a character scene's frame.
#[derive(Debug, Serialize)]
pub struct CharacterFigures {
    /// Linear blend skinning of the Fox (every non-zero joint weight of every vertex), median.
    pub skinning_vertex_influences_per_sec: f64,
    /// Frames of the ripple simulation (exact spectral step with a body's source) on a 256 x 256-node
    /// grid, median.
    pub ripple_frames_per_sec_256: f64,
    /// The character scene's frame times (skinning and ripples stages included).
    pub frame: FrameFigures,
    /// (skinning + ripples) / (water + refraction + render + skinning + ripples) of that scene's
    /// frames, medians: the figure with the 20 % target.
    pub skinning_and_ripples_share: f64,
}

#[derive(Debug, Serialize)]
pub struct RefractionFigures {
    /// 100k true vertices under a 256x256-cell membrane, every image enumerated, per-frame build included.
    pub vertices_per_sec: f64,
    /// Accelerated search against testing every cell, at the thesis's scale (2,628 vertices x ~1,800 facets).
    pub speedup_vs_brute_force: f64,
    pub scenario: String,
}

#[derive(Debug, Serialize)]
pub struct FrameFigures {
    pub scene: String,
    pub size: [u32; 2],
    pub frames_measured: u32,
    pub adapter: String,
    /// Median seconds per stage over the measured frames.
    pub median_stage_ms: BTreeMap<String, f64>,
    /// Median of (water membrane + refraction + render with readback) per frame: the figure with the 100 ms target.
    pub refraction_plus_render_ms: f64,
}

impl FrameFigures {
    fn to_text(&self) -> String {
        let mut text = format!(
            "frame times of {} at {}x{} on {} (median of {} frames):\n",
            self.scene, self.size[0], self.size[1], self.adapter, self.frames_measured,
        );
        for (stage, ms) in &self.median_stage_ms {
            text.push_str(&format!("  {stage:<12} {ms:8.2} ms\n"));
        }
        text.push_str(&format!(
            "  water + refraction + render (readback included): {:.2} ms\n",
            self.refraction_plus_render_ms
        ));
        text
    }
}

impl BenchFigures {
    pub fn to_text(&self) -> String {
        let characters = &self.characters;
        format!(
            "refraction search: {:.2} M vertices/s ({})\n\
             speed-up over brute force at the thesis's scale: {:.0}x\n\
             {}\
             skinning: {:.1} M vertex-influences/s (Fox)\n\
             ripples: {:.0} frames/s on a 256x256 grid\n\
             {}\
             skinning + ripples: {:.1} % of the {} frame\n\
             {}{}{}{}",
            self.refraction.vertices_per_sec / 1e6,
            self.refraction.scenario,
            self.refraction.speedup_vs_brute_force,
            self.frame.to_text(),
            characters.skinning_vertex_influences_per_sec / 1e6,
            characters.ripple_frames_per_sec_256,
            characters.frame.to_text(),
            100.0 * characters.skinning_and_ripples_share,
            characters.frame.scene,
            self.reference.to_text(),
            self.exact.to_text(),
            self.wake.to_text(),
            self.written.to_text(),
        )
    }
}

/// Skinning throughput of `scenes/assets/Fox.glb` and ripple frames per second on a 256^2 grid.
fn character_throughput(fox: &Path) -> Result<(f64, f64), SnellError> {
    let asset = crate::character::CharacterAsset::load(fox)
        .map_err(|e| SnellError::Argument(e.to_string()))?;
    let skinning = crate::character::skinning_throughput(&asset, 50);
    let settings = crate::sim::RippleSettings {
        nodes_x: 256,
        nodes_z: 256,
        min_x: -5.0,
        min_z: -5.0,
        spacing_m: 10.0 / 255.0,
        depth_m: 1.0,
        surface_tension_n_per_m: crate::sim::ripples::WATER_SURFACE_TENSION_N_PER_M,
        density_kg_per_m3: crate::sim::ripples::WATER_DENSITY_KG_PER_M3,
        damping_per_s: 0.5,
        cutoff_per_m: 0.5 * std::f64::consts::PI * 255.0 / 10.0,
        border: crate::sim::Border::Absorb,
        sponge_nodes: 12,
        sponge_damping_per_s: 8.0,
    };
    let stepper = crate::sim::RippleStepper::new(settings, 1.0 / 24.0);
    let mut state = crate::sim::RippleState::calm(settings);
    state.height_m[128 * 256 + 128] = 0.01;
    let push = vec![0.0f32; settings.node_count()];
    let mut per_batch = Vec::new();
    for _ in 0..7 {
        let start = Instant::now();
        for _ in 0..10 {
            stepper.advance_frame(&mut state, &push);
        }
        per_batch.push(10.0 / start.elapsed().as_secs_f64());
    }
    Ok((skinning, median(&mut per_batch)))
}

/// Frames of each pass of [`written_times`] in `snell bench`, and its passes.
pub const WRITTEN_FRAMES: u32 = 8;
pub const WRITTEN_PASSES: u32 = 3;

pub fn run(
    scene_path: &Path,
    characters_scene_path: &Path,
    fox_path: &Path,
    frames: u32,
    wake_scene_path: &Path,
    wake_frames: &str,
) -> Result<BenchFigures, SnellError> {
    let search = crate::refraction::bench::bench_search();
    let refraction = RefractionFigures {
        vertices_per_sec: search.vertices_per_sec,
        speedup_vs_brute_force: search.speedup_vs_brute_force,
        scenario: format!(
            "{} true vertices under a {}-facet membrane; thesis scale {} vertices x {} facets, {} mismatches against brute force",
            search.pool_vertices, search.pool_facets, search.thesis_vertices, search.thesis_facets, search.thesis_mismatched_vertices
        ),
    };

    let mut renderer = Renderer::new()?;
    let frame = frame_times(&mut renderer, scene_path, frames)?;
    let characters_frame = frame_times(&mut renderer, characters_scene_path, frames)?;
    let stage = |name: &str| {
        characters_frame
            .median_stage_ms
            .get(name)
            .copied()
            .unwrap_or(0.0)
    };
    let dynamics_ms = stage("skinning") + stage("ripples");
    let share =
        dynamics_ms / (dynamics_ms + stage("water") + stage("refraction") + stage("render"));
    let (skinning, ripple_steps) = character_throughput(fox_path)?;
    let reference = reference_figures(scene_path, frames)?;
    let exact = exact_times(scene_path, frames)?;
    let wake = wake_times(wake_scene_path, wake_frames)?;
    let written = written_times(scene_path, WRITTEN_FRAMES, WRITTEN_PASSES)?;
    Ok(BenchFigures {
        refraction,
        frame,
        reference,
        characters: CharacterFigures {
            skinning_vertex_influences_per_sec: skinning,
            ripple_frames_per_sec_256: ripple_steps,
            frame: characters_frame,
            skinning_and_ripples_share: share,
        },
        exact,
        wake,
        written,
    })
}

/// Per-stage times of `frames` frames of a scene at 1280x720, in sequence from its first frame
/// (after one warm-up frame).
fn frame_times(
    renderer: &mut Renderer,
    scene_path: &Path,
    frames: u32,
) -> Result<FrameFigures, SnellError> {
    let (width, height) = (1280, 720);
    let job = RenderJob::prepare(scene_path)?;
    job.upload_textures(renderer)?;
    let timeline = *job.timeline();
    let frames = frames
        .max(1)
        .min(timeline.last_frame - timeline.first_frame + 1);
    let mut per_stage: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut totals = Vec::new();
    let mut previous = None;
    // One warm-up frame (shader compilation, buffer allocation), then the measured ones.
    for (i, frame) in (timeline.first_frame..timeline.first_frame + frames + 1).enumerate() {
        let frame = frame.min(timeline.last_frame);
        let mut refracted = job.refract(frame, width, height, previous.as_ref())?;
        job.render_refracted_strips(
            &mut *renderer,
            &mut refracted,
            width,
            height,
            &mut |_, _| Ok(()),
        )?;
        if i > 0 {
            for (stage, secs) in &refracted.stage_secs {
                per_stage.entry(stage.clone()).or_default().push(secs * 1e3);
            }
            // Water membrane build counted in: it is per-frame CPU work the refraction needs.
            totals.push(
                (refracted.stage_secs["water"]
                    + refracted.stage_secs["refraction"]
                    + refracted.stage_secs["render"])
                    * 1e3,
            );
        }
        previous = Some(refracted.tracking);
    }
    let median_stage_ms = per_stage
        .into_iter()
        .map(|(k, mut v)| (k, median(&mut v)))
        .collect();
    Ok(FrameFigures {
        scene: job.scene_name().to_string(),
        size: [width, height],
        frames_measured: frames,
        adapter: renderer.adapter_summary(),
        median_stage_ms,
        refraction_plus_render_ms: median(&mut totals),
    })
}

/// Traces `frames` frames of a scene at 1280x720 with `--method raytrace` (after one warm-up
/// frame) and takes the medians.
pub fn reference_figures(scene_path: &Path, frames: u32) -> Result<ReferenceFigures, SnellError> {
    let (width, height) = (1280, 720);
    let mut job = RenderJob::prepare(scene_path)?;
    job.method = super::Method::Raytrace;
    let timeline = *job.timeline();
    let frames = frames
        .max(1)
        .min(timeline.last_frame - timeline.first_frame + 1);
    let (mut rates, mut secs, mut rays, mut builds, mut evaluations) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut cpu_secs, mut unshared) = (Vec::new(), Vec::new());
    let threads = rayon::current_num_threads();
    let mut triangles = 0;
    for (i, frame) in (timeline.first_frame..timeline.first_frame + frames + 1).enumerate() {
        let frame = frame.min(timeline.last_frame);
        let refracted = job.refract(frame, width, height, None)?;
        let cpu_before = process_cpu_secs();
        let traced = job.trace_refracted(&refracted, width, height)?;
        let cpu = process_cpu_secs() - cpu_before;
        let stats = traced.stats;
        if i > 0 {
            cpu_secs.push(cpu);
            unshared.push(stats.refracted_rays as f64 / (cpu / threads as f64));
            rates.push(stats.refracted_rays as f64 / stats.total_secs);
            secs.push(stats.total_secs);
            rays.push(stats.refracted_rays as f64);
            builds.push(stats.build_secs * 1e3);
            evaluations.push(stats.surface_evaluations as f64 / stats.refracted_rays.max(1) as f64);
            triangles = stats.triangles;
        }
    }
    Ok(ReferenceFigures {
        scene: job.scene_name().to_string(),
        size: [width, height],
        frames_measured: frames,
        threads,
        cpu_secs_per_frame: median(&mut cpu_secs),
        refracted_rays_per_sec_unshared: median(&mut unshared),
        refracted_rays_per_sec: median(&mut rates),
        secs_per_frame: median(&mut secs),
        refracted_rays_per_frame: median(&mut rays) as u64,
        triangles,
        bvh_build_ms: median(&mut builds),
        surface_evaluations_per_refracted_ray: median(&mut evaluations),
    })
}

/// User + system CPU seconds this process has used, over all its threads.
fn process_cpu_secs() -> f64 {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage fills the struct it is given; RUSAGE_SELF is always valid.
    let usage = unsafe {
        libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr());
        usage.assume_init()
    };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    secs(usage.ru_utime) + secs(usage.ru_stime)
}

#[cfg(test)]
mod tuning {
    use super::*;

    /// `snell bench`'s written-frame figures alone, on `SNELL_WRITTEN_SCENE` (default
    /// scenes/pool.toml):
    /// `cargo test --release --lib frame::bench::tuning::written_frames -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn written_frames() {
        let scene =
            std::env::var("SNELL_WRITTEN_SCENE").unwrap_or_else(|_| "scenes/pool.toml".to_string());
        let figures = written_times(Path::new(&scene), WRITTEN_FRAMES, WRITTEN_PASSES).unwrap();
        print!("{}", figures.to_text());
    }

    /// The README's table of compression choices ("What a render gives you"): `snell render` of
    /// `pool.toml` frames 23-25 at 1280x720 with each `--compression`, float32 and `--half`
    /// beauty, every layer; per choice the median frame's file size, write stage (report.jsonl:
    /// encoding, compression, write, fsync, rename) and file MB over write seconds. Prints the
    /// table as markdown:
    /// `cargo test --release --lib frame::bench::tuning::compression_table -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn compression_table() {
        use crate::output::exr::{ExrCompression, WriteOptions};
        let mut job = RenderJob::prepare(Path::new("scenes/pool.toml")).unwrap();
        let frames = [23, 24, 25];
        println!("| compression | file | write | file MB/s | with `--half`: file | write |");
        println!("|---|---|---|---|---|---|");
        for compression in ExrCompression::ALL {
            let mut cells = Vec::new();
            for half_beauty in [false, true] {
                job.write = WriteOptions {
                    half_beauty,
                    compression,
                    ..WriteOptions::default()
                };
                let dir = tempfile::tempdir().unwrap();
                let output =
                    crate::output::pattern::OutputPattern::for_scene(dir.path(), job.scene_name());
                job.render_sequence(&super::super::resume::SequenceOptions {
                    frames: &frames,
                    width: 1280,
                    height: 720,
                    output: &output,
                    write_png: false,
                    progress: false,
                    log: super::super::resume::FrameLog::Quiet,
                    resume: false,
                    stop: None,
                })
                .unwrap();
                let report = std::fs::read_to_string(dir.path().join("report.jsonl")).unwrap();
                let mut rows: Vec<(f64, f64)> = report
                    .lines()
                    .map(|line| {
                        let row: serde_json::Value = serde_json::from_str(line).unwrap();
                        let frame = row["frame"].as_u64().unwrap() as u32;
                        let mb = std::fs::metadata(output.path(frame)).unwrap().len() as f64 / 1e6;
                        (row["stage_secs"]["write"].as_f64().unwrap(), mb)
                    })
                    .collect();
                rows.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (secs, mb) = rows[rows.len() / 2];
                cells.push((mb, secs));
            }
            let default = if compression == ExrCompression::default() {
                " (default)"
            } else {
                ""
            };
            println!(
                "| `{}`{default} | {:.1} MB | {:.2} s | {:.0} | {:.1} MB | {:.2} s |",
                compression.name(),
                cells[0].0,
                cells[0].1,
                cells[0].0 / cells[0].1,
                cells[1].0,
                cells[1].1
            );
        }
    }

    /// Tuning aid: the exact surface's global bounds (slope, curvature, height range) that every
    /// visibility walk steps by, on frames of scenes/hard/wading_wake.toml:
    /// `cargo test --release --lib frame::bench::tuning::wake_bounds -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn wake_bounds() {
        let job = RenderJob::prepare(Path::new("scenes/hard/wading_wake.toml")).unwrap();
        for frame in [1, 20, 40, 48] {
            let water = job.frame_water(frame, &mut BTreeMap::new()).unwrap();
            let heights = water.surface();
            let surface = water.exact_surface(&heights);
            println!(
                "frame {frame}: slope bound {:.4}, curvature bound {:.2} /m, heights {:?} m, largest ripple node {:?} m",
                surface.slope_bound,
                surface.curvature_bound,
                surface.height_range_m,
                water.ripples.as_ref().map(|r| r.max_abs_height_m())
            );
        }
    }

    /// Tuning aid: `snell bench`'s wake pair alone (no GPU), on `SNELL_WAKE_SCENE` (default
    /// scenes/hard/wading_wake.toml) frames `SNELL_WAKE_FRAMES` (default 40-48):
    /// `cargo test --release --lib frame::bench::tuning::wake_pair -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn wake_pair() {
        let scene = std::env::var("SNELL_WAKE_SCENE")
            .unwrap_or_else(|_| "scenes/hard/wading_wake.toml".to_string());
        let frames = std::env::var("SNELL_WAKE_FRAMES").unwrap_or_else(|_| "40-48".to_string());
        let figures = wake_times(Path::new(&scene), &frames).unwrap();
        print!("{}", figures.to_text());
    }

    /// Tuning aid: the exact method's Newton fallbacks on every frame of every
    /// `scenes/hard/*.toml` (or `SNELL_HARD_SCENES`, comma-separated) at 1280x720, every
    /// `SNELL_HARD_STEP`-th frame (default 1), with the refraction stage's median ms: per scene the
    /// total share of under-water vertices and the worst frame's:
    /// `cargo test --release --lib frame::bench::tuning::hard_fallbacks -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn hard_fallbacks() {
        let scenes: Vec<String> = match std::env::var("SNELL_HARD_SCENES") {
            Ok(list) => list.split(',').map(str::to_string).collect(),
            Err(_) => {
                let mut found: Vec<String> = std::fs::read_dir("scenes/hard")
                    .unwrap()
                    .map(|e| e.unwrap().path().display().to_string())
                    .filter(|p| p.ends_with(".toml"))
                    .collect();
                found.sort();
                found
            }
        };
        let step: u32 = std::env::var("SNELL_HARD_STEP").map_or(1, |s| s.parse().unwrap());
        for scene in scenes {
            let mut job = RenderJob::prepare(Path::new(&scene)).unwrap();
            job.method = super::super::Method::Exact;
            let timeline = *job.timeline();
            let (mut fallbacks, mut under_water) = (0u64, 0u64);
            let mut worst = (0.0f64, 0u32, 0u64, 0u64);
            let mut ms = Vec::new();
            let mut previous = None;
            for frame in (timeline.first_frame..=timeline.last_frame).step_by(step as usize) {
                let r = job.refract(frame, 1280, 720, previous.as_ref()).unwrap();
                let v = &r.counts.vertices;
                fallbacks += v.newton_fallback;
                under_water += v.under_water;
                let share = v.newton_fallback as f64 / v.under_water.max(1) as f64;
                if share >= worst.0 {
                    worst = (share, frame, v.newton_fallback, v.under_water);
                }
                ms.push(r.stage_secs["refraction"] * 1e3);
                previous = Some(r.tracking);
            }
            println!(
                "{scene}: {} frames, Newton fallbacks {fallbacks} of {under_water} under-water vertices ({:.3} %); \
                 worst frame {} {} of {} ({:.3} %); exact refraction stage median {:.1} ms",
                ms.len(),
                100.0 * fallbacks as f64 / under_water.max(1) as f64,
                worst.1,
                worst.2,
                worst.3,
                100.0 * worst.0,
                median(&mut ms)
            );
        }
    }

    /// Tuning aid: the refraction stage of `pool.toml` frames alone (no GPU), fastest of 3 passes
    /// over frames 1-24: `cargo test --release --lib frame::bench::tuning -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn pool_refraction_stage() {
        let job = RenderJob::prepare(Path::new("scenes/pool.toml")).unwrap();
        let mut best = [f64::INFINITY; 24];
        for _ in 0..3 {
            let mut previous = None;
            for frame in 1..=24 {
                let refracted = job.refract(frame, 1280, 720, previous.as_ref()).unwrap();
                best[frame as usize - 1] =
                    best[frame as usize - 1].min(refracted.stage_secs["refraction"]);
                previous = Some(refracted.tracking);
            }
        }
        best.sort_by(f64::total_cmp);
        println!(
            "REFRACTION stage fastest {:.2} ms median {:.2} ms",
            best[0] * 1e3,
            best[12] * 1e3
        );
    }

    /// Tuning aid: the render stage (draw + readback) of `pool.toml` frames 1-24 at 1280x720,
    /// fastest and median over 2 passes:
    /// `cargo test --release --lib frame::bench::tuning::pool_render_stage -- --ignored --nocapture`.
    #[test]
    #[ignore = "tuning aid"]
    fn pool_render_stage() {
        let job = RenderJob::prepare(Path::new("scenes/pool.toml")).unwrap();
        let mut renderer = Renderer::new().unwrap();
        job.upload_textures(&mut renderer).unwrap();
        let mut previous = None;
        let mut refracted: Vec<_> = (1..=24)
            .map(|frame| {
                let r = job.refract(frame, 1280, 720, previous.as_ref()).unwrap();
                previous = Some(r.tracking.clone());
                r
            })
            .collect();
        let (mut times, mut cpu) = (Vec::new(), Vec::new());
        for pass in 0..3 {
            for r in refracted.iter_mut() {
                let (start, cpu_start) = (std::time::Instant::now(), process_cpu_secs());
                job.render_refracted(&mut renderer, r, 1280, 720).unwrap();
                if pass > 0 {
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                    cpu.push((process_cpu_secs() - cpu_start) * 1e3);
                }
            }
        }
        times.sort_by(f64::total_cmp);
        cpu.sort_by(f64::total_cmp);
        println!(
            "RENDER stage fastest {:.2} ms median {:.2} ms; CPU fastest {:.1} ms median {:.1} ms",
            times[0],
            times[times.len() / 2],
            cpu[0],
            cpu[cpu.len() / 2]
        );
    }
}
