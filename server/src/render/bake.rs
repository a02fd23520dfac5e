//! Bakes billboard textures (SPEC P4): each atlas tile is the plant geometry of one billboard
//! plane drawn offscreen with an orthographic camera (`shaders/bake.wgsl`), read back so it can
//! be cached on disk and uploaded with a mip chain like any material texture.

use super::bind_layouts::storage_entry;
use super::gbuffer::{DEPTH_FORMAT, Vertex};
use super::{Gpu, RenderError, readback};
use crate::prep::lod::Atlas;
use std::ops::Range;
use wgpu::util::DeviceExt;

/// Format of the baked atlas: sRGB like the model textures it is made from.
const ATLAS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// One indexed draw of a mesh into a tile.
pub struct BakeDraw<'a> {
    pub vertices: &'a wgpu::Buffer,
    pub indices: &'a wgpu::Buffer,
    pub range: Range<u32>,
    /// A material bind group of the geometry pass's material layout.
    pub material: &'a wgpu::BindGroup,
}

/// What one atlas tile shows: the world → clip matrix of its plane and the draws.
pub struct BakeTile<'a> {
    pub matrix: glam::Mat4,
    pub draws: Vec<BakeDraw<'a>>,
}

/// The bake pipeline.
pub struct Baker {
    pipeline: wgpu::RenderPipeline,
    tiles_layout: wgpu::BindGroupLayout,
}

impl Baker {
    /// Compiles `shaders/bake.wgsl`; materials are bound with `material_layout`, the geometry
    /// pass's material layout, so the scene's material bind groups are reused.
    pub fn new(device: &wgpu::Device, material_layout: &wgpu::BindGroupLayout) -> Baker {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bake.wgsl"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let tiles_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("bake tiles"),
            entries: &[storage_entry(0, wgpu::ShaderStages::VERTEX)],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("bake"),
            bind_group_layouts: &[Some(&tiles_layout), Some(material_layout)],
            immediate_size: 0,
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("bake"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_bake"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_bake"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: ATLAS_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        Baker { pipeline, tiles_layout }
    }

    /// Draws every tile into an atlas and reads it back. Texels no geometry covers are
    /// transparent; their colour is grown from covered neighbours so mip levels do not darken
    /// the billboards' edges.
    pub fn bake(&self, gpu: &Gpu, atlas: &Atlas, tiles: &[BakeTile<'_>]) -> Result<image::RgbaImage, RenderError> {
        let device = &gpu.device;
        let (width, height) = atlas.size();
        let target = |format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some("bake"),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = target(ATLAS_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
        let depth = target(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
        let matrices: Vec<[[f32; 4]; 4]> = tiles.iter().map(|t| t.matrix.to_cols_array_2d()).collect();
        let matrices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake tiles"),
            contents: bytemuck::cast_slice(&matrices),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let tiles_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bake tiles"),
            layout: &self.tiles_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: matrices.as_entire_binding() }],
        });
        let color_view = color.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("bake") });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("bake"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &tiles_group, &[]);
            for (index, tile) in tiles.iter().enumerate() {
                let [x, y, w, h] = atlas.viewport(index);
                pass.set_viewport(x as f32, y as f32, w as f32, h as f32, 0.0, 1.0);
                pass.set_scissor_rect(x, y, w, h);
                for draw in &tile.draws {
                    pass.set_bind_group(1, draw.material, &[]);
                    pass.set_vertex_buffer(0, draw.vertices.slice(..));
                    pass.set_index_buffer(draw.indices.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(draw.range.clone(), 0, index as u32..index as u32 + 1);
                }
            }
        }
        gpu.queue.submit([encoder.finish()]);
        let mut image = readback::read_rgba8(gpu, &color, width, height)?;
        bleed_colour(&mut image, 4);
        Ok(image)
    }
}

/// Gives transparent texels the mean colour of their covered 8-neighbours, `rounds` times
/// (alpha stays 0), so filtering across a coverage edge blends towards the plant's colour.
fn bleed_colour(image: &mut image::RgbaImage, rounds: usize) {
    let (w, h) = image.dimensions();
    let mut known: Vec<bool> = image.pixels().map(|p| p[3] > 0).collect();
    for _ in 0..rounds {
        let mut updates = Vec::new();
        for y in 0..h {
            for x in 0..w {
                if known[(y * w + x) as usize] {
                    continue;
                }
                let (mut sum, mut n) = ([0u32; 3], 0);
                for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= i64::from(w) || ny >= i64::from(h) {
                        continue;
                    }
                    if known[(ny as u32 * w + nx as u32) as usize] {
                        let p = image.get_pixel(nx as u32, ny as u32);
                        (0..3).for_each(|c| sum[c] += u32::from(p[c]));
                        n += 1;
                    }
                }
                if n > 0 {
                    updates.push((x, y, sum.map(|s| (s / n) as u8)));
                }
            }
        }
        if updates.is_empty() {
            break;
        }
        for (x, y, [r, g, b]) in updates {
            image.put_pixel(x, y, image::Rgba([r, g, b, 0]));
            known[(y * w + x) as usize] = true;
        }
    }
}

/// `shaders/bake.wgsl` after the declaration of its material block.
fn shader_source() -> String {
    let material = super::uniforms::Declarations::of::<super::gbuffer::SurfaceMaterial>();
    format!("{material}{}", include_str!("../../../shaders/bake.wgsl"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_bake_shader_compiles_with_its_derived_block() {
        crate::render::uniforms::validate_wgsl("bake", &super::shader_source());
    }

    use super::*;

    #[test]
    fn colour_bleeds_into_transparent_texels_without_alpha() {
        let mut image = image::RgbaImage::from_pixel(5, 1, image::Rgba([0, 0, 0, 0]));
        image.put_pixel(0, 0, image::Rgba([200, 100, 50, 255]));
        bleed_colour(&mut image, 2);
        assert_eq!(image.get_pixel(1, 0).0, [200, 100, 50, 0]);
        assert_eq!(image.get_pixel(2, 0).0, [200, 100, 50, 0]);
        assert_eq!(image.get_pixel(3, 0).0, [0, 0, 0, 0]);
    }
}
