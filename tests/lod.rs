//! Levels of detail, culling and the preprocessing cache (SPEC P4): the same tree at every
//! level and distance (reference image + silhouette overlap), instance culling against the
//! frustum, level selection by distance, and a second start that does no preprocessing.

mod common;

use common::{assert_matches_reference, fraction, gpu, trees_on_a_plain};
use landsketch::prep::cache::DiskCache;
use landsketch::prep::lod::{LodLevel, LodSettings};
use landsketch::render::{RenderOptions, Renderer, Style};
use landsketch::scene::camera::Camera;
use std::path::Path;
use std::sync::Arc;

const WIDTH: u32 = 160;
const HEIGHT: u32 = 200;

fn forced(level: LodLevel) -> RenderOptions {
    RenderOptions { lod: LodSettings { force: Some(level), ..LodSettings::default() }, ..RenderOptions::default() }
}

/// Looking north at the tree at the origin from `distance` metres, aimed at its crown.
fn camera_at(distance: f32) -> Camera {
    let pitch = (5.0f32 / distance).atan().to_degrees();
    Camera::perspective([0.0, -distance, 101.7], 0.0, pitch, 40.0)
}

/// The pixels showing a plant (object IDs with a vegetation layer code).
fn plant_mask(renderer: &Renderer, camera: &Camera) -> Vec<bool> {
    renderer.object_ids(camera, WIDTH, HEIGHT).unwrap().iter().map(|id| id >> 24 >= 2).collect()
}

fn overlap(a: &[bool], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let either = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    both as f64 / either.max(1) as f64
}

#[test]
fn every_level_shows_the_same_tree_at_near_middle_and_far_distance() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderers: Vec<Renderer> =
        LodLevel::ALL.iter().map(|&level| Renderer::with_options(gpu(), &scene, &forced(level)).unwrap()).collect();
    let distances = [18.0, 45.0, 85.0];
    let mut sheet = image::RgbaImage::new(WIDTH * 3, HEIGHT * 3);
    for (row, renderer) in renderers.iter().enumerate() {
        for (col, &distance) in distances.iter().enumerate() {
            let camera = camera_at(distance);
            let image = renderer.render(&camera, Style::default(), WIDTH, HEIGHT).unwrap();
            let ink = fraction(&image, |l| l < 0.5);
            assert!(ink > 0.002, "level {row} at {distance} m draws no ink ({ink})");
            image::imageops::replace(&mut sheet, &image, i64::from(WIDTH) * col as i64, i64::from(HEIGHT) * row as i64);
        }
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/lod_levels.png"), 0.03);
    // The billboards cover the model's silhouette: each level's plant pixels overlap the full
    // model's at every distance.
    for &distance in &distances {
        let camera = camera_at(distance);
        let full = plant_mask(&renderers[0], &camera);
        let coverage = full.iter().filter(|p| **p).count();
        assert!(coverage > 20, "the tree covers {coverage} pixels at {distance} m");
        for (level, renderer) in renderers.iter().enumerate().skip(1) {
            let iou = overlap(&full, &plant_mask(renderer, &camera));
            assert!(iou > 0.55, "level {level} at {distance} m overlaps the full tree by {iou:.2}");
        }
    }
}

#[test]
fn instance_culling_removes_what_is_outside_the_frustum() {
    // Five trees ahead of the camera (north), three behind it, two far to the sides.
    let ahead = [[-20.0, 40.0], [-10.0, 60.0], [0.0, 30.0], [10.0, 50.0], [20.0, 70.0]];
    let outside = [[0.0, -60.0], [-20.0, -80.0], [10.0, -50.0], [-95.0, 5.0], [95.0, 5.0]];
    let positions: Vec<[f32; 2]> = ahead.iter().chain(&outside).copied().collect();
    let scene = trees_on_a_plain(&positions);
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = scene.default_camera;
    let stats = renderer.draw_stats(&camera, 320, 240);
    assert_eq!(stats.plants, 10);
    assert_eq!(stats.plants_drawn, 5, "{stats:?}");
    // Nothing visible was culled: every tree ahead shows up in the ID buffer.
    let ids = renderer.object_ids(&camera, 320, 240).unwrap();
    for index in 0..ahead.len() as u32 {
        let id = (2 << 24) | (index + 1);
        assert!(ids.contains(&id), "tree {index} ahead is missing from the ID buffer");
    }
    // Turned around, the trees behind are the ones drawn.
    let back = Camera { yaw: 180.0, ..camera };
    assert_eq!(renderer.draw_stats(&back, 320, 240).plants_drawn, 3);
}

#[test]
fn levels_are_chosen_by_distance_and_cut_the_triangles() {
    let positions: Vec<[f32; 2]> = (0..40).map(|i| [(i % 5) as f32 * 8.0 - 16.0, -20.0 + i as f32 * 3.0]).collect();
    let scene = trees_on_a_plain(&positions);
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = scene.default_camera;
    let stats = renderer.draw_stats(&camera, 512, 384);
    assert!(stats.per_level.iter().all(|&n| n > 0), "near, middle and far trees: {stats:?}");
    assert!(stats.triangles < stats.source_triangles / 2, "{stats:?}");
    let full = Renderer::with_options(gpu(), &scene, &forced(LodLevel::Full)).unwrap();
    let all = full.draw_stats(&camera, 512, 384);
    assert_eq!(all.triangles, all.source_triangles, "forced full detail draws the source geometry");
}

#[test]
fn a_second_start_with_the_disk_cache_does_no_preprocessing() {
    let dir = tempfile::tempdir().unwrap();
    // A species no other test uses, so the in-process HLP cache starts cold.
    let mut scene = trees_on_a_plain(&[[0.0, 0.0], [6.0, 20.0]]);
    scene.species[0].hlp_radius *= 0.93;
    let render = |cache: &Arc<DiskCache>| {
        let options = RenderOptions { cache: Some(cache.clone()), ..RenderOptions::default() };
        let renderer = Renderer::with_options(gpu(), &scene, &options).unwrap();
        renderer.render(&camera_at(45.0), Style::default(), WIDTH, HEIGHT).unwrap()
    };
    let first_cache = Arc::new(DiskCache::open(dir.path()).unwrap());
    let first = render(&first_cache);
    let stats = first_cache.stats();
    assert_eq!((stats.hits, stats.misses), (0, 2), "HLPs and billboards computed once: {stats:?}");
    // A restart: a new cache object on the same directory answers everything from disk. (The
    // HLPs are still in this process's memory cache, so only the billboards reach the disk.)
    let second_cache = Arc::new(DiskCache::open(dir.path()).unwrap());
    let second = render(&second_cache);
    let stats = second_cache.stats();
    assert_eq!(stats.misses, 0, "nothing recomputed: {stats:?}");
    assert!(stats.hits >= 1, "{stats:?}");
    assert_eq!(first, second, "cached preprocessing renders the same image");
}
