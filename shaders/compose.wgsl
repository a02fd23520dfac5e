// Post pass 3: isolated-pixel removal (thesis eq. 5.2), tone blur (vertical half), hatching with a tonal art
// map on the hybrid parametrization (thesis 6.1), stylized silhouettes with a silhouette art
// map (thesis 5.2), composited on paper or, with colour (thesis 6.2, 8.2.6–8.2.7), on the
// shaded surface colour and the sky. Every pixel uses the style of its layer (thesis 8.2.8); a
// compose pass draws the style slots of its art-map group (`styles.art_group`) and discards
// the rest. Data layers (thesis 9.3) adjust tone, TAM, SAM channel, silhouettes and colour
// and add coloured hatchings through `data_common.wgsl`: the surface colour
// or paper, with the style's ink over it, is multiplied by the data's colour tint and by the
// hatch colours' inks.

const MAX_SUPPORT: i32 = 16;
const LUMA: vec3<f32> = vec3<f32>(0.2126, 0.7152, 0.0722);

// Thesis eq. 5.2: p0 <- p0 * sat(sum_i ceil(sat(p_i - t')) - 2), the sum running over the 3x3
// neighbourhood including the centre, so a contour pixel survives only with >= 2 contour
// neighbours.
fn contour_ink(p: vec2<i32>, size: vec2<u32>) -> f32 {
    let p0 = textureLoad(contour_tex, p, 0).r;
    if post.isolated_pixel_removal == 0u || p0 <= 0.0 {
        return p0;
    }
    var count = 0.0;
    for (var i = 0; i < 9; i++) {
        let pi = textureLoad(contour_tex, clamp_coord(p + vec2<i32>(i % 3 - 1, i / 3 - 1), size), 0).r;
        count += ceil(saturate(pi - post.isolated_pixel_threshold));
    }
    return p0 * saturate(count - 2.0);
}

// The tone blurred by the style's Gaussian (thesis Fig. 6.9d): the vertical half over the
// horizontally blurred tone of the tone-blur pass.
fn blurred_tone(p: vec2<i32>) -> f32 {
    // The style's radius, not the frame's BLUR_RADIUS: lavapipe 22.3 miscompiled this shader
    // with the loop unrolled (leaf-free ground at tone 1 came out hatched), and the unrolled
    // loop saved nothing here.
    return gaussian_tone(tone_tex, 0u, p, vec2<i32>(0, 1), i32(post.tone_blur));
}

// Tonal art map lookup (Praun et al., thesis 6.1) at hatch coordinates `coords` in the TAM whose
// first array layer is `base`: the darkness is placed between the two tone levels whose mean
// darkness brackets it (level i of n aims at 0.1 + 0.8 i / (n - 1), `artmaps::tone_target`;
// below level 0 it fades to paper) and the two are blended. Layer j of a TAM holds levels j - 1
// (paper for j = 0) and j in red and green (`art_textures::upload_tams`), so one lookup reads
// both. Returns ink coverage 0..1.
fn tam_ink(coords: vec2<f32>, base: i32, darkness: f32, lod: f32) -> f32 {
    let levels = i32(post.tam_levels);
    let step = 0.8 / f32(levels - 1);
    let position = select((darkness - 0.1) / step, darkness / 0.1 - 1.0, darkness < 0.1);
    let pair = textureSampleLevel(tam, tam_sampler, coords, base + clamp(i32(floor(position)) + 1, 0, levels), lod).rg;
    return 1.0 - mix(pair.r, pair.g, position - floor(position));
}

// The first array layer of TAM `index` (each takes `tam_levels` + 1, `tam_ink`).
fn tam_base(index: i32) -> i32 {
    return index * (i32(post.tam_levels) + 1);
}

// How many TAM layers the pixel's strokes blend: 1 (its one set of hatch coordinates), or for
// object-space terrain 4 (two orientations at two scales, see `stroke_layer`), 2 where one
// orientation has all the weight (`second`, its share, is 0 or 1: half the ground, as the
// orientation weights are sharpened). A loop over this count rather than a branch: lavapipe
// runs both sides of a branch for every pixel, but leaves a loop as soon as all pixels of its
// group are done, so plants pay for one layer and ground of one direction for two.
fn stroke_layers(p: vec2<i32>, second: f32) -> i32 {
    let terrain = post.terrain_strokes != TERRAIN_IMAGE && is_terrain(textureLoad(id_tex, p, 0).xy);
    return select(1, select(4, 2, second <= 0.0 || second >= 1.0), terrain);
}

// One TAM layer of the pixel's strokes: its hatch coordinates, weight and mip level. Layer 0
// alone is the plain lookup. Object-space terrain (gbuffer.wgsl `terrain_hatch`, Bénard et al.
// 2010) blends its two quantized stroke orientations (hatch xy and zw, the second's share in
// the linear-depth target's y) at the finer stroke scale and at the next coarser one (half
// the coordinates, one mip level up), weighted by the fractional part of the scale
// log2(tiles per pixel · tile size in pixels), so strokes keep their size on screen.
struct StrokeLayer {
    coords: vec2<f32>,
    weight: f32,
    lod: f32,
};

// What the pixel's stroke layers are made of, read from the G-buffer once per pixel (not
// once per layer): its hatch coordinates, mip level, the second orientation's share and the
// coarser scale's, and the layer count.
struct StrokeFrame {
    hatch: vec4<f32>,
    lod: f32,
    second: f32,
    coarse: f32,
    layers: i32,
};

fn stroke_frame(p: vec2<i32>) -> StrokeFrame {
    let second = textureLoad(depth_tex, p, 0).g;
    let layers = stroke_layers(p, second);
    // The TAM mip level follows the texture's tiles per pixel, so strokes keep their width
    // on screen.
    let normal_w = textureLoad(normal_tex, p, 0).w;
    let lod = log2(max(normal_w * post.tam_size, 1e-4));
    let coarse = saturate(log2(normal_w * post.terrain_tile));
    return StrokeFrame(textureLoad(hatch_tex, p, 0), lod, second, coarse, layers);
}

fn stroke_layer(frame: StrokeFrame, index: i32) -> StrokeLayer {
    if frame.layers == 1 {
        return StrokeLayer(frame.hatch.xy, 1.0, frame.lod);
    }
    // Of two layers, the two scales of the one orientation with weight: layers 0 and 2, or 1
    // and 3.
    let layer = select(index, 2 * index + select(0, 1, frame.second >= 1.0), frame.layers == 2);
    let second = (layer & 1) == 1;
    let coarse = layer >= 2;
    let weight = select(1.0 - frame.second, frame.second, second) * select(1.0 - frame.coarse, frame.coarse, coarse);
    let coords = select(frame.hatch.xy, frame.hatch.zw, second) * select(1.0, 0.5, coarse);
    return StrokeLayer(coords, weight, frame.lod - select(0.0, 1.0, coarse));
}

// Ink of the pixel's strokes (`frame`, read once per pixel by `stroke_frame`) at `darkness`
// from the TAM at `base`, its hatch coordinates turned by `rotation` (cos, sin): the
// variance-preserving blend of its stroke layers (Bénard et al. 2010 eq. 3, after Heitz and
// Neyret): m + (Σ w_i·(x_i − m)) / sqrt(Σ w_i²) with m the mean ink of the tone (its
// darkness), so blended layers keep the contrast of one instead of fading to grey
// half-strokes; one layer is returned as it is.
fn stroke_ink(frame: StrokeFrame, base: i32, darkness: f32, rotation: vec2<f32>) -> f32 {
    var ink = 0.0;
    var squares = 0.0;
    for (var i = 0; i < frame.layers; i++) {
        let l = stroke_layer(frame, i);
        let r = rotation;
        let c = vec2<f32>(r.x * l.coords.x - r.y * l.coords.y, r.y * l.coords.x + r.x * l.coords.y);
        ink += l.weight * tam_ink(c, base, darkness, l.lod);
        // A layer's lookup is itself a blend of two mip levels (trilinear), by the fractional
        // part f of its level: its strokes' variance is (1 − f)² + f² of one level's, which the
        // normalisation restores as it does the layers' (terrain layers only: a single layer
        // is returned as it is).
        let f = fract(max(l.lod, 0.0));
        squares += l.weight * l.weight * select(1.0, (1.0 - f) * (1.0 - f) + f * f, frame.layers > 1);
    }
    // The lookups' mean ink: the darkness, up to the darkest tone level's 0.9 (`tam_ink`).
    let mean = clamp(darkness, 0.0, 0.9);
    return saturate(mean + (ink - mean) / sqrt(max(squares, 1e-4)));
}

// Hatching of tone t (1 = white) with the pixel's TAM (its style's, or a hatch-pattern
// mapping's), by the hatch strength.
fn hatch_ink(p: vec2<i32>, t: f32, strokes: StrokeFrame) -> f32 {
    if post.hatch_strength <= 0.0 {
        return 0.0;
    }
    let base = tam_base(data_tam_index(data_at(p)));
    return stroke_ink(strokes, base, 1.0 - t, vec2<f32>(1.0, 0.0)) * post.hatch_strength;
}

// The filter of one hatch-colour slot: strokes of the slot's darkness from the TAM at `base`,
// at the hatch coordinates rotated by the slot's angle, in the slot's ink at its opacity; 1
// (white) off the strokes.
fn hatch_color_filter(strokes: StrokeFrame, slot: HatchColor, darkness: f32, base: i32) -> vec3<f32> {
    if darkness <= 0.0 || slot.opacity <= 0.0 {
        return vec3<f32>(1.0);
    }
    return mix(vec3<f32>(1.0), slot.color, stroke_ink(strokes, base, darkness, slot.rotation) * slot.opacity);
}

// Thesis 9.2.2, Fig. 9.3: several fields with equal visual importance as hatchings of different
// colours. Each hatch-colour slot draws the TAM of the pixel's style at its own darkness and
// stroke direction in its ink over the sketch. The inks multiply like transparent inks, so the
// result does not depend on the slots' order and no field hides another (crossing strokes
// darken); the style's hatch strength and brightness do not apply (the data stay visible in any
// style).
fn hatch_colors_over(p: vec2<i32>, rgb: vec3<f32>, strokes: StrokeFrame) -> vec3<f32> {
    let darkness = data_hatch_darkness(data_at(p));
    if !HATCH_COLORS || all(darkness <= vec3<f32>(0.0)) {
        return rgb;
    }
    let base = tam_base(i32(post.hatch_map));
    return rgb * hatch_color_filter(strokes, hatch_colors.slots[0], darkness.x, base)
        * hatch_color_filter(strokes, hatch_colors.slots[1], darkness.y, base)
        * hatch_color_filter(strokes, hatch_colors.slots[2], darkness.z, base);
}

// Thesis 5.2: stylized silhouettes. Search from the pixel along E (the screen projection of the
// HLP normal) for the nearest contour pixel within the support width; its distance is v. Only
// contour pixels with the pixel's own object and patch ID count, so a contour between two
// patches is stylized from one side only (thesis Fig. 5.7). u = c·α·r/d (eq. 5.5) with α the
// angle of E against the per-object orientation vector V_O, which turns with the camera roll.
// The SAM channel (style variant) follows the tone: darker regions get heavier strokes.
fn silhouette_ink(p: vec2<i32>, t: f32, size: vec2<u32>) -> f32 {
    let ids = textureLoad(id_tex, p, 0).xy;
    // The terrain has no HLP (its hatch zw holds object-space stroke coordinates).
    let e = select(textureLoad(hatch_tex, p, 0).zw, vec2<f32>(0.0), is_terrain(ids));
    // −1 where there is nothing to search: the loop below runs to the style's support (not a
    // constant bound, which the compiler would unroll into the full 17 steps for every pixel).
    let searching = post.silhouette_support >= 1.0 && post.silhouette_strength > 0.0 && dot(e, e) >= 0.25;
    let support = select(-1, min(i32(post.silhouette_support), MAX_SUPPORT), searching);
    if support < 0 {
        return 0.0;
    }
    let step = vec2<f32>(e.x, -e.y);
    var v = -1;
    for (var k = 0; k <= support; k++) {
        let q = clamp_coord(p + vec2<i32>(round(step * f32(k))), size);
        if textureLoad(contour_tex, q, 0).r > post.isolated_pixel_threshold && all(textureLoad(id_tex, q, 0).xy == ids) {
            v = k;
            break;
        }
    }
    if v < 0 {
        return 0.0;
    }
    let vo = -post.roll;
    let alpha = atan2(vo.x * e.y - vo.y * e.x, dot(vo, e));
    let radius_px = textureLoad(depth_tex, p, 0).g;
    let u = post.silhouette_stretch * alpha * radius_px;
    let sam_size = vec2<f32>(textureDimensions(sam));
    let texel = textureSampleLevel(sam, sam_sampler, vec2<f32>(u / sam_size.x, (f32(v) + 0.5) / f32(support + 1)), 0.0);
    let channel = data_sam_channel(data_at(p), clamp(i32((1.0 - t) * 4.0), 0, 3));
    return texel[channel] * post.silhouette_strength * data_silhouettes(data_at(p));
}

// Ink of a leaf outline (thesis eq. 4.1): the G-buffer pass marks outline texels of leaves with
// albedo alpha 0.75 (`OUTLINE_ALPHA` in gbuffer.wgsl) instead of 1.
fn outline_ink(albedo_alpha: f32) -> f32 {
    return saturate((1.0 - albedo_alpha) * 4.0);
}

// Linear RGB to the sRGB encoding of the output (the paper, ink and sky colours are sRGB).
fn encode_srgb(c: vec3<f32>) -> vec3<f32> {
    let x = saturate(c);
    return select(1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - 0.055, x * 12.92, x <= vec3<f32>(0.0031308));
}

// Thesis 6.2: the surface colour, linear RGB. The albedo (already blended towards the
// material's average colour in the G-buffer pass) with its saturation, lit by Lambert light
// with ambient from the HLP-blended normal (thesis 6.1.3; the ambient term darkened by k_a of
// the implicit-surface illumination, Luft et al. 2007); optionally banded by a 1D toon ramp
// of `toon_levels` flat bands (Campos et al. 2004) and blended towards Gooch cool-to-warm
// shading, k_cool = (0, 0, 0.4) + 0.2·k_d, k_warm = (0.4, 0.4, 0) + 0.6·k_d (Gooch et al. 1998).
fn surface_color(p: vec2<i32>) -> vec3<f32> {
    let albedo = textureLoad(albedo_tex, p, 0).rgb;
    let c = max(mix(vec3<f32>(dot(albedo, LUMA)), albedo, post.color_saturation), vec3<f32>(0.0));
    let light = light_from_normal(textureLoad(normal_tex, p, 0).xyz);
    let smooth_light = light.x;
    let ndl = light.y;
    let bands = post.toon_levels;
    let ramp = min(floor(smooth_light * bands), bands - 1.0) / (bands - 1.0);
    let lit = c * mix(smooth_light, ramp, post.toon);
    let k = 0.5 * (1.0 + ndl);
    let gooch = mix(vec3<f32>(0.0, 0.0, 0.4) + 0.2 * c, vec3<f32>(0.4, 0.4, 0.0) + 0.6 * c, k);
    return mix(lit, gooch, post.gooch);
}

// The sky behind the landscape (sRGB): from the horizon colour to the zenith colour with the
// elevation of the pixel's view ray (straight down in a plan view: the horizon colour).
fn sky_color(frag: vec2<f32>, size: vec2<u32>) -> vec3<f32> {
    let ndc = vec2<f32>(frag.x / f32(size.x) * 2.0 - 1.0, 1.0 - frag.y / f32(size.y) * 2.0);
    let z = styles.ray.x + ndc.x * styles.ray.y + ndc.y * styles.ray.z;
    let len = length(vec3<f32>(1.0, ndc.x * styles.ray.w, ndc.y * styles.tan_half_fov));
    return mix(post.sky_horizon, post.sky_zenith, sqrt(saturate(z / len)));
}

// The style of the pixel (thesis 8.2.8), or false where its style slot belongs to another
// art-map group's compose pass.
fn style_of_group(p: vec2<i32>) -> bool {
    use_style(textureLoad(id_tex, p, 0).x);
    return post.art_group == styles.art_group;
}

// Contour ink by the style's contour strength (thesis eq. 5.1, 5.2).
fn contour_part(p: vec2<i32>, size: vec2<u32>) -> f32 {
    if post.contour_strength > 0.0 {
        return contour_ink(p, size) * post.contour_strength;
    }
    return 0.0;
}

// The final colour: the base with the ink over it, tinted by the data and with the data's
// coloured hatchings (along the pixel's `strokes`).
fn finish(p: vec2<i32>, base: vec3<f32>, ink: f32, strokes: StrokeFrame) -> vec4<f32> {
    return vec4<f32>(hatch_colors_over(p, data_tint(data_at(p), mix(base, post.ink, ink)), strokes), 1.0);
}

// The geometry's pixels (the pipeline's depth test passes only where the G-buffer pass drew).
@fragment
fn fs_compose(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    if !style_of_group(p) {
        discard;
    }
    let size = textureDimensions(contour_tex);
    let strokes = stroke_frame(p);
    var ink = max(contour_part(p, size), outline_ink(textureLoad(albedo_tex, p, 0).a));
    // The tone is only needed for strokes (a photorealistic style draws none).
    if post.hatch_strength > 0.0 || post.silhouette_strength > 0.0 {
        let t = data_tone(data_at(p), blurred_tone(p));
        // Thesis 8.2.7: the hatch tone is lifted towards the brightest level (no strokes), and
        // further with the distance (thesis 7.3, `distance_simplification`): the TAM's nested
        // tones drop far strokes one by one.
        let far = smoothstep(post.abstraction_near, post.abstraction_far, textureLoad(depth_tex, p, 0).r);
        let lift = 1.0 - (1.0 - post.hatch_brightness) * (1.0 - post.distance_simplification * far);
        ink = max(ink, hatch_ink(p, mix(t, 1.0, lift), strokes));
        ink = max(ink, silhouette_ink(p, t, size));
    }
    var base = post.paper;
    if SURFACE_COLOR {
        base = mix(base, encode_srgb(surface_color(p)), post.color);
    }
    return finish(p, base, ink, strokes);
}

// The background's pixels: paper or sky (no contours: they lie on the nearer surface).
@fragment
fn fs_sky(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    if !style_of_group(p) {
        discard;
    }
    let sky = mix(post.paper, sky_color(frag.xy, textureDimensions(contour_tex)), post.sky);
    return finish(p, sky, 0.0, stroke_frame(p));
}
