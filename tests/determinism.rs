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
