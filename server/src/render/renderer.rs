//! The frame loop: one [`FrameRequest`] → the geometry pass into the G-buffer, then the
//! declared post passes ([`super::passes::POST_PASSES`]) over the named targets, then the
//! read-back of what the request asks for.

use super::art_textures::{ArtKind, ArtMap, ArtMapSet, ArtTextures};
use super::compare::{Compare, Split};
use super::creases::CreaseCounts;
use super::gbuffer::{GeometryFrame, GeometryPass, LayerStyle, layer_uniforms, render_target};
use super::layer_code::LayerCode;
use super::marks::{GlyphAtlas, Marks, Pin};
use super::parametrization::ReferenceCoords;
use super::passes::pipeline::FrameContext;
use super::passes::post_block::{PostStyle, Styles};
use super::passes::targets::{FrameTargets, OUTPUT_FORMAT};
use super::passes::{COPY, POST_PASSES, PostPass, Resource, Specialization, Target, When};
use super::profile::{PassTimes, Recorder};
use super::projection::{DataFrame, DataInputs, DataView, ProjectionPass};
use super::scene_gpu::{DrawStats, LayerDraw, SceneGpu};
use super::style::{FrameStyle, STYLE_SLOTS, Style, art_groups, style_slot};
use super::{Gpu, RenderError, readback, uniforms};
use crate::prep::cache::DiskCache;
use crate::prep::lod::LodSettings;
use crate::progress::{Progress, Silent};
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
    /// The passes of [`POST_PASSES`], in that order.
    passes: Vec<PostPass>,
    copy: PostPass,
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
    /// The scene's plan layer (`[about] plan_layer`): the layer the style's `focus` highlights.
    plan_layer: Option<String>,
    /// The digits of the pins' heads, and their texture.
    glyphs: GlyphAtlas,
    glyph_texture: wgpu::TextureView,
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

/// Options fixed for the lifetime of a [`Renderer`].
#[derive(Debug, Clone, Default)]
pub struct RenderOptions {
    /// When each plant level of detail is drawn.
    pub lod: LodSettings,
    /// Disk cache of preprocessing results (HLPs, baked billboards); `None` keeps them in the
    /// process only.
    pub cache: Option<Arc<DiskCache>>,
    /// Time the passes of every n-th frame (available from [`Renderer::take_pass_times`]); 0
    /// never does.
    pub profile_every: u32,
    /// Where building the renderer reports its preprocessing; `None`: nowhere.
    pub progress: Option<Arc<dyn Progress>>,
}

/// What a frame reads back besides its image.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Readback {
    /// The linear depth (metres, row-major), for motion-compensated comparisons of
    /// consecutive frames and for picking.
    pub depth: bool,
    /// Object IDs (row-major; see [`super::gbuffer::object_id`]): for picking the plant
    /// under a pointer, and for tests.
    pub ids: bool,
}

impl Readback {
    /// The depth as well as the image.
    pub const DEPTH: Readback = Readback { depth: true, ids: false };
    /// The object IDs as well as the image.
    pub const IDS: Readback = Readback { depth: false, ids: true };
}

/// Everything one frame depends on: the camera, the style of every layer, the size, the data
/// layers, the view's history and what to read back.
pub struct FrameRequest<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// A [`Style`] or a [`FrameStyle`] with styles per layer (thesis 8.2.8).
    pub style: FrameStyle,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Data layers projected onto the landscape (thesis 9.3); `None`: none.
    pub data: Option<&'a DataView>,
    /// The per-view state of an animated sequence: the hatching reference coordinates follow
    /// the camera from the last frame (thesis eq. 6.2). Without, every HLP's reference
    /// coordinates are zero, so the same request always gives the same image.
    pub history: Option<&'a mut ViewState>,
    /// What to read back besides the image.
    pub read: Readback,
    /// Time every pass ([`Frame::times`]): slower than a plain frame, because each pass waits
    /// for the previous one; for the benchmark.
    pub profile: bool,
    /// Comment pins drawn in the view (none: the marks pass does not run for them).
    pub pins: &'a [Pin],
    /// A before/after comparison: a layer hidden, in the whole view or left of a split.
    pub compare: Option<&'a Compare>,
}

impl<'a> FrameRequest<'a> {
    /// A frame of `camera` in `style` at `width` × `height`, without data layers or history,
    /// reading back the image only.
    pub fn new(camera: &'a Camera, style: impl Into<FrameStyle>, width: u32, height: u32) -> FrameRequest<'a> {
        FrameRequest {
            camera,
            style: style.into(),
            width,
            height,
            data: None,
            history: None,
            read: Readback::default(),
            profile: false,
            pins: &[],
            compare: None,
        }
    }

    /// With comment pins at their world points.
    pub fn pins(self, pins: &'a [Pin]) -> FrameRequest<'a> {
        FrameRequest { pins, ..self }
    }

    /// Comparing before and after: without `compare.layer`, or split at `compare.split`.
    pub fn compare(self, compare: &'a Compare) -> FrameRequest<'a> {
        FrameRequest { compare: Some(compare), ..self }
    }

    /// With the data layers of `data`.
    pub fn data(self, data: &'a DataView) -> FrameRequest<'a> {
        FrameRequest { data: Some(data), ..self }
    }

    /// As the next frame of the view `state`.
    pub fn history(self, state: &'a mut ViewState) -> FrameRequest<'a> {
        FrameRequest { history: Some(state), ..self }
    }

    /// Reading back `read` as well as the image.
    pub fn read(self, read: Readback) -> FrameRequest<'a> {
        FrameRequest { read, ..self }
    }

    /// Timing every pass.
    pub fn profiled(self) -> FrameRequest<'a> {
        FrameRequest { profile: true, ..self }
    }
}

/// A rendered frame and what its request read back.
pub struct Frame {
    /// The image.
    pub image: image::RgbaImage,
    /// Linear depth in metres, row-major, when [`Readback::depth`] was asked for.
    pub depth: Option<Vec<f32>>,
    /// Object IDs, row-major, when [`Readback::ids`] was asked for.
    pub ids: Option<Vec<u32>>,
    /// The G-buffer's second ID of every pixel, row-major, with the object IDs: the kind of
    /// surface (`gbuffer::Surface` code) in the top 8 bits and the patch below (an HLP index
    /// + 1, a substitution shape's, or a terrain pixel's land-cover class).
    pub patches: Option<Vec<u32>>,
    /// What the geometry pass drew (the seeds' Table 8.1 figures).
    pub stats: DrawStats,
    /// Per-pass times when the request was [`FrameRequest::profiled`].
    pub times: Option<PassTimes>,
}

/// What the frame's post passes are bound to, once its geometry is drawn.
struct PostFrame<'a> {
    targets: &'a FrameTargets,
    data: Option<&'a DataFrame>,
    /// Targets read in place of the outputs of passes that did not run
    /// ([`super::passes::PostPassDecl::bypass`]).
    bypass: Vec<(Target, Target)>,
    /// The marks pass's block, when the frame has pins or a split line.
    marks: Option<&'a wgpu::Buffer>,
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
        let progress: &dyn Progress = options.progress.as_deref().unwrap_or(&Silent);
        let scene_gpu = SceneGpu::new(&gpu, &geometry, scene, options.cache.as_deref(), progress)?;
        let glyphs = GlyphAtlas::digits();
        Ok(Renderer {
            glyph_texture: glyphs.upload(&gpu.device, &gpu.queue),
            glyphs,
            sun: scene.sun.direction(),
            layer_names: scene.layers.iter().map(|l| l.name.clone()).collect(),
            plan_layer: scene.about.plan_layer.clone(),
            passes: POST_PASSES.iter().map(|decl| PostPass::new(&gpu.device, decl)).collect(),
            copy: PostPass::new(&gpu.device, &COPY),
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

    /// What the geometry pass would draw for `request` (plants culled and drawn per level of
    /// detail, triangles submitted and the source geometry: the seeds' Table 8.1 figures),
    /// without drawing.
    pub fn draw_stats(&self, request: &FrameRequest<'_>) -> Result<DrawStats, RenderError> {
        let (slots, _) = self.frame_slots(request)?;
        let size = (request.width, request.height);
        let drawn_as = |id| LayerDraw::from(&slots[style_slot(id)]);
        Ok(self.scene.cull(request.camera, size, &self.lod, drawn_as, |_, _| [0.0; 2]).stats)
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
        styles.slots(&self.layer_names, self.plan_layer.as_deref())
    }

    /// The resolved style of every slot of `request` with its comparison applied, and where
    /// the compared layer starts (see [`Compare::apply`]).
    fn frame_slots(&self, request: &FrameRequest<'_>) -> Result<(Vec<Style>, Option<Split>), RenderError> {
        let mut slots = self.check(&request.style, request.width, request.height)?;
        let split = match request.compare {
            Some(compare) => Some(compare.apply(&mut slots, &self.layer_names, request.width)?),
            None => None,
        };
        Ok((slots, split))
    }

    /// Binds the frame uniforms of `camera` with the styles of `slots` (the compared layer
    /// starting at `split`) and the reference coordinates `references` (see
    /// [`SceneGpu::upload`]).
    fn frame_bind_group(
        &self,
        camera: &Camera,
        (slots, split): (&[Style], Option<Split>),
        width: u32,
        height: u32,
        references: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let device = &self.gpu.device;
        let frame_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("frame"),
            contents: &uniforms::bytes(&GeometryFrame::new(camera, width, height, self.art.directional_tams())),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let layer_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("layers"),
            contents: &layer_uniforms(slots, split),
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
                        size: wgpu::BufferSize::new(uniforms::size_of::<LayerStyle>()),
                    }),
                },
                wgpu::BindGroupEntry { binding: 3, resource: self.scene.cover_buffer().as_entire_binding() },
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

    /// Renders the frame `request` asks for (see [`FrameRequest`]).
    pub fn render(&self, mut request: FrameRequest<'_>) -> Result<Frame, RenderError> {
        let (slots, split) = self.frame_slots(&request)?;
        if let Some(data) = request.data {
            ProjectionPass::check(data)?;
        }
        self.scoped(|| {
            if request.profile {
                let mut times = PassTimes::new();
                let frame = self.render_frame(&mut request, (&slots, split), Some(&mut times))?;
                return Ok(Frame { times: Some(times), ..frame });
            }
            self.sampled(|times| self.render_frame(&mut request, (&slots, split), times))
        })
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
            size: uniforms::size_of::<Styles>(),
            usage: wgpu::BufferUsages::UNIFORM,
            mapped_at_creation: false,
        });
        let inputs = self.copy.bind_group(device, &uniform, &[wgpu::BindingResource::TextureView(&source)]);
        let context = FrameContext { device, spec: Specialization::default(), depth: None, marks: 0, creases: 0 };
        self.scoped(|| {
            (0..runs.max(1) + 1)
                .map(|_| {
                    let mut times = PassTimes::new();
                    let mut recorder = Recorder::new(&self.gpu, Some(&mut times));
                    self.copy.encode(recorder.encoder(), &target, &inputs, true, context);
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
        self.scene.gpu_bytes() + FrameTargets::bytes_per_pixel() * u64::from(width) * u64::from(height)
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

    /// A fresh per-view state for [`FrameRequest::history`].
    pub fn new_view_state(&self) -> ViewState {
        ViewState { references: ReferenceCoords::new() }
    }

    /// What a post pass binds for `reads` in `frame`, with the SAM of art-map group `sam`.
    fn resource<'r>(
        &'r self,
        frame: &PostFrame<'r>,
        reads: Resource,
        sam: usize,
    ) -> Result<wgpu::BindingResource<'r>, RenderError> {
        let view = wgpu::BindingResource::TextureView;
        Ok(match reads {
            Resource::Target(target) => {
                let read = frame.bypass.iter().find(|(output, _)| *output == target).map_or(target, |(_, to)| *to);
                view(frame.targets.view(read))
            }
            Resource::Tams => view(&self.art.all_tams),
            Resource::Sam => view(&self.art.sams[sam]),
            Resource::TamSampler => wgpu::BindingResource::Sampler(&self.art.tam_sampler),
            Resource::SamSampler => wgpu::BindingResource::Sampler(&self.art.sam_sampler),
            Resource::HatchColors => self.projection.hatch_colors().as_entire_binding(),
            Resource::Glyphs => view(&self.glyph_texture),
            Resource::CoverClasses => self.scene.cover_buffer().as_entire_binding(),
            Resource::CreaseLines => self.scene.crease_lines().buffer.as_entire_binding(),
            Resource::Marks => frame.marks.map(wgpu::Buffer::as_entire_binding).ok_or(RenderError::Gpu {
                stage: "frame",
                message: "the marks block is read while no marks are drawn".into(),
            })?,
            other => {
                frame.data.and_then(|data| self.projection.resource(data, other)).ok_or_else(|| RenderError::Gpu {
                    stage: "frame",
                    message: format!("{other:?} is read while no data layers are drawn"),
                })?
            }
        })
    }

    fn render_frame(
        &self,
        request: &mut FrameRequest<'_>,
        (slots, split): (&[Style], Option<Split>),
        times: Option<&mut PassTimes>,
    ) -> Result<Frame, RenderError> {
        let device = &self.gpu.device;
        let started = std::time::Instant::now();
        let (camera, width, height) = (request.camera, request.width, request.height);
        let no_data = DataView::default();
        let data = request.data.unwrap_or(&no_data);
        let mut cache = self.targets.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let targets = FrameTargets::get(&mut cache, device, width, height);

        // One post uniform block per silhouette-art-map group, each with the styles of all
        // slots; the compose pass runs once per group (thesis 8.2.8, see `art_groups`).
        let style = &slots[0];
        let (sams, slot_groups) = art_groups(slots);
        let params: [PostStyle; STYLE_SLOTS] = std::array::from_fn(|i| {
            let tam = &self.art.tams[slots[i].hatch_map];
            PostStyle::new(&slots[i], self.sun, camera.roll.to_radians(), tam.levels, tam.size, slot_groups[i])
        });
        let layer_tams = slots.iter().any(|s| s.hatch_map != style.hatch_map);
        let data_runs = ProjectionPass::writes(data, layer_tams);
        // The pins and the split line, over the composed image.
        let split_x = split.and_then(|s| s.x);
        // The terrain's crease lines, when its style draws them (the marks block carries the
        // camera for both passes).
        let terrain = &params[LayerCode::TERRAIN.slot()];
        let creases = match terrain.terrain_creases > 0.0 {
            true => self.scene.crease_lines().drawn(terrain.terrain_crease_area, terrain.terrain_break_angle),
            false => CreaseCounts::default(),
        };
        let marks = (!request.pins.is_empty() || split_x.is_some() || creases.instances() > 0).then(|| {
            let first_break = self.scene.crease_lines().first_break();
            Marks::new(camera, (width, height), request.pins, split_x, &self.glyphs).with_creases(creases, first_break)
        });
        // Pipelines specialised for what this frame's styles and data need.
        let context = FrameContext {
            device,
            spec: Specialization::for_frame(&params, data.has_hatch_colors(), data_runs, self.scene.has_land_cover()),
            depth: Some(&targets.gbuffer.depth),
            marks: marks.as_ref().map_or(0, |m| m.instances()),
            creases: creases.instances(),
        };
        let post_buffers: Vec<wgpu::Buffer> = (0..sams.len())
            .map(|group| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("styles"),
                    contents: &uniforms::bytes(&Styles::new(params, camera, width, height, group as u32)),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
            })
            .collect();

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
        let uvs = request.history.as_deref_mut().map(|state| {
            let eye = glam::Vec3::from(camera.position);
            let (center, parent) = (|k| self.scene.reference_center(k), |k| self.scene.reference_parent(k));
            state.references.update(visible.references(), center, parent, eye, slots[0].hatch_tiles)
        });
        let references = self.scene.upload(device, &self.gpu.queue, &visible, uvs.as_deref());
        let frame = self.frame_bind_group(camera, (slots, split), width, height, &references);
        recorder.mark("cull")?;
        self.geometry.encode(recorder.encoder(), &targets.gbuffer, &frame, &self.scene, &visible);
        recorder.mark("geometry")?;

        let inputs = DataInputs { camera, width, height, tams: self.art.tams.len(), layer_tams };
        let data_frame = if data_runs { self.projection.prepare(&self.gpu, &inputs, data)? } else { None };
        let marks = marks.map(|block| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("marks"),
                contents: &uniforms::bytes(block.as_ref()),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        });
        let mut post = PostFrame { targets, data: data_frame.as_ref(), bypass: Vec::new(), marks: marks.as_ref() };
        for pass in &self.passes {
            let decl = pass.decl();
            let runs = match decl.runs {
                When::Always => true,
                When::Prefilter => style.contour_prefilter,
                When::DataLayers => data_runs,
                When::Marks => context.marks > 0,
                When::Creases => context.creases > 0,
            };
            if !runs {
                post.bypass.extend(decl.bypass.map(|to| (decl.output, to)));
                continue;
            }
            let groups = if decl.per_art_group { sams.len() } else { 1 };
            for (group, buffer) in post_buffers.iter().enumerate().take(groups) {
                let resources = decl
                    .inputs
                    .iter()
                    .map(|binding| self.resource(&post, binding.reads, sams[group]))
                    .collect::<Result<Vec<_>, _>>()?;
                let bind_group = pass.bind_group(device, buffer, &resources);
                pass.encode(recorder.encoder(), targets.view(decl.output), &bind_group, group == 0, context);
            }
            recorder.mark(decl.name)?;
        }
        let mut timer = recorder.submit();
        let image = readback::read_rgba8(&self.gpu, &targets.output, width, height)?;
        timer.mark("readback");
        // The two 32-bit channels of every texel of a two-channel 32-bit target.
        let channels = |texture: &wgpu::Texture| -> Result<Vec<[[u8; 4]; 2]>, RenderError> {
            let texels = readback::read_texels(&self.gpu, texture, width, height, 8)?;
            Ok(texels.chunks_exact(8).map(|b| [[b[0], b[1], b[2], b[3]], [b[4], b[5], b[6], b[7]]]).collect())
        };
        let depth = match request.read.depth {
            true => Some(
                channels(&targets.gbuffer.linear_depth_texture)?
                    .into_iter()
                    .map(|[d, _]| f32::from_ne_bytes(d))
                    .collect(),
            ),
            false => None,
        };
        let (ids, patches) = match request.read.ids {
            true => {
                let texels = channels(&targets.gbuffer.id_texture)?;
                let ids = texels.iter().map(|[id, _]| u32::from_ne_bytes(*id)).collect();
                (Some(ids), Some(texels.iter().map(|[_, patch]| u32::from_ne_bytes(*patch)).collect()))
            }
            false => (None, None),
        };
        debug!(
            width,
            height,
            ms = started.elapsed().as_secs_f64() * 1e3,
            triangles = visible.stats.triangles,
            plants = visible.stats.plants_drawn,
            "frame rendered"
        );
        Ok(Frame { image, depth, ids, patches, stats: visible.stats, times: None })
    }
}
