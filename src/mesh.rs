//! Shared geometry types that flow between stages: world-space triangle meshes, their materials
//! and textures. Produced by the scene stage (built-in primitives), consumed by refraction and GPU.

use glam::{Vec2, Vec3};

/// An indexed triangle mesh in world space (metres). Normals are unit and per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    /// Counter-clockwise seen from the side the normal points to.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
}

/// An 8-bit sRGB RGBA image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height * 4` bytes, sRGB-encoded colour, linear alpha.
    pub rgba8_srgb: Vec<u8>,
}

/// How a surface is shaded: a texture (index into the frame's texture list) times a linear tint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub texture: u32,
    pub tint_linear: Vec3,
}

/// One scene object after loading: its world-space mesh and its material.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub name: String,
    pub mesh: Mesh,
    pub material: Material,
}
