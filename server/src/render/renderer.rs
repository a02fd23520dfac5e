//! The frame loop: G-buffer pass, contour pass, compose pass, read-back.

use super::gbuffer::{FrameUniform, GBuffer, GeometryPass, render_target};
use super::post::{self, CONTOUR_FORMAT, FullscreenPass, OUTPUT_FORMAT};
use super::scene_gpu::SceneGpu;
use super::style::{PostParams, Style};
use super::{Gpu, RenderError, readback};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use std::sync::Arc;
use tracing::debug;
use wgpu::util::DeviceExt;

/// Renders one scene from any camera in any [`Style`]. GPU resources of the scene are built
/// once in [`Renderer::new`]; each [`Renderer::render`] call only records and submits passes.
pub struct Renderer {
    gpu: Arc<Gpu>,
    geometry: GeometryPass,
    contour: FullscreenPass,
    compose: FullscreenPass,
    scene: SceneGpu,
    sun: glam::Vec3,
}

impl Renderer {
    /// Compiles the pipelines and uploads `scene` to the GPU.
    pub fn new(gpu: Arc<Gpu>, scene: &Scene) -> Renderer {
        let geometry = GeometryPass::new(&gpu.device);
        let contour = post::contour(&gpu.device);
        let compose = post::compose(&gpu.device);
        let scene_gpu = SceneGpu::new(&gpu.device, &gpu.queue, &geometry, scene);
        Renderer { sun: scene.sun.direction(), gpu, geometry, contour, compose, scene: scene_gpu }
    }

    /// Triangles the geometry pass submits per frame.
    pub fn triangles_per_frame(&self) -> u64 {
        self.scene.triangles()
    }

    fn check_size(&self, width: u32, height: u32) -> Result<(), RenderError> {
        let max = self.gpu.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Size { width, height, max });
        }
        Ok(())
    }

    /// Binds the frame uniforms of `camera` for an image of `width` × `height`.
    fn frame_bind_group(&self, camera: &Camera, width: u32, height: u32) -> wgpu::BindGroup {
        let device = &self.gpu.device;
        let frame_uniform = FrameUniform::new(camera, width as f32 / height as f32);
        let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: bytemuck::bytes_of(&frame_uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &self.geometry.frame_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() }],
        })
    }

    /// Runs `work` inside a validation error scope, turning wgpu errors into [`RenderError`].
    fn scoped<T>(&self, work: impl FnOnce() -> Result<T, RenderError>) -> Result<T, RenderError> {
        let scope = self.gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let result = work();
        match pollster::block_on(scope.pop()) {
            Some(error) => Err(RenderError::Gpu { stage: "frame", message: error.to_string() }),
            None => result,
        }
    }

    /// The object/patch ID of every pixel (row-major; see [`super::gbuffer::object_id`]), from the
    /// G-buffer pass alone: for picking the plant under a pointer, and for tests.
    pub fn object_ids(&self, camera: &Camera, width: u32, height: u32) -> Result<Vec<u32>, RenderError> {
        self.check_size(width, height)?;
        self.scoped(|| {
            let device = &self.gpu.device;
            let gbuffer = GBuffer::new(device, width, height);
            let frame = self.frame_bind_group(camera, width, height);
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ids") });
            self.geometry.encode(&mut encoder, &gbuffer, &frame, &self.scene);
            self.gpu.queue.submit([encoder.finish()]);
            readback::read_u32(&self.gpu, &gbuffer.id_texture, width, height)
        })
    }

    /// Renders a `width` × `height` pen-and-ink image of the scene seen from `camera`.
    pub fn render(
        &self,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
    ) -> Result<image::RgbaImage, RenderError> {
        self.check_size(width, height)?;
        style.validate()?;
        self.scoped(|| self.render_frame(camera, style, width, height))
    }

    fn render_frame(
        &self,
        camera: &Camera,
        style: &Style,
        width: u32,
        height: u32,
    ) -> Result<image::RgbaImage, RenderError> {
        let device = &self.gpu.device;
        let started = std::time::Instant::now();
        let gbuffer = GBuffer::new(device, width, height);
        let contours =
            render_target(device, "contours", CONTOUR_FORMAT, width, height).create_view(&Default::default());
        let output = render_target(device, "output", OUTPUT_FORMAT, width, height);
        let output_view = output.create_view(&Default::default());

        let frame = self.frame_bind_group(camera, width, height);
        let post_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("post"),
            contents: bytemuck::bytes_of(&PostParams::new(style, self.sun)),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let contour_inputs = self.contour.bind_group(device, &post_buffer, &[&gbuffer.linear_depth]);
        let compose_inputs = self.compose.bind_group(
            device,
            &post_buffer,
            &[&gbuffer.linear_depth, &contours, &gbuffer.albedo, &gbuffer.normal],
        );

        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        self.geometry.encode(&mut encoder, &gbuffer, &frame, &self.scene);
        self.contour.encode(&mut encoder, &contours, &contour_inputs);
        self.compose.encode(&mut encoder, &output_view, &compose_inputs);
        self.gpu.queue.submit([encoder.finish()]);
        let image = readback::read_rgba8(&self.gpu, &output, width, height)?;
        debug!(
            width,
            height,
            ms = started.elapsed().as_secs_f64() * 1e3,
            triangles = self.scene.triangles(),
            "frame rendered"
        );
        Ok(image)
    }
}
