//! The per-frame report `DIR/report.jsonl`: receives one [`FrameReport`] per rendered frame and keeps
//! the file as one JSON object per line, sorted by frame. Rendering a subset of frames into a
//! directory that already has a report replaces the rows of those frames and keeps the others.
//! After every frame the whole file is rewritten atomically (temporary file, sync, rename), so an
//! interrupted render leaves a complete report of the frames finished so far.
//!
//! Any number of processes may render into one folder at once (a farm's chunks): each update
//! takes an exclusive lock on `DIR/.report.jsonl.lock`, reads the report as it is now, replaces
//! its frame's row and renames the new file into place before unlocking, so no process's rows are
//! lost. A locked rewrite rather than per-frame files or a bare append: the file stays one sorted
//! row per frame (a re-rendered frame replaces its row), readers need no lock (they only ever see
//! a whole renamed file), and the cost, a few hundred bytes a frame read and written once per
//! frame, is nothing beside the frame's EXR.

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{ensure_output_dir, write_atomically, OutputError};

pub const REPORT_FILE_NAME: &str = "report.jsonl";
/// The file every writer of the report locks while it updates it (never renamed, so the lock is
/// on one file for everyone).
pub const REPORT_LOCK_NAME: &str = ".report.jsonl.lock";

/// One report row.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    pub frame: u32,
    pub time_secs: f64,
    /// How the image drawn in a convergence zone is chosen, in words.
    pub convergence_policy: String,
    /// Vertex and triangle counts per flag, as the refraction stage serialises them.
    pub counts: serde_json::Value,
    /// Wall-clock seconds per pipeline stage.
    pub stage_secs: BTreeMap<String, f64>,
    /// Width and height in pixels.
    pub size: [u32; 2],
    pub method: String,
    /// The frame's input hash (as in its EXR header), so `snell render --resume` can tell a row
    /// of this render from a row of an earlier one with other inputs. Absent in older reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_hash: Option<String>,
    /// The configuration chosen for the scene's `max_error_px` and the errors behind the choice
    /// (`crate::chart::budget::QualityChoice`); absent when the scene states no budget.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<serde_json::Value>,
}

/// Keeps `DIR/report.jsonl` up to date frame by frame.
#[derive(Debug)]
pub struct ReportWriter {
    path: PathBuf,
    /// Serialised rows by frame. Rows read from an existing report are kept verbatim, so a report
    /// written by another snell version keeps fields this version does not know.
    rows_by_frame: BTreeMap<u32, String>,
}

impl ReportWriter {
    /// Opens the report of `dir` (creating `dir` if needed), loading the rows already there.
    pub fn create(dir: &Path) -> Result<Self, OutputError> {
        ensure_output_dir(dir)?;
        Self::read(dir)
    }

    /// The report of `dir` as it is, creating nothing (no rows when the report or `dir` is
    /// missing): for checks that must leave the folder untouched (`snell farm check`).
    pub fn read(dir: &Path) -> Result<Self, OutputError> {
        let path = dir.join(REPORT_FILE_NAME);
        let rows_by_frame = match fs::read_to_string(&path) {
            Ok(contents) => parse_rows(&path, &contents)?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => BTreeMap::new(),
            Err(error) => {
                return Err(OutputError::Read {
                    path,
                    cause: error.to_string(),
                })
            }
        };
        Ok(Self {
            path,
            rows_by_frame,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The `input_hash` of `frame`'s row: None when there is no row or it has no hash.
    pub fn row_input_hash(&self, frame: u32) -> Option<String> {
        let row = self.rows_by_frame.get(&frame)?;
        let value: serde_json::Value = serde_json::from_str(row).ok()?;
        value.get("input_hash")?.as_str().map(str::to_string)
    }

    /// Adds (or replaces) the row of `report.frame` and rewrites the file, flushed and synced,
    /// under the report's lock and over the rows on disk now (other processes' included).
    pub fn append(&mut self, report: &FrameReport) -> Result<(), OutputError> {
        let write_error = |cause: String| OutputError::Write {
            path: self.path.clone(),
            cause,
        };
        let row = serde_json::to_string(report).map_err(|error| write_error(error.to_string()))?;
        let lock_path = self.path.with_file_name(REPORT_LOCK_NAME);
        let lock = fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&lock_path)
            .map_err(|error| {
                write_error(format!(
                    "cannot open the lock {}: {error}",
                    lock_path.display()
                ))
            })?;
        super::lock::lock(&lock, super::lock::Lock::Exclusive).map_err(|error| {
            write_error(format!("cannot lock {}: {error}", lock_path.display()))
        })?;
        // Under the lock: the rows other processes wrote since this one last looked.
        let mut rows = match fs::read_to_string(&self.path) {
            Ok(contents) => parse_rows(&self.path, &contents)?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => BTreeMap::new(),
            Err(error) => {
                return Err(OutputError::Read {
                    path: self.path.clone(),
                    cause: error.to_string(),
                })
            }
        };
        rows.insert(report.frame, row);
        let result = write_rows(&self.path, &rows);
        drop(lock); // unlocks
        if result.is_ok() {
            // Memory follows the file only once it is on disk.
            self.rows_by_frame = rows;
        }
        result
    }
}

fn write_rows(path: &Path, rows: &BTreeMap<u32, String>) -> Result<(), OutputError> {
    write_atomically(path, |file| {
        let mut contents = String::new();
        for row in rows.values() {
            contents.push_str(row);
            contents.push('\n');
        }
        file.write_all(contents.as_bytes())
            .map_err(|error| error.to_string())?;
        file.flush().map_err(|error| error.to_string())
    })
}

fn parse_rows(path: &Path, contents: &str) -> Result<BTreeMap<u32, String>, OutputError> {
    let mut rows_by_frame = BTreeMap::new();
    let mut line_of_frame: HashMap<u32, usize> = HashMap::new();
    for (index, line) in contents.lines().enumerate() {
        let line_number = index + 1;
        if line.trim().is_empty() {
            continue;
        }
        let parse_error = |cause: String| OutputError::Parse {
            path: path.to_path_buf(),
            line: line_number,
            cause: format!("{cause}; delete the report or render into another directory"),
        };
        let value: serde_json::Value = serde_json::from_str(line)
            .map_err(|error| parse_error(format!("not a JSON object: {error}")))?;
        let frame = value
            .get("frame")
            .and_then(serde_json::Value::as_u64)
            .and_then(|frame| u32::try_from(frame).ok())
            .ok_or_else(|| parse_error("the row has no integer `frame`".into()))?;
        if let Some(first_line) = line_of_frame.insert(frame, line_number) {
            return Err(parse_error(format!(
                "frame {frame} already has a row on line {first_line}"
            )));
        }
        rows_by_frame.insert(frame, line.to_string());
    }
    Ok(rows_by_frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(frame: u32, method: &str) -> FrameReport {
        FrameReport {
            frame,
            time_secs: frame as f64 / 24.0,
            convergence_policy: "least optical path, then lowest facet index".into(),
            counts: serde_json::json!({ "vertices": { "convergence": frame * 2 }, "triangles": { "boundary": 1 } }),
            stage_secs: BTreeMap::from([("refraction".into(), 0.012), ("render".into(), 0.034)]),
            size: [320, 180],
            method: method.into(),
            input_hash: None,
            quality: None,
        }
    }

    fn read_rows(path: &Path) -> Vec<FrameReport> {
        fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|line| serde_json::from_str(line).unwrap())
            .collect()
    }

    #[test]
    fn one_row_per_frame_written_as_it_goes() {
        let temp = tempfile::tempdir().unwrap();
        let dir = temp.path().join("out");
        let mut writer = ReportWriter::create(&dir).unwrap();
        writer.append(&report(0, "geometric")).unwrap();
        // Readable after every frame, not only at the end.
        assert_eq!(read_rows(writer.path()), vec![report(0, "geometric")]);
        writer.append(&report(1, "geometric")).unwrap();
        assert_eq!(
            read_rows(&dir.join("report.jsonl")),
            vec![report(0, "geometric"), report(1, "geometric")]
        );
        let mut names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        assert_eq!(
            names,
            vec![
                std::ffi::OsString::from(REPORT_LOCK_NAME),
                std::ffi::OsString::from("report.jsonl")
            ],
            "no temporary file left"
        );
    }

    #[test]
    fn rendering_a_subset_replaces_those_rows_and_keeps_the_others_sorted() {
        let temp = tempfile::tempdir().unwrap();
        let mut first_run = ReportWriter::create(temp.path()).unwrap();
        for frame in [0, 1, 2, 3] {
            first_run.append(&report(frame, "geometric")).unwrap();
        }
        drop(first_run);
        // A foreign row (another version, an extra field) must survive untouched.
        let path = temp.path().join(REPORT_FILE_NAME);
        let mut contents = fs::read_to_string(&path).unwrap();
        contents.push_str("{\"frame\":9,\"future_field\":true}\n");
        fs::write(&path, contents).unwrap();

        let mut second_run = ReportWriter::create(temp.path()).unwrap();
        second_run.append(&report(2, "raytrace")).unwrap();
        second_run.append(&report(5, "raytrace")).unwrap();
        second_run.append(&report(1, "raytrace")).unwrap();

        let lines: Vec<String> = fs::read_to_string(&path)
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        let frames: Vec<u64> = lines
            .iter()
            .map(|line| {
                serde_json::from_str::<serde_json::Value>(line).unwrap()["frame"]
                    .as_u64()
                    .unwrap()
            })
            .collect();
        assert_eq!(frames, vec![0, 1, 2, 3, 5, 9]);
        let method =
            |line: &str| serde_json::from_str::<serde_json::Value>(line).unwrap()["method"].clone();
        assert_eq!(method(&lines[0]), "geometric");
        assert_eq!(method(&lines[1]), "raytrace");
        assert_eq!(method(&lines[2]), "raytrace");
        assert_eq!(method(&lines[3]), "geometric");
        assert_eq!(lines[5], "{\"frame\":9,\"future_field\":true}");
    }

    /// Writers opened on one folder at once (as processes of a farm are) each update the report
    /// on disk as it is then: every row of every writer is kept.
    #[test]
    fn writers_of_one_folder_at_once_lose_no_row() {
        let temp = tempfile::tempdir().unwrap();
        let dir = temp.path().to_path_buf();
        std::thread::scope(|scope| {
            for writer_index in 0..4u32 {
                let dir = dir.clone();
                scope.spawn(move || {
                    // Opened before any other writer has written: its memory holds no rows.
                    let mut writer = ReportWriter::create(&dir).unwrap();
                    for frame in (0..10).map(|k| writer_index + 4 * k) {
                        writer.append(&report(frame, "geometric")).unwrap();
                    }
                });
            }
        });
        let frames: Vec<u32> = read_rows(&dir.join(REPORT_FILE_NAME))
            .iter()
            .map(|row| row.frame)
            .collect();
        assert_eq!(frames, (0..40).collect::<Vec<u32>>());
    }

    #[test]
    fn the_input_hash_of_a_row_is_read_back() {
        let temp = tempfile::tempdir().unwrap();
        let mut writer = ReportWriter::create(temp.path()).unwrap();
        writer.append(&report(1, "geometric")).unwrap();
        let mut hashed = report(2, "geometric");
        hashed.input_hash = Some("ab12".into());
        writer.append(&hashed).unwrap();
        drop(writer);
        let reopened = ReportWriter::create(temp.path()).unwrap();
        assert_eq!(reopened.row_input_hash(1), None, "a row without a hash");
        assert_eq!(reopened.row_input_hash(2).as_deref(), Some("ab12"));
        assert_eq!(reopened.row_input_hash(3), None, "no row");
    }

    #[test]
    fn row_has_the_specified_fields() {
        let value = serde_json::to_value(report(3, "geometric")).unwrap();
        let mut keys: Vec<&str> = value
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        keys.sort();
        assert_eq!(
            keys,
            [
                "convergence_policy",
                "counts",
                "frame",
                "method",
                "size",
                "stage_secs",
                "time_secs"
            ]
        );
        assert_eq!(value["counts"]["vertices"]["convergence"], 6);
    }

    #[test]
    fn corrupt_existing_report_names_file_and_line() {
        let temp = tempfile::tempdir().unwrap();
        let path = temp.path().join(REPORT_FILE_NAME);
        fs::write(&path, "{\"frame\":0}\nnot json\n").unwrap();
        let message = ReportWriter::create(temp.path()).unwrap_err().to_string();
        assert!(
            message.contains(&format!("{}:2:", path.display())),
            "{message}"
        );

        fs::write(&path, "{\"frame\":0}\n{\"frame\":0}\n").unwrap();
        let message = ReportWriter::create(temp.path()).unwrap_err().to_string();
        assert!(
            message.contains("frame 0 already has a row on line 1"),
            "{message}"
        );
    }

    #[test]
    fn unwritable_directory_is_a_clear_error() {
        let temp = tempfile::tempdir().unwrap();
        let regular_file = temp.path().join("file");
        fs::write(&regular_file, b"x").unwrap();
        let message = ReportWriter::create(&regular_file.join("out"))
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("a path component is a regular file"),
            "{message}"
        );
    }
}
