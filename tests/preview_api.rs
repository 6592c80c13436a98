//! The preview's HTTP API, served in-process on a free port: frames are the frames `snell render`
//! makes, bad requests get a clear 4xx, concurrent requests each get their own frame, and a scene
//! edited on disk reloads (a broken edit is reported with file and line while the last good
//! version stays served).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use snell::frame::RenderJob;
use snell::gpu::Renderer;
use snell::output::tonemap::tonemap_srgb8;
use snell::preview::client::{get, Response};
use snell::preview::{PreviewOptions, PreviewServer};

const WIDTH: u32 = 160;
const HEIGHT: u32 = 90;

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
}

fn start(scene_path: &Path, checkpoints: &Path) -> PreviewServer {
    let mut options = PreviewOptions::new(scene_path);
    options.port = 0;
    options.width = WIDTH;
    options.height = HEIGHT;
    options.out_dir = Some(checkpoints.to_path_buf());
    options.watch_interval = Duration::from_millis(50);
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
    assert!(error_of(&server, "/api/frame/1.png", 503).contains("did not load"));
    server.stop();
}

/// Saves a scene as editors do: a temporary file renamed over the old one.
fn save(path: &Path, contents: impl AsRef<[u8]>) {
    let temporary = path.with_extension("toml.saving");
    std::fs::write(&temporary, contents).unwrap();
    std::fs::rename(&temporary, path).unwrap();
}
