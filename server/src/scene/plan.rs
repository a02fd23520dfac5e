//! Plants from vector plans (`[[layers.plans]]`): planting polygons filled at a density,
//! hedgerows along lines in one or more rows, single plants at points (GeoJSON or a CSV tree
//! inventory). Every random number is a hash of (seed, feature, position), so a plan places
//! the same plants for a seed whatever else the scene holds.

use geo::{Contains, Geometry, LineString, Point};

use super::config::{PlanConfig, PlanKind};
use super::terrain::Terrain;
use super::vegetation::{PlacementRule, PlantInstance, place_in};
use super::{SceneError, Species};
use crate::gis::{SceneFeature, VectorError, vector::overlaps};
use crate::rng::{SplitMix64, mix};
use std::path::Path;

/// The plants of one plan. `features` are in scene metres (see [`crate::gis::read_vector`]);
/// `path` names the file in errors; at most `max_plants` plants.
pub fn place_plan(
    plan: &PlanConfig,
    features: &[SceneFeature],
    path: &Path,
    terrain: &Terrain,
    species: &[Species],
    seed: u64,
    max_plants: usize,
) -> Result<Vec<PlantInstance>, SceneError> {
    let fail = |index: usize, message: String| VectorError::Feature { path: path.to_path_buf(), index, message };
    if !(plan.scale[0] > 0.0 && plan.scale[1] >= plan.scale[0]) {
        return Err(SceneError::Invalid(format!("{}: plan needs 0 < scale[0] <= scale[1]", path.display())));
    }
    let (lo, hi) = terrain.bounds();
    let mut plants = Vec::new();
    for f in features {
        let kind = resolve_species(plan, f, species).map_err(|m| fail(f.index, m))?;
        let feature_seed = mix(seed ^ mix(f.index as u64));
        let remaining = max_plants.saturating_sub(plants.len());
        let placed = match plan.kind {
            PlanKind::Areas => {
                if !matches!(f.geometry, Geometry::Polygon(_) | Geometry::MultiPolygon(_)) {
                    return Err(fail(f.index, "an `areas` plan needs polygons".into()).into());
                }
                if !overlaps(&f.geometry, lo, hi) {
                    return Err(fail(f.index, "the polygon does not overlap the terrain".into()).into());
                }
                let density = f.number(&plan.density_property).map_err(|m| fail(f.index, m))?.or(plan.density);
                let density = density.filter(|d| (0.0..=10_000.0).contains(d)).ok_or_else(|| {
                    fail(
                        f.index,
                        format!("needs a density (0..=10000 plants/ha) in '{}' or the plan", plan.density_property),
                    )
                })?;
                let rule = PlacementRule {
                    class: 1,
                    species: kind,
                    density_per_ha: density,
                    min_spacing: plan.min_spacing,
                    scale: plan.scale,
                };
                let rect =
                    geo::BoundingRect::bounding_rect(&f.geometry).ok_or_else(|| fail(f.index, "is empty".into()))?;
                let bounds = (
                    [rect.min().x.max(lo[0]), rect.min().y.max(lo[1])],
                    [rect.max().x.min(hi[0]), rect.max().y.min(hi[1])],
                );
                let inside = |p: [f64; 2]| f.geometry.contains(&Point::new(p[0], p[1])).then_some(1);
                place_in(terrain, bounds, &inside, &[rule], feature_seed, remaining, &|_| {})?
            }
            PlanKind::Hedgerows => {
                let lines: Vec<&LineString<f64>> = match &f.geometry {
                    Geometry::LineString(l) => vec![l],
                    Geometry::MultiLineString(m) => m.0.iter().collect(),
                    _ => return Err(fail(f.index, "a `hedgerows` plan needs lines".into()).into()),
                };
                if !(plan.spacing >= 0.05 && plan.row_spacing >= 0.0 && (1..=20).contains(&plan.rows)) {
                    return Err(SceneError::Invalid(format!(
                        "{}: hedgerows need spacing >= 0.05 m, row_spacing >= 0 and 1..=20 rows",
                        path.display()
                    )));
                }
                let mut placed = Vec::new();
                for line in lines {
                    along_line(line, plan, kind, feature_seed, terrain, &mut placed);
                }
                if placed.is_empty() {
                    return Err(fail(f.index, "the line does not overlap the terrain".into()).into());
                }
                placed
            }
            PlanKind::Plants => {
                let points: Vec<Point<f64>> = match &f.geometry {
                    Geometry::Point(p) => vec![*p],
                    Geometry::MultiPoint(m) => m.0.clone(),
                    _ => return Err(fail(f.index, "a `plants` plan needs points".into()).into()),
                };
                let scale = plant_scale(plan, f, &species[kind]).map_err(|m| fail(f.index, m))?;
                points
                    .iter()
                    .enumerate()
                    .filter_map(|(k, p)| {
                        let z = terrain.height_at(p.x(), p.y())?;
                        let mut rng = SplitMix64::new(mix(feature_seed ^ k as u64));
                        let scale = scale.unwrap_or_else(|| rng.range(plan.scale[0], plan.scale[1]));
                        let rotation = (rng.unit_f64() * std::f64::consts::TAU) as f32;
                        Some(PlantInstance {
                            species: kind,
                            position: [p.x() as f32, p.y() as f32, z as f32],
                            rotation,
                            scale,
                        })
                    })
                    .collect()
            }
        };
        plants.extend(placed);
        if plants.len() > max_plants {
            return Err(SceneError::Invalid(format!(
                "{}: more than {max_plants} plants would be placed; lower the densities or raise max_plants",
                path.display()
            )));
        }
    }
    if plants.is_empty() {
        return Err(VectorError::Format {
            path: path.to_path_buf(),
            message: "no feature places a plant on the terrain (do the file's coordinates and CRS match the DEM?)"
                .into(),
        }
        .into());
    }
    Ok(plants)
}

/// The scene species of a feature: its species property mapped by `species_map` (or taken
/// as a species name, case-insensitively), else the plan's `species`.
fn resolve_species(plan: &PlanConfig, f: &SceneFeature, species: &[Species]) -> Result<usize, String> {
    let given = f.text(&plan.species_property);
    let name = match (&given, &plan.species) {
        (Some(value), _) => plan.species_map.get(value).map_or(value.as_str(), String::as_str),
        (None, Some(default)) => default.as_str(),
        (None, None) => {
            return Err(format!("has no '{}' property and the plan gives no `species`", plan.species_property));
        }
    };
    species.iter().position(|s| s.name.eq_ignore_ascii_case(name)).ok_or_else(|| {
        let known: Vec<&str> = species.iter().map(|s| s.name.as_str()).collect();
        format!("unknown species '{name}' (scene species: {}; map names with `species_map`)", known.join(", "))
    })
}

/// The scale of a single plant: its height over the model's, else its crown diameter over
/// the model's crown width; `None` when the feature gives neither (then drawn from `scale`).
fn plant_scale(plan: &PlanConfig, f: &SceneFeature, species: &Species) -> Result<Option<f32>, String> {
    let positive = |v: Option<f64>, what: &str| match v {
        Some(v) if v.is_finite() && v > 0.0 && v < 200.0 => Ok(Some(v as f32)),
        Some(v) => Err(format!("{what} {v} m is not within 0..200 m")),
        None => Ok(None),
    };
    if let Some(h) = positive(f.number(&plan.height_property)?, "height")? {
        return Ok(Some(h / species.model.height().max(1e-3)));
    }
    if let Some(d) = positive(f.number(&plan.crown_property)?, "crown diameter")? {
        let (lo, hi) = species.model.bounds();
        let width = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3);
        return Ok(Some(d / width));
    }
    Ok(None)
}

/// Plants along one line: rows parallel to it `row_spacing` apart (centred on the line),
/// plants every `spacing` along each row, odd rows shifted by half a spacing (a staggered
/// hedge), each jittered by up to 10 % of the spacings. Points off the terrain are skipped.
fn along_line(
    line: &LineString<f64>,
    plan: &PlanConfig,
    species: usize,
    seed: u64,
    terrain: &Terrain,
    out: &mut Vec<PlantInstance>,
) {
    let mut walked = 0.0;
    for (segment, seg) in line.lines().enumerate() {
        let (dx, dy) = (seg.end.x - seg.start.x, seg.end.y - seg.start.y);
        let len = dx.hypot(dy);
        if len <= 0.0 {
            continue;
        }
        let (ux, uy) = (dx / len, dy / len);
        for row in 0..plan.rows {
            let offset = (f64::from(row) - 0.5 * f64::from(plan.rows - 1)) * plan.row_spacing;
            let shift = if row % 2 == 1 { 0.5 } else { 0.0 };
            // Positions s = (k + 0.5 + shift)·spacing along the whole line that fall on this segment.
            let first = ((walked / plan.spacing) - 0.5 - shift).ceil().max(0.0) as u64;
            let mut k = first;
            loop {
                let s = (k as f64 + 0.5 + shift) * plan.spacing - walked;
                if s >= len {
                    break;
                }
                let mut rng = SplitMix64::new(mix(seed ^ mix(u64::from(row) ^ mix(k ^ ((segment as u64) << 40)))));
                let along = s + (rng.unit_f64() - 0.5) * 0.2 * plan.spacing;
                let across = offset + (rng.unit_f64() - 0.5) * 0.2 * plan.row_spacing;
                let (x, y) = (seg.start.x + ux * along - uy * across, seg.start.y + uy * along + ux * across);
                let scale = rng.range(plan.scale[0], plan.scale[1]);
                let rotation = (rng.unit_f64() * std::f64::consts::TAU) as f32;
                if let Some(z) = terrain.height_at(x, y) {
                    out.push(PlantInstance { species, position: [x as f32, y as f32, z as f32], rotation, scale });
                }
                k += 1;
            }
        }
        walked += len;
    }
}
