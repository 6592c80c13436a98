//! The fuzz corpus (issue 19 point 5): 520 cases generated from the shipped scenes, models and a
//! rendered frame with a fixed seed (`tests/fuzz/mod.rs` says how), plus at least one case for
//! every example of the table, each run against the real `snell` binary under a timeout
//! and a 4 GiB address-space cap. Every command must answer exit 0 or 2 (`diff`, `check`,
//! `compare`: their documented codes), never a panic, a signal, a hang or an allocation failure,
//! and a frame written with exit 0 must hold only finite samples.
//!
//! A failing case is kept under the printed folder with its files; its name says which shipped
//! file it mutated and how. `FUZZ_SEED=N` runs another seed, `FUZZ_CASES=N` another count.

mod fuzz;
use fuzz::{character_scene, huge_png, Case, Expect, Sink, Step};
use std::time::Instant;

const SEED: u64 = 19_005;
const GENERATED: usize = 520;

fn tiny() -> String {
    std::fs::read_to_string(fuzz::repo().join("scenes/tiny.toml")).unwrap()
}

fn edit(from: &str, to: &str) -> String {
    let t = tiny();
    assert!(t.contains(from), "tiny.toml no longer contains {from:?}");
    t.replacen(from, to, 1)
}

fn scene_row(name: &str, text: String) -> Case {
    let mut case = Case {
        name: format!("row {name}"),
        ..Case::default()
    };
    case.files.push(("scene.toml".into(), text.into_bytes()));
    case.fifos.push("fifo".into());
    case.steps
        .push(step(&["info", "scene.toml"], Expect::Scene));
    case.steps.push(step(
        &[
            "render",
            "scene.toml",
            "--out",
            "out",
            "--size",
            "16x16",
            "--frames",
            "1",
        ],
        Expect::Scene,
    ));
    case.renders = true;
    case
}

/// Both of the case's commands must refuse it with these words.
fn refused(case: &mut Case, needles: &[&str]) {
    for s in &mut case.steps {
        s.expect = Expect::Refused(needles.iter().map(|n| n.to_string()).collect());
    }
}

fn step(args: &[&str], expect: Expect) -> Step {
    Step {
        args: args.iter().map(|s| s.to_string()).collect(),
        stdout: Sink::Piped,
        expect,
    }
}

/// step.gltf (a two-joint rig with one animation) with `edit` applied to its JSON.
fn model_row(name: &str, edit: impl FnOnce(&mut serde_json::Value), extra: &str) -> Case {
    let path = fuzz::repo().join("tests/gltf/step.gltf");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    edit(&mut json);
    let mut case = scene_row(name, character_scene("model.gltf", 0.3, extra));
    case.files
        .push(("model.gltf".into(), serde_json::to_vec(&json).unwrap()));
    case.files.push(("huge.png".into(), huge_png()));
    case
}

/// One case (or more) for every example of the table.
fn table_rows(base_frame: &[u8]) -> Vec<Case> {
    use serde_json::json;
    let mut rows = Vec::new();
    // panics (exit 101)
    let mut big = scene_row("panics: --size above the readback buffer", tiny());
    big.steps[1].args[5] = "4000x3000".into();
    rows.push(big);
    let mut node = model_row(
        "panics: animation channel target.node out of range",
        |j| j["animations"][0]["channels"][0]["target"]["node"] = json!(99),
        "animation = 0\n",
    );
    refused(
        &mut node,
        &[
            "scene.toml:",
            "character[0].file",
            "animations[0].channels[0].target.node",
            "node 99 of 4",
        ],
    );
    rows.push(node);
    let mut path = model_row(
        "panics: animation channel target.path invalid",
        |j| j["animations"][0]["channels"][1]["target"]["path"] = json!("bogus"),
        "animation = 0\n",
    );
    refused(
        &mut path,
        &["scene.toml:", "animations[0].channels[1].target.path"],
    );
    rows.push(path);
    rows.push(model_row(
        "panics: animation channel target.path weights without morph targets",
        |j| j["animations"][0]["channels"][2]["target"]["path"] = json!("weights"),
        "animation = 0\n",
    ));
    rows.push(scene_row(
        "panics: a camera key looking straight down",
        edit("eye = [0.0, 1.8, -2.2]", "eye = [0.0, 3.0, 0.3]"),
    ));
    rows.push(scene_row(
        "panics: an eye value overflowing f32",
        edit("eye = [0.0, 1.8, -2.2]", "eye = [0.0, 1e39, -2.2]"),
    ));
    for (sink, name, codes) in [
        (Sink::ClosedPipe, "panics: snell info | true", vec![1]),
        (Sink::DevFull, "panics: snell info > /dev/full", vec![1]),
    ] {
        let mut case = Case {
            name: format!("row {name}"),
            ..Case::default()
        };
        case.files.push(("tiny.toml".into(), tiny().into_bytes()));
        let mut s = step(&["info", "tiny.toml"], Expect::Codes(codes));
        s.stdout = sink;
        case.steps.push(s);
        let mut s = step(
            &[
                "render",
                "tiny.toml",
                "--out",
                "out",
                "--size",
                "16x16",
                "--frames",
                "1",
            ],
            Expect::Codes(vec![0]),
        );
        s.stdout = sink;
        case.steps.push(s);
        case.renders = true;
        rows.push(case);
    }
    // silently wrong, exit 0
    rows.push(scene_row(
        "silently wrong: two legal camera keys passing over the target",
        edit(
            "[[camera]]\neye = [0.0, 1.8, -2.2]\ntarget = [0.0, -0.6, 0.3]\nfov_deg = 50\n",
            "[[camera]]\nframe = 1\neye = [-2.0, 1.0, 0.3]\ntarget = [0.0, -0.6, 0.3]\n\n\
             [[camera]]\nframe = 3\neye = [2.0, 1.0, 0.3]\ntarget = [0.0, -0.6, 0.3]\n",
        ),
    ));
    rows.push(scene_row(
        "silently wrong: absorption_per_m 1e39",
        edit(
            "resolution = [16, 16]",
            "resolution = [16, 16]\nabsorption_per_m = [1e39, 0.1, 0.1]",
        ),
    ));
    rows.push(scene_row(
        "silently wrong: sun intensity 1e39",
        format!("{}\n[sun]\nintensity = 1e39\n", tiny()),
    ));
    rows.push(scene_row(
        "silently wrong: a checker square of 1e-50",
        edit("square_m = 0.15", "square_m = 1e-50"),
    ));
    let mut nan = Case {
        name: "row silently wrong: snell diff given a NaN beauty pixel".into(),
        ..Case::default()
    };
    nan.files
        .push(("golden/tiny.0001.exr".into(), base_frame.to_vec()));
    nan.files.push((
        "test/tiny.0001.exr".into(),
        fuzz::frame_with_sample(base_frame, "R", 100, f32::NAN),
    ));
    nan.steps.push(step(
        &[
            "diff",
            "golden/tiny.0001.exr",
            "test/tiny.0001.exr",
            "--heatmaps",
            "heat",
        ],
        Expect::NotPass,
    ));
    nan.steps.push(step(
        &["diff", "golden", "test", "--heatmaps", "heat"],
        Expect::NotPass,
    ));
    nan.steps.push(step(
        &[
            "check",
            "tiny.toml",
            "--golden",
            "test",
            "--frames",
            "1",
            "--out",
            "out",
        ],
        Expect::NotPass,
    ));
    nan.files.push(("tiny.toml".into(), tiny().into_bytes()));
    nan.renders = true;
    rows.push(nan);
    // memory exhausted
    rows.push(scene_row(
        "memory exhausted: the maximum membrane 8192^2",
        edit("resolution = [16, 16]", "resolution = [8192, 8192]"),
    ));
    rows.push(scene_row(
        "memory exhausted: a 300 m box",
        format!(
            "{}\n[[object]]\nshape = \"box\"\nsize_m = [300.0, 300.0, 300.0]\n",
            tiny()
        ),
    ));
    rows.push(scene_row(
        "memory exhausted: a 1e7 m deck",
        edit("deck_width_m = 1.0", "deck_width_m = 1e7"),
    ));
    rows.push(scene_row(
        "memory exhausted: a 1e6 m sphere",
        edit("radius_m = 0.2", "radius_m = 1e6"),
    ));
    rows.push(scene_row(
        "memory exhausted: scale 1e30",
        edit(
            "radius_m = 0.2",
            "radius_m = 0.2\nscale = [1e30, 1e30, 1e30]",
        ),
    ));
    rows.push(scene_row(
        "memory exhausted: a water extent of 1e12",
        edit("max = [1.0, 1.0]", "max = [1e12, 1e12]"),
    ));
    rows.push(model_row(
        "memory exhausted: a buffer URI of /dev/zero",
        |j| j["buffers"][0]["uri"] = json!("/dev/zero"),
        "",
    ));
    rows.push(model_row(
        "memory exhausted: an image URI of /dev/zero",
        |j| {
            j["images"] = json!([{ "uri": "/dev/zero" }]);
            j["textures"] = json!([{ "source": 0 }]);
            j["materials"] =
                json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
            j["meshes"][0]["primitives"][0]["material"] = json!(0);
        },
        "",
    ));
    rows.push(model_row(
        "memory exhausted: an image of 65535x65535",
        |j| {
            j["images"] = json!([{ "uri": "huge.png" }]);
            j["textures"] = json!([{ "source": 0 }]);
            j["materials"] =
                json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
            j["meshes"][0]["primitives"][0]["material"] = json!(0);
        },
        "",
    ));
    let mut zero = Case {
        name: "row memory exhausted: the scene path /dev/zero".into(),
        ..Case::default()
    };
    zero.steps
        .push(step(&["info", "/dev/zero"], Expect::Codes(vec![2])));
    zero.steps.push(step(
        &[
            "render",
            "/dev/zero",
            "--out",
            "out",
            "--size",
            "16x16",
            "--frames",
            "1",
        ],
        Expect::Codes(vec![2]),
    ));
    rows.push(zero);
    // hangs
    rows.push(model_row(
        "hangs: a buffer URI that is a FIFO",
        |j| j["buffers"][0]["uri"] = json!("fifo"),
        "",
    ));
    let mut fifo = Case {
        name: "row hangs: the scene path is a FIFO".into(),
        ..Case::default()
    };
    fifo.fifos.push("scene.toml".into());
    fifo.steps
        .push(step(&["info", "scene.toml"], Expect::Codes(vec![2])));
    fifo.steps.push(step(
        &[
            "render",
            "scene.toml",
            "--out",
            "out",
            "--size",
            "16x16",
            "--frames",
            "1",
        ],
        Expect::Codes(vec![2]),
    ));
    rows.push(fifo);
    for scale in ["1e10", "1e30"] {
        let mut case = model_row(&format!("hangs: character scale {scale}"), |_| {}, "");
        let text = character_scene("model.gltf", 0.3, "")
            .replace("scale = 0.3", &format!("scale = {scale}"));
        case.files[0] = ("scene.toml".into(), text.into_bytes());
        rows.push(case);
    }
    let mut window = Case {
        name: "row hangs: snell compare --window 100000".into(),
        ..Case::default()
    };
    window.files.push(("a.exr".into(), base_frame.to_vec()));
    window.files.push(("b.exr".into(), base_frame.to_vec()));
    window.steps.push(step(
        &["compare", "a.exr", "b.exr", "--window", "100000"],
        Expect::Frames,
    ));
    window
        .steps
        .push(step(&["compare", "a.exr", "b.exr"], Expect::Codes(vec![0])));
    rows.push(window);
    // late or vague errors
    rows.push(scene_row(
        "late errors: frame 4294967295",
        edit("frames = [1, 3]", "frames = [1, 4294967295]"),
    ));
    let mut last = scene_row(
        "late errors: --frames 4294967295",
        edit("frames = [1, 3]", "frames = [4294967290, 4294967295]"),
    );
    last.steps[1].args[7] = "4294967295".into();
    rows.push(last);
    rows.push(scene_row(
        "late errors: a NUL in the scene name",
        edit("name = \"tiny\"", "name = \"ti\\u0000ny\""),
    ));
    rows.push(scene_row(
        "late errors: a 300-character name",
        edit(
            "name = \"tiny\"",
            &format!("name = \"{}\"", "n".repeat(300)),
        ),
    ));
    let mut latin = scene_row("vague errors: a non-UTF-8 scene", String::new());
    latin.files[0].1 = {
        let mut b = tiny().into_bytes();
        let at = b.iter().position(|&c| c == b'y').unwrap();
        b[at] = 0xe9;
        b
    };
    rows.push(latin);
    // preview: the row's examples (Host headers, worker panics, threads) are the server's, which
    // tests/preview_api.rs tests; a scene the preview cannot load is served as an error page by
    // design, so it has no case here.
    rows
}

#[test]
fn every_fuzz_case_exits_0_or_2_with_finite_frames() {
    let clock = Instant::now();
    let root = tempfile::tempdir().unwrap();
    let base_frame = fuzz::render_base_frame(root.path());
    let seed = std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SEED);
    let n = std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(GENERATED);
    let mut cases = table_rows(&base_frame);
    let rows = cases.len();
    cases.extend(fuzz::generate(seed, n, &base_frame));
    let mut names = std::collections::HashSet::new();
    for c in &cases {
        assert!(names.insert(c.name.clone()), "two cases named {}", c.name);
    }
    // Two workers: CI's two cores (lavapipe threads itself within a render).
    let workers = std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .clamp(1, 2);
    let keep = fuzz::repo().join("target/fuzz-failures");
    let (failures, mut times) = fuzz::run_all(&cases, &keep, workers);
    times.sort();
    let rendered = times.iter().filter(|t| t.1).count();
    let render_secs: f64 = times
        .iter()
        .filter(|t| t.1)
        .map(|t| t.0.as_secs_f64())
        .sum();
    eprintln!(
        "fuzz corpus: {} cases ({rows} table rows, {n} generated from seed {seed}; {rendered} \
         rendered a frame, {render_secs:.0} s of case time) in {:.1} s on {workers} workers; \
         mix {:?}; slowest: {:?}",
        cases.len(),
        clock.elapsed().as_secs_f64(),
        fuzz::mix(&cases[rows..]),
        times.iter().rev().take(3).collect::<Vec<_>>()
    );
    assert!(
        failures.is_empty(),
        "{} of {} fuzz cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    let _ = std::fs::remove_dir(&keep);
}
