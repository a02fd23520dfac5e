//! The style parameters of a rendering: one struct, serialisable, with defaults and ranges.
//!
//! Every pass reads its parameters from here; the field-by-field reference is in the README
//! ("Style"). Later issues add abstraction, colour and the photorealism axis.

use super::RenderError;
use serde::{Deserialize, Serialize};

/// How hatch texture coordinates are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HatchSpace {
    /// The thesis' hybrid parametrization (eq. 6.2–6.6) on foliage, cylindrical object space on
    /// trunks and branches; the terrain is hatched in image space.
    Hybrid,
    /// Plain image-space hatching (screen coordinates), the baseline the coherence figure is
    /// compared with.
    Image,
}

/// Pen-and-ink style parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Style {
    /// Depth-difference scale `c` of thesis eq. 5.1 (applied to relative depth differences).
    pub contour_scale: f32,
    /// Threshold `t` of thesis eq. 5.1: relative depth steps below `t / c` draw no contour.
    pub contour_threshold: f32,
    /// Selective-dilation depth pre-filter before contour detection (thesis eq. 5.4).
    pub contour_prefilter: bool,
    /// Remove isolated contour pixels (thesis eq. 5.2).
    pub isolated_pixel_removal: bool,
    /// Threshold `t'` of thesis eq. 5.2 separating contour pixels from background.
    pub isolated_pixel_threshold: f32,
    /// How dark plain contours are drawn, 0 (invisible) to 1 (full ink).
    pub contour_strength: f32,
    /// Silhouette art map (SAM) index (see `Renderer::silhouette_maps`).
    pub silhouette_map: usize,
    /// Width in pixels of the silhouette support searched along E (thesis 5.2); 0 disables
    /// stylized silhouettes.
    pub silhouette_support: f32,
    /// Stretch `c` of the SAM along the contour (thesis eq. 5.5).
    pub silhouette_stretch: f32,
    /// How dark stylized silhouettes are drawn, 0 to 1.
    pub silhouette_strength: f32,
    /// Tonal art map (TAM) index (see `Renderer::tonal_art_maps`).
    pub hatch_map: usize,
    /// Hybrid (thesis 6.1) or plain image-space hatch coordinates for plants.
    pub hatch_space: HatchSpace,
    /// TAM tiles per π radians of an HLP sphere (`m = n` of thesis eq. 6.1–6.3).
    pub hatch_tiles: f32,
    /// `c` of the surface function f(A) (thesis eq. 6.6); 0 keeps hatching flat.
    pub hatch_surface: f32,
    /// Size of one TAM tile in pixels where hatching is in image space (the terrain, and
    /// everything with `hatch_space: image`); the TAM's size gives its finest level.
    pub image_hatch_scale: f32,
    /// How dark hatching is drawn, 0 (none) to 1.
    pub hatch_strength: f32,
    /// Blend of the original normals towards the HLP normals for lighting (thesis 6.1.3).
    pub normal_blend: f32,
    /// Ambient share of the light, 0 (pure Lambert) to 1 (flat).
    pub ambient: f32,
    /// How much the surface's own albedo darkens the tone, 0 (lighting only) to 1.
    pub albedo_weight: f32,
    /// Contrast `scale` of thesis eq. 6.7 about `tone_reference`; 1 leaves the tone unchanged.
    pub tone_contrast: f32,
    /// `L_ref` of thesis eq. 6.7.
    pub tone_reference: f32,
    /// Banding of the tone into this many levels (thesis 6.1.3); 0 keeps it continuous.
    pub tone_levels: u32,
    /// Radius in pixels of the Gaussian blur of the tone image (thesis Fig. 6.9d); 0 = none.
    pub tone_blur: u32,
    /// Ink colour (sRGB, 0..1).
    pub ink: [f32; 3],
    /// Paper colour (sRGB, 0..1).
    pub paper: [f32; 3],
}

impl Default for Style {
    fn default() -> Self {
        Style {
            contour_scale: 4.0,
            contour_threshold: 0.2,
            contour_prefilter: true,
            isolated_pixel_removal: true,
            isolated_pixel_threshold: 0.5,
            contour_strength: 1.0,
            silhouette_map: 1,
            silhouette_support: 8.0,
            silhouette_stretch: 1.0,
            silhouette_strength: 1.0,
            hatch_map: 0,
            hatch_space: HatchSpace::Hybrid,
            hatch_tiles: 2.0,
            hatch_surface: 0.0,
            image_hatch_scale: 256.0,
            hatch_strength: 1.0,
            normal_blend: 0.5,
            ambient: 0.5,
            albedo_weight: 0.6,
            tone_contrast: 1.6,
            tone_reference: 0.45,
            tone_levels: 0,
            tone_blur: 2,
            ink: [0.08, 0.08, 0.1],
            paper: [1.0, 1.0, 0.98],
        }
    }
}

fn check(field: &'static str, value: f32, lo: f32, hi: f32, range: &'static str) -> Result<(), RenderError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(RenderError::Style { field, value, range })
    }
}

impl Style {
    /// Checks every parameter against its documented range; art map indices are checked by the
    /// renderer that knows how many maps it has.
    pub fn validate(&self) -> Result<(), RenderError> {
        check("contour_scale", self.contour_scale, 0.0, 1000.0, "0..=1000")?;
        check("contour_threshold", self.contour_threshold, 0.0, 10.0, "0..=10")?;
        check("isolated_pixel_threshold", self.isolated_pixel_threshold, 0.0, 1.0, "0..=1")?;
        check("contour_strength", self.contour_strength, 0.0, 1.0, "0..=1")?;
        check("silhouette_support", self.silhouette_support, 0.0, 16.0, "0..=16")?;
        check("silhouette_stretch", self.silhouette_stretch, 0.01, 100.0, "0.01..=100")?;
        check("silhouette_strength", self.silhouette_strength, 0.0, 1.0, "0..=1")?;
        check("hatch_tiles", self.hatch_tiles, 0.05, 64.0, "0.05..=64")?;
        check("hatch_surface", self.hatch_surface, 0.0, 10.0, "0..=10")?;
        check("image_hatch_scale", self.image_hatch_scale, 4.0, 4096.0, "4..=4096")?;
        check("hatch_strength", self.hatch_strength, 0.0, 1.0, "0..=1")?;
        check("normal_blend", self.normal_blend, 0.0, 1.0, "0..=1")?;
        check("ambient", self.ambient, 0.0, 1.0, "0..=1")?;
        check("albedo_weight", self.albedo_weight, 0.0, 1.0, "0..=1")?;
        check("tone_contrast", self.tone_contrast, 0.0, 10.0, "0..=10")?;
        check("tone_reference", self.tone_reference, 0.0, 1.0, "0..=1")?;
        check("tone_levels", self.tone_levels as f32, 0.0, 16.0, "0..=16")?;
        check("tone_blur", self.tone_blur as f32, 0.0, 4.0, "0..=4")?;
        for c in self.ink.iter().chain(&self.paper) {
            check("ink/paper", *c, 0.0, 1.0, "0..=1")?;
        }
        Ok(())
    }
}

/// Thesis eq. 6.7 followed by banding: `L' = (L − L_ref)·scale + L_ref`, clamped to 0..1, then
/// rounded to `levels` steps when `levels > 0`. The compose shader implements the same.
pub fn contrast_tone(light: f32, reference: f32, scale: f32, levels: u32) -> f32 {
    let t = ((light - reference) * scale + reference).clamp(0.0, 1.0);
    if levels == 0 { t } else { (t * levels as f32).round() / levels as f32 }
}

/// The uniform block of the post passes (`shaders/post_common.wgsl`), built from a [`Style`]
/// and the sun direction.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PostParams {
    contour: [f32; 4],
    light: [f32; 4],
    tone: [f32; 4],
    tone2: [f32; 4],
    silhouette: [f32; 4],
    hatch: [f32; 4],
    ink: [f32; 4],
    paper: [f32; 4],
}

impl PostParams {
    /// Packs `style` for the GPU; `sun` is the unit vector towards the sun in world space,
    /// `roll` the camera roll in radians (the orientation vector V_O of thesis 5.2 follows it),
    /// `tam_levels` and `tam_size` describe the bound tonal art map.
    pub fn new(style: &Style, sun: glam::Vec3, roll: f32, tam_levels: u32, tam_size: u32) -> PostParams {
        let rgb = |c: [f32; 3]| [c[0], c[1], c[2], 1.0];
        let flag = |b: bool| f32::from(u8::from(b));
        PostParams {
            contour: [
                style.contour_scale,
                style.contour_threshold,
                style.isolated_pixel_threshold,
                flag(style.isolated_pixel_removal),
            ],
            light: [sun.x, sun.y, sun.z, style.ambient],
            tone: [style.albedo_weight, style.tone_contrast, style.tone_reference, style.contour_strength],
            tone2: [style.tone_levels as f32, style.tone_blur as f32, tam_levels as f32, tam_size as f32],
            silhouette: [style.silhouette_support, style.silhouette_stretch, style.silhouette_strength, 0.0],
            hatch: [style.hatch_strength, roll.cos(), roll.sin(), 0.0],
            ink: rgb(style.ink),
            paper: rgb(style.paper),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_style_is_valid_and_round_trips_through_json() {
        let style = Style::default();
        style.validate().unwrap();
        let json = serde_json::to_string(&style).unwrap();
        assert_eq!(serde_json::from_str::<Style>(&json).unwrap(), style);
        let image: Style = serde_json::from_str(r#"{"hatch_space": "image"}"#).unwrap();
        assert_eq!(image.hatch_space, HatchSpace::Image);
    }

    #[test]
    fn out_of_range_and_unknown_fields_are_rejected() {
        let err = Style { silhouette_support: -1.0, ..Style::default() }.validate().unwrap_err().to_string();
        assert!(err.contains("silhouette_support"), "{err}");
        assert!(Style { ambient: f32::NAN, ..Style::default() }.validate().is_err());
        assert!(serde_json::from_str::<Style>(r#"{"hatch_spacng": 3}"#).is_err());
        assert!(serde_json::from_str::<Style>(r#"{"hatch_space": "diagonal"}"#).is_err());
    }

    #[test]
    fn contrast_follows_eq_6_7() {
        // L = 0.7, L_ref = 0.5, scale 2 → 0.5 + 0.4 = 0.9; L = 0.3 → 0.1; clamped beyond.
        assert!((contrast_tone(0.7, 0.5, 2.0, 0) - 0.9).abs() < 1e-6);
        assert!((contrast_tone(0.3, 0.5, 2.0, 0) - 0.1).abs() < 1e-6);
        assert_eq!(contrast_tone(0.9, 0.5, 3.0, 0), 1.0);
        // Banding into 4 levels: 0.9 → 1.0, 0.6 → 0.5 (nearest quarter).
        assert_eq!(contrast_tone(0.7, 0.5, 2.0, 4), 1.0);
        assert_eq!(contrast_tone(0.6, 0.5, 1.0, 4), 0.5);
    }
}
