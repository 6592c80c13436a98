//! One frame, end to end: scene + frame number -> water membrane -> refraction (virtual geometry,
//! flags) -> GPU passes -> layers, and the loop that renders a range of frames into EXR files and
//! the report. [`RenderJob`] is the single entry point used by the CLI and by the tests, so both
//! render exactly the same way.

pub mod bench;
pub mod characters;
pub mod finite;
pub mod inputs;
pub mod limits;
mod queue;
pub mod resume;
pub mod traced;
#[cfg(test)]
mod wake_tuning;
mod writer;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::camera::Camera;
use crate::draw::{DrawMaterial, FrameDraw, FrameView, MembraneVertex, RenderedFrame};
use crate::gpu::{GpuError, Renderer};
use crate::mesh::{Object, Texture};
use crate::output::OutputError;
use crate::refraction::flags::TrackingState as VertexTracking;
use crate::refraction::flags::{FlagCounts, CONVERGENCE_POLICY};
use crate::refraction::search::{CellMode, RefractionField, RefractionSetup};
use crate::refraction::subdivision::SubdivisionSettings;
use crate::refraction::virtual_geometry::{
    build_virtual_geometry_with, ImageSearch, Placement, VirtualGeometryRequest,
};
use crate::scene::{Scene, SceneError};
use crate::sim::SumHeightField;
use crate::timeline::{CameraMotion, Timeline};
use crate::water::{build_membrane, HeightField, Membrane, Wave, WaveField};

/// Everything that can stop a render, sorted into "your input is wrong" (exit 2) and the rest.
#[derive(Debug, thiserror::Error)]
pub enum SnellError {
    #[error("{0}")]
    Scene(#[from] SceneError),
    #[error("{0}")]
    Output(#[from] OutputError),
    #[error("{0}")]
    Gpu(#[from] GpuError),
    /// A command-line argument that cannot be used; the message says which and what to write.
    #[error("{0}")]
    Argument(String),
    /// Simulation checkpoints cannot be written where the output goes.
    #[error("{0}")]
    Checkpoint(#[from] crate::sim::CheckpointError),
    /// A bug: a panic inside snell or a library while making a frame (or, without a frame, a
    /// command), caught and reported instead of a backtrace.
    #[error("{}internal error: {message}; this is a bug in snell, please report it with the scene and the command", .frame.map_or_else(String::new, |f| format!("frame {f}: ")))]
    Internal { frame: Option<u32>, message: String },
    /// A rendered frame has a non-finite sample where the channel map allows none: it is not
    /// written.
    #[error("frame {frame}: pixel ({x}, {y}) has {layer} = {value}, not a finite number where the pixel sees something; the frame is not written (a bug in snell: please report it with the scene and the command)")]
    NonFinite {
        frame: u32,
        x: u32,
        y: u32,
        layer: &'static str,
        value: String,
    },
    /// The scene is valid as a file but a frame cannot be rendered from it.
    #[error("{scene}: frame {frame}: {problem}")]
    Frame {
        scene: PathBuf,
        frame: u32,
        problem: String,
    },
}

impl SnellError {
    /// Whether the user's input (scene, arguments, output location) is at fault: exit code 2.
    pub fn is_bad_input(&self) -> bool {
        match self {
            SnellError::Scene(_) | SnellError::Argument(_) | SnellError::Frame { .. } => true,
            SnellError::Checkpoint(error) => error.is_bad_input(),
            SnellError::Output(error) => error.is_bad_input(),
            SnellError::Gpu(_) | SnellError::Internal { .. } | SnellError::NonFinite { .. } => {
                false
            }
        }
    }
}

/// `WxH`, e.g. `1280x720`.
pub fn parse_size(text: &str) -> Result<(u32, u32), SnellError> {
    let bad = || {
        SnellError::Argument(format!(
            "--size {text:?}: expected WIDTHxHEIGHT in pixels, each between 1 and 16384, e.g. --size 1280x720"
        ))
    };
    let (w, h) = text.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let width: u32 = w.trim().parse().map_err(|_| bad())?;
    let height: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
        return Err(bad());
    }
    Ok((width, height))
}

/// `--frames`: a frame list (`N`, `A-B`, `A-BxS`, comma-separated, e.g. `1-48x4,50`), sorted and
/// each frame once, checked against the timeline.
pub fn parse_frame_list(text: &str, timeline: &Timeline) -> Result<Vec<u32>, SnellError> {
    let frames = crate::timeline::parse_frame_list(text)
        .map_err(|e| SnellError::Argument(format!("--frames {text:?}: {e}")))?;
    let outside: Vec<u32> = frames
        .iter()
        .copied()
        .filter(|frame| !timeline.contains(*frame))
        .collect();
    if !outside.is_empty() {
        return Err(SnellError::Argument(format!(
            "--frames {text:?}: frame(s) {} lie outside the scene's timeline, which runs from frame {} to {}; choose frames inside it",
            resume::frame_list(&outside),
            timeline.first_frame,
            timeline.last_frame
        )));
    }
    Ok(frames)
}

/// An inclusive range of frame numbers inside a scene's timeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    pub first: u32,
    pub last: u32,
}

impl FrameRange {
    pub fn whole(timeline: &Timeline) -> Self {
        FrameRange {
            first: timeline.first_frame,
            last: timeline.last_frame,
        }
    }

    /// `"A-B"` or `"N"`, checked against the timeline.
    pub fn parse(text: &str, timeline: &Timeline) -> Result<Self, SnellError> {
        let (first, last) = crate::timeline::parse_frame_range(text)
            .map_err(|e| SnellError::Argument(format!("--frames {text:?}: {e}")))?;
        if first < timeline.first_frame || last > timeline.last_frame {
            return Err(SnellError::Argument(format!(
                "--frames {text:?}: the scene's timeline runs from frame {} to {}; choose frames inside it",
                timeline.first_frame, timeline.last_frame
            )));
        }
        Ok(FrameRange { first, last })
    }

    pub fn frames(&self) -> impl Iterator<Item = u32> {
        self.first..=self.last
    }

    pub fn len(&self) -> u32 {
        self.last - self.first + 1
    }

    pub fn is_empty(&self) -> bool {
        false
    }
}

/// The CPU side of one frame: what the GPU will draw, and the refraction stage's verdicts.
pub struct RefractedFrame {
    pub frame: u32,
    pub time_secs: f64,
    pub camera: Camera,
    pub draw: FrameDraw,
    pub view: FrameView,
    pub counts: FlagCounts,
    /// Width and height in pixels the frame is refracted for.
    pub image_size: (u32, u32),
    /// Chosen images per vertex, for the next frame's popping test.
    pub tracking: VertexTracking,
    pub stage_secs: BTreeMap<String, f64>,
    /// What the ray-traced methods trace instead of drawing `draw` (None for the others).
    pub trace: Option<traced::TraceInputs>,
}

/// One frame's water and world, before refraction: what [`RenderJob::frame_water`] returns.
pub struct FrameWater<'a> {
    pub frame: u32,
    pub time_secs: f64,
    pub camera: Camera,
    /// World space: the static objects, then the posed characters; an object's index here is its
    /// material index in the frame (and its object id minus one).
    pub objects: std::borrow::Cow<'a, [Object]>,
    /// The waves at this instant (exact).
    pub waves_now: crate::water::WaterSurface,
    /// The characters' ripples at this frame, if the scene has any.
    pub ripples: Option<std::sync::Arc<crate::sim::RippleState>>,
    /// The faceted membrane sampled from [`FrameWater::surface`].
    pub membrane: Membrane,
    /// Heights the refraction search must answer for (lowest object vertex to highest water).
    pub query_y_range: (f32, f32),
}

impl FrameWater<'_> {
    /// The exact water surface: waves plus ripples.
    pub fn surface(&self) -> SumHeightField<'_> {
        SumHeightField {
            base: &self.waves_now,
            ripples: self.ripples.as_ref().map(|state| state.field()),
        }
    }

    /// [`FrameWater::surface`] (pass its result) over the membrane's extent, with the bounds every
    /// exact-surface query steps by ([`crate::refraction::surface`]).
    pub fn exact_surface<'a>(
        &'a self,
        heights: &'a SumHeightField<'a>,
    ) -> crate::refraction::surface::ExactSurface<'a> {
        crate::refraction::surface::of_water(
            &self.waves_now,
            heights.ripples,
            heights,
            self.membrane.grid,
        )
    }
}

/// How under-water geometry is placed: which refraction cells the virtual vertices come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// Equal-t cells (ALGORITHM §5): no gaps, no overlaps. The default.
    #[default]
    EqualT,
    /// The thesis's per-facet plane test, kept for comparison (gaps and overlaps between cells).
    ThesisPlane,
    /// Exact virtual vertices: from each equal-t image's sight point, Newton on Fermat's principle
    /// over the exact surface (ALGORITHM §6), with adaptive subdivision of under-water triangles.
    Exact,
    /// The ray-traced reference on the CPU through the exact surface (no virtual geometry).
    Raytrace,
    /// The ray-traced reference through the triangulated membrane with interpolated normals.
    RaytraceMembrane,
}

impl Method {
    pub const ALL: [Method; 5] = [
        Method::EqualT,
        Method::ThesisPlane,
        Method::Exact,
        Method::Raytrace,
        Method::RaytraceMembrane,
    ];

    /// The short name used on the command line and in the preview (`equal-t`, `thesis-plane`).
    pub fn name(self) -> &'static str {
        match self {
            Method::EqualT => "equal-t",
            Method::ThesisPlane => "thesis-plane",
            Method::Exact => "exact",
            Method::Raytrace => "raytrace",
            Method::RaytraceMembrane => "raytrace-membrane",
        }
    }

    /// The label written into EXR headers and reports.
    pub fn label(self) -> &'static str {
        match self {
            Method::EqualT => "virtual-vertices/equal-t",
            Method::ThesisPlane => "virtual-vertices/thesis-plane",
            Method::Exact => "virtual-vertices/exact",
            Method::Raytrace => "raytrace/exact-surface",
            Method::RaytraceMembrane => "raytrace/membrane",
        }
    }

    /// One line saying what the method is, for `--help` and the preview's selector.
    pub fn description(self) -> &'static str {
        match self {
            Method::EqualT => "virtual vertices through equal-t refraction cells (exact cell boundaries)",
            Method::ThesisPlane => {
                "virtual vertices through the thesis's plane-test cells (gaps and overlaps between cells)"
            }
            Method::Exact => {
                "exact virtual vertices (Newton on Fermat's principle from each equal-t image) with adaptive subdivision"
            }
            Method::Raytrace => {
                "CPU ray-traced reference through the exact wave surface (no virtual vertices: flag counts are 0)"
            }
            Method::RaytraceMembrane => {
                "CPU ray tracer through the triangulated membrane with interpolated normals (flag counts are 0)"
            }
        }
    }

    /// The water the ray-traced methods meet; `None` for the virtual-vertex methods (GPU).
    pub fn traced_water(self) -> Option<crate::reference::WaterModel> {
        match self {
            Method::EqualT | Method::ThesisPlane | Method::Exact => None,
            Method::Raytrace => Some(crate::reference::WaterModel::Exact),
            Method::RaytraceMembrane => Some(crate::reference::WaterModel::Membrane),
        }
    }

    /// Whether frames of this method are drawn by the GPU renderer (the others trace on the CPU).
    pub fn uses_gpu(self) -> bool {
        self.traced_water().is_none()
    }

    /// Parses [`Method::name`]; the error lists the choices.
    pub fn parse(text: &str) -> Result<Method, SnellError> {
        Method::ALL
            .into_iter()
            .find(|method| method.name() == text.trim())
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                SnellError::Argument(format!(
                    "method {text:?} is unknown; choose one of: {}",
                    names.join(", ")
                ))
            })
    }

    fn cell_mode(self) -> CellMode {
        match self {
            Method::EqualT => CellMode::EqualT,
            Method::ThesisPlane => CellMode::Thesis,
            // Never asked: the ray-traced methods build no refraction field.
            Method::Raytrace | Method::RaytraceMembrane => CellMode::EqualT,
            Method::Exact => CellMode::EqualT,
        }
    }

    /// Where the method puts under-water vertices (the subdivision settings apply to
    /// [`Method::Exact`] only).
    fn placement(self, subdivision: SubdivisionSettings) -> Placement {
        match self {
            // The ray-traced methods are never asked: they place no vertices.
            Method::EqualT | Method::ThesisPlane | Method::Raytrace | Method::RaytraceMembrane => {
                Placement::Linear
            }
            Method::Exact => Placement::Exact(subdivision),
        }
    }
}

/// A loaded scene, ready to render any of its frames.
pub struct RenderJob {
    pub scene: Scene,
    pub objects: Vec<Object>,
    pub textures: Vec<Texture>,
    pub waves: WaveField,
    /// The camera: keyframes or a glTF file's.
    pub camera_motion: CameraMotion,
    /// Characters (posed every frame) and the ripples they make.
    pub dynamics: characters::Dynamics,
    /// How under-water geometry is placed ([`Method::EqualT`] unless set).
    pub method: Method,
    /// How finely [`Method::Exact`] subdivides under-water triangles (ignored by the others).
    pub subdivision: SubdivisionSettings,
    /// Set when the scene's `max_error_px` chose the method and membrane resolution
    /// ([`crate::chart::budget::apply_budget`]); reported in EXR headers and report rows.
    pub quality_choice: Option<crate::chart::budget::QualityChoice>,
    /// The EXR header's `owner` and `capDate`; none by default, so frames are byte-identical
    /// run to run (the CLI sets them from `--owner` and `SOURCE_DATE_EPOCH`).
    pub stamp: HeaderStamp,
    /// How frames are stored (`--half`, `--compression`); part of the input hash when not the
    /// default, so `--resume` renders again frames stored otherwise.
    pub write: crate::output::exr::WriteOptions,
    /// Rows of the strips [`Self::render_sequence`] draws frames in ([`Renderer::set_strip_rows`]);
    /// `None`: whole frames when they fit one readback, strips otherwise. Strips give the same
    /// pixels; forcing them is for tests and measurements (`--strip-rows`).
    pub strip_rows: Option<u32>,
    /// Whole frames the command keeps at once (0: a render, which streams its strips to the
    /// file): counted in each frame's memory estimate ([`Self::check_frame_resources`]), so a
    /// size whose frames cannot all be held is refused before the work, not killed in it.
    pub frames_held: u32,
    /// Heights the refraction search must cover for the static objects (characters and ripples
    /// widen it per frame).
    query_y_range: (f32, f32),
    /// The textures as the ray-traced methods sample them, made on first use.
    traced_textures: std::sync::OnceLock<traced::TracedTextures>,
    /// The scene file and every file it references, hashed once at load (frames' input hash,
    /// simulation checkpoint key).
    scene_files: inputs::SceneFilesDigest,
    /// What a frame needs before the image size is known ([`limits`]); checked at load.
    pub resources: crate::scene::resources::Estimate,
}

/// Who made a frame and when, for the EXR header (`owner`, `capDate`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HeaderStamp {
    pub owner: Option<String>,
    /// A Unix time, normally `SOURCE_DATE_EPOCH`'s.
    pub capture_unix_secs: Option<i64>,
}

/// What a finished render reports to the CLI.
pub struct RenderSummary {
    pub frames: u32,
    pub secs_per_frame: f64,
}

impl RenderJob {
    /// Loads and validates the scene and builds its static geometry and textures.
    pub fn prepare(scene_path: &Path) -> Result<Self, SnellError> {
        let scene = Scene::load(scene_path)?;
        Self::from_scene(scene)
    }

    pub fn from_scene(scene: Scene) -> Result<Self, SnellError> {
        if !scene.vessels.is_empty() {
            // Issue 18 so far: vessels are parsed, validated, traced by the reference's vessel
            // code and benchmarked, but the renderer does not draw them yet. Say so rather than
            // render silently without them.
            crate::errln!(
                "warning: the scene's {} [[vessel]] entries are validated but not drawn yet: \
                 frames show the scene without them",
                scene.vessels.len()
            );
        }
        let (objects, mut textures) = scene.build_objects()?;
        let loaded = characters::load_characters(&scene, &mut textures)?;
        let scene_files = inputs::digest_scene_files(&scene, &loaded)?;
        let dynamics = characters::Dynamics::new(&scene, loaded, &scene_files)?;
        let resources = limits::check_loaded(&scene, &dynamics.characters, &textures)?;
        let waves = WaveField {
            level_m: scene.water.level_m,
            waves: scene.water.waves.iter().map(wave_from_spec).collect(),
        };
        let camera_motion = scene.camera.motion();
        let top = waves.height_bounds_m().1 as f32 + 1e-3;
        let bottom = objects
            .iter()
            .flat_map(|o| o.mesh.positions.iter().map(|p| p.y))
            .fold(top, f32::min)
            - 1e-3;
        Ok(RenderJob {
            scene,
            objects,
            textures,
            waves,
            camera_motion,
            dynamics,
            method: Method::default(),
            subdivision: SubdivisionSettings::default(),
            quality_choice: None,
            stamp: HeaderStamp::default(),
            write: Default::default(),
            strip_rows: None,
            frames_held: 0,
            query_y_range: (bottom, top),
            traced_textures: std::sync::OnceLock::new(),
            scene_files,
            resources,
        })
    }

    /// A frame of this job at `width` x `height` within the memory limit and the GPU's readback
    /// limit ([`limits::check_frame`]); every frame checks it before it starts, and a render
    /// before its first frame.
    pub fn check_frame_resources(&self, width: u32, height: u32) -> Result<(), SnellError> {
        // A glTF camera with its own aspect ratio renders only frames of that shape.
        self.scene.camera.check_frame_size(width, height)?;
        limits::check_frame(
            &self.resources,
            self.method,
            width,
            height,
            self.frames_held,
        )
        .map(|_| ())
    }

    /// The rendering method, as EXR headers and report rows name it.
    pub fn method_label(&self) -> &'static str {
        self.method.label()
    }

    /// The hash of everything a frame of this job at `width` x `height` is made from: the scene's
    /// files as loaded, the size, [`Self::method_label`] and snell's version.
    pub fn input_hash(&self, width: u32, height: u32) -> inputs::InputHash {
        // The exact method's output depends on its subdivision settings too.
        let method = match self.method {
            Method::Exact => format!(
                "{} tolerance_px={} max_depth={}",
                self.method_label(),
                self.subdivision.tolerance_px,
                self.subdivision.max_depth
            ),
            _ => self.method_label().to_string(),
        };
        // Frames of the default storage keep the hash they had before the choice existed.
        let method = if self.write == crate::output::exr::WriteOptions::default() {
            method
        } else {
            format!("{method} {}", self.write.label())
        };
        inputs::input_hash(&self.scene_files, width, height, &method)
    }

    /// The digest of the scene file and every file it references (as hashed at load).
    pub fn scene_files_digest(&self) -> inputs::SceneFilesDigest {
        self.scene_files
    }

    /// Reads and writes simulation checkpoints under `out_dir` from now on (a note when stale
    /// checkpoints of this scene were deleted).
    pub fn use_checkpoints(&self, out_dir: &Path) -> Result<Option<String>, SnellError> {
        self.dynamics.use_checkpoints(out_dir, &self.scene.name)
    }

    /// Every file the scene references besides the scene file (character models with their
    /// buffers and images, a glTF camera with its buffers, image textures), sorted, without repeats.
    pub fn referenced_files(&self) -> Vec<PathBuf> {
        inputs::referenced_files(&self.scene, &self.dynamics.characters)
    }

    pub fn scene_name(&self) -> &str {
        &self.scene.name
    }

    /// The name of each scene object id ([`RenderedFrame::object`]): id `k + 1` is
    /// `object_names()[k]`. Static objects in scene order (each part of a pool on its own), then
    /// one id per character, whatever the number of its glTF primitives.
    pub fn object_names(&self) -> Vec<String> {
        self.objects
            .iter()
            .map(|object| object.name.clone())
            .chain(
                self.dynamics
                    .characters
                    .iter()
                    .map(|character| character.spec.name.clone()),
            )
            .collect()
    }

    /// The scene object id of each of a frame's objects (materials): the static objects, then
    /// every posed primitive of each character in turn, which all get their character's id.
    fn object_ids(&self) -> Vec<u32> {
        let statics = self.objects.len() as u32;
        let mut ids: Vec<u32> = (1..=statics).collect();
        for (index, character) in self.dynamics.characters.iter().enumerate() {
            let primitives = character.asset.stored_primitives().len();
            ids.extend(std::iter::repeat_n(statics + 1 + index as u32, primitives));
        }
        ids
    }

    pub fn timeline(&self) -> &Timeline {
        &self.scene.timeline
    }

    pub fn camera_at(&self, frame: u32) -> Camera {
        self.camera_motion
            .sample(self.scene.timeline.time_secs(frame))
    }

    /// The optics of every frame of this job seen from `eye` ([`Self::method`]'s cells).
    pub fn refraction_setup(&self, eye: glam::Vec3) -> RefractionSetup {
        RefractionSetup {
            eye,
            n_above: self.scene.water.n_above as f32,
            n_below: self.scene.water.n_below as f32,
            cell_mode: self.method.cell_mode(),
        }
    }

    /// The first CPU stages of a frame, shared by [`Self::refract`], `snell locate` and
    /// `snell export`: camera, posed characters, ripples, the exact surface and its membrane.
    /// Records the `skinning`, `ripples` and `water` stage times in `stage_secs`. An eye at or
    /// under the water is an error (snell renders from above).
    pub fn frame_water(
        &self,
        frame: u32,
        stage_secs: &mut BTreeMap<String, f64>,
    ) -> Result<FrameWater<'_>, SnellError> {
        let time_secs = self.scene.timeline.time_secs(frame);
        let camera = self.camera_motion.sample(time_secs);
        let clock = Instant::now();
        let posed = self.dynamics.posed_objects(time_secs);
        limits::check_posed(&self.scene, frame, &posed)?;
        stage_secs.insert("skinning".to_string(), clock.elapsed().as_secs_f64());
        let clock = Instant::now();
        let ripples = self
            .dynamics
            .ripples_at(&self.scene, &self.waves, frame, &posed)?;
        stage_secs.insert("ripples".to_string(), clock.elapsed().as_secs_f64());
        let waves_now = self.waves.at(time_secs);
        // Characters widen the heights the search covers; the static objects' range is known.
        let query_y_range = (
            posed
                .iter()
                .flat_map(|o| o.mesh.positions.iter().map(|p| p.y))
                .fold(self.query_y_range.0, f32::min),
            self.query_y_range.1 + ripples.as_ref().map_or(0.0, |r| r.max_abs_height_m()),
        );
        let objects: std::borrow::Cow<'_, [Object]> = if posed.is_empty() {
            std::borrow::Cow::Borrowed(&self.objects)
        } else {
            std::borrow::Cow::Owned(self.objects.iter().cloned().chain(posed).collect())
        };
        let surface = SumHeightField {
            base: &waves_now,
            ripples: ripples.as_ref().map(|state| state.field()),
        };
        let water_at_eye = surface.height(camera.eye.x as f64, camera.eye.z as f64);
        if (camera.eye.y as f64) <= water_at_eye + 0.01 {
            return Err(SnellError::Frame {
                scene: self.scene.path.clone(),
                frame,
                problem: format!(
                    "the camera's eye ({:.3}, {:.3}, {:.3}) is at or under the water surface (height {:.3} m there); \
                     snell renders from above the water: raise the camera keyframes' eye",
                    camera.eye.x, camera.eye.y, camera.eye.z, water_at_eye
                ),
            });
        }
        let clock = Instant::now();
        let membrane = build_membrane(&surface, &self.scene.water.grid());
        stage_secs.insert("water".to_string(), clock.elapsed().as_secs_f64());
        Ok(FrameWater {
            frame,
            time_secs,
            camera,
            objects,
            waves_now,
            ripples,
            membrane,
            query_y_range,
        })
    }

    /// CPU stages of a frame: water, membrane, refraction, virtual geometry, flags. `previous` is the
    /// tracking of frame - 1 (for popping); pass `None` only for the timeline's first frame.
    pub fn refract(
        &self,
        frame: u32,
        width: u32,
        height: u32,
        previous: Option<&VertexTracking>,
    ) -> Result<RefractedFrame, SnellError> {
        self.check_frame_resources(width, height)?;
        catch_frame(frame, || {
            self.refract_caught(frame, width, height, previous)
        })
    }

    fn refract_caught(
        &self,
        frame: u32,
        width: u32,
        height: u32,
        previous: Option<&VertexTracking>,
    ) -> Result<RefractedFrame, SnellError> {
        crate::panics::inject_for_tests(frame);
        let mut stage_secs = BTreeMap::new();
        let water = self.frame_water(frame, &mut stage_secs)?;
        if self.method.traced_water().is_some() {
            // The tracer needs no refraction field or virtual geometry: it traces the frame.
            let inputs = traced::TraceInputs {
                posed: water.objects[self.objects.len()..].to_vec(),
                waves: water.waves_now,
                ripples: water.ripples,
                membrane: water.membrane,
            };
            return Ok(self.traced_frame(
                frame,
                water.time_secs,
                water.camera,
                (width, height),
                inputs,
                stage_secs,
            ));
        }
        let (time_secs, camera, objects, membrane) = (
            water.time_secs,
            water.camera,
            &water.objects,
            &water.membrane,
        );
        let heights = water.surface();
        let surface = water.exact_surface(&heights);
        let clock = Instant::now();
        let field = RefractionField::build(
            membrane,
            &surface,
            self.refraction_setup(camera.eye),
            water.query_y_range,
        );
        let request = VirtualGeometryRequest {
            field: &field,
            camera,
            image_size: (width, height),
            objects,
            mean_level_m: self.waves.level_m as f32,
            search: ImageSearch::Accelerated,
        };
        let placement = self.method.placement(self.subdivision);
        let geometry = build_virtual_geometry_with(&request, previous, placement);
        stage_secs.insert("refraction".to_string(), clock.elapsed().as_secs_f64());

        let draw = FrameDraw {
            above_vertices: geometry.above_vertices,
            above_indices: geometry.above_indices,
            under_vertices: geometry.under_vertices,
            membrane_vertices: membrane_vertices(membrane),
            membrane_indices: membrane.triangles.iter().flatten().copied().collect(),
            materials: draw_materials(objects.iter()),
        };
        let view = FrameView {
            camera,
            previous_camera: previous.map_or(camera, |p| p.camera),
            lighting: self.scene.lighting(),
            water: self.scene.water_optics(),
        };
        Ok(RefractedFrame {
            frame,
            time_secs,
            camera,
            draw,
            view,
            counts: geometry.counts,
            image_size: (width, height),
            tracking: geometry.tracking,
            stage_secs,
            trace: None,
        })
    }

    /// The tracking state popping compares against for `frame`: frame - 1 recomputed (CPU only),
    /// or nothing at the start of the timeline. A frame rendered alone is thus judged exactly as
    /// in a sequence.
    pub fn previous_tracking(
        &self,
        frame: u32,
        width: u32,
        height: u32,
    ) -> Result<Option<VertexTracking>, SnellError> {
        if frame <= self.scene.timeline.first_frame || !self.method.uses_gpu() {
            // The ray-traced methods have no virtual vertices that could pop.
            return Ok(None);
        }
        Ok(Some(self.refract(frame - 1, width, height, None)?.tracking))
    }

    /// Renders one frame on `renderer` (textures must have been set with [`Self::upload_textures`]),
    /// or, for the ray-traced methods, traces it on the CPU (no renderer needed: pass `None`).
    pub fn render_refracted<'r>(
        &self,
        renderer: impl Into<Option<&'r mut Renderer>>,
        refracted: &mut RefractedFrame,
        width: u32,
        height: u32,
    ) -> Result<RenderedFrame, SnellError> {
        let frame = refracted.frame;
        let renderer = renderer.into();
        catch_frame(frame, || {
            self.render_caught(renderer, refracted, width, height)
        })
    }

    fn render_caught(
        &self,
        renderer: Option<&mut Renderer>,
        refracted: &mut RefractedFrame,
        width: u32,
        height: u32,
    ) -> Result<RenderedFrame, SnellError> {
        // The strips gathered into the whole frame as they come (held once, never twice).
        let mut whole = None;
        self.render_strips_caught(renderer, refracted, width, height, &mut |_, strip| {
            RenderedFrame::gather(&mut whole, strip, height);
            Ok(())
        })?;
        Ok(whole.unwrap_or_default())
    }

    /// Renders one frame as [`Self::render_refracted`] does, but gives it to `sink` strip by
    /// strip (bands of rows, top first, each with the frame row it starts at) as the GPU reads
    /// them back ([`Renderer::render_strips`]), so that the whole frame is never held. A frame
    /// small enough to read back at once, and every ray-traced one, comes as a single strip.
    /// The `render` stage time leaves out the time spent in `sink`.
    pub fn render_refracted_strips<'r>(
        &self,
        renderer: impl Into<Option<&'r mut Renderer>>,
        refracted: &mut RefractedFrame,
        width: u32,
        height: u32,
        sink: &mut dyn FnMut(u32, RenderedFrame) -> Result<(), SnellError>,
    ) -> Result<(), SnellError> {
        let frame = refracted.frame;
        let renderer = renderer.into();
        catch_frame(frame, || {
            self.render_strips_caught(renderer, refracted, width, height, sink)
        })
    }

    fn render_strips_caught(
        &self,
        renderer: Option<&mut Renderer>,
        refracted: &mut RefractedFrame,
        width: u32,
        height: u32,
        sink: &mut dyn FnMut(u32, RenderedFrame) -> Result<(), SnellError>,
    ) -> Result<(), SnellError> {
        let clock = Instant::now();
        let mut in_sink = 0.0;
        let ids = self.object_ids();
        let frame = refracted.frame;
        let mut finish_strip = |first_row: u32, strip: RenderedFrame| {
            let strip = checked_strip(frame, &ids, first_row, strip)?;
            let entered = Instant::now();
            let given = sink(first_row, strip);
            in_sink += entered.elapsed().as_secs_f64();
            given
        };
        if refracted.trace.is_some() {
            let rendered = self.trace_refracted(refracted, width, height)?.rendered;
            finish_strip(0, rendered)?;
        } else {
            let renderer = renderer.ok_or_else(|| {
                SnellError::Argument(format!(
                    "method {} draws on the GPU, but no renderer was given",
                    self.method.name()
                ))
            })?;
            renderer.set_supersample(self.scene.antialias.supersample)?;
            renderer.render_strips(
                &refracted.draw,
                &refracted.view,
                width,
                height,
                &mut finish_strip,
            )?;
        }
        refracted.stage_secs.insert(
            "render".to_string(),
            (clock.elapsed().as_secs_f64() - in_sink).max(0.0),
        );
        Ok(())
    }

    pub fn upload_textures(&self, renderer: &mut Renderer) -> Result<(), SnellError> {
        renderer.set_textures(&self.textures)?;
        Ok(())
    }

    /// Renders a single frame alone (popping judged against frame - 1 recomputed). Textures must
    /// have been set once with [`Self::upload_textures`]: they do not change between frames.
    pub fn render_frame<'r>(
        &self,
        renderer: impl Into<Option<&'r mut Renderer>>,
        frame: u32,
        width: u32,
        height: u32,
    ) -> Result<(RefractedFrame, RenderedFrame), SnellError> {
        let previous = self.previous_tracking(frame, width, height)?;
        let mut refracted = self.refract(frame, width, height, previous.as_ref())?;
        let rendered = self.render_refracted(renderer, &mut refracted, width, height)?;
        Ok((refracted, rendered))
    }

    /// Renders `range` into `out_dir` (EXR per frame, report.jsonl, optional PNGs), with a progress
    /// bar: every frame, no resume, no stop request (see [`resume::SequenceOptions`] for those).
    pub fn render_to_dir(
        &self,
        range: FrameRange,
        width: u32,
        height: u32,
        out_dir: &Path,
        write_png: bool,
        progress: bool,
    ) -> Result<RenderSummary, SnellError> {
        let frames: Vec<u32> = range.frames().collect();
        let output = crate::output::pattern::OutputPattern::for_scene(out_dir, &self.scene.name);
        let outcome = self.render_sequence(&resume::SequenceOptions {
            frames: &frames,
            width,
            height,
            output: &output,
            write_png,
            progress,
            log: resume::FrameLog::Quiet,
            resume: false,
            stop: None,
        })?;
        Ok(RenderSummary {
            frames: outcome.rendered.len() as u32,
            secs_per_frame: outcome.secs_per_frame,
        })
    }

    pub fn frame_meta(&self, refracted: &RefractedFrame) -> crate::output::exr::FrameMeta {
        crate::output::exr::FrameMeta {
            scene_name: self.scene.name.clone(),
            frame: refracted.frame,
            time_secs: refracted.time_secs,
            camera: refracted.camera,
            method: self.method_label().to_string(),
            version: crate::VERSION.to_string(),
            fps: self.scene.timeline.fps,
            object_names: self.object_names(),
            owner: self.stamp.owner.clone(),
            capture_unix_secs: self.stamp.capture_unix_secs,
            write: self.write,
            extra: vec![
                (
                    "convergencePolicy".to_string(),
                    CONVERGENCE_POLICY.to_string(),
                ),
                ("scene".to_string(), self.scene.path.display().to_string()),
                // So a lone EXR carries its flag counts (`snell diff` compares them exactly).
                (
                    "flagCounts".to_string(),
                    serde_json::to_string(&refracted.counts).expect("flag counts serialise"),
                ),
                (
                    inputs::INPUT_HASH_ATTRIBUTE.to_string(),
                    self.input_hash(refracted.image_size.0, refracted.image_size.1)
                        .hex(),
                ),
            ]
            .into_iter()
            .chain(self.quality_choice.as_ref().map(|choice| {
                (
                    crate::chart::budget::CHOICE_ATTRIBUTE.to_string(),
                    choice.to_json().to_string(),
                )
            }))
            .collect(),
        }
    }

    pub fn frame_report(
        &self,
        refracted: &RefractedFrame,
        width: u32,
        height: u32,
    ) -> crate::output::report::FrameReport {
        crate::output::report::FrameReport {
            frame: refracted.frame,
            time_secs: refracted.time_secs,
            convergence_policy: CONVERGENCE_POLICY.to_string(),
            counts: serde_json::to_value(refracted.counts).expect("flag counts serialise"),
            stage_secs: refracted.stage_secs.clone(),
            size: [width, height],
            method: self.method_label().to_string(),
            input_hash: Some(self.input_hash(width, height).hex()),
            quality: self.quality_choice.as_ref().map(|choice| choice.to_json()),
        }
    }

    /// A human-readable description for `snell info`.
    pub fn describe(&self) -> String {
        let scene = &self.scene;
        let vertices: usize = self.objects.iter().map(|o| o.mesh.vertex_count()).sum();
        let triangles: usize = self.objects.iter().map(|o| o.mesh.triangle_count()).sum();
        let grid = scene.water.grid();
        let mut text = String::new();
        use std::fmt::Write;
        let _ = writeln!(text, "scene      {} ({})", scene.name, scene.path.display());
        let _ = writeln!(
            text,
            "timeline   frames {}-{} at {} fps ({:.2} s)",
            scene.timeline.first_frame,
            scene.timeline.last_frame,
            scene.timeline.fps,
            scene.timeline.time_secs(scene.timeline.last_frame)
        );
        let _ = writeln!(
            text,
            "objects    {} ({} vertices, {} triangles)",
            self.objects.len(),
            vertices,
            triangles
        );
        for object in &self.objects {
            let _ = writeln!(
                text,
                "           - {}: {} vertices, {} triangles",
                object.name,
                object.mesh.vertex_count(),
                object.mesh.triangle_count()
            );
        }
        if !scene.vessels.is_empty() {
            let _ = writeln!(
                text,
                "vessels    {} (validated; not drawn yet, issue 18)",
                scene.vessels.len()
            );
            for spec in scene.vessels.iter() {
                let _ = writeln!(
                    text,
                    "           - {}: {}",
                    spec.name,
                    spec.vessel.describe()
                );
            }
        }
        let _ = match &scene.camera {
            crate::scene::CameraSpec::Keys(keys) => {
                writeln!(text, "camera     {} keyframe(s)", keys.len())
            }
            crate::scene::CameraSpec::Gltf(spec) => {
                let camera = &spec.camera;
                let p = camera.projection;
                writeln!(
                    text,
                    "camera     glTF {} node {:?}: yfov {:.2} deg, aspectRatio {}, znear {} m, zfar {}; {}",
                    spec.file.display(),
                    camera.node_name,
                    p.yfov_rad.to_degrees(),
                    p.aspect_ratio
                        .map_or("none (the frame's)".to_string(), |a| format!("{a:.4}")),
                    p.znear_m,
                    p.zfar_m.map_or(
                        format!("none (clipped at {} m)", crate::camera::FAR_M),
                        |f| format!("{f} m")
                    ),
                    match &camera.animation {
                        Some((label, [start, end])) => {
                            format!("animation {label}, {start:.3}-{end:.3} s")
                        }
                        None => "no animation (still)".to_string(),
                    }
                )
            }
        };
        let characters = &self.dynamics.characters;
        if !characters.is_empty() {
            let _ = writeln!(text, "characters {}", characters.len());
            for character in characters {
                text.push_str(&character.describe());
            }
        }
        let _ = writeln!(
            text,
            "water      {}x{} cells over x {:.2}..{:.2} m, z {:.2}..{:.2} m ({} facets), {} waves, n {} / {}",
            grid.cells_x,
            grid.cells_z,
            grid.min_x,
            grid.max_x,
            grid.min_z,
            grid.max_z,
            2 * grid.cells_x as u64 * grid.cells_z as u64,
            self.waves.waves.len(),
            scene.water.n_above,
            scene.water.n_below
        );
        let _ = writeln!(text, "textures   {}", self.textures.len());
        let mut at_default_size = self.resources;
        at_default_size.pixels = 1280 * 720;
        let _ = writeln!(
            text,
            "resources  {} (at 1280x720; limit {})",
            at_default_size.describe(),
            crate::scene::resources::memory_limit()
                .map_or_else(|e| e, crate::scene::resources::human_bytes)
        );
        let adapter = crate::gpu::probe_adapter().unwrap_or_else(|e| format!("none usable: {e}"));
        let _ = writeln!(text, "adapter    {adapter}");
        text
    }
}

/// Runs one frame's `work`; a panic inside it becomes [`SnellError::Internal`] naming the frame.
fn catch_frame<T>(
    frame: u32,
    work: impl FnOnce() -> Result<T, SnellError>,
) -> Result<T, SnellError> {
    crate::panics::catch(work).unwrap_or_else(|message| {
        Err(SnellError::Internal {
            frame: Some(frame),
            message,
        })
    })
}

/// A strip of frame `frame` from row `first_row` as the GPU or the tracer gave it, with its
/// object (material) indices + 1 made scene object ids (`ids`), and checked finite: a non-finite
/// sample is [`SnellError::NonFinite`] at its frame pixel.
fn checked_strip(
    frame: u32,
    ids: &[u32],
    first_row: u32,
    mut strip: RenderedFrame,
) -> Result<RenderedFrame, SnellError> {
    for object in &mut strip.object {
        if *object != crate::draw::NO_OBJECT {
            *object = ids.get(*object as usize - 1).copied().ok_or_else(|| {
                SnellError::Argument(format!(
                    "frame {frame}: object index {} is not one of the {} objects drawn",
                    *object - 1,
                    ids.len()
                ))
            })?;
        }
    }
    for rank in strip.coverage.iter_mut().flatten() {
        if rank.key != crate::draw::NO_OBJECT && rank.key != crate::draw::COVERAGE_WATER {
            rank.key = ids.get(rank.key as usize - 1).copied().ok_or_else(|| {
                SnellError::Argument(format!(
                    "frame {frame}: coverage of object index {} is not one of the {} objects drawn",
                    rank.key - 1,
                    ids.len()
                ))
            })?;
        }
    }
    if let Some((x, y, layer, value)) = finite::first_non_finite(&strip) {
        return Err(SnellError::NonFinite {
            frame,
            x,
            y: first_row + y,
            layer,
            value,
        });
    }
    Ok(strip)
}

/// The scene file's wave (direction in degrees) as the water stage's wave (unit direction).
fn wave_from_spec(spec: &crate::scene::WaveSpec) -> Wave {
    Wave {
        amplitude_m: spec.amplitude_m,
        wavelength_m: spec.wavelength_m,
        direction: spec.direction_xz(),
        phase_rad: spec.phase_rad,
        speed_m_per_s: spec.speed_m_per_s,
    }
}

/// The materials of `objects` as the GPU (and the tracer) index them: one per object, in order.
pub(crate) fn draw_materials<'a>(objects: impl Iterator<Item = &'a Object>) -> Vec<DrawMaterial> {
    objects
        .map(|o| DrawMaterial {
            texture: o.material.texture,
            tint_linear: o.material.tint_linear,
        })
        .collect()
}

fn membrane_vertices(membrane: &Membrane) -> Vec<MembraneVertex> {
    membrane
        .positions
        .iter()
        .zip(&membrane.normals)
        .map(|(p, n)| MembraneVertex {
            position: p.to_array(),
            normal: n.to_array(),
        })
        .collect()
}

/// The progress bar of long CPU/GPU work (frames, configurations): hidden unless `visible`.
pub(crate) fn progress_bar(len: u64, visible: bool) -> indicatif::ProgressBar {
    if !visible {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} {msg} (ETA {eta})",
        )
        .expect("valid template"),
    );
    bar
}
