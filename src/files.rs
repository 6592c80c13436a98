//! Input files, read safely. Every file snell reads on a user's word (scene files, glTF models
//! with their buffers and images, image textures, EXR frames, point lists) must be a regular file
//! no larger than a stated cap: a FIFO would block the read forever, `/dev/zero` or a directory
//! would never end or not be data at all, and a multi-gigabyte file would exhaust memory before
//! any check could run. The file is opened without blocking (so a FIFO cannot stall the open),
//! its type is checked on the open descriptor (so it cannot be swapped after the check), and the
//! read stops one byte past the cap.

use std::io::Read;
use std::path::{Path, PathBuf};

/// The largest scene file read (a scene of a million keyframes is well under this).
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// The largest glTF, GLB, glTF buffer or image file read.
pub const MAX_ASSET_BYTES: u64 = 512 << 20;
/// The largest points file `snell locate` reads.
pub const MAX_POINTS_BYTES: u64 = 64 << 20;

/// Why an input file cannot be used. `Display` says which file, what is wrong, and nothing about
/// what to do (the caller knows where the path came from and says that).
#[derive(Debug, thiserror::Error)]
pub enum InputFileError {
    #[error("{}: no such file", .0.display())]
    NotFound(PathBuf),
    #[error("{}: is {kind}, not a regular file", .path.display())]
    NotRegular { path: PathBuf, kind: &'static str },
    #[error("{}: is {} bytes, more than the {} bytes snell reads from such a file", .path.display(), .size, .max)]
    TooLarge { path: PathBuf, size: u64, max: u64 },
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl InputFileError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            InputFileError::NotFound(path)
            | InputFileError::NotRegular { path, .. }
            | InputFileError::TooLarge { path, .. }
            | InputFileError::Io { path, .. } => path,
        }
    }
}

/// What a file system entry is, in words, for messages.
fn kind_of(file_type: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if file_type.is_dir() {
        "a directory"
    } else if file_type.is_fifo() {
        "a FIFO (named pipe)"
    } else if file_type.is_char_device() {
        "a character device"
    } else if file_type.is_block_device() {
        "a block device"
    } else if file_type.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

fn io_error(path: &Path, source: std::io::Error) -> InputFileError {
    if source.kind() == std::io::ErrorKind::NotFound {
        InputFileError::NotFound(path.to_path_buf())
    } else {
        InputFileError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Checks that `path` names a regular file (symbolic links followed) of at most `max_bytes`,
/// without opening it. For validation that names the file before it is read.
pub fn check_regular(path: &Path, max_bytes: u64) -> Result<u64, InputFileError> {
    let metadata = std::fs::metadata(path).map_err(|e| io_error(path, e))?;
    check_metadata(path, &metadata, max_bytes)
}

/// A regular file of at most `max_bytes`: its length, or why not.
fn check_metadata(
    path: &Path,
    metadata: &std::fs::Metadata,
    max_bytes: u64,
) -> Result<u64, InputFileError> {
    if !metadata.file_type().is_file() {
        return Err(InputFileError::NotRegular {
            path: path.to_path_buf(),
            kind: kind_of(metadata.file_type()),
        });
    }
    if metadata.len() > max_bytes {
        return Err(InputFileError::TooLarge {
            path: path.to_path_buf(),
            size: metadata.len(),
            max: max_bytes,
        });
    }
    Ok(metadata.len())
}

/// Opens `path` for reading if it is a regular file of at most `max_bytes`.
pub fn open_regular(path: &Path, max_bytes: u64) -> Result<std::fs::File, InputFileError> {
    use std::os::unix::fs::OpenOptionsExt;
    // Non-blocking, so opening a FIFO with no writer returns at once instead of waiting.
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| io_error(path, e))?;
    let metadata = file.metadata().map_err(|e| io_error(path, e))?;
    check_metadata(path, &metadata, max_bytes)?;
    Ok(file)
}

/// The whole of `path`, which must be a regular file of at most `max_bytes` (also while it is
/// read: a file that grows past the cap is refused).
pub fn read_regular(path: &Path, max_bytes: u64) -> Result<Vec<u8>, InputFileError> {
    let file = open_regular(path, max_bytes)?;
    let expected = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut bytes = Vec::with_capacity(expected.min(max_bytes) as usize);
    file.take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| io_error(path, e))?;
    if bytes.len() as u64 > max_bytes {
        return Err(InputFileError::TooLarge {
            path: path.to_path_buf(),
            size: bytes.len() as u64,
            max: max_bytes,
        });
    }
    Ok(bytes)
}

/// The largest image side decoded (a texture larger than the GPU's 16K limit cannot be drawn).
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// The most memory one image decoder may allocate (a 16K x 16K RGBA8 image is 1 GiB).
pub const MAX_IMAGE_DECODE_BYTES: u64 = 1 << 30;

/// Decodes a PNG or JPEG into RGBA8 within [`MAX_IMAGE_SIDE`] and [`MAX_IMAGE_DECODE_BYTES`], so a
/// small file that claims a huge image (a decompression bomb) is refused before it is allocated.
pub fn decode_image_rgba8(bytes: &[u8]) -> Result<image::RgbaImage, String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(MAX_IMAGE_DECODE_BYTES);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => format!(
            "the image is larger than {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} pixels or needs more than \
             {} MiB to decode",
            MAX_IMAGE_DECODE_BYTES >> 20
        ),
        other => other.to_string(),
    })?;
    let (width, height) = (decoded.width() as u64, decoded.height() as u64);
    if width * height * 4 > MAX_IMAGE_DECODE_BYTES {
        return Err(format!(
            "the image is {width}x{height} pixels, more than {} MiB as RGBA",
            MAX_IMAGE_DECODE_BYTES >> 20
        ));
    }
    Ok(decoded.to_rgba8())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_files_are_read_and_everything_else_refused_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.toml");
        std::fs::write(&file, b"name = \"a\"\n").unwrap();
        assert_eq!(read_regular(&file, 100).unwrap(), b"name = \"a\"\n");
        assert!(matches!(
            read_regular(&file, 4),
            Err(InputFileError::TooLarge {
                size: 11,
                max: 4,
                ..
            })
        ));
        assert!(matches!(
            read_regular(&dir.path().join("missing"), 100),
            Err(InputFileError::NotFound(_))
        ));
        let message = read_regular(dir.path(), 100).unwrap_err().to_string();
        assert!(
            message.ends_with("is a directory, not a regular file"),
            "{message}"
        );
        let message = read_regular(Path::new("/dev/zero"), 100)
            .unwrap_err()
            .to_string();
        assert!(message.contains("a character device"), "{message}");
        // A FIFO with no writer: refused without blocking.
        let fifo = dir.path().join("pipe");
        let name = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
        let message = read_regular(&fifo, 100).unwrap_err().to_string();
        assert!(message.contains("a FIFO"), "{message}");
        assert!(check_regular(&fifo, 100).is_err());
        assert_eq!(check_regular(&file, 100).unwrap(), 11);
        // Symbolic links to regular files are fine; to devices they are not.
        let link = dir.path().join("link");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        assert!(read_regular(&link, 100).is_err());
    }

    #[test]
    fn images_that_claim_huge_sizes_are_refused_before_decoding() {
        // A valid PNG header claiming 100000 x 100000 pixels, and nothing after it.
        fn crc32(bytes: &[u8]) -> u32 {
            let mut crc = !0u32;
            for &byte in bytes {
                crc ^= byte as u32;
                for _ in 0..8 {
                    crc = if crc & 1 != 0 {
                        (crc >> 1) ^ 0xEDB8_8320
                    } else {
                        crc >> 1
                    };
                }
            }
            !crc
        }
        let mut chunk = b"IHDR".to_vec();
        chunk.extend(100_000u32.to_be_bytes());
        chunk.extend(100_000u32.to_be_bytes());
        chunk.extend([8, 6, 0, 0, 0]);
        let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\r".to_vec();
        png.extend(&chunk);
        png.extend(crc32(&chunk).to_be_bytes());
        let message = decode_image_rgba8(&png).unwrap_err();
        assert!(message.contains("larger than 16384x16384"), "{message}");
        let mut small = Vec::new();
        image::RgbaImage::from_pixel(3, 2, image::Rgba([1, 2, 3, 4]))
            .write_to(
                &mut std::io::Cursor::new(&mut small),
                image::ImageFormat::Png,
            )
            .unwrap();
        assert_eq!(decode_image_rgba8(&small).unwrap().dimensions(), (3, 2));
    }
}
