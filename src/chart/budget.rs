//! A scene's `[quality] max_error_px`: model no more than the shot needs. Receives a job whose
//! scene states the budget, the image size and the output directory; measures candidate
//! configurations against the ray-traced reference on frames of the shot and returns the first,
//! in order of cost, that meets the budget — then sets the job to it. The choice is cached in the
//! output directory under the hash of its inputs, so a re-render does not measure again.
//!
//! The rule, in words (also in `snell render --help`):
//! - the error of a configuration is the 99th percentile of its screen-space position error
//!   against the reference, over the pixels where both see the same object (flagged pixels
//!   included: coarse membranes flag more, and leaving those out would flatter them), at the
//!   render's size, taken as the worst over [`measured_frames`] (first, middle and last frame of
//!   the scene's timeline);
//! - candidates, cheapest first: membrane resolutions from the coarsest up ([`candidates`]: the
//!   chart's square grids and the scene's own), and at each resolution the linear method (equal-t)
//!   before the exact one; the first that meets the budget is chosen;
//! - when none does, the reference itself (error 0 by definition) is used.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{Configuration, Measurer, LINEAR_RESOLUTIONS, REFERENCE_METHOD};
use crate::draw::RenderedFrame;
use crate::frame::{inputs, Method, RenderJob, SnellError};

/// The cache file in the output directory.
pub const CHOICE_FILE_NAME: &str = "quality_choice.json";
/// The EXR header attribute (`snell.extra.<key>`) that carries the choice.
pub const CHOICE_ATTRIBUTE: &str = "qualityChoice";
/// What the cache key hashes besides the scene's files, the size and snell's version.
const CHOICE_KEY_LABEL: &str = "max-error-px-choice/p99-all-pixels/first-middle-last";

/// One candidate as measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CandidateError {
    pub method: String,
    pub resolution: [u32; 2],
    /// Worst over the measured frames.
    pub p99_px: f64,
    pub mean_px: f64,
    pub object_mismatch_fraction: f64,
}

/// The configuration snell chose for a scene's `max_error_px`, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QualityChoice {
    pub max_error_px: f64,
    /// [`Method::name`] of the chosen method.
    pub method: String,
    /// Membrane cells along x and z the frames are rendered with.
    pub resolution: [u32; 2],
    /// The frames the candidates were measured on.
    pub measured_frames: Vec<u32>,
    pub size: [u32; 2],
    /// Every candidate measured, in the order tried, with its worst error over the measured frames
    /// (a candidate is dropped at the first frame it fails); when one met the budget it is last.
    pub candidates: Vec<CandidateError>,
    /// Whether this run measured it or read it from the cache (not stored in the cache).
    #[serde(skip)]
    pub from_cache: bool,
}

impl QualityChoice {
    pub fn chosen_method(&self) -> Result<Method, SnellError> {
        Method::parse(&self.method)
    }

    /// The line `snell render` prints.
    pub fn describe(&self) -> String {
        let how = if self.from_cache {
            "measured before, read from the cache"
        } else {
            "measured now"
        };
        let frames: Vec<String> = self.measured_frames.iter().map(u32::to_string).collect();
        let chosen = match self.candidates.last() {
            Some(c) if c.method == self.method && c.resolution == self.resolution => {
                format!("p99 error {:.3} px, mean {:.3} px", c.p99_px, c.mean_px)
            }
            _ => "no cheaper candidate met the budget; the reference has error 0".to_string(),
        };
        let resolution = if self.method == REFERENCE_METHOD.name() {
            "the exact surface".to_string()
        } else {
            format!("{}x{} cells", self.resolution[0], self.resolution[1])
        };
        format!(
            "max_error_px = {}: rendering with {} at {resolution} ({chosen}, worst of frames {} at {}x{} \
             against the ray-traced reference; {} candidate(s) tried; {how})",
            self.max_error_px,
            self.method,
            frames.join(", "),
            self.size[0],
            self.size[1],
            self.candidates.len(),
        )
    }

    /// As JSON, for report rows and EXR headers.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a choice serialises")
    }
}

/// The frames of the shot a budget is measured on: the first, middle and last of the timeline.
pub fn measured_frames(job: &RenderJob) -> Vec<u32> {
    let timeline = job.timeline();
    let mut frames = vec![
        timeline.first_frame,
        timeline.first_frame + (timeline.last_frame - timeline.first_frame) / 2,
        timeline.last_frame,
    ];
    frames.dedup();
    frames
}

/// Candidates in the order they are tried, cheapest first (see the module documentation). The
/// reference is not among them: it is the fallback.
pub fn candidates(scene_resolution: [u32; 2]) -> Vec<Configuration> {
    let mut resolutions: Vec<[u32; 2]> = LINEAR_RESOLUTIONS.iter().map(|&n| [n, n]).collect();
    if !resolutions.contains(&scene_resolution) {
        resolutions.push(scene_resolution);
    }
    // Fewest cells first; equal counts: the one with fewer cells along x.
    resolutions.sort_by_key(|r| (r[0] as u64 * r[1] as u64, r[0]));
    resolutions
        .into_iter()
        .flat_map(|resolution| {
            [Method::EqualT, Method::Exact].map(|method| Configuration { method, resolution })
        })
        .collect()
}

/// The cache's contents.
#[derive(Serialize, Deserialize)]
struct CachedChoice {
    /// Hex of the hash of the scene's files, the size, the rule and snell's version.
    key: String,
    choice: QualityChoice,
}

fn choice_key(job: &RenderJob, width: u32, height: u32) -> String {
    inputs::input_hash(&job.scene_files_digest(), width, height, CHOICE_KEY_LABEL).hex()
}

fn read_cached(path: &Path, key: &str) -> Option<QualityChoice> {
    let text = std::fs::read_to_string(path).ok()?;
    let cached: CachedChoice = serde_json::from_str(&text).ok()?;
    (cached.key == key).then_some(QualityChoice {
        from_cache: true,
        ..cached.choice
    })
}

/// Picks (or reads from `out_dir`'s cache) the configuration for the job's `max_error_px` at
/// `width` x `height` and sets the job to it. `Ok(None)`: the scene states no budget and the job is
/// left as it was.
pub fn apply_budget(
    job: &mut RenderJob,
    width: u32,
    height: u32,
    out_dir: &Path,
    progress: bool,
) -> Result<Option<QualityChoice>, SnellError> {
    let Some(max_error_px) = job.scene.quality.max_error_px else {
        return Ok(None);
    };
    let cache: PathBuf = out_dir.join(CHOICE_FILE_NAME);
    let key = choice_key(job, width, height);
    let choice = match read_cached(&cache, &key) {
        Some(choice) => choice,
        None => {
            let choice = measure_choice(job, max_error_px, width, height, progress)?;
            crate::output::ensure_output_dir(out_dir)?;
            let text = serde_json::to_string_pretty(&CachedChoice {
                key,
                choice: choice.clone(),
            })
            .expect("a choice serialises");
            use std::io::Write;
            crate::output::write_atomically(&cache, |file| {
                file.write_all(text.as_bytes())
                    .map_err(|error| error.to_string())
            })?;
            choice
        }
    };
    job.method = choice.chosen_method()?;
    job.scene.water.resolution = choice.resolution;
    job.quality_choice = Some(choice.clone());
    Ok(Some(choice))
}

/// Measures [`candidates`] in order until one meets `max_error_px` on every [`measured_frames`].
pub fn measure_choice(
    job: &mut RenderJob,
    max_error_px: f64,
    width: u32,
    height: u32,
    progress: bool,
) -> Result<QualityChoice, SnellError> {
    let frames = measured_frames(job);
    let scene_resolution = job.scene.water.resolution;
    let configurations = candidates(scene_resolution);
    // Every measured frame's reference, the candidate measured and the frame in the making.
    let frames_held = frames.len() as u32 + 2;
    let mut measurer = Measurer::new(job, width, height, frames_held)?;
    let bar = super::progress_bar((frames.len() * (1 + configurations.len())) as u64, progress);
    let reference_configuration = Configuration {
        method: REFERENCE_METHOD,
        resolution: scene_resolution,
    };
    let mut references: Vec<RenderedFrame> = Vec::new();
    for &frame in &frames {
        bar.set_message(format!("max_error_px: reference, frame {frame}"));
        references.push(measurer.render_once(reference_configuration, frame)?);
        bar.inc(1);
    }
    let mut tried = Vec::new();
    let mut chosen = reference_configuration;
    for configuration in configurations {
        let mut worst: Option<CandidateError> = None;
        for (&frame, reference) in frames.iter().zip(&references) {
            bar.set_message(format!(
                "max_error_px: {}, frame {frame}",
                configuration.describe()
            ));
            let rendered = measurer.render_once(configuration, frame)?;
            let comparison =
                super::position_error_against(&rendered, reference, frame, measurer.job)?;
            // Both ways, outside the reference's fold band, where one sample per pixel cannot
            // place the images (`snell compare`'s figures).
            let error = comparison.both.outside_fold_band;
            bar.inc(1);
            let worst_so_far = worst.get_or_insert(CandidateError {
                method: configuration.method.name().to_string(),
                resolution: configuration.resolution,
                p99_px: 0.0,
                mean_px: 0.0,
                object_mismatch_fraction: 0.0,
            });
            worst_so_far.p99_px = worst_so_far.p99_px.max(error.p99_px);
            worst_so_far.mean_px = worst_so_far.mean_px.max(error.mean_px);
            worst_so_far.object_mismatch_fraction = worst_so_far
                .object_mismatch_fraction
                .max(comparison.object_mismatch_fraction);
            if worst_so_far.p99_px > max_error_px {
                break; // fails on this frame: the others cannot save it
            }
        }
        let worst = worst.expect("at least one frame is measured");
        let met = worst.p99_px <= max_error_px;
        tried.push(worst);
        if met {
            chosen = configuration;
            break;
        }
    }
    bar.finish_and_clear();
    Ok(QualityChoice {
        max_error_px,
        method: chosen.method.name().to_string(),
        resolution: chosen.resolution,
        measured_frames: frames,
        size: [width, height],
        candidates: tried,
        from_cache: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_go_from_coarse_to_fine_linear_first() {
        let list = candidates([160, 80]);
        let cells: Vec<u64> = list
            .iter()
            .map(|c| c.resolution[0] as u64 * c.resolution[1] as u64)
            .collect();
        assert!(cells.windows(2).all(|w| w[0] <= w[1]), "{cells:?}");
        assert_eq!(list[0].method, Method::EqualT);
        assert_eq!(list[1].method, Method::Exact);
        assert_eq!(list[0].resolution, list[1].resolution);
        // 160x80 = 12,800 cells lies between 64x64 and 128x128.
        let at = list.iter().position(|c| c.resolution == [160, 80]).unwrap();
        assert_eq!(list[at - 1].resolution, [64, 64]);
        assert_eq!(list[at + 2].resolution, [128, 128]);
        assert_eq!(list.len(), 12);
        assert!(list.iter().all(|c| !c.is_reference()));
        assert_eq!(candidates([64, 64]).len(), 10);
    }
}
