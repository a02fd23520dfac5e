//! What a frame draws over the finished sketch, in the marks pass (`shaders/marks.wgsl`,
//! declared as [`super::passes::MARKS`]): pen-drawn numbered pins of comments standing at
//! world points, and the pen line of a before/after split ([`super::compare`]). Pins are a
//! handful of instanced quads read from one uniform block; a frame without pins or split does
//! not run the pass at all.

use super::creases::CreaseCounts;
use super::uniforms::{Mat4f, Vec2f, Vec3f, Vec4f, gpu_block};
use crate::fields::legend::Canvas;
use crate::scene::camera::Camera;
use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::ascii::FONT_9X18_BOLD;
use embedded_graphics::pixelcolor::{Rgb888, RgbColor};
use embedded_graphics::prelude::{Drawable, Point};
use embedded_graphics::text::{Baseline, Text};
use glam::Vec3;

/// Pins in a row of [`Marks::pins`] (the GPU blocks' arrays have at most 32 elements, for
/// `Default`).
pub const PIN_ROW: usize = 32;
/// Pins a frame draws at most; beyond, the ones nearest the camera. The block stays within
/// the 16 KiB a uniform binding may have on every adapter.
pub const MAX_PINS: usize = PIN_ROW * 15;
/// Radius of a pin's head in scene metres: its size on screen follows distance…
pub const HEAD_METRES: f32 = 2.5;
/// …but never below this radius in pixels (two legible digits)…
pub const HEAD_MIN_PX: f32 = 11.0;
/// …nor above this one.
pub const HEAD_MAX_PX: f32 = 18.0;

/// A comment pinned in the landscape, as the renderer draws it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pin {
    /// The point the pin stands on, scene metres.
    pub position: Vec3,
    /// The number in its head (the comment's number; shown modulo 10 000).
    pub number: u32,
    /// The comment's category (its index in the scene's categories): the head's tint.
    pub category: u8,
}

/// A pin in a view's JSON (and so its ETag): `[x, y, z, number, category]`.
impl serde::Serialize for Pin {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let [x, y, z] = self.position.to_array();
        (x, y, z, self.number, self.category).serialize(serializer)
    }
}

gpu_block! {
    /// One pin as the marks pass reads it.
    pub struct PinMark {
        /// The ground point, scene metres.
        pub position: Vec3f,
        /// The number in the head.
        pub number: u32,
        /// The category (the head's tint).
        pub category: u32,
    }
}

gpu_block! {
    /// The uniform block of the marks pass (`marks` in `shaders/marks.wgsl`).
    pub struct Marks {
        /// World → clip.
        pub view_proj: Mat4f,
        /// World → view (the linear depth of a pin, as the G-buffer stores it).
        pub view: Mat4f,
        /// Image size in pixels.
        pub size: Vec2f,
        /// Pixels per metre at unit depth (perspective), or 0.
        pub px_per_metre: f32,
        /// Metres per pixel of a plan view, or 0.
        pub plan_metres_per_pixel: f32,
        /// The before/after split line in pixels from the left (negative: none).
        pub split_x: f32,
        /// Pins in `pins`.
        pub pin_count: u32,
        /// Head radius in metres and its bounds in pixels (x: metres, y: min, z: max).
        pub head: Vec3f,
        /// The ink box of a digit in its atlas cell, texels (x, y, width, height).
        pub glyph_box: Vec4f,
        /// The atlas cell of a digit, texels (its gutter included).
        pub glyph_cell: Vec2f,
        /// The creases pass's instances: the first this many are the first segments of the
        /// crease buffer (valleys and ridges), the rest count from `first_break` (breaks of
        /// slope; [`crate::render::creases::CreaseSet`]).
        pub crease_areas: u32,
        /// Where the breaks of slope begin in the crease buffer.
        pub first_break: u32,
        /// The pins, farthest first, in rows of [`PIN_ROW`].
        pub pins: [[PinMark; PIN_ROW]; MAX_PINS / PIN_ROW],
    }
}

impl Marks {
    /// The block for `pins` seen by `camera` in a `width` × `height` frame, with the split
    /// line at `split_x` pixels (if any), the digits laid out as in `glyphs`. Pins behind the
    /// camera are left out; of the rest, the [`MAX_PINS`] nearest, farthest first.
    pub fn new(
        camera: &Camera,
        (width, height): (u32, u32),
        pins: &[Pin],
        split_x: Option<f32>,
        glyphs: &GlyphAtlas,
    ) -> Box<Marks> {
        let view = camera.view();
        let depth = |p: Vec3| -(view * p.extend(1.0)).z;
        let mut ahead: Vec<(f32, &Pin)> =
            pins.iter().map(|p| (depth(p.position), p)).filter(|(d, _)| *d > 0.0).collect();
        ahead.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut marks = Box::new(Marks {
            view_proj: (camera.projection(width as f32 / height as f32) * view).into(),
            view: view.into(),
            size: Vec2f([width as f32, height as f32]),
            px_per_metre: match camera.projection.is_perspective() {
                true => height as f32 / (2.0 * (camera.fov.to_radians() * 0.5).tan()),
                false => 0.0,
            },
            plan_metres_per_pixel: camera.plan_metres_per_pixel(width).unwrap_or(0.0),
            split_x: split_x.unwrap_or(-1.0),
            pin_count: ahead.len().min(MAX_PINS) as u32,
            head: Vec3f([HEAD_METRES, HEAD_MIN_PX, HEAD_MAX_PX]),
            glyph_box: Vec4f(glyphs.ink_box.map(|v| v as f32)),
            glyph_cell: Vec2f([glyphs.cell[0] as f32, glyphs.cell[1] as f32]),
            ..Marks::default()
        });
        // Drawn in order, the farthest first, so that nearer pins overlap farther ones.
        ahead.truncate(MAX_PINS);
        ahead.reverse();
        for (slot, (_, pin)) in marks.pins.iter_mut().flatten().zip(ahead) {
            *slot = PinMark { position: pin.position.into(), number: pin.number, category: u32::from(pin.category) };
        }
        marks
    }

    /// This block with the crease segments a frame draws (`counts`), the breaks of slope
    /// from `first_break` in the crease buffer.
    pub fn with_creases(mut self: Box<Marks>, counts: CreaseCounts, first_break: u32) -> Box<Marks> {
        self.crease_areas = counts.areas;
        self.first_break = first_break;
        self
    }

    /// Instances the marks pass draws: one quad per pin, one for the split line.
    pub fn instances(&self) -> u32 {
        self.pin_count + u32::from(self.split_x >= 0.0)
    }
}

/// The digits 0–9 of a bold bitmap font (`embedded-graphics`' 9×18) side by side in one
/// coverage texture, each in a cell with a one-texel gutter so that filtering inside a cell
/// never reads its neighbour.
pub struct GlyphAtlas {
    /// Coverage 0…255, row-major.
    pub texels: Vec<u8>,
    /// Texels across and down.
    pub size: [u32; 2],
    /// One digit's cell (gutter included).
    pub cell: [u32; 2],
    /// The box the digits' ink covers within a cell: x, y, width, height.
    pub ink_box: [u32; 4],
}

impl GlyphAtlas {
    /// Rasterizes the digits.
    pub fn digits() -> GlyphAtlas {
        let glyph = FONT_9X18_BOLD.character_size;
        let cell = [glyph.width + 2, glyph.height + 2];
        let size = [cell[0] * 10, cell[1]];
        let mut canvas = Canvas(image::RgbaImage::from_pixel(size[0], size[1], image::Rgba([0, 0, 0, 255])));
        let style = MonoTextStyle::new(&FONT_9X18_BOLD, Rgb888::WHITE);
        for digit in 0..10u32 {
            let text = digit.to_string();
            let origin = Point::new((digit * cell[0] + 1) as i32, 1);
            // Drawing on a Canvas cannot fail (Infallible).
            let _ = Text::with_baseline(&text, origin, style, Baseline::Top).draw(&mut canvas);
        }
        let texels: Vec<u8> = canvas.0.pixels().map(|p| p[0]).collect();
        // The ink box over all digits, in cell coordinates.
        let (mut lo, mut hi) = ([u32::MAX; 2], [0u32; 2]);
        for (i, _) in texels.iter().enumerate().filter(|(_, t)| **t > 0) {
            let (x, y) = (i as u32 % size[0] % cell[0], i as u32 / size[0]);
            lo = [lo[0].min(x), lo[1].min(y)];
            hi = [hi[0].max(x), hi[1].max(y)];
        }
        GlyphAtlas { texels, size, cell, ink_box: [lo[0], lo[1], hi[0] + 1 - lo[0], hi[1] + 1 - lo[1]] }
    }

    /// Uploads the atlas as an `R8Unorm` texture (read by `glyphs` in the marks pass).
    pub fn upload(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> wgpu::TextureView {
        use wgpu::util::DeviceExt;
        let texture = device.create_texture_with_data(
            queue,
            &wgpu::TextureDescriptor {
                label: Some("pin digits"),
                size: wgpu::Extent3d { width: self.size[0], height: self.size[1], depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            &self.texels,
        );
        texture.create_view(&Default::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_atlas_holds_ten_distinct_digits_inside_their_cells() {
        let atlas = GlyphAtlas::digits();
        let [w, h] = atlas.cell;
        let [x0, y0, bw, bh] = atlas.ink_box;
        assert!(x0 >= 1 && y0 >= 1 && x0 + bw < w && y0 + bh < h, "ink stays off the gutter: {:?}", atlas.ink_box);
        assert!(bh >= 10, "digits are tall enough to read: {bh} texels");
        let digit = |d: u32| -> Vec<u8> {
            (0..h)
                .flat_map(|y| (0..w).map(move |x| (y, x)))
                .map(|(y, x)| atlas.texels[(y * atlas.size[0] + d * w + x) as usize])
                .collect()
        };
        let all: Vec<Vec<u8>> = (0..10).map(digit).collect();
        for (i, a) in all.iter().enumerate() {
            assert!(a.iter().any(|t| *t > 0), "digit {i} has ink");
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn the_shader_reads_the_pins_in_rows_of_pin_row() {
        let shader = crate::render::passes::MARKS.shader;
        assert!(shader.contains(&format!("const PIN_ROW: u32 = {PIN_ROW}u;")));
    }

    #[test]
    fn marks_keep_the_nearest_pins_in_front_of_the_camera() {
        let camera = Camera::perspective([0.0, 0.0, 10.0], 0.0, 0.0, 60.0);
        let pin = |y: f32, number| Pin { position: Vec3::new(0.0, y, 10.0), number, category: 1 };
        let pins = [pin(300.0, 3), pin(-50.0, 9), pin(100.0, 1)];
        let marks = Marks::new(&camera, (400, 300), &pins, Some(100.0), &GlyphAtlas::digits());
        assert_eq!(marks.pin_count, 2, "the pin behind the camera is left out");
        assert_eq!((marks.pins[0][0].number, marks.pins[0][1].number), (3, 1), "farthest first");
        assert_eq!(marks.instances(), 3);
        let many: Vec<Pin> = (0..MAX_PINS as u32 + 10).map(|i| pin(10.0 + i as f32, i)).collect();
        let marks = Marks::new(&camera, (400, 300), &many, None, &GlyphAtlas::digits());
        assert_eq!(marks.instances(), MAX_PINS as u32);
        assert_eq!(marks.pins[0][0].number, MAX_PINS as u32 - 1, "the nearest MAX_PINS, farthest first");
        assert_eq!(marks.pins[MAX_PINS / PIN_ROW - 1][PIN_ROW - 1].number, 0);
    }
}
