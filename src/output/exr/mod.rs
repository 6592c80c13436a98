//! One rendered frame as one OpenEXR file, laid out by the channel map ([`channels`], README
//! "The EXR channel map"): receives a [`RenderedFrame`] and its [`FrameMeta`] and writes
//! `DIR/<scene>.<frame>.exr` atomically; reads such a file back (this layout and the first one)
//! for snell's own tools and tests.
//!
//! Header: the layout attributes, OpenEXR's standard `screenWindowCenter`/`screenWindowWidth`,
//! `worldToCamera`, `worldToNDC`, `framesPerSecond`, `chromaticities`, `software` (and `owner`,
//! `capDate`/`utcOffset` when asked for), the Cryptomatte metadata, and snell's own:
//! `snell.frame` (int), `snell.timeSecs` (double), `snell.worldFromCamera` (m44f),
//! `snell.fovYDeg` (float), `snell.cameraEye|Target|Up` (v3f), `snell.clipNearM|FarM` (float:
//! the camera's clip planes, defaults when absent), `snell.method`, `snell.version`,
//! `snell.channelMap` (the map's version), `snell.objectNames` (JSON: the name of each
//! `IndexOB`), and each extra entry `k = v` as the string attribute `snell.extra.k`.
//!
//! Matrix convention: matrices are stored in Imath's layout (row vectors, translation in the last
//! row), which is the same 16 floats as glam's column-major `to_cols_array`.
//! `snell.worldFromCamera` maps snell's right-handed camera space (looking down -Z) to world;
//! `worldToCamera` follows the OpenEXR standard: left-handed camera space looking down +Z.

pub mod channels;
pub mod cli;
pub mod cryptomatte;
mod decode;
mod encode;
mod header;
mod zip;

use std::path::{Path, PathBuf};

use ::exr::compression::Compression;

use super::{write_unsynced, OutputError, Unsynced};
use crate::camera::Camera;
use crate::draw::{RenderedFrame, NO_OBJECT};
pub use decode::{read_channels, read_frame_and_channels, read_frame_exr};
use encode::{push_f16_all, push_f32, ChannelSource};

/// What the header records about a frame besides its pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMeta {
    pub scene_name: String,
    pub frame: u32,
    pub time_secs: f64,
    pub camera: Camera,
    /// The rendering method (e.g. "geometric" or "raytrace").
    pub method: String,
    /// snell's version, normally [`crate::VERSION`].
    pub version: String,
    /// The scene's frame rate (`framesPerSecond`).
    pub fps: f64,
    /// Names of the scene's objects by [`RenderedFrame::object`] id: `object_names[k]` is id
    /// `k + 1`. The Cryptomatte manifest holds these and the water surface's name.
    pub object_names: Vec<String>,
    /// `owner`, written when set.
    pub owner: Option<String>,
    /// `capDate` (and `utcOffset` 0), written when set: a Unix time, normally
    /// `SOURCE_DATE_EPOCH`'s, so that frames stay reproducible.
    pub capture_unix_secs: Option<i64>,
    /// Further text attributes, written as `snell.extra.<key>`.
    pub extra: Vec<(String, String)>,
    /// How the frame is stored (`--half`, `--compression`).
    pub write: WriteOptions,
}

/// How a frame's pixels are stored: the beauty's sample type, the file's compression and which
/// layers it holds. Every other layer stays float32 (or half for the 0/1 masks) whatever the
/// choice: half-float `P` would step 4 mm at 4 m, about a pixel at 720p. Recorded in the header
/// (`compression`, and `snell.output`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// `R, G, B, A` as half floats (the VFX default; about 3 significant digits; brighter values
    /// than 65504 saturate there).
    pub half_beauty: bool,
    pub compression: ExrCompression,
    /// The layers written (`--layers`; every one by default).
    pub layers: channels::LayerSet,
}

/// The lossless compressions a frame may be written with (one for the whole file). OpenEXR's lossy
/// DWAA and DWAB, which would suit the beauty only, are not offered: the `exr` crate snell writes
/// with cannot encode them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ExrCompression {
    /// Deflate over blocks of 16 scan lines: compact on smooth float data.
    #[default]
    Zip,
    /// Deflate per scan line: larger files, reads one line at a time.
    Zips,
    /// Wavelet and Huffman: often the smallest for noisy float images.
    Piz,
    /// Run-length: fast, good only on flat areas.
    Rle,
    /// Uncompressed: the fastest to write, the largest files.
    None,
}

impl ExrCompression {
    pub const ALL: [ExrCompression; 5] = [Self::Zip, Self::Zips, Self::Piz, Self::Rle, Self::None];

    /// The name `--compression` takes and the header's `snell.output` gives.
    pub fn name(self) -> &'static str {
        match self {
            Self::Zip => "zip",
            Self::Zips => "zips",
            Self::Piz => "piz",
            Self::Rle => "rle",
            Self::None => "none",
        }
    }

    fn codec(self) -> Compression {
        match self {
            Self::Zip => Compression::ZIP16,
            Self::Zips => Compression::ZIP1,
            Self::Piz => Compression::PIZ,
            Self::Rle => Compression::RLE,
            Self::None => Compression::Uncompressed,
        }
    }
}

impl WriteOptions {
    /// `beauty=float32 compression=zip layers=all`: the header's `snell.output`.
    pub fn label(&self) -> String {
        let beauty = if self.half_beauty { "half" } else { "float32" };
        format!(
            "beauty={beauty} compression={} layers={}",
            self.compression.name(),
            self.layers.label()
        )
    }

    /// Reads [`Self::label`] back (the header's `snell.output`); `None` if it is not one.
    pub fn from_label(label: &str) -> Option<WriteOptions> {
        let mut words = label.split(' ');
        let half_beauty = match words.next()?.strip_prefix("beauty=")? {
            "half" => true,
            "float32" => false,
            _ => return None,
        };
        let compression = words.next()?.strip_prefix("compression=")?;
        let compression = ExrCompression::ALL
            .into_iter()
            .find(|kind| kind.name() == compression)?;
        let (layers, _) = channels::LayerSet::parse(words.next()?.strip_prefix("layers=")?).ok()?;
        words.next().is_none().then_some(WriteOptions {
            half_beauty,
            compression,
            layers,
        })
    }
}

/// The header of a frame read back by [`read_frame_exr`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReadMeta {
    pub frame: u32,
    pub time_secs: f64,
    pub camera: Camera,
    /// `snell.worldFromCamera` as written (Imath layout = glam column-major).
    pub world_from_camera: [f32; 16],
    /// The standard `worldToCamera` (left-handed, +Z forward), if present.
    pub world_to_camera_standard: Option<[f32; 16]>,
    pub method: String,
    pub version: String,
    /// `snell.channelMap`; `None` for the first layout.
    pub channel_map: Option<String>,
    /// `snell.objectNames`; empty for the first layout.
    pub object_names: Vec<String>,
    /// The `snell.extra.*` attributes with the prefix removed, sorted by key.
    pub text_attributes: Vec<(String, String)>,
    /// The channels the file holds, sorted (a frame written with `--layers` lacks some).
    pub channels: Vec<String>,
    /// How the frame was stored, from `snell.output`; the default (every layer, float32 beauty,
    /// zip) for frames written before it existed, which held every layer.
    pub write: WriteOptions,
}

impl FrameMeta {
    /// The metadata of a frame read back, to write it again (tools and tests that edit frames).
    pub fn from_read(read: &ReadMeta, scene_name: &str) -> FrameMeta {
        FrameMeta {
            scene_name: scene_name.to_string(),
            frame: read.frame,
            time_secs: read.time_secs,
            camera: read.camera,
            method: read.method.clone(),
            version: read.version.clone(),
            fps: 24.0,
            object_names: read.object_names.clone(),
            owner: None,
            capture_unix_secs: None,
            extra: read.text_attributes.clone(),
            write: read.write,
        }
    }
}

/// `DIR/<scene>.<frame, at least 4 digits>.exr`.
pub fn frame_path(dir: &Path, scene_name: &str, frame: u32) -> PathBuf {
    crate::output::pattern::OutputPattern::for_scene(dir, scene_name).path(frame)
}

/// Checks that every layer holds one value per pixel; the optional layers may be empty (a frame
/// read from a file written before they existed, or without them), and are then not written.
/// `Z`, `P` and the flags may be empty only where `layers` leaves them out.
fn check_frame_shape(frame: &RenderedFrame, layers: channels::LayerSet) -> Result<usize, String> {
    use channels::Layer;
    if frame.width == 0 || frame.height == 0 {
        return Err(format!("frame is empty ({}x{})", frame.width, frame.height));
    }
    let pixel_count = frame.pixel_count();
    let lengths = [
        ("beauty_rgba", frame.beauty_rgba.len(), false),
        ("depth_m", frame.depth_m.len(), !layers.has(Layer::Depth)),
        (
            "position",
            frame.position.len(),
            !layers.has(Layer::Position),
        ),
        (
            "flags",
            frame.flags.len(),
            !FLAG_CHANNELS_LAYERS.iter().any(|&layer| layers.has(layer)),
        ),
        ("apparent_depth_m", frame.apparent_depth_m.len(), true),
        ("object", frame.object.len(), true),
        ("water_matte", frame.water_matte.len(), true),
        ("water_reflection", frame.water_reflection.len(), true),
    ];
    for (name, length, optional) in lengths {
        if length != pixel_count && !(optional && length == 0) {
            return Err(format!(
                "frame buffer `{name}` holds {length} pixels but the frame is {}x{} = {pixel_count}",
                frame.width, frame.height
            ));
        }
    }
    if frame.water_matte.is_empty() && !frame.water_reflection.is_empty() {
        return Err("frame buffer `water_reflection` is given without `water_matte`".into());
    }
    Ok(pixel_count)
}

/// The flag layers, in [`channels::FLAG_CHANNELS`]' order.
const FLAG_CHANNELS_LAYERS: [channels::Layer; 4] = [
    channels::Layer::FlagConvergence,
    channels::Layer::FlagBoundary,
    channels::Layer::FlagPopping,
    channels::Layer::FlagExtrapolated,
];

/// The largest finite half float: a half beauty saturates there.
const HALF_MAX: f32 = 65504.0;

/// The channels of a frame, by the channel map.
fn frame_channels<'a>(
    frame: &'a RenderedFrame,
    crypto_ids: &'a [f32],
    water_id: f32,
    write: &WriteOptions,
) -> Vec<ChannelSource<'a>> {
    use channels::*;
    let half_beauty = write.half_beauty;
    let has = |layer: Layer| write.layers.has(layer);
    let width = frame.width as usize;
    let row = move |y: usize| y * width..(y + 1) * width;
    let mut list = Vec::new();
    for (c, name) in BEAUTY.into_iter().enumerate() {
        list.push(if half_beauty {
            // Saturated at the largest half (65504) rather than made infinite.
            ChannelSource::f16(name, move |y, out| {
                push_f16_all(
                    out,
                    frame.beauty_rgba[row(y)].iter().map(|p| p[c].min(HALF_MAX)),
                )
            })
        } else {
            ChannelSource::f32(name, move |y, out| {
                frame.beauty_rgba[row(y)]
                    .iter()
                    .for_each(|p| push_f32(out, p[c]))
            })
        });
    }
    if has(Layer::Depth) {
        list.push(ChannelSource::f32(DEPTH, move |y, out| {
            frame.depth_m[row(y)].iter().for_each(|&d| push_f32(out, d))
        }));
    }
    for (c, name) in POSITION
        .into_iter()
        .enumerate()
        .filter(|_| has(Layer::Position))
    {
        list.push(ChannelSource::f32(name, move |y, out| {
            frame.position[row(y)]
                .iter()
                .for_each(|p| push_f32(out, p[c]))
        }));
    }
    for (name, bit) in FLAG_CHANNELS
        .into_iter()
        .filter(|&(_, bit)| has(Layer::of_flag(bit)))
    {
        list.push(ChannelSource::f16(name, move |y, out| {
            push_f16_all(
                out,
                frame.flags[row(y)]
                    .iter()
                    .map(|f| if f & bit != 0 { 1.0 } else { 0.0 }),
            )
        }));
    }
    if !frame.apparent_depth_m.is_empty() && has(Layer::ApparentDepth) {
        list.push(ChannelSource::f32(APPARENT_DEPTH, move |y, out| {
            frame.apparent_depth_m[row(y)]
                .iter()
                .for_each(|&d| push_f32(out, d))
        }));
    }
    for (c, name) in MOTION
        .into_iter()
        .enumerate()
        .filter(|_| !frame.motion_px.is_empty() && has(Layer::Motion))
    {
        list.push(ChannelSource::f32(name, move |y, out| {
            frame.motion_px[row(y)]
                .iter()
                .for_each(|m| push_f32(out, m[c]))
        }));
    }
    if !frame.object.is_empty() && has(Layer::IndexOb) {
        list.push(ChannelSource::f32(INDEX_OB, move |y, out| {
            frame.object[row(y)]
                .iter()
                .for_each(|&id| push_f32(out, id as f32))
        }));
    }
    let has_water = !frame.water_matte.is_empty();
    if has_water && has(Layer::WaterMatte) {
        list.push(ChannelSource::f16(WATER_MATTE, move |y, out| {
            push_f16_all(out, frame.water_matte[row(y)].iter().copied())
        }));
    }
    // The effects: what is seen without the water, the refracted share, the reflected sky (not
    // for a frame read from the first layout, which did not keep the reflection).
    let has_split = !frame.water_reflection.is_empty();
    if has_split {
        let is_water = move |i: usize| frame.water_matte[i] > 0.5;
        for (c, name) in DIRECT
            .into_iter()
            .enumerate()
            .filter(|_| has(Layer::Direct))
        {
            list.push(ChannelSource::f32(name, move |y, out| {
                for i in row(y) {
                    push_f32(
                        out,
                        if is_water(i) {
                            0.0
                        } else {
                            frame.beauty_rgba[i][c]
                        },
                    );
                }
            }));
        }
        for (c, name) in REFRACTION
            .into_iter()
            .enumerate()
            .filter(|_| has(Layer::Refraction))
        {
            list.push(ChannelSource::f32(name, move |y, out| {
                for i in row(y) {
                    let refracted = frame.beauty_rgba[i][c] - frame.water_reflection[i][c];
                    push_f32(out, if is_water(i) { refracted } else { 0.0 });
                }
            }));
        }
        for (c, name) in SKY_REFLECTION
            .into_iter()
            .enumerate()
            .filter(|_| has(Layer::SkyReflection))
        {
            list.push(ChannelSource::f32(name, move |y, out| {
                for i in row(y) {
                    let reflected = frame.water_reflection[i][c];
                    push_f32(out, if is_water(i) { reflected } else { 0.0 });
                }
            }));
        }
    }
    if !frame.object.is_empty() && has(Layer::CryptoObject) {
        let from_samples = move |i: usize| {
            let mut ranks = [(0.0, 0.0); CRYPTO_RANKS];
            for (rank, share) in ranks.iter_mut().zip(&frame.coverage[i]) {
                let id = match share.key {
                    crate::draw::COVERAGE_WATER => Some(water_id),
                    NO_OBJECT => None,
                    object => crypto_ids.get(object as usize - 1).copied(),
                };
                if let Some(id) = id {
                    *rank = (id, share.coverage);
                }
            }
            ranks
        };
        let ranks = move |i: usize| {
            if !frame.coverage.is_empty() {
                return from_samples(i);
            }
            let object = frame.object[i];
            let object = (object != NO_OBJECT)
                .then(|| crypto_ids.get(object as usize - 1).copied())
                .flatten();
            let water = (has_split && frame.water_matte[i] > 0.5)
                .then(|| (water_id, frame.water_reflection[i][3]));
            cryptomatte::pixel_ranks(object, water)
        };
        for (rank, (id_name, coverage_name)) in crypto_rank_channels().into_iter().enumerate() {
            list.push(ChannelSource::f32(id_name, move |y, out| {
                row(y).for_each(|i| push_f32(out, ranks(i)[rank].0))
            }));
            list.push(ChannelSource::f32(coverage_name, move |y, out| {
                row(y).for_each(|i| push_f32(out, ranks(i)[rank].1))
            }));
        }
    }
    list
}

/// The values of `frame`'s channels whose names `wanted` accepts, as [`write_frame_exr`] would store
/// them with `write` (half samples rounded as the file holds them), for rows `rows`: each channel's
/// name and its samples, row after row. The one mapping from a frame to its channels, for readers
/// that need a file's values without a file (the preview's inspector and layer views).
pub fn channel_values(
    frame: &RenderedFrame,
    object_names: &[String],
    write: &WriteOptions,
    rows: std::ops::Range<usize>,
    wanted: impl Fn(&str) -> bool,
) -> Vec<(String, Vec<f32>)> {
    let water_id = cryptomatte::id_float(&cryptomatte::water_name(object_names));
    let crypto_ids: Vec<f32> = object_names
        .iter()
        .map(|name| cryptomatte::id_float(name))
        .collect();
    let mut bytes = Vec::new();
    frame_channels(frame, &crypto_ids, water_id, write)
        .into_iter()
        .filter(|channel| wanted(&channel.name))
        .map(|channel| {
            let mut values = Vec::with_capacity(rows.len() * frame.width as usize);
            for y in rows.clone() {
                bytes.clear();
                (channel.fill)(y, &mut bytes);
                match channel.sample_type {
                    ::exr::meta::attribute::SampleType::F16 => {
                        values.extend(bytes.chunks_exact(2).map(|b| {
                            ::exr::prelude::f16::from_bits(u16::from_ne_bytes([b[0], b[1]]))
                                .to_f32()
                        }))
                    }
                    _ => values.extend(
                        bytes
                            .chunks_exact(4)
                            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
                    ),
                }
            }
            (channel.name, values)
        })
        .collect()
}

/// A frame's EXR file written strip by strip (bands of rows, top first), as the renderer reads
/// them back: the header from the first strip's layers, then each strip's chunks. The file's
/// bytes are the same however the frame is cut into strips.
pub struct FrameStream<W: std::io::Write + std::io::Seek> {
    stream: encode::ChunkStream<W>,
    crypto_ids: Vec<f32>,
    water_id: f32,
    write: WriteOptions,
    object_count: usize,
    width: u32,
}

impl<W: std::io::Write + std::io::Seek> FrameStream<W> {
    /// Writes the header of a `width` x `height` frame of `meta` whose layers are those of
    /// `first_strip` (its first strip, not yet written).
    pub fn start(
        out: W,
        meta: &FrameMeta,
        width: u32,
        height: u32,
        first_strip: &RenderedFrame,
    ) -> Result<Self, String> {
        let water_name = cryptomatte::water_name(&meta.object_names);
        let crypto_ids: Vec<f32> = meta
            .object_names
            .iter()
            .map(|name| cryptomatte::id_float(name))
            .collect();
        let mut crypto_names = meta.object_names.clone();
        crypto_names.push(water_name.clone());
        let spec = encode::FileSpec {
            width: width as usize,
            height: height as usize,
            compression: meta.write.compression.codec(),
            attributes: header::attributes(meta, width as usize, height as usize, &crypto_names)?,
        };
        let water_id = cryptomatte::id_float(&water_name);
        let channels = frame_channels(first_strip, &crypto_ids, water_id, &meta.write);
        let stream = encode::ChunkStream::start(out, &spec, &channels)?;
        drop(channels);
        Ok(FrameStream {
            stream,
            crypto_ids,
            water_id,
            write: meta.write,
            object_count: meta.object_names.len(),
            width,
        })
    }

    /// Writes `strip`, the frame's rows from `first_row` on (the next ones; a whole number of the
    /// compression's chunks unless it ends the frame).
    pub fn write_strip(&mut self, first_row: u32, strip: &RenderedFrame) -> Result<(), String> {
        check_frame_shape(strip, self.write.layers)?;
        if strip.width != self.width {
            return Err(format!(
                "a strip is {} pixels wide, the frame {}",
                strip.width, self.width
            ));
        }
        if let Some(&id) = strip
            .object
            .iter()
            .find(|&&id| id as usize > self.object_count)
        {
            return Err(format!(
                "object id {id} has no name (the frame names {} objects)",
                self.object_count
            ));
        }
        let channels = frame_channels(strip, &self.crypto_ids, self.water_id, &self.write);
        self.stream
            .write_rows(first_row as usize, strip.height as usize, channels)
    }

    /// Completes the file once every row is written; returns the output.
    pub fn finish(self) -> Result<W, String> {
        self.stream.finish()
    }
}

/// Writes one frame to `path` (normally [`frame_path`]) via a temporary file in the same directory,
/// synced and renamed; creates the directory if needed. On error nothing is left at `path` that was
/// not there before, and the temporary file is removed.
pub fn write_frame_exr(
    path: &Path,
    frame: &RenderedFrame,
    meta: &FrameMeta,
) -> Result<(), OutputError> {
    let mut whole = Some(frame);
    write_frame_exr_strips(path, meta, frame.width, frame.height, || {
        Ok(whole
            .take()
            .map(|frame| (0, std::borrow::Cow::Borrowed(frame))))
    })
}

/// Writes a `width` x `height` frame to `path` as [`write_frame_exr`] does, from the strips
/// `next_strip` gives (each with the frame row it starts at, top first; `None` after the last),
/// each written as it comes: only one strip of the frame is held here at a time. An error from
/// `next_strip` (the render stopped) or a frame left incomplete leaves nothing at `path`.
pub fn write_frame_exr_strips<'f>(
    path: &Path,
    meta: &FrameMeta,
    width: u32,
    height: u32,
    next_strip: impl FnMut() -> Result<Option<(u32, std::borrow::Cow<'f, RenderedFrame>)>, String>,
) -> Result<(), OutputError> {
    write_frame_exr_unsynced(path, meta, width, height, next_strip)?.commit()
}

/// [`write_frame_exr_strips`] but for the sync and rename, which [`Unsynced::commit`] does (on
/// another thread, for the sequence writer).
pub(crate) fn write_frame_exr_unsynced<'f>(
    path: &Path,
    meta: &FrameMeta,
    width: u32,
    height: u32,
    mut next_strip: impl FnMut() -> Result<Option<(u32, std::borrow::Cow<'f, RenderedFrame>)>, String>,
) -> Result<Unsynced, OutputError> {
    // Chunks are compressed in parallel (ZIP dominates the cost of a frame) and written in order,
    // so the bytes do not depend on thread timing.
    write_unsynced(path, |file| {
        let Some((first_row, first)) = next_strip()? else {
            return Err("the frame has no rows".to_string());
        };
        let mut stream = FrameStream::start(
            std::io::BufWriter::new(&mut *file),
            meta,
            width,
            height,
            &first,
        )?;
        stream.write_strip(first_row, &first)?;
        drop(first);
        while let Some((first_row, strip)) = next_strip()? {
            stream.write_strip(first_row, &strip)?;
        }
        stream
            .finish()?
            .into_inner()
            .map_err(|error| error.error().to_string())?;
        Ok(())
    })
}

#[cfg(test)]
mod tests;
