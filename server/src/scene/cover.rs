//! The ground's drape (SPEC S1, issue 18): a land-cover raster and/or an RGB orthophoto laid on
//! the terrain as one grid in scene metres. Every cell holds a colour (the class's, or the
//! orthophoto's) and a land-cover class; each class says how its ground is drawn — colour,
//! tone offset, stroke direction and tonal art map, outline — the way a panorama painter gives
//! forest, field, meadow and water their own textures (Bratkova et al. 2009). Tables for the
//! common classifications (NLCD, CORINE, ESA WorldCover) give sensible defaults that the scene
//! file's `[terrain.cover.<code>]` entries override.

use super::SceneError;
use crate::gis::{LocalFrame, Raster};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

/// Longest side of the drape grid in cells (a texture side every GPU accepts).
pub const MAX_DRAPE_SIDE: usize = 4096;
/// Most land-cover classes of one scene (the class index is a byte; 0 is "no class").
pub const MAX_CLASSES: usize = 255;

/// How the ground of a land-cover class is hatched in the sketch styles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CoverStrokes {
    /// The style's terrain strokes (`terrain_stroke_direction`).
    Style,
    /// Along the level lines.
    Contour,
    /// Down the slope (hachures).
    FallLine,
    /// Parallel lines at the class's `angle`, whatever the slope: furrows of a field.
    Furrows,
    /// Lines across the view, level on screen: ripples on water.
    Ripples,
    /// No strokes: the class stays paper (built-up ground, snow).
    None,
}

impl CoverStrokes {
    /// The code the shaders read (`COVER_*` in `shaders/cover_common.wgsl`; contour and fall
    /// line share the codes of [`crate::render::style::TerrainStrokes`]).
    pub fn code(self) -> u32 {
        match self {
            CoverStrokes::Style => 0,
            CoverStrokes::Contour => 1,
            CoverStrokes::FallLine => 2,
            CoverStrokes::Furrows => 3,
            CoverStrokes::Ripples => 4,
            CoverStrokes::None => 5,
        }
    }
}

/// A classification with a table of default classes (`[terrain] classes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CoverTable {
    /// US National Land Cover Database codes (11 water … 95 emergent wetlands).
    Nlcd,
    /// NLCD reclassified into 8 classes (1 water, 2 developed, 3 barren, 4 forest, 5
    /// shrubland, 6 herbaceous, 7 cultivated, 8 wetlands), as in the sample scene.
    NlcdSimplified,
    /// CORINE Land Cover, the three-digit CLC codes (111 continuous urban fabric … 523 sea).
    Corine,
    /// ESA WorldCover (10 tree cover … 100 moss and lichen).
    Worldcover,
}

/// `[terrain.cover.<code>]`: how one land-cover class is drawn; every field is optional and
/// falls back on the `classes` table's entry for the code (or plain ground).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoverClassConfig {
    /// What the class is called (legends, logs).
    pub name: Option<String>,
    /// Colour of the class in the colour styles, sRGB 0..1.
    pub color: Option<[f32; 3]>,
    /// Added to the hatch tone, −1 (black) to 1 (paper): negative values hatch flat lit ground.
    pub tone: Option<f32>,
    /// How its ground is hatched.
    pub strokes: Option<CoverStrokes>,
    /// `furrows`: direction of the lines, degrees clockwise from north.
    pub angle: Option<f32>,
    /// Tonal art map of its strokes (an index as a style's `hatch_map`); the style's when absent.
    pub hatch_map: Option<u32>,
    /// Whether its borders with other classes get an outline (where the style draws them).
    pub outline: Option<bool>,
}

/// A land-cover class as the renderer draws it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoverClass {
    /// The class's code in the land-cover raster.
    pub code: i64,
    pub name: String,
    /// sRGB 0..1.
    pub color: [f32; 3],
    /// Offset of the hatch tone (−1..1).
    pub tone: f32,
    pub strokes: CoverStrokes,
    /// `furrows`: degrees clockwise from north.
    pub angle: f32,
    /// Tonal art map index, or the style's.
    pub hatch_map: Option<u32>,
    pub outline: bool,
}

impl CoverClass {
    /// Its colour as 8-bit sRGB (the drape's, the legend's).
    pub fn rgb8(&self) -> [u8; 3] {
        self.color.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
    }
}

/// The kinds of ground the default tables are made of.
#[derive(Debug, Clone, Copy)]
enum Kind {
    Water,
    Ice,
    Built,
    UrbanGreen,
    Barren,
    Broadleaf,
    Conifer,
    MixedForest,
    Shrub,
    Grass,
    Pasture,
    Crops,
    Orchard,
    Wetland,
}

impl Kind {
    /// The class of this kind: a natural colour (not the legend's), a tone offset so flat lit
    /// ground of the kind still carries its texture, its strokes and art map (0 lines, 1
    /// cross-hatching, 2 scribbles, 3 stipples).
    fn class(self, code: i64, name: &str) -> CoverClass {
        use CoverStrokes as S;
        let (color, tone, strokes, hatch_map, outline) = match self {
            Kind::Water => (0x7d9fbf, -0.12, S::Ripples, Some(0), true),
            Kind::Ice => (0xf0f3f5, 0.0, S::None, None, true),
            Kind::Built => (0xbcb4aa, 0.0, S::None, None, true),
            Kind::UrbanGreen => (0xa9bb78, 0.0, S::Style, None, true),
            Kind::Barren => (0xcdbd9f, 0.0, S::Style, Some(3), false),
            Kind::Broadleaf => (0x58763f, -0.25, S::Style, None, true),
            Kind::Conifer => (0x3f5d3c, -0.28, S::Style, None, true),
            Kind::MixedForest => (0x4d6a3d, -0.26, S::Style, None, true),
            Kind::Shrub => (0x939056, -0.12, S::Style, Some(3), true),
            Kind::Grass => (0xb3b86f, -0.03, S::Style, None, true),
            Kind::Pasture => (0xa3bd6c, -0.03, S::Style, None, true),
            Kind::Crops => (0xd4c47c, -0.12, S::Furrows, Some(0), true),
            Kind::Orchard => (0x8fa65e, -0.1, S::Furrows, Some(3), true),
            Kind::Wetland => (0x7f9f88, -0.1, S::Ripples, Some(3), true),
        };
        let srgb = |shift: u32| f32::from(((color >> shift) & 0xff) as u8) / 255.0;
        CoverClass {
            code,
            name: name.to_owned(),
            color: [srgb(16), srgb(8), srgb(0)],
            tone,
            strokes,
            angle: 30.0,
            hatch_map,
            outline,
        }
    }
}

const NLCD: &[(i64, &str, Kind)] = &[
    (11, "open water", Kind::Water),
    (12, "perennial ice and snow", Kind::Ice),
    (21, "developed, open space", Kind::UrbanGreen),
    (22, "developed, low intensity", Kind::Built),
    (23, "developed, medium intensity", Kind::Built),
    (24, "developed, high intensity", Kind::Built),
    (31, "barren land", Kind::Barren),
    (41, "deciduous forest", Kind::Broadleaf),
    (42, "evergreen forest", Kind::Conifer),
    (43, "mixed forest", Kind::MixedForest),
    (51, "dwarf scrub", Kind::Shrub),
    (52, "shrub and scrub", Kind::Shrub),
    (71, "grassland and herbaceous", Kind::Grass),
    (72, "sedge and herbaceous", Kind::Grass),
    (73, "lichens", Kind::Barren),
    (74, "moss", Kind::Grass),
    (81, "pasture and hay", Kind::Pasture),
    (82, "cultivated crops", Kind::Crops),
    (90, "woody wetlands", Kind::Wetland),
    (95, "emergent herbaceous wetlands", Kind::Wetland),
];

const NLCD_SIMPLIFIED: &[(i64, &str, Kind)] = &[
    (1, "water", Kind::Water),
    (2, "developed", Kind::Built),
    (3, "barren", Kind::Barren),
    (4, "forest", Kind::Conifer),
    (5, "shrubland", Kind::Shrub),
    (6, "herbaceous", Kind::Grass),
    (7, "cultivated", Kind::Crops),
    (8, "wetlands", Kind::Wetland),
];

const CORINE: &[(i64, &str, Kind)] = &[
    (111, "continuous urban fabric", Kind::Built),
    (112, "discontinuous urban fabric", Kind::Built),
    (121, "industrial or commercial units", Kind::Built),
    (122, "road and rail networks", Kind::Built),
    (123, "port areas", Kind::Built),
    (124, "airports", Kind::Built),
    (131, "mineral extraction sites", Kind::Barren),
    (132, "dump sites", Kind::Barren),
    (133, "construction sites", Kind::Built),
    (141, "green urban areas", Kind::UrbanGreen),
    (142, "sport and leisure facilities", Kind::UrbanGreen),
    (211, "non-irrigated arable land", Kind::Crops),
    (212, "permanently irrigated land", Kind::Crops),
    (213, "rice fields", Kind::Crops),
    (221, "vineyards", Kind::Orchard),
    (222, "fruit trees and berry plantations", Kind::Orchard),
    (223, "olive groves", Kind::Orchard),
    (231, "pastures", Kind::Pasture),
    (241, "annual crops with permanent crops", Kind::Crops),
    (242, "complex cultivation patterns", Kind::Crops),
    (243, "agriculture with natural vegetation", Kind::Pasture),
    (244, "agro-forestry areas", Kind::Orchard),
    (311, "broad-leaved forest", Kind::Broadleaf),
    (312, "coniferous forest", Kind::Conifer),
    (313, "mixed forest", Kind::MixedForest),
    (321, "natural grasslands", Kind::Grass),
    (322, "moors and heathland", Kind::Shrub),
    (323, "sclerophyllous vegetation", Kind::Shrub),
    (324, "transitional woodland-shrub", Kind::Shrub),
    (331, "beaches, dunes, sands", Kind::Barren),
    (332, "bare rocks", Kind::Barren),
    (333, "sparsely vegetated areas", Kind::Barren),
    (334, "burnt areas", Kind::Barren),
    (335, "glaciers and perpetual snow", Kind::Ice),
    (411, "inland marshes", Kind::Wetland),
    (412, "peat bogs", Kind::Wetland),
    (421, "salt marshes", Kind::Wetland),
    (422, "salines", Kind::Barren),
    (423, "intertidal flats", Kind::Wetland),
    (511, "water courses", Kind::Water),
    (512, "water bodies", Kind::Water),
    (521, "coastal lagoons", Kind::Water),
    (522, "estuaries", Kind::Water),
    (523, "sea and ocean", Kind::Water),
];

const WORLDCOVER: &[(i64, &str, Kind)] = &[
    (10, "tree cover", Kind::MixedForest),
    (20, "shrubland", Kind::Shrub),
    (30, "grassland", Kind::Grass),
    (40, "cropland", Kind::Crops),
    (50, "built-up", Kind::Built),
    (60, "bare or sparse vegetation", Kind::Barren),
    (70, "snow and ice", Kind::Ice),
    (80, "permanent water bodies", Kind::Water),
    (90, "herbaceous wetland", Kind::Wetland),
    (95, "mangroves", Kind::Wetland),
    (100, "moss and lichen", Kind::Grass),
];

impl CoverTable {
    /// The table's classes by code.
    pub fn classes(self) -> Vec<CoverClass> {
        let rows = match self {
            CoverTable::Nlcd => NLCD,
            CoverTable::NlcdSimplified => NLCD_SIMPLIFIED,
            CoverTable::Corine => CORINE,
            CoverTable::Worldcover => WORLDCOVER,
        };
        rows.iter().map(|(code, name, kind)| kind.class(*code, name)).collect()
    }
}

/// The classes of a scene: the table's (if any) with the scene file's entries over them. Codes
/// are the keys of `[terrain.cover]`; a key that is no integer, a tone or colour out of range
/// or a class without a name nor a table entry is an error naming the key.
pub fn resolve_classes(
    table: Option<CoverTable>,
    entries: &BTreeMap<String, CoverClassConfig>,
) -> Result<(Vec<CoverClass>, BTreeSet<i64>), SceneError> {
    let mut classes: BTreeMap<i64, CoverClass> =
        table.map(CoverTable::classes).unwrap_or_default().into_iter().map(|c| (c.code, c)).collect();
    let mut declared = BTreeSet::new();
    for (key, entry) in entries {
        let invalid = |what: String| SceneError::Invalid(format!("terrain.cover.{key}: {what}"));
        let code: i64 = key.trim().parse().map_err(|_| invalid("the key must be the class's integer code".into()))?;
        declared.insert(code);
        let mut class = classes.remove(&code).unwrap_or_else(|| CoverClass {
            code,
            name: format!("class {code}"),
            color: [0.8, 0.78, 0.72],
            tone: 0.0,
            strokes: CoverStrokes::Style,
            angle: 30.0,
            hatch_map: None,
            outline: true,
        });
        if let Some(name) = &entry.name {
            class.name = name.clone();
        }
        if let Some(color) = entry.color {
            if !color.iter().all(|c| (0.0..=1.0).contains(c)) {
                return Err(invalid(format!("color {color:?} must be sRGB values within 0..1")));
            }
            class.color = color;
        }
        if let Some(tone) = entry.tone {
            if !(-1.0..=1.0).contains(&tone) {
                return Err(invalid(format!("tone {tone} must be within -1..1")));
            }
            class.tone = tone;
        }
        if let Some(angle) = entry.angle {
            if !angle.is_finite() {
                return Err(invalid("angle must be a number of degrees".into()));
            }
            class.angle = angle;
        }
        if let Some(map) = entry.hatch_map {
            if map > 255 {
                return Err(invalid(format!("hatch_map {map} must be a tonal art map index within 0..=255")));
            }
            class.hatch_map = Some(map);
        }
        class.strokes = entry.strokes.unwrap_or(class.strokes);
        class.outline = entry.outline.unwrap_or(class.outline);
        classes.insert(code, class);
    }
    if classes.len() > MAX_CLASSES {
        return Err(SceneError::Invalid(format!(
            "terrain.cover: {} land-cover classes, more than the {MAX_CLASSES} a scene can draw",
            classes.len()
        )));
    }
    Ok((classes.into_values().collect(), declared))
}

/// The drape of the terrain: a north-up grid over the terrain in scene metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Drape {
    /// Scene x of the grid's west edge and y of its north edge, metres.
    pub origin: [f64; 2],
    /// Side of a cell in metres.
    pub cell: f64,
    pub width: usize,
    pub height: usize,
    /// Per cell, row-major from the north-west: index into `classes` plus one (0: no class,
    /// plain ground).
    pub class_of: Vec<u8>,
    /// Per cell: sRGB colour.
    pub colors: Vec<[u8; 3]>,
    /// The classes the grid indexes (those of the scene's table and file).
    pub classes: Vec<CoverClass>,
}

/// The files a drape is made of, already in the scene CRS.
pub struct DrapeSources<'a> {
    /// The land cover (class codes) and its file.
    pub landcover: Option<(&'a Raster, &'a Path)>,
    /// The orthophoto's red, green and blue bands (0..255) and its file.
    pub orthophoto: Option<(&'a [Raster], &'a Path)>,
    /// The classes of [`resolve_classes`] and the codes the scene file declared itself.
    pub classes: (Vec<CoverClass>, BTreeSet<i64>),
}

impl Drape {
    /// One cell of the linear albedo `albedo` over `bounds`: the ground of a scene without a
    /// land cover or orthophoto.
    pub fn plain(albedo: [f32; 3], bounds: ([f64; 2], [f64; 2])) -> Drape {
        let (lo, hi) = bounds;
        Drape {
            origin: [lo[0], hi[1]],
            cell: (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0),
            width: 1,
            height: 1,
            class_of: vec![0],
            colors: vec![albedo.map(crate::srgb::from_linear)],
            classes: Vec::new(),
        }
    }

    /// The drape of `sources` over the terrain's `bounds` (scene metres) in `frame`: cells as
    /// fine as the finer source (at most [`MAX_DRAPE_SIDE`] along a side), each cell's class
    /// the land cover's code at its centre (nearest cell) and its colour the orthophoto's
    /// (bilinear) or the class's, else `albedo` (linear RGB). Errors name the file: a source
    /// that does not overlap the terrain, a class the scene file declares that the land cover
    /// does not hold.
    pub fn build(
        sources: DrapeSources<'_>,
        frame: &LocalFrame,
        bounds: ([f64; 2], [f64; 2]),
        albedo: [f32; 3],
    ) -> Result<Drape, SceneError> {
        let (lo, hi) = bounds;
        let (sx, sy) = frame.scale();
        let cell_of = |r: &Raster| (r.transform.cell_width * sx).min(r.transform.cell_height * sy);
        let mut cell = f64::INFINITY;
        if let Some((lc, _)) = sources.landcover {
            cell = cell.min(cell_of(lc));
        }
        if let Some((bands, _)) = sources.orthophoto {
            cell = cell.min(bands.first().map_or(f64::INFINITY, cell_of));
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0);
        let cell = cell.max(extent / MAX_DRAPE_SIDE as f64);
        if !cell.is_finite() {
            return Ok(Drape::plain(albedo, bounds));
        }
        let width = (((hi[0] - lo[0]) / cell).ceil() as usize).clamp(1, MAX_DRAPE_SIDE);
        let height = (((hi[1] - lo[1]) / cell).ceil() as usize).clamp(1, MAX_DRAPE_SIDE);
        let (classes, declared) = sources.classes;
        let index: HashMap<i64, u8> = classes.iter().enumerate().map(|(i, c)| (c.code, (i + 1) as u8)).collect();
        let plain = albedo.map(crate::srgb::from_linear);
        let mut class_of = vec![0u8; width * height];
        let mut colors = vec![plain; width * height];
        let mut seen = BTreeSet::new();
        let mut covered = (0usize, 0usize);
        for row in 0..height {
            for col in 0..width {
                let (x, y) = (lo[0] + (col as f64 + 0.5) * cell, hi[1] - (row as f64 + 0.5) * cell);
                let (cx, cy) = frame.to_crs(x, y);
                let at = row * width + col;
                if let Some((lc, _)) = sources.landcover
                    && let Some(v) = lc.sample_nearest(cx, cy)
                {
                    covered.0 += 1;
                    let code = v.round() as i64;
                    seen.insert(code);
                    if let Some(&i) = index.get(&code) {
                        class_of[at] = i;
                        colors[at] = classes[usize::from(i) - 1].rgb8();
                    }
                }
                if let Some((bands, _)) = sources.orthophoto {
                    let rgb: Option<Vec<f64>> = bands.iter().take(3).map(|b| b.sample_bilinear(cx, cy)).collect();
                    if let Some(rgb) = rgb {
                        covered.1 += 1;
                        colors[at] = [0, 1, 2].map(|i| rgb[i].clamp(0.0, 255.0).round() as u8);
                    }
                }
            }
        }
        let no_overlap = |path: &Path, what: &str| {
            SceneError::Invalid(format!(
                "{}: the {what} does not overlap the terrain (the DEM covers scene x {:.0}..{:.0} m, y {:.0}..{:.0} m)",
                path.display(),
                lo[0],
                hi[0],
                lo[1],
                hi[1]
            ))
        };
        if let Some((_, path)) = sources.landcover {
            if covered.0 == 0 {
                return Err(no_overlap(path, "land cover"));
            }
            let missing: Vec<String> = declared.difference(&seen).map(i64::to_string).collect();
            if !missing.is_empty() {
                return Err(SceneError::Invalid(format!(
                    "{}: terrain.cover declares class {} that the land cover does not hold (its classes are {})",
                    path.display(),
                    missing.join(", "),
                    seen.iter().map(i64::to_string).collect::<Vec<_>>().join(", ")
                )));
            }
        }
        if let Some((_, path)) = sources.orthophoto
            && covered.1 == 0
        {
            return Err(no_overlap(path, "orthophoto"));
        }
        Ok(Drape { origin: [lo[0], hi[1]], cell, width, height, class_of, colors, classes })
    }

    /// Texture coordinates (0..1 over the grid, v growing southwards) of scene point `(x, y)`.
    pub fn uv(&self, x: f64, y: f64) -> [f32; 2] {
        let u = (x - self.origin[0]) / (self.cell * self.width as f64);
        let v = (self.origin[1] - y) / (self.cell * self.height as f64);
        [u as f32, v as f32]
    }

    /// The classes some cell of the drape holds, in table order (the ground's legend).
    pub fn present_classes(&self) -> Vec<&CoverClass> {
        let mut present = vec![false; self.classes.len()];
        for &i in &self.class_of {
            if i > 0 {
                present[usize::from(i) - 1] = true;
            }
        }
        self.classes.iter().zip(present).filter(|(_, p)| *p).map(|(c, _)| c).collect()
    }

    /// The class at scene point `(x, y)`, if the drape has one there.
    pub fn class_at(&self, x: f64, y: f64) -> Option<&CoverClass> {
        let col = ((x - self.origin[0]) / self.cell).floor();
        let row = ((self.origin[1] - y) / self.cell).floor();
        if col < 0.0 || row < 0.0 || col >= self.width as f64 || row >= self.height as f64 {
            return None;
        }
        let i = self.class_of[row as usize * self.width + col as usize];
        (i > 0).then(|| &self.classes[usize::from(i) - 1])
    }

    /// The drape as an RGBA mip chain for the GPU: rgb the sRGB colour, alpha the class index.
    /// Each coarser level averages the colours of its 2 × 2 children and keeps the class that
    /// most of them hold (a mode filter: classes never blend into a third one), so a far view
    /// reads the dominant class instead of flickering between small patches.
    pub fn mip_chain(&self) -> Vec<image::RgbaImage> {
        let mut level = image::RgbaImage::from_fn(self.width as u32, self.height as u32, |x, y| {
            let i = y as usize * self.width + x as usize;
            let [r, g, b] = self.colors[i];
            image::Rgba([r, g, b, self.class_of[i]])
        });
        let mut chain = Vec::new();
        loop {
            let (w, h) = level.dimensions();
            chain.push(level.clone());
            if w == 1 && h == 1 {
                return chain;
            }
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            level = image::RgbaImage::from_fn(nw, nh, |x, y| {
                let children: Vec<image::Rgba<u8>> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|(dx, dy)| *chain[chain.len() - 1].get_pixel((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1)))
                    .collect();
                let mean = |c: usize| (children.iter().map(|p| u32::from(p[c])).sum::<u32>() / 4) as u8;
                let count = |class: u8| children.iter().filter(|p| p[3] == class).count();
                let class = children.iter().map(|p| p[3]).max_by_key(|&c| (count(c), c > 0)).unwrap_or(0);
                image::Rgba([mean(0), mean(1), mean(2), class])
            });
        }
    }

    /// The mean colour of the drape, linear RGB (the terrain's abstract colour, thesis 6.2).
    pub fn mean_linear(&self) -> [f32; 3] {
        let n = self.colors.len().max(1) as f32;
        [0, 1, 2].map(|i| self.colors.iter().map(|c| crate::srgb::to_linear(c[i])).sum::<f32>() / n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::{Crs, GeoTransform};

    fn raster(width: usize, height: usize, cell: f64, data: Vec<f64>) -> Raster {
        Raster {
            width,
            height,
            data,
            nodata: Some(0.0),
            transform: GeoTransform {
                origin_x: 0.0,
                origin_y: cell * height as f64,
                cell_width: cell,
                cell_height: cell,
            },
            crs: Crs::from_epsg(32613).expect("UTM 13N"),
            palette: None,
        }
    }

    fn frame() -> LocalFrame {
        LocalFrame::new(Crs::from_epsg(32613).expect("UTM 13N"), 0.0, 0.0).expect("frame")
    }

    #[test]
    fn tables_override_by_scene_entries_and_unknown_keys_are_named() {
        let mut entries = BTreeMap::new();
        entries.insert("42".to_owned(), CoverClassConfig { tone: Some(-0.2), ..Default::default() });
        entries.insert("7".to_owned(), CoverClassConfig { name: Some("vineyard".into()), ..Default::default() });
        let (classes, declared) = resolve_classes(Some(CoverTable::Nlcd), &entries).expect("classes");
        let evergreen = classes.iter().find(|c| c.code == 42).expect("42");
        assert_eq!((evergreen.name.as_str(), evergreen.tone), ("evergreen forest", -0.2));
        assert_eq!(classes.iter().find(|c| c.code == 7).map(|c| c.name.as_str()), Some("vineyard"));
        assert_eq!(declared, BTreeSet::from([7, 42]));
        entries.insert("forest".to_owned(), CoverClassConfig::default());
        let err = resolve_classes(None, &entries).expect_err("a key that is no code");
        assert!(err.to_string().contains("terrain.cover.forest"), "{err}");
        let bad_tone = BTreeMap::from([("4".to_owned(), CoverClassConfig { tone: Some(3.0), ..Default::default() })]);
        assert!(resolve_classes(None, &bad_tone).expect_err("tone").to_string().contains("tone 3"));
    }

    #[test]
    fn every_default_table_has_distinct_codes_and_water_ripples() {
        for table in [CoverTable::Nlcd, CoverTable::NlcdSimplified, CoverTable::Corine, CoverTable::Worldcover] {
            let classes = table.classes();
            let codes: BTreeSet<i64> = classes.iter().map(|c| c.code).collect();
            assert_eq!(codes.len(), classes.len(), "{table:?}");
            assert!(classes.iter().any(|c| c.strokes == CoverStrokes::Ripples), "{table:?}");
        }
    }

    #[test]
    fn the_drape_takes_classes_at_cell_centres_and_names_files_that_do_not_overlap() {
        // Two 10 m cells: class 4 west, class 6 east, over a terrain of 20 × 10 m.
        let lc = raster(2, 1, 10.0, vec![4.0, 6.0]);
        let classes = resolve_classes(Some(CoverTable::NlcdSimplified), &BTreeMap::new()).expect("classes");
        let sources = DrapeSources { landcover: Some((&lc, Path::new("lc.tif"))), orthophoto: None, classes };
        let drape = Drape::build(sources, &frame(), ([0.0, 0.0], [20.0, 10.0]), [0.5; 3]).expect("drape");
        assert_eq!((drape.width, drape.height, drape.cell), (2, 1, 10.0));
        assert_eq!(drape.class_at(3.0, 5.0).map(|c| c.code), Some(4));
        assert_eq!(drape.class_at(13.0, 5.0).map(|c| c.code), Some(6));
        assert_eq!(drape.uv(20.0, 0.0), [1.0, 1.0]);
        let chain = drape.mip_chain();
        assert_eq!(chain.len(), 2);
        assert_eq!(chain[1].get_pixel(0, 0)[3], chain[0].get_pixel(0, 0)[3].max(chain[0].get_pixel(1, 0)[3]));

        let far = raster(2, 1, 10.0, vec![4.0, 6.0]);
        let far = Raster { transform: GeoTransform { origin_x: 5000.0, ..far.transform }, ..far };
        let classes = resolve_classes(None, &BTreeMap::new()).expect("classes");
        let sources = DrapeSources { landcover: Some((&far, Path::new("far.tif"))), orthophoto: None, classes };
        let err = Drape::build(sources, &frame(), ([0.0, 0.0], [20.0, 10.0]), [0.5; 3]).expect_err("no overlap");
        assert!(err.to_string().contains("far.tif: the land cover does not overlap"), "{err}");

        let declared = BTreeMap::from([("9".to_owned(), CoverClassConfig::default())]);
        let classes = resolve_classes(None, &declared).expect("classes");
        let sources = DrapeSources { landcover: Some((&lc, Path::new("lc.tif"))), orthophoto: None, classes };
        let err = Drape::build(sources, &frame(), ([0.0, 0.0], [20.0, 10.0]), [0.5; 3]).expect_err("unknown class");
        assert!(err.to_string().contains("lc.tif: terrain.cover declares class 9"), "{err}");
        assert!(err.to_string().contains("its classes are 4, 6"), "{err}");
    }

    #[test]
    fn coarser_levels_keep_the_majority_class() {
        let lc = raster(2, 2, 10.0, vec![4.0, 4.0, 4.0, 6.0]);
        let classes = resolve_classes(Some(CoverTable::NlcdSimplified), &BTreeMap::new()).expect("classes");
        let sources = DrapeSources { landcover: Some((&lc, Path::new("lc.tif"))), orthophoto: None, classes };
        let drape = Drape::build(sources, &frame(), ([0.0, 0.0], [20.0, 20.0]), [0.5; 3]).expect("drape");
        let forest = drape.class_at(1.0, 19.0).map(|c| c.code);
        assert_eq!(forest, Some(4));
        let chain = drape.mip_chain();
        assert_eq!(chain[1].get_pixel(0, 0)[3], chain[0].get_pixel(0, 0)[3]);
    }
}
