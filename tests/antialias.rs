//! Anti-aliasing (issue 16 point 5): a thin card with a slanted edge (8 degrees off vertical) in
//! front of a black sky, rendered as `snell render` renders it, by the rasteriser (supersampled:
//! `[antialias] supersample = 2`, the box filter by the trapezoid rule on 3 x 3 points a pixel,
//! 4 of them its own) and by the reference (4 x 4 stratified rays a pixel). Across the edge the
//! beauty must follow the card's covered fraction of each pixel, computed exactly here (the card's
//! face projected through the frame's camera and clipped against the pixel's square: an oracle
//! that shares nothing with either renderer), and so must the Cryptomatte coverage of the card;
//! `P`, `Z` and the object index stay the pixel centre's. Without supersampling the same check
//! fails (stair steps: every pixel all or nothing), so the test can fail.
//!
//! Tolerances: the trapezoid rule on points at 0, 1/2 and 1 of the pixel puts a straight edge's
//! coverage within 1/4 of the true fraction along each axis (its estimate is 0, 1/4, 3/4 or 1
//! for an edge parallel to a side, whose error averages 1/8); 16 jittered rays are within about
//! 1/8 at worst. Measured 2026-12-08 over the 237 edge pixels, the same on lavapipe (Vulkan) and
//! llvmpipe (GL): rasteriser mean 0.092, max 0.182; reference mean 0.036, max 0.182; without
//! supersampling mean 0.219, max 0.500 (no pixel between the card and the sky). Bounds:
//! rasteriser mean < 0.12 and max <= 0.25, reference mean < 0.07 and max <= 0.25, not
//! supersampled mean > 0.15.

mod common;

use glam::{Vec2, Vec3};
use snell::draw::RenderedFrame;
use snell::frame::{Method, RenderJob};
use snell::gpu::Renderer;

const WIDTH: u32 = 96;
const HEIGHT: u32 = 64;
/// Half the card's side, its centre and its turn about the view axis.
const HALF_SIDE_M: f32 = 0.3;
const CENTRE: Vec3 = Vec3::new(0.0, 1.0, 0.0);
const TURN_DEG: f32 = 8.0;

fn scene_text(supersample: u32, reference_grid: u32) -> String {
    format!(
        r#"
name = "slanted_edge"
[timeline]
frames = [1, 1]
[[camera]]
eye = [0.0, 1.0, -3.0]
target = [0.2, 1.0, 0.0]
fov_deg = 14
[water]
min = [40.0, 40.0]
max = [41.0, 41.0]
resolution = [2, 2]
[sky]
zenith_color = [0.0, 0.0, 0.0]
horizon_color = [0.0, 0.0, 0.0]
ambient_color = [1.0, 1.0, 1.0]
ambient_intensity = 0.5
[sun]
intensity = 0.0
[antialias]
supersample = {supersample}
reference_grid = {reference_grid}
[[object]]
name = "card"
shape = "box"
size_m = [{side}, {side}, 0.001]
translate = [{x}, {y}, {z}]
rotate_deg = [0, 0, {TURN_DEG}]
texture = {{ kind = "solid", color = [1.0, 1.0, 1.0] }}
"#,
        side = 2.0 * HALF_SIDE_M,
        x = CENTRE.x,
        y = CENTRE.y,
        z = CENTRE.z,
    )
}

fn job(supersample: u32, reference_grid: u32, method: Method) -> RenderJob {
    common::scene_job(
        "antialias",
        &format!("edge_{supersample}_{reference_grid}"),
        &scene_text(supersample, reference_grid),
        method,
    )
}

/// The card's front face (facing the eye, at z = -0.0005) as a polygon in pixel coordinates.
fn projected_face(camera: &snell::camera::Camera) -> Vec<Vec2> {
    let turn = TURN_DEG.to_radians();
    let (sin, cos) = turn.sin_cos();
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(a, b)| {
            let (x, y) = (a * HALF_SIDE_M, b * HALF_SIDE_M);
            let corner = CENTRE + Vec3::new(x * cos - y * sin, x * sin + y * cos, -0.0005);
            camera
                .pixel_of(corner, WIDTH, HEIGHT)
                .expect("the card is in view")
        })
        .collect()
}

/// The area of `polygon` (convex, any winding) inside pixel `(x, y)`'s unit square:
/// Sutherland-Hodgman against the square's four sides, then the shoelace formula.
fn covered_fraction(polygon: &[Vec2], x: u32, y: u32) -> f32 {
    let (x0, y0) = (x as f32, y as f32);
    let sides: [(Vec2, f32); 4] = [
        (Vec2::X, x0),
        (-Vec2::X, -(x0 + 1.0)),
        (Vec2::Y, y0),
        (-Vec2::Y, -(y0 + 1.0)),
    ];
    let mut points = polygon.to_vec();
    for (normal, offset) in sides {
        let inside = |p: Vec2| p.dot(normal) - offset;
        let mut kept = Vec::new();
        for i in 0..points.len() {
            let (p, q) = (points[i], points[(i + 1) % points.len()]);
            let (dp, dq) = (inside(p), inside(q));
            if dp >= 0.0 {
                kept.push(p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                kept.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
        points = kept;
        if points.is_empty() {
            return 0.0;
        }
    }
    let twice_area: f32 = (0..points.len())
        .map(|i| points[i].perp_dot(points[(i + 1) % points.len()]))
        .sum();
    (twice_area * 0.5).abs()
}

/// How far the beauty (as a fraction of the card's own colour) and the card's Cryptomatte
/// coverage are from the covered fraction over the pixels the card's edges cross.
#[derive(Debug)]
struct Ramp {
    edge_pixels: usize,
    beauty_mean: f32,
    beauty_max: f32,
    coverage_mean: f32,
    coverage_max: f32,
    /// Pixels whose beauty is neither the card's nor the sky's (the ramp's steps).
    partial_pixels: usize,
}

fn ramp(frame: &RenderedFrame, camera: &snell::camera::Camera) -> Ramp {
    let face = projected_face(camera);
    let card_id = 1;
    // The card's colour: the brightest red (fully covered interior pixels; the sky is black).
    let card = frame
        .beauty_rgba
        .iter()
        .map(|p| p[0])
        .fold(0.0f32, f32::max);
    assert!(card > 0.1, "the card is not lit: {card}");
    let (mut n, mut beauty_sum, mut beauty_max, mut coverage_sum, mut coverage_max) =
        (0, 0.0, 0.0f32, 0.0, 0.0f32);
    let mut partial_pixels = 0;
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let at = (y * WIDTH + x) as usize;
            let fraction = covered_fraction(&face, x, y);
            let seen = frame.beauty_rgba[at][0] / card;
            if seen > 0.02 && seen < 0.98 {
                partial_pixels += 1;
            }
            if fraction <= 1e-6 || fraction >= 1.0 - 1e-6 {
                // Away from the edge every layer is exact.
                let inside = fraction > 0.5;
                assert!(
                    (seen - if inside { 1.0 } else { 0.0 }).abs() < 1e-3,
                    "pixel ({x},{y}) covered {fraction} shows {seen}"
                );
                continue;
            }
            n += 1;
            let beauty_error = (seen - fraction).abs();
            beauty_sum += beauty_error;
            beauty_max = beauty_max.max(beauty_error);
            let coverage = if frame.coverage.is_empty() {
                // One sample: the centre's object has it all.
                if frame.object[at] == card_id {
                    1.0
                } else {
                    0.0
                }
            } else {
                frame.coverage[at]
                    .iter()
                    .find(|rank| rank.key == card_id)
                    .map_or(0.0, |rank| rank.coverage)
            };
            let coverage_error = (coverage - fraction).abs();
            coverage_sum += coverage_error;
            coverage_max = coverage_max.max(coverage_error);
            // The centre's layers: the card's where its face covers the centre, else the sky's
            // (not judged within float error of the edge, 0.01 px).
            let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let centre_in = covered_fraction_contains(&face, centre);
            let margin = distance_to_polygon_edge(&face, centre);
            if margin > 0.01 {
                assert_eq!(
                    frame.object[at],
                    if centre_in { card_id } else { 0 },
                    "pixel ({x},{y}): the object index is not the pixel centre's"
                );
                if centre_in {
                    assert!(
                        (frame.position[at][2] + 0.0005).abs() < 1e-3,
                        "pixel ({x},{y}): P {:?} is not on the card",
                        frame.position[at]
                    );
                } else {
                    assert_eq!(frame.depth_m[at], snell::draw::SKY_DEPTH_M);
                }
            }
        }
    }
    assert!(n > 100, "only {n} edge pixels");
    Ramp {
        edge_pixels: n,
        beauty_mean: beauty_sum / n as f32,
        beauty_max,
        coverage_mean: coverage_sum / n as f32,
        coverage_max,
        partial_pixels,
    }
}

/// Whether `point` is inside the convex `polygon`.
fn covered_fraction_contains(polygon: &[Vec2], point: Vec2) -> bool {
    let sides: Vec<f32> = (0..polygon.len())
        .map(|i| (polygon[(i + 1) % polygon.len()] - polygon[i]).perp_dot(point - polygon[i]))
        .collect();
    sides.iter().all(|&s| s >= 0.0) || sides.iter().all(|&s| s <= 0.0)
}

/// Distance in pixels from `point` to the nearest side of `polygon`.
fn distance_to_polygon_edge(polygon: &[Vec2], point: Vec2) -> f32 {
    (0..polygon.len())
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
            let t = ((point - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - point).length()
        })
        .fold(f32::INFINITY, f32::min)
}

fn rasterised(supersample: u32) -> (Ramp, RenderedFrame) {
    let job = job(supersample, 1, Method::EqualT);
    let mut renderer = Renderer::new().unwrap_or_else(|error| panic!("{error}"));
    job.upload_textures(&mut renderer).unwrap();
    let (refracted, frame) = job
        .render_frame(&mut renderer, 1, WIDTH, HEIGHT)
        .unwrap_or_else(|error| panic!("{error}"));
    assert_eq!(renderer.supersample(), supersample);
    (ramp(&frame, &refracted.view.camera), frame)
}

#[test]
fn the_rasteriser_follows_the_covered_fraction_across_a_slanted_edge() {
    let (ramp, _) = rasterised(2);
    eprintln!("rasteriser, supersampled: {ramp:?}");
    assert!(ramp.beauty_mean < 0.12, "{ramp:?}");
    assert!(ramp.beauty_max <= 0.25, "{ramp:?}");
    assert!(ramp.coverage_mean < 0.12, "{ramp:?}");
    assert!(ramp.coverage_max <= 0.25, "{ramp:?}");
    assert!(ramp.partial_pixels > ramp.edge_pixels / 2, "{ramp:?}");
}

#[test]
fn without_supersampling_the_edge_stair_steps_and_fails_the_ramp() {
    let (ramp, _) = rasterised(1);
    eprintln!("rasteriser, not supersampled: {ramp:?}");
    assert!(ramp.beauty_mean > 0.15, "{ramp:?}");
    assert!(ramp.partial_pixels == 0, "{ramp:?}");
}

#[test]
fn the_reference_follows_the_covered_fraction_across_a_slanted_edge() {
    let job = job(2, 4, Method::Raytrace);
    let (refracted, frame) = job
        .render_frame(None, 1, WIDTH, HEIGHT)
        .unwrap_or_else(|error| panic!("{error}"));
    let ramp = ramp(&frame, &refracted.view.camera);
    eprintln!("reference, 4 x 4 rays: {ramp:?}");
    assert!(ramp.beauty_mean < 0.07, "{ramp:?}");
    assert!(ramp.beauty_max <= 0.25, "{ramp:?}");
    assert!(ramp.coverage_mean < 0.07, "{ramp:?}");
    assert!(ramp.coverage_max <= 0.25, "{ramp:?}");
}
