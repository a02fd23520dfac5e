//! Stage one: the G-buffer (multiple render targets) and the geometry pass that fills it.

use super::bind_layouts::{storage_entry, texture_entry, uniform_entry};
use super::compare::Split;
use super::layer_code::LayerCode;
use super::style::{HatchSpace, STYLE_SLOTS, Style};
use super::uniforms::{self, Declarations, Mat4f, Vec2f, Vec3f, Vec4f, Wgsl, gpu_block};
use crate::prep::hlp::Sphere;
use crate::prep::leaves::{CORNERS, Leaf};
use crate::scene::camera::Camera;
use bytemuck::{Pod, Zeroable};

/// Albedo (linear RGB) and coverage (alpha: 1 where geometry was drawn).
pub const ALBEDO_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// World-space normal blended towards the HLP normal (xyz) and TAM tiles per pixel (w).
pub const NORMAL_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// Linear view depth in metres (x; the background holds [`BACKGROUND_DEPTH`]) and the HLP
/// radius in pixels (y; 0 where there is no HLP).
pub const LINEAR_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;
/// IDs: x = object ID (layer code in the top 8 bits, object index + 1 below; 0 = background),
/// y = patch ID (part kind << 24 | HLP index + 1), for the contour-doubling test.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Uint;
/// Hatch texture coordinates T in TAM tiles (xy) and E, the screen direction of the HLP normal
/// (zw, y up; zero without HLP).
pub const HATCH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Hardware depth (reverse Z) used for the depth test only.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Linear depth written where no geometry is: "infinitely" far, so the horizon gets a contour.
pub const BACKGROUND_DEPTH: f64 = 1.0e7;

/// Layer code of the terrain in the ID buffer ([`LayerCode::TERRAIN`] as a number).
pub const TERRAIN_LAYER_CODE: u32 = LayerCode::TERRAIN.code();

/// Builds an object ID for the ID buffer from a layer code and an object index.
pub fn object_id(layer: LayerCode, index: u32) -> u32 {
    (layer.code() << LayerCode::SHIFT) | ((index + 1) & LayerCode::INDEX_MASK)
}

/// The render targets of stage one for one image size.
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    pub albedo: wgpu::TextureView,
    pub normal: wgpu::TextureView,
    pub linear_depth: wgpu::TextureView,
    pub id: wgpu::TextureView,
    /// The ID target itself, for reading object IDs back.
    pub id_texture: wgpu::Texture,
    pub hatch: wgpu::TextureView,
    /// The linear depth target itself, for reading depth back (coherence measurement).
    pub linear_depth_texture: wgpu::Texture,
    pub depth: wgpu::TextureView,
}

/// Creates a 2D render target that later passes can read.
pub fn render_target(
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    width: u32,
    height: u32,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

impl GBuffer {
    /// Allocates all targets for a `width` × `height` image.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> GBuffer {
        let view = |label, format| render_target(device, label, format, width, height).create_view(&Default::default());
        let id_texture = render_target(device, "gbuffer id", ID_FORMAT, width, height);
        let linear_depth_texture = render_target(device, "gbuffer linear depth", LINEAR_DEPTH_FORMAT, width, height);
        GBuffer {
            width,
            height,
            albedo: view("gbuffer albedo", ALBEDO_FORMAT),
            normal: view("gbuffer normal", NORMAL_FORMAT),
            linear_depth: linear_depth_texture.create_view(&Default::default()),
            linear_depth_texture,
            id: id_texture.create_view(&Default::default()),
            id_texture,
            hatch: view("gbuffer hatch", HATCH_FORMAT),
            depth: view("gbuffer depth", DEPTH_FORMAT),
        }
    }
}

gpu_block! {
    /// Per-frame uniforms of the geometry pass (`frame` in `shaders/gbuffer.wgsl`).
    pub struct GeometryFrame {
        /// World → clip.
        pub view_proj: Mat4f,
        /// World → view.
        pub view: Mat4f,
        /// Camera position (world).
        pub camera_pos: Vec3f,
        /// tan(fov/2).
        pub tan_half_fov: f32,
        /// Image width in pixels.
        pub width: f32,
        /// Image height in pixels.
        pub height: f32,
        /// Metres per pixel of a plan view (orthographic; 0 in perspective).
        pub plan_metres_per_pixel: f32,
        /// cos and sin of −roll (the hatch coordinates turn against the camera roll).
        pub roll: Vec2f,
        /// Bit `i` set where TAM `i`'s strokes run in one direction
        /// ([`super::art_textures::ArtTextures::directional_tams`]): the terrain sizes those by
        /// the ground's footprint across the strokes, the others by its area.
        pub directional_tams: u32,
    }
}

/// Bytes between the style slots' [`LayerStyle`]s in the layer buffer: each draw binds its
/// slot's block at a dynamic offset, which must be a multiple of the device's uniform offset
/// alignment (256 at most by the WebGPU limits).
pub const LAYER_STRIDE: u64 = 256;

/// The [`LayerStyle`] of every style slot at [`LAYER_STRIDE`] (see
/// [`super::style::FrameStyle::slots`]); slots beyond `slots` take the default style. The
/// slot of a split view's layer starts at the split line ([`Split`]).
pub fn layer_uniforms(slots: &[Style], split: Option<Split>) -> Vec<u8> {
    let mut bytes = vec![0u8; STYLE_SLOTS * LAYER_STRIDE as usize];
    let default = Style::default();
    for (slot, chunk) in bytes.chunks_exact_mut(LAYER_STRIDE as usize).enumerate() {
        let mut layer = LayerStyle::new(slots.get(slot).unwrap_or(&default));
        if let Some(Split { slot: split_slot, x: Some(x) }) = split
            && split_slot == slot
        {
            layer.hidden_left_of = x;
        }
        let layer = uniforms::bytes(&layer);
        chunk[..layer.len()].copy_from_slice(&layer);
    }
    bytes
}

gpu_block! {
    /// The geometry-pass parameters of one style slot (`layer` in `shaders/gbuffer.wgsl`).
    pub struct LayerStyle {
        /// Blend of the normal towards the HLP normal.
        pub normal_blend: f32,
        /// 1: hatch coordinates in image space, 0: hybrid.
        pub image_space: u32,
        /// HLP abstraction 1 − f (thesis eq. 4.8).
        pub hlp_abstraction: f32,
        /// Share of the way to 1 that the HLP abstraction and the normal blend rise with
        /// distance ([`Style::distance_abstraction`]).
        pub distance_abstraction: f32,
        /// Where that rise starts and where it is full, metres from the eye (far > near).
        pub abstraction_near: f32,
        /// See `abstraction_near`.
        pub abstraction_far: f32,
        /// Colour abstraction: texture → average material colour (thesis 6.2).
        pub color_abstraction: f32,
        /// TAM tiles per π (m = n).
        pub hatch_tiles: f32,
        /// Surface function c (eq. 6.6).
        pub hatch_surface: f32,
        /// Image-space tile size in pixels (also the object-space terrain strokes' size on screen).
        pub image_hatch_scale: f32,
        /// The terrain's strokes ([`super::style::TerrainStrokes::code`]).
        pub terrain_strokes: u32,
        /// The largest tile of the terrain's object-space strokes on screen, in pixels
        /// ([`super::style::Style::terrain_tile`]).
        pub terrain_tile: f32,
        /// The style's TAM index (the terrain's strokes where its land-cover class has none).
        pub hatch_map: u32,
        /// Leaf mode ([`super::style::LeafMode`]: 0 original, 1 billboard, 2 reoriented,
        /// 3 elliptical, 4 shapes).
        pub leaf_mode: u32,
        /// Leaf size.
        pub leaf_size: f32,
        /// Leaf shape: α_t from α_max to α_min (thesis 4.1).
        pub leaf_shape: f32,
        /// Leaf outline Δα (eq. 4.1).
        pub leaf_outline: f32,
        /// Blend towards the implicit-surface normal (Luft et al. 2007 §3.3).
        pub implicit_normals: f32,
        /// How much k_a of the implicit surface (eq. 4) darkens the ambient light.
        pub ambient_occlusion: f32,
        /// Ink of a vegetation mass's outline: the style's contour strength (the masses' edges
        /// are too shallow in depth for the contour pass far away).
        pub mass_outline: f32,
        /// Pixels left of this x (from the left edge) draw none of the layer: the "before"
        /// half of a split view ([`super::compare`]); 0 draws it everywhere.
        pub hidden_left_of: f32,
    }
}

impl LayerStyle {
    /// The geometry-stage fields of a resolved `style`.
    pub fn new(style: &Style) -> LayerStyle {
        LayerStyle {
            normal_blend: style.normal_blend,
            image_space: u32::from(style.hatch_space == HatchSpace::Image),
            hlp_abstraction: style.hlp_abstraction,
            distance_abstraction: style.distance_abstraction,
            abstraction_near: style.abstraction_near,
            abstraction_far: style.abstraction_far.max(style.abstraction_near + 0.01),
            color_abstraction: style.color_abstraction,
            hatch_tiles: style.hatch_tiles,
            hatch_surface: style.hatch_surface,
            image_hatch_scale: style.image_hatch_scale,
            terrain_strokes: style.terrain_stroke_direction.code(),
            terrain_tile: style.terrain_tile(),
            hatch_map: style.hatch_map as u32,
            leaf_mode: style.leaf_mode as u32,
            leaf_size: style.leaf_size,
            leaf_shape: style.leaf_shape,
            leaf_outline: style.leaf_outline,
            implicit_normals: style.implicit_normals,
            ambient_occlusion: style.ambient_occlusion,
            mass_outline: style.contour_strength,
            hidden_left_of: 0.0,
        }
    }
}

impl GeometryFrame {
    /// The uniforms for `camera` rendering a `width` × `height` image with the TAMs whose bits
    /// `directional_tams` sets directional.
    pub fn new(camera: &Camera, width: u32, height: u32, directional_tams: u32) -> GeometryFrame {
        let view = camera.view();
        let roll = -camera.roll.to_radians();
        GeometryFrame {
            view_proj: (camera.projection(width as f32 / height as f32) * view).into(),
            view: view.into(),
            camera_pos: Vec3f(camera.position),
            tan_half_fov: (camera.fov.to_radians() * 0.5).tan(),
            width: width as f32,
            height: height as f32,
            plan_metres_per_pixel: camera.plan_metres_per_pixel(width).unwrap_or(0.0),
            roll: Vec2f([roll.cos(), roll.sin()]),
            directional_tams,
        }
    }

    /// The WGSL declarations of the geometry-stage blocks (prefixing `shaders/gbuffer.wgsl`).
    pub fn declarations() -> String {
        let mut declarations = Declarations::default();
        for declare in [
            GeometryFrame::declare,
            LayerStyle::declare,
            SurfaceMaterial::declare,
            super::ground_cover::CoverStyle::declare,
        ] {
            declare(&mut declarations);
        }
        declarations.into_text()
    }
}

/// What a surface is, as the G-buffer pass distinguishes it (`SURFACE` in
/// `shaders/gbuffer.wgsl`): each kind is drawn by its own pipeline, whose shader holds only that
/// kind's code (lavapipe runs both sides of every branch for every fragment).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    Terrain = 0,
    Wood = 1,
    Foliage = 2,
    /// A billboard of an HLP or a whole plant: shaded as its HLP sphere.
    Billboard = 3,
    /// The domes of a far vegetation mass (`prep::masses`): hatched like foliage from the grid
    /// reference points, coloured per vertex, outlined at the mass's edge.
    Mass = 4,
}

impl Surface {
    /// Every kind, in the order of their codes.
    pub const ALL: [Surface; 5] =
        [Surface::Terrain, Surface::Wood, Surface::Foliage, Surface::Billboard, Surface::Mass];
}

gpu_block! {
    /// Per-material uniforms (`material` in `shaders/gbuffer.wgsl` and `shaders/bake.wgsl`).
    pub struct SurfaceMaterial {
        /// Base colour (linear RGBA), multiplied with the texture.
        pub base_color: Vec4f,
        /// Alpha cutoff: negative for opaque surfaces; α_max of thesis 4.1 for foliage.
        pub alpha_cutoff: f32,
        /// α_min, the alpha threshold of the most abstract leaf shape (foliage; the cutoff
        /// elsewhere).
        pub alpha_min: f32,
        /// Scale of leaf particles drawn as a share of the leaves (√(all / drawn), SPEC P4; 1
        /// elsewhere).
        pub particle_scale: f32,
        /// The material's average colour, linear RGB (abstract colour, thesis 6.2; see
        /// [`average_color`]).
        pub average_color: Vec3f,
    }
}

impl SurfaceMaterial {
    /// The block of `material` with its alpha thresholds and leaf-particle scale.
    pub fn new(material: &crate::scene::plant::Material, cutoff: f32, alpha_min: f32, particle_scale: f32) -> Self {
        let [r, g, b, _] = average_color(material);
        SurfaceMaterial {
            base_color: Vec4f(material.base_color),
            alpha_cutoff: cutoff,
            alpha_min,
            particle_scale,
            average_color: Vec3f([r, g, b]),
        }
    }
}

/// The average colour of a material, linear RGB: the base colour times the mean of its
/// texture's texels weighted by their alpha (so the transparent surround of a leaf texture
/// does not count); the source of abstract colour (thesis 6.2).
pub fn average_color(material: &crate::scene::plant::Material) -> [f32; 4] {
    let [r, g, b, a] = material.base_color;
    let Some(texture) = &material.texture else { return [r, g, b, a] };
    let linear: Vec<f32> = (0..=255u8).map(crate::srgb::to_linear).collect();
    let mut sum = [0.0f64; 4];
    for p in texture.pixels() {
        let w = f64::from(p[3]) / 255.0;
        for c in 0..3 {
            sum[c] += w * f64::from(linear[usize::from(p[c])]);
        }
        sum[3] += w;
    }
    if sum[3] <= 0.0 {
        return [r, g, b, a];
    }
    let mean = |c: usize| (sum[c] / sum[3]) as f32;
    [r * mean(0), g * mean(1), b * mean(2), a]
}

/// One mesh vertex as the geometry pass reads it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    /// HLP centre (model space) and radius; radius 0 for vertices without HLP.
    pub hlp: [f32; 4],
    /// HLP index within the model ([`NO_HLP`] without).
    pub hlp_index: u32,
    /// Foliage: the normal of the implicit surface at the vertex scaled by its ambient
    /// coefficient, k_a·N_s (Luft et al. 2007 §3.2–3.3, [`crate::prep::implicit`]), in model
    /// space; billboards: (0, 0, mean k_a of the leaves they stand for), only the length
    /// counts since they are lit as their HLP sphere; zero ("none") for terrain and wood. The
    /// paper stores k_a in the length of the replaced vertex normal; this extra attribute keeps
    /// the original normal as well, so styles blend original, implicit and HLP normals at run
    /// time (SPEC R6).
    pub implicit: [f32; 3],
}

/// HLP index of vertices that belong to no HLP (terrain, wood).
pub const NO_HLP: u32 = u32::MAX;

/// One corner of a leaf particle as `vs_leaf` reads it (`LeafIn` in `shaders/gbuffer.wgsl`):
/// the whole leaf rectangle ([`Leaf`]) and which corner this is, so the vertex shader can
/// place, turn and size the particle for the style of the frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct LeafVertex {
    /// Leaf centre, model space.
    pub center: [f32; 3],
    /// The corner (s, t) ∈ {−1, 1}² (see [`crate::prep::leaves::CORNERS`]).
    pub corner: [f32; 2],
    /// The leaf's first in-plane axis times its half size (texture u grows along it).
    pub axis_u: [f32; 3],
    /// The second in-plane axis times its half size (texture v grows along it).
    pub axis_v: [f32; 3],
    /// Unit leaf normal (front side).
    pub normal: [f32; 3],
    /// Texture coordinates of this corner.
    pub uv: [f32; 2],
    /// HLP centre (model space) and radius.
    pub hlp: [f32; 4],
    /// HLP index within the model.
    pub hlp_index: u32,
    /// The share of the rectangle the leaf's texture covers ([`crate::prep::leaves::coverage`]):
    /// an elliptical leaf keeps that area.
    pub coverage: f32,
    /// The implicit-surface illumination k_a·N_s of the leaf (see [`Vertex::implicit`]).
    pub implicit: [f32; 3],
}

impl LeafVertex {
    /// The four corners of `leaf`, whose HLP is `sphere`, whose texture covers `coverage` of
    /// its rectangle and whose implicit-surface illumination is `implicit`, in the order of
    /// [`crate::prep::leaves::CORNERS`].
    pub fn corners(leaf: &Leaf, sphere: Sphere, coverage: f32, implicit: [f32; 3]) -> [LeafVertex; 4] {
        let [h0, h1] = leaf.half_sizes;
        std::array::from_fn(|i| LeafVertex {
            center: leaf.center.to_array(),
            corner: CORNERS[i],
            axis_u: (leaf.axes[0] * h0).to_array(),
            axis_v: (leaf.axes[1] * h1).to_array(),
            normal: leaf.normal.to_array(),
            uv: leaf.uv_corners[i],
            hlp: [sphere.center.x, sphere.center.y, sphere.center.z, sphere.radius.max(1e-3)],
            hlp_index: leaf.hlp,
            coverage,
            implicit,
        })
    }
}

/// One instance of a mesh: placement, uniform scale, rotation about z, object ID and the first
/// entry of its HLPs in the reference-coordinate buffer.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Instance {
    pub offset_scale: [f32; 4],
    pub rotation: [f32; 2],
    pub object_id: u32,
    pub reference_base: u32,
    /// Screen-door mask of a level-of-detail blend: pixels whose dither value lies in
    /// `mask[0]..mask[1]` are drawn (`[0, 1]`: all).
    pub mask: [f32; 2],
    /// A data layer's HLP abstraction for this plant and the weight it replaces the style's
    /// with (D3 `abstraction`; `[0, 0]`: the style's). For a chunk of vegetation masses, the
    /// screen-door window of its level of detail instead: pixels whose dither value lies in
    /// `[0]..[1]` are drawn (two levels blend in complementary windows). The shader reads it
    /// with `mask` as one vec4 (location 9): every vertex location is taken.
    pub data_abstraction: [f32; 2],
    /// A far reference point standing in for the plant's own HLP sphere in the hatching and
    /// silhouette parametrizations (world centre, radius; radius 0: the plant's own, thesis 7.3).
    pub reference_sphere: [f32; 4],
}

/// The geometry pass pipelines and the bind group layouts meshes and frames are bound with.
pub struct GeometryPass {
    /// One pipeline per [`Surface`] for meshes (`vs_main`), in the order of [`Surface::ALL`].
    pipelines: [wgpu::RenderPipeline; Surface::ALL.len()],
    /// The terrain's pipeline for a drape without land-cover classes.
    bare_terrain: wgpu::RenderPipeline,
    /// The pipeline drawing leaf particles (`vs_leaf`, SPEC R1, R2; foliage).
    pub leaf_pipeline: wgpu::RenderPipeline,
    pub frame_layout: wgpu::BindGroupLayout,
    pub material_layout: wgpu::BindGroupLayout,
    pub sampler: wgpu::Sampler,
}

/// `shaders/gbuffer.wgsl` after the declarations of its blocks.
fn shader_source() -> String {
    format!("{}{}", GeometryFrame::declarations(), include_str!("../../../shaders/gbuffer.wgsl"))
}

/// A bind group layout entry for the [`LayerStyle`] of one style slot, bound per draw at a
/// dynamic offset into the layer buffer (see [`layer_uniforms`]).
fn layer_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: wgpu::BufferSize::new(uniforms::size_of::<LayerStyle>()),
        },
        count: None,
    }
}

impl GeometryPass {
    /// Compiles `shaders/gbuffer.wgsl` and builds the pipeline.
    pub fn new(device: &wgpu::Device) -> GeometryPass {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("gbuffer.wgsl"),
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
        });
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                storage_entry(1, wgpu::ShaderStages::VERTEX),
                layer_entry(2),
                storage_entry(3, wgpu::ShaderStages::FRAGMENT),
            ],
        });
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("material"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                texture_entry(1, wgpu::TextureSampleType::Float { filterable: true }),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gbuffer"),
            bind_group_layouts: &[Some(&frame_layout), Some(&material_layout)],
            immediate_size: 0,
        });
        let vertex_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x4, 4 => Uint32, 13 => Float32x3];
        let instance_attrs = wgpu::vertex_attr_array![5 => Float32x4, 6 => Float32x2, 7 => Uint32, 8 => Uint32, 9 => Float32x4, 15 => Float32x4];
        let target = |format| Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL });
        // The pipelines share the instances, the fragment shader and the targets; they differ
        // in their vertices, mesh vertices (`vs_main`) or leaf-particle corners (`vs_leaf`),
        // and in the kind of surface their shader is compiled for.
        let pipeline_with =
            |label, entry_point, vertices: wgpu::VertexBufferLayout<'_>, surface: Surface, cover: bool| {
                let flag = |b: bool| f64::from(u8::from(b));
                let constants = [
                    ("SURFACE", surface as u32 as f64),
                    ("LEAF_PARTICLES", flag(entry_point == "vs_leaf")),
                    ("LAND_COVER", flag(cover)),
                ];
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&layout),
                    vertex: wgpu::VertexState {
                        module: &shader,
                        entry_point: Some(entry_point),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &constants,
                            ..Default::default()
                        },
                        buffers: &[
                            Some(vertices),
                            Some(wgpu::VertexBufferLayout {
                                array_stride: std::mem::size_of::<Instance>() as u64,
                                step_mode: wgpu::VertexStepMode::Instance,
                                attributes: &instance_attrs,
                            }),
                        ],
                    },
                    primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_FORMAT,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Greater),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &shader,
                        entry_point: Some("fs_main"),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &constants,
                            ..Default::default()
                        },
                        targets: &[
                            target(ALBEDO_FORMAT),
                            target(NORMAL_FORMAT),
                            target(LINEAR_DEPTH_FORMAT),
                            target(ID_FORMAT),
                            target(HATCH_FORMAT),
                        ],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
        let mesh_pipeline = |surface: Surface, cover: bool| {
            pipeline_with(
                "gbuffer",
                "vs_main",
                wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &vertex_attrs,
                },
                surface,
                cover,
            )
        };
        let pipelines = Surface::ALL.map(|surface| mesh_pipeline(surface, true));
        let bare_terrain = mesh_pipeline(Surface::Terrain, false);
        let leaf_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x2, 2 => Float32x3, 3 => Float32x3,
            4 => Float32x3, 10 => Float32x2, 11 => Float32x4, 12 => Uint32, 13 => Float32, 14 => Float32x3];
        let leaf_pipeline = pipeline_with(
            "gbuffer leaves",
            "vs_leaf",
            wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<LeafVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &leaf_attrs,
            },
            Surface::Foliage,
            true,
        );
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("material"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            // The nearest mip level: alpha-tested leaves and billboards keep crisp edges, and
            // it halves the texel reads per fragment on lavapipe (10k-plant G-buffer −2 ms).
            mipmap_filter: wgpu::MipmapFilterMode::Nearest,
            ..Default::default()
        });
        GeometryPass { pipelines, bare_terrain, leaf_pipeline, frame_layout, material_layout, sampler }
    }

    /// The pipeline drawing meshes of `surface`.
    pub fn pipeline(&self, surface: Surface) -> &wgpu::RenderPipeline {
        &self.pipelines[surface as usize]
    }

    /// The pipeline drawing the terrain, with or without its land-cover class lookup (a
    /// terrain without classes skips it: `LAND_COVER` in `shaders/gbuffer.wgsl`).
    pub fn terrain_pipeline(&self, land_cover: bool) -> &wgpu::RenderPipeline {
        match land_cover {
            true => self.pipeline(Surface::Terrain),
            false => &self.bare_terrain,
        }
    }

    /// Clears the G-buffer and draws every batch of `scene` into it.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        gbuffer: &GBuffer,
        frame: &wgpu::BindGroup,
        scene: &super::scene_gpu::SceneGpu,
        visible: &super::scene_gpu::VisibleSet,
    ) {
        let clear = |view, color| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(color), store: wgpu::StoreOp::Store },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("gbuffer"),
            color_attachments: &[
                clear(&gbuffer.albedo, wgpu::Color::TRANSPARENT),
                clear(&gbuffer.normal, wgpu::Color::TRANSPARENT),
                clear(&gbuffer.linear_depth, wgpu::Color { r: BACKGROUND_DEPTH, g: 0.0, b: 0.0, a: 0.0 }),
                clear(&gbuffer.id, wgpu::Color::TRANSPARENT),
                clear(&gbuffer.hatch, wgpu::Color::TRANSPARENT),
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &gbuffer.depth,
                // Kept for the compose pass, which tells background from geometry by it.
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        scene.draw(&mut pass, visible, frame, self);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_geometry_shader_compiles_with_its_derived_blocks() {
        crate::render::uniforms::validate_wgsl("gbuffer", &super::shader_source());
    }
}
