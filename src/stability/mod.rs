//! `snell stability SCENE`: every method against the ray-traced reference over time. Receives a
//! loaded [`RenderJob`], a frame range, an image size and the methods; renders every frame with
//! each method (at the scene's membrane) and with the reference, on one renderer; returns per frame
//! and method the figures of [`FrameFigures`], which [`write_outputs`] writes as `stability.csv`,
//! `stability_summary.txt` (the worst frame per figure and method) and a chart over time
//! (`stability.svg`, `stability.png`, one line per method).
//!
//! The position figures are `snell compare`'s ([`compare_positions`]: both ways, no search window,
//! over all same-object pixels, outside flagged pixels and outside the reference's fold band), with
//! the reference as A and the method as B. The temporal figure is [`temporal::temporal_error`]
//! between each frame and the one before it in the range; the first frame of the range has none.
//!
//! Per frame it also reports how hard the frame is by the truth: the share of under-water
//! vertices with two or more images by the independent oracle ([`oracle_share`]), in its own CSV
//! (`stability_oracle.csv`), in a column of the main one and in the summary (the lowest frame: a
//! hard scene must stay hard in every frame). `oracle_only` measures that alone, without rendering.

pub mod oracle_share;
pub mod plot;
pub mod temporal;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::chart::{Configuration, Measurer, REFERENCE_METHOD};
use crate::draw::RenderedFrame;
use crate::frame::{progress_bar, FrameRange, Method, RenderJob, SnellError};
use crate::output::position_error::{
    compare_positions, CompareOptions, PositionComparison, PositionError, Side,
};
use crate::refraction::flags::FlagCounts;
use oracle_share::{oracle_share, OracleShare};
use temporal::{temporal_error, FramePair, TemporalError};

/// The methods measured unless `--methods` says otherwise.
pub const DEFAULT_METHODS: [Method; 2] = [Method::EqualT, Method::Exact];

pub const CSV_FILE_NAME: &str = "stability.csv";
pub const SUMMARY_FILE_NAME: &str = "stability_summary.txt";
pub const SVG_FILE_NAME: &str = "stability.svg";
pub const PNG_FILE_NAME: &str = "stability.png";
pub const ORACLE_CSV_FILE_NAME: &str = "stability_oracle.csv";

/// What `snell stability` does.
pub struct StabilityOptions {
    pub frames: FrameRange,
    pub width: u32,
    pub height: u32,
    pub methods: Vec<Method>,
    pub out_dir: PathBuf,
    pub progress: bool,
    /// Under-water vertices the oracle measures per frame (a systematic sample; 0: all of them).
    pub oracle_samples: usize,
    /// Measure only the oracle's multi-image share: no renders, no position figures.
    pub oracle_only: bool,
}

/// One method at one frame, against the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameFigures {
    pub frame: u32,
    pub method: Method,
    pub position: PositionComparison,
    /// Against the frame before in the range; `None` for the range's first frame.
    pub temporal: Option<TemporalError>,
    pub counts: FlagCounts,
}

/// Everything `snell stability` measured, in frame order, methods in the order asked.
pub struct StabilityOutcome {
    pub scene: String,
    pub size: (u32, u32),
    pub adapter: String,
    pub rows: Vec<FrameFigures>,
    /// The oracle's multi-image share, one per frame in frame order.
    pub oracle: Vec<OracleShare>,
    pub oracle_csv: PathBuf,
    pub csv: PathBuf,
    pub summary: PathBuf,
    pub svg: PathBuf,
    pub png: PathBuf,
}

/// Parses `--methods equal-t,exact`: method names, comma-separated, each once.
pub fn parse_methods(text: &str) -> Result<Vec<Method>, SnellError> {
    let mut methods = Vec::new();
    for name in text.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let method = Method::parse(name)
            .map_err(|error| SnellError::Argument(format!("--methods {text:?}: {error}")))?;
        if methods.contains(&method) {
            return Err(SnellError::Argument(format!(
                "--methods {text:?}: {name} is named twice; name each method once"
            )));
        }
        methods.push(method);
    }
    if methods.is_empty() {
        return Err(SnellError::Argument(format!(
            "--methods {text:?}: name at least one method, e.g. --methods equal-t,exact"
        )));
    }
    Ok(methods)
}

/// Renders and measures every frame of `options.frames` (see the module documentation), then
/// writes the outputs into `options.out_dir`.
pub fn run_stability(
    job: &mut RenderJob,
    options: &StabilityOptions,
) -> Result<StabilityOutcome, SnellError> {
    crate::output::ensure_output_dir(&options.out_dir)?;
    crate::output::check_writable(&options.out_dir)?;
    let scene = job.scene_name().to_string();
    if options.oracle_only {
        let bar = progress_bar(options.frames.len() as u64, options.progress);
        let mut oracle = Vec::new();
        for frame in options.frames.frames() {
            bar.set_message(format!("frame {frame}: oracle"));
            oracle.push(oracle_share(job, frame, options.oracle_samples)?);
            bar.inc(1);
        }
        bar.finish_and_clear();
        let adapter = "no renderer (--oracle-only)".to_string();
        let outcome = StabilityOutcome::new(scene, options, adapter, Vec::new(), oracle);
        crate::chart::write_text(&outcome.oracle_csv, &outcome.oracle_csv_text())?;
        crate::chart::write_text(&outcome.summary, &outcome.summary_text(&[]))?;
        return Ok(outcome);
    }
    let resolution = job.scene.water.resolution;
    // The static objects are the first ids (object index + 1); characters follow and move.
    let static_objects = job.objects.len() as u32;
    let tracked = move |object: u32| object >= 1 && object <= static_objects;
    // This frame's and the previous frame's reference and renders, one per method.
    let frames_held = 2 * (options.methods.len() as u32 + 1);
    let mut measurer = Measurer::new(job, options.width, options.height, frames_held)?;
    let adapter = measurer.adapter();
    let renders_per_frame = options.methods.len() as u64 + 1;
    let bar = progress_bar(
        options.frames.len() as u64 * renders_per_frame,
        options.progress,
    );
    let reference_configuration = Configuration {
        method: REFERENCE_METHOD,
        resolution,
    };
    let mut rows = Vec::new();
    let mut oracle = Vec::new();
    let mut previous: Option<(RenderedFrame, Vec<RenderedFrame>)> = None;
    for frame in options.frames.frames() {
        bar.set_message(format!("frame {frame}: oracle"));
        oracle.push(oracle_share(measurer.job(), frame, options.oracle_samples)?);
        bar.set_message(format!("frame {frame}: reference"));
        let reference = measurer.render_once(reference_configuration, frame)?;
        bar.inc(1);
        let eye = measurer.job().camera_at(frame).eye;
        let mut renders = Vec::with_capacity(options.methods.len());
        for (index, &method) in options.methods.iter().enumerate() {
            bar.set_message(format!("frame {frame}: {}", method.name()));
            let configuration = Configuration { method, resolution };
            let (rendered, counts) = measurer.render_counted(configuration, frame)?;
            let position = compare_positions(
                &reference,
                &rendered,
                &CompareOptions {
                    flags_from: Side::B,
                    eyes: Some((eye, eye)),
                },
            )
            .map_err(|error| SnellError::Frame {
                scene: measurer.job().scene.path.clone(),
                frame,
                problem: format!(
                    "cannot measure {} against the reference: {error}",
                    method.name()
                ),
            })?;
            let temporal = previous.as_ref().map(|(reference_before, before)| {
                temporal_error(
                    &FramePair {
                        reference: [reference_before, &reference],
                        method: [&before[index], &rendered],
                    },
                    tracked,
                )
            });
            rows.push(FrameFigures {
                frame,
                method,
                position,
                temporal,
                counts,
            });
            renders.push(rendered);
            bar.inc(1);
        }
        previous = Some((reference, renders));
    }
    bar.finish_and_clear();
    drop(measurer);
    let outcome = StabilityOutcome::new(scene, options, adapter, rows, oracle);
    write_outputs(&outcome, &options.methods)?;
    Ok(outcome)
}

/// The CSV's header. Position figures: `{direction}_{subset}_{figure}` with direction `both`
/// (pooled), `ref_to_method` (per pixel of the reference: undrawn images) and `method_to_ref`
/// (per pixel of the method: images drawn where the truth has none); subset `all`,
/// `unflagged` (outside the method's flagged pixels) and `unfolded` (outside the reference's fold
/// band).
pub fn csv_header() -> String {
    let mut columns: Vec<String> = vec!["frame".into(), "method".into()];
    for direction in ["both", "ref_to_method", "method_to_ref"] {
        for subset in ["all", "unflagged", "unfolded"] {
            for figure in [
                "mean_px",
                "p99_px",
                "max_px",
                "over_1px_fraction",
                "counted",
            ] {
                columns.push(format!("{direction}_{subset}_{figure}"));
            }
        }
    }
    columns.extend(
        [
            "fold_band_water_fraction",
            "flagged_water_fraction",
            "object_mismatch_fraction",
            "temporal_mean_px",
            "temporal_p99_px",
            "temporal_max_px",
            "temporal_points",
            "popping_vertices",
            "popping_triangles",
            "convergence_vertices",
            "under_water_vertices",
            "oracle_multi_image_fraction",
            "oracle_sampled_vertices",
        ]
        .map(String::from),
    );
    columns.join(",")
}

fn number(value: f64) -> String {
    format!("{value}")
}

fn optional(value: Option<f64>) -> String {
    value.map(number).unwrap_or_default()
}

impl StabilityOutcome {
    /// What was measured, with the output files' paths in `options.out_dir`.
    fn new(
        scene: String,
        options: &StabilityOptions,
        adapter: String,
        rows: Vec<FrameFigures>,
        oracle: Vec<OracleShare>,
    ) -> Self {
        let path = |name: &str| options.out_dir.join(name);
        StabilityOutcome {
            scene,
            size: (options.width, options.height),
            adapter,
            rows,
            oracle,
            oracle_csv: path(ORACLE_CSV_FILE_NAME),
            csv: path(CSV_FILE_NAME),
            summary: path(SUMMARY_FILE_NAME),
            svg: path(SVG_FILE_NAME),
            png: path(PNG_FILE_NAME),
        }
    }

    /// `stability.csv`: one row per frame and method.
    pub fn csv_text(&self) -> String {
        let mut text = csv_header();
        text.push('\n');
        for row in &self.rows {
            let p = &row.position;
            let mut fields: Vec<String> = vec![row.frame.to_string(), row.method.name().into()];
            for direction in [&p.both, &p.a_to_b, &p.b_to_a] {
                for e in [
                    &direction.all,
                    &direction.outside_flagged,
                    &direction.outside_fold_band,
                ] {
                    fields.extend([
                        number(e.mean_px),
                        number(e.p99_px),
                        number(e.max_px),
                        number(e.over_1px_fraction),
                        e.counted.to_string(),
                    ]);
                }
            }
            let temporal = row.temporal;
            fields.extend([
                optional(p.fold_band_water_fraction),
                optional(p.flagged_water_fraction),
                number(p.object_mismatch_fraction),
                optional(temporal.map(|t| t.mean_px)),
                optional(temporal.map(|t| t.p99_px)),
                optional(temporal.map(|t| t.max_px)),
                temporal.map(|t| t.points.to_string()).unwrap_or_default(),
                row.counts.vertices.popping.to_string(),
                row.counts.triangles.popping.to_string(),
                row.counts.vertices.convergence.to_string(),
                row.counts.vertices.under_water.to_string(),
            ]);
            let share = self.oracle.iter().find(|o| o.frame == row.frame);
            fields.extend([
                optional(share.map(OracleShare::fraction)),
                share.map(|o| o.sampled.to_string()).unwrap_or_default(),
            ]);
            text.push_str(&fields.join(","));
            text.push('\n');
        }
        text
    }

    /// `stability_oracle.csv`: one row per frame, the oracle's multi-image share with its 95 %
    /// interval and what it measured.
    pub fn oracle_csv_text(&self) -> String {
        let mut text = String::from(ORACLE_CSV_HEADER);
        text.push('\n');
        for o in &self.oracle {
            let (low, high) = o.interval95();
            let _ = writeln!(
                text,
                "{},{},{},{},{},{},{},{},{},{}",
                o.frame,
                o.under_water_vertices,
                o.sampled,
                o.certain,
                o.multi_image,
                o.uncertain,
                number(o.fraction()),
                number(low),
                number(high),
                number(o.seconds)
            );
        }
        text
    }

    /// The summary's oracle part: the frame with the lowest multi-image share (a hard scene must
    /// stay hard in each frame), with its interval, and the mean.
    fn oracle_summary(&self, text: &mut String) {
        let Some(lowest) = self.oracle.iter().min_by(|a, b| {
            a.fraction()
                .total_cmp(&b.fraction())
                .then(a.frame.cmp(&b.frame))
        }) else {
            return;
        };
        let mean =
            self.oracle.iter().map(OracleShare::fraction).sum::<f64>() / self.oracle.len() as f64;
        let (low, high) = lowest.interval95();
        let sampled = if lowest.sampled >= lowest.under_water_vertices {
            "every under-water vertex".to_string()
        } else {
            format!(
                "a systematic sample of {} of {} under-water vertices per frame, 95 % Wilson interval {:.2}-{:.2} %",
                lowest.sampled,
                lowest.under_water_vertices,
                100.0 * low,
                100.0 * high
            )
        };
        let _ = writeln!(
            text,
            "\nunder-water vertices with two or more images by the oracle: lowest {:.2} % (frame {}), mean {:.2} %\n  ({sampled}; {} of them unsettled, on folds, left out)",
            100.0 * lowest.fraction(),
            lowest.frame,
            100.0 * mean,
            lowest.uncertain
        );
    }

    /// The summary: per method, each headline figure's worst frame.
    pub fn summary_text(&self, methods: &[Method]) -> String {
        let mut text = String::new();
        let mut frames: Vec<u32> = self.rows.iter().map(|r| r.frame).collect();
        frames.extend(self.oracle.iter().map(|o| o.frame));
        let _ = writeln!(
            text,
            "snell stability: {} frames {}-{} at {}x{} on {}, each method against the ray-traced reference",
            self.scene,
            frames.iter().min().copied().unwrap_or(0),
            frames.iter().max().copied().unwrap_or(0),
            self.size.0,
            self.size.1,
            self.adapter
        );
        text.push_str(
            "position error both ways (reference -> method and method -> reference pooled), px;\n\
             temporal: |dx_method - dx_reference| per tracked point of a static object, px\n",
        );
        self.oracle_summary(&mut text);
        for &method in methods {
            let rows: Vec<&FrameFigures> =
                self.rows.iter().filter(|r| r.method == method).collect();
            let _ = writeln!(text, "\n{}:", method.name());
            let _ = writeln!(
                text,
                "  {:<44} {:>10} {:>8} {:>10}",
                "figure", "worst", "frame", "mean"
            );
            let figures: [(&str, Figure); 13] = [
                ("p99, all same-object pixels", |r| {
                    Some(r.position.both.all.p99_px)
                }),
                ("p99, outside flagged pixels", |r| {
                    Some(r.position.both.outside_flagged.p99_px)
                }),
                ("p99, outside the fold band", |r| {
                    Some(r.position.both.outside_fold_band.p99_px)
                }),
                ("p99 ref -> method, outside the fold band", |r| {
                    Some(r.position.a_to_b.outside_fold_band.p99_px)
                }),
                ("p99 method -> ref, outside the fold band", |r| {
                    Some(r.position.b_to_a.outside_fold_band.p99_px)
                }),
                ("max, all same-object pixels", |r| {
                    Some(r.position.both.all.max_px)
                }),
                ("share over 1 px, outside the fold band (%)", |r| {
                    Some(100.0 * r.position.both.outside_fold_band.over_1px_fraction)
                }),
                ("fold band, share of water pixels (%)", |r| {
                    r.position.fold_band_water_fraction.map(|f| 100.0 * f)
                }),
                ("flagged, share of water pixels (%)", |r| {
                    r.position.flagged_water_fraction.map(|f| 100.0 * f)
                }),
                ("pixels seeing another object (%)", |r| {
                    Some(100.0 * r.position.object_mismatch_fraction)
                }),
                ("temporal p99", |r| r.temporal.map(|t| t.p99_px)),
                ("temporal mean", |r| r.temporal.map(|t| t.mean_px)),
                ("popping vertices", |r| {
                    Some(r.counts.vertices.popping as f64)
                }),
            ];
            for (name, figure) in &figures {
                let values: Vec<(u32, f64)> = rows
                    .iter()
                    .filter_map(|r| figure(r).map(|v| (r.frame, v)))
                    .collect();
                let Some(&(worst_frame, worst)) = values
                    .iter()
                    .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
                else {
                    let _ = writeln!(text, "  {name:<44} {:>10} {:>8} {:>10}", "-", "-", "-");
                    continue;
                };
                let mean = values.iter().map(|v| v.1).sum::<f64>() / values.len() as f64;
                let _ = writeln!(
                    text,
                    "  {name:<44} {worst:>10.4} {worst_frame:>8} {mean:>10.4}"
                );
            }
        }
        text
    }
}

/// The header of `stability_oracle.csv`.
pub const ORACLE_CSV_HEADER: &str = "frame,under_water_vertices,sampled,certain,multi_image,uncertain,multi_image_fraction,fraction_low95,fraction_high95,seconds";

/// One figure of a row for the summary (`None` where the row has none).
type Figure = fn(&FrameFigures) -> Option<f64>;

/// The pooled position error outside the fold band (the chart's first panel).
pub fn headline(row: &FrameFigures) -> PositionError {
    row.position.both.outside_fold_band
}

/// Writes the CSV, the summary and the chart of `outcome`, each atomically.
pub fn write_outputs(outcome: &StabilityOutcome, methods: &[Method]) -> Result<(), SnellError> {
    crate::chart::write_text(&outcome.csv, &outcome.csv_text())?;
    crate::chart::write_text(&outcome.oracle_csv, &outcome.oracle_csv_text())?;
    crate::chart::write_text(&outcome.summary, &outcome.summary_text(methods))?;
    let input = plot::TimeChart::of(outcome, methods);
    let drawing_error = |path: &Path, cause: String| {
        SnellError::Output(crate::output::OutputError::Write {
            path: path.to_path_buf(),
            cause: format!("drawing the chart: {cause}"),
        })
    };
    let svg = plot::chart_svg(&input).map_err(|cause| drawing_error(&outcome.svg, cause))?;
    crate::chart::write_text(&outcome.svg, &svg)?;
    let image = plot::chart_image(&input).map_err(|cause| drawing_error(&outcome.png, cause))?;
    crate::output::save_png_atomic(&outcome.png, &image)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_parse_in_order_once_each() {
        assert_eq!(
            parse_methods("exact, equal-t").unwrap(),
            vec![Method::Exact, Method::EqualT]
        );
        for (text, needle) in [
            ("exact,exact", "named twice"),
            ("", "at least one"),
            ("equal-t,fast", "\"fast\" is unknown"),
        ] {
            let message = parse_methods(text).unwrap_err().to_string();
            assert!(message.contains(needle), "{text:?}: {message}");
        }
    }

    #[test]
    fn the_header_has_one_column_per_field() {
        let columns = csv_header().split(',').count();
        assert_eq!(columns, 2 + 3 * 3 * 5 + 11 + 2);
    }
}
