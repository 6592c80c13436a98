//! Rendering a range of frames into a directory so that the work survives failure. Receives a
//! [`RenderJob`] and [`SequenceOptions`]; writes EXR frames, PNGs and report rows (each renamed
//! into place whole) and returns what it rendered, what it skipped and why.
//!
//! With `resume`, a frame is skipped when its EXR reads back whole, its header's
//! `snell.extra.inputHash` equals the job's and its report row carries the same hash; every other
//! frame is rendered, with popping judged against frame - 1 exactly as in an uninterrupted run.
//! A stop request (Ctrl-C) ends the sequence once the frame in flight is written.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::inputs::{InputHash, INPUT_HASH_ATTRIBUTE};
use super::writer::{FrameStart, ToWriter};
use super::{RenderJob, SnellError, VertexTracking};
use crate::gpu::Renderer;
use crate::output::report::ReportWriter;

/// What [`RenderJob::render_sequence`] renders, where, and how it may be cut short.
pub struct SequenceOptions<'a> {
    /// The frames to render, sorted, each once ([`super::parse_frame_list`]).
    pub frames: &'a [u32],
    pub width: u32,
    pub height: u32,
    /// Where each frame goes; its folder also holds the report and the checkpoints.
    pub output: &'a crate::output::pattern::OutputPattern,
    /// Also write a tone-mapped PNG next to each EXR.
    pub write_png: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// A line on stdout per frame written (for farm logs).
    pub log: FrameLog,
    /// Skip frames already complete from the same inputs.
    pub resume: bool,
    /// When set (by a signal handler), no new frame is started; the frame in flight is finished
    /// and written.
    pub stop: Option<&'a AtomicBool>,
}

/// What a render prints on stdout for each frame it has written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrameLog {
    /// Nothing (a terminal shows the progress bar instead).
    #[default]
    Quiet,
    /// `frame 12: 0.84 s, <path>; vertices: ...; triangles: ...`.
    Text,
    /// The same as one JSON object per line.
    Json,
}

impl FrameLog {
    /// The line for a written frame (`report` carries its counts and seconds per stage, the
    /// write included); None when quiet.
    pub fn line(self, path: &Path, report: &crate::output::report::FrameReport) -> Option<String> {
        let secs: f64 = report.stage_secs.values().sum();
        match self {
            FrameLog::Quiet => None,
            FrameLog::Json => Some(
                serde_json::json!({
                    "frame": report.frame,
                    "secs": (secs * 1000.0).round() / 1000.0,
                    "path": path.display().to_string(),
                    "counts": report.counts,
                })
                .to_string(),
            ),
            FrameLog::Text => {
                let group = |name: &str| -> String {
                    let counts = report.counts.get(name).and_then(|v| v.as_object());
                    let items: Vec<String> = counts
                        .into_iter()
                        .flatten()
                        .map(|(key, value)| format!("{key} {value}"))
                        .collect();
                    format!("{name}: {}", items.join(", "))
                };
                Some(format!(
                    "frame {}: {secs:.2} s, {}; {}; {}",
                    report.frame,
                    path.display(),
                    group("vertices"),
                    group("triangles")
                ))
            }
        }
    }
}

/// Why a frame is rendered when resuming.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RenderReason {
    /// No EXR for the frame.
    Missing,
    /// The EXR cannot be read back whole (truncated, corrupted, not OpenEXR); the cause.
    Unreadable(String),
    /// The EXR was made from other inputs (scene, an asset, size, method or snell version), or
    /// carries no input hash.
    HashDiffers,
    /// The EXR is current but the report has no row from the same inputs for it (a process
    /// killed between writing the frame and its row).
    ReportRowStale,
}

/// Which frames a resumed render skips and which it renders, with the reason for each.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ResumePlan {
    pub skip: Vec<u32>,
    pub render: Vec<(u32, RenderReason)>,
}

impl ResumePlan {
    /// One paragraph for the user: how many frames are skipped and why the others are rendered.
    pub fn summary(&self) -> String {
        let total = self.skip.len() + self.render.len();
        let mut text = format!(
            "resume: {} of {total} frame(s) complete from the same inputs, skipped",
            self.skip.len()
        );
        if !self.skip.is_empty() {
            text.push_str(&format!(" ({})", frame_list(&self.skip)));
        }
        if self.render.is_empty() {
            text.push_str("; nothing to render");
            return text;
        }
        text.push_str(&format!(
            "; rendering {}: {}",
            self.render.len(),
            self.reasons()
        ));
        text
    }

    /// The frames to render grouped by reason: `2 missing (5-6), 1 unreadable (frame 9: ...)`.
    pub fn reasons(&self) -> String {
        let with = |wanted: fn(&RenderReason) -> bool| -> Vec<u32> {
            self.render
                .iter()
                .filter(|(_, reason)| wanted(reason))
                .map(|(frame, _)| *frame)
                .collect()
        };
        let mut groups = Vec::new();
        let missing = with(|r| *r == RenderReason::Missing);
        if !missing.is_empty() {
            groups.push(format!(
                "{} missing ({})",
                missing.len(),
                frame_list(&missing)
            ));
        }
        let differs = with(|r| *r == RenderReason::HashDiffers);
        if !differs.is_empty() {
            groups.push(format!(
                "{} made from other inputs, hash differs ({})",
                differs.len(),
                frame_list(&differs)
            ));
        }
        let stale = with(|r| *r == RenderReason::ReportRowStale);
        if !stale.is_empty() {
            groups.push(format!(
                "{} without a current report row ({})",
                stale.len(),
                frame_list(&stale)
            ));
        }
        let unreadable: Vec<String> = self
            .render
            .iter()
            .filter_map(|(frame, reason)| match reason {
                RenderReason::Unreadable(cause) => Some(format!("frame {frame}: {cause}")),
                _ => None,
            })
            .collect();
        if !unreadable.is_empty() {
            groups.push(format!(
                "{} unreadable ({})",
                unreadable.len(),
                unreadable.join("; ")
            ));
        }
        groups.join(", ")
    }
}

/// What a sequence did.
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceOutcome {
    /// Frames rendered and written by this run, in order.
    pub rendered: Vec<u32>,
    /// Frames left as they were (resume).
    pub skipped: Vec<u32>,
    /// Set when resuming.
    pub plan: Option<ResumePlan>,
    /// A stop request ended the sequence before every frame was done.
    pub interrupted: bool,
    /// Frames of the range neither skipped nor rendered (only after an interruption).
    pub remaining: Vec<u32>,
    /// Wall-clock seconds per rendered frame (0 when none was rendered).
    pub secs_per_frame: f64,
}

impl SequenceOutcome {
    /// Frames of the range that are complete on disk now, sorted.
    pub fn done(&self) -> Vec<u32> {
        let mut done: Vec<u32> = self.skipped.iter().chain(&self.rendered).copied().collect();
        done.sort_unstable();
        done
    }
}

/// `1-3, 7, 9-12`.
pub fn frame_list(frames: &[u32]) -> String {
    if frames.is_empty() {
        return "none".to_string();
    }
    let mut sorted = frames.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut runs: Vec<(u32, u32)> = Vec::new();
    for frame in sorted {
        match runs.last_mut() {
            Some((_, last)) if *last + 1 == frame => *last = frame,
            _ => runs.push((frame, frame)),
        }
    }
    runs.iter()
        .map(|&(first, last)| {
            if first == last {
                first.to_string()
            } else {
                format!("{first}-{last}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether the EXR at `path` is a complete frame `frame` made from `expected` inputs. Reads every
/// pixel: a truncated or corrupted file fails here.
pub fn check_frame_file(path: &Path, frame: u32, expected: &InputHash) -> Result<(), RenderReason> {
    match std::fs::symlink_metadata(path) {
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
            return Err(RenderReason::Missing)
        }
        Err(error) => return Err(RenderReason::Unreadable(error.to_string())),
        Ok(_) => {}
    }
    let (_, meta) = crate::output::read_frame_exr(path)
        .map_err(|error| RenderReason::Unreadable(error.to_string()))?;
    let hash = meta
        .text_attributes
        .iter()
        .find(|(key, _)| key == INPUT_HASH_ATTRIBUTE)
        .map(|(_, value)| value.as_str());
    if meta.frame != frame || hash != Some(expected.hex().as_str()) {
        return Err(RenderReason::HashDiffers);
    }
    Ok(())
}

/// Sorts `frames` in `out_dir` into complete (skip) and to render, checking the EXR
/// files in parallel and each report row's hash.
pub fn plan_resume(
    job: &RenderJob,
    frames: &[u32],
    width: u32,
    height: u32,
    output: &crate::output::pattern::OutputPattern,
    report: &ReportWriter,
) -> ResumePlan {
    let expected = job.input_hash(width, height);
    let frames: Vec<u32> = frames.to_vec();
    let checks: Vec<Result<(), RenderReason>> = frames
        .par_iter()
        .map(|&frame| check_frame_file(&output.path(frame), frame, &expected))
        .collect();
    let mut plan = ResumePlan::default();
    for (frame, check) in frames.into_iter().zip(checks) {
        let check = check.and_then(|()| {
            if report.row_input_hash(frame).as_deref() == Some(expected.hex().as_str()) {
                Ok(())
            } else {
                Err(RenderReason::ReportRowStale)
            }
        });
        match check {
            Ok(()) => plan.skip.push(frame),
            Err(reason) => plan.render.push((frame, reason)),
        }
    }
    plan
}

/// Notes for the user about the output folder (removed leftovers); printed as they come.
fn note(text: &str) {
    errln!("note: {text}");
}

fn paths_list(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

impl RenderJob {
    /// Renders `options.frames` into `options.out_dir`: checks the folder can be written (exit 2
    /// otherwise), removes temporary files that killed processes left there, skips complete frames
    /// when resuming, and stops early on a stop request. Each frame's EXR (and PNG) is written
    /// before its report row, each renamed into place whole.
    pub fn render_sequence(
        &self,
        options: &SequenceOptions<'_>,
    ) -> Result<SequenceOutcome, SnellError> {
        let SequenceOptions {
            frames,
            width,
            height,
            output,
            write_png,
            progress,
            log,
            resume,
            stop,
        } = *options;
        self.check_frame_resources(width, height)?;
        let out_dir = output.dir();
        crate::output::ensure_output_dir(out_dir)?;
        crate::output::check_writable(out_dir)?;
        let stale =
            crate::output::temporary::remove_stale(out_dir, crate::sim::checkpoint::CHECKPOINT_DIR);
        if !stale.is_empty() {
            note(&format!(
                "removed {} temporary file(s) left by a render that was killed: {}",
                stale.len(),
                paths_list(&stale)
            ));
        }
        if let Some(text) = self.use_checkpoints(out_dir)? {
            note(&text);
        }
        let report = ReportWriter::create(out_dir)?;
        let plan = resume.then(|| plan_resume(self, frames, width, height, output, &report));
        let (to_render, skipped): (Vec<u32>, Vec<u32>) = match &plan {
            Some(plan) => {
                errln!("{}", plan.summary());
                (
                    plan.render.iter().map(|(frame, _)| *frame).collect(),
                    plan.skip.clone(),
                )
            }
            None => (frames.to_vec(), Vec::new()),
        };
        let stop_requested = || stop.is_some_and(|flag| flag.load(Ordering::SeqCst));
        let mut rendered = Vec::new();
        let mut interrupted = false;
        let started = Instant::now();
        if !to_render.is_empty() {
            // The ray-traced methods render on the CPU: no GPU needed (nor set up).
            let mut renderer = if self.method.uses_gpu() {
                let mut renderer = Renderer::new()?;
                renderer.set_strip_rows(self.strip_rows);
                self.upload_textures(&mut renderer)?;
                Some(renderer)
            } else {
                None
            };
            let bar = super::progress_bar(to_render.len() as u64, progress);
            // Frames are encoded and written on threads of their own while the next ones are
            // refracted and rendered (see writer.rs), strip by strip as the GPU reads them back
            // (a frame small enough to read back at once is one strip). The queue between holds
            // at most two frames' layers, or 256 MiB of strips (or one larger strip), so memory
            // stays flat however long the sequence; the report row of a frame is appended only
            // after its EXR is safely renamed into place.
            let (sender, receiver) =
                super::queue::byte_channel::<ToWriter>(super::queue::capacity_for(width, height));
            let written = std::thread::scope(|scope| {
                let writer = scope
                    .spawn(move || super::writer::write_frames(receiver, report, write_png, log));
                let mut render_error = None;
                // Set when the writer stopped (on an error of its own, returned below).
                let mut writer_stopped = false;
                // The tracking of the frame rendered last, for the next frame's popping test.
                let mut last: Option<(u32, VertexTracking)> = None;
                for &frame in &to_render {
                    if stop_requested() {
                        interrupted = true;
                        break;
                    }
                    bar.set_message(format!("frame {frame}"));
                    let previous = match last.take() {
                        Some((last_frame, tracking)) if last_frame + 1 == frame => {
                            Ok(Some(tracking))
                        }
                        // After a skipped frame (or at the start): frame - 1 recomputed, so
                        // the frame is judged exactly as in an uninterrupted run.
                        _ => self.previous_tracking(frame, width, height),
                    };
                    let result = previous.and_then(|previous| {
                        let mut refracted =
                            self.refract(frame, width, height, previous.as_ref())?;
                        let mut start = Some(Box::new(FrameStart {
                            path: output.path(frame),
                            meta: self.frame_meta(&refracted),
                            width,
                            height,
                        }));
                        let mut send = |message: ToWriter| {
                            let bytes = message.bytes();
                            sender.send(message, bytes).map_err(|_| {
                                writer_stopped = true;
                                SnellError::Internal {
                                    frame: Some(frame),
                                    message: "the frame writer stopped".to_string(),
                                }
                            })
                        };
                        self.render_refracted_strips(
                            renderer.as_mut(),
                            &mut refracted,
                            width,
                            height,
                            &mut |first_row, strip| {
                                if let Some(start) = start.take() {
                                    send(ToWriter::Start(start))?;
                                }
                                send(ToWriter::Strip(first_row, Box::new(strip)))
                            },
                        )?;
                        send(ToWriter::Done(Box::new(
                            self.frame_report(&refracted, width, height),
                        )))?;
                        Ok(refracted)
                    });
                    let refracted = match result {
                        Ok(done) => done,
                        Err(error) => {
                            if !writer_stopped {
                                render_error = Some(error);
                            }
                            break;
                        }
                    };
                    last = Some((frame, refracted.tracking));
                    rendered.push(frame);
                    bar.inc(1);
                }
                drop(sender);
                let written = writer.join().unwrap_or_else(|payload| {
                    Err(SnellError::Internal {
                        frame: None,
                        message: format!(
                            "the frame writer failed: {}",
                            crate::panics::describe(payload.as_ref())
                        ),
                    })
                });
                match render_error {
                    Some(error) => Err(error),
                    None => written,
                }
            });
            bar.finish_and_clear();
            written?;
        }
        let secs = started.elapsed().as_secs_f64();
        let remaining: Vec<u32> = to_render
            .iter()
            .copied()
            .filter(|frame| !rendered.contains(frame))
            .collect();
        Ok(SequenceOutcome {
            secs_per_frame: if rendered.is_empty() {
                0.0
            } else {
                secs / rendered.len() as f64
            },
            rendered,
            skipped,
            plan,
            interrupted,
            remaining,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_log_line_gives_frame_seconds_and_flag_counts() {
        let report = crate::output::report::FrameReport {
            frame: 12,
            time_secs: 0.5,
            convergence_policy: String::new(),
            counts: serde_json::json!({ "vertices": { "convergence": 3, "popping": 1 }, "triangles": { "boundary": 2 } }),
            stage_secs: [("render".to_string(), 0.5), ("write".to_string(), 0.25)].into(),
            size: [64, 36],
            method: "m".into(),
            input_hash: None,
            quality: None,
        };
        let path = Path::new("out/tiny.0012.exr");
        assert_eq!(FrameLog::Quiet.line(path, &report), None);
        assert_eq!(
            FrameLog::Text.line(path, &report).unwrap(),
            "frame 12: 0.75 s, out/tiny.0012.exr; vertices: convergence 3, popping 1; triangles: boundary 2"
        );
        let json: serde_json::Value =
            serde_json::from_str(&FrameLog::Json.line(path, &report).unwrap()).unwrap();
        assert_eq!(
            json,
            serde_json::json!({ "frame": 12, "secs": 0.75, "path": "out/tiny.0012.exr", "counts": report.counts })
        );
    }

    #[test]
    fn frame_lists_are_compact() {
        assert_eq!(frame_list(&[]), "none");
        assert_eq!(frame_list(&[3]), "3");
        assert_eq!(frame_list(&[1, 2, 3, 7, 9, 10, 11, 12]), "1-3, 7, 9-12");
        assert_eq!(frame_list(&[5, 4, 4, 1]), "1, 4-5");
    }

    #[test]
    fn the_plan_summary_counts_skips_and_says_why_others_render() {
        let plan = ResumePlan {
            skip: vec![1, 2, 3],
            render: vec![
                (4, RenderReason::HashDiffers),
                (
                    5,
                    RenderReason::Unreadable("OpenEXR decoding: truncated".into()),
                ),
                (6, RenderReason::Missing),
                (7, RenderReason::Missing),
                (8, RenderReason::ReportRowStale),
            ],
        };
        assert_eq!(
            plan.summary(),
            "resume: 3 of 8 frame(s) complete from the same inputs, skipped (1-3); rendering 5: \
             2 missing (6-7), 1 made from other inputs, hash differs (4), 1 without a current \
             report row (8), 1 unreadable (frame 5: OpenEXR decoding: truncated)"
        );
        let done = ResumePlan {
            skip: vec![1, 2],
            render: vec![],
        };
        assert_eq!(
            done.summary(),
            "resume: 2 of 2 frame(s) complete from the same inputs, skipped (1-2); nothing to render"
        );
    }

    #[test]
    fn a_missing_or_garbage_file_is_told_apart() {
        let dir = tempfile::tempdir().unwrap();
        let hash = InputHash([7; 32]);
        let path = dir.path().join("pool.0001.exr");
        assert_eq!(
            check_frame_file(&path, 1, &hash),
            Err(RenderReason::Missing)
        );
        std::fs::write(&path, b"not an exr").unwrap();
        assert!(matches!(
            check_frame_file(&path, 1, &hash),
            Err(RenderReason::Unreadable(cause)) if cause.contains("pool.0001.exr")
        ));
    }
}
