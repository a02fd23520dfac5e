//! The style space (SPEC R1, R7–R10): every preset on the sample scene, the photorealism →
//! sketch strip (thesis 8.2.7), colour and photorealistic shading on a plain with known
//! pixels, HLP abstraction (eq. 4.8), per-layer styles in one frame (thesis 8.2.8) and errors.
//! References are 256 × 192 and compared with tolerance; each test also asserts properties.

mod common;

use common::{assert_matches_reference, fraction, full_detail, gpu, luminance, trees_on_a_plain};
use landsketch::render::presets::PRESETS;
use landsketch::render::style::{FrameStyle, LayerStyle, TERRAIN_LAYER};
use landsketch::render::view_style::ViewStyle;
use landsketch::render::{FrameRequest, Readback, RenderError, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::Sun;
use landsketch::scene::camera::Camera;
use landsketch::scene::cover::Drape;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const SIZE: (u32, u32) = (256, 192);

fn sample() -> &'static (Scene, Renderer) {
    static SAMPLE: OnceLock<(Scene, Renderer)> = OnceLock::new();
    SAMPLE.get_or_init(|| {
        let scene = Scene::load(Path::new("data/boulder/scene.toml")).expect("sample scene");
        let renderer = Renderer::new(gpu(), &scene).expect("renderer");
        (scene, renderer)
    })
}

fn reference(name: &str) -> PathBuf {
    PathBuf::from(format!("tests/reference/styles/{name}.png"))
}

fn preset(name: &str) -> Style {
    landsketch::render::presets::preset(name).expect("preset")
}

/// `styles` with every style's ink set to `ink`.
fn with_ink(styles: &FrameStyle, ink: [f32; 3]) -> FrameStyle {
    let mut styles = styles.clone();
    for style in std::iter::once(&mut styles.base).chain(styles.layers.values_mut()) {
        style.ink = ink;
    }
    styles
}

/// Renders `styles` with black and with white ink: the image (black ink) and the ink coverage
/// of every pixel. The output is mix(base, ink, coverage), so the difference of the two
/// renders divided by the difference of the inks is the coverage.
fn render_with_coverage(renderer: &Renderer, camera: &Camera, styles: &FrameStyle) -> (image::RgbaImage, Vec<f32>) {
    let black = renderer
        .render(FrameRequest::new(camera, with_ink(styles, [0.0; 3]), SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    let white = renderer
        .render(FrameRequest::new(camera, with_ink(styles, [1.0; 3]), SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    let coverage = black
        .pixels()
        .zip(white.pixels())
        .map(|(b, w)| (0..3).map(|c| f32::from(w[c]) - f32::from(b[c])).sum::<f32>() / (3.0 * 255.0))
        .collect();
    (black, coverage)
}

fn mean(values: &[f32]) -> f32 {
    values.iter().sum::<f32>() / values.len() as f32
}

/// Mean absolute difference of two images, 0..1.
fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> f32 {
    let sum: f32 =
        a.pixels().zip(b.pixels()).map(|(p, q)| (0..3).map(|c| f32::from(p[c].abs_diff(q[c]))).sum::<f32>()).sum();
    sum / (3.0 * 255.0 * (a.width() * a.height()) as f32)
}

/// Saturation (max − min of the channels, 0..1) of a pixel.
fn chroma(p: &image::Rgba<u8>) -> f32 {
    f32::from(p[0].max(p[1]).max(p[2]) - p[0].min(p[1]).min(p[2])) / 255.0
}

#[test]
fn every_preset_matches_its_reference() {
    let (scene, renderer) = sample();
    let camera = scene.default_camera;
    for p in PRESETS {
        let styles = FrameStyle::from(p.style().unwrap());
        let image = renderer.render(FrameRequest::new(&camera, &styles, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
        assert_matches_reference(&image, &reference(&format!("preset_{}", p.name)), 0.02);
        let (_, coverage) = render_with_coverage(renderer, &camera, &styles);
        let ink = coverage.iter().filter(|c| **c > 0.1).count() as f32 / coverage.len() as f32;
        let colourful = image.pixels().filter(|p| chroma(p) > 0.15).count() as f32 / coverage.len() as f32;
        match p.name {
            // No line, no stroke anywhere; colour everywhere, a blue sky on top.
            "photorealism" => {
                assert_eq!(ink, 0.0, "photorealism draws ink");
                let sky = image.get_pixel(SIZE.0 / 2, 2);
                assert!(sky[2] > sky[0] + 40, "sky {sky:?}");
            }
            // Pen and ink: no colour, paper sky, ink on a part of the image.
            "full_npr" | "silhouettes_hatching" | "minimalistic" => {
                assert!(colourful < 0.01, "{}: colour on {colourful}", p.name);
                assert!(ink > 0.002 && ink < 0.5, "{}: ink covers {ink}", p.name);
                assert!(luminance(image.get_pixel(SIZE.0 / 2, 2)) > 0.95, "{}: sky not paper", p.name);
            }
            _ => {
                assert!(colourful > 0.02, "{}: colour on only {colourful}", p.name);
                assert!(ink > 0.002, "{}: ink covers only {ink}", p.name);
            }
        }
    }
    // Minimalistic draws contours only: far less ink than the full pen-and-ink preset.
    let coverage = |name: &str| mean(&render_with_coverage(renderer, &camera, &preset(name).into()).1);
    assert!(coverage("minimalistic") < 0.5 * coverage("full_npr"));
}

#[test]
fn photorealism_strip_is_a_continuous_progression() {
    let (scene, renderer) = sample();
    let camera = scene.default_camera;
    let mut images = Vec::new();
    let mut inks = Vec::new();
    for (i, photorealism) in [1.0f32, 0.75, 0.5, 0.25, 0.0].into_iter().enumerate() {
        let style = Style { photorealism, ..preset("full_npr") };
        let (image, coverage) = render_with_coverage(renderer, &camera, &style.into());
        assert_matches_reference(&image, &reference(&format!("strip_{i}")), 0.02);
        inks.push(mean(&coverage));
        images.push(image);
    }
    // Ink grows along the strip, from none at full photorealism.
    assert_eq!(inks[0], 0.0);
    for w in inks.windows(2) {
        assert!(w[1] > w[0], "ink coverage {inks:?} does not grow");
    }
    // Continuity: every step changes the image by less than half of the whole way.
    let whole = difference(&images[0], &images[4]);
    for w in images.windows(2) {
        let step = difference(&w[0], &w[1]);
        assert!(step < 0.5 * whole, "a step of {step} out of {whole}");
    }
}

/// A bare plain (albedo 0.5, 0.4, 0.3) lit from 30° elevation, seen from 20 m looking down.
fn lit_plain() -> (Renderer, Camera) {
    let mut scene = trees_on_a_plain(&[]);
    let bounds = scene.terrain.bounds();
    scene.terrain.set_drape(Drape::plain([0.5, 0.4, 0.3], bounds));
    scene.sun = Sun { azimuth: 180.0, elevation: 30.0 };
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = Camera { position: [0.0, 0.0, 120.0], pitch: -30.0, ..scene.default_camera };
    (renderer, camera)
}

fn encode_srgb(c: f32) -> f32 {
    if c <= 0.0031308 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

#[test]
fn photoreal_pixels_are_albedo_times_lambert_and_ambient() {
    let (renderer, camera) = lit_plain();
    let style = Style { photorealism: 1.0, ambient: 0.3, ..Style::default() };
    let image = renderer.render(FrameRequest::new(&camera, &style, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    // Flat ground, normal (0, 0, 1): N·L = sin 30° = 0.5; light = 0.3 + 0.7·0.5 = 0.65.
    let light = 0.3 + 0.7 * 0.5;
    let ground = image.get_pixel(SIZE.0 / 2, SIZE.1 - 10);
    for (c, albedo) in [0.5f32, 0.4, 0.3].into_iter().enumerate() {
        let expected = encode_srgb(albedo * light) * 255.0;
        assert!((f32::from(ground[c]) - expected).abs() <= 2.0, "channel {c}: {ground:?} vs {expected}");
    }
    // The sky above the horizon runs from the horizon colour towards the zenith colour.
    let [top, low] = [image.get_pixel(SIZE.0 / 2, 1), image.get_pixel(SIZE.0 / 2, SIZE.1 / 4)];
    assert!(top[2] > top[0] && chroma(top) > chroma(low), "sky {top:?} above {low:?}");
    assert_matches_reference(&image, &reference("photoreal_plain"), 0.01);

    // Colour over the sketch: saturation 0 greys it, Gooch turns it cool or warm, the toon ramp
    // quantizes the light (0.65 with 3 bands → the middle band, 0.5).
    let sketch = Style { color: 1.0, hatch_strength: 0.0, contour_strength: 0.0, ambient: 0.3, ..Style::default() };
    let grey = renderer
        .render(FrameRequest::new(&camera, &Style { color_saturation: 0.0, ..sketch.clone() }, SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    assert!(chroma(grey.get_pixel(SIZE.0 / 2, SIZE.1 - 10)) < 0.01);
    let toon = Style { toon: 1.0, toon_levels: 3, ..sketch.clone() };
    let image = renderer.render(FrameRequest::new(&camera, &toon, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    let ground = image.get_pixel(SIZE.0 / 2, SIZE.1 - 10);
    let expected = encode_srgb(0.5 * 0.5) * 255.0;
    assert!((f32::from(ground[0]) - expected).abs() <= 2.0, "toon {ground:?} vs {expected}");
    let gooch = renderer
        .render(FrameRequest::new(&camera, &Style { gooch: 1.0, ..sketch }, SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    let g = gooch.get_pixel(SIZE.0 / 2, SIZE.1 - 10);
    // k = (1 + N·L)/2 = 0.75: 0.25·(0.2·k_d + (0, 0, 0.4)) + 0.75·(0.6·k_d + (0.4, 0.4, 0)).
    let expected_blue = encode_srgb(0.25 * (0.2 * 0.3 + 0.4) + 0.75 * (0.6 * 0.3)) * 255.0;
    assert!((f32::from(g[2]) - expected_blue).abs() <= 2.0, "gooch {g:?} vs blue {expected_blue}");
}

#[test]
fn hlp_abstraction_pulls_leaves_onto_their_spheres() {
    let scene = trees_on_a_plain(&[[0.0, 0.0]]);
    let renderer = full_detail(&scene);
    let camera = Camera { position: [0.0, -16.0, 105.5], pitch: 8.0, fov: 50.0, ..scene.default_camera };
    let plain = Style { hatch_strength: 0.0, silhouette_strength: 0.0, ..Style::default() };
    let original = renderer.render(FrameRequest::new(&camera, &plain, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    let abstract_ = renderer
        .render(FrameRequest::new(&camera, &Style { hlp_abstraction: 1.0, ..plain.clone() }, SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    assert_matches_reference(&abstract_, &reference("hlp_abstraction"), 0.02);
    // Eq. 4.8 is a blend: half-way differs from the original less than the full projection,
    // and the trunk (no HLP) does not move.
    let half = renderer
        .render(FrameRequest::new(&camera, &Style { hlp_abstraction: 0.5, ..plain }, SIZE.0, SIZE.1))
        .map(|f| f.image)
        .unwrap();
    let (to_half, to_full) = (difference(&half, &original), difference(&abstract_, &original));
    assert!(0.0 < to_half && to_half < to_full, "{to_half} vs {to_full}");
    let trunk =
        |image: &image::RgbaImage| (150..SIZE.1).map(|y| luminance(image.get_pixel(SIZE.0 / 2, y))).collect::<Vec<_>>();
    assert_eq!(trunk(&abstract_), trunk(&original));
}

#[test]
fn layers_have_styles_of_their_own_in_one_frame() {
    let (scene, renderer) = sample();
    let camera = scene.default_camera;
    let base = preset("full_npr");
    let overrides: LayerStyle = serde_json::from_value(serde_json::json!({"preset": "photorealism"})).unwrap();
    let mut mixed = FrameStyle::from(base.clone());
    mixed.layers.insert("existing".into(), overrides.resolve(&base).unwrap().style);
    let image = renderer.render(FrameRequest::new(&camera, &mixed, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    assert_matches_reference(&image, &reference("mixed_existing_planned"), 0.02);

    let ids = renderer
        .render(FrameRequest::new(&camera, Style::default(), SIZE.0, SIZE.1).read(Readback::IDS))
        .map(|f| f.ids.unwrap_or_default())
        .unwrap();
    let (_, coverage) = render_with_coverage(renderer, &camera, &mixed);
    let photo =
        renderer.render(FrameRequest::new(&camera, preset("photorealism"), SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    let sketch = renderer.render(FrameRequest::new(&camera, &base, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    let layer_pixels = |code: u32| ids.iter().enumerate().filter(move |(_, id)| *id >> 24 == code).map(|(i, _)| i);
    // `existing` (layer code 2) is photorealistic: no ink, and the pixels of the photorealistic
    // frame (the frames' geometry differs only where `planned` leaves are abstracted).
    let existing: Vec<usize> = layer_pixels(2).collect();
    assert!(existing.len() > 100, "existing plants cover {} pixels", existing.len());
    let same = |a: &image::RgbaImage, i: usize| {
        let (x, y) = (i as u32 % SIZE.0, i as u32 / SIZE.0);
        (0..3).all(|c| a.get_pixel(x, y)[c].abs_diff(image.get_pixel(x, y)[c]) <= 2)
    };
    let inked = existing.iter().filter(|&&i| coverage[i] > 0.05).count();
    assert!(inked * 50 < existing.len(), "{inked} of {} existing pixels carry ink", existing.len());
    let as_photo = existing.iter().filter(|&&i| same(&photo, i)).count();
    assert!(as_photo * 10 > existing.len() * 9, "{as_photo} of {} existing pixels photorealistic", existing.len());
    // `planned` (code 3) and the terrain keep the sketch: ink on them, as in the sketch frame,
    // with the contours between the layers drawn.
    for code in [1, 3] {
        let pixels: Vec<usize> = layer_pixels(code).collect();
        let inked = pixels.iter().filter(|&&i| coverage[i] > 0.3).count();
        assert!(inked * 50 > pixels.len(), "layer code {code}: {inked} of {} pixels inked", pixels.len());
        // Far planned plants stand among existing dots and masses: the tone blur mixes in their
        // photorealistic neighbours' tone by a few levels, so "as sketch" allows that.
        let near_sketch = |i: usize| {
            let (x, y) = (i as u32 % SIZE.0, i as u32 / SIZE.0);
            (0..3).all(|c| sketch.get_pixel(x, y)[c].abs_diff(image.get_pixel(x, y)[c]) <= 12)
        };
        let as_sketch = pixels.iter().filter(|&&i| near_sketch(i)).count();
        assert!(as_sketch * 10 > pixels.len() * 9, "layer code {code}: {as_sketch} of {} as sketch", pixels.len());
    }

    // The terrain by its name; unknown layers are errors naming the known ones.
    let mut terrain = FrameStyle::from(base.clone());
    // (Toned by its absolute light: with the relief tone this view's sunny ground is paper.)
    terrain.layers.insert(TERRAIN_LAYER.into(), Style { hatch_map: 1, terrain_relief: 0.0, ..base.clone() });
    let crossed = renderer.render(FrameRequest::new(&camera, &terrain, SIZE.0, SIZE.1)).map(|f| f.image).unwrap();
    assert!(difference(&crossed, &sketch) > 0.01);
    let mut unknown = FrameStyle::from(base);
    unknown.layers.insert("meadow".into(), Style::default());
    let err = renderer.render(FrameRequest::new(&camera, &unknown, 32, 32)).map(|f| f.image).unwrap_err();
    assert!(matches!(&err, RenderError::UnknownLayer { name, known } if name == "meadow" && known.contains("planned")));
}

#[test]
fn bad_presets_and_values_are_errors_naming_them() {
    let winter = ViewStyle { preset: Some("winter".into()), ..ViewStyle::default() };
    let err = winter.resolve(&[]).unwrap_err().to_string();
    for name in ["winter", "photorealism", "van_gogh", "childrens_book"] {
        assert!(err.contains(name), "{err}");
    }
    let style = serde_json::from_value(serde_json::json!({"photorealism": 1.5})).unwrap();
    let overrides = ViewStyle { preset: Some("full_npr".into()), style, ..ViewStyle::default() };
    let err = overrides.resolve(&[]).unwrap_err().to_string();
    assert!(err.contains("photorealism") && err.contains("0..=1"), "{err}");
    let (scene, renderer) = sample();
    let bad = Style { color_saturation: 3.0, ..Style::default() };
    let err = renderer
        .render(FrameRequest::new(&scene.default_camera, &bad, 32, 32))
        .map(|f| f.image)
        .unwrap_err()
        .to_string();
    assert!(err.contains("color_saturation") && err.contains("0..=2"), "{err}");
}

#[test]
fn a_hidden_layer_draws_no_plants() {
    let camera = trees_on_a_plain(&[]).default_camera;
    let scene = trees_on_a_plain(&[[-5.0, 5.0], [4.0, 10.0]]);
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let hidden = FrameStyle {
        base: Style::default(),
        layers: [("test".to_owned(), Style { visible: false, ..Style::default() })].into(),
    };
    let bare = Renderer::new(gpu(), &trees_on_a_plain(&[])).unwrap();
    let without_plants = bare.render(FrameRequest::new(&camera, Style::default(), 160, 120)).map(|f| f.image).unwrap();
    assert_eq!(
        renderer.render(FrameRequest::new(&camera, &hidden, 160, 120)).map(|f| f.image).unwrap(),
        without_plants
    );
    assert_ne!(
        renderer.render(FrameRequest::new(&camera, Style::default(), 160, 120)).map(|f| f.image).unwrap(),
        without_plants
    );
}

/// Frames whose slots all share one style are drawn with post-pass pipelines specialised for
/// it (`render::post::Specialization`); a style difference no pixel shows (the sky colours of
/// the terrain layer, whose pixels never show the sky) forces the general shaders, which look
/// each pixel's style up. Both must draw the same image.
#[test]
fn specialised_pipelines_draw_what_the_general_ones_draw() {
    let scene = trees_on_a_plain(&[[-5.0, 5.0], [4.0, 10.0]]);
    let renderer = Renderer::new(gpu(), &scene).unwrap();
    let camera = scene.default_camera;
    for preset in PRESETS.iter().filter(|p| ["full_npr", "photorealism"].contains(&p.name)) {
        let base = preset.style().unwrap();
        let terrain = Style { sky_zenith: [1.0, 0.0, 0.0], sky_horizon: [0.0, 1.0, 0.0], ..base.clone() };
        let general = FrameStyle { base: base.clone(), layers: [(TERRAIN_LAYER.to_owned(), terrain)].into() };
        let specialised = renderer.render(FrameRequest::new(&camera, &base, 160, 120)).map(|f| f.image).unwrap();
        assert_eq!(
            specialised,
            renderer.render(FrameRequest::new(&camera, &general, 160, 120)).map(|f| f.image).unwrap(),
            "{}",
            preset.name
        );
        assert!(fraction(&specialised, |l| l < 0.5) > 0.01, "{} draws ink", preset.name);
    }
}

/// Mean luminance of the `mask` pixels of `image`.
fn masked_mean(image: &image::RgbaImage, mask: &[bool]) -> f32 {
    let values: Vec<f32> = image.pixels().zip(mask).filter(|(_, m)| **m).map(|(p, _)| luminance(p)).collect();
    mean(&values)
}

/// Mean absolute luminance step between neighbouring `mask` pixels (right and down): the
/// small-scale noise of the shading.
fn masked_noise(image: &image::RgbaImage, mask: &[bool]) -> f32 {
    let (w, h) = image.dimensions();
    let mut steps = Vec::new();
    for y in 0..h {
        for x in 0..w {
            for (nx, ny) in [(x + 1, y), (x, y + 1)] {
                let (i, j) = ((y * w + x) as usize, (ny * w + nx) as usize);
                if nx < w && ny < h && mask[i] && mask[j] {
                    steps.push((luminance(image.get_pixel(x, y)) - luminance(image.get_pixel(nx, ny))).abs());
                }
            }
        }
    }
    mean(&steps)
}

#[test]
fn implicit_surface_illumination_smooths_and_darkens_the_crown() {
    // Luft et al. 2007 on one tree lit from the east (the right of the image): the leaves' own
    // normals, normals realigned to the implicit surface (§3.3), and those with the ambient
    // light darkened by k_a (eq. 4) — in colour (top row) and in pen and ink (bottom row).
    let mut scene = trees_on_a_plain(&[[0.0, 0.0]]);
    scene.sun = Sun { azimuth: 100.0, elevation: 30.0 };
    let renderer = full_detail(&scene);
    let camera = Camera { position: [0.0, -11.0, 106.0], pitch: 4.0, fov: 50.0, ..scene.default_camera };
    let colour = Style {
        color: 1.0,
        hatch_strength: 0.0,
        contour_strength: 0.0,
        silhouette_strength: 0.0,
        normal_blend: 0.0,
        ..Style::default()
    };
    let ink = Style { normal_blend: 0.0, ..Style::default() };
    let row = |base: &Style| {
        [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)].map(|(implicit_normals, ambient_occlusion)| {
            let style = Style { implicit_normals, ambient_occlusion, ..base.clone() };
            renderer.render(FrameRequest::new(&camera, &style, SIZE.0, SIZE.1)).map(|f| f.image).unwrap()
        })
    };
    let (colours, inks) = (row(&colour), row(&ink));
    let mut sheet = image::RgbaImage::new(3 * SIZE.0, 2 * SIZE.1);
    for (i, image) in colours.iter().chain(&inks).enumerate() {
        image::imageops::replace(&mut sheet, image, i64::from(i as u32 % 3 * SIZE.0), i64::from(i as u32 / 3 * SIZE.1));
    }
    assert_matches_reference(&sheet, &reference("implicit_illumination"), 0.02);

    // The crown: the green pixels (the plain is grey, the trunk brown, the sky paper).
    let [own, realigned, occluded] = &colours;
    let crown: Vec<bool> = own.pixels().map(|p| i32::from(p[1]) > i32::from(p[0]) + 15).collect();
    let area = crown.iter().filter(|c| **c).count();
    assert!(area > 3000, "the crown covers {area} pixels");
    // Realigned normals follow the crown's shape, not the random leaves: smoother shading.
    let (noise_own, noise_realigned) = (masked_noise(own, &crown), masked_noise(realigned, &crown));
    assert!(noise_realigned < 0.85 * noise_own, "noise {noise_own} → {noise_realigned}");
    // ... and a light side: the crown's east half gets brighter than its west half.
    let centre_x = crown.iter().enumerate().filter(|(_, c)| **c).map(|(i, _)| (i as u32 % SIZE.0) as f32).sum::<f32>()
        / area as f32;
    let half = |east: bool| -> Vec<bool> {
        crown.iter().enumerate().map(|(i, c)| *c && ((i as u32 % SIZE.0) as f32 > centre_x) == east).collect()
    };
    let contrast = |image| masked_mean(image, &half(true)) - masked_mean(image, &half(false));
    assert!(contrast(realigned) > contrast(own) + 0.01, "east − west {} → {}", contrast(own), contrast(realigned));
    // Ambient occlusion darkens the crown, its dense centre more than its rim.
    let (lit, dark) = (masked_mean(realigned, &crown), masked_mean(occluded, &crown));
    assert!(dark < 0.9 * lit, "mean {lit} → {dark}");
    let centre_y = crown.iter().enumerate().filter(|(_, c)| **c).map(|(i, _)| (i as u32 / SIZE.0) as f32).sum::<f32>()
        / area as f32;
    let radius = (area as f32 / std::f32::consts::PI).sqrt();
    let ring = |lo: f32, hi: f32| -> Vec<bool> {
        crown
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let (x, y) = ((i as u32 % SIZE.0) as f32 - centre_x, (i as u32 / SIZE.0) as f32 - centre_y);
                *c && (lo..hi).contains(&((x * x + y * y).sqrt() / radius))
            })
            .collect()
    };
    let darkening = |mask: &[bool]| masked_mean(occluded, mask) / masked_mean(realigned, mask);
    let (centre, rim) = (darkening(&ring(0.0, 0.5)), darkening(&ring(0.8, 2.0)));
    assert!(centre < rim - 0.05, "centre keeps {centre} of its light, the rim {rim}");
    // In pen and ink the darker crown carries more ink.
    assert!(masked_mean(&inks[2], &crown) < 0.9 * masked_mean(&inks[1], &crown));
}
