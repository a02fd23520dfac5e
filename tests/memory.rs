//! Memory stays flat over many frames. A renderer that leaks per frame takes a long-running
//! server down: indexing a uniform array with a computed index in the G-buffer shader once
//! leaked ~12 MB per frame on lavapipe. (Their own test binary, run one at a time, so no other test's
//! allocations move the resident size while one measures.)

mod common;

use common::{full_detail, trees_on_a_plain};
use landsketch::render::{FrameRequest, Style};

/// One measurement at a time: another test's allocations would move the resident size.
fn measuring() -> std::sync::MutexGuard<'static, ()> {
    static MEASURING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    MEASURING.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[test]
fn rendering_many_frames_does_not_grow_memory() {
    let _alone = measuring();
    let positions: Vec<[f32; 2]> = (0..30).map(|i| [(i % 6) as f32 * 6.0 - 15.0, (i / 6) as f32 * 8.0]).collect();
    let scene = trees_on_a_plain(&positions);
    let renderer = full_detail(&scene);
    let camera = scene.default_camera;
    let frame =
        || renderer.render(FrameRequest::new(&camera, Style::default(), 96, 72)).map(|f| f.image).expect("frame");
    // Warm up: pipelines, shader variants, the cached render targets.
    for _ in 0..10 {
        frame();
    }
    let before = landsketch::bench::rss_mib().expect("VmRSS in /proc/self/status");
    for _ in 0..60 {
        frame();
    }
    let growth = landsketch::bench::rss_mib().expect("VmRSS in /proc/self/status") - before;
    assert!(growth < 60.0, "60 frames grew the resident size by {growth:.0} MiB");
}

/// A plan view of the plain with a scalar field mapped to colour and hatch colour, as a public server renders
/// without a token: every such frame once kept ~2 MB on lavapipe 22.3 (early returns taken by
/// some pixels of the projection shader, see `shaders/data.wgsl`).
#[test]
fn rendering_many_mapped_frames_does_not_grow_memory() {
    let _alone = measuring();
    use landsketch::fields::{Field, FieldKind, FieldStep, Mapping};
    use landsketch::gis::{Crs, CrsDefinition, GeoTransform, Raster};
    use landsketch::render::projection::{DataLayer, DataMapping, DataView};
    use landsketch::scene::camera::Camera;
    use std::sync::Arc;

    let scene = trees_on_a_plain(&[]);
    let renderer = landsketch::render::Renderer::new(common::gpu(), &scene).expect("renderer");
    let (cols, rows) = (64, 64);
    let raster = Raster {
        width: cols,
        height: rows,
        data: (0..cols * rows).map(|i| (i % cols) as f64).collect(),
        nodata: None,
        transform: GeoTransform {
            origin_x: 500_000.0,
            origin_y: 4_400_000.0,
            cell_width: 200.0 / cols as f64,
            cell_height: 200.0 / rows as f64,
        },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    };
    let step = FieldStep { time: None, raster };
    let crs = CrsDefinition::from_epsg(32613).expect("UTM 13N");
    let field = Field::new(FieldKind::Scalar, crs, None, vec![step]).expect("field");
    let mapping = |target| -> Mapping {
        serde_json::from_value(serde_json::json!({"layer": "ramp", "target": target})).expect("mapping")
    };
    let layer = Arc::new(DataLayer { key: "ramp".into(), field });
    // Colour and coloured hatching: the compose pass draws data layers too.
    let mappings =
        ["color", "hatch_color"].map(|target| DataMapping { layer: layer.clone(), mapping: mapping(target) });
    let data = DataView { mappings: mappings.to_vec(), time: None };
    let frame = |i: usize| {
        let camera = Camera::plan(i as f32 % 7.0, 0.0, 300.0, 200.0);
        renderer
            .render(FrameRequest::new(&camera, Style::default(), 64, 64).data(&data))
            .map(|f| f.image)
            .expect("frame")
    };
    for i in 0..20 {
        frame(i);
    }
    let before = landsketch::bench::rss_mib().expect("VmRSS in /proc/self/status");
    for i in 0..1000 {
        frame(i);
    }
    let growth = landsketch::bench::rss_mib().expect("VmRSS in /proc/self/status") - before;
    assert!(growth < 50.0, "1,000 mapped frames grew the resident size by {growth:.0} MiB");
}
