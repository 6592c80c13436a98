//! Camera keyframes: times, positions and targets in order, and the interpolated views checked.

use super::*;

pub(super) fn camera_keys(
    raw: Option<&[RawCameraKey]>,
    timeline: &Timeline,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<Vec<CameraKey>> {
    let path = KeyPath::root().key("camera");
    let Some(raw) = raw.filter(|keys| !keys.is_empty()) else {
        // Standing on the deck at the middle of one long side, looking across and down.
        let [x0, z0] = water.min_xz;
        let [x1, z1] = water.max_xz;
        let eye = Vec3::new(
            (0.5 * (x0 + x1)) as f32,
            (water.level_m + 2.2) as f32,
            (z0 - 1.5) as f32,
        );
        let target = Vec3::new(
            (0.5 * (x0 + x1)) as f32,
            (water.level_m - 1.2) as f32,
            (0.25 * z0 + 0.75 * z1) as f32,
        );
        return Ok(vec![CameraKey {
            time_secs: 0.0,
            eye,
            target,
            fov_y_deg: DEFAULT_FOV_DEG as f32,
        }]);
    };
    let crest_m = water.level_m + water.max_crest_m();
    let mut keys: Vec<CameraKey> = Vec::with_capacity(raw.len());
    for (i, key) in raw.iter().enumerate() {
        let at = path.index(i);
        let time_secs = keyframe_time(
            (key.frame, key.time_secs),
            keys.last().map(|k| k.time_secs),
            KeyList {
                noun: "camera",
                table: "[[camera]]",
                count: raw.len(),
            },
            &at,
            timeline,
            map,
        )?;
        let eye = key.eye.map(|v| v as f32);
        let target = key.target.map(|v| v as f32);
        if key.eye[1] <= crest_m {
            return Err(map.error(
                &at.key("eye"),
                format!(
                    "the eye is under the water (y = {} m; the surface reaches {crest_m} m at its highest \
                     crest); snell renders from the air",
                    key.eye[1]
                ),
                format!("raise it, e.g. eye = [{}, {}, {}]", key.eye[0], water.level_m + 2.0, key.eye[2]),
            ));
        }
        if Vec3::from(eye).distance(Vec3::from(target)) < 1e-4 {
            return Err(map.error(
                &at.key("target"),
                "the target is at the eye",
                "look at a point away from the eye",
            ));
        }
        let fov_deg = key.fov_deg.unwrap_or(DEFAULT_FOV_DEG);
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(map.error(
                &at.key("fov_deg"),
                format!(
                    "the vertical field of view must be between 0 and 180 degrees (got {fov_deg})"
                ),
                "set e.g. fov_deg = 50",
            ));
        }
        keys.push(CameraKey {
            time_secs,
            eye: eye.into(),
            target: target.into(),
            fov_y_deg: fov_deg as f32,
        });
    }
    check_interpolated_views(&keys, timeline, &path, map)?;
    Ok(keys)
}

/// The camera between keys is interpolated (eye and target separately): at no frame may the eye
/// come onto its target, where the view has no direction. Straight up or down is fine (the camera
/// has a stated fallback up vector). Every frame of the timeline is sampled, as a render would.
pub(super) fn check_interpolated_views(
    keys: &[CameraKey],
    timeline: &Timeline,
    path: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<()> {
    let track = crate::timeline::CameraTrack::try_new(keys.to_vec()).map_err(|error| {
        map.error(
            path,
            format!("the camera keys cannot be interpolated: {error}"),
            "",
        )
    })?;
    for frame in timeline.first_frame..=timeline.last_frame {
        let time_secs = timeline.time_secs(frame);
        let camera = track.sample(time_secs);
        if camera.eye.distance(camera.target) >= 1e-4 {
            continue;
        }
        // The key that ends the segment (or the last key).
        let after = keys
            .iter()
            .position(|key| key.time_secs >= time_secs)
            .unwrap_or(keys.len() - 1);
        let before = after.saturating_sub(1);
        return Err(map.error(
            &path.index(after).key("target"),
            format!(
                "between camera keys {before} and {after} the interpolated eye reaches the target at frame {frame} \
                 (t = {time_secs:.3} s, eye {:?}): the view has no direction there",
                camera.eye.to_array()
            ),
            "move the keys' targets so the eye passes beside them, or add a key in between",
        ));
    }
    Ok(())
}

/// A list of keyframes, for [`keyframe_time`]'s messages.
pub(super) struct KeyList {
    /// "camera", "root-path".
    pub(super) noun: &'static str,
    /// The TOML tables the keys are written as.
    pub(super) table: &'static str,
    pub(super) count: usize,
}

/// A keyframe's time in seconds from `frame` or `time_secs` (a key alone in its list may have
/// neither: t = 0), checked to come after the previous key's time.
pub(super) fn keyframe_time(
    (frame, time_secs): (Option<f64>, Option<f64>),
    previous_secs: Option<f64>,
    list: KeyList,
    at: &KeyPath,
    timeline: &Timeline,
    map: &SourceMap<'_>,
) -> Result<f64> {
    let (time_secs, time_key) = match (frame, time_secs) {
        (Some(_), Some(_)) => {
            return Err(map.error(
                &at.key("time_secs"),
                "both frame and time_secs are given",
                "keep one of them",
            ))
        }
        (Some(frame), None) => (
            (frame - timeline.first_frame as f64) / timeline.fps,
            "frame",
        ),
        (None, Some(t)) => (t, "time_secs"),
        (None, None) if list.count == 1 => return Ok(0.0),
        (None, None) => {
            return Err(map.error(
                at,
                format!(
                    "a {} keyframe needs a time when there are several",
                    list.noun
                ),
                "add frame = N or time_secs = T",
            ))
        }
    };
    match previous_secs {
        Some(previous) if time_secs <= previous => Err(map.error(
            &at.key(time_key),
            format!(
                "{} keyframes are out of order: this one is at {time_secs:.3} s, the one before it \
                 at {previous:.3} s; keys must be in increasing time order",
                list.noun
            ),
            format!("reorder the {} tables or correct this time", list.table),
        )),
        _ => Ok(time_secs),
    }
}
