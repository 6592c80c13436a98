//! Frames rendered in strips (issue 19: large images draw, read back and write a band of rows at a
//! time) against frames rendered whole, at 1280x720 forced into strips of 96 rows (7 strips and a
//! last one of 48). Issue 19's must-hold: every layer within 1e-5, in the rendered frame and in
//! every channel of the written EXR (and the written frame passes `snell diff` against the whole
//! one). The table printed (`--nocapture`) also counts the samples that are not bit-equal.
//!
//! What makes it hold (src/gpu/pulling.rs, shaders/common.inc.wgsl): Mesa's rasteriser (llvmpipe /
//! lavapipe) sets up each attribute's plane equation at the attachment's window origin, which a
//! strip moves, and rounds vertex window positions through the strip's viewport before its
//! 1/256-pixel snap. So the triangle draws pull their vertices from storage buffers: the vertex
//! stage clips each triangle itself and places its corners on the whole frame's subpixel grid
//! (w = 1), and the fragment stage interpolates every attribute, and the depth it writes, from
//! the whole frame's pixel centre. Before that, pool frame 24 had 18,321 beauty samples beyond
//! 1e-5 (largest 0.23), 4 position samples and 2 object pixels.

use std::path::Path;

use snell::draw::RenderedFrame;
use snell::frame::resume::SequenceOptions;
use snell::frame::RenderJob;
use snell::gpu::Renderer;

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 720;
const STRIP_ROWS: u32 = 96;
const TOLERANCE: f32 = 1e-5;

fn pool() -> RenderJob {
    RenderJob::prepare(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pool.toml")).unwrap()
}

/// How many samples differ by more than [`TOLERANCE`] (relative above 1: depths are metres, and a
/// float32 at 16 m steps 2e-6); all of them when the lengths differ.
fn over_tolerance(a: &[f32], b: &[f32]) -> usize {
    if a.len() != b.len() {
        return a.len().max(b.len());
    }
    a.iter()
        .zip(b)
        .filter(|(x, y)| x != y && (*x - *y).abs() > TOLERANCE * x.abs().max(1.0))
        .count()
}

fn layers(frame: &RenderedFrame) -> Vec<(&'static str, Vec<f32>)> {
    let flat4 = |v: &[[f32; 4]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    vec![
        ("beauty", flat4(&frame.beauty_rgba)),
        ("depth", frame.depth_m.clone()),
        ("apparent depth", frame.apparent_depth_m.clone()),
        (
            "position",
            frame.position.iter().flatten().copied().collect(),
        ),
        ("flags", frame.flags.iter().map(|&f| f as f32).collect()),
        ("object", frame.object.iter().map(|&o| o as f32).collect()),
        ("water matte", frame.water_matte.clone()),
        ("water reflection", flat4(&frame.water_reflection)),
        (
            "coverage",
            frame
                .coverage
                .iter()
                .flatten()
                .flat_map(|rank| [rank.key as f32, rank.coverage])
                .collect(),
        ),
    ]
}

/// How far one layer of the strips is from the whole frame's.
struct LayerDifference {
    name: &'static str,
    /// Samples whose bits differ at all.
    unequal: usize,
    /// Samples beyond [`TOLERANCE`] ([`over_tolerance`]).
    over: usize,
    /// The largest difference (relative above 1) and the frame row it is on.
    largest: f32,
    row: usize,
}

/// Pool frame 24 at 1280x720 drawn whole, and drawn in strips of [`STRIP_ROWS`] rows, compared
/// layer by layer (every layer of [`layers`]); prints the table.
fn strips_against_whole() -> Vec<LayerDifference> {
    let job = pool();
    let mut renderer = Renderer::new().unwrap();
    job.upload_textures(&mut renderer).unwrap();
    // As `snell render` draws the scene: supersampled by default (the points of a strip are the
    // whole frame's too).
    renderer
        .set_supersample(job.scene.antialias.supersample)
        .unwrap();
    assert_eq!(renderer.supersample(), 2, "pool.toml is supersampled");
    let previous = job.previous_tracking(24, WIDTH, HEIGHT).unwrap();
    let refracted = job.refract(24, WIDTH, HEIGHT, previous.as_ref()).unwrap();

    assert_eq!(
        renderer.strip_rows(WIDTH, HEIGHT),
        HEIGHT,
        "1280x720 draws whole"
    );
    let whole = renderer
        .render(&refracted.draw, &refracted.view, WIDTH, HEIGHT)
        .unwrap();

    renderer.set_strip_rows(Some(STRIP_ROWS));
    assert_eq!(renderer.strip_rows(WIDTH, HEIGHT), STRIP_ROWS);
    let mut starts = Vec::new();
    let mut strips = Vec::new();
    renderer
        .render_strips(
            &refracted.draw,
            &refracted.view,
            WIDTH,
            HEIGHT,
            |first_row, strip| {
                starts.push((first_row, strip.height));
                strips.push(strip);
                Ok::<(), snell::gpu::GpuError>(())
            },
        )
        .unwrap();
    let expected: Vec<(u32, u32)> = (0..HEIGHT)
        .step_by(STRIP_ROWS as usize)
        .map(|row| (row, STRIP_ROWS.min(HEIGHT - row)))
        .collect();
    assert_eq!(starts, expected, "strips of 96 rows, the last one 48");
    let stacked = RenderedFrame::stacked(strips);
    assert_eq!((stacked.width, stacked.height), (WIDTH, HEIGHT));
    println!("adapter: {}", renderer.adapter_summary());
    layers(&whole)
        .into_iter()
        .zip(layers(&stacked))
        .map(|((name, whole), (_, strips))| {
            assert!(!whole.is_empty(), "layer {name} is empty");
            let (largest, at) = largest_difference(&whole, &strips);
            let difference = LayerDifference {
                name,
                unequal: whole
                    .iter()
                    .zip(&strips)
                    .filter(|(a, b)| a.to_bits() != b.to_bits())
                    .count(),
                over: over_tolerance(&whole, &strips),
                largest,
                row: at / (whole.len() / HEIGHT as usize),
            };
            println!(
                "layer {name}: {} of {} samples not bit-equal, {} beyond {TOLERANCE}, largest difference {largest:e} (row {}, column {})",
                difference.unequal,
                whole.len(),
                difference.over,
                difference.row,
                at % (whole.len() / HEIGHT as usize) / (whole.len() / (WIDTH * HEIGHT) as usize)
            );
            difference
        })
        .collect()
}

/// The largest difference of `a` and `b` (relative above 1, as [`over_tolerance`] measures) and
/// the index of its sample.
fn largest_difference(a: &[f32], b: &[f32]) -> (f32, usize) {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            if x == y {
                0.0
            } else {
                (x - y).abs() / x.abs().max(1.0)
            }
        })
        .enumerate()
        .fold((0.0f32, 0usize), |(max, at), (i, d)| {
            if d > max || d.is_nan() {
                (d, i)
            } else {
                (max, at)
            }
        })
}

/// Issue 19's must-hold: every layer of [`layers`] within [`TOLERANCE`] of the whole frame's.
#[test]
fn every_layer_drawn_in_strips_is_within_1e_5_of_the_frame_drawn_whole() {
    let differences = strips_against_whole();
    assert_eq!(differences.len(), 9, "every layer compared");
    let failures: Vec<String> = differences
        .into_iter()
        .filter(|difference| difference.over > 0)
        .map(|difference| {
            format!(
                "{}: {} samples beyond {TOLERANCE}, largest {:e} at row {}",
                difference.name, difference.over, difference.largest, difference.row
            )
        })
        .collect();
    assert!(
        failures.is_empty(),
        "strips differ from the whole frame: {failures:?}"
    );
}

#[test]
fn a_frame_written_in_strips_equals_the_frame_written_whole_in_every_channel() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, strip_rows: Option<u32>| {
        let mut job = pool();
        job.strip_rows = strip_rows;
        let out_dir = dir.path().join(name);
        let output = snell::output::pattern::OutputPattern::for_scene(&out_dir, "pool");
        job.render_sequence(&SequenceOptions {
            frames: &[24],
            width: WIDTH,
            height: HEIGHT,
            output: &output,
            write_png: true,
            progress: false,
            log: snell::frame::resume::FrameLog::Quiet,
            resume: false,
            stop: None,
        })
        .unwrap();
        let exr = snell::output::exr::read_channels(&out_dir.join("pool.0024.exr")).unwrap();
        let png = image::open(out_dir.join("pool.0024.png"))
            .unwrap()
            .to_rgba8();
        (exr, png)
    };
    let (whole, whole_png) = render("whole", None);
    let (strips, strips_png) = render("strips", Some(STRIP_ROWS));
    assert_eq!(
        (strips.width, strips.height),
        (WIDTH as usize, HEIGHT as usize)
    );
    assert_eq!(
        whole.channels.keys().collect::<Vec<_>>(),
        strips.channels.keys().collect::<Vec<_>>()
    );
    // The channel map's layers, Cryptomatte ranks included, are all there.
    assert!(whole.channels.len() >= 20, "{:?}", whole.channels.keys());
    for (name, values) in &whole.channels {
        let over = over_tolerance(values, &strips.channels[name]);
        assert_eq!(
            over, 0,
            "channel {name}: {over} samples differ from the whole frame's by more than {TOLERANCE}"
        );
    }
    assert_eq!(whole_png.dimensions(), strips_png.dimensions());
    assert_eq!(whole_png.as_raw(), strips_png.as_raw(), "the PNGs differ");
    // And by the goldens' criteria (FLIP, Z and P tolerances, counts).
    let diff = std::process::Command::new(env!("CARGO_BIN_EXE_snell"))
        .arg("diff")
        .arg(dir.path().join("whole/pool.0024.exr"))
        .arg(dir.path().join("strips/pool.0024.exr"))
        .output()
        .unwrap();
    assert!(
        diff.status.success(),
        "snell diff whole strips: {}{}",
        String::from_utf8_lossy(&diff.stdout),
        String::from_utf8_lossy(&diff.stderr)
    );
}
