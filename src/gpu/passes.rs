//! The passes of a frame (or a strip) encoded: the frame's uploads, the main render pass (draws
//! 1 to 5) and pass d.

use super::buffers::GrowingBuffer;
use super::pipelines::MEMBRANE_STENCIL;
use super::readback::FrameTargets;
use super::strips::set_strip_viewport;
use super::Renderer;
use crate::draw::FrameDraw;

impl Renderer {
    /// Uploads a frame's materials and vertex and index lists (once for all its strips).
    pub(super) fn upload_frame(&mut self, draw: &FrameDraw) {
        let device = &self.context.device;
        let queue = &self.context.queue;
        let materials: Vec<[u32; 4]> = draw
            .materials
            .iter()
            .map(|material| {
                let tint = material.tint_linear.to_array().map(f32::to_bits);
                [tint[0], tint[1], tint[2], material.texture]
            })
            .collect();
        if !materials.is_empty() {
            queue.write_buffer(&self.material_uniform, 0, bytemuck::cast_slice(&materials));
        }
        self.above_vertices
            .upload(device, queue, bytemuck::cast_slice(&draw.above_vertices));
        self.above_indices
            .upload(device, queue, bytemuck::cast_slice(&draw.above_indices));
        self.under_vertices
            .upload(device, queue, bytemuck::cast_slice(&draw.under_vertices));
        if self.under_index_count < draw.under_vertices.len() {
            // Sequential indices, written only when the triangle list outgrows them.
            let count = draw.under_vertices.len().next_power_of_two();
            let indices: Vec<u32> = (0..count as u32).collect();
            self.under_indices
                .upload(device, queue, bytemuck::cast_slice(&indices));
            self.under_index_count = count;
        }
        self.membrane_vertices
            .upload(device, queue, bytemuck::cast_slice(&draw.membrane_vertices));
        self.membrane_indices
            .upload(device, queue, bytemuck::cast_slice(&draw.membrane_indices));
    }

    /// The passes of a frame; `viewport`, for a strip: the frame's width and height and the
    /// strip's first row.
    pub(super) fn encode_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        draw: &FrameDraw,
        targets: &FrameTargets,
        viewport: Option<(u32, u32, u32)>,
    ) {
        if !self.encode_main_pass(encoder, draw, targets, viewport) {
            return;
        }
        // d. a render pass of its own, so that it can read the reflection target pass b wrote.
        let load = |view| colour_attachment(view, wgpu::LoadOp::Load);
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("snell pass d"),
            color_attachments: &[
                load(&targets.beauty_view),
                load(&targets.position_view),
                load(&targets.flags_view),
            ],
            // Read-only: the stencil of the main pass says where the membrane is visible.
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_stencil_view,
                depth_ops: None,
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        set_strip_viewport(&mut pass, viewport);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &targets.reflection_bind_group, &[]);
        pass.set_stencil_reference(MEMBRANE_STENCIL);
        pass.set_pipeline(&self.pipelines.reflection);
        pass.draw(0..3, 0..1);
    }

    /// Passes a to c; false when there is no membrane (and so nothing for pass d to do).
    fn encode_main_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        draw: &FrameDraw,
        targets: &FrameTargets,
        viewport: Option<(u32, u32, u32)>,
    ) -> bool {
        let colour = |view| colour_attachment(view, wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT));
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("snell passes"),
            color_attachments: &[
                colour(&targets.beauty_view),
                colour(&targets.position_view),
                colour(&targets.flags_view),
                // Only read inside the stencil, where pass b always writes it: no clear needed.
                colour_attachment(&targets.reflection_view, wgpu::LoadOp::Load),
                colour(&targets.extra_view),
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_stencil_view,
                // Stored too: pass d attaches depth-stencil read-only, and a discarded aspect
                // would be cleared again before it.
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                // Kept for pass d, which reads the stencil.
                stencil_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0),
                    store: wgpu::StoreOp::Store,
                }),
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        set_strip_viewport(&mut pass, viewport);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_stencil_reference(MEMBRANE_STENCIL);
        let pipelines = &self.pipelines;
        fn buffer_of(growing: &GrowingBuffer) -> Option<wgpu::BufferSlice<'_>> {
            growing.buffer.as_ref().map(|buffer| buffer.slice(..))
        }

        // a. the geometry on the eye's side.
        if let (Some(vertices), Some(indices)) = (
            buffer_of(&self.above_vertices),
            buffer_of(&self.above_indices),
        ) {
            if !draw.above_indices.is_empty() {
                pass.set_pipeline(&pipelines.above);
                pass.set_vertex_buffer(0, vertices);
                pass.set_index_buffer(indices, wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..draw.above_indices.len() as u32, 0, 0..1);
            }
        }
        let membrane = match (
            buffer_of(&self.membrane_vertices),
            buffer_of(&self.membrane_indices),
        ) {
            (Some(vertices), Some(indices)) if !draw.membrane_indices.is_empty() => {
                Some((vertices, indices))
            }
            _ => None,
        };
        let Some((membrane_vertices, membrane_indices)) = membrane else {
            pass.set_pipeline(&pipelines.sky);
            pass.draw(0..3, 0..1);
            return false;
        };
        // b. the membrane: stencil where it is visible, its distance and reflection; then the sky
        // where nothing is.
        pass.set_pipeline(&pipelines.membrane);
        pass.set_vertex_buffer(0, membrane_vertices);
        pass.set_index_buffer(membrane_indices, wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..draw.membrane_indices.len() as u32, 0, 0..1);
        pass.set_pipeline(&pipelines.sky);
        pass.draw(0..3, 0..1);
        // c. inside the stencil: depth to far + deep-water colour, then the virtual geometry.
        pass.set_pipeline(&pipelines.deep_water);
        pass.draw(0..3, 0..1);
        if let Some(vertices) = buffer_of(&self.under_vertices) {
            if !draw.under_vertices.is_empty() {
                pass.set_pipeline(&pipelines.under);
                pass.set_vertex_buffer(0, vertices);
                let vertex_count = draw.under_vertices.len() as u32;
                match buffer_of(&self.under_indices) {
                    // Indexed although the list is a plain triangle soup: on Mesa's lavapipe /
                    // llvmpipe the non-indexed draw of this list, whose triangles crossing the
                    // viewport's edges must be clipped, spent ~15 ms of ~190 ms CPU per 1280x720
                    // pool frame in the draw module's per-batch vertex-id reset loop; indexed,
                    // that loop all but vanished from the profile (same pixels).
                    Some(indices) => {
                        pass.set_index_buffer(indices, wgpu::IndexFormat::Uint32);
                        pass.draw_indexed(0..vertex_count, 0, 0..1);
                    }
                    _ => pass.draw(0..vertex_count, 0..1),
                }
            }
        }
        true
    }
}

/// A colour attachment of the frame's render passes, loaded as `load` says and stored.
fn colour_attachment(
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        },
    })
}
