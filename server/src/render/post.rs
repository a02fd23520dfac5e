//! Stage two: full-screen post-processing passes over the G-buffer (thesis 8.2, NPAR §9).
//!
//! Each pass reads the post uniform block (binding 0) and its inputs (bindings 1..) and writes
//! one render target: [`prefilter`] (thesis eq. 5.4, optional), [`contour`] (eq. 5.1 and the
//! tone of 6.1.3), [`tone_blur`] (horizontal) and [`ComposePass`] (eq. 5.2, vertical tone
//! blur, TAM hatching, SAM silhouettes, paper).

use super::bind_layouts::{texture_entry, uniform_layout_entry};
use super::gbuffer::DEPTH_FORMAT;
use super::style::PostParams;
use std::collections::HashMap;
use std::sync::Mutex;

const FULLSCREEN: &str = include_str!("../../../shaders/fullscreen.wgsl");
const POST_COMMON: &str = include_str!("../../../shaders/post_common.wgsl");

/// Output format of the depth pre-filter.
pub const PREFILTER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
/// Output format of the contour pass: grey-level contour intensity (r) and tone (g).
pub const CONTOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg16Float;
/// Output format of the tone-blur pass: the horizontally blurred tone.
pub const TONE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;
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

/// Frame-wide facts the post passes' shaders are specialised on (the override constants of
/// `shaders/post_common.wgsl`). On lavapipe every instruction of a shader runs for every pixel,
/// whichever way its branches go, so a frame that needs less gets pipelines compiled without
/// the rest. [`Specialization::default`] leaves out coloured hatchings, data layers and surface
/// colour: the passes that use no styles or data are compiled with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Specialization {
    /// Every style slot holds the same post style: no per-pixel style lookup.
    pub uniform_style: bool,
    /// The tone blur radius when every slot has the same one (the tone-blur pass's loop
    /// unrolls).
    pub blur_radius: Option<u32>,
    /// Whether the frame has coloured hatchings of data layers (compose).
    pub hatch_colors: bool,
    /// Whether the projection pass writes data layers; without, compose reads none.
    pub data_layers: bool,
    /// Whether any slot shows surface colour; without, compose shades none.
    pub surface_color: bool,
}

impl Specialization {
    /// The specialisation of a frame whose style slots have the post parameters `slots`,
    /// with or without coloured hatchings and data layers.
    pub fn for_frame(slots: &[PostParams], hatch_colors: bool, data_layers: bool) -> Specialization {
        let uniform_style = slots.windows(2).all(|w| bytemuck::bytes_of(&w[0]) == bytemuck::bytes_of(&w[1]));
        let shared_blur = slots.windows(2).all(|w| w[0].tone_blur() == w[1].tone_blur());
        let blur_radius = slots.first().map(PostParams::tone_blur).filter(|_| shared_blur);
        let surface_color = slots.iter().any(|s| s.color_amount() > 0.0);
        Specialization { uniform_style, blur_radius, hatch_colors, data_layers, surface_color }
    }

    fn constants(self) -> [(&'static str, f64); 5] {
        let flag = |b: bool| f64::from(u8::from(b));
        [
            ("UNIFORM_STYLE", flag(self.uniform_style)),
            ("BLUR_RADIUS", self.blur_radius.map_or(-1.0, f64::from)),
            ("HATCH_COLORS", flag(self.hatch_colors)),
            ("DATA_LAYERS", flag(self.data_layers)),
            ("SURFACE_COLOR", flag(self.surface_color)),
        ]
    }
}

/// The pipelines of one post shader, compiled on first use for each entry point, depth gate and
/// specialisation a frame asks for (a handful in practice).
pub(crate) struct Variants {
    label: &'static str,
    shader: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    output: wgpu::TextureFormat,
    cache: Mutex<HashMap<(&'static str, Gate, Specialization), wgpu::RenderPipeline>>,
}

impl Variants {
    fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &str,
        inputs: &[Input],
        output: wgpu::TextureFormat,
    ) -> Variants {
        Variants {
            label,
            shader: shader_module(device, label, source),
            layout: input_layout(device, label, inputs),
            output,
            cache: Mutex::default(),
        }
    }

    fn get(
        &self,
        device: &wgpu::Device,
        entry_point: &'static str,
        gate: Gate,
        spec: Specialization,
    ) -> wgpu::RenderPipeline {
        let mut cache = self.cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        cache
            .entry((entry_point, gate, spec))
            .or_insert_with(|| {
                let constants = spec.constants();
                fullscreen_pipeline(
                    device,
                    self.label,
                    &self.shader,
                    &self.layout,
                    (entry_point, &constants),
                    self.output,
                    gate,
                )
            })
            .clone()
    }
}

/// A post pass built on one shader's [`Variants`]: binds its uniform block and inputs.
pub(crate) trait PostPass {
    fn variants(&self) -> &Variants;

    /// Binds the uniform buffer and the inputs in binding order.
    fn bind_group(
        &self,
        device: &wgpu::Device,
        uniform: &wgpu::Buffer,
        inputs: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let variants = self.variants();
        input_bind_group(device, variants.label, &variants.layout, uniform, inputs)
    }
}

impl PostPass for FullscreenPass {
    fn variants(&self) -> &Variants {
        &self.variants
    }
}

impl PostPass for ComposePass {
    fn variants(&self) -> &Variants {
        &self.variants
    }
}

/// What the post passes of one frame are drawn with: the specialisation of their shaders and
/// the G-buffer depth that gated passes test against.
#[derive(Clone, Copy)]
pub struct FrameContext<'a> {
    pub device: &'a wgpu::Device,
    pub spec: Specialization,
    /// The G-buffer depth (needed by gated passes only).
    pub depth: Option<&'a wgpu::TextureView>,
}

impl<'a> FrameContext<'a> {
    /// The context of a pass that neither depends on styles nor is gated.
    pub fn plain(device: &'a wgpu::Device) -> FrameContext<'a> {
        FrameContext { device, spec: Specialization::default(), depth: None }
    }
}

/// A full-screen pass: one fragment shader over the whole image, or over the part of it its
/// [`Gate`] lets through (the rest keeps the pass's clear colour).
pub struct FullscreenPass {
    variants: Variants,
    entry_point: &'static str,
    gate: Gate,
    clear: wgpu::Color,
}

/// Compiles a post pass's WGSL source, prefixed with the shared vertex stage and uniform block.
fn shader_module(device: &wgpu::Device, label: &'static str, source: &str) -> wgpu::ShaderModule {
    let code = format!("{FULLSCREEN}\n{POST_COMMON}\n{source}");
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(code.into()),
    })
}

/// The bind group layout of a post pass: the uniform block (binding 0), then `inputs`.
fn input_layout(device: &wgpu::Device, label: &'static str, inputs: &[Input]) -> wgpu::BindGroupLayout {
    let mut entries = vec![uniform_layout_entry(0)];
    entries.extend(inputs.iter().enumerate().map(|(i, input)| input.layout_entry(i as u32 + 1)));
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

/// How a full-screen draw is limited to part of the image by the G-buffer's depth (reverse Z:
/// 0 where nothing was drawn). The depth test is the one way to skip pixels on lavapipe: a
/// branch in a shader runs both sides for every pixel, the early depth test leaves out whole
/// groups of 8 pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Gate {
    /// Every pixel (no depth attachment).
    None,
    /// Only pixels with geometry.
    Geometry,
    /// Only background pixels (the sky).
    Background,
}

impl Gate {
    fn depth_stencil(self) -> Option<wgpu::DepthStencilState> {
        // The full-screen triangle lies at depth 0, so it is nearer than (reverse Z: less
        // than) every drawn pixel and equal to the cleared background.
        let compare = match self {
            Gate::None => return None,
            Gate::Geometry => wgpu::CompareFunction::Less,
            Gate::Background => wgpu::CompareFunction::GreaterEqual,
        };
        Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(false),
            depth_compare: Some(compare),
            stencil: Default::default(),
            bias: Default::default(),
        })
    }
}

/// A pipeline drawing the full-screen triangle with `entry_point` into `output`, limited by
/// `gate`, with values for the shader's override constants.
fn fullscreen_pipeline(
    device: &wgpu::Device,
    label: &'static str,
    shader: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    (entry_point, constants): (&str, &[(&str, f64)]),
    output: wgpu::TextureFormat,
    gate: Gate,
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: gate.depth_stencil(),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: shader,
            entry_point: Some(entry_point),
            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
            targets: &[Some(wgpu::ColorTargetState {
                format: output,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Binds the uniform buffer and the inputs in binding order.
fn input_bind_group(
    device: &wgpu::Device,
    label: &'static str,
    layout: &wgpu::BindGroupLayout,
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
    device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}

/// Records one render pass over `target` (cleared or loaded) that draws the full-screen
/// triangle with each pipeline in turn; `depth` is the G-buffer depth that gated pipelines
/// test against (read only).
fn record_fullscreen(
    encoder: &mut wgpu::CommandEncoder,
    label: &'static str,
    (target, load): (&wgpu::TextureView, wgpu::LoadOp<wgpu::Color>),
    depth: Option<&wgpu::TextureView>,
    bind_group: &wgpu::BindGroup,
    pipelines: &[&wgpu::RenderPipeline],
) {
    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations { load, store: wgpu::StoreOp::Store },
        })],
        depth_stencil_attachment: depth.map(|view| wgpu::RenderPassDepthStencilAttachment {
            view,
            depth_ops: None,
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_bind_group(0, bind_group, &[]);
    for pipeline in pipelines {
        pass.set_pipeline(pipeline);
        pass.draw(0..3, 0..1);
    }
}

impl FullscreenPass {
    /// Builds a pass from a WGSL source (prefixed with the shared vertex stage and uniform
    /// block), its fragment entry point, its inputs in binding order and its output format.
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &'static str,
        source: &str,
        entry_point: &'static str,
        inputs: &[Input],
        output: wgpu::TextureFormat,
    ) -> FullscreenPass {
        let variants = Variants::new(device, label, source, inputs, output);
        FullscreenPass { variants, entry_point, gate: Gate::None, clear: wgpu::Color::TRANSPARENT }
    }

    /// The pass limited to the pixels `gate` lets through; the others are cleared to `clear`.
    pub(crate) fn gated(self, gate: Gate, clear: wgpu::Color) -> FullscreenPass {
        FullscreenPass { gate, clear, ..self }
    }

    /// Records the pass over `target` with the pipeline for the frame's specialisation.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        bind_group: &wgpu::BindGroup,
        frame: FrameContext<'_>,
    ) {
        let pipeline = self.variants.get(frame.device, self.entry_point, self.gate, frame.spec);
        let depth = if self.gate == Gate::None { None } else { frame.depth };
        let target = (target, wgpu::LoadOp::Clear(self.clear));
        record_fullscreen(encoder, self.variants.label, target, depth, bind_group, &[&pipeline]);
    }
}

/// The compose pass (`shaders/compose.wgsl` with `shaders/data_common.wgsl`): the background
/// (`fs_sky`) and the geometry (`fs_compose`) are drawn by separate pipelines gated by the
/// G-buffer depth ([`Gate`]), so no pixel runs the other's code.
pub struct ComposePass {
    variants: Variants,
}

impl ComposePass {
    /// Compiles the shader. Inputs: contour + tone, depth + HLP radius, IDs, hatch
    /// coordinates + E, normal + tiles per pixel, albedo, the array of all TAMs, SAM, TAM
    /// sampler, SAM sampler, data layers ([`super::projection::DATA_FORMAT`]), the
    /// hatch-colour slots ([`super::projection::ProjectionPass::hatch_colors`]), the
    /// horizontally blurred tone ([`tone_blur`]).
    pub fn new(device: &wgpu::Device) -> ComposePass {
        use Input::*;
        let source = concat!(
            include_str!("../../../shaders/data_common.wgsl"),
            "\n",
            include_str!("../../../shaders/compose.wgsl")
        );
        let inputs =
            [Float, Float, Uint, Float, Float, Float, FilteredArray, Filtered, Sampler, Sampler, Uint, Uniform, Float];
        ComposePass { variants: Variants::new(device, "compose", source, &inputs, OUTPUT_FORMAT) }
    }

    /// Records the pass of one art-map group into `target`: the first group clears the
    /// target, further groups draw over it (their shaders discard the pixels of other groups).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        bind_group: &wgpu::BindGroup,
        first: bool,
        frame: FrameContext<'_>,
    ) {
        let load = if first { wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT) } else { wgpu::LoadOp::Load };
        let sky = self.variants.get(frame.device, "fs_sky", Gate::Background, frame.spec);
        let geometry = self.variants.get(frame.device, "fs_compose", Gate::Geometry, frame.spec);
        record_fullscreen(encoder, "compose", (target, load), frame.depth, bind_group, &[&sky, &geometry]);
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
/// Only pixels with geometry: the background carries no contour and white tone (contours lie
/// on the nearer surface, eq. 5.1).
pub fn contour(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "contour",
        include_str!("../../../shaders/contour.wgsl"),
        "fs_contour",
        &[Input::Float, Input::Float, Input::Float, Input::Uint],
        CONTOUR_FORMAT,
    )
    .gated(Gate::Geometry, wgpu::Color { r: 0.0, g: 1.0, b: 0.0, a: 1.0 })
}

/// The horizontal half of the tone blur (`shaders/tone_blur.wgsl`, thesis Fig. 6.9d).
/// Inputs: contour + tone, IDs (the style slot per pixel).
pub fn tone_blur(device: &wgpu::Device) -> FullscreenPass {
    FullscreenPass::new(
        device,
        "tone blur",
        include_str!("../../../shaders/tone_blur.wgsl"),
        "fs_tone_blur",
        &[Input::Float, Input::Uint],
        TONE_FORMAT,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Style;

    fn params(style: &Style) -> PostParams {
        PostParams::new(style, glam::Vec3::Z, 0.0, 6, 256, 0)
    }

    #[test]
    fn frames_are_specialised_only_on_what_all_slots_share() {
        let base = Style::default();
        let one = Specialization::for_frame(&[params(&base); 4], false, false);
        let uniform = Specialization {
            uniform_style: true,
            blur_radius: Some(base.tone_blur),
            surface_color: base.color > 0.0,
            ..Default::default()
        };
        assert_eq!(one, uniform);

        // Another hatch strength in one slot: styles differ, the blur radius is still shared.
        let strokes = Style { hatch_strength: 0.3, ..base.clone() };
        let mixed = Specialization::for_frame(&[params(&base), params(&strokes)], true, true);
        let expected = Specialization { uniform_style: false, hatch_colors: true, data_layers: true, ..uniform };
        assert_eq!(mixed, expected);

        let blurred = Style { tone_blur: base.tone_blur + 1, ..base.clone() };
        let radii = Specialization::for_frame(&[params(&base), params(&blurred)], false, false);
        assert_eq!(radii, Specialization { surface_color: base.color > 0.0, ..Default::default() });

        let colour = Style { color: 0.5, ..base.clone() };
        let coloured = Specialization::for_frame(&[params(&base), params(&colour)], false, false);
        assert!(coloured.surface_color);
    }
}
