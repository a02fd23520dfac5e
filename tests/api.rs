//! Integration tests of `landsketch serve`: real servers on loopback ports rendering the sample
//! scene at small sizes, exercised over HTTP (reqwest) and WebSocket (tokio-tungstenite).

mod common;

use clap::Parser;
use common::server::{TestServer, client, get, json_of, loaded, raw_exchange};
use common::ws::{Incoming, Socket, connect, next_frame, receive, send};
use futures_util::{SinkExt, StreamExt};
use landsketch::api::view::{ImageFormat, Limits, Source, ViewParams};
use landsketch::api::{Server, ServerConfig};
use landsketch::render::Style;
use reqwest::StatusCode;
use serde_json::{Value, json};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

/// The data directory of the servers in this file.
fn data_dir() -> std::path::PathBuf {
    std::env::temp_dir().join("landsketch-api-tests")
}

trait Servers {
    fn shared() -> &'static TestServer;
    fn tiny_queue() -> &'static TestServer;
    fn guarded() -> &'static TestServer;
}

impl Servers for TestServer {
    /// The shared server with the default configuration.
    fn shared() -> &'static TestServer {
        static SHARED: OnceLock<TestServer> = OnceLock::new();
        SHARED.get_or_init(|| TestServer::start(&data_dir(), |_| {}))
    }

    /// A shared server with a render queue of 2 and no cache.
    fn tiny_queue() -> &'static TestServer {
        static TINY: OnceLock<TestServer> = OnceLock::new();
        TINY.get_or_init(|| {
            TestServer::start(&data_dir(), |c| {
                c.queue_depth = 2;
                c.cache_bytes = 0;
            })
        })
    }

    /// A shared server with an admin token, one WebSocket session at most and a 1 s idle timeout.
    fn guarded() -> &'static TestServer {
        static GUARDED: OnceLock<TestServer> = OnceLock::new();
        GUARDED.get_or_init(|| {
            TestServer::start(&data_dir(), |c| {
                c.admin_token = Some("s3cret".into());
                c.cors_origins = vec!["https://maps.example.org".into()];
                c.max_sessions = 1;
                c.idle_timeout_s = 1;
            })
        })
    }
}

async fn post(url: &str, body: impl Into<String>) -> reqwest::Response {
    client().post(url).header("content-type", "application/json").body(body.into()).send().await.expect("POST")
}

/// Asserts a JSON error with `status`, `code` and (when given) `parameter`.
async fn assert_error(response: reqwest::Response, status: u16, code: &str, parameter: Option<&str>) -> Value {
    let url = response.url().to_string();
    assert_eq!(response.status().as_u16(), status, "{url}");
    let body = json_of(response).await;
    let error = &body["error"];
    assert_eq!(error["code"], code, "{url}: {body}");
    assert!(error["message"].as_str().is_some_and(|m| !m.is_empty()), "{url}: {body}");
    if let Some(parameter) = parameter {
        assert_eq!(error["parameter"], parameter, "{url}: {body}");
    }
    body
}

async fn metric(server: &TestServer, name: &str) -> f64 {
    let text = get(&server.url("/metrics")).await.text().await.expect("metrics");
    text.lines()
        .filter(|l| l.starts_with(name) && (l.len() == name.len() || l[name.len()..].starts_with([' ', '{'])))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

const VIEW: &str = "x=205&y=185&yaw=268&pitch=-1.5&width=160&height=120";

// ---------------------------------------------------------------------------------------------
// REST

#[tokio::test]
async fn health_scene_metrics_and_openapi_describe_the_server() {
    let server = TestServer::shared();
    let response = get(&server.url("/api/health")).await;
    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.headers().contains_key("x-request-id"));
    let health = json_of(response).await;
    assert_eq!(health["status"], "ok");
    assert_eq!(health["scene"], "Boulder foothills");
    assert!(health["adapter"].as_str().is_some_and(|a| !a.is_empty()), "{health}");
    assert!(health["uptime_s"].as_f64().is_some_and(|u| u >= 0.0));

    let scene = json_of(get(&server.url("/api/scene")).await).await;
    assert_eq!(scene["name"], "Boulder foothills");
    let layers = scene["layers"].as_array().expect("layers");
    assert_eq!(
        layers.iter().map(|l| l["name"].as_str().unwrap_or_default()).collect::<Vec<_>>(),
        ["existing", "planned"]
    );
    assert!(layers.iter().all(|l| l["plants"].as_u64().is_some_and(|n| n > 0)), "{scene}");
    // The ground's land-cover classes present in the scene, for the legend.
    let ground: Vec<(&str, &str)> = scene["ground"]
        .as_array()
        .expect("ground")
        .iter()
        .map(|g| (g["name"].as_str().unwrap_or_default(), g["color"].as_str().unwrap_or_default()))
        .collect();
    assert_eq!(ground, [("forest", "#3f5d3c"), ("shrubland", "#939056"), ("herbaceous", "#b3b86f")]);
    assert_eq!(scene["default_camera"]["yaw"], 268.0);
    assert!(scene["extent"]["min"][0].as_f64().unwrap_or(0.0) < scene["extent"]["max"][0].as_f64().unwrap_or(0.0));
    assert_eq!(scene["sun"]["azimuth"], 165.0);
    let default_style: Value =
        serde_json::from_str(&serde_json::to_string(&Style::default()).expect("JSON")).expect("style JSON");
    assert_eq!(scene["default_style"], default_style);
    assert_eq!(scene["formats"], json!(["png", "jpeg"]));
    assert_eq!(scene["max_width"], 2048);

    let openapi = json_of(get(&server.url("/api/openapi.json")).await).await;
    assert!(openapi["openapi"].as_str().is_some_and(|v| v.starts_with("3.")), "{openapi}");
    for (path, method) in [
        ("/api/health", "get"),
        ("/api/scene", "get"),
        ("/api/render", "get"),
        ("/api/render", "post"),
        ("/api/cache/clear", "post"),
        ("/api/ws", "get"),
        ("/api/openapi.json", "get"),
        ("/metrics", "get"),
    ] {
        assert!(openapi["paths"][path][method].is_object(), "OpenAPI lacks {method} {path}");
    }
    assert!(openapi["components"]["schemas"]["ClientMessage"].is_object());

    let metrics = get(&server.url("/metrics")).await;
    assert!(metrics.headers()["content-type"].to_str().is_ok_and(|t| t.starts_with("application/openmetrics-text")));
    let text = metrics.text().await.expect("metrics text");
    for name in [
        "landsketch_http_requests_total{",
        "landsketch_render_queue_depth ",
        "landsketch_ws_sessions ",
        "landsketch_cache_hits_total ",
    ] {
        assert!(text.contains(name), "metrics lack {name}:\n{text}");
    }
    assert!(text.contains(r#"route="/api/scene",method="GET",status="200""#), "{text}");

    // The first frame of a renderer is always a sampled one: its passes reach the metrics.
    let render = get(&server.url(&format!("/api/render?{VIEW}"))).await;
    assert_eq!(render.status().as_u16(), 200);
    for pass in ["cull", "geometry", "contour", "compose", "readback"] {
        let count = metric(server, &format!("landsketch_render_pass_seconds_count{{pass=\"{pass}\"}}")).await;
        assert!(count >= 1.0, "no {pass} timing in the metrics");
    }
}

/// The scene's `[about]` and the layers' extents (the browser's welcome, "go to the plan"),
/// and `GET /api/auth`, the planner login's check: 200 with the token, 401 without or wrong;
/// without a configured token, 200 for a loopback client.
#[tokio::test]
async fn scene_about_layer_extents_and_the_planner_login_check() {
    let server = TestServer::shared();
    let scene = json_of(get(&server.url("/api/scene")).await).await;
    let about = &scene["about"];
    assert_eq!(about["plan_layer"], "planned");
    assert!(about["title"].as_str().is_some_and(|t| t.contains("Boulder")), "{about}");
    for key in ["description", "plan_summary", "attribution"] {
        assert!(about[key].as_str().is_some_and(|t| t.len() > 20), "{key}: {about}");
    }
    let (min, max) = (&scene["extent"]["min"], &scene["extent"]["max"]);
    let planned = scene["layers"].as_array().and_then(|l| l.iter().find(|l| l["name"] == "planned")).expect("planned");
    let extent = &planned["extent"];
    for axis in 0..2 {
        let (lo, hi) = (extent["min"][axis].as_f64().expect("min"), extent["max"][axis].as_f64().expect("max"));
        assert!(min[axis].as_f64() <= Some(lo) && lo < hi && Some(hi) <= max[axis].as_f64(), "{extent} in {min} {max}");
    }

    let open = json_of(get(&server.url("/api/auth")).await).await;
    assert_eq!(open, json!({"token_required": false}), "no token configured: loopback is admitted");
    let guarded = TestServer::guarded();
    let ask = |token: Option<&'static str>| {
        let mut request = client().get(guarded.url("/api/auth"));
        if let Some(token) = token {
            request = request.bearer_auth(token);
        }
        request.send()
    };
    let admitted = ask(Some("s3cret")).await.expect("auth");
    assert_eq!(admitted.status().as_u16(), 200);
    assert_eq!(json_of(admitted).await, json!({"token_required": true}));
    for wrong in [None, Some("s3cre"), Some("S3cret")] {
        let refused = ask(wrong).await.expect("auth");
        assert_error(refused, 401, "unauthorized", None).await;
    }
}

#[tokio::test]
async fn get_and_post_render_the_same_bytes_and_the_link_round_trips() {
    let server = TestServer::shared();
    let got = get(&server.url(&format!("/api/render?{VIEW}&style=%7B%22contour_threshold%22%3A0.4%7D"))).await;
    assert_eq!(got.status(), StatusCode::OK);
    assert_eq!(got.headers()["content-type"], "image/png");
    let etag = got.headers()["etag"].to_str().expect("etag").to_owned();
    let got = got.bytes().await.expect("image");
    let image = image::load_from_memory(&got).expect("PNG");
    assert_eq!((image.width(), image.height()), (160, 120));

    let body = json!({
        "camera": {"position": [205, 185], "yaw": 268, "pitch": -1.5},
        "width": 160, "height": 120, "style": {"contour_threshold": 0.4}
    });
    let posted = post(&server.url("/api/render"), body.to_string()).await;
    assert_eq!(posted.status(), StatusCode::OK);
    assert_eq!(posted.headers()["etag"].to_str().ok(), Some(etag.as_str()));
    let link = posted.headers()["content-location"].to_str().expect("link").to_owned();
    assert_eq!(posted.bytes().await.expect("image"), got, "GET and POST differ");

    // The normalized link of the POST renders the same image again.
    let linked = get(&server.url(&link)).await;
    assert_eq!(linked.headers()["etag"].to_str().ok(), Some(etag.as_str()), "{link}");
    assert_eq!(linked.bytes().await.expect("image"), got);

    let jpeg = get(&server.url(&format!("/api/render?{VIEW}&format=jpeg&quality=70"))).await;
    assert_eq!(jpeg.status(), StatusCode::OK);
    assert_eq!(jpeg.headers()["content-type"], "image/jpeg");
    let jpeg = image::load_from_memory(&jpeg.bytes().await.expect("jpeg")).expect("JPEG");
    assert_eq!((jpeg.width(), jpeg.height()), (160, 120));
}

#[tokio::test]
async fn etag_gives_304_and_repeats_come_from_the_cache() {
    let server = TestServer::shared();
    let url = server.url("/api/render?x=150&y=200&yaw=250&width=96&height=72");
    let first = get(&url).await;
    assert_eq!(first.status(), StatusCode::OK);
    let etag = first.headers()["etag"].clone();
    let bytes = first.bytes().await.expect("image");

    let hits = metric(server, "landsketch_cache_hits_total").await;
    let second = get(&url).await;
    assert_eq!(second.headers()["x-cache"], "hit");
    assert_eq!(second.bytes().await.expect("image"), bytes);
    assert!(metric(server, "landsketch_cache_hits_total").await >= hits + 1.0);

    let revalidated = client().get(&url).header("if-none-match", etag.clone()).send().await.expect("GET");
    assert_eq!(revalidated.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(revalidated.headers()["etag"], etag);
    assert!(revalidated.bytes().await.expect("body").is_empty());
    let other = client().get(&url).header("if-none-match", "\"something-else\"").send().await.expect("GET");
    assert_eq!(other.status(), StatusCode::OK);
}

#[tokio::test]
async fn bad_requests_get_json_errors_naming_the_parameter() {
    let server = TestServer::shared();
    let render = |query: &str| server.url(&format!("/api/render?{query}"));
    for (query, status, code, parameter) in [
        ("width=4096&height=100", 413, "too_large", Some("width")),
        ("width=100&height=5000", 413, "too_large", Some("height")),
        ("width=0", 422, "invalid_parameter", Some("width")),
        ("width=abc", 400, "bad_request", Some("width")),
        ("pitch=100", 422, "invalid_parameter", Some("pitch")),
        ("fov=0", 422, "invalid_parameter", Some("fov")),
        ("x=1", 422, "invalid_parameter", Some("y")),
        ("x=99999&y=0", 422, "invalid_parameter", Some("x")),
        ("x=0&y=0&z=100", 422, "invalid_parameter", Some("z")),
        ("format=webp", 422, "invalid_parameter", Some("format")),
        ("format=jpeg&quality=0", 422, "invalid_parameter", Some("quality")),
        ("style=%7B%22ambient%22%3A2%7D", 422, "invalid_parameter", Some("style.ambient")),
        ("style=%7B%22ambient%22%3A%22dark%22%7D", 422, "invalid_parameter", Some("style.ambient")),
        ("style=%7B%22no_such_field%22%3A1%7D", 422, "invalid_parameter", None),
        ("style=%5B1%5D", 422, "invalid_parameter", Some("style")),
        ("style=%7Bnot-json", 400, "bad_request", Some("style")),
        ("colour=red", 400, "bad_request", None),
        ("yaw=1&yaw=2", 400, "bad_request", None),
        ("preset=winter", 404, "not_found", None),
    ] {
        let body = assert_error(get(&render(query)).await, status, code, parameter).await;
        if query.starts_with("format=webp") {
            assert!(body["error"]["message"].as_str().is_some_and(|m| m.contains("png, jpeg")), "{body}");
        }
        if query.contains("z=100") {
            let message = body["error"]["message"].as_str().unwrap_or_default();
            assert!(message.contains("below the terrain") && message.contains("eye_height"), "{body}");
        }
        if query.contains("no_such_field") {
            assert!(body["error"]["message"].as_str().is_some_and(|m| m.contains("no_such_field")), "{body}");
        }
    }
    let url = server.url("/api/render");
    assert_error(post(&url, "{not json").await, 400, "bad_request", None).await;
    assert_error(post(&url, r#"{"width": "wide"}"#).await, 422, "invalid_parameter", Some("width")).await;
    assert_error(post(&url, r#"{"camera": {"pitch": -91}}"#).await, 422, "invalid_parameter", Some("camera.pitch"))
        .await;
    assert_error(
        post(&url, r#"{"camera": {"position": [1]}}"#).await,
        422,
        "invalid_parameter",
        Some("camera.position"),
    )
    .await;
    assert_error(post(&url, r#"{"camera": {"zoom": 2}}"#).await, 422, "invalid_parameter", None).await;
    assert_error(post(&url, r#"{"style": {"ambient": 2}}"#).await, 422, "invalid_parameter", Some("style.ambient"))
        .await;
    assert_error(post(&url, r#"{"width": 3000}"#).await, 413, "too_large", Some("width")).await;
    // A body announced beyond the limit is refused before it is sent (the server does not read
    // it, so a client still writing it may see the connection close instead of the answer).
    let huge = format!(
        "POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        2u64 << 20
    );
    let (received, _) = raw_exchange(server, huge.as_bytes(), std::time::Duration::from_secs(10)).await;
    assert!(received.starts_with("HTTP/1.1 413") && received.contains("too_large"), "{received}");
    assert!(received.contains(r#""parameter":"body""#), "{received}");

    assert_error(get(&server.url("/api/nothing-here")).await, 404, "not_found", None).await;
    let deleted = client().delete(&url).send().await.expect("DELETE");
    assert_error(deleted, 405, "method_not_allowed", None).await;
    assert_error(get(&server.url("/api/ws")).await, 400, "bad_request", None).await;
}

/// Client input echoed in an error message is cut to a readable length: a 500 kB preset or
/// layer name comes back as a few dozen characters and `…`.
#[tokio::test]
async fn error_messages_bound_the_client_input_they_echo() {
    let server = TestServer::shared();
    let url = server.url("/api/render");
    let long = "p".repeat(500_000);
    for (body, status, code) in [
        (json!({ "preset": long }), 404, "not_found"),
        (json!({ "layer_styles": { long.as_str(): { "ambient": 0.5 } } }), 422, "invalid_parameter"),
        (json!({ "style": { long.as_str(): 1 } }), 422, "invalid_parameter"),
    ] {
        let body = assert_error(post(&url, body.to_string()).await, status, code, None).await;
        let message = body["error"]["message"].as_str().expect("message");
        // The echo is cut; the rest of a message (serde's list of the style's fields) may be long.
        assert!(
            !message.contains(&"p".repeat(100)) && message.len() < 4000 && message.contains('…'),
            "{} bytes: {}",
            message.len(),
            message.chars().take(200).collect::<String>()
        );
        let parameter = body["error"]["parameter"].as_str().unwrap_or_default();
        assert!(parameter.len() < 200, "parameter of {} bytes", parameter.len());
    }
}

#[tokio::test]
async fn a_view_request_round_trips_through_query_parameters() {
    let (scene, _) = loaded();
    let limits = Limits { max_width: 2048, max_height: 2048 };
    let dir = tempfile::tempdir().expect("temp dir");
    let store = &landsketch::store::Store::open(dir.path()).expect("store");
    for body in [
        json!({}),
        json!({"camera": {"position": [205.25, 185.5]}, "width": 160, "height": 120}),
        json!({"camera": {"position": [0, -1500, 3000], "yaw": 12.3, "pitch": -35, "fov": 45}, "format": "jpeg"}),
        json!({"camera": {"roll": -12.5}}),
        json!({"camera": {"mode": "plan", "center": [10.5, -20], "width": 500, "yaw": 30}, "width": 64}),
        json!({"camera": {"mode": "plan"}}),
        json!({"camera": {"eye_height": 12}, "format": "jpg", "quality": 55, "style": {"contour_threshold": 0.35, "ink": [0.1, 0.2, 0.3]}}),
    ] {
        let params: ViewParams = serde_json::from_value(body.clone()).expect("body");
        let view = params.normalize(scene, store, limits, Source::Body).expect("valid view");
        // The JSON body as query parameters is the same view ...
        let from_query = ViewParams::from_query(&params.to_query()).expect("query");
        assert_eq!(from_query.normalize(scene, store, limits, Source::Query).expect("valid"), view, "{body}");
        // ... and so is the normalized view's own link and body.
        let link = view.to_params().to_query();
        let again = ViewParams::from_query(&link).expect("link").normalize(scene, store, limits, Source::Query);
        assert_eq!(again.expect("valid"), view, "{link}");
        let body = serde_json::to_value(view.to_params()).expect("serializes");
        let again: ViewParams = serde_json::from_value(body).expect("body");
        assert_eq!(again.normalize(scene, store, limits, Source::Body).expect("valid"), view);
        assert_eq!(
            view.etag("scene"),
            again.normalize(scene, store, limits, Source::Body).expect("valid").etag("scene")
        );
    }
    let rolled: ViewParams = serde_json::from_value(json!({"camera": {"roll": 190}})).expect("body");
    assert!(rolled.normalize(scene, store, limits, Source::Body).is_err(), "roll beyond 180 degrees accepted");
    let default = ViewParams::default().normalize(scene, store, limits, Source::Body).expect("default");
    assert_eq!(default.camera, scene.default_camera);
    assert_eq!((default.width, default.height, default.format), (1024, 768, ImageFormat::Png));
}

#[tokio::test]
async fn a_full_queue_answers_503_with_retry_after() {
    let server = TestServer::tiny_queue();
    let requests = (0..8).map(|i| get_owned(server.url(&format!("/api/render?yaw={}&width=320&height=240", i * 40))));
    let responses = futures_util::future::join_all(requests).await;
    let mut busy = 0;
    for response in responses {
        match response.status().as_u16() {
            200 => {}
            503 => {
                busy += 1;
                let retry = response.headers()["retry-after"].to_str().expect("retry-after").parse::<u32>();
                assert!(retry.is_ok_and(|s| s >= 1));
                assert_error(response, 503, "busy", None).await;
            }
            other => panic!("unexpected status {other}"),
        }
    }
    assert!(busy >= 1, "8 simultaneous renders with a queue of 2 should see a 503");
    assert!(metric(server, "landsketch_render_queue_rejected_total").await >= f64::from(busy));
}

async fn get_owned(url: String) -> reqwest::Response {
    get(&url).await
}

/// What the REST render queue promises under a burst far larger than it: no more than
/// `queue_depth` renders ever wait; a render is refused only while they do, with 503 `busy`
/// and a Retry-After of the time they take; every accepted render is rendered (a PNG of the
/// size asked for) and every refusal counted; the server answers `/api/health` during the
/// burst and renders again after it.
#[tokio::test]
async fn a_burst_of_renders_queues_at_most_queue_depth_and_refuses_the_rest() {
    const REQUESTS: usize = 200;
    const QUEUE: usize = 2;
    // A server of its own, so that its counters and queue hold only this burst.
    let data = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(data.path(), |c| {
        c.queue_depth = u32::try_from(QUEUE).expect("small");
        c.cache_bytes = 0;
    });
    let health_url = server.url("/api/health");
    let health = || async { json_of(get(&health_url).await).await };
    assert_eq!(health().await["queue_depth"], 0);
    let rejected_before = metric(&server, "landsketch_render_queue_rejected_total").await;
    let rendered_before = metric(&server, "landsketch_render_seconds_count").await;

    let started = Instant::now();
    let requests =
        (0..REQUESTS).map(|i| get_owned(server.url(&format!("/api/render?yaw={}&width=64&height=48", i * 7))));
    let mut burst = std::pin::pin!(futures_util::future::join_all(requests));
    // Meanwhile the server answers /api/health, whose queue depth never exceeds the queue's.
    let mut depths = Vec::new();
    let responses = loop {
        let poll = async {
            tokio::time::sleep(Duration::from_millis(5)).await;
            health().await
        };
        tokio::select! {
            responses = &mut burst => break responses,
            answer = poll => depths.push(answer["queue_depth"].as_u64().expect("queue_depth")),
        }
    };
    let elapsed = started.elapsed().as_secs_f64();
    assert!(!depths.is_empty(), "no /api/health answer during the burst");
    assert!(depths.iter().all(|&d| d <= QUEUE as u64), "more than {QUEUE} renders waited: {depths:?}");

    let (mut ok, mut busy, mut slowest_ms, mut retry_afters) = (0, 0, 0, Vec::new());
    for response in responses {
        match response.status().as_u16() {
            200 => {
                ok += 1;
                assert_eq!(response.headers()["content-type"], "image/png");
                assert_eq!(response.headers()["x-cache"], "miss");
                let render_ms = response.headers()["x-render-ms"].to_str().expect("ASCII").parse::<u32>();
                slowest_ms = slowest_ms.max(render_ms.expect("x-render-ms"));
                let image = image::load_from_memory_with_format(
                    &response.bytes().await.expect("body"),
                    image::ImageFormat::Png,
                )
                .expect("PNG");
                assert_eq!((image.width(), image.height()), (64, 48));
            }
            503 => {
                busy += 1;
                let retry = response.headers()["retry-after"].to_str().expect("ASCII").parse::<u32>();
                retry_afters.push(retry.expect("Retry-After in whole seconds"));
                let body = assert_error(response, 503, "busy", None).await;
                // Refused only when the queue is full: the message names the renders waiting.
                let message = body["error"]["message"].as_str().unwrap_or_default();
                assert!(message.contains(&format!("({QUEUE} renders waiting)")), "{message}");
            }
            other => panic!("unexpected status {other}"),
        }
    }
    eprintln!(
        "burst of {REQUESTS}: {ok} rendered, {busy} refused in {elapsed:.1} s; {} health answers, deepest queue {}, \
         slowest render {slowest_ms} ms, longest Retry-After {} s",
        depths.len(),
        depths.iter().max().unwrap_or(&0),
        retry_afters.iter().max().unwrap_or(&0)
    );
    // The queue takes `QUEUE` renders before it refuses one, and a burst this size does not fit.
    assert!(ok >= QUEUE, "only {ok} of {REQUESTS} renders accepted with a queue of {QUEUE}");
    assert!(busy >= 1, "{REQUESTS} simultaneous renders with a queue of {QUEUE} all fitted");
    // Retry-After is the time the waiting renders take, in whole seconds, at least 1.
    let estimate = (QUEUE as u64 * u64::from(slowest_ms + 1)).div_ceil(1000).max(1);
    assert!(
        retry_afters.iter().all(|&s| s >= 1 && u64::from(s) <= estimate),
        "{retry_afters:?}; estimate {estimate} s"
    );
    // Every refusal is counted, every accepted render was rendered, and none is left waiting.
    assert_eq!(metric(&server, "landsketch_render_queue_rejected_total").await - rejected_before, busy as f64);
    assert_eq!(metric(&server, "landsketch_render_seconds_count").await - rendered_before, ok as f64);
    assert_eq!(health().await["queue_depth"], 0);

    // The server recovers: honouring Retry-After, a render gets through.
    let url = server.url("/api/render?yaw=3&width=64&height=48");
    for attempt in 0.. {
        let response = get(&url).await;
        if response.status() == StatusCode::OK {
            break;
        }
        assert!(attempt < 20, "no render got through after the burst");
        let retry = response.headers()["retry-after"].to_str().ok().and_then(|s| s.parse::<u64>().ok()).unwrap_or(1);
        tokio::time::sleep(Duration::from_secs(retry.min(5))).await;
    }
}

#[tokio::test]
async fn admin_endpoints_need_the_token_or_loopback() {
    let open = TestServer::shared();
    let cleared = post(&open.url("/api/cache/clear"), "").await;
    assert_eq!(cleared.status(), StatusCode::OK, "no token: loopback clients may write");
    let cleared = json_of(cleared).await;
    assert!(cleared["entries"].is_u64() && cleared["bytes"].is_u64(), "{cleared}");

    let guarded = TestServer::guarded();
    let url = guarded.url("/api/cache/clear");
    let missing = post(&url, "").await;
    assert_eq!(missing.headers()["www-authenticate"], "Bearer");
    assert_error(missing, 401, "unauthorized", None).await;
    let wrong = client().post(&url).bearer_auth("guess").send().await.expect("POST");
    assert_error(wrong, 401, "unauthorized", None).await;
    let right = client().post(&url).bearer_auth("s3cret").send().await.expect("POST");
    assert_eq!(right.status(), StatusCode::OK);
    // Reading stays public.
    assert_eq!(get(&guarded.url("/api/scene")).await.status(), StatusCode::OK);
}

/// D9: without a token, writes need a loopback peer that names a loopback `Host` and, when it
/// sends an `Origin`, a loopback origin (no CSRF from a foreign page, no DNS rebinding).
#[tokio::test]
async fn tokenless_writes_refuse_foreign_hosts_and_origins() {
    let open = TestServer::shared();
    let url = open.url("/api/cache/clear");
    let port = open.addr.port();
    let foreign_origin = client().post(&url).header("origin", "https://attacker.example").send().await.expect("POST");
    let body = assert_error(foreign_origin, 403, "forbidden", None).await;
    let message = body["error"]["message"].as_str().unwrap_or_default();
    assert!(message.contains("Origin") && message.contains("token"), "{message}");
    let text_plain = client()
        .post(&url)
        .header("origin", "null")
        .header("content-type", "text/plain")
        .body("x")
        .send()
        .await
        .expect("POST");
    assert_error(text_plain, 403, "forbidden", None).await;
    let rebound = client().post(&url).header("host", "attacker.example").send().await.expect("POST");
    let body = assert_error(rebound, 403, "forbidden", None).await;
    let message = body["error"]["message"].as_str().unwrap_or_default();
    assert!(message.contains("Host") && message.contains("token"), "{message}");
    let rebound_port = client().post(&url).header("host", format!("attacker.example:{port}")).send().await;
    assert_error(rebound_port.expect("POST"), 403, "forbidden", None).await;
    // Loopback names, with or without port, and loopback origins stay allowed.
    for (host, origin) in [
        (format!("127.0.0.1:{port}"), None),
        ("localhost".to_owned(), None),
        (format!("LocalHost:{port}"), Some(format!("http://localhost:{port}"))),
        (format!("[::1]:{port}"), Some("http://[::1]:3000".to_owned())),
        (format!("127.0.0.1:{port}"), Some(format!("http://127.0.0.1:{port}"))),
    ] {
        let mut request = client().post(&url).header("host", &host);
        if let Some(origin) = &origin {
            request = request.header("origin", origin);
        }
        let response = request.send().await.expect("POST");
        assert_eq!(response.status(), StatusCode::OK, "Host {host}, Origin {origin:?}");
    }
}

/// D9: with a token, a write from a browser page of a foreign origin is refused even with the
/// token; this server's own origin and the allowed CORS origins may write.
#[tokio::test]
async fn token_writes_refuse_cross_origin_requests() {
    let guarded = TestServer::guarded();
    let url = guarded.url("/api/cache/clear");
    let write = |origin: String| client().post(&url).bearer_auth("s3cret").header("origin", origin).send();
    let foreign = write("https://attacker.example".into()).await.expect("POST");
    let body = assert_error(foreign, 403, "forbidden", None).await;
    assert!(body["error"]["message"].as_str().unwrap_or_default().contains("attacker.example"), "{body}");
    for origin in [format!("http://{}", guarded.addr), "https://maps.example.org".to_owned()] {
        assert_eq!(write(origin.clone()).await.expect("POST").status(), StatusCode::OK, "{origin}");
    }
}

#[tokio::test]
async fn cors_is_off_unless_origins_are_configured() {
    let origin = "https://maps.example.org";
    let request = |server: &TestServer| client().get(server.url("/api/scene")).header("origin", origin).send();
    let open = request(TestServer::shared()).await.expect("GET");
    assert!(!open.headers().contains_key("access-control-allow-origin"));
    let allowed = request(TestServer::guarded()).await.expect("GET");
    assert_eq!(allowed.headers()["access-control-allow-origin"], origin);
    let preflight = client()
        .request(reqwest::Method::OPTIONS, TestServer::guarded().url("/api/render"))
        .header("origin", origin)
        .header("access-control-request-method", "POST")
        .send()
        .await
        .expect("OPTIONS");
    assert!(preflight.status().is_success());
    assert_eq!(preflight.headers()["access-control-allow-origin"], origin);

    // Browsers do not count `Authorization` under `Access-Control-Allow-Headers: *`: it and
    // `Content-Type` must be named.
    let preflight = client()
        .request(reqwest::Method::OPTIONS, TestServer::guarded().url("/api/layers"))
        .header("origin", origin)
        .header("access-control-request-method", "POST")
        .header("access-control-request-headers", "authorization, content-type")
        .send()
        .await
        .expect("OPTIONS");
    assert!(preflight.status().is_success());
    let allowed = preflight.headers()["access-control-allow-headers"].to_str().expect("ASCII").to_ascii_lowercase();
    let allowed: Vec<&str> = allowed.split(',').map(str::trim).collect();
    for needed in ["authorization", "content-type"] {
        assert!(allowed.contains(&needed), "{needed} missing from {allowed:?}");
    }
}

#[tokio::test]
async fn shutdown_finishes_in_flight_renders() {
    let server = TestServer::start(&data_dir(), |_| {});
    let url = server.url("/api/render?width=640&height=480");
    let request = tokio::spawn(get_owned(url));
    tokio::time::sleep(Duration::from_millis(100)).await;
    let stopped = tokio::task::spawn_blocking(move || server.stop());
    let response = request.await.expect("request task");
    assert_eq!(response.status(), StatusCode::OK);
    assert!(!response.bytes().await.expect("image").is_empty());
    stopped.await.expect("stop task").expect("clean shutdown");
}

#[tokio::test]
async fn a_missing_scene_stops_the_server_with_an_error() {
    let config = ServerConfig::try_parse_from([
        "serve",
        "--scene",
        "data/no-such-scene.toml",
        "--addr",
        "127.0.0.1:0",
        "--data-dir",
        std::env::temp_dir().join("landsketch-api-tests").to_str().expect("UTF-8"),
    ])
    .expect("flags");
    let server = Server::bind(config).await.expect("bind");
    let error = server.run(std::future::pending()).await.expect_err("no scene");
    assert!(error.to_string().contains("no-such-scene.toml"), "{error}");
}

#[tokio::test]
async fn health_reports_the_loading_stage_and_percent_until_the_scene_is_ready() {
    // The valley sample (365,000 plants) loads for seconds: long enough to watch.
    let data = tempfile::tempdir().expect("temp dir");
    let config =
        ServerConfig::try_parse_from(["serve", "--scene", landsketch::scene::SAMPLE_SCENE, "--addr", "127.0.0.1:0"])
            .map(|mut c| {
                c.data_dir = data.path().to_owned();
                c
            })
            .expect("flags");
    let server = Server::bind(config).await.expect("bind");
    let url = format!("http://{}/api/health", server.local_addr().expect("address"));
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let running = tokio::spawn(server.run(async {
        let _ = stopped.await;
    }));
    let mut seen = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(300);
    loop {
        let response = get(&url).await;
        let status = response.status();
        let body = json_of(response).await;
        if body["status"] == "ok" {
            assert_eq!(status, StatusCode::OK);
            assert!(body.get("stage").is_none() && body.get("percent").is_none(), "{body}");
            break;
        }
        assert_eq!((status, &body["status"]), (StatusCode::SERVICE_UNAVAILABLE, &json!("loading")));
        if let (Some(stage), Some(percent)) = (body["stage"].as_str(), body["percent"].as_f64()) {
            assert!((0.0..=100.0).contains(&percent) && body["stage_label"].is_string(), "{body}");
            seen.push((stage.to_owned(), percent));
        }
        assert!(Instant::now() < deadline, "the scene did not load");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // Stages in order, the percent never falling, preprocessing reached.
    assert!(seen.windows(2).all(|w| w[0].1 <= w[1].1), "{seen:?}");
    assert!(seen.iter().any(|(stage, _)| stage == "preprocessing"), "{seen:?}");
    let _ = stop.send(());
    running.await.expect("server task").expect("server stops cleanly");
}

/// `landsketch serve` prints the address to open in a browser, with the port it bound.
#[test]
fn serve_prints_the_address_to_open() {
    let data = tempfile::tempdir().expect("temp dir");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["serve", "--scene", "data/no-such-scene.toml", "--addr", "127.0.0.1:0", "--data-dir"])
        .arg(data.path())
        .output()
        .expect("run landsketch serve");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let url = stdout.lines().find_map(|l| l.strip_prefix("landsketch: open ")).expect("the address line");
    let port = url.strip_prefix("http://127.0.0.1:").and_then(|rest| rest.strip_suffix("/ in a browser"));
    assert!(port.and_then(|p| p.parse::<u16>().ok()).is_some_and(|p| p != 0), "{stdout}");
    // The scene is missing: the server stops with an error after printing the address.
    assert!(!output.status.success());
}

// ---------------------------------------------------------------------------------------------
// WebSocket

#[tokio::test]
async fn the_first_frame_arrives_with_a_correct_header() {
    let server = TestServer::shared();
    let mut socket = connect(server, "width=160&height=120").await;
    let Incoming::Json(hello) = receive(&mut socket).await else { panic!("hello first") };
    assert_eq!(hello["type"], "hello");
    assert_eq!(hello["protocol"], 1);
    assert_eq!(hello["scene"], "Boulder foothills");
    let (_, status, header, bytes) = next_frame(&mut socket).await;
    assert_eq!(header.frame_id, 1);
    assert_eq!(header.seq, 0);
    assert!(header.still);
    assert_eq!((header.width, header.height, header.format), (160, 120, ImageFormat::Png));
    assert_eq!(status["id"], 1);
    assert_eq!(status["camera"], hello["camera"]);
    let image = image::load_from_memory(&bytes).expect("PNG frame");
    assert_eq!((image.width(), image.height()), (160, 120));
}

#[tokio::test]
async fn latest_control_wins_and_a_still_follows_at_rest() {
    let server = TestServer::shared();
    let mut socket = connect(server, "width=160&height=120&format=jpeg&quality=90").await;
    let (_, first, _, _) = next_frame(&mut socket).await;
    let yaw0 = first["camera"]["yaw"].as_f64().expect("yaw");
    for _ in 0..10 {
        send(&mut socket, json!({"type": "move", "yaw": 5, "forward": 1})).await;
    }
    let mut frames = Vec::new();
    let last = loop {
        let (errors, status, header, bytes) = next_frame(&mut socket).await;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(status["seq"].as_u64(), Some(u64::from(header.seq)));
        if header.still {
            break (status, header, bytes);
        }
        assert_eq!((header.width, header.height, header.format, header.quality), (80, 60, ImageFormat::Jpeg, 50));
        frames.push(header);
    };
    let (status, header, bytes) = last;
    assert!(frames.len() < 6, "latest wins: 10 moves gave {} interactive frames", frames.len());
    assert!(frames.windows(2).all(|w| w[0].seq < w[1].seq));
    assert_eq!(header.seq, 10, "the still reflects the last control");
    assert_eq!((header.width, header.height, header.format, header.quality), (160, 120, ImageFormat::Jpeg, 90));
    let yaw = status["camera"]["yaw"].as_f64().expect("yaw");
    assert!(
        ((yaw - yaw0 - 50.0).rem_euclid(360.0)).min((yaw0 + 50.0 - yaw).rem_euclid(360.0)) < 1e-3,
        "{yaw0} → {yaw}"
    );
    let image = image::load_from_memory(&bytes).expect("JPEG still");
    assert_eq!((image.width(), image.height()), (160, 120));
}

/// A flying eye moved or placed under the ground lands on it, eye height above it, instead of
/// rendering the paper under the terrain.
#[tokio::test]
async fn flying_down_lands_on_the_ground() {
    let server = TestServer::shared();
    let (scene, _) = loaded();
    let ground = scene.terrain.height_at(0.0, 0.0).expect("the terrain under the origin");
    let mut socket = connect(server, "width=64&height=48").await;
    next_frame(&mut socket).await;
    send(&mut socket, json!({"type": "camera", "position": [0.0, 0.0, ground + 500.0], "pitch": -30})).await;
    // The eye's z in the still of control `seq`.
    async fn still_z(socket: &mut Socket, seq: u32) -> f64 {
        loop {
            let (errors, status, header, _) = next_frame(socket).await;
            assert!(errors.is_empty(), "{errors:?}");
            if header.still && header.seq == seq {
                return status["camera"]["position"][2].as_f64().expect("z");
            }
        }
    }
    send(&mut socket, json!({"type": "move", "up": -2000})).await;
    let z = still_z(&mut socket, 2).await;
    assert!((z - (ground + 1.7)).abs() < 0.01, "landed at {z}, ground {ground}");
    // A flying position under the ground (a client's own flight into a hill) lands there too.
    send(&mut socket, json!({"type": "camera", "position": [0.0, 0.0, ground - 300.0]})).await;
    let z = still_z(&mut socket, 3).await;
    assert!((z - (ground + 1.7)).abs() < 0.01, "landed at {z}, ground {ground}");
}

#[tokio::test]
async fn garbage_messages_get_errors_and_the_session_goes_on() {
    let server = TestServer::shared();
    let mut socket = connect(server, "width=96&height=72").await;
    next_frame(&mut socket).await;
    let bad = metric(server, "landsketch_ws_bad_messages_total").await;
    for garbage in [
        Message::text("not json at all"),
        Message::text(r#"{"type": "fly", "speed": 3}"#),
        Message::text(r#"{"type": "camera", "pitch": 200}"#),
        Message::text(r#"{"type": "size", "width": 100000, "height": 10}"#),
        Message::text(r#"{"type": "style", "style": {"ambient": -1}}"#),
        Message::binary(vec![0u8, 1, 2, 3]),
    ] {
        socket.send(garbage).await.expect("send");
        let Incoming::Json(error) = receive(&mut socket).await else { panic!("an error message") };
        assert_eq!(error["type"], "error", "{error}");
        assert!(error["message"].as_str().is_some_and(|m| !m.is_empty()), "{error}");
    }
    assert!(metric(server, "landsketch_ws_bad_messages_total").await >= bad + 6.0);
    send(&mut socket, json!({"type": "ping", "id": 7})).await;
    let Incoming::Json(pong) = receive(&mut socket).await else { panic!("pong") };
    assert_eq!(pong, json!({"type": "pong", "id": 7}));
    send(&mut socket, json!({"type": "camera", "pitch": -10})).await;
    loop {
        let (_, status, header, _) = next_frame(&mut socket).await;
        assert_eq!(header.seq, 1, "only the valid control counts");
        if header.still {
            assert_eq!(status["camera"]["pitch"], -10.0);
            break;
        }
    }
}

/// Eight sessions move their cameras until each has two frames: none starves, and round-robin
/// keeps them close to each other.
#[tokio::test]
async fn concurrent_sessions_all_get_frames() {
    use std::sync::atomic::{AtomicU32, Ordering};
    const SESSIONS: usize = 8;
    const FRAMES: u32 = 2;
    let server = TestServer::shared();
    let counts: Arc<Vec<AtomicU32>> = Arc::new((0..SESSIONS).map(|_| AtomicU32::new(0)).collect());
    let all_done = {
        let counts = counts.clone();
        move || counts.iter().all(|c| c.load(Ordering::SeqCst) >= FRAMES)
    };
    let started = Instant::now();
    let deadline = started + Duration::from_secs(60);
    let sessions = (0..SESSIONS).map(|i| {
        let url = server.ws_url("width=64&height=48");
        let (counts, all_done) = (counts.clone(), all_done.clone());
        tokio::spawn(async move {
            let (mut socket, _) = tokio_tungstenite::connect_async(url).await.expect("connect");
            let mut interval = tokio::time::interval(Duration::from_millis(60));
            while !all_done() && Instant::now() < deadline {
                tokio::select! {
                    _ = interval.tick() => {
                        let message = json!({"type": "move", "yaw": 3 + i});
                        socket.send(Message::text(message.to_string())).await.expect("send");
                    }
                    message = socket.next() => match message {
                        Some(Ok(Message::Binary(_))) => {
                            counts[i].fetch_add(1, Ordering::SeqCst);
                        }
                        Some(Ok(_)) => {}
                        _ => panic!("session {i} closed"),
                    }
                }
            }
            socket.close(None).await.expect("close");
        })
    });
    for session in futures_util::future::join_all(sessions).await {
        session.expect("session task");
    }
    let secs = started.elapsed().as_secs_f64();
    let frames: Vec<u32> = counts.iter().map(|c| c.load(Ordering::SeqCst)).collect();
    for (i, n) in frames.iter().enumerate() {
        eprintln!("session {i}: {n} frames, {:.2} fps", f64::from(*n) / secs);
    }
    assert!(frames.iter().all(|n| *n >= FRAMES), "a session starved within 60 s: {frames:?}");
    let spread = frames.iter().max().unwrap_or(&0) - frames.iter().min().unwrap_or(&0);
    assert!(spread <= 3, "sessions were served unevenly: {frames:?}");
}

#[tokio::test]
async fn idle_sessions_are_closed_and_sessions_are_limited() {
    let server = TestServer::guarded();
    let mut socket = connect(server, "width=32&height=24").await;
    match tokio_tungstenite::connect_async(server.ws_url("")).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => assert_eq!(response.status().as_u16(), 503),
        other => panic!("a second session should be refused, got {:?}", other.map(|_| ())),
    }
    let started = Instant::now();
    loop {
        if let Incoming::Closed(reason) = receive(&mut socket).await {
            assert_eq!(reason.as_deref(), Some("idle timeout"));
            break;
        }
    }
    assert!(started.elapsed() < Duration::from_secs(5));
    // The closed session was cleaned up: the single session slot is free again.
    let deadline = Instant::now() + Duration::from_secs(5);
    while metric(server, "landsketch_ws_sessions").await > 0.0 {
        assert!(Instant::now() < deadline, "the session was not cleaned up");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let mut again = connect(server, "width=32&height=24").await;
    assert!(matches!(receive(&mut again).await, Incoming::Json(hello) if hello["type"] == "hello"));
}

/// Connects a WebSocket client that sends `pings` pings with 60 KB ids and never reads:
/// the pongs fill the socket buffers until the server cannot send. The sending task is
/// returned (abort it when done).
async fn stuck_client(server: &TestServer, pings: usize) -> tokio::task::JoinHandle<()> {
    let (socket, _) = tokio_tungstenite::connect_async(server.ws_url("width=16&height=12")).await.expect("connect");
    let (mut sink, stream) = socket.split();
    tokio::spawn(async move {
        let _unread = stream;
        let ping = json!({"type": "ping", "id": "p".repeat(60_000)}).to_string();
        for _ in 0..pings {
            if sink.send(Message::text(ping.clone())).await.is_err() {
                break;
            }
        }
        std::future::pending::<()>().await;
    })
}

/// D6: a client that never reads is disconnected within `--ws-send-timeout-s` and frees its
/// `--max-sessions` slot (the idle timeout alone never fired: the server blocked on send).
#[tokio::test]
async fn a_client_that_never_reads_is_closed_and_frees_its_slot() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| {
        c.max_sessions = 1;
        c.ws_send_timeout_s = 1;
    });
    let stuck = stuck_client(&server, 400).await;
    let started = Instant::now();
    // The slot is taken while the client is stuck, and free again after the deadline.
    loop {
        match tokio_tungstenite::connect_async(server.ws_url("width=16&height=12")).await {
            Ok((mut socket, _)) => {
                assert!(matches!(receive(&mut socket).await, Incoming::Json(hello) if hello["type"] == "hello"));
                break;
            }
            Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
                assert_eq!(response.status().as_u16(), 503);
            }
            Err(other) => panic!("connect: {other}"),
        }
        assert!(started.elapsed() < Duration::from_secs(15), "the stuck session kept its slot");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(started.elapsed() > Duration::from_millis(500), "the slot was taken while the client was stuck");
    stuck.abort();
}

/// D6: shutdown does not wait for a session blocked on a client that never reads.
#[tokio::test]
async fn shutdown_does_not_wait_for_a_client_that_never_reads() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| c.ws_send_timeout_s = 600);
    let stuck = stuck_client(&server, 400).await;
    // Wait until the session is blocked: its pongs no longer fit the buffers.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let started = Instant::now();
    let stopped = tokio::task::spawn_blocking(move || server.stop()).await.expect("stop task");
    stopped.expect("clean stop");
    let took = started.elapsed();
    stuck.abort();
    assert!(took < landsketch::api::ws::CLOSE_GRACE - Duration::from_secs(1), "shutdown took {took:?}");
}

/// D8: partial headers, an idle kept-alive connection and a slow upload are cut off after
/// `--header-timeout-s` and `--body-timeout-s`; a `Content-Length` beyond the upload limit is
/// refused with 413 before any of the body is sent.
#[tokio::test]
async fn slow_clients_time_out_and_huge_bodies_are_refused_up_front() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| {
        c.header_timeout_s = 1;
        c.body_timeout_s = 1;
    });
    let wait = Duration::from_secs(8);
    let (received, held) = raw_exchange(&server, b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n", wait).await;
    assert!(held < Duration::from_secs(4), "partial headers held for {held:?}: {received}");
    let (received, held) = raw_exchange(&server, b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", wait).await;
    assert!(received.starts_with("HTTP/1.1 200"), "{received}");
    assert!(held < Duration::from_secs(4), "an idle keep-alive held for {held:?}");
    let slow =
        b"POST /api/layers?name=Slow&kind=scalar HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000\r\n\r\nII*\0";
    let (received, held) = raw_exchange(&server, slow, wait).await;
    assert!(held < Duration::from_secs(4), "a slow upload held for {held:?}: {received}");
    assert!(received.contains("--body-timeout-s"), "{received}");
    let huge = format!(
        "POST /api/layers?name=Huge&kind=scalar HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {}\r\n\r\n",
        10u64 << 30
    );
    let (received, held) = raw_exchange(&server, huge.as_bytes(), wait).await;
    assert!(received.starts_with("HTTP/1.1 413"), "{received}");
    assert!(received.contains("too_large"), "{received}");
    assert!(held < Duration::from_secs(2), "{held:?}");
    assert!(tree_is_empty(&dir.path().join("layers")), "nothing stored");
}

/// Whether a directory has no entries (or does not exist).
fn tree_is_empty(dir: &std::path::Path) -> bool {
    std::fs::read_dir(dir).map_or(true, |mut entries| entries.next().is_none())
}

/// D12: a message over `--ws-max-message` (64 KiB) gets close code 1009, not a reset.
#[tokio::test]
async fn an_oversized_message_is_closed_with_1009() {
    let server = TestServer::shared();
    let socket = connect(server, "width=32&height=24").await;
    let (mut sink, mut stream) = socket.split();
    let oversized = json!({"type": "ping", "id": "x".repeat(100 << 10)}).to_string();
    // The server stops reading mid-message: the send may never finish.
    let sender = tokio::spawn(async move { sink.send(Message::text(oversized)).await });
    let code = loop {
        let message = tokio::time::timeout(Duration::from_secs(30), stream.next()).await.expect("a close in time");
        match message {
            Some(Ok(Message::Close(frame))) => break frame.map(|f| (u16::from(f.code), f.reason.to_string())),
            Some(Ok(_)) => {}
            other => panic!("closed without a close frame: {other:?}"),
        }
    };
    assert_eq!(code, Some((1009, "message too big".to_owned())));
    sender.abort();
}

#[tokio::test]
async fn presets_schema_and_layer_styles_over_rest() {
    let server = TestServer::shared();
    // The scene lists the presets and the style schema with ranges.
    let scene = json_of(get(&server.url("/api/scene")).await).await;
    let presets: Vec<&str> =
        scene["presets"].as_array().expect("presets").iter().filter_map(|p| p["name"].as_str()).collect();
    assert_eq!(presets.len(), landsketch::render::presets::PRESETS.len());
    assert!(presets.contains(&"photorealism") && presets.contains(&"childrens_book"), "{presets:?}");
    assert_eq!(scene["presets"][0]["style"]["photorealism"], 1.0);
    let schema = scene["style_schema"].as_array().expect("schema");
    let photo = schema.iter().find(|f| f["name"] == "photorealism").expect("photorealism field");
    assert_eq!(
        (photo["min"].as_f64(), photo["max"].as_f64(), photo["default"].as_f64()),
        (Some(0.0), Some(1.0), Some(0.0))
    );
    let fields = serde_json::to_value(Style::default()).expect("JSON");
    assert_eq!(schema.len(), fields.as_object().map_or(0, |f| f.len()));

    // A preset renders; style fields merge over it; a view link keeps it.
    let photo = get(&server.url(&format!("/api/render?{VIEW}&preset=photorealism"))).await;
    assert_eq!(photo.status(), StatusCode::OK);
    let photo = photo.bytes().await.expect("image");
    let sketch = get(&server.url(&format!("/api/render?{VIEW}"))).await.bytes().await.expect("image");
    assert_ne!(photo, sketch);
    let layers = json!({"existing": {"preset": "photorealism"}, "terrain": {"hatch_map": 1}});
    let body = json!({
        "camera": {"position": [205, 185], "yaw": 268, "pitch": -1.5}, "width": 160, "height": 120,
        "preset": "full_npr", "style": {"ambient": 0.4}, "layer_styles": layers,
    });
    let posted = post(&server.url("/api/render"), body.to_string()).await;
    assert_eq!(posted.status(), StatusCode::OK);
    let link = posted.headers()["content-location"].to_str().expect("link").to_owned();
    assert!(link.contains("layer_styles"), "{link}");
    let mixed = posted.bytes().await.expect("image");
    assert_ne!(mixed, sketch);
    assert_eq!(get(&server.url(&link)).await.bytes().await.expect("image"), mixed, "{link}");

    // Unknown presets are 404s naming them; bad values 422s naming the field.
    let render = |query: &str| server.url(&format!("/api/render?{VIEW}&{query}"));
    let body = assert_error(get(&render("preset=winter")).await, 404, "not_found", None).await;
    let message = body["error"]["message"].as_str().unwrap_or_default();
    assert!(message.contains("winter") && message.contains("van_gogh"), "{message}");
    for (query, status, code, parameter) in [
        ("preset=full_npr&style=%7B%22photorealism%22%3A2%7D", 422, "invalid_parameter", Some("style.photorealism")),
        ("layer_styles=%7B%22meadow%22%3A%7B%7D%7D", 422, "invalid_parameter", Some("layer_styles.meadow")),
        (
            "layer_styles=%7B%22planned%22%3A%7B%22color%22%3A5%7D%7D",
            422,
            "invalid_parameter",
            Some("layer_styles.planned.color"),
        ),
        ("layer_styles=%7B%22planned%22%3A%7B%22preset%22%3A%22winter%22%7D%7D", 404, "not_found", None),
        ("layer_styles=%7Bnot-json", 400, "bad_request", Some("layer_styles")),
    ] {
        let body = assert_error(get(&render(query)).await, status, code, parameter).await;
        let message = body["error"]["message"].as_str().unwrap_or_default().to_owned();
        if query.contains("photorealism") {
            assert!(message.contains("0..=1"), "{message}");
        }
        if query.contains("meadow") {
            assert!(message.contains("existing") && message.contains("terrain"), "{message}");
        }
    }
}

#[tokio::test]
async fn websocket_style_messages_take_presets_and_layer_styles() {
    let server = TestServer::shared();
    let mut socket = connect(server, "width=96&height=72&preset=minimalistic").await;
    let (_, _, _, first) = next_frame(&mut socket).await;
    send(
        &mut socket,
        json!({"type": "style", "preset": "photorealism", "layer_styles": {"planned": {"preset": "full_npr"}}}),
    )
    .await;
    let mut still = Vec::new();
    for _ in 0..10 {
        let (_, _, header, bytes) = next_frame(&mut socket).await;
        if header.still && header.seq == 1 {
            still = bytes;
            break;
        }
    }
    assert!(!still.is_empty() && still != first, "no new still frame after the style message");
    send(&mut socket, json!({"type": "style", "layer_styles": {"meadow": {}}})).await;
    let Incoming::Json(error) = receive(&mut socket).await else { panic!("an error message") };
    assert_eq!(
        (error["type"].as_str(), error["parameter"].as_str()),
        (Some("error"), Some("layer_styles.meadow")),
        "{error}"
    );
}

/// The styles of one view resolve to the same complete styles whichever way they come: as a
/// rendered view (`ViewParams::normalize`, what `GET`/`POST /api/render` render), as
/// `POST /api/styles/resolve` (what the browser's style panel shows) and as a WebSocket `style`
/// control (answered with the styles the session renders).
#[tokio::test]
async fn styles_resolve_alike_over_rest_and_websocket() {
    let server = TestServer::shared();
    let styles = json!({
        "preset": "full_npr",
        "style": {"ambient": 0.4, "ink": [0.1, 0.2, 0.3]},
        "layer_styles": {"existing": {"preset": "photorealism", "sky": 0.5}, "terrain": {"hatch_map": 1}},
    });
    let (scene, _) = loaded();
    let dir = tempfile::tempdir().expect("temp dir");
    let store = &landsketch::store::Store::open(dir.path()).expect("store");
    let params: ViewParams = serde_json::from_value(styles.clone()).expect("view parameters");
    let limits = Limits { max_width: 2048, max_height: 2048 };
    let view = params.normalize(scene, store, limits, Source::Body).expect("valid view");
    let style = |value: &Value| -> Style { serde_json::from_value(value.clone()).expect("a complete style") };

    let response = post(&server.url("/api/styles/resolve"), styles.to_string()).await;
    assert_eq!(response.status(), StatusCode::OK);
    let resolved = json_of(response).await;
    assert_eq!(style(&resolved["view"]["style"]), view.style);
    assert_eq!(style(&resolved["view"]["base"]), landsketch::render::presets::preset("full_npr").expect("preset"));
    let layers = resolved["layers"].as_object().expect("layers");
    assert_eq!(layers.keys().collect::<Vec<_>>(), ["existing", "planned", "terrain"]);
    for (name, own) in &view.layer_styles {
        assert_eq!(&style(&layers[name]["style"]), own, "{name}");
    }
    assert_eq!(
        style(&layers["existing"]["base"]),
        landsketch::render::presets::preset("photorealism").expect("preset")
    );
    assert_eq!(style(&layers["terrain"]["base"]), view.style, "a layer without a preset starts from the view's style");
    assert_eq!(style(&layers["planned"]["style"]), view.style, "a layer without a style of its own has the view's");

    let mut socket = connect(server, "width=96&height=72").await;
    let mut message = styles.clone();
    message["type"] = json!("style");
    message["replace"] = json!(true);
    send(&mut socket, message).await;
    let answer = loop {
        match receive(&mut socket).await {
            Incoming::Json(v) if v["type"] == "style" => break v,
            Incoming::Closed(reason) => panic!("closed: {reason:?}"),
            _ => {}
        }
    };
    assert_eq!(style(&answer["style"]), view.style);
    let answered = answer["layer_styles"].as_object().expect("layer styles");
    assert_eq!(answered.len(), view.layer_styles.len());
    for (name, own) in &view.layer_styles {
        assert_eq!(&style(&answered[name]), own, "{name}");
    }

    // Errors name the field, the layer or the preset as rendering does.
    let url = server.url("/api/styles/resolve");
    assert_error(post(&url, r#"{"style": {"ambient": 2}}"#).await, 422, "invalid_parameter", Some("style.ambient"))
        .await;
    assert_error(
        post(&url, r#"{"style": {"ambient": "dark"}}"#).await,
        422,
        "invalid_parameter",
        Some("style.ambient"),
    )
    .await;
    let body = r#"{"layer_styles": {"planned": {"color": 5}}}"#;
    assert_error(post(&url, body).await, 422, "invalid_parameter", Some("layer_styles.planned.color")).await;
    let body = assert_error(
        post(&url, r#"{"layer_styles": {"meadow": {}}}"#).await,
        422,
        "invalid_parameter",
        Some("layer_styles.meadow"),
    )
    .await;
    assert!(body["error"]["message"].as_str().is_some_and(|m| m.contains("existing")), "{body}");
    let body = assert_error(post(&url, r#"{"preset": "winter"}"#).await, 404, "not_found", None).await;
    assert!(body["error"]["message"].as_str().is_some_and(|m| m.contains("van_gogh")), "{body}");
    assert_error(post(&url, r#"{"colour": {}}"#).await, 422, "invalid_parameter", None).await;
    assert_error(post(&url, "{not json").await, 400, "bad_request", None).await;
}

/// Camera errors name the parameter as each source writes it: the query's `x` and
/// `plan_width`, the body's `camera.…`, the WebSocket's field names, the CLI's flags.
#[test]
fn camera_errors_name_the_parameter_as_the_client_wrote_it() {
    use landsketch::scene::camera_params::{CameraMode, CameraParams};
    let (scene, _) = loaded();
    let camera = &scene.default_camera;
    let outside = CameraParams { position: Some(vec![1.0e6, 0.0]), ..CameraParams::default() };
    let narrow = CameraParams { mode: Some(CameraMode::Plan), width: Some(0.0), ..CameraParams::default() };
    let turned = CameraParams { yaw: Some(-4000.0), ..CameraParams::default() };
    // An elevation under the ground (a height above it given as z, say).
    let buried = CameraParams { position: Some(vec![0.0, 0.0, 100.0]), ..CameraParams::default() };
    for (source, position, width, yaw, z) in [
        (Source::Query, "x", "plan_width", "yaw", "z"),
        (Source::Body, "camera.position", "camera.width", "camera.yaw", "camera.position"),
        (Source::Message, "position", "width", "yaw", "position"),
        (Source::CommandLine, "--pos", "--plan WIDTH", "--yaw", "--pos"),
    ] {
        let error = |params: &CameraParams| params.resolve(camera, scene, source).expect_err("an error").parameter;
        assert_eq!(
            [error(&outside), error(&narrow), error(&turned), error(&buried)],
            [position, width, yaw, z],
            "{source:?}"
        );
    }
    // Just above the ground, and anywhere outside the terrain, z places the eye freely.
    let ground = scene.terrain.height_at(0.0, 0.0).expect("the terrain under the origin") as f32;
    let above = CameraParams { position: Some(vec![0.0, 0.0, ground + 0.5]), ..CameraParams::default() };
    let resolved = above.resolve(camera, scene, Source::Body).expect("above the ground");
    assert_eq!(resolved.camera.position, [0.0, 0.0, ground + 0.5]);
    let off_the_map = CameraParams { position: Some(vec![1.0e5, 0.0, -50.0]), ..CameraParams::default() };
    assert!(off_the_map.resolve(camera, scene, Source::Body).is_ok());
    let error = turned.resolve(camera, scene, Source::CommandLine).expect_err("an error");
    assert_eq!(error.to_string(), "--yaw -4000 is outside -3600..=3600");
}
