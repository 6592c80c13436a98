//! Temporal stability of a method against the reference between two consecutive frames. Receives
//! the reference's and the method's renders of frames t and t+1; returns, per tracked surface point,
//! how differently the method moves it on screen than the truth does:
//! |Δx_method − Δx_reference| in pixels, as mean, p99 and max.
//!
//! A tracked point is the world point X (`P`) that a pixel of the reference at frame t sees on an
//! object that does not move between the frames (the scene's static objects; a character's `P` at
//! t+1 is another material point). Δx_reference is where the reference sees X at t+1 minus that
//! pixel; Δx_method is where the method sees X at t+1 minus where it sees X at t (each the image
//! nearest the previous place, found with [`PositionMap::place_of`]: the whole frame, no window).
//! A point that one of the four frames does not show is not tracked. A method that flickers where
//! the truth moves smoothly shows here even when each frame on its own is close to the truth.

use rayon::prelude::*;

use crate::draw::{RenderedFrame, NO_OBJECT};
use crate::output::compare::percentile_of_sorted;
use crate::output::position_error::PositionMap;

/// |Δx_method − Δx_reference| over the tracked points.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TemporalError {
    pub mean_px: f64,
    pub p99_px: f64,
    pub max_px: f64,
    /// Points tracked through all four frames.
    pub points: usize,
}

/// The four frames [`temporal_error`] compares; all of one size, with `P` and object layers (the
/// caller has compared them with [`crate::output::position_error::compare_positions`], which checks
/// that).
pub struct FramePair<'f> {
    pub reference: [&'f RenderedFrame; 2],
    pub method: [&'f RenderedFrame; 2],
}

/// See the module documentation. `tracked(object)` says which object ids do not move between the
/// two frames.
pub fn temporal_error(
    frames: &FramePair<'_>,
    tracked: impl Fn(u32) -> bool + Sync,
) -> TemporalError {
    let [reference_0, reference_1] = frames.reference;
    let [method_0, method_1] = frames.method;
    let pixels = reference_0.width as usize * reference_0.height as usize;
    let sized = |f: &RenderedFrame| f.object.len() == pixels && f.position.len() == pixels;
    if pixels == 0
        || ![reference_1, method_0, method_1].iter().all(|f| sized(f))
        || !sized(reference_0)
    {
        return TemporalError::default();
    }
    let (maps_reference, maps_method) = rayon::join(
        || PositionMap::build(reference_1),
        || {
            rayon::join(
                || PositionMap::build(method_0),
                || PositionMap::build(method_1),
            )
        },
    );
    let (method_map_0, method_map_1) = maps_method;
    let width = reference_0.width as usize;
    let mut differences: Vec<f32> = (0..pixels)
        .into_par_iter()
        .filter_map(|index| {
            let object = reference_0.object[index];
            let point = reference_0.position[index];
            if object == NO_OBJECT || !tracked(object) || !point.iter().all(|c| c.is_finite()) {
                return None;
            }
            let here = [(index % width) as f64, (index / width) as f64];
            let truth = maps_reference.place_of(point, object, here)?;
            let before = method_map_0.place_of(point, object, here)?;
            let after = method_map_1.place_of(point, object, before.screen)?;
            if !(truth.seen && before.seen && after.seen) {
                return None;
            }
            let true_motion = [truth.screen[0] - here[0], truth.screen[1] - here[1]];
            let method_motion = [
                after.screen[0] - before.screen[0],
                after.screen[1] - before.screen[1],
            ];
            Some(
                (method_motion[0] - true_motion[0]).hypot(method_motion[1] - true_motion[1]) as f32,
            )
        })
        .collect();
    if differences.is_empty() {
        return TemporalError::default();
    }
    // Sorted first so the sum does not depend on thread timing.
    differences.sort_by(f32::total_cmp);
    TemporalError {
        mean_px: differences.iter().map(|&d| d as f64).sum::<f64>() / differences.len() as f64,
        p99_px: percentile_of_sorted(&differences, 0.99) as f64,
        max_px: *differences.last().expect("not empty") as f64,
        points: differences.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FLOOR: u32 = 1;
    const FOX: u32 = 2;

    /// A frame seeing a plane (1 cm per pixel, face-on) shifted by `offset` pixels: pixel (x, y)
    /// sees the plane's point (x + offset.0, y + offset.1). Columns from 40 on see the moving
    /// object `FOX` instead.
    fn frame(offset: (f64, f64)) -> RenderedFrame {
        let (width, height) = (64u32, 24u32);
        let pixels = (width * height) as usize;
        let mut frame = RenderedFrame {
            width,
            height,
            beauty_rgba: vec![[0.5, 0.5, 0.5, 1.0]; pixels],
            depth_m: vec![2.0; pixels],
            position: Vec::with_capacity(pixels),
            flags: vec![0; pixels],
            object: Vec::with_capacity(pixels),
            ..Default::default()
        };
        for y in 0..height {
            for x in 0..width {
                let (px, py) = (x as f64 + offset.0, y as f64 + offset.1);
                frame
                    .position
                    .push([(0.01 * px) as f32, (0.01 * py) as f32, 2.0]);
                frame.object.push(if x >= 40 { FOX } else { FLOOR });
            }
        }
        frame
    }

    fn error(reference: [(f64, f64); 2], method: [(f64, f64); 2]) -> TemporalError {
        let (r0, r1) = (frame(reference[0]), frame(reference[1]));
        let (m0, m1) = (frame(method[0]), frame(method[1]));
        temporal_error(
            &FramePair {
                reference: [&r0, &r1],
                method: [&m0, &m1],
            },
            |object| object == FLOOR,
        )
    }

    /// The truth moves the floor 1 px left per frame (pixel x sees at t+1 what x+1 saw at t); a
    /// method that lags 0.3 px at t and moves 1.5 px differs by 0.5 px at every tracked point;
    /// one that moves exactly with the truth, whatever its constant offset, by 0.
    #[test]
    fn a_method_moving_differently_from_the_truth_measures_the_difference() {
        let truth = [(0.0, 0.0), (1.0, 0.0)];
        let steady = error(truth, [(0.3, 0.0), (1.3, 0.0)]);
        assert!(steady.points > 500, "{steady:?}");
        assert!(steady.max_px < 1e-3, "{steady:?}");
        let jumpy = error(truth, [(0.3, 0.0), (1.8, 0.0)]);
        assert!((jumpy.mean_px - 0.5).abs() < 1e-3, "{jumpy:?}");
        assert!((jumpy.p99_px - 0.5).abs() < 1e-3, "{jumpy:?}");
        // Sideways error of the same size.
        let sideways = error(truth, [(0.0, 0.0), (1.0, 0.4)]);
        assert!((sideways.p99_px - 0.4).abs() < 1e-3, "{sideways:?}");
    }

    /// Only points of tracked (static) objects that every frame shows are counted: the moving
    /// object's columns never, the floor's points that leave the frame not.
    #[test]
    fn only_points_seen_in_all_four_frames_of_static_objects_count() {
        let truth = [(0.0, 0.0), (1.0, 0.0)];
        let tracked = error(truth, truth);
        // Floor columns 0..40 at t; at t+1 the floor shows points 1..41 in columns 0..40, so
        // column 0's point (x = 0) is gone: 39 columns x 24 rows remain.
        assert_eq!(tracked.points, 39 * 24, "{tracked:?}");
        assert_eq!(tracked.max_px, 0.0);
    }
}
