//! GIS input: georeferenced rasters (GeoTIFF, ESRI ASCII grid), their CRS and the local
//! metric frame the scene lives in.

pub mod ascii_grid;
pub mod crs;
pub mod error;
pub mod frame;
pub mod geotiff;
pub mod raster;
pub mod reproject;

pub use ascii_grid::read_ascii_grid;
pub use crs::Crs;
pub use error::GisError;
pub use frame::LocalFrame;
pub use geotiff::{GeoKeyValues, read_geokeys, read_geotiff, write_geotiff_f32, write_geotiff_u8};
pub use raster::{Extent, GeoTransform, MAX_CELLS, Raster, load_raster};
pub use reproject::{CrsDefinition, ReprojectError, Transformer};
