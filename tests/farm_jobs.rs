//! The farm's jobs outside a scheduler (issue 15): `snell farm simulate` leaves every checkpoint the
//! chunks read, so a chunk steps no ripple frame and renders the frames a whole local render makes;
//! `snell farm check` reads the output folder without creating anything in it; and the Open Job
//! Description template `snell farm openjd` writes passes `openjd check` and renders, under
//! `openjd run`, a chunk whose frames are bit for bit the local ones.
//!
//! The OpenJD test runs the `openjd` CLI of the venv .ci/run makes (pip `openjd-cli` in
//! target/openjd-venv); it fails, saying so, when that is missing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

const SIZE: &str = "64x36";

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn snell(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .output()
        .expect("the snell binary runs")
}

fn text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

fn ok(output: Output) -> String {
    let text = text(&output);
    assert!(output.status.success(), "snell failed: {text}");
    text
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn render(out: &Path, frames: &str) -> String {
    let scene = repo("scenes/fox_wading.toml");
    let args = common::render_args(&scene, out, frames, SIZE);
    ok(snell(&args.iter().map(String::as_str).collect::<Vec<_>>()))
}

fn frame_bytes(out: &Path, frame: u32) -> Vec<u8> {
    let file = out.join(format!("fox_wading.{frame:04}.exr"));
    std::fs::read(&file).unwrap_or_else(|error| panic!("{}: {error}", file.display()))
}

/// `snell farm simulate` of fox_wading's `frames` into `out`.
fn simulate(out: &Path, frames: &str) -> String {
    let scene = repo("scenes/fox_wading.toml");
    ok(snell(&[
        "farm",
        "simulate",
        path(&scene),
        "--frames",
        frames,
        "--out",
        path(out),
    ]))
}

/// The number in "ripples: stepped N frame(s)" of a render's output.
fn stepped(render_output: &str) -> u64 {
    let line = render_output
        .lines()
        .find(|line| line.starts_with("ripples: stepped "))
        .unwrap_or_else(|| panic!("no ripples line in: {render_output}"));
    line["ripples: stepped ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn chunks_after_the_simulation_job_step_no_ripples_and_match_a_whole_render() {
    let temp = tempfile::tempdir().unwrap();
    let whole = temp.path().join("whole");
    render(&whole, "1-6");

    // Without the simulation job, a chunk from frame 4 steps the ripples from frame 1: 1->3 for
    // frame 3 (the previous frame, for popping), then 4, 5, 6.
    let alone = temp.path().join("alone");
    assert_eq!(stepped(&render(&alone, "4-6")), 5);

    let shared = temp.path().join("shared");
    let first = simulate(&shared, "1-6");
    assert!(first.contains("5 frame(s) stepped"), "{first}");
    assert!(
        !shared.join("fox_wading.0001.exr").exists(),
        "the simulation renders nothing"
    );
    // Both chunks read every state they need.
    for chunk in ["1-3", "4-6"] {
        let output = render(&shared, chunk);
        assert_eq!(stepped(&output), 0, "chunk {chunk}: {output}");
    }
    for frame in 1..=6 {
        assert!(
            frame_bytes(&shared, frame) == frame_bytes(&whole, frame),
            "frame {frame} of the chunks differs from the whole render's"
        );
    }
    // A second simulation finds every checkpoint there.
    let again = simulate(&shared, "1-6");
    assert!(again.contains("0 frame(s) stepped"), "{again}");
}

#[test]
fn farm_check_creates_nothing_in_the_output_folder() {
    let temp = tempfile::tempdir().unwrap();
    let scene = temp.path().join("tiny.toml");
    std::fs::write(&scene, common::TINY).unwrap();
    let missing = temp.path().join("never-rendered");
    let output = snell(&["farm", "check", path(&scene), "--out", path(&missing)]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    assert!(text(&output).contains("missing (1-3)"), "{}", text(&output));
    assert!(
        !missing.exists(),
        "farm check created {}",
        missing.display()
    );

    let empty = temp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let output = snell(&["farm", "check", path(&scene), "--out", path(&empty)]);
    assert_eq!(output.status.code(), Some(1), "{}", text(&output));
    let left: Vec<_> = std::fs::read_dir(&empty).unwrap().flatten().collect();
    assert!(left.is_empty(), "farm check wrote {left:?}");
}

fn openjd() -> PathBuf {
    let path = repo("target/openjd-venv/bin/openjd");
    assert!(
        path.is_file(),
        "{} is missing: this test runs the openjd CLI from pip's openjd-cli in a venv there \
         (bash .ci/run makes it: python3 -m venv target/openjd-venv && target/openjd-venv/bin/pip install openjd-cli)",
        path.display()
    );
    path
}

fn run_openjd(args: &[&str]) -> String {
    let output = Command::new(openjd())
        .args(args)
        .output()
        .expect("openjd runs");
    let text = text(&output);
    assert!(output.status.success(), "openjd {args:?} failed: {text}");
    text
}

#[test]
fn the_openjd_template_checks_and_its_chunk_renders_the_local_frames() {
    let temp = tempfile::tempdir().unwrap();
    let scene = repo("scenes/fox_wading.toml");
    let local = temp.path().join("local");
    render(&local, "1-4");

    let out = temp.path().join("openjd");
    let wrote = ok(snell(&[
        "farm",
        "openjd",
        path(&scene),
        "--frames",
        "1-4",
        "--chunk",
        "2",
        "--size",
        SIZE,
        "--out",
        path(&out),
    ]));
    let template = out.join("farm/job.template.json");
    assert!(wrote.contains("2 chunk(s)"), "{wrote}");
    let checked = run_openjd(&["check", path(&template)]);
    assert!(
        checked.to_lowercase().contains("passes"),
        "openjd check: {checked}"
    );

    // The Render step's second chunk, after the Simulate step it depends on.
    let ran = run_openjd(&[
        "run",
        path(&template),
        "--step",
        "Render",
        "--task-param",
        "Frames=3-4",
        "--run-dependencies",
    ]);
    assert!(
        ran.contains("Running step 'Simulate'") && ran.contains("simulate: ripples of fox_wading"),
        "the Simulate step ran: {ran}"
    );
    assert!(
        ran.contains("ripples: stepped 0 frame(s)"),
        "the chunk read the simulation's checkpoints: {ran}"
    );
    for frame in [3, 4] {
        assert!(
            frame_bytes(&out, frame) == frame_bytes(&local, frame),
            "frame {frame} from openjd run differs from the local render's"
        );
    }
    for frame in [1, 2] {
        assert!(
            !out.join(format!("fox_wading.{frame:04}.exr")).exists(),
            "only the chunk given ran"
        );
    }
}
