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

use landsketch::gis::{LocalFrame, Raster, load_raster, write_geotiff_u8};
use std::path::Path;

#[path = "common/landcover.rs"]
mod landcover;
use landcover::{DemSampler, Ground, fill, refined_grid, value_noise};

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
    let ground = DemSampler { dem: &dem, frame: LocalFrame::for_raster(&dem)? };
    let frame = &ground.frame;
    let mut existing = refined_grid(&dem, REFINE);
    let mut planned = existing.clone();
    fill(&mut existing, frame, |x, y, _| {
        let Some(Ground { z, slope, northness }) = ground.ground(x, y, 30.0) else { return 0 };
        let noise = 0.65 * value_noise(x, y, 180.0, 1) + 0.35 * value_noise(x, y, 60.0, 2);
        let score = 0.8 * northness * (slope / 20.0).min(1.0) + 0.0012 * (z - 2350.0) + 0.7 * noise;
        if slope > 38.0 {
            BARREN
        } else if score > 0.2 {
            FOREST
        } else if score > -0.2 {
            SHRUBLAND
        } else {
            HERBACEOUS
        }
    });
    // The plan: a woodland patch on open ground and a hedgerow along a line, both in scene
    // metres about the origin (see data/boulder/scene.toml for the camera looking at them).
    fill(&mut planned, frame, |x, y, index| {
        let open = existing.data[index] != f64::from(FOREST);
        let patch = ((x + 290.0) / 110.0).powi(2) + ((y - 190.0) / 70.0).powi(2) < 1.0;
        let hedge = (y - (70.0 + 0.3 * x)).abs() < 8.0 && (-470.0..-80.0).contains(&x);
        match (open, patch, hedge) {
            (true, true, _) => PLANNED_WOODLAND,
            (true, false, true) => PLANNED_HEDGEROW,
            _ => 0,
        }
    });
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
