//! Levels of detail of the terrain (SPEC P4): the DEM's triangle mesh split into square chunks,
//! each with index ranges at several levels (geomipmapping, de Boer 2000: level k uses every
//! 2^k-th row and column of the DEM, counted from the chunk's corner), all sharing one vertex
//! list, so a renderer culls chunks by their bounding spheres and picks a level per chunk from
//! the projected size of a DEM cell.
//!
//! - **Level 0** is the chunk's part of [`Terrain::new`]'s triangulation, triangle for triangle.
//! - **Coarser levels**: a quad of level k spans 2^k × 2^k cells (the last quad of a chunk whose
//!   size is not a multiple is shorter, clamped to the chunk's last row and column). A quad
//!   with nodata anywhere inside falls back to its four level-(k − 1) quads, recursively down
//!   to the level-0 quads, which are left out where a corner is nodata as in `Terrain::new`;
//!   so every level covers exactly the area of level 0 and never spans a nodata cell.
//! - **Skirts** hide the cracks where surfaces of different resolution meet — at chunk borders
//!   (the neighbour may be drawn at another level) and inside a chunk where a coarse quad meets
//!   the finer quads of a fallback: every side of a drawn quad whose neighbour across it is not
//!   a quad of the same level in the same chunk gets a vertical strip of two triangles from the
//!   side's two vertices down to copies of them (same normals and uvs), facing outwards. Sides
//!   with no valid data across them (the DEM's border, nodata) get none, so holes stay holes.
//!   Both surfaces along such a side interpolate heights of vertices on that side, so a crack is
//!   never deeper than the chunk's height range: the copies are lowered by that range (at least
//!   one cell size), which takes every skirt's lower edge below the chunk's lowest point.

use std::ops::Range;

use glam::Vec3;

use crate::scene::mesh::Mesh;
use crate::scene::terrain::Terrain;

/// The terrain split into square chunks of `chunk_cells` × `chunk_cells` quads, each with
/// index ranges at several levels (geomipmapping: level k uses every 2^k-th row and column of
/// the DEM), sharing one vertex list; skirts hide cracks between chunks at different levels.
#[derive(Debug, Clone)]
pub struct TerrainLod {
    /// Vertices: the terrain's own (same order, so per-vertex data stays valid), then skirt
    /// vertices; `indices` holds every chunk's every level, back to back.
    pub mesh: Mesh,
    /// The chunks, row-major from the north-west; chunks without any valid quad are left out.
    pub chunks: Vec<TerrainChunk>,
    cell_size: f32,
    source_triangles: u64,
}

/// One chunk of [`TerrainLod`]: its bounding sphere and its levels.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainChunk {
    /// Bounding sphere (scene metres) for frustum culling.
    pub center: Vec3,
    /// Radius of the bounding sphere (skirts included).
    pub radius: f32,
    /// Index ranges into `mesh.indices` per level, finest first (level 0 = every quad of the
    /// chunk exactly as `Terrain::new` triangulates it). Each range includes the level's skirts.
    pub levels: Vec<Range<u32>>,
}

/// A rectangle of quads: columns `c0..c1`, rows `r0..r1` (vertex columns `c0..=c1`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    c0: usize,
    r0: usize,
    c1: usize,
    r1: usize,
}

impl Block {
    fn contains(&self, col: usize, row: usize) -> bool {
        (self.c0..self.c1).contains(&col) && (self.r0..self.r1).contains(&row)
    }

    fn area(&self) -> u32 {
        ((self.c1 - self.c0) * (self.r1 - self.r0)) as u32
    }
}

/// The DEM's quads (between four cell centres) with a summed-area table of the valid ones
/// (four valid corners), so that any rectangle is counted in constant time.
struct QuadGrid {
    quads_w: usize,
    quads_h: usize,
    /// `(quads_w + 1) × (quads_h + 1)`: valid quads in columns `0..c`, rows `0..r`.
    sum: Vec<u32>,
}

impl QuadGrid {
    fn new(terrain: &Terrain) -> QuadGrid {
        let dem = &terrain.dem;
        let (quads_w, quads_h) = (dem.width - 1, dem.height - 1);
        let valid: Vec<bool> =
            (0..dem.height).flat_map(|row| (0..dem.width).map(move |col| dem.get(col, row).is_some())).collect();
        let stride = quads_w + 1;
        let mut sum = vec![0u32; stride * (quads_h + 1)];
        for row in 0..quads_h {
            let mut run = 0;
            for col in 0..quads_w {
                let v = |c: usize, r: usize| valid[r * dem.width + c];
                run += u32::from(v(col, row) && v(col + 1, row) && v(col, row + 1) && v(col + 1, row + 1));
                sum[(row + 1) * stride + col + 1] = sum[row * stride + col + 1] + run;
            }
        }
        QuadGrid { quads_w, quads_h, sum }
    }

    /// Number of valid quads in `b`.
    fn count(&self, b: Block) -> u32 {
        let at = |c: usize, r: usize| self.sum[r * (self.quads_w + 1) + c];
        at(b.c1, b.r1) + at(b.c0, b.r0) - at(b.c0, b.r1) - at(b.c1, b.r0)
    }
}

/// Marker in [`ChunkBuilder::owner`] for a quad no drawn quad covers.
const NO_QUAD: u8 = u8::MAX;

/// Builds one chunk's levels into the shared mesh.
struct ChunkBuilder<'a> {
    grid: &'a QuadGrid,
    /// Vertices per DEM row.
    stride: usize,
    chunk: Block,
    /// Whether every quad of the chunk is valid: then no quad falls back, every quad inside
    /// the chunk has neighbours of its own level, only the chunk's border needs skirts and
    /// `owner` is not kept.
    complete: bool,
    /// How far skirt vertices are lowered.
    depth: f32,
    /// Per quad of the chunk: the level of the drawn quad covering it at the current level.
    owner: Vec<u8>,
    /// The drawn quads of the current level with their levels.
    drawn: Vec<(u8, Block)>,
    /// Per vertex of the chunk: its lowered copy, `u32::MAX` before it is made.
    lowered: Vec<u32>,
}

impl ChunkBuilder<'_> {
    fn vertex(&self, col: usize, row: usize) -> u32 {
        // Indices fit: the DEM has at most `MAX_CELLS` = 2^28 cells.
        (row * self.stride + col) as u32
    }

    fn owner_at(&self, col: usize, row: usize) -> u8 {
        self.owner[(row - self.chunk.r0) * (self.chunk.c1 - self.chunk.c0) + col - self.chunk.c0]
    }

    /// Appends one level (its quads, then its skirts) to `mesh.indices` and returns its range.
    fn level(&mut self, level: u8, mesh: &mut Mesh) -> Range<u32> {
        let start = mesh.indices.len() as u32;
        if !self.complete {
            self.owner.fill(NO_QUAD);
        }
        self.drawn.clear();
        let step = 1usize << level;
        let Block { c0, r0, c1, r1 } = self.chunk;
        for row in (r0..r1).step_by(step) {
            for col in (c0..c1).step_by(step) {
                let block = Block { c0: col, r0: row, c1: (col + step).min(c1), r1: (row + step).min(r1) };
                self.quads(level, block, &mut mesh.indices);
            }
        }
        let chunk = self.chunk;
        for i in 0..self.drawn.len() {
            let (level, b) = self.drawn[i];
            if !self.complete || b.c0 == chunk.c0 || b.r0 == chunk.r0 || b.c1 == chunk.c1 || b.r1 == chunk.r1 {
                self.skirts(level, b, mesh);
            }
        }
        start..mesh.indices.len() as u32
    }

    /// Draws `b` as one quad of `level` when all its cells are valid, else falls back to its
    /// quads of the next finer level.
    fn quads(&mut self, level: u8, b: Block, indices: &mut Vec<u32>) {
        let valid = if self.complete { b.area() } else { self.grid.count(b) };
        if valid == b.area() {
            let (nw, ne, sw, se) =
                (self.vertex(b.c0, b.r0), self.vertex(b.c1, b.r0), self.vertex(b.c0, b.r1), self.vertex(b.c1, b.r1));
            // The winding of `Terrain::new`: counter-clockwise from above.
            indices.extend_from_slice(&[nw, sw, se, nw, se, ne]);
            if !self.complete {
                let width = self.chunk.c1 - self.chunk.c0;
                for row in b.r0..b.r1 {
                    let at = (row - self.chunk.r0) * width;
                    self.owner[at + b.c0 - self.chunk.c0..at + b.c1 - self.chunk.c0].fill(level);
                }
            }
            self.drawn.push((level, b));
        } else if valid > 0 && level > 0 {
            let half = 1usize << (level - 1);
            let (cm, rm) = ((b.c0 + half).min(b.c1), (b.r0 + half).min(b.r1));
            for (r0, r1) in [(b.r0, rm), (rm, b.r1)] {
                for (c0, c1) in [(b.c0, cm), (cm, b.c1)] {
                    if c0 < c1 && r0 < r1 {
                        self.quads(level - 1, Block { c0, r0, c1, r1 }, indices);
                    }
                }
            }
        }
    }

    /// The skirts of the drawn quad `b` of `level`: on each side with valid data across it that
    /// is not covered by a quad of the same level of this chunk.
    fn skirts(&mut self, level: u8, b: Block, mesh: &mut Mesh) {
        let grid = self.grid;
        // The sides counter-clockwise from above (interior on the left) with the strip of quads
        // across each, if inside the DEM.
        let sides = [
            ((b.c0, b.r0), (b.c0, b.r1), (b.c0 > 0).then(|| Block { c0: b.c0 - 1, c1: b.c0, ..b })),
            ((b.c0, b.r1), (b.c1, b.r1), (b.r1 < grid.quads_h).then_some(Block { r0: b.r1, r1: b.r1 + 1, ..b })),
            ((b.c1, b.r1), (b.c1, b.r0), (b.c1 < grid.quads_w).then_some(Block { c0: b.c1, c1: b.c1 + 1, ..b })),
            ((b.c1, b.r0), (b.c0, b.r0), (b.r0 > 0).then(|| Block { r0: b.r0 - 1, r1: b.r0, ..b })),
        ];
        for (from, to, strip) in sides {
            let Some(strip) = strip else { continue };
            let same_level = self.chunk.contains(strip.c0, strip.r0)
                && (self.complete || self.owner_at(strip.c0, strip.r0) == level);
            if same_level || grid.count(strip) == 0 {
                continue;
            }
            let (a, b) = (self.vertex(from.0, from.1), self.vertex(to.0, to.1));
            let (la, lb) = (self.lowered(from, mesh), self.lowered(to, mesh));
            // A wall under a → b, counter-clockwise seen from outside.
            mesh.indices.extend_from_slice(&[a, la, lb, a, lb, b]);
        }
    }

    /// The lowered copy of the vertex at `(col, row)`, made on first use.
    fn lowered(&mut self, (col, row): (usize, usize), mesh: &mut Mesh) -> u32 {
        let slot = (row - self.chunk.r0) * (self.chunk.c1 - self.chunk.c0 + 1) + col - self.chunk.c0;
        if self.lowered[slot] == u32::MAX {
            let top = row * self.stride + col;
            let [x, y, z] = mesh.positions[top];
            self.lowered[slot] = mesh.positions.len() as u32;
            mesh.positions.push([x, y, z - self.depth]);
            mesh.normals.push(mesh.normals[top]);
            mesh.uvs.push(mesh.uvs[top]);
        }
        self.lowered[slot]
    }
}

impl TerrainLod {
    /// Builds the chunks of `terrain` with up to `max_levels` levels: every chunk gets the same
    /// number, `max_levels` but no more than needed to reach one quad per chunk
    /// (1 + ⌈log₂ chunk_cells⌉), at least 1. A `chunk_cells` of 0 counts as 1.
    pub fn build(terrain: &Terrain, chunk_cells: usize, max_levels: usize) -> TerrainLod {
        let n = chunk_cells.max(1);
        let levels = max_levels.clamp(1, 1 + n.next_power_of_two().trailing_zeros() as usize);
        let grid = QuadGrid::new(terrain);
        let cell_size = cell_size(terrain);
        // Room for the skirts (about one lowered vertex per chunk border vertex, two walls per
        // border segment over all levels) and for all levels (level 0 plus ~1/3 for the rest).
        let chunk_count = grid.quads_w.div_ceil(n) * grid.quads_h.div_ceil(n);
        let skirt_vertices = chunk_count * 2 * (n.min(grid.quads_w) + n.min(grid.quads_h) + 2);
        let full = grid.count(Block { c0: 0, r0: 0, c1: grid.quads_w, r1: grid.quads_h }) as usize;
        let source = &terrain.mesh;
        let mut mesh = Mesh {
            positions: with_room(&source.positions, skirt_vertices),
            normals: with_room(&source.normals, skirt_vertices),
            uvs: with_room(&source.uvs, skirt_vertices),
            indices: Vec::with_capacity(8 * full + 24 * skirt_vertices),
        };
        let mut chunks = Vec::new();
        let mut source_triangles = 0;
        for r0 in (0..grid.quads_h).step_by(n) {
            for c0 in (0..grid.quads_w).step_by(n) {
                let chunk = Block { c0, r0, c1: (c0 + n).min(grid.quads_w), r1: (r0 + n).min(grid.quads_h) };
                let valid = grid.count(chunk);
                if valid == 0 {
                    continue;
                }
                let (lo, hi) = chunk_bounds(terrain, chunk);
                let depth = (hi.z - lo.z).max(cell_size);
                let quads = ((chunk.c1 - c0) * (chunk.r1 - r0), (chunk.c1 - c0 + 1) * (chunk.r1 - r0 + 1));
                let mut builder = ChunkBuilder {
                    grid: &grid,
                    stride: terrain.dem.width,
                    chunk,
                    complete: valid == chunk.area(),
                    depth,
                    owner: vec![NO_QUAD; quads.0],
                    drawn: Vec::new(),
                    lowered: vec![u32::MAX; quads.1],
                };
                let levels: Vec<Range<u32>> = (0..levels as u8).map(|k| builder.level(k, &mut mesh)).collect();
                source_triangles += 2 * u64::from(valid);
                let lo = lo - Vec3::Z * depth;
                chunks.push(TerrainChunk { center: (lo + hi) * 0.5, radius: (hi - lo).length() * 0.5, levels });
            }
        }
        TerrainLod { mesh, chunks, cell_size, source_triangles }
    }

    /// DEM cell size in metres (for projected sizes): the larger of the mean spacings of the
    /// cell centres along x and y.
    pub fn cell_size(&self) -> f32 {
        self.cell_size
    }

    /// Triangles of the finest level of all chunks (= the terrain's own count, skirts excluded).
    pub fn source_triangles(&self) -> u64 {
        self.source_triangles
    }
}

impl TerrainChunk {
    /// The level to draw when one DEM cell is `cell_px` pixels on screen: the coarsest level
    /// whose cells (2^k · cell) stay below `target_px` pixels, at least 0 (also for a NaN size).
    pub fn level_for(&self, cell_px: f32, target_px: f32) -> usize {
        let coarsest = self.levels.len().saturating_sub(1);
        (1..=coarsest).take_while(|&k| cell_px * 2f32.powi(k as i32) < target_px).last().unwrap_or(0)
    }
}

/// A copy of `items` with capacity for `extra` more.
fn with_room<T: Clone>(items: &[T], extra: usize) -> Vec<T> {
    let mut copy = Vec::with_capacity(items.len() + extra);
    copy.extend_from_slice(items);
    copy
}

/// The larger of the mean spacings of the terrain's cell centres along x and y (metres).
fn cell_size(terrain: &Terrain) -> f32 {
    let (w, h) = (terrain.dem.width, terrain.dem.height);
    let p = &terrain.mesh.positions;
    let dx = (p[w - 1][0] - p[0][0]).abs() / (w - 1) as f32;
    let dy = (p[0][1] - p[(h - 1) * w][1]).abs() / (h - 1) as f32;
    dx.max(dy)
}

/// Bounds `(min, max)` of the valid vertices of `chunk`.
fn chunk_bounds(terrain: &Terrain, chunk: Block) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for row in chunk.r0..=chunk.r1 {
        for col in chunk.c0..=chunk.c1 {
            if terrain.dem.get(col, row).is_some() {
                let p = Vec3::from(terrain.mesh.positions[row * terrain.dem.width + col]);
                (lo, hi) = (lo.min(p), hi.max(p));
            }
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::{Crs, GeoTransform, Raster};
    use glam::Vec2;
    use std::collections::{HashMap, HashSet};

    const NODATA: f64 = -9999.0;

    /// A terrain of `w` × `h` cells of 10 m with heights `z(col, row)` (`None`: nodata).
    fn terrain(w: usize, h: usize, z: impl Fn(usize, usize) -> Option<f64>) -> Terrain {
        let data = (0..h).flat_map(|r| (0..w).map(move |c| (c, r))).map(|(c, r)| z(c, r).unwrap_or(NODATA)).collect();
        let dem = Raster {
            width: w,
            height: h,
            data,
            nodata: Some(NODATA),
            transform: GeoTransform { origin_x: 500_000.0, origin_y: 4_400_000.0, cell_width: 10.0, cell_height: 10.0 },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        };
        Terrain::new(dem, [0.8; 3]).expect("terrain")
    }

    fn hills(c: usize, r: usize) -> Option<f64> {
        Some(100.0 + 30.0 * (c as f64 * 0.3).sin() * (r as f64 * 0.2).cos() + r as f64)
    }

    /// Hills with nodata: a disc, the north-west corner and one single cell.
    fn holes(c: usize, r: usize) -> Option<f64> {
        let disc = (c as f64 - 22.0).powi(2) + (r as f64 - 20.0).powi(2) < 30.0;
        let corner = c < 7 && r < 5;
        (!(disc || corner || (c, r) == (9, 31))).then(|| hills(c, r)).flatten()
    }

    fn triangles(lod: &TerrainLod, range: &Range<u32>) -> Vec<[u32; 3]> {
        lod.mesh.indices[range.start as usize..range.end as usize].chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
    }

    /// The level's triangles split into surface and skirt triangles (those with a skirt vertex).
    fn split(lod: &TerrainLod, t: &Terrain, range: &Range<u32>) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
        let n = t.mesh.positions.len() as u32;
        triangles(lod, range).into_iter().partition(|tri| tri.iter().all(|&v| v < n))
    }

    fn xy(lod: &TerrainLod, v: u32) -> Vec2 {
        Vec3::from(lod.mesh.positions[v as usize]).truncate()
    }

    /// Signed area of a triangle projected on xy (positive: counter-clockwise from above).
    fn area(lod: &TerrainLod, [a, b, c]: [u32; 3]) -> f32 {
        0.5 * (xy(lod, b) - xy(lod, a)).perp_dot(xy(lod, c) - xy(lod, a))
    }

    fn level_area(lod: &TerrainLod, tris: &[[u32; 3]]) -> f64 {
        tris.iter().map(|&t| f64::from(area(lod, t))).sum()
    }

    /// Whether the DEM has a valid quad in the strip of quads along the grid segment `a → b`
    /// on its right (the outside of a counter-clockwise boundary).
    fn data_across(t: &Terrain, a: u32, b: u32) -> bool {
        let w = t.dem.width;
        let ((ca, ra), (cb, rb)) = ((a as usize % w, a as usize / w), (b as usize % w, b as usize / w));
        let quad_valid = |c: usize, r: usize| {
            [(c, r), (c + 1, r), (c, r + 1), (c + 1, r + 1)].iter().all(|&(c, r)| t.dem.get(c, r).is_some())
        };
        // Rows run south: going south (rb > ra) the right is west; going east the right is south.
        let quads: Vec<(Option<usize>, Option<usize>)> = if ca == cb {
            let col = if rb > ra { ca.checked_sub(1) } else { Some(ca) };
            (ra.min(rb)..ra.max(rb)).map(|r| (col, Some(r))).collect()
        } else {
            assert_eq!(ra, rb, "boundary edges run along the grid");
            let row = if cb > ca { Some(ra) } else { ra.checked_sub(1) };
            (ca.min(cb)..ca.max(cb)).map(|c| (Some(c), row)).collect()
        };
        quads.into_iter().any(|q| matches!(q, (Some(c), Some(r)) if quad_valid(c, r)))
    }

    #[test]
    fn level_zero_is_the_terrain_triangulation() {
        let t = terrain(37, 29, holes);
        let lod = TerrainLod::build(&t, 8, 5);
        assert_eq!(lod.mesh.positions[..t.mesh.positions.len()], t.mesh.positions[..]);
        assert_eq!(lod.mesh.normals[..t.mesh.normals.len()], t.mesh.normals[..]);
        assert_eq!(lod.mesh.uvs[..t.mesh.uvs.len()], t.mesh.uvs[..]);
        let mut level0: Vec<[u32; 3]> = lod.chunks.iter().flat_map(|c| split(&lod, &t, &c.levels[0]).0).collect();
        let mut source: Vec<[u32; 3]> = t.mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        level0.sort_unstable();
        source.sort_unstable();
        assert_eq!(level0, source);
        assert_eq!(lod.source_triangles(), t.mesh.triangle_count() as u64);
        assert_eq!(lod.cell_size(), 10.0);
        assert!(lod.chunks.iter().all(|c| c.levels.len() == 4), "1 + log2(8) levels");
    }

    #[test]
    fn coarser_levels_have_a_quarter_of_the_triangles() {
        // A DEM that is a multiple of the chunk size: exactly a quarter per level.
        let t = terrain(257, 257, hills);
        let lod = TerrainLod::build(&t, 64, 10);
        assert_eq!(lod.chunks.len(), 16);
        let count = |lod: &TerrainLod, t: &Terrain, k: usize| {
            lod.chunks.iter().map(|c| split(lod, t, &c.levels[k]).0.len()).sum::<usize>()
        };
        assert_eq!(count(&lod, &t, 0), 256 * 256 * 2);
        for k in 1..7 {
            assert_eq!(count(&lod, &t, k) * 4, count(&lod, &t, k - 1), "level {k}");
        }
        // A DEM that is not: shorter last quads, about a quarter.
        let t = terrain(250, 250, hills);
        let lod = TerrainLod::build(&t, 64, 3);
        assert!(lod.chunks.iter().all(|c| c.levels.len() == 3));
        for k in 1..3 {
            let ratio = count(&lod, &t, k - 1) as f64 / count(&lod, &t, k) as f64;
            assert!((3.5..=4.0).contains(&ratio), "level {k}: {ratio}");
        }
    }

    #[test]
    fn every_level_covers_its_chunk_counter_clockwise() {
        let t = terrain(45, 38, hills);
        let lod = TerrainLod::build(&t, 16, 8);
        let mut total = 0.0;
        for chunk in &lod.chunks {
            let level0 = level_area(&lod, &split(&lod, &t, &chunk.levels[0]).0);
            total += level0;
            for range in &chunk.levels {
                let (surface, skirts) = split(&lod, &t, range);
                assert!(surface.iter().all(|&tri| area(&lod, tri) > 0.0), "counter-clockwise from above");
                assert!(skirts.iter().all(|&tri| area(&lod, tri).abs() < 1e-3), "skirts are vertical");
                let a = level_area(&lod, &surface);
                assert!((a - level0).abs() < 1e-6 * level0, "{a} vs {level0}");
            }
        }
        assert!((total - 44.0 * 37.0 * 100.0).abs() < 1e-3, "{total}");
    }

    #[test]
    fn coarse_levels_fall_back_around_nodata() {
        let t = terrain(40, 40, holes);
        let lod = TerrainLod::build(&t, 16, 5);
        let w = t.dem.width;
        let nodata: Vec<u32> = (0..t.mesh.positions.len() as u32)
            .filter(|&v| t.dem.get(v as usize % w, v as usize / w).is_none())
            .collect();
        let mut coarse_quads = 0;
        for chunk in &lod.chunks {
            let level0 = level_area(&lod, &split(&lod, &t, &chunk.levels[0]).0);
            for range in &chunk.levels {
                let surface = split(&lod, &t, range).0;
                assert!((level_area(&lod, &surface) - level0).abs() < 1e-6 * level0, "same area as level 0");
                for &tri in &surface {
                    let [a, b, c] = tri.map(|v| xy(&lod, v));
                    coarse_quads += usize::from((b - a).length() > 15.0);
                    for &v in &nodata {
                        assert!(!tri.contains(&v), "triangle {tri:?} uses nodata vertex {v}");
                        let p = xy(&lod, v);
                        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(s, e)| (e - s).perp_dot(p - s) >= -1e-3);
                        assert!(!inside, "triangle {tri:?} spans nodata cell {v}");
                    }
                }
            }
        }
        assert!(coarse_quads > 0, "coarse quads away from nodata");
    }

    #[test]
    fn skirts_close_every_seam_and_only_seams() {
        for (t, n) in [(terrain(40, 40, holes), 16), (terrain(45, 38, hills), 16), (terrain(33, 21, holes), 5)] {
            let lod = TerrainLod::build(&t, n, 6);
            let terrain_vertices = t.mesh.positions.len() as u32;
            for chunk in &lod.chunks {
                for (k, range) in chunk.levels.iter().enumerate() {
                    let (surface, skirts) = split(&lod, &t, range);
                    // Skirt tops: the second triangle of each wall, [a, lowered b, b].
                    let tops: HashSet<(u32, u32)> = skirts
                        .iter()
                        .filter(|s| s[0] < terrain_vertices && s[2] < terrain_vertices)
                        .map(|s| (s[0], s[2]))
                        .collect();
                    assert_eq!(tops.len() * 2, skirts.len(), "two triangles per wall");
                    let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
                    for tri in &surface {
                        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
                            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                        }
                    }
                    for tri in &surface {
                        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
                            let boundary = edges[&(a.min(b), a.max(b))] == 1;
                            if boundary && data_across(&t, a, b) {
                                assert!(tops.contains(&(a, b)), "level {k}: open seam {a} → {b}");
                            }
                        }
                    }
                    for &(a, b) in &tops {
                        assert!(data_across(&t, a, b), "level {k}: skirt {a} → {b} hangs into no data");
                    }
                }
            }
        }
        // Without nodata level 0 has skirts on both sides of every inner chunk border only.
        let t = terrain(45, 38, hills);
        let lod = TerrainLod::build(&t, 16, 1);
        let skirts: usize = lod.chunks.iter().map(|c| split(&lod, &t, &c.levels[0]).1.len()).sum();
        let border_segments = 2 * 37 + 2 * 44;
        assert_eq!(skirts, border_segments * 2 * 2);
    }

    #[test]
    fn skirts_hang_below_their_chunk_inside_its_sphere() {
        let t = terrain(40, 40, holes);
        let lod = TerrainLod::build(&t, 16, 5);
        let terrain_vertices = t.mesh.positions.len() as u32;
        assert!(lod.mesh.positions.len() > t.mesh.positions.len(), "skirt vertices follow the terrain's");
        for chunk in &lod.chunks {
            let lowest = split(&lod, &t, &chunk.levels[0])
                .0
                .iter()
                .flatten()
                .map(|&v| lod.mesh.positions[v as usize][2])
                .fold(f32::INFINITY, f32::min);
            for range in &chunk.levels {
                let (_, skirts) = split(&lod, &t, range);
                for tri in &skirts {
                    for &s in tri.iter().filter(|&&v| v >= terrain_vertices) {
                        let top = tri
                            .iter()
                            .find(|&&v| v < terrain_vertices && xy(&lod, v) == xy(&lod, s))
                            .or_else(|| {
                                skirts.iter().flatten().find(|&&v| v < terrain_vertices && xy(&lod, v) == xy(&lod, s))
                            })
                            .copied()
                            .expect("a skirt vertex lies under a terrain vertex");
                        let (s, top) = (s as usize, top as usize);
                        assert!(lod.mesh.positions[s][2] < lod.mesh.positions[top][2], "skirts go down");
                        assert!(lod.mesh.positions[s][2] <= lowest + 1e-3, "below the chunk's lowest point");
                        assert_eq!(lod.mesh.normals[s], lod.mesh.normals[top]);
                        assert_eq!(lod.mesh.uvs[s], lod.mesh.uvs[top]);
                    }
                }
                for v in triangles(&lod, range).iter().flatten() {
                    let d = Vec3::from(lod.mesh.positions[*v as usize]).distance(chunk.center);
                    assert!(d <= chunk.radius * (1.0 + 1e-5), "vertex {v} outside the bounding sphere");
                }
            }
        }
    }

    #[test]
    fn level_for_is_monotonic_in_the_projected_cell_size() {
        let t = terrain(65, 65, hills);
        let lod = TerrainLod::build(&t, 64, 10);
        let chunk = &lod.chunks[0];
        assert_eq!(chunk.levels.len(), 7);
        assert_eq!(chunk.level_for(8.0, 4.0), 0);
        assert_eq!(chunk.level_for(1.0, 4.0), 1, "2 px cells stay below 4 px, 4 px cells do not");
        assert_eq!(chunk.level_for(0.9, 4.0), 2);
        assert_eq!(chunk.level_for(1e-4, 4.0), 6, "no coarser level than there is");
        assert_eq!(chunk.level_for(f32::NAN, 4.0), 0);
        let mut last = 0;
        for i in 0..200 {
            let cell_px = 100.0 * 0.95f32.powi(i);
            let level = chunk.level_for(cell_px, 4.0);
            assert!(level >= last && level < chunk.levels.len(), "{cell_px} px: level {level} after {last}");
            assert!(level == 0 || cell_px * 2f32.powi(level as i32) < 4.0);
            last = level;
        }
        assert_eq!(last, 6);
    }
}
