//! Frames read back by other programs, as a compositor's pipeline reads them: OpenEXR's own
//! `exrheader`, OpenImageIO's `oiiotool` and the pip `OpenEXR` module (with `tests/exr_readers.py`,
//! which checks the Cryptomatte, `Z`, `worldToNDC` and the effects with numpy and the pip `mmh3`
//! module, none of snell's code). `.ci/run` installs all three (Debian's `openexr` and
//! `openimageio-tools`, and a venv in `target/exr-venv`); a missing reader fails its test.
//!
//! The channel list expected here is written out by hand from the README's table, not taken from
//! the constants it checks.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use snell::output::exr::read_channels;

/// Every channel of a frame of `pool.toml` and its type, by the README's channel map.
const EXPECTED: [(&str, &str); 30] = [
    ("A", "f32"),
    ("ApparentDepth.Z", "f32"),
    ("B", "f32"),
    ("CryptoObject00.A", "f32"),
    ("CryptoObject00.B", "f32"),
    ("CryptoObject00.G", "f32"),
    ("CryptoObject00.R", "f32"),
    ("Direct.B", "f32"),
    ("Direct.G", "f32"),
    ("Direct.R", "f32"),
    ("FlagBoundary.X", "f16"),
    ("FlagConvergence.X", "f16"),
    ("FlagExtrapolated.X", "f16"),
    ("FlagPopping.X", "f16"),
    ("G", "f32"),
    ("IndexOB.X", "f32"),
    ("Motion.X", "f32"),
    ("Motion.Y", "f32"),
    ("P.X", "f32"),
    ("P.Y", "f32"),
    ("P.Z", "f32"),
    ("R", "f32"),
    ("Refraction.B", "f32"),
    ("Refraction.G", "f32"),
    ("Refraction.R", "f32"),
    ("SkyReflection.B", "f32"),
    ("SkyReflection.G", "f32"),
    ("SkyReflection.R", "f32"),
    ("WaterMatte.X", "f16"),
    ("Z", "f32"),
];

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A 160x90 frame 24 of `scenes/pool.toml` (every object, the ball and the stick partly under
/// water), rendered once for all the tests of this file.
fn frame() -> &'static Path {
    static FRAME: OnceLock<PathBuf> = OnceLock::new();
    FRAME.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("exr_readers");
        let _ = std::fs::remove_dir_all(&out);
        let scene = repo().join("scenes/pool.toml");
        let output = common::snell(
            &[
                "render",
                scene.to_str().unwrap(),
                "--frames",
                "24",
                "--size",
                "160x90",
                "--out",
                out.to_str().unwrap(),
            ],
            repo(),
        );
        assert!(
            output.status.success(),
            "render failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        out.join("pool.0024.exr")
    })
}

/// Runs a reader; a reader that is not installed fails the test, saying how to install it.
fn run(program: &str, args: &[&str], install: &str) -> String {
    let output = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|error| panic!("cannot run {program} ({error}): {install}"));
    assert!(
        output.status.success(),
        "{program} {args:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).expect("readers print UTF-8")
}

const DEBIAN_TOOLS: &str =
    "install Debian's openexr and openimageio-tools (bash .ci/run does: apt-get install -y openexr openimageio-tools)";

/// The float32 bits of every channel of an EXR file as snell's reader gives them.
fn bits_by_channel(path: &Path) -> BTreeMap<String, Vec<u32>> {
    read_channels(path)
        .unwrap()
        .channels
        .into_iter()
        .map(|(name, values)| (name, values.iter().map(|v| v.to_bits()).collect()))
        .collect()
}

#[test]
fn exrheader_lists_every_channel_with_its_type_and_the_standard_attributes() {
    let text = run("exrheader", &[frame().to_str().unwrap()], DEBIAN_TOOLS);
    let channel_lines: Vec<&str> = text
        .split("channels (type chlist):")
        .nth(1)
        .expect("exrheader prints the channel list")
        .lines()
        .skip(1)
        .take_while(|line| line.starts_with("    "))
        .collect();
    let listed: Vec<(String, &str)> = channel_lines
        .iter()
        .map(|line| {
            let (name, rest) = line.trim().split_once(", ").unwrap();
            let kind = if rest.starts_with("32-bit floating-point") {
                "f32"
            } else if rest.starts_with("16-bit floating-point") {
                "f16"
            } else {
                "other"
            };
            (name.to_string(), kind)
        })
        .collect();
    let expected: Vec<(String, &str)> = EXPECTED
        .iter()
        .map(|(name, kind)| (name.to_string(), *kind))
        .collect();
    assert_eq!(listed, expected, "{text}");
    for attribute in [
        "worldToNDC (type m44f)",
        "worldToCamera (type m44f)",
        "screenWindowWidth (type float)",
        "screenWindowCenter (type v2f)",
        "framesPerSecond (type rational): 24/1",
        "chromaticities (type chromaticities)",
        "snell.channelMap (type string): \"2\"",
        "cryptomatte/3ae39a5/name (type string): \"CryptoObject\"",
        "cryptomatte/3ae39a5/conversion (type string): \"uint32_to_float32\"",
    ] {
        assert!(text.contains(attribute), "no `{attribute}` in:\n{text}");
    }
    for absent in [
        "owner ",
        "capDate ",
        "near ",
        "far ",
        "fieldOfViewVertical ",
    ] {
        assert!(
            !text.lines().any(|line| line.starts_with(absent)),
            "`{absent}` is written by default:\n{text}"
        );
    }
}

#[test]
fn oiiotool_reads_every_layer_and_copies_ids_unchanged() {
    let path = frame().to_str().unwrap();
    let info = run("oiiotool", &["--info", "-v", path], DEBIAN_TOOLS);
    let list = info
        .lines()
        .find_map(|line| line.trim().strip_prefix("channel list: "))
        .expect("oiiotool prints the channel list");
    let mut listed: Vec<(String, &str)> = list
        .split(", ")
        .map(|entry| {
            let (name, kind) = entry.split_once(" (").unwrap();
            let kind = match kind.trim_end_matches(')') {
                "float" => "f32",
                "half" => "f16",
                _ => "other",
            };
            (name.to_string(), kind)
        })
        .collect();
    listed.sort();
    let mut expected: Vec<(String, &str)> = EXPECTED
        .iter()
        .map(|(name, kind)| (name.to_string(), *kind))
        .collect();
    expected.sort();
    assert_eq!(listed, expected, "{info}");
    assert!(info.contains("framesPerSecond: 24/1"), "{info}");
    assert!(info.contains("worldToNDC: "), "{info}");

    // What the first layout lost: OIIO used to divide u32 ids by 2^32 - 1 on the way to float.
    // Every layer, the index and the Cryptomatte ids included, must come out of OIIO bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("copy.exr");
    let index_only = dir.path().join("index.exr");
    run(
        "oiiotool",
        &[path, "-o", copy.to_str().unwrap()],
        DEBIAN_TOOLS,
    );
    run(
        "oiiotool",
        &[
            path,
            "--ch",
            "IndexOB.X",
            "-d",
            "float",
            "-o",
            index_only.to_str().unwrap(),
        ],
        DEBIAN_TOOLS,
    );
    let original = bits_by_channel(frame());
    let copied = bits_by_channel(&copy);
    assert_eq!(
        copied.keys().collect::<Vec<_>>(),
        original.keys().collect::<Vec<_>>()
    );
    for (name, bits) in &original {
        assert!(copied[name] == *bits, "{name} changed in oiiotool's copy");
    }
    let index = read_channels(&index_only).unwrap();
    let values = index
        .get("IndexOB.X")
        .expect("oiiotool kept the channel's name");
    assert_eq!(
        values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        original["IndexOB.X"]
    );
    assert!(
        values.iter().any(|&v| v >= 4.0),
        "the ball's index survives"
    );
}

/// The Python interpreter with the pip `OpenEXR`, `numpy` and `mmh3` modules: `SNELL_EXR_PYTHON`,
/// or the venv `.ci/run` makes in `target/exr-venv`.
fn python() -> PathBuf {
    let path = std::env::var_os("SNELL_EXR_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("target/exr-venv/bin/python3"));
    assert!(
        path.exists(),
        "{} is missing: run bash .ci/run, or python3 -m venv target/exr-venv && \
         target/exr-venv/bin/pip install OpenEXR numpy mmh3 (or set SNELL_EXR_PYTHON)",
        path.display()
    );
    path
}

#[test]
fn the_pip_openexr_module_reads_every_layer_and_decodes_the_cryptomatte() {
    let dir = tempfile::tempdir().unwrap();
    let script = repo().join("tests/exr_readers.py");
    let output = Command::new(python())
        .args([
            script.as_os_str(),
            frame().as_os_str(),
            dir.path().as_os_str(),
        ])
        .output()
        .expect("python runs");
    assert!(
        output.status.success(),
        "tests/exr_readers.py failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    // The module's channel list and every value equal snell's own reader's, bit for bit.
    let types: BTreeMap<String, String> =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("channels.json")).unwrap())
            .unwrap();
    let expected: BTreeMap<String, String> = EXPECTED
        .iter()
        .map(|(name, kind)| {
            let kind = if *kind == "f16" { "HALF" } else { "FLOAT" };
            (name.to_string(), kind.to_string())
        })
        .collect();
    assert_eq!(types, expected);
    for (name, bits) in bits_by_channel(frame()) {
        let raw = std::fs::read(dir.path().join(format!("{name}.f32"))).unwrap();
        let read: Vec<u32> = raw
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        assert!(read == bits, "{name}: the module reads other values");
    }
}

/// `--half --compression piz`: exrheader sees a half beauty, float32 data layers, PIZ, and the
/// header's `snell.output` says so; oiiotool reads the frame whole.
#[test]
fn half_beauty_and_piz_are_what_the_readers_see() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo().join("scenes/tiny.toml");
    let output = common::snell(
        &[
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "1",
            "--size",
            "96x54",
            "--half",
            "--compression",
            "piz",
            "--out",
            dir.path().to_str().unwrap(),
        ],
        repo(),
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let path = dir.path().join("tiny.0001.exr");
    let text = run("exrheader", &[path.to_str().unwrap()], DEBIAN_TOOLS);
    for line in [
        "    R, 16-bit floating-point",
        "    A, 16-bit floating-point",
        "    Z, 32-bit floating-point",
        "    P.X, 32-bit floating-point",
        "    IndexOB.X, 32-bit floating-point",
        "    CryptoObject00.R, 32-bit floating-point",
        "compression (type compression): piz",
        "snell.output (type string): \"beauty=half compression=piz layers=all\"",
    ] {
        assert!(text.contains(line), "no `{line}` in:\n{text}");
    }
    let info = run(
        "oiiotool",
        &["--info", "-v", path.to_str().unwrap()],
        DEBIAN_TOOLS,
    );
    assert!(
        info.contains("R (half)") && info.contains("Z (float)"),
        "{info}"
    );
    assert!(info.contains("compression: \"piz\""), "{info}");
}

/// `--layers comp`: exrheader sees only the half beauty, `Z`, the IDs and the matte, and the
/// header says `layers=comp`; `--resume` keeps the frame for the same choice and renders it again
/// for another; an unknown layer is named with the valid ones; `snell compare` names the layer it
/// lacks; `snell diff` fails a test frame lacking `P` and warns when the reference lacks it.
#[test]
fn layers_comp_writes_what_it_says_and_the_tools_cope() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo().join("scenes/tiny.toml");
    let render = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--frames",
            "1",
            "--size",
            "96x54",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        common::snell(&args, repo())
    };
    let text = |output: &std::process::Output| {
        format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        )
    };
    let (all, comp) = (dir.path().join("all"), dir.path().join("comp"));
    for (out, extra) in [(&all, &[][..]), (&comp, &["--layers", "comp"][..])] {
        let output = render(out, extra);
        assert!(output.status.success(), "{}", text(&output));
    }
    let path = comp.join("tiny.0001.exr");
    let header = run("exrheader", &[path.to_str().unwrap()], DEBIAN_TOOLS);
    for line in [
        "    R, 16-bit floating-point",
        "    A, 16-bit floating-point",
        "    Z, 32-bit floating-point",
        "    IndexOB.X, 32-bit floating-point",
        "    CryptoObject00.A, 32-bit floating-point",
        "    WaterMatte.X, 16-bit floating-point",
        "cryptomatte/",
        "snell.output (type string): \"beauty=half compression=zip layers=comp\"",
    ] {
        assert!(header.contains(line), "no `{line}` in:\n{header}");
    }
    for absent in [
        "P.X",
        "ApparentDepth",
        "Direct",
        "Refraction",
        "SkyReflection",
        "Flag",
    ] {
        assert!(!header.contains(absent), "`{absent}` in:\n{header}");
    }
    let all_header = run(
        "exrheader",
        &[all.join("tiny.0001.exr").to_str().unwrap()],
        DEBIAN_TOOLS,
    );
    assert!(
        all_header.contains("layers=all\"") && all_header.contains("    P.X, 32-bit"),
        "{all_header}"
    );

    // The same choice resumes; another renders the frame again, with its layers.
    let resumed = render(&comp, &["--layers", "COMP", "--resume"]);
    assert!(
        text(&resumed).contains("nothing to render"),
        "{}",
        text(&resumed)
    );
    let again = render(&comp, &["--resume"]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        !text(&again).contains("nothing to render"),
        "{}",
        text(&again)
    );
    assert!(read_channels(&path).unwrap().get("P.X").is_some());
    let output = render(&comp, &["--layers", "comp"]);
    assert!(output.status.success(), "{}", text(&output));

    let unknown = render(&dir.path().join("x"), &["--layers", "comp,Motoin"]);
    assert!(!unknown.status.success());
    let message = text(&unknown);
    for word in [
        "unknown layer `Motoin`",
        "all, comp",
        "beauty, Z, ApparentDepth",
        "FlagExtrapolated",
    ] {
        assert!(message.contains(word), "no `{word}` in: {message}");
    }
    assert!(!dir.path().join("x").join("tiny.0001.exr").exists());

    let (all_frame, comp_frame) = (all.join("tiny.0001.exr"), comp.join("tiny.0001.exr"));
    let compare = common::snell(
        &[
            "compare",
            all_frame.to_str().unwrap(),
            comp_frame.to_str().unwrap(),
        ],
        repo(),
    );
    assert_eq!(compare.status.code(), Some(2), "{}", text(&compare));
    assert!(
        text(&compare).contains("tiny.0001.exr: has no `P` layer (P.X, P.Y, P.Z)"),
        "{}",
        text(&compare)
    );
    let diff = |a: &Path, b: &Path| {
        // In the temporary folder: a failing diff writes its heat maps under the working folder.
        common::snell(
            &["diff", a.to_str().unwrap(), b.to_str().unwrap()],
            dir.path(),
        )
    };
    let lacking_test = diff(&all_frame, &comp_frame);
    assert_eq!(
        lacking_test.status.code(),
        Some(2),
        "{}",
        text(&lacking_test)
    );
    assert!(
        text(&lacking_test).contains("the test frame has no `P` layer"),
        "{}",
        text(&lacking_test)
    );
    let lacking_reference = diff(&comp_frame, &all_frame);
    assert!(
        text(&lacking_reference).contains("the reference has no `P` layer"),
        "{}",
        text(&lacking_reference)
    );
    assert!(!text(&lacking_reference).contains("no `Z` layer"));
}
