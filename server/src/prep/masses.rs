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
/// Rings from the top of a dome to its base at level 0 (one fewer per coarser level: a dome
/// a few pixels wide needs no more), and segments around it.
const RINGS: usize = 3;
const SEGMENTS: usize = 6;
/// How much larger than the region of its level-0 cells a merged cell's dome is at least.
const MERGED_OVERLAP: f32 = 1.15;
/// The least height of a dome of a merged level, in its minor semi-axes.
const MERGED_DOME_RISE: f32 = 0.5;
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
    /// Where in a merged cell ([`coarsen`]) its level-0 cells lie: the ellipse of their
    /// second moments; `None` for a level-0 cell (its dome stands on the whole cell).
    pub footprint: Option<Footprint>,
}

/// The ellipse with the second moments of a set of level-0 cells (scene metres): a merged
/// cell's dome stands on it, so a narrow wood or a hedge merged into wide cells keeps its
/// shape (a band stays a band, a wood's edge does not grow into its neighbour's field), as
/// Campos et al. (2004) fit substitution shapes to their branches' leaves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Centre (x, y).
    pub center: [f32; 2],
    /// Semi-axes: the major first, along `direction`, then the minor.
    pub half_axes: [f32; 2],
    /// Unit vector of the major axis.
    pub direction: [f32; 2],
    /// The mean crown cover of its level-0 cells.
    pub cover: f32,
    /// The slope (∂z/∂x, ∂z/∂y) of the plane fitted to its cells' ground: the dome's base lies
    /// on it, so a wide dome on a hillside neither sinks into the slope above it nor floats
    /// over the slope below.
    pub slope: [f32; 2],
}

impl Footprint {
    /// The ellipse of the cells whose centres have these sums: count `n`, Σx, Σy, Σx², Σxy,
    /// Σy² (metres), each cell a square of side `cell`: a uniform ellipse of semi-axis a has the
    /// variance a²/4 along it, a square of side s the variance s²/12.
    /// `origin` is the point the sums were taken from (the merged cell's corner, so the sums
    /// stay small), `cover` the cells' summed cover, `ground` the sums Σz, Σxz, Σyz of their
    /// ground heights.
    fn of_moments(
        n: f32,
        [sx, sy, sxx, sxy, syy]: [f32; 5],
        cell: f32,
        origin: Vec2,
        cover: f32,
        [sz, sxz, syz]: [f32; 3],
    ) -> Footprint {
        let (mx, my) = (sx / n, sy / n);
        let own = cell * cell / 12.0;
        // The ground plane by least squares over the cells' centres: the centres' covariance
        // times the slope is their covariance with the height (none for fewer than 3 cells or
        // cells in a line: level).
        let (cxx, cxy, cyy) = (sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my);
        let (cxz, cyz) = (sxz / n - mx * sz / n, syz / n - my * sz / n);
        let det = cxx * cyy - cxy * cxy;
        let slope = if det > 1e-3 * (cell * cell).powi(2) {
            [(cyy * cxz - cxy * cyz) / det, (cxx * cyz - cxy * cxz) / det]
        } else {
            [0.0, 0.0]
        };
        let (vxx, vxy, vyy) = (cxx + own, cxy, cyy + own);
        // Eigenvalues and the major eigenvector of the 2 × 2 covariance.
        let half_trace = 0.5 * (vxx + vyy);
        let root = (0.25 * (vxx - vyy) * (vxx - vyy) + vxy * vxy).sqrt();
        let (major, minor) = (half_trace + root, (half_trace - root).max(own));
        let direction = if vxy.abs() > 1e-6 {
            Vec2::new(major - vyy, vxy).normalize()
        } else if vxx >= vyy {
            Vec2::X
        } else {
            Vec2::Y
        };
        Footprint {
            center: (origin + Vec2::new(mx, my)).to_array(),
            half_axes: [2.0 * major.sqrt(), 2.0 * minor.sqrt()],
            direction: direction.to_array(),
            cover: cover / n,
            slope,
        }
    }
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
                footprint: None,
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

/// Levels of detail of the masses: level `l` has cells of `MASS_CELL · 2^l` metres, so far
/// away a forest costs a quarter of the domes per level while its domes stay a few pixels
/// wide on screen.
pub const MASS_LEVELS: usize = 3;

/// The cells of `cells` (level 0, [`MASS_CELL`]) merged into cells `factor` times as wide: a
/// coarse cell's ground is the mean of its cells', its height, colour and cover their
/// cover-weighted means and sum (over the coarse cell's area), and its edge depth counted
/// again in coarse cells.
pub fn coarsen(cells: &[MassCell], factor: i64) -> Vec<MassCell> {
    if factor <= 1 {
        return cells.to_vec();
    }
    #[derive(Default)]
    struct Sum {
        count: u32,
        cover: f32,
        ground: f32,
        height: f32,
        color: Vec3,
        /// Σx, Σy, Σx², Σxy, Σy² of the cells' centres.
        moments: [f32; 5],
        /// Σz, Σxz, Σyz of their ground heights (relative to the first cell's).
        heights: [f32; 3],
        /// The ground height the heights are relative to.
        datum: Option<f32>,
    }
    let mut sums: HashMap<(i64, i64), Sum> = HashMap::new();
    for c in cells {
        let s = sums.entry((c.key.0.div_euclid(factor), c.key.1.div_euclid(factor))).or_default();
        s.count += 1;
        s.cover += c.cover;
        s.ground += c.ground;
        s.height += c.cover * c.height;
        s.color += c.cover * Vec3::from(c.color);
        // Relative to the merged cell's corner.
        let (x, y) = (
            (c.key.0.rem_euclid(factor) as f32 + 0.5) * MASS_CELL,
            (c.key.1.rem_euclid(factor) as f32 + 0.5) * MASS_CELL,
        );
        for (sum, v) in s.moments.iter_mut().zip([x, y, x * x, x * y, y * y]) {
            *sum += v;
        }
        let z = c.ground - *s.datum.get_or_insert(c.ground);
        for (sum, v) in s.heights.iter_mut().zip([z, x * z, y * z]) {
            *sum += v;
        }
    }
    let area = (factor * factor) as f32;
    let mut coarse: Vec<MassCell> = sums
        .into_iter()
        .map(|(key, s)| MassCell {
            key,
            ground: s.ground / s.count as f32,
            height: s.height / s.cover,
            cover: s.cover / area,
            color: (s.color / s.cover).to_array(),
            depth: 0,
            footprint: Some(Footprint::of_moments(
                s.count as f32,
                s.moments,
                MASS_CELL,
                Vec2::new(key.0 as f32, key.1 as f32) * factor as f32 * MASS_CELL,
                s.cover,
                s.heights,
            )),
        })
        .collect();
    coarse.sort_by_key(|c| c.key);
    let depths = edge_depths(&coarse);
    for cell in &mut coarse {
        cell.depth = depths[&cell.key];
    }
    coarse
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
    /// Per vertex: distance in metres to the outer edge of the mass (the dome's foot where it
    /// faces open ground, measured over the dome's surface; negative on the buried skirt;
    /// larger inside the mass), for its outline.
    pub edge: Vec<f32>,
    /// Per vertex: the position of its cell in the `cells` given to [`dome_mesh`].
    pub cell: Vec<u32>,
    pub indices: Vec<u32>,
}

/// The radius of a level-0 dome in cell widths for a cell of crown `cover`: about the crowns'
/// area, overlapping the neighbours' domes from a cover of about half.
fn crown_share(cover: f32) -> f32 {
    ((cover / std::f32::consts::PI).sqrt() * 1.2).clamp(0.3, 0.7)
}

/// Builds one dome per cell of `cells` (all from `all`, which holds every mass cell of the
/// same plants and `level`, for the neighbours; cells [`cell_size`] wide): an ellipsoid cap
/// over the cell at the cell's height,
/// its area about that of the crowns, its centre jittered within the cell so the scallops of
/// a mass's outline do not line up with the grid.
pub fn dome_mesh(cells: &[MassCell], all: &HashMap<(i64, i64), MassCell>, level: usize) -> DomeMesh {
    let size = cell_size(level);
    let rings = dome_rings(level);
    let mut mesh = DomeMesh::default();
    for (index, cell) in cells.iter().enumerate() {
        let (i, j) = cell.key;
        // The dome's base: a level-0 cell's circle about the crowns' area (a sparse cell stays
        // a small dome), overlapping the neighbours' domes from a cover of about half, its
        // centre jittered; a merged cell's ellipse over its level-0 cells, as much larger
        // than their region as a level-0 dome is than its cell (at their mean cover) and large
        // enough to overlap its neighbours, so a wood or a band stays unbroken.
        let slope = cell.footprint.map_or(Vec2::ZERO, |f| Vec2::from(f.slope));
        let (center, half_axes, major) = match cell.footprint {
            None => {
                let mut rng = SplitMix64::new(mix(i as u64 ^ mix(j as u64)));
                let jitter = Vec2::new(rng.range(-0.15, 0.15), rng.range(-0.15, 0.15)) * size;
                let radius = size * crown_share(cell.cover) * rng.range(0.9, 1.1);
                ((Vec2::new(i as f32, j as f32) + 0.5) * size + jitter, Vec2::splat(radius), Vec2::X)
            }
            Some(f) => {
                // A level-0 dome's radius against the circle of its cell's area, but at least
                // MERGED_OVERLAP: level-0 domes a few pixels wide read as a closed canopy
                // whatever the gaps between them, so merged domes close them too.
                let grow = (crown_share(f.cover) * std::f32::consts::PI.sqrt()).max(MERGED_OVERLAP);
                let [a, b] = f.half_axes;
                (Vec2::from(f.center), Vec2::new(a, b) * grow, Vec2::from(f.direction))
            }
        };
        let minor_axis = major.perp();
        let base = cell.ground - SKIRT;
        // A merged cell's dome rises at least MERGED_DOME_RISE of its minor semi-axis above its
        // base, so a low wood drawn by wide, flat domes is not lost in the coarser levels of
        // the terrain under it.
        let least_height = if level > 0 { MERGED_DOME_RISE * half_axes.y } else { 0.5 };
        let half_height = (cell.height + SKIRT).max(least_height);
        // The canopy's slope from the neighbours' crown tops (open ground counts as ground).
        let top = |di: i64, dj: i64| all.get(&(i + di, j + dj)).map_or(cell.ground, |c| c.ground + c.height);
        let gradient = Vec2::new(top(1, 0) - top(-1, 0), top(0, 1) - top(0, -1)) / (2.0 * size);
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
            let (cos_p, sin_p) = (phi.cos(), phi.sin());
            // The base ellipse's point at angle phi, and the ellipsoid's gradient there
            // (x/a², y/b², z/h²), both from the ellipse's axes to the scene's.
            let rim = major * (half_axes.x * cos_p) + minor_axis * (half_axes.y * sin_p);
            let p = center + rim * sin_t;
            // The dome sheared onto the ground's plane (z += slope · offset), its normal by the
            // shear's inverse transpose.
            mesh.positions.push([p.x, p.y, base + slope.dot(rim * sin_t) + half_height * cos_t]);
            let across = major * (cos_p / half_axes.x) + minor_axis * (sin_p / half_axes.y);
            let n_z = cos_t / half_height;
            let dome = (across * sin_t - slope * n_z).extend(n_z).normalize();
            mesh.normals.push((dome * DOME_NORMAL_SHARE + canopy * (1.0 - DOME_NORMAL_SHARE)).normalize().to_array());
            // Outward vertices of an edge cell lie their distance from the dome's foot inside
            // the mass, the rest of a cell half a cell more, and each ring of cells in one more.
            // The distance from the foot runs over the dome's surface: its height above the
            // ground (negative for the buried skirt, so the interpolated distance is zero where
            // the dome leaves the ground) plus its inset from the base ellipse. The inset alone
            // grows only with the square of the height up a steep side, which drew the lower
            // sides of tall domes seen from the side entirely in outline ink (flat grey blocks
            // in a forest seen from 1 km).
            let dir = rim.normalize_or_zero();
            let radius = rim.length();
            let outward = open.iter().any(|o| o.dot(dir) > 0.3);
            let inset = radius * (1.0 - sin_t);
            let own = if outward { inset + half_height * cos_t - SKIRT } else { 0.5 * (size + inset) };
            mesh.edge.push((cell.depth.max(1) - 1) as f32 * size + own);
            mesh.cell.push(index as u32);
        };
        vertex(0.0, 0.0);
        for ring in 1..=rings {
            let theta = std::f32::consts::FRAC_PI_2 * ring as f32 / rings as f32;
            for s in 0..SEGMENTS {
                vertex(theta, std::f32::consts::TAU * (s as f32 + 0.5 * (ring % 2) as f32) / SEGMENTS as f32);
            }
        }
        let at = |ring: usize, s: usize| first + 1 + ((ring - 1) * SEGMENTS + s % SEGMENTS) as u32;
        for s in 0..SEGMENTS {
            mesh.indices.extend([first, at(1, s), at(1, s + 1)]);
        }
        for ring in 1..rings {
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

/// The width of a cell of the masses at `level` (metres).
pub fn cell_size(level: usize) -> f32 {
    MASS_CELL * (1_u32 << level) as f32
}

/// The rings of a dome at `level`.
fn dome_rings(level: usize) -> usize {
    RINGS.saturating_sub(level).max(1)
}

/// Triangles of one dome at `level`.
pub fn dome_triangles(level: usize) -> u64 {
    (SEGMENTS * (2 * dome_rings(level) - 1)) as u64
}

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
        let mesh = dome_mesh(&masses.cells, &all, 0);
        let per_dome = 1 + RINGS * SEGMENTS;
        assert_eq!(mesh.positions.len(), per_dome * masses.cells.len());
        assert_eq!(mesh.indices.len() as u64, 3 * dome_triangles(0) * masses.cells.len() as u64);
        let top = mesh.positions.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
        assert!((top - 112.0).abs() < 1e-3, "the domes reach the crowns' height: {top}");
        assert!(mesh.normals.iter().all(|n| n[2] > 0.0), "normals face up and out");
        // Every dome's base touches the mass edge only where it faces open ground.
        assert!(mesh.edge.iter().any(|e| *e < 1e-3) && mesh.edge.iter().any(|e| *e > 3.0));
        // Towards open ground the distance to the edge runs over the dome from its foot: the
        // buried base ring lies SKIRT below it, and a vertex up the side is at least its height
        // above the ground away from it (the outline does not climb a steep side); inside the
        // mass it is at least half a cell.
        let ground = 100.0;
        let edges: Vec<(f32, f32)> = mesh.edge.iter().zip(&mesh.positions).map(|(e, p)| (*e, p[2] - ground)).collect();
        assert!(edges.iter().any(|(e, z)| (*e + SKIRT).abs() < 1e-3 && (*z + SKIRT).abs() < 1e-3));
        assert!(edges.iter().all(|(e, z)| *e >= z.min(0.5 * MASS_CELL) - 1e-3));
        assert!(mesh.indices.iter().all(|&i| (i as usize) < mesh.positions.len()));
    }

    #[test]
    fn a_merged_dome_keeps_the_shape_of_its_cells() {
        // A hedge of small plants 4 m apart along y = 1: one row of level-0 cells of low cover.
        let hedge: Vec<MassPlant> =
            (0..60).map(|i| MassPlant { crown_radius: 1.0, height: 3.0, ..plant(i as f32 * 4.0 + 1.0, 1.0) }).collect();
        let fine = group(&hedge).cells;
        for level in 1..MASS_LEVELS {
            let coarse = coarsen(&fine, 1 << level);
            let all: HashMap<_, _> = coarse.iter().map(|c| (c.key, *c)).collect();
            let size = cell_size(level);
            for cell in coarse.iter().filter(|c| c.key.0 > 0 && c.key.0 < 5) {
                let mesh = dome_mesh(std::slice::from_ref(cell), &all, level);
                let extent = |axis: usize| {
                    let values = mesh.positions.iter().map(|p| p[axis]);
                    values.clone().fold(f32::MIN, f32::max) - values.fold(f32::MAX, f32::min)
                };
                // Along the hedge the domes overlap (no gaps); across it a dome is about as
                // wide as the hedge's cells, not as its merged cell (the field beside the hedge
                // stays open).
                assert!(extent(0) >= size, "level {level}: {} m along a {size} m cell: {cell:?}", extent(0));
                assert!(extent(1) < 0.5 * size.max(2.0 * MASS_CELL), "level {level}: {} m across", extent(1));
            }
        }
    }

    #[test]
    fn a_merged_dome_on_a_slope_stands_on_it() {
        // A block of forest on ground rising 0.5 m per metre eastwards.
        let slope = 0.5;
        let plants: Vec<MassPlant> = (0..20)
            .flat_map(|i| (0..20).map(move |j| (i as f32 * 4.0 + 1.0, j as f32 * 4.0 + 1.0)))
            .map(|(x, y)| MassPlant { position: [x, y, 100.0 + slope * x], ..plant(x, y) })
            .collect();
        let coarse = coarsen(&group(&plants).cells, 4);
        let all: HashMap<_, _> = coarse.iter().map(|c| (c.key, *c)).collect();
        let footprint = coarse[0].footprint.expect("a merged cell has a footprint");
        assert!((footprint.slope[0] - slope).abs() < 0.05 && footprint.slope[1].abs() < 0.05, "{footprint:?}");
        let mesh = dome_mesh(&coarse[..1], &all, 2);
        // The base ring lies SKIRT below the ground under it on both sides of the dome.
        let rings = dome_rings(2);
        for p in &mesh.positions[1 + (rings - 1) * SEGMENTS..] {
            let ground = 100.0 + slope * p[0];
            assert!((p[2] - (ground - SKIRT)).abs() < 1.5, "base vertex {p:?} against the ground {ground}");
        }
    }

    #[test]
    fn coarser_levels_merge_cells_and_keep_the_forest() {
        let plants: Vec<MassPlant> =
            (0..20).flat_map(|i| (0..20).map(move |j| plant(i as f32 * 4.0 + 1.0, j as f32 * 4.0 + 1.0))).collect();
        let fine = group(&plants).cells;
        let coarse = coarsen(&fine, 2);
        assert_eq!((fine.len(), coarse.len()), (64, 16), "80 m of forest: 8 × 8 cells, then 4 × 4");
        assert_eq!(coarsen(&fine, 1), fine);
        let mean_cover = fine.iter().map(|c| c.cover).sum::<f32>() / fine.len() as f32;
        for c in &coarse {
            assert!((c.height - 12.0).abs() < 1e-3 && (c.ground - 100.0).abs() < 1e-3, "{c:?}");
            assert!((c.cover - mean_cover).abs() < 0.05, "a full block keeps its cover: {c:?}");
        }
        let depth = |key| coarse.iter().find(|c| c.key == key).map(|c| c.depth);
        assert_eq!((depth((0, 0)), depth((1, 1)), depth((3, 3))), (Some(1), Some(2), Some(1)));
        // A coarse dome is as much wider as its cell, and as high.
        let all: HashMap<_, _> = coarse.iter().map(|c| (c.key, *c)).collect();
        let mesh = dome_mesh(&coarse[..1], &all, 1);
        assert_eq!(mesh.indices.len() as u64, 3 * dome_triangles(1));
        let xs = mesh.positions.iter().map(|p| p[0]);
        let width = xs.clone().fold(f32::MIN, f32::max) - xs.fold(f32::MAX, f32::min);
        assert!(width > MASS_CELL, "a 20 m cell's dome is wider than a 10 m cell: {width}");
        let top = mesh.positions.iter().map(|p| p[2]).fold(f32::MIN, f32::max);
        assert!((top - 112.0).abs() < 1e-3, "{top}");
    }
}
