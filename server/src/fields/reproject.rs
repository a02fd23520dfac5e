//! Fields on the scene: reprojection of a field's grid onto a regular grid in scene metres,
//! the form the renderer uploads as a texture and looks up orthographically along z (D2).
//!
//! A scene point (x, y) in metres goes through the scene's [`LocalFrame`] to the scene CRS,
//! then through a [`Transformer`] to the field's CRS, where the field is sampled (bilinear for
//! scalars, nearest for labels; [`Field::sample`]). Every cell of a [`FieldGrid`] holds the
//! value at its centre.

use chrono::{DateTime, Utc};

use super::FieldError;
use super::field::{Field, FieldKind};
use super::series::TimeSample;
use crate::gis::{CrsDefinition, Extent, LocalFrame, Transformer};
use crate::scene::terrain::Terrain;

/// Where the scene is: its local frame, the full definition of its CRS and its extent in
/// scene metres (x east, y north).
#[derive(Debug, Clone)]
pub struct SceneGeo {
    frame: LocalFrame,
    crs: CrsDefinition,
    min: [f64; 2],
    max: [f64; 2],
}

impl SceneGeo {
    /// A scene from its frame, CRS definition and extent `min`..`max` in scene metres. The
    /// definition must be of the same kind (geographic or projected) as the frame's CRS.
    pub fn new(frame: LocalFrame, crs: CrsDefinition, min: [f64; 2], max: [f64; 2]) -> Result<SceneGeo, FieldError> {
        if frame.crs().is_geographic() != crs.is_geographic() {
            return Err(FieldError::Invalid(format!(
                "scene CRS definition {} does not match the frame's CRS {}",
                crs.label(),
                frame.crs()
            )));
        }
        let ok = min.iter().chain(&max).all(|v| v.is_finite()) && min[0] < max[0] && min[1] < max[1];
        if !ok {
            return Err(FieldError::Invalid(format!("scene extent {min:?}..{max:?} is empty or not finite")));
        }
        Ok(SceneGeo { frame, crs, min, max })
    }

    /// The scene of a terrain: the DEM's frame, the CRS definition of its EPSG code (a DEM
    /// with a user-defined CRS needs [`SceneGeo::new`] with an explicit definition) and the
    /// DEM's full extent.
    pub fn from_terrain(terrain: &Terrain) -> Result<SceneGeo, FieldError> {
        let crs = CrsDefinition::from_crs(terrain.frame.crs())?;
        let e = terrain.dem.extent();
        let (x0, y0) = terrain.frame.to_local(e.min_x, e.min_y);
        let (x1, y1) = terrain.frame.to_local(e.max_x, e.max_y);
        SceneGeo::new(terrain.frame, crs, [x0, y0], [x1, y1])
    }

    /// The scene's local frame.
    pub fn frame(&self) -> &LocalFrame {
        &self.frame
    }

    /// The scene's CRS definition.
    pub fn crs(&self) -> &CrsDefinition {
        &self.crs
    }

    /// South-west corner in scene metres.
    pub fn min(&self) -> [f64; 2] {
        self.min
    }

    /// North-east corner in scene metres.
    pub fn max(&self) -> [f64; 2] {
        self.max
    }

    /// Converts scene points to the scene CRS and to WGS 84 (for comments and their export).
    pub fn locator(&self) -> Result<Locator<'_>, FieldError> {
        let to_wgs84 = Transformer::new(&self.crs, &CrsDefinition::wgs84())?;
        Ok(Locator { geo: self, to_wgs84 })
    }

    /// Describes the extent in the scene CRS and in scene metres (for messages).
    pub fn describe(&self) -> String {
        let (x0, y0) = self.frame.to_crs(self.min[0], self.min[1]);
        let (x1, y1) = self.frame.to_crs(self.max[0], self.max[1]);
        format!(
            "{} in {} = x {:.0}…{:.0} m, y {:.0}…{:.0} m in scene metres",
            describe_extent(&Extent { min_x: x0, min_y: y0, max_x: x1, max_y: y1 }),
            self.crs.label(),
            self.min[0],
            self.max[0],
            self.min[1],
            self.max[1]
        )
    }
}

/// A scene point in the scene CRS and in WGS 84.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// `[x, y]` in the scene CRS (its units).
    pub crs: [f64; 2],
    /// `[longitude, latitude]` in WGS 84 degrees.
    pub lon_lat: [f64; 2],
}

/// Converts scene metres to the scene CRS and WGS 84 ([`SceneGeo::locator`]).
#[derive(Debug)]
pub struct Locator<'a> {
    geo: &'a SceneGeo,
    to_wgs84: Transformer,
}

impl Locator<'_> {
    /// The scene point (`x`, `y`) in the scene CRS and in WGS 84; `None` outside the CRS's
    /// domain.
    pub fn locate(&self, x: f64, y: f64) -> Option<Located> {
        let (cx, cy) = self.geo.frame.to_crs(x, y);
        let (lon, lat) = self.to_wgs84.transform(cx, cy)?;
        Some(Located { crs: [cx, cy], lon_lat: [lon, lat] })
    }
}

/// A regular grid in scene metres: `width × height` square cells of `cell_size` metres whose
/// south-west corner is `min`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    /// South-west corner (x, y) in scene metres.
    pub min: [f64; 2],
    /// Cell edge in metres.
    pub cell_size: f64,
    /// Columns (west → east).
    pub width: usize,
    /// Rows (north → south, like rasters and images).
    pub height: usize,
}

/// Fewest cells along the longer side of a default grid (fine enough that CPU bilinear
/// sampling of a coarse field looks smooth).
pub const MIN_GRID_SIDE: usize = 256;
/// Most cells along either side of a default grid (a GPU texture of at most 1024²).
pub const MAX_GRID_SIDE: usize = 1024;

impl GridSpec {
    /// The grid that covers the whole scene with cells of about `cell_size` metres, at most
    /// `max_side` cells per side (cells grow to respect that).
    pub fn covering(scene: &SceneGeo, cell_size: f64, max_side: usize) -> GridSpec {
        let (w, h) = (scene.max[0] - scene.min[0], scene.max[1] - scene.min[1]);
        let max_side = max_side.max(1) as f64;
        let cell = if cell_size.is_finite() && cell_size > 0.0 { cell_size } else { w.max(h) };
        let cell = cell.max(w.max(h) / max_side);
        // Both ratios are ≤ max_side and positive, so the casts are in range.
        let width = ((w / cell).ceil() as usize).max(1);
        let height = ((h / cell).ceil() as usize).max(1);
        GridSpec { min: scene.min, cell_size: cell, width, height }
    }

    /// Scene point of the centre of cell (`col`, `row`).
    pub fn cell_center(&self, col: usize, row: usize) -> (f64, f64) {
        let top = self.min[1] + self.height as f64 * self.cell_size;
        (self.min[0] + (col as f64 + 0.5) * self.cell_size, top - (row as f64 + 0.5) * self.cell_size)
    }
}

/// A field resampled onto a [`GridSpec`]: row-major `f32` values, row 0 north, NaN = nodata.
/// Scalars hold their values; labels hold label indices (0, 1, …; positions in
/// [`Field::classes`] and in the colour look-up table) as exact small floats.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldGrid {
    /// The grid's geometry in scene metres.
    pub spec: GridSpec,
    /// Scalar or label.
    pub kind: FieldKind,
    /// `spec.width × spec.height` values, row 0 north; NaN where there is no data.
    pub values: Vec<f32>,
}

impl FieldGrid {
    /// The value of a cell; `None` outside or on nodata.
    pub fn get(&self, col: usize, row: usize) -> Option<f32> {
        if col >= self.spec.width || row >= self.spec.height {
            return None;
        }
        self.values.get(row * self.spec.width + col).copied().filter(|v| !v.is_nan())
    }

    /// The value of the cell containing scene point (x, y); `None` outside or on nodata.
    pub fn value_at(&self, x: f64, y: f64) -> Option<f32> {
        let s = &self.spec;
        let col = (x - s.min[0]) / s.cell_size;
        let row = (s.min[1] + s.height as f64 * s.cell_size - y) / s.cell_size;
        if !(col >= 0.0 && row >= 0.0 && col < s.width as f64 && row < s.height as f64) {
            return None;
        }
        // Non-negative and below the grid size, so the casts are in range.
        self.get(col as usize, row as usize)
    }

    /// `[a, b, c, d]` with texture coordinates `u = a·x + b`, `v = c·y + d` for a scene point
    /// (x, y) in metres, for a texture whose first row is the grid's row 0 (north): u runs
    /// west → east over [0, 1], v north → south.
    pub fn uv_transform(&self) -> [f32; 4] {
        let s = &self.spec;
        let (w, h) = (s.width as f64 * s.cell_size, s.height as f64 * s.cell_size);
        let top = s.min[1] + h;
        [(1.0 / w) as f32, (-s.min[0] / w) as f32, (-1.0 / h) as f32, (top / h) as f32]
    }
}

impl Field {
    /// The field's extent in scene metres (bounding box of its outline transformed into the
    /// scene), `None` if no point of the outline can be transformed.
    pub fn scene_extent(&self, scene: &SceneGeo) -> Result<Option<[f64; 4]>, FieldError> {
        let to_scene = Transformer::new(self.crs(), scene.crs())?;
        let e = self.extent();
        const N: usize = 32;
        let mut bbox: Option<[f64; 4]> = None;
        for i in 0..=N {
            let t = i as f64 / N as f64;
            let (x, y) = (e.min_x + t * e.width(), e.min_y + t * e.height());
            for (px, py) in [(x, e.min_y), (x, e.max_y), (e.min_x, y), (e.max_x, y)] {
                let Some((sx, sy)) = to_scene.transform(px, py) else { continue };
                let (lx, ly) = scene.frame.to_local(sx, sy);
                bbox = Some(match bbox {
                    None => [lx, ly, lx, ly],
                    Some(b) => [b[0].min(lx), b[1].min(ly), b[2].max(lx), b[3].max(ly)],
                });
            }
        }
        Ok(bbox)
    }

    /// Checks that the field overlaps the scene; the error names both extents.
    pub fn check_overlap(&self, scene: &SceneGeo) -> Result<(), FieldError> {
        let bbox = self.scene_extent(scene)?;
        let overlaps = bbox
            .is_some_and(|b| b[0] < scene.max[0] && b[2] > scene.min[0] && b[1] < scene.max[1] && b[3] > scene.min[1]);
        if overlaps {
            return Ok(());
        }
        let in_scene = match bbox {
            Some(b) => format!(" = x {:.0}…{:.0} m, y {:.0}…{:.0} m in scene metres", b[0], b[2], b[1], b[3]),
            None => " (cannot be transformed into the scene CRS)".to_string(),
        };
        Err(FieldError::NoOverlap {
            field: format!("{} in {}{in_scene}", describe_extent(&self.extent()), self.crs().label()),
            scene: scene.describe(),
        })
    }

    /// A default grid: the whole scene, with cells about the size of the field's own cells in
    /// metres but at least [`MIN_GRID_SIDE`] and at most [`MAX_GRID_SIDE`] cells along the
    /// longer side.
    pub fn default_grid_spec(&self, scene: &SceneGeo) -> Result<GridSpec, FieldError> {
        let native = self.native_cell_metres(scene)?;
        let longest = (scene.max[0] - scene.min[0]).max(scene.max[1] - scene.min[1]);
        let cell = native.min(longest / MIN_GRID_SIDE as f64);
        Ok(GridSpec::covering(scene, cell, MAX_GRID_SIDE))
    }

    /// Step `step` resampled onto `spec` (scene metres).
    pub fn resample(&self, step: usize, scene: &SceneGeo, spec: &GridSpec) -> Result<FieldGrid, FieldError> {
        if step >= self.steps().len() {
            return Err(FieldError::Invalid(format!("time step {step} does not exist ({} steps)", self.steps().len())));
        }
        let to_field = Transformer::new(scene.crs(), self.crs())?;
        let mut values = Vec::with_capacity(spec.width * spec.height);
        for row in 0..spec.height {
            for col in 0..spec.width {
                let (x, y) = spec.cell_center(col, row);
                let (cx, cy) = scene.frame.to_crs(x, y);
                let v = to_field.transform(cx, cy).and_then(|(fx, fy)| self.sample(step, fx, fy));
                let v = match (self.kind(), v) {
                    (_, None) => f32::NAN,
                    (FieldKind::Scalar, Some(v)) => v as f32,
                    // Indices are < MAX_LABEL_CLASSES, exact in f32.
                    (FieldKind::Label, Some(v)) => self.label_index(v).map_or(f32::NAN, |i| i as f32),
                };
                values.push(v);
            }
        }
        Ok(FieldGrid { spec: *spec, kind: self.kind(), values })
    }

    /// Where time `t` falls in the series ([`TimeSample::locate`]); for a field without time
    /// or for `t = None`, its first step.
    pub fn time_sample(&self, t: Option<DateTime<Utc>>) -> TimeSample {
        let times = self.times();
        match t {
            Some(t) if times.len() == self.steps().len() => {
                TimeSample::locate(&times, t, self.kind()).unwrap_or(TimeSample::single(0))
            }
            _ => TimeSample::single(0),
        }
    }

    /// The field at time `t` on `spec`: eq. 9.4 between the bracketing steps for scalars, the
    /// nearest step for labels (see [`Field::time_sample`]). The [`TimeSample`] says which steps
    /// were used and whether `t` was clamped.
    pub fn grid_at(
        &self,
        t: Option<DateTime<Utc>>,
        scene: &SceneGeo,
        spec: &GridSpec,
    ) -> Result<(FieldGrid, TimeSample), FieldError> {
        let sample = self.time_sample(t);
        let lower = self.resample(sample.lower, scene, spec)?;
        if sample.lower == sample.upper || sample.weight == 0.0 {
            return Ok((lower, sample));
        }
        let upper = self.resample(sample.upper, scene, spec)?;
        let values = sample.blend(&lower.values, &upper.values);
        Ok((FieldGrid { values, ..lower }, sample))
    }

    /// The smaller cell edge of the field in scene metres, measured at the centre of the first
    /// step's grid.
    fn native_cell_metres(&self, scene: &SceneGeo) -> Result<f64, FieldError> {
        let to_scene = Transformer::new(self.crs(), scene.crs())?;
        let r = &self.steps()[0].raster;
        let (cx, cy) = r.extent().center();
        let t = &r.transform;
        let local = |x: f64, y: f64| to_scene.transform(x, y).map(|(sx, sy)| scene.frame.to_local(sx, sy));
        let cell = match (local(cx, cy), local(cx + t.cell_width, cy), local(cx, cy + t.cell_height)) {
            (Some(c), Some(e), Some(n)) => (e.0 - c.0).hypot(e.1 - c.1).min((n.0 - c.0).hypot(n.1 - c.1)),
            _ => f64::INFINITY,
        };
        Ok(if cell.is_finite() && cell > 0.0 { cell } else { f64::INFINITY })
    }
}

/// `x a…b, y c…d` with enough digits for degrees or metres.
fn describe_extent(e: &Extent) -> String {
    let digits = if e.width().abs().max(e.height().abs()) < 50.0 { 4 } else { 0 };
    format!("x {:.*}…{:.*}, y {:.*}…{:.*}", digits, e.min_x, digits, e.max_x, digits, e.min_y, digits, e.max_y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fields::field::FieldStep;
    use crate::gis::{Crs, GeoTransform, Raster};

    /// A 2 × 2 scalar field in UTM 13N with 100 m cells at (500000, 4400000).
    fn utm_field(kind: FieldKind) -> Field {
        let raster = Raster {
            width: 2,
            height: 2,
            data: vec![1.0, 2.0, 3.0, 4.0],
            nodata: None,
            transform: GeoTransform {
                origin_x: 500_000.0,
                origin_y: 4_400_200.0,
                cell_width: 100.0,
                cell_height: 100.0,
            },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        };
        Field::new(kind, CrsDefinition::from_epsg(32613).unwrap(), None, vec![FieldStep { time: None, raster }])
            .unwrap()
    }

    fn utm_scene() -> SceneGeo {
        let frame =
            LocalFrame::new(Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 }, 500_100.0, 4_400_100.0).unwrap();
        SceneGeo::new(frame, CrsDefinition::from_epsg(32613).unwrap(), [-100.0, -100.0], [100.0, 100.0]).unwrap()
    }

    #[test]
    fn same_crs_resample() {
        let f = utm_field(FieldKind::Scalar);
        let scene = utm_scene();
        let spec = GridSpec { min: [-100.0, -100.0], cell_size: 100.0, width: 2, height: 2 };
        let g = f.resample(0, &scene, &spec).unwrap();
        assert_eq!(g.values, vec![1.0, 2.0, 3.0, 4.0]);
        assert_eq!(g.value_at(50.0, -50.0), Some(4.0));
        assert_eq!(g.value_at(150.0, 0.0), None);
        let uv = g.uv_transform();
        assert_eq!((uv[0] * -100.0 + uv[1], uv[2] * 100.0 + uv[3]), (0.0, 0.0));
        assert_eq!((uv[0] * 100.0 + uv[1], uv[2] * -100.0 + uv[3]), (1.0, 1.0));
        let labels = utm_field(FieldKind::Label).resample(0, &scene, &spec).unwrap();
        assert_eq!(labels.values, vec![0.0, 1.0, 2.0, 3.0]);
        let d = f.default_grid_spec(&scene).unwrap();
        assert_eq!((d.width, d.height), (256, 256));
        assert!(f.check_overlap(&scene).is_ok());
    }

    #[test]
    fn covering_respects_max_side() {
        let scene = utm_scene();
        let g = GridSpec::covering(&scene, 0.01, 100);
        assert_eq!((g.width, g.height, g.cell_size), (100, 100, 2.0));
        assert_eq!(g.cell_center(0, 0), (-99.0, 99.0));
    }
}
