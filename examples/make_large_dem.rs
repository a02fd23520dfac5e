//! Writes a large lidar-like DEM for the large-DEM benchmark (`BENCHMARKS.md`, "Large DEMs"):
//! `SIDE` × `SIDE` cells of 1 m in British National Grid (EPSG:27700) south of Kingston St
//! Mary, Float32 Deflate GeoTIFF: rolling hills (a few octaves of value noise on rotated
//! lattices, about 200 m of relief over kilometres), stream valleys cut along noise valleys, and the 0.1–1 m micro relief
//! of banks and furrows a 1 m lidar tile shows, so loading and decimating it does real work.
//!
//! Usage:
//!
//! ```text
//! cargo run --release --example make_large_dem -- /tmp/large/dem.tif 5000
//! ```

use landsketch::gis::{Crs, GeoTransform, Raster, write_geotiff_f32};
use landsketch::rng::mix;
use std::path::Path;

/// Value noise in 0..1 at (x, y) with lattice spacing `cell` and seed `seed`: a smoothstep
/// blend of hashed lattice values.
fn value_noise(x: f64, y: f64, cell: f64, seed: u64) -> f64 {
    let (gx, gy) = (x / cell, y / cell);
    let (ix, iy) = (gx.floor(), gy.floor());
    let (fx, fy) = (gx - ix, gy - iy);
    let lattice = |dx: f64, dy: f64| {
        let h = mix(seed ^ mix(((ix + dx) as i64 as u64) ^ mix((iy + dy) as i64 as u64)));
        (h >> 11) as f64 / (1u64 << 53) as f64
    };
    let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (smooth(fx), smooth(fy));
    let top = lattice(0.0, 0.0) * (1.0 - sx) + lattice(1.0, 0.0) * sx;
    let bottom = lattice(0.0, 1.0) * (1.0 - sx) + lattice(1.0, 1.0) * sx;
    top * (1.0 - sy) + bottom * sy
}

/// Height in metres at (x, y) metres from the tile's north-west corner.
fn height(x: f64, y: f64) -> f64 {
    // Each octave on its own rotated lattice, so no ridge runs along a lattice line.
    let rotated = |angle: f64| (x * angle.cos() - y * angle.sin(), x * angle.sin() + y * angle.cos());
    let hills: f64 = [(1600.0, 140.0), (700.0, 45.0), (260.0, 12.0), (90.0, 2.5)]
        .iter()
        .enumerate()
        .map(|(i, &(cell, amp))| {
            let (u, v) = rotated(0.7 + 1.3 * i as f64);
            amp * value_noise(u, v, cell, i as u64)
        })
        .sum();
    // Streams where a broad noise field crosses its middle: valleys up to 6 m deep.
    let channel = (value_noise(x, y, 1100.0, 9) - 0.5).abs();
    let valley = 6.0 * (1.0 - (channel / 0.06).min(1.0)).powi(2);
    // Field banks every 120 m east-west and furrows every 6 m (tens of centimetres).
    let banks = 0.8 * (1.0 - ((y % 120.0) - 60.0).abs() / 3.0).max(0.0);
    let furrows = 0.08 * (std::f64::consts::TAU * x / 6.0).sin();
    let texture = 0.3 * value_noise(x, y, 7.0, 11);
    20.0 + hills - valley + banks + furrows + texture
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (out, side) = match &args[..] {
        [_, out, side] => (Path::new(out), side.parse::<usize>()?),
        _ => return Err("usage: make_large_dem OUT.tif SIDE".into()),
    };
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let dem = Raster {
        width: side,
        height: side,
        data: (0..side * side).map(|i| height((i % side) as f64 + 0.5, (i / side) as f64 + 0.5)).collect(),
        nodata: None,
        transform: GeoTransform { origin_x: 320_000.0, origin_y: 130_000.0, cell_width: 1.0, cell_height: 1.0 },
        crs: Crs::Projected { epsg: Some(27700), unit_to_metre: 1.0 },
        palette: None,
    };
    write_geotiff_f32(out, &dem)?;
    println!("{}: {side} × {side} cells of 1 m in EPSG:27700", out.display());
    Ok(())
}
