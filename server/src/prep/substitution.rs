//! Tree generalization (SPEC P5; Campos et al. 2004, "Real time tree sketching", §3.2): the
//! leaves of each branch cluster are replaced by one substitution shape. The paper computes
//! the convex hull of a branch's leaves, its oriented bounding box, and draws an ellipsoid (or
//! another shape) in the box; here the clusters are the model's HLPs (their leaves are a
//! branch's, thesis 4.2), the box is oriented along the principal axes of the cluster's leaf
//! vertices and spans their extent, and the ellipsoid is inscribed in it. Drawn with the
//! style's 1D toon ramp (`toon`, `toon_levels`: the paper's §4 shading by a 1D texture) and the
//! contours between shapes (each shape is a patch of the ID buffer), it gives the paper's
//! generalized trees; as a level of detail it replaces the HLP billboard clouds with opaque
//! geometry the depth test can reject early.

use super::hlp::Hlps;
use crate::scene::mesh::Mesh;
use crate::scene::plant::{PartKind, PlantModel};
use glam::{Mat3, Vec3};

/// Segments around a substitution ellipsoid and rings from pole to pole: 8 × 5 makes 64
/// triangles, round enough for a shape a few dozen pixels wide.
const SEGMENTS: usize = 8;
const RINGS: usize = 5;

/// One substitution shape: an ellipsoid in a box oriented along `axes`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    /// Centre of the box (model space).
    pub center: Vec3,
    /// The box's axes (unit, orthogonal), the cluster's principal axes, largest variance first.
    pub axes: [Vec3; 3],
    /// The ellipsoid's semi-axes along `axes`: half the box's extent (at least `MIN_HALF`).
    pub half: [f32; 3],
}

/// The smallest semi-axis (metres) of a shape: a cluster of leaves in one plane still makes a
/// body.
const MIN_HALF: f32 = 0.05;

impl Shape {
    /// The ellipsoid inscribed in the box of `points` oriented along their principal axes;
    /// `None` without points.
    pub fn fit(points: &[Vec3]) -> Option<Shape> {
        if points.is_empty() {
            return None;
        }
        let n = points.len() as f32;
        let mean = points.iter().copied().sum::<Vec3>() / n;
        let mut covariance = Mat3::ZERO;
        for p in points {
            let d = *p - mean;
            covariance += Mat3::from_cols(d * d.x, d * d.y, d * d.z);
        }
        let axes = principal_axes(covariance * (1.0 / n));
        // The box: each axis's extent over the points, centred on its middle.
        let mut center = Vec3::ZERO;
        let mut half = [0.0; 3];
        for (k, axis) in axes.iter().enumerate() {
            let (lo, hi) =
                points.iter().map(|p| p.dot(*axis)).fold((f32::MAX, f32::MIN), |(lo, hi), t| (lo.min(t), hi.max(t)));
            center += *axis * (0.5 * (lo + hi));
            half[k] = (0.5 * (hi - lo)).max(MIN_HALF);
        }
        Some(Shape { center, axes, half })
    }

    /// The point of the ellipsoid at the polar angle `theta` from its first axis and the
    /// azimuth `phi` about it, with the ellipsoid's normal there.
    fn point(&self, theta: f32, phi: f32) -> (Vec3, Vec3) {
        let (sin_t, cos_t) = theta.sin_cos();
        let (sin_p, cos_p) = phi.sin_cos();
        // Unit-sphere coordinates along the axes; the ellipsoid scales them by its semi-axes
        // and its normal by their inverses.
        let u = [cos_t, sin_t * cos_p, sin_t * sin_p];
        let mut p = self.center;
        let mut n = Vec3::ZERO;
        for ((axis, u), half) in self.axes.iter().zip(u).zip(self.half) {
            p += *axis * (u * half);
            n += *axis * (u / half);
        }
        (p, n.normalize_or(self.axes[0]))
    }
}

/// The principal axes of the symmetric matrix `m` (eigenvectors by cyclic Jacobi rotations,
/// A ← Jᵀ A J, V ← V J), largest eigenvalue first, as a right-handed orthonormal frame.
fn principal_axes(m: Mat3) -> [Vec3; 3] {
    // a[i][j] and v[i][j]: row i, column j (m is symmetric, so its columns are its rows).
    let mut a = m.to_cols_array_2d();
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off < 1e-12 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-15 {
                continue;
            }
            // The rotation that zeroes a[p][q] (Golub & Van Loan, the symmetric Schur step).
            let tau = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
            let t = if tau == 0.0 { 1.0 } else { t };
            let c = 1.0 / (1.0 + t * t).sqrt();
            let s = t * c;
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for (k, (apk, aqk)) in row_p.into_iter().zip(row_q).enumerate() {
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // v[k][j] is row k, column j of V = ∏ J: its columns are the eigenvectors.
    let vector = |j: usize| Vec3::new(v[0][j], v[1][j], v[2][j]);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    let first = vector(order[0]).normalize_or(Vec3::X);
    let second = vector(order[1]).reject_from_normalized(first).normalize_or(first.any_orthonormal_vector());
    [first, second, first.cross(second)]
}

/// The substitution shape of every HLP of `model` (by `hlps`), fitted to the vertices of its
/// foliage triangles; `None` for an HLP without leaves.
pub fn fit_shapes(model: &PlantModel, hlps: &Hlps) -> Vec<Option<Shape>> {
    let mut points: Vec<Vec<Vec3>> = vec![Vec::new(); hlps.spheres.len()];
    for (part, triangle_hlp) in model.parts.iter().zip(&hlps.triangle_hlp) {
        if part.kind != PartKind::Foliage {
            continue;
        }
        for (triangle, &h) in part.mesh.indices.chunks_exact(3).zip(triangle_hlp) {
            if let Some(cluster) = points.get_mut(h as usize) {
                cluster.extend(triangle.iter().map(|&v| Vec3::from(part.mesh.positions[v as usize])));
            }
        }
    }
    points.iter().map(|p| Shape::fit(p)).collect()
}

/// The shapes as one mesh with each vertex's HLP index (for the HLP attributes of the G-buffer:
/// the shape's hatching and silhouettes are laid out around its HLP, and each shape is a patch
/// of its own).
pub fn shape_mesh(shapes: &[Option<Shape>]) -> (Mesh, Vec<u32>) {
    let mut mesh = Mesh::default();
    let mut owners = Vec::new();
    for (h, shape) in shapes.iter().enumerate() {
        let Some(shape) = shape else { continue };
        let first = mesh.positions.len() as u32;
        // Poles on the first axis, rings between.
        let mut vertex = |theta: f32, phi: f32| {
            let (p, n) = shape.point(theta, phi);
            mesh.positions.push(p.to_array());
            mesh.normals.push(n.to_array());
            mesh.uvs.push([phi / std::f32::consts::TAU, theta / std::f32::consts::PI]);
            owners.push(h as u32);
        };
        vertex(0.0, 0.0);
        for ring in 1..RINGS {
            let theta = std::f32::consts::PI * ring as f32 / RINGS as f32;
            for s in 0..SEGMENTS {
                vertex(theta, std::f32::consts::TAU * s as f32 / SEGMENTS as f32);
            }
        }
        vertex(std::f32::consts::PI, 0.0);
        let at = |ring: usize, s: usize| first + 1 + ((ring - 1) * SEGMENTS + s % SEGMENTS) as u32;
        let last = first + 1 + ((RINGS - 1) * SEGMENTS) as u32;
        // Counter-clockwise seen from outside (the normal's side).
        let outward = |mesh: &Mesh, [a, b, c]: [u32; 3]| {
            let p = |i: u32| Vec3::from(mesh.positions[i as usize]);
            let n = Vec3::from(mesh.normals[a as usize])
                + Vec3::from(mesh.normals[b as usize])
                + Vec3::from(mesh.normals[c as usize]);
            if (p(b) - p(a)).cross(p(c) - p(a)).dot(n) >= 0.0 { [a, b, c] } else { [a, c, b] }
        };
        let mut triangles = Vec::with_capacity(2 * SEGMENTS * (RINGS - 1));
        for s in 0..SEGMENTS {
            triangles.push([first, at(1, s), at(1, s + 1)]);
            triangles.push([last, at(RINGS - 1, s + 1), at(RINGS - 1, s)]);
        }
        for ring in 1..RINGS - 1 {
            for s in 0..SEGMENTS {
                let (a, b, c, d) = (at(ring, s), at(ring, s + 1), at(ring + 1, s), at(ring + 1, s + 1));
                triangles.push([a, c, d]);
                triangles.push([a, d, b]);
            }
        }
        for triangle in triangles {
            let t = outward(&mesh, triangle);
            mesh.indices.extend(t);
        }
    }
    (mesh, owners)
}

/// Triangles of one substitution shape.
pub const SHAPE_TRIANGLES: u64 = (2 * SEGMENTS * (RINGS - 1)) as u64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn principal_axes_of_a_stretched_cloud_follow_its_stretch() {
        // Points along a tilted line with a little spread: the first axis is the line.
        let dir = Vec3::new(1.0, 2.0, 0.5).normalize();
        let side = dir.any_orthonormal_vector();
        let points: Vec<Vec3> =
            (0..50).map(|i| dir * (i as f32 * 0.1) + side * (((i * 7) % 5) as f32 * 0.01)).collect();
        let shape = Shape::fit(&points).unwrap();
        assert!(shape.axes[0].dot(dir).abs() > 0.999, "{:?}", shape.axes);
        assert!((shape.half[0] - 2.45).abs() < 0.01, "half the line's length: {:?}", shape.half);
        assert!(shape.half[1] <= 0.05 + 1e-6 && shape.half[2] <= 0.05 + 1e-6, "{:?}", shape.half);
        let [a, b, c] = shape.axes;
        assert!(a.dot(b).abs() < 1e-5 && a.cross(b).dot(c) > 0.999, "a right-handed frame");
    }

    #[test]
    fn the_ellipsoid_is_inscribed_in_the_box_of_its_points() {
        // The corners of a box 4 × 2 × 1 turned about z: the ellipsoid touches the box's faces.
        let turn = glam::Quat::from_rotation_z(0.6);
        let points: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new([-2.0, 2.0][i & 1], [-1.0, 1.0][(i >> 1) & 1], [-0.5, 0.5][i >> 2]))
            .map(|p| turn * p + Vec3::new(3.0, -1.0, 5.0))
            .collect();
        let shape = Shape::fit(&points).unwrap();
        assert!(shape.center.distance(Vec3::new(3.0, -1.0, 5.0)) < 1e-4, "{shape:?}");
        let mut half = shape.half;
        half.sort_by(|a, b| b.total_cmp(a));
        assert!(
            (half[0] - 2.0).abs() < 1e-3 && (half[1] - 1.0).abs() < 1e-3 && (half[2] - 0.5).abs() < 1e-3,
            "{half:?}"
        );
        let (mesh, owners) = shape_mesh(&[None, Some(shape)]);
        assert_eq!(mesh.indices.len() as u64, 3 * SHAPE_TRIANGLES);
        assert!(owners.iter().all(|&h| h == 1), "every vertex belongs to HLP 1");
        // Every vertex on the ellipsoid: Σ (x_k / a_k)² = 1 in its frame, normals outward.
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let d = Vec3::from(*p) - shape.center;
            let r: f32 = (0..3).map(|k| (d.dot(shape.axes[k]) / shape.half[k]).powi(2)).sum();
            assert!((r - 1.0).abs() < 1e-3, "{p:?} off the ellipsoid: {r}");
            assert!(Vec3::from(*n).dot(d) > 0.0, "the normal at {p:?} points inwards");
        }
        // Triangles wind counter-clockwise seen from outside.
        for t in mesh.indices.chunks_exact(3) {
            let p = |i: u32| Vec3::from(mesh.positions[i as usize]);
            let face = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
            let centroid = (p(t[0]) + p(t[1]) + p(t[2])) / 3.0 - shape.center;
            assert!(face.dot(centroid) > 0.0, "triangle {t:?} faces inwards");
        }
    }

    #[test]
    fn a_cluster_without_leaves_has_no_shape() {
        assert_eq!(Shape::fit(&[]), None);
    }
}
