//! Test helpers: membranes and height fields built from wave sums, shared by the refraction tests.

use crate::refraction::surface::ExactSurface;
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

/// A test surface that knows its bounds (see [`ExactSurface`]: they must hold over the plane).
pub trait Bounded: HeightField + Sized {
    /// The exact surface over `extent`, with the field's bounds.
    fn exact(&self, extent: MembraneGrid) -> ExactSurface<'_>;
}

impl Bounded for crate::water::FlatHeightField {
    fn exact(&self, extent: MembraneGrid) -> ExactSurface<'_> {
        flat(self, self.level_m, extent)
    }
}

impl Bounded for Waves {
    /// Heights within the level -/+ the sum of amplitudes, slope at most `sum a k`, curvature at
    /// most `sum a k^2`.
    fn exact(&self, extent: MembraneGrid) -> ExactSurface<'_> {
        let sum = |f: &dyn Fn(f64, f64) -> f64| {
            self.waves
                .iter()
                .map(|&(a, kx, kz, _)| a.abs() * f(kx, kz))
                .sum::<f64>()
        };
        let reach = sum(&|_, _| 1.0);
        exact(
            self,
            extent,
            (self.level_m - reach, self.level_m + reach),
            sum(&|kx, kz| kx.hypot(kz)),
            sum(&|kx, kz| kx * kx + kz * kz),
        )
    }
}

/// A surface with the bounds the caller knows for it (they must hold over the whole plane).
pub fn exact<'a>(
    height_field: &'a dyn HeightField,
    extent: MembraneGrid,
    height_range_m: (f64, f64),
    slope_bound: f64,
    curvature_bound: f64,
) -> ExactSurface<'a> {
    ExactSurface {
        height_field,
        extent,
        height_range_m,
        slope_bound,
        curvature_bound,
        local_bounds: None,
    }
}

/// A flat surface at `level_m` over `extent`.
pub fn flat<'a>(
    height_field: &'a dyn HeightField,
    level_m: f64,
    extent: MembraneGrid,
) -> ExactSurface<'a> {
    exact(height_field, extent, (level_m, level_m), 0.0, 0.0)
}

/// (slope, curvature) bounds of a Gaussian ridge `a exp(-(x / w)^2)`: `|h'|` peaks at
/// `a sqrt(2 / e) / w` (x = w / sqrt 2), `|h''|` at `2 a / w^2` (x = 0).
pub fn gaussian_ridge_bounds(amplitude_m: f64, width_m: f64) -> (f64, f64) {
    let a = amplitude_m.abs();
    (
        a * (2.0 / std::f64::consts::E).sqrt() / width_m,
        2.0 * a / (width_m * width_m),
    )
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
