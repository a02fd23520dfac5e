//! landsketch: GIS landscapes (terrain + plants) rendered offscreen with wgpu as pen-and-ink
//! sketches.
//!
//! Data flows one way: [`gis`] (rasters, CRS, DEM, land cover) → [`scene`] (terrain mesh,
//! plant models, vegetation placement, scene file, camera parameters) → [`prep`] → [`render`]
//! (device, G-buffer pass, post passes, styles, image formats) → [`api`] (HTTP and WebSocket,
//! which maps the domain's errors to status codes). Environment data layers: [`fields`]
//! (scalar/label fields, time series, reprojection onto the scene, colour maps, legends,
//! mappings) kept by [`store`], which also checks the data layers a view asks for. No module
//! but `api` knows HTTP; the CLI calls the same domain functions as the server.

pub mod api;
pub mod bench;
pub mod echo;
pub mod fields;
pub mod gis;
pub mod prep;
pub mod progress;
pub mod render;
pub mod rng;
pub mod scene;
pub mod srgb;
pub mod store;
