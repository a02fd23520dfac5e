// Stage one: the G-buffer pass (thesis 8.2, NPAR §9). Terrain and instanced plant parts are
// drawn with one pipeline; each fragment writes albedo, the (HLP-blended) normal, linear depth,
// object and patch IDs, the hatch texture coordinates and the screen projection E of the HLP
// normal that the post passes need.

// The blocks `frame` (`render::gbuffer::GeometryFrame`), `layer` (`LayerStyle`: the
// geometry-pass parameters of one style slot) and `material` (`SurfaceMaterial`) are declared
// ahead of this file from their Rust definitions.

// The kind of surface a pipeline draws (`render::gbuffer::Surface`): 0 terrain, 1 wood,
// 2 foliage, 3 billboard, 4 vegetation mass. One pipeline per kind, so each shader holds only its kind's code:
// lavapipe runs both sides of every branch for every fragment.
override SURFACE: u32 = 0u;
// Whether the pipeline draws leaf particles (`vs_leaf`), which may be elliptical.
override LEAF_PARTICLES: bool = false;
// Whether the terrain has land-cover classes (`render::gbuffer::GeometryPass::terrain_pipeline`):
// without, its pixels skip the class lookup.
override LAND_COVER: bool = true;

@group(0) @binding(0) var<uniform> frame: GeometryFrame;
// Reference texture coordinates R_uv of every (instance, HLP) pair (thesis eq. 6.2).
@group(0) @binding(1) var<storage, read> references: array<vec2<f32>>;
// The style of the layer being drawn (thesis 8.2.8): every draw holds the instances of one
// style slot and binds that slot's block (a dynamic offset into the per-slot buffer). A lookup
// per fragment by the object ID's layer code cost more than the rest of the shading on
// lavapipe, and indexing a uniform array with a computed slot leaked memory every frame in
// its version 22.3 (see tests/memory.rs).
@group(0) @binding(2) var<uniform> layer: LayerStyle;
// The land-cover classes of the ground (`render::ground_cover`), entry 0 the plain ground; the
// terrain's texture holds each cell's class index in its alpha.
@group(0) @binding(3) var<storage, read> cover: array<CoverStyle>;
@group(1) @binding(0) var<uniform> material: SurfaceMaterial;
@group(1) @binding(1) var base_tex: texture_2d<f32>;
@group(1) @binding(2) var base_sampler: sampler;

const NO_HLP: u32 = 0xffffffffu;
// Albedo alpha of a leaf-outline texel (thesis eq. 4.1), which the compose pass draws in ink
// (`outline_ink` in compose.wgsl); other geometry writes 1, the background 0.
const OUTLINE_ALPHA: f32 = 0.75;
const PI: f32 = 3.14159265;
const WOOD_TILES: f32 = 4.0;
const WOOD_TILE_HEIGHT: f32 = 1.5;
// The surface kind of vegetation masses (`render::gbuffer::Surface::Mass`).
const MASS: u32 = 4u;
// Radius in pixels of its sphere below which a billboard's alpha cutoff falls towards zero.
const DOT_RADIUS_PX: f32 = 2.0;
// Width in pixels of a vegetation mass's outline.
const MASS_OUTLINE_PX: f32 = 1.25;

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
    // per instance: xy screen-door range of a level-of-detail blend (all pixels: 0..1); zw a
    // data layer's HLP abstraction for the plant and its weight (D3, see `plant_abstraction`)
    @location(9) lod_mask: vec4<f32>,
    // per instance: a far reference point (world centre, radius) replacing the HLP sphere in
    // the parametrizations; radius 0: the plant's own HLPs (thesis 7.3)
    @location(15) reference_sphere: vec4<f32>,
    // foliage: the implicit surface's normal N_s scaled by the ambient coefficient k_a (Luft
    // et al. eq. 4, §3.3), model space; billboards: the mean k_a of their leaves along z (only
    // the length counts); zero for terrain and wood ("none"); vegetation masses: their colour
    // (linear RGB, and their uv holds the distance to the mass's edge and the height of its
    // plants, see `mass_cover`)
    @location(13) implicit: vec3<f32>,
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
    @location(9) @interpolate(flat) lod_mask: vec4<f32>,
    // the plant's own HLP sphere for billboard normals: centre in NDC, view depth, radius
    @location(10) @interpolate(flat) own_sphere: vec4<f32>,
    // leaf particles: xy the position in the particle, (±1, ±1) at its corners; z 1 for an
    // elliptical leaf (0 otherwise, and for every mesh vertex)
    @location(14) leaf: vec3<f32>,
    // k_a·N_s in world space (zero: none)
    @location(11) implicit: vec3<f32>,
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
    return select(2.0 * depth * frame.tan_half_fov / frame.height, frame.plan_metres_per_pixel, frame.plan_metres_per_pixel > 0.0);
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

// How far towards full abstraction a plant `depth` metres away along the view is taken
// (thesis 7.3, "increased abstraction of the background"): `distance_abstraction` times a
// smoothstep from `abstraction_near` to `abstraction_far`.
fn distance_share(depth: f32) -> f32 {
    return layer.distance_abstraction * smoothstep(layer.abstraction_near, layer.abstraction_far, depth);
}

// A style value `v` raised towards 1 by the distance share `d`.
fn with_distance(v: f32, d: f32) -> f32 {
    return v + (1.0 - v) * d;
}

// The HLP abstraction 1 − f (eq. 4.8) of a plant at `at`: its layer style's raised with its
// distance, moved towards the value a data layer maps onto abstraction at the plant's position
// by that mapping's weight (thesis Table 9.1; `lod_mask.zw`, zero without such a mapping).
fn plant_abstraction(lod_mask: vec4<f32>, at: vec3<f32>) -> f32 {
    return mix(with_distance(layer.hlp_abstraction, distance_share(view_depth(at))), lod_mask.z, lod_mask.w);
}

fn view_depth(world: vec3<f32>) -> f32 {
    // Linear depth along the view axis, in metres (view space looks down -z).
    return -(frame.view * vec4<f32>(world, 1.0)).z;
}

@vertex
fn vs_main(in: VertexIn) -> VertexOut {
    // Leaves only: billboards (kind 3) already stand for their HLP sphere.
    let abstraction = select(0.0, plant_abstraction(in.lod_mask, in.offset_scale.xyz), SURFACE == 2u);
    return vertex_out(in, hlp_blend(in.position, in.hlp, abstraction));
}

// What the fragment shader needs of the vertex `in` placed at the model-space position `p`
// (after HLP abstraction): shared by mesh vertices and leaf-particle corners.
fn vertex_out(in: VertexIn, p: vec3<f32>) -> VertexOut {
    let world = to_world(p, in);
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = rotate_z(in.normal, in.rotation);
    out.implicit = rotate_z(in.implicit, in.rotation);
    out.uv = in.uv;
    out.view_depth = view_depth(world);
    let has_hlp = in.hlp.w > 0.0;
    // A mass is one patch: its grid reference points place strokes, they draw no contours.
    let patch_id = select(0u, in.hlp_index + 1u, has_hlp && SURFACE != MASS);
    out.ids = vec2<u32>(in.object_id, (SURFACE << 24u) | patch_id);
    let center = to_world(in.hlp.xyz, in);
    out.hlp_normal = world - center;
    // Thesis 7.3: far plants take their hatching and silhouette parametrization from a shared
    // reference point; their normals still come from their own sphere.
    let far = in.reference_sphere.w > 0.0;
    let reference = select(vec4<f32>(center, in.hlp.w * in.offset_scale.w), in.reference_sphere, far);
    out.hlp_clip = frame.view_proj * vec4<f32>(reference.xyz, 1.0);
    out.hlp_depth_radius = vec2<f32>(view_depth(reference.xyz), reference.w);
    let own_clip = frame.view_proj * vec4<f32>(center, 1.0);
    out.own_sphere = vec4<f32>(own_clip.xy / own_clip.w, view_depth(center), in.hlp.w * in.offset_scale.w);
    out.lod_mask = in.lod_mask;
    out.reference_uv = vec2<f32>(0.0);
    if has_hlp {
        out.reference_uv = references[in.reference_base + in.hlp_index];
    }
    // Wood: a cylinder around the model's z axis, WOOD_TILES around and one tile per
    // WOOD_TILE_HEIGHT metres up. Terrain: its world xy in metres (`terrain_hatch`).
    let around = atan2(in.position.y, in.position.x) / (2.0 * PI) * WOOD_TILES;
    let wood_uv = vec2<f32>(around, in.position.z * in.offset_scale.w / WOOD_TILE_HEIGHT);
    out.object_uv = select(wood_uv, world.xy, SURFACE == 0u);
    out.leaf = vec3<f32>(0.0);
    return out;
}

// One corner of a leaf particle (`render::gbuffer::LeafVertex`, SPEC R1, R2) and its plant
// instance (the per-instance attributes of `VertexIn`).
struct LeafIn {
    // leaf centre (model space)
    @location(0) center: vec3<f32>,
    // which corner: (s, t) in {-1, 1}²
    @location(1) corner: vec2<f32>,
    // the leaf's in-plane axes times their half sizes (texture u and v grow along them)
    @location(2) axis_u: vec3<f32>,
    @location(3) axis_v: vec3<f32>,
    @location(4) normal: vec3<f32>,
    @location(10) uv: vec2<f32>,
    @location(11) hlp: vec4<f32>,
    @location(12) hlp_index: u32,
    // the share of the leaf rectangle its texture covers (an elliptical leaf keeps that area)
    @location(13) coverage: f32,
    // the leaf's implicit-surface illumination k_a·N_s, as `VertexIn.implicit`
    @location(14) implicit: vec3<f32>,
    @location(5) offset_scale: vec4<f32>,
    @location(6) rotation: vec2<f32>,
    @location(7) object_id: u32,
    @location(8) reference_base: u32,
    @location(9) lod_mask: vec4<f32>,
    @location(15) reference_sphere: vec4<f32>,
};

// Leaf modes (`render::style::LeafMode`).
const LEAF_BILLBOARD: u32 = 1u;
const LEAF_REORIENTED: u32 = 2u;
const LEAF_ELLIPTICAL: u32 = 3u;
// Ratio of an elliptical leaf's long axis (along the HLP tangent) to its short axis.
const ELLIPSE_ASPECT: f32 = 2.5;

// The unit vector in the plane normal to the unit vector `n` closest to `v` (any one when `v`
// is along `n`).
fn in_plane(v: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let w = v - n * dot(v, n);
    if length(w) > 1e-5 {
        return normalize(w);
    }
    let a = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(n.x) > 0.9);
    return normalize(a - n * dot(a, n));
}

// Leaf particles (thesis 4.1–4.2, ch. 7; NPAR §4): one quad per leaf, placed about the leaf's
// centre moved by the HLP abstraction (eq. 4.8–4.9) and sized by `leaf_size` and the share of
// leaves drawn (`material.particle_scale`), turned per mode: facing the camera (billboard, SPEC R2),
// with its normal along N_HLP = P − C pointing away from the HLP centre (eq. 4.7; thesis 4.2
// "children book"), or as an ellipse tangent to the HLP sphere whose long axis runs around the
// HLP's vertical axis ("Van Gogh", NPAR Fig. 3). The rest is the mesh vertices' `vertex_out`.
@vertex
fn vs_leaf(leaf: LeafIn) -> VertexOut {
    let center = hlp_blend(leaf.center, leaf.hlp, plant_abstraction(leaf.lod_mask, leaf.offset_scale.xyz));
    let from_hlp = center - leaf.hlp.xyz;
    let nh = select(leaf.normal, normalize(from_hlp), leaf.hlp.w > 0.0 && length(from_hlp) > 1e-6);
    var half = vec2<f32>(length(leaf.axis_u), length(leaf.axis_v));
    var a0 = leaf.axis_u / max(half.x, 1e-9);
    var a1 = leaf.axis_v / max(half.y, 1e-9);
    var n = leaf.normal;
    // +1 when (u, v, normal) is right-handed: the leaf's index order keeps its front face on the
    // normal's side, so turned quads keep the handedness.
    let hand = select(-1.0, 1.0, dot(cross(leaf.axis_u, leaf.axis_v), leaf.normal) >= 0.0);
    var ellipse = 0.0;
    let mode = layer.leaf_mode;
    if mode == LEAF_BILLBOARD {
        // The camera's right, up and backward axes (rows of the view matrix) in model space.
        let inverse = vec2<f32>(leaf.rotation.x, -leaf.rotation.y);
        let right = rotate_z(vec3<f32>(frame.view[0].x, frame.view[1].x, frame.view[2].x), inverse);
        let up = rotate_z(vec3<f32>(frame.view[0].y, frame.view[1].y, frame.view[2].y), inverse);
        let back = rotate_z(vec3<f32>(frame.view[0].z, frame.view[1].z, frame.view[2].z), inverse);
        a0 = hand * right;
        a1 = up;
        n = select(-leaf.normal, leaf.normal, dot(leaf.normal, back) >= 0.0);
    } else if mode == LEAF_REORIENTED {
        n = nh;
        a0 = in_plane(a0, nh);
        a1 = hand * cross(nh, a0);
    } else if mode == LEAF_ELLIPTICAL {
        n = nh;
        a0 = in_plane(vec3<f32>(-nh.y, nh.x, 0.0), nh);
        a1 = hand * cross(nh, a0);
        // Half axes a = k·b with π·a·b the area the leaf's texture covers in its rectangle.
        let b = sqrt(4.0 * leaf.coverage * half.x * half.y / (PI * ELLIPSE_ASPECT));
        half = vec2<f32>(ELLIPSE_ASPECT * b, b);
        ellipse = 1.0;
    }
    let size = layer.leaf_size * material.particle_scale;
    let p = center + (a0 * half.x * leaf.corner.x + a1 * half.y * leaf.corner.y) * size;
    let vertex = VertexIn(p, n, leaf.uv, leaf.hlp, leaf.hlp_index, leaf.offset_scale, leaf.rotation,
        leaf.object_id, leaf.reference_base, leaf.lod_mask, leaf.reference_sphere, leaf.implicit);
    var out = vertex_out(vertex, p);
    out.leaf = vec3<f32>(leaf.corner, ellipse);
    return out;
}

struct GBuffer {
    @location(0) albedo: vec4<f32>,
    // xyz: normal blended towards the HLP normal; w: TAM tiles per pixel (for the mip level)
    @location(1) normal: vec4<f32>,
    // x: linear depth (m); y: HLP radius in pixels (0 without HLP; object-space terrain: the
    // share of its second stroke orientation, `TerrainHatch`)
    @location(2) depth: vec2<f32>,
    // x: object ID; y: part kind << 24 | HLP index + 1 (the patch ID of thesis Fig. 5.7)
    @location(3) ids: vec2<u32>,
    // xy: hatch texture coordinates T (tiles); zw: E, the HLP normal's screen direction (y up)
    // (object-space terrain: the coordinates of its two stroke orientations, `TerrainHatch`)
    @location(4) hatch: vec4<f32>,
};

// Thesis eq. 6.3–6.6: T = R + f(A)·Q_VO·O, with O the pixel's offset from the projected HLP
// centre, brought to the HLP sphere at the centre's depth and expressed in tiles (m/π).
fn hybrid_uv(frag: vec2<f32>, in: VertexOut) -> vec2<f32> {
    let center_ndc = in.hlp_clip.xy / in.hlp_clip.w;
    let center_px = (center_ndc * vec2<f32>(0.5, -0.5) + 0.5) * vec2<f32>(frame.width, frame.height);
    let depth = in.hlp_depth_radius.x;
    let radius = max(in.hlp_depth_radius.y, 1e-4);
    let d = (frag - center_px) * metres_per_px(depth) / radius * (layer.hatch_tiles / PI);
    let o = vec2<f32>(d.x, -d.y);
    let q = vec2<f32>(frame.roll.x * o.x - frame.roll.y * o.y, frame.roll.y * o.x + frame.roll.x * o.y);
    let dz = (in.view_depth - (depth - radius)) / radius;
    let f = 1.0 + layer.hatch_surface * dz * dz;
    return in.reference_uv + f * q;
}

// The terrain's strokes (`render::style::TerrainStrokes`), and a land-cover class's own
// (`scene::cover::CoverStrokes`: 0 the style's, 1 and 2 as the style's codes).
const TERRAIN_IMAGE: u32 = 0u;
const TERRAIN_CONTOUR: u32 = 1u;
const COVER_FURROWS: u32 = 3u;
const COVER_RIPPLES: u32 = 4u;
// Stroke orientations of object-space terrain hatching: a pixel blends the two quantized
// orientations nearest its own, each with hatch coordinates fixed to the ground, so a
// direction that varies over the slope never rotates (and swirls) the coordinates themselves.
const TERRAIN_ORIENTATIONS: f32 = 8.0;
// How much longer than across them the ground's footprint along the strokes may be before it
// sets their scale (`terrain_hatch`).
const TERRAIN_ANISOTROPY: f32 = 4.0;

// What the G-buffer holds of object-space terrain hatching (compose.wgsl's `terrain_layers`
// reads it): `hatch` the TAM coordinates of the two orientations at the finer stroke scale,
// `tiles_per_px` the footprint at that scale and `weight` the second orientation's share.
struct TerrainHatch {
    hatch: vec4<f32>,
    tiles_per_px: f32,
    weight: f32,
};

// Object-space terrain strokes (Bénard et al. 2010, "infinite zoom" of a fractalized
// texture): the TAM is laid on the ground's xy at two power-of-two scales, 2^k and 2^(k+1)
// metres per tile, chosen from the pixel's footprint so that a tile of the finer one covers
// between a half and one `terrain_tile` (half `image_hatch_scale`: the coarser one never
// magnifies a TAM made for that scale) in pixels; the compose pass blends the two by the
// fractional part of the scale, and the TAM's mip levels keep the stroke width (Praun et al.
// 2001). The orientation weight is sharpened (a quarter of the way on either side of a bin is
// that bin alone) so fewer pixels show two half-strength stroke sets. The stroke
// direction follows the land (Bratkova et al. 2009, Buchin et al. 2011): the fall line is the
// horizontal part of the normal (downhill), the contour direction its perpendicular; on
// near-flat ground it fades to a fixed direction instead of noise. A land-cover class may
// override the direction (`land`): furrows at a fixed angle on the ground, ripples across the
// view (the camera's right axis), as a panorama painter gives fields and water their own
// strokes (Bratkova et al. 2009).
fn terrain_hatch(world_xy: vec2<f32>, n: vec3<f32>, land: CoverStyle) -> TerrainHatch {
    let dx = dpdx(world_xy);
    let dy = dpdy(world_xy);
    let strokes = select(layer.terrain_strokes, land.strokes, land.strokes != 0u);
    var d = n.xy + vec2<f32>(0.01, 0.0);
    if strokes == TERRAIN_CONTOUR {
        d = vec2<f32>(-d.y, d.x);
    }
    if strokes == COVER_FURROWS {
        d = land.direction;
    }
    if strokes == COVER_RIPPLES {
        d = vec2<f32>(frame.view[0].x, frame.view[1].x) + vec2<f32>(1e-4, 0.0);
    }
    // The footprint across the strokes (metres of the ground per pixel, measured along the
    // spacing of the strokes): on ground seen at a grazing angle strokes running across the
    // view keep their spacing on screen (the scale grows with the foreshortening) and strokes
    // running towards the eye their width; along the strokes the footprint may be at most
    // TERRAIN_ANISOTROPY times longer, so their dashes do not shrink below a few pixels.
    // Maps whose strokes have no direction (stipples, scribbles: `Tam::directional`) are
    // sized by the footprint's area, so they are not stretched along the strokes.
    let along_dir = normalize(d);
    let across_dir = vec2<f32>(-along_dir.y, along_dir.x);
    let across = length(vec2<f32>(dot(across_dir, dx), dot(across_dir, dy)));
    let along = length(vec2<f32>(dot(along_dir, dx), dot(along_dir, dy)));
    let tam = select(layer.hatch_map, u32(land.hatch_map), land.hatch_map >= 0);
    let directional = tam >= 32u || ((frame.directional_tams >> tam) & 1u) == 1u;
    let area = sqrt(length(dx) * length(dy));
    let metres_per_px = select(area, clamp(across, along / TERRAIN_ANISOTROPY, area * 2.0), directional);
    let scale = exp2(floor(log2(max(metres_per_px * layer.terrain_tile, 1e-6))));
    let x = fract(atan2(d.y, d.x) / PI) * TERRAIN_ORIENTATIONS;
    let a = floor(x);
    let b = a + 1.0;
    let p = world_xy / scale;
    let ra = vec2<f32>(cos(a * PI / TERRAIN_ORIENTATIONS), sin(a * PI / TERRAIN_ORIENTATIONS));
    let rb = vec2<f32>(cos(b * PI / TERRAIN_ORIENTATIONS), sin(b * PI / TERRAIN_ORIENTATIONS));
    // u along the stroke (the TAM's strokes run along u), v across.
    let ta = vec2<f32>(dot(p, ra), ra.x * p.y - ra.y * p.x);
    let tb = vec2<f32>(dot(p, rb), rb.x * p.y - rb.y * p.x);
    return TerrainHatch(vec4<f32>(ta, tb), metres_per_px / scale, smoothstep(0.25, 0.75, x - a));
}

// The land-cover class index of a terrain pixel at drape coordinates `uv` (the alpha of the
// terrain's texture, `scene::cover::Drape::mip_chain`): read at the mip level of the pixel's
// footprint (whose classes are the mode of the finer ones), as the class that holds the most
// bilinear weight among the four nearest cells, so class borders run as smooth diagonals
// instead of cell staircases and never blend two classes into a third.
fn cover_class(uv: vec2<f32>) -> u32 {
    let texels = uv * vec2<f32>(textureDimensions(base_tex, 0));
    let footprint = sqrt(length(dpdx(texels)) * length(dpdy(texels)));
    let level = clamp(i32(floor(log2(max(footprint, 1.0)))), 0, i32(textureNumLevels(base_tex)) - 1);
    let size = vec2<i32>(textureDimensions(base_tex, level));
    let x = uv * vec2<f32>(size) - 0.5;
    let cell = vec2<i32>(floor(x));
    let f = x - floor(x);
    var classes: array<u32, 4>;
    var weights: array<f32, 4>;
    for (var k = 0; k < 4; k++) {
        let o = vec2<i32>(k & 1, k >> 1u);
        let q = clamp(cell + o, vec2<i32>(0), size - 1);
        classes[k] = u32(round(textureLoad(base_tex, q, level).a * 255.0));
        weights[k] = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1);
    }
    var best = classes[0];
    var best_weight = -1.0;
    for (var a = 0; a < 4; a++) {
        var w = 0.0;
        for (var b = 0; b < 4; b++) {
            w += select(0.0, weights[b], classes[b] == classes[a]);
        }
        if w > best_weight {
            best_weight = w;
            best = classes[a];
        }
    }
    return min(best, arrayLength(&cover) - 1u);
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
    let center_px = (in.own_sphere.xy * vec2<f32>(0.5, -0.5) + 0.5) * vec2<f32>(frame.width, frame.height);
    let radius = max(in.own_sphere.w, 1e-4);
    var o = (frag - center_px) * metres_per_px(in.own_sphere.z) / radius;
    o = vec2<f32>(o.x, -o.y) / max(1.0, length(o));
    let view_normal = vec3<f32>(o, sqrt(max(0.0, 1.0 - dot(o, o))));
    // The view matrix is a rotation (plus translation): its transpose takes view to world.
    let r = mat3x3<f32>(frame.view[0].xyz, frame.view[1].xyz, frame.view[2].xyz);
    return normalize(transpose(r) * view_normal);
}

// Vegetation masses (`prep::masses`, thesis 7.3): the share of the screen-door values a mass
// pixel covers, `LodSettings::mass_cover` of the height in pixels of the plants it stands for
// (`uv.y`, metres) across the blend band (`lod_mask`, pixels), so the mass takes over exactly
// the pixels its plants leave.
fn mass_cover(in: VertexOut) -> f32 {
    let px = in.uv.y / metres_per_px(in.view_depth);
    let band = in.lod_mask.xy;
    return select(select(0.0, 1.0, px < band.x), saturate((band.y - px) / (band.y - band.x)), band.y > band.x);
}

// The albedo alpha of a mass pixel: within MASS_OUTLINE_PX of the mass's outer edge (`uv.x`,
// metres) its outline, inked by the layer's `mass_outline` as leaf outlines are (thesis eq.
// 4.1, `outline_ink` in compose.wgsl: ink (1 − α)·4).
fn mass_alpha(in: VertexOut) -> f32 {
    return select(1.0, 1.0 - 0.25 * layer.mass_outline, in.uv.x < MASS_OUTLINE_PX * metres_per_px(in.view_depth));
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> GBuffer {
    let frag = in.clip;
    // A split view's "before" half: the compared layer's plants, leaves and masses are left
    // out left of the line (`render::compare`); the terrain is never compared.
    if SURFACE != 0u && frag.x < layer.hidden_left_of {
        discard;
    }
    let texel = textureSample(base_tex, base_sampler, in.uv) * material.base_color;
    let has_hlp = SURFACE >= 2u && in.hlp_depth_radius.y > 0.0;
    let image_space = select(layer.image_space != 0u, layer.terrain_strokes == TERRAIN_IMAGE, SURFACE == 0u);
    let t = select(select(in.object_uv, hybrid_uv(frag.xy, in), has_hlp), frag.xy / layer.image_hatch_scale, image_space);
    // Area-based footprint: the geometric mean of the two axes, so grazing terrain keeps
    // crisp (foreshortened) strokes instead of the blur of the coarsest axis.
    let tiles_per_px = sqrt(length(dpdx(t)) * length(dpdy(t)));
    // Thesis 4.1: the alpha threshold α_t moves from α_max (the original leaf) to α_min (the
    // most abstract shape of the leaf shape map) with the leaf shape. `inside` is how far the
    // texel lies inside the shape: α − α_t, or 1 − (s² + t²) on an elliptical leaf (the
    // ellipse equation in the particle's coordinates).
    var alpha_t = mix(material.alpha_cutoff, material.alpha_min, layer.leaf_shape);
    // A billboard only a few pixels across samples a mip level where its texels blend with
    // the transparent gutter: its cutoff falls with its size, so a far lone plant stays a dot.
    if SURFACE == 3u {
        alpha_t *= saturate(in.own_sphere.w / metres_per_px(in.own_sphere.z) / DOT_RADIUS_PX);
    }
    let elliptical = LEAF_PARTICLES && in.leaf.z > 0.5;
    let inside = select(texel.a - alpha_t, 1.0 - dot(in.leaf.xy, in.leaf.xy), elliptical);
    if material.alpha_cutoff >= 0.0 && inside < 0.0 {
        discard;
    }
    // Thesis eq. 4.1: leaf texels with α − α_t ≤ Δα are the leaf's outline, drawn in ink by
    // the compose pass (albedo alpha OUTLINE_ALPHA instead of 1).
    let outline = SURFACE == 2u && layer.leaf_outline > 0.0 && inside <= layer.leaf_outline;
    // Terrain has no levels of detail to blend; a mass covers what its plants leave.
    let dither = screen_door(frag.xy);
    if SURFACE != 0u && SURFACE != MASS && (dither < in.lod_mask.x || dither >= in.lod_mask.y) {
        discard;
    }
    // A chunk of masses between two levels of its domes draws each in its share of the dither
    // values (`lod_mask.zw`), so the coarser level blends in instead of popping.
    if SURFACE == MASS && (dither >= mass_cover(in) || dither < in.lod_mask.z || dither >= in.lod_mask.w) {
        discard;
    }
    var n = normalize(in.normal);
    if !front {
        n = -n;
    }
    // Luft et al. 2007: foliage normals realigned to the implicit surface (§3.3,
    // N' = mix(N, N_s)), and the ambient coefficient k_a (eq. 4) carried as the attribute's
    // length; k_a' = mix(1, k_a, ambient_occlusion) goes into the G-buffer normal's length
    // (the paper's encoding) for the post passes' ambient term.
    let ka = length(in.implicit);
    var ambient_k = 1.0;
    if SURFACE >= 2u && SURFACE != MASS && ka > 1e-4 {
        let blended = mix(n, in.implicit / ka, layer.implicit_normals);
        n = select(in.implicit / ka, normalize(blended), length(blended) > 1e-4);
        ambient_k = max(mix(1.0, ka, layer.ambient_occlusion), 1e-3);
    }
    var e = vec2<f32>(0.0);
    var radius_px = 0.0;
    if has_hlp {
        var nh = normalize(in.hlp_normal);
        if SURFACE == 3u {
            nh = billboard_normal(frag.xy, in);
            n = nh;
        }
        // A mass keeps its own smooth normals: the reference point only places the strokes.
        if SURFACE == MASS {
            nh = n;
        }
        n = normalize(mix(n, nh, with_distance(layer.normal_blend, distance_share(in.view_depth))));
        let ev = (frame.view * vec4<f32>(nh, 0.0)).xy;
        e = select(vec2<f32>(0.0), normalize(ev), length(ev) > 1e-4);
        radius_px = in.hlp_depth_radius.y / metres_per_px(in.hlp_depth_radius.x);
    }
    var out: GBuffer;
    // Thesis 6.2: abstract colour, the texture blended towards the material's average colour.
    // Elliptical leaves take the material's average colour: their shape is not the texture's.
    let color = select(texel.rgb, material.average_color, elliptical);
    out.albedo = vec4<f32>(mix(color, material.average_color, layer.color_abstraction), select(1.0, OUTLINE_ALPHA, outline));
    if SURFACE == MASS {
        out.albedo = vec4<f32>(in.implicit, mass_alpha(in));
    }
    out.normal = vec4<f32>(n * ambient_k, tiles_per_px);
    out.depth = vec2<f32>(in.view_depth, radius_px);
    out.ids = in.ids;
    out.hatch = vec4<f32>(t, e);
    if SURFACE == 0u {
        // The land-cover class goes into the terrain's patch ID (which has no HLP).
        var land = 0u;
        if LAND_COVER {
            land = cover_class(in.uv);
        }
        out.ids = vec2<u32>(in.ids.x, in.ids.y | land);
        if !image_space {
            let terrain = terrain_hatch(in.object_uv, n, cover[land]);
            out.hatch = terrain.hatch;
            out.normal.w = terrain.tiles_per_px;
            out.depth.y = terrain.weight;
        }
    }
    return out;
}
