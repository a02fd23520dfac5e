//! The uniform block of the post passes (`styles` in every post shader): one [`PostStyle`]
//! per style slot (thesis 8.2.8: every layer in its own style) and the frame's view rays.

use crate::render::style::{STYLE_SLOTS, Style};
use crate::render::uniforms::{Vec2f, Vec3f, Vec4f, gpu_block};
use crate::scene::camera::Camera;

gpu_block! {
    /// The post-pass parameters of one style slot, as the shaders read them (`post.…`).
    pub struct PostStyle {
        /// Contour scale c (thesis eq. 5.1).
        pub contour_scale: f32,
        /// Contour threshold t (eq. 5.1).
        pub contour_threshold: f32,
        /// Isolated-pixel threshold t' (eq. 5.2).
        pub isolated_pixel_threshold: f32,
        /// Isolated-pixel removal on (1) or off (0).
        pub isolated_pixel_removal: u32,
        /// Unit vector towards the sun (world).
        pub sun: Vec3f,
        /// Ambient light.
        pub ambient: f32,
        /// Albedo weight of the tone.
        pub albedo_weight: f32,
        /// Contrast scale about the reference (eq. 6.7).
        pub tone_contrast: f32,
        /// Reference L_ref (eq. 6.7).
        pub tone_reference: f32,
        /// Contour ink strength.
        pub contour_strength: f32,
        /// Tone bands (0: continuous).
        pub tone_levels: f32,
        /// Tone blur radius in pixels.
        pub tone_blur: f32,
        /// Tone levels of the style's TAM.
        pub tam_levels: f32,
        /// Texels across one tile of the style's TAM.
        pub tam_size: f32,
        /// Silhouette support width in pixels.
        pub silhouette_support: f32,
        /// SAM stretch c (eq. 5.5).
        pub silhouette_stretch: f32,
        /// Silhouette ink strength.
        pub silhouette_strength: f32,
        /// The art-map group (the compose pass that draws this slot).
        pub art_group: u32,
        /// cos and sin of the camera roll (the orientation vector V_O of thesis 5.2 follows it).
        pub roll: Vec2f,
        /// Hatch ink strength.
        pub hatch_strength: f32,
        /// Hatch brightness (tone lift, thesis 8.2.7).
        pub hatch_brightness: f32,
        /// The hatch tone's lift towards paper far away ([`Style::distance_simplification`]),
        /// from `abstraction_near` (none) to `abstraction_far` (all of it), metres of depth.
        pub distance_simplification: f32,
        /// See `distance_simplification`.
        pub abstraction_near: f32,
        /// See `distance_simplification`.
        pub abstraction_far: f32,
        /// How much surface colour shows (thesis 6.2).
        pub color: f32,
        /// Colour saturation.
        pub color_saturation: f32,
        /// Gooch blend.
        pub gooch: f32,
        /// Toon blend.
        pub toon: f32,
        /// Toon bands.
        pub toon_levels: f32,
        /// How much sky colour shows behind the landscape.
        pub sky: f32,
        /// The style's TAM index (the data pass's default hatch pattern).
        pub hatch_map: u32,
        /// The terrain's strokes ([`crate::render::style::TerrainStrokes::code`]).
        pub terrain_strokes: u32,
        /// The largest tile of the terrain's object-space strokes on screen, in pixels
        /// ([`Style::terrain_tile`]).
        pub terrain_tile: f32,
        /// Terrain tone from light relative to flat ground's (0..1).
        pub terrain_relief: f32,
        /// Terrain darkening with steepness (0..1).
        pub terrain_slope_tone: f32,
        /// Vertical exaggeration of the relief for the terrain's tone (1..10).
        pub terrain_exaggeration: f32,
        /// Ink of the terrain's crease lines (0..1, times the contour strength).
        pub terrain_creases: f32,
        /// Hectares a crease line drains at least to be drawn.
        pub terrain_crease_area: f32,
        /// Degrees of slope change a break-of-slope line has at least to be drawn.
        pub terrain_break_angle: f32,
        /// Ink of the borders between land-cover classes (0..1).
        pub land_cover_outline: f32,
        /// Ink colour (sRGB).
        pub ink: Vec3f,
        /// Paper colour (sRGB).
        pub paper: Vec3f,
        /// Sky colour at the zenith (sRGB).
        pub sky_zenith: Vec3f,
        /// Sky colour at the horizon (sRGB).
        pub sky_horizon: Vec3f,
    }
}

gpu_block! {
    /// The uniform block of the post passes (`styles`): the view rays for the sky, the
    /// art-map group a compose pass draws, and one [`PostStyle`] per style slot.
    pub struct Styles {
        /// World z of the view ray through NDC (x, y): ray.x + x·ray.y + y·ray.z;
        /// ray.w = tan(fov/2)·aspect.
        pub ray: Vec4f,
        /// The art-map group drawn by this compose pass.
        pub art_group: u32,
        /// tan(fov/2) (0 for a plan view).
        pub tan_half_fov: f32,
        /// The style of every slot.
        pub slots: [PostStyle; STYLE_SLOTS],
    }
}

impl PostStyle {
    /// The post parameters of a resolved `style`; `sun` is the unit vector towards the sun in
    /// world space, `roll` the camera roll in radians, `tam_levels` and `tam_size` describe the
    /// style's tonal art map and `art_group` is its compose-pass group
    /// ([`crate::render::style::art_groups`]).
    pub fn new(style: &Style, sun: glam::Vec3, roll: f32, tam_levels: u32, tam_size: u32, art_group: u32) -> PostStyle {
        PostStyle {
            contour_scale: style.contour_scale,
            contour_threshold: style.contour_threshold,
            isolated_pixel_threshold: style.isolated_pixel_threshold,
            isolated_pixel_removal: u32::from(style.isolated_pixel_removal),
            sun: sun.into(),
            ambient: style.ambient,
            albedo_weight: style.albedo_weight,
            tone_contrast: style.tone_contrast,
            tone_reference: style.tone_reference,
            contour_strength: style.contour_strength,
            tone_levels: style.tone_levels as f32,
            tone_blur: style.tone_blur as f32,
            tam_levels: tam_levels as f32,
            tam_size: tam_size as f32,
            silhouette_support: style.silhouette_support,
            silhouette_stretch: style.silhouette_stretch,
            silhouette_strength: style.silhouette_strength,
            art_group,
            roll: Vec2f([roll.cos(), roll.sin()]),
            hatch_strength: style.hatch_strength,
            hatch_brightness: style.hatch_brightness,
            distance_simplification: style.distance_simplification,
            abstraction_near: style.abstraction_near,
            abstraction_far: style.abstraction_far.max(style.abstraction_near + 0.01),
            color: style.color,
            color_saturation: style.color_saturation,
            gooch: style.gooch,
            toon: style.toon,
            toon_levels: style.toon_levels as f32,
            sky: style.sky,
            hatch_map: style.hatch_map as u32,
            terrain_strokes: style.terrain_stroke_direction.code(),
            terrain_tile: style.terrain_tile(),
            terrain_relief: style.terrain_relief,
            terrain_slope_tone: style.terrain_slope_tone,
            terrain_exaggeration: style.terrain_exaggeration,
            terrain_creases: style.terrain_creases * style.contour_strength,
            terrain_crease_area: style.terrain_crease_area,
            terrain_break_angle: style.terrain_break_angle,
            land_cover_outline: style.land_cover_outline,
            ink: Vec3f(style.ink),
            paper: Vec3f(style.paper),
            sky_zenith: Vec3f(style.sky_zenith),
            sky_horizon: Vec3f(style.sky_horizon),
        }
    }
}

impl Styles {
    /// The block for `slots` seen by `camera` in a `width` × `height` image; `group` is the
    /// art-map group this compose pass draws. The ray terms give the world-space z of the view
    /// ray through each pixel (the sky gradient follows the elevation of the ray).
    pub fn new(slots: [PostStyle; STYLE_SLOTS], camera: &Camera, width: u32, height: u32, group: u32) -> Styles {
        let to_world = camera.view().inverse();
        let right = to_world.x_axis.truncate();
        let up = to_world.y_axis.truncate();
        let forward = -to_world.z_axis.truncate();
        let tan = if camera.projection.is_perspective() { (camera.fov.to_radians() * 0.5).tan() } else { 0.0 };
        let tan_x = tan * width as f32 / height.max(1) as f32;
        Styles {
            ray: Vec4f([forward.z, right.z * tan_x, up.z * tan, tan_x]),
            art_group: group,
            tan_half_fov: tan,
            slots,
        }
    }
}
