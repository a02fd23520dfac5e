//! The plant-cluster hierarchy culling walks (issue 17, "culling and LOD cost follows what is
//! visible"): the plants grouped into squares of the ground, plants of vegetation masses apart
//! from lone ones. A frame tests each cluster's bounding sphere against the view and bounds
//! the projected size of its plants before it looks at any of them, so a million plants cost
//! what the clusters near the eye hold: far clusters of a mass are drawn by the mass, and once
//! the frame's budget of a kind of plants is full of larger ones, smaller clusters of that
//! kind are not opened.

use super::cull::sphere_outside;
use super::{Plant, SpeciesGpu};
use glam::Vec3;
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};
use std::ops::Range;

/// Side of a cluster's square of ground, in metres: at forest density (300 trees/ha) about
/// 120 plants, so a million plants make some 10,000 clusters.
const CLUSTER_SIZE: f32 = 64.0;

/// Plants standing in one square of the ground, all of vegetation masses or all not.
struct Cluster {
    /// Bounding sphere of its plants' bounding spheres (world space).
    center: Vec3,
    radius: f32,
    /// The tallest plant's height and the widest plant's bounding radius (metres), which
    /// bound its plants' projected size.
    height: f32,
    crown: f32,
    /// Whether its plants are plants of vegetation masses (`Plant::massed`).
    massed: bool,
    /// Its plants' indices in [`PlantClusters::members`].
    members: Range<usize>,
}

/// Every plant of a scene, clustered (see the module documentation).
pub(super) struct PlantClusters {
    clusters: Vec<Cluster>,
    /// Plant indices (into the scene's plant list), cluster after cluster.
    members: Vec<u32>,
}

/// What [`PlantClusters::visit`] needs of the view.
pub(super) struct ClusterView<'a> {
    pub planes: &'a [glam::Vec4; 5],
    pub eye: Vec3,
    pub forward: Vec3,
    /// Metres per pixel of a plan view.
    pub plan: Option<f32>,
    pub px_per_metre: f32,
    /// Plants of masses at most this many pixels tall are drawn by their masses: the lower
    /// edge of the mass band (`LodSettings::mass_band`), `None` without masses.
    pub massed_below: Option<f32>,
    /// The budgets of plants outside masses and of plants of masses
    /// (`LodSettings::lone_budget` and `billboard_budget`; 0: no limit), in that order.
    pub budgets: [u32; 2],
    /// Plants outside masses taller than this many pixels are drawn whatever their budget
    /// (`LodSettings::min_px`, see `LodSettings::lone_threshold`).
    pub lone_kept_above: f32,
}

impl PlantClusters {
    /// Groups `plants` by the square of [`CLUSTER_SIZE`] metres they stand in and by whether a
    /// mass stands for them.
    pub(super) fn new(plants: &[Plant], species: &[SpeciesGpu]) -> PlantClusters {
        let mut groups: BTreeMap<(i64, i64, bool), Vec<u32>> = BTreeMap::new();
        for (index, plant) in plants.iter().enumerate() {
            let [x, y, ..] = plant.instance.offset_scale;
            let key = ((x / CLUSTER_SIZE).floor() as i64, (y / CLUSTER_SIZE).floor() as i64, plant.massed);
            groups.entry(key).or_default().push(index as u32);
        }
        let mut clusters = Vec::with_capacity(groups.len());
        let mut members = Vec::with_capacity(plants.len());
        for ((_, _, massed), indices) in groups {
            let spheres: Vec<(Vec3, f32, f32)> = indices
                .iter()
                .map(|&i| {
                    let plant = &plants[i as usize];
                    let s = &species[plant.species];
                    let scale = plant.instance.offset_scale[3];
                    (plant.world(s.bounds.center), s.bounds.radius * scale, s.height * scale)
                })
                .collect();
            let (lo, hi) = spheres
                .iter()
                .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), (c, ..)| (lo.min(*c), hi.max(*c)));
            let center = (lo + hi) * 0.5;
            let radius = spheres.iter().map(|(c, r, _)| c.distance(center) + r).fold(0.0, f32::max);
            let height = spheres.iter().map(|s| s.2).fold(0.0, f32::max);
            let crown = spheres.iter().map(|s| s.1).fold(0.0, f32::max);
            let start = members.len();
            members.extend(indices);
            clusters.push(Cluster { center, radius, height, crown, massed, members: start..members.len() });
        }
        PlantClusters { clusters, members }
    }

    /// Calls `plant` with the index of every plant the frame may draw: the plants of the
    /// clusters in view, except clusters of masses whose plants are all small enough for
    /// their masses to draw, and clusters opened after their kind's budget filled: their
    /// plants are no larger than the `budget + 1` largest plants of their kind seen before
    /// them, which `plant` tells by returning the plant's projected size (a cluster outside
    /// masses only when its plants are no taller than `lone_kept_above`). Clusters are opened
    /// largest first. Returns how many plants were visited.
    pub(super) fn visit(&self, view: &ClusterView<'_>, mut plant: impl FnMut(u32) -> Option<f32>) -> u64 {
        let mut open: Vec<(f32, usize)> = Vec::new();
        for (index, c) in self.clusters.iter().enumerate() {
            if sphere_outside(view.planes, c.center, c.radius) {
                continue;
            }
            let largest_px = match view.plan {
                Some(m) => 2.0 * c.crown / m,
                None => {
                    let nearest = (c.center - view.eye).dot(view.forward) - c.radius;
                    if nearest <= 0.0 { f32::INFINITY } else { c.height * view.px_per_metre / nearest }
                }
            };
            if c.massed && view.massed_below.is_some_and(|edge| largest_px <= edge) {
                continue;
            }
            open.push((largest_px, index));
        }
        open.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        // Per kind (outside masses, of masses) the `budget + 1` largest plants so far (sizes
        // are positive, so their bits order as the sizes do), smallest on top.
        let mut largest: [BinaryHeap<Reverse<u32>>; 2] = Default::default();
        // Plants of masses are only left to their masses when there are masses.
        let budgets = [view.budgets[0], if view.massed_below.is_some() { view.budgets[1] } else { 0 }];
        let mut visited = 0;
        for (largest_px, index) in open {
            let c = &self.clusters[index];
            let kind = usize::from(c.massed);
            let (heap, budget) = (&mut largest[kind], budgets[kind] as usize);
            let full = budget > 0 && heap.len() > budget && (c.massed || largest_px <= view.lone_kept_above);
            if full && heap.peek().is_some_and(|Reverse(bits)| f32::from_bits(*bits) >= largest_px) {
                continue;
            }
            for &i in &self.members[c.members.clone()] {
                visited += 1;
                if let Some(px) = plant(i)
                    && budget > 0
                    && px > 0.0
                {
                    heap.push(Reverse(px.to_bits()));
                    if heap.len() > budget + 1 {
                        heap.pop();
                    }
                }
            }
        }
        visited
    }
}
