//! Picks what a frame draws: plants culled against the view frustum, each visible plant's
//! level(s) of detail (or share of leaf particles) and style slot, the terrain chunks at their
//! levels, and the hatching reference points (thesis 7.3) the instances index.

use super::batch::{Batch, BatchKey, Runs, Share};
use super::clusters::ClusterView;
use super::masses::{MassDraw, MassView};
use super::{LEVELS, Plant, SceneGpu, SpeciesGpu};
use crate::prep::hlp::Sphere;
use crate::prep::leaves;
use crate::prep::lod::{LodLevel, LodSettings};
use crate::render::gbuffer::{Instance, object_id};
use crate::render::layer_code::LayerCode;
use crate::render::parametrization::RefKey;
use crate::render::style::{LeafMode, Style};
use crate::scene::camera::Camera;
use glam::Vec3;
use serde::Serialize;
use std::collections::HashMap;
use std::ops::Range;

/// On-screen size in pixels below which the terrain's (coarsened) cells are kept.
const TERRAIN_CELL_PX: f32 = 8.0;

/// Counts of a frame's geometry: what the seeds' Table 8.1 reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct DrawStats {
    /// Plants in the scene.
    pub plants: u64,
    /// Plants inside the view frustum and large enough to draw.
    pub plants_drawn: u64,
    /// Plants culling looked at one by one: those of the plant clusters it opened
    /// (`scene_gpu::clusters`), which follow what is near, not the scene's plant count.
    pub plants_visited: u64,
    /// Plant draws per level of detail (full, HLP billboards, plant billboard); a plant in a
    /// blend band counts at both levels.
    pub per_level: [u64; LEVELS],
    /// Triangles submitted, terrain included.
    pub triangles: u64,
    /// Triangles of the full scene (every plant at full detail, and the terrain).
    pub source_triangles: u64,
    /// Hatching reference points of the frame (HLPs, plants and terrain-grid cells, thesis 7.3).
    pub reference_points: u64,
    /// Domes of vegetation masses drawn (`prep::masses`: each stands for the plants of a cell
    /// of the plant-density grid far away).
    pub mass_domes: u64,
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
    /// Whether plants at full detail and at the HLP level draw substitution shapes instead of
    /// foliage and HLP billboard clouds (`Style::leaf_mode` `shapes`).
    pub shapes: bool,
}

impl From<&Style> for LayerDraw {
    fn from(style: &Style) -> LayerDraw {
        LayerDraw {
            visible: style.visible,
            particles: style.leaf_mode.particles(),
            shapes: style.leaf_mode == LeafMode::Shapes,
        }
    }
}

/// The plants one frame draws: its instance list in (species, level) runs and the reference
/// points the instances index.
pub struct VisibleSet {
    pub(super) instances: Vec<Instance>,
    /// Runs of plants drawn with the species' meshes at a level of detail.
    pub(super) batches: Vec<Batch<LodLevel>>,
    /// Runs of plants at full detail drawn with a share of their leaf particles.
    pub(super) particle_batches: Vec<Batch<Share>>,
    /// Runs drawn with substitution shapes (`LayerDraw::shapes`): the full or HLP level's
    /// wood and the species' shapes.
    pub(super) shape_batches: Vec<Batch<LodLevel>>,
    /// Chunks of vegetation masses, each with its instance.
    pub(super) masses: Vec<MassDraw>,
    /// Index ranges of the visible terrain chunks at their levels of detail.
    pub(super) terrain_ranges: Vec<Range<u32>>,
    pub(super) references: Vec<RefKey>,
    pub stats: DrawStats,
}

impl VisibleSet {
    /// The reference points of the frame, in the order of its reference buffer.
    pub fn references(&self) -> &[RefKey] {
        &self.references
    }
}

impl SceneGpu {
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
        let mut runs = Runs::<LodLevel>::new(self.species.len());
        let mut particle_runs = Runs::<Share>::new(self.species.len());
        let mut shape_runs = Runs::<LodLevel>::new(self.species.len());
        let mut stats = DrawStats { plants: self.plants.len() as u64, ..DrawStats::default() };
        let mut references = References::default();
        // The plants in view with their projected size (and whether a mass stands for them);
        // the frame's budgets apply to them all before any level is chosen. The clusters
        // leave out the plants their masses draw.
        let (mut in_view, mut sizes) = (Vec::new(), Vec::new());
        let view = ClusterView {
            planes: &planes,
            eye,
            forward,
            plan,
            px_per_metre,
            massed_below: lod.masses().then(|| lod.mass_band().0),
            budgets: [lod.lone_budget, lod.billboard_budget],
            lone_kept_above: lod.min_px,
        };
        stats.plants_visited = self.clusters.visit(&view, |index| {
            let plant = &self.plants[index as usize];
            let s = &self.species[plant.species];
            let i = &plant.instance;
            let drawn_as = layer(i.object_id);
            if !drawn_as.visible {
                return None;
            }
            let center = plant.world(s.bounds.center);
            let radius = s.bounds.radius * i.offset_scale[3];
            if sphere_outside(&planes, center, radius) {
                return None;
            }
            let px = match plan {
                // Seen from above, the crown's extent matters, not the height.
                Some(m) => 2.0 * radius / m,
                None => {
                    let depth = (center - eye).dot(forward).max(radius * 0.5).max(1e-3);
                    s.height * i.offset_scale[3] * px_per_metre / depth
                }
            };
            in_view.push((index as usize, drawn_as));
            sizes.push((px, plant.massed));
            Some(px)
        });
        let lone_above = lod.lone_threshold(&sizes);
        let lod = &lod.within_budget(&sizes);
        for ((index, drawn_as), (px, _)) in in_view.into_iter().zip(sizes) {
            let plant = &self.plants[index];
            let s = &self.species[plant.species];
            let i = &plant.instance;
            let slot = LayerCode::of_object_id(i.object_id).slot();
            let draws = lod.select(px, plant.massed);
            if draws[0].is_none() || (!plant.massed && px <= lone_above) {
                continue;
            }
            // A lone plant far away stays a dot (a mass draws the plants of a wood); a plan view
            // is a map at true scale, which leaves plants below `min_px` out.
            let dot = match plan {
                Some(_) if px < lod.min_px && lod.force.is_none() => continue,
                Some(_) => 1.0,
                None => lod.dot_scale(px),
            };
            stats.plants_drawn += 1;
            let data_abstraction = abstraction(i.offset_scale[0], i.offset_scale[1]);
            for draw in draws.into_iter().flatten() {
                stats.per_level[draw.level.index()] += 1;
                // Leaf particles: the share of the leaves falls with the plant's size (SPEC P4).
                let share = (drawn_as.particles && draw.level == LodLevel::Full)
                    .then(|| leaves::particle_bucket(px, s.particles.count));
                // Substitution shapes stand for the foliage of both finer levels (SPEC P5).
                let shapes = drawn_as.shapes && draw.level != LodLevel::Plant;
                stats.triangles += match (share, shapes) {
                    (Some(b), _) => s.particles.triangles[b],
                    (None, true) => s.wood_triangles[draw.level.index()] + s.shapes.triangles,
                    (None, false) => s.triangles[draw.level.index()],
                };
                let (reference_base, reference_sphere) = match draw.level {
                    LodLevel::Full | LodLevel::Hlp => (references.hlps(index as u32, s.spheres.len()), [0.0; 4]),
                    LodLevel::Plant if px < lod.grid_px => {
                        let cell = self.cells[plant.cell as usize];
                        let [x, y, z] = cell.center.to_array();
                        (references.point(RefKey::Cell(plant.cell)), [x, y, z, cell.radius])
                    }
                    LodLevel::Plant => (references.point(RefKey::Plant(index as u32)), [0.0; 4]),
                };
                let mut instance =
                    Instance { mask: draw.mask, reference_base, reference_sphere, data_abstraction, ..*i };
                instance.offset_scale[3] *= dot;
                let species = plant.species;
                let key = BatchKey { species, detail: draw.level, slot };
                match (share, shapes) {
                    (Some(b), _) => particle_runs.push(BatchKey { species, detail: Share(b), slot }, instance),
                    (None, true) => shape_runs.push(key, instance),
                    (None, false) => runs.push(key, instance),
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
            if sphere_outside(&planes, chunk.center, chunk.radius) {
                continue;
            }
            let cell_px = match plan {
                Some(m) => self.terrain_cell / m,
                None => self.terrain_cell * px_per_metre / ((chunk.center - eye).length() - chunk.radius).max(1e-3),
            };
            let range = chunk.levels[chunk.level_for(cell_px, TERRAIN_CELL_PX)].clone();
            stats.triangles += u64::from((range.end - range.start) / 3);
            terrain_ranges.push((chunk.center.distance_squared(eye), range));
        }
        // Front to back: a hill hides the ground behind it before that ground is shaded.
        terrain_ranges.sort_by(|a, b| a.0.total_cmp(&b.0));
        let terrain_ranges = terrain_ranges.into_iter().map(|(_, range)| range).collect();
        stats.source_triangles = self.source_triangles;
        // Front to back within each run, so the depth test rejects hidden fragments early.
        let distance = |i: &Instance| eye.distance_squared(Vec3::from_slice(&i.offset_scale[..3]));
        runs.sort_each(|a, b| distance(a).total_cmp(&distance(b)));
        particle_runs.sort_each(|a, b| distance(a).total_cmp(&distance(b)));
        shape_runs.sort_each(|a, b| distance(a).total_cmp(&distance(b)));
        let mut instances = vec![terrain];
        let batches = runs.append_to(&mut instances);
        let particle_batches = particle_runs.append_to(&mut instances);
        let shape_batches = shape_runs.append_to(&mut instances);
        let masses = match &self.masses {
            Some(masses) if lod.masses() => {
                let view = MassView { planes: &planes, eye, plan, px_per_metre, band: lod.mass_band(), width };
                masses.cull(&view, &layer, &mut instances, &mut references, &mut stats)
            }
            _ => Vec::new(),
        };
        stats.reference_points = references.keys.len() as u64;
        VisibleSet {
            instances,
            batches,
            particle_batches,
            shape_batches,
            masses,
            terrain_ranges,
            references: references.keys,
            stats,
        }
    }
}

/// The reference points of a frame as [`SceneGpu::cull`] collects them: each plant's HLPs as
/// one run, plants and grid cells once each.
#[derive(Default)]
pub(super) struct References {
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

    /// The first entry of a run of `cells` grid cells (a chunk of a vegetation mass indexes its
    /// cells from there; a cell may also have an entry of its own, with the same coordinates).
    pub(super) fn cells(&mut self, cells: &[u32]) -> u32 {
        let first = self.keys.len() as u32;
        self.keys.extend(cells.iter().map(|&c| RefKey::Cell(c)));
        first
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

/// The far reference points of thesis 7.3: one sphere per cell holding plants, and the cell
/// of each grid position.
pub(super) struct ReferenceGrid {
    pub spheres: Vec<Sphere>,
    index: HashMap<(i64, i64), u32>,
    spacing: f32,
}

impl ReferenceGrid {
    fn key(spacing: f32, x: f32, y: f32) -> (i64, i64) {
        ((x / spacing).floor() as i64, (y / spacing).floor() as i64)
    }

    /// The cell holding the ground position (x, y), if any plant stands in it.
    pub fn cell_at(&self, x: f32, y: f32) -> Option<u32> {
        self.index.get(&Self::key(self.spacing, x, y)).copied()
    }
}

/// The far reference points of thesis 7.3: an evenly spaced grid of `spacing` metres over the
/// ground the plants stand on. Each cell holding plants gets one sphere, centred on the mean
/// foliage centre of its plants (so it lies inside the vegetation, as the thesis asks) and
/// reaching over the cell; sets every plant's `cell`.
pub(super) fn reference_grid(plants: &mut [Plant], species: &[SpeciesGpu], spacing: f32) -> ReferenceGrid {
    let mut cells: HashMap<(i64, i64), (u32, Vec3, u32)> = HashMap::new();
    for plant in plants.iter_mut() {
        let [x, y, ..] = plant.instance.offset_scale;
        let key = ReferenceGrid::key(spacing, x, y);
        let next = cells.len() as u32;
        let cell = cells.entry(key).or_insert((next, Vec3::ZERO, 0));
        cell.1 += plant.world(species[plant.species].board.center);
        cell.2 += 1;
        plant.cell = cell.0;
    }
    let mut spheres = vec![Sphere { center: Vec3::ZERO, radius: 0.0 }; cells.len()];
    let mut index = HashMap::with_capacity(cells.len());
    for (key, (i, sum, count)) in cells {
        spheres[i as usize] = Sphere { center: sum / count as f32, radius: spacing * std::f32::consts::FRAC_1_SQRT_2 };
        index.insert(key, i);
    }
    ReferenceGrid { spheres, index, spacing }
}

/// The side planes of a view frustum (left, right, bottom, top, near) from a world → clip
/// matrix with wgpu's clip volume (−w ≤ x, y ≤ w, 0 ≤ z ≤ w), each as (n, d) with the inside
/// where n·p + d ≥ 0 and |n| = 1. The far plane is omitted (the projection has none).
pub fn frustum_planes(view_proj: glam::Mat4) -> [glam::Vec4; 5] {
    let m = view_proj.transpose();
    let (r0, r1, r2, r3) = (m.x_axis, m.y_axis, m.z_axis, m.w_axis);
    [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 - r2].map(|p| p / p.truncate().length().max(1e-12))
}

/// Whether the sphere at `center` of `radius` lies wholly outside one of the frustum's
/// `planes` ([`frustum_planes`]): culled.
pub(super) fn sphere_outside(planes: &[glam::Vec4; 5], center: Vec3, radius: f32) -> bool {
    planes.iter().any(|p| p.truncate().dot(center) + p.w < -radius)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frustum_planes_contain_what_the_camera_sees() {
        let camera = Camera::perspective([0.0, 0.0, 2.0], 0.0, 0.0, 60.0);
        let planes = frustum_planes(camera.projection(1.0) * camera.view());
        let inside = |p: Vec3, r: f32| !sphere_outside(&planes, p, r);
        assert!(inside(Vec3::new(0.0, 50.0, 2.0), 0.0), "straight ahead");
        assert!(inside(Vec3::new(0.0, 1.0e5, 2.0), 0.0), "far ahead: no far plane");
        assert!(!inside(Vec3::new(0.0, -10.0, 2.0), 1.0), "behind");
        assert!(!inside(Vec3::new(40.0, 50.0, 2.0), 1.0), "right of the 60° cone");
        assert!(inside(Vec3::new(40.0, 50.0, 2.0), 20.0), "a large sphere reaching in");
    }
}
