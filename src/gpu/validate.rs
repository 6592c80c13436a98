//! What a frame's draw lists must satisfy before they reach the GPU: size, materials, textures,
//! whole triangles and indices in range.

use super::{GpuError, Renderer, MAX_MATERIALS};
use crate::draw::FrameDraw;

fn check_indices(list: &'static str, indices: &[u32], vertex_count: usize) -> Result<(), GpuError> {
    match indices
        .iter()
        .position(|&index| index as usize >= vertex_count)
    {
        Some(at) => Err(GpuError::IndexOutOfRange {
            list,
            index: at,
            value: indices[at],
            count: vertex_count,
        }),
        None => Ok(()),
    }
}

fn check_materials<'a>(
    list: &'static str,
    materials: impl Iterator<Item = u32> + 'a,
    material_count: usize,
) -> Result<(), GpuError> {
    for (index, material) in materials.enumerate() {
        if material as usize >= material_count {
            return Err(GpuError::IndexOutOfRange {
                list,
                index,
                value: material,
                count: material_count,
            });
        }
    }
    Ok(())
}

impl Renderer {
    pub(super) fn validate(
        &self,
        draw: &FrameDraw,
        width: u32,
        height: u32,
    ) -> Result<(), GpuError> {
        let max = self.context.device.limits().max_texture_dimension_2d;
        // A supersampled frame draws 2 width + 1 by 2 height + 1 points (super::resolve).
        let max = if self.supersample > 1 {
            (max - 1) / super::resolve::SUPERSAMPLE
        } else {
            max
        };
        if width == 0 || height == 0 || width > max || height > max {
            return Err(GpuError::BadSize { width, height, max });
        }
        if draw.materials.len() > MAX_MATERIALS {
            return Err(GpuError::TooManyMaterials {
                count: draw.materials.len(),
                max: MAX_MATERIALS,
            });
        }
        if let Some((material, texture)) = draw
            .materials
            .iter()
            .enumerate()
            .find(|(_, material)| material.texture >= self.texture_layers)
        {
            return Err(GpuError::TextureOutOfRange {
                material,
                texture: texture.texture,
                count: self.texture_layers,
            });
        }
        if !draw.under_vertices.len().is_multiple_of(3) {
            return Err(GpuError::PartialTriangle {
                count: draw.under_vertices.len(),
            });
        }
        check_indices(
            "above_indices",
            &draw.above_indices,
            draw.above_vertices.len(),
        )?;
        check_indices(
            "membrane_indices",
            &draw.membrane_indices,
            draw.membrane_vertices.len(),
        )?;
        let material_count = draw.materials.len();
        check_materials(
            "above_vertices[..].material",
            draw.above_vertices.iter().map(|v| v.material),
            material_count,
        )?;
        check_materials(
            "under_vertices[..].material",
            draw.under_vertices.iter().map(|v| v.material),
            material_count,
        )?;
        Ok(())
    }
}
