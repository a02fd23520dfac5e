//! Integration tests of the art-map API (SPEC R11): real servers on loopback ports with the
//! sample scene, each with a data directory of its own, exercised over HTTP (reqwest) and
//! WebSocket (tokio-tungstenite). Art maps are uploaded as PNGs built here: an all-ink TAM
//! (every tone level black) and a SAM with every channel fully inked.

mod common;

use common::fraction;
use common::server::{TestServer, client, get, json_of, raw_exchange};
use futures_util::StreamExt;
use image::{GrayImage, Luma, Rgba, RgbaImage};
use landsketch::api::ws::{FrameHeader, HEADER_LEN};
use reqwest::StatusCode;
use serde_json::Value;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message;

/// A view of the sample scene with hatched trees and terrain; `{style}` is filled in.
// Tests that measure how much ink a TAM adds tone the terrain by its absolute light
// (`terrain_relief: 0`): with the default relief tone the lit ground is paper under any TAM.
const VIEW: &str = "x=205&y=185&yaw=268&pitch=-1.5&width=192&height=144";

/// The shape of the renderer's TAMs: 6 tone levels of 256².
const TAM_SIZE: u32 = 256;
const TAM_LEVELS: u32 = 6;

fn png(image: impl Into<image::DynamicImage>) -> Vec<u8> {
    let mut bytes = Vec::new();
    image.into().write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).expect("encode PNG");
    bytes
}

/// A TAM strip of `levels` tone images of `size`², every pixel ink.
fn black_tam(size: u32, levels: u32) -> Vec<u8> {
    png(GrayImage::from_pixel(size * levels, size, Luma([0])))
}

/// A TAM strip whose tone level `l` has ink in every `(l + 2)`-th column: a pattern that
/// survives the grey round trip exactly.
fn striped_tam() -> GrayImage {
    GrayImage::from_fn(TAM_SIZE * TAM_LEVELS, TAM_SIZE, |x, _| {
        let level = x / TAM_SIZE;
        Luma([if x % (level + 2) == 0 { 0 } else { 255 }])
    })
}

async fn put(server: &TestServer, path: &str, body: Vec<u8>, token: Option<&str>) -> reqwest::Response {
    let mut request = client().put(server.url(path)).body(body);
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    request.send().await.expect("PUT")
}

async fn delete(server: &TestServer, path: &str, token: Option<&str>) -> reqwest::Response {
    let mut request = client().delete(server.url(path));
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    request.send().await.expect("DELETE")
}

/// Asserts a JSON error with `status` and `code`; returns the message.
async fn assert_error(response: reqwest::Response, status: u16, code: &str) -> String {
    let url = response.url().to_string();
    assert_eq!(response.status().as_u16(), status, "{url}");
    let body = json_of(response).await;
    assert_eq!(body["error"]["code"], code, "{url}: {body}");
    body["error"]["message"].as_str().expect("message").to_owned()
}

/// A render of [`VIEW`] with the style JSON `style`: its ETag, `X-Cache` and image.
async fn render(server: &TestServer, style: &str) -> (String, String, image::RgbaImage) {
    let style: String = form_urlencoded::byte_serialize(style.as_bytes()).collect();
    let response = get(&server.url(&format!("/api/render?{VIEW}&style={style}"))).await;
    assert_eq!(response.status(), StatusCode::OK, "render with {style}");
    let etag = response.headers()["etag"].to_str().expect("etag").to_owned();
    let cache = response.headers()["x-cache"].to_str().expect("x-cache").to_owned();
    let image = image::load_from_memory(&response.bytes().await.expect("image")).expect("PNG").to_rgba8();
    (etag, cache, image)
}

/// Asserts that (almost) every ink pixel of `before` is ink in `after`, as when an art map
/// is replaced by one with ink wherever the old one had some.
fn assert_ink_kept(before: &image::RgbaImage, after: &image::RgbaImage, paths: &impl std::fmt::Debug) {
    let kept = before.pixels().zip(after.pixels()).filter(|(b, a)| {
        let (b, a) = (common::luminance(b), common::luminance(a));
        b >= 0.5 || a < 0.5
    });
    let total = f64::from(before.width() * before.height());
    assert!(kept.count() as f64 >= 0.995 * total, "ink pixels stay ink: {paths:?}");
}

/// Fraction of ink pixels (luminance below one half).
fn ink(image: &image::RgbaImage) -> f64 {
    fraction(image, |l| l < 0.5)
}

async fn list(server: &TestServer) -> Value {
    let response = get(&server.url("/api/artmaps")).await;
    assert_eq!(response.status(), StatusCode::OK);
    json_of(response).await
}

async fn art_png(server: &TestServer, path: &str) -> image::DynamicImage {
    let response = get(&server.url(path)).await;
    assert_eq!(response.status(), StatusCode::OK, "{path}");
    assert_eq!(response.headers()["content-type"], "image/png");
    image::load_from_memory(&response.bytes().await.expect("PNG")).expect("a PNG")
}

/// Sources of every map of `kind` in the list.
fn sources(listed: &Value, kind: &str) -> Vec<String> {
    listed[kind].as_array().expect("maps").iter().map(|m| m["source"].as_str().expect("source").to_owned()).collect()
}

/// Keeps tests' images when they fail: writes them to `$TMPDIR/landsketch-test-images/`.
fn save(name: &str, image: &image::RgbaImage) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join("landsketch-test-images");
    std::fs::create_dir_all(&dir).expect("image dir");
    let path = dir.join(format!("artmaps-{name}.png"));
    image.save(&path).expect("save image");
    path
}

#[tokio::test]
async fn an_uploaded_tam_changes_the_next_render_and_delete_restores_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});

    let listed = list(&server).await;
    assert_eq!(sources(&listed, "tams"), ["generated"; 4]);
    assert_eq!(sources(&listed, "sams"), ["generated"; 4]);
    assert_eq!(listed["tam_shape"]["size"], TAM_SIZE);
    assert_eq!(listed["tam_shape"]["levels"], TAM_LEVELS);
    assert_eq!(listed["tam_shape"]["width"], TAM_SIZE * TAM_LEVELS);
    assert_eq!(listed["tams"][1]["url"], "/api/artmaps/tam/1.png");
    assert_eq!(listed["tams"][1]["has_default"], true);
    let generated = art_png(&server, "/api/artmaps/tam/1.png").await.to_luma8();
    assert_eq!(generated.dimensions(), (TAM_SIZE * TAM_LEVELS, TAM_SIZE));

    let hatched = r#"{"hatch_map": 1, "terrain_relief": 0}"#;
    let other = r#"{"hatch_map": 0}"#;
    let (etag, _, before) = render(&server, hatched).await;
    let (_, _, other_before) = render(&server, other).await;
    let (_, cache, _) = render(&server, hatched).await;
    assert_eq!(cache, "hit");

    let response = put(&server, "/api/artmaps/tam/1", black_tam(TAM_SIZE, TAM_LEVELS), None).await;
    assert_eq!(response.status(), StatusCode::OK, "replacing answers 200");
    let info = json_of(response).await;
    assert_eq!((info["kind"].as_str(), info["index"].as_u64()), (Some("tam"), Some(1)));
    assert_eq!((info["source"].as_str(), info["levels"].as_u64()), (Some("uploaded"), Some(6)));
    assert_eq!(sources(&list(&server).await, "tams"), ["generated", "uploaded", "generated", "generated"]);

    // The next render hatches with the all-ink TAM: every pixel that had ink keeps it, and
    // hatched pixels that were paper between strokes turn to ink.
    let (new_etag, cache, after) = render(&server, hatched).await;
    assert_ne!(new_etag, etag, "the ETag depends on the art maps");
    assert_eq!(cache, "miss", "the cache was emptied");
    let (ink_before, ink_after) = (ink(&before), ink(&after));
    let paths = (save("tam1-before", &before), save("tam1-black", &after));
    assert!(ink_after > ink_before + 0.1, "ink {ink_before:.3} → {ink_after:.3}: {paths:?}");
    assert_ink_kept(&before, &after, &paths);
    let stale = client()
        .get(server.url(&format!("/api/render?{VIEW}&style=%7B%22hatch_map%22%3A1%2C%22terrain_relief%22%3A0%7D")));
    let stale = stale.header("if-none-match", &etag).send().await.expect("GET");
    assert_eq!(stale.status(), StatusCode::OK, "the old ETag no longer matches");
    // Another TAM draws as before.
    let (_, _, other_after) = render(&server, other).await;
    assert_eq!(other_after, other_before, "hatch_map 0 is unchanged");

    // The map reads back as uploaded; a pattern round-trips exactly.
    let black = art_png(&server, "/api/artmaps/tam/1.png").await.to_luma8();
    assert!(black.dimensions() == generated.dimensions() && black.pixels().all(|p| p[0] == 0));
    let striped = striped_tam();
    assert_eq!(put(&server, "/api/artmaps/tam/1.png", png(striped.clone()), None).await.status(), StatusCode::OK);
    assert_eq!(art_png(&server, "/api/artmaps/tam/1.png").await.to_luma8(), striped);

    // DELETE restores the generated map: the same PNG, image and ETag as at the start.
    let deleted = delete(&server, "/api/artmaps/tam/1", None).await;
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    assert_eq!(art_png(&server, "/api/artmaps/tam/1.png").await.to_luma8(), generated);
    let (restored_etag, _, restored) = render(&server, hatched).await;
    assert_eq!((restored_etag, restored), (etag, before), "the generated TAM is back");
    assert_eq!(sources(&list(&server).await, "tams"), ["generated"; 4]);
    assert_eq!(delete(&server, "/api/artmaps/tam/1", None).await.status(), StatusCode::NO_CONTENT, "idempotent");
    assert!(std::fs::read_dir(dir.path().join("artmaps")).expect("art-map dir").next().is_none(), "no file left");
}

#[tokio::test]
async fn maps_are_added_at_the_count_and_only_the_last_added_is_removed() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let heavy = png(RgbaImage::from_pixel(64, 16, Rgba([255; 4])));

    // A SAM added as index 4 can be drawn; 5 is no map yet.
    let added = put(&server, "/api/artmaps/sam/4", heavy.clone(), None).await;
    assert_eq!(added.status(), StatusCode::CREATED);
    assert_eq!(added.headers()["location"], "/api/artmaps/sam/4.png");
    let info = json_of(added).await;
    assert_eq!(
        (info["width"].as_u64(), info["height"].as_u64(), info["has_default"].as_bool()),
        (Some(64), Some(16), Some(false))
    );
    let (_, _, plain) = render(&server, r#"{"silhouette_map": 0, "contour_strength": 0}"#).await;
    let (_, _, inked) = render(&server, r#"{"silhouette_map": 4, "contour_strength": 0}"#).await;
    let paths = (save("sam0", &plain), save("sam-added", &inked));
    assert!(ink(&inked) > ink(&plain) + 0.005, "a fully inked SAM draws heavier silhouettes: {paths:?}");
    assert_ink_kept(&plain, &inked, &paths);
    let style: String = form_urlencoded::byte_serialize(br#"{"silhouette_map": 5}"#).collect();
    let unknown = get(&server.url(&format!("/api/render?{VIEW}&style={style}"))).await;
    let message = assert_error(unknown, 422, "invalid_parameter").await;
    assert!(message.contains("silhouette_map") && message.contains("there are 5"), "{message}");

    // Indices beyond the count are refused; two added TAMs go away last first.
    let gap = put(&server, "/api/artmaps/tam/5", black_tam(TAM_SIZE, TAM_LEVELS), None).await;
    let message = assert_error(gap, 422, "invalid_parameter").await;
    assert!(message.contains("add one as 4"), "{message}");
    for index in [4, 5] {
        let added = put(&server, &format!("/api/artmaps/tam/{index}"), black_tam(TAM_SIZE, TAM_LEVELS), None).await;
        assert_eq!(added.status(), StatusCode::CREATED);
    }
    assert_eq!(list(&server).await["tams"].as_array().map(Vec::len), Some(6));
    let (_, _, black) = render(&server, r#"{"hatch_map": 5, "terrain_relief": 0}"#).await;
    assert!(ink(&black) > 0.2, "hatch_map 5 draws with the added TAM: {:?}", save("tam5", &black));
    let message = assert_error(delete(&server, "/api/artmaps/tam/4", None).await, 409, "conflict").await;
    assert!(message.contains("remove tonal art map 5 first"), "{message}");
    assert_eq!(delete(&server, "/api/artmaps/tam/5", None).await.status(), StatusCode::NO_CONTENT);
    assert_eq!(delete(&server, "/api/artmaps/tam/4", None).await.status(), StatusCode::NO_CONTENT);
    assert_error(delete(&server, "/api/artmaps/tam/4", None).await, 404, "not_found").await;
    assert_eq!(delete(&server, "/api/artmaps/sam/4", None).await.status(), StatusCode::NO_CONTENT);
    let listed = list(&server).await;
    assert_eq!((listed["tams"].as_array().map(Vec::len), listed["sams"].as_array().map(Vec::len)), (Some(4), Some(4)));
    let style: String = form_urlencoded::byte_serialize(br#"{"hatch_map": 4}"#).collect();
    assert_error(get(&server.url(&format!("/api/render?{VIEW}&style={style}"))).await, 422, "invalid_parameter").await;
}

#[tokio::test]
async fn bad_uploads_get_422_and_change_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let (etag, _, before) = render(&server, r#"{"hatch_map": 2}"#).await;
    let listed = list(&server).await;

    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("/api/artmaps/tam/2", b"definitely not a PNG".to_vec(), "is not a PNG file"),
        ("/api/artmaps/tam/2", b"\x89PNG\r\n\x1a\n\0\0\0".to_vec(), "cannot decode art map tam/2"),
        ("/api/artmaps/tam/2", black_tam(TAM_SIZE, 5), "a strip of 6 square tone images"),
        ("/api/artmaps/tam/2", png(GrayImage::new(300, 256)), "a strip of 6 square tone images"),
        ("/api/artmaps/tam/2", black_tam(32, TAM_LEVELS), "this renderer's TAMs are 256×256 with 6 levels and 9 mips"),
        ("/api/artmaps/sam/1", png(RgbaImage::new(4, 4)), "at least 8×8"),
        ("/api/artmaps/sam/1", Vec::new(), "is not a PNG file"),
    ];
    for (path, body, expected) in cases {
        let response = put(&server, path, body, None).await;
        let url = response.url().to_string();
        assert_eq!(response.status(), StatusCode::UNPROCESSABLE_ENTITY, "{url}");
        let error = json_of(response).await;
        assert_eq!(
            (error["error"]["code"].as_str(), error["error"]["parameter"].as_str()),
            (Some("invalid_parameter"), Some("body"))
        );
        let message = error["error"]["message"].as_str().expect("message");
        assert!(message.contains(expected), "{path}: {message:?} lacks {expected:?}");
    }
    // A header that claims an enormous image (its CRC broken too) is refused.
    let mut huge = black_tam(16, 1);
    huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    assert_error(put(&server, "/api/artmaps/tam/2", huge, None).await, 422, "invalid_parameter").await;
    assert_error(put(&server, "/api/artmaps/tim/2", black_tam(TAM_SIZE, 6), None).await, 404, "not_found").await;
    assert_error(put(&server, "/api/artmaps/tam/two", black_tam(TAM_SIZE, 6), None).await, 404, "not_found").await;
    assert_error(get(&server.url("/api/artmaps/tam/9.png")).await, 404, "not_found").await;
    assert_error(get(&server.url("/api/artmaps/sam/x.png")).await, 404, "not_found").await;
    // Announced beyond the limit: refused before the body is sent (the server does not read
    // it, so a client still writing it would see the connection close instead of the answer).
    let oversized =
        format!("PUT /api/artmaps/sam/1 HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {}\r\n\r\n", 16u64 << 20 | 1);
    let (received, _) = raw_exchange(&server, oversized.as_bytes(), Duration::from_secs(10)).await;
    assert!(received.starts_with("HTTP/1.1 413") && received.contains("too_large"), "{received}");

    assert_eq!(list(&server).await, listed, "nothing changed");
    let (after_etag, _, after) = render(&server, r#"{"hatch_map": 2}"#).await;
    assert_eq!((after_etag, after), (etag, before), "the renders are unchanged");
    assert!(!dir.path().join("artmaps").exists(), "nothing was stored");
}

/// The signature and IHDR chunk (valid CRC) of a grey 8-bit PNG of `width` × `height`
/// pixels, followed by an IDAT chunk of a few bytes: a header that announces an image far
/// larger than the file.
fn announced_png(width: u32, height: u32) -> Vec<u8> {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        let mut bytes = (data.len() as u32).to_be_bytes().to_vec();
        bytes.extend_from_slice(kind);
        bytes.extend_from_slice(data);
        bytes.extend_from_slice(&crc.sum().to_be_bytes());
        bytes
    };
    let mut header = width.to_be_bytes().to_vec();
    header.extend_from_slice(&height.to_be_bytes());
    header.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &header));
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00]));
    png
}

/// D10: a TAM whose header announces 16384² pixels (256 MiB decoded) is refused from the
/// header's shape, before decoding; a SAM too small likewise.
#[tokio::test]
async fn art_map_shapes_are_checked_on_the_header_before_decoding() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let listed = list(&server).await;
    for (path, body, expected) in [
        ("/api/artmaps/tam/2", announced_png(16384, 16384), "16384×16384 pixels, expected a strip of 6"),
        ("/api/artmaps/sam/1", announced_png(4, 16384), "4×16384 pixels, expected at least 8×8"),
    ] {
        let message = assert_error(put(&server, path, body, None).await, 422, "invalid_parameter").await;
        assert!(message.contains(expected), "{path}: {message:?} lacks {expected:?}");
    }
    assert_eq!(list(&server).await, listed, "nothing changed");
}

#[tokio::test]
async fn writes_need_the_admin_token() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |c| c.admin_token = Some("s3cret".into()));
    let body = black_tam(TAM_SIZE, TAM_LEVELS);
    assert_error(put(&server, "/api/artmaps/tam/0", body.clone(), None).await, 401, "unauthorized").await;
    assert_error(put(&server, "/api/artmaps/tam/0", body.clone(), Some("guess")).await, 401, "unauthorized").await;
    assert_error(delete(&server, "/api/artmaps/tam/0", None).await, 401, "unauthorized").await;
    assert_eq!(sources(&list(&server).await, "tams"), ["generated"; 4], "reading is public; nothing changed");
    assert_eq!(put(&server, "/api/artmaps/tam/0", body, Some("s3cret")).await.status(), StatusCode::OK);
    assert_eq!(delete(&server, "/api/artmaps/tam/0", Some("s3cret")).await.status(), StatusCode::NO_CONTENT);
    let openapi = json_of(get(&server.url("/api/openapi.json")).await).await;
    for path in ["/api/artmaps", "/api/artmaps/{kind}/{index}.png", "/api/artmaps/{kind}/{index}"] {
        assert!(openapi["paths"][path].is_object(), "{path} is documented");
    }
    assert!(openapi["paths"]["/api/artmaps/{kind}/{index}"]["put"]["security"].is_array());
}

/// D9: without a token, a foreign-origin art-map upload or delete is refused.
#[tokio::test]
async fn tokenless_writes_refuse_foreign_origins() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let url = server.url("/api/artmaps/tam/0");
    let body = black_tam(TAM_SIZE, TAM_LEVELS);
    let forged = client().put(&url).header("origin", "https://attacker.example").body(body).send().await;
    assert_error(forged.expect("PUT"), 403, "forbidden").await;
    let rebound = client().delete(&url).header("host", "attacker.example").send().await.expect("DELETE");
    assert_error(rebound, 403, "forbidden").await;
    assert_eq!(sources(&list(&server).await, "tams"), ["generated"; 4], "nothing changed");
}

#[tokio::test]
async fn uploads_are_stored_and_reloaded_after_a_restart() {
    let dir = tempfile::tempdir().expect("temp dir");
    let striped = striped_tam();
    let sam = RgbaImage::from_fn(128, 24, |x, y| Rgba([if (x / 4 + y) % 3 == 0 { 255 } else { 0 }; 4]));
    let hatched = r#"{"hatch_map": 2, "silhouette_map": 4}"#;
    let (etag, image) = {
        let server = TestServer::start(dir.path(), |_| {});
        assert_eq!(put(&server, "/api/artmaps/tam/2", png(striped.clone()), None).await.status(), StatusCode::OK);
        assert_eq!(put(&server, "/api/artmaps/sam/4", png(sam.clone()), None).await.status(), StatusCode::CREATED);
        let (etag, _, image) = render(&server, hatched).await;
        server.stop().expect("clean stop");
        (etag, image)
    };
    // A stored file that no longer fits is skipped; the server starts anyway.
    std::fs::write(dir.path().join("artmaps/tam-3.png"), black_tam(32, TAM_LEVELS)).expect("write");

    let server = TestServer::start(dir.path(), |_| {});
    let listed = list(&server).await;
    assert_eq!(sources(&listed, "tams"), ["generated", "generated", "uploaded", "generated"]);
    assert_eq!(sources(&listed, "sams"), ["generated", "generated", "generated", "generated", "uploaded"]);
    assert_eq!(art_png(&server, "/api/artmaps/tam/2.png").await.to_luma8(), striped);
    assert_eq!(art_png(&server, "/api/artmaps/sam/4.png").await.to_rgba8(), sam);
    let (restarted_etag, _, restarted) = render(&server, hatched).await;
    assert_eq!(restarted_etag, etag, "the same maps give the same ETag");
    // The same picture. Not compared byte for byte: with several servers rendering at once on
    // one lavapipe device (the other tests of this binary), a restart's frame has been seen to
    // differ in a few ink pixels (cause not found; one server alone renders identically).
    let (share, _) = common::outliers(&restarted, &image);
    assert!(share < 0.005, "the restarted server draws the same image ({:.2} % of pixels differ)", share * 100.0);
}

#[tokio::test]
async fn websocket_sessions_get_the_new_maps_in_their_next_frame() {
    let dir = tempfile::tempdir().expect("temp dir");
    let server = TestServer::start(dir.path(), |_| {});
    let query = format!("{VIEW}&style=%7B%22hatch_map%22%3A3%2C%22terrain_relief%22%3A0%7D");
    let (mut socket, _) = tokio_tungstenite::connect_async(server.ws_url(&query)).await.expect("WebSocket");
    let first = next_frame(&mut socket).await.1;

    assert_eq!(
        put(&server, "/api/artmaps/tam/3", black_tam(TAM_SIZE, TAM_LEVELS), None).await.status(),
        StatusCode::OK
    );
    let (messages, second) = next_frame(&mut socket).await;
    let announced = messages.iter().find(|m| m["type"] == "art_maps").expect("an art_maps message");
    assert_eq!((announced["tams"].as_u64(), announced["sams"].as_u64()), (Some(4), Some(4)));
    let paths = (save("ws-before", &first), save("ws-after", &second));
    assert!(ink(&second) > ink(&first) + 0.1, "the session's next frame uses the all-ink TAM: {paths:?}");
}

/// The next binary frame of a session as an image, with the JSON messages before it.
async fn next_frame<S>(socket: &mut S) -> (Vec<Value>, image::RgbaImage)
where
    S: futures_util::Stream<Item = Result<Message, tokio_tungstenite::tungstenite::Error>> + Unpin,
{
    let mut messages = Vec::new();
    loop {
        let message = tokio::time::timeout(Duration::from_secs(60), socket.next()).await.expect("a message in time");
        match message.expect("open").expect("message") {
            Message::Text(text) => messages.push(serde_json::from_str(text.as_str()).expect("JSON")),
            Message::Binary(bytes) => {
                assert!(FrameHeader::decode(&bytes).is_some(), "frame header");
                let image = image::load_from_memory(&bytes[HEADER_LEN..]).expect("PNG frame").to_rgba8();
                return (messages, image);
            }
            other => panic!("unexpected {other:?}"),
        }
    }
}
