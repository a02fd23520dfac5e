//! The persistent layer store (SPEC A2): uploaded environment data layers kept in a data
//! directory that survives restarts.
//!
//! # Layout
//!
//! ```text
//! <dir>/
//!   store.json                    {"format": 1}
//!   layers/<id>/meta.json         LayerMeta as JSON (the layer exists iff this file does)
//!   layers/<id>/step-<n>.f32      one grid per time step: width × height little-endian f32,
//!                                 row 0 north, NaN = nodata (geometry in meta.json)
//!   tmp/                          staging area; emptied whenever the store is opened
//! ```
//!
//! # Atomicity
//!
//! Every write goes to a new file, is flushed with `fsync` and then renamed into place (a new
//! layer is staged as a whole directory in `tmp/` and renamed to `layers/<id>`; an appended
//! time step is renamed into the layer directory before the new `meta.json` replaces the old
//! one). A crash therefore leaves either the old or the new state: half-written staging
//! directories are deleted when the store is opened, step files that `meta.json` does not
//! list are removed, and a layer directory without a readable `meta.json` is skipped (with a
//! warning) and never listed. Deleting renames the layer directory into `tmp/` first.
//!
//! # Ids and names
//!
//! A layer id is derived from its name (`[a-z0-9-]`, at most 49 characters, e.g.
//! `air-temperature-3fa2b1c0`); names are free text (1–100 characters, no control
//! characters) and never reach a path. Ids given to [`Store::get`] and friends are looked up
//! in the in-memory index only.
//!
//! Uploaded art maps are kept in `artmaps/` (see [`Store::save_art_map`]). With several
//! replicas the directory is a local copy of the database's layers and art maps ([`shared`]).

mod artmaps;
pub mod participation;
pub mod request;
pub mod shared;

pub use artmaps::StoredArtMap;

use std::collections::{BTreeMap, HashSet};
use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use serde::{Deserialize, Serialize};
use tracing::warn;

use crate::echo::echo;
use crate::fields::{
    ClassInfo, ColorMapSpec, Field, FieldError, FieldKind, FieldStep, Legend, LoadOptions, Lut, MAX_LABEL_CLASSES,
    SceneGeo, format_time, load_bytes, parse_time,
};
use crate::gis::{CrsDefinition, GeoTransform, Raster};

/// Version of the on-disk layout written to `store.json` and every `meta.json`.
pub const STORE_FORMAT: u32 = 1;

/// Why a store operation failed. [`StoreError::status`] gives the HTTP status to answer with.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The upload is not a valid field (format, kind, CRS, extent, time, classes) → 422, or
    /// too large (cells, steps) → 413.
    #[error(transparent)]
    Field(#[from] FieldError),
    /// No layer with this id → 404.
    #[error("unknown layer \"{}\"", echo(.id))]
    NotFound {
        /// The id asked for.
        id: String,
    },
    /// The request conflicts with a stored layer (name taken by a layer that cannot take the
    /// upload as a further time step) → 409.
    #[error("{0}")]
    Conflict(String),
    /// Upload bytes or the number of layers above a limit → 413.
    #[error("{what} is too large: {size} exceeds the limit of {limit}")]
    TooLarge {
        /// What was measured.
        what: String,
        /// The size found.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// An unusable layer name or upload option → 422.
    #[error("{0}")]
    Invalid(String),
    /// An unusable text field of an upload (`name`, `units`, `filename`) → 422 naming it.
    #[error("{field}: {message}")]
    InvalidField {
        /// The upload parameter.
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// The data directory could not be read or written → 500.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Stored data that does not match its metadata → 500.
    #[error("layer {id} is damaged: {message}")]
    Corrupt {
        /// The layer.
        id: String,
        /// What is wrong.
        message: String,
    },
}

impl StoreError {
    /// The HTTP status for this error: 404, 409, 413, 422 or 500.
    pub fn status(&self) -> u16 {
        match self {
            StoreError::NotFound { .. } => 404,
            StoreError::Conflict(_) => 409,
            StoreError::TooLarge { .. } => 413,
            StoreError::Field(e) if e.is_too_large() => 413,
            StoreError::Field(FieldError::Gis(crate::gis::GisError::Io { .. })) => 500,
            StoreError::Field(_) | StoreError::Invalid(_) | StoreError::InvalidField { .. } => 422,
            StoreError::Io { .. } | StoreError::Corrupt { .. } => 500,
        }
    }
}

/// Limits applied to uploads and to the store.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoreLimits {
    /// Largest upload body in bytes.
    pub max_upload_bytes: u64,
    /// Largest grid per time step (width × height), checked before decoding.
    pub max_cells: u64,
    /// Most time steps per layer.
    pub max_steps: usize,
    /// Most layers in the store.
    pub max_layers: usize,
}

impl Default for StoreLimits {
    /// 256 MiB uploads, 4096² cells per step, 1000 steps per layer, 1000 layers.
    fn default() -> StoreLimits {
        StoreLimits {
            max_upload_bytes: 256 << 20,
            max_cells: crate::fields::source::DEFAULT_MAX_CELLS,
            max_steps: crate::fields::source::DEFAULT_MAX_STEPS,
            max_layers: 1000,
        }
    }
}

/// An upload's parameters (the query string of `POST /api/layers`, deserialisable).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct UploadRequest {
    /// Display name; an upload with the name of a stored series adds time steps to it.
    pub name: String,
    /// `scalar` or `label`.
    pub kind: Option<FieldKind>,
    /// ISO 8601 time stamp of a single-grid upload (a step of a series).
    pub time: Option<String>,
    /// Original file name (format fallback and messages); at most 255 characters, no control
    /// characters.
    pub filename: Option<String>,
    /// CRS to use instead of the file's: `EPSG:<code>`, a PROJ.4 string, or `scene` to assume
    /// the scene's CRS. Needed for ESRI ASCII grids (no `.prj` in an upload).
    pub crs: Option<String>,
    /// NetCDF variable.
    pub variable: Option<String>,
    /// Units of the values (overrides the file's); at most 100 characters, no control
    /// characters.
    pub units: Option<String>,
    /// Class names of a label field: `1=Water,2=Developed,…`.
    pub classes: Option<String>,
}

/// Geometry and statistics of one stored time step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct StepMeta {
    /// ISO 8601 time, `None` for a layer without time.
    pub time: Option<String>,
    /// File name inside the layer directory.
    pub file: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Geotransform in the layer CRS: x of the west edge, y of the north edge, cell width,
    /// cell height.
    pub transform: [f64; 4],
    /// Smallest valid value.
    pub min: f64,
    /// Largest valid value.
    pub max: f64,
    /// Number of valid cells.
    pub valid_cells: u64,
}

/// What is known about a stored layer (its `meta.json`, and the JSON of `GET /api/layers/{id}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct LayerMeta {
    /// Layout version ([`STORE_FORMAT`]).
    pub format: u32,
    /// Id (`[a-z0-9-]`), stable across restarts.
    pub id: String,
    /// Display name.
    pub name: String,
    /// Scalar or label.
    pub kind: FieldKind,
    /// CRS label (`EPSG:<code>` or the PROJ.4 string).
    pub crs: String,
    /// Full CRS definition (PROJ.4).
    pub crs_definition: String,
    /// Extent in the layer CRS: `[min_x, min_y, max_x, max_y]` (union of all steps).
    pub extent: [f64; 4],
    /// Extent in scene metres at upload time, `[min_x, min_y, max_x, max_y]`.
    pub scene_extent: Option<[f64; 4]>,
    /// Smallest valid value over all steps.
    pub min: f64,
    /// Largest valid value over all steps.
    pub max: f64,
    /// Label classes with cell counts (empty for scalars).
    pub classes: Vec<ClassInfo>,
    /// Time steps in time order.
    pub steps: Vec<StepMeta>,
    /// Units of the values.
    pub units: Option<String>,
    /// File name (or format) of the first upload.
    pub source: String,
    /// When the layer was created (RFC 3339).
    pub created: String,
}

impl LayerMeta {
    /// The time stamps of the steps (empty for a layer without time).
    pub fn times(&self) -> Vec<&str> {
        self.steps.iter().filter_map(|s| s.time.as_deref()).collect()
    }
}

/// The layer store. All methods take `&self` and are safe to call from several threads;
/// writes are serialised.
#[derive(Debug)]
pub struct Store {
    root: PathBuf,
    limits: StoreLimits,
    index: Mutex<BTreeMap<String, LayerMeta>>,
    /// Held by one writer at a time ([`Store::writing`]).
    writes: Mutex<()>,
}

impl Store {
    /// Opens (creating if needed) the store in `dir` with default limits: empties `tmp/`,
    /// loads every complete layer and removes files no layer refers to.
    pub fn open(dir: &Path) -> Result<Store, StoreError> {
        Store::open_with_limits(dir, StoreLimits::default())
    }

    /// [`Store::open`] with explicit limits.
    pub fn open_with_limits(dir: &Path, limits: StoreLimits) -> Result<Store, StoreError> {
        let store =
            Store { root: dir.to_path_buf(), limits, index: Mutex::new(BTreeMap::new()), writes: Mutex::new(()) };
        for d in [store.root.clone(), store.layers_dir(), store.tmp_dir()] {
            fs::create_dir_all(&d).map_err(io_err(&d))?;
        }
        clear_dir(&store.tmp_dir())?;
        let version = store.root.join("store.json");
        if !version.exists() {
            store.write_file_atomic(
                &version,
                &serde_json::to_vec(&serde_json::json!({ "format": STORE_FORMAT })).unwrap_or_default(),
            )?;
        }
        let mut index = BTreeMap::new();
        let entries = fs::read_dir(store.layers_dir()).map_err(io_err(&store.layers_dir()))?;
        for entry in entries {
            let entry = entry.map_err(io_err(&store.layers_dir()))?;
            let id = entry.file_name().to_string_lossy().to_string();
            match store.load_layer_dir(&id, &entry.path()) {
                Ok(meta) => {
                    index.insert(id, meta);
                }
                Err(e) => warn!(layer = %id, error = %e, "skipping an incomplete or damaged layer"),
            }
        }
        *store.lock() = index;
        Ok(store)
    }

    /// The data directory.
    pub fn dir(&self) -> &Path {
        &self.root
    }

    /// The limits in force.
    pub fn limits(&self) -> &StoreLimits {
        &self.limits
    }

    /// All layers, sorted by name.
    pub fn list(&self) -> Vec<LayerMeta> {
        let mut all: Vec<LayerMeta> = self.lock().values().cloned().collect();
        all.sort_by(|a, b| a.name.cmp(&b.name).then_with(|| a.id.cmp(&b.id)));
        all
    }

    /// One layer's metadata.
    pub fn get(&self, id: &str) -> Result<LayerMeta, StoreError> {
        self.lock().get(id).cloned().ok_or_else(|| StoreError::NotFound { id: id.to_string() })
    }

    /// The layer with this display name, if any.
    pub fn find_by_name(&self, name: &str) -> Option<LayerMeta> {
        self.lock().values().find(|m| m.name == name.trim()).cloned()
    }

    /// Decodes, validates and stores an upload (GeoTIFF, ESRI ASCII grid or NetCDF-3 bytes).
    /// Checks size limits, format, kind, CRS and overlap with `scene`. A new name creates a
    /// layer; the name of a stored time series adds the upload's time steps to it (same kind
    /// and CRS, new times). On any error the store is unchanged.
    pub fn add_upload(&self, bytes: &[u8], req: &UploadRequest, scene: &SceneGeo) -> Result<LayerMeta, StoreError> {
        let size = bytes.len() as u64;
        if size > self.limits.max_upload_bytes {
            return Err(StoreError::TooLarge { what: "upload".into(), size, limit: self.limits.max_upload_bytes });
        }
        let name = check_name(&req.name)?;
        if let Some(units) = &req.units {
            check_text("units", units, 100)?;
        }
        if let Some(filename) = &req.filename {
            check_text("filename", filename, 255)?;
        }
        let kind = req.kind.ok_or_else(|| StoreError::Invalid("kind is required: scalar or label".into()))?;
        let crs = match req.crs.as_deref().map(str::trim) {
            None | Some("") => None,
            Some(s) if s.eq_ignore_ascii_case("scene") => Some(scene.crs().clone()),
            Some(s) => Some(CrsDefinition::parse(s).map_err(FieldError::from)?),
        };
        let opts = LoadOptions {
            crs,
            time: req.time.clone(),
            variable: req.variable.clone(),
            units: req.units.clone(),
            max_cells: self.limits.max_cells,
            max_steps: self.limits.max_steps,
            ..LoadOptions::new(kind)
        };
        let mut field = load_bytes(bytes, req.filename.as_deref(), &opts, &self.tmp_dir())?;
        if let Some(text) = &req.classes {
            if kind != FieldKind::Label {
                return Err(StoreError::Invalid("class names are for label fields only".into()));
            }
            field.set_class_names(&parse_class_names(text)?)?;
        }
        let source = req.filename.clone().unwrap_or_else(|| "upload".into());
        self.add_field(&name, field, &source, scene)
    }

    /// Stores an already decoded field under `name` (see [`Store::add_upload`] for the rules;
    /// `source` is recorded in the metadata). Writers are serialised; the index is locked only
    /// to look up and to publish, never across disk writes, so reads go on meanwhile.
    pub fn add_field(&self, name: &str, field: Field, source: &str, scene: &SceneGeo) -> Result<LayerMeta, StoreError> {
        let name = check_name(name)?;
        check_representable(&field, source)?;
        field.check_overlap(scene)?;
        let scene_extent = field.scene_extent(scene)?;
        if !scene_extent.is_some_and(|e| e.iter().all(|v| fits_f32(*v))) {
            return Err(StoreError::Invalid(format!(
                "{}: the layer's extent cannot be placed in the scene (it is not finite in scene metres)",
                echo(source)
            )));
        }
        let _writing = self.writing();
        let existing = self.lock().values().find(|m| m.name == name).cloned();
        if let Some(existing) = existing {
            let meta = self.append_steps(&existing, field, scene_extent)?;
            self.lock().insert(meta.id.clone(), meta.clone());
            return Ok(meta);
        }
        let id = {
            let index = self.lock();
            if index.len() >= self.limits.max_layers {
                return Err(StoreError::TooLarge {
                    what: "store".into(),
                    size: index.len() as u64 + 1,
                    limit: self.limits.max_layers as u64,
                });
            }
            // A directory left by a damaged layer (skipped at start-up) keeps its id taken.
            unique_id(&name, |id| index.contains_key(id) || self.layers_dir().join(id).exists())
        };
        if field.steps().len() > self.limits.max_steps {
            return Err(StoreError::TooLarge {
                what: "series".into(),
                size: field.steps().len() as u64,
                limit: self.limits.max_steps as u64,
            });
        }
        let stage = self.tmp_dir().join(format!("new-{id}-{}", nonce()));
        fs::create_dir(&stage).map_err(io_err(&stage))?;
        let result = (|| -> Result<LayerMeta, StoreError> {
            let steps =
                field.steps().iter().map(|s| self.write_step(&stage, s)).collect::<Result<Vec<_>, StoreError>>()?;
            let e = field.extent();
            let (min, max) = field.value_range();
            let meta = LayerMeta {
                format: STORE_FORMAT,
                id: id.clone(),
                name: name.clone(),
                kind: field.kind(),
                crs: field.crs().label(),
                crs_definition: field.crs().proj_string().to_string(),
                extent: [e.min_x, e.min_y, e.max_x, e.max_y],
                scene_extent,
                min,
                max,
                classes: field.classes().to_vec(),
                steps,
                units: field.units().map(str::to_string),
                source: source.to_string(),
                created: format_time(&chrono::DateTime::<chrono::Utc>::from(std::time::SystemTime::now())),
            };
            self.write_file_atomic(&stage.join("meta.json"), &meta_json(&meta)?)?;
            sync_dir(&stage)?;
            let target = self.layers_dir().join(&id);
            fs::rename(&stage, &target).map_err(io_err(&target))?;
            sync_dir(&self.layers_dir())?;
            Ok(meta)
        })();
        if result.is_err() {
            let _ = fs::remove_dir_all(&stage);
        }
        let meta = result?;
        self.lock().insert(id, meta.clone());
        Ok(meta)
    }

    /// Deletes a layer and returns its metadata. It leaves the index first (so no render
    /// starts on it), then its directory goes.
    pub fn delete(&self, id: &str) -> Result<LayerMeta, StoreError> {
        let _writing = self.writing();
        let meta = self.lock().remove(id).ok_or_else(|| StoreError::NotFound { id: id.to_string() })?;
        let dir = self.layers_dir().join(&meta.id);
        let grave = self.tmp_dir().join(format!("deleted-{}-{}", meta.id, nonce()));
        let moved = fs::rename(&dir, &grave).map_err(io_err(&dir)).and_then(|()| sync_dir(&self.layers_dir()));
        if let Err(e) = moved {
            self.lock().insert(meta.id.clone(), meta);
            return Err(e);
        }
        if let Err(e) = fs::remove_dir_all(&grave) {
            warn!(path = %grave.display(), error = %e, "could not remove a deleted layer; it goes at the next start");
        }
        Ok(meta)
    }

    /// The file of step `file` of layer `id` (as [`StepMeta::file`] names it).
    pub fn step_path(&self, id: &str, file: &str) -> PathBuf {
        self.layers_dir().join(id).join(file)
    }

    /// A new empty directory in the staging area for a copy of layer `id` to
    /// [`install`](Store::install).
    pub fn staging_dir(&self, id: &str) -> Result<PathBuf, StoreError> {
        let stage = self.tmp_dir().join(format!("copy-{id}-{}", nonce()));
        fs::create_dir(&stage).map_err(io_err(&stage))?;
        Ok(stage)
    }

    /// Installs a copy of a layer made elsewhere (another replica's, [`shared`]): `stage` (from
    /// [`Store::staging_dir`]) holds the step files `meta` lists. It is checked like a layer at
    /// start-up, then replaces the stored layer of that id atomically (the limits on the
    /// number of layers do not apply: the copy is stored already). Returns the replaced
    /// version.
    pub fn install(&self, meta: LayerMeta, stage: &Path) -> Result<Option<LayerMeta>, StoreError> {
        let _writing = self.writing();
        if !valid_id(&meta.id) {
            return Err(StoreError::Corrupt { id: echo(&meta.id).to_string(), message: "not a layer id".into() });
        }
        self.write_file_atomic(&stage.join("meta.json"), &meta_json(&meta)?)?;
        let meta = self.load_layer_dir(&meta.id.clone(), stage)?;
        sync_dir(stage)?;
        let target = self.layers_dir().join(&meta.id);
        let grave = self.tmp_dir().join(format!("replaced-{}-{}", meta.id, nonce()));
        let previous = self.lock().get(&meta.id).cloned();
        if target.exists() {
            fs::rename(&target, &grave).map_err(io_err(&target))?;
        }
        fs::rename(stage, &target).map_err(io_err(&target))?;
        sync_dir(&self.layers_dir())?;
        self.lock().insert(meta.id.clone(), meta);
        if grave.exists()
            && let Err(e) = fs::remove_dir_all(&grave)
        {
            warn!(path = %grave.display(), error = %e, "could not remove a replaced layer; it goes at the next start");
        }
        Ok(previous)
    }

    /// Writes `shared.json`, the marker of the database this directory mirrors ([`shared`]).
    pub fn write_marker(&self, text: &str) -> Result<(), StoreError> {
        self.write_file_atomic(&self.root.join("shared.json"), text.as_bytes())
    }

    /// Reads a layer's data as a [`Field`] (every time step, in the layer's CRS).
    pub fn field(&self, id: &str) -> Result<Field, StoreError> {
        let meta = self.get(id)?;
        self.read_field(&meta)
    }

    /// The legend of a layer under a colour map (JSON via serde, PNG via [`Legend::to_png`]).
    pub fn legend(&self, id: &str, spec: &ColorMapSpec) -> Result<Legend, StoreError> {
        let meta = self.get(id)?;
        let lut = match meta.kind {
            FieldKind::Scalar => Lut::for_scalar(spec, (meta.min, meta.max))?,
            FieldKind::Label => Lut::for_labels(spec, &meta.classes)?,
        };
        Ok(Legend::new(&meta.name, meta.kind, meta.units.as_deref(), &meta.classes, &lut))
    }

    /// Serialises writers (uploads, appends, deletes); held across their disk writes, which
    /// run off the async threads. Readers never take it.
    fn writing(&self) -> std::sync::MutexGuard<'_, ()> {
        self.writes.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, LayerMeta>> {
        // A panic while holding the lock cannot leave the map half-updated (inserts and
        // removes are single calls), so a poisoned lock is still usable.
        self.index.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn layers_dir(&self) -> PathBuf {
        self.root.join("layers")
    }

    fn tmp_dir(&self) -> PathBuf {
        self.root.join("tmp")
    }

    /// Adds the steps of `field` to the stored series `existing`, checked against its
    /// metadata (kind, CRS, times, classes): the stored steps are not read.
    fn append_steps(
        &self,
        existing: &LayerMeta,
        field: Field,
        scene_extent: Option<[f64; 4]>,
    ) -> Result<LayerMeta, StoreError> {
        let conflict = |why: &str| StoreError::Conflict(format!("a layer named \"{}\" exists; {why}", existing.name));
        if existing.times().is_empty() || field.times().len() != field.steps().len() {
            return Err(conflict("only time steps (with a time) can be added to a stored time series"));
        }
        if existing.steps.len() + field.steps().len() > self.limits.max_steps {
            return Err(StoreError::TooLarge {
                what: "series".into(),
                size: (existing.steps.len() + field.steps().len()) as u64,
                limit: self.limits.max_steps as u64,
            });
        }
        if field.kind() != existing.kind {
            return Err(conflict(&format!("cannot add a {} grid to a {} series", field.kind(), existing.kind)));
        }
        if field.crs().proj_string() != existing.crs_definition {
            return Err(conflict(&format!(
                "every step of a series must be in the same CRS ({} vs {})",
                field.crs().label(),
                existing.crs
            )));
        }
        let stored: HashSet<&str> = existing.times().into_iter().collect();
        if let Some(t) = field.times().iter().map(format_time).find(|t| stored.contains(t.as_str())) {
            return Err(conflict(&format!("time step {t} appears twice")));
        }
        let classes = merge_classes(&existing.classes, field.classes()).map_err(|e| conflict(&e))?;
        let dir = self.layers_dir().join(&existing.id);
        let mut written = Vec::new();
        let result = (|| -> Result<LayerMeta, StoreError> {
            let mut steps = existing.steps.clone();
            for step in field.steps() {
                let staged = self.write_step(&self.tmp_dir(), step)?;
                let target = dir.join(&staged.file);
                fs::rename(self.tmp_dir().join(&staged.file), &target).map_err(io_err(&target))?;
                written.push(target);
                steps.push(staged);
            }
            sync_dir(&dir)?;
            // Times are ISO 8601 in one format (`format_time`): their text sorts by time.
            steps.sort_by(|a, b| a.time.cmp(&b.time));
            let e = field.extent();
            let (min, max) = field.value_range();
            let mut meta = existing.clone();
            meta.extent = union(existing.extent, [e.min_x, e.min_y, e.max_x, e.max_y]);
            meta.min = existing.min.min(min);
            meta.max = existing.max.max(max);
            meta.classes = classes;
            meta.units = existing.units.clone().or_else(|| field.units().map(str::to_string));
            meta.steps = steps;
            meta.scene_extent = union_box(existing.scene_extent, scene_extent);
            self.write_file_atomic(&dir.join("meta.json"), &meta_json(&meta)?)?;
            Ok(meta)
        })();
        if result.is_err() {
            for f in written {
                let _ = fs::remove_file(f);
            }
        }
        result
    }

    /// Writes one step's grid as a new `step-*.f32` file in `dir` (fsynced).
    fn write_step(&self, dir: &Path, step: &FieldStep) -> Result<StepMeta, StoreError> {
        let r = &step.raster;
        let file = format!("step-{}.f32", nonce());
        let mut bytes = Vec::with_capacity(r.data.len() * 4);
        for &v in &r.data {
            // Stored as f32, the precision of GPU textures.
            let v = if r.is_valid(v) { v as f32 } else { f32::NAN };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        self.write_file_atomic(&dir.join(&file), &bytes)?;
        let (min, max) = r.valid_range().unwrap_or((f64::NAN, f64::NAN));
        let t = &r.transform;
        Ok(StepMeta {
            time: step.time.map(|t| format_time(&t)),
            file,
            width: r.width,
            height: r.height,
            transform: [t.origin_x, t.origin_y, t.cell_width, t.cell_height],
            min,
            max,
            valid_cells: r.valid_count() as u64,
        })
    }

    /// Writes `bytes` to `path` through a temporary file in the same directory, fsynced and
    /// renamed into place.
    fn write_file_atomic(&self, path: &Path, bytes: &[u8]) -> Result<(), StoreError> {
        let tmp = path.with_file_name(format!(
            ".{}.tmp-{}",
            path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default(),
            nonce()
        ));
        let result = (|| {
            let mut f = File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()?;
            fs::rename(&tmp, path)
        })();
        if result.is_err() {
            let _ = fs::remove_file(&tmp);
        }
        result.map_err(io_err(path))
    }

    /// Loads and checks a layer directory at open; removes files its meta does not list.
    fn load_layer_dir(&self, id: &str, dir: &Path) -> Result<LayerMeta, StoreError> {
        let corrupt = |message: String| StoreError::Corrupt { id: id.to_string(), message };
        if !valid_id(id) || !dir.is_dir() {
            return Err(corrupt("not a layer directory".into()));
        }
        let text = fs::read(dir.join("meta.json")).map_err(|e| corrupt(format!("meta.json: {e}")))?;
        let meta: LayerMeta = serde_json::from_slice(&text).map_err(|e| corrupt(format!("meta.json: {e}")))?;
        if meta.id != id || meta.format != STORE_FORMAT {
            return Err(corrupt(format!("meta.json is for layer {} (format {})", meta.id, meta.format)));
        }
        let mut listed = HashSet::from(["meta.json".to_string()]);
        for step in &meta.steps {
            if !valid_step_file(&step.file) {
                return Err(corrupt(format!("bad step file name {}", step.file)));
            }
            let len = fs::metadata(dir.join(&step.file)).map_err(|e| corrupt(format!("{}: {e}", step.file)))?.len();
            if Some(len) != step.width.checked_mul(step.height).and_then(|n| n.checked_mul(4)).map(|n| n as u64) {
                return Err(corrupt(format!(
                    "{} has {len} bytes for {} × {} cells",
                    step.file, step.width, step.height
                )));
            }
            listed.insert(step.file.clone());
        }
        for entry in fs::read_dir(dir).map_err(io_err(dir))? {
            let entry = entry.map_err(io_err(dir))?;
            let name = entry.file_name().to_string_lossy().to_string();
            if !listed.contains(&name) {
                warn!(layer = %id, file = %name, "removing a file left by an interrupted write");
                let _ = fs::remove_file(entry.path());
            }
        }
        Ok(meta)
    }

    /// Reads the steps of a stored layer back into a field.
    fn read_field(&self, meta: &LayerMeta) -> Result<Field, StoreError> {
        let corrupt = |message: String| StoreError::Corrupt { id: meta.id.clone(), message };
        let crs = CrsDefinition::from_proj_string(&meta.crs_definition).map_err(|e| corrupt(e.to_string()))?;
        let palette = class_palette(&meta.classes);
        let dir = self.layers_dir().join(&meta.id);
        let mut steps = Vec::with_capacity(meta.steps.len());
        for s in &meta.steps {
            let path = dir.join(&s.file);
            let bytes = fs::read(&path).map_err(io_err(&path))?;
            if Some(bytes.len()) != s.width.checked_mul(s.height).and_then(|n| n.checked_mul(4)) {
                return Err(corrupt(format!(
                    "{} has {} bytes for {} × {} cells",
                    s.file,
                    bytes.len(),
                    s.width,
                    s.height
                )));
            }
            let data = bytes.chunks_exact(4).map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))).collect();
            let time = s.time.as_deref().map(parse_time).transpose().map_err(|e| corrupt(e.to_string()))?;
            let [origin_x, origin_y, cell_width, cell_height] = s.transform;
            let raster = Raster {
                width: s.width,
                height: s.height,
                data,
                nodata: None,
                transform: GeoTransform { origin_x, origin_y, cell_width, cell_height },
                crs: crs.crs(),
                palette: palette.clone(),
            };
            steps.push(FieldStep { time, raster });
        }
        let mut field = Field::new(meta.kind, crs, meta.units.clone(), steps).map_err(|e| corrupt(e.to_string()))?;
        let names: BTreeMap<i64, String> =
            meta.classes.iter().filter_map(|c| Some((c.value, c.name.clone()?))).collect();
        field.set_class_names(&names).map_err(|e| corrupt(e.to_string()))?;
        Ok(field)
    }
}

/// The classes of a stored label series and of the steps added to it: counts summed, the
/// stored names and colours kept (new classes take the new steps' colours); more than
/// [`MAX_LABEL_CLASSES`] is an error.
fn merge_classes(stored: &[ClassInfo], added: &[ClassInfo]) -> Result<Vec<ClassInfo>, String> {
    let mut merged: BTreeMap<i64, ClassInfo> = stored.iter().map(|c| (c.value, c.clone())).collect();
    for class in added {
        merged
            .entry(class.value)
            .and_modify(|c| c.count += class.count)
            .or_insert_with(|| ClassInfo { name: None, ..class.clone() });
    }
    if merged.len() > MAX_LABEL_CLASSES {
        return Err(format!(
            "a label field may have at most {MAX_LABEL_CLASSES} classes ({} with these steps)",
            merged.len()
        ));
    }
    Ok(merged.into_values().collect())
}

/// A 256-entry palette from class colours (values 0…255), so label colours survive a reload.
fn class_palette(classes: &[ClassInfo]) -> Option<Vec<[u8; 3]>> {
    if classes.iter().all(|c| c.color.is_none()) {
        return None;
    }
    let mut palette = vec![[0u8; 3]; 256];
    for c in classes {
        if let (Some(color), Ok(i)) = (c.color, usize::try_from(c.value))
            && let Some(slot) = palette.get_mut(i)
        {
            *slot = color;
        }
    }
    Some(palette)
}

/// The union of two boxes `[min_x, min_y, max_x, max_y]`.
fn union(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])]
}

/// The union of two optional boxes.
fn union_box(a: Option<[f64; 4]>, b: Option<[f64; 4]>) -> Option<[f64; 4]> {
    match (a, b) {
        (Some(a), Some(b)) => Some(union(a, b)),
        (a, b) => a.or(b),
    }
}

/// Pretty JSON of a meta (NaN-free: serde_json refuses non-finite numbers).
fn meta_json(meta: &LayerMeta) -> Result<Vec<u8>, StoreError> {
    serde_json::to_vec_pretty(meta)
        .map_err(|e| StoreError::Corrupt { id: meta.id.clone(), message: format!("cannot serialise metadata: {e}") })
}

/// Trims and checks a layer name: 1–100 characters, no control characters.
fn check_name(name: &str) -> Result<String, StoreError> {
    let name = name.trim();
    let chars = name.chars().count();
    if chars == 0 || chars > 100 {
        return Err(StoreError::InvalidField {
            field: "name",
            message: format!("layer name must have 1–100 characters, has {chars}"),
        });
    }
    check_text("name", name, 100)?;
    Ok(name.to_string())
}

/// Checks a free-text upload field: at most `max` characters, no control characters (tabs,
/// newlines and escape sequences included).
fn check_text(field: &'static str, text: &str, max: usize) -> Result<(), StoreError> {
    let chars = text.chars().count();
    if chars > max {
        return Err(StoreError::InvalidField {
            field,
            message: format!("must have at most {max} characters, has {chars}"),
        });
    }
    if let Some(c) = text.chars().find(|c| c.is_control()) {
        return Err(StoreError::InvalidField {
            field,
            message: format!("must not contain control characters (found U+{:04X})", u32::from(c)),
        });
    }
    Ok(())
}

/// `1=Water,2=Developed` → {1: "Water", 2: "Developed"}.
fn parse_class_names(text: &str) -> Result<BTreeMap<i64, String>, StoreError> {
    text.split(',')
        .filter(|p| !p.trim().is_empty())
        .map(|pair| {
            let (v, n) = pair
                .split_once('=')
                .ok_or_else(|| StoreError::Invalid(format!("class name \"{}\" must read value=name", echo(pair))))?;
            let v: i64 = v
                .trim()
                .parse()
                .map_err(|_| StoreError::Invalid(format!("class value \"{}\" is not an integer", echo(v.trim()))))?;
            let n = check_name(n).map_err(|e| StoreError::Invalid(format!("classes: class {v}: {e}")))?;
            Ok((v, n))
        })
        .collect()
}

/// An id for `name` not yet in `index`: a slug of the name plus 8 hex digits of its hash.
/// Whether `v` is finite and within the range of `f32`, the precision of the step files and
/// of the renderer's textures and coordinates.
fn fits_f32(v: f64) -> bool {
    v.abs() <= f64::from(f32::MAX)
}

/// Refuses a field the store could write but not render or read back: valid values beyond
/// the `f32` range (they would become infinities in the step files) and an extent beyond it
/// (an absurd cell size such as 1e306).
fn check_representable(field: &Field, source: &str) -> Result<(), StoreError> {
    let source = echo(source);
    for step in field.steps() {
        if let Some((min, max)) = step.raster.valid_range()
            && let Some(v) = [min, max].into_iter().find(|v| !fits_f32(*v))
        {
            return Err(StoreError::Invalid(format!(
                "{source}: the value {v:e} is beyond the range of 32-bit floats (±{:e}) that layers are stored in",
                f32::MAX
            )));
        }
    }
    let e = field.extent();
    if ![e.min_x, e.min_y, e.max_x, e.max_y].into_iter().all(fits_f32) {
        return Err(StoreError::Invalid(format!(
            "{source}: the extent x {:e}…{:e}, y {:e}…{:e} (cell size × cells) is beyond the range of 32-bit floats",
            e.min_x, e.max_x, e.min_y, e.max_y
        )));
    }
    Ok(())
}

/// The id of a new layer named `name`: its slug and hash, with a counter appended while
/// `taken` says the id is in use.
fn unique_id(name: &str, taken: impl Fn(&str) -> bool) -> String {
    let mut slug = String::new();
    for c in name.chars().flat_map(char::to_lowercase) {
        if c.is_ascii_alphanumeric() {
            slug.push(c);
        } else if !slug.ends_with('-') && !slug.is_empty() {
            slug.push('-');
        }
        if slug.len() >= 40 {
            break;
        }
    }
    let slug = slug.trim_end_matches('-');
    let slug = if slug.is_empty() { "layer" } else { slug };
    // FNV-1a: stable across runs and platforms.
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    let base = format!("{slug}-{:08x}", hash as u32);
    let mut id = base.clone();
    let mut n = 2;
    while taken(&id) {
        id = format!("{base}-{n}");
        n += 1;
    }
    id
}

/// Whether `id` has the form of a layer id.
fn valid_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 64
        && id.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        && !id.starts_with('-')
}

/// Whether `name` has the form of a step file written by this store.
fn valid_step_file(name: &str) -> bool {
    name.strip_prefix("step-")
        .and_then(|r| r.strip_suffix(".f32"))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// A process-unique hex token for file names.
fn nonce() -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64);
    format!("{:016x}", nanos ^ (u64::from(std::process::id()) << 40) ^ n.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// Deletes everything inside `dir`.
fn clear_dir(dir: &Path) -> Result<(), StoreError> {
    for entry in fs::read_dir(dir).map_err(io_err(dir))? {
        let path = entry.map_err(io_err(dir))?.path();
        let removed = if path.is_dir() { fs::remove_dir_all(&path) } else { fs::remove_file(&path) };
        if let Err(e) = removed {
            warn!(path = %path.display(), error = %e, "cannot remove a leftover temporary file");
        }
    }
    Ok(())
}

/// Flushes a directory's entries (renames) to disk.
fn sync_dir(dir: &Path) -> Result<(), StoreError> {
    File::open(dir).and_then(|d| d.sync_all()).map_err(io_err(dir))
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io { path: path.to_path_buf(), source }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_path_safe() {
        let free = |_: &str| false;
        let id = unique_id("../../etc/passwd", free);
        assert!(id.starts_with("etc-passwd-") && valid_id(&id), "{id}");
        assert!(unique_id("Ünïcödé ☃", free).starts_with("n-c-d-"));
        assert!(unique_id("☃", free).starts_with("layer-"));
        assert_eq!(unique_id("a", free), unique_id("a", free));
        let first = unique_id("a", free);
        assert_eq!(unique_id("a", |id| id == first), format!("{first}-2"));
        assert!(!valid_id("../x") && !valid_id("") && !valid_id("A") && !valid_id("-x"));
        assert!(valid_step_file("step-00ff.f32") && !valid_step_file("step-.f32") && !valid_step_file("../step-1.f32"));
    }

    #[test]
    fn names_and_classes() {
        assert_eq!(check_name("  Air temperature ").unwrap(), "Air temperature");
        assert!(check_name("").is_err() && check_name("a\nb").is_err() && check_name(&"x".repeat(101)).is_err());
        let c = parse_class_names("1=Water, 2 = Developed,").unwrap();
        assert_eq!(c.get(&2).map(String::as_str), Some("Developed"));
        assert!(parse_class_names("x=Water").is_err() && parse_class_names("1").is_err());
    }

    #[test]
    fn statuses() {
        assert_eq!(StoreError::NotFound { id: "x".into() }.status(), 404);
        assert_eq!(StoreError::Conflict("x".into()).status(), 409);
        let big = FieldError::TooLarge { what: "x".into(), size: 2, limit: 1 };
        assert_eq!(StoreError::Field(big).status(), 413);
        assert_eq!(StoreError::Field(FieldError::Invalid("x".into())).status(), 422);
    }
}
