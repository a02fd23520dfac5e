//! Memory stays flat over many frames. A renderer that leaks per frame takes a long-running
//! server down: indexing a uniform array with a computed index in the G-buffer shader once
//! leaked ~12 MB per frame on lavapipe. (Its own test binary, so no other test's allocations
//! move the resident size while it measures.)

mod common;

use common::{full_detail, trees_on_a_plain};
use landsketch::render::Style;

fn resident_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let kib: f64 = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        .expect("VmRSS");
    kib / 1024.0
}

#[test]
fn rendering_many_frames_does_not_grow_memory() {
    let positions: Vec<[f32; 2]> = (0..30).map(|i| [(i % 6) as f32 * 6.0 - 15.0, (i / 6) as f32 * 8.0]).collect();
    let scene = trees_on_a_plain(&positions);
    let renderer = full_detail(&scene);
    let camera = scene.default_camera;
    let frame = || renderer.render(&camera, Style::default(), 96, 72).expect("frame");
    // Warm up: pipelines, shader variants, the cached render targets.
    for _ in 0..10 {
        frame();
    }
    let before = resident_mib();
    for _ in 0..60 {
        frame();
    }
    let growth = resident_mib() - before;
    assert!(growth < 60.0, "60 frames grew the resident size by {growth:.0} MiB");
}
