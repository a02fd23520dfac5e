//! Participation (issue #14) over real servers on loopback: comments pinned at a pixel of a
//! synthetic sloping scene land on the terrain (within one cell), survive a restart, export as
//! GeoJSON and CSV, are moderated (hidden ones never public), refuse every bad input, are
//! rate-limited, and reach other WebSocket sessions live; they are drawn as pins where they
//! were made, over REST and in a session that follows them live (hidden ones never);
//! viewpoints from the scene file and the admin API.

mod common;

use common::server::{TestServer, client, get, json_of};
use common::ws::{Socket, next_changed};
use futures_util::StreamExt;
use landsketch::gis::{Crs, CrsDefinition, GeoTransform, Raster, Transformer, write_geotiff_f32};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message;

/// DEM cells are this many metres.
const CELL: f64 = 10.0;
/// The slope of the synthetic terrain: metres up per metre east.
const SLOPE: f64 = 0.2;
const TOKEN: &str = "citizen-token-0123456789";
const OTHER: &str = "another-citizen-0123456789";
const THIRD: &str = "a-third-citizen-0123456789";
const ADMIN: &str = "moderator-s3cret";

/// A 30 × 30-cell DEM (EPSG:32613, 10 m cells) rising `SLOPE` to the east, one oak at its
/// centre, and a scene file with `extra` TOML appended; returns the scene file.
fn synthetic_scene(dir: &Path, extra: &str) -> PathBuf {
    let n = 30;
    let dem = Raster {
        width: n,
        height: n,
        data: (0..n * n).map(|i| 100.0 + (i % n) as f64 * CELL * SLOPE).collect(),
        nodata: None,
        transform: GeoTransform { origin_x: 480_000.0, origin_y: 4_430_000.0, cell_width: CELL, cell_height: CELL },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    };
    write_geotiff_f32(&dir.join("dem.tif"), &dem).expect("write DEM");
    std::fs::write(dir.join("trees.csv"), "x,y\n480150,4429850\n").expect("write trees");
    let text = format!(
        r#"name = "slope"
[terrain]
dem = "dem.tif"
[sun]
azimuth = 135.0
elevation = 40.0
[camera]
position = [-120.0, 0.0]
z = 160.0
yaw = 90.0
pitch = -20.0
fov = 60.0
[species.oak]
procedural = "broadleaf"
seed = 1
[[layers]]
name = "planned"
[[layers.plans]]
kind = "plants"
file = "trees.csv"
species = "oak"
{extra}
"#
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).expect("write scene");
    path
}

/// A server on a fresh synthetic scene in `dir` (data directory `dir/data`).
fn start(dir: &Path, extra: &str, admin_token: Option<&str>) -> (TestServer, Arc<Scene>) {
    let path = synthetic_scene(dir, extra);
    let scene = Arc::new(Scene::load(&path).unwrap_or_else(|e| panic!("{e}")));
    let token = admin_token.map(str::to_owned);
    let server = TestServer::start_scene(&dir.join("data"), &path, scene.clone(), move |c| c.admin_token = token);
    (server, scene)
}

/// The view a client sees: looking east down onto the slope.
fn view() -> Value {
    json!({"camera": {"position": [-120.0, 0.0, 160.0], "yaw": 90.0, "pitch": -20.0}, "width": 160, "height": 120})
}

fn comment_body(text: &str, pixel: [u32; 2], author: &str) -> Value {
    json!({"view": view(), "pixel": pixel, "text": text, "category": "idea", "author": author})
}

/// JSON request bodies (reqwest is built without its `json` feature).
trait JsonBody {
    fn json_body(self, body: &Value) -> Self;
}

impl JsonBody for reqwest::RequestBuilder {
    fn json_body(self, body: &Value) -> Self {
        self.header("content-type", "application/json").body(body.to_string())
    }
}

async fn post_json(url: &str, body: &Value) -> reqwest::Response {
    client().post(url).json_body(body).send().await.expect("POST")
}

async fn with_admin(request: reqwest::RequestBuilder) -> reqwest::Response {
    request.bearer_auth(ADMIN).send().await.expect("request")
}

/// Where the ray of pixel `pixel` of `view()` meets the terrain (bisection on the height
/// above the ground), independent of the renderer.
fn expected_point(scene: &Scene, pixel: [u32; 2]) -> [f64; 3] {
    let camera = Camera::perspective([-120.0, 0.0, 160.0], 90.0, -20.0, 60.0);
    let (w, h) = (160, 120);
    let origin = camera.pixel_point(pixel[0], pixel[1], 1.0, w, h);
    let far = camera.pixel_point(pixel[0], pixel[1], 150.0, w, h);
    let above = |t: f64| {
        let p = origin + (far - origin) * t as f32;
        let ground = scene.terrain.height_at(f64::from(p.x), f64::from(p.y)).unwrap_or(f64::NEG_INFINITY);
        f64::from(p.z) - ground
    };
    let (mut lo, mut hi) = (0.0, 1.0);
    assert!(above(lo) > 0.0 && above(hi) < 0.0, "the pixel's ray must meet the terrain");
    for _ in 0..60 {
        let mid = (lo + hi) / 2.0;
        if above(mid) > 0.0 { lo = mid } else { hi = mid }
    }
    let p = origin + (far - origin) * lo as f32;
    [f64::from(p.x), f64::from(p.y), f64::from(p.z)]
}

fn position_of(comment: &Value) -> [f64; 3] {
    let p = comment["position"].as_array().expect("position");
    [p[0].as_f64().expect("x"), p[1].as_f64().expect("y"), p[2].as_f64().expect("z")]
}

/// Scene metres of a WGS 84 point (the inverse of what the server did).
fn scene_of_lon_lat(scene: &Scene, lon: f64, lat: f64) -> [f64; 2] {
    let utm = CrsDefinition::from_epsg(32613).expect("UTM 13N");
    let back = Transformer::new(&CrsDefinition::wgs84(), &utm).expect("transformer");
    let (x, y) = back.transform(lon, lat).expect("in range");
    let (lx, ly) = scene.terrain.frame.to_local(x, y);
    [lx, ly]
}

#[tokio::test]
async fn a_comment_lands_where_its_pixel_points_and_survives_a_restart() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, scene) = start(dir.path(), "", None);
    let pixel = [40, 100];
    let response =
        post_json(&server.url("/api/comments"), &comment_body("The hedge blocks my view", pixel, TOKEN)).await;
    assert_eq!(response.status(), 201);
    let location = response.headers()["location"].to_str().expect("location").to_owned();
    let comment = json_of(response).await;
    assert_eq!((comment["number"].as_i64(), comment["status"].as_str()), (Some(1), Some("visible")));
    assert_eq!(comment["hit"], json!({"kind": "terrain"}));
    let got = position_of(&comment);
    let want = expected_point(&scene, pixel);
    let off = ((got[0] - want[0]).powi(2) + (got[1] - want[1]).powi(2)).sqrt();
    assert!(off < CELL, "the comment is {off:.2} m from where the pixel's ray meets the terrain ({got:?} vs {want:?})");
    let ground = scene.terrain.height_at(got[0], got[1]).expect("on the terrain");
    assert!((got[2] - ground).abs() < 1.0, "z {} vs ground {ground}", got[2]);
    // WGS 84 round trip through the scene CRS.
    let back = scene_of_lon_lat(&scene, comment["lon"].as_f64().expect("lon"), comment["lat"].as_f64().expect("lat"));
    assert!((back[0] - got[0]).abs() < 0.01 && (back[1] - got[1]).abs() < 0.01, "{back:?} vs {got:?}");

    // The oak at the centre of the DEM: a plant of layer `planned`.
    let (min, max) = scene.terrain.bounds();
    let centre = [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0];
    let oak = &scene.layers[0].plants[0];
    let oak_view = json!({"camera": {"position": [centre[0] - 30.0, centre[1], f64::from(oak.position[2]) + 6.0], "yaw": 90.0, "pitch": -5.0}, "width": 160, "height": 120});
    let body = json!({"view": oak_view, "pixel": [80, 60], "text": "Keep this oak", "author": TOKEN});
    let plant = json_of(post_json(&server.url("/api/comments"), &body).await).await;
    assert_eq!(plant["hit"], json!({"kind": "plant", "layer": "planned", "index": 0}), "{plant}");
    assert_eq!(plant["number"], 2);

    drop(server);
    let (server, _) = start(dir.path(), "", None);
    let listed = json_of(get(&server.url("/api/comments")).await).await;
    let texts: Vec<_> = listed["comments"].as_array().expect("list").iter().map(|c| c["text"].clone()).collect();
    assert_eq!(texts, vec![json!("The hedge blocks my view"), json!("Keep this oak")]);
    let again = json_of(get(&server.url(&location)).await).await;
    assert_eq!(position_of(&again), got, "the position survives the restart");
}

/// A minimal RFC 4180 reader (quoted cells, doubled quotes, CRLF records).
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let (mut rows, mut row, mut cell, mut quoted) = (Vec::new(), Vec::new(), String::new(), false);
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                cell.push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => row.push(std::mem::take(&mut cell)),
            ('\r', false) => {}
            ('\n', false) => {
                row.push(std::mem::take(&mut cell));
                rows.push(std::mem::take(&mut row));
            }
            (c, _) => cell.push(c),
        }
    }
    rows
}

#[tokio::test]
async fn comments_export_as_geojson_and_csv_that_parse_back() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, scene) = start(dir.path(), "", None);
    let texts = ["Plain", "Commas, \"quotes\"\nand a second line", "=1+1 looks like a formula"];
    for (i, text) in texts.iter().enumerate() {
        let response =
            post_json(&server.url("/api/comments"), &comment_body(text, [30 + 20 * i as u32, 95], TOKEN)).await;
        assert_eq!(response.status(), 201);
    }
    let response = get(&server.url("/api/comments?format=geojson")).await;
    assert_eq!(response.headers()["content-type"], "application/geo+json");
    let text = response.text().await.expect("body");
    let parsed: geojson::GeoJson = text.parse().expect("valid GeoJSON");
    let geojson::GeoJson::FeatureCollection(collection) = parsed else { panic!("not a FeatureCollection") };
    assert_eq!(collection.features.len(), 3);
    let utm = CrsDefinition::from_epsg(32613).expect("UTM");
    let to_utm = Transformer::new(&CrsDefinition::wgs84(), &utm).expect("transformer");
    for (feature, text) in collection.features.iter().zip(texts) {
        let Some(geojson::GeometryValue::Point { coordinates }) = feature.geometry.as_ref().map(|g| &g.value) else {
            panic!("not a point")
        };
        let (lon, lat) = (coordinates[0], coordinates[1]);
        assert!((-180.0..=180.0).contains(&lon) && (-90.0..=90.0).contains(&lat));
        let (x, y) = to_utm.transform(lon, lat).expect("in range");
        let crs_x = feature.property("crs_x").and_then(Value::as_f64).expect("crs_x");
        let crs_y = feature.property("crs_y").and_then(Value::as_f64).expect("crs_y");
        assert!((x - crs_x).abs() < 0.01 && (y - crs_y).abs() < 0.01, "{x},{y} vs {crs_x},{crs_y}");
        assert_eq!(feature.property("text"), Some(&json!(text)));
        assert_eq!(feature.property("crs"), Some(&json!("EPSG:32613")));
        assert!(feature.property("created").and_then(Value::as_str).is_some_and(|t| t.ends_with('Z')));
        assert!(feature.id.is_some() && feature.property("reports").is_none());
        let local = scene.terrain.frame.to_local(crs_x, crs_y);
        assert!((local.0 - feature.property("scene_x").and_then(Value::as_f64).expect("scene_x")).abs() < 1e-6);
    }
    let response = get(&server.url("/api/comments?format=csv")).await;
    assert!(response.headers()["content-type"].to_str().expect("type").starts_with("text/csv"));
    let rows = parse_csv(&response.text().await.expect("body"));
    assert_eq!(rows.len(), 4, "{rows:?}");
    let header = &rows[0];
    let column = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    assert_eq!(&header[..2], ["lon", "lat"]);
    for ((row, feature), text) in rows[1..].iter().zip(&collection.features).zip(texts) {
        assert_eq!(row.len(), header.len());
        let expected = if text.starts_with('=') { format!("'{text}") } else { text.to_owned() };
        assert_eq!(row[column("text")], expected);
        let lon: f64 = row[column("lon")].parse().expect("lon");
        let Some(geojson::GeometryValue::Point { coordinates }) = feature.geometry.as_ref().map(|g| &g.value) else {
            panic!("not a point")
        };
        assert_eq!(lon, coordinates[0]);
        assert_eq!(row[column("crs_x")].parse::<f64>().ok(), feature.property("crs_x").and_then(Value::as_f64));
    }
    // Filters: category and time.
    let none = json_of(get(&server.url("/api/comments?category=concern")).await).await;
    assert_eq!(none["comments"], json!([]));
    let future = json_of(get(&server.url("/api/comments?since=2999-01-01T00:00:00Z")).await).await;
    assert_eq!(future["comments"], json!([]));
    let past = json_of(get(&server.url("/api/comments?until=2999-01-01")).await).await;
    assert_eq!(past["comments"].as_array().map(Vec::len), Some(3));
    let bad = get(&server.url("/api/comments?format=kml")).await;
    assert_eq!(bad.status(), 422);
}

async fn session(server: &TestServer) -> Socket {
    let (socket, _) = tokio_tungstenite::connect_async(server.ws_url("width=64&height=48")).await.expect("connect");
    socket
}

#[tokio::test]
async fn moderation_keeps_pending_and_hidden_comments_from_the_public() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let extra = "[participation]\nmoderation = \"pre\"\nreport_hide_threshold = 2\n";
    let (server, _) = start(dir.path(), extra, Some(ADMIN));
    let mut public = session(&server).await;
    let created =
        json_of(post_json(&server.url("/api/comments"), &comment_body("Wait for approval", [40, 100], TOKEN)).await)
            .await;
    assert_eq!(created["status"], "pending");
    let id = created["id"].as_i64().expect("id");
    let comment_url = server.url(&format!("/api/comments/{id}"));
    assert_eq!(json_of(get(&server.url("/api/comments")).await).await["comments"], json!([]));
    assert_eq!(get(&comment_url).await.status(), 404);
    let geojson = json_of(get(&server.url("/api/comments?format=geojson")).await).await;
    assert_eq!(geojson["features"], json!([]));
    assert_eq!(get(&server.url("/api/comments?status=pending")).await.status(), 401);
    assert_eq!(get(&server.url("/api/comments?format=csv&status=all")).await.status(), 401);
    assert_eq!(next_changed(&mut public, Duration::from_millis(500)).await, None, "pending comments are not announced");
    let pending = json_of(with_admin(client().get(server.url("/api/comments?status=pending"))).await).await;
    assert_eq!(pending["comments"][0]["id"], id);
    assert_eq!(pending["comments"][0]["reports"], 0);
    assert_eq!(with_admin(client().get(&comment_url)).await.status(), 200);
    // Likes and reports need a visible comment.
    let like = post_json(&format!("{comment_url}/like"), &json!({"author": OTHER})).await;
    assert_eq!(like.status(), 404);

    assert_eq!(client().post(format!("{comment_url}/approve")).send().await.expect("approve").status(), 401);
    assert_eq!(with_admin(client().post(format!("{comment_url}/approve"))).await.status(), 200);
    let added = next_changed(&mut public, Duration::from_secs(5)).await.expect("approval announced");
    assert_eq!((added["what"].as_str(), added["change"].as_str()), (Some("comments"), Some("added")));
    assert_eq!(added["comment"]["text"], "Wait for approval");
    assert!(added["comment"].get("reports").is_none());
    assert_eq!(json_of(get(&server.url("/api/comments")).await).await["comments"][0]["id"], id);

    let own = post_json(&format!("{comment_url}/like"), &json!({"author": TOKEN})).await;
    assert_eq!(own.status(), 403);
    for expected in [1, 1] {
        let liked = json_of(post_json(&format!("{comment_url}/like"), &json!({"author": OTHER})).await).await;
        assert_eq!(liked["likes"], expected, "one like per author");
    }
    let changed = next_changed(&mut public, Duration::from_secs(5)).await.expect("like announced");
    assert_eq!((changed["change"].as_str(), changed["comment"]["likes"].as_i64()), (Some("changed"), Some(1)));
    let unliked = client()
        .delete(format!("{comment_url}/like"))
        .json_body(&json!({"author": OTHER}))
        .send()
        .await
        .expect("unlike");
    assert_eq!(json_of(unliked).await["likes"], 0);
    next_changed(&mut public, Duration::from_secs(5)).await.expect("unlike announced");

    for (author, counted) in [(OTHER, true), (OTHER, false), (THIRD, true)] {
        let reported = json_of(post_json(&format!("{comment_url}/report"), &json!({"author": author})).await).await;
        assert_eq!(reported["counted"], counted);
    }
    let removed = next_changed(&mut public, Duration::from_secs(5)).await.expect("hiding announced");
    assert_eq!(removed, json!({"type": "changed", "what": "comments", "change": "removed", "id": id}));
    assert_eq!(json_of(get(&server.url("/api/comments")).await).await["comments"], json!([]));
    assert_eq!(get(&comment_url).await.status(), 404);
    let csv = get(&server.url("/api/comments?format=csv")).await.text().await.expect("csv");
    assert_eq!(parse_csv(&csv).len(), 1, "only the header: {csv}");
    let hidden = json_of(with_admin(client().get(server.url("/api/comments?status=hidden"))).await).await;
    assert_eq!((hidden["comments"][0]["id"].as_i64(), hidden["comments"][0]["reports"].as_i64()), (Some(id), Some(2)));

    assert_eq!(client().delete(&comment_url).send().await.expect("delete").status(), 401);
    assert_eq!(with_admin(client().delete(&comment_url)).await.status(), 204);
    assert_eq!(with_admin(client().get(&comment_url)).await.status(), 404);
    assert_eq!(
        next_changed(&mut public, Duration::from_millis(500)).await,
        None,
        "deleting a hidden comment is not news"
    );
}

#[tokio::test]
async fn bad_comments_are_refused_naming_the_field_and_nothing_is_stored() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, _) = start(dir.path(), "[participation]\nmax_text_chars = 20\n", None);
    let url = server.url("/api/comments");
    let good = comment_body("Fine", [40, 100], TOKEN);
    let with = |key: &str, value: Value| {
        let mut body = good.clone();
        body[key] = value;
        body
    };
    let mut missing_author = good.clone();
    missing_author.as_object_mut().expect("object").remove("author");
    let sky = json!({"view": {"camera": {"position": [-120.0, 0.0, 160.0], "yaw": 90.0, "pitch": 30.0}, "width": 160, "height": 120}, "pixel": [80, 2], "text": "Clouds", "author": TOKEN});
    let cases = [
        (with("text", json!("x".repeat(21))), 422, "text"),
        (with("text", json!("<script>alert(1)</script>")), 422, "text"),
        (with("text", json!("see <a href=x>here</a>")), 422, "text"),
        (with("text", json!("   ")), 422, "text"),
        (with("category", json!("rant")), 422, "category"),
        (missing_author, 422, "author"),
        (with("author", json!("short")), 422, "author"),
        (with("pixel", json!([160, 10])), 422, "pixel"),
        (with("pixel", json!([1])), 422, "pixel"),
        (sky, 422, "pixel"),
        (with("view", json!({"camera": {"pitch": 120.0}})), 422, "camera.pitch"),
        (with("colour", json!("red")), 422, ""),
    ];
    for (body, status, parameter) in cases {
        let response = post_json(&url, &body).await;
        assert_eq!(response.status(), status, "{body}");
        let error = json_of(response).await;
        if !parameter.is_empty() {
            assert_eq!(error["error"]["parameter"], parameter, "{error}");
        }
        assert!(!error["error"]["message"].as_str().unwrap_or_default().is_empty());
    }
    let malformed = client().post(&url).header("content-type", "application/json").body("{\"text\": ").send().await;
    assert_eq!(malformed.expect("POST").status(), 400);
    let all = json_of(get(&server.url("/api/comments?status=all")).await).await;
    assert_eq!(all["comments"], json!([]), "nothing stored");
    assert_eq!(get(&server.url("/api/health")).await.status(), 200, "the server keeps serving");
    assert_eq!(post_json(&url, &good).await.status(), 201);
}

#[tokio::test]
async fn a_flood_from_one_token_or_address_gets_429_with_retry_after() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let extra = "[participation.rate_limit]\nper_token = { burst = 3, per_minute = 1.0 }\nper_address = { burst = 5, per_minute = 1.0 }\n";
    let (server, _) = start(dir.path(), extra, None);
    let url = server.url("/api/comments");
    let mut statuses = Vec::new();
    for i in 0..5 {
        let response = post_json(&url, &comment_body(&format!("Flood {i}"), [40, 100], TOKEN)).await;
        statuses.push(response.status().as_u16());
        if response.status() == 429 {
            let wait: u64 = response.headers()["retry-after"].to_str().expect("ascii").parse().expect("seconds");
            assert!((1..=60).contains(&wait), "{wait}");
            assert_eq!(json_of(response).await["error"]["code"], "too_many_requests");
        }
    }
    assert_eq!(statuses, [201, 201, 201, 429, 429]);
    // Another token from the same address has the address's last two writes left.
    for expected in [201, 201, 429] {
        assert_eq!(post_json(&url, &comment_body("Other", [40, 100], OTHER)).await.status(), expected);
    }
    let all = json_of(get(&server.url("/api/comments?status=all")).await).await;
    assert_eq!(all["comments"].as_array().map(Vec::len), Some(5));
}

#[tokio::test]
async fn live_events_reach_every_session() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, _) = start(dir.path(), "", None);
    let (mut first, mut second) = (session(&server).await, session(&server).await);
    let created = json_of(post_json(&server.url("/api/comments"), &comment_body("Live", [40, 100], TOKEN)).await).await;
    for socket in [&mut first, &mut second] {
        let event = next_changed(socket, Duration::from_secs(10)).await.expect("comment announced");
        assert_eq!((event["what"].as_str(), event["change"].as_str()), (Some("comments"), Some("added")));
        assert_eq!(event["id"], created["id"]);
        assert_eq!(event["comment"]["number"], 1);
    }
    let viewpoint = json!({"caption": "From the road", "camera": {"position": [-100.0, 0.0], "yaw": 90.0}});
    let put = client().put(server.url("/api/viewpoints/road")).json_body(&viewpoint).send().await.expect("PUT");
    assert_eq!(put.status(), 201);
    for socket in [&mut first, &mut second] {
        let event = next_changed(socket, Duration::from_secs(10)).await.expect("viewpoint announced");
        assert_eq!(event, json!({"type": "changed", "what": "viewpoints", "change": "added", "name": "road"}));
    }
}

#[tokio::test]
async fn viewpoints_come_from_the_scene_file_and_the_admin_api() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let extra = r#"
[[viewpoints]]
name = "Woodland"
caption = "The planned oak"
camera = { position = [-40.0, 0.0], yaw = 90.0, pitch = -5.0 }
preset = "full_npr"

[[viewpoints]]
name = "Above"
caption = "Bird's-eye"
camera = { mode = "plan", width = 300.0 }
"#;
    let (server, _) = start(dir.path(), extra, Some(ADMIN));
    let url = |name: &str| server.url(&format!("/api/viewpoints/{name}"));
    let body = json!({"caption": "Stored", "camera": {"position": [0.0, 0.0], "yaw": 45.0}, "layer_styles": {"planned": {"preset": "photorealism"}}});
    assert_eq!(client().put(url("stored")).json_body(&body).send().await.expect("PUT").status(), 401);
    assert_eq!(with_admin(client().put(url("stored")).json_body(&body)).await.status(), 201);
    assert_eq!(with_admin(client().put(url("stored")).json_body(&body)).await.status(), 200);
    assert_eq!(with_admin(client().post(url("stored")).json_body(&body)).await.status(), 409);
    assert_eq!(with_admin(client().put(url("Woodland")).json_body(&body)).await.status(), 409);
    let bad = with_admin(client().put(url("bad")).json_body(&json!({"camera": {"pitch": 100.0}}))).await;
    assert_eq!(bad.status(), 422);
    assert_eq!(json_of(bad).await["error"]["parameter"], "camera.pitch");
    let unknown = with_admin(client().put(url("bad")).json_body(&json!({"layer_styles": {"nowhere": {}}}))).await;
    assert_eq!(unknown.status(), 422);
    let renamed = with_admin(client().put(url("one")).json_body(&json!({"name": "two"}))).await;
    assert_eq!(json_of(renamed).await["error"]["parameter"], "name");
    let listed = json_of(get(&server.url("/api/viewpoints")).await).await;
    let names: Vec<_> = listed["viewpoints"]
        .as_array()
        .expect("list")
        .iter()
        .map(|v| (v["name"].clone(), v["source"].clone()))
        .collect();
    assert_eq!(
        names,
        vec![(json!("Woodland"), json!("scene")), (json!("Above"), json!("scene")), (json!("stored"), json!("admin"))]
    );
    assert_eq!(listed["viewpoints"][0]["preset"], "full_npr");
    assert_eq!(listed["viewpoints"][2]["layer_styles"]["planned"]["preset"], "photorealism");
    // A viewpoint's parameters render.
    let woodland = &listed["viewpoints"][0];
    let render = json!({"camera": woodland["camera"], "preset": woodland["preset"], "width": 64, "height": 48});
    assert_eq!(client().post(server.url("/api/render")).json_body(&render).send().await.expect("render").status(), 200);
    assert_eq!(with_admin(client().delete(url("Woodland"))).await.status(), 409);
    assert_eq!(with_admin(client().delete(url("stored"))).await.status(), 204);
    assert_eq!(with_admin(client().delete(url("stored"))).await.status(), 404);
}

#[test]
fn a_bad_participation_section_or_viewpoint_stops_the_server_naming_it() {
    for (extra, needle) in [
        ("[participation]\nreport_hide_threshold = 0\n", "report_hide_threshold"),
        ("[[viewpoints]]\nname = \"x\"\ncamera = { pitch = 100.0 }\n", "viewpoint \"x\": camera.pitch"),
        ("[[viewpoints]]\nname = \"x\"\n[[viewpoints]]\nname = \"x\"\n", "used twice"),
    ] {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = synthetic_scene(dir.path(), extra);
        let scene = Arc::new(Scene::load(&path).unwrap_or_else(|e| panic!("{e}")));
        let Err(error) = TestServer::try_start_scene(&dir.path().join("data"), &path, scene, |_| {}) else {
            panic!("the server must not start with {extra}");
        };
        assert!(error.contains(needle) && error.contains("scene.toml"), "{error}");
    }
}

#[tokio::test]
async fn the_sample_scene_has_viewpoints_that_render_and_the_openapi_document_lists_the_endpoints() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let server = TestServer::start(dir.path(), |_| {});
    let listed = json_of(get(&server.url("/api/viewpoints")).await).await;
    let viewpoints = listed["viewpoints"].as_array().expect("list");
    let names: Vec<_> = viewpoints.iter().map(|v| v["name"].as_str().unwrap_or_default()).collect();
    assert_eq!(names, ["Planned woodland", "Bird's-eye", "Plan"]);
    for viewpoint in viewpoints {
        assert!(viewpoint["caption"].as_str().is_some_and(|c| !c.is_empty()));
        let body = json!({"camera": viewpoint["camera"], "width": 64, "height": 48});
        let response = client().post(server.url("/api/render")).json_body(&body).send().await.expect("render");
        assert_eq!(response.status(), 200, "{viewpoint}");
    }
    let openapi = json_of(get(&server.url("/api/openapi.json")).await).await;
    for (path, method) in [
        ("/api/participation", "get"),
        ("/api/comments", "get"),
        ("/api/comments", "post"),
        ("/api/comments/{id}", "get"),
        ("/api/comments/{id}", "delete"),
        ("/api/comments/{id}/like", "post"),
        ("/api/comments/{id}/like", "delete"),
        ("/api/comments/{id}/report", "post"),
        ("/api/comments/{id}/approve", "post"),
        ("/api/comments/{id}/hide", "post"),
        ("/api/viewpoints", "get"),
        ("/api/viewpoints/{name}", "post"),
        ("/api/viewpoints/{name}", "put"),
        ("/api/viewpoints/{name}", "delete"),
    ] {
        assert!(openapi["paths"][path][method].is_object(), "OpenAPI lacks {method} {path}");
    }
    assert!(openapi["components"]["schemas"]["Changed"].is_object());
}

/// Pixels that differ between two same-sized RGBA images, as (column, row).
fn differing(a: &image::RgbaImage, b: &image::RgbaImage) -> Vec<(u32, u32)> {
    a.enumerate_pixels()
        .filter(|&(x, y, p)| p.0.iter().zip(b.get_pixel(x, y).0).any(|(u, v)| u.abs_diff(v) > 24))
        .map(|(x, y, _)| (x, y))
        .collect()
}

async fn render(server: &TestServer, body: &Value) -> (String, image::RgbaImage) {
    let response = post_json(&server.url("/api/render"), body).await;
    assert_eq!(response.status(), 200, "{body}");
    let etag = response.headers()["etag"].to_str().expect("etag").to_owned();
    let bytes = response.bytes().await.expect("image");
    (etag, image::load_from_memory(&bytes).expect("PNG").to_rgba8())
}

#[tokio::test]
async fn comments_are_drawn_as_pins_where_they_were_made_and_hidden_ones_never() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, _scene) = start(dir.path(), "", Some(ADMIN));
    let made =
        json_of(post_json(&server.url("/api/comments"), &comment_body("A bench here", [60, 70], TOKEN)).await).await;
    let point = position_of(&made);

    // From elsewhere: south of the point, looking north at it from 80 m.
    let (w, h) = (200, 150);
    let eye = [point[0] as f32, point[1] as f32 - 80.0, point[2] as f32 + 25.0];
    let camera = Camera::perspective(eye, 0.0, -15.0, 60.0);
    let view = |comments: bool| json!({"camera": {"position": eye, "yaw": 0.0, "pitch": -15.0, "fov": 60.0}, "width": w, "height": h, "comments": comments});
    let (plain_tag, plain) = render(&server, &view(false)).await;
    let (pinned_tag, pinned) = render(&server, &view(true)).await;
    assert_ne!(plain_tag, pinned_tag, "the pins are part of the view's ETag");
    let (px, py) = camera.point_pixel(glam::DVec3::from_array(point).as_vec3(), w, h);
    let changed = differing(&plain, &pinned);
    assert!(!changed.is_empty(), "the pin is drawn");
    for &(x, y) in &changed {
        // The stem rises from the ground point to the head above it.
        assert!(
            (x as f32 - px).abs() <= 24.0 && y as f32 <= py + 6.0 && y as f32 >= py - 70.0,
            "ink at ({x}, {y}) is not at the pin standing on ({px:.0}, {py:.0})"
        );
    }
    assert!(
        changed.iter().any(|&(x, y)| (x as f32 - px).abs() <= 3.0 && (y as f32 - py).abs() <= 8.0),
        "the stem reaches the ground point ({px:.0}, {py:.0})"
    );

    // From above (plan view centred on the point) the pin is at the centre.
    let plan = |comments: bool| json!({"camera": {"mode": "plan", "center": [point[0], point[1]], "width": 120.0}, "width": 160, "height": 120, "comments": comments});
    let plan_changed = differing(&render(&server, &plan(false)).await.1, &render(&server, &plan(true)).await.1);
    assert!(!plan_changed.is_empty(), "the pin is drawn in the plan view");
    assert!(plan_changed.iter().all(|&(x, y)| x.abs_diff(80) <= 24 && y.abs_diff(60) <= 70), "{plan_changed:?}");

    // The pin of a comment made at a pixel of the default view, seen from 80 m south of it and
    // from above, against the reference (looked at: a numbered pen pin on the slope).
    let mut sheet = image::RgbaImage::new(w + 160, h.max(120));
    image::imageops::replace(&mut sheet, &pinned, 0, 0);
    image::imageops::replace(&mut sheet, &render(&server, &plan(true)).await.1, i64::from(w), 0);
    let reference =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/marks/comment_from_elsewhere.png");
    common::assert_matches_reference(&sheet, &reference, 0.02);

    // The link of a pinned view keeps the pins.
    let link = get(&server.url(&format!("/api/render?{}", "comments=true"))).await;
    assert_eq!(link.status(), 200);

    // A hidden comment is not drawn any more, and a new one changes the ETag again.
    let id = made["id"].as_i64().expect("id");
    let hide = with_admin(client().post(server.url(&format!("/api/comments/{id}/hide")))).await;
    assert_eq!(hide.status(), 200);
    let (hidden_tag, hidden) = render(&server, &view(true)).await;
    assert_ne!(hidden_tag, pinned_tag);
    assert!(differing(&plain, &hidden).is_empty(), "a hidden comment is not drawn");
}

/// The image of the next still frame of a session (other messages are skipped).
async fn next_still(socket: &mut Socket) -> image::RgbaImage {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    let mut still = false;
    loop {
        let message = tokio::time::timeout_at(deadline, socket.next())
            .await
            .expect("a still frame in time")
            .expect("the session is open")
            .expect("message");
        match message {
            Message::Text(text) => {
                let value: Value = serde_json::from_str(&text).expect("JSON");
                if value["type"] == "frame" {
                    still = value["still"] == true;
                }
            }
            Message::Binary(bytes) if still => {
                let header = landsketch::api::ws::HEADER_LEN;
                return image::load_from_memory(&bytes[header..]).expect("PNG frame").to_rgba8();
            }
            _ => {}
        }
    }
}

#[tokio::test]
async fn a_session_shows_comment_pins_that_follow_the_comments_live() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (server, _) = start(dir.path(), "", Some(ADMIN));
    let made =
        json_of(post_json(&server.url("/api/comments"), &comment_body("Shade here", [60, 70], TOKEN)).await).await;
    let point = position_of(&made);
    let (w, h) = (200, 150);
    let eye = [point[0] as f32, point[1] as f32 - 80.0, point[2] as f32 + 25.0];
    let (px, py) =
        Camera::perspective(eye, 0.0, -15.0, 60.0).point_pixel(glam::DVec3::from_array(point).as_vec3(), w, h);
    let query = format!(
        "x={}&y={}&z={}&yaw=0&pitch=-15&fov=60&width={w}&height={h}&format=png&comments=true",
        eye[0], eye[1], eye[2]
    );
    let (mut socket, _) = tokio_tungstenite::connect_async(server.ws_url(&query)).await.expect("connect");
    let pinned = next_still(&mut socket).await;
    let send = |show: bool| Message::text(json!({"type": "comments", "show": show}).to_string());
    futures_util::SinkExt::send(&mut socket, send(false)).await.expect("send");
    let plain = next_still(&mut socket).await;
    let changed = differing(&plain, &pinned);
    assert!(!changed.is_empty(), "the session draws the pin");
    assert!(
        changed.iter().all(|&(x, y)| (x as f32 - px).abs() <= 24.0 && y as f32 <= py + 6.0),
        "only the pin differs"
    );

    futures_util::SinkExt::send(&mut socket, send(true)).await.expect("send");
    assert!(!differing(&plain, &next_still(&mut socket).await).is_empty(), "the pin is back");
    // Hidden by a moderator: the session's next frame has no pin, without asking.
    let id = made["id"].as_i64().expect("id");
    let hide = with_admin(client().post(server.url(&format!("/api/comments/{id}/hide")))).await;
    assert_eq!(hide.status(), 200);
    assert!(differing(&plain, &next_still(&mut socket).await).is_empty(), "a hidden comment's pin goes away live");
}
