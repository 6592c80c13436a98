//! A frame drawn and read back as horizontal strips of rows (issue 19): how many rows a strip
//! has, and the loop that draws, reads back and hands on each strip.

use super::device::within_error_scopes;
use super::readback::{read_back, readback_bytes_per_row, FrameTargets};
use super::resolve::{points_for, SUPERSAMPLE};
use super::uniform::FrameUniform;
use super::{GpuError, Renderer};
use crate::draw::{FrameDraw, FrameView, RenderedFrame};

/// Bytes of readback buffer a strip may take: wgpu's default `max_buffer_size`, which the device
/// keeps. A 1280x720 frame (about 60 MiB) and a 2560x1440 one fit whole; a 7680x4320 frame is
/// read back in 9 strips of 512 rows.
const STRIP_READBACK_BYTES: u64 = 256 << 20;

/// A strip's rows are a multiple of this (but a frame's last strip): the largest block of scan
/// lines an EXR compression writes (PIZ's 32), so that a strip ends on a block of the file.
pub const STRIP_ROW_MULTIPLE: u32 = 32;

/// How many rows each strip of a frame `height` rows high has (`height`: the frame is drawn
/// whole) when a strip's readback may take `budget_bytes` and a row takes `row_bytes`, or as
/// `forced` says; fewer rows than the frame are rounded down to [`STRIP_ROW_MULTIPLE`] (at least
/// one multiple).
pub fn strip_rows_for(height: u32, row_bytes: u64, budget_bytes: u64, forced: Option<u32>) -> u32 {
    let rows = match forced {
        Some(rows) => rows,
        None if row_bytes.saturating_mul(height as u64) <= budget_bytes => return height,
        None => (budget_bytes / row_bytes.max(1)).min(u32::MAX as u64) as u32,
    };
    if rows >= height {
        return height;
    }
    (rows / STRIP_ROW_MULTIPLE * STRIP_ROW_MULTIPLE)
        .max(STRIP_ROW_MULTIPLE)
        .min(height)
}

impl Renderer {
    /// Draws one frame at `width` x `height` and reads every layer back: whole, or strip by strip
    /// ([`Self::render_strips`]) joined into one frame where it is too large to read back at once.
    pub fn render(
        &mut self,
        draw: &FrameDraw,
        view: &FrameView,
        width: u32,
        height: u32,
    ) -> Result<RenderedFrame, GpuError> {
        let mut whole = None;
        self.render_strips(draw, view, width, height, |_, strip| {
            RenderedFrame::gather(&mut whole, strip, height);
            Ok::<(), GpuError>(())
        })?;
        Ok(whole.unwrap_or_default())
    }

    /// Makes every frame's strips `rows` rows high (rounded down to [`STRIP_ROW_MULTIPLE`]), or,
    /// with `None`, as [`Self::strip_rows`] chooses. Strips render the same pixels as a whole
    /// frame; forcing them is for tests and measurements.
    pub fn set_strip_rows(&mut self, rows: Option<u32>) {
        self.forced_strip_rows = rows;
    }

    /// Rows of each strip of a `width` x `height` frame: `height` (one strip, the whole frame)
    /// when its readback fits [`STRIP_READBACK_BYTES`], otherwise as many rows as do, a multiple
    /// of [`STRIP_ROW_MULTIPLE`].
    pub fn strip_rows(&self, width: u32, height: u32) -> u32 {
        let budget = STRIP_READBACK_BYTES.min(self.context.device.limits().max_buffer_size);
        let row_bytes = readback_bytes_per_row(&self.context, width, self.supersample);
        strip_rows_for(height, row_bytes, budget, self.forced_strip_rows)
    }

    /// Draws one frame at `width` x `height` as horizontal strips of [`Self::strip_rows`] rows,
    /// top first, and gives each strip's layers to `sink` with the frame row it starts at, as
    /// soon as it is read back. Each strip draws the whole frame's geometry through the frame's
    /// own projection with the viewport moved up by the strip's first row, and its pixels are the
    /// frame's: the triangle draws place their corners on the whole frame's subpixel grid and
    /// interpolate from the whole frame's pixel centres ([`super::pulling`]), and only
    /// one strip's targets and readback are held at a time. A frame of one strip is drawn exactly
    /// as before strips existed (no viewport set, offset 0).
    pub fn render_strips<E: From<GpuError>>(
        &mut self,
        draw: &FrameDraw,
        view: &FrameView,
        width: u32,
        height: u32,
        mut sink: impl FnMut(u32, RenderedFrame) -> Result<(), E>,
    ) -> Result<(), E> {
        self.validate(draw, width, height)?;
        let rows = self.strip_rows(width, height);
        if self
            .targets
            .as_ref()
            .is_none_or(|targets| (targets.width, targets.height) != (width, rows))
        {
            // The old targets go first, so that two sizes are never held at once.
            self.targets = None;
            self.targets = Some(FrameTargets::new(
                &self.context,
                &self.reflection_layout,
                self.resolve.as_ref(),
                (width, rows),
                self.supersample,
            ));
        }
        let device = self.context.device.clone();
        within_error_scopes(&device, "uploading the frame", || {
            self.upload_frame(draw);
            Ok(())
        })?;
        let mut first_row = 0;
        while first_row < height {
            let strip_rows = rows.min(height - first_row);
            let started = std::time::Instant::now();
            within_error_scopes(&device, "drawing the frame", || {
                self.draw_strip(draw, view, (width, height), first_row, strip_rows);
                Ok(())
            })?;
            let submitted = std::time::Instant::now();
            // Waiting here separately only splits the time between drawing and reading back.
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(GpuError::from)?;
            let drawn = std::time::Instant::now();
            let targets = self.targets.as_ref().expect("created above");
            let strip = read_back(&device, targets, strip_rows)?;
            log::debug!(
                "gpu frame {width}x{height} rows {first_row}..{}: encode {:.1} ms, draw {:.1} ms, readback {:.1} ms",
                first_row + strip_rows,
                (submitted - started).as_secs_f64() * 1e3,
                (drawn - submitted).as_secs_f64() * 1e3,
                drawn.elapsed().as_secs_f64() * 1e3
            );
            sink(first_row, strip)?;
            first_row += strip_rows;
        }
        Ok(())
    }

    /// Encodes and submits the passes of the strip of `rows` rows from `first_row` of a frame of
    /// `size`, and its copy into the readback buffer.
    fn draw_strip(
        &self,
        draw: &FrameDraw,
        view: &FrameView,
        size: (u32, u32),
        first_row: u32,
        rows: u32,
    ) {
        let device = &self.context.device;
        let queue = &self.context.queue;
        let (width, height) = size;
        let targets = self.targets.as_ref().expect("created above");
        // A supersampled frame draws its points: the frame of 2 width + 1 by 2 height + 1
        // points, a strip from point row 2 first_row (super::resolve).
        let (drawn_width, drawn_height, drawn_first_row) = match &targets.points {
            Some(_) => (
                points_for(width),
                points_for(height),
                SUPERSAMPLE * first_row,
            ),
            None => (width, height, first_row),
        };
        queue.write_buffer(
            &self.frame_uniform,
            0,
            bytemuck::bytes_of(&FrameUniform::new(
                view,
                (width, height),
                first_row,
                targets.points.is_some(),
            )),
        );
        // The whole frame's viewport, moved up so that the strip's first row lands on the
        // targets' row 0 (WebGPU allows a viewport beyond the attachment). Not set for a whole
        // frame, which keeps the default viewport.
        let viewport =
            (targets.height < height).then_some((drawn_width, drawn_height, drawn_first_row));
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        self.encode_passes(&mut encoder, draw, targets, viewport);
        targets.copy_to_readback(&mut encoder, rows);
        queue.submit([encoder.finish()]);
    }
}

/// Sets a strip's viewport: the whole frame's (`width` x `height`), its top `first_row` rows
/// above the attachment.
pub(super) fn set_strip_viewport(
    pass: &mut wgpu::RenderPass<'_>,
    viewport: Option<(u32, u32, u32)>,
) {
    if let Some((width, height, first_row)) = viewport {
        pass.set_viewport(
            0.0,
            -(first_row as f32),
            width as f32,
            height as f32,
            0.0,
            1.0,
        );
    }
}
