//! The EXR channel map: the name, type and meaning of every layer snell writes, and of the layers
//! later work will add (reserved here so that they are filled in, not renamed). The README's table
//! "The EXR channel map" is the same map in words; a test checks that every row below is in it.
//!
//! Naming rules, chosen so that Blender, Nuke and OpenImageIO all read every layer:
//! - a layer is `<Layer>.<channel>` with a CamelCase layer name (no dots, no spaces: Nuke splits at
//!   the last dot and Blender at every dot) and a one-letter channel: Blender's multilayer reader
//!   (`imb_exr_split_channel_name`) drops a channel whose last token is not one letter, two
//!   letters ending in X, Y, Z, R, G, B, U, V or A, or one of red, green, blue, alpha, depth;
//! - colours are `.R .G .B`, positions and vectors `.X .Y .Z`, depths `.Z`, every other scalar
//!   (masks, mattes, indices) `.X`, as Blender names its own value passes (`IndexOB.X`);
//! - the beauty and the first surface's depth keep the layer-less `R G B A` and `Z` that every
//!   tool shows by default (Blender: Combined and Depth; Nuke: rgba and depth);
//! - IDs are float32: OpenImageIO converts u32 channels to float by dividing by 2^32 - 1, which
//!   loses them. Indices are small integers, exact in float32; Cryptomatte IDs are the spec's
//!   float bit patterns.
//!
//! Nothing seen: no layer holds NaN or an infinity. Depths hold [`SKY_DEPTH_M`] (Blender's 1e10),
//! positions, IDs, masks and effects 0.

use crate::draw::flag_bits;
pub use crate::draw::SKY_DEPTH_M;

/// Written to `snell.channelMap`: which version of this map a frame follows. Frames without the
/// attribute follow the first layout ([`legacy`]).
pub const CHANNEL_MAP_VERSION: &str = "2";

/// Linear HDR beauty (Rec. 709 primaries, D65: the `chromaticities` attribute).
pub const BEAUTY: [&str; 4] = ["R", "G", "B", "A"];
/// Depth along the view axis of the first surface (the water's for water pixels), metres.
pub const DEPTH: &str = "Z";
/// Depth along the view axis of what the pixel shows (the virtual image through water).
pub const APPARENT_DEPTH: &str = "ApparentDepth.Z";
/// Screen motion of what the pixel shows from frame t-1 to t, in pixels: x to the right, y down
/// (the pixel now minus where the same point, seen through the water too, was at t-1); 0 where
/// nothing is seen and on the timeline's first frame. Derived, not checked in those tools: Blender's
/// `Vector.X, Vector.Y` (Cycles stores now minus before, rows counted up) are `Motion.X, -Motion.Y`;
/// Nuke's `backward` (toward t-1, y up) is `-Motion.X, Motion.Y`.
pub const MOTION: [&str; 2] = ["Motion.X", "Motion.Y"];
/// True world position of what the pixel shows.
pub const POSITION: [&str; 3] = ["P.X", "P.Y", "P.Z"];
/// Scene object index (1-based) of what the pixel shows, 0 for none.
pub const INDEX_OB: &str = "IndexOB.X";
/// 1 where the first surface is the water.
pub const WATER_MATTE: &str = "WaterMatte.X";
/// The beauty split into effects; their sum is the beauty's RGB.
pub const DIRECT: [&str; 3] = ["Direct.R", "Direct.G", "Direct.B"];
pub const REFRACTION: [&str; 3] = ["Refraction.R", "Refraction.G", "Refraction.B"];
pub const SKY_REFLECTION: [&str; 3] = ["SkyReflection.R", "SkyReflection.G", "SkyReflection.B"];
/// The Cryptomatte type name; its layers are `CryptoObject00`, `CryptoObject01`, ...
pub const CRYPTO_OBJECT: &str = "CryptoObject";
/// Cryptomatte ranks written per pixel (two per layer): a pixel holds at most two IDs today (the
/// water and the object seen through it). Fixed per snell version, so a sequence has one channel
/// set; more come with reflections and anti-aliasing.
pub const CRYPTO_RANKS: usize = 2;

/// The 0/1 masks of the [`flag_bits`] (f16).
pub const FLAG_CHANNELS: [(&str, u32); 4] = [
    ("FlagConvergence.X", flag_bits::CONVERGENCE),
    ("FlagBoundary.X", flag_bits::BOUNDARY),
    ("FlagPopping.X", flag_bits::POPPING),
    ("FlagExtrapolated.X", flag_bits::EXTRAPOLATED),
];

/// `CryptoObject00.R` ... for `CRYPTO_RANKS` ranks: (id channel, coverage channel) per rank.
pub fn crypto_rank_channels() -> Vec<(String, String)> {
    (0..CRYPTO_RANKS)
        .map(|rank| {
            let layer = format!("{CRYPTO_OBJECT}{:02}", rank / 2);
            let (id, coverage) = if rank % 2 == 0 {
                ("R", "G")
            } else {
                ("B", "A")
            };
            (format!("{layer}.{id}"), format!("{layer}.{coverage}"))
        })
        .collect()
}

/// A layer of the map that frames hold today, as `--layers` names it: the layer name before the
/// dot, `beauty` for `R, G, B, A` and `Z` for the depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Layer {
    Beauty,
    Depth,
    ApparentDepth,
    Position,
    IndexOb,
    CryptoObject,
    WaterMatte,
    Direct,
    Refraction,
    SkyReflection,
    FlagConvergence,
    FlagBoundary,
    FlagPopping,
    FlagExtrapolated,
    Motion,
}

impl Layer {
    /// Every layer, in the map's order.
    pub const ALL: [Layer; 15] = [
        Layer::Beauty,
        Layer::Depth,
        Layer::ApparentDepth,
        Layer::Position,
        Layer::IndexOb,
        Layer::CryptoObject,
        Layer::WaterMatte,
        Layer::Direct,
        Layer::Refraction,
        Layer::SkyReflection,
        Layer::FlagConvergence,
        Layer::FlagBoundary,
        Layer::FlagPopping,
        Layer::FlagExtrapolated,
        Layer::Motion,
    ];

    /// The name `--layers` takes and `snell.output` gives.
    pub fn name(self) -> &'static str {
        match self {
            Layer::Beauty => "beauty",
            Layer::Depth => "Z",
            Layer::ApparentDepth => "ApparentDepth",
            Layer::Position => "P",
            Layer::IndexOb => "IndexOB",
            Layer::CryptoObject => "CryptoObject",
            Layer::WaterMatte => "WaterMatte",
            Layer::Direct => "Direct",
            Layer::Refraction => "Refraction",
            Layer::SkyReflection => "SkyReflection",
            Layer::FlagConvergence => "FlagConvergence",
            Layer::FlagBoundary => "FlagBoundary",
            Layer::FlagPopping => "FlagPopping",
            Layer::FlagExtrapolated => "FlagExtrapolated",
            Layer::Motion => "Motion",
        }
    }

    /// The flag layer of a [`flag_bits`] bit.
    pub fn of_flag(bit: u32) -> Layer {
        match bit {
            flag_bits::CONVERGENCE => Layer::FlagConvergence,
            flag_bits::BOUNDARY => Layer::FlagBoundary,
            flag_bits::POPPING => Layer::FlagPopping,
            flag_bits::EXTRAPOLATED => Layer::FlagExtrapolated,
            _ => unreachable!("flag bit {bit:#x} has no layer"),
        }
    }

    fn bit(self) -> u32 {
        1 << self as u32
    }
}

/// Which layers a frame holds (`--layers`). The beauty is always among them: every reader shows
/// it first, and snell's own tools and `--resume` read it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerSet(u32);

impl Default for LayerSet {
    /// Every layer (`all`), what frames held before `--layers` existed.
    fn default() -> Self {
        LayerSet::ALL
    }
}

impl LayerSet {
    /// The preset `all`: every layer of the map.
    pub const ALL: LayerSet = LayerSet::of(&Layer::ALL);
    /// The preset `comp`: what a compositor grades with (the beauty, which `comp` also stores as
    /// half floats, `Z`, the IDs and the water matte).
    pub const COMP: LayerSet = LayerSet::of(&[
        Layer::Beauty,
        Layer::Depth,
        Layer::IndexOb,
        Layer::CryptoObject,
        Layer::WaterMatte,
    ]);
    /// The presets `--layers` takes by name.
    pub const PRESETS: [(&'static str, LayerSet); 2] =
        [("all", LayerSet::ALL), ("comp", LayerSet::COMP)];

    const fn of(layers: &[Layer]) -> LayerSet {
        let mut bits = 1 << Layer::Beauty as u32;
        let mut i = 0;
        while i < layers.len() {
            bits |= 1 << layers[i] as u32;
            i += 1;
        }
        LayerSet(bits)
    }

    pub fn has(self, layer: Layer) -> bool {
        self.0 & layer.bit() != 0
    }

    /// The layers held, in the map's order.
    pub fn layers(self) -> impl Iterator<Item = Layer> {
        Layer::ALL.into_iter().filter(move |&layer| self.has(layer))
    }

    /// `all`, `comp`, or the layers' names joined by commas (`beauty,Z,P`): what the header's
    /// `snell.output` gives after `layers=`.
    pub fn label(self) -> String {
        if let Some((name, _)) = Self::PRESETS.iter().find(|(_, set)| *set == self) {
            return name.to_string();
        }
        self.layers().map(Layer::name).collect::<Vec<_>>().join(",")
    }

    /// Reads `--layers`: comma-separated presets and layer names (any case), their union, the
    /// beauty always included. Also says whether `comp` was among them (it stores the beauty as
    /// half floats). The error names the unknown word and lists every valid one.
    pub fn parse(text: &str) -> Result<(LayerSet, bool), String> {
        let mut bits = LayerSet::of(&[]).0;
        let mut half = false;
        for word in text.split(',').map(str::trim) {
            if let Some((name, set)) = Self::PRESETS
                .iter()
                .find(|(name, _)| name.eq_ignore_ascii_case(word))
            {
                bits |= set.0;
                half |= *name == "comp";
            } else if let Some(layer) = Layer::ALL
                .iter()
                .find(|layer| layer.name().eq_ignore_ascii_case(word))
            {
                bits |= layer.bit();
            } else {
                let what = if word.is_empty() {
                    "an empty layer name".to_string()
                } else {
                    format!("unknown layer `{word}`")
                };
                return Err(format!(
                    "{what}; give presets ({}) or layers ({}), separated by commas, e.g. --layers comp,P",
                    Self::PRESETS.map(|(name, _)| name).join(", "),
                    Layer::ALL.map(Layer::name).join(", ")
                ));
            }
        }
        Ok((LayerSet(bits), half))
    }
}

/// Whether a layer is in frames today or only reserved for later work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    Written,
    /// Reserved for the work of the named issue; not written yet.
    Reserved(&'static str),
}

/// One row of the channel map (the README's table has the same rows).
#[derive(Clone, Copy, Debug)]
pub struct LayerRow {
    /// As the README's first column spells it, e.g. `P.X, P.Y, P.Z` or `CryptoObject00..`.
    pub channels: &'static str,
    pub status: Status,
}

/// Every row of the map, written and reserved.
pub const LAYERS: &[LayerRow] = &[
    row("R, G, B, A"),
    row("Z"),
    row("ApparentDepth.Z"),
    row("P.X, P.Y, P.Z"),
    row("IndexOB.X"),
    row("CryptoObject00.R, .G, .B, .A"),
    row("WaterMatte.X"),
    row("Direct.R, .G, .B"),
    row("Refraction.R, .G, .B"),
    row("SkyReflection.R, .G, .B"),
    row("FlagConvergence.X"),
    row("FlagBoundary.X"),
    row("FlagPopping.X"),
    row("FlagExtrapolated.X"),
    row("Motion.X, Motion.Y"),
    reserved("Pref.X, Pref.Y, Pref.Z", "14 point 2"),
    reserved("CryptoObject01.R, .G, .B, .A", "16"),
    reserved("SceneReflection.R, .G, .B", "16"),
    reserved("Caustics.R, .G, .B", "16"),
    reserved("Glints.R, .G, .B", "16"),
    reserved("PReflected.X, PReflected.Y, PReflected.Z", "16"),
    reserved("IndexOBReflected.X", "16"),
    reserved("FlagReflConvergence.X", "16"),
    reserved("FlagReflBoundary.X", "16"),
    reserved("FlagNotDrawn.X", "13"),
    reserved("FlagOffscreen.X", "17"),
    reserved("IndexGlass.X", "17, 18"),
    reserved("FlagVessel.X", "18"),
];

const fn row(channels: &'static str) -> LayerRow {
    LayerRow {
        channels,
        status: Status::Written,
    }
}

const fn reserved(channels: &'static str, issue: &'static str) -> LayerRow {
    LayerRow {
        channels,
        status: Status::Reserved(issue),
    }
}

/// The first layout (snell before the channel map), still read by `read_frame_exr`.
pub mod legacy {
    use crate::draw::flag_bits;

    /// `Z` held the distance from the eye (+inf for sky), `P` NaN where nothing was seen.
    pub const FLAG_CHANNELS: [(&str, u32); 4] = [
        ("flags.convergence", flag_bits::CONVERGENCE),
        ("flags.boundary", flag_bits::BOUNDARY),
        ("flags.popping", flag_bits::POPPING),
        ("flags.extrapolated", flag_bits::EXTRAPOLATED),
    ];
    /// u32: the frame's object (material) index + 1, one per glTF primitive.
    pub const OBJECT: &str = "object";
}

/// Blender's rule for a channel it keeps in a multilayer file (`imb_exr_split_channel_name` in
/// `source/blender/imbuf/intern/openexr/openexr_api.cpp`, Blender 3.x): a one-letter name, or a
/// last dot-separated token that is one letter, two letters ending in X Y Z R G B U V A, or one of
/// red, green, blue, alpha, depth (any case).
pub fn blender_keeps(channel: &str) -> bool {
    if channel.len() == 1 {
        return true;
    }
    let Some((_, token)) = channel.rsplit_once('.') else {
        return false;
    };
    match token.len() {
        0 => false,
        1 => true,
        2 => matches!(
            token.as_bytes()[1].to_ascii_uppercase(),
            b'X' | b'Y' | b'Z' | b'R' | b'G' | b'B' | b'U' | b'V' | b'A'
        ),
        _ => ["red", "green", "blue", "alpha", "depth"]
            .iter()
            .any(|name| token.eq_ignore_ascii_case(name)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_channel_names() -> Vec<String> {
        let mut names: Vec<String> = BEAUTY.iter().map(|s| s.to_string()).collect();
        names.push(DEPTH.into());
        names.push(APPARENT_DEPTH.into());
        names.extend(POSITION.iter().map(|s| s.to_string()));
        names.push(INDEX_OB.into());
        names.push(WATER_MATTE.into());
        for layer in [DIRECT, REFRACTION, SKY_REFLECTION] {
            names.extend(layer.iter().map(|s| s.to_string()));
        }
        for (id, coverage) in crypto_rank_channels() {
            names.push(id);
            names.push(coverage);
        }
        names.extend(FLAG_CHANNELS.iter().map(|(name, _)| name.to_string()));
        names.extend(MOTION.iter().map(|s| s.to_string()));
        names
    }

    #[test]
    fn every_written_channel_is_one_blender_keeps_and_none_repeats() {
        let names = all_channel_names();
        for name in &names {
            assert!(blender_keeps(name), "{name}");
            assert!(
                name.chars().all(|c| c.is_ascii_alphanumeric() || c == '.'),
                "{name}: Nuke wants letters, digits and the one dot"
            );
            assert!(name.matches('.').count() <= 1, "{name}");
        }
        let mut sorted = names.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), names.len());
    }

    #[test]
    fn blenders_rule_refuses_what_the_first_layout_wrote() {
        for (name, _) in legacy::FLAG_CHANNELS {
            assert!(!blender_keeps(name), "{name}");
        }
        assert!(!blender_keeps(legacy::OBJECT));
        assert!(blender_keeps("P.X") && blender_keeps("Z") && blender_keeps("diffuse.RX"));
        assert!(blender_keeps("layer.pass.alpha") && !blender_keeps("layer.pass.QQ"));
    }

    #[test]
    fn layers_parse_presets_names_and_their_union() {
        let (all, half) = LayerSet::parse("all").unwrap();
        assert_eq!((all, half), (LayerSet::ALL, false));
        assert!(Layer::ALL.iter().all(|&layer| all.has(layer)));
        let (comp, half) = LayerSet::parse("comp").unwrap();
        assert!(half, "comp stores the beauty as half floats");
        assert_eq!(comp.label(), "comp");
        assert_eq!(
            comp.layers().collect::<Vec<_>>(),
            [
                Layer::Beauty,
                Layer::Depth,
                Layer::IndexOb,
                Layer::CryptoObject,
                Layer::WaterMatte
            ]
        );
        // Any case, spaces around commas; the beauty is always there; union with a preset.
        let (list, half) = LayerSet::parse("p, z,flagPopping").unwrap();
        assert!(!half);
        assert_eq!(list.label(), "beauty,Z,P,FlagPopping");
        let (more, half) = LayerSet::parse("comp,P").unwrap();
        assert!(half && more.has(Layer::Position) && more.has(Layer::CryptoObject));
        assert!(!more.has(Layer::Direct));
        assert_eq!(more.label(), "beauty,Z,P,IndexOB,CryptoObject,WaterMatte");
        assert_eq!(LayerSet::parse("beauty").unwrap().0.label(), "beauty");
    }

    #[test]
    fn an_unknown_layer_is_named_with_every_valid_one() {
        let message = LayerSet::parse("Z,Vector").unwrap_err();
        assert!(message.contains("unknown layer `Vector`"), "{message}");
        for name in ["all", "comp"]
            .into_iter()
            .chain(Layer::ALL.map(Layer::name))
        {
            assert!(message.contains(name), "{name} not in: {message}");
        }
        let message = LayerSet::parse("Z,,P").unwrap_err();
        assert!(message.contains("an empty layer name"), "{message}");
    }

    /// Every layer `--layers` names is a layer of the map's written rows.
    #[test]
    fn every_layer_name_is_a_written_row() {
        for layer in Layer::ALL {
            let name = layer.name();
            let found = LAYERS.iter().any(|row| {
                row.status == Status::Written
                    && match layer {
                        Layer::Beauty => row.channels == "R, G, B, A",
                        Layer::Depth => row.channels == "Z",
                        _ => {
                            row.channels.starts_with(&format!("{name}."))
                                || row.channels.starts_with(&format!("{name}00."))
                        }
                    }
            });
            assert!(found, "{name}");
        }
    }

    #[test]
    fn crypto_ranks_fill_rgba_pairs() {
        assert_eq!(
            crypto_rank_channels(),
            vec![
                (
                    "CryptoObject00.R".to_string(),
                    "CryptoObject00.G".to_string()
                ),
                (
                    "CryptoObject00.B".to_string(),
                    "CryptoObject00.A".to_string()
                ),
            ]
        );
    }

    /// The README's table lists every row of the map, written or reserved, and says which.
    #[test]
    fn the_readme_table_has_every_row() {
        let readme = include_str!("../../../README.md");
        let section = readme
            .split("## The EXR channel map")
            .nth(1)
            .expect("README has a section \"The EXR channel map\"");
        let section = section.split("\n## ").next().unwrap_or(section);
        for row in LAYERS {
            let line = section
                .lines()
                .find(|line| line.starts_with(&format!("| `{}`", row.channels)))
                .unwrap_or_else(|| panic!("README table has no row for `{}`", row.channels));
            match row.status {
                Status::Written => assert!(line.contains("| written |"), "{line}"),
                Status::Reserved(issue) => assert!(
                    line.contains(&format!("| reserved (issue {issue}) |")),
                    "{line}"
                ),
            }
        }
    }
}
