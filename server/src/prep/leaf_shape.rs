//! Leaf shape maps (thesis 4.1, SPEC P3): a leaf texture whose alpha channel encodes a nested
//! series of increasingly abstract leaf outlines, from the original shape (α ≥ α_max) to the
//! most abstract and largest one (α ≥ α_min), so that one alpha test at α_t picks the shape at
//! render time and eq. 4.1 draws its outline.
//!
//! The shapes come from conditional grey-scale dilation (eq. 4.2–4.6): starting from the
//! original alpha thresholded at α_max, iteration i gives every texel outside the previous
//! shapes whose Gaussian-weighted count of neighbours inside them exceeds t the value α_i. The
//! count favours concave regions, so the shapes grow more convex (hence more abstract) instead
//! of only growing larger. The structuring element is 5 × 5 with Gaussian weights
//! exp(−(dx² + dy²)/(2σ²)), σ = 1.5 px and weight 1 at the centre, so f counts neighbours: a
//! texel beside a straight edge counts 4.15, beside a square's corner 2.68, diagonally off a
//! corner 1.47 — with the thesis' t = 3, edges and concavities grow by one texel per
//! iteration, convex corners and tips wait until their neighbours have grown.
//!
//! Colour follows the shapes: every texel outside the original shape gets the RGB of its
//! nearest texel inside it (8-connected breadth-first fill), so abstract shapes (and texture
//! filtering at their edges) show leaf colour instead of the texture's background.

use super::cache::{DiskCache, KeyBuilder, Reader};
use image::RgbaImage;
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, OnceLock};

/// Parameters of thesis eq. 4.2–4.6.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeParams {
    /// α_max (eq. 4.2): texels of the original alpha at or above it form the original shape
    /// and keep their alpha; the others start transparent. Choose the material's alpha cutoff,
    /// so α_t = α_max shows the leaf exactly as the plain alpha test does.
    pub alpha_max: f32,
    /// α_min (eq. 4.3): the alpha of the most abstract (largest) shape; > 0 so that it differs
    /// from the transparent background.
    pub alpha_min: f32,
    /// n, the number of dilation iterations (shapes beyond the original).
    pub iterations: u32,
    /// t of eq. 4.6: a texel joins shape i when its weighted neighbour count f_i exceeds t.
    pub threshold: f32,
}

impl Default for ShapeParams {
    /// α_max = 0.5 (glTF's default alpha cutoff, used by the procedural leaves), α_min = 0.05,
    /// 12 iterations, t = 3 (the thesis' best value).
    fn default() -> Self {
        ShapeParams { alpha_max: 0.5, alpha_min: 0.05, iterations: 12, threshold: 3.0 }
    }
}

impl ShapeParams {
    /// Eq. 4.3: α_i = α_max − i·(α_max − α_min)/n, the alpha threshold that selects shape i
    /// (0 the original, n the most abstract). The map stores shape i's alpha as
    /// round(255·α_i) + 1, between α_i + 0.5/255 and α_i + 1.5/255, so a test α ≥ α_i keeps
    /// shapes 0..=i whatever the rounding, as long as the steps are at least 2/255 apart.
    pub fn level(&self, i: u32) -> f32 {
        let n = self.iterations.max(1) as f32;
        self.alpha_max - i as f32 * (self.alpha_max - self.alpha_min) / n
    }
}

/// Eq. 4.1: whether a texel of alpha `alpha` is on the outline at threshold `alpha_t` with
/// thickness `delta`: it passes the alpha test (α ≥ α_t) and 0 ≤ α − α_t ≤ Δα.
pub fn on_outline(alpha: f32, alpha_t: f32, delta: f32) -> bool {
    alpha >= alpha_t && alpha - alpha_t <= delta
}

/// Half the side of the structuring element (5 × 5).
const RADIUS: i64 = 2;
/// σ of its Gaussian weights, in texels.
const SIGMA: f32 = 1.5;

/// The weights g(d) = exp(−d²/(2σ²)) for d = −2..=2; the 2D element is g(dx)·g(dy).
fn weights() -> [f32; 5] {
    std::array::from_fn(|k| {
        let d = k as f32 - RADIUS as f32;
        (-d * d / (2.0 * SIGMA * SIGMA)).exp()
    })
}

/// Eq. 4.4: f(x, y) = Σ_k G_k·[texel k inside], the Gaussian-weighted count of the texels of
/// `inside` in the structuring element around each texel (outside the image counts as empty),
/// by two separable passes.
fn neighbour_counts(inside: &[bool], width: usize, height: usize) -> Vec<f32> {
    let g = weights();
    let at = |v: usize, d: usize, n: usize| (v + d).checked_sub(RADIUS as usize).filter(|&u| u < n);
    let mut rows = vec![0.0f32; inside.len()];
    for y in 0..height {
        for x in 0..width {
            rows[y * width + x] =
                (0..5).filter_map(|k| at(x, k, width).map(|u| g[k] * f32::from(u8::from(inside[y * width + u])))).sum();
        }
    }
    let mut counts = vec![0.0f32; inside.len()];
    for y in 0..height {
        for x in 0..width {
            counts[y * width + x] = (0..5).filter_map(|k| at(y, k, height).map(|v| g[k] * rows[v * width + x])).sum();
        }
    }
    counts
}

/// The leaf shape map: the texture's RGB kept, alpha replaced by the nested shapes encoding.
///
/// Texels of the original shape (alpha ≥ α_max) keep their alpha and colour; a texel first
/// covered by iteration i gets α_i (just above it in 8 bits, see [`ShapeParams::level`]) and the colour of its nearest
/// original texel; texels outside every shape get alpha 0 (and that colour too).
pub fn shape_map(texture: &image::RgbaImage, params: &ShapeParams) -> image::RgbaImage {
    let (width, height) = (texture.width() as usize, texture.height() as usize);
    let mut out = texture.clone();
    // Eq. 4.2: I = I_O where I_O ≥ α_max, else 0.
    let mut inside: Vec<bool> = texture.pixels().map(|p| f32::from(p[3]) / 255.0 >= params.alpha_max).collect();
    let original = inside.clone();
    for (p, &keep) in out.pixels_mut().zip(&inside) {
        if !keep {
            p[3] = 0;
        }
    }
    for i in 1..=params.iterations {
        // Eq. 4.4–4.6: texels outside the shapes so far whose count f_i exceeds t get α_i.
        let alpha = ((params.level(i) * 255.0).round() + 1.0).clamp(1.0, 255.0) as u8;
        let counts = neighbour_counts(&inside, width, height);
        let grown: Vec<usize> = (0..inside.len()).filter(|&k| !inside[k] && counts[k] > params.threshold).collect();
        for k in grown {
            inside[k] = true;
            out.as_mut()[4 * k + 3] = alpha;
        }
    }
    fill_colour(&mut out, &original, width, height);
    out
}

/// Gives every texel outside `sources` the RGB of its nearest source texel (breadth-first over
/// 8-connected neighbours); leaves the image alone without sources.
fn fill_colour(image: &mut RgbaImage, sources: &[bool], width: usize, height: usize) {
    let mut done = sources.to_vec();
    let mut queue: VecDeque<usize> = (0..sources.len()).filter(|&k| sources[k]).collect();
    let raw = image.as_mut();
    while let Some(k) = queue.pop_front() {
        let (x, y) = ((k % width) as i64, (k / width) as i64);
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (1, -1), (-1, 1), (1, 1)] {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
                continue;
            }
            let n = ny as usize * width + nx as usize;
            if !done[n] {
                done[n] = true;
                raw.copy_within(4 * k..4 * k + 3, 4 * n);
                queue.push_back(n);
            }
        }
    }
}

/// [`shape_map`] cached in memory and on disk by the texture's content and the parameters.
pub fn shape_map_cached(
    texture: &Arc<image::RgbaImage>,
    params: &ShapeParams,
    disk: Option<&DiskCache>,
) -> Arc<image::RgbaImage> {
    type Cache = Mutex<HashMap<String, Arc<RgbaImage>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let key = KeyBuilder::default()
        .bytes(b"leaf shapes v1")
        .u64(u64::from(texture.width()))
        .u64(u64::from(texture.height()))
        .bytes(texture.as_raw())
        .f32(params.alpha_max)
        .f32(params.alpha_min)
        .u64(u64::from(params.iterations))
        .f32(params.threshold)
        .finish();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(hit) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return hit.clone();
    }
    let size = texture.dimensions();
    let map = Arc::new(match disk {
        Some(disk) => {
            disk.get_or_compute("leaf_shapes", &key, |b| decode(b, size), encode, || shape_map(texture, params))
        }
        None => shape_map(texture, params),
    });
    cache.lock().unwrap_or_else(|e| e.into_inner()).insert(key, map.clone());
    map
}

/// Width, height (u32, little endian), then the RGBA bytes.
fn encode(image: &RgbaImage) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 + image.as_raw().len());
    out.extend(image.width().to_le_bytes());
    out.extend(image.height().to_le_bytes());
    out.extend(image.as_raw());
    out
}

/// Reads what [`encode`] wrote, rejecting another size than `size` or a wrong length.
fn decode(bytes: &[u8], size: (u32, u32)) -> Option<RgbaImage> {
    let mut r = Reader::new(bytes);
    if (r.u32()?, r.u32()?) != size {
        return None;
    }
    let raw = r.take(4 * size.0 as usize * size.1 as usize)?.to_vec();
    if !r.is_empty() {
        return None;
    }
    RgbaImage::from_raw(size.0, size.1, raw)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::plant::PartKind;
    use crate::scene::procedural::{ProceduralKind, procedural_plant};
    use image::Rgba;

    /// An opaque green shape on a transparent red background.
    fn mask_image(width: u32, height: u32, inside: impl Fn(u32, u32) -> bool) -> RgbaImage {
        RgbaImage::from_fn(
            width,
            height,
            |x, y| {
                if inside(x, y) { Rgba([30, 160, 40, 255]) } else { Rgba([255, 0, 0, 0]) }
            },
        )
    }

    /// The texels of shape `i` of `map`: alpha ≥ α_i.
    fn shape(map: &RgbaImage, params: &ShapeParams, i: u32) -> Vec<bool> {
        map.pixels().map(|p| f32::from(p[3]) / 255.0 >= params.level(i)).collect()
    }

    fn count(mask: &[bool]) -> usize {
        mask.iter().filter(|&&m| m).count()
    }

    /// Area of the convex hull of the texel squares of `mask` (monotone chain over their corners).
    fn hull_area(mask: &[bool], width: u32) -> f64 {
        let mut points: Vec<(i64, i64)> = (0..mask.len())
            .filter(|&k| mask[k])
            .flat_map(|k| {
                let (x, y) = ((k as u32 % width) as i64, (k as u32 / width) as i64);
                [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]
            })
            .collect();
        points.sort_unstable();
        points.dedup();
        let cross = |o: (i64, i64), a: (i64, i64), b: (i64, i64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
        let mut hull: Vec<(i64, i64)> = Vec::new();
        for pass in [points.clone(), points.iter().rev().copied().collect()] {
            let start = hull.len();
            for p in pass {
                while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0 {
                    hull.pop();
                }
                hull.push(p);
            }
            hull.pop();
        }
        let twice: i64 = (0..hull.len()).map(|i| cross((0, 0), hull[i], hull[(i + 1) % hull.len()])).sum();
        twice.abs() as f64 / 2.0
    }

    /// (hull area − area) / hull area: 0 for a convex shape.
    fn deficiency(mask: &[bool], width: u32) -> f64 {
        let hull = hull_area(mask, width);
        (hull - count(mask) as f64) / hull
    }

    #[test]
    fn outline_follows_eq_4_1() {
        // α_t = 0.4, Δα = 0.05: 0.42 and 0.45 are on it, 0.46 inside, 0.39 cut away.
        assert!(on_outline(0.42, 0.4, 0.05));
        assert!(on_outline(0.45, 0.4, 0.05));
        assert!(!on_outline(0.46, 0.4, 0.05));
        assert!(!on_outline(0.39, 0.4, 0.05));
        assert!(on_outline(0.4, 0.4, 0.0));
    }

    #[test]
    fn levels_follow_eq_4_3() {
        // α_max = 0.5, α_min = 0.05, n = 12: steps of 0.45 / 12 = 0.0375.
        let p = ShapeParams::default();
        assert_eq!(p.level(0), 0.5);
        assert!((p.level(4) - 0.35).abs() < 1e-6);
        assert!((p.level(12) - 0.05).abs() < 1e-6);
    }

    #[test]
    fn threshold_t_decides_which_texels_grow() {
        // A 5 × 5 square at x, y ∈ 2..=6 in a 9 × 9 image, one iteration. With the weights
        // g(0) = 1, g(1) = e^(−1/4.5) = 0.80074, g(2) = e^(−4/4.5) = 0.41111 (row sum S = 3.42370):
        // (4, 1), above the middle of the top edge: S·(g1 + g2) = 3.4237 · 1.21185 = 4.149;
        // (3, 1): (g1 + 1 + g1 + g2)·(g1 + g2) = 3.01259 · 1.21185 = 3.651;
        // (2, 1), above the corner: (1 + g1 + g2)·(g1 + g2) = 2.21185 · 1.21185 = 2.680;
        // (1, 1), diagonally off the corner: (g1 + g2)² = 1.469;
        // (4, 0), two above the edge: S·g2 = 1.408.
        let square = mask_image(9, 9, |x, y| (2..=6).contains(&x) && (2..=6).contains(&y));
        let counts = neighbour_counts(&square.pixels().map(|p| p[3] > 0).collect::<Vec<_>>(), 9, 9);
        for ((x, y), f) in [((4, 1), 4.149), ((3, 1), 3.651), ((2, 1), 2.680), ((1, 1), 1.469), ((4, 0), 1.408)] {
            assert!((counts[y * 9 + x] - f).abs() < 2e-3, "({x}, {y}): {}", counts[y * 9 + x]);
        }
        let grown = |t: f32| {
            let params = ShapeParams { iterations: 1, threshold: t, ..ShapeParams::default() };
            let map = shape_map(&square, &params);
            let at = |x: u32, y: u32| map.get_pixel(x, y)[3] > 0;
            (count(&shape(&map, &params, 1)) - 25, at(2, 1), at(1, 1), at(4, 0))
        };
        // t = 3: the three middle texels of each side (3·4 = 12), not the corners' neighbours.
        assert_eq!(grown(3.0), (12, false, false, false));
        // t = 2.5: whole sides (5·4 = 20), still not the diagonal.
        assert_eq!(grown(2.5), (20, true, false, false));
        // t = 1.4: the diagonal corners too, and the texels two off the edges' middles.
        let (_, side, diagonal, second) = grown(1.4);
        assert!(side && diagonal && second);
        // t = 4.2: nothing grows.
        assert_eq!(grown(4.2).0, 0);
    }

    #[test]
    fn shapes_are_nested_and_grow_every_iteration() {
        let leaf = procedural_plant(ProceduralKind::Broadleaf, 1);
        let texture = leaf.parts_of(PartKind::Foliage).next().unwrap().material.texture.clone().unwrap();
        let params = ShapeParams::default();
        let map = shape_map(&texture, &params);
        // Shape 0 is the original leaf at α_max, with its alpha and colour.
        let original: Vec<bool> = texture.pixels().map(|p| f32::from(p[3]) / 255.0 >= 0.5).collect();
        assert_eq!(shape(&map, &params, 0), original);
        for (a, b) in texture.pixels().zip(map.pixels()).filter(|(a, _)| f32::from(a[3]) / 255.0 >= 0.5) {
            assert_eq!(a, b);
        }
        let mut previous = original;
        for i in 1..=params.iterations {
            let current = shape(&map, &params, i);
            assert!(previous.iter().zip(&current).all(|(p, c)| !p || *c), "shape {i} does not contain shape {}", i - 1);
            assert!(count(&current) > count(&previous), "shape {i} did not grow");
            previous = current;
        }
        // Texels outside every shape are transparent; covered ones have the leaf's colour.
        for (p, inside) in map.pixels().zip(&previous) {
            assert_eq!(p[3] > 0, *inside);
            if *inside {
                assert!(p[1] > p[0] && p[1] > p[2], "{p:?} is not leaf green");
            }
        }
    }

    #[test]
    fn concavities_fill_first_and_shapes_become_convex() {
        // An L: a 40 × 12 bar and a 12 × 40 bar sharing a corner, in a 64 × 64 image.
        let l = mask_image(64, 64, |x, y| {
            (8..48).contains(&x) && (8..20).contains(&y) || (8..20).contains(&x) && (8..48).contains(&y)
        });
        let params = ShapeParams::default();
        let map = shape_map(&l, &params);
        let original = shape(&map, &params, 0);
        let abstract_ = shape(&map, &params, params.iterations);
        let (before, after) = (deficiency(&original, 64), deficiency(&abstract_, 64));
        assert!(after < 0.6 * before, "convex-hull deficiency {before:.3} → {after:.3}");
        // Compared with plain dilation (t = 0: any neighbour), the conditional operator puts a
        // larger share of its growth into the concavity (inside the original's convex hull).
        let hull_of_l = |x: u32, y: u32| x >= 8 && y >= 8 && x + y < 48 + 20 + 1;
        let share_in_concavity = |t: f32| {
            let p = ShapeParams { iterations: 4, threshold: t, ..params };
            let grown = shape(&shape_map(&l, &p), &p, 4);
            let new: Vec<usize> = (0..grown.len()).filter(|&k| grown[k] && !original[k]).collect();
            new.iter().filter(|&&k| hull_of_l(k as u32 % 64, k as u32 / 64)).count() as f64 / new.len() as f64
        };
        let (conditional, plain) = (share_in_concavity(3.0), share_in_concavity(0.0));
        assert!(conditional > plain + 0.05, "concavity share {conditional:.3} vs plain dilation {plain:.3}");
    }

    #[test]
    fn colour_is_filled_from_the_nearest_leaf_texel() {
        // Left half blue, right half green, both opaque in a band; the background is red.
        let image = RgbaImage::from_fn(20, 20, |x, y| match ((8..12).contains(&y), x < 10) {
            (true, true) => Rgba([0, 0, 200, 255]),
            (true, false) => Rgba([0, 200, 0, 255]),
            _ => Rgba([255, 0, 0, 0]),
        });
        let map = shape_map(&image, &ShapeParams::default());
        assert_eq!(&map.get_pixel(2, 7).0[..3], &[0, 0, 200]);
        assert_eq!(&map.get_pixel(17, 1).0[..3], &[0, 200, 0]);
        assert!(map.pixels().all(|p| p[0] == 0), "red background left");
        // No leaf at all: alpha 0 everywhere, colour untouched.
        let empty = shape_map(&mask_image(4, 4, |_, _| false), &ShapeParams::default());
        assert!(empty.pixels().all(|p| p.0 == [255, 0, 0, 0]));
    }

    #[test]
    fn cache_round_trips_in_memory_and_on_disk() {
        let texture = Arc::new(mask_image(16, 16, |x, y| (4..12).contains(&x) && (3..13).contains(&y) && x != 8));
        let params = ShapeParams { iterations: 5, ..ShapeParams::default() };
        let map = shape_map(&texture, &params);
        assert_eq!(decode(&encode(&map), (16, 16)), Some(map.clone()));
        assert_eq!(decode(&encode(&map), (16, 8)), None);
        assert_eq!(decode(&encode(&map)[..100], (16, 16)), None);

        let dir = tempfile::tempdir().unwrap();
        let disk = DiskCache::open(dir.path()).unwrap();
        let first = shape_map_cached(&texture, &params, Some(&disk));
        assert_eq!(*first, map);
        assert_eq!(disk.stats().misses, 1);
        // The same content in another Arc hits the memory cache.
        assert!(Arc::ptr_eq(&first, &shape_map_cached(&Arc::new((*texture).clone()), &params, None)));
        // The disk entry decodes to the same map.
        let entries: Vec<_> = std::fs::read_dir(dir.path().join("leaf_shapes")).unwrap().collect();
        assert_eq!(entries.len(), 1);
        let bytes = std::fs::read(entries[0].as_ref().unwrap().path()).unwrap();
        assert_eq!(decode(&bytes, (16, 16)), Some(map));
        let other = ShapeParams { threshold: 2.0, ..params };
        assert!(!Arc::ptr_eq(&first, &shape_map_cached(&texture, &other, None)));
    }
}
