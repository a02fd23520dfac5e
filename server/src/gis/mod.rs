//! GIS input: georeferenced rasters (GeoTIFF, ESRI ASCII grid) and vector plans (GeoJSON,
//! CSV), their CRS, reprojection into the scene's CRS and the local metric frame the scene
//! lives in.

pub mod ascii_grid;
pub mod crs;
pub mod dem;
pub mod dequantize;
pub mod error;
pub mod frame;
pub mod geotiff;
pub mod raster;
pub mod reproject;
pub mod vector;
pub mod warp;

pub use ascii_grid::read_ascii_grid;
pub use crs::Crs;
pub use dem::load_dem;
pub use error::GisError;
pub use frame::LocalFrame;
pub use geotiff::{
    GeoKeyValues, read_geokeys, read_geotiff, read_geotiff_bands, write_geotiff_f32, write_geotiff_rgb16,
    write_geotiff_u8,
};
pub use raster::{Extent, GeoTransform, MAX_CELLS, Raster, load_raster};
pub use reproject::{CrsDefinition, ReprojectError, Transformer};
pub use vector::{SceneFeature, SceneTarget, VectorError, read_vector};
pub use warp::{bands_in, file_definition, load_raster_in, warp_nearest};
