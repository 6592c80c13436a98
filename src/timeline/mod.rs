//! Stage 1, timeline: frame numbers <-> seconds, and keyframe tracks sampled at a time (the camera).
//! OWNER: water/timeline helper.

use glam::Vec3;

/// Frame range and rate. Frame `first_frame` is at t = 0: `time_secs(f) = (f - first_frame) / fps`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timeline {
    pub fps: f64,
    pub first_frame: u32,
    pub last_frame: u32,
}

/// A camera keyframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKey {
    pub time_secs: f64,
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_y_deg: f32,
}
