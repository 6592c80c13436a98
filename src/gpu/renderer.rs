//! The renderer made: bind group layouts, pipelines, uniform buffers, the sampler and the
//! texture array; and what it says about its adapter.

use super::buffers::GrowingBuffer;
use super::device::{within_error_scopes, GpuContext};
use super::pipelines::create_pipelines;
use super::uniform::FrameUniform;
use super::{pulling, textures, GpuError, Renderer, MAX_MATERIALS};
use crate::mesh::Texture;

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
        let pulled_layout = pulling::bind_group_layout(device);
        let pipelines = create_pipelines(
            &context,
            &bind_group_layout,
            &reflection_layout,
            &pulled_layout,
        )?;
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
        // Pulled by the shaders (storage); the sequential list is the draws' index buffer too.
        let vertex = wgpu::BufferUsages::STORAGE;
        let index = wgpu::BufferUsages::STORAGE;
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
            sequential_indices: GrowingBuffer::new(
                "sequential indices",
                index | wgpu::BufferUsages::INDEX,
            ),
            sequential_index_count: 0,
            membrane_vertices: GrowingBuffer::new("membrane vertices", vertex),
            membrane_indices: GrowingBuffer::new("membrane indices", index),
            pulled_layout,
            pulled: Default::default(),
            targets: None,
            forced_strip_rows: None,
            supersample: 1,
            resolve: None,
        })
    }

    /// Whether this adapter can supersample ([`Self::set_supersample`]): it must take the resolve
    /// pass's seven targets.
    pub fn can_supersample(&self) -> bool {
        self.context.formats.supersampling
    }

    /// How the frames drawn from now on are sampled: 1 (the default), every layer at the pixel
    /// centre; or 2, supersampled ([`super::resolve`]): drawn on a grid of points half a pixel
    /// apart (four points a pixel), the beauty filtered by the box over the pixel, `Z`, `P`, IDs
    /// and flags the pixel centre's, the Cryptomatte's coverage counted over the points.
    pub fn set_supersample(&mut self, supersample: u32) -> Result<(), GpuError> {
        if supersample == self.supersample {
            return Ok(());
        }
        let possible = supersample == 1
            || (supersample == super::resolve::SUPERSAMPLE && self.can_supersample());
        if !possible {
            return Err(GpuError::BadSupersample {
                asked: supersample,
                adapter: self.adapter_summary(),
            });
        }
        if supersample > 1 && self.resolve.is_none() {
            let device = self.context.device.clone();
            let resolve = within_error_scopes(&device, "creating the resolve pass", || {
                super::resolve::Resolve::new(&self.context)
            })?;
            self.resolve = Some(resolve);
        }
        self.supersample = supersample;
        // Targets of the old sampling go.
        self.targets = None;
        Ok(())
    }

    /// How the frames drawn are sampled ([`Self::set_supersample`]).
    pub fn supersample(&self) -> u32 {
        self.supersample
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
}
