//! The style parameters of a rendering: one struct, serialisable, with defaults, ranges and a
//! schema generated from the same field list, together with its partial form
//! ([`PartialStyle`]: any subset of the fields, as requests, presets and layers give them);
//! the photorealism axis (thesis 8.2.7); per-layer styles of one frame (thesis 8.2.8); and the
//! uniform blocks the passes read.
//!
//! The field-by-field reference is in the README ("Style"); [`Style::schema`] gives the same
//! as data (name, kind, default, range, description) for the CLI and the API.

use super::RenderError;
use super::layer_code::LayerCode;
use serde::de::{self, Deserializer, MapAccess, Visitor};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;
use std::fmt;

/// How hatch texture coordinates are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HatchSpace {
    /// The thesis' hybrid parametrization (eq. 6.2–6.6) on foliage, cylindrical object space on
    /// trunks and branches (the terrain follows `terrain_stroke_direction`).
    Hybrid,
    /// Plain image-space hatching (screen coordinates), the baseline the coherence figure is
    /// compared with.
    Image,
}

/// Where the terrain's hatch strokes come from and which way they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TerrainStrokes {
    /// Image-space hatching (screen coordinates): the strokes stay on the screen when the
    /// camera moves; the coherence baseline.
    Image,
    /// Strokes attached to the ground, along the contour direction (level lines).
    Contour,
    /// Strokes attached to the ground, along the fall line (hachures, Imhof).
    FallLine,
}

impl TerrainStrokes {
    /// The code the shaders read (`TERRAIN_IMAGE`, `TERRAIN_CONTOUR`, `TERRAIN_FALL_LINE`).
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// How the leaves of plants at full detail are drawn (thesis 4.1–4.2; SPEC R1, R2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LeafMode {
    /// The model's own leaf geometry.
    Original,
    /// One camera-facing quad per leaf (leaf particles, SPEC R2).
    Billboard,
    /// One quad per leaf, turned so its normal points away from its HLP centre along N_HLP
    /// (thesis eq. 4.7; the "children's book" look of thesis 4.2).
    Reoriented,
    /// One ellipse per leaf in the plane tangent to its HLP sphere, elongated around the HLP's
    /// vertical axis (the "Van Gogh" look of NPAR Fig. 3, thesis Fig. 4.8c).
    Elliptical,
    /// No leaves: one substitution shape per branch cluster, an ellipsoid in the box of its
    /// leaves (SPEC P5, Campos et al. 2004 §3.2, `prep::substitution`), also in place of the
    /// HLP billboard clouds of the next level of detail.
    Shapes,
}

impl LeafMode {
    /// Whether leaves are drawn as particles (one primitive per leaf) rather than the model's
    /// own geometry or substitution shapes.
    pub fn particles(self) -> bool {
        !matches!(self, LeafMode::Original | LeafMode::Shapes)
    }
}

/// A type a style field can have: its kind in the schema, the numbers its range applies to
/// and its value in the schema.
trait FieldValue {
    /// `number`, `integer`, `boolean`, `string` or `color` (three numbers).
    const KIND: &'static str;
    /// The numbers checked against the field's range (every component of a colour).
    fn numbers(&self) -> Vec<f32>;
    /// The value as JSON.
    fn to_json(&self) -> Value;
}

/// `value` as a JSON number in its short decimal form (0.2, not the 0.20000000298023224 that
/// widening the `f32` to `f64` gives), as JSON text writes it.
fn short_number(value: f32) -> Value {
    value.to_string().parse::<f64>().ok().and_then(serde_json::Number::from_f64).map_or(Value::Null, Value::Number)
}

impl FieldValue for f32 {
    const KIND: &'static str = "number";
    fn numbers(&self) -> Vec<f32> {
        vec![*self]
    }
    fn to_json(&self) -> Value {
        short_number(*self)
    }
}

impl FieldValue for u32 {
    const KIND: &'static str = "integer";
    fn numbers(&self) -> Vec<f32> {
        vec![*self as f32]
    }
    fn to_json(&self) -> Value {
        Value::from(*self)
    }
}

impl FieldValue for usize {
    const KIND: &'static str = "integer";
    fn numbers(&self) -> Vec<f32> {
        vec![*self as f32]
    }
    fn to_json(&self) -> Value {
        Value::from(*self)
    }
}

impl FieldValue for bool {
    const KIND: &'static str = "boolean";
    fn numbers(&self) -> Vec<f32> {
        Vec::new()
    }
    fn to_json(&self) -> Value {
        Value::Bool(*self)
    }
}

impl FieldValue for HatchSpace {
    const KIND: &'static str = "string";
    fn numbers(&self) -> Vec<f32> {
        Vec::new()
    }
    fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

impl FieldValue for TerrainStrokes {
    const KIND: &'static str = "string";
    fn numbers(&self) -> Vec<f32> {
        Vec::new()
    }
    fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

impl FieldValue for LeafMode {
    const KIND: &'static str = "string";
    fn numbers(&self) -> Vec<f32> {
        Vec::new()
    }
    fn to_json(&self) -> Value {
        serde_json::to_value(self).unwrap_or(Value::Null)
    }
}

impl FieldValue for [f32; 3] {
    const KIND: &'static str = "color";
    fn numbers(&self) -> Vec<f32> {
        self.to_vec()
    }
    fn to_json(&self) -> Value {
        Value::Array(self.iter().map(|c| short_number(*c)).collect())
    }
}

/// One style field described as data: what `landsketch presets --schema`, `GET /api/scene`
/// and the README table show.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FieldSchema {
    /// The JSON field name.
    pub name: &'static str,
    /// `number`, `integer`, `boolean`, `string` (an enumeration, values in the description) or
    /// `color` (three sRGB numbers).
    pub kind: &'static str,
    /// The default value.
    pub default: Value,
    /// Smallest allowed value (of each component for colours); `None` when unbounded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min: Option<f32>,
    /// Largest allowed value; `None` when unbounded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max: Option<f32>,
    /// What the field does.
    pub doc: String,
}

/// Joins the lines of a doc comment into one paragraph.
fn paragraph(doc: &str) -> String {
    doc.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Defines [`Style`], its `Default`, its range validation and its schema, and [`PartialStyle`]
/// with its merge rules, from one field list: `/// doc` `name: type = default, lo..=hi;` (the
/// range is optional).
macro_rules! style_fields {
    ($($(#[doc = $doc:literal])+ $name:ident : $ty:ty = $default:expr $(, $lo:literal ..= $hi:literal)?;)+) => {
        /// Style parameters, from pen-and-ink sketch to photorealism. Every field has a default,
        /// so any subset can be given as JSON; unknown fields are errors.
        #[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct Style {
            $($(#[doc = $doc])+ pub $name: $ty,)+
        }

        impl Default for Style {
            fn default() -> Self {
                Style { $($name: $default,)+ }
            }
        }

        impl Style {
            /// Checks every parameter against its range (the error names the field and the
            /// range); art map indices are checked by the renderer, which knows its maps.
            pub fn validate(&self) -> Result<(), RenderError> {
                $($(
                    for value in self.$name.numbers() {
                        if !(value.is_finite() && (($lo as f32)..=($hi as f32)).contains(&value)) {
                            return Err(RenderError::Style {
                                field: stringify!($name),
                                value,
                                range: concat!(stringify!($lo), "..=", stringify!($hi)),
                            });
                        }
                    }
                )?)+
                Ok(())
            }

            /// Every field with its kind, default, range and description, in declaration order.
            pub fn schema() -> Vec<FieldSchema> {
                let defaults = Style::default();
                vec![$(FieldSchema {
                    name: stringify!($name),
                    kind: <$ty as FieldValue>::KIND,
                    default: defaults.$name.to_json(),
                    min: None $(.or(Some($lo as f32)))?,
                    max: None $(.or(Some($hi as f32)))?,
                    doc: paragraph(concat!($($doc, " "),+)),
                },)+]
            }

            /// Replaces the fields `partial` sets (without validating: see [`Style::with`]).
            pub fn apply(&mut self, partial: &PartialStyle) {
                $(if let Some(value) = &partial.$name {
                    self.$name = value.clone();
                })+
            }
        }

        /// Any subset of the [`Style`] fields (`None`: not set): the overrides of a request,
        /// a preset's fields, a layer's own fields. As JSON an object of style fields; unknown
        /// fields and values of the wrong type are errors naming the field (ranges are checked
        /// on the complete style, [`Style::with`]).
        #[derive(Debug, Clone, Default, PartialEq, Serialize)]
        pub struct PartialStyle {
            $($(#[doc = $doc])+ #[serde(skip_serializing_if = "Option::is_none")] pub $name: Option<$ty>,)+
        }

        impl PartialStyle {
            /// The field names, in declaration order.
            pub const FIELDS: &'static [&'static str] = &[$(stringify!($name)),+];

            /// Sets the fields `later` sets: later wins.
            pub fn merge(&mut self, later: &PartialStyle) {
                $(if let Some(value) = &later.$name {
                    self.$name = Some(value.clone());
                })+
            }

            /// The fields of `style` that differ from `base`: `base` with them applied is
            /// `style`.
            pub fn diff(style: &Style, base: &Style) -> PartialStyle {
                PartialStyle { $($name: (style.$name != base.$name).then(|| style.$name.clone()),)+ }
            }

            /// Whether no field is set.
            pub fn is_empty(&self) -> bool {
                true $(&& self.$name.is_none())+
            }

            /// Reads the value of the field `key` from `map` (a field given twice keeps the
            /// later value, as in a JSON object); `false` (nothing read) when no field has this
            /// name. A value of the wrong type is an error naming the field.
            fn read_field<'de, A: MapAccess<'de>>(&mut self, key: &str, map: &mut A) -> Result<bool, A::Error> {
                match key {
                    $(stringify!($name) => self.$name = Some(map.next_value().map_err(|e| field_error(key, e))?),)+
                    _ => return Ok(false),
                }
                Ok(true)
            }
        }
    };
}

/// The deserialization error of a style field: [`RenderError::StyleField`] naming it.
fn field_error<E: de::Error>(field: &str, message: impl fmt::Display) -> E {
    E::custom(RenderError::StyleField { field: Some(field.to_owned()), message: message.to_string() })
}

/// The deserialization error of a key that is no style field: [`RenderError::StyleField`]
/// listing the fields (and `extra`, the other keys the object takes).
fn unknown_field<E: de::Error>(key: &str, extra: &[&str]) -> E {
    let fields: Vec<String> = extra.iter().chain(PartialStyle::FIELDS).map(|f| format!("`{f}`")).collect();
    let message = format!("unknown field `{key}`, expected one of {}", fields.join(", "));
    E::custom(RenderError::StyleField { field: None, message })
}

impl<'de> Deserialize<'de> for PartialStyle {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<PartialStyle, D::Error> {
        /// Reads a JSON object of style fields.
        struct Fields;
        impl<'de> Visitor<'de> for Fields {
            type Value = PartialStyle;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a JSON object of style fields")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<PartialStyle, A::Error> {
                let mut partial = PartialStyle::default();
                while let Some(key) = map.next_key::<String>()? {
                    if !partial.read_field(&key, &mut map)? {
                        return Err(unknown_field(&key, &[]));
                    }
                }
                Ok(partial)
            }
        }
        deserializer.deserialize_map(Fields)
    }
}

/// A layer's own style (thesis 8.2.8): its fields over the view's style, or over a preset it
/// names. As JSON an object of style fields with an optional `"preset"`, e.g.
/// `{"preset": "photorealism", "ambient": 0.2}`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LayerStyle {
    /// The preset the fields merge over instead of the view's style.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// The layer's own fields.
    #[serde(flatten)]
    pub fields: PartialStyle,
}

impl<'de> Deserialize<'de> for LayerStyle {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<LayerStyle, D::Error> {
        /// Reads a JSON object of style fields and `preset`.
        struct Fields;
        impl<'de> Visitor<'de> for Fields {
            type Value = LayerStyle;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a layer style: a JSON object of style fields and an optional \"preset\"")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<LayerStyle, A::Error> {
                let mut layer = LayerStyle::default();
                while let Some(key) = map.next_key::<String>()? {
                    if key == "preset" {
                        let name = map.next_value::<String>().map_err(|e| field_error(&key, e))?;
                        layer.preset = Some(name);
                    } else if !layer.fields.read_field(&key, &mut map)? {
                        return Err(unknown_field(&key, &["preset"]));
                    }
                }
                Ok(layer)
            }
        }
        deserializer.deserialize_map(Fields)
    }
}

impl LayerStyle {
    /// Sets what `later` sets: its preset, if it names one, and its fields (later wins).
    pub fn merge(&mut self, later: &LayerStyle) {
        if later.preset.is_some() {
            self.preset.clone_from(&later.preset);
        }
        self.fields.merge(&later.fields);
    }
}

style_fields! {
    /// Whether plants are drawn: `false` in a vegetation layer's style hides that layer (e.g.
    /// the planned state without the existing plants), in the base style every vegetation
    /// layer without a style of its own; the terrain is always drawn.
    visible: bool = true;
    /// Master axis between sketch (0) and photorealism (1), thesis 8.2.7 (where the parameter
    /// runs the other way, 1 = sketch): moves every other parameter continuously towards
    /// photorealistic rendering (see `Style::resolved`).
    photorealism: f32 = 0.0, 0..=1;
    /// Depth-difference scale `c` of thesis eq. 5.1 (applied to relative depth differences).
    contour_scale: f32 = 4.0, 0..=1000;
    /// Threshold `t` of thesis eq. 5.1: relative depth steps below `t / c` draw no contour.
    contour_threshold: f32 = 0.2, 0..=10;
    /// Selective-dilation depth pre-filter before contour detection (thesis eq. 5.4).
    contour_prefilter: bool = true;
    /// Remove isolated contour pixels (thesis eq. 5.2).
    isolated_pixel_removal: bool = true;
    /// Threshold `t'` of thesis eq. 5.2 separating contour pixels from background (also what
    /// counts as a contour pixel for silhouettes).
    isolated_pixel_threshold: f32 = 0.5, 0..=1;
    /// How dark plain contours are drawn, 0 (invisible) to 1 (full ink).
    contour_strength: f32 = 1.0, 0..=1;
    /// Silhouette art map (SAM) index: 0 plain lines, 1 scallops, 2 spikes, 3 sketchy double
    /// lines.
    silhouette_map: usize = 1, 0..=255;
    /// Width in pixels of the silhouette support searched along E (thesis 5.2); 0 disables
    /// stylized silhouettes.
    silhouette_support: f32 = 8.0, 0..=16;
    /// Stretch `c` of the SAM along the contour (thesis eq. 5.5).
    silhouette_stretch: f32 = 1.0, 0.01..=100;
    /// How dark stylized silhouettes are drawn, 0 to 1.
    silhouette_strength: f32 = 1.0, 0..=1;
    /// Tonal art map (TAM) index: 0 lines, 1 cross-hatching, 2 scribbles, 3 stipples.
    hatch_map: usize = 0, 0..=255;
    /// `hybrid` (thesis 6.1) or `image`: how plants' hatch coordinates are computed.
    hatch_space: HatchSpace = HatchSpace::Hybrid;
    /// TAM tiles per π radians of an HLP sphere (`m = n` of thesis eq. 6.1–6.3).
    hatch_tiles: f32 = 2.0, 0.05..=64;
    /// `c` of the surface function f(A) (thesis eq. 6.6); 0 keeps hatching flat.
    hatch_surface: f32 = 0.0, 0..=10;
    /// Size of one TAM tile in pixels where hatching is in image space (everything with
    /// `hatch_space: image`, the terrain with `terrain_stroke_direction: image`), and the size
    /// on screen the terrain's object-space strokes keep from the feet to the horizon.
    image_hatch_scale: f32 = 256.0, 4..=4096;
    /// The terrain's hatch strokes: `fall_line` (hachures down the slope) or `contour` (along
    /// the level lines), both attached to the ground with constant width and spacing on
    /// screen (two power-of-two stroke scales blended by the screen footprint, Bénard et al.
    /// 2010 infinite zoom, over the TAM's mip levels), or `image` (screen-space hatching,
    /// glued to the screen when the camera moves).
    terrain_stroke_direction: TerrainStrokes = TerrainStrokes::FallLine;
    /// Tone of the terrain from its light relative to flat ground's, 0 (the absolute light,
    /// as every other surface) to 1 (flat ground and slopes facing the sun are paper, slopes
    /// turned away from it dark: the pen-and-ink convention of Imhof and Buchin et al. 2011).
    terrain_relief: f32 = 1.0, 0..=1;
    /// How much the terrain darkens with its steepness, 0 (light alone) to 1 (a 45° slope is
    /// black whatever its light): Lehmann's hachure rule "the steeper, the darker", so gentle
    /// relief in full sun (valleys, banks, field edges) still gets sparse strokes.
    terrain_slope_tone: f32 = 0.4, 0..=1;
    /// Vertical exaggeration of the relief for the terrain's tone (the z-factor of a
    /// hillshade): 1 as it is; 3–5 let the gentle slopes, banks and valleys of lowland country
    /// read in the strokes.
    terrain_exaggeration: f32 = 1.0, 1..=10;
    /// How dark the terrain's crease lines are drawn — valley bottoms and ridge crests, fixed
    /// to the ground (`prep::creases`) — with the contours (scaled by `contour_strength`), 0
    /// (none) to 1.
    terrain_creases: f32 = 0.7, 0..=1;
    /// The smallest area in hectares a valley (or, of the inverted terrain, a ridge) drains for
    /// its crease line to be drawn: larger values keep only the main valleys and crests.
    terrain_crease_area: f32 = 20.0, 0.2..=100000;
    /// The smallest change of slope in degrees, along the fall line, for a break-of-slope line
    /// to be drawn (the top of a bank or a scarp, the foot of a slope, a terrace's edge; drawn
    /// with the crease lines): lower values draw gentler breaks, 90 none.
    terrain_break_angle: f32 = 15.0, 4..=90;
    /// How dark the borders between the ground's land-cover classes are drawn (with the
    /// contours, scaled by `contour_strength`), 0 (none) to 1: the outline of a wood, a field
    /// or a lake on the ground (`[terrain] landcover`).
    land_cover_outline: f32 = 0.6, 0..=1;
    /// How dark hatching is drawn, 0 (none) to 1.
    hatch_strength: f32 = 1.0, 0..=1;
    /// Lifts the hatch tone towards white, 0 (as lit) to 1 (brightest: no strokes), thesis
    /// 8.2.5/8.2.7.
    hatch_brightness: f32 = 0.0, 0..=1;
    /// HLP abstraction `1 − f` of thesis eq. 4.8: leaves move from their positions (0) to the
    /// surface of their HLP sphere (1).
    hlp_abstraction: f32 = 0.0, 0..=1;
    /// Distance-dependent abstraction (thesis 7.3, "increased abstraction of the background"):
    /// how much `hlp_abstraction` and `normal_blend` of the plants rise towards 1 with their
    /// distance from the eye, none up to `abstraction_near`, this share of the way to 1 from
    /// `abstraction_far` on, smoothly in between; 0 off. Near plants keep their detail while
    /// the ones behind them simplify into their crowns' shapes.
    distance_abstraction: f32 = 0.0, 0..=1;
    /// Stroke simplification with distance (thesis 7.3; pen-and-ink's fewer, lighter strokes
    /// for the background): the share of the way to paper that the hatch tone is lifted at
    /// `abstraction_far` and beyond (along the same curve as `distance_abstraction`), so far
    /// surfaces keep the strokes of their darkest parts only; the TAM's nested tones drop
    /// strokes one by one as the distance grows, without popping. 0 off.
    distance_simplification: f32 = 0.0, 0..=1;
    /// Distance from the eye in metres (along the view) where `distance_abstraction` and
    /// `distance_simplification` start.
    abstraction_near: f32 = 30.0, 0..=100000;
    /// Distance from the eye in metres where `distance_abstraction` and
    /// `distance_simplification` are reached in full (at least `abstraction_near`).
    abstraction_far: f32 = 150.0, 0..=100000;
    /// How leaves of plants at full detail are drawn: `original` (the model's leaf geometry),
    /// `billboard` (a camera-facing quad per leaf, SPEC R2), `reoriented` (each leaf's quad
    /// turned away from its HLP centre, thesis 4.2 "children's book"), `elliptical`
    /// (ellipses tangent to the HLP sphere, elongated around its vertical axis, "Van Gogh") or
    /// `shapes` (one ellipsoid per branch cluster instead of its leaves, also at the next level
    /// of detail, SPEC P5). The particle modes draw fewer, larger leaves as a plant gets
    /// smaller on screen (SPEC P4).
    leaf_mode: LeafMode = LeafMode::Original;
    /// Scale of the leaf particles about their centres (the particle modes of `leaf_mode`).
    leaf_size: f32 = 1.0, 0.25..=4;
    /// Leaf shape (thesis 4.1): the alpha threshold moves from α_max (0: the original leaf
    /// outline) to α_min (1: the most abstract, largest shape of the leaf shape map).
    leaf_shape: f32 = 0.0, 0..=1;
    /// Leaf outline thickness Δα of thesis eq. 4.1: leaf texels with α − α_t ≤ Δα are drawn in
    /// ink (on `elliptical` leaves, where 1 − (s² + t²) ≤ Δα); 0 = no outlines.
    leaf_outline: f32 = 0.0, 0..=1;
    /// Blend of the original normals towards the HLP normals for lighting and colour (thesis
    /// 6.1.3, 6.2).
    normal_blend: f32 = 0.5, 0..=1;
    /// Ambient share of the light, 0 (pure Lambert) to 1 (flat).
    ambient: f32 = 0.5, 0..=1;
    /// Blend of the foliage's lighting normals towards the normals of its implicit surface
    /// (Luft et al. 2007 §3.3, `prep::implicit`: a metaball surface over the leaf centres), 0
    /// the leaves' own normals, 1 the crown's smooth overall shape; applied before
    /// `normal_blend`. Plants at full detail.
    implicit_normals: f32 = 0.0, 0..=1;
    /// How much the density-based ambient coefficient k_a of the foliage (Luft et al. eq. 4:
    /// darker where the leaves are denser, inside the crown) darkens the ambient light, 0 (not
    /// at all) to 1 (fully). Plants at full detail.
    ambient_occlusion: f32 = 0.0, 0..=1;
    /// How much the surface's own albedo darkens the hatch tone, 0 (lighting only) to 1.
    albedo_weight: f32 = 0.6, 0..=1;
    /// Contrast `scale` of thesis eq. 6.7 about `tone_reference`; 1 leaves the tone unchanged.
    tone_contrast: f32 = 1.6, 0..=10;
    /// `L_ref` of thesis eq. 6.7.
    tone_reference: f32 = 0.45, 0..=1;
    /// Banding of the hatch tone into this many levels (thesis 6.1.3); 0 keeps it continuous.
    tone_levels: u32 = 0, 0..=16;
    /// Radius in pixels of the Gaussian blur of the tone image (thesis Fig. 6.9d); 0 = none.
    tone_blur: u32 = 2, 0..=4;
    /// Amount of colour painted under the ink (thesis 6.2, 8.2.6): 0 paper, 1 the shaded
    /// surface colour.
    color: f32 = 0.0, 0..=1;
    /// Saturation of the surface colour: 0 grey, 1 as textured, 2 doubled.
    color_saturation: f32 = 1.0, 0..=2;
    /// Colour abstraction (thesis 6.2): 0 the texture colour, 1 the material's average colour.
    color_abstraction: f32 = 0.0, 0..=1;
    /// Highlight the plan: the scene's plan layer (`[about] plan_layer`) keeps its detail and
    /// gets colour, while the ground and the other layers are drawn lighter and greyer (thesis
    /// 7.3, "increased abstraction of the background"); 0 off, 1 full.
    focus: f32 = 0.0, 0..=1;
    /// Blend of Lambert shading towards Gooch cool-to-warm shading, 0 to 1.
    gooch: f32 = 0.0, 0..=1;
    /// Blend of smooth shading towards toon shading with a 1D ramp of `toon_levels` bands
    /// (Campos et al.), 0 to 1.
    toon: f32 = 0.0, 0..=1;
    /// Bands of the toon ramp.
    toon_levels: u32 = 3, 2..=16;
    /// Background: 0 paper, 1 the sky gradient from `sky_horizon` to `sky_zenith`.
    sky: f32 = 0.0, 0..=1;
    /// Sky colour overhead (sRGB, 0..1).
    sky_zenith: [f32; 3] = [0.33, 0.52, 0.82], 0..=1;
    /// Sky colour at the horizon (sRGB, 0..1).
    sky_horizon: [f32; 3] = [0.8, 0.87, 0.94], 0..=1;
    /// Ink colour (sRGB, 0..1).
    ink: [f32; 3] = [0.08, 0.08, 0.1], 0..=1;
    /// Paper colour (sRGB, 0..1).
    paper: [f32; 3] = [1.0, 1.0, 0.98], 0..=1;
}

/// Value the contour threshold moves to at full photorealism: the top of its range, where no
/// depth step draws a contour (thesis 8.2.7: "edge detection threshold … to 1").
const PHOTOREAL_CONTOUR_THRESHOLD: f32 = 10.0;

/// Photorealism from which the leaves are the model's own (`leaf_mode` `original`): the leaf
/// primitive is a discrete choice, so it switches where every continuous parameter is half-way.
const PHOTOREAL_ORIGINAL_LEAVES: f32 = 0.5;

impl Style {
    /// The parameters actually rendered: every field moved from its value towards its
    /// photorealistic value by `photorealism` p (thesis 8.2.7), `v + (target − v)·p`:
    /// HLP abstraction, its rise with distance and HLP normals → 0 (original geometry and
    /// lighting), contour threshold
    /// → 10 (no contours), contour and silhouette strength and silhouette support → 0 (no
    /// lines), hatch brightness → 1 (no strokes), colour → 1, saturation → 1, colour
    /// abstraction → 0 (full, realistic colour), Gooch and toon → 0 (Lambert shading), sky → 1;
    /// leaf size → 1, leaf shape → 0 and leaf outline → 0 (the original leaves), and the leaf
    /// mode becomes `original` from p = 0.5 on. `implicit_normals` and `ambient_occlusion`
    /// keep their values: the implicit-surface illumination is lighting, not abstraction, and
    /// serves photorealistic rendering as well as sketches (Luft et al. 2007 §4, Fig. 5).
    pub fn resolved(&self) -> Style {
        let p = self.photorealism;
        let to = |value: f32, target: f32| value + (target - value) * p;
        Style {
            hlp_abstraction: to(self.hlp_abstraction, 0.0),
            distance_abstraction: to(self.distance_abstraction, 0.0),
            distance_simplification: to(self.distance_simplification, 0.0),
            normal_blend: to(self.normal_blend, 0.0),
            contour_threshold: to(self.contour_threshold, PHOTOREAL_CONTOUR_THRESHOLD),
            contour_strength: to(self.contour_strength, 0.0),
            silhouette_strength: to(self.silhouette_strength, 0.0),
            silhouette_support: to(self.silhouette_support, 0.0),
            hatch_brightness: to(self.hatch_brightness, 1.0),
            color: to(self.color, 1.0),
            color_saturation: to(self.color_saturation, 1.0),
            color_abstraction: to(self.color_abstraction, 0.0),
            gooch: to(self.gooch, 0.0),
            toon: to(self.toon, 0.0),
            sky: to(self.sky, 1.0),
            leaf_mode: if p >= PHOTOREAL_ORIGINAL_LEAVES { LeafMode::Original } else { self.leaf_mode },
            leaf_size: to(self.leaf_size, 1.0),
            leaf_shape: to(self.leaf_shape, 0.0),
            leaf_outline: to(self.leaf_outline, 0.0),
            ..self.clone()
        }
    }

    /// This (resolved) style with its `focus` f applied: the plan layer (`plan`) gets colour
    /// under its ink (at least f), saturation (at least 1 + 0.8 f) and hatching lifted by at
    /// least 0.3 f (`hatch_brightness`, so the colour shows between the strokes; its lines
    /// stay), everything else
    /// keeps `1 − 0.5 f` of its hatching, crease and land-cover lines, `1 − 0.4 f` of its
    /// contours and silhouettes and `1 − 0.7 f` of its saturation, so the plan stands out by
    /// detail, contrast and colour in every style.
    pub fn focused(&self, plan: bool) -> Style {
        let f = self.focus;
        if plan {
            return Style {
                color: self.color.max(f),
                color_saturation: self.color_saturation.max(1.0 + 0.8 * f),
                hatch_brightness: self.hatch_brightness.max(0.3 * f),
                ..self.clone()
            };
        }
        Style {
            hatch_strength: self.hatch_strength * (1.0 - 0.5 * f),
            terrain_creases: self.terrain_creases * (1.0 - 0.5 * f),
            land_cover_outline: self.land_cover_outline * (1.0 - 0.5 * f),
            contour_strength: self.contour_strength * (1.0 - 0.4 * f),
            silhouette_strength: self.silhouette_strength * (1.0 - 0.4 * f),
            color_saturation: self.color_saturation * (1.0 - 0.7 * f),
            ..self.clone()
        }
    }

    /// The largest tile of the terrain's object-space strokes on screen, in pixels: half
    /// `image_hatch_scale`. The strokes blend two power-of-two scales whose tiles cover
    /// between a quarter and a half of `image_hatch_scale` pixels (the finer) and between a
    /// half and one (the coarser), so a TAM made for image-space hatching at that scale is
    /// never magnified and its strokes keep their width (`shaders/gbuffer.wgsl`
    /// `terrain_hatch`).
    pub fn terrain_tile(&self) -> f32 {
        0.5 * self.image_hatch_scale
    }

    /// This style with the fields of `partial` replaced, validated: out-of-range values are
    /// [`RenderError::Style`] naming the field and its range.
    pub fn with(&self, partial: &PartialStyle) -> Result<Style, RenderError> {
        let mut style = self.clone();
        style.apply(partial);
        style.validate()?;
        Ok(style)
    }
}

/// Name of the terrain in per-layer styles (vegetation layers use their scene names).
pub const TERRAIN_LAYER: &str = "terrain";

/// The style slot of an object ID: its layer code (top 8 bits), or the base slot 0 beyond the
/// slots (`style_slot` in the shaders).
pub fn style_slot(object_id: u32) -> usize {
    super::layer_code::LayerCode::of_object_id(object_id).slot()
}

/// Style slots of one frame, indexed by the layer code of the ID buffer: 0 the background (the
/// base style), 1 the terrain, `i + 2` vegetation layer `i`. Layer codes from here on use the
/// base style.
pub const STYLE_SLOTS: usize = 16;

/// The styles of one frame (thesis 8.2.8): a base style and, by layer name (`terrain` or a
/// vegetation layer's name), styles of their own for some layers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStyle {
    /// The style of the background and of every layer without its own.
    pub base: Style,
    /// Styles of single layers.
    pub layers: BTreeMap<String, Style>,
}

impl From<Style> for FrameStyle {
    fn from(base: Style) -> FrameStyle {
        FrameStyle { base, layers: BTreeMap::new() }
    }
}

impl From<&Style> for FrameStyle {
    fn from(base: &Style) -> FrameStyle {
        FrameStyle::from(base.clone())
    }
}

impl From<&FrameStyle> for FrameStyle {
    fn from(styles: &FrameStyle) -> FrameStyle {
        styles.clone()
    }
}

impl FrameStyle {
    /// Every style of the frame, the base first.
    pub fn styles(&self) -> impl Iterator<Item = &Style> {
        std::iter::once(&self.base).chain(self.layers.values())
    }

    /// The resolved style (photorealism applied) of every slot, given the scene's vegetation
    /// layer names and its plan layer (the one `focus` highlights; see [`Style::focused`]). A
    /// layer name the scene does not have, or a layer beyond the slots, is an error.
    pub fn slots(&self, vegetation_layers: &[String], plan_layer: Option<&str>) -> Result<Vec<Style>, RenderError> {
        let mut slots = vec![self.base.resolved(); STYLE_SLOTS];
        for (name, style) in &self.layers {
            let code = layer_code(name, vegetation_layers)?;
            let Some(slot) = code.own_slot() else {
                return Err(RenderError::LayerSlots { name: name.clone(), max: LayerCode::VEGETATION_SLOTS });
            };
            slots[slot] = style.resolved();
        }
        let plan_slot =
            plan_layer.and_then(|name| layer_code(name, vegetation_layers).ok()).and_then(|code| code.own_slot());
        if let Some(plan_slot) = plan_slot {
            for (slot, style) in slots.iter_mut().enumerate() {
                *style = style.focused(slot == plan_slot);
            }
        }
        Ok(slots)
    }
}

/// The layer code of the layer `name` (`terrain` or one of `vegetation_layers`, the scene's
/// vegetation layer names), which may be beyond the slots; another name is an error naming the
/// scene's layers.
pub fn layer_code(name: &str, vegetation_layers: &[String]) -> Result<LayerCode, RenderError> {
    if name == TERRAIN_LAYER {
        return Ok(LayerCode::TERRAIN);
    }
    let index = vegetation_layers.iter().position(|l| l == name).ok_or_else(|| {
        let known: Vec<&str> =
            std::iter::once(TERRAIN_LAYER).chain(vegetation_layers.iter().map(String::as_str)).collect();
        RenderError::UnknownLayer { name: name.to_owned(), known: known.join(", ") }
    })?;
    Ok(LayerCode::vegetation(index))
}

/// Groups the slots by silhouette art map: the distinct `silhouette_map`s in slot order, and
/// each slot's group. The compose pass runs once per group (a pass binds one SAM; the TAMs are
/// one array picked per pixel) and draws only the pixels of its group's slots.
pub fn art_groups(slots: &[Style]) -> (Vec<usize>, Vec<u32>) {
    let mut groups: Vec<usize> = Vec::new();
    let slot_groups = slots
        .iter()
        .map(|s| {
            let key = s.silhouette_map;
            let index = groups.iter().position(|g| *g == key).unwrap_or_else(|| {
                groups.push(key);
                groups.len() - 1
            });
            index as u32
        })
        .collect();
    (groups, slot_groups)
}

/// Thesis eq. 6.7 followed by banding: `L' = (L − L_ref)·scale + L_ref`, clamped to 0..1, then
/// rounded to `levels` steps when `levels > 0`. The contour shader implements the same.
pub fn contrast_tone(light: f32, reference: f32, scale: f32, levels: u32) -> f32 {
    let t = ((light - reference) * scale + reference).clamp(0.0, 1.0);
    if levels == 0 { t } else { (t * levels as f32).round() / levels as f32 }
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
        assert!(err.contains("silhouette_support") && err.contains("0..=16"), "{err}");
        assert!(Style { ambient: f32::NAN, ..Style::default() }.validate().is_err());
        let err = Style { sky_zenith: [0.2, 1.5, 0.2], ..Style::default() }.validate().unwrap_err().to_string();
        assert!(err.contains("sky_zenith") && err.contains("1.5"), "{err}");
        assert!(Style { toon_levels: 1, ..Style::default() }.validate().is_err());
        assert!(serde_json::from_str::<Style>(r#"{"hatch_spacng": 3}"#).is_err());
        assert!(serde_json::from_str::<Style>(r#"{"hatch_space": "diagonal"}"#).is_err());
    }

    #[test]
    fn schema_lists_every_field_with_its_default_and_range() {
        let schema = Style::schema();
        // Through JSON text, where `f32` numbers have their short form as in the schema.
        let text = serde_json::to_string(&Style::default()).unwrap();
        let json: serde_json::Map<String, Value> = serde_json::from_str(&text).unwrap();
        assert_eq!(schema.len(), json.len());
        for field in &schema {
            assert_eq!(json[field.name], field.default, "{}", field.name);
            assert!(!field.doc.is_empty() && !field.doc.contains("  "), "{}", field.name);
        }
        let photo = schema.iter().find(|f| f.name == "photorealism").unwrap();
        assert_eq!((photo.kind, photo.min, photo.max), ("number", Some(0.0), Some(1.0)));
        let threshold = schema.iter().find(|f| f.name == "contour_threshold").unwrap();
        assert_eq!((threshold.default.as_f64(), threshold.max), (Some(0.2), Some(10.0)));
        let prefilter = schema.iter().find(|f| f.name == "contour_prefilter").unwrap();
        assert_eq!((prefilter.kind, prefilter.min), ("boolean", None));
        assert_eq!(schema.iter().find(|f| f.name == "ink").unwrap().kind, "color");
    }

    #[test]
    fn photorealism_moves_every_parameter_as_thesis_8_2_7_lists() {
        let sketch = Style { hlp_abstraction: 0.6, normal_blend: 0.8, gooch: 1.0, ..Style::default() };
        assert_eq!(sketch.resolved(), sketch);
        let photo = Style { photorealism: 1.0, ..sketch.clone() }.resolved();
        assert_eq!((photo.hlp_abstraction, photo.normal_blend), (0.0, 0.0));
        assert_eq!((photo.contour_threshold, photo.contour_strength, photo.silhouette_strength), (10.0, 0.0, 0.0));
        assert_eq!((photo.hatch_brightness, photo.color, photo.color_abstraction, photo.sky), (1.0, 1.0, 0.0, 1.0));
        assert_eq!((photo.gooch, photo.toon, photo.color_saturation), (0.0, 0.0, 1.0));
        // Half-way: linear interpolation, e.g. threshold 0.2 → 5.1, strength 1 → 0.5.
        let half = Style { photorealism: 0.5, ..sketch.clone() }.resolved();
        assert!((half.contour_threshold - 5.1).abs() < 1e-5 && (half.contour_strength - 0.5).abs() < 1e-6);
        assert!((half.hlp_abstraction - 0.3).abs() < 1e-6 && (half.color - 0.5).abs() < 1e-6);
        // Parameters the thesis does not list keep their values.
        assert_eq!((photo.hatch_map, photo.ambient, photo.ink), (sketch.hatch_map, sketch.ambient, sketch.ink));
    }

    #[test]
    fn photorealism_brings_back_the_original_leaves() {
        let leaves = Style {
            leaf_mode: LeafMode::Elliptical,
            leaf_size: 3.0,
            leaf_shape: 0.8,
            leaf_outline: 0.2,
            ..Style::default()
        };
        let quarter = Style { photorealism: 0.25, ..leaves.clone() }.resolved();
        assert_eq!(quarter.leaf_mode, LeafMode::Elliptical);
        assert!((quarter.leaf_size - 2.5).abs() < 1e-6 && (quarter.leaf_shape - 0.6).abs() < 1e-6);
        assert!((quarter.leaf_outline - 0.15).abs() < 1e-6);
        let half = Style { photorealism: 0.5, ..leaves.clone() }.resolved();
        assert_eq!(half.leaf_mode, LeafMode::Original);
        let photo = Style { photorealism: 1.0, ..leaves }.resolved();
        assert_eq!(
            (photo.leaf_mode, photo.leaf_size, photo.leaf_shape, photo.leaf_outline),
            (LeafMode::Original, 1.0, 0.0, 0.0)
        );
        let json: Style = serde_json::from_str(r#"{"leaf_mode": "reoriented"}"#).unwrap();
        assert!(json.leaf_mode.particles() && !Style::default().leaf_mode.particles());
        assert!(serde_json::from_str::<Style>(r#"{"leaf_mode": "round"}"#).is_err());
        assert!(Style { leaf_size: 5.0, ..Style::default() }.validate().is_err());
    }

    #[test]
    fn implicit_illumination_keeps_its_values_along_the_photorealism_axis() {
        let lit = Style { implicit_normals: 0.8, ambient_occlusion: 0.6, ..Style::default() };
        for photorealism in [0.0, 0.5, 1.0] {
            let resolved = Style { photorealism, ..lit.clone() }.resolved();
            assert_eq!((resolved.implicit_normals, resolved.ambient_occlusion), (0.8, 0.6));
        }
        assert!(Style { ambient_occlusion: 1.5, ..Style::default() }.validate().is_err());
        assert!(Style { implicit_normals: -0.1, ..Style::default() }.validate().is_err());
    }

    #[test]
    fn partial_styles_merge_and_name_the_bad_field() {
        let base = Style { color: 0.7, ..Style::default() };
        let overrides: PartialStyle = serde_json::from_str(r#"{"hatch_map": 2, "ink": [0, 0, 0.5]}"#).unwrap();
        let merged = base.with(&overrides).unwrap();
        assert_eq!((merged.color, merged.hatch_map, merged.ink), (0.7, 2, [0.0, 0.0, 0.5]));
        let err = serde_json::from_str::<PartialStyle>(r#"{"ambient": "dark"}"#).unwrap_err().to_string();
        assert!(err.starts_with("invalid style parameter `ambient`: invalid type: string"), "{err}");
        let range: PartialStyle = serde_json::from_str(r#"{"color": 3}"#).unwrap();
        assert!(matches!(base.with(&range), Err(RenderError::Style { field: "color", .. })));
    }

    #[test]
    fn layer_styles_fill_their_slots() {
        let layers = vec!["existing".to_owned(), "planned".to_owned()];
        let photo = Style { photorealism: 1.0, ..Style::default() };
        let mut frame = FrameStyle::from(Style::default());
        frame.layers.insert("existing".into(), photo.clone());
        frame.layers.insert(TERRAIN_LAYER.into(), Style { hatch_map: 1, silhouette_map: 3, ..Style::default() });
        let slots = frame.slots(&layers, None).unwrap();
        assert_eq!(slots.len(), STYLE_SLOTS);
        assert_eq!((slots[0].hatch_map, slots[1].hatch_map), (0, 1));
        assert_eq!(slots[2], photo.resolved());
        assert_eq!(slots[3], Style::default());
        let (groups, slot_groups) = art_groups(&slots);
        assert_eq!(groups, vec![1, 3]);
        assert_eq!(&slot_groups[..4], &[0, 1, 0, 0]);
        // A layer's partial style merges over the frame's style, or over a preset it names.
        let base = Style { color: 0.4, ..Style::default() };
        let partial: LayerStyle = serde_json::from_str(r#"{"hatch_map": 2}"#).unwrap();
        assert_eq!(partial.resolve(&base).unwrap().style, Style { hatch_map: 2, ..base.clone() });
        let partial: LayerStyle = serde_json::from_str(r#"{"preset": "minimalistic", "ambient": 0.2}"#).unwrap();
        let layer = partial.resolve(&base).unwrap().style;
        assert_eq!((layer.color, layer.hatch_strength, layer.ambient), (0.0, 0.0, 0.2));
        let err = serde_json::from_str::<LayerStyle>(r#"{"preset": 3}"#).unwrap_err();
        assert!(err.to_string().contains("preset"));
        frame.layers.insert("meadow".into(), Style::default());
        let err = frame.slots(&layers, None).unwrap_err().to_string();
        assert!(err.contains("meadow") && err.contains("terrain, existing, planned"), "{err}");
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
