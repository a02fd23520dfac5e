//! Derives the Rio San Francisco valley sample scene (`data/rbsf/`, see `data/SOURCES.md`)
//! from the shared 10 m DEM of the valley:
//!
//! - `dem.tif`: the DEM as it is (Float32, NaN outside the mapped area).
//! - `landcover.tif`: a land cover on a 5 m grid in NLCD codes. No land-cover map of the
//!   valley ships with the data, so it is synthesised from the terrain the way the vegetation
//!   of this part of the Andes follows it (Ungerechts 2010; Beck et al. 2008, *Gradients in a
//!   tropical mountain ecosystem of Ecuador*): rivers along the terrain's valley lines that
//!   drain more than 30 ha (the drainage network of `prep::creases`),
//!   pastures on the valley floor and the lowest slopes, lower montane forest above them, upper
//!   montane ("elfin") forest from about 2,300 m, subpáramo shrub from about 2,800 m and páramo
//!   grass on the highest ridges, bare landslide scars on the steepest forested slopes, and
//!   bracken on parts of the pastures. A deterministic value noise breaks up the boundaries.
//! - `planned.tif`: the plan on the same grid: 1 = a planned native woodland on pasture,
//!   2 = a planned hedgerow across the pastures below it.
//!
//! Usage:
//!
//! ```text
//! cargo run --example make_valley_scene -- ../shared/data/ecuador_rbsf data/rbsf
//! ```

use glam::Vec2;
use landsketch::gis::{LocalFrame, Raster, load_raster, write_geotiff_f32, write_geotiff_u8};
use landsketch::prep::creases::{CreaseKind, crease_lines};
use landsketch::scene::terrain::Terrain;
use std::path::Path;

#[path = "common/landcover.rs"]
mod landcover;
use landcover::{DemSampler, Ground, fill, refined_grid, value_noise};

/// Land-cover classes (NLCD codes; the scene file names them for this valley).
const WATER: u8 = 11;
const BARREN: u8 = 31;
const LOWER_FOREST: u8 = 41;
const UPPER_FOREST: u8 = 43;
const SHRUB: u8 = 52;
const GRASS: u8 = 71;
const PASTURE: u8 = 81;
/// Classes of the planned state.
const PLANNED_WOODLAND: u8 = 1;
const PLANNED_HEDGEROW: u8 = 2;

/// Output cells per DEM cell along each axis (10 m → 5 m).
const REFINE: usize = 2;
/// Area drained (m²) from which a valley line of the terrain is a stream drawn as water.
const STREAM_AREA: f64 = 300_000.0;
/// A line along the main river (scene metres): pastures reach up the slopes on its
/// north-west side.
const PASTURE_SIDE: ((f64, f64), (f64, f64)) = ((-1425.0, 600.0), (-450.0, 1875.0));
/// A gallery forest lines the streams in the pastures: cells this far from one (metres).
const GALLERY: f64 = 25.0;
/// Half the width of the main river (the widest [`river_half_width`] gives).
const MAIN_RIVER_HALF_WIDTH: f64 = 6.0;
/// The planned woodland: an ellipse (centre, half axes in metres, scene frame).
const WOODLAND: ((f64, f64), (f64, f64)) = ((-1300.0, 1500.0), (260.0, 150.0));
/// The planned hedgerow: a line across the pastures below the woodland (scene metres) and its
/// width.
const HEDGE: ((f32, f32), (f32, f32)) = ((-1600.0, 1320.0), (-1020.0, 1300.0));
const HEDGE_WIDTH: f32 = 6.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (source, out_dir) = match &args[..] {
        [_, source, out] => (Path::new(source), Path::new(out)),
        _ => return Err("usage: make_valley_scene SHARED_ECUADOR_RBSF_DIR OUT_DIR".into()),
    };
    let dem = load_raster(&source.join("dem_10m.tif"))?;
    let ground = DemSampler { dem: &dem, frame: LocalFrame::for_raster(&dem)? };
    let frame = &ground.frame;
    let terrain = Terrain::new(dem.clone(), [0.5; 3])?;
    let rivers: Vec<(Vec2, Vec2, f64)> = crease_lines(&terrain)
        .into_iter()
        .filter(|s| s.kind == CreaseKind::Valley && s.measure >= STREAM_AREA)
        .map(|s| (s.a.truncate(), s.b.truncate(), river_half_width(s.measure)))
        .collect();
    let mut existing = refined_grid(&dem, REFINE);
    let mut planned = existing.clone();
    let transform = existing.transform;
    // Half the width of the widest river at (x, y), if one runs there.
    let river_at = |x: f64, y: f64| {
        let p = Vec2::new(x as f32, y as f32);
        rivers.iter().filter(|&&(a, b, half)| distance_to_segment(p, a, b) <= half as f32).map(|r| r.2).reduce(f64::max)
    };
    let river = |x: f64, y: f64| river_at(x, y).is_some();
    let stream = |x: f64, y: f64| river_at(x, y).is_some_and(|half| half < MAIN_RIVER_HALF_WIDTH);
    // Whether `water` lies `r` metres from (x, y) in one of 16 directions.
    let near = |water: &dyn Fn(f64, f64) -> bool, x: f64, y: f64, r: f64| {
        (0..16).any(|k| {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            water(x + r * a.cos(), y + r * a.sin())
        })
    };
    fill(&mut existing, frame, |x, y, _| {
        let Some(Ground { z, slope, .. }) = ground.ground(x, y, 20.0) else { return 0 };
        let noise = 0.65 * value_noise(x, y, 260.0, 1) + 0.35 * value_noise(x, y, 80.0, 2);
        let scars = value_noise(x, y, 70.0, 3);
        let bracken = value_noise(x, y, 120.0, 4);
        // Pastures: the valley floor, and the slopes north-west of the river up to about
        // 2,250 m, with a gallery forest along the streams and remnant patches of forest.
        let north_west = (PASTURE_SIDE.1.0 - PASTURE_SIDE.0.0) * (y - PASTURE_SIDE.0.1)
            - (PASTURE_SIDE.1.1 - PASTURE_SIDE.0.1) * (x - PASTURE_SIDE.0.0)
            > 0.0;
        let gallery = [0.5, 1.0].iter().any(|f| near(&stream, x, y, f * GALLERY));
        let remnant = value_noise(x, y, 150.0, 5) > 0.5;
        let pasture = slope < 35.0
            && !gallery
            && !remnant
            && (z < 1900.0 + 40.0 * noise || (north_west && z < 2250.0 + 50.0 * noise));
        if river(x, y) {
            WATER
        } else if z > 3010.0 + 60.0 * noise {
            GRASS
        } else if z > 2820.0 + 80.0 * noise {
            SHRUB
        } else if pasture {
            if bracken > 0.6 { SHRUB } else { PASTURE }
        } else if slope > 40.0 && scars > 0.55 {
            BARREN
        } else if z > 2300.0 + 100.0 * noise {
            UPPER_FOREST
        } else {
            LOWER_FOREST
        }
    });
    // The plan: a woodland on the pastures of the slope and a hedgerow across the pastures
    // below it (both only on pasture: the forest is not replanted).
    fill(&mut planned, frame, |x, y, index| {
        if existing.data[index] != f64::from(PASTURE) {
            return 0;
        }
        let ((wx, wy), (ax, ay)) = WOODLAND;
        let woodland = ((x - wx) / ax).powi(2) + ((y - wy) / ay).powi(2) < 1.0;
        let (a, b) = (Vec2::from(HEDGE.0), Vec2::from(HEDGE.1));
        let hedge = distance_to_segment(Vec2::new(x as f32, y as f32), a, b) <= 0.5 * HEDGE_WIDTH;
        if woodland {
            PLANNED_WOODLAND
        } else if hedge {
            PLANNED_HEDGEROW
        } else {
            0
        }
    });
    // Palettes: the NLCD legend colours of these classes, and the plan in warm colours.
    let mut existing_palette = vec![[0u8, 0, 0]; 256];
    for (code, rgb) in [
        (WATER, [70, 107, 159]),
        (BARREN, [179, 172, 159]),
        (LOWER_FOREST, [104, 171, 95]),
        (UPPER_FOREST, [181, 201, 142]),
        (SHRUB, [204, 184, 121]),
        (GRASS, [223, 223, 194]),
        (PASTURE, [220, 217, 57]),
    ] {
        existing_palette[usize::from(code)] = rgb;
    }
    let planned_palette = [[255, 255, 255], [214, 96, 77], [253, 174, 97]];
    std::fs::create_dir_all(out_dir)?;
    write_geotiff_f32(&out_dir.join("dem.tif"), &dem)?;
    write_geotiff_u8(&out_dir.join("landcover.tif"), &existing, Some(&existing_palette))?;
    write_geotiff_u8(&out_dir.join("planned.tif"), &planned, Some(&planned_palette))?;
    let hectares = |r: &Raster, c: u8| {
        r.data.iter().filter(|v| **v == f64::from(c)).count() as f64 * transform.cell_width.abs().powi(2) / 10_000.0
    };
    for (name, class) in [
        ("water", WATER),
        ("barren (landslides)", BARREN),
        ("lower montane forest", LOWER_FOREST),
        ("upper montane forest", UPPER_FOREST),
        ("shrub (subpáramo, bracken)", SHRUB),
        ("grass (páramo)", GRASS),
        ("pasture", PASTURE),
    ] {
        println!("existing {name:<28} {:>7.1} ha", hectares(&existing, class));
    }
    println!(
        "planned woodland {:.1} ha, hedgerow {:.2} ha",
        hectares(&planned, PLANNED_WOODLAND),
        hectares(&planned, PLANNED_HEDGEROW)
    );
    Ok(())
}

/// Half the width of a river draining `area` m² (a stream of 20 ha 2 m, the main river 6 m).
fn river_half_width(area: f64) -> f64 {
    (1.0 + 1.6 * (area / STREAM_AREA).log10()).min(MAIN_RIVER_HALF_WIDTH)
}

/// Distance from `p` to the segment `a`–`b`.
fn distance_to_segment(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
    p.distance(a + t * ab)
}
