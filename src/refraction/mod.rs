//! Stage 3, refraction: per membrane vertex the refraction ray and Fresnel weight; refraction cells;
//! the sight-facet search (accelerated, with a brute-force oracle) returning every image of a point;
//! virtual vertices, triangles split at the water line, and the per-frame failure flags; for the
//! exact method, sight points by Newton on Fermat's principle and adaptive subdivision.
//! Pure CPU (rayon): no wgpu, no I/O.

pub mod bench;
pub mod cells;
pub mod exact;
#[cfg(test)]
mod exact_tests;
pub mod flags;
pub mod flat;
#[cfg(test)]
mod oracle_tests;
pub mod rays;
pub mod search;
pub mod split;
pub mod subdivision;
pub mod surface;
pub mod virtual_geometry;
#[cfg(test)]
pub(crate) mod work;
