//! `snell render --method exact` as a user runs it: frames, report rows naming the method and
//! carrying the exact method's counts, and a clear refusal of a bad subdivision tolerance.

mod common;
use common::{snell, TINY};

use std::path::Path;

fn report_rows(out: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(out.join("report.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn exact_method_renders_tiny_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let render = |method: &str, out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--size",
            "320x180",
            "--frames",
            "2",
            "--method",
            method,
        ];
        args.extend_from_slice(extra);
        let output = snell(&args, dir.path());
        assert!(
            output.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        out
    };
    let exact = render("exact", "exact", &[]);
    let rows = report_rows(&exact);
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    assert_eq!(row["method"], "virtual-vertices/exact");
    let counts = &row["counts"];
    let under_water = counts["vertices"]["under_water"].as_u64().unwrap();
    assert!(under_water > 0, "{counts}");
    // Gentle waves seen from above: Newton converges everywhere (the key is left out at zero).
    assert!(
        counts["vertices"].get("newton_fallback").is_none(),
        "{counts}"
    );
    let subdivided = counts["triangles"]["subdivided"].as_u64().unwrap_or(0);
    let (frame, meta) = snell::output::exr::read_frame_exr(&exact.join("tiny.0002.exr")).unwrap();
    assert_eq!((frame.width, frame.height), (320, 180));
    assert_eq!(meta.method, "virtual-vertices/exact");

    // The equal-t render of the same frame: same vertices under water, no exact-only keys.
    let equal_t = render("equal-t", "equal-t", &[]);
    let linear = &report_rows(&equal_t)[0]["counts"];
    assert_eq!(
        linear["vertices"]["under_water"].as_u64().unwrap(),
        under_water
    );
    assert!(linear["vertices"].get("newton_fallback").is_none());
    assert!(linear["triangles"].get("subdivided").is_none());

    // A coarser tolerance subdivides less than the default.
    let coarse = render("exact", "coarse", &["--subdivision-px", "4"]);
    let coarse_subdivided = report_rows(&coarse)[0]["counts"]["triangles"]["subdivided"]
        .as_u64()
        .unwrap_or(0);
    eprintln!("tiny frame 2 at 320x180: {subdivided} triangles subdivided at 0.25 px, {coarse_subdivided} at 4 px");
    // The ball's and the pool's big triangles bend visibly even at this size (10 split, measured),
    // and a 16x coarser tolerance splits fewer (none, measured).
    assert!(subdivided > 0);
    assert!(coarse_subdivided < subdivided);
}

#[test]
fn bad_subdivision_tolerance_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    for bad in ["0", "-1", "NaN", "inf"] {
        let flag = format!("--subdivision-px={bad}");
        let output = snell(
            &[
                "render",
                scene.to_str().unwrap(),
                "--method",
                "exact",
                &flag,
            ],
            dir.path(),
        );
        assert_eq!(output.status.code(), Some(2), "{flag}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr.contains("expected a number of pixels > 0"),
            "{flag}: {stderr}"
        );
        assert!(
            !dir.path().join("output").exists(),
            "{flag}: output written"
        );
    }
}

/// `snell locate --method exact` prints exact images: each printed sight point is a stationary
/// point of the optical path on the frame's exact surface (to the printed f32 precision), where
/// the equal-t images of the coarse tiny membrane are measurably not.
#[test]
fn locate_with_the_exact_method_prints_stationary_points() {
    use snell::refraction::exact::FermatProblem;
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(
        &points,
        "x,y,z\n0.2,-0.6,0.1\n-0.3,-0.5,0.4\n0.0,-0.79,-0.2\n",
    )
    .unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tiny.toml");
    let job = snell::frame::RenderJob::prepare(&scene).unwrap();
    let mut stage_secs = Default::default();
    let water = job.frame_water(2, &mut stage_secs).unwrap();
    let surface = water.surface();
    let largest_gradient = |method: &str| {
        let output = snell(
            &[
                "locate",
                scene.to_str().unwrap(),
                "--frame",
                "2",
                "--points",
                points.to_str().unwrap(),
                "--method",
                method,
            ],
            dir.path(),
        );
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let text = String::from_utf8(output.stdout).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').take(8).map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 3, "{text}");
        let given = [[0.2, -0.6, 0.1], [-0.3, -0.5, 0.4], [0.0, -0.79, -0.2]];
        rows.iter()
            .map(|row| {
                let problem = FermatProblem {
                    surface: &surface,
                    eye: water.camera.eye.as_dvec3(),
                    point: glam::DVec3::from(given[row[0] as usize]),
                    n_above: job.scene.water.n_above,
                    n_below: job.scene.water.n_below,
                };
                problem
                    .optical_gradient(glam::DVec2::new(row[5], row[7]))
                    .length()
            })
            .fold(0.0, f64::max)
    };
    let (linear, exact) = (largest_gradient("equal-t"), largest_gradient("exact"));
    eprintln!("largest |grad L| at printed sight points: equal-t {linear:e}, exact {exact:e}");
    // Printed f32 coordinates (~3e-8 m at 0.3 m) leave |grad L| ~ n dx / distance ~ 1e-7.
    assert!(exact < 1e-5, "{exact}");
    assert!(linear > 100.0 * exact, "{linear} vs {exact}");
}
