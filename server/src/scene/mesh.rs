//! Indexed triangle meshes shared by terrain and plant models.

/// An indexed triangle mesh in scene space (x east, y north, z up, metres).
///
/// `positions`, `normals` and `uvs` have one entry per vertex; `indices` holds three vertex
/// indices per triangle, counter-clockwise seen from the front.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Appends a leaf card: the quad `center ∓ u ∓ v`, counter-clockwise around its normal
    /// u × v, textured with uv (0, 1) (1, 1) (1, 0) (0, 0), so the texture's v = 1 (a leaf's
    /// stem) lies on the −v side.
    pub fn push_card(&mut self, center: glam::Vec3, u: glam::Vec3, v: glam::Vec3) {
        let normal = u.cross(v).normalize_or(glam::Vec3::Z).to_array();
        let first = self.positions.len() as u32;
        for (corner, uv) in [
            (center - u - v, [0.0, 1.0]),
            (center + u - v, [1.0, 1.0]),
            (center + u + v, [1.0, 0.0]),
            (center - u + v, [0.0, 0.0]),
        ] {
            self.positions.push(corner.to_array());
            self.normals.push(normal);
            self.uvs.push(uv);
        }
        self.indices.extend([0, 1, 2, 0, 2, 3].map(|corner| first + corner));
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Axis-aligned bounds `(min, max)` of the vertices, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(mut lo, mut hi), p| {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            (lo, hi)
        }))
    }
}
