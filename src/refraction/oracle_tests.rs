//! The search and the exact method against the independent image oracle ([`crate::oracle`]) on
//! seeded steep membranes, with points placed in convergence zones (several images by the
//! oracle), and the test asserts that they were.

use glam::{DVec3, Vec3};

use super::exact::{exact_images, ExactImage};
use super::search::test_support::{membrane_from, square_grid, Bounded, Waves};
use super::search::{CellMode, Image, RefractionField, RefractionSetup};
use crate::oracle::{OracleImages, OracleWater};
use crate::seeded::SplitMix64;

const N_AIR: f64 = 1.0;
const N_WATER: f64 = 1.333;

/// Seeded crest-focusing waves: `count` sines of total steepness `steepness` (a k summed).
fn steep_waves(rng: &mut SplitMix64, count: usize, steepness: f64) -> Waves {
    let waves = (0..count)
        .map(|_| {
            let k = std::f64::consts::TAU / rng.range(0.8, 2.0);
            let angle = rng.range(-0.4, 0.4);
            (
                steepness / k / count as f64,
                k * angle.cos(),
                k * angle.sin(),
                rng.range(0.0, std::f64::consts::TAU),
            )
        })
        .collect();
    Waves {
        waves,
        level_m: 0.0,
    }
}

struct Case {
    surface: Waves,
    eye: DVec3,
}

/// What one point gave: the oracle's images, the linear search's and the exact method's.
struct Found {
    oracle: OracleImages,
    linear: Vec<Image>,
    exact: Vec<ExactImage>,
}

fn cases() -> Vec<Case> {
    let mut rng = SplitMix64::new(0x04AC_1E5E);
    (0..4)
        .map(|i| Case {
            surface: steep_waves(&mut rng, 1 + i % 2, [0.45, 0.6][i % 2]),
            eye: DVec3::new(
                rng.range(-1.5, -0.5),
                rng.range(2.0, 3.5),
                rng.range(-0.3, 0.3),
            ),
        })
        .collect()
}

/// Runs `visit` on every sampled point of every case with what the three found.
fn for_each_point(points_per_case: usize, mut visit: impl FnMut(usize, DVec3, &Found)) {
    for (c, case) in cases().iter().enumerate() {
        let membrane = membrane_from(&case.surface, square_grid(2.5, CELLS));
        let water = case.surface.exact(membrane.grid);
        let oracle = OracleWater {
            height_field: &case.surface,
            extent: membrane.grid,
            height_range_m: water.height_range_m,
            slope_bound: water.slope_bound,
            curvature_bound: water.curvature_bound,
            n_above: N_AIR,
            n_below: N_WATER,
            local_bounds: None,
        };
        let setup = RefractionSetup {
            eye: case.eye.as_vec3(),
            n_above: N_AIR as f32,
            n_below: N_WATER as f32,
            cell_mode: CellMode::EqualT,
        };
        let field = RefractionField::build(&membrane, &water, setup, (-3.0, 0.5));
        let mut rng = SplitMix64::new(0x5EED + c as u64);
        for _ in 0..points_per_case {
            let point = Vec3::new(
                rng.range(-1.5, 1.5) as f32,
                rng.range(-3.0, -0.8) as f32,
                rng.range(-1.0, 1.0) as f32,
            )
            .as_dvec3();
            let mut found = Found {
                oracle: oracle.images(case.eye, point),
                linear: Vec::new(),
                exact: Vec::new(),
            };
            field.images(point.as_vec3(), &mut found.linear);
            exact_images(&field, point, &found.linear, &mut found.exact);
            visit(c, point, &found);
        }
    }
}

/// Membrane cells across (over 5 m): spacing 5.2 cm.
const CELLS: u32 = 96;
const SPACING_M: f64 = 5.0 / CELLS as f64;

/// The exact method (Newton from the linear search's images) against the oracle, and the linear
/// search's image count, on four seeded crest-focusing surfaces seen from 2-3.5 m. Every exact
/// image must be one of the oracle's (no false image); every oracle image must be found unless
/// another image of the same point lies within one membrane cell of it: such a pair sits on both
/// sides of a fold about to merge, which the faceted membrane (whose cells seed the exact method)
/// does not resolve. The linear count must equal the oracle's wherever no such pair exists. The
/// points must reach convergence zones: at least 20 with several well-separated images.
#[test]
fn the_exact_method_finds_every_image_the_oracle_finds_in_convergence_zones() {
    let (mut separated_multi, mut near_fold) = (0, 0);
    for_each_point(700, |c, point, found| {
        let context = format!("case {c}, point {point}");
        assert!(found.oracle.is_certain(), "{context}: {:?}", found.oracle);
        let truth = &found.oracle.images;
        let solved: Vec<DVec3> = found
            .exact
            .iter()
            .filter(|e| !e.newton_fallback)
            .map(|e| e.sight_point)
            .collect();
        let matches = |a: DVec3, b: DVec3| (a - b).length() < 1e-6;
        for s in &solved {
            assert!(
                truth.iter().any(|t| matches(t.sight_point, *s)),
                "{context}: exact image {s} is none of the oracle's {truth:?}"
            );
        }
        let paired = |i: usize| {
            truth.iter().enumerate().any(|(j, other)| {
                j != i && (other.sight_point - truth[i].sight_point).length() < SPACING_M
            })
        };
        let mut any_paired = false;
        for (i, t) in truth.iter().enumerate() {
            if paired(i) {
                any_paired = true;
                continue;
            }
            assert!(
                solved.iter().any(|s| matches(t.sight_point, *s)),
                "{context}: the exact method missed {t:?} (linear {:?})",
                found.linear
            );
        }
        if any_paired {
            near_fold += 1;
        } else {
            assert_eq!(
                found.linear.len(),
                truth.len(),
                "{context}: linear {:?}, oracle {truth:?}",
                found.linear
            );
            separated_multi += (truth.len() >= 2) as usize;
        }
    });
    assert!(
        separated_multi >= 20,
        "only {separated_multi} points in convergence zones ({near_fold} near folds)"
    );
}
