//! The same inputs give the same bytes: a frame rendered twice, and a frame rendered alone versus
//! inside a sequence (popping is judged against frame t-1 recomputed), are identical.

use std::path::Path;

use snell::draw::RenderedFrame;
use snell::frame::RenderJob;
use snell::gpu::Renderer;

fn bits(frame: &RenderedFrame) -> (Vec<u32>, Vec<u32>, Vec<u32>, Vec<u32>) {
    (
        frame
            .beauty_rgba
            .iter()
            .flatten()
            .map(|v| v.to_bits())
            .collect(),
        frame.distance_m.iter().map(|v| v.to_bits()).collect(),
        frame
            .position
            .iter()
            .flatten()
            .map(|v| v.to_bits())
            .collect(),
        frame.flags.clone(),
    )
}

#[test]
fn same_frame_twice_gives_identical_pixels_and_alone_equals_in_sequence() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pool.toml");
    let job = RenderJob::prepare(&scene).unwrap();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    let (w, h) = (192, 108);
    let (first_cpu, first) = job.render_frame(&mut renderer, 12, w, h).unwrap();
    let (second_cpu, second) = job.render_frame(&mut renderer, 12, w, h).unwrap();
    assert!(
        first.beauty_rgba.iter().any(|p| p[0] > 0.0),
        "the frame is not empty"
    );
    assert_eq!(
        bits(&first),
        bits(&second),
        "two renders of frame 12 differ"
    );
    assert_eq!(first_cpu.counts, second_cpu.counts);

    // In a sequence: frame 11 then frame 12 with frame 11's tracking carried over.
    let eleven = job
        .refract(11, w, h, job.previous_tracking(11, w, h).unwrap().as_ref())
        .unwrap();
    let mut twelve = job.refract(12, w, h, Some(&eleven.tracking)).unwrap();
    let in_sequence = job
        .render_refracted(&mut renderer, &mut twelve, w, h)
        .unwrap();
    assert_eq!(
        bits(&first),
        bits(&in_sequence),
        "frame 12 alone differs from frame 12 in a sequence"
    );
    assert_eq!(first_cpu.counts, twelve.counts);
}

/// The ripple state at a frame depends on every earlier frame. Frames 40-48 of `fox_wading.toml`
/// rendered alone (the ripples stepped from frame 1 in memory) and rendered by a later job that
/// resumes from the full run's checkpoints equal, pixel for pixel, those frames of the full 1-48 run.
#[test]
fn fox_frames_40_to_48_alone_equal_those_of_the_full_run() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fox_wading.toml");
    let (w, h) = (96, 54);
    let checkpoints = tempfile::tempdir().unwrap();
    let mut renderer = Renderer::new().unwrap();

    // The full run, in sequence, writing checkpoints.
    let full = RenderJob::prepare(&scene).unwrap();
    full.use_checkpoints(checkpoints.path()).unwrap();
    full.upload_textures(&mut renderer).unwrap();
    let mut previous = None;
    let mut expected = Vec::new();
    for frame in 1..=48 {
        let mut refracted = full.refract(frame, w, h, previous.as_ref()).unwrap();
        let rendered = full
            .render_refracted(&mut renderer, &mut refracted, w, h)
            .unwrap();
        if frame >= 40 {
            expected.push((bits(&rendered), refracted.counts));
        }
        previous = Some(refracted.tracking);
    }
    let simulation = full.dynamics.simulation.as_ref().expect("ripples are on");
    let ripples_at_40 = simulation
        .store()
        .unwrap()
        .load(40, simulation.settings())
        .expect("the full run checkpointed frame 40");
    assert!(
        ripples_at_40.max_abs_height_m() > 1e-4,
        "the fox made ripples by frame 40 (else this test checks nothing)"
    );

    // Alone, without checkpoints; then a new job resuming from the checkpoints.
    let alone = RenderJob::prepare(&scene).unwrap();
    let resumed = RenderJob::prepare(&scene).unwrap();
    resumed.use_checkpoints(checkpoints.path()).unwrap();
    for (job, how) in [(&alone, "alone"), (&resumed, "from checkpoints")] {
        for (frame, (pixels, counts)) in (40..=48).zip(&expected) {
            let (refracted, rendered) = job.render_frame(&mut renderer, frame, w, h).unwrap();
            assert!(
                bits(&rendered) == *pixels,
                "frame {frame} rendered {how} differs from the full run"
            );
            assert_eq!(
                refracted.counts, *counts,
                "frame {frame} {how}: flag counts"
            );
        }
    }
    let resumed_simulation = resumed.dynamics.simulation.as_ref().unwrap();
    assert_eq!(
        resumed_simulation.frames_stepped(),
        0,
        "the resumed job read every state from checkpoints"
    );
}
