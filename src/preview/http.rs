//! The preview's HTTP side: routes requests (see the module docs of [`super`]), waits for frames
//! from the worker, tone-maps, overlays flag masks and encodes PNGs, and answers every bad
//! request with a 4xx status and a message saying what to ask instead.

use std::io::Cursor;
use std::sync::Arc;
use std::time::{Duration, Instant};

use image::RgbaImage;
use serde_json::json;

use super::source::Source;
use super::{layers, server, worker, CachedFrame, FrameKey, ImageKey, Shared, State};
use crate::draw::flag_bits;
use crate::output::exr::channels::Layer;

/// The flags a page can overlay: name, bit, overlay colour (sRGB bytes).
pub(super) const OVERLAYS: [(&str, u32, [u8; 3]); 4] = [
    ("convergence", flag_bits::CONVERGENCE, [255, 0, 255]),
    ("boundary", flag_bits::BOUNDARY, [255, 220, 0]),
    ("popping", flag_bits::POPPING, [255, 40, 40]),
    ("extrapolated", flag_bits::EXTRAPOLATED, [0, 230, 255]),
];

/// How long a request waits for its frame before giving up (a frame takes well under a second;
/// this only guards against a stuck GPU).
const FRAME_WAIT: Duration = Duration::from_secs(120);

struct Reply {
    status: u16,
    content_type: &'static str,
    body: Vec<u8>,
    headers: Vec<(&'static str, String)>,
}

impl Reply {
    fn json(status: u16, value: serde_json::Value) -> Reply {
        Reply {
            status,
            content_type: "application/json",
            body: serde_json::to_vec(&value).expect("JSON values serialise"),
            headers: Vec::new(),
        }
    }

    fn error(status: u16, message: impl Into<String>) -> Reply {
        Reply::json(status, json!({ "error": message.into() }))
    }
}

/// Answers one request: refuses other hosts and methods, routes the rest.
pub(super) fn handle(shared: &Shared, request: &server::Request) -> server::Response {
    let started = Instant::now();
    let host = request.host.as_deref();
    let reply = if !host.is_some_and(is_loopback_host) {
        // DNS rebinding: a page of evil.example resolving to 127.0.0.1 would read frames and
        // the scene. Only loopback names are served (any port, so SSH tunnels keep working).
        Reply::error(
            421,
            format!(
                "the preview answers only requests for 127.0.0.1, localhost or [::1] (Host: {})",
                host.unwrap_or("missing")
            ),
        )
    } else if request.method == "GET" {
        route(shared, &request.target)
    } else {
        Reply::error(405, "the preview only answers GET requests")
    };
    let mut headers = vec![
        ("Content-Type", reply.content_type.to_string()),
        ("Cache-Control", "no-store".to_string()),
        (
            "X-Snell-Millis",
            format!("{:.2}", started.elapsed().as_secs_f64() * 1e3),
        ),
    ];
    headers.extend(reply.headers);
    server::Response {
        status: reply.status,
        headers,
        body: reply.body,
    }
}

/// Whether a `Host` header names this machine's loopback: `127.0.0.1`, `localhost` or `[::1]`,
/// with or without a port.
fn is_loopback_host(host: &str) -> bool {
    let host = host.trim();
    let name = if let Some(rest) = host.strip_prefix('[') {
        match rest.split_once(']') {
            Some((inside, port)) if port.is_empty() || port.starts_with(':') => {
                return inside == "::1" && port_ok(port);
            }
            _ => return false,
        }
    } else {
        match host.split_once(':') {
            Some((name, port)) => {
                if !port_ok(&format!(":{port}")) {
                    return false;
                }
                name
            }
            None => host,
        }
    };
    name == "127.0.0.1" || name.eq_ignore_ascii_case("localhost")
}

/// Empty, or `:` and a port number.
fn port_ok(port: &str) -> bool {
    port.is_empty()
        || port
            .strip_prefix(':')
            .is_some_and(|p| !p.is_empty() && p.parse::<u16>().is_ok())
}

fn route(shared: &Shared, url: &str) -> Reply {
    let (path, query) = url.split_once('?').unwrap_or((url, ""));
    let params = Query::parse(query);
    match path {
        "/" | "/index.html" => Reply {
            status: 200,
            content_type: "text/html; charset=utf-8",
            body: super::page::PAGE.as_bytes().to_vec(),
            headers: Vec::new(),
        },
        "/api/scene" => scene(shared),
        "/api/health" => health(shared),
        "/api/strip" => match params.source(shared, "method") {
            Ok(source) => strip(shared, source),
            Err(reply) => reply,
        },
        _ => match (path.strip_prefix("/api/frame/"), path.strip_prefix("/api/pixel/")) {
            (Some(rest), _) => frame(shared, rest, &params),
            (_, Some(rest)) => pixel(shared, rest, &params),
            _ => Reply::error(
                404,
                format!("no such page: {path}; the preview serves /, /api/scene, /api/health, /api/strip, /api/frame/<N>.png, /api/frame/<N>.json and /api/pixel/<N>?x=&y="),
            ),
        },
    }
}

fn scene(shared: &Shared) -> Reply {
    let state = shared.lock();
    let methods: Vec<_> = shared
        .sources()
        .into_iter()
        .map(|(_, name, description)| json!({ "name": name, "description": description }))
        .collect();
    let name_of = |source: Source| {
        shared
            .sources()
            .into_iter()
            .find(|(s, _, _)| *s == source)
            .map(|(_, name, _)| name)
    };
    let layers: Vec<_> = Layer::ALL
        .iter()
        .map(|&l| json!({ "name": l.name(), "description": layers::describe(l) }))
        .collect();
    Reply::json(
        200,
        json!({
            "revision": state.revision,
            "generation": state.generation,
            "scene": state.scene,
            "size": [shared.width, shared.height],
            "methods": methods,
            "default_method": name_of(shared.default_source()),
            "mode": if shared.folders.is_empty() { "render" } else { "frames" },
            "reference": shared.reference_source().and_then(name_of),
            "layers": layers,
            "flags": OVERLAYS.iter().map(|(name, _, rgb)| json!({
                "name": name,
                "color": format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2]),
            })).collect::<Vec<_>>(),
            "cached_frames": state.frames.len(),
            "problem": state.problem,
            "notice": state.notice,
            "worker_busy": state.worker_busy
                || !state.demand.is_empty()
                || !state.prefetch.is_empty(),
            "strips_done": state.strips.values().all(|s| s.counts.iter().all(Option::is_some)),
            "threads": threads(&state),
            "thread_problem": thread_problem(&state),
        }),
    )
}

fn threads(state: &State) -> serde_json::Value {
    json!({ "render_worker": state.worker, "file_watcher": state.watcher })
}

/// What went wrong with the render worker or the file watcher, for the page (None: nothing).
fn thread_problem(state: &State) -> Option<String> {
    let lines: Vec<String> = [
        state.worker.summary("render worker"),
        state.watcher.summary("file watcher").map(|text| {
            if state.watcher.dead.is_some() {
                format!("{text}: edits of the scene are no longer seen; restart snell preview")
            } else {
                text
            }
        }),
    ]
    .into_iter()
    .flatten()
    .collect();
    (!lines.is_empty()).then(|| lines.join("\n"))
}

/// `/api/health`: 200 while the render worker and the file watcher run, 503 when one was given
/// up after repeated panics.
fn health(shared: &Shared) -> Reply {
    let state = shared.lock();
    let dead = state.worker.dead.is_some() || state.watcher.dead.is_some();
    Reply::json(
        if dead { 503 } else { 200 },
        json!({
            "ok": !dead,
            "threads": threads(&state),
            "problem": thread_problem(&state),
        }),
    )
}

fn strip(shared: &Shared, source: Source) -> Reply {
    let mut state = shared.lock();
    let Some(scene) = state.scene.clone() else {
        return no_scene(&state);
    };
    let method_name = params_name(shared, source);
    if source.method().is_none() {
        // Frames read from files keep no vertex or triangle counts.
        return Reply::json(
            200,
            json!({ "generation": state.generation, "method": method_name, "available": false,
                    "done": true, "frames": [] }),
        );
    }
    if !state.strips.contains_key(&source) {
        worker::want_strip(&mut state, source);
        shared.wake.notify_all();
    }
    let strip = &state.strips[&source];
    let frames: Vec<_> = strip
        .counts
        .iter()
        .enumerate()
        .map(|(index, counts)| {
            let frame = scene.first_frame + index as u32;
            json!({
                "frame": frame,
                "time_secs": (frame - scene.first_frame) as f64 / scene.fps,
                "counts": counts,
            })
        })
        .collect();
    Reply::json(
        200,
        json!({
            "generation": state.generation,
            "method": method_name,
            "available": true,
            "done": strip.counts.iter().all(Option::is_some),
            "frames": frames,
        }),
    )
}

fn no_scene(state: &State) -> Reply {
    Reply::error(
        503,
        format!(
            "the scene did not load: {}",
            state.problem.as_deref().unwrap_or("(no message)")
        ),
    )
}

/// The source's name, as requests and the page use it.
fn params_name(shared: &Shared, source: Source) -> String {
    shared
        .sources()
        .into_iter()
        .find(|(s, _, _)| *s == source)
        .map_or_else(|| "?".to_string(), |(_, name, _)| name)
}

/// A frame number from the path (`12` of `/api/frame/12.png`), or a 400 saying what one is.
fn frame_number(number: &str) -> Result<u32, Reply> {
    number.parse::<u32>().map_err(|_| {
        Reply::error(
            400,
            format!("frame {number:?} is not a frame number (a whole number such as 12)"),
        )
    })
}

/// The frame number of the path and the source `method=` names, or the 400 that says why not.
fn frame_and_source(shared: &Shared, number: &str, params: &Query) -> Result<(u32, Source), Reply> {
    Ok((frame_number(number)?, params.source(shared, "method")?))
}

/// The key of frame `frame` of `source`, or 503 (no scene) or 404 (outside the timeline).
fn key_in_range(shared: &Shared, source: Source, frame: u32) -> Result<FrameKey, Reply> {
    let state = shared.lock();
    let Some(scene) = state.scene.clone() else {
        return Err(no_scene(&state));
    };
    if !state.frame_in_range(frame) {
        return Err(Reply::error(
            404,
            format!(
                "frame {frame} is outside the timeline of {} (frames {} to {})",
                scene.name, scene.first_frame, scene.last_frame
            ),
        ));
    }
    Ok(state.frame_key(source, frame))
}

/// `/api/frame/<N>.png` and `/api/frame/<N>.json`.
fn frame(shared: &Shared, rest: &str, params: &Query) -> Reply {
    let (number, extension) = rest.rsplit_once('.').unwrap_or((rest, ""));
    if extension != "png" && extension != "json" {
        return Reply::error(
            404,
            format!("/api/frame/{rest}: ask for /api/frame/<N>.png (the image) or /api/frame/<N>.json (its flag counts)"),
        );
    }
    let (frame, source) = match frame_and_source(shared, number, params) {
        Ok(found) => found,
        Err(reply) => return reply,
    };
    let against = match params.get("against") {
        None | Some("") => None,
        Some(_) => match params.source(shared, "against") {
            Ok(against) => Some(against),
            Err(reply) => return reply,
        },
    };
    let layer = match params.get("layer") {
        None | Some("") => Layer::Beauty,
        Some(name) => match layers::layer_named(name) {
            Some(layer) => layer,
            None => {
                return Reply::error(
                    400,
                    format!(
                        "layer {name:?} is not a layer of the channel map; use one of {}",
                        Layer::ALL.map(Layer::name).join(", ")
                    ),
                )
            }
        },
    };
    let exposure_stops = match params.get("exposure") {
        None | Some("") => 0.0,
        Some(text) => match text.parse::<f32>() {
            Ok(value) if value.is_finite() && value.abs() <= 20.0 => value,
            _ => {
                return Reply::error(
                    400,
                    format!("exposure {text:?} must be a number of stops between -20 and 20"),
                )
            }
        },
    };
    let mut overlay_bits = 0;
    for name in params
        .get("flags")
        .unwrap_or("")
        .split(',')
        .filter(|n| !n.is_empty())
    {
        match OVERLAYS.iter().find(|(overlay, _, _)| *overlay == name) {
            Some((_, bit, _)) => overlay_bits |= bit,
            None => {
                return Reply::error(
                    400,
                    format!("flags: {name:?} is not a flag; use convergence, boundary, popping or extrapolated"),
                )
            }
        }
    }

    let key = match key_in_range(shared, source, frame) {
        Ok(key) => key,
        Err(reply) => return reply,
    };
    let image_key = ImageKey {
        frame: key,
        exposure_milli_stops: (exposure_stops * 1000.0).round() as i32,
        overlay_bits,
        layer,
        against,
    };
    let mut headers = vec![
        ("X-Snell-Frame", frame.to_string()),
        ("X-Snell-Generation", key.generation.to_string()),
        ("X-Snell-Method", params_name(shared, source)),
        ("X-Snell-Layer", layer.name().to_string()),
    ];
    if extension == "png" {
        let mut state = shared.lock();
        if let Some((bytes, legend)) = state.images.get(&image_key) {
            state.queue_prefetch(key);
            drop(state);
            shared.wake.notify_all();
            headers.push(("X-Snell-Cache", "image".to_string()));
            headers.push(("X-Snell-Legend", legend.as_ref().clone()));
            return png_reply(bytes.as_ref().clone(), headers);
        }
    }
    let (cached, was_cached) = match wait_for_frame(shared, key) {
        Ok(found) => found,
        Err(reply) => return reply,
    };
    headers.push((
        "X-Snell-Cache",
        if was_cached { "frame" } else { "miss" }.to_string(),
    ));
    if extension == "json" {
        let mut reply = Reply::json(
            200,
            json!({
                "frame": frame,
                "method": params_name(shared, source),
                "generation": key.generation,
                "counts": cached.counts,
                "stage_secs": cached.stage_secs,
                "size": [cached.rendered.width, cached.rendered.height],
            }),
        );
        reply.headers = headers;
        return reply;
    }
    let other = match against {
        Some(against) => match wait_for_frame(
            shared,
            FrameKey {
                source: against,
                ..key
            },
        ) {
            Ok((other, _)) => Some(other),
            Err(reply) => return reply,
        },
        None => None,
    };
    let drawn = match &other {
        Some(other) => layers::difference_image(&cached, other, layer)
            .map(|(image, legend)| (encode(&image), legend)),
        None if layer == Layer::Beauty => Some((
            encode_png(&cached, exposure_stops, overlay_bits),
            format!("beauty: tone-mapped at {exposure_stops:+.2} EV"),
        )),
        None => layers::layer_image(&cached, layer, exposure_stops).map(|(mut image, legend)| {
            if overlay_bits != 0 {
                overlay_flags(&mut image, &cached.rendered.flags, overlay_bits);
            }
            (encode(&image), legend)
        }),
    };
    let Some((bytes, legend)) = drawn else {
        return Reply::error(
            404,
            format!(
                "frame {frame} of {} has no {} layer{}",
                params_name(shared, source),
                layer.name(),
                if other.is_some() {
                    " to compare (or the two frames differ in size)"
                } else {
                    ""
                }
            ),
        );
    };
    let bytes = Arc::new(bytes);
    shared
        .lock()
        .images
        .insert(image_key, (Arc::clone(&bytes), Arc::new(legend.clone())));
    headers.push(("X-Snell-Legend", legend));
    png_reply(bytes.as_ref().clone(), headers)
}

/// `/api/pixel/<N>?method=&x=&y=`: every channel's value at one pixel of frame N (as the frame's
/// EXR holds it), the object's name, the flags set, and the distance from its `P` to the
/// reference's `P` there once the reference frame is rendered (`reference.status` says whether it
/// is; asking for its `/api/frame/<N>.json` renders it).
fn pixel(shared: &Shared, number: &str, params: &Query) -> Reply {
    let (frame, source) = match frame_and_source(shared, number, params) {
        Ok(found) => found,
        Err(reply) => return reply,
    };
    let key = match key_in_range(shared, source, frame) {
        Ok(key) => key,
        Err(reply) => return reply,
    };
    let (cached, _) = match wait_for_frame(shared, key) {
        Ok(found) => found,
        Err(reply) => return reply,
    };
    let (width, height) = (cached.rendered.width, cached.rendered.height);
    let coordinate = |name: &str, size: u32| -> Result<u32, Reply> {
        match params.get(name).map(str::parse::<u32>) {
            Some(Ok(value)) if value < size => Ok(value),
            _ => Err(Reply::error(
                400,
                format!(
                    "{name} must be a pixel column or row of the {width}x{height} frame (0 to {})",
                    size - 1
                ),
            )),
        }
    };
    let (x, y) = match (coordinate("x", width), coordinate("y", height)) {
        (Ok(x), Ok(y)) => (x, y),
        (Err(reply), _) | (_, Err(reply)) => return reply,
    };
    let channels = layers::pixel_channels(&cached, x, y);
    let index = (y * width + x) as usize;
    let object = cached.rendered.object.get(index).copied();
    let object_name = object.map(|id| match id {
        crate::draw::NO_OBJECT => "nothing (sky, or water with nothing behind it)".to_string(),
        id => cached
            .object_names
            .get(id as usize - 1)
            .cloned()
            .unwrap_or_else(|| format!("object {id} (not named in the frame)")),
    });
    let bits = cached.rendered.flags.get(index).copied().unwrap_or(0);
    let flags: Vec<&str> = OVERLAYS
        .iter()
        .filter(|(_, bit, _)| bits & bit != 0)
        .map(|(name, _, _)| *name)
        .collect();
    let position = |frame: &CachedFrame| frame.rendered.position.get(index).copied();
    let reference = match shared.reference_source() {
        None => {
            json!({ "status": "none", "message": "no --frames-dir folder holds the ray-traced reference (snell.method raytrace/exact-surface)" })
        }
        Some(reference) if reference == source => {
            json!({ "status": "this is the reference", "method": params_name(shared, reference) })
        }
        Some(reference) => {
            let reference_key = FrameKey {
                source: reference,
                ..key
            };
            let found = shared.lock().frames.get(&reference_key);
            let name = params_name(shared, reference);
            match found {
                None => json!({ "status": "not rendered", "method": name }),
                Some(found) => match (position(cached.as_ref()), position(found.as_ref())) {
                    (Some(p), Some(r)) => {
                        let error = glam::Vec3::from(p).distance(glam::Vec3::from(r));
                        let reference_object = found.rendered.object.get(index).copied();
                        json!({
                            "status": "rendered",
                            "method": name,
                            "P": r.map(|v| v.to_string()),
                            "error_m": error.to_string(),
                            "same_object": reference_object == object,
                        })
                    }
                    _ => json!({ "status": "no P layer", "method": name }),
                },
            }
        }
    };
    let mut reply = Reply::json(
        200,
        json!({
            "x": x,
            "y": y,
            "frame": frame,
            "method": params_name(shared, source),
            "generation": key.generation,
            // As text: Rust's shortest form that reads back as the same float32 (and `inf`, `NaN`).
            "channels": channels.iter().map(|(name, value)| json!([name, value.to_string()])).collect::<Vec<_>>(),
            "object": object.map(|id| json!({ "index": id, "name": object_name })),
            "flags": flags,
            "reference": reference,
        }),
    );
    reply.headers = vec![("X-Snell-Frame", frame.to_string())];
    reply
}

fn encode(image: &RgbaImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        Cursor::new(&mut bytes),
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    image
        .write_with_encoder(encoder)
        .expect("PNG encoding into memory cannot fail");
    bytes
}

fn png_reply(body: Vec<u8>, headers: Vec<(&'static str, String)>) -> Reply {
    Reply {
        status: 200,
        content_type: "image/png",
        body,
        headers,
    }
}

/// The frame of `key`, waiting for the worker when it is not cached (then asking for it first).
/// Returns whether it was already cached.
fn wait_for_frame(shared: &Shared, key: FrameKey) -> Result<(Arc<CachedFrame>, bool), Reply> {
    let deadline = Instant::now() + FRAME_WAIT;
    let mut state = shared.lock();
    let mut was_cached = true;
    loop {
        if state.generation != key.generation {
            return Err(Reply::error(
                409,
                "the scene was reloaded while this frame was rendering; ask again",
            ));
        }
        if let Some(frame) = state.frames.get(&key) {
            state.queue_prefetch(key);
            drop(state);
            shared.wake.notify_all();
            return Ok((frame, was_cached));
        }
        if let Some((status, message)) = state.failed.get(&key) {
            return Err(Reply::error(*status, message.clone()));
        }
        if let Some(problem) = &state.renderer_problem {
            return Err(Reply::error(500, format!("no GPU renderer: {problem}")));
        }
        if let Some(dead) = &state.worker.dead {
            return Err(Reply::error(500, dead.clone()));
        }
        if state.stopping {
            return Err(Reply::error(503, "the preview is stopping"));
        }
        was_cached = false;
        if state.demand.front() != Some(&key) {
            state.demand.retain(|k| *k != key);
            state.demand.push_front(key);
            shared.wake.notify_all();
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(Reply::error(
                503,
                format!(
                    "frame {} was not rendered within {} s",
                    key.frame,
                    FRAME_WAIT.as_secs()
                ),
            ));
        }
        state = shared
            .wake
            .wait_timeout(state, deadline - now)
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .0;
    }
}

/// Tone-maps, overlays the chosen flag masks (each flagged pixel blended towards its flag's
/// colour; when several flags are chosen the first in [`OVERLAYS`] order wins), encodes PNG.
fn encode_png(frame: &CachedFrame, exposure_stops: f32, overlay_bits: u32) -> Vec<u8> {
    let mut image = crate::output::tonemap::tonemap_srgb8(&frame.rendered, exposure_stops);
    if overlay_bits != 0 {
        overlay_flags(&mut image, &frame.rendered.flags, overlay_bits);
    }
    encode(&image)
}

/// How strongly a flagged pixel takes its flag's colour (enough to see, not enough to hide what
/// is under it).
const OVERLAY_OPACITY: f32 = 0.6;

fn overlay_flags(image: &mut RgbaImage, flags: &[u32], overlay_bits: u32) {
    for (pixel, &bits) in image.pixels_mut().zip(flags) {
        let chosen = bits & overlay_bits;
        if chosen == 0 {
            continue;
        }
        let Some((_, _, color)) = OVERLAYS.iter().find(|(_, bit, _)| chosen & bit != 0) else {
            continue;
        };
        for (value, &over) in pixel.0.iter_mut().zip(color) {
            let (under, over) = (*value as f32, over as f32);
            *value = (under + (over - under) * OVERLAY_OPACITY).round() as u8;
        }
        pixel.0[3] = 255;
    }
}

/// A URL query string, percent-decoded.
struct Query(Vec<(String, String)>);

impl Query {
    fn parse(query: &str) -> Query {
        Query(
            query
                .split('&')
                .filter(|pair| !pair.is_empty())
                .map(|pair| {
                    let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
                    (percent_decode(key), percent_decode(value))
                })
                .collect(),
        )
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.0
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// The source parameter `key` names (`method=`, `against=`): a method, or a `--frames-dir`
    /// folder's name; the default source when absent.
    fn source(&self, shared: &Shared, key: &str) -> Result<Source, Reply> {
        shared
            .source_named(self.get(key))
            .map_err(|message| Reply::error(400, format!("{key}: {message}")))
    }
}

fn percent_decode(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut index = 0;
    while index < bytes.len() {
        match bytes[index] {
            b'+' => decoded.push(b' '),
            b'%' if index + 2 < bytes.len() => {
                let hex = std::str::from_utf8(&bytes[index + 1..index + 3]).unwrap_or("");
                match u8::from_str_radix(hex, 16) {
                    Ok(byte) => {
                        decoded.push(byte);
                        index += 2;
                    }
                    Err(_) => decoded.push(b'%'),
                }
            }
            byte => decoded.push(byte),
        }
        index += 1;
    }
    String::from_utf8_lossy(&decoded).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_loopback_hosts_are_served() {
        for host in [
            "127.0.0.1",
            "127.0.0.1:8765",
            "localhost",
            "LOCALHOST:80",
            "[::1]",
            "[::1]:8765",
        ] {
            assert!(is_loopback_host(host), "{host}");
        }
        for host in [
            "evil.example",
            "evil.example:8765",
            "127.0.0.1.evil.example",
            "localhost.evil.example",
            "127.0.0.2",
            "[::2]:80",
            "[::1]x",
            "localhost:",
            "localhost:99999",
            "",
        ] {
            assert!(!is_loopback_host(host), "{host}");
        }
    }

    #[test]
    fn queries_are_percent_decoded() {
        let query = Query::parse("flags=convergence%2Cpopping&exposure=-1.5&method=equal-t&x");
        assert_eq!(query.get("flags"), Some("convergence,popping"));
        assert_eq!(query.get("exposure"), Some("-1.5"));
        assert_eq!(query.get("x"), Some(""));
        assert_eq!(query.get("y"), None);
        assert_eq!(percent_decode("a%2"), "a%2");
        assert_eq!(percent_decode("%zz"), "%zz");
        assert_eq!(percent_decode("100%25"), "100%");
    }

    #[test]
    fn overlay_marks_only_chosen_flags() {
        let mut image = RgbaImage::from_pixel(3, 1, image::Rgba([100, 100, 100, 255]));
        let flags = [flag_bits::CONVERGENCE, flag_bits::BOUNDARY, 0];
        overlay_flags(&mut image, &flags, flag_bits::CONVERGENCE);
        assert_eq!(image.get_pixel(0, 0).0, [193, 40, 193, 255]);
        assert_eq!(image.get_pixel(1, 0).0, [100, 100, 100, 255]);
        assert_eq!(image.get_pixel(2, 0).0, [100, 100, 100, 255]);
    }
}
