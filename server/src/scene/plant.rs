//! Plant models: meshes split into foliage and wood parts, each with its material.
//!
//! Models come from glTF files ([`crate::scene::gltf_loader`]) or from the procedural
//! generator ([`crate::scene::procedural`]); both produce a [`PlantModel`] in scene units
//! (metres, z up) standing on z = 0.

use std::path::PathBuf;
use std::sync::Arc;

use glam::Vec3;

use crate::scene::mesh::Mesh;

/// Which part of a plant a mesh part is: foliage (leaves, needles; alpha-tested cards) or wood
/// (trunk, branches).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PartKind {
    /// Leaves, needles, fronds: usually alpha-tested cards.
    Foliage,
    /// Trunk and branches.
    Wood,
}

/// Surface description of a mesh part.
#[derive(Debug, Clone)]
pub struct Material {
    /// Material name from the model file (or a generated one).
    pub name: String,
    /// Base colour factor, linear RGBA; multiplies the texture.
    pub base_color: [f32; 4],
    /// Base colour texture, 8-bit RGBA, sRGB-encoded as stored in the file (16-bit images are
    /// converted). Parts using the same image share one `Arc`.
    pub texture: Option<Arc<image::RgbaImage>>,
    /// `Some(cutoff)` for alpha-tested materials (glTF alphaMode MASK, default 0.5); `None` for
    /// opaque ones.
    pub alpha_cutoff: Option<f32>,
    /// Whether back faces are visible (no back-face culling).
    pub double_sided: bool,
}

/// One mesh of a plant with its kind and material.
#[derive(Debug, Clone)]
pub struct MeshPart {
    /// Foliage or wood.
    pub kind: PartKind,
    /// Geometry in model space (metres, z up).
    pub mesh: Mesh,
    /// Surface of the whole part.
    pub material: Material,
}

/// A plant model in scene units (metres), z up, standing on z = 0 (lowest vertex at 0), trunk
/// base near x = y = 0.
#[derive(Debug, Clone)]
pub struct PlantModel {
    /// Model name (file stem or procedural kind and seed).
    pub name: String,
    /// Mesh parts; one per material.
    pub parts: Vec<MeshPart>,
}

impl PlantModel {
    /// Number of triangles over all parts.
    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(|part| part.mesh.triangle_count()).sum()
    }

    /// Number of triangles in the parts of one kind.
    pub fn triangle_count_of(&self, kind: PartKind) -> usize {
        self.parts_of(kind).map(|part| part.mesh.triangle_count()).sum()
    }

    /// The parts of one kind.
    pub fn parts_of(&self, kind: PartKind) -> impl Iterator<Item = &MeshPart> {
        self.parts.iter().filter(move |part| part.kind == kind)
    }

    /// Axis-aligned bounds `(min, max)` over all parts; zeros for a model without vertices.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        self.parts
            .iter()
            .filter_map(|part| part.mesh.bounds())
            .reduce(|(lo, hi), (part_lo, part_hi)| {
                (std::array::from_fn(|k| lo[k].min(part_lo[k])), std::array::from_fn(|k| hi[k].max(part_hi[k])))
            })
            .unwrap_or_default()
    }

    /// Vertical extent (max z − min z) in metres.
    pub fn height(&self) -> f32 {
        let (lo, hi) = self.bounds();
        hi[2] - lo[2]
    }

    /// Moves the model vertically so that its lowest vertex lies exactly at z = 0.
    pub fn rest_on_ground(&mut self) {
        let min_z = self.bounds().0[2];
        for part in &mut self.parts {
            for position in &mut part.mesh.positions {
                position[2] -= min_z;
            }
        }
    }
}

/// Errors from loading or generating plant models. Messages name the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The model file cannot be read at all.
    #[error("{path}: cannot read file: {error}")]
    Read { path: PathBuf, error: std::io::Error },
    /// The file is neither binary glTF nor a JSON document.
    #[error("{path}: not a glTF file (expected a binary .glb or a JSON .gltf)")]
    NotGltf { path: PathBuf },
    /// The glTF parser or validator rejected the file.
    #[error("{path}: cannot read glTF: {error}")]
    Gltf { path: PathBuf, error: gltf::Error },
    /// An external buffer file cannot be read.
    #[error("{path}: buffer {index} is missing (uri {uri}): {error}")]
    MissingBuffer { path: PathBuf, index: usize, uri: String, error: std::io::Error },
    /// A buffer exists but cannot be used (bad data URI, too short, no GLB chunk, ...).
    #[error("{path}: buffer {index} is invalid: {reason}")]
    InvalidBuffer { path: PathBuf, index: usize, reason: String },
    /// A texture image cannot be read or decoded.
    #[error("{path}: image {index} cannot be loaded: {reason}")]
    Image { path: PathBuf, index: usize, reason: String },
    /// A triangle primitive lacks vertex positions.
    #[error("{path}: primitive has no positions (mesh {mesh}, primitive {primitive})")]
    NoPositions { path: PathBuf, mesh: usize, primitive: usize },
    /// A vertex attribute or index accessor cannot be read safely.
    #[error("{path}: unreadable {attribute} accessor (mesh {mesh}, primitive {primitive}): {reason}")]
    BadAccessor { path: PathBuf, mesh: usize, primitive: usize, attribute: &'static str, reason: String },
    /// A triangle refers to a vertex that does not exist.
    #[error("{path}: vertex index {index} out of range ({vertex_count} vertices; mesh {mesh}, primitive {primitive})")]
    IndexOutOfRange { path: PathBuf, mesh: usize, primitive: usize, index: u32, vertex_count: usize },
    /// The default scene holds no triangles.
    #[error("{path}: no triangle geometry")]
    NoGeometry { path: PathBuf },
    /// A procedural plant kind name that is not known.
    #[error("unknown procedural plant kind {0:?} (expected broadleaf, conifer or shrub)")]
    UnknownProceduralKind(String),
}

/// Appends `src` to `dst`, offsetting its indices past `dst`'s vertices.
pub(crate) fn append_mesh(dst: &mut Mesh, src: &Mesh) {
    let offset = dst.positions.len() as u32;
    dst.positions.extend_from_slice(&src.positions);
    dst.normals.extend_from_slice(&src.normals);
    dst.uvs.extend_from_slice(&src.uvs);
    dst.indices.extend(src.indices.iter().map(|index| index + offset));
}

/// Unit-length copy of `v`, or +z when `v` is zero or not finite.
pub(crate) fn unit_or_up(v: Vec3) -> [f32; 3] {
    v.normalize_or(Vec3::Z).to_array()
}

/// Area-weighted smooth vertex normals of a triangle list whose indices are all in range;
/// vertices on no (or only degenerate) triangles get +z.
pub(crate) fn smooth_normals(positions: &[[f32; 3]], indices: &[u32]) -> Vec<[f32; 3]> {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    for triangle in indices.chunks_exact(3) {
        let [a, b, c] = [triangle[0], triangle[1], triangle[2]].map(|i| i as usize);
        let [pa, pb, pc] = [a, b, c].map(|i| Vec3::from(positions[i]));
        let weighted_normal = (pb - pa).cross(pc - pa);
        for i in [a, b, c] {
            sums[i] += weighted_normal;
        }
    }
    sums.into_iter().map(unit_or_up).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(kind: PartKind, positions: Vec<[f32; 3]>) -> MeshPart {
        let indices: Vec<u32> = (0..positions.len() as u32).collect();
        MeshPart {
            kind,
            mesh: Mesh {
                normals: smooth_normals(&positions, &indices),
                uvs: vec![[0.0; 2]; positions.len()],
                positions,
                indices,
            },
            material: Material {
                name: "test".into(),
                base_color: [1.0; 4],
                texture: None,
                alpha_cutoff: None,
                double_sided: false,
            },
        }
    }

    #[test]
    fn bounds_height_and_counts_cover_all_parts() {
        let mut model = PlantModel {
            name: "t".into(),
            parts: vec![
                part(PartKind::Wood, vec![[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 1.0, 2.0]]),
                part(PartKind::Foliage, vec![[-2.0, 0.0, 3.0], [0.0, 0.0, 4.0], [0.0, 3.0, 3.0]]),
            ],
        };
        assert_eq!(model.bounds(), ([-2.0, 0.0, -1.0], [1.0, 3.0, 4.0]));
        assert_eq!(model.height(), 5.0);
        assert_eq!(model.triangle_count(), 2);
        assert_eq!(model.triangle_count_of(PartKind::Foliage), 1);
        model.rest_on_ground();
        assert_eq!(model.bounds().0[2], 0.0);
        assert_eq!(model.height(), 5.0);
    }

    #[test]
    fn empty_model_has_zero_bounds() {
        let model = PlantModel { name: String::new(), parts: Vec::new() };
        assert_eq!(model.bounds(), ([0.0; 3], [0.0; 3]));
        assert_eq!(model.height(), 0.0);
    }

    #[test]
    fn append_offsets_indices() {
        let mut a = part(PartKind::Wood, vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]).mesh;
        let b = a.clone();
        append_mesh(&mut a, &b);
        assert_eq!(a.indices, vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(a.positions.len(), 6);
        assert_eq!(a.normals.len(), 6);
        assert_eq!(a.uvs.len(), 6);
    }

    #[test]
    fn smooth_normals_follow_winding_and_fall_back_to_up() {
        // A counter-clockwise triangle in the xz plane seen from −y, plus an unused vertex.
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [5.0; 3]];
        let normals = smooth_normals(&positions, &[0, 1, 2]);
        for normal in &normals[..3] {
            assert!((Vec3::from(*normal) - Vec3::NEG_Y).length() < 1e-6);
        }
        assert_eq!(normals[3], [0.0, 0.0, 1.0]);
        assert_eq!(unit_or_up(Vec3::new(f32::NAN, 0.0, 0.0)), [0.0, 0.0, 1.0]);
        assert_eq!(unit_or_up(Vec3::new(0.0, 3.0, 4.0)), [0.0, 0.6, 0.8]);
    }
}
