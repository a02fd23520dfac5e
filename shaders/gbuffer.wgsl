// Stage one: the G-buffer pass (thesis 8.2, NPAR §9). Terrain and instanced plant parts are
// drawn with one pipeline; each fragment writes albedo, the (HLP-blended) normal, linear depth,
// object and patch IDs, the hatch texture coordinates and the screen projection E of the HLP
// normal that the post passes need.

// The geometry-pass parameters of one style slot (`render::gbuffer::LayerUniform`).
struct LayerStyle {
    // x: HLP normal blend, y: hatch space (0 hybrid, 1 image), z: HLP abstraction 1 - f
    // (eq. 4.8), w: colour abstraction (texture -> average material colour, thesis 6.2)
    hlp: vec4<f32>,
    // x: TAM tiles per π (m = n), y: surface function c (eq. 6.6), w: image-space tile (px)
    hatch: vec4<f32>,
};

const STYLE_SLOTS: u32 = 16u;

struct Frame {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    camera_pos: vec4<f32>,
    // x: tan(fov/2), y: image height (px), z: image width (px),
    // w: metres per pixel of a plan view (orthographic; 0 in perspective)
    viewport: vec4<f32>,
    // x: cos(-roll), y: sin(-roll)
    roll: vec4<f32>,
    // per style slot (layer code of the object ID, see `layer_style`)
    layers: array<LayerStyle, STYLE_SLOTS>,
};

struct Material {
    base_color: vec4<f32>,
    // x: alpha cutoff (< 0: opaque), y: part kind (0 terrain, 1 wood, 2 foliage)
    params: vec4<f32>,
    // average colour of the textured material, linear RGB (abstract colour, thesis 6.2)
    average_color: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
// Reference texture coordinates R_uv of every (instance, HLP) pair (thesis eq. 6.2).
@group(0) @binding(1) var<storage, read> references: array<vec2<f32>>;
@group(1) @binding(0) var<uniform> material: Material;
@group(1) @binding(1) var base_tex: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

const NO_HLP: u32 = 0xffffffffu;
const PI: f32 = 3.14159265;
const WOOD_TILES: f32 = 4.0;
const WOOD_TILE_HEIGHT: f32 = 1.5;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    // HLP centre (model space) and radius; radius 0 for terrain and wood
    @location(3) hlp: vec4<f32>,
    @location(4) hlp_index: u32,
    // per instance: xyz position, w uniform scale
    @location(5) offset_scale: vec4<f32>,
    // per instance: cos and sin of the rotation about z
    @location(6) rotation: vec2<f32>,
    @location(7) object_id: u32,
    // per instance: first entry of its HLPs in `references`
    @location(8) reference_base: u32,
    // per instance: screen-door range of a level-of-detail blend (all pixels: 0..1)
    @location(9) lod_mask: vec2<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) view_depth: f32,
    @location(3) @interpolate(flat) ids: vec2<u32>,
    // world-space HLP normal N_HLP = P - C (thesis eq. 4.7)
    @location(4) hlp_normal: vec3<f32>,
    // HLP centre in clip space, its view depth and world radius (radius 0: no HLP)
    @location(5) @interpolate(flat) hlp_clip: vec4<f32>,
    @location(6) @interpolate(flat) hlp_depth_radius: vec2<f32>,
    @location(7) @interpolate(flat) reference_uv: vec2<f32>,
    // object-space hatch coordinates for terrain (planar) and wood (cylindrical)
    @location(8) object_uv: vec2<f32>,
    @location(9) @interpolate(flat) lod_mask: vec2<f32>,
};

fn rotate_z(v: vec3<f32>, cs: vec2<f32>) -> vec3<f32> {
    return vec3<f32>(cs.x * v.x - cs.y * v.y, cs.y * v.x + cs.x * v.y, v.z);
}

fn to_world(p: vec3<f32>, in: VertexIn) -> vec3<f32> {
    return rotate_z(p * in.offset_scale.w, in.rotation) + in.offset_scale.xyz;
}

// Metres one pixel spans at linear depth `depth`: the perspective footprint, or the constant one
// of an orthographic plan view.
fn metres_per_px(depth: f32) -> f32 {
    return select(2.0 * depth * frame.viewport.x / frame.viewport.y, frame.viewport.w, frame.viewport.w > 0.0);
}

// The style of an object: the slot of its layer code (top 8 bits; 1 terrain, i + 2 vegetation
// layer i), the base slot 0 beyond the slots (thesis 8.2.8).
fn layer_style(object_id: u32) -> LayerStyle {
    let code = object_id >> 24u;
    // A loop instead of `frame.layers[slot]`: indexing the uniform array with a computed slot
    // leaked memory on every frame in Mesa's lavapipe 22.3 (measured: ~12 MB per frame at full
    // detail, see tests/memory.rs).
    var style = frame.layers[0];
    for (var i = 1u; i < STYLE_SLOTS; i++) {
        if i == code {
            style = frame.layers[i];
        }
    }
    return style;
}

// Thesis eq. 4.8–4.9: P' = f·P + (1 − f)·P_HLP with P_HLP = C + r·N_HLP/|N_HLP| the leaf
// position projected onto its HLP sphere; `abstraction` is 1 − f.
fn hlp_blend(p: vec3<f32>, hlp: vec4<f32>, abstraction: f32) -> vec3<f32> {
    let n = p - hlp.xyz;
    let len = length(n);
    if hlp.w <= 0.0 || len < 1e-6 {
        return p;
    }
    return mix(p, hlp.xyz + n / len * hlp.w, abstraction);
}

fn view_depth(world: vec3<f32>) -> f32 {
    // Linear depth along the view axis, in metres (view space looks down -z).
    return -(frame.view * vec4<f32>(world, 1.0)).z;
}

@vertex
fn vs_main(in: VertexIn) -> VertexOut {
    // Leaves only: billboards (kind 3) already stand for their HLP sphere.
    let abstraction = select(0.0, layer_style(in.object_id).hlp.z, u32(material.params.y) == 2u);
    let world = to_world(hlp_blend(in.position, in.hlp, abstraction), in);
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = rotate_z(in.normal, in.rotation);
    out.uv = in.uv;
    out.view_depth = view_depth(world);
    let kind = u32(material.params.y);
    let has_hlp = in.hlp.w > 0.0;
    let patch_id = select(0u, in.hlp_index + 1u, has_hlp);
    out.ids = vec2<u32>(in.object_id, (kind << 24u) | patch_id);
    let center = to_world(in.hlp.xyz, in);
    out.hlp_normal = world - center;
    out.hlp_clip = frame.view_proj * vec4<f32>(center, 1.0);
    out.hlp_depth_radius = vec2<f32>(view_depth(center), in.hlp.w * in.offset_scale.w);
    out.lod_mask = in.lod_mask;
    out.reference_uv = vec2<f32>(0.0);
    if has_hlp {
        out.reference_uv = references[in.reference_base + in.hlp_index];
    }
    // Wood: a cylinder around the model's z axis, WOOD_TILES around and one tile per
    // WOOD_TILE_HEIGHT metres up. (Terrain uses image-space coordinates, see fs_main.)
    let around = atan2(in.position.y, in.position.x) / (2.0 * PI) * WOOD_TILES;
    out.object_uv = vec2<f32>(around, in.position.z * in.offset_scale.w / WOOD_TILE_HEIGHT);
    return out;
}

struct GBuffer {
    @location(0) albedo: vec4<f32>,
    // xyz: normal blended towards the HLP normal; w: TAM tiles per pixel (for the mip level)
    @location(1) normal: vec4<f32>,
    // x: linear depth (m); y: HLP radius in pixels (0 without HLP)
    @location(2) depth: vec2<f32>,
    // x: object ID; y: part kind << 24 | HLP index + 1 (the patch ID of thesis Fig. 5.7)
    @location(3) ids: vec2<u32>,
    // xy: hatch texture coordinates T (tiles); zw: E, the HLP normal's screen direction (y up)
    @location(4) hatch: vec4<f32>,
};

// Thesis eq. 6.3–6.6: T = R + f(A)·Q_VO·O, with O the pixel's offset from the projected HLP
// centre, brought to the HLP sphere at the centre's depth and expressed in tiles (m/π).
fn hybrid_uv(frag: vec2<f32>, in: VertexOut, style: LayerStyle) -> vec2<f32> {
    let center_ndc = in.hlp_clip.xy / in.hlp_clip.w;
    let center_px = (center_ndc * vec2<f32>(0.5, -0.5) + 0.5) * vec2<f32>(frame.viewport.z, frame.viewport.y);
    let depth = in.hlp_depth_radius.x;
    let radius = max(in.hlp_depth_radius.y, 1e-4);
    let d = (frag - center_px) * metres_per_px(depth) / radius * (style.hatch.x / PI);
    let o = vec2<f32>(d.x, -d.y);
    let q = vec2<f32>(frame.roll.x * o.x - frame.roll.y * o.y, frame.roll.y * o.x + frame.roll.x * o.y);
    let dz = (in.view_depth - (depth - radius)) / radius;
    let f = 1.0 + style.hatch.y * dz * dz;
    return in.reference_uv + f * q;
}

// 4×4 ordered-dither value of a pixel in (0, 1): plants between two levels of detail draw
// complementary ranges of it, so the levels blend instead of popping.
fn screen_door(frag: vec2<f32>) -> f32 {
    let bayer = array<u32, 16>(0u, 8u, 2u, 10u, 12u, 4u, 14u, 6u, 3u, 11u, 1u, 9u, 15u, 7u, 13u, 5u);
    let p = vec2<u32>(frag) % vec2<u32>(4u);
    return (f32(bayer[p.y * 4u + p.x]) + 0.5) / 16.0;
}

// The normal of a billboard pixel: the HLP sphere's normal behind it (thesis eq. 4.7 for the
// sphere seen as an impostor), from the pixel's offset to the projected HLP centre.
fn billboard_normal(frag: vec2<f32>, in: VertexOut) -> vec3<f32> {
    let center_ndc = in.hlp_clip.xy / in.hlp_clip.w;
    let center_px = (center_ndc * vec2<f32>(0.5, -0.5) + 0.5) * vec2<f32>(frame.viewport.z, frame.viewport.y);
    let radius = max(in.hlp_depth_radius.y, 1e-4);
    var o = (frag - center_px) * metres_per_px(in.hlp_depth_radius.x) / radius;
    o = vec2<f32>(o.x, -o.y) / max(1.0, length(o));
    let view_normal = vec3<f32>(o, sqrt(max(0.0, 1.0 - dot(o, o))));
    // The view matrix is a rotation (plus translation): its transpose takes view to world.
    let r = mat3x3<f32>(frame.view[0].xyz, frame.view[1].xyz, frame.view[2].xyz);
    return normalize(transpose(r) * view_normal);
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> GBuffer {
    let frag = in.clip;
    let texel = textureSample(base_tex, base_sampler, in.uv) * material.base_color;
    let style = layer_style(in.ids.x);
    let has_hlp = in.hlp_depth_radius.y > 0.0;
    // Terrain is hatched in image space: seen from walking height a planar object-space mapping
    // is magnified far beyond the TAM's finest level in the foreground.
    let image_space = style.hlp.y > 0.5 || u32(material.params.y) == 0u;
    let t = select(select(in.object_uv, hybrid_uv(frag.xy, in, style), has_hlp), frag.xy / style.hatch.w, image_space);
    // Area-based footprint: the geometric mean of the two axes, so grazing terrain keeps
    // crisp (foreshortened) strokes instead of the blur of the coarsest axis.
    let tiles_per_px = sqrt(length(dpdx(t)) * length(dpdy(t)));
    if material.params.x >= 0.0 && texel.a < material.params.x {
        discard;
    }
    let dither = screen_door(frag.xy);
    if dither < in.lod_mask.x || dither >= in.lod_mask.y {
        discard;
    }
    var n = normalize(in.normal);
    if !front {
        n = -n;
    }
    var e = vec2<f32>(0.0);
    var radius_px = 0.0;
    if has_hlp {
        var nh = normalize(in.hlp_normal);
        if u32(material.params.y) == 3u {
            nh = billboard_normal(frag.xy, in);
            n = nh;
        }
        n = normalize(mix(n, nh, style.hlp.x));
        let ev = (frame.view * vec4<f32>(nh, 0.0)).xy;
        e = select(vec2<f32>(0.0), normalize(ev), length(ev) > 1e-4);
        radius_px = in.hlp_depth_radius.y / metres_per_px(in.hlp_depth_radius.x);
    }
    var out: GBuffer;
    // Thesis 6.2: abstract colour, the texture blended towards the material's average colour.
    out.albedo = vec4<f32>(mix(texel.rgb, material.average_color.rgb, style.hlp.w), 1.0);
    out.normal = vec4<f32>(n, tiles_per_px);
    out.depth = vec2<f32>(in.view_depth, radius_px);
    out.ids = in.ids;
    out.hatch = vec4<f32>(t, e);
    return out;
}
