//! The render pipelines of the six draws of ALGORITHM §7 (see the module documentation of
//! [`super`]): their shaders, layouts, colour writes, depth and stencil.

use super::device::{GpuContext, EXTRA_FORMAT, FLAGS_FORMAT, POSITION_FORMAT, REFLECTION_FORMAT};
use super::{shaders, GpuError};

/// The pipelines of the six draws, in drawing order.
pub(super) struct Pipelines {
    pub(super) sky: wgpu::RenderPipeline,
    pub(super) above: wgpu::RenderPipeline,
    pub(super) membrane: wgpu::RenderPipeline,
    pub(super) deep_water: wgpu::RenderPipeline,
    pub(super) under: wgpu::RenderPipeline,
    pub(super) reflection: wgpu::RenderPipeline,
}

/// Which colour channels a draw writes into (beauty, position, flags, and in the main render pass
/// the membrane's reflection; `None`: a draw of pass d, which has no reflection target).
struct Writes {
    beauty: wgpu::ColorWrites,
    beauty_blend: Option<wgpu::BlendState>,
    position: wgpu::ColorWrites,
    flags: wgpu::ColorWrites,
    /// The main pass's membrane reflection and extra targets; `None` in pass d, which has neither.
    reflection_and_extra: Option<(wgpu::ColorWrites, wgpu::ColorWrites)>,
}

const ALL_WRITES: Writes = Writes {
    beauty: wgpu::ColorWrites::ALL,
    beauty_blend: None,
    position: wgpu::ColorWrites::ALL,
    flags: wgpu::ColorWrites::ALL,
    reflection_and_extra: Some((wgpu::ColorWrites::empty(), wgpu::ColorWrites::ALL)),
};
/// Inside the stencil: the position's w (distance) is the membrane's, written by pass b.
const UNDER_WATER_WRITES: Writes = Writes {
    beauty: wgpu::ColorWrites::ALL,
    beauty_blend: None,
    position: wgpu::ColorWrites::COLOR,
    flags: wgpu::ColorWrites::ALL,
    reflection_and_extra: Some((wgpu::ColorWrites::empty(), wgpu::ColorWrites::ALL)),
};

/// Depth and stencil behaviour of a draw.
struct DepthStencil {
    depth_write: bool,
    depth_compare: wgpu::CompareFunction,
    stencil_compare: wgpu::CompareFunction,
    stencil_pass: wgpu::StencilOperation,
}

/// The stencil value that marks "the membrane is visible here".
pub(super) const MEMBRANE_STENCIL: u32 = 1;

struct PipelineFactory<'a> {
    device: &'a wgpu::Device,
    layout: wgpu::PipelineLayout,
    /// Pass d's layout: the frame's bind group and the reflection target's.
    reflection_layout: wgpu::PipelineLayout,
    /// The triangle draws' layout: the frame's bind group and their pulled vertices'.
    pulled_layout: wgpu::PipelineLayout,
    beauty_format: wgpu::TextureFormat,
    depth_stencil_format: wgpu::TextureFormat,
}

impl PipelineFactory<'_> {
    /// A pipeline of the main render pass, or of pass d where `writes` has no reflection; with
    /// `pulled`, one that reads vertices from group 1 ([`super::pulling`]). No draw has vertex
    /// buffers.
    #[allow(clippy::too_many_arguments)]
    fn pipeline(
        &self,
        label: &str,
        module: &wgpu::ShaderModule,
        vertex_entry: &str,
        fragment_entry: &str,
        pulled: bool,
        writes: Writes,
        depth_stencil: DepthStencil,
    ) -> wgpu::RenderPipeline {
        let layout = match (writes.reflection_and_extra, pulled) {
            (Some(_), true) => &self.pulled_layout,
            (Some(_), false) => &self.layout,
            (None, _) => &self.reflection_layout,
        };
        let stencil_face = wgpu::StencilFaceState {
            compare: depth_stencil.stencil_compare,
            fail_op: wgpu::StencilOperation::Keep,
            depth_fail_op: wgpu::StencilOperation::Keep,
            pass_op: depth_stencil.stencil_pass,
        };
        self.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some(vertex_entry),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    // Virtual geometry can mirror a triangle's winding; nothing here is culled.
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: self.depth_stencil_format,
                    depth_write_enabled: Some(depth_stencil.depth_write),
                    depth_compare: Some(depth_stencil.depth_compare),
                    stencil: wgpu::StencilState {
                        front: stencil_face,
                        back: stencil_face,
                        read_mask: 0xff,
                        write_mask: 0xff,
                    },
                    bias: wgpu::DepthBiasState::default(),
                }),
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some(fragment_entry),
                    compilation_options: Default::default(),
                    targets: &[
                        Some(wgpu::ColorTargetState {
                            format: self.beauty_format,
                            blend: writes.beauty_blend,
                            write_mask: writes.beauty,
                        }),
                        Some(wgpu::ColorTargetState {
                            format: POSITION_FORMAT,
                            blend: None,
                            write_mask: writes.position,
                        }),
                        Some(wgpu::ColorTargetState {
                            format: FLAGS_FORMAT,
                            blend: None,
                            write_mask: writes.flags,
                        }),
                        writes
                            .reflection_and_extra
                            .map(|(write_mask, _)| wgpu::ColorTargetState {
                                format: REFLECTION_FORMAT,
                                blend: None,
                                write_mask,
                            }),
                        writes
                            .reflection_and_extra
                            .map(|(_, write_mask)| wgpu::ColorTargetState {
                                format: EXTRA_FORMAT,
                                blend: None,
                                write_mask,
                            }),
                    ][..if writes.reflection_and_extra.is_some() {
                        5
                    } else {
                        3
                    }],
                }),
                multiview_mask: None,
                cache: None,
            })
    }
}

fn shader_module(device: &wgpu::Device, name: &str) -> Result<wgpu::ShaderModule, GpuError> {
    let assembled = shaders::assembled_shader(name).ok_or(GpuError::Wgpu {
        stage: "looking up a shader",
        message: format!("no shader module named {name}"),
    })?;
    Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(assembled.name),
        source: wgpu::ShaderSource::Wgsl(assembled.source.into()),
    }))
}

pub(super) fn create_pipelines(
    context: &GpuContext,
    bind_group_layout: &wgpu::BindGroupLayout,
    reflection_layout: &wgpu::BindGroupLayout,
    pulled_layout: &wgpu::BindGroupLayout,
) -> Result<Pipelines, GpuError> {
    use wgpu::CompareFunction::{Always, Equal, Less, LessEqual, NotEqual};
    use wgpu::StencilOperation::{Keep, Replace};
    let device = &context.device;
    let factory = PipelineFactory {
        device,
        layout: device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("snell passes"),
            bind_group_layouts: &[Some(bind_group_layout)],
            immediate_size: 0,
        }),
        reflection_layout: device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("snell pass d"),
            bind_group_layouts: &[Some(bind_group_layout), Some(reflection_layout)],
            immediate_size: 0,
        }),
        pulled_layout: device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("snell pulled draws"),
            bind_group_layouts: &[Some(bind_group_layout), Some(pulled_layout)],
            immediate_size: 0,
        }),
        beauty_format: context.formats.beauty,
        depth_stencil_format: context.formats.depth_stencil,
    };
    let sky_module = shader_module(device, "sky")?;
    let above_module = shader_module(device, "above")?;
    let membrane_module = shader_module(device, "membrane")?;
    let water_clear_module = shader_module(device, "water_clear")?;
    let under_module = shader_module(device, "under")?;

    let inside_stencil = |depth_write, depth_compare| DepthStencil {
        depth_write,
        depth_compare,
        stencil_compare: Equal,
        stencil_pass: Keep,
    };
    let fresnel_blend = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
        operation: wgpu::BlendOperation::Add,
    };

    Ok(Pipelines {
        sky: factory.pipeline(
            "sky",
            &sky_module,
            "vs_sky",
            "fs_sky",
            false,
            ALL_WRITES,
            // Drawn after the above-water geometry and the membrane's stencil: only pixels that
            // nothing has covered (depth still at the far plane, no visible membrane) shade the
            // sky, instead of every pixel of the frame shading it to be overwritten.
            DepthStencil {
                depth_write: false,
                depth_compare: LessEqual,
                stencil_compare: NotEqual,
                stencil_pass: Keep,
            },
        ),
        above: factory.pipeline(
            "above water",
            &above_module,
            "vs_above",
            "fs_above",
            true,
            ALL_WRITES,
            DepthStencil {
                depth_write: true,
                depth_compare: Less,
                stencil_compare: Always,
                stencil_pass: Keep,
            },
        ),
        // One draw of the membrane: depth-tested against the geometry above water and writing
        // depth, so the last fragment to land in a pixel is its front-most visible membrane
        // fragment (the first of equal depths). It marks the stencil and leaves that fragment's
        // distance and reflection for pass d.
        membrane: factory.pipeline(
            "membrane",
            &membrane_module,
            "vs_membrane",
            "fs_membrane",
            true,
            Writes {
                beauty: wgpu::ColorWrites::empty(),
                beauty_blend: None,
                position: wgpu::ColorWrites::ALPHA,
                flags: wgpu::ColorWrites::empty(),
                reflection_and_extra: Some((wgpu::ColorWrites::ALL, wgpu::ColorWrites::empty())),
            },
            DepthStencil {
                depth_write: true,
                depth_compare: Less,
                stencil_compare: Always,
                stencil_pass: Replace,
            },
        ),
        deep_water: factory.pipeline(
            "deep water clear",
            &water_clear_module,
            "vs_far",
            "fs_deep_water",
            false,
            UNDER_WATER_WRITES,
            inside_stencil(true, Always),
        ),
        under: factory.pipeline(
            "under water (virtual)",
            &under_module,
            "vs_under",
            "fs_under",
            true,
            UNDER_WATER_WRITES,
            inside_stencil(true, Less),
        ),
        reflection: factory.pipeline(
            "membrane reflection",
            &water_clear_module,
            "vs_far",
            "fs_reflection",
            false,
            Writes {
                beauty: wgpu::ColorWrites::ALL,
                beauty_blend: Some(wgpu::BlendState {
                    color: fresnel_blend,
                    alpha: fresnel_blend,
                }),
                position: wgpu::ColorWrites::empty(),
                flags: wgpu::ColorWrites::empty(),
                reflection_and_extra: None,
            },
            inside_stencil(false, Always),
        ),
    })
}
