//! `snell locate`: receives a scene, a frame and world points (a CSV of `x,y,z`); returns every
//! image of each point through that frame's water — virtual vertex, sight point, facet, whether an
//! extrapolated ray made it — exactly as a render of that frame computes them (the same
//! [`RenderJob::frame_water`], [`RenderJob::refraction_setup`] and accelerated
//! [`RefractionField::images`]), so anyone can check snell's geometry point by point.

use std::fmt::Write as _;
use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;

use super::{check_frame, ToolError};
use crate::frame::{Method, RenderJob};
use crate::refraction::exact::exact_images;
use crate::refraction::flat::virtual_vertex;
use crate::refraction::search::RefractionField;
use crate::refraction::split::{Side, WaterVolume};

/// The CSV columns `snell locate` prints, in order.
pub const CSV_HEADER: &str = "point,image,vx,vy,vz,sx,sy,sz,facet,extrapolated";

/// Where a point is relative to the frame's water.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointPlace {
    /// Over the water (or outside its extent): seen directly, no refracted image.
    Above { height_above_surface_m: Option<f64> },
    /// On the exact surface (within the splitter's tolerance) or under it: refracted.
    Under,
}

/// One image of a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocatedImage {
    /// Where the point appears: `V' = E + normalize(S - E)(|S - E| + eta |V - S|)`.
    pub virtual_vertex: Vec3,
    pub sight_point: Vec3,
    /// Membrane facet (index into the membrane's triangles) the point is seen through.
    pub facet: u32,
    pub extrapolated: bool,
}

/// Every image of one point, ordered by facet index (as the search returns them).
#[derive(Clone, Debug, PartialEq)]
pub struct LocatedPoint {
    pub point: Vec3,
    pub place: PointPlace,
    pub images: Vec<LocatedImage>,
}

/// Every image of each of `points` at `frame`, with [`RenderJob::method`]'s cells (for
/// [`Method::Exact`]: the exact images Newton reaches from them, as a render draws them).
pub fn locate(
    job: &RenderJob,
    frame: u32,
    points: &[Vec3],
) -> Result<Vec<LocatedPoint>, ToolError> {
    check_frame(job, frame)?;
    let mut stage_secs = Default::default();
    let water = job.frame_water(frame, &mut stage_secs)?;
    let heights = water.surface();
    let surface = water.exact_surface(&heights);
    let setup = job.refraction_setup(water.camera.eye);
    // The field answers heights between the frame's objects and water; widen it to the points so
    // the accelerated search covers them (outside its range it would test every cell instead).
    let query_y_range = points.iter().fold(water.query_y_range, |(low, high), p| {
        (low.min(p.y - 1e-3), high)
    });
    let field = RefractionField::build(&water.membrane, &surface, setup, query_y_range);
    let volume = WaterVolume {
        surface: &heights,
        extent: water.membrane.grid,
    };
    let eye = setup.eye.as_dvec3();
    let (n_above, n_below) = (setup.n_above as f64, setup.n_below as f64);
    Ok(points
        .par_iter()
        .map_init(Vec::new, |scratch, &point| {
            let point_f64 = point.as_dvec3();
            if volume.side_of(point_f64) == Side::Above {
                return LocatedPoint {
                    point,
                    place: PointPlace::Above {
                        height_above_surface_m: volume.height_above_surface_m(point_f64),
                    },
                    images: Vec::new(),
                };
            }
            field.images(point, scratch);
            if job.method == Method::Exact {
                // The exact method's images: one Newton solve from each linear one, as a render.
                let mut exact = Vec::new();
                exact_images(&field, point_f64, scratch, &mut exact);
                return LocatedPoint {
                    point,
                    place: PointPlace::Under,
                    images: exact
                        .iter()
                        .map(|image| LocatedImage {
                            virtual_vertex: virtual_vertex(
                                eye,
                                image.sight_point,
                                point_f64,
                                n_above,
                                n_below,
                            )
                            .as_vec3(),
                            sight_point: image.sight_point.as_vec3(),
                            facet: image.facet,
                            extrapolated: image.extrapolated,
                        })
                        .collect(),
                };
            }
            let images = scratch
                .iter()
                .map(|image| LocatedImage {
                    virtual_vertex: virtual_vertex(
                        eye,
                        image.sight_point.as_dvec3(),
                        point_f64,
                        n_above,
                        n_below,
                    )
                    .as_vec3(),
                    sight_point: image.sight_point,
                    facet: image.facet,
                    extrapolated: image.extrapolated,
                })
                .collect();
            LocatedPoint {
                point,
                place: PointPlace::Under,
                images,
            }
        })
        .collect())
}

/// Reads `x,y,z` points, one per line. A first line `x,y,z` (any case, spaces allowed) is a
/// header; blank lines and lines starting with `#` are skipped. Anything else that is not three
/// finite numbers is an error naming the file and line.
pub fn read_points_csv(path: &Path) -> Result<Vec<Vec3>, ToolError> {
    let bytes =
        crate::files::read_regular(path, crate::files::MAX_POINTS_BYTES).map_err(|error| {
            ToolError::InputFile {
                path: path.to_path_buf(),
                problem: format!("cannot read the points file: {error}"),
            }
        })?;
    let text = String::from_utf8(bytes).map_err(|error| ToolError::InputFile {
        path: path.to_path_buf(),
        problem: format!("the points file is not UTF-8 text: {error}"),
    })?;
    parse_points_csv(&text, path)
}

fn parse_points_csv(text: &str, path: &Path) -> Result<Vec<Vec3>, ToolError> {
    let mut points = Vec::new();
    let mut seen_content = false;
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
        let first_content = !seen_content;
        seen_content = true;
        if first_content
            && fields.len() == 3
            && fields
                .iter()
                .zip(["x", "y", "z"])
                .all(|(field, name)| field.eq_ignore_ascii_case(name))
        {
            continue;
        }
        let problem = |problem: String| ToolError::InputLine {
            path: path.to_path_buf(),
            line: index + 1,
            problem,
        };
        if fields.len() != 3 {
            return Err(problem(format!(
                "expected three comma-separated numbers x,y,z (metres, world space), found {} field(s): {trimmed:?}",
                fields.len()
            )));
        }
        let mut xyz = [0.0f32; 3];
        for (slot, (field, name)) in xyz.iter_mut().zip(fields.iter().zip(["x", "y", "z"])) {
            let value: f32 = field.parse().map_err(|_| {
                problem(format!(
                    "{name} = {field:?} is not a number (write e.g. 0.25,-0.6,1.0; a header is allowed only as the first line, x,y,z)"
                ))
            })?;
            if !value.is_finite() {
                return Err(problem(format!("{name} = {field:?} is not finite")));
            }
            *slot = value;
        }
        points.push(Vec3::from_array(xyz));
    }
    Ok(points)
}

/// The CSV `snell locate` prints (header and one row per image) and the notes for points without
/// an image, one line each.
pub fn format_located(located: &[LocatedPoint]) -> (String, Vec<String>) {
    let mut csv = format!("{CSV_HEADER}\n");
    let mut notes = Vec::new();
    for (index, point) in located.iter().enumerate() {
        let p = point.point;
        for (image_index, image) in point.images.iter().enumerate() {
            let (v, s) = (image.virtual_vertex, image.sight_point);
            let _ = writeln!(
                csv,
                "{index},{image_index},{},{},{},{},{},{},{},{}",
                v.x, v.y, v.z, s.x, s.y, s.z, image.facet, image.extrapolated
            );
        }
        if point.images.is_empty() {
            let why = match point.place {
                PointPlace::Above {
                    height_above_surface_m: Some(h),
                } => format!("is {h:.4} m above the water surface: seen directly, no refracted image"),
                PointPlace::Above {
                    height_above_surface_m: None,
                } => "is outside the water's extent: seen directly, no refracted image".to_string(),
                PointPlace::Under => {
                    "is under the water but in no refraction cell (outside the visible volume): no image"
                        .to_string()
                }
            };
            notes.push(format!("point {index} ({}, {}, {}) {why}", p.x, p.y, p.z));
        }
    }
    (csv, notes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Vec3>, ToolError> {
        parse_points_csv(text, Path::new("points.csv"))
    }

    #[test]
    fn header_comments_and_blank_lines() {
        let points = parse("# probe points\n X, Y ,z\n\n0.1,-0.5,0.2\n 1e-1 , -1 , 3\n").unwrap();
        assert_eq!(
            points,
            vec![Vec3::new(0.1, -0.5, 0.2), Vec3::new(0.1, -1.0, 3.0)]
        );
        assert_eq!(parse("1,2,3").unwrap(), vec![Vec3::new(1.0, 2.0, 3.0)]);
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        let message = parse("x,y,z\n1,2,3\n1,2\n").unwrap_err().to_string();
        assert!(
            message.starts_with("points.csv:3: expected three"),
            "{message}"
        );
        let message = parse("1,2,3\n\n1,abc,3\n").unwrap_err().to_string();
        assert!(
            message.starts_with("points.csv:3: y = \"abc\" is not a number"),
            "{message}"
        );
        let message = parse("1,2,3\nx,y,z\n").unwrap_err().to_string();
        assert!(message.starts_with("points.csv:2: x = \"x\""), "{message}");
        let message = parse("1,inf,3\n").unwrap_err().to_string();
        assert!(message.contains("not finite"), "{message}");
        assert!(parse("1,2,3\n").is_ok());
    }
}
