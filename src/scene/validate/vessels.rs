//! `[[vessel]]` tables: glass panes and cylinders (issue 18, [`crate::vessel`]), each problem at
//! its key. Numbers were range-checked where they stand (`super::limits`); this checks what the
//! ranges cannot: the kind, the keys that belong to it, the required ones, directions that are
//! not zero or parallel, and a wall thicker than nothing.

use glam::DVec3;

use super::*;
use crate::scene::format::RawVessel;
use crate::scene::VesselSpec;
use crate::vessel::{Cylinder, Medium, Pane, Vessel};

const KINDS: [&str; 2] = ["pane", "cylinder"];
const COMMON_KEYS: [&str; 4] = ["name", "kind", "glass_index", "inside"];
const PANE_KEYS: [&str; 5] = ["position", "normal", "up", "size_m", "thickness_m"];
const CYLINDER_KEYS: [&str; 5] = [
    "base",
    "axis",
    "inner_radius_m",
    "outer_radius_m",
    "height_m",
];
/// Window glass.
const DEFAULT_GLASS_INDEX: f64 = 1.5;
/// A pane of window glass, 1 cm.
const DEFAULT_THICKNESS_M: f64 = 0.01;

pub(super) fn vessel(
    raw: &RawVessel,
    at: &KeyPath,
    index: usize,
    map: &SourceMap<'_>,
) -> Result<VesselSpec> {
    let Some(kind) = raw.kind.as_deref() else {
        return Err(map.error(
            at,
            "a vessel needs a kind",
            format!(
                "add kind = \"pane\" or kind = \"cylinder\" ({})",
                quoted_list(&KINDS)
            ),
        ));
    };
    let kind_keys: &[&str] = match kind {
        "pane" => &PANE_KEYS,
        "cylinder" => &CYLINDER_KEYS,
        other => {
            return Err(map.error(
                &at.key("kind"),
                format!("unknown vessel kind {other:?}"),
                format!("use one of {}", quoted_list(&KINDS)),
            ))
        }
    };
    for (key, span) in map.keys_in(at) {
        if !COMMON_KEYS.contains(&key.as_str()) && !kind_keys.contains(&key.as_str()) {
            return Err(map.error_at(
                span.start,
                at.key(&key).to_string(),
                format!("{key} does not apply to kind = {kind:?}"),
                format!("remove it; a {kind} takes {}", quoted_list(kind_keys)),
            ));
        }
    }
    let glass_index = raw.glass_index.unwrap_or(DEFAULT_GLASS_INDEX);
    let inside = match raw.inside.as_deref().unwrap_or("air") {
        "air" => Medium::Air,
        "water" => Medium::Water,
        other => {
            return Err(map.error(
                &at.key("inside"),
                format!("unknown medium {other:?} inside the vessel"),
                "use \"air\" or \"water\"",
            ))
        }
    };
    let required = |value: Option<[f64; 3]>, key: &str, example: &str| {
        value.map(DVec3::from).ok_or_else(|| {
            map.error(
                at,
                format!("a {kind} needs {key}"),
                format!("add e.g. {key} = {example}"),
            )
        })
    };
    let direction = |value: DVec3, key: &str, example: &str| {
        if value.length() > 0.0 {
            Ok(value.normalize())
        } else {
            Err(map.error(
                &at.key(key),
                format!("{key} cannot be the zero vector"),
                format!("set e.g. {key} = {example}"),
            ))
        }
    };
    let vessel = if kind == "pane" {
        let center = required(raw.position, "position", "[0.0, 0.3, 1.0]")?;
        let normal = direction(
            required(raw.normal, "normal", "[0.0, 0.0, 1.0]")?,
            "normal",
            "[0.0, 0.0, 1.0]",
        )?;
        let up = direction(
            raw.up.map_or(DVec3::Y, DVec3::from),
            "up",
            "[0.0, 1.0, 0.0]",
        )?;
        let in_plane = up - up.dot(normal) * normal;
        if in_plane.length() < 1e-6 {
            let (key, fix) = if raw.up.is_some() {
                ("up", "give an up direction that is not along the normal")
            } else {
                (
                    "normal",
                    "the pane lies flat: add up = [0.0, 0.0, 1.0] (the direction its size_m's height runs)",
                )
            };
            return Err(map.error(
                &at.key(key),
                "the pane's up direction is along its normal, so its height has no direction",
                fix,
            ));
        }
        let Some([width, height]) = raw.size_m else {
            return Err(map.error(
                at,
                "a pane needs size_m",
                "add e.g. size_m = [1.2, 0.6] (width, height)",
            ));
        };
        let height_axis = in_plane.normalize();
        Vessel::Pane(Pane {
            center,
            normal,
            u_axis: height_axis.cross(normal),
            half_size_m: [0.5 * width, 0.5 * height],
            thickness_m: raw.thickness_m.unwrap_or(DEFAULT_THICKNESS_M),
            glass_index,
            inside,
        })
    } else {
        let base = required(raw.base, "base", "[0.0, 0.0, 0.0]")?;
        let axis = direction(
            raw.axis.map_or(DVec3::Y, DVec3::from),
            "axis",
            "[0.0, 1.0, 0.0]",
        )?;
        let number = |value: Option<f64>, key: &str, example: &str| {
            value.ok_or_else(|| {
                map.error(
                    at,
                    format!("a cylinder needs {key}"),
                    format!("add e.g. {key} = {example}"),
                )
            })
        };
        let inner_radius_m = number(raw.inner_radius_m, "inner_radius_m", "0.036")?;
        let outer_radius_m = number(raw.outer_radius_m, "outer_radius_m", "0.04")?;
        let height_m = number(raw.height_m, "height_m", "0.12")?;
        if inner_radius_m >= outer_radius_m {
            return Err(map.error(
                &at.key("inner_radius_m"),
                format!(
                    "the wall has no thickness: inner_radius_m {inner_radius_m} must be less than outer_radius_m {outer_radius_m}"
                ),
                "set e.g. inner_radius_m = 0.036 and outer_radius_m = 0.04",
            ));
        }
        Vessel::Cylinder(Cylinder {
            base,
            axis,
            inner_radius_m,
            outer_radius_m,
            height_m,
            glass_index,
            inside,
        })
    };
    Ok(VesselSpec {
        name: raw.name.clone().unwrap_or_else(|| format!("{kind}{index}")),
        vessel,
    })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::DVec3;

    use crate::scene::Scene;
    use crate::vessel::{Medium, Vessel};

    #[test]
    fn a_pane_and_a_glass_of_water_as_written() {
        let text = "[[vessel]]\nkind = \"pane\"\nname = \"front\"\nposition = [0.0, 0.3, 1.0]\n\
                    normal = [0.0, 0.0, 2.0]\nsize_m = [1.2, 0.6]\ninside = \"water\"\n\
                    [[vessel]]\nkind = \"cylinder\"\nbase = [0.5, -0.2, 0.0]\ninner_radius_m = 0.036\n\
                    outer_radius_m = 0.04\nheight_m = 0.12\nglass_index = 1.52\n";
        let scene = Scene::parse(text, Path::new("scenes/vessels.toml")).unwrap();
        assert_eq!(scene.vessels.len(), 2);
        assert_eq!(scene.vessels[0].name, "front");
        assert_eq!(scene.vessels[1].name, "cylinder1");
        let Vessel::Pane(pane) = scene.vessels[0].vessel else {
            panic!("not a pane: {:?}", scene.vessels[0]);
        };
        assert_eq!(pane.normal, DVec3::Z);
        assert_eq!(pane.half_size_m, [0.6, 0.3]);
        // The height runs up (the default `up`), the width across it.
        assert_eq!(pane.w_axis(), DVec3::Y);
        assert_eq!(pane.thickness_m, 0.01);
        assert_eq!((pane.glass_index, pane.inside), (1.5, Medium::Water));
        let Vessel::Cylinder(glass) = scene.vessels[1].vessel else {
            panic!("not a cylinder: {:?}", scene.vessels[1]);
        };
        assert_eq!(glass.axis, DVec3::Y);
        assert_eq!(glass.base, DVec3::new(0.5, -0.2, 0.0));
        assert_eq!(
            (glass.inner_radius_m, glass.outer_radius_m, glass.height_m),
            (0.036, 0.04, 0.12)
        );
        assert_eq!((glass.glass_index, glass.inside), (1.52, Medium::Air));
        assert!(Scene::parse("", Path::new("scenes/empty.toml"))
            .unwrap()
            .vessels
            .is_empty());
    }
}
