//! `snell preview`: a local web page to scrub a scene's timeline, or folders of rendered EXRs
//! (`--frames-dir`, see `source.rs`). Receives a scene path and a preview size (or the folders);
//! serves on 127.0.0.1 a page (frame, zoom and pan, timeline slider, play/pause, J/K/L, a loop
//! range, a frame number to type, exposure, method A and B with wipe and difference, a layer
//! to view, flag overlays, a pixel inspector, a strip of per-frame flag counts) and a small API:
//!
//! - `GET /` — the page (no external resources).
//! - `GET /api/scene` — the scene's state: `revision` (changes whenever the page must refresh),
//!   `generation` (changes when a new version of the scene is loaded), name, frame range, fps,
//!   size, methods (the sources: methods, or folders), layers, the reference source, the current
//!   load `problem` (file, line and message) and a `notice`.
//! - `GET /api/frame/<N>.png?method=&exposure=&flags=&layer=&against=` — frame N's `layer`
//!   (default the beauty) drawn as `layers.rs` says, tone-mapped at `exposure` stops, with the
//!   named flag masks (`convergence,boundary,popping,extrapolated`) overlaid; with `against=` the
//!   difference of the layer between the two sources.
//! - `GET /api/frame/<N>.json?method=` — the frame's flag counts and seconds per stage.
//! - `GET /api/pixel/<N>?method=&x=&y=` — every channel's value at one pixel as the frame's EXR
//!   holds it, the object's name, the flags, and the position error against the reference.
//! - `GET /api/strip?method=` — flag counts of every frame (null until computed).
//! - `GET /api/health` — the render worker's and the file watcher's state: 200 while both run,
//!   503 when one was given up after repeated panics (`/api/scene` carries the same, and the page
//!   shows it).
//!
//! Only requests whose `Host` is a loopback name are answered (else 421: DNS rebinding), and the
//! scene path shown is relative to the working folder. Connections are served by a fixed pool of
//! threads with a connection cap and timeouts (see `server.rs`). A panic in the render worker
//! fails the frame it was on at once (500) and restarts the worker; a panic in the watcher
//! restarts it; both are shown on the page.
//!
//! Frames are rendered on demand by one worker thread that owns the GPU renderer, cached (linear
//! frames and encoded images, both bounded), and neighbours of the last requested frame are
//! prefetched while the worker is otherwise idle; after that the worker computes the strip's
//! counts (CPU only). Ripple states come from the simulation checkpoints under the output
//! directory, so any frame is reachable without stepping from the start. A watcher thread polls
//! the scene file and every file it references; a change reloads the scene (a new generation, so
//! frames of the old one are never shown as the new one), and a scene error is shown on the page
//! while the last good version stays available.

pub mod client;
mod http;
mod layers;
mod lru;
mod page;
mod server;
mod source;
mod worker;

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use crate::draw::RenderedFrame;
use crate::frame::{Method, RenderJob, SnellError};
use crate::refraction::flags::FlagCounts;

use lru::Lru;
use source::{Folder, Source};

pub mod bench;

/// How `snell preview` runs.
#[derive(Clone, Debug)]
pub struct PreviewOptions {
    pub scene_path: PathBuf,
    /// 0 picks a free port.
    pub port: u16,
    pub width: u32,
    pub height: u32,
    /// Where simulation checkpoints are read and written (default `output/<scene>/`, shared with
    /// `snell render`, so a render's checkpoints serve the preview and the other way round).
    pub out_dir: Option<PathBuf>,
    /// How often the scene file and its assets are checked for changes.
    pub watch_interval: Duration,
    /// Folders of rendered EXR frames to play back instead of rendering the scene (`--frames-dir`,
    /// once per folder; each is a source to compare A/B). When set, `scene_path` is not read.
    pub frames_dirs: Vec<PathBuf>,
    /// Failures made on purpose, for the tests of the preview's own recovery (the CLI never sets
    /// them; no request or environment variable can).
    pub faults: Faults,
}

/// Panics injected into the preview's threads, so tests can check that a dead render worker or
/// file watcher is restarted and reported. Off by default; only library callers can set them.
#[derive(Clone, Debug, Default)]
pub struct Faults {
    /// The render worker panics whenever it is asked to render this frame.
    pub worker_panic_frame: Option<u32>,
    /// The render worker panics at every task (a frame's render or a strip's count), so that it
    /// is given up after three panics in a row (`RESTARTS_IN_A_ROW`).
    pub worker_panics_always: bool,
    /// The file watcher panics at each of its first this-many polls.
    pub watcher_panics: u32,
}

impl PreviewOptions {
    pub fn new(scene_path: &Path) -> Self {
        PreviewOptions {
            scene_path: scene_path.to_path_buf(),
            port: 8080,
            width: 640,
            height: 360,
            out_dir: None,
            frames_dirs: Vec::new(),
            watch_interval: Duration::from_millis(250),
            faults: Faults::default(),
        }
    }
}

/// Frames of different generations (scene versions) or sources never mix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct FrameKey {
    generation: u64,
    source: Source,
    frame: u32,
}

/// One encoded image: a layer of a frame (or its difference to another source's frame) at one
/// exposure with one set of overlays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct ImageKey {
    frame: FrameKey,
    /// Exposure in 1/1000 stop (floats are not hashable).
    exposure_milli_stops: i32,
    overlay_bits: u32,
    layer: crate::output::exr::channels::Layer,
    /// The difference view: the source the frame is compared with.
    against: Option<Source>,
}

/// A rendered (or decoded) frame kept for the page.
struct CachedFrame {
    rendered: RenderedFrame,
    /// None for a frame read from a file (the vertex and triangle counts are not stored).
    counts: Option<FlagCounts>,
    stage_secs: std::collections::BTreeMap<String, f64>,
    /// Names of the object indices (`IndexOB` 1 is the first).
    object_names: Arc<Vec<String>>,
    /// How the frame's channels are stored (a file's own choice; the defaults for a render).
    write: crate::output::exr::WriteOptions,
    /// A frame read from a file: the file's own channels, as it stores them (derived layers such
    /// as `Refraction` were computed from the float32 beauty before a `--half` file rounded it,
    /// so they cannot be derived again from what the file holds).
    file_channels: Option<Vec<(String, Vec<f32>)>>,
}

/// What the page shows about the loaded scene.
#[derive(Clone, Debug, serde::Serialize)]
struct SceneInfo {
    name: String,
    path: String,
    first_frame: u32,
    last_frame: u32,
    fps: f64,
}

/// Flag counts of every frame of one method, filled by the worker.
struct Strip {
    counts: Vec<Option<FlagCounts>>,
}

struct State {
    /// Bumped on every change the page must see (a reload, a scene error, a fix).
    revision: u64,
    /// Bumped when a new version of the scene is loaded.
    generation: u64,
    scene: Option<SceneInfo>,
    /// The current scene problem (file, line, message), if the last load failed.
    problem: Option<String>,
    notice: Option<String>,
    /// A freshly loaded job for the worker to take.
    incoming_job: Option<RenderJob>,
    /// Frames clients wait for, most recent first.
    demand: VecDeque<FrameKey>,
    /// Neighbours of the last requested frame, nearest first.
    prefetch: VecDeque<FrameKey>,
    frames: Lru<FrameKey, Arc<CachedFrame>>,
    /// Why a frame could not be rendered: HTTP status (422 for the scene's fault, 500 for the
    /// renderer's) and message.
    failed: HashMap<FrameKey, (u16, String)>,
    /// Encoded images and the line saying what they show.
    images: Lru<ImageKey, (Arc<Vec<u8>>, Arc<String>)>,
    /// Strips by source; the worker fills the ones present here (rendered sources only).
    strips: HashMap<Source, Strip>,
    /// Set when the GPU renderer cannot be created: every frame request fails with it.
    renderer_problem: Option<String>,
    /// The worker is rendering or refracting (for the bench: it waits for an idle worker).
    worker_busy: bool,
    /// The frame the worker renders or counts now (a panic there fails it).
    in_flight: Option<FrameKey>,
    worker: ThreadHealth,
    watcher: ThreadHealth,
    stopping: bool,
}

/// Panics after which a thread is given up (a panic between them that did useful work resets
/// the count): the page and the API then report it dead, and every frame request gets a 5xx.
const RESTARTS_IN_A_ROW: u32 = 3;

/// Frames the preview's cache keeps at least, however large (counted in each frame's memory
/// estimate: [`RenderJob::frames_held`]).
const MIN_CACHED_FRAMES: usize = 8;

/// How a supervised thread (the render worker, the file watcher) is doing.
#[derive(Clone, Debug, Default, serde::Serialize)]
struct ThreadHealth {
    /// Times it was restarted after a panic.
    restarts: u32,
    /// Panics since it last did useful work (a frame rendered, a poll of the files).
    #[serde(skip)]
    panics_in_a_row: u32,
    /// The last panic: what and where.
    last_panic: Option<String>,
    /// Set when it was given up: why.
    dead: Option<String>,
}

impl ThreadHealth {
    /// Records a panic; returns whether the thread is to be restarted (else it is now dead).
    fn record_panic(&mut self, name: &str, message: &str) -> bool {
        self.panics_in_a_row += 1;
        self.last_panic = Some(message.to_string());
        if self.panics_in_a_row >= RESTARTS_IN_A_ROW {
            self.dead = Some(format!(
                "the {name} panicked {} times in a row and was stopped; last: {message}",
                self.panics_in_a_row
            ));
            false
        } else {
            self.restarts += 1;
            true
        }
    }

    /// What the page shows about it (None: nothing went wrong).
    fn summary(&self, name: &str) -> Option<String> {
        if let Some(dead) = &self.dead {
            return Some(dead.clone());
        }
        self.last_panic.as_ref().map(|panic| {
            format!(
                "the {name} panicked and was restarted ({} time(s)); last: {panic}",
                self.restarts
            )
        })
    }
}

impl State {
    fn frame_key(&self, source: Source, frame: u32) -> FrameKey {
        FrameKey {
            generation: self.generation,
            source,
            frame,
        }
    }

    fn frame_in_range(&self, frame: u32) -> bool {
        self.scene
            .as_ref()
            .is_some_and(|s| (s.first_frame..=s.last_frame).contains(&frame))
    }

    /// Queues the neighbours of `key` (forward first: playback and scrubbing mostly go forward);
    /// frames read from files are cheaper, and decoded further ahead of the playhead.
    fn queue_prefetch(&mut self, key: FrameKey) {
        self.prefetch.clear();
        const RENDERED: &[i64] = &[1, 2, -1, 3, 4, -2];
        const DECODED: &[i64] = &[1, 2, 3, -1, 4, 5, 6, -2, 7, 8];
        let offsets = match key.source {
            Source::Method(_) => RENDERED,
            Source::Folder(_) => DECODED,
        };
        for &offset in offsets {
            let frame = key.frame as i64 + offset;
            if frame < 0 || !self.frame_in_range(frame as u32) {
                continue;
            }
            let neighbour = FrameKey {
                frame: frame as u32,
                ..key
            };
            if !self.frames.contains(&neighbour) && !self.failed.contains_key(&neighbour) {
                self.prefetch.push_back(neighbour);
            }
        }
    }
}

struct Shared {
    state: Mutex<State>,
    /// Signalled when work arrives for the worker and when a frame is done.
    wake: Condvar,
    width: u32,
    height: u32,
    out_dir: Option<PathBuf>,
    faults: Faults,
    /// The `--frames-dir` folders (empty when the scene is rendered).
    folders: Vec<Folder>,
    /// Watcher panics still to inject.
    watcher_panics_left: std::sync::atomic::AtomicU32,
}

impl Shared {
    /// The sources the page chooses from, with their names and descriptions.
    fn sources(&self) -> Vec<(Source, String, String)> {
        if self.folders.is_empty() {
            Method::ALL
                .iter()
                .map(|&m| {
                    (
                        Source::Method(m),
                        m.name().to_string(),
                        m.description().to_string(),
                    )
                })
                .collect()
        } else {
            self.folders
                .iter()
                .enumerate()
                .map(|(index, folder)| {
                    let method = folder
                        .method_label
                        .as_deref()
                        .unwrap_or("method not recorded");
                    let description =
                        format!("{} ({} frames, {method})", folder.shown, folder.files.len());
                    (
                        Source::Folder(index as u8),
                        folder.name.clone(),
                        description,
                    )
                })
                .collect()
        }
    }

    fn default_source(&self) -> Source {
        if self.folders.is_empty() {
            Source::Method(Method::default())
        } else {
            Source::Folder(0)
        }
    }

    /// The source a request names (`method=`); the default one for none.
    fn source_named(&self, name: Option<&str>) -> Result<Source, String> {
        let Some(name) = name.filter(|n| !n.is_empty()) else {
            return Ok(self.default_source());
        };
        let sources = self.sources();
        match sources.iter().find(|(_, n, _)| n == name) {
            Some((source, _, _)) => Ok(*source),
            None if self.folders.is_empty() => Method::parse(name)
                .map(Source::Method)
                .map_err(|error| error.to_string()),
            None => Err(format!(
                "{name:?} is not a source of this preview; choose one of {}",
                sources
                    .iter()
                    .map(|(_, n, _)| n.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        }
    }

    /// The source whose frames are the ray-traced reference (the inspector's position error).
    fn reference_source(&self) -> Option<Source> {
        if self.folders.is_empty() {
            Some(Source::Method(Method::Raytrace))
        } else {
            self.folders
                .iter()
                .position(Folder::is_reference)
                .map(|index| Source::Folder(index as u8))
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panicking request thread must not take the server down with a poisoned lock.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// A running preview server.
pub struct PreviewServer {
    shared: Arc<Shared>,
    http: server::HttpServer,
    url: String,
    threads: Vec<JoinHandle<()>>,
}

impl PreviewServer {
    /// Binds 127.0.0.1:`port`, loads the scene (a broken scene is shown on the page, not an
    /// error here) and starts serving. Fails only when the port cannot be bound.
    pub fn start(options: PreviewOptions) -> Result<PreviewServer, SnellError> {
        let listener =
            std::net::TcpListener::bind(("127.0.0.1", options.port)).map_err(|error| {
                SnellError::Argument(format!(
                "cannot listen on 127.0.0.1:{}: {error}; choose another port with --port (0 picks a free one)",
                options.port
            ))
            })?;
        let port = listener
            .local_addr()
            .map(|address| address.port())
            .unwrap_or(options.port);
        let url = format!("http://127.0.0.1:{port}/");
        let mut folders: Vec<Folder> = Vec::new();
        for dir in &options.frames_dirs {
            let taken: Vec<String> = folders.iter().map(|f| f.name.clone()).collect();
            folders.push(source::scan_folder(dir, &taken)?);
        }
        let (width, height) = folders
            .first()
            .map_or((options.width, options.height), |f| f.size);
        // A frame read from a file keeps the file's channels too (about 30 floats a pixel).
        let bytes_per_pixel = if folders.is_empty() { 40 } else { 160 };
        let frame_bytes = width as usize * height as usize * bytes_per_pixel;
        // About 1 GiB of linear frames (8 MiB each at 640x360: 128 frames), at least 8.
        let frame_capacity = ((1usize << 30) / frame_bytes.max(1)).clamp(MIN_CACHED_FRAMES, 512);
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                revision: 0,
                generation: 0,
                scene: None,
                problem: None,
                notice: None,
                incoming_job: None,
                demand: VecDeque::new(),
                prefetch: VecDeque::new(),
                frames: Lru::new(frame_capacity),
                failed: HashMap::new(),
                images: Lru::new(256),
                strips: HashMap::new(),
                renderer_problem: None,
                worker_busy: false,
                in_flight: None,
                worker: ThreadHealth::default(),
                watcher: ThreadHealth::default(),
                stopping: false,
            }),
            wake: Condvar::new(),
            width,
            height,
            out_dir: options.out_dir.clone(),
            folders,
            watcher_panics_left: options.faults.watcher_panics.into(),
            faults: options.faults.clone(),
        });
        let mut threads = Vec::new();
        let watcher = if shared.folders.is_empty() {
            let mut watcher = Watcher::new(options.scene_path.clone());
            watcher.reload(&shared);
            Some(watcher)
        } else {
            open_folders(&shared);
            None
        };
        let worker_shared = Arc::clone(&shared);
        threads.push(
            std::thread::Builder::new()
                .name("preview-render".into())
                .spawn(move || worker::supervise(&worker_shared))
                .expect("spawning a thread"),
        );
        if let Some(watcher) = watcher {
            let watch_shared = Arc::clone(&shared);
            let interval = options.watch_interval;
            threads.push(
                std::thread::Builder::new()
                    .name("preview-watch".into())
                    .spawn(move || watcher.supervise(&watch_shared, interval))
                    .expect("spawning a thread"),
            );
        }
        let handler_shared = Arc::clone(&shared);
        let http = server::HttpServer::start(
            listener,
            server::Limits::default(),
            Arc::new(move |request: &server::Request| http::handle(&handler_shared, request)),
        )
        .map_err(|error| {
            SnellError::Argument(format!("cannot start the preview server: {error}"))
        })?;
        Ok(PreviewServer {
            shared,
            http,
            url,
            threads,
        })
    }

    /// `http://127.0.0.1:<port>/`.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Threads the server runs: request threads, the connection poller, the render worker and
    /// the file watcher (a fixed number, whatever the clients do).
    pub fn thread_count(&self) -> usize {
        self.http.thread_count() + self.threads.len()
    }

    /// Stops every thread and closes the socket (waits for the frame the worker is on).
    pub fn stop(self) {
        self.shared.lock().stopping = true;
        self.shared.wake.notify_all();
        self.http.stop();
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

/// Shows the `--frames-dir` folders as the timeline: every frame number any folder holds (a frame
/// a folder lacks is answered 404 for it), at the first folder's frame rate; the first frame is
/// decoded at once.
fn open_folders(shared: &Shared) {
    let numbers: Vec<u32> = shared
        .folders
        .iter()
        .flat_map(|folder| folder.files.keys().copied())
        .collect();
    let first = &shared.folders[0];
    let mut state = shared.lock();
    state.revision += 1;
    state.generation += 1;
    state.scene = Some(SceneInfo {
        name: first.name.clone(),
        path: first.shown.clone(),
        first_frame: numbers.iter().copied().min().unwrap_or(1),
        last_frame: numbers.iter().copied().max().unwrap_or(1),
        fps: first.fps.unwrap_or(24.0),
    });
    let first_key = state.frame_key(Source::Folder(0), *first.files.keys().next().unwrap_or(&1));
    state.prefetch.push_back(first_key);
}

/// Size and modification time of a file (None: missing); the scene file itself is compared by
/// content, because an edit can keep its size and land within the file system's time resolution.
type FileStamp = Option<(SystemTime, u64)>;

/// Watches the scene file and the files it references, and reloads the scene when they change.
/// A change is acted on once it has held for one poll, so a file caught half-written (an editor
/// that truncates, then writes) is not loaded as a scene of its own.
struct Watcher {
    scene_path: PathBuf,
    /// What was loaded last (successfully or not).
    loaded: Fingerprint,
    /// A change seen at the last poll, waiting to hold still.
    pending: Option<Fingerprint>,
    /// The files the last good scene referenced (besides the scene file).
    assets: Vec<PathBuf>,
    /// The scene path as the page shows it ([`shown_path`]).
    shown: String,
}

/// The scene file's content hash and the stamps of its assets.
#[derive(Clone, Debug, PartialEq)]
struct Fingerprint {
    scene: Option<blake3::Hash>,
    assets: Vec<FileStamp>,
}

fn stamp(path: &Path) -> FileStamp {
    let metadata = std::fs::metadata(path).ok()?;
    Some((metadata.modified().ok()?, metadata.len()))
}

impl Watcher {
    fn new(scene_path: PathBuf) -> Self {
        Watcher {
            loaded: Fingerprint {
                scene: None,
                assets: Vec::new(),
            },
            pending: None,
            assets: Vec::new(),
            shown: shown_path(&scene_path),
            scene_path,
        }
    }

    /// `text` (a load error, a notice) with the scene's folders as the page shows them: the scene
    /// path as given and the scene folder's absolute path are replaced by the shown ones.
    fn hide_folders(&self, text: &str) -> String {
        let mut text = text.replace(&self.scene_path.display().to_string(), &self.shown);
        let shown_dir = Path::new(&self.shown)
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .map_or_else(String::new, |p| format!("{}/", p.display()));
        let absolute = std::env::current_dir()
            .map(|cwd| cwd.join(&self.scene_path))
            .unwrap_or_else(|_| self.scene_path.clone());
        let mut folders: Vec<PathBuf> = [
            absolute.clone(),
            std::fs::canonicalize(&absolute).unwrap_or_default(),
        ]
        .iter()
        .filter_map(|p| p.parent().map(Path::to_path_buf))
        .filter(|p| p.is_absolute() && p.parent().is_some())
        .collect();
        folders.sort_by_key(|p| std::cmp::Reverse(p.as_os_str().len()));
        for folder in folders {
            text = text.replace(&format!("{}/", folder.display()), &shown_dir);
        }
        text
    }

    fn fingerprint(&self) -> Fingerprint {
        Fingerprint {
            scene: std::fs::read(&self.scene_path)
                .ok()
                .map(|bytes| blake3::hash(&bytes)),
            assets: self.assets.iter().map(|path| stamp(path)).collect(),
        }
    }

    /// Runs the watcher; a panic restarts it (and is shown), [`RESTARTS_IN_A_ROW`] in a row
    /// stop it (shown as dead: live reload is off).
    fn supervise(mut self, shared: &Shared, interval: Duration) {
        loop {
            match crate::panics::catch(|| self.run(shared, interval)) {
                Ok(()) => return,
                Err(message) => {
                    let mut state = shared.lock();
                    let restart = state.watcher.record_panic("file watcher", &message);
                    state.revision += 1;
                    drop(state);
                    if !restart {
                        return;
                    }
                }
            }
        }
    }

    fn run(&mut self, shared: &Shared, interval: Duration) {
        loop {
            std::thread::sleep(interval);
            if shared.lock().stopping {
                return;
            }
            let injected = &shared.watcher_panics_left;
            if injected
                .fetch_update(
                    std::sync::atomic::Ordering::SeqCst,
                    std::sync::atomic::Ordering::SeqCst,
                    |left| left.checked_sub(1),
                )
                .is_ok()
            {
                panic!("an injected file-watcher panic (Faults::watcher_panics)");
            }
            let now = self.fingerprint();
            if now == self.loaded {
                self.pending = None;
            } else if self.pending.as_ref() == Some(&now) {
                self.reload(shared);
            } else {
                self.pending = Some(now);
            }
            // A poll done: a later panic starts a new count.
            shared.lock().watcher.panics_in_a_row = 0;
        }
    }

    /// Loads the scene; on success hands the job to the worker as a new generation, on failure
    /// shows the problem and keeps the last good version.
    fn reload(&mut self, shared: &Shared) {
        let started = Instant::now();
        self.pending = None;
        let scene_before = self.fingerprint().scene;
        let loaded = RenderJob::prepare(&self.scene_path).and_then(|mut job| {
            // The frame cache keeps at least this many whole frames (see `PreviewServer::start`).
            job.frames_held = MIN_CACHED_FRAMES as u32;
            let out_dir = shared
                .out_dir
                .clone()
                .unwrap_or_else(|| PathBuf::from("output").join(job.scene_name()));
            job.use_checkpoints(&out_dir)?;
            Ok(job)
        });
        let mut state = shared.lock();
        let reloading = state.scene.is_some() || state.problem.is_some();
        state.revision += 1;
        match loaded {
            Ok(job) => {
                self.assets = job.referenced_files();
                let timeline = job.timeline();
                let timeline_first = timeline.first_frame;
                state.scene = Some(SceneInfo {
                    name: job.scene_name().to_string(),
                    path: self.shown.clone(),
                    first_frame: timeline.first_frame,
                    last_frame: timeline.last_frame,
                    fps: timeline.fps,
                });
                state.generation += 1;
                state.problem = None;
                state.notice = reloading.then(|| {
                    format!(
                        "{} changed on disk: reloaded at {} ({:.0} ms)",
                        self.shown,
                        clock_time(),
                        started.elapsed().as_secs_f64() * 1e3
                    )
                });
                state.incoming_job = Some(job);
                state.demand.clear();
                state.prefetch.clear();
                state.frames.clear();
                state.failed.clear();
                state.images.clear();
                // The first frame is rendered at once: the page asks for it first, and the
                // renderer's first frame (pipelines, textures) is the slowest.
                let first = state.frame_key(Source::Method(Method::default()), timeline_first);
                state.prefetch.push_back(first);
                let sources: Vec<Source> = state.strips.keys().copied().collect();
                state.strips.clear();
                for source in sources
                    .into_iter()
                    .chain([Source::Method(Method::default())])
                {
                    worker::want_strip(&mut state, source);
                }
            }
            Err(error) => {
                state.problem = Some(self.hide_folders(&error.to_string()));
                state.notice = state.scene.is_some().then(|| {
                    "the scene has an error: showing the last version that loaded".to_string()
                });
            }
        }
        drop(state);
        // The scene file as it was read (a later edit is seen at the next poll); asset stamps as
        // they are now.
        self.loaded = Fingerprint {
            scene: scene_before,
            ..self.fingerprint()
        };
        shared.wake.notify_all();
    }
}

/// The scene path as the page shows it: relative to the working folder, or only the file name when
/// the scene lies outside it. Never absolute: the page (and anything that reaches the API) learns
/// nothing about the folders above the one `snell preview` was started in.
fn shown_path(path: &Path) -> String {
    shown_path_from(path, std::env::current_dir().ok().as_deref())
}

fn shown_path_from(path: &Path, working: Option<&Path>) -> String {
    let file_name = || {
        path.file_name()
            .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned())
    };
    let Some(working) = working else {
        return file_name();
    };
    let absolute = working.join(path);
    let canonical = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    match canonical(&absolute).strip_prefix(canonical(working)) {
        // A path that cannot be resolved (missing) may still climb out through `..`.
        Ok(relative)
            if !relative.as_os_str().is_empty()
                && relative
                    .components()
                    .all(|c| matches!(c, std::path::Component::Normal(_))) =>
        {
            relative.display().to_string()
        }
        _ => file_name(),
    }
}

/// The time of day (UTC) as HH:MM:SS, for notices.
fn clock_time() -> String {
    let secs = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    format!(
        "{:02}:{:02}:{:02} UTC",
        secs / 3600 % 24,
        secs / 60 % 60,
        secs % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shown_scene_path_is_never_absolute() {
        let working = tempfile::tempdir().unwrap();
        let inside = working.path().join("scenes/pool.toml");
        std::fs::create_dir_all(inside.parent().unwrap()).unwrap();
        std::fs::write(&inside, "").unwrap();
        let cwd = Some(working.path());
        assert_eq!(shown_path_from(&inside, cwd), "scenes/pool.toml");
        assert_eq!(
            shown_path_from(Path::new("scenes/pool.toml"), cwd),
            "scenes/pool.toml"
        );
        assert_eq!(
            shown_path_from(Path::new("scenes/../scenes/pool.toml"), cwd),
            "scenes/pool.toml"
        );
        // Outside the working folder: the file name only.
        let elsewhere = tempfile::tempdir().unwrap();
        let outside = elsewhere.path().join("secret-project.toml");
        assert_eq!(shown_path_from(&outside, cwd), "secret-project.toml");
        assert_eq!(
            shown_path_from(Path::new("../x/secret.toml"), cwd),
            "secret.toml"
        );
        assert_eq!(shown_path_from(&outside, None), "secret-project.toml");
    }
}
