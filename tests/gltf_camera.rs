//! A scene's camera taken from a glTF file (`[camera] gltf = "..."`): the view and projection the
//! job renders with, checked against the glTF spec's math written out here (rotation matrices from
//! angles, not quaternions; the spec's projection matrix), at key times, between keys and past
//! the last key; the EXR headers of rendered frames; a frame rendered through the glTF camera
//! against the same frame through equivalent `[[camera]]` keyframes; the input hash; and every
//! error at its scene key with exit 2.
//!
//! The fixture glTF files are written by [`write_gltf`] (JSON + an external `.bin`), from the
//! same constants the oracle uses in closed form.

mod common;

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use serde_json::{json, Value};
use snell::frame::RenderJob;

use common::snell;

/// One animation channel of a fixture: node, property, LINEAR keys (values flattened).
struct Channel {
    node: usize,
    path: &'static str,
    times: Vec<f32>,
    values: Vec<f32>,
}

/// Writes `<dir>/<stem>.gltf` with its buffer `<stem>.bin`: the given nodes and cameras, and one
/// animation "CameraMove" with `channels` (none: no animation).
fn write_gltf(
    dir: &Path,
    stem: &str,
    nodes: Value,
    cameras: Value,
    channels: &[Channel],
) -> PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |data: &[f32], kind: &str, count: usize, min_max: bool| -> usize {
        let offset = bin.len();
        for v in data {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4}));
        let mut accessor = json!({
            "bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": kind
        });
        if min_max {
            let min = data.iter().cloned().fold(f32::INFINITY, f32::min);
            let max = data.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
            accessor["min"] = json!([min]);
            accessor["max"] = json!([max]);
        }
        accessors.push(accessor);
        accessors.len() - 1
    };
    let mut samplers = Vec::new();
    let mut anim_channels = Vec::new();
    for (i, channel) in channels.iter().enumerate() {
        let input = push(&channel.times, "SCALAR", channel.times.len(), true);
        let (kind, width) = if channel.path == "rotation" {
            ("VEC4", 4)
        } else {
            ("VEC3", 3)
        };
        let output = push(&channel.values, kind, channel.values.len() / width, false);
        samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
        anim_channels
            .push(json!({"sampler": i, "target": {"node": channel.node, "path": channel.path}}));
    }
    let mut root = json!({
        "asset": {"version": "2.0", "generator": "snell tests/gltf_camera.rs"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
    });
    if cameras.as_array().is_some_and(|c| !c.is_empty()) {
        root["cameras"] = cameras;
    }
    if !channels.is_empty() {
        root["animations"] =
            json!([{"name": "CameraMove", "channels": anim_channels, "samplers": samplers}]);
        root["buffers"] = json!([{"uri": format!("{stem}.bin"), "byteLength": bin.len()}]);
        root["bufferViews"] = json!(views);
        root["accessors"] = json!(accessors);
        std::fs::write(dir.join(format!("{stem}.bin")), &bin).unwrap();
    }
    let path = dir.join(format!("{stem}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&root).unwrap()).unwrap();
    path
}

/// Unit quaternion (x, y, z, w) of `deg` about a unit axis: only for writing fixtures.
fn quat(axis: [f64; 3], deg: f64) -> [f32; 4] {
    let half = deg.to_radians() / 2.0;
    let s = half.sin();
    [
        (axis[0] * s) as f32,
        (axis[1] * s) as f32,
        (axis[2] * s) as f32,
        half.cos() as f32,
    ]
}

type M3 = [[f64; 3]; 3];

/// Rotation matrices (rows) about y and x, from the angle.
fn rot_y(deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}
fn rot_x(deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}
fn mul(a: M3, b: M3) -> M3 {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}
fn apply(m: M3, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| m[i][k] * v[k]).sum())
}

// The animated fixture: a parent "Rig" (translation keyed at 0, 1, 2 s; uniform scale keyed at 0
// and 2 s; a fixed yaw of 210 degrees) carrying the node "ShotCam" (fixed offset, pitch keyed at
// 0 and 2 s). A second camera node "Witness" makes `node` necessary.
const RIG_T: [(f64, [f64; 3]); 3] = [
    (0.0, [0.0, 3.0, -6.0]),
    (1.0, [2.0, 3.0, -6.0]),
    (2.0, [2.0, 4.0, -4.0]),
];
const RIG_YAW_DEG: f64 = 210.0;
const CAM_OFFSET: [f64; 3] = [0.0, 0.5, 1.0];
const YFOV_RAD: f64 = 0.8;
const ASPECT: f64 = 16.0 / 9.0;
const ZNEAR: f64 = 0.1;
const ZFAR: f64 = 200.0;

fn animated_fixture(dir: &Path) -> PathBuf {
    let nodes = json!([
        {"name": "Rig", "children": [1, 2], "rotation": quat([0.0, 1.0, 0.0], RIG_YAW_DEG)},
        {"name": "ShotCam", "camera": 0, "translation": CAM_OFFSET},
        {"name": "Witness", "camera": 1, "translation": [0.0, 1.0, 0.0]},
    ]);
    let cameras = json!([
        {"type": "perspective", "name": "ShotCamData",
         "perspective": {"yfov": YFOV_RAD, "aspectRatio": ASPECT, "znear": ZNEAR, "zfar": ZFAR}},
        {"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.05}},
    ]);
    let channels = [
        Channel {
            node: 0,
            path: "translation",
            times: RIG_T.iter().map(|k| k.0 as f32).collect(),
            values: RIG_T.iter().flat_map(|k| k.1.map(|v| v as f32)).collect(),
        },
        Channel {
            node: 0,
            path: "scale",
            times: vec![0.0, 2.0],
            values: vec![1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
        },
        Channel {
            node: 1,
            path: "rotation",
            times: vec![0.0, 2.0],
            values: [quat([1.0, 0.0, 0.0], -20.0), quat([1.0, 0.0, 0.0], -40.0)].concat(),
        },
    ];
    write_gltf(dir, "shot_cam", nodes, cameras, &channels)
}

/// The camera node's world rotation and position at animation time `t`, by the glTF spec in
/// closed form: keys clamped, LINEAR translation and scale, and the pitch slerp between two
/// rotations about one axis is the linear interpolation of the angle.
fn oracle(t: f64) -> (M3, [f64; 3]) {
    let t = t.clamp(0.0, 2.0);
    let segment = if t < 1.0 { 0 } else { 1 };
    let (t0, a) = RIG_T[segment];
    let (t1, b) = RIG_T[segment + 1];
    let s = (t - t0) / (t1 - t0);
    let rig = [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * s);
    let scale = 1.0 + t / 2.0;
    let pitch = -20.0 - 10.0 * t;
    let rotation = mul(rot_y(RIG_YAW_DEG), rot_x(pitch));
    let offset = apply(rot_y(RIG_YAW_DEG), CAM_OFFSET.map(|v| v * scale));
    (rotation, [0, 1, 2].map(|i| rig[i] + offset[i]))
}

/// World -> camera of a rigid camera transform: [R^T | -R^T eye], as a glam matrix.
fn oracle_view(rotation: M3, eye: [f64; 3]) -> Mat4 {
    let rt = |i: usize, j: usize| rotation[j][i];
    let tr = [0, 1, 2].map(|i| -(0..3).map(|k| rt(i, k) * eye[k]).sum::<f64>());
    Mat4::from_cols_array_2d(&[
        [rt(0, 0) as f32, rt(1, 0) as f32, rt(2, 0) as f32, 0.0],
        [rt(0, 1) as f32, rt(1, 1) as f32, rt(2, 1) as f32, 0.0],
        [rt(0, 2) as f32, rt(1, 2) as f32, rt(2, 2) as f32, 0.0],
        [tr[0] as f32, tr[1] as f32, tr[2] as f32, 1.0],
    ])
}

/// The glTF spec's finite perspective matrix (OpenGL clip space, depth in [-1, 1]) followed by
/// the remap to wgpu's depth in [0, 1] (z' = (z + w) / 2).
fn oracle_projection(aspect: f64) -> Mat4 {
    let (n, f) = (ZNEAR, ZFAR);
    let cot = 1.0 / (YFOV_RAD / 2.0).tan();
    // Rows of the spec's matrix.
    let gl = [
        [cot / aspect, 0.0, 0.0, 0.0],
        [0.0, cot, 0.0, 0.0],
        [0.0, 0.0, (f + n) / (n - f), 2.0 * f * n / (n - f)],
        [0.0, 0.0, -1.0, 0.0],
    ];
    let remap = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 0.5, 0.5],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut rows = [[0.0f64; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            rows[i][j] = (0..4).map(|k| remap[i][k] * gl[k][j]).sum();
        }
    }
    Mat4::from_cols_array_2d(&[0, 1, 2, 3].map(|j| [0, 1, 2, 3].map(|i| rows[i][j] as f32)))
}

/// The tiny test scene's water and objects, with `camera` as its camera section.
fn scene_text(camera: &str, frames: [u32; 2], fps: u32) -> String {
    let body = common::TINY
        .split("[water]")
        .nth(1)
        .expect("tiny.toml has a [water] table");
    format!(
        "name = \"cam\"\nmax_edge_m = 0.2\n\n[timeline]\nfps = {fps}\nframes = [{}, {}]\n\n{camera}\n\n[water]{body}",
        frames[0], frames[1]
    )
}

fn write_scene(dir: &Path, file: &str, text: &str) -> PathBuf {
    let path = dir.join(file);
    std::fs::write(&path, text).unwrap();
    path
}

/// `snell render SCENE --out OUT --frames FRAMES --size SIZE`, which must succeed.
fn render(cwd: &Path, scene: &Path, out: &Path, frames: &str, size: &str) {
    let args = common::render_args(scene, out, frames, size);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let output = snell(&args, cwd);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn assert_matrix_close(actual: Mat4, expected: Mat4, tolerance: f32, what: &str) {
    let (a, e) = (actual.to_cols_array(), expected.to_cols_array());
    for i in 0..16 {
        assert!(
            (a[i] - e[i]).abs() <= tolerance * e[i].abs().max(1.0),
            "{what}: element {i}: {} vs {} (expected)\nactual {actual}\nexpected {expected}",
            a[i],
            e[i]
        );
    }
}

/// At 4 fps, frames 1-12 are t = 0 to 2.75 s: keys (0, 1, 2 s), between keys (0.25, 0.5, 1.25,
/// 1.75 s ...) and past the last key (clamped). With `time_offset_secs = 0.25` every frame is a
/// quarter second later in the animation.
#[test]
fn view_and_projection_match_the_gltf_spec_at_keys_between_them_and_after() {
    let dir = tempfile::tempdir().unwrap();
    animated_fixture(dir.path());
    for offset in [0.0, 0.25] {
        let camera = format!(
            "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"ShotCam\"\ntime_offset_secs = {offset}"
        );
        let scene = write_scene(dir.path(), "scene.toml", &scene_text(&camera, [1, 12], 4));
        let job = RenderJob::prepare(&scene).unwrap_or_else(|e| panic!("{e}"));
        let expected_projection = oracle_projection(16.0 / 9.0);
        for frame in 1..=12u32 {
            let t = (frame - 1) as f64 / 4.0 + offset;
            let camera = job.camera_at(frame);
            let (rotation, eye) = oracle(t);
            let what = format!("frame {frame} (animation t = {t} s)");
            assert_matrix_close(
                camera.view_from_world(),
                oracle_view(rotation, eye),
                2e-6,
                &what,
            );
            assert_matrix_close(
                camera.clip_from_view(16.0 / 9.0),
                expected_projection,
                2e-6,
                &what,
            );
            assert_eq!((camera.near_m, camera.far_m), (ZNEAR as f32, ZFAR as f32));
            // The clip matrix the GPU gets for a 16:9 frame is the product of the two.
            assert_matrix_close(
                camera.clip_from_world(64, 36),
                expected_projection * oracle_view(rotation, eye),
                1e-5,
                &what,
            );
        }
    }
}

/// The frames `snell render` writes carry the glTF camera: `snell.worldFromCamera` is the node's
/// world transform without its scale, and the clip planes are the file's.
#[test]
fn rendered_frames_carry_the_gltf_camera_in_their_headers() {
    let dir = tempfile::tempdir().unwrap();
    animated_fixture(dir.path());
    let camera = "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"ShotCam\"";
    let scene = write_scene(dir.path(), "scene.toml", &scene_text(camera, [1, 12], 4));
    let out = dir.path().join("out");
    render(dir.path(), &scene, &out, "2,6", "64x36");
    for frame in [2u32, 6] {
        let path = out.join(format!("cam.{frame:04}.exr"));
        let (_, meta) = snell::output::exr::read_frame_exr(&path).unwrap();
        let (rotation, eye) = oracle((frame - 1) as f64 / 4.0);
        let expected_world = oracle_view(rotation, eye).inverse();
        assert_matrix_close(
            Mat4::from_cols_array(&meta.world_from_camera),
            expected_world,
            1e-5,
            &format!("frame {frame} header"),
        );
        assert!((meta.camera.fov_y_deg as f64 - YFOV_RAD.to_degrees()).abs() < 1e-4);
        assert_eq!(
            (meta.camera.near_m, meta.camera.far_m),
            (ZNEAR as f32, ZFAR as f32)
        );
    }
}

/// A camera at the tiny scene's keyframe poses, as a glTF node (yaw 180 degrees, then the pitch
/// toward the target; no roll) and as `[[camera]]` keys: eye = the key's, target = eye + the
/// node's -Z.
fn equivalent_cameras(dir: &Path) -> (PathBuf, PathBuf) {
    let eyes = [[0.0f64, 1.8, -2.2], [0.3, 1.7, -2.0]];
    let pitch_deg = [-40.0f64, -45.0];
    // Key times as the job computes a frame's time: (frame - first) / fps in f64, then f32.
    let times = [0.0f32, ((3 - 1) as f64 / 24.0) as f32];
    let forward = |pitch: f64| apply(mul(rot_y(180.0), rot_x(pitch)), [0.0, 0.0, -1.0]);
    // Quaternion of yaw 180 about y times pitch about x: (0, 1, 0, 0) * (sx, 0, 0, cx).
    let rotation = |pitch: f64| {
        let [sx, _, _, cx] = quat([1.0, 0.0, 0.0], pitch);
        [0.0f32, cx, -sx, 0.0]
    };
    let nodes = json!([{"name": "Cam", "camera": 0, "translation": eyes[0], "rotation": rotation(pitch_deg[0])}]);
    let cameras = json!([{"type": "perspective", "perspective": {
        "yfov": 50f64.to_radians(), "aspectRatio": 16.0 / 9.0, "znear": 0.05, "zfar": 1000.0}}]);
    let channels = [
        Channel {
            node: 0,
            path: "translation",
            times: times.to_vec(),
            values: eyes.iter().flat_map(|e| e.map(|v| v as f32)).collect(),
        },
        Channel {
            node: 0,
            path: "rotation",
            times: times.to_vec(),
            values: [rotation(pitch_deg[0]), rotation(pitch_deg[1])].concat(),
        },
    ];
    write_gltf(dir, "keys_cam", nodes, cameras, &channels);
    let gltf_scene = write_scene(
        dir,
        "gltf.toml",
        &scene_text("[camera]\ngltf = \"keys_cam.gltf\"", [1, 3], 24),
    );
    let keys: String = [1, 3]
        .iter()
        .zip(eyes.iter().zip(pitch_deg))
        .map(|(frame, (eye, pitch))| {
            let f = forward(pitch);
            format!(
                "[[camera]]\nframe = {frame}\neye = [{}, {}, {}]\ntarget = [{}, {}, {}]\nfov_deg = 50\n\n",
                eye[0],
                eye[1],
                eye[2],
                eye[0] + f[0],
                eye[1] + f[1],
                eye[2] + f[2]
            )
        })
        .collect();
    let keys_scene = write_scene(dir, "keys.toml", &scene_text(&keys, [1, 3], 24));
    (gltf_scene, keys_scene)
}

/// At the key frames, the glTF camera and the equivalent keyframes give the same view up to f32
/// rounding (the eye is the same float; forward and up differ by ~1e-7), so the rendered frames
/// agree except where a pixel centre lies within ~1e-3 px of an edge. Allowed: at most 3 of the
/// 14,400 pixels of a 160x90 frame differ by more than 1e-3 in any beauty channel, and the mean
/// difference is below 5e-5. Measured (lavapipe): 0 pixels above 1e-3 in both frames. The mean
/// bound follows the renderer's own f32 noise: with the hardware's interpolation the mean
/// differences were 2.3e-7 (frame 1) and 1.6e-7 (frame 3), bound 1e-5; since the triangle draws
/// interpolate from the eye ray meeting the triangle's plane in the fragment stage (strips, issue
/// 19), a ~1e-7 change of forward and up moves that f32 intersection by more on grazing far water:
/// mean 1.24e-5, largest 6.2e-4, still 0 pixels above 1e-3 (a precision cost of the pulled draws,
/// listed in the README's Status). `-- --nocapture` prints them.
#[test]
fn a_gltf_camera_renders_as_the_equivalent_keyframes() {
    let dir = tempfile::tempdir().unwrap();
    let (gltf_scene, keys_scene) = equivalent_cameras(dir.path());
    let gltf_job = RenderJob::prepare(&gltf_scene).unwrap_or_else(|e| panic!("{e}"));
    let keys_job = RenderJob::prepare(&keys_scene).unwrap_or_else(|e| panic!("{e}"));
    for frame in [1u32, 3] {
        let (a, b) = (gltf_job.camera_at(frame), keys_job.camera_at(frame));
        assert_eq!(
            a.eye, b.eye,
            "frame {frame}: the eye is the key's own float"
        );
        assert_matrix_close(
            a.clip_from_world(160, 90),
            b.clip_from_world(160, 90),
            1e-6,
            &format!("frame {frame}"),
        );
    }
    let (gltf_out, keys_out) = (dir.path().join("gltf"), dir.path().join("keys"));
    render(dir.path(), &gltf_scene, &gltf_out, "1,3", "160x90");
    render(dir.path(), &keys_scene, &keys_out, "1,3", "160x90");
    for frame in [1u32, 3] {
        let name = format!("cam.{frame:04}.exr");
        let (a, _) = snell::output::exr::read_frame_exr(&gltf_out.join(&name)).unwrap();
        let (b, _) = snell::output::exr::read_frame_exr(&keys_out.join(&name)).unwrap();
        let mut differing = 0;
        let mut sum = 0.0f64;
        for (pa, pb) in a.beauty_rgba.iter().zip(&b.beauty_rgba) {
            let d = (0..4).map(|c| (pa[c] - pb[c]).abs()).fold(0.0f32, f32::max);
            sum += d as f64;
            if d > 1e-3 {
                differing += 1;
            }
        }
        let mean = sum / a.beauty_rgba.len() as f64;
        assert!(
            differing <= 3 && mean < 5e-5,
            "frame {frame}: {differing} pixels differ by more than 1e-3, mean difference {mean:e}"
        );
        eprintln!("frame {frame}: {differing} pixels differ by more than 1e-3, mean {mean:e}");
    }
}

/// The camera's file and its buffer are inputs of every frame: editing the buffer changes the
/// input hash (and so `--resume` renders again).
#[test]
fn the_camera_file_and_its_buffer_are_in_the_input_hash() {
    let dir = tempfile::tempdir().unwrap();
    animated_fixture(dir.path());
    let camera = "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"ShotCam\"";
    let scene = write_scene(dir.path(), "scene.toml", &scene_text(camera, [1, 12], 4));
    let job = RenderJob::prepare(&scene).unwrap();
    assert!(job
        .referenced_files()
        .iter()
        .any(|f| f.ends_with("shot_cam.bin")));
    let hash = job.input_hash(64, 36);
    let bin = dir.path().join("shot_cam.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    // The last float: the second pitch key's w, changed a little.
    let n = bytes.len();
    bytes[n - 4] ^= 1;
    std::fs::write(&bin, bytes).unwrap();
    let edited = RenderJob::prepare(&scene).unwrap().input_hash(64, 36);
    assert_ne!(edited, hash);
}

/// Runs `snell info` (or `render` with `extra` arguments) on a scene and returns (exit code,
/// stderr).
fn run_scene(dir: &Path, scene: &Path, extra: &[&str]) -> (i32, String) {
    let mut args = vec!["info", scene.to_str().unwrap()];
    if !extra.is_empty() {
        args = [&["render", scene.to_str().unwrap()], extra].concat();
    }
    let output = snell(&args, dir);
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Every way the camera section can be wrong: exit 2, the scene file with line and column of the
/// key at fault, and what is wrong.
#[test]
fn camera_errors_name_the_scene_key_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    animated_fixture(dir.path());
    let one_cam = json!([{"name": "Solo", "camera": 0, "translation": [0.0, 2.0, -3.0]}]);
    let perspective = json!([{"type": "perspective", "perspective": {"yfov": 0.9, "aspectRatio": 1.5, "znear": 0.1}}]);
    write_gltf(dir.path(), "solo", one_cam, perspective.clone(), &[]);
    write_gltf(
        dir.path(),
        "no_camera",
        json!([{"name": "Empty"}]),
        json!([]),
        &[],
    );
    write_gltf(
        dir.path(),
        "ortho",
        json!([{"name": "Top", "camera": 0, "translation": [0.0, 5.0, 0.0]}]),
        json!([{"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}]),
        &[],
    );
    write_gltf(
        dir.path(),
        "wet",
        json!([{"name": "Wet", "camera": 0, "translation": [0.0, -0.5, 0.0]}]),
        perspective,
        &[],
    );
    // (camera section, line of the key at fault counted in the whole file, words of the message)
    let header_lines = 8; // name, max_edge_m, blank, [timeline], fps, frames, blank, then the camera
    let cases: &[(&str, usize, &str)] = &[
        (
            "[camera]\ngltf = \"missing.glb\"",
            2,
            "cannot find the glTF file",
        ),
        ("[camera]\ngltf = \"no_camera.gltf\"", 2, "has no camera"),
        (
            "[camera]\ngltf = \"shot_cam.gltf\"",
            2,
            "several cameras: \"ShotCam\", \"Witness\"",
        ),
        (
            "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"Nobody\"",
            3,
            "no node named \"Nobody\"",
        ),
        (
            "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"Rig\"",
            3,
            "node \"Rig\" carries no camera",
        ),
        (
            "[camera]\ngltf = \"solo.gltf\"\nfov_deg = 40",
            3,
            "own field of view",
        ),
        (
            "[camera]\ngltf = \"solo.gltf\"\neye = [0, 2, 0]",
            3,
            "`eye` is a keyframe key",
        ),
        ("[camera]\nnode = \"Solo\"", 1, "needs gltf ="),
        (
            "[camera]\ngltf = \"solo.gltf\"\naspect = \"stretch\"",
            3,
            "unknown aspect \"stretch\"",
        ),
        ("[camera]\ngltf = \"ortho.gltf\"", 2, "orthographic"),
        (
            "[camera]\ngltf = \"wet.gltf\"",
            2,
            "the eye is under the water",
        ),
        (
            "[camera]\ngltf = \"shot_cam.gltf\"\nnode = \"ShotCam\"\nanimation = \"Walk\"",
            4,
            "no animation named \"Walk\"",
        ),
        (
            "[camera]\ngltf = \"solo.gltf\"\n\n[[camera]]\neye = [0, 2, -3]\ntarget = [0, 0, 0]",
            4,
            "malformed TOML",
        ),
    ];
    for (section, line, words) in cases {
        let scene = write_scene(dir.path(), "bad.toml", &scene_text(section, [1, 12], 4));
        let (code, stderr) = run_scene(dir.path(), &scene, &[]);
        let at = format!("bad.toml:{}:", header_lines + line - 1);
        assert!(
            code == 2 && stderr.contains(&at) && stderr.contains(words),
            "{section:?}: exit {code}, wanted exit 2 with {at:?} and {words:?}:\n{stderr}"
        );
    }
    // The frame size against the camera's aspectRatio (1.5): 90x60 renders, 64x36 is refused at
    // the gltf key with sizes that fit, and aspect = "render" takes any size.
    let good = write_scene(
        dir.path(),
        "solo.toml",
        &scene_text("[camera]\ngltf = \"solo.gltf\"", [1, 1], 4),
    );
    let out = dir.path().join("solo_out");
    let out = out.to_str().unwrap();
    let (code, stderr) = run_scene(dir.path(), &good, &["--out", out, "--size", "90x60"]);
    assert_eq!(code, 0, "{stderr}");
    let (code, stderr) = run_scene(dir.path(), &good, &["--out", out, "--size", "64x36"]);
    assert!(
        code == 2
            && stderr.contains(&format!("solo.toml:{}:", header_lines + 1))
            && stderr.contains("aspectRatio 1.5000")
            && stderr.contains("--size 54x36 or 64x43"),
        "exit {code}: {stderr}"
    );
    let stretched = write_scene(
        dir.path(),
        "stretched.toml",
        &scene_text(
            "[camera]\ngltf = \"solo.gltf\"\naspect = \"render\"",
            [1, 1],
            4,
        ),
    );
    let (code, stderr) = run_scene(dir.path(), &stretched, &["--out", out, "--size", "64x36"]);
    assert_eq!(code, 0, "{stderr}");
    // `snell info` says where the camera comes from.
    let output = snell(&["info", good.to_str().unwrap()], dir.path());
    let info = String::from_utf8_lossy(&output.stdout);
    assert!(
        info.contains("camera     glTF")
            && info.contains("node \"Solo\"")
            && info.contains("aspectRatio 1.5000"),
        "{info}"
    );
    // Looking straight down is no degenerate case for a glTF camera: its roll is the node's.
    let down = json!([{"name": "Down", "camera": 0, "translation": [0.0, 3.0, 0.0],
                       "rotation": quat([1.0, 0.0, 0.0], -90.0)}]);
    let cam = json!([{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.1}}]);
    write_gltf(dir.path(), "down", down, cam, &[]);
    let scene = write_scene(
        dir.path(),
        "down.toml",
        &scene_text("[camera]\ngltf = \"down.gltf\"", [1, 1], 4),
    );
    let job = RenderJob::prepare(&scene).unwrap_or_else(|e| panic!("{e}"));
    let camera = job.camera_at(1);
    assert!(camera.clip_from_world(64, 36).is_finite());
    // The node's +Y (after -90 degrees about x: world -Z) is the picture's up.
    assert!((camera.up - Vec3::NEG_Z).length() < 1e-6, "{:?}", camera.up);
}

/// A 4x4 matrix of Blender's JSON (rows) as f64 rows.
fn rows4(value: &Value) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = value[i][j].as_f64().unwrap();
        }
    }
    m
}

/// A glam matrix from f64 rows.
fn mat4_of_rows(rows: [[f64; 4]; 4]) -> Mat4 {
    Mat4::from_cols_array_2d(&[0, 1, 2, 3].map(|j| [0, 1, 2, 3].map(|i| rows[i][j] as f32)))
}

/// The largest |a - e| over the elements, for the message and the README's figure.
fn max_abs_difference(actual: Mat4, expected: Mat4) -> f32 {
    let (a, e) = (actual.to_cols_array(), expected.to_cols_array());
    (0..16).map(|i| (a[i] - e[i]).abs()).fold(0.0, f32::max)
}

/// A camera exported by Blender 3.4.1's own glTF exporter, loaded through snell's scene loader,
/// against Blender's own evaluated camera at each of its 24 frames. tests/blender_camera.py built
/// the shot (an empty "Rig" with keyframed location, Z rotation and uniform scale 1 -> 1.6,
/// carrying "ShotCam" with keyframed location and Euler rotation, Bezier curves; a 30 mm lens on
/// a 36 mm sensor; 1200x800, aspect 3:2; clip 0.1-150 m), exported it (sampled per frame, +Y up)
/// to tests/fixtures/blender_camera/blender_shot.gltf + .bin, and wrote, per frame after
/// `scene.frame_set`, the camera's `matrix_world` and `calc_matrix_camera` projection to
/// blender_camera.json. Blender is not needed to run this test: it reads only those files.
///
/// Conventions, stated here and checked where the file says them:
/// - Time: Blender's exporter puts Blender frame F at F / fps seconds
///   (io_scene_gltf2 `Keyframe.seconds = frame / fps`; the file's first key is at 1/24 s, checked
///   below), and snell's frame 1 is timeline time 0, so the scene sets
///   `time_offset_secs = 1/24` and snell frame F is Blender frame F.
/// - Axes: Blender's world is Z-up, glTF's Y-up: glTF (x, y, z) = Blender (x, z, -y). A camera's
///   own axes are the same in both (it looks down its -Z, +Y up), so the glTF world-from-camera
///   is C * matrix_world with C that change of basis; snell's view is its inverse with the scale
///   (the rig's 1 -> 1.6) divided out of each axis.
/// - Projection: Blender's matrix is OpenGL's (depth -1..1); snell's wgpu one has depth 0..1,
///   the same matrix after z' = (z + w) / 2.
///
/// Tolerance 1e-5 relative (of max(1, |expected|)): the file holds f32 keys, snell composes the
/// two nodes' transforms and interpolates in f32 and keeps the field of view as f32 degrees, and
/// the view's translation is up to ~4 m; f32's epsilon (1.2e-7) times a few dozen operations on
/// values of a few metres is ~1e-5 at worst. Measured (printed with --nocapture): at most 1.4e-6
/// of any view element and 1.2e-7 of any projection element over the 24 frames. A frame off by
/// one (time_offset_secs = 0: 1/24 s early, frame 1 held at the first key) fails at frame 2
/// (element 0: 0.99619 vs 0.99552).
#[test]
fn a_blender_export_gives_blenders_camera() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/blender_camera");
    let blender: Value = serde_json::from_str(
        &std::fs::read_to_string(fixtures.join("blender_camera.json")).unwrap(),
    )
    .unwrap();
    let fps = blender["fps"].as_f64().unwrap();
    let [width, height] = [0, 1].map(|i| blender["resolution"][i].as_u64().unwrap() as u32);
    let aspect = width as f32 / height as f32;
    // The exporter's time convention, read from the file: its animation's first key is frame 1.
    let gltf: Value =
        serde_json::from_str(&std::fs::read_to_string(fixtures.join("blender_shot.gltf")).unwrap())
            .unwrap();
    assert!(
        gltf["asset"]["generator"]
            .as_str()
            .unwrap()
            .contains("Blender"),
        "the fixture is Blender's export"
    );
    let sampler_input = gltf["animations"][0]["samplers"][0]["input"]
        .as_u64()
        .unwrap() as usize;
    let first_key = gltf["accessors"][sampler_input]["min"][0].as_f64().unwrap();
    assert!(
        (first_key - 1.0 / fps).abs() < 1e-6,
        "Blender frame 1 at {first_key} s"
    );

    let dir = tempfile::tempdir().unwrap();
    for file in ["blender_shot.gltf", "blender_shot.bin"] {
        std::fs::copy(fixtures.join(file), dir.path().join(file)).unwrap();
    }
    let frames = blender["frames"].as_array().unwrap();
    let camera = format!(
        "[camera]\ngltf = \"blender_shot.gltf\"\nnode = \"ShotCam\"\ntime_offset_secs = {}",
        1.0 / fps
    );
    let scene = write_scene(
        dir.path(),
        "scene.toml",
        &scene_text(&camera, [1, frames.len() as u32], fps as u32),
    );
    let job = RenderJob::prepare(&scene).unwrap_or_else(|e| panic!("{e}"));
    // glTF (x, y, z) = Blender (x, z, -y).
    let to_y_up = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let remap = Mat4::from_cols_array_2d(&[
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5, 1.0],
    ]);
    let (mut view_max, mut projection_max) = (0.0f32, 0.0f32);
    for entry in frames {
        let frame = entry["frame"].as_u64().unwrap() as u32;
        let m = rows4(&entry["matrix_world"]);
        let mut world = [[0.0f64; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                world[i][j] = (0..4).map(|k| to_y_up[i][k] * m[k][j]).sum();
            }
        }
        // Rotation columns without the scale; the view is [R^T | -R^T eye].
        let rotation: M3 = {
            let norms = [0, 1, 2].map(|j| (0..3).map(|i| world[i][j].powi(2)).sum::<f64>().sqrt());
            [0, 1, 2].map(|i| [0, 1, 2].map(|j| world[i][j] / norms[j]))
        };
        let eye = [world[0][3], world[1][3], world[2][3]];
        let expected_view = oracle_view(rotation, eye);
        let expected_projection = remap * mat4_of_rows(rows4(&entry["projection"]));
        let camera = job.camera_at(frame);
        let what = format!("Blender frame {frame}");
        let (view, projection) = (camera.view_from_world(), camera.clip_from_view(aspect));
        view_max = view_max.max(max_abs_difference(view, expected_view));
        projection_max = projection_max.max(max_abs_difference(projection, expected_projection));
        assert_matrix_close(view, expected_view, 1e-5, &what);
        assert_matrix_close(projection, expected_projection, 1e-5, &what);
        assert_eq!(
            (camera.near_m, camera.far_m),
            (
                entry["clip_start"].as_f64().unwrap() as f32,
                entry["clip_end"].as_f64().unwrap() as f32
            ),
            "{what}: clip planes"
        );
    }
    println!(
        "Blender 3.4 export, {} frames: largest |difference| view {view_max:.2e}, projection {projection_max:.2e}",
        frames.len()
    );
}
