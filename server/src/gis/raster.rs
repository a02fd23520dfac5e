//! In-memory single-band georeferenced rasters (north-up) and their sampling.

use std::path::Path;

use super::crs::Crs;
use super::error::GisError;

/// Largest raster accepted on load (width × height), 2^28 cells (2 GiB of `f64`).
pub const MAX_CELLS: u64 = 1 << 28;

/// Affine north-up georeferencing: CRS x of the left edge of column 0, y of the top edge of
/// row 0, cell sizes (both > 0; rows go south).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoTransform {
    /// CRS x of the left edge of column 0.
    pub origin_x: f64,
    /// CRS y of the top edge of row 0.
    pub origin_y: f64,
    /// Cell size along x (> 0).
    pub cell_width: f64,
    /// Cell size along y (> 0; row index grows southwards).
    pub cell_height: f64,
}

impl GeoTransform {
    /// Fractional grid position (column, row) of a CRS point; cell `(c, r)` covers
    /// `[c, c+1) × [r, r+1)`.
    pub fn to_grid(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.origin_x) / self.cell_width, (self.origin_y - y) / self.cell_height)
    }

    /// CRS point of a fractional grid position (inverse of [`GeoTransform::to_grid`]).
    pub fn to_crs(&self, col: f64, row: f64) -> (f64, f64) {
        (self.origin_x + col * self.cell_width, self.origin_y - row * self.cell_height)
    }
}

/// An axis-aligned rectangle in CRS coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// West edge.
    pub min_x: f64,
    /// South edge.
    pub min_y: f64,
    /// East edge.
    pub max_x: f64,
    /// North edge.
    pub max_y: f64,
}

impl Extent {
    /// Centre point.
    pub fn center(&self) -> (f64, f64) {
        (0.5 * (self.min_x + self.max_x), 0.5 * (self.min_y + self.max_y))
    }

    /// Width along x in CRS units.
    pub fn width(&self) -> f64 {
        self.max_x - self.min_x
    }

    /// Height along y in CRS units.
    pub fn height(&self) -> f64 {
        self.max_y - self.min_y
    }

    /// Whether the point lies inside or on the boundary.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.min_x && x <= self.max_x && y >= self.min_y && y <= self.max_y
    }
}

/// A single-band georeferenced raster held as `f64` cells.
#[derive(Debug, Clone)]
pub struct Raster {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Cell values, row-major, row 0 = north.
    pub data: Vec<f64>,
    /// Value marking missing cells (NaN cells are always missing).
    pub nodata: Option<f64>,
    /// Georeferencing.
    pub transform: GeoTransform,
    /// Coordinate reference system of the transform.
    pub crs: Crs,
    /// TIFF ColorMap scaled to 8 bit, for palette rasters (index = cell value).
    pub palette: Option<Vec<[u8; 3]>>,
}

impl Raster {
    /// Whether `v` is a valid (non-nodata, non-NaN) value for this raster.
    pub fn is_valid(&self, v: f64) -> bool {
        !v.is_nan() && self.nodata != Some(v)
    }

    /// The value at a cell; `None` if out of range, nodata or NaN.
    pub fn get(&self, col: usize, row: usize) -> Option<f64> {
        if col >= self.width || row >= self.height {
            return None;
        }
        let v = *self.data.get(row * self.width + col)?;
        self.is_valid(v).then_some(v)
    }

    /// The rectangle the raster covers in CRS coordinates.
    pub fn extent(&self) -> Extent {
        extent_of(&self.transform, self.width, self.height)
    }

    /// CRS coordinates of the centre of a cell (no range check).
    pub fn cell_center(&self, col: usize, row: usize) -> (f64, f64) {
        self.transform.to_crs(col as f64 + 0.5, row as f64 + 0.5)
    }

    /// The cell containing a CRS point (the east and south edges of the extent belong to the
    /// last column/row); `None` outside the extent.
    pub fn cell_at(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let (fc, fr) = self.transform.to_grid(x, y);
        let (w, h) = (self.width as f64, self.height as f64);
        if !(0.0..=w).contains(&fc) || !(0.0..=h).contains(&fr) {
            return None;
        }
        // In range and non-negative, so the casts cannot wrap.
        let col = (fc.floor() as usize).min(self.width.saturating_sub(1));
        let row = (fr.floor() as usize).min(self.height.saturating_sub(1));
        Some((col, row))
    }

    /// The value of the cell containing a CRS point; `None` outside or on nodata.
    pub fn sample_nearest(&self, x: f64, y: f64) -> Option<f64> {
        let (col, row) = self.cell_at(x, y)?;
        self.get(col, row)
    }

    /// Bilinear interpolation between cell centres at a CRS point. Points between the extent's
    /// edge and the outermost cell centres are clamped to those centres. `None` outside the
    /// extent or if a neighbour with non-zero weight is nodata.
    pub fn sample_bilinear(&self, x: f64, y: f64) -> Option<f64> {
        self.cell_at(x, y)?;
        let (fc, fr) = self.transform.to_grid(x, y);
        let (c0, tc) = lerp_axis(fc - 0.5, self.width);
        let (r0, tr) = lerp_axis(fr - 0.5, self.height);
        let corners = [
            (c0, r0, (1.0 - tc) * (1.0 - tr)),
            (c0 + 1, r0, tc * (1.0 - tr)),
            (c0, r0 + 1, (1.0 - tc) * tr),
            (c0 + 1, r0 + 1, tc * tr),
        ];
        let mut sum = 0.0;
        for (c, r, w) in corners {
            if w > 0.0 {
                sum += w * self.get(c, r)?;
            }
        }
        Some(sum)
    }

    /// Minimum and maximum over valid cells; `None` if there are none.
    pub fn valid_range(&self) -> Option<(f64, f64)> {
        self.data.iter().copied().filter(|&v| self.is_valid(v)).fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
    }

    /// Number of valid cells.
    pub fn valid_count(&self) -> usize {
        self.data.iter().filter(|&&v| self.is_valid(v)).count()
    }

    /// A sub-window of `width × height` cells starting at (`col0`, `row0`), with the
    /// georeferencing moved to the window. Errors if the window is empty or does not fit.
    pub fn crop(&self, col0: usize, row0: usize, width: usize, height: usize) -> Result<Raster, GisError> {
        let fits =
            |start: usize, len: usize, total: usize| len > 0 && start.checked_add(len).is_some_and(|end| end <= total);
        if !fits(col0, width, self.width) || !fits(row0, height, self.height) {
            return Err(GisError::CropOutOfRange {
                col0,
                row0,
                width,
                height,
                raster_width: self.width,
                raster_height: self.height,
            });
        }
        if self.width.checked_mul(self.height) != Some(self.data.len()) {
            return Err(GisError::InconsistentRaster { len: self.data.len(), width: self.width, height: self.height });
        }
        // The window fits and the data has width × height values, so the slices are in range.
        let data = (row0..row0 + height)
            .flat_map(|r| {
                let start = r * self.width + col0;
                self.data[start..start + width].iter().copied()
            })
            .collect();
        let (origin_x, origin_y) = self.transform.to_crs(col0 as f64, row0 as f64);
        Ok(Raster {
            width,
            height,
            data,
            nodata: self.nodata,
            transform: GeoTransform { origin_x, origin_y, ..self.transform },
            crs: self.crs,
            palette: self.palette.clone(),
        })
    }
}

impl Raster {
    /// The cells (column, row, width, height) whose area meets `extent` (CRS coordinates);
    /// `None` if it does not overlap the raster.
    pub fn window_of(&self, extent: &Extent) -> Option<(usize, usize, usize, usize)> {
        window(&self.transform, self.width, self.height, extent)
    }

    /// The raster averaged down by `factor` along both axes: each cell the mean of the valid
    /// cells of its `factor` × `factor` block (blocks at the east and south edges may be
    /// partial), nodata where a block has none. A DEM too large for the terrain keeps its
    /// relief at a coarser cell this way, without the aliasing of taking every n-th cell.
    pub fn decimate(&self, factor: usize) -> Raster {
        let factor = factor.max(1);
        let (w, h) = (self.width.div_ceil(factor), self.height.div_ceil(factor));
        let fill = self.nodata.unwrap_or(f64::NAN);
        let mut data = Vec::with_capacity(w * h);
        for row in 0..h {
            for col in 0..w {
                let (mut sum, mut n) = (0.0, 0u32);
                for r in row * factor..((row + 1) * factor).min(self.height) {
                    for c in col * factor..((col + 1) * factor).min(self.width) {
                        if let Some(v) = self.get(c, r) {
                            sum += v;
                            n += 1;
                        }
                    }
                }
                data.push(if n > 0 { sum / f64::from(n) } else { fill });
            }
        }
        let t = self.transform;
        Raster {
            width: w,
            height: h,
            data,
            transform: GeoTransform {
                cell_width: t.cell_width * factor as f64,
                cell_height: t.cell_height * factor as f64,
                ..t
            },
            nodata: self.nodata,
            crs: self.crs,
            palette: self.palette.clone(),
        }
    }
}

/// The rectangle a `width` × `height` grid placed by `t` covers.
pub fn extent_of(t: &GeoTransform, width: usize, height: usize) -> Extent {
    Extent {
        min_x: t.origin_x,
        max_x: t.origin_x + width as f64 * t.cell_width,
        max_y: t.origin_y,
        min_y: t.origin_y - height as f64 * t.cell_height,
    }
}

/// The cells (column, row, width, height) of a `width` × `height` grid placed by `t` whose
/// area meets `extent`; `None` if none does.
pub fn window(t: &GeoTransform, width: usize, height: usize, extent: &Extent) -> Option<(usize, usize, usize, usize)> {
    let (c0, r0) = t.to_grid(extent.min_x, extent.max_y);
    let (c1, r1) = t.to_grid(extent.max_x, extent.min_y);
    let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64);
    // Clamped to 0..=n, so the casts are in range.
    let (c0, c1) = (clamp(c0.floor(), width) as usize, clamp(c1.ceil(), width) as usize);
    let (r0, r1) = (clamp(r0.floor(), height) as usize, clamp(r1.ceil(), height) as usize);
    (c1 > c0 && r1 > r0).then_some((c0, r0, c1 - c0, r1 - r0))
}

/// The smallest whole factor `f` with ⌈width / f⌉ × ⌈height / f⌉ ≤ `max_cells` (1 when the
/// grid fits): how much a DEM is averaged down to fit a terrain's cell budget.
pub fn fit_factor(width: usize, height: usize, max_cells: u64) -> usize {
    let cells = (width as u64).saturating_mul(height as u64);
    if cells <= max_cells.max(1) {
        return 1;
    }
    let mut factor = ((cells as f64 / max_cells.max(1) as f64).sqrt().floor() as usize).max(2);
    while (width.div_ceil(factor) as u64).saturating_mul(height.div_ceil(factor) as u64) > max_cells.max(1) {
        factor += 1;
    }
    factor
}

/// For a fractional position `g` between cell centres (centre i at `g = i`), the lower index
/// and the weight of the upper one, clamped to the outermost centres.
fn lerp_axis(g: f64, n: usize) -> (usize, f64) {
    if n < 2 {
        return (0, 0.0);
    }
    let last = (n - 1) as f64;
    let g = g.clamp(0.0, last);
    // `g` is in [0, n-1], so the cast is exact and in range.
    let i = (g.floor() as usize).min(n - 2);
    let t = g - i as f64;
    // Snap rounding noise of CRS → grid conversion, so that a point at a cell centre gives
    // exactly that cell's value and does not depend on its neighbours.
    let t = if t < SNAP {
        0.0
    } else if t > 1.0 - SNAP {
        1.0
    } else {
        t
    };
    (i, t)
}

/// Interpolation weights closer than this to 0 or 1 (in cells) are snapped.
const SNAP: f64 = 1e-9;

/// Checks width × height against [`MAX_CELLS`] (and zero sizes) for a file being loaded.
pub fn check_dimensions(path: &Path, width: u64, height: u64) -> Result<(), GisError> {
    if width == 0 || height == 0 {
        return Err(GisError::Format {
            path: path.to_path_buf(),
            message: format!("raster has zero size ({width} × {height} cells)"),
        });
    }
    if width.checked_mul(height).is_none_or(|n| n > MAX_CELLS) {
        return Err(GisError::TooLarge { path: path.to_path_buf(), width, height, limit: MAX_CELLS });
    }
    Ok(())
}

/// Checks that a freshly loaded raster has at least one valid cell.
pub fn check_not_all_nodata(path: &Path, raster: &Raster) -> Result<(), GisError> {
    if raster.data.iter().any(|&v| raster.is_valid(v)) {
        Ok(())
    } else {
        Err(GisError::AllNodata { path: path.to_path_buf() })
    }
}

/// Checks that a transform has finite coordinates and positive finite cell sizes.
pub fn check_transform(path: &Path, t: &GeoTransform) -> Result<(), GisError> {
    let bad = |reason: String| GisError::BadGeoreferencing { path: path.to_path_buf(), reason };
    if !t.origin_x.is_finite() || !t.origin_y.is_finite() {
        return Err(bad(format!("origin ({}, {}) is not finite", t.origin_x, t.origin_y)));
    }
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !positive(t.cell_width) || !positive(t.cell_height) {
        return Err(bad(format!("cell size {} × {} must be positive", t.cell_width, t.cell_height)));
    }
    Ok(())
}

/// Loads a raster by extension: `.tif`/`.tiff` → GeoTIFF, `.asc` → ESRI ASCII grid (with a
/// sibling `.prj` if present). Band 1 only.
pub fn load_raster(path: &Path) -> Result<Raster, GisError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("tif" | "tiff") => super::geotiff::read_geotiff(path),
        Some("asc") => super::ascii_grid::read_ascii_grid(path),
        _ => Err(GisError::UnknownFormat { path: path.to_path_buf() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3 × 2 raster with 10 m cells, origin (100, 50), values 1..6, nodata -1.
    fn small() -> Raster {
        Raster {
            width: 3,
            height: 2,
            data: vec![1.0, 2.0, 3.0, 4.0, 5.0, -1.0],
            nodata: Some(-1.0),
            transform: GeoTransform { origin_x: 100.0, origin_y: 50.0, cell_width: 10.0, cell_height: 10.0 },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        }
    }

    #[test]
    fn get_and_extent() {
        let r = small();
        assert_eq!(r.get(0, 0), Some(1.0));
        assert_eq!(r.get(2, 1), None);
        assert_eq!(r.get(3, 0), None);
        assert_eq!(r.get(0, 2), None);
        let e = r.extent();
        assert_eq!(e, Extent { min_x: 100.0, min_y: 30.0, max_x: 130.0, max_y: 50.0 });
        assert_eq!(r.cell_center(1, 1), (115.0, 35.0));
        assert_eq!(r.valid_range(), Some((1.0, 5.0)));
        assert_eq!(r.valid_count(), 5);
    }

    #[test]
    fn nearest_includes_far_edges() {
        let r = small();
        assert_eq!(r.sample_nearest(100.0, 50.0), Some(1.0));
        assert_eq!(r.sample_nearest(119.9, 30.0), Some(5.0));
        assert_eq!(r.sample_nearest(130.0, 50.0), Some(3.0));
        assert_eq!(r.sample_nearest(99.9, 45.0), None);
        assert_eq!(r.sample_nearest(105.0, 50.1), None);
        assert_eq!(r.sample_nearest(f64::NAN, 45.0), None);
    }

    #[test]
    fn bilinear_interpolates_and_clamps() {
        let r = small();
        // Centre of the 2×2 block of cells (0..1, 0..1): mean of 1, 2, 4, 5.
        assert_eq!(r.sample_bilinear(110.0, 40.0), Some(3.0));
        // On the vertical line through the centres of column 1: mean of 2 and 5.
        assert_eq!(r.sample_bilinear(115.0, 40.0), Some(3.5));
        // Exactly at a centre next to nodata: the nodata neighbour has zero weight.
        assert_eq!(r.sample_bilinear(115.0, 35.0), Some(5.0));
        // Between a valid centre and the nodata one.
        assert_eq!(r.sample_bilinear(120.0, 35.0), None);
        // West edge clamps to the first centre column; a quarter of the way down.
        let v = r.sample_bilinear(100.0, 42.5).unwrap();
        assert!((v - (1.0 * 0.75 + 4.0 * 0.25)).abs() < 1e-12);
        assert_eq!(r.sample_bilinear(100.0, 50.0), Some(1.0));
        assert_eq!(r.sample_bilinear(131.0, 45.0), None);
    }

    #[test]
    fn bilinear_snaps_near_centres() {
        let r = small();
        let (x, y) = r.cell_center(1, 1);
        assert_eq!(r.sample_bilinear(x + 1e-12, y - 1e-12), Some(5.0));
    }

    #[test]
    fn bilinear_on_single_cell() {
        let mut r = small();
        r.width = 1;
        r.height = 1;
        r.data = vec![7.0];
        assert_eq!(r.sample_bilinear(101.0, 49.0), Some(7.0));
    }

    #[test]
    fn window_of_an_extent_and_decimation() {
        // small(): 3 × 2 cells of 10 m from (100, 50): x 100..130, y 30..50.
        let r = small();
        let e = |min_x, min_y, max_x, max_y| Extent { min_x, min_y, max_x, max_y };
        assert_eq!(r.window_of(&e(111.0, 31.0, 119.0, 39.0)), Some((1, 1, 1, 1)));
        assert_eq!(r.window_of(&e(0.0, 0.0, 1000.0, 1000.0)), Some((0, 0, 3, 2)));
        assert_eq!(r.window_of(&e(105.0, 45.0, 125.0, 46.0)), Some((0, 0, 3, 1)));
        assert_eq!(r.window_of(&e(200.0, 0.0, 300.0, 10.0)), None);
        // Blocks of 2 × 2: (1+2+4+5)/4, and 3 alone (the nodata cell is left out).
        let d = r.decimate(2);
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.data, vec![3.0, 3.0]);
        assert_eq!((d.transform.cell_width, d.transform.origin_x), (20.0, 100.0));
        let all_nodata = Raster { data: vec![-1.0; 6], ..small() };
        assert_eq!(all_nodata.decimate(3).data, vec![-1.0]);
        assert_eq!(r.decimate(1).data, r.data);
    }

    #[test]
    fn crop_moves_origin() {
        let r = small();
        let c = r.crop(1, 1, 2, 1).unwrap();
        assert_eq!((c.width, c.height), (2, 1));
        assert_eq!(c.data, vec![5.0, -1.0]);
        assert_eq!((c.transform.origin_x, c.transform.origin_y), (110.0, 40.0));
        assert_eq!(c.get(0, 0), r.get(1, 1));
        let mut short = r.clone();
        short.data.pop();
        assert!(matches!(short.crop(0, 0, 1, 1), Err(GisError::InconsistentRaster { .. })));
        for (c0, r0, w, h) in [(0, 0, 0, 1), (2, 0, 2, 1), (0, 1, 1, 2), (usize::MAX, 0, 2, 1)] {
            assert!(matches!(r.crop(c0, r0, w, h), Err(GisError::CropOutOfRange { .. })));
        }
    }

    #[test]
    fn dimension_checks() {
        let p = Path::new("x.tif");
        assert!(check_dimensions(p, 16384, 16384).is_ok());
        assert!(matches!(check_dimensions(p, 16385, 16384), Err(GisError::TooLarge { .. })));
        assert!(matches!(check_dimensions(p, u64::MAX, 2), Err(GisError::TooLarge { .. })));
        assert!(matches!(check_dimensions(p, 0, 2), Err(GisError::Format { .. })));
    }

    #[test]
    fn nan_is_never_valid() {
        let mut r = small();
        r.data[0] = f64::NAN;
        r.nodata = None;
        assert_eq!(r.get(0, 0), None);
        assert_eq!(r.valid_range(), Some((-1.0, 5.0)));
    }

    #[test]
    fn unknown_extension() {
        let err = load_raster(Path::new("dem.png")).unwrap_err();
        assert!(err.to_string().contains("dem.png"), "{err}");
    }
}
