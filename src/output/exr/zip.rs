//! EXR `zip` and `zips` chunks compressed here, with libdeflate, instead of by the `exr` crate
//! (miniz_oxide at level 4, 3-5x slower on snell's layers for files 0.1-0.6 % smaller: deflate was
//! half of a written frame's CPU time, issue 14 point 4).
//!
//! OpenEXR's ZIP compression of a chunk (`ImfZip.cpp`): the chunk's little-endian bytes are split
//! into the even-indexed bytes followed by the odd-indexed ones, each byte is replaced by its
//! difference to the one before plus 128 (mod 256; the first byte kept), and the result is one
//! zlib stream; any conforming stream decodes the same. A chunk whose stream is not smaller than
//! its raw bytes is stored raw, as OpenEXR and the `exr` crate do (readers tell the two apart by
//! the size). The bytes depend only on the chunk's pixels and [`LEVEL`]: not on thread counts or
//! on which thread compresses which chunk.

use std::cell::RefCell;

/// libdeflate's compression level. Level 1 against 4 and 6 on 1280x720 `pool.toml` frames
/// (README, "Where a written frame's time goes"): the fastest for files a few tenths of a
/// percent larger.
pub(crate) const LEVEL: i32 = 1;

/// Each encoding thread's compressor and scratch, kept from chunk to chunk: fresh buffers for
/// every chunk cost page faults on zeroed memory (8 % of a written frame's CPU time before).
struct Work {
    compressor: libdeflater::Compressor,
    /// The chunk's bytes separated, then predicted, then compressed.
    separated: Vec<u8>,
    predicted: Vec<u8>,
    packed: Vec<u8>,
}

thread_local! {
    static WORK: RefCell<Option<Work>> = const { RefCell::new(None) };
}

/// Appends to `out` the ZIP-compressed form of one chunk whose samples are `native` (rows of each
/// channel's samples, in native byte order), or its raw little-endian bytes where compressing
/// does not make it smaller: what goes in the file after the chunk's row and size fields.
pub(crate) fn append_chunk(native: &[u8], out: &mut Vec<u8>) {
    #[cfg(target_endian = "big")]
    compile_error!(
        "snell's ZIP chunks assume a little-endian machine (native byte order is the file's)"
    );
    WORK.with(|work| {
        let mut work = work.borrow_mut();
        let work = work.get_or_insert_with(|| Work {
            compressor: libdeflater::Compressor::new(
                libdeflater::CompressionLvl::new(LEVEL).expect("a valid libdeflate level"),
            ),
            separated: Vec::new(),
            predicted: Vec::new(),
            packed: Vec::new(),
        });
        separate_bytes(native, &mut work.separated);
        predict(&work.separated, &mut work.predicted);
        let bound = work.compressor.zlib_compress_bound(native.len());
        if work.packed.len() < bound {
            work.packed.resize(bound, 0);
        }
        match work
            .compressor
            .zlib_compress(&work.predicted, &mut work.packed)
        {
            Ok(size) if size < native.len() => out.extend_from_slice(&work.packed[..size]),
            // Not smaller (or no room, which libdeflate reports for incompressible input).
            _ => out.extend_from_slice(native),
        }
    })
}

/// `out` = the even-indexed bytes of `bytes`, then the odd-indexed ones.
fn separate_bytes(bytes: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.resize(bytes.len(), 0);
    let (first, second) = out.split_at_mut(bytes.len().div_ceil(2));
    for ((pair, a), b) in bytes
        .chunks_exact(2)
        .zip(first.iter_mut())
        .zip(second.iter_mut())
    {
        *a = pair[0];
        *b = pair[1];
    }
    if bytes.len() % 2 == 1 {
        first[first.len() - 1] = bytes[bytes.len() - 1];
    }
}

/// `out[i] = bytes[i] - bytes[i - 1] + 128` (mod 256), `out[0] = bytes[0]`.
fn predict(bytes: &[u8], out: &mut Vec<u8>) {
    out.clear();
    out.resize(bytes.len(), 0);
    if let Some(&first) = bytes.first() {
        out[0] = first;
        for ((o, &b), &a) in out[1..].iter_mut().zip(&bytes[1..]).zip(bytes) {
            *o = b.wrapping_sub(a).wrapping_add(128);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn compress_chunk(native: Vec<u8>) -> Vec<u8> {
        let mut out = Vec::new();
        append_chunk(&native, &mut out);
        out
    }
    use ::exr::compression::Compression;
    use ::exr::math::Vec2;
    use ::exr::meta::attribute::{ChannelDescription, IntegerBounds, SampleType, Text};
    use ::exr::meta::header::Header;

    /// A header of `width` x `rows` with the given channels (name order) and compression, for
    /// the `exr` crate's codecs.
    fn header(
        width: usize,
        rows: usize,
        types: &[(&str, SampleType)],
        compression: Compression,
    ) -> Header {
        let channels: Vec<ChannelDescription> = types
            .iter()
            .map(|(name, t)| ChannelDescription::new(Text::from(*name), *t, false))
            .collect();
        let mut header = Header::new(Text::from(""), (width, rows), channels.into());
        header.compression = compression;
        header.blocks = ::exr::meta::BlockDescription::ScanLines;
        header
    }

    /// Deterministic bytes: a smooth field (as rendered layers mostly are), or pure noise.
    fn samples(len: usize, seed: u64, smooth: bool) -> Vec<u8> {
        let mut state = seed | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        (0..len / 4)
            .flat_map(|i| {
                let value = if smooth {
                    // A smooth field in steps of 1/64 (few mantissa bits), an odd pixel off.
                    let step = if next() % 7 == 0 { 1.0 } else { 0.0 };
                    ((i as f32 * 0.01).sin() * 64.0).round() / 64.0 + step
                } else {
                    f32::from_bits(next() as u32)
                };
                value.to_le_bytes()
            })
            .chain((0..len % 4).map(|_| 7u8))
            .collect()
    }

    /// Decodes `packed` with the `exr` crate's own decompressor (zune-inflate and its predictor
    /// and interleave, none of this module's code).
    fn decode(
        packed: Vec<u8>,
        width: usize,
        rows: usize,
        types: &[(&str, SampleType)],
        compression: Compression,
    ) -> Vec<u8> {
        let header = header(width, rows, types, compression);
        let section = IntegerBounds::new(Vec2(0, 0), Vec2(width, rows));
        compression
            .decompress_image_section_from_le(&header, packed, section, true)
            .expect("the exr crate reads the chunk")
    }

    #[test]
    fn chunks_decode_to_their_samples_with_the_exr_crate() {
        let types = [
            ("A", SampleType::F32),
            ("B", SampleType::F16),
            ("C", SampleType::U32),
        ];
        // 10 bytes a pixel; 16 rows (zip) and 1 row (zips), odd and even widths.
        for (rows, compression) in [(16, Compression::ZIP16), (1, Compression::ZIP1)] {
            for width in [1, 7, 320, 1281] {
                for smooth in [true, false] {
                    let native = samples(width * rows * 10, width as u64 + rows as u64, smooth);
                    let packed = compress_chunk(native.clone());
                    if smooth && width > 7 {
                        assert!(
                            packed.len() < native.len() * 3 / 4,
                            "{width}x{rows}: {} of {}",
                            packed.len(),
                            native.len()
                        );
                    }
                    assert_eq!(
                        decode(packed, width, rows, &types, compression),
                        native,
                        "{width}x{rows}, smooth {smooth}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_chunk_that_does_not_shrink_is_stored_raw() {
        let native = samples(64 * 16 * 4, 3, false);
        let packed = compress_chunk(native.clone());
        assert_eq!(packed, native, "noise is stored as it is");
        // Readers take a chunk of the raw size as raw.
        assert_eq!(
            decode(
                packed,
                64,
                16,
                &[("A", SampleType::F32)],
                Compression::ZIP16
            ),
            native
        );
    }

    #[test]
    fn the_transform_is_openexrs() {
        // ImfZip.cpp on bytes 10 20 30 40 50: separated 10 30 50 20 40, predicted
        // 10, 30-10+128, 50-30+128, 20-50+128 (mod 256), 40-20+128.
        let mut separated = Vec::new();
        separate_bytes(&[10, 20, 30, 40, 50], &mut separated);
        assert_eq!(separated, [10, 30, 50, 20, 40]);
        let mut predicted = Vec::new();
        predict(&separated, &mut predicted);
        assert_eq!(predicted, [10, 148, 148, 98, 148]);
    }

    #[test]
    fn the_same_chunk_gives_the_same_bytes_on_every_thread() {
        let native = samples(1280 * 16 * 10, 11, true);
        let here = compress_chunk(native.clone());
        let there: Vec<Vec<u8>> = std::thread::scope(|scope| {
            (0..3)
                .map(|_| scope.spawn(|| compress_chunk(native.clone())))
                .collect::<Vec<_>>()
                .into_iter()
                .map(|thread| thread.join().unwrap())
                .collect()
        });
        assert!(there.iter().all(|bytes| *bytes == here));
        // And again on a thread whose compressor and scratch were used for other chunks.
        compress_chunk(samples(999, 5, false));
        assert_eq!(compress_chunk(native), here);
    }
}
