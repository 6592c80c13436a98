//! The passes of a frame (or a strip) encoded: the frame's uploads, the main render pass (draws
//! 1 to 5) and pass d, and for a supersampled frame the resolve pass after them
//! ([`super::resolve`]).

use super::pipelines::MEMBRANE_STENCIL;
use super::pulling::{bind_group, PulledBindGroups, CORNERS_PER_TRIANGLE};
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
        self.membrane_vertices
            .upload(device, queue, bytemuck::cast_slice(&draw.membrane_vertices));
        self.membrane_indices
            .upload(device, queue, bytemuck::cast_slice(&draw.membrane_indices));
        // Each pulled draw takes CORNERS_PER_TRIANGLE sequential indices a triangle; the
        // under-water soup's triangles are read from the same list.
        let triangles = draw
            .above_indices
            .len()
            .max(draw.under_vertices.len())
            .max(draw.membrane_indices.len())
            / 3;
        let needed = (triangles * CORNERS_PER_TRIANGLE as usize).max(draw.under_vertices.len());
        if self.sequential_index_count < needed {
            // Written only when the draws outgrow them.
            let count = needed.next_power_of_two();
            let indices: Vec<u32> = (0..count as u32).collect();
            self.sequential_indices
                .upload(device, queue, bytemuck::cast_slice(&indices));
            self.sequential_index_count = count;
        }
        let layout = &self.pulled_layout;
        self.pulled = PulledBindGroups {
            above: bind_group(
                device,
                layout,
                "above water",
                &self.above_vertices,
                &self.above_indices,
            ),
            membrane: bind_group(
                device,
                layout,
                "membrane",
                &self.membrane_vertices,
                &self.membrane_indices,
            ),
            under: bind_group(
                device,
                layout,
                "under water",
                &self.under_vertices,
                &self.sequential_indices,
            ),
        };
    }

    /// The passes of a frame; `viewport`, for a strip: the frame's width and height and the
    /// strip's first row (of the points, for a supersampled frame). A supersampled frame draws its
    /// points, then resolves them into `targets`.
    pub(super) fn encode_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        draw: &FrameDraw,
        targets: &FrameTargets,
        viewport: Option<(u32, u32, u32)>,
    ) {
        let (Some(points), Some(resolve)) = (&targets.points, &self.resolve) else {
            self.encode_drawn_passes(encoder, draw, targets, viewport);
            return;
        };
        self.encode_drawn_passes(encoder, draw, &points.targets, viewport);
        let [corners, edges] = &targets.coverage_views[..] else {
            unreachable!("a supersampled frame's targets have two coverage targets");
        };
        resolve.encode(
            encoder,
            &points.resolve_bind_group,
            [
                &targets.beauty_view,
                &targets.position_view,
                &targets.flags_view,
                &targets.reflection_view,
                &targets.extra_view,
                corners,
                edges,
            ],
        );
    }

    /// Passes a to d into `targets`.
    fn encode_drawn_passes(
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
        // Every triangle draw is pulled (super::pulling): no vertex buffers, CORNERS_PER_TRIANGLE
        // sequential indices a triangle. Indexed, not plain draws: on Mesa's lavapipe / llvmpipe
        // a non-indexed draw of the under-water list spent ~15 ms of ~190 ms CPU per 1280x720
        // pool frame in the draw module's per-batch vertex-id reset loop; indexed, that loop all
        // but vanished from the profile (same pixels).
        let sequential = self.sequential_indices.buffer.as_ref();
        fn draw_pulled(
            pass: &mut wgpu::RenderPass<'_>,
            pipeline: &wgpu::RenderPipeline,
            group: Option<&wgpu::BindGroup>,
            sequential: Option<&wgpu::Buffer>,
            triangles: usize,
        ) -> bool {
            let (Some(group), Some(indices)) = (group, sequential) else {
                return false;
            };
            if triangles == 0 {
                return false;
            }
            pass.set_pipeline(pipeline);
            pass.set_bind_group(1, group, &[]);
            pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..triangles as u32 * CORNERS_PER_TRIANGLE, 0, 0..1);
            true
        }

        // a. the geometry on the eye's side.
        draw_pulled(
            &mut pass,
            &pipelines.above,
            self.pulled.above.as_ref(),
            sequential,
            draw.above_indices.len() / 3,
        );
        // b. the membrane: stencil where it is visible, its distance and reflection; then the sky
        // where nothing is.
        if !draw_pulled(
            &mut pass,
            &pipelines.membrane,
            self.pulled.membrane.as_ref(),
            sequential,
            draw.membrane_indices.len() / 3,
        ) {
            pass.set_pipeline(&pipelines.sky);
            pass.draw(0..3, 0..1);
            return false;
        }
        pass.set_pipeline(&pipelines.sky);
        pass.draw(0..3, 0..1);
        // c. inside the stencil: depth to far + deep-water colour, then the virtual geometry.
        pass.set_pipeline(&pipelines.deep_water);
        pass.draw(0..3, 0..1);
        draw_pulled(
            &mut pass,
            &pipelines.under,
            self.pulled.under.as_ref(),
            sequential,
            draw.under_vertices.len() / 3,
        );
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
