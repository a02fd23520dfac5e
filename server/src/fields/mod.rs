//! Environment data fields (SPEC D, thesis ch. 9): scalar and label fields on georeferenced
//! grids, time series, reprojection onto the scene, colour maps, legends and mappings.
//!
//! Data flows: a file ([`source`]: GeoTIFF, ESRI ASCII grid, NetCDF-3, or several timestamped
//! rasters) → a [`Field`] in its own CRS with one or more time steps ([`field`], [`series`]) →
//! for a time t and a scene ([`SceneGeo`]), a [`FieldGrid`] in scene metres ([`reproject`]) →
//! a colour look-up table ([`colormap`]), a legend ([`legend`]) and checked mappings onto
//! visual features ([`mapping`], Table 9.1).
//!
//! The renderer's path for one layer at time `t`:
//!
//! ```no_run
//! # use landsketch::fields::*;
//! # fn demo(field: &Field, scene: &SceneGeo) -> Result<(), FieldError> {
//! let t = parse_time("1999-03-15")?;
//! let spec = field.default_grid_spec(scene)?;
//! let (grid, sample) = field.grid_at(Some(t), scene, &spec)?; // eq. 9.4 applied, NaN = nodata
//! let lut = Lut::for_field(&ColorMapSpec::default(), field)?; // 256 RGBA entries
//! let uv = grid.uv_transform(); // scene (x, y) → texture (u, v)
//! # let _ = (grid, sample, lut, uv); Ok(()) }
//! ```

pub mod colormap;
pub mod field;
pub mod legend;
pub mod mapping;
pub mod netcdf;
pub mod reproject;
pub mod series;
pub mod source;

pub use colormap::{ColorMapName, ColorMapSpec, LUT_SIZE, Lut};
pub use field::{ClassInfo, Field, FieldKind, FieldStep, MAX_LABEL_CLASSES};
pub use legend::Legend;
pub use mapping::{
    HATCH_COLORS, MAX_MAPPINGS, Mapping, MappingTarget, MappingWarning, Severity, Suitability, validate_mappings,
};
pub use reproject::{FieldGrid, GridSpec, SceneGeo};
pub use series::{Clamp, TimeSample, format_time, parse_time};
pub use source::{FieldFormat, LoadOptions, load_bytes, load_file, load_series};

use crate::gis::{GisError, ReprojectError};

/// Why a field could not be loaded, combined or placed in the scene.
#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    /// A raster file could not be read (malformed, truncated, unsupported sample type, …).
    #[error(transparent)]
    Gis(#[from] GisError),
    /// The CRS is missing, unsupported or invalid.
    #[error(transparent)]
    Crs(#[from] ReprojectError),
    /// Malformed input that is not a raster error (NetCDF structure, unknown format, …).
    #[error("{}: {message}", crate::echo::echo(.context))]
    Format {
        /// The file or part concerned.
        context: String,
        /// What is wrong.
        message: String,
    },
    /// The input is larger than a limit (cells, bytes, time steps).
    #[error("{what} is too large: {size} exceeds the limit of {limit}")]
    TooLarge {
        /// What was measured, e.g. "raster of 50000 × 50000 cells".
        what: String,
        /// The size found.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// The field does not overlap the scene; both extents are named.
    #[error("the field does not overlap the scene: field extent {field}; scene extent {scene}")]
    NoOverlap {
        /// The field's extent, in its CRS and in scene metres.
        field: String,
        /// The scene's extent, in its CRS and in scene metres.
        scene: String,
    },
    /// A timestamp that is not ISO 8601 or CF time that cannot be converted.
    #[error("invalid time \"{}\": {reason}", crate::echo::echo(.text))]
    Time {
        /// The text as given.
        text: String,
        /// Why it was rejected.
        reason: String,
    },
    /// Valid input that does not make a valid field: label values that are not integers, too
    /// many classes, duplicate time steps, mixing kinds or CRSs in one series, bad options.
    #[error("{0}")]
    Invalid(String),
}

impl FieldError {
    /// Whether the error is about size (cells, bytes, steps), so that an HTTP layer can answer
    /// 413 instead of 422.
    pub fn is_too_large(&self) -> bool {
        matches!(self, FieldError::TooLarge { .. } | FieldError::Gis(GisError::TooLarge { .. }))
    }
}
