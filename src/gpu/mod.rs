//! Stage 4, GPU: a headless wgpu device, the passes of ALGORITHM §7, and readback. Receives a
//! [`FrameDraw`] (vertex lists split above/under water, membrane, materials) and a [`FrameView`]
//! (camera, light, water); returns a [`RenderedFrame`] (linear beauty, distance, true position,
//! flags). The only module that touches wgpu.
//!
//! Passes a to c share one render pass over five attachments — beauty (Rgba32Float, or
//! Rgba16Float where float32 cannot be rendered/blended), position (Rgba32Uint: float32 bits of
//! the true world position in xyz and of the eye distance in w, on every backend), flags (R32Uint:
//! the flag bits, and above them the object seen), the membrane's reflection (Rgba32Uint: float32
//! bits of F * sky and F) and depth-stencil — and pass d has a render pass of its own; six draws:
//! 1. above-water geometry (true positions, depth test), 2. the membrane, depth-tested against it
//!    and writing depth, marks stencil = 1 where visible and leaves the front-most fragment's
//!    distance (position w) and sky reflection by Schlick's F (even where a crest hides a trough,
//!    the last fragment written is the front-most), 3. sky (full-screen at the far plane, only
//!    where depth is still far and the stencil unmarked, so covered pixels never shade it),
//!    4. inside the stencil a full-screen triangle pushes depth to far and writes the deep-water
//!    colour, 5. under-water geometry at virtual positions with true attributes, 6. pass d: inside
//!    the stencil a full-screen triangle blends the kept reflection over the refracted image.
//!
//! The reflection used to be found after the under-water image, by resetting depth inside the
//! stencil, redrawing the membrane depth-only and drawing it a third time with depth Equal: on
//! llvmpipe each draw of the 25,600 small membrane triangles costs ~10 ms of CPU, however cheap
//! its fragment stage, so keeping the reflection from the one draw is cheaper (same pixels).

mod device;
mod readback;
pub mod shaders;
pub mod shading;
pub(crate) mod textures;

use glam::{Mat4, Vec3};

use crate::draw::{FrameDraw, FrameView, MembraneVertex, RenderedFrame, TrueVertex, VirtualVertex};
use crate::mesh::Texture;

pub use device::probe_adapter;
use device::{GpuContext, EXTRA_FORMAT, FLAGS_FORMAT, POSITION_FORMAT, REFLECTION_FORMAT};
use readback::{read_back, readback_bytes_per_row, FrameTargets};

/// Most materials one frame can use: the uniform array in `shaders/common.inc.wgsl` (16 bytes
/// each; 16 KiB is the uniform binding size every backend guarantees).
pub const MAX_MATERIALS: usize = 1024;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no graphics adapter found (backends {backends}{}; adapters present: {found}); \
         on a machine without a GPU install Mesa (libegl-mesa0 for GL, mesa-vulkan-drivers for Vulkan)",
        if wanted_name.is_empty() { String::new() } else { format!(", WGPU_ADAPTER_NAME contains \"{wanted_name}\"") }
    )]
    NoAdapter {
        backends: String,
        wanted_name: String,
        found: String,
    },
    #[error("adapter {adapter} refused to create a device: {source}")]
    RequestDevice {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
    #[error("wgpu reported an error while {stage}: {message}")]
    Wgpu {
        stage: &'static str,
        message: String,
    },
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
    #[error("reading the rendered frame back failed: {0}")]
    Readback(String),
    #[error("render size {width}x{height} is not possible: each side must be between 1 and {max} pixels")]
    BadSize { width: u32, height: u32, max: u32 },
    #[error("texture {index} (\"{name}\") is {width}x{height} but holds {bytes} bytes; it needs width * height * 4 > 0")]
    BadTexture {
        index: usize,
        name: String,
        width: u32,
        height: u32,
        bytes: usize,
    },
    #[error("{count} textures are more than this adapter's {max} texture array layers")]
    TooManyTextures { count: usize, max: usize },
    #[error("{count} materials are more than the renderer's {max}")]
    TooManyMaterials { count: usize, max: usize },
    #[error("material {material} uses texture {texture}, but only {count} textures were uploaded")]
    TextureOutOfRange {
        material: usize,
        texture: u32,
        count: u32,
    },
    #[error("{list}[{index}] refers to {value}, but there are only {count}")]
    IndexOutOfRange {
        list: &'static str,
        index: usize,
        value: u32,
        count: usize,
    },
    #[error("under_vertices holds {count} vertices, not a whole number of triangles")]
    PartialTriangle { count: usize },
}

/// Frame constants as `shaders/common.inc.wgsl` declares `Frame`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameUniform {
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
    fn new(view: &FrameView, width: u32, height: u32, first_row: u32) -> FrameUniform {
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

/// A GPU buffer that keeps its size across frames and grows (to a power of two) when a frame needs more.
struct GrowingBuffer {
    label: &'static str,
    usage: wgpu::BufferUsages,
    buffer: Option<wgpu::Buffer>,
}

impl GrowingBuffer {
    fn new(label: &'static str, usage: wgpu::BufferUsages) -> GrowingBuffer {
        GrowingBuffer {
            label,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            buffer: None,
        }
    }

    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, bytes: &[u8]) {
        let needed = bytes.len() as u64;
        if self
            .buffer
            .as_ref()
            .is_none_or(|buffer| buffer.size() < needed)
        {
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size: needed.next_power_of_two().max(4096),
                usage: self.usage,
                mapped_at_creation: false,
            }));
        }
        if let Some(buffer) = &self.buffer {
            if !bytes.is_empty() {
                queue.write_buffer(buffer, 0, bytes);
            }
        }
    }
}

/// The pipelines of the six draws, in drawing order.
struct Pipelines {
    sky: wgpu::RenderPipeline,
    above: wgpu::RenderPipeline,
    membrane: wgpu::RenderPipeline,
    deep_water: wgpu::RenderPipeline,
    under: wgpu::RenderPipeline,
    reflection: wgpu::RenderPipeline,
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
const MEMBRANE_STENCIL: u32 = 1;

struct PipelineFactory<'a> {
    device: &'a wgpu::Device,
    layout: wgpu::PipelineLayout,
    /// Pass d's layout: the frame's bind group and the reflection target's.
    reflection_layout: wgpu::PipelineLayout,
    beauty_format: wgpu::TextureFormat,
    depth_stencil_format: wgpu::TextureFormat,
}

impl PipelineFactory<'_> {
    #[allow(clippy::too_many_arguments)]
    fn pipeline(
        &self,
        label: &str,
        module: &wgpu::ShaderModule,
        vertex_entry: &str,
        fragment_entry: &str,
        buffers: &[Option<wgpu::VertexBufferLayout>],
        writes: Writes,
        depth_stencil: DepthStencil,
    ) -> wgpu::RenderPipeline {
        let layout = match writes.reflection_and_extra {
            Some(_) => &self.layout,
            None => &self.reflection_layout,
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
                    buffers,
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

fn create_pipelines(
    context: &GpuContext,
    bind_group_layout: &wgpu::BindGroupLayout,
    reflection_layout: &wgpu::BindGroupLayout,
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
        beauty_format: context.formats.beauty,
        depth_stencil_format: context.formats.depth_stencil,
    };
    let sky_module = shader_module(device, "sky")?;
    let above_module = shader_module(device, "above")?;
    let membrane_module = shader_module(device, "membrane")?;
    let water_clear_module = shader_module(device, "water_clear")?;
    let under_module = shader_module(device, "under")?;

    let above_layout = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<TrueVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x2, 4 => Uint32
        ],
    };
    let under_layout = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<VirtualVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3, 4 => Float32x2,
            5 => Uint32, 6 => Float32, 7 => Uint32
        ],
    };
    let membrane_layout = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<MembraneVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
    };
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
            &[],
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
            &[Some(above_layout)],
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
            &[Some(membrane_layout)],
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
            &[],
            UNDER_WATER_WRITES,
            inside_stencil(true, Always),
        ),
        under: factory.pipeline(
            "under water (virtual)",
            &under_module,
            "vs_under",
            "fs_under",
            &[Some(under_layout)],
            UNDER_WATER_WRITES,
            inside_stencil(true, Less),
        ),
        reflection: factory.pipeline(
            "membrane reflection",
            &water_clear_module,
            "vs_far",
            "fs_reflection",
            &[],
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

/// Runs `work` inside out-of-memory and validation error scopes, so wgpu errors come back as a
/// [`GpuError`] naming `stage` instead of panicking; the scopes are popped on every path.
fn within_error_scopes<T>(
    device: &wgpu::Device,
    stage: &'static str,
    work: impl FnOnce() -> Result<T, GpuError>,
) -> Result<T, GpuError> {
    let out_of_memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let result = work();
    // Scopes pop innermost first.
    let caught = [validation.pop(), out_of_memory.pop()].map(pollster::block_on);
    match caught.into_iter().flatten().next() {
        Some(error) => {
            let message = match &error {
                wgpu::Error::Validation { description, .. } => description.clone(),
                other => format!("{other}: {other:?}"),
            };
            Err(GpuError::Wgpu { stage, message })
        }
        None => result,
    }
}

/// The headless renderer: device, pipelines, and buffers and targets reused across frames.
pub struct Renderer {
    context: GpuContext,
    pipelines: Pipelines,
    bind_group_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// Pass d's second bind group: the reflection target (one per [`FrameTargets`]).
    reflection_layout: wgpu::BindGroupLayout,
    frame_uniform: wgpu::Buffer,
    material_uniform: wgpu::Buffer,
    sampler: wgpu::Sampler,
    texture_layers: u32,
    above_vertices: GrowingBuffer,
    above_indices: GrowingBuffer,
    under_vertices: GrowingBuffer,
    /// 0, 1, 2, ... for drawing the under-water triangle list indexed (see `encode_passes`).
    under_indices: GrowingBuffer,
    /// How many sequential indices `under_indices` holds.
    under_index_count: usize,
    membrane_vertices: GrowingBuffer,
    membrane_indices: GrowingBuffer,
    targets: Option<FrameTargets>,
    /// Rows of a strip when set ([`Renderer::set_strip_rows`]); otherwise [`Renderer::strip_rows`]
    /// chooses.
    forced_strip_rows: Option<u32>,
}

/// Bytes of readback buffer a strip may take: wgpu's default `max_buffer_size`, which the device
/// keeps. A 1280x720 frame (about 60 MiB) and a 2560x1440 one fit whole; a 7680x4320 frame is
/// read back in 9 strips of 512 rows.
const STRIP_READBACK_BYTES: u64 = 256 << 20;

/// A strip's rows are a multiple of this (but a frame's last strip): the largest block of scan
/// lines an EXR compression writes (PIZ's 32), so that a strip ends on a block of the file.
pub const STRIP_ROW_MULTIPLE: u32 = 32;

/// How many rows each strip of a frame `height` rows high has (`height`: the frame is drawn
/// whole) when a strip's readback may take `budget_bytes` and a row takes `row_bytes`, or as
/// `forced` says; fewer rows than the frame are rounded down to [`STRIP_ROW_MULTIPLE`] (at least
/// one multiple).
pub fn strip_rows_for(height: u32, row_bytes: u64, budget_bytes: u64, forced: Option<u32>) -> u32 {
    let rows = match forced {
        Some(rows) => rows,
        None if row_bytes.saturating_mul(height as u64) <= budget_bytes => return height,
        None => (budget_bytes / row_bytes.max(1)).min(u32::MAX as u64) as u32,
    };
    if rows >= height {
        return height;
    }
    (rows / STRIP_ROW_MULTIPLE * STRIP_ROW_MULTIPLE)
        .max(STRIP_ROW_MULTIPLE)
        .min(height)
}

fn make_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame_uniform: &wgpu::Buffer,
    material_uniform: &wgpu::Buffer,
    textures: &wgpu::TextureView,
    sampler: &wgpu::Sampler,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("frame"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame_uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: material_uniform.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(textures),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::Sampler(sampler),
            },
        ],
    })
}

fn check_indices(list: &'static str, indices: &[u32], vertex_count: usize) -> Result<(), GpuError> {
    match indices
        .iter()
        .position(|&index| index as usize >= vertex_count)
    {
        Some(at) => Err(GpuError::IndexOutOfRange {
            list,
            index: at,
            value: indices[at],
            count: vertex_count,
        }),
        None => Ok(()),
    }
}

fn check_materials<'a>(
    list: &'static str,
    materials: impl Iterator<Item = u32> + 'a,
    material_count: usize,
) -> Result<(), GpuError> {
    for (index, material) in materials.enumerate() {
        if material as usize >= material_count {
            return Err(GpuError::IndexOutOfRange {
                list,
                index,
                value: material,
                count: material_count,
            });
        }
    }
    Ok(())
}

impl Renderer {
    /// Opens the adapter (Vulkan if present, else GL; `WGPU_BACKEND` honoured) and builds the pipelines.
    pub fn new() -> Result<Renderer, GpuError> {
        let context = GpuContext::new()?;
        let device = context.device.clone();
        within_error_scopes(&device, "creating the pipelines", move || {
            Renderer::build(context)
        })
    }

    fn build(context: GpuContext) -> Result<Renderer, GpuError> {
        let device = &context.device;
        let uniform_entry = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame"),
            entries: &[
                uniform_entry(0),
                uniform_entry(1),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let reflection_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("membrane reflection"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Uint,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let pipelines = create_pipelines(&context, &bind_group_layout, &reflection_layout)?;
        let frame_uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame constants"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let material_uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("materials"),
            size: (MAX_MATERIALS * 16) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let sampler = textures::repeating_sampler(device);
        let texture_array = textures::upload_textures(device, &context.queue, &[])?;
        let bind_group = make_bind_group(
            device,
            &bind_group_layout,
            &frame_uniform,
            &material_uniform,
            &texture_array.view,
            &sampler,
        );
        let vertex = wgpu::BufferUsages::VERTEX;
        let index = wgpu::BufferUsages::INDEX;
        Ok(Renderer {
            context,
            pipelines,
            bind_group_layout,
            bind_group,
            reflection_layout,
            frame_uniform,
            material_uniform,
            sampler,
            texture_layers: texture_array.layer_count,
            above_vertices: GrowingBuffer::new("above-water vertices", vertex),
            above_indices: GrowingBuffer::new("above-water indices", index),
            under_vertices: GrowingBuffer::new("under-water vertices", vertex),
            under_indices: GrowingBuffer::new("under-water indices", index),
            under_index_count: 0,
            membrane_vertices: GrowingBuffer::new("membrane vertices", vertex),
            membrane_indices: GrowingBuffer::new("membrane indices", index),
            targets: None,
            forced_strip_rows: None,
        })
    }

    /// Name, backend, device type and driver of the adapter in use.
    pub fn adapter_summary(&self) -> String {
        self.context.summary()
    }

    /// The beauty target's format name (Rgba32Float, or Rgba16Float where float32 cannot be rendered).
    pub fn beauty_format_name(&self) -> String {
        format!("{:?}", self.context.formats.beauty)
    }

    /// Replaces the scene's textures; `DrawMaterial::texture` indexes this list.
    pub fn set_textures(&mut self, textures: &[Texture]) -> Result<(), GpuError> {
        let device = &self.context.device;
        let (bind_group, layer_count) = within_error_scopes(device, "uploading textures", || {
            let texture_array = textures::upload_textures(device, &self.context.queue, textures)?;
            let bind_group = make_bind_group(
                device,
                &self.bind_group_layout,
                &self.frame_uniform,
                &self.material_uniform,
                &texture_array.view,
                &self.sampler,
            );
            Ok((bind_group, texture_array.layer_count))
        })?;
        self.bind_group = bind_group;
        self.texture_layers = layer_count;
        Ok(())
    }

    fn validate(&self, draw: &FrameDraw, width: u32, height: u32) -> Result<(), GpuError> {
        let max = self.context.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::BadSize { width, height, max });
        }
        if draw.materials.len() > MAX_MATERIALS {
            return Err(GpuError::TooManyMaterials {
                count: draw.materials.len(),
                max: MAX_MATERIALS,
            });
        }
        if let Some((material, texture)) = draw
            .materials
            .iter()
            .enumerate()
            .find(|(_, material)| material.texture >= self.texture_layers)
        {
            return Err(GpuError::TextureOutOfRange {
                material,
                texture: texture.texture,
                count: self.texture_layers,
            });
        }
        if !draw.under_vertices.len().is_multiple_of(3) {
            return Err(GpuError::PartialTriangle {
                count: draw.under_vertices.len(),
            });
        }
        check_indices(
            "above_indices",
            &draw.above_indices,
            draw.above_vertices.len(),
        )?;
        check_indices(
            "membrane_indices",
            &draw.membrane_indices,
            draw.membrane_vertices.len(),
        )?;
        let material_count = draw.materials.len();
        check_materials(
            "above_vertices[..].material",
            draw.above_vertices.iter().map(|v| v.material),
            material_count,
        )?;
        check_materials(
            "under_vertices[..].material",
            draw.under_vertices.iter().map(|v| v.material),
            material_count,
        )?;
        Ok(())
    }

    /// Draws one frame at `width` x `height` and reads every layer back: whole, or strip by strip
    /// ([`Self::render_strips`]) joined into one frame where it is too large to read back at once.
    pub fn render(
        &mut self,
        draw: &FrameDraw,
        view: &FrameView,
        width: u32,
        height: u32,
    ) -> Result<RenderedFrame, GpuError> {
        let mut whole = None;
        self.render_strips(draw, view, width, height, |_, strip| {
            RenderedFrame::gather(&mut whole, strip, height);
            Ok::<(), GpuError>(())
        })?;
        Ok(whole.unwrap_or_default())
    }

    /// Makes every frame's strips `rows` rows high (rounded down to [`STRIP_ROW_MULTIPLE`]), or,
    /// with `None`, as [`Self::strip_rows`] chooses. Strips render the same pixels as a whole
    /// frame; forcing them is for tests and measurements.
    pub fn set_strip_rows(&mut self, rows: Option<u32>) {
        self.forced_strip_rows = rows;
    }

    /// Rows of each strip of a `width` x `height` frame: `height` (one strip, the whole frame)
    /// when its readback fits [`STRIP_READBACK_BYTES`], otherwise as many rows as do, a multiple
    /// of [`STRIP_ROW_MULTIPLE`].
    pub fn strip_rows(&self, width: u32, height: u32) -> u32 {
        let budget = STRIP_READBACK_BYTES.min(self.context.device.limits().max_buffer_size);
        let row_bytes = readback_bytes_per_row(&self.context, width);
        strip_rows_for(height, row_bytes, budget, self.forced_strip_rows)
    }

    /// Draws one frame at `width` x `height` as horizontal strips of [`Self::strip_rows`] rows,
    /// top first, and gives each strip's layers to `sink` with the frame row it starts at, as
    /// soon as it is read back. Each strip draws the whole frame's geometry through the frame's
    /// own projection with the viewport moved up by the strip's first row, so its pixels are the
    /// frame's (the rasteriser's window coordinates shift by a whole number of pixels), and only
    /// one strip's targets and readback are held at a time. A frame of one strip is drawn exactly
    /// as before strips existed (no viewport set, offset 0).
    pub fn render_strips<E: From<GpuError>>(
        &mut self,
        draw: &FrameDraw,
        view: &FrameView,
        width: u32,
        height: u32,
        mut sink: impl FnMut(u32, RenderedFrame) -> Result<(), E>,
    ) -> Result<(), E> {
        self.validate(draw, width, height)?;
        let rows = self.strip_rows(width, height);
        if self
            .targets
            .as_ref()
            .is_none_or(|targets| (targets.width, targets.height) != (width, rows))
        {
            // The old targets go first, so that two sizes are never held at once.
            self.targets = None;
            self.targets = Some(FrameTargets::new(
                &self.context,
                &self.reflection_layout,
                width,
                rows,
            ));
        }
        let device = self.context.device.clone();
        within_error_scopes(&device, "uploading the frame", || {
            self.upload_frame(draw);
            Ok(())
        })?;
        let mut first_row = 0;
        while first_row < height {
            let strip_rows = rows.min(height - first_row);
            let started = std::time::Instant::now();
            within_error_scopes(&device, "drawing the frame", || {
                self.draw_strip(draw, view, (width, height), first_row, strip_rows);
                Ok(())
            })?;
            let submitted = std::time::Instant::now();
            // Waiting here separately only splits the time between drawing and reading back.
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(GpuError::from)?;
            let drawn = std::time::Instant::now();
            let targets = self.targets.as_ref().expect("created above");
            let strip = read_back(&device, targets, strip_rows)?;
            log::debug!(
                "gpu frame {width}x{height} rows {first_row}..{}: encode {:.1} ms, draw {:.1} ms, readback {:.1} ms",
                first_row + strip_rows,
                (submitted - started).as_secs_f64() * 1e3,
                (drawn - submitted).as_secs_f64() * 1e3,
                drawn.elapsed().as_secs_f64() * 1e3
            );
            sink(first_row, strip)?;
            first_row += strip_rows;
        }
        Ok(())
    }

    /// Uploads a frame's materials and vertex and index lists (once for all its strips).
    fn upload_frame(&mut self, draw: &FrameDraw) {
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

    /// Encodes and submits the passes of the strip of `rows` rows from `first_row` of a frame of
    /// `size`, and its copy into the readback buffer.
    fn draw_strip(
        &self,
        draw: &FrameDraw,
        view: &FrameView,
        size: (u32, u32),
        first_row: u32,
        rows: u32,
    ) {
        let device = &self.context.device;
        let queue = &self.context.queue;
        let (width, height) = size;
        queue.write_buffer(
            &self.frame_uniform,
            0,
            bytemuck::bytes_of(&FrameUniform::new(view, width, height, first_row)),
        );
        let targets = self.targets.as_ref().expect("created above");
        // The whole frame's viewport, moved up so that the strip's first row lands on the
        // targets' row 0 (WebGPU allows a viewport beyond the attachment). Not set for a whole
        // frame, which keeps the default viewport.
        let viewport = (targets.height < height).then_some((width, height, first_row));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        self.encode_passes(&mut encoder, draw, targets, viewport);
        targets.copy_to_readback(&mut encoder, rows);
        queue.submit([encoder.finish()]);
    }

    /// The passes of a frame; `viewport`, for a strip: the frame's width and height and the
    /// strip's first row.
    fn encode_passes(
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

/// Sets a strip's viewport: the whole frame's (`width` x `height`), its top `first_row` rows
/// above the attachment.
fn set_strip_viewport(pass: &mut wgpu::RenderPass<'_>, viewport: Option<(u32, u32, u32)>) {
    if let Some((width, height, first_row)) = viewport {
        pass.set_viewport(
            0.0,
            -(first_row as f32),
            width as f32,
            height as f32,
            0.0,
            1.0,
        );
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
