//! Helpers shared by the image tests: a shared GPU, small synthetic scenes, reference
//! comparison with a tolerance and image statistics. (Each test binary uses a subset.)
#![allow(dead_code)]

pub mod server;
pub mod tiff;
pub mod ws;

use image::RgbaImage;
use landsketch::gis::{Crs, GeoTransform, Raster};
use landsketch::prep::lod::{LodLevel, LodSettings};
use landsketch::render::{Gpu, RenderOptions, Renderer};
use landsketch::scene::camera::Camera;
use landsketch::scene::procedural::{ProceduralKind, procedural_plant};
use landsketch::scene::terrain::Terrain;
use landsketch::scene::vegetation::PlantInstance;
use landsketch::scene::{Scene, Species, Sun, VegetationLayer};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// One GPU for all tests of a binary (lavapipe without a GPU).
pub fn gpu() -> Arc<Gpu> {
    static GPU: OnceLock<Arc<Gpu>> = OnceLock::new();
    GPU.get_or_init(|| Arc::new(Gpu::new().expect("a Vulkan adapter (lavapipe: apt-get install mesa-vulkan-drivers)")))
        .clone()
}

/// A renderer drawing every plant with its full model at every distance: for tests of the NPR
/// passes and styles, not of the levels of detail (`tests/lod.rs`).
pub fn full_detail(scene: &Scene) -> Renderer {
    let lod = LodSettings { force: Some(LodLevel::Full), ..LodSettings::default() };
    Renderer::with_options(gpu(), scene, &RenderOptions { lod, ..RenderOptions::default() }).expect("renderer")
}

/// A flat 200 m × 200 m terrain at 100 m with procedural broadleaf trees at `positions`
/// (x, y), lit from the zenith so that flat ground gets no hatching; the camera looks north
/// from (0, −30) at 105 m.
pub fn trees_on_a_plain(positions: &[[f32; 2]]) -> Scene {
    let n = 21;
    let dem = Raster {
        width: n,
        height: n,
        data: vec![100.0; n * n],
        nodata: None,
        transform: GeoTransform { origin_x: 500_000.0, origin_y: 4_400_000.0, cell_width: 10.0, cell_height: 10.0 },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    };
    let plants = positions
        .iter()
        .enumerate()
        .map(|(i, [x, y])| PlantInstance {
            species: 0,
            position: [*x, *y, 100.0],
            rotation: i as f32 * 1.3,
            scale: 1.0,
        })
        .collect();
    Scene {
        name: "plain".into(),
        terrain: Terrain::new(dem, [1.0; 3]).expect("terrain"),
        species: vec![Species::new("oak", procedural_plant(ProceduralKind::Broadleaf, 1))],
        layers: vec![VegetationLayer { name: "test".into(), plants }],
        sun: Sun { azimuth: 0.0, elevation: 90.0 },
        default_camera: Camera::perspective([0.0, -30.0, 105.0], 0.0, 0.0, 60.0),
        about: Default::default(),
    }
}

/// Per-channel difference (0..255) above which a pixel counts as an outlier.
pub const PIXEL_TOLERANCE: u8 = 64;

/// Luminance of an sRGB pixel in 0..1 (Rec. 709 weights on the encoded values).
pub fn luminance(p: &image::Rgba<u8>) -> f32 {
    (0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2])) / 255.0
}

/// Fraction of pixels whose luminance satisfies `pred`.
pub fn fraction(image: &RgbaImage, pred: impl Fn(f32) -> bool) -> f64 {
    image.pixels().filter(|p| pred(luminance(p))).count() as f64 / f64::from(image.width() * image.height())
}

fn sibling(reference: &Path, suffix: &str) -> PathBuf {
    let stem = reference.file_stem().and_then(|s| s.to_str()).unwrap_or("image");
    std::env::temp_dir().join("landsketch-test-images").join(format!("{stem}-{suffix}.png"))
}

/// Compares `actual` with the reference PNG: a pixel is an outlier when any channel differs by
/// more than [`PIXEL_TOLERANCE`]; the test fails when more than `max_outlier_fraction` of the
/// pixels are outliers. On failure the actual image and a diff image (outliers red) are
/// written to `$TMPDIR/landsketch-test-images/` and named in the panic message.
/// `LANDSKETCH_UPDATE_REFERENCES=1` rewrites the reference instead.
/// The share of pixels of `actual` that differ from `expected` (same size) by more than
/// [`PIXEL_TOLERANCE`] in a channel, and a diff image (outliers red, the rest grey by difference).
pub fn outliers(actual: &RgbaImage, expected: &RgbaImage) -> (f64, RgbaImage) {
    let mut diff = RgbaImage::new(actual.width(), actual.height());
    let mut count = 0usize;
    for ((a, e), d) in actual.pixels().zip(expected.pixels()).zip(diff.pixels_mut()) {
        let worst = (0..3).map(|c| a[c].abs_diff(e[c])).max().unwrap_or(0);
        *d = if worst > PIXEL_TOLERANCE {
            count += 1;
            image::Rgba([255, 0, 0, 255])
        } else {
            let g = 255 - worst * 3;
            image::Rgba([g, g, g, 255])
        };
    }
    (count as f64 / f64::from(actual.width() * actual.height()), diff)
}

pub fn assert_matches_reference(actual: &RgbaImage, reference: &Path, max_outlier_fraction: f64) {
    if std::env::var_os("LANDSKETCH_UPDATE_REFERENCES").is_some() {
        actual.save(reference).expect("write reference");
        return;
    }
    let expected = image::open(reference)
        .unwrap_or_else(|e| {
            panic!("cannot open reference {}: {e} (set LANDSKETCH_UPDATE_REFERENCES=1)", reference.display())
        })
        .to_rgba8();
    assert_eq!(expected.dimensions(), actual.dimensions(), "image size differs from {}", reference.display());
    let (share, diff) = outliers(actual, &expected);
    if share > max_outlier_fraction {
        let (actual_path, diff_path) = (sibling(reference, "actual"), sibling(reference, "diff"));
        std::fs::create_dir_all(actual_path.parent().expect("temp dir")).expect("create output dir");
        actual.save(&actual_path).expect("write actual");
        diff.save(&diff_path).expect("write diff");
        panic!(
            "{:.3}% of pixels differ from {} by more than {PIXEL_TOLERANCE} (allowed {:.3}%); see {} and {}",
            share * 100.0,
            reference.display(),
            max_outlier_fraction * 100.0,
            actual_path.display(),
            diff_path.display()
        );
    }
}
