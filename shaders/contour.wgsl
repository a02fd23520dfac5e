// Post pass 1: image-space contours from linear depth (thesis 5.1).

@group(0) @binding(1) var depth_tex: texture_2d<f32>;

// Thesis eq. 5.1: p0 = max_i sat((d_i - d0) c - t) over the 3x3 neighbourhood, with signed
// differences so that contours are one pixel wide and lie on the nearer surface. Depths are
// taken relative to d0 (d_i / d0 - 1) so one threshold works from the foreground to the horizon.
@fragment
fn fs_contour(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    let d0 = textureLoad(depth_tex, p, 0).r;
    var edge = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let di = textureLoad(depth_tex, clamp_coord(p + vec2<i32>(dx, dy)), 0).r;
            edge = max(edge, saturate((di / d0 - 1.0) * post.contour.x - post.contour.y));
        }
    }
    return vec4<f32>(edge, 0.0, 0.0, 1.0);
}
