//! D2–D5: data layers projected onto the rendered landscape (thesis 9.3, Fig. 9.2).
//!
//! A full-screen pass (`shaders/data.wgsl`) recovers each pixel's world position from the
//! linear depth (inverse projection, then inverse view), looks the fields up orthographically
//! along z, blends a series in time (eq. 9.4) and maps up to [`MAX_MAPPINGS`] fields onto
//! visual features (Table 9.1): colour, hatch tone, hatch colour (thesis 9.2.2, Fig. 9.3),
//! hatch pattern (one TAM per label), silhouette style (one SAM channel per label) and
//! silhouette density. It writes one [`DATA_FORMAT`] texel per pixel that the compose pass
//! reads (`shaders/data_common.wgsl`), and the ink and stroke direction of each hatch-colour
//! slot into a small uniform of the compose pass ([`ProjectionPass::hatch_colors`]).
//!
//! Each time step of a field is resampled onto a grid in scene metres
//! ([`Field::default_grid_spec`]) and uploaded once as an `R32Float` texture; later frames
//! reuse it, so moving the camera or the time between steps costs no upload. Scalars are
//! sampled bilinearly, labels at the nearest cell (with `textureLoad`).

use super::post::{FullscreenPass, Input, PostPass};
use super::{Gpu, RenderError};
use crate::fields::{Field, FieldGrid, FieldKind, Lut, MAX_MAPPINGS, Mapping, MappingTarget, SceneGeo};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use bytemuck::{Pod, Zeroable};
use chrono::{DateTime, Utc};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use wgpu::util::DeviceExt;

/// Format of the data target the compose pass reads (see `shaders/data.wgsl` for the layout).
pub const DATA_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
/// Grid value of cells without data in the field textures (NaN is not reliable in shaders).
const NODATA: f32 = -3.0e38;
/// Resampled time steps kept on the GPU; the cache is emptied when it grows beyond this.
const MAX_CACHED_STEPS: usize = 64;
/// Stroke direction of each hatch-colour slot: the rotation (degrees) of the hatch texture
/// coordinates. With the style's own hatching at 0°, the four directions lie 45° apart, so
/// each field's strokes stay apart from the others' and from the tone's (thesis Fig. 9.3).
pub const HATCH_COLOR_ANGLES: [f32; MAX_MAPPINGS] = [45.0, 90.0, 135.0];

/// A data layer to project: its field and a key naming this version of its data (the store's
/// id, creation time and step count), under which its GPU textures are cached.
#[derive(Debug)]
pub struct DataLayer {
    /// Cache key; a changed layer needs a new key.
    pub key: String,
    /// The field with every time step.
    pub field: Field,
}

/// One field mapped onto one visual feature.
#[derive(Debug, Clone)]
pub struct DataMapping {
    /// The layer.
    pub layer: Arc<DataLayer>,
    /// Target feature, range, colour map, opacity, direction.
    pub mapping: Mapping,
}

/// The data shown in one view: up to [`MAX_MAPPINGS`] mappings at time `time` (`None`: each
/// field's first step).
#[derive(Debug, Clone, Default)]
pub struct DataView {
    /// The mappings, in request order (colour tints multiply in this order).
    pub mappings: Vec<DataMapping>,
    /// Time of the view (D5).
    pub time: Option<DateTime<Utc>>,
}

impl DataView {
    /// Whether any mapping draws coloured hatchings (the compose pass compiles them only then).
    pub fn has_hatch_colors(&self) -> bool {
        self.mappings.iter().any(|m| m.mapping.target == MappingTarget::HatchColor)
    }
}

/// Code of a target in the shader (`Slot.params.x`); 0 for abstraction, which the geometry
/// stage draws (see [`ProjectionPass::plant_abstraction`]).
fn feature_code(target: MappingTarget) -> f32 {
    match target {
        MappingTarget::Abstraction => 0.0,
        MappingTarget::Color => 1.0,
        MappingTarget::HatchTone => 2.0,
        MappingTarget::HatchPattern => 3.0,
        MappingTarget::SilhouetteStyle => 4.0,
        MappingTarget::SilhouetteDensity => 5.0,
        MappingTarget::HatchColor => 6.0,
    }
}

/// Resampled steps kept on the CPU for the abstraction mapping.
const MAX_CACHED_GRIDS: usize = 8;

/// D3 abstraction: a field's value at the plants, for the geometry stage. Each plant takes
/// the value at its position (eq. 9.4 in time for scalars, the nearest step for labels),
/// normalized over the mapping's range like every other mapping (labels by class index), as
/// its HLP abstraction 1 − f (thesis eq. 4.8), weighted by the mapping's opacity against its
/// layer style's; plants without data keep the style's.
pub struct PlantAbstraction {
    lower: Arc<FieldGrid>,
    upper: Arc<FieldGrid>,
    /// u_t of eq. 9.4 (0 for labels).
    weight: f32,
    label: bool,
    /// Scalars: the values at the ends of the range; labels: 0 and the last class index.
    range: [f32; 2],
    reverse: bool,
    opacity: f32,
}

impl PlantAbstraction {
    /// The abstraction at scene position (x, y) and its weight (`[0, 0]` without data), as
    /// [`super::gbuffer::Instance::data_abstraction`] takes them.
    pub fn at(&self, x: f32, y: f32) -> [f32; 2] {
        let (x, y) = (f64::from(x), f64::from(y));
        let value = match self.lower.value_at(x, y) {
            Some(a) if self.label || self.weight <= 0.0 => Some(a),
            Some(a) => self.upper.value_at(x, y).map(|b| a + (b - a) * self.weight),
            None => None,
        };
        let Some(v) = value else {
            return [0.0, 0.0];
        };
        let [lo, hi] = self.range;
        let n = if hi > lo { ((v - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.0 };
        [if self.reverse { 1.0 - n } else { n }, self.opacity]
    }
}

/// `Slot` in `shaders/data.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
struct Slot {
    uv: [f32; 4],
    params: [f32; 4],
    range: [f32; 4],
}

/// `Data` in `shaders/data.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct DataUniform {
    inv_view_proj: [[f32; 4]; 4],
    depth_to_clip: [f32; 4],
    info: [f32; 4],
    slots: [Slot; MAX_MAPPINGS],
}

/// `HatchColor` in `shaders/data_common.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
struct HatchColorSlot {
    /// Ink (sRGB) and opacity; opacity 0 where the slot is no hatch colour.
    color: [f32; 4],
    /// cos and sin of the rotation of the hatch coordinates.
    rotation: [f32; 4],
}

/// `HatchColors` in `shaders/data_common.wgsl`: the compose pass's hatch-colour slots.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, Pod, Zeroable)]
struct HatchColorsUniform {
    slots: [HatchColorSlot; MAX_MAPPINGS],
}

impl HatchColorsUniform {
    /// The ink, opacity and stroke direction of every hatch-colour mapping of `data`, in its slot.
    fn new(data: &DataView) -> HatchColorsUniform {
        let mut uniform = HatchColorsUniform::default();
        for (i, (slot, m)) in uniform.slots.iter_mut().zip(&data.mappings).enumerate() {
            let (sin, cos) = HATCH_COLOR_ANGLES[i].to_radians().sin_cos();
            slot.rotation = [cos, sin, 0.0, 0.0];
            if m.mapping.target == MappingTarget::HatchColor {
                let [r, g, b] = m.mapping.hatch_color(i);
                slot.color = [r, g, b, m.mapping.opacity];
            }
        }
        uniform
    }
}

/// One resampled time step on the GPU.
struct StepTexture {
    view: wgpu::TextureView,
    /// Scene metres → texture coordinates ([`crate::fields::FieldGrid::uv_transform`]).
    uv: [f32; 4],
}

/// The projection pass, its cache of field textures and the scene's geography.
pub struct ProjectionPass {
    pass: FullscreenPass,
    scene: Result<SceneGeo, String>,
    steps: Mutex<HashMap<(String, usize), Arc<StepTexture>>>,
    grids: Mutex<HashMap<(String, usize), Arc<FieldGrid>>>,
    empty_grid: wgpu::TextureView,
    empty_lut: wgpu::TextureView,
    hatch_colors: wgpu::Buffer,
}

/// The pass's inputs for one frame.
pub struct DataInputs<'a> {
    /// The camera of the frame.
    pub camera: &'a Camera,
    /// Image size in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The style's TAM index (where no hatch-pattern mapping applies) and the number of TAMs.
    pub tams: (usize, usize),
    /// Whether style layers use TAMs other than `tams.0` (thesis 8.2.8): then the pass runs
    /// even without mappings, so every pixel gets the TAM of its layer's style.
    pub layer_tams: bool,
    /// The post uniform buffer (binding 0 of every post pass).
    pub post: &'a wgpu::Buffer,
    /// Linear depth of the G-buffer.
    pub depth: &'a wgpu::TextureView,
    /// Object IDs of the G-buffer.
    pub ids: &'a wgpu::TextureView,
}

fn texture_2d(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    (width, height): (u32, u32),
    bytes: &[u8],
) -> wgpu::TextureView {
    let texture = gpu.device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytes,
    );
    texture.create_view(&Default::default())
}

impl ProjectionPass {
    /// Compiles the pass for `scene` (whose DEM gives the geography fields are resampled to).
    pub fn new(gpu: &Gpu, scene: &Scene) -> ProjectionPass {
        use Input::*;
        let inputs = [Uniform, Float, Uint, Float, Float, Float, Float, Float, Float, Float, Float, Float];
        ProjectionPass {
            pass: FullscreenPass::new(
                &gpu.device,
                "data",
                include_str!("../../../shaders/data.wgsl"),
                "fs_data",
                &inputs,
                DATA_FORMAT,
            ),
            scene: SceneGeo::from_terrain(&scene.terrain).map_err(|e| e.to_string()),
            steps: Mutex::default(),
            grids: Mutex::default(),
            empty_grid: texture_2d(gpu, "no data", wgpu::TextureFormat::R32Float, (1, 1), &NODATA.to_le_bytes()),
            empty_lut: texture_2d(gpu, "no colours", wgpu::TextureFormat::Rgba8Unorm, (1, 1), &[0; 4]),
            hatch_colors: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hatch colours"),
                size: std::mem::size_of::<HatchColorsUniform>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// The compose pass's uniform of the hatch-colour slots (`HatchColors` in
    /// `shaders/data_common.wgsl`): ink, opacity and stroke direction per slot, written by
    /// [`ProjectionPass::encode`] for the frame it records (frames of a renderer are serialised).
    pub fn hatch_colors(&self) -> &wgpu::Buffer {
        &self.hatch_colors
    }

    /// Checks that `data` can be drawn: at most [`MAX_MAPPINGS`] mappings with valid colour
    /// maps.
    pub fn check(data: &DataView) -> Result<(), RenderError> {
        if data.mappings.len() > MAX_MAPPINGS {
            return Err(RenderError::Data(format!(
                "at most {MAX_MAPPINGS} fields can be mapped at once, {} given",
                data.mappings.len()
            )));
        }
        for (slot, m) in data.mappings.iter().enumerate() {
            Lut::for_field(&m.mapping.color_spec(slot), &m.layer.field)
                .map_err(|e| RenderError::Data(e.to_string()))?;
        }
        Ok(())
    }

    /// Step `step` of `layer` resampled onto its default grid in scene metres.
    fn resampled(&self, layer: &DataLayer, step: usize) -> Result<FieldGrid, RenderError> {
        let scene =
            self.scene.as_ref().map_err(|e| RenderError::Data(format!("the scene cannot place fields: {e}")))?;
        let field = &layer.field;
        field
            .default_grid_spec(scene)
            .and_then(|spec| field.resample(step, scene, &spec))
            .map_err(|e| RenderError::Data(e.to_string()))
    }

    /// Step `step` of `layer` resampled (for CPU lookups), cached on first use.
    fn grid(&self, layer: &DataLayer, step: usize) -> Result<Arc<FieldGrid>, RenderError> {
        let key = (layer.key.clone(), step);
        if let Some(grid) = self.grids.lock().unwrap_or_else(PoisonError::into_inner).get(&key) {
            return Ok(grid.clone());
        }
        let grid = Arc::new(self.resampled(layer, step)?);
        let mut grids = self.grids.lock().unwrap_or_else(PoisonError::into_inner);
        if grids.len() >= MAX_CACHED_GRIDS {
            grids.clear();
        }
        grids.insert(key, grid.clone());
        Ok(grid)
    }

    /// The abstraction mapping of `data`, if it has one, ready to be looked up per plant.
    pub fn plant_abstraction(&self, data: &DataView) -> Result<Option<PlantAbstraction>, RenderError> {
        let Some((slot, m)) =
            data.mappings.iter().enumerate().find(|(_, m)| m.mapping.target == MappingTarget::Abstraction)
        else {
            return Ok(None);
        };
        let field = &m.layer.field;
        let sample = field.time_sample(data.time);
        let label = field.kind() == FieldKind::Label;
        let range = if label {
            [0.0, field.classes().len().saturating_sub(1).max(1) as f32]
        } else {
            let lut =
                Lut::for_field(&m.mapping.color_spec(slot), field).map_err(|e| RenderError::Data(e.to_string()))?;
            let [lo, hi] = lut.range.unwrap_or([0.0, 1.0]);
            [lo as f32, hi as f32]
        };
        Ok(Some(PlantAbstraction {
            lower: self.grid(&m.layer, sample.lower)?,
            upper: self.grid(&m.layer, sample.upper)?,
            weight: if label { 0.0 } else { sample.weight as f32 },
            label,
            range,
            reverse: m.mapping.reverse,
            opacity: m.mapping.opacity,
        }))
    }

    /// Step `step` of `layer` as a texture, resampled and uploaded on first use.
    fn step_texture(&self, gpu: &Gpu, layer: &DataLayer, step: usize) -> Result<Arc<StepTexture>, RenderError> {
        let key = (layer.key.clone(), step);
        if let Some(texture) = self.steps.lock().unwrap_or_else(PoisonError::into_inner).get(&key) {
            return Ok(texture.clone());
        }
        let grid = self.resampled(layer, step)?;
        let bytes: Vec<u8> =
            grid.values.iter().flat_map(|v| if v.is_nan() { NODATA } else { *v }.to_le_bytes()).collect();
        let size = (grid.spec.width as u32, grid.spec.height as u32);
        let view = texture_2d(gpu, "field step", wgpu::TextureFormat::R32Float, size, &bytes);
        let texture = Arc::new(StepTexture { view, uv: grid.uv_transform() });
        let mut steps = self.steps.lock().unwrap_or_else(PoisonError::into_inner);
        if steps.len() >= MAX_CACHED_STEPS {
            steps.clear();
        }
        steps.insert(key, texture.clone());
        Ok(texture)
    }

    /// Whether the pass writes anything for `data` in a frame whose style layers do or do not
    /// use TAMs of their own (`layer_tams`); when it does not, the compose pass reads no data
    /// layers (`Specialization::data_layers`).
    pub fn writes(data: &DataView, layer_tams: bool) -> bool {
        !data.mappings.is_empty() || layer_tams
    }

    /// Records the pass into `encoder`, writing `target` with the projected `data` and the
    /// hatch-colour slots of `data` into [`ProjectionPass::hatch_colors`]; records nothing when
    /// it [`writes`](ProjectionPass::writes) nothing.
    pub fn encode(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        inputs: &DataInputs<'_>,
        data: &DataView,
    ) -> Result<(), RenderError> {
        if !Self::writes(data, inputs.layer_tams) {
            return Ok(());
        }
        Self::check(data)?;
        gpu.queue.write_buffer(&self.hatch_colors, 0, bytemuck::bytes_of(&HatchColorsUniform::new(data)));
        let mut slots = [Slot::default(); MAX_MAPPINGS];
        let mut textures = Vec::new();
        for (i, (slot, m)) in slots.iter_mut().zip(&data.mappings).enumerate() {
            let field = &m.layer.field;
            let sample = field.time_sample(data.time);
            let lower = self.step_texture(gpu, &m.layer, sample.lower)?;
            let upper = self.step_texture(gpu, &m.layer, sample.upper)?;
            let lut = Lut::for_field(&m.mapping.color_spec(i), field).map_err(|e| RenderError::Data(e.to_string()))?;
            let [lo, hi] = lut.range.unwrap_or([0.0, 1.0]);
            let label = field.kind() == FieldKind::Label;
            *slot = Slot {
                uv: lower.uv,
                params: [
                    feature_code(m.mapping.target),
                    f32::from(u8::from(label)),
                    sample.weight as f32,
                    m.mapping.opacity,
                ],
                range: [lo as f32, hi as f32, field.classes().len() as f32, f32::from(u8::from(m.mapping.reverse))],
            };
            let lut_view = texture_2d(
                gpu,
                "colour table",
                wgpu::TextureFormat::Rgba8Unorm,
                (lut.colors.len() as u32, 1),
                &lut.to_rgba_bytes(),
            );
            textures.push((lower, upper, lut_view));
        }
        let projection = inputs.camera.projection(inputs.width as f32 / inputs.height as f32);
        let (z, w) = (projection.z_axis, projection.w_axis);
        let uniform = DataUniform {
            inv_view_proj: (projection * inputs.camera.view()).inverse().to_cols_array_2d(),
            depth_to_clip: [-z.z, w.z, -z.w, w.w],
            info: [inputs.width as f32, inputs.height as f32, inputs.tams.0 as f32, inputs.tams.1 as f32],
            slots,
        };
        let buffer = gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("data"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = wgpu::BindingResource::TextureView;
        let mut resources = vec![buffer.as_entire_binding(), view(inputs.depth), view(inputs.ids)];
        for i in 0..MAX_MAPPINGS {
            match textures.get(i) {
                Some((lower, upper, lut)) => resources.extend([view(&lower.view), view(&upper.view), view(lut)]),
                None => resources.extend([view(&self.empty_grid), view(&self.empty_grid), view(&self.empty_lut)]),
            }
        }
        let bind_group = self.pass.bind_group(&gpu.device, inputs.post, &resources);
        self.pass.encode(encoder, target, &bind_group, super::post::FrameContext::plain(&gpu.device));
        Ok(())
    }
}
