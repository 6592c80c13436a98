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

const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_CHUNK_JSON: u32 = 0x4E4F_534A;
const GLB_CHUNK_BIN: u32 = 0x004E_4942;
/// At most JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1: 8 influences per vertex.
const INFLUENCE_SETS: u32 = 2;

/// The nodes, each node's parent, and an order with parents before children.
type NodeHierarchy = (Vec<Node>, Vec<Option<usize>>, Vec<usize>);

/// What is carried through loading: the file (for messages), everything read, the warnings.
struct Loader {
    path: PathBuf,
    files: Vec<PathBuf>,
    warnings: Vec<String>,
    buffers: Vec<Vec<u8>>,
}

/// The parts of a file: the JSON text and, for GLB, the BIN chunk (possibly cut short) with a
/// note explaining the truncation for the buffer error that will follow.
struct Container<'a> {
    json: &'a [u8],
    bin: Option<&'a [u8]>,
    truncation_note: String,
}

pub(super) fn load(path: &Path) -> Result<CharacterAsset, CharacterError> {
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

fn read_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let word: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
    Some(u32::from_le_bytes(word))
}

/// Splits a GLB into its JSON and BIN chunks; anything not starting with the GLB magic is JSON.
/// A BIN chunk cut short by a truncated file is kept as far as it goes, so that the buffer check
/// can say which buffer is short and by how much.
fn split_container<'a>(path: &Path, bytes: &'a [u8]) -> Result<Container<'a>, CharacterError> {
    if !bytes.starts_with(GLB_MAGIC) {
        return Ok(Container {
            json: bytes,
            bin: None,
            truncation_note: String::new(),
        });
    }
    let not_gltf = |reason: String| CharacterError::NotGltf {
        path: path.to_path_buf(),
        reason,
    };
    let (Some(version), Some(declared_length), Some(json_length), Some(json_type)) = (
        read_u32(bytes, 4),
        read_u32(bytes, 8),
        read_u32(bytes, 12),
        read_u32(bytes, 16),
    ) else {
        return Err(not_gltf(format!(
            "GLB file of {} bytes is shorter than its 20-byte header",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(not_gltf(format!(
            "GLB container version {version}, only 2 is read"
        )));
    }
    if json_type != GLB_CHUNK_JSON {
        return Err(not_gltf(format!(
            "the first GLB chunk has type 0x{json_type:08X}, not JSON"
        )));
    }
    let truncation_note = if (declared_length as usize) > bytes.len() {
        format!(
            " (the file is {} bytes but its GLB header says {declared_length}: the file is truncated)",
            bytes.len()
        )
    } else {
        String::new()
    };
    let json_end = 20 + json_length as usize;
    let Some(json) = bytes.get(20..json_end) else {
        return Err(not_gltf(format!(
            "the GLB JSON chunk needs {json_length} bytes but the file ends first{truncation_note}"
        )));
    };
    let bin = match (read_u32(bytes, json_end), read_u32(bytes, json_end + 4)) {
        (Some(bin_length), Some(GLB_CHUNK_BIN)) => {
            let start = json_end + 8;
            let end = (start + bin_length as usize).min(bytes.len());
            Some(&bytes[start..end])
        }
        // A cut inside the BIN chunk header: the chunk was there but nothing of it survives.
        _ if !truncation_note.is_empty() => Some(&bytes[bytes.len()..]),
        _ => None,
    };
    Ok(Container {
        json,
        bin,
        truncation_note,
    })
}

/// Decodes the payload of a `data:...;base64,` URI.
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let Some((header, payload)) = uri.split_once(',') else {
        return Err("data URI without a ',' before its payload".to_string());
    };
    if !header.ends_with(";base64") {
        return Err(format!("data URI {header:?} is not base64-encoded"));
    }
    decode_base64(payload)
}

/// Standard base64 (RFC 4648, '+' and '/'), padding optional.
fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut accumulator: u32 = 0;
    let mut bits = 0;
    for (position, byte) in text.trim_end_matches('=').bytes().enumerate() {
        let value = match byte {
            b'A'..=b'Z' => byte - b'A',
            b'a'..=b'z' => byte - b'a' + 26,
            b'0'..=b'9' => byte - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => {
                return Err(format!(
                    "invalid base64 character {:?} at position {position}",
                    byte as char
                ))
            }
        };
        accumulator = (accumulator << 6) | u32::from(value);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((accumulator >> bits) as u8);
            accumulator &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

/// `%20` and friends; anything malformed is kept as written.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            if let Some(value) = uri
                .get(i + 1..i + 3)
                .and_then(|hex| u8::from_str_radix(hex, 16).ok())
            {
                out.push(value);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// A URI with a scheme (`http:`, `file:`, ...) rather than a path relative to the glTF file.
fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.len() > 1
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// How a buffer is named in messages: the GLB BIN chunk, an embedded data URI, or its file URI.
fn buffer_source_name(buffer: &gltf::Buffer) -> String {
    match buffer.source() {
        gltf::buffer::Source::Bin => "GLB BIN chunk".to_string(),
        gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
            "embedded data URI".to_string()
        }
        gltf::buffer::Source::Uri(uri) => uri.to_string(),
    }
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
    fn malformed(&self, reason: String) -> CharacterError {
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

    fn load_nodes(&self, document: &gltf::Document) -> Result<NodeHierarchy, CharacterError> {
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

    fn load_image(
        &mut self,
        image: &gltf::Image,
        buffers: &[Vec<u8>],
    ) -> Result<Texture, CharacterError> {
        let index = image.index();
        let (bytes, source_name) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                // In range: every view was checked against its buffer.
                let data =
                    &buffers[view.buffer().index()][view.offset()..view.offset() + view.length()];
                (
                    Ok(data.to_vec()),
                    format!("buffer view {}, {mime_type}", view.index()),
                )
            }
            gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                (decode_data_uri(uri), "embedded data URI".to_string())
            }
            gltf::image::Source::Uri { uri, .. } => (self.read_relative(uri), uri.to_string()),
        };
        let error = |reason: String, source_name: &str| CharacterError::Image {
            path: self.path.clone(),
            image: index,
            source_name: source_name.to_string(),
            reason,
        };
        let bytes = bytes.map_err(|reason| error(reason, &source_name))?;
        let rgba = crate::files::decode_image_rgba8(&bytes).map_err(|e| {
            error(
                format!("cannot decode (PNG and JPEG are read): {e}"),
                &source_name,
            )
        })?;
        let file_name = self
            .path
            .file_name()
            .map_or_else(String::new, |name| name.to_string_lossy().into_owned());
        Ok(Texture {
            name: match image.name() {
                Some(name) => format!("{file_name}/{name}"),
                None => format!("{file_name}/image {index}"),
            },
            width: rgba.width(),
            height: rgba.height(),
            rgba8_srgb: rgba.into_raw(),
        })
    }

    /// One primitive as triangle lists, or None (with a warning) for points and lines.
    fn load_primitive(
        &mut self,
        mesh: &gltf::Mesh,
        primitive: &gltf::Primitive,
        textures: &mut Vec<Texture>,
        texture_of_image: &mut HashMap<usize, usize>,
    ) -> Result<Option<Primitive>, CharacterError> {
        let mesh_name = mesh
            .name()
            .map_or_else(|| format!("mesh #{}", mesh.index()), str::to_string);
        let name = format!("{mesh_name}/primitive {}", primitive.index());
        let mode = primitive.mode();
        if matches!(
            mode,
            Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
        ) {
            self.warnings.push(format!(
                "{name}: {mode:?} primitive skipped (only triangles are drawn)"
            ));
            return Ok(None);
        }
        let buffers = std::mem::take(&mut self.buffers);
        let result =
            self.load_triangles(mesh, primitive, &name, &buffers, textures, texture_of_image);
        self.buffers = buffers;
        result.map(Some)
    }

    fn load_triangles(
        &mut self,
        mesh: &gltf::Mesh,
        primitive: &gltf::Primitive,
        name: &str,
        buffers: &[Vec<u8>],
        textures: &mut Vec<Texture>,
        texture_of_image: &mut HashMap<usize, usize>,
    ) -> Result<Primitive, CharacterError> {
        let reader = primitive.reader(|buffer| buffers.get(buffer.index()).map(Vec::as_slice));
        let unreadable =
            |loader: &Self, what: &str| loader.malformed(format!("{name}: {what} cannot be read"));

        let Some(position_accessor) = primitive.get(&Semantic::Positions) else {
            return Err(self.malformed(format!("{name} has no POSITION attribute")));
        };
        let positions = self.read_vec3(&position_accessor, name, "POSITION", || {
            reader.read_positions()
        })?;
        if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
            return Err(self.malformed(format!("{name}, vertex {vertex}: position is not finite")));
        }
        let vertex_count = positions.len();

        let indices: Vec<u32> = match primitive.indices() {
            Some(accessor) => {
                self.check_kind(
                    &accessor,
                    &format!("{name} indices"),
                    Dimensions::Scalar,
                    &[DataType::U8, DataType::U16, DataType::U32],
                    false,
                )?;
                let indices: Vec<u32> = reader
                    .read_indices()
                    .ok_or_else(|| unreadable(self, "indices"))?
                    .into_u32()
                    .collect();
                if let Some(k) = indices.iter().position(|&i| i as usize >= vertex_count) {
                    return Err(self.malformed(format!(
                        "{name}: index {k} is {} but the primitive has {vertex_count} vertices",
                        indices[k]
                    )));
                }
                indices
            }
            None => (0..vertex_count as u32).collect(),
        };
        let (triangles, leftover) = mode_triangles(primitive.mode(), &indices);
        if leftover > 0 {
            self.warnings.push(format!(
                "{name}: {} indices is not a multiple of 3, the last {leftover} ignored",
                indices.len()
            ));
        }

        let normals = match primitive.get(&Semantic::Normals) {
            Some(accessor) => {
                let normals =
                    self.read_vec3(&accessor, name, "NORMAL", || reader.read_normals())?;
                self.check_count(name, "NORMAL", normals.len(), vertex_count)?;
                if let Some(vertex) = normals.iter().position(|n| !n.is_finite()) {
                    return Err(
                        self.malformed(format!("{name}, vertex {vertex}: normal is not finite"))
                    );
                }
                // The spec asks for unit normals; exporters round. Zero ones become +Y.
                normals
                    .into_iter()
                    .map(|n| n.normalize_or(Vec3::Y))
                    .collect()
            }
            None => smooth_normals(&positions, &triangles),
        };

        let material = primitive.material();
        let pbr = material.pbr_metallic_roughness();
        let base_color_factor = pbr.base_color_factor();
        let (texture, uv_set) = match pbr.base_color_texture() {
            Some(info) => {
                let image = info.texture().source();
                let texture = match texture_of_image.get(&image.index()) {
                    Some(&texture) => texture,
                    None => {
                        let loaded = self.load_image(&image, buffers)?;
                        textures.push(loaded);
                        texture_of_image.insert(image.index(), textures.len() - 1);
                        textures.len() - 1
                    }
                };
                (Some(texture), info.tex_coord())
            }
            None => (None, 0),
        };
        let uvs = match primitive.get(&Semantic::TexCoords(uv_set)) {
            Some(accessor) => {
                let what = format!("{name} TEXCOORD_{uv_set}");
                self.check_kind(
                    &accessor,
                    &what,
                    Dimensions::Vec2,
                    &[DataType::F32, DataType::U8, DataType::U16],
                    true,
                )?;
                let uvs: Vec<Vec2> = reader
                    .read_tex_coords(uv_set)
                    .ok_or_else(|| unreadable(self, &what))?
                    .into_f32()
                    .map(Vec2::from)
                    .collect();
                self.check_count(name, &what, uvs.len(), vertex_count)?;
                uvs
            }
            None => {
                if texture.is_some() {
                    self.warnings.push(format!(
                        "{name}: textured but has no TEXCOORD_{uv_set}; texture coordinates are all zero"
                    ));
                }
                vec![Vec2::ZERO; vertex_count]
            }
        };

        if primitive.morph_targets().len() > 0 {
            let weights = mesh.weights().unwrap_or(&[]);
            if weights.iter().any(|&w| w != 0.0) {
                return Err(CharacterError::Unsupported {
                    path: self.path.clone(),
                    feature: format!(
                        "{name} has morph targets with non-zero default weights {weights:?}"
                    ),
                });
            }
            self.warnings.push(format!(
                "{name}: morph targets ignored (their default weights are zero)"
            ));
        }
        if primitive.get(&Semantic::Colors(0)).is_some() {
            self.warnings
                .push(format!("{name}: vertex colours (COLOR_0) ignored"));
        }

        let influences = self.load_influences(primitive, &reader, name, vertex_count)?;

        Ok(Primitive {
            name: name.to_string(),
            mesh: Mesh {
                positions,
                normals,
                uvs,
                triangles,
            },
            influences,
            base_color_factor,
            texture,
        })
    }

    /// JOINTS_0/WEIGHTS_0 (+ JOINTS_1/WEIGHTS_1), weights checked and normalised to sum 1.
    fn load_influences<'a, 's, F>(
        &self,
        primitive: &gltf::Primitive,
        reader: &gltf::mesh::Reader<'a, 's, F>,
        name: &str,
        vertex_count: usize,
    ) -> Result<Option<Vec<Influences>>, CharacterError>
    where
        F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
    {
        for (semantic, _) in primitive.attributes() {
            if let Semantic::Joints(set) | Semantic::Weights(set) = semantic {
                if set >= INFLUENCE_SETS {
                    return Err(CharacterError::Unsupported {
                        path: self.path.clone(),
                        feature: format!(
                            "{name} has JOINTS_{set}/WEIGHTS_{set}: more than 8 joint influences per vertex"
                        ),
                    });
                }
            }
        }
        let mut influences: Option<Vec<Influences>> = None;
        for set in 0..INFLUENCE_SETS {
            let joints = primitive.get(&Semantic::Joints(set));
            let weights = primitive.get(&Semantic::Weights(set));
            let (joints, weights) = match (joints, weights) {
                (None, None) => break,
                (Some(joints), Some(weights)) => (joints, weights),
                _ => {
                    return Err(self.malformed(format!(
                        "{name} has only one of JOINTS_{set} and WEIGHTS_{set}"
                    )))
                }
            };
            if set > 0 && influences.is_none() {
                return Err(self.malformed(format!("{name} has JOINTS_{set} but no JOINTS_0")));
            }
            self.check_kind(
                &joints,
                &format!("{name} JOINTS_{set}"),
                Dimensions::Vec4,
                &[DataType::U8, DataType::U16],
                false,
            )?;
            self.check_kind(
                &weights,
                &format!("{name} WEIGHTS_{set}"),
                Dimensions::Vec4,
                &[DataType::F32, DataType::U8, DataType::U16],
                true,
            )?;
            let unreadable =
                |what: &str| self.malformed(format!("{name}: {what}_{set} cannot be read"));
            let joint_values: Vec<[u16; 4]> = reader
                .read_joints(set)
                .ok_or_else(|| unreadable("JOINTS"))?
                .into_u16()
                .collect();
            let weight_values: Vec<[f32; 4]> = reader
                .read_weights(set)
                .ok_or_else(|| unreadable("WEIGHTS"))?
                .into_f32()
                .collect();
            self.check_count(
                name,
                &format!("JOINTS_{set}"),
                joint_values.len(),
                vertex_count,
            )?;
            self.check_count(
                name,
                &format!("WEIGHTS_{set}"),
                weight_values.len(),
                vertex_count,
            )?;
            let all = influences.get_or_insert_with(|| vec![Influences::default(); vertex_count]);
            let slot = 4 * set as usize;
            for (vertex, influence) in all.iter_mut().enumerate() {
                influence.joints[slot..slot + 4].copy_from_slice(&joint_values[vertex]);
                influence.weights[slot..slot + 4].copy_from_slice(&weight_values[vertex]);
            }
        }
        let Some(mut influences) = influences else {
            return Ok(None);
        };
        for (vertex, influence) in influences.iter_mut().enumerate() {
            if let Some(w) = influence
                .weights
                .iter()
                .find(|w| !w.is_finite() || **w < 0.0)
            {
                return Err(self.malformed(format!(
                    "{name}, vertex {vertex}: skin weight {w} is negative or not finite"
                )));
            }
            // Fixed left-to-right order: the sum, hence the normalised weights, never vary.
            let sum: f32 = influence.weights.iter().sum();
            if sum <= 0.0 {
                return Err(CharacterError::ZeroWeights {
                    path: self.path.clone(),
                    primitive: name.to_string(),
                    vertex,
                });
            }
            for (joint, weight) in influence
                .joints
                .iter_mut()
                .zip(influence.weights.iter_mut())
            {
                *weight /= sum;
                // A zero-weight slot never reaches a joint matrix; park its index at 0 so that
                // whatever the file wrote there can never index out of range.
                if *weight == 0.0 {
                    *joint = 0;
                }
            }
        }
        Ok(Some(influences))
    }

    /// Every joint index with a non-zero weight must name a joint of the skin that draws it.
    /// Zero-weight slots may hold anything (exporters leave garbage there); they are never read.
    fn check_joint_range(
        &self,
        primitive: &Primitive,
        influences: &[Influences],
        joint_count: usize,
    ) -> Result<(), CharacterError> {
        for (vertex, influence) in influences.iter().enumerate() {
            for (&joint, &weight) in influence.joints.iter().zip(&influence.weights) {
                if weight != 0.0 && usize::from(joint) >= joint_count {
                    return Err(CharacterError::JointOutOfRange {
                        path: self.path.clone(),
                        primitive: primitive.name.clone(),
                        vertex,
                        joint: u32::from(joint),
                        joint_count,
                    });
                }
            }
        }
        Ok(())
    }

    fn load_animations(
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

/// Triangle lists from a triangle mode (glTF spec 3.7.2.1): strips alternate winding so every
/// triangle keeps the orientation of the first; fans share vertex 0. Degenerate strip triangles
/// (repeated indices, used to stitch strips) are dropped. Also returns how many trailing indices
/// were left over (TRIANGLES with a count not a multiple of 3; always 0 for strips and fans).
fn mode_triangles(mode: Mode, indices: &[u32]) -> (Vec<[u32; 3]>, usize) {
    match mode {
        Mode::TriangleStrip => {
            let triangles = (0..indices.len().saturating_sub(2))
                .map(|i| {
                    if i % 2 == 0 {
                        [indices[i], indices[i + 1], indices[i + 2]]
                    } else {
                        [indices[i], indices[i + 2], indices[i + 1]]
                    }
                })
                .filter(|[a, b, c]| a != b && b != c && a != c)
                .collect();
            (triangles, 0)
        }
        Mode::TriangleFan => {
            let triangles = (1..indices.len().saturating_sub(1))
                .map(|i| [indices[i], indices[i + 1], indices[0]])
                .collect();
            (triangles, 0)
        }
        _ => {
            let chunks = indices.chunks_exact(3);
            let leftover = chunks.remainder().len();
            (chunks.map(|t| [t[0], t[1], t[2]]).collect(), leftover)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_strings() {
        assert_eq!(decode_base64("TWFu").unwrap(), b"Man");
        assert_eq!(decode_base64("TWE=").unwrap(), b"Ma");
        assert_eq!(decode_base64("TQ==").unwrap(), b"M");
        assert_eq!(decode_base64("").unwrap(), b"");
        assert!(decode_base64("TW*u").is_err());
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAEC").unwrap(),
            vec![0, 1, 2]
        );
        assert!(decode_data_uri("data:text/plain,hello").is_err());
    }

    #[test]
    fn strips_and_fans_become_ccw_lists() {
        // Strip 0 1 2 3 4: (0,1,2), (1,3,2), (2,3,4) — all with the first triangle's orientation.
        assert_eq!(
            mode_triangles(Mode::TriangleStrip, &[0, 1, 2, 3, 4]),
            (vec![[0, 1, 2], [1, 3, 2], [2, 3, 4]], 0)
        );
        // Fan 0 1 2 3: (1,2,0), (2,3,0).
        assert_eq!(
            mode_triangles(Mode::TriangleFan, &[0, 1, 2, 3]),
            (vec![[1, 2, 0], [2, 3, 0]], 0)
        );
        assert_eq!(
            mode_triangles(Mode::Triangles, &[0, 1, 2, 3]),
            (vec![[0, 1, 2]], 1)
        );
        assert_eq!(mode_triangles(Mode::TriangleStrip, &[0, 1]), (vec![], 0));
        // A repeated index: (1,2,2) and (2,2,3) are degenerate and dropped, the rest keep parity.
        assert_eq!(
            mode_triangles(Mode::TriangleStrip, &[0, 1, 2, 2, 3, 4, 5]),
            (vec![[0, 1, 2], [2, 4, 3], [3, 4, 5]], 0)
        );
    }

    #[test]
    fn uri_helpers() {
        assert_eq!(percent_decode("my%20model.bin"), "my model.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert!(has_scheme("http://example.com/a.bin"));
        assert!(!has_scheme("textures/a.png"));
        assert!(!has_scheme("a.bin"));
    }
}
