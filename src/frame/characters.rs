//! The scene's characters and ripples as the frame stage uses them: glTF assets loaded once, posed
//! at any time (timeline time -> clip time by speed, offset and loop/clamp; root path ->
//! `world_from_character`), their primitives turned into world-space [`Object`]s, and the ripple
//! [`Simulation`] driven by their occupancy of the water, keyed for checkpoints.

use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Vec3};

use super::inputs::SceneFilesDigest;
use super::SnellError;
use crate::character::{AnimationSelector, CharacterAsset};
use crate::mesh::{Material, Object, Texture};
use crate::scene::{AnimationChoice, CharacterSpec, Playback, Scene};
use crate::sim::{coupling, CheckpointKey, KeyHasher, RippleSettings, RippleState, Simulation};
use crate::timeline::{RootKey, RootPath};
use crate::water::{HeightField, WaveField};

/// Bumped whenever the simulation's results change for the same inputs (scheme, coupling,
/// defaults): checkpoints made by another version are then never used.
const SIMULATION_VERSION: &str = "ripples-2-spectral";

/// One `[[character]]`, loaded.
pub struct Character {
    pub spec: CharacterSpec,
    pub asset: CharacterAsset,
    animation: Option<usize>,
    root: RootPath,
    /// Index of the asset's first texture in the job's texture list.
    texture_base: u32,
    /// The job's plain white texture, for primitives without a texture.
    white_texture: u32,
}

impl Character {
    /// What `snell info` says about the character: its file, the model's size in metres (the bind
    /// pose's bounding box at the scene's scale), its vertices, and every animation in the file
    /// with its duration, the one played marked.
    pub fn describe(&self) -> String {
        use std::fmt::Write;
        let pose = self.asset.bind_pose();
        let scale = Mat4::from_scale(Vec3::splat(self.spec.scale as f32));
        let (low, high) = self
            .asset
            .posed_primitives(&pose, scale)
            .iter()
            .flat_map(|primitive| primitive.mesh.positions.iter().copied())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            });
        let size = if low.x.is_finite() {
            high - low
        } else {
            Vec3::ZERO
        };
        let mut text = String::new();
        let _ = writeln!(
            text,
            "           - {}: {} ({} vertices; {:.2} x {:.2} x {:.2} m at scale {}, bind pose)",
            self.spec.name,
            self.spec.file.display(),
            self.asset.vertex_count(),
            size.x,
            size.y,
            size.z,
            self.spec.scale
        );
        let animations = self.asset.animations();
        if animations.is_empty() {
            text.push_str("             no animations: the rest pose is drawn\n");
        }
        for (index, info) in animations.iter().enumerate() {
            let played = if self.animation == Some(index) {
                format!(
                    "  <- played, {} at speed {}",
                    match self.spec.playback {
                        Playback::Loop => "looping",
                        Playback::Clamp => "clamped",
                    },
                    self.spec.speed
                )
            } else {
                String::new()
            };
            let _ = writeln!(
                text,
                "             animation {index} {:?}: {:.2} s{played}",
                info.name.as_deref().unwrap_or("(unnamed)"),
                info.end_secs - info.start_secs
            );
        }
        text
    }

    /// Seconds into the animation clip at timeline time `time_secs`.
    pub fn clip_secs(&self, time_secs: f64) -> f32 {
        let Some(index) = self.animation else {
            return 0.0;
        };
        let info = &self.asset.animations()[index];
        let (start, end) = (info.start_secs as f64, info.end_secs as f64);
        let local = (time_secs + self.spec.time_offset_secs) * self.spec.speed;
        let duration = end - start;
        let clip = match self.spec.playback {
            _ if duration <= 0.0 => start,
            Playback::Loop => start + local.rem_euclid(duration),
            Playback::Clamp => (start + local).clamp(start, end),
        };
        clip as f32
    }

    pub fn world_from_character(&self, time_secs: f64) -> Mat4 {
        self.root
            .world_from_character(time_secs, self.spec.scale)
            .as_mat4()
    }

    /// The primitives posed at timeline time `time_secs` as world-space objects, with materials
    /// indexing the job's texture list.
    pub fn objects(&self, time_secs: f64) -> Vec<Object> {
        let pose = self.asset.pose(self.animation, self.clip_secs(time_secs));
        let tint = Vec3::from(
            crate::scene::textures::srgb_to_linear3(self.spec.tint_srgb).map(|c| c as f32),
        );
        self.asset
            .posed_primitives(&pose, self.world_from_character(time_secs))
            .into_iter()
            .map(|primitive| {
                let [r, g, b, _] = primitive.base_color_factor;
                Object {
                    name: format!("{}/{}", self.spec.name, primitive.name),
                    material: Material {
                        texture: primitive
                            .texture
                            .map_or(self.white_texture, |t| self.texture_base + t as u32),
                        tint_linear: tint * Vec3::new(r, g, b),
                    },
                    mesh: primitive.mesh,
                }
            })
            .collect()
    }
}

/// Loads every character of `scene`, appending their textures (and a white one when a primitive
/// has none) to `textures`. Errors point at the scene file's `file` or `animation` key.
pub fn load_characters(
    scene: &Scene,
    textures: &mut Vec<Texture>,
) -> Result<Vec<Character>, SnellError> {
    let mut characters = Vec::new();
    let mut white_texture = None;
    for spec in scene.characters.iter() {
        let asset = CharacterAsset::load(&spec.file).map_err(|error| {
            spec.file_source.error(
                error.to_string(),
                "check the file (a .glb, or a .gltf with its buffers beside it)",
            )
        })?;
        let selector = match &spec.animation {
            Some(AnimationChoice::Name(name)) => Some(AnimationSelector::Name(name.clone())),
            Some(AnimationChoice::Index(i)) => Some(AnimationSelector::Index(*i)),
            None => None,
        };
        let animation = match selector {
            Some(selector) => Some(asset.resolve_animation(&selector).map_err(|error| {
                spec.animation_source
                    .error(error.to_string(), "name one of the file's animations")
            })?),
            None if asset.animations().is_empty() => None,
            None => Some(0),
        };
        for warning in asset.warnings() {
            log::warn!("{}: {warning}", spec.file.display());
        }
        let texture_base = textures.len() as u32;
        textures.extend(asset.textures().iter().cloned());
        let white = *white_texture.get_or_insert_with(|| {
            textures.push(Texture {
                name: "white".to_string(),
                width: 1,
                height: 1,
                rgba8_srgb: vec![255; 4],
            });
            textures.len() as u32 - 1
        });
        let root = RootPath::new(
            spec.path
                .iter()
                .map(|k| RootKey {
                    time_secs: k.time_secs,
                    position_m: k.position_m.into(),
                    heading_deg: k.heading_deg,
                })
                .collect(),
        );
        characters.push(Character {
            spec: spec.clone(),
            asset,
            animation,
            root,
            texture_base,
            white_texture: white,
        });
    }
    Ok(characters)
}

/// The ripple grid of the scene's `[water.ripples]`, over the water's extent, band-limited to what
/// the membrane resolves.
pub fn ripple_settings(scene: &Scene) -> RippleSettings {
    let water = &scene.water;
    let ripples = &water.ripples;
    let spacing_m = (water.max_xz[0] - water.min_xz[0]) / (ripples.nodes[0] - 1) as f64;
    let grid = water.grid();
    let membrane_cell_m = ((grid.max_x - grid.min_x) / grid.cells_x as f64)
        .max((grid.max_z - grid.min_z) / grid.cells_z as f64);
    // The membrane's Nyquist wavenumber, or half the ripple grid's if that is lower (so the smooth
    // field between nodes stays well resolved).
    let pi = std::f64::consts::PI;
    let cutoff_per_m = (pi / membrane_cell_m).min(0.5 * pi / spacing_m);
    let mut settings = RippleSettings {
        nodes_x: ripples.nodes[0],
        nodes_z: ripples.nodes[1],
        min_x: water.min_xz[0],
        min_z: water.min_xz[1],
        spacing_m,
        depth_m: scene.ripple_depth_m(),
        surface_tension_n_per_m: ripples.surface_tension_n_per_m,
        density_kg_per_m3: ripples.density_kg_per_m3,
        damping_per_s: ripples.damping_per_s,
        cutoff_per_m,
        border: ripples.border,
        sponge_nodes: (ripples.sponge_width_m / spacing_m).round() as u32,
        sponge_damping_per_s: 0.0,
    };
    // A ripple crossing the sponge (width w, at group speed c) spends w / c in it. With an edge
    // damping of 8 c / w on a quadratic ramp (mean: a third of it), its amplitude falls by
    // e^(-gamma t / 2) = e^(-4/3) ~ 0.26 on the way in and again on the way out: about 7 % of the
    // fastest waves come back (less of the slower ones), and the ramp has no sharp edge to reflect from.
    let fastest = settings.dispersion().fastest_group_speed(cutoff_per_m);
    settings.sponge_damping_per_s = 8.0 * fastest / ripples.sponge_width_m.max(spacing_m);
    settings
}

/// The simulation's key: the digest of the scene file and every file it references (see
/// [`super::inputs::digest_scene_files`]), the simulation settings and code version.
pub fn simulation_key(
    scene: &Scene,
    scene_files: &SceneFilesDigest,
    settings: &RippleSettings,
) -> CheckpointKey {
    let mut hasher = KeyHasher::new(SIMULATION_VERSION);
    hasher.input("scene-files", &scene_files.0);
    hasher.input(
        "settings",
        serde_json::to_string(settings)
            .expect("settings serialise")
            .as_bytes(),
    );
    hasher.input(
        "timeline",
        format!("{} {}", scene.timeline.fps, scene.timeline.first_frame).as_bytes(),
    );
    hasher.finish()
}

/// Characters and ripples of a job.
pub struct Dynamics {
    pub characters: Vec<Character>,
    /// None when the scene's ripples are off.
    pub simulation: Option<Simulation>,
    pub coupling_depth_m: f64,
}

impl Dynamics {
    /// `scene_files` is the digest of the scene's files, which keys the simulation's checkpoints.
    pub fn new(
        scene: &Scene,
        characters: Vec<Character>,
        scene_files: &SceneFilesDigest,
    ) -> Result<Self, SnellError> {
        let ripples = &scene.water.ripples;
        let simulation = if ripples.enabled {
            let settings = ripple_settings(scene);
            let key = simulation_key(scene, scene_files, &settings);
            Some(Simulation::new(
                settings,
                ripples.strength,
                scene.timeline.first_frame,
                scene.timeline.fps,
                key,
            ))
        } else {
            None
        };
        Ok(Dynamics {
            characters,
            simulation,
            coupling_depth_m: ripples.coupling_depth_m,
        })
    }

    /// Reads and writes checkpoints under `out_dir` from now on; a note when stale checkpoints
    /// of this scene were deleted.
    pub fn use_checkpoints(
        &self,
        out_dir: &Path,
        scene_name: &str,
    ) -> Result<Option<String>, SnellError> {
        let Some(simulation) = &self.simulation else {
            return Ok(None);
        };
        let removed = simulation.open_store(out_dir, scene_name)?;
        Ok((!removed.is_empty()).then(|| {
            format!(
                "removed the simulation checkpoints of older versions of this scene (unused, beyond the {} most recent): {}",
                crate::sim::checkpoint::KEPT_VERSIONS,
                removed
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }))
    }

    /// Every character posed at `time_secs`, as world-space objects.
    pub fn posed_objects(&self, time_secs: f64) -> Vec<Object> {
        self.characters
            .iter()
            .flat_map(|c| c.objects(time_secs))
            .collect()
    }

    /// The ripple state at `frame` (None when ripples are off). `posed_now` are the characters
    /// posed at `frame` (the caller needs them anyway); other frames the simulation steps through
    /// are posed here.
    pub fn ripples_at(
        &self,
        scene: &Scene,
        waves: &WaveField,
        frame: u32,
        posed_now: &[Object],
    ) -> Result<Option<Arc<RippleState>>, SnellError> {
        let Some(simulation) = &self.simulation else {
            return Ok(None);
        };
        let occupancy = |f: u32| {
            let time_secs = scene.timeline.time_secs(f);
            let surface = waves.at(time_secs);
            let settings = simulation.settings();
            if f == frame {
                self.occupancy(settings, &surface, posed_now)
            } else {
                self.occupancy(settings, &surface, &self.posed_objects(time_secs))
            }
        };
        Ok(Some(simulation.state_at(frame, &occupancy)?))
    }

    /// The occupancy of the ripple grid by `posed` (characters' objects) against `surface`.
    fn occupancy(
        &self,
        settings: &RippleSettings,
        surface: &dyn HeightField,
        posed: &[Object],
    ) -> Vec<f32> {
        let meshes: Vec<(&[Vec3], &[[u32; 3]])> = posed
            .iter()
            .map(|o| (o.mesh.positions.as_slice(), o.mesh.triangles.as_slice()))
            .collect();
        coupling::occupancy(settings, &meshes, surface, self.coupling_depth_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The key a scene's checkpoints are stored under.
    fn key_of(scene_file: &Path) -> CheckpointKey {
        let scene = Scene::load(scene_file).unwrap();
        let mut textures = Vec::new();
        let characters = load_characters(&scene, &mut textures).unwrap();
        let files = super::super::inputs::digest_scene_files(&scene, &characters).unwrap();
        simulation_key(&scene, &files, &ripple_settings(&scene))
    }

    /// Stale checkpoints are never used: editing the scene file or any byte of an asset it
    /// references gives another key (and so another checkpoint folder).
    #[test]
    fn the_key_changes_with_the_scene_and_with_every_asset() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("post.glb");
        let original = std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/assets/RiggedSimple.glb"),
        )
        .unwrap();
        std::fs::write(&model, &original).unwrap();
        let scene_file = dir.path().join("scene.toml");
        let text = "[[character]]\nfile = \"post.glb\"\nscale = 0.15\n";
        std::fs::write(&scene_file, text).unwrap();
        let first = key_of(&scene_file);
        assert_eq!(key_of(&scene_file), first, "same inputs, same key");

        std::fs::write(&scene_file, text.replace("0.15", "0.16")).unwrap();
        let edited_scene = key_of(&scene_file);
        assert_ne!(edited_scene, first);

        // A mesh renamed inside the file: still the same loadable model, another key.
        let name = b"Cylinder";
        let at = original
            .windows(name.len())
            .position(|w| w == name)
            .unwrap();
        let mut changed = original.clone();
        changed[at + name.len() - 1] = b's';
        std::fs::write(&model, &changed).unwrap();
        assert_ne!(key_of(&scene_file), edited_scene);
    }

    /// One scene object id per character, whatever the number of its glTF primitives (issue 14
    /// point 1: each primitive had an id of its own, 62 in a BrainStem frame), and so one name in
    /// the header and the Cryptomatte manifest. `tests/gltf/external.gltf` draws three primitives
    /// (a fourth, of points, is skipped) after tiny.toml's four static objects: the frame's
    /// materials are the statics' and then the three, and every pixel the renderer labels with one
    /// of the three gets the character's id.
    #[test]
    fn every_primitive_of_a_character_gets_the_characters_one_id() {
        let dir = tempfile::tempdir().unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        for file in ["external.gltf", "external.bin", "external_texture.png"] {
            std::fs::copy(root.join("tests/gltf").join(file), dir.path().join(file)).unwrap();
        }
        let tiny = std::fs::read_to_string(root.join("scenes/tiny.toml")).unwrap();
        let scene = dir.path().join("shapes.toml");
        let character = "[[character]]\nname = \"shapes\"\nfile = \"external.gltf\"\n\
                         scale = 0.1\n\n[[character.path]]\nframe = 1\nposition = [0.0, -0.5, 0.0]\n";
        std::fs::write(&scene, format!("{tiny}\n{character}")).unwrap();
        let job = super::super::RenderJob::prepare(&scene).unwrap();

        let names = job.object_names();
        assert_eq!(
            names,
            ["pool0.floor", "pool0.walls", "pool0.deck", "ball", "shapes"],
            "one name per static object part and one for the character"
        );
        let primitives = job.dynamics.characters[0].asset.stored_primitives().len();
        assert_eq!(primitives, 3, "external.gltf's drawn primitives");
        let ids = job.object_ids();
        assert_eq!(ids, [1, 2, 3, 4, 5, 5, 5]);
        let refracted = job.refract(1, 32, 18, None).unwrap();
        assert_eq!(
            refracted.draw.materials.len(),
            ids.len(),
            "the frame draws the statics and then each primitive, one material each"
        );

        // A strip whose pixels the renderer labelled with each material in turn (1-based).
        let pixels = ids.len() + 1;
        let labels: Vec<u32> = (1..=ids.len() as u32)
            .chain([crate::draw::NO_OBJECT])
            .collect();
        let strip = crate::draw::RenderedFrame {
            width: pixels as u32,
            height: 1,
            beauty_rgba: vec![[0.0; 4]; pixels],
            depth_m: vec![1.0; pixels],
            apparent_depth_m: vec![1.0; pixels],
            position: vec![[0.0; 3]; pixels],
            flags: vec![0; pixels],
            object: labels,
            water_matte: vec![0.0; pixels],
            water_reflection: vec![[0.0; 4]; pixels],
            motion_px: vec![[0.0; 2]; pixels],
            coverage: Vec::new(),
        };
        let checked = super::super::checked_strip(1, &ids, 0, strip).unwrap();
        assert_eq!(
            checked.object,
            [1, 2, 3, 4, 5, 5, 5, crate::draw::NO_OBJECT],
            "scene object ids: 5 is names[4], the character"
        );
    }
}
