//! The accuracy study's claims (issue 4, "Must hold"): the linear method (the thesis's cells) gives
//! error-volume means of the thesis's order with its trends, so it is the thesis's algorithm; the
//! exact method's means are at least 100 times smaller than the thesis's in every configuration.
//!
//! The volumes are sampled every 20 units here (8,000 samples per volume, an eighth of
//! `snell accuracy`'s default 64,000) to keep the test fast in a debug build; measured, the linear
//! means at spacing 20 are within 3 % of those at 10 on every row, far inside the factors checked.

use std::sync::OnceLock;

use snell::accuracy::membranes::{Orientation, PLANAR_RADIUS};
use snell::accuracy::study::{run_study, thesis_rows, Shape, StudyOptions, StudyResult};

const TEST_SPACING: f64 = 20.0;

fn results() -> &'static [StudyResult] {
    static RESULTS: OnceLock<Vec<StudyResult>> = OnceLock::new();
    RESULTS.get_or_init(|| {
        let options = StudyOptions {
            spacing: TEST_SPACING,
            ..StudyOptions::default()
        };
        run_study(&thesis_rows(), &options, &|_| {})
    })
}

fn find(table: &str, shape: Shape, eye_height: f64, eye_displacement: f64) -> &'static StudyResult {
    results()
        .iter()
        .find(|r| {
            r.row.table == table
                && r.row.shape == shape
                && r.row.eye_height == eye_height
                && r.row.eye_displacement == eye_displacement
        })
        .unwrap_or_else(|| panic!("no row {table} {shape:?} eye {eye_height}"))
}

fn bowl(radius: f64) -> Shape {
    Shape::Sphere {
        radius,
        orientation: Orientation::Bowl,
    }
}

/// Every volume has enough counted samples that its mean means something.
#[test]
fn every_volume_counts_samples() {
    for r in results() {
        assert!(
            r.result.linear.counted >= 300,
            "{}: only {} samples counted of {}",
            r.row.config(),
            r.result.linear.counted,
            r.result.samples
        );
        assert_eq!(r.result.linear.counted, r.result.exact.counted);
    }
}

/// The linear method's means are within a factor of 3 of the thesis's on the rows the thesis's
/// setup pins down: the flat disk straight under the eye at three heights (Table 4.1), the bowls
/// (Table 4.2) and the flat grids (Table 4.5). Why 3: the thesis leaves the disk's faceting and the
/// sampling open (ALGORITHM §8), and those choices alone move the means by up to ~2x (6 rings
/// instead of 4: ~0.4x); measured here, these rows land at 0.78-1.67x. The exact method, a
/// different algorithm, is 1e9 times off, so the bound tells the two apart by far.
#[test]
fn linear_means_are_of_the_thesis_order() {
    let mut checked = 0;
    for r in results() {
        let pinned = match r.row.shape {
            Shape::FlatDisk => r.row.eye_displacement == 0.0,
            Shape::Sphere { orientation, .. } => orientation == Orientation::Bowl,
            Shape::Grid { .. } => true,
        };
        if !pinned {
            continue;
        }
        let ratio = r.result.linear.mean / r.row.thesis_mean;
        assert!(
            (1.0 / 3.0..=3.0).contains(&ratio),
            "{}: linear mean {} vs the thesis's {} ({ratio:.2}x)",
            r.row.config(),
            r.result.linear.mean,
            r.row.thesis_mean
        );
        checked += 1;
    }
    // 3 heights + (flat + 5 bowls) + 6 grids.
    assert_eq!(checked, 15);
}

/// The thesis's trends: the error grows as the eye comes down, with the membrane's curvature, and
/// falls as the faceting gets finer.
#[test]
fn linear_means_follow_the_thesis_trends() {
    let mean = |r: &StudyResult| r.result.linear.mean;
    let heights = [900.0, 450.0, 150.0].map(|h| mean(find("4.1", Shape::FlatDisk, h, 0.0)));
    assert!(
        heights[0] < heights[1] && heights[1] < heights[2],
        "eye 900, 450, 150: {heights:?}"
    );
    let mut curvature = vec![mean(find("4.2", Shape::FlatDisk, 450.0, 0.0))];
    for radius in [710.0, 355.0, 237.0, 178.0, PLANAR_RADIUS] {
        curvature.push(mean(find("4.2", bowl(radius), 450.0, 0.0)));
    }
    assert!(
        curvature.windows(2).all(|w| w[0] < w[1]),
        "R = inf, 710, 355, 237, 178, 142: {curvature:?}"
    );
    for height in [450.0, 150.0] {
        let grids = [6, 10, 15].map(|cells| mean(find("4.5", Shape::Grid { cells }, height, 0.0)));
        assert!(
            grids[0] > grids[1] && grids[1] > grids[2],
            "eye {height}, 6x6, 10x10, 15x15: {grids:?}"
        );
    }
}

/// The exact method: at least 100 times below the thesis's mean in every configuration (bowls
/// and caps, every eye height and offset, every grid), Newton fallbacks included in its figures.
#[test]
fn exact_means_are_at_least_100_times_smaller_everywhere() {
    for r in results() {
        let exact = r.result.exact.mean;
        assert!(
            exact * 100.0 <= r.row.thesis_mean,
            "{}: exact mean {exact} vs the thesis's {} ({} Newton fallbacks)",
            r.row.config(),
            r.row.thesis_mean,
            r.result.newton_fallbacks
        );
        // And below the linear method's own, so the comparison is not with a broken linear run.
        assert!(exact < r.result.linear.mean, "{}", r.row.config());
    }
}

fn snell(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(args)
        .output()
        .expect("the snell binary runs")
}

/// `snell accuracy --csv`: the Markdown table on stdout with the setup stated, and a CSV with
/// exactly the columns, a line per row and method.
#[test]
fn cli_prints_the_table_and_writes_the_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv_path = dir.path().join("nested/accuracy.csv");
    let out = snell(&[
        "accuracy",
        "--table",
        "4.5",
        "--spacing",
        "50",
        "--csv",
        csv_path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        stdout.contains("every 50-unit cell (512 samples)"),
        "{stdout}"
    );
    assert!(
        stdout.contains("4 concentric rings, each 0.9 times as wide"),
        "{stdout}"
    );
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("| 4.5 |")).count(),
        6
    );
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("config,method,mean,std,counted,excluded,thesis_mean")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 12);
    assert_eq!(rows[0][0], "t4.5/grid-6x6/eye450");
    assert_eq!((rows[0][1], rows[1][1]), ("linear", "exact"));
    for row in &rows {
        assert_eq!(row.len(), 7);
        let mean: f64 = row[2].parse().unwrap();
        let counted: usize = row[4].parse().unwrap();
        let excluded: usize = row[5].parse().unwrap();
        assert!(mean > 0.0 && counted > 0);
        assert_eq!(
            counted + excluded,
            512,
            "grids have no samples in the air: {row:?}"
        );
    }
}

/// Bad options name the option and what it takes, and exit with 2.
#[test]
fn cli_rejects_bad_options_with_exit_2() {
    for (args, expected) in [
        (
            vec!["accuracy", "--spacing", "0.5"],
            "--spacing: must be 2 to 200",
        ),
        (vec!["accuracy", "--rings", "0"], "--rings: must be 1 to 64"),
        (
            vec!["accuracy", "--ring-ratio", "0.01"],
            "--ring-ratio: must be a number",
        ),
        (
            vec!["accuracy", "--table", "4.3"],
            "--table: no table \"4.3\"",
        ),
    ] {
        let out = snell(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
}
