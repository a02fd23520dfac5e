//! Vector plans as planners export them: GeoJSON (RFC 7946, plus the common `crs` member of
//! the 2008 draft that QGIS and GDAL write for other CRSs than WGS 84), ESRI Shapefiles (`.shp`
//! with its `.dbf` attributes and `.prj` CRS) and CSV point lists (tree inventories). Features
//! are read with the `geojson` and `shapefile` crates, checked with `geo` (polygon validity)
//! and moved into the scene's local metric frame, where placement and rasterization work.

use std::path::{Path, PathBuf};

use geo::{BoundingRect, Contains, Coord, Geometry, MapCoords, Validation};
use serde_json::{Map, Value};

use super::crs::parse_epsg_code;
use super::frame::LocalFrame;
use super::raster::{GeoTransform, MAX_CELLS, Raster};
use super::reproject::{CrsDefinition, ReprojectError, Transformer};

/// Largest vector file read, in bytes (a plan, not a national data set).
pub const MAX_VECTOR_BYTES: u64 = 64 << 20;

/// Why a vector file cannot be used. Every variant names the file; feature errors also
/// name the feature's index (0-based, in file order).
#[derive(Debug, thiserror::Error)]
pub enum VectorError {
    /// The file could not be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is not GeoJSON (or not the CSV this reader expects).
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// One feature (or CSV row) is unusable.
    #[error("{}: feature {index}: {message}", path.display())]
    Feature {
        /// The file.
        path: PathBuf,
        /// 0-based feature index (CSV: data row index).
        index: usize,
        /// What is wrong with it.
        message: String,
    },
    /// The file's CRS cannot be used.
    #[error("{}: {source}", path.display())]
    Crs {
        /// The file.
        path: PathBuf,
        /// Why.
        source: ReprojectError,
    },
}

/// One feature in scene metres (x east, y north about the scene origin).
#[derive(Debug, Clone)]
pub struct SceneFeature {
    /// 0-based index of the feature in its file (for messages).
    pub index: usize,
    /// The geometry in scene metres.
    pub geometry: Geometry<f64>,
    /// The feature's properties (CSV: the row's columns).
    pub properties: Map<String, Value>,
}

impl SceneFeature {
    /// A property as text (strings as they are, numbers written out); `None` if absent/null.
    pub fn text(&self, key: &str) -> Option<String> {
        match self.properties.get(key)? {
            Value::Null => None,
            Value::String(s) => Some(s.trim().to_string()).filter(|s| !s.is_empty()),
            other => Some(other.to_string()),
        }
    }

    /// A property as a number (numbers or numeric strings); `Err` names a non-numeric value.
    pub fn number(&self, key: &str) -> Result<Option<f64>, String> {
        match self.properties.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::Number(n)) => Ok(n.as_f64()),
            Some(Value::String(s)) if s.trim().is_empty() => Ok(None),
            Some(Value::String(s)) => {
                s.trim().parse().map(Some).map_err(|_| format!("property '{key}' = \"{s}\" is not a number"))
            }
            Some(other) => Err(format!("property '{key}' = {other} is not a number")),
        }
    }
}

/// Where the features go: the scene's CRS definition and local frame.
#[derive(Debug, Clone, Copy)]
pub struct SceneTarget<'a> {
    /// The scene (DEM) CRS.
    pub crs: &'a CrsDefinition,
    /// The scene's local frame (in `crs`).
    pub frame: &'a LocalFrame,
}

/// Reads a vector file by extension: `.geojson`/`.json`, `.shp` or `.csv`. `crs` overrides
/// the file's own CRS (GeoJSON: WGS 84 or its `crs` member; Shapefile: its `.prj`; CSV: WGS 84
/// for lon/lat columns, else the scene's).
pub fn read_vector(
    path: &Path,
    crs: Option<&CrsDefinition>,
    target: SceneTarget<'_>,
) -> Result<Vec<SceneFeature>, VectorError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() == Some("shp") {
        return read_shapefile(path, crs, target);
    }
    let text = read_text(path)?;
    match ext.as_deref() {
        Some("csv") => read_csv(path, &text, crs, target),
        _ => read_geojson(path, &text, crs, target),
    }
}

/// Refuses a file larger than [`MAX_VECTOR_BYTES`] (or one that cannot be read).
fn check_size(path: &Path) -> Result<(), VectorError> {
    let len = std::fs::metadata(path).map_err(|source| VectorError::Io { path: path.to_path_buf(), source })?.len();
    if len > MAX_VECTOR_BYTES {
        return Err(VectorError::Format {
            path: path.to_path_buf(),
            message: format!("file of {len} bytes is larger than the limit of {MAX_VECTOR_BYTES} bytes"),
        });
    }
    Ok(())
}

fn read_text(path: &Path) -> Result<String, VectorError> {
    check_size(path)?;
    let bytes = std::fs::read(path).map_err(|source| VectorError::Io { path: path.to_path_buf(), source })?;
    String::from_utf8(bytes)
        .map_err(|_| VectorError::Format { path: path.to_path_buf(), message: "not UTF-8 text".into() })
}

/// Parses GeoJSON text (a FeatureCollection, a Feature or a bare Geometry) and moves its
/// features into the scene. Polygons must be valid (no self-intersections); coordinates of a
/// file in WGS 84 must be longitude/latitude in range.
pub fn read_geojson(
    path: &Path,
    text: &str,
    crs: Option<&CrsDefinition>,
    target: SceneTarget<'_>,
) -> Result<Vec<SceneFeature>, VectorError> {
    let format = |message: String| VectorError::Format { path: path.to_path_buf(), message };
    let json: Value = serde_json::from_str(text).map_err(|e| format(format!("not GeoJSON: {e}")))?;
    let file_crs = match crs {
        Some(c) => c.clone(),
        None => crs_member(&json).map_err(|source| VectorError::Crs { path: path.to_path_buf(), source })?,
    };
    let geojson: geojson::GeoJson = serde_json::from_str(text).map_err(|e| format(format!("not GeoJSON: {e}")))?;
    let features: Vec<(Option<geojson::Geometry>, Map<String, Value>)> = match geojson {
        geojson::GeoJson::FeatureCollection(fc) => {
            fc.features.into_iter().map(|f| (f.geometry, f.properties.unwrap_or_default())).collect()
        }
        geojson::GeoJson::Feature(f) => vec![(f.geometry, f.properties.unwrap_or_default())],
        geojson::GeoJson::Geometry(g) => vec![(Some(g), Map::new())],
    };
    let features = features.into_iter().map(|(geometry, properties)| {
        let geometry = geometry.map(|g| {
            if !positions_have_xy(&g.value) {
                return Err("bad geometry: a position needs at least two coordinates (x and y)".to_owned());
            }
            Geometry::try_from(&g.value).map_err(|e| format!("bad geometry: {e}"))
        });
        Ok((geometry.transpose()?, properties))
    });
    features_to_scene(path, &file_crs, target, features)
}

/// Whether every position of `value` has at least two coordinates: the `geojson` crate's
/// conversion to `geo` reads x and y without checking (a `[5]` position would panic).
fn positions_have_xy(value: &geojson::GeometryValue) -> bool {
    use geojson::GeometryValue as V;
    let xy = |p: &geojson::Position| p.len() >= 2;
    match value {
        V::Point { coordinates } => xy(coordinates),
        V::MultiPoint { coordinates } | V::LineString { coordinates } => coordinates.iter().all(xy),
        V::MultiLineString { coordinates } | V::Polygon { coordinates } => coordinates.iter().flatten().all(xy),
        V::MultiPolygon { coordinates } => coordinates.iter().flatten().flatten().all(xy),
        V::GeometryCollection { geometries } => geometries.iter().all(|g| positions_have_xy(&g.value)),
    }
}

/// Checks features read from `path` in `file_crs` (in file order; `Ok((None, _))` for one
/// without a geometry, `Err` for one whose geometry could not be read) and moves them into
/// the scene. Polygons must be valid; at least one feature must have a geometry.
fn features_to_scene(
    path: &Path,
    file_crs: &CrsDefinition,
    target: SceneTarget<'_>,
    features: impl Iterator<Item = Result<(Option<Geometry<f64>>, Map<String, Value>), String>>,
) -> Result<Vec<SceneFeature>, VectorError> {
    let to_scene = Transformer::new(file_crs, target.crs)
        .map_err(|source| VectorError::Crs { path: path.to_path_buf(), source })?;
    let mut out = Vec::new();
    for (index, feature) in features.enumerate() {
        let feature_err = |message: String| VectorError::Feature { path: path.to_path_buf(), index, message };
        let (geometry, properties) = feature.map_err(feature_err)?;
        let Some(geometry) = geometry else { continue };
        if let Err(e) = geometry.check_validation() {
            return Err(feature_err(format!("invalid {}: {e}", kind_name(&geometry))));
        }
        let geometry = move_to_scene(&geometry, file_crs, &to_scene, target.frame).map_err(feature_err)?;
        out.push(SceneFeature { index, geometry, properties });
    }
    if out.is_empty() {
        return Err(VectorError::Format {
            path: path.to_path_buf(),
            message: "has no features with a geometry".into(),
        });
    }
    Ok(out)
}

/// Reads an ESRI Shapefile: the shapes of `path` (`.shp`), their attributes from the `.dbf`
/// beside it (text as the file stores it, numbers, logicals and dates as ISO text) and the CRS
/// from the `.prj` beside it (WKT naming an EPSG CRS by authority or name) unless `crs` is
/// given. Points, multi-points, polylines and polygons (rings by their orientation, holes in
/// their shells) are read; Z and M values are dropped.
pub fn read_shapefile(
    path: &Path,
    crs: Option<&CrsDefinition>,
    target: SceneTarget<'_>,
) -> Result<Vec<SceneFeature>, VectorError> {
    let format = |message: String| VectorError::Format { path: path.to_path_buf(), message };
    let dbf = path.with_extension("dbf");
    for part in [path, dbf.as_path()] {
        check_size(part)?;
    }
    let file_crs = match crs {
        Some(c) => c.clone(),
        None => {
            let prj = path.with_extension("prj");
            let wkt = std::fs::read_to_string(&prj).map_err(|_| {
                format(format!(
                    "has no readable {} beside it: give the file's CRS (`crs = \"EPSG:…\"`)",
                    prj.file_name().map_or("projection file".into(), |n| n.to_string_lossy())
                ))
            })?;
            CrsDefinition::from_wkt(&wkt).map_err(|source| VectorError::Crs { path: prj.clone(), source })?
        }
    };
    let mut reader =
        shapefile::Reader::from_path(path).map_err(|e| format(format!("not a readable Shapefile: {e}")))?;
    let features = reader.iter_shapes_and_records().map(|feature| {
        let (shape, record) = feature.map_err(|e| format!("cannot be read: {e}"))?;
        let geometry = match shape {
            shapefile::Shape::NullShape => None,
            shape => Some(Geometry::try_from(shape).map_err(|e| format!("bad geometry: {e}"))?),
        };
        let properties = record.into_iter().map(|(name, value)| (name, dbf_value(value))).collect();
        Ok((geometry, properties))
    });
    features_to_scene(path, &file_crs, target, features)
}

/// A dBase attribute as a JSON value (numbers as numbers, everything else as text; empty
/// fields as null), so Shapefile features read like GeoJSON ones.
fn dbf_value(value: shapefile::dbase::FieldValue) -> Value {
    use shapefile::dbase::FieldValue as F;
    let number = |n: f64| serde_json::Number::from_f64(n).map_or(Value::Null, Value::Number);
    match value {
        F::Character(Some(s)) | F::Memo(s) => Value::String(s.trim().to_string()),
        F::Numeric(Some(n)) | F::Double(n) | F::Currency(n) => number(n),
        F::Float(Some(n)) => number(f64::from(n)),
        F::Integer(n) => Value::from(n),
        F::Logical(Some(b)) => Value::Bool(b),
        F::Date(Some(d)) => Value::String(format!("{:04}-{:02}-{:02}", d.year(), d.month(), d.day())),
        F::DateTime(t) => {
            let (d, t) = (t.date(), t.time());
            Value::String(format!(
                "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}",
                d.year(),
                d.month(),
                d.day(),
                t.hours(),
                t.minutes(),
                t.seconds()
            ))
        }
        F::Character(None) | F::Numeric(None) | F::Float(None) | F::Logical(None) | F::Date(None) => Value::Null,
    }
}

/// The CRS of GeoJSON text (see [`crs_member`]).
pub fn geojson_crs(path: &Path, text: &str) -> Result<CrsDefinition, VectorError> {
    let json: Value = serde_json::from_str(text)
        .map_err(|e| VectorError::Format { path: path.to_path_buf(), message: format!("not GeoJSON: {e}") })?;
    crs_member(&json).map_err(|source| VectorError::Crs { path: path.to_path_buf(), source })
}

/// The bounding box of features (scene metres); `None` for none.
pub fn bounds(features: &[SceneFeature]) -> Option<([f64; 2], [f64; 2])> {
    features.iter().filter_map(|f| f.geometry.bounding_rect()).fold(None, |acc, r| {
        let (lo, hi) = acc.unwrap_or(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]));
        Some(([lo[0].min(r.min().x), lo[1].min(r.min().y)], [hi[0].max(r.max().x), hi[1].max(r.max().y)]))
    })
}

/// The CRS of a GeoJSON object: its `crs` member (`{"type": "name", "properties": {"name":
/// "urn:ogc:def:crs:EPSG::27700"}}` or the older `{"type": "EPSG", "properties": {"code":
/// 27700}}`), WGS 84 without one (RFC 7946).
fn crs_member(json: &Value) -> Result<CrsDefinition, ReprojectError> {
    let Some(member) = json.get("crs").filter(|c| !c.is_null()) else {
        return Ok(CrsDefinition::wgs84());
    };
    let props = member.get("properties");
    let bad = |reason: &str| ReprojectError::Unsupported { crs: member.to_string(), reason: reason.to_string() };
    let code = match member.get("type").and_then(Value::as_str) {
        Some("name") => {
            let name = props.and_then(|p| p.get("name")).and_then(Value::as_str).ok_or_else(|| bad("no name"))?;
            parse_epsg_code(name).map_err(bad)?
        }
        Some("EPSG") => props
            .and_then(|p| p.get("code"))
            .and_then(Value::as_u64)
            .and_then(|c| u32::try_from(c).ok())
            .ok_or_else(|| bad("no numeric code"))?,
        _ => return Err(bad("the crs member must be of type \"name\" (an EPSG URN) or \"EPSG\"")),
    };
    CrsDefinition::from_epsg(code)
}

fn kind_name(g: &Geometry<f64>) -> &'static str {
    match g {
        Geometry::Point(_) => "point",
        Geometry::MultiPoint(_) => "multi-point",
        Geometry::LineString(_) | Geometry::Line(_) => "line",
        Geometry::MultiLineString(_) => "multi-line",
        Geometry::Polygon(_) | Geometry::Rect(_) | Geometry::Triangle(_) => "polygon",
        Geometry::MultiPolygon(_) => "multi-polygon",
        Geometry::GeometryCollection(_) => "geometry collection",
    }
}

/// A geometry in `file_crs` → scene metres. Lon/lat of a geographic file must be in range
/// (catches projected coordinates in a file without `crs` member).
fn move_to_scene(
    g: &Geometry<f64>,
    file_crs: &CrsDefinition,
    to_scene: &Transformer,
    frame: &LocalFrame,
) -> Result<Geometry<f64>, String> {
    let geographic = file_crs.is_geographic();
    g.try_map_coords(|c: Coord<f64>| {
        if geographic && !(c.x.abs() <= 180.0 && c.y.abs() <= 90.0) {
            return Err(format!(
                "coordinate ({}, {}) is not longitude/latitude in {}; give the file's CRS (`crs = \"EPSG:…\"`)",
                c.x, c.y, file_crs
            ));
        }
        let (x, y) = to_scene
            .transform(c.x, c.y)
            .ok_or_else(|| format!("coordinate ({}, {}) cannot be transformed to {}", c.x, c.y, frame.crs()))?;
        let (lx, ly) = frame.to_local(x, y);
        Ok(Coord { x: lx, y: ly })
    })
}

/// Whether a geometry's bounding box overlaps the rectangle `lo`..`hi` (scene metres).
pub fn overlaps(g: &Geometry<f64>, lo: [f64; 2], hi: [f64; 2]) -> bool {
    g.bounding_rect()
        .is_some_and(|r| r.min().x <= hi[0] && r.max().x >= lo[0] && r.min().y <= hi[1] && r.max().y >= lo[1])
}

/// Reads a CSV point list (header row; columns `x`,`y` (or `easting`,`northing`) or `lon`,`lat`
/// (or `longitude`,`latitude`) and any others as properties). Lon/lat columns are WGS 84,
/// x/y are in `crs` or else the scene CRS. Quoted fields (`"a, b"`, `""` for a quote) are read
/// as RFC 4180 writes them.
pub fn read_csv(
    path: &Path,
    text: &str,
    crs: Option<&CrsDefinition>,
    target: SceneTarget<'_>,
) -> Result<Vec<SceneFeature>, VectorError> {
    let format = |message: String| VectorError::Format { path: path.to_path_buf(), message };
    let mut lines = text.trim_start_matches('\u{feff}').lines().filter(|l| !l.trim().is_empty());
    let header: Vec<String> = split_csv_line(lines.next().ok_or_else(|| format("empty CSV file".into()))?)
        .into_iter()
        .map(|h| h.trim().to_string())
        .collect();
    let column = |names: &[&str]| header.iter().position(|h| names.iter().any(|n| h.eq_ignore_ascii_case(n)));
    let (xi, yi, lonlat) = match (column(&["x", "easting"]), column(&["y", "northing"])) {
        (Some(x), Some(y)) => (x, y, false),
        _ => match (column(&["lon", "longitude", "lng"]), column(&["lat", "latitude"])) {
            (Some(x), Some(y)) => (x, y, true),
            _ => {
                return Err(format(format!(
                    "CSV header {header:?} has no x,y (easting,northing) or lon,lat (longitude,latitude) columns"
                )));
            }
        },
    };
    let file_crs = match (crs, lonlat) {
        (Some(c), _) => c.clone(),
        (None, true) => CrsDefinition::wgs84(),
        (None, false) => target.crs.clone(),
    };
    let to_scene = Transformer::new(&file_crs, target.crs)
        .map_err(|source| VectorError::Crs { path: path.to_path_buf(), source })?;
    let mut out = Vec::new();
    for (index, line) in lines.enumerate() {
        let feature_err = |message: String| VectorError::Feature { path: path.to_path_buf(), index, message };
        let fields = split_csv_line(line);
        let coord = |i: usize, name: &str| -> Result<f64, VectorError> {
            let v = fields.get(i).map(|s| s.trim()).unwrap_or("");
            v.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| feature_err(format!("{name} \"{v}\" is not a number")))
        };
        let point = Geometry::Point(geo::Point::new(coord(xi, &header[xi])?, coord(yi, &header[yi])?));
        let geometry = move_to_scene(&point, &file_crs, &to_scene, target.frame).map_err(feature_err)?;
        let properties =
            header.iter().zip(fields.iter()).map(|(h, v)| (h.clone(), Value::String(v.trim().to_string()))).collect();
        out.push(SceneFeature { index, geometry, properties });
    }
    if out.is_empty() {
        return Err(format("CSV file has no data rows".into()));
    }
    Ok(out)
}

/// Splits one CSV line into fields (RFC 4180 quoting).
fn split_csv_line(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        let field = fields.last_mut().expect("fields is never empty");
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                field.push('"');
                chars.next();
            }
            ('"', true) => quoted = false,
            ('"', false) if field.trim().is_empty() => {
                field.clear();
                quoted = true;
            }
            (',', false) => fields.push(String::new()),
            (c, _) => field.push(c),
        }
    }
    fields
}

/// Rasterizes polygon features into a label raster in the scene CRS: each cell whose centre
/// lies in a polygon gets the polygon's `property` (an integer label; the first feature in
/// file order wins where polygons overlap), others are nodata (`nodata`). The raster covers
/// the scene rectangle `lo`..`hi` (scene metres) with cells of `cell` metres.
pub fn rasterize_labels(
    features: &[SceneFeature],
    property: &str,
    cell: f64,
    lo: [f64; 2],
    hi: [f64; 2],
    frame: &LocalFrame,
    path: &Path,
) -> Result<Raster, VectorError> {
    let format = |message: String| VectorError::Format { path: path.to_path_buf(), message };
    if !(cell.is_finite() && cell > 0.0) {
        return Err(format(format!("cell size {cell} m must be positive")));
    }
    // Both sizes are positive and finite, so the casts are in range once checked below.
    let (w, h) = (((hi[0] - lo[0]) / cell).ceil().max(1.0), ((hi[1] - lo[1]) / cell).ceil().max(1.0));
    if w * h > MAX_CELLS as f64 {
        return Err(format(format!("{w} × {h} cells of {cell} m exceed the limit of {MAX_CELLS} cells")));
    }
    let (width, height) = (w as usize, h as usize);
    const NODATA: f64 = -1.0;
    let mut data = vec![NODATA; width * height];
    for f in features {
        let feature_err = |message: String| VectorError::Feature { path: path.to_path_buf(), index: f.index, message };
        if !matches!(f.geometry, Geometry::Polygon(_) | Geometry::MultiPolygon(_)) {
            return Err(feature_err(format!("is a {}, not a polygon", kind_name(&f.geometry))));
        }
        let label = f
            .number(property)
            .map_err(feature_err)?
            .filter(|v| v.fract() == 0.0 && *v >= 0.0)
            .ok_or_else(|| feature_err(format!("property '{property}' is not a label (an integer ≥ 0)")))?;
        let Some(rect) = f.geometry.bounding_rect() else { continue };
        // Cell ranges covering the feature's box, clamped to the raster.
        let col = |x: f64| ((x - lo[0]) / cell).floor().clamp(0.0, w - 1.0) as usize;
        let row = |y: f64| ((hi[1] - y) / cell).floor().clamp(0.0, h - 1.0) as usize;
        for r in row(rect.max().y)..=row(rect.min().y) {
            for c in col(rect.min().x)..=col(rect.max().x) {
                let i = r * width + c;
                if data[i] != NODATA {
                    continue;
                }
                let p = geo::Point::new(lo[0] + (c as f64 + 0.5) * cell, hi[1] - (r as f64 + 0.5) * cell);
                if f.geometry.contains(&p) {
                    data[i] = label;
                }
            }
        }
    }
    // The grid is square in scene metres; in the scene CRS it has the frame's scale.
    let (sx, sy) = frame.scale();
    let (origin_x, origin_y) = frame.to_crs(lo[0], hi[1]);
    let raster = Raster {
        width,
        height,
        data,
        nodata: Some(NODATA),
        transform: GeoTransform { origin_x, origin_y, cell_width: cell / sx, cell_height: cell / sy },
        crs: *frame.crs(),
        palette: None,
    };
    if raster.valid_count() == 0 {
        return Err(format("no polygon covers the centre of any cell inside the terrain".into()));
    }
    Ok(raster)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quoting() {
        assert_eq!(split_csv_line(r#"1,"a, b",c"#), vec!["1", "a, b", "c"]);
        assert_eq!(split_csv_line(r#""say ""hi""",2"#), vec![r#"say "hi""#, "2"]);
        assert_eq!(split_csv_line(""), vec![""]);
    }

    #[test]
    fn positions_need_x_and_y() {
        use geojson::GeometryValue as V;
        let at = |c: &[f64]| geojson::Position::from(c.to_vec());
        let line = |cs: &[&[f64]]| cs.iter().map(|c| at(c)).collect::<Vec<_>>();
        assert!(positions_have_xy(&V::LineString { coordinates: line(&[&[5.0, 6.0], &[7.0, 8.0, 9.0]]) }));
        let point = geojson::Geometry::new(V::Point { coordinates: at(&[1.0]) });
        for short in [
            V::Point { coordinates: at(&[5.0]) },
            V::LineString { coordinates: line(&[&[5.0]]) },
            V::MultiPolygon { coordinates: vec![vec![line(&[&[0.0, 0.0], &[1.0, 0.0], &[1.0], &[0.0, 0.0]])]] },
            V::GeometryCollection { geometries: vec![point] },
        ] {
            assert!(!positions_have_xy(&short), "{short:?}");
        }
    }

    #[test]
    fn crs_member_variants() {
        let named: Value =
            serde_json::json!({"crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::27700"}}});
        assert_eq!(crs_member(&named).unwrap().crs().epsg(), Some(27700));
        let old: Value = serde_json::json!({"crs": {"type": "EPSG", "properties": {"code": 2056}}});
        assert_eq!(crs_member(&old).unwrap().crs().epsg(), Some(2056));
        let crs84: Value =
            serde_json::json!({"crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}}});
        assert_eq!(crs_member(&crs84).unwrap(), CrsDefinition::wgs84());
        assert_eq!(crs_member(&serde_json::json!({})).unwrap(), CrsDefinition::wgs84());
        let link: Value = serde_json::json!({"crs": {"type": "link", "properties": {"href": "x"}}});
        assert!(crs_member(&link).is_err());
        let unknown: Value = serde_json::json!({"crs": {"type": "name", "properties": {"name": "EPSG:1"}}});
        assert!(crs_member(&unknown).is_err());
    }
}
