// Billboard baking (SPEC P4, thesis 7): plant geometry drawn with an orthographic camera per
// atlas tile, writing the textured albedo and coverage the billboard levels of detail show.
// The shading normal of a billboard is not baked: the G-buffer pass derives it from the HLP
// sphere (thesis eq. 4.7), so only colour and alpha are needed here.

// The block `material` (`render::gbuffer::SurfaceMaterial`) is declared ahead of this file.

// One world → clip matrix per tile, indexed by the draw's instance index.
@group(0) @binding(0) var<storage, read> tiles: array<mat4x4<f32>>;
@group(1) @binding(0) var<uniform> material: SurfaceMaterial;
@group(1) @binding(1) var base_tex: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_bake(@location(0) position: vec3<f32>, @location(2) uv: vec2<f32>, @builtin(instance_index) tile: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = tiles[tile] * vec4<f32>(position, 1.0);
    out.uv = uv;
    return out;
}

@fragment
fn fs_bake(in: VertexOut) -> @location(0) vec4<f32> {
    let texel = textureSample(base_tex, base_sampler, in.uv) * material.base_color;
    if material.alpha_cutoff >= 0.0 && texel.a < material.alpha_cutoff {
        discard;
    }
    return vec4<f32>(texel.rgb, 1.0);
}
