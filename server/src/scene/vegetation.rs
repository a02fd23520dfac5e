//! Vegetation placement from a categorical land-cover raster and per-class rules (SPEC S2).
//!
//! For each rule a jittered grid with one candidate per `10 000 / density` m² is laid over the
//! terrain; a candidate becomes a plant when the land-cover class under it matches the rule,
//! the terrain has a height there and no plant of the layer stands closer than the rule's
//! minimum spacing. Every random number is a hash of (seed, rule, grid cell), so placement is
//! deterministic for a seed and independent of the order anything is evaluated in.

use super::SceneError;
use super::terrain::Terrain;
use crate::gis::{LocalFrame, Raster};
use crate::rng::{SplitMix64, mix};
use std::collections::HashMap;

/// One plant of a vegetation layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantInstance {
    /// Index into the scene's species list.
    pub species: usize,
    /// Base of the trunk in scene metres (on the terrain).
    pub position: [f32; 3],
    /// Rotation about the vertical axis in radians.
    pub rotation: f32,
    /// Uniform scale applied to the species' model.
    pub scale: f32,
}

/// A placement rule: plants of `species` on cells of land-cover `class`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacementRule {
    pub class: i64,
    pub species: usize,
    /// Target density in plants per hectare.
    pub density_per_ha: f64,
    /// No two plants of the layer stand closer than this (metres).
    pub min_spacing: f64,
    /// Range the uniform scale is drawn from.
    pub scale: [f32; 2],
}

/// Four uniform numbers in [0, 1) for grid cell `(i, j)` of rule `rule`.
fn cell_random(seed: u64, rule: usize, i: i64, j: i64) -> [f64; 4] {
    let mut rng = SplitMix64::new(mix(seed ^ mix(rule as u64 ^ mix(i as u64 ^ mix(j as u64)))));
    std::array::from_fn(|_| rng.unit_f64())
}

/// Points placed so far, bucketed for minimum-spacing queries.
struct SpacingGrid {
    cell: f64,
    buckets: HashMap<(i64, i64), Vec<[f64; 2]>>,
}

impl SpacingGrid {
    fn key(&self, p: [f64; 2]) -> (i64, i64) {
        ((p[0] / self.cell).floor() as i64, (p[1] / self.cell).floor() as i64)
    }

    fn is_free(&self, p: [f64; 2], spacing: f64) -> bool {
        let (kx, ky) = self.key(p);
        let reach = (spacing / self.cell).ceil() as i64;
        (kx - reach..=kx + reach).all(|x| {
            (ky - reach..=ky + reach).all(|y| {
                self.buckets
                    .get(&(x, y))
                    .is_none_or(|pts| pts.iter().all(|q| (q[0] - p[0]).hypot(q[1] - p[1]) >= spacing))
            })
        })
    }

    fn insert(&mut self, p: [f64; 2]) {
        self.buckets.entry(self.key(p)).or_default().push(p);
    }
}

/// Places the plants of one layer. `landcover` must be in the same CRS as the terrain's DEM
/// (the scene loader reprojects it); more than `max_plants` plants is an error rather than a
/// silent truncation.
pub fn place(
    terrain: &Terrain,
    landcover: &Raster,
    rules: &[PlacementRule],
    seed: u64,
    max_plants: usize,
) -> Result<Vec<PlantInstance>, SceneError> {
    place_reporting(terrain, landcover, rules, seed, max_plants, &|_| {})
}

/// [`place`], telling `progress` the share of the layer done (0 to 1, rising; a forest of a
/// million plants takes seconds).
pub fn place_reporting(
    terrain: &Terrain,
    landcover: &Raster,
    rules: &[PlacementRule],
    seed: u64,
    max_plants: usize,
    progress: &dyn Fn(f32),
) -> Result<Vec<PlantInstance>, SceneError> {
    check_same_crs(&terrain.frame, landcover)?;
    let (lo, hi) = terrain.bounds();
    let class_at = |p: [f64; 2]| {
        let (cx, cy) = terrain.frame.to_crs(p[0], p[1]);
        landcover.sample_nearest(cx, cy).map(|c| c.round() as i64)
    };
    place_in(terrain, (lo, hi), &class_at, rules, seed, max_plants, progress)
}

/// [`place_reporting`] with the class under a scene point given by `class_at` (a land cover,
/// a polygon) and candidates only within `bounds` (scene metres, e.g. a polygon's box).
pub fn place_in(
    terrain: &Terrain,
    bounds: ([f64; 2], [f64; 2]),
    class_at: &dyn Fn([f64; 2]) -> Option<i64>,
    rules: &[PlacementRule],
    seed: u64,
    max_plants: usize,
    progress: &dyn Fn(f32),
) -> Result<Vec<PlantInstance>, SceneError> {
    let (lo, hi) = bounds;
    let mut grid =
        SpacingGrid { cell: rules.iter().map(|r| r.min_spacing).fold(1.0, f64::max), buckets: HashMap::new() };
    let mut plants = Vec::new();
    for (rule_index, rule) in rules.iter().enumerate() {
        if !(rule.density_per_ha > 0.0 && rule.density_per_ha.is_finite()) {
            continue;
        }
        let step = (10_000.0 / rule.density_per_ha).sqrt();
        let (i0, i1) = ((lo[0] / step).floor() as i64, (hi[0] / step).ceil() as i64);
        let (j0, j1) = ((lo[1] / step).floor() as i64, (hi[1] / step).ceil() as i64);
        let candidates = (i1 - i0 + 1).saturating_mul(j1 - j0 + 1);
        if candidates > (max_plants as i64).saturating_mul(1000) {
            return Err(SceneError::Invalid(format!(
                "rule for class {} would test {candidates} candidate positions; lower its density ({} plants/ha)",
                rule.class, rule.density_per_ha
            )));
        }
        let mut reported = -1;
        for j in j0..=j1 {
            // Whole percents of the layer, so a bar is not redrawn per row.
            let done = (rule_index as f64 + (j - j0) as f64 / (j1 - j0 + 1) as f64) / rules.len() as f64;
            if (done * 100.0) as i32 > reported {
                reported = (done * 100.0) as i32;
                progress(done as f32);
            }
            for i in i0..=i1 {
                let [u, v, r, s] = cell_random(seed, rule_index, i, j);
                let p = [(i as f64 + u) * step, (j as f64 + v) * step];
                if !(lo[0]..=hi[0]).contains(&p[0]) || !(lo[1]..=hi[1]).contains(&p[1]) {
                    continue;
                }
                if class_at(p) != Some(rule.class) {
                    continue;
                }
                let Some(z) = terrain.height_at(p[0], p[1]) else { continue };
                if !grid.is_free(p, rule.min_spacing) {
                    continue;
                }
                grid.insert(p);
                if plants.len() == max_plants {
                    return Err(SceneError::Invalid(format!(
                        "more than {max_plants} plants would be placed; lower the densities or raise max_plants"
                    )));
                }
                plants.push(PlantInstance {
                    species: rule.species,
                    position: [p[0] as f32, p[1] as f32, z as f32],
                    rotation: (r * std::f64::consts::TAU) as f32,
                    scale: rule.scale[0] + (rule.scale[1] - rule.scale[0]) * s as f32,
                });
            }
        }
    }
    progress(1.0);
    Ok(plants)
}

/// Land cover and DEM must share a CRS ([`crate::gis::load_raster_in`] reprojects).
fn check_same_crs(frame: &LocalFrame, landcover: &Raster) -> Result<(), SceneError> {
    if &landcover.crs == frame.crs() {
        Ok(())
    } else {
        Err(SceneError::Invalid(format!(
            "land-cover CRS {} differs from the DEM's CRS {}; load it with gis::load_raster_in to reproject it",
            landcover.crs,
            frame.crs()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_random_is_deterministic_and_uniform_enough() {
        assert_eq!(cell_random(7, 1, 3, -4), cell_random(7, 1, 3, -4));
        assert_ne!(cell_random(7, 1, 3, -4), cell_random(8, 1, 3, -4));
        let mean: f64 = (0..10_000).map(|i| cell_random(1, 0, i, 0)[0]).sum::<f64>() / 10_000.0;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }

    #[test]
    fn spacing_grid_rejects_close_points() {
        let mut grid = SpacingGrid { cell: 2.0, buckets: HashMap::new() };
        grid.insert([0.0, 0.0]);
        assert!(!grid.is_free([1.0, 1.0], 2.0));
        assert!(grid.is_free([3.0, 0.0], 2.0));
        assert!(!grid.is_free([3.0, 0.0], 5.0));
    }
}
