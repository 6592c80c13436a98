//! Raw scene (as written) -> validated [`Scene`]: defaults filled in, every value checked, and each
//! problem reported at the key that causes it, with what to change.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use super::error::{KeyPath, SourceMap};
use super::format::{
    RawAnimation, RawCamera, RawCameraKey, RawCharacter, RawGltfCamera, RawObject, RawRipples,
    RawScene, RawTexture, RawWater,
};
use super::limits::{MAX_FRAME_NUMBER, MAX_TIMELINE_FRAMES};
use super::primitives::DEFAULT_MAX_EDGE_M;
use super::textures::{srgb_to_linear3, ImageSpec, LaneSpec, TextureSpec, TilesSpec};
use super::{
    AnimationChoice, AntialiasSpec, AspectRule, CameraSpec, CharacterSpec, GltfCameraSpec,
    ObjectSpec, PathKey, Playback, QualitySpec, RippleSpec, Scene, SceneError, ShapeSpec,
    WaterSpec, WaveSpec,
};
use crate::draw::Lighting;
use crate::timeline::{CameraKey, Timeline};

mod camera;
mod objects;
mod vessels;
mod water;

use camera::{camera, keyframe_time, KeyList};
use objects::{default_pool, object};
use water::water;

type Result<T> = std::result::Result<T, SceneError>;

const DEFAULT_FPS: f64 = 24.0;
const DEFAULT_FRAMES: [i64; 2] = [1, 48];
const DEFAULT_WATER_MIN_XZ: [f64; 2] = [-5.0, -2.5];
const DEFAULT_WATER_MAX_XZ: [f64; 2] = [5.0, 2.5];
const DEFAULT_RESOLUTION: [i64; 2] = [128, 64];
/// Membrane grids beyond this many cells a side are surely a typo (and would not fit in memory).
const DEFAULT_N_ABOVE: f64 = 1.0;
const DEFAULT_N_BELOW: f64 = 1.333;
/// Clear pool water: red is absorbed within metres, blue travels far (Pope & Fry 1997, roughly).
const DEFAULT_ABSORPTION_PER_M: [f64; 3] = [0.45, 0.07, 0.03];
const DEFAULT_SCATTER_COLOR: [f64; 3] = [0.05, 0.30, 0.40];
/// Rms slope of the waves finer than the membrane: Cox and Munk's slope variance of a calm sea
/// (0.003, their fit 0.003 + 0.00512 U at wind speed U = 0), whose square root is 0.055.
const DEFAULT_WATER_ROUGHNESS: f64 = 0.055;
const DEFAULT_ZENITH_COLOR: [f64; 3] = [0.30, 0.50, 0.85];
const DEFAULT_HORIZON_COLOR: [f64; 3] = [0.78, 0.86, 0.95];
const DEFAULT_AMBIENT_COLOR: [f64; 3] = [0.60, 0.70, 0.85];
const DEFAULT_AMBIENT_INTENSITY: f64 = 0.3;
const DEFAULT_SUN_AZIMUTH_DEG: f64 = 135.0;
const DEFAULT_SUN_ELEVATION_DEG: f64 = 55.0;
const DEFAULT_SUN_COLOR: [f64; 3] = [1.0, 0.97, 0.90];
const DEFAULT_SUN_INTENSITY: f64 = 1.0;
/// The real sun's angular diameter.
const DEFAULT_SUN_SIZE_DEG: f64 = 0.53;
const DEFAULT_FOV_DEG: f64 = 50.0;
/// Ripple nodes per membrane cell along each axis by default: a node on every membrane vertex and
/// one between, so the membrane samples the ripple nodes themselves and the smooth field between
/// them is well within the grid's own resolution (the band limit is the membrane's, half the grid's).
const DEFAULT_RIPPLE_NODES_PER_CELL: i64 = 2;
const MAX_RIPPLE_NODES: i64 = 4096;
/// Ripples from a wading animal die down within a few seconds.
const DEFAULT_RIPPLE_DAMPING_PER_S: f64 = 0.5;
const DEFAULT_SPONGE_WIDTH_M: f64 = 0.5;
/// A body this far under the surface stirs it e times less than one at the surface. A disturbance
/// of wavenumber k at depth d reaches the surface damped by exp(-k d); for the ripples a grid
/// carries (wavelengths of 10 to 60 cm) 1/k is 2 to 10 cm.
const DEFAULT_COUPLING_DEPTH_M: f64 = 0.1;
/// Finer tessellation than this would build millions of vertices per square metre.
const MIN_MAX_EDGE_M: f64 = 0.01;

const SHAPES: [&str; 4] = ["box", "sphere", "quad", "pool"];
const TEXTURE_KINDS: [&str; 4] = ["solid", "checker", "tiles", "image"];
const COMMON_OBJECT_KEYS: [&str; 8] = [
    "name",
    "shape",
    "translate",
    "rotate_deg",
    "scale",
    "max_edge_m",
    "texture",
    "tint",
];

pub(crate) fn validate(raw: RawScene, map: &SourceMap<'_>) -> Result<Scene> {
    let root = KeyPath::root();
    let name = scene_name(raw.name.clone(), map)?;
    let max_edge_m = match raw.max_edge_m {
        Some(v) => max_edge(v, &root.key("max_edge_m"), map)?,
        None => DEFAULT_MAX_EDGE_M,
    };

    let timeline = timeline(&raw, map)?;
    let has_characters = raw.character.as_ref().is_some_and(|c| !c.is_empty());
    let water = water(&raw.water, has_characters, map)?;
    let camera = camera(raw.camera.as_ref(), &timeline, &water, map)?;
    let lighting = lighting(&raw, map)?;
    let quality = quality(&raw, map)?;
    let antialias = antialias(&raw);
    let objects = match &raw.object {
        Some(objects) => objects
            .iter()
            .enumerate()
            .map(|(i, o)| object(o, &root.key("object").index(i), i, max_edge_m, &water, map))
            .collect::<Result<Vec<_>>>()?,
        None => vec![default_pool(max_edge_m)],
    };
    let characters = raw
        .character
        .iter()
        .flatten()
        .enumerate()
        .map(|(i, c)| character(c, &root.key("character").index(i), i, &timeline, map))
        .collect::<Result<Vec<_>>>()?;

    let vessels = raw
        .vessel
        .iter()
        .flatten()
        .enumerate()
        .map(|(i, v)| vessels::vessel(v, &root.key("vessel").index(i), i, map))
        .collect::<Result<Vec<_>>>()?;

    let object_paths: Vec<KeyPath> = match &raw.object {
        Some(_) => (0..objects.len())
            .map(|i| root.key("object").index(i))
            .collect(),
        None => vec![root.clone()],
    };
    let resources =
        super::resources::check_scene(&water, &objects, &object_paths, characters.len(), map)?;

    Ok(Scene {
        name,
        resources,
        path: map.file.to_path_buf(),
        timeline,
        camera,
        water,
        objects: Arc::from(objects),
        characters: Arc::from(characters),
        vessels: Arc::from(vessels),
        lighting,
        quality,
        antialias,
    })
}

/// The rasteriser's sampling by default: 2, supersampled (README "Anti-aliasing" has what it
/// costs).
const DEFAULT_SUPERSAMPLE: u32 = 2;
/// The reference's stratified rays a pixel by default: 4 x 4.
const DEFAULT_REFERENCE_GRID: u32 = 4;

/// `[antialias]`: both keys are whole numbers in their stated ranges (1 or 2, and 1 to 16),
/// checked where they stand (`super::limits`), so nothing here can be wrong.
fn antialias(raw: &RawScene) -> AntialiasSpec {
    let raw = raw.antialias.as_ref();
    let supersample = raw
        .and_then(|a| a.supersample)
        .map_or(DEFAULT_SUPERSAMPLE, |s| s as u32);
    let reference_grid = raw
        .and_then(|a| a.reference_grid)
        .map_or(DEFAULT_REFERENCE_GRID, |n| n as u32);
    AntialiasSpec {
        supersample,
        reference_grid,
    }
}

/// Budgets past this are surely a typo: an error of 1,000 pixels is a different picture.
const MAX_ERROR_PX_LIMIT: f64 = 1000.0;

fn quality(raw: &RawScene, map: &SourceMap<'_>) -> Result<QualitySpec> {
    let path = KeyPath::root().key("quality");
    let max_error_px = raw.quality.as_ref().and_then(|q| q.max_error_px);
    if let Some(error_px) = max_error_px {
        // NaN and infinities are refused before (check_numbers), with their position.
        if !(error_px > 0.0 && error_px <= MAX_ERROR_PX_LIMIT) {
            return Err(map.error(
                &path.key("max_error_px"),
                format!(
                    "must be more than 0 and at most {MAX_ERROR_PX_LIMIT} pixels (got {error_px})"
                ),
                "set e.g. max_error_px = 0.5 (99 % of pixels within half a pixel of the reference), \
                 or remove it to render at the scene's own resolution and method",
            ));
        }
    }
    Ok(QualitySpec { max_error_px })
}

/// The longest scene name, in bytes: output names add at most 96 more
/// (`.<name>.0001.exr.tmp-<pid>.<host>`, the host at most 64) and must stay under the 255 bytes file systems allow.
pub(crate) const MAX_NAME_BYTES: usize = 100;

/// Why `name` cannot name output files, if it cannot.
pub(crate) fn name_problem(name: &str) -> Option<String> {
    if name.is_empty() {
        return Some("the name is empty".into());
    }
    if name.len() > MAX_NAME_BYTES {
        return Some(format!(
            "the name is {} bytes long, more than the {MAX_NAME_BYTES} an output file name can carry",
            name.len()
        ));
    }
    if let Some(c) = name
        .chars()
        .find(|c| c.is_control() || "/\\:*?\"<>|".contains(*c))
    {
        return Some(format!(
            "the name contains {c:?}, which cannot be part of a portable file name"
        ));
    }
    if name.starts_with(['.', '-']) || name.ends_with([' ', '.']) || name.trim() != name {
        return Some(
            "the name starts with '.' or '-', or starts or ends with a space or a '.'".into(),
        );
    }
    None
}

fn scene_name(name: Option<String>, map: &SourceMap<'_>) -> Result<String> {
    let from_file = name.is_none();
    let name = match name {
        Some(name) => name,
        None => map
            .file
            .file_stem()
            .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned()),
    };
    if let Some(problem) = name_problem(&name) {
        let shown: String = name.chars().take(40).collect();
        let shown = if shown.len() < name.len() {
            format!("{shown:?}...")
        } else {
            format!("{shown:?}")
        };
        let problem = if from_file {
            format!("the scene is named after its file, {shown}, which cannot name output files: {problem}")
        } else {
            format!("{shown} cannot name output files: {problem}")
        };
        return Err(map.error(
            &KeyPath::root().key("name"),
            problem,
            format!(
                "set e.g. name = \"pool\" (at most {MAX_NAME_BYTES} bytes; letters, digits, spaces, '-', '_', '.')"
            ),
        ));
    }
    Ok(name)
}

fn timeline(raw: &RawScene, map: &SourceMap<'_>) -> Result<Timeline> {
    let path = KeyPath::root().key("timeline");
    let fps = raw.timeline.fps.unwrap_or(DEFAULT_FPS);
    if fps <= 0.0 {
        return Err(map.error(
            &path.key("fps"),
            format!("must be more than 0 frames per second (got {fps})"),
            "set e.g. fps = 24",
        ));
    }
    let [first, last] = raw.timeline.frames.unwrap_or(DEFAULT_FRAMES);
    let frames_path = path.key("frames");
    // Each number's range was checked where it is written (limits::KEY_RANGES); this is the
    // defaults' and the pair's check.
    if first < 0 || last < 0 || first > MAX_FRAME_NUMBER || last > MAX_FRAME_NUMBER {
        return Err(map.error(
            &frames_path,
            format!(
                "frame numbers must be between 0 and {MAX_FRAME_NUMBER} (got [{first}, {last}])"
            ),
            "set e.g. frames = [1, 48]",
        ));
    }
    if last < first {
        return Err(map.error(
            &frames_path,
            format!("the frame range is empty: the last frame comes before the first (got [{first}, {last}])"),
            format!("write the first frame first, e.g. frames = [{last}, {first}]"),
        ));
    }
    let frames = (last - first) as u64 + 1;
    if frames > MAX_TIMELINE_FRAMES {
        return Err(map.error(
            &frames_path,
            format!(
                "the timeline has {frames} frames, more than the {MAX_TIMELINE_FRAMES} snell renders in one scene"
            ),
            format!("split the shot into scenes of at most {MAX_TIMELINE_FRAMES} frames"),
        ));
    }
    Ok(Timeline {
        fps,
        first_frame: first as u32,
        last_frame: last as u32,
    })
}

/// A glTF file named at `at`, resolved against the scene's folder: it must be a regular file
/// within the asset size cap (its contents are read by whoever uses it).
fn gltf_file(raw: &str, at: &KeyPath, map: &SourceMap<'_>) -> Result<std::path::PathBuf> {
    let folder = map.file.parent().unwrap_or(Path::new(""));
    let file = folder.join(raw);
    if let Err(error) = crate::files::check_regular(&file, crate::files::MAX_ASSET_BYTES) {
        let problem = match error {
            crate::files::InputFileError::NotFound(_) => format!(
                "cannot find the glTF file {} (resolved against the scene's folder)",
                file.display()
            ),
            other => format!("cannot use the glTF file: {other}"),
        };
        return Err(map.error(
            at,
            problem,
            "check the path; it is relative to the scene file and must name a .glb or .gltf file",
        ));
    }
    Ok(file)
}

/// A glTF animation by name or by index (`at` is its key).
fn animation_choice(
    raw: Option<&RawAnimation>,
    at: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<Option<AnimationChoice>> {
    match raw {
        None => Ok(None),
        Some(RawAnimation::Name(name)) => Ok(Some(AnimationChoice::Name(name.clone()))),
        Some(RawAnimation::Index(i)) if *i >= 0 => Ok(Some(AnimationChoice::Index(*i as usize))),
        Some(RawAnimation::Index(i)) => Err(map.error(
            at,
            format!("an animation index cannot be negative (got {i})"),
            "use the animation's name or its index from 0",
        )),
    }
}

fn character(
    raw: &RawCharacter,
    at: &KeyPath,
    index: usize,
    timeline: &Timeline,
    map: &SourceMap<'_>,
) -> Result<CharacterSpec> {
    let file = gltf_file(&raw.file, &at.key("file"), map)?;
    let animation = animation_choice(raw.animation.as_ref(), &at.key("animation"), map)?;
    let speed = raw.speed.unwrap_or(1.0);
    non_negative(speed, &at.key("speed"), "speed = 1.0", map)?;
    let playback = match raw.playback.as_deref().unwrap_or("loop") {
        "loop" => Playback::Loop,
        "clamp" => Playback::Clamp,
        other => {
            return Err(map.error(
                &at.key("playback"),
                format!("unknown playback {other:?}"),
                "use \"loop\" or \"clamp\"",
            ))
        }
    };
    let scale = raw.scale.unwrap_or(1.0);
    positive(
        scale,
        &at.key("scale"),
        "scale = 0.01 (a model in centimetres)",
        map,
    )?;
    let tint_srgb = color(raw.tint, [1.0; 3], &at.key("tint"), map)?;
    let mut path = Vec::new();
    for (i, key) in raw.path.iter().flatten().enumerate() {
        let key_at = at.key("path").index(i);
        let time_secs = keyframe_time(
            (key.frame, key.time_secs),
            path.last().map(|k: &PathKey| k.time_secs),
            KeyList {
                noun: "root-path",
                table: "[[character.path]]",
                count: raw.path.as_ref().map_or(0, Vec::len),
            },
            &key_at,
            timeline,
            map,
        )?;
        path.push(PathKey {
            time_secs,
            position_m: key.position,
            heading_deg: key.heading_deg.unwrap_or(0.0),
        });
    }
    if path.is_empty() {
        path.push(PathKey {
            time_secs: 0.0,
            position_m: [0.0; 3],
            heading_deg: 0.0,
        });
    }
    let name = raw.name.clone().unwrap_or_else(|| {
        let stem = file
            .file_stem()
            .map_or_else(|| "character".into(), |s| s.to_string_lossy().into_owned());
        format!("{stem}{index}")
    });
    Ok(CharacterSpec {
        name,
        file,
        animation,
        speed,
        time_offset_secs: raw.time_offset_secs.unwrap_or(0.0),
        playback,
        scale,
        tint_srgb,
        path,
        file_source: map.source_ref(&at.key("file")),
        animation_source: map.source_ref(&if raw.animation.is_some() {
            at.key("animation")
        } else {
            at.clone()
        }),
    })
}

fn lighting(raw: &RawScene, map: &SourceMap<'_>) -> Result<Lighting> {
    let sky = KeyPath::root().key("sky");
    let sun = KeyPath::root().key("sun");
    let zenith = color(
        raw.sky.zenith_color,
        DEFAULT_ZENITH_COLOR,
        &sky.key("zenith_color"),
        map,
    )?;
    let horizon = color(
        raw.sky.horizon_color,
        DEFAULT_HORIZON_COLOR,
        &sky.key("horizon_color"),
        map,
    )?;
    let ambient = color(
        raw.sky.ambient_color,
        DEFAULT_AMBIENT_COLOR,
        &sky.key("ambient_color"),
        map,
    )?;
    let ambient_intensity = raw
        .sky
        .ambient_intensity
        .unwrap_or(DEFAULT_AMBIENT_INTENSITY);
    non_negative(
        ambient_intensity,
        &sky.key("ambient_intensity"),
        "ambient_intensity = 0.3",
        map,
    )?;

    let angles_given = raw.sun.azimuth_deg.is_some() || raw.sun.elevation_deg.is_some();
    let direction = match raw.sun.direction {
        Some(_) if angles_given => {
            return Err(map.error(
                &sun.key("direction"),
                "both direction and azimuth_deg/elevation_deg are given",
                "keep one way of stating the sun's direction",
            ))
        }
        Some(v) => {
            let v = glam::DVec3::from(v);
            if v.length() == 0.0 || v.y <= 0.0 {
                return Err(map.error(
                    &sun.key("direction"),
                    format!(
                        "the direction toward the sun must point above the horizon (got {:?})",
                        v.to_array()
                    ),
                    "set e.g. direction = [0.4, 0.8, 0.4] (y up)",
                ));
            }
            v.normalize()
        }
        None => {
            let azimuth = raw
                .sun
                .azimuth_deg
                .unwrap_or(DEFAULT_SUN_AZIMUTH_DEG)
                .to_radians();
            let elevation_deg = raw.sun.elevation_deg.unwrap_or(DEFAULT_SUN_ELEVATION_DEG);
            if !(elevation_deg > 0.0 && elevation_deg <= 90.0) {
                return Err(map.error(
                    &sun.key("elevation_deg"),
                    format!("the sun must be above the horizon: 0 < elevation_deg <= 90 (got {elevation_deg})"),
                    "set e.g. elevation_deg = 55",
                ));
            }
            let elevation = elevation_deg.to_radians();
            // Azimuth 0 looks along +z, 90 along +x.
            glam::DVec3::new(
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
                elevation.cos() * azimuth.cos(),
            )
        }
    };
    let sun_color = color(raw.sun.color, DEFAULT_SUN_COLOR, &sun.key("color"), map)?;
    let intensity = raw.sun.intensity.unwrap_or(DEFAULT_SUN_INTENSITY);
    non_negative(intensity, &sun.key("intensity"), "intensity = 1.0", map)?;
    let size_deg = raw.sun.size_deg.unwrap_or(DEFAULT_SUN_SIZE_DEG);
    if !(size_deg > 0.0 && size_deg <= 45.0) {
        return Err(map.error(
            &sun.key("size_deg"),
            format!("the sun's angular diameter must be in (0, 45] degrees (got {size_deg})"),
            "set e.g. size_deg = 0.53 (the real sun)",
        ));
    }
    let linear = |c: [f64; 3], scale: f64| super::to_vec3(srgb_to_linear3(c).map(|v| v * scale));
    Ok(Lighting {
        sky_zenith_linear: linear(zenith, 1.0),
        sky_horizon_linear: linear(horizon, 1.0),
        sun_direction: direction.as_vec3(),
        sun_color_linear: linear(sun_color, intensity),
        sun_size_deg: size_deg as f32,
        ambient_linear: linear(ambient, ambient_intensity),
    })
}

/// An sRGB colour in 0..=1 (the file's convention), or its default.
fn color(
    value: Option<[f64; 3]>,
    default: [f64; 3],
    at: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<[f64; 3]> {
    let c = value.unwrap_or(default);
    if c.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(map.error(
            at,
            format!("colour components are sRGB between 0 and 1 (got {c:?})"),
            "scale it into 0..1 (use the intensity keys for brightness)",
        ));
    }
    Ok(c)
}

/// A value the file did not write (a default, or one derived from other keys) against its key's
/// stated range in [`super::limits::KEY_RANGES`], in the words of the check of written numbers
/// (which has already checked every number the file holds).
fn in_stated_range(value: f64, at: &KeyPath, map: &SourceMap<'_>) -> Result<()> {
    let range = super::limits::range_of(at).expect("in_stated_range: the key has a stated range");
    if range.contains(value) {
        return Ok(());
    }
    let (problem, fix) = range.problem(&value.to_string());
    Err(map.error(at, problem, fix))
}

fn positive(value: f64, at: &KeyPath, example: &str, map: &SourceMap<'_>) -> Result<()> {
    if value > 0.0 {
        Ok(())
    } else {
        Err(map.error(
            at,
            format!("must be positive (got {value})"),
            format!("set e.g. {example}"),
        ))
    }
}

fn non_negative(value: f64, at: &KeyPath, example: &str, map: &SourceMap<'_>) -> Result<()> {
    if value >= 0.0 {
        Ok(())
    } else {
        Err(map.error(
            at,
            format!("cannot be negative (got {value})"),
            format!("set e.g. {example}"),
        ))
    }
}

fn max_edge(value: f64, at: &KeyPath, map: &SourceMap<'_>) -> Result<f64> {
    if value >= MIN_MAX_EDGE_M {
        Ok(value)
    } else {
        Err(map.error(
            at,
            format!("the tessellation spacing must be at least {MIN_MAX_EDGE_M} m (got {value})"),
            "set e.g. max_edge_m = 0.1",
        ))
    }
}

fn quoted_list(items: &[&str]) -> String {
    items
        .iter()
        .map(|s| format!("{s:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}
