//! What the examples that synthesise sample land covers share: a grid finer than the DEM, the
//! terrain read at a point of the scene frame, one pass over the grid's cells, and a
//! deterministic value noise that breaks up class boundaries. (Each example uses a subset.)
#![allow(dead_code)]

use landsketch::gis::{GeoTransform, LocalFrame, Raster};

/// The terrain at a point: height, slope and which way it faces.
pub struct Ground {
    pub z: f64,
    /// Degrees.
    pub slope: f64,
    /// +1 where the ground falls away to the north, −1 where it faces south.
    pub northness: f64,
}

/// A DEM read in its scene frame (metres about its centre).
pub struct DemSampler<'a> {
    pub dem: &'a Raster,
    pub frame: LocalFrame,
}

impl DemSampler<'_> {
    /// The height at (x, y), bilinear; `None` on nodata.
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let (cx, cy) = self.frame.to_crs(x, y);
        self.dem.sample_bilinear(cx, cy)
    }

    /// Height, slope and aspect at (x, y) from central differences over `d` metres each way;
    /// `None` where a sample is nodata.
    pub fn ground(&self, x: f64, y: f64, d: f64) -> Option<Ground> {
        let z = self.height(x, y)?;
        let (e, w) = (self.height(x + d, y)?, self.height(x - d, y)?);
        let (n, s) = (self.height(x, y + d)?, self.height(x, y - d)?);
        let (gx, gy) = ((e - w) / (2.0 * d), (n - s) / (2.0 * d));
        let steepness = gx.hypot(gy);
        let northness = if steepness > 1e-6 { -gy / steepness } else { 0.0 };
        Some(Ground { z, slope: steepness.atan().to_degrees(), northness })
    }
}

/// An empty class grid (nodata 0) over the DEM's extent, `refine` cells per DEM cell along
/// each axis.
pub fn refined_grid(dem: &Raster, refine: usize) -> Raster {
    let (width, height) = (dem.width * refine, dem.height * refine);
    let transform = GeoTransform {
        cell_width: dem.transform.cell_width / refine as f64,
        cell_height: dem.transform.cell_height / refine as f64,
        ..dem.transform
    };
    Raster { width, height, data: vec![0.0; width * height], nodata: Some(0.0), transform, crs: dem.crs, palette: None }
}

/// Sets every cell of `grid` to `class(x, y, index)`: the class at the cell's centre (scene
/// metres of `frame`), `index` the cell's index in `grid.data`.
pub fn fill(grid: &mut Raster, frame: &LocalFrame, mut class: impl FnMut(f64, f64, usize) -> u8) {
    for row in 0..grid.height {
        for col in 0..grid.width {
            let (cx, cy) = grid.cell_center(col, row);
            let (x, y) = frame.to_local(cx, cy);
            let index = row * grid.width + col;
            grid.data[index] = f64::from(class(x, y, index));
        }
    }
}

/// A hash of a grid point and a seed, uniform in [0, 1).
fn hash(i: i64, j: i64, seed: u64) -> f64 {
    let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ seed;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [-1, 1] with features about `scale` metres across.
pub fn value_noise(x: f64, y: f64, scale: f64, seed: u64) -> f64 {
    let (fx, fy) = (x / scale, y / scale);
    let (i, j) = (fx.floor() as i64, fy.floor() as i64);
    let (tx, ty) = (fx - fx.floor(), fy - fy.floor());
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * s(t);
    let top = lerp(hash(i, j, seed), hash(i + 1, j, seed), tx);
    let bottom = lerp(hash(i, j + 1, seed), hash(i + 1, j + 1, seed), tx);
    2.0 * lerp(top, bottom, ty) - 1.0
}
