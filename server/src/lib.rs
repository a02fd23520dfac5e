//! landsketch: GIS landscapes (terrain + plants) rendered offscreen with wgpu as pen-and-ink
//! sketches.
//!
//! Data flows one way: [`gis`] (rasters, CRS, DEM, land cover) → [`scene`] (terrain mesh,
//! plant models, vegetation placement, scene file) → [`render`] (device, G-buffer pass, post
//! passes, style). Environment data layers: [`fields`] (scalar/label fields, time series,
//! reprojection onto the scene, colour maps, legends, mappings) kept by [`store`].

pub mod api;
pub mod bench;
pub mod fields;
pub mod gis;
pub mod prep;
pub mod render;
pub mod rng;
pub mod scene;
pub mod store;
