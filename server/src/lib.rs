//! landsketch: GIS landscapes (terrain + plants) rendered offscreen with wgpu as pen-and-ink
//! sketches.
//!
//! Data flows one way: [`gis`] (rasters, CRS, DEM, land cover) → [`scene`] (terrain mesh,
//! plant models, vegetation placement, scene file) → [`render`] (device, G-buffer pass, post
//! passes, style).

pub mod gis;
pub mod render;
pub mod scene;
