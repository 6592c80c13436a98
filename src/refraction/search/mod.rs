//! The sight-facet search: per frame, the refraction cells of every membrane facet and a search
//! structure over them; per query point, EVERY image (facet, ray parameter, barycentrics, sight
//! point), merged where sight points coincide and with crest-blocked paths rejected.
//!
//! Receives the membrane, the exact surface, the optical setup and the height range of the query
//! points; returns a [`RefractionField`] answering [`RefractionField::images`] (accelerated) and
//! [`RefractionField::images_brute_force`] (every cell tested: the oracle). Both run the same f64
//! containment test on the cells they consider and the same merge and crest check afterwards; the
//! accelerated search only skips cells that provably cannot contain the point, so the two return
//! identical image sets.
//!
//! # The acceleration structure
//! For a ray going down (`T.y < 0`) the point at height y has horizontal position
//! `F_i(y) = A_i + y B_i` with `B_i = T.xz / T.y`, `A_i = P.xz - P.y B_i`: linear in y. A point of an
//! equal-t cell at height y is `sum b_j Q_j(t)` with `Q_j(t)` on ray j at height `y_j(t)`, so its
//! horizontal position is `sum b_j F_j(y) + sum b_j (y_j(t) - y) B_j`: inside the footprint triangle
//! `F_0 F_1 F_2 (y)` grown by `Delta * max|B_j - B|` for any common B (the `y_j(t) - y` average to
//! zero with the weights `b_j`), where `Delta` bounds how far the rays' heights at one t differ from
//! y (the facet's height span plus the spread of the `T.y`, times the largest t that can reach
//! height y). Membrane facets are grouped in blocks of `BLOCK_CELLS x BLOCK_CELLS` grid cells;
//! each block keeps boxes of its `A` and `B` and the `Delta` ingredients. `query_y_range` is cut in
//! depth slabs; per slab a uniform 2-D grid (CSR, counting sort, slabs built in parallel) lists the
//! blocks whose footprint over the slab can cover each bin. A query visits one bin, re-tests each
//! listed block's box at its exact height (in a form without divisions, `BlockQuery`), tests each
//! facet's footprint triangle grown by the block's `Delta` times the facet's own `B` spread (f32,
//! padded for rounding; the footprint lines of a block's facets are stored in structure-of-arrays
//! chunks of eight, `LaneChunk`, tested together) and runs the f64 cubic only on the survivors.
//! The crest check afterwards skips the walk under water when a slope bound proves it clear.
//! Slabs are a few blocks of footprint slide thick: a block listed in a bin but not covering the
//! point at its height costs one box test, far less than the build pass each extra slab costs. Facets with a ray that does not go
//!
//! The parts: [`field`] (the per-frame [`RefractionField`] and its queries), [`blocks`] (the
//! acceleration structure), [`crest`] (the crest check).

mod blocks;
mod crest;
mod field;
#[cfg(test)]
pub mod test_support;
#[cfg(test)]
mod tests;

#[cfg(test)]
pub(crate) use blocks::lanes_may_contain;
pub use crest::CREST_GUARD_PER_SPACING;
pub use field::{CellMode, Image, RefractionField, RefractionSetup, MERGE_DISTANCE_PER_FACET_SIZE};
