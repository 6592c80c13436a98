//! The preview's views of a frame's layers: any layer of the EXR channel map (the README's table)
//! as an image, the difference of a layer between two sources, and every channel's value at one
//! pixel for the inspector. Channel values come from [`crate::output::exr::channel_values`], the
//! mapping the EXR writer itself uses, so what the page shows is what a written frame holds.

use image::RgbaImage;

use super::CachedFrame;
use crate::output::exr::channels::{Layer, SKY_DEPTH_M};
use crate::output::tonemap::display_srgb8;

/// How a layer is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Look {
    /// Linear colour, tone-mapped as the beauty is (exposure applies).
    Colour,
    /// A depth in metres: near bright, far dark over the frame's range; sky black.
    Depth,
    /// Each channel over its own range across the frame, as R, G, B.
    Vector,
    /// Integer indices, each a colour of its own; 0 black.
    Index,
    /// Cryptomatte rank 0: its ID's colour times its coverage.
    Crypto,
    /// A 0-1 mask as grey.
    Mask,
}

fn look(layer: Layer) -> Look {
    match layer {
        Layer::Beauty | Layer::Direct | Layer::Refraction | Layer::SkyReflection => Look::Colour,
        Layer::Depth | Layer::ApparentDepth => Look::Depth,
        Layer::Position | Layer::Motion => Look::Vector,
        Layer::IndexOb => Look::Index,
        Layer::CryptoObject => Look::Crypto,
        Layer::WaterMatte
        | Layer::FlagConvergence
        | Layer::FlagBoundary
        | Layer::FlagPopping
        | Layer::FlagExtrapolated => Look::Mask,
    }
}

/// What the page's layer menu says about a layer.
pub(super) fn describe(layer: Layer) -> &'static str {
    match look(layer) {
        Look::Colour => "linear colour, tone-mapped at the exposure",
        Look::Depth => "metres: near bright, far dark over this frame's range, sky black",
        Look::Vector => "each channel over this frame's range as red, green, blue",
        Look::Index => "one colour per object index, 0 (nothing) black",
        Look::Crypto => "rank 0: a colour per Cryptomatte ID times its coverage",
        Look::Mask => "0 black, 1 white",
    }
}

/// Whether `channel` (an EXR channel name) belongs to `layer`.
pub(super) fn in_layer(layer: Layer, channel: &str) -> bool {
    match layer {
        Layer::Beauty => matches!(channel, "R" | "G" | "B" | "A"),
        Layer::Depth => channel == "Z",
        Layer::CryptoObject => channel.starts_with("CryptoObject"),
        _ => channel
            .strip_prefix(layer.name())
            .is_some_and(|rest| rest.starts_with('.')),
    }
}

/// The layer `--layers` names `name` (`beauty`, `Z`, `P`, `IndexOB`, ...).
pub(super) fn layer_named(name: &str) -> Option<Layer> {
    Layer::ALL.into_iter().find(|layer| layer.name() == name)
}

/// Every channel of `layer` over the whole frame (empty when the frame lacks the layer).
fn layer_channels(frame: &CachedFrame, layer: Layer) -> Vec<(String, Vec<f32>)> {
    if let Some(file) = &frame.file_channels {
        return file
            .iter()
            .filter(|(name, _)| in_layer(layer, name))
            .cloned()
            .collect();
    }
    let rendered = &frame.rendered;
    crate::output::exr::channel_values(
        rendered,
        &frame.object_names,
        &frame.write,
        0..rendered.height as usize,
        |name| in_layer(layer, name),
    )
}

/// A colour of its own for an integer (or a float's bits), bright enough to see on black.
fn index_colour(value: u32) -> [u8; 3] {
    let mut h = value.wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    [
        (h & 0xff) as u8 | 0x40,
        ((h >> 8) & 0xff) as u8 | 0x40,
        ((h >> 16) & 0xff) as u8 | 0x40,
    ]
}

/// The range of `values` (finite ones below the sky's depth); (0, 0) when there are none.
fn range(values: impl Iterator<Item = f32>) -> (f32, f32) {
    let (mut low, mut high) = (f32::INFINITY, f32::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && *v < SKY_DEPTH_M * 0.5) {
        low = low.min(v);
        high = high.max(v);
    }
    if low > high {
        (0.0, 0.0)
    } else {
        (low, high)
    }
}

fn unit(v: f32, (low, high): (f32, f32)) -> f32 {
    if high > low {
        ((v - low) / (high - low)).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn byte(unit: f32) -> u8 {
    (unit.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// An image of `layer` of `frame` and a line saying what its greys or colours mean; None when
/// the frame lacks the layer (a file written with `--layers` that left it out, or a method that
/// does not make it). The beauty is drawn elsewhere (with the flag overlays).
pub(super) fn layer_image(
    frame: &CachedFrame,
    layer: Layer,
    exposure_stops: f32,
) -> Option<(RgbaImage, String)> {
    let channels = layer_channels(frame, layer);
    if channels.is_empty() {
        return None;
    }
    let (width, height) = (frame.rendered.width, frame.rendered.height);
    let pixels = width as usize * height as usize;
    let get = |c: usize, i: usize| channels.get(c).map_or(0.0, |(_, v)| v[i]);
    let mut bytes = Vec::with_capacity(pixels * 4);
    let legend = match look(layer) {
        Look::Colour => {
            let scale = exposure_stops.exp2();
            for i in 0..pixels {
                bytes.extend(display_srgb8([get(0, i), get(1, i), get(2, i)], scale));
                bytes.push(255);
            }
            format!("{}: tone-mapped at {exposure_stops:+.2} EV", layer.name())
        }
        Look::Depth => {
            let span = range(channels[0].1.iter().copied());
            for i in 0..pixels {
                let z = get(0, i);
                let grey = if z.is_finite() && z < SKY_DEPTH_M * 0.5 {
                    byte(1.0 - 0.85 * unit(z, span))
                } else {
                    0
                };
                bytes.extend([grey, grey, grey, 255]);
            }
            format!(
                "{}: {:.3} m (white) to {:.3} m (grey), sky black",
                layer.name(),
                span.0,
                span.1
            )
        }
        Look::Vector => {
            let spans: Vec<(f32, f32)> = channels
                .iter()
                .map(|(_, v)| range(v.iter().copied()))
                .collect();
            for i in 0..pixels {
                for c in 0..3 {
                    bytes.push(spans.get(c).map_or(0, |&span| byte(unit(get(c, i), span))));
                }
                bytes.push(255);
            }
            channels
                .iter()
                .zip(&spans)
                .zip(["red", "green", "blue"])
                .map(|(((name, _), span), colour)| {
                    format!("{name} {:.3} to {:.3} as {colour}", span.0, span.1)
                })
                .collect::<Vec<_>>()
                .join(", ")
        }
        Look::Index => {
            for i in 0..pixels {
                let index = get(0, i) as u32;
                let rgb = if index == 0 {
                    [0; 3]
                } else {
                    index_colour(index)
                };
                bytes.extend(rgb);
                bytes.push(255);
            }
            format!(
                "{}: a colour per object index, 0 (nothing) black; hover for names",
                layer.name()
            )
        }
        Look::Crypto => {
            for i in 0..pixels {
                let (id, coverage) = (get(0, i), get(1, i));
                let rgb = if coverage > 0.0 {
                    index_colour(id.to_bits()).map(|c| byte(c as f32 / 255.0 * coverage))
                } else {
                    [0; 3]
                };
                bytes.extend(rgb);
                bytes.push(255);
            }
            "CryptoObject00: rank 0's ID as a colour, times its coverage".to_string()
        }
        Look::Mask => {
            for i in 0..pixels {
                let grey = byte(get(0, i));
                bytes.extend([grey, grey, grey, 255]);
            }
            format!("{}: 0 black, 1 white", layer.name())
        }
    };
    Some((
        RgbaImage::from_raw(width, height, bytes).expect("sized to the frame"),
        legend,
    ))
}

/// The difference of `layer` between `a` and `b`: per pixel the largest absolute difference of
/// its channels, white at the frame's largest; black where they agree exactly. None when either
/// frame lacks the layer or their sizes differ.
pub(super) fn difference_image(
    a: &CachedFrame,
    b: &CachedFrame,
    layer: Layer,
) -> Option<(RgbaImage, String)> {
    if (a.rendered.width, a.rendered.height) != (b.rendered.width, b.rendered.height) {
        return None;
    }
    let (ca, cb) = (layer_channels(a, layer), layer_channels(b, layer));
    if ca.is_empty() || cb.is_empty() {
        return None;
    }
    let pixels = a.rendered.width as usize * a.rendered.height as usize;
    let pairs: Vec<(&Vec<f32>, &Vec<f32>)> = ca
        .iter()
        .filter_map(|(name, va)| cb.iter().find(|(n, _)| n == name).map(|(_, vb)| (va, vb)))
        .collect();
    let difference: Vec<f32> = (0..pixels)
        .map(|i| {
            pairs
                .iter()
                .map(|(va, vb)| {
                    let d = (va[i] - vb[i]).abs();
                    // Values that differ in kind (a sky value against a surface's) or are not
                    // numbers count as the largest difference.
                    if d.is_finite() {
                        d
                    } else {
                        f32::MAX
                    }
                })
                .fold(0.0, f32::max)
        })
        .collect();
    let finite_max = difference
        .iter()
        .copied()
        .filter(|d| *d < f32::MAX)
        .fold(0.0, f32::max);
    let differing = difference.iter().filter(|d| **d > 0.0).count();
    let mut bytes = Vec::with_capacity(pixels * 4);
    for &d in &difference {
        let grey = if d == 0.0 {
            0
        } else if d == f32::MAX || finite_max == 0.0 {
            255
        } else {
            // At least a dark grey, so a tiny difference is still seen.
            (40.0 + 215.0 * (d / finite_max).clamp(0.0, 1.0)).round() as u8
        };
        bytes.extend([grey, grey, grey, 255]);
    }
    let legend = format!(
        "|A - B| of {}: {differing} of {pixels} pixels differ, largest {finite_max} (white)",
        layer.name()
    );
    Some((
        RgbaImage::from_raw(a.rendered.width, a.rendered.height, bytes)
            .expect("sized to the frame"),
        legend,
    ))
}

/// Every channel's value at pixel (`x`, `y`) of `frame`, in the order the file holds them.
pub(super) fn pixel_channels(frame: &CachedFrame, x: u32, y: u32) -> Vec<(String, f32)> {
    if let Some(file) = &frame.file_channels {
        let index = y as usize * frame.rendered.width as usize + x as usize;
        return file
            .iter()
            .map(|(name, values)| (name.clone(), values[index]))
            .collect();
    }
    crate::output::exr::channel_values(
        &frame.rendered,
        &frame.object_names,
        &frame.write,
        y as usize..y as usize + 1,
        |_| true,
    )
    .into_iter()
    .map(|(name, values)| (name, values[x as usize]))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_written_channel_belongs_to_exactly_one_layer() {
        let names = [
            "R",
            "G",
            "B",
            "A",
            "Z",
            "ApparentDepth.Z",
            "P.X",
            "P.Y",
            "P.Z",
            "IndexOB.X",
            "CryptoObject00.R",
            "CryptoObject00.A",
            "WaterMatte.X",
            "Direct.R",
            "Refraction.B",
            "SkyReflection.G",
            "FlagConvergence.X",
            "FlagBoundary.X",
            "FlagPopping.X",
            "FlagExtrapolated.X",
            "Motion.X",
            "Motion.Y",
        ];
        for name in names {
            let owners: Vec<_> = Layer::ALL
                .into_iter()
                .filter(|&l| in_layer(l, name))
                .collect();
            assert_eq!(owners.len(), 1, "{name}: {owners:?}");
        }
        assert!(!in_layer(Layer::Position, "Pref.X"));
        assert_eq!(layer_named("IndexOB"), Some(Layer::IndexOb));
        assert_eq!(layer_named("nope"), None);
    }

    #[test]
    fn ranges_leave_out_the_sky_and_non_numbers() {
        assert_eq!(
            range([2.0, SKY_DEPTH_M, f32::NAN, 5.0].into_iter()),
            (2.0, 5.0)
        );
        assert_eq!(range([SKY_DEPTH_M].into_iter()), (0.0, 0.0));
        assert_eq!(unit(3.5, (2.0, 5.0)), 0.5);
    }
}
