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
    let triangle = vertex_index / CORNERS_PER_TRIANGLE;
    let first = triangle * 3u;
    let s = VIRTUAL_VERTEX_WORDS;
    let clip = array<vec4<f32>, 3>(
        frame.clip_from_world * vec4<f32>(vertex_vec3(first, s, 0u), 1.0),
        frame.clip_from_world * vec4<f32>(vertex_vec3(first + 1u, s, 0u), 1.0),
        frame.clip_from_world * vec4<f32>(vertex_vec3(first + 2u, s, 0u), 1.0),
    );
    var out: UnderVarying;
    out.clip = clipped_corner(clip[0], clip[1], clip[2], vertex_index % CORNERS_PER_TRIANGLE);
    out.triangle = triangle;
    return out;
}

@fragment
fn fs_under(in: UnderVarying) -> DepthTargets {
    let a = in.triangle * 3u;
    let b = a + 1u;
    let c = a + 2u;
    let s = VIRTUAL_VERTEX_WORDS;
    let virtual_a = vertex_vec3(a, s, 0u);
    let virtual_b = vertex_vec3(b, s, 0u);
    let virtual_c = vertex_vec3(c, s, 0u);
    // Weights on the virtual triangle, the one rasterised: the attributes vary over it as the
    // GPU's perspective-correct interpolation would vary them.
    let weights = pixel_weights(in.clip.xy, virtual_a, virtual_b, virtual_c);
    let virtual_position = weighted3(weights, virtual_a, virtual_b, virtual_c);
    let previous_position = weighted3(weights, vertex_vec3(a, s, 3u), vertex_vec3(b, s, 3u), vertex_vec3(c, s, 3u));
    let true_position = weighted3(weights, vertex_vec3(a, s, 6u), vertex_vec3(b, s, 6u), vertex_vec3(c, s, 6u));
    let normal = normalize(weighted3(weights, vertex_vec3(a, s, 9u), vertex_vec3(b, s, 9u), vertex_vec3(c, s, 9u)));
    let uv = weighted2(weights, vertex_vec2(a, s, 12u), vertex_vec2(b, s, 12u), vertex_vec2(c, s, 12u));
    let water_path_m = weighted1(
        weights,
        bitcast<f32>(vertex_word(a, s, 15u)),
        bitcast<f32>(vertex_word(b, s, 15u)),
        bitcast<f32>(vertex_word(c, s, 15u)),
    );
    // The provoking (first) vertex's material and flags, as flat attributes had them.
    let material = vertex_word(a, s, 14u);
    let flags = vertex_word(a, s, 16u);
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
