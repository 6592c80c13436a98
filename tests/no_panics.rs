//! Write errors on stdout and stderr end quietly (issue 19 point 3): a closed pipe or a full disk
//! is exit 1 for a command whose product is what it prints, the render's exit code otherwise, and
//! never a panic (exit 101).

mod common;
use common::TINY;

use std::os::fd::{FromRawFd, OwnedFd};
use std::path::Path;
use std::process::{Command, Output, Stdio};

/// A pipe whose read end is already closed: every write to the other end fails with EPIPE.
fn broken_pipe() -> Stdio {
    let mut fds = [0; 2];
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    unsafe { libc::close(fds[0]) };
    Stdio::from(unsafe { OwnedFd::from_raw_fd(fds[1]) })
}

fn dev_full() -> Stdio {
    Stdio::from(
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap(),
    )
}

fn run(args: &[&str], cwd: &Path, stdout: Stdio, stderr: Stdio) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .current_dir(cwd)
        .stdout(stdout)
        .stderr(stderr)
        .output()
        .expect("snell runs")
}

/// `snell render tiny.toml --out out --size 64x36 --frames FRAMES` in `cwd`.
fn render_tiny(cwd: &Path, frames: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_snell"));
    command
        .args(["render", "tiny.toml", "--out", "out", "--size", "64x36"])
        .args(["--frames", frames])
        .current_dir(cwd);
    command
}

#[test]
fn printing_commands_fail_quietly_when_stdout_cannot_be_written() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    // `snell info tiny.toml | true`: exit 1 (its product was lost), nothing said about the pipe.
    let output = run(
        &["info", "tiny.toml"],
        dir.path(),
        broken_pipe(),
        Stdio::piped(),
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "stderr:\n{stderr}");
    assert!(stderr.is_empty(), "a closed pipe is no news:\n{stderr}");
    // `--help > /dev/full`: exit 1 with the cause.
    let output = run(
        &["info", "tiny.toml"],
        dir.path(),
        dev_full(),
        Stdio::piped(),
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "stderr:\n{stderr}");
    assert!(
        stderr.contains("cannot write the output to stdout"),
        "{stderr}"
    );
    let output = run(&["--help"], dir.path(), broken_pipe(), Stdio::piped());
    assert_eq!(output.status.code(), Some(1));
    assert!(output.stderr.is_empty());
}

#[test]
fn errors_keep_their_exit_code_when_stderr_cannot_be_written() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.toml"), "[water]\nn_below = -1\n").unwrap();
    for stderr in [broken_pipe(), dev_full()] {
        let output = run(&["info", "bad.toml"], dir.path(), Stdio::piped(), stderr);
        assert_eq!(output.status.code(), Some(2));
    }
    // A usage error too.
    let output = run(
        &["render", "--size"],
        dir.path(),
        Stdio::piped(),
        dev_full(),
    );
    assert_eq!(output.status.code(), Some(2));
}

#[test]
fn a_render_whose_frames_are_written_succeeds_with_both_streams_closed() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let output = render_tiny(dir.path(), "1")
        .stdout(broken_pipe())
        .stderr(broken_pipe())
        .output()
        .expect("snell runs");
    assert_eq!(output.status.code(), Some(0));
    let frames: Vec<_> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "exr"))
        .collect();
    assert_eq!(frames.len(), 1, "{frames:?}");
}

/// A panic on one of a frame's rayon workers (injected with the test hook
/// `SNELL_TEST_PANIC_FRAME`, src/panics.rs) is exit 1 with one paragraph naming the frame, no
/// panic report, and no file for that frame; the frame before it is written.
#[test]
fn a_panic_in_a_frames_worker_is_exit_1_naming_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let output = render_tiny(dir.path(), "1-3")
        .env(snell::panics::TEST_PANIC_VARIABLE, "2")
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("snell runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("frame 2: internal error: an injected panic"),
        "{stderr}"
    );
    assert!(stderr.contains("this is a bug in snell"), "{stderr}");
    assert!(!stderr.contains("panicked at"), "a panic report:\n{stderr}");
    let files: Vec<String> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        files.iter().any(|name| name == "tiny.0001.exr"),
        "{files:?}"
    );
    assert!(
        !files
            .iter()
            .any(|name| name.contains("0002") || name.contains("0003")),
        "nothing of frames 2 and 3 is left: {files:?}"
    );
}
