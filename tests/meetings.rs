//! Integration tests of meetings (presenter mode) and tours: real servers on loopback, a
//! presenter and followers over WebSocket, the meeting endpoints over HTTP.

mod common;

use common::server::{TestServer, client, get, json_of};
use common::ws::{Incoming, Socket, connect, connect_with_receive_buffer, next_frame, receive, send, until};
use landsketch::api::ws::FrameHeader;
use serde_json::{Value, json};
use std::collections::HashMap;
use std::sync::OnceLock;
use std::time::Duration;

fn data_dir() -> std::path::PathBuf {
    std::env::temp_dir().join("landsketch-meeting-tests")
}

/// A server shared by the tests that do not count renders.
fn shared() -> &'static TestServer {
    static SHARED: OnceLock<TestServer> = OnceLock::new();
    SHARED.get_or_init(|| TestServer::start(&data_dir(), |_| {}))
}

const VIEW: &str = "width=64&height=48&format=jpeg";

async fn metric(server: &TestServer, name: &str) -> f64 {
    let text = get(&server.url("/metrics")).await.text().await.expect("metrics");
    text.lines()
        .filter(|l| l.starts_with(name) && (l.len() == name.len() || l[name.len()..].starts_with([' ', '{'])))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

/// A presenter: connects, takes its first frame and opens a meeting; returns the socket and
/// the `meeting` message.
async fn presenter(server: &TestServer) -> (Socket, Value) {
    let mut socket = connect(server, VIEW).await;
    next_frame(&mut socket).await;
    send(&mut socket, json!({"type": "open_meeting", "caption": "Hedge row"})).await;
    let (meeting, _) = until(&mut socket, "meeting").await;
    assert_eq!(meeting["role"], "presenter");
    (socket, meeting)
}

/// Reads frames until the one numbered `id`; returns every frame's number and bytes.
async fn frames_until(socket: &mut Socket, id: u32) -> HashMap<u32, (FrameHeader, Vec<u8>)> {
    let mut frames = HashMap::new();
    loop {
        let (_, _, header, bytes) = next_frame(socket).await;
        frames.insert(header.frame_id, (header, bytes));
        if header.frame_id >= id {
            return frames;
        }
    }
}

#[tokio::test]
async fn followers_get_the_presenters_frames_from_one_render_each() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let server = TestServer::start(dir.path(), |_| {});
    let server = &server;
    let (mut presenter, meeting) = presenter(server).await;
    let code = meeting["code"].as_str().expect("code").to_owned();
    assert_eq!(code.len(), 6);
    assert_eq!(meeting["join_url"], format!("/?meeting={code}"));
    assert_eq!(meeting["caption"], "Hedge row");
    // The view is rendered again for the meeting; that still is the followers' first frame.
    let (_, _, opening, _) = next_frame(&mut presenter).await;

    // Followers join by the link's parameter (in lower case) and by a `join` control.
    let mut followers = vec![
        connect(server, &format!("{VIEW}&meeting={}", code.to_lowercase())).await,
        connect(server, &format!("{VIEW}&meeting={code}")).await,
        connect(server, VIEW).await,
    ];
    // The third renders its own first frame before it joins.
    next_frame(&mut followers[2]).await;
    send(&mut followers[2], json!({"type": "join", "code": code})).await;
    for follower in &mut followers {
        let (meeting, _) = until(follower, "meeting").await;
        assert_eq!((meeting["role"].as_str(), meeting["code"].as_str()), (Some("follower"), Some(code.as_str())));
        let (_, _, header, _) = next_frame(follower).await;
        assert_eq!(header.frame_id, opening.frame_id, "a follower starts with the newest frame");
    }
    let info = json_of(get(&server.url(&format!("/api/meetings/{code}"))).await).await;
    assert_eq!(info["followers"], 3);
    let renders_before = metric(server, "landsketch_render_seconds_count").await;

    // The presenter moves; each move's frame is awaited, then the still at rest.
    let mut presented = HashMap::new();
    for _ in 0..4 {
        send(&mut presenter, json!({"type": "move", "yaw": 15, "forward": 2})).await;
        let (_, _, header, bytes) = next_frame(&mut presenter).await;
        presented.insert(header.frame_id, (header, bytes));
    }
    let last = loop {
        let (_, _, header, bytes) = next_frame(&mut presenter).await;
        presented.insert(header.frame_id, (header, bytes));
        if header.still {
            break header.frame_id;
        }
    };
    for follower in &mut followers {
        let seen = frames_until(follower, last).await;
        assert!(seen.contains_key(&last), "every follower gets the last frame");
        for (id, (header, bytes)) in &seen {
            let (expected_header, expected) = &presented[id];
            assert_eq!(header, expected_header);
            assert_eq!(bytes, expected, "frame {id}: the same bytes as the presenter's");
        }
    }
    // One render per presenter frame, however many follow.
    let renders = metric(server, "landsketch_render_seconds_count").await - renders_before;
    assert_eq!(renders, presented.len() as f64);
    let meeting_renders = metric(server, &format!("landsketch_meeting_renders_total{{meeting=\"{code}\"}}")).await;
    assert_eq!(meeting_renders, presented.len() as f64 + 1.0, "the opening still and the moves");
    assert_eq!(metric(server, &format!("landsketch_meeting_followers{{meeting=\"{code}\"}}")).await, 3.0);
    assert!(metric(server, "landsketch_meeting_frames_sent_total").await >= 3.0 * 2.0);

    // A follower that leaves is no longer counted.
    followers.pop().expect("follower").close(None).await.expect("close");
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while json_of(get(&server.url(&format!("/api/meetings/{code}"))).await).await["followers"] != 2 {
        assert!(std::time::Instant::now() < deadline, "the follower count did not drop");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let (meeting, _) = until(&mut presenter, "meeting").await;
    assert!(meeting["followers"].as_u64().is_some_and(|n| n <= 3));
}

#[tokio::test]
async fn a_wrong_code_is_refused_and_the_session_keeps_serving() {
    let server = shared();
    match tokio_tungstenite::connect_async(server.ws_url(&format!("{VIEW}&meeting=ZZZ999"))).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
            assert_eq!(response.status().as_u16(), 404);
            let body: Value = serde_json::from_slice(response.body().as_deref().unwrap_or_default()).expect("JSON");
            assert_eq!(body["error"]["code"], "not_found");
            assert!(body["error"]["message"].as_str().is_some_and(|m| m.contains("ZZZ999")), "{body}");
        }
        other => panic!("expected a 404, got {:?}", other.map(|_| ())),
    }
    let mut socket = connect(server, VIEW).await;
    for code in ["NOPE22", "0OIL1x", "<script>"] {
        send(&mut socket, json!({"type": "join", "code": code})).await;
        let (error, _) = until(&mut socket, "error").await;
        assert_eq!(error["code"], "not_found", "{error}");
    }
    for refused in [json!({"type": "detach"}), json!({"type": "rejoin"}), json!({"type": "close_meeting"})] {
        send(&mut socket, refused.clone()).await;
        let (error, _) = until(&mut socket, "error").await;
        assert_eq!(error["code"], "conflict", "{refused}: {error}");
    }
    send(&mut socket, json!({"type": "ping", "id": 9})).await;
    let (pong, _) = until(&mut socket, "pong").await;
    assert_eq!(pong["id"], 9);
    let response = get(&server.url("/api/meetings/NOPE22")).await;
    assert_eq!(response.status().as_u16(), 404);
}

#[tokio::test]
async fn the_openapi_document_describes_meetings() {
    let openapi = json_of(get(&shared().url("/api/openapi.json")).await).await;
    for (path, method) in [
        ("/api/meetings", "post"),
        ("/api/meetings/{code}", "get"),
        ("/api/meetings/{code}", "delete"),
        ("/api/meetings/{code}/qr.svg", "get"),
    ] {
        assert!(openapi["paths"][path][method].is_object(), "OpenAPI lacks {method} {path}");
    }
    let schemas = &openapi["components"]["schemas"];
    assert!(schemas["MeetingInfo"].is_object() && schemas["OpenMeeting"].is_object());
    let messages = |name: &str| {
        schemas[name]["oneOf"]
            .as_array()
            .map(|variants| {
                // A variant is an object with `type`, or (newtype variants) all of a
                // reference and such an object.
                variants
                    .iter()
                    .flat_map(|v| std::iter::once(v).chain(v["allOf"].as_array().into_iter().flatten()))
                    .filter_map(|v| v["properties"]["type"]["enum"][0].as_str().map(str::to_owned))
                    .collect::<Vec<_>>()
            })
            .unwrap_or_default()
    };
    let client_messages = messages("ClientMessage");
    for kind in ["open_meeting", "close_meeting", "caption", "join", "detach", "rejoin", "tour"] {
        assert!(client_messages.iter().any(|m| m == kind), "ClientMessage lacks {kind}: {client_messages:?}");
    }
    let server_messages = messages("ServerMessage");
    for kind in ["meeting", "meeting_ended", "tour"] {
        assert!(server_messages.iter().any(|m| m == kind), "ServerMessage lacks {kind}: {server_messages:?}");
    }
}

#[tokio::test]
async fn a_follower_detaches_with_the_presenters_view_and_rejoins() {
    let server = shared();
    let (mut presenter, meeting) = presenter(server).await;
    let code = meeting["code"].as_str().expect("code");
    send(&mut presenter, json!({"type": "camera", "yaw": 123, "pitch": -4})).await;
    // The meeting's opening still may come first; wait for the frame of the new camera.
    let status = loop {
        let (_, status, _, _) = next_frame(&mut presenter).await;
        if status["camera"]["yaw"] == 123.0 {
            break status;
        }
    };
    let mut follower = connect(server, &format!("{VIEW}&meeting={code}")).await;
    let (_, frame, _, _) = next_frame(&mut follower).await;
    assert_eq!(frame["camera"], status["camera"]);
    // Following, the view is the presenter's to change.
    send(&mut follower, json!({"type": "move", "yaw": 5})).await;
    let (error, _) = until(&mut follower, "error").await;
    assert_eq!(error["code"], "conflict");
    assert!(error["message"].as_str().is_some_and(|m| m.contains("detach")), "{error}");

    send(&mut follower, json!({"type": "detach"})).await;
    let (detached, _) = until(&mut follower, "meeting").await;
    assert_eq!(detached["role"], "detached");
    // Its own frame, at its own size, from the presenter's camera.
    let (_, own, header, _) = next_frame(&mut follower).await;
    assert_eq!(own["camera"]["yaw"], 123.0);
    assert_eq!((header.width, header.height), (64, 48));
    assert!(header.frame_id > frame["id"].as_u64().unwrap_or(0) as u32, "frame numbers go on rising");
    send(&mut follower, json!({"type": "move", "yaw": 10})).await;
    let (_, moved, _, _) = next_frame(&mut follower).await;
    assert_eq!(moved["camera"]["yaw"], 133.0);

    send(&mut follower, json!({"type": "rejoin"})).await;
    let (rejoined, _) = until(&mut follower, "meeting").await;
    assert_eq!(rejoined["role"], "follower");
    let (_, again, _, _) = next_frame(&mut follower).await;
    assert_eq!(again["camera"]["yaw"], 123.0, "the presenter's view again");
}

#[tokio::test]
async fn a_follower_that_does_not_read_holds_up_neither_the_presenter_nor_the_others() {
    let dir = tempfile::tempdir().expect("temporary directory");
    // Sends may wait for the sleeper longer than the default deadline on a loaded machine; a
    // send buffer of 64 KiB per connection.
    let server = TestServer::start(dir.path(), |c| {
        c.ws_send_timeout_s = 120;
        c.send_buffer_bytes = 64 << 10;
    });
    let server = &server;
    // Frames of several kilobytes (moving at 512 × 384): the sleeper's 4 KiB receive window
    // and its connection's send buffer fill after a few.
    const LARGE: &str = "width=1024&height=768&format=jpeg&quality=90";
    let mut presenter = connect(server, LARGE).await;
    next_frame(&mut presenter).await;
    send(&mut presenter, json!({"type": "open_meeting"})).await;
    let (meeting, _) = until(&mut presenter, "meeting").await;
    let code = meeting["code"].as_str().expect("code").to_owned();
    let mut reader = connect(server, &format!("{LARGE}&meeting={code}")).await;
    let mut sleeper = connect_with_receive_buffer(server, &format!("{LARGE}&meeting={code}"), 4096).await;
    for follower in [&mut reader, &mut sleeper] {
        until(follower, "meeting").await;
        next_frame(follower).await;
    }
    // The sleeper reads nothing while the presenter moves sixteen times; the reader reads
    // each frame as it comes.
    let (mut last, mut bytes, mut seen) = (0, 0, HashMap::new());
    for _ in 0..16 {
        send(&mut presenter, json!({"type": "move", "yaw": 10, "forward": 1})).await;
        let (_, _, header, frame) = tokio::time::timeout(Duration::from_secs(60), next_frame(&mut presenter))
            .await
            .expect("the presenter's frame");
        (last, bytes) = (header.frame_id, bytes + frame.len());
        let got = tokio::time::timeout(Duration::from_secs(60), frames_until(&mut reader, last))
            .await
            .expect("the reading follower keeps up");
        seen.extend(got);
    }
    assert!(bytes > 4 * (64 << 10), "{bytes} bytes of frames are too few to fill the buffers");
    assert!(seen.contains_key(&last) && seen.len() >= 16, "the reader got {} of 16 frames", seen.len());
    // Woken, the sleeper catches up to the newest frame, skipping what did not fit.
    let caught = tokio::time::timeout(Duration::from_secs(60), frames_until(&mut sleeper, last))
        .await
        .expect("the sleeping follower catches up");
    // (The newest may be the still that follows the last move.)
    assert!(caught.keys().max().is_some_and(|&id| id >= last), "the sleeper got the newest frame");
    assert!(caught.len() < seen.len(), "the sleeper skipped frames: {} of {}", caught.len(), seen.len());
}

#[tokio::test]
async fn followers_are_told_when_the_meeting_ends_and_go_on_alone() {
    let server = shared();
    for close in [true, false] {
        let (mut presenter, meeting) = presenter(server).await;
        let code = meeting["code"].as_str().expect("code").to_owned();
        let mut follower = connect(server, &format!("{VIEW}&meeting={code}")).await;
        next_frame(&mut follower).await;
        if close {
            send(&mut presenter, json!({"type": "close_meeting"})).await;
            let (ended, _) = until(&mut presenter, "meeting_ended").await;
            assert_eq!(ended["code"], code.as_str());
        } else {
            presenter.close(None).await.expect("close");
        }
        let (ended, _) = until(&mut follower, "meeting_ended").await;
        let reason = if close { "the presenter closed the meeting" } else { "the presenter left" };
        assert_eq!(ended["reason"], reason);
        // The follower renders its own view from the presenter's last camera.
        let (_, frame, _, _) = next_frame(&mut follower).await;
        assert_eq!(frame["camera"], meeting_camera(server).await);
        send(&mut follower, json!({"type": "rejoin"})).await;
        let (error, _) = until(&mut follower, "error").await;
        assert_eq!(error["code"], "conflict");
        assert_eq!(get(&server.url(&format!("/api/meetings/{code}"))).await.status().as_u16(), 404);
    }
}

/// The HTTP status a WebSocket upgrade with `query` is refused with (panics if accepted).
async fn refused(server: &TestServer, query: &str) -> u16 {
    match tokio_tungstenite::connect_async(server.ws_url(query)).await {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => response.status().as_u16(),
        Err(other) => panic!("upgrade failed otherwise: {other}"),
        Ok(_) => panic!("the upgrade with {query} was accepted"),
    }
}

#[tokio::test]
async fn followers_take_no_rendering_slot_and_going_on_alone_needs_one() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let server = TestServer::start(dir.path(), |c| {
        c.max_sessions = 1;
        c.max_followers = 2;
    });
    let server = &server;
    // The presenter holds the one rendering slot; another session that renders is refused,
    // followers are not, up to --max-followers.
    let (mut presenter, meeting) = presenter(server).await;
    let code = meeting["code"].as_str().expect("code").to_owned();
    assert_eq!(refused(server, VIEW).await, 503);
    let mut a = connect(server, &format!("{VIEW}&meeting={code}")).await;
    let mut b = connect(server, &format!("{VIEW}&meeting={code}")).await;
    for follower in [&mut a, &mut b] {
        next_frame(follower).await;
    }
    assert_eq!(refused(server, &format!("{VIEW}&meeting={code}")).await, 503);
    assert_eq!(metric(server, "landsketch_ws_sessions").await, 1.0);
    assert_eq!(metric(server, "landsketch_ws_followers").await, 2.0);

    // Detaching needs a rendering slot: refused, and the follower goes on following.
    send(&mut a, json!({"type": "detach"})).await;
    let (error, _) = until(&mut a, "error").await;
    assert_eq!(error["code"], "busy");
    assert!(error["message"].as_str().is_some_and(|m| m.contains("stay with the meeting")), "{error}");
    send(&mut presenter, json!({"type": "camera", "yaw": 77})).await;
    loop {
        let (_, frame, _, _) = next_frame(&mut a).await;
        if frame["camera"]["yaw"] == 77.0 {
            break;
        }
    }

    // The meeting ends while the presenter keeps its slot: the followers cannot go on alone;
    // each is told so, then closed with 1013 (try again later).
    send(&mut presenter, json!({"type": "close_meeting"})).await;
    for follower in [&mut a, &mut b] {
        until(follower, "meeting_ended").await;
        let (error, _) = until(follower, "error").await;
        assert_eq!(error["code"], "busy");
        loop {
            match receive(follower).await {
                Incoming::Closed(reason) => {
                    assert!(reason.is_some_and(|r| r.contains("no rendering session is free")));
                    break;
                }
                Incoming::Json(_) | Incoming::Frame(..) => {}
            }
        }
    }
    // The presenter leaves: its slot is free for a session of its own.
    presenter.close(None).await.expect("close");
    for _ in 0..100 {
        if metric(server, "landsketch_ws_sessions").await == 0.0
            && metric(server, "landsketch_ws_followers").await == 0.0
        {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let mut alone = connect(server, VIEW).await;
    next_frame(&mut alone).await;
}

/// The camera of a fresh session (the scene's default camera).
async fn meeting_camera(server: &TestServer) -> Value {
    let mut socket = connect(server, VIEW).await;
    let (hello, _) = until(&mut socket, "hello").await;
    hello["camera"].clone()
}

#[tokio::test]
async fn meetings_open_over_rest_with_the_password_and_show_a_qr_code() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let server = TestServer::start(dir.path(), |c| {
        c.admin_token = Some("s3cret".into());
        c.meeting_password = Some("hedgehog".into());
    });
    let mut socket = connect(&server, VIEW).await;
    let (hello, _) = until(&mut socket, "hello").await;
    let session = hello["session"].as_u64().expect("session");
    let open = |body: Value| {
        client()
            .post(server.url("/api/meetings"))
            .header("content-type", "application/json")
            .body(body.to_string())
            .send()
    };
    for (body, status) in [
        (json!({"session": session}), 403),
        (json!({"session": session, "password": "wrong"}), 403),
        (json!({"session": session + 1000, "password": "hedgehog"}), 404),
        (json!({"session": session, "password": "hedgehog", "caption": "x".repeat(501)}), 422),
        (json!({"session": session, "password": "hedgehog", "extra": 1}), 422),
    ] {
        let response = open(body.clone()).await.expect("POST");
        assert_eq!(response.status().as_u16(), status, "{body}");
        let error = json_of(response).await;
        assert!(error["error"]["message"].as_str().is_some_and(|m| !m.is_empty()), "{error}");
    }
    // Over the WebSocket, a wrong password is an error message; the session goes on.
    send(&mut socket, json!({"type": "open_meeting", "password": "wrong"})).await;
    let (error, _) = until(&mut socket, "error").await;
    assert_eq!(error["code"], "forbidden");

    let response = open(json!({"session": session, "password": "hedgehog", "caption": "Plan B"})).await.expect("POST");
    assert_eq!(response.status().as_u16(), 201);
    let info = json_of(response).await;
    let code = info["code"].as_str().expect("code").to_owned();
    assert_eq!((info["presenter_session"].as_u64(), info["caption"].as_str()), (Some(session), Some("Plan B")));
    let (meeting, _) = until(&mut socket, "meeting").await;
    assert_eq!((meeting["role"].as_str(), meeting["code"].as_str()), (Some("presenter"), Some(code.as_str())));
    let again = open(json!({"session": session, "password": "hedgehog"})).await.expect("POST");
    assert_eq!(again.status().as_u16(), 409);

    let qr = client()
        .get(server.url(&format!("/api/meetings/{code}/qr.svg")))
        .header("host", "meeting.example.org")
        .send()
        .await
        .expect("GET");
    assert_eq!(qr.status().as_u16(), 200);
    assert_eq!(qr.headers()["content-type"], "image/svg+xml");
    let svg = qr.text().await.expect("SVG");
    assert!(svg.contains("<svg") && svg.contains("<path"), "{svg}");

    let delete = |token: Option<&str>| {
        let request = client().delete(server.url(&format!("/api/meetings/{code}")));
        match token {
            Some(token) => request.bearer_auth(token),
            None => request,
        }
        .send()
    };
    assert_eq!(delete(None).await.expect("DELETE").status().as_u16(), 401);
    assert_eq!(delete(Some("s3cret")).await.expect("DELETE").status().as_u16(), 204);
    let (ended, _) = until(&mut socket, "meeting_ended").await;
    assert_eq!(ended["reason"], "an administrator ended the meeting");
    // The admin token opens one over the WebSocket too.
    send(&mut socket, json!({"type": "open_meeting", "token": "s3cret"})).await;
    let (meeting, _) = until(&mut socket, "meeting").await;
    assert_eq!(meeting["role"], "presenter");
}

#[tokio::test]
async fn a_tour_flies_through_the_viewpoints_and_followers_see_its_captions() {
    let server = shared();
    let (mut presenter, meeting) = presenter(server).await;
    let code = meeting["code"].as_str().expect("code");
    let mut follower = connect(server, &format!("{VIEW}&meeting={code}")).await;
    until(&mut follower, "meeting").await;
    let viewpoints = json!([
        {"camera": {"position": [205, 185], "yaw": 268}, "name": "Gate", "caption": "The gate"},
        {"camera": {"position": [215, 190], "eye_height": 40, "yaw": 300, "pitch": -10}, "caption": "From above"},
        {"camera": {"position": [195, 175], "yaw": 200}, "name": "Hedge", "caption": "The new hedge"},
    ]);
    send(
        &mut presenter,
        json!({"type": "tour", "action": "start", "viewpoints": viewpoints, "leg_s": 0.6, "dwell_s": 0.4}),
    )
    .await;
    let mut arrived = Vec::new();
    let mut cameras = Vec::new();
    let mut last_frame = Value::Null;
    loop {
        match receive(&mut presenter).await {
            Incoming::Json(v) if v["type"] == "tour" => {
                assert_eq!(v["count"], 3);
                match v["event"].as_str() {
                    Some("arrived") => arrived.push((v["index"].as_u64(), v["caption"].clone())),
                    Some("finished") => break,
                    Some("flying") => assert!(arrived.is_empty() && v["index"] == 0, "{v}"),
                    other => panic!("unexpected tour event {other:?}"),
                }
            }
            Incoming::Json(v) if v["type"] == "frame" => {
                cameras.push(v["camera"]["position"].clone());
                last_frame = v;
            }
            Incoming::Json(_) | Incoming::Frame(..) => {}
            Incoming::Closed(reason) => panic!("closed: {reason:?}"),
        }
    }
    assert_eq!(
        arrived,
        [(Some(0), json!("The gate")), (Some(1), json!("From above")), (Some(2), json!("The new hedge"))]
    );
    // The camera moved through intermediate positions, and ends at the last viewpoint.
    cameras.dedup();
    assert!(cameras.len() >= 4, "{cameras:?}");
    // The camera rests at the last viewpoint: its still shows it (it may come after
    // `finished` on a loaded machine).
    while last_frame["still"] != true {
        last_frame = next_frame(&mut presenter).await.1;
    }
    assert_eq!(last_frame["camera"]["yaw"], 200.0);
    assert_eq!(last_frame["camera"]["position"][0], 195.0);
    // The follower saw the captions as the meeting's.
    let mut captions = Vec::new();
    while captions.last() != Some(&json!("The new hedge")) {
        let (meeting, _) = until(&mut follower, "meeting").await;
        if captions.last() != Some(&meeting["caption"]) {
            captions.push(meeting["caption"].clone());
        }
    }
    assert_eq!(captions, [json!("The gate"), json!("From above"), json!("The new hedge")]);

    // Bad tours are refused; stop without a tour is a conflict.
    for (bad, code) in [
        (json!({"type": "tour", "action": "start", "viewpoints": [], "from": 99}), "invalid_parameter"),
        (json!({"type": "tour", "action": "start", "viewpoints": [{"camera": {"pitch": 95}}]}), "invalid_parameter"),
        (json!({"type": "tour", "action": "start", "viewpoints": viewpoints, "from": 3}), "invalid_parameter"),
        (json!({"type": "tour", "action": "next"}), "conflict"),
        (json!({"type": "tour", "action": "fly"}), "bad_request"),
    ] {
        send(&mut presenter, bad.clone()).await;
        let (error, _) = until(&mut presenter, "error").await;
        assert_eq!(error["code"], code, "{bad}: {error}");
    }
    // Followers cannot steer the tour.
    send(&mut follower, json!({"type": "tour", "action": "start", "viewpoints": viewpoints})).await;
    let (error, _) = until(&mut follower, "error").await;
    assert_eq!(error["code"], "conflict");
}

#[tokio::test]
async fn a_tour_without_viewpoints_plays_the_planners_viewpoints() {
    // The sample scene's three [[viewpoints]], in their order, with their captions.
    let server = shared();
    let mut socket = connect(server, VIEW).await;
    next_frame(&mut socket).await;
    send(&mut socket, json!({"type": "tour", "action": "start", "leg_s": 0.3, "dwell_s": 0.2})).await;
    let (flying, _) = until(&mut socket, "tour").await;
    assert_eq!((flying["event"].as_str(), flying["count"].as_u64()), (Some("flying"), Some(3)), "{flying}");
    assert_eq!(flying["name"], "Planned woodland");
    let (arrived, _) = until(&mut socket, "tour").await;
    assert_eq!(arrived["event"], "arrived");
    assert_eq!(arrived["caption"], "The new oak woodland seen at eye height from the slope east of it");
    send(&mut socket, json!({"type": "tour", "action": "stop"})).await;
    let (stopped, _) = until(&mut socket, "tour").await;
    assert_eq!(stopped["event"], "stopped");
}

#[tokio::test]
async fn a_tour_viewpoint_brings_its_look() {
    let server = shared();
    let mut socket = connect(server, VIEW).await;
    next_frame(&mut socket).await;
    // An unknown preset is refused when the tour starts, naming the viewpoint.
    let bad = json!([{"camera": {"position": [205, 185]}, "preset": "watercolour"}]);
    send(&mut socket, json!({"type": "tour", "action": "start", "viewpoints": bad})).await;
    let (error, _) = until(&mut socket, "error").await;
    assert_eq!(error["parameter"], "viewpoints[0].style", "{error}");
    // On arrival the view takes the viewpoint's look: the planned layer hidden, in photorealism.
    let viewpoints = json!([{
        "camera": {"position": [205, 185], "yaw": 10},
        "caption": "Without the plan",
        "preset": "photorealism",
        "layer_styles": {"planned": {"visible": false}},
    }]);
    send(
        &mut socket,
        json!({"type": "tour", "action": "start", "viewpoints": viewpoints, "leg_s": 0.3, "dwell_s": 0.2}),
    )
    .await;
    let (style, _) = until(&mut socket, "style").await;
    assert_eq!(style["style"]["photorealism"], 1.0, "{style}");
    assert_eq!(style["layer_styles"]["planned"]["visible"], false, "{style}");
}

#[tokio::test]
async fn next_previous_and_stop_steer_a_tour() {
    let server = shared();
    let mut socket = connect(server, VIEW).await;
    next_frame(&mut socket).await;
    let viewpoints = json!([
        {"camera": {"position": [205, 185], "yaw": 10}, "caption": "A"},
        {"camera": {"position": [210, 185], "yaw": 20}, "caption": "B"},
        {"camera": {"position": [215, 185], "yaw": 30}, "caption": "C"},
    ]);
    send(
        &mut socket,
        json!({"type": "tour", "action": "start", "viewpoints": viewpoints, "leg_s": 0.3, "dwell_s": 60}),
    )
    .await;
    let (arrived, _) = until(&mut socket, "tour").await;
    assert_eq!((arrived["event"].as_str(), arrived["index"].as_u64()), (Some("flying"), Some(0)));
    let (arrived, _) = until(&mut socket, "tour").await;
    assert_eq!((arrived["event"].as_str(), arrived["index"].as_u64()), (Some("arrived"), Some(0)));
    send(&mut socket, json!({"type": "tour", "action": "previous"})).await;
    let (error, _) = until(&mut socket, "error").await;
    assert_eq!(error["parameter"], "action");
    send(&mut socket, json!({"type": "tour", "action": "next"})).await;
    let (flying, _) = until(&mut socket, "tour").await;
    assert_eq!((flying["event"].as_str(), flying["index"].as_u64()), (Some("flying"), Some(1)));
    let (arrived, _) = until(&mut socket, "tour").await;
    assert_eq!((arrived["event"].as_str(), arrived["caption"].as_str()), (Some("arrived"), Some("B")));
    // A camera control takes over and stops the tour.
    send(&mut socket, json!({"type": "move", "yaw": 5})).await;
    let (stopped, _) = until(&mut socket, "tour").await;
    assert_eq!(stopped["event"], "stopped");
    // The first frame after the move shows it (earlier ones may still be on the way).
    let mut yaws = Vec::new();
    while yaws.last() != Some(&json!(25.0)) {
        let (_, frame, _, _) = next_frame(&mut socket).await;
        yaws.push(frame["camera"]["yaw"].clone());
        assert!(yaws.len() < 4 && yaws.iter().all(|y| *y == 20.0 || *y == 25.0), "{yaws:?}");
    }
}

#[tokio::test]
async fn changes_reach_followers_live_and_the_presenter_shows_them() {
    let dir = tempfile::tempdir().expect("temporary directory");
    let server = TestServer::start(dir.path(), |_| {});
    let (mut presenter, meeting) = presenter(&server).await;
    let code = meeting["code"].as_str().expect("code");
    let mut follower = connect(&server, &format!("{VIEW}&meeting={code}")).await;
    let (_, first, _, _) = next_frame(&mut follower).await;
    // An art map uploaded again (the same PNG) is a change every session hears of.
    let png = get(&server.url("/api/artmaps/tam/0.png")).await.bytes().await.expect("PNG");
    let put = client()
        .put(server.url("/api/artmaps/tam/0"))
        .header("content-type", "image/png")
        .body(png.to_vec())
        .send()
        .await
        .expect("PUT");
    assert!(put.status().is_success(), "{}", put.status());
    let (changed, _) = until(&mut follower, "changed").await;
    assert_eq!(changed["what"], "artmaps", "{changed}");
    // The presenter's view is drawn again with the new maps, and the follower gets that frame.
    let (_, again, _, _) = next_frame(&mut follower).await;
    assert!(again["id"].as_u64() > first["id"].as_u64(), "{again}");
    until(&mut presenter, "changed").await;
}
