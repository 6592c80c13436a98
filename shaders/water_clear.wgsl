// Pass c (first draw) and the depth reset before pass d: full-screen triangles that act only inside
// the membrane stencil. `fs_deep_water` "clears" to what a fully absorbed path shows; the depth
// reset masks every colour write off and only pushes depth back to the far plane.

@vertex
fn vs_far(@builtin(vertex_index) vertex_index: u32) -> @builtin(position) vec4<f32> {
    return full_screen_position(vertex_index, 1.0);
}

@fragment
fn fs_deep_water(@builtin(position) pixel: vec4<f32>) -> Targets {
    var out: Targets;
    out.beauty = vec4<f32>(frame.scatter_color.xyz, 1.0);
    // Nothing behind the water here: no true position (w is masked off; pass d writes it).
    out.position = vec4<u32>(NAN_BITS, NAN_BITS, NAN_BITS, 0u);
    out.flags = 0u;
    return out;
}

@fragment
fn fs_depth_only(@builtin(position) pixel: vec4<f32>) -> Targets {
    var out: Targets;
    out.beauty = vec4<f32>(0.0);
    out.position = vec4<u32>(0u);
    out.flags = 0u;
    return out;
}
