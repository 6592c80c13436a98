// Passes b and d: the water membrane. `fs_mark` only feeds the depth/stencil state (pass b, and
// the depth-only redraw that finds the front-most membrane fragment before pass d); `fs_fresnel`
// blends the sky reflection over the refracted image by Schlick's F (pass d):
// out = F * sky(reflect(I, N)) + (1 - F) * dst, by blend One / OneMinusSrcAlpha with src.a = F.

struct MembraneVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

struct MembraneVarying {
    // Invariant: the depth-only redraw and the Fresnel pass compare depths for equality.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) world_position: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

@vertex
fn vs_membrane(vertex: MembraneVertex) -> MembraneVarying {
    var out: MembraneVarying;
    out.clip = frame.clip_from_world * vec4<f32>(vertex.position, 1.0);
    out.world_position = vertex.position;
    out.normal = vertex.normal;
    return out;
}

@fragment
fn fs_mark(in: MembraneVarying) -> Targets {
    // Every colour write is masked off in the pipelines using this entry point.
    var out: Targets;
    out.beauty = vec4<f32>(0.0);
    out.position = vec4<u32>(0u);
    out.flags = 0u;
    return out;
}

@fragment
fn fs_fresnel(in: MembraneVarying) -> Targets {
    let normal = normalize(in.normal);
    let to_surface = in.world_position - frame.eye.xyz;
    let distance_m = length(to_surface);
    let incident = to_surface / distance_m;
    let reflectance = schlick_reflectance(incident, normal);
    let reflected = reflect(incident, normal);
    var out: Targets;
    out.beauty = vec4<f32>(reflectance * sky_radiance(reflected), reflectance);
    // Only w (the distance to the membrane) is written: xyz keep the under-water true position.
    out.position = vec4<u32>(0u, 0u, 0u, bitcast<u32>(distance_m));
    out.flags = 0u;
    return out;
}
