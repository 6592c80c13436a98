//! The camera: keyframes (times, positions and targets in order, and the interpolated views
//! checked) or a glTF file's camera (read, and its view checked at every frame).

use super::*;
use crate::character::{AnimationSelector, GltfCamera, GltfCameraError};
use crate::scene::limits::WORLD_LIMIT_M;

pub(super) fn camera(
    raw: Option<&RawCamera>,
    timeline: &Timeline,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<CameraSpec> {
    match raw {
        None => camera_keys(None, timeline, water, map).map(CameraSpec::Keys),
        Some(RawCamera::Keys(keys)) => {
            camera_keys(Some(keys), timeline, water, map).map(CameraSpec::Keys)
        }
        Some(RawCamera::Gltf(raw)) => gltf_camera(raw, timeline, water, map).map(CameraSpec::Gltf),
    }
}

/// `[camera] gltf = "file.glb"`: the file's camera read and chosen here, so every problem with it
/// is reported at its key when the scene loads, and its view is checked at every frame.
fn gltf_camera(
    raw: &RawGltfCamera,
    timeline: &Timeline,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<GltfCameraSpec> {
    let at = KeyPath::root().key("camera");
    let conflicts = [
        ("eye", raw.eye.is_some()),
        ("target", raw.target.is_some()),
        ("frame", raw.frame.is_some()),
        ("time_secs", raw.time_secs.is_some()),
    ];
    if let Some((key, _)) = conflicts.iter().find(|(_, given)| *given) {
        return Err(map.error(
            &at.key(key),
            format!(
                "`{key}` is a keyframe key, but this [camera] table takes its camera from a glTF file, \
                 which says where the camera is at every frame"
            ),
            "remove it, or write keyframes as [[camera]] tables without gltf (one or the other)",
        ));
    }
    if raw.fov_deg.is_some() {
        return Err(map.error(
            &at.key("fov_deg"),
            "the glTF camera has its own field of view (its yfov), which fov_deg would contradict",
            "remove fov_deg; change the camera's field of view in the file",
        ));
    }
    let Some(gltf) = &raw.gltf else {
        return Err(map.error(
            &at,
            "a [camera] table takes the camera from a glTF file and needs gltf = \"file\"",
            "add e.g. gltf = \"assets/shot_cam.glb\" (relative to the scene file), or write keyframes \
             as [[camera]] tables",
        ));
    };
    let file = gltf_file(gltf, &at.key("gltf"), map)?;
    let aspect = match raw.aspect.as_deref() {
        None | Some("gltf") => AspectRule::Gltf,
        Some("render") => AspectRule::Render,
        Some(other) => {
            return Err(map.error(
                &at.key("aspect"),
                format!("unknown aspect {other:?}"),
                "use \"gltf\" (the frame must have the camera's aspectRatio) or \"render\" (the camera's \
                 vertical field of view at the frame's aspect)",
            ))
        }
    };
    let time_offset_secs = raw.time_offset_secs.unwrap_or(0.0);
    let animation =
        animation_choice(raw.animation.as_ref(), &at.key("animation"), map)?.map(|choice| {
            match choice {
                AnimationChoice::Name(name) => AnimationSelector::Name(name),
                AnimationChoice::Index(index) => AnimationSelector::Index(index),
            }
        });
    let camera = GltfCamera::load(&file, raw.node.as_deref(), animation.as_ref()).map_err(
        |error| {
            let (key, fix) = match &error {
                GltfCameraError::File(_) => (
                    "gltf",
                    "name a glTF 2.0 file (.glb or .gltf) that Blender, Maya or another DCC exported",
                ),
                GltfCameraError::NoCamera => (
                    "gltf",
                    "export the camera with the file (in Blender: Include > Cameras), or name another file",
                ),
                GltfCameraError::SeveralCameras { .. } => {
                    ("gltf", "choose one with node = \"NAME\" under [camera]")
                }
                GltfCameraError::NodeNotFound { .. } | GltfCameraError::NodeHasNoCamera { .. } => {
                    ("node", "name one of the file's camera nodes")
                }
                GltfCameraError::Orthographic { .. } | GltfCameraError::BadProjection { .. } => (
                    if raw.node.is_some() { "node" } else { "gltf" },
                    "export a perspective camera with a field of view between 0 and 180 degrees and clip \
                     planes 0 < znear < zfar",
                ),
                GltfCameraError::Animation(_) | GltfCameraError::AnimationMissesCamera { .. } => {
                    ("animation", "name an animation that moves the camera node, or leave animation out")
                }
                GltfCameraError::SeveralAnimations { .. } => (
                    "gltf",
                    "choose one with animation = \"NAME\" (or its index) under [camera]",
                ),
            };
            let key = if key == "animation" && raw.animation.is_none() { "gltf" } else { key };
            let problem = match &error {
                GltfCameraError::File(inner) => format!("cannot use the glTF camera file: {inner}"),
                GltfCameraError::Animation(inner) => inner.to_string(),
                other => format!("{}: {other}", file.display()),
            };
            map.error(&at.key(key), problem, fix)
        },
    )?;
    // Every frame the timeline renders gives a view, from the air, inside the world.
    let crest_m = water.level_m + water.max_crest_m();
    for frame in timeline.frames() {
        let time_secs = timeline.time_secs(frame) + time_offset_secs;
        let at_frame = |problem: String, fix: &str| {
            map.error(
                &at.key("gltf"),
                format!(
                    "{}: the camera of node {:?} at frame {frame} (animation time {time_secs:.3} s): {problem}",
                    file.display(),
                    camera.node_name
                ),
                fix,
            )
        };
        let view = camera.try_camera_at(time_secs).map_err(|problem| {
            at_frame(
                problem,
                "fix the camera node's (or its parents') scale in the file",
            )
        })?;
        if view.eye.abs().max_element() as f64 > WORLD_LIMIT_M {
            return Err(at_frame(
                format!(
                    "the eye {:?} is more than {WORLD_LIMIT_M} m from the origin along an axis",
                    view.eye.to_array()
                ),
                "export the scene in metres near the origin",
            ));
        }
        if (view.eye.y as f64) <= crest_m {
            return Err(at_frame(
                format!(
                    "the eye is under the water (y = {} m; the surface reaches {crest_m} m at its highest \
                     crest); snell renders from the air",
                    view.eye.y
                ),
                "move the camera above the water in the file, or set time_offset_secs to use another part of \
                 its animation",
            ));
        }
    }
    Ok(GltfCameraSpec {
        file,
        camera: std::sync::Arc::new(camera),
        time_offset_secs,
        aspect,
        source: map.source_ref(&at.key("gltf")),
    })
}

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
