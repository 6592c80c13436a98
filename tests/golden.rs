//! Golden frames of `scenes/pool.toml` and `scenes/fox_wading.toml`: small frames rendered exactly as `snell render` renders them,
//! compared with committed goldens by FLIP on the tone-mapped beauty, and their per-frame flag counts
//! compared exactly. A missing golden FAILS. `SNELL_BLESS=1 cargo test --test golden` rewrites them;
//! a failure writes `<name>-actual.png` and `<name>-difference.png` next to the golden.

use std::path::{Path, PathBuf};

use snell::frame::RenderJob;
use snell::gpu::Renderer;
use snell::output::compare::{check_golden, flip_ldr, FlipThreshold};
use snell::output::tonemap::tonemap_srgb8;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 180;

/// Mean FLIP allowed between a render and its golden. The refraction stage is deterministic and the
/// flag counts must match exactly, so image differences can only come from the rasteriser: the beauty
/// target is Rgba32Float on Vulkan but Rgba16Float on GL (half floats round the linear colour to 11
/// significant bits: at most about one 8-bit step after tone mapping), and llvmpipe and lavapipe may
/// differ in texture filtering (llvmpipe's sRGB decode is about 0.1 % off). Measured: goldens blessed on
/// Vulkan (lavapipe), rendered on GL (llvmpipe): mean FLIP 0.0042, 0.0046, 0.0050 for pool frames 1, 24, 48 and
/// 0.0044, 0.0044 for fox_wading frames 12, 36 (Mesa 22.3.6). The test below also checks that two frames of the shot differ by more than this.
const FLIP_MEAN_THRESHOLD: f32 = 0.01;

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

fn bless() -> bool {
    std::env::var("SNELL_BLESS").is_ok_and(|v| v == "1")
}

fn check_counts(name: &str, counts: &serde_json::Value) {
    let path = golden_dir().join(format!("{name}.counts.json"));
    let actual = serde_json::to_string_pretty(counts).unwrap() + "\n";
    if bless() {
        std::fs::create_dir_all(golden_dir()).unwrap();
        std::fs::write(&path, &actual).unwrap();
        return;
    }
    let expected = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "golden flag counts {} cannot be read ({e}); if this is a new golden, run SNELL_BLESS=1 cargo test --test golden",
            path.display()
        )
    });
    let expected: serde_json::Value = serde_json::from_str(&expected).unwrap();
    assert_eq!(
        &expected, counts,
        "flag counts of {name} differ from {} (bless with SNELL_BLESS=1 only if the change is intended)",
        path.display()
    );
}

#[test]
fn pool_golden_frames() {
    golden_frames("pool", &[1, 24, 48]);
}

/// The fox wading: skinned character, split at the water line, ripples in its wake (each frame
/// rendered alone, so the ripples are stepped from frame 1 without checkpoints).
#[test]
fn fox_wading_golden_frames() {
    golden_frames("fox_wading", &[12, 36]);
}

/// Renders `frames` of `scenes/<stem>.toml` and checks each against `tests/golden/<stem>-NNNN.*`.
fn golden_frames(stem: &str, frames: &[u32]) {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{stem}.toml"));
    let job = RenderJob::prepare(&scene).expect("the scene loads");
    let mut renderer =
        Renderer::new().expect("a wgpu adapter (Mesa's llvmpipe or lavapipe at least)");
    job.upload_textures(&mut renderer).expect("textures upload");
    let mut failures = Vec::new();
    let mut first_image = None;
    for &frame in frames {
        let (refracted, rendered) = job
            .render_frame(&mut renderer, frame, WIDTH, HEIGHT)
            .expect("frame renders");
        let name = format!("{stem}-{frame:04}");
        check_counts(&name, &serde_json::to_value(refracted.counts).unwrap());
        let image = tonemap_srgb8(&rendered, 0.0);
        if frame == frames[0] {
            first_image = Some(image.clone());
        } else if let Some(first) = &first_image {
            // The threshold must be able to fail: two frames of the same shot (camera moved, waves
            // moved) must differ by more than it, or the golden test would accept a broken render.
            let mean = flip_ldr(first, &image).expect("same size").mean;
            assert!(
                mean > FLIP_MEAN_THRESHOLD,
                "frame {} and frame {frame} differ by a mean FLIP of only {mean}: the threshold {FLIP_MEAN_THRESHOLD} is too loose",
                frames[0]
            );
        }
        match check_golden(
            &golden_dir(),
            &name,
            &image,
            FlipThreshold::Mean(FLIP_MEAN_THRESHOLD),
        ) {
            Ok(outcome) => eprintln!("{name}: {outcome:?} on {}", renderer.adapter_summary()),
            Err(error) => failures.push(format!("{name}: {error}")),
        }
    }
    assert!(
        failures.is_empty(),
        "golden frames differ:\n{}",
        failures.join("\n")
    );
}
