//! The GLB container and buffer URIs: splitting a GLB into its JSON and BIN chunks, decoding
//! data URIs (base64) and percent-encoded file URIs, naming buffers in messages.

use super::*;

pub(super) const GLB_MAGIC: &[u8; 4] = b"glTF";
pub(super) const GLB_CHUNK_JSON: u32 = 0x4E4F_534A;
pub(super) const GLB_CHUNK_BIN: u32 = 0x004E_4942;

/// The parts of a file: the JSON text and, for GLB, the BIN chunk (possibly cut short) with a
/// note explaining the truncation for the buffer error that will follow.
pub(super) struct Container<'a> {
    pub(super) json: &'a [u8],
    pub(super) bin: Option<&'a [u8]>,
    pub(super) truncation_note: String,
}

pub(super) fn read_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let word: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
    Some(u32::from_le_bytes(word))
}

/// Splits a GLB into its JSON and BIN chunks; anything not starting with the GLB magic is JSON.
/// A BIN chunk cut short by a truncated file is kept as far as it goes, so that the buffer check
/// can say which buffer is short and by how much.
pub(super) fn split_container<'a>(
    path: &Path,
    bytes: &'a [u8],
) -> Result<Container<'a>, CharacterError> {
    if !bytes.starts_with(GLB_MAGIC) {
        return Ok(Container {
            json: bytes,
            bin: None,
            truncation_note: String::new(),
        });
    }
    let not_gltf = |reason: String| CharacterError::NotGltf {
        path: path.to_path_buf(),
        reason,
    };
    let (Some(version), Some(declared_length), Some(json_length), Some(json_type)) = (
        read_u32(bytes, 4),
        read_u32(bytes, 8),
        read_u32(bytes, 12),
        read_u32(bytes, 16),
    ) else {
        return Err(not_gltf(format!(
            "GLB file of {} bytes is shorter than its 20-byte header",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(not_gltf(format!(
            "GLB container version {version}, only 2 is read"
        )));
    }
    if json_type != GLB_CHUNK_JSON {
        return Err(not_gltf(format!(
            "the first GLB chunk has type 0x{json_type:08X}, not JSON"
        )));
    }
    let truncation_note = if (declared_length as usize) > bytes.len() {
        format!(
            " (the file is {} bytes but its GLB header says {declared_length}: the file is truncated)",
            bytes.len()
        )
    } else {
        String::new()
    };
    let json_end = 20 + json_length as usize;
    let Some(json) = bytes.get(20..json_end) else {
        return Err(not_gltf(format!(
            "the GLB JSON chunk needs {json_length} bytes but the file ends first{truncation_note}"
        )));
    };
    let bin = match (read_u32(bytes, json_end), read_u32(bytes, json_end + 4)) {
        (Some(bin_length), Some(GLB_CHUNK_BIN)) => {
            let start = json_end + 8;
            let end = (start + bin_length as usize).min(bytes.len());
            Some(&bytes[start..end])
        }
        // A cut inside the BIN chunk header: the chunk was there but nothing of it survives.
        _ if !truncation_note.is_empty() => Some(&bytes[bytes.len()..]),
        _ => None,
    };
    Ok(Container {
        json,
        bin,
        truncation_note,
    })
}

/// Decodes the payload of a `data:...;base64,` URI.
pub(super) fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let Some((header, payload)) = uri.split_once(',') else {
        return Err("data URI without a ',' before its payload".to_string());
    };
    if !header.ends_with(";base64") {
        return Err(format!("data URI {header:?} is not base64-encoded"));
    }
    decode_base64(payload)
}

/// Standard base64 (RFC 4648, '+' and '/'), padding optional.
pub(super) fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut accumulator: u32 = 0;
    let mut bits = 0;
    for (position, byte) in text.trim_end_matches('=').bytes().enumerate() {
        let value = match byte {
            b'A'..=b'Z' => byte - b'A',
            b'a'..=b'z' => byte - b'a' + 26,
            b'0'..=b'9' => byte - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => {
                return Err(format!(
                    "invalid base64 character {:?} at position {position}",
                    byte as char
                ))
            }
        };
        accumulator = (accumulator << 6) | u32::from(value);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((accumulator >> bits) as u8);
            accumulator &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// `%20` and friends; anything malformed is kept as written.
pub(super) fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            if let Some(value) = uri
                .get(i + 1..i + 3)
                .and_then(|hex| u8::from_str_radix(hex, 16).ok())
            {
                out.push(value);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// A URI with a scheme (`http:`, `file:`, ...) rather than a path relative to the glTF file.
pub(super) fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.len() > 1
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// How a buffer is named in messages: the GLB BIN chunk, an embedded data URI, or its file URI.
pub(super) fn buffer_source_name(buffer: &gltf::Buffer) -> String {
    match buffer.source() {
        gltf::buffer::Source::Bin => "GLB BIN chunk".to_string(),
        gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
            "embedded data URI".to_string()
        }
        gltf::buffer::Source::Uri(uri) => uri.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_strings() {
        assert_eq!(decode_base64("TWFu").unwrap(), b"Man");
        assert_eq!(decode_base64("TWE=").unwrap(), b"Ma");
        assert_eq!(decode_base64("TQ==").unwrap(), b"M");
        assert_eq!(decode_base64("").unwrap(), b"");
        assert!(decode_base64("TW*u").is_err());
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAEC").unwrap(),
            vec![0, 1, 2]
        );
        assert!(decode_data_uri("data:text/plain,hello").is_err());
    }

    #[test]
    fn uri_helpers() {
        assert_eq!(percent_decode("my%20model.bin"), "my model.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert!(has_scheme("http://example.com/a.bin"));
        assert!(!has_scheme("textures/a.png"));
        assert!(!has_scheme("a.bin"));
    }
}
