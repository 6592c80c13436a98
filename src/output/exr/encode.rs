//! The OpenEXR writer: single-part scan-line files, written chunk by chunk, with the pixel
//! compressions of the `exr` crate (ZIP: snell's own, [`super::zip`]) applied to chunks built
//! straight from snell's layers (no copy of the whole image in the crate's own structures). Attributes are written in name order, as
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

/// Appends `values` as half samples, native byte order: the same bits as [`push_f16`] of each
/// (IEEE round to nearest even either way), eight at a time with the CPU's F16C instructions
/// where it has them. One call per sample was most of the beauty's conversion into chunk rows
/// with `--half` (issue 14 point 4).
pub(crate) fn push_f16_all(row: &mut Vec<u8>, values: impl Iterator<Item = f32>) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("f16c") {
        let mut eight = [0f32; 8];
        let mut held = 0;
        for value in values {
            eight[held] = value;
            held += 1;
            if held == 8 {
                // SAFETY: the CPU has F16C (detected above), and with it AVX.
                let halves = unsafe { f16c_eight(&eight) };
                row.extend_from_slice(bytemuck::cast_slice(&halves));
                held = 0;
            }
        }
        eight[..held].iter().for_each(|&value| push_f16(row, value));
        return;
    }
    values.for_each(|value| push_f16(row, value));
}

/// Eight floats to halves, rounding to nearest even (`vcvtps2ph`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,f16c")]
unsafe fn f16c_eight(values: &[f32; 8]) -> [u16; 8] {
    use std::arch::x86_64::{
        __m128i, _mm256_cvtps_ph, _mm256_loadu_ps, _mm_storeu_si128, _MM_FROUND_TO_NEAREST_INT,
    };
    let mut halves = [0u16; 8];
    let packed = _mm256_cvtps_ph::<_MM_FROUND_TO_NEAREST_INT>(_mm256_loadu_ps(values.as_ptr()));
    _mm_storeu_si128(halves.as_mut_ptr().cast::<__m128i>(), packed);
    halves
}

thread_local! {
    /// Each encoding thread's buffer for a chunk's samples, kept from chunk to chunk (a fresh
    /// one costs page faults on zeroed memory for every chunk).
    static SAMPLES: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
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

/// A file written as it is made: the header and a chunk offset table to be filled in, then the
/// rows in order, a band at a time (each band's chunks compressed in parallel), then the table.
/// Only one band's samples and chunks are held at once, and the bytes do not depend on how the
/// rows are cut into bands.
pub(crate) struct ChunkStream<W: std::io::Write + std::io::Seek> {
    out: W,
    header: Header,
    /// The channels' names and sample types, in file (name) order.
    channels: Vec<(String, SampleType)>,
    width: usize,
    height: usize,
    compression: Compression,
    /// Where the offset table starts in `out`.
    table_at: u64,
    /// Where the next chunk goes.
    position: u64,
    offsets: Vec<u64>,
    /// The next row to write.
    next_row: usize,
}

fn io_error(error: std::io::Error) -> String {
    error.to_string()
}

impl<W: std::io::Write + std::io::Seek> ChunkStream<W> {
    /// Writes the header of a file of `spec` with `channels` (their names and types; their rows
    /// come with [`Self::write_rows`]) and room for the offset table.
    pub fn start(
        mut out: W,
        spec: &FileSpec,
        channels: &[ChannelSource<'_>],
    ) -> Result<Self, String> {
        if spec.width == 0 || spec.height == 0 {
            return Err(format!("image is empty ({}x{})", spec.width, spec.height));
        }
        let mut names: Vec<(String, SampleType)> = channels
            .iter()
            .map(|channel| (channel.name.clone(), channel.sample_type))
            .collect();
        names.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
        if let Some(pair) = names.windows(2).find(|pair| pair[0].0 == pair[1].0) {
            return Err(format!("channel {} is given twice", pair[0].0));
        }
        let descriptions: Vec<ChannelDescription> = names
            .iter()
            .map(|(name, sample_type)| {
                ChannelDescription::new(
                    Text::from_slice_unchecked(name.as_bytes()),
                    *sample_type,
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
        let header_bytes = header_bytes(attributes, names.iter().map(|(name, _)| name.as_str()))?;
        let chunk_count = spec
            .height
            .div_ceil(spec.compression.scan_lines_per_block());
        out.write_all(&header_bytes).map_err(io_error)?;
        // The table, zeros until the chunks' places are known.
        out.write_all(&vec![0u8; 8 * chunk_count])
            .map_err(io_error)?;
        let table_at = header_bytes.len() as u64;
        Ok(ChunkStream {
            out,
            header,
            channels: names,
            width: spec.width,
            height: spec.height,
            compression: spec.compression,
            table_at,
            position: table_at + 8 * chunk_count as u64,
            offsets: Vec::with_capacity(chunk_count),
            next_row: 0,
        })
    }

    /// Writes rows `first_row..first_row + rows` (the next ones; `first_row` on a chunk's
    /// boundary, and `rows` a whole number of chunks unless they end the image), each channel's
    /// `fill` called with the row's index within the band.
    pub fn write_rows(
        &mut self,
        first_row: usize,
        rows: usize,
        mut channels: Vec<ChannelSource<'_>>,
    ) -> Result<(), String> {
        let lines_per_chunk = self.compression.scan_lines_per_block();
        let end = first_row + rows;
        if first_row != self.next_row || end > self.height {
            return Err(format!(
                "rows {first_row}..{end} do not follow row {} of the {} rows written",
                self.next_row, self.height
            ));
        }
        if end != self.height && !rows.is_multiple_of(lines_per_chunk) {
            return Err(format!(
                "a band of {rows} rows is not a whole number of {lines_per_chunk}-line chunks"
            ));
        }
        channels.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
        let names = channels.iter().map(|c| (c.name.as_str(), c.sample_type));
        if !names.eq(self.channels.iter().map(|(name, t)| (name.as_str(), *t))) {
            return Err("a band's channels are not the file's".to_string());
        }
        let (width, header, compression) = (self.width, &self.header, self.compression);
        let row_bytes: usize = header.channels.bytes_per_pixel * width;
        let chunks: Vec<Result<Vec<u8>, String>> = (0..rows.div_ceil(lines_per_chunk))
            .into_par_iter()
            .map(|chunk| {
                let first = chunk * lines_per_chunk;
                let last = (first + lines_per_chunk).min(rows);
                let top = first_row + first;
                // The chunk's row and size fields, then its pixels.
                let mut chunk_bytes = Vec::with_capacity(8 + row_bytes * (last - first) / 2);
                chunk_bytes.extend_from_slice(&(top as i32).to_le_bytes());
                chunk_bytes.extend_from_slice(&[0; 4]);
                SAMPLES.with(|samples| -> Result<(), String> {
                    let mut bytes = samples.borrow_mut();
                    bytes.clear();
                    for y in first..last {
                        for channel in &channels {
                            let before = bytes.len();
                            (channel.fill)(y, &mut bytes);
                            let expected = width * channel.sample_type.bytes_per_sample();
                            if bytes.len() - before != expected {
                                return Err(format!(
                                    "channel {} gave {} bytes for row {}, not {expected}",
                                    channel.name,
                                    bytes.len() - before,
                                    first_row + y
                                ));
                            }
                        }
                    }
                    match compression {
                        // zlib-rs (see zip.rs); the exr crate's codecs for the rest.
                        Compression::ZIP16 | Compression::ZIP1 => {
                            super::zip::append_chunk(&bytes, &mut chunk_bytes)
                        }
                        _ => {
                            let section =
                                IntegerBounds::new(Vec2(0, top as i32), Vec2(width, last - first));
                            let packed = compression
                                .compress_image_section_to_le(header, bytes.clone(), section)
                                .map_err(|error| format!("{compression}: {error}"))?;
                            chunk_bytes.extend_from_slice(&packed);
                        }
                    }
                    Ok(())
                })?;
                let size = (chunk_bytes.len() - 8) as i32;
                chunk_bytes[4..8].copy_from_slice(&size.to_le_bytes());
                Ok(chunk_bytes)
            })
            .collect();
        for chunk in chunks {
            let chunk = chunk?;
            self.out.write_all(&chunk).map_err(io_error)?;
            self.offsets.push(self.position);
            self.position += chunk.len() as u64;
        }
        self.next_row = end;
        Ok(())
    }

    /// Fills in the offset table once every row is written; returns the output.
    pub fn finish(mut self) -> Result<W, String> {
        if self.next_row != self.height {
            return Err(format!(
                "only {} of the {} rows were written",
                self.next_row, self.height
            ));
        }
        let table: Vec<u8> = self.offsets.iter().flat_map(|o| o.to_le_bytes()).collect();
        self.out
            .seek(std::io::SeekFrom::Start(self.table_at))
            .map_err(io_error)?;
        self.out.write_all(&table).map_err(io_error)?;
        self.out
            .seek(std::io::SeekFrom::Start(self.position))
            .map_err(io_error)?;
        self.out.flush().map_err(io_error)?;
        Ok(self.out)
    }
}

/// Magic number, version field and the attributes in name order, ended by a null byte.
fn header_bytes<'n>(
    mut attributes: Vec<(String, AttributeValue)>,
    channel_names: impl Iterator<Item = &'n str>,
) -> Result<Vec<u8>, String> {
    attributes.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    if let Some(pair) = attributes.windows(2).find(|pair| pair[0].0 == pair[1].0) {
        return Err(format!("header attribute {} is given twice", pair[0].0));
    }
    let mut long_names = false;
    let channel_names: Vec<&str> = channel_names.collect();
    for name in attributes
        .iter()
        .map(|(name, _)| name.as_str())
        .chain(channel_names)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_eight_at_a_time_are_the_halves_one_at_a_time() {
        // Known bits, then every kind of value: ties, subnormals, overflow, infinities, NaN,
        // signed zeros; 8k + 3 of them so the tail is converted one by one as well.
        let known = [
            (1.0f32, 0x3c00u16),
            (65504.0, 0x7bff),
            (-2.0, 0xc000),
            (0.5, 0x3800),
        ];
        let mut row = Vec::new();
        push_f16_all(&mut row, known.iter().map(|k| k.0));
        let bits: Vec<u16> = row
            .chunks_exact(2)
            .map(|b| u16::from_ne_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(bits, known.map(|k| k.1));
        let mut values = vec![
            0.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            65519.0,
            65520.0,
            1e9,
            6e-8,
            3e-8,
            1.0 + 1.0 / 2048.0,
            1.0 + 3.0 / 2048.0,
        ];
        let mut state = 0x2545_f491_u32;
        while values.len() < 8 * 40 + 3 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            values.push(f32::from_bits(state));
            values.push((state % 100_000) as f32 / 997.0);
        }
        values.truncate(8 * 40 + 3);
        let (mut eight, mut one) = (Vec::new(), Vec::new());
        push_f16_all(&mut eight, values.iter().copied());
        values.iter().for_each(|&value| push_f16(&mut one, value));
        assert_eq!(eight, one);
    }
}
