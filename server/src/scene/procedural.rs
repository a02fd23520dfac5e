//! Procedural plants: a deterministic fallback so that scenes render without model files.

use crate::rng::SplitMix64;
use std::f32::consts::{PI, TAU};
use std::str::FromStr;
use std::sync::{Arc, OnceLock};

use glam::Vec3;
use image::{Rgba, RgbaImage};

use crate::scene::mesh::Mesh;
use crate::scene::plant::{Material, MeshPart, ModelError, PartKind, PlantModel, append_mesh, unit_or_up};

/// The kinds of procedural plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProceduralKind {
    /// A deciduous tree, about 10 m, with an ellipsoidal crown.
    Broadleaf,
    /// A coniferous tree, about 14 m, with a conical crown.
    Conifer,
    /// A shrub, about 1.5 m, with a low dome-shaped crown.
    Shrub,
}

impl ProceduralKind {
    /// Every kind, in declaration order.
    pub const ALL: [Self; 3] = [Self::Broadleaf, Self::Conifer, Self::Shrub];

    /// The kind's name as written in scene files (`broadleaf`, `conifer`, `shrub`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Broadleaf => "broadleaf",
            Self::Conifer => "conifer",
            Self::Shrub => "shrub",
        }
    }
}

impl FromStr for ProceduralKind {
    type Err = ModelError;

    /// Parses a kind name, ignoring ASCII case and surrounding blanks.
    fn from_str(text: &str) -> Result<Self, ModelError> {
        Self::ALL
            .into_iter()
            .find(|kind| kind.name().eq_ignore_ascii_case(text.trim()))
            .ok_or_else(|| ModelError::UnknownProceduralKind(text.to_owned()))
    }
}

/// A deterministic procedural plant (same kind + seed → identical model): a tapered trunk
/// cylinder and a few branches (Wood), and foliage made of alpha-tested leaf cards (quads, two
/// triangles each) scattered in a crown volume (ellipsoid for broadleaf, cone for conifer, low
/// dome for shrub) with a procedurally drawn leaf texture (RGBA, leaf-shaped alpha mask, green
/// tones), `alpha_cutoff` `Some(0.5)`. Realistic sizes: broadleaf ~10 m, conifer ~14 m, shrub
/// ~1.5 m (each ±10 % by seed); at most ~3,000 triangles per plant.
pub fn procedural_plant(kind: ProceduralKind, seed: u64) -> PlantModel {
    let mut rng = Rng::new(kind, seed);
    let shape = Shape::new(kind, &mut rng);
    let wood = shape.wood(&mut rng);
    let foliage = shape.foliage(&mut rng);
    let mut model = PlantModel {
        name: format!("{} {seed}", kind.name()),
        parts: vec![
            MeshPart {
                kind: PartKind::Wood,
                mesh: wood,
                material: Material {
                    name: "procedural bark".into(),
                    base_color: [0.13, 0.09, 0.06, 1.0],
                    texture: None,
                    alpha_cutoff: None,
                    double_sided: false,
                },
            },
            MeshPart {
                kind: PartKind::Foliage,
                mesh: foliage,
                material: Material {
                    name: format!("procedural {} leaves", kind.name()),
                    base_color: [1.0; 4],
                    texture: Some(leaf_texture(kind)),
                    alpha_cutoff: Some(0.5),
                    double_sided: true,
                },
            },
        ],
    };
    model.rest_on_ground();
    model
}

/// Edge length of the square leaf textures in pixels.
const LEAF_TEXTURE_SIZE: u32 = 64;
/// Segments around the trunk and along it.
const TRUNK_SIDES: u32 = 8;
const TRUNK_RINGS: u32 = 4;
/// Segments around a branch (one segment along it).
const BRANCH_SIDES: u32 = 5;
/// Leaves sit in the crown's outer shell: no closer to its centre than this fraction.
const HOLLOW_CORE: f32 = 0.35;

/// The volume leaves are scattered in; heights in metres above the trunk base.
enum Crown {
    /// Ellipsoid centred on the trunk axis at height `centre`.
    Ellipsoid { centre: f32, radius: f32, half_height: f32 },
    /// Cone from height `base` (where its radius is `radius`) up to its apex at `top`.
    Cone { base: f32, top: f32, radius: f32 },
    /// Upper half of an ellipsoid standing on the ground.
    Dome { radius: f32, height: f32 },
}

impl Crown {
    /// Maps `q` from the cube [−1, 1]³ into the crown's outer shell, or `None` when `q` falls
    /// outside the shell (used for rejection sampling).
    fn place(&self, q: Vec3) -> Option<Vec3> {
        match *self {
            Crown::Ellipsoid { centre, radius, half_height } => (HOLLOW_CORE..=1.0)
                .contains(&q.length())
                .then(|| Vec3::new(q.x * radius, q.y * radius, centre + q.z * half_height)),
            Crown::Cone { base, top, radius } => {
                let t = (q.z + 1.0) / 2.0;
                let rho = q.truncate().length();
                (HOLLOW_CORE * (1.0 - t)..=1.0 - t)
                    .contains(&rho)
                    .then(|| Vec3::new(q.x * radius, q.y * radius, base + t * (top - base)))
            }
            Crown::Dome { radius, height } => ((HOLLOW_CORE..=1.0).contains(&q.length()) && q.z >= 0.1)
                .then(|| Vec3::new(q.x * radius, q.y * radius, q.z * height)),
        }
    }

    /// Horizontal radius of the crown at height `z` (the full radius below a cone's base).
    fn radius_at(&self, z: f32) -> f32 {
        let ellipse = |radius: f32, dz: f32| radius * (1.0 - dz * dz).max(0.0).sqrt();
        match *self {
            Crown::Ellipsoid { centre, radius, half_height } => ellipse(radius, (z - centre) / half_height),
            Crown::Cone { base, top, radius } => radius * ((top - z) / (top - base)).clamp(0.0, 1.0),
            Crown::Dome { radius, height } => ellipse(radius, z / height),
        }
    }

    /// The point on the trunk axis that leaf normals face away from.
    fn centre(&self) -> Vec3 {
        match *self {
            Crown::Ellipsoid { centre, .. } => Vec3::new(0.0, 0.0, centre),
            Crown::Cone { base, top, .. } => Vec3::new(0.0, 0.0, base + (top - base) / 3.0),
            Crown::Dome { .. } => Vec3::ZERO,
        }
    }
}

/// Size and proportions of one plant (metres).
struct Shape {
    trunk_top: f32,
    trunk_radius: f32,
    /// Trunk radius at its top relative to its base.
    trunk_taper: f32,
    crown: Crown,
    branches: u32,
    /// Heights on the trunk between which branches start.
    branch_heights: (f32, f32),
    /// Rise of a branch per metre of horizontal reach.
    branch_slope: f32,
    /// Branch base radius relative to the trunk radius.
    branch_radius: f32,
    leaves: u32,
    leaf_size: f32,
}

impl Shape {
    /// The proportions of `kind`, scaled by a random factor of 0.9–1.1.
    fn new(kind: ProceduralKind, rng: &mut Rng) -> Shape {
        let scale = rng.range(0.9, 1.1);
        let width = rng.range(0.9, 1.1);
        match kind {
            ProceduralKind::Broadleaf => {
                let height = 10.0 * scale;
                let half_height = 0.3 * height;
                let centre = height - half_height;
                Shape {
                    trunk_top: centre,
                    trunk_radius: 0.03 * height,
                    trunk_taper: 0.3,
                    crown: Crown::Ellipsoid { centre, radius: 0.36 * height * width, half_height },
                    branches: 6,
                    branch_heights: (centre - 0.6 * half_height, centre),
                    branch_slope: 0.7,
                    branch_radius: 0.45,
                    leaves: 1200,
                    leaf_size: 0.5,
                }
            }
            ProceduralKind::Conifer => {
                let height = 14.0 * scale;
                let base = 0.15 * height;
                Shape {
                    trunk_top: 0.95 * height,
                    trunk_radius: 0.025 * height,
                    trunk_taper: 0.1,
                    crown: Crown::Cone { base, top: height, radius: 0.22 * height * width },
                    branches: 7,
                    branch_heights: (base, base + 0.5 * (height - base)),
                    branch_slope: -0.15,
                    branch_radius: 0.35,
                    leaves: 1300,
                    leaf_size: 0.55,
                }
            }
            ProceduralKind::Shrub => {
                let height = 1.5 * scale;
                Shape {
                    trunk_top: 0.35 * height,
                    trunk_radius: 0.025 * height,
                    trunk_taper: 0.4,
                    crown: Crown::Dome { radius: 0.6 * height * width, height },
                    branches: 5,
                    branch_heights: (0.02 * height, 0.1 * height),
                    branch_slope: 1.3,
                    branch_radius: 0.8,
                    leaves: 500,
                    leaf_size: 0.16,
                }
            }
        }
    }

    /// Trunk and branches as one mesh.
    fn wood(&self, rng: &mut Rng) -> Mesh {
        let mut wood = frustum(
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, self.trunk_top),
            self.trunk_radius,
            self.trunk_radius * self.trunk_taper,
            TRUNK_SIDES,
            TRUNK_RINGS,
        );
        let (low, high) = self.branch_heights;
        for i in 0..self.branches {
            let fraction = (i as f32 + rng.range(0.2, 0.8)) / self.branches as f32;
            let start = Vec3::new(0.0, 0.0, low + (high - low) * fraction);
            // Golden-angle spacing with jitter spreads the branches around the trunk.
            let azimuth = i as f32 * 2.4 + rng.range(-0.3, 0.3);
            let reach = 0.7 * self.crown.radius_at(start.z) * rng.range(0.8, 1.0);
            let end = start + Vec3::new(azimuth.cos(), azimuth.sin(), self.branch_slope) * reach.max(0.1);
            let radius = self.trunk_radius * self.branch_radius;
            append_mesh(&mut wood, &frustum(start, end, radius, 0.2 * radius, BRANCH_SIDES, 1));
        }
        wood
    }

    /// Leaf cards scattered in the crown, facing roughly away from its centre.
    fn foliage(&self, rng: &mut Rng) -> Mesh {
        let mut mesh = Mesh::default();
        let half = self.leaf_size / 2.0;
        for _ in 0..self.leaves {
            let centre = loop {
                if let Some(p) = self.crown.place(rng.in_cube()) {
                    break p;
                }
            };
            let outward = (centre - self.crown.centre()).normalize_or(Vec3::Z);
            let normal = (outward + 0.9 * rng.unit_vector()).normalize_or(outward);
            let a = normal.any_orthonormal_vector();
            let (sin, cos) = rng.range(0.0, TAU).sin_cos();
            let u = (a * cos + normal.cross(a) * sin) * half;
            // u × v points along `normal`.
            mesh.push_card(centre, u, normal.cross(u));
        }
        mesh
    }
}

/// An open tapered cylinder from `base` to `top` with radii `base_radius` → `top_radius`,
/// `sides` segments around and `rings` along; analytic normals, u around and v along.
fn frustum(base: Vec3, top: Vec3, base_radius: f32, top_radius: f32, sides: u32, rings: u32) -> Mesh {
    let axis = top - base;
    let length = axis.length();
    let w = axis.normalize_or(Vec3::Z);
    let a = w.any_orthonormal_vector();
    let b = w.cross(a);
    let mut mesh = Mesh::default();
    for ring in 0..=rings {
        let t = ring as f32 / rings as f32;
        let radius = base_radius + (top_radius - base_radius) * t;
        for side in 0..=sides {
            let s = side as f32 / sides as f32;
            let (sin, cos) = (s * TAU).sin_cos();
            let radial = a * cos + b * sin;
            mesh.positions.push((base + axis * t + radial * radius).to_array());
            mesh.normals.push(unit_or_up(radial * length + w * (base_radius - top_radius)));
            mesh.uvs.push([s, t]);
        }
    }
    let row = sides + 1;
    for ring in 0..rings {
        for side in 0..sides {
            let i = ring * row + side;
            mesh.indices.extend([i, i + 1, i + row, i + 1, i + row + 1, i + row]);
        }
    }
    mesh
}

/// The leaf texture of `kind`, drawn once and shared (same `Arc`) by all its models.
fn leaf_texture(kind: ProceduralKind) -> Arc<RgbaImage> {
    static TEXTURES: OnceLock<[Arc<RgbaImage>; 3]> = OnceLock::new();
    let textures = TEXTURES.get_or_init(|| ProceduralKind::ALL.map(|kind| Arc::new(draw_leaf(kind))));
    Arc::clone(&textures[kind as usize])
}

/// Draws a leaf (broadleaf, shrub) or needle spray (conifer): sRGB green tones, antialiased
/// alpha mask with the tip at the top (v = 0) and the stem at the bottom (v = 1).
fn draw_leaf(kind: ProceduralKind) -> RgbaImage {
    let size = LEAF_TEXTURE_SIZE as f32;
    let colour: [f32; 3] = match kind {
        ProceduralKind::Broadleaf => [78.0, 128.0, 52.0],
        ProceduralKind::Conifer => [40.0, 88.0, 48.0],
        ProceduralKind::Shrub => [92.0, 138.0, 60.0],
    };
    RgbaImage::from_fn(LEAF_TEXTURE_SIZE, LEAF_TEXTURE_SIZE, |x, y| {
        let s = (x as f32 + 0.5) / size * 2.0 - 1.0;
        let t = (y as f32 + 0.5) / size;
        let (inside, shade) = leaf_pixel(kind, s, t);
        // `inside` is in units of s (half the texture width): scale to pixels for antialiasing.
        let alpha = (inside * size / 2.0 + 0.5).clamp(0.0, 1.0);
        let [r, g, b] = colour.map(|c| (c * shade).clamp(0.0, 255.0) as u8);
        Rgba([r, g, b, (alpha * 255.0).round() as u8])
    })
}

/// Coverage and shade of the leaf texture at `s` ∈ [−1, 1] across and `t` ∈ [0, 1] from tip
/// to stem: `inside` is positive inside the leaf (a distance in units of s), `shade` scales
/// the base colour.
fn leaf_pixel(kind: ProceduralKind, s: f32, t: f32) -> (f32, f32) {
    let across = s.abs();
    // A stalk along the middle, from `start` down to the stem end.
    let stalk = |start: f32, half_width: f32| {
        if (start..0.98).contains(&t) { half_width - across } else { -1.0 }
    };
    // A blade between the tip (t = 0.04) and `end`, widest at `widest`-controlled shape.
    let blade = |end: f32, max_half_width: f32, exponent: f32| {
        let u = (t - 0.04) / (end - 0.04);
        if (0.0..=1.0).contains(&u) { max_half_width * (PI * u).sin().powf(exponent) - across } else { -1.0 }
    };
    match kind {
        ProceduralKind::Broadleaf | ProceduralKind::Shrub => {
            let (end, width, exponent) =
                if kind == ProceduralKind::Broadleaf { (0.85, 0.78, 0.7) } else { (0.9, 0.9, 0.5) };
            let inside = blade(end, width, exponent).max(stalk(0.5, 0.05));
            let vein = across < 0.04 || (t * 10.0 + across * 3.0).fract() < 0.08;
            let shade = if vein { 0.75 } else { 1.05 - 0.3 * across };
            (inside, shade)
        }
        ProceduralKind::Conifer => {
            // Needles slant from the twig towards the tip: along one needle, t * 7 + |s| * 1.2
            // is constant.
            const NEEDLES: f32 = 7.0;
            let phase = (t * NEEDLES + across * 1.2).fract();
            let across_needle = (0.18 - (phase - 0.5).abs()) / NEEDLES * 2.0;
            let reach = 0.85 * (1.0 - 0.4 * t) - across;
            let needle = if (0.03..0.97).contains(&t) { across_needle.min(reach) } else { -1.0 };
            (needle.max(stalk(0.02, 0.05)), 0.8 + 0.4 * phase)
        }
    }
}

/// The generator's random numbers: a SplitMix64 stream per kind and seed.
struct Rng(SplitMix64);

impl Rng {
    /// A generator for one kind and seed.
    fn new(kind: ProceduralKind, seed: u64) -> Rng {
        Rng(SplitMix64::new(seed ^ (kind as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03)))
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        self.0.range(lo, hi)
    }

    /// Uniform in the cube [−1, 1]³.
    fn in_cube(&mut self) -> Vec3 {
        Vec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0))
    }

    /// A uniformly distributed unit vector.
    fn unit_vector(&mut self) -> Vec3 {
        loop {
            let q = self.in_cube();
            if (0.01..=1.0).contains(&q.length_squared()) {
                return q.normalize();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kind_names_parse_and_match_serde() {
        for kind in ProceduralKind::ALL {
            assert_eq!(kind.name().parse::<ProceduralKind>().unwrap(), kind);
            let json = serde_json::to_string(&kind).unwrap();
            assert_eq!(json, format!("\"{}\"", kind.name()));
        }
        assert_eq!(" Conifer ".parse::<ProceduralKind>().unwrap(), ProceduralKind::Conifer);
        let error = "palm".parse::<ProceduralKind>().unwrap_err();
        assert!(error.to_string().contains("\"palm\""), "{error}");
    }

    #[test]
    fn random_numbers_are_deterministic_and_in_range() {
        let mut a = Rng::new(ProceduralKind::Shrub, 3);
        let mut b = Rng::new(ProceduralKind::Shrub, 3);
        let mut c = Rng::new(ProceduralKind::Conifer, 3);
        let xs: Vec<f32> = (0..1000).map(|_| a.range(2.0, 5.0)).collect();
        assert!(xs.iter().all(|x| (2.0..5.0).contains(x)));
        assert_eq!(xs, (0..1000).map(|_| b.range(2.0, 5.0)).collect::<Vec<_>>());
        assert_ne!(xs[0], c.range(2.0, 5.0));
        assert!((a.unit_vector().length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn frustum_normals_point_outwards_and_winding_matches() {
        let mesh = frustum(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0), 1.0, 0.5, 6, 2);
        assert_eq!(mesh.triangle_count(), 6 * 2 * 2);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let radial = Vec3::new(p[0], p[1], 0.0);
            assert!(Vec3::from(*n).dot(radial) > 0.0);
            assert!(n[2] > 0.0, "a cone narrowing upwards has normals tilted up");
        }
        for triangle in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(mesh.positions[triangle[k] as usize]));
            let face = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            assert!(face.dot(Vec3::new(centre.x, centre.y, 0.0)) > 0.0);
        }
    }

    #[test]
    fn crowns_place_points_inside_their_volume() {
        let mut rng = Rng::new(ProceduralKind::Broadleaf, 1);
        let crowns = [
            Crown::Ellipsoid { centre: 7.0, radius: 3.0, half_height: 2.0 },
            Crown::Cone { base: 2.0, top: 14.0, radius: 3.0 },
            Crown::Dome { radius: 1.0, height: 1.5 },
        ];
        for crown in &crowns {
            let mut accepted = 0;
            for _ in 0..2000 {
                if let Some(p) = crown.place(rng.in_cube()) {
                    accepted += 1;
                    assert!(p.truncate().length() <= crown.radius_at(p.z) + 1e-4);
                }
            }
            assert!(accepted > 100, "rejection sampling accepts too rarely");
        }
        assert_eq!(crowns[1].radius_at(0.0), 3.0);
        assert_eq!(crowns[1].radius_at(14.0), 0.0);
    }

    #[test]
    fn leaf_textures_have_leaf_shaped_masks() {
        for kind in ProceduralKind::ALL {
            let image = draw_leaf(kind);
            let opaque = image.pixels().filter(|p| p[3] >= 128).count() as f32;
            let fraction = opaque / image.pixels().len() as f32;
            assert!((0.1..0.7).contains(&fraction), "{kind:?}: {fraction}");
            // Corners are transparent, the middle of the stalk is opaque.
            assert_eq!(image.get_pixel(0, 0)[3], 0);
            let stalk = image.get_pixel(LEAF_TEXTURE_SIZE / 2, LEAF_TEXTURE_SIZE * 9 / 10);
            assert_eq!(stalk[3], 255, "{kind:?}");
            assert!(stalk[1] > stalk[0] && stalk[1] > stalk[2], "green");
        }
        assert!(Arc::ptr_eq(&leaf_texture(ProceduralKind::Shrub), &leaf_texture(ProceduralKind::Shrub)));
    }
}
