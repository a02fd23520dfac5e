//! Expressive illumination of foliage based on implicit surfaces (Luft, Balzer, Deussen 2007,
//! §2.3–3.3; SPEC P2): a metaball density field over the leaf centres gives every foliage
//! vertex an ambient coefficient k_a (denser inside the crown → darker, eq. 4) and a normal
//! realigned to the implicit surface F = 0 (the normal at the surface point nearest to the
//! vertex), so lighting follows the crown's overall shape instead of the random orientation of
//! single leaves.
//!
//! The paper stores k_a in the length of the (replaced) vertex normal. We keep the original
//! normal, so styles can blend between original, implicit and HLP normals at run time (SPEC
//! R6), and give each vertex one extra attribute: the realigned unit normal scaled by k_a
//! ([`Illumination::normals`]; see `render::gbuffer::Vertex::implicit`).
//!
//! Parameters are relative to the model ([`ImplicitParams`]), so the defaults fit any plant
//! ("values that provide adequate results can be automatically specified with regard to the
//! size of the model", §3.1): ρ is a fraction of the foliage's size, τ and d_min fractions of
//! the density in the core of the crown. [`ImplicitParams::resolve`] turns them into the
//! paper's absolute values for one model.

use super::cache::{DiskCache, KeyBuilder, Reader};
use super::hlp::{Hlps, model_hash};
use crate::rng::SplitMix64;
use crate::scene::plant::{PartKind, PlantModel};
use glam::Vec3;
use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock};

/// Eq. 2: the density of one generator at distance `distance`, radius of influence `radius`:
/// (1 − (d/r)²)² inside the radius, 0 beyond.
pub fn metaball(distance: f32, radius: f32) -> f32 {
    if distance >= radius {
        return 0.0;
    }
    let s = 1.0 - (distance / radius).powi(2);
    s * s
}

/// Eq. 4: the ambient reflection coefficient of a vertex with field value `d` = F(v): 1 outside
/// the implicit surface (d ≤ 0), k_a_min in the core (d ≥ d_min), and
/// k_a_min + (1 − k_a_min)·(1 − d/d_min)ⁿ between.
pub fn ambient_coefficient(d: f32, ka_min: f32, d_min: f32, exponent: f32) -> f32 {
    if d <= 0.0 {
        1.0
    } else if d >= d_min {
        ka_min
    } else {
        ka_min + (1.0 - ka_min) * (1.0 - d / d_min).powf(exponent)
    }
}

/// The density field F(q) = Σᵢ Dᵢ(q) − τ (eq. 3) of a set of generators with one radius of
/// influence ρ, with the generators bucketed in a grid of ρ-sized cells so that evaluating it
/// touches only the 27 cells around q.
#[derive(Debug, Clone)]
pub struct DensityField {
    radius: f32,
    threshold: f32,
    /// Generators sorted by cell.
    generators: Vec<Vec3>,
    /// Cell → range of `generators`.
    cells: HashMap<[i32; 3], (u32, u32)>,
}

/// Newton steps at most this many times ρ long, so a step from where the field is flat does
/// not jump across the crown.
const MAX_STEP: f32 = 0.25;
/// Newton iterations before a projection is given up.
const MAX_ITERATIONS: usize = 64;
/// A projection has converged when the remaining step (|F| / |∇F|) is below this times ρ.
const TOLERANCE: f32 = 1e-3;

impl DensityField {
    /// The field of `generators` with radius of influence `radius` (ρ > 0) and threshold
    /// `threshold` (τ ≥ 0).
    pub fn new(generators: Vec<Vec3>, radius: f32, threshold: f32) -> DensityField {
        let radius = radius.max(f32::MIN_POSITIVE);
        let mut keyed: Vec<([i32; 3], Vec3)> = generators.into_iter().map(|p| (cell_of(p, radius), p)).collect();
        keyed.sort_by_key(|(cell, _)| *cell);
        let mut cells = HashMap::new();
        let mut start = 0;
        for i in 1..=keyed.len() {
            if i == keyed.len() || keyed[i].0 != keyed[start].0 {
                cells.insert(keyed[start].0, (start as u32, i as u32));
                start = i;
            }
        }
        DensityField { radius, threshold, generators: keyed.into_iter().map(|(_, p)| p).collect(), cells }
    }

    /// ρ, the radius of influence.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// τ, the threshold.
    pub fn threshold(&self) -> f32 {
        self.threshold
    }

    /// Calls `f` with the offset q − pᵢ of every generator within one cell of q's cell.
    fn near(&self, q: Vec3, mut f: impl FnMut(Vec3)) {
        let [x, y, z] = cell_of(q, self.radius);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(&(a, b)) = self.cells.get(&[x + dx, y + dy, z + dz]) {
                        self.generators[a as usize..b as usize].iter().for_each(|p| f(q - *p));
                    }
                }
            }
        }
    }

    /// Σᵢ Dᵢ(q): the summed density of the generators (eq. 2), without the threshold.
    pub fn density(&self, q: Vec3) -> f32 {
        let mut sum = 0.0;
        self.near(q, |d| sum += metaball(d.length(), self.radius));
        sum
    }

    /// F(q) = Σᵢ Dᵢ(q) − τ (eq. 3): positive inside the implicit surface, negative outside.
    pub fn value(&self, q: Vec3) -> f32 {
        self.density(q) - self.threshold
    }

    /// F(q) and its gradient ∇F(q) = Σᵢ −4·(1 − |q − pᵢ|²/ρ²)·(q − pᵢ)/ρ² (pointing towards
    /// higher density, i.e. into the foliage).
    pub fn value_and_gradient(&self, q: Vec3) -> (f32, Vec3) {
        let r2 = self.radius * self.radius;
        let (mut sum, mut gradient) = (0.0, Vec3::ZERO);
        self.near(q, |d| {
            let s = 1.0 - d.length_squared() / r2;
            if s > 0.0 {
                sum += s * s;
                gradient += d * (-4.0 * s / r2);
            }
        });
        (sum - self.threshold, gradient)
    }

    /// The point of the implicit surface F = 0 reached from `q` by Newton steps along the
    /// gradient, q ← q − F(q)·∇F/|∇F|² (each at most ρ/4 long): the surface point near q in
    /// the direction the density falls or rises fastest. `None` where the field is flat (no
    /// generator within ρ, or a density extremum) or the steps do not converge.
    pub fn project(&self, q: Vec3) -> Option<Vec3> {
        let mut q = q;
        for _ in 0..MAX_ITERATIONS {
            let (f, gradient) = self.value_and_gradient(q);
            let g = gradient.length();
            if !g.is_finite() || g * self.radius <= 1e-6 {
                return None;
            }
            let step = gradient * (-f / (g * g));
            let length = step.length();
            if length <= TOLERANCE * self.radius {
                return Some(q + step);
            }
            q += step * (MAX_STEP * self.radius / length).min(1.0);
        }
        None
    }

    /// The outward unit normal −∇F/|∇F| of the implicit surface at its point reached from `q`
    /// ([`DensityField::project`]); `None` where the projection fails.
    pub fn surface_normal(&self, q: Vec3) -> Option<Vec3> {
        let surface = self.project(q)?;
        (-self.value_and_gradient(surface).1).try_normalize()
    }
}

fn cell_of(p: Vec3, size: f32) -> [i32; 3] {
    (p / size).floor().as_ivec3().to_array()
}

/// The parameters of the implicit surface and of eq. 4, relative to the model (see the module
/// documentation); [`ImplicitParams::resolve`] gives the absolute values for one model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitParams {
    /// ρ as a fraction of the foliage's size R (half the diagonal of the foliage's bounding
    /// box). Small values follow single branches, large ones the whole crown (§3.1).
    pub radius: f32,
    /// τ as a fraction of the core density D_core (the 90th percentile of Σᵢ Dᵢ at the
    /// generators): lower values put the surface further outside the leaves.
    pub threshold: f32,
    /// k_a_min of eq. 4 (> 0, so the normal's direction survives the scaling).
    pub ka_min: f32,
    /// d_min of eq. 4 as a fraction of D_core − τ, the field value in the core: below 1 the
    /// darkening saturates before the core.
    pub d_min: f32,
    /// n of eq. 4: < 1 darkens slowly from the surface inwards, > 1 quickly.
    pub exponent: f32,
    /// At most this many generators, a seeded random subset of the leaf triangles beyond it
    /// (§3.1: "randomly selecting just a fraction of the geometric primitives").
    pub max_generators: u32,
    /// Seed of that subset.
    pub seed: u64,
}

impl Default for ImplicitParams {
    /// ρ = 0.25·R, τ = 0.2·D_core, k_a_min = 0.25, d_min = D_core − τ, n = 1, at most 4096
    /// generators: on the sample plants the median leaf gets k_a ≈ 0.5, the outermost 10 %
    /// k_a ≈ 0.8–1 and the core k_a_min.
    fn default() -> Self {
        ImplicitParams {
            radius: 0.25,
            threshold: 0.2,
            ka_min: 0.25,
            d_min: 1.0,
            exponent: 1.0,
            max_generators: 4096,
            seed: 1,
        }
    }
}

/// The absolute parameters for one model (the paper's ρ, τ, k_a_min, d_min, n).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resolved {
    /// ρ in model units.
    pub radius: f32,
    /// τ.
    pub threshold: f32,
    /// k_a_min.
    pub ka_min: f32,
    /// d_min.
    pub d_min: f32,
    /// n.
    pub exponent: f32,
    /// D_core, the density the relative values refer to.
    pub core_density: f32,
}

/// Percentile of the densities at the generators taken as the core density.
const CORE_PERCENTILE: f32 = 0.9;

impl ImplicitParams {
    /// The generators of `model` (centroids of its foliage triangles, at most
    /// `max_generators` of them: a seeded random subset) and the absolute parameters, with the
    /// density field they define. `None` for a model without foliage.
    pub fn resolve(&self, model: &PlantModel) -> Option<(Resolved, DensityField)> {
        let mut generators: Vec<Vec3> = model
            .parts_of(PartKind::Foliage)
            .flat_map(|part| {
                let p = &part.mesh.positions;
                part.mesh.indices.chunks_exact(3).map(|t| {
                    (Vec3::from(p[t[0] as usize]) + Vec3::from(p[t[1] as usize]) + Vec3::from(p[t[2] as usize])) / 3.0
                })
            })
            .collect();
        // Partial Fisher–Yates: the first `max` entries become a uniform random subset.
        let max = (self.max_generators.max(1) as usize).min(generators.len());
        let mut rng = SplitMix64::new(self.seed);
        for i in 0..max {
            let j = i + (rng.next_u64() % (generators.len() - i) as u64) as usize;
            generators.swap(i, j);
        }
        generators.truncate(max);
        let size = foliage_size(model)?;
        if generators.is_empty() {
            return None;
        }
        let radius = (self.radius * size).max(1e-4);
        let unthresholded = DensityField::new(generators.clone(), radius, 0.0);
        let mut densities: Vec<f32> = generators.iter().map(|p| unthresholded.density(*p)).collect();
        densities.sort_by(f32::total_cmp);
        let core_density = densities[((densities.len() - 1) as f32 * CORE_PERCENTILE).round() as usize];
        let threshold = self.threshold * core_density;
        let resolved = Resolved {
            radius,
            threshold,
            ka_min: self.ka_min,
            d_min: (self.d_min * (core_density - threshold)).max(1e-6),
            exponent: self.exponent,
            core_density,
        };
        Some((resolved, DensityField::new(generators, radius, threshold)))
    }

    fn cache_key(&self, model: &PlantModel) -> String {
        let mut normals = std::collections::hash_map::DefaultHasher::new();
        for part in &model.parts {
            for n in &part.mesh.normals {
                n.map(f32::to_bits).hash(&mut normals);
            }
        }
        KeyBuilder::default()
            .bytes(b"implicit v1")
            .u64(model_hash(model))
            .u64(normals.finish())
            .f32(self.radius)
            .f32(self.threshold)
            .f32(self.ka_min)
            .f32(self.d_min)
            .f32(self.exponent)
            .u64(u64::from(self.max_generators))
            .u64(self.seed)
            .finish()
    }
}

/// R: half the diagonal of the bounding box of the foliage vertices; `None` without foliage.
fn foliage_size(model: &PlantModel) -> Option<f32> {
    let (lo, hi) = model
        .parts_of(PartKind::Foliage)
        .filter_map(|part| part.mesh.bounds())
        .map(|(lo, hi)| (Vec3::from(lo), Vec3::from(hi)))
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))?;
    Some(0.5 * (hi - lo).length())
}

/// The implicit-surface illumination of one model: per part (the model's parts in order), per
/// vertex, the realigned normal N_s scaled by the ambient coefficient k_a (eq. 4), in model
/// space; wood parts are empty. A vertex whose projection onto the surface fails keeps its own
/// normal (scaled by its k_a).
#[derive(Debug, Clone, PartialEq)]
pub struct Illumination {
    /// `normals[part][vertex]` = k_a·N_s.
    pub normals: Vec<Vec<[f32; 3]>>,
}

/// Computes the [`Illumination`] of `model`'s foliage with `params`. Without a field (no leaf
/// triangles) every foliage vertex keeps its own normal with k_a = 1.
pub fn illuminate(model: &PlantModel, params: &ImplicitParams) -> Illumination {
    let resolved = params.resolve(model);
    let normals = model
        .parts
        .iter()
        .map(|part| {
            if part.kind != PartKind::Foliage {
                return Vec::new();
            }
            let mesh = &part.mesh;
            mesh.positions
                .iter()
                .enumerate()
                .map(|(i, position)| {
                    let v = Vec3::from(*position);
                    let own = Vec3::from(mesh.normals.get(i).copied().unwrap_or([0.0, 0.0, 1.0])).normalize_or(Vec3::Z);
                    let Some((p, field)) = &resolved else { return own.to_array() };
                    let ka = ambient_coefficient(field.value(v), p.ka_min, p.d_min, p.exponent);
                    (field.surface_normal(v).unwrap_or(own) * ka).to_array()
                })
                .collect()
        })
        .collect();
    Illumination { normals }
}

impl Illumination {
    /// The mean ambient coefficient k_a of the leaf vertices of every HLP of `hlps` (the
    /// clustering of the same model), and of the whole foliage: what the billboards that stand
    /// for those leaves at a distance carry, so ambient occlusion stays across levels of
    /// detail. HLPs without leaves get 1.
    pub fn hlp_ambient(&self, model: &PlantModel, hlps: &Hlps) -> (Vec<f32>, f32) {
        let mut sums = vec![(0.0f64, 0u32); hlps.spheres.len()];
        let mut total = (0.0f64, 0u32);
        for ((part, triangle_hlp), normals) in model.parts.iter().zip(&hlps.triangle_hlp).zip(&self.normals) {
            for (triangle, &h) in part.mesh.indices.chunks_exact(3).zip(triangle_hlp) {
                for &v in triangle {
                    let ka = f64::from(Vec3::from(normals[v as usize]).length());
                    for sum in [&mut sums[h as usize], &mut total] {
                        *sum = (sum.0 + ka, sum.1 + 1);
                    }
                }
            }
        }
        let mean = |(sum, n): (f64, u32)| if n == 0 { 1.0 } else { (sum / f64::from(n)) as f32 };
        (sums.into_iter().map(mean).collect(), mean(total))
    }
}

/// [`illuminate`] with a process-wide cache keyed by the model's content (geometry and
/// normals) and the parameters, like [`super::hlp::cluster_cached`]; with `disk`, also cached
/// across restarts.
pub fn illuminate_cached(model: &PlantModel, params: &ImplicitParams, disk: Option<&DiskCache>) -> Arc<Illumination> {
    type Cache = Mutex<HashMap<String, Arc<Illumination>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let key = params.cache_key(model);
    let cache = CACHE.get_or_init(Default::default);
    if let Some(hit) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return hit.clone();
    }
    let illumination = Arc::new(match disk {
        Some(disk) => disk.get_or_compute("implicit", &key, |b| decode(b, model), encode, || illuminate(model, params)),
        None => illuminate(model, params),
    });
    cache.lock().unwrap_or_else(|e| e.into_inner()).insert(key, illumination.clone());
    illumination
}

/// Serialises an illumination: part count, then per part the vertex count and the vectors
/// (little endian).
fn encode(illumination: &Illumination) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((illumination.normals.len() as u32).to_le_bytes());
    for part in &illumination.normals {
        out.extend((part.len() as u32).to_le_bytes());
        out.extend(part.iter().flatten().flat_map(|v| v.to_le_bytes()));
    }
    out
}

/// Reads what [`encode`] wrote, checking part and vertex counts against `model`.
fn decode(bytes: &[u8], model: &PlantModel) -> Option<Illumination> {
    let mut r = Reader::new(bytes);
    if r.u32()? as usize != model.parts.len() {
        return None;
    }
    let mut normals = Vec::with_capacity(model.parts.len());
    for part in &model.parts {
        let n = r.u32()? as usize;
        let expected = if part.kind == PartKind::Foliage { part.mesh.positions.len() } else { 0 };
        if n != expected {
            return None;
        }
        normals.push((0..n).map(|_| Some([r.f32()?, r.f32()?, r.f32()?])).collect::<Option<Vec<_>>>()?);
    }
    r.is_empty().then_some(Illumination { normals })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prep::hlp::Sphere;
    use crate::scene::mesh::Mesh;
    use crate::scene::plant::{Material, MeshPart};

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-5
    }

    /// A foliage model with one small leaf triangle at each point (normal +x, a "random" leaf
    /// orientation) and a wood part.
    fn leaf_model(points: &[Vec3]) -> PlantModel {
        let mut mesh = Mesh::default();
        for p in points {
            let base = mesh.positions.len() as u32;
            mesh.positions
                .extend([*p, *p + Vec3::new(0.0, 0.02, 0.0), *p + Vec3::new(0.0, 0.0, 0.02)].map(|v| v.to_array()));
            mesh.normals.extend([[1.0, 0.0, 0.0]; 3]);
            mesh.uvs.extend([[0.0; 2]; 3]);
            mesh.indices.extend([base, base + 1, base + 2]);
        }
        let material = |name: &str| Material {
            name: name.into(),
            base_color: [1.0; 4],
            texture: None,
            alpha_cutoff: None,
            double_sided: true,
        };
        let trunk = Mesh {
            positions: vec![[0.0; 3], [0.1, 0.0, 0.0], [0.0, 0.0, 1.0]],
            normals: vec![[0.0, -1.0, 0.0]; 3],
            uvs: vec![[0.0; 2]; 3],
            indices: vec![0, 1, 2],
        };
        PlantModel {
            name: "ball".into(),
            parts: vec![
                MeshPart { kind: PartKind::Wood, mesh: trunk, material: material("bark") },
                MeshPart { kind: PartKind::Foliage, mesh, material: material("leaves") },
            ],
        }
    }

    /// `n` points spread evenly through a ball of radius `r` about `center` (a Fibonacci spiral
    /// on shells).
    fn ball(center: Vec3, r: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let t = (i as f32 + 0.5) / n as f32;
                let z = 1.0 - 2.0 * t;
                let phi = i as f32 * 2.399_963;
                let dir = Vec3::new((1.0 - z * z).sqrt() * phi.cos(), (1.0 - z * z).sqrt() * phi.sin(), z);
                center + dir * r * ((i * 7919 % n) as f32 / n as f32).cbrt()
            })
            .collect()
    }

    #[test]
    fn metaball_follows_eq_2() {
        // d = 0: (1 − 0)² = 1; d = 0.5, r = 1: (1 − 0.25)² = 0.5625; d = 1, r = 2: the same;
        // d = 0.8, r = 1: (1 − 0.64)² = 0.1296; at and beyond r: 0.
        assert_eq!(metaball(0.0, 2.0), 1.0);
        assert!(close(metaball(0.5, 1.0), 0.5625));
        assert!(close(metaball(1.0, 2.0), 0.5625));
        assert!(close(metaball(0.8, 1.0), 0.1296));
        assert_eq!(metaball(1.0, 1.0), 0.0);
        assert_eq!(metaball(3.0, 1.0), 0.0);
    }

    #[test]
    fn field_follows_eq_3_with_its_gradient() {
        // Paper Fig. 2: two generators, ρ = 1, τ = 0.3.
        let field = DensityField::new(vec![Vec3::ZERO, Vec3::X], 1.0, 0.3);
        // Midway: both at 0.5 → 2 · 0.5625 − 0.3 = 0.825.
        assert!(close(field.value(Vec3::new(0.5, 0.0, 0.0)), 0.825));
        // (0, 0.5, 0): 0.5 from p₁ → 0.5625; √1.25 ≈ 1.118 > ρ from p₂ → 0; F = 0.2625.
        assert!(close(field.value(Vec3::new(0.0, 0.5, 0.0)), 0.2625));
        // (2, 0, 0): out of reach of both → F = −τ = −0.3.
        assert!(close(field.value(Vec3::new(2.0, 0.0, 0.0)), -0.3));
        // The gradient matches central differences and points into the foliage.
        let q = Vec3::new(0.3, 0.4, -0.2);
        let (f, g) = field.value_and_gradient(q);
        assert!(close(f, field.value(q)));
        let h = 1e-3;
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let numeric = (field.value(q + axis * h) - field.value(q - axis * h)) / (2.0 * h);
            assert!((numeric - g.dot(axis)).abs() < 2e-3, "{axis}: {numeric} vs {}", g.dot(axis));
        }
        assert!(g.dot(Vec3::new(0.5, 0.0, 0.0) - q) > 0.0);
    }

    #[test]
    fn the_grid_finds_every_generator_in_reach() {
        let mut rng = SplitMix64::new(3);
        let mut point = || Vec3::new(rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-1.0, 2.0));
        let generators: Vec<Vec3> = (0..300).map(|_| point()).collect();
        let field = DensityField::new(generators.clone(), 0.7, 0.0);
        for _ in 0..200 {
            let q = point();
            let brute: f32 = generators.iter().map(|p| metaball(p.distance(q), 0.7)).sum();
            assert!((field.density(q) - brute).abs() < 1e-4, "{q}");
        }
    }

    #[test]
    fn ambient_coefficient_follows_eq_4() {
        // k_a_min = 0.2, d_min = 0.5: outside (d ≤ 0) 1; at and beyond d_min 0.2.
        assert_eq!(ambient_coefficient(-0.1, 0.2, 0.5, 2.0), 1.0);
        assert_eq!(ambient_coefficient(0.0, 0.2, 0.5, 2.0), 1.0);
        assert_eq!(ambient_coefficient(0.6, 0.2, 0.5, 2.0), 0.2);
        // d = 0.25: 1 − d/d_min = 0.5; n = 2: 0.2 + 0.8 · 0.25 = 0.4; n = 1: 0.2 + 0.8 · 0.5 = 0.6;
        // n = 1/3: 0.2 + 0.8 · 0.7937 = 0.835.
        assert!(close(ambient_coefficient(0.25, 0.2, 0.5, 2.0), 0.4));
        assert!(close(ambient_coefficient(0.25, 0.2, 0.5, 1.0), 0.6));
        assert!((ambient_coefficient(0.25, 0.2, 0.5, 1.0 / 3.0) - 0.835).abs() < 1e-3);
    }

    #[test]
    fn one_generator_realigns_normals_radially() {
        // One generator at c, ρ = 2, τ = 0.3: the surface is the sphere where
        // (1 − r²/4)² = 0.3, r = 2·√(1 − √0.3) = 2 · √0.45228 ≈ 1.34504.
        let c = Vec3::new(1.0, 2.0, 3.0);
        let field = DensityField::new(vec![c], 2.0, 0.3);
        let surface = 2.0 * (1.0 - 0.3f32.sqrt()).sqrt();
        assert!((surface - 1.34504).abs() < 1e-4);
        for dir in [Vec3::X, Vec3::new(1.0, -2.0, 0.5).normalize(), Vec3::new(-0.3, 0.1, -1.0).normalize()] {
            for distance in [0.2, 1.0, 1.9] {
                let q = c + dir * distance;
                let on = field.project(q).expect("projects");
                assert!((on.distance(c) - surface).abs() < 2e-3, "{distance}: {}", on.distance(c));
                let normal = field.surface_normal(q).expect("normal");
                assert!(normal.dot(dir) > 0.9999, "{dir} at {distance}: {normal}");
            }
        }
        // At the generator itself and beyond ρ the field is flat: no normal.
        assert_eq!(field.surface_normal(c), None);
        assert_eq!(field.surface_normal(c + Vec3::splat(3.0)), None);
    }

    #[test]
    fn a_leaf_ball_gets_radial_normals_and_darkens_inwards() {
        let center = Vec3::new(0.0, 0.0, 4.0);
        let model = leaf_model(&ball(center, 2.0, 1500));
        let illumination = illuminate(&model, &ImplicitParams::default());
        assert!(illumination.normals[0].is_empty(), "wood gets no implicit normal");
        let foliage = &model.parts[1].mesh.positions;
        assert_eq!(illumination.normals[1].len(), foliage.len());
        let (mut outer_ka, mut inner_ka, mut radial, mut outer) = (Vec::new(), Vec::new(), 0, 0);
        for (p, n) in foliage.iter().zip(&illumination.normals[1]) {
            let (offset, n) = (Vec3::from(*p) - center, Vec3::from(*n));
            if offset.length() > 1.6 {
                outer += 1;
                radial += usize::from(n.normalize().dot(offset.normalize()) > 0.8);
                outer_ka.push(n.length());
            } else if offset.length() < 0.8 {
                inner_ka.push(n.length());
            }
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        // The leaves all face +x, yet near the crown's surface the normals point outwards.
        assert!(radial * 10 > outer * 9, "{radial} of {outer} outer normals radial");
        assert!(mean(&inner_ka) < 0.5 * mean(&outer_ka), "inner k_a {} vs outer {}", mean(&inner_ka), mean(&outer_ka));
        let ka_min = ImplicitParams::default().ka_min;
        assert!(illumination.normals[1].iter().all(|n| Vec3::from(*n).length() >= ka_min - 1e-5));
    }

    #[test]
    fn billboards_get_the_mean_ambient_coefficient_of_their_leaves() {
        let model = leaf_model(&ball(Vec3::new(0.0, 0.0, 4.0), 2.0, 600));
        let illumination = illuminate(&model, &ImplicitParams::default());
        // Two HLPs: the leaves near the centre and the rest; the inner one is darker.
        let foliage = &model.parts[1].mesh;
        let inner: Vec<u32> = foliage
            .indices
            .chunks_exact(3)
            .map(|t| u32::from(Vec3::from(foliage.positions[t[0] as usize]).distance(Vec3::new(0.0, 0.0, 4.0)) > 1.0))
            .collect();
        let hlps = Hlps {
            spheres: vec![Sphere { center: Vec3::new(0.0, 0.0, 4.0), radius: 1.0 }; 3],
            triangle_hlp: vec![Vec::new(), inner.clone()],
        };
        let (per_hlp, plant) = illumination.hlp_ambient(&model, &hlps);
        assert!(per_hlp[0] < per_hlp[1], "{per_hlp:?}");
        assert_eq!(per_hlp[2], 1.0, "an HLP without leaves");
        let all: Vec<f32> = illumination.normals[1].iter().map(|n| Vec3::from(*n).length()).collect();
        let mean = all.iter().sum::<f32>() / all.len() as f32;
        assert!((plant - mean).abs() < 1e-4 && per_hlp[0] < plant && plant < per_hlp[1]);
    }

    #[test]
    fn defaults_scale_with_the_model() {
        let points = ball(Vec3::new(0.0, 0.0, 4.0), 2.0, 400);
        let small = leaf_model(&points);
        let mut large = small.clone();
        for part in &mut large.parts {
            part.mesh.positions.iter_mut().for_each(|p| *p = (Vec3::from(*p) * 3.0).to_array());
        }
        let params = ImplicitParams::default();
        let (a, b) = (params.resolve(&small).unwrap().0, params.resolve(&large).unwrap().0);
        assert!((b.radius / a.radius - 3.0).abs() < 1e-3);
        assert!((b.threshold - a.threshold).abs() < 1e-3 * a.threshold);
        let (ia, ib) = (illuminate(&small, &params), illuminate(&large, &params));
        for (na, nb) in ia.normals[1].iter().zip(&ib.normals[1]) {
            assert!(Vec3::from(*na).distance(Vec3::from(*nb)) < 1e-2, "{na:?} vs {nb:?}");
        }
        // A subset of the generators (§3.1) gives a similar field.
        let subset = ImplicitParams { max_generators: 200, ..params };
        let (resolved, field) = subset.resolve(&small).unwrap();
        assert_eq!(field.generators.len(), 200);
        assert!(resolved.radius == a.radius && resolved.core_density < a.core_density);
    }

    #[test]
    fn cache_round_trips_in_memory_and_on_disk() {
        let model = leaf_model(&ball(Vec3::new(5.0, 0.0, 3.0), 1.0, 60));
        let params = ImplicitParams { seed: 77, ..ImplicitParams::default() };
        let computed = illuminate(&model, &params);
        assert_eq!(decode(&encode(&computed), &model), Some(computed.clone()));
        assert_eq!(decode(&encode(&computed)[..20], &model), None);
        assert_eq!(decode(&encode(&computed), &leaf_model(&[Vec3::ZERO])), None);

        let dir = tempfile::tempdir().unwrap();
        let disk = DiskCache::open(dir.path()).unwrap();
        let first = illuminate_cached(&model, &params, Some(&disk));
        assert_eq!(*first, computed);
        assert_eq!(disk.stats().misses, 1);
        assert!(Arc::ptr_eq(&first, &illuminate_cached(&model, &params, None)));
        // The entry on disk decodes to the same illumination (a restart computes nothing).
        let key = params.cache_key(&model);
        let stored = disk.get_or_compute("implicit", &key, |b| decode(b, &model), encode, || unreachable!());
        assert_eq!(stored, computed);
        // Other parameters or other normals are other entries.
        assert_ne!(ImplicitParams { radius: 0.3, ..params }.cache_key(&model), key);
        let mut turned = model.clone();
        turned.parts[1].mesh.normals[0] = [0.0, 1.0, 0.0];
        assert_ne!(params.cache_key(&turned), key);
    }
}
