// Shared by every pass: the frame constants, materials, textures, the sky, and the shading model
// of ALGORITHM §7. The CPU mirror of these formulas is `src/gpu/shading.rs`; keep the two in step.

struct Frame {
    clip_from_world: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    // Frame t-1's camera (the frame's own where there is no t-1), for the motion vectors.
    previous_clip_from_world: mat4x4<f32>,
    // xyz: eye position in world space.
    eye: vec4<f32>,
    // x, y: the frame's size in pixels; z: pixels of the frame a pixel drawn spans (1; 2 where a
    // supersampled frame's points are drawn, gpu::resolve); w: the first row drawn (a strip's; 0
    // for a whole frame).
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
    // x: n_above, y: n_below, z: mean_level_m, w: the square of the sun glint's Beckmann roughness
    // (gpu::shading::glint_roughness2).
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

// The largest radiance shaded: the largest half float (gpu::shading::RADIANCE_MAX).
const RADIANCE_MAX: f32 = 65504.0;

// Radiance of the sky seen along unit direction `direction` without the sun: a zenith-horizon
// gradient (the horizon colour below the horizon).
fn sky_gradient(direction: vec3<f32>) -> vec3<f32> {
    let up = clamp(direction.y, 0.0, 1.0);
    let toward_horizon = 1.0 - up;
    let horizon_weight = toward_horizon * toward_horizon * toward_horizon;
    return frame.sky_zenith.xyz * (1.0 - horizon_weight) + frame.sky_horizon.xyz * horizon_weight;
}

// Radiance of the sky seen along unit direction `direction`: the gradient plus the sun disk.
fn sky_radiance(direction: vec3<f32>) -> vec3<f32> {
    var radiance = sky_gradient(direction);
    if dot(direction, frame.sun_direction.xyz) >= frame.sun_direction.w {
        radiance = radiance + frame.sun_color.xyz * frame.sun_color.w;
    }
    return min(radiance, vec3<f32>(RADIANCE_MAX));
}

// Smith's masking for a Beckmann surface of roughness `alpha` (gpu::shading::smith_beckmann).
fn smith_beckmann(cos_in: f32, alpha: f32) -> f32 {
    let c = clamp(cos_in, 1e-6, 1.0);
    let t = sqrt(max(1.0 - c * c, 0.0)) / c;
    let a = 1.0 / max(alpha * t, 1e-30);
    if a >= 1.6 {
        return 1.0;
    }
    return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a);
}

// The sun's glint off facets finer than the membrane (gpu::shading::sun_glint): Cook-Torrance,
// Beckmann of roughness^2 frame.water.w, Smith, Schlick at the facet; the sun's irradiance is
// pi times its colour.
fn sun_glint(incident: vec3<f32>, normal: vec3<f32>) -> vec3<f32> {
    let to_eye = -incident;
    let to_sun = frame.sun_direction.xyz;
    let cos_view = dot(normal, to_eye);
    let cos_sun = dot(normal, to_sun);
    if cos_view <= 0.0 || cos_sun <= 0.0 {
        return vec3<f32>(0.0);
    }
    let sum = to_eye + to_sun;
    let sum_length = length(sum);
    if sum_length <= 0.0 {
        return vec3<f32>(0.0);
    }
    let half_vector = sum / sum_length;
    let cos_half = dot(normal, half_vector);
    if cos_half <= 0.0 {
        return vec3<f32>(0.0);
    }
    let alpha2 = frame.water.w;
    let alpha = sqrt(alpha2);
    let cos2 = cos_half * cos_half;
    let tan2 = max(1.0 - cos2, 0.0) / cos2;
    let distribution = exp(-tan2 / alpha2) / (3.14159265358979 * alpha2 * cos2 * cos2);
    let masking = smith_beckmann(cos_view, alpha) * smith_beckmann(cos_sun, alpha);
    let fresnel = schlick_reflectance(incident, half_vector);
    let glint = 3.14159265358979 * frame.sun_color.xyz * (fresnel * distribution * masking / (4.0 * cos_view));
    return min(glint, vec3<f32>(RADIANCE_MAX));
}

// What the water reflects toward the eye (gpu::shading::water_reflection), premultiplied:
// (F * sky gradient reflected + the sun's glint, F).
fn water_reflection(incident: vec3<f32>, normal: vec3<f32>) -> vec4<f32> {
    let reflectance = schlick_reflectance(incident, normal);
    let reflected = reflect(incident, normal);
    let radiance = reflectance * sky_gradient(reflected) + sun_glint(incident, normal);
    return vec4<f32>(min(radiance, vec3<f32>(RADIANCE_MAX)), reflectance);
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

// Linear albedo of a material at texture coordinates `uv` (a TextureCoordinates: with their
// change to the next pixel right and down, which choose the mip level): tint times the
// (sRGB-decoded) texture.
fn albedo(material: u32, uv: TextureCoordinates) -> vec3<f32> {
    let entry = materials.entries[min(material, MAX_MATERIALS - 1u)];
    let texel = textureSampleGrad(textures, texture_sampler, uv.at, entry.w, uv.right, uv.down);
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

// Pulled geometry (issue 19: a frame drawn in strips equals the frame drawn whole). The passes
// that draw triangles (above water, membrane, under water) read their vertices from storage
// buffers instead of vertex inputs: the vertex stage places each vertex on the rasteriser's
// 1/256-pixel grid of the WHOLE frame itself, so the coverage of every strip is the frame's, and
// the fragment stage interpolates the triangle's attributes from the whole frame's pixel centre,
// so the values do not depend on the attachment's origin (Mesa's plane equations start there).
// Binding 0 of group 1 is pass d's reflection target (shaders/water_clear.wgsl).
@group(1) @binding(1) var<storage, read> vertex_words: array<u32>;
// Three vertex indices a triangle (for the under-water soup: 0, 1, 2, ...).
@group(1) @binding(2) var<storage, read> triangle_vertices: array<u32>;

// Vertex invocations a triangle: its part inside the clip volume is a polygon of up to 8 corners
// (3 + one a clipping plane), drawn as a fan of up to 6 triangles
// (gpu::pulling::CORNERS_PER_TRIANGLE).
const CORNERS_PER_TRIANGLE: u32 = 18u;
const MAX_POLYGON: u32 = 8u;
// The rasteriser's subpixel grid (Mesa's llvmpipe: 8 bits).
const SUBPIXELS: f32 = 256.0;
// A corner of no triangle: outside the clip volume, so the triangle is dropped whole.
const NO_CORNER: vec4<f32> = vec4<f32>(2.0, 2.0, 2.0, 1.0);

// Word `word` of vertex `vertex` of a buffer of `stride` words a vertex.
fn vertex_word(vertex: u32, stride: u32, word: u32) -> u32 {
    return vertex_words[vertex * stride + word];
}
fn vertex_vec2(vertex: u32, stride: u32, word: u32) -> vec2<f32> {
    return bitcast<vec2<f32>>(vec2<u32>(vertex_word(vertex, stride, word), vertex_word(vertex, stride, word + 1u)));
}
fn vertex_vec3(vertex: u32, stride: u32, word: u32) -> vec3<f32> {
    return vec3<f32>(vertex_vec2(vertex, stride, word), bitcast<f32>(vertex_word(vertex, stride, word + 2u)));
}
// The indices of triangle `triangle`'s three vertices.
fn triangle_of(triangle: u32) -> vec3<u32> {
    return vec3<u32>(triangle_vertices[triangle * 3u], triangle_vertices[triangle * 3u + 1u], triangle_vertices[triangle * 3u + 2u]);
}
// The vertex indices of triangle `triangle` of a soup (three vertices each, in order).
fn soup_triangle(triangle: u32) -> vec3<u32> {
    return vec3<u32>(triangle * 3u) + vec3<u32>(0u, 1u, 2u);
}
// The attribute at word `word` of the vertices `corners` (of `stride` words each) weighted by
// `weights` (pulled_weights).
fn pulled3(weights: vec3<f32>, corners: vec3<u32>, stride: u32, word: u32) -> vec3<f32> {
    return vertex_vec3(corners.x, stride, word) * weights.x + vertex_vec3(corners.y, stride, word) * weights.y + vertex_vec3(corners.z, stride, word) * weights.z;
}
fn pulled1(weights: vec3<f32>, corners: vec3<u32>, stride: u32, word: u32) -> f32 {
    let values = bitcast<vec3<f32>>(vec3<u32>(vertex_word(corners.x, stride, word), vertex_word(corners.y, stride, word), vertex_word(corners.z, stride, word)));
    return dot(weights, values);
}

// Texture coordinates at a fragment, and their change to the next pixel right and down.
struct TextureCoordinates {
    at: vec2<f32>,
    right: vec2<f32>,
    down: vec2<f32>,
};

// The texture coordinates at word `word` of the vertices `corners` (of `stride` words each, the
// position drawn at words 0-2) at the fragment at `pixel`, which has the weights `weights`, and
// their change to the next pixel right and down, all interpolated at the whole frame's pixel
// centres. Not the GPU's derivatives: they difference the 2x2 quad's fragments, and Mesa's
// llvmpipe reads storage buffers as zero in a quad's helper fragments (outside the triangle), so
// every pixel on a triangle's edge took a far too coarse mip level.
fn pulled_texture_coordinates(pixel: vec2<f32>, weights: vec3<f32>, corners: vec3<u32>, stride: u32, word: u32) -> TextureCoordinates {
    let a = vertex_vec3(corners.x, stride, 0u);
    let b = vertex_vec3(corners.y, stride, 0u);
    let c = vertex_vec3(corners.z, stride, 0u);
    let uv_a = vertex_vec2(corners.x, stride, word);
    let uv_b = vertex_vec2(corners.y, stride, word);
    let uv_c = vertex_vec2(corners.z, stride, word);
    let right = pixel_weights(pixel + vec2<f32>(1.0, 0.0), a, b, c);
    let down = pixel_weights(pixel + vec2<f32>(0.0, 1.0), a, b, c);
    let at = uv_a * weights.x + uv_b * weights.y + uv_c * weights.z;
    // A supersampled frame's points are half a pixel apart: their change times 2 is the pixel's,
    // so textures take the level of the frame's pixel, as without supersampling (the texture's
    // mip chain filters what is finer than a pixel; the points filter the edges).
    let span = frame.viewport.z;
    return TextureCoordinates(
        at,
        (uv_a * right.x + uv_b * right.y + uv_c * right.z - at) * span,
        (uv_a * down.x + uv_b * down.y + uv_c * down.z - at) * span,
    );
}

// Corner `vertex_index % CORNERS_PER_TRIANGLE` (clipped_corner) of the triangle of vertices
// `corners` (of `stride` words each, the position drawn at words 0-2).
fn pulled_corner(vertex_index: u32, corners: vec3<u32>, stride: u32) -> vec4<f32> {
    let a = frame.clip_from_world * vec4<f32>(vertex_vec3(corners.x, stride, 0u), 1.0);
    let b = frame.clip_from_world * vec4<f32>(vertex_vec3(corners.y, stride, 0u), 1.0);
    let c = frame.clip_from_world * vec4<f32>(vertex_vec3(corners.z, stride, 0u), 1.0);
    return clipped_corner(a, b, c, vertex_index % CORNERS_PER_TRIANGLE);
}

// The weights (pixel_weights) of the triangle of vertices `corners` (of `stride` words each, the
// position drawn at words 0-2) at the fragment at `pixel`.
fn pulled_weights(pixel: vec2<f32>, corners: vec3<u32>, stride: u32) -> vec3<f32> {
    return pixel_weights(pixel, vertex_vec3(corners.x, stride, 0u), vertex_vec3(corners.y, stride, 0u), vertex_vec3(corners.z, stride, 0u));
}

// A clip position with w = 1 whose window position is `clip`'s in the whole frame, on the
// subpixel grid. The viewport (the frame's, moved up by a strip's first row) maps it to within a
// tiny float error of a grid point, which the rasteriser's round-to-nearest snap recovers: the
// same point of the frame in every strip. `clip` is inside the clip volume (clipped_corner), and
// so is the result, exactly: the GPU clips nothing. The depth buffer takes the fragment stage's
// depth (with_frame_depth); z here only has to be in [0, 1].
fn snapped_clip(clip: vec4<f32>) -> vec4<f32> {
    let ndc = clip.xyz / clip.w;
    let size = frame.viewport.xy;
    let window = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5) * size;
    let snapped = clamp(round(window * SUBPIXELS) / SUBPIXELS, vec2<f32>(0.0), size);
    return vec4<f32>(snapped.x / size.x * 2.0 - 1.0, 1.0 - snapped.y / size.y * 2.0, clamp(ndc.z, 0.0, 1.0), 1.0);
}

// How far clip position `p` is inside clipping plane `plane` (negative: outside): the near plane
// (z >= 0), then the frame's left, right, bottom and top sides.
fn plane_distance(p: vec4<f32>, plane: u32) -> f32 {
    switch plane {
        case 0u: { return p.z; }
        case 1u: { return p.w + p.x; }
        case 2u: { return p.w - p.x; }
        case 3u: { return p.w + p.y; }
        default: { return p.w - p.y; }
    }
}

// Corner `corner` (0 to CORNERS_PER_TRIANGLE - 1) of the part of triangle (a, b, c) (clip
// positions) inside the clip volume, clipped here (Sutherland-Hodgman, in clip space, so
// perspective-correctly) and drawn as the fan (0, f + 1, f + 2) of its polygon; corners of fan
// triangles the polygon lacks are NO_CORNER. Clipping is here, not in the GPU, because w = 1
// (snapped_clip) leaves the GPU nothing to clip perspective-correctly with, and because the GPU's
// clipped corners would be off the subpixel grid, where a strip's viewport rounds differently.
fn clipped_corner(a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, corner: u32) -> vec4<f32> {
    let fan = corner / 3u;
    let k = corner % 3u;
    let index = select(0u, fan + k, k > 0u);
    let sides_a = vec4<f32>(a.w + a.x, a.w - a.x, a.w + a.y, a.w - a.y);
    let sides_b = vec4<f32>(b.w + b.x, b.w - b.x, b.w + b.y, b.w - b.y);
    let sides_c = vec4<f32>(c.w + c.x, c.w - c.x, c.w + c.y, c.w - c.y);
    // Wholly outside one plane: nothing. Wholly inside every plane: the triangle itself.
    if (a.z < 0.0 && b.z < 0.0 && c.z < 0.0) || any((sides_a < vec4<f32>(0.0)) & (sides_b < vec4<f32>(0.0)) & (sides_c < vec4<f32>(0.0))) {
        return NO_CORNER;
    }
    if a.z >= 0.0 && b.z >= 0.0 && c.z >= 0.0 && all(min(min(sides_a, sides_b), sides_c) >= vec4<f32>(0.0)) {
        if corner >= 3u {
            return NO_CORNER;
        }
        var triangle = array<vec4<f32>, 3>(a, b, c);
        return snapped_clip(triangle[corner]);
    }
    var polygon: array<vec4<f32>, MAX_POLYGON>;
    polygon[0] = a;
    polygon[1] = b;
    polygon[2] = c;
    var count = 3u;
    for (var plane = 0u; plane < 5u; plane = plane + 1u) {
        var clipped: array<vec4<f32>, MAX_POLYGON>;
        var kept = 0u;
        for (var i = 0u; i < count; i = i + 1u) {
            let p = polygon[i];
            let q = polygon[(i + 1u) % count];
            let dp = plane_distance(p, plane);
            let dq = plane_distance(q, plane);
            if dp >= 0.0 && kept < MAX_POLYGON {
                clipped[kept] = p;
                kept = kept + 1u;
            }
            if (dp >= 0.0) != (dq >= 0.0) && kept < MAX_POLYGON {
                // From the inside end, so that the triangles on both sides of an edge make the
                // same point.
                var inside = p;
                var outside = q;
                var d_inside = dp;
                var d_outside = dq;
                if dp < 0.0 {
                    inside = q;
                    outside = p;
                    d_inside = dq;
                    d_outside = dp;
                }
                clipped[kept] = inside + (outside - inside) * (d_inside / (d_inside - d_outside));
                kept = kept + 1u;
            }
        }
        polygon = clipped;
        count = kept;
        if count < 3u {
            return NO_CORNER;
        }
    }
    if fan + 2u >= count {
        return NO_CORNER;
    }
    return snapped_clip(polygon[index]);
}

// Perspective-correct weights of a triangle's corners (a, b, c, world space, as drawn) at the
// fragment at `pixel` (@builtin(position).xy of a strip): where the eye's ray through the whole
// frame's pixel centre meets the triangle's plane (Moller-Trumbore). Finite always: an edge-on
// triangle gets equal weights.
fn pixel_weights(pixel: vec2<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let direction = ray_through_pixel(pixel);
    let ab = b - a;
    let ac = c - a;
    let p = cross(direction, ac);
    let det = dot(ab, p);
    let from_a = frame.eye.xyz - a;
    let u = dot(from_a, p) / det;
    let v = dot(direction, cross(from_a, ab)) / det;
    let weights = vec3<f32>(1.0 - u - v, u, v);
    if !all(abs(weights) < vec3<f32>(1e6)) {
        return vec3<f32>(1.0 / 3.0);
    }
    return weights;
}

// Targets of a pulled draw: the main pass's, and the fragment's depth computed from the whole
// frame's pixel (frame_depth), not the rasteriser's, whose plane equation starts at the
// attachment's origin: where two surfaces meet (the membrane at a wall), the depth test then
// keeps the same one in every strip.
struct DepthTargets {
    @location(0) beauty: vec4<f32>,
    @location(1) position: vec4<u32>,
    @location(2) flags: u32,
    @location(3) reflection: vec4<u32>,
    @location(4) extra: vec4<u32>,
    @builtin(frag_depth) depth: f32,
};

// The depth buffer's value (clip z / w) of world point `drawn_position`, as rasterised.
fn with_frame_depth(targets: Targets, drawn_position: vec3<f32>) -> DepthTargets {
    let clip = frame.clip_from_world * vec4<f32>(drawn_position, 1.0);
    return DepthTargets(targets.beauty, targets.position, targets.flags, targets.reflection, targets.extra, clamp(clip.z / clip.w, 0.0, 1.0));
}
