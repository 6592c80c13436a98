//! One frame's map pixel -> true position `P`, per object, as a piecewise-linear surface over the
//! pixel grid, with a bounding-volume hierarchy over its pieces. Receives a [`RenderedFrame`];
//! answers "where on screen, to a fraction of a pixel, does this frame see world point X of object
//! o?" with every image of X anywhere in the frame (no search window), or, where the frame does not
//! see X at all, the place of the nearest point it does see.
//!
//! The surface: the corners of grid cell (x, y) are the pixel centres (x, y), (x+1, y), (x, y+1)
//! and (x+1, y+1), each carrying its `P`. A cell whose four corners see one object and have no jump
//! in `P` between them (an object hiding part of itself) is two triangles along the (x, y)-(x+1, y+1)
//! diagonal, or along the other diagonal when only that one is free of jumps; a cell with three
//! such corners is one triangle. Pixels that belong to no triangle (objects one pixel thin) enter
//! as segments to their right and lower neighbours, or as points. Inside a piece, screen position
//! and `P` are interpolated with the same barycentric weights, so a point X lying on a piece is
//! seen at the barycentric combination of its corners' pixel coordinates.

use rayon::prelude::*;

use crate::draw::{RenderedFrame, NO_OBJECT};

/// A piece "contains" X when X is within this fraction of the piece's longest edge (in metres)
/// from it. The pixel-grid triangles are chords of the true surface: on smooth surfaces they lie
/// within about curvature x edge^2 / 8 of it (far below a tenth of an edge at one sample per
/// pixel), across a 90-degree crease within about 0.35 edge. A quarter of an edge accepts the first
/// and leaves the second to the nearest-point fallback, which finds the same place.
pub const CONTAINMENT_TOLERANCE: f64 = 0.25;

/// An edge between two pixels whose `P`s are further apart than this many times the smaller of the
/// two pixels' median steps to their neighbours (per pixel of distance) crosses a jump (an object
/// hiding part of itself: a deck's lip over its wall) and is not part of the surface. A smooth map
/// in perspective changes its step far less between neighbours.
pub const JUMP_FACTOR: f64 = 4.0;

/// Images of one point closer together on screen than this are one image: pieces next to the one
/// containing X also pass [`CONTAINMENT_TOLERANCE`] near their shared edges, and the best-fitting
/// piece among them is the image's place.
pub const IMAGE_SEPARATION_PX: f64 = 2.0;

/// An axis-aligned box: (min, max) corners.
type Bounds = ([f32; 3], [f32; 3]);

/// A point whose projection onto a triangle's plane has a barycentric weight below minus this is
/// beyond that triangle's edge. Slightly above 0 so that a point on an edge shared by two
/// triangles (f32 `P`, chords of a curved surface) is on both.
pub const EDGE_SLACK: f64 = 0.01;

/// Pieces per leaf of the hierarchy.
const LEAF_SIZE: usize = 8;

/// Where a frame sees a world point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    /// Sub-pixel screen coordinates, pixel (x, y) at (x, y).
    pub screen: [f64; 2],
    /// True when a piece contains the point (the frame sees it there); false when the frame does
    /// not see the point and `screen` is where it sees the nearest point of the same object.
    pub seen: bool,
}

/// A piece of the surface: three pixel indices (repeated for segments and points).
#[derive(Clone, Copy, Debug)]
struct Piece {
    corners: [u32; 3],
}

#[derive(Clone, Copy, Debug)]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    /// Leaf: first piece; internal: index of the first of its two (consecutive) children.
    first: u32,
    /// Pieces of a leaf; 0 for an internal node.
    count: u32,
}

impl Node {
    const EMPTY: Node = Node {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
        first: 0,
        count: 0,
    };

    fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] as f64 && p[k] <= self.max[k] as f64)
    }

    fn squared_distance(&self, p: [f64; 3]) -> f64 {
        (0..3)
            .map(|k| {
                let below = self.min[k] as f64 - p[k];
                let above = p[k] - self.max[k] as f64;
                below.max(above).max(0.0).powi(2)
            })
            .sum()
    }
}

/// A frame's position map with its index (see the module documentation).
pub struct PositionMap<'a> {
    frame: &'a RenderedFrame,
    /// Per pixel: the median distance in `P` to its same-object neighbours per pixel of screen
    /// distance (0 where it has none).
    steps: Vec<f32>,
    pieces: Vec<Piece>,
    nodes: Vec<Node>,
    /// (object, root node), sorted by object.
    roots: Vec<(u32, u32)>,
}

fn is_finite(p: [f32; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

fn to_f64(p: [f32; 3]) -> [f64; 3] {
    p.map(|c| c as f64)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn length(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Spreads the low 21 bits of `v` to every third bit (for a 63-bit Morton code).
fn spread_bits(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x1f00000000ffff;
    x = (x | (x << 16)) & 0x1f0000ff0000ff;
    x = (x | (x << 8)) & 0x100f00f00f00f00f;
    x = (x | (x << 4)) & 0x10c30c30c30c30c3;
    x = (x | (x << 2)) & 0x1249249249249249;
    x
}

impl<'a> PositionMap<'a> {
    /// Builds the surface and its index. `frame.object` and `frame.position` must have one entry
    /// per pixel (the caller checks).
    pub fn build(frame: &'a RenderedFrame) -> PositionMap<'a> {
        let (width, height) = (frame.width as usize, frame.height as usize);
        let mut map = PositionMap {
            frame,
            steps: Vec::new(),
            pieces: Vec::new(),
            nodes: Vec::new(),
            roots: Vec::new(),
        };
        map.steps = (0..width * height)
            .into_par_iter()
            .map(|index| map.median_step(index))
            .collect();
        let cells: Vec<Vec<Piece>> = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut row = Vec::new();
                for x in 0..width {
                    map.cell_pieces(x, y, &mut row);
                }
                row
            })
            .collect();
        let mut pieces: Vec<Piece> = cells.into_iter().flatten().collect();
        let mut covered = vec![false; width * height];
        for piece in &pieces {
            for &corner in &piece.corners {
                covered[corner as usize] = true;
            }
        }
        // Pixels on no triangle: segments to their neighbours, else points.
        for y in 0..height {
            for x in 0..width {
                let index = y * width + x;
                if covered[index] || map.object_at(index).is_none() {
                    continue;
                }
                let mut linked = false;
                for (dx, dy) in [(1, 0), (0, 1), (-1, 0), (0, -1)] {
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    if nx < 0 || ny < 0 || nx >= width as isize || ny >= height as isize {
                        continue;
                    }
                    let neighbour = ny as usize * width + nx as usize;
                    if map.edge_is_usable(index, neighbour) {
                        linked = true;
                        // Each segment once: from the pixel with the lower index.
                        if neighbour > index || covered[neighbour] {
                            pieces.push(Piece {
                                corners: [index as u32, neighbour as u32, neighbour as u32],
                            });
                        }
                    }
                }
                if !linked {
                    pieces.push(Piece {
                        corners: [index as u32; 3],
                    });
                }
            }
        }
        map.index(pieces);
        map
    }

    fn index(&mut self, mut pieces: Vec<Piece>) {
        let boxes: Vec<([f32; 3], [f32; 3])> = pieces
            .par_iter()
            .map(|piece| self.piece_box(piece))
            .collect();
        let (low, high) = boxes.iter().fold(
            ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(lo, hi), (bmin, bmax)| {
                (
                    std::array::from_fn(|k| lo[k].min(bmin[k])),
                    std::array::from_fn(|k| hi[k].max(bmax[k])),
                )
            },
        );
        let scale: [f64; 3] =
            std::array::from_fn(|k| ((high[k] as f64 - low[k] as f64).max(1e-12)).recip());
        let mut keyed: Vec<((u32, u64), Piece, Bounds)> = pieces
            .par_iter()
            .zip(boxes.par_iter())
            .map(|(piece, &bounds)| {
                let object = self.frame.object[piece.corners[0] as usize];
                let code = (0..3).fold(0u64, |code, k| {
                    let centre = 0.5 * (bounds.0[k] as f64 + bounds.1[k] as f64);
                    let cell = ((centre - low[k] as f64) * scale[k] * 2_097_151.0) as u64;
                    code | (spread_bits(cell) << k)
                });
                ((object, code), *piece, bounds)
            })
            .collect();
        // Ties keep the pieces' order (pixel order), so the index is the same run to run.
        keyed.par_sort_by_key(|entry| entry.0);
        pieces = keyed.iter().map(|entry| entry.1).collect();
        let boxes: Vec<([f32; 3], [f32; 3])> = keyed.iter().map(|entry| entry.2).collect();
        self.pieces = pieces;
        let mut start = 0;
        while start < keyed.len() {
            let object = keyed[start].0 .0;
            let end = start + keyed[start..].partition_point(|entry| entry.0 .0 == object);
            let root = self.nodes.len();
            self.nodes.push(Node::EMPTY);
            self.build_node(root, start, end, &boxes);
            self.roots.push((object, root as u32));
            start = end;
        }
    }

    fn build_node(&mut self, node: usize, lo: usize, hi: usize, boxes: &[([f32; 3], [f32; 3])]) {
        if hi - lo <= LEAF_SIZE {
            let mut leaf = Node::EMPTY;
            for (bmin, bmax) in &boxes[lo..hi] {
                for k in 0..3 {
                    leaf.min[k] = leaf.min[k].min(bmin[k]);
                    leaf.max[k] = leaf.max[k].max(bmax[k]);
                }
            }
            leaf.first = lo as u32;
            leaf.count = (hi - lo) as u32;
            self.nodes[node] = leaf;
            return;
        }
        let left = self.nodes.len();
        self.nodes.push(Node::EMPTY);
        self.nodes.push(Node::EMPTY);
        let mid = lo + (hi - lo) / 2;
        self.build_node(left, lo, mid, boxes);
        self.build_node(left + 1, mid, hi, boxes);
        let (a, b) = (self.nodes[left], self.nodes[left + 1]);
        self.nodes[node] = Node {
            min: std::array::from_fn(|k| a.min[k].min(b.min[k])),
            max: std::array::from_fn(|k| a.max[k].max(b.max[k])),
            first: left as u32,
            count: 0,
        };
    }

    /// The object pixel `index` sees, when it sees one at a finite `P`.
    fn object_at(&self, index: usize) -> Option<u32> {
        let object = self.frame.object[index];
        (object != NO_OBJECT && is_finite(self.frame.position[index])).then_some(object)
    }

    /// The `P` of pixel `index`, in f64.
    pub fn position_of(&self, index: usize) -> [f64; 3] {
        to_f64(self.frame.position[index])
    }

    fn pixel(&self, index: usize) -> [f64; 2] {
        let width = self.frame.width as usize;
        [(index % width) as f64, (index / width) as f64]
    }

    fn median_step(&self, index: usize) -> f32 {
        let Some(object) = self.object_at(index) else {
            return 0.0;
        };
        let (width, height) = (self.frame.width as isize, self.frame.height as isize);
        let (x, y) = (index as isize % width, index as isize / width);
        let centre = self.position_of(index);
        let mut steps: Vec<f64> = Vec::with_capacity(8);
        for dy in -1..=1isize {
            for dx in -1..=1isize {
                let (nx, ny) = (x + dx, y + dy);
                if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= width || ny >= height {
                    continue;
                }
                let neighbour = (ny * width + nx) as usize;
                if self.object_at(neighbour) == Some(object) {
                    let distance = length(sub(self.position_of(neighbour), centre));
                    steps.push(distance / ((dx * dx + dy * dy) as f64).sqrt());
                }
            }
        }
        steps.sort_by(f64::total_cmp);
        steps.get(steps.len() / 2).copied().unwrap_or(0.0) as f32
    }

    /// The median step of pixel `index` (see [`JUMP_FACTOR`]).
    pub fn step(&self, index: usize) -> f64 {
        self.steps[index] as f64
    }

    /// Both pixels see the same object and no jump lies between them.
    pub fn edge_is_usable(&self, a: usize, b: usize) -> bool {
        let (Some(oa), Some(ob)) = (self.object_at(a), self.object_at(b)) else {
            return false;
        };
        if oa != ob {
            return false;
        }
        let (pa, pb) = (self.pixel(a), self.pixel(b));
        let screen = ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2)).sqrt();
        let distance = length(sub(self.position_of(a), self.position_of(b)));
        // The smaller step: a pixel at a corner of a patch has more neighbours across the jump
        // than on its own side, so its median is a step across the jump; its neighbour on the
        // other side still measures the smooth side's.
        distance <= JUMP_FACTOR * screen * self.step(a).min(self.step(b))
    }

    /// Every edge of the triangle is usable (so its corners see one object without a jump).
    pub fn triangle_is_usable(&self, corners: [usize; 3]) -> bool {
        self.edge_is_usable(corners[0], corners[1])
            && self.edge_is_usable(corners[1], corners[2])
            && self.edge_is_usable(corners[2], corners[0])
    }

    fn cell_pieces(&self, x: usize, y: usize, out: &mut Vec<Piece>) {
        let (width, height) = (self.frame.width as usize, self.frame.height as usize);
        if x + 1 >= width || y + 1 >= height {
            return;
        }
        let c00 = y * width + x;
        let (c10, c01, c11) = (c00 + 1, c00 + width, c00 + width + 1);
        // The (x, y)-(x+1, y+1) diagonal's two triangles, then the other diagonal's.
        let triples = [
            [c00, c10, c11],
            [c00, c11, c01],
            [c00, c10, c01],
            [c10, c11, c01],
        ];
        let usable = triples.map(|t| self.triangle_is_usable(t));
        let chosen: &[usize] = if usable[0] && usable[1] {
            &[0, 1]
        } else if usable[2] && usable[3] {
            &[2, 3]
        } else {
            &[0, 1, 2, 3]
        };
        for &t in chosen {
            if usable[t] {
                out.push(Piece {
                    corners: triples[t].map(|c| c as u32),
                });
            }
        }
    }

    /// The longest edge of a piece in metres; for a point, its pixel's step.
    fn piece_size(&self, corners: [usize; 3]) -> f64 {
        let p = corners.map(|c| self.position_of(c));
        let longest = [(0, 1), (1, 2), (2, 0)]
            .iter()
            .map(|&(i, j)| length(sub(p[i], p[j])))
            .fold(0.0, f64::max);
        if longest > 0.0 {
            longest
        } else {
            self.step(corners[0])
        }
    }

    fn piece_box(&self, piece: &Piece) -> ([f32; 3], [f32; 3]) {
        let corners = piece.corners.map(|c| c as usize);
        let margin = (CONTAINMENT_TOLERANCE * self.piece_size(corners)) as f32;
        let mut low = [f32::INFINITY; 3];
        let mut high = [f32::NEG_INFINITY; 3];
        for corner in corners {
            let p = self.frame.position[corner];
            for k in 0..3 {
                low[k] = low[k].min(p[k]);
                high[k] = high[k].max(p[k]);
            }
        }
        // Widened by a relative hair too, so rounding to f32 cannot leave a point outside.
        let hair = |v: f32| v.abs() * 1e-6;
        (
            std::array::from_fn(|k| low[k] - margin - hair(low[k])),
            std::array::from_fn(|k| high[k] + margin + hair(high[k])),
        )
    }

    /// The closest point of a piece to `target`: its distance (m) and screen position.
    fn closest_on_piece(&self, piece: &Piece, target: [f64; 3]) -> (f64, [f64; 2]) {
        let corners = piece.corners.map(|c| c as usize);
        let p = corners.map(|c| self.position_of(c));
        let s = corners.map(|c| self.pixel(c));
        let weights = closest_point_weights(p, target);
        let point: [f64; 3] = std::array::from_fn(|k| {
            weights[0] * p[0][k] + weights[1] * p[1][k] + weights[2] * p[2][k]
        });
        let screen = std::array::from_fn(|k| {
            weights[0] * s[0][k] + weights[1] * s[1][k] + weights[2] * s[2][k]
        });
        (length(sub(point, target)), screen)
    }

    fn root(&self, object: u32) -> Option<usize> {
        self.roots
            .binary_search_by_key(&object, |&(o, _)| o)
            .ok()
            .map(|at| self.roots[at].1 as usize)
    }

    /// Every place where the frame sees `target` on `object`: one per image (pieces within
    /// [`IMAGE_SEPARATION_PX`] of a better-fitting one are the same image), best fit first.
    pub fn images_of(&self, target: [f32; 3], object: u32) -> Vec<[f64; 2]> {
        self.candidates(target, object).0
    }

    /// The images of `target` ([`Self::images_of`]), and the places on pieces that pass the
    /// containment tolerance but lie just beyond an edge (a silhouette, a fold), where the frame
    /// nearly sees it.
    fn candidates(&self, target: [f32; 3], object: u32) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
        let Some(root) = self.root(object) else {
            return (Vec::new(), Vec::new());
        };
        let target = to_f64(target);
        let mut found: Vec<(f64, [f64; 2])> = Vec::new();
        let mut nearly: Vec<[f64; 2]> = Vec::new();
        let mut stack = vec![root];
        while let Some(node) = stack.pop() {
            let node = self.nodes[node];
            if !node.contains(target) {
                continue;
            }
            if node.count == 0 {
                stack.push(node.first as usize);
                stack.push(node.first as usize + 1);
                continue;
            }
            for piece in &self.pieces[node.first as usize..(node.first + node.count) as usize] {
                let corners = piece.corners.map(|c| c as usize);
                let size = self.piece_size(corners);
                let (distance, screen) = self.closest_on_piece(piece, target);
                if distance > CONTAINMENT_TOLERANCE * size {
                    continue;
                }
                // Beyond a triangle's edge is not on it, however close: a point just past a
                // silhouette is not seen there (it would measure as on the edge).
                let beyond_an_edge =
                    projection_weights(corners.map(|c| self.position_of(c)), target)
                        .is_some_and(|w| w.iter().any(|&c| c < -EDGE_SLACK));
                if beyond_an_edge {
                    nearly.push(screen);
                } else {
                    // Relative to the piece's size, so fits on pieces of different sizes compare.
                    let fit = if size > 0.0 { distance / size } else { 0.0 };
                    found.push((fit, screen));
                }
            }
        }
        found.sort_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1[1].total_cmp(&b.1[1]))
                .then(a.1[0].total_cmp(&b.1[0]))
        });
        let mut images: Vec<[f64; 2]> = Vec::new();
        for (_, screen) in found {
            let separate = images.iter().all(|image| {
                (image[0] - screen[0]).hypot(image[1] - screen[1]) >= IMAGE_SEPARATION_PX
            });
            if separate {
                images.push(screen);
            }
        }
        (images, nearly)
    }

    /// Where the frame sees the point of `object` nearest `target` (3-D distance), when it sees
    /// any point of that object.
    pub fn nearest_seen(&self, target: [f32; 3], object: u32) -> Option<[f64; 2]> {
        let root = self.root(object)?;
        let target = to_f64(target);
        let mut best: Option<(f64, [f64; 2])> = None;
        let mut stack = vec![root];
        while let Some(node) = stack.pop() {
            let node = self.nodes[node];
            let bound = node.squared_distance(target);
            if best.is_some_and(|(d, _)| bound >= d * d) {
                continue;
            }
            if node.count == 0 {
                let (a, b) = (node.first as usize, node.first as usize + 1);
                // The nearer child last, so it is searched first.
                if self.nodes[a].squared_distance(target) < self.nodes[b].squared_distance(target) {
                    stack.push(b);
                    stack.push(a);
                } else {
                    stack.push(a);
                    stack.push(b);
                }
                continue;
            }
            for piece in &self.pieces[node.first as usize..(node.first + node.count) as usize] {
                let (distance, screen) = self.closest_on_piece(piece, target);
                if best.is_none_or(|(d, _)| distance < d) {
                    best = Some((distance, screen));
                }
            }
        }
        best.map(|(_, screen)| screen)
    }

    /// Where the frame sees `target` on `object`, nearest to screen point `near` among its images.
    /// When it does not see `target` (`seen` false): the nearest place, to `near`, just beyond an
    /// edge where it nearly does (within the containment tolerance: a silhouette, or a sheet's end
    /// at a fold, where one sample per pixel cannot tell), else where it sees the object's point
    /// nearest `target`. Images come first: a neighbouring piece's edge is often nearer to `near`
    /// than the image itself.
    pub fn place_of(&self, target: [f32; 3], object: u32, near: [f64; 2]) -> Option<Place> {
        let (images, nearly) = self.candidates(target, object);
        let nearest = |places: Vec<[f64; 2]>| {
            places.into_iter().min_by(|a, b| {
                let da = (a[0] - near[0]).hypot(a[1] - near[1]);
                let db = (b[0] - near[0]).hypot(b[1] - near[1]);
                da.total_cmp(&db)
            })
        };
        if let Some(screen) = nearest(images) {
            return Some(Place { screen, seen: true });
        }
        nearest(nearly)
            .or_else(|| self.nearest_seen(target, object))
            .map(|screen| Place {
                screen,
                seen: false,
            })
    }
}

/// Barycentric weights of `target`'s orthogonal projection onto the plane of triangle `p`, not
/// clamped to the triangle (a weight below 0: beyond the edge opposite that corner); `None` for a
/// triangle without area.
fn projection_weights(p: [[f64; 3]; 3], target: [f64; 3]) -> Option<[f64; 3]> {
    let (e1, e2, r) = (sub(p[1], p[0]), sub(p[2], p[0]), sub(target, p[0]));
    let (d11, d12, d22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
    let det = d11 * d22 - d12 * d12;
    if det <= 1e-18 * d11.max(d22).powi(2) {
        return None;
    }
    let (r1, r2) = (dot(r, e1), dot(r, e2));
    let v = (d22 * r1 - d12 * r2) / det;
    let w = (d11 * r2 - d12 * r1) / det;
    Some([1.0 - v - w, v, w])
}

/// Barycentric weights of the point of triangle `p` nearest `target` (Ericson, Real-Time Collision
/// Detection, 5.1.5), for degenerate triangles (segments, points) too.
fn closest_point_weights(p: [[f64; 3]; 3], target: [f64; 3]) -> [f64; 3] {
    let ab = sub(p[1], p[0]);
    let ac = sub(p[2], p[0]);
    let normal = cross(ab, ac);
    let scale = dot(ab, ab).max(dot(ac, ac));
    if dot(normal, normal) <= 1e-18 * scale * scale {
        return closest_on_degenerate(p, target);
    }
    let ap = sub(target, p[0]);
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(target, p[1]);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(target, p[2]);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denominator = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denominator, vc * denominator);
    [1.0 - v - w, v, w]
}

/// A triangle without area: the nearest point over its three edges (or its one point).
fn closest_on_degenerate(p: [[f64; 3]; 3], target: [f64; 3]) -> [f64; 3] {
    let mut best = ([1.0, 0.0, 0.0], length(sub(target, p[0])));
    for (i, j) in [(0usize, 1usize), (1, 2), (2, 0)] {
        let edge = sub(p[j], p[i]);
        let squared = dot(edge, edge);
        let t = if squared > 0.0 {
            (dot(sub(target, p[i]), edge) / squared).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let point: [f64; 3] = std::array::from_fn(|k| p[i][k] + t * edge[k]);
        let distance = length(sub(target, point));
        if distance < best.1 {
            let mut weights = [0.0; 3];
            weights[i] = 1.0 - t;
            weights[j] += t;
            best = (weights, distance);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_weights_cover_every_region() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12);
        assert!(close(
            closest_point_weights(p, [0.25, 0.25, 0.3]),
            [0.5, 0.25, 0.25]
        ));
        assert!(close(
            closest_point_weights(p, [-1.0, -1.0, 0.0]),
            [1.0, 0.0, 0.0]
        ));
        assert!(close(
            closest_point_weights(p, [2.0, -0.1, 0.0]),
            [0.0, 1.0, 0.0]
        ));
        assert!(close(
            closest_point_weights(p, [0.5, -1.0, 0.0]),
            [0.5, 0.5, 0.0]
        ));
        assert!(close(
            closest_point_weights(p, [1.0, 1.0, 0.0]),
            [0.0, 0.5, 0.5]
        ));
        // A segment (repeated corner) and a point.
        let segment = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let w = closest_point_weights(segment, [0.5, 1.0, 0.0]);
        assert!(
            (w[0] - 0.75).abs() < 1e-12 && (w[1] + w[2] - 0.25).abs() < 1e-12,
            "{w:?}"
        );
        let point = [[1.0, 2.0, 3.0]; 3];
        let w = closest_point_weights(point, [0.0, 0.0, 0.0]);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn projection_weights_are_unclamped() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let w = projection_weights(p, [0.25, 0.5, 7.0]).unwrap();
        assert!(
            (w[0] - 0.25).abs() < 1e-12
                && (w[1] - 0.25).abs() < 1e-12
                && (w[2] - 0.5).abs() < 1e-12
        );
        let beyond = projection_weights(p, [-0.3, 0.5, 0.0]).unwrap();
        assert!((beyond[1] + 0.3).abs() < 1e-12, "{beyond:?}");
        assert!(
            projection_weights([[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [0.0; 3]).is_none()
        );
    }

    #[test]
    fn morton_bits_interleave() {
        assert_eq!(spread_bits(0b1), 0b1);
        assert_eq!(spread_bits(0b11), 0b1001);
        assert_eq!(spread_bits(0x1f_ffff).count_ones(), 21);
    }
}
