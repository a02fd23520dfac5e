//! A real `landsketch serve` on a loopback port for the API tests: started on its own thread
//! and runtime with the sample scene, stopped when dropped; plus small HTTP helpers.

use clap::Parser;
use landsketch::api::{Server, ServerConfig};
use landsketch::gis::{Crs, GeoTransform, Raster, write_geotiff_f32};
use landsketch::render::Gpu;
use landsketch::scene::Scene;
use serde_json::Value;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

pub const SCENE: &str = "data/boulder/scene.toml";

pub fn loaded() -> &'static (Arc<Scene>, Arc<Gpu>) {
    static LOADED: OnceLock<(Arc<Scene>, Arc<Gpu>)> = OnceLock::new();
    LOADED.get_or_init(|| {
        let scene = Scene::load(Path::new(SCENE)).expect("sample scene");
        let gpu = Gpu::new().expect("a Vulkan adapter (lavapipe: apt-get install mesa-vulkan-drivers)");
        (Arc::new(scene), Arc::new(gpu))
    })
}

/// A server on its own thread and runtime with the data directory `data_dir`, stopped when
/// dropped.
pub struct TestServer {
    pub addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<Result<(), landsketch::api::ServerError>>>,
}

impl TestServer {
    pub fn start(data_dir: &Path, configure: impl FnOnce(&mut ServerConfig)) -> TestServer {
        let (scene, _) = loaded().clone();
        TestServer::start_scene(data_dir, Path::new(SCENE), scene, configure)
    }

    /// A server on the scene file `path` whose scene `scene` is loaded already.
    pub fn start_scene(
        data_dir: &Path,
        path: &Path,
        scene: Arc<Scene>,
        configure: impl FnOnce(&mut ServerConfig),
    ) -> TestServer {
        TestServer::try_start_scene(data_dir, path, scene, configure).unwrap_or_else(|e| panic!("server failed: {e}"))
    }

    /// Like [`TestServer::start_scene`]; the error with which the server stopped instead of
    /// becoming ready.
    pub fn try_start_scene(
        data_dir: &Path,
        path: &Path,
        scene: Arc<Scene>,
        configure: impl FnOnce(&mut ServerConfig),
    ) -> Result<TestServer, String> {
        let mut config = ServerConfig::try_parse_from([
            "serve",
            "--scene",
            path.to_str().expect("UTF-8 scene path"),
            "--addr",
            "127.0.0.1:0",
            "--data-dir",
            data_dir.to_str().expect("UTF-8 temp dir"),
        ])
        .expect("valid flags");
        config.admin_token = None;
        config.cors_origins.clear();
        configure(&mut config);
        let gpu = loaded().1.clone();
        let (addr_tx, addr_rx) = std::sync::mpsc::channel();
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
            runtime.block_on(async move {
                let server = Server::bind(config).await?;
                addr_tx.send(server.local_addr()?).expect("test waits for the address");
                server
                    .run_with(scene, gpu, async move {
                        let _ = stopped.await;
                    })
                    .await
            })
        });
        let Ok(addr) = addr_rx.recv() else {
            return Err(match thread.join() {
                Ok(Err(e)) => e.to_string(),
                _ => "the server thread ended before binding".to_owned(),
            });
        };
        let mut server = TestServer { addr, stop: Some(stop), thread: Some(thread) };
        let deadline = Instant::now() + Duration::from_secs(60);
        while blocking_status(&server.url("/api/health")) != Some(200) {
            if server.thread.as_ref().is_some_and(|t| t.is_finished()) {
                return Err(match server.shutdown() {
                    Err(e) => e.to_string(),
                    Ok(()) => "the server stopped without an error".to_owned(),
                });
            }
            assert!(Instant::now() < deadline, "server did not become ready");
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(server)
    }

    /// The HTTP URL of `path`.
    /// The HTTP URL of `path`.
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    /// The WebSocket URL with `query`.
    pub fn ws_url(&self, query: &str) -> String {
        format!("ws://{}/api/ws?{query}", self.addr)
    }

    /// Stops the server and returns what `run` returned.
    pub fn stop(mut self) -> Result<(), landsketch::api::ServerError> {
        self.shutdown()
    }

    pub fn shutdown(&mut self) -> Result<(), landsketch::api::ServerError> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        match self.thread.take() {
            Some(thread) => thread.join().expect("server thread"),
            None => Ok(()),
        }
    }
}

impl Drop for TestServer {
    fn drop(&mut self) {
        let _ = self.shutdown();
    }
}

/// Status of a GET with a plain blocking TCP request (for use outside a runtime).
pub fn blocking_status(url: &str) -> Option<u16> {
    use std::io::{Read, Write};
    let rest = url.strip_prefix("http://")?;
    let (host, path) = rest.split_at(rest.find('/')?);
    let mut stream = std::net::TcpStream::connect(host).ok()?;
    write!(stream, "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").ok()?;
    let mut response = String::new();
    stream.read_to_string(&mut response).ok()?;
    response.split_whitespace().nth(1)?.parse().ok()
}

pub fn client() -> reqwest::Client {
    reqwest::Client::builder().timeout(Duration::from_secs(60)).build().expect("HTTP client")
}

pub async fn get(url: &str) -> reqwest::Response {
    client().get(url).send().await.expect("GET")
}

/// The JSON body of a response (panics with the body if it is not JSON).
pub async fn json_of(response: reqwest::Response) -> Value {
    let bytes = response.bytes().await.expect("body");
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&bytes)))
}

/// Writes `request` on a raw connection and reads until the server closes it (at most
/// `wait`); returns what came back and how long the server kept the connection.
pub async fn raw_exchange(server: &TestServer, request: &[u8], wait: Duration) -> (String, Duration) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut stream = tokio::net::TcpStream::connect(server.addr).await.expect("connect");
    stream.write_all(request).await.expect("write");
    let started = Instant::now();
    let mut received = Vec::new();
    let mut buffer = [0u8; 4096];
    loop {
        match tokio::time::timeout_at((started + wait).into(), stream.read(&mut buffer)).await {
            Ok(Ok(0) | Err(_)) => break,
            Ok(Ok(n)) => received.extend_from_slice(&buffer[..n]),
            Err(_) => {
                panic!("the server kept the connection open for {wait:?}; got {:?}", String::from_utf8_lossy(&received))
            }
        }
    }
    (String::from_utf8_lossy(&received).into_owned(), started.elapsed())
}

/// A Float32 GeoTIFF (EPSG:4326) of 8 × 6 cells exactly covering the sample scene's DEM, with
/// values `offset + column`.
pub fn scene_tiff(offset: f64) -> Vec<u8> {
    sized_scene_tiff(8, 6, offset)
}

/// [`scene_tiff`] with `width` × `height` cells.
pub fn sized_scene_tiff(width: usize, height: usize, offset: f64) -> Vec<u8> {
    let dem = &loaded().0.terrain.dem;
    let e = dem.extent();
    let raster = Raster {
        width,
        height,
        data: (0..width * height).map(|i| offset + (i % width) as f64).collect(),
        nodata: None,
        transform: GeoTransform {
            origin_x: e.min_x,
            origin_y: e.max_y,
            cell_width: (e.max_x - e.min_x) / width as f64,
            cell_height: (e.max_y - e.min_y) / height as f64,
        },
        crs: Crs::Geographic { epsg: Some(4326) },
        palette: None,
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("ramp.tif");
    write_geotiff_f32(&path, &raster).expect("write GeoTIFF");
    std::fs::read(&path).expect("read GeoTIFF")
}
