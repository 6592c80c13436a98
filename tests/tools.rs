//! `snell locate`, `snell compare` and `snell export` through the binary: their output against the
//! library's own answers (the brute-force image search, the flat-water bisection solution, the
//! scene's meshes and camera), and their errors on bad input (exit 2, naming the file).

mod common;
use common::{snell, TINY};

use std::path::{Path, PathBuf};
use std::process::Output;

use glam::Vec3;
use snell::frame::RenderJob;
use snell::refraction::flat::flat_virtual_vertex;
use snell::refraction::search::RefractionField;
use snell::refraction::virtual_geometry::{vertex_images, ImageSearch};

fn stderr_of(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn stdout_of(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn expect_exit(output: &Output, code: i32, needles: &[&str]) {
    let stderr = stderr_of(output);
    assert_eq!(output.status.code(), Some(code), "stderr:\n{stderr}");
    for needle in needles {
        assert!(
            stderr.contains(needle),
            "stderr should contain {needle:?}:\n{stderr}"
        );
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// One row of `snell locate`'s CSV.
#[derive(Debug)]
struct Row {
    point: usize,
    image: usize,
    virtual_vertex: Vec3,
    sight_point: Vec3,
    facet: u32,
    extrapolated: bool,
}

fn parse_locate_csv(text: &str) -> Vec<Row> {
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("point,image,vx,vy,vz,sx,sy,sz,facet,extrapolated")
    );
    lines
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 10, "{line}");
            let num = |i: usize| f[i].parse::<f32>().unwrap();
            Row {
                point: f[0].parse().unwrap(),
                image: f[1].parse().unwrap(),
                virtual_vertex: Vec3::new(num(2), num(3), num(4)),
                sight_point: Vec3::new(num(5), num(6), num(7)),
                facet: f[8].parse().unwrap(),
                extrapolated: f[9].parse().unwrap(),
            }
        })
        .collect()
}

fn run_locate(scene: &Path, frame: u32, points: &[Vec3], dir: &Path) -> (Vec<Row>, String) {
    let mut csv = String::from("x,y,z\n");
    for p in points {
        csv.push_str(&format!("{},{},{}\n", p.x, p.y, p.z));
    }
    let points_path = write(dir, "points.csv", &csv);
    let output = snell(
        &[
            "locate",
            scene.to_str().unwrap(),
            "--frame",
            &frame.to_string(),
            "--points",
            points_path.to_str().unwrap(),
        ],
        dir,
    );
    expect_exit(&output, 0, &[]);
    (parse_locate_csv(&stdout_of(&output)), stderr_of(&output))
}

/// Points under tiny.toml's wavy water (on the ball, on the floor, near the walls), one above the
/// water and one outside its extent: the CLI prints exactly the images the brute-force search
/// finds through the same frame's field, the drawn one among them bit for bit.
#[test]
fn locate_matches_the_brute_force_search_of_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY);
    let mut points = vec![
        Vec3::new(0.2, -0.6, 0.1),
        Vec3::new(0.2, -0.4, 0.1),
        Vec3::new(-0.5, -0.79, 0.6),
        Vec3::new(0.9, -0.3, 0.95),
        Vec3::new(0.0, 0.5, 0.0),  // above the water
        Vec3::new(3.0, -0.5, 0.0), // outside the water's extent
    ];
    for i in 0..20 {
        let f = i as f32 / 19.0;
        points.push(Vec3::new(-0.9 + 1.8 * f, -0.05 - 0.7 * f, 0.8 - 1.6 * f));
    }
    let frame = 2;
    let (rows, stderr) = run_locate(&scene, frame, &points, dir.path());
    assert!(
        stderr.contains("point 4 (0, 0.5, 0) is 0.") && stderr.contains("above the water surface"),
        "{stderr}"
    );
    assert!(
        stderr.contains("point 5 (3, -0.5, 0) is outside the water's extent"),
        "{stderr}"
    );

    let job = RenderJob::prepare(&scene).unwrap();
    let mut stage_secs = Default::default();
    let water = job.frame_water(frame, &mut stage_secs).unwrap();
    let heights = water.surface();
    let surface = water.exact_surface(&heights);
    let setup = job.refraction_setup(water.camera.eye);
    let field = RefractionField::build(&water.membrane, &surface, setup, (-1.0, 0.2));
    let mut scratch = Vec::new();
    let mut images_seen = 0;
    for (index, &point) in points.iter().enumerate() {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.point == index).collect();
        assert!(
            mine.iter().enumerate().all(|(k, r)| r.image == k),
            "images numbered from 0 in order"
        );
        if index == 4 || index == 5 {
            assert!(mine.is_empty(), "point {index} has no refracted image");
            continue;
        }
        let expected = vertex_images(&field, point, ImageSearch::BruteForce, &mut scratch);
        assert_eq!(mine.len() as u32, expected.image_count, "point {index}");
        for (row, image) in mine.iter().zip(&scratch) {
            assert_eq!(row.facet, image.facet, "point {index}");
            assert_eq!(row.sight_point, image.sight_point, "point {index}");
            assert_eq!(row.extrapolated, image.extrapolated, "point {index}");
        }
        if let Some(chosen) = expected.chosen {
            let drawn = mine
                .iter()
                .find(|r| r.facet == chosen.facet)
                .expect("the drawn image is printed");
            assert_eq!(
                drawn.virtual_vertex, chosen.virtual_position,
                "point {index}"
            );
        }
        images_seen += mine.len();
    }
    assert!(
        images_seen >= 20,
        "most points under the water have an image ({images_seen})"
    );
}

/// Flat water (tiny.toml without its wave): every image is the exact one of the bisection solution
/// (refraction/flat.rs) to within the linear cells' error, which is second order in the facet
/// size; at 64x64 cells over 2 m it is well under a millimetre.
#[test]
fn locate_on_flat_water_matches_the_exact_solution() {
    let dir = tempfile::tempdir().unwrap();
    let flat = TINY
        .replace(
            "[[water.wave]]\namplitude_m = 0.02\nwavelength_m = 1.0\ndirection_deg = 30\n",
            "",
        )
        .replace("resolution = [16, 16]", "resolution = [64, 64]");
    assert!(!flat.contains("[[water.wave]]"));
    let scene = write(dir.path(), "flat.toml", &flat);
    let mut points = Vec::new();
    for i in 0..7 {
        for j in 0..5 {
            points.push(Vec3::new(
                -0.8 + 0.26 * i as f32,
                -0.05 - 0.15 * j as f32,
                -0.7 + 0.23 * (i + j) as f32 / 2.0,
            ));
        }
    }
    let (rows, stderr) = run_locate(&scene, 1, &points, dir.path());
    assert!(!stderr.contains("no image"), "{stderr}");
    let job = RenderJob::prepare(&scene).unwrap();
    let camera = job.camera_at(1);
    let (n_above, n_below) = (job.scene.water.n_above, job.scene.water.n_below);
    let mut worst_m: f64 = 0.0;
    for (index, &point) in points.iter().enumerate() {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.point == index).collect();
        assert_eq!(
            mine.len(),
            1,
            "flat water: exactly one image of point {index}"
        );
        let (exact, _) = flat_virtual_vertex(
            camera.eye.as_dvec3(),
            point.as_dvec3(),
            job.scene.water.level_m,
            n_above,
            n_below,
        );
        let row = mine[0];
        assert!(!row.extrapolated);
        assert!(
            (row.sight_point.y as f64 - job.scene.water.level_m).abs() < 1e-6,
            "the sight point is on the flat surface: {}",
            row.sight_point
        );
        worst_m = worst_m.max((row.virtual_vertex.as_dvec3() - exact).length());
    }
    // Measured: 1.5e-5 m at 64x64 cells: the cells interpolate the rays linearly across a facet
    // (an error second order in the facet size, tested in refraction/virtual_geometry.rs).
    eprintln!("flat water: largest distance to the exact virtual vertex {worst_m:.3e} m");
    assert!(
        worst_m < 5e-5,
        "largest distance to the exact virtual vertex {worst_m} m"
    );
    assert!(
        worst_m > 0.0,
        "two different computations agree to the last bit? suspicious"
    );
}

#[test]
fn locate_bad_input_is_exit_2_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY);
    let points = write(
        dir.path(),
        "points.csv",
        "x,y,z\n0.1,-0.5,0.2\n0.1;-0.5;0.2\n",
    );
    let run = |points: &Path, frame: &str| {
        snell(
            &[
                "locate",
                scene.to_str().unwrap(),
                "--frame",
                frame,
                "--points",
                points.to_str().unwrap(),
            ],
            dir.path(),
        )
    };
    expect_exit(
        &run(&points, "1"),
        2,
        &[&format!(
            "{}:3: expected three comma-separated numbers",
            points.display()
        )],
    );
    let missing = dir.path().join("missing.csv");
    expect_exit(
        &run(&missing, "1"),
        2,
        &["missing.csv", "cannot read the points file"],
    );
    let good = write(dir.path(), "good.csv", "0.1,-0.5,0.2\n");
    expect_exit(&run(&good, "9"), 2, &["--frame 9", "from frame 1 to 3"]);
}

/// Renders tiny.toml frames 1-2 at `size` into `out`.
fn render(scene: &Path, out: &Path, size: &str, cwd: &Path) {
    let output = snell(
        &[
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "1-2",
            "--out",
            out.to_str().unwrap(),
            "--size",
            size,
        ],
        cwd,
    );
    expect_exit(&output, 0, &[]);
}

#[test]
fn compare_of_a_frame_with_itself_is_zero_and_bad_input_is_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY);
    let out = dir.path().join("out");
    render(&scene, &out, "96x54", dir.path());
    let frame1 = out.join("tiny.0001.exr");
    let frame2 = out.join("tiny.0002.exr");
    let compare = |a: &Path, b: &Path, extra: &[&str]| {
        let mut args = vec!["compare", a.to_str().unwrap(), b.to_str().unwrap()];
        args.extend_from_slice(extra);
        snell(&args, dir.path())
    };

    let output = compare(&frame1, &frame1, &["--json"]);
    expect_exit(&output, 0, &[]);
    let json: serde_json::Value = serde_json::from_str(&stdout_of(&output)).unwrap();
    for direction in ["a_to_b", "b_to_a", "both"] {
        for subset in ["all", "outside_flagged", "outside_fold_band"] {
            for figure in ["mean_px", "p99_px", "max_px", "over_1px_fraction"] {
                assert_eq!(
                    json[direction][subset][figure], 0.0,
                    "{direction}.{subset}.{figure}: {json}"
                );
            }
            assert_eq!(json[direction][subset]["unseen"], 0, "{json}");
        }
    }
    assert!(
        json["a_to_b"]["all"]["counted"].as_u64().unwrap() > 1000,
        "{json}"
    );
    assert_eq!(
        json["both"]["all"]["counted"].as_u64().unwrap(),
        2 * json["a_to_b"]["all"]["counted"].as_u64().unwrap()
    );
    assert_eq!(json["flip_mean"], 0.0);
    assert_eq!(json["object_mismatch_fraction"], 0.0);

    // Consecutive frames: the wave moves the under-water image, so the error is not zero, and
    // the text report carries every figure.
    let output = compare(&frame1, &frame2, &[]);
    expect_exit(&output, 0, &[]);
    let text = stdout_of(&output);
    for needle in [
        "where both see the same object",
        "A -> B all",
        "B -> A all",
        "outside flagged pixels",
        "outside the fold band",
        "fold band",
        "beauty FLIP mean",
        "pixels whose seen object differs",
    ] {
        assert!(text.contains(needle), "{needle:?} in\n{text}");
    }
    let output = compare(&frame1, &frame2, &["--json"]);
    let json: serde_json::Value = serde_json::from_str(&stdout_of(&output)).unwrap();
    let mean = json["a_to_b"]["all"]["mean_px"].as_f64().unwrap();
    assert!(mean > 0.0 && mean < 8.0, "{json}");
    assert!(json["flip_mean"].as_f64().unwrap() > 0.0);

    // --flags-from chooses whose flags define "flagged", and the report says which and why.
    for side in ["A", "B"] {
        let output = compare(&frame1, &frame2, &["--json", "--flags-from", side]);
        expect_exit(&output, 0, &[]);
        let json: serde_json::Value = serde_json::from_str(&stdout_of(&output)).unwrap();
        assert_eq!(json["flags_from"], side, "{json}");
        let reason = json["flags_reason"].as_str().unwrap_or_default();
        assert!(reason.contains("--flags-from"), "{side}: {json}");
    }
    let text = stdout_of(&compare(&frame1, &frame2, &["--flags-from", "A"]));
    assert!(text.contains("--flags-from"), "the table says why:\n{text}");
    expect_exit(
        &compare(&frame1, &frame2, &["--flags-from", "C"]),
        2,
        &["choose A"],
    );

    expect_exit(
        &compare(&frame1, &dir.path().join("nope.exr"), &[]),
        2,
        &["nope.exr: no such file"],
    );
    let not_exr = write(dir.path(), "fake.exr", "this is not an OpenEXR file\n");
    expect_exit(
        &compare(&not_exr, &frame1, &[]),
        2,
        &["fake.exr: cannot be read as a snell EXR frame"],
    );
    // A frame written before the object layer existed cannot say which object a pixel sees.
    let (mut old, meta) = snell::output::read_frame_exr(&frame1).unwrap();
    old.object.clear();
    let old_path = dir.path().join("old.exr");
    let old_meta = snell::output::FrameMeta {
        extra: vec![],
        ..snell::output::FrameMeta::from_read(&meta, "tiny")
    };
    snell::output::write_frame_exr(&old_path, &old, &old_meta).unwrap();
    expect_exit(
        &compare(&frame1, &old_path, &[]),
        2,
        &[
            "old.exr: has no `IndexOB` layer (IndexOB.X)",
            "render the frame again with --layers all",
        ],
    );
    let small = dir.path().join("small");
    render(&scene, &small, "48x27", dir.path());
    expect_exit(
        &compare(&frame1, &small.join("tiny.0001.exr"), &[]),
        2,
        &["is 96x54 but", "is 48x27", "same size"],
    );
}

/// `v`, `vt`, `vn`, `f` and `o` lines of an OBJ, and the first vertex of each object.
struct ParsedObj {
    vertices: Vec<Vec3>,
    texcoords: usize,
    normals: usize,
    faces: Vec<[usize; 3]>,
    objects: Vec<(String, usize)>,
}

fn parse_obj(text: &str) -> ParsedObj {
    let mut parsed = ParsedObj {
        vertices: vec![],
        texcoords: 0,
        normals: 0,
        faces: vec![],
        objects: vec![],
    };
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let xyz: Vec<f32> = words.map(|w| w.parse().unwrap()).collect();
                parsed.vertices.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
            Some("vt") => parsed.texcoords += 1,
            Some("vn") => parsed.normals += 1,
            Some("f") => {
                let corners: Vec<usize> = words
                    .map(|w| {
                        let parts: Vec<&str> = w.split('/').collect();
                        assert_eq!(parts.len(), 3, "v/vt/vn: {w}");
                        assert!(parts.iter().all(|p| p == &parts[0]));
                        parts[0].parse().unwrap()
                    })
                    .collect();
                parsed.faces.push([corners[0], corners[1], corners[2]]);
            }
            Some("o") => parsed
                .objects
                .push((words.next().unwrap().to_string(), parsed.vertices.len())),
            _ => {}
        }
    }
    parsed
}

/// `snell export SCENE --frame 2 --out OUT EXTRA...`, run in `cwd`.
fn export(scene: &Path, out: &Path, extra: &[&str], cwd: &Path) -> Output {
    let mut args = vec![
        "export",
        scene.to_str().unwrap(),
        "--frame",
        "2",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    snell(&args, cwd)
}

#[test]
fn export_writes_the_frames_geometry_and_camera() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY);
    let out = dir.path().join("export");
    let frame = 2;
    let output = export(&scene, &out, &["--size", "640x360"], dir.path());
    expect_exit(&output, 0, &[]);

    let job = RenderJob::prepare(&scene).unwrap();
    let mut stage_secs = Default::default();
    let water = job.frame_water(frame, &mut stage_secs).unwrap();
    let obj = parse_obj(&std::fs::read_to_string(out.join("tiny.0002.obj")).unwrap());
    let expected_vertices = water.membrane.positions.len()
        + water
            .objects
            .iter()
            .map(|o| o.mesh.positions.len())
            .sum::<usize>();
    let expected_faces = water.membrane.triangles.len()
        + water
            .objects
            .iter()
            .map(|o| o.mesh.triangles.len())
            .sum::<usize>();
    assert_eq!(obj.vertices.len(), expected_vertices);
    assert_eq!(obj.texcoords, expected_vertices);
    assert_eq!(obj.normals, expected_vertices);
    assert_eq!(obj.faces.len(), expected_faces);
    assert!(obj
        .faces
        .iter()
        .flatten()
        .all(|&i| i >= 1 && i <= expected_vertices));
    let names: Vec<&str> = obj.objects.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names.len(), 1 + water.objects.len(), "{names:?}");
    assert_eq!(names[0], "water");
    assert!(names.contains(&"ball"), "{names:?}");
    // Every vertex equals the library's, object by object (f32 printed to round trip).
    let mut expected_positions: Vec<Vec3> = water.membrane.positions.clone();
    for object in water.objects.iter() {
        expected_positions.extend_from_slice(&object.mesh.positions);
    }
    assert_eq!(obj.vertices, expected_positions);
    let ball = water.objects.iter().position(|o| o.name == "ball").unwrap();
    let ball_start = obj.objects[1 + ball].1;
    assert_eq!(
        obj.vertices[ball_start],
        water.objects[ball].mesh.positions[0]
    );
    // The moving water is the frame's, not frame 1's.
    let frame1 = job.frame_water(1, &mut stage_secs).unwrap();
    assert_ne!(frame1.membrane.positions, water.membrane.positions);

    let mtl = std::fs::read_to_string(out.join("tiny.0002.mtl")).unwrap();
    assert_eq!(mtl.matches("newmtl ").count(), names.len());
    for line in mtl.lines().filter(|l| l.starts_with("map_Kd ")) {
        let file = out.join(line.trim_start_matches("map_Kd "));
        let image = image::open(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        assert!(image.width() > 0);
    }
    assert!(mtl.contains("map_Kd textures/"), "{mtl}");

    let camera_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("camera.json")).unwrap()).unwrap();
    let camera = job.camera_at(frame);
    let array = |key: &str| -> Vec<f32> {
        camera_json[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap() as f32)
            .collect()
    };
    assert_eq!(array("eye"), camera.eye.to_array());
    assert_eq!(array("target"), camera.target.to_array());
    assert_eq!(array("up"), camera.up.to_array());
    assert_eq!(
        camera_json["fov_y_deg"].as_f64().unwrap() as f32,
        camera.fov_y_deg
    );
    assert_eq!(camera_json["width"], 640);
    assert_eq!(camera_json["height"], 360);
    assert_eq!(
        array("clip_from_world"),
        camera.clip_from_world(640, 360).to_cols_array()
    );
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");

    // PLY: one file per object with the same counts.
    let ply_dir = dir.path().join("ply");
    let output = export(&scene, &ply_dir, &["--format", "ply"], dir.path());
    expect_exit(&output, 0, &[]);
    let mut ply_vertices = 0;
    let mut ply_files = 0;
    for entry in std::fs::read_dir(&ply_dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "ply") {
            ply_files += 1;
            let text = std::fs::read_to_string(&path).unwrap();
            let count: usize = text
                .lines()
                .find_map(|l| l.strip_prefix("element vertex "))
                .unwrap()
                .parse()
                .unwrap();
            ply_vertices += count;
        }
    }
    assert_eq!(ply_files, names.len());
    assert_eq!(ply_vertices, expected_vertices);
}

#[test]
fn export_bad_input_is_exit_2_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write(dir.path(), "tiny.toml", TINY);
    let blocker = write(dir.path(), "blocker", "a file, not a directory");
    let out = blocker.join("export");
    expect_exit(&export(&scene, &out, &[], dir.path()), 2, &["blocker"]);
    let output = export(&scene, Path::new("x"), &["--format", "fbx"], dir.path());
    expect_exit(&output, 2, &["--format \"fbx\"", "obj", "ply"]);
}

/// The metric on real renders, against a known answer: the camera turned about its eye by a small
/// yaw. The eye does not move, so the refraction (virtual geometry) is the same and every pixel's
/// ray only turns: the true displacement of each pixel is where camera B projects the direction
/// of A's ray through that pixel's centre (about 0.3 px at the centre, more toward the sides).
/// The measured mean and p99 must match the true ones far below the 0.1 px the issue asks to
/// resolve.
#[test]
fn compare_measures_a_known_camera_turn_on_real_renders() {
    use snell::output::position_error::position_error;
    let dir = tempfile::tempdir().unwrap();
    let (width, height) = (320u32, 180u32);
    let scene_a = write(dir.path(), "a.toml", TINY);
    let job_a = RenderJob::prepare(&scene_a).unwrap();
    let camera_a = job_a.camera_at(1);
    let focal_px = height as f64 / 2.0 / (camera_a.fov_y_deg as f64 / 2.0).to_radians().tan();
    let yaw = (0.3 / focal_px).atan() as f32;
    let target_b =
        camera_a.eye + glam::Quat::from_rotation_y(yaw) * (camera_a.target - camera_a.eye);
    let text_b = TINY.replace(
        "target = [0.0, -0.6, 0.3]",
        &format!("target = [{}, {}, {}]", target_b.x, target_b.y, target_b.z),
    );
    assert_ne!(text_b, TINY);
    let scene_b = write(dir.path(), "b.toml", &text_b);
    let size = format!("{width}x{height}");
    for (scene, out) in [(&scene_a, "ra"), (&scene_b, "rb")] {
        let output = snell(
            &[
                "render",
                scene.to_str().unwrap(),
                "--frames",
                "1",
                "--out",
                out,
                "--size",
                &size,
            ],
            dir.path(),
        );
        expect_exit(&output, 0, &[]);
    }
    let read = |path: PathBuf| snell::output::read_frame_exr(&path).unwrap().0;
    let a = read(dir.path().join("ra/tiny.0001.exr"));
    let b = read(dir.path().join("rb/tiny.0001.exr"));
    let camera_b = RenderJob::prepare(&scene_b).unwrap().camera_at(1);
    assert_eq!(camera_a.eye, camera_b.eye);

    // The true displacement of every pixel where both frames see the same object.
    let mut truth: Vec<f64> = Vec::new();
    for y in 0..height {
        for x in 0..width {
            let index = (y * width + x) as usize;
            if a.object[index] == 0 || a.object[index] != b.object[index] {
                continue;
            }
            let centre = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let ray = camera_a.ray_through_pixel(centre, width, height).as_dvec3();
            let far = camera_a.eye.as_dvec3() + ray * 10.0;
            let moved = camera_b.pixel_of(far.as_vec3(), width, height).unwrap();
            truth.push((moved - centre).as_dvec2().length());
        }
    }
    truth.sort_by(f64::total_cmp);
    let true_mean = truth.iter().sum::<f64>() / truth.len() as f64;
    let true_p99 = truth[(truth.len() as f64 * 0.99).ceil() as usize - 1];

    let measured = position_error(&a, &b).unwrap();
    assert_eq!(measured.counted, truth.len());
    eprintln!(
        "camera turn: true mean {true_mean:.4} px p99 {true_p99:.4} px; measured mean {:.4} px p99 {:.4} px max {:.4} px",
        measured.mean_px, measured.p99_px, measured.max_px
    );
    assert!(
        true_mean > 0.25,
        "the turn moves pixels by about 0.3 px: {true_mean}"
    );
    assert!(
        (measured.mean_px - true_mean).abs() < 0.01,
        "mean {} vs true {true_mean}",
        measured.mean_px
    );
    assert!(
        (measured.p99_px - true_p99).abs() < 0.01,
        "p99 {} vs true {true_p99}",
        measured.p99_px
    );
}

/// A scene with a character: the exported fox is the fox posed at that frame (and differs from
/// its pose a few frames later), the water carries its ripples' frame.
#[test]
fn export_poses_characters_at_the_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/fox_wading.toml");
    let out = dir.path().join("fox");
    expect_exit(&export(&scene, &out, &[], dir.path()), 0, &[]);
    let obj = parse_obj(&std::fs::read_to_string(out.join("fox_wading.0002.obj")).unwrap());
    let job = RenderJob::prepare(&scene).unwrap();
    let mut stage_secs = Default::default();
    let water = job.frame_water(2, &mut stage_secs).unwrap();
    let character = water.objects.len() - 1;
    assert!(
        water.objects[character].name.starts_with("fox"),
        "the last object is the posed fox: {}",
        water.objects[character].name
    );
    let start = obj.objects[1 + character].1;
    let fox = &water.objects[character].mesh.positions;
    assert_eq!(&obj.vertices[start..start + fox.len()], &fox[..]);
    let later = job.frame_water(6, &mut stage_secs).unwrap();
    assert_ne!(
        &later.objects[character].mesh.positions, fox,
        "the fox moves: the export is of frame 2's pose"
    );
    let mut expected_positions = water.membrane.positions.clone();
    for object in water.objects.iter() {
        expected_positions.extend_from_slice(&object.mesh.positions);
    }
    assert_eq!(obj.vertices, expected_positions);
}
