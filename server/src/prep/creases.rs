//! The terrain's crease lines (issue 18): valley bottoms and ridge crests as polylines on the
//! ground, the lines a pen-and-ink artist puts where the land folds. Valley bottoms are the
//! drainage network of the DEM — its pits and flats filled first (priority flood, Barnes et
//! al. 2014, with a small gradient across flats), every cell flows to its steepest lower
//! neighbour (D8, O'Callaghan & Mark 1984) and the cells draining an area of at least
//! [`MIN_AREA`] carry a line to their downstream cell — and ridge crests the drainage network
//! of the inverted DEM.
//! Each segment keeps the area it drains, so a style draws only the lines above its threshold
//! (`terrain_crease_area`). Breaks of slope — the top of a bank or a scarp, the foot of a
//! slope, a terrace's edge — are where the slope angle changes along the fall line: cells
//! whose change over a short baseline is largest across the line (non-maximum suppression, as
//! Canny does for edges) are linked along the contour, each segment keeping its change in
//! degrees for the style's threshold (`terrain_break_angle`). The lines are fixed to the
//! ground: the same segments in every frame, whatever the camera, the level of detail or the
//! image size.

use crate::scene::terrain::Terrain;
use glam::Vec3;

/// The smallest area (m²) a segment drains to be kept; the styles' thresholds start above.
pub const MIN_AREA: f64 = 2_000.0;

/// The smallest change of slope (degrees) a break-of-slope segment needs to be kept; the
/// styles' thresholds start above.
pub const MIN_BREAK: f64 = 4.0;

/// Valley bottom, ridge crest or break of slope.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CreaseKind {
    Valley = 0,
    Ridge = 1,
    Break = 2,
}

/// One segment of a crease line, in scene metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CreaseSegment {
    pub a: Vec3,
    pub b: Vec3,
    /// How strong the crease is: for a valley or ridge the area the segment drains (of the
    /// inverted DEM for a ridge), m²; for a break of slope the change of slope in degrees
    /// along a line of at least [`MIN_BREAK_LENGTH`] (one of a few levels).
    pub measure: f64,
    pub kind: CreaseKind,
}

/// The valley and ridge segments of `terrain` draining at least [`MIN_AREA`] and its breaks
/// of slope of at least [`MIN_BREAK`].
pub fn crease_lines(terrain: &Terrain) -> Vec<CreaseSegment> {
    let mut lines = network(terrain, 1.0, CreaseKind::Valley);
    lines.extend(network(terrain, -1.0, CreaseKind::Ridge));
    lines.extend(breaks(terrain));
    lines
}

/// A value per DEM cell, sampled bilinearly between cell centres (`None` where a corner
/// cell has none).
struct CellGrid<'a> {
    values: &'a [Option<f64>],
    width: usize,
    height: usize,
}

impl CellGrid<'_> {
    /// The value at fractional cell position (`col`, `row`); only the cells with a weight
    /// need a value (a position on a cell centre needs that cell alone).
    fn sample(&self, col: f64, row: f64) -> Option<f64> {
        let (c, r) = (col.floor(), row.floor());
        if c < 0.0 || r < 0.0 || c >= self.width as f64 || r >= self.height as f64 {
            return None;
        }
        let (fc, fr) = (col - c, row - r);
        // In range: checked above (and below for the next column or row).
        let (c, r) = (c as usize, r as usize);
        let mut sum = 0.0;
        for (dc, dr, weight) in
            [(0, 0, (1.0 - fc) * (1.0 - fr)), (1, 0, fc * (1.0 - fr)), (0, 1, (1.0 - fc) * fr), (1, 1, fc * fr)]
        {
            if weight <= 1e-9 {
                continue;
            }
            if c + dc >= self.width || r + dr >= self.height {
                return None;
            }
            sum += weight * self.values[(r + dr) * self.width + c + dc]?;
        }
        Some(sum)
    }
}

/// The terrain's breaks of slope: per cell the slope angle (from the terrain's normals), its
/// change along the fall line over a baseline of 1.5 cells (at least 3 m) each way, the cells
/// where that change is largest across the line and at least [`MIN_BREAK`], and segments
/// between such cells that are neighbours along the contour and break the same way (the top
/// of a slope or its foot), on lines of at least [`MIN_BREAK_LENGTH`].
fn breaks(terrain: &Terrain) -> Vec<CreaseSegment> {
    let dem = &terrain.dem;
    let (w, h) = (dem.width, dem.height);
    let (positions, normals) = (&terrain.mesh.positions, &terrain.mesh.normals);
    if w < 3 || h < 3 || normals.len() != w * h {
        return Vec::new();
    }
    // Cell size along x (columns) and y (rows), metres.
    let cx = f64::from(Vec3::from(positions[1]).distance(Vec3::from(positions[0]))).max(1e-6);
    let cy = f64::from(Vec3::from(positions[w]).truncate().distance(Vec3::from(positions[0]).truncate())).max(1e-6);
    let slope: Vec<Option<f64>> = (0..w * h)
        .map(|i| dem.get(i % w, i / w).map(|_| f64::from(normals[i][2]).clamp(-1.0, 1.0).acos().to_degrees()))
        .collect();
    // The unit downhill direction (x east, y north) where the ground slopes at least 1°.
    let downhill = |i: usize| {
        let n = normals[i];
        let horizontal = glam::DVec2::new(f64::from(n[0]), f64::from(n[1]));
        (slope[i].is_some() && horizontal.length() > 1f64.to_radians().sin()).then(|| horizontal.normalize())
    };
    let slopes = CellGrid { values: &slope, width: w, height: h };
    // Grid position of a point `d` metres from cell i's centre.
    let at = |i: usize, d: glam::DVec2| ((i % w) as f64 + d.x / cx, (i / w) as f64 - d.y / cy);
    let baseline = (1.5 * cx.max(cy)).max(3.0);
    // The change of slope across cell i: upslope minus downslope (negative at the top of a
    // slope, positive at its foot).
    let change: Vec<Option<f64>> = (0..w * h)
        .map(|i| {
            let g = downhill(i)?;
            let (uc, ur) = at(i, -g * baseline);
            let (dc, dr) = at(i, g * baseline);
            Some(slopes.sample(uc, ur)? - slopes.sample(dc, dr)?)
        })
        .collect();
    let changes = CellGrid { values: &change, width: w, height: h };
    let kept: Vec<bool> = (0..w * h)
        .map(|i| {
            let (Some(g), Some(c)) = (downhill(i), change[i]) else { return false };
            if c.abs() < MIN_BREAK {
                return false;
            }
            // Largest across the line: above its downhill neighbour, not below its uphill
            // one (a tie of two cells keeps the upper, so the line is one cell wide).
            let step = g * cx.min(cy);
            let neighbour = |d: glam::DVec2| {
                let (col, row) = at(i, d);
                changes.sample(col, row).map(f64::abs)
            };
            neighbour(step).is_none_or(|n| n < c.abs()) && neighbour(-step).is_none_or(|n| n <= c.abs())
        })
        .collect();
    let mut links = Vec::new();
    for i in (0..w * h).filter(|&i| kept[i]) {
        let (Some(g), Some(ci)) = (downhill(i), change[i]) else { continue };
        let (col, row) = ((i % w) as i64, (i / w) as i64);
        // Forward neighbours only (each pair once): east, south-west, south, south-east.
        for (dc, dr) in [(1i64, 0i64), (-1, 1), (0, 1), (1, 1)] {
            let (c, r) = (col + dc, row + dr);
            if c < 0 || c >= w as i64 || r >= h as i64 {
                continue;
            }
            let j = r as usize * w + c as usize;
            let Some(cj) = change[j].filter(|_| kept[j]) else { continue };
            let along = glam::DVec2::new(dc as f64 * cx, -(dr as f64) * cy).normalize();
            if ci.signum() == cj.signum() && along.dot(g).abs() < 0.6 {
                links.push((i, j, ci.abs().min(cj.abs())));
            }
        }
    }
    // Lines shorter than [`MIN_BREAK_LENGTH`] are the speckle of a rough surface (a lidar
    // DTM's tussocks and ruts), not a break an artist would draw. A style draws the segments
    // of at least its angle, so the lines are measured at each of [`BREAK_LEVELS`]: a
    // segment's measure is the steepest level at which it lies on a long enough line of
    // segments at least that steep.
    let min_length = MIN_BREAK_LENGTH.max(4.0 * cx.max(cy));
    let mut level = vec![None; links.len()];
    for &threshold in BREAK_LEVELS {
        let mut sets = DisjointSets::new(w * h);
        let steep = || links.iter().enumerate().filter(|(_, l)| l.2 >= threshold);
        for (_, &(i, j, _)) in steep() {
            sets.union(i, j);
        }
        let mut length = vec![0.0f64; w * h];
        for (_, &(i, j, _)) in steep() {
            let root = sets.find(i);
            length[root] += f64::from(Vec3::from(positions[i]).distance(Vec3::from(positions[j])));
        }
        let long: Vec<usize> = steep().filter(|(_, l)| length[sets.find(l.0)] >= min_length).map(|(k, _)| k).collect();
        for k in long {
            level[k] = Some(threshold);
        }
    }
    links
        .into_iter()
        .zip(level)
        .filter_map(|((i, j, _), level)| {
            Some(CreaseSegment {
                a: Vec3::from(positions[i]),
                b: Vec3::from(positions[j]),
                measure: level?,
                kind: CreaseKind::Break,
            })
        })
        .collect()
}

/// The changes of slope (degrees) at which break lines are measured (see [`breaks`]).
const BREAK_LEVELS: &[f64] = &[4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 22.0, 26.0, 30.0, 40.0, 50.0, 60.0];

/// The shortest break-of-slope line kept, metres (at least four cells).
pub const MIN_BREAK_LENGTH: f64 = 25.0;

/// Union–find over cell indices (path halving, union by size): the connected lines of
/// linked break cells.
struct DisjointSets {
    parent: Vec<usize>,
    size: Vec<u32>,
}

impl DisjointSets {
    fn new(n: usize) -> DisjointSets {
        DisjointSets { parent: (0..n).collect(), size: vec![1; n] }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        if self.size[a] < self.size[b] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b] = a;
        self.size[a] += self.size[b];
    }
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
        .map(|(i, j)| CreaseSegment { a: smoothed(i), b: smoothed(j), measure: cells[i] * cell_area, kind })
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
    /// A terrain of `n` × `n` cells of 10 m in UTM 13N with `height(col, row)`.
    fn terrain_of(n: usize, height: impl Fn(f64, f64) -> f64) -> Terrain {
        let data = (0..n * n).map(|i| height((i % n) as f64, (i / n) as f64)).collect();
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

    fn valley() -> Terrain {
        terrain_of(41, |col, row| 100.0 + 2.0 * (col - 20.0).abs() - 0.5 * row)
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
        assert!(
            south.measure > 10.0 * north.measure,
            "drains {} at the south end, {} at the north",
            south.measure,
            north.measure
        );
        assert!(axis.iter().all(|s| s.b.y < s.a.y), "every axis segment runs downstream (south)");
        // No ridge crosses the valley bottom: the crests are its two edges.
        assert!(lines.iter().filter(|s| s.kind == CreaseKind::Ridge).all(|s| s.a.x.abs() > 150.0));
    }

    /// A terrace: flat at 100 m west of x = −100 m, a 30° slope down to x = +100 m, flat
    /// below (10 m cells, north–south lines).
    fn terrace() -> Terrain {
        let drop = 30f64.to_radians().tan();
        terrain_of(61, move |col, _| 100.0 - drop * (((col - 30.0) * 10.0).clamp(-100.0, 100.0) + 100.0))
    }

    #[test]
    fn a_terrace_has_break_lines_along_its_top_and_its_foot() {
        let breaks: Vec<CreaseSegment> =
            crease_lines(&terrace()).into_iter().filter(|s| s.kind == CreaseKind::Break).collect();
        let near = |x: f32| breaks.iter().filter(|s| (s.a.x - x).abs() <= 10.0 && (s.b.x - x).abs() <= 10.0).count();
        // Both edges run the terrace's length (60 cells north to south) as one line each, and
        // nothing else breaks.
        for x in [-100.0, 100.0] {
            assert!((50..=60).contains(&near(x)), "{} segments along the edge at x = {x}", near(x));
        }
        assert_eq!(near(-100.0) + near(100.0), breaks.len(), "breaks elsewhere: {breaks:?}");
        for s in &breaks {
            assert!((s.a.y - s.b.y).abs() >= (s.a.x - s.b.x).abs(), "a segment across the slope: {s:?}");
            assert!(s.measure > 15.0 && s.measure <= 31.0, "a change of {}°", s.measure);
        }
        // A plane of one slope has none.
        assert!(crease_lines(&valley()).iter().all(|s| s.kind != CreaseKind::Break || s.measure < 15.0));
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
