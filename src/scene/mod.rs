//! Stage 0, scene: the TOML scene file (serde, `deny_unknown_fields`, defaults), validated into a
//! [`Scene`] with errors that name file, line, column and key; built-in primitives (box, sphere,
//! quad, tiled pool) turned into world-space meshes; procedural and image textures.
//!
//! Receives a scene file; returns a [`Scene`] (cheap to clone: plain values and shared object
//! descriptions), from which the other stages take the [`Timeline`], camera keys, the water's
//! [`MembraneGrid`] and waves, [`Lighting`], [`WaterOptics`] and, via [`Scene::build_objects`], the
//! world-space [`Object`]s with their baked [`Texture`]s.
//!
//! The file format, with every key and its default, is shown in `scenes/pool.toml`; an empty
//! file gives a 10 m x 5 m tiled pool under calm water, seen from one side.

mod error;
mod format;
pub mod limits;
pub mod primitives;
pub mod resources;
pub mod textures;
mod validate;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};
use toml::de::{DeTable, DeValue};

pub use error::SceneError;
use error::{line_column_of, KeyPath, SourceMap};
use primitives::{pool_meshes, PoolDims};
pub use textures::{SourceRef, TextureSpec};

use crate::draw::{Lighting, WaterOptics};
use crate::mesh::{Material, Mesh, Object, Texture};
use crate::timeline::{CameraKey, Timeline};
use crate::water::MembraneGrid;

/// A validated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Used in output file names (`<name>.0001.exr`); the file stem unless the file says.
    pub name: String,
    /// The scene file (image textures are resolved against its folder).
    pub path: PathBuf,
    pub timeline: Timeline,
    /// Where the camera comes from: keyframes or a glTF file.
    pub camera: CameraSpec,
    pub water: WaterSpec,
    /// The static objects as described (meshes are built on demand by [`Scene::build_objects`]).
    pub objects: Arc<[ObjectSpec]>,
    /// Skinned glTF characters (loaded by the frame stage, every frame posed anew).
    pub characters: Arc<[CharacterSpec]>,
    /// `[[vessel]]` glass panes and cylinders, validated. Not drawn yet: the displacement
    /// ([`crate::vessel`]) and the reference's tracing ([`crate::reference::vessel`]) exist, the
    /// renderer's drawing of displaced vertices does not (issue 18).
    pub vessels: Arc<[VesselSpec]>,
    lighting: Lighting,
    /// `[quality]`: the accuracy the scene asks for (none: render as the file says).
    pub quality: QualitySpec,
    /// `[antialias]`: samples a pixel, of the rasteriser and of the reference.
    pub antialias: AntialiasSpec,
    /// What a frame of the scene file needs (characters, textures and the image size are added
    /// by the frame stage), checked against the limits at validation.
    pub resources: resources::Estimate,
}

/// One `[[vessel]]`, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct VesselSpec {
    /// The file's `name`, or the kind and its index (`pane0`).
    pub name: String,
    pub vessel: crate::vessel::Vessel,
}

/// The scene's camera, validated.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSpec {
    /// `[[camera]]` keyframes in strictly increasing time order (at least one).
    Keys(Vec<CameraKey>),
    /// `[camera] gltf = ...`: a glTF file's camera, animated by the file.
    Gltf(GltfCameraSpec),
}

/// How a glTF camera's `aspectRatio` and the frame size (`--size`) go together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AspectRule {
    /// `aspect = "gltf"` (the default): the frame must have the camera's aspect ratio (to a pixel);
    /// another size is an error. A camera without `aspectRatio` takes the frame's, as glTF says.
    Gltf,
    /// `aspect = "render"`: the camera's vertical field of view at the frame's aspect ratio,
    /// whatever the file's `aspectRatio` (the horizontal field of view follows the frame).
    Render,
}

/// `[camera] gltf = ...`, validated: the file is read and its camera checked at every frame of the
/// timeline (a view, above the water, inside the world) when the scene loads.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfCameraSpec {
    /// Resolved against the scene file's folder.
    pub file: PathBuf,
    pub camera: Arc<crate::character::GltfCamera>,
    /// Added to the timeline time to give the glTF animation's time.
    pub time_offset_secs: f64,
    pub aspect: AspectRule,
    /// Where the scene names the file, for errors found later (the frame size).
    pub source: SourceRef,
}

impl CameraSpec {
    /// The camera ready to sample at any time.
    pub fn motion(&self) -> crate::timeline::CameraMotion {
        match self {
            CameraSpec::Keys(keys) => {
                crate::timeline::CameraMotion::Keys(crate::timeline::CameraTrack::new(keys.clone()))
            }
            CameraSpec::Gltf(spec) => crate::timeline::CameraMotion::Gltf {
                camera: spec.camera.clone(),
                time_offset_secs: spec.time_offset_secs,
            },
        }
    }

    /// Files the camera reads besides the scene (a glTF camera's file and buffers).
    pub fn files(&self) -> &[PathBuf] {
        match self {
            CameraSpec::Keys(_) => &[],
            CameraSpec::Gltf(spec) => spec.camera.files(),
        }
    }

    /// Checks a frame size against a glTF camera's aspect ratio ([`AspectRule`]); keyframed
    /// cameras and glTF cameras without `aspectRatio` take any size.
    pub fn check_frame_size(&self, width: u32, height: u32) -> Result<(), SceneError> {
        let CameraSpec::Gltf(spec) = self else {
            return Ok(());
        };
        let Some(aspect) = spec.camera.projection.aspect_ratio else {
            return Ok(());
        };
        if spec.aspect == AspectRule::Render {
            return Ok(());
        }
        let (w, h, a) = (width as f64, height as f64, aspect as f64);
        // Within a pixel of the camera's shape along either side: the nearest whole size.
        if (w - h * a).abs() <= 1.0 || (h - w / a).abs() <= 1.0 {
            return Ok(());
        }
        let wide = ((h * a).round() as u32).max(1);
        let high = ((w / a).round() as u32).max(1);
        Err(spec.source.error(
            format!(
                "the glTF camera of node {:?} has aspectRatio {aspect:.4} (width over height) but the frame is \
                 {width}x{height} ({:.4})",
                spec.camera.node_name,
                w / h
            ),
            format!(
                "render at --size {wide}x{height} or {width}x{high}, or set aspect = \"render\" under [camera] \
                 to keep the camera's vertical field of view at the frame's aspect ratio"
            ),
        ))
    }
}

/// `[antialias]`, validated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AntialiasSpec {
    /// The rasteriser's points a pixel along each side: 1, or 2 supersampled
    /// (`crate::gpu::Renderer::set_supersample`).
    pub supersample: u32,
    /// The reference's stratified rays a pixel along each side: `reference_grid` squared of them
    /// filter the beauty (`crate::reference::trace_frame`); 1 traces the pixel centre alone.
    pub reference_grid: u32,
}

/// `[quality]`, validated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QualitySpec {
    /// The largest screen-space position error, in pixels, that 99 % of the pixels may have against
    /// the ray-traced reference. When set, `snell render` measures the shot and picks the coarsest
    /// membrane and the cheapest method that meet it (see `crate::chart::budget`).
    pub max_error_px: Option<f64>,
}

/// Which animation of a glTF file a character plays.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationChoice {
    Name(String),
    Index(usize),
}

/// What a character does past the end of its animation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Playback {
    Loop,
    Clamp,
}

/// A root-path keyframe: where the character's origin is and which way it faces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathKey {
    pub time_secs: f64,
    pub position_m: [f64; 3],
    /// The direction the model's +z (glTF forward) faces, degrees from +z toward +x.
    pub heading_deg: f64,
}

/// One `[[character]]` of the scene, validated (the file exists; its contents are checked when
/// the frame stage loads it, and errors then still point here through the locations).
#[derive(Clone, Debug, PartialEq)]
pub struct CharacterSpec {
    pub name: String,
    /// Resolved against the scene file's folder.
    pub file: PathBuf,
    /// `None`: the file's first animation, or the rest pose when it has none.
    pub animation: Option<AnimationChoice>,
    /// Animation seconds per timeline second.
    pub speed: f64,
    /// Added to the timeline time before `speed` scales it.
    pub time_offset_secs: f64,
    pub playback: Playback,
    /// Uniform scale from the file's units to metres.
    pub scale: f64,
    /// Multiplies the file's base colour (sRGB components).
    pub tint_srgb: [f64; 3],
    /// Strictly increasing in time; at least one key.
    pub path: Vec<PathKey>,
    /// Where the scene names the file and the animation (the table when no animation is named),
    /// so errors found when the file is loaded still point into the scene file.
    pub file_source: SourceRef,
    pub animation_source: SourceRef,
}

impl SourceRef {
    /// A scene error at this place.
    pub fn error(&self, problem: impl Into<String>, fix: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            file: self.file.clone(),
            line: self.line,
            column: self.column,
            key: self.key.clone(),
            problem: problem.into(),
            fix: fix.into(),
        }
    }
}

/// `[water.ripples]`, validated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RippleSpec {
    pub enabled: bool,
    /// Grid nodes along x and z.
    pub nodes: [u32; 2],
    /// Still-water depth for the dispersion relation; `None`: the pool's `depth_m` (see
    /// [`Scene::ripple_depth_m`]).
    pub depth_m: Option<f64>,
    pub surface_tension_n_per_m: f64,
    pub density_kg_per_m3: f64,
    pub damping_per_s: f64,
    pub border: crate::sim::Border,
    pub sponge_width_m: f64,
    pub strength: f64,
    pub coupling_depth_m: f64,
}

/// One height wave of the water surface, as the scene states it; the water stage turns these into
/// its wave sum `h(x, z, t)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaveSpec {
    pub amplitude_m: f64,
    pub wavelength_m: f64,
    /// Direction of travel in the horizontal plane, degrees from +x toward +z.
    pub direction_deg: f64,
    pub phase_rad: f64,
    /// Phase speed; `None` means deep-water dispersion (omega^2 = g k).
    pub speed_m_per_s: Option<f64>,
}

impl WaveSpec {
    /// Unit direction of travel as (x, z).
    pub fn direction_xz(&self) -> [f64; 2] {
        let radians = self.direction_deg.to_radians();
        [radians.cos(), radians.sin()]
    }
}

/// The water: membrane extent and resolution, mean level, optics and waves.
#[derive(Clone, Debug, PartialEq)]
pub struct WaterSpec {
    pub level_m: f64,
    /// (x, z) corners of the membrane rectangle; a pool's inner walls stand on its edges.
    pub min_xz: [f64; 2],
    pub max_xz: [f64; 2],
    /// Membrane grid cells along x and z (each at least 1).
    pub resolution: [u32; 2],
    pub n_above: f64,
    pub n_below: f64,
    /// Beer-Lambert absorption per RGB channel, 1/m.
    pub absorption_per_m: [f64; 3],
    pub scatter_color_linear: [f64; 3],
    /// Rms slope of the waves finer than the membrane: the sun glint's Beckmann roughness.
    pub roughness: f64,
    pub waves: Vec<WaveSpec>,
    pub ripples: RippleSpec,
}

impl WaterSpec {
    pub fn grid(&self) -> MembraneGrid {
        MembraneGrid {
            min_x: self.min_xz[0],
            min_z: self.min_xz[1],
            max_x: self.max_xz[0],
            max_z: self.max_xz[1],
            cells_x: self.resolution[0],
            cells_z: self.resolution[1],
        }
    }

    /// The highest the surface can rise above its mean level (all crests coinciding).
    pub fn max_crest_m(&self) -> f64 {
        self.waves.iter().map(|w| w.amplitude_m).sum()
    }
}

/// A built-in shape and its dimensions (metres).
// Pool carries two texture specs inline; a scene holds a handful of these, so boxing them would only
// add noise to every construction and pattern.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeSpec {
    /// Centred at the object's origin.
    Box {
        size_m: [f64; 3],
    },
    Sphere {
        radius_m: f64,
    },
    /// Horizontal, normal +y, centred; size along x and z.
    Quad {
        size_m: [f64; 2],
    },
    /// Floor, walls and deck around the water's extent; not transformed.
    Pool {
        depth_m: f64,
        coping_height_m: f64,
        deck_width_m: f64,
        floor_texture: TextureSpec,
        deck_texture: TextureSpec,
    },
}

/// One `[[object]]` of the scene, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    pub name: String,
    pub shape: ShapeSpec,
    pub translate_m: [f64; 3],
    /// Yaw (about +y), pitch (about +x), roll (about +z), degrees.
    pub rotate_deg: [f64; 3],
    pub scale: [f64; 3],
    /// Grid spacing of the tessellation.
    pub max_edge_m: f64,
    /// For a pool: its walls' texture.
    pub texture: TextureSpec,
    pub tint_srgb: [f64; 3],
}

/// Counts for `snell info`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneSummary {
    /// Objects as built (a pool counts as its floor, walls and deck).
    pub objects: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub membrane_cells: u64,
    pub camera_keys: usize,
    pub waves: usize,
}

/// One mesh to be built, before its texture is baked.
struct MeshPart<'a> {
    name: String,
    mesh: Mesh,
    texture: &'a TextureSpec,
    tint_srgb: [f64; 3],
}

/// The depth the ripples take for water with no pool and no `[water.ripples] depth_m`: deep enough
/// that `tanh(k h) = 1` to 1e-6 for every wave longer than a metre.
pub const OPEN_WATER_DEPTH_M: f64 = 10.0;

impl Scene {
    /// The still-water depth of the ripples' dispersion relation: `[water.ripples] depth_m`, else
    /// the (first) pool's `depth_m`, else [`OPEN_WATER_DEPTH_M`].
    pub fn ripple_depth_m(&self) -> f64 {
        self.water.ripples.depth_m.unwrap_or_else(|| {
            self.objects
                .iter()
                .find_map(|o| match &o.shape {
                    ShapeSpec::Pool { depth_m, .. } => Some(*depth_m),
                    _ => None,
                })
                .unwrap_or(OPEN_WATER_DEPTH_M)
        })
    }

    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let bytes = crate::files::read_regular(path, crate::files::MAX_SCENE_BYTES)
            .map_err(SceneError::File)?;
        let text = utf8_text(&bytes, path)?;
        Scene::parse(text, path)
    }

    /// Validates scene text; `path` names the file in errors and anchors relative image paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
        let root = DeTable::parse(text).map_err(|e| syntax_error(text, path, &e))?;
        let map = SourceMap {
            file: path,
            text,
            root: &root,
        };
        check_numbers(&map, root.get_ref(), &KeyPath::root())?;
        let raw: format::RawScene = toml::from_str(text).map_err(|e| structure_error(&map, &e))?;
        validate::validate(raw, &map)
    }

    /// The keyframes of a keyframed camera (none for a glTF camera).
    pub fn camera_keys(&self) -> &[CameraKey] {
        match &self.camera {
            CameraSpec::Keys(keys) => keys,
            CameraSpec::Gltf(_) => &[],
        }
    }

    pub fn lighting(&self) -> Lighting {
        self.lighting
    }

    pub fn water_optics(&self) -> WaterOptics {
        let w = &self.water;
        WaterOptics {
            n_above: w.n_above as f32,
            n_below: w.n_below as f32,
            absorption_per_m: to_vec3(w.absorption_per_m),
            scatter_color_linear: to_vec3(w.scatter_color_linear),
            mean_level_m: w.level_m as f32,
            roughness: w.roughness as f32,
        }
    }

    /// World-space meshes of every object and the textures their materials index. Procedural
    /// textures are baked, image files decoded; identical textures are shared. Uvs are in texture
    /// repeat units (metres divided by the texture's repeat size): sample with repeat addressing.
    pub fn build_objects(&self) -> Result<(Vec<Object>, Vec<Texture>), SceneError> {
        let mut baked: Vec<(&TextureSpec, textures::BakedTexture)> = Vec::new();
        let mut objects = Vec::new();
        for part in self.mesh_parts() {
            let index = match baked.iter().position(|(spec, _)| *spec == part.texture) {
                Some(index) => index,
                None => {
                    let texture = part
                        .texture
                        .bake(&format!("{}.texture", part.name))
                        .map_err(|e| image_error(part.texture, &e.cause))?;
                    baked.push((part.texture, texture));
                    baked.len() - 1
                }
            };
            let repeat_m = baked[index].1.repeat_m;
            let mut mesh = part.mesh;
            for uv in &mut mesh.uvs {
                uv.x /= repeat_m[0] as f32;
                uv.y /= repeat_m[1] as f32;
            }
            objects.push(Object {
                name: part.name,
                mesh,
                material: Material {
                    texture: index as u32,
                    tint_linear: to_vec3(textures::srgb_to_linear3(part.tint_srgb)),
                },
            });
        }
        Ok((objects, baked.into_iter().map(|(_, b)| b.texture).collect()))
    }

    /// Every image file the scene's textures read (for checkpoint keys).
    pub fn image_files(&self) -> Vec<PathBuf> {
        let mut files = Vec::new();
        for object in self.objects.iter() {
            let mut specs = vec![&object.texture];
            if let ShapeSpec::Pool {
                floor_texture,
                deck_texture,
                ..
            } = &object.shape
            {
                specs.push(floor_texture);
                specs.push(deck_texture);
            }
            for spec in specs {
                if let TextureSpec::Image(image) = spec {
                    files.push(image.path.clone());
                }
            }
        }
        files
    }

    /// Counts of what the scene builds (meshes are built, textures are not).
    pub fn summary(&self) -> SceneSummary {
        let parts = self.mesh_parts();
        SceneSummary {
            objects: parts.len(),
            vertices: parts.iter().map(|p| p.mesh.vertex_count()).sum(),
            triangles: parts.iter().map(|p| p.mesh.triangle_count()).sum(),
            membrane_cells: self.water.resolution[0] as u64 * self.water.resolution[1] as u64,
            camera_keys: match &self.camera {
                CameraSpec::Keys(keys) => keys.len(),
                CameraSpec::Gltf(_) => 0,
            },
            waves: self.water.waves.len(),
        }
    }

    fn mesh_parts(&self) -> Vec<MeshPart<'_>> {
        let mut parts = Vec::new();
        for object in self.objects.iter() {
            let scale = DVec3::from(object.scale);
            let translate = DVec3::from(object.translate_m);
            let rotation = primitives::rotation_from_yaw_pitch_roll_deg(object.rotate_deg);
            let e = object.max_edge_m;
            let single = |mesh: Mesh| MeshPart {
                name: object.name.clone(),
                mesh,
                texture: &object.texture,
                tint_srgb: object.tint_srgb,
            };
            match &object.shape {
                // Box and quad: the scale is folded into the size, so the grid spacing and the
                // metre uvs hold after scaling.
                ShapeSpec::Box { size_m } => {
                    let mesh = primitives::box_mesh(DVec3::from(*size_m) * scale, e);
                    parts.push(single(primitives::transformed(
                        mesh,
                        translate,
                        rotation,
                        DVec3::ONE,
                    )));
                }
                ShapeSpec::Quad { size_m } => {
                    let mesh = primitives::quad_mesh([size_m[0] * scale.x, size_m[1] * scale.z], e);
                    parts.push(single(primitives::transformed(
                        mesh,
                        translate,
                        rotation,
                        DVec3::ONE,
                    )));
                }
                // Sphere: tessellated finely enough that the largest scale still keeps edges short.
                ShapeSpec::Sphere { radius_m } => {
                    let mesh = primitives::sphere_mesh(*radius_m, e / scale.max_element());
                    parts.push(single(primitives::transformed(
                        mesh, translate, rotation, scale,
                    )));
                }
                ShapeSpec::Pool {
                    depth_m,
                    coping_height_m,
                    deck_width_m,
                    floor_texture,
                    deck_texture,
                } => {
                    let dims = PoolDims {
                        min_xz: self.water.min_xz,
                        max_xz: self.water.max_xz,
                        water_level_m: self.water.level_m,
                        depth_m: *depth_m,
                        coping_height_m: *coping_height_m,
                        deck_width_m: *deck_width_m,
                    };
                    let pool = pool_meshes(&dims, e);
                    let part = |suffix: &str, mesh: Mesh, texture| MeshPart {
                        name: format!("{}.{suffix}", object.name),
                        mesh,
                        texture,
                        tint_srgb: object.tint_srgb,
                    };
                    parts.push(part("floor", pool.floor, floor_texture));
                    parts.push(part("walls", pool.walls, &object.texture));
                    parts.push(part("deck", pool.deck, deck_texture));
                }
            }
        }
        parts
    }
}

fn to_vec3(c: [f64; 3]) -> Vec3 {
    Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)
}

fn image_error(spec: &TextureSpec, cause: &str) -> SceneError {
    match spec {
        TextureSpec::Image(image) => SceneError::Invalid {
            file: image.source.file.clone(),
            line: image.source.line,
            column: image.source.column,
            key: image.source.key.clone(),
            problem: format!(
                "cannot load texture image {}: {cause}",
                image.path.display()
            ),
            fix: "use a readable PNG or JPEG file (the path is relative to the scene file)".into(),
        },
        // Procedural textures cannot fail to bake.
        _ => SceneError::Invalid {
            file: PathBuf::new(),
            line: 0,
            column: 0,
            key: String::new(),
            problem: format!("texture failed: {cause}"),
            fix: String::new(),
        },
    }
}

/// The file as UTF-8 text, or an error at the line and column of the first byte that is not.
fn utf8_text<'a>(bytes: &'a [u8], path: &Path) -> Result<&'a str, SceneError> {
    std::str::from_utf8(bytes).map_err(|error| {
        let valid = error.valid_up_to();
        let prefix = std::str::from_utf8(&bytes[..valid]).unwrap_or_default();
        let (line, column) = line_column_of(prefix, valid);
        SceneError::Invalid {
            file: path.to_path_buf(),
            line,
            column,
            key: String::new(),
            problem: format!(
                "the file is not UTF-8 text (byte 0x{:02x} cannot start or continue a character here)",
                bytes[valid]
            ),
            fix: "save it as UTF-8, as TOML requires (e.g. iconv -f latin1 -t utf-8)".into(),
        }
    })
}

fn syntax_error(text: &str, path: &Path, error: &toml::de::Error) -> SceneError {
    let offset = error.span().map_or(0, |s| s.start);
    let (line, column) = line_column_of(text, offset);
    SceneError::Invalid {
        file: path.to_path_buf(),
        line,
        column,
        key: String::new(),
        problem: format!("malformed TOML: {}", error.message().trim_end()),
        fix: "fix the syntax at this position (see https://toml.io)".into(),
    }
}

/// An error from deserializing well-formed TOML into the scene structure: an unknown key, a
/// missing one or a value of the wrong type.
fn structure_error(map: &SourceMap<'_>, error: &toml::de::Error) -> SceneError {
    let offset = error.span().map_or(0, |s| s.start);
    let key = map.path_at(offset).to_string();
    let message = error.message().trim_end().to_string();
    let fix = if message.starts_with("unknown field") {
        "remove it or correct its spelling"
    } else if message.starts_with("missing field") {
        "add it"
    } else if message.starts_with("invalid type") || message.starts_with("invalid length") {
        "write a value of the expected type"
    } else {
        ""
    };
    map.error_at(offset, key, message, fix)
}

/// Every number of the file against its key's stated range ([`limits::KEY_RANGES`]), at the
/// number's own position, before the values lose their positions. TOML allows `nan` and `inf`;
/// no scene quantity may be either. Numbers at keys without a range (a number where the format
/// wants text, an unknown key) are left to the typed pass, which names the real problem.
fn check_numbers(
    map: &SourceMap<'_>,
    table: &DeTable<'_>,
    path: &KeyPath,
) -> Result<(), SceneError> {
    for (key, value) in table.iter() {
        check_value(map, value, &path.key(key.get_ref()))?;
    }
    Ok(())
}

fn check_value(
    map: &SourceMap<'_>,
    value: &toml::Spanned<DeValue<'_>>,
    path: &KeyPath,
) -> Result<(), SceneError> {
    let (number, written) = match value.get_ref() {
        DeValue::Float(float) => {
            let written = float.as_str();
            if written.contains("nan") || written.contains("inf") {
                return Err(map.error_at(
                    value.span().start,
                    path.to_string(),
                    format!("must be a finite number (got {written})"),
                    "write a finite value",
                ));
            }
            (
                written.parse::<f64>().unwrap_or(f64::INFINITY),
                written.to_string(),
            )
        }
        DeValue::Integer(integer) => (
            i128::from_str_radix(integer.as_str(), integer.radix())
                .map_or(f64::INFINITY, |v| v as f64),
            integer.to_string(),
        ),
        DeValue::Array(array) => {
            for (i, element) in array.iter().enumerate() {
                check_value(map, element, &path.index(i))?;
            }
            return Ok(());
        }
        DeValue::Table(table) => return check_numbers(map, table, path),
        _ => return Ok(()),
    };
    let Some(range) = limits::range_of(path) else {
        return Ok(());
    };
    // A fraction where a whole number belongs is a type error the typed pass words better.
    if range.integer && matches!(value.get_ref(), DeValue::Float(_)) {
        return Ok(());
    }
    if !range.contains(number) {
        let (problem, fix) = range.problem(&written);
        return Err(map.error_at(value.span().start, path.to_string(), problem, fix));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::primitives::tests::assert_well_formed;
    use super::*;

    fn pool_scene() -> Scene {
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pool.toml"))
            .expect("pool.toml is valid")
    }

    #[test]
    fn an_empty_file_is_a_pool_seen_from_its_side() {
        let scene = Scene::parse("", Path::new("scenes/empty.toml")).unwrap();
        assert_eq!(scene.name, "empty");
        assert_eq!(
            scene.timeline,
            Timeline {
                fps: 24.0,
                first_frame: 1,
                last_frame: 48
            }
        );
        assert_eq!(scene.camera_keys().len(), 1);
        let key = scene.camera_keys()[0];
        assert!(
            key.eye.y > 1.0 && key.target.y < 0.0,
            "camera {key:?} does not look down at the water"
        );
        assert_eq!(
            scene.water.grid(),
            MembraneGrid {
                min_x: -5.0,
                min_z: -2.5,
                max_x: 5.0,
                max_z: 2.5,
                cells_x: 128,
                cells_z: 64
            }
        );
        assert!(scene.water.waves.is_empty());
        let optics = scene.water_optics();
        assert_eq!((optics.n_above, optics.n_below), (1.0, 1.333));
        let (objects, textures) = scene.build_objects().unwrap();
        let names: Vec<_> = objects.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["pool.floor", "pool.walls", "pool.deck"]);
        // Floor (tiles with lanes), walls (tiles), deck (stone): three distinct textures.
        assert_eq!(textures.len(), 3);
        let lighting = scene.lighting();
        assert!(
            (lighting.sun_direction.length() - 1.0).abs() < 1e-6 && lighting.sun_direction.y > 0.0
        );
    }

    #[test]
    fn pool_scene_builds_a_real_looking_pool() {
        let scene = pool_scene();
        assert_eq!(scene.name, "pool");
        assert_eq!(
            (
                scene.timeline.first_frame,
                scene.timeline.last_frame,
                scene.timeline.fps
            ),
            (1, 48, 24.0)
        );
        assert_eq!(scene.camera_keys().len(), 3);
        assert!(scene
            .camera_keys()
            .windows(2)
            .all(|k| k[0].time_secs < k[1].time_secs));
        assert!((scene.camera_keys()[2].time_secs - 47.0 / 24.0).abs() < 1e-12);
        assert_eq!(scene.water.waves.len(), 4);
        for wave in &scene.water.waves {
            assert!(wave.amplitude_m > 0.0 && wave.amplitude_m < 0.05);
            assert!((0.8..=4.0).contains(&wave.wavelength_m));
        }
        let (objects, textures) = scene.build_objects().unwrap();
        for object in &objects {
            assert_well_formed(&object.mesh);
            assert!((object.material.texture as usize) < textures.len());
        }
        for texture in &textures {
            assert_eq!(
                texture.rgba8_srgb.len(),
                (texture.width * texture.height * 4) as usize
            );
        }
        let by_name = |name: &str| {
            objects
                .iter()
                .find(|o| o.name == name)
                .unwrap_or_else(|| panic!("no {name}"))
        };
        // Under water: the ball rests on the floor.
        let ball = by_name("ball");
        let lowest = ball
            .mesh
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min);
        assert!((lowest - -1.6).abs() < 1e-3, "ball bottom at {lowest}");
        // The float crosses the water surface.
        let float = by_name("float");
        assert!(
            float.mesh.positions.iter().any(|p| p.y > 0.1)
                && float.mesh.positions.iter().any(|p| p.y < -0.1)
        );
        // Walls stand on the membrane's edges.
        let walls = by_name("pool.walls");
        let grid = scene.water.grid();
        assert!(walls.mesh.positions.iter().all(|p| {
            let (x, z) = (p.x as f64, p.z as f64);
            x == grid.min_x || x == grid.max_x || z == grid.min_z || z == grid.max_z
        }));
        // The summary counts what build_objects builds.
        let summary = scene.summary();
        assert_eq!(summary.objects, objects.len());
        assert_eq!(
            summary.vertices,
            objects.iter().map(|o| o.mesh.vertex_count()).sum::<usize>()
        );
        assert_eq!(
            summary.triangles,
            objects
                .iter()
                .map(|o| o.mesh.triangle_count())
                .sum::<usize>()
        );
        assert_eq!(summary.membrane_cells, 160 * 80);
    }

    #[test]
    fn tiny_scene_loads() {
        let scene =
            Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tiny.toml")).unwrap();
        assert_eq!(scene.timeline.last_frame, 3);
        assert!(scene.summary().vertices > 0);
    }

    #[test]
    fn uvs_are_in_texture_repeats_and_tints_linear() {
        let text = "[[object]]\nshape = \"quad\"\nsize_m = [2.0, 1.0]\ntint = [0.5, 1.0, 0.0]\n\
                    texture = { kind = \"checker\", square_m = 0.25 }\n";
        let scene = Scene::parse(text, Path::new("q.toml")).unwrap();
        let (objects, textures) = scene.build_objects().unwrap();
        assert_eq!(textures.len(), 1);
        // A checker of 0.25 m squares repeats every 0.5 m: a 2 m quad spans 4 repeats.
        let uv_max = objects[0]
            .mesh
            .uvs
            .iter()
            .fold(glam::Vec2::ZERO, |m, uv| m.max(*uv));
        assert!(
            (uv_max - glam::Vec2::new(4.0, 2.0)).length() < 1e-5,
            "{uv_max}"
        );
        let tint = objects[0].material.tint_linear;
        assert!(
            (tint - Vec3::new(0.214_041, 1.0, 0.0)).length() < 1e-5,
            "{tint}"
        );
    }

    #[test]
    fn wave_direction_as_vector_and_deep_water_speed() {
        let text =
            "[[water.wave]]\namplitude_m = 0.01\nwavelength_m = 1.0\ndirection = [0.0, 2.0]\n";
        let scene = Scene::parse(text, Path::new("w.toml")).unwrap();
        let wave = scene.water.waves[0];
        assert!((wave.direction_deg - 90.0).abs() < 1e-12);
        let [x, z] = wave.direction_xz();
        assert!(x.abs() < 1e-12 && (z - 1.0).abs() < 1e-12);
        assert_eq!(wave.speed_m_per_s, None);
    }

    #[test]
    fn texture_keys_not_stated_keep_the_slot_defaults() {
        // No kind: the pool floor's default kind (tiles, with lanes) is kept, only the tile size changes.
        let text = "[[object]]\nshape = \"pool\"\n[object.floor_texture]\ntile_size_m = 0.25\n";
        let scene = Scene::parse(text, Path::new("p.toml")).unwrap();
        let ShapeSpec::Pool {
            floor_texture: TextureSpec::Tiles(tiles),
            ..
        } = &scene.objects[0].shape
        else {
            panic!("floor texture is not tiles");
        };
        assert_eq!(tiles.tile_size_m, 0.25);
        assert!(tiles.lanes.is_some());
        // ...and lane_spacing_m = 0 removes the lanes.
        let text = "[[object]]\nshape = \"pool\"\n[object.floor_texture]\nlane_spacing_m = 0\n";
        let scene = Scene::parse(text, Path::new("p.toml")).unwrap();
        let ShapeSpec::Pool {
            floor_texture: TextureSpec::Tiles(tiles),
            ..
        } = &scene.objects[0].shape
        else {
            panic!("floor texture is not tiles");
        };
        assert!(tiles.lanes.is_none());
    }

    #[test]
    fn colours_out_of_range_and_moved_pools_are_refused() {
        let e = Scene::parse(
            "[sky]\nzenith_color = [0.2, 1.5, 0.9]\n",
            Path::new("c.toml"),
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with(
                "c.toml:2:22: sky.zenith_color[1]: must be an sRGB colour component from 0 to 1"
            ),
            "{e}"
        );
        let e = Scene::parse(
            "[[object]]\nshape = \"pool\"\ntranslate = [1, 0, 0]\n",
            Path::new("c.toml"),
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("c.toml:3:1: object[0].translate:"),
            "{e}"
        );
        let text =
            "[[water.wave]]\namplitude_m = 0.3\nwavelength_m = 2\n[[object]]\nshape = \"pool\"\n";
        let e = Scene::parse(text, Path::new("c.toml")).unwrap_err();
        assert!(
            e.to_string()
                .contains("object[0].coping_height_m: the deck must stand above"),
            "{e}"
        );
    }

    #[test]
    fn a_quality_budget_is_read_and_bad_ones_are_refused_at_their_line() {
        let scene = Scene::parse("[quality]\nmax_error_px = 0.25\n", Path::new("q.toml")).unwrap();
        assert_eq!(scene.quality.max_error_px, Some(0.25));
        assert_eq!(
            Scene::parse("", Path::new("q.toml")).unwrap().quality,
            QualitySpec::default()
        );
        for (value, problem) in [
            ("0", "must be more than 0"),
            ("-1", "must be more than 0"),
            ("1e6", "at most 1000"),
            ("nan", "must be a finite number"),
            ("-inf", "must be a finite number"),
        ] {
            let text = format!("name = \"q\"\n[quality]\nmax_error_px = {value}\n");
            let e = Scene::parse(&text, Path::new("q.toml"))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("q.toml:3:"), "{value}: {e}");
            assert!(
                e.contains("quality.max_error_px") && e.contains(problem),
                "{value}: {e}"
            );
        }
        let e = Scene::parse("[quality]\nmax_error = 1\n", Path::new("q.toml")).unwrap_err();
        assert!(e.to_string().starts_with("q.toml:2:"), "{e}");
    }

    #[test]
    fn scene_is_cheap_to_clone() {
        let scene = pool_scene();
        let copy = scene.clone();
        assert!(Arc::ptr_eq(&scene.objects, &copy.objects));
        assert_eq!(scene, copy);
    }
}
