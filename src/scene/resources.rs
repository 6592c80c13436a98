//! The resource estimate of a scene: what one frame needs (membrane cells, wave samples, ripple
//! nodes and steps, tessellated vertices and triangles, textures, pixels, memory), computed before
//! any of it is built, and the stated limits it must keep. A scene over a limit is an error at the
//! key that causes it, naming the number and the limit, so a typo (a 300 m box at 1 cm spacing, a
//! water extent of 1e12 m) is refused in milliseconds instead of exhausting memory minutes later.
//!
//! The estimate comes in three steps, as the numbers become known: the scene file alone
//! ([`check_scene`], run by validation), the loaded characters ([`check_characters`]), and the
//! image size and method of a render ([`Estimate::bytes`] against [`memory_limit`]). Its memory
//! figures are per-item costs with a margin (a membrane cell, a vertex, a triangle, a pixel, a
//! ripple node, plus a fixed base for the process and GPU driver); they are estimates, not
//! measurements of every scene, and are meant to refuse what would exhaust memory, not to budget
//! closely.

use super::error::{KeyPath, SourceMap};
use super::limits::GEOMETRY_LIMIT_M;
use super::primitives::{box_counts, pool_counts, quad_counts, sphere_counts, PoolDims};
use super::{ObjectSpec, SceneError, ShapeSpec, WaterSpec};

/// Membrane cells (2048 x 2048); about 3.4 GB of refraction cells and search structure.
pub const MAX_MEMBRANE_CELLS: u64 = 1 << 22;
/// Height waves in the sum.
pub const MAX_WAVES: usize = 256;
/// Wave evaluations a frame (membrane vertices times waves).
pub const MAX_WAVE_SAMPLES: u64 = 1 << 30;
/// Ripple grid nodes (2048 x 2048).
pub const MAX_RIPPLE_NODES: u64 = 1 << 22;
/// Vertices of the built scene (static objects and characters together).
pub const MAX_VERTICES: u64 = 4_000_000;
/// Drawn objects (a pool counts three): the GPU's material table.
pub const MAX_OBJECTS: usize = crate::gpu::MAX_MATERIALS;

/// The default memory limit of a render, when `SNELL_MAX_MEMORY` does not set one.
pub const DEFAULT_MEMORY_LIMIT_BYTES: u64 = 8 << 30;
/// The environment variable that sets the memory limit: bytes, or a number with K, M, G or T
/// (powers of 1024; `MiB` and `GB` read alike), e.g. `SNELL_MAX_MEMORY=2G`.
pub const MEMORY_LIMIT_VARIABLE: &str = "SNELL_MAX_MEMORY";

const BASE_BYTES: u64 = 320 << 20;
const BYTES_PER_CELL: u64 = 800;
const BYTES_PER_VERTEX: u64 = 1000;
const BYTES_PER_TRIANGLE: u64 = 600;
/// A pixel of a frame held whole (the ray-traced methods: the traced layers with their coverage,
/// the EXR's samples).
const BYTES_PER_PIXEL: u64 = 300;
/// A pixel of a frame rendered in strips, beyond its strip: the PNG's 4 bytes when asked for, with
/// a margin.
const BYTES_PER_STREAMED_PIXEL: u64 = 8;
/// Pixels of the largest strip: the renderer's readback budget (256 MiB) over the 100 bytes a
/// supersampled pixel takes there (68, and 32 of coverage: [`crate::gpu::Renderer::strip_rows`]).
const MAX_STRIP_PIXELS: u64 = (256 << 20) / 100;
/// A pixel of a strip: its targets and readback on the device (about 210 bytes, in host memory
/// on Mesa's CPU drivers), a supersampled frame's points (four a pixel, 76 bytes each), the strips
/// in flight to the writer (104 bytes each, up to four) and their EXR samples and chunks.
const BYTES_PER_STRIP_PIXEL: u64 = 1100;
const BYTES_PER_RIPPLE_NODE: u64 = 64;
/// A pixel of a frame kept whole ([`crate::draw::RenderedFrame`]: 104 bytes of layers) with a
/// margin for what is derived from it (a comparison's maps, the preview's encoded images).
const BYTES_PER_HELD_PIXEL: u64 = 140;

/// `SNELL_MAX_MEMORY` parsed, or the default; an unreadable value is an error naming it.
pub fn memory_limit() -> Result<u64, String> {
    match std::env::var(MEMORY_LIMIT_VARIABLE) {
        Err(_) => Ok(DEFAULT_MEMORY_LIMIT_BYTES),
        Ok(text) => parse_bytes(&text).ok_or_else(|| {
            format!(
                "{MEMORY_LIMIT_VARIABLE}={text:?} is not an amount of memory; write bytes or a number \
                 with K, M, G or T, e.g. {MEMORY_LIMIT_VARIABLE}=4G"
            )
        }),
    }
}

/// `1536`, `512M`, `2G`, `1.5GiB`, `8gb`.
fn parse_bytes(text: &str) -> Option<u64> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let number: f64 = number.parse().ok()?;
    let unit = unit.trim().to_ascii_lowercase();
    let scale: u64 = match unit.trim_end_matches("ib").trim_end_matches('b') {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return None,
    };
    let bytes = number * scale as f64;
    (1.0..1e19).contains(&bytes).then_some(bytes as u64)
}

/// `3.4 GiB`, `512 MiB`.
pub fn human_bytes(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
    } else {
        format!("{:.0} MiB", (bytes as f64 / (1u64 << 20) as f64).max(1.0))
    }
}

/// What one frame of a scene needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    pub membrane_cells: u64,
    pub wave_samples: u64,
    pub ripple_nodes: u64,
    pub vertices: u64,
    pub triangles: u64,
    /// Bytes of decoded textures (added once the textures are built).
    pub texture_bytes: u64,
    /// Pixels of the image (0 until the size is known).
    pub pixels: u64,
    /// Whether the frame is drawn and written in strips (the GPU methods), so that only a strip
    /// of it is held at a time.
    pub in_strips: bool,
    /// Whole frames of this size the command keeps in memory at once besides its strips: the
    /// frames `snell chart` and `snell stability` compare and the frames the preview caches (0
    /// for a render, which streams every strip to the file).
    pub frames_held: u64,
    /// Objects drawn (a pool counts three, a character one per primitive once loaded).
    pub objects: u64,
}

impl Estimate {
    /// The memory a frame needs, bytes.
    pub fn bytes(&self) -> u64 {
        BASE_BYTES
            .saturating_add(self.membrane_cells.saturating_mul(BYTES_PER_CELL))
            .saturating_add(self.ripple_nodes.saturating_mul(BYTES_PER_RIPPLE_NODE))
            .saturating_add(self.vertices.saturating_mul(BYTES_PER_VERTEX))
            .saturating_add(self.triangles.saturating_mul(BYTES_PER_TRIANGLE))
            .saturating_add(self.texture_bytes)
            .saturating_add(self.pixel_bytes())
    }

    /// The memory the image itself needs: a strip's and a little per pixel when it is drawn in
    /// strips, every pixel's otherwise; and the whole frames the command keeps.
    fn pixel_bytes(&self) -> u64 {
        let held = self
            .pixels
            .saturating_mul(BYTES_PER_HELD_PIXEL)
            .saturating_mul(self.frames_held);
        let drawn = if self.in_strips {
            let strip = self.pixels.min(MAX_STRIP_PIXELS);
            strip
                .saturating_mul(BYTES_PER_STRIP_PIXEL)
                .saturating_add(self.pixels.saturating_mul(BYTES_PER_STREAMED_PIXEL))
        } else {
            self.pixels.saturating_mul(BYTES_PER_PIXEL)
        };
        drawn.saturating_add(held)
    }

    /// One line for `snell info`.
    pub fn describe(&self) -> String {
        format!(
            "{} membrane cells, {} wave samples, {} ripple nodes, {} vertices, {} triangles: about {}{}",
            self.membrane_cells,
            self.wave_samples,
            self.ripple_nodes,
            self.vertices,
            self.triangles,
            human_bytes(self.bytes()),
            if self.pixels > 0 {
                format!(" at {} pixels", self.pixels)
            } else {
                String::new()
            }
        )
    }
}

/// The vertices and triangles an object tessellates into, and how far from the origin it
/// reaches along any axis.
pub(crate) fn object_extent(object: &ObjectSpec, water: &WaterSpec) -> ((u64, u64), f64) {
    let scale = glam::DVec3::from(object.scale);
    let reach_from = |radius: f64| {
        object
            .translate_m
            .iter()
            .map(|t| t.abs() + radius)
            .fold(0.0, f64::max)
    };
    match &object.shape {
        ShapeSpec::Box { size_m } => {
            let size = glam::DVec3::from(*size_m) * scale;
            (
                box_counts(size, object.max_edge_m),
                reach_from(size.length() / 2.0),
            )
        }
        ShapeSpec::Quad { size_m } => {
            let size = [size_m[0] * scale.x, size_m[1] * scale.z];
            (
                quad_counts(size, object.max_edge_m),
                reach_from(size[0].hypot(size[1]) / 2.0),
            )
        }
        ShapeSpec::Sphere { radius_m } => (
            sphere_counts(*radius_m, object.max_edge_m / scale.max_element()),
            reach_from(radius_m * scale.max_element()),
        ),
        ShapeSpec::Pool {
            depth_m,
            coping_height_m,
            deck_width_m,
            ..
        } => {
            let dims = PoolDims {
                min_xz: water.min_xz,
                max_xz: water.max_xz,
                water_level_m: water.level_m,
                depth_m: *depth_m,
                coping_height_m: *coping_height_m,
                deck_width_m: *deck_width_m,
            };
            let reach = water
                .min_xz
                .iter()
                .chain(&water.max_xz)
                .map(|v| v.abs() + deck_width_m)
                .chain([
                    (water.level_m - depth_m).abs(),
                    (water.level_m + coping_height_m).abs(),
                ])
                .fold(0.0, f64::max);
            (pool_counts(&dims, object.max_edge_m), reach)
        }
    }
}

fn objects_of(object: &ObjectSpec) -> usize {
    match object.shape {
        ShapeSpec::Pool { .. } => 3,
        _ => 1,
    }
}

/// The scene file's part of the estimate, checked against the limits: errors point at the key
/// that causes them (`water.resolution`, an object's `max_edge_m`, ...). Runs at validation.
pub(crate) fn check_scene(
    water: &WaterSpec,
    objects: &[ObjectSpec],
    object_paths: &[KeyPath],
    characters: usize,
    map: &SourceMap<'_>,
) -> Result<Estimate, SceneError> {
    let water_path = KeyPath::root().key("water");
    let [cells_x, cells_z] = water.resolution.map(u64::from);
    let membrane_cells = cells_x * cells_z;
    if membrane_cells > MAX_MEMBRANE_CELLS {
        return Err(map.error(
            &water_path.key("resolution"),
            format!(
                "{cells_x} x {cells_z} = {membrane_cells} membrane cells, more than the {MAX_MEMBRANE_CELLS} \
                 (2048 x 2048) a frame may refract (each cell costs about {BYTES_PER_CELL} bytes)"
            ),
            "use fewer cells, e.g. resolution = [1024, 512]",
        ));
    }
    if water.waves.len() > MAX_WAVES {
        return Err(map.error(
            &water_path.key("wave").index(MAX_WAVES),
            format!(
                "the water has {} waves, more than the {MAX_WAVES} a wave sum may have",
                water.waves.len()
            ),
            "merge or remove waves",
        ));
    }
    let wave_samples = (cells_x + 1) * (cells_z + 1) * water.waves.len() as u64;
    if wave_samples > MAX_WAVE_SAMPLES {
        return Err(map.error(
            &water_path.key("wave"),
            format!(
                "{} waves over {} membrane vertices are {wave_samples} wave evaluations a frame, more \
                 than {MAX_WAVE_SAMPLES}",
                water.waves.len(),
                (cells_x + 1) * (cells_z + 1)
            ),
            "use fewer waves or fewer membrane cells",
        ));
    }
    let ripple_nodes = if water.ripples.enabled {
        water.ripples.nodes[0] as u64 * water.ripples.nodes[1] as u64
    } else {
        0
    };
    if ripple_nodes > MAX_RIPPLE_NODES {
        return Err(map.error(
            &water_path.key("ripples").key("resolution"),
            format!(
                "{} x {} = {ripple_nodes} ripple nodes, more than the {MAX_RIPPLE_NODES} (2048 x 2048) a \
                 ripple grid may have",
                water.ripples.nodes[0], water.ripples.nodes[1]
            ),
            "use fewer nodes, keeping the water's proportions",
        ));
    }
    let drawn = objects.iter().map(objects_of).sum::<usize>() + characters;
    if drawn > MAX_OBJECTS {
        return Err(map.error(
            &KeyPath::root().key("object"),
            format!(
                "the scene draws {drawn} objects (a pool counts three, a character one), more than the \
                 {MAX_OBJECTS} the renderer's material table holds"
            ),
            "merge objects or split the scene",
        ));
    }
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for (object, path) in objects.iter().zip(object_paths) {
        let ((object_vertices, object_triangles), reach) = object_extent(object, water);
        if reach.is_nan() || reach > GEOMETRY_LIMIT_M {
            let key = match object.shape {
                ShapeSpec::Pool { .. } => "deck_width_m",
                _ => "scale",
            };
            return Err(map.error(
                &path.key(key),
                format!(
                    "{} reaches {reach:.0} m from the origin, beyond the {GEOMETRY_LIMIT_M} m every vertex \
                     must stay within (f32 positions lose millimetres beyond)",
                    object.name
                ),
                "make it smaller or move it closer to the origin",
            ));
        }
        if object_vertices > MAX_VERTICES {
            return Err(map.error(
                &path.key("max_edge_m"),
                format!(
                    "{} tessellates into {object_vertices} vertices at a spacing of {} m, more than the \
                     {MAX_VERTICES} a scene may have",
                    object.name, object.max_edge_m
                ),
                "raise max_edge_m (here or at the top of the file) or make the object smaller",
            ));
        }
        vertices += object_vertices;
        triangles += object_triangles;
        if vertices > MAX_VERTICES {
            return Err(map.error(
                &path.key("max_edge_m"),
                format!(
                    "with {} the scene's objects tessellate into {vertices} vertices, more than the \
                     {MAX_VERTICES} a scene may have",
                    object.name
                ),
                "raise max_edge_m or remove objects",
            ));
        }
    }
    let estimate = Estimate {
        membrane_cells,
        wave_samples,
        ripple_nodes,
        vertices,
        triangles,
        texture_bytes: 0,
        pixels: 0,
        in_strips: false,
        frames_held: 0,
        objects: drawn as u64,
    };
    // The scene alone (no image yet) must fit the memory limit too.
    if let Ok(limit) = memory_limit() {
        if estimate.bytes() > limit {
            let at = if membrane_cells * BYTES_PER_CELL >= vertices * BYTES_PER_VERTEX {
                water_path.key("resolution")
            } else {
                KeyPath::root().key("max_edge_m")
            };
            return Err(map.error(
                &at,
                format!(
                    "the scene needs about {} before any image ({}), more than the memory limit of {}",
                    human_bytes(estimate.bytes()),
                    estimate.describe(),
                    human_bytes(limit)
                ),
                format!(
                    "use fewer membrane cells or coarser tessellation, or raise the limit with \
                     {MEMORY_LIMIT_VARIABLE} (e.g. {MEMORY_LIMIT_VARIABLE}=16G)"
                ),
            ));
        }
    }
    Ok(estimate)
}

/// Adds loaded characters (their vertices and triangles) to `estimate`, checked: the error
/// names the character that exceeds, at its `file` key.
pub fn check_characters(
    estimate: &mut Estimate,
    characters: &[(super::SourceRef, u64, u64)],
) -> Result<(), SceneError> {
    for (source, vertices, triangles) in characters {
        estimate.vertices = estimate.vertices.saturating_add(*vertices);
        estimate.triangles = estimate.triangles.saturating_add(*triangles);
        if estimate.vertices > MAX_VERTICES {
            return Err(source.error(
                format!(
                    "with this model's {vertices} vertices the scene has {}, more than the {MAX_VERTICES} \
                     a scene may have",
                    estimate.vertices
                ),
                "use a lighter model or coarser tessellation of the objects (max_edge_m)",
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_amounts_parse_like_people_write_them() {
        assert_eq!(parse_bytes("1536"), Some(1536));
        assert_eq!(parse_bytes("512M"), Some(512 << 20));
        assert_eq!(parse_bytes("2G"), Some(2 << 30));
        assert_eq!(parse_bytes("1.5GiB"), Some(3 << 29));
        assert_eq!(parse_bytes("8gb"), Some(8 << 30));
        assert_eq!(parse_bytes(" 4 G "), Some(4 << 30));
        for bad in ["", "lots", "-1G", "1X", "1e400", "0"] {
            assert_eq!(parse_bytes(bad), None, "{bad}");
        }
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
        assert_eq!(human_bytes(100 << 20), "100 MiB");
    }
}
