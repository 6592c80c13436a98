//! `snell chart` and a scene's `[quality] max_error_px`, through the binary as a user runs them:
//! the chart of tiny.toml at a small size (CSV columns and rows, finite figures, the reference's
//! own error zero, a PNG that decodes and an SVG that parses), budgets that choose coarser or finer
//! configurations and say so (stdout, report.jsonl, EXR header, cache), and bad budgets refused
//! with the file and line.

mod common;
use common::{csv_with_header, snell, stdout_of_success, text_of, TINY};

use std::path::{Path, PathBuf};

use snell::chart::budget::{self, QualityChoice};
use snell::chart::{chart_configurations, Configuration, CSV_HEADER};
use snell::frame::Method;

/// Small enough to keep the test quick, large enough that the membranes' errors differ by more
/// than the sub-pixel measurement resolves.
const SIZE: &str = "128x72";

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn chart_of_tiny_writes_one_row_per_configuration_and_valid_charts() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "tiny.toml", TINY);
    let out = dir.path().join("chart");
    let output = snell(
        &[
            "chart",
            scene.to_str().unwrap(),
            "--size",
            SIZE,
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    let stdout = stdout_of_success(&output);
    let csv = csv_with_header(&out.join("speed_accuracy.csv"), CSV_HEADER);
    let lines = csv.lines().skip(1);
    assert_eq!(
        CSV_HEADER,
        "method,resolution,secs_per_frame,mean_px,p99_px"
    );
    let rows: Vec<Vec<&str>> = lines.map(|line| line.split(',').collect()).collect();
    let scene_resolution = snell::scene::Scene::load(&scene).unwrap().water.resolution;
    let expected: Vec<Configuration> = chart_configurations(scene_resolution);
    assert_eq!(
        rows.len(),
        expected.len(),
        "one row per configuration:\n{csv}"
    );
    for (row, configuration) in rows.iter().zip(&expected) {
        assert_eq!(row.len(), 5, "{row:?}");
        assert_eq!(row[0], configuration.method.name());
        assert_eq!(row[1], configuration.resolution_label());
        let numbers: Vec<f64> = row[2..].iter().map(|v| v.parse().unwrap()).collect();
        assert!(
            numbers.iter().all(|v| v.is_finite() && *v >= 0.0),
            "{row:?}"
        );
        assert!(numbers[0] > 0.0, "a render takes time: {row:?}");
    }
    let reference = rows
        .iter()
        .find(|row| row[0] == Method::Raytrace.name())
        .expect("the reference row");
    assert_eq!(reference[1], "exact-surface");
    assert_eq!(reference[3].parse::<f64>().unwrap(), 0.0, "{reference:?}");
    assert_eq!(reference[4].parse::<f64>().unwrap(), 0.0, "{reference:?}");
    // The coarsest linear membrane is measurably wrong: the measure sees errors at all.
    let coarse = rows
        .iter()
        .find(|row| row[0] == "equal-t" && row[1] == "32x32")
        .unwrap();
    assert!(coarse[3].parse::<f64>().unwrap() > 0.0, "{coarse:?}");

    let detail = std::fs::read_to_string(out.join("speed_accuracy_detail.csv")).unwrap();
    assert_eq!(detail.lines().count(), expected.len() + 1);

    let png = image::open(out.join("speed_accuracy.png")).expect("the PNG decodes");
    assert_eq!(
        (png.width(), png.height()),
        snell::chart::plot::PNG_SIZE,
        "PNG size"
    );
    let svg = std::fs::File::open(out.join("speed_accuracy.svg")).unwrap();
    let mut elements = 0;
    let mut texts = String::new();
    for event in xml::reader::EventReader::new(std::io::BufReader::new(svg)) {
        match event.expect("the SVG is well-formed XML") {
            xml::reader::XmlEvent::StartElement { .. } => elements += 1,
            xml::reader::XmlEvent::Characters(text) => texts.push_str(&text),
            _ => {}
        }
    }
    assert!(elements > 20, "{elements} elements: an empty chart");
    assert!(
        texts.contains("32x32") && texts.contains("reference"),
        "labels: {texts}"
    );

    assert!(stdout.contains("faster than the reference"), "{stdout}");
    assert!(stdout.contains("outside flagged pixels"), "{stdout}");
}

/// tiny.toml with a `[quality]` table.
fn tiny_with_budget(max_error_px: &str) -> String {
    format!("{TINY}\n[quality]\nmax_error_px = {max_error_px}\n")
}

/// Renders frame 2 of tiny.toml with `max_error_px` and returns the choice as cached, with stdout.
fn render_with_budget(dir: &Path, max_error_px: &str) -> (QualityChoice, String, PathBuf) {
    let scene = write_scene(dir, "budget.toml", &tiny_with_budget(max_error_px));
    let out = dir.join("out");
    let output = snell(
        &[
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "2",
            "--size",
            SIZE,
            "--out",
            out.to_str().unwrap(),
        ],
        dir,
    );
    let stdout = stdout_of_success(&output);
    let cached: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(budget::CHOICE_FILE_NAME)).unwrap())
            .unwrap();
    let choice: QualityChoice = serde_json::from_value(cached["choice"].clone()).unwrap();
    (choice, stdout, out)
}

/// Where a choice stands in the order of cost: the index of its candidate, or past them all for
/// the reference.
fn cost_rank(choice: &QualityChoice, scene_resolution: [u32; 2]) -> usize {
    let candidates = budget::candidates(scene_resolution);
    candidates
        .iter()
        .position(|c| c.method.name() == choice.method && c.resolution == choice.resolution)
        .unwrap_or(candidates.len())
}

#[test]
fn a_loose_budget_picks_a_coarser_configuration_than_a_tight_one_and_says_so() {
    let scene_resolution = [16, 16];
    let loose_dir = tempfile::tempdir().unwrap();
    let (loose, loose_stdout, loose_out) = render_with_budget(loose_dir.path(), "50");
    let tight_dir = tempfile::tempdir().unwrap();
    let (tight, tight_stdout, _) = render_with_budget(tight_dir.path(), "0.02");

    // 16x16 cells are the coarsest candidate; any membrane meets a 50 px budget at 128x72.
    assert_eq!(
        (loose.method.as_str(), loose.resolution),
        ("equal-t", scene_resolution),
        "{loose:?}"
    );
    assert_eq!(loose.candidates.len(), 1);
    assert!(loose.candidates[0].p99_px <= 50.0);
    assert!(
        cost_rank(&tight, scene_resolution) > cost_rank(&loose, scene_resolution),
        "tight {tight:?} vs loose {loose:?}"
    );
    // Every candidate the tight budget passed over failed it, as measured.
    let (chosen, passed_over) = match tight.candidates.last() {
        Some(last) if last.method == tight.method && last.resolution == tight.resolution => {
            assert!(last.p99_px <= 0.02, "{last:?}");
            (1, &tight.candidates[..tight.candidates.len() - 1])
        }
        _ => (0, &tight.candidates[..]),
    };
    assert!(passed_over.iter().all(|c| c.p99_px > 0.02), "{tight:?}");
    assert!(passed_over.len() + chosen >= 2, "{tight:?}");

    // Reported: stdout, the report row, the EXR header.
    for (stdout, choice) in [(&loose_stdout, &loose), (&tight_stdout, &tight)] {
        assert!(
            stdout.contains("max_error_px = ") && stdout.contains(&choice.method),
            "{stdout}"
        );
        assert!(stdout.contains("measured now"), "{stdout}");
    }
    let report = std::fs::read_to_string(loose_out.join("report.jsonl")).unwrap();
    let row: serde_json::Value = serde_json::from_str(report.lines().next().unwrap()).unwrap();
    assert_eq!(row["quality"]["method"], "equal-t");
    assert_eq!(row["quality"]["resolution"], serde_json::json!([16, 16]));
    let (_, meta) =
        snell::output::read_frame_exr(&loose_out.join("tiny.0002.exr")).expect("the frame");
    let header = meta
        .text_attributes
        .iter()
        .find(|(key, _)| key == budget::CHOICE_ATTRIBUTE)
        .map(|(_, value)| value.clone())
        .expect("the EXR header carries the choice");
    let from_header: QualityChoice = serde_json::from_str(&header).unwrap();
    assert_eq!(from_header.resolution, loose.resolution);

    // Rendering again reads the cache instead of measuring.
    let (again, again_stdout, _) = render_with_budget(loose_dir.path(), "50");
    assert_eq!(again.resolution, loose.resolution);
    assert!(
        again_stdout.contains("read from the cache"),
        "{again_stdout}"
    );
}

/// Bad budgets: exit 2 with the file, the line and the key, before any output.
#[test]
fn bad_budgets_are_refused_with_file_and_line() {
    for (value, needle) in [
        ("0", "must be more than 0"),
        ("-0.5", "must be more than 0"),
        ("nan", "finite"),
        ("inf", "finite"),
        ("\"half a pixel\"", "invalid type"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let text = tiny_with_budget(value);
        let line = text
            .lines()
            .position(|l| l.starts_with("max_error_px"))
            .unwrap()
            + 1;
        let scene = write_scene(dir.path(), "bad.toml", &text);
        let out = dir.path().join("out");
        let output = snell(
            &[
                "render",
                scene.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--size",
                "64x36",
            ],
            dir.path(),
        );
        let stderr = text_of(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{value}: {stderr}");
        assert!(
            stderr.contains(&format!("bad.toml:{line}:")),
            "{value}: {stderr}"
        );
        assert!(stderr.contains("quality.max_error_px"), "{value}: {stderr}");
        assert!(stderr.contains(needle), "{value}: {stderr}");
        assert!(!out.exists(), "{value}: output written");
    }
    // An unknown key in [quality] is named too.
    let dir = tempfile::tempdir().unwrap();
    let text = format!("{TINY}\n[quality]\nmax_error = 1\n");
    let scene = write_scene(dir.path(), "bad.toml", &text);
    let output = snell(&["render", scene.to_str().unwrap()], dir.path());
    let stderr = text_of(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("max_error"), "{stderr}");
}
