//! What the command-line tests share: the smallest shipped scene and a way to run the binary.
// Each test crate compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// `scenes/tiny.toml`, written into each test's temporary directory so renders stay small.
pub const TINY: &str = include_str!("../../scenes/tiny.toml");

/// Runs `snell ARGS` in `cwd` and returns what it printed and its exit status.
pub fn snell(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the snell binary runs")
}

/// `render SCENE --out OUT --frames FRAMES --size SIZE`, as owned arguments.
pub fn render_args(scene: &Path, out: &Path, frames: &str, size: &str) -> Vec<String> {
    vec![
        "render".into(),
        scene.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--frames".into(),
        frames.into(),
        "--size".into(),
        size.into(),
    ]
}

/// What a command printed, as text.
pub fn text_of(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Asserts that the command of `output` exited 0 (showing both its streams when not) and
/// returns what it printed on stdout.
pub fn stdout_of_success(output: &Output) -> String {
    let (stdout, stderr) = (text_of(&output.stdout), text_of(&output.stderr));
    assert!(
        output.status.success(),
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    stdout
}

/// The CSV file at `path`, whose first line must be `header`: its whole text.
pub fn csv_with_header(path: &Path, header: &str) -> String {
    let csv =
        std::fs::read_to_string(path).unwrap_or_else(|error| panic!("{}: {error}", path.display()));
    assert_eq!(csv.lines().next(), Some(header), "{}", path.display());
    csv
}

/// A scene written as `text` to `<target tmp>/<folder>/<name>.toml`, loaded, with `method`.
pub fn scene_job(
    folder: &str,
    name: &str,
    text: &str,
    method: snell::frame::Method,
) -> snell::frame::RenderJob {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(folder);
    std::fs::create_dir_all(&dir).expect("the test's folder can be made");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).expect("the scene can be written");
    let mut job = snell::frame::RenderJob::prepare(&path).unwrap_or_else(|error| panic!("{error}"));
    job.method = method;
    job
}
