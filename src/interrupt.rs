//! Stopping a render when asked (Ctrl-C = SIGINT, or SIGTERM): receives the signals on a thread of
//! its own and turns the first into a stop request (a flag the render loop reads between frames, so
//! the frame in flight is finished and written) and the second into an immediate exit that first
//! removes this process's temporary files. The exit code is 128 + the signal number (130 for
//! SIGINT, 143 for SIGTERM), as shells report a process killed by that signal.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::OnceLock;

use signal_hook::consts::signal::{SIGINT, SIGTERM};
use signal_hook::iterator::Signals;

static STOP: AtomicBool = AtomicBool::new(false);
static FIRST_SIGNAL: AtomicI32 = AtomicI32::new(0);
static RESUME_HINT: OnceLock<String> = OnceLock::new();

fn signal_name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "Ctrl-C (SIGINT)",
        SIGTERM => "SIGTERM",
        _ => "a signal",
    }
}

/// Handles SIGINT and SIGTERM from now on and returns the stop flag to pass to the render loop.
/// `resume_hint` (e.g. the command line that finishes the render) is printed if the process has
/// to exit at once. Call once per process.
pub fn install(resume_hint: String) -> std::io::Result<&'static AtomicBool> {
    let _ = RESUME_HINT.set(resume_hint);
    let mut signals = Signals::new([SIGINT, SIGTERM])?;
    std::thread::Builder::new()
        .name("snell-signals".into())
        .spawn(move || {
            for signal in signals.forever() {
                // Only this thread writes the two: the signal is known before the stop is seen.
                if STOP.load(Ordering::SeqCst) {
                    stop_at_once(signal);
                }
                FIRST_SIGNAL.store(signal, Ordering::SeqCst);
                STOP.store(true, Ordering::SeqCst);
                errln!(
                    "\nsnell: {} received: stopping after the frame in flight is written \
                     (press Ctrl-C again to stop at once)",
                    signal_name(signal)
                );
            }
        })?;
    Ok(&STOP)
}

/// The second signal: no frame is finished; temporary files go, complete frames stay.
fn stop_at_once(signal: i32) -> ! {
    let removed = crate::output::temporary::remove_all_and_refuse_new();
    errln!(
        "\nsnell: {} again: stopped at once (removed {} temporary file(s); frames already \
         written are complete)",
        signal_name(signal),
        removed.len()
    );
    if let Some(hint) = RESUME_HINT.get() {
        errln!("to finish: {hint}");
    }
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    // _exit, not exit, as in `exit_at_first_signal`: exit runs the C libraries' exit handlers
    // (Mesa's, LLVM's) while the render and writer threads may still be inside them; in
    // `bash .ci/run` at 3957d77 that killed the process by a signal instead of exit 130.
    // SAFETY: _exit ends the process at once; nothing runs after it.
    unsafe { libc::_exit(exit_code_for(signal).into()) }
}

/// For a command that stops at the first signal (`snell preview`): handles SIGINT and SIGTERM
/// from now on (call before announcing that the command runs). Handling them replaces a
/// disposition of "ignore" inherited from the parent (a shell starting a job in the background
/// sets it for SIGINT), so `kill -INT` always stops the command.
pub fn catch_stop_signals() -> std::io::Result<Signals> {
    Signals::new([SIGINT, SIGTERM])
}

/// Blocks until a signal of [`catch_stop_signals`] arrives, then removes this process's temporary
/// files and exits with 128 + the signal, without waiting for work in flight (a frame still
/// rendering) and without running exit handlers.
pub fn exit_at_first_signal(mut signals: Signals, what: &str) -> ! {
    let signal = signals.forever().next().unwrap_or(SIGINT);
    let removed = crate::output::temporary::remove_all_and_refuse_new();
    errln!(
        "\nsnell: {} received: {what} stopped{}",
        signal_name(signal),
        if removed.is_empty() {
            String::new()
        } else {
            format!(" (removed {} temporary file(s))", removed.len())
        }
    );
    use std::io::Write;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    // _exit, not exit: exit runs the C libraries' exit handlers (Mesa's, LLVM's) while the render
    // worker may still be inside them, which crashed the process (SIGSEGV) instead of ending it.
    // SAFETY: _exit ends the process at once; nothing runs after it.
    unsafe { libc::_exit(exit_code_for(signal).into()) }
}

fn exit_code_for(signal: i32) -> u8 {
    u8::try_from(128 + signal).unwrap_or(1)
}

/// The exit code for a render stopped by the first signal received: 130 for SIGINT, 143 for
/// SIGTERM; None when no signal came.
pub fn exit_code() -> Option<u8> {
    match FIRST_SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        signal => Some(exit_code_for(signal)),
    }
}
