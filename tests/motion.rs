//! The `Motion` layer against known answers, on `tests/fixtures/scenes/motion_pan.toml` (a static
//! scene, its water slowed to 1 mm/s, seen by a camera sweeping 7.5 m in 2 s). It is the hard
//! `fast_camera` scene without its short crossing swell: where the swell focuses the floor into
//! convergence zones a floor point has several images, and a pixel's single motion vector has no
//! one true answer to be checked against (popping and `snell stability` judge those zones).
//! - above the water, a pixel's motion is where its true point `P` projects now minus where it
//!   projected through frame t-1's camera (the camera's own projection, not the GPU's);
//! - through the water, following a pixel's motion back to frame t-1 lands where frame t-1,
//!   rendered on its own, shows the same true point `P` (sampled between its pixels).
//!   This compares against the renderer's own frame t-1, not the reference tracer.

use std::path::Path;

use glam::{Vec2, Vec3};
use snell::draw::{RenderedFrame, NO_OBJECT};
use snell::frame::RenderJob;
use snell::gpu::Renderer;

const SIZE: (u32, u32) = (320, 180);
const FRAME: u32 = 24;

fn render(
    job: &RenderJob,
    renderer: &mut Renderer,
    frame: u32,
) -> (snell::camera::Camera, RenderedFrame) {
    let (refracted, rendered) = job
        .render_frame(&mut *renderer, frame, SIZE.0, SIZE.1)
        .unwrap();
    (refracted.camera, rendered)
}

/// Pixels whose 3x3 neighbourhood shows one object, all above water (`water` false) or all
/// through it: away from edges, where a pixel's interpolated P is one surface's.
fn interior(frame: &RenderedFrame, water: bool) -> Vec<(usize, usize)> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut out = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let object = frame.object[i];
            if object == NO_OBJECT {
                continue;
            }
            let same = (-1i32..=1).all(|dy| {
                (-1i32..=1).all(|dx| {
                    let j = (y as i32 + dy) as usize * w + (x as i32 + dx) as usize;
                    frame.object[j] == object && (frame.water_matte[j] == 1.0) == water
                })
            });
            if same {
                out.push((x, y));
            }
        }
    }
    out
}

fn percentile(mut values: Vec<f32>, q: f32) -> f32 {
    values.sort_by(f32::total_cmp);
    values[((values.len() - 1) as f32 * q) as usize]
}

#[test]
fn motion_is_the_true_screen_motion_above_and_through_the_water() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/scenes/motion_pan.toml");
    let job = RenderJob::prepare(&scene).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    let (camera_before, before) = render(&job, &mut renderer, FRAME - 1);
    let (camera, now) = render(&job, &mut renderer, FRAME);
    let (w, h) = SIZE;
    assert_eq!(now.motion_px.len(), now.pixel_count());
    let motion = |x: usize, y: usize| Vec2::from(now.motion_px[y * w as usize + x]);

    // Nothing seen: 0.
    for (i, m) in now.motion_px.iter().enumerate() {
        if now.object[i] == NO_OBJECT {
            assert_eq!(*m, [0.0, 0.0], "pixel {i} sees nothing");
        }
    }

    // Above the water: the camera's projection of P at t and t-1.
    let above = interior(&now, false);
    assert!(above.len() > 2000, "{} pixels above water", above.len());
    let mut errors = Vec::new();
    let mut largest = 0.0f32;
    for &(x, y) in &above {
        let p = Vec3::from(now.position[y * w as usize + x]);
        let expected = camera.pixel_of(p, w, h).unwrap() - camera_before.pixel_of(p, w, h).unwrap();
        largest = largest.max(expected.length());
        errors.push((motion(x, y) - expected).length());
    }
    let (median, p99, max) = (
        percentile(errors.clone(), 0.5),
        percentile(errors.clone(), 0.99),
        percentile(errors, 1.0),
    );
    eprintln!("above water: {} px, motion up to {largest:.2} px, error median {median:.4} p99 {p99:.4} max {max:.4} px", above.len());
    assert!(largest > 5.0, "the camera moves: {largest} px");
    assert!(max < 0.01, "above-water motion off by up to {max} px");

    // Through the water: back along the motion, frame t-1 shows the same true point.
    let through = interior(&now, true);
    assert!(
        through.len() > 2000,
        "{} pixels through water",
        through.len()
    );
    let bw = w as usize;
    let sample = |q: Vec2| -> Option<(Vec3, f32)> {
        // Bilinear between the centres of t-1's pixels; all four must see one object through
        // the water. Also returns the size of one pixel there in metres of P.
        let (fx, fy) = (q.x - 0.5, q.y - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        if x0 < 0.0 || y0 < 0.0 || x0 + 2.0 >= w as f32 || y0 + 2.0 >= h as f32 {
            return None;
        }
        let (x0, y0, tx, ty) = (x0 as usize, y0 as usize, fx - fx.floor(), fy - fy.floor());
        let at = |x: usize, y: usize| y * bw + x;
        let corners = [
            at(x0, y0),
            at(x0 + 1, y0),
            at(x0, y0 + 1),
            at(x0 + 1, y0 + 1),
        ];
        let object = before.object[corners[0]];
        if object == NO_OBJECT
            || corners
                .iter()
                .any(|&c| before.object[c] != object || before.water_matte[c] != 1.0)
        {
            return None;
        }
        let p = |c: usize| Vec3::from(before.position[corners[c]]);
        let value = p(0).lerp(p(1), tx).lerp(p(2).lerp(p(3), tx), ty);
        let pixel_m = 0.5 * (p(0).distance(p(1)) + p(0).distance(p(2)));
        Some((value, pixel_m))
    };
    let mut errors_px = Vec::new();
    let mut largest = 0.0f32;
    for &(x, y) in &through {
        let m = motion(x, y);
        let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - m;
        let Some((p_before, pixel_m)) = sample(q) else {
            continue;
        };
        if pixel_m <= 0.0 {
            continue;
        }
        largest = largest.max(m.length());
        let p_now = Vec3::from(now.position[y * bw + x]);
        errors_px.push(p_now.distance(p_before) / pixel_m);
    }
    assert!(
        errors_px.len() > 1000,
        "{} refracted pixels compared",
        errors_px.len()
    );
    let (median, p99) = (
        percentile(errors_px.clone(), 0.5),
        percentile(errors_px.clone(), 0.99),
    );
    eprintln!("through water: {} px compared, motion up to {largest:.2} px, error (pixels of P at t-1) median {median:.4} p99 {p99:.4}", errors_px.len());
    assert!(largest > 5.0, "the refracted image moves: {largest} px");
    assert!(
        median < 0.01 && p99 < 0.1,
        "refracted motion off: median {median} p99 {p99} px"
    );
}
