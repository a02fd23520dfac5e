//! What each fuzz target feeds to landsketch, shared by the targets (`fuzz_targets/*.rs`) and by
//! the replay of found inputs in `cargo test` (`tests/fuzz_inputs.rs`), so both run the same code.
//! Every function must return normally for any input: an error is fine, a panic is a bug.

use landsketch::api::view::ViewParams;
use landsketch::api::ws::ClientMessage;
use landsketch::fields::{FieldKind, LoadOptions, load_bytes};
use landsketch::gis::vector::{SceneTarget, read_csv, read_geojson};
use landsketch::gis::{Crs, CrsDefinition, LocalFrame};
use landsketch::render::artmaps::{Sam, Tam};
use landsketch::scene::config::SceneConfig;
use landsketch::scene::gltf_loader::load_gltf;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A fuzz target: its name (`cargo fuzz run <name>`, `fuzz/regressions/<name>/`) and entry point.
pub type Target = (&'static str, fn(&[u8]));

/// Every target.
pub const TARGETS: [Target; 6] = [
    ("upload", upload),
    ("art_map", art_map),
    ("scene_file", scene_file),
    ("view_request", view_request),
    ("vector_plan", vector_plan),
    ("gltf_model", gltf_model),
];

fn scratch_dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("landsketch-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("the fuzzer's scratch directory");
        dir
    })
}

/// A data-layer upload (`PUT /api/layers/{name}`): format detection (by content), then the
/// GeoTIFF, ESRI ASCII grid, NetCDF or GeoJSON reader with the server's default limits, as a
/// scalar and as a label layer.
pub fn upload(data: &[u8]) {
    for kind in [FieldKind::Scalar, FieldKind::Label] {
        let mut opts = LoadOptions::new(kind);
        opts.crs = Some(CrsDefinition::wgs84());
        let _ = load_bytes(data, Some("upload"), &opts, scratch_dir());
    }
}

/// An uploaded art map (`PUT /api/artmaps/…`): a tonal art map strip and a silhouette art map.
pub fn art_map(data: &[u8]) {
    let _ = Tam::from_png_bytes(data, 8, Path::new("fuzz.png"));
    let _ = Sam::from_png_bytes(data, Path::new("fuzz.png"));
}

/// A scene file as `landsketch serve` parses it before loading what it names.
pub fn scene_file(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = toml::from_str::<SceneConfig>(text);
    }
}

/// What a client sends to ask for a view: a `GET /api/render` query string, a
/// `POST /api/render` JSON body, a WebSocket control message.
pub fn view_request(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = ViewParams::from_query(text);
    }
    let _ = serde_json::from_slice::<ViewParams>(data);
    let _ = serde_json::from_slice::<ClientMessage>(data);
}

/// A plan's vector file (`[[layers.plans]]`), GeoJSON and CSV, moved into a scene in EPSG:2056.
pub fn vector_plan(data: &[u8]) {
    static SCENE: OnceLock<(CrsDefinition, LocalFrame)> = OnceLock::new();
    let Ok(text) = std::str::from_utf8(data) else { return };
    let (crs, frame) = SCENE.get_or_init(|| {
        let crs = CrsDefinition::from_epsg(2056).expect("EPSG:2056 is in the table");
        let frame = LocalFrame::new(Crs::from_epsg(2056).expect("EPSG:2056"), 2_600_000.0, 1_200_000.0)
            .expect("a local frame in EPSG:2056");
        (crs, frame)
    });
    let target = SceneTarget { crs, frame };
    let _ = read_geojson(Path::new("plan.geojson"), text, None, target);
    let _ = read_csv(Path::new("plants.csv"), text, None, target);
}

/// A plant model (`.glb`/`.gltf`) named by a scene, loaded from a scratch file.
pub fn gltf_model(data: &[u8]) {
    let path = scratch_dir().join(format!("model-{:?}.glb", std::thread::current().id()));
    if std::fs::write(&path, data).is_ok() {
        let _ = load_gltf(&path);
    }
}
