//! S1 terrain input: GeoTIFF / ESRI ASCII grid loading, georeferencing, CRS, local frame and
//! bad-input errors, against the fixtures in `data/test/` (see `data/test/README.md`).

mod common;

use std::io::Cursor;
use std::path::{Path, PathBuf};

use landsketch::gis::{
    Crs, Extent, GeoTransform, GisError, LocalFrame, Raster, load_dem, load_raster, read_ascii_grid, read_geotiff,
    write_geotiff_f32, write_geotiff_u8,
};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/test").join(name)
}

fn load(name: &str) -> Raster {
    load_raster(&fixture(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

const WGS84: Crs = Crs::Geographic { epsg: Some(4326) };

/// The Boulder DEM window all `boulder_crop_*` fixtures were cut from (`-srcwin 100 60 20 16`).
const CROP: (usize, usize, usize, usize) = (100, 60, 20, 16);

fn assert_transform_close(a: &GeoTransform, b: &GeoTransform, tol: f64) {
    assert!(
        (a.origin_x - b.origin_x).abs() < tol
            && (a.origin_y - b.origin_y).abs() < tol
            && (a.cell_width - b.cell_width).abs() < tol
            && (a.cell_height - b.cell_height).abs() < tol,
        "{a:?} vs {b:?}"
    );
}

fn assert_same_cells(a: &Raster, b: &Raster) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    for row in 0..a.height {
        for col in 0..a.width {
            assert_eq!(a.get(col, row), b.get(col, row), "cell ({col}, {row})");
        }
    }
}

#[test]
fn boulder_asc_and_tif_agree_cell_by_cell() {
    let tif = load("boulder_SRTMGL3_derived.tif");
    let mut asc = load("boulder_SRTMGL3.asc");
    assert_eq!(asc.crs, Crs::Unspecified, "the .asc has no .prj");
    asc.crs = "EPSG:4326".parse().unwrap();

    assert_eq!((tif.width, tif.height), (240, 144));
    assert_eq!(tif.data, asc.data);
    assert_eq!(tif.nodata, Some(0.0));
    assert_eq!(asc.nodata, Some(0.0));
    assert_transform_close(&tif.transform, &asc.transform, 1e-9);
    assert_eq!(tif.crs, WGS84);
    assert_eq!(asc.crs, tif.crs);
    assert!(tif.palette.is_none());
}

#[test]
fn boulder_known_values_extent_and_range() {
    let r = load("boulder_SRTMGL3_derived.tif");
    // First row of the .asc text: 2569 2569 2573 …; others from `gdallocationinfo`.
    for (col, row, v) in [
        (0, 0, 2569.0),
        (1, 0, 2569.0),
        (2, 0, 2573.0),
        (0, 1, 2591.0),
        (1, 1, 2597.0),
        (100, 60, 2490.0),
        (119, 75, 2635.0),
        (57, 131, 2788.0),
        (239, 143, 2028.0),
    ] {
        assert_eq!(r.get(col, row), Some(v), "cell ({col}, {row})");
    }
    assert_eq!(r.get(240, 0), None);
    assert_eq!(r.valid_range(), Some((1943.0, 3286.0)));

    let e = r.extent();
    let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
    assert!(close(e.min_x, -105.550416666684), "{e:?}");
    assert!(close(e.min_y, 40.090416666671), "{e:?}");
    assert!(close(e.max_x, -105.550416666684 + 240.0 * 0.000833333333), "{e:?}");
    assert!(close(e.max_y, 40.090416666671 + 144.0 * 0.000833333333), "{e:?}");
    let (cx, cy) = r.cell_center(0, 0);
    assert!(close(cx, -105.550416666684 + 0.5 * 0.000833333333));
    assert!(close(cy, e.max_y - 0.5 * 0.000833333333));
}

#[test]
fn boulder_sampling_by_hand() {
    let r = load("boulder_SRTMGL3_derived.tif");
    let t = r.transform;
    // A quarter of the way from the centre of cell (0, 0) to (1, 0), half way down to row 1:
    // 0.375·2569 + 0.125·2569 + 0.375·2591 + 0.125·2597 = 2580.75.
    let x = t.origin_x + 0.75 * t.cell_width;
    let y = t.origin_y - 1.0 * t.cell_height;
    let v = r.sample_bilinear(x, y).unwrap();
    assert!((v - 2580.75).abs() < 1e-6, "{v}");
    // At a cell centre bilinear and nearest agree with the cell.
    let (cx, cy) = r.cell_center(100, 60);
    assert_eq!(r.sample_nearest(cx, cy), Some(2490.0));
    assert!((r.sample_bilinear(cx, cy).unwrap() - 2490.0).abs() < 1e-6);
    // Nearest picks the containing cell.
    assert_eq!(r.sample_nearest(t.origin_x + 2.9 * t.cell_width, t.origin_y - 0.1 * t.cell_height), Some(2573.0));
    // Outside the extent.
    let e = r.extent();
    assert_eq!(r.sample_nearest(e.min_x - 1e-6, cy), None);
    assert_eq!(r.sample_bilinear(cx, e.max_y + 1e-6), None);
    // Between the last centre and the east edge: clamped to the last column.
    let (lx, ly) = r.cell_center(239, 143);
    assert_eq!(r.sample_bilinear(e.max_x, ly), Some(2028.0));
    assert_eq!(r.sample_bilinear(lx, ly), Some(2028.0));
}

/// The `boulder_crop_*` fixtures: one window of the Boulder DEM in every sample layout.
const CROP_FIXTURES: [&str; 10] = [
    "boulder_crop_tiled_i16.tif",
    "boulder_crop_u16_lzw.tif",
    "boulder_crop_f32_fpredict.tif",
    "boulder_crop_f64.tif",
    "boulder_crop_i32_bigendian.tif",
    "boulder_crop_f32_bigendian_tiled.tif",
    "boulder_crop_u32_packbits.tif",
    "boulder_crop_pixelispoint.tif",
    "boulder_crop_3band_pixel.tif",
    "boulder_crop_2band_planar.tif",
];

#[test]
fn crop_fixtures_match_the_full_dem() {
    let full = load("boulder_SRTMGL3_derived.tif");
    let window = full.crop(CROP.0, CROP.1, CROP.2, CROP.3).unwrap();
    assert_eq!(window.get(0, 0), Some(2490.0));
    for name in CROP_FIXTURES {
        let r = load(name);
        assert_same_cells(&r, &window);
        assert_transform_close(&r.transform, &window.transform, 1e-9);
        assert_eq!(r.crs, WGS84, "{name}");
        assert_eq!(r.nodata, Some(0.0), "{name}");
    }
}

#[test]
fn windows_of_every_layout_read_only_their_chunks_and_match_the_whole_file() {
    // Every sample layout (strips, tiles with partial tiles, predictors, big-endian, planar,
    // three bands) read through the windowed reader: whole, and a window across chunk
    // borders, equal the whole file read at once and cropped.
    let window = Extent { min_x: -105.4595, min_y: 40.1390, max_x: -105.4555, max_y: 40.1420 };
    for name in CROP_FIXTURES.into_iter().chain(["boulder_SRTMGL3_derived.tif", "zion_nlcd2011_simplified.tif"]) {
        let whole = load(name);
        let read = load_dem(&fixture(name), None, u64::MAX).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same_cells(&read, &whole);
        assert_transform_close(&read.transform, &whole.transform, 1e-12);
        if let Some((col, row, w, h)) = whole.window_of(&window) {
            let expected = whole.crop(col, row, w, h).unwrap();
            let read = load_dem(&fixture(name), Some(&window), u64::MAX).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_same_cells(&read, &expected);
            assert_transform_close(&read.transform, &expected.transform, 1e-12);
        }
    }
    let err = load_dem(
        &fixture("boulder_crop_f64.tif"),
        Some(&Extent { min_x: 0.0, min_y: 0.0, max_x: 1.0, max_y: 1.0 }),
        u64::MAX,
    )
    .unwrap_err();
    assert!(matches!(err, GisError::WindowOutside { .. }), "{err}");
    assert!(err.to_string().contains("boulder_crop_f64.tif") && err.to_string().contains("does not overlap"), "{err}");
}

/// A tiled Float32 GeoTIFF (EPSG:4326, 16 × 16 tiles, uncompressed) of `full` and its
/// overview by 2 (a COG's layout); the tiles listed in `broken` of the full image point past
/// the end of the file, and with `broken_full` every full-resolution tile does.
fn cog(full: &Raster, broken: &[usize], broken_full: bool) -> Vec<u8> {
    use common::tiff::{DATA_OFFSET, DOUBLE, Entry, LONG, SHORT, doubles, longs, shorts, tiff_images};
    let overview = full.decimate(2);
    let mut data = Vec::new();
    let mut images: Vec<Vec<Entry>> = Vec::new();
    for (level, r) in [full, &overview].into_iter().enumerate() {
        let (across, down) = (r.width.div_ceil(16), r.height.div_ceil(16));
        let (mut offsets, mut counts) = (Vec::new(), Vec::new());
        for tile in 0..across * down {
            let (tx, ty) = (tile % across * 16, tile / across * 16);
            let bytes: Vec<u8> = (0..256)
                .flat_map(|i| {
                    let (x, y) = (tx + i % 16, ty + i / 16);
                    let v = if x < r.width && y < r.height { r.data[y * r.width + x] as f32 } else { 0.0 };
                    v.to_le_bytes()
                })
                .collect();
            let bad = level == 0 && (broken_full || broken.contains(&tile));
            offsets.push(if bad { 0x7fff_0000 } else { DATA_OFFSET + data.len() as u32 });
            counts.push(bytes.len() as u32);
            data.extend_from_slice(&bytes);
        }
        let n = offsets.len() as u32;
        let mut entries = vec![
            (254, LONG, 1, longs(&[u32::from(level > 0)])),
            (256, LONG, 1, longs(&[r.width as u32])),
            (257, LONG, 1, longs(&[r.height as u32])),
            (258, SHORT, 1, shorts(&[32])),
            (259, SHORT, 1, shorts(&[1])),
            (262, SHORT, 1, shorts(&[1])),
            (277, SHORT, 1, shorts(&[1])),
            (284, SHORT, 1, shorts(&[1])),
            (322, LONG, 1, longs(&[16])),
            (323, LONG, 1, longs(&[16])),
            (324, LONG, n, longs(&offsets)),
            (325, LONG, n, longs(&counts)),
            (339, SHORT, 1, shorts(&[3])),
        ];
        if level == 0 {
            let t = r.transform;
            entries.push((33550, DOUBLE, 3, doubles(&[t.cell_width, t.cell_height, 0.0])));
            entries.push((33922, DOUBLE, 6, doubles(&[0.0, 0.0, 0.0, t.origin_x, t.origin_y, 0.0])));
            entries.push((34735, SHORT, 8, shorts(&[1, 1, 0, 1, 2048, 0, 1, 4326])));
        }
        images.push(entries);
    }
    tiff_images(&data, images)
}

#[test]
fn a_cloud_optimized_geotiff_is_read_by_its_window_and_overview_only() {
    // 40 × 36 cells of the Boulder DEM: 3 × 3 tiles of 16 at full resolution, 2 × 2 in the overview.
    let full = load("boulder_SRTMGL3_derived.tif").crop(60, 40, 40, 36).unwrap();
    let full = Raster { nodata: None, ..full };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cog.tif");
    // Every tile but the north-west one is unreadable: a window inside it still loads.
    std::fs::write(&path, cog(&full, &(1..9).collect::<Vec<_>>(), false)).unwrap();
    let (x0, y0) = full.transform.to_crs(2.0, 3.0);
    let (x1, y1) = full.transform.to_crs(14.0, 15.0);
    let window = Extent { min_x: x0 + 1e-9, min_y: y1 + 1e-9, max_x: x1 - 1e-9, max_y: y0 - 1e-9 };
    let read = load_dem(&path, Some(&window), u64::MAX).unwrap_or_else(|e| panic!("{e}"));
    assert_same_cells(&read, &Raster { nodata: None, ..full.crop(2, 3, 12, 12).unwrap() });
    let err = load_dem(&path, None, u64::MAX).unwrap_err();
    assert!(err.to_string().contains("cog.tif"), "a whole read touches the broken tiles: {err}");
    // Every full-resolution tile unreadable: a budget of a quarter of the cells reads the
    // overview, whose cells are the 2 × 2 means, on the full extent.
    std::fs::write(&path, cog(&full, &[], true)).unwrap();
    let coarse = load_dem(&path, None, (20 * 18) as u64).unwrap_or_else(|e| panic!("{e}"));
    let expected = full.decimate(2);
    assert_eq!((coarse.width, coarse.height), (20, 18));
    for (a, b) in coarse.data.iter().zip(&expected.data) {
        assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    }
    assert_transform_close(&coarse.transform, &expected.transform, 1e-12);
    // A budget between the levels: the overview, averaged down further to fit.
    let smaller = load_dem(&path, None, 100).unwrap_or_else(|e| panic!("{e}"));
    assert!(smaller.width * smaller.height <= 100, "{} × {}", smaller.width, smaller.height);
    // 40 × 36 by 4 fits 100 cells: the overview by 2, averaged by 2 again (4 × 4 means).
    assert_eq!((smaller.width, smaller.height), (10, 9));
    for (a, b) in smaller.data.iter().zip(&full.decimate(4).data) {
        assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    }
}

#[test]
fn utm_fixture_is_projected_with_known_values() {
    let r = load("boulder_utm13n_f32.tif");
    assert_eq!(r.crs, Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 });
    assert_eq!((r.width, r.height), (19, 18));
    assert_eq!(r.nodata, Some(-9999.0));
    assert_transform_close(
        &r.transform,
        &GeoTransform { origin_x: 459495.7317108921, origin_y: 4443717.306473893, cell_width: 90.0, cell_height: 90.0 },
        1e-6,
    );
    // Values from `gdallocationinfo` (printed with 15 significant digits).
    assert_eq!(r.get(0, 0), Some(2562.52490234375));
    assert!((r.get(5, 5).unwrap() - 2710.52221679688).abs() < 1e-9);
    assert!((r.sample_nearest(460000.0, 4443000.0).unwrap() - 2708.595703125).abs() < 1e-9);
    let (lo, hi) = r.valid_range().unwrap();
    assert!(lo > 1943.0 && hi < 3286.0, "{lo}..{hi}");

    // The local frame is a translation: neighbouring cell centres are 90 m apart.
    let frame = LocalFrame::for_raster(&r).unwrap();
    let (ax, ay) = r.cell_center(3, 4);
    let (bx, by) = r.cell_center(4, 5);
    let (a, b) = (frame.to_local(ax, ay), frame.to_local(bx, by));
    assert!((b.0 - a.0 - 90.0).abs() < 1e-9 && (a.1 - b.1 - 90.0).abs() < 1e-9);
}

/// NLCD class colours of the simplified Zion land cover, entries 1..=8 (from `gdalinfo`).
const ZION_PALETTE: [[u8; 3]; 8] = [
    [71, 107, 160],
    [170, 0, 0],
    [178, 173, 163],
    [104, 170, 99],
    [165, 140, 48],
    [201, 201, 119],
    [219, 216, 61],
    [186, 216, 234],
];

#[test]
fn palette_land_cover_loads_label_indices() {
    let r = load("zion_nlcd2011_simplified.tif");
    assert_eq!((r.width, r.height), (1073, 1359));
    assert_eq!(r.crs, Crs::Projected { epsg: Some(26912), unit_to_metre: 1.0 });
    assert_eq!(r.nodata, Some(255.0));
    let palette = r.palette.as_ref().expect("palette");
    assert_eq!(palette.len(), 256);
    assert_eq!(palette[0], [255, 255, 255]);
    assert_eq!(&palette[1..=8], &ZION_PALETTE);

    // Class histogram from `gdalinfo -hist`; there are no nodata cells.
    let mut counts = [0usize; 9];
    for &v in &r.data {
        assert!(v.fract() == 0.0 && (1.0..=8.0).contains(&v), "label {v}");
        counts[v as usize] += 1;
    }
    assert_eq!(counts, [0, 1209, 17517, 106070, 767537, 545771, 4878, 8728, 6497]);
    assert_eq!(r.get(300, 300), Some(5.0));
    assert_eq!(r.get(500, 600), Some(4.0));
    assert!((r.transform.origin_x - 301903.344386758).abs() < 1e-6);
    assert!((r.transform.cell_height - 31.52465870178793).abs() < 1e-9);
}

#[test]
fn user_defined_projected_geokeys_have_no_epsg() {
    let r = load("zion_nlcd2011_userdefined_crop.tif");
    assert_eq!(r.crs, Crs::Projected { epsg: None, unit_to_metre: 1.0 });
    assert_eq!((r.width, r.height), (24, 16));
    assert_eq!(r.get(0, 0), Some(42.0));
    assert_eq!(r.get(23, 15), Some(41.0));
    assert!(r.palette.is_some());
    assert!((r.transform.origin_x - 317668.4934991513).abs() < 1e-6);
    assert!((r.transform.origin_y - 4135171.676943077).abs() < 1e-6);
}

#[test]
fn local_frame_round_trip_and_distances() {
    let dem = load("boulder_SRTMGL3_derived.tif");
    let frame = LocalFrame::for_raster(&dem).unwrap();
    let (x0, y0) = frame.origin_crs();
    let (cx, cy) = dem.extent().center();
    assert_eq!((x0, y0), (cx, cy));
    assert_eq!(frame.crs(), &WGS84);
    let e = dem.extent();
    for (x, y) in [(e.min_x, e.min_y), (e.max_x, e.max_y), (cx, cy), (-105.4, 40.1)] {
        let (lx, ly) = frame.to_local(x, y);
        let (bx, by) = frame.to_crs(lx, ly);
        assert!((bx - x).abs() < 1e-12 && (by - y).abs() < 1e-12);
    }
    // The DEM spans 0.2° × 0.12° about 40.15°N: ≈ 17.04 km × 13.32 km.
    let (w, _) = frame.to_local(e.max_x, y0);
    let (_, h) = frame.to_local(x0, e.max_y);
    assert!((w - 8_520.6).abs() < 0.1, "half width {w}");
    assert!((h - 6_662.3).abs() < 0.1, "half height {h}");

    // On the WGS 84 ellipsoid at 40°N: 1″ of latitude = 30.843 m, 0.001° of longitude = 85.394 m.
    let at40 = LocalFrame::new(WGS84, -105.0, 40.0).unwrap();
    let (_, north) = at40.to_local(-105.0, 40.0 + 1.0 / 3600.0);
    assert!((north - 30.843).abs() < 1e-3, "{north}");
    let (east, _) = at40.to_local(-105.0 + 0.001, 40.0);
    assert!((east - 85.394).abs() < 1e-3, "{east}");
}

#[test]
fn local_frame_needs_a_crs() {
    let asc = load("boulder_SRTMGL3.asc");
    let err = LocalFrame::for_raster(&asc).unwrap_err();
    assert!(matches!(err, GisError::UnspecifiedCrs));
    assert!(err.to_string().contains("crs = \"EPSG:4326\""), "{err}");
}

#[test]
fn asc_with_prj_and_center_header() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture("boulder_SRTMGL3.asc")).unwrap();
    let asc = dir.path().join("dem.asc");
    std::fs::write(&asc, &text).unwrap();
    std::fs::write(
        dir.path().join("dem.prj"),
        r#"GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]"#,
    )
    .unwrap();
    let with_prj = read_ascii_grid(&asc).unwrap();
    assert_eq!(with_prj.crs, WGS84);

    // The same grid with centre coordinates and lower-case keys.
    let centred = text
        .replace("xllcorner    -105.550416666684", "xllcenter -105.550000000017")
        .replace("yllcorner    40.090416666671", "YLLCENTER 40.090833333337")
        .replace("NODATA_value", "nodata_value");
    let path = dir.path().join("centred.asc");
    std::fs::write(&path, centred).unwrap();
    let r = read_ascii_grid(&path).unwrap();
    assert_eq!(r.crs, Crs::Unspecified);
    assert_transform_close(&r.transform, &with_prj.transform, 1e-9);
    assert_eq!(r.data, with_prj.data);
}

/// Asserts that loading `path` fails, that the message names the file, and returns the error.
fn load_err(path: &Path) -> GisError {
    let err = load_raster(path).expect_err("load should fail");
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(err.to_string().contains(name), "message does not name {name}: {err}");
    err
}

#[test]
fn bad_tiffs_give_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();

    let err = load_err(&dir.path().join("missing.tif"));
    assert!(matches!(err, GisError::Io { .. }), "{err}");
    assert!(err.to_string().contains("cannot read"), "{err}");

    let fake = dir.path().join("fake.tif");
    std::fs::write(&fake, "ncols 3\nnrows 3\n").unwrap();
    assert!(matches!(load_err(&fake), GisError::NotTiff { .. }));
    let empty = dir.path().join("empty.tiff");
    std::fs::write(&empty, "").unwrap();
    assert!(matches!(load_err(&empty), GisError::NotTiff { .. }));

    let err = load_err(&fixture("no_georef.tif"));
    assert!(matches!(err, GisError::NoGeoreferencing { .. }), "{err}");
    assert!(err.to_string().contains("no georeferencing"), "{err}");

    let err = load_err(&fixture("complex_cint16.tif"));
    assert!(matches!(err, GisError::UnsupportedSampleType { .. }), "{err}");
    assert!(err.to_string().contains("complex integer"), "{err}");

    let err = load_err(&fixture("all_nodata.tif"));
    assert!(matches!(err, GisError::AllNodata { .. }), "{err}");
    assert!(err.to_string().contains("every cell is nodata"), "{err}");

    // A truncated file: valid header, data cut off.
    let bytes = std::fs::read(fixture("boulder_SRTMGL3_derived.tif")).unwrap();
    let truncated = dir.path().join("truncated.tif");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    load_err(&truncated);
    std::fs::write(&truncated, &bytes[..12]).unwrap();
    load_err(&truncated);

    let err = load_err(&dir.path().join("dem.png"));
    assert!(matches!(err, GisError::UnknownFormat { .. }), "{err}");
}

/// A minimal little-endian TIFF declaring `width × height` 8-bit pixels in one strip.
fn tiff_header_only(width: u32, height: u32) -> Vec<u8> {
    let entries: [(u16, u16, u32); 7] = [
        (256, 4, width),  // ImageWidth, LONG
        (257, 4, height), // ImageLength
        (258, 3, 8),      // BitsPerSample, SHORT
        (262, 3, 1),      // PhotometricInterpretation = BlackIsZero
        (273, 4, 8),      // StripOffsets
        (278, 4, height), // RowsPerStrip
        (279, 4, 1),      // StripByteCounts
    ];
    let mut b = b"II*\0".to_vec();
    b.extend(8u32.to_le_bytes());
    b.extend((entries.len() as u16).to_le_bytes());
    for (tag, ty, value) in entries {
        b.extend(tag.to_le_bytes());
        b.extend(ty.to_le_bytes());
        b.extend(1u32.to_le_bytes());
        if ty == 3 {
            b.extend((value as u16).to_le_bytes());
            b.extend([0, 0]);
        } else {
            b.extend(value.to_le_bytes());
        }
    }
    b.extend(0u32.to_le_bytes());
    b
}

#[test]
fn absurd_tiff_dimensions_are_rejected_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.tif");
    std::fs::write(&path, tiff_header_only(100_000, 100_000)).unwrap();
    let err = load_err(&path);
    assert!(matches!(err, GisError::TooLarge { .. }), "{err}");
}

#[test]
fn bad_ascii_grids_give_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let head = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 10\n";
    let cases: [(&str, String, Option<usize>); 9] = [
        ("bad_value.asc", format!("{head}1 2 3\n4 x 6\n"), Some(7)),
        ("too_few.asc", format!("{head}1 2 3\n4 5\n"), Some(7)),
        ("too_many.asc", format!("{head}1 2 3\n4 5 6\n7\n"), Some(8)),
        ("bad_key.asc", "ncols 3\nrows 2\n".to_string(), Some(2)),
        ("no_ncols.asc", "nrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n".to_string(), Some(5)),
        ("zero_size.asc", "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 0\n1 2 3 4 5 6\n".to_string(), Some(5)),
        ("negative.asc", "ncols -3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n".to_string(), Some(1)),
        ("huge.asc", "ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n".to_string(), None),
        ("nodata.asc", format!("{head}NODATA_value -9999\n-9999 -9999 -9999\n-9999 -9999 -9999\n"), None),
    ];
    for (name, text, line) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let err = load_err(&path);
        match (line, &err) {
            (Some(expected), GisError::AsciiGrid { line, .. }) => assert_eq!(*line, expected, "{name}: {err}"),
            (Some(_), _) => panic!("{name}: expected a line error, got {err}"),
            (None, _) => {}
        }
        if let Some(n) = line {
            assert!(err.to_string().contains(&format!("line {n}:")), "{err}");
        }
    }
    let huge = load_err(&dir.path().join("huge.asc"));
    assert!(matches!(huge, GisError::TooLarge { .. }), "{huge}");
    let nodata = load_err(&dir.path().join("nodata.asc"));
    assert!(matches!(nodata, GisError::AllNodata { .. }), "{nodata}");
    let binary = dir.path().join("binary.asc");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x80]).unwrap();
    load_err(&binary);
}

#[test]
fn written_geotiffs_read_back() {
    let dir = tempfile::tempdir().unwrap();

    // Float32 DEM window.
    let dem = load("boulder_SRTMGL3_derived.tif").crop(CROP.0, CROP.1, CROP.2, CROP.3).unwrap();
    let path = dir.path().join("dem.tif");
    write_geotiff_f32(&path, &dem).unwrap();
    let back = read_geotiff(&path).unwrap();
    assert_eq!(back.data, dem.data);
    assert_eq!(back.transform, dem.transform);
    assert_eq!(back.crs, dem.crs);
    assert_eq!(back.nodata, dem.nodata);

    // A projected CRS in US survey feet without EPSG code, with NaN holes and no nodata value.
    let mut feet = dem.clone();
    feet.crs = Crs::Projected { epsg: None, unit_to_metre: 1200.0 / 3937.0 };
    feet.nodata = None;
    feet.data[3] = f64::NAN;
    write_geotiff_f32(&path, &feet).unwrap();
    let back = read_geotiff(&path).unwrap();
    assert_eq!(back.crs, feet.crs);
    assert_eq!(back.get(3, 0), None);
    assert_eq!(back.get(4, 0), feet.get(4, 0));

    // 8-bit palette land cover.
    let zion = load("zion_nlcd2011_simplified.tif").crop(400, 500, 30, 20).unwrap();
    let palette = zion.palette.clone().unwrap();
    let path = dir.path().join("landcover.tif");
    write_geotiff_u8(&path, &zion, Some(&palette)).unwrap();
    let back = read_geotiff(&path).unwrap();
    assert_eq!(back.data, zion.data);
    assert_eq!(back.palette.as_ref(), Some(&palette));
    assert_eq!(back.crs, zion.crs);
    assert_eq!(back.nodata, Some(255.0));
    assert_eq!(back.transform, zion.transform);

    // Plain 8-bit without palette; an unspecified CRS is written without GeoKeys.
    let mut plain = zion.clone();
    plain.crs = Crs::Unspecified;
    write_geotiff_u8(&path, &plain, None).unwrap();
    let back = read_geotiff(&path).unwrap();
    assert_eq!(back.data, zion.data);
    assert!(back.palette.is_none());
    assert_eq!(back.crs, Crs::Unspecified);

    // Values that do not fit 8 bits are refused, naming the file.
    let err = write_geotiff_u8(&path, &dem, None).unwrap_err();
    assert!(matches!(err, GisError::Write { .. }), "{err}");
    assert!(err.to_string().contains("landcover.tif"), "{err}");
}

/// Writes a GeoTIFF with the `tiff` encoder directly: `C` samples, a ModelTransformation and
/// a geographic WGS 84 GeoKey directory.
fn write_with_matrix<C: tiff::encoder::colortype::ColorType>(path: &Path, w: u32, h: u32, data: &[C::Inner])
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    use tiff::tags::Tag;
    let mut buf = Cursor::new(Vec::new());
    let mut enc = tiff::encoder::TiffEncoder::new(&mut buf).unwrap();
    let mut image = enc.new_image::<C>(w, h).unwrap();
    let matrix = [
        0.5, 0.0, 0.0, 10.0, //
        0.0, -0.25, 0.0, 50.0, //
        0.0, 0.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    ];
    image.encoder().write_tag(Tag::ModelTransformationTag, &matrix[..]).unwrap();
    let keys: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];
    image.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    image.write_data(data).unwrap();
    std::fs::write(path, buf.into_inner()).unwrap();
}

#[test]
fn model_transformation_and_signed_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("i8.tif");
    write_with_matrix::<tiff::encoder::colortype::GrayI8>(&path, 3, 2, &[-128, -1, 0, 1, 2, 127]);
    let r = read_geotiff(&path).unwrap();
    assert_eq!(r.data, vec![-128.0, -1.0, 0.0, 1.0, 2.0, 127.0]);
    assert_eq!(r.transform, GeoTransform { origin_x: 10.0, origin_y: 50.0, cell_width: 0.5, cell_height: 0.25 });
    assert_eq!(r.crs, WGS84);
    assert_eq!(r.nodata, None);

    // 1-bit samples are refused as an unsupported sample type.
    let path = dir.path().join("bits.tif");
    let mut bytes = tiff_header_only(8, 1);
    // BitsPerSample entry (3rd) value: 8 → 1.
    let bps_value = 8 + 2 + 2 * 12 + 8;
    bytes[bps_value] = 1;
    std::fs::write(&path, bytes).unwrap();
    let err = load_err(&path);
    assert!(matches!(err, GisError::UnsupportedSampleType { .. }), "{err}");
    assert!(err.to_string().contains("1-bit"), "{err}");
}
