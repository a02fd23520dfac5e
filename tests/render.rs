//! Rendering tests on lavapipe (or a real GPU): the sample view against a reference image
//! with tolerance, image properties, the ID buffer, a synthetic scene with known pixels, and
//! errors for bad sizes and styles.

mod common;

use common::{assert_matches_reference, fraction, gpu, luminance, trees_on_a_plain};
use landsketch::render::gbuffer::TERRAIN_LAYER_CODE;
use landsketch::render::{FrameRequest, Readback, RenderError, Renderer, Style};
use landsketch::scene::Scene;
use std::collections::HashSet;
use std::path::Path;
use std::sync::OnceLock;

fn sample() -> &'static (Scene, Renderer) {
    static SAMPLE: OnceLock<(Scene, Renderer)> = OnceLock::new();
    SAMPLE.get_or_init(|| {
        let scene = Scene::load(Path::new("data/boulder/scene.toml")).expect("sample scene");
        let renderer = Renderer::new(gpu(), &scene).unwrap();
        (scene, renderer)
    })
}

/// Paper colour of the default style as 8-bit sRGB.
fn paper() -> [u8; 3] {
    Style::default().paper.map(|c| (c * 255.0).round() as u8)
}

#[test]
fn sample_view_matches_reference_and_looks_like_a_sketch() {
    let (scene, renderer) = sample();
    let image =
        renderer.render(FrameRequest::new(&scene.default_camera, Style::default(), 512, 384)).map(|f| f.image).unwrap();
    assert_matches_reference(&image, Path::new("tests/reference/sample_view.png"), 0.02);

    let ink = fraction(&image, |l| l < 0.5);
    let white = fraction(&image, |l| l > 0.95);
    assert!((0.03..0.45).contains(&ink), "ink coverage {ink}");
    assert!(white > 0.4, "paper-white fraction {white}");
    // The sky in the top rows is untouched paper.
    for x in 0..image.width() {
        assert_eq!(image.get_pixel(x, 2).0[..3], paper(), "sky pixel at x={x}");
    }
    // The terrain carries hatching where it turns away from the sun: some ink, mostly paper.
    let ids = renderer
        .render(FrameRequest::new(&scene.default_camera, Style::default(), 512, 384).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    let terrain: Vec<f32> =
        image.pixels().zip(&ids).filter(|(_, id)| *id >> 24 == TERRAIN_LAYER_CODE).map(|(p, _)| luminance(p)).collect();
    let terrain_ink = terrain.iter().filter(|l| **l < 0.9).count() as f64 / terrain.len() as f64;
    assert!((0.02..0.6).contains(&terrain_ink), "ink covers {terrain_ink} of the terrain");
}

#[test]
fn default_view_shows_terrain_and_hundreds_of_plants_of_both_layers() {
    let (scene, renderer) = sample();
    let ids = renderer
        .render(FrameRequest::new(&scene.default_camera, Style::default(), 1024, 768).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    assert_eq!(ids.len(), 1024 * 768);
    let distinct: HashSet<u32> = ids.iter().copied().collect();
    assert!(distinct.contains(&0), "background visible");
    let layer = |id: u32| id >> 24;
    assert!(distinct.iter().any(|id| layer(*id) == TERRAIN_LAYER_CODE));
    let existing = distinct.iter().filter(|id| layer(**id) == 2).count();
    let planned = distinct.iter().filter(|id| layer(**id) == 3).count();
    assert!(existing + planned >= 300, "only {existing} + {planned} plants visible");
    assert!(planned >= 20, "only {planned} planned plants visible");
}

fn tree_on_a_plain() -> Scene {
    trees_on_a_plain(&[[0.0, 0.0]])
}

#[test]
fn a_tree_on_a_plain_is_outlined_on_paper() {
    let scene = tree_on_a_plain();
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let (w, h) = (256, 192);
    let image =
        renderer.render(FrameRequest::new(&scene.default_camera, Style::default(), w, h)).map(|f| f.image).unwrap();
    assert_matches_reference(&image, Path::new("tests/reference/tree_on_plain.png"), 0.02);

    // Sky and the sunlit flat ground far from the tree are plain paper.
    assert_eq!(image.get_pixel(5, 5).0[..3], paper());
    assert_eq!(image.get_pixel(5, h - 5).0[..3], paper());
    // The tree stands in the middle: the centre column has ink, the image edges do not.
    let column_ink = |x: u32| (0..h).filter(|y| luminance(image.get_pixel(x, *y)) < 0.5).count();
    assert!(column_ink(w / 2) > 10, "no ink on the tree's column");
    assert_eq!(column_ink(2), column_ink(w - 3), "left and right edges differ (horizon only)");
    // The far edge of the plain is a contour: a dark pixel in the edge column below the horizon.
    assert!((h / 2..h / 2 + 12).any(|y| luminance(image.get_pixel(2, y)) < 0.5), "no horizon contour at the left edge");

    // With contours and hatching switched off the whole image is paper.
    let blank = Style { contour_strength: 0.0, hatch_strength: 0.0, silhouette_strength: 0.0, ..Style::default() };
    let image = renderer.render(FrameRequest::new(&scene.default_camera, &blank, w, h)).map(|f| f.image).unwrap();
    assert!(image.pixels().all(|p| p.0[..3] == paper()));
}

#[test]
fn isolated_pixel_removal_only_removes_ink() {
    let scene = tree_on_a_plain();
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let hatchless = Style { hatch_strength: 0.0, silhouette_strength: 0.0, ..Style::default() };
    let with =
        renderer.render(FrameRequest::new(&scene.default_camera, &hatchless, 256, 192)).map(|f| f.image).unwrap();
    let without = renderer
        .render(FrameRequest::new(
            &scene.default_camera,
            &Style { isolated_pixel_removal: false, ..hatchless.clone() },
            256,
            192,
        ))
        .map(|f| f.image)
        .unwrap();
    let ink = |img: &image::RgbaImage| fraction(img, |l| l < 0.9);
    assert!(ink(&with) < ink(&without), "eq. 5.2 removed nothing: {} vs {}", ink(&with), ink(&without));
    for (a, b) in with.pixels().zip(without.pixels()) {
        assert!(luminance(a) >= luminance(b) - 1e-6, "removal added ink");
    }
}

#[test]
fn bad_sizes_and_styles_are_errors() {
    let (scene, renderer) = sample();
    let cam = scene.default_camera;
    assert!(matches!(
        renderer.render(FrameRequest::new(&cam, Style::default(), 0, 10)).map(|f| f.image),
        Err(RenderError::Size { .. })
    ));
    assert!(matches!(
        renderer.render(FrameRequest::new(&cam, Style::default(), 100_000, 10)).map(|f| f.image),
        Err(RenderError::Size { .. })
    ));
    let bad = Style { contour_threshold: -1.0, ..Style::default() };
    let err = renderer.render(FrameRequest::new(&cam, &bad, 64, 64)).map(|f| f.image).unwrap_err().to_string();
    assert!(err.contains("contour_threshold"), "{err}");
}
