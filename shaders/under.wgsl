// Pass c: under-water geometry rasterised at its VIRTUAL positions, shaded with its TRUE
// attributes, attenuated along the true water path; writes the true position and the flags.

struct UnderVertex {
    @location(0) virtual_position: vec3<f32>,
    @location(1) previous_position: vec3<f32>,
    @location(2) true_position: vec3<f32>,
    @location(3) normal: vec3<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) material: u32,
    @location(6) water_path_m: f32,
    @location(7) flags: u32,
};

struct UnderVarying {
    @builtin(position) clip: vec4<f32>,
    @location(0) true_position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) water_path_m: f32,
    @location(4) @interpolate(flat, either) material: u32,
    @location(5) @interpolate(flat, either) flags: u32,
    // Depth along the view axis of the virtual position (affine in world space, so perspective-
    // correct interpolation gives the virtual surface's depth exactly).
    @location(6) apparent_depth_m: f32,
    // The clip position of the virtual vertex now and of t-1's virtual vertex through t-1's
    // camera (motion vectors).
    @location(7) clip_now: vec4<f32>,
    @location(8) clip_before: vec4<f32>,
};

@vertex
fn vs_under(vertex: UnderVertex) -> UnderVarying {
    var out: UnderVarying;
    out.clip = frame.clip_from_world * vec4<f32>(vertex.virtual_position, 1.0);
    out.true_position = vertex.true_position;
    out.normal = vertex.normal;
    out.uv = vertex.uv;
    out.water_path_m = vertex.water_path_m;
    out.material = vertex.material;
    out.flags = vertex.flags;
    out.apparent_depth_m = view_depth(vertex.virtual_position);
    out.clip_now = out.clip;
    out.clip_before = frame.previous_clip_from_world * vec4<f32>(vertex.previous_position, 1.0);
    return out;
}

@fragment
fn fs_under(in: UnderVarying) -> Targets {
    let normal = normalize(in.normal);
    let colour = shade_under(albedo(in.material, in.uv), normal, in.true_position, max(in.water_path_m, 0.0));
    var out: Targets;
    out.beauty = vec4<f32>(colour, 1.0);
    // w is masked off: the depth is the membrane's, written by pass b.
    out.position = vec4<u32>(bitcast<vec3<u32>>(in.true_position), 0u);
    out.flags = flags_and_object(in.flags, in.material) | WATER_BIT;
    let motion = motion_px(in.clip_now, in.clip_before);
    out.extra = vec4<u32>(bitcast<vec2<u32>>(motion), 0u, bitcast<u32>(in.apparent_depth_m));
    return out;
}
