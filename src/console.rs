//! Writing to stdout and stderr without dying of it. `println!` panics when the write fails: a
//! closed pipe (`snell info scene.toml | head -1`), `/dev/full`, a terminal that went away. Here
//! a failed write is remembered instead, and nothing more is written to that stream; the command
//! finishes its work, and the CLI then decides its exit code ([`stdout_failure`]): commands whose
//! product is what they print fail quietly (exit 1), a render whose frames are written succeeds.
//!
//! Use [`outln!`](crate::outln) / [`out!`](crate::out) for stdout and [`errln!`](crate::errln)
//! for stderr, exactly like `println!` and `eprintln!`.

use std::fmt;
use std::io::Write;
use std::sync::Mutex;

/// The first write error of each stream (None while it works).
static STDOUT_ERROR: Mutex<Option<std::io::ErrorKind>> = Mutex::new(None);
static STDERR_ERROR: Mutex<Option<std::io::ErrorKind>> = Mutex::new(None);

fn lock(
    stream: &Mutex<Option<std::io::ErrorKind>>,
) -> std::sync::MutexGuard<'_, Option<std::io::ErrorKind>> {
    stream
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Writes to stdout (and flushes at line ends, as `println!` does); a failure is remembered and
/// later writes are dropped.
pub fn write_stdout(args: fmt::Arguments<'_>) {
    let mut failed = lock(&STDOUT_ERROR);
    if failed.is_some() {
        return;
    }
    let mut stdout = std::io::stdout().lock();
    if let Err(error) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        *failed = Some(error.kind());
    }
}

/// Writes to stderr; a failure is remembered and later writes are dropped.
pub fn write_stderr(args: fmt::Arguments<'_>) {
    let mut failed = lock(&STDERR_ERROR);
    if failed.is_some() {
        return;
    }
    if let Err(error) = std::io::stderr().lock().write_fmt(args) {
        *failed = Some(error.kind());
    }
}

/// Flushes stdout; a failure counts as a failed write.
pub fn flush_stdout() {
    let mut failed = lock(&STDOUT_ERROR);
    if failed.is_none() {
        if let Err(error) = std::io::stdout().lock().flush() {
            *failed = Some(error.kind());
        }
    }
}

/// How stdout failed, if it did.
pub fn stdout_failure() -> Option<std::io::ErrorKind> {
    flush_stdout();
    *lock(&STDOUT_ERROR)
}

/// How stderr failed, if it did.
pub fn stderr_failure() -> Option<std::io::ErrorKind> {
    *lock(&STDERR_ERROR)
}

/// `print!` that never panics (see the module docs).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::console::write_stdout(format_args!($($arg)*)) };
}

/// `println!` that never panics (see the module docs).
#[macro_export]
macro_rules! outln {
    () => { $crate::console::write_stdout(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::console::write_stdout(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `eprintln!` that never panics (see the module docs).
#[macro_export]
macro_rules! errln {
    () => { $crate::console::write_stderr(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::console::write_stderr(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `eprint!` that never panics.
#[macro_export]
macro_rules! err {
    ($($arg:tt)*) => { $crate::console::write_stderr(format_args!($($arg)*)) };
}
