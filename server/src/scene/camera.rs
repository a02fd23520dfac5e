//! Cameras in scene coordinates (x east, y north, z up, metres): perspective views and
//! orthographic top-down plan views.

use glam::{Mat4, Vec3, Vec4};
use serde::{Deserialize, Serialize};

/// How a camera projects the scene onto the image.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Projection {
    /// Perspective with the camera's vertical field of view.
    #[default]
    Perspective,
    /// Plan view: orthographic, looking straight down (−z) from the eye, `width` scene metres
    /// across the image; the compass heading `yaw` points up in the image (0: north up).
    Plan {
        /// Metres of the scene across the image width.
        width: f32,
    },
}

impl Projection {
    /// Whether this is the (default) perspective projection.
    pub fn is_perspective(&self) -> bool {
        *self == Projection::Perspective
    }
}

/// Depth range of a plan view below its eye, in metres (the orthographic far plane).
pub const PLAN_DEPTH_RANGE: f32 = 100_000.0;

/// A camera: eye position, compass heading, pitch, vertical field of view, roll and projection.
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
    /// Perspective (default) or an orthographic plan view.
    #[serde(default, skip_serializing_if = "Projection::is_perspective")]
    pub projection: Projection,
}

/// Nearest distance the camera sees, in metres (the projection has no far plane).
pub const NEAR_PLANE: f32 = 0.25;

impl Camera {
    /// A perspective camera at `position` with heading `yaw`, `pitch` and vertical field of
    /// view `fov` (degrees), not rolled.
    pub fn perspective(position: [f32; 3], yaw: f32, pitch: f32, fov: f32) -> Camera {
        Camera { position, yaw, pitch, fov, roll: 0.0, projection: Projection::Perspective }
    }

    /// A plan view centred on (`x`, `y`), `width` metres across, looking down from height `z`,
    /// north up.
    pub fn plan(x: f32, y: f32, z: f32, width: f32) -> Camera {
        Camera {
            position: [x, y, z],
            yaw: 0.0,
            pitch: -90.0,
            fov: 60.0,
            roll: 0.0,
            projection: Projection::Plan { width },
        }
    }

    /// Unit vector the camera looks along (straight down in a plan view).
    pub fn forward(&self) -> Vec3 {
        if !self.projection.is_perspective() {
            return Vec3::NEG_Z;
        }
        let (yaw, pitch) = (self.yaw.to_radians(), self.pitch.clamp(-89.9, 89.9).to_radians());
        Vec3::new(yaw.sin() * pitch.cos(), yaw.cos() * pitch.cos(), pitch.sin())
    }

    /// World → view matrix (right-handed, z up in the world, rolled by `roll`).
    pub fn view(&self) -> Mat4 {
        let eye = Vec3::from(self.position);
        let forward = self.forward();
        let (right, up) = match self.projection {
            Projection::Perspective => {
                let right = forward.cross(Vec3::Z).try_normalize().unwrap_or(Vec3::X);
                (right, right.cross(forward))
            }
            Projection::Plan { .. } => {
                let yaw = self.yaw.to_radians();
                let up = Vec3::new(yaw.sin(), yaw.cos(), 0.0);
                (forward.cross(up), up)
            }
        };
        let roll = self.roll.to_radians();
        glam::camera::rh::view::look_at_mat4(eye, eye + forward, up * roll.cos() + right * roll.sin())
    }

    /// View → clip matrix. Perspective: reverse-Z infinite perspective (depth 1 at the near
    /// plane, 0 at infinity), which keeps depth precision from a blade of grass to the horizon.
    /// Plan view: reverse-Z orthographic, depth 1 at the eye and 0 [`PLAN_DEPTH_RANGE`] below.
    pub fn projection(&self, aspect: f32) -> Mat4 {
        match self.projection {
            Projection::Perspective => glam::camera::rh::proj::directx::perspective_infinite_reverse(
                self.fov.clamp(1.0, 170.0).to_radians(),
                aspect,
                NEAR_PLANE,
            ),
            Projection::Plan { width } => {
                let half_width = width.max(1e-3) * 0.5;
                Mat4::from_cols(
                    Vec4::new(1.0 / half_width, 0.0, 0.0, 0.0),
                    Vec4::new(0.0, aspect / half_width, 0.0, 0.0),
                    Vec4::new(0.0, 0.0, 1.0 / PLAN_DEPTH_RANGE, 0.0),
                    Vec4::new(0.0, 0.0, 1.0, 1.0),
                )
            }
        }
    }

    /// Scene metres per pixel of a plan view `image_width` pixels wide; `None` in perspective.
    pub fn plan_metres_per_pixel(&self, image_width: u32) -> Option<f32> {
        match self.projection {
            Projection::Perspective => None,
            Projection::Plan { width } => Some(width / image_width.max(1) as f32),
        }
    }

    /// The world point seen at normalized device coordinates (`ndc_x`, `ndc_y`, y up) at linear
    /// depth `depth` (metres along the view axis): the inverse projection, then the inverse view
    /// (thesis 9.3; `shaders/data.wgsl` does the same per pixel).
    pub fn unproject(&self, ndc_x: f32, ndc_y: f32, depth: f32, aspect: f32) -> Vec3 {
        let projection = self.projection(aspect);
        let clip = projection * Vec4::new(0.0, 0.0, -depth, 1.0);
        let view = projection.inverse() * Vec4::new(ndc_x, ndc_y, clip.z / clip.w, 1.0);
        (self.view().inverse() * (view / view.w)).truncate()
    }

    /// The world point seen at the centre of pixel (`column`, `row`) of a `width` × `height`
    /// image (row 0 at the top) at linear depth `depth` (what the G-buffer holds there):
    /// [`Camera::unproject`] at the pixel centre's normalized device coordinates.
    pub fn pixel_point(&self, column: u32, row: u32, depth: f32, width: u32, height: u32) -> Vec3 {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let ndc_x = (column as f32 + 0.5) / w * 2.0 - 1.0;
        let ndc_y = 1.0 - (row as f32 + 0.5) / h * 2.0;
        self.unproject(ndc_x, ndc_y, depth, w / h)
    }

    /// Where the world point `point` lands in a `width` × `height` image: image coordinates
    /// (x right, y down, the centre of pixel (c, r) at (c + 0.5, r + 0.5)), the inverse of
    /// [`Camera::pixel_point`].
    pub fn point_pixel(&self, point: Vec3, width: u32, height: u32) -> (f32, f32) {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let clip = self.projection(w / h) * self.view() * point.extend(1.0);
        let ndc = clip.truncate() / clip.w;
        ((ndc.x + 1.0) / 2.0 * w, (1.0 - ndc.y) / 2.0 * h)
    }

    /// Checks that every number is finite, the field of view is within 1..=170 degrees and a
    /// plan view's width is positive.
    pub fn is_valid(&self) -> bool {
        let plan_ok = match self.projection {
            Projection::Perspective => true,
            Projection::Plan { width } => width.is_finite() && width > 0.0,
        };
        self.position.iter().chain([&self.yaw, &self.pitch, &self.roll]).all(|v| v.is_finite())
            && (1.0..=170.0).contains(&self.fov)
            && (-90.0..=90.0).contains(&self.pitch)
            && plan_ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_points_lie_on_the_pixel_ray_at_its_depth() {
        let cam = Camera { roll: 7.0, ..Camera::perspective([10.0, 20.0, 105.0], 30.0, -12.0, 50.0) };
        let (w, h) = (320, 240);
        let target = Vec3::new(60.0, 110.0, 98.0);
        let (x, y) = cam.point_pixel(target, w, h);
        let (column, row) = ((x - 0.5).round() as u32, (y - 0.5).round() as u32);
        let depth = -(cam.view() * target.extend(1.0)).z;
        let back = cam.pixel_point(column, row, depth, w, h);
        // And back to the pixel's centre.
        let (bx, by) = cam.point_pixel(back, w, h);
        assert!((bx - (column as f32 + 0.5)).abs() < 1e-2 && (by - (row as f32 + 0.5)).abs() < 1e-2, "{bx}, {by}");
        // Within one pixel's footprint at that depth.
        let footprint = depth * (cam.fov.to_radians() * 0.5).tan() * 2.0 / h as f32;
        assert!((back - target).length() < footprint * 1.5, "{back} vs {target}");
        let plan = Camera::plan(100.0, 50.0, 500.0, 200.0);
        let centre = plan.pixel_point(99, 49, 480.0, 200, 100);
        assert!((centre - Vec3::new(99.5, 50.5, 20.0)).length() < 1e-2, "{centre}");
    }

    #[test]
    fn heading_follows_the_compass() {
        let mut cam = Camera::perspective([0.0; 3], 0.0, 0.0, 60.0);
        assert!((cam.forward() - Vec3::Y).length() < 1e-6);
        cam.yaw = 90.0;
        assert!((cam.forward() - Vec3::X).length() < 1e-6);
        cam.pitch = 90.0;
        assert!(cam.forward().z > 0.99);
    }

    #[test]
    fn point_ahead_projects_to_the_centre_with_reverse_depth() {
        let cam = Camera::perspective([10.0, 20.0, 2.0], 90.0, 0.0, 60.0);
        let clip = cam.projection(1.5) * cam.view() * glam::Vec4::new(110.0, 20.0, 2.0, 1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5);
        let near = cam.projection(1.5) * cam.view() * glam::Vec4::new(10.0 + NEAR_PLANE, 20.0, 2.0, 1.0);
        assert!((near.z / near.w - 1.0).abs() < 1e-5);
        assert!(ndc.z > 0.0 && ndc.z < 0.01);
    }

    #[test]
    fn plan_view_looks_down_north_up_and_unprojects() {
        let cam = Camera::plan(100.0, 50.0, 500.0, 200.0);
        // 2:1 image: 200 m across, 100 m up; a point 50 m east and 25 m north of the centre
        // lands half-way to the right and top edges.
        let clip = cam.projection(2.0) * cam.view() * Vec4::new(150.0, 75.0, 20.0, 1.0);
        assert!((clip.x / clip.w - 0.5).abs() < 1e-5 && (clip.y / clip.w - 0.5).abs() < 1e-5, "{clip:?}");
        // Linear depth is the drop below the eye; depth 1 at the eye, smaller below.
        let view = cam.view() * Vec4::new(150.0, 75.0, 20.0, 1.0);
        assert!((-view.z - 480.0).abs() < 1e-3);
        assert!(clip.z > 0.0 && clip.z < 1.0);
        let back = cam.unproject(0.5, 0.5, 480.0, 2.0);
        assert!((back - Vec3::new(150.0, 75.0, 20.0)).length() < 1e-2, "{back}");
        // Heading 90: east is up in the image.
        let east_up = Camera { yaw: 90.0, ..cam };
        let clip = east_up.projection(2.0) * east_up.view() * Vec4::new(150.0, 50.0, 0.0, 1.0);
        assert!(clip.x.abs() < 1e-5 && clip.y > 0.9, "{clip:?}");
        assert!(cam.is_valid() && !Camera::plan(0.0, 0.0, 1.0, 0.0).is_valid());
        assert_eq!(cam.plan_metres_per_pixel(400), Some(0.5));
    }

    #[test]
    fn perspective_unproject_inverts_the_projection() {
        let cam = Camera { roll: 5.0, ..Camera::perspective([10.0, 20.0, 2.0], 30.0, -10.0, 60.0) };
        let p = Vec3::new(40.0, 70.0, -3.0);
        let clip = cam.projection(1.5) * cam.view() * p.extend(1.0);
        let depth = -(cam.view() * p.extend(1.0)).z;
        let back = cam.unproject(clip.x / clip.w, clip.y / clip.w, depth, 1.5);
        assert!((back - p).length() < 1e-3, "{back}");
    }

    #[test]
    fn positive_roll_turns_the_picture_counter_clockwise() {
        let cam = Camera { roll: 30.0, ..Camera::perspective([0.0; 3], 0.0, 0.0, 60.0) };
        // A point straight above the view axis appears up and to the left.
        let clip = cam.projection(1.0) * cam.view() * glam::Vec4::new(0.0, 10.0, 1.0, 1.0);
        assert!(clip.x / clip.w < -0.01 && clip.y / clip.w > 0.01, "{clip:?}");
    }
}
