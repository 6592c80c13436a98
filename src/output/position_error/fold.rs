//! The folds of a frame's position map and the band around them. Receives a [`PositionMap`];
//! returns a per-pixel mask of the pixels within [`FOLD_BAND_PX`] of a fold.
//!
//! A fold is a caustic line in screen space: seen through a focusing wave, the map pixel -> `P`
//! turns back on itself, so the pixels on either side of the line see the same strip of the object
//! twice, mirrored. At the line the map's Jacobian is singular: one sample per pixel cannot say
//! where the images are, and no local linear fit holds there. Detection, exactly: cut every grid
//! cell whose four corners are usable (see [`PositionMap::triangle_is_usable`]) into its two
//! triangles along the (x, y)-(x+1, y+1) diagonal, corners in the same screen winding, and give
//! each triangle the normal n = (P1 - P0) x (P2 - P0). Where the map keeps its orientation,
//! neighbouring triangles' normals agree; where it folds, they point opposite ways. A **fold edge**
//! is an edge shared by two such triangles with n1 . n2 < [`FOLD_COSINE`] |n1| |n2|. The fold line
//! of the smooth map crosses one of the two triangles, so it lies within one pixel of the edge; the
//! band, pixels whose centre lies within [`FOLD_BAND_PX`] of a fold edge (3 px across a straight
//! fold), covers it with half a pixel to spare.
//!
//! Only the map's geometry is used (no normals or rays from the renderer), so a knife edge seen
//! on both of its faces within a pixel (faces less than 60 degrees apart) reads as a fold too: the
//! map folds there as well, and its samples are as unreliable.

use super::map::{cross, PositionMap};

/// Half-width of the fold band, pixels: a pixel belongs to it when its centre is within this
/// distance of a fold edge.
pub const FOLD_BAND_PX: f64 = 1.5;

/// Neighbouring triangles whose normals are more than 120 degrees apart are folded against each
/// other. Both sheets of a fold lie on one surface, so their normals are nearly opposite (the
/// cosine near -1); a crease of the object itself (a box's edge, the pool's floor meeting its wall)
/// turns the normal by 90 degrees or less and stays well above this.
pub const FOLD_COSINE: f64 = -0.5;

/// A frame's folds.
#[derive(Clone, Debug, PartialEq)]
pub struct FoldBand {
    /// Per pixel: within [`FOLD_BAND_PX`] of a fold edge.
    pub mask: Vec<bool>,
    /// Fold edges found.
    pub fold_edges: usize,
}

impl FoldBand {
    pub fn pixels(&self) -> usize {
        self.mask.iter().filter(|&&m| m).count()
    }
}

fn is_folded(a: [f64; 3], b: [f64; 3]) -> bool {
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let lengths = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
        * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    lengths > 0.0 && dot < FOLD_COSINE * lengths
}

/// The folds of `map`'s frame (see the module documentation).
pub fn fold_band(map: &PositionMap<'_>, width: u32, height: u32) -> FoldBand {
    use rayon::prelude::*;
    let (width, height) = (width as usize, height as usize);
    let mut mask = vec![false; width * height];
    if width < 2 || height < 2 {
        return FoldBand {
            mask,
            fold_edges: 0,
        };
    }
    let (cells_x, cells_y) = (width - 1, height - 1);
    // Per cell, the normals of its triangles (x, y)-(x+1, y)-(x+1, y+1) and
    // (x, y)-(x+1, y+1)-(x, y+1), where usable.
    let normals: Vec<[Option<[f64; 3]>; 2]> = (0..cells_x * cells_y)
        .into_par_iter()
        .map(|cell| {
            let (x, y) = (cell % cells_x, cell / cells_x);
            let c00 = y * width + x;
            let (c10, c01, c11) = (c00 + 1, c00 + width, c00 + width + 1);
            [[c00, c10, c11], [c00, c11, c01]].map(|corners| {
                map.triangle_is_usable(corners).then(|| {
                    let p = corners.map(|c| map.position_of(c));
                    let ab = std::array::from_fn(|k| p[1][k] - p[0][k]);
                    let ac = std::array::from_fn(|k| p[2][k] - p[0][k]);
                    cross(ab, ac)
                })
            })
        })
        .collect();
    // Fold edges as segments between pixel centres.
    let mut edges: Vec<([f64; 2], [f64; 2])> = Vec::new();
    for y in 0..cells_y {
        for x in 0..cells_x {
            let [upper, lower] = normals[y * cells_x + x];
            let Some(upper) = upper else {
                // Its three shared edges all need it.
                continue;
            };
            let (xf, yf) = (x as f64, y as f64);
            if lower.is_some_and(|lower| is_folded(upper, lower)) {
                edges.push(([xf, yf], [xf + 1.0, yf + 1.0]));
            }
            if y > 0 && normals[(y - 1) * cells_x + x][1].is_some_and(|n| is_folded(upper, n)) {
                edges.push(([xf, yf], [xf + 1.0, yf]));
            }
            if x + 1 < cells_x
                && normals[y * cells_x + x + 1][1].is_some_and(|n| is_folded(upper, n))
            {
                edges.push(([xf + 1.0, yf], [xf + 1.0, yf + 1.0]));
            }
        }
    }
    let reach = FOLD_BAND_PX.ceil() as isize;
    for (a, b) in &edges {
        let x0 = (a[0].min(b[0]) as isize - reach).max(0);
        let x1 = (a[0].max(b[0]) as isize + reach).min(width as isize - 1);
        let y0 = (a[1].min(b[1]) as isize - reach).max(0);
        let y1 = (a[1].max(b[1]) as isize + reach).min(height as isize - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if segment_distance([x as f64, y as f64], *a, *b) <= FOLD_BAND_PX {
                    mask[y as usize * width + x as usize] = true;
                }
            }
        }
    }
    FoldBand {
        mask,
        fold_edges: edges.len(),
    }
}

fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
    let squared = ex * ex + ey * ey;
    let t = if squared > 0.0 {
        (((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / squared).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * ex).hypot(p[1] - a[1] - t * ey)
}
