// D2 projection of data layers (thesis 9.3, Fig. 9.2): for every pixel the world position is
// recovered from the linear depth (inverse projection, then inverse view), the fields are
// looked up orthographically along z (u = a·x + b, v = c·y + d in scene metres), blended in
// time (eq. 9.4) and mapped onto visual features (Table 9.1). The result is one Rgba32Uint
// texel per pixel that the compose pass reads through `shaders/data_common.wgsl`:
//   x  colour tint, RGBA8: the sketch is multiplied by rgb (white: unchanged)
//   y  hatch tone and its weight, unorm16 each: t' = mix(t, tone, weight)
//   z  TAM index (bits 0–7) and SAM channel + 1 (bits 8–15; 0 = chosen by tone)
//   w  bit 0: 1 where silhouettes are drawn, 0 where silhouette density drops them;
//      bits 8–15, 16–23, 24–31: darkness (unorm8) of the coloured hatching of slots 0, 1, 2
//      (hatch colour, thesis 9.2.2, Fig. 9.3; 0 = none). The slots' inks and stroke
//      directions are a uniform of the compose pass (`HatchColors`, `render::projection`).

// The block `data` (`render::projection::DataBlock`), its slots (`DataSlot`) and the
// bindings are declared by the pass's declaration (`render::passes::DATA`): per slot the
// bracketing time steps t_i and t_i+1 (`lowerN`, `upperN`: R32Float grids) and the colour
// table (`lutN`).

// Grid cells without data hold this value (NaN is not reliable in shaders).
const NODATA: f32 = -3.0e38;
const NO_VALUE: f32 = -1.0e38;
const BACKGROUND: f32 = 1.0e6;
const SAM_CHANNELS: u32 = 4u;

// Thesis 9.3: camera-space position from depth by the inverse projection, world position by
// the inverse view (one matrix here). The NDC depth of linear depth d comes from the
// projection's own z and w rows, so perspective and plan views are treated alike.
fn world_position(frag: vec2<f32>, depth: f32) -> vec3<f32> {
    let ndc_xy = vec2<f32>(frag.x / data.width * 2.0 - 1.0, 1.0 - frag.y / data.height * 2.0);
    let z = (data.depth_to_clip.x * depth + data.depth_to_clip.y) / (data.depth_to_clip.z * depth + data.depth_to_clip.w);
    let world = data.inv_view_proj * vec4<f32>(ndc_xy, z, 1.0);
    return world.xyz / world.w;
}

fn texel(tex: texture_2d<f32>, c: vec2<i32>) -> f32 {
    return textureLoad(tex, clamp(c, vec2<i32>(0), vec2<i32>(textureDimensions(tex)) - 1), 0).r;
}

// D1: scalars bilinearly between cell centres; a point with a nodata neighbour of non-zero
// weight is nodata. Outside the grid there is no data. (These functions select instead of
// returning early where pixels differ: on lavapipe 22.3 a `return` taken by some pixels of a
// quad leaked memory on every draw, ~2 MB per frame; see tests/memory.rs.)
fn bilinear(tex: texture_2d<f32>, uv: vec2<f32>) -> f32 {
    let st = uv * vec2<f32>(textureDimensions(tex)) - 0.5;
    let i = vec2<i32>(floor(st));
    let f = st - floor(st);
    let w = vec4<f32>((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    let v = vec4<f32>(texel(tex, i), texel(tex, i + vec2<i32>(1, 0)), texel(tex, i + vec2<i32>(0, 1)), texel(tex, i + vec2<i32>(1, 1)));
    let outside = any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0));
    let missing = any((v < vec4<f32>(NO_VALUE)) & (w > vec4<f32>(0.0)));
    return select(dot(select(v, vec4<f32>(0.0), v < vec4<f32>(NO_VALUE)), w), NODATA, outside || missing);
}

// D1: labels at the nearest cell, with textureLoad (label indices must never be blended).
fn nearest(tex: texture_2d<f32>, uv: vec2<f32>) -> f32 {
    let outside = any(uv < vec2<f32>(0.0)) || any(uv >= vec2<f32>(1.0));
    return select(texel(tex, vec2<i32>(floor(uv * vec2<f32>(textureDimensions(tex))))), NODATA, outside);
}

// The field of a slot at the world point: nearest label of the nearest step, or eq. 9.4
// S(t) = (1 - u_t) S(t_i) + u_t S(t_i+1) for scalars (nodata where a weighted step is).
fn field_value(slot: DataSlot, lower: texture_2d<f32>, upper: texture_2d<f32>, world: vec3<f32>) -> f32 {
    let uv = vec2<f32>(slot.uv.x * world.x + slot.uv.y, slot.uv.z * world.y + slot.uv.w);
    let a = bilinear(lower, uv);
    let u = slot.time_weight;
    let b = select(bilinear(upper, uv), a, u <= 0.0);
    let scalar = select(mix(a, b, u), NODATA, a < NO_VALUE || b < NO_VALUE);
    return select(scalar, nearest(lower, uv), slot.label != 0u);
}

// The value as a position 0..1 along the mapping: scalars over the range (reversed if asked),
// labels by class index.
fn normalized(slot: DataSlot, v: f32) -> f32 {
    var n = 0.0;
    if slot.label != 0u {
        n = v / max(slot.classes - 1.0, 1.0);
    } else {
        n = (v - slot.range_low) / (slot.range_high - slot.range_low);
    }
    n = saturate(n);
    return select(n, 1.0 - n, slot.reverse != 0u);
}

// The colour table entry: scalars by round((v - lo)/(hi - lo)·255) (the table is already
// reversed), labels by class index (`fields::Lut::index_of`).
fn lut_color(slot: DataSlot, lut: texture_2d<f32>, v: f32) -> vec4<f32> {
    var i = round(v);
    if slot.label == 0u {
        i = round((v - slot.range_low) / (slot.range_high - slot.range_low) * 255.0);
    }
    return textureLoad(lut, vec2<i32>(i32(clamp(i, 0.0, 255.0)), 0), 0);
}

fn hash(x: u32) -> u32 {
    var h = x * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    return (h >> 22u) ^ h;
}

struct Features {
    tint: vec3<f32>,
    tone: vec2<f32>,
    tam: u32,
    sam: u32,
    keep: u32,
    // darkness of the coloured hatching of each slot
    hatch: vec3<f32>,
};

// Applies the value of slot `index` to the features (Table 9.1 targets); nodata selects the
// empty feature 0 (no early return, see `bilinear`).
fn apply(index: u32, slot: DataSlot, lut: texture_2d<f32>, v: f32, object: u32, f: ptr<function, Features>) {
    let feature = select(0u, slot.feature, v >= NO_VALUE);
    let n = normalized(slot, v);
    let label = u32(max(round(v), 0.0));
    switch feature {
        case 1u: {
            let c = lut_color(slot, lut, v);
            (*f).tint *= mix(vec3<f32>(1.0), c.rgb, c.a);
        }
        case 2u: {
            // High values hatch darkly.
            (*f).tone = vec2<f32>(1.0 - n, slot.opacity);
        }
        case 3u: {
            (*f).tam = label % data.tams;
        }
        case 4u: {
            (*f).sam = label % SAM_CHANNELS + 1u;
        }
        case 5u: {
            // A plant keeps its silhouettes with probability n (per object, stable in time).
            let keep = f32(hash(object) & 0xffffu) / 65535.0 < n * slot.opacity + (1.0 - slot.opacity);
            (*f).keep = select(0u, 1u, keep);
        }
        case 6u: {
            // Thesis 9.2.2, Fig. 9.3: high values hatch darkly in the slot's own ink.
            (*f).hatch[index] = n;
        }
        default: {}
    }
}

@fragment
fn fs_data(@builtin(position) frag: vec4<f32>) -> @location(0) vec4<u32> {
    let p = vec2<i32>(frag.xy);
    // Without a hatch-pattern mapping a pixel keeps the TAM of its layer's style (thesis 8.2.8),
    // or of its land-cover class.
    let ids = textureLoad(id_tex, p, 0).xy;
    let own_tam = cover_tam(ids, styles.slots[style_slot(ids.x)].hatch_map);
    var f = Features(vec3<f32>(1.0), vec2<f32>(0.0), own_tam, 0u, 1u, vec3<f32>(0.0));
    let depth = textureLoad(depth_tex, p, 0).r;
    // The background has no data. Selected, not branched on: see `bilinear`.
    let ground = depth < BACKGROUND;
    let world = world_position(frag.xy, select(0.0, depth, ground));
    let object = textureLoad(id_tex, p, 0).x;
    let v0 = select(NODATA, field_value(data.slots[0], lower0, upper0, world), ground);
    let v1 = select(NODATA, field_value(data.slots[1], lower1, upper1, world), ground);
    let v2 = select(NODATA, field_value(data.slots[2], lower2, upper2, world), ground);
    apply(0u, data.slots[0], lut0, v0, object, &f);
    apply(1u, data.slots[1], lut1, v1, object, &f);
    apply(2u, data.slots[2], lut2, v2, object, &f);
    let w = pack4x8unorm(vec4<f32>(0.0, f.hatch)) | f.keep;
    return vec4<u32>(pack4x8unorm(vec4<f32>(f.tint, 1.0)), pack2x16unorm(f.tone), f.tam | (f.sam << 8u), w);
}
