//! The named render targets of one frame size ([`super::Target`]), kept between frames.

use super::Target;
use crate::render::gbuffer::{GBuffer, render_target};
use crate::render::projection::DATA_FORMAT;

/// Output format of the depth pre-filter.
pub const PREFILTER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
/// Output format of the contour pass: grey-level contour intensity (r) and tone (g).
pub const CONTOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg16Float;
/// Output format of the tone-blur pass: the horizontally blurred tone.
pub const TONE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;
/// Output format of the final image (sRGB-encoded values written directly).
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// The render targets of one frame size, kept for the next frames of that size: allocating
/// (and on a CPU adapter, page-faulting) ~60 MB of targets per 1024×768 frame costs time.
pub struct FrameTargets {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Stage one's targets.
    pub gbuffer: GBuffer,
    prefiltered: wgpu::TextureView,
    contours: wgpu::TextureView,
    tone: wgpu::TextureView,
    data_layers: wgpu::TextureView,
    /// The final image, for reading back.
    pub output: wgpu::Texture,
    output_view: wgpu::TextureView,
}

/// How many frame sizes keep their targets (a WebSocket session alternates two: moving and
/// still frames).
const CACHED_TARGET_SIZES: usize = 3;

impl FrameTargets {
    fn new(device: &wgpu::Device, width: u32, height: u32) -> FrameTargets {
        let view = |texture: wgpu::Texture| texture.create_view(&Default::default());
        let output = render_target(device, "output", OUTPUT_FORMAT, width, height);
        FrameTargets {
            width,
            height,
            gbuffer: GBuffer::new(device, width, height),
            prefiltered: view(render_target(device, "prefiltered depth", PREFILTER_FORMAT, width, height)),
            contours: view(render_target(device, "contours", CONTOUR_FORMAT, width, height)),
            tone: view(render_target(device, "tone", TONE_FORMAT, width, height)),
            data_layers: view(render_target(device, "data layers", DATA_FORMAT, width, height)),
            output_view: output.create_view(&Default::default()),
            output,
        }
    }

    /// The targets of a `width` × `height` frame from `cache` (most recently used last),
    /// allocated when missing; the least recently used size is dropped beyond
    /// [`CACHED_TARGET_SIZES`].
    pub fn get<'a>(
        cache: &'a mut Vec<FrameTargets>,
        device: &wgpu::Device,
        width: u32,
        height: u32,
    ) -> &'a FrameTargets {
        let targets = match cache.iter().position(|t| (t.width, t.height) == (width, height)) {
            Some(index) => cache.remove(index),
            None => FrameTargets::new(device, width, height),
        };
        cache.push(targets);
        if cache.len() > CACHED_TARGET_SIZES {
            cache.remove(0);
        }
        &cache[cache.len() - 1]
    }

    /// The view of `target`.
    pub fn view(&self, target: Target) -> &wgpu::TextureView {
        let g = &self.gbuffer;
        match target {
            Target::Albedo => &g.albedo,
            Target::Normal => &g.normal,
            Target::LinearDepth => &g.linear_depth,
            Target::Ids => &g.id,
            Target::Hatch => &g.hatch,
            Target::Prefiltered => &self.prefiltered,
            Target::Contours => &self.contours,
            Target::Tone => &self.tone,
            Target::DataLayers => &self.data_layers,
            Target::Output => &self.output_view,
        }
    }

    /// The bytes per pixel of every target of a frame and the depth buffer, for the GPU
    /// memory estimate.
    pub fn bytes_per_pixel() -> u64 {
        let formats = Target::ALL.map(Target::format).into_iter().chain([crate::render::gbuffer::DEPTH_FORMAT]);
        formats.map(|f| u64::from(f.target_pixel_byte_cost().unwrap_or(4))).sum()
    }
}
