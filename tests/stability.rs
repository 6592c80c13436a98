//! `snell stability` through the binary, as a user runs it, on tiny.toml at a small size: one CSV
//! row per frame and method with every column, the reference measured against itself exactly
//! zero (position and temporal, with points tracked), a linear method's figures present and
//! finite, the summary naming each method's worst frames, a PNG that decodes and an SVG that
//! parses, and bad arguments refused with exit 2.

mod common;
use common::{snell, TINY};

use std::collections::HashMap;
use std::path::Path;

use snell::stability::{
    csv_header, plot, CSV_FILE_NAME, PNG_FILE_NAME, SUMMARY_FILE_NAME, SVG_FILE_NAME,
};

const SIZE: &str = "96x54";

fn text_of(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn rows_of(csv: &str) -> Vec<HashMap<String, String>> {
    let mut lines = csv.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            assert_eq!(fields.len(), header.len(), "{line}");
            header
                .iter()
                .cloned()
                .zip(fields.into_iter().map(String::from))
                .collect()
        })
        .collect()
}

fn number(row: &HashMap<String, String>, column: &str) -> f64 {
    row[column]
        .parse()
        .unwrap_or_else(|_| panic!("{column} = {:?}", row[column]))
}

#[test]
fn stability_of_tiny_measures_every_frame_and_method() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let out = dir.path().join("stability");
    let output = snell(
        &[
            "stability",
            "tiny.toml",
            "--frames",
            "1-3",
            "--size",
            SIZE,
            "--methods",
            "equal-t,raytrace",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    let (stdout, stderr) = (text_of(&output.stdout), text_of(&output.stderr));
    assert!(
        output.status.success(),
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );

    let csv = std::fs::read_to_string(out.join(CSV_FILE_NAME)).unwrap();
    assert_eq!(csv.lines().next().unwrap(), csv_header());
    let rows = rows_of(&csv);
    let keys: Vec<(String, String)> = rows
        .iter()
        .map(|r| (r["frame"].clone(), r["method"].clone()))
        .collect();
    let expected: Vec<(String, String)> = ["1", "2", "3"]
        .iter()
        .flat_map(|f| ["equal-t", "raytrace"].map(|m| (f.to_string(), m.to_string())))
        .collect();
    assert_eq!(keys, expected, "{csv}");

    for row in &rows {
        let first = row["frame"] == "1";
        // The first frame of the range has nothing to move from.
        assert_eq!(row["temporal_p99_px"].is_empty(), first, "{row:?}");
        assert!(number(row, "both_all_counted") > 1000.0, "{row:?}");
        if row["method"] == "raytrace" {
            // The reference against itself: every position figure and the motion exactly zero.
            for (column, value) in row {
                let figure = column.ends_with("_px")
                    || (column.ends_with("fraction") && column != "fold_band_water_fraction");
                if figure && !value.is_empty() {
                    assert_eq!(
                        value, "0",
                        "{column} of the reference against itself: {row:?}"
                    );
                }
            }
            if !first {
                assert!(number(row, "temporal_points") > 500.0, "{row:?}");
            }
        } else {
            for column in [
                "both_all_mean_px",
                "both_all_p99_px",
                "ref_to_method_unfolded_p99_px",
            ] {
                let value = number(row, column);
                assert!(value.is_finite() && value >= 0.0, "{column}: {row:?}");
            }
            // A linear method is not the reference: its images sit a little elsewhere.
            assert!(number(row, "both_all_mean_px") > 0.0, "{row:?}");
            if !first {
                let temporal = number(row, "temporal_p99_px");
                assert!(temporal.is_finite() && temporal > 0.0, "{row:?}");
            }
            assert!(number(row, "under_water_vertices") > 0.0, "{row:?}");
        }
    }

    let summary = std::fs::read_to_string(out.join(SUMMARY_FILE_NAME)).unwrap();
    assert!(
        stdout.contains(&summary),
        "the summary is printed:\n{stdout}"
    );
    for needle in [
        "equal-t:",
        "raytrace:",
        "p99, outside the fold band",
        "temporal p99",
        "worst",
    ] {
        assert!(summary.contains(needle), "{needle:?} in\n{summary}");
    }
    let png = image::open(out.join(PNG_FILE_NAME)).unwrap();
    assert_eq!((png.width(), png.height()), plot::SIZE);
    let svg = std::fs::read_to_string(out.join(SVG_FILE_NAME)).unwrap();
    assert!(svg.trim_start().starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("equal-t") && svg.contains("frame"));
}

#[test]
fn stability_refuses_bad_arguments_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["stability", "tiny.toml"];
        args.extend_from_slice(extra);
        snell(&args, Path::new(dir.path()))
    };
    for (extra, needle) in [
        (
            &["--size", "32x18", "--methods", "equal-t,fast"][..],
            "\"fast\" is unknown",
        ),
        (
            &["--size", "32x18", "--frames", "2-9"][..],
            "runs from frame 1 to 3",
        ),
        (&["--size", "0x10"][..], "--size \"0x10\""),
        (
            &["--size", "32x18", "--methods", "exact,exact"][..],
            "named twice",
        ),
    ] {
        let output = run(extra);
        let stderr = text_of(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(needle), "{extra:?}: {stderr}");
    }
}
