//! The per-frame failure flags (ALGORITHM §9): receives, per under-water vertex, the image chosen
//! this frame and the one chosen the frame before; returns the popping verdicts, the flag counts
//! written to the report, and the convergence policy in words.
//!
//! Popping compares frame t with frame t-1's [`TrackingState`]. The tracking state is a pure
//! function of a frame's inputs (the chosen image never depends on earlier frames), so a frame
//! rendered alone computes frame t-1's state by running the same geometry function at t-1
//! (`virtual_geometry::tracking_state`), and gets exactly what a sequential render carried over.

use glam::{Vec2, Vec3};
use serde::Serialize;

use crate::camera::Camera;
use crate::water::MembraneGrid;

/// How the drawn image is chosen where a vertex has several (a zone of convergence). Written into
/// every frame's report.
pub const CONVERGENCE_POLICY: &str = "every image is enumerated; the one drawn has the least optical \
path n_above*|S-E| + n_below*|V-S|, ties broken by the lowest membrane facet index; the choice never \
depends on earlier frames";

/// A vertex pops only if its screen position jumps by more than this (ALGORITHM §9).
pub const POPPING_THRESHOLD_PX: f32 = 2.0;

/// Vertex counts of one frame. Every count is over distinct under-water mesh vertices (a vertex
/// shared by many triangles counts once).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct VertexFlagCounts {
    /// Vertices strictly under the water (vertices on the surface are their own image: not counted).
    pub under_water: u64,
    /// Under-water vertices with no image (outside the visible volume).
    pub outside: u64,
    /// Whose drawn image comes from an extrapolated (back-facing or TIR) refraction ray.
    pub extrapolated: u64,
    /// With more than one image (zone of convergence).
    pub convergence: u64,
    /// Whose image popped since the previous frame.
    pub popping: u64,
    /// Exact method only: with an image whose Newton solve failed, drawn at the linear cell's
    /// sight point instead. Left out of the report when zero, so the linear methods' reports (and
    /// their goldens) are unchanged.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub newton_fallback: u64,
}

/// Triangle counts of one frame, over the under-water parts after splitting at the surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TriangleFlagCounts {
    pub under_water: u64,
    /// Some under-water vertices with an image and some without; drawn with the flat-water position
    /// for the imageless ones.
    pub boundary: u64,
    /// Every under-water vertex without an image: not drawn.
    pub not_drawn: u64,
    pub convergence: u64,
    pub extrapolated: u64,
    pub popping: u64,
    /// Exact method only: under-water triangles the adaptive subdivision split (thesis §4.7)...
    #[serde(default, skip_serializing_if = "is_zero")]
    pub subdivided: u64,
    /// ...and how many triangles they were drawn as. Both left out of the report when zero.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub subdivision_pieces: u64,
}

fn is_zero(count: &u64) -> bool {
    *count == 0
}

/// The flag counts of one frame (the report's `flags` object).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FlagCounts {
    pub vertices: VertexFlagCounts,
    pub triangles: TriangleFlagCounts,
}

/// What popping needs to know about one original mesh vertex in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrackedVertex {
    /// Above the water, on its surface, or outside the membrane: no image involved.
    NotUnderWater,
    /// Under water and seen through `facet`; `pixel` is where its virtual vertex lands on screen
    /// (`None`: behind the eye).
    Seen { facet: u32, pixel: Option<Vec2> },
    /// Under water with no image; `pixel` is where its flat-water fallback would land.
    Unseen { pixel: Option<Vec2> },
}

/// One frame's chosen images, per object and per original mesh vertex, for popping at frame t+1.
/// Build it with `virtual_geometry::build_virtual_geometry` (returned beside the geometry) or
/// `virtual_geometry::tracking_state` (the same computation without the geometry): a pure function
/// of the frame's inputs.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackingState {
    /// Facet indices are only comparable between frames of the same membrane grid.
    pub grid: MembraneGrid,
    /// Pixel positions are only comparable at the same image size.
    pub image_size: (u32, u32),
    /// `vertices[object][vertex]`.
    pub vertices: Vec<Vec<TrackedVertex>>,
    /// The frame's camera, which projects [`Self::drawn_positions`] to the screen (motion vectors).
    pub camera: Camera,
    /// `drawn_positions[object][vertex]`: where each original mesh vertex was drawn this frame
    /// (its true position above or on the water, its drawn virtual position under it), for the
    /// motion vectors of frame t+1.
    pub drawn_positions: Vec<Vec<Vec3>>,
    /// `true_positions[object][vertex]`: each original mesh vertex's true position this frame
    /// (a water-line crossing of frame t+1 starts its motion on its edge between these).
    pub true_positions: Vec<Vec<Vec3>>,
}

impl TrackingState {
    /// Whether this state (of frame t-1) can be compared with a frame of this grid and image size.
    /// If not (resolution changed mid-sequence), popping is not judged for the frame.
    pub fn is_comparable(&self, grid: &MembraneGrid, image_size: (u32, u32)) -> bool {
        self.grid == *grid && self.image_size == image_size
    }

    pub fn vertex(&self, object: usize, vertex: usize) -> Option<TrackedVertex> {
        self.vertices.get(object)?.get(vertex).copied()
    }

    /// Where original vertex `vertex` of `object` was drawn this frame (motion vectors); `None`
    /// if the object or vertex did not exist.
    pub fn drawn_position(&self, object: usize, vertex: usize) -> Option<Vec3> {
        self.drawn_positions.get(object)?.get(vertex).copied()
    }

    /// Original vertex `vertex` of `object`'s true position this frame.
    pub fn true_position(&self, object: usize, vertex: usize) -> Option<Vec3> {
        self.true_positions.get(object)?.get(vertex).copied()
    }
}

/// Whether facets `a` and `b` of the membrane are the same or neighbours (share a vertex): moving
/// between them is a continuation, not a jump to another image.
pub fn facets_adjacent(triangles: &[[u32; 3]], a: u32, b: u32) -> bool {
    if a == b {
        return true;
    }
    match (triangles.get(a as usize), triangles.get(b as usize)) {
        (Some(ta), Some(tb)) => ta.iter().any(|v| tb.contains(v)),
        _ => false,
    }
}

/// Whether a vertex pops between the previous frame and this one (ALGORITHM §9): its chosen image is
/// not the continuation of the previous one (a facet that is neither the same nor a neighbour), or it
/// gained or lost its last image — AND its screen position jumped by more than
/// [`POPPING_THRESHOLD_PX`]. A vertex not under water in either frame never pops (its drawn position
/// moves continuously through the surface, where it is its own image).
pub fn vertex_pops(
    previous: TrackedVertex,
    current: TrackedVertex,
    membrane_triangles: &[[u32; 3]],
) -> bool {
    use TrackedVertex::*;
    let (image_changed, previous_pixel, current_pixel) = match (previous, current) {
        (NotUnderWater, _) | (_, NotUnderWater) => return false,
        (
            Seen {
                facet: a,
                pixel: pa,
            },
            Seen {
                facet: b,
                pixel: pb,
            },
        ) => (!facets_adjacent(membrane_triangles, a, b), pa, pb),
        (Unseen { .. }, Unseen { .. }) => return false,
        (Seen { pixel: pa, .. }, Unseen { pixel: pb })
        | (Unseen { pixel: pa }, Seen { pixel: pb, .. }) => (true, pa, pb),
    };
    let jumped = match (previous_pixel, current_pixel) {
        (Some(a), Some(b)) => a.distance(b) > POPPING_THRESHOLD_PX,
        // Crossing behind the eye is a jump off screen.
        (None, Some(_)) | (Some(_), None) => true,
        (None, None) => false,
    };
    image_changed && jumped
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The triangles of a 3x2-cell membrane grid, in the membrane's layout.
    fn grid_triangles() -> Vec<[u32; 3]> {
        let grid = MembraneGrid {
            min_x: 0.0,
            min_z: 0.0,
            max_x: 3.0,
            max_z: 2.0,
            cells_x: 3,
            cells_z: 2,
        };
        (0..grid.triangle_count() as u32)
            .map(|facet| grid.facet_vertices(facet))
            .collect()
    }

    fn seen(facet: u32, x: f32) -> TrackedVertex {
        TrackedVertex::Seen {
            facet,
            pixel: Some(Vec2::new(x, 10.0)),
        }
    }

    #[test]
    fn neighbour_crossing_is_not_popping_even_with_a_jump() {
        let triangles = grid_triangles();
        assert!(facets_adjacent(&triangles, 0, 1));
        // Facet 0 = [0, 4, 5] and facet 2 = [1, 5, 6] share vertex 5 only: still a neighbour.
        assert!(facets_adjacent(&triangles, 0, 2));
        assert!(!vertex_pops(seen(0, 10.0), seen(2, 30.0), &triangles));
        assert!(!vertex_pops(seen(0, 10.0), seen(1, 30.0), &triangles));
        assert!(!vertex_pops(seen(0, 10.0), seen(0, 30.0), &triangles));
    }

    #[test]
    fn distant_facet_with_a_jump_pops_and_without_does_not() {
        let triangles = grid_triangles();
        // Facet 0 = [0, 4, 5] and facet 11 = [6, 11, 7]: no shared vertex.
        assert!(!facets_adjacent(&triangles, 0, 11));
        assert!(vertex_pops(seen(0, 10.0), seen(11, 12.5), &triangles));
        assert!(!vertex_pops(seen(0, 10.0), seen(11, 11.5), &triangles));
    }

    #[test]
    fn gaining_or_losing_the_last_image_pops_only_with_a_jump() {
        let triangles = grid_triangles();
        let unseen = |x: f32| TrackedVertex::Unseen {
            pixel: Some(Vec2::new(x, 10.0)),
        };
        assert!(vertex_pops(seen(4, 10.0), unseen(20.0), &triangles));
        assert!(vertex_pops(unseen(20.0), seen(4, 10.0), &triangles));
        assert!(!vertex_pops(seen(4, 10.0), unseen(11.0), &triangles));
        assert!(!vertex_pops(unseen(3.0), unseen(30.0), &triangles));
    }

    #[test]
    fn leaving_or_entering_the_water_never_pops() {
        let triangles = grid_triangles();
        assert!(!vertex_pops(
            TrackedVertex::NotUnderWater,
            seen(11, 300.0),
            &triangles
        ));
        assert!(!vertex_pops(
            seen(0, 0.0),
            TrackedVertex::NotUnderWater,
            &triangles
        ));
    }

    #[test]
    fn counts_serialize_with_their_names() {
        let json = serde_json::to_value(FlagCounts::default()).unwrap();
        for key in [
            "under_water",
            "outside",
            "extrapolated",
            "convergence",
            "popping",
        ] {
            assert!(json["vertices"].get(key).is_some(), "{key}");
        }
        for key in [
            "under_water",
            "boundary",
            "not_drawn",
            "convergence",
            "extrapolated",
            "popping",
        ] {
            assert!(json["triangles"].get(key).is_some(), "{key}");
        }
    }
}
