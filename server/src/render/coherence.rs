//! Measuring temporal coherence (SPEC R12): render a smooth camera path and compare each frame
//! with the previous one after motion compensation through the depth buffer. Strokes that stay
//! on the surfaces they draw give small differences; strokes that swim or flicker give large
//! ones.

use super::RenderError;
use super::gbuffer::BACKGROUND_DEPTH;
use super::renderer::{FrameRequest, Readback, Renderer};
use super::style::Style;
use crate::scene::camera::Camera;
use glam::{Vec3, Vec4};

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

/// Mean absolute luminance difference between `current` and `previous` after reprojecting each
/// of the current frame's geometry pixels into the previous frame; pixels that were hidden or
/// outside the previous frame (depth mismatch over 2 %) are skipped. Returns the mean and the
/// number of pixels compared. Each frame is its camera, image and linear depth.
pub fn compensated_difference(
    previous: (&Camera, &image::RgbaImage, &[f32]),
    current: (&Camera, &image::RgbaImage, &[f32]),
) -> (f64, usize) {
    let (w, h) = current.1.dimensions();
    let mut sum = 0.0;
    let mut count = 0usize;
    for y in 0..h {
        for x in 0..w {
            let depth = current.2[(y * w + x) as usize];
            if f64::from(depth) >= BACKGROUND_DEPTH * 0.5 {
                continue;
            }
            let world = unproject(current.0, x as f32, y as f32, depth, w, h);
            let Some((px, py, pd)) = project(previous.0, world, w, h) else { continue };
            let (qx, qy) = (px.round(), py.round());
            if qx < 0.0 || qy < 0.0 || qx >= w as f32 || qy >= h as f32 {
                continue;
            }
            let (qx, qy) = (qx as u32, qy as u32);
            let previous_depth = previous.2[(qy * w + qx) as usize];
            if (previous_depth - pd).abs() > 0.02 * pd {
                continue;
            }
            let a = luminance(current.1.get_pixel(x, y));
            let b = luminance(previous.1.get_pixel(qx, qy));
            sum += f64::from((a - b).abs());
            count += 1;
        }
    }
    (if count == 0 { 0.0 } else { sum / count as f64 }, count)
}

/// The motion-compensated difference ([`compensated_difference`]) of every consecutive frame
/// pair of `style` along `path` that shares pixels, rendered with one view state so the hybrid
/// hatching follows the camera: a spike among them is a pop.
pub fn frame_differences(
    renderer: &Renderer,
    style: &Style,
    path: &[Camera],
    width: u32,
    height: u32,
) -> Result<Vec<f64>, RenderError> {
    let mut state = renderer.new_view_state();
    let mut previous: Option<(Camera, image::RgbaImage, Vec<f32>)> = None;
    let mut differences = Vec::with_capacity(path.len());
    for camera in path {
        let request = FrameRequest::new(camera, style, width, height).history(&mut state);
        let frame = renderer.render(request.read(Readback::DEPTH))?;
        let depth = frame.depth.unwrap_or_default();
        if let Some((prev_cam, prev_image, prev_depth)) = &previous {
            let (diff, count) =
                compensated_difference((prev_cam, prev_image, prev_depth), (camera, &frame.image, &depth));
            if count > 0 {
                differences.push(diff);
            }
        }
        previous = Some((*camera, frame.image, depth));
    }
    Ok(differences)
}

/// The flicker figure of `style` along `path`: the mean of its [`frame_differences`].
pub fn flicker(
    renderer: &Renderer,
    style: &Style,
    path: &[Camera],
    width: u32,
    height: u32,
) -> Result<f64, RenderError> {
    let differences = frame_differences(renderer, style, path, width, height)?;
    Ok(if differences.is_empty() { 0.0 } else { differences.iter().sum::<f64>() / differences.len() as f64 })
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
