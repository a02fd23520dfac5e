//! The far-field vegetation masses on the GPU (`prep::masses`, thesis 7.3): each layer's domes
//! in chunks of the plant-density grid, uploaded once; a frame culls the chunks, draws those
//! reaching beyond the billboard range at the level of detail their distance asks (coarser
//! cells far away, `prep::masses::coarsen`), and blends them with their plants by screen door
//! (`mass_cover` in `shaders/gbuffer.wgsl`). A chunk's domes take their hatching from the
//! grid reference points their plants use far away, so strokes stay put across the blend.

use super::cull::{DrawStats, LayerDraw, ReferenceGrid, References, sphere_outside};
use super::upload::Uploader;
use crate::prep::masses::{MASS_CELL, MASS_LEVELS, MassCell, Masses, cell_size, coarsen, dome_mesh, dome_triangles};
use crate::render::gbuffer::{Instance, Surface, Vertex, average_color, object_id};
use crate::render::layer_code::LayerCode;
use crate::scene::plant::{Material, PartKind, PlantModel};
use glam::Vec3;
use std::collections::{BTreeMap, HashMap};
use std::ops::Range;

/// Cells of the plant-density grid along each side of a chunk.
const CHUNK_CELLS: i64 = 16;
/// The object index of a layer's masses (the last one: plants count from zero).
const MASS_INDEX: u32 = LayerCode::INDEX_MASK - 1;
/// The on-screen width of a cell of the masses, as a share of the image's width, below which a
/// chunk draws its next coarser level (`prep::masses::coarsen`): domes stay 8 px wide in a
/// 1024 px view, and a forest far away costs a quarter of the domes per level. A share, not
/// pixels, so a thumbnail draws the same masses as the large view it stands for.
const MIN_DOME_SHARE: f32 = 8.0 / 1024.0;

/// Octaves of the cell width before a level takes over across which it blends in: a chunk
/// whose cells are up to this many octaves wider than the least dome width draws its level and
/// the next coarser one, each in a share of the screen door.
const LEVEL_BLEND_OCTAVES: f32 = 0.5;

/// The levels of detail a chunk whose finest cells are `cell_px` pixels wide draws, each with
/// its screen-door window (`Instance::data_abstraction`): the finest level whose cells are at
/// least `min_px` wide, and within LEVEL_BLEND_OCTAVES before the next coarser one takes over
/// that one too, its share of the dither values growing as the cells shrink.
fn level_windows(cell_px: f32, min_px: f32) -> Vec<(usize, [f32; 2])> {
    let last = MASS_LEVELS - 1;
    // The level in octaves: the chunk draws level ceil(x) alone unless x is near the next
    // whole number.
    let x = (min_px / cell_px.max(1e-6)).log2();
    let level = (x.ceil().max(0.0) as usize).min(last);
    let share = if level == last {
        0.0
    } else {
        ((x - (level as f32 - LEVEL_BLEND_OCTAVES)) / LEVEL_BLEND_OCTAVES).clamp(0.0, 1.0)
    };
    let share = share * share * (3.0 - 2.0 * share);
    if share <= 0.0 {
        return vec![(level, [0.0, 1.0])];
    }
    if share >= 1.0 {
        return vec![(level + 1, [0.0, 1.0])];
    }
    vec![(level, [0.0, 1.0 - share]), (level + 1, [1.0 - share, 1.0])]
}

/// The foliage colour of a species: the triangle-weighted average colour of its foliage
/// materials (of all parts when it has none), linear RGB.
pub(super) fn species_color(model: &PlantModel) -> [f32; 3] {
    let foliage = model.parts.iter().any(|p| p.kind == PartKind::Foliage);
    let mut sum = Vec3::ZERO;
    let mut weight = 0.0;
    for part in model.parts.iter().filter(|p| !foliage || p.kind == PartKind::Foliage) {
        let [r, g, b, _] = average_color(&part.material);
        let w = part.mesh.triangle_count().max(1) as f32;
        sum += w * Vec3::new(r, g, b);
        weight += w;
    }
    if weight > 0.0 { (sum / weight).to_array() } else { [0.2, 0.35, 0.15] }
}

/// One chunk of a layer's domes.
struct MassChunk {
    object_id: u32,
    /// Bounding sphere of its domes.
    center: Vec3,
    radius: f32,
    /// Heights of the shortest and tallest plants its domes stand for (metres).
    heights: (f32, f32),
    /// Its domes' indices and count per level of detail, finest first.
    levels: [(Range<u32>, u64); MASS_LEVELS],
    /// The grid reference points its vertices index (`Vertex::hlp_index`), in order: the
    /// same for every level.
    references: Vec<u32>,
}

/// Every layer's masses, resident on the GPU.
pub(super) struct MassGpu {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    material: wgpu::BindGroup,
    chunks: Vec<MassChunk>,
}

/// One chunk a frame draws: its instance, indices and style slot.
pub(super) struct MassDraw {
    pub slot: usize,
    pub instance: u32,
    pub indices: Range<u32>,
}

/// What [`MassGpu::cull`] needs of the view.
pub(super) struct MassView<'a> {
    pub planes: &'a [glam::Vec4; 5],
    pub eye: Vec3,
    /// Metres per pixel of a plan view.
    pub plan: Option<f32>,
    pub px_per_metre: f32,
    /// `LodSettings::mass_band`.
    pub band: (f32, f32),
    /// The image's width in pixels.
    pub width: u32,
}

impl MassGpu {
    /// Uploads the domes of every layer's `masses` (by layer index), their vertices indexing
    /// the cells of `grid`; `None` when no layer has a mass.
    pub(super) fn new(up: &mut Uploader<'_>, masses: &[Masses], grid: &ReferenceGrid) -> Option<MassGpu> {
        let mut vertices: Vec<Vertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut chunks = Vec::new();
        for (layer, masses) in masses.iter().enumerate() {
            // Each level's cells, and every chunk's cells per level (a coarse cell belongs to
            // the chunk of its first fine cell: the chunk's side is a multiple of its width).
            let mut by_chunk: BTreeMap<(i64, i64), [Vec<MassCell>; MASS_LEVELS]> = BTreeMap::new();
            let mut all: Vec<HashMap<(i64, i64), MassCell>> = Vec::with_capacity(MASS_LEVELS);
            for level in 0..MASS_LEVELS {
                let factor = 1_i64 << level;
                let cells = coarsen(&masses.cells, factor);
                for cell in &cells {
                    let (i, j) = (cell.key.0 * factor, cell.key.1 * factor);
                    let chunk = (i.div_euclid(CHUNK_CELLS), j.div_euclid(CHUNK_CELLS));
                    by_chunk.entry(chunk).or_default()[level].push(*cell);
                }
                all.push(cells.iter().map(|c| (c.key, *c)).collect());
            }
            for per_level in by_chunk.values() {
                // Each dome's reference point: the grid cell its centre lies in (every mass
                // cell of every level lies inside one, as its width divides the grid spacing).
                let mut references = Vec::new();
                let mut local = HashMap::new();
                let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
                let mut levels: [(Range<u32>, u64); MASS_LEVELS] = Default::default();
                for (level, cells) in per_level.iter().enumerate() {
                    let size = cell_size(level);
                    let mesh = dome_mesh(cells, &all[level], level);
                    let dome_reference: Vec<u32> = cells
                        .iter()
                        .map(|c| {
                            let (x, y) = ((c.key.0 as f32 + 0.5) * size, (c.key.1 as f32 + 0.5) * size);
                            let cell = grid.cell_at(x, y).unwrap_or(0);
                            *local.entry(cell).or_insert_with(|| {
                                references.push(cell);
                                references.len() as u32 - 1
                            })
                        })
                        .collect();
                    let first_vertex = vertices.len() as u32;
                    let first_index = indices.len() as u32;
                    for (v, p) in mesh.positions.iter().enumerate() {
                        let dome = mesh.cell[v] as usize;
                        let local_reference = dome_reference[dome];
                        let sphere = grid.spheres[references[local_reference as usize] as usize];
                        lo = lo.min(Vec3::from(*p));
                        hi = hi.max(Vec3::from(*p));
                        vertices.push(Vertex {
                            position: *p,
                            normal: mesh.normals[v],
                            uv: [mesh.edge[v], cells[dome].height],
                            hlp: [sphere.center.x, sphere.center.y, sphere.center.z, sphere.radius],
                            hlp_index: local_reference,
                            implicit: cells[dome].color,
                        });
                    }
                    indices.extend(mesh.indices.iter().map(|i| i + first_vertex));
                    levels[level] = (first_index..indices.len() as u32, cells.len() as u64);
                }
                let heights =
                    per_level[0].iter().fold((f32::MAX, f32::MIN), |(a, b), c| (a.min(c.height), b.max(c.height)));
                chunks.push(MassChunk {
                    object_id: object_id(LayerCode::vegetation(layer), MASS_INDEX),
                    center: (lo + hi) * 0.5,
                    radius: (hi - lo).length() * 0.5,
                    heights,
                    levels,
                    references,
                });
            }
        }
        if chunks.is_empty() {
            return None;
        }
        let (vertices, indices) = up.buffers(bytemuck::cast_slice(&vertices), &indices);
        let white = Material {
            name: "vegetation masses".into(),
            base_color: [1.0; 4],
            texture: None,
            alpha_cutoff: None,
            double_sided: true,
        };
        let material = up.material(&white, Surface::Mass, 1.0);
        Some(MassGpu { vertices, indices, material, chunks })
    }

    /// Chunks the masses can draw: an upper bound of a frame's mass instances.
    pub(super) fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Culls the chunks against the view, keeps those of visible layers with a part beyond the
    /// start of the mass band, and appends an instance per chunk (its reference points as one
    /// run of `references`, its band in the screen-door mask) to `instances`.
    pub(super) fn cull(
        &self,
        view: &MassView<'_>,
        layer: &impl Fn(u32) -> LayerDraw,
        instances: &mut Vec<Instance>,
        references: &mut References,
        stats: &mut DrawStats,
    ) -> Vec<MassDraw> {
        let mut draws: Vec<(f32, MassDraw)> = Vec::new();
        for chunk in &self.chunks {
            if !layer(chunk.object_id).visible || sphere_outside(view.planes, chunk.center, chunk.radius) {
                continue;
            }
            // The smallest its plants get on screen: at the chunk's far side (or everywhere in
            // a plan view). Above the band everywhere, the plants draw the whole chunk.
            let smallest_px = match view.plan {
                Some(m) => chunk.heights.0 / m,
                None => chunk.heights.0 * view.px_per_metre / (chunk.center.distance(view.eye) + chunk.radius),
            };
            if smallest_px >= view.band.1 {
                continue;
            }
            // The finest level whose cells are at least MIN_DOME_SHARE of the image wide at the
            // chunk's near side, blended with the next coarser one before it takes over.
            let cell_px = match view.plan {
                Some(m) => MASS_CELL / m,
                None => MASS_CELL * view.px_per_metre / (chunk.center.distance(view.eye) - chunk.radius).max(1e-3),
            };
            let slot = LayerCode::of_object_id(chunk.object_id).slot();
            let distance = chunk.center.distance_squared(view.eye);
            for (level, window) in level_windows(cell_px, MIN_DOME_SHARE * view.width as f32) {
                let (indices, domes) = chunk.levels[level].clone();
                let instance = instances.len() as u32;
                instances.push(Instance {
                    offset_scale: [0.0, 0.0, 0.0, 1.0],
                    rotation: [1.0, 0.0],
                    object_id: chunk.object_id,
                    reference_base: references.cells(&chunk.references),
                    mask: [view.band.0, view.band.1],
                    data_abstraction: window,
                    reference_sphere: [0.0; 4],
                });
                stats.mass_domes += domes;
                stats.triangles += domes * dome_triangles(level);
                draws.push((distance, MassDraw { slot, instance, indices }));
            }
        }
        // Front to back, so the early depth test skips the domes behind nearer ones.
        draws.sort_by(|a, b| a.0.total_cmp(&b.0));
        draws.into_iter().map(|(_, draw)| draw).collect()
    }

    /// Records the draws of a frame's chunks with `pipeline`, each binding `frame` at the
    /// offset `layer_offset` gives its style slot.
    pub(super) fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        draws: &[MassDraw],
        pipeline: &wgpu::RenderPipeline,
        frame: &wgpu::BindGroup,
        layer_offset: impl Fn(usize) -> [u32; 1],
    ) {
        if draws.is_empty() {
            return;
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(1, &self.material, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        for draw in draws {
            pass.set_bind_group(0, frame, &layer_offset(draw.slot));
            pass.draw_indexed(draw.indices.clone(), 0, draw.instance..draw.instance + 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chunk_blends_into_its_next_level_before_it_takes_over() {
        // Cells wide on screen: the finest level alone.
        let min = 8.0;
        assert_eq!(level_windows(4.0 * min, min), vec![(0, [0.0, 1.0])]);
        // Just before level 1 takes over both are drawn, in complementary windows, the
        // coarser one's share growing as the cells shrink.
        let shares: Vec<f32> = [0.3, 0.2, 0.1]
            .iter()
            .map(|octaves| {
                let windows = level_windows(min * 2f32.powf(*octaves), min);
                assert_eq!(windows.len(), 2, "{windows:?}");
                assert_eq!((windows[0].0, windows[1].0), (0, 1));
                assert_eq!(windows[0].1[1], windows[1].1[0], "complementary: {windows:?}");
                1.0 - windows[1].1[0]
            })
            .collect();
        assert!(shares[0] < shares[1] && shares[1] < shares[2], "{shares:?}");
        // Past the switch the coarser level alone, and the coarsest never blends further.
        assert_eq!(level_windows(min * 0.9, min), vec![(1, [0.0, 1.0])]);
        assert_eq!(level_windows(min / 64.0, min), vec![(MASS_LEVELS - 1, [0.0, 1.0])]);
    }
}
