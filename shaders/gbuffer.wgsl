// Stage one: the G-buffer pass (thesis 8.2, NPAR §9). Terrain and instanced plant parts are
// drawn with one pipeline; each fragment writes albedo, world normal, linear view depth and an
// object/patch ID that the post passes read.

struct Frame {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    camera_pos: vec4<f32>,
};

struct Material {
    base_color: vec4<f32>,
    // x: alpha cutoff (< 0: opaque), y: part kind (0 terrain, 1 wood, 2 foliage)
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<uniform> material: Material;
@group(1) @binding(1) var base_tex: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    // per instance: xyz position, w uniform scale
    @location(3) offset_scale: vec4<f32>,
    // per instance: cos and sin of the rotation about z
    @location(4) rotation: vec2<f32>,
    @location(5) object_id: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) view_depth: f32,
    @location(3) @interpolate(flat) object_id: u32,
};

fn rotate_z(v: vec3<f32>, cs: vec2<f32>) -> vec3<f32> {
    return vec3<f32>(cs.x * v.x - cs.y * v.y, cs.y * v.x + cs.x * v.y, v.z);
}

@vertex
fn vs_main(in: VertexIn) -> VertexOut {
    let world = rotate_z(in.position * in.offset_scale.w, in.rotation) + in.offset_scale.xyz;
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = rotate_z(in.normal, in.rotation);
    out.uv = in.uv;
    // Linear depth along the view axis, in metres (view space looks down -z).
    out.view_depth = -(frame.view * vec4<f32>(world, 1.0)).z;
    out.object_id = in.object_id;
    return out;
}

struct GBuffer {
    @location(0) albedo: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) depth: f32,
    @location(3) id: u32,
};

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> GBuffer {
    let texel = textureSample(base_tex, base_sampler, in.uv) * material.base_color;
    if material.params.x >= 0.0 && texel.a < material.params.x {
        discard;
    }
    var n = normalize(in.normal);
    if !front {
        n = -n;
    }
    var out: GBuffer;
    out.albedo = vec4<f32>(texel.rgb, 1.0);
    out.normal = vec4<f32>(n, material.params.y);
    out.depth = in.view_depth;
    out.id = in.object_id;
    return out;
}
