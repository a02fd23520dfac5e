//! D3/D4 mappings of fields onto visual features, checked against Table 9.1 of the thesis.
//!
//! | feature | label field | scalar field |
//! | --- | --- | --- |
//! | abstraction | • binary label fields only | • low-precision data only (e.g. fire hazard) |
//! | silhouette density | • binary label fields (presence/absence) | ◦ ambiguous, not suitable |
//! | silhouette style | •• one style per label | ◦ not quantifiable |
//! | hatch tone | • ambiguous except binary label fields | • low and medium precision |
//! | hatch pattern | •• one pattern per label | ◦ not quantifiable |
//! | colour | •• one colour per label | •• best suited, with an application colour map |
//!
//! •• well suited, • limited, ◦ unsuitable. An unsuitable combination (and a "binary only"
//! one used with more than two classes) gives a [`Severity::Unsuitable`] warning, a limited
//! one for scalars a [`Severity::Caution`] — warnings, never silent changes or errors. Up to
//! [`MAX_MAPPINGS`] fields can be shown at once (D4, thesis 9.2.2); colour may be used by
//! several of them (e.g. three scalars as three hatch colours, Fig. 9.3), every other feature
//! by one.

use serde::{Deserialize, Serialize};

use super::FieldError;
use super::colormap::{ColorMapName, ColorMapSpec};
use super::field::FieldKind;

/// Most fields mapped at once (D4).
pub const MAX_MAPPINGS: usize = 3;

/// A visual feature a field can drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MappingTarget {
    /// Colour of the sketch (colour maps). Also accepted as `colour`.
    #[serde(alias = "colour")]
    Color,
    /// Hatching tone (darkness).
    HatchTone,
    /// Hatching pattern: one tonal art map per label.
    HatchPattern,
    /// Silhouette style: one stroke style (SAM channel) per label.
    SilhouetteStyle,
    /// Silhouette density (how many silhouettes are drawn).
    SilhouetteDensity,
    /// Degree of abstraction of the plants.
    Abstraction,
}

/// Every target, in Table 9.1 order.
pub const ALL_TARGETS: [MappingTarget; 6] = [
    MappingTarget::Abstraction,
    MappingTarget::SilhouetteDensity,
    MappingTarget::SilhouetteStyle,
    MappingTarget::HatchTone,
    MappingTarget::HatchPattern,
    MappingTarget::Color,
];

impl MappingTarget {
    /// The name as in JSON (`hatch_tone`, …).
    pub fn as_str(&self) -> &'static str {
        match self {
            MappingTarget::Color => "color",
            MappingTarget::HatchTone => "hatch_tone",
            MappingTarget::HatchPattern => "hatch_pattern",
            MappingTarget::SilhouetteStyle => "silhouette_style",
            MappingTarget::SilhouetteDensity => "silhouette_density",
            MappingTarget::Abstraction => "abstraction",
        }
    }
}

/// A rating of Table 9.1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Suitability {
    /// •• well suited.
    Good,
    /// • usable with limits (for labels: binary label fields only).
    Limited,
    /// ◦ not suitable.
    Unsuitable,
}

/// Table 9.1: how well a feature represents a kind of field, with the thesis's remark.
pub fn suitability(target: MappingTarget, kind: FieldKind) -> (Suitability, &'static str) {
    use FieldKind::{Label, Scalar};
    use MappingTarget::*;
    use Suitability::*;
    match (target, kind) {
        (Abstraction, Label) => {
            (Limited, "more than two abstraction degrees are hard to tell apart: binary label fields only")
        }
        (Abstraction, Scalar) => {
            (Limited, "only for low-precision data where a rough estimate suffices (e.g. fire hazard)")
        }
        (SilhouetteDensity, Label) => (Limited, "suitable for binary label fields (presence/absence of silhouettes)"),
        (SilhouetteDensity, Scalar) => (Unsuitable, "silhouette density is ambiguous for scalar data"),
        (SilhouetteStyle, Label) => (Good, "a different silhouette style for each label"),
        (SilhouetteStyle, Scalar) => (Unsuitable, "silhouette style is not quantifiable"),
        (HatchTone, Label) => {
            (Limited, "hatch tone is ambiguous except for binary label fields (presence/absence of hatching)")
        }
        (HatchTone, Scalar) => (Limited, "hatch tone suits low- and medium-precision data"),
        (HatchPattern, Label) => (Good, "each hatch pattern can represent a label"),
        (HatchPattern, Scalar) => (Unsuitable, "hatch pattern is not quantifiable"),
        (Color, Label) => (Good, "each label can be represented by a different colour"),
        (Color, Scalar) => (Good, "best suited, especially with an application-specific colour map"),
    }
}

/// How serious a warning is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Usable with care.
    Caution,
    /// Marked unsuitable: the picture is likely to mislead.
    Unsuitable,
}

/// A warning about one mapping, for the response next to the rendered view.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MappingWarning {
    /// Position of the mapping in the request.
    pub index: usize,
    /// The layer.
    pub layer: String,
    /// The target feature.
    pub target: MappingTarget,
    /// How serious.
    pub severity: Severity,
    /// What to know, e.g. "scalar field → silhouette style: silhouette style is not quantifiable (Table 9.1)".
    pub message: String,
}

/// One field shown through one visual feature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// Layer id.
    pub layer: String,
    /// The feature it drives.
    pub target: MappingTarget,
    /// Values mapped to the two ends of the feature (0…1 of tone, density, abstraction, or the
    /// ends of the colour map); default: the layer's min and max.
    #[serde(default)]
    pub range: Option<[f64; 2]>,
    /// Colour map for [`MappingTarget::Color`]; default by kind.
    #[serde(default)]
    pub colormap: Option<ColorMapName>,
    /// Opacity 0…1 of the effect.
    #[serde(default = "one")]
    pub opacity: f32,
    /// Map high values to the low end.
    #[serde(default)]
    pub reverse: bool,
}

fn one() -> f32 {
    1.0
}

impl Mapping {
    /// A mapping of `layer` onto `target` with defaults.
    pub fn new(layer: &str, target: MappingTarget) -> Mapping {
        Mapping { layer: layer.to_string(), target, range: None, colormap: None, opacity: 1.0, reverse: false }
    }

    /// The colour-map part of the mapping.
    pub fn color_spec(&self) -> ColorMapSpec {
        ColorMapSpec { map: self.colormap, range: self.range, opacity: self.opacity, reverse: self.reverse }
    }
}

/// Checks up to [`MAX_MAPPINGS`] mappings: `layer` gives a layer id's kind and number of
/// classes (`None`: unknown id). Errors for too many mappings, unknown layers, a feature other
/// than colour used twice, bad ranges/opacity or the file palette on a scalar; warnings per
/// Table 9.1 otherwise.
pub fn validate_mappings(
    mappings: &[Mapping],
    layer: impl Fn(&str) -> Option<(FieldKind, usize)>,
) -> Result<Vec<MappingWarning>, FieldError> {
    if mappings.len() > MAX_MAPPINGS {
        return Err(FieldError::Invalid(format!(
            "at most {MAX_MAPPINGS} fields can be mapped at once, {} given",
            mappings.len()
        )));
    }
    let mut warnings = Vec::new();
    for (index, m) in mappings.iter().enumerate() {
        let (kind, classes) = layer(&m.layer)
            .ok_or_else(|| FieldError::Invalid(format!("mapping {index}: unknown layer \"{}\"", m.layer)))?;
        if m.target != MappingTarget::Color && mappings[..index].iter().any(|o| o.target == m.target) {
            return Err(FieldError::Invalid(format!(
                "mapping {index}: {} is already driven by another field (only color can be shared)",
                m.target.as_str()
            )));
        }
        m.color_spec().validate().map_err(|e| FieldError::Invalid(format!("mapping {index}: {e}")))?;
        if kind == FieldKind::Scalar && m.colormap == Some(ColorMapName::File) {
            return Err(FieldError::Invalid(format!("mapping {index}: the file palette colours label fields only")));
        }
        let mut warn = |severity, message: String| {
            warnings.push(MappingWarning { index, layer: m.layer.clone(), target: m.target, severity, message })
        };
        let (rating, remark) = suitability(m.target, kind);
        let what = format!("{kind} field → {}", m.target.as_str());
        match (rating, kind) {
            (Suitability::Good, _) => {}
            (Suitability::Unsuitable, _) => warn(Severity::Unsuitable, format!("{what}: {remark} (Table 9.1)")),
            (Suitability::Limited, FieldKind::Label) if classes > 2 => {
                warn(Severity::Unsuitable, format!("{what}: {remark}; this field has {classes} classes (Table 9.1)"))
            }
            (Suitability::Limited, FieldKind::Label) => {}
            (Suitability::Limited, FieldKind::Scalar) => {
                warn(Severity::Caution, format!("{what}: {remark} (Table 9.1)"))
            }
        }
        if m.target != MappingTarget::Color && m.colormap.is_some() {
            warn(Severity::Caution, format!("{what}: the colour map is only used by the color target"));
        }
        if kind == FieldKind::Scalar && m.colormap.is_some_and(|c| c.is_categorical()) {
            warn(Severity::Caution, format!("{what}: a categorical palette shows a scalar field as bands"));
        }
    }
    Ok(warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layers(id: &str) -> Option<(FieldKind, usize)> {
        match id {
            "tas" => Some((FieldKind::Scalar, 0)),
            "fire" => Some((FieldKind::Label, 2)),
            "cover" => Some((FieldKind::Label, 8)),
            _ => None,
        }
    }

    #[test]
    fn table_9_1_every_cell() {
        for target in ALL_TARGETS {
            for kind in [FieldKind::Scalar, FieldKind::Label] {
                let (_, remark) = suitability(target, kind);
                assert!(!remark.is_empty());
            }
        }
        assert_eq!(suitability(MappingTarget::Color, FieldKind::Scalar).0, Suitability::Good);
        assert_eq!(suitability(MappingTarget::SilhouetteStyle, FieldKind::Scalar).0, Suitability::Unsuitable);
    }

    #[test]
    fn warnings() {
        let w = validate_mappings(&[Mapping::new("tas", MappingTarget::SilhouetteStyle)], layers).unwrap();
        assert_eq!(w.len(), 1);
        assert_eq!(w[0].severity, Severity::Unsuitable);
        assert!(w[0].message.contains("not quantifiable"), "{}", w[0].message);
        assert!(validate_mappings(&[Mapping::new("tas", MappingTarget::Color)], layers).unwrap().is_empty());
        let tone = validate_mappings(&[Mapping::new("tas", MappingTarget::HatchTone)], layers).unwrap();
        assert_eq!(tone[0].severity, Severity::Caution);
        assert!(validate_mappings(&[Mapping::new("fire", MappingTarget::HatchTone)], layers).unwrap().is_empty());
        let many = validate_mappings(&[Mapping::new("cover", MappingTarget::HatchTone)], layers).unwrap();
        assert!(many[0].message.contains("8 classes"));
    }

    #[test]
    fn d4_limits() {
        let three = [
            Mapping::new("tas", MappingTarget::Color),
            Mapping::new("fire", MappingTarget::Color),
            Mapping::new("cover", MappingTarget::SilhouetteStyle),
        ];
        assert!(validate_mappings(&three, layers).unwrap().is_empty());
        let four: Vec<_> = three.iter().cloned().chain([Mapping::new("tas", MappingTarget::HatchTone)]).collect();
        assert!(validate_mappings(&four, layers).unwrap_err().to_string().contains("at most 3"));
        let twice =
            [Mapping::new("fire", MappingTarget::HatchPattern), Mapping::new("cover", MappingTarget::HatchPattern)];
        assert!(validate_mappings(&twice, layers).is_err());
        assert!(
            validate_mappings(&[Mapping::new("nope", MappingTarget::Color)], layers)
                .unwrap_err()
                .to_string()
                .contains("unknown layer")
        );
        let m: Mapping =
            serde_json::from_str(r#"{"layer":"tas","target":"colour","colormap":"magma","opacity":0.5}"#).unwrap();
        assert_eq!((m.target, m.colormap, m.opacity), (MappingTarget::Color, Some(ColorMapName::Magma), 0.5));
        assert!(serde_json::from_str::<Mapping>(r#"{"layer":"tas","target":"color","bogus":1}"#).is_err());
    }
}
