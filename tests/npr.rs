//! The pen-and-ink pipeline of thesis ch. 5–6 (SPEC R3–R6, R12): contours at several
//! thresholds, every silhouette art map and every tonal art map on the same tree, the
//! coherence of the hybrid hatching against image-space hatching, and invalid parameters.

mod common;

use common::{assert_matches_reference, fraction, full_detail, luminance, trees_on_a_plain};
use landsketch::render::coherence::{camera_path, flicker};
use landsketch::render::style::HatchSpace;
use landsketch::render::{FrameRequest, Readback, RenderError, Renderer, Style};
use landsketch::scene::camera::Camera;
use std::path::PathBuf;

const SIZE: (u32, u32) = (192, 192);

/// A close view of one tree filling most of the frame.
fn close_up() -> (Renderer, Camera) {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = Camera::perspective([0.0, -16.0, 105.5], 0.0, 8.0, 50.0);
    (renderer, camera)
}

fn reference(name: &str) -> PathBuf {
    PathBuf::from(format!("tests/reference/npr/{name}.png"))
}

/// Fraction of pixels with any ink.
fn ink(image: &image::RgbaImage) -> f64 {
    fraction(image, |l| l < 0.9)
}

#[test]
fn contours_at_three_thresholds() {
    let (renderer, camera) = close_up();
    let mut previous = f64::INFINITY;
    for threshold in [0.05f32, 0.3, 1.5] {
        let style =
            Style { contour_threshold: threshold, hatch_strength: 0.0, silhouette_strength: 0.0, ..Style::default() };
        let image = renderer.render(FrameRequest::new(&camera, &style, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
        assert_matches_reference(&image, &reference(&format!("contours_t{threshold}")), 0.02);
        let covered = ink(&image);
        assert!(covered > 0.005, "threshold {threshold}: no contours at all");
        assert!(covered < previous, "threshold {threshold}: {covered} not below {previous}");
        previous = covered;
        // Only contours: sky and ground stay paper away from the tree.
        assert!(luminance(image.get_pixel(3, 3)) > 0.95 && luminance(image.get_pixel(3, SIZE.1 - 3)) > 0.95);
    }
}

#[test]
fn every_silhouette_art_map_on_the_same_tree() {
    let (renderer, camera) = close_up();
    // A dark uniform tone (contrast 0, eq. 6.7) selects the heavier SAM channels.
    let plain = Style {
        hatch_strength: 0.0,
        silhouette_strength: 0.0,
        tone_contrast: 0.0,
        tone_reference: 0.3,
        ..Style::default()
    };
    let without = renderer.render(FrameRequest::new(&camera, &plain, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    let ids = renderer
        .render(FrameRequest::new(&camera, Style::default(), SIZE.0, SIZE.1).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    let (_, sams) = renderer.art_map_counts();
    assert!(sams >= 4);
    let mut images = Vec::new();
    for map in 0..sams {
        let style = Style { silhouette_map: map, silhouette_strength: 1.0, ..plain.clone() };
        let image = renderer.render(FrameRequest::new(&camera, &style, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
        assert_matches_reference(&image, &reference(&format!("sam_{map}")), 0.02);
        // Stylized silhouettes add ink inside the tree's outline, never outside it.
        assert!(ink(&image) > ink(&without), "SAM {map} adds no strokes");
        for ((a, b), id) in image.pixels().zip(without.pixels()).zip(&ids) {
            if luminance(a) < luminance(b) - 0.05 {
                assert_eq!(id >> 24, 2, "silhouette ink outside the tree (object id {id:#x})");
            }
        }
        images.push(image);
    }
    for i in 0..images.len() {
        for j in i + 1..images.len() {
            assert_ne!(images[i], images[j], "SAMs {i} and {j} draw the same strokes");
        }
    }
}

#[test]
fn every_tonal_art_map_at_three_tones() {
    let (renderer, camera) = close_up();
    let (tams, _) = renderer.art_map_counts();
    assert!(tams >= 4);
    // Contrast 0 makes the tone equal to the reference everywhere (eq. 6.7), so the tone of
    // the whole tree is set directly.
    for map in 0..tams {
        let mut previous = 0.0;
        for tone in [0.8f32, 0.5, 0.2] {
            let style = Style {
                hatch_map: map,
                tone_contrast: 0.0,
                tone_reference: tone,
                silhouette_strength: 0.0,
                contour_strength: 0.0,
                ..Style::default()
            };
            let image = renderer.render(FrameRequest::new(&camera, &style, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
            assert_matches_reference(&image, &reference(&format!("tam_{map}_tone{tone}")), 0.02);
            let darkness =
                1.0 - image.pixels().map(|p| f64::from(luminance(p))).sum::<f64>() / f64::from(SIZE.0 * SIZE.1);
            assert!(darkness > previous, "TAM {map} at tone {tone}: darkness {darkness} not above {previous}");
            previous = darkness;
        }
    }
}

#[test]
fn hybrid_hatching_flickers_less_than_image_space_hatching() {
    let scene = trees_on_a_plain(&[[-6.0, 0.0], [5.0, 4.0], [0.0, 12.0], [-12.0, 14.0], [10.0, 18.0]]);
    let renderer = full_detail(&scene);
    let path = camera_path(&scene.default_camera, 3);
    let base = Style { silhouette_strength: 0.0, ..Style::default() };
    let hybrid = flicker(&renderer, &Style { hatch_space: HatchSpace::Hybrid, ..base.clone() }, &path, 160, 120)
        .unwrap()
        .whole_frame;
    let image =
        flicker(&renderer, &Style { hatch_space: HatchSpace::Image, ..base }, &path, 160, 120).unwrap().whole_frame;
    assert!(hybrid > 0.0 && image > 0.0);
    assert!(hybrid < image, "hybrid {hybrid} vs image-space {image}");
}

#[test]
fn invalid_npr_parameters_are_clear_errors() {
    let (renderer, camera) = close_up();
    let negative = Style { silhouette_support: -2.0, ..Style::default() };
    let err = renderer.render(FrameRequest::new(&camera, &negative, 32, 32)).map(|f| f.image).unwrap_err().to_string();
    assert!(err.contains("silhouette_support"), "{err}");
    let (tams, sams) = renderer.art_map_counts();
    let err = renderer
        .render(FrameRequest::new(&camera, &Style { hatch_map: tams, ..Style::default() }, 32, 32))
        .map(|f| f.image)
        .unwrap_err();
    assert!(matches!(err, RenderError::UnknownArtMap { field: "hatch_map", .. }), "{err}");
    let err = renderer
        .render(FrameRequest::new(&camera, &Style { silhouette_map: sams + 3, ..Style::default() }, 32, 32))
        .map(|f| f.image)
        .unwrap_err();
    assert!(err.to_string().contains("silhouette_map"), "{err}");
}
