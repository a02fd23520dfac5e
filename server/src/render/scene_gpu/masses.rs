//! The far-field vegetation masses on the GPU (`prep::masses`, thesis 7.3): each layer's domes
//! in chunks of the plant-density grid, uploaded once; a frame culls the chunks, draws those
//! reaching beyond the billboard range, and blends them with their plants by screen door
//! (`mass_cover` in `shaders/gbuffer.wgsl`). A chunk's domes take their hatching from the
//! grid reference points their plants use far away, so strokes stay put across the blend.

use super::cull::{DrawStats, LayerDraw, ReferenceGrid, References};
use super::upload::Uploader;
use crate::prep::masses::{DOME_TRIANGLES, MASS_CELL, MassCell, Masses, dome_mesh};
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
    indices: Range<u32>,
    /// The grid reference points its vertices index (`Vertex::hlp_index`), in order.
    references: Vec<u32>,
    domes: u64,
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
}

impl MassGpu {
    /// Uploads the domes of every layer's `masses` (by layer index), their vertices indexing
    /// the cells of `grid`; `None` when no layer has a mass.
    pub(super) fn new(up: &mut Uploader<'_>, masses: &[Masses], grid: &ReferenceGrid) -> Option<MassGpu> {
        let mut vertices: Vec<Vertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut chunks = Vec::new();
        for (layer, masses) in masses.iter().enumerate() {
            let all: HashMap<(i64, i64), MassCell> = masses.cells.iter().map(|c| (c.key, *c)).collect();
            let mut by_chunk: BTreeMap<(i64, i64), Vec<MassCell>> = BTreeMap::new();
            for cell in &masses.cells {
                let (i, j) = cell.key;
                by_chunk.entry((i.div_euclid(CHUNK_CELLS), j.div_euclid(CHUNK_CELLS))).or_default().push(*cell);
            }
            for cells in by_chunk.values() {
                let mesh = dome_mesh(cells, &all);
                // Each dome's reference point: the grid cell its centre lies in (every mass
                // cell lies inside one, as MASS_CELL divides the grid spacing).
                let mut references = Vec::new();
                let mut local = HashMap::new();
                let dome_reference: Vec<u32> = cells
                    .iter()
                    .map(|c| {
                        let (x, y) = ((c.key.0 as f32 + 0.5) * MASS_CELL, (c.key.1 as f32 + 0.5) * MASS_CELL);
                        let cell = grid.cell_at(x, y).unwrap_or(0);
                        *local.entry(cell).or_insert_with(|| {
                            references.push(cell);
                            references.len() as u32 - 1
                        })
                    })
                    .collect();
                let first_vertex = vertices.len() as u32;
                let first_index = indices.len() as u32;
                let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
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
                let heights = cells.iter().fold((f32::MAX, f32::MIN), |(a, b), c| (a.min(c.height), b.max(c.height)));
                chunks.push(MassChunk {
                    object_id: object_id(LayerCode::vegetation(layer), MASS_INDEX),
                    center: (lo + hi) * 0.5,
                    radius: (hi - lo).length() * 0.5,
                    heights,
                    indices: first_index..indices.len() as u32,
                    references,
                    domes: cells.len() as u64,
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
        let mut draws = Vec::new();
        for chunk in &self.chunks {
            if !layer(chunk.object_id).visible
                || view.planes.iter().any(|p| p.truncate().dot(chunk.center) + p.w < -chunk.radius)
            {
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
            let instance = instances.len() as u32;
            instances.push(Instance {
                offset_scale: [0.0, 0.0, 0.0, 1.0],
                rotation: [1.0, 0.0],
                object_id: chunk.object_id,
                reference_base: references.cells(&chunk.references),
                mask: [view.band.0, view.band.1],
                data_abstraction: [0.0; 2],
                reference_sphere: [0.0; 4],
            });
            stats.mass_domes += chunk.domes;
            stats.triangles += chunk.domes * DOME_TRIANGLES;
            let slot = LayerCode::of_object_id(chunk.object_id).slot();
            draws.push(MassDraw { slot, instance, indices: chunk.indices.clone() });
        }
        draws
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
