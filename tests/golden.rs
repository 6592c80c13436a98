//! Golden frames of `scenes/pool.toml` and `scenes/fox_wading.toml` at 320x180, checked by the code
//! behind `snell check` ([`snell::check::scene::SceneCheck`]): each frame rendered exactly as
//! `snell render` renders it, compared with the committed EXR golden `tests/golden/<scene>.NNNN.exr`
//! by FLIP on the tone-mapped beauty (mean and 99th percentile), `Z` and `P` within tolerances, and
//! the flag counts exactly, all at the default thresholds of `snell diff` (see
//! `snell::check::defaults` for the measurements behind them). Only a pass passes: a warning fails
//! here too. A missing golden FAILS.
//!
//! After an intended change, rewrite the goldens with `SNELL_BLESS=1 cargo test --test golden`
//! (the same as `snell check scenes/pool.toml --golden tests/golden --frames N --size 320x180
//! --bless` per frame). A failing run leaves the renders and `<frame>-difference.png` heat maps in
//! `target/tmp/golden/<scene>/`.

use std::path::{Path, PathBuf};

use snell::check::scene::SceneCheck;
use snell::check::{compare_pair, defaults, FramePair, Thresholds, Verdict};
use snell::frame::RenderJob;

const SIZE: (u32, u32) = (320, 180);

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn bless() -> bool {
    std::env::var("SNELL_BLESS").is_ok_and(|v| v == "1")
}

#[test]
fn pool_golden_frames() {
    golden_frames("pool", &[1, 24, 48]);
}

/// The fox wading: skinned character, split at the water line, ripples in its wake (stepped from
/// frame 1 through checkpoints in the work directory).
#[test]
fn fox_wading_golden_frames() {
    golden_frames("fox_wading", &[12, 36]);
}

/// Renders `frames` of `scenes/<stem>.toml` and checks each against its golden.
fn golden_frames(stem: &str, frames: &[u32]) {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{stem}.toml"));
    let job = RenderJob::prepare(&scene).expect("the scene loads");
    let work_dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("golden")
        .join(stem);
    let golden = golden_dir();
    let check = SceneCheck {
        job: &job,
        frames: frames.to_vec(),
        size: SIZE,
        golden_dir: &golden,
        work_dir: &work_dir,
        thresholds: Thresholds::default(),
        progress: false,
    };
    if bless() {
        let written = check.bless().unwrap_or_else(|error| panic!("{error}"));
        eprintln!("blessed {written:?}");
        return;
    }
    let report = check
        .check(Some(&work_dir))
        .unwrap_or_else(|error| panic!("{error}"));
    eprintln!("{}", report.table());

    // The thresholds must be able to fail: two frames of the same shot (camera moved, waves moved)
    // must fail against each other, or the golden test would accept a broken render.
    for &later in &frames[1..] {
        let between = compare_pair(
            &FramePair {
                name: format!("frame {} vs {later}", frames[0]),
                reference: check.rendered_path(frames[0]),
                test: check.rendered_path(later),
                missing_reference_hint: String::new(),
            },
            &Thresholds::default(),
            None,
        )
        .unwrap_or_else(|error| panic!("{error}"));
        let flip_mean = between.metrics.as_ref().expect("same size").flip_mean;
        assert!(
            between.verdict() == Verdict::Fail && flip_mean > defaults::FLIP_MEAN_FAIL,
            "frames {} and {later} differ by a mean FLIP of only {flip_mean} ({}): the thresholds are too loose",
            frames[0],
            between.reasons()
        );
    }

    let not_passed: Vec<String> = report
        .frames
        .iter()
        .filter(|frame| frame.verdict() != Verdict::Pass)
        .map(|frame| {
            format!(
                "{} {}: {}",
                frame.verdict().label(),
                frame.name,
                frame.reasons()
            )
        })
        .collect();
    assert!(
        not_passed.is_empty(),
        "golden frames of {stem} differ (renders and heat maps in {}):\n{}\n\
         If the change is intended, rewrite the goldens with SNELL_BLESS=1 cargo test --test golden",
        work_dir.display(),
        not_passed.join("\n")
    );
}
