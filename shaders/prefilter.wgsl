// Post pass 0 (optional): selective-dilation pre-filter of the depth buffer (thesis eq. 5.4).

// Thesis eq. 5.3–5.4: dilate (take the nearest depth of the 3x3 neighbourhood) only where more
// than half of the neighbours are nearer than the neighbourhood's average, i.e. at isolated
// holes, not along clean object boundaries.
@fragment
fn fs_prefilter(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    let size = textureDimensions(depth_tex);
    var d: array<f32, 9>;
    var sum = 0.0;
    var nearest = 3.4e38;
    for (var i = 0; i < 9; i++) {
        let q = clamp_coord(p + vec2<i32>(i % 3 - 1, i / 3 - 1), size);
        d[i] = textureLoad(depth_tex, q, 0).r;
        sum += d[i];
        nearest = min(nearest, d[i]);
    }
    let average = sum / 9.0;
    var nearer = 0;
    for (var i = 0; i < 9; i++) {
        if i != 4 && d[i] < average {
            nearer++;
        }
    }
    return vec4<f32>(select(d[4], nearest, nearer > 4), 0.0, 0.0, 1.0);
}
