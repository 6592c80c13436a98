//! The same inputs give the same bytes: a frame rendered twice, and a frame rendered alone versus
//! inside a sequence (popping is judged against frame t-1 recomputed), are identical.

use std::path::Path;

use snell::draw::RenderedFrame;
use snell::frame::RenderJob;
use snell::gpu::Renderer;

/// Every layer of a frame as bits.
fn bits(frame: &RenderedFrame) -> Vec<Vec<u32>> {
    let floats = |values: &[f32]| values.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
    vec![
        floats(frame.beauty_rgba.as_flattened()),
        floats(&frame.depth_m),
        floats(&frame.apparent_depth_m),
        floats(frame.position.as_flattened()),
        frame.flags.clone(),
        frame.object.clone(),
        floats(&frame.water_matte),
        floats(frame.water_reflection.as_flattened()),
    ]
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

/// A frame's EXR is the same bytes run to run: the header holds no time or user unless asked.
/// `--owner` writes `owner`, and `SOURCE_DATE_EPOCH` writes `capDate` (that time, UTC) and
/// `utcOffset`, so a stamped render is reproducible too.
#[test]
fn exr_files_are_byte_identical_run_to_run_with_or_without_owner_and_date() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tiny.toml");
    let render = |out: &str, stamped: bool| {
        let out_dir = dir.path().join(out);
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_snell"));
        command.args([
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "2",
            "--size",
            "64x36",
        ]);
        command
            .arg("--out")
            .arg(&out_dir)
            .env_remove("SOURCE_DATE_EPOCH");
        if stamped {
            command
                .args(["--owner", "Studio Ü"])
                .env("SOURCE_DATE_EPOCH", "1700000000");
        }
        let output = command.output().unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let path = out_dir.join("tiny.0002.exr");
        (std::fs::read(&path).unwrap(), path)
    };
    let (plain_a, plain_path) = render("a", false);
    let (plain_b, _) = render("b", false);
    assert!(plain_a == plain_b, "two plain renders differ");
    let plain = snell::output::exr::read_channels(&plain_path)
        .unwrap()
        .attributes;
    assert_eq!(
        (plain.owner, plain.capture_date, plain.utc_offset),
        (None, None, None)
    );

    let (stamped_a, stamped_path) = render("c", true);
    let (stamped_b, _) = render("d", true);
    assert!(stamped_a == stamped_b, "two stamped renders differ");
    let stamped = snell::output::exr::read_channels(&stamped_path)
        .unwrap()
        .attributes;
    // OpenEXR strings are bytes; snell writes UTF-8.
    let owner = stamped.owner.unwrap();
    assert_eq!(std::str::from_utf8(owner.as_slice()).unwrap(), "Studio Ü");
    assert_eq!(
        stamped.capture_date.unwrap().to_string(),
        "2023:11:14 22:13:20"
    );
    assert_eq!(stamped.utc_offset, Some(0.0));
}
