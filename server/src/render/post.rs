//! Stage two: full-screen post-processing passes over the G-buffer (thesis 8.2, NPAR §9).
//!
//! Each pass reads the post uniform block (binding 0) and its inputs (bindings 1..) and writes
//! one render target: [`prefilter`] (thesis eq. 5.4, optional), [`contour`] (eq. 5.1 and the
//! tone of 6.1.3) and [`compose`] (eq. 5.2, tone blur, TAM hatching, SAM silhouettes, paper).

use super::gbuffer::{texture_entry, uniform_layout_entry};

const FULLSCREEN: &str = include_str!("../../../shaders/fullscreen.wgsl");
const POST_COMMON: &str = include_str!("../../../shaders/post_common.wgsl");

/// Output format of the depth pre-filter.
pub const PREFILTER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
/// Output format of the contour pass: grey-level contour intensity (r) and tone (g).
pub const CONTOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg16Float;
/// Output format of the final image (sRGB-encoded values written directly).
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// One input binding of a pass.
#[derive(Debug, Clone, Copy)]
pub enum Input {
    /// A texture read with `textureLoad` (unfilterable float).
    Float,
    /// An unsigned-integer texture (IDs).
    Uint,
    /// A filterable 2D texture sampled with a sampler.
    Filtered,
    /// A filterable 2D array texture (tonal art maps).
    FilteredArray,
    /// A filtering sampler.
    Sampler,
    /// A uniform buffer of the pass's own.
    Uniform,
}

impl Input {
    fn layout_entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        let float = |filterable| wgpu::TextureSampleType::Float { filterable };
        match self {
            Input::Float => texture_entry(binding, float(false)),
            Input::Uint => texture_entry(binding, wgpu::TextureSampleType::Uint),
            Input::Filtered => texture_entry(binding, float(true)),
            Input::FilteredArray => wgpu::BindGroupLayoutEntry {
                ty: wgpu::BindingType::Texture {
                    sample_type: float(true),
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
                ..texture_entry(binding, float(true))
            },
            Input::Sampler => wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
            Input::Uniform => uniform_layout_entry(binding),
        }
    }
}

/// A full-screen pass: one fragment shader over the whole image.
pub struct FullscreenPass {
    label: &'static str,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

impl FullscreenPass {
    /// Builds a pass from a WGSL source (prefixed with the shared vertex stage and uniform
    /// block), its fragment entry point, its inputs in binding order and its output format.
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &str,
        entry_point: &str,
        inputs: &[Input],
        output: wgpu::TextureFormat,
    ) -> FullscreenPass {
        let code = format!("{FULLSCREEN}\n{POST_COMMON}\n{source}");
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(code.into()),
        });
        let mut entries = vec![uniform_layout_entry(0)];
        entries.extend(inputs.iter().enumerate().map(|(i, input)| input.layout_entry(i as u32 + 1)));
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

    /// Binds the uniform buffer and the inputs in binding order.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        uniform: &wgpu::Buffer,
        inputs: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }];
        entries.extend(
            inputs
                .iter()
                .enumerate()
                .map(|(i, resource)| wgpu::BindGroupEntry { binding: i as u32 + 1, resource: resource.clone() }),
        );
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(self.label),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Records the pass: every pixel of `target` is written (or cleared, where the shader
    /// discards).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView, bind_group: &wgpu::BindGroup) {
        self.record(encoder, target, bind_group, wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT));
    }

    /// Records the pass over what `target` holds: pixels the shader discards keep their value
    /// (the compose pass of a further art-map group).
    pub fn encode_over(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        bind_group: &wgpu::BindGroup,
    ) {
        self.record(encoder, target, bind_group, wgpu::LoadOp::Load);
    }

    fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        bind_group: &wgpu::BindGroup,
        load: wgpu::LoadOp<wgpu::Color>,
    ) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(self.label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load, store: wgpu::StoreOp::Store },
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

/// The depth pre-filter (`shaders/prefilter.wgsl`, thesis eq. 5.4). Inputs: linear depth.
pub fn prefilter(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "prefilter",
        include_str!("../../../shaders/prefilter.wgsl"),
        "fs_prefilter",
        &[Input::Float],
        PREFILTER_FORMAT,
    )
}

/// The contour and tone pass (`shaders/contour.wgsl`, thesis eq. 5.1, 6.7).
/// Inputs: linear depth (raw or pre-filtered), albedo, normal, IDs (the style slot per pixel).
pub fn contour(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "contour",
        include_str!("../../../shaders/contour.wgsl"),
        "fs_contour",
        &[Input::Float, Input::Float, Input::Float, Input::Uint],
        CONTOUR_FORMAT,
    )
}

/// The compose pass (`shaders/compose.wgsl` with `shaders/data_common.wgsl`). Inputs: contour +
/// tone, depth + HLP radius, IDs, hatch coordinates + E, normal + tiles per pixel, albedo, the
/// array of all TAMs, SAM, TAM sampler, SAM sampler, data layers
/// ([`super::projection::DATA_FORMAT`]), the hatch-colour slots
/// ([`super::projection::ProjectionPass::hatch_colors`]).
pub fn compose(device: &wgpu::Device) -> FullscreenPass {
    use Input::*;
    FullscreenPass::new(
        device,
        "compose",
        concat!(include_str!("../../../shaders/data_common.wgsl"), "\n", include_str!("../../../shaders/compose.wgsl")),
        "fs_compose",
        &[Float, Float, Uint, Float, Float, Float, FilteredArray, Filtered, Sampler, Sampler, Uint, Uniform],
        OUTPUT_FORMAT,
    )
}

/// A plain copy of one texture (`shaders/copy.wgsl`): the cheapest possible full-screen pass,
/// the floor the benchmark compares the NPR passes with. Inputs: the source (output format).
pub fn copy(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "copy",
        include_str!("../../../shaders/copy.wgsl"),
        "fs_copy",
        &[Input::Float],
        OUTPUT_FORMAT,
    )
}
