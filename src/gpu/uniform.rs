//! The frame constants every pass reads: [`FrameUniform`], laid out as `shaders/common.inc.wgsl`
//! declares `Frame`.

use glam::{Mat4, Vec3};

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
    /// The constants of a frame of `width` x `height` drawn from its row `first_row` down (0 for
    /// a whole frame; a strip's first row otherwise, which the shaders add to a fragment's y).
    pub(super) fn new(view: &FrameView, width: u32, height: u32, first_row: u32) -> FrameUniform {
        let clip_from_world: Mat4 = view.camera.clip_from_world(width, height);
        let lighting = &view.lighting;
        let water = &view.water;
        let sun_in_water = shading::sun_direction_in_water(lighting, water);
        FrameUniform {
            clip_from_world: clip_from_world.to_cols_array_2d(),
            world_from_clip: clip_from_world.inverse().to_cols_array_2d(),
            previous_clip_from_world: view
                .previous_camera
                .clip_from_world(width, height)
                .to_cols_array_2d(),
            eye: vec4(view.camera.eye, 1.0),
            viewport: [width as f32, height as f32, 0.0, first_row as f32],
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
            water: [water.n_above, water.n_below, water.mean_level_m, 0.0],
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
