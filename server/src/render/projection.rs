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

use super::passes::Resource;
use super::uniforms::{self, Mat4f, Vec2f, Vec3f, Vec4f, gpu_block};
use super::{Gpu, RenderError};
use crate::fields::{Field, FieldGrid, FieldKind, Lut, MAX_MAPPINGS, Mapping, MappingTarget, SceneGeo};
use crate::scene::Scene;
use crate::scene::camera::Camera;
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

/// Code of a target in the shader ([`DataSlot::feature`]); 0 for abstraction, which the
/// geometry stage draws (see [`ProjectionPass::plant_abstraction`]).
fn feature_code(target: MappingTarget) -> u32 {
    match target {
        MappingTarget::Abstraction => 0,
        MappingTarget::Color => 1,
        MappingTarget::HatchTone => 2,
        MappingTarget::HatchPattern => 3,
        MappingTarget::SilhouetteStyle => 4,
        MappingTarget::SilhouetteDensity => 5,
        MappingTarget::HatchColor => 6,
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

gpu_block! {
    /// One mapping slot of the projection pass (`data.slots[i]` in `shaders/data.wgsl`).
    pub struct DataSlot {
        /// u = a·x + b, v = c·y + d: scene metres → field texture (a, b, c, d;
        /// [`FieldGrid::uv_transform`]).
        pub uv: Vec4f,
        /// The target feature ([`feature_code`]; 0: none).
        pub feature: u32,
        /// 1 for a label field, 0 for a scalar field.
        pub label: u32,
        /// u_t of eq. 9.4 between the two bracketing steps.
        pub time_weight: f32,
        /// Opacity of the mapping.
        pub opacity: f32,
        /// Value at the low end of the range (scalars).
        pub range_low: f32,
        /// Value at the high end of the range (scalars).
        pub range_high: f32,
        /// Number of label classes.
        pub classes: f32,
        /// 1 when the mapping runs reversed.
        pub reverse: u32,
    }
}

gpu_block! {
    /// The projection pass's block (`data` in `shaders/data.wgsl`).
    pub struct DataBlock {
        /// Clip space → world.
        pub inv_view_proj: Mat4f,
        /// The projection's z and w rows at view (0, 0, −d, 1): z_clip = x·d + y,
        /// w_clip = z·d + w.
        pub depth_to_clip: Vec4f,
        /// Image width in pixels.
        pub width: f32,
        /// Image height in pixels.
        pub height: f32,
        /// Number of TAMs (hatch-pattern mappings pick one by label).
        pub tams: u32,
        /// The mapping slots.
        pub slots: [DataSlot; MAX_MAPPINGS],
    }
}

gpu_block! {
    /// Thesis 9.2.2, Fig. 9.3: one hatch-colour slot of the compose pass (the mapping at that
    /// position of the view).
    pub struct HatchColor {
        /// Ink colour (sRGB).
        pub color: Vec3f,
        /// Opacity; 0 where the slot draws no coloured hatching.
        pub opacity: f32,
        /// cos and sin of the rotation of the hatch texture coordinates, which gives the
        /// slot's strokes their own direction.
        pub rotation: Vec2f,
    }
}

gpu_block! {
    /// The compose pass's hatch-colour slots (`hatch_colors` in `shaders/data_common.wgsl`).
    pub struct HatchColors {
        /// One per mapping slot.
        pub slots: [HatchColor; MAX_MAPPINGS],
    }
}

impl HatchColors {
    /// The ink, opacity and stroke direction of every hatch-colour mapping of `data`, in its slot.
    fn new(data: &DataView) -> HatchColors {
        let mut block = HatchColors::default();
        for (i, (slot, m)) in block.slots.iter_mut().zip(&data.mappings).enumerate() {
            let (sin, cos) = HATCH_COLOR_ANGLES[i].to_radians().sin_cos();
            slot.rotation = Vec2f([cos, sin]);
            if m.mapping.target == MappingTarget::HatchColor {
                slot.color = Vec3f(m.mapping.hatch_color(i));
                slot.opacity = m.mapping.opacity;
            }
        }
        block
    }
}

/// One resampled time step on the GPU.
struct StepTexture {
    view: wgpu::TextureView,
    /// Scene metres → texture coordinates ([`crate::fields::FieldGrid::uv_transform`]).
    uv: [f32; 4],
}

/// The projection pass's data (its shader is the declared [`super::passes::DATA`]): the cache
/// of field textures and the scene's geography.
pub struct ProjectionPass {
    scene: Result<SceneGeo, String>,
    steps: Mutex<HashMap<(String, usize), Arc<StepTexture>>>,
    grids: Mutex<HashMap<(String, usize), Arc<FieldGrid>>>,
    empty_grid: wgpu::TextureView,
    empty_lut: wgpu::TextureView,
    hatch_colors: wgpu::Buffer,
}

/// What the pass needs of a frame besides its data.
pub struct DataInputs<'a> {
    /// The camera of the frame.
    pub camera: &'a Camera,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The number of TAMs.
    pub tams: usize,
    /// Whether style layers use TAMs other than the base style's (thesis 8.2.8): then the
    /// pass runs even without mappings, so every pixel gets the TAM of its layer's style.
    pub layer_tams: bool,
}

/// The projection of one frame: the pass's block and each mapping's step textures and colour
/// table, bound by [`ProjectionPass::resource`].
pub struct DataFrame {
    block: wgpu::Buffer,
    fields: Vec<(Arc<StepTexture>, Arc<StepTexture>, wgpu::TextureView)>,
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
        ProjectionPass {
            scene: SceneGeo::from_terrain(&scene.terrain).map_err(|e| e.to_string()),
            steps: Mutex::default(),
            grids: Mutex::default(),
            empty_grid: texture_2d(gpu, "no data", wgpu::TextureFormat::R32Float, (1, 1), &NODATA.to_le_bytes()),
            empty_lut: texture_2d(gpu, "no colours", wgpu::TextureFormat::Rgba8Unorm, (1, 1), &[0; 4]),
            hatch_colors: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hatch colours"),
                size: uniforms::size_of::<HatchColors>(),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// The compose pass's uniform of the hatch-colour slots ([`HatchColors`]): ink, opacity
    /// and stroke direction per slot, written by [`ProjectionPass::prepare`] for the frame it
    /// prepares (frames of a renderer are serialised).
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

    /// Prepares the pass for a frame: writes the hatch-colour slots of `data` into
    /// [`ProjectionPass::hatch_colors`] and returns the block and field textures to bind, or
    /// `None` when the pass [`writes`](ProjectionPass::writes) nothing.
    pub fn prepare(
        &self,
        gpu: &Gpu,
        inputs: &DataInputs<'_>,
        data: &DataView,
    ) -> Result<Option<DataFrame>, RenderError> {
        if !Self::writes(data, inputs.layer_tams) {
            return Ok(None);
        }
        Self::check(data)?;
        gpu.queue.write_buffer(&self.hatch_colors, 0, &uniforms::bytes(&HatchColors::new(data)));
        let mut slots = [DataSlot::default(); MAX_MAPPINGS];
        let mut fields = Vec::new();
        for (i, (slot, m)) in slots.iter_mut().zip(&data.mappings).enumerate() {
            let field = &m.layer.field;
            let sample = field.time_sample(data.time);
            let lower = self.step_texture(gpu, &m.layer, sample.lower)?;
            let upper = self.step_texture(gpu, &m.layer, sample.upper)?;
            let lut = Lut::for_field(&m.mapping.color_spec(i), field).map_err(|e| RenderError::Data(e.to_string()))?;
            let [lo, hi] = lut.range.unwrap_or([0.0, 1.0]);
            *slot = DataSlot {
                uv: Vec4f(lower.uv),
                feature: feature_code(m.mapping.target),
                label: u32::from(field.kind() == FieldKind::Label),
                time_weight: sample.weight as f32,
                opacity: m.mapping.opacity,
                range_low: lo as f32,
                range_high: hi as f32,
                classes: field.classes().len() as f32,
                reverse: u32::from(m.mapping.reverse),
            };
            let lut_view = texture_2d(
                gpu,
                "colour table",
                wgpu::TextureFormat::Rgba8Unorm,
                (lut.colors.len() as u32, 1),
                &lut.to_rgba_bytes(),
            );
            fields.push((lower, upper, lut_view));
        }
        let projection = inputs.camera.projection(inputs.width as f32 / inputs.height as f32);
        let (z, w) = (projection.z_axis, projection.w_axis);
        let block = DataBlock {
            inv_view_proj: Mat4f::from((projection * inputs.camera.view()).inverse()),
            depth_to_clip: Vec4f([-z.z, w.z, -z.w, w.w]),
            width: inputs.width as f32,
            height: inputs.height as f32,
            tams: inputs.tams as u32,
            slots,
        };
        let block = gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("data"),
            contents: &uniforms::bytes(&block),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        Ok(Some(DataFrame { block, fields }))
    }

    /// What the pass binds for `resource` ([`Resource::DataBlock`] and the field resources) in
    /// the frame prepared as `frame`: mapping slots without a field read an empty grid and
    /// colour table. `None` for other resources.
    pub fn resource<'a>(&'a self, frame: &'a DataFrame, resource: Resource) -> Option<wgpu::BindingResource<'a>> {
        let view = wgpu::BindingResource::TextureView;
        let field = |i: usize| frame.fields.get(i);
        Some(match resource {
            Resource::DataBlock => frame.block.as_entire_binding(),
            Resource::FieldLower(i) => view(field(i).map_or(&self.empty_grid, |f| &f.0.view)),
            Resource::FieldUpper(i) => view(field(i).map_or(&self.empty_grid, |f| &f.1.view)),
            Resource::FieldColors(i) => view(field(i).map_or(&self.empty_lut, |f| &f.2)),
            _ => return None,
        })
    }
}
