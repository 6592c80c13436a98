//! No frame with a non-finite sample is ever written. The EXR channel map (README) states a finite
//! value for every layer where nothing is seen (`Z` = [`crate::draw::SKY_DEPTH_M`] for sky, `P` 0),
//! so a NaN or an infinity in any float layer is a render error naming the frame, the pixel and
//! the layer (absorption 1e39 or a sun of 1e39 used to give NaN pixels with exit 0).

use crate::draw::RenderedFrame;

/// The first pixel (in row order) with a non-finite sample, as (x, y, layer, value).
pub fn first_non_finite(frame: &RenderedFrame) -> Option<(u32, u32, &'static str, String)> {
    let width = frame.width.max(1) as usize;
    let pixels = frame.beauty_rgba.len();
    for index in 0..pixels {
        let mut samples: Vec<(&'static str, f32)> = Vec::with_capacity(16);
        let rgba = frame.beauty_rgba[index];
        samples.extend(["R", "G", "B", "A"].into_iter().zip(rgba));
        if let Some(&z) = frame.depth_m.get(index) {
            samples.push(("Z", z));
        }
        if let Some(&z) = frame.apparent_depth_m.get(index) {
            samples.push(("ApparentZ", z));
        }
        if let Some(p) = frame.position.get(index) {
            samples.extend(["P.X", "P.Y", "P.Z"].into_iter().zip(*p));
        }
        if let Some(&m) = frame.water_matte.get(index) {
            samples.push(("WaterMatte", m));
        }
        if let Some(m) = frame.motion_px.get(index) {
            samples.extend(["Motion.X", "Motion.Y"].into_iter().zip(*m));
        }
        if let Some(r) = frame.water_reflection.get(index) {
            samples.extend(
                [
                    "reflection.R",
                    "reflection.G",
                    "reflection.B",
                    "reflection.A",
                ]
                .into_iter()
                .zip(*r),
            );
        }
        if let Some((layer, value)) = samples.into_iter().find(|(_, v)| !v.is_finite()) {
            return Some((
                (index % width) as u32,
                (index / width) as u32,
                layer,
                value.to_string(),
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::{NO_OBJECT, SKY_DEPTH_M};

    fn frame() -> RenderedFrame {
        RenderedFrame {
            width: 2,
            height: 2,
            beauty_rgba: vec![[0.5, 0.5, 0.5, 1.0]; 4],
            // Pixel 1 is sky, pixel 2 water with nothing behind it: the channel map's values.
            depth_m: vec![1.0, SKY_DEPTH_M, 2.0, 3.0],
            apparent_depth_m: vec![1.0, SKY_DEPTH_M, SKY_DEPTH_M, 3.0],
            position: vec![[0.5; 3], [0.0; 3], [0.0; 3], [1.0; 3]],
            flags: vec![0; 4],
            object: vec![1, NO_OBJECT, NO_OBJECT, 2],
            water_matte: vec![0.0, 0.0, 1.0, 0.0],
            water_reflection: vec![[0.0; 4], [0.0; 4], [0.1, 0.1, 0.1, 0.02], [0.0; 4]],
            motion_px: vec![[0.5, -2.0], [0.0; 2], [0.0; 2], [1.0, 0.0]],
            coverage: Vec::new(),
        }
    }

    #[test]
    fn channel_map_values_pass_and_any_non_finite_sample_is_named() {
        assert_eq!(first_non_finite(&frame()), None);
        let mut bad = frame();
        bad.beauty_rgba[3][1] = f32::NAN;
        assert_eq!(first_non_finite(&bad), Some((1, 1, "G", "NaN".into())));
        let mut bad = frame();
        bad.depth_m[1] = f32::INFINITY;
        assert_eq!(first_non_finite(&bad), Some((1, 0, "Z", "inf".into())));
        let mut bad = frame();
        bad.apparent_depth_m[2] = f32::NAN;
        assert_eq!(
            first_non_finite(&bad),
            Some((0, 1, "ApparentZ", "NaN".into()))
        );
        let mut bad = frame();
        bad.position[3][2] = f32::NEG_INFINITY;
        assert_eq!(first_non_finite(&bad), Some((1, 1, "P.Z", "-inf".into())));
        let mut bad = frame();
        bad.water_reflection[2][3] = f32::NAN;
        assert_eq!(
            first_non_finite(&bad),
            Some((0, 1, "reflection.A", "NaN".into()))
        );
    }
}
