//! The temporary files every output is written under before its rename: their names
//! (`.<file>.tmp-<pid>`, hidden, beside the destination), a registry of the ones this process has
//! open so that an immediate stop (a second Ctrl-C) can remove them before exiting, and the
//! clean-up of stale ones a killed process (SIGKILL, power loss) left behind.

use std::collections::BTreeSet;
use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// Temporary files that exist now, and whether new ones are refused (the process is stopping).
struct Registry {
    state: Mutex<RegistryState>,
}

struct RegistryState {
    live: BTreeSet<PathBuf>,
    closed: bool,
}

/// This process's temporary files.
static REGISTRY: Registry = Registry::new();

impl Registry {
    const fn new() -> Self {
        Registry {
            state: Mutex::new(RegistryState {
                live: BTreeSet::new(),
                closed: false,
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, RegistryState> {
        // A panic while holding the lock leaves the set itself intact: keep using it.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn create(&self, temporary: &Path) -> io::Result<File> {
        let mut state = self.lock();
        if state.closed {
            return Err(io::Error::new(
                io::ErrorKind::Interrupted,
                "snell is stopping: no new file is started",
            ));
        }
        let file = File::create(temporary)?;
        state.live.insert(temporary.to_path_buf());
        Ok(file)
    }

    fn release(&self, temporary: &Path) {
        self.lock().live.remove(temporary);
    }

    fn remove_all_and_refuse_new(&self) -> Vec<PathBuf> {
        let mut state = self.lock();
        state.closed = true;
        let live = std::mem::take(&mut state.live);
        live.into_iter()
            .filter(|path| fs::remove_file(path).is_ok())
            .collect()
    }
}

const MARKER: &str = ".tmp-";

/// The temporary name `path` is written under: `.<file name>.tmp-<pid>` in the same directory (so
/// the rename cannot cross file systems), unique per process.
pub fn temporary_path_for(path: &Path) -> PathBuf {
    let file_name = path
        .file_name()
        .map(|name| name.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{file_name}{MARKER}{}", std::process::id()))
}

/// The process id in a temporary file's name, if `file_name` is one (`.<name>.tmp-<pid>`).
pub fn temporary_owner_pid(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?;
    let (name, pid) = rest.rsplit_once(MARKER)?;
    if name.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok()
}

/// Creates (truncating) the temporary file `temporary` and registers it, so that
/// [`remove_all_and_refuse_new`] can find it. Refused once the process is stopping. The file is
/// created while the registry is locked: a stop cannot slip between creation and registration.
pub fn create(temporary: &Path) -> io::Result<File> {
    REGISTRY.create(temporary)
}

/// Forgets `temporary` (renamed into place or removed).
pub fn release(temporary: &Path) {
    REGISTRY.release(temporary)
}

/// Removes every temporary file this process has open and refuses new ones; returns the files
/// removed. For a process about to exit without finishing its writes.
pub fn remove_all_and_refuse_new() -> Vec<PathBuf> {
    REGISTRY.remove_all_and_refuse_new()
}

/// Whether process `pid` is running. Unknown (not Linux or other Unix) counts as running, so a
/// file that might still be written is never removed.
fn process_is_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return false;
        };
        if pid <= 0 {
            return false;
        }
        // Signal 0 checks existence and permission only. ESRCH: no such process; EPERM: it
        // exists but belongs to someone else.
        // SAFETY: kill with signal 0 sends nothing and has no memory effects.
        let result = unsafe { libc::kill(pid, 0) };
        result == 0 || io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        true
    }
}

/// Removes the temporary files of dead processes in `dir` and, one level down, in each folder of
/// `dir/<nested>/` (the simulation checkpoints' folders); returns what it removed. A process id can
/// be reused: a stale file whose id now belongs to a running process is kept (harmless: it is
/// hidden and never read as a frame).
pub fn remove_stale(dir: &Path, nested: &str) -> Vec<PathBuf> {
    let mut folders = vec![dir.to_path_buf()];
    if let Ok(entries) = fs::read_dir(dir.join(nested)) {
        folders.extend(
            entries
                .flatten()
                .map(|entry| entry.path())
                .filter(|path| path.is_dir()),
        );
    }
    let mut removed = Vec::new();
    for folder in folders {
        let Ok(entries) = fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(pid) = temporary_owner_pid(&name) else {
                continue;
            };
            let is_file = entry.file_type().is_ok_and(|kind| kind.is_file());
            if is_file && !process_is_alive(pid) && fs::remove_file(entry.path()).is_ok() {
                removed.push(entry.path());
            }
        }
    }
    removed.sort();
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_frames_are_not_temporaries() {
        let path = temporary_path_for(Path::new("out/pool.0001.exr"));
        let name = path.file_name().unwrap().to_str().unwrap();
        assert_eq!(name, format!(".pool.0001.exr.tmp-{}", std::process::id()));
        assert_eq!(temporary_owner_pid(name), Some(std::process::id()));
        assert_eq!(temporary_owner_pid("pool.0001.exr"), None);
        assert_eq!(temporary_owner_pid(".pool.0001.exr.tmp-"), None);
        assert_eq!(temporary_owner_pid(".pool.0001.exr.tmp-12x"), None);
        assert_eq!(temporary_owner_pid("..tmp-12"), None);
    }

    /// A pid that cannot be running: above the kernel's maximum (4194304 on 64-bit Linux).
    const DEAD_PID: u32 = 99_999_999;

    #[test]
    fn stale_files_of_dead_processes_go_and_live_ones_stay() {
        let dir = tempfile::tempdir().unwrap();
        let nested = dir.path().join(".sim").join("pool-abc");
        fs::create_dir_all(&nested).unwrap();
        let dead = dir.path().join(format!(".pool.0002.exr.tmp-{DEAD_PID}"));
        let dead_nested = nested.join(format!(".ripples-000002.bin.tmp-{DEAD_PID}"));
        let mine = temporary_path_for(&dir.path().join("pool.0003.exr"));
        let frame = dir.path().join("pool.0001.exr");
        for path in [&dead, &dead_nested, &mine, &frame] {
            fs::write(path, b"x").unwrap();
        }
        let removed = remove_stale(dir.path(), ".sim");
        let mut expected = vec![dead.clone(), dead_nested.clone()];
        expected.sort();
        assert_eq!(removed, expected);
        assert!(mine.exists(), "this process is alive: its file stays");
        assert!(frame.exists());
        assert!(!dead.exists() && !dead_nested.exists());
    }

    #[test]
    fn registered_files_are_removed_and_new_ones_refused() {
        // A registry of its own: closing the process-wide one would stop other tests' writes.
        let registry = Registry::new();
        let dir = tempfile::tempdir().unwrap();
        let temporary = temporary_path_for(&dir.path().join("a.exr"));
        drop(registry.create(&temporary).unwrap());
        let finished = temporary_path_for(&dir.path().join("b.exr"));
        drop(registry.create(&finished).unwrap());
        registry.release(&finished);
        let removed = registry.remove_all_and_refuse_new();
        assert_eq!(removed, vec![temporary.clone()]);
        assert!(!temporary.exists());
        assert!(
            finished.exists(),
            "a released file (renamed into place) is not removed"
        );
        let late = temporary_path_for(&dir.path().join("c.exr"));
        let refused = registry.create(&late).unwrap_err();
        assert_eq!(refused.kind(), io::ErrorKind::Interrupted);
        assert!(!late.exists(), "a refused file is not created");
    }
}
