//! Virtual geometry (ALGORITHM §5.4-5, §7, §9): receives one frame's refraction field, camera, image
//! size and world-space objects (plus frame t-1's tracking state, for popping); returns what the GPU
//! draws — geometry above the water at true positions (indexed), geometry under it at virtual
//! positions with true attributes and per-triangle flags (unindexed) — with the frame's flag counts
//! and its own tracking state for frame t+1.
//!
//! Every distinct under-water vertex is queried once (in parallel, results in input order), every
//! image is enumerated, and the drawn one is chosen by [`crate::refraction::flags::CONVERGENCE_POLICY`],
//! never by looking at earlier frames: the output, tracking state included, is a pure function of
//! the frame's inputs. That is what lets a frame rendered alone recompute frame t-1's tracking state
//! with [`tracking_state`] and get what a sequential render would have carried over.

use glam::{DVec2, Vec3};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::draw::{flag_bits, TrueVertex, VirtualVertex};
use crate::mesh::Object;
use crate::refraction::exact::{exact_images, ExactImage};
use crate::refraction::flags::{vertex_pops, FlagCounts, TrackedVertex, TrackingState};
use crate::refraction::flat::{flat_virtual_vertex, virtual_vertex};
use crate::refraction::search::{Image, RefractionField};
use crate::refraction::split::{split_mesh, Side, SplitMesh, WaterVolume};
use crate::refraction::subdivision::{
    Subdivider, SubdivisionSettings, SubdivisionStats, SubdivisionVertex,
};
use crate::water::Membrane;

/// Which sight-facet search answers the queries: the accelerated one for rendering, the brute-force
/// oracle for tests of the search itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImageSearch {
    #[default]
    Accelerated,
    BruteForce,
}

/// Where under-water vertices are placed: at the linear cells' sight points (the cell methods), or
/// at exact sight points (Fermat's principle, ALGORITHM §6) with adaptive subdivision.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Placement {
    #[default]
    Linear,
    /// From each linear image's sight point, Newton on the exact surface; every valid stationary
    /// point is an image; failed solves fall back to the linear image (counted as
    /// `newton_fallback`); under-water triangles are subdivided as `SubdivisionSettings` says.
    Exact(SubdivisionSettings),
}

/// One frame's inputs to the virtual geometry.
#[derive(Clone, Copy)]
pub struct VirtualGeometryRequest<'a> {
    /// Built for query heights covering [`query_height_range`] of the objects.
    pub field: &'a RefractionField<'a>,
    /// Used only for screen positions (popping); the optics use `field.setup.eye`.
    pub camera: Camera,
    /// Width and height in pixels.
    pub image_size: (u32, u32),
    /// World space; the material index of a drawn vertex is its object's index here.
    pub objects: &'a [Object],
    /// The flat plane used for the position of imageless vertices of boundary triangles.
    pub mean_level_m: f32,
    pub search: ImageSearch,
}

/// The image drawn for an under-water vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChosenImage {
    pub facet: u32,
    pub sight_point: Vec3,
    pub virtual_position: Vec3,
    /// `|V - S|`.
    pub water_path_m: f32,
    pub extrapolated: bool,
}

/// What the search says about one under-water vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexImages {
    /// Distinct images found (0: outside the visible volume; > 1: zone of convergence).
    pub image_count: u32,
    /// `None` when there is no image.
    pub chosen: Option<ChosenImage>,
}

/// One frame's geometry for the GPU, with its flags.
#[derive(Clone, Debug)]
pub struct VirtualGeometry {
    pub above_vertices: Vec<TrueVertex>,
    pub above_indices: Vec<u32>,
    /// Three per triangle.
    pub under_vertices: Vec<VirtualVertex>,
    pub counts: FlagCounts,
    /// This frame's chosen images, for popping at the next frame.
    pub tracking: TrackingState,
}

/// The height range the refraction field must answer queries for (`RefractionField::build`'s
/// `query_y_range`): from the lowest object vertex over the membrane to the highest membrane vertex.
/// Split vertices lie on object edges, so they are inside this range too.
pub fn query_height_range(objects: &[Object], membrane: &Membrane) -> (f32, f32) {
    let grid = &membrane.grid;
    let (membrane_low, membrane_high) = membrane
        .positions
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let object_low = objects
        .iter()
        .flat_map(|o| o.mesh.positions.iter())
        .filter(|p| {
            let (x, z) = (p.x as f64, p.z as f64);
            x >= grid.min_x && x <= grid.max_x && z >= grid.min_z && z <= grid.max_z
        })
        .fold(f32::INFINITY, |lo, p| lo.min(p.y));
    (object_low.min(membrane_low), membrane_high)
}

/// Every image of `point` and the one drawn: least optical path `n_above |S - E| + n_below |V - S|`,
/// then lowest facet index. `scratch` is reused between calls.
pub fn vertex_images(
    field: &RefractionField,
    point: Vec3,
    search: ImageSearch,
    scratch: &mut Vec<Image>,
) -> VertexImages {
    match search {
        ImageSearch::Accelerated => field.images(point, scratch),
        ImageSearch::BruteForce => field.images_brute_force(point, scratch),
    }
    let eye = field.setup.eye.as_dvec3();
    let (n_above, n_below) = (field.setup.n_above as f64, field.setup.n_below as f64);
    let point_f64 = point.as_dvec3();
    let optical_path = |image: &Image| {
        let s = image.sight_point.as_dvec3();
        n_above * (s - eye).length() + n_below * (point_f64 - s).length()
    };
    let best = scratch.iter().min_by(|a, b| {
        optical_path(a)
            .total_cmp(&optical_path(b))
            .then(a.facet.cmp(&b.facet))
    });
    VertexImages {
        image_count: scratch.len() as u32,
        chosen: best.map(|image| {
            let s = image.sight_point.as_dvec3();
            ChosenImage {
                facet: image.facet,
                sight_point: image.sight_point,
                virtual_position: virtual_vertex(eye, s, point_f64, n_above, n_below).as_vec3(),
                water_path_m: (point_f64 - s).length() as f32,
                extrapolated: image.extrapolated,
            }
        }),
    }
}

/// [`vertex_images`] for the exact method: the linear images (into `scratch`), then one Newton
/// solve from each ([`exact_images`], into `exact`); the drawn image is chosen by the same policy
/// (least optical path, then lowest facet index). Returns the images and the chosen exact image.
pub fn exact_vertex_images(
    field: &RefractionField,
    point: Vec3,
    search: ImageSearch,
    scratch: &mut Vec<Image>,
    exact: &mut Vec<ExactImage>,
) -> (VertexImages, Option<ExactImage>) {
    match search {
        ImageSearch::Accelerated => field.images(point, scratch),
        ImageSearch::BruteForce => field.images_brute_force(point, scratch),
    }
    let point_f64 = point.as_dvec3();
    exact_images(field, point_f64, scratch, exact);
    let eye = field.setup.eye.as_dvec3();
    let (n_above, n_below) = (field.setup.n_above as f64, field.setup.n_below as f64);
    let optical_path = |image: &ExactImage| {
        let s = image.sight_point;
        n_above * (s - eye).length() + n_below * (point_f64 - s).length()
    };
    let best = exact
        .iter()
        .min_by(|a, b| {
            optical_path(a)
                .total_cmp(&optical_path(b))
                .then(a.facet.cmp(&b.facet))
        })
        .copied();
    let images = VertexImages {
        image_count: exact.len() as u32,
        chosen: best.map(|image| {
            let s = image.sight_point;
            ChosenImage {
                facet: image.facet,
                sight_point: s.as_vec3(),
                virtual_position: virtual_vertex(eye, s, point_f64, n_above, n_below).as_vec3(),
                water_path_m: (point_f64 - s).length() as f32,
                extrapolated: image.extrapolated,
            }
        }),
    };
    (images, best)
}

/// An under-water vertex after the query: where it is drawn and how it is flagged.
#[derive(Clone, Copy, Debug)]
struct ResolvedVertex {
    images: VertexImages,
    /// The chosen image's virtual position, or the flat-water one when there is no image.
    drawn_position: Vec3,
    water_path_m: f32,
    pops: bool,
    /// Exact method: the chosen image is a linear one because Newton failed.
    newton_fallback: bool,
    /// Exact method: the chosen exact sight point's (x, z), for the subdivision's solves.
    exact_sight_xz: Option<DVec2>,
}

/// Builds the frame's geometry, flags and tracking state. `previous` is frame t-1's tracking state
/// (from the previous call in a sequence, or from [`tracking_state`] at t-1 for a frame rendered
/// alone — the same value); without it nothing is judged popping.
pub fn build_virtual_geometry(
    request: &VirtualGeometryRequest,
    previous: Option<&TrackingState>,
) -> VirtualGeometry {
    build_virtual_geometry_with(request, previous, Placement::Linear)
}

/// [`build_virtual_geometry`] with the vertices placed as `placement` says.
pub fn build_virtual_geometry_with(
    request: &VirtualGeometryRequest,
    previous: Option<&TrackingState>,
    placement: Placement,
) -> VirtualGeometry {
    let field = request.field;
    let membrane = field.membrane;
    let water = WaterVolume {
        surface: field.surface.height_field,
        extent: membrane.grid,
    };
    let splits: Vec<SplitMesh> = request
        .objects
        .par_iter()
        .map(|object| split_mesh(&object.mesh, &water))
        .collect();

    // Each distinct under-water vertex once, in a fixed order: (object, vertex).
    let queries: Vec<(u32, u32)> = splits
        .iter()
        .enumerate()
        .flat_map(|(object, split)| {
            split
                .vertices
                .iter()
                .enumerate()
                .filter(|(_, v)| v.side == Side::Below)
                .map(move |(vertex, _)| (object as u32, vertex as u32))
        })
        .collect();
    let eye = field.setup.eye.as_dvec3();
    let (n_above, n_below) = (field.setup.n_above as f64, field.setup.n_below as f64);
    let (width, height) = request.image_size;
    // Motion vectors compare world positions, which stay comparable when the grid or image size
    // changes; popping compares facets and pixels, which do not.
    let motion_previous = previous;
    let previous = previous.filter(|p| p.is_comparable(&membrane.grid, request.image_size));
    let answers: Vec<(ResolvedVertex, TrackedVertex)> = queries
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(scratch, exact), &(object, vertex)| {
                let split = &splits[object as usize];
                let point = split.vertices[vertex as usize].position;
                let (images, chosen_exact) = match placement {
                    Placement::Linear => {
                        (vertex_images(field, point, request.search, scratch), None)
                    }
                    Placement::Exact(_) => {
                        exact_vertex_images(field, point, request.search, scratch, exact)
                    }
                };
                let newton_fallback = chosen_exact.is_some_and(|c| c.newton_fallback);
                let exact_sight_xz = chosen_exact
                    .filter(|c| !c.newton_fallback)
                    .map(|c| DVec2::new(c.sight_point.x, c.sight_point.z));
                let (drawn_position, water_path_m) = match images.chosen {
                    Some(chosen) => (chosen.virtual_position, chosen.water_path_m),
                    None => {
                        let (position, path_m) = flat_virtual_vertex(
                            eye,
                            point.as_dvec3(),
                            request.mean_level_m as f64,
                            n_above,
                            n_below,
                        );
                        (position.as_vec3(), path_m as f32)
                    }
                };
                let pixel = request.camera.pixel_of(drawn_position, width, height);
                let tracked = match images.chosen {
                    Some(chosen) => TrackedVertex::Seen {
                        facet: chosen.facet,
                        pixel,
                    },
                    None => TrackedVertex::Unseen { pixel },
                };
                // Only the mesh's own vertices are tracked: crossings are created per frame.
                let pops = (vertex as usize) < split.original_vertex_count
                    && previous
                        .and_then(|p| p.vertex(object as usize, vertex as usize))
                        .is_some_and(|before| vertex_pops(before, tracked, &membrane.triangles));
                (
                    ResolvedVertex {
                        images,
                        drawn_position,
                        water_path_m,
                        pops,
                        newton_fallback,
                        exact_sight_xz,
                    },
                    tracked,
                )
            },
        )
        .collect();

    let mut counts = FlagCounts::default();
    let mut resolved: Vec<Vec<Option<ResolvedVertex>>> = splits
        .iter()
        .map(|s| vec![None; s.vertices.len()])
        .collect();
    let mut tracking: Vec<Vec<TrackedVertex>> = splits
        .iter()
        .map(|s| vec![TrackedVertex::NotUnderWater; s.original_vertex_count])
        .collect();
    for (&(object, vertex), &(answer, tracked)) in queries.iter().zip(&answers) {
        let (object, vertex) = (object as usize, vertex as usize);
        resolved[object][vertex] = Some(answer);
        if vertex < splits[object].original_vertex_count {
            tracking[object][vertex] = tracked;
        }
        let vertex_counts = &mut counts.vertices;
        vertex_counts.under_water += 1;
        vertex_counts.outside += u64::from(answer.images.image_count == 0);
        vertex_counts.convergence += u64::from(answer.images.image_count > 1);
        vertex_counts.extrapolated +=
            u64::from(answer.images.chosen.is_some_and(|c| c.extrapolated));
        vertex_counts.popping += u64::from(answer.pops);
        vertex_counts.newton_fallback += u64::from(answer.newton_fallback);
    }

    // Where every split vertex is drawn this frame, and where it was drawn at t-1.
    let drawn: Vec<Vec<Vec3>> = splits
        .iter()
        .zip(&resolved)
        .map(|(split, resolved)| {
            split
                .vertices
                .iter()
                .zip(resolved)
                .map(|(v, r)| r.map_or(v.position, |r| r.drawn_position))
                .collect()
        })
        .collect();
    let previous_drawn: Vec<Vec<Vec3>> = splits
        .iter()
        .zip(&drawn)
        .enumerate()
        .map(|(object, (split, drawn))| previous_positions(object, split, drawn, motion_previous))
        .collect();
    let drawn_positions: Vec<Vec<Vec3>> = splits
        .iter()
        .zip(&drawn)
        .map(|(split, drawn)| drawn[..split.original_vertex_count].to_vec())
        .collect();
    let true_positions: Vec<Vec<Vec3>> = splits
        .iter()
        .map(|split| {
            split.vertices[..split.original_vertex_count]
                .iter()
                .map(|v| v.position)
                .collect()
        })
        .collect();

    let mut above_vertices = Vec::new();
    let mut above_indices = Vec::new();
    let mut under_vertices = Vec::new();
    let subdivider = match placement {
        Placement::Linear => None,
        Placement::Exact(settings) => Some(Subdivider {
            field,
            camera: request.camera,
            image_size: request.image_size,
            settings,
        }),
    };
    let skirt = WaterlineSkirt::new(field);
    for (object, split) in splits.iter().enumerate() {
        append_above(
            object as u32,
            split,
            &previous_drawn[object],
            &skirt,
            &mut above_vertices,
            &mut above_indices,
        );
        append_under(
            object as u32,
            split,
            &resolved[object],
            &previous_drawn[object],
            subdivider.as_ref(),
            &skirt,
            &mut under_vertices,
            &mut counts,
        );
    }
    VirtualGeometry {
        above_vertices,
        above_indices,
        under_vertices,
        counts,
        tracking: TrackingState {
            grid: membrane.grid,
            image_size: request.image_size,
            vertices: tracking,
            camera: request.camera,
            drawn_positions,
            true_positions,
        },
    }
}

/// Where each split vertex of `object` was drawn at frame t-1 (the motion vectors' start): an
/// original vertex where t-1's tracking state says; a crossing (new each frame, on the water
/// line: its own image) at the same parameter along its edge between its ends' TRUE t-1
/// positions, as if it were still on the water line at t-1 (exact for still water); with no t-1
/// state (the timeline's first frame), or for a vertex t-1 did not have, where it is drawn now
/// (no motion).
fn previous_positions(
    object: usize,
    split: &SplitMesh,
    drawn: &[Vec3],
    previous: Option<&TrackingState>,
) -> Vec<Vec3> {
    let Some(previous) = previous else {
        return drawn.to_vec();
    };
    let mut out: Vec<Vec3> = (0..split.original_vertex_count)
        .map(|v| previous.drawn_position(object, v).unwrap_or(drawn[v]))
        .collect();
    for &(under, over, s) in &split.crossing_edges {
        let true_before = |v: u32| {
            previous
                .true_position(object, v as usize)
                .unwrap_or(split.vertices[v as usize].position)
        };
        out.push(true_before(under).lerp(true_before(over), s));
    }
    out
}

/// Frame t's tracking state alone: exactly the `tracking` [`build_virtual_geometry`] returns for
/// the same request (it IS that computation), for popping at frame t+1 when t was not rendered.
pub fn tracking_state(request: &VirtualGeometryRequest) -> TrackingState {
    build_virtual_geometry(request, None).tracking
}

/// The water-line skirt: a mesh is split where its edges cross the EXACT surface (ALGORITHM §7),
/// but the water drawn is the faceted membrane, which passes a little above or below the split
/// line. A pixel whose centre fell between the two showed the sky through a wall, or the
/// deep-water colour with no position (124 pixels over the 48 frames of `pool.toml` at 1280x720).
/// So at each vertex on the water line the part above water reaches down to the membrane, and the
/// virtual part under it up to the membrane, each by a margin more for the straight edges of the
/// mesh and the membrane between vertices. The skirts show nowhere else: the part above water
/// reaches down behind the membrane, which hides it wherever the membrane is in front, and the
/// virtual part is drawn only inside the membrane's stencil.
pub(crate) struct WaterlineSkirt<'a> {
    membrane: &'a Membrane,
    margin_m: f64,
}

/// The skirt's margin per membrane spacing: 0.6 mm at the default 6.25 cm, a twentieth of a pixel
/// at the default camera's distance (a skirt of half this margin alone, without reaching to the
/// membrane first, already closed every gap of `pool.toml` at 1280x720).
pub const WATERLINE_SKIRT_MARGIN_PER_SPACING: f64 = 0.01;

impl<'a> WaterlineSkirt<'a> {
    pub(crate) fn new(field: &RefractionField<'a>) -> Self {
        Self {
            membrane: field.membrane,
            margin_m: WATERLINE_SKIRT_MARGIN_PER_SPACING * field.spacing_m(),
        }
    }

    /// How far the faceted membrane lies above (+) or below (-) a water-line vertex.
    fn membrane_offset_m(&self, position: Vec3) -> f64 {
        self.membrane
            .faceted_height_at_xz(position.x as f64, position.z as f64)
            .map_or(0.0, |height| height - position.y as f64)
    }

    /// How far down the part above water reaches at a water-line vertex.
    pub(crate) fn below_m(&self, position: Vec3) -> f32 {
        ((-self.membrane_offset_m(position)).max(0.0) + self.margin_m) as f32
    }

    /// How far up the virtual part reaches at a water-line vertex.
    pub(crate) fn above_m(&self, position: Vec3) -> f32 {
        (self.membrane_offset_m(position).max(0.0) + self.margin_m) as f32
    }
}

/// The part above water, its vertices on the water line lowered by the skirt.
fn append_above(
    object: u32,
    split: &SplitMesh,
    previous: &[Vec3],
    skirt: &WaterlineSkirt,
    vertices: &mut Vec<TrueVertex>,
    indices: &mut Vec<u32>,
) {
    // Only the vertices the above part uses are uploaded.
    let mut remap = vec![u32::MAX; split.vertices.len()];
    for triangle in &split.above_triangles {
        for &i in triangle {
            if remap[i as usize] == u32::MAX {
                let mut v = split.vertices[i as usize];
                let mut previous_position = previous[i as usize];
                if v.side == Side::Surface {
                    let below_m = skirt.below_m(v.position);
                    v.position.y -= below_m;
                    previous_position.y -= below_m;
                }
                remap[i as usize] = vertices.len() as u32;
                vertices.push(TrueVertex {
                    position: v.position.to_array(),
                    previous_position: previous_position.to_array(),
                    normal: v.normal.to_array(),
                    uv: v.uv.to_array(),
                    material: object,
                });
            }
            indices.push(remap[i as usize]);
        }
    }
}

/// The part under water at virtual positions, with the virtual positions of its vertices on the
/// water line raised by the skirt (after any subdivision: the skirt is not an image to refine).
// Eight distinct inputs and outputs of one object's drawing, each used in its own step; a struct
// gathering them would only rename them at the one call site.
#[allow(clippy::too_many_arguments)]
fn append_under(
    object: u32,
    split: &SplitMesh,
    resolved: &[Option<ResolvedVertex>],
    previous: &[Vec3],
    subdivider: Option<&Subdivider>,
    skirt: &WaterlineSkirt,
    out: &mut Vec<VirtualVertex>,
    counts: &mut FlagCounts,
) {
    // Drawn triangles with their flags, before any subdivision.
    let mut drawn: Vec<([SubdivisionVertex; 3], u32)> = Vec::new();
    let mut drawn_indices: Vec<[u32; 3]> = Vec::new();
    for triangle in &split.below_triangles {
        counts.triangles.under_water += 1;
        let mut under_water = 0;
        let mut with_image = 0;
        let mut flags = 0;
        for &i in triangle {
            if let Some(r) = resolved[i as usize] {
                under_water += 1;
                with_image += u32::from(r.images.chosen.is_some());
                if r.images.image_count > 1 {
                    flags |= flag_bits::CONVERGENCE;
                }
                if r.images.chosen.is_some_and(|c| c.extrapolated) {
                    flags |= flag_bits::EXTRAPOLATED;
                }
                if r.pops {
                    flags |= flag_bits::POPPING;
                }
            }
        }
        if with_image == 0 {
            // Every under-water vertex is outside the visible volume: nothing to draw it with.
            counts.triangles.not_drawn += 1;
            continue;
        }
        if with_image < under_water {
            flags |= flag_bits::BOUNDARY;
        }
        let triangle_counts = &mut counts.triangles;
        triangle_counts.boundary += u64::from(flags & flag_bits::BOUNDARY != 0);
        triangle_counts.convergence += u64::from(flags & flag_bits::CONVERGENCE != 0);
        triangle_counts.extrapolated += u64::from(flags & flag_bits::EXTRAPOLATED != 0);
        triangle_counts.popping += u64::from(flags & flag_bits::POPPING != 0);
        let corners = triangle.map(|i| {
            let v = split.vertices[i as usize];
            // A surface vertex is its own virtual vertex: V' = V, no water on its path (and its
            // own exact sight point).
            let (virtual_position, water_path_m, sight_xz) = match resolved[i as usize] {
                Some(r) => (r.drawn_position, r.water_path_m, r.exact_sight_xz),
                None => (
                    v.position,
                    0.0,
                    Some(DVec2::new(v.position.x as f64, v.position.z as f64)),
                ),
            };
            SubdivisionVertex {
                position: v.position,
                normal: v.normal,
                uv: v.uv,
                virtual_position,
                previous_position: previous[i as usize],
                water_path_m,
                sight_xz,
                on_surface: v.side == Side::Surface,
            }
        });
        drawn.push((corners, flags));
        drawn_indices.push(*triangle);
    }
    let mut push = |corners: &[SubdivisionVertex; 3], flags: u32| {
        for v in corners {
            let mut virtual_position = v.virtual_position;
            let mut previous_position = v.previous_position;
            if v.on_surface {
                let above_m = skirt.above_m(v.position);
                virtual_position.y += above_m;
                previous_position.y += above_m;
            }
            out.push(VirtualVertex {
                virtual_position: virtual_position.to_array(),
                previous_position: previous_position.to_array(),
                true_position: v.position.to_array(),
                normal: v.normal.to_array(),
                uv: v.uv.to_array(),
                material: object,
                water_path_m: v.water_path_m,
                flags,
            });
        }
    };
    let Some(subdivider) = subdivider else {
        for (corners, flags) in &drawn {
            push(corners, *flags);
        }
        return;
    };
    // The first split test of each edge once (neighbours share it), then each triangle's
    // subdivision, a function of its own edges: in parallel, output in order. The pieces keep the
    // triangle's flags.
    let mut edge_of: std::collections::HashMap<(u32, u32), u32> = Default::default();
    let mut edges: Vec<(SubdivisionVertex, SubdivisionVertex)> = Vec::new();
    let triangle_edges: Vec<[u32; 3]> = drawn
        .iter()
        .zip(&drawn_indices)
        .map(|((corners, _), indices)| {
            std::array::from_fn(|k| {
                let (a, b) = (indices[k], indices[(k + 1) % 3]);
                *edge_of.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    edges.push((corners[k], corners[(k + 1) % 3]));
                    (edges.len() - 1) as u32
                })
            })
        })
        .collect();
    let first_splits: Vec<Option<SubdivisionVertex>> = if subdivider.settings.max_depth == 0 {
        vec![None; edges.len()]
    } else {
        edges
            .par_iter()
            .map(|(a, b)| subdivider.split_edge(a, b))
            .collect()
    };
    let pieces: Vec<(Vec<[SubdivisionVertex; 3]>, SubdivisionStats)> = drawn
        .par_iter()
        .zip(&triangle_edges)
        .map(|((corners, _), edge_indices)| {
            let mut pieces = Vec::new();
            let first = edge_indices.map(|e| first_splits[e as usize]);
            let stats = subdivider.subdivide_from(*corners, first, &mut pieces);
            (pieces, stats)
        })
        .collect();
    for ((_, flags), (triangles, stats)) in drawn.iter().zip(&pieces) {
        if stats.pieces > 1 {
            counts.triangles.subdivided += 1;
            counts.triangles.subdivision_pieces += u64::from(stats.pieces);
        }
        for corners in triangles {
            push(corners, *flags);
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
