//! Stage 5, output: receives a [`crate::draw::RenderedFrame`] (linear HDR beauty, distance, true
//! position, flag bits) and writes it as a multi-channel OpenEXR frame, appends its row to the
//! per-frame JSONL report, tone-maps PNG previews, and compares images with FLIP.
//! Every file is written to a temporary name beside its destination, synced and renamed, so an
//! interrupted render never leaves a truncated file.

pub mod compare;
pub mod exr;
pub mod report;
pub mod tonemap;

use std::fs::{self, File};
use std::path::{Path, PathBuf};

pub use self::exr::{frame_path, read_frame_exr, write_frame_exr, FrameMeta, ReadMeta};
pub use compare::{flip_ldr, FlipResult};
pub use report::{FrameReport, ReportWriter};
pub use tonemap::{save_png_atomic, tonemap_srgb8};

/// Everything that can go wrong while writing or reading the stage's files; each variant names the
/// file and the cause.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot create directory {dir}: {cause}")]
    CreateDir { dir: PathBuf, cause: String },
    #[error("cannot write {path}: {cause}")]
    Write { path: PathBuf, cause: String },
    #[error("cannot read {path}: {cause}")]
    Read { path: PathBuf, cause: String },
    #[error("{path}:{line}: {cause}")]
    Parse {
        path: PathBuf,
        line: usize,
        cause: String,
    },
}

impl OutputError {
    /// Whether the user's choice of output location is at fault (the CLI exits with 2): a directory
    /// that cannot be created, or an existing report that is not snell's. Failures while writing
    /// (a full disk, an I/O error) are not.
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            OutputError::CreateDir { .. } | OutputError::Parse { .. }
        )
    }
}

/// Creates `dir` and its parents. When that fails because something on the way is a regular file
/// (the usual way an output path cannot be created when running as root), the error says which.
pub fn ensure_output_dir(dir: &Path) -> Result<(), OutputError> {
    if dir.as_os_str().is_empty() || dir.is_dir() {
        return Ok(());
    }
    fs::create_dir_all(dir).map_err(|error| {
        let blocking_file = dir.ancestors().find(|ancestor| ancestor.is_file());
        let cause = match blocking_file {
            Some(file) => format!("a path component is a regular file ({})", file.display()),
            None => error.to_string(),
        };
        OutputError::CreateDir {
            dir: dir.to_path_buf(),
            cause,
        }
    })
}

/// The temporary name a file is written under before the rename: hidden, in the same directory
/// (so the rename cannot cross file systems), unique per process.
fn temporary_path_for(path: &Path) -> PathBuf {
    let file_name = path
        .file_name()
        .map(|name| name.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{file_name}.tmp-{}", std::process::id()))
}

/// Writes `path` atomically: creates the parent directory, lets `write_contents` fill a temporary
/// file beside it, syncs it to disk and renames it over `path`. On any error the temporary file is
/// removed and `path` is left as it was.
pub(crate) fn write_atomically(
    path: &Path,
    write_contents: impl FnOnce(&mut File) -> Result<(), String>,
) -> Result<(), OutputError> {
    if let Some(parent) = path.parent() {
        ensure_output_dir(parent)?;
    }
    let temporary_path = temporary_path_for(path);
    let write_error = |cause: String| OutputError::Write {
        path: path.to_path_buf(),
        cause,
    };
    let result = (|| {
        let mut file = File::create(&temporary_path).map_err(|error| error.to_string())?;
        write_contents(&mut file)?;
        file.sync_all()
            .map_err(|error| format!("sync failed: {error}"))?;
        drop(file);
        fs::rename(&temporary_path, path)
            .map_err(|error| format!("rename from {}: {error}", temporary_path.display()))
    })();
    if let Err(cause) = result {
        // The temporary file may not exist (creation failed); either way it must not stay behind.
        let _ = fs::remove_file(&temporary_path);
        return Err(write_error(cause));
    }
    sync_parent_dir(path);
    Ok(())
}

/// Makes the rename itself durable. Best effort: not every platform can open a directory.
fn sync_parent_dir(path: &Path) {
    if let Some(parent) = path
        .parent()
        .filter(|parent| !parent.as_os_str().is_empty())
    {
        if let Ok(dir) = File::open(parent) {
            let _ = dir.sync_all();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_dir_through_a_regular_file_names_the_file() {
        let temp = tempfile::tempdir().unwrap();
        let blocker = temp.path().join("not-a-dir");
        fs::write(&blocker, b"x").unwrap();
        let error = ensure_output_dir(&blocker.join("frames")).unwrap_err();
        let message = error.to_string();
        assert!(message.starts_with("cannot create directory "), "{message}");
        assert!(
            message.contains("a path component is a regular file"),
            "{message}"
        );
        assert!(message.contains("not-a-dir"), "{message}");
    }

    #[test]
    fn atomic_write_leaves_no_temporary_on_failure() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("out.bin");
        fs::write(&path, b"old").unwrap();
        let error = write_atomically(&path, |_| Err("simulated failure".into())).unwrap_err();
        assert!(error.to_string().contains("simulated failure"));
        assert_eq!(
            fs::read(&path).unwrap(),
            b"old",
            "the destination must be untouched"
        );
        let leftovers: Vec<_> = fs::read_dir(temp.path())
            .unwrap()
            .map(|entry| entry.unwrap().file_name())
            .collect();
        assert_eq!(leftovers, vec![std::ffi::OsString::from("out.bin")]);
    }
}
