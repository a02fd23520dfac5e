//! Vegetation masses for the far field (thesis ch. 7 and 7.3, "increased abstraction of the
//! background"; NPAR §8): plants are grouped on a plant-density grid, and every cell with
//! enough canopy cover becomes one dome at crown height. Far away the domes of a forest are
//! drawn instead of its plants, so a wood reads as one merged canopy surface whose silhouette
//! is scalloped by the domes, and what a far forest costs follows its area, not its plants.
//!
//! This module builds the CPU side (grouping, dome geometry); `render::scene_gpu` uploads the
//! domes in chunks, culls them and blends them with the plants' billboards.

use crate::rng::{SplitMix64, mix};
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// Side of a cell of the plant-density grid in metres: about a tree crown, so the domes'
/// scallops have the size of crowns. It divides the 40 m grid of far reference points
/// (thesis 7.3), so each cell lies in one of them.
pub const MASS_CELL: f32 = 10.0;
/// Canopy cover (the share of a cell under crowns) from which a cell joins a mass.
const MIN_COVER: f32 = 0.1;
/// Plants a cell needs to join a mass: a lone tree stays a tree (drawn as a dot far away).
const MIN_PLANTS: u32 = 2;
/// Rings from the top of a dome to its base, and segments around it.
const RINGS: usize = 3;
const SEGMENTS: usize = 6;
/// How far a dome's base reaches below the mean ground of its plants (metres), so it stands
/// in sloping ground instead of floating over it.
const SKIRT: f32 = 1.5;
/// Share of a dome's own (ellipsoid) normal in its shading normal; the rest is the normal of
/// the canopy surface over the neighbouring cells, so a mass is shaded as one smooth surface
/// with a little relief per crown.
const DOME_NORMAL_SHARE: f32 = 0.45;

/// What grouping needs of one plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassPlant {
    /// Base of the trunk (scene metres).
    pub position: [f32; 3],
    /// Horizontal radius of the crown.
    pub crown_radius: f32,
    /// Height of the plant above its base.
    pub height: f32,
    /// The plant's foliage colour (linear RGB).
    pub color: [f32; 3],
}

/// One cell of the plant-density grid that is part of a mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassCell {
    /// Grid coordinates of the cell.
    pub key: (i64, i64),
    /// Mean ground height of its plants.
    pub ground: f32,
    /// Crown-weighted mean height of its plants above their base: the dome's height, and the
    /// size by which the level of detail hands the cell's plants over to the dome.
    pub height: f32,
    /// Share of the cell under crowns (0..1).
    pub cover: f32,
    /// Crown-weighted mean foliage colour (linear RGB).
    pub color: [f32; 3],
    /// Cells to the mass's edge: 1 for a cell next to open ground, 2 for the next ring in.
    pub depth: u32,
}

/// The masses of one set of plants.
#[derive(Debug, Clone, PartialEq)]
pub struct Masses {
    pub cells: Vec<MassCell>,
    /// Per input plant: whether it stands in a mass cell (and is drawn by it far away).
    pub massed: Vec<bool>,
}

/// The key of the grid cell holding (x, y).
fn key_of(x: f32, y: f32) -> (i64, i64) {
    ((x / MASS_CELL).floor() as i64, (y / MASS_CELL).floor() as i64)
}

/// Groups `plants` on the plant-density grid: a cell becomes part of a mass when it holds at
/// least [`MIN_PLANTS`] plants whose crowns cover [`MIN_COVER`] of it.
pub fn group(plants: &[MassPlant]) -> Masses {
    #[derive(Default)]
    struct Sum {
        count: u32,
        area: f32,
        ground: f32,
        height: f32,
        color: Vec3,
    }
    let mut sums: HashMap<(i64, i64), Sum> = HashMap::new();
    for p in plants {
        let s = sums.entry(key_of(p.position[0], p.position[1])).or_default();
        let area = std::f32::consts::PI * p.crown_radius * p.crown_radius;
        s.count += 1;
        s.area += area;
        s.ground += p.position[2];
        s.height += area * p.height;
        s.color += area * Vec3::from(p.color);
    }
    let mut cells: Vec<MassCell> = sums
        .into_iter()
        .filter_map(|(key, s)| {
            let cover = (s.area / (MASS_CELL * MASS_CELL)).min(1.0);
            (s.count >= MIN_PLANTS && cover >= MIN_COVER && s.area > 0.0).then(|| MassCell {
                key,
                ground: s.ground / s.count as f32,
                height: s.height / s.area,
                cover,
                color: (s.color / s.area).to_array(),
                depth: 0,
            })
        })
        .collect();
    cells.sort_by_key(|c| c.key);
    let depths = edge_depths(&cells);
    for cell in &mut cells {
        cell.depth = depths[&cell.key];
    }
    let massed = plants.iter().map(|p| depths.contains_key(&key_of(p.position[0], p.position[1]))).collect();
    Masses { cells, massed }
}

/// The 8 neighbours of a cell.
const NEIGHBOURS: [(i64, i64); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// Each cell's distance in cells to open ground (a breadth-first search from the cells with an
/// open neighbour), so the outline of a mass can be a width in metres at every distance.
fn edge_depths(cells: &[MassCell]) -> HashMap<(i64, i64), u32> {
    let mut depth: HashMap<(i64, i64), u32> = cells.iter().map(|c| (c.key, 0)).collect();
    let mut front: Vec<(i64, i64)> = cells
        .iter()
        .map(|c| c.key)
        .filter(|&(i, j)| NEIGHBOURS.iter().any(|(di, dj)| !depth.contains_key(&(i + di, j + dj))))
        .collect();
    let mut level = 1;
    while !front.is_empty() {
        for key in &front {
            depth.insert(*key, level);
        }
        let mut next = Vec::new();
        for &(i, j) in &front {
            for (di, dj) in NEIGHBOURS {
                let key = (i + di, j + dj);
                if depth.get(&key) == Some(&0) {
                    depth.insert(key, level + 1);
                    next.push(key);
                }
            }
        }
        front = next;
        level += 1;
    }
    depth
}

/// The dome geometry of some mass cells in world space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DomeMesh {
    pub positions: Vec<[f32; 3]>,
    /// Smooth shading normals (see [`DOME_NORMAL_SHARE`]).
    pub normals: Vec<[f32; 3]>,
    /// Per vertex: horizontal distance in metres to the outer edge of the mass (the dome's
    /// base circle where it faces open ground, larger inside the mass), for its outline.
    pub edge: Vec<f32>,
    /// Per vertex: the position of its cell in the `cells` given to [`dome_mesh`].
    pub cell: Vec<u32>,
    pub indices: Vec<u32>,
}

/// Builds one dome per cell of `cells` (all from `all`, which holds every mass cell of the
/// same plants, for the neighbours): an ellipsoid cap over the cell at the cell's height,
/// its area about that of the crowns, its centre jittered within the cell so the scallops of
/// a mass's outline do not line up with the grid.
pub fn dome_mesh(cells: &[MassCell], all: &HashMap<(i64, i64), MassCell>) -> DomeMesh {
    let mut mesh = DomeMesh::default();
    for (index, cell) in cells.iter().enumerate() {
        let (i, j) = cell.key;
        let mut rng = SplitMix64::new(mix(i as u64 ^ mix(j as u64)));
        let jitter = Vec2::new(rng.range(-0.15, 0.15), rng.range(-0.15, 0.15)) * MASS_CELL;
        let center = (Vec2::new(i as f32, j as f32) + 0.5) * MASS_CELL + jitter;
        // About the crowns' area (a sparse cell stays a small dome), overlapping the
        // neighbours' domes from a cover of about half.
        let radius =
            MASS_CELL * ((cell.cover / std::f32::consts::PI).sqrt() * 1.2).clamp(0.3, 0.7) * rng.range(0.9, 1.1);
        let base = cell.ground - SKIRT;
        let half_height = (cell.height + SKIRT).max(0.5);
        // The canopy's slope from the neighbours' crown tops (open ground counts as ground).
        let top = |di: i64, dj: i64| all.get(&(i + di, j + dj)).map_or(cell.ground, |c| c.ground + c.height);
        let gradient = Vec2::new(top(1, 0) - top(-1, 0), top(0, 1) - top(0, -1)) / (2.0 * MASS_CELL);
        let canopy = Vec3::new(-gradient.x, -gradient.y, 1.0).normalize();
        // Directions towards open neighbours: the dome's outer side, where the mass has its edge.
        let open: Vec<Vec2> = NEIGHBOURS
            .into_iter()
            .filter(|(di, dj)| !all.contains_key(&(i + di, j + dj)))
            .map(|(di, dj)| Vec2::new(di as f32, dj as f32).normalize())
            .collect();
        let first = mesh.positions.len() as u32;
        let mut vertex = |theta: f32, phi: f32| {
            let (sin_t, cos_t) = theta.sin_cos();
            let dir = Vec2::from_angle(phi);
            let p = center + dir * (radius * sin_t);
            mesh.positions.push([p.x, p.y, base + half_height * cos_t]);
            let dome = Vec3::new(dir.x * sin_t / radius, dir.y * sin_t / radius, cos_t / half_height).normalize();
            mesh.normals.push((dome * DOME_NORMAL_SHARE + canopy * (1.0 - DOME_NORMAL_SHARE)).normalize().to_array());
            // Outward vertices of an edge cell lie their distance from the base circle inside
            // the mass, the rest of a cell half a cell more, and each ring of cells in one more.
            let outward = open.iter().any(|o| o.dot(dir) > 0.3);
            let own = if outward { radius * (1.0 - sin_t) } else { 0.5 * (MASS_CELL + radius * (1.0 - sin_t)) };
            mesh.edge.push((cell.depth.max(1) - 1) as f32 * MASS_CELL + own);
            mesh.cell.push(index as u32);
        };
        vertex(0.0, 0.0);
        for ring in 1..=RINGS {
            let theta = std::f32::consts::FRAC_PI_2 * ring as f32 / RINGS as f32;
            for s in 0..SEGMENTS {
                vertex(theta, std::f32::consts::TAU * (s as f32 + 0.5 * (ring % 2) as f32) / SEGMENTS as f32);
            }
        }
        let at = |ring: usize, s: usize| first + 1 + ((ring - 1) * SEGMENTS + s % SEGMENTS) as u32;
        for s in 0..SEGMENTS {
            mesh.indices.extend([first, at(1, s), at(1, s + 1)]);
        }
        for ring in 1..RINGS {
            for s in 0..SEGMENTS {
                // Odd rings are turned by half a segment: the quads become a triangle strip
                // between staggered rings.
                let (a, b, c, d) = (at(ring, s), at(ring, s + 1), at(ring + 1, s), at(ring + 1, s + 1));
                if ring % 2 == 1 {
                    mesh.indices.extend([a, c, d, a, d, b]);
                } else {
                    mesh.indices.extend([a, c, b, b, c, d]);
                }
            }
        }
    }
    mesh
}

/// Triangles of one dome.
pub const DOME_TRIANGLES: u64 = (SEGMENTS * (2 * RINGS - 1)) as u64;

#[cfg(test)]
mod tests {
    use super::*;

    fn plant(x: f32, y: f32) -> MassPlant {
        MassPlant { position: [x, y, 100.0], crown_radius: 2.5, height: 12.0, color: [0.1, 0.3, 0.1] }
    }

    #[test]
    fn a_forest_groups_into_cells_and_a_lone_tree_stays_alone() {
        let mut plants: Vec<MassPlant> =
            (0..20).flat_map(|i| (0..20).map(move |j| plant(i as f32 * 4.0 + 1.0, j as f32 * 4.0 + 1.0))).collect();
        plants.push(plant(500.0, 500.0));
        let masses = group(&plants);
        assert_eq!(masses.cells.len(), 64, "80 m × 80 m of forest: 8 × 8 cells");
        assert!(masses.massed[..400].iter().all(|m| *m) && !masses.massed[400], "the lone tree is not massed");
        let cell = masses.cells[0];
        assert!((cell.height - 12.0).abs() < 1e-4 && (cell.ground - 100.0).abs() < 1e-4);
        assert!(cell.cover > 0.5, "{}", cell.cover);
        let depth = |key| masses.cells.iter().find(|c| c.key == key).map(|c| c.depth);
        assert_eq!((depth((0, 0)), depth((1, 1)), depth((3, 4)), depth((7, 3))), (Some(1), Some(2), Some(4), Some(1)));
    }

    #[test]
    fn domes_stand_over_their_cells_and_face_out_at_the_mass_edge() {
        let plants: Vec<MassPlant> =
            (0..10).flat_map(|i| (0..5).map(move |j| plant(i as f32 * 4.0 + 1.0, j as f32 * 4.0 + 1.0))).collect();
        let masses = group(&plants);
        let all: HashMap<_, _> = masses.cells.iter().map(|c| (c.key, *c)).collect();
        let mesh = dome_mesh(&masses.cells, &all);
        let per_dome = 1 + RINGS * SEGMENTS;
        assert_eq!(mesh.positions.len(), per_dome * masses.cells.len());
        assert_eq!(mesh.indices.len() as u64, 3 * DOME_TRIANGLES * masses.cells.len() as u64);
        let top = mesh.positions.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
        assert!((top - 112.0).abs() < 1e-3, "the domes reach the crowns' height: {top}");
        assert!(mesh.normals.iter().all(|n| n[2] > 0.0), "normals face up and out");
        // Every dome's base touches the mass edge only where it faces open ground.
        assert!(mesh.edge.iter().any(|e| *e < 1e-3) && mesh.edge.iter().any(|e| *e > 3.0));
        assert!(mesh.indices.iter().all(|&i| (i as usize) < mesh.positions.len()));
    }
}
