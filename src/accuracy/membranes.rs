//! The refractors of the thesis's accuracy studies (its chapter 4): each is an exact surface (a
//! [`HeightField`], for the exact solver and the ray intersection of the computed vertex) bounded
//! by an outline, plus its triangulated faceting whose vertices lie on the exact surface with the
//! exact surface's normals. Receives the shape's parameters; returns a [`ThesisMembrane`].
//!
//! Coordinates: y up, the eye above; every refractor's rim (the edge of its outline) is at y = 0.

use glam::{DQuat, DVec2, DVec3};

use crate::water::{FlatHeightField, HeightField};

/// Planar radius of the thesis's circular refractors (flat disk and sphere-conforming membranes),
/// and half the side of its square grids (284 units on a side), in scene units.
pub const PLANAR_RADIUS: f64 = 142.0;

/// Which way a sphere-conforming membrane curves, seen from the eye above it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// Concave toward the eye, rim at the top (a bowl): diverging. Table 4.2 fits these.
    Bowl,
    /// Convex toward the eye, bulging up (a cap), rim at the bottom.
    Cap,
}

impl Orientation {
    pub fn name(self) -> &'static str {
        match self {
            Orientation::Bowl => "bowl",
            Orientation::Cap => "cap",
        }
    }
}

/// Where the refractor exists in the horizontal plane: beyond it there is no surface, so a sight
/// point or a ray intersection outside the outline is no refraction at all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outline {
    Disk {
        radius: f64,
    },
    /// The square `|x| <= half_side, |z| <= half_side`.
    Square {
        half_side: f64,
    },
}

impl Outline {
    /// Whether (x, z) is on the refractor; `slack` (units) admits points a rounding error outside.
    pub fn contains(&self, xz: DVec2, slack: f64) -> bool {
        match *self {
            Outline::Disk { radius } => xz.length() <= radius + slack,
            Outline::Square { half_side } => xz.abs().max_element() <= half_side + slack,
        }
    }
}

/// A sphere of radius `radius` over the disk of radius `planar_radius`, rim at y = 0: the bowl's
/// lowest point (and the cap's apex) is `radius - sqrt(radius^2 - planar_radius^2)` from the rim;
/// `radius == planar_radius` is the hemisphere. Outside the disk the height is the rim's (0) and
/// the slope 0: there is no refractor there (see [`Outline`]), the values only keep callers finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereSurface {
    pub radius: f64,
    pub planar_radius: f64,
    pub orientation: Orientation,
}

impl SphereSurface {
    /// Height of the sphere's centre: above the rim for a bowl, below it for a cap.
    pub fn centre_y(&self) -> f64 {
        let offset = (self.radius * self.radius - self.planar_radius * self.planar_radius)
            .max(0.0)
            .sqrt();
        match self.orientation {
            Orientation::Bowl => offset,
            Orientation::Cap => -offset,
        }
    }

    /// The half of the sphere this membrane is part of, as a height field over the whole plane.
    pub fn half_sphere(&self) -> HalfSphere {
        HalfSphere {
            centre: DVec3::new(0.0, self.centre_y(), 0.0),
            radius: self.radius,
            side: match self.orientation {
                Orientation::Bowl => -1.0,
                Orientation::Cap => 1.0,
            },
        }
    }

    /// On the disk, rim included: rim vertices placed by cos/sin land a rounding error outside.
    fn on_disk(&self, x: f64, z: f64) -> bool {
        x * x + z * z <= self.planar_radius * self.planar_radius * (1.0 + 1e-12)
    }

    /// Lowest and highest height of the surface over its disk.
    pub fn height_range(&self) -> (f64, f64) {
        let centre = self.height(0.0, 0.0);
        (centre.min(0.0), centre.max(0.0))
    }
}

impl HeightField for SphereSurface {
    fn height(&self, x: f64, z: f64) -> f64 {
        if !self.on_disk(x, z) {
            return 0.0;
        }
        self.half_sphere().height(x, z)
    }

    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        if !self.on_disk(x, z) {
            return (0.0, 0.0);
        }
        self.half_sphere().gradient(x, z)
    }

    fn normal(&self, x: f64, z: f64) -> DVec3 {
        if !self.on_disk(x, z) {
            return DVec3::Y;
        }
        self.half_sphere().normal(x, z)
    }

    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        if !self.on_disk(x, z) {
            return (0.0, 0.0, 0.0);
        }
        self.half_sphere().hessian(x, z)
    }
}

/// The upper (`side = 1`) or lower (`side = -1`) half of a sphere as a height field,
/// `y = centre.y + side sqrt(R^2 - (x - cx)^2 - (z - cz)^2)`, its normal pointing up (out of the
/// sphere for the upper half, into it for the lower). Outside the sphere's silhouette the root is
/// taken as 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSphere {
    pub centre: DVec3,
    pub radius: f64,
    pub side: f64,
}

impl HalfSphere {
    /// Offsets from the centre and `q = sqrt(R^2 - dx^2 - dz^2)`.
    fn local(&self, x: f64, z: f64) -> (f64, f64, f64) {
        let (dx, dz) = (x - self.centre.x, z - self.centre.z);
        let q = (self.radius * self.radius - dx * dx - dz * dz)
            .max(0.0)
            .sqrt();
        (dx, dz, q)
    }
}

impl HeightField for HalfSphere {
    fn height(&self, x: f64, z: f64) -> f64 {
        self.centre.y + self.side * self.local(x, z).2
    }

    fn gradient(&self, x: f64, z: f64) -> (f64, f64) {
        // dq/dx = -dx / q: infinite on the silhouette (a hemisphere's rim is a vertical wall).
        let (dx, dz, q) = self.local(x, z);
        (-self.side * dx / q, -self.side * dz / q)
    }

    /// The sphere's own normal, `side (P - centre) / R`: exact also on the silhouette, where the
    /// slope is infinite and the height-field formula divides by zero.
    fn normal(&self, x: f64, z: f64) -> DVec3 {
        let (dx, dz, q) = self.local(x, z);
        DVec3::new(dx, self.side * q, dz) * (self.side / self.radius)
    }

    /// Analytic: `d2q/dx2 = -(R^2 - dz^2) / q^3`, `d2q/dxdz = -dx dz / q^3`,
    /// `d2q/dz2 = -(R^2 - dx^2) / q^3`.
    fn hessian(&self, x: f64, z: f64) -> (f64, f64, f64) {
        let (dx, dz, q) = self.local(x, z);
        let q3 = q * q * q;
        let r2 = self.radius * self.radius;
        let s = -self.side;
        (
            s * (r2 - dz * dz) / q3,
            s * dx * dz / q3,
            s * (r2 - dx * dx) / q3,
        )
    }
}

/// A chart of a surface around one of its points: the frame rotated so that the surface's normal
/// there points up (`chart_from_world`), and the surface as a height field in that frame. Newton on
/// Fermat's principle works on height fields; near a steep wall (a hemisphere's rim) the world's
/// height field is singular, the rotated one is not. The stationary points are the same.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceChart {
    pub chart_from_world: DQuat,
    pub field: ChartField,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChartField {
    Flat(FlatHeightField),
    Sphere(HalfSphere),
}

impl ChartField {
    pub fn as_height_field(&self) -> &dyn HeightField {
        match self {
            ChartField::Flat(flat) => flat,
            ChartField::Sphere(sphere) => sphere,
        }
    }
}

/// The exact surface of a thesis refractor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThesisSurface {
    Flat(FlatHeightField),
    Sphere(SphereSurface),
}

impl ThesisSurface {
    pub fn as_height_field(&self) -> &dyn HeightField {
        match self {
            ThesisSurface::Flat(flat) => flat,
            ThesisSurface::Sphere(sphere) => sphere,
        }
    }

    /// The chart around the surface point over `xz` (see [`SurfaceChart`]); flat water is its own.
    pub fn chart_at(&self, xz: DVec2) -> SurfaceChart {
        match self {
            ThesisSurface::Flat(flat) => SurfaceChart {
                chart_from_world: DQuat::IDENTITY,
                field: ChartField::Flat(*flat),
            },
            ThesisSurface::Sphere(sphere) => {
                let half = sphere.half_sphere();
                let chart_from_world = DQuat::from_rotation_arc(half.normal(xz.x, xz.y), DVec3::Y);
                let rotated = HalfSphere {
                    centre: chart_from_world * half.centre,
                    ..half
                };
                SurfaceChart {
                    chart_from_world,
                    field: ChartField::Sphere(rotated),
                }
            }
        }
    }

    /// Lowest and highest height of the surface over the refractor.
    pub fn height_range(&self) -> (f64, f64) {
        match self {
            ThesisSurface::Flat(flat) => (flat.level_m, flat.level_m),
            ThesisSurface::Sphere(sphere) => sphere.height_range(),
        }
    }
}

/// How the flat disk (and the sphere-conforming membranes over it) is faceted: a centre vertex and
/// `rings` concentric circles, circle k (1-based) carrying `6 k` vertices evenly spaced from angle 0
/// (nearly equilateral triangles when the rings are equally wide); each ring is `width_ratio` times
/// as wide as the ring inside it (below 1: finer toward the rim), the outermost circle on the rim.
/// The centre fan has 6 facets and ring k `6 (2k - 1)`: `6 rings^2` facets,
/// `1 + 3 rings (rings + 1)` vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RingFaceting {
    pub rings: u32,
    pub width_ratio: f64,
}

impl RingFaceting {
    /// ALGORITHM §8: an independent reimplementation fits the thesis's published means best with
    /// 4 rings and a ratio of about 0.9.
    pub const THESIS_FIT: RingFaceting = RingFaceting {
        rings: 4,
        width_ratio: 0.9,
    };

    /// Radii of the circles, innermost first, the last equal to `planar_radius`.
    pub fn circle_radii(&self, planar_radius: f64) -> Vec<f64> {
        let widths: Vec<f64> = (0..self.rings)
            .map(|k| self.width_ratio.powi(k as i32))
            .collect();
        let total: f64 = widths.iter().sum();
        let mut radius = 0.0;
        let mut radii: Vec<f64> = widths
            .iter()
            .map(|w| {
                radius += w / total * planar_radius;
                radius
            })
            .collect();
        // Exactly on the rim, whatever the rounding of the sum.
        if let Some(last) = radii.last_mut() {
            *last = planar_radius;
        }
        radii
    }
}

/// A thesis refractor: the exact surface, its outline and its faceting (f64 positions on the exact
/// surface, exact unit normals pointing to the eye's side, counter-clockwise facets seen from above).
#[derive(Clone, Debug, PartialEq)]
pub struct ThesisMembrane {
    /// What it is, for tables ("flat disk", "bowl R=355", "grid 10x10").
    pub name: String,
    pub surface: ThesisSurface,
    pub outline: Outline,
    pub positions: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl ThesisMembrane {
    fn from_planar(
        name: String,
        surface: ThesisSurface,
        outline: Outline,
        planar: &[DVec2],
        triangles: Vec<[u32; 3]>,
    ) -> Self {
        let field = surface.as_height_field();
        let positions = planar
            .iter()
            .map(|p| DVec3::new(p.x, field.height(p.x, p.y), p.y))
            .collect();
        let normals = planar.iter().map(|p| field.normal(p.x, p.y)).collect();
        ThesisMembrane {
            name,
            surface,
            outline,
            positions,
            normals,
            triangles,
        }
    }

    /// The flat disk of Table 4.1 (planar radius [`PLANAR_RADIUS`], at y = 0) in concentric rings.
    pub fn flat_disk(faceting: RingFaceting) -> Self {
        let (planar, triangles) = ring_faceting(faceting, PLANAR_RADIUS);
        Self::from_planar(
            "flat disk".into(),
            ThesisSurface::Flat(FlatHeightField { level_m: 0.0 }),
            Outline::Disk {
                radius: PLANAR_RADIUS,
            },
            &planar,
            triangles,
        )
    }

    /// A membrane conforming to a sphere of radius `radius` (Table 4.2): the disk's ring faceting,
    /// each vertex lifted (or lowered) onto the sphere. `radius` must be at least the planar radius
    /// ([`PLANAR_RADIUS`] = hemisphere).
    pub fn sphere(radius: f64, orientation: Orientation, faceting: RingFaceting) -> Self {
        assert!(
            radius >= PLANAR_RADIUS,
            "a sphere of radius {radius} cannot span a disk of radius {PLANAR_RADIUS}"
        );
        let (planar, triangles) = ring_faceting(faceting, PLANAR_RADIUS);
        let sphere = SphereSurface {
            radius,
            planar_radius: PLANAR_RADIUS,
            orientation,
        };
        Self::from_planar(
            format!("{} R={radius}", orientation.name()),
            ThesisSurface::Sphere(sphere),
            Outline::Disk {
                radius: PLANAR_RADIUS,
            },
            &planar,
            triangles,
        )
    }

    /// The flat square refractor of Table 4.5: 284 units on a side (at y = 0), `cells` x `cells`
    /// squares of two triangles each, cut along the same diagonal as the render's membranes.
    pub fn square_grid(cells: u32) -> Self {
        assert!(cells >= 1, "a grid needs at least one cell a side");
        let n = cells as usize + 1;
        let step = 2.0 * PLANAR_RADIUS / cells as f64;
        let planar: Vec<DVec2> = (0..n * n)
            .map(|i| {
                let (ix, iz) = (i % n, i / n);
                DVec2::new(
                    -PLANAR_RADIUS + ix as f64 * step,
                    -PLANAR_RADIUS + iz as f64 * step,
                )
            })
            .collect();
        let mut triangles = Vec::with_capacity(2 * (n - 1) * (n - 1));
        for iz in 0..n - 1 {
            for ix in 0..n - 1 {
                let v00 = (iz * n + ix) as u32;
                let v10 = v00 + 1;
                let v01 = v00 + n as u32;
                let v11 = v01 + 1;
                triangles.push([v00, v01, v11]);
                triangles.push([v00, v11, v10]);
            }
        }
        Self::from_planar(
            format!("grid {cells}x{cells}"),
            ThesisSurface::Flat(FlatHeightField { level_m: 0.0 }),
            Outline::Square {
                half_side: PLANAR_RADIUS,
            },
            &planar,
            triangles,
        )
    }

    /// Height of the refractor's top: the plane the error volume's cube is flush with.
    pub fn top_y(&self) -> f64 {
        self.surface.height_range().1
    }
}

/// Planar vertices and triangles of a disk of radius `radius` faceted in rings (see
/// [`RingFaceting`]); triangles counter-clockwise seen from above (+y).
pub fn ring_faceting(faceting: RingFaceting, radius: f64) -> (Vec<DVec2>, Vec<[u32; 3]>) {
    assert!(faceting.rings >= 1, "a disk needs at least one ring");
    assert!(
        faceting.width_ratio > 0.0 && faceting.width_ratio.is_finite(),
        "ring width ratio must be a positive number"
    );
    let radii = faceting.circle_radii(radius);
    let mut vertices = vec![DVec2::ZERO];
    // Index of the first vertex of each circle, and how many it has.
    let mut circles: Vec<(u32, u32)> = Vec::new();
    for (k, &r) in radii.iter().enumerate() {
        let count = 6 * (k as u32 + 1);
        circles.push((vertices.len() as u32, count));
        vertices.extend((0..count).map(|j| {
            let angle = std::f64::consts::TAU * j as f64 / count as f64;
            // In the xz plane, angle measured from +x toward -z: counter-clockwise seen from +y.
            DVec2::new(r * angle.cos(), -r * angle.sin())
        }));
    }
    let mut triangles = Vec::new();
    let (first, count) = circles[0];
    for j in 0..count {
        triangles.push([0, first + j, first + (j + 1) % count]);
    }
    for pair in circles.windows(2) {
        let ((inner_first, inner_count), (outer_first, outer_count)) = (pair[0], pair[1]);
        // Zip the two circles by angle: step whichever circle's next vertex comes first. Every
        // step makes one triangle; both circles are walked once around.
        let (mut i, mut o) = (0u32, 0u32);
        while i < inner_count || o < outer_count {
            let next_inner = (i + 1) as f64 / inner_count as f64;
            let next_outer = (o + 1) as f64 / outer_count as f64;
            let a = inner_first + i % inner_count;
            let b = outer_first + o % outer_count;
            if o < outer_count && (i >= inner_count || next_outer <= next_inner) {
                triangles.push([a, b, outer_first + (o + 1) % outer_count]);
                o += 1;
            } else {
                triangles.push([a, b, inner_first + (i + 1) % inner_count]);
                i += 1;
            }
        }
    }
    (vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_membranes() -> Vec<ThesisMembrane> {
        let mut all = vec![ThesisMembrane::flat_disk(RingFaceting::THESIS_FIT)];
        for &radius in &[710.0, 355.0, 237.0, 178.0, 142.0] {
            for orientation in [Orientation::Bowl, Orientation::Cap] {
                all.push(ThesisMembrane::sphere(
                    radius,
                    orientation,
                    RingFaceting::THESIS_FIT,
                ));
            }
        }
        for cells in [6, 10, 15] {
            all.push(ThesisMembrane::square_grid(cells));
        }
        all
    }

    fn facet_normal(m: &ThesisMembrane, t: [u32; 3]) -> DVec3 {
        let p = t.map(|i| m.positions[i as usize]);
        (p[1] - p[0]).cross(p[2] - p[0])
    }

    #[test]
    fn facet_and_vertex_counts() {
        for rings in 1..=7 {
            let faceting = RingFaceting {
                rings,
                width_ratio: 0.9,
            };
            let disk = ThesisMembrane::flat_disk(faceting);
            assert_eq!(disk.triangles.len() as u32, 6 * rings * rings);
            assert_eq!(disk.positions.len() as u32, 1 + 3 * rings * (rings + 1));
        }
        for cells in [6u32, 10, 15] {
            let grid = ThesisMembrane::square_grid(cells);
            // The thesis: 6x6 has 49 vertices and 72 facets, 10x10 121 and 200, 15x15 256 and 450.
            assert_eq!(grid.positions.len() as u32, (cells + 1) * (cells + 1));
            assert_eq!(grid.triangles.len() as u32, 2 * cells * cells);
        }
        assert_eq!(ThesisMembrane::square_grid(6).triangles.len(), 72);
        assert_eq!(ThesisMembrane::square_grid(15).positions.len(), 256);
    }

    #[test]
    fn rings_follow_the_width_ratio_and_end_on_the_rim() {
        let radii = RingFaceting::THESIS_FIT.circle_radii(PLANAR_RADIUS);
        assert_eq!(radii.len(), 4);
        assert_eq!(radii[3], PLANAR_RADIUS);
        let widths: Vec<f64> = std::iter::once(radii[0])
            .chain(radii.windows(2).map(|w| w[1] - w[0]))
            .collect();
        for w in widths.windows(2) {
            assert!((w[1] / w[0] - 0.9).abs() < 1e-12, "{widths:?}");
        }
    }

    /// The faceting tiles the outline: facets are counter-clockwise seen from above, none
    /// degenerate, and their planar areas add up to the polygon the vertices outline (the disk's
    /// inscribed 6 rings-gon, the square exactly), so there are no holes or overlaps.
    #[test]
    fn facets_tile_the_outline_without_holes_or_overlaps() {
        for m in all_membranes() {
            let mut area = 0.0;
            for &t in &m.triangles {
                let p = t.map(|i| m.positions[i as usize]);
                let planar = (p[1] - p[0]).cross(p[2] - p[0]).y / 2.0;
                assert!(
                    planar > 1e-6,
                    "{}: facet {t:?} not counter-clockwise",
                    m.name
                );
                area += planar;
            }
            let expected = match m.outline {
                Outline::Square { half_side } => 4.0 * half_side * half_side,
                Outline::Disk { radius } => {
                    let n = m
                        .positions
                        .iter()
                        .filter(|p| (DVec2::new(p.x, p.z).length() - radius).abs() < 1e-9)
                        .count() as f64;
                    0.5 * n * radius * radius * (std::f64::consts::TAU / n).sin()
                }
            };
            assert!(
                (area - expected).abs() < 1e-9 * expected,
                "{}: {area} vs {expected}",
                m.name
            );
            // Every facet normal points to the eye's side.
            for &t in &m.triangles {
                assert!(facet_normal(&m, t).y > 0.0, "{}", m.name);
            }
        }
    }

    /// Vertices lie on the exact surface (the sphere itself, not just the height field) and their
    /// normals are the sphere's, unit and pointing to the eye's side.
    #[test]
    fn vertices_on_the_exact_surface_with_exact_normals() {
        for m in all_membranes() {
            let field = m.surface.as_height_field();
            for (p, n) in m.positions.iter().zip(&m.normals) {
                assert!((p.y - field.height(p.x, p.z)).abs() < 1e-12, "{}", m.name);
                assert!((n.length() - 1.0).abs() < 1e-12, "{}", m.name);
                assert!(n.y >= -1e-12, "{}: normal {n} points down", m.name);
                match m.surface {
                    ThesisSurface::Flat(_) => assert_eq!(*n, DVec3::Y),
                    ThesisSurface::Sphere(s) => {
                        let centre = DVec3::new(0.0, s.centre_y(), 0.0);
                        assert!(
                            ((*p - centre).length() - s.radius).abs() < 1e-9,
                            "{}",
                            m.name
                        );
                        // The normal is radial: parallel to P - centre.
                        let skew = (*p - centre).normalize().cross(*n).length();
                        assert!(skew < 1e-12, "{}: {p} skew {skew:e}", m.name);
                        // Away from the rim, the height field's normal from its gradient agrees.
                        if DVec2::new(p.x, p.z).length() < 0.99 * s.planar_radius {
                            let (gx, gz) = s.gradient(p.x, p.z);
                            let from_gradient = DVec3::new(-gx, 1.0, -gz).normalize();
                            assert!((from_gradient - *n).length() < 1e-12, "{}", m.name);
                        }
                    }
                }
            }
        }
        // Hemisphere: bottom of the bowl 142 below the rim, the cap's apex 142 above it; the rim's
        // normals are horizontal, pointing in (bowl) and out (cap).
        let bowl = SphereSurface {
            radius: 142.0,
            planar_radius: 142.0,
            orientation: Orientation::Bowl,
        };
        assert!((bowl.height(0.0, 0.0) + 142.0).abs() < 1e-12);
        assert!((bowl.normal(142.0, 0.0) - DVec3::NEG_X).length() < 1e-12);
        let cap = SphereSurface {
            orientation: Orientation::Cap,
            ..bowl
        };
        assert!((cap.height(0.0, 0.0) - 142.0).abs() < 1e-12);
        assert!((cap.normal(0.0, -142.0) - DVec3::NEG_Z).length() < 1e-12);
    }

    #[test]
    fn sphere_hessian_matches_differences_of_the_gradient() {
        for orientation in [Orientation::Bowl, Orientation::Cap] {
            let s = SphereSurface {
                radius: 237.0,
                planar_radius: 142.0,
                orientation,
            };
            for &(x, z) in &[(0.0, 0.0), (50.0, -30.0), (-100.0, 90.0)] {
                let step = 1e-4;
                let (gx_plus, gz_plus) = s.gradient(x + step, z);
                let (gx_minus, gz_minus) = s.gradient(x - step, z);
                let (_, gz_up) = s.gradient(x, z + step);
                let (_, gz_down) = s.gradient(x, z - step);
                let (hxx, hxz, hzz) = s.hessian(x, z);
                assert!((hxx - (gx_plus - gx_minus) / (2.0 * step)).abs() < 1e-8);
                assert!((hxz - (gz_plus - gz_minus) / (2.0 * step)).abs() < 1e-8);
                assert!((hzz - (gz_up - gz_down) / (2.0 * step)).abs() < 1e-8);
            }
        }
    }
}
