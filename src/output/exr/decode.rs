//! Reading frames back: the channel map's layout and the first layout (`flags.*`, u32 `object`,
//! `Z` as the distance from the eye with +inf for sky, NaN `P` for sky), both into the same
//! [`RenderedFrame`], so frames of either age compare with each other.

use std::collections::BTreeMap;
use std::path::Path;

use ::exr::prelude::{AttributeValue, FlatSamples, ReadChannels, ReadLayers};
use glam::{Vec2, Vec3};

use super::channels::{self, legacy, SKY_DEPTH_M};
use super::header::{self, text};
use super::{OutputError, ReadMeta};
use crate::camera::Camera;
use crate::draw::RenderedFrame;

/// Every channel of an EXR file (all parts) as float32 values, with the attributes of its first
/// part: for tools and tests that look at layers by name.
pub struct ExrChannels {
    pub width: usize,
    pub height: usize,
    pub channels: BTreeMap<String, Vec<f32>>,
    /// The sample type of each channel: "f16", "f32" or "u32".
    pub types: BTreeMap<String, &'static str>,
    pub attributes: ::exr::meta::header::LayerAttributes,
}

impl ExrChannels {
    pub fn get(&self, name: &str) -> Option<&[f32]> {
        self.channels.get(name).map(Vec::as_slice)
    }
}

/// An EXR file's every part, channel and attribute.
type AnyImage =
    ::exr::prelude::Image<::exr::prelude::Layers<::exr::prelude::AnyChannels<FlatSamples>>>;

fn read_error_of(path: &Path) -> impl Fn(String) -> OutputError + '_ {
    move |cause| OutputError::Read {
        path: path.to_path_buf(),
        cause,
    }
}

/// The largest EXR file read (a 16K x 16K frame of every layer, uncompressed, is under 12 GiB).
const MAX_EXR_BYTES: u64 = 16 << 30;

/// Reads all of `path` (the largest level, no deep data); an error if it has no image part.
fn read_image(path: &Path) -> Result<AnyImage, OutputError> {
    let read_error = read_error_of(path);
    // A FIFO or a device given as a frame would block or never end: only regular files are read.
    let file =
        crate::files::open_regular(path, MAX_EXR_BYTES).map_err(|e| read_error(e.to_string()))?;
    let image = ::exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::BufReader::new(file))
        .map_err(|error| read_error(format!("OpenEXR decoding: {error}")))?;
    if image.layer_data.is_empty() {
        return Err(read_error("the file has no image part".into()));
    }
    Ok(image)
}

/// Reads every channel of `path` as float32 (u32 samples converted exactly up to 2^24).
pub fn read_channels(path: &Path) -> Result<ExrChannels, OutputError> {
    channels_of(path, &read_image(path)?)
}

/// [`read_frame_exr`] and [`read_channels`] of one file from a single read and decoding of it
/// (the preview's `--frames-dir` wants both).
pub fn read_frame_and_channels(
    path: &Path,
) -> Result<(RenderedFrame, ReadMeta, ExrChannels), OutputError> {
    let image = read_image(path)?;
    let channels = channels_of(path, &image)?;
    let (frame, meta) = frame_of(path, &image)?;
    Ok((frame, meta, channels))
}

/// [`read_channels`] of `image`, read from `path`.
fn channels_of(path: &Path, image: &AnyImage) -> Result<ExrChannels, OutputError> {
    let read_error = read_error_of(path);
    let first = &image.layer_data[0];
    let (width, height) = (first.size.width(), first.size.height());
    let mut channels = BTreeMap::new();
    let mut types = BTreeMap::new();
    for layer in &image.layer_data {
        if (layer.size.width(), layer.size.height()) != (width, height) {
            return Err(read_error("the file's parts differ in size".into()));
        }
        for channel in &layer.channel_data.list {
            let (values, kind): (Vec<f32>, _) = match &channel.sample_data {
                FlatSamples::F16(values) => (values.iter().map(|v| v.to_f32()).collect(), "f16"),
                FlatSamples::F32(values) => (values.clone(), "f32"),
                FlatSamples::U32(values) => (values.iter().map(|&v| v as f32).collect(), "u32"),
            };
            let name = channel.name.to_string();
            types.insert(name.clone(), kind);
            channels.insert(name, values);
        }
    }
    Ok(ExrChannels {
        width,
        height,
        channels,
        types,
        attributes: first.attributes.clone(),
    })
}

/// Reads a frame written by [`super::write_frame_exr`] (or by snell before the channel map):
/// pixels and the snell header attributes. `flags` comes back as the four flag bits of the flag
/// channels. From the first layout, `Z` is converted to depth along the view axis and sky to
/// [`SKY_DEPTH_M`], NaN positions to 0, the water matte is derived from `Z` and `P` as the first
/// layout allowed, and the other layers it did not have come back empty. A layer `--layers` left
/// out comes back empty too (only the beauty is always there); [`ReadMeta::channels`] lists what
/// the file holds.
pub fn read_frame_exr(path: &Path) -> Result<(RenderedFrame, ReadMeta), OutputError> {
    frame_of(path, &read_image(path)?)
}

/// [`read_frame_exr`] of `image`, read from `path`.
fn frame_of(path: &Path, image: &AnyImage) -> Result<(RenderedFrame, ReadMeta), OutputError> {
    let read_error = read_error_of(path);
    // u32 channels must stay exact (the first layout's object ids): read them apart.
    let first = &image.layer_data[0];
    let (width, height) = (first.size.width(), first.size.height());
    let pixel_count = width * height;
    let find = |name: &str| {
        image
            .layer_data
            .iter()
            .flat_map(|layer| layer.channel_data.list.iter())
            .find(|channel| channel.name == *name)
            .map(|channel| &channel.sample_data)
    };
    let floats = |name: &str| -> Result<Option<Vec<f32>>, OutputError> {
        match find(name) {
            None => Ok(None),
            Some(FlatSamples::F32(values)) => Ok(Some(values.clone())),
            Some(FlatSamples::F16(values)) => Ok(Some(values.iter().map(|v| v.to_f32()).collect())),
            Some(FlatSamples::U32(_)) => Err(read_error(format!(
                "channel `{name}` is 32-bit unsigned, not float"
            ))),
        }
    };
    let required = |name: &str| {
        floats(name)?.ok_or_else(|| read_error(format!("channel `{name}` is missing")))
    };
    let mut meta = read_meta(&first.attributes, &read_error)?;
    meta.channels = image
        .layer_data
        .iter()
        .flat_map(|layer| layer.channel_data.list.iter())
        .map(|channel| channel.name.to_string())
        .collect();
    meta.channels.sort();
    let legacy_layout = meta.channel_map.is_none();
    let flag_channels = if legacy_layout {
        legacy::FLAG_CHANNELS
    } else {
        channels::FLAG_CHANNELS
    };

    let [r, g, b, a] = channels::BEAUTY.map(required);
    let (r, g, b, a) = (r?, g?, b?, a?);
    // The first layout had every layer; the map's frames hold those `--layers` chose: a layer
    // left out comes back empty (the flags: when none of their layers is there).
    let layer = |name: &str| {
        if legacy_layout {
            required(name).map(Some)
        } else {
            floats(name)
        }
    };
    let [px, py, pz] = channels::POSITION.map(layer);
    let mut position: Vec<[f32; 3]> = match (px?, py?, pz?) {
        (Some(px), Some(py), Some(pz)) => (0..pixel_count).map(|i| [px[i], py[i], pz[i]]).collect(),
        (None, None, None) => Vec::new(),
        _ => {
            return Err(read_error(
                "the layer `P` lacks some of `P.X, P.Y, P.Z`".into(),
            ))
        }
    };
    let mut depth_m = layer(channels::DEPTH)?.unwrap_or_default();
    let mut flags = vec![0u32; pixel_count];
    let mut any_flag = false;
    for (name, bit) in flag_channels {
        let Some(values) = layer(name)? else { continue };
        any_flag = true;
        for (flags, value) in flags.iter_mut().zip(values) {
            if value != 0.0 {
                *flags |= bit;
            }
        }
    }
    if !any_flag {
        flags.clear();
    }
    let object = if legacy_layout {
        match find(legacy::OBJECT) {
            Some(FlatSamples::U32(values)) => values.clone(),
            Some(_) => {
                return Err(read_error(format!(
                    "channel `{}` is not 32-bit unsigned",
                    legacy::OBJECT
                )))
            }
            None => Vec::new(),
        }
    } else {
        match floats(channels::INDEX_OB)? {
            None => Vec::new(),
            Some(values) => values
                .into_iter()
                .map(|v| {
                    // Indices are small integers, exact in float32.
                    if v >= 0.0 && v.fract() == 0.0 && v < 16_777_216.0 {
                        Ok(v as u32)
                    } else {
                        Err(read_error(format!(
                            "channel `{}` holds {v}, not an object index",
                            channels::INDEX_OB
                        )))
                    }
                })
                .collect::<Result<_, _>>()?,
        }
    };
    // The first layout had no water matte: a pixel saw the water when its first surface (`Z`, then
    // the distance from the eye) was nearer than what it showed (`P`, NaN where nothing was behind
    // the water). Sight rays meeting an object directly give the same distance to rounding; a ray
    // through the water goes on at least millimetres under it.
    let legacy_water_matte: Vec<f32> = if legacy_layout {
        depth_m
            .iter()
            .zip(&position)
            .map(|(&distance, &p)| {
                let p = Vec3::from(p);
                let water = distance.is_finite()
                    && (!p.is_finite()
                        || (p - meta.camera.eye).length() > distance * (1.0 + 1e-4) + 1e-3);
                f32::from(u8::from(water))
            })
            .collect()
    } else {
        Vec::new()
    };
    if legacy_layout {
        // Distance from the eye -> depth along the view axis; nothing seen -> the map's values.
        let rays = meta.camera.pixel_rays(width as u32, height as u32);
        let forward = meta.camera.forward();
        for (i, depth) in depth_m.iter_mut().enumerate() {
            *depth = if depth.is_finite() {
                let pixel = Vec2::new((i % width) as f32 + 0.5, (i / width) as f32 + 0.5);
                *depth * rays.direction(pixel).dot(forward)
            } else {
                SKY_DEPTH_M
            };
        }
        for p in &mut position {
            if !Vec3::from(*p).is_finite() {
                *p = [0.0; 3];
            }
        }
    }
    let apparent_depth_m = floats(channels::APPARENT_DEPTH)?.unwrap_or_default();
    let [mx, my] = channels::MOTION.map(floats);
    let motion_px = match (mx?, my?) {
        (Some(mx), Some(my)) => mx.into_iter().zip(my).map(|(x, y)| [x, y]).collect(),
        _ => Vec::new(),
    };
    let water_matte = match floats(channels::WATER_MATTE)? {
        Some(matte) => matte,
        None => legacy_water_matte,
    };
    // A frame written from one read in the first layout has a water matte but no sky reflection.
    let [sr, sg, sb] = channels::SKY_REFLECTION.map(floats);
    let water_reflection = match (sr?, sg?, sb?) {
        (Some(sr), Some(sg), Some(sb)) if !water_matte.is_empty() => {
            match water_reflectance(image, &meta, &water_matte) {
                Some(reflectance) => (0..pixel_count)
                    .map(|i| [sr[i], sg[i], sb[i], reflectance[i]])
                    .collect(),
                None => Vec::new(),
            }
        }
        _ => Vec::new(),
    };
    let frame = RenderedFrame {
        width: width as u32,
        height: height as u32,
        beauty_rgba: (0..pixel_count).map(|i| [r[i], g[i], b[i], a[i]]).collect(),
        depth_m,
        apparent_depth_m,
        position,
        flags,
        object,
        water_matte,
        water_reflection,
        motion_px,
        // The file keeps the ranks, not the samples they were counted from.
        coverage: Vec::new(),
    };
    Ok((frame, meta))
}

/// Schlick's F per water pixel: the Cryptomatte coverage of the water's ID (0 elsewhere). Where
/// nothing is behind the water that coverage is 1, not F: the file keeps F only where an object
/// shares the pixel; and in an anti-aliased frame it is the water's share counted over the
/// pixel's samples, which is F only where every sample sees the water. `None` for a file without the Cryptomatte (written from a frame without an
/// object layer).
fn water_reflectance(image: &AnyImage, meta: &ReadMeta, water_matte: &[f32]) -> Option<Vec<f32>> {
    let water_id =
        super::cryptomatte::id_float(&super::cryptomatte::water_name(&meta.object_names));
    let find = |name: &str| {
        image
            .layer_data
            .iter()
            .flat_map(|layer| layer.channel_data.list.iter())
            .find(|channel| channel.name == *name)
            .and_then(|channel| match &channel.sample_data {
                FlatSamples::F32(values) => Some(values),
                _ => None,
            })
    };
    let mut reflectance = vec![0.0f32; water_matte.len()];
    for (id_name, coverage_name) in channels::crypto_rank_channels() {
        let (Some(ids), Some(coverages)) = (find(&id_name), find(&coverage_name)) else {
            return None;
        };
        for i in 0..reflectance.len() {
            if water_matte[i] > 0.5 && ids[i].to_bits() == water_id.to_bits() {
                reflectance[i] = coverages[i];
            }
        }
    }
    Some(reflectance)
}

/// An attribute's text as UTF-8 (what snell writes; other bytes are replaced).
pub(super) fn text_string(value: &::exr::meta::attribute::Text) -> String {
    String::from_utf8_lossy(value.as_slice()).into_owned()
}

fn read_meta(
    attributes: &::exr::meta::header::LayerAttributes,
    read_error: &impl Fn(String) -> OutputError,
) -> Result<ReadMeta, OutputError> {
    let attribute = |name: &str| {
        attributes
            .other
            .get(&text(name))
            .ok_or_else(|| read_error(format!("header attribute `{name}` is missing")))
    };
    let mismatch =
        |name: &str| read_error(format!("header attribute `{name}` has an unexpected type"));
    let string_attribute = |name: &str| match attribute(name)? {
        AttributeValue::Text(value) => Ok(text_string(value)),
        _ => Err(mismatch(name)),
    };
    let vec3_attribute = |name: &str| match attribute(name)? {
        AttributeValue::FloatVec3((x, y, z)) => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(mismatch(name)),
    };
    let frame = match attribute(header::FRAME)? {
        AttributeValue::I32(value) => u32::try_from(*value).map_err(|_| mismatch(header::FRAME))?,
        _ => return Err(mismatch(header::FRAME)),
    };
    let time_secs = match attribute(header::TIME_SECS)? {
        AttributeValue::F64(value) => *value,
        _ => return Err(mismatch(header::TIME_SECS)),
    };
    let world_from_camera = match attribute(header::WORLD_FROM_CAMERA)? {
        AttributeValue::Matrix4x4(value) => *value,
        _ => return Err(mismatch(header::WORLD_FROM_CAMERA)),
    };
    let fov_y_deg = match attribute(header::FOV_Y_DEG)? {
        AttributeValue::F32(value) => *value,
        _ => return Err(mismatch(header::FOV_Y_DEG)),
    };
    // Frames written before cameras had their own clip planes used the defaults.
    let clip_plane = |name: &str, default: f32| match attributes.other.get(&text(name)) {
        None => Ok(default),
        Some(AttributeValue::F32(value)) => Ok(*value),
        Some(_) => Err(mismatch(name)),
    };
    let near_m = clip_plane(header::CLIP_NEAR_M, crate::camera::NEAR_M)?;
    let far_m = clip_plane(header::CLIP_FAR_M, crate::camera::FAR_M)?;
    let channel_map = match attributes.other.get(&text(header::CHANNEL_MAP)) {
        None => None,
        Some(AttributeValue::Text(value)) => Some(text_string(value)),
        Some(_) => return Err(mismatch(header::CHANNEL_MAP)),
    };
    let object_names = match attributes.other.get(&text(header::OBJECT_NAMES)) {
        None => Vec::new(),
        Some(AttributeValue::Text(value)) => {
            serde_json::from_str(&text_string(value)).map_err(|error| {
                read_error(format!(
                    "header attribute `{}` is not a JSON list of names: {error}",
                    header::OBJECT_NAMES
                ))
            })?
        }
        Some(_) => return Err(mismatch(header::OBJECT_NAMES)),
    };
    let mut text_attributes: Vec<(String, String)> = attributes
        .other
        .iter()
        .filter_map(|(name, value)| {
            let name = name.to_string();
            let key = name.strip_prefix(header::EXTRA_PREFIX)?.to_string();
            match value {
                AttributeValue::Text(value) => Some((key, text_string(value))),
                _ => None,
            }
        })
        .collect();
    text_attributes.sort();
    let write = match attributes.other.get(&text(header::OUTPUT)) {
        None => super::WriteOptions::default(),
        Some(AttributeValue::Text(label)) => {
            let label = text_string(label);
            super::WriteOptions::from_label(&label).ok_or_else(|| {
                read_error(format!(
                    "header attribute `{}` is {label:?}, not `beauty=half|float32 compression=KIND layers=LIST`",
                    header::OUTPUT
                ))
            })?
        }
        Some(_) => return Err(mismatch(header::OUTPUT)),
    };
    Ok(ReadMeta {
        frame,
        time_secs,
        camera: Camera {
            eye: vec3_attribute(header::CAMERA_EYE)?,
            target: vec3_attribute(header::CAMERA_TARGET)?,
            up: vec3_attribute(header::CAMERA_UP)?,
            fov_y_deg,
            near_m,
            far_m,
        },
        world_from_camera,
        world_to_camera_standard: attributes.world_to_camera,
        method: string_attribute(header::METHOD)?,
        version: string_attribute(header::VERSION)?,
        channel_map,
        object_names,
        text_attributes,
        channels: Vec::new(),
        write,
    })
}
