//! Export of comments (`GET /api/comments?format=geojson|csv`): an RFC 7946 GeoJSON
//! FeatureCollection of points in WGS 84 longitude/latitude, and CSV with the same columns,
//! both importable in QGIS as they are. The scene CRS coordinates are properties (columns).

use super::Ready;
use super::comments::rfc3339_ms;
use super::error::ApiError;
use crate::echo::echo;
use crate::store::participation::{Comment, Hit};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde_json::{Value, json};

/// What `GET /api/comments` answers with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// `{"comments": […]}`.
    Json,
    /// An RFC 7946 FeatureCollection (`application/geo+json`).
    GeoJson,
    /// Comma-separated values, RFC 4180 (`text/csv`).
    Csv,
}

impl ExportFormat {
    /// The format of a `format` parameter (default JSON); a 422 for other names.
    pub fn parse(name: Option<&str>) -> Result<ExportFormat, ApiError> {
        match name {
            None | Some("json") => Ok(ExportFormat::Json),
            Some("geojson") => Ok(ExportFormat::GeoJson),
            Some("csv") => Ok(ExportFormat::Csv),
            Some(other) => Err(ApiError::invalid(
                "format",
                format!("format: unknown format {:?}; use json, geojson or csv", echo(other)),
            )),
        }
    }
}

/// The names of the properties (GeoJSON) and columns (CSV, after `lon` and `lat`), in the
/// order [`values`] gives them; `reports` only for the admin.
const COLUMNS: [&str; 17] = [
    "id", "number", "text", "category", "likes", "created", "status", "crs", "crs_x", "crs_y", "scene_x", "scene_y",
    "scene_z", "hit", "layer", "plant", "reports",
];

/// The column names for the admin or the public.
fn column_names(admin: bool) -> &'static [&'static str] {
    if admin { &COLUMNS } else { &COLUMNS[..COLUMNS.len() - 1] }
}

/// The values of one comment in the order of [`COLUMNS`].
fn values(comment: &Comment, ready: &Ready, admin: bool) -> Vec<Value> {
    let [x, y, z] = comment.position;
    let (crs_x, crs_y) = ready.scene.terrain.frame.to_crs(x, y);
    let crs = match &ready.geo {
        Ok(geo) => geo.crs().label(),
        Err(_) => ready.scene.terrain.dem.crs.to_string(),
    };
    let (hit, layer, plant) = match &comment.hit {
        Hit::Terrain => ("terrain", Value::Null, Value::Null),
        Hit::Plant { layer, index } => ("plant", json!(layer), json!(index)),
    };
    let mut values = vec![
        json!(comment.id),
        json!(comment.number),
        json!(comment.text),
        json!(comment.category),
        json!(comment.likes),
        json!(rfc3339_ms(comment.created_ms)),
        json!(comment.status.name()),
        json!(crs),
        json!(crs_x),
        json!(crs_y),
        json!(x),
        json!(y),
        json!(z),
        json!(hit),
        layer,
        plant,
    ];
    if admin {
        values.push(json!(comment.reports));
    }
    values
}

/// The comments as GeoJSON or CSV.
pub fn export(format: ExportFormat, comments: &[Comment], ready: &Ready, admin: bool) -> Result<Response, ApiError> {
    match format {
        ExportFormat::Json => Err(ApiError::Internal("JSON is not an export format".into())),
        ExportFormat::GeoJson => {
            let features = comments.iter().map(|c| {
                let mut feature = geojson::Feature::from(geojson::Geometry::new_point(c.lon_lat));
                feature.id = Some(geojson::feature::Id::Number(c.id.into()));
                for (name, value) in column_names(admin).iter().zip(values(c, ready, admin)) {
                    feature.set_property(*name, value);
                }
                feature
            });
            let collection = geojson::FeatureCollection::new(features);
            let body = serde_json::to_vec(&collection).map_err(|e| ApiError::Internal(e.to_string()))?;
            Ok(([(header::CONTENT_TYPE, HeaderValue::from_static("application/geo+json"))], body).into_response())
        }
        ExportFormat::Csv => {
            let mut text = String::new();
            let names = ["lon", "lat"].iter().chain(column_names(admin));
            push_row(&mut text, names.map(|name| (*name).to_owned()));
            for comment in comments {
                let lon_lat = [json!(comment.lon_lat[0]), json!(comment.lon_lat[1])];
                let row = lon_lat.into_iter().chain(values(comment, ready, admin));
                push_row(&mut text, row.map(|value| csv_cell(&value)));
            }
            let headers = [
                (header::CONTENT_TYPE, HeaderValue::from_static("text/csv; charset=utf-8")),
                (header::CONTENT_DISPOSITION, HeaderValue::from_static("attachment; filename=\"comments.csv\"")),
            ];
            Ok((headers, text).into_response())
        }
    }
}

/// Appends one CSV record (CRLF-terminated, RFC 4180).
fn push_row(text: &mut String, cells: impl Iterator<Item = String>) {
    let cells: Vec<String> = cells.map(|c| quote(&c)).collect();
    text.push_str(&cells.join(","));
    text.push_str("\r\n");
}

/// The text of a CSV cell: numbers as JSON writes them, text as it is, null empty. Text a
/// spreadsheet would run as a formula (`=`, `+`, `-`, `@` first) gets a leading `'`.
fn csv_cell(value: &Value) -> String {
    match value {
        Value::Null => String::new(),
        Value::String(s) if s.starts_with(['=', '+', '-', '@']) => format!("'{s}"),
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// A cell quoted when it holds a comma, a quote, a line break or surrounding space.
fn quote(cell: &str) -> String {
    let needs = cell.contains([',', '"', '\n', '\r']) || cell.trim() != cell;
    if needs { format!("\"{}\"", cell.replace('"', "\"\"")) } else { cell.to_owned() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_quoted_and_formulas_defused() {
        assert_eq!(quote("plain"), "plain");
        assert_eq!(quote("a, b"), "\"a, b\"");
        assert_eq!(quote("say \"hi\""), "\"say \"\"hi\"\"\"");
        assert_eq!(quote("two\nlines"), "\"two\nlines\"");
        assert_eq!(csv_cell(&json!("=HYPERLINK(1)")), "'=HYPERLINK(1)");
        assert_eq!(csv_cell(&json!(-105.25)), "-105.25");
        assert_eq!(csv_cell(&Value::Null), "");
        assert!(ExportFormat::parse(Some("kml")).is_err());
    }
}
