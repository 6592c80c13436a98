//! The preview's HTTP API, served in-process on a free port: frames are the frames `snell render`
//! makes, bad requests get a clear 4xx, concurrent requests each get their own frame, and a scene
//! edited on disk reloads (a broken edit is reported with file and line while the last good
//! version stays served). The server's own robustness: a render-worker panic fails its frame at
//! once and the worker restarts, a watcher panic restarts the watcher, a flood of idle
//! connections adds no threads, and `snell preview` stops at SIGINT even when its parent told it
//! to ignore SIGINT.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use snell::frame::RenderJob;
use snell::gpu::Renderer;
use snell::output::tonemap::tonemap_srgb8;
use snell::preview::client::{get, Response};
use snell::preview::{Faults, PreviewOptions, PreviewServer};

const WIDTH: u32 = 160;
const HEIGHT: u32 = 90;

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn start(scene_path: &Path, checkpoints: &Path) -> PreviewServer {
    start_with(scene_path, checkpoints, Faults::default())
}

fn start_with(scene_path: &Path, checkpoints: &Path, faults: Faults) -> PreviewServer {
    let mut options = PreviewOptions::new(scene_path);
    options.port = 0;
    options.width = WIDTH;
    options.height = HEIGHT;
    options.out_dir = Some(checkpoints.to_path_buf());
    options.watch_interval = Duration::from_millis(50);
    options.faults = faults;
    PreviewServer::start(options).expect("the preview starts")
}

fn fetch(server: &PreviewServer, path: &str) -> Response {
    get(server.url(), path).unwrap_or_else(|e| panic!("GET {path}: {e}"))
}

fn png(response: &Response) -> image::RgbaImage {
    assert_eq!(
        response.status,
        200,
        "{}",
        String::from_utf8_lossy(&response.body)
    );
    assert_eq!(response.header("content-type"), Some("image/png"));
    image::load_from_memory(&response.body)
        .expect("a PNG")
        .to_rgba8()
}

fn error_of(server: &PreviewServer, path: &str, status: u16) -> String {
    let response = fetch(server, path);
    assert_eq!(
        response.status,
        status,
        "GET {path}: {}",
        String::from_utf8_lossy(&response.body)
    );
    let message = response.json().unwrap()["error"]
        .as_str()
        .expect("an error message")
        .to_string();
    assert!(!message.is_empty());
    message
}

fn wait_until(what: &str, mut done: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while !done() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn frames_equal_the_renderers_and_bad_requests_are_4xx() {
    let temp = tempfile::tempdir().unwrap();
    let server = start(&scene("pool.toml"), temp.path());

    let state = fetch(&server, "/api/scene").json().unwrap();
    assert_eq!(state["scene"]["name"], "pool");
    // The path relative to the working folder (cargo runs tests in the package's), never absolute.
    assert_eq!(state["scene"]["path"], "scenes/pool.toml");
    assert_eq!(state["scene"]["first_frame"], 1);
    assert_eq!(state["scene"]["last_frame"], 48);
    assert_eq!(state["size"], serde_json::json!([WIDTH, HEIGHT]));
    assert!(state["problem"].is_null());
    let page = fetch(&server, "/");
    assert_eq!(page.status, 200);
    assert!(String::from_utf8_lossy(&page.body).contains("id=\"slider\""));

    // A frame is the library's render of that frame, tone-mapped, bit for bit.
    let response = fetch(&server, "/api/frame/17.png");
    assert_eq!(response.header("x-snell-frame"), Some("17"));
    let served = png(&response);
    assert_eq!(served.dimensions(), (WIDTH, HEIGHT));
    let job = RenderJob::prepare(&scene("pool.toml")).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    let (refracted, rendered) = job.render_frame(&mut renderer, 17, WIDTH, HEIGHT).unwrap();
    assert!(
        served == tonemap_srgb8(&rendered, 0.0),
        "frame 17 differs from the library's render"
    );

    // Asked again, it comes from the cache, identical.
    let again = fetch(&server, "/api/frame/17.png");
    assert_eq!(again.header("x-snell-cache"), Some("image"));
    assert_eq!(again.body, response.body);
    // Its counts are the refraction stage's.
    let counts = fetch(&server, "/api/frame/17.json").json().unwrap();
    assert_eq!(
        counts["counts"],
        serde_json::to_value(refracted.counts).unwrap()
    );

    // Exposure brightens.
    let brighter = png(&fetch(&server, "/api/frame/17.png?exposure=2"));
    let sum = |image: &image::RgbaImage| image.as_raw().iter().map(|&b| b as u64).sum::<u64>();
    assert!(sum(&brighter) > sum(&served));

    // Bad requests: a clear 4xx with a message.
    assert!(error_of(&server, "/api/frame/0.png", 404).contains("frames 1 to 48"));
    assert!(error_of(&server, "/api/frame/49.png", 404).contains("outside the timeline"));
    assert!(error_of(&server, "/api/frame/abc.png", 400).contains("not a frame number"));
    error_of(&server, "/api/frame/-3.png", 400);
    error_of(&server, "/api/frame/1.5.png", 400);
    error_of(&server, "/api/frame/99999999999.png", 400);
    error_of(&server, "/api/frame/3.gif", 404);
    assert!(error_of(&server, "/api/frame/3.png?method=no-such-method", 400).contains("equal-t"));
    error_of(&server, "/api/frame/3.png?exposure=bright", 400);
    error_of(&server, "/api/frame/3.png?exposure=1e9", 400);
    assert!(error_of(&server, "/api/frame/3.png?flags=wobble", 400).contains("convergence"));
    error_of(&server, "/api/nothing", 404);
    error_of(&server, "/api/strip?method=nope", 400);

    // Only GET is served.
    use std::io::{Read, Write};
    let authority = server
        .url()
        .trim_start_matches("http://")
        .trim_end_matches('/');
    let raw = |request: String| {
        let mut stream = std::net::TcpStream::connect(authority).unwrap();
        stream.write_all(request.as_bytes()).unwrap();
        let mut reply = String::new();
        stream.read_to_string(&mut reply).unwrap();
        reply
    };
    let reply = raw(format!(
        "POST /api/frame/1.png HTTP/1.1\r\nHost: {authority}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    ));
    assert!(reply.starts_with("HTTP/1.1 405"), "{reply}");
    // DNS rebinding: a request for another host name is refused before any route, the scene
    // included; loopback names on any port (an SSH tunnel's) are served.
    for (host, status) in [
        ("evil.example", "421"),
        ("evil.example:8765", "421"),
        ("localhost:1", "200"),
        ("[::1]", "200"),
    ] {
        let reply = raw(format!(
            "GET /api/scene HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
        ));
        assert!(
            reply.starts_with(&format!("HTTP/1.1 {status}")),
            "Host: {host}: {reply}"
        );
    }
    let reply = raw("GET /api/scene HTTP/1.0\r\nConnection: close\r\n\r\n".into());
    assert!(
        reply.starts_with("HTTP/1.1 421") || reply.starts_with("HTTP/1.0 421"),
        "no Host: {reply}"
    );
    server.stop();
}

#[test]
fn concurrent_requests_each_get_their_frame() {
    let temp = tempfile::tempdir().unwrap();
    let server = start(&scene("pool.toml"), temp.path());
    let url = server.url().to_string();
    // Eight different frames and four requests for one frame, all at once.
    let frames: Vec<u32> = (0..8).map(|i| 3 + 5 * i).chain([40, 40, 40, 40]).collect();
    let responses: Vec<(u32, Response)> = std::thread::scope(|scope| {
        let handles: Vec<_> = frames
            .iter()
            .map(|&frame| {
                let url = url.clone();
                scope.spawn(move || {
                    (
                        frame,
                        get(&url, &format!("/api/frame/{frame}.png")).unwrap(),
                    )
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut frame_40 = None;
    for (frame, response) in &responses {
        assert_eq!(response.status, 200, "frame {frame}");
        assert_eq!(
            response.header("x-snell-frame"),
            Some(frame.to_string().as_str())
        );
        assert_eq!(png(response).dimensions(), (WIDTH, HEIGHT));
        if *frame == 40 {
            let body = frame_40.get_or_insert_with(|| response.body.clone());
            assert_eq!(
                body, &response.body,
                "one frame asked for at once is one image"
            );
        }
    }
    let distinct: std::collections::HashSet<&Vec<u8>> =
        responses.iter().map(|(_, r)| &r.body).collect();
    assert_eq!(distinct.len(), 9, "nine different frames were asked for");

    // Every frame answered alone afterwards is the same as under load.
    for (frame, response) in responses.iter().take(3) {
        let alone = fetch(&server, &format!("/api/frame/{frame}.png"));
        assert_eq!(alone.body, response.body, "frame {frame}");
    }

    // The strip has one entry per frame and agrees with the frames' own counts.
    wait_until("the strip", || {
        fetch(&server, "/api/strip").json().unwrap()["done"] == true
    });
    let strip = fetch(&server, "/api/strip").json().unwrap();
    let entries = strip["frames"].as_array().unwrap();
    assert_eq!(entries.len(), 48);
    for frame in [1u32, 5, 40] {
        let counts = fetch(&server, &format!("/api/frame/{frame}.json"))
            .json()
            .unwrap();
        assert_eq!(entries[frame as usize - 1]["frame"], frame);
        assert_eq!(
            entries[frame as usize - 1]["counts"],
            counts["counts"],
            "frame {frame}"
        );
    }
    server.stop();
}

/// Overlays mark flagged pixels, and only those (the fox's wake has flagged triangles in view;
/// pool.toml has none on screen).
#[test]
fn overlays_mark_flagged_pixels_only() {
    let temp = tempfile::tempdir().unwrap();
    let server = start(&scene("fox_wading.toml"), temp.path());
    let plain = png(&fetch(&server, "/api/frame/12.png"));
    let overlaid = png(&fetch(
        &server,
        "/api/frame/12.png?flags=convergence%2Cboundary,popping,extrapolated",
    ));
    let job = RenderJob::prepare(&scene("fox_wading.toml")).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    let (_, rendered) = job.render_frame(&mut renderer, 12, WIDTH, HEIGHT).unwrap();
    assert!(
        plain == tonemap_srgb8(&rendered, 0.0),
        "fox frame 12 differs from the library's render"
    );
    let flagged = rendered.flags.iter().filter(|&&bits| bits != 0).count();
    let mut changed = 0;
    for ((before, after), &bits) in plain.pixels().zip(overlaid.pixels()).zip(&rendered.flags) {
        if before != after {
            assert_ne!(bits, 0, "an unflagged pixel changed under the overlay");
            changed += 1;
        }
    }
    assert!(flagged > 0, "fox_wading frame 12 has flagged pixels");
    assert!(
        changed * 10 >= flagged * 9,
        "{changed} of {flagged} flagged pixels marked"
    );
    // One flag alone marks a subset.
    let boundary_only = png(&fetch(&server, "/api/frame/12.png?flags=boundary"));
    let marked = plain
        .pixels()
        .zip(boundary_only.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(marked <= changed);
    server.stop();
}

#[test]
fn an_edited_scene_reloads_and_a_broken_one_is_reported() {
    let temp = tempfile::tempdir().unwrap();
    let scene_path = temp.path().join("tiny.toml");
    let original = std::fs::read_to_string(scene("tiny.toml")).unwrap();
    save(&scene_path, &original);
    let server = start(&scene_path, &temp.path().join("out"));
    let first = fetch(&server, "/api/scene").json().unwrap();
    let generation = first["generation"].as_u64().unwrap();
    let before = fetch(&server, "/api/frame/2.png").body;

    save(&scene_path, format!("bogus_key = 1\n{original}"));
    wait_until("the problem", || {
        !fetch(&server, "/api/scene").json().unwrap()["problem"].is_null()
    });
    let broken = fetch(&server, "/api/scene").json().unwrap();
    let problem = broken["problem"].as_str().unwrap();
    assert!(
        problem.contains("tiny.toml:1:1") && problem.contains("bogus_key"),
        "{problem}"
    );
    assert_eq!(
        broken["generation"].as_u64(),
        Some(generation),
        "the last good version stays"
    );
    assert_eq!(fetch(&server, "/api/frame/2.png").body, before);

    // The fix: a different camera, so the frame must change.
    let edited = original.replacen("fov_deg", "fov_deg = 30.0\n# was", 1);
    assert_ne!(edited, original, "tiny.toml sets the camera's fov_deg");
    save(&scene_path, &edited);
    wait_until("the reload", || {
        let state = fetch(&server, "/api/scene").json().unwrap();
        state["problem"].is_null() && state["generation"].as_u64() == Some(generation + 1)
    });
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert!(state["notice"].as_str().unwrap().contains("reloaded"));
    let after = fetch(&server, "/api/frame/2.png");
    assert_eq!(
        after.status,
        200,
        "{}",
        String::from_utf8_lossy(&after.body)
    );
    assert_eq!(
        after.header("x-snell-generation"),
        Some((generation + 1).to_string().as_str())
    );
    assert_ne!(
        after.body, before,
        "the reloaded scene renders its new camera"
    );
    server.stop();
}

#[test]
fn a_scene_that_never_loaded_is_reported_not_fatal() {
    let temp = tempfile::tempdir().unwrap();
    let scene_path = temp.path().join("broken.toml");
    save(&scene_path, "[timeline]\nfps = \"fast\"\n");
    let server = start(&scene_path, temp.path());
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert!(state["scene"].is_null());
    assert!(
        state["problem"].as_str().unwrap().contains("broken.toml:2"),
        "{state}"
    );
    // Outside the working folder only the file name is shown, in the problem too.
    let folder = temp.path().display().to_string();
    assert!(!state.to_string().contains(&folder), "{state}");
    assert!(error_of(&server, "/api/frame/1.png", 503).contains("did not load"));
    server.stop();
}

/// Saves a scene as editors do: a temporary file renamed over the old one.
fn save(path: &Path, contents: impl AsRef<[u8]>) {
    let temporary = path.with_extension("toml.saving");
    std::fs::write(&temporary, contents).unwrap();
    std::fs::rename(&temporary, path).unwrap();
}

#[test]
fn a_render_worker_panic_fails_its_frame_at_once_and_the_worker_restarts() {
    let temp = tempfile::tempdir().unwrap();
    let faults = Faults {
        worker_panic_frame: Some(30),
        ..Faults::default()
    };
    let server = start_with(&scene("pool.toml"), temp.path(), faults);
    // The renderer is up once a frame is served. Then wait until it is idle (no prefetch or
    // timeline strip in flight): a render in progress is not interrupted, so otherwise the time
    // below would measure how long that render takes on a loaded machine (1.15 s once in CI with
    // the other tests running), not how fast a panic becomes a 500.
    png(&fetch(&server, "/api/frame/1.png"));
    wait_until("the render worker is idle", || {
        let scene = fetch(&server, "/api/scene").json().unwrap();
        scene["worker_busy"] == false && scene["strips_done"] == true
    });
    let asked = Instant::now();
    let message = error_of(&server, "/api/frame/30.png", 500);
    let waited = asked.elapsed();
    assert!(
        waited < Duration::from_secs(1),
        "the 500 came after {waited:?}"
    );
    assert!(
        message.contains("panicked on frame 30") && message.contains("restarted"),
        "{message}"
    );
    // Asked again, at once again (the failure is kept, the frame is not retried).
    let asked = Instant::now();
    error_of(&server, "/api/frame/30.png", 500);
    assert!(asked.elapsed() < Duration::from_secs(1));
    // The restarted worker renders other frames.
    png(&fetch(&server, "/api/frame/40.png"));
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert_eq!(state["threads"]["render_worker"]["restarts"], 1, "{state}");
    assert!(state["threads"]["render_worker"]["dead"].is_null());
    let shown = state["thread_problem"].as_str().unwrap();
    assert!(shown.contains("render worker panicked"), "{shown}");
    assert_eq!(fetch(&server, "/api/health").status, 200);
    server.stop();
}

/// A render worker that panics at every task is restarted twice and given up at the third panic
/// in a row: the health check is then 503, and every frame request fails at once (a 5xx within a
/// second) with the reason, naming how often it panicked.
#[test]
fn a_render_worker_that_keeps_panicking_is_given_up_and_frames_fail_at_once() {
    let temp = tempfile::tempdir().unwrap();
    let faults = Faults {
        worker_panics_always: true,
        ..Faults::default()
    };
    let server = start_with(&scene("pool.toml"), temp.path(), faults);
    error_of(&server, "/api/frame/1.png", 500);
    wait_until("the dead render worker", || {
        fetch(&server, "/api/health").status == 503
    });
    let health = fetch(&server, "/api/health").json().unwrap();
    assert_eq!(
        health["threads"]["render_worker"]["restarts"], 2,
        "{health}"
    );
    let dead = health["threads"]["render_worker"]["dead"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    assert!(
        dead.contains("render worker panicked 3 times in a row") && dead.contains("injected"),
        "{health}"
    );
    // A frame far from those the three panics were on: it fails at once with the reason.
    let asked = Instant::now();
    let message = error_of(&server, "/api/frame/40.png", 500);
    assert!(
        asked.elapsed() < Duration::from_secs(1),
        "the 5xx came after {:?}",
        asked.elapsed()
    );
    assert!(message.contains("3 times in a row"), "{message}");
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert!(
        state["thread_problem"]
            .as_str()
            .unwrap_or_default()
            .contains("render worker panicked 3 times in a row"),
        "{state}"
    );
    server.stop();
}

#[test]
fn a_watcher_panic_restarts_it_and_repeated_ones_are_reported_with_a_5xx() {
    let temp = tempfile::tempdir().unwrap();
    let scene_path = temp.path().join("tiny.toml");
    let original = std::fs::read_to_string(scene("tiny.toml")).unwrap();
    save(&scene_path, &original);
    let faults = Faults {
        watcher_panics: 1,
        ..Faults::default()
    };
    let server = start_with(&scene_path, &temp.path().join("out"), faults);
    wait_until("the watcher's restart", || {
        fetch(&server, "/api/scene").json().unwrap()["threads"]["file_watcher"]["restarts"] == 1
    });
    let generation = fetch(&server, "/api/scene").json().unwrap()["generation"]
        .as_u64()
        .unwrap();
    // Live reload still works.
    save(
        &scene_path,
        original.replacen("fov_deg", "fov_deg = 30.0\n# was", 1),
    );
    wait_until("the reload", || {
        fetch(&server, "/api/scene").json().unwrap()["generation"].as_u64() == Some(generation + 1)
    });
    assert_eq!(fetch(&server, "/api/health").status, 200);
    server.stop();

    // A watcher that keeps panicking is given up: the API says so with a 503, and the page's
    // state carries the reason.
    let faults = Faults {
        watcher_panics: 100,
        ..Faults::default()
    };
    let server = start_with(&scene_path, &temp.path().join("out"), faults);
    wait_until("the dead watcher", || {
        fetch(&server, "/api/health").status == 503
    });
    let health = fetch(&server, "/api/health").json().unwrap();
    assert!(
        health["threads"]["file_watcher"]["dead"]
            .as_str()
            .unwrap()
            .contains("3 times in a row"),
        "{health}"
    );
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert!(
        state["thread_problem"]
            .as_str()
            .unwrap()
            .contains("edits of the scene are no longer seen"),
        "{state}"
    );
    server.stop();
}

/// `snell preview` as a process, with SIGINT ignored as a shell does for a background job.
struct Preview {
    child: std::process::Child,
    url: String,
}

impl Drop for Preview {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Preview {
    fn spawn(scene_path: &Path, size: &str, out: &Path) -> Preview {
        use std::io::BufRead;
        use std::os::unix::process::CommandExt;
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_snell"));
        command
            .arg("preview")
            .arg(scene_path)
            .args(["--port", "0", "--size", size, "--out"])
            .arg(out)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null());
        // SAFETY: signal(2) is async-signal-safe, as pre_exec requires.
        unsafe {
            command.pre_exec(|| {
                libc::signal(libc::SIGINT, libc::SIG_IGN);
                Ok(())
            });
        }
        let mut child = command.spawn().expect("snell preview starts");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        std::io::BufReader::new(stdout)
            .read_line(&mut line)
            .unwrap();
        let url = line
            .trim()
            .rsplit_once(" on ")
            .map(|(_, url)| url.to_string())
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
        Preview { child, url }
    }

    fn pid(&self) -> u32 {
        self.child.id()
    }

    fn threads(&self) -> usize {
        std::fs::read_dir(format!("/proc/{}/task", self.pid()))
            .unwrap()
            .count()
    }

    fn open_files(&self) -> usize {
        std::fs::read_dir(format!("/proc/{}/fd", self.pid()))
            .unwrap()
            .count()
    }
}

#[test]
fn a_flood_of_idle_connections_adds_no_threads_and_requests_are_still_served() {
    use std::io::Read;
    let temp = tempfile::tempdir().unwrap();
    let preview = Preview::spawn(&scene("tiny.toml"), "160x90", temp.path());
    let url = preview.url.clone();
    png(&get(&url, "/api/frame/2.png").unwrap());
    wait_until("the strip", || {
        get(&url, "/api/strip").unwrap().json().unwrap()["done"] == true
    });
    let (threads_before, files_before) = (preview.threads(), preview.open_files());
    let authority = url.trim_start_matches("http://").trim_end_matches('/');
    // 300 connections that send nothing, and 20 that send half a request head.
    let mut idle: Vec<std::net::TcpStream> = (0..300)
        .map(|_| std::net::TcpStream::connect(authority).unwrap())
        .collect();
    for stream in idle.iter_mut().take(20) {
        use std::io::Write;
        stream.write_all(b"GET /api/scene HTTP/1.1\r\nHo").unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    let (threads_during, files_during) = (preview.threads(), preview.open_files());
    let asked = Instant::now();
    let scene = get(&url, "/api/scene").unwrap();
    assert_eq!(scene.status, 200);
    png(&get(&url, "/api/frame/3.png").unwrap());
    let served_in = asked.elapsed();
    eprintln!(
        "threads {threads_before} -> {threads_during}, open files {files_before} -> {files_during}, \
         2 requests served in {served_in:?} beside 300 idle connections"
    );
    assert!(
        threads_during <= threads_before,
        "300 idle connections made threads: {threads_before} -> {threads_during}"
    );
    // At most 128 connections stay open; the ones idle longest were closed.
    assert!(
        files_during <= files_before + 128,
        "open files {files_before} -> {files_during}"
    );
    let mut closed = 0;
    for stream in &mut idle {
        stream
            .set_read_timeout(Some(Duration::from_millis(5)))
            .unwrap();
        match stream.read(&mut [0u8; 16]) {
            Ok(0) => closed += 1,
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => closed += 1,
            _ => {}
        }
    }
    assert!(
        closed >= 300 - 128,
        "{closed} of 300 idle connections closed"
    );
}

#[test]
fn sigint_stops_the_preview_even_when_the_parent_ignores_it() {
    let temp = tempfile::tempdir().unwrap();
    for busy in [false, true] {
        let mut preview = Preview::spawn(&scene("pool.toml"), "640x360", temp.path());
        if busy {
            // A frame rendering when the signal comes.
            let url = preview.url.clone();
            std::thread::spawn(move || get(&url, "/api/frame/30.png"));
            std::thread::sleep(Duration::from_millis(100));
        }
        let sent = Instant::now();
        // SAFETY: kill(2) on our own child's pid.
        assert_eq!(unsafe { libc::kill(preview.pid() as i32, libc::SIGINT) }, 0);
        let status = loop {
            if let Some(status) = preview.child.try_wait().unwrap() {
                break status;
            }
            assert!(
                sent.elapsed() < Duration::from_secs(2),
                "snell preview (busy: {busy}) still runs 2 s after SIGINT"
            );
            std::thread::sleep(Duration::from_millis(10));
        };
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(
            status.code(),
            Some(130),
            "busy: {busy}; killed by signal {:?}",
            status.signal()
        );
    }
}

/// A scene path that is not a regular file is refused before the server starts, with exit 2 and
/// the reason, as `snell render` refuses it: a device that never ends, a FIFO with no writer
/// (which would block a reader), and a folder. Serving an error page for these would leave a
/// server up for a scene that can never load.
#[test]
fn a_scene_that_is_not_a_regular_file_is_refused_at_start() {
    let folder = tempfile::tempdir().unwrap();
    let fifo = folder.path().join("scene.toml");
    let c_path = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo(3) has no other preconditions.
    assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0, "mkfifo");
    for (path, kind) in [
        (Path::new("/dev/zero"), "character device"),
        (fifo.as_path(), "FIFO"),
        (folder.path(), "folder"),
    ] {
        let started = Instant::now();
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
            .arg("preview")
            .arg(path)
            .args(["--port", "0", "--size", "160x90"])
            .stdin(std::process::Stdio::null())
            .output()
            .expect("snell runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(2),
            "{}: {stderr}",
            path.display()
        );
        assert!(
            stderr.contains(&path.display().to_string()) && stderr.contains("regular"),
            "{kind}: the error names the path and what is wanted: {stderr}"
        );
        assert!(
            output.stdout.is_empty(),
            "{kind}: no server address printed: {:?}",
            String::from_utf8_lossy(&output.stdout)
        );
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "{kind}: refused at once"
        );
    }
}

/// The inspector's API: every channel at a pixel as the frame holds it, the object's name, its
/// flags, and the position error against the ray-traced reference once that is rendered.
#[test]
fn pixels_layers_and_differences_are_served() {
    let temp = tempfile::tempdir().unwrap();
    let server = start(&scene("pool.toml"), temp.path());
    let job = RenderJob::prepare(&scene("pool.toml")).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    let (_, rendered) = job.render_frame(&mut renderer, 9, WIDTH, HEIGHT).unwrap();
    let names = job.object_names();

    // A pixel that sees an object through the water, near the centre.
    let index = (0..rendered.pixel_count())
        .filter(|&i| rendered.water_matte[i] > 0.5 && rendered.object[i] != 0)
        .min_by_key(|&i| {
            let (x, y) = ((i as u32 % WIDTH) as i64, (i as u32 / WIDTH) as i64);
            (x - WIDTH as i64 / 2).abs() + (y - HEIGHT as i64 / 2).abs()
        })
        .expect("a pixel seen through water");
    let (x, y) = (index as u32 % WIDTH, index as u32 / WIDTH);
    let pixel = fetch(&server, &format!("/api/pixel/9?x={x}&y={y}"))
        .json()
        .unwrap();
    let value = |name: &str| -> f32 {
        let found = pixel["channels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|pair| pair[0] == name)
            .unwrap_or_else(|| panic!("no channel {name} in {pixel}"));
        found[1].as_str().unwrap().parse().unwrap()
    };
    let beauty = rendered.beauty_rgba[index];
    for (c, name) in ["R", "G", "B", "A"].into_iter().enumerate() {
        assert_eq!(value(name).to_bits(), beauty[c].to_bits(), "{name}");
    }
    assert_eq!(value("Z").to_bits(), rendered.depth_m[index].to_bits());
    for (c, name) in ["P.X", "P.Y", "P.Z"].into_iter().enumerate() {
        assert_eq!(
            value(name).to_bits(),
            rendered.position[index][c].to_bits(),
            "{name}"
        );
    }
    assert_eq!(value("IndexOB.X"), rendered.object[index] as f32);
    assert_eq!(value("WaterMatte.X"), 1.0);
    assert_eq!(
        pixel["object"]["name"],
        names[rendered.object[index] as usize - 1]
    );
    assert_eq!(pixel["reference"]["status"], "not rendered");

    // Once the reference frame is rendered, the error is the distance between the two P's.
    assert_eq!(
        fetch(&server, "/api/frame/9.json?method=raytrace").status,
        200
    );
    let pixel = fetch(&server, &format!("/api/pixel/9?x={x}&y={y}"))
        .json()
        .unwrap();
    assert_eq!(pixel["reference"]["status"], "rendered", "{pixel}");
    let reference = fetch(
        &server,
        &format!("/api/pixel/9?method=raytrace&x={x}&y={y}"),
    )
    .json()
    .unwrap();
    assert_eq!(reference["reference"]["status"], "this is the reference");
    let p = |pixel: &serde_json::Value, name: &str| -> f64 {
        let pairs = pixel["channels"].as_array().unwrap();
        let pair = pairs.iter().find(|pair| pair[0] == name).unwrap();
        pair[1].as_str().unwrap().parse::<f32>().unwrap() as f64
    };
    let distance = ["P.X", "P.Y", "P.Z"]
        .iter()
        .map(|c| (p(&pixel, c) - p(&reference, c)).powi(2))
        .sum::<f64>()
        .sqrt();
    let error: f64 = pixel["reference"]["error_m"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        (error - distance).abs() <= 1e-6 * distance.max(1e-3),
        "{error} vs {distance}"
    );

    // Every layer of the map is an image of the frame's size, with a legend.
    let scene_state = fetch(&server, "/api/scene").json().unwrap();
    let layers: Vec<String> = scene_state["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["name"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(layers.len(), snell::output::exr::channels::Layer::ALL.len());
    let mut distinct = std::collections::BTreeSet::new();
    for layer in &layers {
        let response = fetch(&server, &format!("/api/frame/9.png?layer={layer}"));
        let image = png(&response);
        assert_eq!(image.dimensions(), (WIDTH, HEIGHT), "{layer}");
        assert!(
            !response.header("x-snell-legend").unwrap_or("").is_empty(),
            "{layer}"
        );
        distinct.insert(image.into_raw());
    }
    assert!(
        distinct.len() >= layers.len() - 5,
        "layers drawn alike: {} distinct of {}",
        distinct.len(),
        layers.len()
    );
    let same = png(&fetch(
        &server,
        "/api/frame/9.png?method=equal-t&against=equal-t",
    ));
    assert!(
        same.pixels().all(|p| p.0[..3] == [0, 0, 0]),
        "a frame against itself is black"
    );

    // Bad requests.
    assert!(error_of(&server, &format!("/api/pixel/9?x={WIDTH}&y=0"), 400).contains("0 to 159"));
    error_of(&server, "/api/pixel/9?x=1", 400);
    error_of(&server, "/api/pixel/99?x=1&y=1", 404);
    assert!(error_of(&server, "/api/frame/9.png?layer=Nope", 400).contains("IndexOB"));
    assert!(error_of(&server, "/api/frame/9.png?against=nope", 400).contains("against"));
    server.stop();

    // The difference of two methods: black where they agree, and not all black. On tiny.toml:
    // thesis-plane's refraction enumerates every image over every membrane facet, 53 s for one
    // pool.toml frame on 2 cores (twice over in the preview, which refracts the frame before for
    // popping too), so the request outlived the 120 s wait; a tiny.toml frame refracts in 0.05 s.
    let tiny = start(&scene("tiny.toml"), &temp.path().join("tiny"));
    let difference = png(&fetch(&tiny, "/api/frame/2.png?against=thesis-plane"));
    assert!(
        difference.pixels().any(|p| p.0[0] > 0),
        "equal-t and thesis-plane differ somewhere"
    );
    let same = png(&fetch(
        &tiny,
        "/api/frame/2.png?method=thesis-plane&against=thesis-plane",
    ));
    assert!(
        same.pixels().all(|p| p.0[..3] == [0, 0, 0]),
        "a frame against itself is black"
    );
    tiny.stop();
}

/// `--frames-dir`: frames are the files' (tone-mapped beauty, every channel's value), each folder
/// is a source, a frame a folder lacks is named, and an empty folder is refused at start.
#[test]
fn folders_of_rendered_frames_are_served() {
    let temp = tempfile::tempdir().unwrap();
    let renders = temp.path().join("renders");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .arg("render")
        .arg(scene("pool.toml"))
        .args(["--frames", "2-4", "--size", "160x90", "--half", "--out"])
        .arg(&renders)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let fewer = temp.path().join("fewer");
    std::fs::create_dir(&fewer).unwrap();
    std::fs::copy(renders.join("pool.0003.exr"), fewer.join("pool.0003.exr")).unwrap();
    let mut options = PreviewOptions::new(Path::new(""));
    options.port = 0;
    options.frames_dirs = vec![renders.clone(), fewer.clone()];
    let server = PreviewServer::start(options).expect("the preview starts");
    let state = fetch(&server, "/api/scene").json().unwrap();
    assert_eq!(state["mode"], "frames");
    assert_eq!(state["scene"]["first_frame"], 2);
    assert_eq!(state["scene"]["last_frame"], 4);
    assert_eq!(state["size"], serde_json::json!([160, 90]));
    let methods: Vec<&str> = state["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(methods, ["renders", "fewer"]);
    assert!(state["reference"].is_null());

    let exr = renders.join("pool.0003.exr");
    let (frame, _) = snell::output::exr::read_frame_exr(&exr).unwrap();
    assert!(png(&fetch(&server, "/api/frame/3.png")) == tonemap_srgb8(&frame, 0.0));
    let file = snell::output::exr::read_channels(&exr).unwrap();
    let (x, y) = (80, 50);
    let pixel = fetch(&server, &format!("/api/pixel/3?x={x}&y={y}"))
        .json()
        .unwrap();
    let channels = pixel["channels"].as_array().unwrap();
    assert_eq!(channels.len(), file.channels.len(), "{pixel}");
    for pair in channels {
        let name = pair[0].as_str().unwrap();
        let served: f32 = pair[1].as_str().unwrap().parse().unwrap();
        let stored = file
            .get(name)
            .unwrap_or_else(|| panic!("{name} is not in the file"))[y * 160 + x];
        assert_eq!(served.to_bits(), stored.to_bits(), "{name}");
    }
    assert_eq!(
        file.types["R"], "f16",
        "--half: the values checked are the half beauty's"
    );
    assert!(error_of(&server, "/api/frame/2.png?method=fewer", 422).contains("holds no frame 2"));
    let strip = fetch(&server, "/api/strip?method=fewer").json().unwrap();
    assert_eq!(strip["available"], false);
    server.stop();

    let empty = temp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(["preview", "--port", "0", "--frames-dir"])
        .arg(&empty)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("--frames-dir") && stderr.contains("no EXR frames"),
        "{stderr}"
    );
}
