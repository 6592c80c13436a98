// Pass c (first draw) and pass d: full-screen triangles that act only inside the membrane stencil.
// `fs_deep_water` "clears" to what a fully absorbed path shows and pushes depth back to the far
// plane; `fs_reflection` blends the membrane's reflection over the refracted image.

@vertex
fn vs_far(@builtin(vertex_index) vertex_index: u32) -> @builtin(position) vec4<f32> {
    return full_screen_position(vertex_index, 1.0);
}

@fragment
fn fs_deep_water(@builtin(position) pixel: vec4<f32>) -> Targets {
    var out: Targets;
    out.beauty = vec4<f32>(frame.scatter_color.xyz, 1.0);
    // Nothing behind the water here: no true position (w is masked off: the membrane's depth,
    // written by pass b), nothing seen (apparent depth), but the water.
    out.position = vec4<u32>(0u, 0u, 0u, 0u);
    out.flags = WATER_BIT;
    out.extra = vec4<u32>(0u, 0u, 0u, bitcast<u32>(SKY_DEPTH_M));
    return out;
}

// Pass d, in a render pass of its own: the membrane's reflection (pass b) blended over the
// refracted image wherever the membrane is visible (inside the stencil).
@group(1) @binding(0) var reflection_texture: texture_2d<u32>;

// The targets of pass d's render pass: the main pass's, without the reflection it reads.
struct ResolveTargets {
    @location(0) beauty: vec4<f32>,
    @location(1) position: vec4<u32>,
    @location(2) flags: u32,
};

@fragment
fn fs_reflection(@builtin(position) pixel: vec4<f32>) -> ResolveTargets {
    var out: ResolveTargets;
    out.beauty = bitcast<vec4<f32>>(textureLoad(reflection_texture, vec2<i32>(pixel.xy), 0));
    return out;
}
