//! Speed figures of the vessel displacement for `snell bench`: receives the vertex count and the
//! repetitions; returns [`VesselBenchFigures`], each time the median of the repetitions, measured
//! with `std::time::Instant` on rayon's pool (every core of the machine), beside the paper's
//! figures and the water's refraction stage on the same number of vertices in the same run.
//!
//! Scenario "glass of water" (the paper's Table 2 case, a cup with something in it): a glass of
//! 4 cm outer and 3.6 cm inner radius, 12 cm high, water inside, the eye 40 cm away and 3 cm above
//! the rim's middle height; vertices seeded uniformly in a 16 x 12 x 16 cm box around it (in the
//! water, in the glass, behind and beside it). Scenario "pane": an aquarium's front pane, 1 x 0.6 m,
//! 1 cm, water behind, the eye 1 m in front; vertices in a box 1.2 x 0.8 x 0.6 m behind it. Every
//! image of every vertex is found (the direct view included).

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use super::{Cylinder, Image, Medium, Pane, Vessel};
use crate::seeded::SplitMix64;
use crate::stats::median;

/// Mukai et al., Table 2: 100,000 vertices through a cylindrical glass at 96 fps on average
/// (GTX 570, 1,600 x 1,200).
pub const PAPER_CYLINDER_VERTICES_PER_SEC: f64 = 100_000.0 * 96.0;
/// Mukai et al., Table 1: 100,000 vertices through a parallel pane at 122 fps.
pub const PAPER_PANE_VERTICES_PER_SEC: f64 = 100_000.0 * 122.0;

/// One scenario's figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ScenarioFigures {
    pub vertices: usize,
    /// Seconds for all vertices (median).
    pub secs: f64,
    pub vertices_per_sec: f64,
    /// Images found over all vertices, and of those with 1-4 refractions.
    pub images: usize,
    pub refracted_images: usize,
    /// Images whose solve missed its tolerance (drawn flagged).
    pub unconverged_images: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct VesselBenchFigures {
    pub threads: usize,
    pub repetitions: usize,
    pub cylinder: ScenarioFigures,
    pub pane: ScenarioFigures,
    pub paper_cylinder_vertices_per_sec: f64,
    pub paper_pane_vertices_per_sec: f64,
    /// The water's refraction stage (sight-facet search, build included: `refraction::bench`'s pool
    /// scenario) on its vertex count, measured in the same run.
    pub water_stage_vertices: usize,
    pub water_stage_secs: f64,
    pub water_stage_vertices_per_sec: f64,
}

fn glass_of_water() -> (Vessel, DVec3, Vec<DVec3>) {
    let cylinder = Cylinder {
        base: DVec3::ZERO,
        axis: DVec3::Y,
        inner_radius_m: 0.036,
        outer_radius_m: 0.04,
        height_m: 0.12,
        glass_index: 1.5,
        inside: Medium::Water,
    };
    let eye = DVec3::new(0.0, 0.09, 0.4);
    let mut rng = SplitMix64::new(0x61A55);
    let points = (0..VERTICES_DEFAULT)
        .map(|_| {
            DVec3::new(
                rng.range(-0.08, 0.08),
                rng.range(0.0, 0.12),
                rng.range(-0.08, 0.08),
            )
        })
        .collect();
    (Vessel::Cylinder(cylinder), eye, points)
}

fn aquarium_pane() -> (Vessel, DVec3, Vec<DVec3>) {
    let pane = Pane {
        center: DVec3::new(0.0, 0.3, 0.0),
        normal: DVec3::Z,
        u_axis: DVec3::X,
        half_size_m: [0.5, 0.3],
        thickness_m: 0.01,
        glass_index: 1.5,
        inside: Medium::Water,
    };
    let eye = DVec3::new(0.1, 0.45, 1.0);
    let mut rng = SplitMix64::new(0xA0A);
    let points = (0..VERTICES_DEFAULT)
        .map(|_| {
            DVec3::new(
                rng.range(-0.6, 0.6),
                rng.range(-0.1, 0.7),
                rng.range(-0.6, -0.01),
            )
        })
        .collect();
    (Vessel::Pane(pane), eye, points)
}

/// The vertex count of both scenarios: the paper's 100,000.
pub const VERTICES_DEFAULT: usize = 100_000;

fn run_scenario(
    (vessel, eye, points): (Vessel, DVec3, Vec<DVec3>),
    vertices: usize,
    repetitions: usize,
) -> ScenarioFigures {
    let points = &points[..vertices.min(points.len())];
    let mut times = Vec::new();
    let mut counts = (0, 0, 0);
    for _ in 0..repetitions {
        let start = Instant::now();
        counts = points
            .par_iter()
            .with_min_len(256)
            .map_init(Vec::<Image>::new, |images, &point| {
                images.clear();
                vessel.images(eye, point, images);
                let refracted = images.iter().filter(|i| i.refractions > 0).count();
                let failed = images.iter().filter(|i| !i.converged).count();
                (images.len(), refracted, failed)
            })
            .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
        times.push(start.elapsed().as_secs_f64());
    }
    let secs = median(&mut times);
    ScenarioFigures {
        vertices: points.len(),
        secs,
        vertices_per_sec: points.len() as f64 / secs,
        images: counts.0,
        refracted_images: counts.1,
        unconverged_images: counts.2,
    }
}

/// Both scenarios on `vertices` vertices (at most [`VERTICES_DEFAULT`]) and the water's stage,
/// `repetitions` times each.
pub fn run(vertices: usize, repetitions: usize) -> VesselBenchFigures {
    let repetitions = repetitions.max(1);
    let cylinder = run_scenario(glass_of_water(), vertices, repetitions);
    let pane = run_scenario(aquarium_pane(), vertices, repetitions);
    let water = crate::refraction::bench::bench_search_with(repetitions);
    VesselBenchFigures {
        threads: rayon::current_num_threads(),
        repetitions,
        cylinder,
        pane,
        paper_cylinder_vertices_per_sec: PAPER_CYLINDER_VERTICES_PER_SEC,
        paper_pane_vertices_per_sec: PAPER_PANE_VERTICES_PER_SEC,
        water_stage_vertices: water.pool_vertices,
        water_stage_secs: water.pool_frame_secs,
        water_stage_vertices_per_sec: water.vertices_per_sec,
    }
}

impl VesselBenchFigures {
    pub fn to_text(&self) -> String {
        let line = |name: &str, s: &ScenarioFigures, paper: f64| {
            format!(
                "  {name}: {:.2} M vertices/s ({} vertices in {:.1} ms; {} images, {} through the glass, {} unconverged); \
                 the paper {:.1} M/s on a GTX 570, {:.3}x; water stage for as many vertices {:.1} ms, vessel/water {:.2}x\n",
                s.vertices_per_sec / 1e6,
                s.vertices,
                s.secs * 1e3,
                s.images,
                s.refracted_images,
                s.unconverged_images,
                paper / 1e6,
                s.vertices_per_sec / paper,
                s.vertices as f64 / self.water_stage_vertices_per_sec * 1e3,
                self.water_stage_vertices_per_sec / s.vertices_per_sec,
            )
        };
        format!(
            "vessel displacement (Mukai et al.), {} threads, median of {}:\n{}{}  water refraction stage: {:.2} M vertices/s ({} vertices in {:.1} ms, build included)\n",
            self.threads,
            self.repetitions,
            line("glass of water (cylinder)", &self.cylinder, self.paper_cylinder_vertices_per_sec),
            line("aquarium pane", &self.pane, self.paper_pane_vertices_per_sec),
            self.water_stage_vertices_per_sec / 1e6,
            self.water_stage_vertices,
            self.water_stage_secs * 1e3,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Not a timing test: a small run checking the scenarios see through the glass and solve.
    #[test]
    fn the_scenarios_find_images_through_the_glass_and_every_solve_converges() {
        let (vessel, eye, points) = glass_of_water();
        let cylinder = run_scenario((vessel, eye, points), 2000, 1);
        assert_eq!(cylinder.vertices, 2000);
        assert!(cylinder.refracted_images > 500, "{cylinder:?}");
        assert_eq!(cylinder.unconverged_images, 0, "{cylinder:?}");
        let pane = run_scenario(aquarium_pane(), 2000, 1);
        assert!(pane.refracted_images > 1000, "{pane:?}");
        assert_eq!(pane.unconverged_images, 0, "{pane:?}");
    }

    /// The figures on the paper's 100,000 vertices, for the README:
    /// `cargo test --release --lib vessel::bench -- --ignored --nocapture`.
    #[test]
    #[ignore = "a benchmark: run it on a quiet machine"]
    fn figures() {
        print!("{}", run(VERTICES_DEFAULT, 5).to_text());
        // How many images the scan finds at other densities on the glass of water (skew rays:
        // the brute-force fan of the tests checks level ones only).
        let (Vessel::Cylinder(cylinder), eye, points) = glass_of_water() else {
            unreachable!()
        };
        for samples in [6, 8, 12, 24, 48] {
            let images: usize = points
                .par_iter()
                .map_init(Vec::new, |images, &point| {
                    images.clear();
                    cylinder.images_with_samples(eye, point, samples, images);
                    images.len()
                })
                .sum();
            println!("  glass of water, {samples} scan samples per piece: {images} images");
        }
    }
}
