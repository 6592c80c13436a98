//! The temporary files every output is written under before its rename: their names
//! (`.<file>.tmp-<pid>.<host>`, hidden, beside the destination), a registry of the ones this
//! process has open so that an immediate stop (a second Ctrl-C) can remove them before exiting,
//! and the clean-up of stale ones a killed process (SIGKILL, power loss) left behind.
//!
//! The host is in the name because farm machines share output folders: a process id says nothing
//! about a process on another machine, so another host's temporary file is removed only once it
//! is older than [`FOREIGN_STALE_AFTER`] (no frame takes that long to write).

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

/// Another machine's temporary file older than this is taken as left by a killed process.
pub const FOREIGN_STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(24 * 3600);

/// This machine's name as it appears in temporary names: letters, digits and `-` only (anything
/// else becomes `-`), so the name parses back; `unknown` when it cannot be read.
pub fn host_tag() -> &'static str {
    static HOST: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    HOST.get_or_init(|| {
        let name = read_host_name().unwrap_or_default();
        // At most 64 characters (HOST_NAME_MAX), so names stay well under 255 bytes.
        let tag: String = name
            .chars()
            .take(64)
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        if tag.is_empty() {
            "unknown".to_string()
        } else {
            tag
        }
    })
}

fn read_host_name() -> Option<String> {
    #[cfg(unix)]
    {
        let mut buffer = [0u8; 256];
        // SAFETY: the buffer is valid for its length; gethostname writes at most that many bytes.
        let result = unsafe { libc::gethostname(buffer.as_mut_ptr().cast(), buffer.len()) };
        if result != 0 {
            return None;
        }
        let end = buffer.iter().position(|&b| b == 0).unwrap_or(buffer.len());
        Some(String::from_utf8_lossy(&buffer[..end]).into_owned())
    }
    #[cfg(not(unix))]
    {
        std::env::var("COMPUTERNAME").ok()
    }
}

/// The temporary name `path` is written under: `.<file name>.tmp-<pid>.<host>` in the same
/// directory (so the rename cannot cross file systems), unique per process and machine.
pub fn temporary_path_for(path: &Path) -> PathBuf {
    let file_name = path
        .file_name()
        .map(|name| name.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(
        ".{file_name}{MARKER}{}.{}",
        std::process::id(),
        host_tag()
    ))
}

/// Who wrote a temporary file: its process id and, for names of this version, its host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TemporaryOwner {
    pub pid: u32,
    /// None for names without a host (`.<name>.tmp-<pid>`, written by older versions): taken as
    /// this machine's.
    pub host: Option<String>,
}

/// The owner in a temporary file's name, if `file_name` is one (`.<name>.tmp-<pid>.<host>` or
/// the older `.<name>.tmp-<pid>`).
pub fn temporary_owner(file_name: &str) -> Option<TemporaryOwner> {
    let rest = file_name.strip_prefix('.')?;
    let (name, owner) = rest.rsplit_once(MARKER)?;
    let (pid, host) = match owner.split_once('.') {
        Some((pid, host)) => (pid, Some(host)),
        None => (owner, None),
    };
    let host_ok = host.is_none_or(|host| {
        !host.is_empty() && host.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
    });
    if name.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) || !host_ok {
        return None;
    }
    Some(TemporaryOwner {
        pid: pid.parse().ok()?,
        host: host.map(str::to_string),
    })
}

/// The process id in a temporary file's name, if `file_name` is one.
pub fn temporary_owner_pid(file_name: &str) -> Option<u32> {
    temporary_owner(file_name).map(|owner| owner.pid)
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

/// Whether the temporary file `path` (owned by `owner`) was left by a process that is gone: on
/// this machine, its process is not running; from another machine (a farm's shared folder), it
/// is older than [`FOREIGN_STALE_AFTER`].
fn is_stale(path: &Path, owner: &TemporaryOwner) -> bool {
    match &owner.host {
        Some(host) if host != host_tag() => fs::metadata(path)
            .and_then(|meta| meta.modified())
            .ok()
            .and_then(|modified| modified.elapsed().ok())
            .is_some_and(|age| age > FOREIGN_STALE_AFTER),
        _ => !process_is_alive(owner.pid),
    }
}

/// Removes the temporary files of dead processes in `dir` and, one level down, in each folder of
/// `dir/<nested>/` (the simulation checkpoints' folders); returns what it removed. A folder of
/// `dir/<nested>/` with a temporary name is a checkpoint version a process moved aside to delete
/// it (`sim/checkpoint.rs`): if that process is gone (killed between the move and the delete),
/// the folder goes whole. A process id can be reused: a stale file whose id now belongs to a
/// running process is kept (harmless: it is hidden and never read as a frame). Another machine's
/// files are judged by age ([`is_stale`]).
pub fn remove_stale(dir: &Path, nested: &str) -> Vec<PathBuf> {
    let mut folders = vec![dir.to_path_buf()];
    let mut removed = Vec::new();
    if let Ok(entries) = fs::read_dir(dir.join(nested)) {
        for entry in entries.flatten() {
            let path = entry.path();
            if !entry.file_type().is_ok_and(|kind| kind.is_dir()) {
                continue;
            }
            let name = entry.file_name().to_string_lossy().into_owned();
            match temporary_owner(&name) {
                Some(owner) => {
                    if is_stale(&path, &owner) && fs::remove_dir_all(&path).is_ok() {
                        removed.push(path);
                    }
                }
                None => folders.push(path),
            }
        }
    }
    for folder in folders {
        let Ok(entries) = fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(owner) = temporary_owner(&name) else {
                continue;
            };
            let is_file = entry.file_type().is_ok_and(|kind| kind.is_file());
            if is_file && is_stale(&entry.path(), &owner) && fs::remove_file(entry.path()).is_ok() {
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
        assert_eq!(
            name,
            format!(".pool.0001.exr.tmp-{}.{}", std::process::id(), host_tag())
        );
        assert_eq!(
            temporary_owner(name),
            Some(TemporaryOwner {
                pid: std::process::id(),
                host: Some(host_tag().to_string())
            })
        );
        // The older name without a host still parses (taken as this machine's).
        assert_eq!(
            temporary_owner(".pool.0001.exr.tmp-12"),
            Some(TemporaryOwner {
                pid: 12,
                host: None
            })
        );
        assert_eq!(temporary_owner_pid(".pool.0001.exr.tmp-12.a.b"), None);
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
        let dead_here = dir
            .path()
            .join(format!(".pool.0004.exr.tmp-{DEAD_PID}.{}", host_tag()));
        let mine = temporary_path_for(&dir.path().join("pool.0003.exr"));
        let frame = dir.path().join("pool.0001.exr");
        // Another machine's files: a pid there says nothing here; only age counts.
        let foreign_fresh = dir.path().join(format!(
            ".pool.0005.exr.tmp-{DEAD_PID}.elsewhere-{}",
            host_tag()
        ));
        let foreign_old = dir.path().join(format!(
            ".pool.0006.exr.tmp-{DEAD_PID}.elsewhere-{}",
            host_tag()
        ));
        for path in [
            &dead,
            &dead_nested,
            &dead_here,
            &mine,
            &frame,
            &foreign_fresh,
            &foreign_old,
        ] {
            fs::write(path, b"x").unwrap();
        }
        let old =
            std::time::SystemTime::now() - FOREIGN_STALE_AFTER - std::time::Duration::from_secs(60);
        File::options()
            .write(true)
            .open(&foreign_old)
            .unwrap()
            .set_modified(old)
            .unwrap();
        let removed = remove_stale(dir.path(), ".sim");
        let mut expected = vec![
            dead.clone(),
            dead_nested.clone(),
            dead_here.clone(),
            foreign_old.clone(),
        ];
        expected.sort();
        assert_eq!(removed, expected);
        assert!(mine.exists(), "this process is alive: its file stays");
        assert!(
            foreign_fresh.exists(),
            "a fresh file of another machine may be written now: it stays"
        );
        assert!(frame.exists());
        assert!(!dead.exists() && !dead_nested.exists());
    }

    /// A checkpoint version folder moved aside for deletion by a process that was then killed
    /// goes whole; one moved aside by a live process (deleting it now) and the versions in use
    /// stay.
    #[test]
    fn folders_moved_aside_by_dead_processes_go_whole() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join(".sim");
        let version = root.join("pool-abc");
        let dead_aside = root.join(format!(".pool-old.tmp-{DEAD_PID}.{}", host_tag()));
        let live_aside = temporary_path_for(&root.join("pool-older"));
        for folder in [&version, &dead_aside, &live_aside] {
            fs::create_dir_all(folder).unwrap();
            fs::write(folder.join("ripples-000002.bin"), b"x").unwrap();
        }
        let removed = remove_stale(dir.path(), ".sim");
        assert_eq!(removed, vec![dead_aside.clone()]);
        assert!(!dead_aside.exists());
        assert!(live_aside.join("ripples-000002.bin").exists());
        assert!(version.join("ripples-000002.bin").exists());
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
