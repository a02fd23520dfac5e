//! Deterministic value noise for the examples that synthesise sample land covers.

/// A hash of a grid point and a seed, uniform in [0, 1).
fn hash(i: i64, j: i64, seed: u64) -> f64 {
    let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ seed;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [-1, 1] with features about `scale` metres across.
pub fn value_noise(x: f64, y: f64, scale: f64, seed: u64) -> f64 {
    let (fx, fy) = (x / scale, y / scale);
    let (i, j) = (fx.floor() as i64, fy.floor() as i64);
    let (tx, ty) = (fx - fx.floor(), fy - fy.floor());
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * s(t);
    let top = lerp(hash(i, j, seed), hash(i + 1, j, seed), tx);
    let bottom = lerp(hash(i, j + 1, seed), hash(i + 1, j + 1, seed), tx);
    2.0 * lerp(top, bottom, ty) - 1.0
}
