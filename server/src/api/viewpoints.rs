//! Viewpoints (`/api/viewpoints`, issue #14): named views planners prepare — in the scene
//! file (`[[viewpoints]]`, listed first, in order) and over the admin API (kept in the
//! participation store, listed after, in the order they were created). Citizens jump to them;
//! tours play them in order.

use super::AppState;
use super::auth::Admin;
use super::comments::store_error;
use super::error::{ApiError, ErrorBody};
use super::events::{Change, LiveEvent};
use super::view::{Source, ViewParams};
use crate::echo::echo;
use crate::scene::Scene;
use crate::scene::participation::{Viewpoint, is_viewpoint_name};
use crate::store::participation::now_ms;
use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

/// Where a viewpoint is defined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ViewpointSource {
    /// `[[viewpoints]]` in the scene file (read-only over the API).
    Scene,
    /// The admin API (`PUT /api/viewpoints/{name}`).
    Admin,
}

/// A viewpoint as `GET /api/viewpoints` lists it.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ListedViewpoint {
    /// The viewpoint.
    #[serde(flatten)]
    pub viewpoint: Viewpoint,
    /// `scene` or `admin`.
    pub source: ViewpointSource,
}

/// `GET /api/viewpoints`.
#[derive(Debug, Serialize, ToSchema)]
pub struct ViewpointList {
    /// Scene-file viewpoints first, in order, then those of the admin API.
    pub viewpoints: Vec<ListedViewpoint>,
}

/// The render parameters of a viewpoint at `width` × `height` (what a client posts to
/// `/api/render` or sends as WebSocket controls to show it).
pub fn view_params(viewpoint: &Viewpoint, width: Option<u32>, height: Option<u32>) -> ViewParams {
    ViewParams {
        camera: viewpoint.camera.clone(),
        width,
        height,
        preset: viewpoint.preset.clone(),
        style: viewpoint.style.clone(),
        layer_styles: viewpoint.layer_styles.clone(),
        mappings: viewpoint.mappings.clone(),
        time: viewpoint.time.clone(),
        ..ViewParams::default()
    }
}

/// Checks a viewpoint against the scene: its name, camera and styles (data mappings are
/// checked when it is shown: their layers may be uploaded later).
pub fn check(viewpoint: &Viewpoint, scene: &Scene) -> Result<(), ApiError> {
    if !is_viewpoint_name(&viewpoint.name) {
        return Err(ApiError::invalid("name", "name: 1-80 characters, no control characters and no '/'"));
    }
    viewpoint.camera.resolve(&scene.default_camera, scene, Source::Body)?;
    view_params(viewpoint, None, None).view_style().resolve(&scene.layer_names())?;
    Ok(())
}

/// Checks the scene file's viewpoints: each one, and that names are unique. The message names
/// the viewpoint and the key.
pub fn check_all(viewpoints: &[Viewpoint], scene: &Scene) -> Result<(), String> {
    for (i, viewpoint) in viewpoints.iter().enumerate() {
        if viewpoints[..i].iter().any(|v| v.name == viewpoint.name) {
            return Err(format!("viewpoints: the name {:?} is used twice", viewpoint.name));
        }
        check(viewpoint, scene).map_err(|e| {
            let key = e.detail().parameter.unwrap_or_default();
            format!("viewpoint {:?}: {key}: {e}", viewpoint.name)
        })?;
    }
    Ok(())
}

/// Every viewpoint: the scene file's, then the stored ones (what tours play).
pub async fn all(state: &AppState) -> Result<Vec<ListedViewpoint>, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let scene = ready.participation.scene_viewpoints.iter().cloned();
    let mut listed: Vec<ListedViewpoint> =
        scene.map(|viewpoint| ListedViewpoint { viewpoint, source: ViewpointSource::Scene }).collect();
    for stored in state.participation().viewpoints().await.map_err(store_error)? {
        let mut body = stored.body;
        if let Some(object) = body.as_object_mut() {
            object.insert("name".into(), serde_json::Value::String(stored.name.clone()));
        }
        match serde_json::from_value::<Viewpoint>(body) {
            Ok(viewpoint) => listed.push(ListedViewpoint { viewpoint, source: ViewpointSource::Admin }),
            Err(e) => tracing::warn!(viewpoint = %stored.name, error = %e, "stored viewpoint unreadable; skipped"),
        }
    }
    Ok(listed)
}

/// Every viewpoint: the scene file's first, in order, then the admin API's.
#[utoipa::path(get, path = "/api/viewpoints", tag = "participation",
    responses(
        (status = 200, description = "The viewpoints", body = ViewpointList),
        (status = 503, description = "The scene is still loading", body = ErrorBody)))]
pub async fn list(State(state): State<AppState>) -> Result<Json<ViewpointList>, ApiError> {
    Ok(Json(ViewpointList { viewpoints: all(&state).await? }))
}

/// Parses a viewpoint body for `name`: the body's `name` may be left out, else must match.
fn parse(name: &str, body: Result<Bytes, BytesRejection>) -> Result<Viewpoint, ApiError> {
    let mut value: serde_json::Value = super::routes::parse_body(body)?;
    let object = value.as_object_mut().ok_or_else(|| ApiError::invalid("body", "a viewpoint is a JSON object"))?;
    match object.get("name") {
        None => {
            object.insert("name".into(), serde_json::Value::String(name.to_owned()));
        }
        Some(given) if given.as_str() == Some(name) => {}
        Some(_) => {
            return Err(ApiError::invalid(
                "name",
                format!("name: the body names another viewpoint than {:?}", echo(name)),
            ));
        }
    }
    let bytes = serde_json::to_vec(&value).map_err(|e| ApiError::Internal(e.to_string()))?;
    super::routes::parse_body(Ok(Bytes::from(bytes)))
}

/// Stores a viewpoint (admin); `create_only` refuses an existing name.
async fn store(
    state: &AppState,
    name: &str,
    body: Result<Bytes, BytesRejection>,
    create_only: bool,
) -> Result<Response, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    let viewpoint = parse(name, body)?;
    check(&viewpoint, &ready.scene)?;
    if ready.participation.scene_viewpoints.iter().any(|v| v.name == viewpoint.name) {
        return Err(ApiError::Conflict(format!(
            "the viewpoint {:?} is defined in the scene file; change it there",
            echo(name)
        )));
    }
    let exists = state.participation().viewpoints().await.map_err(store_error)?.iter().any(|v| v.name == name);
    if create_only && exists {
        return Err(ApiError::Conflict(format!("there is a viewpoint {:?} already; PUT replaces it", echo(name))));
    }
    let mut body = serde_json::to_value(&viewpoint).map_err(|e| ApiError::Internal(e.to_string()))?;
    if let Some(object) = body.as_object_mut() {
        object.remove("name");
    }
    let created = state.participation().put_viewpoint(name, body, now_ms()).await.map_err(store_error)?;
    let change = if created { Change::Added } else { Change::Changed };
    tracing::info!(viewpoint = name, created, "viewpoint stored");
    state.publish(LiveEvent::Viewpoint { change, name: name.to_owned() });
    let listed = ListedViewpoint { viewpoint, source: ViewpointSource::Admin };
    let status = if created { StatusCode::CREATED } else { StatusCode::OK };
    Ok((status, Json(listed)).into_response())
}

/// Creates a viewpoint (admin); 409 when the name is taken.
#[utoipa::path(post, path = "/api/viewpoints/{name}", tag = "participation", request_body = Viewpoint,
    params(("name" = String, Path, description = "Viewpoint name")), security(("bearer" = []), ()),
    responses(
        (status = 201, description = "Created", body = ListedViewpoint),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 409, description = "The name is taken (or belongs to a scene-file viewpoint)", body = ErrorBody),
        (status = 422, description = "Bad name, camera or style", body = ErrorBody)))]
pub async fn create(
    _admin: Admin,
    State(state): State<AppState>,
    Path(name): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    store(&state, &name, body, true).await
}

/// Creates or replaces a viewpoint (admin).
#[utoipa::path(put, path = "/api/viewpoints/{name}", tag = "participation", request_body = Viewpoint,
    params(("name" = String, Path, description = "Viewpoint name")), security(("bearer" = []), ()),
    responses(
        (status = 200, description = "Replaced", body = ListedViewpoint),
        (status = 201, description = "Created", body = ListedViewpoint),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 409, description = "The name belongs to a scene-file viewpoint", body = ErrorBody),
        (status = 422, description = "Bad name, camera or style", body = ErrorBody)))]
pub async fn put(
    _admin: Admin,
    State(state): State<AppState>,
    Path(name): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    store(&state, &name, body, false).await
}

/// Deletes a viewpoint of the admin API (admin).
#[utoipa::path(delete, path = "/api/viewpoints/{name}", tag = "participation",
    params(("name" = String, Path, description = "Viewpoint name")), security(("bearer" = []), ()),
    responses(
        (status = 204, description = "Deleted"),
        (status = 401, description = "Admin token missing or wrong", body = ErrorBody),
        (status = 403, description = "Refused by the admin guard", body = ErrorBody),
        (status = 404, description = "No such viewpoint of the admin API", body = ErrorBody),
        (status = 409, description = "A scene-file viewpoint", body = ErrorBody)))]
pub async fn delete(
    _admin: Admin,
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<StatusCode, ApiError> {
    let ready = state.ready().ok_or(ApiError::NotReady)?;
    if ready.participation.scene_viewpoints.iter().any(|v| v.name == name) {
        return Err(ApiError::Conflict(format!(
            "the viewpoint {:?} is defined in the scene file; remove it there",
            echo(&name)
        )));
    }
    if !state.participation().delete_viewpoint(&name).await.map_err(store_error)? {
        return Err(ApiError::NotFound(format!("no viewpoint {:?}", echo(&name))));
    }
    state.publish(LiveEvent::Viewpoint { change: Change::Removed, name });
    Ok(StatusCode::NO_CONTENT)
}
