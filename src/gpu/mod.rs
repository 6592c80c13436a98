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
//!
//! The files: `device.rs` the adapter, device, target formats and wgpu error scopes;
//! `renderer.rs` the [`Renderer`] made (bind groups, uniforms, sampler, textures);
//! `pipelines.rs` the six draws' pipelines; `pulling.rs` the triangle draws' vertices read from
//! storage buffers, clipped and snapped in the shaders so that strips draw the frame's pixels;
//! `uniform.rs` the frame constants; `buffers.rs` the vertex and index buffers; `validate.rs` the checks of a frame's draw lists; `passes.rs` the
//! uploads and render passes encoded; `strips.rs` a frame drawn and read back strip by strip;
//! `readback.rs` the targets, readback buffer and unpacking; `resolve.rs` the resolve pass of a
//! supersampled frame (anti-aliasing: passes a to d draw its points, then the resolve filters the
//! beauty and keeps the centre's layers); `textures.rs` the texture array;
//! `shaders.rs` and `shading.rs` the WGSL sources and their CPU mirror (the shading model, the
//! sun's glint included).

mod buffers;
mod device;
mod passes;
mod pipelines;
mod pulling;
mod readback;
mod renderer;
mod resolve;
pub mod shaders;
pub mod shading;
mod strips;
pub(crate) mod textures;
mod uniform;
mod validate;

pub use device::probe_adapter;
pub use strips::{strip_rows_for, STRIP_ROW_MULTIPLE};

use buffers::GrowingBuffer;
use device::GpuContext;
use pipelines::Pipelines;
use readback::FrameTargets;

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
    #[error(
        "render size {width}x{height} is not possible: each side must be between 1 and {max} pixels \
         (supersampled frames draw twice as many points a side: [antialias] supersample = 1 allows twice the size)"
    )]
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
    #[error(
        "supersampling {asked} times a side is not possible on adapter {adapter}: 1 always, 2 \
         where it allows 116 bytes of colour targets a pixel"
    )]
    BadSupersample { asked: u32, adapter: String },
    #[error("under_vertices holds {count} vertices, not a whole number of triangles")]
    PartialTriangle { count: usize },
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
    /// 0, 1, 2, ...: the index list of every pulled draw (see `encode_passes`), and the
    /// under-water soup's triangles.
    sequential_indices: GrowingBuffer,
    /// How many sequential indices `sequential_indices` holds.
    sequential_index_count: usize,
    membrane_vertices: GrowingBuffer,
    membrane_indices: GrowingBuffer,
    /// Group 1 of the pulled draws ([`pulling`]): its layout and the frame's bind groups.
    pulled_layout: wgpu::BindGroupLayout,
    pulled: pulling::PulledBindGroups,
    targets: Option<FrameTargets>,
    /// Rows of a strip when set ([`Renderer::set_strip_rows`]); otherwise [`Renderer::strip_rows`]
    /// chooses.
    forced_strip_rows: Option<u32>,
    /// Points a pixel along each side ([`Renderer::set_supersample`]): 1, or 2 supersampled and
    /// resolved ([`resolve`]).
    supersample: u32,
    /// The resolve pass of a supersampled frame (made by [`Renderer::set_supersample`]).
    resolve: Option<resolve::Resolve>,
}
