//! Mesh building: images and textures, primitives into triangles (with strips and fans), skin
//! influences and their joint ranges.

use super::*;

impl Loader {
    pub(super) fn load_image(
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
    pub(super) fn load_primitive(
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

    pub(super) fn load_triangles(
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
    pub(super) fn load_influences<'a, 's, F>(
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
    pub(super) fn check_joint_range(
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
}

/// Triangle lists from a triangle mode (glTF spec 3.7.2.1): strips alternate winding so every
/// triangle keeps the orientation of the first; fans share vertex 0. Degenerate strip triangles
/// (repeated indices, used to stitch strips) are dropped. Also returns how many trailing indices
/// were left over (TRIANGLES with a count not a multiple of 3; always 0 for strips and fans).
pub(super) fn mode_triangles(mode: Mode, indices: &[u32]) -> (Vec<[u32; 3]>, usize) {
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
}
