//! Single leaves of a plant model (thesis 4.1–4.2 and ch. 7; SPEC R1, R2, P4): the foliage
//! split into connected components of its triangles (a leaf card, a needle spray), each
//! described as a textured rectangle in the leaf's plane. The renderer draws these rectangles
//! as leaf particles — camera-facing, re-oriented away from their HLP centre, or as ellipses
//! around it — and draws a shuffled prefix of them, so the particle count can fall with the
//! distance while every prefix stays a uniform random subset of the leaves.

use super::hlp::Hlps;
use crate::rng::SplitMix64;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{PartKind, PlantModel};
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// The corners of a leaf rectangle in its own coordinates (s, t): centre + s·h₀·a₀ + t·h₁·a₁.
pub const CORNERS: [[f32; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Smallest half size of a leaf rectangle (metres), so a leaf of collinear triangles stays a
/// drawable rectangle.
const MIN_HALF_SIZE: f32 = 1e-4;

/// Seed of the leaf order (see [`shuffled`]).
pub const LEAF_ORDER_SEED: u64 = 0x1ea7_5eed;

/// One leaf: a rectangle in the plane of its triangles, with the texture mapped as on them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leaf {
    /// Centre of the rectangle, model space.
    pub center: Vec3,
    /// Unit normal, on the side the leaf's vertex normals face.
    pub normal: Vec3,
    /// Unit axes in the leaf's plane: the texture's u grows along `axes[0]`, v along `axes[1]`.
    pub axes: [Vec3; 2],
    /// Half extents of the rectangle along the axes (metres).
    pub half_sizes: [f32; 2],
    /// Texture coordinates at the [`CORNERS`]: the leaf's UV rectangle, from the affine
    /// mapping of its triangles (exact for a flat card).
    pub uv_corners: [[f32; 2]; 4],
    /// The HLP of the leaf: the one most of its triangles belong to.
    pub hlp: u32,
    /// The model part the leaf comes from (its material).
    pub part: usize,
    /// A vertex of the leaf in its part's mesh (the first of its first triangle): where the
    /// particle takes per-vertex data of the model from (the implicit-surface illumination).
    pub vertex: u32,
}

impl Leaf {
    /// The two triangles of the rectangle as indices into [`CORNERS`], counter-clockwise seen
    /// from the normal's side (the front face, as on the model).
    pub fn triangles(&self) -> [u32; 6] {
        if self.axes[0].cross(self.axes[1]).dot(self.normal) >= 0.0 { [0, 1, 2, 0, 2, 3] } else { [0, 2, 1, 0, 3, 2] }
    }

    /// The model-space position of corner `corner` of [`CORNERS`].
    pub fn corner(&self, corner: usize) -> Vec3 {
        let [s, t] = CORNERS[corner];
        self.center + self.axes[0] * (s * self.half_sizes[0]) + self.axes[1] * (t * self.half_sizes[1])
    }
}

/// The leaves of every foliage part of `model`, part by part, each with the HLP of `hlps`
/// most of its triangles belong to. A leaf is a connected component of a part's triangles
/// (triangles sharing a vertex index); components of zero area are left out.
pub fn split(model: &PlantModel, hlps: &Hlps) -> Vec<Leaf> {
    let mut leaves = Vec::new();
    for (part_index, (part, triangle_hlp)) in model.parts.iter().zip(&hlps.triangle_hlp).enumerate() {
        if part.kind != PartKind::Foliage {
            continue;
        }
        for triangles in components(&part.mesh) {
            if let Some(leaf) = leaf_of(&part.mesh, &triangles, triangle_hlp, part_index) {
                leaves.push(leaf);
            }
        }
    }
    leaves
}

/// The triangles of each connected component of `mesh` (triangles are connected when they
/// share a vertex index), components in the order of their first triangle.
fn components(mesh: &Mesh) -> Vec<Vec<usize>> {
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let up = parent[parent[v as usize] as usize];
            parent[v as usize] = up;
            v = up;
        }
        v
    }
    for tri in mesh.indices.chunks_exact(3) {
        let a = root(&mut parent, tri[0]);
        for &v in &tri[1..] {
            let b = root(&mut parent, v);
            parent[b as usize] = a;
        }
    }
    let mut index_of_root: HashMap<u32, usize> = HashMap::new();
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
        let r = root(&mut parent, tri[0]);
        let i = *index_of_root.entry(r).or_insert_with(|| {
            out.push(Vec::new());
            out.len() - 1
        });
        out[i].push(t);
    }
    out
}

/// Solves `[a b] x = r` for two 2D columns `a`, `b`; `None` when they are (nearly) parallel.
fn solve2(a: Vec2, b: Vec2, r: Vec2) -> Option<Vec2> {
    let det = a.x * b.y - b.x * a.y;
    (det.abs() > 1e-12).then(|| Vec2::new(r.x * b.y - b.x * r.y, a.x * r.y - r.x * a.y) / det)
}

/// The leaf rectangle of the triangles `triangles` of `mesh`.
fn leaf_of(mesh: &Mesh, triangles: &[usize], triangle_hlp: &[u32], part: usize) -> Option<Leaf> {
    let position = |v: u32| Vec3::from(mesh.positions[v as usize]);
    let uv = |v: u32| Vec2::from(mesh.uvs.get(v as usize).copied().unwrap_or_default());
    let corners = |t: usize| [0, 1, 2].map(|k| mesh.indices[3 * t + k]);
    // Area-weighted normal and centroid; vertex normals decide the front side.
    let (mut normal_sum, mut area, mut centroid, mut vertex_normals) = (Vec3::ZERO, 0.0f32, Vec3::ZERO, Vec3::ZERO);
    // dP/du and dP/dv of the texture mapping, area-weighted (as tangent frames are built).
    let (mut du, mut dv) = (Vec3::ZERO, Vec3::ZERO);
    for &t in triangles {
        let [a, b, c] = corners(t).map(position);
        let cross = (b - a).cross(c - a);
        let w = cross.length() * 0.5;
        normal_sum += cross;
        area += w;
        centroid += (a + b + c) / 3.0 * w;
        for v in corners(t) {
            vertex_normals += Vec3::from(mesh.normals.get(v as usize).copied().unwrap_or_default());
        }
        let [ua, ub, uc] = corners(t).map(uv);
        let (e1, e2, d1, d2) = (b - a, c - a, ub - ua, uc - ua);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() > 1e-12 {
            du += (e1 * d2.y - e2 * d1.y) / det * w;
            dv += (e2 * d1.x - e1 * d2.x) / det * w;
        }
    }
    if area <= 0.0 {
        return None;
    }
    let centroid = centroid / area;
    let mut normal = normal_sum.normalize_or(vertex_normals.normalize_or(Vec3::Z));
    if normal.dot(vertex_normals) < 0.0 {
        normal = -normal;
    }
    let a0 = (du - normal * normal.dot(du)).normalize_or(normal.any_orthonormal_vector());
    let mut a1 = normal.cross(a0);
    if a1.dot(dv) < 0.0 {
        a1 = -a1;
    }
    // The rectangle: the extent of the vertices along the axes.
    let st = |p: Vec3| Vec2::new((p - centroid).dot(a0), (p - centroid).dot(a1));
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &t in triangles {
        for v in corners(t) {
            let q = st(position(v));
            (lo, hi) = (lo.min(q), hi.max(q));
        }
    }
    let mid = (lo + hi) * 0.5;
    let half = ((hi - lo) * 0.5).max(Vec2::splat(MIN_HALF_SIZE));
    // The texture mapping as an affine function of (s, t): area-weighted gradients of u and v
    // about the area-weighted mean.
    let (mut grad_u, mut grad_v, mut mean_st, mut mean_uv) = (Vec2::ZERO, Vec2::ZERO, Vec2::ZERO, Vec2::ZERO);
    for &t in triangles {
        let [a, b, c] = corners(t).map(|v| st(position(v)));
        let [ua, ub, uc] = corners(t).map(uv);
        let w = (b - a).perp_dot(c - a).abs() * 0.5;
        mean_st += (a + b + c) / 3.0 * w;
        mean_uv += (ua + ub + uc) / 3.0 * w;
        let solve = |r: Vec2| solve2(Vec2::new(b.x - a.x, c.x - a.x), Vec2::new(b.y - a.y, c.y - a.y), r);
        if let (Some(gu), Some(gv)) =
            (solve(Vec2::new(ub.x - ua.x, uc.x - ua.x)), solve(Vec2::new(ub.y - ua.y, uc.y - ua.y)))
        {
            grad_u += gu * w;
            grad_v += gv * w;
        }
    }
    let (mean_st, mean_uv, grad_u, grad_v) = (mean_st / area, mean_uv / area, grad_u / area, grad_v / area);
    let uv_corners = CORNERS.map(|[s, t]| {
        let d = mid + Vec2::new(s, t) * half - mean_st;
        (mean_uv + Vec2::new(grad_u.dot(d), grad_v.dot(d))).to_array()
    });
    Some(Leaf {
        center: centroid + a0 * mid.x + a1 * mid.y,
        normal,
        axes: [a0, a1],
        half_sizes: half.to_array(),
        uv_corners,
        hlp: majority(triangles.iter().filter_map(|&t| triangle_hlp.get(t).copied())),
        part,
        vertex: mesh.indices[3 * triangles[0]],
    })
}

/// Samples per side of the grid [`coverage`] tests.
const COVERAGE_SAMPLES: usize = 8;

/// The share of `leaf`'s rectangle that its texture covers: texels with alpha at or above
/// `cutoff`, on a grid of 8 × 8 points mapped through the leaf's texture coordinates (nearest
/// texel, wrapping); 1 without a texture or cutoff. An elliptical leaf keeps this area.
pub fn coverage(leaf: &Leaf, texture: Option<&image::RgbaImage>, cutoff: Option<f32>) -> f32 {
    let (Some(texture), Some(cutoff)) = (texture, cutoff) else { return 1.0 };
    let (w, h) = texture.dimensions();
    if w == 0 || h == 0 {
        return 1.0;
    }
    let [c00, c10, c11, c01] = leaf.uv_corners.map(Vec2::from);
    let n = COVERAGE_SAMPLES;
    let mut inside = 0;
    for j in 0..n {
        for i in 0..n {
            let (x, y) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let uv = (c00 * (1.0 - x) + c10 * x) * (1.0 - y) + (c01 * (1.0 - x) + c11 * x) * y;
            let tx = ((uv.x * w as f32).floor() as i64).rem_euclid(i64::from(w)) as u32;
            let ty = ((uv.y * h as f32).floor() as i64).rem_euclid(i64::from(h)) as u32;
            inside += usize::from(f32::from(texture.get_pixel(tx, ty)[3]) / 255.0 >= cutoff);
        }
    }
    inside as f32 / (n * n) as f32
}

/// The most frequent value (the smallest of equally frequent ones); 0 for none.
fn majority(values: impl Iterator<Item = u32>) -> u32 {
    let mut counts: HashMap<u32, usize> = HashMap::new();
    for v in values {
        *counts.entry(v).or_default() += 1;
    }
    counts.into_iter().max_by_key(|&(v, n)| (n, std::cmp::Reverse(v))).map_or(0, |(v, _)| v)
}

/// `leaves` in a random order (Fisher–Yates with `seed`): every prefix is a uniform random
/// subset, so drawing the first k leaves thins the foliage evenly (thesis 4.2, 7: the number
/// of leaf particles varies with the distance).
pub fn shuffled(mut leaves: Vec<Leaf>, seed: u64) -> Vec<Leaf> {
    let mut rng = SplitMix64::new(seed);
    for i in (1..leaves.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        leaves.swap(i, j);
    }
    leaves
}

/// Shares of a plant's leaf particles drawn, from near to far (SPEC P4): each a prefix of
/// the shuffled leaves, drawn with primitives scaled by √(all / drawn) so the coverage stays.
pub const PARTICLE_SHARES: [f32; 4] = [1.0, 0.5, 0.25, 0.125];

/// Projected height (pixels) from which a plant draws all its leaf particles; smaller plants
/// at full detail draw a share (see [`particle_bucket`]).
pub const ALL_LEAVES_PX: f32 = 480.0;

/// The fewest leaf particles a share may leave of a plant (all of a plant with fewer leaves):
/// a plant of few, large leaves is not thinned to a handful of huge ones.
pub const MIN_PARTICLES: usize = 200;

/// How many of `count` leaves the share `share` draws: at least one when there are any.
pub fn prefix_len(count: usize, share: f32) -> usize {
    ((count as f32 * share).ceil() as usize).clamp(count.min(1), count)
}

/// The bucket (index into [`PARTICLE_SHARES`]) of a plant `px` pixels tall with `count`
/// leaves: all of them from [`ALL_LEAVES_PX`] up; below, the leaves' screen size stays roughly
/// constant (thesis 4.2: "the leaf size is being kept roughly constant while the number of
/// leaf primitives is varied"), so the share falls with the square of the plant's size,
/// rounded up to the next bucket and never below [`MIN_PARTICLES`] leaves.
pub fn particle_bucket(px: f32, count: usize) -> usize {
    let share = (px / ALL_LEAVES_PX).powi(2);
    let fewest = count.min(MIN_PARTICLES);
    (0..PARTICLE_SHARES.len())
        .rev()
        .find(|&b| PARTICLE_SHARES[b] >= share && prefix_len(count, PARTICLE_SHARES[b]) >= fewest)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prep::hlp;
    use crate::scene::plant::{Material, MeshPart};

    fn material() -> Material {
        Material {
            name: "leaves".into(),
            base_color: [1.0; 4],
            texture: None,
            alpha_cutoff: Some(0.5),
            double_sided: true,
        }
    }

    fn model(meshes: Vec<Mesh>) -> PlantModel {
        let parts =
            meshes.into_iter().map(|mesh| MeshPart { kind: PartKind::Foliage, mesh, material: material() }).collect();
        PlantModel { name: "leaves".into(), parts }
    }

    #[test]
    fn a_card_becomes_one_leaf_with_its_rectangle_and_uvs() {
        let mut mesh = Mesh::default();
        let (center, u, v) = (Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.3, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.2));
        mesh.push_card(center, u, v);
        let model = model(vec![mesh]);
        let leaves = split(&model, &hlp::cluster(&model, 1.0));
        assert_eq!(leaves.len(), 1);
        let leaf = leaves[0];
        assert!(leaf.center.distance(center) < 1e-5, "{leaf:?}");
        // Normal u × v = (0, −1, 0)·0.06, on the vertex normals' side.
        assert!(leaf.normal.distance(Vec3::NEG_Y) < 1e-5, "{leaf:?}");
        // u grows along +x; v grows towards −z (v = 1 at the −v edge).
        assert!(leaf.axes[0].distance(Vec3::X) < 1e-5 && leaf.axes[1].distance(Vec3::NEG_Z) < 1e-5, "{leaf:?}");
        assert!((leaf.half_sizes[0] - 0.3).abs() < 1e-5 && (leaf.half_sizes[1] - 0.2).abs() < 1e-5);
        // The rectangle's corners carry the card's texture coordinates.
        let expected = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        for (got, want) in leaf.uv_corners.iter().zip(expected) {
            assert!((Vec2::from(*got) - Vec2::from(want)).length() < 1e-5, "{:?}", leaf.uv_corners);
        }
        for c in 0..4 {
            let p = leaf.corner(c);
            assert!(model.parts[0].mesh.positions.iter().any(|q| Vec3::from(*q).distance(p) < 1e-5), "corner {c} {p}");
        }
        // The triangles keep the card's front side: counter-clockwise about the normal.
        let t = leaf.triangles();
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| leaf.corner(i as usize));
        assert!((b - a).cross(c - a).dot(leaf.normal) > 0.0);
    }

    #[test]
    fn components_follow_shared_vertices_and_leaves_take_their_majority_hlp() {
        let mut a = Mesh::default();
        a.push_card(Vec3::new(0.0, 0.0, 5.0), Vec3::X * 0.1, Vec3::Y * 0.1);
        a.push_card(Vec3::new(0.0, 0.05, 5.0), Vec3::X * 0.1, Vec3::Z * 0.1);
        a.push_card(Vec3::new(4.0, 0.0, 5.0), Vec3::X * 0.1, Vec3::Y * 0.1);
        // A fan of three triangles sharing vertex 0: one leaf.
        let b = Mesh {
            positions: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0], [-1.0, 0.5, 1.0]],
            normals: vec![[0.0, 0.0, 1.0]; 5],
            uvs: vec![[0.0; 2]; 5],
            indices: vec![0, 1, 2, 0, 2, 3, 0, 3, 4],
        };
        let model = model(vec![a, b]);
        let mut hlps = hlp::cluster(&model, 1.0);
        let leaves = split(&model, &hlps);
        assert_eq!(leaves.len(), 4, "three cards (overlapping positions do not join them) and one fan");
        assert_eq!(leaves.iter().map(|l| l.part).collect::<Vec<_>>(), vec![0, 0, 0, 1]);
        assert_eq!(leaves[0].hlp, leaves[1].hlp);
        assert_ne!(leaves[0].hlp, leaves[2].hlp, "four metres apart");
        // Untextured: the leaf is still a rectangle in its plane, around all its vertices.
        let fan = leaves[3];
        assert!(fan.normal.distance(Vec3::Z) < 1e-5);
        for p in &model.parts[1].mesh.positions {
            let d = Vec3::from(*p) - fan.center;
            for k in 0..2 {
                assert!(d.dot(fan.axes[k]).abs() <= fan.half_sizes[k] + 1e-5, "{p:?} outside {fan:?}");
            }
        }
        // Two of a fan's three triangles in HLP 7: the leaf is in HLP 7.
        hlps.triangle_hlp[1] = vec![7, 2, 7];
        assert_eq!(split(&model, &hlps)[3].hlp, 7);
        assert_eq!(majority([3, 1, 3, 1].into_iter()), 1, "ties go to the smaller index");
    }

    #[test]
    fn procedural_foliage_splits_into_its_cards() {
        use crate::scene::procedural::{ProceduralKind, procedural_plant};
        let model = procedural_plant(ProceduralKind::Broadleaf, 1);
        let hlps = hlp::cluster(&model, 0.15 * model.height());
        let leaves = split(&model, &hlps);
        assert_eq!(leaves.len(), model.triangle_count_of(PartKind::Foliage) / 2);
        for leaf in &leaves {
            let sphere = hlps.spheres[leaf.hlp as usize];
            assert!(leaf.center.distance(sphere.center) <= sphere.radius + 1e-3);
            assert!((leaf.half_sizes[0] - 0.25).abs() < 1e-3 && (leaf.half_sizes[1] - 0.25).abs() < 1e-3, "{leaf:?}");
        }
    }

    #[test]
    fn coverage_is_the_opaque_share_of_the_leaf() {
        let mut mesh = Mesh::default();
        mesh.push_card(Vec3::ZERO, Vec3::X, Vec3::Z);
        let model = model(vec![mesh]);
        let leaf = split(&model, &hlp::cluster(&model, 2.0))[0];
        // Opaque in the left quarter of the texture (u < 0.25) only.
        let texture = image::RgbaImage::from_fn(16, 16, |x, _| image::Rgba([0, 255, 0, if x < 4 { 255 } else { 0 }]));
        assert_eq!(coverage(&leaf, Some(&texture), Some(0.5)), 0.25);
        assert_eq!(coverage(&leaf, Some(&texture), None), 1.0);
        assert_eq!(coverage(&leaf, None, Some(0.5)), 1.0);
    }

    #[test]
    fn shuffled_prefixes_are_even_subsets() {
        let mut mesh = Mesh::default();
        for i in 0..400 {
            mesh.push_card(Vec3::new(i as f32, 0.0, 1.0), Vec3::X * 0.1, Vec3::Y * 0.1);
        }
        let model = model(vec![mesh]);
        let leaves = split(&model, &hlp::cluster(&model, 0.5));
        let order = shuffled(leaves.clone(), LEAF_ORDER_SEED);
        assert_eq!(order, shuffled(leaves.clone(), LEAF_ORDER_SEED), "deterministic");
        assert_ne!(order, leaves);
        let mut xs: Vec<f32> = order.iter().map(|l| l.center.x).collect();
        xs.sort_by(f32::total_cmp);
        assert_eq!(xs, (0..400).map(|i| i as f32).collect::<Vec<_>>(), "a permutation");
        // The first eighth spreads over the whole crown: its mean x is near the middle.
        let n = prefix_len(order.len(), PARTICLE_SHARES[3]);
        assert_eq!(n, 50);
        let mean = order[..n].iter().map(|l| l.center.x).sum::<f32>() / n as f32;
        assert!((mean - 199.5).abs() < 40.0, "{mean}");
        assert_eq!((prefix_len(3, 0.125), prefix_len(0, 0.5), prefix_len(10, 1.0)), (1, 0, 10));
    }

    #[test]
    fn buckets_fall_with_the_square_of_the_size_down_to_the_fewest_particles() {
        let many = 8 * MIN_PARTICLES;
        assert_eq!(particle_bucket(1000.0, many), 0);
        assert_eq!(particle_bucket(ALL_LEAVES_PX, many), 0);
        assert_eq!(particle_bucket(400.0, many), 0);
        assert_eq!(particle_bucket(330.0, many), 1);
        assert_eq!(particle_bucket(240.0, many), 2);
        assert_eq!(particle_bucket(160.0, many), 3);
        assert_eq!(particle_bucket(10.0, many), 3);
        // Fewer leaves: the share stops where MIN_PARTICLES remain, or at all of them.
        assert_eq!(particle_bucket(10.0, 2 * MIN_PARTICLES), 1);
        assert_eq!(particle_bucket(10.0, MIN_PARTICLES / 2), 0);
    }
}
