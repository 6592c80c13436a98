//! Skinned, animated glTF characters (pure CPU).
//!
//! Receives a `.glb` or `.gltf` file (external `.bin` buffers and images resolved next to it), an
//! animation and a time; returns world-space triangle meshes ([`PosedPrimitive`]) with their
//! base-colour factor and texture, ready to be turned into scene objects.
//!
//! The work is split in three steps so that a frame only pays for the last two:
//! 1. [`CharacterAsset::load`] reads and *validates* everything once: buffers long enough, joint
//!    indices inside their skin, weights that can be normalised, animation keys well formed.
//!    A loaded asset is therefore always safe to pose; posing never fails.
//! 2. [`CharacterAsset::pose`] samples the animation (`animation.rs`) into node and joint matrices.
//! 3. [`CharacterAsset::posed_primitives`] skins the vertices (linear blend skinning, rayon,
//!    deterministic) or, for meshes without a skin, applies their node's global transform.
//!
//! The same reader gives a scene its camera from a glTF file ([`GltfCamera`], `camera.rs`): the
//! file checked as above, a camera node's global transform animated like a character's nodes.

mod animation;
mod camera;
mod load;
mod skinning;

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Mat4, Quat, Vec3};

use crate::mesh::{Mesh, Texture};

pub use camera::{GltfCamera, GltfCameraError, Perspective};
pub use skinning::Pose;

/// Why a character file cannot be used. Every variant names the file and says the cause plainly.
#[derive(Debug, thiserror::Error)]
pub enum CharacterError {
    /// The model file is not a regular file of a sensible size (a FIFO, a device, too large).
    #[error("{0}")]
    File(crate::files::InputFileError),
    #[error("{}: not a usable glTF 2.0 file: {reason}", .path.display())]
    NotGltf { path: PathBuf, reason: String },
    #[error("{}: buffer {buffer} ({source_name}) cannot be read: {reason}", .path.display())]
    MissingBuffer {
        path: PathBuf,
        buffer: usize,
        source_name: String,
        reason: String,
    },
    #[error("{}: buffer {buffer} ({source_name}) is truncated: {reason}", .path.display())]
    TruncatedBuffer {
        path: PathBuf,
        buffer: usize,
        source_name: String,
        reason: String,
    },
    #[error("{}: buffer {buffer} ({source_name}) cannot be decoded: {reason}", .path.display())]
    UndecodableBuffer {
        path: PathBuf,
        buffer: usize,
        source_name: String,
        reason: String,
    },
    #[error("{}: image {image} ({source_name}) cannot be used: {reason}", .path.display())]
    Image {
        path: PathBuf,
        image: usize,
        source_name: String,
        reason: String,
    },
    #[error(
        "{}: {primitive}, vertex {vertex}: joint index {joint} is out of range, the skin has {joint_count} joints",
        .path.display()
    )]
    JointOutOfRange {
        path: PathBuf,
        primitive: String,
        vertex: usize,
        joint: u32,
        joint_count: usize,
    },
    #[error(
        "{}: {primitive}, vertex {vertex}: the skin weights sum to zero, so the vertex follows no joint",
        .path.display()
    )]
    ZeroWeights {
        path: PathBuf,
        primitive: String,
        vertex: usize,
    },
    #[error("{}: no animation named {name:?}; the file has: {available}", .path.display())]
    AnimationNotFound {
        path: PathBuf,
        name: String,
        available: String,
    },
    #[error(
        "{}: animation index {index} is out of range, the file has {count} animations",
        .path.display()
    )]
    AnimationIndexOutOfRange {
        path: PathBuf,
        index: usize,
        count: usize,
    },
    #[error("{}: malformed data: {reason}", .path.display())]
    Malformed { path: PathBuf, reason: String },
    #[error("{}: unsupported, it would render wrong: {feature}", .path.display())]
    Unsupported { path: PathBuf, feature: String },
}

/// Which animation of a file to play.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AnimationSelector {
    Name(String),
    Index(usize),
}

/// What the caller needs to know about one animation: its name and its time span (the union of its
/// channels' key ranges; before `start_secs` and after `end_secs` every channel holds its end value).
#[derive(Clone, Debug, PartialEq)]
pub struct AnimationInfo {
    pub name: Option<String>,
    pub start_secs: f32,
    pub end_secs: f32,
}

/// One primitive of one mesh instance after posing.
#[derive(Clone, Debug, PartialEq)]
pub struct PosedPrimitive {
    /// World space = `world_from_character` * model space; unit normals; CCW triangles.
    pub mesh: Mesh,
    /// Linear RGBA, as in the file.
    pub base_color_factor: [f32; 4],
    /// Index into [`CharacterAsset::textures`].
    pub texture: Option<usize>,
    /// "mesh name/primitive i", for messages.
    pub name: String,
}

/// A node's own transform as written in the file. Matrix nodes stay matrices unless an animation
/// targets them (the spec forbids that, but decomposing is the only sensible reading).
#[derive(Clone, Copy, Debug, PartialEq)]
enum LocalTransform {
    Trs {
        translation: Vec3,
        rotation: Quat,
        scale: Vec3,
    },
    Matrix(Mat4),
}

#[derive(Clone, Debug)]
struct Node {
    local: LocalTransform,
    children: Vec<usize>,
}

#[derive(Clone, Debug)]
struct Skin {
    /// Node index of every joint.
    joints: Vec<usize>,
    /// One per joint; identity when the file has none.
    inverse_bind: Vec<Mat4>,
}

/// Up to 8 joint influences of one vertex; unused slots have weight 0. Weights sum to 1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Influences {
    joints: [u16; 8],
    weights: [f32; 8],
}

/// One primitive as stored in the file, in model space (normals computed if absent, UVs zero if
/// absent), triangle lists only.
#[derive(Clone, Debug)]
struct Primitive {
    name: String,
    mesh: Mesh,
    /// Present when the primitive has JOINTS_0/WEIGHTS_0.
    influences: Option<Vec<Influences>>,
    base_color_factor: [f32; 4],
    texture: Option<usize>,
}

/// One primitive drawn by one node of the scene.
#[derive(Clone, Copy, Debug)]
struct DrawItem {
    node: usize,
    primitive: usize,
    skin: Option<usize>,
}

/// A loaded, validated character: geometry, skins, animations and textures of one glTF file.
#[derive(Clone, Debug)]
pub struct CharacterAsset {
    path: PathBuf,
    files: Vec<PathBuf>,
    nodes: Vec<Node>,
    /// Parents before children; every node exactly once.
    node_order: Vec<usize>,
    parents: Vec<Option<usize>>,
    skins: Vec<Skin>,
    primitives: Vec<Primitive>,
    draw_items: Vec<DrawItem>,
    animations: Vec<animation::Animation>,
    animation_infos: Vec<AnimationInfo>,
    textures: Vec<Texture>,
    warnings: Vec<String>,
}

impl CharacterAsset {
    /// Reads and validates a `.glb` or `.gltf` file and everything it refers to.
    pub fn load(path: &Path) -> Result<Self, CharacterError> {
        load::load(path)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every file read: the .gltf/.glb, external buffers, external images.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    pub fn animations(&self) -> &[AnimationInfo] {
        &self.animation_infos
    }

    /// The index of the selected animation, or an error that lists what the file has.
    pub fn resolve_animation(&self, selector: &AnimationSelector) -> Result<usize, CharacterError> {
        resolve_animation(&self.path, &self.animation_infos, selector)
    }

    pub fn textures(&self) -> &[Texture] {
        &self.textures
    }

    /// Things that were skipped or ignored while loading (points/lines primitives, morph-target
    /// animation channels, ...), one sentence each.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Vertices over all posed primitives (a mesh drawn by two nodes counts twice).
    pub fn vertex_count(&self) -> usize {
        self.draw_items
            .iter()
            .map(|item| self.primitives[item.primitive].mesh.vertex_count())
            .sum()
    }

    /// Sum over the posed vertices of their non-zero weights: the number of matrix blends one pose
    /// costs. A vertex of an unskinned mesh counts as one influence (one matrix is applied).
    pub fn influence_count(&self) -> usize {
        self.draw_items
            .iter()
            .map(|item| {
                let primitive = &self.primitives[item.primitive];
                match (item.skin, &primitive.influences) {
                    (Some(_), Some(influences)) => influences
                        .iter()
                        .map(|vertex| vertex.weights.iter().filter(|w| **w != 0.0).count())
                        .sum(),
                    _ => primitive.mesh.vertex_count(),
                }
            })
            .sum()
    }

    /// Joint and node matrices at `time_secs` of `animation` (None = rest pose from the nodes' own
    /// TRS). An index out of range also gives the rest pose; use [`Self::resolve_animation`] first.
    pub fn pose(&self, animation: Option<usize>, time_secs: f32) -> Pose {
        skinning::pose(
            self,
            animation.and_then(|i| self.animations.get(i)),
            time_secs,
        )
    }

    /// The bind pose: every joint's global matrix is `inverse(inverse_bind)`, so every joint matrix
    /// is (up to rounding) the identity and skinning reproduces the stored vertices. Nodes that are
    /// not joints keep their rest transform.
    pub fn bind_pose(&self) -> Pose {
        skinning::bind_pose(self)
    }

    /// Skinned/posed primitives for a pose, transformed by `world_from_character`.
    pub fn posed_primitives(&self, pose: &Pose, world_from_character: Mat4) -> Vec<PosedPrimitive> {
        skinning::posed_primitives(self, pose, world_from_character)
    }

    /// The primitives of every drawn mesh instance as stored in the file (model space, before any
    /// node transform or skinning; normals computed where the file has none), in the same order as
    /// [`Self::posed_primitives`] returns them.
    pub fn stored_primitives(&self) -> Vec<(&str, &Mesh)> {
        self.draw_items
            .iter()
            .map(|item| {
                let primitive = &self.primitives[item.primitive];
                (primitive.name.as_str(), &primitive.mesh)
            })
            .collect()
    }
}

/// The index of the animation `selector` names among a file's `infos`, or an error that lists
/// what the file has.
fn resolve_animation(
    path: &Path,
    infos: &[AnimationInfo],
    selector: &AnimationSelector,
) -> Result<usize, CharacterError> {
    match selector {
        AnimationSelector::Index(index) => {
            if *index < infos.len() {
                Ok(*index)
            } else {
                Err(CharacterError::AnimationIndexOutOfRange {
                    path: path.to_path_buf(),
                    index: *index,
                    count: infos.len(),
                })
            }
        }
        AnimationSelector::Name(name) => infos
            .iter()
            .position(|info| info.name.as_deref() == Some(name.as_str()))
            .ok_or_else(|| CharacterError::AnimationNotFound {
                path: path.to_path_buf(),
                name: name.clone(),
                available: animation_list(infos),
            }),
    }
}

/// "0: Survey, 1: Walk, 2: Run"; unnamed animations as "#i"; "(no animations)" when empty.
fn animation_list(infos: &[AnimationInfo]) -> String {
    if infos.is_empty() {
        return "(no animations)".to_string();
    }
    infos
        .iter()
        .enumerate()
        .map(|(index, info)| match &info.name {
            Some(name) => format!("{index}: {name:?}"),
            None => format!("#{index}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Throughput figure for `snell bench`: skins `asset` `repetitions` times (at least once), returns
/// vertex-influences per second (median over the repetitions). The pose is the middle of the first
/// animation, or the rest pose when there is none; posing itself is not timed.
pub fn skinning_throughput(asset: &CharacterAsset, repetitions: usize) -> f64 {
    let pose = match asset.animation_infos.first() {
        Some(info) => asset.pose(Some(0), 0.5 * (info.start_secs + info.end_secs)),
        None => asset.pose(None, 0.0),
    };
    let influences = asset.influence_count() as f64;
    let mut rates: Vec<f64> = (0..repetitions.max(1))
        .map(|_| {
            let start = Instant::now();
            let posed = asset.posed_primitives(&pose, Mat4::IDENTITY);
            let secs = start.elapsed().as_secs_f64();
            std::hint::black_box(posed);
            // A zero-length interval can only come from a coarse clock on a tiny asset; count it as
            // one nanosecond rather than reporting infinity.
            influences / secs.max(1e-9)
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    rates[rates.len() / 2]
}

/// Area-weighted smooth vertex normals: each triangle adds its (unnormalised) cross product to its
/// three vertices. Vertices on no or only degenerate triangles get +Y so normals stay unit.
fn smooth_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    for triangle in triangles {
        let [a, b, c] = triangle.map(|i| i as usize);
        let area_normal = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        sums[a] += area_normal;
        sums[b] += area_normal;
        sums[c] += area_normal;
    }
    sums.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_normals_are_area_weighted() {
        // Two triangles sharing vertex 0: a big one in the xy plane, (2,0,0)x(0,2,0) = (0,0,4), and a
        // small one in the xz plane, (1,0,0)x(0,0,1) = (0,-1,0). Vertex 0 gets normalize(0,-1,4).
        let positions = vec![
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let normals = smooth_normals(&positions, &[[0, 1, 2], [0, 3, 4]]);
        let expected = Vec3::new(0.0, -1.0, 4.0).normalize();
        assert!((normals[0] - expected).length() < 1e-6, "{:?}", normals[0]);
        assert!((normals[1] - Vec3::Z).length() < 1e-6);
        assert!((normals[4] + Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn degenerate_triangles_still_give_unit_normals() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::Z];
        let normals = smooth_normals(&positions, &[[0, 1, 2]]);
        assert_eq!(normals, vec![Vec3::Y; 4]);
    }
}
