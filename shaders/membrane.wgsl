// Pass b: the water membrane, drawn once, depth-tested against the geometry above water and
// writing depth, so that the last fragment written in each pixel is the front-most visible one.
// It marks the stencil, writes its depth (position.w) and keeps its sky reflection by
// Schlick's F with the sun's glint, premultiplied, in the reflection target:
// (F * sky(reflect(I, N)) + glint, F) (water_reflection). Pass d
// (shaders/water_clear.wgsl) blends that over the refracted image:
// out = F * sky(reflect(I, N)) + (1 - F) * dst, by blend One / OneMinusSrcAlpha with src.a = F.
// Pulled (common.inc.wgsl): crate::draw::MembraneVertex is 6 words: position 0-2, normal 3-5.

const MEMBRANE_VERTEX_WORDS: u32 = 6u;

struct MembraneVarying {
    // Invariant: the rasterised depth must not depend on what the fragment stage reads.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) @interpolate(flat, either) triangle: u32,
};

@vertex
fn vs_membrane(@builtin(vertex_index) vertex_index: u32) -> MembraneVarying {
    var out: MembraneVarying;
    out.triangle = vertex_index / CORNERS_PER_TRIANGLE;
    out.clip = pulled_corner(vertex_index, triangle_of(out.triangle), MEMBRANE_VERTEX_WORDS);
    return out;
}

@fragment
fn fs_membrane(in: MembraneVarying) -> DepthTargets {
    let corners = triangle_of(in.triangle);
    let s = MEMBRANE_VERTEX_WORDS;
    let weights = pulled_weights(in.clip.xy, corners, s);
    let world_position = pulled3(weights, corners, s, 0u);
    let normal = normalize(pulled3(weights, corners, s, 3u));
    let to_surface = world_position - frame.eye.xyz;
    let distance_m = length(to_surface);
    let incident = to_surface / distance_m;
    var out: Targets;
    // Only w (the membrane's depth along the view axis) and the reflection are written: beauty
    // and xyz are the under-water image's, drawn after this.
    out.position = vec4<u32>(0u, 0u, 0u, bitcast<u32>(view_depth(world_position)));
    out.reflection = bitcast<vec4<u32>>(water_reflection(incident, normal));
    return with_frame_depth(out, world_position);
}
