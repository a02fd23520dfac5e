//! The Rio San Francisco valley sample scene (`data/rbsf/`, issue 17): montane forest at real
//! densities from its land cover, viewpoints that resolve and frame the plan, the style's
//! `focus` that makes the planned woodland findable (in colour, the rest lighter), and the
//! viewpoints in three presets against their reference sheet.

mod common;

use common::{assert_matches_reference, gpu, luminance};
use image::RgbaImage;
use landsketch::render::{FrameRequest, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use landsketch::scene::camera_params::Source;
use landsketch::scene::config::SceneConfig;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// The scene and one renderer of it, shared by the tests of this binary.
fn valley() -> &'static (Scene, Renderer) {
    static VALLEY: OnceLock<(Scene, Renderer)> = OnceLock::new();
    VALLEY.get_or_init(|| {
        let scene = Scene::load(&repo("data/rbsf/scene.toml")).expect("the valley scene");
        let renderer = Renderer::new(gpu(), &scene).expect("renderer");
        (scene, renderer)
    })
}

fn preset(name: &str) -> Style {
    landsketch::render::presets::preset(name).expect("preset")
}

/// The scene file's viewpoints with their cameras resolved (as the server does).
fn viewpoints(scene: &Scene) -> Vec<(String, Camera)> {
    let config = SceneConfig::load(&repo("data/rbsf/scene.toml")).expect("scene file");
    config
        .viewpoints
        .iter()
        .map(|v| {
            let camera = v.camera.resolve(&scene.default_camera, scene, Source::Body).expect("viewpoint camera").camera;
            (v.name.clone(), camera)
        })
        .collect()
}

/// Whether a pixel is clearly green (its green channel over the others by more than
/// rounding and the JPEG-free image's own noise).
fn is_green(p: &image::Rgba<u8>) -> bool {
    i32::from(p[1]) > i32::from(p[0]).max(i32::from(p[2])) + 6
}

/// Share of pixels whose colour is clearly green (the plan's foliage under `focus`; the
/// `full_npr` ink and paper are grey).
fn green_fraction(image: &RgbaImage) -> f64 {
    let green = image.pixels().filter(|p| is_green(p)).count();
    green as f64 / f64::from(image.width() * image.height())
}

#[test]
fn the_forest_has_real_densities_and_the_viewpoints_are_valid() {
    let (scene, _) = valley();
    let config = SceneConfig::load(&repo("data/rbsf/scene.toml")).expect("scene file");
    landsketch::api::viewpoints::check_all(&config.viewpoints, scene).expect("viewpoints");
    // Trees per hectare of forest: the land cover's forest cells (41, 43) against the trees
    // the two forest rules placed.
    let cover = landsketch::gis::load_raster(&repo("data/rbsf/landcover.tif")).expect("land cover");
    let cell_ha = cover.transform.cell_width.abs() * cover.transform.cell_height.abs() / 10_000.0;
    let forest_ha = cover.data.iter().filter(|&&v| v == 41.0 || v == 43.0).count() as f64 * cell_ha;
    let species = |name: &str| scene.species.iter().position(|s| s.name == name).expect("species");
    let (montane, elfin) = (species("montane"), species("elfin"));
    let existing = scene.layers.iter().find(|l| l.name == "existing").expect("existing layer");
    let trees = existing.plants.iter().filter(|p| p.species == montane || p.species == elfin).count() as f64;
    let density = trees / forest_ha;
    assert!(forest_ha > 1000.0 && (200.0..=1000.0).contains(&density), "{trees} trees on {forest_ha:.0} ha");
    // The default camera is the first viewpoint, the one that frames the plan.
    let (_, first) = &viewpoints(scene)[0];
    assert_eq!(first.position, scene.default_camera.position);
    assert_eq!((first.yaw, first.pitch), (scene.default_camera.yaw, scene.default_camera.pitch));
}

#[test]
fn focus_colours_the_plan_and_lightens_the_rest_in_the_default_view() {
    let (scene, renderer) = valley();
    let (w, h) = (320, 240);
    let render = |focus: f32| {
        let style = Style { focus, ..preset("full_npr") };
        renderer.render(FrameRequest::new(&scene.default_camera, style, w, h)).expect("render").image
    };
    let (plain, focused) = (render(0.0), render(1.0));
    // Without focus the sketch is ink on paper; with it the planned woodland is green.
    assert!(green_fraction(&plain) < 0.001, "plain sketch green {:.4}", green_fraction(&plain));
    assert!(green_fraction(&focused) > 0.03, "the plan covers {:.3} of the default view", green_fraction(&focused));
    // The rest is lighter: outside the plan's pixels the ink darkens less.
    let mean = |image: &RgbaImage, keep: &dyn Fn(u32, u32) -> bool| {
        let values: Vec<f32> =
            image.enumerate_pixels().filter(|(x, y, _)| keep(*x, *y)).map(|(_, _, p)| luminance(p)).collect();
        values.iter().sum::<f32>() / values.len().max(1) as f32
    };
    let plan_pixel = |x: u32, y: u32| is_green(focused.get_pixel(x, y));
    let (before, after) = (mean(&plain, &|x, y| !plan_pixel(x, y)), mean(&focused, &|x, y| !plan_pixel(x, y)));
    assert!(after > before + 0.03, "background luminance {before:.3} → {after:.3}");
}

#[test]
fn the_viewpoints_in_three_presets_match_their_reference_and_show_the_plan() {
    // The README gallery's valley views: every viewpoint (near, 1 km, 3 km, the summit, the
    // bird's-eye and the plan) in full_npr, half_npr and photorealism, each with its own
    // style (`focus`) over the preset.
    let (scene, renderer) = valley();
    let config = SceneConfig::load(&repo("data/rbsf/scene.toml")).expect("scene file");
    let views = viewpoints(scene);
    let (w, h) = (192u32, 144u32);
    let presets = ["full_npr", "half_npr", "photorealism"];
    let mut sheet = RgbaImage::new(w * presets.len() as u32, h * views.len() as u32);
    for (row, ((name, camera), viewpoint)) in views.iter().zip(&config.viewpoints).enumerate() {
        for (col, preset_name) in presets.iter().enumerate() {
            let style = preset(preset_name).with(&viewpoint.style.clone().unwrap_or_default()).expect("style");
            let image = renderer.render(FrameRequest::new(camera, style.clone(), w, h)).expect("render").image;
            if *preset_name == "full_npr" {
                // The plan is findable from every viewpoint: its woodland is the only colour
                // (4 km away a patch of a few hundred pixels in 800 × 600).
                let large = renderer.render(FrameRequest::new(camera, style, 320, 240)).expect("render").image;
                let green = large.pixels().filter(|p| is_green(p)).count();
                assert!(green >= 20, "{name}: {green} pixels of the plan in the sketch");
            }
            image::imageops::replace(&mut sheet, &image, i64::from(w) * col as i64, i64::from(h) * row as i64);
        }
    }
    assert_matches_reference(&sheet, &repo("tests/reference/valley_viewpoints.png"), 0.03);
}
