//! Bad scene input: every case must give a one-paragraph `SceneError` naming the file, the line and
//! column of the offending text, and the key's path.

use std::path::{Path, PathBuf};

use snell::scene::{Scene, SceneError};

/// Parses `text` as if it were `dir/bad.toml` and returns the error it must produce.
fn error_of(text: &str, dir: &Path) -> SceneError {
    let path = dir.join("bad.toml");
    match Scene::parse(text, &path) {
        Ok(_) => panic!("scene was accepted:\n{text}"),
        Err(e) => e,
    }
}

/// Asserts the error names the file, points at `line:column`, names `key`, and mentions `needle`.
fn assert_error(text: &str, line: usize, column: usize, key: &str, needle: &str) -> String {
    let dir = PathBuf::from("scenes");
    let error = error_of(text, &dir);
    let message = error.to_string();
    let location = format!("{}:{line}:{column}: ", dir.join("bad.toml").display());
    assert!(
        message.starts_with(&location),
        "expected {location:?} at the start of:\n{message}"
    );
    assert!(message.contains(key), "expected key {key:?} in:\n{message}");
    assert!(
        message.contains(needle),
        "expected {needle:?} in:\n{message}"
    );
    assert!(
        !message.contains('\n'),
        "the message must be one paragraph:\n{message}"
    );
    assert_eq!(error.line_column(), Some((line, column)));
    message
}

#[test]
fn malformed_toml() {
    // The second `=` is where the parser gives up.
    let message = assert_error("[water]\nlevel_m = = 0.0\n", 2, 11, "", "malformed TOML");
    assert!(message.contains("fix the syntax"));
}

#[test]
fn unclosed_table_header() {
    assert_error(
        "name = \"x\"\n[water\nlevel_m = 0.0\n",
        2,
        7,
        "",
        "malformed TOML",
    );
}

#[test]
fn unknown_key() {
    let message = assert_error(
        "[water]\nlevle_m = 0.0\n",
        2,
        1,
        "water.levle_m",
        "unknown field `levle_m`",
    );
    assert!(message.contains("correct its spelling"));
}

#[test]
fn unknown_key_in_an_array_of_tables() {
    let text = "[[object]]\nshape = \"box\"\n\n[[object]]\nshape = \"sphere\"\nradius = 0.3\n";
    assert_error(text, 6, 1, "object[1].radius", "unknown field `radius`");
}

#[test]
fn key_of_another_shape() {
    let text = "[[object]]\nshape = \"box\"\nradius_m = 0.3\n";
    assert_error(
        text,
        3,
        1,
        "object[0].radius_m",
        "does not apply to shape = \"box\"",
    );
}

#[test]
fn resolution_zero() {
    let text = "name = \"t\"\n\n[water]\nresolution = [0, 64]\n";
    let message = assert_error(text, 4, 15, "water.resolution[0]", "from 1 to 8192");
    assert!(
        message.contains("(got 0)") && message.contains("e.g. resolution = [128, 64]"),
        "{message}"
    );
}

#[test]
fn index_of_refraction_not_positive() {
    assert_error(
        "[water]\nn_below = 0.0\n",
        2,
        11,
        "water.n_below",
        "must be from 0.1 to 10 (got 0.0)",
    );
    assert_error(
        "[water]\nn_above = -1\n",
        2,
        11,
        "water.n_above",
        "must be from 0.1 to 10 (got -1)",
    );
}

#[test]
fn nan_and_infinity() {
    let text = "[[water.wave]]\namplitude_m = nan\nwavelength_m = 2.0\n";
    assert_error(text, 2, 15, "water.wave[0].amplitude_m", "finite");
    assert_error(
        "[[camera]]\neye = [0, inf, -4]\ntarget = [0, 0, 0]\n",
        2,
        11,
        "camera[0].eye[1]",
        "finite",
    );
    assert_error("[timeline]\nfps = -inf\n", 2, 7, "timeline.fps", "finite");
}

#[test]
fn missing_texture_image() {
    let text = "[[object]]\nshape = \"box\"\ntexture = { image = \"no-such.png\" }\n";
    let message = assert_error(text, 3, 21, "object[0].texture.image", "not found");
    assert!(message.contains("no-such.png"));
}

#[test]
fn undecodable_texture_image_fails_when_building() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("broken.png"), b"not a png at all").unwrap();
    let path = dir.path().join("scene.toml");
    let text = "[[object]]\nshape = \"quad\"\n\n[object.texture]\nimage = \"broken.png\"\n";
    let scene = Scene::parse(text, &path).expect("the file exists, so parsing passes");
    let message = scene.build_objects().unwrap_err().to_string();
    let location = format!("{}:5:9: ", path.display());
    assert!(
        message.starts_with(&location),
        "expected {location:?} at the start of:\n{message}"
    );
    assert!(
        message.contains("object[0].texture.image") && message.contains("broken.png"),
        "{message}"
    );
}

#[test]
fn keyframes_out_of_order() {
    let text = "[[camera]]\nframe = 10\neye = [0, 2, -4]\ntarget = [0, 0, 0]\n\n\
                [[camera]]\nframe = 5\neye = [0, 2, -4]\ntarget = [0, 0, 0]\n";
    assert_error(text, 7, 9, "camera[1].frame", "increasing time order");
}

#[test]
fn empty_frame_range_and_bad_fps() {
    assert_error(
        "[timeline]\nframes = [48, 1]\n",
        2,
        10,
        "timeline.frames",
        "empty",
    );
    assert_error(
        "[timeline]\nfps = 0\n",
        2,
        7,
        "timeline.fps",
        "must be from 1 to 1000 frames/s (got 0)",
    );
}

#[test]
fn unknown_shape() {
    let message = assert_error(
        "[[object]]\nshape = \"ball\"\n",
        2,
        9,
        "object[0].shape",
        "unknown shape",
    );
    assert!(message.contains("\"sphere\""));
}

#[test]
fn camera_under_water() {
    let text = "[[camera]]\neye = [0, -0.5, 0]\ntarget = [0, -1, 1]\n";
    assert_error(text, 2, 7, "camera[0].eye", "under the water");
}

#[test]
fn wrong_type() {
    assert_error(
        "[water]\nresolution = \"high\"\n",
        2,
        14,
        "water.resolution",
        "invalid type",
    );
}

#[test]
fn unreadable_file_names_it() {
    let path = Path::new("scenes/does-not-exist.toml");
    let message = Scene::load(path).unwrap_err().to_string();
    assert!(
        message.starts_with("scenes/does-not-exist.toml: no such file"),
        "{message}"
    );
}

/// `[water.ripples]`: the old one-speed key is refused with what replaced it, and the dispersion
/// relation's inputs are bounded (`src/scene/limits.rs`).
#[test]
fn ripple_physics_keys() {
    let message = assert_error(
        "[water.ripples]\nspeed_m_per_s = 0.45\n",
        2,
        17,
        "water.ripples.speed_m_per_s",
        "no longer have one speed",
    );
    assert!(message.contains("remove speed_m_per_s"), "{message}");
    assert_error(
        "[water.ripples]\ndepth_m = 0.0\n",
        2,
        11,
        "water.ripples.depth_m",
        "from 0.005 to 1000 m",
    );
    assert_error(
        "[water.ripples]\nsurface_tension_n_per_m = -0.07\n",
        2,
        27,
        "water.ripples.surface_tension_n_per_m",
        "from 0 to 1 N/m",
    );
    assert_error(
        "[water.ripples]\ndensity_kg_per_m3 = 1e9\n",
        2,
        21,
        "water.ripples.density_kg_per_m3",
        "from 100 to 20000 kg/m^3",
    );
}

#[test]
fn vessel_kind_missing_or_unknown() {
    let message = assert_error(
        "[[vessel]]\nkind = \"bowl\"\n",
        2,
        8,
        "vessel[0].kind",
        "unknown vessel kind \"bowl\"",
    );
    assert!(message.contains("\"cylinder\""), "{message}");
    assert_error(
        "name = \"x\"\n[[vessel]]\nglass_index = 1.5\n",
        2,
        1,
        "vessel[0]",
        "a vessel needs a kind",
    );
}

#[test]
fn vessel_key_of_the_other_kind_and_missing_keys() {
    let message = assert_error(
        "[[vessel]]\nkind = \"pane\"\ninner_radius_m = 0.03\n",
        3,
        1,
        "vessel[0].inner_radius_m",
        "does not apply to kind = \"pane\"",
    );
    assert!(message.contains("\"thickness_m\""), "{message}");
    assert_error(
        "[[vessel]]\nkind = \"pane\"\nposition = [0.0, 0.3, 1.0]\nnormal = [0.0, 0.0, 1.0]\n",
        1,
        1,
        "vessel[0]",
        "a pane needs size_m",
    );
    assert_error(
        "[[vessel]]\nkind = \"cylinder\"\nbase = [0.0, 0.0, 0.0]\nouter_radius_m = 0.04\nheight_m = 0.1\n",
        1,
        1,
        "vessel[0]",
        "a cylinder needs inner_radius_m",
    );
}

#[test]
fn vessel_geometry_that_cannot_be() {
    assert_error(
        "[[vessel]]\nkind = \"cylinder\"\nbase = [0.0, 0.0, 0.0]\ninner_radius_m = 0.05\nouter_radius_m = 0.04\nheight_m = 0.1\n",
        4,
        18,
        "vessel[0].inner_radius_m",
        "the wall has no thickness",
    );
    assert_error(
        "[[vessel]]\nkind = \"pane\"\nposition = [0.0, 0.3, 1.0]\nnormal = [0.0, 0.0, 0.0]\nsize_m = [1.0, 0.5]\n",
        4,
        10,
        "vessel[0].normal",
        "cannot be the zero vector",
    );
    assert_error(
        "[[vessel]]\nkind = \"pane\"\nposition = [0.0, 0.3, 1.0]\nnormal = [0.0, 1.0, 0.0]\nsize_m = [1.0, 0.5]\n",
        4,
        10,
        "vessel[0].normal",
        "along its normal",
    );
    assert_error(
        "[[vessel]]\nkind = \"pane\"\nthickness_m = 0.0\n",
        3,
        15,
        "vessel[0].thickness_m",
        "more than 0 and at most 1 m",
    );
    assert_error(
        "[[vessel]]\nkind = \"cylinder\"\ninside = \"oil\"\n",
        3,
        10,
        "vessel[0].inside",
        "unknown medium \"oil\"",
    );
}
