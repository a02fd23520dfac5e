// Post pass 1: image-space contours from linear depth (thesis 5.1) and the tone image
// (thesis 6.1.3), each pixel with the style of its layer.

// Thesis eq. 5.1: p0 = max_i sat((d_i - d0) c - t) over the 3x3 neighbourhood, with signed
// differences so that contours are one pixel wide and lie on the nearer surface. Depths are
// taken relative to d0 (d_i / d0 - 1) so one threshold works from the foreground to the
// horizon, and far plant groups merge (their relative depth steps shrink) instead of turning
// into noise (thesis 7.3).
fn contour(p: vec2<i32>) -> f32 {
    let size = textureDimensions(depth_tex);
    let d0 = textureLoad(depth_tex, p, 0).r;
    var edge = 0.0;
    for (var i = 0; i < 9; i++) {
        let di = textureLoad(depth_tex, clamp_coord(p + vec2<i32>(i % 3 - 1, i / 3 - 1), size), 0).r;
        edge = max(edge, saturate((di / d0 - 1.0) * post.contour_scale - post.contour_threshold));
    }
    return edge;
}

// Thesis 6.1.3: Lambert light from the (HLP-blended) normal with ambient light (scaled by k_a of
// the implicit-surface illumination, Luft et al. 2007), darkened by the albedo, contrast about
// L_ref (eq. 6.7: L' = (L - L_ref) scale + L_ref) and optional banding. `ids` are the pixel's
// object IDs (read once by the pass).
fn tone(p: vec2<i32>, ids: vec2<u32>) -> f32 {
    let albedo = textureLoad(albedo_tex, p, 0);
    if albedo.a < 0.5 {
        return 1.0;
    }
    let encoded = textureLoad(normal_tex, p, 0).xyz;
    let terrain = is_terrain(ids);
    var light = light_from_normal(encoded).x;
    // The terrain's relief tone: its light relative to flat ground's, so level and sunny
    // ground stay paper and slopes turned away from the sun darken (Imhof's shaded relief
    // read as pen-and-ink: Buchin et al. 2011), darkened further by the slope angle up to 45°
    // (Lehmann's hachure rule) so lit slopes keep sparse indication strokes. Both from the
    // normal of the relief exaggerated vertically by `terrain_exaggeration` (the z-factor of a
    // cartographer's hillshade), so gentle lowland relief reads.
    if terrain {
        let flat_light = light_from_normal(vec3<f32>(0.0, 0.0, 1.0)).x;
        let n = normalize(vec3<f32>(encoded.xy * post.terrain_exaggeration, encoded.z) + vec3<f32>(0.0, 0.0, 1e-6));
        light = light_from_normal(n * length(encoded)).x;
        light = mix(light, min(light / max(flat_light, 1e-3), 1.0), post.terrain_relief);
        let steepness = saturate(acos(saturate(n.z)) / 0.78539816);
        light *= 1.0 - post.terrain_slope_tone * steepness;
    }
    // The ground's tone comes from its relief and its land-cover class's tone, not from its
    // drape's colour (the shadows and texture of an orthophoto would print as noise).
    let lum = select(sqrt(dot(albedo.rgb, vec3<f32>(0.2126, 0.7152, 0.0722))), 1.0, terrain);
    let l = light * mix(1.0, lum, post.albedo_weight);
    var t = saturate((l - post.tone_reference) * post.tone_contrast + post.tone_reference);
    // The land-cover class's tone offset (forest floor dark, meadow light), or paper for a
    // class drawn without strokes; plain ground and plants have neither.
    let land = cover[cover_index(ids)];
    t = select(saturate(t + land.tone), 1.0, land.strokes == COVER_NONE);
    if post.tone_levels > 0.0 {
        t = round(t * post.tone_levels) / post.tone_levels;
    }
    return t;
}

// The outline between two land-cover classes (`land_cover_outline`): a terrain pixel whose
// right or lower neighbour is terrain of another class, one of the two outlined. Drawn with the
// contours, so it is one pixel wide and fixed to the ground like the classes. `here` are the
// pixel's object IDs.
fn cover_border(p: vec2<i32>, here: vec2<u32>) -> f32 {
    if !LAND_COVER {
        return 0.0;
    }
    let size = textureDimensions(id_tex);
    let a = cover_index(here);
    var edge = 0.0;
    for (var k = 0; k < 2; k++) {
        let q = textureLoad(id_tex, clamp_coord(p + vec2<i32>(1 - k, k), size), 0).xy;
        let b = cover_index(q);
        let outlined = max(cover[a].outline, cover[b].outline) > 0.0;
        edge = max(edge, select(0.0, 1.0, is_terrain(here) && is_terrain(q) && b != a && outlined));
    }
    return edge * post.land_cover_outline;
}

@fragment
fn fs_contour(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(frag.xy);
    // Each pixel in the style of its layer (thesis 8.2.8): contours lie on the nearer surface,
    // so an edge between two layers takes the style of the one in front.
    let ids = textureLoad(id_tex, p, 0).xy;
    use_style(ids.x);
    return vec4<f32>(max(contour(p), cover_border(p, ids)), tone(p, ids), 0.0, 1.0);
}
