//! Several replicas on one PostgreSQL database (issue #16): two `landsketch serve` with data
//! directories of their own on a throw-away PostgreSQL (Debian's `postgresql`, started here in
//! a temporary directory). A layer uploaded on one renders on the other, a comment made on one
//! reaches a WebSocket session on the other within a second, art maps follow, and a replica
//! killed (SIGKILL) in the middle of uploads leaves the database and the other replica's view
//! of it consistent. (Meetings across replicas: `tests/replicas_meetings.rs`.)

mod common;

#[path = "common/postgres.rs"]
mod postgres;

use common::server::{TestServer, client, get, json_of, scene_tiff, sized_scene_tiff};
use common::ws::next_changed;
use postgres::TempPostgres;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::time::{Duration, Instant};

/// How long a change on one replica may take to reach the other.
const PROPAGATION: Duration = Duration::from_secs(1);

fn database() -> Option<TempPostgres> {
    let postgres = TempPostgres::start();
    if postgres.is_none() {
        eprintln!("PostgreSQL is not installed (scripts/setup installs it); skipped");
    }
    postgres
}

fn replica(dir: &std::path::Path, url: &str) -> TestServer {
    let url = url.to_owned();
    TestServer::start(dir, move |c| c.database_url = Some(url))
}

/// Polls `GET url` until `done` holds for its JSON body, at most `wait`; the last body.
async fn poll(url: &str, wait: Duration, done: impl Fn(&Value) -> bool) -> (Value, Duration) {
    let started = Instant::now();
    loop {
        let body = json_of(get(url).await).await;
        if done(&body) || started.elapsed() > wait {
            return (body, started.elapsed());
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

async fn upload(server: &TestServer, query: &str, body: Vec<u8>) -> reqwest::Response {
    client().post(server.url(&format!("/api/layers?{query}"))).body(body).send().await.expect("POST")
}

/// A plan-view render of `layer` in colour (`POST /api/render`).
async fn render_layer(server: &TestServer, layer: &str) -> reqwest::Response {
    let body = json!({"camera": {"mode": "plan", "center": [0, 0], "width": 2000}, "width": 64, "height": 48,
        "mappings": [{"layer": layer, "target": "color", "colormap": "magma"}]});
    let request = client().post(server.url("/api/render")).header("content-type", "application/json");
    request.body(body.to_string()).send().await.expect("POST /api/render")
}

fn ids(list: &Value) -> Vec<String> {
    list["layers"].as_array().expect("layers").iter().map(|l| l["id"].as_str().expect("id").to_owned()).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_replicas_share_layers_comments_viewpoints_and_art_maps() {
    let Some(postgres) = database() else { return };
    let (dir_a, dir_b) = (tempfile::tempdir().expect("temp dir"), tempfile::tempdir().expect("temp dir"));
    let a = replica(dir_a.path(), &postgres.url());
    let b = replica(dir_b.path(), &postgres.url());
    let (mut session, _) = tokio_tungstenite::connect_async(b.ws_url("width=64&height=48")).await.expect("connect");

    // A layer uploaded on A renders on B, and B's sessions are told.
    let query = "name=Air%20temperature&kind=scalar&time=2024-06-01T00:00:00Z&filename=t1.tif";
    let created = upload(&a, query, scene_tiff(0.0)).await;
    assert_eq!(created.status(), 201);
    let meta = json_of(created).await;
    let id = meta["id"].as_str().expect("id").to_owned();
    let told = next_changed(&mut session, PROPAGATION).await.expect("B's session hears of the layer");
    assert_eq!(told, json!({"type": "changed", "what": "layers", "change": "added", "id": id}));
    assert_eq!(json_of(get(&b.url(&format!("/api/layers/{id}"))).await).await, meta, "B has A's layer");
    let rendered = render_layer(&b, &id).await;
    assert_eq!(rendered.status(), 200, "{:?}", rendered.text().await);

    // A time step appended on B reaches A; A's version is B's.
    let step = "name=Air%20temperature&kind=scalar&time=2024-06-02T00:00:00Z&filename=t2.tif";
    assert_eq!(upload(&b, step, scene_tiff(10.0)).await.status(), 200);
    let url = a.url(&format!("/api/layers/{id}"));
    let (on_a, waited) = poll(&url, PROPAGATION, |m| m["steps"].as_array().map(Vec::len) == Some(2)).await;
    assert!(waited <= PROPAGATION, "the step reached A in {waited:?}");
    assert_eq!(on_a, json_of(get(&b.url(&format!("/api/layers/{id}"))).await).await);
    assert_eq!(next_changed(&mut session, PROPAGATION).await.expect("appended")["change"], "changed");

    // A comment made on A appears in B's session within a second.
    let comment = json!({"view": {"width": 160, "height": 120}, "pixel": [80, 110], "text": "Keep the old hedge",
        "author": "citizen-token-0123456789"});
    let request = client().post(a.url("/api/comments")).header("content-type", "application/json");
    let response = request.body(comment.to_string()).send().await.expect("POST comment");
    // From A's answer (the comment is stored then; making it includes a render on A).
    let sent = Instant::now();
    assert_eq!(response.status(), 201, "{:?}", response.text().await);
    let told = next_changed(&mut session, PROPAGATION).await.expect("B's session hears of the comment");
    assert!(sent.elapsed() <= PROPAGATION, "{:?}", sent.elapsed());
    assert_eq!((told["what"].as_str(), told["change"].as_str()), (Some("comments"), Some("added")), "{told}");
    assert_eq!(told["comment"]["text"], "Keep the old hedge");
    let listed = json_of(get(&b.url("/api/comments")).await).await;
    assert_eq!(listed["comments"][0]["text"], "Keep the old hedge");

    // A viewpoint defined on B is announced on A's sessions.
    let (mut on_a, _) = tokio_tungstenite::connect_async(a.ws_url("width=64&height=48")).await.expect("connect");
    let viewpoint = json!({"caption": "From the road", "camera": {"position": [0.0, 0.0], "yaw": 90.0}});
    let put = client().put(b.url("/api/viewpoints/road")).header("content-type", "application/json");
    assert_eq!(put.body(viewpoint.to_string()).send().await.expect("PUT viewpoint").status(), 201);
    let told = next_changed(&mut on_a, PROPAGATION).await.expect("A's session hears of the viewpoint");
    assert_eq!(told, json!({"type": "changed", "what": "viewpoints", "change": "added", "name": "road"}));

    // An art map uploaded on A is used by B, and restoring it on A restores it on B.
    let tam = black_tam();
    assert_eq!(client().put(a.url("/api/artmaps/tam/1")).body(tam).send().await.expect("PUT").status(), 200);
    let source = |list: &Value| list["tams"][1]["source"].as_str().unwrap_or_default().to_owned();
    let (list, waited) = poll(&b.url("/api/artmaps"), PROPAGATION, |l| source(l) == "uploaded").await;
    assert_eq!(source(&list), "uploaded", "B uses A's TAM after {waited:?}");
    let png = |s: &TestServer| client().get(s.url("/api/artmaps/tam/1.png")).send();
    assert_eq!(
        png(&a).await.expect("A").bytes().await.expect("A"),
        png(&b).await.expect("B").bytes().await.expect("B")
    );
    assert_eq!(client().delete(a.url("/api/artmaps/tam/1")).send().await.expect("DELETE").status(), 204);
    let (list, _) = poll(&b.url("/api/artmaps"), PROPAGATION, |l| source(l) == "generated").await;
    assert_eq!(source(&list), "generated");

    // A layer deleted on B is gone from A.
    assert_eq!(client().delete(b.url(&format!("/api/layers/{id}"))).send().await.expect("DELETE").status(), 204);
    let (list, _) = poll(&a.url("/api/layers"), PROPAGATION, |l| ids(l).is_empty()).await;
    assert_eq!(ids(&list), Vec::<String>::new());

    // A third replica started now copies what the database holds: the comment, no layer.
    drop(session);
    drop(on_a);
    let dir_c = tempfile::tempdir().expect("temp dir");
    let c = replica(dir_c.path(), &postgres.url());
    assert_eq!(json_of(get(&c.url("/api/comments")).await).await["comments"].as_array().map(Vec::len), Some(1));
    assert_eq!(ids(&json_of(get(&c.url("/api/layers")).await).await), Vec::<String>::new());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_single_servers_data_directory_joins_the_database_then_follows_it() {
    let Some(postgres) = database() else { return };
    let (dir_a, dir_b) = (tempfile::tempdir().expect("temp dir"), tempfile::tempdir().expect("temp dir"));
    // A single server (SQLite) with an uploaded layer and art map.
    let single = TestServer::start(dir_a.path(), |_| {});
    let created = upload(&single, "name=Noise&kind=scalar&filename=noise.tif", scene_tiff(0.0)).await;
    assert_eq!(created.status(), 201);
    let id = json_of(created).await["id"].as_str().expect("id").to_owned();
    assert_eq!(
        client().put(single.url("/api/artmaps/tam/1")).body(black_tam()).send().await.expect("PUT").status(),
        200
    );
    single.stop().expect("stopped");

    // Started on PostgreSQL, its data directory adds what it holds to the database.
    let a = replica(dir_a.path(), &postgres.url());
    let b = replica(dir_b.path(), &postgres.url());
    for server in [&a, &b] {
        assert_eq!(ids(&json_of(get(&server.url("/api/layers")).await).await), vec![id.clone()]);
        let art = json_of(get(&server.url("/api/artmaps")).await).await;
        assert_eq!(art["tams"][1]["source"], "uploaded", "{art}");
    }
    // From then on the database is the truth: a layer deleted while A is down is gone from A
    // when it comes back.
    a.stop().expect("stopped");
    assert_eq!(client().delete(b.url(&format!("/api/layers/{id}"))).send().await.expect("DELETE").status(), 204);
    let a = replica(dir_a.path(), &postgres.url());
    assert_eq!(ids(&json_of(get(&a.url("/api/layers")).await).await), Vec::<String>::new());
    let art = json_of(get(&a.url("/api/artmaps")).await).await;
    assert_eq!(art["tams"][1]["source"], "uploaded", "the art map stays: {art}");
}

/// A TAM strip of the renderer's shape (6 tone levels of 256²), every pixel ink.
fn black_tam() -> Vec<u8> {
    let image = image::GrayImage::from_pixel(256 * 6, 256, image::Luma([0]));
    let mut bytes = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).expect("encode PNG");
    bytes
}

/// `landsketch serve` as a child process (so that it can be killed with SIGKILL) with its
/// address.
struct Child {
    process: std::process::Child,
    addr: String,
}

impl Child {
    fn start(data_dir: &std::path::Path, url: &str) -> Child {
        let mut process = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
            .args(["serve", "--scene", common::server::SCENE, "--addr", "127.0.0.1:0", "--database-url", url])
            .arg("--data-dir")
            .arg(data_dir)
            .env("XDG_RUNTIME_DIR", std::env::var("XDG_RUNTIME_DIR").unwrap_or_else(|_| "/tmp".into()))
            .env("RUST_LOG", "warn")
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("start landsketch serve");
        let stdout = process.stdout.take().expect("stdout");
        let (line, address) = std::sync::mpsc::channel();
        // Reads stdout to its end, so that the server never writes to a closed pipe.
        std::thread::spawn(move || {
            for text in BufReader::new(stdout).lines().map_while(Result::ok) {
                if let Some(rest) = text.strip_prefix("landsketch: open http://") {
                    let _ = line.send(rest.split('/').next().unwrap_or_default().to_owned());
                }
            }
        });
        let addr = address.recv_timeout(Duration::from_secs(60)).expect("the address line");
        let deadline = Instant::now() + Duration::from_secs(60);
        while common::server::blocking_status(&format!("http://{addr}/api/health")) != Some(200) {
            assert!(Instant::now() < deadline, "the replica did not become ready");
            std::thread::sleep(Duration::from_millis(50));
        }
        Child { process, addr }
    }

    fn kill(mut self) {
        self.process.kill().expect("SIGKILL");
        self.process.wait().expect("reaped");
    }
}

/// Every layer row of the database with its step files, and every step row's layer: the
/// database is consistent when each layer's metadata lists exactly its step rows.
async fn database_is_consistent(url: &str) {
    let pool = sqlx::PgPool::connect(url).await.expect("connect");
    let layers: Vec<(String, String)> =
        sqlx::query_as("SELECT id, meta FROM landsketch_layers").fetch_all(&pool).await.expect("layers");
    let steps: Vec<(String, String, i32)> =
        sqlx::query_as("SELECT layer_id, file, length(data) FROM landsketch_layer_steps")
            .fetch_all(&pool)
            .await
            .expect("steps");
    let mut by_layer: BTreeMap<String, Vec<(String, i32)>> = BTreeMap::new();
    for (layer, file, length) in steps {
        by_layer.entry(layer).or_default().push((file, length));
    }
    for (id, meta) in &layers {
        let meta: Value = serde_json::from_str(meta).expect("meta is JSON");
        let mut listed: Vec<(String, i32)> = meta["steps"]
            .as_array()
            .expect("steps")
            .iter()
            .map(|s| {
                let cells = s["width"].as_i64().expect("width") * s["height"].as_i64().expect("height");
                (s["file"].as_str().expect("file").to_owned(), i32::try_from(cells * 4).expect("size"))
            })
            .collect();
        listed.sort();
        let mut stored = by_layer.remove(id).unwrap_or_default();
        stored.sort();
        assert_eq!(listed, stored, "layer {id}: its metadata lists exactly its step rows, of their sizes");
    }
    assert!(by_layer.is_empty(), "step rows without a layer: {by_layer:?}");
    pool.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killing_a_replica_mid_upload_leaves_the_database_and_the_other_replica_consistent() {
    let Some(postgres) = database() else { return };
    let (dir_a, dir_b) = (tempfile::tempdir().expect("temp dir"), tempfile::tempdir().expect("temp dir"));
    let b = replica(dir_b.path(), &postgres.url());
    // 3000 × 3000 cells: 36 MB per step, so the upload, its decoding and its transaction
    // take long enough to be interrupted.
    let big = sized_scene_tiff(3000, 3000, 0.0);
    // The first upload runs to its end and times the whole; the others are killed at a
    // fraction of that time: receiving the body, decoding, writing, in the transaction.
    let mut whole: Option<Duration> = None;
    let mut interrupted = 0;
    for (round, fraction) in [None, Some(0.2), Some(0.4), Some(0.6), Some(0.8), Some(0.95)].into_iter().enumerate() {
        let url = postgres.url();
        let dir = dir_a.path().to_owned();
        let a = tokio::task::spawn_blocking(move || Child::start(&dir, &url)).await.expect("start A");
        let query =
            format!("name=Soil%20moisture&kind=scalar&time=2024-06-{:02}T00:00:00Z&filename=big.tif", round + 1);
        let target = format!("http://{}/api/layers?{query}", a.addr);
        let body = big.clone();
        let started = Instant::now();
        let request = tokio::spawn(async move { client().post(target).body(body).send().await });
        match fraction.zip(whole) {
            Some((fraction, whole)) => tokio::time::sleep(whole.mul_f64(fraction)).await,
            None => {
                let response = request.await.expect("request task").expect("the first upload");
                assert_eq!(response.status(), 201);
                whole = Some(started.elapsed());
                tokio::task::spawn_blocking(move || a.kill()).await.expect("stop A");
                continue;
            }
        }
        tokio::task::spawn_blocking(move || a.kill()).await.expect("kill A");
        match request.await.expect("request task") {
            Ok(response) => assert!(response.status().is_success(), "round {round}: {}", response.status()),
            Err(_) => interrupted += 1,
        }
        tokio::time::sleep(PROPAGATION).await;
        database_is_consistent(&postgres.url()).await;
        // B's view: every layer it lists renders.
        for id in ids(&json_of(get(&b.url("/api/layers")).await).await) {
            let rendered = render_layer(&b, &id).await;
            assert_eq!(rendered.status(), 200, "round {round}: layer {id}: {:?}", rendered.text().await);
        }
    }
    assert!(interrupted >= 2, "at least two uploads were cut off by the kill ({interrupted})");
    let steps = json_of(get(&b.url("/api/layers")).await).await["layers"][0]["steps"].as_array().map(Vec::len);
    assert!(
        steps.is_some_and(|n| (1..=6 - interrupted).contains(&n)),
        "the first upload and the completed ones: {steps:?}"
    );
    // A restarted agrees with B (what it had written locally but not to the database is gone).
    let url = postgres.url();
    let dir = dir_a.path().to_owned();
    let a = tokio::task::spawn_blocking(move || Child::start(&dir, &url)).await.expect("restart A");
    let on_a = json_of(get(&format!("http://{}/api/layers", a.addr)).await).await;
    assert_eq!(on_a, json_of(get(&b.url("/api/layers")).await).await);
    tokio::task::spawn_blocking(move || a.kill()).await.expect("stop A");
}
