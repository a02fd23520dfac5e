//! A meeting presented on one replica is followed on another (issue #16): the follower's
//! replica relays it, rendering the presenter's views, with caption, follower count and end.
//! Its own binary, so that it does not share the machine with the other replica tests
//! (`tests/replicas.rs`) while it waits on frames.

mod common;

#[path = "common/postgres.rs"]
mod postgres;

use common::server::{TestServer, get, json_of};
use common::ws::{connect, next_frame, send, until};
use postgres::TempPostgres;
use serde_json::json;

fn replica(dir: &std::path::Path, url: &str) -> TestServer {
    let url = url.to_owned();
    TestServer::start(dir, move |c| c.database_url = Some(url))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_meeting_presented_on_one_replica_is_followed_on_another() {
    let Some(postgres) = TempPostgres::start() else {
        eprintln!("PostgreSQL is not installed (scripts/setup installs it); skipped");
        return;
    };
    let (dir_a, dir_b) = (tempfile::tempdir().expect("temp dir"), tempfile::tempdir().expect("temp dir"));
    let a = replica(dir_a.path(), &postgres.url());
    let b = replica(dir_b.path(), &postgres.url());
    let view = "width=64&height=48";
    let mut presenter = connect(&a, view).await;
    next_frame(&mut presenter).await;
    send(&mut presenter, json!({"type": "open_meeting", "caption": "Hedge row"})).await;
    let (meeting, _) = until(&mut presenter, "meeting").await;
    let code = meeting["code"].as_str().expect("code").to_owned();
    let (_, _, opening, opening_image) = next_frame(&mut presenter).await;

    // B does not present the meeting; it relays it and renders the presenter's view itself.
    let info = json_of(get(&b.url(&format!("/api/meetings/{code}"))).await).await;
    assert_eq!(info["code"], code.as_str(), "{info}");
    let mut follower = connect(&b, &format!("{view}&meeting={code}")).await;
    let (joined, _) = until(&mut follower, "meeting").await;
    assert_eq!((joined["role"].as_str(), joined["code"].as_str()), (Some("follower"), Some(code.as_str())));
    // The relay may show an earlier frame of the presenter's first while it renders the
    // newest; the camera has not moved, so every one shows the opening picture.
    loop {
        let (_, _, header, image) = next_frame(&mut follower).await;
        assert_same_picture(&image, &opening_image, "B renders the presenter's view");
        if header.frame_id >= opening.frame_id {
            break;
        }
    }
    // The presenter counts the follower on B.
    let (audience, _) = until(&mut presenter, "meeting").await;
    assert_eq!(audience["followers"], 1, "{audience}");
    let info = json_of(get(&a.url(&format!("/api/meetings/{code}"))).await).await;
    assert_eq!(info["followers"], 1, "{info}");

    // The presenter moves: the follower on B gets the same frames.
    send(&mut presenter, json!({"type": "move", "yaw": 20, "forward": 5})).await;
    let last = loop {
        let (_, _, header, image) = next_frame(&mut presenter).await;
        if header.still {
            break (header.frame_id, image);
        }
    };
    let relayed = loop {
        let (_, _, header, image) = next_frame(&mut follower).await;
        if header.frame_id >= last.0 {
            break (header.frame_id, image);
        }
    };
    assert_eq!(relayed.0, last.0, "the follower on B gets the presenter's still at rest");
    assert_same_picture(&relayed.1, &last.1, "the still at rest, rendered on B");

    // The caption and the end of the meeting reach the follower.
    send(&mut presenter, json!({"type": "caption", "text": "The new wood"})).await;
    let (status, _) = until(&mut follower, "meeting").await;
    assert_eq!(status["caption"], "The new wood");
    send(&mut presenter, json!({"type": "close_meeting"})).await;
    let (ended, _) = until(&mut follower, "meeting_ended").await;
    assert!(ended["reason"].as_str().is_some_and(|r| r.contains("ended")), "{ended}");
    assert_eq!(get(&b.url(&format!("/api/meetings/{code}"))).await.status(), 404);
}

/// Asserts that two encoded frames show the same picture: the relay renders the presenter's
/// view with its own per-view hatching state (the reference points follow each lane's own
/// frames, thesis eq. 6.2), so strokes may differ in a few pixels, nothing more.
fn assert_same_picture(a: &[u8], b: &[u8], what: &str) {
    let (a, b) =
        (image::load_from_memory(a).expect("frame").to_rgb8(), image::load_from_memory(b).expect("frame").to_rgb8());
    assert_eq!(a.dimensions(), b.dimensions(), "{what}");
    let differing =
        a.pixels().zip(b.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(x, y)| x.abs_diff(y) > 40)).count();
    let share = differing as f64 / f64::from(a.width() * a.height());
    assert!(share < 0.03, "{what}: {:.1} % of the pixels differ", 100.0 * share);
}
