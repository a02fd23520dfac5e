//! Runs of plant instances that one draw each takes: a species' meshes at a level of detail
//! (or a share of its leaf particles) with the layer style of one style slot, keyed by a
//! [`BatchKey`].

use crate::prep::leaves::PARTICLE_SHARES;
use crate::prep::lod::LodLevel;
use crate::render::gbuffer::Instance;
use crate::render::style::STYLE_SLOTS;
use std::cmp::Ordering;
use std::marker::PhantomData;
use std::ops::Range;

/// Which of a species' mesh sets a run draws besides the species: a level of detail, or a
/// share of the leaf particles.
pub(super) trait Detail: Copy {
    /// Values per species.
    const COUNT: usize;
    /// The position of the value among the [`Detail::COUNT`] values.
    fn position(self) -> usize;
    /// The value at `position`.
    fn at(position: usize) -> Self;
}

impl Detail for LodLevel {
    const COUNT: usize = LodLevel::ALL.len();

    fn position(self) -> usize {
        self.index()
    }

    fn at(position: usize) -> LodLevel {
        LodLevel::ALL[position]
    }
}

/// A share of a species' leaf particles: an index into [`PARTICLE_SHARES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Share(pub usize);

impl Detail for Share {
    const COUNT: usize = PARTICLE_SHARES.len();

    fn position(self) -> usize {
        self.0
    }

    fn at(position: usize) -> Share {
        Share(position)
    }
}

/// What one run of instances is drawn with: the meshes of `species` at `detail`, with the
/// layer style of style slot `slot`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct BatchKey<D> {
    pub species: usize,
    pub detail: D,
    pub slot: usize,
}

impl<D: Detail> BatchKey<D> {
    /// The number of keys of `species` species.
    fn count(species: usize) -> usize {
        species * D::COUNT * STYLE_SLOTS
    }

    /// The key's position among all keys, in drawing order: by species, then detail, then slot.
    pub fn index(self) -> usize {
        debug_assert!(self.detail.position() < D::COUNT && self.slot < STYLE_SLOTS);
        (self.species * D::COUNT + self.detail.position()) * STYLE_SLOTS + self.slot
    }

    /// The key at `index` (the inverse of [`BatchKey::index`]).
    pub fn from_index(index: usize) -> BatchKey<D> {
        let (kind, slot) = (index / STYLE_SLOTS, index % STYLE_SLOTS);
        BatchKey { species: kind / D::COUNT, detail: D::at(kind % D::COUNT), slot }
    }
}

/// One run of a frame's instance list and what it is drawn with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Batch<D> {
    pub key: BatchKey<D>,
    pub instances: Range<u32>,
}

/// A frame's instances as they are collected, one run per key (every key of the scene's
/// species has a place, most stay empty).
pub(super) struct Runs<D> {
    runs: Vec<Vec<Instance>>,
    detail: PhantomData<D>,
}

impl<D: Detail> Runs<D> {
    /// No instances yet, for `species` species.
    pub fn new(species: usize) -> Runs<D> {
        Runs { runs: vec![Vec::new(); BatchKey::<D>::count(species)], detail: PhantomData }
    }

    /// Adds `instance` to the run of `key`.
    pub fn push(&mut self, key: BatchKey<D>, instance: Instance) {
        self.runs[key.index()].push(instance);
    }

    /// Sorts the instances of every run by `compare` (unstably).
    pub fn sort_each(&mut self, mut compare: impl FnMut(&Instance, &Instance) -> Ordering) {
        for run in &mut self.runs {
            run.sort_unstable_by(&mut compare);
        }
    }

    /// Appends the non-empty runs to `instances` in key order; returns each one's batch.
    pub fn append_to(self, instances: &mut Vec<Instance>) -> Vec<Batch<D>> {
        let mut batches = Vec::new();
        for (index, run) in self.runs.into_iter().enumerate() {
            if run.is_empty() {
                continue;
            }
            let start = instances.len() as u32;
            instances.extend(run);
            batches.push(Batch { key: BatchKey::from_index(index), instances: start..instances.len() as u32 });
        }
        batches
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batch_keys_round_trip_in_drawing_order() {
        let keys: Vec<BatchKey<LodLevel>> = (0..BatchKey::<LodLevel>::count(3)).map(BatchKey::from_index).collect();
        for (index, key) in keys.iter().enumerate() {
            assert_eq!(key.index(), index);
        }
        assert_eq!(keys[0], BatchKey { species: 0, detail: LodLevel::Full, slot: 0 });
        assert_eq!(keys[1], BatchKey { species: 0, detail: LodLevel::Full, slot: 1 });
        assert_eq!(keys[STYLE_SLOTS], BatchKey { species: 0, detail: LodLevel::Hlp, slot: 0 });
        assert_eq!(keys[LodLevel::ALL.len() * STYLE_SLOTS], BatchKey { species: 1, detail: LodLevel::Full, slot: 0 });
        let last = BatchKey { species: 2, detail: Share(PARTICLE_SHARES.len() - 1), slot: STYLE_SLOTS - 1 };
        assert_eq!(last.index(), BatchKey::<Share>::count(3) - 1);
        assert_eq!(BatchKey::from_index(last.index()), last);
    }

    #[test]
    fn runs_append_in_key_order() {
        let instance = |x: f32| Instance {
            offset_scale: [x, 0.0, 0.0, 1.0],
            rotation: [1.0, 0.0],
            object_id: 0,
            reference_base: 0,
            mask: [0.0, 1.0],
            data_abstraction: [0.0; 2],
            reference_sphere: [0.0; 4],
        };
        let mut runs = Runs::<Share>::new(2);
        let late = BatchKey { species: 1, detail: Share(0), slot: 2 };
        let early = BatchKey { species: 0, detail: Share(3), slot: 5 };
        runs.push(late, instance(2.0));
        runs.push(early, instance(3.0));
        runs.push(early, instance(1.0));
        runs.sort_each(|a, b| a.offset_scale[0].total_cmp(&b.offset_scale[0]));
        let mut instances = vec![instance(0.0)];
        let batches = runs.append_to(&mut instances);
        assert_eq!(batches, vec![Batch { key: early, instances: 1..3 }, Batch { key: late, instances: 3..4 }]);
        let xs: Vec<f32> = instances.iter().map(|i| i.offset_scale[0]).collect();
        assert_eq!(xs, [0.0, 1.0, 3.0, 2.0], "runs in key order, each sorted");
    }
}
