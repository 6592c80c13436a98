//! The scene file as written: serde structs mirroring the TOML, every field optional unless a scene
//! cannot do without it, unknown keys refused. Values are checked and defaulted in `validate`,
//! which knows the key paths and so can point at the offending line.

use serde::de::{IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScene {
    pub name: Option<String>,
    /// Longest triangle edge of the built-in primitives, metres.
    pub max_edge_m: Option<f64>,
    #[serde(default)]
    pub timeline: RawTimeline,
    pub camera: Option<RawCamera>,
    #[serde(default)]
    pub water: RawWater,
    #[serde(default)]
    pub sky: RawSky,
    #[serde(default)]
    pub sun: RawSun,
    pub object: Option<Vec<RawObject>>,
    pub character: Option<Vec<RawCharacter>>,
    pub vessel: Option<Vec<RawVessel>>,
    pub quality: Option<RawQuality>,
    pub antialias: Option<RawAntialias>,
}

/// `[antialias]`: samples a pixel.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAntialias {
    /// The rasteriser's points a pixel along each side: 1, or 2 supersampled.
    pub supersample: Option<i64>,
    /// The reference's stratified rays a pixel along each side (n x n).
    pub reference_grid: Option<i64>,
}

/// `[[vessel]]`: a glass pane or cylinder objects are seen through (`crate::vessel`). Every key of
/// both kinds is here so that a key of the other kind gets a message of its own.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawVessel {
    pub name: Option<String>,
    /// "pane" or "cylinder" (required; optional here so that its absence gets a message).
    pub kind: Option<String>,
    pub glass_index: Option<f64>,
    /// "air" or "water".
    pub inside: Option<String>,
    // A pane's keys.
    pub position: Option<[f64; 3]>,
    pub normal: Option<[f64; 3]>,
    pub up: Option<[f64; 3]>,
    pub size_m: Option<[f64; 2]>,
    pub thickness_m: Option<f64>,
    // A cylinder's keys.
    pub base: Option<[f64; 3]>,
    pub axis: Option<[f64; 3]>,
    pub inner_radius_m: Option<f64>,
    pub outer_radius_m: Option<f64>,
    pub height_m: Option<f64>,
}

/// `[quality]`: how accurate the scene must be, so snell models no more than it needs.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawQuality {
    /// Screen-space position error allowed against the ray-traced reference, pixels.
    pub max_error_px: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTimeline {
    pub fps: Option<f64>,
    pub frames: Option<[i64; 2]>,
}

/// `camera`: `[[camera]]` keyframe tables, or one `[camera]` table that takes the camera from a
/// glTF file. (TOML itself refuses both in one file: a key defined twice.)
#[derive(Debug)]
pub(crate) enum RawCamera {
    Keys(Vec<RawCameraKey>),
    Gltf(RawGltfCamera),
}

impl<'de> Deserialize<'de> for RawCamera {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct CameraVisitor;
        impl<'de> Visitor<'de> for CameraVisitor {
            type Value = RawCamera;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "[[camera]] keyframe tables, or a [camera] table with gltf = \"file.glb\"",
                )
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<RawCamera, A::Error> {
                Vec::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(RawCamera::Keys)
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<RawCamera, A::Error> {
                RawGltfCamera::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(RawCamera::Gltf)
            }
        }
        deserializer.deserialize_any(CameraVisitor)
    }
}

/// `[camera]`: the camera of a glTF file, animated by the file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawGltfCamera {
    /// The .glb/.gltf, relative to the scene file (required; optional here so that its absence
    /// gets a message of its own).
    pub gltf: Option<String>,
    /// The name of the node that carries the camera.
    pub node: Option<String>,
    pub animation: Option<RawAnimation>,
    pub time_offset_secs: Option<f64>,
    /// "gltf" (the camera's aspectRatio must match the frame's) or "render".
    pub aspect: Option<String>,
    // Keyframe keys, refused with a message that says why (they conflict with the file's camera).
    pub eye: Option<IgnoredAny>,
    pub target: Option<IgnoredAny>,
    pub fov_deg: Option<IgnoredAny>,
    pub frame: Option<IgnoredAny>,
    pub time_secs: Option<IgnoredAny>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCameraKey {
    pub frame: Option<f64>,
    pub time_secs: Option<f64>,
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub fov_deg: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawWater {
    pub level_m: Option<f64>,
    /// (x, z) of the membrane's corner with the smallest coordinates.
    pub min: Option<[f64; 2]>,
    pub max: Option<[f64; 2]>,
    /// Cells along x and z.
    pub resolution: Option<[i64; 2]>,
    pub n_above: Option<f64>,
    pub n_below: Option<f64>,
    pub absorption_per_m: Option<[f64; 3]>,
    pub scatter_color: Option<[f64; 3]>,
    /// Rms slope of the waves finer than the membrane (the sun glint's roughness).
    pub roughness: Option<f64>,
    pub wave: Option<Vec<RawWave>>,
    pub ripples: Option<RawRipples>,
}

/// `[water.ripples]`: the simulated ripples characters make.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRipples {
    pub enabled: Option<bool>,
    /// Grid nodes along x and z.
    pub resolution: Option<[i64; 2]>,
    /// No longer a setting (ripples follow the dispersion relation); kept to say so.
    pub speed_m_per_s: Option<f64>,
    pub depth_m: Option<f64>,
    pub surface_tension_n_per_m: Option<f64>,
    pub density_kg_per_m3: Option<f64>,
    pub damping_per_s: Option<f64>,
    pub border: Option<String>,
    pub sponge_width_m: Option<f64>,
    pub strength: Option<f64>,
    pub coupling_depth_m: Option<f64>,
}

/// `[[character]]`: a skinned, animated glTF model walking a root path.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCharacter {
    pub name: Option<String>,
    pub file: String,
    pub animation: Option<RawAnimation>,
    pub speed: Option<f64>,
    pub time_offset_secs: Option<f64>,
    pub playback: Option<String>,
    pub scale: Option<f64>,
    pub tint: Option<[f64; 3]>,
    pub path: Option<Vec<RawPathKey>>,
}

/// An animation by name or by index.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum RawAnimation {
    Index(i64),
    Name(String),
}

/// `[[character.path]]`: where the character's root is at a time, and which way it faces.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawPathKey {
    pub frame: Option<f64>,
    pub time_secs: Option<f64>,
    pub position: [f64; 3],
    pub heading_deg: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawWave {
    pub amplitude_m: f64,
    pub wavelength_m: f64,
    pub direction_deg: Option<f64>,
    pub direction: Option<[f64; 2]>,
    pub phase_rad: Option<f64>,
    pub speed_m_per_s: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSky {
    pub zenith_color: Option<[f64; 3]>,
    pub horizon_color: Option<[f64; 3]>,
    pub ambient_color: Option<[f64; 3]>,
    pub ambient_intensity: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSun {
    pub azimuth_deg: Option<f64>,
    pub elevation_deg: Option<f64>,
    pub direction: Option<[f64; 3]>,
    pub color: Option<[f64; 3]>,
    pub intensity: Option<f64>,
    pub size_deg: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawObject {
    pub name: Option<String>,
    pub shape: String,
    /// box: [x, y, z]; quad: [x, z].
    pub size_m: Option<Vec<f64>>,
    pub radius_m: Option<f64>,
    pub depth_m: Option<f64>,
    pub coping_height_m: Option<f64>,
    pub deck_width_m: Option<f64>,
    pub translate: Option<[f64; 3]>,
    pub rotate_deg: Option<[f64; 3]>,
    pub scale: Option<[f64; 3]>,
    pub max_edge_m: Option<f64>,
    pub texture: Option<RawTexture>,
    pub floor_texture: Option<RawTexture>,
    pub deck_texture: Option<RawTexture>,
    pub tint: Option<[f64; 3]>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTexture {
    pub kind: Option<String>,
    pub color: Option<[f64; 3]>,
    pub color_b: Option<[f64; 3]>,
    pub square_m: Option<f64>,
    pub tile_size_m: Option<f64>,
    pub grout_width_m: Option<f64>,
    pub grout_color: Option<[f64; 3]>,
    pub variation: Option<f64>,
    pub accent_color: Option<[f64; 3]>,
    pub accent_fraction: Option<f64>,
    pub lane_spacing_m: Option<f64>,
    pub lane_width_m: Option<f64>,
    pub lane_color: Option<[f64; 3]>,
    pub seed: Option<u32>,
    pub image: Option<String>,
    pub size_m: Option<[f64; 2]>,
}
