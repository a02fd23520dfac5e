//! The frame loop: G-buffer pass, depth pre-filter, contour + tone pass, compose pass,
//! read-back.

use super::art_textures::ArtTextures;
use super::gbuffer::{FrameUniform, GBuffer, GeometryPass, render_target};
use super::parametrization::ReferenceCoords;
use super::post::{self, CONTOUR_FORMAT, FullscreenPass, OUTPUT_FORMAT, PREFILTER_FORMAT};
use super::scene_gpu::SceneGpu;
use super::style::{PostParams, Style};
use super::{Gpu, RenderError, readback};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use std::sync::Arc;
use tracing::debug;
use wgpu::util::DeviceExt;

/// Renders one scene from any camera in any [`Style`]. GPU resources of the scene are built
/// once in [`Renderer::new`]; each frame only records and submits passes.
pub struct Renderer {
    gpu: Arc<Gpu>,
    geometry: GeometryPass,
    prefilter: FullscreenPass,
    contour: FullscreenPass,
    compose: FullscreenPass,
    scene: SceneGpu,
    art: ArtTextures,
    sun: glam::Vec3,
}

/// A wgpu error with all its causes on one line.
fn error_chain(error: &wgpu::Error) -> String {
    let mut message = error.to_string().lines().next().unwrap_or_default().to_owned();
    let mut source = std::error::Error::source(error);
    while let Some(cause) = source {
        message.push_str(": ");
        message.push_str(&cause.to_string());
        source = cause.source();
    }
    message
}

/// The per-view state of an animated sequence (a WebSocket session, a camera path): the
/// reference texture coordinates of the hybrid hatching (thesis eq. 6.2), which follow the
/// camera from frame to frame so strokes stay on the plants.
pub struct ViewState {
    references: ReferenceCoords,
    buffer: wgpu::Buffer,
}

/// A rendered frame with its linear depth (metres, row-major), for motion-compensated
/// comparisons of consecutive frames.
pub struct FrameWithDepth {
    pub image: image::RgbaImage,
    pub depth: Vec<f32>,
}

impl Renderer {
    /// Compiles the pipelines, generates the default art maps and uploads `scene` to the GPU.
    pub fn new(gpu: Arc<Gpu>, scene: &Scene) -> Renderer {
        let geometry = GeometryPass::new(&gpu.device);
        let scene_gpu = SceneGpu::new(&gpu.device, &gpu.queue, &geometry, scene);
        Renderer {
            sun: scene.sun.direction(),
            prefilter: post::prefilter(&gpu.device),
            contour: post::contour(&gpu.device),
            compose: post::compose(&gpu.device),
            art: ArtTextures::defaults(&gpu.device, &gpu.queue),
            gpu,
            geometry,
            scene: scene_gpu,
        }
    }

    /// Triangles the geometry pass submits per frame.
    pub fn triangles_per_frame(&self) -> u64 {
        self.scene.triangles()
    }

    /// Number of tonal art maps (`Style::hatch_map` indexes them) and silhouette art maps
    /// (`Style::silhouette_map`).
    pub fn art_map_counts(&self) -> (usize, usize) {
        (self.art.tams.len(), self.art.sams.len())
    }

    fn check(&self, style: &Style, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.gpu.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Size { width, height, max });
        }
        style.validate()?;
        let (tams, sams) = self.art_map_counts();
        if style.hatch_map >= tams {
            return Err(RenderError::UnknownArtMap { field: "hatch_map", index: style.hatch_map, count: tams });
        }
        if style.silhouette_map >= sams {
            return Err(RenderError::UnknownArtMap {
                field: "silhouette_map",
                index: style.silhouette_map,
                count: sams,
            });
        }
        Ok(())
    }

    /// Binds the frame uniforms of `camera` and the reference coordinates `references`.
    fn frame_bind_group(
        &self,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
        references: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let device = &self.gpu.device;
        let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: bytemuck::bytes_of(&FrameUniform::new(camera, style, width, height)),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &self.geometry.frame_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: references.as_entire_binding() },
            ],
        })
    }

    /// Runs `work` inside a validation error scope, turning wgpu errors into [`RenderError`].
    fn scoped<T>(&self, work: impl FnOnce() -> Result<T, RenderError>) -> Result<T, RenderError> {
        let scope = self.gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let result = work();
        match pollster::block_on(scope.pop()) {
            Some(error) => Err(RenderError::Gpu { stage: "frame", message: error_chain(&error) }),
            None => result,
        }
    }

    /// The object ID of every pixel (row-major; see [`super::gbuffer::object_id`]), from the
    /// G-buffer pass alone: for picking the plant under a pointer, and for tests.
    pub fn object_ids(&self, camera: &Camera, width: u32, height: u32) -> Result<Vec<u32>, RenderError> {
        let style = Style::default();
        self.check(&style, width, height)?;
        self.scoped(|| {
            let device = &self.gpu.device;
            let gbuffer = GBuffer::new(device, width, height);
            let frame = self.frame_bind_group(camera, &style, width, height, self.scene.zero_references());
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ids") });
            self.geometry.encode(&mut encoder, &gbuffer, &frame, &self.scene);
            self.gpu.queue.submit([encoder.finish()]);
            let texels = readback::read_texels(&self.gpu, &gbuffer.id_texture, width, height, 8)?;
            Ok(texels.chunks_exact(8).map(|b| u32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect())
        })
    }

    /// Renders a `width` × `height` pen-and-ink image of the scene seen from `camera`. Without
    /// history, every HLP's reference texture coordinates are zero, so the same request always
    /// gives the same image.
    pub fn render(
        &self,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
    ) -> Result<image::RgbaImage, RenderError> {
        self.check(style, width, height)?;
        self.scoped(|| Ok(self.render_frame(camera, style, width, height, self.scene.zero_references(), false)?.image))
    }

    /// A fresh per-view state for [`Renderer::render_view`].
    pub fn new_view_state(&self) -> ViewState {
        let references = ReferenceCoords::new(self.scene.reference_centers().to_vec());
        let buffer = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("references"),
            size: 8 * references.as_slice().len().max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        ViewState { references, buffer }
    }

    /// Renders the next frame of an animated view: first moves the hatching reference
    /// coordinates with the camera (thesis eq. 6.2), then renders with them. Returns the depth
    /// too when `with_depth` is set.
    pub fn render_view(
        &self,
        state: &mut ViewState,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
        with_depth: bool,
    ) -> Result<FrameWithDepth, RenderError> {
        self.check(style, width, height)?;
        state.references.update(glam::Vec3::from(camera.position), style.hatch_tiles);
        if !state.references.as_slice().is_empty() {
            self.gpu.queue.write_buffer(&state.buffer, 0, bytemuck::cast_slice(state.references.as_slice()));
        }
        self.scoped(|| self.render_frame(camera, style, width, height, &state.buffer, with_depth))
    }

    fn render_frame(
        &self,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
        references: &wgpu::Buffer,
        with_depth: bool,
    ) -> Result<FrameWithDepth, RenderError> {
        let device = &self.gpu.device;
        let started = std::time::Instant::now();
        let gbuffer = GBuffer::new(device, width, height);
        let prefiltered = render_target(device, "prefiltered depth", PREFILTER_FORMAT, width, height)
            .create_view(&Default::default());
        let contours =
            render_target(device, "contours", CONTOUR_FORMAT, width, height).create_view(&Default::default());
        let output = render_target(device, "output", OUTPUT_FORMAT, width, height);
        let output_view = output.create_view(&Default::default());

        let frame = self.frame_bind_group(camera, style, width, height, references);
        let tam = &self.art.tams[style.hatch_map];
        let params = PostParams::new(style, self.sun, camera.roll.to_radians(), tam.levels, tam.size);
        let post_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("post"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = wgpu::BindingResource::TextureView;
        let depth_for_contours = if style.contour_prefilter { &prefiltered } else { &gbuffer.linear_depth };
        let prefilter_inputs = self.prefilter.bind_group(device, &post_buffer, &[view(&gbuffer.linear_depth)]);
        let contour_inputs = self.contour.bind_group(
            device,
            &post_buffer,
            &[view(depth_for_contours), view(&gbuffer.albedo), view(&gbuffer.normal)],
        );
        let compose_inputs = self.compose.bind_group(
            device,
            &post_buffer,
            &[
                view(&contours),
                view(&gbuffer.linear_depth),
                view(&gbuffer.id),
                view(&gbuffer.hatch),
                view(&gbuffer.normal),
                view(&gbuffer.albedo),
                view(&tam.view),
                view(&self.art.sams[style.silhouette_map]),
                wgpu::BindingResource::Sampler(&self.art.tam_sampler),
                wgpu::BindingResource::Sampler(&self.art.sam_sampler),
            ],
        );

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        self.geometry.encode(&mut encoder, &gbuffer, &frame, &self.scene);
        if style.contour_prefilter {
            self.prefilter.encode(&mut encoder, &prefiltered, &prefilter_inputs);
        }
        self.contour.encode(&mut encoder, &contours, &contour_inputs);
        self.compose.encode(&mut encoder, &output_view, &compose_inputs);
        self.gpu.queue.submit([encoder.finish()]);
        let image = readback::read_rgba8(&self.gpu, &output, width, height)?;
        let depth = if with_depth {
            let texels = readback::read_texels(&self.gpu, &gbuffer.linear_depth_texture, width, height, 8)?;
            texels.chunks_exact(8).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect()
        } else {
            Vec::new()
        };
        debug!(
            width,
            height,
            ms = started.elapsed().as_secs_f64() * 1e3,
            triangles = self.scene.triangles(),
            "frame rendered"
        );
        Ok(FrameWithDepth { image, depth })
    }
}
