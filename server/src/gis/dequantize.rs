//! Heights stored in whole units (a lidar DTM written as 8-bit metres: 1 m terraces on gentle
//! slopes) turned back into smooth ground. Every cell stays inside its quantization interval
//! [v − q/2, v + q/2] — so the result agrees with the file — while the surface relaxes towards
//! the smoothest one consistent with it: box blurs of shrinking radius, each followed by that
//! clamp (a projection onto the constraint set, as in dequantization by constrained smoothing).
//! Terraces become ramps; banks, cuttings and valley sides higher than q stay.

use super::raster::Raster;

/// Blur radii in cells, coarse to fine, each applied twice.
const RADII: [usize; 5] = [16, 8, 4, 2, 1];

/// The quantization step of `raster`'s values: 1 when every valid value is a whole number and
/// they are not all equal, else `None`.
pub fn quantization_step(raster: &Raster) -> Option<f64> {
    let mut valid = raster.data.iter().copied().filter(|&v| raster.is_valid(v));
    let first = valid.next()?;
    let mut varies = false;
    for v in valid {
        if v.fract() != 0.0 {
            return None;
        }
        varies |= v != first;
    }
    (first.fract() == 0.0 && varies).then_some(1.0)
}

/// Smooths `raster`'s valid cells within ±`step`/2 of their stored values (see the module);
/// nodata cells are left alone and do not pull on their neighbours.
pub fn dequantize(raster: &mut Raster, step: f64) {
    let (w, h) = (raster.width, raster.height);
    let stored: Vec<Option<f64>> = raster.data.iter().map(|&v| raster.is_valid(v).then_some(v)).collect();
    let mut heights: Vec<f64> = stored.iter().map(|v| v.unwrap_or(0.0)).collect();
    let weights: Vec<f64> = stored.iter().map(|v| if v.is_some() { 1.0 } else { 0.0 }).collect();
    let half = 0.5 * step;
    for radius in RADII.into_iter().flat_map(|r| [r, r]) {
        let weighted: Vec<f64> = heights.iter().zip(&weights).map(|(z, w)| z * w).collect();
        let sum = box_blur(&weighted, w, h, radius);
        let count = box_blur(&weights, w, h, radius);
        for (i, z) in heights.iter_mut().enumerate() {
            if let Some(v) = stored[i]
                && count[i] > 0.0
            {
                *z = (sum[i] / count[i]).clamp(v - half, v + half);
            }
        }
    }
    for (cell, (z, v)) in raster.data.iter_mut().zip(heights.into_iter().zip(&stored)) {
        if v.is_some() {
            *cell = z;
        }
    }
}

/// Sums of `values` over (2r + 1)² boxes (clipped at the edges), separably with running sums.
fn box_blur(values: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let mut rows = vec![0.0; values.len()];
    for y in 0..h {
        let line = &values[y * w..(y + 1) * w];
        running_sum(line, r, &mut rows[y * w..(y + 1) * w]);
    }
    let mut out = vec![0.0; values.len()];
    let (mut column, mut summed) = (vec![0.0; h], vec![0.0; h]);
    for x in 0..w {
        for y in 0..h {
            column[y] = rows[y * w + x];
        }
        running_sum(&column, r, &mut summed);
        for y in 0..h {
            out[y * w + x] = summed[y];
        }
    }
    out
}

/// `out[i]` = the sum of `line[i − r ..= i + r]` (clipped).
fn running_sum(line: &[f64], r: usize, out: &mut [f64]) {
    let n = line.len();
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    for v in line {
        prefix.push(prefix[prefix.len() - 1] + v);
    }
    for (i, o) in out.iter_mut().enumerate() {
        *o = prefix[(i + r + 1).min(n)] - prefix[i.saturating_sub(r)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::{Crs, GeoTransform};

    fn ramp(values: Vec<f64>, width: usize) -> Raster {
        Raster {
            width,
            height: values.len() / width,
            data: values,
            nodata: Some(-1.0),
            transform: GeoTransform { origin_x: 0.0, origin_y: 100.0, cell_width: 1.0, cell_height: 1.0 },
            crs: Crs::Projected { epsg: Some(27700), unit_to_metre: 1.0 },
            palette: None,
        }
    }

    #[test]
    fn terraces_become_a_ramp_within_half_a_step_of_the_data() {
        // A 5 % slope stored in whole metres: 20 m terraces, 64 cells wide, 8 rows.
        let (w, h) = (64usize, 8usize);
        let truth: Vec<f64> = (0..w * h).map(|i| 0.05 * (i % w) as f64 + 0.3).collect();
        let mut raster = ramp(truth.iter().map(|v| v.floor()).collect(), w);
        assert_eq!(quantization_step(&raster), Some(1.0));
        let stored = raster.data.clone();
        dequantize(&mut raster, 1.0);
        for (z, v) in raster.data.iter().zip(&stored) {
            assert!((z - v).abs() <= 0.5 + 1e-9, "{z} left its interval around {v}");
        }
        // Away from the ends, the steps are gone: neighbours differ by about the true slope.
        let row = &raster.data[3 * w..4 * w];
        let worst = row[16..48].windows(2).map(|p| (p[1] - p[0] - 0.05).abs()).fold(0.0, f64::max);
        assert!(worst < 0.03, "the slope still steps by up to {worst}");
    }

    #[test]
    fn real_values_and_nodata_are_left_alone() {
        assert_eq!(quantization_step(&ramp(vec![1.5, 2.0, 3.0, 4.0], 2)), None);
        assert_eq!(quantization_step(&ramp(vec![7.0; 4], 2)), None);
        let mut raster = ramp(vec![1.0, -1.0, 3.0, 4.0], 2);
        dequantize(&mut raster, 1.0);
        assert_eq!(raster.data[1], -1.0);
    }
}
