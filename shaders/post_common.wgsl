// Style parameters shared by the post-processing passes (mirrors `render::style::PostParams`).

struct Post {
    // x: contour scale c, y: contour threshold t (thesis eq. 5.1),
    // z: isolated-pixel threshold t' (eq. 5.2), w: isolated-pixel removal on (1) / off (0)
    contour: vec4<f32>,
    // xyz: direction towards the sun (world), w: ambient light
    light: vec4<f32>,
    // x: albedo weight, y: contrast scale, z: reference L_ref (eq. 6.7), w: contour strength
    tone: vec4<f32>,
    // x: tone bands (0 = continuous), y: tone blur radius (px), z: TAM tone levels, w: TAM size
    tone2: vec4<f32>,
    // x: silhouette support (px), y: SAM stretch c (eq. 5.5), z: silhouette strength
    silhouette: vec4<f32>,
    // x: hatch strength, y: cos(roll), z: sin(roll)
    hatch: vec4<f32>,
    ink: vec4<f32>,
    paper: vec4<f32>,
};

@group(0) @binding(0) var<uniform> post: Post;

fn clamp_coord(p: vec2<i32>, size: vec2<u32>) -> vec2<i32> {
    return clamp(p, vec2<i32>(0), vec2<i32>(size) - 1);
}
