//! The ground's land-cover drape (issue 18, SPEC S1): the sample scene's classes read apart in
//! the sketch and colour styles, class borders are outlined where the style asks, and the
//! scene file's drape inputs fail with messages that name the file.

mod common;

use common::{gpu, luminance};
use landsketch::render::presets::preset;
use landsketch::render::{FrameRequest, Renderer, Style};
use landsketch::scene::Scene;
use landsketch::scene::camera::Camera;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const SIZE: u32 = 256;
/// Metres across the plan view of the sample scene.
const PLAN_WIDTH: f32 = 1600.0;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// A style of `preset` without the vegetation, so only the ground is drawn.
fn ground_only(name: &str) -> Style {
    Style { visible: false, ..preset(name).expect("preset") }
}

/// Pixel positions in an image.
type Pixels = Vec<(u32, u32)>;

/// The sample scene's plan view in `style`, and per land-cover code the pixels whose 3 × 3
/// neighbourhood lies in that class only (borders left out) and the pixels on a border.
fn classes_in_plan(
    scene: &Scene,
    renderer: &Renderer,
    style: &Style,
) -> (image::RgbaImage, BTreeMap<i64, Pixels>, Pixels) {
    classes_in_plan_at(scene, renderer, style, [0.0, 0.0], PLAN_WIDTH)
}

/// [`classes_in_plan`] of a plan view centred on `centre`, `width` metres across.
fn classes_in_plan_at(
    scene: &Scene,
    renderer: &Renderer,
    style: &Style,
    centre: [f32; 2],
    width: f32,
) -> (image::RgbaImage, BTreeMap<i64, Pixels>, Pixels) {
    let camera = Camera::plan(centre[0], centre[1], 4000.0, width);
    let image = renderer.render(FrameRequest::new(&camera, style.clone(), SIZE, SIZE)).expect("render").image;
    let metres = width / SIZE as f32;
    let class = |px: i64, py: i64| {
        let x = centre[0] - width / 2.0 + (px as f32 + 0.5) * metres;
        let y = centre[1] + width / 2.0 - (py as f32 + 0.5) * metres;
        scene.terrain.drape.class_at(f64::from(x), f64::from(y)).map(|c| c.code)
    };
    let (mut inside, mut borders) = (BTreeMap::<i64, Pixels>::new(), Vec::new());
    for py in 2..i64::from(SIZE) - 2 {
        for px in 2..i64::from(SIZE) - 2 {
            let Some(code) = class(px, py) else { continue };
            let neighbours: Vec<Option<i64>> = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| class(px + dx, py + dy))
                .collect();
            if neighbours.iter().all(|c| *c == Some(code)) {
                inside.entry(code).or_default().push((px as u32, py as u32));
            } else {
                borders.push((px as u32, py as u32));
            }
        }
    }
    (image, inside, borders)
}

fn mean_luminance(image: &image::RgbaImage, pixels: &[(u32, u32)]) -> f32 {
    pixels.iter().map(|&(x, y)| luminance(image.get_pixel(x, y))).sum::<f32>() / pixels.len().max(1) as f32
}

fn mean_color(image: &image::RgbaImage, pixels: &[(u32, u32)]) -> [f32; 3] {
    let n = pixels.len().max(1) as f32;
    [0, 1, 2].map(|c| pixels.iter().map(|&(x, y)| f32::from(image.get_pixel(x, y)[c]) / 255.0).sum::<f32>() / n)
}

#[test]
fn the_sample_scenes_land_cover_classes_read_apart_in_every_style() {
    let scene = Scene::load(&repo("data/boulder/scene.toml")).expect("sample scene");
    assert_eq!(scene.terrain.drape.classes.len(), 8, "the simplified NLCD table");
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    // 4 forest, 5 shrubland, 6 herbaceous (the table has 3 barren too, which the DEM does not reach).
    let (sketch, inside, _) = classes_in_plan(&scene, &renderer, &ground_only("full_npr"));
    for code in [4, 5, 6] {
        assert!(inside.get(&code).is_some_and(|p| p.len() > 200), "class {code} covers the plan view");
    }
    let tone = |code: i64| mean_luminance(&sketch, &inside[&code]);
    // Sketch: the forest floor is hatched darkly, shrubland in between, herbaceous ground lightest.
    assert!(tone(4) + 0.2 < tone(6), "forest {} against herbaceous {}", tone(4), tone(6));
    assert!(tone(4) < tone(5) && tone(5) < tone(6), "shrubland {} between forest and herbaceous", tone(5));
    for name in ["half_npr", "photorealism"] {
        let (image, inside, _) = classes_in_plan(&scene, &renderer, &ground_only(name));
        let (forest, meadow) = (mean_color(&image, &inside[&4]), mean_color(&image, &inside[&6]));
        let distance = forest.iter().zip(&meadow).map(|(a, b)| (a - b).powi(2)).sum::<f32>().sqrt();
        assert!(distance > 0.12, "{name}: forest {forest:?} and herbaceous {meadow:?} look alike");
        // Greener than it is red, and darker than the meadow.
        assert!(forest[1] > forest[0] && forest[1] < meadow[1], "{name}: forest {forest:?}, herbaceous {meadow:?}");
    }
}

#[test]
fn class_borders_are_outlined_where_the_style_asks() {
    let scene = Scene::load(&repo("data/boulder/scene.toml")).expect("sample scene");
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let dark = |image: &image::RgbaImage, pixels: &[(u32, u32)]| {
        pixels.iter().filter(|&&(x, y)| luminance(image.get_pixel(x, y)) < 0.35).count() as f64 / pixels.len() as f64
    };
    let outlined = Style { land_cover_outline: 1.0, ..ground_only("full_npr") };
    let plain = Style { land_cover_outline: 0.0, ..ground_only("full_npr") };
    let (with, _, borders) = classes_in_plan(&scene, &renderer, &outlined);
    let (without, _, _) = classes_in_plan(&scene, &renderer, &plain);
    assert!(borders.len() > 500, "the plan view crosses class borders");
    let (a, b) = (dark(&with, &borders), dark(&without, &borders));
    assert!(a > b + 0.1, "dark border pixels: {a:.3} with outlines, {b:.3} without");
}

/// A scene file over the DEM `dem` (under the repository's `data/`) with `terrain` added to
/// its `[terrain]` section, in a temporary directory; paths in `terrain` may use `{data}` for
/// the repository's `data/`.
fn scene_on(name: &str, dem: &str, terrain: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("landsketch-ground-cover-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let data = repo("data");
    let text = format!(
        "name = \"drape\"\n[terrain]\ndem = \"{}\"\n{}\n[camera]\nposition = [0.0, 0.0]\nyaw = 0.0\n",
        data.join(dem).display(),
        terrain.replace("{data}", &data.display().to_string())
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).expect("write scene");
    path
}

/// [`scene_on`] the sample scene's DEM.
fn scene_with(name: &str, terrain: &str) -> PathBuf {
    scene_on(name, "boulder/dem.tif", terrain)
}

fn load_error(name: &str, terrain: &str) -> String {
    Scene::load(&scene_with(name, terrain)).expect_err("a bad drape").to_string()
}

#[test]
fn bad_drapes_are_refused_naming_the_file() {
    // A class the land cover does not hold.
    let err = load_error(
        "unknown",
        "landcover = \"{data}/boulder/landcover.tif\"\nclasses = \"nlcd_simplified\"\n[terrain.cover.9]\nname = \"quarry\"",
    );
    assert!(
        err.contains("landcover.tif") && err.contains("class 9") && err.contains("its classes are 4, 5, 6"),
        "{err}"
    );
    // A key that is no class code, a stroke kind that does not exist.
    let err = load_error("key", "[terrain.cover.forest]\ntone = -0.3");
    assert!(err.contains("terrain.cover.forest") && err.contains("integer code"), "{err}");
    let err = load_error("strokes", "[terrain.cover.4]\nstrokes = \"zigzag\"");
    assert!(err.contains("scene.toml") && err.contains("zigzag"), "{err}");
    // An orthophoto of one band (the DEM itself), one stored plane by plane.
    let err = load_error("one-band", "orthophoto = \"{data}/boulder/dem.tif\"");
    assert!(err.contains("dem.tif") && err.contains("3 bands") && err.contains("has 1"), "{err}");
    let err = load_error("planar", "orthophoto = \"{data}/test/boulder_crop_2band_planar.tif\"");
    assert!(err.contains("boulder_crop_2band_planar.tif") && err.contains("plane by plane"), "{err}");
    // A land cover 1000 km away in the same CRS.
    let lc = landsketch::gis::load_raster(&repo("data/boulder/landcover.tif")).expect("land cover");
    let far = landsketch::gis::Raster {
        transform: landsketch::gis::GeoTransform { origin_x: lc.transform.origin_x + 10.0, ..lc.transform },
        ..lc
    };
    let far_path = scene_with("far", "").with_file_name("far.tif");
    landsketch::gis::write_geotiff_u8(&far_path, &far, None).expect("write far land cover");
    let err = load_error("far", &format!("landcover = \"{}\"", far_path.display()));
    assert!(err.contains("far.tif") && err.contains("does not overlap"), "{err}");
}

#[test]
fn an_orthophoto_colours_the_ground() {
    // Three bands over a window of the Boulder DEM (`data/test/README.md`): band 1 the
    // elevation (over 255: red saturates), bands 2 and 3 scaled to 0..40.
    let ortho = "orthophoto = \"{data}/test/boulder_crop_3band_pixel.tif\"";
    let path = scene_on("ortho", "test/boulder_crop_tiled_i16.tif", ortho);
    let scene = Scene::load(&path).expect("scene with an orthophoto");
    let drape = &scene.terrain.drape;
    assert!(drape.width > 1 && drape.classes.is_empty());
    let (lo, hi) = scene.terrain.bounds();
    let centre = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    let col = ((centre.0 - drape.origin[0]) / drape.cell) as usize;
    let row = ((drape.origin[1] - centre.1) / drape.cell) as usize;
    let [r, g, b] = drape.colors[row * drape.width + col];
    assert!(r == 255 && g <= 40 && b <= 40, "orthophoto colour ({r}, {g}, {b})");
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let camera = Camera::plan(centre.0 as f32, centre.1 as f32, 4000.0, 200.0);
    let image = renderer.render(FrameRequest::new(&camera, ground_only("photorealism"), 64, 64)).expect("render").image;
    let p = image.get_pixel(32, 32);
    assert!(p[0] > 2 * p[1].max(p[2]), "the ground takes the orthophoto's red: {p:?}");
}

#[test]
fn the_draped_ground_up_a_slope_and_in_plan_matches_its_references() {
    // The gallery's views (guide, "Rendering"): up a slope (`--pos 0,300 --yaw 90 --pitch 4`)
    // and the plan view (`--plan 0,0,2000`), in full_npr, half_npr and photorealism; the
    // default and bird's-eye views are `tests/reference/styles/preset_*.png` and
    // `tests/reference/sample_above.png`.
    let scene = Scene::load(&repo("data/boulder/scene.toml")).expect("sample scene");
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let ground = scene.terrain.height_at(0.0, 300.0).expect("on the DEM") as f32;
    let up_slope = Camera { position: [0.0, 300.0, ground + 1.7], yaw: 90.0, pitch: 4.0, ..scene.default_camera };
    let plan = Camera::plan(0.0, 0.0, 4000.0, 2000.0);
    let (w, h) = (192u32, 144u32);
    let mut sheet = image::RgbaImage::new(w * 3, h * 2);
    for (row, camera) in [up_slope, plan].iter().enumerate() {
        for (col, name) in ["full_npr", "half_npr", "photorealism"].iter().enumerate() {
            let style = preset(name).expect("preset");
            let image = renderer.render(FrameRequest::new(camera, style, w, h)).expect("render").image;
            image::imageops::replace(&mut sheet, &image, i64::from(w) * col as i64, i64::from(h) * row as i64);
        }
    }
    // Ink on the sketch of the slope, colour in the photoreal plan.
    let sketch = image::imageops::crop_imm(&sheet, 0, 0, w, h).to_image();
    assert!(common::fraction(&sketch, |l| l < 0.5) > 0.02, "the slope carries strokes");
    let photo = image::imageops::crop_imm(&sheet, 2 * w, h, w, h).to_image();
    let green = photo.pixels().filter(|p| p[1] > p[0] && p[1] > p[2]).count() as f32 / (w * h) as f32;
    assert!(green > 0.3, "the photoreal plan is {green:.2} green");
    common::assert_matches_reference(&sheet, &repo("tests/reference/ground_views.png"), 0.03);
}

#[test]
fn a_16_bit_orthophoto_is_scaled_to_the_drapes_bytes() {
    // Full red, half green, no blue in 16-bit samples, on the grid of a window of the DEM.
    let grid = landsketch::gis::load_raster(&repo("data/test/boulder_crop_tiled_i16.tif")).expect("grid");
    let band = |v: f64| landsketch::gis::Raster { data: vec![v; grid.data.len()], nodata: None, ..grid.clone() };
    let ortho = scene_with("ortho16", "").with_file_name("ortho16.tif");
    landsketch::gis::write_geotiff_rgb16(&ortho, &[band(65535.0), band(32768.0), band(0.0)]).expect("write");
    let path = scene_on("ortho16", "test/boulder_crop_tiled_i16.tif", &format!("orthophoto = \"{}\"", ortho.display()));
    let drape = Scene::load(&path).expect("scene with a 16-bit orthophoto").terrain.drape;
    let inside = drape.colors[(drape.height / 2) * drape.width + drape.width / 2];
    assert_eq!(inside, [255, 128, 0]);
}

#[test]
fn a_jpeg_compressed_ycbcr_orthophoto_colours_the_ground_in_rgb() {
    // An orthophoto as agencies ship them (and GDAL writes with COMPRESS=JPEG
    // PHOTOMETRIC=YCBCR): one JPEG strip of YCbCr samples, 4:2:0 chroma, over the sample
    // scene's DEM in EPSG:4326; the western half red, the eastern half green.
    use common::tiff::{LONG, SHORT, geographic_entries, longs, shorts, tiff_file};
    let (w, h) = (64u32, 48u32);
    let (red, green) = ([200u8, 40, 40], [40u8, 160, 60]);
    let rgb: Vec<u8> = (0..w * h).flat_map(|i| if i % w < w / 2 { red } else { green }).collect();
    let mut jpeg = Vec::new();
    jpeg_encoder::Encoder::new(&mut jpeg, 95)
        .encode(&rgb, w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
        .expect("JPEG");
    let e = landsketch::gis::load_raster(&repo("data/boulder/dem.tif")).expect("DEM").extent();
    let mut entries = vec![
        (256, LONG, 1, longs(&[w])),
        (257, LONG, 1, longs(&[h])),
        (258, SHORT, 3, shorts(&[8, 8, 8])),
        (259, SHORT, 1, shorts(&[7])),
        (262, SHORT, 1, shorts(&[6])),
        (273, LONG, 1, longs(&[common::tiff::DATA_OFFSET])),
        (277, SHORT, 1, shorts(&[3])),
        (278, LONG, 1, longs(&[h])),
        (279, LONG, 1, longs(&[jpeg.len() as u32])),
        (284, SHORT, 1, shorts(&[1])),
        (530, SHORT, 2, shorts(&[2, 2])),
    ];
    entries.extend(geographic_entries(w, h, e.min_x, e.min_y, e.max_x, e.max_y));
    let ortho = scene_with("ortho-jpeg", "").with_file_name("ortho-jpeg.tif");
    std::fs::write(&ortho, tiff_file(&jpeg, entries)).expect("write");
    let scene = Scene::load(&scene_with("ortho-jpeg", &format!("orthophoto = \"{}\"", ortho.display())))
        .expect("scene with a JPEG orthophoto");
    let drape = &scene.terrain.drape;
    let (lo, hi) = scene.terrain.bounds();
    let at = |fx: f64| {
        let (x, y) = (lo[0] + fx * (hi[0] - lo[0]), 0.5 * (lo[1] + hi[1]));
        let col = ((x - drape.origin[0]) / drape.cell) as usize;
        let row = ((drape.origin[1] - y) / drape.cell) as usize;
        drape.colors[row * drape.width + col]
    };
    let near = |a: [u8; 3], b: [u8; 3]| a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 8);
    assert!(near(at(0.25), red), "west {:?}, expected {red:?}", at(0.25));
    assert!(near(at(0.75), green), "east {:?}, expected {green:?}", at(0.75));
}

#[test]
fn the_lidar_villages_buildings_read_as_a_land_cover_class() {
    // The real Kingston St Mary DTM with its OpenStreetMap building footprints (tests only,
    // ../shared/data/SOURCES.md) as one class of the ground: built-up ground without strokes,
    // outlined.
    let shared = repo("../shared/data/kingston_st_mary");
    if !shared.join("dtm_1m.tif").exists() {
        eprintln!("../shared/data/kingston_st_mary not present; skipped");
        return;
    }
    let dir = std::env::temp_dir().join(format!("landsketch-ground-cover-{}-village", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let text = format!(
        "name = \"Kingston St Mary\"\n[terrain]\ndem = \"{dtm}\"\nlandcover = \"{buildings}\"\nclasses = \"nlcd_simplified\"\n\
         [terrain.landcover_options]\nclass = 2\ncell = 1.0\n[camera]\nposition = [0.0, 0.0]\nyaw = 0.0\n",
        dtm = shared.join("dtm_1m.tif").display(),
        buildings = shared.join("osm_buildings.wgs84.geojson").display()
    );
    std::fs::write(dir.join("scene.toml"), text).expect("write scene");
    let scene = Scene::load(&dir.join("scene.toml")).expect("the village with its buildings");
    let drape = &scene.terrain.drape;
    let built: Vec<usize> = (0..drape.class_of.len()).filter(|&i| drape.class_of[i] > 0).collect();
    // 401 footprints of some 100 m² each.
    assert!(built.len() > 20_000, "{} building cells", built.len());
    let centre = {
        let sum =
            built.iter().fold((0.0, 0.0), |(x, y), &i| (x + (i % drape.width) as f64, y + (i / drape.width) as f64));
        let n = built.len() as f64;
        [drape.origin[0] + (sum.0 / n + 0.5) * drape.cell, drape.origin[1] - (sum.1 / n + 0.5) * drape.cell]
            .map(|v| v as f32)
    };
    let renderer = Renderer::new(gpu(), &scene).expect("renderer");
    let style = Style { land_cover_outline: 1.0, terrain_creases: 0.0, ..preset("full_npr").expect("preset") };
    let (image, inside, borders) = classes_in_plan_at(&scene, &renderer, &style, centre, 300.0);
    assert!(inside.get(&2).is_some_and(|p| p.len() > 100) && borders.len() > 200, "the village is in the view");
    let dark = |pixels: &[(u32, u32)]| {
        pixels.iter().filter(|&&(x, y)| luminance(image.get_pixel(x, y)) < 0.35).count() as f64 / pixels.len() as f64
    };
    // Footprints are paper inside (no strokes) and outlined.
    assert!(dark(&inside[&2]) < 0.05, "{:.3} of the building pixels are dark", dark(&inside[&2]));
    assert!(dark(&borders) > 0.3, "{:.3} of the border pixels are dark", dark(&borders));
}
