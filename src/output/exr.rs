//! One rendered frame as one OpenEXR file: receives a [`RenderedFrame`] and its [`FrameMeta`],
//! writes `DIR/<scene>.<frame>.exr` atomically with the channels `R,G,B,A` (linear beauty, f32),
//! `Z` (distance from the eye, f32), `P.X,P.Y,P.Z` (true world position, f32) and the 0/1 masks
//! `flags.convergence`, `flags.boundary`, `flags.popping`, `flags.extrapolated` (f16) and
//! `object` (u32: index + 1 of the object seen, 0 for none), ZIP compressed. Reads such a file back for tests and tools.
//!
//! Header attributes (besides the standard `worldToCamera`, `vFov`, `near`, `far`, `software`):
//! `snell.frame` (int), `snell.timeSecs` (double), `snell.worldFromCamera` (m44f),
//! `snell.fovYDeg` (float), `snell.cameraEye|Target|Up` (v3f), `snell.method`, `snell.version`,
//! and each extra entry `k = v` as the string attribute `snell.extra.k`.
//!
//! Matrix convention: both matrices are stored in Imath's layout (row vectors, translation in the
//! last row), which is the same 16 floats as glam's column-major `to_cols_array`.
//! `snell.worldFromCamera` maps snell's right-handed camera space (looking down -Z) to world;
//! `worldToCamera` follows the OpenEXR standard: left-handed camera space looking down +Z.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use ::exr::prelude::{
    f16, AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer,
    LayerAttributes, ReadChannels, ReadLayers, Text, WritableImage,
};
use glam::{Mat4, Vec3};

use super::{write_atomically, OutputError};
use crate::camera::{Camera, FAR_M, NEAR_M};
use crate::draw::{flag_bits, RenderedFrame};

/// Names of the flag channels and the [`flag_bits`] each one holds.
pub const FLAG_CHANNELS: [(&str, u32); 4] = [
    ("flags.convergence", flag_bits::CONVERGENCE),
    ("flags.boundary", flag_bits::BOUNDARY),
    ("flags.popping", flag_bits::POPPING),
    ("flags.extrapolated", flag_bits::EXTRAPOLATED),
];

/// Index + 1 of the object each pixel sees ([`RenderedFrame::object`]).
pub const OBJECT_CHANNEL: &str = "object";

const ATTRIBUTE_FRAME: &str = "snell.frame";
const ATTRIBUTE_TIME_SECS: &str = "snell.timeSecs";
const ATTRIBUTE_WORLD_FROM_CAMERA: &str = "snell.worldFromCamera";
const ATTRIBUTE_FOV_Y_DEG: &str = "snell.fovYDeg";
const ATTRIBUTE_CAMERA_EYE: &str = "snell.cameraEye";
const ATTRIBUTE_CAMERA_TARGET: &str = "snell.cameraTarget";
const ATTRIBUTE_CAMERA_UP: &str = "snell.cameraUp";
const ATTRIBUTE_METHOD: &str = "snell.method";
const ATTRIBUTE_VERSION: &str = "snell.version";
const EXTRA_PREFIX: &str = "snell.extra.";

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
    /// Further text attributes, written as `snell.extra.<key>`.
    pub extra: Vec<(String, String)>,
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
    /// The `snell.extra.*` attributes with the prefix removed, sorted by key.
    pub text_attributes: Vec<(String, String)>,
}

/// `DIR/<scene>.<frame, at least 4 digits>.exr`.
pub fn frame_path(dir: &Path, scene_name: &str, frame: u32) -> PathBuf {
    dir.join(format!("{scene_name}.{frame:04}.exr"))
}

/// OpenEXR's camera space is left-handed with +Z forward; snell's (glam's look_at_rh) is
/// right-handed with -Z forward, so the standard matrix flips Z after the view transform.
fn standard_camera_from_world(camera: &Camera) -> Mat4 {
    Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0)) * camera.view_from_world()
}

fn text(value: &str) -> Text {
    // OpenEXR strings are byte strings; UTF-8 is what current OpenEXR and its tools assume.
    Text::from_slice_unchecked(value.as_bytes())
}

fn text_to_string(value: &Text) -> String {
    String::from_utf8_lossy(value.as_slice()).into_owned()
}

fn check_frame_shape(frame: &RenderedFrame) -> Result<usize, String> {
    if frame.width == 0 || frame.height == 0 {
        return Err(format!("frame is empty ({}x{})", frame.width, frame.height));
    }
    let pixel_count = frame.width as usize * frame.height as usize;
    let lengths = [
        ("beauty_rgba", frame.beauty_rgba.len()),
        ("distance_m", frame.distance_m.len()),
        ("position", frame.position.len()),
        ("flags", frame.flags.len()),
        // Empty: a frame read from a file written before the layer existed.
        ("object", frame.object.len()),
    ];
    for (name, length) in lengths {
        if length != pixel_count && !(name == "object" && length == 0) {
            return Err(format!(
                "frame buffer `{name}` holds {length} pixels but the frame is {}x{} = {pixel_count}",
                frame.width, frame.height
            ));
        }
    }
    Ok(pixel_count)
}

fn build_image(
    frame: &RenderedFrame,
    meta: &FrameMeta,
) -> Result<Image<Layer<AnyChannels<FlatSamples>>>, String> {
    check_frame_shape(frame)?;
    let f32_channel =
        |name: &str, values: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(values));
    let beauty_component = |index: usize| {
        frame
            .beauty_rgba
            .iter()
            .map(|rgba| rgba[index])
            .collect::<Vec<f32>>()
    };
    let position_component = |index: usize| {
        frame
            .position
            .iter()
            .map(|xyz| xyz[index])
            .collect::<Vec<f32>>()
    };

    let mut channels = vec![
        f32_channel("R", beauty_component(0)),
        f32_channel("G", beauty_component(1)),
        f32_channel("B", beauty_component(2)),
        f32_channel("A", beauty_component(3)),
        f32_channel("Z", frame.distance_m.clone()),
        f32_channel("P.X", position_component(0)),
        f32_channel("P.Y", position_component(1)),
        f32_channel("P.Z", position_component(2)),
    ];
    for (name, bit) in FLAG_CHANNELS {
        let mask = frame
            .flags
            .iter()
            .map(|flags| {
                if flags & bit != 0 {
                    f16::ONE
                } else {
                    f16::ZERO
                }
            })
            .collect();
        channels.push(AnyChannel::new(name, FlatSamples::F16(mask)));
    }
    if !frame.object.is_empty() {
        channels.push(AnyChannel::new(
            OBJECT_CHANNEL,
            FlatSamples::U32(frame.object.clone()),
        ));
    }

    let camera = &meta.camera;
    let mut attributes = LayerAttributes {
        world_to_camera: Some(standard_camera_from_world(camera).to_cols_array()),
        vertical_field_of_view: Some(camera.fov_y_deg),
        near_clip_plane: Some(NEAR_M),
        far_clip_plane: Some(FAR_M),
        software_name: Some(text(&format!("snell {}", meta.version))),
        ..LayerAttributes::default()
    };
    let frame_number = i32::try_from(meta.frame)
        .map_err(|_| format!("frame number {} exceeds i32", meta.frame))?;
    let vec3 = |v: Vec3| AttributeValue::FloatVec3((v.x, v.y, v.z));
    let mut other: HashMap<Text, AttributeValue> = HashMap::from([
        (text(ATTRIBUTE_FRAME), AttributeValue::I32(frame_number)),
        (
            text(ATTRIBUTE_TIME_SECS),
            AttributeValue::F64(meta.time_secs),
        ),
        (
            text(ATTRIBUTE_WORLD_FROM_CAMERA),
            AttributeValue::Matrix4x4(camera.view_from_world().inverse().to_cols_array()),
        ),
        (
            text(ATTRIBUTE_FOV_Y_DEG),
            AttributeValue::F32(camera.fov_y_deg),
        ),
        (text(ATTRIBUTE_CAMERA_EYE), vec3(camera.eye)),
        (text(ATTRIBUTE_CAMERA_TARGET), vec3(camera.target)),
        (text(ATTRIBUTE_CAMERA_UP), vec3(camera.up)),
        (
            text(ATTRIBUTE_METHOD),
            AttributeValue::Text(text(&meta.method)),
        ),
        (
            text(ATTRIBUTE_VERSION),
            AttributeValue::Text(text(&meta.version)),
        ),
    ]);
    for (key, value) in &meta.extra {
        // Attribute names are NUL-terminated in the file and at most 255 bytes long.
        let name = format!("{EXTRA_PREFIX}{key}");
        if key.is_empty() || key.contains('\0') || name.len() > 255 {
            return Err(format!(
                "extra attribute name {key:?} is empty, contains NUL or is too long"
            ));
        }
        if other
            .insert(text(&name), AttributeValue::Text(text(value)))
            .is_some()
        {
            return Err(format!("extra attribute {key:?} is given twice"));
        }
    }
    attributes.other = other;

    let layer = Layer::new(
        (frame.width as usize, frame.height as usize),
        attributes,
        // ZIP over 16 scan lines: lossless and compact on smooth float data.
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    Ok(Image::from_layer(layer))
}

/// Writes one frame to `path` (normally [`frame_path`]) via a temporary file in the same directory,
/// synced and renamed; creates the directory if needed. On error nothing is left at `path` that was
/// not there before, and the temporary file is removed.
pub fn write_frame_exr(
    path: &Path,
    frame: &RenderedFrame,
    meta: &FrameMeta,
) -> Result<(), OutputError> {
    let image = build_image(frame, meta).map_err(|cause| OutputError::Write {
        path: path.to_path_buf(),
        cause,
    })?;
    // Parallel compression: ZIP (deflate level 4, fixed by the exr crate) dominates the cost of a
    // frame, about 0.4-1 s at 1280x720 on one core. With increasing line order the crate writes
    // the chunks in order, so the pixel bytes do not depend on thread timing.
    let mut encoded = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut encoded)
        .map_err(|error| OutputError::Write {
            path: path.to_path_buf(),
            cause: format!("OpenEXR encoding: {error}"),
        })?;
    let mut bytes = encoded.into_inner();
    sort_header_attributes(&mut bytes).map_err(|cause| OutputError::Write {
        path: path.to_path_buf(),
        cause: format!("OpenEXR header: {cause}"),
    })?;
    write_atomically(path, |file| {
        file.write_all(&bytes).map_err(|error| error.to_string())
    })
}

/// Puts the header attributes of a single-part OpenEXR file in name order, in place.
///
/// The exr crate writes custom attributes in `HashMap` order, which is random per process, so the
/// same frame would give different bytes on every run. The header's length does not change when
/// its attributes are permuted, so the chunk offset table after it stays valid.
fn sort_header_attributes(bytes: &mut [u8]) -> Result<(), String> {
    const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
    const MULTIPART_FLAG: u32 = 0x1000;
    if bytes.len() < 8 || bytes[..4] != MAGIC {
        return Err("not an OpenEXR file".into());
    }
    let version_and_flags = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
    if version_and_flags & MULTIPART_FLAG != 0 {
        return Err("multi-part files are not expected here".into());
    }
    let header_start = 8;
    let mut attributes: Vec<(Vec<u8>, std::ops::Range<usize>)> = Vec::new();
    let mut position = header_start;
    let nul_after = |from: usize| {
        bytes[from..]
            .iter()
            .position(|&byte| byte == 0)
            .map(|offset| from + offset)
            .ok_or("unterminated header")
    };
    loop {
        let attribute_start = position;
        let name_end = nul_after(position)?;
        if name_end == position {
            break; // an empty name ends the header
        }
        let type_end = nul_after(name_end + 1)?;
        let size_at = type_end + 1;
        let size_bytes: [u8; 4] = bytes
            .get(size_at..size_at + 4)
            .ok_or("truncated header")?
            .try_into()
            .unwrap_or_default();
        let size = usize::try_from(i32::from_le_bytes(size_bytes))
            .map_err(|_| "negative attribute size")?;
        position = size_at + 4 + size;
        if position > bytes.len() {
            return Err("truncated header".into());
        }
        attributes.push((
            bytes[attribute_start..name_end].to_vec(),
            attribute_start..position,
        ));
    }
    let header_end = position;
    let mut sorted = Vec::with_capacity(header_end - header_start);
    attributes.sort_by(|a, b| a.0.cmp(&b.0));
    for (_, range) in &attributes {
        sorted.extend_from_slice(&bytes[range.clone()]);
    }
    bytes[header_start..header_end].copy_from_slice(&sorted);
    Ok(())
}

/// Reads a frame written by [`write_frame_exr`]: pixels and the snell header attributes.
/// `flags` comes back as the four [`flag_bits`] of the flag channels; other bits are not stored.
pub fn read_frame_exr(path: &Path) -> Result<(RenderedFrame, ReadMeta), OutputError> {
    let read_error = |cause: String| OutputError::Read {
        path: path.to_path_buf(),
        cause,
    };
    let image = ::exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|error| read_error(format!("OpenEXR decoding: {error}")))?;
    let layer = &image.layer_data;
    let width = layer.size.width();
    let height = layer.size.height();

    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|channel| channel.name == *name)
            .map(|channel| &channel.sample_data)
            .ok_or_else(|| read_error(format!("channel `{name}` is missing")))
    };
    let f32_channel = |name: &str| match channel(name)? {
        FlatSamples::F32(values) => Ok(values),
        _ => Err(read_error(format!("channel `{name}` is not 32-bit float"))),
    };
    let (r, g, b, a) = (
        f32_channel("R")?,
        f32_channel("G")?,
        f32_channel("B")?,
        f32_channel("A")?,
    );
    let (px, py, pz) = (
        f32_channel("P.X")?,
        f32_channel("P.Y")?,
        f32_channel("P.Z")?,
    );
    let pixel_count = width * height;
    let mut flags = vec![0u32; pixel_count];
    for (name, bit) in FLAG_CHANNELS {
        let mask: Vec<bool> = match channel(name)? {
            FlatSamples::F16(values) => values.iter().map(|value| value.to_f32() != 0.0).collect(),
            FlatSamples::F32(values) => values.iter().map(|value| *value != 0.0).collect(),
            FlatSamples::U32(values) => values.iter().map(|value| *value != 0).collect(),
        };
        for (flags, set) in flags.iter_mut().zip(mask) {
            if set {
                *flags |= bit;
            }
        }
    }
    let frame = RenderedFrame {
        width: width as u32,
        height: height as u32,
        beauty_rgba: (0..pixel_count).map(|i| [r[i], g[i], b[i], a[i]]).collect(),
        distance_m: f32_channel("Z")?.clone(),
        position: (0..pixel_count).map(|i| [px[i], py[i], pz[i]]).collect(),
        flags,
        // Frames written before the object layer existed have none.
        object: match channel(OBJECT_CHANNEL) {
            Ok(FlatSamples::U32(values)) => values.clone(),
            Ok(_) => {
                return Err(read_error(format!(
                    "channel `{OBJECT_CHANNEL}` is not 32-bit unsigned"
                )))
            }
            Err(_) => Vec::new(),
        },
    };

    let attributes = &layer.attributes;
    let attribute = |name: &str| {
        attributes
            .other
            .get(&text(name))
            .ok_or_else(|| read_error(format!("header attribute `{name}` is missing")))
    };
    let mismatch =
        |name: &str| read_error(format!("header attribute `{name}` has an unexpected type"));
    let string_attribute = |name: &str| match attribute(name)? {
        AttributeValue::Text(value) => Ok(text_to_string(value)),
        _ => Err(mismatch(name)),
    };
    let vec3_attribute = |name: &str| match attribute(name)? {
        AttributeValue::FloatVec3((x, y, z)) => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(mismatch(name)),
    };
    let frame_number = match attribute(ATTRIBUTE_FRAME)? {
        AttributeValue::I32(value) => {
            u32::try_from(*value).map_err(|_| mismatch(ATTRIBUTE_FRAME))?
        }
        _ => return Err(mismatch(ATTRIBUTE_FRAME)),
    };
    let time_secs = match attribute(ATTRIBUTE_TIME_SECS)? {
        AttributeValue::F64(value) => *value,
        _ => return Err(mismatch(ATTRIBUTE_TIME_SECS)),
    };
    let world_from_camera = match attribute(ATTRIBUTE_WORLD_FROM_CAMERA)? {
        AttributeValue::Matrix4x4(value) => *value,
        _ => return Err(mismatch(ATTRIBUTE_WORLD_FROM_CAMERA)),
    };
    let fov_y_deg = match attribute(ATTRIBUTE_FOV_Y_DEG)? {
        AttributeValue::F32(value) => *value,
        _ => return Err(mismatch(ATTRIBUTE_FOV_Y_DEG)),
    };
    let mut text_attributes: Vec<(String, String)> = attributes
        .other
        .iter()
        .filter_map(|(name, value)| {
            let name = text_to_string(name);
            let key = name.strip_prefix(EXTRA_PREFIX)?.to_string();
            match value {
                AttributeValue::Text(value) => Some((key, text_to_string(value))),
                _ => None,
            }
        })
        .collect();
    text_attributes.sort();
    let meta = ReadMeta {
        frame: frame_number,
        time_secs,
        camera: Camera {
            eye: vec3_attribute(ATTRIBUTE_CAMERA_EYE)?,
            target: vec3_attribute(ATTRIBUTE_CAMERA_TARGET)?,
            up: vec3_attribute(ATTRIBUTE_CAMERA_UP)?,
            fov_y_deg,
        },
        world_from_camera,
        world_to_camera_standard: attributes.world_to_camera,
        method: string_attribute(ATTRIBUTE_METHOD)?,
        version: string_attribute(ATTRIBUTE_VERSION)?,
        text_attributes,
    };
    Ok((frame, meta))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    fn test_camera() -> Camera {
        Camera {
            eye: Vec3::new(1.0, 3.0, 8.0),
            target: Vec3::new(0.0, -1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
        }
    }

    fn test_meta() -> FrameMeta {
        FrameMeta {
            scene_name: "pool".into(),
            frame: 7,
            time_secs: 7.0 / 24.0,
            camera: test_camera(),
            method: "geometric".into(),
            version: crate::VERSION.into(),
            extra: vec![
                ("scene_file".into(), "scenes/pool.toml".into()),
                ("note".into(), "ünïcode ok".into()),
            ],
        }
    }

    /// A frame whose every pixel differs, with the special values a render produces: NaN positions
    /// (sky), +inf distance (sky), negative zero, denormals, every flag combination.
    fn test_frame(width: u32, height: u32) -> RenderedFrame {
        let pixel_count = (width * height) as usize;
        let mut frame = RenderedFrame {
            width,
            height,
            ..Default::default()
        };
        for i in 0..pixel_count {
            let x = i as f32;
            frame.beauty_rgba.push([
                x * 0.37,
                1.0 / (x + 1.0),
                x * 1e3,
                if i % 5 == 0 { 0.0 } else { 1.0 },
            ]);
            frame.distance_m.push(match i % 4 {
                0 => f32::INFINITY,
                1 => f32::MIN_POSITIVE / 8.0,
                _ => x * 0.125 + 0.05,
            });
            frame.position.push(match i % 3 {
                0 => [f32::NAN; 3],
                1 => [-0.0, x, -x * 3.25],
                _ => [f32::from_bits(0x7fc0_1234), 1e-30, 12345.678],
            });
            frame.flags.push((i as u32 * 7) % 16);
            frame.object.push((i as u32 * 5) % 3);
        }
        frame
    }

    fn assert_bit_exact(expected: &RenderedFrame, actual: &RenderedFrame) {
        assert_eq!(
            (expected.width, expected.height),
            (actual.width, actual.height)
        );
        let bits = |values: &[f32]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(expected.beauty_rgba.as_flattened()),
            bits(actual.beauty_rgba.as_flattened()),
            "beauty"
        );
        assert_eq!(
            bits(&expected.distance_m),
            bits(&actual.distance_m),
            "distance"
        );
        assert_eq!(
            bits(expected.position.as_flattened()),
            bits(actual.position.as_flattened()),
            "position"
        );
        assert_eq!(expected.flags, actual.flags, "flags");
        assert_eq!(expected.object, actual.object, "object");
    }

    #[test]
    fn frame_path_pads_to_four_digits() {
        assert_eq!(
            frame_path(Path::new("out"), "pool", 7),
            PathBuf::from("out/pool.0007.exr")
        );
        assert_eq!(
            frame_path(Path::new("out"), "pool", 12345),
            PathBuf::from("out/pool.12345.exr")
        );
    }

    #[test]
    fn round_trip_is_bit_exact_with_attributes() {
        let temp = tempfile::tempdir().unwrap();
        let meta = test_meta();
        let path = frame_path(
            &temp.path().join("new-subdir"),
            &meta.scene_name,
            meta.frame,
        );
        let frame = test_frame(13, 7);
        write_frame_exr(&path, &frame, &meta).unwrap();
        let (read, read_meta) = read_frame_exr(&path).unwrap();
        assert_bit_exact(&frame, &read);

        assert_eq!(read_meta.frame, 7);
        assert_eq!(read_meta.time_secs, 7.0 / 24.0);
        assert_eq!(read_meta.camera, meta.camera);
        assert_eq!(read_meta.method, "geometric");
        assert_eq!(read_meta.version, crate::VERSION);
        let mut extra = meta.extra.clone();
        extra.sort();
        assert_eq!(read_meta.text_attributes, extra);
        // The camera matrix must place the eye at the origin of camera space.
        let world_from_camera = Mat4::from_cols_array(&read_meta.world_from_camera);
        assert!(world_from_camera
            .transform_point3(Vec3::ZERO)
            .abs_diff_eq(meta.camera.eye, 1e-5));
        // The standard matrix puts the target straight ahead on +Z (left-handed, OpenEXR convention).
        let camera_from_world = Mat4::from_cols_array(&read_meta.world_to_camera_standard.unwrap());
        let target_in_camera = camera_from_world.transform_point3(meta.camera.target);
        let distance = (meta.camera.target - meta.camera.eye).length();
        assert!(
            target_in_camera.abs_diff_eq(Vec3::new(0.0, 0.0, distance), 1e-4),
            "{target_in_camera}"
        );
    }

    #[test]
    fn channel_names_and_types_are_as_specified() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("frame.exr");
        write_frame_exr(&path, &test_frame(4, 3), &test_meta()).unwrap();
        let image = ::exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        let layer = &image.layer_data;
        assert_eq!(
            layer.attributes.layer_name, None,
            "the image must be layer-less"
        );
        let mut names: Vec<(String, &'static str)> = layer
            .channel_data
            .list
            .iter()
            .map(|channel| {
                let kind = match channel.sample_data {
                    FlatSamples::F16(_) => "f16",
                    FlatSamples::F32(_) => "f32",
                    FlatSamples::U32(_) => "u32",
                };
                (channel.name.to_string(), kind)
            })
            .collect();
        names.sort();
        let mut expected: Vec<(String, &str)> = [
            ("R", "f32"),
            ("G", "f32"),
            ("B", "f32"),
            ("A", "f32"),
            ("Z", "f32"),
            ("P.X", "f32"),
            ("P.Y", "f32"),
            ("P.Z", "f32"),
            ("flags.convergence", "f16"),
            ("flags.boundary", "f16"),
            ("flags.popping", "f16"),
            ("flags.extrapolated", "f16"),
            ("object", "u32"),
        ]
        .into_iter()
        .map(|(name, kind)| (name.to_string(), kind))
        .collect();
        expected.sort();
        assert_eq!(names, expected);
        assert_eq!(
            layer.encoding.compression,
            ::exr::prelude::Compression::ZIP16
        );
        assert_eq!(layer.attributes.vertical_field_of_view, Some(50.0));
        for name in [
            ATTRIBUTE_FRAME,
            ATTRIBUTE_TIME_SECS,
            ATTRIBUTE_WORLD_FROM_CAMERA,
            ATTRIBUTE_METHOD,
            ATTRIBUTE_VERSION,
        ] {
            assert!(
                layer.attributes.other.contains_key(&text(name)),
                "missing {name}"
            );
        }
    }

    #[test]
    fn flag_channels_are_zero_one_masks_of_their_bit() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("frame.exr");
        let frame = test_frame(4, 4);
        write_frame_exr(&path, &frame, &test_meta()).unwrap();
        let image = ::exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        for (name, bit) in FLAG_CHANNELS {
            let channel = image
                .layer_data
                .channel_data
                .list
                .iter()
                .find(|c| c.name == *name)
                .unwrap();
            let FlatSamples::F16(values) = &channel.sample_data else {
                panic!("{name} is not f16")
            };
            let expected: Vec<f32> = frame
                .flags
                .iter()
                .map(|f| if f & bit != 0 { 1.0 } else { 0.0 })
                .collect();
            assert_eq!(
                values.iter().map(|v| v.to_f32()).collect::<Vec<_>>(),
                expected,
                "{name}"
            );
        }
    }

    fn directory_entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn no_temporary_file_after_success_or_failure() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("pool.0001.exr");
        write_frame_exr(&path, &test_frame(3, 2), &test_meta()).unwrap();
        assert_eq!(directory_entries(temp.path()), vec!["pool.0001.exr"]);

        // An inconsistent frame fails before any file is created.
        let mut broken = test_frame(3, 2);
        broken.flags.pop();
        let error =
            write_frame_exr(&temp.path().join("pool.0002.exr"), &broken, &test_meta()).unwrap_err();
        assert!(error.to_string().contains("pool.0002.exr"), "{error}");
        assert!(error.to_string().contains("flags"), "{error}");
        assert_eq!(directory_entries(temp.path()), vec!["pool.0001.exr"]);

        // A failure after the temporary file was created (the destination is a non-empty directory,
        // so the rename fails) removes the temporary file too.
        let blocked = temp.path().join("pool.0003.exr");
        fs::create_dir(&blocked).unwrap();
        fs::write(blocked.join("keep"), b"x").unwrap();
        let error = write_frame_exr(&blocked, &test_frame(3, 2), &test_meta()).unwrap_err();
        assert!(error.to_string().contains("pool.0003.exr"), "{error}");
        assert_eq!(
            directory_entries(temp.path()),
            vec!["pool.0001.exr", "pool.0003.exr"]
        );
    }

    #[test]
    fn unwritable_output_path_is_a_clear_error() {
        let temp = tempfile::tempdir().unwrap();
        let regular_file = temp.path().join("file");
        fs::write(&regular_file, b"x").unwrap();
        let path = frame_path(&regular_file.join("out"), "pool", 1);
        let message = write_frame_exr(&path, &test_frame(2, 2), &test_meta())
            .unwrap_err()
            .to_string();
        assert!(message.contains("cannot create directory"), "{message}");
        assert!(
            message.contains("a path component is a regular file"),
            "{message}"
        );
        assert!(
            message.contains(&regular_file.join("out").display().to_string()),
            "{message}"
        );
    }

    #[test]
    fn same_frame_gives_the_same_bytes() {
        let temp = tempfile::tempdir().unwrap();
        let (first, second) = (temp.path().join("a.exr"), temp.path().join("b.exr"));
        // 96 lines = 6 ZIP chunks, so parallel compression has several blocks to put in order;
        // each write builds its own attribute HashMap, whose order is random.
        let frame = test_frame(40, 96);
        write_frame_exr(&first, &frame, &test_meta()).unwrap();
        write_frame_exr(&second, &frame, &test_meta()).unwrap();
        assert_eq!(fs::read(&first).unwrap(), fs::read(&second).unwrap());
    }

    #[test]
    fn overwriting_an_existing_frame_replaces_it() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("pool.0001.exr");
        write_frame_exr(&path, &test_frame(3, 2), &test_meta()).unwrap();
        let second = test_frame(5, 4);
        write_frame_exr(&path, &second, &test_meta()).unwrap();
        assert_bit_exact(&second, &read_frame_exr(&path).unwrap().0);
    }
}
