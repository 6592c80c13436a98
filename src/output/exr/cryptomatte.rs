//! Cryptomatte (Psyop's published specification, versions 1.1 and 1.2): IDs from names by
//! MurmurHash3_x86_32 (seed 0), stored as float32 bit patterns whose exponent is kept inside
//! 1..=254 (bit 23 flipped where it is 0 or 255, the same values as the spec's clamp), ranked
//! (id, coverage) pairs per pixel, and the header metadata
//! `cryptomatte/<key>/name|hash|conversion|manifest` with `key` the first 7 hex digits of the
//! hash of the type name.
//!
//! What a pixel holds (one sample per pixel today, so coverage is not a fraction of area but of
//! the light): an object seen directly has coverage 1. In a water pixel the water surface and the
//! object seen through it share the pixel by their part of the beauty: the water gets Schlick's
//! reflectance F (the reflected share), the object 1 - F (the refracted share); the two sum to 1,
//! so a matte of the object through water is its refracted contribution. Water with nothing
//! behind it gives the water coverage 1. Sky has no ID (0, 0). Ranks are by coverage, larger
//! first; on a tie the object comes first.

use std::collections::BTreeMap;

/// MurmurHash3_x86_32 of `data` with `seed` (Austin Appleby's public-domain reference).
pub fn murmur3_32(data: &[u8], seed: u32) -> u32 {
    const C1: u32 = 0xcc9e_2d51;
    const C2: u32 = 0x1b87_3593;
    let mix = |mut k: u32| {
        k = k.wrapping_mul(C1);
        k = k.rotate_left(15);
        k.wrapping_mul(C2)
    };
    let mut h = seed;
    let mut blocks = data.chunks_exact(4);
    for block in &mut blocks {
        h ^= mix(u32::from_le_bytes([block[0], block[1], block[2], block[3]]));
        h = h.rotate_left(13);
        h = h.wrapping_mul(5).wrapping_add(0xe654_6b64);
    }
    let tail = blocks.remainder();
    if !tail.is_empty() {
        let mut k = 0u32;
        for (i, &byte) in tail.iter().enumerate() {
            k ^= (byte as u32) << (8 * i);
        }
        h ^= mix(k);
    }
    h ^= data.len() as u32;
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// The float32 bits of a name's ID: its hash with bit 23 flipped when the exponent would be 0
/// (denormal or zero) or 255 (infinity or NaN).
pub fn id_bits(name: &str) -> u32 {
    let hash = murmur3_32(name.as_bytes(), 0);
    let exponent = (hash >> 23) & 0xff;
    if exponent == 0 || exponent == 0xff {
        hash ^ (1 << 23)
    } else {
        hash
    }
}

/// A name's ID as the pixels hold it.
pub fn id_float(name: &str) -> f32 {
    f32::from_bits(id_bits(name))
}

/// The 7-hex-digit metadata key of a Cryptomatte type (`CryptoObject`).
pub fn metadata_key(type_name: &str) -> String {
    format!("{:08x}", murmur3_32(type_name.as_bytes(), 0))[..7].to_string()
}

/// The manifest: JSON object of name to the 8 hex digits of its ID's float bits, names sorted.
pub fn manifest(names: impl IntoIterator<Item = impl AsRef<str>>) -> String {
    let map: BTreeMap<String, String> = names
        .into_iter()
        .map(|name| {
            let name = name.as_ref().to_string();
            let hex = format!("{:08x}", id_bits(&name));
            (name, hex)
        })
        .collect();
    serde_json::to_string(&map).expect("a map of strings serialises")
}

/// The Cryptomatte name of the water surface: `water`, unless an object or character already
/// has that name (their IDs would merge), then `water surface`, `water surface 2`, ...
pub fn water_name(object_names: &[String]) -> String {
    let taken = |name: &str| object_names.iter().any(|n| n == name);
    if !taken("water") {
        return "water".to_string();
    }
    (1..)
        .map(|n| {
            if n == 1 {
                "water surface".to_string()
            } else {
                format!("water surface {n}")
            }
        })
        .find(|name| !taken(name))
        .expect("some name is free")
}

/// The ranked (id, coverage) pairs of one pixel: `object` the ID of the object seen (directly or
/// through the water), `water` Some(F) where the first surface is the water.
pub fn pixel_ranks(object: Option<f32>, water: Option<(f32, f32)>) -> [(f32, f32); 2] {
    const NONE: (f32, f32) = (0.0, 0.0);
    match (object, water) {
        (None, None) => [NONE, NONE],
        (Some(object), None) => [(object, 1.0), NONE],
        (None, Some((water, _))) => [(water, 1.0), NONE],
        (Some(object), Some((water, reflectance))) => {
            let (object_share, water_share) = (1.0 - reflectance, reflectance);
            if water_share > object_share {
                [(water, water_share), (object, object_share)]
            } else {
                [(object, object_share), (water, water_share)]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Published MurmurHash3_x86_32 vectors (seeds 0, 1, 0xffffffff and 0x9747b28c), covering every
    /// tail length.
    #[test]
    fn murmur3_matches_the_published_vectors() {
        let cases: [(&[u8], u32, u32); 12] = [
            (b"", 0, 0),
            (b"", 1, 0x514e_28b7),
            (b"", 0xffff_ffff, 0x81f1_6f39),
            (&[0, 0, 0, 0], 0, 0x2362_f9de),
            (&[0xff, 0xff, 0xff, 0xff], 0, 0x7629_3b50),
            (&[0x21, 0x43, 0x65, 0x87], 0, 0xf55b_516b),
            (&[0x21, 0x43, 0x65], 0, 0x7e4a_8634),
            (&[0x21, 0x43], 0, 0xa0f7_b07a),
            (&[0x21], 0, 0x7266_1cf4),
            (b"Hello, world!", 0x9747_b28c, 0x2488_4cba),
            (b"aaaa", 0x9747_b28c, 0x5a97_808a),
            (
                b"The quick brown fox jumps over the lazy dog",
                0x9747_b28c,
                0x2fa8_26cd,
            ),
        ];
        for (data, seed, expected) in cases {
            assert_eq!(murmur3_32(data, seed), expected, "{data:?} seed {seed:#x}");
        }
    }

    /// The specification's own manifest example.
    #[test]
    fn ids_match_the_specifications_manifest_example() {
        assert_eq!(format!("{:08x}", id_bits("bunny")), "13851a76");
        assert_eq!(format!("{:08x}", id_bits("default")), "42c9679f");
        assert_eq!(
            manifest(["default", "bunny"]),
            r#"{"bunny":"13851a76","default":"42c9679f"}"#
        );
    }

    #[test]
    fn ids_are_finite_normal_floats() {
        for i in 0..20_000 {
            let id = id_float(&format!("object{i}"));
            assert!(id.is_normal(), "{i}: {id}");
        }
        // A hash whose exponent is 0 or 255 is moved by one exponent step, as the spec's clamp.
        for hash in [0u32, 0x007f_ffff, 0x7f80_0000, 0xffff_ffff, 0x8000_0001] {
            let exponent = (hash >> 23) & 0xff;
            let flipped = if exponent == 0 || exponent == 255 {
                hash ^ (1 << 23)
            } else {
                hash
            };
            let clamped_exponent = exponent.clamp(1, 254);
            assert_eq!((flipped >> 23) & 0xff, clamped_exponent, "{hash:#x}");
        }
    }

    #[test]
    fn water_never_shares_an_objects_name() {
        assert_eq!(water_name(&["ball".into()]), "water");
        assert_eq!(water_name(&["water".into()]), "water surface");
        assert_eq!(
            water_name(&["water".into(), "water surface".into()]),
            "water surface 2"
        );
    }

    #[test]
    fn water_pixels_share_coverage_by_fresnel() {
        assert_eq!(pixel_ranks(None, None), [(0.0, 0.0); 2]);
        assert_eq!(pixel_ranks(Some(3.0), None), [(3.0, 1.0), (0.0, 0.0)]);
        assert_eq!(
            pixel_ranks(None, Some((7.0, 0.1))),
            [(7.0, 1.0), (0.0, 0.0)]
        );
        let [first, second] = pixel_ranks(Some(3.0), Some((7.0, 0.25)));
        assert_eq!((first, second), ((3.0, 0.75), (7.0, 0.25)));
        // Grazing: the reflection dominates, so the water ranks first.
        let [first, second] = pixel_ranks(Some(3.0), Some((7.0, 0.75)));
        assert_eq!((first, second), ((7.0, 0.75), (3.0, 0.25)));
        assert_eq!(first.1 + second.1, 1.0);
    }
}
