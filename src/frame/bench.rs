//! `snell bench`: the speed figures the README quotes, from one run. Refraction search throughput
//! and speed-up over brute force (the refraction stage's own benchmark), and per-stage frame times
//! of a scene at 1280x720 (refraction + render with readback being the figure with a target).

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;

use super::{RenderJob, SnellError};
use crate::gpu::Renderer;

#[derive(Debug, Serialize)]
pub struct BenchFigures {
    pub refraction: RefractionFigures,
    pub frame: FrameFigures,
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

impl BenchFigures {
    pub fn to_text(&self) -> String {
        let mut text = format!(
            "refraction search: {:.2} M vertices/s ({})\n\
             speed-up over brute force at the thesis's scale: {:.0}x\n\
             frame times of {} at {}x{} on {} (median of {} frames):\n",
            self.refraction.vertices_per_sec / 1e6,
            self.refraction.scenario,
            self.refraction.speedup_vs_brute_force,
            self.frame.scene,
            self.frame.size[0],
            self.frame.size[1],
            self.frame.adapter,
            self.frame.frames_measured,
        );
        for (stage, ms) in &self.frame.median_stage_ms {
            text.push_str(&format!("  {stage:<12} {ms:8.2} ms\n"));
        }
        text.push_str(&format!(
            "  water + refraction + render (readback included): {:.2} ms\n",
            self.frame.refraction_plus_render_ms
        ));
        text
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(|a, b| a.total_cmp(b));
    if values.is_empty() {
        return f64::NAN;
    }
    values[values.len() / 2]
}

pub fn run(scene_path: &Path, frames: u32) -> Result<BenchFigures, SnellError> {
    let search = crate::refraction::bench::bench_search();
    let refraction = RefractionFigures {
        vertices_per_sec: search.vertices_per_sec,
        speedup_vs_brute_force: search.speedup_vs_brute_force,
        scenario: format!(
            "{} true vertices under a {}-facet membrane; thesis scale {} vertices x {} facets, {} mismatches against brute force",
            search.pool_vertices, search.pool_facets, search.thesis_vertices, search.thesis_facets, search.thesis_mismatched_vertices
        ),
    };

    let (width, height) = (1280, 720);
    let job = RenderJob::prepare(scene_path)?;
    let mut renderer = Renderer::new()?;
    job.upload_textures(&mut renderer)?;
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
        job.render_refracted(&mut renderer, &mut refracted, width, height)?;
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
    Ok(BenchFigures {
        refraction,
        frame: FrameFigures {
            scene: job.scene_name().to_string(),
            size: [width, height],
            frames_measured: frames,
            adapter: renderer.adapter_summary(),
            median_stage_ms,
            refraction_plus_render_ms: median(&mut totals),
        },
    })
}
