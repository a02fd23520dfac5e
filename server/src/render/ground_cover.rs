//! The land-cover classes of the ground as the shaders read them (`cover` in
//! `shaders/gbuffer.wgsl` and `shaders/cover_common.wgsl`): one [`CoverStyle`] per class of the
//! scene's drape ([`crate::scene::cover`]), entry 0 the plain ground. The G-buffer pass writes
//! a terrain pixel's class into its patch ID and turns its strokes by the class; the contour
//! pass shifts its tone and outlines class borders; the data and compose passes pick its
//! tonal art map.

use super::uniforms::{Vec2f, gpu_block, storage_buffer};
use crate::scene::cover::{CoverClass, CoverStrokes, Drape};

gpu_block! {
    /// How the ground of one land-cover class is drawn.
    pub struct CoverStyle {
        /// Added to the hatch tone (−1..1).
        pub tone: f32,
        /// [`CoverStrokes::code`].
        pub strokes: u32,
        /// `furrows`: the strokes' direction on the ground (x east, y north), a unit vector
        /// so the shader does not evaluate its cosine and sine per pixel.
        pub direction: Vec2f,
        /// Tonal art map index, −1 for the style's.
        pub hatch_map: i32,
        /// 1 where borders with other classes are outlined.
        pub outline: f32,
    }
}

impl CoverStyle {
    /// The block of `class`; `None` is the plain ground (the style's strokes, no outline).
    pub fn new(class: Option<&CoverClass>) -> CoverStyle {
        match class {
            None => CoverStyle { strokes: CoverStrokes::Style.code(), hatch_map: -1, ..Default::default() },
            Some(c) => CoverStyle {
                tone: c.tone,
                strokes: c.strokes.code(),
                direction: glam::Vec2::from_angle((90.0 - c.angle).to_radians()).into(),
                hatch_map: c.hatch_map.map_or(-1, |m| m as i32),
                outline: f32::from(u8::from(c.outline)),
            },
        }
    }
}

/// The storage buffer of `drape`'s classes, plain ground first (index 0, the drape's "no
/// class").
pub fn cover_buffer(device: &wgpu::Device, drape: &Drape) -> wgpu::Buffer {
    let blocks: Vec<CoverStyle> =
        std::iter::once(CoverStyle::new(None)).chain(drape.classes.iter().map(|c| CoverStyle::new(Some(c)))).collect();
    storage_buffer(device, "land-cover classes", &blocks)
}
