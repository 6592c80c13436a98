//! Scene textures as one sRGB 2-D array texture (one layer per texture, all resampled to the
//! largest size so a material's texture is just a layer index, on every backend), with a mip
//! chain filtered in linear light on the CPU, and a repeating sampler: pool tiles tile.

use crate::mesh::Texture;

use super::GpuError;

/// The format every texture is stored in: decoding sRGB is the sampler's job.
use crate::color::{linear_to_srgb8 as linear_to_srgb, srgb8_to_linear as srgb_to_linear};

pub(crate) const TEXTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// Textures as uploaded: what the bind group needs.
pub(crate) struct TextureArray {
    pub view: wgpu::TextureView,
    pub layer_count: u32,
}

/// Half-size image by a 2x2 box in linear light (alpha linear already). Odd sizes clamp the last
/// row/column.
fn downsample(
    pixels: &[u8],
    width: u32,
    height: u32,
    to_linear: &[f32; 256],
) -> (Vec<u8>, u32, u32) {
    let new_width = (width / 2).max(1);
    let new_height = (height / 2).max(1);
    let mut out = vec![0u8; (new_width * new_height * 4) as usize];
    for y in 0..new_height {
        for x in 0..new_width {
            let mut sum = [0.0f32; 4];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let sx = (2 * x + dx).min(width - 1);
                let sy = (2 * y + dy).min(height - 1);
                let at = ((sy * width + sx) * 4) as usize;
                for channel in 0..3 {
                    sum[channel] += to_linear[pixels[at + channel] as usize];
                }
                sum[3] += pixels[at + 3] as f32 / 255.0;
            }
            let at = ((y * new_width + x) * 4) as usize;
            for channel in 0..3 {
                out[at + channel] = linear_to_srgb(sum[channel] * 0.25);
            }
            out[at + 3] = (sum[3] * 0.25 * 255.0 + 0.5) as u8;
        }
    }
    (out, new_width, new_height)
}

/// A texture's pixels at `width` x `height` (bilinear resampling when the size differs).
fn resized(texture: &Texture, width: u32, height: u32) -> Vec<u8> {
    if texture.width == width && texture.height == height {
        return texture.rgba8_srgb.clone();
    }
    let image =
        image::RgbaImage::from_raw(texture.width, texture.height, texture.rgba8_srgb.clone())
            .expect("size checked by validate_texture");
    image::imageops::resize(&image, width, height, image::imageops::FilterType::Triangle).into_raw()
}

/// The sRGB bytes of every mip level of `texture` as the GPU stores it in the array: resized to
/// the array's `width` x `height`, then halved by [`downsample`] down to 1x1 (`1 + log2(max side)`
/// levels). The CPU reference tracer samples these same bytes.
pub(crate) fn mip_chain(texture: &Texture, width: u32, height: u32) -> Vec<(Vec<u8>, u32, u32)> {
    let to_linear: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as u8));
    let mip_level_count = 32 - width.max(height).leading_zeros();
    let mut levels = vec![(resized(texture, width, height), width, height)];
    while levels.len() < mip_level_count as usize {
        let (pixels, w, h) = levels.last().expect("level 0 is there");
        let next = downsample(pixels, *w, *h, &to_linear);
        levels.push(next);
    }
    levels
}

/// The single white texel used when a scene has no textures (untextured materials are tints).
pub(crate) fn white_texture() -> Texture {
    Texture {
        name: "white".to_string(),
        width: 1,
        height: 1,
        rgba8_srgb: vec![255; 4],
    }
}

fn validate_texture(index: usize, texture: &Texture) -> Result<(), GpuError> {
    let expected = texture.width as usize * texture.height as usize * 4;
    if texture.width == 0 || texture.height == 0 || texture.rgba8_srgb.len() != expected {
        return Err(GpuError::BadTexture {
            index,
            name: texture.name.clone(),
            width: texture.width,
            height: texture.height,
            bytes: texture.rgba8_srgb.len(),
        });
    }
    Ok(())
}

/// Uploads `textures` (a single white texel when there are none, so untextured materials are just tints).
pub(crate) fn upload_textures(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    textures: &[Texture],
) -> Result<TextureArray, GpuError> {
    let white = white_texture();
    let textures: &[Texture] = if textures.is_empty() {
        std::slice::from_ref(&white)
    } else {
        textures
    };
    for (index, texture) in textures.iter().enumerate() {
        validate_texture(index, texture)?;
    }
    let limits = device.limits();
    if textures.len().max(2) > limits.max_texture_array_layers as usize {
        return Err(GpuError::TooManyTextures {
            count: textures.len(),
            max: limits.max_texture_array_layers as usize,
        });
    }
    let max_side = limits.max_texture_dimension_2d;
    let width = textures
        .iter()
        .map(|t| t.width)
        .max()
        .unwrap_or(1)
        .min(max_side);
    let height = textures
        .iter()
        .map(|t| t.height)
        .max()
        .unwrap_or(1)
        .min(max_side);
    let mip_level_count = 32 - width.max(height).leading_zeros();
    let layer_count = textures.len() as u32;
    // wgpu's GL backend makes a one-layer texture a plain TEXTURE_2D, which a D2Array view then
    // samples as black: allocate a spare layer so it is always a TEXTURE_2D_ARRAY.
    let allocated_layers = layer_count.max(2);

    let gpu_texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("scene textures"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: allocated_layers,
        },
        mip_level_count,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: TEXTURE_FORMAT,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });

    for (layer, texture) in textures.iter().enumerate() {
        for (mip_level, (pixels, level_width, level_height)) in
            (0u32..).zip(mip_chain(texture, width, height))
        {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &gpu_texture,
                    mip_level,
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: 0,
                        z: layer as u32,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                &pixels,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(level_width * 4),
                    rows_per_image: Some(level_height),
                },
                wgpu::Extent3d {
                    width: level_width,
                    height: level_height,
                    depth_or_array_layers: 1,
                },
            );
        }
    }
    let view = gpu_texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("scene textures"),
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    Ok(TextureArray { view, layer_count })
}

pub(crate) fn repeating_sampler(device: &wgpu::Device) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("repeating trilinear"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        address_mode_w: wgpu::AddressMode::ClampToEdge,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for byte in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(byte)), byte);
        }
    }

    #[test]
    fn downsampling_averages_in_linear_light() {
        let to_linear: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as u8));
        // Black and white checker: the linear mean is 0.5, which sRGB-encodes to 188, not 128.
        let checker = [
            0, 0, 0, 255, 255, 255, 255, 255, 255, 255, 255, 255, 0, 0, 0, 255,
        ];
        let (half, w, h) = downsample(&checker, 2, 2, &to_linear);
        assert_eq!((w, h), (1, 1));
        assert_eq!(half, vec![188, 188, 188, 255]);
    }
}
