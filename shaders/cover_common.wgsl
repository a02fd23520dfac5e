// The land-cover classes of the ground (`render::ground_cover`, issue 18) as the contour, data
// and compose passes read them: `cover` (one `CoverStyle` per class, entry 0 the plain ground)
// is declared ahead of this file from the pass's declaration. The G-buffer pass writes a
// terrain pixel's class index into the low bits of its patch ID.

// `CoverStyle.strokes` of a class drawn without strokes (`scene::cover::CoverStrokes::None`).
const COVER_NONE: u32 = 5u;

// The class index of the ID-buffer pair `ids`: a terrain pixel's class, 0 (plain ground)
// for everything else and in frames without land cover (`LAND_COVER`).
fn cover_index(ids: vec2<u32>) -> u32 {
    return select(0u, min(ids.y & 0xffffffu, arrayLength(&cover) - 1u), LAND_COVER && is_terrain(ids));
}

// The tonal art map of a pixel without a hatch-pattern mapping: its land-cover class's, else
// `style_tam`, its style's.
fn cover_tam(ids: vec2<u32>, style_tam: u32) -> u32 {
    let c = cover[cover_index(ids)];
    return select(style_tam, u32(c.hatch_map), c.hatch_map >= 0);
}
