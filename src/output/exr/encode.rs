//! The OpenEXR writer: single-part scan-line files, written chunk by chunk, with the pixel
//! compressions of the `exr` crate applied to chunks built straight from snell's layers (no copy
//! of the whole image in the crate's own structures). Attributes are written in name order, as
//! OpenEXR's own library writes them, so the same frame always gives the same bytes.

use ::exr::compression::Compression;
use ::exr::math::Vec2;
use ::exr::meta::attribute::{
    AttributeValue, ChannelDescription, IntegerBounds, LineOrder, SampleType, Text,
};
use ::exr::meta::header::Header;
use ::exr::meta::BlockDescription;
use rayon::prelude::*;

/// Appends row `y`'s samples of a channel (native byte order, one per pixel) to the vector.
pub(crate) type FillRow<'a> = Box<dyn Fn(usize, &mut Vec<u8>) + Sync + 'a>;

/// One channel: its name, sample type and how to produce one row of its samples.
pub(crate) struct ChannelSource<'a> {
    pub name: String,
    pub sample_type: SampleType,
    pub fill: FillRow<'a>,
}

impl<'a> ChannelSource<'a> {
    pub fn f32(name: impl Into<String>, fill: impl Fn(usize, &mut Vec<u8>) + Sync + 'a) -> Self {
        Self {
            name: name.into(),
            sample_type: SampleType::F32,
            fill: Box::new(fill),
        }
    }

    pub fn f16(name: impl Into<String>, fill: impl Fn(usize, &mut Vec<u8>) + Sync + 'a) -> Self {
        Self {
            name: name.into(),
            sample_type: SampleType::F16,
            fill: Box::new(fill),
        }
    }
}

/// Appends `value` as a float32 or half sample, native byte order.
pub(crate) fn push_f32(row: &mut Vec<u8>, value: f32) {
    row.extend_from_slice(&value.to_ne_bytes());
}

pub(crate) fn push_f16(row: &mut Vec<u8>, value: f32) {
    row.extend_from_slice(&::exr::prelude::f16::from_f32(value).to_bits().to_ne_bytes());
}

/// Everything a file's header says besides its channels.
pub(crate) struct FileSpec {
    pub width: usize,
    pub height: usize,
    pub compression: Compression,
    /// Every attribute but the required layout ones (`channels`, `compression`, `dataWindow`,
    /// `displayWindow`, `lineOrder`), which the writer adds.
    pub attributes: Vec<(String, AttributeValue)>,
}

const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const VERSION: u32 = 2;
/// Version-field flag: some attribute or channel name is longer than 31 bytes.
const LONG_NAMES: u32 = 0x400;

/// Encodes a whole file into memory: header, chunk offset table and chunks (compressed in
/// parallel, written in increasing y order).
pub(crate) fn encode(
    spec: &FileSpec,
    mut channels: Vec<ChannelSource<'_>>,
) -> Result<Vec<u8>, String> {
    if spec.width == 0 || spec.height == 0 {
        return Err(format!("image is empty ({}x{})", spec.width, spec.height));
    }
    channels.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
    if let Some(pair) = channels
        .windows(2)
        .find(|pair| pair[0].name == pair[1].name)
    {
        return Err(format!("channel {} is given twice", pair[0].name));
    }
    let descriptions: Vec<ChannelDescription> = channels
        .iter()
        .map(|channel| {
            ChannelDescription::new(
                Text::from_slice_unchecked(channel.name.as_bytes()),
                channel.sample_type,
                false,
            )
        })
        .collect();
    let mut header = Header::new(
        Text::from_slice_unchecked(b""),
        (spec.width, spec.height),
        descriptions.into(),
    );
    header.blocks = BlockDescription::ScanLines;
    header.compression = spec.compression;
    header.line_order = LineOrder::Increasing;

    let lines_per_chunk = spec.compression.scan_lines_per_block();
    let chunk_count = spec.height.div_ceil(lines_per_chunk);
    let row_bytes: usize = header.channels.bytes_per_pixel * spec.width;
    let chunks: Vec<Result<Vec<u8>, String>> = (0..chunk_count)
        .into_par_iter()
        .map(|chunk| {
            let first = chunk * lines_per_chunk;
            let last = (first + lines_per_chunk).min(spec.height);
            let mut bytes = Vec::with_capacity(row_bytes * (last - first));
            for y in first..last {
                for channel in &channels {
                    let before = bytes.len();
                    (channel.fill)(y, &mut bytes);
                    let expected = spec.width * channel.sample_type.bytes_per_sample();
                    if bytes.len() - before != expected {
                        return Err(format!(
                            "channel {} gave {} bytes for row {y}, not {expected}",
                            channel.name,
                            bytes.len() - before
                        ));
                    }
                }
            }
            let section = IntegerBounds::new(Vec2(0, first as i32), Vec2(spec.width, last - first));
            let packed = spec
                .compression
                .compress_image_section_to_le(&header, bytes, section)
                .map_err(|error| format!("{}: {error}", spec.compression))?;
            let mut chunk_bytes = Vec::with_capacity(packed.len() + 8);
            chunk_bytes.extend_from_slice(&(first as i32).to_le_bytes());
            chunk_bytes.extend_from_slice(&(packed.len() as i32).to_le_bytes());
            chunk_bytes.extend_from_slice(&packed);
            Ok(chunk_bytes)
        })
        .collect();
    let chunks: Vec<Vec<u8>> = chunks.into_iter().collect::<Result<_, _>>()?;

    let mut attributes = spec.attributes.clone();
    let window = IntegerBounds::new(Vec2(0, 0), Vec2(spec.width, spec.height));
    attributes.extend([
        (
            "channels".to_string(),
            AttributeValue::ChannelList(header.channels.clone()),
        ),
        (
            "compression".to_string(),
            AttributeValue::Compression(spec.compression),
        ),
        (
            "dataWindow".to_string(),
            AttributeValue::IntegerBounds(window),
        ),
        (
            "displayWindow".to_string(),
            AttributeValue::IntegerBounds(window),
        ),
        (
            "lineOrder".to_string(),
            AttributeValue::LineOrder(LineOrder::Increasing),
        ),
    ]);
    let header_bytes = header_bytes(attributes, &channels)?;
    let table_bytes = 8 * chunk_count;
    let total = header_bytes.len() + table_bytes + chunks.iter().map(Vec::len).sum::<usize>();
    let mut file = Vec::with_capacity(total);
    file.extend_from_slice(&header_bytes);
    let mut offset = (header_bytes.len() + table_bytes) as u64;
    for chunk in &chunks {
        file.extend_from_slice(&offset.to_le_bytes());
        offset += chunk.len() as u64;
    }
    for chunk in chunks {
        file.extend_from_slice(&chunk);
    }
    Ok(file)
}

/// Magic number, version field and the attributes in name order, ended by a null byte.
fn header_bytes(
    mut attributes: Vec<(String, AttributeValue)>,
    channels: &[ChannelSource<'_>],
) -> Result<Vec<u8>, String> {
    attributes.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    if let Some(pair) = attributes.windows(2).find(|pair| pair[0].0 == pair[1].0) {
        return Err(format!("header attribute {} is given twice", pair[0].0));
    }
    let mut long_names = false;
    for name in attributes
        .iter()
        .map(|(name, _)| name.as_str())
        .chain(channels.iter().map(|channel| channel.name.as_str()))
    {
        if name.is_empty() || name.contains('\0') || name.len() > 255 {
            return Err(format!(
                "name {name:?} is empty, contains NUL or is longer than 255 bytes"
            ));
        }
        long_names |= name.len() > 31;
    }
    let mut bytes = Vec::new();
    bytes.extend_from_slice(&MAGIC);
    let version = VERSION | if long_names { LONG_NAMES } else { 0 };
    bytes.extend_from_slice(&version.to_le_bytes());
    for (name, value) in &attributes {
        ::exr::meta::attribute::write(name.as_bytes(), value, &mut bytes)
            .map_err(|error| format!("header attribute {name}: {error}"))?;
    }
    bytes.push(0);
    Ok(bytes)
}
