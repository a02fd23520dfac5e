//! D3/D4 mappings of fields onto visual features, checked against Table 9.1 of the thesis.
//!
//! | feature | label field | scalar field |
//! | --- | --- | --- |
//! | abstraction | • binary label fields only | • low-precision data only (e.g. fire hazard) |
//! | silhouette density | • binary label fields (presence/absence) | ◦ ambiguous, not suitable |
//! | silhouette style | •• one style per label | ◦ not quantifiable |
//! | hatch tone | • ambiguous except binary label fields | • low and medium precision |
//! | hatch colour (tone of a coloured hatching) | • as hatch tone | • as hatch tone |
//! | hatch pattern | •• one pattern per label | ◦ not quantifiable |
//! | colour | •• one colour per label | •• best suited, with an application colour map |
//!
//! •• well suited, • limited, ◦ unsuitable. An unsuitable combination (and a "binary only"
//! one used with more than two classes) gives a [`Severity::Unsuitable`] warning, a limited
//! one for scalars a [`Severity::Caution`] — warnings, never silent changes or errors. Up to
//! [`MAX_MAPPINGS`] fields can be shown at once (D4, thesis 9.2.2); colour and hatch colour
//! may be used by several of them, every other feature by one. Three scalars as three hatch
//! colours give every field equal visual importance (thesis 9.2.2, Fig. 9.3): each drives the
//! darkness of a hatching in its own ink colour ([`Mapping::color`], by default
//! [`HATCH_COLORS`] of its slot) and its own stroke direction.

use serde::{Deserialize, Serialize};

use super::FieldError;
use super::colormap::{ColorMapName, ColorMapSpec, check_srgb};
use super::field::FieldKind;

/// Most fields mapped at once (D4).
pub const MAX_MAPPINGS: usize = 3;

/// Default ink colours (sRGB 0…1) of [`MappingTarget::HatchColor`] mappings by slot (the
/// mapping's position in the request): the Okabe–Ito vermillion, blue and bluish green, told
/// apart also with the common colour-vision deficiencies.
pub const HATCH_COLORS: [[f32; 3]; MAX_MAPPINGS] = [[0.835, 0.369, 0.0], [0.0, 0.447, 0.698], [0.0, 0.620, 0.451]];

/// A visual feature a field can drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MappingTarget {
    /// Colour of the sketch (colour maps). Also accepted as `colour`.
    #[serde(alias = "colour")]
    Color,
    /// Hatching tone (darkness).
    HatchTone,
    /// Darkness of a hatching in the mapping's own ink colour and stroke direction (thesis
    /// 9.2.2, Fig. 9.3: several scalars as hatchings of different colours).
    HatchColor,
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
pub const ALL_TARGETS: [MappingTarget; 7] = [
    MappingTarget::Abstraction,
    MappingTarget::SilhouetteDensity,
    MappingTarget::SilhouetteStyle,
    MappingTarget::HatchTone,
    MappingTarget::HatchColor,
    MappingTarget::HatchPattern,
    MappingTarget::Color,
];

impl MappingTarget {
    /// Whether several mappings may drive this feature at once (colour tints multiply, hatch
    /// colours each draw their own hatching); every other feature takes one field.
    pub fn is_shared(&self) -> bool {
        matches!(self, MappingTarget::Color | MappingTarget::HatchColor)
    }

    /// The name as in JSON (`hatch_tone`, …).
    pub fn as_str(&self) -> &'static str {
        match self {
            MappingTarget::Color => "color",
            MappingTarget::HatchTone => "hatch_tone",
            MappingTarget::HatchColor => "hatch_color",
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
        (HatchColor, Label) => {
            (Limited, "the tone of a coloured hatching is ambiguous except for binary label fields (presence/absence)")
        }
        (HatchColor, Scalar) => (Limited, "the tone of a coloured hatching suits low- and medium-precision data"),
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// Ink colour (sRGB, each 0…1) of a [`MappingTarget::HatchColor`] mapping; default
    /// [`HATCH_COLORS`] of its slot. Other targets take none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
}

fn one() -> f32 {
    1.0
}

impl Mapping {
    /// A mapping of `layer` onto `target` with defaults.
    pub fn new(layer: &str, target: MappingTarget) -> Mapping {
        Mapping {
            layer: layer.to_string(),
            target,
            range: None,
            colormap: None,
            opacity: 1.0,
            reverse: false,
            color: None,
        }
    }

    /// The colour-map part of the mapping; for a hatch colour, the ramp from paper to its ink
    /// in `slot` (the legend's colours).
    pub fn color_spec(&self, slot: usize) -> ColorMapSpec {
        let ink = (self.target == MappingTarget::HatchColor).then(|| self.hatch_color(slot));
        ColorMapSpec { map: self.colormap, range: self.range, opacity: self.opacity, reverse: self.reverse, ink }
    }

    /// The ink colour of a hatch-colour mapping in `slot` (its position in the request): its
    /// own [`Mapping::color`] or the slot's default of [`HATCH_COLORS`].
    pub fn hatch_color(&self, slot: usize) -> [f32; 3] {
        self.color.unwrap_or(HATCH_COLORS[slot % MAX_MAPPINGS])
    }
}

/// Checks up to [`MAX_MAPPINGS`] mappings: `layer` gives a layer id's kind and number of
/// classes (`None`: unknown id). Errors for too many mappings, unknown layers, a feature other
/// than colour and hatch colour used twice, bad ranges/opacity/colours, a colour on another
/// target than hatch colour or the file palette on a scalar; warnings per Table 9.1 otherwise.
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
        if !m.target.is_shared() && mappings[..index].iter().any(|o| o.target == m.target) {
            return Err(FieldError::Invalid(format!(
                "mapping {index}: {} is already driven by another field (only color and hatch_color can be shared)",
                m.target.as_str()
            )));
        }
        if let Some(color) = m.color {
            if m.target != MappingTarget::HatchColor {
                return Err(FieldError::Invalid(format!(
                    "mapping {index}: \"color\" is the ink of a hatch_color mapping; {} takes none (use colormap)",
                    m.target.as_str()
                )));
            }
            check_srgb(color).map_err(|e| FieldError::Invalid(format!("mapping {index}: color {e}")))?;
        }
        m.color_spec(index).validate().map_err(|e| FieldError::Invalid(format!("mapping {index}: {e}")))?;
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
        // Three scalars as three hatch colours (Fig. 9.3): hatch colour may be shared like colour.
        let hatchings = [
            Mapping::new("tas", MappingTarget::HatchColor),
            Mapping::new("tas", MappingTarget::HatchColor),
            Mapping::new("fire", MappingTarget::HatchColor),
        ];
        let w = validate_mappings(&hatchings, layers).unwrap();
        assert_eq!(
            w.iter().map(|w| (w.index, w.severity)).collect::<Vec<_>>(),
            [(0, Severity::Caution), (1, Severity::Caution)]
        );
        let m: Mapping =
            serde_json::from_str(r#"{"layer":"tas","target":"colour","colormap":"magma","opacity":0.5}"#).unwrap();
        assert_eq!((m.target, m.colormap, m.opacity), (MappingTarget::Color, Some(ColorMapName::Magma), 0.5));
        assert!(serde_json::from_str::<Mapping>(r#"{"layer":"tas","target":"color","bogus":1}"#).is_err());
    }

    #[test]
    fn hatch_color_is_rated_like_hatch_tone() {
        for kind in [FieldKind::Scalar, FieldKind::Label] {
            assert_eq!(suitability(MappingTarget::HatchColor, kind).0, suitability(MappingTarget::HatchTone, kind).0);
        }
        assert!(ALL_TARGETS.contains(&MappingTarget::HatchColor));
        let tas = validate_mappings(&[Mapping::new("tas", MappingTarget::HatchColor)], layers).unwrap();
        assert_eq!(tas[0].severity, Severity::Caution);
        assert!(tas[0].message.contains("hatch_color") && tas[0].message.contains("Table 9.1"), "{}", tas[0].message);
        assert!(validate_mappings(&[Mapping::new("fire", MappingTarget::HatchColor)], layers).unwrap().is_empty());
        let cover = validate_mappings(&[Mapping::new("cover", MappingTarget::HatchColor)], layers).unwrap();
        assert_eq!(cover[0].severity, Severity::Unsuitable);
        assert!(cover[0].message.contains("8 classes"), "{}", cover[0].message);
    }

    #[test]
    fn hatch_colors_are_validated_and_default_per_slot() {
        let parse = |json: &str| serde_json::from_str::<Mapping>(json);
        let red = parse(r#"{"layer":"tas","target":"hatch_color","color":[1,0,0],"reverse":true}"#).unwrap();
        assert_eq!((red.color, red.hatch_color(2)), (Some([1.0, 0.0, 0.0]), [1.0, 0.0, 0.0]));
        assert_eq!(red.color_spec(0).ink, Some([1.0, 0.0, 0.0]));
        let plain = Mapping::new("tas", MappingTarget::HatchColor);
        assert_eq!((0..3).map(|slot| plain.hatch_color(slot)).collect::<Vec<_>>(), HATCH_COLORS);
        assert_eq!(Mapping::new("tas", MappingTarget::Color).color_spec(0).ink, None);
        // Serialised without a colour when none was given (view identities stay as they were).
        assert!(!serde_json::to_string(&plain).unwrap().contains("\"color\""));
        assert!(parse(r#"{"layer":"tas","target":"hatch_color","color":[1,0]}"#).is_err());
        let error = |m: Mapping| validate_mappings(&[m], layers).unwrap_err().to_string();
        let bright = error(Mapping { color: Some([0.2, 1.5, 0.0]), ..plain.clone() });
        assert!(bright.contains("mapping 0: color [0.2, 1.5, 0]") && bright.contains("within 0…1"), "{bright}");
        let misplaced = error(Mapping { color: Some([1.0, 0.0, 0.0]), ..Mapping::new("tas", MappingTarget::Color) });
        assert!(misplaced.contains("hatch_color") && misplaced.contains("colormap"), "{misplaced}");
    }
}
