//! The frame constants every pass reads: [`FrameUniform`], laid out as `shaders/common.inc.wgsl`
//! declares `Frame`.

use glam::{Mat4, Vec3};

use super::resolve::{points_for, SUPERSAMPLE};
use super::shading;
use crate::draw::FrameView;

/// Frame constants as `shaders/common.inc.wgsl` declares `Frame`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct FrameUniform {
    clip_from_world: [[f32; 4]; 4],
    world_from_clip: [[f32; 4]; 4],
    previous_clip_from_world: [[f32; 4]; 4],
    eye: [f32; 4],
    viewport: [f32; 4],
    sky_zenith: [f32; 4],
    sky_horizon: [f32; 4],
    sun_direction: [f32; 4],
    sun_color: [f32; 4],
    ambient: [f32; 4],
    absorption_per_m: [f32; 4],
    scatter_color: [f32; 4],
    sun_in_water: [f32; 4],
    water: [f32; 4],
    view_forward: [f32; 4],
}

fn vec4(v: Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

impl FrameUniform {
    /// The constants of a frame of `size` (width, height) drawn from its row `first_row` down (0
    /// for a whole frame; a strip's first row otherwise, which the shaders add to a fragment's y).
    /// `supersampled`: the frame's points are drawn instead (`super::resolve`), a frame of
    /// `2 width + 1` by `2 height + 1` whose pixel centres are the frame's pixel corners, edge
    /// midpoints and centres: the projection widened by a quarter pixel on each side (clip x
    /// and y scaled by `2 width / (2 width + 1)` and `2 height / (2 height + 1)`), from point row
    /// `2 first_row`.
    pub(super) fn new(
        view: &FrameView,
        size: (u32, u32),
        first_row: u32,
        supersampled: bool,
    ) -> FrameUniform {
        let (frame_width, frame_height) = size;
        let (width, height, first_row, widening) = if supersampled {
            let (w, h) = (points_for(frame_width), points_for(frame_height));
            let scale = Vec3::new((w - 1) as f32 / w as f32, (h - 1) as f32 / h as f32, 1.0);
            (w, h, SUPERSAMPLE * first_row, Mat4::from_scale(scale))
        } else {
            (frame_width, frame_height, first_row, Mat4::IDENTITY)
        };
        // The camera's projection is the frame's (its aspect ratio); the widening, if any, after.
        let clip_from_world: Mat4 =
            widening * view.camera.clip_from_world(frame_width, frame_height);
        let lighting = &view.lighting;
        let water = &view.water;
        let sun_in_water = shading::sun_direction_in_water(lighting, water);
        FrameUniform {
            clip_from_world: clip_from_world.to_cols_array_2d(),
            world_from_clip: clip_from_world.inverse().to_cols_array_2d(),
            previous_clip_from_world: (widening
                * view
                    .previous_camera
                    .clip_from_world(frame_width, frame_height))
            .to_cols_array_2d(),
            eye: vec4(view.camera.eye, 1.0),
            viewport: [
                width as f32,
                height as f32,
                if supersampled {
                    SUPERSAMPLE as f32
                } else {
                    1.0
                },
                first_row as f32,
            ],
            sky_zenith: vec4(lighting.sky_zenith_linear, 0.0),
            sky_horizon: vec4(lighting.sky_horizon_linear, 0.0),
            sun_direction: vec4(
                lighting.sun_direction,
                shading::sun_disk_cos_radius(lighting),
            ),
            sun_color: vec4(lighting.sun_color_linear, shading::sun_disk_gain(lighting)),
            ambient: vec4(lighting.ambient_linear, 0.0),
            absorption_per_m: vec4(water.absorption_per_m, 0.0),
            scatter_color: vec4(water.scatter_color_linear, 0.0),
            sun_in_water: match sun_in_water {
                Some(direction) => vec4(direction, 1.0),
                None => [0.0, 1.0, 0.0, 0.0],
            },
            water: [
                water.n_above,
                water.n_below,
                water.mean_level_m,
                shading::glint_roughness2(lighting, water),
            ],
            view_forward: vec4(view.camera.forward(), 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_uniform_matches_the_wgsl_struct_size() {
        // 3 mat4x4 (clip_from_world, world_from_clip, previous_clip_from_world) + 12 vec4 in
        // shaders/common.inc.wgsl's `Frame`.
        assert_eq!(std::mem::size_of::<FrameUniform>(), 3 * 64 + 12 * 16);
    }
}
