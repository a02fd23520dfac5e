//! D3 legends, drawn on the CPU: a colour bar with tick labels for scalar fields, class
//! swatches with names for label fields, as a PNG ([`Legend::to_png`]) and as a JSON
//! description (the [`Legend`] itself serialises: colours, classes, range, units). The legend
//! of a `hatch_color` mapping is the ramp from paper to its ink
//! ([`ColorMapSpec::ink`](super::ColorMapSpec::ink)).
//!
//! Text uses the X11 `misc-fixed` 7×13 bitmap font (ISO 8859-1, public domain) shipped inside
//! the `embedded-graphics` crate, so no font file is needed. Colours are drawn at the map's
//! opacity over white paper.

use std::convert::Infallible;

use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::iso_8859_1::FONT_7X13;
use embedded_graphics::pixelcolor::{Rgb888, RgbColor};
use embedded_graphics::prelude::{DrawTarget, Drawable, OriginDimensions, Pixel, Point, Size};
use embedded_graphics::text::{Alignment, Baseline, Text, TextStyleBuilder};
use image::{ImageEncoder, RgbaImage};
use serde::Serialize;

use super::FieldError;
use super::colormap::{ColorMapName, LUT_SIZE, Lut};
use super::field::{ClassInfo, FieldKind};
use super::mapping::MappingTarget;

/// One labelled tick of a colour bar.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Tick {
    /// The value.
    pub value: f64,
    /// The value as printed.
    pub label: String,
    /// Its colour, `#rrggbb`.
    pub color: String,
}

/// One class swatch.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct LegendClass {
    /// Label index (position in the look-up table).
    pub index: usize,
    /// The class's cell value.
    pub value: i64,
    /// The text shown: the class name, or `class <value>`.
    pub name: String,
    /// Its colour, `#rrggbb`.
    pub color: String,
    /// Number of cells with this class.
    pub count: u64,
}

/// A legend: everything needed to draw it and to describe it as JSON.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Legend {
    /// Heading (usually the layer name).
    pub title: String,
    /// Scalar or label.
    pub kind: FieldKind,
    /// Units of the values, if known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<String>,
    /// The feature shown: `color` (a colour map) or `hatch_color` (the darkness of a hatching
    /// in one ink colour).
    pub target: MappingTarget,
    /// The colour map (`color`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colormap: Option<ColorMapName>,
    /// The ink colour, `#rrggbb` (`hatch_color`): the bar runs from paper to it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub color: Option<String>,
    /// Opacity of the colours over the sketch, 0…1.
    pub opacity: f32,
    /// Scalars: values at the two ends of the bar.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<[f64; 2]>,
    /// Scalars: labelled ticks along the bar.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ticks: Vec<Tick>,
    /// Scalars: the bar's colours from `range[0]` to `range[1]`, `#rrggbb`, 16 stops.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub stops: Vec<String>,
    /// Labels: one swatch per class.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub classes: Vec<LegendClass>,
    /// How nodata is shown.
    pub nodata: String,
    /// The full look-up table, for drawing the bar.
    #[serde(skip)]
    bar: Vec<[u8; 4]>,
}

/// Legend image width in pixels.
pub const LEGEND_WIDTH: u32 = 320;
/// Height of the scalar colour-bar legend in pixels.
pub const SCALAR_LEGEND_HEIGHT: u32 = 72;
/// Height of one class row in pixels.
pub const CLASS_ROW_HEIGHT: u32 = 18;

const MARGIN: i32 = 12;
const TITLE_HEIGHT: i32 = 22;
const BAR_TOP: i32 = 26;
const BAR_HEIGHT: i32 = 20;
const SWATCH: i32 = 14;

impl Legend {
    /// A legend for a field described by its kind, units and classes, coloured by `lut`
    /// (which holds the map or ink, range and opacity).
    pub fn new(title: &str, kind: FieldKind, units: Option<&str>, classes: &[ClassInfo], lut: &Lut) -> Legend {
        let hex = |c: [u8; 4]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
        let opacity = f32::from(lut.colors.iter().map(|c| c[3]).max().unwrap_or(255)) / 255.0;
        let (ticks, stops) = match (kind, lut.range) {
            (FieldKind::Scalar, Some([lo, hi])) => {
                let ticks = nice_ticks(lo, hi)
                    .into_iter()
                    .map(|(value, label)| Tick { value, label, color: hex(lut.color_of(value)) })
                    .collect();
                let stops = (0..16).map(|i| hex(lut.colors[i * (LUT_SIZE - 1) / 15])).collect();
                (ticks, stops)
            }
            _ => (Vec::new(), Vec::new()),
        };
        let classes = match kind {
            FieldKind::Label => classes
                .iter()
                .enumerate()
                .take(LUT_SIZE)
                .map(|(index, c)| LegendClass {
                    index,
                    value: c.value,
                    name: c.name.clone().unwrap_or_else(|| format!("class {}", c.value)),
                    color: hex(lut.colors[index]),
                    count: c.count,
                })
                .collect(),
            FieldKind::Scalar => Vec::new(),
        };
        Legend {
            title: title.to_string(),
            kind,
            units: units.map(str::to_string),
            target: if lut.ink.is_some() { MappingTarget::HatchColor } else { MappingTarget::Color },
            colormap: lut.map,
            color: lut.ink.map(|[r, g, b]| hex([r, g, b, 255])),
            opacity,
            range: if kind == FieldKind::Scalar { lut.range } else { None },
            ticks,
            stops: if kind == FieldKind::Scalar { stops } else { Vec::new() },
            classes,
            nodata: "transparent (the sketch shows through)".into(),
            bar: lut.colors.clone(),
        }
    }

    /// Width and height of the PNG in pixels.
    pub fn png_size(&self) -> (u32, u32) {
        match self.kind {
            FieldKind::Scalar => (LEGEND_WIDTH, SCALAR_LEGEND_HEIGHT),
            // At most LUT_SIZE classes, so the product is small.
            FieldKind::Label => (LEGEND_WIDTH, TITLE_HEIGHT as u32 + CLASS_ROW_HEIGHT * self.classes.len() as u32 + 6),
        }
    }

    /// The legend as an RGBA image on white.
    pub fn to_image(&self) -> RgbaImage {
        let (w, h) = self.png_size();
        let mut canvas = Canvas(RgbaImage::from_pixel(w, h, image::Rgba([255, 255, 255, 255])));
        let title = match &self.units {
            Some(u) => format!("{} [{u}]", self.title),
            None => self.title.clone(),
        };
        let max_chars = ((w as i32 - 2 * MARGIN) / 7).max(4) as usize;
        canvas.text(&ellipsize(&title, max_chars), MARGIN, 5, Alignment::Left);
        match self.kind {
            FieldKind::Scalar => self.draw_bar(&mut canvas),
            FieldKind::Label => self.draw_classes(&mut canvas, max_chars),
        }
        canvas.0
    }

    /// The legend as PNG bytes.
    pub fn to_png(&self) -> Result<Vec<u8>, FieldError> {
        let img = self.to_image();
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(img.as_raw(), img.width(), img.height(), image::ExtendedColorType::Rgba8)
            .map_err(|e| FieldError::Invalid(format!("cannot encode the legend PNG: {e}")))?;
        Ok(out)
    }

    fn draw_bar(&self, canvas: &mut Canvas) {
        let Some([lo, hi]) = self.range else { return };
        let x0 = MARGIN;
        let x1 = LEGEND_WIDTH as i32 - MARGIN;
        let last = self.bar.len().saturating_sub(1);
        let lut_at = |x: i32| -> [u8; 4] {
            let t = f64::from(x - x0) / f64::from(x1 - 1 - x0);
            // t in [0, 1], so the index is in range.
            self.bar.get((t * last as f64).round() as usize).copied().unwrap_or([0, 0, 0, 255])
        };
        for x in x0..x1 {
            let c = over_white(lut_at(x), self.opacity);
            for y in BAR_TOP..BAR_TOP + BAR_HEIGHT {
                canvas.put(x, y, c);
            }
        }
        canvas.frame(x0 - 1, BAR_TOP - 1, x1 - x0 + 2, BAR_HEIGHT + 2);
        for tick in &self.ticks {
            let t = (tick.value - lo) / (hi - lo);
            // t in [0, 1] for ticks inside the range, so the pixel is on the bar.
            let x = x0 + (t * f64::from(x1 - 1 - x0)).round() as i32;
            for y in BAR_TOP + BAR_HEIGHT..BAR_TOP + BAR_HEIGHT + 4 {
                canvas.put(x, y, [0, 0, 0, 255]);
            }
            canvas.text(&tick.label, x, BAR_TOP + BAR_HEIGHT + 6, Alignment::Center);
        }
    }

    fn draw_classes(&self, canvas: &mut Canvas, max_chars: usize) {
        for (i, class) in self.classes.iter().enumerate() {
            // At most LUT_SIZE rows, so the cast is exact.
            let top = TITLE_HEIGHT + i as i32 * CLASS_ROW_HEIGHT as i32;
            let c = over_white(self.bar.get(class.index).copied().unwrap_or([0, 0, 0, 255]), self.opacity);
            for y in top..top + SWATCH {
                for x in MARGIN..MARGIN + SWATCH {
                    canvas.put(x, y, c);
                }
            }
            canvas.frame(MARGIN - 1, top - 1, SWATCH + 2, SWATCH + 2);
            let text = if class.name == format!("class {}", class.value) {
                class.name.clone()
            } else {
                format!("{} ({})", class.name, class.value)
            };
            canvas.text(&ellipsize(&text, max_chars.saturating_sub(4)), MARGIN + SWATCH + 8, top + 1, Alignment::Left);
        }
    }
}

/// About four to seven round tick values (1, 2 or 5 × 10ᵏ apart) within [lo, hi] (either order),
/// always including both ends when no round value is near them, with printed labels (see
/// [`tick_label`]).
fn nice_ticks(lo: f64, hi: f64) -> Vec<(f64, String)> {
    let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
    let span = b - a;
    if !(span.is_finite() && span > 0.0) {
        let label = if scientific(a.abs()) { format!("{a:e}") } else { format_number(a, 0) };
        return vec![(a, label)];
    }
    let raw = span / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let magnitude = a.abs().max(b.abs());
    let first = (a / step).ceil() * step;
    let mut ticks = Vec::new();
    let mut v = first;
    while v <= b + step * 1e-9 && ticks.len() < 12 {
        ticks.push((v, tick_label(v, step, magnitude)));
        v += step;
    }
    ticks
}

/// Whether values of this magnitude are labelled in scientific notation: from 10⁶ up and
/// below 10⁻³.
fn scientific(magnitude: f64) -> bool {
    magnitude != 0.0 && !(1e-3..1e6).contains(&magnitude)
}

/// The decimal exponent of `v` (≠ 0), robust to values a rounding error below a power of ten.
fn exponent(v: f64) -> i32 {
    (v.abs().log10() + 1e-9).floor() as i32
}

/// The label of tick `v` on a bar with ticks `step` apart over values up to `magnitude`:
/// fixed-point with the decimals the step needs, or — for magnitudes from 10⁶ up or below
/// 10⁻³ — scientific notation with the digits the step needs (`2e299`, `1.5e6`, `3e-5`).
fn tick_label(v: f64, step: f64, magnitude: f64) -> String {
    if scientific(magnitude) {
        if v.abs() < step * 1e-6 {
            return "0".to_string();
        }
        let digits = (exponent(v) - exponent(step)).clamp(0, 15) as usize;
        format!("{v:.digits$e}")
    } else {
        // Digits after the decimal point for this step (0 for steps ≥ 1); the value is small.
        let decimals = (-step.log10().floor()).clamp(0.0, 17.0) as usize;
        format_number(v, decimals)
    }
}

/// A number with `decimals` digits, without a negative zero.
fn format_number(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// `text` cut to `max` characters with a trailing `…` when longer.
fn ellipsize(text: &str, max: usize) -> String {
    if text.chars().count() <= max {
        text.to_string()
    } else {
        let mut s: String = text.chars().take(max.saturating_sub(1)).collect();
        s.push('…');
        s
    }
}

/// A colour at `opacity` composited over white.
fn over_white(c: [u8; 4], opacity: f32) -> [u8; 4] {
    let a = opacity.clamp(0.0, 1.0);
    // Result within 0..=255.
    let mix = |v: u8| (f32::from(v) * a + 255.0 * (1.0 - a)).round() as u8;
    [mix(c[0]), mix(c[1]), mix(c[2]), 255]
}

/// An RGBA image that `embedded-graphics` can draw text on (also the comment pins' glyph
/// atlas, `render::marks`).
pub(crate) struct Canvas(pub(crate) RgbaImage);

impl Canvas {
    fn put(&mut self, x: i32, y: i32, c: [u8; 4]) {
        if let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y))
            && x < self.0.width()
            && y < self.0.height()
        {
            self.0.put_pixel(x, y, image::Rgba(c));
        }
    }

    /// A one-pixel grey outline.
    fn frame(&mut self, x: i32, y: i32, w: i32, h: i32) {
        let grey = [96, 96, 96, 255];
        for i in x..x + w {
            self.put(i, y, grey);
            self.put(i, y + h - 1, grey);
        }
        for j in y..y + h {
            self.put(x, j, grey);
            self.put(x + w - 1, j, grey);
        }
    }

    /// Black text with its top at `y`, aligned at `x`.
    fn text(&mut self, s: &str, x: i32, y: i32, alignment: Alignment) {
        let style = MonoTextStyle::new(&FONT_7X13, Rgb888::BLACK);
        let layout = TextStyleBuilder::new().alignment(alignment).baseline(Baseline::Top).build();
        // Drawing on a Canvas cannot fail (Infallible).
        let _ = Text::with_text_style(s, Point::new(x, y), style, layout).draw(self);
    }
}

impl OriginDimensions for Canvas {
    fn size(&self) -> Size {
        Size::new(self.0.width(), self.0.height())
    }
}

impl DrawTarget for Canvas {
    type Color = Rgb888;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<Rgb888>>>(&mut self, pixels: I) -> Result<(), Infallible> {
        for Pixel(p, c) in pixels {
            self.put(p.x, p.y, [c.r(), c.g(), c.b(), 255]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fields::colormap::ColorMapSpec;

    #[test]
    fn ticks_are_round() {
        let labels = |lo, hi| nice_ticks(lo, hi).into_iter().map(|t| t.1).collect::<Vec<_>>();
        assert_eq!(labels(0.0, 10.0), ["0", "2", "4", "6", "8", "10"]);
        assert_eq!(labels(-1.3, 27.9), ["0", "5", "10", "15", "20", "25"]);
        assert_eq!(labels(0.12, 0.31), ["0.15", "0.20", "0.25", "0.30"]);
        assert_eq!(labels(-0.5, 0.5), ["-0.4", "-0.2", "0.0", "0.2", "0.4"]);
        assert_eq!(labels(3.0, 3.0), ["3"]);
    }

    /// Huge and tiny values get scientific notation with the digits the step needs, never
    /// hundreds of digits.
    #[test]
    fn ticks_of_huge_and_tiny_values_are_short() {
        let labels = |lo, hi| nice_ticks(lo, hi).into_iter().map(|t| t.1).collect::<Vec<_>>();
        assert_eq!(labels(0.0, 1e300), ["0", "2e299", "4e299", "6e299", "8e299", "1.0e300"]);
        assert_eq!(labels(1e6, 1.5e6), ["1.0e6", "1.1e6", "1.2e6", "1.3e6", "1.4e6", "1.5e6"]);
        assert_eq!(labels(-3e7, 3e7), ["-3e7", "-2e7", "-1e7", "0", "1e7", "2e7", "3e7"]);
        assert_eq!(labels(0.0, 5e-5), ["0", "1e-5", "2e-5", "3e-5", "4e-5", "5e-5"]);
        assert_eq!(labels(0.0, 999_000.0), ["0", "200000", "400000", "600000", "800000"]);
        assert_eq!(labels(1e300, 1e300), ["1e300"]);
        for (lo, hi) in [(-1e308, 1e308), (1e-300, 2e-300), (0.0, f64::MAX), (12345.678, 12345.679)] {
            for label in labels(lo, hi) {
                assert!(label.len() <= 24, "{lo}…{hi}: {label}");
            }
        }
    }

    #[test]
    fn scalar_legend_draws_the_bar() {
        let lut = Lut::for_scalar(&ColorMapSpec::default(), (0.0, 10.0)).unwrap();
        let legend = Legend::new("temperature", FieldKind::Scalar, Some("°C"), &[], &lut);
        assert_eq!(legend.stops.first().map(String::as_str), Some("#440154"));
        assert_eq!(legend.stops.last().map(String::as_str), Some("#fde725"));
        let img = legend.to_image();
        assert_eq!(img.dimensions(), (LEGEND_WIDTH, SCALAR_LEGEND_HEIGHT));
        let left = img.get_pixel(MARGIN as u32, (BAR_TOP + 5) as u32).0;
        assert_eq!(left, [0x44, 0x01, 0x54, 255]);
        let right = img.get_pixel(LEGEND_WIDTH - MARGIN as u32 - 1, (BAR_TOP + 5) as u32).0;
        assert_eq!(right, [0xfd, 0xe7, 0x25, 255]);
        // Some text pixels in the title row.
        assert!((0..LEGEND_WIDTH).any(|x| img.get_pixel(x, 10).0 == [0, 0, 0, 255]));
        let json = serde_json::to_value(&legend).unwrap();
        assert_eq!(json["units"], "°C");
        assert_eq!(json["range"], serde_json::json!([0.0, 10.0]));
        assert_eq!((json["target"].as_str(), json["colormap"].as_str()), (Some("color"), Some("viridis")));
        assert!(json.get("color").is_none(), "{json}");
    }

    #[test]
    fn hatch_color_legend_ramps_from_paper_to_the_ink() {
        let spec = ColorMapSpec { ink: Some([0.0, 0.0, 1.0]), ..Default::default() };
        let lut = Lut::for_scalar(&spec, (0.0, 4.0)).unwrap();
        let legend = Legend::new("rain", FieldKind::Scalar, Some("mm"), &[], &lut);
        let img = legend.to_image();
        let y = (BAR_TOP + 5) as u32;
        assert_eq!(img.get_pixel(MARGIN as u32, y).0, [255, 255, 255, 255], "paper at the low end");
        assert_eq!(img.get_pixel(LEGEND_WIDTH - MARGIN as u32 - 1, y).0, [0, 0, 255, 255], "ink at the high end");
        let json = serde_json::to_value(&legend).unwrap();
        assert_eq!((json["target"].as_str(), json["color"].as_str()), (Some("hatch_color"), Some("#0000ff")));
        assert!(json.get("colormap").is_none(), "{json}");
        assert_eq!(json["stops"][15], "#0000ff");
    }
}
