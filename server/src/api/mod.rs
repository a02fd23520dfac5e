//! The HTTP server (`landsketch serve`): rendered views over REST (`/api/render`), live frame
//! streams over WebSocket (`/api/ws`), scene description, the data-layer store
//! (`/api/layers`), art maps (`/api/artmaps`), health, Prometheus metrics and an OpenAPI document. One render worker owns the GPU renderer; REST requests and WebSocket
//! sessions share it round-robin (see [`pool`]).

pub mod artmaps;
pub mod auth;
pub mod cache;
pub mod comments;
pub mod config;
pub mod connections;
pub mod error;
pub mod events;
pub mod export;
pub mod layers;
pub mod meetings;
pub mod metrics;
pub mod openapi;
pub mod pool;
pub mod ratelimit;
pub mod replicas;
pub mod routes;
pub mod view;
pub mod viewpoints;
pub mod ws;

pub use config::ServerConfig;
pub use error::ApiError;

use crate::fields::SceneGeo;
use crate::progress::{LoadProgress, Stage};
use crate::render::{Gpu, RenderError};
use crate::scene::{Scene, SceneError};
use crate::store::participation::{ParticipationError, ParticipationStore, SqlStore};
use crate::store::{Store, StoreError, StoreLimits};
use artmaps::ArtMaps;
use axum::Router;
use axum::extract::{DefaultBodyLimit, FromRef};
use axum::handler::HandlerWithoutStateExt;
use axum::http::{HeaderName, HeaderValue, Request, header};
use axum::routing::{MethodRouter, get, post};
use cache::RenderCache;
use metrics::Metrics;
use pool::RenderPool;
use sha2::{Digest, Sha256};
use std::future::Future;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};
use tokio::net::TcpListener;
use tokio::sync::watch;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::services::ServeDir;
use tower_http::trace::{DefaultOnFailure, DefaultOnResponse, TraceLayer};
use tracing::{Level, info};
use view::Limits;

/// Errors that stop the server.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// The listen address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind { addr: SocketAddr, source: std::io::Error },
    /// The data directory cannot be created.
    #[error("cannot create the data directory {path}: {source}")]
    DataDir { path: PathBuf, source: std::io::Error },
    /// The scene file cannot be read.
    #[error("{path}: cannot read scene file: {source}")]
    SceneFile { path: PathBuf, source: std::io::Error },
    /// The layer store in the data directory cannot be opened.
    #[error("cannot open the layer store: {0}")]
    Store(#[from] StoreError),
    /// The participation store (`--database-url`, or the SQLite file in the data directory)
    /// cannot be opened or migrated.
    #[error(transparent)]
    Participation(#[from] ParticipationError),
    /// The layer and art-map store shared with other replicas cannot be opened or synced.
    #[error(transparent)]
    Shared(#[from] crate::store::shared::SharedError),
    /// `--admin-token-file` or `--meeting-password-file` is unreadable or empty.
    #[error(transparent)]
    TokenFile(#[from] config::TokenFileError),
    /// A `--cors-origins` entry is not a valid origin.
    #[error("invalid CORS origin {0:?}")]
    CorsOrigin(String),
    /// The scene cannot be loaded.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// No GPU device.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Serving failed.
    #[error("server I/O error: {0}")]
    Io(#[from] std::io::Error),
}

/// What exists once the scene is loaded: the scene, the render queue and the cache.
pub struct Ready {
    /// The scene.
    pub scene: Arc<Scene>,
    /// Identifier of scene file, renderer version and adapter: part of every ETag.
    pub scene_id: String,
    /// Name of the graphics adapter.
    pub adapter: String,
    /// The render queue.
    pub pool: RenderPool,
    /// Encoded images of REST renders.
    pub cache: RenderCache,
    /// Where the scene lies, for placing uploaded layers; the error says why layers cannot be
    /// placed (a DEM CRS without EPSG code).
    pub geo: Result<Arc<SceneGeo>, String>,
    /// The renderer's art maps and which were uploaded (`/api/artmaps`).
    pub art: ArtMaps,
    /// The scene file's `[participation]` and `[[viewpoints]]`, and the rate limits.
    pub participation: comments::Participation,
}

struct Inner {
    config: ServerConfig,
    metrics: Metrics,
    store: Arc<Store>,
    participation: Arc<dyn ParticipationStore>,
    events: events::Events,
    started: Instant,
    ready: OnceLock<Ready>,
    /// How far loading the scene has come (`GET /api/health` while loading).
    loading: Arc<LoadProgress>,
    shutdown: watch::Sender<bool>,
    /// Permits for decoding uploads (`--upload-decodes`).
    decodes: Arc<tokio::sync::Semaphore>,
    /// Open meetings (presenter mode).
    meetings: meetings::Meetings,
    /// The database shared with other replicas (a PostgreSQL `--database-url`).
    replication: Option<replicas::Replication>,
}

/// State shared by every handler; cheap to clone.
#[derive(Clone)]
pub struct AppState(Arc<Inner>);

impl AppState {
    fn new(
        config: ServerConfig,
        store: Arc<Store>,
        participation: Arc<dyn ParticipationStore>,
        replication: Option<replicas::Replication>,
    ) -> AppState {
        let decodes = Arc::new(tokio::sync::Semaphore::new(config.upload_decodes));
        let metrics = Metrics::new();
        AppState(Arc::new(Inner {
            decodes,
            config,
            meetings: meetings::Meetings::new(metrics.clone(), participation.clone()),
            metrics,
            store,
            participation,
            events: events::Events::default(),
            started: Instant::now(),
            ready: OnceLock::new(),
            loading: Arc::default(),
            shutdown: watch::Sender::new(false),
            replication,
        }))
    }

    /// The configuration.
    pub fn config(&self) -> &ServerConfig {
        &self.0.config
    }

    /// The metrics.
    pub fn metrics(&self) -> &Metrics {
        &self.0.metrics
    }

    /// The data-layer store (opened from `--data-dir`).
    pub fn store(&self) -> &Arc<Store> {
        &self.0.store
    }

    /// The open meetings.
    pub fn meetings(&self) -> &meetings::Meetings {
        &self.0.meetings
    }

    /// The participation store: comments, likes, reports, viewpoints, meetings.
    pub fn participation(&self) -> &Arc<dyn ParticipationStore> {
        &self.0.participation
    }

    /// The live-event channel every WebSocket session listens to.
    pub fn events(&self) -> &events::Events {
        &self.0.events
    }

    /// Tells every WebSocket session about a change (see [`events`]).
    pub fn publish(&self, event: events::LiveEvent) {
        let Some(changed) = event.public() else { return };
        if let Some(replication) = &self.0.replication {
            replication.announce(&changed);
        }
        self.0.events.send(changed);
    }

    /// The database shared with other replicas, with a PostgreSQL `--database-url`.
    pub fn replication(&self) -> Option<&replicas::Replication> {
        self.0.replication.as_ref()
    }

    /// The loaded scene and renderer; `None` while loading.
    pub fn ready(&self) -> Option<&Ready> {
        self.0.ready.get()
    }

    /// The loading stage reached and the percent done, while the scene loads.
    pub fn loading(&self) -> Option<(Stage, f32)> {
        self.0.loading.current()
    }

    /// Time since the server started.
    pub fn uptime(&self) -> Duration {
        self.0.started.elapsed()
    }

    /// Image-size limits of views.
    pub fn limits(&self) -> Limits {
        Limits { max_width: self.0.config.max_width, max_height: self.0.config.max_height }
    }

    /// Waits for one of the `--upload-decodes` permits: decoding an upload (a layer file, an
    /// art-map PNG) holds one, so concurrent uploads cannot multiply the memory of a decode.
    pub async fn decode_permit(&self) -> Result<tokio::sync::OwnedSemaphorePermit, ApiError> {
        // Nothing closes the semaphore; a closed one would mean the server is going away.
        self.0.decodes.clone().acquire_owned().await.map_err(|_| ApiError::ShuttingDown)
    }

    /// A receiver that turns `true` when the server begins to shut down.
    pub fn shutdown_receiver(&self) -> watch::Receiver<bool> {
        self.0.shutdown.subscribe()
    }

    fn begin_shutdown(&self) {
        self.0.shutdown.send_replace(true);
    }
}

impl FromRef<AppState> for Metrics {
    fn from_ref(state: &AppState) -> Metrics {
        state.0.metrics.clone()
    }
}

/// The router with every endpoint and middleware (request ids, tracing, metrics, body limit,
/// CORS when configured).
pub fn router(state: AppState) -> Result<Router, ServerError> {
    let config = state.config();
    let request_id = HeaderName::from_static("x-request-id");
    let trace = TraceLayer::new_for_http()
        .make_span_with(|request: &Request<_>| {
            let id = request.headers().get("x-request-id").and_then(|v| v.to_str().ok()).unwrap_or_default();
            tracing::info_span!("request", method = %request.method(), uri = %request.uri(), id = %id)
        })
        .on_response(DefaultOnResponse::new().level(Level::INFO))
        .on_failure(DefaultOnFailure::new().level(Level::WARN));
    let mut router = Router::new()
        .route("/api/health", get(routes::health))
        .route("/api/scene", get(routes::scene))
        .route("/api/render", limited(get(routes::render_get).post(routes::render_post), config.body_limit))
        .route("/api/styles/resolve", limited(post(routes::resolve_styles), config.body_limit))
        .route("/api/auth", get(auth::check))
        .route("/api/cache/clear", limited(post(routes::cache_clear), config.body_limit))
        .route("/api/layers", limited(get(layers::list).post(layers::upload), config.max_upload))
        .route("/api/layers/{id}", get(layers::get).delete(layers::delete))
        .route("/api/layers/{id}/legend.png", get(layers::legend_png))
        .route("/api/layers/{id}/legend.json", get(layers::legend_json))
        .route("/api/artmaps", get(artmaps::list))
        .route(
            "/api/artmaps/{kind}/{index}",
            limited(get(artmaps::png).put(artmaps::put).delete(artmaps::delete), artmaps::MAX_ART_MAP_BYTES),
        )
        .route("/api/participation", get(comments::info))
        .route("/api/comments", limited(get(comments::list).post(comments::create), config.body_limit))
        .route("/api/comments/{id}", get(comments::get).delete(comments::delete))
        .route("/api/comments/{id}/like", limited(post(comments::like).delete(comments::unlike), config.body_limit))
        .route("/api/comments/{id}/report", limited(post(comments::report), config.body_limit))
        .route("/api/comments/{id}/approve", post(comments::approve))
        .route("/api/comments/{id}/hide", post(comments::hide))
        .route("/api/viewpoints", get(viewpoints::list))
        .route(
            "/api/viewpoints/{name}",
            limited(post(viewpoints::create).put(viewpoints::put).delete(viewpoints::delete), config.body_limit),
        )
        .route("/api/ws", get(ws::upgrade))
        .route("/api/meetings", limited(post(meetings::open), config.body_limit))
        .route("/api/meetings/{code}", get(meetings::get).delete(meetings::delete))
        .route("/api/meetings/{code}/qr.svg", get(meetings::qr))
        .route("/api/openapi.json", get(openapi::openapi_json))
        .route("/metrics", get(metrics::metrics_handler))
        // The browser UI at `/`; paths that are neither routes nor files get the JSON 404.
        .fallback_service(ServeDir::new(&config.web_dir).not_found_service(routes::not_found.into_service()))
        .method_not_allowed_fallback(routes::method_not_allowed)
        .layer(DefaultBodyLimit::max(config.body_limit))
        .layer(axum::middleware::from_fn_with_state(config.body_timeout(), connections::body_deadline))
        .layer(axum::middleware::from_fn_with_state(state.metrics().clone(), metrics::track_requests))
        .layer(trace)
        .layer(PropagateRequestIdLayer::new(request_id.clone()))
        .layer(SetRequestIdLayer::new(request_id, MakeRequestUuid));
    if !config.cors_origins.is_empty() {
        router = router.layer(cors(&config.cors_origins)?);
    }
    Ok(router.with_state(state))
}

/// A route taking bodies of at most `limit` bytes: the extractors' limit, and a
/// `Content-Length` above it refused up front.
fn limited(route: MethodRouter<AppState>, limit: usize) -> MethodRouter<AppState> {
    route
        .layer(DefaultBodyLimit::max(limit))
        .layer(axum::middleware::from_fn_with_state(limit, connections::refuse_oversized))
}

fn cors(origins: &[String]) -> Result<CorsLayer, ServerError> {
    let allow = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        let origins = origins
            .iter()
            .map(|o| HeaderValue::from_str(o.trim()).map_err(|_| ServerError::CorsOrigin(o.clone())))
            .collect::<Result<Vec<_>, _>>()?;
        AllowOrigin::list(origins)
    };
    Ok(CorsLayer::new()
        .allow_origin(allow)
        .allow_methods(tower_http::cors::Any)
        // Named, not `*`: browsers never count `Authorization` under a wildcard, so the admin
        // token could not be sent cross-origin.
        .allow_headers([header::AUTHORIZATION, header::CONTENT_TYPE, header::IF_NONE_MATCH])
        .expose_headers([header::ETAG, HeaderName::from_static("x-render-ms")]))
}

/// Identifies what an image depends on besides the request: the scene file, the renderer
/// version and the adapter.
fn scene_id(scene_file: &Path, adapter: &str) -> Result<String, ServerError> {
    let bytes =
        std::fs::read(scene_file).map_err(|source| ServerError::SceneFile { path: scene_file.to_owned(), source })?;
    let digest = Sha256::new()
        .chain_update(env!("CARGO_PKG_VERSION"))
        .chain_update([0])
        .chain_update(adapter)
        .chain_update([0])
        .chain_update(&bytes)
        .finalize();
    Ok(view::hex(&digest[..8]))
}

/// A bound server, ready to [`run`](Server::run).
pub struct Server {
    listener: TcpListener,
    state: AppState,
}

impl Server {
    /// Reads the admin token file (if any), creates the data directory, opens the layer store
    /// and the participation store in it (or at `--database-url`) and binds the listen address (port 0 picks a free port).
    pub async fn bind(mut config: ServerConfig) -> Result<Server, ServerError> {
        config.resolve_admin_token()?;
        std::fs::create_dir_all(&config.data_dir)
            .map_err(|source| ServerError::DataDir { path: config.data_dir.clone(), source })?;
        let dir = config.data_dir.clone();
        let limits = StoreLimits { max_upload_bytes: config.max_upload as u64, ..StoreLimits::default() };
        let store = tokio::task::spawn_blocking(move || Store::open_with_limits(&dir, limits))
            .await
            .map_err(std::io::Error::other)??;
        info!(dir = %config.data_dir.display(), layers = store.list().len(), "layer store opened");
        let participation = match &config.database_url {
            Some(url) => SqlStore::open(url).await?,
            None => SqlStore::open_in(&config.data_dir).await?,
        };
        let store = Arc::new(store);
        let replication = replicas::Replication::open(config.database_url.as_deref()).await?;
        if !config.web_dir.join("index.html").is_file() {
            tracing::warn!(dir = %config.web_dir.display(), "no index.html in the web directory: the browser UI is off");
        }
        let listener =
            TcpListener::bind(config.addr).await.map_err(|source| ServerError::Bind { addr: config.addr, source })?;
        Ok(Server { listener, state: AppState::new(config, store, Arc::new(participation), replication) })
    }

    /// The address the server listens on.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Loads the scene (health answers 503 meanwhile), opens the GPU and serves until
    /// `shutdown` completes; then stops accepting, closes WebSocket sessions, finishes
    /// in-flight renders and returns.
    pub async fn run(self, shutdown: impl Future<Output = ()> + Send + 'static) -> Result<(), ServerError> {
        self.serve(None, shutdown).await
    }

    /// Like [`run`](Server::run) with a scene and GPU loaded already (several servers in one
    /// process can share them).
    pub async fn run_with(
        self,
        scene: Arc<Scene>,
        gpu: Arc<Gpu>,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> Result<(), ServerError> {
        self.serve(Some((scene, gpu)), shutdown).await
    }

    async fn serve(
        self,
        loaded: Option<(Arc<Scene>, Arc<Gpu>)>,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> Result<(), ServerError> {
        let Server { listener, state } = self;
        let app = router(state.clone())?;
        let signal = {
            let state = state.clone();
            let mut stopping = state.shutdown_receiver();
            async move {
                tokio::select! {
                    () = shutdown => info!("shutdown requested"),
                    _ = stopping.wait_for(|s| *s) => {}
                }
                state.begin_shutdown();
            }
        };
        info!(addr = %listener.local_addr()?, "listening");
        tokio::spawn(signal);
        let header_timeout = state.config().header_timeout();
        let server = tokio::spawn(connections::serve(
            listener,
            app,
            header_timeout,
            state.config().send_buffer(),
            state.shutdown_receiver(),
        ));
        // Listening starts before the copy, so that nothing changed in between is missed.
        let synced = match replicas::subscribe(&state).await {
            Ok(listener) => {
                if let Some(listener) = listener {
                    tokio::spawn(replicas::listen(state.clone(), listener));
                }
                replicas::sync(&state).await
            }
            Err(error) => Err(error),
        };
        let loaded = match synced {
            Ok(()) => load(state.clone(), loaded).await,
            Err(error) => Err(error.into()),
        };
        if loaded.is_err() {
            state.begin_shutdown();
        }
        let served = server.await.map_err(std::io::Error::other)?;
        // HTTP requests are done; WebSocket sessions saw the shutdown signal and close.
        let deadline = Instant::now() + ws::CLOSE_GRACE;
        while state.metrics().sessions.get() > 0 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let pool_state = state.clone();
        tokio::task::spawn_blocking(move || {
            if let Some(ready) = pool_state.ready() {
                ready.pool.join();
            }
        })
        .await
        .map_err(std::io::Error::other)?;
        info!("server stopped");
        loaded?;
        Ok(served?)
    }
}

/// Loads the scene and GPU (unless given), starts the render worker and marks the server
/// ready.
async fn load(state: AppState, loaded: Option<(Arc<Scene>, Arc<Gpu>)>) -> Result<(), ServerError> {
    let runtime = tokio::runtime::Handle::current();
    tokio::task::spawn_blocking(move || {
        let started = Instant::now();
        let config = state.config();
        let (scene, gpu) = match loaded {
            Some(loaded) => loaded,
            None => (Arc::new(Scene::load_with(&config.scene, &*state.0.loading)?), Arc::new(Gpu::new()?)),
        };
        let adapter = gpu.adapter_info.name.clone();
        let scene_id = scene_id(&config.scene, &adapter)?;
        let metrics = state.metrics().clone();
        let queue_depth = usize::try_from(config.queue_depth).unwrap_or(usize::MAX);
        let options =
            crate::render::RenderOptions { progress: Some(state.0.loading.clone()), ..config.render_options()? };
        let pool = RenderPool::start(
            gpu,
            scene.clone(),
            state.store().clone(),
            options,
            queue_depth,
            metrics.clone(),
            runtime,
        )?;
        let participation = comments::load_settings(&config.scene, &scene)?;
        let art = ArtMaps::restore(&pool, state.store());
        let cache = RenderCache::new(config.cache_bytes, metrics);
        let geo = SceneGeo::from_terrain(&scene.terrain).map(Arc::new).map_err(|e| e.to_string());
        if let Err(e) = &geo {
            tracing::warn!(error = %e, "uploaded data layers cannot be placed in this scene");
        }
        info!(
            scene = %scene.name,
            plants = scene.plant_count(),
            %adapter,
            ms = started.elapsed().as_millis() as u64,
            "scene ready"
        );
        // `load` runs once per state, so the cell is empty.
        let _ = state.0.ready.set(Ready { scene, scene_id, adapter, pool, cache, geo, art, participation });
        Ok(())
    })
    .await
    .map_err(std::io::Error::other)?
}
