//! The frame loop: G-buffer pass, depth pre-filter, contour + tone pass, compose pass,
//! read-back.

use super::art_textures::{ArtKind, ArtMap, ArtMapSet, ArtTextures};
use super::gbuffer::{FrameUniform, GBuffer, GeometryPass, LayerUniform, layer_uniforms, render_target};
use super::parametrization::ReferenceCoords;
use super::post::{
    self, CONTOUR_FORMAT, ComposePass, FrameContext, FullscreenPass, OUTPUT_FORMAT, PREFILTER_FORMAT, PostPass,
    Specialization, TONE_FORMAT,
};
use super::profile::{PassTimes, Recorder};
use super::projection::{DATA_FORMAT, DataInputs, DataView, ProjectionPass};
use super::scene_gpu::{DrawStats, LayerDraw, SceneGpu};
use super::style::{FrameStyle, PostParams, PostUniform, STYLE_SLOTS, Style, art_groups, style_slot};
use super::{Gpu, RenderError, readback};
use crate::prep::cache::DiskCache;
use crate::prep::lod::LodSettings;
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
    tone_blur: FullscreenPass,
    compose: ComposePass,
    copy: FullscreenPass,
    projection: ProjectionPass,
    scene: SceneGpu,
    lod: LodSettings,
    profile_every: u32,
    frames: std::sync::atomic::AtomicU32,
    pass_times: std::sync::Mutex<Option<PassTimes>>,
    /// Render targets of recent frame sizes; the lock also serialises frames of one renderer.
    targets: std::sync::Mutex<Vec<FrameTargets>>,
    art: ArtTextures,
    sun: glam::Vec3,
    /// Names of the scene's vegetation layers, in layer-code order (per-layer styles).
    layer_names: Vec<String>,
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
}

/// The render targets of one frame size, kept for the next frames of that size: allocating
/// (and on a CPU adapter, page-faulting) ~60 MB of targets per 1024×768 frame costs time.
struct FrameTargets {
    width: u32,
    height: u32,
    gbuffer: GBuffer,
    prefiltered: wgpu::TextureView,
    contours: wgpu::TextureView,
    /// The horizontally blurred tone.
    tone: wgpu::TextureView,
    data_layers: wgpu::TextureView,
    output: wgpu::Texture,
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
    fn get<'a>(cache: &'a mut Vec<FrameTargets>, device: &wgpu::Device, width: u32, height: u32) -> &'a FrameTargets {
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
}

/// Options fixed for the lifetime of a [`Renderer`].
#[derive(Debug, Clone, Default)]
pub struct RenderOptions {
    /// When each plant level of detail is drawn.
    pub lod: LodSettings,
    /// Disk cache of preprocessing results (HLPs, baked billboards); `None` keeps them in the
    /// process only.
    pub cache: Option<Arc<DiskCache>>,
    /// Time the passes of every n-th frame of `render`/`render_with_data`/`render_view`
    /// (available from [`Renderer::take_pass_times`]); 0 never does.
    pub profile_every: u32,
}

/// A rendered frame with its linear depth (metres, row-major), for motion-compensated
/// comparisons of consecutive frames.
pub struct FrameWithDepth {
    pub image: image::RgbaImage,
    pub depth: Vec<f32>,
}

impl Renderer {
    /// Compiles the pipelines, generates the default art maps and uploads `scene` to the GPU
    /// with the default [`RenderOptions`] (no disk cache).
    pub fn new(gpu: Arc<Gpu>, scene: &Scene) -> Result<Renderer, RenderError> {
        Renderer::with_options(gpu, scene, &RenderOptions::default())
    }

    /// [`Renderer::new`] with explicit options: levels of detail and the preprocessing cache.
    pub fn with_options(gpu: Arc<Gpu>, scene: &Scene, options: &RenderOptions) -> Result<Renderer, RenderError> {
        options.lod.validate().map_err(RenderError::Options)?;
        let geometry = GeometryPass::new(&gpu.device);
        let scene_gpu = SceneGpu::new(&gpu, &geometry, scene, options.cache.as_deref())?;
        Ok(Renderer {
            sun: scene.sun.direction(),
            layer_names: scene.layers.iter().map(|l| l.name.clone()).collect(),
            prefilter: post::prefilter(&gpu.device),
            contour: post::contour(&gpu.device),
            tone_blur: post::tone_blur(&gpu.device),
            compose: ComposePass::new(&gpu.device),
            copy: post::copy(&gpu.device),
            projection: ProjectionPass::new(&gpu, scene),
            art: ArtTextures::defaults(&gpu.device, &gpu.queue),
            gpu,
            geometry,
            scene: scene_gpu,
            lod: options.lod,
            profile_every: options.profile_every,
            frames: Default::default(),
            pass_times: Default::default(),
            targets: Default::default(),
        })
    }

    /// What the geometry pass would draw for `camera`: plants culled and drawn per level of
    /// detail, triangles submitted and the source geometry (the seeds' Table 8.1 figures).
    pub fn draw_stats(&self, camera: &Camera, width: u32, height: u32) -> DrawStats {
        self.draw_stats_with_style(camera, &Style::default(), width, height)
    }

    /// [`Renderer::draw_stats`] with every layer in `style` (hidden layers, leaf particles).
    pub fn draw_stats_with_style(&self, camera: &Camera, style: &Style, width: u32, height: u32) -> DrawStats {
        let drawn_as = LayerDraw::from(&style.resolved());
        self.scene.cull(camera, (width, height), &self.lod, |_| drawn_as, |_, _| [0.0; 2]).stats
    }

    /// Number of tonal art maps (`Style::hatch_map` indexes them) and silhouette art maps
    /// (`Style::silhouette_map`).
    pub fn art_map_counts(&self) -> (usize, usize) {
        (self.art.tams.len(), self.art.sams.len())
    }

    /// The art maps in index order (CPU copies of what the passes sample).
    pub fn art_maps(&self) -> &ArtMapSet {
        &self.art.maps
    }

    /// Replaces art map `index` of the map's kind, or adds one when `index` is the count
    /// (thesis 8.2.5: art maps painted at run time); the next frame draws with it. A TAM must
    /// have the shape of the others (see [`ArtTextures::set`]); nothing changes when refused.
    pub fn set_art_map(&mut self, index: usize, map: ArtMap) -> Result<(), RenderError> {
        self.art.set(&self.gpu.device, &self.gpu.queue, index, map)
    }

    /// Removes the last art map of `kind` (`index` must name it; at least one stays).
    pub fn remove_art_map(&mut self, kind: ArtKind, index: usize) -> Result<(), RenderError> {
        self.art.remove(&self.gpu.device, &self.gpu.queue, kind, index)
    }

    /// Checks the size and every style of the frame; returns the resolved style of every slot.
    fn check(&self, styles: &FrameStyle, width: u32, height: u32) -> Result<Vec<Style>, RenderError> {
        let max = self.gpu.device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Size { width, height, max });
        }
        let (tams, sams) = self.art_map_counts();
        for style in styles.styles() {
            style.validate()?;
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
        }
        styles.slots(&self.layer_names)
    }

    /// Binds the frame uniforms of `camera` with the styles of `slots` and the reference
    /// coordinates `references` (see [`SceneGpu::upload`]).
    fn frame_bind_group(
        &self,
        camera: &Camera,
        slots: &[Style],
        width: u32,
        height: u32,
        references: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let device = &self.gpu.device;
        let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: bytemuck::bytes_of(&FrameUniform::new(camera, width, height)),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let layer_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("layers"),
            contents: &layer_uniforms(slots),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &self.geometry.frame_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: references.as_entire_binding() },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &layer_buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<LayerUniform>() as u64),
                    }),
                },
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
        self.object_ids_with_style(camera, FrameStyle::default(), width, height)
    }

    /// [`Renderer::object_ids`] of the scene drawn in `style` (leaf modes, HLP abstraction).
    pub fn object_ids_with_style(
        &self,
        camera: &Camera,
        style: impl Into<FrameStyle>,
        width: u32,
        height: u32,
    ) -> Result<Vec<u32>, RenderError> {
        let slots = self.check(&style.into(), width, height)?;
        self.scoped(|| {
            let device = &self.gpu.device;
            let gbuffer = GBuffer::new(device, width, height);
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("ids") });
            // The instance buffer is shared: one frame at a time.
            let _frame = self.targets.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            let layer = |id| LayerDraw::from(&slots[style_slot(id)]);
            let visible = self.scene.cull(camera, (width, height), &self.lod, layer, |_, _| [0.0; 2]);
            let references = self.scene.upload(device, &self.gpu.queue, &visible, None);
            let frame = self.frame_bind_group(camera, &slots, width, height, &references);
            self.geometry.encode(&mut encoder, &gbuffer, &frame, &self.scene, &visible);
            self.gpu.queue.submit([encoder.finish()]);
            let texels = readback::read_texels(&self.gpu, &gbuffer.id_texture, width, height, 8)?;
            Ok(texels.chunks_exact(8).map(|b| u32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect())
        })
    }

    /// Renders a `width` × `height` image of the scene seen from `camera` in `style`: a
    /// [`Style`] (`&style`) or a [`FrameStyle`] with styles per layer (thesis 8.2.8). Without
    /// history, every HLP's reference texture coordinates are zero, so the same request always
    /// gives the same image.
    pub fn render(
        &self,
        camera: &Camera,
        style: impl Into<FrameStyle>,
        width: u32,
        height: u32,
    ) -> Result<image::RgbaImage, RenderError> {
        self.render_with_data(camera, style, width, height, &DataView::default())
    }

    /// [`Renderer::render`] with data layers projected onto the landscape (thesis 9.3).
    pub fn render_with_data(
        &self,
        camera: &Camera,
        style: impl Into<FrameStyle>,
        width: u32,
        height: u32,
        data: &DataView,
    ) -> Result<image::RgbaImage, RenderError> {
        let slots = self.check(&style.into(), width, height)?;
        ProjectionPass::check(data)?;
        self.scoped(|| {
            self.sampled(|times| Ok(self.render_frame(camera, &slots, width, height, None, data, false, times)?.image))
        })
    }

    /// [`Renderer::render`] (or, with `state`, [`Renderer::render_view`]) timing every pass
    /// (see [`super::profile`]): slower than a plain frame, because each pass waits for the
    /// previous one; for the benchmark.
    pub fn render_profiled(
        &self,
        state: Option<&mut ViewState>,
        camera: &Camera,
        style: impl Into<FrameStyle>,
        width: u32,
        height: u32,
    ) -> Result<(image::RgbaImage, PassTimes), RenderError> {
        let slots = self.check(&style.into(), width, height)?;
        let mut times = PassTimes::new();
        let data = DataView::default();
        let history = state.map(|s| &mut s.references);
        let frame =
            self.scoped(|| self.render_frame(camera, &slots, width, height, history, &data, false, Some(&mut times)))?;
        Ok((frame.image, times))
    }

    /// Wall times (ms) of `runs` plain full-screen copy passes at `width` × `height`: the floor
    /// any post-processing pass costs on this adapter.
    pub fn time_copy_pass(&self, width: u32, height: u32, runs: usize) -> Result<Vec<f64>, RenderError> {
        self.check(&FrameStyle::from(&Style::default()), width, height)?;
        let device = &self.gpu.device;
        let source =
            render_target(device, "copy source", OUTPUT_FORMAT, width, height).create_view(&Default::default());
        let target =
            render_target(device, "copy target", OUTPUT_FORMAT, width, height).create_view(&Default::default());
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("copy uniform"),
            size: std::mem::size_of::<PostUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM,
            mapped_at_creation: false,
        });
        let inputs = self.copy.bind_group(device, &uniform, &[wgpu::BindingResource::TextureView(&source)]);
        self.scoped(|| {
            (0..runs.max(1) + 1)
                .map(|_| {
                    let mut times = PassTimes::new();
                    let mut recorder = Recorder::new(&self.gpu, Some(&mut times));
                    self.copy.encode(recorder.encoder(), &target, &inputs, FrameContext::plain(device));
                    recorder.mark("copy")?;
                    recorder.submit();
                    Ok(times[0].1)
                })
                .skip(1)
                .collect()
        })
    }

    /// Estimated GPU memory in bytes: the scene's buffers and textures plus the render targets
    /// of one `width` × `height` frame.
    pub fn gpu_bytes(&self, width: u32, height: u32) -> u64 {
        let formats = [
            super::gbuffer::ALBEDO_FORMAT,
            super::gbuffer::NORMAL_FORMAT,
            super::gbuffer::LINEAR_DEPTH_FORMAT,
            super::gbuffer::ID_FORMAT,
            super::gbuffer::HATCH_FORMAT,
            super::gbuffer::DEPTH_FORMAT,
            PREFILTER_FORMAT,
            CONTOUR_FORMAT,
            TONE_FORMAT,
            DATA_FORMAT,
            OUTPUT_FORMAT,
        ];
        let per_pixel: u64 = formats.iter().map(|f| u64::from(f.target_pixel_byte_cost().unwrap_or(4))).sum();
        self.scene.gpu_bytes() + per_pixel * u64::from(width) * u64::from(height)
    }

    /// Runs `frame`, with pass timing when it is one of the sampled frames
    /// ([`RenderOptions::profile_every`]); the times wait in [`Renderer::take_pass_times`].
    fn sampled<T>(
        &self,
        frame: impl FnOnce(Option<&mut PassTimes>) -> Result<T, RenderError>,
    ) -> Result<T, RenderError> {
        let every = self.profile_every;
        if every == 0 || !self.frames.fetch_add(1, std::sync::atomic::Ordering::Relaxed).is_multiple_of(every) {
            return frame(None);
        }
        let mut times = PassTimes::new();
        let result = frame(Some(&mut times));
        if result.is_ok() {
            *self.pass_times.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(times);
        }
        result
    }

    /// The pass times of the last sampled frame, if one was rendered since the last call.
    pub fn take_pass_times(&self) -> Option<PassTimes> {
        self.pass_times.lock().unwrap_or_else(std::sync::PoisonError::into_inner).take()
    }

    /// A fresh per-view state for [`Renderer::render_view`].
    pub fn new_view_state(&self) -> ViewState {
        ViewState { references: ReferenceCoords::new() }
    }

    /// Renders the next frame of an animated view: first moves the hatching reference
    /// coordinates with the camera (thesis eq. 6.2), then renders with them and the data
    /// layers of `data`. Returns the depth too when `with_depth` is set.
    #[allow(clippy::too_many_arguments)]
    pub fn render_view(
        &self,
        state: &mut ViewState,
        camera: &Camera,
        style: impl Into<FrameStyle>,
        width: u32,
        height: u32,
        data: &DataView,
        with_depth: bool,
    ) -> Result<FrameWithDepth, RenderError> {
        let slots = self.check(&style.into(), width, height)?;
        ProjectionPass::check(data)?;
        self.scoped(|| {
            self.sampled(|times| {
                self.render_frame(camera, &slots, width, height, Some(&mut state.references), data, with_depth, times)
            })
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn render_frame(
        &self,
        camera: &Camera,
        slots: &[Style],
        width: u32,
        height: u32,
        history: Option<&mut ReferenceCoords>,
        data: &DataView,
        with_depth: bool,
        times: Option<&mut PassTimes>,
    ) -> Result<FrameWithDepth, RenderError> {
        let device = &self.gpu.device;
        let started = std::time::Instant::now();
        let mut cache = self.targets.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let targets = FrameTargets::get(&mut cache, device, width, height);
        let FrameTargets { gbuffer, prefiltered, contours, tone, data_layers, output, output_view, .. } = targets;

        // One post uniform block per silhouette-art-map group, each with the styles of all
        // slots; the compose pass runs once per group (thesis 8.2.8, see `art_groups`).
        let style = &slots[0];
        let (sams, slot_groups) = art_groups(slots);
        let params: [PostParams; STYLE_SLOTS] = std::array::from_fn(|i| {
            let tam = &self.art.tams[slots[i].hatch_map];
            PostParams::new(&slots[i], self.sun, camera.roll.to_radians(), tam.levels, tam.size, slot_groups[i])
        });
        let layer_tams = slots.iter().any(|s| s.hatch_map != style.hatch_map);
        // Pipelines specialised for what this frame's styles and data need.
        let context = FrameContext {
            device,
            spec: Specialization::for_frame(&params, data.has_hatch_colors(), ProjectionPass::writes(data, layer_tams)),
            depth: Some(&gbuffer.depth),
        };
        let post_buffers: Vec<wgpu::Buffer> = (0..sams.len())
            .map(|group| {
                let uniform = PostUniform::new(params, camera, width, height, group as u32);
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("post"),
                    contents: bytemuck::bytes_of(&uniform),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
            })
            .collect();
        let post_buffer = &post_buffers[0];
        let view = wgpu::BindingResource::TextureView;
        let depth_for_contours = if style.contour_prefilter { prefiltered } else { &gbuffer.linear_depth };
        let prefilter_inputs = self.prefilter.bind_group(device, post_buffer, &[view(&gbuffer.linear_depth)]);
        let contour_inputs = self.contour.bind_group(
            device,
            post_buffer,
            &[view(depth_for_contours), view(&gbuffer.albedo), view(&gbuffer.normal), view(&gbuffer.id)],
        );
        let tone_inputs = self.tone_blur.bind_group(device, post_buffer, &[view(contours), view(&gbuffer.id)]);
        let compose_inputs: Vec<wgpu::BindGroup> = sams
            .iter()
            .zip(&post_buffers)
            .map(|(&sam, buffer)| {
                self.compose.bind_group(
                    device,
                    buffer,
                    &[
                        view(contours),
                        view(&gbuffer.linear_depth),
                        view(&gbuffer.id),
                        view(&gbuffer.hatch),
                        view(&gbuffer.normal),
                        view(&gbuffer.albedo),
                        view(&self.art.all_tams),
                        view(&self.art.sams[sam]),
                        wgpu::BindingResource::Sampler(&self.art.tam_sampler),
                        wgpu::BindingResource::Sampler(&self.art.sam_sampler),
                        view(data_layers),
                        self.projection.hatch_colors().as_entire_binding(),
                        view(tone),
                    ],
                )
            })
            .collect();
        let data_inputs = DataInputs {
            camera,
            width,
            height,
            tams: (style.hatch_map, self.art.tams.len()),
            layer_tams,
            post: post_buffer,
            depth: &gbuffer.linear_depth,
            ids: &gbuffer.id,
        };

        let mut recorder = Recorder::new(&self.gpu, times);
        // D3 abstraction is drawn here, in the geometry stage: per plant, from the field at its
        // position.
        let abstraction = self.projection.plant_abstraction(data)?;
        let visible = self.scene.cull(
            camera,
            (width, height),
            &self.lod,
            |id| LayerDraw::from(&slots[style_slot(id)]),
            |x, y| abstraction.as_ref().map_or([0.0; 2], |a| a.at(x, y)),
        );
        // The reference coordinates follow the camera (eq. 6.2) in the base style's tiles
        // (layers share them); a frame without history has them all at zero.
        let uvs = history.map(|state| {
            let eye = glam::Vec3::from(camera.position);
            let (center, parent) = (|k| self.scene.reference_center(k), |k| self.scene.reference_parent(k));
            state.update(visible.references(), center, parent, eye, slots[0].hatch_tiles)
        });
        let references = self.scene.upload(device, &self.gpu.queue, &visible, uvs.as_deref());
        let frame = self.frame_bind_group(camera, slots, width, height, &references);
        recorder.mark("cull")?;
        self.geometry.encode(recorder.encoder(), gbuffer, &frame, &self.scene, &visible);
        recorder.mark("geometry")?;
        if style.contour_prefilter {
            self.prefilter.encode(recorder.encoder(), prefiltered, &prefilter_inputs, context);
            recorder.mark("prefilter")?;
        }
        self.contour.encode(recorder.encoder(), contours, &contour_inputs, context);
        recorder.mark("contour")?;
        self.tone_blur.encode(recorder.encoder(), tone, &tone_inputs, context);
        recorder.mark("tone_blur")?;
        self.projection.encode(&self.gpu, recorder.encoder(), data_layers, &data_inputs, data)?;
        recorder.mark("data")?;
        for (group, inputs) in compose_inputs.iter().enumerate() {
            self.compose.encode(recorder.encoder(), output_view, inputs, group == 0, context);
        }
        recorder.mark("compose")?;
        let mut timer = recorder.submit();
        let image = readback::read_rgba8(&self.gpu, output, width, height)?;
        timer.mark("readback");
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
            triangles = visible.stats.triangles,
            plants = visible.stats.plants_drawn,
            "frame rendered"
        );
        Ok(FrameWithDepth { image, depth })
    }
}
