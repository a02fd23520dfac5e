//! Perspective cameras in scene coordinates (x east, y north, z up, metres).

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

/// A perspective camera: eye position, compass heading, pitch and vertical field of view.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Eye position in scene metres.
    pub position: [f32; 3],
    /// Compass heading in degrees: 0 looks north (+y), 90 east (+x).
    pub yaw: f32,
    /// Degrees above (+) or below (−) the horizon.
    pub pitch: f32,
    /// Vertical field of view in degrees.
    pub fov: f32,
    /// Rotation about the view direction in degrees; positive turns the camera clockwise (its
    /// up vector leans right), so the picture turns counter-clockwise.
    #[serde(default)]
    pub roll: f32,
}

/// Nearest distance the camera sees, in metres (the projection has no far plane).
pub const NEAR_PLANE: f32 = 0.25;

impl Camera {
    /// Unit vector the camera looks along.
    pub fn forward(&self) -> Vec3 {
        let (yaw, pitch) = (self.yaw.to_radians(), self.pitch.clamp(-89.9, 89.9).to_radians());
        Vec3::new(yaw.sin() * pitch.cos(), yaw.cos() * pitch.cos(), pitch.sin())
    }

    /// World → view matrix (right-handed, z up in the world, rolled by `roll`).
    pub fn view(&self) -> Mat4 {
        let eye = Vec3::from(self.position);
        let forward = self.forward();
        let right = forward.cross(Vec3::Z).try_normalize().unwrap_or(Vec3::X);
        let up = right.cross(forward);
        let roll = self.roll.to_radians();
        glam::camera::rh::view::look_at_mat4(eye, eye + forward, up * roll.cos() + right * roll.sin())
    }

    /// View → clip matrix: reverse-Z infinite perspective (depth 1 at the near plane, 0 at
    /// infinity), which keeps depth precision from a blade of grass to the horizon.
    pub fn projection(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective_infinite_reverse(
            self.fov.clamp(1.0, 170.0).to_radians(),
            aspect,
            NEAR_PLANE,
        )
    }

    /// Checks that every number is finite and the field of view is within 1..=170 degrees.
    pub fn is_valid(&self) -> bool {
        self.position.iter().chain([&self.yaw, &self.pitch, &self.roll]).all(|v| v.is_finite())
            && (1.0..=170.0).contains(&self.fov)
            && (-90.0..=90.0).contains(&self.pitch)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heading_follows_the_compass() {
        let mut cam = Camera { position: [0.0; 3], yaw: 0.0, pitch: 0.0, fov: 60.0, roll: 0.0 };
        assert!((cam.forward() - Vec3::Y).length() < 1e-6);
        cam.yaw = 90.0;
        assert!((cam.forward() - Vec3::X).length() < 1e-6);
        cam.pitch = 90.0;
        assert!(cam.forward().z > 0.99);
    }

    #[test]
    fn point_ahead_projects_to_the_centre_with_reverse_depth() {
        let cam = Camera { position: [10.0, 20.0, 2.0], yaw: 90.0, pitch: 0.0, fov: 60.0, roll: 0.0 };
        let clip = cam.projection(1.5) * cam.view() * glam::Vec4::new(110.0, 20.0, 2.0, 1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5);
        let near = cam.projection(1.5) * cam.view() * glam::Vec4::new(10.0 + NEAR_PLANE, 20.0, 2.0, 1.0);
        assert!((near.z / near.w - 1.0).abs() < 1e-5);
        assert!(ndc.z > 0.0 && ndc.z < 0.01);
    }

    #[test]
    fn positive_roll_turns_the_picture_counter_clockwise() {
        let cam = Camera { position: [0.0; 3], yaw: 0.0, pitch: 0.0, fov: 60.0, roll: 30.0 };
        // A point straight above the view axis appears up and to the left.
        let clip = cam.projection(1.0) * cam.view() * glam::Vec4::new(0.0, 10.0, 1.0, 1.0);
        assert!(clip.x / clip.w < -0.01 && clip.y / clip.w > 0.01, "{clip:?}");
    }
}
