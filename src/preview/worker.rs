//! The preview's render worker: the one thread that owns the GPU renderer and the loaded job.
//! Takes work in priority order: frames a client waits for (latest request first), then the
//! neighbours of the last requested frame, then the strip's flag counts one frame at a time (so a
//! client's request waits at most one CPU-only frame).

use std::collections::HashMap;
use std::sync::Arc;

use super::source::Source;
use super::{CachedFrame, FrameKey, Shared, State, Strip};
use crate::frame::{Method, RenderJob, SnellError};
use crate::gpu::Renderer;
use crate::refraction::flags::TrackingState;

use super::lru::Lru;

/// Asks the worker to fill the strip of `source` (no-op when it already exists, and for frames
/// read from files, whose vertex and triangle counts are not stored).
pub(super) fn want_strip(state: &mut State, source: Source) {
    let Some(scene) = &state.scene else { return };
    if source.method().is_none() {
        return;
    }
    let frames = (scene.last_frame - scene.first_frame + 1) as usize;
    state.strips.entry(source).or_insert_with(|| Strip {
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

/// The loaded job and its generation, kept outside [`Worker`] so that a worker restarted after a
/// panic carries on with the scene (a panic unwinds through the worker, not through this).
struct Loaded {
    job: Option<RenderJob>,
    generation: u64,
}

struct Worker<'a> {
    loaded: &'a mut Loaded,
    renderer: Option<Renderer>,
    textures_uploaded: bool,
    /// Tracking states of recently refracted frames, so a frame after one just rendered needs no
    /// recomputation of its predecessor.
    trackings: Lru<FrameKey, Arc<TrackingState>>,
    cursors: HashMap<Source, StripCursor>,
}

/// Runs the worker; a panic fails the frame it was on at once (500, so no request waits for it),
/// is shown on the page and in the API, and restarts the worker with a new renderer.
/// [`super::RESTARTS_IN_A_ROW`] panics without a frame done in between stop it: every frame
/// request then fails at once with the reason.
pub(super) fn supervise(shared: &Shared) {
    let mut loaded = Loaded {
        job: None,
        generation: 0,
    };
    loop {
        let Err(message) = crate::panics::catch(|| run(shared, &mut loaded)) else {
            return;
        };
        let mut state = shared.lock();
        state.worker_busy = false;
        let in_flight = state.in_flight.take();
        let restart = state.worker.record_panic("render worker", &message);
        if let Some(key) = in_flight.filter(|key| key.generation == state.generation) {
            let then = if restart {
                "the worker was restarted; other frames render"
            } else {
                "the worker was stopped; restart snell preview"
            };
            state.failed.insert(
                key,
                (
                    500,
                    format!(
                        "the render worker panicked on frame {}: {message}; {then}",
                        key.frame
                    ),
                ),
            );
        }
        state.revision += 1;
        drop(state);
        shared.wake.notify_all();
        if !restart {
            return;
        }
    }
}

fn run(shared: &Shared, loaded: &mut Loaded) {
    // The renderer is made before the first request, so no request pays for creating it; frames
    // read from files need none.
    let renderer = if !shared.folders.is_empty() {
        None
    } else {
        match Renderer::new() {
            Ok(renderer) => Some(renderer),
            Err(error) => {
                shared.lock().renderer_problem = Some(error.to_string());
                None
            }
        }
    };
    let mut worker = Worker {
        loaded,
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
                state.in_flight = None;
                if key.generation == state.generation {
                    match result {
                        Ok(frame) => {
                            state.worker.panics_in_a_row = 0;
                            let first = state.scene.as_ref().map_or(0, |s| s.first_frame);
                            if let Some(strip) = state.strips.get_mut(&key.source) {
                                if let Some(slot) =
                                    strip.counts.get_mut((key.frame - first) as usize)
                                {
                                    *slot = frame.counts;
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
                state.in_flight = None;
                if result.is_ok() {
                    state.worker.panics_in_a_row = 0;
                }
                if key.generation == state.generation {
                    let first = state.scene.as_ref().map_or(0, |s| s.first_frame);
                    if let Some(strip) = state.strips.get_mut(&key.source) {
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
            worker.loaded.job = Some(job);
            worker.loaded.generation = state.generation;
            worker.textures_uploaded = false;
            worker.trackings.clear();
            worker.cursors.clear();
        }
        let reading_files = !shared.folders.is_empty();
        if reading_files
            || (worker.loaded.job.is_some() && worker.loaded.generation == state.generation)
        {
            let mut task = None;
            while let Some(key) = state.demand.pop_front() {
                if is_wanted(&state, key) {
                    task = Some(Task::Render(key));
                    break;
                }
            }
            while task.is_none() {
                match state.prefetch.pop_front() {
                    Some(key) if is_wanted(&state, key) => task = Some(Task::Render(key)),
                    Some(_) => {}
                    None => break,
                }
            }
            if task.is_none() {
                task = next_count(&state, worker).map(Task::Count);
            }
            if let Some(task) = task {
                state.worker_busy = true;
                state.in_flight = Some(match task {
                    Task::Render(key) | Task::Count(key) => key,
                });
                return Some(task);
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
    let mut sources: Vec<Source> = state.strips.keys().copied().collect();
    sources.sort_by_key(|s| s.method().map(Method::name));
    for source in sources {
        let strip = &state.strips[&source];
        let cursor = worker.cursors.entry(source).or_insert(StripCursor {
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
            return Some(state.frame_key(source, cursor.next_frame));
        }
    }
    None
}

impl Worker<'_> {
    fn job_for(&mut self, method: Method) -> &mut RenderJob {
        let job = self.loaded.job.as_mut().expect("a task implies a job");
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
        let job = self.job_for(key.source.method().expect("rendered sources only"));
        Ok(job
            .previous_tracking(key.frame, shared.width, shared.height)?
            .map(Arc::new))
    }

    fn render(&mut self, shared: &Shared, key: FrameKey) -> Result<CachedFrame, SnellError> {
        if shared.faults.worker_panic_frame == Some(key.frame) || shared.faults.worker_panics_always
        {
            panic!("an injected render-worker panic (Faults::worker_panic_frame)");
        }
        let method = match key.source {
            Source::Method(method) => method,
            Source::Folder(index) => return decode(shared, index, key.frame),
        };
        // The ray-traced methods render on the CPU and need no GPU.
        if self.renderer.is_none() && method.uses_gpu() {
            let problem = shared.lock().renderer_problem.clone().unwrap_or_default();
            return Err(SnellError::Argument(format!("no GPU renderer: {problem}")));
        }
        let previous = self.previous_tracking(shared, key)?;
        let (width, height) = (shared.width, shared.height);
        let job = self.loaded.job.as_mut().expect("a task implies a job");
        job.method = method;
        let renderer = self.renderer.as_mut().filter(|_| method.uses_gpu());
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
            counts: Some(counts),
            stage_secs,
            object_names: Arc::new(job.object_names()),
            write: crate::output::exr::WriteOptions::default(),
            file_channels: None,
        })
    }

    /// The CPU stages only, for the strip; frames are taken in order so each one's predecessor
    /// tracking is at hand.
    fn count(
        &mut self,
        shared: &Shared,
        key: FrameKey,
    ) -> Result<crate::refraction::flags::FlagCounts, SnellError> {
        if shared.faults.worker_panics_always {
            panic!("an injected render-worker panic (Faults::worker_panics_always)");
        }
        let cursor_previous = self
            .cursors
            .get_mut(&key.source)
            .and_then(|cursor| cursor.previous.take());
        let previous = match cursor_previous {
            Some(tracking) => Some(Arc::new(tracking)),
            None => self.previous_tracking(shared, key)?,
        };
        let (width, height) = (shared.width, shared.height);
        let job = self.job_for(
            key.source
                .method()
                .expect("strips of rendered sources only"),
        );
        let result = job.refract(key.frame, width, height, previous.as_deref());
        let cursor = self
            .cursors
            .get_mut(&key.source)
            .expect("next_count made the cursor");
        cursor.next_frame = key.frame + 1;
        let refracted = result?;
        let counts = refracted.counts;
        cursor.previous = Some(refracted.tracking);
        Ok(counts)
    }
}

/// Frame `frame` of `--frames-dir` folder `index`, read from its EXR file (with the read's time
/// as its only stage). A frame the folder lacks, or a file that does not read, is the input's
/// fault (422), named with its file.
fn decode(shared: &Shared, index: u8, frame: u32) -> Result<CachedFrame, SnellError> {
    let folder = &shared.folders[index as usize];
    let Some(path) = folder.files.get(&frame) else {
        return Err(SnellError::Argument(format!(
            "{} holds no frame {frame} (it has {} frames, {} to {})",
            folder.shown,
            folder.files.len(),
            folder.files.keys().next().unwrap_or(&0),
            folder.files.keys().next_back().unwrap_or(&0)
        )));
    };
    let started = std::time::Instant::now();
    let (rendered, meta, file) =
        crate::output::exr::read_frame_and_channels(path).map_err(SnellError::Output)?;
    // In the file's order (the reader sorts by name): the order the writer gives them.
    let order: Vec<String> = crate::output::exr::channel_values(
        &rendered,
        &meta.object_names,
        &meta.write,
        0..0,
        |_| true,
    )
    .into_iter()
    .map(|(name, _)| name)
    .collect();
    let mut channels: Vec<(String, Vec<f32>)> = file.channels.into_iter().collect();
    channels.sort_by_key(|(name, _)| order.iter().position(|n| n == name).unwrap_or(usize::MAX));
    let mut stage_secs = std::collections::BTreeMap::new();
    stage_secs.insert("read_exr".to_string(), started.elapsed().as_secs_f64());
    Ok(CachedFrame {
        rendered,
        counts: None,
        stage_secs,
        object_names: Arc::new(meta.object_names),
        write: meta.write,
        file_channels: Some(channels),
    })
}
