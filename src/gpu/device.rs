//! Adapter and device: Vulkan when present, else GL (`WGPU_BACKEND` and `WGPU_ADAPTER_NAME`
//! honoured), the target formats the chosen adapter can actually render, and the error scopes
//! wgpu's calls run in.

use super::GpuError;

/// The device and what was chosen for it.
pub(crate) struct GpuContext {
    pub adapter_info: wgpu::AdapterInfo,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub formats: TargetFormats,
}

/// Render-target formats picked from what the adapter reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct TargetFormats {
    /// Rgba32Float where it is renderable and blendable, else Rgba16Float (GL/llvmpipe).
    pub beauty: wgpu::TextureFormat,
    /// Depth32FloatStencil8 where supported, else Depth24PlusStencil8.
    pub depth_stencil: wgpu::TextureFormat,
    /// Whether the adapter takes the resolve pass of a supersampled frame (its seven targets:
    /// [`super::resolve`]).
    pub supersampling: bool,
}

/// World position and distance as float bits: float32 on every backend.
pub(crate) const POSITION_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
pub(crate) const FLAGS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// The membrane's premultiplied sky reflection, kept from pass b to pass d as float32 bits
/// (float32 targets are not renderable on GL/llvmpipe; the bits blend exactly as the fragment
/// stage's own float32 output would).
pub(crate) const REFLECTION_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
/// Float32 bits of the apparent depth (w); xyz reserved.
pub(crate) const EXTRA_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

fn instance() -> wgpu::Instance {
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

/// Backend preference: Vulkan first (WebGPU-compliant, float32 targets), then GL, then the rest.
fn backend_rank(backend: wgpu::Backend) -> u32 {
    match backend {
        wgpu::Backend::Vulkan => 0,
        wgpu::Backend::Gl => 1,
        _ => 2,
    }
}

fn choose_adapter(instance: &wgpu::Instance) -> Result<wgpu::Adapter, GpuError> {
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all());
    let adapters = pollster::block_on(instance.enumerate_adapters(backends));
    let wanted_name = std::env::var("WGPU_ADAPTER_NAME")
        .ok()
        .map(|name| name.to_lowercase());
    let found: Vec<String> = adapters
        .iter()
        .map(|adapter| {
            let info = adapter.get_info();
            format!("{} ({:?})", info.name, info.backend)
        })
        .collect();
    adapters
        .into_iter()
        .filter(|adapter| match &wanted_name {
            Some(name) => adapter.get_info().name.to_lowercase().contains(name),
            None => true,
        })
        // Stable: among equal backends the enumeration order (hardware before software) stands.
        .min_by_key(|adapter| backend_rank(adapter.get_info().backend))
        .ok_or_else(|| GpuError::NoAdapter {
            backends: format!("{backends:?}"),
            wanted_name: wanted_name.unwrap_or_default(),
            found: if found.is_empty() {
                "none".to_string()
            } else {
                found.join(", ")
            },
        })
}

fn summary_of(info: &wgpu::AdapterInfo) -> String {
    let driver = match (info.driver.is_empty(), info.driver_info.is_empty()) {
        (true, true) => "unknown driver".to_string(),
        (false, true) => info.driver.clone(),
        (true, false) => info.driver_info.clone(),
        (false, false) => format!("{} {}", info.driver, info.driver_info),
    };
    format!(
        "{} ({:?}, {:?}, {})",
        info.name, info.backend, info.device_type, driver
    )
}

/// Name, backend and driver of the adapter a renderer would use, without creating a device.
pub fn probe_adapter() -> Result<String, GpuError> {
    let adapter = choose_adapter(&instance())?;
    Ok(summary_of(&adapter.get_info()))
}

fn renders_and_blends(adapter: &wgpu::Adapter, format: wgpu::TextureFormat) -> bool {
    let features = adapter.get_texture_format_features(format);
    features
        .allowed_usages
        .contains(wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC)
        && features
            .flags
            .contains(wgpu::TextureFormatFeatureFlags::BLENDABLE)
}

impl GpuContext {
    pub fn new() -> Result<GpuContext, GpuError> {
        let adapter = choose_adapter(&instance())?;
        let adapter_info = adapter.get_info();
        let available = adapter.features();
        let mut required_features = wgpu::Features::empty();
        let mut required_limits = wgpu::Limits::default().using_resolution(adapter.limits());
        // The triangle draws read their vertex lists as storage buffers (gpu::pulling), each
        // bound whole: as large as the adapter allows, like a vertex buffer.
        required_limits.max_storage_buffer_binding_size =
            adapter.limits().max_storage_buffer_binding_size;

        // Float32 blending is a device feature: without it a float32 target cannot take pass d's
        // blend. Beauty (16 or 8) + position (16) + flags (4) + reflection (16) + extra (16) bytes
        // per sample exceed the default limit of 32, so the adapter must allow more (Mesa's
        // drivers: 128).
        let bytes_per_sample = |beauty_bytes: u32| beauty_bytes + 16 + 4 + 16 + 16;
        let allowed_bytes_per_sample = adapter.limits().max_color_attachment_bytes_per_sample;
        let beauty = if available.contains(wgpu::Features::FLOAT32_BLENDABLE)
            && renders_and_blends(&adapter, wgpu::TextureFormat::Rgba32Float)
            && allowed_bytes_per_sample >= bytes_per_sample(16)
        {
            required_features |= wgpu::Features::FLOAT32_BLENDABLE;
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
        // The resolve pass of a supersampled frame adds the corner and edge coverage (16 bytes
        // each).
        let beauty_bytes = beauty.block_copy_size(None).unwrap_or(16);
        let resolve_bytes = bytes_per_sample(beauty_bytes) + 2 * 16;
        let supersampling = allowed_bytes_per_sample >= resolve_bytes;
        required_limits.max_color_attachment_bytes_per_sample = required_limits
            .max_color_attachment_bytes_per_sample
            .max(if supersampling {
                resolve_bytes
            } else {
                bytes_per_sample(beauty_bytes)
            });
        let depth_stencil = if available.contains(wgpu::Features::DEPTH32FLOAT_STENCIL8) {
            required_features |= wgpu::Features::DEPTH32FLOAT_STENCIL8;
            wgpu::TextureFormat::Depth32FloatStencil8
        } else {
            wgpu::TextureFormat::Depth24PlusStencil8
        };

        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("snell"),
            required_features,
            required_limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|source| GpuError::RequestDevice {
            adapter: summary_of(&adapter_info),
            source,
        })?;

        Ok(GpuContext {
            adapter_info,
            device,
            queue,
            formats: TargetFormats {
                beauty,
                depth_stencil,
                supersampling,
            },
        })
    }

    pub fn summary(&self) -> String {
        summary_of(&self.adapter_info)
    }
}

/// Runs `work` inside out-of-memory and validation error scopes, so wgpu errors come back as a
/// [`GpuError`] naming `stage` instead of panicking; the scopes are popped on every path.
pub(crate) fn within_error_scopes<T>(
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
