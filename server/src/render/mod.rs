//! Offscreen wgpu rendering in two stages (thesis 8.2, NPAR §9): a G-buffer pass that draws
//! terrain and instanced plants into several render targets, then post-processing passes that
//! turn the G-buffer into a pen-and-ink image. All style parameters live in [`style::Style`].

pub mod art_textures;
pub mod artmaps;
pub mod bake;
pub mod bind_layouts;
pub mod coherence;
pub mod compare;
pub mod creases;
pub mod device;
pub mod gbuffer;
pub mod ground_cover;
pub mod image_format;
pub mod layer_code;
pub mod marks;
pub mod parametrization;
pub mod passes;
pub mod presets;
pub mod profile;
pub mod projection;
mod readback;
pub mod renderer;
pub mod scene_gpu;
pub mod style;
pub mod uniforms;
pub mod view_style;

pub use device::Gpu;
pub use renderer::{Frame, FrameRequest, Readback, RenderOptions, Renderer};
pub use style::Style;

/// Errors raised while setting up the GPU or rendering a frame.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter (GPU or software rasterizer such as lavapipe) could be found.
    #[error(
        "no graphics adapter found ({0}); on a machine without a GPU install Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1"
    )]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("cannot create a device on adapter '{adapter}': {message}")]
    Device { adapter: String, message: String },
    /// A validation or out-of-memory error reported by wgpu while rendering.
    #[error("GPU error during {stage}: {message}")]
    Gpu { stage: &'static str, message: String },
    /// Geometry larger than the adapter's largest buffer.
    #[error("{what} need a buffer of {} MiB, more than the graphics adapter allows ({} MiB); {hint}", bytes >> 20, limit >> 20)]
    TooLarge { what: String, bytes: u64, limit: u64, hint: &'static str },
    /// Waiting for the GPU or mapping the read-back buffer failed.
    #[error("reading the frame back from the GPU failed: {0}")]
    Readback(String),
    /// The requested image size is empty or larger than the device allows.
    #[error("image size {width}x{height} is out of range (1..={max} per side)")]
    Size { width: u32, height: u32, max: u32 },
    /// A style names an art map the renderer does not have.
    #[error("style parameter `{field}` = {index} names no art map (there are {count})")]
    UnknownArtMap { field: &'static str, index: usize, count: usize },
    /// An art-map change the renderer refuses (an index beyond the maps, a TAM whose shape
    /// differs from the others', too many maps).
    #[error("{kind} {index}: {message}")]
    ArtMap { kind: art_textures::ArtKind, index: usize, message: String },
    /// Data layers that cannot be drawn (too many mappings, an unsupported target, a field that
    /// cannot be placed in the scene).
    #[error("data layers: {0}")]
    Data(String),
    /// Renderer options are inconsistent.
    #[error("invalid renderer options: {0}")]
    Options(String),
    /// A style parameter is outside its allowed range.
    #[error("style parameter `{field}` = {value} is out of range ({range})")]
    Style { field: &'static str, value: f32, range: &'static str },
    /// A style field has the wrong type, or the style names an unknown field (`field` is
    /// `None` when the error is about the object as a whole).
    #[error("invalid style{}: {message}", field.as_ref().map(|f| format!(" parameter `{f}`")).unwrap_or_default())]
    StyleField { field: Option<String>, message: String },
    /// A style preset name that does not exist.
    #[error("unknown style preset `{}`; presets: {known}", crate::echo::echo(.name))]
    UnknownPreset { name: String, known: String },
    /// A per-layer style for a layer the scene does not have.
    #[error("style layer `{}` is not a layer of this scene; layers: {known}", crate::echo::echo(.name))]
    UnknownLayer { name: String, known: String },
    /// A before/after comparison of a layer the scene does not have among its vegetation
    /// layers.
    #[error("compare layer `{}` is not a vegetation layer of this scene; layers: {known}", crate::echo::echo(.name))]
    CompareLayer { name: String, known: String },
    /// A before/after comparison that cannot be drawn (a split outside the image).
    #[error("compare: {0}")]
    Compare(String),
    /// A per-layer style for a vegetation layer beyond the style slots.
    #[error(
        "style layer `{}`: only the first {max} vegetation layers can have styles of their own",
        crate::echo::echo(.name)
    )]
    LayerSlots { name: String, max: usize },
}
