//! Comments pinned in the landscape (`/api/comments`, issue #14): a citizen points at a pixel
//! of the view it sees; the server renders that view reading back depth and object ids,
//! unprojects the pixel to scene metres ([`Camera::pixel_point`]), records what it hit
//! (terrain or a plant of a named layer), geolocates it in WGS 84 and stores it. Likes and
//! reports, moderation (admin), and export as GeoJSON or CSV.

use super::AppState;
use super::auth::Admin;
use super::error::{ApiError, ErrorBody};
use super::events::{Change, LiveEvent};
use super::ratelimit::{RateLimiter, take};
use super::routes::{parse_body, pool_error};
use super::view::{Source, ViewParams, ViewRequest};
use crate::echo::echo;
use crate::fields::{format_time, parse_time};
use crate::render::gbuffer::BACKGROUND_DEPTH;
use crate::render::layer_code::LayerCode;
use crate::render::marks::Pin;
use crate::scene::Scene;
use crate::scene::participation::{Moderation, ParticipationConfig, Viewpoint};
use crate::store::participation::{
    Comment, CommentFilter, CommentStatus, Hit, LikeOutcome, NewComment, ParticipationError, ReportOutcome,
    author_hash, now_ms,
};
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{ConnectInfo, FromRequestParts, Path, State};
use axum::http::request::Parts;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::time::Instant;
use utoipa::{IntoParams, ToSchema};

/// The participation settings of the loaded scene and the rate-limit buckets.
#[derive(Debug)]
pub struct Participation {
    /// `[participation]` of the scene file.
    pub config: ParticipationConfig,
    /// `[[viewpoints]]` of the scene file, in order.
    pub scene_viewpoints: Vec<Viewpoint>,
    tokens: RateLimiter,
    addresses: RateLimiter,
}

impl Participation {
    /// The settings and fresh buckets.
    pub fn new(config: ParticipationConfig, scene_viewpoints: Vec<Viewpoint>) -> Participation {
        Participation {
            tokens: RateLimiter::new(config.rate_limit.per_token),
            addresses: RateLimiter::new(config.rate_limit.per_address),
            config,
            scene_viewpoints,
        }
    }

    /// Takes one write from the author's and the address's buckets; a 429 with `Retry-After`
    /// when either is empty.
    fn admit(&self, author: &str, address: &str) -> Result<(), ApiError> {
        take(&[(&self.tokens, author), (&self.addresses, address)], Instant::now()).map_err(|wait| {
            let seconds = wait.as_secs_f64().ceil().max(1.0);
            ApiError::TooManyRequests {
                message: format!(
                    "too many comments, likes or reports from this author or address; retry in {seconds:.0} s"
                ),
                retry_after: seconds as u32,
            }
        })
    }
}

/// A comment as the API answers it. The public form leaves out the report count.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct CommentJson {
    /// Identifier (below 2⁵³).
    pub id: i64,
    /// The number drawn on its pin.
    pub number: i64,
    /// Position in scene metres `[x, y, z]` (x east, y north, z up).
    pub position: [f64; 3],
    /// WGS 84 longitude in degrees.
    pub lon: f64,
    /// WGS 84 latitude in degrees.
    pub lat: f64,
    /// What the pixel showed: `{"kind": "terrain"}` or `{"kind": "plant", "layer", "index"}`.
    pub hit: Hit,
    /// The camera the comment was made from (`position`, `yaw`, `pitch`, `fov`, `roll`,
    /// `projection` when not perspective).
    #[schema(value_type = Object)]
    pub camera: serde_json::Value,
    /// Plain text.
    pub text: String,
    /// Category (one of the scene's), if given.
    pub category: Option<String>,
    /// Creation time, RFC 3339 (UTC).
    pub created: String,
    /// Likes.
    pub likes: i64,
    /// `visible`, `pending` or `hidden` (always `visible` publicly).
    pub status: CommentStatus,
    /// Reports received (admin answers only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reports: Option<i64>,
}

/// RFC 3339 of a time in milliseconds since the epoch.
pub fn rfc3339_ms(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms).map(|t| format_time(&t)).unwrap_or_default()
}

impl CommentJson {
    /// The public form.
    pub fn public(comment: &Comment) -> CommentJson {
        CommentJson {
            id: comment.id,
            number: comment.number,
            position: comment.position,
            lon: comment.lon_lat[0],
            lat: comment.lon_lat[1],
            hit: comment.hit.clone(),
            camera: comment.camera.clone(),
            text: comment.text.clone(),
            category: comment.category.clone(),
            created: rfc3339_ms(comment.created_ms),
            likes: comment.likes,
            status: comment.status,
            reports: None,
        }
    }

    /// The moderators' form, with the report count.
    pub fn admin(comment: &Comment) -> CommentJson {
        CommentJson { reports: Some(comment.reports), ..CommentJson::public(comment) }
    }
}

/// The body of `POST /api/comments`.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct NewCommentBody {
    /// The view the client sees, as the body of `POST /api/render` (`camera`, `width`,
    /// `height`, `preset`, `style`, `layer_styles`, `mappings`, `time`; `format` and `quality`
    /// do not matter).
    pub view: ViewParams,
    /// `[column, row]` of the pixel pointed at, from the image's top-left corner.
    #[schema(value_type = Option<Vec<u32>>, min_items = 2, max_items = 2)]
    pub pixel: Option<Vec<u32>>,
    /// Plain text (no HTML), at most `max_text_chars` characters (`[participation]`).
    pub text: Option<String>,
    /// One of the scene's categories (`GET /api/participation`), if any.
    pub category: Option<String>,
    /// The anonymous author token: 16–128 characters of letters, digits, `-` and `_`, random
    /// and kept by the browser.
    pub author: Option<String>,
}

/// The body of likes and reports: who acts.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct AuthorBody {
    /// The author token.
    pub author: Option<String>,
}

/// The answer to a like or unlike.
#[derive(Debug, Serialize, ToSchema)]
pub struct Likes {
    /// The comment.
    pub id: i64,
    /// Its likes now.
    pub likes: i64,
    /// Whether this author likes it now.
    pub liked: bool,
}

/// The answer to a report.
#[derive(Debug, Serialize, ToSchema)]
pub struct Reported {
    /// The comment.
    pub id: i64,
    /// `false` when this author had reported it already.
    pub counted: bool,
}

/// `GET /api/participation`: what a client needs to offer commenting.
#[derive(Debug, Serialize, ToSchema)]
pub struct ParticipationInfo {
    /// `post` or `pre`.
    pub moderation: Moderation,
    /// The categories a comment may have.
    pub categories: Vec<String>,
    /// Longest text in characters.
    pub max_text_chars: usize,
}

/// The query of `GET /api/comments`.
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(default, deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct CommentQuery {
    /// `json` (default), `geojson` (RFC 7946, WGS 84) or `csv`.
    pub format: Option<String>,
    /// Comma-separated statuses: `visible` (default), `pending`, `hidden`, or `all`; anything
    /// but `visible` needs the admin token.
    pub status: Option<String>,
    /// Only this category.
    pub category: Option<String>,
    /// Only comments created at or after this ISO 8601 time.
    pub since: Option<String>,
    /// Only comments created at or before this ISO 8601 time.
    pub until: Option<String>,
}

/// `GET /api/comments` as JSON.
#[derive(Debug, Serialize, ToSchema)]
pub struct CommentList {
    /// The comments, by number.
    pub comments: Vec<CommentJson>,
}

/// Longest author token.
const MAX_TOKEN_CHARS: usize = 128;
/// Shortest author token (random enough not to be guessed).
const MIN_TOKEN_CHARS: usize = 16;

/// The author token's hash, or a 422 naming `author`.
fn author_of(token: Option<&str>) -> Result<String, ApiError> {
    let token = token.ok_or_else(|| ApiError::invalid("author", "author: the anonymous author token is missing"))?;
    let ok = (MIN_TOKEN_CHARS..=MAX_TOKEN_CHARS).contains(&token.len())
        && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !ok {
        return Err(ApiError::invalid(
            "author",
            format!(
                "author: the token must be {MIN_TOKEN_CHARS}-{MAX_TOKEN_CHARS} letters, digits, '-' or '_' \
                 (a random id the browser keeps)"
            ),
        ));
    }
    Ok(author_hash(token))
}

/// Checks comment text: not empty, at most `max_chars` characters, plain text (no HTML tag,
/// no control characters but line breaks and tabs). Returns it trimmed.
pub fn check_text(text: Option<&str>, max_chars: usize) -> Result<String, ApiError> {
    let text = text.map(str::trim).unwrap_or_default();
    if text.is_empty() {
        return Err(ApiError::invalid("text", "text: the comment is empty"));
    }
    let chars = text.chars().count();
    if chars > max_chars {
        return Err(ApiError::invalid(
            "text",
            format!("text: {chars} characters is over this scene's limit of {max_chars}"),
        ));
    }
    if let Some(tag) = html_tag(text) {
        return Err(ApiError::invalid(
            "text",
            format!("text: comments are plain text; the HTML tag {:?} is not accepted", echo(tag)),
        ));
    }
    if text.chars().any(|c| c.is_control() && !matches!(c, '\n' | '\r' | '\t')) {
        return Err(ApiError::invalid("text", "text: control characters are not accepted"));
    }
    Ok(text.to_owned())
}

/// The first thing in `text` that an HTML parser would take for markup: `<` followed by a
/// letter, `/`, `!` or `?` (a tag, an end tag, a comment or doctype, a processing
/// instruction), up to its `>` or the end. `a < b` and `<3` are plain text.
fn html_tag(text: &str) -> Option<&str> {
    text.match_indices('<').find_map(|(at, _)| {
        let rest = &text[at..];
        let next = rest[1..].chars().next()?;
        (next.is_ascii_alphabetic() || matches!(next, '/' | '!' | '?'))
            .then(|| rest.find('>').map_or(rest, |end| &rest[..=end]))
    })
}

/// The category, checked against the scene's; a 422 listing them when unknown.
fn check_category(category: Option<String>, config: &ParticipationConfig) -> Result<Option<String>, ApiError> {
    match category {
        Some(c) if !config.categories.contains(&c) => Err(ApiError::invalid(
            "category",
            format!("category: unknown category {:?}; this scene has {}", echo(&c), config.categories.join(", ")),
        )),
        other => Ok(other),
    }
}

/// The client's address, the key of its rate-limit bucket.
fn client_address(parts: &Parts) -> String {
    parts
        .extensions
        .get::<ConnectInfo<SocketAddr>>()
        .map_or_else(|| "unknown".to_owned(), |ConnectInfo(addr)| addr.ip().to_canonical().to_string())
}

/// Whether the request passes the admin guard (without answering its refusal).
async fn is_admin(parts: &mut Parts, state: &AppState) -> bool {
    Admin::from_request_parts(parts, state).await.is_ok()
}

/// A participation-store failure: a 500 whose details go to the log.
pub fn store_error(error: ParticipationError) -> ApiError {
    ApiError::Storage(error.to_string())
}

/// What an object id of the G-buffer names: the terrain or a plant of a vegetation layer;
/// `None` on the sky.
pub fn hit_of(scene: &Scene, object_id: u32) -> Option<Hit> {
    let layer = LayerCode::of_object_id(object_id);
    if layer == LayerCode::BACKGROUND {
        return None;
    }
    if layer == LayerCode::TERRAIN {
        return Some(Hit::Terrain);
    }
    let index = layer.code().checked_sub(LayerCode::FIRST_VEGETATION)?;
    let plant = (object_id & LayerCode::INDEX_MASK).checked_sub(1)?;
    let name = scene.layers.get(usize::try_from(index).ok()?)?.name.clone();
    Some(Hit::Plant { layer: name, index: plant })
}

/// Creates a comment at the pixel of the view the client sees.
#[utoipa::path(post, path = "/api/comments", tag = "participation", request_body = NewCommentBody,
    responses(
        (status = 201, description = "Stored; `Location` names it. `status` is `pending` under pre-moderation", body = CommentJson),
        (status = 400, description = "Malformed JSON", body = ErrorBody),
        (status = 413, description = "Image or body larger than the server allows", body = ErrorBody),
        (status = 422, description = "Bad text (empty, too long, HTML), unknown category, bad or missing author token, a pixel outside the image or on the sky, a bad view", body = ErrorBody),
        (status = 429, description = "Too many writes from this author or address; see `Retry-After`", body = ErrorBody),
        (status = 503, description = "Render queue full or scene loading", body = ErrorBody)))]
pub async fn create(
    State(state): State<AppState>,
    parts: Parts,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let settings = &ready.participation;
    let body: NewCommentBody = parse_body(body)?;
    let author = author_of(body.author.as_deref())?;
    let text = check_text(body.text.as_deref(), settings.config.max_text_chars)?;
    let category = check_category(body.category, &settings.config)?;
    let pixel = match body.pixel.as_deref() {
        Some(&[x, y]) => [x, y],
        _ => return Err(ApiError::invalid("pixel", "pixel: give [column, row] of the pixel pointed at")),
    };
    let view = body.view.normalize(&ready.scene, state.store(), state.limits(), Source::Body)?;
    if pixel[0] >= view.width || pixel[1] >= view.height {
        return Err(ApiError::invalid(
            "pixel",
            format!("pixel: {},{} is outside the {}×{} image", pixel[0], pixel[1], view.width, view.height),
        ));
    }
    let geo = ready
        .geo
        .as_ref()
        .map_err(|e| ApiError::invalid("view", format!("comments cannot be placed on a map in this scene: {e}")))?;
    settings.admit(&author, &client_address(&parts))?;
    let camera = view.camera;
    let (width, height) = (view.width, view.height);
    let receiver = ready.pool.pick(view, pixel).map_err(pool_error)?;
    let pick = receiver.await.map_err(|_| ApiError::ShuttingDown)?.map_err(pool_error)?;
    let hit = hit_of(&ready.scene, pick.object_id)
        .filter(|_| f64::from(pick.depth) < BACKGROUND_DEPTH * 0.5)
        .ok_or_else(|| ApiError::invalid("pixel", "pixel: it shows the sky; point at the ground or a plant"))?;
    let point = camera.pixel_point(pixel[0], pixel[1], pick.depth, width, height);
    let position = [f64::from(point.x), f64::from(point.y), f64::from(point.z)];
    let located = geo
        .locator()
        .ok()
        .and_then(|l| l.locate(position[0], position[1]))
        .ok_or_else(|| ApiError::invalid("pixel", "pixel: the point cannot be converted to WGS 84"))?;
    let status = match settings.config.moderation {
        Moderation::Post => CommentStatus::Visible,
        Moderation::Pre => CommentStatus::Pending,
    };
    let camera = serde_json::to_value(camera).map_err(|e| ApiError::Internal(e.to_string()))?;
    let new = NewComment {
        position,
        lon_lat: located.lon_lat,
        hit,
        camera,
        text,
        category,
        created_ms: now_ms(),
        author,
        status,
    };
    let comment = state.participation().add_comment(new).await.map_err(store_error)?;
    tracing::info!(comment = comment.id, number = comment.number, status = comment.status.name(), "comment added");
    state.publish(LiveEvent::Comment { change: Change::Added, comment: Box::new(comment.clone()), was_public: false });
    let mut response = (StatusCode::CREATED, Json(CommentJson::public(&comment))).into_response();
    if let Ok(location) = HeaderValue::from_str(&format!("/api/comments/{}", comment.id)) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    Ok(response)
}

/// The filter of a comment query; statuses other than `visible` need the admin.
fn filter_of(query: &CommentQuery) -> Result<CommentFilter, ApiError> {
    let statuses = match query.status.as_deref() {
        None => vec![CommentStatus::Visible],
        Some("all") => CommentStatus::ALL.to_vec(),
        Some(list) => list
            .split(',')
            .map(|s| {
                CommentStatus::parse(s.trim()).ok_or_else(|| {
                    ApiError::invalid(
                        "status",
                        format!("status: unknown status {:?}; use visible, pending, hidden or all", echo(s)),
                    )
                })
            })
            .collect::<Result<Vec<_>, _>>()?,
    };
    let time = |parameter: &str, text: &Option<String>| {
        text.as_deref()
            .map(|t| {
                parse_time(t)
                    .map(|t| t.timestamp_millis())
                    .map_err(|e| ApiError::invalid(parameter, format!("{parameter}: {e}")))
            })
            .transpose()
    };
    Ok(CommentFilter {
        statuses,
        category: query.category.clone(),
        since_ms: time("since", &query.since)?,
        until_ms: time("until", &query.until)?,
    })
}

/// Lists comments: visible ones to everyone, others to the admin; as JSON, GeoJSON or CSV.
#[utoipa::path(get, path = "/api/comments", tag = "participation", params(CommentQuery),
    security((), ("bearer" = [])),
    responses(
        (status = 200, description = "The comments (JSON), a GeoJSON FeatureCollection (`application/geo+json`) or CSV (`text/csv`)", body = CommentList),
        (status = 400, description = "Unknown query parameter", body = ErrorBody),
        (status = 401, description = "A status other than `visible` without the admin token", body = ErrorBody),
        (status = 422, description = "Unknown format or status, unreadable time", body = ErrorBody)))]
pub async fn list(State(state): State<AppState>, mut parts: Parts) -> Result<Response, ApiError> {
    let query: CommentQuery = serde_urlencoded::from_str(parts.uri.query().unwrap_or_default())
        .map_err(|e| ApiError::BadRequest { parameter: None, message: format!("query: {e}") })?;
    let filter = filter_of(&query)?;
    let format = super::export::ExportFormat::parse(query.format.as_deref())?;
    let admin = filter.statuses != [CommentStatus::Visible];
    if admin {
        Admin::from_request_parts(&mut parts, &state).await?;
    }
    let comments = state.participation().comments(filter).await.map_err(store_error)?;
    let form = if admin { CommentJson::admin } else { CommentJson::public };
    match format {
        super::export::ExportFormat::Json => {
            Ok(Json(CommentList { comments: comments.iter().map(form).collect() }).into_response())
        }
        other => {
            let ready = state.ready().ok_or(ApiError::NotReady)?;
            super::export::export(other, &comments, ready, admin)
        }
    }
}

/// The visible comments as the pins a view draws: at their points, with their numbers and
/// their categories' indices in the scene's list (none or an unlisted one: the grey of `other`).
pub async fn comment_pins(state: &AppState, ready: &super::Ready) -> Result<Vec<Pin>, ApiError> {
    let comments = state.participation().comments(CommentFilter::public()).await.map_err(store_error)?;
    let categories = &ready.participation.config.categories;
    Ok(comments
        .iter()
        .map(|c| Pin {
            position: glam::DVec3::from_array(c.position).as_vec3(),
            number: u32::try_from(c.number).unwrap_or(u32::MAX),
            category: c
                .category
                .as_ref()
                .and_then(|name| categories.iter().position(|k| k == name))
                .and_then(|i| u8::try_from(i).ok())
                .unwrap_or(u8::MAX),
        })
        .collect())
}

/// `view` with its comment pins filled in when it asks for them (`comments`).
pub async fn with_pins(state: &AppState, ready: &super::Ready, mut view: ViewRequest) -> Result<ViewRequest, ApiError> {
    if view.comments.is_some() {
        view.comments = Some(comment_pins(state, ready).await?);
    }
    Ok(view)
}

/// One comment; a comment that is not visible only to the admin (404 otherwise).
#[utoipa::path(get, path = "/api/comments/{id}", tag = "participation",
    params(("id" = i64, Path, description = "Comment id")),
    responses(
        (status = 200, description = "The comment", body = CommentJson),
        (status = 404, description = "No such (visible) comment", body = ErrorBody)))]
pub async fn get(
    State(state): State<AppState>,
    Path(id): Path<String>,
    mut parts: Parts,
) -> Result<Json<CommentJson>, ApiError> {
    let id = comment_id(&id)?;
    let comment = state.participation().comment(id).await.map_err(store_error)?.ok_or_else(|| not_found(id))?;
    if comment.status == CommentStatus::Visible {
        return Ok(Json(CommentJson::public(&comment)));
    }
    if is_admin(&mut parts, &state).await { Ok(Json(CommentJson::admin(&comment))) } else { Err(not_found(id)) }
}

fn not_found(id: i64) -> ApiError {
    ApiError::NotFound(format!("no comment {id}"))
}

/// The comment id of a path, or a 404.
fn comment_id(text: &str) -> Result<i64, ApiError> {
    text.parse::<i64>()
        .ok()
        .filter(|id| *id > 0)
        .ok_or_else(|| ApiError::NotFound(format!("no comment {:?}", echo(text))))
}

/// A visible comment for a citizen's like or report, or a 404.
async fn visible(state: &AppState, id: i64) -> Result<Comment, ApiError> {
    let comment = state.participation().comment(id).await.map_err(store_error)?;
    comment.filter(|c| c.status == CommentStatus::Visible).ok_or_else(|| not_found(id))
}

/// The author of a like or report body, admitted by the rate limits.
fn acting_author(state: &AppState, parts: &Parts, body: Result<Bytes, BytesRejection>) -> Result<String, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let body: AuthorBody = parse_body(body)?;
    let author = author_of(body.author.as_deref())?;
    ready.participation.admit(&author, &client_address(parts))?;
    Ok(author)
}

/// Tells the sessions that a visible comment changed (likes), with its state now.
async fn publish_changed(state: &AppState, id: i64) -> Result<Comment, ApiError> {
    let comment = state.participation().comment(id).await.map_err(store_error)?.ok_or_else(|| not_found(id))?;
    state.publish(LiveEvent::Comment { change: Change::Changed, comment: Box::new(comment.clone()), was_public: true });
    Ok(comment)
}

/// Likes a visible comment: once per author token, never one's own.
#[utoipa::path(post, path = "/api/comments/{id}/like", tag = "participation", request_body = AuthorBody,
    params(("id" = i64, Path, description = "Comment id")),
    responses(
        (status = 200, description = "Liked (again: unchanged)", body = Likes),
        (status = 403, description = "One's own comment", body = ErrorBody),
        (status = 404, description = "No such visible comment", body = ErrorBody),
        (status = 422, description = "Bad or missing author token", body = ErrorBody),
        (status = 429, description = "Too many writes; see `Retry-After`", body = ErrorBody)))]
pub async fn like(
    State(state): State<AppState>,
    Path(id): Path<String>,
    parts: Parts,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<Likes>, ApiError> {
    let id = comment_id(&id)?;
    let author = acting_author(&state, &parts, body)?;
    visible(&state, id).await?;
    match state.participation().like(id, &author, now_ms()).await.map_err(store_error)? {
        LikeOutcome::Done => {
            let comment = publish_changed(&state, id).await?;
            Ok(Json(Likes { id, likes: comment.likes, liked: true }))
        }
        LikeOutcome::Unchanged => Ok(Json(Likes { id, likes: visible(&state, id).await?.likes, liked: true })),
        LikeOutcome::OwnComment => Err(ApiError::Forbidden("you cannot like your own comment".into())),
        LikeOutcome::NoComment => Err(not_found(id)),
    }
}

/// Takes back a like.
#[utoipa::path(delete, path = "/api/comments/{id}/like", tag = "participation", request_body = AuthorBody,
    params(("id" = i64, Path, description = "Comment id")),
    responses(
        (status = 200, description = "Not liked (any more)", body = Likes),
        (status = 404, description = "No such visible comment", body = ErrorBody),
        (status = 422, description = "Bad or missing author token", body = ErrorBody),
        (status = 429, description = "Too many writes; see `Retry-After`", body = ErrorBody)))]
pub async fn unlike(
    State(state): State<AppState>,
    Path(id): Path<String>,
    parts: Parts,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<Likes>, ApiError> {
    let id = comment_id(&id)?;
    let author = acting_author(&state, &parts, body)?;
    visible(&state, id).await?;
    match state.participation().unlike(id, &author).await.map_err(store_error)? {
        LikeOutcome::Done => {
            let comment = publish_changed(&state, id).await?;
            Ok(Json(Likes { id, likes: comment.likes, liked: false }))
        }
        LikeOutcome::NoComment => Err(not_found(id)),
        LikeOutcome::Unchanged | LikeOutcome::OwnComment => {
            Ok(Json(Likes { id, likes: visible(&state, id).await?.likes, liked: false }))
        }
    }
}

/// Reports a visible comment (once per author token); it is hidden when it has
/// `report_hide_threshold` reports.
#[utoipa::path(post, path = "/api/comments/{id}/report", tag = "participation", request_body = AuthorBody,
    params(("id" = i64, Path, description = "Comment id")),
    responses(
        (status = 200, description = "Reported", body = Reported),
        (status = 404, description = "No such visible comment", body = ErrorBody),
        (status = 422, description = "Bad or missing author token", body = ErrorBody),
        (status = 429, description = "Too many writes; see `Retry-After`", body = ErrorBody)))]
pub async fn report(
    State(state): State<AppState>,
    Path(id): Path<String>,
    parts: Parts,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<Reported>, ApiError> {
    let id = comment_id(&id)?;
    let author = acting_author(&state, &parts, body)?;
    visible(&state, id).await?;
    let threshold = state.ready().ok_or(ApiError::NotReady)?.participation.config.report_hide_threshold;
    match state.participation().report(id, &author, now_ms(), threshold).await.map_err(store_error)? {
        ReportOutcome::Counted(comment) => {
            if comment.status != CommentStatus::Visible {
                tracing::info!(comment = id, reports = comment.reports, "comment hidden by reports");
                state.publish(LiveEvent::Comment {
                    change: Change::Changed,
                    comment: Box::new(comment),
                    was_public: true,
                });
            }
            Ok(Json(Reported { id, counted: true }))
        }
        ReportOutcome::Repeated(_) => Ok(Json(Reported { id, counted: false })),
        ReportOutcome::NoComment => Err(not_found(id)),
    }
}

/// Sets a comment's status (admin) and tells the sessions.
async fn moderate(state: &AppState, id: &str, status: CommentStatus) -> Result<Json<CommentJson>, ApiError> {
    let id = comment_id(id)?;
    let before = state.participation().comment(id).await.map_err(store_error)?.ok_or_else(|| not_found(id))?;
    let after =
        state.participation().set_status(id, status).await.map_err(store_error)?.ok_or_else(|| not_found(id))?;
    tracing::info!(comment = id, status = status.name(), "comment moderated");
    let was_public = before.status == CommentStatus::Visible;
    state.publish(LiveEvent::Comment { change: Change::Changed, comment: Box::new(after.clone()), was_public });
    Ok(Json(CommentJson::admin(&after)))
}

/// Approves a comment (admin): it becomes visible.
#[utoipa::path(post, path = "/api/comments/{id}/approve", tag = "participation",
    params(("id" = i64, Path, description = "Comment id")), security(("bearer" = []), ()),
    responses(
        (status = 200, description = "Visible now", body = CommentJson),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No such comment", body = ErrorBody)))]
pub async fn approve(
    _admin: Admin,
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<CommentJson>, ApiError> {
    moderate(&state, &id, CommentStatus::Visible).await
}

/// Hides a comment (admin).
#[utoipa::path(post, path = "/api/comments/{id}/hide", tag = "participation",
    params(("id" = i64, Path, description = "Comment id")), security(("bearer" = []), ()),
    responses(
        (status = 200, description = "Hidden now", body = CommentJson),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No such comment", body = ErrorBody)))]
pub async fn hide(
    _admin: Admin,
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<CommentJson>, ApiError> {
    moderate(&state, &id, CommentStatus::Hidden).await
}

/// Deletes a comment with its likes and reports (admin).
#[utoipa::path(delete, path = "/api/comments/{id}", tag = "participation",
    params(("id" = i64, Path, description = "Comment id")), security(("bearer" = []), ()),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No such comment", body = ErrorBody)))]
pub async fn delete(
    _admin: Admin,
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    let id = comment_id(&id)?;
    let comment = state.participation().delete_comment(id).await.map_err(store_error)?.ok_or_else(|| not_found(id))?;
    tracing::info!(comment = id, "comment deleted");
    let was_public = comment.status == CommentStatus::Visible;
    state.publish(LiveEvent::Comment { change: Change::Removed, comment: Box::new(comment), was_public });
    Ok(StatusCode::NO_CONTENT)
}

/// The scene's participation settings: moderation, categories, text limit.
#[utoipa::path(get, path = "/api/participation", tag = "participation",
    responses(
        (status = 200, description = "The settings", body = ParticipationInfo),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn info(State(state): State<AppState>) -> Result<Json<ParticipationInfo>, ApiError> {
    let config = &state.ready().ok_or(ApiError::NotReady)?.participation.config;
    Ok(Json(ParticipationInfo {
        moderation: config.moderation,
        categories: config.categories.clone(),
        max_text_chars: config.max_text_chars,
    }))
}

/// Reads the participation settings and viewpoints of the scene file `path` and checks them
/// against the loaded scene (each viewpoint's camera and styles).
pub fn load_settings(path: &std::path::Path, scene: &Scene) -> Result<Participation, crate::scene::SceneError> {
    let config = crate::scene::config::SceneConfig::load(path)?;
    let invalid = |message: String| crate::scene::SceneError::Parse { path: path.to_owned(), message };
    config.participation.validate().map_err(invalid)?;
    super::viewpoints::check_all(&config.viewpoints, scene).map_err(invalid)?;
    Ok(Participation::new(config.participation, config.viewpoints))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_plain_bounded_and_trimmed() {
        assert_eq!(check_text(Some("  The hedge blocks my view.\n"), 100).expect("ok"), "The hedge blocks my view.");
        assert_eq!(check_text(Some("a < b and <3 are fine"), 100).expect("ok"), "a < b and <3 are fine");
        for (text, needle) in [
            ("<script>alert(1)</script>", "<script>"),
            ("nice <b>bold</b>", "<b>"),
            ("</p>", "</p>"),
            ("<!-- hidden -->", "<!-- hidden -->"),
            ("<img src=x onerror=alert(1)", "<img src=x onerror=alert(1)"),
        ] {
            let error = check_text(Some(text), 100).expect_err(text);
            assert!(error.to_string().contains(needle), "{error}");
            assert_eq!(error.detail().parameter.as_deref(), Some("text"));
        }
        assert!(check_text(Some("   "), 100).is_err());
        assert!(check_text(None, 100).is_err());
        assert!(check_text(Some("bell\u{7}"), 100).is_err());
        let long = "é".repeat(101);
        assert!(check_text(Some(&long), 100).expect_err("long").to_string().contains("101 characters"));
        assert!(check_text(Some(&long[..200]), 100).is_ok(), "characters, not bytes, count");
    }

    #[test]
    fn author_tokens_are_checked_and_hashed() {
        let hash = author_of(Some("0123456789abcdef-_XY")).expect("token");
        assert_eq!(hash.len(), 64);
        assert_ne!(hash, "0123456789abcdef-_XY");
        for bad in [None, Some("short"), Some("0123456789abcdef ghij"), Some(&"x".repeat(129)[..])] {
            assert_eq!(author_of(bad).expect_err("bad").detail().parameter.as_deref(), Some("author"));
        }
    }

    #[test]
    fn object_ids_name_the_terrain_or_a_plant() {
        let scene = crate::scene::Scene {
            name: "t".into(),
            terrain: crate::scene::terrain::Terrain::new(
                crate::gis::Raster {
                    width: 2,
                    height: 2,
                    data: vec![0.0; 4],
                    nodata: None,
                    transform: crate::gis::GeoTransform {
                        origin_x: 0.0,
                        origin_y: 2.0,
                        cell_width: 1.0,
                        cell_height: 1.0,
                    },
                    crs: crate::gis::Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
                    palette: None,
                },
                [1.0; 3],
            )
            .expect("terrain"),
            species: Vec::new(),
            layers: vec![crate::scene::VegetationLayer { name: "planned".into(), plants: Vec::new() }],
            sun: crate::scene::Sun { azimuth: 0.0, elevation: 45.0 },
            default_camera: crate::scene::camera::Camera::perspective([0.0; 3], 0.0, 0.0, 60.0),
            about: Default::default(),
        };
        use crate::render::gbuffer::object_id;
        assert_eq!(hit_of(&scene, 0), None);
        assert_eq!(hit_of(&scene, object_id(LayerCode::TERRAIN, 0)), Some(Hit::Terrain));
        assert_eq!(
            hit_of(&scene, object_id(LayerCode::vegetation(0), 41)),
            Some(Hit::Plant { layer: "planned".into(), index: 41 })
        );
        assert_eq!(hit_of(&scene, object_id(LayerCode::vegetation(3), 1)), None);
    }
}
