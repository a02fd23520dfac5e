// Helpers shared by the post-processing passes. The block `styles` (`render::passes::post_block::
// Styles`: one `PostStyle` per style slot, picked per pixel by the layer code of the ID buffer,
// thesis 8.2.8) and each pass's bindings are declared ahead of this file from the pass's
// declaration (`render::passes`), with the layer-code constants.

// Frame-wide specialisation (`render::passes::Specialization`), set per pipeline: lavapipe runs
// every instruction of a shader for every pixel whichever way its branches go, so a frame that
// needs less gets pipelines compiled without the rest.
// Every slot holds the same style: slot 0 serves all pixels, no per-pixel lookup.
override UNIFORM_STYLE: bool = false;
// The tone blur radius of every slot (−1: each pixel's style's), so the tone-blur pass's loop
// unrolls.
override BLUR_RADIUS: i32 = -1;
// Whether the frame has hatch-colour mappings of data layers (compose).
override HATCH_COLORS: bool = true;
// Whether the projection pass wrote data layers (compose reads none without).
override DATA_LAYERS: bool = true;
// Whether any slot shows surface colour (compose shades none without).
override SURFACE_COLOR: bool = true;
// Whether the terrain has land-cover classes (without, every pixel is of the plain ground's).
override LAND_COVER: bool = true;

// The style of the pixel being shaded; set by each fragment entry point with `use_style`.
var<private> post: PostStyle;

// Style slot of an object ID: its layer code (`LAYER_SHIFT`, `STYLE_SLOTS` and
// `LAYER_BACKGROUND`, the base slot, come from `render::layer_code::LayerCode`), or the base
// slot beyond the slots.
fn style_slot(object_id: u32) -> u32 {
    let code = object_id >> LAYER_SHIFT;
    return select(LAYER_BACKGROUND, code, code < STYLE_SLOTS);
}

fn use_style(object_id: u32) {
    post = styles.slots[select(style_slot(object_id), 0u, UNIFORM_STYLE)];
}

// The terrain's strokes as `PostStyle.terrain_strokes` gives them (`render::style::TerrainStrokes`).
const TERRAIN_IMAGE: u32 = 0u;

// Whether the ID-buffer pair `ids` (object ID, part kind << 24 | patch) is terrain (part kind
// 0, `render::gbuffer::Surface::Terrain`) rather than background or a plant.
fn is_terrain(ids: vec2<u32>) -> bool {
    return ids.x != 0u && (ids.y >> 24u) == 0u;
}

fn clamp_coord(p: vec2<i32>, size: vec2<u32>) -> vec2<i32> {
    return clamp(p, vec2<i32>(0), vec2<i32>(size) - 1);
}

// Light at a pixel from its G-buffer normal (thesis 6.1.3): ambient plus Lambert,
// a + (1 − a)·max(N·L, 0), with the ambient term scaled by the normal's length, the ambient
// coefficient k_a' of the implicit-surface illumination (Luft et al. 2007 eq. 1: I_a·k_a; eq. 4;
// 1 where there is none). x: the light, y: N·L.
fn light_from_normal(encoded: vec3<f32>) -> vec2<f32> {
    let ka = length(encoded);
    let ndl = dot(encoded / max(ka, 1e-6), post.sun);
    return vec2<f32>(post.ambient * ka + (1.0 - post.ambient) * max(ndl, 0.0), ndl);
}

// One axis of the separable Gaussian blur of the tone image (thesis Fig. 6.9d): the mean of
// channel `channel` of `tex` along `axis` within `radius` (the style's blur radius), weighted
// by exp(−d²/2σ²) with σ = radius / 2. The tone-blur pass (horizontal) and the compose pass
// (vertical) together give the 2D Gaussian with a tenth of the texel reads at radius 4.
fn gaussian_tone(tex: texture_2d<f32>, channel: u32, p: vec2<i32>, axis: vec2<i32>, radius: i32) -> f32 {
    let size = textureDimensions(tex);
    let sigma = max(f32(radius) * 0.5, 0.5);
    let k = -0.5 / (sigma * sigma);
    var sum = 0.0;
    var weight = 0.0;
    for (var d = -radius; d <= radius; d++) {
        let w = exp(f32(d * d) * k);
        sum += w * textureLoad(tex, clamp_coord(p + axis * d, size), 0)[channel];
        weight += w;
    }
    return sum / weight;
}
