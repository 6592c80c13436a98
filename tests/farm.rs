//! Farm-safe output (issue 14 point 5), through the `snell` binary as a farm runs it: several
//! `snell render` processes writing one folder at once. Four processes on overlapping ranges leave
//! every frame whole and every report row present, and `--resume` afterwards renders nothing; two
//! processes rendering two versions of a scene (one edited) into one folder keep each other's
//! simulation checkpoints, and each version then resumes its ripples from its own.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use snell::frame::RenderJob;
use snell::output::read_frame_exr;
use snell::sim::StateSource;

mod common;

const SIZE: &str = "64x36";

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn render_args(scene: &Path, out: &Path, frames: &str) -> Vec<String> {
    common::render_args(scene, out, frames, SIZE)
}

fn spawn(args: &[String]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the snell binary starts")
}

fn expect_success(output: &Output) -> String {
    let text = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "snell failed: {text}");
    text
}

/// Starts every command at once and waits for all; each must succeed.
fn run_at_once(commands: &[Vec<String>]) -> Vec<String> {
    let children: Vec<Child> = commands.iter().map(|args| spawn(args)).collect();
    children
        .into_iter()
        .map(|child| expect_success(&child.wait_with_output().unwrap()))
        .collect()
}

/// tiny.toml with a timeline of frames 1-8 (the scene references no file, so a copy renders).
fn tiny_with_eight_frames(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo("scenes/tiny.toml")).unwrap();
    let longer = text.replace("frames = [1, 3]", "frames = [1, 8]");
    assert_ne!(
        longer, text,
        "tiny.toml's timeline line changed: update this test"
    );
    let path = dir.join("tiny.toml");
    std::fs::write(&path, longer).unwrap();
    path
}

#[test]
fn four_processes_on_overlapping_ranges_lose_nothing() {
    let temp = tempfile::tempdir().unwrap();
    let scene = tiny_with_eight_frames(temp.path());
    let out = temp.path().join("shared");
    let ranges = ["1-4", "3-6", "5-8", "2-7"];
    let commands: Vec<Vec<String>> = ranges
        .iter()
        .map(|range| render_args(&scene, &out, range))
        .collect();
    run_at_once(&commands);

    for frame in 1..=8u32 {
        let path = out.join(format!("tiny.{frame:04}.exr"));
        let (_, meta) = read_frame_exr(&path)
            .unwrap_or_else(|error| panic!("frame {frame} is not whole: {error}"));
        assert_eq!(meta.frame, frame);
    }
    let rows: Vec<u64> = std::fs::read_to_string(out.join("report.jsonl"))
        .unwrap()
        .lines()
        .map(|line| {
            serde_json::from_str::<serde_json::Value>(line).unwrap()["frame"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert_eq!(
        rows,
        (1..=8).collect::<Vec<u64>>(),
        "one report row per frame"
    );
    let hidden: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|entry| entry.file_name().to_string_lossy().into_owned())
        .filter(|name| name.contains(".tmp-"))
        .collect();
    assert!(hidden.is_empty(), "temporary files left: {hidden:?}");

    let mut resume = render_args(&scene, &out, "1-8");
    resume.push("--resume".into());
    let text = expect_success(&spawn(&resume).wait_with_output().unwrap());
    assert!(
        text.contains("resume: 8 of 8 frame(s) complete from the same inputs, skipped (1-8); nothing to render"),
        "{text}"
    );
}

/// A scene of one small rigged character wading (ripples on by default), at `scale`.
fn character_scene(dir: &Path, file: &str, scale: &str) -> PathBuf {
    let model = repo("scenes/assets/RiggedSimple.glb");
    let text = format!(
        "name = \"wading\"\n[timeline]\nfps = 24\nframes = [1, 8]\n\n[[character]]\nfile = {:?}\nscale = {scale}\n",
        model.display().to_string()
    );
    let path = dir.join(file);
    std::fs::write(&path, text).unwrap();
    path
}

/// The checkpoint folders of scene `wading` under `out`.
fn checkpoint_folders(out: &Path) -> Vec<PathBuf> {
    let mut folders: Vec<PathBuf> = std::fs::read_dir(out.join(".snell-sim"))
        .unwrap()
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| {
            path.is_dir()
                && path
                    .file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with("wading-")
        })
        .collect();
    folders.sort();
    folders
}

#[test]
fn two_versions_of_a_scene_at_once_keep_their_own_checkpoints() {
    let temp = tempfile::tempdir().unwrap();
    let original = character_scene(temp.path(), "original.toml", "0.15");
    let edited = character_scene(temp.path(), "edited.toml", "0.16");
    let out = temp.path().join("shared");
    // Before the fix the process that opened its checkpoints second deleted the other's folder,
    // and the other then failed writing its next checkpoint.
    run_at_once(&[
        render_args(&original, &out, "1-6"),
        render_args(&edited, &out, "1-6"),
    ]);
    let folders = checkpoint_folders(&out);
    assert_eq!(folders.len(), 2, "one folder per version: {folders:?}");
    for folder in &folders {
        for frame in 1..=6 {
            let path = folder.join(format!("ripples-{frame:06}.bin"));
            assert!(path.is_file(), "{} missing", path.display());
        }
    }
    // Each version, opened again, finds its own latest checkpoint for frame 8 (frame 6), and its
    // ripples there equal those stepped from calm water without any checkpoint.
    for scene in [&original, &edited] {
        let job = RenderJob::prepare(scene).unwrap();
        job.use_checkpoints(&out).unwrap();
        let simulation = job.dynamics.simulation.as_ref().expect("ripples are on");
        assert_eq!(simulation.source_for(8), StateSource::Checkpoint(6));
        let from_checkpoint = job
            .frame_water(8, &mut Default::default())
            .unwrap()
            .ripples
            .unwrap();
        assert_eq!(simulation.frames_stepped(), 2, "stepped 7 and 8 only");
        let fresh = RenderJob::prepare(scene).unwrap();
        let from_calm = fresh
            .frame_water(8, &mut Default::default())
            .unwrap()
            .ripples
            .unwrap();
        assert_eq!(from_checkpoint.height_m, from_calm.height_m);
    }
    // Both versions were opened again above: both folders are still there.
    assert_eq!(checkpoint_folders(&out), folders);
}

/// `--frames` takes lists and steps; with stdout not a terminal (a pipe here) each written frame
/// is one line on stdout, and `--log-json` makes that line JSON.
#[test]
fn frame_lists_and_one_line_per_frame_on_a_pipe() {
    let temp = tempfile::tempdir().unwrap();
    let scene = tiny_with_eight_frames(temp.path());
    let out = temp.path().join("out");
    let output = Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(render_args(&scene, &out, "1-8x3,8"))
        .output()
        .unwrap();
    expect_success(&output);
    let stdout = String::from_utf8(output.stdout).unwrap();
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 4, "{stdout}");
    for (line, frame) in lines.iter().zip([1u32, 4, 7, 8]) {
        let start = format!("frame {frame}: ");
        assert!(line.starts_with(&start), "{line}");
        assert!(
            line.contains(&format!("tiny.{frame:04}.exr; vertices: ")),
            "{line}"
        );
        assert!(
            line.contains("; triangles: ") && line.contains("boundary "),
            "{line}"
        );
    }
    let mut written: Vec<u32> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter_map(|entry| {
            let name = entry.file_name().to_string_lossy().into_owned();
            name.strip_prefix("tiny.")?
                .strip_suffix(".exr")?
                .parse()
                .ok()
        })
        .collect();
    written.sort();
    assert_eq!(written, [1, 4, 7, 8]);

    let mut json = render_args(&scene, &out, "2,3");
    json.push("--log-json".into());
    let output = Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(json)
        .output()
        .unwrap();
    expect_success(&output);
    let rows: Vec<serde_json::Value> = String::from_utf8(output.stdout)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    let frames: Vec<u64> = rows
        .iter()
        .map(|row| row["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, [2, 3]);
    for row in &rows {
        assert!(row["secs"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["counts"]["vertices"]["convergence"].is_u64(), "{row}");
        assert!(row["path"].as_str().unwrap().ends_with(".exr"), "{row}");
    }

    for (list, says) in [
        ("1-8x0", "the step must be at least 1"),
        ("1,,2", "item 2 is empty"),
        ("7-9", "frame(s) 9 lie outside the scene's timeline"),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_snell"))
            .args(render_args(&scene, &out, list))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{list}: {text}");
        assert!(text.contains(says), "{list}: {text}");
    }
}

/// `--out` as a file pattern: `#` runs and husk's `$F4` give the padding; the report goes in the
/// pattern's folder and `--resume` with the same pattern keeps the frames.
#[test]
fn output_patterns_name_the_frames() {
    let temp = tempfile::tempdir().unwrap();
    let scene = tiny_with_eight_frames(temp.path());
    let pattern = temp.path().join("shots/pool/render.####.exr");
    expect_success(
        &Command::new(env!("CARGO_BIN_EXE_snell"))
            .args(render_args(&scene, &pattern, "1"))
            .output()
            .unwrap(),
    );
    let folder = temp.path().join("shots/pool");
    let mut names: Vec<String> = std::fs::read_dir(&folder)
        .unwrap()
        .flatten()
        .map(|entry| entry.file_name().to_string_lossy().into_owned())
        .filter(|name| !name.starts_with('.'))
        .collect();
    names.sort();
    assert_eq!(names, ["render.0001.exr", "report.jsonl"]);
    let (_, meta) = read_frame_exr(&folder.join("render.0001.exr")).unwrap();
    assert_eq!(meta.frame, 1);
    let mut resume = render_args(&scene, &pattern, "1");
    resume.push("--resume".into());
    let text = expect_success(&spawn(&resume).wait_with_output().unwrap());
    assert!(text.contains("nothing to render"), "{text}");

    let husk = temp.path().join("husk/beauty_$F6.exr");
    expect_success(
        &Command::new(env!("CARGO_BIN_EXE_snell"))
            .args(render_args(&scene, &husk, "3"))
            .output()
            .unwrap(),
    );
    assert!(temp.path().join("husk/beauty_000003.exr").is_file());

    let bad = temp.path().join("shots/render.####.png");
    let output = Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(render_args(&scene, &bad, "3"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{text}");
    assert!(text.contains("the file name must end with .exr"), "{text}");
}
