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
    /// Ground albedo, linear RGB 0..1.
    #[serde(default = "default_albedo")]
    pub albedo: [f32; 3],
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
    /// Absolute eye height in metres; when absent the eye is `eye_height` above the terrain.
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

/// `[[layers]]`: a named group of plants placed from a land-cover raster.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerConfig {
    pub name: String,
    /// Categorical land-cover raster in the DEM's CRS.
    pub landcover: PathBuf,
    /// Placement seed.
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub rules: Vec<RuleConfig>,
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
