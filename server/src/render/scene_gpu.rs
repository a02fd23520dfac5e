//! GPU-side copy of a scene: vertex/index buffers per mesh, textures, material bind groups and
//! one instance buffer, all built once per scene and reused by every frame.

use super::gbuffer::{GeometryPass, Instance, MaterialUniform, NO_HLP, TERRAIN_LAYER_CODE, Vertex, object_id};
use crate::prep::hlp::{self, Sphere};
use crate::scene::Scene;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{Material, PartKind};
use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;
use wgpu::util::DeviceExt;

/// One uploaded mesh with its material.
struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    material: wgpu::BindGroup,
}

/// A run of instances of one species in the instance buffer.
struct Batch {
    species: usize,
    instances: Range<u32>,
}

/// Everything the geometry pass draws, resident on the GPU.
pub struct SceneGpu {
    terrain: GpuMesh,
    species: Vec<Vec<GpuMesh>>,
    instances: wgpu::Buffer,
    batches: Vec<Batch>,
    triangles: u64,
    /// World-space centre of every (instance, HLP) pair, in reference-buffer order.
    reference_centers: Vec<glam::Vec3>,
    /// All-zero reference coordinates for stateless frames.
    zero_references: wgpu::Buffer,
}

/// Part kind code stored in the G-buffer normal's w (see `shaders/gbuffer.wgsl`).
fn kind_code(kind: Option<PartKind>) -> f32 {
    match kind {
        None => 0.0,
        Some(PartKind::Wood) => 1.0,
        Some(PartKind::Foliage) => 2.0,
    }
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
}

impl Uploader<'_> {
    /// Uploads a mesh; `hlp` gives the HLP index of every vertex and the spheres they index.
    fn mesh(
        &mut self,
        mesh: &Mesh,
        hlp: Option<(&[u32], &[Sphere])>,
        material: &Material,
        kind: Option<PartKind>,
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
            params: [material.alpha_cutoff.unwrap_or(-1.0), kind_code(kind), 0.0, 0.0],
        };
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let view = match &material.texture {
            Some(image) => {
                let (device, queue) = (self.device, self.queue);
                self.textures.entry(Arc::as_ptr(image)).or_insert_with(|| upload_texture(device, queue, image)).clone()
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

impl SceneGpu {
    /// Uploads the terrain, every species' model and all plant instances of `scene`.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, pass: &GeometryPass, scene: &Scene) -> SceneGpu {
        let white = upload_texture(device, queue, &image::RgbaImage::from_pixel(1, 1, image::Rgba([255; 4])));
        let mut up = Uploader { device, queue, pass, textures: HashMap::new(), white };
        let [r, g, b] = scene.terrain.albedo;
        let terrain_material = Material {
            name: "terrain".into(),
            base_color: [r, g, b, 1.0],
            texture: None,
            alpha_cutoff: None,
            double_sided: false,
        };
        let terrain = up.mesh(&scene.terrain.mesh, None, &terrain_material, None);
        let clusters: Vec<_> = scene.species.iter().map(|s| hlp::cluster_cached(&s.model, s.hlp_radius)).collect();
        let species = scene
            .species
            .iter()
            .zip(&clusters)
            .map(|(s, hlps)| {
                s.model
                    .parts
                    .iter()
                    .zip(&hlps.triangle_hlp)
                    .map(|(part, triangle_hlp)| match part.kind {
                        PartKind::Foliage => {
                            let split = hlp::split_by_hlp(&part.mesh, triangle_hlp);
                            up.mesh(&split.mesh, Some((&split.hlp, &hlps.spheres)), &part.material, Some(part.kind))
                        }
                        PartKind::Wood => up.mesh(&part.mesh, None, &part.material, Some(part.kind)),
                    })
                    .collect()
            })
            .collect();

        let mut instances = vec![Instance {
            offset_scale: [0.0, 0.0, 0.0, 1.0],
            rotation: [1.0, 0.0],
            object_id: object_id(TERRAIN_LAYER_CODE, 0),
            reference_base: 0,
        }];
        let mut reference_centers = Vec::new();
        let mut batches = Vec::new();
        for (layer_index, layer) in scene.layers.iter().enumerate() {
            let mut order: Vec<u32> = (0..layer.plants.len() as u32).collect();
            order.sort_by_key(|&i| layer.plants[i as usize].species);
            for chunk in order.chunk_by(|&a, &b| layer.plants[a as usize].species == layer.plants[b as usize].species) {
                let start = instances.len() as u32;
                for &i in chunk {
                    let plant = &layer.plants[i as usize];
                    let [x, y, z] = plant.position;
                    let rotation = glam::Quat::from_rotation_z(plant.rotation);
                    let offset = glam::Vec3::new(x, y, z);
                    instances.push(Instance {
                        offset_scale: [x, y, z, plant.scale],
                        rotation: [plant.rotation.cos(), plant.rotation.sin()],
                        object_id: object_id(layer_index as u32 + 2, i),
                        reference_base: reference_centers.len() as u32,
                    });
                    reference_centers.extend(
                        clusters[plant.species].spheres.iter().map(|s| offset + rotation * (s.center * plant.scale)),
                    );
                }
                batches.push(Batch {
                    species: layer.plants[chunk[0] as usize].species,
                    instances: start..instances.len() as u32,
                });
            }
        }
        let instance_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("instances"),
            contents: bytemuck::cast_slice(&instances),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let triangles = scene.terrain.mesh.triangle_count() as u64
            + batches
                .iter()
                .map(|b| {
                    u64::from(b.instances.end - b.instances.start)
                        * scene.species[b.species].model.triangle_count() as u64
                })
                .sum::<u64>();
        let zero_references = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zero references"),
            contents: &vec![0u8; 8 * reference_centers.len().max(1)],
            usage: wgpu::BufferUsages::STORAGE,
        });
        SceneGpu {
            terrain,
            species,
            instances: instance_buffer,
            batches,
            triangles,
            reference_centers,
            zero_references,
        }
    }

    /// World-space centres of every (instance, HLP) pair, in the order of the reference buffer.
    pub fn reference_centers(&self) -> &[glam::Vec3] {
        &self.reference_centers
    }

    /// Reference coordinates that are all zero: what a frame without history uses.
    pub fn zero_references(&self) -> &wgpu::Buffer {
        &self.zero_references
    }

    /// Triangles submitted per frame.
    pub fn triangles(&self) -> u64 {
        self.triangles
    }

    /// Records the draws of the terrain and every instance batch.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_vertex_buffer(1, self.instances.slice(..));
        let mut draw = |mesh: &GpuMesh, instances: Range<u32>| {
            pass.set_bind_group(1, &mesh.material, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, instances);
        };
        draw(&self.terrain, 0..1);
        for batch in &self.batches {
            for mesh in &self.species[batch.species] {
                draw(mesh, batch.instances.clone());
            }
        }
    }
}
