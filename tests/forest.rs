//! Vegetation at landscape scale (`prep::masses`, thesis 7.3): a forest block on a plain reads as
//! a forest from above at 500 m, 2 km and 5 km (more ink than the open ground in a sketch, its
//! own colour in photorealism), a lone tree far away is still drawn, a dolly from 3 km to
//! 200 m towards the forest edge has no flicker spike where billboards hand over to the mass,
//! and the edge at 200 m, 1 km and 3 km matches its reference in three presets.

mod common;

use common::{assert_matches_reference, gpu, luminance};
use glam::Vec3;
use image::RgbaImage;
use landsketch::gis::{Crs, GeoTransform, Raster};
use landsketch::render::coherence::frame_differences;
use landsketch::render::{FrameRequest, Readback, Renderer, Style};
use landsketch::scene::camera::Camera;
use landsketch::scene::procedural::{ProceduralKind, procedural_plant};
use landsketch::scene::terrain::Terrain;
use landsketch::scene::vegetation::PlantInstance;
use landsketch::scene::{Scene, Species, Sun, VegetationLayer};
use std::path::Path;
use std::sync::OnceLock;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
/// Ground height of the plain.
const GROUND: f32 = 100.0;
/// The forest block: x from −WIDE to +WIDE, y from 0 to DEEP metres.
const WIDE: f32 = 1000.0;
const DEEP: f32 = 400.0;
/// Trees per hectare in the block (a real forest has 200–1,000).
const DENSITY: f32 = 300.0;
/// A lone tree on open ground, 600 m east of the block.
const LONE: [f32; 2] = [1600.0, 200.0];

fn preset(name: &str) -> Style {
    landsketch::render::presets::preset(name).expect("preset")
}

/// Height of the forest's trees (metres, give or take 30 %).
const TREE_HEIGHT: f32 = 15.0;

/// A 12 km × 12 km plain with a 2 km × 400 m block of broadleaf trees at forest density on a
/// jittered grid, and one lone tree.
fn forest_scene() -> Scene {
    let oak = procedural_plant(ProceduralKind::Broadleaf, 1);
    let scale = TREE_HEIGHT / oak.bounds().1[2];
    let n = 121;
    let dem = Raster {
        width: n,
        height: n,
        data: vec![f64::from(GROUND); n * n],
        nodata: None,
        transform: GeoTransform { origin_x: 494_000.0, origin_y: 4_406_000.0, cell_width: 100.0, cell_height: 100.0 },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    };
    let spacing = (10_000.0 / DENSITY).sqrt();
    let mut plants = Vec::new();
    for i in 0..(2.0 * WIDE / spacing) as usize {
        for j in 0..(DEEP / spacing) as usize {
            let h = (i * 7919 + j * 104_729) as f32;
            let jitter = |k: f32| (h * k).sin() * 0.3 * spacing;
            plants.push(PlantInstance {
                species: 0,
                position: [
                    (i as f32 + 0.5) * spacing + jitter(1.7) - WIDE,
                    (j as f32 + 0.5) * spacing + jitter(2.3),
                    GROUND,
                ],
                rotation: h.sin() * 3.0,
                scale: scale * (1.0 + 0.3 * (h * 0.37).sin()),
            });
        }
    }
    plants.push(PlantInstance { species: 0, position: [LONE[0], LONE[1], GROUND], rotation: 0.0, scale });
    let terrain = Terrain::new(dem, [0.78, 0.74, 0.66]).expect("terrain");
    Scene {
        name: "forest".into(),
        terrain,
        species: vec![Species::new("oak", oak)],
        layers: vec![VegetationLayer { name: "existing".into(), plants }],
        sun: Sun { azimuth: 165.0, elevation: 35.0 },
        default_camera: Camera::perspective([200.0, -300.0, 120.0], 0.0, -5.0, 60.0),
        about: Default::default(),
    }
}

fn scene() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(forest_scene)
}

fn renderer() -> &'static Renderer {
    static RENDERER: OnceLock<Renderer> = OnceLock::new();
    RENDERER.get_or_init(|| Renderer::new(gpu(), scene()).expect("renderer"))
}

/// Looking at `target` from `distance` metres, `pitch` degrees down, from the south.
fn looking_at(target: Vec3, distance: f32, pitch: f32) -> Camera {
    let camera = Camera::perspective([0.0, 0.0, 0.0], 0.0, -pitch, 60.0);
    let eye = target - camera.forward() * distance;
    Camera { position: eye.to_array(), ..camera }
}

/// Where the ray through the centre of pixel (x, y) meets the ground plane.
fn ground_hit(camera: &Camera, x: u32, y: u32) -> Option<[f32; 2]> {
    let tan = (camera.fov.to_radians() * 0.5).tan();
    let ndc = [(x as f32 + 0.5) / WIDTH as f32 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / HEIGHT as f32 * 2.0];
    let aspect = WIDTH as f32 / HEIGHT as f32;
    let dir_view = glam::Vec4::new(ndc[0] * tan * aspect, ndc[1] * tan, -1.0, 0.0);
    let dir = (camera.view().inverse() * dir_view).truncate();
    let eye = Vec3::from(camera.position);
    let t = (GROUND - eye.z) / dir.z;
    (t > 0.0).then(|| {
        let p = eye + dir * t;
        [p.x, p.y]
    })
}

/// Mean ink (1 − luminance) and mean colour of the pixels whose ground point lies in the
/// forest block (shrunk by `margin`), and of those on open ground (beyond `margin` outside it).
struct Regions {
    forest: (f64, [f64; 3], usize),
    open: (f64, [f64; 3], usize),
}

fn regions(camera: &Camera, image: &RgbaImage, margin: f32) -> Regions {
    let mut sums = [(0.0, [0.0; 3], 0usize); 2];
    for (x, y, p) in image.enumerate_pixels() {
        let Some([gx, gy]) = ground_hit(camera, x, y) else { continue };
        let inside = (margin - WIDE..WIDE - margin).contains(&gx) && (margin..DEEP - margin).contains(&gy);
        let outside = gx < -WIDE - margin || gx > WIDE + margin || gy < -margin || gy > DEEP + margin;
        let near_lone = (gx - LONE[0]).hypot(gy - LONE[1]) < 2.0 * margin;
        let region = match (inside, outside && !near_lone) {
            (true, _) => 0,
            (_, true) => 1,
            _ => continue,
        };
        let s = &mut sums[region];
        s.0 += f64::from(1.0 - luminance(p));
        for c in 0..3 {
            s.1[c] += f64::from(p[c]) / 255.0;
        }
        s.2 += 1;
    }
    let mean = |(ink, rgb, n): (f64, [f64; 3], usize)| {
        let n_f = n.max(1) as f64;
        (ink / n_f, rgb.map(|c| c / n_f), n)
    };
    Regions { forest: mean(sums[0]), open: mean(sums[1]) }
}

#[test]
fn a_forest_reads_as_a_forest_from_above_at_every_distance() {
    let renderer = renderer();
    let center = Vec3::new(0.0, DEEP * 0.5, GROUND);
    let mut sheet = RgbaImage::new(WIDTH * 3, HEIGHT * 2);
    for (col, distance) in [500.0, 2000.0, 5000.0].into_iter().enumerate() {
        let camera = looking_at(center, distance, 35.0);
        // The canopy stands above the ground it covers, and a pixel spans some ground: a margin
        // of the canopy's parallax and two pixels keeps the edge out of both regions.
        let pixel = 2.0 * distance * (30.0f32.to_radians().tan()) / HEIGHT as f32 / 35.0f32.to_radians().sin();
        let margin = 1.5 * TREE_HEIGHT / 35.0f32.to_radians().tan() + 2.0 * pixel;
        let sketch =
            renderer.render(FrameRequest::new(&camera, preset("full_npr"), WIDTH, HEIGHT)).map(|f| f.image).unwrap();
        let r = regions(&camera, &sketch, margin);
        image::imageops::replace(&mut sheet, &sketch, i64::from(WIDTH) * col as i64, 0);
        assert!(r.forest.2 > 30 && r.open.2 > 1000, "{distance} m: {} forest, {} open pixels", r.forest.2, r.open.2);
        assert!(
            r.forest.0 >= 2.0 * r.open.0 && r.forest.0 > 0.05,
            "{distance} m: the forest carries {:.3} ink, the open ground {:.3}",
            r.forest.0,
            r.open.0
        );
        let photo = renderer
            .render(FrameRequest::new(&camera, preset("photorealism"), WIDTH, HEIGHT))
            .map(|f| f.image)
            .unwrap();
        let r = regions(&camera, &photo, margin);
        image::imageops::replace(&mut sheet, &photo, i64::from(WIDTH) * col as i64, i64::from(HEIGHT));
        let [fr, fg, fb] = r.forest.1;
        let [or, og, ob] = r.open.1;
        let distance_rgb = ((fr - or).powi(2) + (fg - og).powi(2) + (fb - ob).powi(2)).sqrt();
        assert!(distance_rgb > 0.15, "{distance} m: forest {:?} and open ground {:?} look alike", r.forest.1, r.open.1);
        assert!(fg > fr && fg > fb, "{distance} m: the forest is not green: {:?}", r.forest.1);
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/forest_above.png"), 0.03);
}

#[test]
fn a_lone_tree_far_away_is_still_drawn() {
    let renderer = renderer();
    let tree = Vec3::new(LONE[0], LONE[1], GROUND + 4.0);
    for distance in [1000.0, 3000.0] {
        let camera = looking_at(tree, distance, 35.0);
        let ids = renderer
            .render(FrameRequest::new(&camera, Style::default(), WIDTH, HEIGHT).read(Readback::IDS))
            .map(|f| f.ids.unwrap_or_default())
            .unwrap();
        // The lone tree is the layer's last plant: its object index is its index + 1.
        let index = scene().layers[0].plants.len() as u32;
        let lone = ids.iter().filter(|&&id| id >> 24 >= 2 && id & 0x00FF_FFFF == index).count();
        assert!(lone >= 1, "the lone tree at {distance} m covers no pixel");
    }
}

/// The dolly of the edge tests: from `start` to `end` metres in `frames` steps of equal ratio
/// towards the middle of the block's southern edge, looking 3° down at the foot of the edge
/// (from a house or a low hill).
fn dolly(start: f32, end: f32, frames: usize) -> Vec<Camera> {
    let target = Vec3::new(0.0, 0.0, GROUND);
    (0..frames)
        .map(|k| {
            let distance = start * (end / start).powf(k as f32 / (frames - 1).max(1) as f32);
            looking_at(target, distance, 3.0)
        })
        .collect()
}

#[test]
fn a_dolly_towards_the_forest_edge_has_no_flicker_spike() {
    let renderer = renderer();
    let path = dolly(3000.0, 200.0, 28);
    let differences = frame_differences(renderer, &preset("full_npr"), &path, WIDTH, HEIGHT).unwrap();
    assert_eq!(differences.len(), path.len() - 1);
    // A pop is a frame pair that differs much more than the pairs around it; the difference
    // itself grows steadily as the forest fills more of the view, which is no pop.
    for (i, &difference) in differences.iter().enumerate() {
        let mut around: Vec<f64> =
            (i.saturating_sub(3)..(i + 4).min(differences.len())).filter(|&j| j != i).map(|j| differences[j]).collect();
        around.sort_by(f64::total_cmp);
        let median = around[around.len() / 2];
        assert!(median > 0.0, "the frames differ not at all: {differences:?}");
        assert!(
            difference <= 1.5 * median,
            "a flicker spike of {difference:.4} at pair {i} against the median {median:.4} of its neighbours: {differences:?}"
        );
    }
}

#[test]
fn the_forest_edge_matches_its_reference_at_200_m_1_km_and_3_km() {
    let renderer = renderer();
    let presets = ["full_npr", "half_npr", "photorealism"];
    let distances = [200.0, 1000.0, 3000.0];
    let mut sheet = RgbaImage::new(WIDTH * 3, HEIGHT * 3);
    let mut bands = Vec::new();
    for (row, name) in presets.iter().enumerate() {
        for (col, &distance) in distances.iter().enumerate() {
            let camera = dolly(distance, distance, 1)[0];
            let frame =
                renderer.render(FrameRequest::new(&camera, preset(name), WIDTH, HEIGHT).read(Readback::IDS)).unwrap();
            // The edge is a continuous band of vegetation across the middle of the picture.
            let ids = frame.ids.unwrap_or_default();
            let columns = (WIDTH / 3..2 * WIDTH / 3)
                .filter(|&x| (0..HEIGHT).any(|y| ids[(y * WIDTH + x) as usize] >> 24 >= 2))
                .count();
            bands.push((name, distance, columns));
            let image = frame.image;
            image::imageops::replace(&mut sheet, &image, i64::from(WIDTH) * col as i64, i64::from(HEIGHT) * row as i64);
        }
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/forest_edge.png"), 0.03);
    for (name, distance, columns) in bands {
        assert_eq!(columns as u32, WIDTH / 3 + 1, "{name} at {distance} m: the edge shows in {columns} columns");
    }
}

#[test]
fn the_sample_scene_from_above_shows_its_plants_in_three_presets() {
    let scene = Scene::load(Path::new("data/boulder/scene.toml")).expect("sample scene");
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    // `landsketch render --pos 0,-1500,3000 --yaw 0 --pitch -35`: north over the terrain.
    let camera = Camera { position: [0.0, -1500.0, 3000.0], yaw: 0.0, pitch: -35.0, ..scene.default_camera };
    let ids = renderer
        .render(FrameRequest::new(&camera, Style::default(), WIDTH, HEIGHT).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    // The existing layer's plants as dots (9 pines/ha).
    let pixels = ids.iter().filter(|&&id| id >> 24 == 2).count();
    assert!(pixels > 150, "the existing plants cover {pixels} pixels from above");
    let mut sheet = RgbaImage::new(WIDTH * 3, HEIGHT);
    for (col, name) in ["full_npr", "half_npr", "photorealism"].iter().enumerate() {
        let image = renderer.render(FrameRequest::new(&camera, preset(name), WIDTH, HEIGHT)).map(|f| f.image).unwrap();
        image::imageops::replace(&mut sheet, &image, i64::from(WIDTH) * col as i64, 0);
    }
    assert_matches_reference(&sheet, Path::new("tests/reference/sample_above.png"), 0.03);
}
