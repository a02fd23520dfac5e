// Post pass 2: isolated-pixel removal (thesis eq. 5.2), Lambert tone, simple screen-space
// hatching, composited with the contours on paper.

@group(0) @binding(1) var depth_tex: texture_2d<f32>;
@group(0) @binding(2) var contour_tex: texture_2d<f32>;
@group(0) @binding(3) var albedo_tex: texture_2d<f32>;
@group(0) @binding(4) var normal_tex: texture_2d<f32>;

// Thesis eq. 5.2: p0 <- p0 * sat(sum_i ceil(sat(p_i - t')) - 2), the sum running over the 3x3
// neighbourhood including the centre, so a contour pixel survives only with >= 2 contour
// neighbours.
fn contour_ink(p: vec2<i32>) -> f32 {
    let p0 = textureLoad(contour_tex, p, 0).r;
    if post.contour.w < 0.5 || p0 <= 0.0 {
        return p0;
    }
    var count = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let pi = textureLoad(contour_tex, clamp_coord(p + vec2<i32>(dx, dy)), 0).r;
            count += ceil(saturate(pi - post.contour.z));
        }
    }
    return p0 * saturate(count - 2.0);
}

// Lambert tone with ambient light, darkened by the surface's own albedo and stretched about a
// reference grey.
fn tone(p: vec2<i32>) -> f32 {
    let n = normalize(textureLoad(normal_tex, p, 0).xyz);
    let light = post.light.w + (1.0 - post.light.w) * max(dot(n, post.light.xyz), 0.0);
    let albedo = textureLoad(albedo_tex, p, 0).rgb;
    let lum = sqrt(dot(albedo, vec3<f32>(0.2126, 0.7152, 0.0722)));
    let t = light * mix(1.0, lum, post.tone.x);
    return saturate((t - post.tone.z) * post.tone.y + post.tone.z);
}

// One family of parallel anti-aliased lines at `angle`, as thick as the tone is below `level`.
fn hatch_layer(frag: vec2<f32>, t: f32, level: f32, angle: f32) -> f32 {
    let darkness = saturate((level - t) / post.hatch.w);
    let width = darkness * post.hatch.y;
    let u = dot(frag, vec2<f32>(cos(angle), sin(angle))) / post.hatch.x;
    let dist = abs(fract(u) - 0.5) * post.hatch.x;
    return saturate(width * 0.5 + 0.5 - dist) * step(0.001, width);
}

@fragment
fn fs_compose(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    var ink = contour_ink(p) * post.tone.w;
    if textureLoad(albedo_tex, p, 0).a > 0.5 {
        let t = tone(p);
        let a = post.hatch.z;
        let quarter = 1.5707963;
        ink = max(ink, hatch_layer(frag.xy, t, post.hatch_levels.x, a));
        ink = max(ink, hatch_layer(frag.xy, t, post.hatch_levels.y, a + quarter));
        ink = max(ink, hatch_layer(frag.xy, t, post.hatch_levels.z, a + 0.5 * quarter));
        ink = max(ink, hatch_layer(frag.xy, t, post.hatch_levels.w, a - 0.5 * quarter));
    }
    return vec4<f32>(mix(post.paper.rgb, post.ink.rgb, ink), 1.0);
}
