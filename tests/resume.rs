//! Renders that survive failure, through the `snell` binary as a user runs it: a render killed
//! with SIGKILL leaves only complete frames and resumes to exactly what an uninterrupted run makes;
//! `--resume` keeps complete frames made from the same inputs and re-renders the others (other
//! size, truncated file, missing report row); Ctrl-C stops after the frame in flight with exit 130
//! and no temporary file; a second Ctrl-C stops at once and still leaves no temporary file; stale
//! temporary files of dead processes go at the next start; an unusable output directory is exit 2
//! and a write failing mid-render exit 1, each with a message naming the path and the cause.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime};

use snell::output::read_frame_exr;

mod common;
use common::render_args;

const SIZE: &str = "160x90";

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn snell(args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .output()
        .expect("the snell binary runs")
}

fn spawn(args: &[String]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the snell binary starts")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn expect_success(output: &Output) -> String {
    let text = stderr(output);
    assert!(output.status.success(), "snell failed: {text}");
    text
}

/// Frame files (`<scene>.NNNN.exr`, not hidden) in `dir`, sorted by frame.
fn frame_files(dir: &Path) -> Vec<(u32, PathBuf)> {
    let mut frames: Vec<(u32, PathBuf)> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .filter_map(|entry| {
                    let name = entry.file_name().to_string_lossy().into_owned();
                    if name.starts_with('.') {
                        return None;
                    }
                    let number = name.strip_suffix(".exr")?.rsplit_once('.')?.1;
                    Some((number.parse().ok()?, entry.path()))
                })
                .collect()
        })
        .unwrap_or_default();
    frames.sort();
    frames
}

/// Temporary files (`.<name>.tmp-<pid>.<host>`) anywhere under `dir`.
fn temporary_files(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(folder) = stack.pop() {
        for entry in std::fs::read_dir(&folder).into_iter().flatten().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if entry.file_name().to_string_lossy().contains(".tmp-") {
                found.push(path);
            }
        }
    }
    found
}

/// Waits until `dir` holds at least one frame (at most a minute).
fn wait_for_first_frame(child: &mut Child, dir: &Path) -> usize {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let count = frame_files(dir).len();
        if count > 0 {
            return count;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("snell ended ({status}) before writing a frame");
        }
        assert!(Instant::now() < deadline, "no frame after 60 s");
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn send_signal(child: &Child, signal: libc::c_int) {
    // SAFETY: kill has no memory effects; the pid is our own child's, not yet reaped.
    let result = unsafe { libc::kill(child.id() as libc::pid_t, signal) };
    assert_eq!(result, 0, "kill failed");
}

/// Every frame file reads back whole.
fn assert_all_complete(dir: &Path) {
    for (frame, path) in frame_files(dir) {
        if let Err(error) = read_frame_exr(&path) {
            panic!("frame {frame} is not complete: {error}");
        }
    }
}

/// Report rows by frame, without the wall-clock seconds (which differ between any two runs).
fn report_rows(dir: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(dir.join("report.jsonl"))
        .unwrap_or_default()
        .lines()
        .map(|line| {
            let mut row: serde_json::Value = serde_json::from_str(line).unwrap();
            row.as_object_mut().unwrap().remove("stage_secs");
            row
        })
        .collect()
}

/// The frames of `a` and `b` are equal: every pixel of every layer bit for bit, every header
/// field (the scene path, camera, input hash, version...), and the report rows except the seconds
/// each stage took, the only field that legitimately differs.
fn assert_same_frames(a: &Path, b: &Path) {
    let frames_a = frame_files(a);
    let frames_b = frame_files(b);
    assert_eq!(
        frames_a.iter().map(|(f, _)| *f).collect::<Vec<_>>(),
        frames_b.iter().map(|(f, _)| *f).collect::<Vec<_>>()
    );
    for ((frame, path_a), (_, path_b)) in frames_a.iter().zip(&frames_b) {
        let (pixels_a, meta_a) = read_frame_exr(path_a).unwrap();
        let (pixels_b, meta_b) = read_frame_exr(path_b).unwrap();
        assert_eq!(meta_a, meta_b, "frame {frame}: header");
        let bits = |values: &[f32]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(pixels_a.beauty_rgba.as_flattened()),
            bits(pixels_b.beauty_rgba.as_flattened()),
            "frame {frame}: beauty"
        );
        assert_eq!(
            bits(&pixels_a.depth_m),
            bits(&pixels_b.depth_m),
            "frame {frame}: Z"
        );
        assert_eq!(
            bits(pixels_a.position.as_flattened()),
            bits(pixels_b.position.as_flattened()),
            "frame {frame}: P"
        );
        assert_eq!(pixels_a.flags, pixels_b.flags, "frame {frame}: flag masks");
    }
    let (rows_a, rows_b) = (report_rows(a), report_rows(b));
    assert_eq!(rows_a.len(), rows_b.len(), "report rows");
    for (row_a, row_b) in rows_a.iter().zip(&rows_b) {
        assert!(
            row_a == row_b,
            "report rows differ (flag counts, hash...):\n{row_a}\n{row_b}"
        );
    }
}

fn modified(path: &Path) -> SystemTime {
    std::fs::metadata(path).unwrap().modified().unwrap()
}

/// SIGKILL mid-render: only complete frames (a temporary file may remain, hidden and named for the
/// dead process, and is never a frame); `--resume` removes it, renders the rest, and the result
/// equals an uninterrupted run's.
#[test]
fn a_killed_render_resumes_to_the_uninterrupted_result() {
    let temp = tempfile::tempdir().unwrap();
    let killed = temp.path().join("killed");
    let whole = temp.path().join("whole");
    let pool = scene("pool.toml");
    let frames = "5-20";

    let mut child = spawn(&render_args(&pool, &killed, frames, SIZE));
    wait_for_first_frame(&mut child, &killed);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let survivors = frame_files(&killed);
    assert!(
        !survivors.is_empty() && survivors.len() < 16,
        "killed after {} of 16 frames: not mid-way",
        survivors.len()
    );
    assert_all_complete(&killed);
    let leftovers = temporary_files(&killed);
    for path in &leftovers {
        let name = path.file_name().unwrap().to_string_lossy();
        assert!(
            name.starts_with('.') && name.contains(&format!(".tmp-{}.", child.id())),
            "{name}"
        );
    }

    // A frame is kept only with its report row: the kill may land between the two renames.
    let rows: Vec<u64> = report_rows(&killed)
        .iter()
        .map(|row| row["frame"].as_u64().unwrap())
        .collect();
    let kept = survivors
        .iter()
        .filter(|(frame, _)| rows.contains(&u64::from(*frame)))
        .count();
    let mut args = render_args(&pool, &killed, frames, SIZE);
    args.push("--resume".into());
    let resumed = expect_success(&snell(&args));
    assert!(
        resumed.contains(&format!(
            "resume: {kept} of 16 frame(s) complete from the same inputs, skipped"
        )),
        "{resumed}"
    );
    if kept < survivors.len() {
        assert!(
            resumed.contains("1 without a current report row"),
            "{resumed}"
        );
    }
    if !leftovers.is_empty() {
        assert!(
            resumed.contains("removed 1 temporary file(s) left by a render that was killed"),
            "{resumed}"
        );
    }
    assert_eq!(temporary_files(&killed), Vec::<PathBuf>::new());

    expect_success(&snell(&render_args(&pool, &whole, frames, SIZE)));
    assert_same_frames(&killed, &whole);
}

/// Complete frames of the same inputs are kept untouched; a frame made at another size, a
/// truncated frame and a frame without a report row are rendered again, and each reason is said.
#[test]
fn resume_keeps_current_frames_and_renders_the_others() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("tiny");
    let reference = temp.path().join("reference");
    let tiny = scene("tiny.toml");
    expect_success(&snell(&render_args(&tiny, &reference, "1-3", SIZE)));
    expect_success(&snell(&render_args(&tiny, &out, "1-3", SIZE)));
    let path = |frame: u32| out.join(format!("tiny.{frame:04}.exr"));
    let rows_before = std::fs::read_to_string(out.join("report.jsonl")).unwrap();

    // The input hash is in the header and in the report row.
    let (_, meta) = read_frame_exr(&path(1)).unwrap();
    let hash = meta
        .text_attributes
        .iter()
        .find(|(key, _)| key == "inputHash")
        .map(|(_, value)| value.clone())
        .expect("snell.extra.inputHash in the header");
    assert_eq!(hash.len(), 64);
    assert_eq!(report_rows(&out)[0]["input_hash"], hash.as_str());

    // Nothing to do: every frame kept, untouched, and its report row too.
    let times: Vec<SystemTime> = (1..=3).map(|f| modified(&path(f))).collect();
    let mut resume = render_args(&tiny, &out, "1-3", SIZE);
    resume.push("--resume".into());
    let text = expect_success(&snell(&resume));
    assert!(
        text.contains("resume: 3 of 3 frame(s) complete from the same inputs, skipped (1-3); nothing to render"),
        "{text}"
    );
    assert!(
        text.contains("nothing to render: the 3 frame(s) of tiny at 160x90 in"),
        "{text}"
    );
    assert_eq!(
        (1..=3).map(|f| modified(&path(f))).collect::<Vec<_>>(),
        times
    );
    assert_eq!(
        std::fs::read_to_string(out.join("report.jsonl")).unwrap(),
        rows_before
    );

    // Frame 2 made at another size (another hash), frame 3 truncated.
    expect_success(&snell(&render_args(&tiny, &out, "2", "96x54")));
    let bytes = std::fs::read(path(3)).unwrap();
    std::fs::write(path(3), &bytes[..bytes.len() / 2]).unwrap();
    let text = expect_success(&snell(&resume));
    assert!(
        text.contains("resume: 1 of 3 frame(s) complete from the same inputs, skipped (1); rendering 2: 1 made from other inputs, hash differs (2), 1 unreadable (frame 3: "),
        "{text}"
    );
    assert_eq!(modified(&path(1)), times[0], "frame 1 kept");
    assert_same_frames(&out, &reference);

    // A frame whose report row is gone (a process killed between the frame and its row).
    let rows: Vec<String> = std::fs::read_to_string(out.join("report.jsonl"))
        .unwrap()
        .lines()
        .filter(|line| !line.starts_with("{\"frame\":1,"))
        .map(|line| format!("{line}\n"))
        .collect();
    std::fs::write(out.join("report.jsonl"), rows.concat()).unwrap();
    let text = expect_success(&snell(&resume));
    assert!(
        text.contains("rendering 1: 1 without a current report row (1)"),
        "{text}"
    );
    assert_same_frames(&out, &reference);
}

/// Ctrl-C: the frame in flight is finished and written, then snell says what is done and how to
/// finish, and exits with 130; no temporary file stays and every frame is complete.
#[test]
fn ctrl_c_stops_after_the_frame_in_flight() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("pool");
    let mut child = spawn(&render_args(&scene("pool.toml"), &out, "1-16", SIZE));
    let seen = wait_for_first_frame(&mut child, &out);
    send_signal(&child, libc::SIGINT);
    let output = child.wait_with_output().unwrap();
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(130), "{text}");
    let frames = frame_files(&out);
    // At most: the one being written, the one queued for the writer, the one being rendered.
    assert!(
        frames.len() <= seen + 3 && frames.len() < 16,
        "{} frames after the signal at {seen}: {text}",
        frames.len()
    );
    assert_all_complete(&out);
    assert_eq!(temporary_files(&out), Vec::<PathBuf>::new());
    assert_eq!(report_rows(&out).len(), frames.len(), "a row per frame");
    let done = format!(
        "interrupted: {} of 16 frame(s) done in {} (1-{})",
        frames.len(),
        out.display(),
        frames.len()
    );
    assert!(text.contains(&done), "{text}");
    assert!(
        text.contains("--frames 1-16 --out") && text.contains("--size 160x90 --resume"),
        "{text}"
    );
}

/// SIGTERM (what service managers and `kill` send) stops the same way, with 128 + 15.
#[test]
fn sigterm_stops_after_the_frame_in_flight_with_143() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("pool");
    let mut child = spawn(&render_args(&scene("pool.toml"), &out, "1-16", SIZE));
    wait_for_first_frame(&mut child, &out);
    send_signal(&child, libc::SIGTERM);
    let output = child.wait_with_output().unwrap();
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(143), "{text}");
    assert!(
        text.contains("SIGTERM received: stopping after the frame in flight"),
        "{text}"
    );
    assert!(frame_files(&out).len() < 16, "{text}");
    assert_all_complete(&out);
    assert_eq!(temporary_files(&out), Vec::<PathBuf>::new());
}

/// A second Ctrl-C exits at once (still 130), removing this process's temporary files; the frames
/// already written are complete.
#[test]
fn a_second_ctrl_c_stops_at_once_without_temporary_files() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("pool");
    let mut child = spawn(&render_args(&scene("pool.toml"), &out, "1-16", SIZE));
    wait_for_first_frame(&mut child, &out);
    send_signal(&child, libc::SIGINT);
    std::thread::sleep(Duration::from_millis(30));
    send_signal(&child, libc::SIGINT);
    let output = child.wait_with_output().unwrap();
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(130), "{text}");
    assert!(text.contains("again: stopped at once"), "{text}");
    assert_eq!(temporary_files(&out), Vec::<PathBuf>::new());
    assert_all_complete(&out);
    assert!(frame_files(&out).len() < 16);
}

/// Temporary files whose process is dead are removed when the next render starts there; those of
/// a live process (this test) stay.
#[test]
fn stale_temporary_files_are_removed_at_the_next_start() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("tiny");
    std::fs::create_dir_all(out.join(".snell-sim/tiny-0123")).unwrap();
    // Above the kernel's largest pid (4194304 on 64-bit Linux): never running.
    let dead = out.join(".tiny.0002.exr.tmp-99999999");
    let dead_checkpoint = out.join(".snell-sim/tiny-0123/.ripples-000002.bin.tmp-99999999");
    let live = out.join(format!(".tiny.0003.exr.tmp-{}", std::process::id()));
    for path in [&dead, &dead_checkpoint, &live] {
        std::fs::write(path, b"half a frame").unwrap();
    }
    let text = expect_success(&snell(&render_args(&scene("tiny.toml"), &out, "1", SIZE)));
    assert!(
        text.contains("removed 2 temporary file(s) left by a render that was killed"),
        "{text}"
    );
    assert!(!dead.exists() && !dead_checkpoint.exists());
    assert!(live.exists(), "a live process's file is not touched");
}

/// An output location that cannot be used is exit 2 before any work, naming the path and cause.
#[cfg(target_os = "linux")]
#[test]
fn an_unwritable_output_directory_is_exit_2() {
    // /proc refuses new entries even for root, whom permission bits would not stop.
    for (out, message) in [
        (
            "/proc/snell-test",
            "error: cannot create directory /proc/snell-test: ",
        ),
        ("/proc", "error: cannot write into directory /proc: "),
    ] {
        let output = snell(&render_args(&scene("tiny.toml"), Path::new(out), "1", SIZE));
        let text = stderr(&output);
        assert_eq!(output.status.code(), Some(2), "{text}");
        assert!(text.contains(message), "{text}");
        assert!(!text.contains("panicked"), "{text}");
    }
}

/// A write that fails mid-render (here a file size limit, which fails `write` with EFBIG as a full
/// disk fails it with ENOSPC, through the same code) is exit 1 naming the file and the cause,
/// without a panic or a temporary file.
#[cfg(target_os = "linux")]
#[test]
fn a_write_failing_mid_render_is_exit_1() {
    let temp = tempfile::tempdir().unwrap();
    let out = temp.path().join("tiny");
    std::fs::create_dir_all(&out).unwrap();
    let args = render_args(&scene("tiny.toml"), &out, "1-3", SIZE);
    // 100 KiB: the probe fits, a 160x90 frame (about 230 KB) does not.
    let output = with_file_size_limit_kib(100, &args);
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{text}");
    assert!(
        text.contains(&format!(
            "error: cannot write {}: File too large",
            out.join("tiny.0001.exr").display()
        )),
        "{text}"
    );
    assert!(!text.contains("panicked"), "{text}");
    assert_eq!(temporary_files(&out), Vec::<PathBuf>::new());
    assert_eq!(frame_files(&out), Vec::new());

    // The simulation checkpoints (fox_wading's ripple grid, 385x193 nodes: about 600 KB each)
    // go through the same writes: the first one fails before any frame.
    let out = temp.path().join("fox");
    let args = render_args(&scene("fox_wading.toml"), &out, "1", SIZE);
    let output = with_file_size_limit_kib(100, &args);
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(1), "{text}");
    assert!(
        text.contains("error: cannot write the simulation checkpoint ")
            && text.contains("ripples-000001.bin: File too large"),
        "{text}"
    );
    assert_eq!(temporary_files(&out), Vec::<PathBuf>::new());
}

/// Runs snell with `args` under a file size limit, SIGXFSZ ignored (ignored signals stay ignored
/// across exec), so a write past the limit fails with EFBIG.
fn with_file_size_limit_kib(limit_kib: u32, args: &[String]) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {limit_kib}; exec \"$@\""))
        .arg("bash")
        .arg(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .output()
        .unwrap()
}
