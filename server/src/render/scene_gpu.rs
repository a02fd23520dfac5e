//! GPU-side copy of a scene: vertex/index buffers per mesh and level of detail, textures,
//! baked billboard atlases and material bind groups, all built once per scene. Each frame only
//! culls the plant instances against the view frustum, picks every visible plant's level of
//! detail from its projected size (`prep::lod`) and uploads the resulting instance list.

use super::bake::{BakeDraw, BakeTile, Baker};
use super::gbuffer::{
    GeometryPass, Instance, MaterialUniform, NO_HLP, TERRAIN_LAYER_CODE, Vertex, average_color, object_id,
};
use super::{Gpu, RenderError};
use crate::prep::cache::{DiskCache, KeyBuilder};
use crate::prep::hlp::{self, Hlps, Sphere};
use crate::prep::lod::{self, Atlas, Billboard, LodLevel, LodSettings};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{Material, PartKind, PlantModel};
use glam::Vec3;
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

/// One uploaded mesh with its material.
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    material: wgpu::BindGroup,
}

/// What a surface is, as the G-buffer pass distinguishes it (`Material.params.y` in
/// `shaders/gbuffer.wgsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Surface {
    Terrain = 0,
    Wood = 1,
    Foliage = 2,
    /// A billboard of an HLP or a whole plant: shaded as its HLP sphere.
    Billboard = 3,
}

impl From<PartKind> for Surface {
    fn from(kind: PartKind) -> Surface {
        match kind {
            PartKind::Wood => Surface::Wood,
            PartKind::Foliage => Surface::Foliage,
        }
    }
}

/// One species on the GPU: its meshes at every level of detail.
struct SpeciesGpu {
    levels: [Vec<GpuMesh>; 3],
    triangles: [u64; 3],
    /// Bounding sphere of the model (model space), for culling.
    bounds: Sphere,
    /// Height of the model, for its projected size.
    height: f32,
}

/// One plant: its species and its instance data.
#[derive(Clone, Copy)]
struct Plant {
    species: usize,
    instance: Instance,
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
}

impl DrawStats {
    /// Submitted triangles as a percentage of the source geometry (the seeds' "% lod").
    pub fn percent_drawn(&self) -> f64 {
        100.0 * self.triangles as f64 / self.source_triangles.max(1) as f64
    }
}

/// The plants one frame draws: its instance list in (species, level) runs.
pub struct VisibleSet {
    instances: Vec<Instance>,
    batches: Vec<(usize, LodLevel, Range<u32>)>,
    pub stats: DrawStats,
}

/// Everything the geometry pass draws, resident on the GPU.
pub struct SceneGpu {
    terrain: GpuMesh,
    species: Vec<SpeciesGpu>,
    plants: Vec<Plant>,
    source_triangles: u64,
    /// World-space centre of every (instance, HLP) pair, in reference-buffer order; each
    /// plant's HLPs are followed by one entry for the whole plant (its far level of detail).
    reference_centers: Vec<Vec3>,
    /// All-zero reference coordinates for stateless frames.
    zero_references: wgpu::Buffer,
    /// The instances of a frame: room for every plant at two levels, and the terrain.
    instance_buffer: wgpu::Buffer,
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
                }
            })
            .collect();
        self.bytes += (std::mem::size_of_val(vertices.as_slice()) + 4 * mesh.indices.len()) as u64;
        let vertices = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&mesh.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let uniform = MaterialUniform {
            base_color: material.base_color,
            params: [material.alpha_cutoff.unwrap_or(-1.0), surface as u32 as f32, 0.0, 0.0],
            average_color: average_color(material),
        };
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = match &material.texture {
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
        let material = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&material.name),
            layout: &self.pass.material_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&self.pass.sampler) },
            ],
        });
        GpuMesh { vertices, indices, index_count: mesh.indices.len() as u32, material }
    }
}

/// A content key for a species' baked billboards: geometry, textures, HLPs and bake settings.
fn bake_key(model: &PlantModel, hlp_radius: f32) -> String {
    let mut key = KeyBuilder::default().bytes(b"billboards v1").u64(hlp::model_hash(model)).f32(hlp_radius);
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
        let mut up = Uploader { device, queue, pass, textures: HashMap::new(), white, bytes: 0 };
        let [r, g, b] = scene.terrain.albedo;
        let terrain_material = Material {
            name: "terrain".into(),
            base_color: [r, g, b, 1.0],
            texture: None,
            alpha_cutoff: None,
            double_sided: false,
        };
        let terrain = up.mesh(&scene.terrain.mesh, None, &terrain_material, Surface::Terrain);
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
        let mut reference_centers = Vec::new();
        for (layer_index, layer) in scene.layers.iter().enumerate() {
            for (i, plant) in layer.plants.iter().enumerate() {
                let [x, y, z] = plant.position;
                let rotation = glam::Quat::from_rotation_z(plant.rotation);
                let offset = Vec3::new(x, y, z);
                let (hlps, board) = &plant_boards[plant.species];
                let instance = Instance {
                    offset_scale: [x, y, z, plant.scale],
                    rotation: [plant.rotation.cos(), plant.rotation.sin()],
                    object_id: object_id(layer_index as u32 + 2, i as u32),
                    reference_base: reference_centers.len() as u32,
                    mask: [0.0, 1.0],
                };
                let world = |c: Vec3| offset + rotation * (c * plant.scale);
                reference_centers.extend(hlps.spheres.iter().map(|s| world(s.center)));
                reference_centers.push(world(board.center));
                plants.push(Plant { species: plant.species, instance });
            }
        }
        plants.sort_by_key(|p| p.species);
        let source_triangles = scene.terrain.mesh.triangle_count() as u64
            + plants.iter().map(|p| species[p.species].triangles[LodLevel::Full.index()]).sum::<u64>();
        let zero_references = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zero references"),
            contents: &vec![0u8; 8 * reference_centers.len().max(1)],
            usage: wgpu::BufferUsages::STORAGE,
        });
        info!(
            species = species.len(),
            plants = plants.len(),
            hlps = plant_boards.iter().map(|(hlps, _)| hlps.spheres.len()).sum::<usize>(),
            source_triangles,
            "scene uploaded"
        );
        // Meshes and textures, the zero references, and at most every plant twice per frame.
        let gpu_bytes = up.bytes
            + 8 * reference_centers.len() as u64
            + 2 * (plants.len() as u64 + 1) * std::mem::size_of::<Instance>() as u64;
        let instance_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("instances"),
            size: (2 * plants.len() as u64 + 1) * std::mem::size_of::<Instance>() as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(SceneGpu {
            terrain,
            species,
            plants,
            source_triangles,
            reference_centers,
            zero_references,
            instance_buffer,
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
        for (part, triangle_hlp) in model.parts.iter().zip(&hlps.triangle_hlp) {
            match part.kind {
                PartKind::Foliage => {
                    let mut split = hlp::split_by_hlp(&part.mesh, triangle_hlp);
                    let ranges = hlp::sort_by_hlp(&mut split, spheres.len());
                    full.push(up.mesh(&split.mesh, Some((&split.hlp, spheres)), &part.material, Surface::Foliage));
                    hlp_ranges.push(Some(ranges));
                }
                PartKind::Wood => {
                    full.push(up.mesh(&part.mesh, None, &part.material, Surface::Wood));
                    hlp_ranges.push(None);
                }
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
        // Level 1: the HLP billboard cloud and the trunk prism.
        let (hlp_mesh, owners) = lod::billboard_mesh(&boards, &atlas, 0);
        let mut hlp_level = vec![up.mesh(&hlp_mesh, Some((&owners, spheres)), &billboard_material, Surface::Billboard)];
        let mut hlp_triangles = hlp_mesh.triangle_count() as u64;
        if let Some((trunk, part)) = lod::trunk_cylinder(model, TRUNK_SIDES) {
            hlp_triangles += trunk.triangle_count() as u64;
            hlp_level.push(up.mesh(&trunk, None, &model.parts[part].material, Surface::Wood));
        }
        // Level 2: one billboard for the plant, indexing the reference entry after the HLPs.
        let (plant_mesh, plant_owner) = lod::billboard_mesh(&[plant_board], &atlas, 3 * boards.len());
        let plant_sphere = [Sphere { center: plant_board.center, radius: plant_board.radius }];
        let plant_index = vec![spheres.len() as u32; plant_owner.len()];
        let mut indexed_spheres = spheres.to_vec();
        indexed_spheres.extend(plant_sphere);
        let plant_level =
            vec![up.mesh(&plant_mesh, Some((&plant_index, &indexed_spheres)), &billboard_material, Surface::Billboard)];
        let (lo, hi) = model.bounds();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        Ok(SpeciesGpu {
            levels: [full, hlp_level, plant_level],
            triangles: [model.triangle_count() as u64, hlp_triangles, plant_mesh.triangle_count() as u64],
            bounds: Sphere { center: (lo + hi) * 0.5, radius: (hi - lo).length() * 0.5 },
            height: hi.z - lo.z,
        })
    }

    /// World-space centres of every (instance, HLP) pair, in the order of the reference buffer.
    pub fn reference_centers(&self) -> &[Vec3] {
        &self.reference_centers
    }

    /// Reference coordinates that are all zero: what a frame without history uses.
    pub fn zero_references(&self) -> &wgpu::Buffer {
        &self.zero_references
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
    /// leaves out the plants whose object ID `shown` refuses (hidden layers), picks each
    /// visible plant's level(s) of detail. [`SceneGpu::upload`] then writes the instance list to
    /// the GPU.
    pub fn cull(
        &self,
        camera: &Camera,
        (width, height): (u32, u32),
        lod: &LodSettings,
        shown: impl Fn(u32) -> bool,
    ) -> VisibleSet {
        let aspect = width as f32 / height as f32;
        let planes = frustum_planes(camera.projection(aspect) * camera.view());
        let eye = Vec3::from(camera.position);
        let forward = camera.forward();
        // Pixels per metre at unit depth (perspective) or everywhere (plan view).
        let plan = camera.plan_metres_per_pixel(width);
        let px_per_metre = height as f32 / (2.0 * (camera.fov.to_radians() * 0.5).tan());
        let mut runs: Vec<Vec<Instance>> = vec![Vec::new(); self.species.len() * 3];
        let mut stats = DrawStats { plants: self.plants.len() as u64, ..DrawStats::default() };
        for plant in &self.plants {
            let s = &self.species[plant.species];
            let i = &plant.instance;
            if !shown(i.object_id) {
                continue;
            }
            let [x, y, z, scale] = i.offset_scale;
            let [c, sn] = i.rotation;
            let local = s.bounds.center * scale;
            let center = Vec3::new(x + c * local.x - sn * local.y, y + sn * local.x + c * local.y, z + local.z);
            let radius = s.bounds.radius * scale;
            if planes.iter().any(|p| p.truncate().dot(center) + p.w < -radius) {
                continue;
            }
            let px = match plan {
                // Seen from above, the crown's extent matters, not the height.
                Some(m) => 2.0 * radius / m,
                None => {
                    let depth = (center - eye).dot(forward).max(radius * 0.5).max(1e-3);
                    s.height * scale * px_per_metre / depth
                }
            };
            let draws = lod.select(px);
            if draws[0].is_some() {
                stats.plants_drawn += 1;
            }
            for draw in draws.into_iter().flatten() {
                stats.per_level[draw.level.index()] += 1;
                stats.triangles += s.triangles[draw.level.index()];
                runs[plant.species * 3 + draw.level.index()].push(Instance { mask: draw.mask, ..*i });
            }
        }
        let terrain = Instance {
            offset_scale: [0.0, 0.0, 0.0, 1.0],
            rotation: [1.0, 0.0],
            object_id: object_id(TERRAIN_LAYER_CODE, 0),
            reference_base: 0,
            mask: [0.0, 1.0],
        };
        stats.triangles += u64::from(self.terrain.index_count / 3);
        stats.source_triangles = self.source_triangles;
        let mut instances = vec![terrain];
        let mut batches = Vec::new();
        for (run_index, run) in runs.into_iter().enumerate() {
            if run.is_empty() {
                continue;
            }
            let start = instances.len() as u32;
            instances.extend(run);
            batches.push((run_index / 3, LodLevel::ALL[run_index % 3], start..instances.len() as u32));
        }
        VisibleSet { instances, batches, stats }
    }

    /// Writes the instance list of `visible` to the instance buffer, which is reused by every
    /// frame (one frame at a time: the caller serialises frames).
    pub fn upload(&self, queue: &wgpu::Queue, visible: &VisibleSet) {
        queue.write_buffer(&self.instance_buffer, 0, bytemuck::cast_slice(&visible.instances));
    }

    /// Records the draws of the terrain and every visible instance run.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, visible: &VisibleSet) {
        let bytes = std::mem::size_of_val(visible.instances.as_slice()) as u64;
        pass.set_vertex_buffer(1, self.instance_buffer.slice(..bytes));
        let mut draw = |mesh: &GpuMesh, instances: Range<u32>| {
            pass.set_bind_group(1, &mesh.material, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, instances);
        };
        draw(&self.terrain, 0..1);
        for (species, level, instances) in &visible.batches {
            for mesh in &self.species[*species].levels[level.index()] {
                draw(mesh, instances.clone());
            }
        }
    }
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
