// Pass c: under-water geometry rasterised at its VIRTUAL positions, shaded with its TRUE
// attributes, attenuated along the true water path; writes the true position and the flags.
// Pulled (common.inc.wgsl): crate::draw::VirtualVertex is 17 words: virtual position 0-2,
// previous (virtual) position 3-5, true position 6-8, normal 9-11, uv 12-13, material 14, water
// path 15, flags 16. The list is a triangle soup: triangle t is vertices 3t, 3t + 1, 3t + 2.

const VIRTUAL_VERTEX_WORDS: u32 = 17u;

struct UnderVarying {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat, either) triangle: u32,
};

@vertex
fn vs_under(@builtin(vertex_index) vertex_index: u32) -> UnderVarying {
    var out: UnderVarying;
    out.triangle = vertex_index / CORNERS_PER_TRIANGLE;
    out.clip = pulled_corner(vertex_index, soup_triangle(out.triangle), VIRTUAL_VERTEX_WORDS);
    return out;
}

@fragment
fn fs_under(in: UnderVarying) -> DepthTargets {
    let corners = soup_triangle(in.triangle);
    let s = VIRTUAL_VERTEX_WORDS;
    // Weights on the virtual triangle, the one rasterised: the attributes vary over it as the
    // GPU's perspective-correct interpolation would vary them.
    let weights = pulled_weights(in.clip.xy, corners, s);
    let virtual_position = pulled3(weights, corners, s, 0u);
    let previous_position = pulled3(weights, corners, s, 3u);
    let true_position = pulled3(weights, corners, s, 6u);
    let normal = normalize(pulled3(weights, corners, s, 9u));
    let uv = pulled_texture_coordinates(in.clip.xy, weights, corners, s, 12u);
    let water_path_m = pulled1(weights, corners, s, 15u);
    // The provoking (first) vertex's material and flags, as flat attributes had them.
    let material = vertex_word(corners.x, s, 14u);
    let flags = vertex_word(corners.x, s, 16u);
    let colour = shade_under(albedo(material, uv), normal, true_position, max(water_path_m, 0.0));
    var out: Targets;
    out.beauty = vec4<f32>(colour, 1.0);
    // w is masked off: the depth is the membrane's, written by pass b.
    out.position = vec4<u32>(bitcast<vec3<u32>>(true_position), 0u);
    out.flags = flags_and_object(flags, material) | WATER_BIT;
    // The virtual surface's depth along the view axis (the apparent depth).
    let apparent_depth_m = view_depth(virtual_position);
    let clip_now = frame.clip_from_world * vec4<f32>(virtual_position, 1.0);
    let clip_before = frame.previous_clip_from_world * vec4<f32>(previous_position, 1.0);
    let motion = motion_px(clip_now, clip_before);
    out.extra = vec4<u32>(bitcast<vec2<u32>>(motion), 0u, bitcast<u32>(apparent_depth_m));
    return with_frame_depth(out, virtual_position);
}
