//! The style parameters of a rendering: one struct, serialisable, with defaults and ranges.
//!
//! Later issues extend this with the full NPR parameter space (silhouette art maps, tonal art
//! maps, abstraction, colour); every pass reads its parameters from here.

use super::RenderError;
use serde::{Deserialize, Serialize};

/// Pen-and-ink style parameters of the first rendering pipeline.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Style {
    /// Depth-difference scale `c` of thesis eq. 5.1 (applied to relative depth differences).
    pub contour_scale: f32,
    /// Threshold `t` of thesis eq. 5.1: relative depth steps below `t / c` draw no contour.
    pub contour_threshold: f32,
    /// Remove isolated contour pixels (thesis eq. 5.2).
    pub isolated_pixel_removal: bool,
    /// Threshold `t'` of thesis eq. 5.2 separating contour pixels from background.
    pub isolated_pixel_threshold: f32,
    /// How dark contours are drawn, 0 (invisible) to 1 (full ink).
    pub contour_strength: f32,
    /// Ambient share of the light, 0 (pure Lambert) to 1 (flat).
    pub ambient: f32,
    /// How much the surface's own albedo darkens the tone, 0 (lighting only) to 1.
    pub albedo_weight: f32,
    /// Tone contrast about `tone_reference`; 1 leaves the tone unchanged.
    pub tone_contrast: f32,
    /// The grey level the contrast pivots about.
    pub tone_reference: f32,
    /// Distance between hatch lines in pixels.
    pub hatch_spacing: f32,
    /// Width of a hatch line in the darkest tone, in pixels.
    pub hatch_width: f32,
    /// Direction of the first hatch layer in degrees (0 = horizontal lines' normal along x).
    pub hatch_angle: f32,
    /// Tone thresholds below which the four hatch layers appear (from light to dark).
    pub hatch_levels: [f32; 4],
    /// Width of the tone band over which a hatch layer grows from nothing to full width.
    pub hatch_band: f32,
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
            isolated_pixel_removal: true,
            isolated_pixel_threshold: 0.5,
            contour_strength: 1.0,
            ambient: 0.35,
            albedo_weight: 0.6,
            tone_contrast: 1.3,
            tone_reference: 0.5,
            hatch_spacing: 6.0,
            hatch_width: 1.8,
            hatch_angle: 60.0,
            hatch_levels: [0.68, 0.5, 0.33, 0.18],
            hatch_band: 0.15,
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
    /// Checks every parameter against its documented range.
    pub fn validate(&self) -> Result<(), RenderError> {
        check("contour_scale", self.contour_scale, 0.0, 1000.0, "0..=1000")?;
        check("contour_threshold", self.contour_threshold, 0.0, 10.0, "0..=10")?;
        check("isolated_pixel_threshold", self.isolated_pixel_threshold, 0.0, 1.0, "0..=1")?;
        check("contour_strength", self.contour_strength, 0.0, 1.0, "0..=1")?;
        check("ambient", self.ambient, 0.0, 1.0, "0..=1")?;
        check("albedo_weight", self.albedo_weight, 0.0, 1.0, "0..=1")?;
        check("tone_contrast", self.tone_contrast, 0.0, 10.0, "0..=10")?;
        check("tone_reference", self.tone_reference, 0.0, 1.0, "0..=1")?;
        check("hatch_spacing", self.hatch_spacing, 2.0, 64.0, "2..=64")?;
        check("hatch_width", self.hatch_width, 0.0, 16.0, "0..=16")?;
        check("hatch_angle", self.hatch_angle, -360.0, 360.0, "-360..=360")?;
        check("hatch_band", self.hatch_band, 0.01, 1.0, "0.01..=1")?;
        for level in self.hatch_levels {
            check("hatch_levels", level, 0.0, 1.0, "0..=1")?;
        }
        for c in self.ink.iter().chain(&self.paper) {
            check("ink/paper", *c, 0.0, 1.0, "0..=1")?;
        }
        Ok(())
    }
}

/// The uniform block of the post passes (`shaders/post_common.wgsl`), built from a [`Style`]
/// and the sun direction.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PostParams {
    contour: [f32; 4],
    light: [f32; 4],
    tone: [f32; 4],
    hatch: [f32; 4],
    hatch_levels: [f32; 4],
    ink: [f32; 4],
    paper: [f32; 4],
}

impl PostParams {
    /// Packs `style` for the GPU; `sun` is the unit vector towards the sun in world space.
    pub fn new(style: &Style, sun: glam::Vec3) -> PostParams {
        let rgb = |c: [f32; 3]| [c[0], c[1], c[2], 1.0];
        PostParams {
            contour: [
                style.contour_scale,
                style.contour_threshold,
                style.isolated_pixel_threshold,
                f32::from(u8::from(style.isolated_pixel_removal)),
            ],
            light: [sun.x, sun.y, sun.z, style.ambient],
            tone: [style.albedo_weight, style.tone_contrast, style.tone_reference, style.contour_strength],
            hatch: [style.hatch_spacing, style.hatch_width, style.hatch_angle.to_radians(), style.hatch_band],
            hatch_levels: style.hatch_levels,
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
    }

    #[test]
    fn out_of_range_and_unknown_fields_are_rejected() {
        let style = Style { hatch_spacing: 0.5, ..Style::default() };
        let err = style.validate().unwrap_err().to_string();
        assert!(err.contains("hatch_spacing"), "{err}");
        let nan = Style { ambient: f32::NAN, ..Style::default() };
        assert!(nan.validate().is_err());
        assert!(serde_json::from_str::<Style>(r#"{"hatch_spacng": 3}"#).is_err());
    }
}
