//! Where the preview's frames come from: a method rendering the scene (`snell preview SCENE`), or
//! a folder of rendered EXRs (`snell preview --frames-dir DIR`, once per folder), each folder a
//! source of its own so that two renders (two methods, or before and after a change) compare A/B.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ::exr::prelude::AttributeValue;

use crate::frame::{Method, SnellError};

/// One source of frames. The API and the page name it (`method=` in requests) by [`Source::name`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Source {
    /// The scene rendered by this method.
    Method(Method),
    /// The EXR files of the `--frames-dir` folder with this index.
    Folder(u8),
}

impl Source {
    pub fn method(self) -> Option<Method> {
        match self {
            Source::Method(method) => Some(method),
            Source::Folder(_) => None,
        }
    }
}

/// A folder of rendered frames: one EXR file per frame number.
#[derive(Clone, Debug)]
pub(super) struct Folder {
    /// The name the page shows and requests use: the folder's own name (made unique).
    pub name: String,
    /// The folder as given on the command line.
    pub shown: String,
    pub files: BTreeMap<u32, PathBuf>,
    /// `snell.method` of its first frame (`raytrace/exact-surface` is the reference), if any.
    pub method_label: Option<String>,
    /// `framesPerSecond` of its first frame.
    pub fps: Option<f64>,
    /// Width and height of its first frame.
    pub size: (u32, u32),
}

impl Folder {
    /// Whether its frames are the ray-traced reference the inspector measures positions against.
    pub fn is_reference(&self) -> bool {
        self.method_label.as_deref() == Some(Method::Raytrace.label())
    }
}

/// The frame number of a rendered frame's file name: the digits before `.exr` (`pool.0012.exr`,
/// `shot_0012.exr`, `render.12.exr`); None for other files.
fn frame_number(file_name: &str) -> Option<u32> {
    let stem = file_name.strip_suffix(".exr")?;
    let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    if digits == 0 {
        return None;
    }
    stem[stem.len() - digits..].parse().ok()
}

/// Lists `dir`'s frames and reads its first frame's header; an error names the folder and what
/// is wrong (not a folder, no frames, two files of one frame number).
pub(super) fn scan_folder(dir: &Path, taken: &[String]) -> Result<Folder, SnellError> {
    let problem =
        |what: String| SnellError::Argument(format!("--frames-dir {}: {what}", dir.display()));
    let entries =
        std::fs::read_dir(dir).map_err(|error| problem(format!("cannot list it: {error}")))?;
    let mut files: BTreeMap<u32, PathBuf> = BTreeMap::new();
    for entry in entries {
        let entry = entry.map_err(|error| problem(format!("cannot list it: {error}")))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(number) = frame_number(&name) else {
            continue;
        };
        if !entry.file_type().is_ok_and(|kind| kind.is_file()) {
            continue;
        }
        let path = entry.path();
        if let Some(other) = files.insert(number, path.clone()) {
            let (a, b) = if other < path {
                (other, path)
            } else {
                (path, other)
            };
            return Err(problem(format!(
                "two files hold frame {number}: {} and {}; give a folder with one render",
                a.display(),
                b.display()
            )));
        }
    }
    let Some(first) = files.values().next() else {
        return Err(problem(
            "no EXR frames in it (files named like pool.0001.exr, with the frame number before .exr)".into(),
        ));
    };
    let meta = ::exr::meta::MetaData::read_from_file(first, false).map_err(|error| {
        problem(format!(
            "{}: not a readable EXR file: {error}",
            first.display()
        ))
    })?;
    let attribute = |name: &str| {
        meta.headers.first().and_then(|header| {
            header
                .own_attributes
                .other
                .iter()
                .chain(header.shared_attributes.other.iter())
                .find(|(key, _)| **key == *name)
                .map(|(_, value)| value.clone())
        })
    };
    let method_label = match attribute("snell.method") {
        Some(AttributeValue::Text(text)) => Some(text.to_string()),
        _ => None,
    };
    let fps = match attribute("framesPerSecond") {
        Some(AttributeValue::Rational((numerator, denominator)))
            if denominator > 0 && numerator > 0 =>
        {
            Some(numerator as f64 / denominator as f64)
        }
        _ => None,
    };
    let size = meta.headers.first().map_or((0, 0), |header| {
        (
            header.layer_size.width() as u32,
            header.layer_size.height() as u32,
        )
    });
    let base = dir
        .canonicalize()
        .unwrap_or_else(|_| dir.to_path_buf())
        .file_name()
        .map_or_else(
            || "frames".to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
    let mut name = base.clone();
    let mut count = 2;
    while taken.contains(&name) {
        name = format!("{base}-{count}");
        count += 1;
    }
    Ok(Folder {
        name,
        shown: super::shown_path(dir),
        files,
        method_label,
        fps,
        size,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_numbers_come_from_the_digits_before_exr() {
        assert_eq!(frame_number("pool.0012.exr"), Some(12));
        assert_eq!(frame_number("shot_0007.exr"), Some(7));
        assert_eq!(frame_number("render.3.exr"), Some(3));
        assert_eq!(frame_number("pool.exr"), None);
        assert_eq!(frame_number("pool.0012.exr.tmp"), None);
        assert_eq!(frame_number("pool.0012.png"), None);
    }

    #[test]
    fn a_folder_without_frames_or_with_two_of_one_number_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let error = scan_folder(dir.path(), &[]).unwrap_err().to_string();
        assert!(error.contains("no EXR frames"), "{error}");
        std::fs::write(dir.path().join("a.0001.exr"), b"").unwrap();
        std::fs::write(dir.path().join("b.1.exr"), b"").unwrap();
        let error = scan_folder(dir.path(), &[]).unwrap_err().to_string();
        assert!(error.contains("two files hold frame 1"), "{error}");
    }
}
