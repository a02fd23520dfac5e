//! Records the geometry pass's draws of a frame's [`VisibleSet`].

use super::batch::{Batch, Share};
use super::{GpuMesh, SceneGpu, VisibleSet};
use crate::prep::lod::LodLevel;
use crate::render::gbuffer::{GeometryPass, LAYER_STRIDE, Surface};
use crate::render::layer_code::LayerCode;
use std::ops::Range;

impl SceneGpu {
    /// Records the draws of every visible instance run, each mesh with the `geometry`
    /// pipeline of its surface, and of the runs drawn with substitution shapes, then the
    /// chunks of vegetation masses, then the terrain (each
    /// front to back, so hidden pixels fail the early depth test); plants drawn with leaf
    /// particles last, their leaves with the leaf pipeline. Each draw binds `frame`
    /// (group 0) at the layer-style offset of its style slot.
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        visible: &VisibleSet,
        frame: &wgpu::BindGroup,
        geometry: &GeometryPass,
    ) {
        let bytes = std::mem::size_of_val(visible.instances.as_slice()) as u64;
        let layer_offset = |slot: usize| [(slot as u64 * LAYER_STRIDE) as u32];
        pass.set_vertex_buffer(1, self.instance_buffer.slice(..bytes));
        let draw = |pass: &mut wgpu::RenderPass<'_>, mesh: &GpuMesh, instances: Range<u32>| {
            pass.set_pipeline(geometry.pipeline(mesh.surface));
            pass.set_bind_group(1, &mesh.material, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, instances);
        };
        for Batch { key, instances } in &visible.batches {
            pass.set_bind_group(0, frame, &layer_offset(key.slot));
            for mesh in &self.species[key.species].levels[key.detail.index()] {
                draw(pass, mesh, instances.clone());
            }
        }
        // Substitution shapes (SPEC P5): the level's wood (the full model's, or the HLP
        // level's trunk prism) and the species' shapes.
        for Batch { key, instances } in &visible.shape_batches {
            pass.set_bind_group(0, frame, &layer_offset(key.slot));
            let s = &self.species[key.species];
            for mesh in s.levels[key.detail.index()].iter().filter(|m| m.surface == Surface::Wood) {
                draw(pass, mesh, instances.clone());
            }
            draw(pass, &s.shapes.mesh, instances.clone());
        }
        if let Some(masses) = &self.masses {
            masses.draw(pass, &visible.masses, geometry.pipeline(Surface::Mass), frame, layer_offset);
        }
        // The terrain after the vegetation standing on it: where plants and masses cover the
        // ground, the early depth test skips its pixels (lavapipe shades every pixel drawn).
        pass.set_bind_group(0, frame, &layer_offset(LayerCode::TERRAIN.slot()));
        pass.set_pipeline(geometry.terrain_pipeline(self.land_cover));
        pass.set_bind_group(1, &self.terrain.material, &[]);
        pass.set_vertex_buffer(0, self.terrain.vertices.slice(..));
        pass.set_index_buffer(self.terrain.indices.slice(..), wgpu::IndexFormat::Uint32);
        for range in &visible.terrain_ranges {
            pass.draw_indexed(range.clone(), 0, 0..1);
        }
        for Batch { key, instances } in &visible.particle_batches {
            pass.set_bind_group(0, frame, &layer_offset(key.slot));
            let s = &self.species[key.species];
            for &wood in &s.particles.wood {
                draw(pass, &s.levels[LodLevel::Full.index()][wood], instances.clone());
            }
        }
        if visible.particle_batches.is_empty() {
            return;
        }
        pass.set_pipeline(&geometry.leaf_pipeline);
        for Batch { key, instances } in &visible.particle_batches {
            pass.set_bind_group(0, frame, &layer_offset(key.slot));
            let Share(share) = key.detail;
            for leaves in &self.species[key.species].particles.leaves {
                pass.set_bind_group(1, &leaves.materials[share], &[]);
                pass.set_vertex_buffer(0, leaves.vertices.slice(..));
                pass.set_index_buffer(leaves.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..leaves.counts[share], 0, instances.clone());
            }
        }
    }
}
