// Data layers (thesis 9.3) as the compose pass reads them: one Rgba32Uint texel per pixel
// (`data_tex`) written by the projection pass (`shaders/data.wgsl`, `render::projection`), or
// "no data" (white tint, no tone weight, the style's TAM, silhouettes kept, no coloured
// hatching) when the pass did not run; and the hatch-colour slots (`hatch_colors`:
// `render::projection::HatchColors`), which `ProjectionPass::prepare` writes.

fn data_at(p: vec2<i32>) -> vec4<u32> {
    if !DATA_LAYERS {
        // "No data" as the projection pass would clear to, with the style's (or the land-cover
        // class's) TAM.
        return vec4<u32>(0xffffffffu, 0u, cover_tam(textureLoad(id_tex, p, 0).xy, post.hatch_map), 1u);
    }
    return textureLoad(data_tex, p, 0);
}

// D3 hatch tone: t' = mix(t, tone, weight).
fn data_tone(d: vec4<u32>, t: f32) -> f32 {
    let tone = unpack2x16unorm(d.y);
    return mix(t, tone.x, tone.y);
}

// D3 hatch pattern: the index of the pixel's TAM among all TAMs.
fn data_tam_index(d: vec4<u32>) -> i32 {
    return i32(d.z & 0xffu);
}

// D3 silhouette style: the SAM channel of the pixel's label, else `by_tone`.
fn data_sam_channel(d: vec4<u32>, by_tone: i32) -> i32 {
    let channel = i32((d.z >> 8u) & 0xffu);
    return select(by_tone, channel - 1, channel > 0);
}

// D3 silhouette density: 1 where the pixel's plant keeps its silhouettes.
fn data_silhouettes(d: vec4<u32>) -> f32 {
    return f32(d.w & 1u);
}

// D4 hatch colours: the darkness 0..1 of the coloured hatching of slots 0, 1, 2 (0: none).
fn data_hatch_darkness(d: vec4<u32>) -> vec3<f32> {
    return unpack4x8unorm(d.w).yzw;
}

// D3 colour: the sketch multiplied by the colour maps' tint (ink stays dark, paper takes the
// colour).
fn data_tint(d: vec4<u32>, rgb: vec3<f32>) -> vec3<f32> {
    return rgb * unpack4x8unorm(d.x).rgb;
}
