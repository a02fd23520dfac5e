//! GPU-side copy of a scene: vertex/index buffers per mesh and level of detail, textures,
//! baked billboard atlases and material bind groups, all built once per scene. Each frame only
//! culls the plant instances against the view frustum, picks every visible plant's level of
//! detail from its projected size (`prep::lod`) and uploads the resulting instance list.

use super::bake::{BakeDraw, BakeTile, Baker};
use super::gbuffer::{
    GeometryPass, Instance, LAYER_STRIDE, LeafVertex, MaterialUniform, NO_HLP, Surface, Vertex, average_color,
    object_id,
};
use super::layer_code::LayerCode;
use super::parametrization::RefKey;
use super::style::{STYLE_SLOTS, Style};
use super::{Gpu, RenderError};
use crate::prep::cache::{DiskCache, KeyBuilder};
use crate::prep::hlp::{self, Hlps, Sphere};
use crate::prep::implicit::{self, ImplicitParams};
use crate::prep::leaf_shape::{ShapeParams, shape_map_cached};
use crate::prep::leaves::{self, Leaf, PARTICLE_SHARES};
use crate::prep::lod::{self, Atlas, Billboard, LodLevel, LodSettings};
use crate::prep::terrain_lod::{TerrainChunk, TerrainLod};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{Material, PartKind, PlantModel};
use glam::{Vec2, Vec3};
use serde::Serialize;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;
use tracing::info;
use wgpu::util::DeviceExt;

/// Pixel size of one billboard atlas tile.
const BILLBOARD_TILE: u32 = 64;
/// Sides of the fitted trunk prism.
const TRUNK_SIDES: usize = 6;
/// Alpha below which billboard texels are cut away.
const BILLBOARD_ALPHA_CUTOFF: f32 = 0.35;
/// DEM cells along each side of a terrain chunk.
const TERRAIN_CHUNK_CELLS: usize = 32;
/// Most levels of detail of a terrain chunk.
const TERRAIN_LEVELS: usize = 6;
/// On-screen size in pixels below which the terrain's (coarsened) cells are kept.
const TERRAIN_CELL_PX: f32 = 8.0;
/// Spacing in metres of the terrain grid of far reference points (thesis 7.3).
const REFERENCE_GRID_SPACING: f32 = 40.0;

/// One uploaded mesh with its material.
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    material: wgpu::BindGroup,
    /// Which of the geometry pass's pipelines draws the mesh.
    surface: Surface,
}

impl From<PartKind> for Surface {
    fn from(kind: PartKind) -> Surface {
        match kind {
            PartKind::Wood => Surface::Wood,
            PartKind::Foliage => Surface::Foliage,
        }
    }
}

/// The leaf particles of one foliage part (SPEC R1, R2, P4): a quad per leaf, in a shuffled
/// order so that every prefix is an even share of the leaves.
struct LeafGpu {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// Indices drawn per share of [`PARTICLE_SHARES`].
    counts: [u32; PARTICLE_SHARES.len()],
    /// The part's material per share, scaling the particles by √(all / drawn).
    materials: [wgpu::BindGroup; PARTICLE_SHARES.len()],
}

/// A species drawn with leaf particles at full detail: the wood of the full model and the
/// particles of every foliage part.
struct Particles {
    /// Indices of the wood meshes in the full level.
    wood: Vec<usize>,
    leaves: Vec<LeafGpu>,
    /// Number of leaves over all parts.
    count: usize,
    /// Triangles drawn per share of [`PARTICLE_SHARES`], wood included.
    triangles: [u64; PARTICLE_SHARES.len()],
}

/// One species on the GPU: its meshes at every level of detail.
struct SpeciesGpu {
    levels: [Vec<GpuMesh>; 3],
    /// What replaces the full level in the particle leaf modes.
    particles: Particles,
    triangles: [u64; 3],
    /// Bounding sphere of the model (model space), for culling.
    bounds: Sphere,
    /// Height of the model, for its projected size.
    height: f32,
    /// The HLP spheres (model space): reference points of the two finer levels.
    spheres: Vec<Sphere>,
    /// The sphere of the whole-plant billboard: the plant's reference point.
    board: Sphere,
}

/// One plant: its species, its instance data and the terrain-grid cell it stands in.
#[derive(Clone, Copy)]
struct Plant {
    species: usize,
    instance: Instance,
    cell: u32,
}

impl Plant {
    /// A model-space point of the plant in world space.
    fn world(&self, p: Vec3) -> Vec3 {
        let [x, y, z, scale] = self.instance.offset_scale;
        let [c, s] = self.instance.rotation;
        let p = p * scale;
        Vec3::new(x + c * p.x - s * p.y, y + s * p.x + c * p.y, z + p.z)
    }
}

/// Counts of a frame's geometry: what the seeds' Table 8.1 reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct DrawStats {
    /// Plants in the scene.
    pub plants: u64,
    /// Plants inside the view frustum and large enough to draw.
    pub plants_drawn: u64,
    /// Plant draws per level of detail (full, HLP billboards, plant billboard); a plant in a
    /// blend band counts at both levels.
    pub per_level: [u64; 3],
    /// Triangles submitted, terrain included.
    pub triangles: u64,
    /// Triangles of the full scene (every plant at full detail, and the terrain).
    pub source_triangles: u64,
    /// Hatching reference points of the frame (HLPs, plants and terrain-grid cells, thesis 7.3).
    pub reference_points: u64,
}

impl DrawStats {
    /// Submitted triangles as a percentage of the source geometry (the seeds' "% lod").
    pub fn percent_drawn(&self) -> f64 {
        100.0 * self.triangles as f64 / self.source_triangles.max(1) as f64
    }
}

/// How [`SceneGpu::cull`] draws the plants of one layer, from the layer's (resolved) style.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LayerDraw {
    /// Whether the layer's plants are drawn (`Style::visible`).
    pub visible: bool,
    /// Whether plants at full detail draw leaf particles instead of the model's foliage (a
    /// particle `Style::leaf_mode`).
    pub particles: bool,
}

impl From<&Style> for LayerDraw {
    fn from(style: &Style) -> LayerDraw {
        LayerDraw { visible: style.visible, particles: style.leaf_mode.particles() }
    }
}

/// The plants one frame draws: its instance list in (species, level) runs and the reference
/// points the instances index.
pub struct VisibleSet {
    instances: Vec<Instance>,
    /// Runs of plants drawn with the species' meshes: (species, level, style slot, instances).
    batches: Vec<(usize, LodLevel, usize, Range<u32>)>,
    /// Runs of plants at full detail drawn with leaf particles: (species, share, style slot,
    /// instances).
    particle_batches: Vec<(usize, usize, usize, Range<u32>)>,
    /// Index ranges of the visible terrain chunks at their levels of detail.
    terrain_ranges: Vec<Range<u32>>,
    references: Vec<RefKey>,
    pub stats: DrawStats,
}

impl VisibleSet {
    /// The reference points of the frame, in the order of its reference buffer.
    pub fn references(&self) -> &[RefKey] {
        &self.references
    }
}

/// Everything the geometry pass draws, resident on the GPU.
pub struct SceneGpu {
    /// The terrain's chunks at all levels of detail, in one vertex and one index buffer.
    terrain: GpuMesh,
    terrain_chunks: Vec<TerrainChunk>,
    /// DEM cell size in metres, for the chunks' projected cell size.
    terrain_cell: f32,
    species: Vec<SpeciesGpu>,
    plants: Vec<Plant>,
    source_triangles: u64,
    /// The far reference points: one sphere per terrain-grid cell holding plants (world space).
    cells: Vec<Sphere>,
    /// The instances of a frame: room for every plant at two levels, and the terrain.
    instance_buffer: wgpu::Buffer,
    /// The reference coordinates of a frame, grown when a frame needs more.
    reference_buffer: std::sync::Mutex<wgpu::Buffer>,
    /// GPU memory of everything above.
    gpu_bytes: u64,
}

/// Uploads an sRGB RGBA image with a full mip chain (box-filtered on the CPU).
fn upload_texture(device: &wgpu::Device, queue: &wgpu::Queue, image: &image::RgbaImage) -> wgpu::TextureView {
    let (width, height) = image.dimensions();
    let levels = 32 - width.max(height).max(1).leading_zeros();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("material texture"),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: levels,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let mut level_image = image.clone();
    for level in 0..levels {
        let (w, h) = level_image.dimensions();
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: level,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &level_image,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * w), rows_per_image: Some(h) },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
        level_image = image::imageops::resize(
            &level_image,
            (w / 2).max(1),
            (h / 2).max(1),
            image::imageops::FilterType::Triangle,
        );
    }
    texture.create_view(&Default::default())
}

/// Builds GPU resources, sharing textures between materials that use the same image.
struct Uploader<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    pass: &'a GeometryPass,
    textures: HashMap<*const image::RgbaImage, wgpu::TextureView>,
    white: wgpu::TextureView,
    /// Bytes of GPU memory uploaded so far (buffers, textures with their mip chains).
    bytes: u64,
    /// Where leaf shape maps are cached.
    disk: Option<&'a DiskCache>,
}

impl Uploader<'_> {
    /// Uploads a mesh; `hlp` gives the HLP index of every vertex and the spheres they index.
    fn mesh(
        &mut self,
        mesh: &Mesh,
        hlp: Option<(&[u32], &[Sphere])>,
        material: &Material,
        surface: Surface,
    ) -> GpuMesh {
        self.lit_mesh(mesh, hlp, &[], material, surface)
    }

    /// [`Uploader::mesh`] with the implicit-surface illumination k_a·N_s of every vertex
    /// ([`Vertex::implicit`]; vertices beyond `implicit` get zero, "none").
    fn lit_mesh(
        &mut self,
        mesh: &Mesh,
        hlp: Option<(&[u32], &[Sphere])>,
        implicit: &[[f32; 3]],
        material: &Material,
        surface: Surface,
    ) -> GpuMesh {
        let vertices: Vec<Vertex> = (0..mesh.positions.len())
            .map(|i| {
                let (index, sphere) = match hlp {
                    Some((indices, spheres)) => {
                        let s = spheres[indices[i] as usize];
                        (indices[i], [s.center.x, s.center.y, s.center.z, s.radius.max(1e-3)])
                    }
                    None => (NO_HLP, [0.0; 4]),
                };
                Vertex {
                    position: mesh.positions[i],
                    normal: mesh.normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0]),
                    uv: mesh.uvs.get(i).copied().unwrap_or([0.0, 0.0]),
                    hlp: sphere,
                    hlp_index: index,
                    implicit: implicit.get(i).copied().unwrap_or([0.0; 3]),
                }
            })
            .collect();
        let (vertices, indices) = self.buffers(bytemuck::cast_slice(&vertices), &mesh.indices);
        let material = self.material(material, surface, 1.0);
        GpuMesh { vertices, indices, index_count: mesh.indices.len() as u32, material, surface }
    }

    /// Uploads a vertex and an index buffer.
    fn buffers(&mut self, vertices: &[u8], indices: &[u32]) -> (wgpu::Buffer, wgpu::Buffer) {
        self.bytes += (vertices.len() + 4 * indices.len()) as u64;
        let vertex_buffer = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: vertices,
            usage: wgpu::BufferUsages::VERTEX,
        });
        let index_buffer = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        (vertex_buffer, index_buffer)
    }

    /// Uploads the leaf particles of one foliage part: a quad per leaf of `leaves` (in their
    /// shuffled order), whose HLPs `spheres` holds, with `material`; `implicit` is the part's
    /// implicit-surface illumination per vertex.
    fn particles(
        &mut self,
        leaves: &[Leaf],
        spheres: &[Sphere],
        implicit: &[[f32; 3]],
        material: &Material,
    ) -> LeafGpu {
        let mut vertices = Vec::with_capacity(4 * leaves.len());
        let mut indices = Vec::with_capacity(6 * leaves.len());
        for leaf in leaves {
            let first = vertices.len() as u32;
            let sphere = spheres.get(leaf.hlp as usize).copied().unwrap_or(Sphere { center: leaf.center, radius: 0.0 });
            let coverage = leaves::coverage(leaf, material.texture.as_deref(), material.alpha_cutoff);
            let lit = implicit.get(leaf.vertex as usize).copied().unwrap_or([0.0; 3]);
            vertices.extend(LeafVertex::corners(leaf, sphere, coverage, lit));
            indices.extend(leaf.triangles().map(|corner| first + corner));
        }
        let (vertices, indices) = self.buffers(bytemuck::cast_slice(&vertices), &indices);
        let drawn = PARTICLE_SHARES.map(|share| leaves::prefix_len(leaves.len(), share));
        // Fewer particles, larger: √(all / drawn) keeps the coverage (SPEC P4).
        let materials =
            drawn.map(|n| self.material(material, Surface::Foliage, (leaves.len() as f32 / n.max(1) as f32).sqrt()));
        let counts = drawn.map(|n| 6 * n as u32);
        LeafGpu { vertices, indices, counts, materials }
    }

    /// The bind group of `material` drawn as `surface`: its uniform, texture and sampler.
    /// Alpha-tested foliage gets the leaf shape map of its texture (thesis 4.1,
    /// [`shape_map_cached`]) with α_max at the material's cutoff, so the style's `leaf_shape`
    /// picks a more abstract shape at render time. `particle_scale` sizes leaf particles drawn
    /// as a share of the leaves (1 for everything else).
    fn material(&mut self, material: &Material, surface: Surface, particle_scale: f32) -> wgpu::BindGroup {
        let cutoff = material.alpha_cutoff.unwrap_or(-1.0);
        let shapes = match (&material.texture, material.alpha_cutoff) {
            (Some(texture), Some(alpha_max)) if surface == Surface::Foliage => {
                let defaults = ShapeParams::default();
                let params = ShapeParams { alpha_max, alpha_min: defaults.alpha_min.min(0.5 * alpha_max), ..defaults };
                Some((shape_map_cached(texture, &params, self.disk), params.alpha_min))
            }
            _ => None,
        };
        let alpha_min = shapes.as_ref().map_or(cutoff, |(_, alpha_min)| *alpha_min);
        let texture = shapes.map(|(map, _)| map).or_else(|| material.texture.clone());
        let uniform = MaterialUniform {
            base_color: material.base_color,
            params: [cutoff, 0.0, alpha_min, particle_scale],
            average_color: average_color(material),
        };
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = match &texture {
            Some(image) => {
                let (device, queue, bytes) = (self.device, self.queue, &mut self.bytes);
                let upload = || {
                    // A full mip chain adds a third to the base level.
                    *bytes += u64::from(image.width()) * u64::from(image.height()) * 16 / 3;
                    upload_texture(device, queue, image)
                };
                self.textures.entry(Arc::as_ptr(image)).or_insert_with(upload).clone()
            }
            None => self.white.clone(),
        };
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&material.name),
            layout: &self.pass.material_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&self.pass.sampler) },
            ],
        })
    }
}

/// A content key for a species' baked billboards: geometry, textures, HLPs and bake settings.
fn bake_key(model: &PlantModel, hlp_radius: f32) -> String {
    // v2: foliage is baked with the leaf shape maps of its textures.
    let mut key = KeyBuilder::default().bytes(b"billboards v2").u64(hlp::model_hash(model)).f32(hlp_radius);
    key = key.u64(u64::from(BILLBOARD_TILE));
    for part in &model.parts {
        let m = &part.material;
        key = m.base_color.iter().fold(key, |k, c| k.f32(*c)).f32(m.alpha_cutoff.unwrap_or(-1.0));
        for uv in &part.mesh.uvs {
            key = key.f32(uv[0]).f32(uv[1]);
        }
        if let Some(texture) = &m.texture {
            key = key.u64(u64::from(texture.width())).bytes(texture.as_raw());
        }
    }
    key.finish()
}

fn encode_png(image: &image::RgbaImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    // Encoding an in-memory RGBA image to PNG cannot fail; an empty entry is recomputed.
    let _ = image.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png);
    bytes
}

fn decode_png(bytes: &[u8], size: (u32, u32)) -> Option<image::RgbaImage> {
    let image = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).ok()?.to_rgba8();
    (image.dimensions() == size).then_some(image)
}

impl SceneGpu {
    /// Uploads the terrain, every species' model at all levels of detail (baking billboard
    /// atlases, or loading them from `disk`) and the plant instances of `scene`.
    pub fn new(
        gpu: &Gpu,
        pass: &GeometryPass,
        scene: &Scene,
        disk: Option<&DiskCache>,
    ) -> Result<SceneGpu, RenderError> {
        let (device, queue) = (&gpu.device, &gpu.queue);
        let white = upload_texture(device, queue, &image::RgbaImage::from_pixel(1, 1, image::Rgba([255; 4])));
        let mut up = Uploader { device, queue, pass, textures: HashMap::new(), white, bytes: 0, disk };
        let [r, g, b] = scene.terrain.albedo;
        let terrain_material = Material {
            name: "terrain".into(),
            base_color: [r, g, b, 1.0],
            texture: None,
            alpha_cutoff: None,
            double_sided: false,
        };
        let terrain_lod = TerrainLod::build(&scene.terrain, TERRAIN_CHUNK_CELLS, TERRAIN_LEVELS);
        let terrain = up.mesh(&terrain_lod.mesh, None, &terrain_material, Surface::Terrain);
        let baker = Baker::new(device, &pass.material_layout);
        let mut species = Vec::with_capacity(scene.species.len());
        let mut plant_boards = Vec::with_capacity(scene.species.len());
        for s in &scene.species {
            let hlps = hlp::cluster_cached(&s.model, s.hlp_radius, disk);
            let board = Billboard::of_model(&s.model);
            species.push(Self::upload_species(gpu, &mut up, &baker, &s.model, s.hlp_radius, &hlps, board, disk)?);
            plant_boards.push((hlps, board));
        }

        let mut plants = Vec::with_capacity(scene.plant_count());
        for (layer_index, layer) in scene.layers.iter().enumerate() {
            for (i, plant) in layer.plants.iter().enumerate() {
                let [x, y, z] = plant.position;
                let instance = Instance {
                    offset_scale: [x, y, z, plant.scale],
                    rotation: [plant.rotation.cos(), plant.rotation.sin()],
                    object_id: object_id(LayerCode::vegetation(layer_index), i as u32),
                    reference_base: 0,
                    mask: [0.0, 1.0],
                    data_abstraction: [0.0; 2],
                    reference_sphere: [0.0; 4],
                };
                plants.push(Plant { species: plant.species, instance, cell: 0 });
            }
        }
        plants.sort_by_key(|p| p.species);
        let cells = reference_grid(&mut plants, &species, REFERENCE_GRID_SPACING);
        let source_triangles = scene.terrain.mesh.triangle_count() as u64
            + plants.iter().map(|p| species[p.species].triangles[LodLevel::Full.index()]).sum::<u64>();
        info!(
            species = species.len(),
            plants = plants.len(),
            hlps = plant_boards.iter().map(|(hlps, _)| hlps.spheres.len()).sum::<usize>(),
            source_triangles,
            "scene uploaded"
        );
        // Meshes and textures, and at most every plant twice per frame (the reference buffer
        // grows with what a frame draws; it is not counted).
        let gpu_bytes = up.bytes + 2 * (plants.len() as u64 + 1) * std::mem::size_of::<Instance>() as u64;
        let instance_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("instances"),
            size: (2 * plants.len() as u64 + 1) * std::mem::size_of::<Instance>() as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(SceneGpu {
            terrain,
            terrain_cell: terrain_lod.cell_size(),
            terrain_chunks: terrain_lod.chunks,
            species,
            plants,
            source_triangles,
            cells,
            instance_buffer,
            reference_buffer: std::sync::Mutex::new(reference_buffer(device, 1)),
            gpu_bytes,
        })
    }

    /// Uploads one species at every level of detail; bakes (or loads) its billboard atlas.
    #[allow(clippy::too_many_arguments)]
    fn upload_species(
        gpu: &Gpu,
        up: &mut Uploader<'_>,
        baker: &Baker,
        model: &PlantModel,
        hlp_radius: f32,
        hlps: &Hlps,
        plant_board: Billboard,
        disk: Option<&DiskCache>,
    ) -> Result<SpeciesGpu, RenderError> {
        let spheres = hlps.spheres.as_slice();
        // Level 0: the model, foliage split and sorted by HLP so each HLP can be baked alone.
        let mut full = Vec::new();
        let mut hlp_ranges = Vec::new();
        // The implicit-surface illumination of the foliage (Luft et al. 2007), per original vertex.
        let lighting = implicit::illuminate_cached(model, &ImplicitParams::default(), up.disk);
        for ((part, triangle_hlp), lit) in model.parts.iter().zip(&hlps.triangle_hlp).zip(&lighting.normals) {
            match part.kind {
                PartKind::Foliage => {
                    let mut split = hlp::split_by_hlp(&part.mesh, triangle_hlp);
                    let ranges = hlp::sort_by_hlp(&mut split, spheres.len());
                    let lit: Vec<[f32; 3]> = split.source.iter().map(|&v| lit[v as usize]).collect();
                    let hlp = Some((split.hlp.as_slice(), spheres));
                    full.push(up.lit_mesh(&split.mesh, hlp, &lit, &part.material, Surface::Foliage));
                    hlp_ranges.push(Some(ranges));
                }
                PartKind::Wood => {
                    full.push(up.mesh(&part.mesh, None, &part.material, Surface::Wood));
                    hlp_ranges.push(None);
                }
            }
        }
        // Leaf particles (SPEC R1, R2, P4): each foliage part's leaves as quads in one shuffled
        // order, drawn with the wood of the full model.
        let order = leaves::shuffled(leaves::split(model, hlps), leaves::LEAF_ORDER_SEED);
        let mut particles = Particles {
            wood: Vec::new(),
            leaves: Vec::new(),
            count: order.len(),
            triangles: [0; PARTICLE_SHARES.len()],
        };
        for (index, part) in model.parts.iter().enumerate() {
            if part.kind == PartKind::Wood {
                particles.wood.push(index);
                particles.triangles = particles.triangles.map(|t| t + part.mesh.triangle_count() as u64);
                continue;
            }
            let own: Vec<Leaf> = order.iter().filter(|leaf| leaf.part == index).copied().collect();
            if !own.is_empty() {
                let lit = lighting.normals.get(index).map_or(&[][..], Vec::as_slice);
                let gpu_leaves = up.particles(&own, spheres, lit, &part.material);
                for (t, count) in particles.triangles.iter_mut().zip(gpu_leaves.counts) {
                    *t += u64::from(count / 3);
                }
                particles.leaves.push(gpu_leaves);
            }
        }
        // Atlas tiles: three views per HLP, then three for the whole plant.
        let boards: Vec<Billboard> = spheres.iter().map(Billboard::of_sphere).collect();
        let atlas = Atlas::new(3 * (boards.len() + 1), BILLBOARD_TILE);
        let bake = || {
            let mut tiles = Vec::with_capacity(3 * (boards.len() + 1));
            for (h, board) in boards.iter().enumerate() {
                for view in 0..3 {
                    let draws = full
                        .iter()
                        .zip(&hlp_ranges)
                        .filter_map(|(mesh, ranges)| {
                            let range = ranges.as_ref()?.get(h)?.clone();
                            (!range.is_empty()).then_some(BakeDraw {
                                vertices: &mesh.vertices,
                                indices: &mesh.indices,
                                range,
                                material: &mesh.material,
                            })
                        })
                        .collect();
                    tiles.push(BakeTile { matrix: board.bake_matrix(view), draws });
                }
            }
            for view in 0..3 {
                let draws = full
                    .iter()
                    .map(|mesh| BakeDraw {
                        vertices: &mesh.vertices,
                        indices: &mesh.indices,
                        range: 0..mesh.index_count,
                        material: &mesh.material,
                    })
                    .collect();
                tiles.push(BakeTile { matrix: plant_board.bake_matrix(view), draws });
            }
            baker.bake(gpu, &atlas, &tiles)
        };
        let image = match disk {
            Some(disk) => {
                let mut failure = None;
                let image = disk.get_or_compute(
                    "billboards",
                    &bake_key(model, hlp_radius),
                    |bytes| decode_png(bytes, atlas.size()),
                    encode_png,
                    || {
                        bake().unwrap_or_else(|e| {
                            failure = Some(e);
                            image::RgbaImage::new(1, 1)
                        })
                    },
                );
                if let Some(error) = failure {
                    return Err(error);
                }
                image
            }
            None => bake()?,
        };
        let billboard_material = Material {
            name: format!("{} billboards", model.name),
            base_color: [1.0; 4],
            texture: Some(Arc::new(image)),
            alpha_cutoff: Some(BILLBOARD_ALPHA_CUTOFF),
            double_sided: true,
        };
        // Billboards carry the mean k_a of the leaves they stand for (only the length of their
        // implicit attribute counts: they are lit as their HLP sphere), so ambient occlusion
        // does not pop between levels of detail.
        let (hlp_ka, plant_ka) = lighting.hlp_ambient(model, hlps);
        // Level 1: the HLP billboard cloud and the trunk prism.
        let (hlp_mesh, owners) = lod::billboard_mesh(&boards, &atlas, 0);
        let lit: Vec<[f32; 3]> = owners.iter().map(|&h| [0.0, 0.0, hlp_ka[h as usize]]).collect();
        let mut hlp_level =
            vec![up.lit_mesh(&hlp_mesh, Some((&owners, spheres)), &lit, &billboard_material, Surface::Billboard)];
        let mut hlp_triangles = hlp_mesh.triangle_count() as u64;
        if let Some((trunk, part)) = lod::trunk_cylinder(model, TRUNK_SIDES) {
            hlp_triangles += trunk.triangle_count() as u64;
            hlp_level.push(up.mesh(&trunk, None, &model.parts[part].material, Surface::Wood));
        }
        // Level 2: one billboard for the plant, its one sphere the plant's reference point.
        let (plant_mesh, plant_owner) = lod::billboard_mesh(&[plant_board], &atlas, 3 * boards.len());
        let board = Sphere { center: plant_board.center, radius: plant_board.radius };
        let lit = vec![[0.0, 0.0, plant_ka]; plant_mesh.positions.len()];
        let plant_owner = Some((plant_owner.as_slice(), std::slice::from_ref(&board)));
        let plant_level = vec![up.lit_mesh(&plant_mesh, plant_owner, &lit, &billboard_material, Surface::Billboard)];
        let (lo, hi) = model.bounds();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        Ok(SpeciesGpu {
            levels: [full, hlp_level, plant_level],
            particles,
            triangles: [model.triangle_count() as u64, hlp_triangles, plant_mesh.triangle_count() as u64],
            bounds: Sphere { center: (lo + hi) * 0.5, radius: (hi - lo).length() * 0.5 },
            height: hi.z - lo.z,
            spheres: spheres.to_vec(),
            board,
        })
    }

    /// The world-space centre of a reference point.
    pub fn reference_center(&self, key: RefKey) -> Vec3 {
        match key {
            RefKey::Hlp(plant, hlp) => {
                let plant = &self.plants[plant as usize];
                plant.world(self.species[plant.species].spheres[hlp as usize].center)
            }
            RefKey::Plant(plant) => {
                let plant = &self.plants[plant as usize];
                plant.world(self.species[plant.species].board.center)
            }
            RefKey::Cell(cell) => self.cells[cell as usize].center,
        }
    }

    /// The next coarser reference point (thesis 7.3): the plant of an HLP, the grid cell of a
    /// plant.
    pub fn reference_parent(&self, key: RefKey) -> Option<RefKey> {
        match key {
            RefKey::Hlp(plant, _) => Some(RefKey::Plant(plant)),
            RefKey::Plant(plant) => Some(RefKey::Cell(self.plants[plant as usize].cell)),
            RefKey::Cell(_) => None,
        }
    }

    /// Estimated GPU memory of the scene in bytes (see [`super::Renderer::gpu_bytes`]).
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }

    /// Triangles of the whole scene at full detail.
    pub fn source_triangles(&self) -> u64 {
        self.source_triangles
    }

    /// Culls the plants against the view frustum of `camera` (for a `width` × `height` image),
    /// leaves out the plants of hidden layers, picks each visible plant's level(s) of detail,
    /// and for plants at full detail whose layer draws leaf particles, the share of their
    /// leaves (SPEC P4); `layer` tells how the layer of an object ID is drawn, `abstraction`
    /// gives a data layer's HLP abstraction and its weight at a plant's scene position (see
    /// [`Instance::data_abstraction`]). [`SceneGpu::upload`] then writes the instance list to
    /// the GPU.
    pub fn cull(
        &self,
        camera: &Camera,
        (width, height): (u32, u32),
        lod: &LodSettings,
        layer: impl Fn(u32) -> LayerDraw,
        abstraction: impl Fn(f32, f32) -> [f32; 2],
    ) -> VisibleSet {
        let aspect = width as f32 / height as f32;
        let planes = frustum_planes(camera.projection(aspect) * camera.view());
        let eye = Vec3::from(camera.position);
        let forward = camera.forward();
        // Pixels per metre at unit depth (perspective) or everywhere (plan view).
        let plan = camera.plan_metres_per_pixel(width);
        let px_per_metre = height as f32 / (2.0 * (camera.fov.to_radians() * 0.5).tan());
        // One run per species, level (or particle share) and style slot: a draw binds its
        // slot's layer style once (per-pixel lookups of it cost more than the shading).
        let mut runs: Vec<Vec<Instance>> = vec![Vec::new(); self.species.len() * 3 * STYLE_SLOTS];
        let mut particle_runs: Vec<Vec<Instance>> =
            vec![Vec::new(); self.species.len() * PARTICLE_SHARES.len() * STYLE_SLOTS];
        let mut stats = DrawStats { plants: self.plants.len() as u64, ..DrawStats::default() };
        let mut references = References::default();
        for (index, plant) in self.plants.iter().enumerate() {
            let s = &self.species[plant.species];
            let i = &plant.instance;
            let drawn_as = layer(i.object_id);
            let slot = LayerCode::of_object_id(i.object_id).slot();
            if !drawn_as.visible {
                continue;
            }
            let center = plant.world(s.bounds.center);
            let radius = s.bounds.radius * i.offset_scale[3];
            if planes.iter().any(|p| p.truncate().dot(center) + p.w < -radius) {
                continue;
            }
            let px = match plan {
                // Seen from above, the crown's extent matters, not the height.
                Some(m) => 2.0 * radius / m,
                None => {
                    let depth = (center - eye).dot(forward).max(radius * 0.5).max(1e-3);
                    s.height * i.offset_scale[3] * px_per_metre / depth
                }
            };
            let draws = lod.select(px);
            if draws[0].is_none() {
                continue;
            }
            stats.plants_drawn += 1;
            let data_abstraction = abstraction(i.offset_scale[0], i.offset_scale[1]);
            for draw in draws.into_iter().flatten() {
                stats.per_level[draw.level.index()] += 1;
                // Leaf particles: the share of the leaves falls with the plant's size (SPEC P4).
                let share = (drawn_as.particles && draw.level == LodLevel::Full)
                    .then(|| leaves::particle_bucket(px, s.particles.count));
                stats.triangles += share.map_or(s.triangles[draw.level.index()], |b| s.particles.triangles[b]);
                let (reference_base, reference_sphere) = match draw.level {
                    LodLevel::Full | LodLevel::Hlp => (references.hlps(index as u32, s.spheres.len()), [0.0; 4]),
                    LodLevel::Plant if px < lod.grid_px => {
                        let cell = self.cells[plant.cell as usize];
                        let [x, y, z] = cell.center.to_array();
                        (references.point(RefKey::Cell(plant.cell)), [x, y, z, cell.radius])
                    }
                    LodLevel::Plant => (references.point(RefKey::Plant(index as u32)), [0.0; 4]),
                };
                let instance = Instance { mask: draw.mask, reference_base, reference_sphere, data_abstraction, ..*i };
                match share {
                    Some(b) => {
                        particle_runs[(plant.species * PARTICLE_SHARES.len() + b) * STYLE_SLOTS + slot].push(instance)
                    }
                    None => runs[(plant.species * 3 + draw.level.index()) * STYLE_SLOTS + slot].push(instance),
                }
            }
        }
        let terrain = Instance {
            offset_scale: [0.0, 0.0, 0.0, 1.0],
            rotation: [1.0, 0.0],
            object_id: object_id(LayerCode::TERRAIN, 0),
            reference_base: 0,
            mask: [0.0, 1.0],
            data_abstraction: [0.0; 2],
            reference_sphere: [0.0; 4],
        };
        // Terrain chunks: culled like plants, their level from the projected size of a cell
        // at the chunk's nearest point.
        let mut terrain_ranges = Vec::new();
        for chunk in &self.terrain_chunks {
            if planes.iter().any(|p| p.truncate().dot(chunk.center) + p.w < -chunk.radius) {
                continue;
            }
            let cell_px = match plan {
                Some(m) => self.terrain_cell / m,
                None => self.terrain_cell * px_per_metre / ((chunk.center - eye).length() - chunk.radius).max(1e-3),
            };
            let range = chunk.levels[chunk.level_for(cell_px, TERRAIN_CELL_PX)].clone();
            stats.triangles += u64::from((range.end - range.start) / 3);
            terrain_ranges.push(range);
        }
        stats.source_triangles = self.source_triangles;
        // Front to back within each run, so the depth test rejects hidden fragments early.
        let distance = |i: &Instance| eye.distance_squared(Vec3::from_slice(&i.offset_scale[..3]));
        for run in runs.iter_mut().chain(particle_runs.iter_mut()) {
            run.sort_unstable_by(|a, b| distance(a).total_cmp(&distance(b)));
        }
        let mut instances = vec![terrain];
        let batches = append_runs(&mut instances, runs)
            .into_iter()
            .map(|(run, range)| {
                let (kind, slot) = (run / STYLE_SLOTS, run % STYLE_SLOTS);
                (kind / 3, LodLevel::ALL[kind % 3], slot, range)
            })
            .collect();
        let shares = PARTICLE_SHARES.len();
        let particle_batches = append_runs(&mut instances, particle_runs)
            .into_iter()
            .map(|(run, range)| {
                let (kind, slot) = (run / STYLE_SLOTS, run % STYLE_SLOTS);
                (kind / shares, kind % shares, slot, range)
            })
            .collect();
        stats.reference_points = references.keys.len() as u64;
        VisibleSet { instances, batches, particle_batches, terrain_ranges, references: references.keys, stats }
    }

    /// Writes the instance list of `visible` and the coordinates of its reference points
    /// (`uvs`, in [`VisibleSet::references`] order; `None`: all zero, a frame without
    /// history) to the buffers every frame reuses (one frame at a time: the caller serialises
    /// frames). Returns the reference buffer to bind.
    pub fn upload(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        visible: &VisibleSet,
        uvs: Option<&[Vec2]>,
    ) -> wgpu::Buffer {
        queue.write_buffer(&self.instance_buffer, 0, bytemuck::cast_slice(&visible.instances));
        let count = visible.references.len().max(1);
        let mut buffer = self.reference_buffer.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if buffer.size() < 8 * count as u64 {
            *buffer = reference_buffer(device, count.next_power_of_two());
        }
        match uvs {
            Some(uvs) => queue.write_buffer(&buffer, 0, bytemuck::cast_slice(uvs)),
            None => queue.write_buffer(&buffer, 0, &vec![0u8; 8 * count]),
        }
        buffer.clone()
    }

    /// Records the draws of the terrain and every visible instance run, each mesh with the
    /// `geometry` pipeline of its surface; plants drawn with leaf particles last, their leaves
    /// with the leaf pipeline. Each draw binds `frame` (group 0) at the layer-style offset of
    /// its style slot.
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        visible: &VisibleSet,
        frame: &wgpu::BindGroup,
        geometry: &GeometryPass,
    ) {
        let bytes = std::mem::size_of_val(visible.instances.as_slice()) as u64;
        let layer_offset = |slot: usize| [(slot as u64 * LAYER_STRIDE) as u32];
        pass.set_vertex_buffer(1, self.instance_buffer.slice(..bytes));
        pass.set_bind_group(0, frame, &layer_offset(LayerCode::TERRAIN.slot()));
        pass.set_pipeline(geometry.pipeline(Surface::Terrain));
        pass.set_bind_group(1, &self.terrain.material, &[]);
        pass.set_vertex_buffer(0, self.terrain.vertices.slice(..));
        pass.set_index_buffer(self.terrain.indices.slice(..), wgpu::IndexFormat::Uint32);
        for range in &visible.terrain_ranges {
            pass.draw_indexed(range.clone(), 0, 0..1);
        }
        let draw = |pass: &mut wgpu::RenderPass<'_>, mesh: &GpuMesh, instances: Range<u32>| {
            pass.set_pipeline(geometry.pipeline(mesh.surface));
            pass.set_bind_group(1, &mesh.material, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, instances);
        };
        for (species, level, slot, instances) in &visible.batches {
            pass.set_bind_group(0, frame, &layer_offset(*slot));
            for mesh in &self.species[*species].levels[level.index()] {
                draw(pass, mesh, instances.clone());
            }
        }
        for (species, _, slot, instances) in &visible.particle_batches {
            pass.set_bind_group(0, frame, &layer_offset(*slot));
            let s = &self.species[*species];
            for &wood in &s.particles.wood {
                draw(pass, &s.levels[LodLevel::Full.index()][wood], instances.clone());
            }
        }
        if visible.particle_batches.is_empty() {
            return;
        }
        pass.set_pipeline(&geometry.leaf_pipeline);
        for (species, share, slot, instances) in &visible.particle_batches {
            pass.set_bind_group(0, frame, &layer_offset(*slot));
            for leaves in &self.species[*species].particles.leaves {
                pass.set_bind_group(1, &leaves.materials[*share], &[]);
                pass.set_vertex_buffer(0, leaves.vertices.slice(..));
                pass.set_index_buffer(leaves.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..leaves.counts[*share], 0, instances.clone());
            }
        }
    }
}

/// Appends the non-empty `runs` to `instances`; returns each one's index and instance range.
fn append_runs(instances: &mut Vec<Instance>, runs: Vec<Vec<Instance>>) -> Vec<(usize, Range<u32>)> {
    let mut ranges = Vec::new();
    for (index, run) in runs.into_iter().enumerate() {
        if run.is_empty() {
            continue;
        }
        let start = instances.len() as u32;
        instances.extend(run);
        ranges.push((index, start..instances.len() as u32));
    }
    ranges
}

/// The reference points of a frame as [`SceneGpu::cull`] collects them: each plant's HLPs as
/// one run, plants and grid cells once each.
#[derive(Default)]
struct References {
    keys: Vec<RefKey>,
    index: HashMap<RefKey, u32>,
}

impl References {
    /// The entry of a single reference point, added on first use.
    fn point(&mut self, key: RefKey) -> u32 {
        let next = self.keys.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.keys.push(key);
            next
        })
    }

    /// The first entry of the `count` HLPs of `plant`, added as one run on first use (a plant
    /// in a blend band draws two levels with the same HLPs).
    fn hlps(&mut self, plant: u32, count: usize) -> u32 {
        let first = self.keys.len() as u32;
        *self.index.entry(RefKey::Hlp(plant, 0)).or_insert_with(|| {
            self.keys.extend((0..count as u32).map(|h| RefKey::Hlp(plant, h)));
            first
        })
    }
}

/// A storage buffer for `count` reference coordinates.
fn reference_buffer(device: &wgpu::Device, count: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("references"),
        size: 8 * count as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The far reference points of thesis 7.3: an evenly spaced grid of `spacing` metres over the
/// ground the plants stand on. Each cell holding plants gets one sphere, centred on the mean
/// foliage centre of its plants (so it lies inside the vegetation, as the thesis asks) and
/// reaching over the cell; sets every plant's `cell`.
fn reference_grid(plants: &mut [Plant], species: &[SpeciesGpu], spacing: f32) -> Vec<Sphere> {
    let mut cells: HashMap<(i64, i64), (u32, Vec3, u32)> = HashMap::new();
    for plant in plants.iter_mut() {
        let [x, y, ..] = plant.instance.offset_scale;
        let key = ((x / spacing).floor() as i64, (y / spacing).floor() as i64);
        let next = cells.len() as u32;
        let cell = cells.entry(key).or_insert((next, Vec3::ZERO, 0));
        cell.1 += plant.world(species[plant.species].board.center);
        cell.2 += 1;
        plant.cell = cell.0;
    }
    let mut spheres = vec![Sphere { center: Vec3::ZERO, radius: 0.0 }; cells.len()];
    for (index, sum, count) in cells.into_values() {
        spheres[index as usize] =
            Sphere { center: sum / count as f32, radius: spacing * std::f32::consts::FRAC_1_SQRT_2 };
    }
    spheres
}

/// The side planes of a view frustum (left, right, bottom, top, near) from a world → clip
/// matrix with wgpu's clip volume (−w ≤ x, y ≤ w, 0 ≤ z ≤ w), each as (n, d) with the inside
/// where n·p + d ≥ 0 and |n| = 1. The far plane is omitted (the projection has none).
pub fn frustum_planes(view_proj: glam::Mat4) -> [glam::Vec4; 5] {
    let m = view_proj.transpose();
    let (r0, r1, r2, r3) = (m.x_axis, m.y_axis, m.z_axis, m.w_axis);
    [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 - r2].map(|p| p / p.truncate().length().max(1e-12))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frustum_planes_contain_what_the_camera_sees() {
        let camera = Camera::perspective([0.0, 0.0, 2.0], 0.0, 0.0, 60.0);
        let planes = frustum_planes(camera.projection(1.0) * camera.view());
        let inside = |p: Vec3, r: f32| planes.iter().all(|q| q.truncate().dot(p) + q.w >= -r);
        assert!(inside(Vec3::new(0.0, 50.0, 2.0), 0.0), "straight ahead");
        assert!(inside(Vec3::new(0.0, 1.0e5, 2.0), 0.0), "far ahead: no far plane");
        assert!(!inside(Vec3::new(0.0, -10.0, 2.0), 1.0), "behind");
        assert!(!inside(Vec3::new(40.0, 50.0, 2.0), 1.0), "right of the 60° cone");
        assert!(inside(Vec3::new(40.0, 50.0, 2.0), 20.0), "a large sphere reaching in");
    }
}
