//! The writer of [`super::RenderJob::render_sequence`]: frames arrive strip by strip
//! ([`ToWriter`], through a queue bounded in bytes, [`super::queue`]) and go to disk as they come,
//! in two stages on threads of their own that overlap the render of the next frames:
//! - the encoder: each frame's EXR chunks compressed (on a thread pool of the writer's own) and
//!   written under the file's temporary name, and the PNG tone-mapped when asked for;
//! - the committer: each file synced to disk and renamed into place, then the PNG, then the report
//!   row and the log line, in frame order. The fsync (about 30 ms a 720p frame, waiting on the
//!   disk) so no longer holds up the next frame's encoding.
//!
//! A frame larger than one strip is never held whole.

use std::path::PathBuf;
use std::time::Instant;

use super::queue::ByteReceiver;
use super::SnellError;
use crate::draw::RenderedFrame;
use crate::output::Unsynced;

/// A frame on its way to disk, strip by strip: what the writer of
/// [`super::RenderJob::render_sequence`] receives.
pub(super) enum ToWriter {
    /// A frame begins: where it goes and what its header says.
    Start(Box<FrameStart>),
    /// The frame's next strip: the row it starts at, and its layers (boxed: a RenderedFrame holds
    /// a vector per layer, and unboxed every Start and Done message in the queue would be as large).
    Strip(u32, Box<RenderedFrame>),
    /// The frame's last strip was sent: its report row (render time filled in).
    Done(Box<crate::output::report::FrameReport>),
}

impl ToWriter {
    /// What the message weighs in the writer's queue: a strip's layers (the rest is small).
    pub fn bytes(&self) -> usize {
        match self {
            ToWriter::Strip(_, strip) => strip.layer_bytes(),
            ToWriter::Start(_) | ToWriter::Done(_) => 0,
        }
    }
}

pub(super) struct FrameStart {
    pub path: PathBuf,
    pub meta: crate::output::exr::FrameMeta,
    pub width: u32,
    pub height: u32,
}

/// A frame encoded under its temporary name, on its way to the committer.
struct Encoded {
    file: Unsynced,
    png: Option<image::RgbaImage>,
    row: Box<crate::output::report::FrameReport>,
    /// Seconds the encoder spent on it (not waiting for strips).
    encode_secs: f64,
}

/// The writer of [`super::RenderJob::render_sequence`]: each frame's EXR (atomic, streamed strip
/// by strip as they come), optional PNG, then the report row with the write time (encoding,
/// sync, rename and PNG; not the waiting for strips) filled in. Stops at the first error; a frame
/// whose strips stop coming (the render failed) leaves no file.
///
/// The chunks of a frame are compressed on a thread pool of the writer's own, one thread per
/// core: on rayon's shared pool they queued ahead of the next frame's water, refraction and
/// render work, which then waited for the whole frame's compression (the `water` stage of a
/// written frame took 0.3-1.2 s instead of a few ms); with a pool of its own the system shares
/// the cores between the two.
pub(super) fn write_frames(
    receiver: ByteReceiver<ToWriter>,
    report: crate::output::report::ReportWriter,
    write_png: bool,
    log: super::resume::FrameLog,
) -> Result<(), SnellError> {
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("snell-encode-{i}"))
        .build();
    match pool {
        Ok(pool) => pool.install(|| write_each(receiver, report, write_png, log)),
        // No threads to be had: compress on the shared pool, as the rest of snell does.
        Err(_) => write_each(receiver, report, write_png, log),
    }
}

fn write_each(
    receiver: ByteReceiver<ToWriter>,
    report: crate::output::report::ReportWriter,
    write_png: bool,
    log: super::resume::FrameLog,
) -> Result<(), SnellError> {
    // One frame waits between the two stages (its file handle, and its PNG if any).
    let (to_commit, committing) = std::sync::mpsc::sync_channel::<Encoded>(1);
    std::thread::scope(|scope| {
        let committer = std::thread::Builder::new()
            .name("snell-commit".to_string())
            .spawn_scoped(scope, move || commit_each(committing, report, log))
            .map_err(|error| SnellError::Internal {
                frame: None,
                message: format!("cannot start the frame committer: {error}"),
            })?;
        let encoded = encode_each(receiver, write_png, &to_commit);
        drop(to_commit);
        let committed = committer.join().unwrap_or_else(|payload| {
            Err(SnellError::Internal {
                frame: None,
                message: format!(
                    "the frame committer failed: {}",
                    crate::panics::describe(payload.as_ref())
                ),
            })
        });
        // The committer's error first: the encoder stops without one of its own when the
        // committer has stopped.
        committed.and(encoded)
    })
}

/// The encoder stage: frames from the queue into temporary files, handed to the committer.
/// Returns (dropping the queue, so the render stops too) at the first error or once the
/// committer has stopped.
fn encode_each(
    receiver: ByteReceiver<ToWriter>,
    write_png: bool,
    to_commit: &std::sync::mpsc::SyncSender<Encoded>,
) -> Result<(), SnellError> {
    while let Some(message) = receiver.recv() {
        let ToWriter::Start(start) = message else {
            return Err(SnellError::Internal {
                frame: None,
                message: "the frame writer got a strip before its frame began".to_string(),
            });
        };
        let clock = Instant::now();
        let mut waiting = 0.0;
        let mut png = write_png.then(|| image::RgbaImage::new(start.width, start.height));
        let mut done = None;
        let file = crate::output::exr::write_frame_exr_unsynced(
            &start.path,
            &start.meta,
            start.width,
            start.height,
            || {
                let asked = Instant::now();
                let message = receiver.recv();
                waiting += asked.elapsed().as_secs_f64();
                match message {
                    Some(ToWriter::Strip(first_row, strip)) => {
                        if let Some(png) = &mut png {
                            let rows = crate::output::tonemap::tonemap_srgb8(&strip, 0.0);
                            let at = first_row as usize * start.width as usize * 4;
                            let bytes: &mut [u8] = png;
                            bytes[at..at + rows.len()].copy_from_slice(&rows);
                        }
                        Ok(Some((first_row, std::borrow::Cow::Owned(*strip))))
                    }
                    Some(ToWriter::Done(row)) => {
                        done = Some(row);
                        Ok(None)
                    }
                    Some(ToWriter::Start(_)) => {
                        Err("a frame began before the last one was complete".to_string())
                    }
                    None => Err("the render stopped before the frame was complete".to_string()),
                }
            },
        )?;
        let encoded = Encoded {
            file,
            png,
            row: done.expect("the frame is complete once written"),
            encode_secs: (clock.elapsed().as_secs_f64() - waiting).max(0.0),
        };
        if to_commit.send(encoded).is_err() {
            // The committer stopped on an error, which write_each returns.
            return Ok(());
        }
    }
    log::debug!(
        "the writer's queue held at most {:.1} MB at once",
        receiver.peak_bytes() as f64 / 1e6
    );
    Ok(())
}

/// The committer stage: each encoded frame synced and renamed into place, its PNG, its report
/// row (the write time completed) and its log line, in the order they were rendered.
fn commit_each(
    committing: std::sync::mpsc::Receiver<Encoded>,
    mut report: crate::output::report::ReportWriter,
    log: super::resume::FrameLog,
) -> Result<(), SnellError> {
    for encoded in committing {
        let clock = Instant::now();
        let path = encoded.file.path().to_path_buf();
        encoded.file.commit()?;
        if let Some(png) = &encoded.png {
            crate::output::tonemap::save_png_atomic(&path.with_extension("png"), png)?;
        }
        let mut row = encoded.row;
        row.stage_secs.insert(
            "write".to_string(),
            encoded.encode_secs + clock.elapsed().as_secs_f64(),
        );
        report.append(&row)?;
        if let Some(line) = log.line(&path, &row) {
            crate::outln!("{line}");
        }
    }
    Ok(())
}
