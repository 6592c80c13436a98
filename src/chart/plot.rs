//! The speed-vs-accuracy chart: receives labelled points (seconds per frame, mean position error)
//! and the reference's time, returns the chart as SVG text or as an RGBA image. Log axes both ways;
//! text is laid out with the DejaVu Sans shipped in `src/chart/font` (plotters' `ab_glyph` backend),
//! so the chart draws the same on every machine, system fonts or not.

use std::sync::Once;

use image::RgbaImage;
use plotters::coord::Shift;
use plotters::prelude::*;

/// DejaVu Sans (Bitstream Vera licence; see src/chart/font/CREDITS.md).
static FONT: &[u8] = include_bytes!("font/DejaVuSans.ttf");
pub(crate) const FONT_FAMILY: &str = "sans-serif";

/// One configuration on the chart.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartPoint {
    /// The series (method) it belongs to: points of a series share a colour and are joined in order.
    pub series: String,
    /// Written beside the point, e.g. `64x64`.
    pub label: String,
    pub secs_per_frame: f64,
    pub mean_px: f64,
}

/// Everything the chart shows.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartInput {
    pub title: String,
    /// Lines under the title (at most two are shown): what was measured, where.
    pub caption: String,
    pub points: Vec<ChartPoint>,
    /// The ray-traced reference: its label and seconds per frame. Its error is zero by definition,
    /// which a log axis cannot show, so it is drawn as a horizontal line: the time to beat.
    pub reference: Option<(String, f64)>,
    /// A vertical line at this error, with its label (e.g. the 0.1 px target).
    pub error_target: Option<(String, f64)>,
}

/// Image size of the PNG chart, pixels.
pub const PNG_SIZE: (u32, u32) = (1200, 800);
/// Size of the SVG chart, in its user units.
pub const SVG_SIZE: (u32, u32) = (1200, 800);

fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The bytes are a valid TrueType file compiled into the binary: failure would be a build defect.
        if plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT).is_err() {
            panic!("the embedded DejaVu Sans font does not parse");
        }
    });
}

/// The chart as an SVG document.
pub fn chart_svg(input: &ChartInput) -> Result<String, String> {
    svg_of(SVG_SIZE, |root| draw(root, input))
}

/// The chart as an opaque RGBA image of [`PNG_SIZE`].
pub fn chart_image(input: &ChartInput) -> Result<RgbaImage, String> {
    image_of(PNG_SIZE, |root| draw(root, input))
}

/// What `draw` draws on an SVG drawing area of `size`, as an SVG document (fonts registered).
pub(crate) fn svg_of(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<String, String> {
    register_font();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// What `draw` draws on a bitmap of `size`, as an opaque RGBA image (fonts registered).
pub(crate) fn image_of(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<RgbaImage, String> {
    register_font();
    let (width, height) = size;
    let mut rgb = vec![0u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| e.to_string())?;
    }
    let rgba = rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    Ok(RgbaImage::from_raw(width, height, rgba).expect("buffer has width * height pixels"))
}

/// Colours of the series, in order of first appearance (colour-blind safe: Okabe & Ito).
pub(crate) const SERIES_COLOURS: [RGBColor; 5] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(230, 159, 0),
];
const REFERENCE_COLOUR: RGBColor = RGBColor(0, 158, 115);
const TARGET_COLOUR: RGBColor = RGBColor(120, 120, 120);

/// The decades `[10^a, 10^b]` that hold every value (at least one decade wide).
fn decade_range(values: impl Iterator<Item = f64>, fallback: (f64, f64)) -> (f64, f64) {
    let (low, high) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !low.is_finite() {
        return fallback;
    }
    let a = low.log10().floor();
    let mut b = high.log10().ceil();
    if b <= a {
        b = a + 1.0;
    }
    (10f64.powf(a), 10f64.powf(b))
}

/// Axis labels on a log axis: plain decimals without trailing zeros (0.01, 0.1, 1, 10).
fn tick_label(value: f64) -> String {
    if value >= 1.0 {
        format!("{value:.0}")
    } else {
        let digits = (-value.log10()).ceil().max(0.0) as usize + 1;
        let text = format!("{value:.digits$}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    input: &ChartInput,
) -> Result<(), String> {
    let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(fail)?;
    let drawable: Vec<&ChartPoint> = input
        .points
        .iter()
        .filter(|p| {
            p.mean_px.is_finite()
                && p.mean_px > 0.0
                && p.secs_per_frame.is_finite()
                && p.secs_per_frame > 0.0
        })
        .collect();
    let x_range = decade_range(
        drawable
            .iter()
            .map(|p| p.mean_px)
            // Room right of the target's line for its label.
            .chain(input.error_target.iter().map(|t| t.1 * 3.0)),
        (0.01, 10.0),
    );
    let y_range = decade_range(
        drawable
            .iter()
            .map(|p| p.secs_per_frame)
            // Room above the reference's line for the legend.
            .chain(input.reference.iter().map(|r| r.1 * 2.5)),
        (0.01, 10.0),
    );

    let (title_area, rest) = root.split_vertically(96);
    title_area
        .draw(&Text::new(
            input.title.clone(),
            (20, 10),
            (FONT_FAMILY, 26).into_font(),
        ))
        .map_err(fail)?;
    let mut caption_lines: Vec<String> = input.caption.lines().map(str::to_string).collect();
    let hidden: Vec<&str> = input
        .points
        .iter()
        .filter(|p| !drawable.iter().any(|d| std::ptr::eq(*d, *p)))
        .map(|p| p.label.as_str())
        .collect();
    if !hidden.is_empty() {
        // A log axis has no place for an error of 0 (or a failed measurement): say so.
        caption_lines.push(format!(
            "not drawn (error or time 0 or not finite): {}",
            hidden.join(", ")
        ));
    }
    for (index, line) in caption_lines.iter().take(3).enumerate() {
        title_area
            .draw(&Text::new(
                line.clone(),
                (20, 42 + 18 * index as i32),
                (FONT_FAMILY, 15).into_font().color(&RGBColor(80, 80, 80)),
            ))
            .map_err(fail)?;
    }

    let mut chart = ChartBuilder::on(&rest)
        .margin(20)
        .x_label_area_size(55)
        .y_label_area_size(80)
        .build_cartesian_2d(
            (x_range.0..x_range.1).log_scale(),
            (y_range.0..y_range.1).log_scale(),
        )
        .map_err(fail)?;
    let x_format = |v: &f64| tick_label(*v);
    let y_format = |v: &f64| tick_label(*v);
    chart
        .configure_mesh()
        .x_desc("mean screen-space position error against the reference (pixels, log)")
        .y_desc("seconds per frame (log)")
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .label_style((FONT_FAMILY, 15))
        .axis_desc_style((FONT_FAMILY, 17))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(fail)?;

    if let Some((label, secs)) = &input.reference {
        let style = REFERENCE_COLOUR.stroke_width(2);
        chart
            .draw_series(DashedLineSeries::new(
                [(x_range.0, *secs), (x_range.1, *secs)],
                10,
                6,
                style,
            ))
            .map_err(fail)?
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], style));
    }
    if let Some((label, error)) = &input.error_target {
        chart
            .draw_series(DashedLineSeries::new(
                [(*error, y_range.0), (*error, y_range.1)],
                6,
                6,
                TARGET_COLOUR.stroke_width(1),
            ))
            .map_err(fail)?;
        chart
            .draw_series(std::iter::once(Text::new(
                label.clone(),
                (*error * 1.08, y_range.0 * 1.25),
                (FONT_FAMILY, 14).into_font().color(&TARGET_COLOUR),
            )))
            .map_err(fail)?;
    }

    let mut series_names: Vec<&str> = Vec::new();
    for point in &drawable {
        if !series_names.contains(&point.series.as_str()) {
            series_names.push(&point.series);
        }
    }
    for (index, name) in series_names.iter().enumerate() {
        let colour = SERIES_COLOURS[index % SERIES_COLOURS.len()];
        let points: Vec<(f64, f64)> = drawable
            .iter()
            .filter(|p| p.series == *name)
            .map(|p| (p.mean_px, p.secs_per_frame))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(1)))
            .map_err(fail)?;
        chart
            .draw_series(points.iter().map(|&at| Circle::new(at, 6, colour.filled())))
            .map_err(fail)?
            .label(name.to_string())
            .legend(move |(x, y)| Circle::new((x + 10, y), 6, colour.filled()));
        let label_font = (FONT_FAMILY, 14).into_font().color(&colour);
        chart
            .draw_series(drawable.iter().filter(|p| p.series == *name).map(|p| {
                EmptyElement::at((p.mean_px, p.secs_per_frame))
                    + Text::new(p.label.clone(), (9, -18), label_font.clone())
            }))
            .map_err(fail)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT_FAMILY, 15))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(180, 180, 180))
        .draw()
        .map_err(fail)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> ChartInput {
        let point = |series: &str, label: &str, secs, mean| ChartPoint {
            series: series.into(),
            label: label.into(),
            secs_per_frame: secs,
            mean_px: mean,
        };
        ChartInput {
            title: "speed vs accuracy".into(),
            caption: "test".into(),
            points: vec![
                point("equal-t", "32x32", 0.05, 3.0),
                point("equal-t", "64x64", 0.06, 1.2),
                point("exact", "64x64", 0.2, 0.02),
            ],
            reference: Some(("reference".into(), 4.0)),
            error_target: Some(("0.1 px".into(), 0.1)),
        }
    }

    #[test]
    fn decades_hold_every_value() {
        assert_eq!(
            decade_range([0.02, 3.0].into_iter(), (1.0, 2.0)),
            (0.01, 10.0)
        );
        assert_eq!(decade_range([1.0].into_iter(), (1.0, 2.0)), (1.0, 10.0));
        assert_eq!(
            decade_range([0.0, f64::NAN].into_iter(), (0.5, 2.0)),
            (0.5, 2.0)
        );
        assert_eq!(tick_label(0.01), "0.01");
        assert_eq!(tick_label(0.1), "0.1");
        assert_eq!(tick_label(10.0), "10");
    }

    /// The PNG has text and points drawn (not a blank page), and both formats carry the labels.
    #[test]
    fn the_chart_draws_points_and_text() {
        let input = sample();
        let image = chart_image(&input).unwrap();
        assert_eq!(image.dimensions(), PNG_SIZE);
        let exact_colour = SERIES_COLOURS[1];
        let coloured = image
            .pixels()
            .filter(|p| p.0[..3] == [exact_colour.0, exact_colour.1, exact_colour.2])
            .count();
        assert!(
            coloured > 50,
            "the exact point is missing: {coloured} pixels"
        );
        let dark = image.pixels().filter(|p| p.0[0] < 100).count();
        assert!(dark > 1000, "no text or axes drawn: {dark} dark pixels");
        let svg = chart_svg(&input).unwrap();
        for text in ["32x32", "exact", "reference", "0.1 px", "seconds per frame"] {
            assert!(svg.contains(text), "{text} missing from the SVG");
        }
    }
}
