//! The WGSL modules of the renderer, embedded at build time and assembled by concatenating the
//! shared piece (`shaders/common.inc.wgsl`) in front of each pass's file. The naga test
//! (`tests/shaders.rs`) validates exactly what [`assembled_shaders`] returns.

/// The shared prelude every module starts with.
pub const COMMON_FILE: &str = "shaders/common.inc.wgsl";
const COMMON_SOURCE: &str = include_str!("../../shaders/common.inc.wgsl");

/// One assembled shader module: where its pieces came from, and the WGSL text.
#[derive(Clone, Debug)]
pub struct ShaderModuleSource {
    /// Short name, used as the wgpu label.
    pub name: &'static str,
    /// The pass's own file, relative to the crate root.
    pub file: &'static str,
    /// `COMMON_FILE`'s text followed by the pass's file.
    pub source: String,
    /// Number of lines of the prelude, so a line of `source` maps back to its file.
    pub prelude_lines: usize,
}

impl ShaderModuleSource {
    /// File and 1-based line inside it for a 1-based line of the assembled source.
    pub fn origin_of_line(&self, assembled_line: usize) -> (&'static str, usize) {
        if assembled_line <= self.prelude_lines {
            (COMMON_FILE, assembled_line)
        } else {
            (self.file, assembled_line - self.prelude_lines)
        }
    }
}

/// (name, file, text) of every pass's module.
const PASS_SOURCES: [(&str, &str, &str); 6] = [
    (
        "sky",
        "shaders/sky.wgsl",
        include_str!("../../shaders/sky.wgsl"),
    ),
    (
        "above",
        "shaders/above.wgsl",
        include_str!("../../shaders/above.wgsl"),
    ),
    (
        "membrane",
        "shaders/membrane.wgsl",
        include_str!("../../shaders/membrane.wgsl"),
    ),
    (
        "water_clear",
        "shaders/water_clear.wgsl",
        include_str!("../../shaders/water_clear.wgsl"),
    ),
    (
        "under",
        "shaders/under.wgsl",
        include_str!("../../shaders/under.wgsl"),
    ),
    (
        "resolve",
        "shaders/resolve.wgsl",
        include_str!("../../shaders/resolve.wgsl"),
    ),
];

/// Every shader module the renderer creates, assembled as it creates them.
pub fn assembled_shaders() -> Vec<ShaderModuleSource> {
    let mut prelude = COMMON_SOURCE.to_string();
    if !prelude.ends_with('\n') {
        prelude.push('\n');
    }
    let prelude_lines = prelude.lines().count();
    PASS_SOURCES
        .iter()
        .map(|&(name, file, body)| ShaderModuleSource {
            name,
            file,
            source: format!("{prelude}{body}"),
            prelude_lines,
        })
        .collect()
}

/// The assembled module called `name`.
pub(crate) fn assembled_shader(name: &str) -> Option<ShaderModuleSource> {
    assembled_shaders()
        .into_iter()
        .find(|module| module.name == name)
}
