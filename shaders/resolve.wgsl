// The resolve pass of a supersampled frame (gpu::resolve): from the supersampled targets (the
// whole frame drawn on a grid of half-pixel spacing whose points are every pixel's corners, edge
// midpoints and centre: 2W + 1 by 2H + 1 points) to the frame's own targets, read back. A
// full-screen triangle; pixel (x, y) of a strip reads the 3 x 3 points (2x + i, 2y + j) of the
// strip's supersampled targets, its centre at (2x + 1, 2y + 1).
// - Beauty and reflection: the box filter over the pixel, integrated by the trapezoid rule on its
//   3 x 3 points (weights 1/16 at the corners, 1/8 at the edge midpoints, 1/4 at the centre; the
//   corners and edges are shared with the neighbours, so 4 points a pixel are drawn). Pass d has
//   blended the membrane's reflection over each point already; the reflection is 0 at points off
//   the water, so the SkyReflection layer is the reflected share of the filtered beauty.
// - Position, flags and the extra target: the centre point's, the pixel centre exactly (motion
//   halved: the points are half pixels), and in extra.z the centre's coverage word.
// - Coverage: one word per point for the Cryptomatte (gpu::readback): object + 1 in bits 16-31,
//   bit 15 where the water is the first surface, Schlick's F as a 15-bit fraction in bits 0-14;
//   the corners in `corners` (xyzw: top left, top right, bottom left, bottom right), the edge
//   midpoints in `edges` (top, left, right, bottom).

// Group 0 after the prelude's bindings (0-3, not used here): the resolve pass's only group.
@group(0) @binding(4) var points_beauty: texture_2d<f32>;
@group(0) @binding(5) var points_position: texture_2d<u32>;
@group(0) @binding(6) var points_flags: texture_2d<u32>;
@group(0) @binding(7) var points_reflection: texture_2d<u32>;
@group(0) @binding(8) var points_extra: texture_2d<u32>;

const COVERAGE_WATER_BIT: u32 = 0x8000u;
const COVERAGE_F_SCALE: f32 = 32767.0;

struct ResolvedTargets {
    @location(0) beauty: vec4<f32>,
    @location(1) position: vec4<u32>,
    @location(2) flags: u32,
    @location(3) reflection: vec4<u32>,
    @location(4) extra: vec4<u32>,
    @location(5) corners: vec4<u32>,
    @location(6) edges: vec4<u32>,
};

@vertex
fn vs_resolve(@builtin(vertex_index) vertex_index: u32) -> @builtin(position) vec4<f32> {
    return full_screen_position(vertex_index, 0.0);
}

// A point's beauty, reflection and coverage word.
struct Point {
    beauty: vec3<f32>,
    reflection: vec4<f32>,
    word: u32,
};

fn point_at(at: vec2<i32>) -> Point {
    let flags = textureLoad(points_flags, at, 0).x;
    var point: Point;
    point.beauty = textureLoad(points_beauty, at, 0).xyz;
    point.reflection = vec4<f32>(0.0);
    var reflectance = 0.0;
    let water = (flags & WATER_BIT) != 0u;
    if water {
        point.reflection = bitcast<vec4<f32>>(textureLoad(points_reflection, at, 0));
        reflectance = point.reflection.w;
    }
    point.word = ((flags >> OBJECT_SHIFT) << 16u) | select(0u, COVERAGE_WATER_BIT, water)
        | u32(round(clamp(reflectance, 0.0, 1.0) * COVERAGE_F_SCALE));
    return point;
}

@fragment
fn fs_resolve(@builtin(position) pixel: vec4<f32>) -> ResolvedTargets {
    let corner = vec2<i32>(pixel.xy) * 2;
    var beauty = vec3<f32>(0.0);
    var reflection = vec4<f32>(0.0);
    var words: array<u32, 9>;
    for (var j = 0; j < 3; j = j + 1) {
        for (var i = 0; i < 3; i = i + 1) {
            let point = point_at(corner + vec2<i32>(i, j));
            let weight = select(1.0, 2.0, i == 1) * select(1.0, 2.0, j == 1) / 16.0;
            beauty = beauty + weight * point.beauty;
            reflection = reflection + weight * point.reflection;
            words[j * 3 + i] = point.word;
        }
    }
    let centre = corner + vec2<i32>(1, 1);
    var out: ResolvedTargets;
    out.beauty = vec4<f32>(min(beauty, vec3<f32>(RADIANCE_MAX)), 1.0);
    out.position = textureLoad(points_position, centre, 0);
    out.flags = textureLoad(points_flags, centre, 0).x;
    out.reflection = bitcast<vec4<u32>>(reflection);
    let extra = textureLoad(points_extra, centre, 0);
    let motion = bitcast<vec2<f32>>(extra.xy) * 0.5;
    out.extra = vec4<u32>(bitcast<vec2<u32>>(motion), words[4], extra.w);
    out.corners = vec4<u32>(words[0], words[2], words[6], words[8]);
    out.edges = vec4<u32>(words[1], words[3], words[5], words[7]);
    return out;
}
