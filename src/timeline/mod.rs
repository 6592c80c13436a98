//! Stage 1, timeline: frame numbers <-> seconds, and keyframe tracks sampled at a time (the camera,
//! characters' root paths).
//! Receives the scene's frame rate, frame range and camera keys; returns times and [`crate::camera::Camera`]s.

use glam::Vec3;

mod camera_track;
mod root_path;

pub use camera_track::{CameraTrack, CameraTrackError};
pub use root_path::{RootKey, RootPath};

/// Frame range and rate. Frame `first_frame` is at t = 0: `time_secs(f) = (f - first_frame) / fps`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timeline {
    pub fps: f64,
    pub first_frame: u32,
    pub last_frame: u32,
}

/// Where a scene's camera comes from, ready to be sampled at a time.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraMotion {
    /// `[[camera]]` keyframes.
    Keys(CameraTrack),
    /// A glTF file's camera node, animated by the file: timeline time + `time_offset_secs` is the
    /// animation's time.
    Gltf {
        camera: std::sync::Arc<crate::character::GltfCamera>,
        time_offset_secs: f64,
    },
}

impl CameraMotion {
    /// The camera at `time_secs` of the timeline.
    pub fn sample(&self, time_secs: f64) -> crate::camera::Camera {
        match self {
            CameraMotion::Keys(track) => track.sample(time_secs),
            CameraMotion::Gltf {
                camera,
                time_offset_secs,
            } => camera.camera_at(time_secs + time_offset_secs),
        }
    }
}

/// A camera keyframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKey {
    pub time_secs: f64,
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_y_deg: f32,
}

/// A `--frames` value that is not a frame range, or a range outside the scene's timeline.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum FrameRangeError {
    #[error("frame range {input:?}: {reason}; write a frame \"N\" or a range \"A-B\" with A <= B, e.g. \"0-47\" (a list takes commas and steps, e.g. \"1-48x4,50\")")]
    Malformed { input: String, reason: String },
    #[error(
        "frames {first}-{last} are outside the scene's timeline {timeline_first}-{timeline_last}"
    )]
    OutsideTimeline {
        first: u32,
        last: u32,
        timeline_first: u32,
        timeline_last: u32,
    },
}

/// Parses `"A-B"` (inclusive) or `"N"` (= `"N-N"`) into (first, last). Spaces around the numbers
/// are allowed; negative numbers, `A > B`, and anything else are errors that quote the input.
pub fn parse_frame_range(input: &str) -> Result<(u32, u32), FrameRangeError> {
    let malformed = |reason: String| FrameRangeError::Malformed {
        input: input.to_string(),
        reason,
    };
    let number = |text: &str, which: &str| -> Result<u32, FrameRangeError> {
        let text = text.trim();
        if text.is_empty() {
            return Err(malformed(format!("the {which}frame is missing")));
        }
        text.parse::<u32>().map_err(|cause| {
            malformed(format!(
                "the {which}frame {text:?} is not a frame number ({cause})"
            ))
        })
    };
    let (first, last) = match input.split_once('-') {
        Some((first, last)) => (number(first, "first ")?, number(last, "last ")?),
        None => {
            let frame = number(input, "")?;
            (frame, frame)
        }
    };
    if first > last {
        return Err(malformed(format!(
            "the first frame {first} comes after the last frame {last}"
        )));
    }
    Ok((first, last))
}

/// Parses a frame list: items separated by commas, each a frame `N`, a range `A-B` or a range
/// with a step `A-BxS` (A, A+S, ... up to B), e.g. `1-48x4,50`. Returns the frames sorted, each
/// once. An error names the item at fault and what is wrong with it.
pub fn parse_frame_list(input: &str) -> Result<Vec<u32>, FrameRangeError> {
    let malformed = |reason: String| FrameRangeError::Malformed {
        input: input.to_string(),
        reason,
    };
    let mut frames = Vec::new();
    for (index, item) in input.split(',').enumerate() {
        let item = item.trim();
        let which = if input.contains(',') {
            format!("item {} ({item:?})", index + 1)
        } else {
            format!("{item:?}")
        };
        if item.is_empty() {
            return Err(malformed(format!(
                "item {} is empty (two commas in a row, or one at an end)",
                index + 1
            )));
        }
        let (range, step) = match item.split_once('x') {
            Some((range, step)) => {
                let step = step.trim();
                let step: u32 = step.parse().map_err(|_| {
                    malformed(format!(
                        "{which}: the step {step:?} after `x` is not a whole number of frames"
                    ))
                })?;
                if step == 0 {
                    return Err(malformed(format!("{which}: the step must be at least 1")));
                }
                if !range.contains('-') {
                    return Err(malformed(format!(
                        "{which}: a step needs a range before it, as in 1-48x4"
                    )));
                }
                (range, step)
            }
            None => (item, 1),
        };
        let (first, last) = parse_frame_range(range).map_err(|error| match error {
            FrameRangeError::Malformed { reason, .. } => malformed(format!("{which}: {reason}")),
            other => other,
        })?;
        frames.extend((first..=last).step_by(step as usize));
    }
    frames.sort_unstable();
    frames.dedup();
    Ok(frames)
}

impl Timeline {
    /// Seconds from the first frame to `frame` (negative before it).
    pub fn time_secs(&self, frame: u32) -> f64 {
        (frame as f64 - self.first_frame as f64) / self.fps
    }

    /// Every frame of the timeline, first to last inclusive.
    pub fn frames(&self) -> std::ops::RangeInclusive<u32> {
        self.first_frame..=self.last_frame
    }

    pub fn contains(&self, frame: u32) -> bool {
        self.frames().contains(&frame)
    }

    pub fn frame_count(&self) -> u32 {
        self.last_frame.saturating_sub(self.first_frame)
            + u32::from(self.last_frame >= self.first_frame)
    }

    /// The same timeline (same rate, same t = 0 at `first_frame`) rendering only `first..=last`,
    /// which must lie inside it. Times of the kept frames are unchanged.
    pub fn frames_to_render(
        &self,
        (first, last): (u32, u32),
    ) -> Result<std::ops::RangeInclusive<u32>, FrameRangeError> {
        if !self.contains(first) || !self.contains(last) {
            return Err(FrameRangeError::OutsideTimeline {
                first,
                last,
                timeline_first: self.first_frame,
                timeline_last: self.last_frame,
            });
        }
        Ok(first..=last)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_lists_take_ranges_steps_and_single_frames() {
        assert_eq!(parse_frame_list("1-48x4,50").unwrap(), {
            let mut expected: Vec<u32> = (1..=45).step_by(4).collect();
            expected.push(50);
            expected
        });
        assert_eq!(parse_frame_list("7").unwrap(), vec![7]);
        assert_eq!(parse_frame_list("3-5").unwrap(), vec![3, 4, 5]);
        assert_eq!(parse_frame_list(" 9, 1-3 ,2").unwrap(), vec![1, 2, 3, 9]);
        assert_eq!(parse_frame_list("1-10x3").unwrap(), vec![1, 4, 7, 10]);
        assert_eq!(parse_frame_list("1-2x5").unwrap(), vec![1]);
        let message = |input: &str| parse_frame_list(input).unwrap_err().to_string();
        assert!(
            message("1,,3").contains("item 2 is empty"),
            "{}",
            message("1,,3")
        );
        assert!(message("1-9x0").contains("\"1-9x0\": the step must be at least 1"));
        assert!(message("1-9x").contains("the step \"\" after `x` is not a whole number"));
        assert!(message("4x2").contains("a step needs a range before it"));
        assert!(
            message("1,5-3")
                .contains("item 2 (\"5-3\"): the first frame 5 comes after the last frame 3"),
            "{}",
            message("1,5-3")
        );
        assert!(message("1,a").contains("item 2 (\"a\"): the frame \"a\" is not a frame number"));
    }

    #[test]
    fn frames_map_to_seconds_from_the_first_frame() {
        let timeline = Timeline {
            fps: 24.0,
            first_frame: 10,
            last_frame: 57,
        };
        assert_eq!(timeline.time_secs(10), 0.0);
        assert_eq!(timeline.time_secs(34), 1.0);
        assert_eq!(timeline.time_secs(4), -0.25);
        assert_eq!(timeline.frames().count(), 48);
        assert_eq!(timeline.frame_count(), 48);
        assert_eq!(timeline.frames().next(), Some(10));
        assert_eq!(timeline.frames().last(), Some(57));
        assert!(timeline.contains(10) && timeline.contains(57));
        assert!(!timeline.contains(9) && !timeline.contains(58));
    }

    #[test]
    fn frame_ranges_parse() {
        assert_eq!(parse_frame_range("0-47"), Ok((0, 47)));
        assert_eq!(parse_frame_range(" 3 - 5 "), Ok((3, 5)));
        assert_eq!(parse_frame_range("12"), Ok((12, 12)));
        assert_eq!(parse_frame_range("7-7"), Ok((7, 7)));
    }

    #[test]
    fn malformed_frame_ranges_say_what_is_wrong_and_how_to_write_one() {
        let message = |input: &str| parse_frame_range(input).unwrap_err().to_string();
        let reversed = message("9-3");
        assert!(
            reversed.contains("\"9-3\"") && reversed.contains("comes after"),
            "{reversed}"
        );
        assert!(reversed.contains("A-B"), "{reversed}");
        assert!(message("").contains("missing"));
        assert!(message("-4").contains("first frame is missing"));
        assert!(message("4-").contains("last frame is missing"));
        assert!(message("a-4").contains("\"a\" is not a frame number"));
        assert!(message("1-2-3").contains("not a frame number"));
        assert!(message("1.5").contains("not a frame number"));
        assert!(message("99999999999").contains("not a frame number"));
    }

    #[test]
    fn rendered_frames_must_lie_in_the_timeline() {
        let timeline = Timeline {
            fps: 30.0,
            first_frame: 0,
            last_frame: 47,
        };
        assert_eq!(timeline.frames_to_render((5, 9)), Ok(5..=9));
        let error = timeline.frames_to_render((40, 60)).unwrap_err();
        assert_eq!(
            error.to_string(),
            "frames 40-60 are outside the scene's timeline 0-47"
        );
    }
}
