//! Marks over the sketch: comment pins drawn at their projected pixels, hidden behind hills
//! (a synthetic scene), near, far and in the plan view of the sample scene against reference
//! images; and the before/after split view (IDs of the compared layer absent left of the line,
//! present right of it; each half the same as the view without, respectively with, the layer).

mod common;

use common::{assert_matches_reference, gpu, luminance, outliers, trees_on_a_plain};
use glam::Vec3;
use image::RgbaImage;
use landsketch::render::compare::Compare;
use landsketch::render::layer_code::LayerCode;
use landsketch::render::marks::Pin;
use landsketch::render::{FrameRequest, Readback, RenderError, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use std::path::Path;
use std::sync::OnceLock;

fn sample() -> &'static (Scene, Renderer) {
    static SAMPLE: OnceLock<(Scene, Renderer)> = OnceLock::new();
    SAMPLE.get_or_init(|| {
        let scene = Scene::load(Path::new("data/boulder/scene.toml")).expect("sample scene");
        let renderer = Renderer::new(gpu(), &scene).expect("renderer");
        (scene, renderer)
    })
}

/// A point on the terrain of `scene` at (x, y).
fn ground(scene: &Scene, x: f32, y: f32) -> Vec3 {
    let z = scene.terrain.height_at(f64::from(x), f64::from(y)).expect("on the terrain");
    Vec3::new(x, y, z as f32)
}

/// Pixels in the box `(x0..x1, y0..y1)` that differ between `a` and `b` by more than a tenth
/// in luminance.
fn changed(a: &RgbaImage, b: &RgbaImage, (x0, x1): (f32, f32), (y0, y1): (f32, f32)) -> usize {
    let clamp = |v: f32, n: u32| v.clamp(0.0, n as f32) as u32;
    let (x0, x1, y0, y1) = (clamp(x0, a.width()), clamp(x1, a.width()), clamp(y0, a.height()), clamp(y1, a.height()));
    (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .filter(|&(x, y)| (luminance(a.get_pixel(x, y)) - luminance(b.get_pixel(x, y))).abs() > 0.1)
        .count()
}

/// Pixels darker than half grey in the box around `(x, y)` with half sizes `(hx, hy)`.
fn ink_near(image: &RgbaImage, (x, y): (f32, f32), (hx, hy): (f32, f32)) -> usize {
    let mut n = 0;
    for py in (y - hy).max(0.0) as u32..((y + hy) as u32).min(image.height()) {
        for px in (x - hx).max(0.0) as u32..((x + hx) as u32).min(image.width()) {
            n += usize::from(luminance(image.get_pixel(px, py)) < 0.5);
        }
    }
    n
}

/// A 200 m square plain at 100 m with a round hill 30 m high at its centre and no plants that
/// stand in the way; the camera looks north at it from 90 m south, 4 m above the plain.
fn hill() -> Scene {
    let mut scene = trees_on_a_plain(&[[-90.0, 90.0]]);
    let n = 81;
    let cell = 2.5;
    let mut dem = scene.terrain.dem.clone();
    dem.width = n;
    dem.height = n;
    dem.transform.cell_width = cell;
    dem.transform.cell_height = cell;
    dem.data = (0..n * n)
        .map(|i| {
            let (col, row) = ((i % n) as f64, (i / n) as f64);
            let c = (n as f64 - 1.0) / 2.0;
            let d2 = ((col - c).powi(2) + (row - c).powi(2)) * cell * cell;
            100.0 + 30.0 * (-d2 / (2.0 * 14.0f64.powi(2))).exp()
        })
        .collect();
    scene.terrain = landsketch::scene::terrain::Terrain::new(dem, [1.0; 3]).expect("terrain");
    scene.default_camera = Camera::perspective([0.0, -90.0, 104.0], 0.0, 0.0, 60.0);
    scene
}

#[test]
fn a_pin_is_drawn_at_its_projected_pixel_unless_a_hill_hides_it() {
    let scene = hill();
    let renderer = common::full_detail(&scene);
    let camera = scene.default_camera;
    let size = (480, 320);
    let behind = ground(&scene, 8.0, 45.0);
    let slope = ground(&scene, -8.0, -16.0);
    let plain = ground(&scene, -30.0, -40.0);
    // The hill is between the camera and the pin behind it: its ground point is hidden.
    let depth = renderer
        .render(FrameRequest::new(&camera, Style::default(), size.0, size.1).read(Readback::DEPTH))
        .expect("frame")
        .depth
        .expect("depth");
    // Seen: the depth at its pixel is about its distance (ground at a grazing angle spans
    // metres per pixel); hidden: something much nearer is in front.
    let seen = |p: Vec3| {
        let (x, y) = camera.point_pixel(p, size.0, size.1);
        let distance = -(camera.view() * p.extend(1.0)).z;
        depth[(y as u32 * size.0 + x as u32) as usize] > 0.85 * distance
    };
    let visible = [behind, slope, plain].map(seen);
    assert_eq!(visible, [false, true, true], "the synthetic scene hides the pin behind the hill only");
    let pins = [
        Pin { position: behind, number: 7, category: 0 },
        Pin { position: slope, number: 12, category: 1 },
        Pin { position: plain, number: 3, category: 2 },
    ];
    let render = |pins: &[Pin]| {
        renderer.render(FrameRequest::new(&camera, Style::default(), size.0, size.1).pins(pins)).expect("frame").image
    };
    let without = render(&[]);
    let with = render(&pins);
    assert_matches_reference(&with, Path::new("tests/reference/marks/pins_hill.png"), 0.01);
    for pin in &pins {
        let (x, y) = camera.point_pixel(pin.position, size.0, size.1);
        // The stem rises from the ground point; the head sits above it.
        let around = changed(&without, &with, (x - 12.0, x + 12.0), (y - 60.0, y + 3.0));
        let ground_ink = ink_near(&with, (x, y - 4.0), (2.0, 3.0));
        if pin.number == 7 {
            assert_eq!(around, 0, "the pin behind the hill is hidden");
        } else {
            assert!(around > 80, "pin {} is drawn at its pixel ({x:.0}, {y:.0}): {around} pixels", pin.number);
            assert!(ground_ink > 0, "pin {}'s stem stands on its ground point", pin.number);
        }
    }
    // Nothing else changes: the pins are all the pass draws.
    let (share, _) = outliers(&with, &without);
    assert!(share < 0.01, "{share}");
    // From above, the hill hides nothing: all three pins are drawn in the plan view.
    let plan = Camera::plan(0.0, 0.0, 400.0, 200.0);
    let from_above = |pins: &[Pin]| {
        renderer.render(FrameRequest::new(&plan, Style::default(), 320, 320).pins(pins)).expect("plan frame").image
    };
    let (bare, pinned) = (from_above(&[]), from_above(&pins));
    for pin in &pins {
        let (x, y) = plan.point_pixel(pin.position, 320, 320);
        assert!(
            changed(&bare, &pinned, (x - 12.0, x + 12.0), (y - 50.0, y + 3.0)) > 60,
            "plan view pin {}",
            pin.number
        );
    }
}

/// Ground points ahead of the sample scene's default camera, `distance` metres along its
/// heading and `right` metres to its right.
fn ahead(scene: &Scene, distance: f32, right: f32) -> Vec3 {
    let c = &scene.default_camera;
    let (sin, cos) = c.yaw.to_radians().sin_cos();
    let [x, y, _] = c.position;
    ground(scene, x + distance * sin + right * cos, y + distance * cos - right * sin)
}

#[test]
fn pins_read_as_numbered_pen_pins_near_far_and_from_above() {
    let (scene, renderer) = sample();
    let pins: Vec<Pin> = [(25.0, -6.0, 1), (60.0, 14.0, 2), (200.0, -40.0, 13), (1000.0, 120.0, 104)]
        .iter()
        .enumerate()
        .map(|(i, &(d, r, number))| Pin { position: ahead(scene, d, r), number, category: i as u8 })
        .collect();
    let camera = scene.default_camera;
    let near = renderer.render(FrameRequest::new(&camera, Style::default(), 512, 384).pins(&pins)).expect("near");
    assert_matches_reference(&near.image, Path::new("tests/reference/marks/pins_near.png"), 0.02);
    // A bird's-eye view from a kilometre back and 400 m up: every head at its minimum size.
    let (sin, cos) = camera.yaw.to_radians().sin_cos();
    let [x, y, z] = camera.position;
    let far = Camera::perspective([x - 1000.0 * sin, y - 1000.0 * cos, z + 400.0], camera.yaw, -18.0, 60.0);
    let far_image =
        renderer.render(FrameRequest::new(&far, Style::default(), 512, 384).pins(&pins)).expect("far").image;
    assert_matches_reference(&far_image, Path::new("tests/reference/marks/pins_far.png"), 0.02);
    let plan = Camera::plan(x + 300.0 * sin, y + 300.0 * cos, z + 2000.0, 1600.0);
    let plan_image =
        renderer.render(FrameRequest::new(&plan, Style::default(), 512, 384).pins(&pins)).expect("plan").image;
    assert_matches_reference(&plan_image, Path::new("tests/reference/marks/pins_plan.png"), 0.02);
    // Heads shrink with distance down to a legible minimum: the nearest is the largest.
    let bare =
        renderer.render(FrameRequest::new(&camera, Style::default(), 512, 384).read(Readback::DEPTH)).expect("bare");
    let drawn = |pin: &Pin| {
        let (x, y) = camera.point_pixel(pin.position, 512, 384);
        changed(&bare.image, &near.image, (x - 24.0, x + 24.0), (y - 60.0, y + 3.0))
    };
    let sizes: Vec<usize> = pins.iter().map(drawn).collect();
    assert!(sizes[0] > sizes[2] && sizes[2] > 150, "pixels of the pins near and far: {sizes:?}");
    // Pins whose ground point is in view are drawn, those that nearer terrain or plants
    // hide are not.
    let depth = bare.depth.expect("depth");
    for (pin, size) in pins.iter().zip(&sizes) {
        let (x, y) = camera.point_pixel(pin.position, 512, 384);
        let distance = -(camera.view() * pin.position.extend(1.0)).z;
        let inside = (0.0..512.0).contains(&x) && (0.0..384.0).contains(&y);
        let at = if inside { depth[(y as usize) * 512 + x as usize] / distance } else { 0.0 };
        let message = format!("pin {} at ({x:.0}, {y:.0}), {distance:.0} m, depth ×{at:.2}: {size} pixels", pin.number);
        if at > 0.97 {
            assert!(*size > 150, "{message}");
        } else if at < 0.8 {
            assert!(*size < 10, "{message}");
        }
    }
}

#[test]
fn a_split_view_hides_the_plan_left_of_the_line_only() {
    let (scene, renderer) = sample();
    let camera = scene.default_camera;
    let (w, h) = (512, 384);
    let planned = LayerCode::vegetation(scene.layers.iter().position(|l| l.name == "planned").expect("planned")).code();
    let frame = |compare: Option<&Compare>| {
        let request = FrameRequest::new(&camera, Style::default(), w, h).read(Readback::IDS);
        let request = match compare {
            Some(c) => request.compare(c),
            None => request,
        };
        renderer.render(request).expect("frame")
    };
    let split = Compare { layer: "planned".into(), split: Some(0.5) };
    let hidden = Compare { layer: "planned".into(), split: None };
    let (after, before, both) = (frame(None), frame(Some(&hidden)), frame(Some(&split)));
    let planned_in = |ids: &[u32], columns: std::ops::Range<u32>| {
        ids.iter()
            .enumerate()
            .filter(|(i, id)| columns.contains(&(*i as u32 % w)) && **id >> LayerCode::SHIFT == planned)
            .count()
    };
    let ids = |f: &landsketch::render::Frame| f.ids.clone().expect("ids");
    assert!(planned_in(&ids(&after), 0..w / 2) > 100, "the view shows the plan on the left without a comparison");
    assert_eq!(planned_in(&ids(&before), 0..w), 0, "hiding the layer hides all of it");
    assert_eq!(planned_in(&ids(&both), 0..w / 2), 0, "no plan left of the split");
    assert_eq!(planned_in(&ids(&both), w / 2..w), planned_in(&ids(&after), w / 2..w), "all of it right of the split");
    // Each half is the view without, or with, the plan (apart from the pen line).
    let half = |image: &RgbaImage, x0: u32, x1: u32| image::imageops::crop_imm(image, x0, 0, x1 - x0, h).to_image();
    let (left, right) = ((0, w / 2 - 4), (w / 2 + 4, w));
    let (share, _) = outliers(&half(&both.image, left.0, left.1), &half(&before.image, left.0, left.1));
    assert!(share < 0.01, "left half differs from the view without the plan: {share}");
    let (share, _) = outliers(&half(&both.image, right.0, right.1), &half(&after.image, right.0, right.1));
    assert!(share < 0.01, "right half differs from the view with the plan: {share}");
    // The pen line at the split.
    let line = (0..h).filter(|&y| (w / 2 - 2..w / 2 + 2).any(|x| luminance(both.image.get_pixel(x, y)) < 0.4)).count();
    assert!(line as f64 > 0.9 * f64::from(h), "a pen line runs down the split: {line} of {h} rows");
    assert_matches_reference(&both.image, Path::new("tests/reference/marks/split.png"), 0.02);
    assert_matches_reference(&before.image, Path::new("tests/reference/marks/without_plan.png"), 0.02);

    let err = |compare: Compare| match renderer
        .render(FrameRequest::new(&camera, Style::default(), 64, 48).compare(&compare))
    {
        Err(e) => e,
        Ok(_) => panic!("{compare:?} renders"),
    };
    let unknown = err(Compare { layer: "meadow".into(), split: Some(0.5) });
    assert!(matches!(unknown, RenderError::CompareLayer { .. }), "{unknown}");
    assert!(unknown.to_string().contains("meadow") && unknown.to_string().contains("existing, planned"), "{unknown}");
    let outside = err(Compare { layer: "planned".into(), split: Some(2.0) });
    assert!(outside.to_string().contains("0..=1"), "{outside}");
}
