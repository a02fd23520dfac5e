//! REST handlers: health, scene description, rendered views, the cache-clearing admin
//! endpoint and the JSON 404/405 fallbacks.

use super::auth::Admin;
use super::cache::CachedImage;
use super::error::{ApiError, ErrorBody};
use super::pool::PoolError;
use super::view::{ImageFormat, RenderQuery, Source, ViewParams, ViewRequest};
use super::{AppState, Ready};
use crate::progress::Stage;
use crate::render::presets::PRESETS;
use crate::render::style::{FieldSchema, PartialStyle};
use crate::render::view_style::{ResolvedStyles, ViewStyle};
use crate::render::{RenderError, Style};
use crate::scene::VegetationLayer;
use crate::scene::camera::Camera;
use crate::scene::config::AboutConfig;
use crate::scene::cover::CoverClass;
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use serde::de::DeserializeOwned;
use utoipa::ToSchema;

/// `GET /api/health`.
#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// `ok` when the scene is loaded and rendering, `loading` before.
    pub status: &'static str,
    /// While loading: the stage reached (`terrain`, `drape`, `placement`, `preprocessing`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stage: Option<Stage>,
    /// While loading: the stage in words, for people waiting.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stage_label: Option<&'static str>,
    /// While loading: percent of the load done (an estimate: each stage has a fixed share).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub percent: Option<f32>,
    /// Server version.
    pub version: &'static str,
    /// Seconds since the server started.
    pub uptime_s: f64,
    /// The graphics adapter (GPU or lavapipe) once known.
    pub adapter: Option<String>,
    /// The scene's name once loaded.
    pub scene: Option<String>,
    /// Open WebSocket sessions.
    pub sessions: i64,
    /// Renders waiting for the renderer.
    pub queue_depth: usize,
}

/// A camera in scene metres.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct CameraInfo {
    /// Eye position `[x, y, z]`.
    pub position: [f32; 3],
    /// Compass heading in degrees.
    pub yaw: f32,
    /// Degrees above or below the horizon.
    pub pitch: f32,
    /// Vertical field of view in degrees.
    pub fov: f32,
}

impl From<&Camera> for CameraInfo {
    fn from(c: &Camera) -> Self {
        CameraInfo { position: c.position, yaw: c.yaw, pitch: c.pitch, fov: c.fov }
    }
}

/// The scene's extent in the local metric frame (x east, y north, metres).
#[derive(Debug, Serialize, ToSchema)]
pub struct Extent {
    /// `[x, y]` of the south-west corner.
    pub min: [f64; 2],
    /// `[x, y]` of the north-east corner.
    pub max: [f64; 2],
}

/// One land-cover class on the ground in `GET /api/scene`.
#[derive(Debug, Serialize, ToSchema)]
pub struct GroundClassInfo {
    /// Its code in the land cover.
    pub code: i64,
    /// What it is called (the scene file's or the classification's name).
    pub name: String,
    /// Its colour in the colour styles, `#rrggbb`.
    pub color: String,
}

impl From<&CoverClass> for GroundClassInfo {
    fn from(class: &CoverClass) -> Self {
        let [r, g, b] = class.rgb8();
        GroundClassInfo { code: class.code, name: class.name.clone(), color: format!("#{r:02x}{g:02x}{b:02x}") }
    }
}

/// One vegetation layer.
#[derive(Debug, Serialize, ToSchema)]
pub struct LayerInfo {
    /// Layer name.
    pub name: String,
    /// Number of plants.
    pub plants: usize,
    /// The area the plants stand on (their bounding box); `null` for an empty layer.
    pub extent: Option<Extent>,
}

impl From<&VegetationLayer> for LayerInfo {
    fn from(layer: &VegetationLayer) -> Self {
        let extent = layer.plants.iter().fold(None, |box_: Option<Extent>, plant| {
            let [x, y] = [f64::from(plant.position[0]), f64::from(plant.position[1])];
            Some(match box_ {
                None => Extent { min: [x, y], max: [x, y] },
                Some(e) => Extent { min: [e.min[0].min(x), e.min[1].min(y)], max: [e.max[0].max(x), e.max[1].max(y)] },
            })
        });
        LayerInfo { name: layer.name.clone(), plants: layer.plants.len(), extent }
    }
}

/// The sun's direction.
#[derive(Debug, Serialize, ToSchema)]
pub struct SunInfo {
    /// Degrees clockwise from north.
    pub azimuth: f32,
    /// Degrees above the horizon.
    pub elevation: f32,
}

/// `GET /api/scene`: what a client needs to navigate and render the scene.
#[derive(Debug, Serialize, ToSchema)]
pub struct SceneInfo {
    /// Scene name.
    pub name: String,
    /// The scene file's `[about]`: welcome title, description, plan summary and the plan's layer.
    pub about: AboutConfig,
    /// Identifier of the scene and renderer (part of every ETag).
    pub id: String,
    /// The DEM's coordinate reference system.
    pub crs: String,
    /// Extent in scene metres.
    pub extent: Extent,
    /// Vegetation layers.
    pub layers: Vec<LayerInfo>,
    /// The land-cover classes on the ground (`[terrain] landcover`), for the legend; empty
    /// without a land cover.
    pub ground: Vec<GroundClassInfo>,
    /// Plant species.
    pub species: Vec<String>,
    /// The default camera.
    pub default_camera: CameraInfo,
    /// The sun.
    pub sun: SunInfo,
    /// Every style field with its default value.
    #[schema(value_type = Object)]
    pub default_style: Style,
    /// Style presets: name, one-line description and the style fields each sets.
    pub presets: Vec<PresetInfo>,
    /// Every style field: name, kind (`number`, `integer`, `boolean`, `string`, `color`),
    /// default, `min`/`max` where bounded, and what it does.
    #[schema(value_type = Vec<Object>)]
    pub style_schema: Vec<FieldSchema>,
    /// Image formats.
    pub formats: Vec<ImageFormat>,
    /// Largest image width in pixels.
    pub max_width: u32,
    /// Largest image height in pixels.
    pub max_height: u32,
}

/// A style preset in `GET /api/scene`.
#[derive(Debug, Serialize, ToSchema)]
pub struct PresetInfo {
    /// The name to pass as `preset`.
    pub name: &'static str,
    /// What it looks like.
    pub description: &'static str,
    /// The style fields it sets over the defaults.
    #[schema(value_type = Object)]
    pub style: PartialStyle,
}

/// `POST /api/cache/clear`.
#[derive(Debug, Serialize, ToSchema)]
pub struct CacheCleared {
    /// Images removed.
    pub entries: usize,
    /// Bytes freed.
    pub bytes: usize,
}

/// Liveness and readiness: 200 with the adapter and scene once the scene is loaded, 503 before.
#[utoipa::path(get, path = "/api/health", tag = "operations", responses(
    (status = 200, description = "Ready", body = Health),
    (status = 503, description = "The scene is still loading", body = Health)))]
pub async fn health(State(state): State<AppState>) -> Response {
    let ready = state.ready();
    let loading = if ready.is_some() { None } else { state.loading() };
    let health = Health {
        status: if ready.is_some() { "ok" } else { "loading" },
        stage: loading.map(|(stage, _)| stage),
        stage_label: loading.map(|(stage, _)| stage.label()),
        percent: loading.map(|(_, percent)| (percent * 10.0).round() / 10.0),
        version: env!("CARGO_PKG_VERSION"),
        uptime_s: state.uptime().as_secs_f64(),
        adapter: ready.map(|r| r.adapter.clone()),
        scene: ready.map(|r| r.scene.name.clone()),
        sessions: state.metrics().sessions.get(),
        queue_depth: ready.map_or(0, |r| r.pool.depth()),
    };
    let status = if ready.is_some() { StatusCode::OK } else { StatusCode::SERVICE_UNAVAILABLE };
    (status, Json(health)).into_response()
}

/// The scene: name, CRS, extent, layers with plant counts, default camera, sun, default style
/// and the server's image limits.
#[utoipa::path(get, path = "/api/scene", tag = "scene", responses(
    (status = 200, description = "The scene", body = SceneInfo),
    (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn scene(State(state): State<AppState>) -> Result<Json<SceneInfo>, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let scene = &ready.scene;
    let (min, max) = scene.terrain.bounds();
    let config = state.config();
    Ok(Json(SceneInfo {
        name: scene.name.clone(),
        id: ready.scene_id.clone(),
        crs: scene.terrain.dem.crs.to_string(),
        extent: Extent { min, max },
        about: scene.about.clone(),
        layers: scene.layers.iter().map(LayerInfo::from).collect(),
        ground: scene.terrain.drape.present_classes().into_iter().map(GroundClassInfo::from).collect(),
        species: scene.species.iter().map(|s| s.name.clone()).collect(),
        default_camera: CameraInfo::from(&scene.default_camera),
        sun: SunInfo { azimuth: scene.sun.azimuth, elevation: scene.sun.elevation },
        default_style: Style::default(),
        presets: PRESETS
            .iter()
            .map(|p| PresetInfo { name: p.name, description: p.description, style: p.overrides() })
            .collect(),
        style_schema: Style::schema(),
        formats: vec![ImageFormat::Png, ImageFormat::Jpeg],
        max_width: config.max_width,
        max_height: config.max_height,
    }))
}

/// Renders a view given as query parameters (a shareable link; see `POST /api/render` for
/// the same as JSON).
#[utoipa::path(get, path = "/api/render", tag = "render", params(RenderQuery),
    responses(
        (status = 200, description = "The image; `ETag` identifies the view", content(("image/png"), ("image/jpeg"))),
        (status = 304, description = "Not modified (`If-None-Match` matched the ETag)"),
        (status = 400, description = "Malformed parameter", body = ErrorBody),
        (status = 404, description = "Unknown preset", body = ErrorBody),
        (status = 413, description = "Image larger than the server allows", body = ErrorBody),
        (status = 422, description = "Value out of range or invalid style", body = ErrorBody),
        (status = 503, description = "Render queue full or scene loading; see `Retry-After`", body = ErrorBody)))]
pub async fn render_get(
    State(state): State<AppState>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let params = ViewParams::from_query(query.as_deref().unwrap_or_default())?;
    let view = params.normalize(&ready.scene, state.store(), state.limits(), Source::Query)?;
    let view = super::comments::with_pins(&state, ready, view).await?;
    render_view(ready, view, &headers).await
}

/// Renders a view given as a JSON body; its query-parameter form renders the same image.
#[utoipa::path(post, path = "/api/render", tag = "render", request_body = ViewParams,
    responses(
        (status = 200, description = "The image; `ETag` identifies the view", content(("image/png"), ("image/jpeg"))),
        (status = 304, description = "Not modified (`If-None-Match` matched the ETag)"),
        (status = 400, description = "Malformed JSON", body = ErrorBody),
        (status = 404, description = "Unknown preset", body = ErrorBody),
        (status = 413, description = "Image or body larger than the server allows", body = ErrorBody),
        (status = 422, description = "Value out of range, wrong type or invalid style", body = ErrorBody),
        (status = 503, description = "Render queue full or scene loading; see `Retry-After`", body = ErrorBody)))]
pub async fn render_post(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let params: ViewParams = parse_body(body)?;
    let view = params.normalize(&ready.scene, state.store(), state.limits(), Source::Body)?;
    let view = super::comments::with_pins(&state, ready, view).await?;
    render_view(ready, view, &headers).await
}

/// Resolves the styles of a view as a render does (the defaults, the preset, the fields; each
/// layer's fields over its own preset or the view's style) and answers every style of the
/// view: the view's and each layer's of the scene, with what its own fields merge over. The
/// browser's style panel shows these.
#[utoipa::path(post, path = "/api/styles/resolve", tag = "render", request_body = ViewStyle,
    responses(
        (status = 200, description = "The resolved styles", body = ResolvedStyles),
        (status = 400, description = "Malformed JSON", body = ErrorBody),
        (status = 404, description = "Unknown preset", body = ErrorBody),
        (status = 413, description = "Body larger than the server allows", body = ErrorBody),
        (status = 422, description = "Unknown layer, value out of range, wrong type or unknown field", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn resolve_styles(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<ResolvedStyles>, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let styles: ViewStyle = parse_body(body)?;
    Ok(Json(styles.resolve_all(&ready.scene.layer_names())?))
}

/// Parses a JSON body: too large a body is a 413, malformed JSON a 400, wrong types or unknown
/// fields a 422 naming the field.
pub fn parse_body<T: DeserializeOwned>(body: Result<Bytes, BytesRejection>) -> Result<T, ApiError> {
    let body = body.map_err(|e| match e.status() {
        StatusCode::PAYLOAD_TOO_LARGE => {
            ApiError::too_large("body", "the request body is larger than this server allows")
        }
        _ => super::connections::body_error(&e, || ApiError::bad("body", e.body_text())),
    })?;
    let mut deserializer = serde_json::Deserializer::from_slice(&body);
    let params: T = serde_path_to_error::deserialize(&mut deserializer).map_err(|e| {
        let path = e.path().to_string();
        let parameter = (path != ".").then_some(path);
        let inner = e.into_inner();
        let message = format!("request body: {inner}");
        if inner.is_data() {
            ApiError::Invalid { parameter, message }
        } else {
            ApiError::BadRequest { parameter, message }
        }
    })?;
    deserializer.end().map_err(|e| ApiError::bad("body", format!("request body: {e}")))?;
    Ok(params)
}

/// Answers a normalized view: 304 when `If-None-Match` matches, else from the cache or the
/// renderer.
async fn render_view(ready: &Ready, view: ViewRequest, headers: &HeaderMap) -> Result<Response, ApiError> {
    // Art maps change at run time: the generation tells whether a frame may be cached under
    // this ETag (an upload between the ETag and the render would make it stale).
    let art_generation = ready.art.generation();
    let etag = view.etag(&ready.art.etag_basis(&ready.scene_id));
    let etag_header = HeaderValue::from_str(&etag).map_err(|e| ApiError::Internal(e.to_string()))?;
    let link = format!("/api/render?{}", view.to_params().to_query());
    let warnings: Vec<HeaderValue> = view.data.warnings.iter().filter_map(|w| warning_header(w)).collect();
    let common = |response: &mut Response, cache: &'static str| {
        let h = response.headers_mut();
        for warning in &warnings {
            h.append(header::WARNING, warning.clone());
        }
        h.insert(header::ETAG, etag_header.clone());
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
        h.insert("x-cache", HeaderValue::from_static(cache));
        if let Ok(link) = HeaderValue::from_str(&link) {
            h.insert(header::CONTENT_LOCATION, link);
        }
    };
    if if_none_match(headers, &etag) {
        let mut response = StatusCode::NOT_MODIFIED.into_response();
        common(&mut response, "revalidated");
        return Ok(response);
    }
    let (image, cache) = match ready.cache.get(&etag) {
        Some(image) => (image, "hit"),
        None => {
            let receiver = ready.pool.submit(view.clone()).map_err(pool_error)?;
            let frame = receiver.await.map_err(|_| ApiError::ShuttingDown)?.map_err(pool_error)?;
            let image = CachedImage { bytes: frame.bytes, render_ms: frame.render_ms };
            if ready.art.generation() == art_generation {
                ready.cache.insert(etag.clone(), image.clone());
            }
            (image, "miss")
        }
    };
    let mut response = ([(header::CONTENT_TYPE, view.format.mime())], image.bytes).into_response();
    common(&mut response, cache);
    response.headers_mut().insert("x-render-ms", HeaderValue::from(image.render_ms.round() as u32));
    Ok(response)
}

/// A `Warning: 199 landsketch "…"` header value (RFC 7234 miscellaneous warning) for a data
/// note (Table 9.1, clamped time), in ASCII.
fn warning_header(message: &str) -> Option<HeaderValue> {
    let ascii: String = message
        .replace('→', "->")
        .replace('…', "..")
        .chars()
        .map(|c| if c.is_ascii_graphic() || c == ' ' { c } else { '?' })
        .filter(|c| *c != '"' && *c != '\\')
        .collect();
    HeaderValue::from_str(&format!("199 landsketch \"{ascii}\"")).ok()
}

/// True when an `If-None-Match` header lists `etag` (or is `*`).
fn if_none_match(headers: &HeaderMap, etag: &str) -> bool {
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.split(',').map(str::trim).any(|tag| tag == "*" || tag.strip_prefix("W/").unwrap_or(tag) == etag))
}

/// Maps render-queue errors to API errors.
pub fn pool_error(error: PoolError) -> ApiError {
    match error {
        PoolError::Full { depth, retry_after_s } => ApiError::Busy {
            message: format!("the render queue is full ({depth} renders waiting); retry later"),
            retry_after: retry_after_s,
        },
        PoolError::Closed | PoolError::Cancelled => ApiError::ShuttingDown,
        // Art maps can be added and removed at run time, so an index is checked on render.
        PoolError::Render(error @ RenderError::UnknownArtMap { field, .. }) => {
            ApiError::invalid(format!("style.{field}"), error.to_string())
        }
        other => ApiError::Internal(other.to_string()),
    }
}

/// Empties the render cache (admin).
#[utoipa::path(post, path = "/api/cache/clear", tag = "operations",
    security(("bearer" = []), ()),
    responses(
        (status = 200, description = "Cache cleared", body = CacheCleared),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused: without an admin token, a client not on loopback, a foreign Host or a foreign Origin; with one, a foreign Origin", body = ErrorBody),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn cache_clear(_admin: Admin, State(state): State<AppState>) -> Result<Json<CacheCleared>, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let (entries, bytes) = ready.cache.clear();
    tracing::info!(entries, bytes, "render cache cleared");
    Ok(Json(CacheCleared { entries, bytes }))
}

/// JSON 404 for unknown routes.
pub async fn not_found() -> ApiError {
    ApiError::NotFound("no such endpoint; see /api/openapi.json".into())
}

/// JSON 405 for known routes with the wrong method.
pub async fn method_not_allowed() -> ApiError {
    ApiError::MethodNotAllowed
}
