//! Objects crossing the surface meet the water without a gap (ALGORITHM §7): in `pool.toml`, no
//! pixel along the walls' water line shows the sky through a wall, or the membrane with nothing
//! behind it (every ray into the pool's water ends on the floor, a wall or an object). Before the
//! water-line skirt (`refraction::virtual_geometry`), these frames at 1280x720 had 2, 7, 1 and 1
//! such pixels: the split line runs through the exact surface, the drawn water is the faceted
//! membrane, and a pixel centre could fall between the two.

use std::path::Path;

use snell::draw::{RenderedFrame, NO_OBJECT, SKY_DEPTH_M};
use snell::frame::RenderJob;
use snell::gpu::Renderer;

/// Pixels that see water with nothing behind it (the water matte, no object), and sky pixels with
/// geometry right above and right below them (the sky through a hole).
fn gaps(frame: &RenderedFrame) -> Vec<(u32, u32, &'static str)> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut found = Vec::new();
    for y in 1..h - 1 {
        for x in 0..w {
            let i = y * w + x;
            let sky = |i: usize| frame.depth_m[i] == SKY_DEPTH_M;
            if frame.water_matte[i] == 1.0 && frame.object[i] == NO_OBJECT {
                found.push((x as u32, y as u32, "water with nothing behind it"));
            }
            if sky(i) && !sky(i - w) && !sky(i + w) {
                found.push((x as u32, y as u32, "sky through a hole"));
            }
        }
    }
    found
}

#[test]
fn pool_walls_meet_the_water_without_a_gap() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pool.toml");
    let job = RenderJob::prepare(&scene).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    for frame in [12, 24, 36, 48] {
        let (_, rendered) = job.render_frame(&mut renderer, frame, 1280, 720).unwrap();
        // What the check looks for is in the frame: the sky above the deck, the floor through the
        // water.
        assert!(
            rendered.depth_m.contains(&SKY_DEPTH_M),
            "frame {frame}: no sky"
        );
        assert!(
            rendered.position.iter().any(|p| p[1] < -1.0),
            "frame {frame}: no floor seen through the water"
        );
        let found = gaps(&rendered);
        assert!(
            found.is_empty(),
            "frame {frame}: gaps at the water line {found:?}"
        );
    }
}
