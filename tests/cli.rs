//! The `snell` binary as a user meets it: bad input is a clear one-paragraph error naming the file,
//! line and column, with exit code 2 and no partial output; good input renders EXR frames and the
//! report. Each case writes its scene into a fresh temporary directory.

mod common;
use common::{snell, TINY};

use std::path::{Path, PathBuf};
use std::process::Output;

/// `snell render SCENE --out OUT --size 64x36 EXTRA...`, run in `cwd`.
fn render_small(scene: &Path, out: &Path, extra: &[&str], cwd: &Path) -> Output {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "64x36",
    ];
    args.extend_from_slice(extra);
    snell(&args, cwd)
}

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Files left anywhere under `dir` other than the scene files themselves.
fn outputs_under(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_none_or(|e| e != "toml")
                && path.file_name().is_some_and(|n| n != "blocker")
            {
                found.push(path);
            }
        }
    }
    found
}

/// Renders `scene_text` and expects exit 2 with every `needles` in stderr and nothing written.
fn expect_bad_input(scene_text: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bad.toml", scene_text);
    let out = dir.path().join("out");
    let output = render_small(&scene, &out, &[], dir.path());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(2),
        "exit code for bad input; stderr:\n{stderr}"
    );
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "stderr should contain {needle:?}:\n{stderr}"
        );
    }
    assert!(
        !stderr.contains("panicked"),
        "a panic is not an error message:\n{stderr}"
    );
    assert!(
        outputs_under(dir.path()).is_empty(),
        "bad input left files: {:?}",
        outputs_under(dir.path())
    );
}

fn replace_once(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "tiny.toml no longer contains {from:?}");
    text.replacen(from, to, 1)
}

/// `":N:"`, where N is the 1-based line of `text` that contains `needle`: how an error names its line.
fn line_marker(text: &str, needle: &str) -> String {
    let line = text
        .lines()
        .position(|l| l.contains(needle))
        .expect("the edited line is there")
        + 1;
    format!(":{line}:")
}

/// Edits tiny.toml (`from` -> `to`) and expects an error naming the file, the line holding `marked`
/// and each of `needles`.
fn expect_bad_edit(from: &str, to: &str, marked: &str, needles: &[&str]) {
    let text = replace_once(TINY, from, to);
    let mut all = vec!["bad.toml".to_string(), line_marker(&text, marked)];
    all.extend(needles.iter().map(|n| n.to_string()));
    expect_bad_input(&text, &all.iter().map(String::as_str).collect::<Vec<_>>());
}

#[test]
fn malformed_toml_names_file_line_and_column() {
    expect_bad_edit("fps = 24", "fps = = 24", "fps = = 24", &[]);
}

#[test]
fn unknown_key_is_named() {
    expect_bad_edit("fps = 24", "fps = 24\nfsp = 25", "fsp = 25", &["fsp"]);
}

#[test]
fn zero_resolution_is_refused() {
    expect_bad_edit(
        "resolution = [16, 16]",
        "resolution = [0, 16]",
        "resolution = [0, 16]",
        &["resolution"],
    );
}

#[test]
fn non_positive_index_of_refraction_is_refused() {
    expect_bad_edit(
        "resolution = [16, 16]",
        "resolution = [16, 16]\nn_below = -1.333",
        "n_below = -1.333",
        &["n_below"],
    );
}

#[test]
fn nan_is_refused() {
    expect_bad_edit(
        "amplitude_m = 0.02",
        "amplitude_m = nan",
        "amplitude_m = nan",
        &["amplitude_m"],
    );
}

#[test]
fn missing_texture_image_is_named() {
    let text = replace_once(
        TINY,
        r#"texture = { kind = "checker", color = [0.95, 0.93, 0.90], color_b = [0.85, 0.12, 0.10], square_m = 0.15 }"#,
        r#"texture = { image = "no-such-texture.png" }"#,
    );
    expect_bad_input(&text, &["bad.toml", "no-such-texture.png"]);
}

#[test]
fn output_path_through_a_regular_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    std::fs::write(dir.path().join("blocker"), "a regular file").unwrap();
    let out = dir.path().join("blocker").join("frames");
    let output = render_small(&scene, &out, &[], dir.path());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "stderr:\n{stderr}");
    assert!(
        stderr.contains("blocker"),
        "the error names the path:\n{stderr}"
    );
    assert!(
        outputs_under(dir.path()).is_empty(),
        "left files: {:?}",
        outputs_under(dir.path())
    );
}

#[test]
fn bad_arguments_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    for args in [["--size", "0x10"], ["--frames", "2-99"], ["--frames", "x"]] {
        let mut all = vec!["render", scene.to_str().unwrap()];
        all.extend(args);
        let output = snell(&all, dir.path());
        assert_eq!(
            output.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let missing = snell(&["render", "no-such-scene.toml"], dir.path());
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no-such-scene.toml"));
}

#[test]
fn render_writes_frames_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    let out = dir.path().join("frames");
    let output = render_small(&scene, &out, &["--frames", "2-3"], dir.path());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    // The report's lock file (farm-safe updates, tests/farm.rs) is the only hidden file.
    assert_eq!(
        names,
        [
            ".report.jsonl.lock",
            "report.jsonl",
            "tiny.0002.exr",
            "tiny.0003.exr"
        ]
    );
    let report = std::fs::read_to_string(out.join("report.jsonl")).unwrap();
    let rows: Vec<serde_json::Value> = report
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[0]["frame"], 2);
    assert_eq!(rows[1]["frame"], 3);
    for row in &rows {
        assert!(row["convergence_policy"]
            .as_str()
            .unwrap()
            .contains("optical path"));
        assert!(row["counts"].is_object());
        assert!(row["stage_secs"]["refraction"].as_f64().unwrap() >= 0.0);
    }

    let (frame, _meta) = snell::output::exr::read_frame_exr(&out.join("tiny.0002.exr")).unwrap();
    assert_eq!((frame.width, frame.height), (64, 36));
}

#[test]
fn info_describes_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    let output = snell(&["info", scene.to_str().unwrap()], dir.path());
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    for needle in ["frames 1-3", "16x16 cells", "adapter"] {
        assert!(
            stdout.contains(needle),
            "info should mention {needle:?}:\n{stdout}"
        );
    }
}

/// A scene with a character: `snell info` lists it with its model's size and every animation of
/// its file with its duration, the one played marked. The durations are read here from the glTF
/// JSON itself (each animation's sampler inputs, from their accessors' min and max), not by snell's
/// loader.
#[test]
fn info_lists_characters_with_their_animations_and_size() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fox_wading.toml");
    let output = snell(&["info", scene.to_str().unwrap()], dir.path());
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}");

    let glb = std::fs::read(repo_file("scenes/assets/Fox.glb")).unwrap();
    let json_length = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    assert_eq!(&glb[16..20], b"JSON");
    let gltf: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_length]).unwrap();
    let accessors = gltf["accessors"].as_array().unwrap();
    let animations = gltf["animations"].as_array().unwrap();
    assert!(animations.len() >= 2);
    assert!(stdout.contains("characters 1"), "{stdout}");
    for (index, animation) in animations.iter().enumerate() {
        let (mut start, mut end) = (f64::INFINITY, f64::NEG_INFINITY);
        for sampler in animation["samplers"].as_array().unwrap() {
            let input = &accessors[sampler["input"].as_u64().unwrap() as usize];
            start = start.min(input["min"][0].as_f64().unwrap());
            end = end.max(input["max"][0].as_f64().unwrap());
        }
        let name = animation["name"].as_str().unwrap();
        let line = format!("animation {index} {name:?}: {:.2} s", end - start);
        assert!(stdout.contains(&line), "{line:?} in\n{stdout}");
    }
    let played = stdout
        .lines()
        .find(|line| line.contains("<- played"))
        .unwrap_or_else(|| panic!("no animation marked as played:\n{stdout}"));
    assert!(played.contains("\"Walk\""), "{played}");
    // The scene says the fox is 0.63 m from paws to ears at its scale.
    let model = stdout
        .lines()
        .find(|line| line.contains("Fox.glb"))
        .unwrap_or_else(|| panic!("no model line:\n{stdout}"));
    let sizes: Vec<f64> = model
        .split(';')
        .nth(1)
        .unwrap()
        .split(" m ")
        .next()
        .unwrap()
        .split(" x ")
        .map(|v| v.trim().parse().unwrap())
        .collect();
    assert_eq!(sizes.len(), 3, "{model}");
    assert!(
        (0.5..0.8).contains(&sizes[1]),
        "height {} in {model}",
        sizes[1]
    );
}

/// A file of the repository, as an absolute path a scene in a temporary folder can name.
fn repo_file(relative: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(relative)
        .to_str()
        .unwrap()
        .to_string()
}

/// tiny.toml with one `[[character]]` table (`body` are its lines) appended; expects an error
/// naming bad.toml, the line holding `marked`, and each of `needles`.
fn expect_bad_character(body: &str, marked: &str, needles: &[&str]) {
    let text = format!("{TINY}\n[[character]]\n{body}\n");
    let mut all = vec!["bad.toml".to_string(), line_marker(&text, marked)];
    all.extend(needles.iter().map(|n| n.to_string()));
    expect_bad_input(&text, &all.iter().map(String::as_str).collect::<Vec<_>>());
}

#[test]
fn missing_gltf_file_is_named() {
    expect_bad_character(
        "file = \"models/nowhere.glb\"",
        "nowhere.glb",
        &["character[0].file", "nowhere.glb", "cannot find"],
    );
}

#[test]
fn broken_gltf_files_are_named_with_their_cause() {
    let cases = [
        (
            "tests/gltf/short_buffer.gltf",
            vec!["short_buffer.gltf", "truncated"],
        ),
        (
            "tests/gltf/missing_buffer.gltf",
            vec!["missing_buffer.gltf", "cannot be read"],
        ),
        (
            "tests/gltf/joint_out_of_range.gltf",
            vec!["joint_out_of_range.gltf", "joint index", "out of range"],
        ),
        (
            "tests/gltf/zero_weights.gltf",
            vec!["zero_weights.gltf", "weights sum to zero"],
        ),
    ];
    for (file, mut needles) in cases {
        needles.push("character[0].file");
        let path = repo_file(file);
        expect_bad_character(&format!("file = {path:?}"), "file =", &needles);
    }
}

#[test]
fn unknown_animation_lists_the_ones_that_exist() {
    let fox = repo_file("scenes/assets/Fox.glb");
    expect_bad_character(
        &format!("file = {fox:?}\nanimation = \"Gallop\""),
        "Gallop",
        &[
            "character[0].animation",
            "\"Gallop\"",
            "\"Survey\"",
            "\"Walk\"",
            "\"Run\"",
        ],
    );
}

#[test]
fn root_path_keyframes_out_of_order_are_refused() {
    let fox = repo_file("scenes/assets/Fox.glb");
    expect_bad_character(
        &format!(
            "file = {fox:?}\n\n[[character.path]]\nframe = 10\nposition = [0.0, 0.0, 0.0]\n\n\
             [[character.path]]\nframe = 4\nposition = [1.0, 0.0, 0.0]"
        ),
        "frame = 4",
        &["character[0].path[1].frame", "out of order"],
    );
}

/// Every scene shipped in `scenes/` loads and renders its last frame (so the characters' ripples
/// have been stepped through the whole timeline).
#[test]
fn every_shipped_scene_renders() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut rendered = Vec::new();
    for entry in std::fs::read_dir(&scenes).unwrap().flatten() {
        let scene = entry.path();
        if scene.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let text = std::fs::read_to_string(&scene).unwrap();
        let last = text
            .lines()
            .find_map(|l| l.trim().strip_prefix("frames = ["))
            .and_then(|rest| {
                rest.split(']')
                    .next()?
                    .split(',')
                    .nth(1)?
                    .trim()
                    .parse::<u32>()
                    .ok()
            })
            .unwrap_or(48); // the default timeline: frames 1-48
        let frame = last.to_string();
        let output = render_small(&scene, &out, &["--frames", &frame], dir.path());
        assert!(
            output.status.success(),
            "{} fails: {}",
            scene.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        rendered.push(scene.file_stem().unwrap().to_string_lossy().to_string());
    }
    rendered.sort();
    assert_eq!(
        rendered,
        [
            "cesium_submerged",
            "fox_wading",
            "pool",
            "pool_gltf_camera",
            "post_breaking_surface",
            "tiny"
        ]
    );
}

#[test]
fn raytrace_renders_tiny_into_an_exr_with_every_layer() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    let out = dir.path().join("frames");
    let output = render_small(
        &scene,
        &out,
        &["--frames", "2", "--method", "raytrace"],
        dir.path(),
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let (frame, meta) = snell::output::exr::read_frame_exr(&out.join("tiny.0002.exr")).unwrap();
    assert_eq!(meta.method, "raytrace/exact-surface");
    assert_eq!((frame.width, frame.height), (64, 36));
    let pixels = 64 * 36;
    assert_eq!(frame.beauty_rgba.len(), pixels);
    assert_eq!(frame.depth_m.len(), pixels);
    assert_eq!(frame.position.len(), pixels);
    assert_eq!(frame.flags.len(), pixels);
    assert_eq!(frame.object.len(), pixels);
    assert!(frame
        .beauty_rgba
        .iter()
        .all(|p| p.iter().all(|c| c.is_finite()) && p[3] == 1.0));
    assert!(
        frame.flags.iter().all(|&f| f == 0),
        "the reference has no flags"
    );
    // tiny.toml: the pool (object 1) seen through the water, about a fifth of the image (443
    // of 2,304 pixels when written; deck and sky are the rest), and the ball (object 2) under it.
    let through_water = (0..pixels)
        .filter(|&i| frame.object[i] != 0 && frame.position[i][1] < -0.05)
        .count();
    assert!(
        through_water > pixels / 10,
        "{through_water} pixels see under water"
    );
    assert!(frame.object.contains(&2), "the ball is in view");
    for i in 0..pixels {
        let seen = frame.object[i] != 0;
        if seen {
            assert!(frame.depth_m[i] > 0.0 && frame.depth_m[i] < snell::draw::SKY_DEPTH_M);
            assert_ne!(
                frame.position[i], [0.0; 3],
                "pixel {i}: P and object disagree"
            );
        } else {
            assert_eq!(
                frame.position[i], [0.0; 3],
                "pixel {i}: P and object disagree"
            );
        }
    }
    let report = std::fs::read_to_string(out.join("report.jsonl")).unwrap();
    let row: serde_json::Value = serde_json::from_str(report.lines().next().unwrap()).unwrap();
    assert_eq!(row["method"], "raytrace/exact-surface");
    for group in ["triangles", "vertices"] {
        for (key, count) in row["counts"][group].as_object().unwrap() {
            assert_eq!(count, 0, "{group}.{key}");
        }
    }
}

/// Every hard scene in `scenes/hard/` (issue 13 point 2) loads and renders, small, its last frame
/// (so a wading character's ripples are stepped through the whole shot); each file says in its
/// first lines what fails there.
#[test]
fn every_hard_scene_renders() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/hard");
    let mut rendered = Vec::new();
    for entry in std::fs::read_dir(&scenes).unwrap().flatten() {
        let scene = entry.path();
        if scene.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let text = std::fs::read_to_string(&scene).unwrap();
        assert!(
            text.starts_with("# HARD: ") && text.contains("What fails here:"),
            "{} must say in its first lines what fails there",
            scene.display()
        );
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let output = render_small(&scene, &out, &["--frames", "48"], dir.path());
        assert!(
            output.status.success(),
            "{} fails: {}",
            scene.display(),
            String::from_utf8_lossy(&output.stderr)
        );
        let name = scene.file_stem().unwrap().to_string_lossy().to_string();
        assert!(out.join(format!("{name}.0048.exr")).is_file(), "{name}");
        rendered.push(name);
    }
    rendered.sort();
    assert_eq!(
        rendered,
        [
            "fast_camera",
            "grazing_eye",
            "rising_object",
            "steep_waves",
            "wading_wake",
            "wall_crossing"
        ]
    );
}
