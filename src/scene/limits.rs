//! The stated range of every numeric scene key, checked where the value is written (before the
//! scene is typed, so the error points at the number itself), and the limits of the world.
//!
//! The ranges are chosen so that no computation of a frame can overflow `f32`, and generous for
//! real shots: positions within [`WORLD_LIMIT_M`] metres (the far clip plane is 1,000 m, and f32
//! keeps 0.1 mm there), colours in 0..1, intensities up to 1,000, absorption up to 1,000 per
//! metre. The README's scene reference lists the same table (`tests/docs.rs`-style check in this
//! module's tests keeps the two equal).

use super::error::{KeyPath, Seg};

/// Every coordinate a scene states (eye, target, translations, water extent, root paths) lies
/// within this many metres of the origin, and every object built from them within
/// [`GEOMETRY_LIMIT_M`].
pub const WORLD_LIMIT_M: f64 = 1000.0;
/// Every vertex of the built scene (objects scaled, pools with their decks, posed characters)
/// lies within this many metres of the origin along each axis.
pub const GEOMETRY_LIMIT_M: f64 = 2000.0;
/// The longest timeline, in frames (11.6 hours at 24 fps).
pub const MAX_TIMELINE_FRAMES: u64 = 1_000_000;
/// Frame numbers as OpenEXR headers store them (a signed 32-bit integer).
pub const MAX_FRAME_NUMBER: i64 = i32::MAX as i64;

/// A closed or open interval of allowed values of one key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyRange {
    /// The key's path with `[]` for any array index, e.g. `camera[].eye[]`; texture keys are
    /// written for `texture` and hold for `floor_texture` and `deck_texture` too.
    pub key: &'static str,
    pub min: f64,
    pub max: f64,
    /// The bounds themselves are not allowed.
    pub min_open: bool,
    pub max_open: bool,
    /// A whole number.
    pub integer: bool,
    /// "m", "s", "deg", ... ("" for plain numbers).
    pub unit: &'static str,
    /// A value to suggest.
    pub example: &'static str,
}

const fn closed(
    key: &'static str,
    min: f64,
    max: f64,
    unit: &'static str,
    example: &'static str,
) -> KeyRange {
    KeyRange {
        key,
        min,
        max,
        min_open: false,
        max_open: false,
        integer: false,
        unit,
        example,
    }
}

/// Greater than `min` (not equal), at most `max`.
const fn above(
    key: &'static str,
    min: f64,
    max: f64,
    unit: &'static str,
    example: &'static str,
) -> KeyRange {
    KeyRange {
        min_open: true,
        ..closed(key, min, max, unit, example)
    }
}

/// An sRGB colour component: 0 to 1 (brightness comes from the intensity keys).
const fn srgb(key: &'static str, example: &'static str) -> KeyRange {
    closed(key, 0.0, 1.0, "sRGB", example)
}

const fn whole(key: &'static str, min: f64, max: f64, example: &'static str) -> KeyRange {
    KeyRange {
        integer: true,
        ..closed(key, min, max, "", example)
    }
}

const W: f64 = WORLD_LIMIT_M;
/// Angles: ten turns either way.
const TURNS_DEG: f64 = 3600.0;
/// Keyframe times: 115 days either way.
const KEY_SECS: f64 = 1e7;

/// Every numeric key of the scene format and its range, in the order of the README's reference.
pub const KEY_RANGES: &[KeyRange] = &[
    closed("max_edge_m", 0.01, 100.0, "m", "0.1"),
    closed("timeline.fps", 1.0, 1000.0, "frames/s", "24"),
    whole("timeline.frames[]", 0.0, MAX_FRAME_NUMBER as f64, "[1, 48]"),
    closed(
        "camera[].frame",
        -(MAX_FRAME_NUMBER as f64),
        MAX_FRAME_NUMBER as f64,
        "frame",
        "1",
    ),
    closed("camera[].time_secs", -KEY_SECS, KEY_SECS, "s", "0.0"),
    closed("camera[].eye[]", -W, W, "m", "[0.0, 2.0, -4.0]"),
    closed("camera[].target[]", -W, W, "m", "[0.0, -0.5, 0.0]"),
    KeyRange {
        max_open: true,
        ..above("camera[].fov_deg", 0.0, 180.0, "deg", "50")
    },
    whole("camera.animation", 0.0, 1e6, "0"),
    closed("camera.time_offset_secs", -KEY_SECS, KEY_SECS, "s", "0.0"),
    closed("water.level_m", -W, W, "m", "0.0"),
    closed("water.min[]", -W, W, "m", "[-5.0, -2.5]"),
    closed("water.max[]", -W, W, "m", "[5.0, 2.5]"),
    whole("water.resolution[]", 1.0, 8192.0, "[128, 64]"),
    closed("water.n_above", 0.1, 10.0, "", "1.0"),
    closed("water.n_below", 0.1, 10.0, "", "1.333"),
    closed(
        "water.absorption_per_m[]",
        0.0,
        1000.0,
        "1/m",
        "[0.45, 0.07, 0.03]",
    ),
    srgb("water.scatter_color[]", "[0.05, 0.30, 0.40]"),
    closed("water.roughness", 0.0, 1.0, "", "0.055"),
    closed("water.wave[].amplitude_m", 0.0, 10.0, "m", "0.02"),
    closed("water.wave[].wavelength_m", 0.01, 10000.0, "m", "2.0"),
    closed(
        "water.wave[].direction_deg",
        -TURNS_DEG,
        TURNS_DEG,
        "deg",
        "30",
    ),
    closed("water.wave[].direction[]", -W, W, "", "[1.0, 0.5]"),
    closed("water.wave[].phase_rad", -1000.0, 1000.0, "rad", "0.0"),
    above("water.wave[].speed_m_per_s", 0.0, 1000.0, "m/s", "1.5"),
    whole("water.ripples.resolution[]", 3.0, 4096.0, "[256, 128]"),
    closed("water.ripples.depth_m", 0.005, 1000.0, "m", "0.5"),
    closed(
        "water.ripples.surface_tension_n_per_m",
        0.0,
        1.0,
        "N/m",
        "0.0728",
    ),
    closed(
        "water.ripples.density_kg_per_m3",
        100.0,
        20000.0,
        "kg/m^3",
        "1000",
    ),
    closed("water.ripples.damping_per_s", 0.0, 1000.0, "1/s", "0.5"),
    closed("water.ripples.sponge_width_m", 0.0, W, "m", "0.5"),
    closed("water.ripples.strength", 0.0, 100.0, "", "1.0"),
    above("water.ripples.coupling_depth_m", 0.0, 10.0, "m", "0.1"),
    srgb("sky.zenith_color[]", "[0.30, 0.50, 0.85]"),
    srgb("sky.horizon_color[]", "[0.78, 0.86, 0.95]"),
    srgb("sky.ambient_color[]", "[0.60, 0.70, 0.85]"),
    closed("sky.ambient_intensity", 0.0, 1000.0, "", "0.3"),
    closed("sun.azimuth_deg", -TURNS_DEG, TURNS_DEG, "deg", "135"),
    above("sun.elevation_deg", 0.0, 90.0, "deg", "55"),
    closed("sun.direction[]", -W, W, "", "[0.4, 0.8, 0.4]"),
    srgb("sun.color[]", "[1.0, 0.97, 0.90]"),
    closed("sun.intensity", 0.0, 1000.0, "", "1.0"),
    above("sun.size_deg", 0.0, 45.0, "deg", "0.53"),
    closed("object[].size_m[]", 0.001, 2.0 * W, "m", "[1.0, 0.5, 0.8]"),
    closed("object[].radius_m", 0.001, W, "m", "0.3"),
    closed("object[].depth_m", 0.01, 100.0, "m", "1.6"),
    closed("object[].coping_height_m", 0.0, 100.0, "m", "0.25"),
    closed("object[].deck_width_m", 0.01, W, "m", "3.0"),
    closed("object[].translate[]", -W, W, "m", "[0.0, -1.0, 0.0]"),
    closed(
        "object[].rotate_deg[]",
        -TURNS_DEG,
        TURNS_DEG,
        "deg",
        "[30, 0, 0]",
    ),
    closed("object[].scale[]", 0.001, 1000.0, "", "[1.0, 1.0, 1.0]"),
    closed("object[].max_edge_m", 0.01, 100.0, "m", "0.1"),
    srgb("object[].tint[]", "[1.0, 1.0, 1.0]"),
    srgb("object[].texture.color[]", "[0.8, 0.8, 0.8]"),
    srgb("object[].texture.color_b[]", "[0.15, 0.15, 0.15]"),
    closed("object[].texture.square_m", 0.001, 1000.0, "m", "0.5"),
    closed("object[].texture.tile_size_m", 0.001, 1000.0, "m", "0.125"),
    closed("object[].texture.grout_width_m", 0.0, 1000.0, "m", "0.004"),
    srgb("object[].texture.grout_color[]", "[0.62, 0.66, 0.68]"),
    closed("object[].texture.variation", 0.0, 1.0, "", "0.04"),
    srgb("object[].texture.accent_color[]", "[0.72, 0.87, 0.96]"),
    closed("object[].texture.accent_fraction", 0.0, 1.0, "", "0.15"),
    closed("object[].texture.lane_spacing_m", 0.0, 1000.0, "m", "2.5"),
    closed("object[].texture.lane_width_m", 0.0, 1000.0, "m", "0.25"),
    srgb("object[].texture.lane_color[]", "[0.04, 0.10, 0.32]"),
    whole("object[].texture.seed", 0.0, u32::MAX as f64, "1"),
    closed(
        "object[].texture.size_m[]",
        0.001,
        1000.0,
        "m",
        "[1.0, 1.0]",
    ),
    whole("character[].animation", 0.0, 1e6, "0"),
    closed("character[].speed", 0.0, 100.0, "", "1.0"),
    closed(
        "character[].time_offset_secs",
        -KEY_SECS,
        KEY_SECS,
        "s",
        "0.0",
    ),
    closed("character[].scale", 1e-4, 1000.0, "", "0.01"),
    srgb("character[].tint[]", "[1.0, 1.0, 1.0]"),
    closed(
        "character[].path[].frame",
        -(MAX_FRAME_NUMBER as f64),
        MAX_FRAME_NUMBER as f64,
        "frame",
        "1",
    ),
    closed(
        "character[].path[].time_secs",
        -KEY_SECS,
        KEY_SECS,
        "s",
        "0.0",
    ),
    closed(
        "character[].path[].position[]",
        -W,
        W,
        "m",
        "[0.0, -0.4, 0.0]",
    ),
    closed(
        "character[].path[].heading_deg",
        -10.0 * TURNS_DEG,
        10.0 * TURNS_DEG,
        "deg",
        "90",
    ),
    closed("vessel[].glass_index", 1.0, 4.0, "", "1.5"),
    closed("vessel[].position[]", -W, W, "m", "[0.0, 0.3, 1.0]"),
    closed("vessel[].normal[]", -W, W, "", "[0.0, 0.0, 1.0]"),
    closed("vessel[].up[]", -W, W, "", "[0.0, 1.0, 0.0]"),
    above("vessel[].size_m[]", 0.0, 2.0 * W, "m", "[1.2, 0.6]"),
    above("vessel[].thickness_m", 0.0, 1.0, "m", "0.01"),
    closed("vessel[].base[]", -W, W, "m", "[0.0, 0.0, 0.0]"),
    closed("vessel[].axis[]", -W, W, "", "[0.0, 1.0, 0.0]"),
    above("vessel[].inner_radius_m", 0.0, W, "m", "0.036"),
    above("vessel[].outer_radius_m", 0.0, W, "m", "0.04"),
    above("vessel[].height_m", 0.0, 2.0 * W, "m", "0.12"),
    above("quality.max_error_px", 0.0, 1000.0, "px", "0.5"),
    whole("antialias.supersample", 1.0, 2.0, "2"),
    whole("antialias.reference_grid", 1.0, 16.0, "4"),
];

/// The key path as [`KeyRange::key`] writes it: indices as `[]`, texture slots as `texture`.
pub(crate) fn pattern_of(path: &KeyPath) -> String {
    let mut text = String::new();
    for (i, seg) in path.0.iter().enumerate() {
        match seg {
            Seg::Key(key) => {
                if i > 0 {
                    text.push('.');
                }
                let key = match key.as_str() {
                    "floor_texture" | "deck_texture" => "texture",
                    other => other,
                };
                text.push_str(key);
            }
            Seg::Index(_) => text.push_str("[]"),
        }
    }
    text
}

/// The range of the key at `path`, if the format has one there.
pub(crate) fn range_of(path: &KeyPath) -> Option<&'static KeyRange> {
    let pattern = pattern_of(path);
    KEY_RANGES.iter().find(|range| range.key == pattern)
}

/// `3.2e7` or `0.25`: short, and exact for the table's round numbers.
fn number(value: f64) -> String {
    if value.fract() == 0.0 && value.abs() < 1e10 {
        format!("{}", value as i64)
    } else if value != 0.0 && (value.abs() >= 1e6 || value.abs() < 1e-3) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

impl KeyRange {
    pub fn contains(&self, value: f64) -> bool {
        let above_min = if self.min_open {
            value > self.min
        } else {
            value >= self.min
        };
        let below_max = if self.max_open {
            value < self.max
        } else {
            value <= self.max
        };
        above_min && below_max && (!self.integer || value.fract() == 0.0)
    }

    /// `from 0.01 to 100 m`, `more than 0 and less than 180 deg`.
    pub fn describe(&self) -> String {
        let (min, max) = (number(self.min), number(self.max));
        let unit = if self.unit.is_empty() || self.unit == "sRGB" {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        let span = match (self.min_open, self.max_open) {
            (false, false) => format!("from {min} to {max}{unit}"),
            (true, false) => format!("more than {min} and at most {max}{unit}"),
            (false, true) => format!("at least {min} and less than {max}{unit}"),
            (true, true) => format!("more than {min} and less than {max}{unit}"),
        };
        if self.integer {
            format!("a whole number {span}")
        } else if self.unit == "sRGB" {
            format!("an sRGB colour component {span} (brightness comes from the intensity keys)")
        } else {
            span
        }
    }

    /// The error of a value `written` outside the range: the problem and the fix (the key's
    /// last name, e.g. `resolution`, set to the table's example).
    pub fn problem(&self, written: &str) -> (String, String) {
        let name = self
            .key
            .rsplit('.')
            .next()
            .unwrap_or(self.key)
            .trim_end_matches("[]");
        (
            format!("must be {} (got {written})", self.describe()),
            format!(
                "write a value in that range, e.g. {name} = {}",
                self.example
            ),
        )
    }

    /// The README's row: `| key | range | example |`.
    pub fn markdown_row(&self) -> String {
        let low = if self.min_open { "(" } else { "[" };
        let high = if self.max_open { ")" } else { "]" };
        let kind = if self.integer { " integer" } else { "" };
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        format!(
            "| `{}` | {low}{}, {}{high}{unit}{kind} | `{}` |",
            self.key,
            number(self.min),
            number(self.max),
            self.example
        )
    }
}

/// The README's table of key ranges (header included), generated from [`KEY_RANGES`].
pub fn markdown_table() -> String {
    let mut text = String::from("| key | allowed values | example |\n|---|---|---|\n");
    for range in KEY_RANGES {
        text.push_str(&range.markdown_row());
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_name_indices_and_texture_slots_alike() {
        let path = KeyPath::root()
            .key("object")
            .index(3)
            .key("deck_texture")
            .key("color")
            .index(1);
        assert_eq!(pattern_of(&path), "object[].texture.color[]");
        assert_eq!(range_of(&path).unwrap().max, 1.0);
        assert!(range_of(&KeyPath::root().key("name")).is_none());
    }

    #[test]
    fn bounds_open_closed_and_whole() {
        let fov = range_of(&KeyPath::root().key("camera").index(0).key("fov_deg")).unwrap();
        assert!(
            !fov.contains(0.0) && fov.contains(1e-9) && fov.contains(179.9) && !fov.contains(180.0)
        );
        assert_eq!(fov.describe(), "more than 0 and less than 180 deg");
        let resolution =
            range_of(&KeyPath::root().key("water").key("resolution").index(0)).unwrap();
        assert!(
            resolution.contains(8192.0)
                && !resolution.contains(8193.0)
                && !resolution.contains(2.5)
        );
        assert_eq!(resolution.describe(), "a whole number from 1 to 8192");
        assert!(!resolution.contains(f64::NAN));
    }

    #[test]
    fn every_key_is_stated_once_and_its_example_is_in_range() {
        for (i, range) in KEY_RANGES.iter().enumerate() {
            assert!(
                KEY_RANGES[..i].iter().all(|other| other.key != range.key),
                "{} is listed twice",
                range.key
            );
            assert!(range.min < range.max, "{}", range.key);
            // The example parses as a number or an array of numbers inside the range.
            let example = range.example.trim_matches(['[', ']']);
            for value in example.split(',') {
                let value: f64 = value
                    .trim()
                    .parse()
                    .unwrap_or_else(|_| panic!("{}", range.key));
                assert!(range.contains(value), "{}: example {value}", range.key);
            }
        }
    }

    /// No numeric field of the scene format goes without a stated range: every field of
    /// `format.rs` with a numeric type is listed (this reads the source, so a key added there
    /// without a range fails here, naming it).
    #[test]
    fn every_numeric_field_of_the_format_has_a_range() {
        let source = include_str!("format.rs");
        let numeric = ["f64", "f32", "i64", "u32", "u64", "i32", "usize"];
        let mut fields = Vec::new();
        for line in source.lines() {
            let line = line.trim();
            let Some(rest) = line.strip_prefix("pub ") else {
                continue;
            };
            let Some((name, ty)) = rest.split_once(':') else {
                continue;
            };
            if name.contains(' ') || name.contains('(') {
                continue;
            }
            let ty = ty.trim().trim_end_matches(',');
            if numeric.iter().any(|n| ty.contains(n)) {
                fields.push(name.trim().to_string());
            }
        }
        assert!(fields.len() > 40, "found only {fields:?}");
        for field in fields {
            assert!(
                KEY_RANGES
                    .iter()
                    .any(|range| range.key.trim_end_matches("[]").rsplit('.').next()
                        == Some(field.as_str())),
                "the scene key `{field}` (src/scene/format.rs) has no stated range: add it to \
                 KEY_RANGES in src/scene/limits.rs and to the README's table"
            );
        }
    }

    #[test]
    fn the_readme_lists_the_same_ranges() {
        let readme = include_str!("../../README.md");
        let table = markdown_table();
        assert!(
            readme.contains(&table),
            "README.md's table of scene key ranges differs from KEY_RANGES; paste this:\n{table}"
        );
    }
}
