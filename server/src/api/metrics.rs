//! Prometheus metrics of one server (`GET /metrics`, OpenMetrics text): HTTP requests by route
//! and status, render and encode times, queue depth, WebSocket sessions and frames, cache use.

use axum::extract::{MatchedPath, Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{Histogram, exponential_buckets};
use prometheus_client::registry::Registry;
use std::sync::Arc;
use std::time::Instant;

/// Labels of HTTP request metrics: the route pattern (`unmatched` for unknown paths), the
/// method and the status code.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct HttpLabels {
    /// Route pattern such as `/api/render`.
    pub route: String,
    /// HTTP method.
    pub method: String,
    /// Status code.
    pub status: u16,
}

/// Label of render metrics: `rest`, `interactive` or `still`.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct KindLabels {
    /// What the frame is for.
    pub kind: &'static str,
}

/// Label of meeting metrics: the join code.
#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct MeetingLabels {
    /// The meeting's join code.
    pub meeting: String,
}

type HistogramFamily<L> = Family<L, Histogram, fn() -> Histogram>;

fn seconds_histogram() -> Histogram {
    Histogram::new(exponential_buckets(0.001, 2.0, 16))
}

/// Every metric of a server; cheap to clone (the metrics are shared handles).
#[derive(Clone)]
pub struct Metrics {
    registry: Arc<Registry>,
    /// HTTP requests by route, method and status.
    pub http_requests: Family<HttpLabels, Counter>,
    /// Wall time of HTTP requests by route.
    pub http_seconds: HistogramFamily<[(&'static str, String); 1]>,
    /// Time the renderer spends on a frame, by kind.
    pub render_seconds: HistogramFamily<KindLabels>,
    /// Time spent encoding a frame as PNG or JPEG.
    pub encode_seconds: Histogram,
    /// Time of each render pass, from sampled frames (`--profile-every`).
    pub pass_seconds: HistogramFamily<[(&'static str, &'static str); 1]>,
    /// Renders waiting for the renderer.
    pub queue_depth: Gauge,
    /// REST renders refused because the queue was full.
    pub queue_rejected: Counter,
    /// Open WebSocket sessions that render their own view (the `--max-sessions` slots).
    pub sessions: Gauge,
    /// Open WebSocket sessions following a meeting (they render nothing; `--max-followers`).
    pub followers: Gauge,
    /// WebSocket sessions opened since the start.
    pub sessions_opened: Counter,
    /// Frames sent over WebSockets, by kind.
    pub frames_sent: Family<KindLabels, Counter>,
    /// WebSocket client messages answered with an error.
    pub ws_bad_messages: Counter,
    /// Open meetings.
    pub meetings: Gauge,
    /// Followers of each open meeting.
    pub meeting_followers: Family<MeetingLabels, Gauge>,
    /// Frames rendered for each open meeting (once each, shared by all followers).
    pub meeting_renders: Family<MeetingLabels, Counter>,
    /// Presenter frames sent to followers.
    pub meeting_frames_sent: Counter,
    /// Render-cache lookups that found the image.
    pub cache_hits: Counter,
    /// Render-cache lookups that did not.
    pub cache_misses: Counter,
    /// Bytes of encoded images in the render cache.
    pub cache_bytes: Gauge,
    /// Images in the render cache.
    pub cache_entries: Gauge,
}

impl Default for Metrics {
    fn default() -> Self {
        Metrics::new()
    }
}

impl Metrics {
    /// Registers every metric under the `landsketch_` prefix in a registry of its own.
    pub fn new() -> Metrics {
        let mut registry = Registry::with_prefix("landsketch");
        let metrics = Metrics {
            registry: Arc::default(),
            http_requests: Family::default(),
            http_seconds: Family::new_with_constructor(seconds_histogram),
            render_seconds: Family::new_with_constructor(seconds_histogram),
            encode_seconds: seconds_histogram(),
            pass_seconds: Family::new_with_constructor(seconds_histogram),
            queue_depth: Gauge::default(),
            queue_rejected: Counter::default(),
            sessions: Gauge::default(),
            followers: Gauge::default(),
            sessions_opened: Counter::default(),
            frames_sent: Family::default(),
            ws_bad_messages: Counter::default(),
            meetings: Gauge::default(),
            meeting_followers: Family::default(),
            meeting_renders: Family::default(),
            meeting_frames_sent: Counter::default(),
            cache_hits: Counter::default(),
            cache_misses: Counter::default(),
            cache_bytes: Gauge::default(),
            cache_entries: Gauge::default(),
        };
        let r = &mut registry;
        r.register("http_requests", "HTTP requests by route, method and status", metrics.http_requests.clone());
        r.register("http_request_seconds", "HTTP request wall time by route", metrics.http_seconds.clone());
        r.register("render_seconds", "Renderer time per frame by kind", metrics.render_seconds.clone());
        r.register("encode_seconds", "PNG/JPEG encoding time per frame", metrics.encode_seconds.clone());
        r.register(
            "render_pass_seconds",
            "Time per render pass (cull, geometry, prefilter, contour, data, compose, readback) of sampled frames",
            metrics.pass_seconds.clone(),
        );
        r.register("render_queue_depth", "Renders waiting for the renderer", metrics.queue_depth.clone());
        r.register("render_queue_rejected", "REST renders refused with 503", metrics.queue_rejected.clone());
        r.register("ws_sessions", "Open WebSocket sessions rendering their own view", metrics.sessions.clone());
        r.register("ws_followers", "Open WebSocket sessions following a meeting", metrics.followers.clone());
        r.register("ws_sessions_opened", "WebSocket sessions opened", metrics.sessions_opened.clone());
        r.register("ws_frames_sent", "Frames sent over WebSockets by kind", metrics.frames_sent.clone());
        r.register("ws_bad_messages", "WebSocket messages answered with an error", metrics.ws_bad_messages.clone());
        r.register("meetings", "Open meetings", metrics.meetings.clone());
        r.register("meeting_followers", "Followers of each open meeting", metrics.meeting_followers.clone());
        r.register("meeting_renders", "Frames rendered for each open meeting", metrics.meeting_renders.clone());
        r.register("meeting_frames_sent", "Presenter frames sent to followers", metrics.meeting_frames_sent.clone());
        r.register("cache_hits", "Render-cache hits", metrics.cache_hits.clone());
        r.register("cache_misses", "Render-cache misses", metrics.cache_misses.clone());
        r.register("cache_bytes", "Bytes of images in the render cache", metrics.cache_bytes.clone());
        r.register("cache_entries", "Images in the render cache", metrics.cache_entries.clone());
        Metrics { registry: Arc::new(registry), ..metrics }
    }

    /// The metrics in the OpenMetrics text format.
    pub fn encode(&self) -> String {
        let mut text = String::new();
        prometheus_client::encoding::text::encode(&mut text, &self.registry).expect("writing to a String cannot fail");
        text
    }
}

/// Middleware counting every request by route pattern, method and status.
pub async fn track_requests(State(metrics): State<Metrics>, request: Request, next: Next) -> Response {
    let route = request.extensions().get::<MatchedPath>().map_or("unmatched", MatchedPath::as_str).to_owned();
    let method = request.method().to_string();
    let started = Instant::now();
    let response = next.run(request).await;
    metrics.http_seconds.get_or_create(&[("route", route.clone())]).observe(started.elapsed().as_secs_f64());
    metrics.http_requests.get_or_create(&HttpLabels { route, method, status: response.status().as_u16() }).inc();
    response
}

/// `GET /metrics`: every metric in the OpenMetrics text format.
#[utoipa::path(get, path = "/metrics", tag = "operations",
    responses((status = 200, description = "Prometheus/OpenMetrics text", content_type = "application/openmetrics-text", body = String)))]
pub async fn metrics_handler(State(metrics): State<Metrics>) -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/openmetrics-text; version=1.0.0; charset=utf-8")], metrics.encode())
}
