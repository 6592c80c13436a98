//! Anti-aliasing by supersampling (issue 16 point 5). A supersampled frame is drawn by the usual
//! passes (a to d) on a grid of points half a pixel apart that includes every pixel's corners,
//! edge midpoints and centre (`2W + 1` by `2H + 1` points: the frame's projection widened by a
//! quarter pixel on each side, [`super::uniform::FrameUniform::new`]); a resolve pass of its own
//! (`shaders/resolve.wgsl`) then makes the frame's targets, which are read back: the beauty and
//! the water's reflection filtered by the box over the pixel (the trapezoid rule on its 3 x 3
//! points), `Z`, `P`, IDs, flags, matte and apparent depth from the centre point, exactly the
//! pixel centre, and one coverage word per point for the Cryptomatte. The points are the whole
//! frame's (a strip draws its own rows of them, `2 rows + 1`, from point row `2 first_row`), so
//! strips stay the whole frame's; neighbouring pixels share their edge points, so a pixel costs 4
//! points, not 9.
//!
//! Why not multisampling, which the adapters report for every target format: wgpu 30's GL backend
//! makes a multisampled texture that shaders read with the target GL_TEXTURE_2D
//! (`glTexStorage2DMultisample(target=GL_TEXTURE_2D)`, GL_INVALID_ENUM, and every draw into it
//! fails: gfx-rs/wgpu#6084), and the resolve needs each sample (pass d blends the reflection per
//! sample; the Cryptomatte counts objects per sample). On Vulkan alone a 4x multisampled beauty
//! pass worked; and one multisampled pass cannot give the pixel centre's `Z`, `P` and IDs (no
//! sample of the standard pattern is at the centre, and a triangle holding the centre may cover
//! no sample), so it needed a second, one-sample pass besides.

use super::device::{GpuContext, EXTRA_FORMAT, FLAGS_FORMAT, POSITION_FORMAT, REFLECTION_FORMAT};
use super::{shaders, GpuError};

/// The coverage targets (corners and edge midpoints: `shaders/resolve.wgsl`).
pub(super) const COVERAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

/// Points a pixel along each side of a supersampled frame's grid, less the shared one: 2 (the
/// points of pixel x are at x, x + 1/2 and x + 1).
pub(crate) const SUPERSAMPLE: u32 = 2;

/// Points along a side of `pixels` pixels: `SUPERSAMPLE * pixels + 1`.
pub(super) fn points_for(pixels: u32) -> u32 {
    SUPERSAMPLE * pixels + 1
}

/// The resolve pass's pipeline and the layout of its bind group (group 0, bindings 4 to 8: the
/// supersampled targets).
pub(super) struct Resolve {
    pub(super) layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
}

impl Resolve {
    pub(super) fn new(context: &GpuContext) -> Result<Resolve, GpuError> {
        let device = &context.device;
        let texture = |binding, sample_type| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let uint = wgpu::TextureSampleType::Uint;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("resolve"),
            entries: &[
                texture(4, wgpu::TextureSampleType::Float { filterable: false }),
                texture(5, uint),
                texture(6, uint),
                texture(7, uint),
                texture(8, uint),
            ],
        });
        let assembled = shaders::assembled_shader("resolve").ok_or(GpuError::Wgpu {
            stage: "looking up a shader",
            message: "no shader module named resolve".to_string(),
        })?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(assembled.name),
            source: wgpu::ShaderSource::Wgsl(assembled.source.into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("resolve"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let target = |format| {
            Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })
        };
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("resolve"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_resolve"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_resolve"),
                compilation_options: Default::default(),
                targets: &[
                    target(context.formats.beauty),
                    target(POSITION_FORMAT),
                    target(FLAGS_FORMAT),
                    target(REFLECTION_FORMAT),
                    target(EXTRA_FORMAT),
                    target(COVERAGE_FORMAT),
                    target(COVERAGE_FORMAT),
                ],
            }),
            multiview_mask: None,
            cache: None,
        });
        Ok(Resolve { layout, pipeline })
    }

    /// Encodes the resolve of `from` (a strip's points) into the frame's `into` views (beauty,
    /// position, flags, reflection, extra, corner and edge coverage) of the strip: a full-screen
    /// triangle, no viewport of its own (each pixel reads its own points).
    pub(super) fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        from: &wgpu::BindGroup,
        into: [&wgpu::TextureView; 7],
    ) {
        let attachments = into.map(|view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("snell resolve"),
            color_attachments: &attachments,
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, from, &[]);
        pass.draw(0..3, 0..1);
    }
}
