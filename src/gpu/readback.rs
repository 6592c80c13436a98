//! The attachments of one strip size (a whole frame, or a band of its rows), the buffer they are
//! read back through, and the unpacking of the read-back bytes into a [`RenderedFrame`] of the
//! strip's rows.

use super::device::{GpuContext, EXTRA_FORMAT, FLAGS_FORMAT, POSITION_FORMAT, REFLECTION_FORMAT};
use super::resolve::{points_for, Resolve, COVERAGE_FORMAT};
use super::GpuError;
use crate::draw::{CoverageSample, RenderedFrame};

/// Row pitch of a texture copy: `COPY_BYTES_PER_ROW_ALIGNMENT` (256) aligned.
pub(super) fn padded_bytes_per_row(width: u32, bytes_per_pixel: u32) -> u32 {
    let unpadded = width * bytes_per_pixel;
    unpadded.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// The images read back, in readback-buffer order (the coverage of the corner and edge points only
/// from supersampled frames).
const BEAUTY: usize = 0;
const POSITION: usize = 1;
const FLAGS: usize = 2;
const REFLECTION: usize = 3;
const EXTRA: usize = 4;
const CORNERS: usize = 5;
const EDGES: usize = 6;

/// The formats of the images read back from frames supersampled `supersample` times a side.
fn image_formats(context: &GpuContext, supersample: u32) -> Vec<wgpu::TextureFormat> {
    let mut formats = vec![
        context.formats.beauty,
        POSITION_FORMAT,
        FLAGS_FORMAT,
        REFLECTION_FORMAT,
        EXTRA_FORMAT,
    ];
    if supersample > 1 {
        formats.extend([COVERAGE_FORMAT, COVERAGE_FORMAT]);
    }
    formats
}

/// Bytes of readback buffer one row of `width` pixels takes (every image, rows padded).
pub(super) fn readback_bytes_per_row(context: &GpuContext, width: u32, supersample: u32) -> u64 {
    image_formats(context, supersample)
        .iter()
        .map(|format| {
            padded_bytes_per_row(width, format.block_copy_size(None).unwrap_or(16)) as u64
        })
        .sum()
}

/// The attachments of one strip size (`width` x `height` rows) and the buffer they are read back
/// through.
pub(super) struct FrameTargets {
    pub width: u32,
    /// Rows of the attachments: the frame's height, or a strip's.
    pub height: u32,
    /// Beauty, position, flags, reflection, extra and, for supersampled frames, the coverage of
    /// the corner and edge points (the order of the readback buffer).
    textures: Vec<wgpu::Texture>,
    pub beauty_view: wgpu::TextureView,
    pub position_view: wgpu::TextureView,
    pub flags_view: wgpu::TextureView,
    pub reflection_view: wgpu::TextureView,
    pub extra_view: wgpu::TextureView,
    /// Binds the reflection target for pass d, which reads it.
    pub reflection_bind_group: wgpu::BindGroup,
    pub depth_stencil_view: wgpu::TextureView,
    /// A supersampled frame's points, which passes a to d draw; the views above are then the
    /// resolve pass's ([`super::resolve`]).
    pub points: Option<Box<Points>>,
    /// The resolve pass's coverage targets of a supersampled frame: corners, edge midpoints.
    pub coverage_views: Vec<wgpu::TextureView>,
    bytes_per_pixel: Vec<u32>,
    /// `None` for a supersampled frame's points, which are not read back.
    readback: Option<wgpu::Buffer>,
    /// Byte offsets of the images in `readback`.
    readback_offsets: Vec<u64>,
}

/// The points of a supersampled strip ([`super::resolve`]): targets `2 width + 1` by
/// `2 rows + 1` that passes a to d draw, and the resolve pass's bind group of them.
pub(super) struct Points {
    pub targets: FrameTargets,
    pub resolve_bind_group: wgpu::BindGroup,
}

impl FrameTargets {
    /// The targets of a strip `size` (width, rows) supersampled `supersample` times a side (1: not;
    /// more needs `resolve`, the resolve pass).
    pub fn new(
        context: &GpuContext,
        reflection_layout: &wgpu::BindGroupLayout,
        resolve: Option<&Resolve>,
        size: (u32, u32),
        supersample: u32,
    ) -> FrameTargets {
        let points = resolve.filter(|_| supersample > 1).map(|resolve| {
            let size = (points_for(size.0), points_for(size.1));
            let targets = FrameTargets::drawn(context, reflection_layout, size, false);
            let resolve_bind_group = targets.resolve_bind_group(context, resolve);
            Box::new(Points {
                targets,
                resolve_bind_group,
            })
        });
        let mut targets = FrameTargets::drawn(context, reflection_layout, size, true);
        if points.is_some() {
            targets.add_coverage(context);
        }
        targets.points = points;
        targets
    }

    /// Targets of `size` for passes a to d; `read_back`: with their readback buffer (else bound
    /// for the resolve pass to read).
    fn drawn(
        context: &GpuContext,
        reflection_layout: &wgpu::BindGroupLayout,
        size: (u32, u32),
        read_back: bool,
    ) -> FrameTargets {
        let (width, height) = size;
        let device = &context.device;
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let target = |label: &str, format: wgpu::TextureFormat, usage: wgpu::TextureUsages| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let colour_usage = wgpu::TextureUsages::RENDER_ATTACHMENT
            | if read_back {
                wgpu::TextureUsages::COPY_SRC
            } else {
                wgpu::TextureUsages::TEXTURE_BINDING
            };
        let textures = vec![
            target("beauty", context.formats.beauty, colour_usage),
            target("position", POSITION_FORMAT, colour_usage),
            target("flags", FLAGS_FORMAT, colour_usage),
            target(
                "membrane reflection",
                REFLECTION_FORMAT,
                colour_usage | wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            target("extra", EXTRA_FORMAT, colour_usage),
        ];
        let depth_stencil = target(
            "depth-stencil",
            context.formats.depth_stencil,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let view =
            |texture: &wgpu::Texture| texture.create_view(&wgpu::TextureViewDescriptor::default());
        let reflection_view = view(&textures[REFLECTION]);
        let reflection_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("membrane reflection"),
            layout: reflection_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&reflection_view),
            }],
        });
        let mut targets = FrameTargets {
            width,
            height,
            beauty_view: view(&textures[BEAUTY]),
            position_view: view(&textures[POSITION]),
            flags_view: view(&textures[FLAGS]),
            reflection_view,
            extra_view: view(&textures[EXTRA]),
            reflection_bind_group,
            depth_stencil_view: view(&depth_stencil),
            points: None,
            coverage_views: Vec::new(),
            textures,
            bytes_per_pixel: Vec::new(),
            readback: None,
            readback_offsets: Vec::new(),
        };
        if read_back {
            targets.make_readback(context);
        }
        targets
    }

    /// Adds the coverage targets a supersampled frame's resolve writes (and reads back).
    fn add_coverage(&mut self, context: &GpuContext) {
        for label in ["corner coverage", "edge coverage"] {
            let texture = context.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: self.width,
                    height: self.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: COVERAGE_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            self.coverage_views
                .push(texture.create_view(&wgpu::TextureViewDescriptor::default()));
            self.textures.push(texture);
        }
        self.make_readback(context);
    }

    /// The readback buffer of every texture, and each one's offset in it.
    fn make_readback(&mut self, context: &GpuContext) {
        self.bytes_per_pixel = self
            .textures
            .iter()
            .map(|texture| texture.format().block_copy_size(None).unwrap_or(16))
            .collect();
        self.readback_offsets = vec![0u64; self.textures.len()];
        let mut total = 0u64;
        for (offset, &bytes) in self.readback_offsets.iter_mut().zip(&self.bytes_per_pixel) {
            // Every region starts on a padded row, so the offsets keep the 256-byte alignment.
            *offset = total;
            total += padded_bytes_per_row(self.width, bytes) as u64 * self.height as u64;
        }
        self.readback = Some(context.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: total,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        }));
    }

    /// The resolve pass's bind group of these targets (a supersampled frame's points).
    fn resolve_bind_group(&self, context: &GpuContext, resolve: &Resolve) -> wgpu::BindGroup {
        let entry = |binding, view| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(view),
        };
        context
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("resolve"),
                layout: &resolve.layout,
                entries: &[
                    entry(4, &self.beauty_view),
                    entry(5, &self.position_view),
                    entry(6, &self.flags_view),
                    entry(7, &self.reflection_view),
                    entry(8, &self.extra_view),
                ],
            })
    }

    /// Copies the first `rows` rows of every attachment (all of them but in a frame's last,
    /// shorter strip) into the readback buffer.
    pub fn copy_to_readback(&self, encoder: &mut wgpu::CommandEncoder, rows: u32) {
        let Some(readback) = &self.readback else {
            return;
        };
        let size = wgpu::Extent3d {
            width: self.width,
            height: rows,
            depth_or_array_layers: 1,
        };
        for ((texture, &bytes_per_pixel), &offset) in self
            .textures
            .iter()
            .zip(&self.bytes_per_pixel)
            .zip(&self.readback_offsets)
        {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(padded_bytes_per_row(self.width, bytes_per_pixel)),
                        rows_per_image: Some(self.height),
                    },
                },
                size,
            );
        }
    }
}

/// Converts an IEEE half-float to f32 exactly (every half is representable in f32).
fn f16_bits_to_f32(bits: u16) -> f32 {
    let sign = if bits & 0x8000 != 0 { -1.0f32 } else { 1.0 };
    let exponent = (bits >> 10) & 0x1f;
    let mantissa = (bits & 0x3ff) as f32;
    match exponent {
        0 => sign * mantissa * (2.0f32).powi(-24),
        0x1f if mantissa == 0.0 => sign * f32::INFINITY,
        0x1f => f32::NAN,
        _ => sign * (1.0 + mantissa / 1024.0) * (2.0f32).powi(exponent as i32 - 15),
    }
}

/// Maps the readback buffer and unpacks its first `rows` rows (as [`FrameTargets::copy_to_readback`]
/// copied them).
pub(super) fn read_back(
    device: &wgpu::Device,
    targets: &FrameTargets,
    rows: u32,
) -> Result<RenderedFrame, GpuError> {
    let readback = targets
        .readback
        .as_ref()
        .ok_or_else(|| GpuError::Readback("these targets have no readback buffer".to_string()))?;
    let slice = readback.slice(..);
    let (sender, receiver) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |result| {
        // The receiver outlives the poll below; a failed send only means nobody is waiting.
        let _ = sender.send(result);
    });
    device.poll(wgpu::PollType::wait_indefinitely())?;
    receiver
        .recv()
        .map_err(|_| GpuError::Readback("the map callback never ran".to_string()))?
        .map_err(|error| GpuError::Readback(error.to_string()))?;
    let mapped = std::time::Instant::now();
    let frame = {
        let bytes = slice
            .get_mapped_range()
            .map_err(|error| GpuError::Readback(error.to_string()))?;
        unpack_frame(&bytes, targets, rows)
    };
    readback.unmap();
    log::debug!(
        "readback: unpacking {:.1} ms",
        mapped.elapsed().as_secs_f64() * 1e3
    );
    Ok(frame)
}

fn word(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

fn float(bytes: &[u8], at: usize) -> f32 {
    f32::from_bits(word(bytes, at))
}

/// The flags target holds the flag bits below this bit and the object index + 1 above it
/// (`flags_and_object` in shaders/common.inc.wgsl).
const OBJECT_SHIFT: u32 = 8;
/// Set in the flags target where the membrane is the first surface (`WATER_BIT` in
/// shaders/common.inc.wgsl); not one of the [`crate::draw::flag_bits`].
const WATER_BIT: u32 = 0x80;

/// Removes the row padding and converts every layer to the CPU types of [`RenderedFrame`].
/// Rows are converted in parallel (rayon) straight into preallocated layers: done on one thread
/// with a push per value, this was ~6.7 ms of a ~60 ms 1280x720 pool frame on the 2-core machine,
/// run while the rasteriser's threads sit idle.
fn unpack_frame(bytes: &[u8], targets: &FrameTargets, rows: u32) -> RenderedFrame {
    use rayon::prelude::*;
    let (width, height) = (targets.width as usize, rows as usize);
    let pixel_count = width * height;
    let mut frame = RenderedFrame {
        width: targets.width,
        height: rows,
        beauty_rgba: vec![[0.0; 4]; pixel_count],
        depth_m: vec![0.0; pixel_count],
        apparent_depth_m: vec![0.0; pixel_count],
        position: vec![[0.0; 3]; pixel_count],
        flags: vec![0; pixel_count],
        object: vec![0; pixel_count],
        water_matte: vec![0.0; pixel_count],
        water_reflection: vec![[0.0; 4]; pixel_count],
        motion_px: vec![[0.0; 2]; pixel_count],
        coverage: Vec::new(),
    };
    let row_of = |image: usize, y: usize| {
        let pitch = padded_bytes_per_row(targets.width, targets.bytes_per_pixel[image]) as usize;
        let start = targets.readback_offsets[image] as usize + y * pitch;
        &bytes[start..start + width * targets.bytes_per_pixel[image] as usize]
    };
    let half_beauty = targets.bytes_per_pixel[BEAUTY] == 8;
    frame
        .beauty_rgba
        .par_chunks_mut(width)
        .zip(frame.position.par_chunks_mut(width))
        .zip(frame.depth_m.par_chunks_mut(width))
        .zip(
            frame
                .apparent_depth_m
                .par_chunks_mut(width)
                .zip(frame.motion_px.par_chunks_mut(width)),
        )
        .zip(frame.flags.par_chunks_mut(width))
        .zip(frame.object.par_chunks_mut(width))
        .zip(frame.water_matte.par_chunks_mut(width))
        .zip(frame.water_reflection.par_chunks_mut(width))
        .enumerate()
        .for_each(
            |(
                y,
                (
                    ((((((beauty, position), depth), (apparent, motion)), flags), object), matte),
                    reflection,
                ),
            )| {
                let row = row_of(BEAUTY, y);
                if half_beauty {
                    for (out, pixel) in beauty.iter_mut().zip(row.chunks_exact(8)) {
                        *out = std::array::from_fn(|c| {
                            f16_bits_to_f32(u16::from_le_bytes([pixel[2 * c], pixel[2 * c + 1]]))
                        });
                    }
                } else {
                    for (out, pixel) in beauty.iter_mut().zip(row.chunks_exact(16)) {
                        *out = std::array::from_fn(|c| float(pixel, 4 * c));
                    }
                }
                for ((out, depth), pixel) in position
                    .iter_mut()
                    .zip(depth.iter_mut())
                    .zip(row_of(POSITION, y).chunks_exact(16))
                {
                    *out = std::array::from_fn(|c| float(pixel, 4 * c));
                    *depth = float(pixel, 12);
                }
                for ((apparent, motion), pixel) in apparent
                    .iter_mut()
                    .zip(motion.iter_mut())
                    .zip(row_of(EXTRA, y).chunks_exact(16))
                {
                    *motion = [float(pixel, 0), float(pixel, 4)];
                    *apparent = float(pixel, 12);
                }
                let reflections = row_of(REFLECTION, y).chunks_exact(16);
                for ((((flag, object), matte), reflection), (pixel, reflected)) in flags
                    .iter_mut()
                    .zip(object.iter_mut())
                    .zip(matte.iter_mut())
                    .zip(reflection.iter_mut())
                    .zip(row_of(FLAGS, y).chunks_exact(4).zip(reflections))
                {
                    let packed = word(pixel, 0);
                    *flag = packed & ((1 << OBJECT_SHIFT) - 1) & !WATER_BIT;
                    *object = packed >> OBJECT_SHIFT;
                    // The reflection target outside the stencil holds whatever an earlier
                    // frame left there: read only where the water is seen.
                    if packed & WATER_BIT != 0 {
                        *matte = 1.0;
                        *reflection = std::array::from_fn(|c| float(reflected, 4 * c));
                    }
                }
            },
        );
    if targets.textures.len() > EDGES {
        // The trapezoid rule's weights: corners 1/16, edge midpoints 1/8, the centre 1/4.
        frame.coverage = (0..pixel_count)
            .into_par_iter()
            .with_min_len(width)
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let words = |image: usize| {
                    let pixel = &row_of(image, y)[16 * x..16 * (x + 1)];
                    [0, 1, 2, 3].map(|k| word(pixel, 4 * k))
                };
                let centre = word(&row_of(EXTRA, y)[16 * x..16 * (x + 1)], 8);
                let mut points = Vec::with_capacity(9);
                points.extend(words(CORNERS).map(|w| (coverage_sample(w), 1.0 / 16.0)));
                points.extend(words(EDGES).map(|w| (coverage_sample(w), 1.0 / 8.0)));
                points.push((coverage_sample(centre), 1.0 / 4.0));
                crate::draw::coverage_ranks(&points)
            })
            .collect();
    }
    frame
}

/// One point's coverage word (`shaders/resolve.wgsl`): object + 1 in bits 16-31, bit 15 where
/// the water is the first surface, Schlick's F as a 15-bit fraction in bits 0-14.
fn coverage_sample(packed: u32) -> CoverageSample {
    CoverageSample {
        object: packed >> 16,
        water_reflectance: (packed & 0x8000 != 0).then(|| (packed & 0x7fff) as f32 / 32767.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    // 0.333251953125 is the exact value of half 0x3555; the shorter literal clippy wants hides that.
    #[allow(clippy::excessive_precision)]
    fn half_floats_convert_exactly() {
        assert_eq!(f16_bits_to_f32(0x3c00), 1.0);
        assert_eq!(f16_bits_to_f32(0xc000), -2.0);
        assert_eq!(f16_bits_to_f32(0x7bff), 65504.0);
        assert_eq!(f16_bits_to_f32(0x0001), 2.0f32.powi(-24));
        assert_eq!(f16_bits_to_f32(0x3555), 0.333251953125);
        assert_eq!(f16_bits_to_f32(0x7c00), f32::INFINITY);
        assert_eq!(f16_bits_to_f32(0xfc00), f32::NEG_INFINITY);
        assert!(f16_bits_to_f32(0x7e00).is_nan());
        assert_eq!(f16_bits_to_f32(0x0000), 0.0);
    }

    #[test]
    fn row_pitch_is_256_aligned() {
        assert_eq!(padded_bytes_per_row(1, 4), 256);
        assert_eq!(padded_bytes_per_row(64, 4), 256);
        assert_eq!(padded_bytes_per_row(65, 4), 512);
        assert_eq!(padded_bytes_per_row(1280, 16), 1280 * 16);
    }
}
