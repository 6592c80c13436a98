//! The renderer on a tiny synthetic frame (64x48): sky above the horizon, a wall standing out of
//! the water, a membrane quad over an under-water floor quad with known flags, and membrane with
//! nothing behind it. Every pixel whose class is unambiguous (its centre and four corners see the
//! same surface, by CPU ray casting) is checked against the CPU shading model of
//! `snell::gpu::shading`. Runs on whatever adapter `Renderer::new` picks: set `WGPU_BACKEND=gl` or
//! `=vulkan` to choose; on a machine without a GPU, Mesa's llvmpipe/lavapipe serve.

use glam::{Vec2, Vec3};
use snell::camera::Camera;
use snell::color::srgb8_to_linear as srgb_to_linear;
use snell::draw::{
    flag_bits, DrawMaterial, FrameDraw, FrameView, Lighting, MembraneVertex, RenderedFrame,
    TrueVertex, VirtualVertex, WaterOptics, SKY_DEPTH_M,
};
use snell::gpu::shading::{
    schlick_reflectance, shade_above, shade_under, sky_radiance, water_reflection,
};
use snell::gpu::{GpuError, Renderer};
use snell::mesh::Texture;

const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
// Levels that half floats cannot hold (nearest f16 is ~1e-4 away), so the P checks see float32.
const FLOOR_Y_M: f32 = -1.234567;
const FLOOR_FLAGS: u32 = flag_bits::CONVERGENCE | flag_bits::POPPING;
const WATER_PATH_M: f32 = 1.5;
const WALL_Z_M: f32 = -1.0123457;
/// Texel colour of the one-colour test texture, sRGB-encoded. White decodes exactly on every
/// driver, so the pixel checks test the shading model; `srgb_textures_decode_to_linear` tests decoding.
const TEXEL_SRGB: [u8; 3] = [255, 255, 255];

fn view() -> FrameView {
    let camera = Camera {
        eye: Vec3::new(0.3, 2.0, 6.0),
        target: Vec3::new(0.0, 0.0, -4.0),
        up: Vec3::Y,
        fov_y_deg: 50.0,
        near_m: snell::camera::NEAR_M,
        far_m: snell::camera::FAR_M,
    };
    FrameView {
        camera,
        previous_camera: camera,
        lighting: Lighting {
            sky_zenith_linear: Vec3::new(0.2, 0.4, 0.9),
            sky_horizon_linear: Vec3::new(0.8, 0.85, 0.9),
            sun_direction: Vec3::new(0.3, 0.8, 0.2).normalize(),
            sun_color_linear: Vec3::new(2.0, 1.9, 1.8),
            sun_size_deg: 0.53,
            ambient_linear: Vec3::new(0.25, 0.3, 0.35),
        },
        water: WaterOptics {
            n_above: 1.0,
            n_below: 1.333,
            absorption_per_m: Vec3::new(0.45, 0.12, 0.06),
            scatter_color_linear: Vec3::new(0.01, 0.06, 0.09),
            mean_level_m: 0.0,
            roughness: 0.05,
        },
    }
}

fn texture() -> Texture {
    one_colour_texture(TEXEL_SRGB)
}

fn one_colour_texture(srgb: [u8; 3]) -> Texture {
    let texel = [srgb[0], srgb[1], srgb[2], 255];
    Texture {
        name: "one colour".into(),
        width: 4,
        height: 4,
        rgba8_srgb: texel.repeat(16),
    }
}

fn materials() -> Vec<DrawMaterial> {
    vec![
        DrawMaterial {
            texture: 0,
            tint_linear: Vec3::new(0.9, 0.8, 0.7),
        },
        DrawMaterial {
            texture: 0,
            tint_linear: Vec3::new(0.5, 0.9, 0.6),
        },
    ]
}

fn albedo(material: usize) -> Vec3 {
    let texel = Vec3::new(
        srgb_to_linear(TEXEL_SRGB[0]),
        srgb_to_linear(TEXEL_SRGB[1]),
        srgb_to_linear(TEXEL_SRGB[2]),
    );
    materials()[material].tint_linear * texel
}

/// Axis-aligned rectangle in a plane: membrane (y = 0), floor (y = -1) and wall (z = -1).
#[derive(Clone, Copy)]
struct Rect {
    /// Which coordinate is constant (0 x, 1 y, 2 z) and its value.
    axis: usize,
    level: f32,
    min: Vec2,
    max: Vec2,
}

const MEMBRANE: Rect = Rect {
    axis: 1,
    level: 0.0,
    min: Vec2::new(-3.0, -6.0),
    max: Vec2::new(3.0, 2.0),
};
const FLOOR: Rect = Rect {
    axis: 1,
    level: FLOOR_Y_M,
    min: Vec2::new(-2.0, -5.0),
    max: Vec2::new(2.0, 1.0),
};
/// x in [1.2, 2.4], y in [-0.5, 1.0]: crosses the water line; its under-water half is hidden by the membrane.
const WALL: Rect = Rect {
    axis: 2,
    level: WALL_Z_M,
    min: Vec2::new(1.2, -0.5),
    max: Vec2::new(2.4, 1.0),
};

impl Rect {
    fn corner(&self, a: f32, b: f32) -> Vec3 {
        match self.axis {
            1 => Vec3::new(a, self.level, b),
            _ => Vec3::new(a, b, self.level),
        }
    }

    fn corners(&self) -> [Vec3; 4] {
        [
            self.corner(self.min.x, self.min.y),
            self.corner(self.max.x, self.min.y),
            self.corner(self.max.x, self.max.y),
            self.corner(self.min.x, self.max.y),
        ]
    }

    /// Ray parameter of the hit, if the ray meets the rectangle.
    // `!(t > 0.0)` also misses on a NaN `t` (ray parallel to the plane); `t <= 0.0` would not.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn hit(&self, origin: Vec3, direction: Vec3) -> Option<f32> {
        let t = (self.level - origin[self.axis]) / direction[self.axis];
        if !(t > 0.0) {
            return None;
        }
        let point = origin + direction * t;
        let (a, b) = if self.axis == 1 {
            (point.x, point.z)
        } else {
            (point.x, point.y)
        };
        (a >= self.min.x && a <= self.max.x && b >= self.min.y && b <= self.max.y).then_some(t)
    }
}

const QUAD: [u32; 6] = [0, 1, 2, 0, 2, 3];

fn frame_draw() -> FrameDraw {
    let wall_above: Vec<TrueVertex> = WALL
        .corners()
        .iter()
        .map(|&p| TrueVertex {
            position: p.into(),
            previous_position: p.into(),
            normal: [0.0, 0.0, 1.0],
            uv: [p.x, p.y],
            material: 0,
        })
        .collect();
    let membrane_vertices: Vec<MembraneVertex> = MEMBRANE
        .corners()
        .iter()
        .map(|&p| MembraneVertex {
            position: p.into(),
            normal: [0.0, 1.0, 0.0],
        })
        .collect();
    // Virtual positions equal true ones here, so the CPU can ray-cast the expected true position.
    let floor_corners = FLOOR.corners();
    let under_vertices: Vec<VirtualVertex> = QUAD
        .iter()
        .map(|&i| {
            let p = floor_corners[i as usize];
            VirtualVertex {
                virtual_position: p.into(),
                previous_position: p.into(),
                true_position: p.into(),
                normal: [0.0, 1.0, 0.0],
                uv: [p.x * 0.5, p.z * 0.5],
                material: 1,
                water_path_m: WATER_PATH_M,
                flags: FLOOR_FLAGS,
            }
        })
        .collect();
    FrameDraw {
        above_vertices: wall_above,
        above_indices: QUAD.to_vec(),
        under_vertices,
        membrane_vertices,
        membrane_indices: QUAD.to_vec(),
        materials: materials(),
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Seen {
    Sky,
    Wall {
        t: f32,
    },
    /// Membrane with the floor behind it.
    Floor {
        membrane_t: f32,
        floor_t: f32,
    },
    /// Membrane with nothing behind it.
    DeepWater {
        membrane_t: f32,
    },
}

fn cast(camera: &Camera, pixel: Vec2) -> (Vec3, Seen) {
    let direction = camera.ray_through_pixel(pixel, WIDTH, HEIGHT);
    let eye = camera.eye;
    let wall = WALL.hit(eye, direction);
    let membrane = MEMBRANE.hit(eye, direction);
    let seen = match (wall, membrane) {
        (Some(t), m) if m.is_none_or(|m| t < m) => Seen::Wall { t },
        (_, Some(membrane_t)) => match FLOOR.hit(eye, direction) {
            Some(floor_t) => Seen::Floor {
                membrane_t,
                floor_t,
            },
            None => Seen::DeepWater { membrane_t },
        },
        _ => Seen::Sky,
    };
    (direction, seen)
}

/// What a pixel shows when its centre and its four corners all see the same kind of surface.
fn unambiguous(camera: &Camera, x: u32, y: u32) -> Option<(Vec3, Seen)> {
    let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
    let (direction, seen) = cast(camera, centre);
    let same_kind = |other: Seen| std::mem::discriminant(&other) == std::mem::discriminant(&seen);
    let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
    corners
        .iter()
        .all(|&(dx, dy)| same_kind(cast(camera, Vec2::new(x as f32 + dx, y as f32 + dy)).1))
        .then_some((direction, seen))
}

#[test]
fn srgb_textures_decode_to_linear() {
    let mut renderer = renderer();
    let white = render(&mut renderer);
    let texel = [188u8, 128, 64];
    renderer
        .set_textures(&[one_colour_texture(texel)])
        .unwrap_or_else(|error| panic!("{error}"));
    let coloured = render(&mut renderer);
    let camera = view().camera;
    let mut checked = 0;
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let Some((_, Seen::Wall { .. })) = unambiguous(&camera, x, y) else {
                continue;
            };
            let at = (y * WIDTH + x) as usize;
            for (c, &code) in texel.iter().enumerate() {
                let ratio = coloured.beauty_rgba[at][c] / white.beauty_rgba[at][c];
                let expected = srgb_to_linear(code);
                // Drivers decode sRGB approximately (llvmpipe/lavapipe by a polynomial, measured
                // ~0.1 % off here), and a half-float target adds 2^-11 per value: allow a quarter
                // of the 8-bit step at this code, far below what a missing or doubled decode gives.
                let step = srgb_to_linear(code + 1) - expected;
                assert!(
                    (ratio - expected).abs() <= 0.25 * step + 2e-3 * expected,
                    "pixel ({x},{y}) channel {c}: ratio {ratio}, sRGB {code} decodes to {expected}"
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 20, "only {checked} wall pixels");
}

fn renderer() -> Renderer {
    let mut renderer = Renderer::new().unwrap_or_else(|error| panic!("no renderer: {error}"));
    renderer
        .set_textures(&[texture()])
        .unwrap_or_else(|error| panic!("textures: {error}"));
    eprintln!(
        "adapter: {} / beauty {}",
        renderer.adapter_summary(),
        renderer.beauty_format_name()
    );
    renderer
}

/// Relative tolerance on beauty. Half floats (GL) keep 11 significant bits, and a pixel seen
/// through the membrane is converted to half twice (the refracted colour, then the blend result);
/// llvmpipe converts toward zero (measured: rendered values fall below the CPU's), so each
/// conversion can lose up to one half-float ulp, 2^-10 relative: 2 x 9.8e-4, plus ~1e-4 of GPU
/// vs CPU arithmetic. Float32 targets keep only the arithmetic differences (pow/exp, ~1e-5).
fn beauty_tolerance(renderer: &Renderer) -> f32 {
    if renderer.beauty_format_name().contains("16") {
        2.1e-3
    } else {
        1e-4
    }
}

fn assert_colour_near(what: &str, x: u32, y: u32, actual: [f32; 4], expected: Vec3, relative: f32) {
    for c in 0..3 {
        let tolerance = relative * expected[c].abs().max(0.05);
        assert!(
            (actual[c] - expected[c]).abs() <= tolerance,
            "{what} pixel ({x},{y}) channel {c}: rendered {} expected {} (tolerance {tolerance})",
            actual[c],
            expected[c]
        );
    }
    assert_eq!(actual[3], 1.0, "{what} pixel ({x},{y}) alpha");
}

/// A coordinate that is the same at every vertex of a quad comes back as float32 within 2 ulps.
/// Not bit-exact: rasterisers interpolate perspective-correctly (a/w, then times w), which
/// llvmpipe rounds to 1 ulp off for a constant (measured); a half-float path would be ~2000 ulps off.
fn assert_float32_constant(what: &str, x: u32, y: u32, actual: f32, expected: f32) {
    let ulps = (actual.to_bits() as i64 - expected.to_bits() as i64).abs();
    assert!(
        ulps <= 2,
        "{what} at pixel ({x},{y}): {actual} is {ulps} ulps from {expected}"
    );
}

fn render(renderer: &mut Renderer) -> RenderedFrame {
    renderer
        .render(&frame_draw(), &view(), WIDTH, HEIGHT)
        .unwrap_or_else(|error| panic!("render failed: {error}"))
}

#[test]
fn every_unambiguous_pixel_matches_the_cpu_model() {
    let mut renderer = renderer();
    let frame = render(&mut renderer);
    let view = view();
    let camera = view.camera;
    let tolerance = beauty_tolerance(&renderer);
    assert_eq!((frame.width, frame.height), (WIDTH, HEIGHT));
    let pixel_count = (WIDTH * HEIGHT) as usize;
    for layer_len in [
        frame.beauty_rgba.len(),
        frame.position.len(),
        frame.depth_m.len(),
        frame.apparent_depth_m.len(),
        frame.flags.len(),
        frame.object.len(),
        frame.water_matte.len(),
        frame.water_reflection.len(),
    ] {
        assert_eq!(layer_len, pixel_count);
    }

    let mut counts = [0usize; 4];
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let at = (y * WIDTH + x) as usize;
            let (beauty, position, depth, flags, object) = (
                frame.beauty_rgba[at],
                frame.position[at],
                frame.depth_m[at],
                frame.flags[at],
                frame.object[at],
            );
            let (apparent, matte, reflection) = (
                frame.apparent_depth_m[at],
                frame.water_matte[at],
                frame.water_reflection[at],
            );
            // Every pixel, ambiguous or not: only the floor's flags or none.
            assert!(
                flags == 0 || flags == FLOOR_FLAGS,
                "pixel ({x},{y}) flags {flags}"
            );
            let Some((direction, seen)) = unambiguous(&camera, x, y) else {
                continue;
            };
            // Z is the depth along the view axis of a hit at ray parameter t.
            let depth_of = |t: f32| t * direction.dot(camera.forward());
            let through_membrane = |membrane_t: f32, behind: Vec3| {
                let normal = Vec3::Y;
                let f =
                    schlick_reflectance(direction, normal, view.water.n_above, view.water.n_below);
                let (sky, f_model) =
                    water_reflection(direction, normal, &view.lighting, &view.water);
                assert_eq!(f, f_model, "the reflection's F is Schlick's");
                let membrane_depth = depth_of(membrane_t);
                assert!(
                    (depth - membrane_depth).abs() <= 1e-4 * membrane_depth,
                    "pixel ({x},{y}) Z {depth} vs {membrane_depth}"
                );
                assert_eq!(matte, 1.0, "water pixel ({x},{y}) matte");
                assert!(
                    (reflection[3] - f).abs() <= 1e-5,
                    "pixel ({x},{y}) F {reflection:?} vs {f}"
                );
                for c in 0..3 {
                    assert!(
                        (reflection[c] - sky[c]).abs() <= 1e-4 * sky[c].max(0.05),
                        "pixel ({x},{y}) reflection {reflection:?} vs {sky}"
                    );
                }
                (f, sky + (1.0 - f) * behind)
            };
            match seen {
                Seen::Sky => {
                    counts[0] += 1;
                    let expected = sky_radiance(direction, &view.lighting);
                    assert_colour_near("sky", x, y, beauty, expected, tolerance);
                    assert_eq!(position, [0.0; 3], "sky pixel ({x},{y}) position");
                    assert_eq!(depth, SKY_DEPTH_M, "sky pixel ({x},{y})");
                    assert_eq!(apparent, SKY_DEPTH_M, "sky pixel ({x},{y})");
                    assert_eq!((matte, reflection), (0.0, [0.0; 4]), "sky pixel ({x},{y})");
                    assert_eq!(flags, 0);
                    assert_eq!(object, snell::draw::NO_OBJECT, "sky pixel ({x},{y})");
                }
                Seen::Wall { t } => {
                    counts[1] += 1;
                    let expected = shade_above(albedo(0), Vec3::Z, &view.lighting);
                    assert_colour_near("wall", x, y, beauty, expected, tolerance);
                    let hit = camera.eye + direction * t;
                    assert_float32_constant("wall z", x, y, position[2], WALL_Z_M);
                    assert!(
                        (Vec3::from(position) - hit).length() <= 1e-4 * t,
                        "wall ({x},{y}) {position:?} vs {hit}"
                    );
                    assert!(
                        (depth - depth_of(t)).abs() <= 1e-4 * t,
                        "wall pixel ({x},{y}) Z {depth} vs {}",
                        depth_of(t)
                    );
                    assert_eq!(apparent, depth, "wall pixel ({x},{y}): nothing refracted");
                    assert_eq!((matte, reflection), (0.0, [0.0; 4]), "wall pixel ({x},{y})");
                    assert_eq!(flags, 0, "wall pixel ({x},{y})");
                    // The wall is material 0: object index 0, stored as 1.
                    assert_eq!(object, 1, "wall pixel ({x},{y})");
                }
                Seen::Floor {
                    membrane_t,
                    floor_t,
                } => {
                    counts[2] += 1;
                    let hit = camera.eye + direction * floor_t;
                    let under = shade_under(
                        albedo(1),
                        Vec3::Y,
                        hit,
                        WATER_PATH_M,
                        &view.lighting,
                        &view.water,
                    );
                    let (f, expected) = through_membrane(membrane_t, under);
                    assert_colour_near("floor through water", x, y, beauty, expected, tolerance);
                    // Seen from above at these angles the water is mostly transparent.
                    assert!(f < 0.2, "pixel ({x},{y}) Fresnel {f}");
                    let brightness = beauty[0] + beauty[1] + beauty[2];
                    let refracted = under.x + under.y + under.z;
                    assert!(
                        brightness >= (1.0 - f) * refracted * 0.999,
                        "pixel ({x},{y}) darker than its refracted part"
                    );
                    assert_float32_constant("floor y", x, y, position[1], FLOOR_Y_M);
                    assert!(
                        (Vec3::from(position) - hit).length() <= 1e-4 * floor_t,
                        "floor ({x},{y}) {position:?} vs {hit}"
                    );
                    assert_eq!(flags, FLOOR_FLAGS, "floor pixel ({x},{y})");
                    // The virtual floor is the true one here: its depth is the floor's.
                    assert!(
                        (apparent - depth_of(floor_t)).abs() <= 1e-4 * floor_t,
                        "floor pixel ({x},{y}) apparent depth {apparent} vs {}",
                        depth_of(floor_t)
                    );
                    assert_eq!(object, 2, "floor pixel ({x},{y})");
                }
                Seen::DeepWater { membrane_t } => {
                    counts[3] += 1;
                    let (_, expected) =
                        through_membrane(membrane_t, view.water.scatter_color_linear);
                    assert_colour_near("deep water", x, y, beauty, expected, tolerance);
                    assert_eq!(position, [0.0; 3], "deep water ({x},{y}) position");
                    assert_eq!(apparent, SKY_DEPTH_M, "deep water ({x},{y}): nothing seen");
                    assert_eq!(flags, 0, "deep water pixel ({x},{y})");
                    assert_eq!(object, snell::draw::NO_OBJECT, "deep water ({x},{y})");
                }
            }
        }
    }
    // The frame must actually contain each kind of pixel, or the checks above prove little.
    for (kind, count) in ["sky", "wall", "floor", "deep water"].iter().zip(counts) {
        assert!(count >= 20, "only {count} unambiguous {kind} pixels");
    }
    eprintln!(
        "checked pixels: sky {} wall {} floor {} deep water {}",
        counts[0], counts[1], counts[2], counts[3]
    );
}

#[test]
fn flags_are_set_exactly_where_the_floor_is_seen_through_the_membrane() {
    let mut renderer = renderer();
    let frame = render(&mut renderer);
    let camera = view().camera;
    let mut flagged_without_floor = Vec::new();
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let flagged = frame.flags[(y * WIDTH + x) as usize] != 0;
            let (_, seen) = cast(&camera, Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            let floor = matches!(seen, Seen::Floor { .. });
            // Pixel centres exactly on an edge can go either way; everything else must agree.
            if flagged != floor && unambiguous(&camera, x, y).is_some() {
                flagged_without_floor.push((x, y, flagged));
            }
        }
    }
    assert!(
        flagged_without_floor.is_empty(),
        "flags disagree with ray casting at {flagged_without_floor:?}"
    );
}

fn bits(frame: &RenderedFrame) -> Vec<u32> {
    let mut out = Vec::new();
    out.extend(frame.beauty_rgba.iter().flatten().map(|v| v.to_bits()));
    out.extend(frame.position.iter().flatten().map(|v| v.to_bits()));
    out.extend(frame.depth_m.iter().map(|v| v.to_bits()));
    out.extend(frame.apparent_depth_m.iter().map(|v| v.to_bits()));
    out.extend(frame.flags.iter().copied());
    out.extend(frame.object.iter().copied());
    out.extend(frame.water_matte.iter().map(|v| v.to_bits()));
    out.extend(frame.water_reflection.iter().flatten().map(|v| v.to_bits()));
    out
}

#[test]
fn rendering_is_deterministic_and_survives_size_changes() {
    let mut renderer = renderer();
    let first = render(&mut renderer);
    let second = render(&mut renderer);
    assert!(
        bits(&first) == bits(&second),
        "two renders of the same frame differ"
    );
    let small = renderer
        .render(&frame_draw(), &view(), 32, 24)
        .unwrap_or_else(|error| panic!("{error}"));
    assert_eq!(small.beauty_rgba.len(), 32 * 24);
    // More geometry than before forces the vertex buffers to grow; the frame must not change.
    let mut bigger = frame_draw();
    let mut far_away = bigger.under_vertices.clone();
    for vertex in &mut far_away {
        vertex.virtual_position[2] -= 2000.0; // beyond the far plane: clipped, never visible
    }
    for _ in 0..200 {
        bigger.under_vertices.extend_from_slice(&far_away);
    }
    let third = renderer
        .render(&bigger, &view(), WIDTH, HEIGHT)
        .unwrap_or_else(|error| panic!("{error}"));
    assert!(
        bits(&first) == bits(&third),
        "frame changed after a resize and a buffer growth"
    );
}

#[test]
fn bad_draw_data_is_an_error_not_a_crash() {
    let mut renderer = renderer();
    let mut draw = frame_draw();
    draw.under_vertices[1].material = 7;
    let error = renderer
        .render(&draw, &view(), WIDTH, HEIGHT)
        .expect_err("material 7 does not exist");
    assert!(
        matches!(error, GpuError::IndexOutOfRange { value: 7, .. }),
        "{error}"
    );
    let mut draw = frame_draw();
    draw.membrane_indices[2] = 99;
    assert!(matches!(
        renderer.render(&draw, &view(), WIDTH, HEIGHT),
        Err(GpuError::IndexOutOfRange { value: 99, .. })
    ));
    let mut draw = frame_draw();
    draw.materials[0].texture = 3;
    assert!(matches!(
        renderer.render(&draw, &view(), WIDTH, HEIGHT),
        Err(GpuError::TextureOutOfRange { .. })
    ));
    assert!(matches!(
        renderer.render(&frame_draw(), &view(), 0, HEIGHT),
        Err(GpuError::BadSize { .. })
    ));
    let broken = Texture {
        name: "short".into(),
        width: 4,
        height: 4,
        rgba8_srgb: vec![0; 10],
    };
    assert!(matches!(
        renderer.set_textures(&[broken]),
        Err(GpuError::BadTexture { .. })
    ));
    // The renderer still works after refusing bad input.
    render(&mut renderer);
}

/// A floor grid of `cells` x `cells` quads as unindexed virtual triangles, and a membrane grid.
fn heavy_draw(cells: usize, membrane_cells: usize) -> FrameDraw {
    let mut draw = frame_draw();
    draw.under_vertices.clear();
    let at = |i: usize, j: usize, n: usize, rect: &Rect| {
        let a = rect.min.x + (rect.max.x - rect.min.x) * i as f32 / n as f32;
        let b = rect.min.y + (rect.max.y - rect.min.y) * j as f32 / n as f32;
        rect.corner(a, b)
    };
    for j in 0..cells {
        for i in 0..cells {
            let corners = [
                at(i, j, cells, &FLOOR),
                at(i + 1, j, cells, &FLOOR),
                at(i + 1, j + 1, cells, &FLOOR),
                at(i, j + 1, cells, &FLOOR),
            ];
            for &k in &QUAD {
                let p = corners[k as usize];
                draw.under_vertices.push(VirtualVertex {
                    virtual_position: p.into(),
                    previous_position: p.into(),
                    true_position: p.into(),
                    normal: [0.0, 1.0, 0.0],
                    uv: [p.x, p.z],
                    material: 1,
                    water_path_m: WATER_PATH_M,
                    flags: ((i + j) % 16) as u32,
                });
            }
        }
    }
    let n = membrane_cells;
    draw.membrane_vertices = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| (i, j)))
        .map(|(i, j)| MembraneVertex {
            position: at(i, j, n, &MEMBRANE).into(),
            normal: [0.0, 1.0, 0.0],
        })
        .collect();
    draw.membrane_indices = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let v = |i: usize, j: usize| (j * (n + 1) + i) as u32;
            [
                v(i, j),
                v(i + 1, j),
                v(i + 1, j + 1),
                v(i, j),
                v(i + 1, j + 1),
                v(i, j + 1),
            ]
        })
        .collect();
    draw
}

/// Not a pass/fail test: prints the time of a 1280x720 frame of ~200k vertices, readback included.
/// Run with `cargo test --release --test gpu_render -- --ignored --nocapture`.
#[test]
#[ignore]
fn timing_1280x720_with_200k_vertices() {
    let mut renderer = renderer();
    let draw = heavy_draw(180, 128);
    let vertex_count =
        draw.under_vertices.len() + draw.membrane_vertices.len() + draw.above_vertices.len();
    let mut times_ms = Vec::new();
    for _ in 0..12 {
        let start = std::time::Instant::now();
        let frame = renderer
            .render(&draw, &view(), 1280, 720)
            .unwrap_or_else(|error| panic!("{error}"));
        times_ms.push(start.elapsed().as_secs_f64() * 1e3);
        assert_eq!(frame.flags.len(), 1280 * 720);
    }
    let first_ms = times_ms[0];
    let warm = &mut times_ms[2..];
    warm.sort_by(f64::total_cmp);
    eprintln!(
        "{} vertices at 1280x720 on {}: first {:.1} ms, warm median {:.1} ms, min {:.1} ms, max {:.1} ms",
        vertex_count,
        renderer.adapter_summary(),
        first_ms,
        warm[warm.len() / 2],
        warm[0],
        warm[warm.len() - 1]
    );
}
