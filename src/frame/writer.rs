//! The writer thread of [`super::RenderJob::render_sequence`]: frames arrive strip by strip
//! ([`ToWriter`]) and go to disk as they come, EXR (streamed, atomic), optional PNG, then the
//! report row, so a frame larger than one strip is never held whole.

use std::path::PathBuf;
use std::time::Instant;

use super::SnellError;
use crate::draw::RenderedFrame;

/// A frame on its way to disk, strip by strip: what the writer thread of
/// [`super::RenderJob::render_sequence`] receives.
pub(super) enum ToWriter {
    /// A frame begins: where it goes and what its header says.
    Start(Box<FrameStart>),
    /// The frame's next strip: the row it starts at, and its layers.
    Strip(u32, RenderedFrame),
    /// The frame's last strip was sent: its report row (render time filled in).
    Done(Box<crate::output::report::FrameReport>),
}

pub(super) struct FrameStart {
    pub path: PathBuf,
    pub meta: crate::output::exr::FrameMeta,
    pub width: u32,
    pub height: u32,
}

/// The writer thread of [`super::RenderJob::render_sequence`]: each frame's EXR (atomic, streamed strip
/// by strip as they come), optional PNG, then the report row with the write time (the time spent
/// writing, not waiting for strips) filled in. Stops at the first error; a frame whose strips stop
/// coming (the render failed) leaves no file.
///
/// The chunks of a frame are compressed on a thread pool of the writer's own, one thread per
/// core: on rayon's shared pool they queued ahead of the next frame's water, refraction and
/// render work, which then waited for the whole frame's compression (the `water` stage of a
/// written frame took 0.3-1.2 s instead of a few ms); with a pool of its own the system shares
/// the cores between the two.
pub(super) fn write_frames(
    receiver: std::sync::mpsc::Receiver<ToWriter>,
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
    receiver: std::sync::mpsc::Receiver<ToWriter>,
    mut report: crate::output::report::ReportWriter,
    write_png: bool,
    log: super::resume::FrameLog,
) -> Result<(), SnellError> {
    while let Ok(message) = receiver.recv() {
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
        crate::output::exr::write_frame_exr_strips(
            &start.path,
            &start.meta,
            start.width,
            start.height,
            || {
                let asked = Instant::now();
                let message = receiver.recv();
                waiting += asked.elapsed().as_secs_f64();
                match message {
                    Ok(ToWriter::Strip(first_row, strip)) => {
                        if let Some(png) = &mut png {
                            let rows = crate::output::tonemap::tonemap_srgb8(&strip, 0.0);
                            let at = first_row as usize * start.width as usize * 4;
                            let bytes: &mut [u8] = png;
                            bytes[at..at + rows.len()].copy_from_slice(&rows);
                        }
                        Ok(Some((first_row, std::borrow::Cow::Owned(strip))))
                    }
                    Ok(ToWriter::Done(row)) => {
                        done = Some(row);
                        Ok(None)
                    }
                    Ok(ToWriter::Start(_)) => {
                        Err("a frame began before the last one was complete".to_string())
                    }
                    Err(_) => Err("the render stopped before the frame was complete".to_string()),
                }
            },
        )?;
        if let Some(png) = &png {
            crate::output::tonemap::save_png_atomic(&start.path.with_extension("png"), png)?;
        }
        let mut row = done.expect("the frame is complete once written");
        row.stage_secs.insert(
            "write".to_string(),
            (clock.elapsed().as_secs_f64() - waiting).max(0.0),
        );
        report.append(&row)?;
        if let Some(line) = log.line(&start.path, &row) {
            crate::outln!("{line}");
        }
    }
    Ok(())
}
