//! Posing and skinning: receives a loaded asset, an animation and a time (or an explicit [`Pose`])
//! and returns the world-space meshes. Node global matrices come from the animated local TRS,
//! joint matrices are `global(joint) * inverse_bind`, and skinned vertices are blended with linear
//! blend skinning: `M = sum_i w_i * world * joint_i`, position `M p`, normal `M^-T n` renormalised.
//! As the glTF spec requires, a skinned mesh ignores its own node's transform.
//!
//! Skinning runs on rayon, one vertex per work item with a fixed summation order inside the
//! vertex, so the output is the same bytes however the work is split between threads.

use glam::{Mat3, Mat4, Vec3};
use rayon::prelude::*;

use super::animation::{Animation, Sampled};
use super::{CharacterAsset, Influences, LocalTransform, PosedPrimitive};
use crate::mesh::Mesh;

/// The matrices of one instant of an animation.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// Model-space (character-space) matrix of every node, indexed like the file's nodes.
    pub node_global: Vec<Mat4>,
    /// Per skin, per joint: `node_global[joint] * inverse_bind[joint]`.
    pub joint_matrices: Vec<Vec<Mat4>>,
}

/// Vertices per rayon work item: small enough to share a 1,728-vertex fox between two cores,
/// large enough that the scheduling overhead stays well below the blending work.
const VERTICES_PER_TASK: usize = 256;

pub(super) fn local_matrix(local: &LocalTransform) -> Mat4 {
    match *local {
        LocalTransform::Trs {
            translation,
            rotation,
            scale,
        } => {
            // Keys and node rotations are validated non-zero at load; normalising here keeps a
            // nearly-unit quaternion from scaling the mesh.
            Mat4::from_scale_rotation_translation(scale, rotation.normalize(), translation)
        }
        LocalTransform::Matrix(matrix) => matrix,
    }
}

/// Applies an animated component to a node's local transform.
pub(super) fn apply(local: LocalTransform, sampled: Sampled) -> LocalTransform {
    let (mut translation, mut rotation, mut scale) = match local {
        LocalTransform::Trs {
            translation,
            rotation,
            scale,
        } => (translation, rotation, scale),
        LocalTransform::Matrix(matrix) => {
            let (scale, rotation, translation) = matrix.to_scale_rotation_translation();
            (translation, rotation, scale)
        }
    };
    match sampled {
        Sampled::Translation(t) => translation = t,
        Sampled::Rotation(r) => rotation = r,
        Sampled::Scale(s) => scale = s,
    }
    LocalTransform::Trs {
        translation,
        rotation,
        scale,
    }
}

fn node_globals(asset: &CharacterAsset, locals: &[LocalTransform]) -> Vec<Mat4> {
    let mut global = vec![Mat4::IDENTITY; locals.len()];
    // Parents come before children in `node_order`, so a parent's global is ready when needed.
    for &node in &asset.node_order {
        let local = local_matrix(&locals[node]);
        global[node] = match asset.parents[node] {
            Some(parent) => global[parent] * local,
            None => local,
        };
    }
    global
}

fn joint_matrices(asset: &CharacterAsset, node_global: &[Mat4]) -> Vec<Vec<Mat4>> {
    asset
        .skins
        .iter()
        .map(|skin| {
            skin.joints
                .iter()
                .zip(&skin.inverse_bind)
                .map(|(&joint, inverse_bind)| node_global[joint] * *inverse_bind)
                .collect()
        })
        .collect()
}

pub(super) fn pose(asset: &CharacterAsset, animation: Option<&Animation>, time_secs: f32) -> Pose {
    let mut locals: Vec<LocalTransform> = asset.nodes.iter().map(|node| node.local).collect();
    if let Some(animation) = animation {
        for channel in &animation.channels {
            locals[channel.node] = apply(locals[channel.node], channel.sample(time_secs));
        }
    }
    let node_global = node_globals(asset, &locals);
    let joint_matrices = joint_matrices(asset, &node_global);
    Pose {
        node_global,
        joint_matrices,
    }
}

/// The rest pose with every joint's global matrix replaced by `inverse(inverse_bind)`; the joint
/// matrices are computed once, from those.
pub(super) fn bind_pose(asset: &CharacterAsset) -> Pose {
    let rest: Vec<LocalTransform> = asset.nodes.iter().map(|node| node.local).collect();
    let mut node_global = node_globals(asset, &rest);
    for skin in &asset.skins {
        for (&joint, inverse_bind) in skin.joints.iter().zip(&skin.inverse_bind) {
            node_global[joint] = inverse_bind.inverse();
        }
    }
    let joint_matrices = joint_matrices(asset, &node_global);
    Pose {
        node_global,
        joint_matrices,
    }
}

/// `M^-T n` up to a positive factor, without dividing by the determinant: the columns of the
/// cofactor matrix are `c1 x c2`, `c2 x c0`, `c0 x c1` (= det * M^-T), and the sign of det restores
/// the direction for mirroring matrices. Stays defined for singular matrices (e.g. zero scale
/// along one axis), where the plain inverse does not.
fn normal_matrix(m: &Mat4) -> Mat3 {
    let c0 = m.x_axis.truncate();
    let c1 = m.y_axis.truncate();
    let c2 = m.z_axis.truncate();
    let cofactor = Mat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1));
    if c0.dot(c1.cross(c2)) < 0.0 {
        -cofactor
    } else {
        cofactor
    }
}

/// Blends the joint matrices of one vertex. Fixed slot order, so the result does not depend on
/// threads.
fn blended_matrix(influences: &Influences, world_joint: &[Mat4]) -> Mat4 {
    let mut blended = Mat4::ZERO;
    for (&joint, &weight) in influences.joints.iter().zip(&influences.weights) {
        if weight != 0.0 {
            blended += world_joint[usize::from(joint)] * weight;
        }
    }
    blended
}

/// Linear blend skinning of one primitive. `world_joint[j]` = world_from_character * joint matrix.
fn skin_vertices(
    mesh: &Mesh,
    influences: &[Influences],
    world_joint: &[Mat4],
) -> (Vec<Vec3>, Vec<Vec3>) {
    (0..mesh.positions.len())
        .into_par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|vertex| {
            let m = blended_matrix(&influences[vertex], world_joint);
            let normal = mesh.normals[vertex];
            (
                m.transform_point3(mesh.positions[vertex]),
                (normal_matrix(&m) * normal).normalize_or(normal),
            )
        })
        .unzip()
}

/// One matrix for every vertex (meshes without a skin).
fn transform_vertices(mesh: &Mesh, m: &Mat4) -> (Vec<Vec3>, Vec<Vec3>) {
    let normal_m = normal_matrix(m);
    (0..mesh.positions.len())
        .into_par_iter()
        .with_min_len(VERTICES_PER_TASK)
        .map(|vertex| {
            let normal = mesh.normals[vertex];
            (
                m.transform_point3(mesh.positions[vertex]),
                (normal_m * normal).normalize_or(normal),
            )
        })
        .unzip()
}

/// A mirroring transform turns counter-clockwise triangles clockwise; swapping two corners keeps
/// them counter-clockwise seen from the side the (correctly transformed) normals point to.
fn oriented_triangles(triangles: &[[u32; 3]], mirrored: bool) -> Vec<[u32; 3]> {
    if mirrored {
        triangles.iter().map(|&[a, b, c]| [a, c, b]).collect()
    } else {
        triangles.to_vec()
    }
}

pub(super) fn posed_primitives(
    asset: &CharacterAsset,
    pose: &Pose,
    world_from_character: Mat4,
) -> Vec<PosedPrimitive> {
    // Per skin, once per call however many primitives it draws: world_from_character * joint.
    // A pose built by hand with too few matrices gets identity joints rather than a panic; poses
    // from `CharacterAsset::pose` always have them all.
    let world_joints: Vec<Vec<Mat4>> = asset
        .skins
        .iter()
        .enumerate()
        .map(|(index, skin)| {
            let matrices = pose.joint_matrices.get(index);
            (0..skin.joints.len())
                .map(|j| {
                    let joint = matrices.and_then(|m| m.get(j)).copied();
                    world_from_character * joint.unwrap_or(Mat4::IDENTITY)
                })
                .collect()
        })
        .collect();
    let world_mirrored = world_from_character.determinant() < 0.0;
    asset
        .draw_items
        .iter()
        .map(|item| {
            let primitive = &asset.primitives[item.primitive];
            let stored = &primitive.mesh;
            let ((positions, normals), mirrored) = match (item.skin, &primitive.influences) {
                (Some(skin), Some(influences)) => (
                    skin_vertices(stored, influences, &world_joints[skin]),
                    world_mirrored,
                ),
                _ => {
                    let node = pose.node_global.get(item.node).copied();
                    let m = world_from_character * node.unwrap_or(Mat4::IDENTITY);
                    (transform_vertices(stored, &m), m.determinant() < 0.0)
                }
            };
            PosedPrimitive {
                mesh: Mesh {
                    positions,
                    normals,
                    uvs: stored.uvs.clone(),
                    triangles: oriented_triangles(&stored.triangles, mirrored),
                },
                base_color_factor: primitive.base_color_factor,
                texture: primitive.texture,
                name: primitive.name.clone(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec4};

    #[test]
    fn normal_matrix_is_inverse_transpose_direction() {
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, -3.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let expected = Mat3::from_mat4(m).inverse().transpose();
        for n in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(1.0, -2.0, 0.5).normalize(),
        ] {
            let a = (normal_matrix(&m) * n).normalize();
            let b = (expected * n).normalize();
            assert!((a - b).length() < 1e-6, "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn blend_of_two_translations_is_their_weighted_mean() {
        // 0.25 * translate(4,0,0) + 0.75 * translate(0,8,0) moves a point by (1, 6, 0).
        let joints = [
            Mat4::from_translation(Vec3::new(4.0, 0.0, 0.0)),
            Mat4::from_translation(Vec3::new(0.0, 8.0, 0.0)),
        ];
        let influences = Influences {
            joints: [0, 1, 0, 0, 0, 0, 0, 0],
            weights: [0.25, 0.75, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        let mesh = Mesh {
            positions: vec![Vec3::new(1.0, 1.0, 1.0)],
            normals: vec![Vec3::Z],
            uvs: vec![],
            triangles: vec![],
        };
        let (p, n) = skin_vertices(&mesh, &[influences], &joints);
        assert_eq!(p, vec![Vec3::new(2.0, 7.0, 1.0)]);
        assert_eq!(n, vec![Vec3::Z]);
        let m = blended_matrix(&influences, &joints);
        assert_eq!(m.w_axis, Vec4::new(1.0, 6.0, 0.0, 1.0));
    }

    #[test]
    fn mirroring_flips_winding() {
        assert_eq!(oriented_triangles(&[[0, 1, 2]], true), vec![[0, 2, 1]]);
        assert_eq!(oriented_triangles(&[[0, 1, 2]], false), vec![[0, 1, 2]]);
    }
}
