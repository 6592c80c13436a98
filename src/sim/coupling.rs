//! How characters push the water: the volume of body under the surface in every column of the
//! ripple grid ("occupancy", as a height), and the ripple displacement its change between two
//! frames causes.
//!
//! Occupancy is sampled per node, along the vertical line through it: with
//! `F(y) = D (exp(-(h - y) / D) - 1)` under the water and 0 above (D: the coupling depth), the
//! line's crossings of a closed surface with outward normals give
//! `sum over crossings of sign(n_y) F(y)` = the length of body under the water on that line
//! weighted by `exp(-depth / D)`, since `dF/dy` is that weight under the water and 0 above. Parts
//! above the water add nothing, and a body moving deep under the surface (depth >> D) barely stirs
//! it; for `D -> infinity` it is the plain submerged length. Sampling the lines exactly (rather
//! than spreading each triangle's share of the divergence sum over nearby nodes) keeps the top
//! and bottom of a body in the same column cancelling exactly, whatever the triangle sizes.
//!
//! Displacement: where occupancy grows by `dO` the body has pushed that much water aside. The
//! water goes down where the body now is and up around it: `strength * (blur(dO) - dO)`, which
//! moves volume without creating any (the blur keeps the sum), so a wading leg drives a bow wave
//! ahead and fills in behind; the wave equation turns that into rings and wakes.

use glam::{DVec3, Vec3};

use super::ripples::RippleSettings;
use crate::water::HeightField;

/// Column occupancy (metres of body under the water per node) of `meshes` (world space, outward
/// CCW triangles) over the ripple grid, against the surface `surface`.
pub fn occupancy(
    settings: &RippleSettings,
    meshes: &[(&[Vec3], &[[u32; 3]])],
    surface: &dyn HeightField,
    coupling_depth_m: f64,
) -> Vec<f32> {
    let (nx, nz) = (settings.nodes_x as usize, settings.nodes_z as usize);
    let mut length_m = vec![0.0f64; nx * nz];
    let node_x = |ix: usize| settings.min_x + ix as f64 * settings.spacing_m;
    let node_z = |iz: usize| settings.min_z + iz as f64 * settings.spacing_m;
    // Grid index range of the nodes in [low, high] along one axis.
    let nodes_between = |low: f64, high: f64, min: f64, count: usize| {
        let first = ((low - min) / settings.spacing_m).ceil().max(0.0) as usize;
        let last = ((high - min) / settings.spacing_m).floor();
        (last >= 0.0).then(|| first..=(last as usize).min(count - 1))
    };
    for &(positions, triangles) in meshes {
        for triangle in triangles {
            let [a, b, c] = triangle.map(|i| positions[i as usize].as_dvec3());
            let normal_y = (b - a).cross(c - a).y;
            if normal_y == 0.0 {
                continue; // vertical: no vertical line crosses it
            }
            // The projection on (x, z), counter-clockwise seen from above.
            let [p, q, r] = if normal_y > 0.0 { [a, b, c] } else { [a, c, b] };
            let edges = [(p, q), (q, r), (r, p)];
            let (Some(xs), Some(zs)) = (
                nodes_between(
                    p.x.min(q.x).min(r.x),
                    p.x.max(q.x).max(r.x),
                    settings.min_x,
                    nx,
                ),
                nodes_between(
                    p.z.min(q.z).min(r.z),
                    p.z.max(q.z).max(r.z),
                    settings.min_z,
                    nz,
                ),
            ) else {
                continue;
            };
            for iz in zs {
                for ix in xs.clone() {
                    let (x, z) = (node_x(ix), node_z(iz));
                    let Some(weights) = covers(&edges, x, z) else {
                        continue;
                    };
                    let y = weights[0] * p.y + weights[1] * q.y + weights[2] * r.y;
                    let below_m = (y - surface.height(x, z)).min(0.0);
                    if below_m < 0.0 {
                        // exp_m1 keeps F accurate for depths far below D (F -> y - h).
                        let weighted_m = coupling_depth_m * (below_m / coupling_depth_m).exp_m1();
                        length_m[iz * nx + ix] += weighted_m * normal_y.signum();
                    }
                }
            }
        }
    }
    length_m.into_iter().map(|v| v as f32).collect()
}

/// Barycentric weights of (x, z) in the triangle with `edges` (its vertices ordered so that the
/// triangle's normal points up), when it covers the point. A point on an edge shared by two such
/// triangles is covered by exactly one of them (see [`owns_edge`], the rasterisers' top-left
/// rule), so no line is counted twice or missed.
fn covers(edges: &[(DVec3, DVec3); 3], x: f64, z: f64) -> Option<[f64; 3]> {
    // Edge function: the y component of (to - from) x (point - from), which is positive for
    // points inside an up-facing triangle on all three of its edges.
    let side = |(from, to): &(DVec3, DVec3)| {
        (to.x - from.x) * (from.z - z) - (to.z - from.z) * (from.x - x)
    };
    let values = edges.map(|edge| side(&edge));
    for (value, edge) in values.iter().zip(edges) {
        if *value < 0.0 || (*value == 0.0 && !owns_edge(edge)) {
            return None;
        }
    }
    let total: f64 = values.iter().sum();
    (total > 0.0).then(|| {
        // The weight of a vertex is the edge function of the edge opposite it.
        [values[1] / total, values[2] / total, values[0] / total]
    })
}

/// Whether points exactly on `edge` belong to its triangle: a fixed choice per edge direction,
/// opposite for the two triangles sharing the edge (they run along it in opposite directions).
fn owns_edge((from, to): &(DVec3, DVec3)) -> bool {
    let (dx, dz) = (to.x - from.x, to.z - from.z);
    dz < 0.0 || (dz == 0.0 && dx > 0.0)
}

/// Ripple displacement (metres per node) from the occupancy change `before -> now`:
/// `strength * (blur(dO) - dO)`, with `blur` two passes of a 3x3 box (volume-preserving,
/// mirrored at the border).
pub fn displacement(
    settings: &RippleSettings,
    before: &[f32],
    now: &[f32],
    strength: f64,
) -> Vec<f32> {
    let (nx, nz) = (settings.nodes_x as usize, settings.nodes_z as usize);
    let change: Vec<f32> = now.iter().zip(before).map(|(n, b)| n - b).collect();
    let mut blurred = change.clone();
    for _ in 0..2 {
        blurred = box3(&blurred, nx, nz);
    }
    change
        .iter()
        .zip(&blurred)
        .map(|(d, b)| (strength as f32) * (b - d))
        .collect()
}

/// 3x3 box filter that keeps the sum: every node spreads its value equally over its 3x3
/// neighbourhood, mirrored back in at the border.
fn box3(values: &[f32], nx: usize, nz: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; values.len()];
    // A share that would leave the grid lands on the edge node instead.
    let mirror = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    for iz in 0..nz {
        for ix in 0..nx {
            let share = values[iz * nx + ix] / 9.0;
            if share == 0.0 {
                continue;
            }
            for dz in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (tx, tz) = (mirror(ix as isize + dx, nx), mirror(iz as isize + dz, nz));
                    out[tz * nx + tx] += share;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::water::FlatHeightField;

    fn grid() -> RippleSettings {
        RippleSettings {
            // Binary fractions: nodes fall exactly on the test boxes' edges (the tie rule's case).
            min_x: -1.25,
            min_z: -1.25,
            ..crate::sim::spectral::tests::settings(41, 41, 0.0625)
        }
    }

    /// An axis-aligned box as 12 outward CCW triangles.
    fn cube(min: Vec3, max: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { max.x } else { min.x },
                if y { max.y } else { min.y },
                if z { max.z } else { min.z },
            )
        };
        let positions: Vec<Vec3> = (0..8)
            .map(|i| p(i & 1 != 0, i & 2 != 0, i & 4 != 0))
            .collect();
        let quads = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
        ];
        let mut triangles = Vec::new();
        for [a, b, c, d] in quads {
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
        (positions, triangles)
    }

    fn total_volume(occupancy: &[f32], settings: &RippleSettings) -> f64 {
        occupancy.iter().map(|&o| o as f64).sum::<f64>() * settings.spacing_m.powi(2)
    }

    #[test]
    fn occupancy_integrates_to_the_submerged_volume() {
        let s = grid();
        let water = FlatHeightField { level_m: 0.0 };
        // A 0.25 x 0.4 x 0.25 m post standing half out of the water: 0.25 x 0.2 x 0.25 under,
        // its sides on grid lines: each node on them is counted by one triangle, not two or none.
        let (positions, triangles) = cube(
            Vec3::new(-0.125, -0.2, -0.125),
            Vec3::new(0.125, 0.2, 0.125),
        );
        // Depth weighting off (a very deep coupling depth) to check the volume itself.
        let o = occupancy(&s, &[(&positions, &triangles)], &water, 1e9);
        let volume = total_volume(&o, &s);
        assert!((volume - 0.0125).abs() < 1e-9, "{volume}");
        // Off the grid lines: the same volume, each line inside counted once.
        let (shifted, triangles) = cube(Vec3::new(-0.1, -0.2, -0.1), Vec3::new(0.15, 0.2, 0.15));
        let o = occupancy(&s, &[(&shifted, &triangles)], &water, 1e9);
        assert!((total_volume(&o, &s) - 0.0125).abs() < 1e-9);
        // Entirely above the water: nothing.
        let (high, triangles) = cube(Vec3::new(-0.1, 0.1, -0.1), Vec3::new(0.1, 0.3, 0.1));
        let o = occupancy(&s, &[(&high, &triangles)], &water, 1e9);
        assert_eq!(total_volume(&o, &s), 0.0);
        // Deep under the surface, with weighting: on every line only the weighted length
        // D (exp(-1.5 / D) - exp(-1.7 / D)), about 1 mm; the top and bottom faces' large terms
        // (about D each) cancel on each line, whatever their triangles.
        let (deep, triangles) = cube(Vec3::new(-0.1, -1.7, -0.1), Vec3::new(0.1, -1.5, 0.1));
        let o = occupancy(&s, &[(&deep, &triangles)], &water, 0.3);
        let expected = 0.3 * ((-1.5f64 / 0.3).exp() - (-1.7f64 / 0.3).exp());
        for value in o.iter().filter(|v| **v != 0.0) {
            assert!(
                (*value as f64 - expected).abs() < 1e-6,
                "{value} vs {expected}"
            );
        }
    }

    #[test]
    fn displacement_moves_water_without_creating_it() {
        let s = grid();
        let water = FlatHeightField { level_m: 0.0 };
        let (positions, triangles) = cube(
            Vec3::new(-0.125, -0.2, -0.125),
            Vec3::new(0.125, 0.2, 0.125),
        );
        let before = vec![0.0; s.node_count()];
        let now = occupancy(&s, &[(&positions, &triangles)], &water, 0.3);
        let push = displacement(&s, &before, &now, 1.0);
        let net: f64 = push.iter().map(|&p| p as f64).sum();
        let gross: f64 = push.iter().map(|&p| p.abs() as f64).sum();
        assert!(gross > 0.0);
        assert!(net.abs() < 1e-5 * gross, "net {net} of {gross}");
        // Down where the body entered, up around it.
        let centre = 20 * 41 + 20;
        assert!(push[centre] < 0.0);
        assert!(push[centre + 3] > 0.0);
    }
}
