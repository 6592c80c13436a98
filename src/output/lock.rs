//! Advisory whole-file locks (`flock`) between processes sharing an output folder: the report's
//! updates and the simulation checkpoints' folders. On Linux, NFS maps them to its own locks, so
//! they hold between machines of a farm too. Elsewhere than Unix they are not taken.

use std::fs::File;
use std::io;

/// How a lock is taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lock {
    /// One holder at a time; waits.
    Exclusive,
    /// Many holders at once, none exclusive; waits.
    Shared,
    /// Exclusive if free now; `WouldBlock` otherwise.
    TryExclusive,
}

/// Takes `lock` on `file`; released when the file is closed.
pub fn lock(file: &File, lock: Lock) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::io::AsRawFd;
        let operation = match lock {
            Lock::Exclusive => libc::LOCK_EX,
            Lock::Shared => libc::LOCK_SH,
            Lock::TryExclusive => libc::LOCK_EX | libc::LOCK_NB,
        };
        loop {
            // SAFETY: flock on an open descriptor has no memory effects.
            if unsafe { libc::flock(file.as_raw_fd(), operation) } == 0 {
                return Ok(());
            }
            let error = io::Error::last_os_error();
            if error.kind() != io::ErrorKind::Interrupted {
                return Err(error);
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, lock);
        Ok(())
    }
}
