//! How characters push the water: the volume of body under the surface in every column of the
//! ripple grid ("occupancy", as a height), and the ripple displacement its change between two
//! frames causes.
//!
//! Occupancy comes from the divergence theorem: for a closed surface with outward normals and
//! `F(y) = D (exp(-(h - y) / D) - 1)` under the water (0 above), `sum over triangles of
//! F(y) n_y A` is the volume of body under the water in a column weighted by
//! `exp(-depth / D)`, because `dF/dy` is that weight under the water and 0 above. So triangles
//! above the water add nothing, no large terms cancel, and a body moving deep under the surface
//! (depth >> D, the coupling depth) barely stirs it; for `D -> infinity` it is the plain volume.
//! Each triangle's term is splatted bilinearly at its centroid.
//!
//! Displacement: where occupancy grows by `dO` the body has pushed that much water aside. The
//! water goes down where the body now is and up around it: `strength * (blur(dO) - dO)`, which
//! moves volume without creating any (the blur keeps the sum), so a wading leg drives a bow wave
//! ahead and fills in behind; the wave equation turns that into rings and wakes.

use glam::Vec3;

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
    let mut volume_m3 = vec![0.0f64; nx * nz];
    let cell_area_m2 = settings.spacing_m * settings.spacing_m;
    for &(positions, triangles) in meshes {
        for triangle in triangles {
            let [a, b, c] = triangle.map(|i| positions[i as usize].as_dvec3());
            let centroid = (a + b + c) / 3.0;
            let area_normal = 0.5 * (b - a).cross(c - a);
            let water_m = surface.height(centroid.x, centroid.z);
            let below_m = (centroid.y - water_m).min(0.0);
            if below_m == 0.0 || area_normal.y == 0.0 {
                continue;
            }
            // exp_m1 keeps F accurate for depths far below D (F -> y - h).
            let weighted_m = coupling_depth_m * (below_m / coupling_depth_m).exp_m1();
            let term = weighted_m * area_normal.y;
            // Bilinear splat at the centroid; outside the grid nothing is pushed.
            let gx = (centroid.x - settings.min_x) / settings.spacing_m;
            let gz = (centroid.z - settings.min_z) / settings.spacing_m;
            if !(gx >= 0.0 && gz >= 0.0 && gx <= (nx - 1) as f64 && gz <= (nz - 1) as f64) {
                continue;
            }
            let (ix, iz) = ((gx as usize).min(nx - 2), (gz as usize).min(nz - 2));
            let (fx, fz) = (gx - ix as f64, gz - iz as f64);
            let at = iz * nx + ix;
            volume_m3[at] += term * (1.0 - fx) * (1.0 - fz);
            volume_m3[at + 1] += term * fx * (1.0 - fz);
            volume_m3[at + nx] += term * (1.0 - fx) * fz;
            volume_m3[at + nx + 1] += term * fx * fz;
        }
    }
    volume_m3
        .into_iter()
        .map(|v| (v / cell_area_m2) as f32)
        .collect()
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
    use crate::sim::ripples::Border;
    use crate::water::FlatHeightField;

    fn grid() -> RippleSettings {
        RippleSettings {
            nodes_x: 41,
            nodes_z: 41,
            min_x: -1.0,
            min_z: -1.0,
            spacing_m: 0.05,
            speed_m_per_s: 0.5,
            damping_per_s: 0.0,
            border: Border::Reflect,
            sponge_nodes: 0,
            sponge_damping_per_s: 0.0,
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
        // A 0.2 x 0.4 x 0.2 m post standing half out of the water: 0.2 x 0.2 x 0.2 under.
        let (positions, triangles) = cube(Vec3::new(-0.1, -0.2, -0.1), Vec3::new(0.1, 0.2, 0.1));
        // Depth weighting off (a very deep coupling depth) to check the volume itself.
        let o = occupancy(&s, &[(&positions, &triangles)], &water, 1e9);
        assert!(
            (total_volume(&o, &s) - 0.008).abs() < 1e-6,
            "{}",
            total_volume(&o, &s)
        );
        // Entirely above the water: nothing.
        let (high, triangles) = cube(Vec3::new(-0.1, 0.1, -0.1), Vec3::new(0.1, 0.3, 0.1));
        let o = occupancy(&s, &[(&high, &triangles)], &water, 1e9);
        assert_eq!(total_volume(&o, &s), 0.0);
        // Deep under the surface, with the default weighting, almost nothing.
        let (deep, triangles) = cube(Vec3::new(-0.1, -1.7, -0.1), Vec3::new(0.1, -1.5, 0.1));
        let o = occupancy(&s, &[(&deep, &triangles)], &water, 0.3);
        assert!(total_volume(&o, &s).abs() < 0.008 * 0.01);
    }

    #[test]
    fn displacement_moves_water_without_creating_it() {
        let s = grid();
        let water = FlatHeightField { level_m: 0.0 };
        let (positions, triangles) = cube(Vec3::new(-0.1, -0.2, -0.1), Vec3::new(0.1, 0.2, 0.1));
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
