//! The [water] table and its [water.ripples] solver settings.

use super::*;

pub(super) fn water(
    raw: &RawWater,
    has_characters: bool,
    map: &SourceMap<'_>,
) -> Result<WaterSpec> {
    let path = KeyPath::root().key("water");
    let min_xz = raw.min.unwrap_or(DEFAULT_WATER_MIN_XZ);
    let max_xz = raw.max.unwrap_or(DEFAULT_WATER_MAX_XZ);
    if max_xz[0] <= min_xz[0] || max_xz[1] <= min_xz[1] {
        let at = if raw.max.is_some() {
            path.key("max")
        } else {
            path.key("min")
        };
        return Err(map.error(
            &at,
            format!(
                "the water's extent is empty: max {max_xz:?} must exceed min {min_xz:?} in both x and z"
            ),
            "set e.g. min = [-5.0, -2.5] and max = [5.0, 2.5]",
        ));
    }
    let resolution = raw.resolution.unwrap_or(DEFAULT_RESOLUTION);
    for (i, &cells) in resolution.iter().enumerate() {
        in_stated_range(cells as f64, &path.key("resolution").index(i), map)?;
    }
    let n_above = raw.n_above.unwrap_or(DEFAULT_N_ABOVE);
    let n_below = raw.n_below.unwrap_or(DEFAULT_N_BELOW);
    let absorption_per_m = raw.absorption_per_m.unwrap_or(DEFAULT_ABSORPTION_PER_M);
    // Written values were checked against their ranges where they stand; these catch defaults.
    in_stated_range(n_above, &path.key("n_above"), map)?;
    in_stated_range(n_below, &path.key("n_below"), map)?;
    for (i, &a) in absorption_per_m.iter().enumerate() {
        in_stated_range(a, &path.key("absorption_per_m").index(i), map)?;
    }
    let roughness = raw.roughness.unwrap_or(DEFAULT_WATER_ROUGHNESS);
    let scatter = color(
        raw.scatter_color,
        DEFAULT_SCATTER_COLOR,
        &path.key("scatter_color"),
        map,
    )?;

    let mut waves = Vec::new();
    for (i, wave) in raw.wave.iter().flatten().enumerate() {
        let at = path.key("wave").index(i);
        // amplitude_m, wavelength_m and speed_m_per_s are written values, range-checked where
        // they stand (`super::limits`).
        let direction_deg = match (wave.direction_deg, wave.direction) {
            (Some(_), Some(_)) => {
                return Err(map.error(
                    &at.key("direction"),
                    "both direction and direction_deg are given",
                    "keep one of them",
                ))
            }
            (Some(deg), None) => deg,
            (None, Some([x, z])) => {
                if x * x + z * z == 0.0 {
                    return Err(map.error(
                        &at.key("direction"),
                        "a direction cannot be the zero vector",
                        "set e.g. direction = [1.0, 0.5] (x, z)",
                    ));
                }
                z.atan2(x).to_degrees()
            }
            (None, None) => 0.0,
        };
        waves.push(WaveSpec {
            amplitude_m: wave.amplitude_m,
            wavelength_m: wave.wavelength_m,
            direction_deg,
            phase_rad: wave.phase_rad.unwrap_or(0.0),
            speed_m_per_s: wave.speed_m_per_s,
        });
    }

    Ok(WaterSpec {
        level_m: raw.level_m.unwrap_or(0.0),
        min_xz,
        max_xz,
        resolution: [resolution[0] as u32, resolution[1] as u32],
        n_above,
        n_below,
        absorption_per_m,
        scatter_color_linear: srgb_to_linear3(scatter),
        roughness,
        waves,
        ripples: ripples(
            raw.ripples.as_ref(),
            has_characters,
            (min_xz, max_xz),
            [resolution[0], resolution[1]],
            map,
        )?,
    })
}

/// Ripples are on when the scene has characters to make them, unless `enabled = false`.
/// `membrane_cells` is `[water] resolution`: the default ripple grid has
/// [`DEFAULT_RIPPLE_NODES_PER_CELL`] nodes per membrane cell.
pub(super) fn ripples(
    raw: Option<&RawRipples>,
    has_characters: bool,
    (min_xz, max_xz): ([f64; 2], [f64; 2]),
    membrane_cells: [i64; 2],
    map: &SourceMap<'_>,
) -> Result<RippleSpec> {
    let path = KeyPath::root().key("water").key("ripples");
    let default = RawRipples::default();
    let raw = raw.unwrap_or(&default);
    if raw.speed_m_per_s.is_some() {
        return Err(map.error(
            &path.key("speed_m_per_s"),
            "ripples no longer have one speed: they are water waves, each wavelength travelling at \
             the speed water's dispersion relation gives it over the pool's depth",
            "remove speed_m_per_s; long waves travel at sqrt(9.81 * depth), so a shallower pool \
             (the pool's depth_m, or [water.ripples] depth_m) makes them slower",
        ));
    }
    let (width_m, depth_m) = (max_xz[0] - min_xz[0], max_xz[1] - min_xz[1]);
    // Square cells, DEFAULT_RIPPLE_NODES_PER_CELL per membrane cell along the finer axis.
    let spacing_m = (width_m / membrane_cells[0] as f64).min(depth_m / membrane_cells[1] as f64)
        / DEFAULT_RIPPLE_NODES_PER_CELL as f64;
    let default_nodes = [
        ((width_m / spacing_m).round() as i64 + 1).min(MAX_RIPPLE_NODES),
        ((depth_m / spacing_m).round() as i64 + 1).min(MAX_RIPPLE_NODES),
    ];
    let nodes = raw.resolution.unwrap_or(default_nodes);
    for (i, &n) in nodes.iter().enumerate() {
        in_stated_range(n as f64, &path.key("resolution").index(i), map)?;
    }
    let spacing = [
        width_m / (nodes[0] - 1) as f64,
        depth_m / (nodes[1] - 1) as f64,
    ];
    if (spacing[0] - spacing[1]).abs() > 0.01 * spacing[0].max(spacing[1]) {
        return Err(map.error(
            &path.key("resolution"),
            format!(
                "ripple cells must be square: these nodes make cells of {:.4} m along x and {:.4} m along z",
                spacing[0], spacing[1]
            ),
            format!(
                "choose nodes in the water's proportions, e.g. resolution = [{}, {}]",
                default_nodes[0], default_nodes[1]
            ),
        ));
    }
    // Their ranges are checked where they are written (`super::limits`).
    let water_depth_m = raw.depth_m;
    let surface_tension_n_per_m = raw
        .surface_tension_n_per_m
        .unwrap_or(crate::sim::ripples::WATER_SURFACE_TENSION_N_PER_M);
    let density_kg_per_m3 = raw
        .density_kg_per_m3
        .unwrap_or(crate::sim::ripples::WATER_DENSITY_KG_PER_M3);
    let damping_per_s = raw.damping_per_s.unwrap_or(DEFAULT_RIPPLE_DAMPING_PER_S);
    let border = match raw.border.as_deref().unwrap_or("reflect") {
        "reflect" => crate::sim::Border::Reflect,
        "absorb" => crate::sim::Border::Absorb,
        other => {
            return Err(map.error(
                &path.key("border"),
                format!("unknown border {other:?}"),
                "use \"reflect\" (walls) or \"absorb\" (open water)",
            ))
        }
    };
    let sponge_width_m = raw.sponge_width_m.unwrap_or(DEFAULT_SPONGE_WIDTH_M);
    let strength = raw.strength.unwrap_or(1.0);
    let coupling_depth_m = raw.coupling_depth_m.unwrap_or(DEFAULT_COUPLING_DEPTH_M);
    // Written values were checked against their ranges where they stand; these catch defaults.
    for (key, value) in [
        ("damping_per_s", damping_per_s),
        ("sponge_width_m", sponge_width_m),
        ("strength", strength),
        ("coupling_depth_m", coupling_depth_m),
    ] {
        in_stated_range(value, &path.key(key), map)?;
    }
    Ok(RippleSpec {
        enabled: raw.enabled.unwrap_or(has_characters),
        nodes: [nodes[0] as u32, nodes[1] as u32],
        depth_m: water_depth_m,
        surface_tension_n_per_m,
        density_kg_per_m3,
        damping_per_s,
        border,
        sponge_width_m,
        strength,
        coupling_depth_m,
    })
}
