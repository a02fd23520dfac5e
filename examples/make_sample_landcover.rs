//! Derives the sample scene's land-cover rasters from its DEM (see `data/SOURCES.md`).
//!
//! No real land-cover map shares the Boulder DEM's area, so this synthesises a plausible one
//! from terrain alone, the way Front Range vegetation follows it: conifer forest on
//! north-facing and higher slopes, shrubland in between, grassland on south-facing slopes and
//! valley floors, bare rock where it is steep; a deterministic value noise breaks up the
//! boundaries. It also writes the `planned` layer's raster: a planned woodland patch and a
//! hedgerow. Usage:
//!
//! ```text
//! cargo run --example make_sample_landcover -- data/boulder/dem.tif data/boulder
//! ```

use landsketch::gis::{GeoTransform, LocalFrame, Raster, load_raster, write_geotiff_u8};
use std::path::Path;

#[path = "common/noise.rs"]
mod noise;
use noise::value_noise;

/// Land-cover classes of the existing state (NLCD-like simplified codes).
const BARREN: u8 = 3;
const FOREST: u8 = 4;
const SHRUBLAND: u8 = 5;
const HERBACEOUS: u8 = 6;
/// Classes of the planned state.
const PLANNED_WOODLAND: u8 = 1;
const PLANNED_HEDGEROW: u8 = 2;

/// Output cells per DEM cell along each axis.
const REFINE: usize = 3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (dem_path, out_dir) = match &args[..] {
        [_, dem, out] => (Path::new(dem), Path::new(out)),
        _ => return Err("usage: make_sample_landcover DEM.tif OUT_DIR".into()),
    };
    let dem = load_raster(dem_path)?;
    let frame = LocalFrame::for_raster(&dem)?;
    let (w, h) = (dem.width * REFINE, dem.height * REFINE);
    let transform = GeoTransform {
        origin_x: dem.transform.origin_x,
        origin_y: dem.transform.origin_y,
        cell_width: dem.transform.cell_width / REFINE as f64,
        cell_height: dem.transform.cell_height / REFINE as f64,
    };
    let blank =
        Raster { width: w, height: h, data: vec![0.0; w * h], nodata: None, transform, crs: dem.crs, palette: None };
    let mut existing = Raster { nodata: Some(0.0), ..blank.clone() };
    let mut planned = Raster { nodata: Some(0.0), ..blank };
    let height = |x: f64, y: f64| {
        let (cx, cy) = frame.to_crs(x, y);
        dem.sample_bilinear(cx, cy)
    };
    for row in 0..h {
        for col in 0..w {
            let (cx, cy) = existing.cell_center(col, row);
            let (x, y) = frame.to_local(cx, cy);
            let (Some(z), Some(e), Some(wst), Some(n), Some(s)) =
                (height(x, y), height(x + 30.0, y), height(x - 30.0, y), height(x, y + 30.0), height(x, y - 30.0))
            else {
                continue;
            };
            let (gx, gy) = ((e - wst) / 60.0, (n - s) / 60.0);
            let slope = gx.hypot(gy).atan().to_degrees();
            // +1 where the ground falls away to the north (shaded, moist), -1 facing south.
            let northness = if gx.hypot(gy) > 1e-6 { -gy / gx.hypot(gy) } else { 0.0 };
            let noise = 0.65 * value_noise(x, y, 180.0, 1) + 0.35 * value_noise(x, y, 60.0, 2);
            let score = 0.8 * northness * (slope / 20.0).min(1.0) + 0.0012 * (z - 2350.0) + 0.7 * noise;
            existing.data[row * w + col] = f64::from(if slope > 38.0 {
                BARREN
            } else if score > 0.2 {
                FOREST
            } else if score > -0.2 {
                SHRUBLAND
            } else {
                HERBACEOUS
            });
        }
    }
    // The plan: a woodland patch on open ground and a hedgerow along a line, both in scene
    // metres about the origin (see data/boulder/scene.toml for the camera looking at them).
    for row in 0..h {
        for col in 0..w {
            let (cx, cy) = planned.cell_center(col, row);
            let (x, y) = frame.to_local(cx, cy);
            let open = existing.data[row * w + col] != f64::from(FOREST);
            let patch = ((x + 290.0) / 110.0).powi(2) + ((y - 190.0) / 70.0).powi(2) < 1.0;
            let hedge = (y - (70.0 + 0.3 * x)).abs() < 8.0 && (-470.0..-80.0).contains(&x);
            planned.data[row * w + col] = f64::from(match (open, patch, hedge) {
                (true, true, _) => PLANNED_WOODLAND,
                (true, false, true) => PLANNED_HEDGEROW,
                _ => 0,
            });
        }
    }
    let existing_palette = [
        [0, 0, 0],
        [70, 107, 159],
        [222, 197, 197],
        [179, 172, 159],
        [56, 129, 78],
        [204, 184, 121],
        [223, 223, 194],
        [220, 217, 57],
        [184, 217, 235],
    ];
    let planned_palette = [[255, 255, 255], [214, 96, 77], [253, 174, 97]];
    std::fs::create_dir_all(out_dir)?;
    write_geotiff_u8(&out_dir.join("landcover.tif"), &existing, Some(&existing_palette))?;
    write_geotiff_u8(&out_dir.join("planned.tif"), &planned, Some(&planned_palette))?;
    let count = |r: &Raster, c: u8| r.data.iter().filter(|v| **v == f64::from(c)).count();
    for (name, class) in [("barren", BARREN), ("forest", FOREST), ("shrubland", SHRUBLAND), ("herbaceous", HERBACEOUS)]
    {
        println!("existing {name:<10} {:>6} cells", count(&existing, class));
    }
    println!(
        "planned woodland {} cells, hedgerow {} cells",
        count(&planned, PLANNED_WOODLAND),
        count(&planned, PLANNED_HEDGEROW)
    );
    Ok(())
}
