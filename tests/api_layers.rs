//! Integration tests of the data-layer API (SPEC A2): real servers on loopback ports with the
//! sample scene and a data directory of their own, exercised over HTTP (reqwest) and WebSocket
//! `data` messages (tokio-tungstenite). Uploads are
//! GeoTIFFs written here to cover the sample scene, and the ASCII-grid fixture
//! `data/test/fields/ramp_scalar_4326.asc`, which lies south-west of it.

mod common;

use common::server::{TestServer, client, get, json_of, loaded, scene_tiff, sized_scene_tiff};
use common::tiff::{DATA_OFFSET, Entry, LONG, SHORT, geographic_entries, longs, shorts, tiff_file};
use futures_util::{SinkExt, StreamExt};
use landsketch::api::ws::{FrameHeader, HEADER_LEN};
use landsketch::fields::legend::{LEGEND_WIDTH, SCALAR_LEGEND_HEIGHT};
use landsketch::fields::{ColorMapName, ColorMapSpec, Lut};
use landsketch::gis::{Crs, GeoTransform, Raster, write_geotiff_f32};
use reqwest::StatusCode;
use serde_json::Value;
use std::path::{Path, PathBuf};
use tokio_tungstenite::tungstenite::Message;

async fn upload(server: &TestServer, query: &str, body: Vec<u8>) -> reqwest::Response {
    client().post(server.url(&format!("/api/layers?{query}"))).body(body).send().await.expect("POST")
}

async fn delete(url: &str) -> reqwest::Response {
    client().delete(url).send().await.expect("DELETE")
}

/// Asserts a JSON error with `status`, `code` and (when given) `parameter`; returns the message.
async fn assert_error(response: reqwest::Response, status: u16, code: &str, parameter: Option<&str>) -> String {
    let url = response.url().to_string();
    assert_eq!(response.status().as_u16(), status, "{url}");
    let body = json_of(response).await;
    let error = &body["error"];
    assert_eq!(error["code"], code, "{url}: {body}");
    if let Some(parameter) = parameter {
        assert_eq!(error["parameter"], parameter, "{url}: {body}");
    }
    let message = error["message"].as_str().unwrap_or_default().to_string();
    assert!(!message.is_empty(), "{url}: {body}");
    message
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/test").join(name)).expect("fixture")
}

/// Every path under `dir`, relative, sorted.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("read dir") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                stack.push(path.clone());
            }
            out.push(path.strip_prefix(dir).expect("inside").to_path_buf());
        }
    }
    out.sort();
    out
}

/// A `multipart/form-data` body with text fields and one file part; returns the content type
/// and the body.
fn multipart(fields: &[(&str, &str)], filename: &str, file: &[u8]) -> (String, Vec<u8>) {
    let boundary = "landsketch-test-boundary-7f3a";
    let mut body = Vec::new();
    for (name, value) in fields {
        body.extend_from_slice(
            format!("--{boundary}\r\nContent-Disposition: form-data; name=\"{name}\"\r\n\r\n{value}\r\n").as_bytes(),
        );
    }
    body.extend_from_slice(
        format!(
            "--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"{filename}\"\r\n\
             Content-Type: application/octet-stream\r\n\r\n"
        )
        .as_bytes(),
    );
    body.extend_from_slice(file);
    body.extend_from_slice(format!("\r\n--{boundary}--\r\n").as_bytes());
    (format!("multipart/form-data; boundary={boundary}"), body)
}

const STEP_1: &str = "name=Air%20temperature&kind=scalar&time=2024-06-01T00:00:00Z&filename=t1.tif&units=degC";
const STEP_2: &str = "name=Air%20temperature&kind=scalar&time=2024-06-02T00:00:00Z&filename=t2.tif";

#[tokio::test]
async fn upload_list_get_legends_and_delete() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    assert_eq!(json_of(get(&server.url("/api/layers")).await).await["layers"], Value::Array(Vec::new()));

    let created = upload(&server, STEP_1, scene_tiff(0.0)).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let location = created.headers()["location"].to_str().expect("ASCII").to_string();
    let meta = json_of(created).await;
    let id = meta["id"].as_str().expect("id").to_string();
    assert!(id.starts_with("air-temperature-"), "{meta}");
    assert_eq!(location, format!("/api/layers/{id}"));
    assert_eq!((meta["kind"].as_str(), meta["crs"].as_str()), (Some("scalar"), Some("EPSG:4326")), "{meta}");
    assert_eq!((meta["min"].as_f64(), meta["max"].as_f64()), (Some(0.0), Some(7.0)), "{meta}");
    assert_eq!(meta["units"], "degC");
    assert_eq!(meta["source"], "t1.tif");

    // A second time step of the same name extends the series.
    let appended = upload(&server, STEP_2, scene_tiff(10.0)).await;
    assert_eq!(appended.status(), StatusCode::OK);
    let series = json_of(appended).await;
    assert_eq!(series["id"], id.as_str());
    let times: Vec<&str> =
        series["steps"].as_array().expect("steps").iter().filter_map(|s| s["time"].as_str()).collect();
    assert_eq!(times, ["2024-06-01T00:00:00Z", "2024-06-02T00:00:00Z"]);
    assert_eq!(series["max"].as_f64(), Some(17.0));

    // The same layer as a multipart form (file part plus text fields).
    let (content_type, body) = multipart(&[("name", "Form ramp"), ("kind", "scalar")], "form.tif", &scene_tiff(100.0));
    let form = client()
        .post(server.url("/api/layers"))
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .expect("POST");
    assert_eq!(form.status(), StatusCode::CREATED);
    let form = json_of(form).await;
    assert_eq!((form["name"].as_str(), form["source"].as_str()), (Some("Form ramp"), Some("form.tif")), "{form}");
    let form_id = form["id"].as_str().expect("id").to_string();

    let listed = json_of(get(&server.url("/api/layers")).await).await;
    let names: Vec<&str> =
        listed["layers"].as_array().expect("layers").iter().filter_map(|l| l["name"].as_str()).collect();
    assert_eq!(names, ["Air temperature", "Form ramp"]);
    assert_eq!(json_of(get(&server.url(&location)).await).await, series);

    let png = get(&server.url(&format!("/api/layers/{id}/legend.png?colormap=magma&range=0,20"))).await;
    assert_eq!(png.status(), StatusCode::OK);
    assert_eq!(png.headers()["content-type"], "image/png");
    let image = image::load_from_memory(&png.bytes().await.expect("PNG")).expect("a valid PNG");
    assert_eq!((image.width(), image.height()), (LEGEND_WIDTH, SCALAR_LEGEND_HEIGHT));

    let legend =
        json_of(get(&server.url(&format!("/api/layers/{id}/legend.json?opacity=0.5&reverse=true"))).await).await;
    assert_eq!(legend["title"], "Air temperature");
    assert_eq!((legend["colormap"].as_str(), legend["units"].as_str()), (Some("viridis"), Some("degC")), "{legend}");
    assert_eq!(legend["range"], serde_json::json!([0.0, 17.0]));
    assert!(legend["opacity"].as_f64().is_some_and(|o| (o - 0.5).abs() < 0.01), "{legend}");
    assert_eq!(legend["stops"].as_array().map(Vec::len), Some(16));
    let magma =
        json_of(get(&server.url(&format!("/api/layers/{id}/legend.json?colormap=magma&range=0,20"))).await).await;
    assert_eq!((magma["colormap"].as_str(), &magma["range"]), (Some("magma"), &serde_json::json!([0.0, 20.0])));

    // A hatch colour's legend: the ramp from paper to its ink.
    let ink =
        json_of(get(&server.url(&format!("/api/layers/{id}/legend.json?target=hatch_color&color=0,0,1"))).await).await;
    assert_eq!((ink["target"].as_str(), ink["color"].as_str()), (Some("hatch_color"), Some("#0000ff")), "{ink}");
    assert_eq!((ink["stops"][0].as_str(), ink["stops"][15].as_str()), (Some("#ffffff"), Some("#0000ff")), "{ink}");
    assert!(ink.get("colormap").is_none(), "{ink}");
    let legend_url = |query: &str| server.url(&format!("/api/layers/{id}/legend.json?{query}"));
    assert_error(get(&legend_url("target=hatch_color&color=0,0,3")).await, 422, "invalid_parameter", Some("color"))
        .await;
    assert_error(get(&legend_url("color=0,0,1")).await, 422, "invalid_parameter", Some("color")).await;
    assert_error(get(&legend_url("opacity=2")).await, 422, "invalid_parameter", Some("opacity")).await;
    assert_error(get(&legend_url("range=5,5")).await, 422, "invalid_parameter", Some("range")).await;
    assert_error(get(&legend_url("colormap=plaid")).await, 422, "invalid_parameter", Some("colormap")).await;
    assert_error(get(&legend_url("colour=red")).await, 400, "bad_request", Some("colour")).await;

    // Unknown ids, including ones that look like paths.
    for path in ["/api/layers/no-such-layer", "/api/layers/no-such-layer/legend.png", "/api/layers/..%2F..%2Fetc"] {
        assert_error(get(&server.url(path)).await, 404, "not_found", None).await;
    }
    assert_error(delete(&server.url("/api/layers/no-such-layer")).await, 404, "not_found", None).await;

    let deleted = delete(&server.url(&location)).await;
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    let message = assert_error(get(&server.url(&location)).await, 404, "not_found", None).await;
    assert!(message.contains(&id), "{message}");
    assert_error(delete(&server.url(&location)).await, 404, "not_found", None).await;
    let listed = json_of(get(&server.url("/api/layers")).await).await;
    assert_eq!(listed["layers"].as_array().map(Vec::len), Some(1));
    assert!(!dir.path().join("layers").join(&id).exists());
    assert!(dir.path().join("layers").join(&form_id).join("meta.json").is_file());

    // Documented and counted like every other route.
    let openapi = json_of(get(&server.url("/api/openapi.json")).await).await;
    for (path, method) in [
        ("/api/layers", "get"),
        ("/api/layers", "post"),
        ("/api/layers/{id}", "get"),
        ("/api/layers/{id}", "delete"),
        ("/api/layers/{id}/legend.png", "get"),
        ("/api/layers/{id}/legend.json", "get"),
    ] {
        assert!(openapi["paths"][path][method].is_object(), "OpenAPI lacks {method} {path}");
    }
    assert!(openapi["components"]["schemas"]["LayerMeta"].is_object());
    // Mappings are described with their targets and the hatch colour's ink.
    let targets = &openapi["components"]["schemas"]["MappingTarget"]["enum"];
    assert!(targets.as_array().is_some_and(|t| t.contains(&Value::from("hatch_color"))), "{targets}");
    assert!(openapi["components"]["schemas"]["Mapping"]["properties"]["color"].is_object());
    let metrics = get(&server.url("/metrics")).await.text().await.expect("metrics");
    for line in [
        r#"route="/api/layers",method="POST",status="201""#,
        r#"route="/api/layers/{id}",method="DELETE",status="204""#,
        r#"route="/api/layers/{id}/legend.png",method="GET",status="200""#,
    ] {
        assert!(metrics.contains(line), "metrics lack {line}:\n{metrics}");
    }
}

#[tokio::test]
async fn bad_uploads_get_errors_and_leave_the_store_unchanged() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| c.max_upload = 64 << 10);
    assert_eq!(upload(&server, "name=Kept&kind=scalar", scene_tiff(0.0)).await.status(), StatusCode::CREATED);
    let before = tree(dir.path());
    let listed = json_of(get(&server.url("/api/layers")).await).await;

    let garbage = b"this is not a raster at all".repeat(20);
    assert_error(
        upload(&server, "name=Garbage&kind=scalar&filename=x.tif", garbage.clone()).await,
        422,
        "invalid_parameter",
        None,
    )
    .await;
    assert_error(upload(&server, "name=Garbage&kind=scalar", Vec::new()).await, 422, "invalid_parameter", None).await;
    let outside = upload(
        &server,
        "name=Ramp&kind=scalar&crs=EPSG:4326&filename=ramp.asc",
        fixture("fields/ramp_scalar_4326.asc"),
    )
    .await;
    let message = assert_error(outside, 422, "invalid_parameter", None).await;
    assert!(message.contains("field extent") && message.contains("scene extent"), "{message}");
    assert!(message.contains("-105.5") && message.contains("-105.4"), "both extents in degrees: {message}");
    assert_error(upload(&server, "kind=scalar", scene_tiff(0.0)).await, 422, "invalid_parameter", Some("name")).await;
    assert_error(upload(&server, "name=K&kind=vector", scene_tiff(0.0)).await, 422, "invalid_parameter", Some("kind"))
        .await;
    assert_error(upload(&server, "name=K", scene_tiff(0.0)).await, 422, "invalid_parameter", None).await;
    assert_error(upload(&server, "name=K&kind=scalar&colour=red", scene_tiff(0.0)).await, 400, "bad_request", None)
        .await;
    assert_error(
        upload(&server, "name=K&kind=scalar&time=June", scene_tiff(0.0)).await,
        422,
        "invalid_parameter",
        None,
    )
    .await;
    // A time step for a layer without time conflicts with it.
    assert_error(
        upload(&server, "name=Kept&kind=scalar&time=2024-06-01", scene_tiff(0.0)).await,
        409,
        "conflict",
        None,
    )
    .await;
    let huge = vec![0u8; 100 << 10];
    assert_error(upload(&server, "name=Huge&kind=scalar", huge.clone()).await, 413, "too_large", Some("body")).await;
    let (content_type, body) = multipart(&[("name", "Huge"), ("kind", "scalar")], "huge.tif", &huge);
    let form = client().post(server.url("/api/layers")).header("content-type", content_type).body(body).send().await;
    assert_error(form.expect("POST"), 413, "too_large", Some("body")).await;
    let (content_type, body) = multipart(&[("name", "Garbage"), ("kind", "scalar")], "g.tif", &garbage);
    let form = client().post(server.url("/api/layers")).header("content-type", content_type).body(body).send().await;
    assert_error(form.expect("POST"), 422, "invalid_parameter", None).await;

    assert_eq!(tree(dir.path()), before, "files changed");
    assert_eq!(json_of(get(&server.url("/api/layers")).await).await, listed, "listing changed");
}

/// The 4096 × 4096 cell limit holds however an ESRI ASCII grid lays out its header: a
/// byte-order mark before a key or kilobytes of blank lines between keys are read as the
/// reader reads them, and the upload is refused with 413 before any value is decoded.
#[tokio::test]
async fn ascii_grids_over_the_cell_limit_are_refused_however_the_header_is_laid_out() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let before = tree(dir.path());
    let tail = "xllcorner -105.3\nyllcorner 40.0\ncellsize 0.00001\n1 2 3\n";
    for (what, grid) in [
        ("byte-order mark", format!("ncols 4200\n\u{feff}nrows 4200\n{tail}")),
        ("blank lines", format!("ncols 4472\n{}nrows 4472\n{tail}", "\n".repeat(4096))),
    ] {
        let response = upload(&server, "name=Big&kind=scalar&crs=scene&filename=big.asc", grid.into_bytes()).await;
        let message = assert_error(response, 413, "too_large", None).await;
        assert!(message.contains("big.asc") && message.contains("cells"), "{what}: {message}");
    }
    assert_eq!(tree(dir.path()), before, "nothing stored");
}

/// How a decompression bomb blows up.
#[derive(Debug, Clone, Copy)]
enum Bomb {
    /// 4096 × 4096 cells of 29 Float32 samples in one-row strips that all point to the same
    /// deflated row: 1.95 GB decoded from about 33 KB.
    Samples,
    /// 4096 × 4096 Float32 cells in tiles 65536 wide (the decoder decompresses and discards
    /// their padding) that all point to the same deflated tile: 1 GiB decoded.
    TilePadding,
}

/// A little-endian GeoTIFF (EPSG:4326, over the sample scene) whose strips or tiles all
/// point to one small Deflate stream of zeros: what the probe uploaded (D4).
fn bomb_tiff(bomb: Bomb) -> Vec<u8> {
    use std::io::Write;
    const SIDE: u32 = 4096;
    let (samples, chunk_width, chunk_rows) = match bomb {
        Bomb::Samples => (29u16, SIDE, 1u32),
        Bomb::TilePadding => (1, 65536, 16),
    };
    let chunk_bytes = chunk_width as usize * chunk_rows as usize * usize::from(samples) * 4;
    let mut zlib = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    zlib.write_all(&vec![0u8; chunk_bytes]).expect("deflate");
    let blob = zlib.finish().expect("deflate");
    let chunks = SIDE.div_ceil(chunk_rows) * SIDE.div_ceil(chunk_width);
    let e = loaded().0.terrain.dem.extent();
    let offsets = vec![DATA_OFFSET; chunks as usize];
    let counts = vec![blob.len() as u32; chunks as usize];
    let (offsets_tag, counts_tag) = match bomb {
        Bomb::Samples => (273, 279),
        Bomb::TilePadding => (324, 325),
    };
    let mut entries: Vec<Entry> = vec![
        (256, LONG, 1, longs(&[SIDE])),
        (257, LONG, 1, longs(&[SIDE])),
        (258, SHORT, u32::from(samples), shorts(&vec![32; usize::from(samples)])),
        (259, SHORT, 1, shorts(&[8])),
        (262, SHORT, 1, shorts(&[1])),
        (offsets_tag, LONG, chunks, longs(&offsets)),
        (277, SHORT, 1, shorts(&[samples])),
        (counts_tag, LONG, chunks, longs(&counts)),
        (284, SHORT, 1, shorts(&[1])),
        (339, SHORT, u32::from(samples), shorts(&vec![3; usize::from(samples)])),
    ];
    entries.extend(geographic_entries(SIDE, SIDE, e.min_x, e.min_y, e.max_x, e.max_y));
    match bomb {
        Bomb::Samples => {
            entries.push((278, LONG, 1, longs(&[chunk_rows])));
            entries.push((338, SHORT, u32::from(samples - 1), shorts(&vec![0; usize::from(samples - 1)])));
        }
        Bomb::TilePadding => {
            entries.push((322, LONG, 1, longs(&[chunk_width])));
            entries.push((323, LONG, 1, longs(&[chunk_rows])));
        }
    }
    tiff_file(&blob, entries)
}

/// D4: GeoTIFFs within the cell limit whose strips or tiles decode to gigabytes are refused
/// with 413 from their tags, before anything is decompressed; nothing is stored.
#[tokio::test]
async fn geotiff_decompression_bombs_are_refused_before_decoding() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let before = tree(dir.path());
    for bomb in [Bomb::Samples, Bomb::TilePadding] {
        let file = bomb_tiff(bomb);
        assert!(file.len() < 40_000, "{bomb:?}: {} bytes", file.len());
        let started = std::time::Instant::now();
        let response = upload(&server, "name=Bomb&kind=scalar&filename=bomb.tif", file).await;
        let message = assert_error(response, 413, "too_large", None).await;
        assert!(message.contains("bomb.tif") && message.contains("decoded"), "{bomb:?}: {message}");
        assert!(started.elapsed() < std::time::Duration::from_secs(5), "{bomb:?} took {:?}", started.elapsed());
    }
    assert_eq!(tree(dir.path()), before, "nothing stored");
}

/// An ESRI ASCII grid of 2 × 2 cells with its lower-left corner on the sample scene's DEM's,
/// the given cell size and values (uploaded with `crs=scene`).
fn scene_grid(cellsize: f64, values: &str) -> Vec<u8> {
    let e = loaded().0.terrain.dem.extent();
    format!("ncols 2\nnrows 2\nxllcorner {}\nyllcorner {}\ncellsize {cellsize:e}\n{values}\n", e.min_x, e.min_y)
        .into_bytes()
}

/// D5: values beyond the f32 range and an absurd cell size (1e306) are refused at upload
/// (422, nothing stored) instead of being stored and failing every render or the next start.
#[tokio::test]
async fn layers_that_could_not_be_rendered_or_reloaded_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let before = tree(dir.path());
    let cell = {
        let e = loaded().0.terrain.dem.extent();
        (e.max_x - e.min_x) / 2.0
    };
    for (what, grid, expected) in [
        ("f32 overflow", scene_grid(cell, "1 2\n3 1e39"), "1e39"),
        ("negative f32 overflow", scene_grid(cell, "-4e38 2\n3 4"), "-4e38"),
        ("absurd cell size", scene_grid(1e306, "1 2\n3 4"), "extent"),
    ] {
        let response = upload(&server, "name=Huge&kind=scalar&crs=scene&filename=huge.asc", grid).await;
        let message = assert_error(response, 422, "invalid_parameter", None).await;
        assert!(message.contains("huge.asc") && message.contains(expected), "{what}: {message}");
    }
    assert_eq!(tree(dir.path()), before, "nothing stored");
    assert!(json_of(get(&server.url("/api/layers")).await).await["layers"].as_array().is_some_and(Vec::is_empty));
}

/// D5: a layer directory whose `meta.json` is damaged is skipped at start-up; it never makes
/// a later upload under the same name fail (the new layer gets another id).
#[tokio::test]
async fn a_damaged_layer_directory_does_not_block_its_name() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let first = json_of(upload(&server, STEP_1, scene_tiff(0.0)).await).await;
    let id = first["id"].as_str().expect("id").to_owned();
    server.stop().expect("clean stop");
    std::fs::write(dir.path().join("layers").join(&id).join("meta.json"), "{").expect("damage meta.json");
    let server = TestServer::start(dir.path(), |_| {});
    assert_eq!(get(&server.url(&format!("/api/layers/{id}"))).await.status(), StatusCode::NOT_FOUND);
    let again = upload(&server, STEP_1, scene_tiff(0.0)).await;
    assert_eq!(again.status(), StatusCode::CREATED);
    let again = json_of(again).await;
    assert_ne!(again["id"], id.as_str(), "a new id");
    let rendered = get(&server.url(&format!("/api/layers/{}/legend.json", again["id"].as_str().expect("id")))).await;
    assert_eq!(rendered.status(), StatusCode::OK);
    assert!(dir.path().join("layers").join(&id).exists(), "the damaged directory is left for inspection");
}

/// D7: while a large time step is appended, the store's index stays readable: `/api/health`
/// answers within 100 ms even with layer listings in flight, and the append neither reads
/// the stored steps nor loses them.
#[tokio::test]
async fn health_answers_quickly_during_a_large_append() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let step = |day: u32| format!("name=Big&kind=scalar&time=2024-06-{day:02}T00:00:00Z&filename=big{day}.tif");
    let big = sized_scene_tiff(2048, 2048, 0.0);
    for day in 1..=2 {
        assert!(upload(&server, &step(day), big.clone()).await.status().is_success());
    }
    let append = {
        let url = server.url(&format!("/api/layers?{}", step(3)));
        tokio::spawn(async move { client().post(url).body(sized_scene_tiff(2048, 2048, 5.0)).send().await })
    };
    let mut latencies = Vec::new();
    while !append.is_finished() {
        // Listings take the index; two keep the server's two worker threads busy with it.
        let listings: Vec<_> = (0..2).map(|_| tokio::spawn(get_owned(server.url("/api/layers")))).collect();
        let started = std::time::Instant::now();
        assert_eq!(get(&server.url("/api/health")).await.status(), StatusCode::OK);
        latencies.push(started.elapsed());
        for listing in listings {
            assert_eq!(listing.await.expect("listing"), StatusCode::OK);
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    let appended = append.await.expect("append task").expect("append");
    assert_eq!(appended.status(), StatusCode::OK);
    let meta = json_of(appended).await;
    assert_eq!(meta["steps"].as_array().map(Vec::len), Some(3));
    assert_eq!((meta["min"].as_f64(), meta["max"].as_f64()), (Some(0.0), Some(5.0 + 2047.0)));
    // On a loaded test machine a poll may miss its time slice (one in ten, and at least one:
    // a short append makes few polls); a store lock held across the append's writes would
    // stall every poll behind it instead.
    latencies.sort();
    let limit = std::time::Duration::from_millis(100);
    let slow = latencies.iter().filter(|l| **l > limit).count();
    assert!(
        latencies.len() >= 3 && slow <= (latencies.len() / 10).max(1),
        "{slow} of {} polls over {limit:?}: {latencies:?}",
        latencies.len()
    );
    assert!(latencies.last().is_some_and(|l| *l < std::time::Duration::from_secs(1)), "{latencies:?}");
}

/// The status of a GET of an owned URL (for spawned requests).
async fn get_owned(url: String) -> StatusCode {
    get(&url).await.status()
}

/// Text fields of an upload refuse control characters (422 naming the field), and error
/// messages cut long client input short.
#[tokio::test]
async fn upload_text_fields_refuse_control_characters_and_errors_bound_echoes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let before = tree(dir.path());
    for (query, parameter) in [
        ("name=K&kind=scalar&units=deg%07C", "units"),
        ("name=K&kind=scalar&units=%1B%5B31mred", "units"),
        ("name=K%0AL&kind=scalar", "name"),
        ("name=K&kind=scalar&filename=a%00.tif", "filename"),
    ] {
        let message =
            assert_error(upload(&server, query, scene_tiff(0.0)).await, 422, "invalid_parameter", Some(parameter))
                .await;
        assert!(message.contains("control characters"), "{query}: {message}");
    }
    let long = "x".repeat(20_000);
    for query in [
        format!("name=K&kind=scalar&time={long}"),
        format!("name=K&kind=scalar&crs={long}"),
        format!("name=K&kind=label&classes={long}"),
        format!("name=K&kind=scalar&filename={long}.asc"),
        format!("name=K&kind=scalar&units={long}"),
    ] {
        let response = upload(&server, &query, scene_tiff(0.0)).await;
        assert!(response.status().is_client_error(), "{}", response.status());
        let body = json_of(response).await;
        let message = body["error"]["message"].as_str().expect("message");
        assert!(message.len() < 1000, "{} bytes: {}", message.len(), message.chars().take(200).collect::<String>());
    }
    let missing = get(&server.url(&format!("/api/layers/{}", "y".repeat(5000)))).await;
    let message = assert_error(missing, 404, "not_found", None).await;
    assert!(message.len() < 200 && message.contains('…'), "{message}");
    assert_eq!(tree(dir.path()), before, "nothing stored");
}

#[tokio::test]
async fn concurrent_uploads_all_land() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let mut tasks = Vec::new();
    for i in 0..6 {
        let url = server.url(&format!("/api/layers?name=Layer%20{i}&kind=scalar"));
        tasks.push(tokio::spawn(client().post(url).body(scene_tiff(f64::from(i))).send()));
        let url = server.url(&format!("/api/layers?name=Series&kind=scalar&time=2024-06-{:02}", i + 1));
        tasks.push(tokio::spawn(client().post(url).body(scene_tiff(f64::from(i))).send()));
    }
    for task in tasks {
        let response = task.await.expect("task").expect("POST");
        assert!(response.status().is_success(), "{}", response.status());
    }
    let listed = json_of(get(&server.url("/api/layers")).await).await;
    let layers = listed["layers"].as_array().expect("layers");
    assert_eq!(layers.len(), 7, "{listed}");
    let series = layers.iter().find(|l| l["name"] == "Series").expect("the series");
    assert_eq!(series["steps"].as_array().map(Vec::len), Some(6), "{series}");
    drop(server);
    // What the store wrote reads back completely.
    let reopened = landsketch::store::Store::open(dir.path()).expect("reopen");
    assert_eq!(reopened.list().len(), 7);
    assert_eq!(reopened.field(series["id"].as_str().expect("id")).expect("series data").steps().len(), 6);
}

#[tokio::test]
async fn layers_survive_a_restart() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let meta = json_of(upload(&server, STEP_1, scene_tiff(0.0)).await).await;
    let id = meta["id"].as_str().expect("id").to_string();
    server.stop().expect("clean shutdown");

    let server = TestServer::start(dir.path(), |_| {});
    let listed = json_of(get(&server.url("/api/layers")).await).await;
    assert_eq!(listed["layers"], Value::Array(vec![meta.clone()]));
    assert_eq!(json_of(get(&server.url(&format!("/api/layers/{id}"))).await).await, meta);
    let png = get(&server.url(&format!("/api/layers/{id}/legend.png"))).await;
    assert_eq!(png.status(), StatusCode::OK);
    // The series goes on after the restart.
    let appended = upload(&server, STEP_2, scene_tiff(1.0)).await;
    assert_eq!(appended.status(), StatusCode::OK);
    assert_eq!(json_of(appended).await["steps"].as_array().map(Vec::len), Some(2));
}

#[tokio::test]
async fn writes_need_the_admin_token() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| c.admin_token = Some("s3cret".into()));
    let url = server.url(&format!("/api/layers?{STEP_1}"));
    let missing = client().post(&url).body(scene_tiff(0.0)).send().await.expect("POST");
    assert_eq!(missing.headers()["www-authenticate"], "Bearer");
    assert_error(missing, 401, "unauthorized", None).await;
    let wrong = client().post(&url).bearer_auth("guess").body(scene_tiff(0.0)).send().await.expect("POST");
    assert_error(wrong, 401, "unauthorized", None).await;
    assert!(tree(&dir.path().join("layers")).is_empty());

    let created = client().post(&url).bearer_auth("s3cret").body(scene_tiff(0.0)).send().await.expect("POST");
    assert_eq!(created.status(), StatusCode::CREATED);
    let location = server.url(created.headers()["location"].to_str().expect("ASCII"));
    // Reading stays public; deleting needs the token too.
    assert_eq!(get(&location).await.status(), StatusCode::OK);
    assert_eq!(get(&server.url("/api/layers")).await.status(), StatusCode::OK);
    assert_error(delete(&location).await, 401, "unauthorized", None).await;
    let deleted = client().delete(&location).bearer_auth("s3cret").send().await.expect("DELETE");
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
}

/// D9: without a token, a foreign-origin multipart upload and a DELETE naming a foreign `Host`
/// are refused (CSRF, DNS rebinding); nothing is stored or deleted.
#[tokio::test]
async fn tokenless_writes_refuse_foreign_origins_and_hosts() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let (content_type, body) = multipart(&[("name", "Forged"), ("kind", "scalar")], "forged.tif", &scene_tiff(0.0));
    let forged = client().post(server.url("/api/layers")).header("origin", "https://attacker.example");
    let forged = forged.header("content-type", content_type).body(body).send().await.expect("POST");
    assert_error(forged, 403, "forbidden", None).await;
    assert!(tree(&dir.path().join("layers")).is_empty());
    let created = upload(&server, STEP_1, scene_tiff(0.0)).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let location = server.url(created.headers()["location"].to_str().expect("ASCII"));
    let rebound = client().delete(&location).header("host", "attacker.example").send().await.expect("DELETE");
    assert_error(rebound, 403, "forbidden", None).await;
    assert_eq!(get(&location).await.status(), StatusCode::OK, "still there");
}

/// POSTs a render body; returns the response.
async fn render(server: &TestServer, body: Value) -> reqwest::Response {
    let request = client().post(server.url("/api/render")).header("content-type", "application/json");
    request.body(body.to_string()).send().await.expect("POST /api/render")
}

#[tokio::test]
async fn renders_show_data_layers_in_plan_view_with_table_9_1_warnings() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let meta = json_of(upload(&server, STEP_1, scene_tiff(0.0)).await).await;
    assert_eq!(upload(&server, STEP_2, scene_tiff(10.0)).await.status(), StatusCode::OK);
    let id = meta["id"].as_str().expect("id").to_string();
    let camera = serde_json::json!({"mode": "plan", "center": [0, 0], "width": 2000});
    let colour = serde_json::json!([{"layer": id, "target": "color", "colormap": "magma"}]);

    let plain = render(&server, serde_json::json!({"camera": camera, "width": 64, "height": 48})).await;
    assert_eq!(plain.status(), StatusCode::OK);
    let plain = image::load_from_memory(&plain.bytes().await.expect("body")).expect("PNG").to_rgba8();
    let body = serde_json::json!({"camera": camera, "width": 64, "height": 48, "mappings": colour,
        "time": "2024-06-01T12:00:00Z"});
    let coloured = render(&server, body.clone()).await;
    assert_eq!(coloured.status(), StatusCode::OK);
    assert!(coloured.headers().get("warning").is_none(), "colour suits scalars");
    let link = coloured.headers()["content-location"].to_str().expect("ASCII").to_string();
    assert!(link.contains("mode=plan") && link.contains("mappings=") && link.contains("time="), "{link}");
    let bytes = coloured.bytes().await.expect("body");
    let image = image::load_from_memory(&bytes).expect("PNG").to_rgba8();
    let changed = image.pixels().zip(plain.pixels()).filter(|(a, b)| a != b).count();
    assert!(changed > image.pixels().len() / 2, "the plan view is coloured ({changed} pixels changed)");
    // The query form of the view renders the same bytes.
    let again = get(&server.url(&link)).await;
    assert_eq!(again.bytes().await.expect("body"), bytes);

    // Table 9.1: a scalar as silhouette style is unsuitable → a Warning header, still an image.
    let body = serde_json::json!({"camera": camera, "width": 32, "height": 24,
        "mappings": [{"layer": id, "target": "silhouette_style"}], "time": "2030-01-01"});
    let warned = render(&server, body).await;
    assert_eq!(warned.status(), StatusCode::OK);
    let warnings: Vec<String> =
        warned.headers().get_all("warning").iter().map(|v| v.to_str().expect("ASCII").to_string()).collect();
    assert!(warnings.iter().any(|w| w.contains("not quantifiable") && w.contains("Table 9.1")), "{warnings:?}");
    assert!(warnings.iter().any(|w| w.contains("after the last") && w.contains("clamped")), "{warnings:?}");

    // Abstraction is drawn per plant (a scalar: a Table 9.1 caution).
    let body = serde_json::json!({"camera": camera, "width": 32, "height": 24,
        "mappings": [{"layer": id, "target": "abstraction"}]});
    let abstracted = render(&server, body).await;
    assert_eq!(abstracted.status(), StatusCode::OK);
    let warnings: Vec<String> =
        abstracted.headers().get_all("warning").iter().map(|v| v.to_str().expect("ASCII").to_string()).collect();
    assert!(warnings.iter().any(|w| w.contains("low-precision")), "{warnings:?}");

    // Unknown layers are 404s; bad times and a fourth mapping 422s.
    let unknown = serde_json::json!({"mappings": [{"layer": "nope", "target": "color"}]});
    assert_error(render(&server, unknown).await, 404, "not_found", None).await;
    let bad_time = serde_json::json!({"mappings": colour, "time": "yesterday"});
    assert_error(render(&server, bad_time).await, 422, "invalid_parameter", Some("time")).await;
    let four = serde_json::json!({"mappings": [colour[0], colour[0], colour[0], colour[0]]});
    let message = assert_error(render(&server, four).await, 422, "invalid_parameter", Some("mappings")).await;
    assert!(message.contains("at most 3"), "{message}");
    let plan_pitch = serde_json::json!({"camera": {"mode": "plan", "pitch": -30}});
    assert_error(render(&server, plan_pitch).await, 422, "invalid_parameter", Some("camera.pitch")).await;
}

#[tokio::test]
async fn a_geojson_label_layer_uploads_and_maps_like_the_same_labels_as_a_raster() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    // Two zones splitting the sample scene's DEM at its middle meridian: class 1 west, 2 east.
    let e = loaded().0.terrain.dem.extent();
    let mid = 0.5 * (e.min_x + e.max_x);
    let zone = |x0: f64, x1: f64, class: u32| {
        let ring = [(x0, e.min_y), (x1, e.min_y), (x1, e.max_y), (x0, e.max_y), (x0, e.min_y)];
        let ring: Vec<String> = ring.iter().map(|(x, y)| format!("[{x}, {y}]")).collect();
        format!(
            r#"{{"type": "Feature", "properties": {{"zone": {class}}}, "geometry": {{"type": "Polygon", "coordinates": [[{}]]}}}}"#,
            ring.join(", ")
        )
    };
    let geojson = format!(
        r#"{{"type": "FeatureCollection", "features": [{}, {}]}}"#,
        zone(e.min_x, mid, 1),
        zone(mid, e.max_x, 2)
    );
    let created =
        upload(&server, "name=Zones&kind=label&variable=zone&filename=zones.geojson", geojson.into_bytes()).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let zones = json_of(created).await;
    assert_eq!(
        (zones["kind"].as_str(), zones["crs"].as_str(), zones["source"].as_str()),
        (Some("label"), Some("EPSG:4326"), Some("zones.geojson")),
        "{zones}"
    );
    assert_eq!((zones["min"].as_f64(), zones["max"].as_f64()), (Some(1.0), Some(2.0)), "{zones}");
    // The same split as a label GeoTIFF: 8 columns, 1 in the western four, 2 in the eastern.
    let raster = Raster {
        width: 8,
        height: 6,
        data: (0..48).map(|i| if i % 8 < 4 { 1.0 } else { 2.0 }).collect(),
        nodata: None,
        transform: GeoTransform {
            origin_x: e.min_x,
            origin_y: e.max_y,
            cell_width: (e.max_x - e.min_x) / 8.0,
            cell_height: (e.max_y - e.min_y) / 6.0,
        },
        crs: Crs::Geographic { epsg: Some(4326) },
        palette: None,
    };
    let tif = dir.path().join("zones.tif");
    write_geotiff_f32(&tif, &raster).expect("write GeoTIFF");
    let created =
        upload(&server, "name=Zones%20raster&kind=label&filename=zones.tif", std::fs::read(&tif).expect("read")).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let raster_id = json_of(created).await["id"].as_str().expect("id").to_string();

    // Both map to colour in a plan view the same way: the halves differ, the layers agree.
    let camera = serde_json::json!({"mode": "plan", "center": [0, 0], "width": 2000});
    let view = |layer: &str| {
        serde_json::json!({"camera": camera, "width": 96, "height": 64,
            "mappings": [{"layer": layer, "target": "color", "colormap": "tableau10"}]})
    };
    let picture = |response: reqwest::Response| async move {
        assert_eq!(response.status(), StatusCode::OK);
        image::load_from_memory(&response.bytes().await.expect("body")).expect("PNG").to_rgba8()
    };
    let from_json = picture(render(&server, view(zones["id"].as_str().expect("id"))).await).await;
    let from_tif = picture(render(&server, view(&raster_id)).await).await;
    let close = |a: &image::Rgba<u8>, b: &image::Rgba<u8>| a.0.iter().zip(b.0).all(|(x, y)| x.abs_diff(y) <= 8);
    let agree = from_json.pixels().zip(from_tif.pixels()).filter(|(a, b)| close(a, b)).count();
    let total = from_json.pixels().len();
    assert!(agree * 100 >= total * 97, "only {agree} of {total} pixels agree");
    // Mean colour of the western and eastern quarters (the zones' middles) differ.
    let mean = |image: &image::RgbaImage, x0: u32, x1: u32| {
        let mut sum = [0f64; 3];
        for y in 0..image.height() {
            for x in x0..x1 {
                let p = image.get_pixel(x, y);
                (0..3).for_each(|c| sum[c] += f64::from(p[c]));
            }
        }
        sum.map(|v| v / f64::from((x1 - x0) * image.height()))
    };
    let (west, east) = (mean(&from_json, 8, 32), mean(&from_json, 64, 88));
    let apart: f64 = west.iter().zip(east).map(|(a, b)| (a - b).abs()).sum();
    assert!(apart > 30.0, "west {west:?} and east {east:?} look alike");
    // A GeoJSON upload given as a scalar is refused by name, nothing stored.
    let before = tree(dir.path());
    let scalar = upload(&server, "name=Zones2&kind=scalar&filename=zones.geojson", b"{}".to_vec()).await;
    assert_eq!(scalar.status().as_u16(), 422);
    assert_eq!(tree(dir.path()), before);
}

// ---------------------------------------------------------------------------------------------
// WebSocket `data` messages

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The next message of a session: JSON, or a binary frame with its header.
async fn next_message(socket: &mut Socket) -> Result<Value, (FrameHeader, image::RgbaImage)> {
    loop {
        let message = tokio::time::timeout(std::time::Duration::from_secs(60), socket.next())
            .await
            .expect("a message in time")
            .expect("the session stays open")
            .expect("a message");
        match message {
            Message::Text(text) => return Ok(serde_json::from_str(text.as_str()).expect("JSON message")),
            Message::Binary(bytes) => {
                let header = FrameHeader::decode(&bytes).expect("frame header");
                let image = image::load_from_memory(&bytes[HEADER_LEN..]).expect("PNG or JPEG frame").to_rgba8();
                return Err((header, image));
            }
            Message::Close(frame) => panic!("closed: {frame:?}"),
            _ => {}
        }
    }
}

/// The JSON messages up to the next still frame, and that frame (interactive frames are skipped).
async fn next_still(socket: &mut Socket) -> (Vec<Value>, FrameHeader, image::RgbaImage) {
    let mut messages = Vec::new();
    loop {
        match next_message(socket).await {
            Ok(json) => messages.push(json),
            Err((header, image)) if header.still => return (messages, header, image),
            Err(_) => {}
        }
    }
}

/// The `error` message answering a rejected control (no frame comes first: nothing changed).
async fn next_error(socket: &mut Socket) -> Value {
    match next_message(socket).await {
        Ok(json) if json["type"] == "error" => json,
        Ok(json) => panic!("an error message, not {json}"),
        Err((header, _)) => panic!("an error message, not frame {}", header.frame_id),
    }
}

async fn send_json(socket: &mut Socket, message: Value) {
    socket.send(Message::text(message.to_string())).await.expect("send");
}

/// The entry of `lut` nearest to `pixel` as it shows on the default paper.
fn nearest_entry(lut: &Lut, pixel: &image::Rgba<u8>) -> usize {
    let paper = landsketch::render::Style::default().paper;
    let distance = |c: &[u8; 4]| (0..3).map(|i| (f32::from(c[i]) * paper[i] - f32::from(pixel[i])).abs()).sum::<f32>();
    (0..lut.colors.len()).min_by(|&a, &b| distance(&lut.colors[a]).total_cmp(&distance(&lut.colors[b]))).unwrap_or(0)
}

#[tokio::test]
async fn websocket_data_messages_map_layers_and_bad_ones_get_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let id = json_of(upload(&server, STEP_1, scene_tiff(0.0)).await).await["id"].as_str().expect("id").to_string();
    // A north-up plan view of the scene's middle (it spans ±958 m east–west) without strokes,
    // so the data's colours show on paper. The layer grows east by 1 per eighth of the scene,
    // from about 0.2 to 6.8 across the view and 3.5 in its middle.
    let style = r#"{"hatch_strength": 0, "contour_strength": 0, "silhouette_strength": 0}"#;
    let query = format!(
        "mode=plan&center=0,0&plan_width=1600&yaw=0&width=64&height=48&style={}",
        form_urlencoded::byte_serialize(style.as_bytes()).collect::<String>()
    );
    let (mut socket, _) = tokio_tungstenite::connect_async(server.ws_url(&query)).await.expect("WebSocket");
    let (_, first, plain) = next_still(&mut socket).await;
    assert_eq!(first.seq, 0);

    // Colour: the next still shows the colour map over the layer's values.
    let colour = serde_json::json!({"layer": id, "target": "color", "colormap": "magma"});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [colour]})).await;
    let (messages, header, coloured) = next_still(&mut socket).await;
    let answer = messages.iter().find(|m| m["type"] == "data").expect("a data message");
    assert_eq!(answer["warnings"], serde_json::json!([]), "colour suits scalars: {answer}");
    assert_eq!(header.seq, 1);
    let changed = coloured.pixels().zip(plain.pixels()).filter(|(a, b)| a != b).count();
    assert!(changed > coloured.pixels().len() * 9 / 10, "the frame is coloured ({changed} pixels changed)");
    let spec = ColorMapSpec { map: Some(ColorMapName::Magma), ..ColorMapSpec::default() };
    let lut = Lut::for_scalar(&spec, (0.0, 7.0)).expect("table");
    let paper = landsketch::render::Style::default().paper;
    for pixel in coloured.pixels() {
        let entry = lut.colors[nearest_entry(&lut, pixel)];
        let off = (0..3).map(|i| (f32::from(entry[i]) * paper[i] - f32::from(pixel[i])).abs()).fold(0.0, f32::max);
        assert!(off <= 6.0, "{pixel:?} is a magma colour on paper (nearest {entry:?})");
    }
    let row: Vec<usize> = (0..64).map(|x| nearest_entry(&lut, coloured.get_pixel(x, 24))).collect();
    assert!(row.windows(2).all(|w| w[1] + 2 >= w[0]), "magma runs west to east: {row:?}");
    assert!(row[0] < 20 && row[63] > 235 && row[31].abs_diff(128) <= 10, "{row:?}");

    // Bad mappings: an error naming the problem, nothing changes, the session goes on.
    let unknown = serde_json::json!({"layer": "no-such-layer", "target": "color"});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [unknown]})).await;
    let error = next_error(&mut socket).await;
    assert_eq!(error["code"], "not_found", "{error}");
    assert!(error["message"].as_str().is_some_and(|m| m.contains("no-such-layer")), "{error}");
    let too_opaque = serde_json::json!({"layer": id, "target": "color", "opacity": 2});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [too_opaque]})).await;
    let error = next_error(&mut socket).await;
    assert_eq!((error["code"].as_str(), error["parameter"].as_str()), (Some("invalid_parameter"), Some("mappings")));
    assert!(error["message"].as_str().is_some_and(|m| m.contains("opacity 2")), "{error}");
    let too_bright = serde_json::json!({"layer": id, "target": "hatch_color", "color": [0, 2, 0]});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [too_bright]})).await;
    let error = next_error(&mut socket).await;
    assert!(error["message"].as_str().is_some_and(|m| m.contains("color [0, 2, 0]")), "{error}");
    let misplaced = serde_json::json!({"layer": id, "target": "color", "color": [0, 0, 1]});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [misplaced]})).await;
    let error = next_error(&mut socket).await;
    assert!(error["message"].as_str().is_some_and(|m| m.contains("hatch_color")), "{error}");

    // Hatch colour (thesis Fig. 9.3) over 2…5: no ink in the west (x < −358 m, at the bottom
    // of the range), dense blue strokes in the east, and the Table 9.1 caution in the answer.
    // Only the valid controls count.
    let blue = serde_json::json!({"layer": id, "target": "hatch_color", "color": [0, 0, 1], "range": [2, 5]});
    send_json(&mut socket, serde_json::json!({"type": "data", "mappings": [blue]})).await;
    let (messages, header, hatched) = next_still(&mut socket).await;
    assert!(messages.iter().all(|m| m["type"] != "error"), "{messages:?}");
    let answer = messages.iter().find(|m| m["type"] == "data").expect("a data message");
    let warnings = answer["warnings"].as_array().expect("warnings");
    assert!(warnings.iter().any(|w| w.as_str().is_some_and(|w| w.contains("hatch_color"))), "{answer}");
    assert_eq!(header.seq, 2, "the rejected controls do not count");
    let blue_ink = |x0: u32| {
        (x0..x0 + 16)
            .flat_map(|x| (0..48).map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let p = hatched.get_pixel(x, y);
                i32::from(p[2]) - i32::from(p[0].max(p[1])) > 40
            })
            .count()
    };
    let (west, east) = (blue_ink(0), blue_ink(48));
    assert!(west == 0 && east > 16 * 48 / 2, "blue hatching in the east only: {west} west, {east} east pixels");
    let west_paper = (0..16)
        .flat_map(|x| (0..48).map(move |y| (x, y)))
        .all(|(x, y)| hatched.get_pixel(x, y) == plain.get_pixel(x, y));
    assert!(west_paper, "the west stays as it was");
    // Blue ink filters red and green only: the blue channel keeps the paper's value.
    assert!(hatched.pixels().all(|p| p[2] >= 245), "only blue ink on the paper");
}
