//! Measuring temporal coherence (SPEC R12): render a smooth camera path and compare each frame
//! with the previous one after motion compensation through the depth buffer. Strokes that stay
//! on the surfaces they draw give small differences; strokes that swim or flicker give large
//! ones.

use super::RenderError;
use super::gbuffer::BACKGROUND_DEPTH;
use super::layer_code::LayerCode;
use super::renderer::{FrameRequest, Readback, Renderer};
use super::style::Style;
use crate::scene::camera::Camera;
use glam::{Vec3, Vec4};
use serde::Serialize;

/// A smooth camera path from `start`: a pan (yaw +8°), a dolly (6 m forward), an orbit (10°
/// around a point 30 m ahead) and a roll (to 12°), `steps` frames each.
pub fn camera_path(start: &Camera, steps: usize) -> Vec<Camera> {
    let mut path = Vec::with_capacity(4 * steps + 1);
    let mut cam = *start;
    path.push(cam);
    let steps_f = steps.max(1) as f32;
    for _ in 0..steps {
        cam.yaw += 8.0 / steps_f;
        path.push(cam);
    }
    for _ in 0..steps {
        let f = cam.forward() * (6.0 / steps_f);
        cam.position = (Vec3::from(cam.position) + f).to_array();
        path.push(cam);
    }
    let pivot = Vec3::from(cam.position) + cam.forward() * 30.0;
    for _ in 0..steps {
        let offset = Vec3::from(cam.position) - pivot;
        let rotated = glam::Quat::from_rotation_z((10.0 / steps_f).to_radians()) * offset;
        cam.position = (pivot + rotated).to_array();
        cam.yaw -= 10.0 / steps_f;
        path.push(cam);
    }
    for _ in 0..steps {
        cam.roll += 12.0 / steps_f;
        path.push(cam);
    }
    path
}

fn luminance(p: &image::Rgba<u8>) -> f32 {
    (0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])) / 255.0
}

/// The luminance of `image` at the sub-pixel position (`x`, `y`) (pixel centres at whole
/// numbers), interpolated bilinearly between the four nearest pixels.
fn bilinear_luminance(image: &image::RgbaImage, x: f32, y: f32) -> f32 {
    let (w, h) = image.dimensions();
    let (x, y) = (x.clamp(0.0, (w - 1) as f32), y.clamp(0.0, (h - 1) as f32));
    let (x0, y0) = (x.floor() as u32, y.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let l = |x, y| luminance(image.get_pixel(x, y));
    let top = l(x0, y0) * (1.0 - fx) + l(x1, y0) * fx;
    let bottom = l(x0, y1) * (1.0 - fx) + l(x1, y1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// World position of pixel `(x, y)` at linear depth `depth` seen by `camera`.
fn unproject(camera: &Camera, x: f32, y: f32, depth: f32, width: u32, height: u32) -> Vec3 {
    let tan = (camera.fov.to_radians() * 0.5).tan();
    let aspect = width as f32 / height as f32;
    let ndc_x = (x + 0.5) / width as f32 * 2.0 - 1.0;
    let ndc_y = 1.0 - (y + 0.5) / height as f32 * 2.0;
    let view_pos = Vec4::new(ndc_x * tan * aspect * depth, ndc_y * tan * depth, -depth, 1.0);
    (camera.view().inverse() * view_pos).truncate()
}

/// Pixel coordinates and linear depth of world point `p` seen by `camera`.
fn project(camera: &Camera, p: Vec3, width: u32, height: u32) -> Option<(f32, f32, f32)> {
    let v = camera.view() * p.extend(1.0);
    let depth = -v.z;
    if depth <= 0.0 {
        return None;
    }
    let tan = (camera.fov.to_radians() * 0.5).tan();
    let aspect = width as f32 / height as f32;
    let ndc_x = v.x / (depth * tan * aspect);
    let ndc_y = v.y / (depth * tan);
    Some(((ndc_x + 1.0) * 0.5 * width as f32 - 0.5, (1.0 - ndc_y) * 0.5 * height as f32 - 0.5, depth))
}

/// One frame of a coherence measurement: its camera, image, linear depth and object IDs.
pub struct MeasuredFrame<'a> {
    /// The camera the frame was rendered with.
    pub camera: &'a Camera,
    /// The rendered image.
    pub image: &'a image::RgbaImage,
    /// Linear depth per pixel (metres).
    pub depth: &'a [f32],
    /// Object ID per pixel (its layer code in the top bits).
    pub ids: &'a [u32],
}

/// Sums of absolute luminance differences and pixel counts: of every geometry pixel, and of
/// the terrain's alone.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Difference {
    /// Sum of the differences of all compared pixels.
    pub sum: f64,
    /// Pixels compared.
    pub count: usize,
    /// Sum of the differences of the compared terrain pixels.
    pub terrain_sum: f64,
    /// Terrain pixels compared.
    pub terrain_count: usize,
}

impl Difference {
    /// The mean difference of all compared pixels (0 when none was).
    pub fn mean(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.sum / self.count as f64 }
    }

    /// The mean difference of the compared terrain pixels (0 when none was).
    pub fn terrain_mean(&self) -> f64 {
        if self.terrain_count == 0 { 0.0 } else { self.terrain_sum / self.terrain_count as f64 }
    }
}

/// One pixel compared by [`compensated_pixels`].
struct ComparedPixel {
    x: u32,
    y: u32,
    /// The absolute luminance difference to the previous frame.
    difference: f64,
    /// Whether the pixel shows the terrain (by the current frame's object IDs).
    terrain: bool,
}

/// The current frame's geometry pixels, each reprojected into the previous frame through its
/// depth, with the absolute difference of its luminance to the previous frame's there
/// (interpolated bilinearly at the reprojected position); pixels that were hidden or outside
/// the previous frame (depth mismatch over 2 %) are skipped.
fn compensated_pixels<'a>(
    previous: &'a MeasuredFrame<'a>,
    current: &'a MeasuredFrame<'a>,
) -> impl Iterator<Item = ComparedPixel> + 'a {
    let (w, h) = current.image.dimensions();
    (0..h).flat_map(move |y| (0..w).map(move |x| (x, y))).filter_map(move |(x, y)| {
        let index = (y * w + x) as usize;
        let depth = current.depth[index];
        if f64::from(depth) >= BACKGROUND_DEPTH * 0.5 {
            return None;
        }
        let world = unproject(current.camera, x as f32, y as f32, depth, w, h);
        let (px, py, pd) = project(previous.camera, world, w, h)?;
        let (qx, qy) = (px.round(), py.round());
        if qx < 0.0 || qy < 0.0 || qx >= w as f32 || qy >= h as f32 {
            return None;
        }
        let previous_depth = previous.depth[(qy as u32 * w + qx as u32) as usize];
        if (previous_depth - pd).abs() > 0.02 * pd {
            return None;
        }
        let a = luminance(current.image.get_pixel(x, y));
        let b = bilinear_luminance(previous.image, px, py);
        let terrain = current.ids.get(index).is_some_and(|id| LayerCode::of_object_id(*id) == LayerCode::TERRAIN);
        Some(ComparedPixel { x, y, difference: f64::from((a - b).abs()), terrain })
    })
}

/// Absolute luminance differences between `current` and `previous` after reprojecting each of
/// the current frame's geometry pixels into the previous frame ([`compensated_pixels`]), the
/// terrain pixels (by the current frame's object IDs) also summed on their own; and the same
/// as an image, to see where flicker comes from: white where the pixels agree (or were not
/// compared), darker the more they differ (a difference of 0.5 or more is black). One pass
/// over the pixels gives both.
pub fn compensated_difference(previous: &MeasuredFrame, current: &MeasuredFrame) -> (Difference, image::GrayImage) {
    let (w, h) = current.image.dimensions();
    let mut diff = Difference::default();
    let mut map = image::GrayImage::from_pixel(w, h, image::Luma([255]));
    for pixel in compensated_pixels(previous, current) {
        diff.sum += pixel.difference;
        diff.count += 1;
        if pixel.terrain {
            diff.terrain_sum += pixel.difference;
            diff.terrain_count += 1;
        }
        let dark = (pixel.difference * 2.0 * 255.0).min(255.0) as u8;
        map.put_pixel(pixel.x, pixel.y, image::Luma([255 - dark]));
    }
    (diff, map)
}

/// The flicker figures of one style along a camera path.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Flicker {
    /// Mean over consecutive frame pairs of the mean difference of every compared pixel.
    pub whole_frame: f64,
    /// The same of the terrain's pixels alone.
    pub terrain: f64,
    /// The share of the first frame's terrain pixels more ink than paper (luminance below
    /// 0.5): the check that less flicker comes neither from fewer strokes nor from blurred,
    /// grey ones.
    pub terrain_ink: f64,
}

/// What rendering a style along a camera path measured: the motion-compensated difference
/// ([`compensated_difference`]) of every consecutive frame pair, the first frame's terrain
/// ink share ([`terrain_ink_share`]) and the frames themselves (to look at where a figure
/// comes from: `landsketch coherence --frames`).
pub struct PathMeasurement {
    /// The difference of each consecutive frame pair, in the path's order.
    pub differences: Vec<Difference>,
    /// The share of the first frame's terrain pixels more ink than paper.
    pub terrain_ink: f64,
    /// The rendered frames, in the path's order.
    pub frames: Vec<image::RgbaImage>,
    /// The difference map of each consecutive frame pair ([`compensated_difference`]), in
    /// the path's order.
    pub difference_maps: Vec<image::GrayImage>,
}

impl PathMeasurement {
    /// The flicker figures: the means over consecutive frame pairs of the whole-frame and the
    /// terrain-only differences (pairs that share such pixels).
    pub fn flicker(&self) -> Flicker {
        let mean = |values: Vec<f64>| {
            if values.is_empty() { 0.0 } else { values.iter().sum::<f64>() / values.len() as f64 }
        };
        let d = &self.differences;
        Flicker {
            whole_frame: mean(d.iter().filter(|d| d.count > 0).map(Difference::mean).collect()),
            terrain: mean(d.iter().filter(|d| d.terrain_count > 0).map(Difference::terrain_mean).collect()),
            terrain_ink: self.terrain_ink,
        }
    }
}

/// Renders `style` along `path` with one view state, so the hybrid hatching follows the camera,
/// and measures every consecutive frame pair.
pub fn measure_path(
    renderer: &Renderer,
    style: &Style,
    path: &[Camera],
    width: u32,
    height: u32,
) -> Result<PathMeasurement, RenderError> {
    let mut state = renderer.new_view_state();
    let mut previous: Option<(Camera, image::RgbaImage, Vec<f32>, Vec<u32>)> = None;
    let mut differences = Vec::with_capacity(path.len());
    let mut frames = Vec::with_capacity(path.len());
    let mut difference_maps = Vec::with_capacity(path.len());
    let mut terrain_ink = None;
    for camera in path {
        let request = FrameRequest::new(camera, style, width, height).history(&mut state);
        let frame = renderer.render(request.read(Readback { depth: true, ids: true }))?;
        let depth = frame.depth.unwrap_or_default();
        let ids = frame.ids.unwrap_or_default();
        terrain_ink.get_or_insert_with(|| terrain_ink_share(&frame.image, &ids));
        if let Some((prev_cam, prev_image, prev_depth, prev_ids)) = &previous {
            let before = MeasuredFrame { camera: prev_cam, image: prev_image, depth: prev_depth, ids: prev_ids };
            let now = MeasuredFrame { camera, image: &frame.image, depth: &depth, ids: &ids };
            let (difference, map) = compensated_difference(&before, &now);
            differences.push(difference);
            difference_maps.push(map);
        }
        frames.push(frame.image.clone());
        previous = Some((*camera, frame.image, depth, ids));
    }
    Ok(PathMeasurement { differences, terrain_ink: terrain_ink.unwrap_or(0.0), frames, difference_maps })
}

/// The whole-frame difference of every consecutive frame pair of `style` along `path` that
/// shares pixels: a spike among them is a pop.
pub fn frame_differences(
    renderer: &Renderer,
    style: &Style,
    path: &[Camera],
    width: u32,
    height: u32,
) -> Result<Vec<f64>, RenderError> {
    let measured = measure_path(renderer, style, path, width, height)?;
    Ok(measured.differences.iter().filter(|d| d.count > 0).map(Difference::mean).collect())
}

/// The flicker figures of `style` along `path`: the means over consecutive frame pairs of the
/// whole-frame and the terrain-only differences (pairs that share such pixels).
pub fn flicker(
    renderer: &Renderer,
    style: &Style,
    path: &[Camera],
    width: u32,
    height: u32,
) -> Result<Flicker, RenderError> {
    Ok(measure_path(renderer, style, path, width, height)?.flicker())
}

/// The share of the terrain pixels of `image` (by the object IDs `ids`) more ink than paper:
/// luminance below 0.5.
pub fn terrain_ink_share(image: &image::RgbaImage, ids: &[u32]) -> f64 {
    let (mut inked, mut terrain) = (0usize, 0usize);
    for (pixel, id) in image.pixels().zip(ids) {
        if LayerCode::of_object_id(*id) == LayerCode::TERRAIN {
            terrain += 1;
            inked += usize::from(luminance(pixel) < 0.5);
        }
    }
    if terrain == 0 { 0.0 } else { inked as f64 / terrain as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unproject_inverts_project() {
        let cam = Camera { roll: 7.0, ..Camera::perspective([3.0, -4.0, 12.0], 30.0, -5.0, 50.0) };
        let p = unproject(&cam, 100.0, 40.0, 25.0, 320, 240);
        let (x, y, d) = project(&cam, p, 320, 240).unwrap();
        assert!((x - 100.0).abs() < 1e-2 && (y - 40.0).abs() < 1e-2 && (d - 25.0).abs() < 1e-3, "{x} {y} {d}");
    }

    #[test]
    fn path_is_smooth_and_ends_rolled() {
        let start = Camera::perspective([0.0, 0.0, 2.0], 0.0, 0.0, 60.0);
        let path = camera_path(&start, 5);
        assert_eq!(path.len(), 21);
        assert!((path[20].roll - 12.0).abs() < 1e-4);
        for pair in path.windows(2) {
            let moved = Vec3::from(pair[1].position).distance(Vec3::from(pair[0].position));
            assert!(moved < 1.5 && (pair[1].yaw - pair[0].yaw).abs() <= 2.0 + 1e-4);
        }
    }
}
