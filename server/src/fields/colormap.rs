//! D3 colour maps: continuous maps for scalar fields (viridis, magma, inferno, plasma,
//! cividis, turbo and ColorBrewer maps such as RdYlBu, from the `colorous` crate), categorical
//! palettes for label fields, a value range, opacity and reversal — sampled into a
//! [`LUT_SIZE`]-entry RGBA look-up table for the GPU.
//!
//! Colours are 8-bit sRGB (upload the table as `Rgba8UnormSrgb` to blend in linear space, or
//! `Rgba8Unorm` to use it as is). Scalars index the table by
//! `i = round((v − lo)/(hi − lo) · 255)` clamped to 0…255; labels by their label index (class
//! position), so a label table holds the class colours at entries 0…n−1.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::FieldError;
use super::field::{ClassInfo, Field, FieldKind};

/// Entries in a look-up table.
pub const LUT_SIZE: usize = 256;

/// A named colour map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ColorMapName {
    /// Perceptually uniform, dark purple → yellow.
    Viridis,
    /// Black → purple → light yellow.
    Magma,
    /// Black → red → yellow.
    Inferno,
    /// Blue → magenta → yellow.
    Plasma,
    /// Colour-blind friendly blue → yellow.
    Cividis,
    /// Rainbow-like, high contrast.
    Turbo,
    /// Diverging red → yellow → blue.
    RdYlBu,
    /// Diverging red → white → blue.
    RdBu,
    /// Diverging red → yellow → green.
    RdYlGn,
    /// Diverging spectral.
    Spectral,
    /// Diverging brown → blue-green.
    BrBG,
    /// Sequential white → black.
    Greys,
    /// Sequential white → blue.
    Blues,
    /// Sequential white → green.
    Greens,
    /// Sequential white → red.
    Reds,
    /// Sequential yellow → orange → red.
    YlOrRd,
    /// Categorical, 10 colours (d3 category10).
    Category10,
    /// Categorical, 10 colours (Tableau 10).
    Tableau10,
    /// Categorical, 9 colours (ColorBrewer Set1).
    Set1,
    /// Categorical, 8 colours (ColorBrewer Set2).
    Set2,
    /// Categorical, 12 colours (ColorBrewer Set3).
    Set3,
    /// Categorical, 12 colours in pairs (ColorBrewer Paired).
    Paired,
    /// Categorical, 8 colours (ColorBrewer Dark2).
    Dark2,
    /// Categorical, 8 colours (ColorBrewer Accent).
    Accent,
    /// A label field's own palette (from a palette GeoTIFF); classes without a colour fall back
    /// to Tableau 10.
    File,
}

/// Every map, in documentation order.
pub const ALL_COLOR_MAPS: [ColorMapName; 25] = [
    ColorMapName::Viridis,
    ColorMapName::Magma,
    ColorMapName::Inferno,
    ColorMapName::Plasma,
    ColorMapName::Cividis,
    ColorMapName::Turbo,
    ColorMapName::RdYlBu,
    ColorMapName::RdBu,
    ColorMapName::RdYlGn,
    ColorMapName::Spectral,
    ColorMapName::BrBG,
    ColorMapName::Greys,
    ColorMapName::Blues,
    ColorMapName::Greens,
    ColorMapName::Reds,
    ColorMapName::YlOrRd,
    ColorMapName::Category10,
    ColorMapName::Tableau10,
    ColorMapName::Set1,
    ColorMapName::Set2,
    ColorMapName::Set3,
    ColorMapName::Paired,
    ColorMapName::Dark2,
    ColorMapName::Accent,
    ColorMapName::File,
];

impl ColorMapName {
    /// The name as used in JSON and query strings (lower case, e.g. `rdylbu`).
    pub fn as_str(&self) -> &'static str {
        match self {
            ColorMapName::Viridis => "viridis",
            ColorMapName::Magma => "magma",
            ColorMapName::Inferno => "inferno",
            ColorMapName::Plasma => "plasma",
            ColorMapName::Cividis => "cividis",
            ColorMapName::Turbo => "turbo",
            ColorMapName::RdYlBu => "rdylbu",
            ColorMapName::RdBu => "rdbu",
            ColorMapName::RdYlGn => "rdylgn",
            ColorMapName::Spectral => "spectral",
            ColorMapName::BrBG => "brbg",
            ColorMapName::Greys => "greys",
            ColorMapName::Blues => "blues",
            ColorMapName::Greens => "greens",
            ColorMapName::Reds => "reds",
            ColorMapName::YlOrRd => "ylorrd",
            ColorMapName::Category10 => "category10",
            ColorMapName::Tableau10 => "tableau10",
            ColorMapName::Set1 => "set1",
            ColorMapName::Set2 => "set2",
            ColorMapName::Set3 => "set3",
            ColorMapName::Paired => "paired",
            ColorMapName::Dark2 => "dark2",
            ColorMapName::Accent => "accent",
            ColorMapName::File => "file",
        }
    }

    /// Whether the map is a categorical palette (for labels) rather than a gradient.
    pub fn is_categorical(&self) -> bool {
        self.palette().is_some() || *self == ColorMapName::File
    }

    /// The default map for a kind: viridis for scalars, Tableau 10 for labels.
    pub fn default_for(kind: FieldKind) -> ColorMapName {
        match kind {
            FieldKind::Scalar => ColorMapName::Viridis,
            FieldKind::Label => ColorMapName::Tableau10,
        }
    }

    fn gradient(&self) -> Option<colorous::Gradient> {
        Some(match self {
            ColorMapName::Viridis => colorous::VIRIDIS,
            ColorMapName::Magma => colorous::MAGMA,
            ColorMapName::Inferno => colorous::INFERNO,
            ColorMapName::Plasma => colorous::PLASMA,
            ColorMapName::Cividis => colorous::CIVIDIS,
            ColorMapName::Turbo => colorous::TURBO,
            ColorMapName::RdYlBu => colorous::RED_YELLOW_BLUE,
            ColorMapName::RdBu => colorous::RED_BLUE,
            ColorMapName::RdYlGn => colorous::RED_YELLOW_GREEN,
            ColorMapName::Spectral => colorous::SPECTRAL,
            ColorMapName::BrBG => colorous::BROWN_GREEN,
            ColorMapName::Greys => colorous::GREYS,
            ColorMapName::Blues => colorous::BLUES,
            ColorMapName::Greens => colorous::GREENS,
            ColorMapName::Reds => colorous::REDS,
            ColorMapName::YlOrRd => colorous::YELLOW_ORANGE_RED,
            _ => return None,
        })
    }

    fn palette(&self) -> Option<&'static [colorous::Color]> {
        Some(match self {
            ColorMapName::Category10 => &colorous::CATEGORY10,
            ColorMapName::Tableau10 => &colorous::TABLEAU10,
            ColorMapName::Set1 => &colorous::SET1,
            ColorMapName::Set2 => &colorous::SET2,
            ColorMapName::Set3 => &colorous::SET3,
            ColorMapName::Paired => &colorous::PAIRED,
            ColorMapName::Dark2 => &colorous::DARK2,
            ColorMapName::Accent => &colorous::ACCENT,
            _ => return None,
        })
    }

    /// The colour at `t` in [0, 1] of a gradient, or of a palette spread evenly over [0, 1].
    pub fn at(&self, t: f64) -> [u8; 3] {
        let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
        match (self.gradient(), self.palette()) {
            (Some(g), _) => g.eval_continuous(t).as_array(),
            (None, Some(p)) => {
                // t in [0, 1], so the index is in range.
                let i = ((t * p.len() as f64) as usize).min(p.len() - 1);
                p[i].as_array()
            }
            (None, None) => colorous::GREYS.eval_continuous(t).as_array(),
        }
    }

    /// The colour of class number `i`: palettes cycle, gradients are sampled evenly over `n`
    /// classes.
    pub fn class_color(&self, i: usize, n: usize) -> [u8; 3] {
        match (self.palette(), self.gradient()) {
            (Some(p), _) => p[i % p.len()].as_array(),
            (None, Some(g)) => g.eval_rational(i.min(n.saturating_sub(1)), n.max(1)).as_array(),
            (None, None) => colorous::TABLEAU10[i % colorous::TABLEAU10.len()].as_array(),
        }
    }
}

impl FromStr for ColorMapName {
    type Err = FieldError;

    /// A map by name, case-insensitive, ignoring `-` and `_` (`RdYlBu`, `rd-yl-bu`).
    fn from_str(s: &str) -> Result<ColorMapName, FieldError> {
        let key: String = s.chars().filter(|c| *c != '-' && *c != '_').collect::<String>().to_ascii_lowercase();
        ALL_COLOR_MAPS.iter().copied().find(|m| m.as_str() == key).ok_or_else(|| {
            let names: Vec<&str> = ALL_COLOR_MAPS.iter().map(|m| m.as_str()).collect();
            FieldError::Invalid(format!("unknown colour map \"{s}\" (known: {})", names.join(", ")))
        })
    }
}

impl fmt::Display for ColorMapName {
    /// The lower-case name.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How a field is coloured: map, value range, opacity, direction — or, for a hatch-colour
/// mapping, a ramp from paper to its ink.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColorMapSpec {
    /// The map; `None` picks [`ColorMapName::default_for`] the field's kind.
    pub map: Option<ColorMapName>,
    /// Values mapped to the two ends of a gradient; `None`: the field's min and max.
    pub range: Option<[f64; 2]>,
    /// Opacity 0…1 of the colour over the sketch.
    pub opacity: f32,
    /// Run the map backwards.
    pub reverse: bool,
    /// Ink colour (sRGB, each 0…1) of a `hatch_color` mapping (thesis Fig. 9.3): the table
    /// ramps from paper (white) at the low end to the ink at the high end instead of following
    /// `map`.
    pub ink: Option<[f32; 3]>,
}

impl Default for ColorMapSpec {
    /// Default map for the kind, the data range, opacity 1, not reversed, no ink.
    fn default() -> ColorMapSpec {
        ColorMapSpec { map: None, range: None, opacity: 1.0, reverse: false, ink: None }
    }
}

impl ColorMapSpec {
    /// Checks opacity (0…1), range (finite, distinct ends) and ink (sRGB 0…1).
    pub fn validate(&self) -> Result<(), FieldError> {
        if !(0.0..=1.0).contains(&self.opacity) {
            return Err(FieldError::Invalid(format!("opacity {} must be within 0…1", self.opacity)));
        }
        if let Some([lo, hi]) = self.range
            && !(lo.is_finite() && hi.is_finite() && lo != hi)
        {
            return Err(FieldError::Invalid(format!("range [{lo}, {hi}] needs two different finite values")));
        }
        if let Some(ink) = self.ink {
            check_srgb(ink).map_err(|e| FieldError::Invalid(format!("ink {e}")))?;
        }
        Ok(())
    }
}

/// Checks an sRGB colour of three components within 0…1; the error reads "[r, g, b] must …".
pub fn check_srgb(rgb: [f32; 3]) -> Result<(), FieldError> {
    if rgb.iter().all(|c| (0.0..=1.0).contains(c)) {
        Ok(())
    } else {
        Err(FieldError::Invalid(format!(
            "[{}, {}, {}] must be three sRGB components within 0…1",
            rgb[0], rgb[1], rgb[2]
        )))
    }
}

/// An sRGB colour 0…1 as bytes.
fn srgb_bytes(rgb: [f32; 3]) -> [u8; 3] {
    // Clamped to 0..=255 before the cast.
    rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// A colour look-up table of [`LUT_SIZE`] RGBA entries (8-bit sRGB, alpha = opacity).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Lut {
    /// The map used; `None` for the ink ramp of a hatch colour ([`ColorMapSpec::ink`]).
    pub map: Option<ColorMapName>,
    /// The ink of an ink ramp, 8-bit sRGB.
    pub ink: Option<[u8; 3]>,
    /// Scalars: values at entries 0 and 255 (`lo` may exceed `hi` for a reversed range).
    /// Labels: `None`.
    pub range: Option<[f64; 2]>,
    /// The entries.
    pub colors: Vec<[u8; 4]>,
    /// Colour for nodata cells (fully transparent: the sketch shows through).
    pub nodata: [u8; 4],
}

/// Entry `t` (0…1 along the range or the classes) of an ink ramp: paper (white) to `ink`.
fn ink_at(ink: [u8; 3], t: f64) -> [u8; 3] {
    // A mix of two bytes stays within 0..=255.
    ink.map(|c| (255.0 + (f64::from(c) - 255.0) * t.clamp(0.0, 1.0)).round() as u8)
}

impl Lut {
    /// The table for a field: a gradient over the spec's range (default: the field's value
    /// range) for scalars, one entry per class for labels.
    pub fn for_field(spec: &ColorMapSpec, field: &Field) -> Result<Lut, FieldError> {
        match field.kind() {
            FieldKind::Scalar => Lut::for_scalar(spec, field.value_range()),
            FieldKind::Label => Lut::for_labels(spec, field.classes()),
        }
    }

    /// A scalar table from `data_range` (used when the spec has no range). A categorical map
    /// gives stepped bands; the file palette is an error for scalars. With an ink, the table
    /// ramps from paper to it.
    pub fn for_scalar(spec: &ColorMapSpec, data_range: (f64, f64)) -> Result<Lut, FieldError> {
        spec.validate()?;
        let map = spec.map.unwrap_or(ColorMapName::Viridis);
        if map == ColorMapName::File && spec.ink.is_none() {
            return Err(FieldError::Invalid("the file palette colours label fields only".into()));
        }
        let [mut lo, mut hi] = spec.range.unwrap_or([data_range.0, data_range.1]);
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(FieldError::Invalid("the field has no finite value range".into()));
        }
        if lo == hi {
            // A constant field: centre it in a unit range so it takes the middle colour.
            (lo, hi) = (lo - 0.5, hi + 0.5);
        }
        let alpha = opacity_byte(spec.opacity);
        let ink = spec.ink.map(srgb_bytes);
        let colors = (0..LUT_SIZE)
            .map(|i| {
                let t = i as f64 / (LUT_SIZE - 1) as f64;
                let t = if spec.reverse { 1.0 - t } else { t };
                let [r, g, b] = ink.map_or_else(|| map.at(t), |ink| ink_at(ink, t));
                [r, g, b, alpha]
            })
            .collect();
        let map = ink.is_none().then_some(map);
        Ok(Lut { map, ink, range: Some([lo, hi]), colors, nodata: [0; 4] })
    }

    /// A label table: entry i is the colour of class i (`classes` sorted by value, as in
    /// [`Field::classes`]); unused entries are transparent. With an ink, class i of n is
    /// i / (n − 1) of the way from paper to it.
    pub fn for_labels(spec: &ColorMapSpec, classes: &[ClassInfo]) -> Result<Lut, FieldError> {
        spec.validate()?;
        let map = spec.map.unwrap_or(ColorMapName::Tableau10);
        let alpha = opacity_byte(spec.opacity);
        let ink = spec.ink.map(srgb_bytes);
        let n = classes.len().min(LUT_SIZE);
        let mut colors = vec![[0u8; 4]; LUT_SIZE];
        for (i, class) in classes.iter().take(LUT_SIZE).enumerate() {
            let j = if spec.reverse { n - 1 - i } else { i };
            let [r, g, b] = match (ink, map, class.color) {
                (Some(ink), _, _) => ink_at(ink, j as f64 / (n.max(2) - 1) as f64),
                (None, ColorMapName::File, Some(c)) => c,
                _ => map.class_color(j, n),
            };
            colors[i] = [r, g, b, alpha];
        }
        let map = ink.is_none().then_some(map);
        Ok(Lut { map, ink, range: None, colors, nodata: [0; 4] })
    }

    /// The table index of a value: scalars by the range (clamped), labels by the value as an
    /// index. `None` for NaN.
    pub fn index_of(&self, v: f64) -> Option<usize> {
        if v.is_nan() {
            return None;
        }
        let last = (LUT_SIZE - 1) as f64;
        let i = match self.range {
            Some([lo, hi]) => ((v - lo) / (hi - lo) * last).round(),
            None => v.round(),
        };
        // Clamped to 0..=255, so the cast is exact.
        Some(i.clamp(0.0, last) as usize)
    }

    /// The colour of a value (grid value: scalar or label index); the nodata colour for NaN.
    pub fn color_of(&self, v: f64) -> [u8; 4] {
        self.index_of(v).map_or(self.nodata, |i| self.colors[i])
    }

    /// The table as `LUT_SIZE × 4` bytes (RGBA rows) for a 256 × 1 texture.
    pub fn to_rgba_bytes(&self) -> Vec<u8> {
        self.colors.iter().flatten().copied().collect()
    }
}

/// Opacity 0…1 as an alpha byte.
fn opacity_byte(opacity: f32) -> u8 {
    // Clamped to 0..=255 before the cast.
    (opacity.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_endpoints() {
        let lut = Lut::for_scalar(&ColorMapSpec::default(), (0.0, 10.0)).unwrap();
        assert_eq!(lut.colors[0], [0x44, 0x01, 0x54, 255]);
        assert_eq!(lut.colors[255], [0xfd, 0xe7, 0x25, 255]);
        assert_eq!(lut.color_of(-5.0), lut.colors[0]);
        assert_eq!(lut.color_of(10.0), lut.colors[255]);
        assert_eq!(lut.color_of(f64::NAN), [0, 0, 0, 0]);
        assert_eq!(lut.to_rgba_bytes().len(), 1024);
        let rev =
            Lut::for_scalar(&ColorMapSpec { reverse: true, opacity: 0.5, ..Default::default() }, (0.0, 1.0)).unwrap();
        assert_eq!(rev.colors[0], [0xfd, 0xe7, 0x25, 128]);
    }

    #[test]
    fn names_parse() {
        assert_eq!("RdYlBu".parse::<ColorMapName>().unwrap(), ColorMapName::RdYlBu);
        assert_eq!("rd_yl_bu".parse::<ColorMapName>().unwrap(), ColorMapName::RdYlBu);
        for m in ALL_COLOR_MAPS {
            assert_eq!(m.as_str().parse::<ColorMapName>().unwrap(), m);
            assert_eq!(serde_json::to_string(&m).unwrap(), format!("\"{m}\""));
        }
        assert!("jet".parse::<ColorMapName>().unwrap_err().to_string().contains("viridis"));
    }

    #[test]
    fn label_tables() {
        let class = |value, color| ClassInfo { value, count: 1, name: None, color };
        let classes = [class(1, Some([1, 2, 3])), class(5, None)];
        let file =
            Lut::for_labels(&ColorMapSpec { map: Some(ColorMapName::File), ..Default::default() }, &classes).unwrap();
        assert_eq!(file.colors[0], [1, 2, 3, 255]);
        assert_eq!(file.colors[1][..3], colorous::TABLEAU10[1].as_array());
        assert_eq!(file.color_of(1.0), file.colors[1]);
        assert_eq!(file.colors[2], [0; 4]);
        assert!(
            Lut::for_scalar(&ColorMapSpec { map: Some(ColorMapName::File), ..Default::default() }, (0.0, 1.0)).is_err()
        );
        assert!(ColorMapSpec { opacity: 1.5, ..Default::default() }.validate().is_err());
        assert!(ColorMapSpec { range: Some([1.0, 1.0]), ..Default::default() }.validate().is_err());
    }

    #[test]
    fn ink_ramps_run_from_paper_to_the_ink() {
        let ink = ColorMapSpec { ink: Some([1.0, 0.0, 0.0]), ..Default::default() };
        let lut = Lut::for_scalar(&ink, (0.0, 10.0)).unwrap();
        assert_eq!((lut.map, lut.ink), (None, Some([255, 0, 0])));
        assert_eq!((lut.colors[0], lut.colors[255]), ([255, 255, 255, 255], [255, 0, 0, 255]));
        assert_eq!(lut.color_of(5.0), [255, 127, 127, 255]);
        let reversed = Lut::for_scalar(&ColorMapSpec { reverse: true, ..ink.clone() }, (0.0, 10.0)).unwrap();
        assert_eq!(reversed.colors[0], [255, 0, 0, 255]);
        let class = |value| ClassInfo { value, count: 1, name: None, color: None };
        let labels = Lut::for_labels(&ink, &[class(1), class(2), class(3)]).unwrap();
        assert_eq!(labels.colors[..3], [[255, 255, 255, 255], [255, 128, 128, 255], [255, 0, 0, 255]]);
        let bad = ColorMapSpec { ink: Some([0.0, 1.5, 0.0]), ..Default::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("within 0…1"));
    }
}
