//! Integration tests of `snell::character`: the Khronos sample characters in `scenes/assets/` and
//! the small models in `tests/gltf/` (written by `tests/gltf/make_test_models.py`). Expected values
//! are worked out by hand next to each assertion, or (RiggedSimple) by the independent reference
//! script `tests/gltf/rigged_simple_reference.py`.

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use snell::character::{
    skinning_throughput, AnimationSelector, CharacterAsset, CharacterError, Pose,
};

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn load(relative: &str) -> CharacterAsset {
    let path = repo_path(relative);
    CharacterAsset::load(&path).unwrap_or_else(|e| panic!("loading {relative}: {e}"))
}

fn load_err(path: &Path) -> CharacterError {
    match CharacterAsset::load(path) {
        Ok(_) => panic!("{} loaded but should have failed", path.display()),
        Err(e) => e,
    }
}

/// Writes `contents` to `dir/name` and loads it, expecting an error.
fn load_err_written(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> CharacterError {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    load_err(&path)
}

/// The error's message contains every one of `parts`.
fn assert_mentions(error: &CharacterError, parts: &[&str]) {
    let message = error.to_string();
    for part in parts {
        assert!(message.contains(part), "{message:?} lacks {part:?}");
    }
}

/// Positions of the first posed primitive at `time_secs` of animation 0, model = world space.
fn posed_positions(asset: &CharacterAsset, time_secs: f32) -> Vec<Vec3> {
    let pose = asset.pose(Some(0), time_secs);
    asset.posed_primitives(&pose, Mat4::IDENTITY)[0]
        .mesh
        .positions
        .clone()
}

/// Agreement to 1e-4 relative to the expected magnitude, with 1 as the floor so that components
/// that should be ~0 are compared absolutely. The code works in f32 from f32 file data; its
/// rounding error on these magnitudes (< 10) is ~1e-6, so 1e-4 still catches any formula error.
fn assert_close(actual: f32, expected: f64, what: &str) {
    let tolerance = 1e-4 * expected.abs().max(1.0);
    assert!(
        (f64::from(actual) - expected).abs() <= tolerance,
        "{what}: got {actual}, expected {expected}"
    );
}

fn assert_vec_close(actual: Vec3, expected: [f64; 3], what: &str) {
    for axis in 0..3 {
        assert_close(actual[axis], expected[axis], &format!("{what}[{axis}]"));
    }
}

// ---------------------------------------------------------------------------------------------
// The sample characters

#[test]
fn loads_the_three_sample_characters() {
    let fox = load("scenes/assets/Fox.glb");
    assert_eq!(fox.vertex_count(), 1728);
    let names: Vec<_> = fox.animations().iter().map(|a| a.name.clone()).collect();
    assert_eq!(
        names,
        vec![
            Some("Survey".to_string()),
            Some("Walk".to_string()),
            Some("Run".to_string())
        ]
    );
    assert_eq!(fox.textures().len(), 1);
    let texture = &fox.textures()[0];
    assert_eq!(
        texture.rgba8_srgb.len(),
        (texture.width * texture.height * 4) as usize
    );
    let posed = fox.posed_primitives(&fox.pose(None, 0.0), Mat4::IDENTITY);
    assert_eq!(posed.len(), 1);
    assert_eq!(posed[0].texture, Some(0));
    assert!(posed[0].name.ends_with("/primitive 0"), "{}", posed[0].name);
    assert_eq!(
        posed[0].mesh.triangle_count(),
        576,
        "1,728 unindexed vertices = 576 triangles"
    );
    assert_eq!(fox.files(), &[repo_path("scenes/assets/Fox.glb")]);
    assert!(fox.influence_count() >= fox.vertex_count());

    let cesium = load("scenes/assets/CesiumMan.glb");
    assert_eq!(cesium.animations().len(), 1);
    assert_eq!(cesium.animations()[0].name, None);
    // Its first key is at 1/24 s (0.0417), not at 0.
    assert!((cesium.animations()[0].start_secs - 1.0 / 24.0).abs() < 1e-6);
    assert!(cesium.animations()[0].end_secs > cesium.animations()[0].start_secs);
    assert_eq!(cesium.textures().len(), 1);

    let rigged = load("scenes/assets/RiggedSimple.glb");
    assert_eq!(rigged.vertex_count(), 160);
    assert_eq!(rigged.animations().len(), 1);
    assert!(rigged.textures().is_empty());
    assert_eq!(
        rigged
            .resolve_animation(&AnimationSelector::Index(0))
            .unwrap(),
        0
    );

    for asset in [&fox, &cesium, &rigged] {
        for primitive in asset.posed_primitives(&asset.pose(Some(0), 0.7), Mat4::IDENTITY) {
            for normal in &primitive.mesh.normals {
                assert!(
                    (normal.length() - 1.0).abs() < 1e-5,
                    "{}: normal {normal}",
                    primitive.name
                );
            }
        }
        assert!(skinning_throughput(asset, 3) > 0.0);
    }
}

/// Joint matrices and skinned positions of RiggedSimple at a key time (0.125 s is key 2) and
/// between keys (0.3 s, 1.7 s). Expected numbers: printed by `python3
/// tests/gltf/rigged_simple_reference.py`, which parses the GLB by hand and evaluates the glTF
/// formulas in double precision, sharing no code with snell.
#[test]
fn rigged_simple_matches_reference_poses() {
    let asset = load("scenes/assets/RiggedSimple.glb");
    // Bone (joint 0) is not animated: the same matrix at every time.
    let joint0 = [
        1.0,
        0.0,
        4.371139894e-08,
        0.0,
        4.371139894e-08,
        0.0,
        -1.0,
        0.0,
        0.0,
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
    ];
    struct Reference {
        time_secs: f32,
        joint1: [f64; 16],
        vertices: [(usize, [f64; 3]); 5],
    }
    let references = [
        Reference {
            time_secs: 0.125,
            joint1: [
                9.987801624e-01,
                -4.937679528e-02,
                4.364728892e-08,
                0.0,
                4.369336983e-08,
                -1.462759574e-10,
                -1.000000109e+00,
                0.0,
                4.937679770e-02,
                9.987802113e-01,
                2.149586719e-09,
                0.0,
                -2.989193825e-04,
                1.390193705e-03,
                -6.680414934e-11,
                1.0,
            ],
            vertices: [
                (0, [-4.371138071e-08, -4.575077057e+00, 9.999995828e-01]),
                (20, [4.519106131e-01, -5.472287717e-03, -1.872792845e-01]),
                (40, [-3.460153900e-01, 4.829832423e-03, -3.460471284e-01]),
                (80, [-1.897081343e-01, 4.591418438e+00, -1.722369316e-01]),
                (150, [-9.226223537e-02, 4.586600996e+00, -3.182533472e-01]),
            ],
        },
        Reference {
            time_secs: 0.3,
            joint1: [
                9.881547836e-01,
                -1.534603403e-01,
                4.315838786e-08,
                0.0,
                4.361922417e-08,
                -3.639215575e-10,
                -1.000000109e+00,
                0.0,
                1.534603405e-01,
                9.881547848e-01,
                6.486279939e-09,
                0.0,
                -7.038716673e-04,
                4.373854893e-03,
                -8.243174040e-11,
                1.0,
            ],
            vertices: [
                (0, [-4.371138071e-08, -4.575077057e+00, 9.999995828e-01]),
                (20, [4.505489805e-01, -1.699365762e-02, -1.872792845e-01]),
                (40, [-3.451601122e-01, 1.502476021e-02, -3.460471283e-01]),
                (80, [2.904953776e-01, 4.589069881e+00, -1.722369115e-01]),
                (150, [3.869046124e-01, 4.574097537e+00, -3.182533272e-01]),
            ],
        },
        Reference {
            time_secs: 1.7,
            joint1: [
                9.758741248e-01,
                -2.183335192e-01,
                4.258320694e-08,
                0.0,
                4.352775312e-08,
                -4.836801078e-10,
                -1.000000109e+00,
                0.0,
                2.183335324e-01,
                9.758741842e-01,
                9.183626235e-09,
                0.0,
                -7.979635409e-04,
                6.271683655e-03,
                -8.456718088e-11,
                1.0,
            ],
            vertices: [
                (0, [-4.371138071e-08, -4.575077057e+00, 9.999995828e-01]),
                (20, [4.490729742e-01, -2.416471731e-02, -1.872792846e-01]),
                (40, [-3.440738457e-01, 2.138903183e-02, -3.460471283e-01]),
                (80, [5.923076704e-01, 4.561758523e+00, -1.722368990e-01]),
                (150, [6.875187439e-01, 4.540456834e+00, -3.182533147e-01]),
            ],
        },
    ];
    for reference in &references {
        let t = reference.time_secs;
        let pose = asset.pose(Some(0), t);
        assert_eq!(pose.joint_matrices.len(), 1);
        assert_eq!(pose.joint_matrices[0].len(), 2);
        for (joint, expected) in [(0, &joint0), (1, &reference.joint1)] {
            let actual = pose.joint_matrices[0][joint].to_cols_array();
            for i in 0..16 {
                assert_close(
                    actual[i],
                    expected[i],
                    &format!("t = {t}: joint {joint} element {i}"),
                );
            }
        }
        let positions = &asset.posed_primitives(&pose, Mat4::IDENTITY)[0]
            .mesh
            .positions;
        for (vertex, expected) in reference.vertices {
            assert_vec_close(
                positions[vertex],
                expected,
                &format!("t = {t}: vertex {vertex}"),
            );
        }
    }
}

/// With every joint at its bind transform, skinning must give back the stored mesh: positions
/// and normals of every vertex (joint matrices are inverse(ibm) * ibm, identity up to rounding).
#[test]
fn bind_pose_reproduces_the_stored_mesh() {
    for file in [
        "scenes/assets/RiggedSimple.glb",
        "scenes/assets/Fox.glb",
        "scenes/assets/CesiumMan.glb",
    ] {
        let asset = load(file);
        let pose = asset.bind_pose();
        for skin in &pose.joint_matrices {
            for m in skin {
                assert!(
                    m.abs_diff_eq(Mat4::IDENTITY, 1e-4),
                    "{file}: joint matrix {m}"
                );
            }
        }
        let posed = asset.posed_primitives(&pose, Mat4::IDENTITY);
        let stored = asset.stored_primitives();
        assert_eq!(posed.len(), stored.len());
        for (posed, (name, stored)) in posed.iter().zip(stored) {
            assert_eq!(posed.name, name);
            assert_eq!(posed.mesh.positions.len(), stored.positions.len());
            // Scale for positions: the model's extent (Fox is ~100 units long, RiggedSimple ~10).
            let extent = stored
                .positions
                .iter()
                .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
            for (v, (a, b)) in posed
                .mesh
                .positions
                .iter()
                .zip(&stored.positions)
                .enumerate()
            {
                assert!(
                    (*a - *b).length() <= 1e-5 * extent.max(1.0),
                    "{file} vertex {v}: {a} vs {b}"
                );
            }
            for (v, (a, b)) in posed.mesh.normals.iter().zip(&stored.normals).enumerate() {
                assert!((*a - *b).length() <= 1e-4, "{file} normal {v}: {a} vs {b}");
            }
            assert_eq!(posed.mesh.triangles, stored.triangles);
            assert_eq!(posed.mesh.uvs, stored.uvs);
        }
    }
}

#[test]
fn fox_mid_walk_is_finite_and_plausible() {
    let fox = load("scenes/assets/Fox.glb");
    let walk = fox
        .resolve_animation(&AnimationSelector::Name("Walk".to_string()))
        .unwrap();
    assert_eq!(walk, 1);
    let info = &fox.animations()[walk];
    let mid = 0.5 * (info.start_secs + info.end_secs);
    let bounds = |pose: &Pose| {
        let posed = fox.posed_primitives(pose, Mat4::IDENTITY);
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &posed[0].mesh.positions {
            assert!(p.is_finite(), "non-finite vertex {p}");
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        for n in &posed[0].mesh.normals {
            assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5);
        }
        (lo, hi)
    };
    let (bind_lo, bind_hi) = bounds(&fox.bind_pose());
    let (lo, hi) = bounds(&fox.pose(Some(walk), mid));
    let bind_size = bind_hi - bind_lo;
    let size = hi - lo;
    // A walking fox keeps roughly its bind-pose size: legs swing, nothing explodes or collapses.
    for axis in 0..3 {
        let ratio = size[axis] / bind_size[axis];
        assert!(
            (0.5..2.0).contains(&ratio),
            "axis {axis}: {size} vs bind {bind_size}"
        );
    }
    // And the fox is centred where it stands in bind pose (within half its length).
    let shift = (0.5 * (lo + hi) - 0.5 * (bind_lo + bind_hi)).length();
    assert!(
        shift < 0.5 * bind_size.max_element(),
        "centre moved by {shift}"
    );
    // Mid-walk differs from the bind pose.
    assert!(lo != bind_lo || hi != bind_hi);
}

#[test]
fn posing_is_bit_identical_across_runs_and_thread_counts() {
    let fox = load("scenes/assets/Fox.glb");
    let pose = fox.pose(Some(2), 0.37);
    let world = Mat4::from_scale_rotation_translation(
        Vec3::splat(0.01),
        Quat::from_rotation_y(0.3),
        Vec3::new(1.0, -2.0, 3.0),
    );
    let bits = |primitives: Vec<snell::character::PosedPrimitive>| -> Vec<u32> {
        primitives
            .iter()
            .flat_map(|p| p.mesh.positions.iter().chain(&p.mesh.normals))
            .flat_map(|v| v.to_array().map(f32::to_bits))
            .collect()
    };
    let first = bits(fox.posed_primitives(&pose, world));
    let second = bits(fox.posed_primitives(&fox.pose(Some(2), 0.37), world));
    assert_eq!(first, second);
    let single_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| bits(fox.posed_primitives(&pose, world)));
    assert_eq!(first, single_thread);
}

// ---------------------------------------------------------------------------------------------
// Authored models: STEP, CUBICSPLINE, 8 influences, external files

/// The rig of step.gltf / cubic.gltf (see make_test_models.py): joint J1 has inverse bind
/// translate(0, -1, 0) and parent J0 = identity, so with J1 animated to T, R, S a vertex p bound
/// to it lands at T + R (S (p - (0, 1, 0))). v0 (0,0,0) is on J0 (never moves), v1 (1,1,0) on J1,
/// v2 (0,2,0) half on each.
#[test]
fn step_channels_hold_the_key_at_or_before_t() {
    let asset = load("tests/gltf/step.gltf");
    assert_eq!(asset.animations()[0].name.as_deref(), Some("Steps"));
    assert_eq!(asset.animations()[0].start_secs, 0.0);
    assert_eq!(asset.animations()[0].end_secs, 2.0);
    // Keys: T (0,1,0)@0 (1,1,0)@1 (2,1,0)@2; R identity@0, 90 deg about z@1; S 1@0.5, 2@1.5.
    let cases: [(f32, [f64; 3], [f64; 3]); 6] = [
        // before every key: T (0,1,0), R id, S 1 -> v1 = (1,1,0); v2: J1 gives (0,2,0) too.
        (-1.0, [1.0, 1.0, 0.0], [0.0, 2.0, 0.0]),
        // 0.75: every channel still on its first key (S's key 0.5 is at or before 0.75).
        (0.75, [1.0, 1.0, 0.0], [0.0, 2.0, 0.0]),
        // exactly key 1: T (1,1,0), R 90z, S 1: (1,0,0) -> (0,1,0) -> (1,2,0).
        // v2: (0,1,0) -> (-1,0,0) -> (0,1,0); half with (0,2,0) -> (0,1.5,0).
        (1.0, [1.0, 2.0, 0.0], [0.0, 1.5, 0.0]),
        // 1.25: same keys as at 1.0.
        (1.25, [1.0, 2.0, 0.0], [0.0, 1.5, 0.0]),
        // 1.5: S jumps to 2: (2,0,0) -> (0,2,0) -> (1,3,0); v2: (0,2,0) -> (-2,0,0) -> (-1,1,0),
        // half with (0,2,0) -> (-0.5,1.5,0).
        (1.5, [1.0, 3.0, 0.0], [-0.5, 1.5, 0.0]),
        // after every key: T (2,1,0): v1 (2,3,0); v2 (0,1,0) blended -> (0,1.5,0).
        (5.0, [2.0, 3.0, 0.0], [0.0, 1.5, 0.0]),
    ];
    for (t, v1, v2) in cases {
        let p = posed_positions(&asset, t);
        assert_vec_close(p[0], [0.0, 0.0, 0.0], &format!("t = {t}: v0"));
        assert_vec_close(p[1], v1, &format!("t = {t}: v1"));
        assert_vec_close(p[2], v2, &format!("t = {t}: v2"));
    }
}

#[test]
fn cubic_spline_channels_follow_the_hermite_spline() {
    let asset = load("tests/gltf/cubic.gltf");
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // Keys at 0 s and 2 s (td = 2). T: value (0,1,0) -> (10,1,0), out-tangent 0 = (3,0,0),
    // in-tangent 1 = (-1,0,0). R: identity -> 90 deg about z, zero tangents. S: 1 -> 3, out-
    // tangent 0 = (1,0,0), in-tangent 1 = 0. Spec: p = h00 v0 + h10 td b0 + h01 v1 + h11 td a1.
    let expected_at = |t: f64| -> ([f64; 3], [f64; 3]) {
        let s = t / 2.0;
        let h00 = 2.0 * s * s * s - 3.0 * s * s + 1.0;
        let h10 = s * s * s - 2.0 * s * s + s;
        let h01 = -2.0 * s * s * s + 3.0 * s * s;
        let h11 = s * s * s - s * s;
        // Translation x: start 0, out-tangent b0 = 3, end 10, in-tangent a1 = -1, td = 2.
        let (td, b0, end_x, a1) = (2.0, 3.0, 10.0, -1.0);
        let tx = h10 * td * b0 + h01 * end_x + h11 * td * a1;
        let ty = h00 + h01;
        let (qz, qw) = (h01 * h, h00 + h01 * h);
        let norm = (qz * qz + qw * qw).sqrt();
        let angle = 2.0 * (qz / norm).atan2(qw / norm);
        let sx = h00 + h10 * 2.0 + h01 * 3.0;
        let sy = h00 + h01 * 3.0;
        let (sin, cos) = angle.sin_cos();
        // v1: offset (1,0,0) scaled to (sx,0,0), rotated to (sx cos, sx sin), then + T.
        let v1 = [tx + sx * cos, ty + sx * sin, 0.0];
        // v2: offset (0,1,0) -> (0,sy,0) -> (-sy sin, sy cos) + T, averaged with J0's (0,2,0).
        let j1 = [tx - sy * sin, ty + sy * cos, 0.0];
        let v2 = [0.5 * j1[0], 0.5 * (j1[1] + 2.0), 0.0];
        (v1, v2)
    };
    // Worked by hand at t = 1 (s = 0.5: h00 = h01 = 0.5, h10 = 0.125, h11 = -0.125):
    // T = (0.75 + 5 + 0.25, 1, 0) = (6,1,0); R = 45 deg about z; S = (0.5 + 0.25 + 1.5, 2, 2);
    // v1 = (6 + 2.25 cos45, 1 + 2.25 sin45) = (7.5909903, 2.5909903, 0).
    let (v1_at_1, _) = expected_at(1.0);
    assert!((v1_at_1[0] - 7.590_990_3).abs() < 1e-6 && (v1_at_1[1] - 2.590_990_3).abs() < 1e-6);
    for t in [0.0, 0.5, 1.0, 1.5, 2.0] {
        let (v1, v2) = expected_at(t);
        let p = posed_positions(&asset, t as f32);
        assert_vec_close(p[1], v1, &format!("t = {t}: v1"));
        assert_vec_close(p[2], v2, &format!("t = {t}: v2"));
    }
    // Clamped: before the first key as at 0 s, after the last as at 2 s.
    assert_eq!(posed_positions(&asset, -3.0), posed_positions(&asset, 0.0));
    assert_eq!(posed_positions(&asset, 7.0), posed_positions(&asset, 2.0));
    // At the last key exactly: T (10,1,0), R 90z, S 3: v1 = (10, 1 + 3, 0).
    assert_vec_close(
        posed_positions(&asset, 2.0)[1],
        [10.0, 4.0, 0.0],
        "t = 2: v1",
    );
}

#[test]
fn eight_influences_blend_as_computed_by_hand() {
    let asset = load("tests/gltf/eight_influences.glb");
    // Joint k = translate(d_k), d_k = (k+1, 10 (k % 2), -k) (inverse binds are identity).
    // v0 = (0,0,0), slots: joints 7,6,5,4 (u16) weights .1 .2 .3 .4 (float) and joints 3,2,1,0
    // (u8) weights 51,102,153,204 / 255 = .2 .4 .6 .8; sum 3, so each is divided by 3.
    //   x: .1*8 + .2*7 + .3*6 + .4*5 + .2*4 + .4*3 + .6*2 + .8*1 = 10
    //   y: .1*10 + .3*10 + .2*10 + .6*10                          = 12
    //   z: -(.1*7 + .2*6 + .3*5 + .4*4 + .2*3 + .4*2 + .6*1)      = -7
    // -> (10/3, 4, -7/3). v1 = (1,0,0) + d_3 = (5,10,-3). v2 = (0,1,0) + d_2 = (3,1,-2) (its
    // single raw weight 2 normalises to 1).
    let p = posed_positions(&asset, 0.0);
    assert_vec_close(p[0], [10.0 / 3.0, 4.0, -7.0 / 3.0], "v0");
    assert_vec_close(p[1], [5.0, 10.0, -3.0], "v1");
    assert_vec_close(p[2], [3.0, 1.0, -2.0], "v2");
    assert_eq!(asset.influence_count(), 8 + 1 + 1);
    // Pure translations leave normals alone.
    let pose = asset.pose(None, 0.0);
    let posed = asset.posed_primitives(&pose, Mat4::IDENTITY);
    for n in &posed[0].mesh.normals {
        assert!((*n - Vec3::Z).length() < 1e-6);
    }
}

#[test]
fn external_buffer_and_texture_hierarchy_and_modes() {
    let asset = load("tests/gltf/external.gltf");
    assert_eq!(
        asset.files(),
        &[
            repo_path("tests/gltf/external.gltf"),
            repo_path("tests/gltf/external.bin"),
            repo_path("tests/gltf/external_texture.png"),
        ]
    );
    let texture = &asset.textures()[0];
    assert_eq!((texture.width, texture.height), (2, 2));
    assert_eq!(texture.name, "external.gltf/checker");
    // Top row first: red, green; then blue, half-transparent white.
    assert_eq!(
        texture.rgba8_srgb,
        vec![255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 128]
    );
    let warnings = asset.warnings().join("\n");
    assert!(
        warnings.contains("shapes/primitive 3: Points primitive skipped"),
        "{warnings}"
    );
    assert!(
        warnings.contains("morph-target weights channel ignored"),
        "{warnings}"
    );
    assert!(warnings.contains("morph targets ignored"), "{warnings}");

    let posed = asset.posed_primitives(&asset.pose(None, 0.0), Mat4::IDENTITY);
    let names: Vec<&str> = posed.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "shapes/primitive 0",
            "shapes/primitive 1",
            "shapes/primitive 2"
        ]
    );
    assert_eq!(asset.vertex_count(), 12);
    assert_eq!(asset.influence_count(), 12);

    // parent = translate(0,0,-5) * scale 2, child = translate(1,0,0) * rot90z: a model point
    // (x, y, z) goes to 2 (Rz90 (x,y,z) + (1,0,0)) + (0,0,-5) = (2 (1 - y), 2 x, 2 z - 5).
    let quad = &posed[0];
    let expected = [
        [2.0, 0.0, -5.0],
        [2.0, 2.0, -5.0],
        [0.0, 2.0, -5.0],
        [0.0, 0.0, -5.0],
    ];
    for (v, e) in expected.iter().enumerate() {
        assert_vec_close(quad.mesh.positions[v], *e, &format!("quad v{v}"));
    }
    // No NORMAL in the file: computed from the CCW quad, +z, and rotation about z keeps it.
    for n in &quad.mesh.normals {
        assert!((*n - Vec3::Z).length() < 1e-6, "{n}");
    }
    assert_eq!(quad.mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(quad.base_color_factor, [0.5, 0.25, 1.0, 1.0]);
    assert_eq!(quad.texture, Some(0));
    assert_eq!(quad.mesh.uvs[0], glam::Vec2::new(0.0, 1.0));
    assert_eq!(quad.mesh.uvs[2], glam::Vec2::new(1.0, 0.0));

    let strip = &posed[1];
    assert_eq!(strip.mesh.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    assert_eq!(strip.base_color_factor, [1.0; 4]);
    assert_eq!(strip.texture, None);
    assert_eq!(
        strip.mesh.uvs,
        vec![glam::Vec2::ZERO; 4],
        "missing UVs are zeros"
    );
    let fan = &posed[2];
    assert_eq!(fan.mesh.triangles, vec![[1, 2, 0], [2, 3, 0]]);
    // Fan vertex (1,1,2) -> (2 (1 - 1), 2, 4 - 5) = (0, 2, -1).
    assert_vec_close(fan.mesh.positions[2], [0.0, 2.0, -1.0], "fan v2");

    // Animation "Spin" at its last key: child rotation 180 deg about z, so
    // (x, y, z) -> (2 (1 - x), -2 y, 2 z - 5); quad v2 (1,1,0) -> (0, -2, -5).
    let spin = asset
        .resolve_animation(&AnimationSelector::Name("Spin".to_string()))
        .unwrap();
    let posed = asset.posed_primitives(&asset.pose(Some(spin), 1.0), Mat4::IDENTITY);
    assert_vec_close(
        posed[0].mesh.positions[2],
        [0.0, -2.0, -5.0],
        "spun quad v2",
    );
}

#[test]
fn world_transform_and_mirroring_keep_triangles_ccw() {
    let asset = load("tests/gltf/step.gltf");
    let pose = asset.pose(None, 0.0);
    for world in [
        Mat4::from_translation(Vec3::new(5.0, 0.0, 0.0)),
        Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)),
        Mat4::from_scale(Vec3::new(2.0, 2.0, -3.0)),
    ] {
        let posed = asset.posed_primitives(&pose, world);
        let mesh = &posed[0].mesh;
        for (v, (p, stored)) in mesh
            .positions
            .iter()
            .zip(&asset.stored_primitives()[0].1.positions)
            .enumerate()
        {
            let expected = world.transform_point3(*stored);
            assert!(
                (*p - expected).length() < 1e-5,
                "vertex {v}: {p} vs {expected}"
            );
        }
        for triangle in &mesh.triangles {
            let [a, b, c] = triangle.map(|i| mesh.positions[i as usize]);
            let face = (b - a).cross(c - a);
            let normal = mesh.normals[triangle[0] as usize];
            assert!(
                face.dot(normal) > 0.0,
                "world {world}: face {face} vs normal {normal}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors

#[test]
fn joint_index_out_of_range_is_reported() {
    let path = repo_path("tests/gltf/joint_out_of_range.gltf");
    let error = load_err(&path);
    assert!(
        matches!(
            &error,
            CharacterError::JointOutOfRange { vertex: 1, joint: 5, joint_count: 2, primitive, .. }
                if primitive == "rig/primitive 0"
        ),
        "{error:?}"
    );
    assert_mentions(
        &error,
        &[
            "joint_out_of_range.gltf",
            "rig/primitive 0",
            "vertex 1",
            "joint index 5",
            "2 joints",
        ],
    );
}

/// An animation channel whose target node is out of range or whose path is not a property: the
/// `gltf` crate unwraps both when the animation is read (a panic), so the loader checks them first.
#[test]
fn animation_channel_targets_out_of_range_are_reported() {
    let original: serde_json::Value =
        serde_json::from_slice(&std::fs::read(repo_path("tests/gltf/step.gltf")).unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut json = original.clone();
    json["animations"][0]["channels"][0]["target"]["node"] = serde_json::json!(99);
    let error = load_err_written(dir.path(), "node.gltf", serde_json::to_vec(&json).unwrap());
    assert_mentions(
        &error,
        &[
            "node.gltf",
            "animations[0].channels[0].target.node",
            "node 99 of 4 nodes",
        ],
    );
    let mut json = original.clone();
    json["animations"][0]["channels"][1]["target"]["path"] = serde_json::json!("bogus");
    let error = load_err_written(dir.path(), "path.gltf", serde_json::to_vec(&json).unwrap());
    assert_mentions(
        &error,
        &[
            "path.gltf",
            "animations[0].channels[1].target.path",
            "translation, rotation, scale or weights",
        ],
    );
    // A legal path on a node without morph targets loads (the loader ignores weights).
    let mut json = original;
    json["animations"][0]["channels"][2]["target"]["path"] = serde_json::json!("weights");
    let path = dir.path().join("weights.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    CharacterAsset::load(&path).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn weights_summing_to_zero_are_reported() {
    let error = load_err(&repo_path("tests/gltf/zero_weights.gltf"));
    assert!(
        matches!(error, CharacterError::ZeroWeights { vertex: 2, .. }),
        "{error:?}"
    );
    assert_mentions(
        &error,
        &[
            "zero_weights.gltf",
            "rig/primitive 0",
            "vertex 2",
            "sum to zero",
        ],
    );
}

#[test]
fn short_external_buffer_is_truncated() {
    let error = load_err(&repo_path("tests/gltf/short_buffer.gltf"));
    assert!(
        matches!(error, CharacterError::TruncatedBuffer { buffer: 0, .. }),
        "{error:?}"
    );
    assert_mentions(
        &error,
        &[
            "short_buffer.gltf",
            "short_buffer.bin",
            "truncated",
            "258 bytes",
            "byteLength is 268",
        ],
    );
}

#[test]
fn missing_external_buffer_is_reported() {
    let error = load_err(&repo_path("tests/gltf/missing_buffer.gltf"));
    assert!(
        matches!(error, CharacterError::MissingBuffer { buffer: 0, .. }),
        "{error:?}"
    );
    assert_mentions(&error, &["missing_buffer.gltf", "does_not_exist.bin"]);
}

#[test]
fn truncated_glb_is_reported() {
    let original = std::fs::read(repo_path("scenes/assets/RiggedSimple.glb")).unwrap();
    let dir = tempfile::tempdir().unwrap();

    // Cut inside the BIN chunk: the buffer is short.
    let error = load_err_written(dir.path(), "cut.glb", &original[..original.len() - 1000]);
    assert!(
        matches!(error, CharacterError::TruncatedBuffer { buffer: 0, .. }),
        "{error:?}"
    );
    assert_mentions(&error, &["cut.glb", "GLB BIN chunk", "truncated", "14104"]);

    // Cut inside the JSON chunk: not a usable glTF at all.
    let error = load_err_written(dir.path(), "head.glb", &original[..100]);
    assert!(matches!(error, CharacterError::NotGltf { .. }), "{error:?}");
    assert_mentions(&error, &["head.glb"]);
}

#[test]
fn unreadable_and_non_gltf_files_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nobody.glb");
    let error = load_err(&missing);
    assert!(matches!(error, CharacterError::File(_)), "{error:?}");
    assert_mentions(&error, &["nobody.glb", "no such file"]);
    // A directory or a device is refused as such, without reading it.
    let error = load_err(dir.path());
    assert_mentions(&error, &["a directory, not a regular file"]);
    let error = load_err(Path::new("/dev/zero"));
    assert_mentions(&error, &["/dev/zero", "a character device"]);

    let error = load_err_written(dir.path(), "notes.gltf", "this is not JSON");
    assert!(matches!(error, CharacterError::NotGltf { .. }), "{error:?}");
    assert_mentions(&error, &["notes.gltf", "broken JSON"]);

    // Valid JSON that references a missing accessor: fails glTF validation.
    let error = load_err_written(
        dir.path(),
        "invalid.gltf",
        r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":7}}]}]}"#,
    );
    assert!(matches!(error, CharacterError::NotGltf { .. }), "{error:?}");
    assert_mentions(&error, &["POSITION is accessor 7"]);

    // Valid JSON, glTF validation fails (POSITION without min/max, no buffer view 3).
    let error = load_err_written(
        dir.path(),
        "incomplete.gltf",
        r#"{"asset":{"version":"2.0"},"accessors":[{"bufferView":3,"componentType":5126,"count":3,"type":"VEC3"}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#,
    );
    assert!(matches!(error, CharacterError::NotGltf { .. }), "{error:?}");
    assert_mentions(&error, &["incomplete.gltf"]);

    let error = load_err_written(
        dir.path(),
        "draco.gltf",
        r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
            "extensionsRequired":["KHR_draco_mesh_compression"]}"#,
    );
    assert!(
        matches!(error, CharacterError::Unsupported { .. }),
        "{error:?}"
    );
    assert_mentions(&error, &["KHR_draco_mesh_compression", "draco.gltf"]);
}

#[test]
fn unknown_animation_lists_what_exists() {
    let fox = load("scenes/assets/Fox.glb");
    let error = fox
        .resolve_animation(&AnimationSelector::Name("Trot".to_string()))
        .unwrap_err();
    assert!(
        matches!(error, CharacterError::AnimationNotFound { .. }),
        "{error:?}"
    );
    assert_mentions(
        &error,
        &[
            "Fox.glb",
            "\"Trot\"",
            "0: \"Survey\"",
            "1: \"Walk\"",
            "2: \"Run\"",
        ],
    );
    let error = fox
        .resolve_animation(&AnimationSelector::Index(3))
        .unwrap_err();
    assert!(
        matches!(
            error,
            CharacterError::AnimationIndexOutOfRange {
                index: 3,
                count: 3,
                ..
            }
        ),
        "{error:?}"
    );
    assert_mentions(&error, &["Fox.glb"]);

    let rigged = load("scenes/assets/RiggedSimple.glb");
    let message = rigged
        .resolve_animation(&AnimationSelector::Name("Bend".to_string()))
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("#0"),
        "unnamed animations are listed as #i: {message}"
    );
}
