//! Test helpers: membranes and height fields built from wave sums, shared by the refraction tests.

use crate::water::{HeightField, Membrane, MembraneGrid};

/// A sum of sine waves `amplitude * sin(k . (x, z) + phase)`.
#[derive(Clone, Debug, Default)]
pub struct Waves {
    /// (amplitude_m, kx, kz, phase)
    pub waves: Vec<(f64, f64, f64, f64)>,
    pub level_m: f64,
}

impl HeightField for Waves {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.level_m
            + self
                .waves
                .iter()
                .map(|&(a, kx, kz, ph)| a * (kx * x + kz * z + ph).sin())
                .sum::<f64>()
    }
    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        self.waves
            .iter()
            .fold((0.0, 0.0), |(gx, gz), &(a, kx, kz, ph)| {
                let c = a * (kx * x + kz * z + ph).cos();
                (gx + c * kx, gz + c * kz)
            })
    }
}

/// The membrane a frame builds over the rectangle ([`crate::water::build_membrane`]: its
/// triangulation, heights and analytic normals).
pub fn membrane_from(surface: &dyn HeightField, grid: MembraneGrid) -> Membrane {
    crate::water::build_membrane(surface, &grid)
}

pub fn square_grid(half_m: f64, cells: u32) -> MembraneGrid {
    MembraneGrid {
        min_x: -half_m,
        min_z: -half_m,
        max_x: half_m,
        max_z: half_m,
        cells_x: cells,
        cells_z: cells,
    }
}
