//! Glass vessels by vertex displacement (Mukai, Makino & Chang, `papers/002_*`; ALGORITHM §10):
//! receives a vessel (a parallel pane or a cylindrical glass, the glass's index and the medium
//! inside), the eye and a point; returns every image of the point through the vessel's walls: the
//! wall crossings of its light path, the refraction count, and the displaced vertex that, seen
//! along a straight line from the eye, is where the refracted view puts the point. Pure CPU, f64,
//! no wgpu, no I/O.
//!
//! ## The displaced vertex
//! Mukai et al. move each vertex onto the straight sight line from the eye through the first wall
//! crossing: its screen position is then exact. How far along that line it goes only orders
//! depths. Their pane formula (eq. 2) keeps the vertex's distance across the pane's normal and
//! moves it along the normal; for the cylinder they chain one such move per wall with a moving
//! eye, which has no 3-D form for skew rays. Here every vessel uses one rule, the virtual vertex of
//! ALGORITHM §5 generalised to several media: along the first segment's direction `D0`,
//!
//! ```text
//! V' = E + D0 * sum_k (n_eye / n_k) * l_k      (l_k: length of the path's k-th segment, in medium n_k)
//! ```
//!
//! each segment's length scaled by the eye's index over its own ("apparent distance"). It equals
//! §5's `|S - E| + eta |V - S|` for one interface, gives the apparent depth `d n_eye / n` at
//! normal incidence through any stack of flat layers, and keeps the order of true distances along
//! one path. It differs from Mukai's pane depth off the normal, never in screen position.
//!
//! ## What is and is not modelled
//! - Pane: two parallel faces clipped to a rectangle; its four edge faces absorb (a path through
//!   them is no image). The medium behind applies to paths through the pane only: a tank is
//!   several vessels, and a path around a pane's edge stays in the eye's medium.
//! - Cylinder: the wall between the inner and outer radius, from the base up to the height; open
//!   at both ends and with no bottom; the top and bottom rims absorb. With water inside, the water
//!   fills the inner radius over the wall's height; paths through the water's own surface (an open
//!   glass seen from above) belong to the water's refraction stage and are not enumerated here.
//! - The eye must be outside the vessel's glass and, for a cylinder, outside its outer radius.

pub mod bench;
pub mod cylinder;
pub mod pane;
#[cfg(test)]
mod tests;

use glam::DVec3;

pub use cylinder::Cylinder;
pub use pane::Pane;

/// Index of refraction of air (the eye's medium outside every vessel).
pub const AIR_INDEX: f64 = 1.0;
/// Index of refraction of water, the value the water stage uses.
pub const WATER_INDEX: f64 = 1.333;

/// What fills a vessel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Medium {
    Air,
    Water,
}

impl Medium {
    pub fn index(self) -> f64 {
        match self {
            Medium::Air => AIR_INDEX,
            Medium::Water => WATER_INDEX,
        }
    }
}

/// A vessel of either kind.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Vessel {
    Pane(Pane),
    Cylinder(Cylinder),
}

impl Vessel {
    /// One line for `snell info`.
    pub fn describe(&self) -> String {
        let inside = |m: Medium| match m {
            Medium::Air => "air",
            Medium::Water => "water",
        };
        match self {
            Vessel::Pane(p) => format!(
                "pane {:.3} x {:.3} m, {:.1} mm thick, glass {}, {} behind, at {:?} facing {:?}",
                2.0 * p.half_size_m[0],
                2.0 * p.half_size_m[1],
                1000.0 * p.thickness_m,
                p.glass_index,
                inside(p.inside),
                p.center.to_array(),
                p.normal.to_array()
            ),
            Vessel::Cylinder(c) => format!(
                "cylinder radii {:.4}-{:.4} m, {:.3} m high, glass {}, {} inside, base {:?} axis {:?}",
                c.inner_radius_m,
                c.outer_radius_m,
                c.height_m,
                c.glass_index,
                inside(c.inside),
                c.base.to_array(),
                c.axis.to_array()
            ),
        }
    }

    /// Every image of `point` seen from `eye` through this vessel (and the direct view when the
    /// straight segment misses the glass), appended to `out`.
    pub fn images(&self, eye: DVec3, point: DVec3, out: &mut Vec<Image>) {
        match self {
            Vessel::Pane(pane) => pane.images(eye, point, out),
            Vessel::Cylinder(cylinder) => cylinder.images(eye, point, out),
        }
    }
}

/// Most wall crossings a path can have (four: in and out of both walls of a cylinder).
pub const MAX_CROSSINGS: usize = 4;

/// One image of a point: one light path from the point to the eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Image {
    /// The moved vertex (see the module's doc): seen along a straight line from the eye, it is where
    /// this path shows the point.
    pub displaced: DVec3,
    /// Wall crossings on the path, in order from the eye: 0 (the direct view), 1, 2, 3 or 4.
    pub refractions: u8,
    /// The crossings, the first `refractions` of them.
    pub crossings: [DVec3; MAX_CROSSINGS],
    /// Optical path length `sum n_k l_k` from the eye to the point, metres.
    pub optical_path_m: f64,
    /// The solve met its tolerance (the path's end is within [`position_tolerance_m`] of the point);
    /// an image that did not is kept and must be flagged, like the water's failed solves.
    pub converged: bool,
    /// Solver iterations spent on this image.
    pub iterations: u32,
}

impl Image {
    pub fn crossings(&self) -> &[DVec3] {
        &self.crossings[..self.refractions as usize]
    }
}

/// How close the end of a solved path must come to the point for the image to count as converged,
/// relative to the scene's scale (the eye-point distance): 1e-9 of it, far under a pixel at any
/// resolution and far over f64 round-off of the closed-form paths.
pub const POSITION_TOLERANCE: f64 = 1e-9;

/// [`POSITION_TOLERANCE`] in metres for one eye and point.
pub fn position_tolerance_m(eye: DVec3, point: DVec3) -> f64 {
    POSITION_TOLERANCE * (point - eye).length().max(1e-3)
}

/// The image of a path given by its vertices `eye, c_1 .. c_k, point` and the index of each of its
/// `k + 1` segments: the displaced vertex along the first segment at the reduced distance.
fn image_from_path(
    eye: DVec3,
    crossings: &[DVec3],
    point: DVec3,
    indices: &[f64],
    converged: bool,
    iterations: u32,
) -> Image {
    debug_assert_eq!(indices.len(), crossings.len() + 1);
    let (mut optical_path_m, mut apparent_m) = (0.0, 0.0);
    let mut from = eye;
    for (k, &to) in crossings.iter().chain(std::iter::once(&point)).enumerate() {
        let length_m = (to - from).length();
        optical_path_m += indices[k] * length_m;
        apparent_m += indices[0] / indices[k] * length_m;
        from = to;
    }
    let first = crossings.first().copied().unwrap_or(point);
    let direction = (first - eye).normalize_or_zero();
    let mut stored = [DVec3::ZERO; MAX_CROSSINGS];
    stored[..crossings.len()].copy_from_slice(crossings);
    Image {
        displaced: eye + direction * apparent_m,
        refractions: crossings.len() as u8,
        crossings: stored,
        optical_path_m,
        converged,
        iterations,
    }
}
