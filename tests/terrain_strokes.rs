//! Object-space terrain strokes (issue 18): on synthetic DEMs the strokes follow the fall line
//! or the contour direction, a flat lit plane stays paper, a dolly towards a slope keeps the
//! strokes' width on screen, and the strokes stay on the ground when the camera moves.

mod common;

use common::{gpu, luminance};
use landsketch::gis::{Crs, GeoTransform, Raster};
use landsketch::render::coherence::{camera_path, flicker};
use landsketch::render::style::{HatchSpace, TerrainStrokes};
use landsketch::render::{FrameRequest, Readback, Renderer, Style};
use landsketch::scene::camera::Camera;
use landsketch::scene::cover::{CoverClassConfig, CoverStrokes, Drape, DrapeSources, resolve_classes};
use landsketch::scene::terrain::Terrain;
use landsketch::scene::{Scene, Sun};
use std::path::Path;

/// A bare terrain of `n` × `n` cells of `cell` metres with heights `height(x, y)` (x east, y
/// north, metres from the centre), lit by `sun`.
fn terrain_scene(n: usize, cell: f64, sun: Sun, height: impl Fn(f64, f64) -> f64) -> Scene {
    let half = (n as f64 - 1.0) * cell / 2.0;
    let data = (0..n * n)
        .map(|i| {
            let (col, row) = (i % n, i / n);
            height(col as f64 * cell - half, half - row as f64 * cell)
        })
        .collect();
    let dem = Raster {
        width: n,
        height: n,
        data,
        nodata: None,
        transform: GeoTransform { origin_x: 500_000.0, origin_y: 4_400_000.0, cell_width: cell, cell_height: cell },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    };
    Scene {
        name: "terrain".into(),
        terrain: Terrain::new(dem, [1.0; 3]).expect("terrain"),
        species: Vec::new(),
        layers: Vec::new(),
        sun,
        default_camera: Camera::perspective([0.0, -80.0, 20.0], 0.0, -10.0, 60.0),
        about: Default::default(),
    }
}

/// A cone of slope 1:2 (26.6°) with its apex 100 m up at the origin.
fn cone() -> Scene {
    terrain_scene(121, 2.0, Sun { azimuth: 135.0, elevation: 45.0 }, |x, y| 100.0 - 0.5 * x.hypot(y))
}

/// Hatching of one uniform mid tone (eq. 6.7 with contrast 0), no lines: only strokes.
fn strokes_only(direction: TerrainStrokes, tone: f32) -> Style {
    Style {
        terrain_stroke_direction: direction,
        tone_contrast: 0.0,
        tone_reference: tone,
        tone_blur: 0,
        contour_strength: 0.0,
        silhouette_strength: 0.0,
        ..Style::default()
    }
}

fn lum(image: &image::RgbaImage) -> Vec<f32> {
    image.pixels().map(luminance).collect()
}

/// The dominant stroke orientation (radians, mod π, in image coordinates x right, y down) of
/// the `size` × `size` window at (`x0`, `y0`) of a luminance image `width` wide: the structure
/// tensor of the luminance gradients (central differences) gives the gradient's orientation;
/// strokes run across it. Also the tensor's coherence (0 isotropic, 1 one orientation).
fn stroke_orientation(l: &[f32], width: usize, x0: usize, y0: usize, size: usize) -> (f32, f32) {
    let (mut jxx, mut jxy, mut jyy) = (0.0f64, 0.0f64, 0.0f64);
    for y in y0.max(1)..(y0 + size).min(l.len() / width - 1) {
        for x in x0.max(1)..(x0 + size).min(width - 1) {
            let gx = f64::from(l[y * width + x + 1] - l[y * width + x - 1]);
            let gy = f64::from(l[(y + 1) * width + x] - l[(y - 1) * width + x]);
            jxx += gx * gx;
            jxy += gx * gy;
            jyy += gy * gy;
        }
    }
    let gradient = 0.5 * (2.0 * jxy).atan2(jxx - jyy);
    let coherence = ((jxx - jyy).powi(2) + 4.0 * jxy * jxy).sqrt() / (jxx + jyy).max(1e-12);
    ((gradient + std::f64::consts::FRAC_PI_2) as f32, coherence as f32)
}

/// The angle between two orientations (mod π), 0..π/2.
fn orientation_error(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(std::f32::consts::PI);
    d.min(std::f32::consts::PI - d)
}

#[test]
fn strokes_follow_the_fall_line_or_the_contours_of_a_cone() {
    let scene = cone();
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let size = 256u32;
    // Seen from above the apex, 200 m across: the fall line runs radially on screen.
    let camera = Camera::plan(0.0, 0.0, 400.0, 200.0);
    for (direction, across) in [(TerrainStrokes::FallLine, 0.0f32), (TerrainStrokes::Contour, 90.0)] {
        let frame =
            renderer.render(FrameRequest::new(&camera, strokes_only(direction, 0.55), size, size)).expect("render");
        let l = lum(&frame.image);
        let (window, mut checked, mut worst) = (32usize, 0, 0.0f32);
        for wy in 0..(size as usize / window) {
            for wx in 0..(size as usize / window) {
                let (cx, cy) = ((wx * window + window / 2) as f32, (wy * window + window / 2) as f32);
                let (dx, dy) = (cx - size as f32 / 2.0, cy - size as f32 / 2.0);
                // Away from the apex (where the fall line turns within the window); the slope is
                // 26.6° everywhere else.
                if dx.hypot(dy) < 40.0 {
                    continue;
                }
                let (orientation, coherence) = stroke_orientation(&l, size as usize, wx * window, wy * window, window);
                let expected = dy.atan2(dx) + across.to_radians();
                let error = orientation_error(orientation, expected).to_degrees();
                assert!(coherence > 0.2, "{direction:?}: window ({wx}, {wy}) has no dominant orientation");
                worst = worst.max(error);
                checked += 1;
            }
        }
        assert!(checked >= 40, "{checked} windows");
        assert!(worst < 20.0, "{direction:?}: strokes up to {worst:.1}° off the expected direction");
    }
}

#[test]
fn furrows_of_a_field_class_run_at_its_angle_whatever_the_slope() {
    // A ramp rising to the east (fall line west-east) covered by one field class whose furrows
    // run 30° east of north (`[terrain.cover.7] strokes = "furrows"`, angle 30).
    let mut scene = terrain_scene(61, 4.0, Sun { azimuth: 135.0, elevation: 45.0 }, |x, _| 50.0 + 0.3 * x);
    let dem = &scene.terrain.dem;
    let landcover = Raster { data: vec![7.0; dem.width * dem.height], nodata: Some(0.0), ..dem.clone() };
    let entries = std::collections::BTreeMap::from([(
        "7".to_owned(),
        CoverClassConfig { strokes: Some(CoverStrokes::Furrows), angle: Some(30.0), ..Default::default() },
    )]);
    let classes = resolve_classes(None, &entries).expect("classes");
    let sources =
        DrapeSources { landcover: Some((&landcover, std::path::Path::new("field.tif"))), orthophoto: None, classes };
    let drape = Drape::build(sources, &scene.terrain.frame, scene.terrain.bounds(), [1.0; 3]).expect("drape");
    scene.terrain.set_drape(drape);
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let size = 192u32;
    let camera = Camera::plan(0.0, 0.0, 400.0, 160.0);
    let frame = renderer.render(FrameRequest::new(&camera, strokes_only(TerrainStrokes::FallLine, 0.55), size, size));
    let l = lum(&frame.expect("render").image);
    // 30° clockwise from north, in image coordinates (x right, y down).
    let expected = (-30f32.to_radians().cos()).atan2(30f32.to_radians().sin());
    let window = 48usize;
    for wy in 0..size as usize / window {
        for wx in 0..size as usize / window {
            let (orientation, coherence) = stroke_orientation(&l, size as usize, wx * window, wy * window, window);
            let error = orientation_error(orientation, expected).to_degrees();
            assert!(coherence > 0.2 && error < 20.0, "window ({wx}, {wy}): {error:.1}° off, coherence {coherence:.2}");
        }
    }
}

#[test]
fn a_flat_plane_in_full_light_stays_paper() {
    let scene = terrain_scene(41, 10.0, Sun { azimuth: 200.0, elevation: 90.0 }, |_, _| 50.0);
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    // Looking down at the plane from 10 m, its edges out of sight.
    let camera = Camera::perspective([0.0, -60.0, 60.0], 0.0, -40.0, 60.0);
    for direction in [TerrainStrokes::FallLine, TerrainStrokes::Contour] {
        let style = Style { terrain_stroke_direction: direction, ..Style::default() };
        let frame = renderer.render(FrameRequest::new(&camera, &style, 192, 144).read(Readback::IDS)).expect("render");
        let ids = frame.ids.expect("ids");
        let terrain: Vec<f32> =
            frame.image.pixels().zip(&ids).filter(|(_, id)| **id != 0).map(|(p, _)| luminance(p)).collect();
        assert_eq!(terrain.len(), 192 * 144, "the plane fills the frame");
        let ink = terrain.iter().filter(|l| **l < 0.9).count() as f64 / terrain.len() as f64;
        assert!(ink < 0.05, "{direction:?}: {:.1} % of the lit plane is inked", ink * 100.0);
    }
}

/// Height of the ramp `y` metres north of its centre: rising northwards at 20°.
fn ramp_height(y: f32) -> f32 {
    100.0 + 20f32.to_radians().tan() * y
}

/// A plane rising northwards at 20°, lit from the north-east so it is in half shade.
fn ramp() -> Scene {
    terrain_scene(121, 2.0, Sun { azimuth: 30.0, elevation: 35.0 }, |_, y| f64::from(ramp_height(y as f32)))
}

/// Mean stroke width in pixels of the inked pixels of a luminance window: twice the ink area
/// over the length of its boundary (ink pixels with a paper 4-neighbour), the width of long
/// thin strokes.
fn stroke_width(l: &[f32], width: usize, x0: usize, y0: usize, size: usize) -> Option<f32> {
    let ink = |x: usize, y: usize| l[y * width + x] < 0.6;
    let (mut area, mut boundary) = (0usize, 0usize);
    for y in y0 + 1..y0 + size - 1 {
        for x in x0 + 1..x0 + size - 1 {
            if ink(x, y) {
                area += 1;
                let edges =
                    [(x - 1, y), (x + 1, y), (x, y - 1), (x, y + 1)].iter().filter(|(a, b)| !ink(*a, *b)).count();
                boundary += edges;
            }
        }
    }
    (boundary > 20).then(|| 2.0 * area as f32 / (boundary as f32 / 2.0))
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

#[test]
fn a_dolly_towards_a_slope_keeps_the_stroke_width() {
    let scene = ramp();
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let (w, h) = (256u32, 192u32);
    let style = strokes_only(TerrainStrokes::FallLine, 0.6);
    let widths: Vec<f32> = [0.0f32, 20.0]
        .iter()
        .map(|forward| {
            // Looking north up the ramp from 8 m above it, then 20 m closer.
            let y = -60.0 + forward;
            let camera = Camera::perspective([0.0, y, ramp_height(y) + 8.0], 0.0, 5.0, 60.0);
            let frame = renderer.render(FrameRequest::new(&camera, &style, w, h)).expect("render");
            let l = lum(&frame.image);
            let window = 32usize;
            let per_window: Vec<f32> = (0..(h as usize / window))
                .flat_map(|wy| (0..(w as usize / window)).map(move |wx| (wx, wy)))
                .filter_map(|(wx, wy)| stroke_width(&l, w as usize, wx * window, wy * window, window))
                .collect();
            assert!(per_window.len() >= 12, "strokes in {} windows", per_window.len());
            median(per_window)
        })
        .collect();
    let ratio = widths[1] / widths[0];
    assert!(
        (1.0 / 1.5..=1.5).contains(&ratio),
        "median stroke width {:.2} px before and {:.2} px after a 20 m dolly",
        widths[0],
        widths[1]
    );
}

#[test]
fn terrain_strokes_stay_on_the_ground_when_the_camera_moves() {
    let scene = ramp();
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let start = Camera::perspective([0.0, -60.0, ramp_height(-60.0) + 8.0], 0.0, 5.0, 60.0);
    let path = camera_path(&start, 2);
    let object = Style { silhouette_strength: 0.0, ..strokes_only(TerrainStrokes::FallLine, 0.6) };
    let image =
        Style { hatch_space: HatchSpace::Image, terrain_stroke_direction: TerrainStrokes::Image, ..object.clone() };
    let a = flicker(&renderer, &object, &path, 160, 120).expect("object space");
    let b = flicker(&renderer, &image, &path, 160, 120).expect("image space");
    assert!(b.terrain > 0.0 && a.terrain > 0.0);
    assert!(
        a.terrain < 0.5 * b.terrain,
        "object-space terrain flicker {} against image-space {}",
        a.terrain,
        b.terrain
    );
    // Not by drawing fewer strokes: the ink stays comparable.
    assert!((a.terrain_ink / b.terrain_ink - 1.0).abs() < 0.25, "ink {} against {}", a.terrain_ink, b.terrain_ink);
}

#[test]
fn the_lidar_villages_relief_reads_from_above_once_exaggerated() {
    // The real 1 m lidar DTM of Kingston St Mary (tests only, ../shared/data/SOURCES.md),
    // stored in whole metres: dequantized on load, its valleys and banks drawn from 400 m up.
    let dtm = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kingston_st_mary/dtm_1m.tif");
    if !dtm.exists() {
        eprintln!("../shared/data/kingston_st_mary not present; skipped");
        return;
    }
    let dem = landsketch::gis::load_raster(&dtm).expect("lidar DTM");
    let stored = dem.clone();
    let terrain = Terrain::new(dem, [1.0; 3]).expect("terrain");
    // Every height within half a metre of the file's, and the terraces gone: no height is a
    // whole number any more in most cells.
    let moved = terrain.dem.data.iter().zip(&stored.data).filter(|(z, v)| (*z - *v).abs() > 1e-6).count();
    assert!(terrain.dem.data.iter().zip(&stored.data).all(|(z, v)| (z - v).abs() <= 0.5 + 1e-9));
    assert!(moved > stored.data.len() / 2, "only {moved} cells smoothed");
    let scene = Scene {
        name: "Kingston St Mary".into(),
        terrain,
        species: Vec::new(),
        layers: Vec::new(),
        sun: Sun { azimuth: 165.0, elevation: 35.0 },
        default_camera: Camera::perspective([0.0, -700.0, 400.0], 0.0, -35.0, 60.0),
        about: Default::default(),
    };
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let camera = Camera::perspective([0.0, -700.0, 400.0], 0.0, -35.0, 60.0);
    let ink = |exaggeration: f32| {
        // The strokes alone (the crease lines are tested on their own).
        let full_npr = landsketch::render::presets::preset("full_npr").expect("preset");
        let style = Style { terrain_exaggeration: exaggeration, terrain_creases: 0.0, ..full_npr };
        let image = renderer.render(FrameRequest::new(&camera, style, 256, 192)).expect("render").image;
        common::fraction(&image, |l| l < 0.5)
    };
    let (plain, exaggerated) = (ink(1.0), ink(4.0));
    assert!(
        exaggerated > 0.03 && exaggerated > 3.0 * plain,
        "ink {plain:.3} as it is, {exaggerated:.3} exaggerated 4×"
    );
}

/// Of `points` (scene metres) seen by `camera` in a `w` × `h` frame of `style`, how many are
/// in view and how many are inked (the darkest pixel within one pixel below 0.6).
fn inked_points(
    renderer: &Renderer,
    camera: &Camera,
    style: Style,
    points: &[glam::Vec3],
    w: u32,
    h: u32,
) -> (usize, usize) {
    let image = renderer.render(FrameRequest::new(camera, style, w, h)).expect("render").image;
    let (mut seen, mut inked) = (0, 0);
    for p in points {
        let (x, y) = camera.point_pixel(*p, w, h);
        if x < 2.0 || y < 2.0 || x > w as f32 - 3.0 || y > h as f32 - 3.0 {
            continue;
        }
        seen += 1;
        let darkest = (-1..=1)
            .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| luminance(image.get_pixel((x as i32 + dx) as u32, (y as i32 + dy) as u32)))
            .fold(1.0f32, f32::min);
        inked += usize::from(darkest < 0.6);
    }
    (seen, inked)
}

/// Only the crease lines: no hatching, no silhouettes.
fn lines_only(creases: f32, crease_area: f32, break_angle: f32) -> Style {
    Style {
        hatch_strength: 0.0,
        silhouette_strength: 0.0,
        terrain_creases: creases,
        terrain_crease_area: crease_area,
        terrain_break_angle: break_angle,
        ..Style::default()
    }
}

#[test]
fn a_valley_bottom_gets_a_crease_line_that_stays_on_it_when_the_camera_moves() {
    // A V-shaped valley along x = 0, falling 0.5 m per 10 m cell to the south, sides 1:5.
    let scene =
        terrain_scene(61, 10.0, Sun { azimuth: 135.0, elevation: 45.0 }, |x, y| 100.0 + 0.2 * x.abs() + 0.05 * y);
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let (w, h) = (256u32, 192u32);
    let axis: Vec<glam::Vec3> = (-20..=10)
        .map(|k| {
            let y = k as f32 * 10.0;
            glam::Vec3::new(0.0, y, scene.terrain.height_at(0.0, f64::from(y)).expect("on the DEM") as f32)
        })
        .collect();
    // From the south, 60 m up, and after a dolly, a pan and a climb.
    for camera in [
        Camera::perspective([0.0, -320.0, 150.0], 0.0, -20.0, 60.0),
        Camera::perspective([30.0, -260.0, 170.0], -6.0, -24.0, 60.0),
    ] {
        let (seen, with) = inked_points(&renderer, &camera, lines_only(1.0, 1.0, 90.0), &axis, w, h);
        let (_, without) = inked_points(&renderer, &camera, lines_only(0.0, 1.0, 90.0), &axis, w, h);
        assert!(seen >= 15, "{seen} points of the axis in view");
        assert!(with * 10 >= seen * 9, "the line covers {with} of {seen} axis points");
        assert!(without * 2 <= seen, "without crease lines {without} of {seen} axis points are inked");
    }
}

#[test]
fn a_terraces_top_and_foot_get_break_of_slope_lines_at_the_styles_angle() {
    // Flat west of x = −100 m, a 30° slope down to x = +100 m, flat east of it.
    let drop = 30f64.to_radians().tan();
    let scene = terrain_scene(61, 10.0, Sun { azimuth: 135.0, elevation: 45.0 }, move |x, _| {
        100.0 - drop * (x.clamp(-100.0, 100.0) + 100.0)
    });
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let edge = |x: f32| -> Vec<glam::Vec3> {
        (-20..=20)
            .map(|k| {
                let y = k as f32 * 10.0;
                let z = scene.terrain.height_at(f64::from(x), f64::from(y)).expect("on the DEM") as f32;
                glam::Vec3::new(x, y, z)
            })
            .collect()
    };
    let (w, h) = (256u32, 192u32);
    // From the south-east above the slope; valleys and ridges left out (a huge area).
    let camera = Camera::perspective([150.0, -420.0, 260.0], -15.0, -32.0, 60.0);
    for x in [-100.0, 100.0] {
        let points = edge(x);
        let (seen, with) = inked_points(&renderer, &camera, lines_only(1.0, 100_000.0, 15.0), &points, w, h);
        let (_, steeper) = inked_points(&renderer, &camera, lines_only(1.0, 100_000.0, 40.0), &points, w, h);
        assert!(seen >= 20, "{seen} points of the edge at x = {x} in view");
        assert!(with * 10 >= seen * 8, "the line at x = {x} covers {with} of {seen} points");
        assert!(steeper * 4 <= seen, "a 40° threshold still inks {steeper} of {seen} points at x = {x}");
    }
}
