//! Levels of detail, culling and the preprocessing cache (SPEC P4): the same tree at every
//! level and distance (reference image + silhouette overlap), instance culling against the
//! frustum, level selection by distance, and a second start that does no preprocessing.

mod common;

use common::{assert_matches_reference, fraction, gpu, trees_on_a_plain};
use landsketch::gis::Raster;
use landsketch::prep::cache::DiskCache;
use landsketch::prep::lod::{LodLevel, LodSettings};
use landsketch::render::{FrameRequest, Readback, RenderOptions, Renderer, Style};
use landsketch::scene::camera::Camera;
use landsketch::scene::terrain::Terrain;
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
    renderer
        .render(FrameRequest::new(camera, Style::default(), WIDTH, HEIGHT).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap()
        .iter()
        .map(|id| id >> 24 >= 2)
        .collect()
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
            let image =
                renderer.render(FrameRequest::new(&camera, Style::default(), WIDTH, HEIGHT)).map(|f| f.image).unwrap();
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
    let stats = renderer.draw_stats(&FrameRequest::new(&camera, Style::default(), 320, 240)).expect("stats");
    assert_eq!(stats.plants, 10);
    assert_eq!(stats.plants_drawn, 5, "{stats:?}");
    // Nothing visible was culled: every tree ahead shows up in the ID buffer.
    let ids = renderer
        .render(FrameRequest::new(&camera, Style::default(), 320, 240).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    for index in 0..ahead.len() as u32 {
        let id = (2 << 24) | (index + 1);
        assert!(ids.contains(&id), "tree {index} ahead is missing from the ID buffer");
    }
    // Turned around, the trees behind are the ones drawn.
    let back = Camera { yaw: 180.0, ..camera };
    assert_eq!(
        renderer.draw_stats(&FrameRequest::new(&back, Style::default(), 320, 240)).expect("stats").plants_drawn,
        3
    );
}

#[test]
fn levels_are_chosen_by_distance_and_cut_the_triangles() {
    let positions: Vec<[f32; 2]> = (0..40).map(|i| [(i % 5) as f32 * 8.0 - 16.0, -20.0 + i as f32 * 3.0]).collect();
    let scene = trees_on_a_plain(&positions);
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = scene.default_camera;
    let stats = renderer.draw_stats(&FrameRequest::new(&camera, Style::default(), 512, 384)).expect("stats");
    assert!(stats.per_level.iter().all(|&n| n > 0), "near, middle and far trees: {stats:?}");
    assert!(stats.triangles < stats.source_triangles / 2, "{stats:?}");
    let full = Renderer::with_options(gpu(), &scene, &forced(LodLevel::Full)).unwrap();
    let all = full.draw_stats(&FrameRequest::new(&camera, Style::default(), 512, 384)).expect("stats");
    assert_eq!(all.triangles, all.source_triangles, "forced full detail draws the source geometry");
}

#[test]
fn reference_points_thin_out_with_distance() {
    // Thesis 7.3, Fig. 7.6: HLP centres near the camera, plant centres at middle distance and
    // terrain-grid points far away. 60 trees on a 9 m lattice cover 3 × 2 cells of the 40 m grid.
    let positions: Vec<[f32; 2]> = (0..60).map(|i| [(i % 10) as f32 * 9.0 - 45.0, (i / 10) as f32 * 9.0]).collect();
    let scene = trees_on_a_plain(&positions);
    let height = scene.species[0].model.height();
    // Without vegetation masses, which draw the far trees of this small wood instead.
    let no_masses = RenderOptions { lod: LodSettings { mass_px: 0.0, ..LodSettings::default() }, ..Default::default() };
    let renderer = Renderer::with_options(gpu(), &scene, &no_masses).unwrap();
    let (width, h) = (512, 384);
    let px_per_metre = h as f32 / (2.0 * 30f32.to_radians().tan());
    let looking_north_from = |y: f32| Camera::perspective([0.0, y, 100.0 + height * 0.5], 0.0, 0.0, 60.0);

    let near =
        renderer.draw_stats(&FrameRequest::new(&looking_north_from(-30.0), Style::default(), width, h)).expect("stats");
    assert!(near.per_level[0] + near.per_level[1] > 0, "{near:?}");
    assert!(near.reference_points > near.plants_drawn, "near trees bring their HLPs: {near:?}");

    // Every tree between 32 px (below the HLP level's blend band) and 12 px: one point each.
    let distance = height * px_per_metre / 30.0;
    let middle = renderer
        .draw_stats(&FrameRequest::new(&looking_north_from(-distance), Style::default(), width, h))
        .expect("stats");
    assert_eq!(middle.per_level, [0, 0, 60], "{middle:?}");
    assert_eq!(middle.reference_points, 60, "{middle:?}");

    // Far away the trees share the points of their grid cells.
    let far = renderer
        .draw_stats(&FrameRequest::new(&looking_north_from(-height * px_per_metre / 4.0), Style::default(), width, h))
        .expect("stats");
    assert_eq!(far.plants_drawn, 60, "{far:?}");
    assert_eq!(far.reference_points, 6, "{far:?}");
    // With masses the domes of the wood's cells stand for the far trees, on the same points.
    let massed = Renderer::new(gpu(), &scene)
        .unwrap()
        .draw_stats(&FrameRequest::new(&looking_north_from(-height * px_per_metre / 4.0), Style::default(), width, h))
        .expect("stats");
    assert!(massed.mass_domes > 0 && massed.plants_drawn < 60, "{massed:?}");
}

#[test]
fn terrain_chunks_coarsen_with_distance_without_cracks() {
    // A 257 × 257 DEM of 10 m cells with rolling hills, seen from walking height at its south end.
    let n = 257;
    let data = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64, (i / n) as f64);
            100.0 + 8.0 * (x * 0.07).sin() * (y * 0.05).cos() + 3.0 * (x * 0.31 + y * 0.17).sin()
        })
        .collect();
    let mut scene = trees_on_a_plain(&[]);
    let dem = Raster { width: n, height: n, data, ..scene.terrain.dem.clone() };
    scene.terrain = Terrain::new(dem, [1.0; 3]).unwrap();
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = Camera::perspective([0.0, -1100.0, 125.0], 0.0, -5.0, 60.0);
    let (width, height) = (320, 240);
    let stats = renderer.draw_stats(&FrameRequest::new(&camera, Style::default(), width, height)).expect("stats");
    let full = 2 * (n as u64 - 1) * (n as u64 - 1);
    assert_eq!(stats.source_triangles, full);
    assert!(stats.triangles < full / 4, "distant chunks are coarser or culled: {stats:?}");
    // No cracks between chunks at different levels: below the horizon every pixel is terrain.
    let ids = renderer
        .render(FrameRequest::new(&camera, Style::default(), width, height).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    let holes = ids[(width * height / 2) as usize..].iter().filter(|&&id| id == 0).count();
    assert_eq!(holes, 0, "background shows through the terrain in {holes} pixels");
    let image = renderer.render(FrameRequest::new(&camera, Style::default(), width, height)).map(|f| f.image).unwrap();
    assert!(fraction(&image, |l| l < 0.5) > 0.01, "the hills are drawn");
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
        renderer.render(FrameRequest::new(&camera_at(45.0), Style::default(), WIDTH, HEIGHT)).map(|f| f.image).unwrap()
    };
    let first_cache = Arc::new(DiskCache::open(dir.path()).unwrap());
    let first = render(&first_cache);
    let stats = first_cache.stats();
    // HLPs and billboards (keyed by this test's radius) are computed; the leaf shape maps and
    // the implicit-surface illumination reach the disk only when no other test of this process
    // has them in memory yet.
    assert!(stats.hits == 0 && stats.misses >= 2, "HLPs and billboards computed once: {stats:?}");
    // A restart: a new cache object on the same directory answers everything from disk. (The
    // HLPs are still in this process's memory cache, so only the billboards reach the disk.)
    let second_cache = Arc::new(DiskCache::open(dir.path()).unwrap());
    let second = render(&second_cache);
    let stats = second_cache.stats();
    assert_eq!(stats.misses, 0, "nothing recomputed: {stats:?}");
    assert!(stats.hits >= 1, "{stats:?}");
    assert_eq!(first, second, "cached preprocessing renders the same image");
}
