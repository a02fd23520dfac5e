//! Before / after: a view of the landscape without a named vegetation layer (the plan), or a
//! split view that shows it without the layer left of a vertical line and with it right of
//! the line, in one frame. One render serves both halves: the geometry pass drops the layer's
//! fragments left of the line (`hidden_left_of` of its style slot in `shaders/gbuffer.wgsl`,
//! which plants, leaves and far vegetation masses all read), while culling and levels of
//! detail stay as in the full view, so silhouettes and hatching are right on both sides; the
//! marks pass ([`super::marks`]) draws a pen line at the split.

use super::RenderError;
use super::layer_code::LayerCode;
use super::style::{STYLE_SLOTS, Style, layer_code};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A before/after comparison of a view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Compare {
    /// The vegetation layer compared (the plan), e.g. `planned`.
    pub layer: String,
    /// The split position, 0…1 of the image width from the left: left of it the view without
    /// the layer, right of it with it. Left out: the layer is hidden in the whole view.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split: Option<f32>,
}

/// What a [`Compare`] changes in one frame: the style slot of the compared layer and the
/// pixel column left of which it is hidden (`None`: hidden everywhere).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Split {
    /// The compared layer's style slot.
    pub slot: usize,
    /// The split line in pixels from the left edge; `None` when the layer is hidden in the
    /// whole frame.
    pub x: Option<f32>,
}

impl Compare {
    /// Checks the comparison against the scene's vegetation layer names: the layer must be
    /// one of them (with a style slot of its own) and the split within 0…1.
    pub fn check(&self, vegetation_layers: &[String]) -> Result<usize, RenderError> {
        let unknown = || RenderError::CompareLayer { name: self.layer.clone(), known: vegetation_layers.join(", ") };
        let code = layer_code(&self.layer, vegetation_layers).map_err(|_| unknown())?;
        if code == LayerCode::TERRAIN {
            return Err(unknown());
        }
        let slot = code.own_slot().ok_or_else(|| {
            RenderError::Compare(format!(
                "layer `{}` cannot be compared: only the first {} vegetation layers can",
                crate::echo::echo(&self.layer),
                LayerCode::VEGETATION_SLOTS
            ))
        })?;
        if let Some(split) = self.split
            && !(split.is_finite() && (0.0..=1.0).contains(&split))
        {
            return Err(RenderError::Compare(format!("split {split} is outside 0..=1 (a share of the image width)")));
        }
        Ok(slot)
    }

    /// Applies the comparison to the resolved styles of a frame `width` pixels wide: without a
    /// split the layer's slot is not drawn at all (so it is not culled or uploaded either);
    /// with one it is drawn as usual and [`Split`] tells the geometry pass where it starts.
    pub fn apply(&self, slots: &mut [Style], vegetation_layers: &[String], width: u32) -> Result<Split, RenderError> {
        let slot = self.check(vegetation_layers)?;
        debug_assert!(slot < STYLE_SLOTS && slot < slots.len());
        let x = self.split.map(|s| s * width as f32);
        if x.is_none() {
            slots[slot].visible = false;
        }
        Ok(Split { slot, x })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layers() -> Vec<String> {
        vec!["existing".into(), "planned".into()]
    }

    #[test]
    fn a_comparison_names_a_vegetation_layer_and_a_split_within_the_width() {
        let planned = Compare { layer: "planned".into(), split: Some(0.25) };
        assert_eq!(planned.check(&layers()).unwrap(), LayerCode::vegetation(1).code() as usize);
        let mut slots = vec![Style::default(); STYLE_SLOTS];
        let split = planned.apply(&mut slots, &layers(), 800).unwrap();
        assert_eq!(split, Split { slot: 3, x: Some(200.0) });
        assert!(slots[3].visible, "a split view draws the layer (right of the line)");
        let hidden = Compare { layer: "planned".into(), split: None };
        assert_eq!(hidden.apply(&mut slots, &layers(), 800).unwrap().x, None);
        assert!(!slots[3].visible && slots[2].visible);

        for name in ["meadow", "terrain"] {
            let err = Compare { layer: name.into(), split: None }.check(&layers()).unwrap_err().to_string();
            assert!(err.contains(name) && err.contains("existing, planned"), "{err}");
        }
        for split in [-0.1, 1.5, f32::NAN] {
            let err = Compare { layer: "planned".into(), split: Some(split) }.check(&layers()).unwrap_err();
            assert!(err.to_string().contains("0..=1"), "{err}");
        }
    }
}
