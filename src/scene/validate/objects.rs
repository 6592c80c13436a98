//! Objects and their textures: the default pool and its tiles, each [[object]] and its texture.

use super::*;

pub(super) fn default_pool(max_edge_m: f64) -> ObjectSpec {
    ObjectSpec {
        name: "pool".into(),
        shape: ShapeSpec::Pool {
            depth_m: 1.6,
            coping_height_m: 0.25,
            deck_width_m: 3.0,
            floor_texture: default_floor_tiles(),
            deck_texture: default_deck_stone(),
        },
        translate_m: [0.0; 3],
        rotate_deg: [0.0; 3],
        scale: [1.0; 3],
        max_edge_m,
        texture: default_wall_tiles(),
        tint_srgb: [1.0; 3],
    }
}

/// White glazed tiles with some pale-blue ones among them, light-grey grout.
pub(super) fn default_wall_tiles() -> TextureSpec {
    TextureSpec::Tiles(TilesSpec {
        color_srgb: [0.93, 0.96, 0.98],
        grout_color_srgb: [0.62, 0.66, 0.68],
        tile_size_m: 0.125,
        grout_width_m: 0.004,
        variation: 0.04,
        accent_color_srgb: [0.72, 0.87, 0.96],
        accent_fraction: 0.15,
        lanes: None,
        seed: 1,
    })
}

/// The wall tiles with dark-blue lane stripes every 2.5 m.
pub(super) fn default_floor_tiles() -> TextureSpec {
    let TextureSpec::Tiles(mut tiles) = default_wall_tiles() else {
        unreachable!("wall tiles are tiles")
    };
    tiles.lanes = Some(LaneSpec {
        spacing_m: 2.5,
        width_m: 0.25,
        color_srgb: [0.04, 0.10, 0.32],
    });
    tiles.seed = 2;
    TextureSpec::Tiles(tiles)
}

/// Large sandstone-coloured slabs.
pub(super) fn default_deck_stone() -> TextureSpec {
    TextureSpec::Tiles(TilesSpec {
        color_srgb: [0.80, 0.76, 0.68],
        grout_color_srgb: [0.58, 0.55, 0.50],
        tile_size_m: 0.5,
        grout_width_m: 0.008,
        variation: 0.10,
        accent_color_srgb: [0.74, 0.70, 0.62],
        accent_fraction: 0.3,
        lanes: None,
        seed: 3,
    })
}

pub(super) fn object(
    raw: &RawObject,
    at: &KeyPath,
    index: usize,
    scene_max_edge_m: f64,
    water: &WaterSpec,
    map: &SourceMap<'_>,
) -> Result<ObjectSpec> {
    let shape_name = raw.shape.as_str();
    if !SHAPES.contains(&shape_name) {
        return Err(map.error(
            &at.key("shape"),
            format!("unknown shape {shape_name:?}"),
            format!("use one of {}", quoted_list(&SHAPES)),
        ));
    }
    let shape_keys: &[&str] = match shape_name {
        "box" | "quad" => &["size_m"],
        "sphere" => &["radius_m"],
        _ => &[
            "depth_m",
            "coping_height_m",
            "deck_width_m",
            "floor_texture",
            "deck_texture",
        ],
    };
    for (key, span) in map.keys_in(at) {
        let allowed =
            COMMON_OBJECT_KEYS.contains(&key.as_str()) || shape_keys.contains(&key.as_str());
        let moves_pool =
            shape_name == "pool" && ["translate", "rotate_deg", "scale"].contains(&key.as_str());
        if !allowed || moves_pool {
            let fix = if moves_pool {
                "remove it: the pool follows the water's extent (move water.min and water.max instead)".to_owned()
            } else {
                format!(
                    "remove it; a {shape_name} takes {}",
                    quoted_list(shape_keys)
                )
            };
            return Err(map.error_at(
                span.start,
                at.key(&key).to_string(),
                format!("{key} does not apply to shape = {shape_name:?}"),
                fix,
            ));
        }
    }

    let max_edge_m = match raw.max_edge_m {
        Some(v) => max_edge(v, &at.key("max_edge_m"), map)?,
        None => scene_max_edge_m,
    };
    let size = |count: usize, default: &[f64], example: &str| -> Result<Vec<f64>> {
        let size = raw.size_m.clone().unwrap_or_else(|| default.to_vec());
        if size.len() != count || size.iter().any(|&s| s <= 0.0) {
            return Err(map.error(
                &at.key("size_m"),
                format!("a {shape_name} needs {count} positive sizes in metres (got {size:?})"),
                format!("set e.g. size_m = {example}"),
            ));
        }
        Ok(size)
    };
    let shape = match shape_name {
        "box" => {
            let s = size(3, &[1.0, 1.0, 1.0], "[1.0, 0.5, 0.8]")?;
            ShapeSpec::Box {
                size_m: [s[0], s[1], s[2]],
            }
        }
        "quad" => {
            let s = size(2, &[1.0, 1.0], "[2.0, 1.0]")?;
            ShapeSpec::Quad {
                size_m: [s[0], s[1]],
            }
        }
        "sphere" => {
            let radius_m = raw.radius_m.unwrap_or(0.5);
            positive(radius_m, &at.key("radius_m"), "radius_m = 0.3", map)?;
            ShapeSpec::Sphere { radius_m }
        }
        _ => {
            let depth_m = raw.depth_m.unwrap_or(1.6);
            positive(depth_m, &at.key("depth_m"), "depth_m = 1.6", map)?;
            let coping_height_m = raw.coping_height_m.unwrap_or(0.25);
            if coping_height_m <= water.max_crest_m() {
                return Err(map.error(
                    &at.key("coping_height_m"),
                    format!(
                        "the deck must stand above the highest wave crest ({} m above the level; got {coping_height_m} m)",
                        water.max_crest_m()
                    ),
                    "raise it, e.g. coping_height_m = 0.25, or lower the waves' amplitudes",
                ));
            }
            let deck_width_m = raw.deck_width_m.unwrap_or(3.0);
            positive(
                deck_width_m,
                &at.key("deck_width_m"),
                "deck_width_m = 3.0",
                map,
            )?;
            let floor_texture = texture(
                raw.floor_texture.as_ref(),
                default_floor_tiles(),
                &at.key("floor_texture"),
                map,
            )?;
            let deck_texture = texture(
                raw.deck_texture.as_ref(),
                default_deck_stone(),
                &at.key("deck_texture"),
                map,
            )?;
            ShapeSpec::Pool {
                depth_m,
                coping_height_m,
                deck_width_m,
                floor_texture,
                deck_texture,
            }
        }
    };
    let default_texture = match shape {
        ShapeSpec::Pool { .. } => default_wall_tiles(),
        _ => TextureSpec::Solid {
            color_srgb: [0.8, 0.8, 0.8],
        },
    };
    let texture = texture(
        raw.texture.as_ref(),
        default_texture,
        &at.key("texture"),
        map,
    )?;
    let scale = raw.scale.unwrap_or([1.0; 3]);
    if scale.iter().any(|&s| s <= 0.0) {
        return Err(map.error(
            &at.key("scale"),
            format!("scale factors must be positive (got {scale:?}); a mirror would turn the mesh inside out"),
            "set e.g. scale = [1.0, 1.0, 1.0]",
        ));
    }
    Ok(ObjectSpec {
        name: raw
            .name
            .clone()
            .unwrap_or_else(|| format!("{shape_name}{index}")),
        shape,
        translate_m: raw.translate.unwrap_or([0.0; 3]),
        rotate_deg: raw.rotate_deg.unwrap_or([0.0; 3]),
        scale,
        max_edge_m,
        texture,
        tint_srgb: color(raw.tint, [1.0; 3], &at.key("tint"), map)?,
    })
}

/// A texture table: its kind is stated, implied by `image`, or the slot's default kind; keys it does
/// not state take the default's values when the kinds agree.
pub(super) fn texture(
    raw: Option<&RawTexture>,
    default: TextureSpec,
    at: &KeyPath,
    map: &SourceMap<'_>,
) -> Result<TextureSpec> {
    let Some(raw) = raw else { return Ok(default) };
    let kind = match (&raw.kind, &raw.image) {
        (Some(kind), _) => kind.as_str(),
        (None, Some(_)) => "image",
        (None, None) => match default {
            TextureSpec::Solid { .. } => "solid",
            TextureSpec::Checker { .. } => "checker",
            TextureSpec::Tiles(_) => "tiles",
            TextureSpec::Image(_) => "image",
        },
    };
    if !TEXTURE_KINDS.contains(&kind) {
        return Err(map.error(
            &at.key("kind"),
            format!("unknown texture kind {kind:?}"),
            format!("use one of {}", quoted_list(&TEXTURE_KINDS)),
        ));
    }
    let kind_keys: &[&str] = match kind {
        "solid" => &["color"],
        "checker" => &["color", "color_b", "square_m"],
        "tiles" => &[
            "color",
            "grout_color",
            "tile_size_m",
            "grout_width_m",
            "variation",
            "accent_color",
            "accent_fraction",
            "lane_spacing_m",
            "lane_width_m",
            "lane_color",
            "seed",
        ],
        _ => &["image", "size_m"],
    };
    for (key, span) in map.keys_in(at) {
        if key != "kind" && !kind_keys.contains(&key.as_str()) {
            return Err(map.error_at(
                span.start,
                at.key(&key).to_string(),
                format!("{key} does not apply to a {kind} texture"),
                format!(
                    "remove it; a {kind} texture takes {}",
                    quoted_list(kind_keys)
                ),
            ));
        }
    }
    let color_at = |key: &str, value: Option<[f64; 3]>, fallback: [f64; 3]| {
        color(value, fallback, &at.key(key), map)
    };
    match kind {
        "solid" => {
            let fallback = match default {
                TextureSpec::Solid { color_srgb } => color_srgb,
                _ => [0.8, 0.8, 0.8],
            };
            Ok(TextureSpec::Solid {
                color_srgb: color_at("color", raw.color, fallback)?,
            })
        }
        "checker" => {
            let square_m = raw.square_m.unwrap_or(0.5);
            positive(square_m, &at.key("square_m"), "square_m = 0.5", map)?;
            Ok(TextureSpec::Checker {
                color_srgb: color_at("color", raw.color, [0.9, 0.9, 0.9])?,
                color_b_srgb: color_at("color_b", raw.color_b, [0.15, 0.15, 0.15])?,
                square_m,
            })
        }
        "tiles" => {
            let base = match default {
                TextureSpec::Tiles(tiles) => tiles,
                _ => match default_wall_tiles() {
                    TextureSpec::Tiles(tiles) => tiles,
                    _ => unreachable!("wall tiles are tiles"),
                },
            };
            let tile_size_m = raw.tile_size_m.unwrap_or(base.tile_size_m);
            positive(
                tile_size_m,
                &at.key("tile_size_m"),
                "tile_size_m = 0.125",
                map,
            )?;
            let grout_width_m = raw.grout_width_m.unwrap_or(base.grout_width_m);
            if !(0.0..tile_size_m).contains(&grout_width_m) {
                return Err(map.error(
                    &at.key("grout_width_m"),
                    format!("must be at least 0 and less than the tile size {tile_size_m} m (got {grout_width_m})"),
                    "set e.g. grout_width_m = 0.004",
                ));
            }
            let variation = raw.variation.unwrap_or(base.variation);
            let accent_fraction = raw.accent_fraction.unwrap_or(base.accent_fraction);
            for (key, value) in [
                ("variation", variation),
                ("accent_fraction", accent_fraction),
            ] {
                if !(0.0..=1.0).contains(&value) {
                    return Err(map.error(
                        &at.key(key),
                        format!("must be between 0 and 1 (got {value})"),
                        format!("set e.g. {key} = 0.1"),
                    ));
                }
            }
            let base_lanes = base.lanes.clone();
            let lanes = match raw
                .lane_spacing_m
                .or(base_lanes.as_ref().map(|l| l.spacing_m))
            {
                // lane_spacing_m = 0 turns a default's lanes off.
                None => None,
                Some(spacing) if spacing == 0.0 && raw.lane_spacing_m.is_some() => None,
                Some(spacing_m) => {
                    if spacing_m < tile_size_m {
                        return Err(map.error(
                            &at.key("lane_spacing_m"),
                            format!("lanes must be at least a tile apart (got {spacing_m} m for {tile_size_m} m tiles)"),
                            "set e.g. lane_spacing_m = 2.5, or 0 for no lanes",
                        ));
                    }
                    let width_m = raw
                        .lane_width_m
                        .or(base_lanes.as_ref().map(|l| l.width_m))
                        .unwrap_or(0.25);
                    if !(width_m > 0.0 && width_m < spacing_m) {
                        return Err(map.error(
                            &at.key("lane_width_m"),
                            format!("must be positive and less than the lane spacing {spacing_m} m (got {width_m})"),
                            "set e.g. lane_width_m = 0.25",
                        ));
                    }
                    let fallback = base_lanes
                        .as_ref()
                        .map_or([0.04, 0.10, 0.32], |l| l.color_srgb);
                    Some(LaneSpec {
                        spacing_m,
                        width_m,
                        color_srgb: color_at("lane_color", raw.lane_color, fallback)?,
                    })
                }
            };
            Ok(TextureSpec::Tiles(TilesSpec {
                color_srgb: color_at("color", raw.color, base.color_srgb)?,
                grout_color_srgb: color_at("grout_color", raw.grout_color, base.grout_color_srgb)?,
                tile_size_m,
                grout_width_m,
                variation,
                accent_color_srgb: color_at(
                    "accent_color",
                    raw.accent_color,
                    base.accent_color_srgb,
                )?,
                accent_fraction,
                lanes,
                seed: raw.seed.unwrap_or(base.seed),
            }))
        }
        _ => {
            let image_at = at.key("image");
            let Some(written) = &raw.image else {
                return Err(map.error(
                    at,
                    "an image texture needs a file",
                    "add image = \"textures/tiles.png\"",
                ));
            };
            let folder = map.file.parent().unwrap_or(Path::new(""));
            let path = folder.join(written);
            if let Err(error) = crate::files::check_regular(&path, crate::files::MAX_ASSET_BYTES) {
                let problem = match error {
                    crate::files::InputFileError::NotFound(_) => format!(
                        "texture image {written:?} not found (looked for {})",
                        path.display()
                    ),
                    other => format!("cannot use texture image {written:?}: {other}"),
                };
                return Err(map.error(
                    &image_at,
                    problem,
                    "check the path, which is relative to the scene file's folder, and name a PNG or JPEG file",
                ));
            }
            let size_m = raw.size_m.unwrap_or([1.0, 1.0]);
            if size_m.iter().any(|&s| s <= 0.0) {
                return Err(map.error(
                    &at.key("size_m"),
                    format!(
                        "the metres one copy of the image covers must be positive (got {size_m:?})"
                    ),
                    "set e.g. size_m = [1.0, 1.0]",
                ));
            }
            Ok(TextureSpec::Image(ImageSpec {
                path,
                size_m,
                source: map.source_ref(&image_at),
            }))
        }
    }
}
