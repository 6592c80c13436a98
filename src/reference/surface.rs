//! Where a sight ray meets the water in the model the rasteriser draws: the triangulated
//! membrane with interpolated vertex normals ([`MembraneSurface`]). The other model, the exact
//! surface, is [`crate::refraction::surface::ExactSurface`] (the one exact-surface module, with
//! its guarantee).

use glam::Vec3;

use super::bvh::{Bvh, Ray};
use crate::refraction::surface::SurfaceHit;
use crate::water::Membrane;

/// The membrane as triangles with interpolated vertex normals.
pub struct MembraneSurface<'a> {
    pub membrane: &'a Membrane,
    bvh: Bvh,
}

impl<'a> MembraneSurface<'a> {
    pub fn new(membrane: &'a Membrane) -> Self {
        let triangles: Vec<[Vec3; 3]> = membrane
            .triangles
            .iter()
            .map(|t| t.map(|i| membrane.positions[i as usize]))
            .collect();
        MembraneSurface {
            membrane,
            bvh: Bvh::build(&triangles),
        }
    }

    /// The nearest facet the ray meets in `(t_min, t_max)` (either side), with the normal
    /// interpolated from its vertices' as the rasteriser interpolates it.
    pub fn first_hit(
        &self,
        origin: Vec3,
        direction: Vec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<SurfaceHit> {
        let ray = Ray::new(origin, direction);
        let hit = self.bvh.closest_hit(&ray, t_min, t_max, |_| true)?;
        let [a, b, c] = self.membrane.triangles[hit.triangle as usize];
        let w = 1.0 - hit.u - hit.v;
        let n = &self.membrane.normals;
        let normal = n[a as usize] * w + n[b as usize] * hit.u + n[c as usize] * hit.v;
        Some(SurfaceHit {
            t: hit.t as f64,
            position: ray.at(hit.t).as_dvec3(),
            normal: normal.normalize().as_dvec3(),
        })
    }
}
