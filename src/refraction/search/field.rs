//! The refraction field of one frame: the membrane's refraction rays, every facet's cell, the
//! search structure over them ([`super::blocks`]) and the crest check ([`super::crest`]); per
//! query point every image, merged where sight points coincide, crest-blocked paths rejected.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::super::cells::{equal_t_containments, thesis_containment, Cell};
use super::super::rays::{refraction_rays, RefractionRay};
use super::super::surface::ExactSurface;
use super::blocks::SearchStructure;
use super::crest::CrestCheck;
use crate::water::Membrane;

/// Which containment test defines a cell (ALGORITHM §5.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellMode {
    /// Equal-t cells: no gaps, no overlaps. The default.
    #[default]
    EqualT,
    /// The thesis's per-facet plane test, kept to reproduce its tables.
    Thesis,
}

/// The optical setup of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefractionSetup {
    pub eye: Vec3,
    /// Index of refraction on the eye's side (air) and on the far side (water).
    pub n_above: f32,
    pub n_below: f32,
    pub cell_mode: CellMode,
}

/// One image of a point: the facet it is seen through and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Image {
    /// Index into `Membrane::triangles`.
    pub facet: u32,
    /// Ray parameter of the cell cross-section through the point.
    pub t: f32,
    /// Barycentrics of the point in that cross-section (= of the sight point in the facet).
    pub barycentric: [f32; 3],
    /// `S = b0 P0 + b1 P1 + b2 P2` on the facet.
    pub sight_point: Vec3,
    /// Any of the facet's three refraction rays is extrapolated (back-facing or TIR).
    pub extrapolated: bool,
}

/// Two images are one when their sight points are closer than this fraction of the longer facet's
/// longest edge. Duplicates come from the containment slack (`CONTAINMENT_EPS = 1e-4` of a facet)
/// on shared faces, edges and rays, so they lie ~1e-4 facets apart; distinct images of a
/// convergence zone are seen through different parts of the surface, typically facets apart.
pub const MERGE_DISTANCE_PER_FACET_SIZE: f32 = 1e-3;

/// The refraction cells of one frame and the structure that searches them.
pub struct RefractionField<'a> {
    pub membrane: &'a Membrane,
    /// The exact surface: the crest check's, and what the exact method solves on.
    pub surface: &'a ExactSurface<'a>,
    pub setup: RefractionSetup,
    /// One ray per membrane vertex.
    pub rays: Vec<RefractionRay>,
    /// Per facet: any of its rays is extrapolated.
    pub facet_extrapolated: Vec<bool>,
    /// The accelerated search (empty: every query tests every cell).
    pub(crate) structure: SearchStructure,
    pub(crate) crest: CrestCheck,
}

impl<'a> RefractionField<'a> {
    /// Builds rays, cells and the search structure for query points whose heights lie in
    /// `query_y_range` (min, max) — points outside it may be missed by `images` (not by brute force).
    /// (Here they are not missed either: `images` falls back to testing every cell for them.)
    pub fn build(
        membrane: &'a Membrane,
        surface: &'a ExactSurface<'a>,
        setup: RefractionSetup,
        query_y_range: (f32, f32),
    ) -> Self {
        Self::build_with(membrane, surface, setup, Some(query_y_range))
    }

    /// Rays and cells only, no search structure: what the brute-force oracle needs (`images` then
    /// tests every cell too). For benchmarks comparing the two.
    pub fn build_unaccelerated(
        membrane: &'a Membrane,
        surface: &'a ExactSurface<'a>,
        setup: RefractionSetup,
    ) -> Self {
        Self::build_with(membrane, surface, setup, None)
    }

    fn build_with(
        membrane: &'a Membrane,
        surface: &'a ExactSurface<'a>,
        setup: RefractionSetup,
        query_y_range: Option<(f32, f32)>,
    ) -> Self {
        let rays = refraction_rays(membrane, setup.eye, setup.n_above, setup.n_below);
        let facet_extrapolated: Vec<bool> = membrane
            .triangles
            .par_iter()
            .with_min_len(4096)
            .map(|tri| {
                tri.iter()
                    .any(|&i| rays[i as usize].extrapolation.is_extrapolated())
            })
            .collect();
        let grid = membrane.grid;
        let spacing_m = ((grid.max_x - grid.min_x) / grid.cells_x.max(1) as f64)
            .min((grid.max_z - grid.min_z) / grid.cells_z.max(1) as f64)
            .max(1e-9);
        // The crest check's data and the search structure need nothing of each other: built side
        // by side, so the sequential parts of one overlap the other.
        let (crest, structure) = rayon::join(
            || CrestCheck::new(membrane, surface, spacing_m),
            || match (setup.cell_mode, query_y_range) {
                (CellMode::EqualT, Some(range)) => {
                    SearchStructure::build(membrane, &rays, spacing_m, range)
                }
                _ => SearchStructure::empty(),
            },
        );
        Self {
            membrane,
            surface,
            setup,
            rays,
            facet_extrapolated,
            structure,
            crest,
        }
    }

    /// Every image of `point` (cleared into `out`), ordered by facet index, coincident sight points
    /// merged, crest-blocked paths rejected. Accelerated.
    pub fn images(&self, point: Vec3, out: &mut Vec<Image>) {
        out.clear();
        if self.setup.cell_mode == CellMode::Thesis || !self.structure.is_built() {
            self.images_brute_force(point, out);
            return;
        }
        let Some(slab) = self.structure.slab_at(point.y) else {
            // Outside the range the structure was built for: test everything rather than miss.
            self.images_brute_force(point, out);
            return;
        };
        let point64 = point.as_dvec3();
        self.structure.for_each_candidate(slab, point, |facet| {
            self.push_containments(facet, point64, out)
        });
        for &facet in self.structure.unbounded_facets() {
            self.push_containments(facet, point64, out);
        }
        out.sort_unstable_by(|a, b| a.facet.cmp(&b.facet).then(a.t.total_cmp(&b.t)));
        self.merge_and_check_crests(point64, out);
    }

    /// The same answer as [`Self::images`], by testing every cell: the test oracle.
    pub fn images_brute_force(&self, point: Vec3, out: &mut Vec<Image>) {
        out.clear();
        let point64 = point.as_dvec3();
        for facet in 0..self.membrane.triangles.len() as u32 {
            self.push_containments(facet, point64, out);
        }
        self.merge_and_check_crests(point64, out);
    }

    /// The membrane's grid spacing (the smaller of the two directions), metres: the finest
    /// feature the membrane resolves.
    pub fn spacing_m(&self) -> f64 {
        self.crest.spacing_m
    }

    /// The cell of one facet.
    #[inline]
    pub fn cell(&self, facet: u32) -> Cell {
        let tri = self.membrane.triangles[facet as usize];
        let r = tri.map(|i| self.rays[i as usize]);
        Cell::new(r.map(|r| r.origin), r.map(|r| r.direction))
    }

    pub(crate) fn push_containments(&self, facet: u32, point: DVec3, out: &mut Vec<Image>) {
        let cell = self.cell(facet);
        let extrapolated = self.facet_extrapolated[facet as usize];
        let mut push = |c: &super::super::cells::Containment| {
            out.push(Image {
                facet,
                t: c.t as f32,
                barycentric: c.barycentric.map(|b| b as f32),
                sight_point: c.sight_point.as_vec3(),
                extrapolated,
            })
        };
        match self.setup.cell_mode {
            CellMode::EqualT => equal_t_containments(&cell, point)
                .iter()
                .for_each(&mut push),
            CellMode::Thesis => {
                if let Some(c) = thesis_containment(&cell, point) {
                    push(&c)
                }
            }
        }
    }

    fn facet_size_m(&self, facet: u32) -> f32 {
        let p =
            self.membrane.triangles[facet as usize].map(|i| self.membrane.positions[i as usize]);
        (p[1] - p[0])
            .length()
            .max((p[2] - p[1]).length())
            .max((p[0] - p[2]).length())
    }

    /// Drops images whose sight point coincides with an earlier (lower-facet) one, then those whose
    /// path is blocked by a crest. `images` must be sorted by facet.
    fn merge_and_check_crests(&self, point: DVec3, images: &mut Vec<Image>) {
        let mut kept = 0;
        for i in 0..images.len() {
            let candidate = images[i];
            // Most points have one image: nothing to compare it with, no facet size needed.
            let duplicate = kept > 0 && {
                let size = self.facet_size_m(candidate.facet);
                images[..kept].iter().any(|k| {
                    let tolerance =
                        MERGE_DISTANCE_PER_FACET_SIZE * size.max(self.facet_size_m(k.facet));
                    (k.sight_point - candidate.sight_point).length() <= tolerance
                })
            };
            if !duplicate {
                images[kept] = candidate;
                kept += 1;
            }
        }
        images.truncate(kept);
        images.retain(|image| !self.crest_blocks(image.sight_point.as_dvec3(), point));
    }

    /// Is the path eye -> sight point -> point blocked by the surface (ALGORITHM §6)? See
    /// [`CrestCheck::blocks`].
    pub fn crest_blocks(&self, sight_point: DVec3, point: DVec3) -> bool {
        self.crest
            .blocks(self.surface, self.setup.eye.as_dvec3(), sight_point, point)
    }

    /// Size of the search structure: (slabs, bins, block entries, blocks). For tuning.
    pub fn structure_size(&self) -> [usize; 4] {
        self.structure.structure_size()
    }

    /// Work counters of one accelerated query: (blocks in the bin, blocks passing their box,
    /// facets tested by footprint, facets passing it, unbounded facets). For tuning.
    pub fn search_work(&self, point: Vec3) -> [usize; 5] {
        self.structure.search_work(point)
    }
}
