//! Where each frame's EXR goes: `DIR/<scene>.<frame>.exr` by default, or a file pattern given to
//! `--out` in which one run of `#` is the frame number padded to that many digits
//! (`shots/pool/render.####.exr`), or husk's `$F4` (`$F` alone: no padding). Frame numbers wider
//! than the padding keep every digit.

use std::path::{Path, PathBuf};

/// A frame file name with the frame number's place and padding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputPattern {
    dir: PathBuf,
    prefix: String,
    digits: usize,
    suffix: String,
}

impl OutputPattern {
    /// `dir/<scene_name>.<frame, 4 digits at least>.exr`.
    pub fn for_scene(dir: &Path, scene_name: &str) -> Self {
        OutputPattern {
            dir: dir.to_path_buf(),
            prefix: format!("{scene_name}."),
            digits: 4,
            suffix: ".exr".to_string(),
        }
    }

    /// `out` as a pattern when its file name holds a frame token (`#` run or `$F`), None when it
    /// names a folder. An error says what is wrong with a pattern.
    pub fn parse(out: &Path) -> Result<Option<Self>, String> {
        let text = out.to_string_lossy();
        let has_token = |s: &str| s.contains('#') || s.contains("$F");
        if !has_token(&text) {
            return Ok(None);
        }
        let name = out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let dir = out.parent().map(Path::to_path_buf).unwrap_or_default();
        let explain = |problem: String| {
            format!("--out {text:?}: {problem}; write a file pattern such as shots/pool/render.####.exr or render.$F4.exr, or a folder")
        };
        if has_token(&dir.to_string_lossy()) {
            return Err(explain(
                "the frame number (`#` or `$F`) may only be in the file name, not in a folder"
                    .into(),
            ));
        }
        let mut tokens = Vec::new(); // (start, end, digits)
        let bytes = name.as_bytes();
        let mut at = 0;
        while at < bytes.len() {
            if bytes[at] == b'#' {
                let start = at;
                while at < bytes.len() && bytes[at] == b'#' {
                    at += 1;
                }
                tokens.push((start, at, at - start));
            } else if name[at..].starts_with("$F") {
                let start = at;
                at += 2;
                let digits_start = at;
                while at < bytes.len() && bytes[at].is_ascii_digit() {
                    at += 1;
                }
                let digits = if at == digits_start {
                    1
                } else {
                    name[digits_start..at]
                        .parse::<usize>()
                        .ok()
                        .filter(|d| (1..=10).contains(d))
                        .ok_or_else(|| explain("the padding after $F must be 1 to 10".into()))?
                };
                tokens.push((start, at, digits));
            } else {
                at += 1;
            }
        }
        let [(start, end, digits)] = tokens[..] else {
            return Err(explain(format!(
                "the file name holds {} frame numbers (`#` runs or `$F`); it must hold exactly one",
                tokens.len()
            )));
        };
        if digits > 10 {
            return Err(explain(format!(
                "{digits} `#` is more padding than a frame number has digits (10 at most)"
            )));
        }
        let suffix = name[end..].to_string();
        if !suffix.to_ascii_lowercase().ends_with(".exr") {
            return Err(explain("the file name must end with .exr".into()));
        }
        let prefix = name[..start].to_string();
        // Temporary names add up to ~96 bytes to a frame's name; file systems allow 255.
        if prefix.len() + suffix.len() + 10 > 150 {
            return Err(explain("the file name is longer than 150 bytes".into()));
        }
        Ok(Some(OutputPattern {
            dir,
            prefix,
            digits,
            suffix,
        }))
    }

    /// The folder the frames (and the report, the checkpoints) go in.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The EXR path of `frame`.
    pub fn path(&self, frame: u32) -> PathBuf {
        self.dir.join(format!(
            "{}{frame:0width$}{}",
            self.prefix,
            self.suffix,
            width = self.digits
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(text: &str) -> OutputPattern {
        OutputPattern::parse(Path::new(text)).unwrap().unwrap()
    }

    #[test]
    fn hashes_and_husk_tokens_give_the_padding() {
        let p = pattern("shots/pool/render.####.exr");
        assert_eq!(p.dir(), Path::new("shots/pool"));
        assert_eq!(p.path(7), Path::new("shots/pool/render.0007.exr"));
        assert_eq!(p.path(12345), Path::new("shots/pool/render.12345.exr"));
        assert_eq!(pattern("r_##.exr").path(3), Path::new("r_03.exr"));
        assert_eq!(
            pattern("out/r.$F4.exr").path(3),
            Path::new("out/r.0003.exr")
        );
        assert_eq!(pattern("out/r.$F.exr").path(3), Path::new("out/r.3.exr"));
        assert_eq!(
            pattern("out/$F6_beauty.EXR").path(42),
            Path::new("out/000042_beauty.EXR")
        );
    }

    #[test]
    fn folders_are_not_patterns_and_the_default_is_the_scene_name() {
        assert_eq!(OutputPattern::parse(Path::new("output/pool")), Ok(None));
        assert_eq!(
            OutputPattern::for_scene(Path::new("out"), "pool").path(7),
            Path::new("out/pool.0007.exr")
        );
    }

    #[test]
    fn bad_patterns_say_what_is_wrong() {
        let error = |text: &str| OutputPattern::parse(Path::new(text)).unwrap_err();
        assert!(error("a/r.##.##.exr").contains("holds 2 frame numbers"));
        assert!(error("a/r.####").contains("must end with .exr"));
        assert!(error("a/r.####.png").contains("must end with .exr"));
        assert!(error("shot_##/r.exr").contains("only be in the file name"));
        assert!(error("a/r.$F99.exr").contains("padding after $F must be 1 to 10"));
        assert!(error("a/r.###########.exr").contains("more padding"));
    }
}
