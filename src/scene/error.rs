//! Scene errors and the source locations they carry: byte offsets from the TOML parser turned into
//! line:column, and key paths (`object[2].radius_m`) turned into the span of the value they name,
//! so semantic errors found after parsing point at the same place a parse error would.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// Everything that can be wrong with a scene. `Display` is one paragraph: where, which key, what is
/// wrong and what to change.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file is not a readable regular file of a sensible size.
    #[error("{0}; name a regular TOML file of at most {max} MiB", max = crate::files::MAX_SCENE_BYTES >> 20)]
    File(#[source] crate::files::InputFileError),
    #[error("{}", located_message(.file, *.line, *.column, .key, .problem, .fix))]
    Invalid {
        file: PathBuf,
        /// 1-based.
        line: usize,
        /// 1-based, in characters.
        column: usize,
        /// The key's path, e.g. `water.resolution` or `camera[1].time_secs`; empty when the file as
        /// a whole is at fault (e.g. a syntax error before any key).
        key: String,
        problem: String,
        fix: String,
    },
}

impl SceneError {
    /// The (line, column) the error points at, when it points into the file.
    pub fn line_column(&self) -> Option<(usize, usize)> {
        match self {
            SceneError::File(_) => None,
            SceneError::Invalid { line, column, .. } => Some((*line, *column)),
        }
    }

    /// The key path the error is about, when there is one.
    pub fn key(&self) -> Option<&str> {
        match self {
            SceneError::Invalid { key, .. } if !key.is_empty() => Some(key),
            _ => None,
        }
    }
}

fn located_message(
    file: &Path,
    line: usize,
    column: usize,
    key: &str,
    problem: &str,
    fix: &str,
) -> String {
    let mut message = format!("{}:{line}:{column}: ", file.display());
    if !key.is_empty() {
        message.push_str(key);
        message.push_str(": ");
    }
    message.push_str(problem);
    if !fix.is_empty() {
        message.push_str("; ");
        message.push_str(fix);
    }
    message
}

/// 1-based line and character column of a byte offset.
pub(crate) fn line_column_of(text: &str, byte_offset: usize) -> (usize, usize) {
    let mut offset = byte_offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

/// One step of a key path.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

/// A key path into the document, displayed the way a user would write it: `object[2].texture.kind`.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct KeyPath(pub Vec<Seg>);

impl KeyPath {
    pub fn root() -> Self {
        KeyPath(Vec::new())
    }
    pub fn key(&self, key: &str) -> Self {
        let mut segs = self.0.clone();
        segs.push(Seg::Key(key.to_owned()));
        KeyPath(segs)
    }
    pub fn index(&self, index: usize) -> Self {
        let mut segs = self.0.clone();
        segs.push(Seg::Index(index));
        KeyPath(segs)
    }
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, seg) in self.0.iter().enumerate() {
            match seg {
                Seg::Key(key) if i == 0 => write!(f, "{key}")?,
                Seg::Key(key) => write!(f, ".{key}")?,
                Seg::Index(index) => write!(f, "[{index}]")?,
            }
        }
        Ok(())
    }
}

/// Whether a value or anything inside it spans `byte_offset`. Tables of a document span only
/// their `[header]`, so their keys have to be searched too.
fn covers(value: &Spanned<DeValue<'_>>, byte_offset: usize) -> bool {
    value.span().contains(&byte_offset)
        || match value.get_ref() {
            DeValue::Table(table) => table
                .iter()
                .any(|(key, v)| key.span().contains(&byte_offset) || covers(v, byte_offset)),
            DeValue::Array(array) => array.iter().any(|v| covers(v, byte_offset)),
            _ => false,
        }
}

/// The parsed document kept beside the typed scene while validating, to locate keys.
pub(crate) struct SourceMap<'a> {
    pub file: &'a Path,
    pub text: &'a str,
    pub root: &'a Spanned<DeTable<'a>>,
}

impl<'a> SourceMap<'a> {
    /// The span of the value at `path`, or of its deepest ancestor present in the file (a key left
    /// to its default has no span of its own: the error then points at its table).
    pub fn span_of(&self, path: &KeyPath) -> Range<usize> {
        let mut span = 0..0;
        let mut current: Option<&DeValue<'a>> = None;
        let mut table: Option<&DeTable<'a>> = Some(self.root.get_ref());
        for seg in &path.0 {
            let next = match (seg, table, current) {
                (Seg::Key(key), Some(t), _) => t.get(key.as_str()),
                (Seg::Index(i), _, Some(DeValue::Array(array))) => array.get(*i),
                _ => None,
            };
            let Some(next) = next else { break };
            span = next.span();
            current = Some(next.get_ref());
            table = match next.get_ref() {
                DeValue::Table(t) => Some(t),
                _ => None,
            };
        }
        span
    }

    fn lookup(&self, path: &KeyPath) -> Option<&'a Spanned<DeValue<'a>>> {
        let mut table: Option<&'a DeTable<'a>> = Some(self.root.get_ref());
        let mut current: Option<&'a Spanned<DeValue<'a>>> = None;
        for seg in &path.0 {
            let next = match seg {
                Seg::Key(key) => table?.get(key.as_str()),
                Seg::Index(i) => match current?.get_ref() {
                    DeValue::Array(array) => array.get(*i),
                    _ => None,
                },
            }?;
            current = Some(next);
            table = match next.get_ref() {
                DeValue::Table(t) => Some(t),
                _ => None,
            };
        }
        current
    }

    /// The keys the file writes in the table at `path`, with their spans.
    pub fn keys_in(&self, path: &KeyPath) -> Vec<(String, Range<usize>)> {
        let table = if path.0.is_empty() {
            Some(self.root.get_ref())
        } else {
            match self.lookup(path).map(|v| v.get_ref()) {
                Some(DeValue::Table(t)) => Some(t),
                _ => None,
            }
        };
        table
            .map(|t| {
                t.iter()
                    .map(|(k, _)| (k.get_ref().to_string(), k.span()))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The key path of the innermost key or value whose span contains `byte_offset`.
    pub fn path_at(&self, byte_offset: usize) -> KeyPath {
        let mut path = KeyPath::root();
        let mut table: Option<&DeTable<'a>> = Some(self.root.get_ref());
        let mut array: Option<&toml::de::DeArray<'a>> = None;
        loop {
            let next = if let Some(table) = table {
                table.iter().find_map(|(key, v)| {
                    let inside = key.span().contains(&byte_offset) || covers(v, byte_offset);
                    inside.then(|| (Seg::Key(key.get_ref().to_string()), v))
                })
            } else if let Some(array) = array {
                array
                    .iter()
                    .enumerate()
                    .find(|(_, v)| covers(v, byte_offset))
                    .map(|(i, v)| (Seg::Index(i), v))
            } else {
                None
            };
            let Some((seg, next)) = next else { break };
            path.0.push(seg);
            (table, array) = match next.get_ref() {
                DeValue::Table(t) => (Some(t), None),
                DeValue::Array(a) => (None, Some(a)),
                _ => (None, None),
            };
        }
        path
    }

    /// The place of the value `path` names, kept for errors raised after validation.
    pub fn source_ref(&self, path: &KeyPath) -> super::SourceRef {
        let (line, column) = line_column_of(self.text, self.span_of(path).start);
        super::SourceRef {
            file: self.file.to_path_buf(),
            line,
            column,
            key: path.to_string(),
        }
    }

    /// An error at the value `path` names.
    pub fn error(
        &self,
        path: &KeyPath,
        problem: impl Into<String>,
        fix: impl Into<String>,
    ) -> SceneError {
        let span = self.span_of(path);
        self.error_at(span.start, path.to_string(), problem, fix)
    }

    /// An error at a byte offset.
    pub fn error_at(
        &self,
        byte_offset: usize,
        key: String,
        problem: impl Into<String>,
        fix: impl Into<String>,
    ) -> SceneError {
        let (line, column) = line_column_of(self.text, byte_offset);
        SceneError::Invalid {
            file: self.file.to_path_buf(),
            line,
            column,
            key,
            problem: problem.into(),
            fix: fix.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_counts_characters_from_one() {
        let text = "a = 1\nbé = 2\n";
        assert_eq!(line_column_of(text, 0), (1, 1));
        assert_eq!(line_column_of(text, 6), (2, 1));
        // "bé = " is 6 bytes but 5 characters: the value starts at column 6.
        assert_eq!(line_column_of(text, 12), (2, 6));
    }

    #[test]
    fn paths_display_like_toml_keys() {
        let path = KeyPath::root()
            .key("object")
            .index(2)
            .key("texture")
            .key("kind");
        assert_eq!(path.to_string(), "object[2].texture.kind");
    }

    #[test]
    fn span_and_path_lookups_agree() {
        let text = "[water]\nresolution = [0, 64]\n\n[[object]]\nshape = \"box\"\n\n[[object]]\nshape = \"ball\"\n";
        let root = DeTable::parse(text).unwrap();
        let map = SourceMap {
            file: Path::new("x.toml"),
            text,
            root: &root,
        };
        let shape = KeyPath::root().key("object").index(1).key("shape");
        let span = map.span_of(&shape);
        assert_eq!(&text[span.clone()], "\"ball\"");
        assert_eq!(line_column_of(text, span.start), (8, 9));
        assert_eq!(map.path_at(span.start), shape);
        let res = KeyPath::root().key("water").key("resolution");
        assert_eq!(line_column_of(text, map.span_of(&res).start), (2, 14));
        // A key left to its default points at its table's header.
        let level = KeyPath::root().key("water").key("level_m");
        assert_eq!(line_column_of(text, map.span_of(&level).start), (1, 1));
        assert_eq!(map.path_at(map.span_of(&res).start), res);
        assert_eq!(map.path_at(map.span_of(&res).start + 1), res.index(0));
    }
}
