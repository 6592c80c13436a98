// Pass b (after the membrane): the sky on a full-screen triangle at the far plane. Sky has no
// position (0) and the depth SKY_DEPTH_M.

@vertex
fn vs_sky(@builtin(vertex_index) vertex_index: u32) -> @builtin(position) vec4<f32> {
    return full_screen_position(vertex_index, 1.0);
}

@fragment
fn fs_sky(@builtin(position) pixel: vec4<f32>) -> Targets {
    var out: Targets;
    out.beauty = vec4<f32>(sky_radiance(ray_through_pixel(pixel.xy)), 1.0);
    out.position = vec4<u32>(0u, 0u, 0u, bitcast<u32>(SKY_DEPTH_M));
    out.flags = 0u;
    out.extra = vec4<u32>(0u, 0u, 0u, bitcast<u32>(SKY_DEPTH_M));
    return out;
}
