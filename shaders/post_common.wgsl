// Style parameters shared by the post-processing passes (mirrors `render::style::PostParams`).

struct Post {
    // x: contour scale c, y: contour threshold t (thesis eq. 5.1),
    // z: isolated-pixel threshold t' (eq. 5.2), w: isolated-pixel removal on (1) / off (0)
    contour: vec4<f32>,
    // xyz: direction towards the sun (world), w: ambient light
    light: vec4<f32>,
    // x: albedo weight, y: tone contrast, z: tone reference, w: contour ink strength
    tone: vec4<f32>,
    // x: hatch spacing (px), y: maximum line width (px), z: hatch angle (radians), w: tone band width
    hatch: vec4<f32>,
    // tone thresholds below which hatch layers 1..4 appear
    hatch_levels: vec4<f32>,
    ink: vec4<f32>,
    paper: vec4<f32>,
};

@group(0) @binding(0) var<uniform> post: Post;

fn clamp_coord(p: vec2<i32>) -> vec2<i32> {
    return clamp(p, vec2<i32>(0), vec2<i32>(textureDimensions(depth_tex)) - 1);
}
