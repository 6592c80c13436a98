// Pass b: the water membrane, drawn once, depth-tested against the geometry above water and
// writing depth, so that the last fragment written in each pixel is the front-most visible one.
// It marks the stencil, writes its depth (position.w) and keeps its sky reflection by
// Schlick's F, premultiplied, in the reflection target: (F * sky(reflect(I, N)), F). Pass d
// (shaders/water_clear.wgsl) blends that over the refracted image:
// out = F * sky(reflect(I, N)) + (1 - F) * dst, by blend One / OneMinusSrcAlpha with src.a = F.

struct MembraneVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

struct MembraneVarying {
    // Invariant: the rasterised depth must not depend on what the fragment stage reads.
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
fn fs_membrane(in: MembraneVarying) -> Targets {
    let normal = normalize(in.normal);
    let to_surface = in.world_position - frame.eye.xyz;
    let distance_m = length(to_surface);
    let incident = to_surface / distance_m;
    let reflectance = schlick_reflectance(incident, normal);
    let reflected = reflect(incident, normal);
    var out: Targets;
    // Only w (the membrane's depth along the view axis) and the reflection are written: beauty
    // and xyz are the under-water image's, drawn after this.
    out.position = vec4<u32>(0u, 0u, 0u, bitcast<u32>(view_depth(in.world_position)));
    out.reflection = bitcast<vec4<u32>>(vec4<f32>(reflectance * sky_radiance(reflected), reflectance));
    return out;
}
