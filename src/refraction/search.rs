//! The sight-facet search: per frame, the refraction cells of every membrane facet and a search
//! structure over them; per query point, EVERY image (facet, ray parameter, barycentrics, sight
//! point), merged where sight points coincide and with crest-blocked paths rejected.
//! OWNER: refraction-search helper. The signatures below are the contract the virtual-geometry code
//! and the frame assembly are written against; bodies are to be written.

use glam::Vec3;

use crate::water::{HeightField, Membrane};

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

/// The refraction cells of one frame and the structure that searches them.
pub struct RefractionField<'a> {
    pub membrane: &'a Membrane,
    pub surface: &'a dyn HeightField,
    pub setup: RefractionSetup,
}

impl<'a> RefractionField<'a> {
    /// Builds rays, cells and the search structure for query points whose heights lie in
    /// `query_y_range` (min, max) — points outside it may be missed by `images` (not by brute force).
    pub fn build(
        membrane: &'a Membrane,
        surface: &'a dyn HeightField,
        setup: RefractionSetup,
        query_y_range: (f32, f32),
    ) -> Self {
        let _ = query_y_range;
        todo!("refraction-search helper: {:?}", setup)
        // (membrane, surface are stored)
        ;
        #[allow(unreachable_code)]
        Self { membrane, surface, setup }
    }

    /// Every image of `point` (cleared into `out`), ordered by facet index, coincident sight points
    /// merged, crest-blocked paths rejected. Accelerated.
    pub fn images(&self, point: Vec3, out: &mut Vec<Image>) {
        let _ = (point, out);
        todo!()
    }

    /// The same answer as [`Self::images`], by testing every cell: the test oracle.
    pub fn images_brute_force(&self, point: Vec3, out: &mut Vec<Image>) {
        let _ = (point, out);
        todo!()
    }
}
