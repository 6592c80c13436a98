//! Tools to check snell's geometry and frames from outside: [`locate`] prints every image of given
//! points at a frame (`snell locate`), [`compare`] measures the screen-space position error, FLIP
//! and object mismatch between two EXR frames (`snell compare`), [`export`] writes a frame's
//! world-space geometry and camera for other renderers and DCC tools (`snell export`).
//! [`cli`] holds their command-line arguments and exit codes.

pub mod cli;
pub mod compare;
pub mod export;
pub mod locate;

use std::path::PathBuf;

use crate::frame::{RenderJob, SnellError};
use crate::output::OutputError;

/// Everything that can stop a tool: "your input is wrong" (exit 2) or not (exit 1).
#[derive(Debug, thiserror::Error)]
pub enum ToolError {
    #[error("{0}")]
    Snell(#[from] SnellError),
    #[error("{0}")]
    Output(#[from] OutputError),
    /// A line of an input file that cannot be used (1-based line).
    #[error("{path}:{line}: {problem}")]
    InputLine {
        path: PathBuf,
        line: usize,
        problem: String,
    },
    /// An input file that cannot be used as a whole (missing, not an EXR, wrong size...).
    #[error("{path}: {problem}")]
    InputFile { path: PathBuf, problem: String },
    /// Two inputs that cannot be compared with each other.
    #[error("{0}")]
    Mismatch(String),
}

impl ToolError {
    /// Whether the user's input is at fault: exit code 2.
    pub fn is_bad_input(&self) -> bool {
        match self {
            ToolError::Snell(error) => error.is_bad_input(),
            ToolError::Output(error) => error.is_bad_input(),
            ToolError::InputLine { .. } | ToolError::InputFile { .. } | ToolError::Mismatch(_) => {
                true
            }
        }
    }
}

/// `--frame N` checked against the scene's timeline.
pub fn check_frame(job: &RenderJob, frame: u32) -> Result<(), ToolError> {
    let timeline = job.timeline();
    if frame < timeline.first_frame || frame > timeline.last_frame {
        return Err(SnellError::Argument(format!(
            "--frame {frame}: the timeline of {} runs from frame {} to {}; choose a frame inside it",
            job.scene.path.display(),
            timeline.first_frame,
            timeline.last_frame
        ))
        .into());
    }
    Ok(())
}
