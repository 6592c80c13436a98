//! `snell accuracy` as the command line sees it: receives parsed arguments, runs the study with a
//! progress bar on stderr, prints the setup and the Markdown table to stdout, writes the CSV
//! atomically, and returns the exit code: 0 done, 2 bad option or unwritable CSV path, 1 a write
//! that failed.

use std::io::Write as _;
use std::path::PathBuf;

use super::membranes::RingFaceting;
use super::study::{self, StudyOptions, DEFAULT_SPACING};
use crate::output::OutputError;

/// Arguments of `snell accuracy`.
#[derive(clap::Args, Clone, Debug)]
pub struct AccuracyArgs {
    /// Also write the results as CSV to FILE, two lines per row (methods `linear` and `exact`),
    /// with the columns config,method,mean,std,counted,excluded,thesis_mean. `excluded` counts
    /// samples with no image, an extrapolated cell, more than one image or no computed vertex.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Concentric rings of facets of the disk and sphere membranes. The thesis's "125 vertices
    /// forming 484 facets" cannot be a triangulated disk; 4 rings fit its published means best
    /// (ALGORITHM §8). Ring k carries 6k vertices: 6 rings^2 facets in all. More rings means smaller
    /// facets and less error (6 rings: about 0.4 times 4 rings').
    #[arg(long, default_value_t = RingFaceting::THESIS_FIT.rings, value_name = "N")]
    pub rings: u32,
    /// How wide each ring is relative to the ring inside it: 1 gives rings of equal width, below 1
    /// rings that narrow toward the rim (where the error is largest). 0.9 fits the thesis.
    #[arg(long, default_value_t = RingFaceting::THESIS_FIT.width_ratio, value_name = "RATIO")]
    pub ring_ratio: f64,
    /// Distance between samples in the 400-unit cube, scene units: (400 / SPACING)^3 samples per
    /// volume (10: 64,000). Smaller is more precise and slower (time grows with its cube).
    /// Measured: every linear mean at 10 is within 0.5 % of its value at 5, at 20 within 3.1 %.
    #[arg(long, default_value_t = DEFAULT_SPACING, value_name = "UNITS")]
    pub spacing: f64,
    /// Only the rows of one table: 4.1 (eye heights and offsets over a flat disk), 4.2 (sphere
    /// membranes, bowls and caps) or 4.5 (square grids).
    #[arg(long, value_name = "TABLE")]
    pub table: Option<String>,
}

/// What can go wrong, each naming the option or the file.
#[derive(Debug, thiserror::Error)]
pub enum AccuracyError {
    #[error("--{option}: {reason}")]
    InvalidOption {
        option: &'static str,
        reason: String,
    },
    #[error(transparent)]
    Output(#[from] OutputError),
}

impl AccuracyError {
    pub fn is_bad_input(&self) -> bool {
        match self {
            AccuracyError::InvalidOption { .. } => true,
            AccuracyError::Output(error) => error.is_bad_input(),
        }
    }
}

/// Checks the options and turns them into the study's.
pub fn options_from(args: &AccuracyArgs) -> Result<StudyOptions, AccuracyError> {
    let invalid = |option, reason: String| Err(AccuracyError::InvalidOption { option, reason });
    if !(1..=64).contains(&args.rings) {
        return invalid(
            "rings",
            format!("must be 1 to 64 rings, got {}", args.rings),
        );
    }
    if !(args.ring_ratio.is_finite() && args.ring_ratio >= 0.1 && args.ring_ratio <= 10.0) {
        return invalid(
            "ring-ratio",
            format!(
                "must be a number from 0.1 to 10 (1 = rings of equal width), got {}",
                args.ring_ratio
            ),
        );
    }
    // Below 2 units a volume has over 8 million samples: hours per table on two cores.
    if !(args.spacing.is_finite() && args.spacing >= 2.0 && args.spacing <= 200.0) {
        return invalid(
            "spacing",
            format!(
                "must be 2 to 200 units (the cube is 400 a side), got {}",
                args.spacing
            ),
        );
    }
    Ok(StudyOptions {
        faceting: RingFaceting {
            rings: args.rings,
            width_ratio: args.ring_ratio,
        },
        spacing: args.spacing,
        ..StudyOptions::default()
    })
}

/// Runs `snell accuracy`; returns the process exit code.
pub fn run(args: &AccuracyArgs) -> u8 {
    match run_inner(args) {
        Ok(()) => 0,
        Err(error) => {
            errln!("error: {error}");
            if error.is_bad_input() {
                2
            } else {
                1
            }
        }
    }
}

fn run_inner(args: &AccuracyArgs) -> Result<(), AccuracyError> {
    let options = options_from(args)?;
    let mut rows = study::thesis_rows();
    if let Some(table) = &args.table {
        rows.retain(|row| row.table == table.as_str());
        if rows.is_empty() {
            return Err(AccuracyError::InvalidOption {
                option: "table",
                reason: format!("no table {table:?}: choose 4.1, 4.2 or 4.5"),
            });
        }
    }
    if let Some(path) = &args.csv {
        // An unwritable CSV path is found before minutes of work.
        if let Some(parent) = path.parent() {
            crate::output::ensure_output_dir(parent)?;
            if !parent.as_os_str().is_empty() {
                crate::output::check_writable(parent)?;
            }
        }
    }
    let total = (rows.len() * options.samples_per_volume()) as u64;
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} samples (ETA {eta})",
        )
        .expect("valid template"),
    );
    let results = study::run_study(&rows, &options, &|n| bar.inc(n as u64));
    bar.finish_and_clear();
    let mut stdout = std::io::stdout().lock();
    let text = format!(
        "# snell accuracy: error volumes of the thesis's Tables 4.1, 4.2 and 4.5\n\n{}\n\n{}",
        study::describe_setup(&options),
        study::markdown_table(&results)
    );
    // A closed pipe (e.g. `| head`) is not an error worth a message.
    let _ = stdout.write_all(text.as_bytes());
    if let Some(path) = &args.csv {
        let csv = study::csv(&results);
        crate::output::write_atomically(path, |file| {
            file.write_all(csv.as_bytes())
                .map_err(|error| error.to_string())
        })?;
        errln!("wrote {}", path.display());
    }
    Ok(())
}
