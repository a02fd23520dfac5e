//! The scene file (`data/<scene>/scene.toml`, SPEC S5): its schema and validation.
//!
//! Paths inside the file are relative to the file's own directory. Unknown keys and wrong
//! types are errors that name the file, line and key.

use super::procedural::ProceduralKind;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Top level of a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// Human-readable scene name.
    pub name: String,
    pub terrain: TerrainConfig,
    #[serde(default)]
    pub sun: SunConfig,
    pub camera: CameraConfig,
    /// Plant species by name.
    #[serde(default)]
    pub species: BTreeMap<String, SpeciesConfig>,
    /// Vegetation layers, drawn in this order.
    #[serde(default)]
    pub layers: Vec<LayerConfig>,
    /// Upper bound on plants per layer; placement beyond it is an error.
    #[serde(default = "default_max_plants")]
    pub max_plants: usize,
    /// `[participation]`: comment moderation and limits (the server reads it).
    #[serde(default)]
    pub participation: super::participation::ParticipationConfig,
    /// `[[viewpoints]]`: named views for citizens and tours (the server reads them).
    #[serde(default)]
    pub viewpoints: Vec<super::participation::Viewpoint>,
    /// `[about]`: the place and the plan in plain words, for the browser's welcome.
    #[serde(default)]
    pub about: AboutConfig,
}

/// `[about]`: what the public reads first (the browser UI's welcome): the place, the plan and
/// the vegetation layer that holds the plan (shown or hidden by "with / without the plan").
#[derive(Debug, Clone, Default, Deserialize, serde::Serialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AboutConfig {
    /// Title of the welcome; the scene name when absent.
    pub title: Option<String>,
    /// What the place is, in a sentence or two.
    pub description: Option<String>,
    /// What the plan changes, in a sentence or two.
    pub plan_summary: Option<String>,
    /// The vegetation layer holding the planned plants (one of `[[layers]]`).
    pub plan_layer: Option<String>,
    /// Credits of the data, printed on saved pictures (e.g. "terrain: NASA SRTM").
    pub attribution: Option<String>,
}

impl SceneConfig {
    /// Reads and parses a scene file (without loading what it names).
    pub fn load(path: &std::path::Path) -> Result<SceneConfig, super::SceneError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| super::SceneError::Io { path: path.to_owned(), source })?;
        toml::from_str(&text).map_err(|e| super::SceneError::Parse { path: path.to_owned(), message: e.to_string() })
    }
}

fn default_max_plants() -> usize {
    200_000
}

/// `[terrain]`: the DEM and how the ground looks.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainConfig {
    /// DEM raster (GeoTIFF or ESRI ASCII grid).
    pub dem: PathBuf,
    /// CRS of the DEM when the file carries none (e.g. an `.asc` without `.prj`): "EPSG:4326".
    pub crs: Option<String>,
    /// Crop window `[min_x, min_y, max_x, max_y]` in the DEM's CRS: the scene is the DEM's
    /// cells that meet it (a village out of a county's lidar).
    pub extent: Option<[f64; 4]>,
    /// Most DEM cells the terrain keeps: a larger DEM (after `extent`) is averaged down by the
    /// smallest whole factor that fits (a 5,000 × 5,000 lidar tile by 3 with the default).
    #[serde(default = "default_max_dem_cells")]
    pub max_cells: u64,
    /// Ground albedo, linear RGB 0..1 (where no land-cover class or orthophoto colours it).
    #[serde(default = "default_albedo")]
    pub albedo: [f32; 3],
    /// Land cover draped on the ground (SPEC S1): a categorical raster in any CRS with a
    /// definition, or GeoJSON polygons (read by `landcover_options`); it may be a vegetation
    /// layer's. Each class is drawn as `classes` and `[terrain.cover.<code>]` say.
    pub landcover: Option<PathBuf>,
    /// How to read `landcover`.
    #[serde(default)]
    pub landcover_options: LandcoverOptions,
    /// The classification of `landcover` whose default classes apply: `nlcd`,
    /// `nlcd_simplified`, `corine` or `worldcover`.
    pub classes: Option<super::cover::CoverTable>,
    /// `[terrain.cover.<code>]`: how each land-cover class is drawn (over `classes`).
    #[serde(default)]
    pub cover: BTreeMap<String, super::cover::CoverClassConfig>,
    /// An RGB (or RGBA) orthophoto GeoTIFF, the colour of the ground in the colour styles.
    pub orthophoto: Option<PathBuf>,
    /// CRS of `orthophoto` when the file has none or a wrong one.
    pub orthophoto_crs: Option<String>,
}

/// 2048 × 2048 cells: what a terrain of chunk LODs renders at walking height and from above
/// in about 1 GB (BENCHMARKS.md, "Large DEMs").
fn default_max_dem_cells() -> u64 {
    1 << 22
}

fn default_albedo() -> [f32; 3] {
    [0.8, 0.78, 0.72]
}

/// `[sun]`: direction of the light.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunConfig {
    /// Compass direction the sun stands in, degrees clockwise from north.
    pub azimuth: f32,
    /// Degrees above the horizon.
    pub elevation: f32,
}

impl Default for SunConfig {
    fn default() -> Self {
        SunConfig { azimuth: 135.0, elevation: 35.0 }
    }
}

/// `[camera]`: the default view at walking height.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// Scene-space position (x east, y north) in metres from the scene origin.
    pub position: [f32; 2],
    /// Eye elevation in metres (not below the terrain there); when absent the eye is
    /// `eye_height` above the terrain.
    pub z: Option<f32>,
    #[serde(default = "default_eye_height")]
    pub eye_height: f32,
    /// Compass heading in degrees (0 = north, 90 = east).
    pub yaw: f32,
    #[serde(default)]
    pub pitch: f32,
    #[serde(default = "default_fov")]
    pub fov: f32,
    /// Rotation about the view direction, degrees (default 0).
    #[serde(default)]
    pub roll: f32,
}

fn default_eye_height() -> f32 {
    1.7
}

fn default_fov() -> f32 {
    60.0
}

/// `[species.NAME]`: a plant model from a glTF file or the procedural generator.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeciesConfig {
    /// A glTF 2.0 model (.gltf or .glb).
    pub model: Option<PathBuf>,
    /// A procedural plant instead of a model file.
    pub procedural: Option<ProceduralKind>,
    /// Seed of the procedural generator.
    #[serde(default)]
    pub seed: u64,
    /// Maximum radius of the model's higher level primitives in model units (thesis 4.2);
    /// default 15 % of the model's height.
    pub hlp_radius: Option<f32>,
}

/// `[[layers]]`: a named group of plants placed from a land cover by rules and/or from
/// vector plans.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerConfig {
    pub name: String,
    /// Categorical land cover: a raster in any CRS with a definition (reprojected to the
    /// DEM's by nearest neighbour) or GeoJSON polygons rasterized by `landcover_options`.
    /// Optional when the layer is built only from `plans`.
    pub landcover: Option<PathBuf>,
    /// How to read `landcover`.
    #[serde(default)]
    pub landcover_options: LandcoverOptions,
    /// Placement seed.
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub rules: Vec<RuleConfig>,
    /// Vector plans: planting areas, hedgerows, single plants.
    #[serde(default)]
    pub plans: Vec<PlanConfig>,
}

/// `[layers.landcover_options]`: the land cover's CRS (when the file has none or a wrong one)
/// and, for GeoJSON polygons, the label property and the rasterization cell size.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LandcoverOptions {
    /// CRS overriding the file's: `EPSG:<code>`, a PROJ string or WKT.
    pub crs: Option<String>,
    /// Polygons: the property holding the integer class.
    #[serde(default = "default_class_property")]
    pub property: String,
    /// Polygons: cell size in metres of the rasterized land cover.
    #[serde(default = "default_landcover_cell")]
    pub cell: f64,
    /// Polygons: the class of every polygon, instead of a property (e.g. building footprints
    /// exported without a class).
    pub class: Option<u32>,
}

impl Default for LandcoverOptions {
    fn default() -> Self {
        LandcoverOptions { crs: None, property: default_class_property(), cell: default_landcover_cell(), class: None }
    }
}

fn default_class_property() -> String {
    "class".into()
}

fn default_landcover_cell() -> f64 {
    1.0
}

/// What a vector plan holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanKind {
    /// Planting polygons: plants at a density inside each polygon.
    Areas,
    /// Lines: plants along each line at a spacing, in one or more rows.
    Hedgerows,
    /// Points (GeoJSON or CSV): one plant at each, e.g. a tree inventory.
    Plants,
}

/// `[[layers.plans]]`: a vector file (GeoJSON, or CSV for `plants`) placing plants. Each
/// feature's species comes from its `species_property` (mapped by `species_map`), else
/// `species`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanConfig {
    pub kind: PlanKind,
    /// The vector file, relative to the scene file.
    pub file: PathBuf,
    /// CRS overriding the file's (GeoJSON: WGS 84 or its `crs` member; CSV: WGS 84 for
    /// lon/lat columns, else the DEM's).
    pub crs: Option<String>,
    /// Species of features without a species property.
    pub species: Option<String>,
    /// Property (CSV: column) naming a feature's species.
    #[serde(default = "default_species_property")]
    pub species_property: String,
    /// Property values → scene species names (e.g. `OAK = "oak"`).
    #[serde(default)]
    pub species_map: BTreeMap<String, String>,
    /// `areas`: plants per hectare where a feature has no `density_property`.
    pub density: Option<f64>,
    /// `areas`: property giving a feature's density (plants per hectare).
    #[serde(default = "default_density_property")]
    pub density_property: String,
    /// `areas`: minimum distance between plants of one polygon, metres.
    #[serde(default)]
    pub min_spacing: f64,
    /// Uniform scale range of the model (`plants`: used where a feature gives no size).
    #[serde(default = "default_scale")]
    pub scale: [f32; 2],
    /// `hedgerows`: distance between plants along a row, metres.
    #[serde(default = "default_hedge_spacing")]
    pub spacing: f64,
    /// `hedgerows`: number of parallel rows.
    #[serde(default = "default_rows")]
    pub rows: u32,
    /// `hedgerows`: distance between rows, metres.
    #[serde(default = "default_row_spacing")]
    pub row_spacing: f64,
    /// `plants`: property giving a plant's height in metres (scales the model to it).
    #[serde(default = "default_height_property")]
    pub height_property: String,
    /// `plants`: property giving the crown diameter in metres (used when there is no height).
    #[serde(default = "default_crown_property")]
    pub crown_property: String,
}

fn default_species_property() -> String {
    "species".into()
}

fn default_density_property() -> String {
    "density".into()
}

fn default_hedge_spacing() -> f64 {
    1.0
}

fn default_rows() -> u32 {
    1
}

fn default_row_spacing() -> f64 {
    0.7
}

fn default_height_property() -> String {
    "height".into()
}

fn default_crown_property() -> String {
    "crown".into()
}

/// `[[layers.rules]]`: which species grow on which land-cover class, how densely.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RuleConfig {
    /// Land-cover class (label value).
    pub class: i64,
    /// Name of a `[species.NAME]` table.
    pub species: String,
    /// Plants per hectare.
    pub density: f64,
    /// Minimum distance between plants of the layer, metres.
    #[serde(default)]
    pub min_spacing: f64,
    /// Uniform scale range of the model.
    #[serde(default = "default_scale")]
    pub scale: [f32; 2],
}

fn default_scale() -> [f32; 2] {
    [1.0, 1.0]
}
