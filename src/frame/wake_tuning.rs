//! Tuning aid (ignored test): where one wake frame's refraction stage goes, against its calm copy
//! (ripples off), with the exact method: the field build, the equal-t search alone, the vertices'
//! exact images (solves from linear images and retries) and the subdivision, each timed (fastest
//! of `SNELL_TUNING_REPEATS` runs, default 3, both cores) and counted (solves, evaluations of
//! `grad L` and `Hess L`, path checks and their walks' evaluations, per under-water vertex), and
//! what one evaluation of the surface costs:
//! `SNELL_WAKE_FRAME=44 cargo test --release --lib frame::wake_tuning -- --ignored --nocapture`.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use super::RenderJob;
use crate::refraction::search::RefractionField;
use crate::refraction::subdivision::SubdivisionSettings;
use crate::refraction::virtual_geometry::{
    build_virtual_geometry_with, ImageSearch, Placement, VirtualGeometry, VirtualGeometryRequest,
};
use crate::refraction::work::{self, Work, SOURCES};
use crate::water::HeightField;

fn fastest(repeats: usize, mut f: impl FnMut()) -> f64 {
    (0..repeats)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn print_work(name: &str, w: &Work, per: f64) {
    println!("  {name}: per under-water vertex");
    for (k, source) in SOURCES.iter().enumerate() {
        if w.solves[k] + w.path_checks[k] + w.walk_evaluations[k] == 0 {
            continue;
        }
        println!(
            "    {source:>12}: {:.3} solves ({:.1} % converged), {:.2} evaluations ({:.1} per solve), \
             {:.3} path checks, {:.2} walk evaluations",
            w.solves[k] as f64 / per,
            100.0 * w.converged[k] as f64 / w.solves[k].max(1) as f64,
            w.evaluations[k] as f64 / per,
            w.evaluations[k] as f64 / w.solves[k].max(1) as f64,
            w.path_checks[k] as f64 / per,
            w.walk_evaluations[k] as f64 / per,
        );
    }
    for (k, source) in SOURCES.iter().enumerate() {
        histogram(source, "converged, iterations", &w.converged_iterations[k]);
        histogram(
            source,
            "converged, evaluations",
            &w.converged_evaluations[k],
        );
        histogram(source, "failed, evaluations", &w.failed_evaluations[k]);
        histogram(
            source,
            "converged, most trials of an iteration",
            &w.converged_trials[k],
        );
        let failed = w.solves[k] - w.converged[k];
        if failed > 0 {
            let capped: Vec<String> = (1..13)
                .map(|n| {
                    format!(
                        "{n}: {:.1}",
                        w.failed_evaluations_capped[k][n] as f64 / failed as f64
                    )
                })
                .collect();
            println!(
                "    {source:>12} failed, mean evaluations with the line search capped at n trials: {}",
                capped.join(", ")
            );
        }
    }
    if w.edge_tests > 0 {
        println!(
            "    edges tested {:.3}, split {:.3}",
            w.edge_tests as f64 / per,
            w.edge_splits as f64 / per
        );
    }
}

/// Percentiles of a histogram (the last bucket: that many or more), its mean, and the histogram.
fn histogram(source: &str, what: &str, histogram: &[u64]) {
    let total: u64 = histogram.iter().sum();
    if total == 0 {
        return;
    }
    let at = |share: f64| {
        let mut seen = 0;
        histogram
            .iter()
            .position(|&n| {
                seen += n;
                seen as f64 >= share * total as f64
            })
            .unwrap_or(histogram.len() - 1)
    };
    let last = histogram.iter().rposition(|&n| n > 0).unwrap_or(0);
    let mean = histogram
        .iter()
        .enumerate()
        .map(|(i, &n)| i as f64 * n as f64)
        .sum::<f64>()
        / total as f64;
    println!(
        "    {source:>12} {what}: {total} solves, mean {mean:.2}, p50 {} p90 {} p99 {} p99.9 {} p99.99 {} max {last}; {:?}",
        at(0.5),
        at(0.9),
        at(0.99),
        at(0.999),
        at(0.9999),
        &histogram[..=last]
    );
}

#[test]
#[ignore = "tuning aid"]
fn wake_breakdown() {
    let frame: u32 = std::env::var("SNELL_WAKE_FRAME").map_or(44, |s| s.parse().unwrap());
    let repeats: usize = std::env::var("SNELL_TUNING_REPEATS").map_or(3, |s| s.parse().unwrap());
    let scene = crate::scene::Scene::load(Path::new("scenes/hard/wading_wake.toml")).unwrap();
    let mut calm = scene.clone();
    calm.water.ripples.enabled = false;
    for (name, scene) in [("wake", scene), ("calm", calm)] {
        let mut job = RenderJob::from_scene(scene).unwrap();
        job.method = super::Method::Exact;
        let water = job.frame_water(frame, &mut BTreeMap::new()).unwrap();
        let heights = water.surface();
        let surface = water.exact_surface(&heights);
        let setup = job.refraction_setup(water.camera.eye);
        let build =
            || RefractionField::build(&water.membrane, &surface, setup, water.query_y_range);
        let build_ms = fastest(repeats, || drop(build()));
        let field = build();
        let request = VirtualGeometryRequest {
            field: &field,
            camera: water.camera,
            image_size: (1280, 720),
            objects: &water.objects,
            mean_level_m: job.waves.level_m as f32,
            search: ImageSearch::Accelerated,
        };
        let run = |placement: Placement| -> (f64, Work, VirtualGeometry) {
            let ms = fastest(repeats, || {
                std::hint::black_box(build_virtual_geometry_with(&request, None, placement));
            });
            work::take();
            let g = build_virtual_geometry_with(&request, None, placement);
            (ms, work::take(), g)
        };
        let (linear_ms, _, _) = run(Placement::Linear);
        let vertices_only = SubdivisionSettings {
            max_depth: 0,
            ..job.subdivision
        };
        let (vertices_ms, vertices_work, _) = run(Placement::Exact(vertices_only));
        let (exact_ms, exact_work, g) = run(Placement::Exact(job.subdivision));
        let v = &g.counts.vertices;
        let t = &g.counts.triangles;
        let per = v.under_water as f64;
        println!(
            "{name} frame {frame}: {} under-water vertices ({} convergence, {} fallbacks), {} under-water triangles, \
             {} subdivided into {} pieces; {} drawn vertices",
            v.under_water,
            v.convergence,
            v.newton_fallback,
            t.under_water,
            t.subdivided,
            t.subdivision_pieces,
            g.under_vertices.len()
        );
        println!(
            "  ms (fastest of {repeats}): field build {build_ms:.1}; virtual geometry: equal-t {linear_ms:.1}, \
             exact without subdivision {vertices_ms:.1}, exact {exact_ms:.1} \
             (so exact images {:.1}, subdivision {:.1}); stage: equal-t {:.1}, exact {:.1}",
            vertices_ms - linear_ms,
            exact_ms - vertices_ms,
            build_ms + linear_ms,
            build_ms + exact_ms,
        );
        print_work("vertices' exact images", &vertices_work, per);
        let subdivision = exact_work.less(&vertices_work);
        print_work("subdivision", &subdivision, per);
        // One evaluation's cost: height, gradient and Hessian at points over the water seen.
        let grid = water.membrane.grid;
        let mut rng = crate::seeded::SplitMix64::new(7);
        let points: Vec<(f64, f64)> = (0..100_000)
            .map(|_| {
                (
                    rng.range(grid.min_x, grid.max_x),
                    rng.range(grid.min_z, grid.max_z),
                )
            })
            .collect();
        let mut sink = 0.0;
        let derivatives_ms = fastest(repeats, || {
            for &(x, z) in &points {
                sink += surface.height_derivatives(x, z).0;
            }
        });
        let gradient_ms = fastest(repeats, || {
            for &(x, z) in &points {
                sink += surface.height_and_gradient(x, z).0;
            }
        });
        let waves_ms = fastest(repeats, || {
            for &(x, z) in &points {
                sink += water.waves_now.height_derivatives(x, z).0;
            }
        });
        println!(
            "  one evaluation (one thread): height+gradient+Hessian {:.0} ns (waves alone {:.0} ns), height+gradient {:.0} ns ({sink:.1e})",
            derivatives_ms * 1e6 / points.len() as f64,
            waves_ms * 1e6 / points.len() as f64,
            gradient_ms * 1e6 / points.len() as f64,
        );
    }
}
