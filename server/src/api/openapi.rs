//! The OpenAPI 3 document of the server (`GET /api/openapi.json`).

use super::{artmaps, auth, comments, error, events, layers, meetings, metrics, routes, view, viewpoints, ws};
use axum::Json;
use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityScheme};
use utoipa::{Modify, OpenApi};

/// Every endpoint, request and response of the server.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "landsketch",
        description = "Pen-and-ink renderings of GIS landscapes over HTTP and WebSocket. Rendering, the WebSocket and reading layers are public; write endpoints (layer upload and delete, art-map upload and delete, cache clearing, comment moderation, viewpoints, ending a meeting) need `Authorization: Bearer <token>` when the server has an admin token, else a loopback client."
    ),
    paths(
        routes::health,
        routes::scene,
        routes::render_get,
        routes::render_post,
        routes::resolve_styles,
        routes::cache_clear,
        auth::check,
        layers::upload,
        layers::list,
        layers::get,
        layers::delete,
        layers::legend_png,
        layers::legend_json,
        artmaps::list,
        artmaps::png,
        artmaps::put,
        artmaps::delete,
        comments::info,
        comments::create,
        comments::list,
        comments::get,
        comments::like,
        comments::unlike,
        comments::report,
        comments::approve,
        comments::hide,
        comments::delete,
        viewpoints::list,
        viewpoints::create,
        viewpoints::put,
        viewpoints::delete,
        ws::upgrade,
        meetings::open,
        meetings::get,
        meetings::qr,
        meetings::delete,
        metrics::metrics_handler,
        openapi_json,
    ),
    components(schemas(
        ws::ClientMessage,
        ws::ServerMessage,
        events::Changed,
        error::ErrorBody,
        view::ViewParams,
        meetings::MeetingInfo,
        meetings::OpenMeeting
    )),
    modifiers(&BearerToken),
    tags(
        (name = "render", description = "Rendered views: REST and WebSocket"),
        (name = "scene", description = "The scene"),
        (name = "layers", description = "Environment data layers: upload, list, legends, delete"),
        (name = "art maps", description = "Tonal and silhouette art maps: list, download, replace or add, restore"),
        (name = "participation", description = "Comments pinned in the landscape, likes, reports, moderation, export; viewpoints"),
        (name = "meetings", description = "Presenter mode: a session presents, followers join with a code and see its frames"),
        (name = "operations", description = "Health, metrics, cache, this document"),
    )
)]
pub struct ApiDoc;

/// Adds the `bearer` security scheme of the admin endpoints.
struct BearerToken;

impl Modify for BearerToken {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme("bearer", SecurityScheme::Http(Http::new(HttpAuthScheme::Bearer)));
    }
}

/// This document.
#[utoipa::path(get, path = "/api/openapi.json", tag = "operations",
    responses((status = 200, description = "OpenAPI 3 document", content_type = "application/json")))]
pub async fn openapi_json() -> Json<utoipa::openapi::OpenApi> {
    Json(ApiDoc::openapi())
}
