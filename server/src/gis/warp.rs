//! Rasters in the scene's CRS: a raster the scene file names (a land cover, a label layer)
//! may come in any CRS with a definition; on load it is resampled onto a north-up grid in
//! the scene CRS by nearest neighbour (labels stay labels), keeping its nodata.

use std::path::Path;

use super::error::GisError;
use super::raster::{Extent, GeoTransform, MAX_CELLS, Raster, load_raster};
use super::reproject::{CrsDefinition, ReprojectError, Transformer};

/// Points per edge sampled to find a raster's extent in another CRS.
const EDGE_SAMPLES: usize = 32;

/// The full CRS definition of a raster file: a GeoTIFF's GeoKeys (EPSG code, citation or
/// user-defined parameters), else the CRS the reader found (an ASCII grid's `.prj`).
pub fn file_definition(path: &Path, raster: &Raster) -> Result<CrsDefinition, ReprojectError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("tif" | "tiff")) {
        let keys = super::read_geokeys(path)
            .map_err(|e| ReprojectError::Unsupported { crs: "GeoKeys".into(), reason: e.to_string() })?;
        if let Some(def) = CrsDefinition::from_geokeys(&keys)? {
            return Ok(def);
        }
    }
    CrsDefinition::from_crs(&raster.crs)
}

/// Loads a raster and brings it into `scene` (the scene's CRS), cropped to `within` (an
/// extent in the scene CRS, e.g. the DEM's): unchanged when its CRS is the scene's,
/// otherwise resampled by [`warp_nearest`]. `crs` overrides the file's CRS.
pub fn load_raster_in(
    path: &Path,
    crs: Option<&CrsDefinition>,
    scene: &CrsDefinition,
    within: &Extent,
) -> Result<Raster, GisError> {
    let mut bands = bands_in(path, vec![load_raster(path)?], crs, scene, within)?;
    Ok(bands.swap_remove(0))
}

/// [`load_raster_in`] for the bands of one file (e.g. an orthophoto's red, green and blue,
/// [`super::geotiff::read_geotiff_bands`]): each brought into `scene` on the same grid.
pub fn bands_in(
    path: &Path,
    bands: Vec<Raster>,
    crs: Option<&CrsDefinition>,
    scene: &CrsDefinition,
    within: &Extent,
) -> Result<Vec<Raster>, GisError> {
    let reproject = |source| GisError::Reproject { path: path.to_path_buf(), source };
    let Some(first) = bands.first() else { return Ok(bands) };
    let def = match crs {
        Some(c) => c.clone(),
        None => file_definition(path, first).map_err(reproject)?,
    };
    if def.proj_string() == scene.proj_string() {
        return Ok(bands.into_iter().map(|raster| Raster { crs: scene.crs(), ..raster }).collect());
    }
    bands.iter().map(|raster| warp_nearest(raster, &def, scene, within).map_err(reproject)).collect()
}

/// Resamples `src` (in `from`) onto a north-up grid in `to` by nearest neighbour. The grid
/// covers `src`'s extent as transformed (its edges sampled), cut to `within`; its square
/// cells are as large as `src`'s smaller cell side near its centre, so no cell is lost.
/// Cells whose centre falls outside `src` or on its nodata get `src`'s nodata (NaN if it has
/// none).
pub fn warp_nearest(
    src: &Raster,
    from: &CrsDefinition,
    to: &CrsDefinition,
    within: &Extent,
) -> Result<Raster, ReprojectError> {
    let fail = |reason: String| ReprojectError::Resample { from: from.to_string(), to: to.to_string(), reason };
    let fwd = Transformer::new(from, to)?;
    let inv = Transformer::new(to, from)?;
    let e = src.extent();
    let mut bounds: Option<Extent> = None;
    for k in 0..=EDGE_SAMPLES {
        let t = k as f64 / EDGE_SAMPLES as f64;
        let (x, y) = (e.min_x + t * e.width(), e.min_y + t * e.height());
        for (px, py) in [(x, e.min_y), (x, e.max_y), (e.min_x, y), (e.max_x, y)] {
            if let Some((qx, qy)) = fwd.transform(px, py) {
                let b = bounds.get_or_insert(Extent { min_x: qx, min_y: qy, max_x: qx, max_y: qy });
                *b = Extent {
                    min_x: b.min_x.min(qx),
                    min_y: b.min_y.min(qy),
                    max_x: b.max_x.max(qx),
                    max_y: b.max_y.max(qy),
                };
            }
        }
    }
    let b = bounds.ok_or_else(|| fail("no point of its extent can be transformed".into()))?;
    let cut = Extent {
        min_x: b.min_x.max(within.min_x),
        min_y: b.min_y.max(within.min_y),
        max_x: b.max_x.min(within.max_x),
        max_y: b.max_y.min(within.max_y),
    };
    if !(cut.min_x < cut.max_x && cut.min_y < cut.max_y) {
        return Err(ReprojectError::NoOverlap { what: "the raster".into(), crs: to.to_string() });
    }
    let (cx, cy) = e.center();
    let t = &src.transform;
    let cell =
        match (fwd.transform(cx, cy), fwd.transform(cx + t.cell_width, cy), fwd.transform(cx, cy + t.cell_height)) {
            (Some(p0), Some(px), Some(py)) => (px.0 - p0.0).hypot(px.1 - p0.1).min((py.0 - p0.0).hypot(py.1 - p0.1)),
            _ => f64::NAN,
        };
    if !(cell.is_finite() && cell > 0.0) {
        return Err(fail("its cell size cannot be transformed".into()));
    }
    let (w, h) = ((cut.width() / cell).ceil().max(1.0), (cut.height() / cell).ceil().max(1.0));
    if w * h > MAX_CELLS as f64 {
        return Err(fail(format!("the resampled grid of {w} × {h} cells exceeds the limit of {MAX_CELLS} cells")));
    }
    // Checked against MAX_CELLS above, so the casts are in range.
    let (width, height) = (w as usize, h as usize);
    let transform = GeoTransform { origin_x: cut.min_x, origin_y: cut.max_y, cell_width: cell, cell_height: cell };
    let fill = src.nodata.unwrap_or(f64::NAN);
    let mut data = Vec::with_capacity(width * height);
    for r in 0..height {
        for c in 0..width {
            let (x, y) = transform.to_crs(c as f64 + 0.5, r as f64 + 0.5);
            let v = inv.transform(x, y).and_then(|(sx, sy)| src.sample_nearest(sx, sy));
            data.push(v.unwrap_or(fill));
        }
    }
    let out =
        Raster { width, height, data, nodata: src.nodata, transform, crs: to.crs(), palette: src.palette.clone() };
    if out.valid_count() == 0 {
        return Err(ReprojectError::NoOverlap { what: "no valid cell of the raster".into(), crs: to.to_string() });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::Crs;

    /// 4 × 4 cells of 100 m in UTM 13N, values 0..16, nodata 5.
    fn utm() -> Raster {
        Raster {
            width: 4,
            height: 4,
            data: (0..16).map(f64::from).collect(),
            nodata: Some(5.0),
            transform: GeoTransform {
                origin_x: 480_000.0,
                origin_y: 4_400_400.0,
                cell_width: 100.0,
                cell_height: 100.0,
            },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        }
    }

    #[test]
    fn warp_to_geographic_keeps_labels_and_nodata() {
        let src = utm();
        let (from, to) = (CrsDefinition::from_epsg(32613).unwrap(), CrsDefinition::wgs84());
        let all = Extent { min_x: -180.0, min_y: -90.0, max_x: 180.0, max_y: 90.0 };
        let out = warp_nearest(&src, &from, &to, &all).unwrap();
        assert_eq!(out.crs, Crs::Geographic { epsg: Some(4326) });
        assert!(out.data.iter().all(|v| v.is_nan() || (v.fract() == 0.0 && (0.0..16.0).contains(v))));
        assert!(out.data.contains(&5.0), "nodata cells stay nodata");
        // Every cell centre that lands inside the source carries the source value there.
        let inv = Transformer::new(&to, &from).unwrap();
        for r in 0..out.height {
            for c in 0..out.width {
                let (x, y) = out.cell_center(c, r);
                let (sx, sy) = inv.transform(x, y).unwrap();
                let v = out.data[r * out.width + c];
                match src.sample_nearest(sx, sy) {
                    Some(e) => assert_eq!(v, e),
                    None => assert_eq!(v, 5.0),
                }
            }
        }
        let far = Extent { min_x: 0.0, min_y: 0.0, max_x: 1.0, max_y: 1.0 };
        assert!(matches!(warp_nearest(&src, &from, &to, &far), Err(ReprojectError::NoOverlap { .. })));
    }
}
