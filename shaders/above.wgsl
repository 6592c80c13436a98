// Pass a: geometry on the eye's side of the water, drawn at its true positions, depth-tested.

struct AboveVertex {
    @location(0) position: vec3<f32>,
    @location(1) previous_position: vec3<f32>,
    @location(2) normal: vec3<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) material: u32,
};

struct AboveVarying {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat, either) material: u32,
    // The clip position now and at t-1 (motion vectors), interpolated perspective-correctly.
    @location(4) clip_now: vec4<f32>,
    @location(5) clip_before: vec4<f32>,
};

@vertex
fn vs_above(vertex: AboveVertex) -> AboveVarying {
    var out: AboveVarying;
    out.clip = frame.clip_from_world * vec4<f32>(vertex.position, 1.0);
    out.world_position = vertex.position;
    out.normal = vertex.normal;
    out.uv = vertex.uv;
    out.material = vertex.material;
    out.clip_now = out.clip;
    out.clip_before = frame.previous_clip_from_world * vec4<f32>(vertex.previous_position, 1.0);
    return out;
}

@fragment
fn fs_above(in: AboveVarying) -> Targets {
    let normal = normalize(in.normal);
    var out: Targets;
    out.beauty = vec4<f32>(shade_above(albedo(in.material, in.uv), normal), 1.0);
    let depth_m = view_depth(in.world_position);
    out.position = vec4<u32>(bitcast<vec3<u32>>(in.world_position), bitcast<u32>(depth_m));
    out.flags = flags_and_object(0u, in.material);
    let motion = motion_px(in.clip_now, in.clip_before);
    out.extra = vec4<u32>(bitcast<vec2<u32>>(motion), 0u, bitcast<u32>(depth_m));
    return out;
}
