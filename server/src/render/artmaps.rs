//! Stroke textures for hatching and stylised silhouettes, generated on the CPU: tonal art maps
//! (TAM, thesis 6.1, after Praun et al. 2001 "Real-time hatching") and silhouette art maps
//! (SAM, thesis 5.2.3).
//!
//! Every stroke is drawn by a small rasterizer of its own: a stroke is a polyline whose
//! radius is given per point (tapered ends), and a pixel's ink coverage is
//! `clamp(r + ½ − d, 0, 1)` for its centre's distance `d` to the centre line (an analytic
//! box-filter approximation, so edges are anti-aliased and caps are round). Overlapping
//! strokes combine by their maximum, so crossings never exceed full ink, and the result does
//! not depend on drawing order. Strokes that cross a tile edge wrap around it, so the textures
//! tile seamlessly (TAMs in both directions, SAMs along u).
//!
//! **TAM conventions.** 8-bit grey, 255 = paper, 0 = ink. Tone level 0 is the lightest; the
//! mean darkness of level `i` of `n` aims at [`tone_target`]`(i, n)`, linearly spaced from 0.1
//! to 0.9. Each level has a full mip chain down to 1×1. Mips down to [`MIN_STROKE_MIP_SIZE`]
//! are drawn at their own resolution, so a stroke is as many pixels wide in every mip (only
//! its length and position scale); the tiny mips below that are box-filtered from the smallest
//! drawn one (there the texture is a flat tone anyway). Strokes are placed by Praun's
//! incremental scheme: tone by tone from light to dark and, within a tone, mip by mip from
//! coarse to fine, the best of a few random candidate strokes (the one whose neighbourhood
//! holds the least ink, which spreads strokes evenly) is added until the mip's mean darkness
//! reaches the tone's target; every stroke added to a mip is also added to all finer mips of
//! its tone and to the same and finer mips of every darker tone. This gives the nesting
//! property exactly: a darker tone is pixelwise at least as dark as a lighter one, and every
//! stroke of a coarser mip is present in all finer mips. Targets are met to within a few
//! thousandths at mip 0 and within a few hundredths (one stroke's worth) at 8×8. Strokes keep
//! their width within a tone; the strokes that darker levels add are a little bolder (up to
//! 1.4× for hatching and scribbles, 1.6× for stipple dots, like halftone dots), which keeps
//! dark tones reading as strokes rather than grey noise. Hatch strokes run along u (x); the
//! renderer orients them by rotating texture coordinates.
//!
//! **SAM conventions.** Each of the four RGBA channels holds one stroke style as ink coverage,
//! 0 = no ink, 255 = full ink (note: the opposite of TAMs). u runs along the contour (x, tiles
//! horizontally), v across it: row 0 lies on the contour and v grows inwards up to the support
//! width (the image height). Strokes touch row 0 and never wrap vertically. Channels go from
//! light/thin (R) to dark/heavy (A), so shading can pick one; as in the thesis there is no
//! nesting between channels and no mip chain.

use crate::rng::SplitMix64 as Rng;
use glam::Vec2;
use image::{GrayImage, Luma, Rgba, RgbaImage};
use serde::{Deserialize, Serialize};
use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

/// The smallest mip of a generated TAM whose strokes are drawn; smaller mips are box-filtered.
pub const MIN_STROKE_MIP_SIZE: u32 = 8;
/// The smallest TAM tone image side (generated or loaded).
pub const MIN_TAM_SIZE: u32 = 16;
/// The smallest side of a loaded SAM in pixels.
pub const MIN_SAM_SIZE: u32 = 8;
/// The largest side of an art map PNG in pixels (a TAM strip holds every tone level side by
/// side), checked from the PNG header before decoding.
pub const MAX_ART_MAP_SIDE: u32 = 16384;

/// Candidate strokes tried per placed TAM stroke (the least crowded one wins).
const CANDIDATES: usize = 8;
/// Safety limit on strokes placed into one TAM image.
const MAX_STROKES_PER_IMAGE: usize = 200_000;
/// Candidates in a row that may add no ink before a TAM image is given up as full.
const MAX_MISSES: usize = 64;

/// Errors raised while loading art maps.
#[derive(Debug, thiserror::Error)]
pub enum ArtMapError {
    /// The file could not be read.
    #[error("cannot read art map {}: {source}", path.display())]
    Io {
        /// The art map file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with the PNG signature.
    #[error("art map {} is not a PNG file", path.display())]
    NotPng {
        /// The art map file.
        path: PathBuf,
    },
    /// The file looks like a PNG but cannot be decoded.
    #[error("cannot decode art map {}: {source}", path.display())]
    Decode {
        /// The art map file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: image::ImageError,
    },
    /// The image's size does not fit the art map layout.
    #[error("art map {} is {width}×{height} pixels, expected {expected}", path.display())]
    Shape {
        /// The art map file.
        path: PathBuf,
        /// Its width in pixels.
        width: u32,
        /// Its height in pixels.
        height: u32,
        /// The expected layout, in words.
        expected: String,
    },
}

/// Tonal art map: `levels[tone][mip]` grey images (255 = paper, 0 = ink), tone 0 lightest,
/// mip 0 = `size`×`size` down to 1×1, with the nesting property across tones and mips (see
/// the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Tam {
    /// Side of mip 0 in pixels (a power of two ≥ [`MIN_TAM_SIZE`]).
    pub size: u32,
    /// `levels[tone][mip]`: tone 0 is the lightest; mip `m` is `size >> m` pixels square.
    pub levels: Vec<Vec<GrayImage>>,
}

/// Stroke style of a generated TAM. All strokes run along u (x) unless stated otherwise;
/// the renderer rotates the texture coordinates to orient them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TamStyle {
    /// Parallel hatch strokes of one direction.
    Lines,
    /// Hatch strokes along u; from the middle level on (index ≥ levels / 2), most new strokes
    /// run along v.
    CrossHatch,
    /// Short looping curves of any direction, like scribbled foliage.
    Scribble,
    /// Dots, like halftone stippling (for a pointillist style).
    Stipple,
}

impl TamStyle {
    /// All styles, in declaration order.
    pub const ALL: [TamStyle; 4] = [TamStyle::Lines, TamStyle::CrossHatch, TamStyle::Scribble, TamStyle::Stipple];
}

/// Target mean darkness (0 = paper, 1 = ink) of tone level `level` of `levels`: linearly spaced
/// from 0.1 (level 0) to 0.9 (the last level); 0.5 for a single level.
pub fn tone_target(level: usize, levels: usize) -> f32 {
    if levels <= 1 { 0.5 } else { 0.1 + 0.8 * level as f32 / (levels - 1) as f32 }
}

/// Generates a tonal art map of `levels` tones whose mip 0 is `size`×`size`, deterministically
/// from `seed` (see the module documentation for the construction).
///
/// # Panics
///
/// If `size` is not a power of two ≥ [`MIN_TAM_SIZE`] or `levels` < 2.
pub fn generate_tam(style: TamStyle, size: u32, levels: usize, seed: u64) -> Tam {
    assert!(size.is_power_of_two() && size >= MIN_TAM_SIZE, "TAM size {size} must be a power of two ≥ {MIN_TAM_SIZE}");
    assert!(levels >= 2, "a TAM needs at least 2 tone levels, got {levels}");
    let drawn = (size / MIN_STROKE_MIP_SIZE).ilog2() as usize + 1;
    let mut canvases: Vec<Vec<Canvas>> =
        (0..levels).map(|_| (0..drawn).map(|m| Canvas::new(size >> m, size >> m)).collect()).collect();
    let mut rng = Rng::new(seed ^ (style as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    for tone in 0..levels {
        for mip in (0..drawn).rev() {
            fill_tam_image(&mut canvases, style, tone, mip, size, &mut rng);
        }
    }
    let levels = canvases
        .iter()
        .map(|mips| {
            let mut chain: Vec<GrayImage> = mips.iter().map(Canvas::to_paper_gray).collect();
            complete_mip_chain(&mut chain);
            chain
        })
        .collect();
    Tam { size, levels }
}

/// Adds strokes to TAM image (`tone`, `mip`) until its mean darkness reaches the tone's target,
/// copying each stroke to the finer mips and darker tones.
fn fill_tam_image(canvases: &mut [Vec<Canvas>], style: TamStyle, tone: usize, mip: usize, size: u32, rng: &mut Rng) {
    let levels = canvases.len();
    let target = f64::from(tone_target(tone, levels));
    let side = size >> mip;
    let scale = side as f32;
    let area = f64::from(side * side);
    let mut misses = 0;
    for _ in 0..MAX_STROKES_PER_IMAGE {
        let canvas = &canvases[tone][mip];
        let deficit = target - canvas.mean();
        if deficit <= 0.0 {
            break;
        }
        // Cross-hatching: from the middle tone on, most new strokes run along v.
        let across = style == TamStyle::CrossHatch && 2 * tone >= levels && rng.chance(0.6);
        let mut best: Option<(f64, Stroke)> = None;
        for _ in 0..CANDIDATES {
            let stroke = tam_stroke(style, tone as f32 / (levels - 1) as f32, across, rng);
            let halo = halo_px(style, &stroke, target as f32).min(scale / 4.0);
            let crowding = canvas.crowding(&rasterize(&stroke, scale, side, side, true, halo));
            if best.as_ref().is_none_or(|(b, _)| crowding < *b) {
                best = Some((crowding, stroke));
            }
        }
        let Some((_, stroke)) = best else { break };
        let footprint = rasterize(&stroke, scale, side, side, true, 0.0);
        let gain = canvas.gain(&footprint) / area;
        if gain <= 1e-9 {
            misses += 1;
            if misses > MAX_MISSES {
                break;
            }
            continue;
        }
        misses = 0;
        if gain - deficit > deficit {
            // This stroke would overshoot the target by more than the current shortfall.
            break;
        }
        for finer in 0..=mip {
            let finer_side = size >> finer;
            let fp = if finer == mip {
                footprint.clone()
            } else {
                rasterize(&stroke, finer_side as f32, finer_side, finer_side, true, 0.0)
            };
            for darker in canvases[tone..].iter_mut() {
                darker[finer].apply(&fp);
            }
        }
    }
}

/// How far around a candidate stroke (in pixels) its crowding is measured: about half the
/// free space between strokes at the target darkness.
fn halo_px(style: TamStyle, stroke: &Stroke, target: f32) -> f32 {
    let radius = stroke.radii.iter().sum::<f32>() / stroke.radii.len() as f32;
    let spacing = match style {
        // Dots of area πr² covering `target` of the paper lie about sqrt(πr²/target) apart.
        TamStyle::Stipple => (PI * radius * radius / target).sqrt(),
        // Parallel strokes of width w covering `target` lie about w/target apart.
        _ => 2.0 * radius / target,
    };
    ((spacing - 2.0 * radius) / 2.0).clamp(0.5, 8.0)
}

/// A random candidate stroke of `style` in texture units (radii in pixels) for tone `darkness`
/// (0 = lightest level, 1 = darkest); `across` turns a hatch stroke to run along v.
fn tam_stroke(style: TamStyle, darkness: f32, across: bool, rng: &mut Rng) -> Stroke {
    // Darker levels add bolder strokes (stipple dots grow like halftone dots).
    let bolder = 1.0 + if style == TamStyle::Stipple { 0.6 } else { 0.4 } * darkness;
    let centre = Vec2::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0));
    match style {
        TamStyle::Lines | TamStyle::CrossHatch => {
            let base = if across { PI / 2.0 } else { 0.0 };
            let angle = base + rng.range(-0.06, 0.06);
            let length = rng.range(0.12, 0.24);
            let dir = Vec2::from_angle(angle);
            let bow = length * rng.range(-0.025, 0.025);
            let radius = rng.range(0.7, 0.95) * bolder;
            let n = 9;
            let mut stroke = Stroke::default();
            for i in 0..n {
                let s = i as f32 / (n - 1) as f32;
                let p = centre + dir * (s - 0.5) * length + dir.perp() * bow * 4.0 * s * (1.0 - s);
                // A pen stroke: a firm start, thinning towards a flicked end.
                stroke.push(p, radius * (1.0 - 0.45 * s * s) * (0.8 + 0.2 * (PI * s).sin()));
            }
            stroke
        }
        TamStyle::Scribble => {
            // A prolate trochoid: a pen running along `heading` while circling, which draws a
            // row of small loops, the way leaves are scribbled.
            let loops = rng.range(1.5, 3.0);
            let loop_radius = rng.range(0.012, 0.017);
            let advance = loop_radius * rng.range(0.35, 0.7);
            let heading = rng.range(0.0, TAU);
            let (dir, phase) = (Vec2::from_angle(heading), rng.range(0.0, TAU));
            let squash = rng.range(0.6, 1.0);
            let radius = rng.range(0.6, 0.8) * bolder;
            let n = (loops * 14.0) as usize;
            let mut stroke = Stroke::default();
            for i in 0..=n {
                let s = i as f32 / n as f32;
                let a = TAU * loops * s + phase;
                let along = advance * TAU * loops * (s - 0.5) + loop_radius * a.sin();
                let side = squash * loop_radius * a.cos();
                stroke.push(centre + dir * along + dir.perp() * side, radius * (0.7 + 0.3 * (PI * s).sin()));
            }
            stroke
        }
        TamStyle::Stipple => {
            let mut stroke = Stroke::default();
            stroke.push(centre, rng.range(0.75, 1.15) * bolder);
            stroke
        }
    }
}

/// Appends box-filtered mips to `chain` until its last image is 1×1.
fn complete_mip_chain(chain: &mut Vec<GrayImage>) {
    while let Some(last) = chain.last().filter(|img| img.width() > 1) {
        let next = box_downsample(last);
        chain.push(next);
    }
}

/// Halves a square grey image by averaging 2×2 blocks (rounded).
fn box_downsample(img: &GrayImage) -> GrayImage {
    let side = img.width() / 2;
    GrayImage::from_fn(side, side, |x, y| {
        let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
            .iter()
            .map(|&(dx, dy)| u32::from(img.get_pixel(2 * x + dx, 2 * y + dy)[0]))
            .sum();
        Luma([((sum + 2) / 4) as u8])
    })
}

impl Tam {
    /// Loads a TAM from a PNG strip of `levels` square tone images side by side (width =
    /// `levels` × height, height a power of two ≥ [`MIN_TAM_SIZE`]), lightest first, as
    /// written by [`Tam::to_png_strip`]; colour images are converted to grey. The mip chains
    /// are built by box-filter downsampling, so unlike generated TAMs the strokes of a loaded
    /// TAM do not keep their pixel width in the smaller mips.
    pub fn from_png(path: &Path, levels: usize) -> Result<Tam, ArtMapError> {
        Tam::from_png_bytes(&read_file(path)?, levels, path)
    }

    /// [`Tam::from_png`] from PNG bytes in memory (an upload); `name` stands for the file in
    /// errors.
    pub fn from_png_bytes(bytes: &[u8], levels: usize, name: &Path) -> Result<Tam, ArtMapError> {
        // The shape is checked on the header, before the strip is decoded.
        let (width, height) = png_dimensions(bytes, name)?;
        let shape_ok = levels >= 1
            && height.is_power_of_two()
            && height >= MIN_TAM_SIZE
            && u64::from(width) == levels as u64 * u64::from(height);
        if !shape_ok {
            return Err(ArtMapError::Shape {
                path: name.to_path_buf(),
                width,
                height,
                expected: format!(
                    "a strip of {levels} square tone images side by side (width = {levels} × height, height a power of two ≥ {MIN_TAM_SIZE}, at least 1 level)"
                ),
            });
        }
        let strip = decode_png(bytes, name)?.to_luma8();
        let levels = (0..levels as u32)
            .map(|level| {
                let mut chain = vec![image::imageops::crop_imm(&strip, level * height, 0, height, height).to_image()];
                complete_mip_chain(&mut chain);
                chain
            })
            .collect();
        Ok(Tam { size: height, levels })
    }

    /// Mip 0 of every tone side by side, lightest first: the strip [`Tam::from_png`] reads.
    pub fn to_png_strip(&self) -> GrayImage {
        let mut strip = GrayImage::new(self.size * self.levels.len() as u32, self.size);
        for (i, mips) in self.levels.iter().enumerate() {
            image::imageops::replace(&mut strip, &mips[0], i64::from(self.size) * i as i64, 0);
        }
        strip
    }

    /// Mean darkness of tone `level`, mip `mip`: 0 = paper, 1 = all ink.
    ///
    /// # Panics
    ///
    /// If `level` or `mip` is out of range.
    pub fn mean_tone(&self, level: usize, mip: usize) -> f32 {
        let img = &self.levels[level][mip];
        let ink: u64 = img.as_raw().iter().map(|&v| u64::from(255 - v)).sum();
        (ink as f64 / (255.0 * img.as_raw().len() as f64)) as f32
    }

    /// How much the strokes of the middle tone share one direction: the coherence
    /// (λ₁ − λ₂) / (λ₁ + λ₂) of the structure tensor of its finest image (Σ of ∇I ∇Iᵀ over the
    /// tile, wrapping at its edges), 1 for parallel lines, near 0 for dots or scribbles of every
    /// direction. It decides whether the terrain sizes the map's strokes by the ground's
    /// footprint across them (`shaders/gbuffer.wgsl` `terrain_hatch`).
    pub fn direction_coherence(&self) -> f32 {
        let img = &self.levels[self.levels.len() / 2][0];
        let (w, h) = img.dimensions();
        let at = |x: u32, y: u32| f64::from(img.get_pixel(x % w, y % h)[0]);
        let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
        for y in 0..h {
            for x in 0..w {
                let gx = at(x + 1, y) - at(x, y);
                let gy = at(x, y + 1) - at(x, y);
                (xx, xy, yy) = (xx + gx * gx, xy + gx * gy, yy + gy * gy);
            }
        }
        let trace = xx + yy;
        if trace <= 0.0 {
            return 0.0;
        }
        (((xx - yy).powi(2) + 4.0 * xy * xy).sqrt() / trace) as f32
    }

    /// Whether the map's strokes run in one direction ([`Tam::direction_coherence`] above a
    /// half): lines and cross-hatching are, stipples and scribbles are not.
    pub fn directional(&self) -> bool {
        self.direction_coherence() > 0.5
    }
}

/// Silhouette art map: four silhouette stroke styles in the RGBA channels of one image, each
/// channel an ink coverage (0 = none, 255 = full); x = u along the contour (tiles), y = v
/// across it (row 0 on the contour, growing inwards). See the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct Sam {
    /// The four stroke styles, light/thin in R to dark/heavy in A.
    pub image: RgbaImage,
}

impl Sam {
    /// Loads a SAM from any PNG; its channels are taken as they are after conversion to RGBA8
    /// (so a grey PNG gives three equal channels and an opaque, i.e. fully inked, alpha).
    pub fn from_png(path: &Path) -> Result<Sam, ArtMapError> {
        Sam::from_png_bytes(&read_file(path)?, path)
    }

    /// [`Sam::from_png`] from PNG bytes in memory (an upload); `name` stands for the file in
    /// errors. The image must be at least [`MIN_SAM_SIZE`] pixels on each side.
    pub fn from_png_bytes(bytes: &[u8], name: &Path) -> Result<Sam, ArtMapError> {
        let (width, height) = png_dimensions(bytes, name)?;
        if width < MIN_SAM_SIZE || height < MIN_SAM_SIZE {
            return Err(ArtMapError::Shape {
                path: name.to_path_buf(),
                width,
                height,
                expected: format!("at least {MIN_SAM_SIZE}×{MIN_SAM_SIZE} (u along the contour × support)"),
            });
        }
        Ok(Sam { image: decode_png(bytes, name)?.to_rgba8() })
    }
}

/// Generates the default silhouette art maps, `width` × `height` (support width) pixels each,
/// deterministically from `seed`; each has four variants from light (R) to heavy (A):
///
/// 0. plain lines of growing width;
/// 1. scallops with curled ends, the "cloud" outline of leafy crowns, of growing size;
/// 2. short tapered spikes across the contour (grass, needles), growing longer and denser;
/// 3. sketchy lines of overlapping wobbly segments, one to three lines, growing heavier.
///
/// Feature sizes are given for a 32-pixel support and scale with `height`.
///
/// # Panics
///
/// If `width` < 8 or `height` < 8.
pub fn generate_sams(width: u32, height: u32, seed: u64) -> Vec<Sam> {
    assert!(width >= 8 && height >= 8, "SAM size {width}×{height} must be at least 8×8");
    let k = height as f32 / 32.0;
    let mut rng = Rng::new(seed ^ 0x5A3C_0FFE_E5A3_C0FF);
    let generators: [SamStrokes; 4] = [sam_plain_lines, sam_scallops, sam_spikes, sam_sketchy_lines];
    generators
        .iter()
        .map(|make| {
            let channels: Vec<Canvas> = (0..4)
                .map(|c| {
                    let mut canvas = Canvas::new(width, height);
                    for stroke in make(c, width as f32, k, &mut rng) {
                        canvas.apply(&rasterize(&stroke.clamp_v(height as f32), 1.0, width, height, false, 0.0));
                    }
                    canvas
                })
                .collect();
            let image = RgbaImage::from_fn(width, height, |x, y| {
                let i = (y * width + x) as usize;
                Rgba(std::array::from_fn(|c| (channels[c].cov[i] * 255.0).round() as u8))
            });
            Sam { image }
        })
        .collect()
}

/// Strokes of one SAM channel: `(channel, width, scale k, rng)`, in pixels.
type SamStrokes = fn(usize, f32, f32, &mut Rng) -> Vec<Stroke>;

/// SAM 0, channel `c`: one continuous line along the contour, 1 to 5.5 px wide, whose width
/// and distance from the contour undulate gently.
fn sam_plain_lines(c: usize, width: f32, k: f32, rng: &mut Rng) -> Vec<Stroke> {
    let radius = [0.5, 1.0, 1.75, 2.75][c] * k;
    let thickness = Periodic::new(width, 40.0, 120.0, rng);
    let offset = Periodic::new(width, 30.0, 90.0, rng);
    let n = (width / 2.0).ceil() as usize;
    let mut stroke = Stroke::default();
    for i in 0..=n {
        let x = width * i as f32 / n as f32;
        let r = radius * (1.0 + 0.18 * thickness.at(x));
        stroke.push(Vec2::new(x, r + 0.3 * k * (1.0 + offset.at(x))), r);
    }
    vec![stroke]
}

/// SAM 1, channel `c`: scallops bulging out to the contour, meeting in cusps inside, with
/// ends curling past each other like a quickly drawn cloud outline.
fn sam_scallops(c: usize, width: f32, k: f32, rng: &mut Rng) -> Vec<Stroke> {
    let bump = [3.0, 5.5, 8.5, 13.0][c] * k;
    let radius = [0.55, 0.7, 0.9, 1.2][c] * k;
    let count = (width / (2.2 * bump)).round().max(1.0) as usize;
    let weights: Vec<f32> = (0..count).map(|_| rng.range(0.75, 1.25)).collect();
    let total: f32 = weights.iter().sum();
    let mut x = rng.range(0.0, width);
    let mut strokes = Vec::with_capacity(count);
    for w in weights {
        let half = 0.5 * width * w / total;
        let depth = bump * rng.range(0.8, 1.1) * w / total * count as f32;
        let cx = x + half;
        let cy = radius + rng.range(0.0, 0.4) * k + depth;
        let curl = rng.range(0.2, 0.45);
        let n = 24;
        let mut stroke = Stroke::default();
        for i in 0..=n {
            let s = i as f32 / n as f32;
            let phi = -curl + (PI + 2.0 * curl) * s;
            let p = Vec2::new(cx - 1.08 * half * phi.cos(), cy - depth * phi.sin());
            stroke.push(p, radius * (0.6 + 0.4 * (PI * s).sin()));
        }
        strokes.push(stroke);
        x += 2.0 * half;
    }
    strokes
}

/// SAM 2, channel `c`: short tapered strokes from the contour inwards, leaning a little, from
/// sparse short ones (R) to long dense ones (A).
fn sam_spikes(c: usize, width: f32, k: f32, rng: &mut Rng) -> Vec<Stroke> {
    let length = [6.0, 10.0, 15.0, 22.0][c] * k;
    let spacing = [5.0, 4.0, 3.5, 3.0][c] * k;
    let radius = [0.55, 0.7, 0.85, 1.05][c] * k;
    let lean = rng.range(-0.2, 0.2);
    let count = (width / spacing).round().max(1.0) as usize;
    (0..count)
        .map(|i| {
            let x = (i as f32 + rng.range(-0.35, 0.35)) * width / count as f32;
            let angle = lean + rng.range(-0.3, 0.3);
            let bend = rng.range(-0.25, 0.25);
            let len = length * rng.range(0.6, 1.15);
            let n = 6;
            let mut stroke = Stroke::default();
            let mut p = Vec2::new(x, radius);
            for j in 0..=n {
                let s = j as f32 / n as f32;
                stroke.push(p, radius * (1.0 - 0.7 * s) + 0.15 * s);
                let a = angle + bend * s;
                p += Vec2::new(a.sin(), a.cos()) * len / n as f32;
            }
            stroke
        })
        .collect()
}

/// SAM 3, channel `c`: one to three sketchy lines along the contour, each a chain of wobbly
/// segments overlapping at slightly different heights.
fn sam_sketchy_lines(c: usize, width: f32, k: f32, rng: &mut Rng) -> Vec<Stroke> {
    let lines = [1, 2, 2, 3][c];
    let radius = [0.5, 0.6, 0.85, 1.1][c] * k;
    let gap = [0.0, 2.2, 2.6, 2.4][c] * k;
    let mut strokes = Vec::new();
    for line in 0..lines {
        let wobble = Periodic::new(width, 25.0, 80.0, rng);
        let base = radius + gap * line as f32;
        let start = rng.range(0.0, width);
        let mut x = start;
        while x < start + width {
            let len = width * rng.range(0.2, 0.4);
            let tilt = rng.range(-1.2, 1.2) * k;
            let n = (len / 2.0).ceil() as usize;
            let mut stroke = Stroke::default();
            for i in 0..=n {
                let s = i as f32 / n as f32;
                let px = x + len * s;
                let v = base + k * (1.0 + wobble.at(px)) + tilt * (s - 0.5);
                stroke.push(Vec2::new(px, v.max(radius)), radius * (0.6 + 0.4 * (PI * s).sin()));
            }
            strokes.push(stroke);
            x += len - rng.range(3.0, 8.0) * k;
        }
    }
    strokes
}

/// Reads an art map file.
fn read_file(path: &Path) -> Result<Vec<u8>, ArtMapError> {
    std::fs::read(path).map_err(|source| ArtMapError::Io { path: path.to_path_buf(), source })
}

/// A PNG reader for `bytes` after checking the signature, limited to [`MAX_ART_MAP_SIDE`]
/// per side; `path` names the file in errors.
fn png_reader<'a>(bytes: &'a [u8], path: &Path) -> Result<image::ImageReader<std::io::Cursor<&'a [u8]>>, ArtMapError> {
    const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
    if !bytes.starts_with(SIGNATURE) {
        return Err(ArtMapError::NotPng { path: path.to_path_buf() });
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_ART_MAP_SIDE);
    limits.max_image_height = Some(MAX_ART_MAP_SIDE);
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Png);
    reader.limits(limits);
    Ok(reader)
}

/// The width and height a PNG's header announces, read before any pixel is decoded, so that
/// a shape that cannot fit is refused without allocating the image.
fn png_dimensions(bytes: &[u8], path: &Path) -> Result<(u32, u32), ArtMapError> {
    png_reader(bytes, path)?
        .into_dimensions()
        .map_err(|source| ArtMapError::Decode { path: path.to_path_buf(), source })
}

/// Decodes PNG bytes, checking the signature first and the size in the header before any
/// pixel is allocated (at most [`MAX_ART_MAP_SIDE`] per side); `path` names the file in errors.
fn decode_png(bytes: &[u8], path: &Path) -> Result<image::DynamicImage, ArtMapError> {
    png_reader(bytes, path)?.decode().map_err(|source| ArtMapError::Decode { path: path.to_path_buf(), source })
}

/// A stroke: a polyline with a radius per point, in texture units (TAM) or pixels (SAM).
#[derive(Debug, Clone, Default)]
struct Stroke {
    points: Vec<Vec2>,
    radii: Vec<f32>,
}

impl Stroke {
    fn push(&mut self, point: Vec2, radius: f32) {
        self.points.push(point);
        self.radii.push(radius);
    }

    /// Keeps every point's disc inside the rows `0..height` (SAMs do not wrap across v).
    fn clamp_v(mut self, height: f32) -> Stroke {
        for (p, r) in self.points.iter_mut().zip(&self.radii) {
            p.y = p.y.clamp(*r, (height - r).max(*r));
        }
        self
    }
}

/// Ink coverage of `stroke` drawn at `scale` pixels per stroke unit, widened by `grow` pixels,
/// on a `width` × `height` grid that wraps horizontally (and vertically if `wrap_v`; otherwise
/// rows outside are dropped): `(pixel index, coverage)` pairs, each pixel once.
fn rasterize(stroke: &Stroke, scale: f32, width: u32, height: u32, wrap_v: bool, grow: f32) -> Vec<(u32, f32)> {
    let points: Vec<Vec2> = stroke.points.iter().map(|p| *p * scale).collect();
    let reach = stroke.radii.iter().fold(0.0f32, |a, &r| a.max(r)) + grow + 1.0;
    let lo = points.iter().fold(Vec2::INFINITY, |a, &p| a.min(p)) - Vec2::splat(reach);
    let hi = points.iter().fold(Vec2::NEG_INFINITY, |a, &p| a.max(p)) + Vec2::splat(reach);
    let (x0, x1) = (lo.x.floor() as i64, hi.x.ceil() as i64);
    let (mut y0, mut y1) = (lo.y.floor() as i64, hi.y.ceil() as i64);
    if !wrap_v {
        (y0, y1) = (y0.max(0), y1.min(i64::from(height)));
    }
    if x1 <= x0 || y1 <= y0 {
        return Vec::new();
    }
    let bw = (x1 - x0) as usize;
    let mut local = vec![0.0f32; bw * (y1 - y0) as usize];
    let segments = points.len().saturating_sub(1).max(1);
    for i in 0..segments {
        let j = (i + 1).min(points.len() - 1);
        let (a, b) = (points[i], points[j]);
        let (ra, rb) = (stroke.radii[i] + grow, stroke.radii[j] + grow);
        let r = ra.max(rb) + 1.0;
        let (smin, smax) = (a.min(b) - Vec2::splat(r), a.max(b) + Vec2::splat(r));
        let ab = b - a;
        let len2 = ab.length_squared();
        for py in (smin.y.floor() as i64).max(y0)..(smax.y.ceil() as i64).min(y1) {
            for px in (smin.x.floor() as i64).max(x0)..(smax.x.ceil() as i64).min(x1) {
                let p = Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
                let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
                let d = (p - (a + ab * t)).length();
                let coverage = (ra + (rb - ra) * t + 0.5 - d).clamp(0.0, 1.0);
                let cell = &mut local[(py - y0) as usize * bw + (px - x0) as usize];
                *cell = cell.max(coverage);
            }
        }
    }
    let (w, h) = (i64::from(width), i64::from(height));
    let mut out: Vec<(u32, f32)> = local
        .iter()
        .enumerate()
        .filter(|(_, c)| **c > 0.0)
        .map(|(i, &c)| {
            let x = (x0 + (i % bw) as i64).rem_euclid(w);
            let y = (y0 + (i / bw) as i64).rem_euclid(h);
            ((y * w + x) as u32, c)
        })
        .collect();
    if (x1 - x0) > w || (y1 - y0) > h {
        // The stroke's box is wider than the grid: merge the pixels that wrapped onto each other.
        out.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
        out.dedup_by_key(|e| e.0);
    }
    out
}

/// An ink coverage image (0 = paper, 1 = ink) with its running sum.
struct Canvas {
    width: u32,
    height: u32,
    cov: Vec<f32>,
    sum: f64,
}

impl Canvas {
    fn new(width: u32, height: u32) -> Canvas {
        Canvas { width, height, cov: vec![0.0; (width * height) as usize], sum: 0.0 }
    }

    /// Mean coverage.
    fn mean(&self) -> f64 {
        self.sum / self.cov.len() as f64
    }

    /// How much ink (in pixels) `footprint` would add.
    fn gain(&self, footprint: &[(u32, f32)]) -> f64 {
        footprint.iter().map(|&(i, c)| f64::from((c - self.cov[i as usize]).max(0.0))).sum()
    }

    /// Draws `footprint` with max-compositing.
    fn apply(&mut self, footprint: &[(u32, f32)]) {
        for &(i, c) in footprint {
            let cell = &mut self.cov[i as usize];
            if c > *cell {
                self.sum += f64::from(c - *cell);
                *cell = c;
            }
        }
    }

    /// Mean existing coverage under `footprint`, weighted by its coverage.
    fn crowding(&self, footprint: &[(u32, f32)]) -> f64 {
        let (mut ink, mut weight) = (0.0f64, 0.0f64);
        for &(i, c) in footprint {
            ink += f64::from(self.cov[i as usize] * c);
            weight += f64::from(c);
        }
        if weight > 0.0 { ink / weight } else { 1.0 }
    }

    /// As a grey image, 255 = paper, 0 = ink.
    fn to_paper_gray(&self) -> GrayImage {
        let pixels = self.cov.iter().map(|&c| 255 - (c * 255.0).round() as u8).collect();
        GrayImage::from_raw(self.width, self.height, pixels).expect("canvas buffer matches its size")
    }
}

/// A smooth periodic function of x with period `period`, values in [−1, 1].
struct Periodic {
    terms: [(f32, f32, f32); 3],
}

impl Periodic {
    /// Three sine terms whose wavelengths lie roughly between `shortest` and `longest` but divide
    /// `period` exactly.
    fn new(period: f32, shortest: f32, longest: f32, rng: &mut Rng) -> Periodic {
        let terms = std::array::from_fn(|_| {
            let cycles = (period / rng.range(shortest, longest)).round().max(1.0);
            (TAU * cycles / period, rng.range(0.3, 1.0), rng.range(0.0, TAU))
        });
        Periodic { terms }
    }

    fn at(&self, x: f32) -> f32 {
        let total: f32 = self.terms.iter().map(|t| t.1).sum();
        self.terms.iter().map(|&(f, a, p)| a * (f * x + p).sin()).sum::<f32>() / total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A two-segment stroke in pixel units, offset by `dx` pixels along x.
    fn stroke(dx: f32, dy: f32) -> Stroke {
        let mut s = Stroke::default();
        for (x, y, r) in [(27.25, 5.5, 1.0), (31.75, 6.25, 1.25), (36.5, 7.0, 0.75)] {
            s.push(Vec2::new(x + dx, y + dy), r);
        }
        s
    }

    fn dense(fp: &[(u32, f32)], len: usize) -> Vec<f32> {
        let mut out = vec![0.0; len];
        for &(i, c) in fp {
            assert_eq!(out[i as usize], 0.0, "pixel {i} listed twice");
            out[i as usize] = c;
        }
        out
    }

    #[test]
    fn strokes_wrap_around_tile_edges_exactly() {
        let (w, h) = (32u32, 16u32);
        let across = dense(&rasterize(&stroke(0.0, 0.0), 1.0, w, h, true, 0.0), (w * h) as usize);
        let inside = dense(&rasterize(&stroke(-16.0, 0.0), 1.0, w, h, true, 0.0), (w * h) as usize);
        // Shifting a stroke by half the tile must only roll its pixels.
        for y in 0..h {
            for x in 0..w {
                let (a, b) = (across[(y * w + x) as usize], inside[(y * w + (x + 16) % w) as usize]);
                assert!((a - b).abs() < 1e-5, "pixel ({x},{y}): {a} vs {b} rolled");
            }
        }
        assert!((0..h).any(|y| across[(y * w) as usize] > 0.5), "ink wraps into column 0");
        assert!((0..h).any(|y| across[(y * w + w - 1) as usize] > 0.5), "ink reaches column 31");
        // Across v too, unless wrapping is off (SAMs): then rows past the edge are dropped.
        let low = dense(&rasterize(&stroke(-16.0, 9.5), 1.0, w, h, true, 0.0), (w * h) as usize);
        assert!(low[..w as usize].iter().any(|&c| c > 0.0), "ink wraps into row 0");
        let clipped = dense(&rasterize(&stroke(-16.0, 9.5), 1.0, w, h, false, 0.0), (w * h) as usize);
        assert!(clipped[..(3 * w) as usize].iter().all(|&c| c == 0.0), "no ink wraps into the top rows");
    }

    #[test]
    fn strokes_wider_than_the_tile_list_each_pixel_once() {
        // A 9 px long stroke widened to 6.5 px on a 4×4 tile: its box wraps over itself.
        let fp = rasterize(&stroke(0.0, 0.0), 1.0, 4, 4, true, 2.0);
        let covered = dense(&fp, 16);
        assert!(covered.iter().all(|&c| c == 1.0), "the whole tile lies under the stroke: {covered:?}");
    }

    #[test]
    fn coverage_is_anti_aliased_and_capped() {
        let mut dot = Stroke::default();
        dot.push(Vec2::new(4.0, 4.0), 1.0);
        let cov = dense(&rasterize(&dot, 1.0, 8, 8, true, 0.0), 64);
        // Centres at distance √0.5 from the dot's centre: r + ½ − d = 0.79.
        assert!((cov[3 * 8 + 3] - (1.5 - 0.5f32.sqrt())).abs() < 1e-6);
        assert!(cov.iter().all(|&c| (0.0..=1.0).contains(&c)));
        let mut canvas = Canvas::new(8, 8);
        let fp = rasterize(&dot, 1.0, 8, 8, true, 0.0);
        canvas.apply(&fp);
        let once = canvas.sum;
        canvas.apply(&fp);
        assert_eq!(canvas.sum, once, "max-compositing: drawing a stroke twice adds no ink");
        assert_eq!(canvas.gain(&fp), 0.0);
    }
}
