//! Tonal art maps and silhouette art maps (thesis 5.2.3, 6.1; Praun et al. 2001): generation,
//! nesting, tone targets, stroke width across mips, tiling, PNG round trip and load errors.

use image::{GrayImage, RgbaImage};
use landsketch::render::artmaps::{
    ArtMapError, MIN_STROKE_MIP_SIZE, Sam, Tam, TamStyle, generate_sams, generate_tam, tone_target,
};
use std::sync::OnceLock;

const SIZE: u32 = 256;
const LEVELS: usize = 6;
const SEED: u64 = 11;

/// The default-sized TAM of every style, generated once per test binary.
fn tams() -> &'static [(TamStyle, Tam)] {
    static TAMS: OnceLock<Vec<(TamStyle, Tam)>> = OnceLock::new();
    TAMS.get_or_init(|| TamStyle::ALL.iter().map(|&s| (s, generate_tam(s, SIZE, LEVELS, SEED))).collect())
}

/// Darkness of a TAM pixel, 0 = paper, 1 = ink.
fn darkness(img: &GrayImage, x: u32, y: u32) -> f32 {
    1.0 - f32::from(img.get_pixel(x, y)[0]) / 255.0
}

/// Mean absolute difference between columns `a` and `b` (of `n` rows) of `value(x, y)`.
fn line_diff(n: u32, a: u32, b: u32, value: &dyn Fn(u32, u32) -> f32) -> f32 {
    (0..n).map(|i| (value(a, i) - value(b, i)).abs()).sum::<f32>() / n as f32
}

/// Checks that the wrap seam between the last and first column of a `w` × `h` image does not
/// stand out: its difference is within four standard deviations of the mean difference between
/// neighbouring columns inside. Returns that limit and the difference between two unrelated
/// columns (half the width apart), which must exceed it where columns along strokes correlate.
fn assert_seamless_columns(w: u32, h: u32, value: &dyn Fn(u32, u32) -> f32, what: &str) -> (f32, f32) {
    let seam = line_diff(h, w - 1, 0, value);
    let interior: Vec<f32> = (0..w - 1).map(|x| line_diff(h, x, x + 1, value)).collect();
    let mean = interior.iter().sum::<f32>() / interior.len() as f32;
    let sigma = (interior.iter().map(|d| (d - mean).powi(2)).sum::<f32>() / interior.len() as f32).sqrt();
    let limit = mean + 4.0 * sigma;
    assert!(seam <= limit, "{what}: seam difference {seam:.4} stands out (interior mean {mean:.4}, σ {sigma:.4})");
    (limit, line_diff(h, w / 2, 0, value))
}

#[test]
fn tam_generation_is_deterministic() {
    for &(style, ref tam) in tams() {
        assert_eq!(&generate_tam(style, SIZE, LEVELS, SEED), tam, "{style:?}: same seed, same pixels");
        let other = generate_tam(style, 64, 4, SEED + 1);
        assert_ne!(other, generate_tam(style, 64, 4, SEED), "{style:?}: another seed draws other strokes");
    }
    assert_eq!(generate_sams(128, 32, 5), generate_sams(128, 32, 5));
    assert_ne!(generate_sams(128, 32, 5), generate_sams(128, 32, 6));
}

#[test]
fn tam_shape_has_full_mip_chains() {
    for (style, tam) in tams() {
        assert_eq!(tam.size, SIZE);
        assert_eq!(tam.levels.len(), LEVELS, "{style:?}");
        for mips in &tam.levels {
            assert_eq!(mips.len(), SIZE.ilog2() as usize + 1, "{style:?}: mips down to 1×1");
            for (m, img) in mips.iter().enumerate() {
                assert_eq!(img.dimensions(), (SIZE >> m, SIZE >> m), "{style:?} mip {m}");
            }
        }
    }
}

#[test]
fn darker_tones_contain_every_stroke_of_lighter_ones() {
    for (style, tam) in tams() {
        for t in 0..LEVELS - 1 {
            for m in 0..tam.levels[t].len() {
                let (light, dark) = (&tam.levels[t][m], &tam.levels[t + 1][m]);
                let lighter = light.as_raw().iter().zip(dark.as_raw()).filter(|(l, d)| d > l).count();
                assert_eq!(lighter, 0, "{style:?}: tone {} mip {m} has pixels lighter than tone {t}", t + 1);
            }
        }
    }
}

/// A fully inked pixel of mip m+1 lies on a stroke, which is drawn in mip m too: the 4×4
/// pixels of mip m around the corresponding 2×2 block hold clearly visible ink.
#[test]
fn finer_mips_contain_every_stroke_of_coarser_ones() {
    let drawn = (SIZE / MIN_STROKE_MIP_SIZE).ilog2() as usize + 1;
    for (style, tam) in tams() {
        for (t, mips) in tam.levels.iter().enumerate() {
            for m in 0..drawn - 1 {
                let (fine, coarse) = (&mips[m], &mips[m + 1]);
                let n = fine.width() as i64;
                for (x, y, p) in coarse.enumerate_pixels().filter(|(_, _, p)| p[0] <= 2) {
                    let (cx, cy) = (2 * i64::from(x), 2 * i64::from(y));
                    let ink = (-1..3)
                        .flat_map(|dy| (-1..3).map(move |dx| (dx, dy)))
                        .map(|(dx, dy)| darkness(fine, (cx + dx).rem_euclid(n) as u32, (cy + dy).rem_euclid(n) as u32))
                        .fold(0.0f32, f32::max);
                    assert!(
                        ink >= 0.25,
                        "{style:?} tone {t}: ink at mip {} ({x},{y}) = {} but mip {m} has at most {ink} there",
                        m + 1,
                        p[0]
                    );
                }
            }
        }
    }
}

#[test]
fn mean_tones_increase_and_meet_their_targets() {
    for (style, tam) in tams() {
        for m in 0..tam.levels[0].len() {
            let tones: Vec<f32> = (0..LEVELS).map(|t| tam.mean_tone(t, m)).collect();
            for (t, &tone) in tones.iter().enumerate() {
                let target = tone_target(t, LEVELS);
                assert!((tone - target).abs() <= 0.05, "{style:?} mip {m}: tone {t} is {tone}, target {target}");
            }
            assert!(tones.windows(2).all(|w| w[0] < w[1]), "{style:?} mip {m}: tones {tones:?} do not increase");
        }
    }
    let targets: Vec<f32> = (0..LEVELS).map(|t| tone_target(t, LEVELS)).collect();
    assert!((targets[0] - 0.1).abs() < 1e-6 && (targets[LEVELS - 1] - 0.9).abs() < 1e-6, "{targets:?}");
}

/// Mean ink width of horizontal strokes in pixels: the darkness summed down each vertical run
/// of inked pixels, averaged over the runs.
fn mean_ink_width(img: &GrayImage) -> f32 {
    let (mut runs, mut total) = (0u32, 0.0f32);
    for x in 0..img.width() {
        let mut run = 0.0;
        for y in 0..=img.height() {
            let ink = if y < img.height() { darkness(img, x, y) } else { 0.0 };
            if ink > 0.05 {
                run += ink;
            } else if run > 0.0 {
                (runs, total, run) = (runs + 1, total + run, 0.0);
            }
        }
    }
    total / runs as f32
}

#[test]
fn strokes_keep_their_pixel_width_across_mips() {
    let (_, lines) = tams().iter().find(|(s, _)| *s == TamStyle::Lines).expect("lines TAM");
    for tone in 0..2 {
        let fine = mean_ink_width(&lines.levels[tone][0]);
        let coarse = mean_ink_width(&lines.levels[tone][2]);
        assert!((1.0..3.0).contains(&fine), "tone {tone}: stroke width {fine} px at mip 0");
        // Box-filtering would make them a quarter as wide at mip 2.
        assert!(
            (0.8..=1.25).contains(&(coarse / fine)),
            "tone {tone}: strokes are {fine:.2} px wide at mip 0 but {coarse:.2} px at mip 2"
        );
    }
}

#[test]
fn tams_tile_seamlessly() {
    for (style, tam) in tams() {
        for tone in [0, 2, 4] {
            for mip in [0, 2] {
                let img = &tam.levels[tone][mip];
                let n = img.width();
                let what = format!("{style:?} tone {tone} mip {mip}");
                let (limit, unrelated) =
                    assert_seamless_columns(n, n, &|x, y| darkness(img, x, y), &format!("{what} (columns)"));
                assert_seamless_columns(n, n, &|x, y| darkness(img, y, x), &format!("{what} (rows)"));
                if *style == TamStyle::Lines {
                    // Along horizontal strokes neighbouring columns match closely, so a seam that
                    // cut strokes would stand out like two unrelated columns do.
                    assert!(unrelated > 2.0 * limit, "{what}: the seam check cannot tell columns apart");
                }
            }
        }
    }
}

#[test]
fn sams_hold_four_distinct_tileable_variants_from_the_contour() {
    let sams = generate_sams(256, 32, SEED);
    assert!(sams.len() >= 4, "{} SAMs", sams.len());
    for (i, sam) in sams.iter().enumerate() {
        let img = &sam.image;
        assert_eq!(img.dimensions(), (256, 32), "SAM {i}");
        let channel = |c: usize| -> Vec<u8> { img.pixels().map(|p| p[c]).collect() };
        let coverage: Vec<f32> =
            (0..4).map(|c| channel(c).iter().map(|&v| f32::from(v)).sum::<f32>() / (255.0 * 256.0 * 32.0)).collect();
        for c in 0..4 {
            for d in c + 1..4 {
                assert_ne!(channel(c), channel(d), "SAM {i}: channels {c} and {d} are equal");
            }
            let row0 = (0..256).map(|x| img.get_pixel(x, 0)[c]).max().unwrap_or(0);
            assert!(row0 >= 128, "SAM {i} channel {c}: no ink on the contour row (max {row0})");
            assert_seamless_columns(256, 32, &|x, y| f32::from(img.get_pixel(x, y)[c]) / 255.0, &format!("SAM {i}"));
        }
        assert!(coverage.windows(2).all(|w| w[0] < w[1]), "SAM {i}: channels do not grow heavier: {coverage:?}");
    }
}

#[test]
fn png_strip_round_trips() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (_, tam) = &tams()[1];
    let strip = tam.to_png_strip();
    assert_eq!(strip.dimensions(), (SIZE * LEVELS as u32, SIZE));
    let path = dir.path().join("tam.png");
    strip.save(&path).expect("write strip");
    let loaded = Tam::from_png(&path, LEVELS).expect("load strip");
    assert_eq!(loaded.size, SIZE);
    assert_eq!(loaded.levels.len(), LEVELS);
    for (t, mips) in loaded.levels.iter().enumerate() {
        assert_eq!(mips[0], tam.levels[t][0], "tone {t} mip 0");
        assert_eq!(mips.len(), tam.levels[t].len(), "tone {t}: full mip chain");
        assert_eq!(mips.last().map(|m| m.dimensions()), Some((1, 1)));
        for m in 1..mips.len() {
            let (a, b) = (loaded.mean_tone(t, m), tam.mean_tone(t, m));
            assert!((a - b).abs() < 0.03, "tone {t} mip {m}: box-filtered mean {a} vs drawn {b}");
        }
    }

    let sam = &generate_sams(64, 16, SEED)[2];
    let sam_path = dir.path().join("sam.png");
    sam.image.save(&sam_path).expect("write SAM");
    assert_eq!(&Sam::from_png(&sam_path).expect("load SAM"), sam);
}

#[test]
fn loading_rejects_bad_files_naming_them() {
    let dir = tempfile::tempdir().expect("temp dir");
    let message = |e: ArtMapError| e.to_string();

    let odd = dir.path().join("odd_shape.png");
    GrayImage::new(100, 30).save(&odd).expect("write");
    let err = Tam::from_png(&odd, 3).expect_err("100×30 is no TAM strip");
    assert!(matches!(err, ArtMapError::Shape { width: 100, height: 30, .. }), "{err:?}");
    let text = message(err);
    assert!(text.contains("odd_shape.png") && text.contains("3 square tone images"), "{text}");

    let strip = dir.path().join("strip.png");
    GrayImage::new(6 * 32, 32).save(&strip).expect("write");
    assert!(Tam::from_png(&strip, 6).is_ok());
    let err = Tam::from_png(&strip, 5).expect_err("6 tones read as 5");
    assert!(message(err).contains("strip.png"));
    let not_pow2 = dir.path().join("not_pow2.png");
    GrayImage::new(3 * 48, 48).save(&not_pow2).expect("write");
    assert!(matches!(Tam::from_png(&not_pow2, 3), Err(ArtMapError::Shape { .. })));
    let tiny = dir.path().join("tiny.png");
    GrayImage::new(4 * 8, 8).save(&tiny).expect("write");
    assert!(matches!(Tam::from_png(&tiny, 4), Err(ArtMapError::Shape { .. })));

    let fake = dir.path().join("fake.png");
    std::fs::write(&fake, "not an image").expect("write");
    for err in [Tam::from_png(&fake, 1).expect_err("text"), Sam::from_png(&fake).expect_err("text")] {
        assert!(matches!(err, ArtMapError::NotPng { .. }), "{err:?}");
        assert!(message(err).contains("fake.png"));
    }
    let truncated = dir.path().join("truncated.png");
    std::fs::write(&truncated, b"\x89PNG\r\n\x1a\n\0\0").expect("write");
    let err = Sam::from_png(&truncated).expect_err("truncated");
    assert!(matches!(err, ArtMapError::Decode { .. }) && message(err).contains("truncated.png"));
    let missing = dir.path().join("missing.png");
    let err = Sam::from_png(&missing).expect_err("missing");
    assert!(matches!(err, ArtMapError::Io { .. }) && message(err).contains("missing.png"));

    let rgba = dir.path().join("rgba.png");
    RgbaImage::new(32, 8).save(&rgba).expect("write");
    assert_eq!(Sam::from_png(&rgba).expect("any PNG is a SAM").image.dimensions(), (32, 8));
}

#[test]
fn tam_style_serialises_in_snake_case() {
    assert_eq!(serde_json::to_string(&TamStyle::CrossHatch).expect("json"), "\"cross_hatch\"");
    let style: TamStyle = serde_json::from_str("\"stipple\"").expect("json");
    assert_eq!(style, TamStyle::Stipple);
}

#[test]
fn lines_and_cross_hatching_are_directional_stipples_and_scribbles_are_not() {
    for (style, tam) in tams() {
        let coherence = tam.direction_coherence();
        let expected = matches!(style, TamStyle::Lines | TamStyle::CrossHatch);
        assert_eq!(tam.directional(), expected, "{style:?}: coherence {coherence}");
    }
}
