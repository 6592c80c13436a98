// Shared by every pass: the frame constants, materials, textures, the sky, and the shading model
// of ALGORITHM §7. The CPU mirror of these formulas is `src/gpu/shading.rs`; keep the two in step.

struct Frame {
    clip_from_world: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    // Frame t-1's camera (the frame's own where there is no t-1), for the motion vectors.
    previous_clip_from_world: mat4x4<f32>,
    // xyz: eye position in world space.
    eye: vec4<f32>,
    // x, y: the frame's size in pixels; w: the first row drawn (a strip's; 0 for a whole frame).
    viewport: vec4<f32>,
    sky_zenith: vec4<f32>,
    sky_horizon: vec4<f32>,
    // xyz: unit vector toward the sun; w: cosine of the sun disk's angular radius.
    sun_direction: vec4<f32>,
    // xyz: sunlight colour for Lambert; w: radiance of the sun disk per unit of that colour.
    sun_color: vec4<f32>,
    ambient: vec4<f32>,
    absorption_per_m: vec4<f32>,
    scatter_color: vec4<f32>,
    // xyz: unit vector toward the sun as seen under the flat mean water plane; w: 1 when the sun
    // lights the water at all (0 below the horizon or under total internal reflection).
    sun_in_water: vec4<f32>,
    // x: n_above, y: n_below, z: mean_level_m.
    water: vec4<f32>,
    // xyz: unit view direction (camera forward); depths are measured along it.
    view_forward: vec4<f32>,
};

// One material: xyz = bits of the linear tint, w = texture layer. Stored as integers so the layer
// index is never a float bit pattern (a small integer is a denormal a driver may flush to zero).
const MAX_MATERIALS: u32 = 1024u;

struct Materials {
    entries: array<vec4<u32>, 1024>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> materials: Materials;
@group(0) @binding(2) var textures: texture_2d_array<f32>;
@group(0) @binding(3) var texture_sampler: sampler;

// Depth where nothing is seen (sky, or water with nothing behind it): crate::draw::SKY_DEPTH_M.
const SKY_DEPTH_M: f32 = 1e10;

// Depth along the view axis of a world point, as the EXR's `Z` holds it.
fn view_depth(world_position: vec3<f32>) -> f32 {
    return dot(world_position - frame.eye.xyz, frame.view_forward.xyz);
}

// Every draw of the main render pass writes the same four targets; write masks decide what
// actually lands.
struct Targets {
    @location(0) beauty: vec4<f32>,
    // xyz: world position bits (0 where nothing is seen); w: bits of the first surface's depth
    // along the view axis.
    @location(1) position: vec4<u32>,
    // Bits 0-3: the flag bits (crate::draw::flag_bits); bit 7: the first surface is the water
    // (WATER_BIT); bits 8-31: object index + 1 (0 = none).
    @location(2) flags: u32,
    // Bits of the front-most membrane fragment's sky reflection, premultiplied (F * sky, F), kept
    // until the under-water image is drawn and blended under it (shaders/water_clear.wgsl); read
    // back too, where WATER_BIT is set.
    @location(3) reflection: vec4<u32>,
    // xyz: reserved (zero); w: bits of the apparent depth: the view depth of what the pixel shows
    // (the virtual image for pixels seen through water).
    @location(4) extra: vec4<u32>,
};

// Set in the flags target where the membrane is the first surface (gpu::WATER_BIT).
const WATER_BIT: u32 = 0x80u;

// The flags target's word for a fragment of object `material` (its index in the frame's object
// list) with triangle flags `flags`; the CPU splits it again (gpu::OBJECT_SHIFT).
const OBJECT_SHIFT: u32 = 8u;
fn flags_and_object(flags: u32, material: u32) -> u32 {
    return flags | ((material + 1u) << OBJECT_SHIFT);
}

// A triangle covering the whole viewport at depth `z` (0 near, 1 far), from the vertex index alone.
fn full_screen_position(vertex_index: u32, z: f32) -> vec4<f32> {
    let x = f32((vertex_index << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vertex_index & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, z, 1.0);
}

// Unit sight ray through a fragment's pixel coordinates, as `Camera::ray_through_pixel` computes it.
// A strip's fragments are at rows of the strip: `viewport.w` (its first row; 0 for a whole frame)
// makes them rows of the frame (`viewport.xy`).
fn ray_through_pixel(pixel: vec2<f32>) -> vec3<f32> {
    let row = pixel.y + frame.viewport.w;
    let ndc = vec2<f32>(pixel.x / frame.viewport.x * 2.0 - 1.0, 1.0 - row / frame.viewport.y * 2.0);
    let far = frame.world_from_clip * vec4<f32>(ndc, 1.0, 1.0);
    return normalize(far.xyz / far.w - frame.eye.xyz);
}

// Radiance of the sky seen along unit direction `direction`: a zenith-horizon gradient (the
// horizon colour below the horizon) plus the sun disk.
fn sky_radiance(direction: vec3<f32>) -> vec3<f32> {
    let up = clamp(direction.y, 0.0, 1.0);
    let toward_horizon = 1.0 - up;
    let horizon_weight = toward_horizon * toward_horizon * toward_horizon;
    var radiance = frame.sky_zenith.xyz * (1.0 - horizon_weight) + frame.sky_horizon.xyz * horizon_weight;
    if dot(direction, frame.sun_direction.xyz) >= frame.sun_direction.w {
        radiance = radiance + frame.sun_color.xyz * frame.sun_color.w;
    }
    return radiance;
}

// Fraction reflected at the membrane by Schlick's approximation (ALGORITHM §3) for a sight ray
// `incident` meeting a surface of unit normal `normal` (pointing to the eye's side).
fn schlick_reflectance(incident: vec3<f32>, normal: vec3<f32>) -> f32 {
    let n1 = frame.water.x;
    let n2 = frame.water.y;
    let r0 = ((n1 - n2) / (n1 + n2)) * ((n1 - n2) / (n1 + n2));
    let cos_incidence = -dot(incident, normal);
    var x = clamp(cos_incidence, 0.0, 1.0);
    if n1 > n2 {
        let eta = n1 / n2;
        let c = clamp(cos_incidence, 0.0, 1.0);
        let k = 1.0 - eta * eta * (1.0 - c * c);
        if k < 0.0 {
            return 1.0;
        }
        x = sqrt(k);
    }
    let m = 1.0 - x;
    return r0 + (1.0 - r0) * (m * m * m * m * m);
}

// Linear albedo of a material at texture coordinates `uv`: tint times the (sRGB-decoded) texture.
fn albedo(material: u32, uv: vec2<f32>) -> vec3<f32> {
    let entry = materials.entries[min(material, MAX_MATERIALS - 1u)];
    let texel = textureSample(textures, texture_sampler, uv, entry.w);
    return bitcast<vec3<f32>>(entry.xyz) * texel.xyz;
}

// Lambert from the sun plus sky ambient, for surfaces on the eye's side of the water.
fn shade_above(albedo_linear: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let sun = frame.sun_color.xyz * max(dot(normal, frame.sun_direction.xyz), 0.0);
    return albedo_linear * (sun + frame.ambient.xyz);
}

// Under water: sunlight refracted through the mean plane and attenuated from the mean level down
// to the point (depth / cos), ambient attenuated over the depth; then the whole colour attenuated
// along the true view path `water_path_m`, with in-scatter toward the deep-water colour.
fn shade_under(albedo_linear: vec3<f32>, normal: vec3<f32>, true_position: vec3<f32>, water_path_m: f32) -> vec3<f32> {
    let sigma = frame.absorption_per_m.xyz;
    let depth_m = max(frame.water.z - true_position.y, 0.0);
    let sun_toward = frame.sun_in_water.xyz;
    var sun = vec3<f32>(0.0);
    if frame.sun_in_water.w > 0.0 {
        let sun_path_m = depth_m / sun_toward.y;
        sun = frame.sun_color.xyz * exp(-sigma * sun_path_m) * max(dot(normal, sun_toward), 0.0);
    }
    let ambient = frame.ambient.xyz * exp(-sigma * depth_m);
    let lit = albedo_linear * (sun + ambient);
    let transmittance = exp(-sigma * water_path_m);
    return lit * transmittance + frame.scatter_color.xyz * (1.0 - transmittance);
}

// Screen motion in pixels (x right, y down) from frame t-1 to t between two interpolated clip
// positions of the same point: now, and at t-1 through t-1's camera. Both are projected the same
// way (camera.rs pixel_of), so strips, which move the viewport, need no offset.
fn motion_px(clip_now: vec4<f32>, clip_before: vec4<f32>) -> vec2<f32> {
    if (clip_before.w <= 1e-6) {
        return vec2<f32>(0.0, 0.0);
    }
    let delta = clip_now.xy / clip_now.w - clip_before.xy / clip_before.w;
    return vec2<f32>(delta.x * 0.5 * frame.viewport.x, -delta.y * 0.5 * frame.viewport.y);
}
