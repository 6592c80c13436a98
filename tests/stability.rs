//! `snell stability` through the binary, as a user runs it, on tiny.toml at a small size: one CSV
//! row per frame and method with every column, the reference measured against itself exactly
//! zero (position and temporal, with points tracked), a linear method's figures present and
//! finite, the summary naming each method's worst frames, a PNG that decodes and an SVG that
//! parses, and bad arguments refused with exit 2. The oracle's multi-image share per frame: in
//! its own CSV over the same under-water vertices the renderer counts, and alone with
//! --oracle-only.

mod common;
use common::{csv_with_header, snell, stdout_of_success, text_of, TINY};

use std::collections::HashMap;
use std::path::Path;

use snell::stability::{
    csv_header, plot, CSV_FILE_NAME, ORACLE_CSV_FILE_NAME, ORACLE_CSV_HEADER, PNG_FILE_NAME,
    SUMMARY_FILE_NAME, SVG_FILE_NAME,
};

const SIZE: &str = "96x54";

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
    let stdout = stdout_of_success(&output);
    let csv = csv_with_header(&out.join(CSV_FILE_NAME), &csv_header());
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

    // The oracle measured every vertex of tiny's few hundred under water (fewer than the
    // default sample), the same ones the renderer counts.
    let oracle = rows_of(&std::fs::read_to_string(out.join(ORACLE_CSV_FILE_NAME)).unwrap());
    assert_eq!(oracle.len(), 3);
    for (share, row) in oracle.iter().zip(rows.iter().step_by(2)) {
        assert_eq!(share["frame"], row["frame"]);
        assert_eq!(
            share["under_water_vertices"], row["under_water_vertices"],
            "{share:?}"
        );
        assert_eq!(share["sampled"], share["under_water_vertices"], "{share:?}");
        let fraction = number(share, "multi_image_fraction");
        assert!((0.0..=1.0).contains(&fraction), "{share:?}");
        assert_eq!(
            number(row, "oracle_multi_image_fraction"),
            fraction,
            "{row:?}"
        );
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

/// `--oracle-only`: no renders, one row per frame of the oracle's share over a systematic sample
/// of the asked size, its interval around it, every sampled vertex settled or counted unsettled,
/// and the summary naming the lowest frame.
#[test]
fn stability_oracle_only_reports_the_multi_image_share_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let out = dir.path().join("oracle");
    let output = snell(
        &[
            "stability",
            "tiny.toml",
            "--frames",
            "2-3",
            "--oracle-only",
            "--oracle-samples",
            "50",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    let stdout = stdout_of_success(&output);
    let csv = csv_with_header(&out.join(ORACLE_CSV_FILE_NAME), ORACLE_CSV_HEADER);
    let rows = rows_of(&csv);
    assert_eq!(
        rows.iter().map(|r| r["frame"].as_str()).collect::<Vec<_>>(),
        ["2", "3"]
    );
    for row in &rows {
        let (sampled, total) = (number(row, "sampled"), number(row, "under_water_vertices"));
        assert!(
            (25.0..=50.0).contains(&sampled) && total > sampled,
            "{row:?}"
        );
        assert_eq!(
            number(row, "certain") + number(row, "uncertain"),
            sampled,
            "{row:?}"
        );
        let (low, p, high) = (
            number(row, "fraction_low95"),
            number(row, "multi_image_fraction"),
            number(row, "fraction_high95"),
        );
        assert!(low <= p && p <= high && high - low > 0.0, "{row:?}");
    }
    assert!(
        !out.join(CSV_FILE_NAME).exists(),
        "no renders, no method rows"
    );
    let summary = std::fs::read_to_string(out.join(SUMMARY_FILE_NAME)).unwrap();
    assert!(stdout.contains(&summary));
    for needle in [
        "two or more images by the oracle: lowest",
        "systematic sample of",
    ] {
        assert!(summary.contains(needle), "{needle:?} in\n{summary}");
    }
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
