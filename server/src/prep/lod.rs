//! Levels of detail of a plant (SPEC P4, thesis 7 and Table 8.1): the full model near the
//! camera, a billboard cloud of its HLPs (cross billboards per HLP, thesis 4.2) with a fitted
//! trunk cylinder at middle distance, and one cross billboard for the whole plant far away.
//! Plants of a vegetation mass (`prep::masses`) smaller than `mass_px` are drawn by the mass
//! instead; other plants are never drawn smaller than `min_px`, so a lone tree far away stays a
//! dot. The level follows the plant's projected height; in a band around each threshold both
//! levels (or the plant and its mass) are drawn with complementary screen-door masks, so levels
//! blend instead of popping. Budgets per frame (HLP clouds, plants of masses drawn as plants,
//! plants outside masses) raise the thresholds when a dense forest would exceed them, so a
//! frame's cost follows what is near, not the forest's density.
//!
//! This module builds the CPU side (geometry, atlas layout, level selection); the billboard
//! textures are baked on the GPU by `render::bake`.

use super::hlp::Sphere;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{PartKind, PlantModel};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Level of detail of one drawn plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LodLevel {
    /// The full model.
    Full = 0,
    /// Cross billboards per HLP plus a trunk cylinder.
    Hlp = 1,
    /// One cross billboard for the whole plant.
    Plant = 2,
}

impl LodLevel {
    /// All levels, finest first.
    pub const ALL: [LodLevel; 3] = [LodLevel::Full, LodLevel::Hlp, LodLevel::Plant];

    /// Index into per-level arrays.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// When each level is used, in projected plant height (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LodSettings {
    /// Plants at least this many pixels tall are drawn with the full model.
    pub full_px: f32,
    /// Plants at least this tall (and below `full_px`) are drawn as HLP billboard clouds;
    /// smaller ones as one billboard.
    pub hlp_px: f32,
    /// Plants outside a vegetation mass smaller than this are drawn enlarged to it (a dot), so
    /// lone trees and hedgerows stay visible at any distance.
    pub min_px: f32,
    /// Plants of a vegetation mass smaller than this are drawn by the mass instead (blended
    /// across the band of `fade`, thesis 7.3); 0 draws no masses.
    pub mass_px: f32,
    /// Plants drawn as one billboard and smaller than this share the reference point of their
    /// terrain-grid cell for hatching and silhouettes (thesis 7.3), larger ones have their own.
    pub grid_px: f32,
    /// Half-width of the blend band around each threshold, relative to it (0 = hard switch).
    pub fade: f32,
    /// At most about this many plants of a frame get their HLP billboard clouds (or the full
    /// model): beyond it the HLP threshold of that frame rises to the size of the budget's
    /// plants, so the nearest keep their detail and a dense forest in front of the eye
    /// costs what the budget does ([`LodSettings::within_budget`]); 0 = no limit.
    pub hlp_budget: u32,
    /// At most about this many plants of vegetation masses are drawn as plants in a frame:
    /// beyond it the mass band of that frame rises to the size of the budget's plants, so the
    /// nearest of a dense forest stay billboards and the rest are drawn by their masses,
    /// whatever the forest's density ([`LodSettings::within_budget`]); 0 = no limit. Lone
    /// plants and hedgerows outside masses are not counted: they are always drawn.
    pub billboard_budget: u32,
    /// At most about this many plants outside masses (lone trees, hedgerows, the scattered
    /// shrubs of open land) are drawn in a frame: beyond it the smallest on screen are left out
    /// ([`LodSettings::lone_threshold`]), so far scattered shrubs are left to the ground's
    /// drape while near plants and tall ones (a lone tree far away) stay; 0 = no limit.
    pub lone_budget: u32,
    /// Draw every plant at this level (for tests and comparisons); `None` selects by size.
    pub force: Option<LodLevel>,
}

impl Default for LodSettings {
    fn default() -> Self {
        LodSettings {
            full_px: 160.0,
            hlp_px: 40.0,
            min_px: 1.5,
            mass_px: 8.0,
            grid_px: 12.0,
            fade: 0.2,
            hlp_budget: 100,
            billboard_budget: 2000,
            lone_budget: 20000,
            force: None,
        }
    }
}

/// One draw of a plant at a level, visible where the screen-door value of a pixel lies in
/// `mask[0]..mask[1]` (`[0, 1]` draws every pixel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelDraw {
    pub level: LodLevel,
    pub mask: [f32; 2],
}

impl LodSettings {
    /// Checks the thresholds' order and ranges.
    pub fn validate(&self) -> Result<(), String> {
        let ok = self.min_px >= 0.0
            && self.hlp_px >= self.min_px
            && self.full_px >= self.hlp_px
            && self.full_px.is_finite()
            && (0.0..=self.hlp_px).contains(&self.grid_px)
            && (0.0..0.5).contains(&self.fade);
        let (lo, hi) = self.mass_band();
        let masses = self.mass_px == 0.0 || (self.min_px <= lo && hi <= self.hlp_px * (1.0 - self.fade));
        if ok && masses {
            Ok(())
        } else {
            Err("LOD thresholds need 0 <= min_px <= hlp_px <= full_px, 0 <= grid_px <= hlp_px, 0 <= fade < 0.5 \
                 and mass_px 0 or with its band between min_px and the HLP band"
                .into())
        }
    }

    /// These settings for a frame whose plants are `sizes` pixels tall (each with whether a
    /// vegetation mass stands for it). When more than `billboard_budget` plants of masses are
    /// larger than the mass band, the band rises so that only the largest `billboard_budget`
    /// are (the HLP and full-model thresholds with it where they would fall below); then, when
    /// more than `hlp_budget` plants reach the HLP band, its threshold rises so that only the
    /// largest `hlp_budget` do. `sizes` may leave out plants of masses smaller than the
    /// `billboard_budget + 1` largest of them: those are not drawn either way.
    pub fn within_budget(&self, sizes: &[(f32, bool)]) -> LodSettings {
        if self.force.is_some() {
            return *self;
        }
        let mut framed = *self;
        if self.masses() {
            let lower_edge = self.mass_band().0;
            let massed = sizes.iter().filter(|&&(px, massed)| massed && px > lower_edge).map(|&(px, _)| px);
            if let Some(first_out) = first_beyond(massed, self.billboard_budget) {
                framed.mass_px = first_out / (1.0 - self.fade);
                let hlp_px = framed.mass_band().1 / (1.0 - self.fade);
                framed.hlp_px = framed.hlp_px.max(hlp_px);
                framed.full_px = framed.full_px.max(framed.hlp_px);
            }
        }
        let lower_edge = framed.hlp_px * (1.0 - self.fade);
        let in_band = sizes.iter().filter(|&&(px, _)| px > lower_edge).map(|&(px, _)| px);
        if let Some(first_out) = first_beyond(in_band, self.hlp_budget) {
            framed.hlp_px = first_out / (1.0 - self.fade);
            framed.full_px = framed.full_px.max(framed.hlp_px);
        }
        framed
    }

    /// The size in pixels up to which a frame leaves out plants outside masses, when more than
    /// `lone_budget` of `sizes` (as for [`LodSettings::within_budget`]) are such plants: the
    /// largest of them beyond the budget, but never more than `min_px` (only plants that would
    /// be enlarged to dots are left out: a lone tree a few pixels tall stays); 0 (none left
    /// out) within the budget or with a forced level. `sizes` may leave out plants outside
    /// masses smaller than the `lone_budget + 1` largest.
    pub fn lone_threshold(&self, sizes: &[(f32, bool)]) -> f32 {
        if self.force.is_some() {
            return 0.0;
        }
        let lone = sizes.iter().filter(|&&(_, massed)| !massed).map(|&(px, _)| px);
        first_beyond(lone, self.lone_budget).map_or(0.0, |px| px.min(self.min_px))
    }

    /// Whether plants far away are drawn by their vegetation masses (not when a level is forced).
    pub fn masses(&self) -> bool {
        self.mass_px > 0.0 && self.force.is_none()
    }

    /// The blend band (pixels of plant height) in which a mass takes over from its plants.
    pub fn mass_band(&self) -> (f32, f32) {
        (self.mass_px * (1.0 - self.fade), self.mass_px * (1.0 + self.fade))
    }

    /// The share of the screen-door values a mass covers where its plants are `px` tall: 1
    /// below the mass band, 0 above it, falling linearly across it; the plants draw the rest.
    /// `mass_cover` in `shaders/gbuffer.wgsl` is the same function on the mass's pixels.
    pub fn mass_cover(&self, px: f32) -> f32 {
        let (lo, hi) = self.mass_band();
        if hi <= lo {
            return if px < lo { 1.0 } else { 0.0 };
        }
        ((hi - px) / (hi - lo)).clamp(0.0, 1.0)
    }

    /// How much a plant `px` tall is enlarged: to `min_px` when it is smaller (plants of a mass
    /// are drawn by it at that size), not at all when a level is forced.
    pub fn dot_scale(&self, px: f32) -> f32 {
        if self.force.is_none() && px > 0.0 && px < self.min_px { self.min_px / px } else { 1.0 }
    }

    /// The draws of a plant that is `px` pixels tall on screen: one level away from the
    /// thresholds, two complementary masked levels inside a blend band. A plant of a mass
    /// (`massed`) is not drawn below the mass band and shares the pixels with the mass inside
    /// it; others are drawn at every size (the caller enlarges them to `min_px`,
    /// [`LodSettings::dot_scale`]).
    pub fn select(&self, px: f32, massed: bool) -> [Option<LevelDraw>; 2] {
        let all = |level| Some(LevelDraw { level, mask: [0.0, 1.0] });
        if let Some(level) = self.force {
            return [all(level), None];
        }
        if px.is_nan() {
            return [None, None];
        }
        if massed && self.masses() {
            let cover = self.mass_cover(px);
            if cover >= 1.0 {
                return [None, None];
            }
            if cover > 0.0 {
                return [Some(LevelDraw { level: LodLevel::Plant, mask: [cover, 1.0] }), None];
            }
        }
        for (threshold, fine, coarse) in
            [(self.full_px, LodLevel::Full, LodLevel::Hlp), (self.hlp_px, LodLevel::Hlp, LodLevel::Plant)]
        {
            let (lo, hi) = (threshold * (1.0 - self.fade), threshold * (1.0 + self.fade));
            if px >= hi {
                return [all(fine), None];
            }
            if px > lo {
                let w = (px - lo) / (hi - lo);
                return [
                    Some(LevelDraw { level: fine, mask: [0.0, w] }),
                    Some(LevelDraw { level: coarse, mask: [w, 1.0] }),
                ];
            }
        }
        [all(LodLevel::Plant), None]
    }
}

/// The largest of `sizes` beyond the `budget` largest (the band's new lower edge), when there
/// are more than `budget` of them and `budget` is not 0 (no limit). Only the sizes in a band
/// are ordered: a few thousand of a forest's plants.
fn first_beyond(sizes: impl Iterator<Item = f32>, budget: u32) -> Option<f32> {
    let budget = budget as usize;
    let mut sizes: Vec<f32> = sizes.collect();
    if budget == 0 || sizes.len() <= budget {
        return None;
    }
    let (_, &mut first_out, _) = sizes.select_nth_unstable_by(budget, |a, b| b.total_cmp(a));
    Some(first_out)
}

/// The three billboard planes of a cross billboard: (right, up) axes in model space. The
/// plane's texture is the model seen along `right × up`.
pub const BILLBOARD_VIEWS: [(Vec3, Vec3); 3] = [(Vec3::X, Vec3::Z), (Vec3::Y, Vec3::Z), (Vec3::X, Vec3::Y)];

/// A cross billboard: a centre and the half-extents of its planes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Billboard {
    pub center: Vec3,
    /// Half-extent along the horizontal axes.
    pub half_width: f32,
    /// Half-extent along z (vertical planes only; the horizontal plane uses `half_width`).
    pub half_height: f32,
    /// Radius of the HLP sphere the billboard stands for (its shading normal's sphere).
    pub radius: f32,
}

impl Billboard {
    /// The billboard of an HLP sphere.
    pub fn of_sphere(s: &Sphere) -> Billboard {
        Billboard { center: s.center, half_width: s.radius, half_height: s.radius, radius: s.radius }
    }

    /// The billboard around a whole model (its bounding box; rotation about z keeps the
    /// larger horizontal half-extent).
    pub fn of_model(model: &PlantModel) -> Billboard {
        let (lo, hi) = model.bounds();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        let half = (hi - lo) * 0.5;
        let half_width = half.x.max(half.y).max(1e-3);
        let half_height = half.z.max(1e-3);
        Billboard { center: (lo + hi) * 0.5, half_width, half_height, radius: half_width.max(half_height) }
    }

    /// Half-extents (right, up) of view `v` of [`BILLBOARD_VIEWS`].
    pub fn extents(&self, view: usize) -> (f32, f32) {
        if BILLBOARD_VIEWS[view].1 == Vec3::Z {
            (self.half_width, self.half_height)
        } else {
            (self.half_width, self.half_width)
        }
    }

    /// Orthographic world → clip matrix that bakes view `v` into a tile (wgpu depth 0..1).
    pub fn bake_matrix(&self, view: usize) -> glam::Mat4 {
        let (right, up) = BILLBOARD_VIEWS[view];
        let normal = right.cross(up);
        let (hr, hu) = self.extents(view);
        let depth = 2.0 * self.radius.max(hr).max(hu);
        let eye = self.center + normal * depth;
        let look = glam::camera::rh::view::look_at_mat4(eye, self.center, up);
        glam::camera::rh::proj::directx::orthographic(-hr, hr, -hu, hu, 0.0, 2.0 * depth) * look
    }
}

/// A texture atlas of square tiles in rows, each with a gutter so mip levels do not bleed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Atlas {
    pub tile: u32,
    pub gutter: u32,
    pub cols: u32,
    pub rows: u32,
}

impl Atlas {
    /// An atlas for `tiles` tiles of `tile` pixels, as square as possible.
    pub fn new(tiles: usize, tile: u32) -> Atlas {
        let cols = (tiles.max(1) as f64).sqrt().ceil() as u32;
        let rows = (tiles.max(1) as u32).div_ceil(cols);
        Atlas { tile, gutter: (tile / 32).max(1), cols, rows }
    }

    /// Atlas size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.cols * self.tile, self.rows * self.tile)
    }

    /// The inner region (x, y, width, height in pixels) of tile `index`.
    pub fn viewport(&self, index: usize) -> [u32; 4] {
        let (col, row) = (index as u32 % self.cols, index as u32 / self.cols);
        let inner = self.tile - 2 * self.gutter;
        [col * self.tile + self.gutter, row * self.tile + self.gutter, inner, inner]
    }

    /// Texture coordinates of the point (s, t) ∈ [−1, 1]² of tile `index` (t up).
    pub fn uv(&self, index: usize, s: f32, t: f32) -> [f32; 2] {
        let [x, y, w, h] = self.viewport(index);
        let (width, height) = self.size();
        [
            (x as f32 + (s + 1.0) * 0.5 * w as f32) / width as f32,
            (y as f32 + (1.0 - t) * 0.5 * h as f32) / height as f32,
        ]
    }
}

/// The cross billboards of `billboards` as one mesh: view `v` of billboard `i` uses atlas tile
/// `first_tile + 3·i + v`. Returns the mesh and the index of each vertex's billboard.
pub fn billboard_mesh(billboards: &[Billboard], atlas: &Atlas, first_tile: usize) -> (Mesh, Vec<u32>) {
    let mut mesh = Mesh::default();
    let mut owner = Vec::new();
    for (i, b) in billboards.iter().enumerate() {
        for (v, (right, up)) in BILLBOARD_VIEWS.iter().enumerate() {
            let (hr, hu) = b.extents(v);
            let tile = first_tile + 3 * i + v;
            let base = mesh.positions.len() as u32;
            for (s, t) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push((b.center + *right * (s * hr) + *up * (t * hu)).to_array());
                mesh.normals.push(right.cross(*up).to_array());
                mesh.uvs.push(atlas.uv(tile, s, t));
                owner.push(i as u32);
            }
            mesh.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    (mesh, owner)
}

/// A tapered prism fitted to the trunk of `model`'s wood parts: the axis through the mean of
/// the lowest quarter of wood vertices, their mean distance from it as the base radius, up to
/// 80 % of the wood's height. Returns the mesh and the wood part whose material it uses, or
/// `None` for a model without wood.
pub fn trunk_cylinder(model: &PlantModel, sides: usize) -> Option<(Mesh, usize)> {
    let (part_index, _) = model
        .parts
        .iter()
        .enumerate()
        .filter(|(_, p)| p.kind == PartKind::Wood && !p.mesh.positions.is_empty())
        .max_by_key(|(_, p)| p.mesh.positions.len())?;
    let points: Vec<Vec3> =
        model.parts_of(PartKind::Wood).flat_map(|p| p.mesh.positions.iter().map(|&q| Vec3::from(q))).collect();
    let (z0, z1) = points.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| (lo.min(p.z), hi.max(p.z)));
    let low: Vec<Vec3> = points.iter().copied().filter(|p| p.z <= z0 + 0.25 * (z1 - z0)).collect();
    let axis = low.iter().fold(Vec3::ZERO, |a, p| a + *p) / low.len() as f32;
    let radius = (low.iter().map(|p| (p.truncate() - axis.truncate()).length()).sum::<f32>() / low.len() as f32)
        .max(0.01 * (z1 - z0).max(1e-3));
    let top = z0 + 0.8 * (z1 - z0);
    let part = &model.parts[part_index];
    let uv = part.mesh.uvs.iter().fold([0.0f32; 2], |a, u| [a[0] + u[0], a[1] + u[1]]);
    let uv = [uv[0] / part.mesh.uvs.len().max(1) as f32, uv[1] / part.mesh.uvs.len().max(1) as f32];
    let mut mesh = Mesh::default();
    for k in 0..sides {
        let angle = k as f32 / sides as f32 * std::f32::consts::TAU;
        let dir = Vec3::new(angle.cos(), angle.sin(), 0.0);
        for (z, r) in [(z0, radius), (top, 0.6 * radius)] {
            mesh.positions.push([axis.x + dir.x * r, axis.y + dir.y * r, z]);
            mesh.normals.push(dir.to_array());
            mesh.uvs.push(uv);
        }
    }
    for k in 0..sides as u32 {
        let (a, b) = (2 * k, 2 * ((k + 1) % sides as u32));
        mesh.indices.extend([a, b, a + 1, b, b + 1, a + 1]);
    }
    Some((mesh, part_index))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural::{ProceduralKind, procedural_plant};

    #[test]
    fn levels_follow_projected_size_and_blend_in_bands() {
        let s = LodSettings::default();
        let level = |px| s.select(px, false).map(|d| d.map(|d| (d.level, d.mask)));
        assert_eq!(level(500.0), [Some((LodLevel::Full, [0.0, 1.0])), None]);
        assert_eq!(level(100.0), [Some((LodLevel::Hlp, [0.0, 1.0])), None]);
        assert_eq!(level(10.0), [Some((LodLevel::Plant, [0.0, 1.0])), None]);
        assert_eq!(level(0.5), [Some((LodLevel::Plant, [0.0, 1.0])), None], "a lone plant stays a dot");
        assert!((s.dot_scale(0.5) - s.min_px / 0.5).abs() < 1e-6 && s.dot_scale(10.0) == 1.0);
        // Exactly on the full/HLP threshold both draw half of the pixels, complementarily.
        assert_eq!(level(160.0), [Some((LodLevel::Full, [0.0, 0.5])), Some((LodLevel::Hlp, [0.5, 1.0]))]);
        let forced = LodSettings { force: Some(LodLevel::Plant), ..s };
        assert_eq!(forced.select(1000.0, true)[0].map(|d| d.level), Some(LodLevel::Plant));
        assert!(LodSettings { hlp_px: 500.0, ..s }.validate().is_err());
        assert!(LodSettings { mass_px: 36.0, ..s }.validate().is_err(), "mass band inside the HLP band");
        s.validate().unwrap();
    }

    #[test]
    fn the_hlp_budget_keeps_the_largest_plants_detailed() {
        let s = LodSettings { hlp_budget: 3, ..LodSettings::default() };
        let hlp = |settings: &LodSettings, sizes: &[(f32, bool)]| {
            sizes
                .iter()
                .filter(|&&(px, _)| settings.select(px, false).iter().flatten().any(|d| d.level != LodLevel::Plant))
                .count()
        };
        let lone = |px: &[f32]| px.iter().map(|&px| (px, false)).collect::<Vec<_>>();
        // Within the budget nothing changes.
        let few = lone(&[300.0, 100.0, 50.0, 10.0]);
        assert_eq!(s.within_budget(&few), s);
        // Ten plants in the HLP band: only the three largest keep more than a billboard, and the
        // full-model threshold stays above the HLP one.
        let many = lone(&(0..10).map(|i| 200.0 - 15.0 * i as f32).chain([5.0, 2.0]).collect::<Vec<_>>());
        let framed = s.within_budget(&many);
        assert_eq!(hlp(&framed, &many), 3, "{framed:?}");
        assert!(framed.full_px >= framed.hlp_px && framed.validate().is_ok());
        assert_eq!(hlp(&LodSettings { hlp_budget: 0, ..s }.within_budget(&many), &many), 10);
    }

    #[test]
    fn the_billboard_budget_hands_a_dense_forest_to_its_masses() {
        let s = LodSettings { billboard_budget: 100, ..LodSettings::default() };
        let drawn = |settings: &LodSettings, sizes: &[(f32, bool)]| {
            sizes.iter().filter(|&&(px, massed)| settings.select(px, massed)[0].is_some()).count()
        };
        // A forest of 1,000 plants of a mass from 120 px down to 12 px (all above the default
        // mass band), and 50 lone trees as small.
        let forest: Vec<(f32, bool)> = (0..1000).map(|i| (120.0 - 0.108 * i as f32, true)).collect();
        let lone: Vec<(f32, bool)> = (0..50).map(|i| (12.0 + i as f32, false)).collect();
        let sizes: Vec<(f32, bool)> = forest.iter().chain(&lone).copied().collect();
        assert_eq!(drawn(&s, &sizes), 1050, "without the budget every plant is drawn");
        let framed = s.within_budget(&sizes);
        assert!(framed.validate().is_ok(), "{framed:?}");
        assert_eq!(drawn(&framed, &forest), 100, "the largest 100 plants of the mass: {framed:?}");
        assert_eq!(drawn(&framed, &lone), 50, "lone trees are not counted");
        let (lo, _) = framed.mass_band();
        assert!(forest[..100].iter().all(|&(px, _)| px > lo), "the nearest are the ones drawn");
        // The HLP band stays above the mass band; within the budget nothing changes.
        assert!(framed.hlp_px * (1.0 - framed.fade) >= framed.mass_band().1 - 1e-4);
        assert_eq!(s.within_budget(&forest[..80]), s);
        assert_eq!(LodSettings { billboard_budget: 0, ..s }.within_budget(&sizes).mass_px, s.mass_px, "no limit");
    }

    #[test]
    fn the_lone_budget_keeps_the_largest_plants_outside_masses() {
        let s = LodSettings { lone_budget: 3, ..LodSettings::default() };
        let kept = |sizes: &[(f32, bool)]| -> Vec<f32> {
            let cut = s.lone_threshold(sizes);
            sizes.iter().filter(|&&(px, massed)| !massed && px > cut).map(|&(px, _)| px).collect()
        };
        let sizes = [(50.0, false), (0.5, false), (9.0, false), (0.2, false), (1.0, false), (30.0, true)];
        assert_eq!(kept(&sizes), [50.0, 9.0, 1.0], "the three largest; the plant of a mass is not counted");
        // Plants larger than a dot are kept beyond the budget: a lone tree far away stays.
        let trees = [(50.0, false), (2.0, false), (9.0, false), (1.0, false), (4.0, false)];
        assert_eq!(kept(&trees), [50.0, 2.0, 9.0, 4.0], "only the plant below min_px is left out");
        assert_eq!(LodSettings { lone_budget: 5, ..s }.lone_threshold(&sizes), 0.0, "within the budget");
        assert_eq!(LodSettings { lone_budget: 0, ..s }.lone_threshold(&sizes), 0.0, "no limit");
        assert_eq!(LodSettings { force: Some(LodLevel::Plant), ..s }.lone_threshold(&sizes), 0.0);
    }

    #[test]
    fn plants_of_a_mass_hand_over_to_it_across_the_band() {
        let s = LodSettings::default();
        let (lo, hi) = s.mass_band();
        let massed = |px| s.select(px, true).map(|d| d.map(|d| (d.level, d.mask)));
        assert_eq!(massed(lo * 0.9), [None, None], "below the band the mass draws the plant");
        assert_eq!(massed(hi * 1.1), [Some((LodLevel::Plant, [0.0, 1.0])), None]);
        let mid = 0.5 * (lo + hi);
        let [Some(draw), None] = s.select(mid, true) else { panic!("one draw in the band") };
        assert_eq!(draw.level, LodLevel::Plant);
        assert!((draw.mask[0] - 0.5).abs() < 1e-6 && draw.mask[1] == 1.0, "the half the mass leaves: {draw:?}");
        assert!((s.mass_cover(mid) - 0.5).abs() < 1e-6 && s.mass_cover(lo) == 1.0 && s.mass_cover(hi) == 0.0);
        // Across the band the plant's share and the mass's share add up to every pixel.
        for px in [lo, 0.3 * lo + 0.7 * hi, hi] {
            let plant = massed(px)[0].map_or(0.0, |(_, mask)| mask[1] - mask[0]);
            assert!((plant + s.mass_cover(px) - 1.0).abs() < 1e-6, "{px}");
        }
        let off = LodSettings { mass_px: 0.0, ..s };
        assert!(!off.masses() && off.select(lo * 0.5, true)[0].is_some());
    }

    #[test]
    fn atlas_tiles_do_not_overlap_and_uvs_stay_inside_their_tile() {
        let atlas = Atlas::new(10, 64);
        assert_eq!((atlas.cols, atlas.rows), (4, 3));
        assert_eq!(atlas.size(), (256, 192));
        assert_eq!(atlas.viewport(5), [64 + 2, 64 + 2, 60, 60]);
        let [u0, v0] = atlas.uv(5, -1.0, 1.0);
        let [u1, v1] = atlas.uv(5, 1.0, -1.0);
        assert!((u0 - 66.0 / 256.0).abs() < 1e-6 && (v0 - 66.0 / 192.0).abs() < 1e-6);
        assert!((u1 - 126.0 / 256.0).abs() < 1e-6 && (v1 - 126.0 / 192.0).abs() < 1e-6);
    }

    #[test]
    fn bake_matrix_maps_the_billboard_plane_onto_the_tile() {
        let b = Billboard { center: Vec3::new(1.0, 2.0, 3.0), half_width: 2.0, half_height: 4.0, radius: 4.0 };
        for (v, (right, up)) in BILLBOARD_VIEWS.iter().enumerate() {
            let (hr, hu) = b.extents(v);
            let m = b.bake_matrix(v);
            let corner = m.project_point3(b.center + *right * hr + *up * hu);
            assert!((corner.x - 1.0).abs() < 1e-5 && (corner.y - 1.0).abs() < 1e-5, "view {v}: {corner}");
            assert!((0.0..=1.0).contains(&corner.z));
        }
    }

    #[test]
    fn billboard_mesh_has_three_quads_per_billboard() {
        let atlas = Atlas::new(6, 32);
        let spheres = [Sphere { center: Vec3::ZERO, radius: 1.0 }, Sphere { center: Vec3::Z, radius: 0.5 }];
        let boards: Vec<_> = spheres.iter().map(Billboard::of_sphere).collect();
        let (mesh, owner) = billboard_mesh(&boards, &atlas, 0);
        assert_eq!(mesh.triangle_count(), 12);
        assert_eq!(owner.iter().filter(|&&o| o == 1).count(), 12);
        // Every vertex of the second billboard lies on the square of half-size 0.5 about it.
        for (p, _) in mesh.positions.iter().zip(&owner).filter(|(_, o)| **o == 1) {
            let d = Vec3::from(*p) - Vec3::Z;
            assert!((d.abs().max_element() - 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn trunk_fits_the_wood_of_a_tree() {
        let model = procedural_plant(ProceduralKind::Broadleaf, 1);
        let (mesh, part) = trunk_cylinder(&model, 6).unwrap();
        assert_eq!(model.parts[part].kind, PartKind::Wood);
        assert_eq!(mesh.triangle_count(), 12);
        let (lo, hi) = model.bounds();
        for p in &mesh.positions {
            assert!((lo[2] - 1e-4..=hi[2]).contains(&p[2]));
            assert!(p[0].abs() < 0.2 * model.height() && p[1].abs() < 0.2 * model.height(), "{p:?}");
        }
    }
}
