//! The frame stage's part of the resource estimate (see [`crate::scene::resources`]): the loaded
//! characters (posed vertices, how far they reach, materials), the textures, the ripple work of a
//! frame, and the image size of a render, each checked against its stated limit before the work
//! starts. Also the check of each frame's posed characters (finite, inside the world).

use super::characters::Character;
use super::{Method, SnellError};
use crate::mesh::{Object, Texture};
use crate::scene::limits::GEOMETRY_LIMIT_M;
use crate::scene::resources::{self, human_bytes, Estimate, MAX_OBJECTS, MEMORY_LIMIT_VARIABLE};
use crate::scene::Scene;

/// The scene's estimate with the loaded characters and the textures added, checked: vertex
/// count, reach and material count of each character (the ripple grid is bounded by its node
/// count in `scene::resources`: the spectral step is one pass a frame).
pub fn check_loaded(
    scene: &Scene,
    characters: &[Character],
    textures: &[Texture],
) -> Result<Estimate, SnellError> {
    let mut estimate = scene.resources;
    let mut counts = Vec::new();
    let mut drawn = scene.resources.objects as usize;
    for character in characters {
        let spec = &character.spec;
        let meshes = character.asset.stored_primitives();
        let vertices: u64 = meshes.iter().map(|(_, m)| m.positions.len() as u64).sum();
        let triangles: u64 = meshes.iter().map(|(_, m)| m.triangles.len() as u64).sum();
        counts.push((spec.file_source.clone(), vertices, triangles));
        // One object per drawn primitive (the scene's check counted each character as one).
        drawn += meshes.len().saturating_sub(1);
        if drawn > MAX_OBJECTS {
            return Err(spec
                .file_source
                .error(
                    format!(
                        "with this model's {} primitives the scene draws {drawn} objects, more than the \
                         {MAX_OBJECTS} the renderer's material table holds",
                        meshes.len()
                    ),
                    "use a model with fewer meshes and materials",
                )
                .into());
        }
        // How far the model reaches in its rest pose, scaled, from the farthest root-path key.
        let model_reach = character
            .asset
            .posed_primitives(&character.asset.bind_pose(), glam::Mat4::IDENTITY)
            .iter()
            .flat_map(|p| p.mesh.positions.iter().map(|v| v.length() as f64))
            .fold(0.0, f64::max)
            * spec.scale;
        let root_reach = spec
            .path
            .iter()
            .flat_map(|key| key.position_m.map(f64::abs))
            .fold(0.0, f64::max);
        let reach = model_reach + root_reach;
        if reach.is_nan() || reach > GEOMETRY_LIMIT_M {
            return Err(spec
                .file_source
                .error(
                    format!(
                        "at scale = {} the model reaches {reach:.3e} m from the origin (its rest pose is \
                         {:.3e} m across from its root), beyond the {GEOMETRY_LIMIT_M} m every vertex \
                         must stay within",
                        spec.scale,
                        2.0 * model_reach
                    ),
                    "set the character's scale to the file's units (e.g. scale = 0.01 for centimetres)",
                )
                .into());
        }
    }
    resources::check_characters(&mut estimate, &counts)?;
    estimate.objects = drawn as u64;
    // Textures as decoded, and again in the GPU's array (every layer at the largest size, with
    // mipmaps: 4/3).
    let (max_w, max_h) = textures.iter().fold((1u64, 1u64), |(w, h), t| {
        (w.max(t.width as u64), h.max(t.height as u64))
    });
    let decoded: u64 = textures.iter().map(|t| t.rgba8_srgb.len() as u64).sum();
    estimate.texture_bytes = decoded + (textures.len().max(2) as u64) * max_w * max_h * 4 * 4 / 3;
    Ok(estimate)
}

/// The whole estimate of a frame at `width` x `height` by `method` against the memory limit,
/// before any frame is made. The GPU methods draw, read back and write a large frame in strips
/// ([`crate::gpu::Renderer::render_strips`]), so their pixels cost a bounded strip plus a little
/// per pixel of the frame; the ray-traced methods hold the whole frame; and `frames_held` whole
/// frames are counted for the commands that keep frames ([`super::RenderJob::frames_held`]).
pub fn check_frame(
    estimate: &Estimate,
    method: Method,
    width: u32,
    height: u32,
    frames_held: u32,
) -> Result<Estimate, SnellError> {
    let mut estimate = *estimate;
    estimate.pixels = width as u64 * height as u64;
    estimate.in_strips = method.uses_gpu();
    estimate.frames_held = frames_held as u64;
    let limit = resources::memory_limit().map_err(SnellError::Argument)?;
    if estimate.bytes() > limit {
        return Err(SnellError::Argument(format!(
            "a frame of this scene at {width}x{height} needs about {} ({}), more than the memory \
             limit of {}; render smaller (--size), lighten the scene, or raise the limit with \
             {MEMORY_LIMIT_VARIABLE} (e.g. {MEMORY_LIMIT_VARIABLE}=16G)",
            human_bytes(estimate.bytes()),
            estimate.describe(),
            human_bytes(limit)
        )));
    }
    Ok(estimate)
}

/// Every vertex of `posed` (a frame's posed characters) finite and inside the world: an
/// animation that throws a vertex to 1e30 m is refused at its frame, before it reaches the
/// ripples or the refraction search.
pub fn check_posed(scene: &Scene, frame: u32, posed: &[Object]) -> Result<(), SnellError> {
    for object in posed {
        if let Some(vertex) = object
            .mesh
            .positions
            .iter()
            .find(|p| !p.is_finite() || p.abs().max_element() as f64 > GEOMETRY_LIMIT_M)
        {
            return Err(SnellError::Frame {
                scene: scene.path.clone(),
                frame,
                problem: format!(
                    "{} is posed with a vertex at {:?}, outside the {GEOMETRY_LIMIT_M} m every vertex must \
                     stay within; check the model's animation and the character's scale and path",
                    object.name,
                    vertex.to_array()
                ),
            });
        }
    }
    Ok(())
}
