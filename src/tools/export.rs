//! `snell export`: receives a scene and a frame; writes that frame's world-space geometry — the
//! water membrane, every object, the characters posed at that instant — and its camera, so other
//! renderers and DCC tools can check or reuse snell's frames.
//!
//! Files in the output directory (each written atomically):
//! - OBJ (default): `<scene>.<frame>.obj` with one `o` per scene object (the membrane first, as
//!   `water`; then the objects in the frame's order, which is their material / object-id order),
//!   positions, texture coordinates and normals; `<scene>.<frame>.mtl` with one material per
//!   object (its tint as `Kd`, its texture as `map_Kd`); the textures as
//!   `textures/texture_<k>.png`. Texture coordinates are OBJ's (origin at the image's bottom-left):
//!   `vt u (1 - v)` of snell's `(u, v)` (top-left origin, as wgpu samples); textures repeat.
//! - PLY (`--format ply`): `<scene>.<frame>.<k>_<object>.ply` per object (ASCII, `x y z nx ny nz
//!   s t`, texture named by a `comment TextureFile` line as MeshLab reads it), same order and names.
//! - `camera.json`: eye, target, up, vertical field of view in degrees, image size, near/far and
//!   the matrices (column-major, as glam and the EXR header store them).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use super::{check_frame, ToolError};
use crate::camera::Camera;
use crate::frame::RenderJob;
use crate::mesh::{Mesh, Object};
use crate::output::{check_writable, ensure_output_dir, save_png_atomic, write_atomically};
use crate::water::Membrane;

/// The geometry file format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExportFormat {
    #[default]
    Obj,
    Ply,
}

impl ExportFormat {
    pub fn parse(text: &str) -> Result<Self, ToolError> {
        match text.trim().to_ascii_lowercase().as_str() {
            "obj" => Ok(ExportFormat::Obj),
            "ply" => Ok(ExportFormat::Ply),
            _ => Err(crate::frame::SnellError::Argument(format!(
                "--format {text:?}: choose obj (one file, an object per scene object, with .mtl and PNG textures) or ply (one file per object)"
            ))
            .into()),
        }
    }
}

/// The camera as `camera.json` holds it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraExport {
    pub scene: String,
    pub frame: u32,
    pub time_secs: f64,
    pub eye: [f32; 3],
    pub target: [f32; 3],
    pub up: [f32; 3],
    pub fov_y_deg: f32,
    pub width: u32,
    pub height: u32,
    pub near_m: f32,
    pub far_m: f32,
    /// World -> snell's right-handed camera space (looking down -Z), column-major.
    pub view_from_world: [f32; 16],
    /// World -> clip space (wgpu's: depth in [0, 1], y up), column-major.
    pub clip_from_world: [f32; 16],
    pub conventions: String,
}

impl CameraExport {
    pub fn new(scene: &str, frame: u32, time_secs: f64, camera: &Camera, size: (u32, u32)) -> Self {
        CameraExport {
            scene: scene.to_string(),
            frame,
            time_secs,
            eye: camera.eye.to_array(),
            target: camera.target.to_array(),
            up: camera.up.to_array(),
            fov_y_deg: camera.fov_y_deg,
            width: size.0,
            height: size.1,
            near_m: camera.near_m,
            far_m: camera.far_m,
            view_from_world: camera.view_from_world().to_cols_array(),
            clip_from_world: camera.clip_from_world(size.0, size.1).to_cols_array(),
            conventions: "world space in metres, y up, right-handed; the camera looks from eye to \
                          target; matrices column-major (translation in elements 12-14); pixel \
                          (x right, y down) centres at +0.5"
                .to_string(),
        }
    }
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSummary {
    pub files: Vec<PathBuf>,
    /// Objects exported, the membrane included.
    pub objects: usize,
    pub vertices: usize,
    pub triangles: usize,
}

/// One mesh to write: the membrane or a scene object.
struct ExportMesh<'a> {
    name: String,
    positions: &'a [glam::Vec3],
    normals: &'a [glam::Vec3],
    /// snell's (u, v), top-left origin.
    uvs: std::borrow::Cow<'a, [glam::Vec2]>,
    triangles: &'a [[u32; 3]],
    /// Index into the job's textures, `None` for the membrane.
    texture: Option<u32>,
    tint_linear: glam::Vec3,
}

/// The membrane's texture coordinates: its grid's (x, z) extent mapped to [0, 1].
fn membrane_uvs(membrane: &Membrane) -> Vec<glam::Vec2> {
    let grid = &membrane.grid;
    let (width, depth) = (grid.max_x - grid.min_x, grid.max_z - grid.min_z);
    membrane
        .positions
        .iter()
        .map(|p| {
            glam::Vec2::new(
                ((p.x as f64 - grid.min_x) / width) as f32,
                ((p.z as f64 - grid.min_z) / depth) as f32,
            )
        })
        .collect()
}

fn object_mesh(object: &Object) -> ExportMesh<'_> {
    let Mesh {
        positions,
        normals,
        uvs,
        triangles,
    } = &object.mesh;
    ExportMesh {
        name: object.name.clone(),
        positions,
        normals,
        uvs: std::borrow::Cow::Borrowed(uvs),
        triangles,
        texture: Some(object.material.texture),
        tint_linear: object.material.tint_linear,
    }
}

/// Names usable as OBJ object, material and file names: no spaces or separators, unique.
fn unique_names(names: impl Iterator<Item = String>) -> Vec<String> {
    let mut used = std::collections::HashSet::new();
    names
        .map(|name| {
            let clean: String = name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            let clean = if clean.is_empty() {
                "object".to_string()
            } else {
                clean
            };
            let mut candidate = clean.clone();
            let mut k = 2;
            while !used.insert(candidate.clone()) {
                candidate = format!("{clean}.{k}");
                k += 1;
            }
            candidate
        })
        .collect()
}

/// Writes `frame` of `job` into `out_dir` (see the module documentation) at image size `size`
/// (for the camera's aspect).
pub fn export_frame(
    job: &RenderJob,
    frame: u32,
    out_dir: &Path,
    format: ExportFormat,
    size: (u32, u32),
) -> Result<ExportSummary, ToolError> {
    check_frame(job, frame)?;
    ensure_output_dir(out_dir)?;
    check_writable(out_dir)?;
    let mut stage_secs = Default::default();
    let water = job.frame_water(frame, &mut stage_secs)?;
    let membrane_uv = membrane_uvs(&water.membrane);
    let mut meshes = vec![ExportMesh {
        name: "water".to_string(),
        positions: &water.membrane.positions,
        normals: &water.membrane.normals,
        uvs: std::borrow::Cow::Owned(membrane_uv),
        triangles: &water.membrane.triangles,
        texture: None,
        tint_linear: glam::Vec3::ONE,
    }];
    meshes.extend(water.objects.iter().map(object_mesh));
    let names = unique_names(meshes.iter().map(|m| m.name.clone()));
    for (mesh, name) in meshes.iter_mut().zip(names) {
        mesh.name = name;
    }

    let stem = format!("{}.{:04}", job.scene_name(), frame);
    let mut files = Vec::new();
    // Textures the objects use, written once each.
    let mut texture_files = std::collections::BTreeMap::new();
    for texture in meshes.iter().filter_map(|m| m.texture) {
        if texture_files.contains_key(&texture) {
            continue;
        }
        let Some(source) = job.textures.get(texture as usize) else {
            continue;
        };
        let relative = format!("textures/texture_{texture}.png");
        let image =
            image::RgbaImage::from_raw(source.width, source.height, source.rgba8_srgb.clone())
                .ok_or_else(|| {
                    crate::frame::SnellError::Argument(format!(
                        "texture {} has {} bytes for {}x{} pixels",
                        source.name,
                        source.rgba8_srgb.len(),
                        source.width,
                        source.height
                    ))
                })?;
        let path = out_dir.join(&relative);
        save_png_atomic(&path, &image)?;
        files.push(path);
        texture_files.insert(texture, relative);
    }

    match format {
        ExportFormat::Obj => {
            let mtl_name = format!("{stem}.mtl");
            let (obj, mtl) = obj_and_mtl(job, frame, &meshes, &mtl_name, &texture_files);
            for (name, contents) in [(format!("{stem}.obj"), obj), (mtl_name, mtl)] {
                let path = out_dir.join(name);
                write_text(&path, &contents)?;
                files.push(path);
            }
        }
        ExportFormat::Ply => {
            for (index, mesh) in meshes.iter().enumerate() {
                let path = out_dir.join(format!("{stem}.{index}_{}.ply", mesh.name));
                let texture = mesh.texture.and_then(|t| texture_files.get(&t));
                write_text(&path, &ply(mesh, texture.map(String::as_str)))?;
                files.push(path);
            }
        }
    }

    let camera = CameraExport::new(
        job.scene_name(),
        frame,
        water.time_secs,
        &water.camera,
        size,
    );
    let path = out_dir.join("camera.json");
    write_text(
        &path,
        &(serde_json::to_string_pretty(&camera).expect("camera serialises") + "\n"),
    )?;
    files.push(path);

    Ok(ExportSummary {
        files,
        objects: meshes.len(),
        vertices: meshes.iter().map(|m| m.positions.len()).sum(),
        triangles: meshes.iter().map(|m| m.triangles.len()).sum(),
    })
}

fn write_text(path: &Path, contents: &str) -> Result<(), ToolError> {
    Ok(write_atomically(path, |file| {
        let mut writer = std::io::BufWriter::new(file);
        writer
            .write_all(contents.as_bytes())
            .and_then(|()| writer.flush())
            .map_err(|error| error.to_string())
    })?)
}

fn obj_and_mtl(
    job: &RenderJob,
    frame: u32,
    meshes: &[ExportMesh],
    mtl_name: &str,
    texture_files: &std::collections::BTreeMap<u32, String>,
) -> (String, String) {
    let header = format!(
        "# snell {} export of {} ({}), frame {frame}: world space, metres, y up\n",
        crate::VERSION,
        job.scene_name(),
        job.scene.path.display()
    );
    let mut obj = header.clone();
    let mut mtl = header;
    let _ = writeln!(obj, "mtllib {mtl_name}");
    // OBJ indices are 1-based and global across objects.
    let mut base = 1usize;
    for mesh in meshes {
        let _ = writeln!(obj, "o {}\nusemtl {}", mesh.name, mesh.name);
        for p in mesh.positions {
            let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
        }
        for i in 0..mesh.positions.len() {
            let uv = mesh.uvs.get(i).copied().unwrap_or_default();
            let _ = writeln!(obj, "vt {} {}", uv.x, 1.0 - uv.y);
        }
        for i in 0..mesh.positions.len() {
            let n = mesh.normals.get(i).copied().unwrap_or(glam::Vec3::Y);
            let _ = writeln!(obj, "vn {} {} {}", n.x, n.y, n.z);
        }
        for triangle in mesh.triangles {
            let [a, b, c] = triangle.map(|i| i as usize + base);
            let _ = writeln!(obj, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
        }
        base += mesh.positions.len();

        let t = mesh.tint_linear;
        let _ = writeln!(mtl, "\nnewmtl {}\nKd {} {} {}", mesh.name, t.x, t.y, t.z);
        match mesh.texture.and_then(|texture| texture_files.get(&texture)) {
            Some(file) => {
                let _ = writeln!(mtl, "map_Kd {file}");
            }
            None if mesh.texture.is_none() => {
                // The water: a clear refracting surface.
                let _ = writeln!(mtl, "d 0.3\nNi {}", job.scene.water.n_below);
            }
            None => {}
        }
    }
    (obj, mtl)
}

fn ply(mesh: &ExportMesh, texture: Option<&str>) -> String {
    let mut text =
        String::from("ply\nformat ascii 1.0\ncomment snell export, world space, metres, y up\n");
    if let Some(file) = texture {
        let _ = writeln!(text, "comment TextureFile {file}");
    }
    let _ = writeln!(
        text,
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    for (i, p) in mesh.positions.iter().enumerate() {
        let n = mesh.normals.get(i).copied().unwrap_or(glam::Vec3::Y);
        let uv = mesh.uvs.get(i).copied().unwrap_or_default();
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {} {}",
            p.x,
            p.y,
            p.z,
            n.x,
            n.y,
            n.z,
            uv.x,
            1.0 - uv.y
        );
    }
    for [a, b, c] in mesh.triangles {
        let _ = writeln!(text, "3 {a} {b} {c}");
    }
    text
}
