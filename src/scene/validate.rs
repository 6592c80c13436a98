//! Raw scene (as written) -> validated [`Scene`]: defaults filled in, every value checked, and each
//! problem reported at the key that causes it, with what to change.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use super::error::{KeyPath, SourceMap};
use super::format::{
    RawAnimation, RawCameraKey, RawCharacter, RawObject, RawRipples, RawScene, RawTexture, RawWater,
};
use super::limits::{MAX_FRAME_NUMBER, MAX_TIMELINE_FRAMES};
use super::primitives::DEFAULT_MAX_EDGE_M;
use super::textures::{srgb_to_linear3, ImageSpec, LaneSpec, TextureSpec, TilesSpec};
use super::{
    AnimationChoice, CharacterSpec, ObjectSpec, PathKey, Playback, QualitySpec, RippleSpec, Scene,
    SceneError, ShapeSpec, WaterSpec, WaveSpec,
};
use crate::draw::Lighting;
use crate::timeline::{CameraKey, Timeline};

type Result<T> = std::result::Result<T, SceneError>;

const DEFAULT_FPS: f64 = 24.0;
const DEFAULT_FRAMES: [i64; 2] = [1, 48];
const DEFAULT_WATER_MIN_XZ: [f64; 2] = [-5.0, -2.5];
const DEFAULT_WATER_MAX_XZ: [f64; 2] = [5.0, 2.5];
const DEFAULT_RESOLUTION: [i64; 2] = [128, 64];
/// Membrane grids beyond this many cells a side are surely a typo (and would not fit in memory).
const MAX_RESOLUTION: i64 = 8192;
const DEFAULT_N_ABOVE: f64 = 1.0;
const DEFAULT_N_BELOW: f64 = 1.333;
/// Clear pool water: red is absorbed within metres, blue travels far (Pope & Fry 1997, roughly).
const DEFAULT_ABSORPTION_PER_M: [f64; 3] = [0.45, 0.07, 0.03];
const DEFAULT_SCATTER_COLOR: [f64; 3] = [0.05, 0.30, 0.40];
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
    let camera_keys = camera_keys(raw.camera.as_deref(), &timeline, &water, map)?;
    let lighting = lighting(&raw, map)?;
    let quality = quality(&raw, map)?;
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
        camera_keys,
        water,
        objects: Arc::from(objects),
        characters: Arc::from(characters),
        lighting,
        quality,
    })
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

fn water(raw: &RawWater, has_characters: bool, map: &SourceMap<'_>) -> Result<WaterSpec> {
    let path = KeyPath::root().key("water");
    let min_xz = raw.min.unwrap_or(DEFAULT_WATER_MIN_XZ);
    let max_xz = raw.max.unwrap_or(DEFAULT_WATER_MAX_XZ);
    if max_xz[0] <= min_xz[0] || max_xz[1] <= min_xz[1] {
        let at = if raw.max.is_some() {
            path.key("max")
        } else {
            path.key("min")
        };
        return Err(map.error(
            &at,
            format!(
                "the water's extent is empty: max {max_xz:?} must exceed min {min_xz:?} in both x and z"
            ),
            "set e.g. min = [-5.0, -2.5] and max = [5.0, 2.5]",
        ));
    }
    let resolution = raw.resolution.unwrap_or(DEFAULT_RESOLUTION);
    if resolution
        .iter()
        .any(|&cells| !(1..=MAX_RESOLUTION).contains(&cells))
    {
        return Err(map.error(
            &path.key("resolution"),
            format!(
                "must be at least 1 and at most {MAX_RESOLUTION} cells in each direction (got [{}, {}])",
                resolution[0], resolution[1]
            ),
            "set e.g. resolution = [128, 64]",
        ));
    }
    let n_above = raw.n_above.unwrap_or(DEFAULT_N_ABOVE);
    let n_below = raw.n_below.unwrap_or(DEFAULT_N_BELOW);
    for (key, n, example) in [
        ("n_above", n_above, "1.0 (air)"),
        ("n_below", n_below, "1.333 (water)"),
    ] {
        if n <= 0.0 {
            return Err(map.error(
                &path.key(key),
                format!("an index of refraction must be positive (got {n})"),
                format!("set e.g. {key} = {example}"),
            ));
        }
    }
    let absorption_per_m = raw.absorption_per_m.unwrap_or(DEFAULT_ABSORPTION_PER_M);
    if absorption_per_m.iter().any(|&a| a < 0.0) {
        return Err(map.error(
            &path.key("absorption_per_m"),
            format!("absorption coefficients cannot be negative (got {absorption_per_m:?})"),
            "set e.g. absorption_per_m = [0.45, 0.07, 0.03] (clear pool water, 1/m)",
        ));
    }
    let scatter = color(
        raw.scatter_color,
        DEFAULT_SCATTER_COLOR,
        &path.key("scatter_color"),
        map,
    )?;

    let mut waves = Vec::new();
    for (i, wave) in raw.wave.iter().flatten().enumerate() {
        let at = path.key("wave").index(i);
        if wave.amplitude_m < 0.0 {
            return Err(map.error(
                &at.key("amplitude_m"),
                format!("cannot be negative (got {})", wave.amplitude_m),
                "set e.g. amplitude_m = 0.02 (shift phase_rad by 3.14159 to flip a wave)",
            ));
        }
        positive(
            wave.wavelength_m,
            &at.key("wavelength_m"),
            "wavelength_m = 2.0",
            map,
        )?;
        let direction_deg = match (wave.direction_deg, wave.direction) {
            (Some(_), Some(_)) => {
                return Err(map.error(
                    &at.key("direction"),
                    "both direction and direction_deg are given",
                    "keep one of them",
                ))
            }
            (Some(deg), None) => deg,
            (None, Some([x, z])) => {
                if x * x + z * z == 0.0 {
                    return Err(map.error(
                        &at.key("direction"),
                        "a direction cannot be the zero vector",
                        "set e.g. direction = [1.0, 0.5] (x, z)",
                    ));
                }
                z.atan2(x).to_degrees()
            }
            (None, None) => 0.0,
        };
        if let Some(speed) = wave.speed_m_per_s {
            positive(
                speed,
                &at.key("speed_m_per_s"),
                "speed_m_per_s = 1.5, or remove it for deep-water speed",
                map,
            )?;
        }
        waves.push(WaveSpec {
            amplitude_m: wave.amplitude_m,
            wavelength_m: wave.wavelength_m,
            direction_deg,
            phase_rad: wave.phase_rad.unwrap_or(0.0),
            speed_m_per_s: wave.speed_m_per_s,
        });
    }

    Ok(WaterSpec {
        level_m: raw.level_m.unwrap_or(0.0),
        min_xz,
        max_xz,
        resolution: [resolution[0] as u32, resolution[1] as u32],
        n_above,
        n_below,
        absorption_per_m,
        scatter_color_linear: srgb_to_linear3(scatter),
        waves,
        ripples: ripples(
            raw.ripples.as_ref(),
            has_characters,
            (min_xz, max_xz),
            [resolution[0], resolution[1]],
            map,
        )?,
    })
}

/// Ripples are on when the scene has characters to make them, unless `enabled = false`.
/// `membrane_cells` is `[water] resolution`: the default ripple grid has
/// [`DEFAULT_RIPPLE_NODES_PER_CELL`] nodes per membrane cell.
fn ripples(
    raw: Option<&RawRipples>,
    has_characters: bool,
    (min_xz, max_xz): ([f64; 2], [f64; 2]),
    membrane_cells: [i64; 2],
    map: &SourceMap<'_>,
) -> Result<RippleSpec> {
    let path = KeyPath::root().key("water").key("ripples");
    let default = RawRipples::default();
    let raw = raw.unwrap_or(&default);
    if raw.speed_m_per_s.is_some() {
        return Err(map.error(
            &path.key("speed_m_per_s"),
            "ripples no longer have one speed: they are water waves, each wavelength travelling at \
             the speed water's dispersion relation gives it over the pool's depth",
            "remove speed_m_per_s; long waves travel at sqrt(9.81 * depth), so a shallower pool \
             (the pool's depth_m, or [water.ripples] depth_m) makes them slower",
        ));
    }
    let (width_m, depth_m) = (max_xz[0] - min_xz[0], max_xz[1] - min_xz[1]);
    // Square cells, DEFAULT_RIPPLE_NODES_PER_CELL per membrane cell along the finer axis.
    let spacing_m = (width_m / membrane_cells[0] as f64).min(depth_m / membrane_cells[1] as f64)
        / DEFAULT_RIPPLE_NODES_PER_CELL as f64;
    let default_nodes = [
        ((width_m / spacing_m).round() as i64 + 1).min(MAX_RIPPLE_NODES),
        ((depth_m / spacing_m).round() as i64 + 1).min(MAX_RIPPLE_NODES),
    ];
    let nodes = raw.resolution.unwrap_or(default_nodes);
    if nodes.iter().any(|&n| !(3..=MAX_RIPPLE_NODES).contains(&n)) {
        return Err(map.error(
            &path.key("resolution"),
            format!(
                "the ripple grid needs 3 to {MAX_RIPPLE_NODES} nodes in each direction (got [{}, {}])",
                nodes[0], nodes[1]
            ),
            "set e.g. resolution = [256, 128]",
        ));
    }
    let spacing = [
        width_m / (nodes[0] - 1) as f64,
        depth_m / (nodes[1] - 1) as f64,
    ];
    if (spacing[0] - spacing[1]).abs() > 0.01 * spacing[0].max(spacing[1]) {
        return Err(map.error(
            &path.key("resolution"),
            format!(
                "ripple cells must be square: these nodes make cells of {:.4} m along x and {:.4} m along z",
                spacing[0], spacing[1]
            ),
            format!(
                "choose nodes in the water's proportions, e.g. resolution = [{}, {}]",
                default_nodes[0], default_nodes[1]
            ),
        ));
    }
    // Their ranges are checked where they are written (`super::limits`).
    let water_depth_m = raw.depth_m;
    let surface_tension_n_per_m = raw
        .surface_tension_n_per_m
        .unwrap_or(crate::sim::ripples::WATER_SURFACE_TENSION_N_PER_M);
    let density_kg_per_m3 = raw
        .density_kg_per_m3
        .unwrap_or(crate::sim::ripples::WATER_DENSITY_KG_PER_M3);
    let damping_per_s = raw.damping_per_s.unwrap_or(DEFAULT_RIPPLE_DAMPING_PER_S);
    non_negative(
        damping_per_s,
        &path.key("damping_per_s"),
        "damping_per_s = 0.5",
        map,
    )?;
    let border = match raw.border.as_deref().unwrap_or("reflect") {
        "reflect" => crate::sim::Border::Reflect,
        "absorb" => crate::sim::Border::Absorb,
        other => {
            return Err(map.error(
                &path.key("border"),
                format!("unknown border {other:?}"),
                "use \"reflect\" (walls) or \"absorb\" (open water)",
            ))
        }
    };
    let sponge_width_m = raw.sponge_width_m.unwrap_or(DEFAULT_SPONGE_WIDTH_M);
    non_negative(
        sponge_width_m,
        &path.key("sponge_width_m"),
        "sponge_width_m = 0.5",
        map,
    )?;
    let strength = raw.strength.unwrap_or(1.0);
    non_negative(strength, &path.key("strength"), "strength = 1.0", map)?;
    let coupling_depth_m = raw.coupling_depth_m.unwrap_or(DEFAULT_COUPLING_DEPTH_M);
    positive(
        coupling_depth_m,
        &path.key("coupling_depth_m"),
        "coupling_depth_m = 0.1",
        map,
    )?;
    Ok(RippleSpec {
        enabled: raw.enabled.unwrap_or(has_characters),
        nodes: [nodes[0] as u32, nodes[1] as u32],
        depth_m: water_depth_m,
        surface_tension_n_per_m,
        density_kg_per_m3,
        damping_per_s,
        border,
        sponge_width_m,
        strength,
        coupling_depth_m,
    })
}

fn character(
    raw: &RawCharacter,
    at: &KeyPath,
    index: usize,
    timeline: &Timeline,
    map: &SourceMap<'_>,
) -> Result<CharacterSpec> {
    let folder = map.file.parent().unwrap_or(Path::new(""));
    let file = folder.join(&raw.file);
    if let Err(error) = crate::files::check_regular(&file, crate::files::MAX_ASSET_BYTES) {
        let problem = match error {
            crate::files::InputFileError::NotFound(_) => format!(
                "cannot find the glTF file {} (resolved against the scene's folder)",
                file.display()
            ),
            other => format!("cannot use the glTF file: {other}"),
        };
        return Err(map.error(
            &at.key("file"),
            problem,
            "check the path; it is relative to the scene file and must name a .glb or .gltf file",
        ));
    }
    let animation = match &raw.animation {
        None => None,
        Some(RawAnimation::Name(name)) => Some(AnimationChoice::Name(name.clone())),
        Some(RawAnimation::Index(i)) if *i >= 0 => Some(AnimationChoice::Index(*i as usize)),
        Some(RawAnimation::Index(i)) => {
            return Err(map.error(
                &at.key("animation"),
                format!("an animation index cannot be negative (got {i})"),
                "use the animation's name or its index from 0",
            ))
        }
    };
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

fn camera_keys(
    raw: Option<&[RawCameraKey]>,
    timeline: &Timeline,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<Vec<CameraKey>> {
    let path = KeyPath::root().key("camera");
    let Some(raw) = raw.filter(|keys| !keys.is_empty()) else {
        // Standing on the deck at the middle of one long side, looking across and down.
        let [x0, z0] = water.min_xz;
        let [x1, z1] = water.max_xz;
        let eye = Vec3::new(
            (0.5 * (x0 + x1)) as f32,
            (water.level_m + 2.2) as f32,
            (z0 - 1.5) as f32,
        );
        let target = Vec3::new(
            (0.5 * (x0 + x1)) as f32,
            (water.level_m - 1.2) as f32,
            (0.25 * z0 + 0.75 * z1) as f32,
        );
        return Ok(vec![CameraKey {
            time_secs: 0.0,
            eye,
            target,
            fov_y_deg: DEFAULT_FOV_DEG as f32,
        }]);
    };
    let crest_m = water.level_m + water.max_crest_m();
    let mut keys: Vec<CameraKey> = Vec::with_capacity(raw.len());
    for (i, key) in raw.iter().enumerate() {
        let at = path.index(i);
        let time_secs = keyframe_time(
            (key.frame, key.time_secs),
            keys.last().map(|k| k.time_secs),
            KeyList {
                noun: "camera",
                table: "[[camera]]",
                count: raw.len(),
            },
            &at,
            timeline,
            map,
        )?;
        let eye = key.eye.map(|v| v as f32);
        let target = key.target.map(|v| v as f32);
        if key.eye[1] <= crest_m {
            return Err(map.error(
                &at.key("eye"),
                format!(
                    "the eye is under the water (y = {} m; the surface reaches {crest_m} m at its highest \
                     crest); snell renders from the air",
                    key.eye[1]
                ),
                format!("raise it, e.g. eye = [{}, {}, {}]", key.eye[0], water.level_m + 2.0, key.eye[2]),
            ));
        }
        if Vec3::from(eye).distance(Vec3::from(target)) < 1e-4 {
            return Err(map.error(
                &at.key("target"),
                "the target is at the eye",
                "look at a point away from the eye",
            ));
        }
        let fov_deg = key.fov_deg.unwrap_or(DEFAULT_FOV_DEG);
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(map.error(
                &at.key("fov_deg"),
                format!(
                    "the vertical field of view must be between 0 and 180 degrees (got {fov_deg})"
                ),
                "set e.g. fov_deg = 50",
            ));
        }
        keys.push(CameraKey {
            time_secs,
            eye: eye.into(),
            target: target.into(),
            fov_y_deg: fov_deg as f32,
        });
    }
    check_interpolated_views(&keys, timeline, &path, map)?;
    Ok(keys)
}

/// The camera between keys is interpolated (eye and target separately): at no frame may the eye
/// come onto its target, where the view has no direction. Straight up or down is fine (the camera
/// has a stated fallback up vector). Every frame of the timeline is sampled, as a render would.
fn check_interpolated_views(
    keys: &[CameraKey],
    timeline: &Timeline,
    path: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<()> {
    let track = crate::timeline::CameraTrack::try_new(keys.to_vec()).map_err(|error| {
        map.error(
            path,
            format!("the camera keys cannot be interpolated: {error}"),
            "",
        )
    })?;
    for frame in timeline.first_frame..=timeline.last_frame {
        let time_secs = timeline.time_secs(frame);
        let camera = track.sample(time_secs);
        if camera.eye.distance(camera.target) >= 1e-4 {
            continue;
        }
        // The key that ends the segment (or the last key).
        let after = keys
            .iter()
            .position(|key| key.time_secs >= time_secs)
            .unwrap_or(keys.len() - 1);
        let before = after.saturating_sub(1);
        return Err(map.error(
            &path.index(after).key("target"),
            format!(
                "between camera keys {before} and {after} the interpolated eye reaches the target at frame {frame} \
                 (t = {time_secs:.3} s, eye {:?}): the view has no direction there",
                camera.eye.to_array()
            ),
            "move the keys' targets so the eye passes beside them, or add a key in between",
        ));
    }
    Ok(())
}

/// A list of keyframes, for [`keyframe_time`]'s messages.
struct KeyList {
    /// "camera", "root-path".
    noun: &'static str,
    /// The TOML tables the keys are written as.
    table: &'static str,
    count: usize,
}

/// A keyframe's time in seconds from `frame` or `time_secs` (a key alone in its list may have
/// neither: t = 0), checked to come after the previous key's time.
fn keyframe_time(
    (frame, time_secs): (Option<f64>, Option<f64>),
    previous_secs: Option<f64>,
    list: KeyList,
    at: &KeyPath,
    timeline: &Timeline,
    map: &SourceMap<'_>,
) -> Result<f64> {
    let (time_secs, time_key) = match (frame, time_secs) {
        (Some(_), Some(_)) => {
            return Err(map.error(
                &at.key("time_secs"),
                "both frame and time_secs are given",
                "keep one of them",
            ))
        }
        (Some(frame), None) => (
            (frame - timeline.first_frame as f64) / timeline.fps,
            "frame",
        ),
        (None, Some(t)) => (t, "time_secs"),
        (None, None) if list.count == 1 => return Ok(0.0),
        (None, None) => {
            return Err(map.error(
                at,
                format!(
                    "a {} keyframe needs a time when there are several",
                    list.noun
                ),
                "add frame = N or time_secs = T",
            ))
        }
    };
    match previous_secs {
        Some(previous) if time_secs <= previous => Err(map.error(
            &at.key(time_key),
            format!(
                "{} keyframes are out of order: this one is at {time_secs:.3} s, the one before it \
                 at {previous:.3} s; keys must be in increasing time order",
                list.noun
            ),
            format!("reorder the {} tables or correct this time", list.table),
        )),
        _ => Ok(time_secs),
    }
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

fn default_pool(max_edge_m: f64) -> ObjectSpec {
    ObjectSpec {
        name: "pool".into(),
        shape: ShapeSpec::Pool {
            depth_m: 1.6,
            coping_height_m: 0.25,
            deck_width_m: 3.0,
            floor_texture: default_floor_tiles(),
            deck_texture: default_deck_stone(),
        },
        translate_m: [0.0; 3],
        rotate_deg: [0.0; 3],
        scale: [1.0; 3],
        max_edge_m,
        texture: default_wall_tiles(),
        tint_srgb: [1.0; 3],
    }
}

/// White glazed tiles with some pale-blue ones among them, light-grey grout.
fn default_wall_tiles() -> TextureSpec {
    TextureSpec::Tiles(TilesSpec {
        color_srgb: [0.93, 0.96, 0.98],
        grout_color_srgb: [0.62, 0.66, 0.68],
        tile_size_m: 0.125,
        grout_width_m: 0.004,
        variation: 0.04,
        accent_color_srgb: [0.72, 0.87, 0.96],
        accent_fraction: 0.15,
        lanes: None,
        seed: 1,
    })
}

/// The wall tiles with dark-blue lane stripes every 2.5 m.
fn default_floor_tiles() -> TextureSpec {
    let TextureSpec::Tiles(mut tiles) = default_wall_tiles() else {
        unreachable!("wall tiles are tiles")
    };
    tiles.lanes = Some(LaneSpec {
        spacing_m: 2.5,
        width_m: 0.25,
        color_srgb: [0.04, 0.10, 0.32],
    });
    tiles.seed = 2;
    TextureSpec::Tiles(tiles)
}

/// Large sandstone-coloured slabs.
fn default_deck_stone() -> TextureSpec {
    TextureSpec::Tiles(TilesSpec {
        color_srgb: [0.80, 0.76, 0.68],
        grout_color_srgb: [0.58, 0.55, 0.50],
        tile_size_m: 0.5,
        grout_width_m: 0.008,
        variation: 0.10,
        accent_color_srgb: [0.74, 0.70, 0.62],
        accent_fraction: 0.3,
        lanes: None,
        seed: 3,
    })
}

fn object(
    raw: &RawObject,
    at: &KeyPath,
    index: usize,
    scene_max_edge_m: f64,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<ObjectSpec> {
    let shape_name = raw.shape.as_str();
    if !SHAPES.contains(&shape_name) {
        return Err(map.error(
            &at.key("shape"),
            format!("unknown shape {shape_name:?}"),
            format!("use one of {}", quoted_list(&SHAPES)),
        ));
    }
    let shape_keys: &[&str] = match shape_name {
        "box" | "quad" => &["size_m"],
        "sphere" => &["radius_m"],
        _ => &[
            "depth_m",
            "coping_height_m",
            "deck_width_m",
            "floor_texture",
            "deck_texture",
        ],
    };
    for (key, span) in map.keys_in(at) {
        let allowed =
            COMMON_OBJECT_KEYS.contains(&key.as_str()) || shape_keys.contains(&key.as_str());
        let moves_pool =
            shape_name == "pool" && ["translate", "rotate_deg", "scale"].contains(&key.as_str());
        if !allowed || moves_pool {
            let fix = if moves_pool {
                "remove it: the pool follows the water's extent (move water.min and water.max instead)".to_owned()
            } else {
                format!(
                    "remove it; a {shape_name} takes {}",
                    quoted_list(shape_keys)
                )
            };
            return Err(map.error_at(
                span.start,
                at.key(&key).to_string(),
                format!("{key} does not apply to shape = {shape_name:?}"),
                fix,
            ));
        }
    }

    let max_edge_m = match raw.max_edge_m {
        Some(v) => max_edge(v, &at.key("max_edge_m"), map)?,
        None => scene_max_edge_m,
    };
    let size = |count: usize, default: &[f64], example: &str| -> Result<Vec<f64>> {
        let size = raw.size_m.clone().unwrap_or_else(|| default.to_vec());
        if size.len() != count || size.iter().any(|&s| s <= 0.0) {
            return Err(map.error(
                &at.key("size_m"),
                format!("a {shape_name} needs {count} positive sizes in metres (got {size:?})"),
                format!("set e.g. size_m = {example}"),
            ));
        }
        Ok(size)
    };
    let shape = match shape_name {
        "box" => {
            let s = size(3, &[1.0, 1.0, 1.0], "[1.0, 0.5, 0.8]")?;
            ShapeSpec::Box {
                size_m: [s[0], s[1], s[2]],
            }
        }
        "quad" => {
            let s = size(2, &[1.0, 1.0], "[2.0, 1.0]")?;
            ShapeSpec::Quad {
                size_m: [s[0], s[1]],
            }
        }
        "sphere" => {
            let radius_m = raw.radius_m.unwrap_or(0.5);
            positive(radius_m, &at.key("radius_m"), "radius_m = 0.3", map)?;
            ShapeSpec::Sphere { radius_m }
        }
        _ => {
            let depth_m = raw.depth_m.unwrap_or(1.6);
            positive(depth_m, &at.key("depth_m"), "depth_m = 1.6", map)?;
            let coping_height_m = raw.coping_height_m.unwrap_or(0.25);
            if coping_height_m <= water.max_crest_m() {
                return Err(map.error(
                    &at.key("coping_height_m"),
                    format!(
                        "the deck must stand above the highest wave crest ({} m above the level; got {coping_height_m} m)",
                        water.max_crest_m()
                    ),
                    "raise it, e.g. coping_height_m = 0.25, or lower the waves' amplitudes",
                ));
            }
            let deck_width_m = raw.deck_width_m.unwrap_or(3.0);
            positive(
                deck_width_m,
                &at.key("deck_width_m"),
                "deck_width_m = 3.0",
                map,
            )?;
            let floor_texture = texture(
                raw.floor_texture.as_ref(),
                default_floor_tiles(),
                &at.key("floor_texture"),
                map,
            )?;
            let deck_texture = texture(
                raw.deck_texture.as_ref(),
                default_deck_stone(),
                &at.key("deck_texture"),
                map,
            )?;
            ShapeSpec::Pool {
                depth_m,
                coping_height_m,
                deck_width_m,
                floor_texture,
                deck_texture,
            }
        }
    };
    let default_texture = match shape {
        ShapeSpec::Pool { .. } => default_wall_tiles(),
        _ => TextureSpec::Solid {
            color_srgb: [0.8, 0.8, 0.8],
        },
    };
    let texture = texture(
        raw.texture.as_ref(),
        default_texture,
        &at.key("texture"),
        map,
    )?;
    let scale = raw.scale.unwrap_or([1.0; 3]);
    if scale.iter().any(|&s| s <= 0.0) {
        return Err(map.error(
            &at.key("scale"),
            format!("scale factors must be positive (got {scale:?}); a mirror would turn the mesh inside out"),
            "set e.g. scale = [1.0, 1.0, 1.0]",
        ));
    }
    Ok(ObjectSpec {
        name: raw
            .name
            .clone()
            .unwrap_or_else(|| format!("{shape_name}{index}")),
        shape,
        translate_m: raw.translate.unwrap_or([0.0; 3]),
        rotate_deg: raw.rotate_deg.unwrap_or([0.0; 3]),
        scale,
        max_edge_m,
        texture,
        tint_srgb: color(raw.tint, [1.0; 3], &at.key("tint"), map)?,
    })
}

/// A texture table: its kind is stated, implied by `image`, or the slot's default kind; keys it does
/// not state take the default's values when the kinds agree.
fn texture(
    raw: Option<&RawTexture>,
    default: TextureSpec,
    at: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<TextureSpec> {
    let Some(raw) = raw else { return Ok(default) };
    let kind = match (&raw.kind, &raw.image) {
        (Some(kind), _) => kind.as_str(),
        (None, Some(_)) => "image",
        (None, None) => match default {
            TextureSpec::Solid { .. } => "solid",
            TextureSpec::Checker { .. } => "checker",
            TextureSpec::Tiles(_) => "tiles",
            TextureSpec::Image(_) => "image",
        },
    };
    if !TEXTURE_KINDS.contains(&kind) {
        return Err(map.error(
            &at.key("kind"),
            format!("unknown texture kind {kind:?}"),
            format!("use one of {}", quoted_list(&TEXTURE_KINDS)),
        ));
    }
    let kind_keys: &[&str] = match kind {
        "solid" => &["color"],
        "checker" => &["color", "color_b", "square_m"],
        "tiles" => &[
            "color",
            "grout_color",
            "tile_size_m",
            "grout_width_m",
            "variation",
            "accent_color",
            "accent_fraction",
            "lane_spacing_m",
            "lane_width_m",
            "lane_color",
            "seed",
        ],
        _ => &["image", "size_m"],
    };
    for (key, span) in map.keys_in(at) {
        if key != "kind" && !kind_keys.contains(&key.as_str()) {
            return Err(map.error_at(
                span.start,
                at.key(&key).to_string(),
                format!("{key} does not apply to a {kind} texture"),
                format!(
                    "remove it; a {kind} texture takes {}",
                    quoted_list(kind_keys)
                ),
            ));
        }
    }
    let color_at = |key: &str, value: Option<[f64; 3]>, fallback: [f64; 3]| {
        color(value, fallback, &at.key(key), map)
    };
    match kind {
        "solid" => {
            let fallback = match default {
                TextureSpec::Solid { color_srgb } => color_srgb,
                _ => [0.8, 0.8, 0.8],
            };
            Ok(TextureSpec::Solid {
                color_srgb: color_at("color", raw.color, fallback)?,
            })
        }
        "checker" => {
            let square_m = raw.square_m.unwrap_or(0.5);
            positive(square_m, &at.key("square_m"), "square_m = 0.5", map)?;
            Ok(TextureSpec::Checker {
                color_srgb: color_at("color", raw.color, [0.9, 0.9, 0.9])?,
                color_b_srgb: color_at("color_b", raw.color_b, [0.15, 0.15, 0.15])?,
                square_m,
            })
        }
        "tiles" => {
            let base = match default {
                TextureSpec::Tiles(tiles) => tiles,
                _ => match default_wall_tiles() {
                    TextureSpec::Tiles(tiles) => tiles,
                    _ => unreachable!("wall tiles are tiles"),
                },
            };
            let tile_size_m = raw.tile_size_m.unwrap_or(base.tile_size_m);
            positive(
                tile_size_m,
                &at.key("tile_size_m"),
                "tile_size_m = 0.125",
                map,
            )?;
            let grout_width_m = raw.grout_width_m.unwrap_or(base.grout_width_m);
            if !(0.0..tile_size_m).contains(&grout_width_m) {
                return Err(map.error(
                    &at.key("grout_width_m"),
                    format!("must be at least 0 and less than the tile size {tile_size_m} m (got {grout_width_m})"),
                    "set e.g. grout_width_m = 0.004",
                ));
            }
            let variation = raw.variation.unwrap_or(base.variation);
            let accent_fraction = raw.accent_fraction.unwrap_or(base.accent_fraction);
            for (key, value) in [
                ("variation", variation),
                ("accent_fraction", accent_fraction),
            ] {
                if !(0.0..=1.0).contains(&value) {
                    return Err(map.error(
                        &at.key(key),
                        format!("must be between 0 and 1 (got {value})"),
                        format!("set e.g. {key} = 0.1"),
                    ));
                }
            }
            let base_lanes = base.lanes.clone();
            let lanes = match raw
                .lane_spacing_m
                .or(base_lanes.as_ref().map(|l| l.spacing_m))
            {
                // lane_spacing_m = 0 turns a default's lanes off.
                None => None,
                Some(spacing) if spacing == 0.0 && raw.lane_spacing_m.is_some() => None,
                Some(spacing_m) => {
                    if spacing_m < tile_size_m {
                        return Err(map.error(
                            &at.key("lane_spacing_m"),
                            format!("lanes must be at least a tile apart (got {spacing_m} m for {tile_size_m} m tiles)"),
                            "set e.g. lane_spacing_m = 2.5, or 0 for no lanes",
                        ));
                    }
                    let width_m = raw
                        .lane_width_m
                        .or(base_lanes.as_ref().map(|l| l.width_m))
                        .unwrap_or(0.25);
                    if !(width_m > 0.0 && width_m < spacing_m) {
                        return Err(map.error(
                            &at.key("lane_width_m"),
                            format!("must be positive and less than the lane spacing {spacing_m} m (got {width_m})"),
                            "set e.g. lane_width_m = 0.25",
                        ));
                    }
                    let fallback = base_lanes
                        .as_ref()
                        .map_or([0.04, 0.10, 0.32], |l| l.color_srgb);
                    Some(LaneSpec {
                        spacing_m,
                        width_m,
                        color_srgb: color_at("lane_color", raw.lane_color, fallback)?,
                    })
                }
            };
            Ok(TextureSpec::Tiles(TilesSpec {
                color_srgb: color_at("color", raw.color, base.color_srgb)?,
                grout_color_srgb: color_at("grout_color", raw.grout_color, base.grout_color_srgb)?,
                tile_size_m,
                grout_width_m,
                variation,
                accent_color_srgb: color_at(
                    "accent_color",
                    raw.accent_color,
                    base.accent_color_srgb,
                )?,
                accent_fraction,
                lanes,
                seed: raw.seed.unwrap_or(base.seed),
            }))
        }
        _ => {
            let image_at = at.key("image");
            let Some(written) = &raw.image else {
                return Err(map.error(
                    at,
                    "an image texture needs a file",
                    "add image = \"textures/tiles.png\"",
                ));
            };
            let folder = map.file.parent().unwrap_or(Path::new(""));
            let path = folder.join(written);
            if let Err(error) = crate::files::check_regular(&path, crate::files::MAX_ASSET_BYTES) {
                let problem = match error {
                    crate::files::InputFileError::NotFound(_) => format!(
                        "texture image {written:?} not found (looked for {})",
                        path.display()
                    ),
                    other => format!("cannot use texture image {written:?}: {other}"),
                };
                return Err(map.error(
                    &image_at,
                    problem,
                    "check the path, which is relative to the scene file's folder, and name a PNG or JPEG file",
                ));
            }
            let size_m = raw.size_m.unwrap_or([1.0, 1.0]);
            if size_m.iter().any(|&s| s <= 0.0) {
                return Err(map.error(
                    &at.key("size_m"),
                    format!(
                        "the metres one copy of the image covers must be positive (got {size_m:?})"
                    ),
                    "set e.g. size_m = [1.0, 1.0]",
                ));
            }
            Ok(TextureSpec::Image(ImageSpec {
                path,
                size_m,
                source: map.source_ref(&image_at),
            }))
        }
    }
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
