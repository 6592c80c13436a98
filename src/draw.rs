//! What the GPU stage draws for one frame: vertex lists already split into geometry above the
//! water (true positions) and under it (virtual positions with true attributes), the membrane,
//! and the frame's camera, lights and water optics. Built on the CPU by [`crate::frame`] from the
//! refraction stage's output; consumed only by [`crate::gpu`]. Plain data: no wgpu types here.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::camera::Camera;

/// Bits of the per-triangle flag mask (the EXR `flags.*` channels are these bits, one channel each).
pub mod flag_bits {
    /// A vertex of the triangle is seen through more than one facet (zone of convergence).
    pub const CONVERGENCE: u32 = 1;
    /// Some under-water vertices of the triangle have an image and some have none.
    pub const BOUNDARY: u32 = 2;
    /// A vertex's chosen image jumped since the previous frame.
    pub const POPPING: u32 = 4;
    /// A vertex's image comes from an extrapolated (back-facing or TIR) refraction ray.
    pub const EXTRAPOLATED: u32 = 8;
}

/// A vertex drawn at its true position (geometry on the eye's side of the water).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TrueVertex {
    pub position: [f32; 3],
    /// Where this vertex was at frame t-1 (world space), for the motion vectors.
    pub previous_position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    /// Index into [`FrameDraw::materials`].
    pub material: u32,
}

/// A vertex of under-water geometry: rasterised at `virtual_position`, shaded with the true
/// attributes. Under-water triangles are drawn unindexed (three vertices each) so every vertex can
/// carry its triangle's flags.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct VirtualVertex {
    pub virtual_position: [f32; 3],
    /// Where this vertex was drawn at frame t-1 (its virtual position then, world space), for
    /// the motion vectors.
    pub previous_position: [f32; 3],
    pub true_position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub material: u32,
    /// True path length in water `|V - S|` in metres (Beer-Lambert along the view path).
    pub water_path_m: f32,
    /// The triangle's [`flag_bits`].
    pub flags: u32,
}

/// A membrane vertex: the faceted water surface with its analytic normal (pointing up, to the air).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MembraneVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// Material as the GPU sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawMaterial {
    /// Index into the renderer's uploaded texture list.
    pub texture: u32,
    pub tint_linear: Vec3,
}

/// Sky, sun and ambient light (linear RGB radiance units, arbitrary but consistent scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    pub sky_zenith_linear: Vec3,
    pub sky_horizon_linear: Vec3,
    /// Unit vector from the scene toward the sun.
    pub sun_direction: Vec3,
    pub sun_color_linear: Vec3,
    /// Angular diameter of the sun disk seen in the sky and its reflections.
    pub sun_size_deg: f32,
    /// Ambient (sky) light on surfaces.
    pub ambient_linear: Vec3,
}

/// Optical properties of the water for shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaterOptics {
    /// Index of refraction above (the eye's side, air) and below (water).
    pub n_above: f32,
    pub n_below: f32,
    /// Beer-Lambert absorption coefficients per channel, 1/m.
    pub absorption_per_m: Vec3,
    /// Colour light takes on when scattered back by deep water (what a fully absorbed path shows).
    pub scatter_color_linear: Vec3,
    /// Height of the mean (flat) water plane, metres; sunlight is refracted through it.
    pub mean_level_m: f32,
    /// Rms slope of the waves finer than the membrane (Beckmann's roughness): how far the sun's
    /// glint spreads ([`crate::gpu::shading::sun_glint`]).
    pub roughness: f32,
}

/// Everything the GPU needs to draw one frame.
#[derive(Clone, Debug, Default)]
pub struct FrameDraw {
    pub above_vertices: Vec<TrueVertex>,
    pub above_indices: Vec<u32>,
    /// Unindexed triangle list (length a multiple of 3).
    pub under_vertices: Vec<VirtualVertex>,
    pub membrane_vertices: Vec<MembraneVertex>,
    pub membrane_indices: Vec<u32>,
    pub materials: Vec<DrawMaterial>,
}

/// The per-frame constants of a render: camera, light, water.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameView {
    pub camera: Camera,
    /// Frame t-1's camera, through which the motion vectors project the vertices' previous
    /// positions (the frame's own camera where there is no t-1).
    pub previous_camera: Camera,
    pub lighting: Lighting,
    pub water: WaterOptics,
}

/// Depth written where a pixel sees nothing (sky; the apparent depth of water with nothing behind
/// it), metres: Blender's background depth, finite so that compositing arithmetic never makes NaN.
pub const SKY_DEPTH_M: f32 = 1e10;

/// What the GPU stage returns for one frame, read back to the CPU, row-major, top row first.
/// No layer holds NaN or an infinity: where nothing is seen, each holds the value the EXR channel
/// map states (README, "The EXR channel map").
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderedFrame {
    pub width: u32,
    pub height: u32,
    /// Linear HDR beauty, alpha 1 where anything (sky included) was drawn.
    pub beauty_rgba: Vec<[f32; 4]>,
    /// Depth along the view axis (camera-space distance in front of the eye, as Blender's `Z`) of
    /// the first surface the pixel's sight ray meets (the water surface for pixels seen through
    /// water), metres; [`SKY_DEPTH_M`] for sky.
    pub depth_m: Vec<f32>,
    /// Depth along the view axis of what the pixel shows: for pixels seen through water the
    /// virtual (apparent) image of the under-water point, [`SKY_DEPTH_M`] for water with nothing
    /// behind it; elsewhere equal to `depth_m`. Empty when read from an EXR written before this
    /// layer existed.
    pub apparent_depth_m: Vec<f32>,
    /// True world position of what the pixel shows (for pixels seen through water: the true,
    /// under-water point, not its virtual image); 0 for sky and for water with nothing behind it
    /// (`object` tells those apart from a point at the origin).
    pub position: Vec<[f32; 3]>,
    /// [`flag_bits`] of the virtual triangle seen in each pixel, 0 elsewhere.
    pub flags: Vec<u32>,
    /// Which object each pixel sees (directly or through the water): its scene object id
    /// (1-based: static objects in scene order, each part of a pool on its own, then one id per
    /// character, see [`crate::frame::RenderJob::object_names`]), [`NO_OBJECT`] for sky and for
    /// water with nothing behind it. The GPU stage and the tracer fill it with the frame's object
    /// (material) index + 1; [`crate::frame::RenderJob::render_refracted`] maps that to the scene
    /// id. Empty when read from an EXR written before this layer existed.
    pub object: Vec<u32>,
    /// 1 where the first surface the pixel's ray meets is the water, 0 elsewhere. Empty when read
    /// from an EXR written before this layer existed.
    pub water_matte: Vec<f32>,
    /// Where `water_matte` is 1: the sky reflected by the water, weighted by Schlick's reflectance
    /// F, in rgb, and F in a; 0 elsewhere. The beauty there is this reflection plus (1 - F) times
    /// the refracted image. Read from an EXR, F is 1 where nothing is behind the water (the file
    /// keeps F as the Cryptomatte coverage, which is 1 there); empty when read from an EXR
    /// written before this layer existed.
    pub water_reflection: Vec<[f32; 4]>,
    /// Screen motion in pixels from frame t-1 to t of what the pixel shows (x right, y down: the
    /// pixel now minus where the same point was seen at t-1, through water too); 0 where nothing
    /// is seen. Empty when not computed (the ray-traced methods) or read from an EXR without it.
    pub motion_px: Vec<[f32; 2]>,
    /// Per pixel, what shares it, counted over its samples ([`coverage_ranks`]): the Cryptomatte's
    /// ranks. Empty for frames of one sample a pixel (and frames read from an EXR), whose ranks
    /// follow from `object` and `water_reflection` alone.
    pub coverage: Vec<[CoverageRank; COVERAGE_RANKS]>,
}

/// Ranks of [`RenderedFrame::coverage`] kept per pixel.
pub const COVERAGE_RANKS: usize = 4;
/// [`CoverageRank::key`] of the water surface.
pub const COVERAGE_WATER: u32 = u32::MAX;

/// One rank of a pixel's coverage: who holds a share of it (an object as
/// [`RenderedFrame::object`] numbers it, or [`COVERAGE_WATER`]; [`NO_OBJECT`] for an empty rank)
/// and the share (0 to 1).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CoverageRank {
    pub key: u32,
    pub coverage: f32,
}

/// What one sample of a pixel shows, for its coverage: the object seen (directly or through the
/// water; [`NO_OBJECT`] for none) and, where the first surface is the water, Schlick's F there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverageSample {
    pub object: u32,
    pub water_reflectance: Option<f32>,
}

/// The ranks of a pixel from its samples and their weights (which sum to 1), as the Cryptomatte
/// counts them: each sample shares its weight between the water (its F, or all of it where
/// nothing is behind the water) and the object seen (the rest), sky holding nothing; ranked by
/// share, largest first (equal shares by key), at most [`COVERAGE_RANKS`] kept. One sample of
/// weight 1 gives what a frame of one sample a pixel writes
/// (`crate::output::exr::cryptomatte::pixel_ranks`).
pub fn coverage_ranks(samples: &[(CoverageSample, f32)]) -> [CoverageRank; COVERAGE_RANKS] {
    // At most two keys a sample.
    let mut shares: Vec<CoverageRank> = Vec::with_capacity(2 * samples.len());
    let mut add = |key: u32, share: f32| {
        if key == NO_OBJECT || share <= 0.0 {
            return;
        }
        match shares.iter_mut().find(|rank| rank.key == key) {
            Some(rank) => rank.coverage += share,
            None => shares.push(CoverageRank {
                key,
                coverage: share,
            }),
        }
    };
    for &(sample, weight) in samples {
        match sample.water_reflectance {
            Some(reflectance) if sample.object != NO_OBJECT => {
                add(COVERAGE_WATER, reflectance * weight);
                add(sample.object, (1.0 - reflectance) * weight);
            }
            Some(_) => add(COVERAGE_WATER, weight),
            None => add(sample.object, weight),
        }
    }
    shares.sort_by(|a, b| b.coverage.total_cmp(&a.coverage).then(a.key.cmp(&b.key)));
    let mut ranks = [CoverageRank::default(); COVERAGE_RANKS];
    for (rank, share) in ranks.iter_mut().zip(shares) {
        *rank = share;
    }
    ranks
}

impl RenderedFrame {
    /// What [`Self::layer_bytes`] counts a pixel with every layer: beauty 16, `Z` 4, apparent
    /// depth 4, position 12, flags 4, object 4, water matte 4, sky reflection 16, motion 8,
    /// coverage 32 (multisampled frames).
    pub const LAYER_BYTES_PER_PIXEL: usize = 104;

    /// Pixels of the frame (`width * height`).
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Bytes its layers hold ([`Self::LAYER_BYTES_PER_PIXEL`] a pixel with every layer): what the
    /// frame weighs in the queue to the sequence writer, which is bounded in bytes.
    pub fn layer_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.beauty_rgba.as_slice())
            + size_of_val(self.depth_m.as_slice())
            + size_of_val(self.apparent_depth_m.as_slice())
            + size_of_val(self.position.as_slice())
            + size_of_val(self.flags.as_slice())
            + size_of_val(self.object.as_slice())
            + size_of_val(self.water_matte.as_slice())
            + size_of_val(self.water_reflection.as_slice())
            + size_of_val(self.motion_px.as_slice())
            + size_of_val(self.coverage.as_slice())
    }

    /// The frame made of `strips` (bands of rows of one width, top first), one under the other.
    pub fn stacked(strips: Vec<RenderedFrame>) -> RenderedFrame {
        let mut strips = strips.into_iter();
        let Some(mut frame) = strips.next() else {
            return RenderedFrame::default();
        };
        for strip in strips {
            frame.append(strip);
        }
        frame
    }

    /// Puts `strip` (the next band of rows, of this frame's width) under this frame's rows.
    pub fn append(&mut self, strip: RenderedFrame) {
        debug_assert_eq!(
            strip.width, self.width,
            "strips of one frame have one width"
        );
        self.height += strip.height;
        self.beauty_rgba.extend(strip.beauty_rgba);
        self.depth_m.extend(strip.depth_m);
        self.apparent_depth_m.extend(strip.apparent_depth_m);
        self.motion_px.extend(strip.motion_px);
        self.position.extend(strip.position);
        self.flags.extend(strip.flags);
        self.object.extend(strip.object);
        self.water_matte.extend(strip.water_matte);
        self.water_reflection.extend(strip.water_reflection);
        self.coverage.extend(strip.coverage);
    }

    /// Adds `strip`, the next band of rows of a frame `height` rows high, to `whole`, the rows
    /// gathered so far (`None` before the first strip): the first strip becomes the frame, with
    /// room reserved for every row, and each later one is appended and dropped, so the whole
    /// frame is held once (plus one strip), never twice.
    pub fn gather(whole: &mut Option<RenderedFrame>, strip: RenderedFrame, height: u32) {
        match whole {
            Some(frame) => frame.append(strip),
            None => {
                let mut frame = strip;
                frame.reserve_rows(height.saturating_sub(frame.height));
                *whole = Some(frame);
            }
        }
    }

    /// Room for `rows` more rows in every layer, so that appending them allocates nothing.
    fn reserve_rows(&mut self, rows: u32) {
        if rows == 0 {
            return;
        }
        let pixels = self.width as usize * rows as usize;
        self.beauty_rgba.reserve_exact(pixels);
        self.depth_m.reserve_exact(pixels);
        self.apparent_depth_m.reserve_exact(pixels);
        self.motion_px.reserve_exact(pixels);
        self.position.reserve_exact(pixels);
        self.flags.reserve_exact(pixels);
        self.object.reserve_exact(pixels);
        self.water_matte.reserve_exact(pixels);
        self.water_reflection.reserve_exact(pixels);
        if !self.coverage.is_empty() {
            self.coverage.reserve_exact(pixels);
        }
    }
}

/// [`RenderedFrame::object`] where no object is seen.
pub const NO_OBJECT: u32 = 0;

#[cfg(test)]
mod coverage_tests {
    use super::*;

    fn sample(object: u32, water_reflectance: Option<f32>) -> CoverageSample {
        CoverageSample {
            object,
            water_reflectance,
        }
    }

    #[test]
    fn ranks_count_each_samples_weight_and_sort_by_share() {
        // Half the pixel sees object 3 directly, a quarter the water (F 0.2) over object 5, a
        // quarter the sky.
        let ranks = coverage_ranks(&[
            (sample(3, None), 0.5),
            (sample(5, Some(0.2)), 0.25),
            (sample(NO_OBJECT, None), 0.25),
        ]);
        let expected = [
            (3, 0.5),
            (5, 0.8 * 0.25),
            (COVERAGE_WATER, 0.2 * 0.25),
            (NO_OBJECT, 0.0),
        ];
        for (rank, (key, share)) in ranks.iter().zip(expected) {
            assert_eq!(rank.key, key, "{ranks:?}");
            assert!((rank.coverage - share).abs() < 1e-6, "{ranks:?}");
        }
        // Water with nothing behind it is all water; equal shares rank by key.
        let ranks = coverage_ranks(&[(sample(NO_OBJECT, Some(0.1)), 0.5), (sample(2, None), 0.5)]);
        assert_eq!(
            ranks[..2],
            [
                CoverageRank {
                    key: 2,
                    coverage: 0.5
                },
                CoverageRank {
                    key: COVERAGE_WATER,
                    coverage: 0.5
                }
            ]
        );
    }
}
