//! Stage 5, output: receives a [`crate::draw::RenderedFrame`] (linear HDR beauty, distance, true
//! position, flag bits) and writes it as a multi-channel OpenEXR frame, appends its row to the
//! per-frame JSONL report, tone-maps PNG previews, and compares images with FLIP.
//! Every file is written to a temporary name beside its destination, synced and renamed, so an
//! interrupted render never leaves a truncated file.

pub mod compare;
pub mod exr;
pub mod lock;
pub mod pattern;
pub mod position_error;
pub mod report;
pub mod temporary;
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
    /// The output directory exists but files cannot be created in it.
    #[error("cannot write into directory {dir}: {cause}")]
    NotWritable { dir: PathBuf, cause: String },
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
    /// that cannot be created or written into, or an existing report that is not snell's. Failures
    /// while writing (a full disk, an I/O error) are not.
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            OutputError::CreateDir { .. }
                | OutputError::NotWritable { .. }
                | OutputError::Parse { .. }
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

/// Checks that files can be created in `dir` (which exists) before any work is done, by creating
/// and removing a temporary file there: a read-only or pseudo file system fails here with exit 2
/// instead of after the first frame.
pub fn check_writable(dir: &Path) -> Result<(), OutputError> {
    let probe = temporary::temporary_path_for(&dir.join("write-check"));
    match temporary::create(&probe) {
        Ok(file) => {
            drop(file);
            let _ = fs::remove_file(&probe);
            temporary::release(&probe);
            Ok(())
        }
        Err(error) => Err(OutputError::NotWritable {
            dir: dir.to_path_buf(),
            cause: error.to_string(),
        }),
    }
}

/// Writes `path` atomically: creates the parent directory, lets `write_contents` fill a temporary
/// file beside it, syncs it to disk and renames it over `path`. On any error the temporary file is
/// removed and `path` is left as it was.
pub(crate) fn write_atomically(
    path: &Path,
    write_contents: impl FnOnce(&mut File) -> Result<(), String>,
) -> Result<(), OutputError> {
    write_unsynced(path, write_contents)?.commit()
}

/// The first half of [`write_atomically`]: `write_contents` fills the temporary file beside
/// `path`, which is neither synced nor renamed until [`Unsynced::commit`]. So a writer can hand the
/// fsync (tens of milliseconds of waiting a frame) to another thread and encode the next file
/// meanwhile. On error, or when the result is dropped uncommitted, the temporary file is removed.
pub(crate) fn write_unsynced(
    path: &Path,
    write_contents: impl FnOnce(&mut File) -> Result<(), String>,
) -> Result<Unsynced, OutputError> {
    if let Some(parent) = path.parent() {
        ensure_output_dir(parent)?;
    }
    let temporary_path = temporary::temporary_path_for(path);
    let mut unsynced = Unsynced {
        file: None,
        temporary_path,
        path: path.to_path_buf(),
    };
    let file = temporary::create(&unsynced.temporary_path)
        .map_err(|error| unsynced.error(error.to_string()))?;
    let file = unsynced.file.insert(file);
    write_contents(file).map_err(|cause| unsynced.error(cause))?;
    Ok(unsynced)
}

/// A file written under its temporary name by [`write_unsynced`], waiting for
/// [`Unsynced::commit`]. Dropped uncommitted, its temporary file is removed.
pub(crate) struct Unsynced {
    /// `None` once committed (or never created).
    file: Option<File>,
    temporary_path: PathBuf,
    path: PathBuf,
}

impl Unsynced {
    /// Syncs the file to disk and renames it over its path (then syncs the folder).
    pub fn commit(mut self) -> Result<(), OutputError> {
        let Some(file) = self.file.take() else {
            return Err(self.error("the file was never created".to_string()));
        };
        let result = file
            .sync_all()
            .map_err(|error| format!("sync failed: {error}"))
            .and_then(|()| {
                drop(file);
                fs::rename(&self.temporary_path, &self.path).map_err(|error| {
                    format!("rename from {}: {error}", self.temporary_path.display())
                })
            });
        if let Err(cause) = result {
            // Drop removes the temporary file.
            self.file = None;
            return Err(self.error(cause));
        }
        temporary::release(&self.temporary_path);
        sync_parent_dir(&self.path);
        // Renamed: nothing left for Drop to remove.
        self.temporary_path = PathBuf::new();
        Ok(())
    }

    /// Where the file goes.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn error(&self, cause: String) -> OutputError {
        OutputError::Write {
            path: self.path.clone(),
            cause,
        }
    }
}

impl Drop for Unsynced {
    fn drop(&mut self) {
        if self.temporary_path.as_os_str().is_empty() {
            return;
        }
        self.file = None;
        // The temporary file may not exist (creation failed); either way it must not stay behind.
        let _ = fs::remove_file(&self.temporary_path);
        temporary::release(&self.temporary_path);
    }
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

    /// A file written but not committed is only its temporary file: the destination keeps its
    /// old contents until the commit, and dropping it uncommitted removes the temporary file.
    #[test]
    fn an_unsynced_file_appears_only_when_committed() {
        let temp = tempfile::tempdir().unwrap();
        let names = || -> Vec<String> {
            let mut names: Vec<String> = fs::read_dir(temp.path())
                .unwrap()
                .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        };
        let path = temp.path().join("pool.0001.exr");
        fs::write(&path, b"old frame").unwrap();
        let write = |text: &'static [u8]| {
            write_unsynced(&path, move |file| {
                use std::io::Write;
                file.write_all(text).map_err(|e| e.to_string())
            })
            .unwrap()
        };
        let dropped = write(b"never committed");
        assert_eq!(
            names().len(),
            2,
            "the temporary file beside it: {:?}",
            names()
        );
        assert_eq!(fs::read(&path).unwrap(), b"old frame");
        drop(dropped);
        assert_eq!(names(), ["pool.0001.exr"]);
        assert_eq!(fs::read(&path).unwrap(), b"old frame");

        let committed = write(b"new frame");
        assert_eq!(committed.path(), path);
        assert_eq!(fs::read(&path).unwrap(), b"old frame");
        committed.commit().unwrap();
        assert_eq!(names(), ["pool.0001.exr"]);
        assert_eq!(fs::read(&path).unwrap(), b"new frame");
    }

    /// A full disk mid-write: the error names the file and the cause, is not blamed on the user
    /// (exit 1, not 2), the destination keeps its old contents and no temporary file stays.
    #[test]
    fn full_disk_is_a_clear_error_and_leaves_nothing_behind() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join("pool.0001.exr");
        fs::write(&path, b"old frame").unwrap();
        let error = write_atomically(&path, |file| {
            use std::io::Write;
            file.write_all(b"half a frame").map_err(|e| e.to_string())?;
            Err(std::io::Error::from_raw_os_error(libc::ENOSPC).to_string())
        })
        .unwrap_err();
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("cannot write {}: ", path.display())),
            "{message}"
        );
        assert!(message.contains("No space left on device"), "{message}");
        assert!(!error.is_bad_input());
        assert_eq!(fs::read(&path).unwrap(), b"old frame");
        let names: Vec<_> = fs::read_dir(temp.path())
            .unwrap()
            .map(|entry| entry.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("pool.0001.exr")]);
    }

    /// /proc refuses new files even for root (permission bits would not stop root).
    #[cfg(target_os = "linux")]
    #[test]
    fn a_directory_that_refuses_files_is_bad_input() {
        let proc_dir = Path::new("/proc");
        let error = check_writable(proc_dir).unwrap_err();
        assert!(error.is_bad_input());
        let message = error.to_string();
        assert!(
            message.starts_with("cannot write into directory /proc: "),
            "{message}"
        );
        let temp = tempfile::tempdir().unwrap();
        check_writable(temp.path()).unwrap();
        assert_eq!(
            fs::read_dir(temp.path()).unwrap().count(),
            0,
            "probe removed"
        );
    }
}
