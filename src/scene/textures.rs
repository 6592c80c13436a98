//! Textures of the scene's surfaces: procedural ones (solid, checker, ceramic tiles with grout and
//! optional lane stripes) baked deterministically into 8-bit sRGB images, and image files decoded
//! with the `image` crate. Each baked texture covers one repeat unit of `repeat_m` metres; mesh uvs
//! (metres) are divided by it, so a sampler in repeat mode tiles it across any surface.

use std::path::PathBuf;

use crate::mesh::Texture;

/// A texture as the (validated) scene describes it. Colours are sRGB in 0..=1, as written.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureSpec {
    Solid {
        color_srgb: [f64; 3],
    },
    Checker {
        color_srgb: [f64; 3],
        color_b_srgb: [f64; 3],
        square_m: f64,
    },
    Tiles(TilesSpec),
    Image(ImageSpec),
}

/// Square ceramic tiles separated by grout lines centred on the tile borders.
#[derive(Clone, Debug, PartialEq)]
pub struct TilesSpec {
    pub color_srgb: [f64; 3],
    pub grout_color_srgb: [f64; 3],
    pub tile_size_m: f64,
    pub grout_width_m: f64,
    /// Per-tile brightness jitter, as a fraction (0.05 = +-5 %), like real glazed tiles.
    pub variation: f64,
    /// A second tile colour mixed in at random (e.g. pale blue among white).
    pub accent_color_srgb: [f64; 3],
    /// Fraction of tiles in the accent colour, 0..=1.
    pub accent_fraction: f64,
    /// Dark stripes along u (the pool's length), one per `spacing_m` of v, centred in each lane.
    pub lanes: Option<LaneSpec>,
    /// Seed of the per-tile randomness: the same seed gives the same bytes.
    pub seed: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LaneSpec {
    pub spacing_m: f64,
    pub width_m: f64,
    pub color_srgb: [f64; 3],
}

/// An image file (path resolved against the scene file's folder) covering `size_m` metres.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageSpec {
    pub path: PathBuf,
    pub size_m: [f64; 2],
    /// Where the scene file names the image, for errors while decoding it.
    pub source: SourceRef,
}

/// A position in the scene file, kept for errors raised after validation (image decoding).
#[derive(Clone, Debug, PartialEq)]
pub struct SourceRef {
    pub file: PathBuf,
    pub line: usize,
    pub column: usize,
    pub key: String,
}

/// A baked texture and the size in metres of the surface one copy of it covers.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedTexture {
    pub texture: Texture,
    pub repeat_m: [f64; 2],
}

/// Pixels per metre of procedural textures: 512 keeps 5 mm grout lines about 2.5 pixels wide.
const PIXELS_PER_M: f64 = 512.0;
/// Largest side of a baked procedural texture.
const MAX_SIDE_PX: f64 = 2048.0;
/// Supersamples per pixel side: grout lines are only a few pixels wide and must not alias.
const SUPERSAMPLES: usize = 3;

/// Why an image texture could not be used.
#[derive(Debug)]
pub struct ImageLoadError {
    pub cause: String,
}

impl TextureSpec {
    /// Bakes the texture (procedural) or decodes it (image).
    pub fn bake(&self, name: &str) -> Result<BakedTexture, ImageLoadError> {
        match self {
            TextureSpec::Solid { color_srgb } => {
                let texel = encode_srgb8(srgb_to_linear3(*color_srgb));
                let rgba8_srgb = (0..16).flat_map(|_| texel).collect();
                Ok(BakedTexture {
                    texture: Texture {
                        name: name.to_owned(),
                        width: 4,
                        height: 4,
                        rgba8_srgb,
                    },
                    repeat_m: [1.0, 1.0],
                })
            }
            TextureSpec::Checker {
                color_srgb,
                color_b_srgb,
                square_m,
            } => {
                let a = srgb_to_linear3(*color_srgb);
                let b = srgb_to_linear3(*color_b_srgb);
                let repeat = 2.0 * square_m;
                // Squares on whole pixels: no supersampling needed and edges stay crisp.
                let side = 256u32;
                let half = side / 2;
                let texture = bake_image(name, side, side, 1, |u, v| {
                    let (x, y) = ((u * side as f64) as u32, (v * side as f64) as u32);
                    if (x < half) == (y < half) {
                        a
                    } else {
                        b
                    }
                });
                Ok(BakedTexture {
                    texture,
                    repeat_m: [repeat, repeat],
                })
            }
            TextureSpec::Tiles(tiles) => Ok(bake_tiles(name, tiles)),
            TextureSpec::Image(image) => {
                let bytes = crate::files::read_regular(&image.path, crate::files::MAX_ASSET_BYTES)
                    .map_err(|e| ImageLoadError {
                        cause: e.to_string(),
                    })?;
                let decoded = crate::files::decode_image_rgba8(&bytes)
                    .map_err(|cause| ImageLoadError { cause })?;
                Ok(BakedTexture {
                    texture: Texture {
                        name: name.to_owned(),
                        width: decoded.width(),
                        height: decoded.height(),
                        rgba8_srgb: decoded.into_raw(),
                    },
                    repeat_m: image.size_m,
                })
            }
        }
    }
}

/// Side of a tile texture's repeat unit: long enough that the per-tile randomness does not show
/// an obvious pattern across a deck or a floor.
const TILES_REPEAT_M: f64 = 2.0;

/// The repeat unit of a tile texture: about two metres of whole tiles along u; along v the lane
/// spacing when there are lanes (tiles then stretch by at most half a tile per lane to fit).
fn tiles_layout(tiles: &TilesSpec) -> ([f64; 2], [u32; 2]) {
    let tiles_u = (TILES_REPEAT_M / tiles.tile_size_m).round().max(1.0) as u32;
    let repeat_u = tiles_u as f64 * tiles.tile_size_m;
    match &tiles.lanes {
        Some(lanes) => {
            let tiles_v = (lanes.spacing_m / tiles.tile_size_m).round().max(1.0) as u32;
            ([repeat_u, lanes.spacing_m], [tiles_u, tiles_v])
        }
        None => ([repeat_u, repeat_u], [tiles_u, tiles_u]),
    }
}

fn bake_tiles(name: &str, tiles: &TilesSpec) -> BakedTexture {
    let (repeat_m, tile_counts) = tiles_layout(tiles);
    let pixels_per_m = PIXELS_PER_M.min(MAX_SIDE_PX / repeat_m[0].max(repeat_m[1]));
    let width = (repeat_m[0] * pixels_per_m).round().max(1.0) as u32;
    let height = (repeat_m[1] * pixels_per_m).round().max(1.0) as u32;
    let tile_u_m = repeat_m[0] / tile_counts[0] as f64;
    let tile_v_m = repeat_m[1] / tile_counts[1] as f64;
    let base = srgb_to_linear3(tiles.color_srgb);
    let accent = srgb_to_linear3(tiles.accent_color_srgb);
    let grout = srgb_to_linear3(tiles.grout_color_srgb);
    let lane = tiles
        .lanes
        .as_ref()
        .map(|l| (l.width_m, srgb_to_linear3(l.color_srgb)));
    let half_grout = tiles.grout_width_m * 0.5;
    let texture = bake_image(name, width, height, SUPERSAMPLES, |u, v| {
        let (u_m, v_m) = (u * repeat_m[0], v * repeat_m[1]);
        let (tile_x, tile_y) = ((u_m / tile_u_m).floor(), (v_m / tile_v_m).floor());
        let (local_u, local_v) = (u_m - tile_x * tile_u_m, v_m - tile_y * tile_v_m);
        // Distance to the nearest tile border (grout is centred on borders, so it wraps seamlessly).
        let edge_m = local_u
            .min(tile_u_m - local_u)
            .min(local_v)
            .min(tile_v_m - local_v);
        if edge_m < half_grout {
            return grout;
        }
        let (ix, iy) = (
            tile_x as u32 % tile_counts[0],
            tile_y as u32 % tile_counts[1],
        );
        let mut color = base;
        if unit_hash(ix, iy, tiles.seed ^ 0x9e37_79b9) < tiles.accent_fraction {
            color = accent;
        }
        if let Some((width_m, lane_color)) = lane {
            if (v_m - 0.5 * repeat_m[1]).abs() < 0.5 * width_m {
                color = lane_color;
            }
        }
        let jitter = 1.0 + tiles.variation * (2.0 * unit_hash(ix, iy, tiles.seed) - 1.0);
        // Glazed tiles darken slightly toward their rounded edges.
        let bevel_m = 2.0 * half_grout.max(0.001);
        let bevel = if edge_m < half_grout + bevel_m {
            0.9
        } else {
            1.0
        };
        color.map(|c| c * jitter * bevel)
    });
    BakedTexture { texture, repeat_m }
}

/// Bakes an image by averaging `supersamples`^2 samples of `linear_at(u, v)` (u, v in [0, 1),
/// v = 0 on the top row) per pixel, then encoding to sRGB.
fn bake_image(
    name: &str,
    width: u32,
    height: u32,
    supersamples: usize,
    linear_at: impl Fn(f64, f64) -> [f64; 3] + Sync,
) -> Texture {
    use rayon::prelude::*;
    let mut rgba8_srgb = vec![0u8; width as usize * height as usize * 4];
    let n = supersamples as f64;
    // Rows are independent, so baking them in parallel gives the same bytes as in sequence.
    rgba8_srgb
        .par_chunks_mut(width as usize * 4)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, texel) in row.chunks_exact_mut(4).enumerate() {
                let mut sum = [0.0; 3];
                for sy in 0..supersamples {
                    for sx in 0..supersamples {
                        let u = (x as f64 + (sx as f64 + 0.5) / n) / width as f64;
                        let v = (y as f64 + (sy as f64 + 0.5) / n) / height as f64;
                        let c = linear_at(u, v);
                        for k in 0..3 {
                            sum[k] += c[k];
                        }
                    }
                }
                texel.copy_from_slice(&encode_srgb8(sum.map(|s| s / (n * n))));
            }
        });
    Texture {
        name: name.to_owned(),
        width,
        height,
        rgba8_srgb,
    }
}

/// A deterministic hash of a tile's coordinates to [0, 1).
fn unit_hash(x: u32, y: u32, seed: u32) -> f64 {
    let mut h = (x as u64) | ((y as u64) << 32);
    h ^= (seed as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    // splitmix64 finaliser
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^= h >> 31;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

pub use crate::color::{linear_to_srgb, srgb_to_linear};

pub fn srgb_to_linear3(c: [f64; 3]) -> [f64; 3] {
    c.map(srgb_to_linear)
}

fn encode_srgb8(linear: [f64; 3]) -> [u8; 4] {
    let [r, g, b] = linear.map(|c| (linear_to_srgb(c) * 255.0).round() as u8);
    [r, g, b, 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool_tiles(lanes: bool) -> TilesSpec {
        TilesSpec {
            color_srgb: [0.92, 0.95, 0.97],
            grout_color_srgb: [0.6, 0.62, 0.62],
            tile_size_m: 0.25,
            grout_width_m: 0.006,
            variation: 0.05,
            accent_color_srgb: [0.7, 0.85, 0.95],
            accent_fraction: 0.2,
            lanes: lanes.then_some(LaneSpec {
                spacing_m: 2.5,
                width_m: 0.25,
                color_srgb: [0.05, 0.1, 0.35],
            }),
            seed: 7,
        }
    }

    fn texel(t: &Texture, x: u32, y: u32) -> [u8; 4] {
        let i = ((y * t.width + x) * 4) as usize;
        t.rgba8_srgb[i..i + 4].try_into().unwrap()
    }

    #[test]
    fn srgb_round_trips() {
        for i in 0..=255u32 {
            let c = i as f64 / 255.0;
            let back = (linear_to_srgb(srgb_to_linear(c)) * 255.0).round() as u32;
            assert_eq!(back, i);
        }
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }

    #[test]
    fn tiles_have_grout_on_borders_and_tile_colour_inside() {
        let baked = TextureSpec::Tiles(pool_tiles(false)).bake("tiles").unwrap();
        let t = &baked.texture;
        assert_eq!(baked.repeat_m, [2.0, 2.0]);
        assert_eq!((t.width, t.height), (1024, 1024));
        assert_eq!(t.rgba8_srgb.len(), 1024 * 1024 * 4);
        // 8 tiles of 128 px: pixel 0 and 128 straddle a border (grout), pixel 64 is a tile centre.
        let grout = encode_srgb8(srgb_to_linear3([0.6, 0.62, 0.62]));
        assert_eq!(texel(t, 0, 64), grout);
        assert_eq!(texel(t, 64, 128), grout);
        let centre = texel(t, 64, 64);
        assert_ne!(centre, grout);
        assert!(
            centre[0] > 150 && centre[2] > 200,
            "tile centre {centre:?} is not a pale tile"
        );
    }

    #[test]
    fn lane_stripe_is_dark_and_centred_in_the_lane() {
        let baked = TextureSpec::Tiles(pool_tiles(true)).bake("floor").unwrap();
        let t = &baked.texture;
        assert_eq!(baked.repeat_m, [2.0, 2.5]);
        assert_eq!((t.width, t.height), (1024, 1280));
        // Lane centre v = 1.25 m = row 640 lies on a tile border (grout): sample beside it.
        let stripe = texel(t, 64, 600);
        assert!(
            stripe[2] < 120 && stripe[0] < 40,
            "lane stripe {stripe:?} is not dark blue"
        );
        let away = texel(t, 64, 64);
        assert!(away[0] > 150, "tile away from the lane {away:?} is dark");
    }

    #[test]
    fn baking_is_deterministic_and_seeded() {
        let a = TextureSpec::Tiles(pool_tiles(false)).bake("a").unwrap();
        let b = TextureSpec::Tiles(pool_tiles(false)).bake("a").unwrap();
        assert_eq!(a, b);
        let mut other = pool_tiles(false);
        other.seed = 8;
        let c = TextureSpec::Tiles(other).bake("a").unwrap();
        assert_ne!(a.texture.rgba8_srgb, c.texture.rgba8_srgb);
    }

    #[test]
    fn checker_alternates() {
        let spec = TextureSpec::Checker {
            color_srgb: [1.0; 3],
            color_b_srgb: [0.0; 3],
            square_m: 0.5,
        };
        let baked = spec.bake("c").unwrap();
        assert_eq!(baked.repeat_m, [1.0, 1.0]);
        assert_eq!(texel(&baked.texture, 10, 10), [255, 255, 255, 255]);
        assert_eq!(texel(&baked.texture, 200, 10), [0, 0, 0, 255]);
        assert_eq!(texel(&baked.texture, 200, 200), [255, 255, 255, 255]);
    }

    #[test]
    fn solid_is_its_colour() {
        let baked = TextureSpec::Solid {
            color_srgb: [0.4, 0.2, 1.0],
        }
        .bake("s")
        .unwrap();
        assert_eq!(texel(&baked.texture, 3, 3), [102, 51, 255, 255]);
    }

    #[test]
    fn missing_image_is_an_error() {
        let spec = TextureSpec::Image(ImageSpec {
            path: PathBuf::from("/nonexistent/snell.png"),
            size_m: [1.0, 1.0],
            source: SourceRef {
                file: PathBuf::from("x.toml"),
                line: 1,
                column: 1,
                key: String::new(),
            },
        });
        assert!(spec.bake("i").is_err());
    }
}
