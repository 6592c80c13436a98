//! The chart over time of `snell stability`: receives the measured rows; returns an SVG document
//! or an RGBA image with two panels sharing the frame axis, one line per method: the position
//! error's p99 both ways outside the fold band, and the temporal p99 |dx_method - dx_reference|.
//! Drawn with the DejaVu Sans of `snell chart` ([`crate::chart::plot`]).

use image::RgbaImage;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{headline, StabilityOutcome};
use crate::chart::plot::{image_of, svg_of, FONT_FAMILY, SERIES_COLOURS};
use crate::frame::Method;

/// One method's line in both panels.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSeries {
    pub name: String,
    /// (frame, p99 px) of the position error.
    pub position_p99: Vec<(f64, f64)>,
    /// (frame, p99 px) of the temporal error (from the range's second frame).
    pub temporal_p99: Vec<(f64, f64)>,
}

/// Everything the chart shows.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeChart {
    pub title: String,
    pub caption: String,
    pub series: Vec<MethodSeries>,
}

pub const SIZE: (u32, u32) = (1200, 900);

impl TimeChart {
    pub fn of(outcome: &StabilityOutcome, methods: &[Method]) -> TimeChart {
        let series = methods
            .iter()
            .map(|&method| {
                let rows = outcome.rows.iter().filter(|r| r.method == method);
                MethodSeries {
                    name: method.name().to_string(),
                    position_p99: rows
                        .clone()
                        .map(|r| (r.frame as f64, headline(r).p99_px))
                        .collect(),
                    temporal_p99: rows
                        .filter_map(|r| r.temporal.map(|t| (r.frame as f64, t.p99_px)))
                        .collect(),
                }
            })
            .collect();
        TimeChart {
            title: format!(
                "{}: every method against the ray-traced reference",
                outcome.scene
            ),
            caption: format!(
                "{}x{}, {}. Top: position error p99, both ways, outside the reference's fold band.\n\
                 Bottom: p99 of |dx_method - dx_reference| over the tracked points, from the frame before.",
                outcome.size.0,
                outcome.size.1,
                crate::chart::short_adapter(&outcome.adapter)
            ),
            series,
        }
    }
}

pub fn chart_svg(input: &TimeChart) -> Result<String, String> {
    svg_of(SIZE, |root| draw(root, input))
}

pub fn chart_image(input: &TimeChart) -> Result<RgbaImage, String> {
    image_of(SIZE, |root| draw(root, input))
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    input: &TimeChart,
) -> Result<(), String> {
    let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(fail)?;
    let (title_area, rest) = root.split_vertically(80);
    title_area
        .draw(&Text::new(
            input.title.clone(),
            (20, 10),
            (FONT_FAMILY, 24).into_font(),
        ))
        .map_err(fail)?;
    for (index, line) in input.caption.lines().take(2).enumerate() {
        title_area
            .draw(&Text::new(
                line.to_string(),
                (20, 42 + 18 * index as i32),
                (FONT_FAMILY, 14).into_font().color(&RGBColor(80, 80, 80)),
            ))
            .map_err(fail)?;
    }
    let frames = input
        .series
        .iter()
        .flat_map(|s| s.position_p99.iter().map(|p| p.0));
    let (first, last) = frames.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
        (lo.min(f), hi.max(f))
    });
    let (first, last) = if first.is_finite() {
        (first, last.max(first + 1.0))
    } else {
        (0.0, 1.0)
    };
    let (top, bottom) = rest.split_vertically(rest.dim_in_pixel().1 / 2);
    let panels: [(&DrawingArea<DB, Shift>, &str, bool); 2] = [
        (&top, "position error p99 (px)", true),
        (&bottom, "temporal p99 (px)", false),
    ];
    for (area, label, position) in panels {
        let points = |s: &MethodSeries| -> Vec<(f64, f64)> {
            let values = if position {
                &s.position_p99
            } else {
                &s.temporal_p99
            };
            values.iter().copied().filter(|p| p.1.is_finite()).collect()
        };
        let highest = input
            .series
            .iter()
            .flat_map(|s| points(s).into_iter().map(|p| p.1))
            .fold(0.0, f64::max);
        let top_value = if highest > 0.0 { highest * 1.15 } else { 1.0 };
        let mut chart = ChartBuilder::on(area)
            .margin(20)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(first..last, 0.0..top_value)
            .map_err(fail)?;
        let frame_label = |v: &f64| format!("{v:.0}");
        chart
            .configure_mesh()
            .x_labels(((last - first) as usize + 1).min(12))
            .x_label_formatter(&frame_label)
            .x_desc("frame")
            .y_desc(label)
            .label_style((FONT_FAMILY, 14))
            .axis_desc_style((FONT_FAMILY, 16))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(fail)?;
        for (index, series) in input.series.iter().enumerate() {
            let colour = SERIES_COLOURS[index % SERIES_COLOURS.len()];
            let line = points(series);
            chart
                .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))
                .map_err(fail)?
                .label(series.name.clone())
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(line.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(fail)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(200, 200, 200))
            .label_font((FONT_FAMILY, 14))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(fail)?;
    }
    Ok(())
}
