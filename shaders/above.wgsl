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
    var out: AboveVarying;
    out.triangle = vertex_index / CORNERS_PER_TRIANGLE;
    out.clip = pulled_corner(vertex_index, triangle_of(out.triangle), TRUE_VERTEX_WORDS);
    return out;
}

@fragment
fn fs_above(in: AboveVarying) -> DepthTargets {
    let corners = triangle_of(in.triangle);
    let s = TRUE_VERTEX_WORDS;
    let weights = pulled_weights(in.clip.xy, corners, s);
    let world_position = pulled3(weights, corners, s, 0u);
    let previous_position = pulled3(weights, corners, s, 3u);
    let normal = normalize(pulled3(weights, corners, s, 6u));
    let uv = pulled_texture_coordinates(in.clip.xy, weights, corners, s, 9u);
    // The provoking (first) vertex's material, as a flat attribute had it.
    let material = vertex_word(corners.x, s, 11u);
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
