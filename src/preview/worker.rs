//! The preview's render worker: the one thread that owns the GPU renderer and the loaded job.
//! Takes work in priority order: frames a client waits for (latest request first), then the
//! neighbours of the last requested frame, then the strip's flag counts one frame at a time (so a
//! client's request waits at most one CPU-only frame).

use std::collections::HashMap;
use std::sync::Arc;

use super::{CachedFrame, FrameKey, Shared, State, Strip};
use crate::frame::{Method, RenderJob, SnellError};
use crate::gpu::Renderer;
use crate::refraction::flags::TrackingState;

use super::lru::Lru;

/// Asks the worker to fill the strip of `method` (no-op when it already exists).
pub(super) fn want_strip(state: &mut State, method: Method) {
    let Some(scene) = &state.scene else { return };
    let frames = (scene.last_frame - scene.first_frame + 1) as usize;
    state.strips.entry(method).or_insert_with(|| Strip {
        counts: vec![None; frames],
    });
}

enum Task {
    Render(FrameKey),
    Count(FrameKey),
}

/// Where the strip of one method has got to: its next frame and that frame's predecessor's
/// tracking (popping compares with it).
struct StripCursor {
    next_frame: u32,
    previous: Option<TrackingState>,
}

struct Worker {
    job: Option<RenderJob>,
    generation: u64,
    renderer: Option<Renderer>,
    textures_uploaded: bool,
    /// Tracking states of recently refracted frames, so a frame after one just rendered needs no
    /// recomputation of its predecessor.
    trackings: Lru<FrameKey, Arc<TrackingState>>,
    cursors: HashMap<Method, StripCursor>,
}

pub(super) fn run(shared: &Shared) {
    // The renderer is made before the first request, so no request pays for creating it.
    let renderer = match Renderer::new() {
        Ok(renderer) => Some(renderer),
        Err(error) => {
            shared.lock().renderer_problem = Some(error.to_string());
            None
        }
    };
    let mut worker = Worker {
        job: None,
        generation: 0,
        renderer,
        textures_uploaded: false,
        trackings: Lru::new(16),
        cursors: HashMap::new(),
    };
    while let Some(task) = next_task(shared, &mut worker) {
        match task {
            Task::Render(key) => {
                let result = worker.render(shared, key);
                let mut guard = shared.lock();
                let state = &mut *guard;
                state.worker_busy = false;
                if key.generation == state.generation {
                    match result {
                        Ok(frame) => {
                            let first = state.scene.as_ref().map_or(0, |s| s.first_frame);
                            if let Some(strip) = state.strips.get_mut(&key.method) {
                                if let Some(slot) =
                                    strip.counts.get_mut((key.frame - first) as usize)
                                {
                                    *slot = Some(frame.counts);
                                }
                            }
                            state.frames.insert(key, Arc::new(frame));
                        }
                        Err(error) => {
                            let status = if error.is_bad_input() { 422 } else { 500 };
                            state.failed.insert(key, (status, error.to_string()));
                        }
                    }
                }
                drop(guard);
                shared.wake.notify_all();
            }
            Task::Count(key) => {
                let result = worker.count(shared, key);
                let mut state = shared.lock();
                state.worker_busy = false;
                if key.generation == state.generation {
                    let first = state.scene.as_ref().map_or(0, |s| s.first_frame);
                    if let Some(strip) = state.strips.get_mut(&key.method) {
                        if let Some(slot) = strip.counts.get_mut((key.frame - first) as usize) {
                            // A frame whose refraction fails keeps no counts; the page shows it
                            // as missing, and the frame request itself reports the error.
                            *slot = result.ok();
                        }
                    }
                }
                drop(state);
                shared.wake.notify_all();
            }
        }
    }
}

/// Waits for the next task; None when the server stops.
fn next_task(shared: &Shared, worker: &mut Worker) -> Option<Task> {
    let mut state = shared.lock();
    loop {
        if state.stopping {
            return None;
        }
        if let Some(job) = state.incoming_job.take() {
            worker.job = Some(job);
            worker.generation = state.generation;
            worker.textures_uploaded = false;
            worker.trackings.clear();
            worker.cursors.clear();
        }
        if worker.job.is_some() && worker.generation == state.generation {
            while let Some(key) = state.demand.pop_front() {
                if is_wanted(&state, key) {
                    state.worker_busy = true;
                    return Some(Task::Render(key));
                }
            }
            while let Some(key) = state.prefetch.pop_front() {
                if is_wanted(&state, key) {
                    state.worker_busy = true;
                    return Some(Task::Render(key));
                }
            }
            if let Some(key) = next_count(&state, worker) {
                state.worker_busy = true;
                return Some(Task::Count(key));
            }
        }
        state = shared
            .wake
            .wait(state)
            .unwrap_or_else(|poisoned| poisoned.into_inner());
    }
}

fn is_wanted(state: &State, key: FrameKey) -> bool {
    key.generation == state.generation
        && !state.frames.contains(&key)
        && !state.failed.contains_key(&key)
        && state.frame_in_range(key.frame)
}

/// The next frame some strip lacks counts for.
fn next_count(state: &State, worker: &mut Worker) -> Option<FrameKey> {
    let scene = state.scene.as_ref()?;
    let mut methods: Vec<Method> = state.strips.keys().copied().collect();
    methods.sort_by_key(|m| m.name());
    for method in methods {
        let strip = &state.strips[&method];
        let cursor = worker.cursors.entry(method).or_insert(StripCursor {
            next_frame: scene.first_frame,
            previous: None,
        });
        // Skip frames whose counts arrived with a rendered frame; the cursor's tracking is then
        // stale, and the next count recomputes its predecessor.
        while cursor.next_frame <= scene.last_frame
            && strip.counts[(cursor.next_frame - scene.first_frame) as usize].is_some()
        {
            cursor.next_frame += 1;
            cursor.previous = None;
        }
        if cursor.next_frame <= scene.last_frame {
            return Some(state.frame_key(method, cursor.next_frame));
        }
    }
    None
}

impl Worker {
    fn job_for(&mut self, method: Method) -> &mut RenderJob {
        let job = self.job.as_mut().expect("a task implies a job");
        job.method = method;
        job
    }

    /// The tracking of the frame before `key`, from the cache or recomputed.
    fn previous_tracking(
        &mut self,
        shared: &Shared,
        key: FrameKey,
    ) -> Result<Option<Arc<TrackingState>>, SnellError> {
        let previous_key = FrameKey {
            frame: key.frame.wrapping_sub(1),
            ..key
        };
        if let Some(tracking) = self.trackings.get(&previous_key) {
            return Ok(Some(tracking));
        }
        let job = self.job_for(key.method);
        Ok(job
            .previous_tracking(key.frame, shared.width, shared.height)?
            .map(Arc::new))
    }

    fn render(&mut self, shared: &Shared, key: FrameKey) -> Result<CachedFrame, SnellError> {
        // The ray-traced methods render on the CPU and need no GPU.
        if self.renderer.is_none() && key.method.uses_gpu() {
            let problem = shared.lock().renderer_problem.clone().unwrap_or_default();
            return Err(SnellError::Argument(format!("no GPU renderer: {problem}")));
        }
        let previous = self.previous_tracking(shared, key)?;
        let (width, height) = (shared.width, shared.height);
        let job = self.job.as_mut().expect("a task implies a job");
        job.method = key.method;
        let renderer = self.renderer.as_mut().filter(|_| key.method.uses_gpu());
        let renderer = match renderer {
            Some(renderer) if !self.textures_uploaded => {
                job.upload_textures(renderer)?;
                self.textures_uploaded = true;
                Some(renderer)
            }
            other => other,
        };
        let mut refracted = job.refract(key.frame, width, height, previous.as_deref())?;
        let rendered = job.render_refracted(renderer, &mut refracted, width, height)?;
        let counts = refracted.counts;
        let stage_secs = refracted.stage_secs.clone();
        self.trackings.insert(key, Arc::new(refracted.tracking));
        Ok(CachedFrame {
            rendered,
            counts,
            stage_secs,
        })
    }

    /// The CPU stages only, for the strip; frames are taken in order so each one's predecessor
    /// tracking is at hand.
    fn count(
        &mut self,
        shared: &Shared,
        key: FrameKey,
    ) -> Result<crate::refraction::flags::FlagCounts, SnellError> {
        let cursor_previous = self
            .cursors
            .get_mut(&key.method)
            .and_then(|cursor| cursor.previous.take());
        let previous = match cursor_previous {
            Some(tracking) => Some(Arc::new(tracking)),
            None => self.previous_tracking(shared, key)?,
        };
        let (width, height) = (shared.width, shared.height);
        let job = self.job_for(key.method);
        let result = job.refract(key.frame, width, height, previous.as_deref());
        let cursor = self
            .cursors
            .get_mut(&key.method)
            .expect("next_count made the cursor");
        cursor.next_frame = key.frame + 1;
        let refracted = result?;
        let counts = refracted.counts;
        cursor.previous = Some(refracted.tracking);
        Ok(counts)
    }
}
