//! The pipelines of a declared post pass ([`super::PostPassDecl`]): its bind layout from the
//! declaration's inputs, its shader compiled once, and pipelines specialised per frame.

use super::post_block::PostStyle;
use super::{BindingKind, Draws, Instances, PostPassDecl};
use crate::render::bind_layouts::{storage_entry, texture_entry, uniform_layout_entry};
use crate::render::gbuffer::DEPTH_FORMAT;
use std::collections::HashMap;
use std::sync::Mutex;

impl BindingKind {
    fn layout_entry(self, binding: u32) -> wgpu::BindGroupLayoutEntry {
        let float = |filterable| wgpu::TextureSampleType::Float { filterable };
        match self {
            BindingKind::Float => texture_entry(binding, float(false)),
            BindingKind::Uint => texture_entry(binding, wgpu::TextureSampleType::Uint),
            BindingKind::Filtered => texture_entry(binding, float(true)),
            BindingKind::FilteredArray => wgpu::BindGroupLayoutEntry {
                ty: wgpu::BindingType::Texture {
                    sample_type: float(true),
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
                ..texture_entry(binding, float(true))
            },
            BindingKind::Sampler => wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
            BindingKind::Uniform(_) => uniform_layout_entry(binding),
            BindingKind::Storage(_) => storage_entry(binding, wgpu::ShaderStages::VERTEX_FRAGMENT),
        }
    }
}

/// Frame-wide facts the post passes' shaders are specialised on (the override constants of
/// `shaders/post_common.wgsl`). On lavapipe every instruction of a shader runs for every pixel,
/// whichever way its branches go, so a frame that needs less gets pipelines compiled without
/// the rest. [`Specialization::default`] leaves out coloured hatchings, data layers, surface
/// colour and land cover: the passes that use no styles or data are compiled with it.
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
    /// Whether the terrain has land-cover classes; without, no pass looks one up.
    pub land_cover: bool,
}

impl Specialization {
    /// The specialisation of a frame whose style slots have the post parameters `slots`,
    /// with or without coloured hatchings, data layers and land-cover classes.
    pub fn for_frame(slots: &[PostStyle], hatch_colors: bool, data_layers: bool, land_cover: bool) -> Specialization {
        let uniform_style = slots.windows(2).all(|w| w[0] == w[1]);
        let shared_blur = slots.windows(2).all(|w| w[0].tone_blur == w[1].tone_blur);
        let blur_radius = slots.first().map(|s| s.tone_blur as u32).filter(|_| shared_blur);
        let surface_color = slots.iter().any(|s| s.color > 0.0);
        Specialization { uniform_style, blur_radius, hatch_colors, data_layers, surface_color, land_cover }
    }

    fn constants(self) -> [(&'static str, f64); 6] {
        let flag = |b: bool| f64::from(u8::from(b));
        [
            ("UNIFORM_STYLE", flag(self.uniform_style)),
            ("BLUR_RADIUS", self.blur_radius.map_or(-1.0, f64::from)),
            ("HATCH_COLORS", flag(self.hatch_colors)),
            ("DATA_LAYERS", flag(self.data_layers)),
            ("SURFACE_COLOR", flag(self.surface_color)),
            ("LAND_COVER", flag(self.land_cover)),
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
    draws: Draws,
    cache: Mutex<HashMap<(&'static str, Gate, Specialization), wgpu::RenderPipeline>>,
}

impl Variants {
    fn new(device: &wgpu::Device, decl: &PostPassDecl) -> Variants {
        let label = decl.name;
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(decl.shader_source().into()),
        });
        let mut entries = vec![uniform_layout_entry(0)];
        entries.extend(decl.inputs.iter().enumerate().map(|(i, b)| b.reads.kind().layout_entry(i as u32 + 1)));
        let layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries });
        Variants { label, shader, layout, output: decl.output_format(), draws: decl.draws, cache: Mutex::default() }
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
                post_pipeline(
                    device,
                    self.label,
                    &self.shader,
                    &self.layout,
                    (entry_point, &constants),
                    (self.output, self.draws),
                    gate,
                )
            })
            .clone()
    }
}

/// What the post passes of one frame are drawn with: the specialisation of their shaders and
/// the G-buffer depth that gated passes test against.
#[derive(Clone, Copy)]
pub struct FrameContext<'a> {
    /// The device.
    pub device: &'a wgpu::Device,
    /// What the frame's shaders are specialised on.
    pub spec: Specialization,
    /// The G-buffer depth (needed by gated passes only).
    pub depth: Option<&'a wgpu::TextureView>,
    /// Instances of the marks pass ([`crate::render::marks::Marks::instances`]).
    pub marks: u32,
    /// Crease lines the creases pass draws.
    pub creases: u32,
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

/// A pipeline drawing what `draws` says with `entry_point` into `output`, limited by `gate`,
/// with values for the shader's override constants: the full-screen triangle written as is,
/// or marks blended over the output (alpha over; the output stays opaque).
fn post_pipeline(
    device: &wgpu::Device,
    label: &'static str,
    shader: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    (entry_point, constants): (&str, &[(&str, f64)]),
    (output, draws): (wgpu::TextureFormat, Draws),
    gate: Gate,
) -> wgpu::RenderPipeline {
    let (vertex, blend) = match draws {
        Draws::Fullscreen => ("vs_fullscreen", None),
        Draws::Instanced(vertex, _) => (vertex, Some(wgpu::BlendState::ALPHA_BLENDING)),
    };
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
            entry_point: Some(vertex),
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
            targets: &[Some(wgpu::ColorTargetState { format: output, blend, write_mask: wgpu::ColorWrites::ALL })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Records one render pass over `target` (cleared or loaded) that draws `vertices` ×
/// `instances` (the full-screen triangle, or the frame's marks) with each pipeline in turn;
/// `depth` is the G-buffer depth that gated pipelines test against (read only).
fn record_post(
    encoder: &mut wgpu::CommandEncoder,
    label: &'static str,
    (target, load): (&wgpu::TextureView, wgpu::LoadOp<wgpu::Color>),
    depth: Option<&wgpu::TextureView>,
    bind_group: &wgpu::BindGroup,
    (pipelines, vertices, instances): (&[&wgpu::RenderPipeline], u32, u32),
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
        pass.draw(0..vertices, 0..instances);
    }
}

/// A declared post pass ready to draw: its shader, bind layout and pipeline variants.
pub struct PostPass {
    decl: &'static PostPassDecl,
    variants: Variants,
}

impl PostPass {
    /// Compiles the shader of `decl` and derives its bind layout from the declaration.
    pub fn new(device: &wgpu::Device, decl: &'static PostPassDecl) -> PostPass {
        PostPass { decl, variants: Variants::new(device, decl) }
    }

    /// The pass's declaration.
    pub fn decl(&self) -> &'static PostPassDecl {
        self.decl
    }

    /// Binds the `styles` block (binding 0) and `inputs`, in the declaration's order.
    pub fn bind_group(
        &self,
        device: &wgpu::Device,
        styles: &wgpu::Buffer,
        inputs: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: styles.as_entire_binding() }];
        entries.extend(
            inputs
                .iter()
                .enumerate()
                .map(|(i, resource)| wgpu::BindGroupEntry { binding: i as u32 + 1, resource: resource.clone() }),
        );
        let layout = &self.variants.layout;
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(self.decl.name), layout, entries: &entries })
    }

    /// Records the pass over `target`: cleared to the declaration's colour when `clear`, drawn
    /// over otherwise (the later art-map groups of compose, and always for marks), each entry
    /// point with the pipeline for the frame's specialisation.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        bind_group: &wgpu::BindGroup,
        clear: bool,
        frame: FrameContext<'_>,
    ) {
        let pipelines: Vec<wgpu::RenderPipeline> = self
            .decl
            .entry_points
            .iter()
            .map(|&(entry, gate)| self.variants.get(frame.device, entry, gate, frame.spec))
            .collect();
        let gated = self.decl.entry_points.iter().any(|(_, gate)| *gate != Gate::None);
        let depth = if gated { frame.depth } else { None };
        let (vertices, instances, clear) = match self.decl.draws {
            Draws::Fullscreen => (3, 1, clear),
            Draws::Instanced(_, Instances::Marks) => (6, frame.marks, false),
            Draws::Instanced(_, Instances::Creases) => (6, frame.creases, false),
        };
        let load = if clear { wgpu::LoadOp::Clear(self.decl.clear) } else { wgpu::LoadOp::Load };
        let pipelines: Vec<&wgpu::RenderPipeline> = pipelines.iter().collect();
        record_post(encoder, self.decl.name, (target, load), depth, bind_group, (&pipelines, vertices, instances));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Style;

    fn params(style: &Style) -> PostStyle {
        PostStyle::new(style, glam::Vec3::Z, 0.0, 6, 256, 0)
    }

    #[test]
    fn frames_are_specialised_only_on_what_all_slots_share() {
        let base = Style::default();
        let one = Specialization::for_frame(&[params(&base); 4], false, false, false);
        let uniform = Specialization {
            uniform_style: true,
            blur_radius: Some(base.tone_blur),
            surface_color: base.color > 0.0,
            ..Default::default()
        };
        assert_eq!(one, uniform);

        // Another hatch strength in one slot: styles differ, the blur radius is still shared.
        let strokes = Style { hatch_strength: 0.3, ..base.clone() };
        let mixed = Specialization::for_frame(&[params(&base), params(&strokes)], true, true, true);
        let expected =
            Specialization { uniform_style: false, hatch_colors: true, data_layers: true, land_cover: true, ..uniform };
        assert_eq!(mixed, expected);

        let blurred = Style { tone_blur: base.tone_blur + 1, ..base.clone() };
        let radii = Specialization::for_frame(&[params(&base), params(&blurred)], false, false, false);
        assert_eq!(radii, Specialization { surface_color: base.color > 0.0, ..Default::default() });

        let colour = Style { color: 0.5, ..base.clone() };
        let coloured = Specialization::for_frame(&[params(&base), params(&colour)], false, false, false);
        assert!(coloured.surface_color);
    }
}
