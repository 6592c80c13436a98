//! `snell diff` and `snell check` as a CI job meets them, through the built binary: verdicts on
//! real renders of scenes/tiny.toml (160x90) and on edited copies of them (one pixel changed, the
//! ball moved, a flag count changed), idiff's exit codes 0/1/2/4, heat maps only for frames that did
//! not pass, JUnit XML that parses, clear errors for unreadable input, and check/bless of goldens.

mod common;
use common::{snell, TINY};

use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::OnceLock;

use snell::output::{read_frame_exr, write_frame_exr, FrameMeta};

const BALL_AT: &str = "translate = [0.2, -0.6, 0.1]";
const SIZE: &str = "160x90";

fn stdout_and_stderr(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

fn assert_exit(output: &Output, code: i32) -> String {
    let text = stdout_and_stderr(output);
    assert_eq!(output.status.code(), Some(code), "{text}");
    assert!(
        !text.contains("panicked"),
        "a panic is not a verdict:\n{text}"
    );
    text
}

/// Renders frames 1-2 of tiny.toml (with `scene_text`) at 160x90 into `dir/frames`.
fn render_tiny(dir: &Path, scene_text: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let scene = dir.join("tiny.toml");
    std::fs::write(&scene, scene_text).unwrap();
    let out = dir.join("frames");
    let output = snell(
        &[
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "1-2",
            "--size",
            SIZE,
            "--out",
            out.to_str().unwrap(),
        ],
        dir,
    );
    assert_exit(&output, 0);
    out
}

/// Renders shared by the tests (rendered once): tiny.toml as shipped, and with the ball moved 0.15 m.
struct Renders {
    _dir: tempfile::TempDir,
    original: PathBuf,
    ball_moved: PathBuf,
}

fn renders() -> &'static Renders {
    static RENDERS: OnceLock<Renders> = OnceLock::new();
    RENDERS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        assert!(
            TINY.contains(BALL_AT),
            "tiny.toml no longer has the ball at {BALL_AT}"
        );
        let original = render_tiny(&dir.path().join("original"), TINY);
        let moved_text = TINY.replace(BALL_AT, "translate = [0.35, -0.6, 0.1]");
        let ball_moved = render_tiny(&dir.path().join("moved"), &moved_text);
        Renders {
            _dir: dir,
            original,
            ball_moved,
        }
    })
}

fn frame_file(dir: &Path, frame: u32) -> PathBuf {
    dir.join(format!("tiny.{frame:04}.exr"))
}

/// Copies `source` to `destination` after `edit` changed its pixels or its header's extra attributes.
fn edited_copy(
    source: &Path,
    destination: &Path,
    edit: impl FnOnce(&mut snell::draw::RenderedFrame, &mut Vec<(String, String)>),
) {
    let (mut frame, meta) = read_frame_exr(source).unwrap();
    let mut extra = meta.text_attributes.clone();
    edit(&mut frame, &mut extra);
    let meta = FrameMeta {
        extra,
        ..FrameMeta::from_read(&meta, "tiny")
    };
    write_frame_exr(destination, &frame, &meta).unwrap();
}

fn diff(a: &Path, b: &Path, extra: &[&str], cwd: &Path) -> Output {
    let mut args = vec!["diff", a.to_str().unwrap(), b.to_str().unwrap()];
    args.extend_from_slice(extra);
    snell(&args, cwd)
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

#[test]
fn identical_frames_and_directories_pass_and_write_no_heat_map() {
    let renders = renders();
    let cwd = tempfile::tempdir().unwrap();
    let a = frame_file(&renders.original, 1);
    let text = assert_exit(&diff(&a, &a, &[], cwd.path()), 0);
    assert!(
        text.contains("tiny.0001.exr") && text.contains("pass"),
        "{text}"
    );
    assert!(text.contains("equal"), "flag counts are compared:\n{text}");
    let text = assert_exit(
        &diff(&renders.original, &renders.original, &[], cwd.path()),
        0,
    );
    assert!(
        text.contains("2 frame(s): 2 pass, 0 warn, 0 fail"),
        "{text}"
    );
    assert!(
        !cwd.path().join("output").exists(),
        "a passing diff writes no heat map"
    );
}

#[test]
fn one_changed_pixel_passes_by_default_and_warns_under_a_zero_warn_level() {
    let renders = renders();
    let temp = tempfile::tempdir().unwrap();
    let changed = temp.path().join("tiny.0001.exr");
    edited_copy(&frame_file(&renders.original, 1), &changed, |frame, _| {
        let middle = (frame.height / 2 * frame.width + frame.width / 2) as usize;
        frame.beauty_rgba[middle] = [50.0, 0.0, 50.0, 1.0];
    });
    let original = frame_file(&renders.original, 1);
    let text = assert_exit(&diff(&original, &changed, &[], temp.path()), 0);
    assert!(text.contains("pass"), "{text}");

    // The same change with no tolerance for any FLIP difference: a warning, exit 1, a heat map.
    let heatmaps = temp.path().join("heat");
    let text = assert_exit(
        &diff(
            &original,
            &changed,
            &[
                "--flip-mean-warn",
                "0",
                "--heatmaps",
                heatmaps.to_str().unwrap(),
            ],
            temp.path(),
        ),
        1,
    );
    assert!(text.contains("warn tiny.0001.exr: FLIP mean"), "{text}");
    assert_eq!(files_in(&heatmaps), vec!["tiny.0001-difference.png"]);
    let heat = image::open(heatmaps.join("tiny.0001-difference.png")).unwrap();
    assert_eq!((heat.width(), heat.height()), (160, 90));
}

#[test]
fn moved_ball_fails_on_flip_and_position() {
    let renders = renders();
    let cwd = tempfile::tempdir().unwrap();
    let output = diff(
        &frame_file(&renders.original, 1),
        &frame_file(&renders.ball_moved, 1),
        &[],
        cwd.path(),
    );
    let text = assert_exit(&output, 2);
    assert!(text.contains("FAIL tiny.0001.exr"), "{text}");
    // The ball covers about 1 % of the frame: the mean dilutes the change, the 99th percentile
    // catches it (measured: mean 0.008, p99 0.33; P off in 147 of 14400 pixels).
    assert!(
        text.contains("FLIP p99") && text.contains("> fail level 0.12"),
        "the beauty must fail:\n{text}"
    );
    // The default heat-map directory, never next to the inputs.
    assert_eq!(
        files_in(&cwd.path().join("output/diff")),
        vec!["tiny.0001-difference.png"]
    );
    assert!(!files_in(&renders.original)
        .iter()
        .any(|name| name.ends_with(".png")));
}

#[test]
fn a_whole_frame_shifted_by_four_pixels_fails() {
    let renders = renders();
    let temp = tempfile::tempdir().unwrap();
    let shifted = temp.path().join("tiny.0001.exr");
    edited_copy(&frame_file(&renders.original, 1), &shifted, |frame, _| {
        let width = frame.width as usize;
        let shift_row = |row: &mut [[f32; 4]]| row.rotate_right(4);
        for row in frame.beauty_rgba.chunks_mut(width) {
            shift_row(row);
        }
        for row in frame.depth_m.chunks_mut(width) {
            row.rotate_right(4);
        }
        for row in frame.position.chunks_mut(width) {
            row.rotate_right(4);
        }
    });
    let text = assert_exit(
        &diff(
            &frame_file(&renders.original, 1),
            &shifted,
            &[],
            temp.path(),
        ),
        2,
    );
    assert!(
        text.contains("FLIP mean") && text.contains("> fail level 0.015"),
        "{text}"
    );
}

#[test]
fn a_changed_flag_count_fails_and_missing_counts_warn() {
    let renders = renders();
    let temp = tempfile::tempdir().unwrap();
    let original = frame_file(&renders.original, 2);
    let changed = temp.path().join("changed.exr");
    edited_copy(&original, &changed, |_, extra| {
        let counts = extra
            .iter_mut()
            .find(|(key, _)| key == "flagCounts")
            .expect("render writes snell.extra.flagCounts");
        let mut value: serde_json::Value = serde_json::from_str(&counts.1).unwrap();
        let boundary = value["triangles"]["boundary"].as_u64().unwrap();
        value["triangles"]["boundary"] = (boundary + 1).into();
        counts.1 = value.to_string();
    });
    let text = assert_exit(&diff(&original, &changed, &[], temp.path()), 2);
    assert!(
        text.contains("flag counts differ: triangles.boundary"),
        "{text}"
    );

    let without = temp.path().join("without.exr");
    edited_copy(&original, &without, |_, extra| {
        extra.retain(|(key, _)| key != "flagCounts")
    });
    let text = assert_exit(&diff(&original, &without, &[], temp.path()), 1);
    assert!(
        text.contains("without.exr has no snell.extra.flagCounts"),
        "{text}"
    );
}

#[test]
fn unreadable_or_missing_input_is_exit_4_naming_the_file() {
    let renders = renders();
    let temp = tempfile::tempdir().unwrap();
    let not_exr = temp.path().join("notes.exr");
    std::fs::write(&not_exr, "not an image").unwrap();
    let good = frame_file(&renders.original, 1);
    let text = assert_exit(&diff(&good, &not_exr, &[], temp.path()), 4);
    assert!(
        text.contains("error:") && text.contains("notes.exr"),
        "{text}"
    );

    let missing = temp.path().join("absent.exr");
    let text = assert_exit(&diff(&missing, &good, &[], temp.path()), 4);
    assert!(text.contains("absent.exr"), "{text}");

    // In two directories, a frame whose file is not a frame makes the diff exit 4 too, while a
    // frame on one side only is a failing frame (2).
    let (dir_a, dir_b) = (temp.path().join("a"), temp.path().join("b"));
    for dir in [&dir_a, &dir_b] {
        std::fs::create_dir_all(dir).unwrap();
        std::fs::copy(&good, dir.join("shot.0001.exr")).unwrap();
    }
    std::fs::write(dir_b.join("shot.0001.exr"), "not an image").unwrap();
    let text = assert_exit(&diff(&dir_a, &dir_b, &[], temp.path()), 4);
    assert!(text.contains("shot.0001.exr"), "{text}");
    std::fs::copy(&good, dir_b.join("shot.0001.exr")).unwrap();
    std::fs::copy(&good, dir_a.join("shot.0002.exr")).unwrap();
    assert_exit(&diff(&dir_a, &dir_b, &[], temp.path()), 2);

    let text = assert_exit(&diff(&good, temp.path(), &[], temp.path()), 2);
    assert!(text.contains("two EXR files or two directories"), "{text}");

    let text = assert_exit(
        &diff(&good, &good, &["--flip-mean-warn", "0.5"], temp.path()),
        2,
    );
    assert!(text.contains("--flip-mean-warn"), "{text}");
}

/// Reads a JUnit file with an XML parser: (testcase count, failure count, suite `tests` attribute).
fn parse_junit(path: &Path) -> (usize, usize, String) {
    use xml::reader::{EventReader, XmlEvent};
    let file = std::fs::File::open(path).unwrap();
    let (mut testcases, mut failures, mut tests_attribute) = (0, 0, String::new());
    for event in EventReader::new(std::io::BufReader::new(file)) {
        if let XmlEvent::StartElement {
            name, attributes, ..
        } = event.expect("the JUnit report is well-formed XML")
        {
            match name.local_name.as_str() {
                "testcase" => testcases += 1,
                "failure" => failures += 1,
                "testsuite" => {
                    tests_attribute = attributes
                        .iter()
                        .find(|a| a.name.local_name == "tests")
                        .map(|a| a.value.clone())
                        .unwrap_or_default()
                }
                _ => {}
            }
        }
    }
    (testcases, failures, tests_attribute)
}

#[test]
fn directories_match_by_name_a_lone_frame_fails_and_junit_parses() {
    let renders = renders();
    let temp = tempfile::tempdir().unwrap();
    let reference = temp.path().join("a&<dir>");
    let test = temp.path().join("b");
    for dir in [&reference, &test] {
        std::fs::create_dir_all(dir).unwrap();
        for frame in [1, 2] {
            std::fs::copy(frame_file(&renders.original, frame), frame_file(dir, frame)).unwrap();
        }
    }
    std::fs::copy(frame_file(&renders.original, 1), frame_file(&reference, 3)).unwrap();
    std::fs::copy(frame_file(&renders.ball_moved, 2), frame_file(&test, 2)).unwrap();
    let junit = temp.path().join("reports/junit.xml");
    let text = assert_exit(
        &diff(
            &reference,
            &test,
            &["--junit", junit.to_str().unwrap()],
            temp.path(),
        ),
        2,
    );
    assert!(
        text.contains("3 frame(s): 1 pass, 0 warn, 2 fail"),
        "{text}"
    );
    assert!(text.contains("only in"), "{text}");
    let (testcases, failures, tests) = parse_junit(&junit);
    assert_eq!((testcases, failures, tests.as_str()), (3, 2, "3"));
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(
        xml.contains("a&amp;&lt;dir&gt;"),
        "paths are escaped:\n{xml}"
    );
    assert_eq!(files_in(junit.parent().unwrap()), vec!["junit.xml"]);
}

#[test]
fn check_fails_without_golden_then_bless_then_passes_and_catches_a_moved_ball() {
    let temp = tempfile::tempdir().unwrap();
    let scene = temp.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let golden = temp.path().join("golden");
    let check = |extra: &[&str]| {
        let mut args = vec![
            "check",
            scene.to_str().unwrap(),
            "--golden",
            golden.to_str().unwrap(),
            "--frames",
            "1-2",
        ];
        args.extend_from_slice(extra);
        snell(&args, temp.path())
    };
    let text = assert_exit(&check(&["--size", SIZE]), 2);
    assert!(
        text.contains("no golden yet") && text.contains("--bless"),
        "{text}"
    );
    assert!(!golden.exists(), "a missing golden must not be written");

    assert_exit(&check(&["--size", SIZE, "--bless"]), 0);
    assert_eq!(files_in(&golden), vec!["tiny.0001.exr", "tiny.0002.exr"]);

    // The size comes from the goldens when --size is not given.
    let junit = temp.path().join("check.xml");
    let text = assert_exit(&check(&["--junit", junit.to_str().unwrap()]), 0);
    assert!(text.contains("at 160x90"), "{text}");
    assert!(text.contains("2 frame(s): 2 pass"), "{text}");
    assert_eq!(parse_junit(&junit).0, 2);
    assert!(temp.path().join("output/tiny/check/tiny.0001.exr").exists());
    assert_eq!(files_in(&golden), vec!["tiny.0001.exr", "tiny.0002.exr"]);

    std::fs::write(
        &scene,
        TINY.replace(BALL_AT, "translate = [0.35, -0.6, 0.1]"),
    )
    .unwrap();
    let text = assert_exit(&check(&[]), 2);
    assert!(text.contains("FAIL tiny.0001.exr"), "{text}");
    assert!(temp
        .path()
        .join("output/tiny/check/tiny.0001-difference.png")
        .exists());
}
