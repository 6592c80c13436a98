//! A camera from a glTF file (Blender, Maya and most DCCs export them): receives the path of a
//! `.glb` or `.gltf`, optionally the name of the node carrying the camera and the animation that
//! moves it; returns a validated [`GltfCamera`] that gives the [`Camera`] at any time.
//!
//! The file is read and checked by the character loader's own front end (`load::open`: regular
//! file, size cap, container, JSON, indices, buffers, accessors), its nodes and animations by the
//! same code that poses characters, so a file that loads as a character loads as a camera.
//!
//! As the glTF 2.0 spec says (3.10): the camera looks down its node's local -Z with +Y up and +X
//! to the right; the view is the inverse of the node's global transform with the scale ignored.
//! The node's global transform is the product of its ancestors' and its own, each animated by the
//! chosen animation's translation, rotation and scale channels (appendix C interpolation, clamped
//! outside the keys). Only perspective cameras are read: `yfov`, `aspectRatio` (optional),
//! `znear` and `zfar` (optional: glTF's infinite projection, which snell clips at its default far
//! plane, [`crate::camera::FAR_M`]). Camera properties are not animated in core glTF (that needs
//! `KHR_animation_pointer`, which this reader does not implement).

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use super::animation::Channel;
use super::load;
use super::skinning::{apply, local_matrix};
use super::{AnimationSelector, CharacterError, LocalTransform};
use crate::camera::{Camera, FAR_M};

/// Why a glTF file cannot give the camera asked for. `File` is about the file as a whole (read,
/// parsed, checked); the others about the choice of camera node, projection or animation.
#[derive(Debug, thiserror::Error)]
pub enum GltfCameraError {
    #[error("{0}")]
    File(CharacterError),
    #[error("the file has no camera (no node carries one)")]
    NoCamera,
    #[error("the file has several cameras: {available}")]
    SeveralCameras { available: String },
    #[error("no node named {name:?} in the file; its camera nodes: {available}")]
    NodeNotFound { name: String, available: String },
    #[error("node {name:?} carries no camera; the file's camera nodes: {available}")]
    NodeHasNoCamera { name: String, available: String },
    #[error("the camera of node {node:?} is orthographic; snell renders perspective cameras only")]
    Orthographic { node: String },
    #[error("the camera of node {node:?} is unusable: {reason}")]
    BadProjection { node: String, reason: String },
    #[error("{0}")]
    Animation(CharacterError),
    #[error(
        "animation {animation} does not move node {node:?} or any of its parents, so it cannot animate the camera"
    )]
    AnimationMissesCamera { animation: String, node: String },
    #[error("several animations move the camera node {node:?} or its parents: {available}")]
    SeveralAnimations { node: String, available: String },
}

/// The perspective projection of a glTF camera, as the file states it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perspective {
    /// Vertical field of view, radians, in (0, pi).
    pub yfov_rad: f32,
    /// Width over height of the field of view; `None`: the viewport's.
    pub aspect_ratio: Option<f32>,
    pub znear_m: f32,
    /// `None`: infinite in glTF, [`FAR_M`] in snell.
    pub zfar_m: Option<f32>,
}

/// A validated camera of a glTF file: its node's chain of ancestors (root first) with their rest
/// transforms, the channels of the chosen animation that drive them, and the projection.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfCamera {
    path: PathBuf,
    files: Vec<PathBuf>,
    /// The camera node's name (or `#index` when it has none).
    pub node_name: String,
    /// The animation that moves the camera: its label (`0: "CameraAction"`) and time span in seconds.
    pub animation: Option<(String, [f32; 2])>,
    pub projection: Perspective,
    chain: Vec<LocalTransform>,
    /// (index into `chain`, channel), in file order (a later channel on a property wins).
    channels: Vec<(usize, Channel)>,
    pub warnings: Vec<String>,
}

/// The view a camera node's global transform gives, or why it gives none.
fn camera_from_world_transform(world: Mat4, projection: &Perspective) -> Result<Camera, String> {
    let eye = world.w_axis.truncate();
    let forward = -world.z_axis.truncate();
    let up = world.y_axis.truncate();
    let Some(forward) = forward.try_normalize() else {
        return Err("the node's global transform has zero scale along its view axis (-Z), so the camera looks nowhere".to_string());
    };
    let up = up.try_normalize().unwrap_or(Vec3::ZERO);
    if forward.cross(up).length() < 1e-4 {
        return Err(
            "the node's global transform has no up direction (its +Y axis is zero or along the view)"
                .to_string(),
        );
    }
    if !eye.is_finite() {
        return Err("the node's global position is not finite".to_string());
    }
    Ok(Camera {
        eye,
        target: eye + forward,
        up,
        fov_y_deg: projection.yfov_rad.to_degrees(),
        near_m: projection.znear_m,
        far_m: projection.zfar_m.unwrap_or(FAR_M),
    })
}

fn node_label(node: &gltf::Node) -> String {
    match node.name() {
        Some(name) => name.to_string(),
        None => format!("#{}", node.index()),
    }
}

impl GltfCamera {
    /// Reads `path` and picks its camera: the node named `node`, or the file's only camera node;
    /// moved by `animation`, or by the only animation with channels on the node or its ancestors
    /// (none: the camera stands still).
    pub fn load(
        path: &Path,
        node: Option<&str>,
        animation: Option<&AnimationSelector>,
    ) -> Result<GltfCamera, GltfCameraError> {
        let (mut loader, document) = load::open(path).map_err(GltfCameraError::File)?;
        let camera_nodes: Vec<gltf::Node> =
            document.nodes().filter(|n| n.camera().is_some()).collect();
        let available = || {
            if camera_nodes.is_empty() {
                "(none)".to_string()
            } else {
                camera_nodes
                    .iter()
                    .map(|n| format!("{:?}", node_label(n)))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        let chosen = match node {
            Some(name) => {
                let Some(found) = document.nodes().find(|n| n.name() == Some(name)) else {
                    return Err(GltfCameraError::NodeNotFound {
                        name: name.to_string(),
                        available: available(),
                    });
                };
                if found.camera().is_none() {
                    return Err(GltfCameraError::NodeHasNoCamera {
                        name: name.to_string(),
                        available: available(),
                    });
                }
                found
            }
            None => match camera_nodes.as_slice() {
                [] => return Err(GltfCameraError::NoCamera),
                [only] => only.clone(),
                _ => {
                    return Err(GltfCameraError::SeveralCameras {
                        available: available(),
                    })
                }
            },
        };
        let node_name = node_label(&chosen);
        let camera = chosen.camera().expect("chosen for its camera");
        let projection = match camera.projection() {
            gltf::camera::Projection::Orthographic(_) => {
                return Err(GltfCameraError::Orthographic { node: node_name })
            }
            gltf::camera::Projection::Perspective(p) => Perspective {
                yfov_rad: p.yfov(),
                aspect_ratio: p.aspect_ratio(),
                znear_m: p.znear(),
                zfar_m: p.zfar(),
            },
        };
        check_projection(&projection).map_err(|reason| GltfCameraError::BadProjection {
            node: node_name.clone(),
            reason,
        })?;

        let (nodes, parents, _) = loader
            .load_nodes(&document)
            .map_err(GltfCameraError::File)?;
        // The chain from the root down to the camera node (the hierarchy has no cycles: checked).
        let mut chain_nodes = vec![chosen.index()];
        while let Some(parent) = parents[*chain_nodes.last().expect("non-empty")] {
            chain_nodes.push(parent);
        }
        chain_nodes.reverse();
        let chain: Vec<LocalTransform> = chain_nodes.iter().map(|&n| nodes[n].local).collect();

        let (animations, infos) = loader
            .load_animations(&document)
            .map_err(GltfCameraError::File)?;
        let label = |index: usize| match &infos[index].name {
            Some(name) => format!("{index}: {name:?}"),
            None => format!("#{index}"),
        };
        let moves_camera = |index: usize| {
            animations[index]
                .channels
                .iter()
                .any(|c| chain_nodes.contains(&c.node))
        };
        let chosen_animation = match animation {
            Some(selector) => {
                let index = super::resolve_animation(&loader.path, &infos, selector)
                    .map_err(GltfCameraError::Animation)?;
                if !moves_camera(index) {
                    return Err(GltfCameraError::AnimationMissesCamera {
                        animation: label(index),
                        node: node_name,
                    });
                }
                Some(index)
            }
            None => {
                let moving: Vec<usize> =
                    (0..animations.len()).filter(|&a| moves_camera(a)).collect();
                match moving.as_slice() {
                    [] => None,
                    [only] => Some(*only),
                    _ => {
                        return Err(GltfCameraError::SeveralAnimations {
                            node: node_name,
                            available: moving
                                .iter()
                                .map(|&a| label(a))
                                .collect::<Vec<_>>()
                                .join(", "),
                        })
                    }
                }
            }
        };
        let channels = match chosen_animation {
            None => Vec::new(),
            Some(index) => animations[index]
                .channels
                .iter()
                .filter_map(|channel| {
                    let at = chain_nodes.iter().position(|&n| n == channel.node)?;
                    Some((at, channel.clone()))
                })
                .collect(),
        };
        let animation = chosen_animation.map(|index| {
            // The span of the channels that move the camera.
            let (start, end) = channels.iter().fold(
                (f32::INFINITY, f32::NEG_INFINITY),
                |(start, end), (_, c)| {
                    (
                        start.min(c.times_secs[0]),
                        end.max(c.times_secs[c.times_secs.len() - 1]),
                    )
                },
            );
            (label(index), [start, end])
        });
        Ok(GltfCamera {
            path: loader.path,
            files: loader.files,
            node_name,
            animation,
            projection,
            chain,
            channels,
            warnings: loader.warnings,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every file read: the .gltf/.glb and its external buffers (they are part of the frames'
    /// input hash).
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// The camera node's global transform at `time_secs` of the animation (clamped outside its
    /// keys; the rest pose when no animation moves the camera).
    pub fn world_from_node(&self, time_secs: f64) -> Mat4 {
        let mut locals = self.chain.clone();
        for (at, channel) in &self.channels {
            locals[*at] = apply(locals[*at], channel.sample(time_secs as f32));
        }
        locals
            .iter()
            .fold(Mat4::IDENTITY, |world, local| world * local_matrix(local))
    }

    /// The camera at `time_secs` of the animation, or why the node's transform gives no view
    /// there (zero scale, no up direction): scene validation asks this at every frame.
    pub fn try_camera_at(&self, time_secs: f64) -> Result<Camera, String> {
        camera_from_world_transform(self.world_from_node(time_secs), &self.projection)
    }

    /// The camera at `time_secs`; never NaN for a camera whose every frame passed
    /// [`Self::try_camera_at`] (elsewhere the [`Camera`]'s own fallbacks apply).
    pub fn camera_at(&self, time_secs: f64) -> Camera {
        let world = self.world_from_node(time_secs);
        camera_from_world_transform(world, &self.projection).unwrap_or_else(|_| {
            let eye = world.w_axis.truncate();
            Camera::looking_at(eye, eye + Vec3::Z, self.projection.yfov_rad.to_degrees())
        })
    }
}

/// glTF's own constraints (3.10.2 and the schema): 0 < yfov < pi, znear > 0, zfar > znear,
/// aspectRatio > 0, all finite.
fn check_projection(p: &Perspective) -> Result<(), String> {
    if !(p.yfov_rad.is_finite() && p.yfov_rad > 0.0 && p.yfov_rad < std::f32::consts::PI) {
        return Err(format!(
            "yfov is {} rad; it must be more than 0 and less than pi",
            p.yfov_rad
        ));
    }
    if !(p.znear_m.is_finite() && p.znear_m > 0.0) {
        return Err(format!("znear is {}; it must be more than 0", p.znear_m));
    }
    if let Some(zfar) = p.zfar_m {
        if !(zfar.is_finite() && zfar > p.znear_m) {
            return Err(format!(
                "zfar is {zfar}; it must be more than znear ({})",
                p.znear_m
            ));
        }
    }
    if let Some(aspect) = p.aspect_ratio {
        if !(aspect.is_finite() && aspect > 0.0) {
            return Err(format!("aspectRatio is {aspect}; it must be more than 0"));
        }
    }
    Ok(())
}
