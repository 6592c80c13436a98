//! The fuzz corpus's generator and runner (issue 19 point 5), shared by `tests/fuzz_corpus.rs`
//! (CI: a fixed seed, every case run) and `tests/fuzz_search.rs` (outside CI: proptest over the
//! same mutations, for a bounded time).
//!
//! A case is a folder of files (a scene, maybe a model, an image, an EXR, a FIFO) and the `snell`
//! commands to run in it. Cases are made by mutating the shipped inputs (`scenes/*.toml`,
//! `scenes/hard/*.toml`, `scenes/assets/*.glb`, `tests/gltf/*`) through their structure: the
//! scene's TOML tree and the glTF's JSON tree (a GLB's JSON chunk), one or a few keys at a time,
//! plus byte-level damage (truncation, non-UTF-8 bytes). The generator, not a corpus, is committed:
//! the cases follow the shipped scenes and models as they change, the seed makes every run the
//! same, and a case's name says how to make it again.
//!
//! The runner runs every command of a case against the real binary with a wall-clock timeout and
//! an address-space cap (`RLIMIT_AS`, set between fork and exec), and judges what it sees: exit 0
//! or 2 (the commands' own codes for `diff`, `check`, `compare`), never 101, a signal, a timeout
//! or an allocation failure, and a frame written with exit 0 holds only finite samples.

// Each test crate uses part of this module.
#![allow(dead_code)]

use snell::seeded::SplitMix64;
use std::collections::BTreeMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use toml::Value;

/// The repository root (where Cargo.toml is).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Address-space cap of every `snell` the corpus runs. lavapipe and the binary map about 1 GiB
/// before any frame; `SNELL_MAX_MEMORY` (below) keeps snell's own estimate well under the cap, so
/// a scene that gets past the estimate and then exhausts the cap is a finding.
pub const MEMORY_CAP_BYTES: u64 = 4 << 30;
pub const SNELL_MAX_MEMORY: &str = "2G";
/// A command that runs longer than this is a hang. A 16x16 frame takes 1-3 s in CI's debug build;
/// the bound is generous because the two workers share two cores with lavapipe's threads.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(90);

// ---------------------------------------------------------------------------------------------
// Cases

/// Where a command's stdout goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sink {
    Piped,
    /// A pipe whose reader is gone (`snell info ... | true`).
    ClosedPipe,
    DevFull,
}

/// What a command may answer.
#[derive(Clone, Debug, PartialEq)]
pub enum Expect {
    /// `render`, `info`: exit 0 or 2; after a render's exit 0, every frame under `out/` is read
    /// back and must hold only finite samples.
    Scene,
    /// `diff`, `check`, `compare`: their documented codes 0, 1, 2, 4.
    Frames,
    /// `diff`, `check` given a NaN the golden lacks: must not pass (exit 1, 2 or 4).
    NotPass,
    /// Exactly these codes.
    Codes(Vec<i32>),
    /// Exit 2 with every one of these in stderr.
    Refused(Vec<String>),
}

#[derive(Clone, Debug)]
pub struct Step {
    pub args: Vec<String>,
    pub stdout: Sink,
    pub expect: Expect,
}

#[derive(Clone, Debug, Default)]
pub struct Case {
    /// How the case was made (base file, mutations), unique in a corpus.
    pub name: String,
    /// Files to write, relative to the case folder.
    pub files: Vec<(String, Vec<u8>)>,
    /// FIFOs to make, relative to the case folder.
    pub fifos: Vec<String>,
    pub steps: Vec<Step>,
    /// Whether the case renders (what makes it slow).
    pub renders: bool,
}

impl Case {
    fn step(&mut self, args: &[&str], expect: Expect) {
        self.steps.push(Step {
            args: args.iter().map(|s| s.to_string()).collect(),
            stdout: Sink::Piped,
            expect,
        });
    }

    /// `info SCENE` and `render SCENE --size 16x16 --frames FRAME` (cheap when the scene is
    /// refused, which most cases are).
    fn info_and_render(&mut self, scene: &str, frame: i64, extra: &[&str]) {
        self.step(&["info", scene], Expect::Scene);
        self.render(scene, frame, extra);
    }

    /// `render SCENE --size 16x16 --frames FRAME` only: `info` of a scene that loads costs
    /// about a second (it asks for the GPU adapter), so generated cases run it one in three.
    fn render(&mut self, scene: &str, frame: i64, extra: &[&str]) {
        let frame = frame.to_string();
        let mut args = vec![
            "render", scene, "--out", "out", "--size", "16x16", "--frames", &frame,
        ];
        args.extend_from_slice(extra);
        self.step(&args, Expect::Scene);
        self.renders = true;
    }
}

// ---------------------------------------------------------------------------------------------
// The shipped inputs

pub struct SceneBase {
    /// Relative to `scenes/`, e.g. `hard/grazing_eye.toml`.
    pub name: String,
    pub text: String,
}

pub fn scene_bases() -> Vec<SceneBase> {
    let mut bases = Vec::new();
    for folder in ["", "hard/"] {
        let dir = repo().join("scenes").join(folder);
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".toml"))
            .collect();
        names.sort();
        for n in names {
            bases.push(SceneBase {
                name: format!("{folder}{n}"),
                text: std::fs::read_to_string(dir.join(&n)).unwrap(),
            });
        }
    }
    assert!(
        bases.len() >= 9,
        "the shipped scenes are gone: {}",
        bases.len()
    );
    bases
}

/// A model: its JSON, its binary chunk (GLB) and the files beside it it names.
#[derive(Clone)]
pub struct ModelBase {
    pub name: String,
    pub json: serde_json::Value,
    pub bin: Option<Vec<u8>>,
    pub sidecars: Vec<(String, Vec<u8>)>,
    /// Metres per file unit that makes it about a metre tall.
    pub scale: f64,
}

pub fn model_bases() -> Vec<ModelBase> {
    let mut bases = Vec::new();
    let assets = repo().join("scenes/assets");
    for (name, scale) in [
        ("Fox.glb", 0.008),
        ("CesiumMan.glb", 0.5),
        ("RiggedSimple.glb", 0.2),
    ] {
        let (json, bin) = split_glb(&std::fs::read(assets.join(name)).unwrap()).unwrap();
        bases.push(ModelBase {
            name: name.into(),
            json,
            bin,
            sidecars: vec![],
            scale,
        });
    }
    let dir = repo().join("tests/gltf");
    for name in ["step.gltf", "cubic.gltf", "external.gltf"] {
        let json = serde_json::from_slice(&std::fs::read(dir.join(name)).unwrap()).unwrap();
        let sidecars = if name == "external.gltf" {
            ["external.bin", "external_texture.png"]
                .iter()
                .map(|s| (s.to_string(), std::fs::read(dir.join(s)).unwrap()))
                .collect()
        } else {
            vec![]
        };
        bases.push(ModelBase {
            name: name.into(),
            json,
            bin: None,
            sidecars,
            scale: 0.3,
        });
    }
    let (json, bin) = split_glb(&std::fs::read(dir.join("eight_influences.glb")).unwrap()).unwrap();
    bases.push(ModelBase {
        name: "eight_influences.glb".into(),
        json,
        bin,
        sidecars: vec![],
        scale: 0.3,
    });
    bases
}

/// A GLB's JSON and BIN chunks.
pub fn split_glb(bytes: &[u8]) -> Option<(serde_json::Value, Option<Vec<u8>>)> {
    let u32_at = |at: usize| Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?));
    if bytes.get(0..4)? != b"glTF" {
        return None;
    }
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at + 8 <= bytes.len() {
        let len = u32_at(at)? as usize;
        let kind = u32_at(at + 4)?;
        let data = bytes.get(at + 8..at + 8 + len)?;
        match kind {
            0x4E4F_534A => json = Some(serde_json::from_slice(data).ok()?),
            0x004E_4942 => bin = Some(data.to_vec()),
            _ => {}
        }
        at += 8 + len;
    }
    Some((json?, bin))
}

pub fn join_glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&0x4E4F_534Au32.to_le_bytes());
    out.extend_from_slice(&json);
    if let Some(bin) = bin {
        let mut bin = bin.to_vec();
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(&0x004E_4942u32.to_le_bytes());
        out.extend_from_slice(&bin);
    }
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    out
}

// ---------------------------------------------------------------------------------------------
// Random choices

pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::new(seed))
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.0.next_u64() % n.max(1) as u64) as usize
    }
    pub fn chance(&mut self, p: f64) -> bool {
        self.0.unit() < p
    }
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
    pub fn u64(&mut self) -> u64 {
        self.0.next_u64()
    }
}

// ---------------------------------------------------------------------------------------------
// Scene (TOML) mutations

#[derive(Clone, Debug, PartialEq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

pub fn path_text(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// Every node of a TOML tree (tables, arrays and leaves), depth first.
pub fn toml_paths(value: &Value) -> Vec<Vec<Seg>> {
    fn walk(value: &Value, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
        match value {
            Value::Table(t) => {
                for (k, v) in t {
                    path.push(Seg::Key(k.clone()));
                    out.push(path.clone());
                    walk(v, path, out);
                    path.pop();
                }
            }
            Value::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    path.push(Seg::Index(i));
                    out.push(path.clone());
                    walk(v, path, out);
                    path.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(value, &mut Vec::new(), &mut out);
    out
}

pub fn toml_get_mut<'a>(value: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut at = value;
    for seg in path {
        at = match (seg, at) {
            (Seg::Key(k), Value::Table(t)) => t.get_mut(k)?,
            (Seg::Index(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(at)
}

/// Removes the node at `path` (a key of a table or an element of an array).
pub fn toml_remove(value: &mut Value, path: &[Seg]) -> bool {
    let Some((last, parent)) = path.split_last() else {
        return false;
    };
    match (last, toml_get_mut(value, parent)) {
        (Seg::Key(k), Some(Value::Table(t))) => t.remove(k).is_some(),
        (Seg::Index(i), Some(Value::Array(a))) if *i < a.len() => {
            a.remove(*i);
            true
        }
        _ => false,
    }
}

/// Numbers at and past every edge: zero, signs, denormal-small, f32-overflowing, huge, not a
/// number, and integers past 32 bits.
pub fn extreme_numbers(original: Option<&Value>) -> Vec<(String, Value)> {
    let mut v: Vec<(String, Value)> = [
        0.0,
        -0.0,
        -1.0,
        1e-50,
        -1e-50,
        1e-310,
        1e39,
        -1e39,
        1e300,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        4294967295.0,
        1e7,
        1e12,
        0.5,
        179.999,
        3e38,
    ]
    .into_iter()
    .map(|x| (format!("{x:?}"), Value::Float(x)))
    .collect();
    for i in [
        0i64,
        -1,
        1,
        4294967295,
        4294967296,
        -4294967295,
        2147483648,
        i64::MAX,
        i64::MIN,
        16384,
        65536,
    ] {
        v.push((i.to_string(), Value::Integer(i)));
    }
    match original {
        Some(Value::Float(x)) => {
            v.push((format!("{:?}", x * 1e6), Value::Float(x * 1e6)));
            v.push((format!("{:?}", -x), Value::Float(-x)));
            v.push((format!("{:?}", x * 1e-6), Value::Float(x * 1e-6)));
        }
        Some(Value::Integer(i)) => {
            v.push((
                (i.saturating_mul(1000)).to_string(),
                Value::Integer(i.saturating_mul(1000)),
            ));
            v.push(((-i).to_string(), Value::Integer(-i)));
            v.push((
                format!("{:?}", *i as f64 + 0.5),
                Value::Float(*i as f64 + 0.5),
            ));
        }
        _ => {}
    }
    v
}

pub fn wrong_types() -> Vec<(String, Value)> {
    let mut t = toml::Table::new();
    t.insert("x".into(), Value::Integer(1));
    vec![
        ("\"text\"".into(), Value::String("text".into())),
        ("\"\"".into(), Value::String(String::new())),
        ("true".into(), Value::Boolean(true)),
        ("[]".into(), Value::Array(vec![])),
        (
            "[\"a\", 1]".into(),
            Value::Array(vec![Value::String("a".into()), Value::Integer(1)]),
        ),
        (
            "[[1.0]]".into(),
            Value::Array(vec![Value::Array(vec![Value::Float(1.0)])]),
        ),
        ("{x = 1}".into(), Value::Table(t)),
        (
            "[1.0, 2.0, 3.0, 4.0, 5.0]".into(),
            Value::Array((1..=5).map(|i| Value::Float(i as f64)).collect()),
        ),
        ("[1.0]".into(), Value::Array(vec![Value::Float(1.0)])),
        (
            "date".into(),
            "1979-05-27T07:32:00Z"
                .parse::<toml::value::Datetime>()
                .map(Value::Datetime)
                .unwrap(),
        ),
    ]
}

pub fn strange_strings() -> Vec<String> {
    vec![
        "ti\u{0}ny".into(),
        "n".repeat(300),
        "../../etc/passwd".into(),
        "/".into(),
        "".into(),
        " ".into(),
        "a/b".into(),
        "con".into(),
        "é\u{202e}x".into(),
        "fox\nnewline".into(),
        "cube".into(),
        "Walk".into(),
        "fifo".into(),
        "/dev/zero".into(),
        "missing.glb".into(),
        "x".repeat(5000),
    ]
}

/// One structural mutation of a scene tree: its description, or None where it does not apply.
pub fn mutate_toml(tree: &mut Value, rng: &mut Rng) -> Option<String> {
    let paths = toml_paths(tree);
    if paths.is_empty() {
        return None;
    }
    let path = rng.pick(&paths).clone();
    let at = path_text(&path);
    let kind = rng.below(100);
    let node = toml_get_mut(tree, &path)?;
    if kind < 38 {
        // A number at an edge (on numbers mostly; anywhere else it is a type error).
        if !matches!(node, Value::Float(_) | Value::Integer(_)) && rng.chance(0.7) {
            return None;
        }
        let choices = extreme_numbers(Some(node));
        let (text, value) = rng.pick(&choices).clone();
        *node = value;
        Some(format!("{at} = {text}"))
    } else if kind < 50 {
        let choices = wrong_types();
        let (text, value) = rng.pick(&choices).clone();
        *node = value;
        Some(format!("{at} = {text} (wrong type)"))
    } else if kind < 60 {
        // Strings: names, enum values, file paths.
        if !matches!(node, Value::String(_)) && rng.chance(0.8) {
            return None;
        }
        let choices = strange_strings();
        let s = rng.pick(&choices).clone();
        let shown: String = s.chars().take(30).collect();
        *node = Value::String(s.clone());
        Some(format!("{at} = {shown:?} ({} chars)", s.chars().count()))
    } else if kind < 66 {
        toml_remove(tree, &path).then(|| format!("{at} removed"))
    } else if kind < 78 {
        // An array shortened, emptied or lengthened.
        let Value::Array(a) = node else { return None };
        let how = rng.below(3);
        match how {
            0 if !a.is_empty() => {
                a.pop();
            }
            1 => a.clear(),
            _ => {
                let copy = a.first().cloned().unwrap_or(Value::Integer(1));
                for _ in 0..1 + rng.below(3) {
                    a.push(copy.clone());
                }
            }
        }
        Some(format!("{at} resized to {}", a.len()))
    } else if kind < 84 {
        // A key the format does not know, in a table.
        let Value::Table(t) = node else { return None };
        t.insert("bogus_key".into(), Value::Integer(1));
        Some(format!("{at}.bogus_key added"))
    } else if kind < 90 {
        // An element of an array of tables repeated (many cameras, objects, waves).
        let (Seg::Index(_), Some((_, parent))) = (path.last()?, path.split_last()) else {
            return None;
        };
        let copy = toml_get_mut(tree, &path)?.clone();
        let Some(Value::Array(a)) = toml_get_mut(tree, parent) else {
            return None;
        };
        // 1,100: past the limits of objects (1,024) and waves (256).
        let n = *rng.pick(&[1usize, 1100]);
        for _ in 0..n {
            a.push(copy.clone());
        }
        Some(format!("{at} repeated {n} more times"))
    } else {
        // Two numbers of one array swapped or made equal (min above max, first frame after
        // last, eye on target).
        let Value::Array(a) = node else { return None };
        if a.len() < 2 {
            return None;
        }
        if rng.chance(0.5) {
            a.swap(0, 1);
            Some(format!("{at}: first two swapped"))
        } else {
            a[1] = a[0].clone();
            Some(format!("{at}: second = first"))
        }
    }
}

/// Camera edits that keep every value legal but aim at the degenerate cases: straight down,
/// straight up, eye on target, two keys passing over the target, keys on one frame.
pub fn mutate_camera(tree: &mut Value, rng: &mut Rng) -> Option<String> {
    let cams = tree.get_mut("camera")?.as_array_mut()?;
    if cams.is_empty() {
        return None;
    }
    let i = rng.below(cams.len());
    let target = cams[i]
        .get("target")
        .and_then(|t| t.as_array())
        .map(|t| {
            t.iter()
                .map(|x| x.as_float().unwrap_or(0.0))
                .collect::<Vec<_>>()
        })
        .unwrap_or(vec![0.0, 0.0, 0.0]);
    let arr = |v: [f64; 3]| Value::Array(v.iter().map(|x| Value::Float(*x)).collect());
    let (tx, ty, tz) = (target[0], target[1], target[2]);
    let kind = rng.below(6);
    let cam = cams[i].as_table_mut()?;
    match kind {
        0 => {
            cam.insert("eye".into(), arr([tx, ty + 3.0, tz]));
            Some(format!("camera[{i}] straight down"))
        }
        1 => {
            cam.insert("eye".into(), arr([tx, ty - 3.0, tz]));
            Some(format!("camera[{i}] straight up"))
        }
        2 => {
            cam.insert("eye".into(), arr([tx, ty, tz]));
            Some(format!("camera[{i}] eye on target"))
        }
        3 => {
            cam.insert("eye".into(), arr([tx + 1e-7, ty + 3.0, tz]));
            Some(format!("camera[{i}] 1e-7 from straight down"))
        }
        4 => {
            // Two keys either side of the target: the path passes over (or through) it.
            cam.insert("eye".into(), arr([tx - 2.0, ty + 1.0, tz]));
            cam.insert("frame".into(), Value::Integer(1));
            cam.remove("time_secs");
            let mut other = cam.clone();
            other.insert("eye".into(), arr([tx + 2.0, ty + 1.0, tz]));
            other.insert("frame".into(), Value::Integer(3));
            cams.truncate(i + 1);
            cams.push(Value::Table(other));
            Some(format!("camera[{i}..{}] pass over the target", i + 1))
        }
        _ => {
            // Two keys on one frame.
            let copy = cams[i].clone();
            cams.insert(i, copy);
            Some(format!("camera[{i}] duplicated on its frame"))
        }
    }
}

/// Byte-level damage to a text: truncation, non-UTF-8 bytes, a NUL, a duplicated line.
pub fn mutate_bytes(bytes: &mut Vec<u8>, rng: &mut Rng) -> String {
    let at = rng.below(bytes.len() + 1);
    match rng.below(6) {
        0 => {
            bytes.truncate(at);
            format!("truncated at byte {at}")
        }
        1 => {
            let b = *rng.pick(&[0xffu8, 0xfe, 0xe9, 0xc0, 0x80]);
            bytes.insert(at, b);
            format!("byte 0x{b:02x} inserted at {at}")
        }
        2 => {
            bytes.insert(at, 0);
            format!("NUL inserted at {at}")
        }
        3 => {
            // A line repeated: a duplicated key or table header.
            let text = String::from_utf8_lossy(bytes).into_owned();
            let lines: Vec<&str> = text.lines().collect();
            let candidates: Vec<usize> = (0..lines.len())
                .filter(|&i| lines[i].contains('=') || lines[i].starts_with('['))
                .collect();
            if candidates.is_empty() {
                bytes.truncate(at);
                return format!("truncated at byte {at}");
            }
            let i = *rng.pick(&candidates);
            let mut out = lines[..=i].join("\n");
            out.push('\n');
            out.push_str(&lines[i..].join("\n"));
            out.push('\n');
            *bytes = out.into_bytes();
            format!("line {} repeated", i + 1)
        }
        4 => {
            let junks: [&[u8]; 6] = [b"[[", b"= =", b"\"", b"]]]", b"{", b"\\u"];
            let junk: &[u8] = junks[rng.below(junks.len())];
            for (k, b) in junk.iter().enumerate() {
                bytes.insert(at + k, *b);
            }
            format!("{:?} inserted at {at}", String::from_utf8_lossy(junk))
        }
        _ => {
            if !bytes.is_empty() {
                let at = at.min(bytes.len() - 1);
                bytes[at] ^= 1 << rng.below(8);
            }
            format!("bit flipped at byte {at}")
        }
    }
}

/// The first frame a mutated scene states (the one the corpus renders), else 1.
pub fn first_frame(text: &[u8]) -> i64 {
    std::str::from_utf8(text)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .and_then(|t| {
            t.get("timeline")?
                .get("frames")?
                .as_array()?
                .first()?
                .as_integer()
        })
        .unwrap_or(1)
}

fn scene_file_name(base: &str) -> (String, String) {
    // The case folder mirrors scenes/: `assets` is a link to the shipped models, and a hard
    // scene's `../assets/...` resolves from `hard/`.
    let path = base.to_string();
    (path.clone(), path)
}

/// One generated scene case: a shipped scene with 1-3 mutations.
pub fn scene_case(index: usize, base: &SceneBase, rng: &mut Rng) -> Case {
    let (scene, _) = scene_file_name(&base.name);
    let mut what = Vec::new();
    let bytes = if rng.chance(0.12) {
        let mut bytes = base.text.clone().into_bytes();
        what.push(mutate_bytes(&mut bytes, rng));
        bytes
    } else {
        let mut tree: Value = Value::Table(base.text.parse().unwrap());
        let n = 1 + rng.below(3);
        let mut tries = 0;
        while what.len() < n && tries < 50 {
            tries += 1;
            let done = if rng.chance(0.06) {
                mutate_camera(&mut tree, rng)
            } else {
                mutate_toml(&mut tree, rng)
            };
            what.extend(done);
        }
        toml::to_string(&tree)
            .unwrap_or_else(|e| panic!("{}: {what:?}: {e}", base.name))
            .into_bytes()
    };
    let mut case = Case {
        name: format!("gen-{index:04} scenes/{}: {}", base.name, what.join("; ")),
        ..Case::default()
    };
    let frame = first_frame(&bytes);
    case.files.push((scene.clone(), bytes));
    if index.is_multiple_of(3) {
        case.info_and_render(&scene, frame, &[]);
    } else {
        case.render(&scene, frame, &[]);
    }
    case
}

// ---------------------------------------------------------------------------------------------
// glTF mutations

/// Every node of a JSON tree, depth first, as paths.
pub fn json_paths(value: &serde_json::Value) -> Vec<Vec<Seg>> {
    fn walk(value: &serde_json::Value, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
        match value {
            serde_json::Value::Object(m) => {
                for (k, v) in m {
                    path.push(Seg::Key(k.clone()));
                    out.push(path.clone());
                    walk(v, path, out);
                    path.pop();
                }
            }
            serde_json::Value::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    path.push(Seg::Index(i));
                    out.push(path.clone());
                    walk(v, path, out);
                    path.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(value, &mut Vec::new(), &mut out);
    out
}

pub fn json_get_mut<'a>(
    value: &'a mut serde_json::Value,
    path: &[Seg],
) -> Option<&'a mut serde_json::Value> {
    let mut at = value;
    for seg in path {
        at = match seg {
            Seg::Key(k) => at.get_mut(k.as_str())?,
            Seg::Index(i) => at.get_mut(*i)?,
        };
    }
    Some(at)
}

fn count(json: &serde_json::Value, key: &str) -> usize {
    json.get(key)
        .and_then(|a| a.as_array())
        .map_or(0, |a| a.len())
}

/// Index-valued keys of glTF and the array they index.
const INDEX_KEYS: &[(&str, &str)] = &[
    ("node", "nodes"),
    ("sampler", "samplers"),
    ("input", "accessors"),
    ("output", "accessors"),
    ("bufferView", "bufferViews"),
    ("buffer", "buffers"),
    ("indices", "accessors"),
    ("POSITION", "accessors"),
    ("NORMAL", "accessors"),
    ("TEXCOORD_0", "accessors"),
    ("JOINTS_0", "accessors"),
    ("WEIGHTS_0", "accessors"),
    ("JOINTS_1", "accessors"),
    ("WEIGHTS_1", "accessors"),
    ("inverseBindMatrices", "accessors"),
    ("skin", "skins"),
    ("mesh", "meshes"),
    ("material", "materials"),
    ("source", "images"),
    ("index", "textures"),
    ("skeleton", "nodes"),
    ("scene", "scenes"),
];

/// One structural mutation of a glTF JSON tree.
pub fn mutate_gltf(json: &mut serde_json::Value, rng: &mut Rng) -> Option<String> {
    use serde_json::json;
    let kind = rng.below(100);
    if kind < 14 {
        // The animation channel's target: the node out of range, a path that is not one.
        let n_nodes = count(json, "nodes");
        let anims = json.get_mut("animations")?.as_array_mut()?;
        let a = rng.below(anims.len());
        let channels = anims[a].get_mut("channels")?.as_array_mut()?;
        let c = rng.below(channels.len());
        let target = channels[c].get_mut("target")?;
        if rng.chance(0.5) {
            let node = *rng.pick(&[n_nodes as u64, n_nodes as u64 + 7, 4294967295, u64::MAX]);
            target["node"] = json!(node);
            Some(format!(
                "animations[{a}].channels[{c}].target.node = {node}"
            ))
        } else {
            let path = *rng.pick(&["bogus", "weights", "", "matrix", "TRANSLATION"]);
            target["path"] = json!(path);
            Some(format!(
                "animations[{a}].channels[{c}].target.path = {path:?}"
            ))
        }
    } else if kind < 40 {
        // An index key out of range (or negative, or not a number).
        let paths = json_paths(json);
        let candidates: Vec<(Vec<Seg>, &str)> = paths
            .into_iter()
            .filter_map(|p| match p.last() {
                Some(Seg::Key(k)) => INDEX_KEYS
                    .iter()
                    .find(|(key, _)| key == k)
                    .map(|(_, array)| (p.clone(), *array)),
                _ => None,
            })
            .collect();
        if candidates.is_empty() {
            return None;
        }
        let (path, array) = rng.pick(&candidates).clone();
        let n = count(json, array) as i64;
        let value = rng
            .pick(&[
                json!(n),
                json!(n + 1),
                json!(-1),
                json!(4294967295u64),
                json!(1.5),
                json!("0"),
            ])
            .clone();
        let at = path_text(&path);
        *json_get_mut(json, &path)? = value.clone();
        Some(format!("{at} = {value} ({array} has {n})"))
    } else if kind < 55 {
        // Accessor and buffer view sizes: counts, offsets, strides, component types, byte lengths.
        let key_sets: &[(&str, &[&str])] = &[
            (
                "accessors",
                &[
                    "count",
                    "byteOffset",
                    "componentType",
                    "type",
                    "normalized",
                    "sparse",
                ],
            ),
            ("bufferViews", &["byteLength", "byteOffset", "byteStride"]),
            ("buffers", &["byteLength"]),
        ];
        let (array, keys) = *rng.pick(key_sets);
        let n = count(json, array);
        if n == 0 {
            return None;
        }
        let i = rng.below(n);
        let key = *rng.pick(keys);
        let value = match key {
            "componentType" => rng
                .pick(&[json!(5120), json!(5130), json!(0), json!(5126), json!(5125)])
                .clone(),
            "type" => rng
                .pick(&[json!("VEC2"), json!("MAT4"), json!("SCALAR"), json!("VEC9")])
                .clone(),
            "normalized" => json!(true),
            "sparse" => {
                json!({"count": 4294967295u64, "indices": {"bufferView": 0, "componentType": 5125}, "values": {"bufferView": 0}})
            }
            _ => rng
                .pick(&[
                    json!(0),
                    json!(1),
                    json!(3),
                    json!(4294967295u64),
                    json!(1_000_000_000),
                    json!(255),
                    json!(-4),
                ])
                .clone(),
        };
        json[array][i][key] = value.clone();
        Some(format!("{array}[{i}].{key} = {value}"))
    } else if kind < 68 {
        // A buffer's or an image's URI: a device, a FIFO, a folder, a missing file, a bad data
        // URI, a path out of the folder.
        let array = if rng.chance(0.6) { "buffers" } else { "images" };
        let n = count(json, array);
        let i = rng.below(n.max(1));
        let uri = *rng.pick(&[
            "/dev/zero",
            "fifo",
            ".",
            "missing.bin",
            "data:application/octet-stream;base64,!!!!",
            "data:application/octet-stream;base64,",
            "../../../../../../dev/zero",
            "huge.png",
            "file:///dev/zero",
        ]);
        if n == 0 {
            json[array] = json!([{ "uri": uri, "byteLength": 64 }]);
        } else {
            json[array][i]["uri"] = json!(uri);
            if array == "images" {
                json[array][i].as_object_mut()?.remove("bufferView");
            }
        }
        Some(format!("{array}[{i}].uri = {uri:?}"))
    } else if kind < 76 {
        // Node graph: a cycle, a child out of range, a skin joint out of range, TRS extremes.
        let n = count(json, "nodes");
        if n == 0 {
            return None;
        }
        let i = rng.below(n);
        match rng.below(4) {
            0 => {
                json["nodes"][i]["children"] = json!([i]);
                Some(format!("nodes[{i}] is its own child"))
            }
            1 => {
                let j = rng.below(n);
                json["nodes"][j]["children"] = json!([i]);
                json["nodes"][i]["children"] = json!([j]);
                Some(format!("nodes[{i}] and nodes[{j}] children of each other"))
            }
            2 => {
                let key = *rng.pick(&["translation", "scale", "rotation"]);
                let x = *rng.pick(&[1e39, -1e39, 1e30, 0.0, 1e-50, 3e38]);
                let v = if key == "rotation" {
                    json!([x, 0, 0, 1])
                } else {
                    json!([x, x, x])
                };
                json["nodes"][i][key] = v;
                Some(format!("nodes[{i}].{key} with {x:e}"))
            }
            _ => {
                json["nodes"][i]["matrix"] = json!(vec![0.0; 16]);
                Some(format!("nodes[{i}].matrix all zero"))
            }
        }
    } else if kind < 84 {
        // A whole array removed or emptied.
        let key = *rng.pick(&[
            "nodes",
            "meshes",
            "accessors",
            "bufferViews",
            "buffers",
            "skins",
            "animations",
            "scenes",
            "images",
            "textures",
            "materials",
            "asset",
        ]);
        let obj = json.as_object_mut()?;
        if rng.chance(0.5) {
            obj.remove(key).map(|_| format!("{key} removed"))
        } else {
            obj.insert(key.into(), json!([]));
            Some(format!("{key} = []"))
        }
    } else {
        // Any number anywhere at an edge.
        let paths: Vec<Vec<Seg>> = json_paths(json)
            .into_iter()
            .filter(|p| {
                let mut j = json.clone();
                json_get_mut(&mut j, p).is_some_and(|v| v.is_number())
            })
            .collect();
        if paths.is_empty() {
            return None;
        }
        let path = rng.pick(&paths).clone();
        let value = rng
            .pick(&[
                json!(0),
                json!(-1),
                json!(1e-50),
                json!(1e39),
                json!(-1e39),
                json!(4294967295u64),
                json!(1e300),
                json!(0.5),
            ])
            .clone();
        let at = path_text(&path);
        *json_get_mut(json, &path)? = value.clone();
        Some(format!("{at} = {value}"))
    }
}

/// The scene a model case renders: tiny.toml with the model as a character, on the pool floor.
pub fn character_scene(model_file: &str, scale: f64, extra: &str) -> String {
    let tiny = std::fs::read_to_string(repo().join("scenes/tiny.toml")).unwrap();
    format!(
        "{tiny}\n[[character]]\nname = \"model\"\nfile = {model_file:?}\nscale = {scale}\n{extra}\
         [[character.path]]\nframe = 1\nposition = [0.0, -0.8, 0.0]\nheading_deg = 90\n"
    )
}

/// One generated model case: a shipped model with 1-2 mutations (or byte damage), in tiny.toml.
pub fn model_case(index: usize, base: &ModelBase, rng: &mut Rng) -> Case {
    let mut json = base.json.clone();
    let mut bin = base.bin.clone();
    let mut what = Vec::new();
    let mut damage = None;
    let roll = rng.below(100);
    if roll < 10 {
        damage = Some(rng.below(3));
    } else {
        let n = 1 + rng.below(2);
        let mut tries = 0;
        while what.len() < n && tries < 50 {
            tries += 1;
            what.extend(mutate_gltf(&mut json, rng));
        }
    }
    let is_glb = base.bin.is_some() || base.name.ends_with(".glb");
    let file = if is_glb { "model.glb" } else { "model.gltf" };
    let json_bytes = serde_json::to_vec(&json).unwrap();
    let mut bytes = if is_glb {
        join_glb(&json_bytes, bin.as_deref())
    } else {
        json_bytes
    };
    match damage {
        Some(0) => {
            let at = rng.below(bytes.len());
            bytes.truncate(at);
            what.push(format!("truncated at byte {at}"));
        }
        Some(1) if is_glb => {
            // A chunk length past the file.
            let field = *rng.pick(&[8usize, 12]);
            bytes[field..field + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            what.push(format!("GLB length field at byte {field} = 4294967295"));
        }
        Some(1) => {
            let at = rng.below(bytes.len());
            bytes.insert(at, 0xff);
            what.push(format!("byte 0xff inserted at {at}"));
        }
        Some(_) => {
            if let Some(b) = bin.as_mut() {
                let at = rng.below(b.len());
                b.truncate(at);
                bytes = join_glb(&serde_json::to_vec(&json).unwrap(), Some(b));
                what.push(format!("BIN chunk truncated at {at}"));
            } else {
                bytes.insert(0, 0);
                what.push("NUL first".into());
            }
        }
        None => {}
    }
    let animation = if count(&json, "animations") > 0 && count(&base.json, "animations") > 0 {
        format!(
            "animation = {}\n",
            rng.below(count(&base.json, "animations"))
        )
    } else {
        String::new()
    };
    let mut case = Case {
        name: format!("gen-{index:04} model {}: {}", base.name, what.join("; ")),
        ..Case::default()
    };
    case.files.push((file.into(), bytes));
    case.files.extend(base.sidecars.iter().cloned());
    case.files.push(("huge.png".into(), huge_png()));
    case.fifos.push("fifo".into());
    case.files.push((
        "scene.toml".into(),
        character_scene(file, base.scale, &animation).into_bytes(),
    ));
    if index.is_multiple_of(3) {
        case.info_and_render("scene.toml", 1, &[]);
    } else {
        case.render("scene.toml", 1, &[]);
    }
    case
}

/// A valid PNG header claiming 65535 x 65535 RGBA pixels (16 GiB decoded), then nothing.
pub fn huge_png() -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&65535u32.to_be_bytes());
    ihdr.extend_from_slice(&65535u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    let idat = b"IDAT\x78\x9c\x03\x00\x00\x00\x00\x01".to_vec();
    png.extend_from_slice(&((idat.len() - 4) as u32).to_be_bytes());
    png.extend_from_slice(&idat);
    png.extend_from_slice(&crc32(&idat).to_be_bytes());
    png
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

// ---------------------------------------------------------------------------------------------
// Command-line and image-texture mutations

/// A shipped scene with odd `render` arguments, or an image texture that is not a small image.
pub fn argument_case(index: usize, rng: &mut Rng) -> Case {
    let tiny = std::fs::read_to_string(repo().join("scenes/tiny.toml")).unwrap();
    let mut case = Case::default();
    case.fifos.push("fifo".into());
    if rng.chance(0.5) {
        let (flag, value) = *rng.pick(&[
            ("--size", "0x0"),
            ("--size", "16384x16384"),
            ("--size", "100000x1"),
            ("--size", "4294967295x1"),
            ("--size", "-16x16"),
            ("--size", "16x"),
            ("--size", "4000x3000"),
            ("--frames", "4294967295"),
            ("--frames", "-1"),
            ("--frames", "3-1"),
            ("--frames", "1-1000000"),
            ("--frames", "1-"),
            ("--frames", "99999999999999999999"),
            ("--method", "bogus"),
            ("--method", "raytrace"),
            ("--method", "exact"),
            ("--subdivision-px", "0"),
            ("--subdivision-px", "NaN"),
            ("--subdivision-px", "1e-50"),
            ("--subdivision-px", "-1"),
            ("--compression", "dwaa"),
        ]);
        case.name = format!("gen-{index:04} render tiny.toml {flag} {value}");
        case.files.push(("tiny.toml".into(), tiny.into_bytes()));
        let mut args = vec!["render", "tiny.toml", "--out", "out"];
        if flag != "--size" {
            args.extend_from_slice(&["--size", "16x16"]);
        }
        if flag != "--frames" {
            args.extend_from_slice(&["--frames", "1"]);
        }
        args.extend_from_slice(&[flag, value]);
        case.step(&args, Expect::Scene);
        case.renders = true;
    } else {
        let image = *rng.pick(&[
            "/dev/zero",
            "fifo",
            ".",
            "huge.png",
            "missing.png",
            "scene.toml",
            "trunc.png",
        ]);
        let size = *rng.pick(&["[1.0, 1.0]", "[1e-50, 1.0]", "[1e39, 1.0]", "[0.0, 0.0]"]);
        case.name = format!("gen-{index:04} image texture {image:?} size_m = {size}");
        let text = tiny.replacen(
            "texture = { kind = \"checker\", color = [0.95, 0.93, 0.90], color_b = [0.85, 0.12, 0.10], square_m = 0.15 }",
            &format!("texture = {{ image = {image:?}, size_m = {size} }}"),
            1,
        );
        assert_ne!(text, tiny, "tiny.toml's ball texture changed");
        case.files.push(("scene.toml".into(), text.into_bytes()));
        case.files.push(("huge.png".into(), huge_png()));
        case.files
            .push(("trunc.png".into(), huge_png()[..20].to_vec()));
        case.info_and_render("scene.toml", 1, &[]);
    }
    case
}

// ---------------------------------------------------------------------------------------------
// EXR mutations

/// A small frame to mutate: tiny.toml frame 1 at 16x16, rendered once by the corpus.
pub fn render_base_frame(dir: &Path) -> Vec<u8> {
    let tiny = repo().join("scenes/tiny.toml");
    let out = dir.join("base");
    let status = Command::new(env!("CARGO_BIN_EXE_snell"))
        .args(["render", tiny.to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--size", "16x16", "--frames", "1"])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    std::fs::read(out.join("tiny.0001.exr")).unwrap()
}

/// The base frame with one float sample of `channel` (by name suffix) made `value`.
pub fn frame_with_sample(base: &[u8], channel: &str, pixel: usize, value: f32) -> Vec<u8> {
    use exr::prelude::*;
    let mut image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(base))
        .unwrap();
    let mut done = false;
    for layer in &mut image.layer_data {
        for ch in &mut layer.channel_data.list {
            let name = ch.name.to_string();
            let full = match &layer.attributes.layer_name {
                Some(l) => format!("{l}.{name}"),
                None => name,
            };
            if !done && full == channel {
                match &mut ch.sample_data {
                    FlatSamples::F32(v) => v[pixel] = value,
                    FlatSamples::F16(v) => v[pixel] = f16::from_f32(value),
                    FlatSamples::U32(_) => continue,
                }
                done = true;
            }
        }
    }
    assert!(done, "no channel {channel} in the base frame");
    let mut out = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

/// One generated EXR case: the base frame damaged, given to `diff`, `compare` and `check`.
pub fn exr_case(index: usize, base: &[u8], rng: &mut Rng) -> Case {
    let mut bytes = base.to_vec();
    let what = match rng.below(5) {
        0 => {
            let at = rng.below(bytes.len());
            bytes.truncate(at);
            format!("truncated at byte {at}")
        }
        1 => {
            // The header (attribute sizes, the offset table) is the first few hundred bytes.
            let at = rng.below(bytes.len().min(1200));
            let n = 1 + rng.below(4);
            for k in 0..n {
                if at + k < bytes.len() {
                    bytes[at + k] = *rng.pick(&[0xff, 0x00, 0x7f, 0x80]);
                }
            }
            format!("{n} header bytes at {at} overwritten")
        }
        2 => {
            let at = rng.below(bytes.len());
            bytes[at] ^= 1 << rng.below(8);
            format!("bit flipped at byte {at}")
        }
        3 => {
            let channel = *rng.pick(&["R", "G", "B", "A", "Z", "P.X", "P.Y", "P.Z"]);
            let value = *rng.pick(&[f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -0.0]);
            let pixel = rng.below(256);
            bytes = frame_with_sample(base, channel, pixel, value);
            format!("{channel} of pixel {pixel} = {value}")
        }
        _ => {
            let at = rng.below(bytes.len());
            let junk = vec![0xffu8; 1 + rng.below(64)];
            bytes.splice(at..at, junk.iter().copied());
            format!("{} bytes 0xff inserted at {at}", junk.len())
        }
    };
    let mut case = Case {
        name: format!("gen-{index:04} exr tiny.0001.exr: {what}"),
        ..Case::default()
    };
    case.files
        .push(("golden/tiny.0001.exr".into(), base.to_vec()));
    case.files
        .push(("test/tiny.0001.exr".into(), bytes.clone()));
    case.step(
        &[
            "diff",
            "golden/tiny.0001.exr",
            "test/tiny.0001.exr",
            "--heatmaps",
            "heat",
        ],
        Expect::Frames,
    );
    case.step(
        &[
            "diff",
            "test/tiny.0001.exr",
            "golden/tiny.0001.exr",
            "--heatmaps",
            "heat",
        ],
        Expect::Frames,
    );
    case.step(
        &["compare", "golden/tiny.0001.exr", "test/tiny.0001.exr"],
        Expect::Frames,
    );
    case
}

// ---------------------------------------------------------------------------------------------
// The corpus

/// `n` generated cases from `seed`: scenes, models, EXRs and arguments, in a fixed mix. Most fail
/// validation in milliseconds; the ones that render do so at 16x16, one frame.
pub fn generate(seed: u64, n: usize, base_frame: &[u8]) -> Vec<Case> {
    let scenes = scene_bases();
    let models = model_bases();
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let roll = rng.below(100);
            if roll < 55 {
                let base = rng.pick(&scenes);
                scene_case(i, base, &mut rng)
            } else if roll < 83 {
                let base = rng.pick(&models);
                model_case(i, base, &mut rng)
            } else if roll < 93 {
                exr_case(i, base_frame, &mut rng)
            } else {
                argument_case(i, &mut rng)
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// The runner

#[derive(Debug)]
pub struct StepOutcome {
    pub code: Option<i32>,
    pub signal: Option<i32>,
    pub timed_out: bool,
    pub elapsed: Duration,
    pub stderr: String,
}

/// What went wrong with a case, or None.
pub fn run_case(case: &Case, root: &Path) -> Result<Vec<StepOutcome>, String> {
    let dir = root.join(sanitize(&case.name));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::os::unix::fs::symlink(repo().join("scenes/assets"), dir.join("assets")).unwrap();
    for (name, bytes) in &case.files {
        let path = dir.join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, bytes).unwrap();
    }
    for fifo in &case.fifos {
        let c = std::ffi::CString::new(dir.join(fifo).as_os_str().as_encoded_bytes()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }
    let mut outcomes = Vec::new();
    for step in &case.steps {
        let outcome = run_step(&dir, step);
        let verdict = judge(&dir, step, &outcome);
        outcomes.push(outcome);
        if let Err(problem) = verdict {
            return Err(format!(
                "{}\n  snell {}\n  {problem}\n  case kept in {}",
                case.name,
                step.args.join(" "),
                dir.display()
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(outcomes)
}

pub fn sanitize(name: &str) -> String {
    name.chars()
        .take(60)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn run_step(dir: &Path, step: &Step) -> StepOutcome {
    let stderr_path = dir.join(".stderr");
    let stdout = match step.stdout {
        Sink::Piped => Stdio::from(std::fs::File::create(dir.join(".stdout")).unwrap()),
        Sink::DevFull => Stdio::from(
            std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/full")
                .unwrap(),
        ),
        Sink::ClosedPipe => {
            use std::os::fd::{FromRawFd, OwnedFd};
            let mut fds = [0; 2];
            assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
            unsafe { libc::close(fds[0]) };
            Stdio::from(unsafe { OwnedFd::from_raw_fd(fds[1]) })
        }
    };
    let mut command = Command::new(env!("CARGO_BIN_EXE_snell"));
    command
        .args(&step.args)
        .current_dir(dir)
        .env("SNELL_MAX_MEMORY", SNELL_MAX_MEMORY)
        .env_remove("SOURCE_DATE_EPOCH")
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(std::fs::File::create(&stderr_path).unwrap());
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: MEMORY_CAP_BYTES,
                rlim_max: MEMORY_CAP_BYTES,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let clock = Instant::now();
    let mut child = command.spawn().expect("snell starts");
    let mut timed_out = false;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if clock.elapsed() > COMMAND_TIMEOUT {
            timed_out = true;
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    use std::os::unix::process::ExitStatusExt;
    StepOutcome {
        code: status.code(),
        signal: status.signal(),
        timed_out,
        elapsed: clock.elapsed(),
        stderr: String::from_utf8_lossy(&std::fs::read(&stderr_path).unwrap()).into_owned(),
    }
}

fn judge(dir: &Path, step: &Step, outcome: &StepOutcome) -> Result<(), String> {
    let tail: String = {
        let lines: Vec<&str> = outcome.stderr.lines().collect();
        lines[lines.len().saturating_sub(6)..].join("\n    ")
    };
    if outcome.timed_out {
        return Err(format!(
            "HANG: no answer in {COMMAND_TIMEOUT:?}\n    {tail}"
        ));
    }
    if outcome.stderr.contains("memory allocation of") {
        return Err(format!(
            "MEMORY CAP: allocation failed under {MEMORY_CAP_BYTES} bytes\n    {tail}"
        ));
    }
    if let Some(signal) = outcome.signal {
        return Err(format!("SIGNAL {signal}\n    {tail}"));
    }
    let code = outcome.code.unwrap();
    if code == 101 || outcome.stderr.contains("panicked") {
        return Err(format!("PANIC (exit {code})\n    {tail}"));
    }
    let allowed: Vec<i32> = match &step.expect {
        Expect::Scene => vec![0, 2],
        Expect::Frames => vec![0, 1, 2, 4],
        Expect::NotPass => vec![1, 2, 4],
        Expect::Codes(c) => c.clone(),
        Expect::Refused(needles) => {
            for needle in needles {
                if !outcome.stderr.contains(needle.as_str()) {
                    return Err(format!("stderr lacks {needle:?}\n    {tail}"));
                }
            }
            vec![2]
        }
    };
    if !allowed.contains(&code) {
        return Err(format!(
            "EXIT {code}, expected one of {allowed:?}\n    {tail}"
        ));
    }
    if code == 2
        && step.expect == Expect::Scene
        && !outcome.stderr.starts_with("error:")
        && !outcome.stderr.contains("error:")
    {
        return Err(format!("exit 2 without an error message\n    {tail}"));
    }
    if code == 0 && step.expect == Expect::Scene && step.args[0] == "render" {
        let frames = exr_files(&dir.join("out"));
        if frames.is_empty() {
            return Err("exit 0 but no frame written".into());
        }
        for frame in frames {
            if let Some(problem) = non_finite_sample(&frame) {
                return Err(format!(
                    "NON-FINITE OUTPUT with exit 0: {}: {problem}",
                    frame.display()
                ));
            }
        }
    }
    Ok(())
}

fn exr_files(dir: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "exr"))
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// The first NaN or infinity in any float channel of an EXR, read with the `exr` crate (the
/// channel map states a finite value for every layer, sky and no-hit pixels included).
pub fn non_finite_sample(path: &Path) -> Option<String> {
    use exr::prelude::*;
    let image = match read_all_flat_layers_from_file(path) {
        Ok(image) => image,
        Err(e) => return Some(format!("unreadable: {e}")),
    };
    for layer in &image.layer_data {
        let lname = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}."))
            .unwrap_or_default();
        for ch in &layer.channel_data.list {
            let bad = match &ch.sample_data {
                FlatSamples::F32(v) => v.iter().position(|x| !x.is_finite()),
                FlatSamples::F16(v) => v.iter().position(|x| !x.to_f32().is_finite()),
                FlatSamples::U32(_) => None,
            };
            if let Some(i) = bad {
                return Some(format!("{lname}{} sample {i}", ch.name));
            }
        }
    }
    None
}

/// Runs every case on `workers` threads; returns the failures and the per-case times.
/// Per case: its time, whether it rendered a frame (exit 0), its name.
pub type CaseTime = (Duration, bool, String);

pub fn run_all(cases: &[Case], root: &Path, workers: usize) -> (Vec<String>, Vec<CaseTime>) {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failures = std::sync::Mutex::new(Vec::new());
    let times = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(case) = cases.get(i) else { break };
                let clock = Instant::now();
                let mut rendered = false;
                match run_case(case, root) {
                    Ok(outcomes) => {
                        rendered = case
                            .steps
                            .iter()
                            .zip(&outcomes)
                            .any(|(s, o)| s.args[0] == "render" && o.code == Some(0));
                    }
                    Err(problem) => failures.lock().unwrap().push(problem),
                }
                times
                    .lock()
                    .unwrap()
                    .push((clock.elapsed(), rendered, case.name.clone()));
            });
        }
    });
    (failures.into_inner().unwrap(), times.into_inner().unwrap())
}

/// Counts of the cases' names by their first word after the index, for the summary.
pub fn mix(cases: &[Case]) -> BTreeMap<String, usize> {
    let mut m = BTreeMap::new();
    for c in cases {
        let kind = c.name.split_whitespace().nth(1).unwrap_or("?").to_string();
        *m.entry(kind).or_insert(0) += 1;
    }
    m
}
