//! Stage 2, water: the analytic wave field (a sum of height waves, y = h(x, z, t)), the height-field
//! view of it at one instant, and the triangulated membrane grid with analytic normals.
//! Receives the scene's water description and a time; returns a [`Membrane`] and a [`HeightField`].

use glam::{DVec3, Vec3};

mod height_fields;
mod membrane;
mod waves;

pub use height_fields::{FlatHeightField, FnHeightField};
pub use membrane::build_membrane;
pub use waves::{WaterSurface, Wave, WaveField, GRAVITY_M_PER_S2};

/// A wave field, a grid or a membrane that cannot be used, with what to change.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WaterError {
    #[error("wave {index}: {reason}")]
    InvalidWave { index: usize, reason: String },
    #[error("water level must be finite, got {level_m}")]
    InvalidLevel { level_m: f64 },
    #[error("membrane grid: {reason}")]
    InvalidGrid { reason: String },
}

/// A surface given as a height field over the horizontal plane. The exact surface: kept beside the
/// faceted membrane for exact solves, splitting triangles at the water line and the reference tracer.
pub trait HeightField: Sync {
    /// Height of the surface at (x, z), metres.
    fn height(&self, x: f64, z: f64) -> f64;
    /// (dh/dx, dh/dz) at (x, z).
    fn gradient(&self, x: f64, z: f64) -> (f64, f64);
    /// Height and (dh/dx, dh/dz) together; fields that share work between the two (one `sin_cos`
    /// per wave) override it. Root finders call this once per step.
    fn height_and_gradient(&self, x: f64, z: f64) -> (f64, (f64, f64)) {
        (self.height(x, z), self.gradient(x, z))
    }
    /// Unit normal pointing up (to the air side): normalize(-dh/dx, 1, -dh/dz).
    fn normal(&self, x: f64, z: f64) -> DVec3 {
        let (gx, gz) = self.gradient(x, z);
        DVec3::new(-gx, 1.0, -gz).normalize()
    }
    /// Second derivatives (h_xx, h_xz, h_zz) at (x, z), for Newton's method on Fermat's principle
    /// (`refraction::exact`). The default takes central differences of [`Self::gradient`] with a
    /// step of 1e-5 of the coordinate's magnitude (at least 1e-5): about 1e-9 relative on smooth
    /// surfaces of metre scale. Fields with cheap analytic second derivatives override it.
    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        let step_x = 1e-5 * x.abs().max(1.0);
        let step_z = 1e-5 * z.abs().max(1.0);
        let (xp_x, xp_z) = self.gradient(x + step_x, z);
        let (xm_x, xm_z) = self.gradient(x - step_x, z);
        let (zp_x, zp_z) = self.gradient(x, z + step_z);
        let (zm_x, zm_z) = self.gradient(x, z - step_z);
        let h_xx = (xp_x - xm_x) / (2.0 * step_x);
        let h_zz = (zp_z - zm_z) / (2.0 * step_z);
        // Both mixed differences estimate the same h_xz; their mean cancels part of the error.
        let h_xz = 0.5 * ((xp_z - xm_z) / (2.0 * step_x) + (zp_x - zm_x) / (2.0 * step_z));
        (h_xx, h_xz, h_zz)
    }
}

/// The rectangle of the horizontal plane the membrane covers and its grid resolution (cells).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MembraneGrid {
    pub min_x: f64,
    pub min_z: f64,
    pub max_x: f64,
    pub max_z: f64,
    pub cells_x: u32,
    pub cells_z: u32,
}

/// The faceted water surface at one instant: (cells_x + 1) * (cells_z + 1) vertices, row-major in z
/// then x (index = iz * (cells_x + 1) + ix), two triangles per cell, counter-clockwise seen from above.
///
/// Triangle layout (fixed, other stages rely on it): cell (ix, iz) has index `c = iz * cells_x + ix`
/// and owns triangles `2c` and `2c + 1`. With `v00 = (ix, iz)`, `v10 = (ix + 1, iz)`,
/// `v01 = (ix, iz + 1)`, `v11 = (ix + 1, iz + 1)`, every cell is cut along the diagonal v00-v11:
/// triangle `2c = [v00, v01, v11]` (the half where the local z fraction >= the x fraction) and
/// `2c + 1 = [v00, v11, v10]`. Both have `(p1 - p0) x (p2 - p0)` pointing to +y.
#[derive(Clone, Debug, PartialEq)]
pub struct Membrane {
    pub grid: MembraneGrid,
    pub positions: Vec<Vec3>,
    /// Analytic unit normals pointing up.
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}
