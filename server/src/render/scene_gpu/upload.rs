//! Uploads a scene's meshes, leaf particles, textures and materials once, and each frame's
//! instance list and reference coordinates.

use super::bake_cache::{BILLBOARD_TILE, VIEWS, bake_tiles, cached_billboards};
use super::masses::species_color;
use super::{GpuMesh, LeafGpu, Particles, SceneGpu, Shapes, SpeciesGpu, VisibleSet};
use crate::prep::cache::DiskCache;
use crate::prep::hlp::{self, Hlps, Sphere};
use crate::prep::implicit::{self, ImplicitParams};
use crate::prep::leaf_shape::{ShapeParams, shape_map_cached};
use crate::prep::leaves::{self, Leaf, PARTICLE_SHARES};
use crate::prep::lod::{self, Atlas, Billboard};
use crate::prep::substitution;
use crate::render::bake::Baker;
use crate::render::gbuffer::{GeometryPass, LeafVertex, NO_HLP, Surface, SurfaceMaterial, Vertex};
use crate::render::uniforms::{self, Vec3f, Vec4f};
use crate::render::{Gpu, RenderError};
use crate::scene::cover::Drape;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{Material, PartKind, PlantModel};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::sync::Arc;
use wgpu::util::DeviceExt;

/// Sides of the fitted trunk prism.
const TRUNK_SIDES: usize = 6;
/// Alpha below which billboard texels are cut away.
const BILLBOARD_ALPHA_CUTOFF: f32 = 0.35;

impl From<PartKind> for Surface {
    fn from(kind: PartKind) -> Surface {
        match kind {
            PartKind::Wood => Surface::Wood,
            PartKind::Foliage => Surface::Foliage,
        }
    }
}

/// Uploads an sRGB RGBA image with a full mip chain (box-filtered on the CPU).
fn upload_texture(device: &wgpu::Device, queue: &wgpu::Queue, image: &image::RgbaImage) -> wgpu::TextureView {
    let (width, height) = image.dimensions();
    let levels = 32 - width.max(height).max(1).leading_zeros();
    let mut chain = vec![image.clone()];
    for _ in 1..levels {
        let last = &chain[chain.len() - 1];
        let (w, h) = last.dimensions();
        let next = image::imageops::resize(last, (w / 2).max(1), (h / 2).max(1), image::imageops::FilterType::Triangle);
        chain.push(next);
    }
    upload_mip_chain(device, queue, &chain)
}

/// Uploads `chain` (level 0 first, each level half the one before) as one sRGB RGBA texture.
fn upload_mip_chain(device: &wgpu::Device, queue: &wgpu::Queue, chain: &[image::RgbaImage]) -> wgpu::TextureView {
    let (width, height) = chain[0].dimensions();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("material texture"),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: chain.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, image) in chain.iter().enumerate() {
        let (w, h) = image.dimensions();
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: level as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            image,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * w), rows_per_image: Some(h) },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
    }
    texture.create_view(&Default::default())
}

/// Builds GPU resources, sharing textures between materials that use the same image.
pub(super) struct Uploader<'a> {
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

impl<'a> Uploader<'a> {
    /// An uploader of resources for meshes drawn by `pass`, caching leaf shape maps and baked
    /// billboards in `disk`.
    pub(super) fn new(
        device: &'a wgpu::Device,
        queue: &'a wgpu::Queue,
        pass: &'a GeometryPass,
        disk: Option<&'a DiskCache>,
    ) -> Uploader<'a> {
        let white = upload_texture(device, queue, &image::RgbaImage::from_pixel(1, 1, image::Rgba([255; 4])));
        Uploader { device, queue, pass, textures: HashMap::new(), white, bytes: 0, disk }
    }

    /// Bytes of GPU memory uploaded so far.
    pub(super) fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Uploads a mesh; `hlp` gives the HLP index of every vertex and the spheres they index.
    pub(super) fn mesh(
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
        let (vertices, indices) = self.vertex_buffers(mesh, hlp, implicit);
        let material = self.material(material, surface, 1.0);
        GpuMesh { vertices, indices, index_count: mesh.indices.len() as u32, material, surface }
    }

    /// The terrain's mesh with its drape (`scene::cover`) as the texture: colours in rgb, the
    /// land-cover class in alpha, its mip levels filtered by [`Drape::mip_chain`].
    /// A terrain larger than the adapter's largest buffer is an error that says so.
    pub(super) fn terrain(&mut self, mesh: &Mesh, drape: &Drape) -> Result<GpuMesh, RenderError> {
        let limit = self.device.limits().max_buffer_size;
        let vertex_bytes = (mesh.positions.len() * std::mem::size_of::<Vertex>()) as u64;
        let index_bytes = 4 * mesh.indices.len() as u64;
        if vertex_bytes.max(index_bytes) > limit {
            return Err(RenderError::TooLarge {
                what: format!(
                    "the terrain's {} vertices and {} triangles",
                    mesh.positions.len(),
                    mesh.indices.len() / 3
                ),
                bytes: vertex_bytes.max(index_bytes),
                limit,
                hint: "lower `terrain.max_cells` or crop with `terrain.extent` in the scene file",
            });
        }
        let (vertices, indices) = self.vertex_buffers(mesh, None, &[]);
        let chain = drape.mip_chain();
        self.bytes += chain.iter().map(|level| 4 * u64::from(level.width()) * u64::from(level.height())).sum::<u64>();
        let view = upload_mip_chain(self.device, self.queue, &chain);
        let uniform = SurfaceMaterial {
            base_color: Vec4f([1.0; 4]),
            alpha_cutoff: -1.0,
            alpha_min: -1.0,
            particle_scale: 1.0,
            average_color: Vec3f(drape.mean_linear()),
        };
        let material = self.bind_material("terrain", &uniform, &view);
        Ok(GpuMesh { vertices, indices, index_count: mesh.indices.len() as u32, material, surface: Surface::Terrain })
    }

    /// The vertex and index buffers of `mesh` (see [`Uploader::lit_mesh`]).
    fn vertex_buffers(
        &mut self,
        mesh: &Mesh,
        hlp: Option<(&[u32], &[Sphere])>,
        implicit: &[[f32; 3]],
    ) -> (wgpu::Buffer, wgpu::Buffer) {
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
        self.buffers(bytemuck::cast_slice(&vertices), &mesh.indices)
    }

    /// Uploads a vertex and an index buffer.
    pub(super) fn buffers(&mut self, vertices: &[u8], indices: &[u32]) -> (wgpu::Buffer, wgpu::Buffer) {
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
    pub(super) fn material(&mut self, material: &Material, surface: Surface, particle_scale: f32) -> wgpu::BindGroup {
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
        let uniform = SurfaceMaterial::new(material, cutoff, alpha_min, particle_scale);
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
        self.bind_material(&material.name, &uniform, &view)
    }

    /// The bind group of a material: its uniform block, texture and the pass's sampler.
    fn bind_material(&self, label: &str, uniform: &SurfaceMaterial, view: &wgpu::TextureView) -> wgpu::BindGroup {
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material"),
            contents: &uniforms::bytes(uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.pass.material_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(view) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::Sampler(&self.pass.sampler) },
            ],
        })
    }

    /// Uploads one species at every level of detail; bakes (or loads from the disk cache) its
    /// billboard atlas with `baker`.
    pub(super) fn species(
        &mut self,
        gpu: &Gpu,
        baker: &Baker,
        model: &PlantModel,
        hlp_radius: f32,
        hlps: &Hlps,
        plant_board: Billboard,
    ) -> Result<SpeciesGpu, RenderError> {
        let spheres = hlps.spheres.as_slice();
        // Level 0: the model, foliage split and sorted by HLP so each HLP can be baked alone.
        let mut full = Vec::new();
        let mut hlp_ranges = Vec::new();
        // The implicit-surface illumination of the foliage (Luft et al. 2007), per original vertex.
        let lighting = implicit::illuminate_cached(model, &ImplicitParams::default(), self.disk);
        for ((part, triangle_hlp), lit) in model.parts.iter().zip(&hlps.triangle_hlp).zip(&lighting.normals) {
            match part.kind {
                PartKind::Foliage => {
                    let mut split = hlp::split_by_hlp(&part.mesh, triangle_hlp);
                    let ranges = hlp::sort_by_hlp(&mut split, spheres.len());
                    let lit: Vec<[f32; 3]> = split.source.iter().map(|&v| lit[v as usize]).collect();
                    let hlp = Some((split.hlp.as_slice(), spheres));
                    full.push(self.lit_mesh(&split.mesh, hlp, &lit, &part.material, Surface::Foliage));
                    hlp_ranges.push(Some(ranges));
                }
                PartKind::Wood => {
                    full.push(self.mesh(&part.mesh, None, &part.material, Surface::Wood));
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
                let gpu_leaves = self.particles(&own, spheres, lit, &part.material);
                for (t, count) in particles.triangles.iter_mut().zip(gpu_leaves.counts) {
                    *t += u64::from(count / 3);
                }
                particles.leaves.push(gpu_leaves);
            }
        }
        // Atlas tiles: three views per HLP, then three for the whole plant.
        let boards: Vec<Billboard> = spheres.iter().map(Billboard::of_sphere).collect();
        let atlas = Atlas::new(VIEWS * (boards.len() + 1), BILLBOARD_TILE);
        let image = cached_billboards(self.disk, model, hlp_radius, atlas.size(), || {
            baker.bake(gpu, &atlas, &bake_tiles(&full, &hlp_ranges, &boards, plant_board))
        })?;
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
            vec![self.lit_mesh(&hlp_mesh, Some((&owners, spheres)), &lit, &billboard_material, Surface::Billboard)];
        let mut hlp_triangles = hlp_mesh.triangle_count() as u64;
        if let Some((trunk, part)) = lod::trunk_cylinder(model, TRUNK_SIDES) {
            hlp_triangles += trunk.triangle_count() as u64;
            hlp_level.push(self.mesh(&trunk, None, &model.parts[part].material, Surface::Wood));
        }
        // Level 2: one billboard for the plant, its one sphere the plant's reference point.
        let (plant_mesh, plant_owner) = lod::billboard_mesh(&[plant_board], &atlas, VIEWS * boards.len());
        let board = Sphere { center: plant_board.center, radius: plant_board.radius };
        let lit = vec![[0.0, 0.0, plant_ka]; plant_mesh.positions.len()];
        let plant_owner = Some((plant_owner.as_slice(), std::slice::from_ref(&board)));
        let plant_level = vec![self.lit_mesh(&plant_mesh, plant_owner, &lit, &billboard_material, Surface::Billboard)];
        // Substitution shapes (SPEC P5): an ellipsoid per HLP in the foliage's mean colour, lit
        // with its HLP's mean k_a along its own normals (an ambient term, no turn).
        let (shape_mesh, shape_owners) = substitution::shape_mesh(&substitution::fit_shapes(model, hlps));
        let lit: Vec<[f32; 3]> = shape_mesh
            .normals
            .iter()
            .zip(&shape_owners)
            .map(|(n, &h)| (Vec3::from(*n) * hlp_ka[h as usize]).to_array())
            .collect();
        let [r, g, b] = species_color(model);
        let shape_material = Material {
            name: format!("{} substitution shapes", model.name),
            base_color: [r, g, b, 1.0],
            texture: None,
            alpha_cutoff: None,
            double_sided: false,
        };
        let shapes = Shapes {
            triangles: shape_mesh.triangle_count() as u64,
            mesh: self.lit_mesh(&shape_mesh, Some((&shape_owners, spheres)), &lit, &shape_material, Surface::Foliage),
        };
        let (lo, hi) = model.bounds();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        let full_wood = model.parts.iter().filter(|p| p.kind == PartKind::Wood).map(|p| p.mesh.triangle_count() as u64);
        let wood_triangles = [full_wood.sum(), hlp_triangles - hlp_mesh.triangle_count() as u64, 0];
        Ok(SpeciesGpu {
            levels: [full, hlp_level, plant_level],
            particles,
            shapes,
            wood_triangles,
            triangles: [model.triangle_count() as u64, hlp_triangles, plant_mesh.triangle_count() as u64],
            bounds: Sphere { center: (lo + hi) * 0.5, radius: (hi - lo).length() * 0.5 },
            height: hi.z - lo.z,
            spheres: spheres.to_vec(),
            board,
        })
    }
}

impl SceneGpu {
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
}

/// A storage buffer for `count` reference coordinates.
pub(super) fn reference_buffer(device: &wgpu::Device, count: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("references"),
        size: 8 * count as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
