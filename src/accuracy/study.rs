//! The thesis's accuracy study, row by row: receives the setup choices the thesis leaves open
//! (ring faceting, sample spacing); returns, for every row of its Tables 4.1, 4.2 (bowls and caps)
//! and 4.5 (flat grids), the linear and exact methods' error statistics beside the published
//! means, and formats them as Markdown and CSV.

use std::fmt::Write as _;

use super::membranes::{Orientation, RingFaceting, ThesisMembrane, PLANAR_RADIUS};
use super::volume::{measure_volume, VolumeResult, VolumeSetup, CUBE_SIDE};

/// Default sample spacing: 40^3 = 64,000 samples in the cube. The thesis's "Data Points" (6,988 to
/// 56,890 counted samples per volume) are of that order.
pub const DEFAULT_SPACING: f64 = 10.0;

/// The refractor of a row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    FlatDisk,
    Sphere {
        radius: f64,
        orientation: Orientation,
    },
    /// Flat square grid of `cells` x `cells` squares.
    Grid {
        cells: u32,
    },
}

/// One row of the thesis's tables.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StudyRow {
    /// "4.1", "4.2" or "4.5".
    pub table: &'static str,
    pub shape: Shape,
    pub eye_height: f64,
    pub eye_displacement: f64,
    /// The thesis's published mean error and standard deviation, scene units.
    pub thesis_mean: f64,
    pub thesis_std: f64,
}

impl StudyRow {
    /// A name without commas or spaces, for the CSV's `config` column.
    pub fn config(&self) -> String {
        let shape = match self.shape {
            Shape::FlatDisk => "flat-disk".to_string(),
            Shape::Sphere {
                radius,
                orientation,
            } => format!("{}-R{radius}", orientation.name()),
            Shape::Grid { cells } => format!("grid-{cells}x{cells}"),
        };
        let mut name = format!("t{}/{shape}/eye{}", self.table, self.eye_height);
        if self.table == "4.1" {
            write!(name, "/offset{}", self.eye_displacement).unwrap();
        }
        name
    }

    pub fn membrane(&self, faceting: RingFaceting) -> ThesisMembrane {
        match self.shape {
            Shape::FlatDisk => ThesisMembrane::flat_disk(faceting),
            Shape::Sphere {
                radius,
                orientation,
            } => ThesisMembrane::sphere(radius, orientation, faceting),
            Shape::Grid { cells } => ThesisMembrane::square_grid(cells),
        }
    }
}

/// Every row reproduced: Table 4.1 (flat disk; eye 900, 450, 150 above; displaced 0, 142, 400,
/// 800 sideways), Table 4.2 (sphere radius infinite = the flat disk, then 710 ... 142 =
/// hemisphere, eye 450 above; as bowls and as caps, the thesis's figures beside both), Table 4.5
/// (flat square grids 6x6, 10x10, 15x15, eye 450 and 150 above). Table 4.5's "hemisphere up" rows
/// are left out: a 284-unit square cannot conform to a sphere of planar radius 142, and the thesis
/// does not say how its square hemisphere was made.
pub fn thesis_rows() -> Vec<StudyRow> {
    let mut rows = Vec::new();
    let row = |table, shape, eye_height, eye_displacement, thesis_mean, thesis_std| StudyRow {
        table,
        shape,
        eye_height,
        eye_displacement,
        thesis_mean,
        thesis_std,
    };
    // Table 4.1: height, displacement, mean, std.
    for &(height, displacement, mean, std) in &[
        (900.0, 0.0, 0.0154, 0.0085),
        (900.0, 142.0, 0.0262, 0.0186),
        (900.0, 400.0, 0.0529, 0.0308),
        (900.0, 800.0, 0.0523, 0.0290),
        (450.0, 0.0, 0.0928, 0.0319),
        (450.0, 142.0, 0.1364, 0.0963),
        (450.0, 400.0, 0.1626, 0.0972),
        (450.0, 800.0, 0.0670, 0.0363),
        (150.0, 0.0, 1.2789, 0.6813),
        (150.0, 142.0, 1.0994, 0.7749),
        (150.0, 400.0, 0.2441, 0.1575),
        (150.0, 800.0, 0.0568, 0.0372),
    ] {
        rows.push(row("4.1", Shape::FlatDisk, height, displacement, mean, std));
    }
    // Table 4.2: the planar row (R = infinity), then the spheres.
    rows.push(row("4.2", Shape::FlatDisk, 450.0, 0.0, 0.0928, 0.0519));
    for orientation in [Orientation::Bowl, Orientation::Cap] {
        for &(radius, mean, std) in &[
            (710.0, 0.1107, 0.0413),
            (355.0, 0.2082, 0.0811),
            (237.0, 0.4558, 0.1599),
            (178.0, 1.1152, 0.5790),
            (PLANAR_RADIUS, 7.5567, 9.2816),
        ] {
            let shape = Shape::Sphere {
                radius,
                orientation,
            };
            rows.push(row("4.2", shape, 450.0, 0.0, mean, std));
        }
    }
    // Table 4.5, planar rows.
    for &(height, cells, mean, std) in &[
        (450.0, 6, 0.1116, 0.0726),
        (450.0, 10, 0.0406, 0.0270),
        (450.0, 15, 0.0174, 0.0118),
        (150.0, 6, 1.6858, 0.9680),
        (150.0, 10, 0.6104, 0.3509),
        (150.0, 15, 0.2641, 0.1560),
    ] {
        rows.push(row("4.5", Shape::Grid { cells }, height, 0.0, mean, std));
    }
    rows
}

/// The choices the thesis leaves open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StudyOptions {
    pub faceting: RingFaceting,
    pub spacing: f64,
    pub n_above: f64,
    pub n_below: f64,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            faceting: RingFaceting::THESIS_FIT,
            spacing: DEFAULT_SPACING,
            n_above: 1.0,
            n_below: 1.51,
        }
    }
}

impl StudyOptions {
    pub fn volume_setup(&self, row: &StudyRow) -> VolumeSetup {
        VolumeSetup {
            eye_height: row.eye_height,
            eye_displacement: row.eye_displacement,
            n_above: self.n_above,
            n_below: self.n_below,
            spacing: self.spacing,
        }
    }

    /// Samples in one volume.
    pub fn samples_per_volume(&self) -> usize {
        VolumeSetup::thesis(450.0, self.spacing)
            .samples_per_axis()
            .pow(3)
    }
}

/// A measured row.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyResult {
    pub row: StudyRow,
    pub facets: usize,
    pub result: VolumeResult,
}

/// Measures `rows`; `on_samples` is told of every batch of samples done (for a progress bar).
pub fn run_study(
    rows: &[StudyRow],
    options: &StudyOptions,
    on_samples: &(dyn Fn(usize) + Sync),
) -> Vec<StudyResult> {
    rows.iter()
        .map(|row| {
            let membrane = row.membrane(options.faceting);
            let result = measure_volume(&membrane, &options.volume_setup(row), on_samples);
            StudyResult {
                row: *row,
                facets: membrane.triangles.len(),
                result,
            }
        })
        .collect()
}

fn row_label(row: &StudyRow) -> String {
    let shape = match row.shape {
        Shape::FlatDisk if row.table == "4.2" => "flat disk (R = inf)".to_string(),
        Shape::FlatDisk => "flat disk".to_string(),
        Shape::Sphere {
            radius,
            orientation,
        } if radius == PLANAR_RADIUS => format!("{} R = {radius} (hemisphere)", orientation.name()),
        Shape::Sphere {
            radius,
            orientation,
        } => format!("{} R = {radius}", orientation.name()),
        Shape::Grid { cells } => format!("grid {cells}x{cells}"),
    };
    let mut label = format!("{shape}, eye {}", row.eye_height);
    if row.eye_displacement != 0.0 {
        write!(label, " offset {}", row.eye_displacement).unwrap();
    }
    label
}

/// The setup paragraph: every choice made, so a reader can reproduce the figures.
pub fn describe_setup(options: &StudyOptions) -> String {
    let disk = ThesisMembrane::flat_disk(options.faceting);
    let radii: Vec<String> = options
        .faceting
        .circle_radii(PLANAR_RADIUS)
        .iter()
        .map(|r| format!("{r:.1}"))
        .collect();
    format!(
        "Setup: a {CUBE_SIDE}-unit cube of samples centred under the refractor, its top flush \
with the refractor's top, one sample at the centre of every {spacing}-unit cell \
({samples} samples); the eye (\"emitter\") at the row's height above the refractor's top, \
straight above its centre unless offset along x; n1 = {n1}, n2 = {n2}. Disk and sphere membranes: planar radius \
{PLANAR_RADIUS}, faceted in {rings} concentric rings, each {ratio} times as wide as the one inside \
it (circles at radii {radii}), 6k vertices on circle k: {facets} facets, {vertices} vertices; the \
sphere membranes lift those vertices onto the sphere, as bowls (concave toward the eye, rim on \
top: the refractor's top is the rim) and as caps (bulging toward the eye: its top is the apex). \
Grids: flat squares 284 units a side, two facets per cell. Vertex normals are the exact surface's.\n\
Linear = the thesis's algorithm: its plane-test cells over per-vertex refraction rays, every facet \
tested, the first image kept. Exact = Newton on Fermat's principle over the exact surface from the \
linear sight point; where Newton fails it keeps the linear point (counted in `fallbacks`). Error = \
|C - V|, C = S* + T* |V' - S*| / eta (exact intersection and refraction of the ray E -> V'). Both \
methods are measured on the same samples: excluded are those with no image (none), an \
extrapolated cell (extr.), more than one image (conv.: a zone of convergence or an overlap of \
neighbouring thesis cells) or no computed vertex (no C); samples above the exact surface are in \
the air, not under the refractor, and are left out (air).",
        spacing = options.spacing,
        samples = options.samples_per_volume(),
        n1 = options.n_above,
        n2 = options.n_below,
        rings = options.faceting.rings,
        ratio = options.faceting.width_ratio,
        radii = radii.join(", "),
        facets = disk.triangles.len(),
        vertices = disk.positions.len(),
    )
}

fn ratio(a: f64, b: f64) -> String {
    if a.is_finite() && b.is_finite() && b != 0.0 {
        let r = a / b;
        if r >= 1000.0 {
            format!("{r:.2e}")
        } else {
            format!("{r:.2}")
        }
    } else {
        "-".into()
    }
}

/// The Markdown table, one line per row, the two methods side by side with the thesis's mean.
pub fn markdown_table(results: &[StudyResult]) -> String {
    let mut out = String::new();
    out.push_str(
        "| table | refractor | facets | thesis mean | thesis std | linear mean | linear std \
| linear / thesis | exact mean | thesis / exact | counted | excluded (none/extr./conv./no C) \
| air | fallbacks |\n",
    );
    out.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|\n");
    for r in results {
        let v = &r.result;
        let e = &v.excluded;
        writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.4} | {:.4} | {} | {:.2e} | {} | {} | {} ({}/{}/{}/{}) | {} | {} |",
            r.row.table,
            row_label(&r.row),
            r.facets,
            r.row.thesis_mean,
            r.row.thesis_std,
            v.linear.mean,
            v.linear.std,
            ratio(v.linear.mean, r.row.thesis_mean),
            v.exact.mean,
            ratio(r.row.thesis_mean, v.exact.mean),
            v.linear.counted,
            e.total(),
            e.no_image,
            e.extrapolated,
            e.convergence,
            e.no_computed_vertex,
            v.in_air,
            v.newton_fallbacks,
        )
        .unwrap();
    }
    out
}

/// The CSV: `config,method,mean,std,counted,excluded,thesis_mean`, a line per row and method.
/// `excluded` is every excluded sample (no image + extrapolated + convergence + no computed vertex).
pub fn csv(results: &[StudyResult]) -> String {
    let mut out = String::from("config,method,mean,std,counted,excluded,thesis_mean\n");
    for r in results {
        for (method, stats) in [("linear", &r.result.linear), ("exact", &r.result.exact)] {
            writeln!(
                out,
                "{},{method},{:e},{:e},{},{},{}",
                r.row.config(),
                stats.mean,
                stats.std,
                stats.counted,
                r.result.excluded.total(),
                r.row.thesis_mean
            )
            .unwrap();
        }
    }
    out
}
