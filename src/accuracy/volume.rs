//! Error volumes (ALGORITHM §8, thesis §4.1): receives a thesis refractor, an eye and a sample
//! spacing; returns, per method, the error statistics of a 400-unit cube of samples under it.
//!
//! For each sample V: its virtual vertex V' by the method; the computed vertex
//! `C = S* + T* |V' - S*| / eta`, with S* the exact intersection of the ray E -> V' with the exact
//! surface and T* the exact refraction there; the error `|C - V|`. The linear method is the
//! thesis's own: its plane-test cells ([`thesis_containment`]) over per-vertex refraction rays
//! ([`refraction_ray`], extrapolated where needed), every facet tested. Samples with no image,
//! with an extrapolated cell, in a zone of convergence (more than one image) or with no computed
//! vertex are excluded and counted. The exact method starts from the linear sight point and solves
//! Fermat's principle on the exact surface by Newton ([`solve_sight_point`]); where Newton fails
//! (or ends off the refractor, or where the eye cannot see the point through it) it keeps the
//! linear point and counts a fallback. Both methods are measured on the same samples.

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::membranes::ThesisMembrane;
use crate::refraction::cells::{thesis_containment, Cell};
use crate::refraction::exact::{solve_sight_point, FermatProblem};
use crate::refraction::flat::virtual_vertex;
use crate::refraction::rays::{refract_exact, refraction_ray};
use crate::refraction::search::MERGE_DISTANCE_PER_FACET_SIZE;

/// Side of the thesis's cube of sample points, in scene units.
pub const CUBE_SIDE: f64 = 400.0;

/// Where the eye is and how the volume is sampled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeSetup {
    /// Eye ("emitter") height above the refractor's top, the plane the cube's top is flush with.
    pub eye_height: f64,
    /// Horizontal displacement of the eye from the refractor's axis, along +x (Table 4.1).
    pub eye_displacement: f64,
    pub n_above: f64,
    pub n_below: f64,
    /// Distance between neighbouring samples. Samples sit at the centres of a grid of cubes of
    /// this side filling the 400-unit cube (centred under the refractor, top flush with its top),
    /// so `(400 / spacing)^3` samples and none on the cube's faces or on the refractor's axis.
    pub spacing: f64,
}

impl VolumeSetup {
    /// The thesis's indices (1.0 above, 1.51 below) with the eye straight above the centre.
    pub fn thesis(eye_height: f64, spacing: f64) -> Self {
        VolumeSetup {
            eye_height,
            eye_displacement: 0.0,
            n_above: 1.0,
            n_below: 1.51,
            spacing,
        }
    }

    pub fn eye(&self, membrane: &ThesisMembrane) -> DVec3 {
        DVec3::new(
            self.eye_displacement,
            membrane.top_y() + self.eye_height,
            0.0,
        )
    }

    /// Samples per axis of the cube.
    pub fn samples_per_axis(&self) -> usize {
        (CUBE_SIDE / self.spacing).round().max(1.0) as usize
    }

    /// The sample points, x fastest, then z, then y from the top down.
    pub fn samples(&self, membrane: &ThesisMembrane) -> Vec<DVec3> {
        let n = self.samples_per_axis();
        let step = CUBE_SIDE / n as f64;
        let top = membrane.top_y();
        let at = |i: usize| -0.5 * CUBE_SIDE + (i as f64 + 0.5) * step;
        (0..n * n * n)
            .map(|k| {
                let (ix, iz, iy) = (k % n, (k / n) % n, k / (n * n));
                DVec3::new(at(ix), top - (iy as f64 + 0.5) * step, at(iz))
            })
            .collect()
    }
}

/// Mean, standard deviation and count of errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorStats {
    pub mean: f64,
    /// Population standard deviation.
    pub std: f64,
    pub counted: usize,
    /// The largest error.
    pub max: f64,
}

impl ErrorStats {
    /// Order-independent up to the f64 rounding of the sums; callers pass errors in sample order,
    /// so the same inputs give the same bytes.
    pub fn of(errors: &[f64]) -> Self {
        let counted = errors.len();
        if counted == 0 {
            return ErrorStats {
                mean: f64::NAN,
                std: f64::NAN,
                counted,
                max: f64::NAN,
            };
        }
        let mean = errors.iter().sum::<f64>() / counted as f64;
        let variance = errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / counted as f64;
        ErrorStats {
            mean,
            std: variance.sqrt(),
            counted,
            max: errors.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// Why samples were left out of the statistics, with counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Exclusions {
    /// In no cell: outside the visible volume (or in a gap between thesis cells).
    pub no_image: usize,
    /// Its only image comes from a cell with an extrapolated (back-facing) ray.
    pub extrapolated: usize,
    /// In more than one cell (images whose sight points differ): a zone of convergence, or an
    /// overlap of neighbouring thesis cells.
    pub convergence: usize,
    /// The ray E -> V' misses the exact refractor, or meets it from behind: no computed vertex.
    pub no_computed_vertex: usize,
}

impl Exclusions {
    pub fn total(&self) -> usize {
        self.no_image + self.extrapolated + self.convergence + self.no_computed_vertex
    }
}

/// One error volume measured for both methods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeResult {
    pub samples: usize,
    /// Samples above the exact surface (inside a bowl, beside a cap): in the eye's medium, not
    /// seen through the refractor; neither counted nor excluded.
    pub in_air: usize,
    pub excluded: Exclusions,
    pub linear: ErrorStats,
    pub exact: ErrorStats,
    /// Counted samples where Newton did not give a valid sight point and the exact method kept
    /// the linear one (their linear error is in the exact statistics).
    pub newton_fallbacks: usize,
}

/// What happened to one sample.
enum Outcome {
    InAir,
    Excluded(Exclusion),
    Counted {
        linear_error: f64,
        exact_error: f64,
        fallback: bool,
    },
}

#[derive(Clone, Copy)]
enum Exclusion {
    NoImage,
    Extrapolated,
    Convergence,
    NoComputedVertex,
}

/// A refractor's cells as the thesis's algorithm builds them for one eye.
struct Cells {
    cells: Vec<Cell>,
    extrapolated: Vec<bool>,
    /// Longest edge of each facet, for merging duplicate images.
    sizes: Vec<f64>,
}

impl Cells {
    fn build(membrane: &ThesisMembrane, eye: DVec3, n_above: f64, n_below: f64) -> Self {
        let rays: Vec<_> = membrane
            .positions
            .iter()
            .zip(&membrane.normals)
            .map(|(p, n)| {
                refraction_ray(
                    p.as_vec3(),
                    n.as_vec3(),
                    eye.as_vec3(),
                    n_above as f32,
                    n_below as f32,
                )
            })
            .collect();
        let mut cells = Vec::with_capacity(membrane.triangles.len());
        let mut extrapolated = Vec::with_capacity(membrane.triangles.len());
        let mut sizes = Vec::with_capacity(membrane.triangles.len());
        for t in &membrane.triangles {
            let r = t.map(|i| rays[i as usize]);
            let mut cell = Cell::new(r.map(|r| r.origin), r.map(|r| r.direction));
            // The facet's corners exactly (f64), not their f32 rounding.
            cell.origins = t.map(|i| membrane.positions[i as usize]);
            cells.push(cell);
            extrapolated.push(r.iter().any(|r| r.extrapolation.is_extrapolated()));
            let p = cell.origins;
            sizes.push(
                (p[1] - p[0])
                    .length()
                    .max((p[2] - p[1]).length())
                    .max((p[0] - p[2]).length()),
            );
        }
        Cells {
            cells,
            extrapolated,
            sizes,
        }
    }

    /// Every facet whose thesis cell contains `point`, as (facet, sight point), with duplicates
    /// (sight points closer than the search's merge distance: the containment slack on a shared
    /// face) merged into the lowest facet's, as the thesis kept the first it found.
    fn images(&self, point: DVec3, out: &mut Vec<(usize, DVec3)>) {
        out.clear();
        for (facet, cell) in self.cells.iter().enumerate() {
            if let Some(c) = thesis_containment(cell, point) {
                let size = self.sizes[facet];
                let duplicate = out.iter().any(|&(kept, s)| {
                    let tolerance =
                        MERGE_DISTANCE_PER_FACET_SIZE as f64 * size.max(self.sizes[kept]);
                    (s - c.sight_point).length() <= tolerance
                });
                if !duplicate {
                    out.push((facet, c.sight_point));
                }
            }
        }
    }
}

/// The first point where the ray `origin + u direction` (u > 0, travelling down) meets the exact
/// surface on the refractor: None if it crosses the surface's height range without meeting it
/// on the outline. The ray is sampled across the height range of the surface (where any crossing
/// must be), the first sign change of `y - h(x, z)` is bisected to round-off.
pub fn first_surface_hit(
    membrane: &ThesisMembrane,
    origin: DVec3,
    direction: DVec3,
) -> Option<DVec3> {
    /// Samples across the surface's height range: enough that no crossing of these smooth
    /// surfaces (at most two per ray) hides between two samples except at grazing incidence.
    const SCAN_SAMPLES: usize = 256;
    let field = membrane.surface.as_height_field();
    // Rays going up (or NaN) never reach a surface below the eye.
    if direction.y.is_nan() || direction.y >= 0.0 {
        return None;
    }
    let (low, high) = membrane.surface.height_range();
    // Slack so that a flat surface (low == high) still gets an interval around its crossing.
    let slack = 1e-6 * (1.0 + (origin.y - low).abs());
    let u_start = ((origin.y - high - slack) / -direction.y).max(0.0);
    let u_end = (origin.y - low + slack) / -direction.y;
    let above = |u: f64| {
        let p = origin + u * direction;
        p.y - field.height(p.x, p.z)
    };
    if above(u_start) < 0.0 {
        return None;
    }
    let mut previous_u = u_start;
    for k in 1..=SCAN_SAMPLES {
        let u = u_start + (u_end - u_start) * k as f64 / SCAN_SAMPLES as f64;
        let value = above(u);
        if value <= 0.0 {
            let (mut lo, mut hi) = (previous_u, u);
            loop {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if above(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let hit = origin + 0.5 * (lo + hi) * direction;
            let hit = DVec3::new(hit.x, field.height(hit.x, hit.z), hit.z);
            return membrane
                .outline
                .contains(DVec2::new(hit.x, hit.z), 1e-9)
                .then_some(hit);
        }
        previous_u = u;
    }
    None
}

/// The computed vertex of a virtual vertex (thesis §4.1): where the true vertex must be for the
/// eye to see it at `virtual_position`, by exact intersection and refraction.
pub fn computed_vertex(
    membrane: &ThesisMembrane,
    eye: DVec3,
    virtual_position: DVec3,
    n_above: f64,
    n_below: f64,
) -> Option<DVec3> {
    let eta = n_above / n_below;
    let direction = (virtual_position - eye).normalize();
    let hit = first_surface_hit(membrane, eye, direction)?;
    let normal = membrane.surface.as_height_field().normal(hit.x, hit.z);
    let refracted = refract_exact(direction, normal, eta)?;
    Some(hit + refracted * ((virtual_position - hit).length() / eta))
}

/// The exact sight point by Newton on Fermat's principle ([`solve_sight_point`]) from the linear
/// one, solved in the chart of the exact surface around the linear sight point (the frame turned
/// so that the surface's normal there is up: regular also on a hemisphere's vertical rim, where
/// the world's height field has an infinite slope), returned in world coordinates.
pub fn exact_sight_point(
    membrane: &ThesisMembrane,
    eye: DVec3,
    point: DVec3,
    linear_sight_point: DVec3,
    n_above: f64,
    n_below: f64,
) -> Option<DVec3> {
    let chart = membrane
        .surface
        .chart_at(DVec2::new(linear_sight_point.x, linear_sight_point.z));
    let to_chart = chart.chart_from_world;
    let surface = chart.field.as_height_field();
    let problem = FermatProblem {
        surface,
        eye: to_chart * eye,
        point: to_chart * point,
        n_above,
        n_below,
    };
    // Start on the exact surface, over (in the chart) the linear sight point.
    let start = to_chart * linear_sight_point;
    let solved = solve_sight_point(&problem, DVec2::new(start.x, start.z))?;
    Some(to_chart.inverse() * solved.sight_point)
}

/// Whether an exact stationary point is an image here: on the refractor, the sight ray arriving
/// from the eye's side and meeting the surface first at it, and the refracted ray leaving into the
/// water. The segment S -> V is not checked against the surface: the thesis's studies have a single
/// interface, so its refracted ray goes on to V (as in its computed vertex) even where it passes
/// under the plane beside a cap's rim; `path_is_clear` would call that blocked.
fn sight_point_is_valid(membrane: &ThesisMembrane, eye: DVec3, point: DVec3, s: DVec3) -> bool {
    if !membrane.outline.contains(DVec2::new(s.x, s.z), 1e-9) {
        return false;
    }
    let normal = membrane.surface.as_height_field().normal(s.x, s.z);
    if (s - eye).dot(normal) >= 0.0 || (point - s).dot(normal) >= 0.0 {
        return false;
    }
    // Round-off of the bisection relative to the eye distance.
    let tolerance = 1e-9 * (s - eye).length();
    first_surface_hit(membrane, eye, (s - eye).normalize())
        .is_some_and(|hit| (hit - s).length() <= tolerance)
}

/// Measures one error volume, samples in parallel; `on_sample_batch` is told how many samples
/// each finished batch held (for a progress bar).
pub fn measure_volume(
    membrane: &ThesisMembrane,
    setup: &VolumeSetup,
    on_sample_batch: &(dyn Fn(usize) + Sync),
) -> VolumeResult {
    let eye = setup.eye(membrane);
    let cells = Cells::build(membrane, eye, setup.n_above, setup.n_below);
    let samples = setup.samples(membrane);
    const BATCH: usize = 512;
    let outcomes: Vec<Outcome> = samples
        .par_chunks(BATCH)
        .flat_map_iter(|batch| {
            let mut images = Vec::new();
            let out: Vec<Outcome> = batch
                .iter()
                .map(|&v| measure_sample(membrane, setup, &cells, eye, v, &mut images))
                .collect();
            on_sample_batch(batch.len());
            out
        })
        .collect();
    let mut excluded = Exclusions::default();
    let (mut in_air, mut newton_fallbacks) = (0, 0);
    let mut linear_errors = Vec::new();
    let mut exact_errors = Vec::new();
    for outcome in outcomes {
        match outcome {
            Outcome::InAir => in_air += 1,
            Outcome::Excluded(why) => match why {
                Exclusion::NoImage => excluded.no_image += 1,
                Exclusion::Extrapolated => excluded.extrapolated += 1,
                Exclusion::Convergence => excluded.convergence += 1,
                Exclusion::NoComputedVertex => excluded.no_computed_vertex += 1,
            },
            Outcome::Counted {
                linear_error,
                exact_error,
                fallback,
            } => {
                linear_errors.push(linear_error);
                exact_errors.push(exact_error);
                newton_fallbacks += fallback as usize;
            }
        }
    }
    VolumeResult {
        samples: samples.len(),
        in_air,
        excluded,
        linear: ErrorStats::of(&linear_errors),
        exact: ErrorStats::of(&exact_errors),
        newton_fallbacks,
    }
}

fn measure_sample(
    membrane: &ThesisMembrane,
    setup: &VolumeSetup,
    cells: &Cells,
    eye: DVec3,
    point: DVec3,
    images: &mut Vec<(usize, DVec3)>,
) -> Outcome {
    let field = membrane.surface.as_height_field();
    // Beyond the outline the height field is the rim's plane: a point above it beside a cap is
    // in the air as well.
    if point.y > field.height(point.x, point.z) {
        return Outcome::InAir;
    }
    cells.images(point, images);
    let (facet, linear_sight_point) = match images.as_slice() {
        [] => return Outcome::Excluded(Exclusion::NoImage),
        [one] => *one,
        _ => return Outcome::Excluded(Exclusion::Convergence),
    };
    if cells.extrapolated[facet] {
        return Outcome::Excluded(Exclusion::Extrapolated);
    }
    let (n_above, n_below) = (setup.n_above, setup.n_below);
    let error_of = |sight_point: DVec3| {
        let virtual_position = virtual_vertex(eye, sight_point, point, n_above, n_below);
        computed_vertex(membrane, eye, virtual_position, n_above, n_below)
            .map(|computed| (computed - point).length())
    };
    let Some(linear_error) = error_of(linear_sight_point) else {
        return Outcome::Excluded(Exclusion::NoComputedVertex);
    };
    let exact = exact_sight_point(membrane, eye, point, linear_sight_point, n_above, n_below)
        .filter(|&s| sight_point_is_valid(membrane, eye, point, s));
    let exact_error = exact.and_then(error_of);
    match exact_error {
        Some(exact_error) => Outcome::Counted {
            linear_error,
            exact_error,
            fallback: false,
        },
        None => Outcome::Counted {
            linear_error,
            exact_error: linear_error,
            fallback: true,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accuracy::membranes::RingFaceting;
    use crate::refraction::flat::flat_sight_point;

    /// On flat water, a virtual vertex made from the exact sight point (the bisection oracle) has
    /// its computed vertex exactly at the true vertex: the error measure itself adds no error.
    #[test]
    fn computed_vertex_of_the_exact_image_is_the_true_vertex_on_flat_water() {
        let disk = ThesisMembrane::flat_disk(RingFaceting::THESIS_FIT);
        for &(eye_height, displacement) in &[(450.0, 0.0), (150.0, 0.0), (900.0, 400.0)] {
            let setup = VolumeSetup {
                eye_displacement: displacement,
                ..VolumeSetup::thesis(eye_height, 40.0)
            };
            let eye = setup.eye(&disk);
            let mut checked = 0;
            for v in setup.samples(&disk) {
                let s = flat_sight_point(eye, v, 0.0, setup.n_above, setup.n_below);
                if !disk.outline.contains(DVec2::new(s.x, s.z), 0.0) {
                    continue;
                }
                let virtual_position = virtual_vertex(eye, s, v, setup.n_above, setup.n_below);
                let c = computed_vertex(&disk, eye, virtual_position, setup.n_above, setup.n_below)
                    .expect("the sight ray meets the disk");
                // Round-off of ~1e3-unit coordinates through a bisection and a square root.
                assert!((c - v).length() < 1e-9, "eye {eye} V {v}: C {c}");
                checked += 1;
            }
            assert!(checked > 300, "{checked} samples seen through the disk");
        }
    }

    /// A sight point off the exact one gives a computed vertex off the true vertex: the measure
    /// can fail.
    #[test]
    fn computed_vertex_of_a_wrong_sight_point_is_off() {
        let disk = ThesisMembrane::flat_disk(RingFaceting::THESIS_FIT);
        let eye = DVec3::new(0.0, 450.0, 0.0);
        let v = DVec3::new(100.0, -200.0, 30.0);
        let s = flat_sight_point(eye, v, 0.0, 1.0, 1.51);
        let moved = s + DVec3::new(1.0, 0.0, 0.0);
        let c = computed_vertex(
            &disk,
            eye,
            virtual_vertex(eye, moved, v, 1.0, 1.51),
            1.0,
            1.51,
        )
        .unwrap();
        assert!((c - v).length() > 0.5, "{}", (c - v).length());
    }

    #[test]
    fn ray_hits_spheres_where_they_are() {
        use crate::accuracy::membranes::Orientation;
        for orientation in [Orientation::Bowl, Orientation::Cap] {
            let m = ThesisMembrane::sphere(142.0, orientation, RingFaceting::THESIS_FIT);
            let eye = DVec3::new(0.0, m.top_y() + 450.0, 0.0);
            for &target in &[
                DVec3::new(0.0, -500.0, 0.0),
                DVec3::new(60.0, -300.0, -20.0),
            ] {
                let hit = first_surface_hit(&m, eye, (target - eye).normalize()).unwrap();
                // On the sphere (centre (0, 0, 0) for a hemisphere), and on the ray.
                assert!((hit.length() - 142.0).abs() < 1e-9, "{orientation:?} {hit}");
                assert!(
                    (hit - eye)
                        .normalize()
                        .cross((target - eye).normalize())
                        .length()
                        < 1e-9
                );
                // The first hit: a cap is met on its upper side, a bowl on its floor.
                assert!(hit.y > 0.0 || orientation == Orientation::Bowl);
            }
        }
    }

    #[test]
    fn samples_fill_the_cube_under_the_refractor() {
        let disk = ThesisMembrane::flat_disk(RingFaceting::THESIS_FIT);
        let setup = VolumeSetup::thesis(450.0, 10.0);
        let samples = setup.samples(&disk);
        assert_eq!(samples.len(), 64_000);
        let top = samples.iter().map(|p| p.y).fold(f64::MIN, f64::max);
        let bottom = samples.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        assert_eq!((top, bottom), (-5.0, -395.0));
        assert!(samples
            .iter()
            .all(|p| p.x.abs() <= 195.0 && p.z.abs() <= 195.0));
    }
    /// On a hemisphere bowl, points just outside the rim are seen through its nearly vertical wall.
    /// Newton in the world's height field (infinite slope at the rim) leaves the disk or lands on
    /// the far wall; in the chart turned to the surface normal it finds the image, which obeys
    /// Snell's law there and reproduces the point through the computed vertex.
    #[test]
    fn exact_sight_points_through_a_hemisphere_rim_obey_snell() {
        use crate::accuracy::membranes::Orientation;
        let m = ThesisMembrane::sphere(142.0, Orientation::Bowl, RingFaceting::THESIS_FIT);
        let setup = VolumeSetup::thesis(450.0, 20.0);
        let eye = setup.eye(&m);
        let cells = Cells::build(&m, eye, 1.0, 1.51);
        let field = m.surface.as_height_field();
        let mut images = Vec::new();
        let (mut near_rim, mut world_chart_failures) = (0, 0);
        for v in setup.samples(&m) {
            if v.y > field.height(v.x, v.z) {
                continue;
            }
            cells.images(v, &mut images);
            let [(facet, linear)] = images.as_slice() else {
                continue;
            };
            if cells.extrapolated[*facet] || DVec2::new(linear.x, linear.z).length() < 137.0 {
                continue;
            }
            near_rim += 1;
            let s = exact_sight_point(&m, eye, v, *linear, 1.0, 1.51).expect("Newton converges");
            assert!(sight_point_is_valid(&m, eye, v, s), "V {v}: S {s}");
            // Snell: n1 (I x N) = n2 (T x N), with I and T the unit directions in and out.
            let normal = field.normal(s.x, s.z);
            let incoming = (s - eye).normalize();
            let outgoing = (v - s).normalize();
            let mismatch = (incoming.cross(normal) - 1.51 * outgoing.cross(normal)).length();
            assert!(mismatch < 1e-9, "V {v}: Snell off by {mismatch:e}");
            let c = computed_vertex(&m, eye, virtual_vertex(eye, s, v, 1.0, 1.51), 1.0, 1.51)
                .expect("a computed vertex");
            assert!((c - v).length() < 1e-6, "V {v}: C {c}");
            let problem = FermatProblem {
                surface: field,
                eye,
                point: v,
                n_above: 1.0,
                n_below: 1.51,
            };
            let in_world = solve_sight_point(&problem, DVec2::new(linear.x, linear.z))
                .map(|e| e.sight_point)
                .filter(|&e| sight_point_is_valid(&m, eye, v, e));
            world_chart_failures += in_world.is_none() as usize;
        }
        assert!(near_rim > 100, "{near_rim} samples seen near the rim");
        // Why the chart is there: in world coordinates most of these fail.
        assert!(
            world_chart_failures * 2 > near_rim,
            "{world_chart_failures} of {near_rim}"
        );
    }
}
