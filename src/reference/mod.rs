//! The ray-traced reference over the same stage-2 output as the rasteriser: receives one frame's
//! objects (static and posed), exact water surface, membrane, camera, lights, materials and
//! textures; returns the same [`RenderedFrame`] layers the GPU stage returns. Pure CPU (rayon over
//! tiles of rows), no wgpu, no I/O.
//!
//! Per pixel: the sight ray through the pixel centre ([`crate::camera::PixelRays`]) meets the
//! water first ([`surface`]: the exact height field, or the triangulated membrane with
//! interpolated normals) and the scene's triangles ([`bvh`]) before it. An object met before the
//! water is shaded above water (only points that are not in the water count: the rasteriser
//! splits objects at the exact surface and draws their under-water parts only through it). At the
//! water, Schlick's F weights the sky seen along the reflected ray (plus the sun's glint,
//! [`shading::water_reflection`]) against the refracted ray,
//! traced through the BVH to the first point under water, shaded by `shade_under` with the true
//! normal and the true path `|V - S|`; a refracted ray that meets nothing in the water shows the
//! deep-water colour, as the rasteriser's stencil clear does. Every formula of the shading model
//! is [`crate::gpu::shading`]'s, the one the shaders mirror.
//!
//! Layers: the depth along the view axis of the first surface met (the water for refracted
//! pixels), the apparent depth (for refracted pixels the virtual image `E + d (|S - E| + eta
//! |V - S|)`, as the rasteriser places it), `position` the true point seen (the under-water point
//! for refracted pixels, 0 for sky and for water with nothing behind), the water matte and
//! reflection, `flags` all 0: the reference has no virtual geometry to flag. Where nothing is
//! seen each layer holds what the EXR channel map states ([`crate::draw::SKY_DEPTH_M`]).
//!
//! Anti-aliasing ([`TraceScene::grid`] above 1): every layer is still the centre ray's, and
//! `grid` x `grid` stratified, jittered rays more a pixel ([`trace_frame`]) give the beauty and
//! the water's reflection their mean (the box filter over the pixel) and the Cryptomatte its
//! coverage, as the rasteriser's supersampled frames do (`crate::gpu`'s `resolve.rs`).
//!
//! Textures ([`texture`]): the GPU's array and mip chain, trilinear, at the level the GPU's
//! derivatives would pick, estimated per hit as log2 of (footprint of the pixel at the hit,
//! metres) x (texels per metre of the triangle) / |cos| of the angle between the ray and the
//! surface (the footprint's long axis, which is what the GPU's max-of-derivatives measures). For
//! refracted pixels the footprint is taken at the apparent distance `|S - E| + eta |V - S|`
//! (ALGORITHM §4) and the obliquity along the refracted ray: an estimate, not the exact
//! derivative of the virtual triangle (on `pool.toml` the whole beauty agrees with the
//! rasteriser's to 0.5 % L1 in linear light, see `tests/reference.rs`).

pub mod bvh;
pub mod surface;
pub mod texture;
pub mod vessel;

use std::time::Instant;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::draw::{DrawMaterial, FrameView, RenderedFrame, SKY_DEPTH_M};
use crate::gpu::shading;
use crate::mesh::Object;
use crate::water::Membrane;

use crate::refraction::surface::{ExactSurface, RootSteps, SurfaceHit};
use bvh::{Bvh, Hit, Ray};
use surface::MembraneSurface;
use texture::TextureSet;

/// Which water surface the sight rays meet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WaterModel {
    /// The frame's analytic height field (waves plus ripples): the reference.
    Exact,
    /// The triangulated membrane with interpolated vertex normals: what the rasteriser draws.
    Membrane,
}

/// Rows per tile: a tile is a band of whole rows, a rayon task each (1280x720: 180 tasks).
const ROWS_PER_TILE: u32 = 4;
/// How far a point may lie outside the water (above the surface or past the extent's border) and
/// still count as in it: f32 round-off of points on the surface or on the pool's walls.
const IN_WATER_SLACK_M: f64 = 1e-4;
/// Refracted rays start this far along from the surface point, so they do not meet a triangle
/// through the very point they leave from.
const REFRACTED_T_MIN_M: f32 = 1e-5;

/// One frame as the tracer sees it.
pub struct TraceScene<'a> {
    /// Static objects then posed characters: an object's index here is its material's index.
    pub objects: Vec<&'a Object>,
    pub materials: &'a [DrawMaterial],
    pub textures: &'a TextureSet,
    /// The exact water: what decides what is in the water in both models, and the surface the
    /// [`WaterModel::Exact`] rays meet.
    pub surface: ExactSurface<'a>,
    pub membrane: &'a Membrane,
    pub view: FrameView,
    pub water_model: WaterModel,
    /// Anti-aliasing: `grid` x `grid` stratified rays a pixel for the beauty and the coverage
    /// ([`trace_frame`]); 1 traces the pixel centre alone.
    pub grid: u32,
}

/// What a traced frame cost and counted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceStats {
    /// One per pixel, and `grid * grid` more a pixel where [`TraceScene::grid`] is above 1.
    pub primary_rays: u64,
    /// Sight rays that met the water and were refracted and traced on through the BVH (one per
    /// such primary ray): the rays `reference.refracted_rays_per_sec` counts.
    pub refracted_rays: u64,
    /// Height-field evaluations of the exact surface's root finder, over the frame.
    pub surface_evaluations: u64,
    pub triangles: usize,
    pub bvh_nodes: usize,
    /// Building the BVH (and the membrane's, for [`WaterModel::Membrane`]).
    pub build_secs: f64,
    /// Everything: build, rays, shading.
    pub total_secs: f64,
}

/// What one pixel shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelSample {
    pub beauty: Vec3,
    /// Distance along the ray to the first surface met; +inf for sky.
    pub distance_m: f32,
    /// Depth along the view axis of the first surface met; [`SKY_DEPTH_M`] for sky.
    pub depth_m: f32,
    /// Depth along the view axis of what the pixel shows (the virtual image through water).
    pub apparent_depth_m: f32,
    /// Where the first surface is the water: (F * sky reflected + the sun's glint, F)
    /// ([`shading::water_reflection`]).
    pub water_reflection: Option<Vec4>,
    /// The true point seen; NaN for sky and for water with nothing behind it (the frame holds 0).
    pub position: Vec3,
    /// 0 = no object (sky, water with nothing behind); k + 1 = object k.
    pub object: u32,
    pub refracted: bool,
    pub surface_evaluations: u32,
}

/// The frame's triangles and what the tracer needs to shade a hit.
pub struct Tracer<'a> {
    scene: &'a TraceScene<'a>,
    bvh: Bvh,
    /// (object, triangle in the object's mesh) of every BVH triangle.
    owners: Vec<(u32, u32)>,
    membrane_surface: Option<MembraneSurface<'a>>,
    camera: Camera,
    forward: Vec3,
    /// Angle one pixel subtends at the image centre, radians (per unit distance).
    pixel_angle: f32,
    /// Level-0 texture size.
    texture_size: Vec2,
    eta: f32,
}

/// A point on an object's triangle, with what shading needs.
struct ObjectPoint {
    object: u32,
    position: Vec3,
    normal: Vec3,
    uv: Vec2,
    geometric_normal: Vec3,
    /// Level-0 texels per metre on the surface (square root of the area ratio).
    texels_per_m: f32,
}

impl<'a> Tracer<'a> {
    /// Builds the frame's BVH (and the membrane's when the membrane is the surface).
    pub fn new(scene: &'a TraceScene<'a>, height: u32) -> Self {
        let mut triangles = Vec::new();
        let mut owners = Vec::new();
        for (object_index, object) in scene.objects.iter().enumerate() {
            let mesh = &object.mesh;
            for (triangle_index, triangle) in mesh.triangles.iter().enumerate() {
                triangles.push(triangle.map(|i| mesh.positions[i as usize]));
                owners.push((object_index as u32, triangle_index as u32));
            }
        }
        let bvh = Bvh::build(&triangles);
        let membrane_surface = (scene.water_model == WaterModel::Membrane)
            .then(|| MembraneSurface::new(scene.membrane));
        let camera = scene.view.camera;
        let (tw, th) = scene.textures.size();
        Tracer {
            scene,
            bvh,
            owners,
            membrane_surface,
            camera,
            forward: camera.forward(),
            pixel_angle: 2.0 * (camera.fov_y_deg.to_radians() * 0.5).tan() / height.max(1) as f32,
            texture_size: Vec2::new(tw as f32, th as f32),
            eta: scene.view.water.n_above / scene.view.water.n_below,
        }
    }

    /// What the sight ray along unit `direction` from the eye shows.
    pub fn trace(&self, direction: Vec3) -> PixelSample {
        let eye = self.camera.eye;
        // The rasteriser clips at the camera's near and far view depths; along this ray that is:
        let depth_per_t = direction.dot(self.forward).max(1e-6);
        let (t_near, t_far) = (
            self.camera.near_m / depth_per_t,
            self.camera.far_m / depth_per_t,
        );
        let mut steps = RootSteps::default();
        let water = match &self.membrane_surface {
            None => self.scene.surface.first_crossing(
                eye.as_dvec3(),
                direction.as_dvec3(),
                t_near as f64,
                t_far as f64,
                &mut steps,
            ),
            Some(membrane) => membrane.first_hit(eye, direction, t_near, t_far),
        };
        let t_object_max = water.map_or(t_far, |w| w.t as f32);
        let ray = Ray::new(eye, direction);
        let object_hit = self.bvh.closest_hit(&ray, t_near, t_object_max, |hit| {
            // Under-water points are seen only through the water (the rasteriser draws them in
            // the stencil of visible water only): a ray meeting one before the water goes on.
            !self
                .scene
                .surface
                .contains(ray.at(hit.t).as_dvec3(), -IN_WATER_SLACK_M)
        });
        let lighting = &self.scene.view.lighting;
        let mut sample = match (object_hit, water) {
            (Some(hit), _) => {
                let point = self.object_point(&hit, &ray);
                let footprint_m = hit.t * self.pixel_angle * depth_per_t;
                let cos = direction.dot(point.geometric_normal).abs();
                let albedo = self.albedo(&point, footprint_m, cos);
                let depth_m = self.camera.view_depth(point.position);
                PixelSample {
                    beauty: shading::shade_above(albedo, point.normal, lighting),
                    distance_m: (point.position - eye).length(),
                    depth_m,
                    apparent_depth_m: depth_m,
                    water_reflection: None,
                    position: point.position,
                    object: point.object + 1,
                    refracted: false,
                    surface_evaluations: 0,
                }
            }
            (None, Some(surface_hit)) => self.through_water(direction, depth_per_t, &surface_hit),
            (None, None) => PixelSample {
                beauty: shading::sky_radiance(direction, lighting),
                distance_m: f32::INFINITY,
                depth_m: SKY_DEPTH_M,
                apparent_depth_m: SKY_DEPTH_M,
                water_reflection: None,
                position: Vec3::NAN,
                object: 0,
                refracted: false,
                surface_evaluations: 0,
            },
        };
        sample.surface_evaluations = steps.evaluations;
        sample
    }

    /// The water seen at `surface_hit`: sky reflection weighted by F over the refracted ray's colour.
    fn through_water(&self, direction: Vec3, depth_per_t: f32, at: &SurfaceHit) -> PixelSample {
        let view = &self.scene.view;
        let (lighting, water) = (&view.lighting, &view.water);
        let sight_point = at.position.as_vec3();
        let normal = at.normal.as_vec3();
        let (sky, reflectance) = shading::water_reflection(direction, normal, lighting, water);
        let refracted = crate::refraction::rays::refract(direction, normal, self.eta).direction;
        let ray = Ray::new(sight_point, refracted);
        let hit = self
            .bvh
            .closest_hit(&ray, REFRACTED_T_MIN_M, f32::INFINITY, |_| true);
        let surface_distance_m = (sight_point - self.camera.eye).length();
        let seen = hit.and_then(|hit| {
            let point = self.object_point(&hit, &ray);
            // A refracted ray that leaves the water (through the extent's side, or up through a
            // crest) meets nothing the rasteriser would draw through the water.
            self.scene
                .surface
                .contains(point.position.as_dvec3(), IN_WATER_SLACK_M)
                .then_some((hit, point))
        });
        let (under, position, object, apparent_depth_m) = match seen {
            Some((hit, point)) => {
                let water_path_m = (point.position - sight_point).length();
                let apparent_m = surface_distance_m + self.eta * water_path_m;
                let footprint_m = apparent_m * self.pixel_angle * depth_per_t;
                let cos = refracted.dot(point.geometric_normal).abs();
                debug_assert!((water_path_m - hit.t).abs() <= 1e-3 * hit.t.max(1.0));
                let albedo = self.albedo(&point, footprint_m, cos);
                (
                    shading::shade_under(
                        albedo,
                        point.normal,
                        point.position,
                        water_path_m,
                        lighting,
                        water,
                    ),
                    point.position,
                    point.object + 1,
                    apparent_m * depth_per_t,
                )
            }
            None => (water.scatter_color_linear, Vec3::NAN, 0, SKY_DEPTH_M),
        };
        PixelSample {
            beauty: sky + (1.0 - reflectance) * under,
            distance_m: surface_distance_m,
            depth_m: self.camera.view_depth(sight_point),
            apparent_depth_m,
            water_reflection: Some(Vec4::from((sky, reflectance))),
            position,
            object,
            refracted: true,
            surface_evaluations: 0,
        }
    }

    fn object_point(&self, hit: &Hit, ray: &Ray) -> ObjectPoint {
        let (object, triangle) = self.owners[hit.triangle as usize];
        let mesh = &self.scene.objects[object as usize].mesh;
        let [a, b, c] = mesh.triangles[triangle as usize].map(|i| i as usize);
        let (u, v) = (hit.u, hit.v);
        let w = 1.0 - u - v;
        let normal =
            (mesh.normals[a] * w + mesh.normals[b] * u + mesh.normals[c] * v).normalize_or(Vec3::Y);
        let uv = mesh.uvs[a] * w + mesh.uvs[b] * u + mesh.uvs[c] * v;
        let (pa, pb, pc) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
        let cross = (pb - pa).cross(pc - pa);
        let area2 = cross.length();
        let size = self.texture_size;
        let (ta, tb, tc) = (mesh.uvs[a] * size, mesh.uvs[b] * size, mesh.uvs[c] * size);
        let uv_area2 = (tb - ta).perp_dot(tc - ta).abs();
        ObjectPoint {
            object,
            position: ray.at(hit.t),
            normal,
            uv,
            geometric_normal: if area2 > 0.0 { cross / area2 } else { normal },
            texels_per_m: if area2 > 0.0 {
                (uv_area2 / area2).sqrt()
            } else {
                0.0
            },
        }
    }

    /// Linear albedo: tint times the texture at the level the footprint asks for.
    fn albedo(&self, point: &ObjectPoint, footprint_m: f32, cos: f32) -> Vec3 {
        let material = &self.scene.materials[point.object as usize];
        let texels = footprint_m * point.texels_per_m / cos.max(1e-3);
        let lod = texels.max(1e-30).log2();
        material.tint_linear * self.scene.textures.sample(material.texture, point.uv, lod)
    }
}

/// A traced frame: the GPU's layers and what it cost.
pub struct TracedFrame {
    /// `object` is filled as the GPU fills it: 0 = no object (sky, water with nothing behind
    /// it); k + 1 = object k of [`TraceScene::objects`].
    pub rendered: RenderedFrame,
    pub stats: TraceStats,
}

/// The anti-aliased part of a pixel traced with several rays ([`TraceScene::grid`] above 1).
struct Filtered {
    /// The mean of the rays' beauty: a box filter over the pixel.
    beauty: Vec3,
    /// The mean of the rays' (F sky + glint, F), 0 for rays off the water.
    water_reflection: Vec4,
    coverage: [crate::draw::CoverageRank; crate::draw::COVERAGE_RANKS],
    refracted: u64,
    surface_evaluations: u64,
}

/// Seeds the jitter of pixel `(x, y)`'s rays: the same rays in every run, on every thread.
const JITTER_SEED: u64 = 0x05ee_d0fa_11a5;

/// The `grid` x `grid` stratified rays of pixel `(x, y)`: one in each cell of a `grid` x `grid`
/// split of the pixel, at a place in its cell drawn from a generator seeded by the pixel
/// ([`crate::seeded::SplitMix64`]): deterministic, and without the regular grid's aliasing on
/// regular patterns (tiles).
fn filtered_pixel(
    tracer: &Tracer,
    rays: &crate::camera::PixelRays,
    (x, y): (u32, u32),
    width: u32,
    grid: u32,
) -> Filtered {
    let mut jitter = crate::seeded::SplitMix64::new(
        JITTER_SEED ^ (u64::from(y) * u64::from(width) + u64::from(x)),
    );
    let mut beauty = Vec3::ZERO;
    let mut water_reflection = Vec4::ZERO;
    let mut samples = Vec::with_capacity((grid * grid) as usize);
    let (mut refracted, mut surface_evaluations) = (0, 0);
    for j in 0..grid {
        for i in 0..grid {
            let (u, v) = (jitter.unit_f32(), jitter.unit_f32());
            let at = Vec2::new(
                x as f32 + (i as f32 + u) / grid as f32,
                y as f32 + (j as f32 + v) / grid as f32,
            );
            let sample = tracer.trace(rays.direction(at));
            beauty += sample.beauty;
            water_reflection += sample.water_reflection.unwrap_or(Vec4::ZERO);
            refracted += u64::from(sample.refracted);
            surface_evaluations += u64::from(sample.surface_evaluations);
            samples.push((
                crate::draw::CoverageSample {
                    object: sample.object,
                    water_reflectance: sample.water_reflection.map(|reflection| reflection.w),
                },
                1.0 / (grid * grid) as f32,
            ));
        }
    }
    let scale = 1.0 / (grid * grid) as f32;
    Filtered {
        beauty: beauty * scale,
        water_reflection: water_reflection * scale,
        coverage: crate::draw::coverage_ranks(&samples),
        refracted,
        surface_evaluations,
    }
}

/// Traces every pixel of a `width` x `height` frame: the ray through the pixel centre (+0.5) for
/// every layer, and where [`TraceScene::grid`] is above 1, `grid * grid` stratified rays more
/// ([`filtered_pixel`]) whose mean is the beauty (and the water's reflection) and whose objects
/// are the coverage: `Z`, `P`, IDs and the water matte stay the centre's, as the rasteriser's
/// multisampled frames keep them.
pub fn trace_frame(scene: &TraceScene, width: u32, height: u32) -> TracedFrame {
    let started = Instant::now();
    let tracer = Tracer::new(scene, height);
    let build_secs = started.elapsed().as_secs_f64();
    let rays = scene.view.camera.pixel_rays(width, height);
    let pixels = (width * height) as usize;
    let grid = scene.grid.max(1);
    let mut samples: Vec<(PixelSample, Option<Filtered>)> = Vec::with_capacity(pixels);
    let tile = (width * ROWS_PER_TILE) as usize;
    (0..pixels)
        .into_par_iter()
        .with_min_len(tile)
        .map(|at| {
            let (x, y) = (at as u32 % width, at as u32 / width);
            let centre = tracer.trace(rays.direction(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)));
            let filtered = (grid > 1).then(|| filtered_pixel(&tracer, &rays, (x, y), width, grid));
            (centre, filtered)
        })
        .collect_into_vec(&mut samples);
    let counts = samples.iter().fold(
        (0u64, 0u64),
        |(refracted, evaluations), (sample, filtered)| {
            let (more_refracted, more_evaluations) = filtered
                .as_ref()
                .map_or((0, 0), |f| (f.refracted, f.surface_evaluations));
            (
                refracted + u64::from(sample.refracted) + more_refracted,
                evaluations + sample.surface_evaluations as u64 + more_evaluations,
            )
        },
    );
    let coverage = if grid > 1 {
        samples
            .iter()
            .map(|(_, filtered)| filtered.as_ref().map(|f| f.coverage).unwrap_or_default())
            .collect()
    } else {
        Vec::new()
    };
    let samples: Vec<PixelSample> = samples
        .into_iter()
        .map(|(mut sample, filtered)| {
            if let Some(filtered) = filtered {
                sample.beauty = filtered.beauty;
                if sample.water_reflection.is_some() {
                    sample.water_reflection = Some(filtered.water_reflection);
                }
            }
            sample
        })
        .collect();
    let seen = |sample: &PixelSample, value: Vec3| {
        if sample.object == 0 {
            [0.0; 3]
        } else {
            value.to_array()
        }
    };
    let frame = RenderedFrame {
        width,
        height,
        beauty_rgba: samples
            .iter()
            .map(|s| Vec4::from((s.beauty, 1.0)).to_array())
            .collect(),
        depth_m: samples.iter().map(|s| s.depth_m).collect(),
        apparent_depth_m: samples.iter().map(|s| s.apparent_depth_m).collect(),
        position: samples.iter().map(|s| seen(s, s.position)).collect(),
        flags: vec![0; pixels],
        object: samples.iter().map(|s| s.object).collect(),
        water_matte: samples
            .iter()
            .map(|s| f32::from(u8::from(s.water_reflection.is_some())))
            .collect(),
        water_reflection: samples
            .iter()
            .map(|s| s.water_reflection.unwrap_or(Vec4::ZERO).to_array())
            .collect(),
        // The tracer follows one frame's rays: no motion vectors (the GPU methods write them).
        motion_px: Vec::new(),
        coverage,
    };
    let stats = TraceStats {
        primary_rays: pixels as u64 * (1 + u64::from(grid > 1) * u64::from(grid * grid)),
        refracted_rays: counts.0,
        surface_evaluations: counts.1,
        triangles: tracer.bvh.triangle_count(),
        bvh_nodes: tracer.bvh.node_count(),
        build_secs,
        total_secs: started.elapsed().as_secs_f64(),
    };
    TracedFrame {
        rendered: frame,
        stats,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::{Lighting, WaterOptics};
    use crate::mesh::{Material, Mesh, Texture};
    use crate::water::{build_membrane, FnHeightField, HeightField, MembraneGrid};

    const N_WATER: f32 = 1.333;

    fn lighting() -> Lighting {
        Lighting {
            sky_zenith_linear: Vec3::new(0.2, 0.4, 0.9),
            sky_horizon_linear: Vec3::new(0.8, 0.85, 0.9),
            // Under the horizon: no sunlight anywhere, so the expected colours are ambient only.
            sun_direction: Vec3::new(0.0, -1.0, 0.0),
            sun_color_linear: Vec3::ONE,
            sun_size_deg: 0.53,
            ambient_linear: Vec3::new(0.3, 0.3, 0.3),
        }
    }

    fn water() -> WaterOptics {
        WaterOptics {
            n_above: 1.0,
            n_below: N_WATER,
            absorption_per_m: Vec3::new(0.4, 0.1, 0.05),
            scatter_color_linear: Vec3::new(0.0, 0.05, 0.08),
            mean_level_m: 0.0,
            roughness: 0.0,
        }
    }

    /// A horizontal square of side `2 half` at height `y`, normal up, one white material.
    fn floor(y: f32, half: f32) -> Object {
        let positions = vec![
            Vec3::new(-half, y, -half),
            Vec3::new(half, y, -half),
            Vec3::new(half, y, half),
            Vec3::new(-half, y, half),
        ];
        Object {
            name: "floor".into(),
            mesh: Mesh {
                normals: vec![Vec3::Y; 4],
                uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
                positions,
                triangles: vec![[0, 2, 1], [0, 3, 2]],
            },
            material: Material {
                texture: 0,
                tint_linear: Vec3::splat(0.5),
            },
        }
    }

    /// A vertical wall in the plane x = `x`, from y = -1 to 1, normal toward -x.
    fn wall(x: f32) -> Object {
        let positions = vec![
            Vec3::new(x, -1.0, -3.0),
            Vec3::new(x, -1.0, 3.0),
            Vec3::new(x, 1.0, 3.0),
            Vec3::new(x, 1.0, -3.0),
        ];
        Object {
            name: "wall".into(),
            mesh: Mesh {
                normals: vec![-Vec3::X; 4],
                uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
                positions,
                triangles: vec![[0, 1, 2], [0, 2, 3]],
            },
            material: Material {
                texture: 0,
                tint_linear: Vec3::new(0.9, 0.2, 0.1),
            },
        }
    }

    fn grid(half: f64, cells: u32) -> MembraneGrid {
        MembraneGrid {
            min_x: -half,
            min_z: -half,
            max_x: half,
            max_z: half,
            cells_x: cells,
            cells_z: cells,
        }
    }

    struct Fixture {
        objects: Vec<Object>,
        materials: Vec<DrawMaterial>,
        textures: TextureSet,
        field: FnHeightField,
        membrane: Membrane,
        camera: Camera,
    }

    impl Fixture {
        fn new(objects: Vec<Object>, field: FnHeightField, eye: Vec3) -> Self {
            let white = Texture {
                name: "white".into(),
                width: 1,
                height: 1,
                rgba8_srgb: vec![255; 4],
            };
            let membrane = build_membrane(&field, &grid(5.0, 40));
            Fixture {
                materials: crate::frame::draw_materials(objects.iter()),
                objects,
                textures: TextureSet::new(&[white]).unwrap(),
                field,
                membrane,
                camera: Camera {
                    eye,
                    target: eye + Vec3::new(1.0, -1.0, 0.0),
                    up: Vec3::Y,
                    fov_y_deg: 60.0,
                    near_m: crate::camera::NEAR_M,
                    far_m: crate::camera::FAR_M,
                },
            }
        }

        fn scene(
            &self,
            water_model: WaterModel,
            slope: f64,
            curvature: f64,
            range: (f64, f64),
        ) -> TraceScene<'_> {
            TraceScene {
                objects: self.objects.iter().collect(),
                materials: &self.materials,
                textures: &self.textures,
                surface: ExactSurface {
                    height_field: &self.field,
                    extent: self.membrane.grid,
                    height_range_m: range,
                    slope_bound: slope,
                    curvature_bound: curvature,
                    local_bounds: None,
                },
                membrane: &self.membrane,
                grid: 1,
                view: FrameView {
                    camera: self.camera,
                    previous_camera: self.camera,
                    lighting: lighting(),
                    water: water(),
                },
                water_model,
            }
        }
    }

    fn flat() -> FnHeightField {
        FnHeightField::new(|_, _| 0.0).with_gradient(|_, _| (0.0, 0.0))
    }

    /// Snell's law by hand: eye 1 m over flat water, a ray at 45 degrees meets the water at
    /// (1, 0, 0), bends to sin(t) = sin(45) / 1.333 and meets the floor 1 m down at
    /// x = 1 + tan(t). The beauty is F sky + (1 - F) (lit T + scatter (1 - T)) with Schlick's F at
    /// cos 45, T = exp(-sigma / cos t) and the floor lit by ambient light attenuated over 1 m.
    #[test]
    fn flat_water_ray_at_45_degrees_lands_where_snell_says() {
        let fixture = Fixture::new(vec![floor(-1.0, 4.0)], flat(), Vec3::new(0.0, 1.0, 0.0));
        for model in [WaterModel::Exact, WaterModel::Membrane] {
            let scene = fixture.scene(model, 0.0, 0.0, (0.0, 0.0));
            let tracer = Tracer::new(&scene, 100);
            let direction = Vec3::new(1.0, -1.0, 0.0).normalize();
            let sample = tracer.trace(direction);

            let sin_t = (0.5f32).sqrt() / N_WATER;
            let cos_t = (1.0 - sin_t * sin_t).sqrt();
            let expected_position = Vec3::new(1.0 + sin_t / cos_t, -1.0, 0.0);
            assert!(sample.refracted, "{model:?}");
            assert!(
                (sample.position - expected_position).length() < 1e-5,
                "{model:?}: {} vs {expected_position}",
                sample.position
            );
            assert!((sample.distance_m - 2f32.sqrt()).abs() < 1e-5, "{model:?}");
            assert_eq!(sample.object, 1);

            let r0 = ((1.0 - N_WATER) / (1.0 + N_WATER)).powi(2);
            let fresnel = r0 + (1.0 - r0) * (1.0 - (0.5f32).sqrt()).powi(5);
            // Reflected ray: 45 degrees up; the sky gradient there.
            let horizon_weight = (1.0 - (0.5f32).sqrt()).powi(3);
            let light = lighting();
            let sky = light.sky_zenith_linear * (1.0 - horizon_weight)
                + light.sky_horizon_linear * horizon_weight;
            let sigma = water().absorption_per_m;
            let water_path_m = 1.0 / cos_t;
            let transmittance = (-sigma * water_path_m).exp();
            let lit = 0.5 * light.ambient_linear * (-sigma * 1.0).exp();
            let under =
                lit * transmittance + water().scatter_color_linear * (Vec3::ONE - transmittance);
            let expected = fresnel * sky + (1.0 - fresnel) * under;
            assert!(
                (sample.beauty - expected).abs().max_element() < 1e-5,
                "{model:?}: {} vs {expected}",
                sample.beauty
            );
        }
    }

    #[test]
    fn an_object_crossing_the_surface_is_seen_directly_above_and_through_the_water_below() {
        let fixture = Fixture::new(
            vec![floor(-1.0, 4.0), wall(2.0)],
            flat(),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let scene = fixture.scene(WaterModel::Exact, 0.0, 0.0, (0.0, 0.0));
        let tracer = Tracer::new(&scene, 100);
        // 20 degrees down: meets the wall at y = 1 - 2 tan(20) = 0.27, above the water.
        let down = 20f32.to_radians();
        let above = tracer.trace(Vec3::new(down.cos(), -down.sin(), 0.0));
        assert!(!above.refracted);
        assert_eq!(above.object, 2);
        assert!((above.position - Vec3::new(2.0, 1.0 - 2.0 * down.tan(), 0.0)).length() < 1e-5);
        // Lambert of a wall facing -x with the sun under the horizon: ambient only.
        let expected = Vec3::new(0.9, 0.2, 0.1) * lighting().ambient_linear;
        assert!((above.beauty - expected).abs().max_element() < 1e-6);
        // 60 degrees down: meets the water at x = 1 / tan(60) = 0.577, bends, and meets the
        // wall under water (at x = 2, where the refracted ray has dropped 2 - 0.577 = 1.42 m times
        // cot of its angle: it reaches the floor first only if that drop exceeds 1 m).
        let steep = 60f32.to_radians();
        let seen = tracer.trace(Vec3::new(steep.cos(), -steep.sin(), 0.0));
        assert!(seen.refracted);
        let sin_t = steep.cos() / N_WATER; // incidence angle is 30 degrees from the normal
        let tan_t = sin_t / (1.0 - sin_t * sin_t).sqrt();
        let s_x = 1.0 / steep.tan();
        let depth_at_wall = (2.0 - s_x) / tan_t;
        let expected = if depth_at_wall < 1.0 {
            (2, Vec3::new(2.0, -depth_at_wall, 0.0))
        } else {
            (1, Vec3::new(s_x + tan_t, -1.0, 0.0))
        };
        assert_eq!(seen.object, expected.0);
        assert!(
            (seen.position - expected.1).length() < 1e-5,
            "{} vs {}",
            seen.position,
            expected.1
        );
        assert!(seen.position.y < 0.0);
    }

    #[test]
    fn outside_the_membrane_there_is_no_water_and_nothing_behind_shows_deep_water() {
        // A floor far larger than the 10 m membrane: past the membrane's edge, the floor under
        // the water level is seen directly (no water there), as the rasteriser draws it.
        let fixture = Fixture::new(vec![floor(-1.0, 40.0)], flat(), Vec3::new(0.0, 1.0, 0.0));
        let scene = fixture.scene(WaterModel::Exact, 0.0, 0.0, (0.0, 0.0));
        let tracer = Tracer::new(&scene, 100);
        // 5 degrees down: meets the water plane at x = 11.4 (outside), the floor at 22.9.
        let shallow = 5f32.to_radians();
        let sample = tracer.trace(Vec3::new(shallow.cos(), -shallow.sin(), 0.0));
        assert!(!sample.refracted);
        assert_eq!(sample.object, 1);
        assert!((sample.position.x - 2.0 / shallow.tan()).abs() < 1e-3);
        // Straight down onto water with no floor under it: the deep-water colour behind F.
        let empty = Fixture::new(vec![floor(-1.0, 0.5)], flat(), Vec3::new(3.0, 1.0, 0.0));
        let scene = empty.scene(WaterModel::Exact, 0.0, 0.0, (0.0, 0.0));
        let tracer = Tracer::new(&scene, 100);
        let sample = tracer.trace(Vec3::NEG_Y);
        assert!(sample.refracted);
        assert_eq!(sample.object, 0);
        assert!(sample.position.is_nan());
        assert!((sample.distance_m - 1.0).abs() < 1e-6);
        let r0 = ((1.0 - N_WATER) / (1.0 + N_WATER)).powi(2);
        let expected =
            r0 * lighting().sky_zenith_linear + (1.0 - r0) * water().scatter_color_linear;
        assert!((sample.beauty - expected).abs().max_element() < 1e-6);
        // Looking up: sky, at infinity, no position.
        let sky = tracer.trace(Vec3::Y);
        assert_eq!(sky.distance_m, f32::INFINITY);
        assert!(sky.position.is_nan());
        assert_eq!(sky.beauty, lighting().sky_zenith_linear);
    }

    #[test]
    fn on_waves_the_exact_surface_and_the_fine_membrane_see_nearly_the_same_floor() {
        let field =
            FnHeightField::new(|x, z| 0.03 * (2.0 * x + 0.5 * z).cos()).with_gradient(|x, z| {
                let s = -0.03 * (2.0 * x + 0.5 * z).sin();
                (2.0 * s, 0.5 * s)
            });
        let k = (4.0f64 + 0.25).sqrt();
        let fixture = Fixture::new(vec![floor(-1.0, 4.0)], field, Vec3::new(-2.0, 1.5, 0.3));
        let exact_scene = fixture.scene(WaterModel::Exact, 0.03 * k, 0.03 * k * k, (-0.03, 0.03));
        let membrane_scene =
            fixture.scene(WaterModel::Membrane, 0.03 * k, 0.03 * k * k, (-0.03, 0.03));
        let exact = TraceScene { ..exact_scene };
        let exact_tracer = Tracer::new(&exact, 100);
        let membrane_tracer = Tracer::new(&membrane_scene, 100);
        let mut largest = 0.0f32;
        for i in 0..200 {
            let a = i as f32 * 0.05;
            let direction = Vec3::new(1.0, -0.6 - 0.3 * a.sin(), 0.4 * a.cos()).normalize();
            let e = exact_tracer.trace(direction);
            let m = membrane_tracer.trace(direction);
            assert!(e.refracted && m.refracted);
            // On the exact surface itself.
            let s = fixture.camera.eye + direction * e.distance_m;
            let h = fixture.field.height(s.x as f64, s.z as f64) as f32;
            assert!(
                (s.y - h).abs() < 1e-4,
                "surface point off the surface: {s} vs {h}"
            );
            largest = largest.max((e.position - m.position).length());
        }
        // 25 cm facets on a 3 cm, 3 m wave: normals interpolated between exact vertex normals
        // differ from the exact normal by ~1e-3 rad, which moves the floor point 1 m down by
        // about a millimetre; the faceted surface's height error (~0.3 mm) adds less.
        assert!(
            largest < 5e-3,
            "exact and membrane floors differ by {largest} m"
        );
        assert!(largest > 0.0, "the two models cannot be identical on waves");
    }
}
