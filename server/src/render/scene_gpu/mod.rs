//! GPU-side copy of a scene: vertex/index buffers per mesh and level of detail, textures,
//! baked billboard atlases and material bind groups, all built once per scene. Each frame only
//! culls the plant instances against the view frustum, picks every visible plant's level of
//! detail from its projected size (`prep::lod`) and uploads the resulting instance list.
//!
//! By job: `upload` builds the GPU resources of a scene (and writes each frame's instances),
//! `bake_cache` bakes the billboard atlases or loads them from the disk cache, `cull` picks what
//! a frame draws into runs keyed by `batch::BatchKey`, `masses` uploads and culls the domes of
//! far vegetation masses, and `draw` records the draws.

mod bake_cache;
mod batch;
mod clusters;
mod cull;
mod draw;
mod masses;
mod upload;

pub use cull::{DrawStats, LayerDraw, VisibleSet, frustum_planes};

use super::bake::Baker;
use super::creases::CreaseSet;
use super::gbuffer::{GeometryPass, Instance, Surface, object_id};
use super::ground_cover::cover_buffer;
use super::layer_code::LayerCode;
use super::parametrization::RefKey;
use super::{Gpu, RenderError};
use crate::prep::cache::DiskCache;
use crate::prep::hlp::{self, Sphere};
use crate::prep::leaves::PARTICLE_SHARES;
use crate::prep::lod::{Billboard, LodLevel};
use crate::prep::masses::{self as mass_groups, MassPlant, Masses};
use crate::prep::terrain_lod::{TerrainChunk, TerrainLod};
use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use clusters::PlantClusters;
use cull::reference_grid;
use glam::Vec3;
use masses::{MassGpu, species_color};
use tracing::info;
use upload::{Uploader, reference_buffer};

/// Levels of detail of a species (the length of per-level arrays).
const LEVELS: usize = LodLevel::ALL.len();
/// DEM cells along each side of a terrain chunk.
const TERRAIN_CHUNK_CELLS: usize = 32;
/// Most levels of detail of a terrain chunk.
const TERRAIN_LEVELS: usize = 6;
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

/// The substitution shapes of a species (SPEC P5, `prep::substitution`): one ellipsoid per
/// HLP, drawn with the wood of the level they stand in for (the full model's or the trunk
/// prism) in the `shapes` leaf mode.
struct Shapes {
    mesh: GpuMesh,
    triangles: u64,
}

/// One species on the GPU: its meshes at every level of detail.
struct SpeciesGpu {
    levels: [Vec<GpuMesh>; LEVELS],
    /// What replaces the full level in the particle leaf modes.
    particles: Particles,
    /// What replaces the foliage of the full and HLP levels in the `shapes` leaf mode.
    shapes: Shapes,
    /// Triangles of the wood meshes of each level (drawn with the shapes).
    wood_triangles: [u64; LEVELS],
    triangles: [u64; LEVELS],
    /// Bounding sphere of the model (model space), for culling.
    bounds: Sphere,
    /// Height of the model, for its projected size.
    height: f32,
    /// The HLP spheres (model space): reference points of the two finer levels.
    spheres: Vec<Sphere>,
    /// The sphere of the whole-plant billboard: the plant's reference point.
    board: Sphere,
}

/// One plant: its species, its instance data, the terrain-grid cell it stands in and whether
/// a vegetation mass draws it far away.
#[derive(Clone, Copy)]
struct Plant {
    species: usize,
    instance: Instance,
    cell: u32,
    massed: bool,
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

/// Everything the geometry pass draws, resident on the GPU.
pub struct SceneGpu {
    /// The terrain's chunks at all levels of detail, in one vertex and one index buffer.
    terrain: GpuMesh,
    terrain_chunks: Vec<TerrainChunk>,
    /// DEM cell size in metres, for the chunks' projected cell size.
    terrain_cell: f32,
    species: Vec<SpeciesGpu>,
    plants: Vec<Plant>,
    /// The plants grouped for culling.
    clusters: PlantClusters,
    source_triangles: u64,
    /// The far reference points: one sphere per terrain-grid cell holding plants (world space).
    cells: Vec<Sphere>,
    /// The domes of far vegetation masses, if any layer has one.
    masses: Option<MassGpu>,
    /// The instances of a frame: room for every plant at two levels, and the terrain.
    instance_buffer: wgpu::Buffer,
    /// The land-cover classes of the terrain's drape ([`crate::render::ground_cover`]).
    cover: wgpu::Buffer,
    /// Whether the drape has any land-cover class (else every pass skips the class lookups).
    land_cover: bool,
    /// The terrain's crease lines ([`crate::render::creases`]).
    creases: CreaseSet,
    /// The reference coordinates of a frame, grown when a frame needs more.
    reference_buffer: std::sync::Mutex<wgpu::Buffer>,
    /// GPU memory of everything above.
    gpu_bytes: u64,
}

impl SceneGpu {
    /// Uploads the terrain, every species' model at all levels of detail (baking billboard
    /// atlases, or loading them from `disk`) and the plant instances of `scene`, reporting the
    /// preprocessing stage to `progress`.
    pub fn new(
        gpu: &Gpu,
        pass: &GeometryPass,
        scene: &Scene,
        disk: Option<&DiskCache>,
        progress: &dyn Progress,
    ) -> Result<SceneGpu, RenderError> {
        progress.report(Stage::Preprocessing, 0.0);
        let (device, queue) = (&gpu.device, &gpu.queue);
        let mut up = Uploader::new(device, queue, pass, disk);
        let terrain_lod = TerrainLod::build(&scene.terrain, TERRAIN_CHUNK_CELLS, TERRAIN_LEVELS);
        let terrain = up.terrain(&terrain_lod.mesh, &scene.terrain.drape)?;
        let segments = crate::prep::creases::crease_lines(&scene.terrain);
        let count = |kind| segments.iter().filter(|s| s.kind == kind).count();
        use crate::prep::creases::CreaseKind;
        info!(
            valleys = count(CreaseKind::Valley),
            ridges = count(CreaseKind::Ridge),
            breaks = count(CreaseKind::Break),
            "terrain crease lines"
        );
        let creases = CreaseSet::new(device, &segments);
        progress.report(Stage::Preprocessing, 0.2);
        let baker = Baker::new(device, &pass.material_layout);
        let mut species = Vec::with_capacity(scene.species.len());
        let mut plant_boards = Vec::with_capacity(scene.species.len());
        for s in &scene.species {
            let hlps = hlp::cluster_cached(&s.model, s.hlp_radius, disk);
            let board = Billboard::of_model(&s.model);
            species.push(up.species(gpu, &baker, &s.model, s.hlp_radius, &hlps, board)?);
            plant_boards.push((hlps, board));
            progress.report(Stage::Preprocessing, 0.2 + 0.5 * species.len() as f32 / scene.species.len() as f32);
        }

        // Each layer's plants grouped into vegetation masses (`prep::masses`).
        let crowns: Vec<(f32, f32, [f32; 3])> = scene
            .species
            .iter()
            .map(|s| {
                let board = Billboard::of_model(&s.model);
                (board.half_width, s.model.bounds().1[2], species_color(&s.model))
            })
            .collect();
        let layer_masses: Vec<Masses> = scene
            .layers
            .iter()
            .map(|layer| {
                let plants: Vec<MassPlant> = layer
                    .plants
                    .iter()
                    .map(|p| {
                        let (radius, height, color) = crowns[p.species];
                        MassPlant {
                            position: p.position,
                            crown_radius: radius * p.scale,
                            height: height * p.scale,
                            color,
                        }
                    })
                    .collect();
                mass_groups::group(&plants)
            })
            .collect();
        let mut plants = Vec::with_capacity(scene.plant_count());
        for (layer_index, layer) in scene.layers.iter().enumerate() {
            let massed = &layer_masses[layer_index].massed;
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
                plants.push(Plant { species: plant.species, instance, cell: 0, massed: massed[i] });
            }
        }
        plants.sort_by_key(|p| p.species);
        let grid = reference_grid(&mut plants, &species, REFERENCE_GRID_SPACING);
        let masses = MassGpu::new(&mut up, &layer_masses, &grid);
        let cells = grid.spheres;
        let clusters = PlantClusters::new(&plants, &species);
        progress.report(Stage::Preprocessing, 1.0);
        let source_triangles = scene.terrain.mesh.triangle_count() as u64
            + plants.iter().map(|p| species[p.species].triangles[LodLevel::Full.index()]).sum::<u64>();
        info!(
            species = species.len(),
            plants = plants.len(),
            hlps = plant_boards.iter().map(|(hlps, _)| hlps.spheres.len()).sum::<usize>(),
            source_triangles,
            "scene uploaded"
        );
        // Meshes and textures, and the most instances a frame draws: every plant at two
        // levels, the terrain, and every chunk of masses at two levels (the reference buffer
        // grows with what a frame draws; it is not counted).
        let instance_count = 2 * plants.len() as u64 + 1 + masses.as_ref().map_or(0, |m| 2 * m.chunk_count() as u64);
        let gpu_bytes = up.bytes() + instance_count * std::mem::size_of::<Instance>() as u64;
        let instance_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("instances"),
            size: instance_count * std::mem::size_of::<Instance>() as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(SceneGpu {
            terrain,
            terrain_cell: terrain_lod.cell_size(),
            terrain_chunks: terrain_lod.chunks,
            species,
            plants,
            clusters,
            source_triangles,
            cells,
            masses,
            instance_buffer,
            cover: cover_buffer(device, &scene.terrain.drape),
            land_cover: !scene.terrain.drape.classes.is_empty(),
            creases,
            reference_buffer: std::sync::Mutex::new(reference_buffer(device, 1)),
            gpu_bytes,
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

    /// The storage buffer of the drape's land-cover classes (`cover` in the shaders).
    pub fn cover_buffer(&self) -> &wgpu::Buffer {
        &self.cover
    }

    /// Whether the terrain's drape has land-cover classes: frames without are drawn with
    /// pipelines compiled without the class lookups (`LAND_COVER` in the shaders).
    pub fn has_land_cover(&self) -> bool {
        self.land_cover
    }

    /// The terrain's crease lines on the GPU.
    pub fn crease_lines(&self) -> &CreaseSet {
        &self.creases
    }

    /// Estimated GPU memory of the scene in bytes (see [`super::Renderer::gpu_bytes`]).
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }

    /// Triangles of the whole scene at full detail.
    pub fn source_triangles(&self) -> u64 {
        self.source_triangles
    }
}
