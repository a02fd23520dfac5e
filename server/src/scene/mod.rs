//! The landscape scene: terrain mesh, plant models, vegetation placement and the scene file.

/// The sample scene the commands and the server load when no `--scene` is given.
pub const SAMPLE_SCENE: &str = "data/rbsf/scene.toml";

pub mod camera;
pub mod camera_params;
pub mod config;
pub mod cover;
pub mod gltf_loader;
pub mod mesh;
pub mod participation;
pub mod plan;
pub mod plant;
pub mod procedural;
pub mod terrain;
pub mod tour;
pub mod vegetation;

use crate::gis::{self, CrsDefinition, GisError, ReprojectError, SceneTarget, VectorError};
use crate::progress::{Progress, Silent, Stage};
use camera::Camera;
use config::{SceneConfig, SpeciesConfig};
use plant::{ModelError, PlantModel};
use std::path::{Path, PathBuf};
use terrain::Terrain;
use tracing::info;
use vegetation::{PlacementRule, PlantInstance};

/// Errors raised while loading a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: cannot read scene file: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error(transparent)]
    Gis(#[from] GisError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Vector(#[from] VectorError),
    #[error("{0}")]
    Invalid(String),
}

/// A plant species: a name, its model and the maximum radius of its HLPs.
#[derive(Debug, Clone)]
pub struct Species {
    pub name: String,
    pub model: PlantModel,
    /// Maximum HLP radius in model units (thesis 4.2); by default 15 % of the model's height.
    pub hlp_radius: f32,
}

impl Species {
    /// A species with the default HLP radius (15 % of the model's height).
    pub fn new(name: impl Into<String>, model: PlantModel) -> Species {
        let hlp_radius = (0.15 * model.height()).max(0.05);
        Species { name: name.into(), model, hlp_radius }
    }
}

/// A named group of plants (SPEC S4), e.g. `existing` or `planned`.
#[derive(Debug, Clone)]
pub struct VegetationLayer {
    pub name: String,
    pub plants: Vec<PlantInstance>,
}

/// Direction of the sunlight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sun {
    /// Degrees clockwise from north.
    pub azimuth: f32,
    /// Degrees above the horizon.
    pub elevation: f32,
}

impl Sun {
    /// Unit vector from the ground towards the sun (x east, y north, z up).
    pub fn direction(&self) -> glam::Vec3 {
        let (az, el) = (self.azimuth.to_radians(), self.elevation.to_radians());
        glam::Vec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin())
    }
}

/// A loaded scene, ready to upload to the GPU.
#[derive(Debug, Clone)]
pub struct Scene {
    pub name: String,
    pub terrain: Terrain,
    pub species: Vec<Species>,
    pub layers: Vec<VegetationLayer>,
    pub sun: Sun,
    pub default_camera: Camera,
    /// The scene file's `[about]` (welcome text and the plan's layer).
    pub about: config::AboutConfig,
}

impl Scene {
    /// Loads a scene file and everything it names: DEM, models, land cover; places plants.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_with(path, &Silent)
    }

    /// [`Scene::load`] reporting its stages to `progress`.
    pub fn load_with(path: &Path, progress: &dyn Progress) -> Result<Scene, SceneError> {
        let config = SceneConfig::load(path)?;
        Scene::from_config_file(&config, path, progress)
    }

    /// [`Scene::from_config`] for a config read from the scene file `path`: relative paths are
    /// resolved against its directory and errors name the file.
    pub fn from_config_file(config: &SceneConfig, path: &Path, progress: &dyn Progress) -> Result<Scene, SceneError> {
        let base = path.parent().unwrap_or(Path::new("."));
        Scene::from_config(config, base, progress).map_err(|e| match e {
            SceneError::Invalid(message) => SceneError::Parse { path: path.to_owned(), message },
            other => other,
        })
    }

    /// Builds a scene from a parsed config; relative paths are resolved against `base`; the
    /// stages (terrain, drape, placement) are reported to `progress`.
    pub fn from_config(config: &SceneConfig, base: &Path, progress: &dyn Progress) -> Result<Scene, SceneError> {
        progress.report(Stage::Terrain, 0.0);
        let dem_path = base.join(&config.terrain.dem);
        let mut dem = load_dem(&config.terrain, &dem_path)?;
        // The DEM's full CRS definition, needed only to bring other data into the scene: a DEM
        // whose CRS has none still loads (its frame needs only the unit).
        let scene_crs: Result<CrsDefinition, ReprojectError> = match &config.terrain.crs {
            Some(text) => Ok(CrsDefinition::parse(text).map_err(|e| SceneError::Invalid(format!("terrain.crs: {e}")))?),
            None => gis::file_definition(&dem_path, &dem),
        };
        if let Ok(def) = &scene_crs {
            dem.crs = def.crs();
        }
        let mut terrain = Terrain::new(dem, config.terrain.albedo)?;
        progress.report(Stage::Drape, 0.0);
        let scene_def = || {
            scene_crs.clone().map_err(|source| SceneError::Gis(GisError::Reproject { path: dem_path.clone(), source }))
        };
        if config.terrain.landcover.is_some() || config.terrain.orthophoto.is_some() || !config.terrain.cover.is_empty()
        {
            let drape = load_drape(&config.terrain, base, &scene_def()?, &terrain)?;
            info!(
                classes = drape.classes.len(),
                width = drape.width,
                height = drape.height,
                cell = drape.cell,
                "ground drape"
            );
            terrain.set_drape(drape);
        }

        let names: Vec<&String> = config.species.keys().collect();
        let species = config
            .species
            .iter()
            .map(|(name, s)| {
                let mut species = Species::new(name.clone(), load_species(name, s, base)?);
                if let Some(r) = s.hlp_radius {
                    if !(r > 0.0 && r.is_finite()) {
                        return Err(SceneError::Invalid(format!("species '{name}': hlp_radius must be > 0")));
                    }
                    species.hlp_radius = r;
                }
                Ok(species)
            })
            .collect::<Result<Vec<_>, SceneError>>()?;

        let mut layers = Vec::new();
        for (index, layer) in config.layers.iter().enumerate() {
            progress.report(Stage::Placement, index as f32 / config.layers.len() as f32);
            let rules = layer
                .rules
                .iter()
                .map(|r| {
                    let species = names.iter().position(|n| **n == r.species).ok_or_else(|| {
                        SceneError::Invalid(format!("layer '{}': rule names unknown species '{}'", layer.name, r.species))
                    })?;
                    if !(r.density >= 0.0 && r.density <= 10_000.0 && r.min_spacing >= 0.0 && r.scale[0] > 0.0 && r.scale[1] >= r.scale[0]) {
                        return Err(SceneError::Invalid(format!(
                            "layer '{}': rule for class {} needs 0 <= density <= 10000, min_spacing >= 0 and 0 < scale[0] <= scale[1]",
                            layer.name, r.class
                        )));
                    }
                    Ok(PlacementRule { class: r.class, species, density_per_ha: r.density, min_spacing: r.min_spacing, scale: r.scale })
                })
                .collect::<Result<Vec<_>, SceneError>>()?;
            let mut plants = Vec::new();
            match &layer.landcover {
                Some(file) => {
                    let what = format!("layer '{}': landcover_options", layer.name);
                    let landcover =
                        load_landcover(&base.join(file), &layer.landcover_options, &what, &scene_def()?, &terrain)?;
                    let layers = config.layers.len() as f32;
                    let within = |done: f32| progress.report(Stage::Placement, (index as f32 + done) / layers);
                    plants = vegetation::place_reporting(
                        &terrain,
                        &landcover,
                        &rules,
                        layer.seed,
                        config.max_plants,
                        &within,
                    )?;
                }
                None if !rules.is_empty() => {
                    return Err(SceneError::Invalid(format!("layer '{}': rules need a `landcover`", layer.name)));
                }
                None if layer.plans.is_empty() => {
                    return Err(SceneError::Invalid(format!(
                        "layer '{}': give a `landcover` with rules or `plans`",
                        layer.name
                    )));
                }
                None => {}
            }
            for (i, plan) in layer.plans.iter().enumerate() {
                let path = base.join(&plan.file);
                let crs = optional_crs(plan.crs.as_deref(), &format!("layer '{}': plan {i}: crs", layer.name))?;
                let scene = scene_def()?;
                let target = SceneTarget { crs: &scene, frame: &terrain.frame };
                let features = gis::read_vector(&path, crs.as_ref(), target)?;
                let seed = layer.seed ^ crate::rng::mix(i as u64 + 1);
                let remaining = config.max_plants.saturating_sub(plants.len());
                plants.extend(plan::place_plan(plan, &features, &path, &terrain, &species, seed, remaining)?);
            }
            info!(layer = %layer.name, plants = plants.len(), "vegetation placed");
            progress.report(Stage::Placement, (index + 1) as f32 / config.layers.len() as f32);
            layers.push(VegetationLayer { name: layer.name.clone(), plants });
        }

        let cam = config.camera;
        let ground = terrain.height_at(f64::from(cam.position[0]), f64::from(cam.position[1]));
        if let Some(z) = cam.z
            && let Some(h) = terrain.buries([cam.position[0], cam.position[1], z])
        {
            return Err(SceneError::Invalid(format!(
                "camera z {z} m is below the terrain at {:?} (ground {h:.1} m): z is an elevation; leave it out to stand `eye_height` above the ground",
                cam.position
            )));
        }
        let z = match (cam.z, ground) {
            (Some(z), _) => z,
            (None, Some(h)) => h as f32 + cam.eye_height,
            (None, None) => {
                return Err(SceneError::Invalid(format!(
                    "camera position {:?} is outside the terrain; give `z` or move it onto the DEM",
                    cam.position
                )));
            }
        };
        let default_camera = Camera {
            position: [cam.position[0], cam.position[1], z],
            yaw: cam.yaw,
            pitch: cam.pitch,
            fov: cam.fov,
            roll: cam.roll,
            projection: Default::default(),
        };
        if !default_camera.is_valid() {
            return Err(SceneError::Invalid(
                "camera: pitch must be within -90..=90 and fov within 1..=170 degrees".into(),
            ));
        }
        if let Some(plan) = &config.about.plan_layer
            && !layers.iter().any(|l| &l.name == plan)
        {
            return Err(SceneError::Invalid(format!(
                "about.plan_layer = {plan:?} names no layer; the layers are {:?}",
                layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>()
            )));
        }
        Ok(Scene {
            name: config.name.clone(),
            about: config.about.clone(),
            terrain,
            species,
            layers,
            sun: Sun { azimuth: config.sun.azimuth, elevation: config.sun.elevation },
            default_camera,
        })
    }

    /// Number of plants over all layers.
    pub fn plant_count(&self) -> usize {
        self.layers.iter().map(|l| l.plants.len()).sum()
    }

    /// The names of the vegetation layers, in order (the names per-layer styles use).
    pub fn layer_names(&self) -> Vec<String> {
        self.layers.iter().map(|l| l.name.clone()).collect()
    }
}

/// The ground's drape (`scene::cover`): the `[terrain]` section's land cover, orthophoto and
/// classes, in the scene CRS over the terrain.
fn load_drape(
    config: &config::TerrainConfig,
    base: &Path,
    scene: &CrsDefinition,
    terrain: &Terrain,
) -> Result<cover::Drape, SceneError> {
    let classes = cover::resolve_classes(config.classes, &config.cover)?;
    let landcover_path = config.landcover.as_ref().map(|file| base.join(file));
    let landcover = landcover_path
        .as_deref()
        .map(|path| load_landcover(path, &config.landcover_options, "terrain.landcover_options", scene, terrain))
        .transpose()?;
    let ortho_path = config.orthophoto.as_ref().map(|file| base.join(file));
    let orthophoto = match &ortho_path {
        Some(path) => {
            let crs = optional_crs(config.orthophoto_crs.as_deref(), "terrain.orthophoto_crs")?;
            let mut bands = gis::read_geotiff_bands(path)?;
            // Unsigned 16-bit orthophotos are scaled from 0..65535 to the drape's bytes.
            if gis::geotiff::is_uint16(path)? {
                for value in bands.iter_mut().flat_map(|band| band.data.iter_mut()) {
                    *value *= 255.0 / 65535.0;
                }
            }
            if !(3..=4).contains(&bands.len()) {
                return Err(SceneError::Invalid(format!(
                    "{}: an orthophoto needs 3 bands (red, green, blue) or 4 (with alpha); this file has {}",
                    path.display(),
                    bands.len()
                )));
            }
            Some(gis::bands_in(path, bands, crs.as_ref(), scene, &terrain.dem.extent())?)
        }
        None => None,
    };
    let sources = cover::DrapeSources {
        landcover: landcover.as_ref().zip(landcover_path.as_deref()),
        orthophoto: orthophoto.as_deref().zip(ortho_path.as_deref()),
        classes,
    };
    cover::Drape::build(sources, &terrain.frame, terrain.bounds(), config.albedo)
}

/// The CRS a scene-file key gives (`EPSG:<code>`, a PROJ string or WKT), if any; errors name
/// the key.
fn optional_crs(text: Option<&str>, key: &str) -> Result<Option<CrsDefinition>, SceneError> {
    text.map(CrsDefinition::parse).transpose().map_err(|e| SceneError::Invalid(format!("{key}: {e}")))
}

/// A land cover in the scene CRS: a raster reprojected if needed, or GeoJSON polygons
/// rasterized over the terrain; `what` names its options in messages.
/// The DEM as the scene uses it: the cells meeting `terrain.extent`, at most
/// `terrain.max_cells` of them ([`gis::load_dem`]).
fn load_dem(terrain: &config::TerrainConfig, path: &Path) -> Result<gis::Raster, SceneError> {
    let window = match terrain.extent {
        None => None,
        Some([min_x, min_y, max_x, max_y]) => {
            if !([min_x, min_y, max_x, max_y].iter().all(|v| v.is_finite()) && max_x > min_x && max_y > min_y) {
                return Err(SceneError::Invalid(
                    "terrain.extent must be [min_x, min_y, max_x, max_y] with min < max, in the DEM's CRS".into(),
                ));
            }
            Some(gis::Extent { min_x, min_y, max_x, max_y })
        }
    };
    if terrain.max_cells < 4 {
        return Err(SceneError::Invalid("terrain.max_cells must be at least 4 (a 2 × 2 terrain)".into()));
    }
    let dem = gis::load_dem(path, window.as_ref(), terrain.max_cells).map_err(|e| match e {
        GisError::WindowOutside { .. } => SceneError::Invalid(format!("terrain.extent: {e}")),
        other => SceneError::Gis(other),
    })?;
    info!(cells = %format!("{} × {}", dem.width, dem.height), cell = dem.transform.cell_width, "DEM loaded");
    Ok(dem)
}

fn load_landcover(
    path: &Path,
    opts: &config::LandcoverOptions,
    what: &str,
    scene: &CrsDefinition,
    terrain: &Terrain,
) -> Result<gis::Raster, SceneError> {
    let crs = optional_crs(opts.crs.as_deref(), &format!("{what}.crs"))?;
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("geojson" | "json" | "shp")) {
        let target = SceneTarget { crs: scene, frame: &terrain.frame };
        let mut features = gis::read_vector(path, crs.as_ref(), target)?;
        if let Some(class) = opts.class {
            for feature in &mut features {
                feature.properties.insert(opts.property.clone(), serde_json::Value::from(class));
            }
        }
        let (lo, hi) = terrain.bounds();
        Ok(gis::vector::rasterize_labels(&features, &opts.property, opts.cell, lo, hi, &terrain.frame, path)?)
    } else {
        Ok(gis::load_raster_in(path, crs.as_ref(), scene, &terrain.dem.extent())?)
    }
}

fn load_species(name: &str, config: &SpeciesConfig, base: &Path) -> Result<PlantModel, SceneError> {
    match (&config.model, config.procedural) {
        (Some(model), None) => Ok(gltf_loader::load_gltf(&base.join(model))?),
        (None, Some(kind)) => Ok(procedural::procedural_plant(kind, config.seed)),
        _ => Err(SceneError::Invalid(format!("species '{name}': give exactly one of `model` or `procedural`"))),
    }
}
