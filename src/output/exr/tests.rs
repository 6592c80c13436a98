use std::fs;

use glam::{Mat4, Vec3};

use super::channels::{self, SKY_DEPTH_M};
use super::*;

fn test_camera() -> Camera {
    Camera {
        eye: Vec3::new(1.0, 3.0, 8.0),
        target: Vec3::new(0.0, -1.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near_m: crate::camera::NEAR_M,
        far_m: crate::camera::FAR_M,
    }
}

fn test_meta() -> FrameMeta {
    FrameMeta {
        scene_name: "pool".into(),
        frame: 7,
        time_secs: 7.0 / 24.0,
        camera: test_camera(),
        method: "geometric".into(),
        version: crate::VERSION.into(),
        fps: 24.0,
        object_names: vec!["pool.floor".into(), "ball".into()],
        owner: None,
        capture_unix_secs: None,
        extra: vec![
            ("scene_file".into(), "scenes/pool.toml".into()),
            ("note".into(), "ünïcode ok".into()),
        ],
        write: WriteOptions::default(),
    }
}

/// A frame whose every pixel differs, with the values a render produces where nothing is seen,
/// negative zero, denormals, every flag combination, water pixels with and without an object.
fn test_frame(width: u32, height: u32) -> RenderedFrame {
    let pixel_count = (width * height) as usize;
    let mut frame = RenderedFrame {
        width,
        height,
        ..Default::default()
    };
    for i in 0..pixel_count {
        let x = i as f32;
        frame.beauty_rgba.push([
            x * 0.37,
            1.0 / (x + 1.0),
            x * 1e3,
            if i % 5 == 0 { 0.0 } else { 1.0 },
        ]);
        frame.depth_m.push(match i % 4 {
            0 => SKY_DEPTH_M,
            1 => f32::MIN_POSITIVE / 8.0,
            _ => x * 0.125 + 0.05,
        });
        frame.apparent_depth_m.push(x * 0.25 + 0.5);
        frame.position.push(match i % 3 {
            0 => [0.0; 3],
            1 => [-0.0, x, -x * 3.25],
            _ => [1e-30, 1e-40, 12345.678],
        });
        frame.flags.push((i as u32 * 7) % 16);
        frame.object.push((i as u32 * 5) % 3);
        let water = i % 7 < 3;
        frame.water_matte.push(if water { 1.0 } else { 0.0 });
        frame.water_reflection.push(if water {
            [0.01 * x, 0.02, 0.03, 0.02 + 0.001 * (i % 50) as f32]
        } else {
            [0.0; 4]
        });
    }
    frame
}

/// What a frame reads back as: all of it, but F where nothing is behind the water, which the
/// file does not keep (the water's Cryptomatte coverage is 1 there).
fn as_read_back(frame: &RenderedFrame) -> RenderedFrame {
    let mut frame = frame.clone();
    for (i, reflection) in frame.water_reflection.iter_mut().enumerate() {
        if frame.water_matte[i] > 0.5 && frame.object[i] == 0 {
            reflection[3] = 1.0;
        }
    }
    frame
}

fn assert_bit_exact(expected: &RenderedFrame, actual: &RenderedFrame) {
    assert_eq!(
        (expected.width, expected.height),
        (actual.width, actual.height)
    );
    let bits = |values: &[f32]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(expected.beauty_rgba.as_flattened()),
        bits(actual.beauty_rgba.as_flattened()),
        "beauty"
    );
    assert_eq!(bits(&expected.depth_m), bits(&actual.depth_m), "depth");
    assert_eq!(
        bits(&expected.apparent_depth_m),
        bits(&actual.apparent_depth_m),
        "apparent depth"
    );
    assert_eq!(
        bits(expected.position.as_flattened()),
        bits(actual.position.as_flattened()),
        "position"
    );
    assert_eq!(expected.flags, actual.flags, "flags");
    assert_eq!(expected.object, actual.object, "object");
    assert_eq!(
        bits(&expected.water_matte),
        bits(&actual.water_matte),
        "water matte"
    );
    assert_eq!(
        bits(expected.water_reflection.as_flattened()),
        bits(actual.water_reflection.as_flattened()),
        "water reflection"
    );
}

#[test]
fn frame_path_pads_to_four_digits() {
    assert_eq!(
        frame_path(Path::new("out"), "pool", 7),
        PathBuf::from("out/pool.0007.exr")
    );
    assert_eq!(
        frame_path(Path::new("out"), "pool", 12345),
        PathBuf::from("out/pool.12345.exr")
    );
}

#[test]
fn round_trip_is_bit_exact_with_attributes() {
    let temp = tempfile::tempdir().unwrap();
    let meta = test_meta();
    let path = frame_path(
        &temp.path().join("new-subdir"),
        &meta.scene_name,
        meta.frame,
    );
    let frame = test_frame(13, 7);
    write_frame_exr(&path, &frame, &meta).unwrap();
    let (read, read_meta) = read_frame_exr(&path).unwrap();
    assert_bit_exact(&as_read_back(&frame), &read);

    assert_eq!(read_meta.frame, 7);
    assert_eq!(read_meta.time_secs, 7.0 / 24.0);
    assert_eq!(read_meta.camera, meta.camera);
    assert_eq!(read_meta.method, "geometric");
    assert_eq!(read_meta.version, crate::VERSION);
    assert_eq!(
        read_meta.channel_map.as_deref(),
        Some(channels::CHANNEL_MAP_VERSION)
    );
    assert_eq!(read_meta.object_names, meta.object_names);
    let mut extra = meta.extra.clone();
    extra.sort();
    assert_eq!(read_meta.text_attributes, extra);
    // The camera matrix must place the eye at the origin of camera space.
    let world_from_camera = Mat4::from_cols_array(&read_meta.world_from_camera);
    assert!(world_from_camera
        .transform_point3(Vec3::ZERO)
        .abs_diff_eq(meta.camera.eye, 1e-5));
    // The standard matrix puts the target straight ahead on +Z (left-handed, OpenEXR convention).
    let camera_from_world = Mat4::from_cols_array(&read_meta.world_to_camera_standard.unwrap());
    let target_in_camera = camera_from_world.transform_point3(meta.camera.target);
    let distance = (meta.camera.target - meta.camera.eye).length();
    assert!(
        target_in_camera.abs_diff_eq(Vec3::new(0.0, 0.0, distance), 1e-4),
        "{target_in_camera}"
    );
}

#[test]
fn channel_names_and_types_are_as_the_map_says() {
    let temp = tempfile::tempdir().unwrap();
    let path = temp.path().join("frame.exr");
    write_frame_exr(&path, &test_frame(4, 3), &test_meta()).unwrap();
    let read = read_channels(&path).unwrap();
    let names: Vec<(String, &str)> = read
        .types
        .iter()
        .map(|(name, kind)| (name.clone(), *kind))
        .collect();
    let mut expected: Vec<(String, &str)> = [
        ("R", "f32"),
        ("G", "f32"),
        ("B", "f32"),
        ("A", "f32"),
        ("Z", "f32"),
        ("ApparentDepth.Z", "f32"),
        ("P.X", "f32"),
        ("P.Y", "f32"),
        ("P.Z", "f32"),
        ("IndexOB.X", "f32"),
        ("CryptoObject00.R", "f32"),
        ("CryptoObject00.G", "f32"),
        ("CryptoObject00.B", "f32"),
        ("CryptoObject00.A", "f32"),
        ("WaterMatte.X", "f16"),
        ("Direct.R", "f32"),
        ("Direct.G", "f32"),
        ("Direct.B", "f32"),
        ("Refraction.R", "f32"),
        ("Refraction.G", "f32"),
        ("Refraction.B", "f32"),
        ("SkyReflection.R", "f32"),
        ("SkyReflection.G", "f32"),
        ("SkyReflection.B", "f32"),
        ("FlagConvergence.X", "f16"),
        ("FlagBoundary.X", "f16"),
        ("FlagPopping.X", "f16"),
        ("FlagExtrapolated.X", "f16"),
    ]
    .into_iter()
    .map(|(name, kind)| (name.to_string(), kind))
    .collect();
    expected.sort();
    assert_eq!(names, expected);
    let attributes = &read.attributes;
    assert_eq!(attributes.layer_name, None, "the image must be layer-less");
    assert_eq!(attributes.owner, None, "no owner unless asked for");
    assert_eq!(attributes.capture_date, None, "no capDate unless asked for");
    for name in [
        header::FRAME,
        header::TIME_SECS,
        header::WORLD_FROM_CAMERA,
        header::METHOD,
        header::VERSION,
        header::CHANNEL_MAP,
        header::OBJECT_NAMES,
    ] {
        assert!(
            attributes.other.contains_key(&header::text(name)),
            "missing {name}"
        );
    }
}

/// The effects sum to the beauty, and each pixel's Cryptomatte ranks say what the pixel holds.
#[test]
fn effects_sum_to_the_beauty_and_ranks_follow_the_ids() {
    let temp = tempfile::tempdir().unwrap();
    let path = temp.path().join("frame.exr");
    let frame = test_frame(9, 5);
    let meta = test_meta();
    write_frame_exr(&path, &frame, &meta).unwrap();
    let read = read_channels(&path).unwrap();
    let get = |name: &str| read.get(name).unwrap();
    let water_id = cryptomatte::id_float("water");
    for i in 0..frame.pixel_count() {
        for (c, beauty) in ["R", "G", "B"].into_iter().enumerate() {
            let sum = get(channels::DIRECT[c])[i]
                + get(channels::REFRACTION[c])[i]
                + get(channels::SKY_REFLECTION[c])[i];
            let expected = get(beauty)[i];
            assert!(
                (sum - expected).abs() <= 1e-6 * expected.abs().max(1.0),
                "{i}"
            );
        }
        let (id0, coverage0) = (get("CryptoObject00.R")[i], get("CryptoObject00.G")[i]);
        let (id1, coverage1) = (get("CryptoObject00.B")[i], get("CryptoObject00.A")[i]);
        let object = frame.object[i];
        let object_id =
            (object != 0).then(|| cryptomatte::id_float(&meta.object_names[object as usize - 1]));
        let water = frame.water_matte[i] > 0.5;
        let ids: Vec<u32> = [(id0, coverage0), (id1, coverage1)]
            .iter()
            .filter(|(_, coverage)| *coverage > 0.0)
            .map(|(id, _)| id.to_bits())
            .collect();
        let mut expected: Vec<u32> = object_id.into_iter().map(f32::to_bits).collect();
        if water {
            expected.push(water_id.to_bits());
        }
        let mut sorted = ids.clone();
        sorted.sort();
        expected.sort();
        assert_eq!(sorted, expected, "pixel {i}");
        assert!(coverage0 >= coverage1);
        if !ids.is_empty() {
            assert!((coverage0 + coverage1 - 1.0).abs() < 1e-6, "pixel {i}");
        }
    }
}

#[test]
fn owner_and_capture_date_only_when_asked() {
    let temp = tempfile::tempdir().unwrap();
    let path = temp.path().join("frame.exr");
    let mut meta = test_meta();
    meta.owner = Some("Studio".into());
    meta.capture_unix_secs = Some(1_700_000_000);
    write_frame_exr(&path, &test_frame(3, 2), &meta).unwrap();
    let read = read_channels(&path).unwrap();
    assert_eq!(
        read.attributes.owner.as_ref().unwrap().to_string(),
        "Studio"
    );
    assert_eq!(
        read.attributes.capture_date.as_ref().unwrap().to_string(),
        "2023:11:14 22:13:20"
    );
    assert_eq!(read.attributes.utc_offset, Some(0.0));
}

#[test]
fn a_frame_naming_too_few_objects_is_refused() {
    let temp = tempfile::tempdir().unwrap();
    let mut meta = test_meta();
    meta.object_names.truncate(1);
    let error = write_frame_exr(&temp.path().join("f.exr"), &test_frame(3, 2), &meta).unwrap_err();
    assert!(
        error.to_string().contains("object id 2 has no name"),
        "{error}"
    );
}

/// Frames of the first layout (rendered by snell before the channel map) read into the same
/// layers: depth along the view axis, the map's sky values, the layers it lacked empty.
#[test]
fn frames_of_the_first_layout_still_read() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/legacy/pool.0024.exr");
    let (frame, meta) = read_frame_exr(&path).unwrap();
    assert_eq!(meta.channel_map, None);
    assert_eq!((frame.width, frame.height), (48, 27));
    assert!(frame.apparent_depth_m.is_empty() && frame.water_reflection.is_empty());
    assert_eq!(frame.water_matte.len(), frame.pixel_count());
    assert!(frame.depth_m.iter().all(|d| d.is_finite() && *d > 0.0));
    assert!(frame.position.iter().flatten().all(|c| c.is_finite()));
    assert_eq!(frame.object.len(), frame.pixel_count());
    // Depth = distance times the cosine to the view axis: where P is known, they agree.
    let camera = meta.camera;
    let mut checked = 0;
    for (i, p) in frame.position.iter().enumerate() {
        let p = Vec3::from(*p);
        if frame.object[i] != 0 && p.y > 0.05 {
            // Above water, P is the first surface.
            assert!(
                (camera.view_depth(p) - frame.depth_m[i]).abs() < 1e-4,
                "{i}"
            );
            checked += 1;
        }
    }
    assert!(checked > 50, "{checked}");
    // The water matte derived from Z and P: the water's surface in front of what is seen below
    // it, and everything seen directly at its own depth.
    let (mut water, mut direct) = (0, 0);
    for (i, p) in frame.position.iter().enumerate() {
        let seen_depth = camera.view_depth(Vec3::from(*p));
        match (frame.water_matte[i] == 1.0, frame.object[i] != 0) {
            (true, true) => {
                assert!(seen_depth > frame.depth_m[i] + 1e-3, "{i}");
                water += 1;
            }
            (false, true) => {
                assert!((seen_depth - frame.depth_m[i]).abs() < 1e-3, "{i}");
                direct += 1;
            }
            (true, false) => assert!(frame.depth_m[i] < SKY_DEPTH_M, "{i}"),
            (false, false) => assert_eq!(frame.depth_m[i], SKY_DEPTH_M, "{i}"),
        }
    }
    assert!(water > 100 && direct > 100, "{water} {direct}");
    let raw = read_channels(&path).unwrap();
    assert!(raw.types.contains_key("flags.convergence") && raw.types["object"] == "u32");

    // Written again, it follows the map, with the matte and without the effects it cannot split.
    let temp = tempfile::tempdir().unwrap();
    let again = temp.path().join("again.exr");
    write_frame_exr(&again, &frame, &FrameMeta::from_read(&meta, "pool")).unwrap_err();
    let mut meta_again = FrameMeta::from_read(&meta, "pool");
    meta_again.object_names = (1..=7).map(|k| format!("object {k}")).collect();
    write_frame_exr(&again, &frame, &meta_again).unwrap();
    let written = read_channels(&again).unwrap();
    assert!(written.types.contains_key(channels::WATER_MATTE));
    assert!(!written.types.contains_key(channels::REFRACTION[0]));
    let (read_again, _) = read_frame_exr(&again).unwrap();
    assert_bit_exact(&frame, &read_again);
}

#[test]
fn no_temporary_file_after_success_or_failure() {
    let temp = tempfile::tempdir().unwrap();
    let path = temp.path().join("pool.0001.exr");
    write_frame_exr(&path, &test_frame(3, 2), &test_meta()).unwrap();
    assert_eq!(directory_entries(temp.path()), vec!["pool.0001.exr"]);

    // An inconsistent frame fails before any file is created.
    let mut broken = test_frame(3, 2);
    broken.flags.pop();
    let error =
        write_frame_exr(&temp.path().join("pool.0002.exr"), &broken, &test_meta()).unwrap_err();
    assert!(error.to_string().contains("pool.0002.exr"), "{error}");
    assert!(error.to_string().contains("flags"), "{error}");
    assert_eq!(directory_entries(temp.path()), vec!["pool.0001.exr"]);

    // A failure after the temporary file was created (the destination is a non-empty directory,
    // so the rename fails) removes the temporary file too.
    let blocked = temp.path().join("pool.0003.exr");
    fs::create_dir(&blocked).unwrap();
    fs::write(blocked.join("keep"), b"x").unwrap();
    let error = write_frame_exr(&blocked, &test_frame(3, 2), &test_meta()).unwrap_err();
    assert!(error.to_string().contains("pool.0003.exr"), "{error}");
    assert_eq!(
        directory_entries(temp.path()),
        vec!["pool.0001.exr", "pool.0003.exr"]
    );
}

fn directory_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn unwritable_output_path_is_a_clear_error() {
    let temp = tempfile::tempdir().unwrap();
    let regular_file = temp.path().join("file");
    fs::write(&regular_file, b"x").unwrap();
    let path = frame_path(&regular_file.join("out"), "pool", 1);
    let message = write_frame_exr(&path, &test_frame(2, 2), &test_meta())
        .unwrap_err()
        .to_string();
    assert!(message.contains("cannot create directory"), "{message}");
    assert!(
        message.contains("a path component is a regular file"),
        "{message}"
    );
    assert!(
        message.contains(&regular_file.join("out").display().to_string()),
        "{message}"
    );
}

#[test]
fn same_frame_gives_the_same_bytes() {
    let temp = tempfile::tempdir().unwrap();
    let (first, second) = (temp.path().join("a.exr"), temp.path().join("b.exr"));
    // 96 lines = 6 ZIP chunks, so parallel compression has several blocks to put in order.
    let frame = test_frame(40, 96);
    write_frame_exr(&first, &frame, &test_meta()).unwrap();
    write_frame_exr(&second, &frame, &test_meta()).unwrap();
    assert_eq!(fs::read(&first).unwrap(), fs::read(&second).unwrap());
}

#[test]
fn overwriting_an_existing_frame_replaces_it() {
    let temp = tempfile::tempdir().unwrap();
    let path = temp.path().join("pool.0001.exr");
    write_frame_exr(&path, &test_frame(3, 2), &test_meta()).unwrap();
    let second = test_frame(5, 4);
    write_frame_exr(&path, &second, &test_meta()).unwrap();
    assert_bit_exact(&as_read_back(&second), &read_frame_exr(&path).unwrap().0);
}

/// Every compression round-trips every layer bit for bit; `--half` stores the beauty, and only
/// it, as half floats (rounded to nearest, saturating at 65504); the header says which.
#[test]
fn every_compression_is_lossless_and_half_touches_only_the_beauty() {
    let temp = tempfile::tempdir().unwrap();
    // 40 x 35 lines: several chunks of every codec (PIZ takes 32 lines, ZIP 16).
    let frame = test_frame(40, 35);
    let expected = as_read_back(&frame);
    for compression in ExrCompression::ALL {
        for half_beauty in [false, true] {
            let write = WriteOptions {
                half_beauty,
                compression,
                ..WriteOptions::default()
            };
            let path = temp
                .path()
                .join(format!("{}-{half_beauty}.exr", compression.name()));
            let meta = FrameMeta {
                write,
                ..test_meta()
            };
            write_frame_exr(&path, &frame, &meta).unwrap();
            let raw = read_channels(&path).unwrap();
            let beauty_type = if half_beauty { "f16" } else { "f32" };
            for name in channels::BEAUTY {
                assert_eq!(raw.types[name], beauty_type, "{name} {write:?}");
            }
            assert_eq!(raw.types[channels::DEPTH], "f32");
            assert_eq!(raw.types[channels::POSITION[0]], "f32");
            assert_eq!(raw.attributes.layer_name, None);
            let label = match raw.attributes.other.get(&header::text(header::OUTPUT)) {
                Some(::exr::meta::attribute::AttributeValue::Text(text)) => text.to_string(),
                other => panic!("snell.output is {other:?}"),
            };
            let beauty_label = if half_beauty { "half" } else { "float32" };
            assert_eq!(
                label,
                format!(
                    "beauty={beauty_label} compression={} layers=all",
                    compression.name()
                )
            );
            let (read, read_meta) = read_frame_exr(&path).unwrap();
            assert_eq!(read_meta.write, write);
            let mut want = expected.clone();
            if half_beauty {
                for p in want.beauty_rgba.iter_mut().flatten() {
                    *p = ::exr::prelude::f16::from_f32(p.min(65504.0)).to_f32();
                }
                assert!(read.beauty_rgba.iter().flatten().all(|v| v.is_finite()));
            }
            assert_bit_exact(&want, &read);
        }
    }
}

/// `snell.output` reads back into the options that wrote it, and nothing else does.
#[test]
fn write_options_labels_read_back() {
    use channels::LayerSet;
    for compression in ExrCompression::ALL {
        for half_beauty in [false, true] {
            for text in ["all", "comp", "Z,P", "beauty"] {
                let write = WriteOptions {
                    half_beauty,
                    compression,
                    layers: LayerSet::parse(text).unwrap().0,
                };
                assert_eq!(WriteOptions::from_label(&write.label()), Some(write));
            }
        }
    }
    for bad in [
        "",
        "beauty=half",
        "beauty=f16 compression=zip layers=all",
        "beauty=half compression=dwaa layers=all",
        "beauty=half compression=zip layers=Q",
        "beauty=half compression=zip layers=all more",
    ] {
        assert_eq!(WriteOptions::from_label(bad), None, "{bad:?}");
    }
}

/// `--layers`: a frame holds exactly the chosen layers, the Cryptomatte's metadata only with its
/// layer, the header says which; read back, the layers left out come back empty and the others
/// bit for bit.
#[test]
fn chosen_layers_are_the_only_ones_written_and_read_back() {
    use channels::{Layer, LayerSet};
    let temp = tempfile::tempdir().unwrap();
    let frame = test_frame(6, 5);
    let expected = as_read_back(&frame);
    for text in ["comp", "Z,FlagPopping,SkyReflection", "beauty"] {
        let (layers, half_beauty) = LayerSet::parse(text).unwrap();
        let path = temp.path().join(format!("{}.exr", layers.label()));
        let meta = FrameMeta {
            write: WriteOptions {
                half_beauty,
                layers,
                ..WriteOptions::default()
            },
            ..test_meta()
        };
        write_frame_exr(&path, &frame, &meta).unwrap();
        let raw = read_channels(&path).unwrap();
        let mut want: Vec<String> = Vec::new();
        for layer in layers.layers() {
            let names: Vec<String> = match layer {
                Layer::Beauty => channels::BEAUTY.map(String::from).to_vec(),
                Layer::Depth => vec![channels::DEPTH.into()],
                Layer::ApparentDepth => vec![channels::APPARENT_DEPTH.into()],
                Layer::Position => channels::POSITION.map(String::from).to_vec(),
                Layer::IndexOb => vec![channels::INDEX_OB.into()],
                Layer::CryptoObject => channels::crypto_rank_channels()
                    .into_iter()
                    .flat_map(|(id, coverage)| [id, coverage])
                    .collect(),
                Layer::WaterMatte => vec![channels::WATER_MATTE.into()],
                Layer::Direct => channels::DIRECT.map(String::from).to_vec(),
                Layer::Refraction => channels::REFRACTION.map(String::from).to_vec(),
                Layer::SkyReflection => channels::SKY_REFLECTION.map(String::from).to_vec(),
                flag => channels::FLAG_CHANNELS
                    .iter()
                    .filter(|(_, bit)| Layer::of_flag(*bit) == flag)
                    .map(|(name, _)| name.to_string())
                    .collect(),
            };
            want.extend(names);
        }
        want.sort();
        let got: Vec<String> = raw.channels.keys().cloned().collect();
        assert_eq!(got, want, "{text}");
        assert_eq!(
            raw.types["R"],
            if half_beauty { "f16" } else { "f32" },
            "{text}"
        );
        let crypto_attributes = raw
            .attributes
            .other
            .keys()
            .filter(|name| name.to_string().starts_with("cryptomatte/"))
            .count();
        assert_eq!(
            crypto_attributes,
            if layers.has(Layer::CryptoObject) {
                4
            } else {
                0
            },
            "{text}"
        );
        let label = match raw.attributes.other.get(&header::text(header::OUTPUT)) {
            Some(::exr::meta::attribute::AttributeValue::Text(label)) => label.to_string(),
            other => panic!("snell.output is {other:?}"),
        };
        assert!(
            label.ends_with(&format!(" layers={}", layers.label())),
            "{label}"
        );

        let (read, read_meta) = read_frame_exr(&path).unwrap();
        assert_eq!(read_meta.channels, want);
        // Read back, the frame's metadata says how it was stored: written again from it, it
        // holds the same layers (not every layer, which the frame lacks).
        assert_eq!(read_meta.write, meta.write, "{text}");
        assert_eq!(FrameMeta::from_read(&read_meta, "pool").write, meta.write);
        let again = temp.path().join(format!("again-{}.exr", layers.label()));
        write_frame_exr(&again, &read, &FrameMeta::from_read(&read_meta, "pool")).unwrap();
        let mut rewritten = raw.types.clone();
        if !(layers.has(Layer::WaterMatte) && layers.has(Layer::CryptoObject)) {
            // The sky reflection reads back only with the matte and the water's Cryptomatte
            // coverage (its reflectance); without them it comes back empty and is not written.
            rewritten.retain(|name, _| !channels::SKY_REFLECTION.contains(&name.as_str()));
        }
        assert_eq!(read_channels(&again).unwrap().types, rewritten, "{text}");
        let beauty = |f: &RenderedFrame| {
            f.beauty_rgba
                .iter()
                .flatten()
                .map(|v| {
                    if half_beauty {
                        ::exr::prelude::f16::from_f32(*v).to_f32().to_bits()
                    } else {
                        v.to_bits()
                    }
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(beauty(&read), beauty(&expected), "{text}");
        let bits = |values: &[f32]| values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        if layers.has(Layer::Depth) {
            assert_eq!(bits(&read.depth_m), bits(&expected.depth_m));
        } else {
            assert!(read.depth_m.is_empty());
        }
        assert_eq!(read.position.is_empty(), !layers.has(Layer::Position));
        assert_eq!(read.object.is_empty(), !layers.has(Layer::IndexOb));
        if layers.has(Layer::FlagPopping) {
            let popping = |f: &RenderedFrame| {
                f.flags
                    .iter()
                    .map(|f| f & crate::draw::flag_bits::POPPING)
                    .collect::<Vec<_>>()
            };
            assert_eq!(
                read.flags,
                popping(&expected),
                "only the popping bit is read"
            );
        } else {
            assert!(read.flags.is_empty());
        }
    }
}

/// A frame without `Z` cannot be written with `Z` chosen; without it, it can.
#[test]
fn a_chosen_layer_must_be_in_the_frame() {
    let temp = tempfile::tempdir().unwrap();
    let mut frame = test_frame(4, 3);
    frame.depth_m.clear();
    let error = write_frame_exr(&temp.path().join("a.exr"), &frame, &test_meta()).unwrap_err();
    assert!(error.to_string().contains("depth_m"), "{error}");
    let (layers, _) = channels::LayerSet::parse("P,IndexOB").unwrap();
    let meta = FrameMeta {
        write: WriteOptions {
            layers,
            ..WriteOptions::default()
        },
        ..test_meta()
    };
    write_frame_exr(&temp.path().join("b.exr"), &frame, &meta).unwrap();
}
