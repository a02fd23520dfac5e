//! The styles a view asks for — a preset, fields over it and styles of single layers — and
//! the one place they are merged into the styles of a frame ([`ViewStyle::resolve`]). The CLI,
//! `GET`/`POST /api/render`, the WebSocket and `POST /api/styles/resolve` (what the browser's
//! style panel shows) all go through it.
//!
//! The merge rules: the view's style is the defaults, then its preset's fields, then its own
//! fields; a layer's style starts from the preset the layer names, else from the view's style,
//! and takes the layer's own fields over that. Later fields win; every complete style is
//! validated against the ranges.

use super::RenderError;
use super::presets::preset;
use super::style::{FrameStyle, LayerStyle, PartialStyle, Style, TERRAIN_LAYER, layer_code};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// The styles of a view as a client gives them (the style part of `POST /api/render`, the
/// body of `POST /api/styles/resolve`, the CLI's `--preset`, `--style` and `--layer-style`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ViewStyle {
    /// A named style preset (`GET /api/scene` lists them) the view's fields merge over.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// The view's own style fields (README, "Style").
    #[serde(skip_serializing_if = "PartialStyle::is_empty")]
    #[schema(value_type = Object)]
    pub style: PartialStyle,
    /// Styles of single layers (thesis 8.2.8): layer name (`terrain` or a vegetation layer)
    /// → style fields over the view's style, or over `"preset"` when it names one.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    #[schema(value_type = Object)]
    pub layer_styles: BTreeMap<String, LayerStyle>,
}

/// The part of a view a style error is in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StyleTarget {
    /// The view's style (its preset and fields).
    View,
    /// The style of the layer of this name.
    Layer(String),
}

/// A view's style that cannot be resolved: where the error is and what it is (an unknown
/// preset or layer, a value out of range).
#[derive(Debug, thiserror::Error)]
#[error("{error}")]
pub struct StyleError {
    /// The style the error is in.
    pub target: StyleTarget,
    /// What is wrong.
    pub error: RenderError,
}

impl StyleError {
    fn view(error: RenderError) -> StyleError {
        StyleError { target: StyleTarget::View, error }
    }

    fn layer(name: &str) -> impl FnOnce(RenderError) -> StyleError + '_ {
        move |error| StyleError { target: StyleTarget::Layer(name.to_owned()), error }
    }
}

/// One style resolved: what its own fields merge over, and the complete style.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ResolvedStyle {
    /// The preset's style, the defaults (the view without a preset) or the view's style (a
    /// layer without a preset): a field of this value is no override.
    #[schema(value_type = Object)]
    pub base: Style,
    /// The complete style: `base` with the own fields.
    #[schema(value_type = Object)]
    pub style: Style,
}

/// Every style of a view resolved: the view's and each layer's of the scene (layers without
/// a style of their own have the view's).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ResolvedStyles {
    /// The view's style.
    pub view: ResolvedStyle,
    /// By layer name (`terrain` and the vegetation layers): the layer's style.
    pub layers: BTreeMap<String, ResolvedStyle>,
}

impl LayerStyle {
    /// This layer's style in a view of the style `view`: the layer's fields over its preset,
    /// else over `view`.
    pub fn resolve(&self, view: &Style) -> Result<ResolvedStyle, RenderError> {
        let base = match &self.preset {
            Some(name) => preset(name)?,
            None => view.clone(),
        };
        let style = base.with(&self.fields)?;
        Ok(ResolvedStyle { base, style })
    }
}

impl ViewStyle {
    /// Sets what `later` sets (later wins): its preset, if it names one, its fields, and the
    /// preset and fields of each layer it names.
    pub fn merge(&mut self, later: &ViewStyle) {
        if later.preset.is_some() {
            self.preset.clone_from(&later.preset);
        }
        self.style.merge(&later.style);
        for (name, layer) in &later.layer_styles {
            self.layer_styles.entry(name.clone()).or_default().merge(layer);
        }
    }

    /// The partial styles that resolve to `frame`: no presets, the fields of the view's style
    /// that differ from the defaults and the fields of each layer's style that differ from the
    /// view's (the short form of a view in links).
    pub fn of_frame(frame: &FrameStyle) -> ViewStyle {
        ViewStyle {
            preset: None,
            style: PartialStyle::diff(&frame.base, &Style::default()),
            layer_styles: frame
                .layers
                .iter()
                .map(|(name, style)| {
                    (name.clone(), LayerStyle { preset: None, fields: PartialStyle::diff(style, &frame.base) })
                })
                .collect(),
        }
    }

    /// The view's own style: its fields over its preset, else over the defaults.
    fn view(&self) -> Result<ResolvedStyle, StyleError> {
        let base = match &self.preset {
            Some(name) => preset(name).map_err(StyleError::view)?,
            None => Style::default(),
        };
        let style = base.with(&self.style).map_err(StyleError::view)?;
        Ok(ResolvedStyle { base, style })
    }

    /// The styles of a frame of this view in a scene with `vegetation_layers` (its vegetation
    /// layer names): the view's style and the style of every layer that has one of its own. An
    /// unknown preset or layer, or a value out of range, is an error naming where it is.
    pub fn resolve(&self, vegetation_layers: &[String]) -> Result<FrameStyle, StyleError> {
        let mut frame = FrameStyle::from(self.view()?.style);
        for (name, layer) in &self.layer_styles {
            layer_code(name, vegetation_layers).map_err(StyleError::layer(name))?;
            let style = layer.resolve(&frame.base).map_err(StyleError::layer(name))?.style;
            frame.layers.insert(name.clone(), style);
        }
        Ok(frame)
    }

    /// Every style of this view resolved, with what its own fields merge over: the view's and
    /// that of the terrain and each of `vegetation_layers`. Errors as [`ViewStyle::resolve`].
    pub fn resolve_all(&self, vegetation_layers: &[String]) -> Result<ResolvedStyles, StyleError> {
        let view = self.view()?;
        let mut layers = BTreeMap::new();
        for (name, layer) in &self.layer_styles {
            layer_code(name, vegetation_layers).map_err(StyleError::layer(name))?;
            layers.insert(name.clone(), layer.resolve(&view.style).map_err(StyleError::layer(name))?);
        }
        for name in std::iter::once(TERRAIN_LAYER).chain(vegetation_layers.iter().map(String::as_str)) {
            // A layer without a style of its own has the view's.
            layers
                .entry(name.to_owned())
                .or_insert_with(|| ResolvedStyle { base: view.style.clone(), style: view.style.clone() });
        }
        Ok(ResolvedStyles { view, layers })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn partial(json: &str) -> PartialStyle {
        serde_json::from_str(json).unwrap()
    }

    fn layer(json: &str) -> LayerStyle {
        serde_json::from_str(json).unwrap()
    }

    fn vegetation() -> Vec<String> {
        vec!["existing".to_owned(), "planned".to_owned()]
    }

    fn named(name: &str) -> Style {
        preset(name).unwrap()
    }

    #[test]
    fn later_fields_win() {
        let mut style = partial(r#"{"ambient": 0.2, "hatch_map": 1}"#);
        style.merge(&partial(r#"{"ambient": 0.4, "ink": [0, 0, 1]}"#));
        assert_eq!(style, partial(r#"{"ambient": 0.4, "hatch_map": 1, "ink": [0, 0, 1]}"#));
        let mut view = ViewStyle {
            preset: Some("full_npr".into()),
            style: partial(r#"{"color": 0.2}"#),
            layer_styles: [("planned".to_owned(), layer(r#"{"preset": "photorealism", "ambient": 0.3}"#))].into(),
        };
        view.merge(&ViewStyle {
            preset: None,
            style: partial(r#"{"color": 0.5}"#),
            layer_styles: [
                ("planned".to_owned(), layer(r#"{"ambient": 0.6}"#)),
                ("terrain".to_owned(), layer(r#"{"hatch_map": 2}"#)),
            ]
            .into(),
        });
        assert_eq!(view.preset.as_deref(), Some("full_npr"), "a change without a preset keeps it");
        assert_eq!(view.style, partial(r#"{"color": 0.5}"#));
        assert_eq!(view.layer_styles["planned"], layer(r#"{"preset": "photorealism", "ambient": 0.6}"#));
        assert_eq!(view.layer_styles["terrain"], layer(r#"{"hatch_map": 2}"#));
        view.merge(&ViewStyle { preset: Some("minimalistic".into()), ..ViewStyle::default() });
        assert_eq!(view.preset.as_deref(), Some("minimalistic"));
        assert_eq!(view.style, partial(r#"{"color": 0.5}"#), "the fields stay over the new preset");
    }

    #[test]
    fn a_view_is_its_fields_over_its_preset_or_the_defaults() {
        let view = ViewStyle {
            preset: Some("photorealism".into()),
            style: partial(r#"{"ambient": 0.6}"#),
            ..ViewStyle::default()
        };
        let frame = view.resolve(&vegetation()).unwrap();
        assert_eq!(frame, FrameStyle::from(Style { ambient: 0.6, ..named("photorealism") }));
        let plain = ViewStyle { style: partial(r#"{"hatch_map": 3}"#), ..ViewStyle::default() };
        assert_eq!(plain.resolve(&[]).unwrap().base, Style { hatch_map: 3, ..Style::default() });
        assert_eq!(ViewStyle::default().resolve(&[]).unwrap(), FrameStyle::default());
    }

    #[test]
    fn a_layer_starts_from_its_own_preset_or_from_the_views_style() {
        let view = ViewStyle {
            preset: Some("full_npr".into()),
            style: partial(r#"{"color": 0.4}"#),
            layer_styles: [
                ("existing".to_owned(), layer(r#"{"preset": "minimalistic", "ambient": 0.2}"#)),
                ("terrain".to_owned(), layer(r#"{"hatch_map": 2}"#)),
            ]
            .into(),
        };
        let frame = view.resolve(&vegetation()).unwrap();
        let view_style = Style { color: 0.4, ..named("full_npr") };
        assert_eq!(frame.base, view_style);
        assert_eq!(frame.layers["terrain"], Style { hatch_map: 2, ..view_style.clone() });
        // The view's colour does not reach a layer with a preset of its own.
        assert_eq!(frame.layers["existing"], Style { ambient: 0.2, ..named("minimalistic") });
        assert_eq!(frame.layers.len(), 2, "only layers with styles of their own");

        // Every style with what its fields merge over, the same styles as `resolve`.
        let all = view.resolve_all(&vegetation()).unwrap();
        assert_eq!(all.view, ResolvedStyle { base: named("full_npr"), style: view_style.clone() });
        assert_eq!(all.layers["existing"].base, named("minimalistic"));
        assert_eq!(all.layers["terrain"].base, view_style);
        assert_eq!(all.layers["planned"], ResolvedStyle { base: view_style.clone(), style: view_style });
        assert_eq!(all.layers.keys().collect::<Vec<_>>(), ["existing", "planned", "terrain"]);
        for (name, style) in &frame.layers {
            assert_eq!(&all.layers[name].style, style, "{name}");
        }
    }

    #[test]
    fn unknown_fields_and_values_out_of_range_are_errors_naming_them() {
        let err = serde_json::from_str::<PartialStyle>(r#"{"hatch_spacng": 3}"#).unwrap_err().to_string();
        assert!(err.starts_with("invalid style: unknown field `hatch_spacng`, expected one of `visible`"), "{err}");
        let err = serde_json::from_str::<LayerStyle>(r#"{"colour": 1}"#).unwrap_err().to_string();
        assert!(err.contains("unknown field `colour`, expected one of `preset`, `visible`"), "{err}");
        let err = serde_json::from_str::<PartialStyle>(r#"{"leaf_mode": "round"}"#).unwrap_err().to_string();
        assert!(err.starts_with("invalid style parameter `leaf_mode`: unknown variant `round`"), "{err}");
        let err = serde_json::from_str::<PartialStyle>(r#"{"ink": [0, 0]}"#).unwrap_err().to_string();
        assert!(err.starts_with("invalid style parameter `ink`"), "{err}");
        let err = serde_json::from_str::<PartialStyle>("[1]").unwrap_err().to_string();
        assert!(err.contains("expected a JSON object of style fields"), "{err}");
        assert!(serde_json::from_str::<ViewStyle>(r#"{"colour": {}}"#).is_err());

        let view = ViewStyle { style: partial(r#"{"ambient": 2}"#), ..ViewStyle::default() };
        let err = view.resolve(&vegetation()).unwrap_err();
        assert_eq!(err.target, StyleTarget::View);
        assert_eq!(err.to_string(), "style parameter `ambient` = 2 is out of range (0..=1)");
        let in_layer = |json: &str| {
            let layer_styles = [("planned".to_owned(), layer(json))].into();
            ViewStyle { layer_styles, ..ViewStyle::default() }.resolve(&vegetation()).unwrap_err()
        };
        let err = in_layer(r#"{"preset": "photorealism", "toon_levels": 1}"#);
        assert_eq!(err.target, StyleTarget::Layer("planned".into()));
        assert!(matches!(err.error, RenderError::Style { field: "toon_levels", range: "2..=16", .. }), "{err}");
        assert!(matches!(in_layer(r#"{"preset": "winter"}"#).error, RenderError::UnknownPreset { .. }));
        let meadow = ViewStyle { layer_styles: [("meadow".to_owned(), layer("{}"))].into(), ..ViewStyle::default() };
        for err in [meadow.resolve(&vegetation()).unwrap_err(), meadow.resolve_all(&vegetation()).unwrap_err()] {
            assert_eq!(err.target, StyleTarget::Layer("meadow".into()));
            assert!(err.to_string().contains("layers: terrain, existing, planned"), "{err}");
        }
    }

    #[test]
    fn styles_keep_their_json_form() {
        let text = r#"{"preset":"photorealism","ambient":0.2,"ink":[0.1,0.2,0.3]}"#;
        let layer: LayerStyle = serde_json::from_str(text).unwrap();
        assert_eq!(layer.preset.as_deref(), Some("photorealism"));
        assert_eq!((layer.fields.ambient, layer.fields.ink), (Some(0.2), Some([0.1, 0.2, 0.3])));
        assert_eq!(serde_json::to_string(&layer).unwrap(), text);
        let text =
            r#"{"preset":"full_npr","style":{"color":0.5},"layer_styles":{"existing":{"preset":"photorealism"}}}"#;
        let view: ViewStyle = serde_json::from_str(text).unwrap();
        assert_eq!(serde_json::to_string(&view).unwrap(), text);
        assert_eq!(serde_json::to_string(&ViewStyle::default()).unwrap(), "{}");
    }

    #[test]
    fn the_short_form_of_a_frame_resolves_back_to_it() {
        let view = ViewStyle {
            preset: Some("van_gogh".into()),
            style: partial(r#"{"color": 0.4}"#),
            layer_styles: [
                ("existing".to_owned(), layer(r#"{"preset": "photorealism"}"#)),
                ("planned".to_owned(), layer("{}")),
            ]
            .into(),
        };
        let frame = view.resolve(&vegetation()).unwrap();
        let short = ViewStyle::of_frame(&frame);
        assert_eq!(short.preset, None);
        assert_eq!(short.style, PartialStyle::diff(&frame.base, &Style::default()));
        assert!(short.layer_styles["planned"].fields.is_empty());
        assert_eq!(short.resolve(&vegetation()).unwrap(), frame);
    }
}
