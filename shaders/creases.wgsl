// The creases pass (`render::creases`, declared as `render::passes::CREASES`): over the
// composed sketch, the terrain's crease lines — valley bottoms (the DEM's drainage network,
// `prep::creases`), ridge crests (the inverted DEM's) and breaks of slope — as pen lines of constant width on
// screen, in the terrain style's ink, fixed to the ground. One quad per segment (six vertices,
// instanced) of those above the style's thresholds (`render::creases::CreaseSet` orders them so
// they are two prefixes), its ends extended by half a width so consecutive segments join. The blocks
// `marks` (the frame's camera, `render::marks::Marks`), the G-buffer's linear depth
// `depth_tex` and the segments `creases` are declared ahead of this file.
//
// Occlusion is a depth test against the scene's linear depth with a tolerance (3 % of the
// distance and 2 m): a line lies on the terrain the finest level of detail describes, which a
// coarser level drawn far away may cut through by a few metres.

// Half the line's width in pixels, and the feather of its edges (antialiasing).
const HALF_WIDTH: f32 = 0.75;
const FEATHER: f32 = 0.75;

struct CreaseOut {
    @builtin(position) clip: vec4<f32>,
    // Pixels from the line's axis.
    @location(0) across: f32,
    // Linear depth, metres.
    @location(1) depth: f32,
    // The segment's ink (0..1).
    @location(2) @interpolate(flat) ink: f32,
};

// The pixel of a clip-space point.
fn crease_pixel(clip: vec4<f32>) -> vec2<f32> {
    let ndc = clip.xy / clip.w;
    return (vec2<f32>(ndc.x, -ndc.y) * 0.5 + 0.5) * marks.size;
}

fn linear_depth(p: vec3<f32>) -> f32 {
    return -(marks.view * vec4<f32>(p, 1.0)).z;
}

@vertex
fn vs_creases(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> CreaseOut {
    use_style(LAYER_TERRAIN << LAYER_SHIFT);
    // The frame's instances are the valleys and ridges above their threshold (the buffer's
    // first `crease_areas`), then the breaks of slope above theirs (from `first_break`).
    let line = creases[select(instance - marks.crease_areas + marks.first_break, instance, instance < marks.crease_areas)];
    var out: CreaseOut;
    // Outside the clip volume: a segment left out draws nothing.
    out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
    out.across = 0.0;
    out.depth = 0.0;
    out.ink = 0.0;
    let ca = marks.view_proj * vec4<f32>(line.a, 1.0);
    let cb = marks.view_proj * vec4<f32>(line.b, 1.0);
    // Valleys and ridges by the area they drain (hectares), breaks of slope by their change
    // of slope (degrees); each against its style threshold.
    let is_break = line.kind == 2u;
    let threshold = select(post.terrain_crease_area, post.terrain_break_angle, is_break);
    if line.measure < threshold || ca.w <= 1e-3 || cb.w <= 1e-3 {
        return out;
    }
    let pa = crease_pixel(ca);
    let pb = crease_pixel(cb);
    let length_px = length(pb - pa);
    let d = select(vec2<f32>(1.0, 0.0), (pb - pa) / length_px, length_px > 1e-4);
    let n = vec2<f32>(-d.y, d.x);
    let quad = array<vec2<f32>, 6>(vec2<f32>(0.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(0.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(0.0, 1.0));
    let corner = quad[vertex];
    let w = HALF_WIDTH + FEATHER;
    let px = mix(pa - d * w, pb + d * w, corner.x) + n * w * corner.y;
    let ndc = px / marks.size * 2.0 - 1.0;
    out.clip = vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
    out.across = corner.y * w;
    out.depth = mix(linear_depth(line.a), linear_depth(line.b), corner.x);
    // Lines of small catchments fainter: full ink from four times the threshold up; breaks
    // from twice their threshold.
    let strength = select(0.5 + 0.25 * log2(line.measure / threshold), line.measure / threshold - 0.5, is_break);
    out.ink = post.terrain_creases * saturate(strength);
    return out;
}

@fragment
fn fs_creases(in: CreaseOut) -> @location(0) vec4<f32> {
    use_style(LAYER_TERRAIN << LAYER_SHIFT);
    let scene = textureLoad(depth_tex, vec2<i32>(in.clip.xy), 0).r;
    if in.depth > scene * 1.03 + 2.0 {
        discard;
    }
    let coverage = saturate((HALF_WIDTH + FEATHER - abs(in.across)) / FEATHER);
    return vec4<f32>(post.ink, coverage * in.ink);
}
