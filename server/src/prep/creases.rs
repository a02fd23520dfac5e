//! The terrain's crease lines (issue 18): valley bottoms and ridge crests as polylines on the
//! ground, the lines a pen-and-ink artist puts where the land folds. Valley bottoms are the
//! drainage network of the DEM — its pits and flats filled first (priority flood, Barnes et
//! al. 2014, with a small gradient across flats), every cell flows to its steepest lower
//! neighbour (D8, O'Callaghan & Mark 1984) and the cells draining an area of at least
//! [`MIN_AREA`] carry a line to their downstream cell — and ridge crests the drainage network
//! of the inverted DEM.
//! Each segment keeps the area it drains, so a style draws only the lines above its threshold
//! (`terrain_crease_area`). The lines are fixed to the ground: the same segments in every
//! frame, whatever the camera, the level of detail or the image size.

use crate::scene::terrain::Terrain;
use glam::Vec3;

/// The smallest area (m²) a segment drains to be kept; the styles' thresholds start above.
pub const MIN_AREA: f64 = 2_000.0;

/// Valley bottom or ridge crest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CreaseKind {
    Valley = 0,
    Ridge = 1,
}

/// One segment of a crease line, in scene metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CreaseSegment {
    pub a: Vec3,
    pub b: Vec3,
    /// The area the segment drains (of the inverted DEM for a ridge), m².
    pub area: f64,
    pub kind: CreaseKind,
}

/// The valley and ridge segments of `terrain` draining at least [`MIN_AREA`].
pub fn crease_lines(terrain: &Terrain) -> Vec<CreaseSegment> {
    let mut lines = network(terrain, 1.0, CreaseKind::Valley);
    lines.extend(network(terrain, -1.0, CreaseKind::Ridge));
    lines
}

/// The drainage network of `sign` × the terrain's heights as segments of `kind`. Vertices
/// are the DEM's cell centres (the terrain's vertices), each moved half-way towards the mean
/// of its downstream cell and its largest upstream one (one pass of smoothing along the
/// line, so the eight directions of D8 do not zigzag), and put back on the ground.
fn network(terrain: &Terrain, sign: f64, kind: CreaseKind) -> Vec<CreaseSegment> {
    let dem = &terrain.dem;
    let (w, h) = (dem.width, dem.height);
    let positions = &terrain.mesh.positions;
    let stored = |i: usize| dem.get(i % w, i / w).map(|z| sign * z);
    let filled = fill_depressions(w, h, stored);
    let height = |i: usize| filled[i];
    let cell_area = {
        let (a, b) = (Vec3::from(positions[0]), Vec3::from(positions[w.min(positions.len() - 1)]));
        let dx = Vec3::from(positions[1.min(positions.len() - 1)]).distance(a);
        f64::from(dx * b.distance(a)).max(1e-6)
    };
    // D8: the steepest lower neighbour of every valid cell (by drop per metre).
    let mut down: Vec<Option<usize>> = vec![None; w * h];
    for (i, slot) in down.iter_mut().enumerate() {
        let Some(z) = height(i) else { continue };
        let (col, row) = ((i % w) as i64, (i / w) as i64);
        let mut best = (0.0f64, None);
        for (dc, dr) in NEIGHBOURS {
            let (c, r) = (col + dc, row + dr);
            if c < 0 || r < 0 || c >= w as i64 || r >= h as i64 {
                continue;
            }
            let j = (r as usize) * w + c as usize;
            if let Some(zj) = height(j) {
                let run = f64::from(Vec3::from(positions[i]).truncate().distance(Vec3::from(positions[j]).truncate()));
                let drop = (z - zj) / run.max(1e-6);
                if drop > best.0 {
                    best = (drop, Some(j));
                }
            }
        }
        *slot = best.1;
    }
    // Accumulate from the highest cell down.
    let mut order: Vec<usize> = (0..w * h).filter(|&i| height(i).is_some()).collect();
    order.sort_by(|&a, &b| height(b).unwrap_or(0.0).total_cmp(&height(a).unwrap_or(0.0)));
    let mut cells = vec![1.0f64; w * h];
    let mut main_up: Vec<Option<usize>> = vec![None; w * h];
    for &i in &order {
        if let Some(j) = down[i] {
            cells[j] += cells[i];
            if main_up[j].is_none_or(|u| cells[u] < cells[i]) {
                main_up[j] = Some(i);
            }
        }
    }
    let keep = |i: usize| cells[i] * cell_area >= MIN_AREA;
    let smoothed = |i: usize| {
        let p = Vec3::from(positions[i]);
        let (Some(d), Some(u)) = (down[i], main_up[i].filter(|&u| keep(u))) else { return p };
        let q = p.lerp((Vec3::from(positions[d]) + Vec3::from(positions[u])) * 0.5, 0.5);
        let z = terrain.height_at(f64::from(q.x), f64::from(q.y)).map_or(q.z, |z| z as f32);
        Vec3::new(q.x, q.y, z)
    };
    // Segments across filled pits and flats (no real drop: a lake, a plain) draw no line.
    let falls = |i: usize, j: usize| match (stored(i), stored(j)) {
        (Some(a), Some(b)) => a - b > MIN_DROP,
        _ => false,
    };
    (0..w * h)
        .filter(|&i| keep(i))
        .filter_map(|i| down[i].map(|j| (i, j)))
        .filter(|&(i, j)| falls(i, j))
        .map(|(i, j)| CreaseSegment { a: smoothed(i), b: smoothed(j), area: cells[i] * cell_area, kind })
        .collect()
}

/// Neighbour offsets of D8.
const NEIGHBOURS: [(i64, i64); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// The least drop in metres (of the DEM as stored) along a segment that draws a line.
const MIN_DROP: f64 = 1e-3;

/// Increment across filled flats, metres: enough to give them a direction of flow.
const FLAT_GRADIENT: f64 = 1e-5;

/// The heights `height` of a `w` × `h` grid (None: nodata) with every depression filled to
/// its spill point and flats sloped towards their outlet by [`FLAT_GRADIENT`] per cell
/// (priority flood from the grid's edge and nodata: cells are taken lowest first, each
/// neighbour raised to at least the cell's height plus the gradient), so that every cell
/// drains to the edge.
fn fill_depressions(w: usize, h: usize, height: impl Fn(usize) -> Option<f64>) -> Vec<Option<f64>> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let mut filled: Vec<Option<f64>> = (0..w * h).map(&height).collect();
    let mut done = vec![false; w * h];
    let mut queue = BinaryHeap::new();
    let key = |z: f64| Reverse(ordered(z));
    let neighbours = |i: usize| {
        let (col, row) = ((i % w) as i64, (i / w) as i64);
        NEIGHBOURS.iter().filter_map(move |(dc, dr)| {
            let (c, r) = (col + dc, row + dr);
            (c >= 0 && r >= 0 && c < w as i64 && r < h as i64).then(|| r as usize * w + c as usize)
        })
    };
    for i in 0..w * h {
        let Some(z) = filled[i] else { continue };
        let (col, row) = (i % w, i / w);
        let edge = col == 0 || row == 0 || col == w - 1 || row == h - 1 || neighbours(i).any(|j| filled[j].is_none());
        if edge {
            done[i] = true;
            queue.push((key(z), i));
        }
    }
    while let Some((_, i)) = queue.pop() {
        let z = filled[i].unwrap_or(0.0);
        for j in neighbours(i) {
            if done[j] {
                continue;
            }
            if let Some(zj) = filled[j] {
                let raised = zj.max(z + FLAT_GRADIENT);
                filled[j] = Some(raised);
                done[j] = true;
                queue.push((key(raised), j));
            }
        }
    }
    filled
}

/// A total order on heights for the priority queue (NaN never occurs: nodata is `None`).
fn ordered(z: f64) -> i64 {
    let bits = z.to_bits() as i64;
    if bits < 0 { bits ^ i64::MAX } else { bits }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::{Crs, GeoTransform, Raster};

    /// A V-shaped valley running north-south along x = 0, sloping down to the south; 10 m cells.
    fn valley() -> Terrain {
        let n = 41;
        let data = (0..n * n)
            .map(|i| {
                let (col, row) = ((i % n) as f64 - 20.0, (i / n) as f64);
                100.0 + 2.0 * col.abs() - 0.5 * row
            })
            .collect();
        let dem = Raster {
            width: n,
            height: n,
            data,
            nodata: None,
            transform: GeoTransform { origin_x: 500_000.0, origin_y: 4_400_000.0, cell_width: 10.0, cell_height: 10.0 },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        };
        Terrain::new(dem, [1.0; 3]).expect("terrain")
    }

    #[test]
    fn the_valley_bottom_is_a_line_down_its_axis_draining_more_downstream() {
        let lines = crease_lines(&valley());
        let valleys: Vec<&CreaseSegment> = lines.iter().filter(|s| s.kind == CreaseKind::Valley).collect();
        // The bottom (x = 0) from north to south, plus short side rills at most.
        let axis: Vec<&&CreaseSegment> = valleys.iter().filter(|s| s.a.x.abs() < 1.0 && s.b.x.abs() < 1.0).collect();
        assert!(axis.len() >= 30, "{} segments on the axis", axis.len());
        let south = axis.iter().min_by(|a, b| a.a.y.total_cmp(&b.a.y)).expect("a segment");
        let north = axis.iter().max_by(|a, b| a.a.y.total_cmp(&b.a.y)).expect("a segment");
        assert!(south.area > 10.0 * north.area, "drains {} at the south end, {} at the north", south.area, north.area);
        assert!(axis.iter().all(|s| s.b.y < s.a.y), "every axis segment runs downstream (south)");
        // No ridge crosses the valley bottom: the crests are its two edges.
        assert!(lines.iter().filter(|s| s.kind == CreaseKind::Ridge).all(|s| s.a.x.abs() > 150.0));
    }

    #[test]
    fn a_pit_is_filled_so_the_valley_drains_through_it() {
        // A 3 × 3 grid with a pit in the middle and the outlet at the south-west corner.
        let heights = [5.0, 5.0, 5.0, 5.0, 1.0, 5.0, 2.0, 5.0, 5.0];
        let filled = fill_depressions(3, 3, |i| Some(heights[i]));
        let centre = filled[4].expect("valid");
        assert!(centre > 2.0 && centre < 2.001, "filled to the spill point: {centre}");
        assert_eq!(filled[6], Some(2.0));
        assert!(ordered(-1.0) < ordered(-0.5) && ordered(-0.5) < ordered(0.0) && ordered(0.0) < ordered(3.0));
    }
}
