// The marks pass (`render::marks`, declared as `render::passes::MARKS`): over the composed
// sketch, comment pins drawn as a pen would — a short ink stem from the ground point up to a
// round head on paper, tinted by the comment's category, ringed in ink with a little pressure
// variation, with the comment's number in it — and the pen line of a before/after split view.
// One quad per mark (six vertices, instanced). The block `marks` (`Marks`), the G-buffer's
// linear depth `depth_tex` and the digit atlas `glyphs` are declared ahead of this file.
//
// Occlusion is a depth test against the scene's linear depth with a tolerance: a pin whose
// ground point lies behind nearer geometry (a hill, a tree) is hidden as a whole, and the
// pixels of a visible pin that nearer geometry covers are left out. The tolerance (10 % of
// the distance, at least 2 m, more on ground seen at a grazing angle) keeps a pin standing on
// the terrain it was placed on visible although another level of detail of that terrain, or
// grass and low shrubs at its foot, may lie slightly in front of it.

struct MarkOut {
    @builtin(position) clip: vec4<f32>,
    // Pixels from the pin's ground point, x right and y up (the split line: x from the line,
    // y down from the top).
    @location(0) local: vec2<f32>,
    // x: the head's radius (px), y: the height of the head's centre above the ground point
    // (px), z: the pin's linear depth (m), w: 1 for the split line, 0 for a pin.
    @location(1) @interpolate(flat) shape: vec4<f32>,
    // The ground point's pixel.
    @location(2) @interpolate(flat) anchor: vec2<f32>,
    // The number and the category.
    @location(3) @interpolate(flat) label: vec2<u32>,
};

// Half the width of the split line's quad in pixels (the line and its wobble).
const SPLIT_HALF: f32 = 3.0;
// Pins in a row of `marks.pins` (`render::marks::PIN_ROW`).
const PIN_ROW: u32 = 32u;
// Digits a head shows at most (numbers are shown modulo 10^4).
const MAX_DIGITS: u32 = 4u;

fn to_clip(px: vec2<f32>) -> vec4<f32> {
    let ndc = px / marks.size * 2.0 - 1.0;
    return vec4<f32>(ndc.x, -ndc.y, 0.0, 1.0);
}

@vertex
fn vs_marks(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> MarkOut {
    let quad = array<vec2<f32>, 6>(vec2<f32>(-1.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, 0.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0));
    let corner = quad[vertex];
    var out: MarkOut;
    out.label = vec2<u32>(0u);
    if instance >= marks.pin_count {
        let px = vec2<f32>(marks.split_x + corner.x * SPLIT_HALF, corner.y * marks.size.y);
        out.clip = to_clip(px);
        out.local = vec2<f32>(corner.x * SPLIT_HALF, px.y);
        out.shape = vec4<f32>(0.0, 0.0, 0.0, 1.0);
        out.anchor = vec2<f32>(marks.split_x, 0.0);
        return out;
    }
    let pin = marks.pins[instance / PIN_ROW][instance % PIN_ROW];
    let clip = marks.view_proj * vec4<f32>(pin.position, 1.0);
    let depth = -(marks.view * vec4<f32>(pin.position, 1.0)).z;
    let ndc = clip.xy / clip.w;
    let anchor = (vec2<f32>(ndc.x, -ndc.y) * 0.5 + 0.5) * marks.size;
    // The head is `head.x` metres across at the pin's distance, within `head.yz` pixels.
    let plan = marks.plan_metres_per_pixel > 0.0;
    let px_per_metre = select(marks.px_per_metre / max(depth, 1e-3), 1.0 / marks.plan_metres_per_pixel, plan);
    let radius = clamp(marks.head.x * px_per_metre, marks.head.y, marks.head.z);
    let height = 1.6 * radius + 8.0;
    let lo = vec2<f32>(-(radius + 2.0), -3.0);
    let hi = vec2<f32>(radius + 2.0, height + radius + 2.0);
    out.local = mix(lo, hi, vec2<f32>(corner.x * 0.5 + 0.5, corner.y));
    out.clip = to_clip(anchor + vec2<f32>(out.local.x, -out.local.y));
    // No pin whose ground point is behind the camera or off the image (a degenerate quad).
    if clip.w <= 0.0 || any(anchor < vec2<f32>(0.0)) || any(anchor >= marks.size) {
        out.clip = vec4<f32>(2.0, 2.0, 0.0, 1.0);
    }
    out.shape = vec4<f32>(radius, height, depth, 0.0);
    out.anchor = anchor;
    out.label = vec2<u32>(pin.number, pin.category);
    return out;
}

// The tint of a category's head (sRGB): idea, concern, question, other, then two more.
fn category_tint(category: u32) -> vec3<f32> {
    let tints = array<vec3<f32>, 6>(vec3<f32>(0.98, 0.80, 0.30), vec3<f32>(0.90, 0.42, 0.36),
        vec3<f32>(0.42, 0.62, 0.90), vec3<f32>(0.70, 0.70, 0.70), vec3<f32>(0.45, 0.75, 0.45),
        vec3<f32>(0.72, 0.52, 0.85));
    return tints[category % 6u];
}

// Coverage of the digit atlas at texel position `t` (bilinear over four texel reads).
fn glyph_coverage(t: vec2<f32>) -> f32 {
    let p = t - 0.5;
    let i = vec2<i32>(floor(p));
    let f = fract(p);
    let a = textureLoad(glyphs, i, 0).r;
    let b = textureLoad(glyphs, i + vec2<i32>(1, 0), 0).r;
    let c = textureLoad(glyphs, i + vec2<i32>(0, 1), 0).r;
    let d = textureLoad(glyphs, i + vec2<i32>(1, 1), 0).r;
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// Ink of the number `number` centred at `q` = 0 (pixels, y up) in a head of radius `radius`:
// the digits' ink box `radius` pixels tall (narrower for long numbers), one texel apart.
fn number_ink(q: vec2<f32>, number: u32, radius: f32) -> f32 {
    let n = number % 10000u;
    var digits = 1u;
    var top = 10u;
    while digits < MAX_DIGITS && n >= top {
        digits += 1u;
        top *= 10u;
    }
    let ink = marks.glyph_box;
    let advance = ink.z + 1.0;
    let width = f32(digits) * advance - 1.0;
    let scale = min(radius / ink.w, 1.55 * radius / width);
    let u = (q.x / scale) + width * 0.5;
    let v = ink.w * 0.5 - q.y / scale;
    let j = floor(u / advance);
    let within = u - j * advance;
    if u < 0.0 || v < 0.0 || v >= ink.w || j >= f32(digits) || within >= ink.z {
        return 0.0;
    }
    var place = 1u;
    for (var k = u32(j) + 1u; k < digits; k++) {
        place *= 10u;
    }
    let digit = (n / place) % 10u;
    let coverage = glyph_coverage(vec2<f32>(f32(digit) * marks.glyph_cell.x + ink.x + within, ink.y + v));
    // Magnified bitmap digits get crisp edges (a threshold on the filtered coverage).
    return mix(coverage, smoothstep(0.3, 0.7, coverage), saturate(scale - 1.0));
}

@fragment
fn fs_marks(in: MarkOut) -> @location(0) vec4<f32> {
    let ink = styles.slots[0].ink;
    let paper = styles.slots[0].paper;
    if in.shape.w > 0.5 {
        // The split line: a pen stroke, 1.5 px wide, wavering slightly down the image.
        let y = in.local.y;
        let wobble = 0.5 * sin(y * 0.045) + 0.3 * sin(y * 0.13 + 2.0);
        let coverage = saturate(1.25 - abs(in.local.x - wobble));
        return vec4<f32>(ink, 0.9 * coverage);
    }
    let depth = in.shape.z;
    let a = vec2<i32>(in.anchor);
    let at_ground = textureLoad(depth_tex, a, 0).x;
    // Ground seen at a grazing angle spans metres of depth per pixel: the tolerance grows by
    // the depth step to the smoother of the pixels above and below (at a silhouette one of
    // them is the far side, the other the same surface).
    let above = abs(textureLoad(depth_tex, a - vec2<i32>(0, 1), 0).x - at_ground);
    let below = abs(textureLoad(depth_tex, a + vec2<i32>(0, 1), 0).x - at_ground);
    let tolerance = max(max(2.0, 0.1 * depth), 1.5 * min(above, below));
    let here = textureLoad(depth_tex, vec2<i32>(in.clip.xy), 0).x;
    if at_ground < depth - tolerance || here < depth - tolerance {
        discard;
    }
    let radius = in.shape.x;
    let p = in.local;
    let q = p - vec2<f32>(0.0, in.shape.y);
    let r = length(q);
    let angle = atan2(q.y, q.x);
    // A hand-drawn ring: its radius wavers a little with the angle, its width with the pen's
    // pressure.
    let rim = radius * (1.0 + 0.025 * sin(3.0 * angle + f32(in.label.x % 7u) * 1.7));
    let pen = 1.3 + 0.6 * (0.5 + 0.5 * sin(angle + 0.8));
    let disk = saturate(rim - r + 0.5);
    let ring = saturate(pen * 0.5 + 0.5 - abs(r - (rim - pen * 0.5)));
    let digits = number_ink(q, in.label.x, radius) * disk;
    // The stem, thickening upwards to the head, and a short tick where it meets the ground.
    let along = saturate(p.y / in.shape.y);
    let stem = saturate(mix(0.55, 1.0, along) + 0.5 - abs(p.x)) * step(0.0, p.y) * step(p.y, in.shape.y - rim * 0.9);
    let tick = saturate(1.0 - length(vec2<f32>(p.x / 3.5, p.y / 1.2)));
    let strokes = max(max(ring, digits), max(stem, saturate(tick * 2.0)) * (1.0 - disk));
    let alpha = max(disk, strokes);
    if alpha <= 0.0 {
        discard;
    }
    let fill = mix(paper, category_tint(in.label.y), 0.5);
    return vec4<f32>(mix(fill, ink, strokes / alpha), alpha);
}
