//! Stage two: full-screen post-processing passes over the G-buffer (thesis 8.2, NPAR §9).
//!
//! Each pass reads the post uniform block (binding 0) and a list of input textures
//! (bindings 1..) and writes one render target. The passes of the first pipeline are:
//! [`contour`] (thesis eq. 5.1) and [`compose`] (eq. 5.2, tone, hatching, paper).

use super::gbuffer::{texture_entry, uniform_layout_entry};

const FULLSCREEN: &str = include_str!("../../../shaders/fullscreen.wgsl");
const POST_COMMON: &str = include_str!("../../../shaders/post_common.wgsl");

/// Output format of the contour pass: grey-level contour intensity.
pub const CONTOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;
/// Output format of the final image (sRGB-encoded values written directly).
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// A full-screen pass: one fragment shader over the whole image.
pub struct FullscreenPass {
    label: &'static str,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

const UNFILTERED: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

impl FullscreenPass {
    /// Builds a pass from a WGSL source (prefixed with the shared vertex stage and uniform
    /// block), its fragment entry point, the sample types of its inputs and its output format.
    fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &str,
        entry_point: &str,
        inputs: &[wgpu::TextureSampleType],
        output: wgpu::TextureFormat,
    ) -> FullscreenPass {
        let code = format!("{FULLSCREEN}\n{POST_COMMON}\n{source}");
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(code.into()),
        });
        let mut entries = vec![uniform_layout_entry(0)];
        entries.extend(inputs.iter().enumerate().map(|(i, ty)| texture_entry(i as u32 + 1, *ty)));
        let layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some(entry_point),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: output,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        FullscreenPass { label, pipeline, layout }
    }

    /// Binds the uniform buffer and the input views in binding order.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        uniform: &wgpu::Buffer,
        inputs: &[&wgpu::TextureView],
    ) -> wgpu::BindGroup {
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }];
        entries.extend(inputs.iter().enumerate().map(|(i, view)| wgpu::BindGroupEntry {
            binding: i as u32 + 1,
            resource: wgpu::BindingResource::TextureView(view),
        }));
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(self.label),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Records the pass: every pixel of `target` is written.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView, bind_group: &wgpu::BindGroup) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(self.label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// The contour pass (`shaders/contour.wgsl`): linear depth → grey-level contours, eq. 5.1.
/// Inputs: linear depth.
pub fn contour(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "contour",
        include_str!("../../../shaders/contour.wgsl"),
        "fs_contour",
        &[UNFILTERED],
        CONTOUR_FORMAT,
    )
}

/// The compose pass (`shaders/compose.wgsl`): isolated-pixel removal (eq. 5.2), tone,
/// hatching and paper. Inputs: linear depth, contours, albedo, normal.
pub fn compose(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "compose",
        include_str!("../../../shaders/compose.wgsl"),
        "fs_compose",
        &[UNFILTERED, UNFILTERED, UNFILTERED, UNFILTERED],
        OUTPUT_FORMAT,
    )
}
