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
