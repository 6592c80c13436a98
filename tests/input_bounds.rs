//! Every input bounded before work starts (issue 19 points 1 and 2), as a user meets it: a scene
//! or argument over a stated limit is refused by the `snell` binary with exit 2, a message naming
//! the file, the line and the problem (with the number that exceeds), before anything is written
//! and in well under a second. Each case is one of the table rows (memory exhausted,
//! hangs, silently wrong, late errors) or one of the limits of `src/scene/resources.rs`.

mod common;
use common::TINY;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn snell_env(args: &[&str], cwd: &Path, env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_snell"));
    command.args(args).current_dir(cwd);
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().expect("snell runs")
}

/// `snell render SCENE --out DIR/out --size SIZE --frames 1`.
fn render(scene: &Path, dir: &Path, size: &str, env: &[(&str, &str)]) -> Output {
    let out = dir.join("out");
    snell_env(
        &[
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--size",
            size,
            "--frames",
            "1",
        ],
        dir,
        env,
    )
}

/// Asserts exit 2, every needle in stderr, no panic, nothing written under `dir/out`, and an
/// answer within a few seconds (the bound is checked before any work).
fn assert_refused(output: &Output, elapsed: Duration, dir: &Path, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(
        output.status.code(),
        Some(2),
        "exit code; stderr:\n{stderr}"
    );
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "stderr should contain {needle:?}:\n{stderr}"
        );
    }
    assert!(!stderr.contains("panicked"), "a panic:\n{stderr}");
    assert!(
        !dir.join("out").exists(),
        "a refused render created its output folder"
    );
    assert!(
        elapsed < Duration::from_secs(20),
        "refused only after {elapsed:?}: the bound must be checked before the work"
    );
    stderr
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("{needle:?} is not in the scene"))
        + 1
}

/// Writes `text` as `DIR/bad.toml`, renders it and expects a refusal at `bad.toml:LINE:` where
/// LINE holds `marked`, with `needles` in the message.
fn expect_refused_at(text: &str, marked: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(&scene, text).unwrap();
    let location = format!("bad.toml:{}:", line_of(text, marked));
    let clock = Instant::now();
    let output = render(&scene, dir.path(), "64x36", &[]);
    let mut all = vec![location.as_str()];
    all.extend_from_slice(needles);
    assert_refused(&output, clock.elapsed(), dir.path(), &all);
}

fn edit(from: &str, to: &str) -> String {
    assert!(TINY.contains(from), "tiny.toml no longer contains {from:?}");
    TINY.replacen(from, to, 1)
}

#[test]
fn numbers_outside_their_stated_range_are_refused_where_they_are_written() {
    // The rows: each would overflow f32 or exhaust memory further on.
    let cases = [
        // absorption 1e39: NaN pixels.
        (
            edit(
                "resolution = [16, 16]",
                "resolution = [16, 16]\nabsorption_per_m = [1e39, 0.1, 0.1]",
            ),
            "absorption_per_m",
            vec!["water.absorption_per_m[0]", "from 0 to 1000", "(got 1e39)"],
        ),
        // An eye overflowing f32.
        (
            edit("eye = [0.0, 1.8, -2.2]", "eye = [0.0, 1e39, -2.2]"),
            "eye =",
            vec!["camera[0].eye[1]", "(got 1e39)"],
        ),
        // scale 1e30.
        (
            edit("radius_m = 0.2", "radius_m = 0.2\nscale = [1e30, 1.0, 1.0]"),
            "scale =",
            vec!["object[1].scale[0]", "(got 1e30)"],
        ),
        // A water extent of 1e12.
        (
            edit("max = [1.0, 1.0]", "max = [1e12, 1.0]"),
            "max = [1e12",
            vec!["water.max[0]", "from -1000 to 1000"],
        ),
        // A sphere of 1e6 m.
        (
            edit("radius_m = 0.2", "radius_m = 1e6"),
            "radius_m = 1e6",
            vec!["object[1].radius_m", "(got 1e6)"],
        ),
        // A checker square of 1e-50.
        (
            edit("square_m = 0.15", "square_m = 1e-50"),
            "square_m = 1e-50",
            vec!["square_m", "(got 1e-50)"],
        ),
        // Frame 4294967295: refused at load, not after rendering.
        (
            edit("frames = [1, 3]", "frames = [1, 4294967295]"),
            "frames = [1, 4294967295]",
            vec!["timeline.frames[1]", "2147483647"],
        ),
        // A sun of 1e39.
        (
            format!("{TINY}\n[sun]\nintensity = 1e39\n"),
            "intensity = 1e39",
            vec!["sun.intensity", "from 0 to 1000"],
        ),
    ];
    for (text, marked, needles) in cases {
        expect_refused_at(&text, marked, &needles);
    }
}

#[test]
fn resource_estimate_over_a_limit_names_the_key_and_the_number() {
    // The documented maximum membrane would need about 55-60 GB: 8192 x 8192 is within the
    // per-side range, but not within the cell limit.
    expect_refused_at(
        &edit("resolution = [16, 16]", "resolution = [8192, 8192]"),
        "resolution = [8192, 8192]",
        &["water.resolution", "67108864 membrane cells", "4194304"],
    );
    // A 300 m sphere at 1 cm spacing: billions of vertices.
    expect_refused_at(
        &edit("radius_m = 0.2", "radius_m = 300.0\nmax_edge_m = 0.01"),
        "max_edge_m = 0.01",
        &["object[1].max_edge_m", "vertices", "4000000"],
    );
    // Within every key's range, but scaled beyond the world.
    expect_refused_at(
        &edit(
            "radius_m = 0.2",
            "radius_m = 100.0\nscale = [100.0, 100.0, 100.0]",
        ),
        "scale = [100.0",
        &["object[1].scale", "beyond the 2000 m"],
    );
    // Ripple nodes.
    expect_refused_at(
        &format!("{TINY}\n[water.ripples]\nenabled = true\nresolution = [4096, 4096]\n"),
        "resolution = [4096, 4096]",
        &["water.ripples.resolution", "16777216 ripple nodes"],
    );
    // A timeline longer than a million frames.
    expect_refused_at(
        &edit("frames = [1, 3]", "frames = [0, 2000000]"),
        "frames = [0, 2000000]",
        &["timeline.frames", "2000001 frames", "1000000"],
    );
}

#[test]
fn too_many_waves_and_objects_are_refused() {
    let wave = "\n[[water.wave]]\namplitude_m = 0.0001\nwavelength_m = 1.0\n";
    let mut text = TINY.to_string();
    for _ in 0..257 {
        text.push_str(wave);
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(&scene, &text).unwrap();
    let clock = Instant::now();
    let output = render(&scene, dir.path(), "64x36", &[]);
    let stderr = assert_refused(
        &output,
        clock.elapsed(),
        dir.path(),
        &["bad.toml:", "water.wave[256]", "258 waves", "256"],
    );
    // The line is the 257th wave's (index 256), 258 counting tiny's own.
    let line: usize = stderr["error: ".len()..]
        .trim_start_matches(|c| c != ':')
        .split(':')
        .nth(1)
        .and_then(|l| l.parse().ok())
        .unwrap_or_else(|| panic!("no line in {stderr}"));
    let wave_256_line = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("[[water.wave]]"))
        .nth(256)
        .unwrap()
        .0
        + 1;
    assert!(
        (wave_256_line..wave_256_line + 3).contains(&line),
        "line {line}, the wave starts at {wave_256_line}: {stderr}"
    );

    let mut text = TINY.to_string();
    for i in 0..1030 {
        text.push_str(&format!(
            "\n[[object]]\nname = \"b{i}\"\nshape = \"sphere\"\nradius_m = 0.01\n"
        ));
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(&scene, &text).unwrap();
    let clock = Instant::now();
    let output = render(&scene, dir.path(), "64x36", &[]);
    assert_refused(
        &output,
        clock.elapsed(),
        dir.path(),
        &["bad.toml:", "object", "1034 objects", "1024"],
    );
}

#[test]
fn names_that_cannot_name_output_files_are_refused_at_load() {
    expect_refused_at(
        &edit("name = \"tiny\"", "name = \"ti\\u0000ny\""),
        "name = ",
        &["name", "cannot name output files", "'\\0'"],
    );
    let long = "n".repeat(300);
    expect_refused_at(
        &edit("name = \"tiny\"", &format!("name = \"{long}\"")),
        "name = ",
        &["name", "300 bytes long", "100"],
    );
}

#[test]
fn scene_files_that_are_not_regular_text_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    // A FIFO with no writer would block a read forever.
    let fifo = dir.path().join("pipe.toml");
    let name = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    let cases: [(PathBuf, &[&str]); 3] = [
        (
            fifo,
            &["pipe.toml", "a FIFO (named pipe), not a regular file"],
        ),
        (
            PathBuf::from("/dev/zero"),
            &["/dev/zero", "a character device"],
        ),
        (dir.path().to_path_buf(), &["a directory"]),
    ];
    for (path, needles) in cases {
        let clock = Instant::now();
        let output = render(&path, dir.path(), "64x36", &[]);
        assert_refused(&output, clock.elapsed(), dir.path(), needles);
    }
    // Latin-1 text: refused at the line and column of the first byte that is not UTF-8.
    let scene = dir.path().join("latin1.toml");
    std::fs::write(&scene, b"# pool\nname = \"caf\xe9\"\n").unwrap();
    let clock = Instant::now();
    let output = render(&scene, dir.path(), "64x36", &[]);
    assert_refused(
        &output,
        clock.elapsed(),
        dir.path(),
        &["latin1.toml:2:12:", "not UTF-8", "0xe9"],
    );
}

#[test]
fn model_files_that_are_devices_are_refused_at_their_line() {
    expect_refused_at(
        &format!("{TINY}\n[[character]]\nfile = \"/dev/zero\"\n"),
        "file = \"/dev/zero\"",
        &["character[0].file", "a character device"],
    );
}

#[test]
fn image_sizes_and_memory_over_the_limits_exit_2_before_any_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    // Over a stated memory limit. (Sizes above the GPU's one readback buffer, refused here before,
    // now render in strips: tests/strips.rs.)
    let clock = Instant::now();
    let output = render(
        &scene,
        dir.path(),
        "1920x1080",
        &[("SNELL_MAX_MEMORY", "400M")],
    );
    assert_refused(
        &output,
        clock.elapsed(),
        dir.path(),
        &["1920x1080", "memory limit of 400 MiB", "SNELL_MAX_MEMORY"],
    );
    // An unreadable limit is named.
    let output = render(&scene, dir.path(), "64x36", &[("SNELL_MAX_MEMORY", "lots")]);
    assert_refused(
        &output,
        Duration::ZERO,
        dir.path(),
        &["SNELL_MAX_MEMORY=\"lots\""],
    );
}

/// Camera keys the renderer used to refuse (straight down) or turn into a NaN matrix (two legal
/// keys whose path passes over the target) now render a finite frame; keys whose interpolated
/// eye lands on its target are an error at the key's line.
#[test]
fn degenerate_cameras_are_handled_or_refused_at_their_line() {
    let down = edit(
        "eye = [0.0, 1.8, -2.2]\ntarget = [0.0, -0.6, 0.3]",
        "eye = [0.0, 3.0, 0.0]\ntarget = [0.0, -0.6, 0.0]",
    );
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("down.toml");
    std::fs::write(&scene, &down).unwrap();
    let output = snell_env(&["info", scene.to_str().unwrap()], dir.path(), &[]);
    assert_eq!(
        output.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );

    let camera = "[[camera]]\neye = [0.0, 1.8, -2.2]\ntarget = [0.0, -0.6, 0.3]\nfov_deg = 50\n";
    let crossing = "[[camera]]\nframe = 1\neye = [-1.0, 0.5, 0.0]\ntarget = [1.0, 0.5, 0.0]\n\n\
                    [[camera]]\nframe = 3\neye = [1.0, 0.5, 0.0]\ntarget = [-1.0, 0.5, 0.0]\n";
    let text = edit(camera, crossing);
    let marked_line = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("target ="))
        .nth(1)
        .unwrap()
        .1
        .to_string();
    expect_refused_at(
        &text,
        &marked_line,
        &[
            "camera[1].target",
            "between camera keys 0 and 1",
            "frame 2",
            "no direction",
        ],
    );
}

/// A command that keeps whole frames (here `snell stability`: this frame's and the previous
/// frame's reference and renders) counts them in its memory estimate, so a size whose strips fit
/// the limit but whose kept frames do not is refused with exit 2 at its first frame, before any
/// frame is rendered, instead of being killed for memory. 4096x4096 under a 3 GiB limit: a render
/// streaming its strips fits (about 2.8 GiB); four kept frames (about 6.3 GiB more) do not.
#[test]
fn commands_that_keep_whole_frames_count_them_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let clock = Instant::now();
    let output = snell_env(
        &[
            "stability",
            "tiny.toml",
            "--frames",
            "1-2",
            "--size",
            "4096x4096",
            "--methods",
            "equal-t",
            "--out",
            "stability",
        ],
        dir.path(),
        &[("SNELL_MAX_MEMORY", "3G")],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("4096x4096") && stderr.contains("memory limit of 3.0 GiB"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "a panic:\n{stderr}");
    // Refused before a 16.8-megapixel frame was drawn (that alone takes minutes here).
    assert!(
        clock.elapsed() < Duration::from_secs(60),
        "{:?}",
        clock.elapsed()
    );
    let written: Vec<_> = std::fs::read_dir(dir.path().join("stability"))
        .map(|entries| entries.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(written.is_empty(), "{written:?}");
}
