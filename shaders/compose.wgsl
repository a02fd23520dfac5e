// Post pass 2: isolated-pixel removal (thesis eq. 5.2), tone blur, hatching with a tonal art
// map on the hybrid parametrization (thesis 6.1), stylized silhouettes with a silhouette art
// map (thesis 5.2), composited on paper.

@group(0) @binding(1) var contour_tex: texture_2d<f32>;
@group(0) @binding(2) var depth_tex: texture_2d<f32>;
@group(0) @binding(3) var id_tex: texture_2d<u32>;
@group(0) @binding(4) var hatch_tex: texture_2d<f32>;
@group(0) @binding(5) var normal_tex: texture_2d<f32>;
@group(0) @binding(6) var albedo_tex: texture_2d<f32>;
@group(0) @binding(7) var tam: texture_2d_array<f32>;
@group(0) @binding(8) var sam: texture_2d<f32>;
@group(0) @binding(9) var tam_sampler: sampler;
@group(0) @binding(10) var sam_sampler: sampler;

const MAX_SUPPORT: i32 = 16;

// Thesis eq. 5.2: p0 <- p0 * sat(sum_i ceil(sat(p_i - t')) - 2), the sum running over the 3x3
// neighbourhood including the centre, so a contour pixel survives only with >= 2 contour
// neighbours.
fn contour_ink(p: vec2<i32>, size: vec2<u32>) -> f32 {
    let p0 = textureLoad(contour_tex, p, 0).r;
    if post.contour.w < 0.5 || p0 <= 0.0 {
        return p0;
    }
    var count = 0.0;
    for (var i = 0; i < 9; i++) {
        let pi = textureLoad(contour_tex, clamp_coord(p + vec2<i32>(i % 3 - 1, i / 3 - 1), size), 0).r;
        count += ceil(saturate(pi - post.contour.z));
    }
    return p0 * saturate(count - 2.0);
}

// Gaussian blur of the tone image (thesis Fig. 6.9d) with radius post.tone2.y, sigma = radius / 2.
fn blurred_tone(p: vec2<i32>, size: vec2<u32>) -> f32 {
    let radius = i32(post.tone2.y);
    if radius == 0 {
        return textureLoad(contour_tex, p, 0).g;
    }
    let sigma = max(post.tone2.y * 0.5, 0.5);
    var sum = 0.0;
    var weight = 0.0;
    for (var dy = -radius; dy <= radius; dy++) {
        for (var dx = -radius; dx <= radius; dx++) {
            let w = exp(-f32(dx * dx + dy * dy) / (2.0 * sigma * sigma));
            sum += w * textureLoad(contour_tex, clamp_coord(p + vec2<i32>(dx, dy), size), 0).g;
            weight += w;
        }
    }
    return sum / weight;
}

// Tonal art map lookup (Praun et al., thesis 6.1): the darkness 1 - t is placed between the
// two tone levels whose mean darkness brackets it (level i of n aims at 0.1 + 0.8 i / (n - 1),
// `artmaps::tone_target`; below level 0 it fades to paper) and the two are blended; the mip
// level follows the texture's tiles per pixel so strokes keep their width on screen. Returns
// ink coverage 0..1.
fn hatch_ink(p: vec2<i32>, t: f32) -> f32 {
    let levels = i32(post.tone2.z);
    let coords = textureLoad(hatch_tex, p, 0).xy;
    let tiles_per_px = textureLoad(normal_tex, p, 0).w;
    let lod = log2(max(tiles_per_px * post.tone2.w, 1e-4));
    let step = 0.8 / f32(levels - 1);
    let darkness = 1.0 - t;
    let position = select((darkness - 0.1) / step, darkness / 0.1 - 1.0, darkness < 0.1);
    let lo = i32(floor(position));
    let f = position - floor(position);
    var a = 1.0;
    if lo >= 0 {
        a = textureSampleLevel(tam, tam_sampler, coords, min(lo, levels - 1), lod).r;
    }
    let b = textureSampleLevel(tam, tam_sampler, coords, clamp(lo + 1, 0, levels - 1), lod).r;
    return (1.0 - mix(a, b, f)) * post.hatch.x;
}

// Thesis 5.2: stylized silhouettes. Search from the pixel along E (the screen projection of the
// HLP normal) for the nearest contour pixel within the support width; its distance is v. Only
// contour pixels with the pixel's own object and patch ID count, so a contour between two
// patches is stylized from one side only (thesis Fig. 5.7). u = c·α·r/d (eq. 5.5) with α the
// angle of E against the per-object orientation vector V_O, which turns with the camera roll.
// The SAM channel (style variant) follows the tone: darker regions get heavier strokes.
fn silhouette_ink(p: vec2<i32>, t: f32, size: vec2<u32>) -> f32 {
    let e = textureLoad(hatch_tex, p, 0).zw;
    let support = i32(post.silhouette.x);
    if support == 0 || dot(e, e) < 0.25 {
        return 0.0;
    }
    let ids = textureLoad(id_tex, p, 0).xy;
    let step = vec2<f32>(e.x, -e.y);
    var v = -1;
    for (var k = 0; k <= MAX_SUPPORT; k++) {
        if k > support {
            break;
        }
        let q = clamp_coord(p + vec2<i32>(round(step * f32(k))), size);
        if textureLoad(contour_tex, q, 0).r > post.contour.z && all(textureLoad(id_tex, q, 0).xy == ids) {
            v = k;
            break;
        }
    }
    if v < 0 {
        return 0.0;
    }
    let vo = vec2<f32>(-post.hatch.y, -post.hatch.z);
    let alpha = atan2(vo.x * e.y - vo.y * e.x, dot(vo, e));
    let radius_px = textureLoad(depth_tex, p, 0).g;
    let u = post.silhouette.y * alpha * radius_px;
    let sam_size = vec2<f32>(textureDimensions(sam));
    let texel = textureSampleLevel(sam, sam_sampler, vec2<f32>(u / sam_size.x, (f32(v) + 0.5) / f32(support + 1)), 0.0);
    let channel = clamp(i32((1.0 - t) * 4.0), 0, 3);
    return texel[channel] * post.silhouette.z;
}

@fragment
fn fs_compose(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    let size = textureDimensions(contour_tex);
    var ink = contour_ink(p, size) * post.tone.w;
    if textureLoad(albedo_tex, p, 0).a > 0.5 {
        let t = blurred_tone(p, size);
        ink = max(ink, hatch_ink(p, t));
        ink = max(ink, silhouette_ink(p, t, size));
    }
    return vec4<f32>(mix(post.paper.rgb, post.ink.rgb, ink), 1.0);
}
