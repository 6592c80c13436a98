//! The scene's textures as the GPU samples them, on the CPU: the same array layout (every texture
//! resized to the largest size), the same mip chain bytes ([`crate::gpu::textures::mip_chain`]),
//! decoded from sRGB to linear light as the `Rgba8UnormSrgb` format does, and sampled like the
//! GPU's repeating trilinear sampler: bilinear inside a level, linear between levels.
//!
//! The GPU picks the level from screen-space derivatives of the texture coordinates. A ray tracer
//! has no neighbouring fragments, so the caller estimates the same quantity (texels per pixel
//! along the footprint's long axis) from the path length, the pixel's angle and the surface's
//! obliquity; see [`crate::reference`] for the estimate.

use glam::{Vec2, Vec3};

use crate::color::srgb8_to_linear;
use crate::mesh::Texture;

/// One mip level, linear RGB.
struct Level {
    width: u32,
    height: u32,
    texels: Vec<Vec3>,
}

/// All textures of a job, every mip level, in linear light.
pub struct TextureSet {
    /// `layers[texture][level]`.
    layers: Vec<Vec<Level>>,
    /// Level-0 size of every layer (the largest texture's).
    width: u32,
    height: u32,
}

/// A texture whose byte count does not match its size.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("texture {index} ({name}): {width}x{height} needs {} bytes of RGBA, it has {bytes}", *width as usize * *height as usize * 4)]
pub struct BadTexture {
    pub index: usize,
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub bytes: usize,
}

impl TextureSet {
    /// The array the GPU would upload for `textures` (one white texel when there are none).
    pub fn new(textures: &[Texture]) -> Result<Self, BadTexture> {
        let white = crate::gpu::textures::white_texture();
        let textures: &[Texture] = if textures.is_empty() {
            std::slice::from_ref(&white)
        } else {
            textures
        };
        for (index, texture) in textures.iter().enumerate() {
            let expected = texture.width as usize * texture.height as usize * 4;
            if texture.width == 0 || texture.height == 0 || texture.rgba8_srgb.len() != expected {
                return Err(BadTexture {
                    index,
                    name: texture.name.clone(),
                    width: texture.width,
                    height: texture.height,
                    bytes: texture.rgba8_srgb.len(),
                });
            }
        }
        let width = textures.iter().map(|t| t.width).max().unwrap_or(1);
        let height = textures.iter().map(|t| t.height).max().unwrap_or(1);
        let to_linear: [f32; 256] = std::array::from_fn(|i| srgb8_to_linear(i as u8));
        let layers = textures
            .iter()
            .map(|texture| {
                crate::gpu::textures::mip_chain(texture, width, height)
                    .into_iter()
                    .map(|(bytes, width, height)| Level {
                        width,
                        height,
                        texels: bytes
                            .chunks_exact(4)
                            .map(|t| {
                                Vec3::new(
                                    to_linear[t[0] as usize],
                                    to_linear[t[1] as usize],
                                    to_linear[t[2] as usize],
                                )
                            })
                            .collect(),
                    })
                    .collect()
            })
            .collect();
        Ok(TextureSet {
            layers,
            width,
            height,
        })
    }

    /// Level-0 size in texels (every layer has it).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Linear colour of layer `layer` at `uv` (repeating), at mip level `lod` (fractional:
    /// trilinear; clamped to the chain). A layer past the end reads the last one, as the GPU
    /// clamps an array index.
    pub fn sample(&self, layer: u32, uv: Vec2, lod: f32) -> Vec3 {
        let levels = &self.layers[(layer as usize).min(self.layers.len() - 1)];
        let top = (levels.len() - 1) as f32;
        let lod = if lod.is_nan() {
            0.0
        } else {
            lod.clamp(0.0, top)
        };
        let low = lod.floor();
        let fraction = lod - low;
        let first = bilinear(&levels[low as usize], uv);
        if fraction <= 0.0 {
            return first;
        }
        let second = bilinear(&levels[(low as usize + 1).min(levels.len() - 1)], uv);
        first + (second - first) * fraction
    }
}

/// Bilinear filtering with repeat addressing; texel centres at half-integers, as on the GPU.
fn bilinear(level: &Level, uv: Vec2) -> Vec3 {
    let (w, h) = (level.width as i64, level.height as i64);
    let x = uv.x * level.width as f32 - 0.5;
    let y = uv.y * level.height as f32 - 0.5;
    if !(x.is_finite() && y.is_finite()) {
        return level.texels[0];
    }
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    // Power-of-two sides (every built-in texture) wrap with a mask, others by remainder.
    let wrap = |i: i64, n: i64| {
        if n & (n - 1) == 0 {
            i & (n - 1)
        } else {
            i.rem_euclid(n)
        }
    };
    let at = |i: i64, j: i64| level.texels[(wrap(j, h) * w + wrap(i, w)) as usize];
    let top = at(ix, iy) * (1.0 - fx) + at(ix + 1, iy) * fx;
    let bottom = at(ix, iy + 1) * (1.0 - fx) + at(ix + 1, iy + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker_2x2() -> Texture {
        // Black and white, top row first: (0,0) black, (1,0) white, (0,1) white, (1,1) black.
        Texture {
            name: "checker".into(),
            width: 2,
            height: 2,
            rgba8_srgb: vec![
                0, 0, 0, 255, 255, 255, 255, 255, 255, 255, 255, 255, 0, 0, 0, 255,
            ],
        }
    }

    #[test]
    fn texel_centres_read_exactly_and_the_top_level_is_the_linear_mean() {
        let set = TextureSet::new(&[checker_2x2()]).unwrap();
        assert_eq!(set.size(), (2, 2));
        assert_eq!(set.sample(0, Vec2::new(0.25, 0.25), 0.0), Vec3::ZERO);
        assert_eq!(set.sample(0, Vec2::new(0.75, 0.25), 0.0), Vec3::ONE);
        // Repeat: one texture width further is the same texel.
        assert_eq!(set.sample(0, Vec2::new(1.75, -0.75), 0.0), Vec3::ONE);
        // Half-way between two texel centres: their mean; at a corner of four: the mean of four.
        let mid = set.sample(0, Vec2::new(0.5, 0.25), 0.0);
        assert!((mid - Vec3::splat(0.5)).length() < 1e-6, "{mid}");
        // Level 1 is the 1x1 box mean in linear light, stored as sRGB 188 (as the GPU has it).
        let top = set.sample(0, Vec2::new(0.3, 0.9), 5.0);
        assert!((top - Vec3::splat(srgb8_to_linear(188))).length() < 1e-6);
        // Half-way between the levels.
        let between = set.sample(0, Vec2::new(0.25, 0.25), 0.5);
        assert!((between - Vec3::splat(0.5 * srgb8_to_linear(188))).length() < 1e-6);
    }

    #[test]
    fn no_textures_is_white_and_a_bad_size_is_reported() {
        let set = TextureSet::new(&[]).unwrap();
        assert_eq!(set.sample(3, Vec2::new(0.1, 0.2), 0.0), Vec3::ONE);
        let mut broken = checker_2x2();
        broken.rgba8_srgb.pop();
        let error = TextureSet::new(&[broken]).err().unwrap();
        assert!(error.to_string().contains("needs 16 bytes"), "{error}");
    }
}
