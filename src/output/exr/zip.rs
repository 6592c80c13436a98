//! EXR `zip` and `zips` chunks compressed here, with zlib-rs at level 1, instead of by the `exr`
//! crate (miniz_oxide at level 4, 3-5x slower on snell's layers for files 0.1-0.6 % smaller:
//! deflate was half of a written frame's CPU time, issue 14 point 4).
//!
//! Why zlib-rs level 1 (zlib-ng's `deflate_quick`: greedy matches, the fixed Huffman code) and
//! not libdeflate level 1, which this module used before: on the 16-line chunks of a 1280x720
//! `pool.toml` `comp` frame (31.3 MB of samples, split and predicted) libdeflate level 1 took
//! 93-95 ms on one thread for 7.11 MB, zlib-rs level 1 49 ms for 7.83 MB (+10 %); zlib-rs levels 2
//! and 3 took 113 and 126 ms (7.22 and 7.10 MB), its RLE and Huffman-only strategies 110 and
//! 155 ms (13.3 and 16.5 MB) (README, "Where a written frame's time goes").
//!
//! OpenEXR's ZIP compression of a chunk (`ImfZip.cpp`): the chunk's little-endian bytes are split
//! into the even-indexed bytes followed by the odd-indexed ones, each byte is replaced by its
//! difference to the one before plus 128 (mod 256; the first byte kept), and the result is one
//! zlib stream; any conforming stream decodes the same. A chunk whose stream is not smaller than
//! its raw bytes is stored raw, as OpenEXR and the `exr` crate do (readers tell the two apart by
//! the size). The bytes depend only on the chunk's pixels and [`LEVEL`]: not on thread counts or
//! on which thread compresses which chunk.

use std::cell::RefCell;

/// zlib-rs's compression level: 1, its fastest that compresses (see above).
pub(crate) const LEVEL: i32 = 1;

/// Each encoding thread's scratch, kept from chunk to chunk: fresh buffers for every chunk cost
/// page faults on zeroed memory (8 % of a written frame's CPU time before).
struct Work {
    /// The chunk's bytes separated and predicted, then compressed.
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
            predicted: Vec::new(),
            packed: Vec::new(),
        });
        separate_and_predict(native, &mut work.predicted);
        let bound = zlib_rs::compress_bound(native.len());
        if work.packed.len() < bound {
            work.packed.resize(bound, 0);
        }
        let config = zlib_rs::DeflateConfig {
            level: LEVEL,
            ..zlib_rs::DeflateConfig::default()
        };
        let (packed, code) = zlib_rs::compress_slice(&mut work.packed, &work.predicted, config);
        if code == zlib_rs::ReturnCode::Ok && packed.len() < native.len() {
            out.extend_from_slice(packed);
        } else {
            // Not smaller (or the compressor failed, which it does not with room for the bound).
            out.extend_from_slice(native);
        }
    })
}

/// OpenEXR's byte split and predictor in one pass: `out` = the even-indexed bytes of `bytes`
/// followed by the odd-indexed ones (the split), each replaced by its difference to the byte
/// before it in that sequence plus 128, mod 256 (the predictor; the first byte kept). One pass
/// over the chunk instead of two, and no buffer between them: a split byte's predecessor is two
/// bytes back in `bytes`, except for the first odd byte, whose predecessor is the last even one.
/// Sixteen pairs at a time with AVX2 where the CPU has it (4-5x faster than one pair at a time:
/// 6.4-7.3 ms instead of 28-35 ms for the 16-line chunks of a 1280x720 `all` frame, one thread;
/// the same bytes, tested).
fn separate_and_predict(bytes: &[u8], out: &mut Vec<u8>) {
    let n = bytes.len();
    out.clear();
    out.resize(n, 0);
    if n < 2 {
        out.copy_from_slice(bytes);
        return;
    }
    let half = n.div_ceil(2);
    let (evens, odds) = out.split_at_mut(half);
    evens[0] = bytes[0];
    // Pair k is bytes[2k], bytes[2k+1]: evens[k] = bytes[2k] - bytes[2k-2] + 128 and
    // odds[k] = bytes[2k+1] - bytes[2k-1] + 128 for 1 <= k < pairs.
    let pairs = n / 2;
    let mut next = 1;
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (detected above).
        next = unsafe { predict_pairs_avx2(bytes, evens, odds, pairs) };
    }
    for k in next..pairs {
        evens[k] = bytes[2 * k]
            .wrapping_sub(bytes[2 * k - 2])
            .wrapping_add(128);
        odds[k] = bytes[2 * k + 1]
            .wrapping_sub(bytes[2 * k - 1])
            .wrapping_add(128);
    }
    if n % 2 == 1 {
        // The last even byte has no odd partner, so the pairs stop before it.
        evens[half - 1] = bytes[n - 1].wrapping_sub(bytes[n - 3]).wrapping_add(128);
    }
    let last_even = bytes[2 * (half - 1)];
    odds[0] = bytes[1].wrapping_sub(last_even).wrapping_add(128);
}

/// Pairs 1, 2, ... of [`separate_and_predict`] sixteen at a time, while sixteen remain before
/// `pairs`; returns the first pair not done. Each step: the 32 bytes of pairs k..k+16 minus the
/// 32 bytes two before them, plus 128 (a flip of the top bit), then the evens and odds of each
/// 128-bit lane gathered (a byte shuffle) and the lanes' halves ordered evens first (a 64-bit
/// permute).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn predict_pairs_avx2(
    bytes: &[u8],
    evens: &mut [u8],
    odds: &mut [u8],
    pairs: usize,
) -> usize {
    use std::arch::x86_64::{
        __m128i, __m256i, _mm256_castsi256_si128, _mm256_extracti128_si256, _mm256_loadu_si256,
        _mm256_permute4x64_epi64, _mm256_set1_epi8, _mm256_setr_epi8, _mm256_shuffle_epi8,
        _mm256_sub_epi8, _mm256_xor_si256, _mm_storeu_si128,
    };
    assert!(2 * pairs <= bytes.len() && pairs <= evens.len() && pairs <= odds.len());
    let split = _mm256_setr_epi8(
        0, 2, 4, 6, 8, 10, 12, 14, 1, 3, 5, 7, 9, 11, 13, 15, 0, 2, 4, 6, 8, 10, 12, 14, 1, 3, 5,
        7, 9, 11, 13, 15,
    );
    let top_bit = _mm256_set1_epi8(-128);
    let mut k = 1;
    while k + 16 <= pairs {
        // SAFETY: bytes 2k-2 .. 2k+32 <= 2 pairs, and evens and odds k .. k+16 <= pairs, are in
        // the slices (asserted above); the loads and stores are unaligned.
        let now = _mm256_loadu_si256(bytes.as_ptr().add(2 * k).cast::<__m256i>());
        let before = _mm256_loadu_si256(bytes.as_ptr().add(2 * k - 2).cast::<__m256i>());
        let predicted = _mm256_xor_si256(_mm256_sub_epi8(now, before), top_bit);
        let lanes = _mm256_shuffle_epi8(predicted, split);
        let grouped = _mm256_permute4x64_epi64::<0b11_01_10_00>(lanes);
        _mm_storeu_si128(
            evens.as_mut_ptr().add(k).cast::<__m128i>(),
            _mm256_castsi256_si128(grouped),
        );
        _mm_storeu_si128(
            odds.as_mut_ptr().add(k).cast::<__m128i>(),
            _mm256_extracti128_si256::<1>(grouped),
        );
        k += 16;
    }
    k
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
        let mut predicted = Vec::new();
        separate_and_predict(&[10, 20, 30, 40, 50], &mut predicted);
        assert_eq!(predicted, [10, 148, 148, 98, 148]);
        // Even length: separated 10 30 20 40.
        separate_and_predict(&[10, 20, 30, 40], &mut predicted);
        assert_eq!(predicted, [10, 148, 118, 148]);
        // Wrapping: separated 250 5 0 (mod 256: 5-250+128 = 139, 0-5+128 = 123).
        separate_and_predict(&[250, 0, 5], &mut predicted);
        assert_eq!(predicted, [250, 139, 123]);
        for short in [&[][..], &[7][..], &[7, 9][..]] {
            separate_and_predict(short, &mut predicted);
            let expected: Vec<u8> = match short {
                [] => vec![],
                [a] => vec![*a],
                _ => vec![7, 130],
            };
            assert_eq!(predicted, expected, "{short:?}");
        }
    }

    /// ImfZip.cpp's two steps, one after the other, as OpenEXR writes them: the split into even-
    /// and odd-indexed bytes, then the predictor over the split bytes.
    fn split_then_predict(bytes: &[u8]) -> Vec<u8> {
        let mut split: Vec<u8> = bytes.iter().step_by(2).copied().collect();
        split.extend(bytes.iter().skip(1).step_by(2));
        let mut predicted = split.clone();
        for i in 1..split.len() {
            predicted[i] = split[i].wrapping_sub(split[i - 1]).wrapping_add(128);
        }
        predicted
    }

    #[test]
    fn the_one_pass_transform_is_the_two_steps_at_every_length() {
        // Every length up to several 32-byte steps (the AVX2 path and the tail after it), odd
        // and even, on noise and on a smooth ramp; then a whole 16-line chunk of a frame.
        let mut predicted = Vec::new();
        for len in 0..=300 {
            for smooth in [false, true] {
                let bytes = samples(len, len as u64 + 1, smooth);
                separate_and_predict(&bytes, &mut predicted);
                assert_eq!(predicted, split_then_predict(&bytes), "{len} bytes");
            }
        }
        let chunk = samples(1281 * 16 * 10 + 3, 17, true);
        separate_and_predict(&chunk, &mut predicted);
        assert_eq!(predicted, split_then_predict(&chunk));
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

    /// This thread's CPU seconds (not waiting for a core: the machine is shared).
    fn thread_cpu_secs() -> f64 {
        let mut time = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime fills the struct it is given; the clock id is a valid constant.
        unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut time) };
        time.tv_sec as f64 + time.tv_nsec as f64 * 1e-9
    }

    /// What each layer of a frame costs to encode (issue 14 point 4): the file's channels grouped
    /// by layer (`R, G, B, A` as the beauty), each group's 16-line (ZIP) and 1-line (ZIPS) chunks
    /// built as the writer builds them (rows of each channel's samples, name order), then per
    /// group the CPU of the split and predictor alone, of the whole ZIP chunk (split, predictor and
    /// zlib-rs) and of the `exr` crate's RLE (1-line chunks, with ZIPS's row), and the bytes each gives; best of 5 on one thread.
    /// `SNELL_LAYER_COSTS_EXR=frame.exr cargo test --release --lib
    /// output::exr::zip::tests::layer_costs -- --ignored --nocapture` (any compression: the
    /// samples are read back first).
    #[test]
    #[ignore = "tuning aid"]
    fn layer_costs() {
        let path = std::env::var("SNELL_LAYER_COSTS_EXR").expect("SNELL_LAYER_COSTS_EXR=frame.exr");
        let file = crate::output::exr::read_channels(std::path::Path::new(&path)).unwrap();
        let (width, height) = (file.width, file.height);
        let mut groups: std::collections::BTreeMap<String, Vec<&str>> = Default::default();
        for name in file.channels.keys() {
            let layer = match name.split_once('.') {
                Some((layer, _)) => layer,
                None if ["R", "G", "B", "A"].contains(&name.as_str()) => "beauty",
                None => name,
            };
            groups.entry(layer.to_string()).or_default().push(name);
        }
        groups.insert(
            "(the whole file)".into(),
            file.channels.keys().map(String::as_str).collect(),
        );
        let sample = |name: &str, i: usize, out: &mut Vec<u8>| {
            let value = file.channels[name][i];
            match file.types[name] {
                "f16" => out.extend_from_slice(
                    &::exr::prelude::f16::from_f32(value).to_bits().to_le_bytes(),
                ),
                "f32" => out.extend_from_slice(&value.to_le_bytes()),
                _ => out.extend_from_slice(&(value as u32).to_le_bytes()),
            }
        };
        let types_of = |names: &[&str]| -> Vec<(String, SampleType)> {
            names
                .iter()
                .map(|name| {
                    let t = match file.types[*name] {
                        "f16" => SampleType::F16,
                        "f32" => SampleType::F32,
                        _ => SampleType::U32,
                    };
                    (name.to_string(), t)
                })
                .collect()
        };
        println!("| layer | lines | samples MB | ZIP MB | split+predict ms | ZIP ms (all of it) | ZIP MB/s | RLE MB | RLE ms |");
        println!("|---|---|---|---|---|---|---|---|---|");
        for (layer, names) in &groups {
            for lines in [16, 1] {
                let chunks: Vec<Vec<u8>> = (0..height.div_ceil(lines))
                    .map(|chunk| {
                        let mut bytes = Vec::new();
                        for y in chunk * lines..((chunk + 1) * lines).min(height) {
                            for name in names {
                                (y * width..(y + 1) * width)
                                    .for_each(|i| sample(name, i, &mut bytes));
                            }
                        }
                        bytes
                    })
                    .collect();
                let raw: usize = chunks.iter().map(Vec::len).sum();
                let best = |f: &mut dyn FnMut() -> usize| {
                    (0..5)
                        .map(|_| {
                            let start = thread_cpu_secs();
                            let size = f();
                            (thread_cpu_secs() - start, size)
                        })
                        .min_by(|a, b| a.0.total_cmp(&b.0))
                        .unwrap()
                };
                let mut scratch = Vec::new();
                let (predict_secs, _) = best(&mut || {
                    chunks
                        .iter()
                        .for_each(|c| separate_and_predict(c, &mut scratch));
                    0
                });
                let mut out = Vec::new();
                let (zip_secs, zip_size) = best(&mut || {
                    chunks
                        .iter()
                        .map(|c| {
                            out.clear();
                            append_chunk(c, &mut out);
                            out.len()
                        })
                        .sum()
                });
                let rle = if lines == 1 {
                    let types = types_of(names);
                    let types: Vec<(&str, SampleType)> =
                        types.iter().map(|(n, t)| (n.as_str(), *t)).collect();
                    let header = header(width, height, &types, Compression::RLE);
                    let (secs, size) = best(&mut || {
                        chunks
                            .iter()
                            .enumerate()
                            .map(|(y, c)| {
                                // RLE chunks are one line each, as ZIPS's.
                                let section = IntegerBounds::new(Vec2(0, y as i32), Vec2(width, 1));
                                let packed = Compression::RLE
                                    .compress_image_section_to_le(&header, c.clone(), section)
                                    .unwrap();
                                packed.len().min(c.len())
                            })
                            .sum()
                    });
                    format!("{:.2} | {:.1}", size as f64 / 1e6, secs * 1e3)
                } else {
                    " | ".to_string()
                };
                println!(
                    "| {layer} | {lines} | {:.2} | {:.2} | {:.1} | {:.1} | {:.0} | {rle} |",
                    raw as f64 / 1e6,
                    zip_size as f64 / 1e6,
                    predict_secs * 1e3,
                    zip_secs * 1e3,
                    raw as f64 / 1e6 / zip_secs
                );
            }
        }
    }
}
