//! Tuning aids of the sight-facet search (ignored tests, single-threaded, fastest of several
//! runs) timing the query's stages on the benchmark's pool scenario:
//! `cargo test --release --lib refraction::bench::tuning -- --ignored --nocapture`.
//! What `snell bench` measures is the whole frame; these take it apart.

use std::time::Instant;

use glam::{DVec3, Vec2, Vec3};

use crate::refraction::cells::Cell;
use crate::refraction::search::{lanes_may_contain, RefractionField, RefractionSetup};
use crate::refraction::surface::{of_water, ExactSurface, PathCheck};
use crate::water::Membrane;

/// Calls `visit` with every facet the accelerated search tests for `p` (its footprint test passed).
fn for_each_candidate(field: &RefractionField, p: Vec3, visit: impl FnMut(u32)) {
    let slab = field
        .structure
        .slab_at(p.y)
        .expect("inside the query range");
    field.structure.for_each_candidate(slab, p, visit);
}

/// The benchmark's pool scenario (`refraction::bench`).
struct Pool {
    /// The waves' exact surface (leaked: a tuning aid runs once).
    surface: ExactSurface<'static>,
    membrane: Membrane,
    points: Vec<Vec3>,
    setup: RefractionSetup,
}

impl Pool {
    fn new() -> Self {
        let (waves, membrane, points, setup) = super::pool_scenario_for_tests();
        let waves: &'static crate::water::WaterSurface = Box::leak(Box::new(waves));
        let surface = of_water(waves, None, waves, membrane.grid);
        Self {
            surface,
            membrane,
            points,
            setup,
        }
    }

    /// The field a frame builds, for the benchmark's query height range.
    fn field(&self) -> RefractionField<'_> {
        RefractionField::build(&self.membrane, &self.surface, self.setup, (-2.0, 0.0))
    }
}

fn gather() -> Vec<(Cell, DVec3)> {
    let pool = Pool::new();
    let (field, points) = (pool.field(), &pool.points);
    let mut cells = Vec::new();
    for p in points {
        for_each_candidate(&field, *p, |f| cells.push((field.cell(f), p.as_dvec3())));
    }
    cells
}

#[test]
#[ignore]
fn containment_only() {
    let cells = gather();
    let mut best = f64::INFINITY;
    let mut n = 0;
    let mut t = 0.0;
    for _ in 0..40 {
        let s = Instant::now();
        n = 0;
        t = 0.0;
        for (c, p) in &cells {
            let r = crate::refraction::cells::equal_t_containments(c, *p);
            n += r.len();
            for x in r.iter() {
                t += x.t;
            }
        }
        best = best.min(s.elapsed().as_secs_f64());
    }
    println!(
        "CONTAINMENT {} calls {:.1} ns/call n {n} sum t {t:.12}",
        cells.len(),
        best / cells.len() as f64 * 1e9
    );
}

#[test]
#[ignore]
fn crest_only() {
    let pool = Pool::new();
    let (field, points) = (pool.field(), &pool.points);
    let mut pairs = Vec::new();
    let mut out = Vec::new();
    for p in points {
        field.images(*p, &mut out);
        for im in &out {
            pairs.push((im.sight_point.as_dvec3(), p.as_dvec3()));
        }
    }
    let eye = field.setup.eye.as_dvec3();
    let check: PathCheck = field.crest.check;
    let (mut a, mut b) = (0, 0);
    for (sp, p) in &pairs {
        if pool
            .surface
            .segment_clear_by_slope(*sp, eye - *sp, 1.0, &check)
        {
            a += 1;
        }
        if pool
            .surface
            .segment_clear_by_slope(*sp, *p - *sp, -1.0, &check)
        {
            b += 1;
        }
    }
    println!(
        "CREST pairs {} eye proven {a} point proven {b} slope {} gap {} tol {}",
        pairs.len(),
        pool.surface.slope_bound,
        check.sight_point_gap_m,
        check.tolerance_m
    );
    let mut best = f64::INFINITY;
    let mut n = 0;
    for _ in 0..20 {
        let s = Instant::now();
        n = 0;
        for (sp, p) in &pairs {
            n += field.crest_blocks(*sp, *p) as usize;
        }
        best = best.min(s.elapsed().as_secs_f64());
    }
    println!(
        "CREST {:.1} ns/call blocked {n}",
        best / pairs.len() as f64 * 1e9
    );
}

/// The benchmark's pool figure alone (both cores): fastest and median of 15 frames.
#[test]
#[ignore]
fn pool_frame() {
    use rayon::prelude::*;
    let pool = Pool::new();
    let mut frames = Vec::new();
    let mut builds = Vec::new();
    for _ in 0..15 {
        let s = Instant::now();
        let field = pool.field();
        builds.push(s.elapsed().as_secs_f64());
        let n: usize = pool
            .points
            .par_iter()
            .with_min_len(256)
            .map_init(Vec::new, |out, &p| {
                field.images(p, out);
                out.len()
            })
            .sum();
        frames.push(s.elapsed().as_secs_f64());
        assert!(n > 90_000);
    }
    frames.sort_by(f64::total_cmp);
    builds.sort_by(f64::total_cmp);
    println!(
        "POOL frame fastest {:.2} ms median {:.2} ms ({:.2} M/s median); build fastest {:.2} median {:.2} ms; size {:?}",
        frames[0] * 1e3,
        frames[7] * 1e3,
        pool.points.len() as f64 / frames[7] / 1e6,
        builds[0] * 1e3,
        builds[7] * 1e3,
        pool.field().structure_size()
    );
}

#[test]
#[ignore]
fn lanes_only() {
    let pool = Pool::new();
    let (field, points) = (pool.field(), &pool.points);
    let chunks = &field.structure.block_chunks.as_flattened()[..4096];
    let mut best = f64::INFINITY;
    let mut n = 0;
    for _ in 0..20 {
        let s = Instant::now();
        n = 0;
        for (i, c) in chunks.iter().enumerate() {
            let p = points[i * 7];
            n += lanes_may_contain(c, Vec2::new(p.x, p.z), p.y, 0.01, 1e-6).count_ones() as usize;
        }
        best = best.min(s.elapsed().as_secs_f64());
    }
    println!(
        "LANES {:.1} ns/chunk ({n})",
        best / chunks.len() as f64 * 1e9
    );
}

#[test]
#[ignore]
fn build_only() {
    let pool = Pool::new();
    let s = Instant::now();
    for _ in 0..100 {
        let f = pool.field();
        drop(f);
    }
    println!("build {:.2} ms", s.elapsed().as_secs_f64() * 10.0);
}

#[test]
#[ignore]
fn breakdown() {
    let pool = Pool::new();
    let (field, points) = (pool.field(), &pool.points);
    let pts: Vec<Vec3> = points.clone();
    let time = |name: &str, f: &dyn Fn(Vec3) -> usize| {
        let mut best = f64::INFINITY;
        let mut n = 0;
        for _ in 0..7 {
            let s = Instant::now();
            n = 0;
            for p in &pts {
                n += f(*p);
            }
            best = best.min(s.elapsed().as_secs_f64());
        }
        println!(
            "{name}: {:.1} ns/query ({n})",
            best / pts.len() as f64 * 1e9
        );
    };
    let mut work = [0usize; 5];
    for p in &pts {
        let w = field.search_work(*p);
        for k in 0..5 {
            work[k] += w[k];
        }
    }
    println!(
        "work per query {:?}, structure {:?}",
        work.map(|w| w as f64 / pts.len() as f64),
        field.structure_size()
    );
    let out = std::cell::RefCell::new(Vec::new());
    time("candidates", &|p| {
        let mut n = 0;
        for_each_candidate(&field, p, |_| n += 1);
        n
    });
    time("candidates+containment", &|p| {
        let o = &mut out.borrow_mut();
        o.clear();
        for_each_candidate(&field, p, |f| field.push_containments(f, p.as_dvec3(), o));
        o.len()
    });
    time("images", &|p| {
        field.images(p, &mut out.borrow_mut());
        out.borrow().len()
    });
    let mut best = f64::INFINITY;
    for _ in 0..10 {
        let s = Instant::now();
        let f = pool.field();
        best = best.min(s.elapsed().as_secs_f64());
        drop(f);
    }
    println!("build {:.2} ms (2 threads)", best * 1e3);
}
