//! Pulled geometry (issue 19): the three triangle draws (above water, membrane, under water) read
//! their vertices from storage buffers, so that the vertex stage can place each vertex on the
//! whole frame's subpixel grid and clip its triangle itself (the GPU clips nothing), and the fragment
//! stage can interpolate from the whole frame's pixel centre (`shaders/common.inc.wgsl`). That
//! makes a strip's pixels the whole frame's. This file holds their bind group (group 1).

use super::buffers::GrowingBuffer;
use crate::draw::{MembraneVertex, TrueVertex, VirtualVertex};

/// Vertex invocations drawn for each triangle: its part inside the clip volume (near plane and
/// the frame's four sides, clipped in the vertex stage) is a polygon of up to 8 corners, a fan of
/// up to 6 triangles (`CORNERS_PER_TRIANGLE` in `shaders/common.inc.wgsl`).
pub(super) const CORNERS_PER_TRIANGLE: u32 = 18;

// The shaders read the vertices as words at these strides (TRUE_VERTEX_WORDS, ...).
const _: () = assert!(std::mem::size_of::<TrueVertex>() == 12 * 4);
const _: () = assert!(std::mem::size_of::<VirtualVertex>() == 17 * 4);
const _: () = assert!(std::mem::size_of::<MembraneVertex>() == 6 * 4);

/// Group 1 of the triangle draws: binding 1, the vertices; binding 2, three vertex indices a
/// triangle (binding 0 is pass d's reflection target, in the same group of the same shaders).
pub(super) fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let storage = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("pulled geometry"),
        entries: &[storage(1), storage(2)],
    })
}

/// The bind group of one draw's `vertices` and `triangles`; `None` while either has no buffer.
pub(super) fn bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    vertices: &GrowingBuffer,
    triangles: &GrowingBuffer,
) -> Option<wgpu::BindGroup> {
    let (vertices, triangles) = (vertices.buffer.as_ref()?, triangles.buffer.as_ref()?);
    Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 1,
                resource: vertices.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: triangles.as_entire_binding(),
            },
        ],
    }))
}

/// The frame's three bind groups, made again with every upload (a buffer may have grown).
#[derive(Default)]
pub(super) struct PulledBindGroups {
    pub(super) above: Option<wgpu::BindGroup>,
    pub(super) membrane: Option<wgpu::BindGroup>,
    pub(super) under: Option<wgpu::BindGroup>,
}
