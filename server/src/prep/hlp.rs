//! Higher level primitives (thesis 4.2, NPAR §4): greedy clustering of a plant's foliage into
//! spheres of bounded radius. Every foliage vertex then knows its HLP centre C and radius r, so
//! shaders can form the HLP normal N_HLP = P − C (thesis eq. 4.7).

use super::cache::{DiskCache, KeyBuilder, Reader};
use crate::scene::mesh::Mesh;
use crate::scene::plant::{PartKind, PlantModel};
use glam::Vec3;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock};

/// One spherical HLP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere {
    /// The smallest sphere containing `self` and `p` (Ritter's growth step).
    fn grown_to(self, p: Vec3) -> Sphere {
        let d = p.distance(self.center);
        if d <= self.radius {
            return self;
        }
        let radius = (self.radius + d) * 0.5;
        Sphere { center: self.center + (p - self.center) * ((radius - self.radius) / d), radius }
    }
}

/// The HLPs of one plant model and, per foliage part, the HLP of each triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct Hlps {
    pub spheres: Vec<Sphere>,
    /// `triangle_hlp[part][triangle]` for the model's parts in order; wood parts are empty.
    pub triangle_hlp: Vec<Vec<u32>>,
}

/// Clusters the foliage triangles of `model` into spheres of radius at most `max_radius`
/// (thesis algorithm `computeFoliageHLPs`): each triangle joins the nearest existing HLP that
/// can take all its vertices without growing beyond `max_radius`, else it starts a new one.
pub fn cluster(model: &PlantModel, max_radius: f32) -> Hlps {
    let mut spheres: Vec<Sphere> = Vec::new();
    let mut triangle_hlp = Vec::with_capacity(model.parts.len());
    for part in &model.parts {
        if part.kind != PartKind::Foliage {
            triangle_hlp.push(Vec::new());
            continue;
        }
        let mesh = &part.mesh;
        let mut assigned = Vec::with_capacity(mesh.triangle_count());
        for tri in mesh.indices.chunks_exact(3) {
            let corners = [tri[0], tri[1], tri[2]].map(|i| Vec3::from(mesh.positions[i as usize]));
            let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
            let grow = |s: Sphere| corners.iter().fold(s, |s, p| s.grown_to(*p));
            let best =
                spheres.iter().enumerate().map(|(i, s)| (i, grow(*s))).filter(|(_, s)| s.radius <= max_radius).min_by(
                    |a, b| spheres[a.0].center.distance(centroid).total_cmp(&spheres[b.0].center.distance(centroid)),
                );
            let index = match best {
                Some((i, grown)) => {
                    spheres[i] = grown;
                    i
                }
                None => {
                    spheres.push(grow(Sphere { center: centroid, radius: 0.0 }));
                    spheres.len() - 1
                }
            };
            assigned.push(index as u32);
        }
        triangle_hlp.push(assigned);
    }
    Hlps { spheres, triangle_hlp }
}

/// A content hash of a model's geometry (positions, indices, part kinds) for cache keys.
pub fn model_hash(model: &PlantModel) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for part in &model.parts {
        (part.kind == PartKind::Foliage).hash(&mut h);
        part.mesh.indices.hash(&mut h);
        for p in &part.mesh.positions {
            p.map(f32::to_bits).hash(&mut h);
        }
    }
    h.finish()
}

/// [`cluster`] with a process-wide cache keyed by the model's content hash and the radius, so
/// every scene (and every restyle) reuses the HLPs of a model already seen; with `disk`, also
/// cached across restarts.
pub fn cluster_cached(model: &PlantModel, max_radius: f32, disk: Option<&DiskCache>) -> Arc<Hlps> {
    type Cache = Mutex<HashMap<(u64, u32), Arc<Hlps>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let key = (model_hash(model), max_radius.to_bits());
    let cache = CACHE.get_or_init(Default::default);
    if let Some(hit) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return hit.clone();
    }
    let hlps = Arc::new(match disk {
        Some(disk) => {
            let disk_key = KeyBuilder::default().bytes(b"hlp v1").u64(key.0).f32(max_radius).finish();
            disk.get_or_compute("hlp", &disk_key, |b| decode(b, model), encode, || cluster(model, max_radius))
        }
        None => cluster(model, max_radius),
    });
    cache.lock().unwrap_or_else(|e| e.into_inner()).insert(key, hlps.clone());
    hlps
}

/// Serialises a clustering for the disk cache: sphere count, spheres, then per part the
/// triangle count and the triangles' HLP indices (all little endian).
fn encode(hlps: &Hlps) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((hlps.spheres.len() as u32).to_le_bytes());
    for s in &hlps.spheres {
        for v in [s.center.x, s.center.y, s.center.z, s.radius] {
            out.extend(v.to_le_bytes());
        }
    }
    out.extend((hlps.triangle_hlp.len() as u32).to_le_bytes());
    for part in &hlps.triangle_hlp {
        out.extend((part.len() as u32).to_le_bytes());
        out.extend(part.iter().flat_map(|i| i.to_le_bytes()));
    }
    out
}

/// Reads what [`encode`] wrote, checking it against `model` (part and triangle counts, index
/// range) so a stale or corrupt entry is rejected.
fn decode(bytes: &[u8], model: &PlantModel) -> Option<Hlps> {
    let mut r = Reader::new(bytes);
    let count = r.u32()? as usize;
    let spheres = (0..count)
        .map(|_| Some(Sphere { center: Vec3::new(r.f32()?, r.f32()?, r.f32()?), radius: r.f32()? }))
        .collect::<Option<Vec<_>>>()?;
    if r.u32()? as usize != model.parts.len() {
        return None;
    }
    let mut triangle_hlp = Vec::with_capacity(model.parts.len());
    for part in &model.parts {
        let n = r.u32()? as usize;
        let expected = if part.kind == PartKind::Foliage { part.mesh.triangle_count() } else { 0 };
        if n != expected {
            return None;
        }
        let indices = (0..n).map(|_| r.u32().filter(|&i| (i as usize) < count)).collect::<Option<Vec<_>>>()?;
        triangle_hlp.push(indices);
    }
    r.is_empty().then_some(Hlps { spheres, triangle_hlp })
}

/// A mesh whose vertices each belong to one HLP: vertices shared by triangles of different
/// HLPs are duplicated. `hlp[i]` is the HLP index of vertex `i`, `source[i]` the vertex of the
/// original mesh it copies (for per-vertex data computed on the original, e.g.
/// [`super::implicit::Illumination`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HlpMesh {
    pub mesh: Mesh,
    pub hlp: Vec<u32>,
    pub source: Vec<u32>,
}

/// Splits `mesh` so every vertex has exactly one HLP, given the HLP of every triangle.
pub fn split_by_hlp(mesh: &Mesh, triangle_hlp: &[u32]) -> HlpMesh {
    let mut out = HlpMesh { mesh: Mesh::default(), hlp: Vec::new(), source: Vec::new() };
    let mut remap: HashMap<(u32, u32), u32> = HashMap::new();
    for (tri, &h) in mesh.indices.chunks_exact(3).zip(triangle_hlp) {
        for &v in tri {
            let index = *remap.entry((v, h)).or_insert_with(|| {
                let i = v as usize;
                out.mesh.positions.push(mesh.positions[i]);
                out.mesh.normals.push(mesh.normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0]));
                out.mesh.uvs.push(mesh.uvs.get(i).copied().unwrap_or([0.0, 0.0]));
                out.hlp.push(h);
                out.source.push(v);
                (out.hlp.len() - 1) as u32
            });
            out.mesh.indices.push(index);
        }
    }
    out
}

/// Reorders the triangles of `split` by HLP and returns, per HLP index below `count`, the range
/// of its indices in `split.mesh.indices`, so one HLP's leaves can be drawn alone.
pub fn sort_by_hlp(split: &mut HlpMesh, count: usize) -> Vec<std::ops::Range<u32>> {
    let indices = &mut split.mesh.indices;
    let mut triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    triangles.sort_by_key(|t| split.hlp[t[0] as usize]);
    *indices = triangles.iter().flatten().copied().collect();
    let mut ranges = vec![0..0; count];
    for (i, t) in triangles.iter().enumerate() {
        let h = split.hlp[t[0] as usize] as usize;
        if let Some(range) = ranges.get_mut(h) {
            let start = if range.start == range.end { 3 * i as u32 } else { range.start };
            *range = start..3 * i as u32 + 3;
        }
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::plant::{Material, MeshPart};

    fn leaf_model(points: &[[f32; 3]]) -> PlantModel {
        // One tiny triangle at each point.
        let mut mesh = Mesh::default();
        for p in points {
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([*p, [p[0] + 0.01, p[1], p[2]], [p[0], p[1] + 0.01, p[2]]]);
            mesh.indices.extend([base, base + 1, base + 2]);
        }
        let material = Material {
            name: "leaves".into(),
            base_color: [1.0; 4],
            texture: None,
            alpha_cutoff: Some(0.5),
            double_sided: true,
        };
        PlantModel { name: "t".into(), parts: vec![MeshPart { kind: PartKind::Foliage, mesh, material }] }
    }

    #[test]
    fn sphere_growth_is_minimal() {
        let s = Sphere { center: Vec3::ZERO, radius: 1.0 }.grown_to(Vec3::new(3.0, 0.0, 0.0));
        assert!((s.radius - 2.0).abs() < 1e-6 && (s.center - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-6);
        let same = Sphere { center: Vec3::ZERO, radius: 1.0 }.grown_to(Vec3::new(0.5, 0.0, 0.0));
        assert_eq!(same.radius, 1.0);
    }

    #[test]
    fn two_distant_clusters_give_two_hlps_within_the_radius() {
        let model = leaf_model(&[[0.0, 0.0, 5.0], [0.3, 0.0, 5.0], [0.0, 0.3, 5.2], [4.0, 0.0, 5.0], [4.2, 0.1, 5.0]]);
        let hlps = cluster(&model, 0.5);
        assert_eq!(hlps.spheres.len(), 2);
        assert_eq!(hlps.triangle_hlp[0], vec![0, 0, 0, 1, 1]);
        assert!(hlps.spheres.iter().all(|s| s.radius <= 0.5));
        // Every vertex lies inside its sphere.
        let mesh = &model.parts[0].mesh;
        for (t, &h) in mesh.indices.chunks_exact(3).zip(&hlps.triangle_hlp[0]) {
            for &v in t {
                let s = hlps.spheres[h as usize];
                assert!(Vec3::from(mesh.positions[v as usize]).distance(s.center) <= s.radius + 1e-5);
            }
        }
    }

    #[test]
    fn shared_vertices_are_split_between_hlps() {
        let mesh = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 4],
            uvs: vec![[0.0; 2]; 4],
            indices: vec![0, 1, 2, 2, 1, 3],
        };
        let split = split_by_hlp(&mesh, &[0, 1]);
        assert_eq!(split.mesh.positions.len(), 6);
        assert_eq!(split.hlp, vec![0, 0, 0, 1, 1, 1]);
        assert_eq!(split.source, vec![0, 1, 2, 2, 1, 3]);
        let same = split_by_hlp(&mesh, &[0, 0]);
        assert_eq!(same.mesh.positions.len(), 4);
        let mut reordered = split_by_hlp(&mesh, &[1, 0]);
        let ranges = sort_by_hlp(&mut reordered, 2);
        assert_eq!(ranges, vec![0..3, 3..6]);
        assert!(reordered.mesh.indices[..3].iter().all(|&v| reordered.hlp[v as usize] == 0));
    }

    #[test]
    fn cache_returns_the_same_clustering() {
        let model = leaf_model(&[[0.0, 0.0, 1.0], [2.0, 0.0, 1.0]]);
        let a = cluster_cached(&model, 0.5, None);
        let b = cluster_cached(&model, 0.5, None);
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(*a, cluster(&model, 0.5));
    }

    #[test]
    fn disk_cache_round_trips_and_rejects_a_different_model() {
        let model = leaf_model(&[[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [2.1, 0.0, 1.0]]);
        let hlps = cluster(&model, 0.5);
        assert_eq!(decode(&encode(&hlps), &model), Some(hlps.clone()));
        let other = leaf_model(&[[0.0, 0.0, 1.0]]);
        assert_eq!(decode(&encode(&hlps), &other), None);
        assert_eq!(decode(&encode(&hlps)[..10], &model), None);
    }
}
