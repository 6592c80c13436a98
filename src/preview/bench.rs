//! Scrub latency for `snell bench`: the time from a request for a frame to its PNG, through the
//! preview's real HTTP server, for frames not rendered yet (uncached) and for frames just shown
//! (cached). Each uncached request is made with the worker idle (prefetching and strip counting
//! done), so it measures one frame, not a queue.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;

use super::{client, PreviewOptions, PreviewServer};
use crate::frame::SnellError;
use crate::stats::median;

#[derive(Debug, Serialize)]
pub struct ScrubFigures {
    pub scene: String,
    pub size: [u32; 2],
    pub frames_measured: usize,
    /// Request to PNG for frames never rendered (refraction, render, tone mapping, encoding).
    pub uncached_ms_median: f64,
    pub uncached_ms_max: f64,
    /// Request to PNG for the frame shown last (served from the image cache).
    pub cached_ms_median: f64,
    pub cached_ms_max: f64,
}

impl ScrubFigures {
    pub fn to_text(&self) -> String {
        format!(
            "preview scrub latency, {} at {}x{} ({} frames): uncached {:.1} ms median ({:.1} max), cached {:.2} ms median ({:.2} max)\n",
            self.scene,
            self.size[0],
            self.size[1],
            self.frames_measured,
            self.uncached_ms_median,
            self.uncached_ms_max,
            self.cached_ms_median,
            self.cached_ms_max
        )
    }
}

fn fail(message: String) -> SnellError {
    SnellError::Argument(format!("preview bench: {message}"))
}

/// Waits until the worker has nothing queued (strip counted, prefetch done).
fn wait_idle(url: &str) -> Result<serde_json::Value, SnellError> {
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        let scene = client::get(url, "/api/scene")
            .map_err(fail)?
            .json()
            .map_err(fail)?;
        if let Some(problem) = scene["problem"].as_str() {
            return Err(fail(problem.to_string()));
        }
        if scene["worker_busy"] == false && scene["strips_done"] == true {
            return Ok(scene);
        }
        if Instant::now() > deadline {
            return Err(fail(
                "the preview worker did not go idle within 300 s".into(),
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn timed_png(url: &str, frame: u32) -> Result<(f64, String), SnellError> {
    let clock = Instant::now();
    let response = client::get(url, &format!("/api/frame/{frame}.png")).map_err(fail)?;
    let ms = clock.elapsed().as_secs_f64() * 1e3;
    if response.status != 200 || response.header("content-type") != Some("image/png") {
        return Err(fail(format!(
            "frame {frame}: status {} {}",
            response.status,
            String::from_utf8_lossy(&response.body)
        )));
    }
    Ok((
        ms,
        response.header("x-snell-cache").unwrap_or("").to_string(),
    ))
}

/// Measures `frames` frames of `scene_path` spread over its timeline at 640x360.
pub fn scrub_latency(scene_path: &Path, frames: usize) -> Result<ScrubFigures, SnellError> {
    let checkpoints = tempfile::tempdir().map_err(|e| fail(e.to_string()))?;
    let mut options = PreviewOptions::new(scene_path);
    options.port = 0;
    options.out_dir = Some(checkpoints.path().to_path_buf());
    let server = PreviewServer::start(options.clone())?;
    let url = server.url().to_string();
    let result = (|| {
        let scene = wait_idle(&url)?;
        let first = scene["scene"]["first_frame"].as_u64().unwrap_or(1) as u32;
        let last = scene["scene"]["last_frame"].as_u64().unwrap_or(1) as u32;
        let span = last - first + 1;
        let count = frames.clamp(1, span as usize) as u32;
        // Frames spread over the timeline, far enough apart not to be each other's prefetch, and
        // centred in their share of it (the first frame is rendered when the scene loads).
        let picks: Vec<u32> = (0..count)
            .map(|i| first + i * span / count + span / (2 * count))
            .collect();
        let (mut uncached, mut cached) = (Vec::new(), Vec::new());
        for frame in picks {
            wait_idle(&url)?;
            let (ms, cache) = timed_png(&url, frame)?;
            if cache != "miss" {
                return Err(fail(format!(
                    "frame {frame} was expected uncached but was {cache}"
                )));
            }
            uncached.push(ms);
            let (ms, cache) = timed_png(&url, frame)?;
            if cache != "image" {
                return Err(fail(format!(
                    "frame {frame} was expected cached but was {cache}"
                )));
            }
            cached.push(ms);
        }
        Ok(ScrubFigures {
            scene: scene["scene"]["name"].as_str().unwrap_or("").to_string(),
            size: [options.width, options.height],
            frames_measured: uncached.len(),
            uncached_ms_max: uncached.iter().copied().fold(0.0, f64::max),
            cached_ms_max: cached.iter().copied().fold(0.0, f64::max),
            uncached_ms_median: median(&mut uncached),
            cached_ms_median: median(&mut cached),
        })
    })();
    server.stop();
    result
}
