//! Panics turned into errors. A panic is a bug in snell (or a library), never the user's fault,
//! and no panic message with a backtrace should reach them: the CLI installs [`install_hook`],
//! which records the message and where it happened instead of printing it, and the frame stage
//! runs each frame under [`catch`], so a panic in any stage of a frame (a rayon worker's
//! included) becomes an error naming the frame, and the command exits 1 with one paragraph.
//! `RUST_BACKTRACE=1` prints the usual panic report as well, for debugging.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

/// The last panic's message and location, as the hook saw it.
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Records panics instead of printing them (printed too when `RUST_BACKTRACE` is set).
pub fn install_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let location = info
            .location()
            .map_or_else(String::new, |l| format!(" at {}:{}", l.file(), l.line()));
        let thread = std::thread::current()
            .name()
            .map_or_else(String::new, |name| format!(" (thread {name})"));
        let message = format!("{}{location}{thread}", payload_text(info.payload()));
        *LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()) = Some(message);
        if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") {
            default(info);
        }
    }));
}

fn payload_text(payload: &(dyn Any + Send)) -> String {
    if let Some(text) = payload.downcast_ref::<&str>() {
        (*text).to_string()
    } else if let Some(text) = payload.downcast_ref::<String>() {
        text.clone()
    } else {
        "a panic without a message".to_string()
    }
}

/// What a caught panic was: the hook's record (message and location) when it matches the
/// payload, else the payload's message.
pub fn describe(payload: &(dyn Any + Send)) -> String {
    let text = payload_text(payload);
    match LAST_PANIC.lock().unwrap_or_else(|p| p.into_inner()).take() {
        Some(recorded) if recorded.starts_with(&text) => recorded,
        _ => text,
    }
}

/// Runs `work`; a panic inside it (on this thread, or re-raised from a rayon worker) comes back
/// as its description.
pub fn catch<T>(work: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(work)).map_err(|payload| describe(payload.as_ref()))
}

/// The environment variable of [`inject_for_tests`].
pub const TEST_PANIC_VARIABLE: &str = "SNELL_TEST_PANIC_FRAME";

/// A test hook: when `SNELL_TEST_PANIC_FRAME` holds `frame`, panics on a rayon worker thread, as
/// a bug in one of the frame's parallel stages would, so that tests can check that such a panic
/// becomes exit 1 naming the frame, with no partial frame left (tests/no_panics.rs). Only tests
/// set it; the README's "Testing" notes list it.
pub fn inject_for_tests(frame: u32) {
    let wanted = std::env::var(TEST_PANIC_VARIABLE)
        .ok()
        .and_then(|value| value.trim().parse::<u32>().ok());
    if wanted != Some(frame) {
        return;
    }
    use rayon::prelude::*;
    (0..64u32).into_par_iter().for_each(|i| {
        if i == 63 {
            panic!("an injected panic ({TEST_PANIC_VARIABLE}={frame})");
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panics_come_back_as_messages_from_any_thread() {
        assert_eq!(catch(|| 2 + 2), Ok(4));
        let message = catch(|| -> u32 { panic!("boom {}", 7) }).unwrap_err();
        assert!(message.starts_with("boom 7"), "{message}");
        // A panic on a rayon worker reaches the caller.
        let message = catch(|| {
            use rayon::prelude::*;
            (0..64)
                .into_par_iter()
                .map(|i| if i == 33 { panic!("worker {i}") } else { i })
                .sum::<i32>()
        })
        .unwrap_err();
        assert!(message.starts_with("worker 33"), "{message}");
    }
}
