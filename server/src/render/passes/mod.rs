//! Stage two as data (thesis 8.2, NPAR §9): every post-processing pass is one
//! [`PostPassDecl`] — its WGSL file, entry points, the render targets and frame resources it
//! reads, by name, and the target it writes — and a frame runs the geometry pass, then
//! [`POST_PASSES`] in order over the named [`Target`]s. Binding indices and the shaders'
//! `@binding` declarations both come from the order of a declaration's inputs
//! ([`PostPassDecl::shader_source`], [`pipeline::PostPass::new`]), so a new pass is a WGSL
//! file plus one declaration here (see the guide's architecture chapter). Most passes draw the
//! full-screen triangle; the marks pass ([`MARKS`]) draws instanced quads over the output
//! ([`Draws`]).

pub mod pipeline;
pub mod post_block;
pub mod targets;

use crate::render::creases::CreaseLine;
use crate::render::ground_cover::CoverStyle;
use crate::render::layer_code::LayerCode;
use crate::render::marks::Marks;
use crate::render::projection::{DataBlock, HatchColors};
use crate::render::uniforms::Declarations;
pub use pipeline::{Gate, PostPass, Specialization};
use post_block::Styles;

/// A render target of a frame, by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// G-buffer: albedo (linear RGB) and coverage.
    Albedo,
    /// G-buffer: HLP-blended normal and TAM tiles per pixel.
    Normal,
    /// G-buffer: linear depth and HLP radius in pixels.
    LinearDepth,
    /// G-buffer: object and patch IDs.
    Ids,
    /// G-buffer: hatch coordinates and E.
    Hatch,
    /// The depth pre-filter's output (thesis eq. 5.4).
    Prefiltered,
    /// Contour intensity and tone.
    Contours,
    /// The horizontally blurred tone.
    Tone,
    /// The projected data layers (thesis 9.3).
    DataLayers,
    /// The final image.
    Output,
}

impl Target {
    /// Every target of a frame.
    pub const ALL: [Target; 10] = [
        Target::Albedo,
        Target::Normal,
        Target::LinearDepth,
        Target::Ids,
        Target::Hatch,
        Target::Prefiltered,
        Target::Contours,
        Target::Tone,
        Target::DataLayers,
        Target::Output,
    ];

    /// The texture format of the target.
    pub fn format(self) -> wgpu::TextureFormat {
        use crate::render::gbuffer::*;
        match self {
            Target::Albedo => ALBEDO_FORMAT,
            Target::Normal => NORMAL_FORMAT,
            Target::LinearDepth => LINEAR_DEPTH_FORMAT,
            Target::Ids => ID_FORMAT,
            Target::Hatch => HATCH_FORMAT,
            Target::Prefiltered => targets::PREFILTER_FORMAT,
            Target::Contours => targets::CONTOUR_FORMAT,
            Target::Tone => targets::TONE_FORMAT,
            Target::DataLayers => crate::render::projection::DATA_FORMAT,
            Target::Output => targets::OUTPUT_FORMAT,
        }
    }
}

/// What one binding of a post pass reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Resource {
    /// A render target of the frame.
    Target(Target),
    /// The array of all tonal art maps.
    Tams,
    /// The silhouette art map of the pass's art-map group.
    Sam,
    /// The sampler of the TAMs.
    TamSampler,
    /// The sampler of the SAMs.
    SamSampler,
    /// The hatch-colour slots of the data layers ([`HatchColors`]).
    HatchColors,
    /// The projection pass's own block ([`DataBlock`]).
    DataBlock,
    /// The earlier bracketing time step of data mapping slot `i` (an `R32Float` grid).
    FieldLower(usize),
    /// The later bracketing time step of data mapping slot `i`.
    FieldUpper(usize),
    /// The colour table of data mapping slot `i`.
    FieldColors(usize),
    /// The marks pass's own block: the frame's pins and split line ([`Marks`]).
    Marks,
    /// The digits of the pins' heads ([`crate::render::marks::GlyphAtlas`]).
    Glyphs,
    /// The land-cover classes of the ground ([`crate::render::ground_cover::CoverStyle`]).
    CoverClasses,
    /// The terrain's crease lines ([`crate::render::creases::CreaseLine`]).
    CreaseLines,
}

/// How a shader reads a binding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindingKind {
    /// A texture read with `textureLoad` (unfilterable float).
    Float,
    /// An unsigned-integer texture.
    Uint,
    /// A filterable 2D texture sampled with a sampler.
    Filtered,
    /// A filterable 2D array texture.
    FilteredArray,
    /// A filtering sampler.
    Sampler,
    /// A uniform block of the named WGSL type.
    Uniform(&'static str),
    /// A read-only storage array of the named WGSL type.
    Storage(&'static str),
}

impl Resource {
    /// How shaders read the resource.
    pub fn kind(self) -> BindingKind {
        match self {
            Resource::Target(Target::Ids | Target::DataLayers) => BindingKind::Uint,
            Resource::Target(_)
            | Resource::FieldLower(_)
            | Resource::FieldUpper(_)
            | Resource::FieldColors(_)
            | Resource::Glyphs => BindingKind::Float,
            Resource::Tams => BindingKind::FilteredArray,
            Resource::Sam => BindingKind::Filtered,
            Resource::TamSampler | Resource::SamSampler => BindingKind::Sampler,
            Resource::HatchColors => BindingKind::Uniform("HatchColors"),
            Resource::DataBlock => BindingKind::Uniform("DataBlock"),
            Resource::Marks => BindingKind::Uniform("Marks"),
            Resource::CoverClasses => BindingKind::Storage("CoverStyle"),
            Resource::CreaseLines => BindingKind::Storage("CreaseLine"),
        }
    }

    /// The WGSL structs a uniform resource needs.
    fn declarations(self) -> String {
        match self {
            Resource::HatchColors => Declarations::of::<HatchColors>(),
            Resource::DataBlock => Declarations::of::<DataBlock>(),
            Resource::Marks => Declarations::of::<Marks>(),
            Resource::CoverClasses => Declarations::of::<CoverStyle>(),
            Resource::CreaseLines => Declarations::of::<CreaseLine>(),
            _ => String::new(),
        }
    }
}

/// One input of a pass: the name its shader reads it by, and what it is.
#[derive(Debug, Clone, Copy)]
pub struct Binding {
    /// The WGSL variable.
    pub name: &'static str,
    /// What is bound.
    pub reads: Resource,
}

/// When a pass runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum When {
    /// Every frame.
    Always,
    /// When the base style pre-filters the depth for contours (`contour_prefilter`).
    Prefilter,
    /// When the frame has data layers to project (or style layers with TAMs of their own).
    DataLayers,
    /// When the frame has pins or a split line to draw.
    Marks,
    /// When the terrain's style draws crease lines and the scene has some.
    Creases,
}

/// What a pass draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Draws {
    /// The full-screen triangle (`vs_fullscreen`), replacing what its output held.
    Fullscreen,
    /// Six vertices per instance from the named vertex entry point, one instance per item
    /// of `Instances`, blended over the output it keeps.
    Instanced(&'static str, Instances),
}

/// What the instances of a [`Draws::Instanced`] pass are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Instances {
    /// The frame's marks ([`Marks::instances`]).
    Marks,
    /// The scene's crease lines.
    Creases,
}

/// One post-processing pass, declared once.
#[derive(Debug)]
pub struct PostPassDecl {
    /// Name in logs, pipeline labels and the per-pass metrics.
    pub name: &'static str,
    /// The WGSL source (its helpers first when it has several files).
    pub shader: &'static str,
    /// Fragment entry points drawn in turn, each limited by its [`Gate`].
    pub entry_points: &'static [(&'static str, Gate)],
    /// Inputs in binding order after the `styles` block at binding 0.
    pub inputs: &'static [Binding],
    /// The target written.
    pub output: Target,
    /// What the output is cleared to before the first draw.
    pub clear: wgpu::Color,
    /// When the pass runs.
    pub runs: When,
    /// Where readers of the output read when the pass does not run (a pass-through).
    pub bypass: Option<Target>,
    /// Whether the pass runs once per art-map group, each over the last (compose).
    pub per_art_group: bool,
    /// What it draws.
    pub draws: Draws,
}

const FULLSCREEN: &str = include_str!("../../../../shaders/fullscreen.wgsl");
const POST_COMMON: &str = include_str!("../../../../shaders/post_common.wgsl");

impl PostPassDecl {
    /// The format of the target the pass writes.
    pub fn output_format(&self) -> wgpu::TextureFormat {
        self.output.format()
    }

    /// The pass's complete WGSL: the shared vertex stage, the uniform structs, the binding
    /// declarations derived from [`PostPassDecl::inputs`], the shared post helpers and the
    /// pass's own source.
    pub fn shader_source(&self) -> String {
        let mut code = format!("{FULLSCREEN}\n{}{}", LayerCode::wgsl_constants(), Declarations::of::<Styles>());
        let mut declared = Vec::new();
        for binding in self.inputs {
            let structs = binding.reads.declarations();
            if !declared.contains(&structs) {
                code.push_str(&structs);
                declared.push(structs);
            }
        }
        code.push_str("@group(0) @binding(0) var<uniform> styles: Styles;\n");
        for (i, binding) in self.inputs.iter().enumerate() {
            let ty = match binding.reads.kind() {
                BindingKind::Float | BindingKind::Filtered => "texture_2d<f32>".to_owned(),
                BindingKind::Uint => "texture_2d<u32>".to_owned(),
                BindingKind::FilteredArray => "texture_2d_array<f32>".to_owned(),
                BindingKind::Sampler => "sampler".to_owned(),
                BindingKind::Uniform(ty) => {
                    code.push_str(&format!("@group(0) @binding({}) var<uniform> {}: {ty};\n", i + 1, binding.name));
                    continue;
                }
                BindingKind::Storage(ty) => {
                    let name = binding.name;
                    code.push_str(&format!("@group(0) @binding({}) var<storage, read> {name}: array<{ty}>;\n", i + 1));
                    continue;
                }
            };
            code.push_str(&format!("@group(0) @binding({}) var {}: {ty};\n", i + 1, binding.name));
        }
        format!("{code}\n{POST_COMMON}\n{}", self.shader)
    }
}

const fn input(name: &'static str, reads: Resource) -> Binding {
    Binding { name, reads }
}

const fn target(name: &'static str, target: Target) -> Binding {
    input(name, Resource::Target(target))
}

const TRANSPARENT: wgpu::Color = wgpu::Color::TRANSPARENT;

/// The depth pre-filter (`shaders/prefilter.wgsl`, thesis eq. 5.4).
pub const PREFILTER: PostPassDecl = PostPassDecl {
    name: "prefilter",
    shader: include_str!("../../../../shaders/prefilter.wgsl"),
    entry_points: &[("fs_prefilter", Gate::None)],
    inputs: &[target("depth_tex", Target::LinearDepth)],
    output: Target::Prefiltered,
    clear: TRANSPARENT,
    runs: When::Prefilter,
    bypass: Some(Target::LinearDepth),
    per_art_group: false,
    draws: Draws::Fullscreen,
};

/// The contour and tone pass (`shaders/contour.wgsl`, thesis eq. 5.1, 6.7), on pixels with
/// geometry only: the background carries no contour and white tone (contours lie on the
/// nearer surface, eq. 5.1).
pub const CONTOUR: PostPassDecl = PostPassDecl {
    name: "contour",
    shader: concat!(
        include_str!("../../../../shaders/cover_common.wgsl"),
        "\n",
        include_str!("../../../../shaders/contour.wgsl")
    ),
    entry_points: &[("fs_contour", Gate::Geometry)],
    inputs: &[
        target("depth_tex", Target::Prefiltered),
        target("albedo_tex", Target::Albedo),
        target("normal_tex", Target::Normal),
        target("id_tex", Target::Ids),
        input("cover", Resource::CoverClasses),
    ],
    output: Target::Contours,
    clear: wgpu::Color { r: 0.0, g: 1.0, b: 0.0, a: 1.0 },
    runs: When::Always,
    bypass: None,
    per_art_group: false,
    draws: Draws::Fullscreen,
};

/// The horizontal half of the tone blur (`shaders/tone_blur.wgsl`, thesis Fig. 6.9d).
pub const TONE_BLUR: PostPassDecl = PostPassDecl {
    name: "tone_blur",
    shader: include_str!("../../../../shaders/tone_blur.wgsl"),
    entry_points: &[("fs_tone_blur", Gate::None)],
    inputs: &[target("contour_tex", Target::Contours), target("id_tex", Target::Ids)],
    output: Target::Tone,
    clear: TRANSPARENT,
    runs: When::Always,
    bypass: None,
    per_art_group: false,
    draws: Draws::Fullscreen,
};

/// D2–D5: data layers projected onto the landscape (`shaders/data.wgsl`, thesis 9.3;
/// [`crate::render::projection`] prepares its block and fields).
pub const DATA: PostPassDecl = PostPassDecl {
    name: "data",
    shader: concat!(
        include_str!("../../../../shaders/cover_common.wgsl"),
        "\n",
        include_str!("../../../../shaders/data.wgsl")
    ),
    entry_points: &[("fs_data", Gate::None)],
    inputs: &[
        input("data", Resource::DataBlock),
        target("depth_tex", Target::LinearDepth),
        target("id_tex", Target::Ids),
        input("lower0", Resource::FieldLower(0)),
        input("upper0", Resource::FieldUpper(0)),
        input("lut0", Resource::FieldColors(0)),
        input("lower1", Resource::FieldLower(1)),
        input("upper1", Resource::FieldUpper(1)),
        input("lut1", Resource::FieldColors(1)),
        input("lower2", Resource::FieldLower(2)),
        input("upper2", Resource::FieldUpper(2)),
        input("lut2", Resource::FieldColors(2)),
        input("cover", Resource::CoverClasses),
    ],
    output: Target::DataLayers,
    clear: TRANSPARENT,
    runs: When::DataLayers,
    bypass: None,
    per_art_group: false,
    draws: Draws::Fullscreen,
};

/// The compose pass (`shaders/data_common.wgsl` + `shaders/compose.wgsl`: eq. 5.2, vertical
/// tone blur, TAM hatching, SAM silhouettes, paper, colour, data layers): the background
/// (`fs_sky`) and the geometry (`fs_compose`) are drawn by separate pipelines gated by the
/// G-buffer depth, so no pixel runs the other's code; once per art-map group.
pub const COMPOSE: PostPassDecl = PostPassDecl {
    name: "compose",
    shader: concat!(
        include_str!("../../../../shaders/cover_common.wgsl"),
        "\n",
        include_str!("../../../../shaders/data_common.wgsl"),
        "\n",
        include_str!("../../../../shaders/compose.wgsl")
    ),
    entry_points: &[("fs_sky", Gate::Background), ("fs_compose", Gate::Geometry)],
    inputs: &[
        target("contour_tex", Target::Contours),
        target("depth_tex", Target::LinearDepth),
        target("id_tex", Target::Ids),
        target("hatch_tex", Target::Hatch),
        target("normal_tex", Target::Normal),
        target("albedo_tex", Target::Albedo),
        input("tam", Resource::Tams),
        input("sam", Resource::Sam),
        input("tam_sampler", Resource::TamSampler),
        input("sam_sampler", Resource::SamSampler),
        target("data_tex", Target::DataLayers),
        input("hatch_colors", Resource::HatchColors),
        target("tone_tex", Target::Tone),
        input("cover", Resource::CoverClasses),
    ],
    output: Target::Output,
    clear: TRANSPARENT,
    runs: When::Always,
    bypass: None,
    per_art_group: true,
    draws: Draws::Fullscreen,
};

/// The marks pass (`shaders/marks.wgsl`): comment pins, numbered, standing at their world
/// points and hidden where the scene's depth puts terrain or plants in front of them, and the
/// pen line of a split view ([`crate::render::marks`]); over the composed image.
pub const MARKS: PostPassDecl = PostPassDecl {
    name: "marks",
    shader: include_str!("../../../../shaders/marks.wgsl"),
    entry_points: &[("fs_marks", Gate::None)],
    inputs: &[
        input("marks", Resource::Marks),
        target("depth_tex", Target::LinearDepth),
        input("glyphs", Resource::Glyphs),
    ],
    output: Target::Output,
    clear: TRANSPARENT,
    runs: When::Marks,
    bypass: None,
    per_art_group: false,
    draws: Draws::Instanced("vs_marks", Instances::Marks),
};

/// The creases pass (`shaders/creases.wgsl`): the terrain's valley bottoms and ridge crests
/// ([`crate::render::creases`]) as pen lines over the composed image, before the pins.
pub const CREASES: PostPassDecl = PostPassDecl {
    name: "creases",
    shader: include_str!("../../../../shaders/creases.wgsl"),
    entry_points: &[("fs_creases", Gate::None)],
    inputs: &[
        input("marks", Resource::Marks),
        target("depth_tex", Target::LinearDepth),
        input("creases", Resource::CreaseLines),
    ],
    output: Target::Output,
    clear: TRANSPARENT,
    runs: When::Creases,
    bypass: None,
    per_art_group: false,
    draws: Draws::Instanced("vs_creases", Instances::Creases),
};

/// The post passes of a frame, in the order they run after the geometry pass.
pub const POST_PASSES: [&PostPassDecl; 7] = [&PREFILTER, &CONTOUR, &TONE_BLUR, &DATA, &COMPOSE, &CREASES, &MARKS];

/// A plain copy of the output (`shaders/copy.wgsl`): the cheapest possible full-screen pass,
/// the floor the benchmark compares the NPR passes with; not part of a frame.
pub const COPY: PostPassDecl = PostPassDecl {
    name: "copy",
    shader: include_str!("../../../../shaders/copy.wgsl"),
    entry_points: &[("fs_copy", Gate::None)],
    inputs: &[target("source", Target::Output)],
    output: Target::Output,
    clear: TRANSPARENT,
    runs: When::Always,
    bypass: None,
    per_art_group: false,
    draws: Draws::Fullscreen,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bindings_are_declared_in_input_order_after_the_styles_block() {
        let wgsl = COMPOSE.shader_source();
        assert!(wgsl.contains("@group(0) @binding(0) var<uniform> styles: Styles;"));
        assert!(wgsl.contains("@group(0) @binding(1) var contour_tex: texture_2d<f32>;"));
        assert!(wgsl.contains("@group(0) @binding(3) var id_tex: texture_2d<u32>;"));
        assert!(wgsl.contains("@group(0) @binding(7) var tam: texture_2d_array<f32>;"));
        assert!(wgsl.contains("@group(0) @binding(12) var<uniform> hatch_colors: HatchColors;"));
        assert!(wgsl.contains("@group(0) @binding(13) var tone_tex: texture_2d<f32>;"));
        assert!(wgsl.contains("struct HatchColors {"));
        // Only the passes' own declarations: no shader file declares a binding by hand.
        for pass in POST_PASSES.iter().chain([&&COPY]) {
            assert_eq!(pass.shader_source().matches("@binding(0)").count(), 1, "{}", pass.name);
            assert!(!pass.shader.contains("@binding"), "{} declares bindings by hand", pass.name);
        }
    }

    #[test]
    fn every_declared_pass_compiles_and_validates() {
        for pass in POST_PASSES.iter().chain([&&COPY]) {
            crate::render::uniforms::validate_wgsl(pass.name, &pass.shader_source());
        }
    }

    #[test]
    fn every_pass_output_is_a_target_no_earlier_pass_needs_after_it() {
        // A pass reads only targets written before it (by the geometry pass or an earlier
        // post pass), so the order of POST_PASSES is an order the frame can run in.
        let gbuffer = [Target::Albedo, Target::Normal, Target::LinearDepth, Target::Ids, Target::Hatch];
        let mut written: Vec<Target> = gbuffer.to_vec();
        for pass in POST_PASSES {
            for binding in pass.inputs {
                if let Resource::Target(t) = binding.reads {
                    assert!(written.contains(&t), "{} reads {t:?} before it is written", pass.name);
                }
            }
            written.push(pass.output);
        }
    }
}
