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

/// The storage buffer of `segments` (one zeroed segment when there are none: a binding
/// cannot be empty) and their count.
pub fn crease_buffer(device: &wgpu::Device, segments: &[CreaseSegment]) -> (wgpu::Buffer, u32) {
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
    let count = lines.len() as u32;
    if lines.is_empty() {
        lines.push(CreaseLine::default());
    }
    (storage_buffer(device, "crease lines", &lines), count)
}
