//! Named style presets (SPEC R10, NPAR paper Fig. 3): documented partial styles over the
//! defaults that anyone can start from and modify — a request's own style fields merge over
//! the preset ([`super::view_style::ViewStyle::resolve`]).

use super::style::PartialStyle;
use super::{RenderError, Style};

/// A named style preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Preset {
    /// The name requests use (`--preset`, `preset`).
    pub name: &'static str,
    /// One line on what it looks like.
    pub description: &'static str,
    /// The fields it sets, as a JSON object; everything else keeps the defaults.
    pub overrides: &'static str,
}

impl Preset {
    /// The fields this preset sets.
    pub fn overrides(&self) -> PartialStyle {
        // The texts are constants checked by the unit tests below.
        serde_json::from_str(self.overrides).unwrap_or_default()
    }

    /// The complete style: the defaults with this preset's fields.
    pub fn style(&self) -> Result<Style, RenderError> {
        Style::default().with(&self.overrides())
    }
}

/// Every preset, from photorealism to the most abstract sketch.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "photorealism",
        description: "textured colour, Lambert and ambient light, sky; no lines, no hatching (thesis 8.2.7)",
        overrides: r#"{"photorealism": 1.0, "ambient": 0.35}"#,
    },
    Preset {
        name: "half_npr",
        description: "realistic colour under a sky with contours, light silhouettes and sparse hatching",
        overrides: r#"{"color": 1.0, "color_abstraction": 0.3, "sky": 1.0, "ambient": 0.4, "normal_blend": 0.3,
            "implicit_normals": 1.0, "ambient_occlusion": 0.6,
            "contour_threshold": 0.3, "contour_strength": 0.9, "silhouette_strength": 0.6,
            "hatch_strength": 0.6, "hatch_brightness": 0.4}"#,
    },
    Preset {
        name: "full_npr",
        description: "pen-and-ink: contours, stylized silhouettes and hatching on abstracted foliage, no colour",
        overrides: r#"{"hlp_abstraction": 0.3, "normal_blend": 0.7, "implicit_normals": 1.0,
            "ambient_occlusion": 0.3}"#,
    },
    Preset {
        name: "silhouettes_hatching",
        description: "only stylized silhouettes and cross-hatching: no plain contours, no colour",
        overrides: r#"{"contour_strength": 0.0, "hatch_map": 1, "silhouette_map": 3, "normal_blend": 0.7}"#,
    },
    Preset {
        name: "van_gogh",
        description: "elliptical leaves on rounded crowns, saturated colour, scribbles, spiky silhouettes, blue ink",
        overrides: r#"{"color": 0.85, "color_saturation": 1.6, "color_abstraction": 0.4, "hlp_abstraction": 0.5,
            "leaf_mode": "elliptical", "leaf_outline": 0.1,
            "normal_blend": 0.9, "hatch_map": 2, "hatch_tiles": 3.0, "hatch_strength": 0.8,
            "image_hatch_scale": 128.0, "tone_contrast": 2.0, "tone_reference": 0.7, "silhouette_map": 2, "silhouette_stretch": 2.5,
            "sky": 0.9, "sky_zenith": [0.13, 0.25, 0.7], "sky_horizon": [0.95, 0.84, 0.45],
            "ink": [0.08, 0.1, 0.32]}"#,
    },
    Preset {
        name: "pointillist",
        description: "stipples (halftoned dots) over abstract colour; no lines",
        overrides: r#"{"hatch_map": 3, "image_hatch_scale": 96.0, "hatch_tiles": 3.0, "tone_contrast": 2.0,
            "tone_reference": 0.7,
            "color": 0.7, "color_abstraction": 1.0, "color_saturation": 1.4, "contour_strength": 0.0,
            "silhouette_strength": 0.0, "normal_blend": 0.8, "ink": [0.12, 0.16, 0.3]}"#,
    },
    Preset {
        name: "minimalistic",
        description: "sparse contours only: no hatching, no silhouettes, no colour",
        overrides: r#"{"contour_threshold": 0.5, "hatch_strength": 0.0, "silhouette_strength": 0.0}"#,
    },
    Preset {
        name: "childrens_book",
        description: "toon colours, outlined leaves turned out of round crowns, plain outlines (thesis Fig. 4.8d)",
        overrides: r#"{"color": 1.0, "color_abstraction": 1.0, "color_saturation": 1.4, "toon": 1.0,
            "leaf_mode": "reoriented", "leaf_outline": 0.15,
            "toon_levels": 3, "ambient": 0.35, "hlp_abstraction": 0.8, "normal_blend": 1.0,
            "contour_threshold": 0.1, "silhouette_map": 0, "silhouette_support": 3.0, "hatch_strength": 0.0,
            "sky": 0.7, "sky_zenith": [0.45, 0.7, 0.95], "sky_horizon": [0.96, 0.95, 0.85],
            "paper": [1.0, 0.98, 0.92]}"#,
    },
    Preset {
        name: "toon_shapes",
        description: "trees generalized into one ellipsoid per branch cluster, toon-shaded in 3 bands with outlines \
            (Campos et al. 2004, Fig. 6)",
        overrides: r#"{"color": 1.0, "color_abstraction": 1.0, "color_saturation": 1.2, "toon": 1.0,
            "leaf_mode": "shapes", "toon_levels": 3, "ambient": 0.35, "normal_blend": 0.0,
            "contour_threshold": 0.1, "silhouette_map": 0, "silhouette_support": 3.0, "hatch_strength": 0.0,
            "sky": 0.7, "sky_zenith": [0.45, 0.7, 0.95], "sky_horizon": [0.96, 0.95, 0.85],
            "paper": [1.0, 0.98, 0.92]}"#,
    },
];

/// The names of all presets, comma-separated (for error messages).
pub fn preset_names() -> String {
    PRESETS.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
}

/// The complete style of the preset `name`; an unknown name is an error listing the known ones.
pub fn preset(name: &str) -> Result<Style, RenderError> {
    PRESETS
        .iter()
        .find(|p| p.name == name)
        .ok_or_else(|| RenderError::UnknownPreset { name: name.to_owned(), known: preset_names() })?
        .style()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::view_style::ViewStyle;

    #[test]
    fn every_preset_parses_validates_and_differs() {
        let mut styles: Vec<Style> = Vec::new();
        for p in PRESETS {
            let overrides: PartialStyle = serde_json::from_str(p.overrides).expect(p.name);
            assert!(!overrides.is_empty(), "{}", p.name);
            let style = p.style().unwrap_or_else(|e| panic!("{}: {e}", p.name));
            assert!(styles.iter().all(|s| *s != style), "{} repeats another preset", p.name);
            styles.push(style);
        }
        assert_eq!(PRESETS.len(), 9);
    }

    #[test]
    fn unknown_presets_name_the_known_ones_and_overrides_merge() {
        let err = preset("winter").unwrap_err().to_string();
        assert!(err.contains("winter") && err.contains("photorealism") && err.contains("childrens_book"), "{err}");
        let photo = preset("photorealism").unwrap();
        assert_eq!((photo.photorealism, photo.ambient), (1.0, 0.35));
        let style: PartialStyle = serde_json::from_str(r#"{"ambient": 0.6}"#).unwrap();
        let view = ViewStyle { preset: Some("photorealism".into()), style, ..ViewStyle::default() };
        let merged = view.resolve(&[]).unwrap().base;
        assert_eq!((merged.photorealism, merged.ambient), (1.0, 0.6));
        assert_eq!(ViewStyle::default().resolve(&[]).unwrap().base, Style::default());
    }
}
