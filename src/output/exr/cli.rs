//! The EXR options of `snell render` (flattened into its arguments), kept here so the channel
//! map's options live beside the map.

use super::channels::LayerSet;
use super::{ExrCompression, WriteOptions};
use crate::frame::{HeaderStamp, SnellError};

/// What the written EXR frames hold besides the pixels.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ExrArgs {
    /// Write the OpenEXR `owner` attribute. With SOURCE_DATE_EPOCH set (a Unix time, as for
    /// reproducible builds) frames also get `capDate` (that time, UTC) and `utcOffset` 0.
    /// Neither is written by default, so the same render gives the same bytes every time.
    #[arg(long, value_name = "NAME")]
    pub owner: Option<String>,
    /// Store the beauty (R, G, B, A) as half floats, the VFX default: half the beauty's bytes.
    /// Z, P, IDs and the other layers stay float32 (half P would step 4 mm at 4 m).
    #[arg(long)]
    pub half: bool,
    /// The frames' compression, lossless all (README "What a render gives you" measures each):
    /// zip (the default) and zips are deflate over 16 lines and over one; piz wavelets; rle
    /// run-length; none. The header's `compression` and `snell.output` say which was used.
    #[arg(long, value_enum, value_name = "KIND", default_value_t = ExrCompression::Zip)]
    pub compression: ExrCompression,
    /// Which layers of the channel map (README "The EXR channel map") to write, comma-separated:
    /// the presets `all` (every layer, the default) and `comp` (the beauty as half floats, `Z`,
    /// `IndexOB`, `CryptoObject` and `WaterMatte`), and layer names (any case): beauty, Z,
    /// ApparentDepth, P, IndexOB, CryptoObject, WaterMatte, Direct, Refraction, SkyReflection,
    /// FlagConvergence, FlagBoundary, FlagPopping, FlagExtrapolated. The beauty is always
    /// written. E.g. `--layers comp,P`. The header's `snell.output` says what was chosen;
    /// `snell compare` needs P, IndexOB and the flags, `snell diff` compares Z and P only where
    /// both frames have them.
    #[arg(long, value_name = "LIST", value_parser = parse_layers)]
    pub layers: Option<LayerChoice>,
}

/// `--layers` as given: the set and whether `comp` (half beauty) was among the words, and the
/// words for the resume command.
#[derive(Clone, Debug)]
pub struct LayerChoice {
    pub set: LayerSet,
    pub comp: bool,
    pub text: String,
}

fn parse_layers(text: &str) -> Result<LayerChoice, String> {
    let (set, comp) = LayerSet::parse(text)?;
    Ok(LayerChoice {
        set,
        comp,
        text: text.to_string(),
    })
}

impl ExrArgs {
    /// The header stamp these options and `SOURCE_DATE_EPOCH` ask for.
    pub fn stamp(&self) -> Result<HeaderStamp, SnellError> {
        stamp_from(self.owner.clone(), std::env::var("SOURCE_DATE_EPOCH").ok())
    }

    /// How the frames are stored.
    pub fn write_options(&self) -> WriteOptions {
        let layers = self.layers.as_ref();
        WriteOptions {
            half_beauty: self.half || layers.is_some_and(|choice| choice.comp),
            compression: self.compression,
            layers: layers.map_or(LayerSet::ALL, |choice| choice.set),
        }
    }

    /// The command-line words that give these options again (for the resume command).
    pub fn command_words(&self) -> Vec<String> {
        let mut words = Vec::new();
        if let Some(owner) = &self.owner {
            words.extend(["--owner".to_string(), owner.clone()]);
        }
        if self.half {
            words.push("--half".into());
        }
        if self.compression != ExrCompression::default() {
            words.extend(["--compression".to_string(), self.compression.name().into()]);
        }
        if let Some(choice) = &self.layers {
            words.extend(["--layers".to_string(), choice.text.clone()]);
        }
        words
    }
}

fn stamp_from(owner: Option<String>, epoch: Option<String>) -> Result<HeaderStamp, SnellError> {
    if let Some(owner) = &owner {
        if owner.is_empty() || owner.contains('\0') {
            return Err(SnellError::Argument(
                "--owner: give a non-empty name without NUL characters, e.g. --owner \"Studio\""
                    .into(),
            ));
        }
    }
    let capture_unix_secs = match epoch.as_deref().map(str::trim) {
        None | Some("") => None,
        Some(text) => Some(text.parse::<i64>().ok().filter(|s| (0..=253_402_300_799).contains(s)).ok_or_else(
            || {
                SnellError::Argument(format!(
                    "SOURCE_DATE_EPOCH={text:?}: expected a Unix time in seconds (0 to 253402300799), e.g. 1700000000, or unset it"
                ))
            },
        )?),
    };
    Ok(HeaderStamp {
        owner,
        capture_unix_secs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_come_only_from_what_was_given() {
        assert_eq!(stamp_from(None, None).unwrap(), HeaderStamp::default());
        let stamp = stamp_from(Some("Studio".into()), Some("1700000000".into())).unwrap();
        assert_eq!(stamp.owner.as_deref(), Some("Studio"));
        assert_eq!(stamp.capture_unix_secs, Some(1_700_000_000));
        let message = stamp_from(None, Some("yesterday".into()))
            .unwrap_err()
            .to_string();
        assert!(message.contains("SOURCE_DATE_EPOCH"), "{message}");
        assert!(stamp_from(Some(String::new()), None).is_err());
    }
}
