//! A bounding volume hierarchy over world-space triangles, built per frame: binned SAH on all three
//! axes (16 bins), subtrees built in parallel, nodes flattened depth-first (left child next to its
//! parent) in 32 bytes each, triangles stored as (v0, e1, e2) in leaf order for Möller-Trumbore
//! tests in f32. Closest-hit traversal visits the nearer child first and skips stack entries
//! farther than the best hit so far; an `accept` callback can reject hits (the ray then goes on).

use glam::Vec3;

/// Triangles per leaf at most, and below which a node is always a leaf.
const MAX_LEAF: usize = 8;
const MIN_LEAF: usize = 2;
const BINS: usize = 16;
/// Cost of visiting a node relative to one triangle test, for the SAH.
const TRAVERSAL_COST: f32 = 1.0;
/// Subtrees with more triangles than this are built on another rayon task.
const PARALLEL_BUILD: usize = 4096;
/// Barycentric slack of the triangle test: a ray through a shared edge hits one of its two
/// triangles even after f32 round-off (a few ulps of overlap, never a crack).
const EDGE_SLACK: f32 = 1e-6;

#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Node {
    min: Vec3,
    /// Leaf: first triangle (in leaf order). Interior: index of the right child (the left child
    /// is the next node).
    first_or_right: u32,
    max: Vec3,
    /// Triangles in a leaf; 0 for an interior node.
    count: u16,
    /// Axis the interior node was split on (0, 1, 2): children are visited in ray order along it.
    axis: u16,
}

/// A triangle as the traversal tests it.
#[derive(Clone, Copy, Debug)]
struct Packed {
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
}

/// A ray with its precomputed reciprocal direction.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    /// Need not be unit: `t` is in units of its length.
    pub direction: Vec3,
    inverse: Vec3,
}

impl Ray {
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Ray {
            origin,
            direction,
            inverse: direction.recip(),
        }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// Where a ray meets a triangle: parameter `t` and barycentrics `(1 - u - v, u, v)` of the
/// triangle's vertices 0, 1, 2; `triangle` is the index in the list the hierarchy was built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
}

/// The hierarchy (see the module docs).
pub struct Bvh {
    nodes: Vec<Node>,
    packed: Vec<Packed>,
    /// Original triangle index of each packed triangle.
    ids: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Bounds {
    min: Vec3,
    max: Vec3,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, other: &Bounds) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    fn grow_point(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    fn half_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// What the builder knows of each triangle.
#[derive(Clone, Copy)]
struct Item {
    bounds: Bounds,
    centroid: Vec3,
    id: u32,
}

impl Bvh {
    /// Builds the hierarchy over `triangles` (degenerate ones included: they are never hit).
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        let mut items: Vec<Item> = triangles
            .iter()
            .enumerate()
            .map(|(id, [a, b, c])| {
                let bounds = Bounds {
                    min: a.min(*b).min(*c),
                    max: a.max(*b).max(*c),
                };
                Item {
                    bounds,
                    centroid: (bounds.min + bounds.max) * 0.5,
                    id: id as u32,
                }
            })
            .collect();
        if items.is_empty() {
            return Bvh {
                nodes: Vec::new(),
                packed: Vec::new(),
                ids: Vec::new(),
            };
        }
        let nodes = build_subtree(&mut items, 0);
        let ids: Vec<u32> = items.iter().map(|item| item.id).collect();
        let packed = ids
            .iter()
            .map(|&id| {
                let [a, b, c] = triangles[id as usize];
                Packed {
                    v0: a,
                    e1: b - a,
                    e2: c - a,
                }
            })
            .collect();
        Bvh { nodes, packed, ids }
    }

    pub fn triangle_count(&self) -> usize {
        self.ids.len()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The nearest hit with `t` in `(t_min, t_max)` that `accept` takes.
    pub fn closest_hit(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mut accept: impl FnMut(&Hit) -> bool,
    ) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<Hit> = None;
        let mut t_far = t_max;
        let mut stack: [(u32, f32); 64] = [(0, 0.0); 64];
        let mut depth = 0usize;
        let mut current = 0u32;
        box_entry(&self.nodes[0], ray, t_min, t_far)?;
        let negative = [
            ray.direction.x < 0.0,
            ray.direction.y < 0.0,
            ray.direction.z < 0.0,
        ];
        loop {
            let node = &self.nodes[current as usize];
            if node.count > 0 {
                let first = node.first_or_right as usize;
                for index in first..first + node.count as usize {
                    if let Some((t, u, v)) = intersect(&self.packed[index], ray, t_min, t_far) {
                        let hit = Hit {
                            t,
                            triangle: self.ids[index],
                            u,
                            v,
                        };
                        if accept(&hit) {
                            t_far = t;
                            best = Some(hit);
                        }
                    }
                }
            } else {
                let (mut near, mut far) = (current + 1, node.first_or_right);
                if negative[node.axis as usize] {
                    std::mem::swap(&mut near, &mut far);
                }
                let near_entry = box_entry(&self.nodes[near as usize], ray, t_min, t_far);
                let far_entry = box_entry(&self.nodes[far as usize], ray, t_min, t_far);
                match (near_entry, far_entry) {
                    (Some(_), Some(far_t)) => {
                        stack[depth] = (far, far_t);
                        depth += 1;
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = near;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = far;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node still in front of the best hit.
            loop {
                if depth == 0 {
                    return best;
                }
                depth -= 1;
                let (node, entry) = stack[depth];
                if entry <= t_far {
                    current = node;
                    break;
                }
            }
        }
    }

    /// The same answer as [`Self::closest_hit`] by testing every triangle: the oracle.
    pub fn brute_force_hit(
        triangles: &[[Vec3; 3]],
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_far = t_max;
        for (id, [a, b, c]) in triangles.iter().enumerate() {
            let packed = Packed {
                v0: *a,
                e1: *b - *a,
                e2: *c - *a,
            };
            if let Some((t, u, v)) = intersect(&packed, ray, t_min, t_far) {
                t_far = t;
                best = Some(Hit {
                    t,
                    triangle: id as u32,
                    u,
                    v,
                });
            }
        }
        best
    }
}

/// Entry `t` of the ray into the node's box within `(t_min, t_max)`, if it meets it.
#[inline(always)]
fn box_entry(node: &Node, ray: &Ray, t_min: f32, t_max: f32) -> Option<f32> {
    let t0 = (node.min - ray.origin) * ray.inverse;
    let t1 = (node.max - ray.origin) * ray.inverse;
    let enter = t0.min(t1).max_element().max(t_min);
    let exit = t0.max(t1).min_element().min(t_max);
    (enter <= exit).then_some(enter)
}

/// Möller-Trumbore: `(t, u, v)` when the ray meets the triangle with `t` in `(t_min, t_max)`.
#[inline(always)]
fn intersect(tri: &Packed, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
    let p = ray.direction.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 {
        return None;
    }
    let inverse_det = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inverse_det;
    if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = ray.direction.dot(q) * inverse_det;
    if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
        return None;
    }
    let t = tri.e2.dot(q) * inverse_det;
    (t > t_min && t < t_max).then_some((t, u, v))
}

/// Builds the subtree over `items` (reordered in place into leaf order); triangle indices in the
/// leaves start at `offset`. Node indices are relative to the subtree's root.
fn build_subtree(items: &mut [Item], offset: usize) -> Vec<Node> {
    let mut bounds = Bounds::EMPTY;
    let mut centroids = Bounds::EMPTY;
    for item in items.iter() {
        bounds.grow(&item.bounds);
        centroids.grow_point(item.centroid);
    }
    let leaf = |items: &[Item]| Node {
        min: bounds.min,
        first_or_right: offset as u32,
        max: bounds.max,
        count: items.len() as u16,
        axis: 0,
    };
    let count = items.len();
    if count <= MIN_LEAF {
        return vec![leaf(items)];
    }
    let split = best_split(items, &bounds, &centroids);
    let (axis, mid) = match split {
        Some((axis, position, cost)) if cost < count as f32 || count > MAX_LEAF => {
            let mid = partition(items, |item| item.centroid[axis] < position);
            if mid == 0 || mid == count {
                // Every centroid on one side (they coincide): split the list in half.
                (axis, count / 2)
            } else {
                (axis, mid)
            }
        }
        None if count > MAX_LEAF => (0, count / 2),
        _ => return vec![leaf(items)],
    };
    let (left_items, right_items) = items.split_at_mut(mid);
    let (left, right) = if count > PARALLEL_BUILD {
        rayon::join(
            || build_subtree(left_items, offset),
            || build_subtree(right_items, offset + mid),
        )
    } else {
        (
            build_subtree(left_items, offset),
            build_subtree(right_items, offset + mid),
        )
    };
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    let right_index = 1 + left.len() as u32;
    nodes.push(Node {
        min: bounds.min,
        first_or_right: right_index,
        max: bounds.max,
        count: 0,
        axis: axis as u16,
    });
    let shift = |node: Node, by: u32| -> Node {
        if node.count == 0 {
            Node {
                first_or_right: node.first_or_right + by,
                ..node
            }
        } else {
            node
        }
    };
    nodes.extend(left.into_iter().map(|n| shift(n, 1)));
    nodes.extend(right.into_iter().map(|n| shift(n, right_index)));
    nodes
}

/// The binned SAH's best plane: (axis, centroid position, cost in triangle tests).
fn best_split(items: &[Item], bounds: &Bounds, centroids: &Bounds) -> Option<(usize, f32, f32)> {
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<(usize, f32, f32)> = None;
    for axis in 0..3 {
        let lo = centroids.min[axis];
        let extent = centroids.max[axis] - lo;
        if extent <= 0.0 || !extent.is_finite() {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut bin_bounds = [Bounds::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for item in items {
            let bin = (((item.centroid[axis] - lo) * scale) as usize).min(BINS - 1);
            bin_counts[bin] += 1;
            bin_bounds[bin].grow(&item.bounds);
        }
        // Sweep from the right, then from the left, evaluating the plane after each bin.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let mut running = Bounds::EMPTY;
        let mut n = 0;
        for bin in (1..BINS).rev() {
            running.grow(&bin_bounds[bin]);
            n += bin_counts[bin];
            right_area[bin] = running.half_area();
            right_count[bin] = n;
        }
        let mut running = Bounds::EMPTY;
        let mut n = 0;
        for bin in 0..BINS - 1 {
            running.grow(&bin_bounds[bin]);
            n += bin_counts[bin];
            let (nr, ar) = (right_count[bin + 1], right_area[bin + 1]);
            if n == 0 || nr == 0 {
                continue;
            }
            let cost =
                TRAVERSAL_COST + (running.half_area() * n as f32 + ar * nr as f32) / parent_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, lo + (bin + 1) as f32 / scale, cost));
            }
        }
    }
    best
}

/// Moves the items for which `left` holds to the front; returns how many there are.
fn partition(items: &mut [Item], left: impl Fn(&Item) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..items.len() {
        if left(&items[i]) {
            items.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seeded generator, with the points these tests draw.
    struct Random(crate::seeded::SplitMix64);
    impl Random {
        fn next(&mut self) -> f32 {
            self.0.unit_f32()
        }
        fn point(&mut self, scale: f32) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next()) * (2.0 * scale) - scale
        }
    }

    fn random_triangles(random: &mut Random, count: usize) -> Vec<[Vec3; 3]> {
        (0..count)
            .map(|_| {
                let centre = random.point(5.0);
                let size = 0.05 + 0.6 * random.next();
                [
                    centre + random.point(size),
                    centre + random.point(size),
                    centre + random.point(size),
                ]
            })
            .collect()
    }

    #[test]
    fn hits_equal_brute_force_on_random_triangles() {
        let mut random = Random(crate::seeded::SplitMix64::new(7));
        for count in [1usize, 2, 3, 9, 100, 5_000] {
            let triangles = random_triangles(&mut random, count);
            let bvh = Bvh::build(&triangles);
            assert_eq!(bvh.triangle_count(), count);
            let (mut hits, mut rays) = (0, 0);
            for _ in 0..2_000 {
                let origin = random.point(7.0);
                // Aim at a triangle's centroid half the time so many rays hit something.
                let direction = if random.next() < 0.5 {
                    let [a, b, c] = triangles[(random.next() * count as f32) as usize % count];
                    (a + b + c) / 3.0 - origin
                } else {
                    random.point(1.0)
                };
                let ray = Ray::new(origin, direction);
                let fast = bvh.closest_hit(&ray, 0.0, f32::INFINITY, |_| true);
                let slow = Bvh::brute_force_hit(&triangles, &ray, 0.0, f32::INFINITY);
                rays += 1;
                hits += usize::from(slow.is_some());
                match (fast, slow) {
                    (Some(f), Some(s)) => {
                        // Equal t: the same triangle or two meeting at exactly that point.
                        assert!(
                            f.triangle == s.triangle || (f.t - s.t).abs() <= 1e-6 * s.t,
                            "{count} triangles: {f:?} vs {s:?}"
                        );
                    }
                    (None, None) => {}
                    other => panic!("{count} triangles: {other:?}"),
                }
            }
            assert!(
                hits > rays / 4,
                "{hits} of {rays} rays hit: too few to test"
            );
        }
    }

    #[test]
    fn rejected_hits_let_the_ray_go_on_and_t_limits_hold() {
        // Three parallel squares at z = 1, 2, 3 facing the ray.
        let square = |z: f32| {
            [
                [
                    Vec3::new(-1.0, -1.0, z),
                    Vec3::new(1.0, -1.0, z),
                    Vec3::new(1.0, 1.0, z),
                ],
                [
                    Vec3::new(-1.0, -1.0, z),
                    Vec3::new(1.0, 1.0, z),
                    Vec3::new(-1.0, 1.0, z),
                ],
            ]
        };
        let triangles: Vec<[Vec3; 3]> = [1.0, 2.0, 3.0].into_iter().flat_map(square).collect();
        let bvh = Bvh::build(&triangles);
        let ray = Ray::new(Vec3::new(0.1, 0.2, 0.0), Vec3::Z);
        let first = bvh.closest_hit(&ray, 0.0, 10.0, |_| true).unwrap();
        assert!((first.t - 1.0).abs() < 1e-6);
        let past_first = bvh
            .closest_hit(&ray, 0.0, 10.0, |hit| hit.triangle >= 2)
            .unwrap();
        assert!((past_first.t - 2.0).abs() < 1e-6);
        assert!(bvh.closest_hit(&ray, 1.5, 10.0, |_| true).unwrap().t > 1.9);
        assert!(bvh.closest_hit(&ray, 0.0, 0.9, |_| true).is_none());
        // Barycentrics locate the point: (0.1, 0.2) on the first square.
        let [a, b, c] = triangles[first.triangle as usize];
        let point = a * (1.0 - first.u - first.v) + b * first.u + c * first.v;
        assert!((point - Vec3::new(0.1, 0.2, 1.0)).length() < 1e-6);
    }

    #[test]
    fn a_ray_through_a_shared_edge_hits() {
        // A fan of triangles around the origin; rays straight through every shared edge.
        let n = 12;
        let rim = |i: usize| {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            Vec3::new(a.cos(), a.sin(), 0.0)
        };
        let triangles: Vec<[Vec3; 3]> = (0..n).map(|i| [Vec3::ZERO, rim(i), rim(i + 1)]).collect();
        let bvh = Bvh::build(&triangles);
        for i in 0..n {
            for along in [0.1f32, 0.37, 0.5, 0.93] {
                let point = rim(i) * along;
                let ray = Ray::new(point + Vec3::Z, -Vec3::Z);
                let hit = bvh.closest_hit(&ray, 0.0, 5.0, |_| true);
                assert!(hit.is_some(), "edge {i} at {along}: missed");
            }
        }
    }
}
