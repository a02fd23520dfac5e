//! CPU side of the view-dependent parametrizations of thesis 5.2 (silhouettes) and 6.1
//! (hatching): the per-HLP reference texture coordinates that follow the camera (eq. 6.2), and
//! reference implementations of the per-pixel formulas that `shaders/gbuffer.wgsl` and
//! `shaders/compose.wgsl` evaluate (eq. 5.5, 6.3–6.6), used to test them by hand.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Thesis eq. 5.5: the SAM coordinate along a silhouette, `u = c·α·r/d`, in pixels: `alpha`
/// is the angle of E against V_O (radians), `radius` the HLP radius and `distance` its depth
/// (metres), `focal_px` the focal length in pixels (so r/d becomes the HLP's radius in pixels).
pub fn silhouette_u(stretch: f32, alpha: f32, radius: f32, distance: f32, focal_px: f32) -> f32 {
    stretch * alpha * radius * focal_px / distance
}

/// The hemispherical parametrization S (thesis eq. 6.1) centred in the reference vector
/// `center`: the angles of `dir` right of and above `center`, times m/π (n/π) tiles.
fn hemisphere_uv(center: Vec3, dir: Vec3, tiles: f32) -> Vec2 {
    let right = Vec3::Z.cross(center).try_normalize().unwrap_or(Vec3::X);
    let up = center.cross(right);
    let forward = dir.dot(center);
    Vec2::new(dir.dot(right).atan2(forward), dir.dot(up).atan2(forward)) * (tiles / PI)
}

/// Thesis eq. 6.2: `R'_uv = R_uv + S(R') − S(R)` with S centred in the old reference vector R
/// (unit vector from the HLP centre to the eye). Moving the eye to the right of an HLP moves
/// its reference coordinates by the angle swept, so strokes stay on the object.
pub fn reference_update(ref_uv: Vec2, old_dir: Vec3, new_dir: Vec3, tiles: f32) -> Vec2 {
    ref_uv + hemisphere_uv(old_dir, new_dir, tiles) - hemisphere_uv(old_dir, old_dir, tiles)
}

/// Thesis eq. 6.3 with 6.5: the image-space offset of a pixel from the projection of its HLP
/// centre, brought back to the HLP sphere (camera-space length at the centre's depth divided
/// by the radius) and expressed in tiles (m/π), then rotated against the camera roll so the
/// strokes turn with the picture (V_O, eq. 6.5; a positive roll turns the picture
/// counter-clockwise). Pixels are framebuffer coordinates (y down); the result has v up.
#[allow(clippy::too_many_arguments)]
pub fn hatch_offset(
    pixel: Vec2,
    center_pixel: Vec2,
    center_depth: f32,
    radius: f32,
    tan_half_fov: f32,
    height_px: f32,
    tiles: f32,
    roll: f32,
) -> Vec2 {
    let metres_per_pixel = 2.0 * center_depth * tan_half_fov / height_px;
    let d = (pixel - center_pixel) * metres_per_pixel / radius * (tiles / PI);
    let o = Vec2::new(d.x, -d.y);
    Vec2::from_angle(-roll).rotate(o)
}

/// Thesis eq. 6.6: `f(A) = 1 + c·[((M·A)_z − (M·B')_z)/r]²`, with B' the point of the HLP
/// sphere nearest the eye (at depth `center_depth − radius`).
pub fn surface_factor(depth: f32, center_depth: f32, radius: f32, c: f32) -> f32 {
    let dz = (depth - (center_depth - radius)) / radius;
    1.0 + c * dz * dz
}

/// A reference point of the hatching and silhouette parametrizations (thesis 7.3, Fig. 7.6):
/// HLP centres near the camera, whole-plant centres at middle distance and an evenly spaced
/// grid over the terrain far away, so far strokes keep larger continuous patches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RefKey {
    /// One HLP of one plant: (plant, HLP index).
    Hlp(u32, u32),
    /// The centre of one plant's foliage.
    Plant(u32),
    /// One cell of the terrain grid.
    Cell(u32),
}

/// One reference point's state: its texture coordinates, the reference vector they were last
/// updated with, and the frame it was last used in.
#[derive(Debug, Clone, Copy)]
struct RefState {
    uv: Vec2,
    last_dir: Vec3,
    used: u64,
}

/// Frames a reference point is kept after it was last drawn; then it is forgotten (and starts
/// again from its coarser parent when it comes back into view).
const FORGET_AFTER_FRAMES: u64 = 600;

/// Per-view state of the hybrid hatching: the reference texture coordinates of the reference
/// points a view has drawn (thesis eq. 6.2), created when a point is first drawn and forgotten
/// some frames after it was last drawn, so the state grows with what is near the camera, not
/// with the scene.
#[derive(Debug, Clone, Default)]
pub struct ReferenceCoords {
    states: std::collections::HashMap<RefKey, RefState>,
    frame: u64,
}

impl ReferenceCoords {
    /// An empty state: the first frame starts every reference point at zero.
    pub fn new() -> ReferenceCoords {
        ReferenceCoords::default()
    }

    /// Applies eq. 6.2 for an eye at `eye` to the reference points `keys` (centres from
    /// `center`) and returns their coordinates in order. A point seen for the first time
    /// starts from the coordinates of its `parent` (the plant of an HLP, the grid cell of a
    /// plant) when the view has one, so a plant coming closer keeps its strokes' phase.
    pub fn update(
        &mut self,
        keys: &[RefKey],
        center: impl Fn(RefKey) -> Vec3,
        parent: impl Fn(RefKey) -> Option<RefKey>,
        eye: Vec3,
        tiles: f32,
    ) -> Vec<Vec2> {
        self.frame += 1;
        let frame = self.frame;
        let uvs = keys
            .iter()
            .map(|&key| {
                let dir = (eye - center(key)).normalize_or(Vec3::Z);
                let state = match self.states.get(&key) {
                    Some(state) => RefState { uv: reference_update(state.uv, state.last_dir, dir, tiles), ..*state },
                    None => {
                        let uv = parent(key).and_then(|p| self.states.get(&p)).map_or(Vec2::ZERO, |p| p.uv);
                        RefState { uv, last_dir: dir, used: frame }
                    }
                };
                self.states.insert(key, RefState { last_dir: dir, used: frame, ..state });
                state.uv
            })
            .collect();
        if frame.is_multiple_of(64) {
            self.states.retain(|_, s| frame - s.used <= FORGET_AFTER_FRAMES);
        }
        uvs
    }

    /// Number of reference points the view keeps.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// Whether the view keeps no reference point yet.
    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq_5_5_u_by_hand() {
        // c = 2, α = 0.5 rad, r = 1.5 m, d = 30 m, focal 665.1 px → 2·0.5·1.5·665.1/30 = 33.255 px.
        assert!((silhouette_u(2.0, 0.5, 1.5, 30.0, 665.1) - 33.255).abs() < 1e-3);
    }

    #[test]
    fn eq_6_2_follows_an_orbit() {
        // HLP at the origin, eye moves from +y (looking south at it) by 10° to the east around it.
        let old = Vec3::Y;
        let a = 10f32.to_radians();
        let new = Vec3::new(-a.sin(), a.cos(), 0.0);
        // Right of the old reference vector (Z × Y = −X): the eye moved right by 10°.
        let uv = reference_update(Vec2::new(1.0, 2.0), old, new, 2.0);
        assert!((uv.x - (1.0 + a * 2.0 / PI)).abs() < 1e-6, "{uv}");
        assert!((uv.y - 2.0).abs() < 1e-6);
        // Rising by 5° changes v only.
        let e = 5f32.to_radians();
        let up = Vec3::new(0.0, e.cos(), e.sin());
        let uv = reference_update(Vec2::ZERO, old, up, 3.0);
        assert!(uv.x.abs() < 1e-6 && (uv.y - e * 3.0 / PI).abs() < 1e-6, "{uv}");
    }

    #[test]
    fn reference_coords_accumulate_small_steps() {
        let mut refs = ReferenceCoords::new();
        let keys = [RefKey::Plant(0)];
        let mut uv = Vec2::ZERO;
        for step in 0..=10 {
            let a = (step as f32).to_radians();
            uv = refs.update(&keys, |_| Vec3::ZERO, |_| None, Vec3::new(-a.sin(), a.cos(), 0.0) * 50.0, 1.0)[0];
        }
        assert!((uv.x - 10f32.to_radians() / PI).abs() < 1e-5);
    }

    #[test]
    fn new_reference_points_start_from_their_parent_and_are_forgotten() {
        let mut refs = ReferenceCoords::new();
        let center = |key| match key {
            RefKey::Hlp(_, h) => Vec3::new(h as f32, 0.0, 0.0),
            _ => Vec3::ZERO,
        };
        let parent = |key| match key {
            RefKey::Hlp(p, _) => Some(RefKey::Plant(p)),
            _ => None,
        };
        let orbit = |deg: f32| Vec3::new(-deg.to_radians().sin(), deg.to_radians().cos(), 0.0) * 100.0;
        refs.update(&[RefKey::Plant(3)], center, parent, orbit(0.0), 2.0);
        let plant = refs.update(&[RefKey::Plant(3)], center, parent, orbit(20.0), 2.0)[0];
        assert!(plant.x > 0.1, "{plant}");
        // The plant comes close: its HLPs start where the plant's strokes were.
        let hlps = refs.update(&[RefKey::Hlp(3, 0), RefKey::Hlp(3, 1)], center, parent, orbit(20.0), 2.0);
        assert_eq!(hlps, vec![plant, plant]);
        assert_eq!(refs.len(), 3);
        // Points not drawn for long are dropped; the state stays bounded.
        for _ in 0..=FORGET_AFTER_FRAMES + 64 {
            refs.update(&[RefKey::Cell(0)], center, parent, orbit(20.0), 2.0);
        }
        assert_eq!(refs.len(), 1);
    }

    #[test]
    fn eq_6_3_offset_for_a_known_camera() {
        // Camera with a 60° vertical field of view, 768 px high; HLP centre 20 m away, r = 2 m.
        // A pixel 100 px right of the centre's projection lies 100·(2·20·tan 30°/768) = 3.0070 m
        // away at that depth = 1.5035 radii → 1.5035·(2/π) tiles = 0.9572.
        let offset = |x: f32, y: f32, roll: f32| {
            hatch_offset(
                Vec2::new(x, y),
                Vec2::new(512.0, 384.0),
                20.0,
                2.0,
                30f32.to_radians().tan(),
                768.0,
                2.0,
                roll,
            )
        };
        let o = offset(612.0, 384.0, 0.0);
        assert!((o.x - 0.95716).abs() < 1e-4 && o.y.abs() < 1e-6, "{o}");
        // Pixels above the centre give positive v; a 90° roll turns u into −v.
        let up = offset(512.0, 284.0, 0.0);
        assert!((up.y - 0.95716).abs() < 1e-4);
        let rolled = offset(612.0, 384.0, PI / 2.0);
        assert!(rolled.x.abs() < 1e-4 && (rolled.y + 0.95716).abs() < 1e-4, "{rolled}");
    }

    #[test]
    fn eq_6_6_is_one_at_the_front_of_the_sphere() {
        assert_eq!(surface_factor(18.0, 20.0, 2.0, 3.0), 1.0);
        assert!((surface_factor(20.0, 20.0, 2.0, 3.0) - 4.0).abs() < 1e-6);
    }
}
