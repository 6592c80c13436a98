//! Loading: receives the path of a `.glb` or `.gltf` file; returns a validated [`CharacterAsset`]
//! or the first problem found, as a [`CharacterError`] naming the file and the cause.
//!
//! The GLB container, external/embedded buffers and images are read here rather than by
//! `gltf::import`, so that a missing, truncated or undecodable buffer is reported as exactly that
//! (with the buffer, the byte counts and the file) instead of a generic import error. Every
//! accessor's byte range is checked against its buffer view and buffer before anything is read,
//! so the `gltf` readers below cannot run off the end of the data.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::animation::util::ReadOutputs;
use gltf::mesh::{Mode, Semantic};

use super::animation::{Animation, Channel, Interpolation, Property};
use super::{
    smooth_normals, AnimationInfo, CharacterAsset, CharacterError, DrawItem, Influences,
    LocalTransform, Node, Primitive, Skin,
};
use crate::mesh::{Mesh, Texture};

mod container;
mod mesh;

use container::{
    buffer_source_name, decode_data_uri, has_scheme, percent_decode, split_container, Container,
};

/// At most JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1: 8 influences per vertex.
const INFLUENCE_SETS: u32 = 2;

/// The nodes, each node's parent, and an order with parents before children.
pub(super) type NodeHierarchy = (Vec<Node>, Vec<Option<usize>>, Vec<usize>);

/// Reads and checks a glTF file as far as every reader needs it, whatever it is read for (a
/// character, a camera): the file regular and within the size cap, the container, the JSON, the
/// indices the `gltf` crate would panic on, the buffers read in full and every view and accessor
/// inside them. Returns the loader (the file, the files read, the warnings, the buffers) and the
/// document.
pub(super) fn open(path: &Path) -> Result<(Loader, gltf::Document), CharacterError> {
    let bytes = crate::files::read_regular(path, crate::files::MAX_ASSET_BYTES)
        .map_err(CharacterError::File)?;
    let container = split_container(path, &bytes)?;
    let not_gltf = |reason: String| CharacterError::NotGltf {
        path: path.to_path_buf(),
        reason,
    };
    let root = gltf::json::Root::from_slice(container.json)
        .map_err(|e| not_gltf(format!("broken JSON: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(not_gltf(format!(
            "asset.version is {:?}, only glTF 2.x is read",
            root.asset.version
        )));
    }
    if !root.extensions_required.is_empty() {
        return Err(CharacterError::Unsupported {
            path: path.to_path_buf(),
            feature: format!(
                "the file requires extension(s) {}, none of which this loader implements",
                root.extensions_required.join(", ")
            ),
        });
    }
    let used_extensions = root.extensions_used.clone();
    // gltf-json 1.4's validator indexes `accessors[POSITION]` before checking the index, so an
    // out-of-range POSITION would panic inside it: check that one first, and keep a backstop in
    // case another hook does the same.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            if let Some(index) = primitive.attributes.get(&position) {
                if index.value() >= root.accessors.len() {
                    return Err(not_gltf(format!(
                        "meshes[{m}].primitives[{p}].attributes.POSITION is accessor {} but the file has {}",
                        index.value(),
                        root.accessors.len()
                    )));
                }
            }
        }
    }
    // gltf-json 1.4's animation validator checks each channel's sampler but not its target, and
    // the `gltf` accessors unwrap both (the node by index, the path as a known property): a
    // target node out of range or an unknown path would panic when the animation is read.
    for (a, animation) in root.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            use gltf::json::validation::Validate;
            let mut problems = Vec::new();
            channel.target.validate(
                &root,
                || {
                    gltf::json::Path::new()
                        .field("animations")
                        .index(a)
                        .field("channels")
                        .index(c)
                        .field("target")
                },
                &mut |path, error| problems.push(format!("{}: {error}", path())),
            );
            if let Some(problem) = problems.into_iter().next() {
                let detail = match &channel.target.path {
                    gltf::json::validation::Checked::Invalid => {
                        " (path must be translation, rotation, scale or weights)".to_string()
                    }
                    _ => format!(
                        " (node {} of {} nodes)",
                        channel.target.node.value(),
                        root.nodes.len()
                    ),
                };
                return Err(not_gltf(format!("{problem}{detail}")));
            }
        }
    }
    let document = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        gltf::Document::from_json(root)
    }))
    .map_err(|_| not_gltf("the glTF validator failed on an out-of-range index".to_string()))?
    .map_err(|e| not_gltf(e.to_string()))?;

    let mut loader = Loader {
        path: path.to_path_buf(),
        files: vec![path.to_path_buf()],
        warnings: Vec::new(),
        buffers: Vec::new(),
    };
    for extension in used_extensions {
        loader.warnings.push(format!(
            "extension {extension} is used by the file but ignored (optional, so the file still renders)"
        ));
    }
    loader.load_buffers(&document, &container)?;
    loader.check_views_and_accessors(&document)?;

    Ok((loader, document))
}

/// What is carried through loading: the file (for messages), everything read, the warnings.
pub(super) struct Loader {
    pub(super) path: PathBuf,
    pub(super) files: Vec<PathBuf>,
    pub(super) warnings: Vec<String>,
    buffers: Vec<Vec<u8>>,
}

pub(super) fn load(path: &Path) -> Result<CharacterAsset, CharacterError> {
    let (mut loader, document) = open(path)?;
    let (nodes, parents, node_order) = loader.load_nodes(&document)?;
    let skins = loader.load_skins(&document)?;

    let mut textures = Vec::new();
    let mut texture_of_image: HashMap<usize, usize> = HashMap::new();
    let mut primitives: Vec<Primitive> = Vec::new();
    let mut primitives_of_mesh: HashMap<usize, Vec<usize>> = HashMap::new();
    let mut draw_items = Vec::new();

    // Draw the default scene (or the first one); a file without scenes draws every root node.
    let scene_roots: Vec<usize> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().map(|node| node.index()).collect(),
        None => (0..nodes.len()).filter(|&n| parents[n].is_none()).collect(),
    };
    let mut stack: Vec<usize> = scene_roots.into_iter().rev().collect();
    let gltf_nodes: Vec<gltf::Node> = document.nodes().collect();
    while let Some(node_index) = stack.pop() {
        let node = &gltf_nodes[node_index];
        stack.extend(nodes[node_index].children.iter().rev());
        let Some(mesh) = node.mesh() else { continue };
        if let std::collections::hash_map::Entry::Vacant(entry) =
            primitives_of_mesh.entry(mesh.index())
        {
            let mut indices = Vec::new();
            for primitive in mesh.primitives() {
                if let Some(loaded) = loader.load_primitive(
                    &mesh,
                    &primitive,
                    &mut textures,
                    &mut texture_of_image,
                )? {
                    indices.push(primitives.len());
                    primitives.push(loaded);
                }
            }
            entry.insert(indices);
        }
        let skin = node.skin().map(|skin| skin.index());
        for &primitive_index in &primitives_of_mesh[&mesh.index()] {
            let primitive = &primitives[primitive_index];
            match (skin, &primitive.influences) {
                (Some(skin), Some(influences)) => {
                    loader.check_joint_range(primitive, influences, skins[skin].joints.len())?;
                }
                (Some(skin), None) => {
                    return Err(loader.malformed(format!(
                        "{} is drawn by node {node_index} with skin {skin} but has no JOINTS_0/WEIGHTS_0",
                        primitive.name
                    )));
                }
                (None, Some(_)) => loader.warnings.push(format!(
                    "{} has joint weights but node {node_index} has no skin: drawn rigidly with the node's transform",
                    primitive.name
                )),
                (None, None) => {}
            }
            draw_items.push(DrawItem {
                node: node_index,
                primitive: primitive_index,
                skin,
            });
        }
    }

    let (animations, animation_infos) = loader.load_animations(&document)?;

    Ok(CharacterAsset {
        path: loader.path,
        files: loader.files,
        nodes,
        node_order,
        parents,
        skins,
        primitives,
        draw_items,
        animations,
        animation_infos,
        textures,
        warnings: loader.warnings,
    })
}

fn dimensions_name(dimensions: Dimensions) -> &'static str {
    match dimensions {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

impl Loader {
    pub(super) fn malformed(&self, reason: String) -> CharacterError {
        CharacterError::Malformed {
            path: self.path.clone(),
            reason,
        }
    }

    /// Resolves a relative URI against the glTF file's folder, reads it and records it.
    fn read_relative(&mut self, uri: &str) -> Result<Vec<u8>, String> {
        if has_scheme(uri) {
            return Err(format!(
                "URI {uri:?} is not a path relative to the glTF file (only relative files and data: URIs are read)"
            ));
        }
        let base = self.path.parent().unwrap_or(Path::new(""));
        let file = base.join(percent_decode(uri));
        let bytes = crate::files::read_regular(&file, crate::files::MAX_ASSET_BYTES)
            .map_err(|e| e.to_string())?;
        self.files.push(file);
        Ok(bytes)
    }

    fn load_buffers(
        &mut self,
        document: &gltf::Document,
        container: &Container,
    ) -> Result<(), CharacterError> {
        for buffer in document.buffers() {
            let index = buffer.index();
            let source_name = buffer_source_name(&buffer);
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => match container.bin {
                    Some(bin) => bin.to_vec(),
                    None => {
                        return Err(CharacterError::MissingBuffer {
                            path: self.path.clone(),
                            buffer: index,
                            source_name,
                            reason: "the file has no BIN chunk".to_string(),
                        })
                    }
                },
                gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => decode_data_uri(uri)
                    .map_err(|reason| CharacterError::UndecodableBuffer {
                        path: self.path.clone(),
                        buffer: index,
                        source_name: source_name.clone(),
                        reason,
                    })?,
                gltf::buffer::Source::Uri(uri) => {
                    self.read_relative(uri)
                        .map_err(|reason| CharacterError::MissingBuffer {
                            path: self.path.clone(),
                            buffer: index,
                            source_name: source_name.clone(),
                            reason,
                        })?
                }
            };
            if data.len() < buffer.length() {
                let note = match buffer.source() {
                    gltf::buffer::Source::Bin => container.truncation_note.as_str(),
                    gltf::buffer::Source::Uri(_) => "",
                };
                return Err(CharacterError::TruncatedBuffer {
                    path: self.path.clone(),
                    buffer: index,
                    source_name,
                    reason: format!(
                        "it has {} bytes but its byteLength is {}{note}",
                        data.len(),
                        buffer.length()
                    ),
                });
            }
            self.buffers.push(data);
        }
        Ok(())
    }

    /// Every buffer view inside its buffer, every accessor (and sparse part) inside its view.
    fn check_views_and_accessors(&self, document: &gltf::Document) -> Result<(), CharacterError> {
        for view in document.views() {
            let buffer = view.buffer();
            let available = self.buffers[buffer.index()].len();
            let end = view.offset().checked_add(view.length());
            if end.is_none_or(|end| end > available) {
                return Err(CharacterError::TruncatedBuffer {
                    path: self.path.clone(),
                    buffer: buffer.index(),
                    source_name: buffer_source_name(&buffer),
                    reason: format!(
                        "buffer view {} needs bytes {}..{} but the buffer has {available}",
                        view.index(),
                        view.offset(),
                        view.offset().saturating_add(view.length())
                    ),
                });
            }
        }
        for accessor in document.accessors() {
            let label = match accessor.name() {
                Some(name) => format!("accessor {} ({name:?})", accessor.index()),
                None => format!("accessor {}", accessor.index()),
            };
            if accessor.count() == 0 {
                return Err(
                    self.malformed(format!("{label} has count 0 (glTF requires at least 1)"))
                );
            }
            let element_size = accessor.size();
            let check = |view: gltf::buffer::View,
                         offset: usize,
                         count: usize,
                         size: usize,
                         part: &str| {
                let stride = view.stride().unwrap_or(size);
                let needed = (count - 1)
                    .checked_mul(stride)
                    .and_then(|n| n.checked_add(offset))
                    .and_then(|n| n.checked_add(size));
                match needed {
                    Some(needed) if needed <= view.length() => Ok(()),
                    _ => Err(self.malformed(format!(
                        "{label}{part} needs {} bytes of buffer view {} (offset {offset}, stride {stride}, {count} elements of {size} bytes) but the view is {} bytes long",
                        needed.map_or_else(|| "more than usize::MAX".to_string(), |n| n.to_string()),
                        view.index(),
                        view.length()
                    ))),
                }
            };
            if let Some(view) = accessor.view() {
                check(view, accessor.offset(), accessor.count(), element_size, "")?;
            }
            if let Some(sparse) = accessor.sparse() {
                let indices = sparse.indices();
                check(
                    indices.view(),
                    indices.offset(),
                    sparse.count(),
                    indices.index_type().size(),
                    " (sparse indices)",
                )?;
                let values = sparse.values();
                check(
                    values.view(),
                    values.offset(),
                    sparse.count(),
                    element_size,
                    " (sparse values)",
                )?;
            } else if accessor.view().is_none() {
                return Err(CharacterError::Unsupported {
                    path: self.path.clone(),
                    feature: format!(
                        "{label} has neither a buffer view nor sparse data (implicit zeros)"
                    ),
                });
            }
        }
        Ok(())
    }

    /// Checks an accessor's element type before a typed reader is used on it (a mismatch would
    /// make the reader reinterpret bytes).
    fn check_kind(
        &self,
        accessor: &gltf::Accessor,
        what: &str,
        dimensions: Dimensions,
        data_types: &[DataType],
        integers_normalized: bool,
    ) -> Result<(), CharacterError> {
        let data_type = accessor.data_type();
        let needs_normalized = integers_normalized && data_type != DataType::F32;
        if accessor.dimensions() != dimensions
            || !data_types.contains(&data_type)
            || (needs_normalized && !accessor.normalized())
        {
            let expected: Vec<String> = data_types.iter().map(|t| format!("{t:?}")).collect();
            return Err(self.malformed(format!(
                "{what} (accessor {}) is {} of {data_type:?}{}, expected {} of {}{}",
                accessor.index(),
                dimensions_name(accessor.dimensions()),
                if accessor.normalized() {
                    " (normalized)"
                } else {
                    ""
                },
                dimensions_name(dimensions),
                expected.join("/"),
                if needs_normalized {
                    " (integers normalized)"
                } else {
                    ""
                },
            )));
        }
        Ok(())
    }

    /// A float VEC3 attribute (POSITION, NORMAL) of primitive `name`: its type is checked before
    /// `read` runs the typed reader on it.
    fn read_vec3<I: Iterator<Item = [f32; 3]>>(
        &self,
        accessor: &gltf::Accessor,
        name: &str,
        semantic: &str,
        read: impl FnOnce() -> Option<I>,
    ) -> Result<Vec<Vec3>, CharacterError> {
        self.check_kind(
            accessor,
            &format!("{name} {semantic}"),
            Dimensions::Vec3,
            &[DataType::F32],
            false,
        )?;
        let values =
            read().ok_or_else(|| self.malformed(format!("{name}: {semantic} cannot be read")))?;
        Ok(values.map(Vec3::from).collect())
    }

    /// Every vertex attribute of primitive `name` has one element per POSITION.
    fn check_count(
        &self,
        name: &str,
        what: &str,
        count: usize,
        vertex_count: usize,
    ) -> Result<(), CharacterError> {
        if count == vertex_count {
            Ok(())
        } else {
            Err(self.malformed(format!(
                "{name}: {what} has {count} elements but POSITION has {vertex_count}"
            )))
        }
    }

    pub(super) fn load_nodes(
        &self,
        document: &gltf::Document,
    ) -> Result<NodeHierarchy, CharacterError> {
        let mut nodes = Vec::new();
        let mut parents: Vec<Option<usize>> = vec![None; document.nodes().len()];
        for node in document.nodes() {
            let local = match node.transform() {
                gltf::scene::Transform::Matrix { matrix } => {
                    let matrix = Mat4::from_cols_array_2d(&matrix);
                    if !matrix.is_finite() {
                        return Err(self
                            .malformed(format!("node {} has a non-finite matrix", node.index())));
                    }
                    LocalTransform::Matrix(matrix)
                }
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => {
                    let translation = Vec3::from(translation);
                    let rotation = Quat::from_array(rotation);
                    let scale = Vec3::from(scale);
                    if !translation.is_finite() || !rotation.is_finite() || !scale.is_finite() {
                        return Err(
                            self.malformed(format!("node {} has a non-finite TRS", node.index()))
                        );
                    }
                    if rotation.length() < 1e-6 {
                        return Err(self.malformed(format!(
                            "node {} has a zero rotation quaternion",
                            node.index()
                        )));
                    }
                    LocalTransform::Trs {
                        translation,
                        rotation,
                        scale,
                    }
                }
            };
            let children: Vec<usize> = node.children().map(|child| child.index()).collect();
            for &child in &children {
                if let Some(other) = parents[child] {
                    return Err(self.malformed(format!(
                        "node {child} is a child of both node {other} and node {}",
                        node.index()
                    )));
                }
                parents[child] = Some(node.index());
            }
            nodes.push(Node { local, children });
        }
        // Parents before children: depth-first from every root. Nodes on a cycle have a parent
        // and are never reached, which the length check catches.
        let mut order = Vec::with_capacity(nodes.len());
        let mut stack: Vec<usize> = (0..nodes.len())
            .filter(|&n| parents[n].is_none())
            .rev()
            .collect();
        while let Some(node) = stack.pop() {
            order.push(node);
            stack.extend(nodes[node].children.iter().rev());
        }
        if order.len() != nodes.len() {
            return Err(self.malformed("the node hierarchy contains a cycle".to_string()));
        }
        Ok((nodes, parents, order))
    }

    fn load_skins(&self, document: &gltf::Document) -> Result<Vec<Skin>, CharacterError> {
        let mut skins = Vec::new();
        for skin in document.skins() {
            let joints: Vec<usize> = skin.joints().map(|joint| joint.index()).collect();
            if joints.is_empty() {
                return Err(self.malformed(format!("skin {} has no joints", skin.index())));
            }
            if joints.len() > usize::from(u16::MAX) + 1 {
                return Err(CharacterError::Unsupported {
                    path: self.path.clone(),
                    feature: format!(
                        "skin {} has {} joints, more than 65536",
                        skin.index(),
                        joints.len()
                    ),
                });
            }
            let inverse_bind = match skin.inverse_bind_matrices() {
                None => vec![Mat4::IDENTITY; joints.len()],
                Some(accessor) => {
                    let what = format!("inverseBindMatrices of skin {}", skin.index());
                    self.check_kind(&accessor, &what, Dimensions::Mat4, &[DataType::F32], false)?;
                    let reader =
                        skin.reader(|buffer| self.buffers.get(buffer.index()).map(Vec::as_slice));
                    let matrices: Vec<Mat4> = reader
                        .read_inverse_bind_matrices()
                        .ok_or_else(|| self.malformed(format!("{what}: data cannot be read")))?
                        .map(|m| Mat4::from_cols_array_2d(&m))
                        .collect();
                    if matrices.len() < joints.len() {
                        return Err(self.malformed(format!(
                            "{what} has {} matrices for {} joints",
                            matrices.len(),
                            joints.len()
                        )));
                    }
                    if let Some(j) = matrices.iter().position(|m| !m.is_finite()) {
                        return Err(self.malformed(format!("{what}: matrix {j} is not finite")));
                    }
                    matrices[..joints.len()].to_vec()
                }
            };
            skins.push(Skin {
                joints,
                inverse_bind,
            });
        }
        Ok(skins)
    }

    pub(super) fn load_animations(
        &mut self,
        document: &gltf::Document,
    ) -> Result<(Vec<Animation>, Vec<AnimationInfo>), CharacterError> {
        let mut animations = Vec::new();
        let mut infos = Vec::new();
        for animation in document.animations() {
            let label = match animation.name() {
                Some(name) => format!("animation {} ({name:?})", animation.index()),
                None => format!("animation #{}", animation.index()),
            };
            let mut channels = Vec::new();
            let mut start_secs = f32::INFINITY;
            let mut end_secs = f32::NEG_INFINITY;
            for channel in animation.channels() {
                let what = format!("{label} channel {}", channel.index());
                let property = match channel.target().property() {
                    gltf::animation::Property::Translation => Property::Translation,
                    gltf::animation::Property::Rotation => Property::Rotation,
                    gltf::animation::Property::Scale => Property::Scale,
                    gltf::animation::Property::MorphTargetWeights => {
                        self.warnings
                            .push(format!("{what}: morph-target weights channel ignored"));
                        continue;
                    }
                };
                let sampler = channel.sampler();
                let interpolation = match sampler.interpolation() {
                    gltf::animation::Interpolation::Step => Interpolation::Step,
                    gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                self.check_kind(
                    &sampler.input(),
                    &format!("{what} input"),
                    Dimensions::Scalar,
                    &[DataType::F32],
                    false,
                )?;
                let (output_dimensions, output_types): (Dimensions, &[DataType]) = match property {
                    Property::Rotation => (
                        Dimensions::Vec4,
                        &[
                            DataType::F32,
                            DataType::I8,
                            DataType::U8,
                            DataType::I16,
                            DataType::U16,
                        ],
                    ),
                    _ => (Dimensions::Vec3, &[DataType::F32]),
                };
                self.check_kind(
                    &sampler.output(),
                    &format!("{what} output"),
                    output_dimensions,
                    output_types,
                    true,
                )?;
                let reader =
                    channel.reader(|buffer| self.buffers.get(buffer.index()).map(Vec::as_slice));
                let unreadable =
                    |part: &str| self.malformed(format!("{what}: {part} cannot be read"));
                let times_secs: Vec<f32> = reader
                    .read_inputs()
                    .ok_or_else(|| unreadable("input"))?
                    .collect();
                let values: Vec<Vec4> = match reader
                    .read_outputs()
                    .ok_or_else(|| unreadable("output"))?
                {
                    ReadOutputs::Translations(values) | ReadOutputs::Scales(values) => {
                        values.map(|v| Vec3::from(v).extend(0.0)).collect()
                    }
                    ReadOutputs::Rotations(values) => values.into_f32().map(Vec4::from).collect(),
                    ReadOutputs::MorphTargetWeights(_) => continue,
                };
                if let Some(k) = times_secs.iter().position(|t| !t.is_finite()) {
                    return Err(self.malformed(format!("{what}: key time {k} is not finite")));
                }
                if let Some(k) = times_secs.windows(2).position(|pair| pair[1] < pair[0]) {
                    return Err(self.malformed(format!(
                        "{what}: key times decrease from {} s (key {k}) to {} s",
                        times_secs[k],
                        times_secs[k + 1]
                    )));
                }
                let per_key = if interpolation == Interpolation::CubicSpline {
                    3
                } else {
                    1
                };
                if values.len() != per_key * times_secs.len() {
                    return Err(self.malformed(format!(
                        "{what}: {} output values for {} keys, {interpolation:?} needs {}",
                        values.len(),
                        times_secs.len(),
                        per_key * times_secs.len()
                    )));
                }
                if let Some(k) = values.iter().position(|v| !v.is_finite()) {
                    return Err(self.malformed(format!("{what}: output value {k} is not finite")));
                }
                if property == Property::Rotation {
                    let middle = if per_key == 3 { 1 } else { 0 };
                    let zero = values
                        .iter()
                        .skip(middle)
                        .step_by(per_key)
                        .position(|q| q.length() < 1e-6);
                    if let Some(k) = zero {
                        return Err(self
                            .malformed(format!("{what}: rotation key {k} is a zero quaternion")));
                    }
                }
                // Non-empty: accessor counts are at least 1.
                start_secs = start_secs.min(times_secs[0]);
                end_secs = end_secs.max(times_secs[times_secs.len() - 1]);
                channels.push(Channel {
                    node: channel.target().node().index(),
                    property,
                    interpolation,
                    times_secs,
                    values,
                });
            }
            if channels.is_empty() {
                start_secs = 0.0;
                end_secs = 0.0;
            }
            infos.push(AnimationInfo {
                name: animation.name().map(str::to_string),
                start_secs,
                end_secs,
            });
            animations.push(Animation { channels });
        }
        Ok((animations, infos))
    }
}
