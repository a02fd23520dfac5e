//! Synthesises the sample scene's data layers (thesis ch. 9; see `data/SOURCES.md`):
//!
//! - `fire_hazard.tif`: a label field of wildfire hazard classes on the land-cover grid, from
//!   the terrain and the fuel: fire runs faster uphill (slope), south- and west-facing slopes
//!   are drier, forest and shrubland carry more fuel than grass, bare rock does not burn.
//!   Classes 1 low, 2 moderate, 3 high, 4 extreme (8-bit palette GeoTIFF, 0 = nodata).
//! - `plume/plume_<time>.tif`: a scalar time series of 8 hourly steps of a spreading pollution
//!   plume (µg/m³): a Gaussian puff released at a point in the valley, carried east-north-east
//!   by the wind and widening with time (σ = σ₀ + k·t), each step a Float32 GeoTIFF.
//!
//! Usage:
//!
//! ```text
//! cargo run --example make_sample_data -- data/boulder
//! ```

use landsketch::gis::{LocalFrame, Raster, load_raster, write_geotiff_f32, write_geotiff_u8};
use std::path::Path;

/// Land-cover classes of `landcover.tif` (see `make_sample_landcover`).
const BARREN: f64 = 3.0;
const FOREST: f64 = 4.0;
const SHRUBLAND: f64 = 5.0;

/// Plume source in scene metres, wind velocity in m per hour, initial spread and growth.
const SOURCE: (f64, f64) = (-450.0, -250.0);
const WIND: (f64, f64) = (170.0, 70.0);
const SIGMA0: f64 = 60.0;
const SIGMA_GROWTH: f64 = 45.0;
/// Peak concentration of the first step in µg/m³ (the puff's mass is conserved after it).
const PEAK: f64 = 120.0;
/// Hourly steps from 2024-07-01 12:00 UTC.
const STEPS: usize = 8;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let dir = match &args[..] {
        [_, dir] => Path::new(dir),
        _ => return Err("usage: make_sample_data SCENE_DIR (with dem.tif and landcover.tif)".into()),
    };
    let dem = load_raster(&dir.join("dem.tif"))?;
    let cover = load_raster(&dir.join("landcover.tif"))?;
    let frame = LocalFrame::for_raster(&dem)?;
    let height = |x: f64, y: f64| {
        let (cx, cy) = frame.to_crs(x, y);
        dem.sample_bilinear(cx, cy)
    };

    let mut hazard = Raster { data: vec![0.0; cover.width * cover.height], nodata: Some(0.0), ..cover.clone() };
    for row in 0..cover.height {
        for col in 0..cover.width {
            let i = row * cover.width + col;
            let (cx, cy) = cover.cell_center(col, row);
            let (x, y) = frame.to_local(cx, cy);
            let (Some(e), Some(w), Some(n), Some(s)) =
                (height(x + 30.0, y), height(x - 30.0, y), height(x, y + 30.0), height(x, y - 30.0))
            else {
                continue;
            };
            let fuel = match cover.data[i] {
                c if c == FOREST => 0.45,
                c if c == SHRUBLAND => 0.35,
                c if c == BARREN => -2.0,
                c if cover.nodata == Some(c) => continue,
                _ => 0.15,
            };
            let (gx, gy) = ((e - w) / 60.0, (n - s) / 60.0);
            let slope = gx.hypot(gy).atan().to_degrees();
            // The downhill direction is the aspect; +1 facing south-west (dry), -1 north-east.
            let len = gx.hypot(gy).max(1e-9);
            let dry = (gx + gy) / len * std::f64::consts::FRAC_1_SQRT_2;
            let score = fuel + slope / 45.0 + 0.25 * dry;
            hazard.data[i] = match score {
                s if s < 0.55 => 1.0,
                s if s < 0.75 => 2.0,
                s if s < 0.95 => 3.0,
                _ => 4.0,
            };
        }
    }
    let palette = [[0, 0, 0], [120, 190, 90], [240, 210, 80], [240, 130, 40], [200, 30, 30]];
    write_geotiff_u8(&dir.join("fire_hazard.tif"), &hazard, Some(&palette))?;

    // The plume on the DEM's area with 1″ cells (as the land cover).
    let plume_dir = dir.join("plume");
    std::fs::create_dir_all(&plume_dir)?;
    let grid = Raster { data: vec![0.0; cover.width * cover.height], nodata: None, palette: None, ..cover.clone() };
    for step in 0..STEPS {
        let t = step as f64;
        let sigma = SIGMA0 + SIGMA_GROWTH * t;
        let (px, py) = (SOURCE.0 + WIND.0 * t, SOURCE.1 + WIND.1 * t);
        let peak = PEAK * (SIGMA0 / sigma).powi(2);
        let mut raster = grid.clone();
        for row in 0..raster.height {
            for col in 0..raster.width {
                let (cx, cy) = raster.cell_center(col, row);
                let (x, y) = frame.to_local(cx, cy);
                let r2 = (x - px).powi(2) + (y - py).powi(2);
                raster.data[row * raster.width + col] = peak * (-r2 / (2.0 * sigma * sigma)).exp();
            }
        }
        write_geotiff_f32(&plume_dir.join(format!("plume_2024-07-01T{:02}.tif", 12 + step)), &raster)?;
    }
    println!("wrote {} and {} plume steps in {}", dir.join("fire_hazard.tif").display(), STEPS, plume_dir.display());
    Ok(())
}
