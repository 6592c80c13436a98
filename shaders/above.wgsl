// Pass a: geometry on the eye's side of the water, drawn at its true positions, depth-tested.
// Pulled (common.inc.wgsl): crate::draw::TrueVertex is 12 words: position 0-2, previous position
// 3-5, normal 6-8, uv 9-10, material 11.

const TRUE_VERTEX_WORDS: u32 = 12u;

struct AboveVarying {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat, either) triangle: u32,
};

@vertex
fn vs_above(@builtin(vertex_index) vertex_index: u32) -> AboveVarying {
    let triangle = vertex_index / CORNERS_PER_TRIANGLE;
    let corners = triangle_of(triangle);
    let clip = array<vec4<f32>, 3>(
        frame.clip_from_world * vec4<f32>(vertex_vec3(corners.x, TRUE_VERTEX_WORDS, 0u), 1.0),
        frame.clip_from_world * vec4<f32>(vertex_vec3(corners.y, TRUE_VERTEX_WORDS, 0u), 1.0),
        frame.clip_from_world * vec4<f32>(vertex_vec3(corners.z, TRUE_VERTEX_WORDS, 0u), 1.0),
    );
    var out: AboveVarying;
    out.clip = clipped_corner(clip[0], clip[1], clip[2], vertex_index % CORNERS_PER_TRIANGLE);
    out.triangle = triangle;
    return out;
}

@fragment
fn fs_above(in: AboveVarying) -> DepthTargets {
    let corners = triangle_of(in.triangle);
    let a = corners.x;
    let b = corners.y;
    let c = corners.z;
    let s = TRUE_VERTEX_WORDS;
    let world_a = vertex_vec3(a, s, 0u);
    let world_b = vertex_vec3(b, s, 0u);
    let world_c = vertex_vec3(c, s, 0u);
    let weights = pixel_weights(in.clip.xy, world_a, world_b, world_c);
    let world_position = weighted3(weights, world_a, world_b, world_c);
    let previous_position = weighted3(weights, vertex_vec3(a, s, 3u), vertex_vec3(b, s, 3u), vertex_vec3(c, s, 3u));
    let normal = normalize(weighted3(weights, vertex_vec3(a, s, 6u), vertex_vec3(b, s, 6u), vertex_vec3(c, s, 6u)));
    let uv = weighted2(weights, vertex_vec2(a, s, 9u), vertex_vec2(b, s, 9u), vertex_vec2(c, s, 9u));
    // The provoking (first) vertex's material, as a flat attribute had it.
    let material = vertex_word(a, s, 11u);
    var out: Targets;
    out.beauty = vec4<f32>(shade_above(albedo(material, uv), normal), 1.0);
    let depth_m = view_depth(world_position);
    out.position = vec4<u32>(bitcast<vec3<u32>>(world_position), bitcast<u32>(depth_m));
    out.flags = flags_and_object(0u, material);
    let clip_now = frame.clip_from_world * vec4<f32>(world_position, 1.0);
    let clip_before = frame.previous_clip_from_world * vec4<f32>(previous_position, 1.0);
    let motion = motion_px(clip_now, clip_before);
    out.extra = vec4<u32>(bitcast<vec2<u32>>(motion), 0u, bitcast<u32>(depth_m));
    return with_frame_depth(out, world_position);
}
