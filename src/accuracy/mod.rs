//! The thesis's accuracy study (its chapter 4, ALGORITHM §8), pure CPU (rayon): the refractors of
//! its Tables 4.1, 4.2 and 4.5 ([`membranes`]: exact surface + faceting), error volumes of the
//! linear (thesis-cell) and exact (Fermat/Newton) methods ([`volume`]), and the table of every row
//! beside the published means ([`study`]). `snell accuracy` ([`cli`]) prints it.

pub mod cli;
pub mod membranes;
pub mod study;
pub mod volume;

pub use membranes::{Orientation, Outline, RingFaceting, SphereSurface, ThesisMembrane};
pub use study::{run_study, thesis_rows, StudyOptions, StudyResult, StudyRow};
pub use volume::{measure_volume, ErrorStats, Exclusions, VolumeResult, VolumeSetup};
