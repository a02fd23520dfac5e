//! The data-layer API (SPEC A2): upload, list, describe and delete layers of the persistent
//! [`Store`](crate::store::Store), and draw their legends. Uploads and deletions go through the
//! [`Admin`] guard; store I/O runs on the blocking thread pool.

use super::AppState;
use super::auth::Admin;
use super::connections::body_error;
use super::error::{ApiError, ErrorBody};
use super::events::{Change, LiveEvent};
use crate::echo::echo;
use crate::fields::{ColorMapName, ColorMapSpec, HATCH_COLORS, Legend, MappingTarget};
use crate::store::{LayerMeta, StoreError, UploadRequest};
use axum::Json;
use axum::body::Bytes;
use axum::extract::{FromRequest, Multipart, Path, RawQuery, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

/// `GET /api/layers`: every stored layer.
#[derive(Debug, Serialize, ToSchema)]
pub struct LayerList {
    /// The layers, sorted by name.
    pub layers: Vec<LayerMeta>,
}

/// Query parameters of the legend endpoints: how the layer is coloured, or (`target=hatch_color`)
/// which ink its hatching has.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct LegendQuery {
    /// Colour map (`viridis`, `magma`, `rdylbu`, `tableau10`, …); default: viridis for
    /// scalars, tableau10 for labels.
    pub colormap: Option<ColorMapName>,
    /// Values at the two ends of the gradient, `min,max`; default: the layer's range.
    pub range: Option<String>,
    /// Opacity 0…1 (default 1).
    pub opacity: Option<f32>,
    /// Run the colour map backwards.
    pub reverse: Option<bool>,
    /// The mapping's target: `hatch_color` draws the ramp from paper to the ink `color`; any
    /// other target (default `color`) the colour map.
    pub target: Option<MappingTarget>,
    /// Ink of a `hatch_color` legend as sRGB `r,g,b`, each 0…1; default the first slot's
    /// (vermillion).
    pub color: Option<String>,
    /// Ignored: a version the browser adds (the layer's steps and range) so that a layer with a
    /// new time step gets a new legend URL instead of the image cached for the old one.
    pub v: Option<String>,
}

impl LegendQuery {
    /// Parses and checks a query string; errors name the parameter.
    pub fn from_query(query: &str) -> Result<LegendQuery, ApiError> {
        let parser = serde_urlencoded::Deserializer::new(form_urlencoded::parse(query.as_bytes()));
        serde_path_to_error::deserialize(parser).map_err(query_error)
    }

    /// The colour-map specification, checked: opacity within 0…1, two distinct finite range ends,
    /// an ink of three components within 0…1 and only for `hatch_color`.
    pub fn spec(&self) -> Result<ColorMapSpec, ApiError> {
        let range = match &self.range {
            Some(text) => {
                let ends: Vec<f64> = text
                    .split(',')
                    .map(|v| v.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| ApiError::invalid("range", format!("range {:?} must read min,max", echo(text))))?;
                match ends[..] {
                    [lo, hi] if lo.is_finite() && hi.is_finite() && lo != hi => Some([lo, hi]),
                    _ => {
                        return Err(ApiError::invalid(
                            "range",
                            format!("range {:?} needs two different finite values: min,max", echo(text)),
                        ));
                    }
                }
            }
            None => None,
        };
        let opacity = self.opacity.unwrap_or(1.0);
        if !(0.0..=1.0).contains(&opacity) {
            return Err(ApiError::invalid("opacity", format!("opacity {opacity} must be within 0…1")));
        }
        let ink = match (self.target, &self.color) {
            (Some(MappingTarget::HatchColor), None) => Some(HATCH_COLORS[0]),
            (Some(MappingTarget::HatchColor), Some(text)) => {
                let rgb = match text.split(',').map(|v| v.trim().parse::<f32>()).collect::<Result<Vec<_>, _>>() {
                    Ok(c) if c.len() == 3 && c.iter().all(|v| (0.0..=1.0).contains(v)) => [c[0], c[1], c[2]],
                    _ => {
                        return Err(ApiError::invalid(
                            "color",
                            format!("color {:?} must read r,g,b with sRGB components within 0…1", echo(text)),
                        ));
                    }
                };
                Some(rgb)
            }
            (_, Some(_)) => {
                return Err(ApiError::invalid("color", "color is the ink of target=hatch_color legends only"));
            }
            (_, None) => None,
        };
        Ok(ColorMapSpec { map: self.colormap, range, opacity, reverse: self.reverse.unwrap_or(false), ink })
    }
}

/// A query-string error: an unknown or repeated parameter is a 400, a bad value a 422; both
/// name the parameter when known.
fn query_error(e: serde_path_to_error::Error<serde_urlencoded::de::Error>) -> ApiError {
    let path = e.path().to_string();
    let parameter = (path != ".").then_some(path);
    let inner = e.inner().to_string();
    let message = format!("malformed query: {inner}");
    if parameter.is_none() || inner.starts_with("unknown field") || inner.starts_with("duplicate field") {
        ApiError::BadRequest { parameter, message }
    } else {
        ApiError::Invalid { parameter, message }
    }
}

/// Maps a store error to the API error with the same status.
pub fn store_error(error: StoreError) -> ApiError {
    if let StoreError::InvalidField { field, .. } = &error {
        return ApiError::invalid(*field, error.to_string());
    }
    let message = error.to_string();
    match error.status() {
        404 => ApiError::NotFound(message),
        409 => ApiError::Conflict(message),
        413 => ApiError::TooLarge { parameter: None, message },
        422 => ApiError::Invalid { parameter: None, message },
        _ => ApiError::Storage(message),
    }
}

/// Runs blocking store work off the async threads.
async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> Result<T, StoreError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(work).await.map_err(|e| ApiError::Storage(e.to_string()))?.map_err(store_error)
}

/// Reads the file and the upload parameters of a request: the raw body with parameters in the
/// query string, or `multipart/form-data` with one file part and parameters as text parts (or
/// in the query string).
async fn read_upload(state: &AppState, query: &str, request: Request) -> Result<(Bytes, UploadRequest), ApiError> {
    let mut pairs: Vec<(String, String)> = form_urlencoded::parse(query.as_bytes()).into_owned().collect();
    let multipart = request
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.trim_start().to_ascii_lowercase().starts_with("multipart/form-data"));
    let too_large = || ApiError::too_large("body", "the upload is larger than this server allows");
    let (bytes, part_filename) = if multipart {
        let mut form =
            Multipart::from_request(request, state).await.map_err(|e| ApiError::bad("body", e.body_text()))?;
        let mut file = None;
        let multipart_error = |e: axum::extract::multipart::MultipartError| match e.status() {
            StatusCode::PAYLOAD_TOO_LARGE => too_large(),
            _ => body_error(&e, || ApiError::bad("body", e.body_text())),
        };
        while let Some(field) = form.next_field().await.map_err(multipart_error)? {
            let name = field.name().unwrap_or_default().to_string();
            let filename = field.file_name().map(str::to_string);
            if name == "file" || filename.is_some() {
                if file.is_some() {
                    return Err(ApiError::bad("file", "the form has more than one file"));
                }
                file = Some((field.bytes().await.map_err(multipart_error)?, filename));
            } else {
                let value = field.text().await.map_err(multipart_error)?;
                pairs.push((name, value));
            }
        }
        file.ok_or_else(|| ApiError::invalid("file", "the form has no file part (name it \"file\")"))?
    } else {
        let bytes = Bytes::from_request(request, state).await.map_err(|e| match e.status() {
            StatusCode::PAYLOAD_TOO_LARGE => too_large(),
            _ => body_error(&e, || ApiError::bad("body", e.body_text())),
        })?;
        (bytes, None)
    };
    if !pairs.iter().any(|(k, _)| k == "name") {
        return Err(ApiError::invalid("name", "name is required"));
    }
    let encoded = form_urlencoded::Serializer::new(String::new()).extend_pairs(&pairs).finish();
    let mut req = serde_path_to_error::deserialize::<_, UploadRequest>(serde_urlencoded::Deserializer::new(
        form_urlencoded::parse(encoded.as_bytes()),
    ))
    .map_err(query_error)?;
    if req.filename.is_none() {
        req.filename = part_filename;
    }
    Ok((bytes, req))
}

/// Uploads a layer (admin): a GeoTIFF, ESRI ASCII grid or NetCDF-3 file as the raw body with
/// the parameters in the query string, or as the `file` part of a multipart form. An upload
/// with the name of a stored time series adds its time steps to it.
#[utoipa::path(post, path = "/api/layers", tag = "layers", params(UploadRequest),
    security(("bearer" = []), ()),
    request_body(description = "The raster file (raw), or a multipart form with a `file` part and the parameters as text parts",
        content(("application/octet-stream"), ("multipart/form-data"))),
    responses(
        (status = 201, description = "Layer created; `Location` names it", body = LayerMeta),
        (status = 200, description = "Time steps added to the layer of that name", body = LayerMeta),
        (status = 400, description = "Malformed request or unknown parameter", body = ErrorBody),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused: without an admin token, a client not on loopback, a foreign Host or a foreign Origin; with one, a foreign Origin", body = ErrorBody),
        (status = 409, description = "The name belongs to a layer that cannot take these steps", body = ErrorBody),
        (status = 413, description = "Upload, raster or series larger than the server allows", body = ErrorBody),
        (status = 422, description = "Not a valid field: format, kind, CRS, time, classes, or no overlap with the scene (both extents named)", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn upload(
    _admin: Admin,
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    request: Request,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let geo = ready.geo.clone().map_err(|e| ApiError::Invalid {
        parameter: None,
        message: format!("data layers cannot be placed in this scene: {e}"),
    })?;
    let (bytes, req) = read_upload(&state, query.as_deref().unwrap_or_default(), request).await?;
    let store = state.store().clone();
    let permit = state.decode_permit().await?;
    let (meta, before) = blocking(move || {
        let _permit = permit;
        let existing = store.find_by_name(&req.name);
        let meta = store.add_upload(&bytes, &req, &geo)?;
        let before = existing.filter(|e| e.id == meta.id);
        Ok((meta, before))
    })
    .await?;
    if let Some(replication) = state.replication() {
        replication.push_layer(state.store(), &meta.id, before.as_ref()).await?;
    }
    let appended = before.is_some();
    tracing::info!(layer = %meta.id, steps = meta.steps.len(), appended, "layer uploaded");
    let change = if appended { Change::Changed } else { Change::Added };
    state.publish(LiveEvent::Layer { change, id: meta.id.clone() });
    let status = if appended { StatusCode::OK } else { StatusCode::CREATED };
    let mut response = (status, Json(&meta)).into_response();
    if let Ok(location) = HeaderValue::from_str(&format!("/api/layers/{}", meta.id)) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    Ok(response)
}

/// Every stored layer with its metadata, sorted by name.
#[utoipa::path(get, path = "/api/layers", tag = "layers",
    responses((status = 200, description = "The layers", body = LayerList)))]
pub async fn list(State(state): State<AppState>) -> Json<LayerList> {
    Json(LayerList { layers: state.store().list() })
}

/// One layer's metadata: kind, CRS, extent, value range, classes, time steps, units.
#[utoipa::path(get, path = "/api/layers/{id}", tag = "layers",
    params(("id" = String, Path, description = "Layer id")),
    responses(
        (status = 200, description = "The layer", body = LayerMeta),
        (status = 404, description = "Unknown layer", body = ErrorBody)))]
pub async fn get(State(state): State<AppState>, Path(id): Path<String>) -> Result<Json<LayerMeta>, ApiError> {
    state.store().get(&id).map(Json).map_err(store_error)
}

/// Deletes a layer (admin).
#[utoipa::path(delete, path = "/api/layers/{id}", tag = "layers",
    params(("id" = String, Path, description = "Layer id")),
    security(("bearer" = []), ()),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused: without an admin token, a client not on loopback, a foreign Host or a foreign Origin; with one, a foreign Origin", body = ErrorBody),
        (status = 404, description = "Unknown layer", body = ErrorBody)))]
pub async fn delete(
    _admin: Admin,
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    let store = state.store().clone();
    let meta = blocking(move || store.delete(&id)).await?;
    if let Some(replication) = state.replication() {
        replication.push_layer(state.store(), &meta.id, Some(&meta)).await?;
    }
    tracing::info!(layer = %meta.id, "layer deleted");
    state.publish(LiveEvent::Layer { change: Change::Removed, id: meta.id });
    Ok(StatusCode::NO_CONTENT)
}

/// The legend of a layer under the colour map of the query.
fn legend_of(state: &AppState, id: &str, query: Option<&str>) -> Result<Legend, ApiError> {
    let spec = LegendQuery::from_query(query.unwrap_or_default())?.spec()?;
    state.store().legend(id, &spec).map_err(store_error)
}

/// The legend as a PNG: a colour bar with ticks for scalars, class swatches for labels.
#[utoipa::path(get, path = "/api/layers/{id}/legend.png", tag = "layers",
    params(("id" = String, Path, description = "Layer id"), LegendQuery),
    responses(
        (status = 200, description = "The legend image", content_type = "image/png"),
        (status = 400, description = "Unknown query parameter", body = ErrorBody),
        (status = 404, description = "Unknown layer", body = ErrorBody),
        (status = 422, description = "Bad colour map, range or opacity", body = ErrorBody)))]
pub async fn legend_png(
    State(state): State<AppState>,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let legend = legend_of(&state, &id, query.as_deref())?;
    let png = tokio::task::spawn_blocking(move || legend.to_png())
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))?
        .map_err(|e| ApiError::Internal(e.to_string()))?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

/// The legend described as JSON: colour map, range, ticks and colour stops, or classes with
/// their colours, and units.
#[utoipa::path(get, path = "/api/layers/{id}/legend.json", tag = "layers",
    params(("id" = String, Path, description = "Layer id"), LegendQuery),
    responses(
        (status = 200, description = "The legend", body = Legend),
        (status = 400, description = "Unknown query parameter", body = ErrorBody),
        (status = 404, description = "Unknown layer", body = ErrorBody),
        (status = 422, description = "Bad colour map, range or opacity", body = ErrorBody)))]
pub async fn legend_json(
    State(state): State<AppState>,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Json<Legend>, ApiError> {
    legend_of(&state, &id, query.as_deref()).map(Json)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_queries_name_the_bad_parameter() {
        let spec = LegendQuery::from_query("colormap=magma&range=0,10&opacity=0.5&reverse=true")
            .and_then(|q| q.spec())
            .expect("valid query");
        assert_eq!(
            spec,
            ColorMapSpec {
                map: Some(ColorMapName::Magma),
                range: Some([0.0, 10.0]),
                opacity: 0.5,
                reverse: true,
                ink: None
            }
        );
        let hatch = |query| LegendQuery::from_query(query).and_then(|q| q.spec()).expect(query).ink;
        assert_eq!(hatch("target=hatch_color&color=0,0.5,1"), Some([0.0, 0.5, 1.0]));
        assert_eq!(hatch("target=hatch_color"), Some(HATCH_COLORS[0]));
        assert_eq!(hatch("target=hatch_tone"), None);
        for (query, parameter) in [
            ("target=hatch_color&color=1,0", Some("color")),
            ("target=hatch_color&color=0,2,0", Some("color")),
            ("color=1,0,0", Some("color")),
            ("target=sparkles", Some("target")),
            ("colormap=plaid", Some("colormap")),
            ("range=1", Some("range")),
            ("range=2,2", Some("range")),
            ("opacity=2", Some("opacity")),
            ("colour=red", Some("colour")),
        ] {
            let error = LegendQuery::from_query(query).and_then(|q| q.spec()).expect_err(query);
            assert_eq!(error.detail().parameter.as_deref(), parameter, "{query}: {error}");
        }
    }

    #[test]
    fn store_errors_keep_their_status() {
        let missing = store_error(StoreError::NotFound { id: "x".into() });
        assert_eq!((missing.status(), missing.to_string().as_str()), (StatusCode::NOT_FOUND, "unknown layer \"x\""));
        assert_eq!(store_error(StoreError::Conflict("taken".into())).status(), StatusCode::CONFLICT);
        let big = StoreError::TooLarge { what: "upload".into(), size: 2, limit: 1 };
        assert_eq!(store_error(big).status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(store_error(StoreError::Invalid("bad".into())).status(), StatusCode::UNPROCESSABLE_ENTITY);
        let io = StoreError::Io { path: "/secret/dir".into(), source: std::io::Error::other("disk full") };
        let io = store_error(io);
        assert_eq!(io.status(), StatusCode::INTERNAL_SERVER_ERROR);
        assert!(!io.to_string().contains("/secret"), "paths stay in the log: {io}");
    }
}
