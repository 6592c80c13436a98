//! The header attributes of a frame: OpenEXR's standard camera and colour attributes, the
//! Cryptomatte metadata and snell's own `snell.*` attributes.

use ::exr::math::Vec2;
use ::exr::meta::attribute::{AttributeValue, Chromaticities, Text};
use glam::{Mat4, Vec3, Vec4};

use super::channels::{CHANNEL_MAP_VERSION, CRYPTO_OBJECT};
use super::cryptomatte;
use super::FrameMeta;
use crate::camera::Camera;

pub(super) const FRAME: &str = "snell.frame";
pub(super) const TIME_SECS: &str = "snell.timeSecs";
pub(super) const WORLD_FROM_CAMERA: &str = "snell.worldFromCamera";
pub(super) const FOV_Y_DEG: &str = "snell.fovYDeg";
pub(super) const CAMERA_EYE: &str = "snell.cameraEye";
pub(super) const CAMERA_TARGET: &str = "snell.cameraTarget";
pub(super) const CAMERA_UP: &str = "snell.cameraUp";
/// The camera's clip planes (view depths, metres); `worldToNDC`'s z row maps them to 0 and 1.
pub(super) const CLIP_NEAR_M: &str = "snell.clipNearM";
pub(super) const CLIP_FAR_M: &str = "snell.clipFarM";
pub(super) const METHOD: &str = "snell.method";
pub(super) const VERSION: &str = "snell.version";
pub(super) const CHANNEL_MAP: &str = "snell.channelMap";
/// JSON array: the name of `IndexOB` 1, 2, ...
pub(super) const OBJECT_NAMES: &str = "snell.objectNames";
/// How the frame is stored: [`super::WriteOptions::label`].
pub(super) const OUTPUT: &str = "snell.output";
pub(super) const EXTRA_PREFIX: &str = "snell.extra.";

pub(super) fn text(value: &str) -> Text {
    // OpenEXR strings are byte strings; UTF-8 is what current OpenEXR and its tools assume.
    Text::from_slice_unchecked(value.as_bytes())
}

fn string(value: &str) -> AttributeValue {
    AttributeValue::Text(text(value))
}

/// OpenEXR's camera space is left-handed with +Z forward; snell's (glam's look_at_rh) is
/// right-handed with -Z forward, so the standard matrix flips Z after the view transform.
pub(super) fn standard_camera_from_world(camera: &Camera) -> Mat4 {
    Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0)) * camera.view_from_world()
}

/// `screenWindowWidth`: the screen window is the image's extent on the z = 1 plane of the
/// (standard) camera space, centred on the view axis, so its width is 2 tan(horizontal fov / 2).
pub(super) fn screen_window_width(camera: &Camera, width: usize, height: usize) -> f32 {
    let aspect = width as f32 / height as f32;
    2.0 * (camera.fov_y_deg.to_radians() * 0.5).tan() * aspect
}

/// `worldToNDC`: world to OpenEXR's (RenderMan's) NDC, where (0, 0) and (1, 1) are the display
/// window's top-left and bottom-right corners: x' = x/(z W) + 1/2, y' = 1/2 - y/(z H) in standard
/// camera space, W and H the screen window's size. The z row maps the near and far clip planes
/// (which the standard names nowhere else) to 0 and 1.
pub(super) fn ndc_from_world(camera: &Camera, width: usize, height: usize) -> Mat4 {
    let window_width = screen_window_width(camera, width, height);
    let window_height = window_width * height as f32 / width as f32;
    let (near, far) = (camera.near_m, camera.far_m);
    let depth_scale = far / (far - near);
    let ndc_from_camera = Mat4::from_cols(
        Vec4::new(1.0 / window_width, 0.0, 0.0, 0.0),
        Vec4::new(0.0, -1.0 / window_height, 0.0, 0.0),
        Vec4::new(0.5, 0.5, depth_scale, 1.0),
        Vec4::new(0.0, 0.0, -near * depth_scale, 0.0),
    );
    ndc_from_camera * standard_camera_from_world(camera)
}

/// The frame rate as OpenEXR's rational: integers exactly, and the NTSC rates (23.976, 29.97,
/// 59.94, ...) as n * 1000 / 1001.
pub(super) fn frames_per_second(fps: f64) -> (i32, u32) {
    if (fps - fps.round()).abs() < 1e-9 && fps >= 1.0 && fps <= i32::MAX as f64 {
        return (fps.round() as i32, 1);
    }
    let ntsc = (fps * 1.001).round();
    if ntsc >= 1.0 && (ntsc * 1000.0 / 1001.0 - fps).abs() < 1e-3 * fps {
        return ((ntsc * 1000.0) as i32, 1001);
    }
    // Any other rate: to a millionth.
    ((fps * 1e6).round() as i32, 1_000_000)
}

/// `capDate` (`YYYY:MM:DD hh:mm:ss`) of a Unix time, in UTC (so `utcOffset` is 0).
pub(super) fn cap_date(unix_secs: i64) -> String {
    let days = unix_secs.div_euclid(86_400);
    let secs = unix_secs.rem_euclid(86_400);
    // Howard Hinnant's days-from-civil inverse.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}:{month:02}:{day:02} {:02}:{:02}:{:02}",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

/// Rec. 709 / sRGB primaries with the D65 white point: the beauty's colour space.
fn rec709() -> Chromaticities {
    Chromaticities {
        red: Vec2(0.64, 0.33),
        green: Vec2(0.30, 0.60),
        blue: Vec2(0.15, 0.06),
        white: Vec2(0.3127, 0.3290),
    }
}

/// Every attribute of a frame's header besides the layout ones the writer adds.
pub(super) fn attributes(
    meta: &FrameMeta,
    width: usize,
    height: usize,
    crypto_names: &[String],
) -> Result<Vec<(String, AttributeValue)>, String> {
    let camera = &meta.camera;
    let frame_number = i32::try_from(meta.frame)
        .map_err(|_| format!("frame number {} exceeds i32", meta.frame))?;
    let vec3 = |v: Vec3| AttributeValue::FloatVec3((v.x, v.y, v.z));
    let key = cryptomatte::metadata_key(CRYPTO_OBJECT);
    let crypto = |field: &str| format!("cryptomatte/{key}/{field}");
    let mut attributes: Vec<(String, AttributeValue)> = vec![
        ("pixelAspectRatio".into(), AttributeValue::F32(1.0)),
        (
            "screenWindowCenter".into(),
            AttributeValue::FloatVec2(Vec2(0.0, 0.0)),
        ),
        (
            "screenWindowWidth".into(),
            AttributeValue::F32(screen_window_width(camera, width, height)),
        ),
        (
            "worldToCamera".into(),
            AttributeValue::Matrix4x4(standard_camera_from_world(camera).to_cols_array()),
        ),
        (
            "worldToNDC".into(),
            AttributeValue::Matrix4x4(ndc_from_world(camera, width, height).to_cols_array()),
        ),
        (
            "framesPerSecond".into(),
            AttributeValue::Rational(frames_per_second(meta.fps)),
        ),
        (
            "chromaticities".into(),
            AttributeValue::Chromaticities(rec709()),
        ),
        (
            "software".into(),
            string(&format!("snell {}", meta.version)),
        ),
        (crypto("name"), string(CRYPTO_OBJECT)),
        (crypto("hash"), string("MurmurHash3_32")),
        (crypto("conversion"), string("uint32_to_float32")),
        (
            crypto("manifest"),
            string(&cryptomatte::manifest(crypto_names)),
        ),
        (FRAME.into(), AttributeValue::I32(frame_number)),
        (TIME_SECS.into(), AttributeValue::F64(meta.time_secs)),
        (
            WORLD_FROM_CAMERA.into(),
            AttributeValue::Matrix4x4(camera.view_from_world().inverse().to_cols_array()),
        ),
        (FOV_Y_DEG.into(), AttributeValue::F32(camera.fov_y_deg)),
        (CAMERA_EYE.into(), vec3(camera.eye)),
        (CAMERA_TARGET.into(), vec3(camera.target)),
        (CAMERA_UP.into(), vec3(camera.up)),
        (CLIP_NEAR_M.into(), AttributeValue::F32(camera.near_m)),
        (CLIP_FAR_M.into(), AttributeValue::F32(camera.far_m)),
        (METHOD.into(), string(&meta.method)),
        (VERSION.into(), string(&meta.version)),
        (CHANNEL_MAP.into(), string(CHANNEL_MAP_VERSION)),
        (OUTPUT.into(), string(&meta.write.label())),
        (
            OBJECT_NAMES.into(),
            string(&serde_json::to_string(&meta.object_names).expect("strings serialise")),
        ),
    ];
    // The Cryptomatte's metadata only with its layer (`--layers` may leave it out).
    if !meta.write.layers.has(super::channels::Layer::CryptoObject) {
        attributes.retain(|(name, _)| !name.starts_with("cryptomatte/"));
    }
    if let Some(owner) = &meta.owner {
        attributes.push(("owner".into(), string(owner)));
    }
    if let Some(unix_secs) = meta.capture_unix_secs {
        attributes.push(("capDate".into(), string(&cap_date(unix_secs))));
        attributes.push(("utcOffset".into(), AttributeValue::F32(0.0)));
    }
    for (key, value) in &meta.extra {
        let name = format!("{EXTRA_PREFIX}{key}");
        if key.is_empty() || key.contains('\0') || name.len() > 255 {
            return Err(format!(
                "extra attribute name {key:?} is empty, contains NUL or is too long"
            ));
        }
        if attributes.iter().any(|(existing, _)| *existing == name) {
            return Err(format!("extra attribute {key:?} is given twice"));
        }
        attributes.push((name, string(value)));
    }
    Ok(attributes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: Vec3::new(1.0, 3.0, 8.0),
            target: Vec3::new(0.0, -1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
            near_m: crate::camera::NEAR_M,
            far_m: crate::camera::FAR_M,
        }
    }

    /// worldToNDC sends a world point to the NDC of the pixel it projects to, as snell's own
    /// camera places it, and the screen window matches.
    #[test]
    fn world_to_ndc_agrees_with_the_cameras_pixels() {
        let (width, height) = (640usize, 360usize);
        let camera = camera();
        let ndc_from_world = ndc_from_world(&camera, width, height);
        for point in [
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.7, -0.5, 1.2),
            Vec3::new(-2.0, 0.3, 2.5),
        ] {
            let pixel = camera.pixel_of(point, width as u32, height as u32).unwrap();
            let ndc = ndc_from_world.project_point3(point);
            assert!(
                (ndc.x - pixel.x / width as f32).abs() < 1e-5
                    && (ndc.y - pixel.y / height as f32).abs() < 1e-5,
                "{ndc} vs {pixel}"
            );
            assert!(ndc.z > 0.0 && ndc.z < 1.0);
            // The same point on the z = 1 plane of standard camera space lies in the screen window.
            let c = standard_camera_from_world(&camera).transform_point3(point);
            let window = screen_window_width(&camera, width, height);
            assert!((c.x / c.z / window + 0.5 - ndc.x).abs() < 1e-5);
        }
    }

    #[test]
    fn frame_rates_are_exact_rationals() {
        assert_eq!(frames_per_second(24.0), (24, 1));
        assert_eq!(frames_per_second(24000.0 / 1001.0), (24000, 1001));
        assert_eq!(frames_per_second(29.97), (30000, 1001));
        assert_eq!(frames_per_second(12.5), (12_500_000, 1_000_000));
    }

    #[test]
    fn cap_dates_are_utc_calendar_dates() {
        assert_eq!(cap_date(0), "1970:01:01 00:00:00");
        assert_eq!(cap_date(951_782_400), "2000:02:29 00:00:00");
        assert_eq!(cap_date(1_700_000_000), "2023:11:14 22:13:20");
    }
}
