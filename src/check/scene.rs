//! Golden checks of a scene: receives a prepared [`RenderJob`], frame numbers, a size, a golden
//! directory and a work directory; renders the frames into the work directory exactly as
//! `snell render` does ([`RenderJob::render_to_dir`]) and either compares each with
//! `GOLDEN/<scene>.NNNN.exr` through [`super::compare_pairs`] (a missing golden fails) or blesses
//! them (copies them atomically into the golden directory). `snell check` and the project's own
//! golden tests both come through here.

use std::path::{Path, PathBuf};

use super::{compare_pairs, CheckError, DiffReport, FramePair, Thresholds};
use crate::frame::{FrameRange, RenderJob};
use crate::output::exr::frame_path;

/// The size used when neither `--size` nor an existing golden gives one: small enough that a CI
/// machine without a GPU renders a frame in about a second (the pool at 320x180 on lavapipe),
/// large enough that a misplaced object covers many pixels.
pub const DEFAULT_CHECK_SIZE: (u32, u32) = (320, 180);

/// What to check: the frames of `job` at `size`, goldens in `golden_dir`, renders in `work_dir`.
pub struct SceneCheck<'a> {
    pub job: &'a RenderJob,
    /// Frame numbers, in any order (rendered in increasing order, consecutive runs together).
    pub frames: Vec<u32>,
    pub size: (u32, u32),
    pub golden_dir: &'a Path,
    /// Where the frames are rendered (with the report and simulation checkpoints); never the
    /// golden directory.
    pub work_dir: &'a Path,
    pub thresholds: Thresholds,
    pub progress: bool,
}

impl SceneCheck<'_> {
    pub fn golden_path(&self, frame: u32) -> PathBuf {
        frame_path(self.golden_dir, self.job.scene_name(), frame)
    }

    pub fn rendered_path(&self, frame: u32) -> PathBuf {
        frame_path(self.work_dir, self.job.scene_name(), frame)
    }

    fn sorted_frames(&self) -> Vec<u32> {
        let mut frames = self.frames.clone();
        frames.sort_unstable();
        frames.dedup();
        frames
    }

    fn same_dirs(&self) -> bool {
        let canonical = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
        canonical(self.golden_dir) == canonical(self.work_dir)
    }

    /// Renders the frames into the work directory: each run of consecutive frames in one
    /// [`RenderJob::render_to_dir`] (popping judged against the frame before, ripples stepped
    /// through checkpoints), exactly as `snell render` would.
    pub fn render(&self) -> Result<(), CheckError> {
        if self.same_dirs() {
            return Err(CheckError::Argument(format!(
                "the work directory {} is the golden directory: renders would overwrite the goldens; choose another --out",
                self.work_dir.display()
            )));
        }
        let frames = self.sorted_frames();
        // A frame left from an earlier run must not stand in for one this run failed to write.
        for &frame in &frames {
            let _ = std::fs::remove_file(self.rendered_path(frame));
        }
        let (width, height) = self.size;
        let mut start = 0;
        while start < frames.len() {
            let mut end = start;
            while end + 1 < frames.len() && frames[end + 1] == frames[end] + 1 {
                end += 1;
            }
            let range = FrameRange {
                first: frames[start],
                last: frames[end],
            };
            self.job
                .render_to_dir(range, width, height, self.work_dir, false, self.progress)?;
            start = end + 1;
        }
        Ok(())
    }

    /// Renders and compares every frame with its golden. Heat maps of frames that warn or fail
    /// go to `heatmap_dir`.
    pub fn check(&self, heatmap_dir: Option<&Path>) -> Result<DiffReport, CheckError> {
        self.thresholds.validate()?;
        self.render()?;
        let pairs: Vec<FramePair> = self
            .sorted_frames()
            .into_iter()
            .map(|frame| {
                let golden = self.golden_path(frame);
                FramePair {
                    name: golden
                        .file_name()
                        .map(|n| n.to_string_lossy().into_owned())
                        .unwrap_or_default(),
                    reference: golden,
                    test: self.rendered_path(frame),
                    missing_reference_hint: format!(
                        " (no golden yet: look at the render {}, then write the golden with \
                         `snell check {} --golden {} --frames {frame} --size {}x{} --bless`)",
                        self.rendered_path(frame).display(),
                        self.job.scene.path.display(),
                        self.golden_dir.display(),
                        self.size.0,
                        self.size.1
                    ),
                }
            })
            .collect();
        Ok(compare_pairs(&pairs, &self.thresholds, heatmap_dir))
    }

    /// Renders the frames and (re)writes them as the goldens, each atomically. Returns the
    /// goldens written.
    pub fn bless(&self) -> Result<Vec<PathBuf>, CheckError> {
        self.render()?;
        let mut written = Vec::new();
        for frame in self.sorted_frames() {
            let rendered = self.rendered_path(frame);
            let bytes =
                std::fs::read(&rendered).map_err(|error| crate::output::OutputError::Read {
                    path: rendered.clone(),
                    cause: error.to_string(),
                })?;
            let golden = self.golden_path(frame);
            crate::output::write_atomically(&golden, |file| {
                use std::io::Write;
                file.write_all(&bytes).map_err(|error| error.to_string())
            })?;
            written.push(golden);
        }
        Ok(written)
    }
}

/// The size to check at: `requested` (`--size`) if given; otherwise the size of the first of
/// `frames` whose golden exists (so a check matches the goldens it is given); otherwise
/// [`DEFAULT_CHECK_SIZE`].
pub fn choose_size(
    requested: Option<(u32, u32)>,
    golden_dir: &Path,
    scene_name: &str,
    frames: &[u32],
) -> Result<(u32, u32), CheckError> {
    if let Some(size) = requested {
        return Ok(size);
    }
    for &frame in frames {
        let path = frame_path(golden_dir, scene_name, frame);
        if path.exists() {
            return exr_size(&path);
        }
    }
    Ok(DEFAULT_CHECK_SIZE)
}

/// The data window size of an EXR file, read from its header only.
pub fn exr_size(path: &Path) -> Result<(u32, u32), CheckError> {
    let read_error = |cause: String| {
        CheckError::Output(crate::output::OutputError::Read {
            path: path.to_path_buf(),
            cause,
        })
    };
    let meta = ::exr::meta::MetaData::read_from_file(path, false)
        .map_err(|error| read_error(format!("OpenEXR header: {error}")))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| read_error("OpenEXR header: no layer".into()))?;
    let size = header.layer_size;
    Ok((size.width() as u32, size.height() as u32))
}
