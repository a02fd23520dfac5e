//! The terrain's crease lines ([`crate::prep::creases`]) on the GPU: one [`CreaseLine`] per
//! segment in a storage buffer that the creases pass (`shaders/creases.wgsl`, declared as
//! [`super::passes::CREASES`]) draws as pen lines of constant width on screen, fixed to the
//! ground, hidden where nearer geometry covers them.

use super::uniforms::{Vec3f, gpu_block, storage_buffer};
use crate::prep::creases::{CreaseKind, CreaseSegment};

gpu_block! {
    /// One segment of a crease line as the creases pass reads it.
    pub struct CreaseLine {
        /// One end, scene metres.
        pub a: Vec3f,
        /// How strong it is: the area drained in hectares (valleys, ridges), the change of
        /// slope in degrees (breaks of slope).
        pub measure: f32,
        /// The other end.
        pub b: Vec3f,
        /// [`crate::prep::creases::CreaseKind`]: 0 valley, 1 ridge, 2 break of slope.
        pub kind: u32,
    }
}

/// The scene's crease lines on the GPU, ordered so that a frame draws only the segments its
/// terrain style's thresholds keep: valleys and ridges first, by the area they drain, largest
/// first, then breaks of slope, by their change of slope, largest first. Most segments of a
/// DEM drain little (72,000 of the sample valley's, of which a few thousand reach 20 ha): a
/// frame's instances are the two prefixes above the thresholds, so the pass costs what it
/// draws (the vertex shader maps an instance past the first prefix into the second).
pub struct CreaseSet {
    /// The segments in that order (one zeroed segment when there are none: a binding cannot
    /// be empty).
    pub buffer: wgpu::Buffer,
    /// The measures of the valleys and ridges (hectares), descending.
    areas: Vec<f32>,
    /// The measures of the breaks of slope (degrees), descending; they follow the areas in
    /// the buffer.
    breaks: Vec<f32>,
}

impl CreaseSet {
    /// Uploads `segments` in the drawing order.
    pub fn new(device: &wgpu::Device, segments: &[CreaseSegment]) -> CreaseSet {
        let mut lines: Vec<CreaseLine> = segments
            .iter()
            .map(|s| {
                let measure = match s.kind {
                    CreaseKind::Valley | CreaseKind::Ridge => s.measure / 10_000.0,
                    CreaseKind::Break => s.measure,
                };
                CreaseLine { a: s.a.into(), measure: measure as f32, b: s.b.into(), kind: s.kind as u32 }
            })
            .collect();
        let is_break = |l: &CreaseLine| l.kind == CreaseKind::Break as u32;
        lines.sort_by(|x, y| is_break(x).cmp(&is_break(y)).then(y.measure.total_cmp(&x.measure)));
        let (areas, breaks): (Vec<&CreaseLine>, Vec<&CreaseLine>) = lines.iter().partition(|l| !is_break(l));
        let (areas, breaks) = (areas.iter().map(|l| l.measure).collect(), breaks.iter().map(|l| l.measure).collect());
        if lines.is_empty() {
            lines.push(CreaseLine::default());
        }
        CreaseSet { buffer: storage_buffer(device, "crease lines", &lines), areas, breaks }
    }

    /// What a frame draws at the thresholds `area` (hectares) and `angle` (degrees): how many
    /// valleys and ridges reach `area`, and how many breaks reach `angle`.
    pub fn drawn(&self, area: f32, angle: f32) -> CreaseCounts {
        let reaching = |measures: &[f32], threshold: f32| measures.partition_point(|&m| m >= threshold) as u32;
        CreaseCounts { areas: reaching(&self.areas, area), breaks: reaching(&self.breaks, angle) }
    }

    /// Where the breaks of slope begin in the buffer.
    pub fn first_break(&self) -> u32 {
        self.areas.len() as u32
    }
}

/// The crease segments a frame draws (see [`CreaseSet::drawn`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CreaseCounts {
    /// Valleys and ridges: the first this many of the buffer.
    pub areas: u32,
    /// Breaks of slope: this many from [`CreaseSet::first_break`].
    pub breaks: u32,
}

impl CreaseCounts {
    /// Instances of the creases pass.
    pub fn instances(self) -> u32 {
        self.areas + self.breaks
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Gpu;

    #[test]
    fn a_frame_draws_the_segments_above_its_thresholds() {
        let Ok(gpu) = Gpu::new() else { return };
        let segment = |kind, measure: f64| CreaseSegment { a: glam::Vec3::ZERO, b: glam::Vec3::X, kind, measure };
        let segments = [
            segment(CreaseKind::Valley, 5.0e4),
            segment(CreaseKind::Break, 30.0),
            segment(CreaseKind::Ridge, 50.0e4),
            segment(CreaseKind::Valley, 1.0e4),
            segment(CreaseKind::Break, 10.0),
            segment(CreaseKind::Valley, 25.0e4),
        ];
        let set = CreaseSet::new(&gpu.device, &segments);
        assert_eq!(set.first_break(), 4);
        assert_eq!(set.drawn(20.0, 15.0), CreaseCounts { areas: 2, breaks: 1 }, "50 and 25 ha, 30°");
        assert_eq!(set.drawn(0.5, 5.0), CreaseCounts { areas: 4, breaks: 2 });
        assert_eq!(set.drawn(100.0, 90.0).instances(), 0);
    }
}
