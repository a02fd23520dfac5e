//! D1 fields, CRS reprojection, D5 time series, D3 colour maps and legends, Table 9.1
//! mappings — against the fixtures in `data/test/` and `data/test/fields/` (see
//! `data/test/README.md`). Known values come from GDAL, netCDF4-python and pyproj.

use std::path::{Path, PathBuf};

use landsketch::fields::{
    Clamp, ColorMapName, ColorMapSpec, Field, FieldError, FieldKind, GridSpec, Legend, LoadOptions, Lut, Mapping,
    MappingTarget, SceneGeo, Severity, format_time, load_bytes, load_file, load_series, parse_time, validate_mappings,
};
use landsketch::gis::{Crs, CrsDefinition, LocalFrame, ReprojectError, Transformer, read_geokeys, read_geotiff};
use landsketch::scene::terrain::Terrain;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/test").join(name)
}

fn load(name: &str, kind: FieldKind, variable: Option<&str>) -> Field {
    let opts = LoadOptions { variable: variable.map(str::to_string), ..LoadOptions::new(kind) };
    load_file(&fixture(name), &opts).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The scene of the full Boulder DEM (EPSG:4326, -105.55…-105.35, 40.09…40.21).
fn boulder_scene() -> SceneGeo {
    let dem = read_geotiff(&fixture("boulder_SRTMGL3_derived.tif")).unwrap();
    let terrain = Terrain::new(dem, [0.8; 3]).unwrap();
    SceneGeo::from_terrain(&terrain).unwrap()
}

/// The value of `field` at time `t` at a point of the scene CRS, through a 1 × 1 grid centred
/// on it (the renderer's path: reprojection + eq. 9.4).
fn grid_value(field: &Field, scene: &SceneGeo, t: Option<&str>, x: f64, y: f64) -> (f32, Option<Clamp>) {
    let (lx, ly) = scene.frame().to_local(x, y);
    let spec = GridSpec { min: [lx - 0.5, ly - 0.5], cell_size: 1.0, width: 1, height: 1 };
    let t = t.map(|t| parse_time(t).unwrap());
    let (grid, sample) = field.grid_at(t, scene, &spec).unwrap();
    (grid.values[0], sample.clamped)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn netcdf_tas_known_cells_fill_and_row_flip() {
    let f = load("bcsd_obs_1999.nc", FieldKind::Scalar, Some("tas"));
    assert_eq!(f.steps().len(), 12);
    assert_eq!(f.crs(), &CrsDefinition::wgs84());
    assert_eq!(f.units(), Some("C"));
    let times: Vec<String> = f.times().iter().map(format_time).collect();
    assert_eq!(times[0], "1999-01-31T00:00:00Z");
    assert_eq!(times[1], "1999-02-28T00:00:00Z");
    assert_eq!(times[11], "1999-12-31T00:00:00Z");
    let e = f.extent();
    assert!(close(e.min_x, -85.0, 1e-9) && close(e.max_x, -74.875, 1e-9), "{e:?}");
    assert!(close(e.min_y, 33.0, 1e-9) && close(e.max_y, 37.125, 1e-9), "{e:?}");
    // Row 0 is north after the flip; values from `gdallocationinfo -valonly -b <step+1>`.
    let r0 = &f.steps()[0].raster;
    assert_eq!(r0.get(0, 0), Some(4.732580661773682));
    assert_eq!(f.steps()[3].raster.get(40, 5), Some(15.097833633422852));
    assert_eq!(f.steps()[11].raster.get(10, 20), Some(6.403871059417725));
    // Ocean cells hold _FillValue 1e20 (gdallocationinfo at col 80, row 32 prints 1e20).
    assert_eq!(r0.get(67, 0), None);
    assert_eq!(r0.get(80, 32), None);
    assert_eq!(r0.valid_count(), 2080);
    // Sampling in lon/lat: the centre of north-up cell (40, 5) of step 3.
    let (x, y) = r0.cell_center(40, 5);
    assert_eq!(f.sample(3, x, y), Some(15.097833633422852));
    let pr = load("bcsd_obs_1999.nc", FieldKind::Scalar, Some("pr"));
    assert_eq!(pr.steps()[3].raster.get(40, 5), Some(92.12999725341797));
}

#[test]
fn netcdf_variable_choice_and_bad_files() {
    let err = load_file(&fixture("bcsd_obs_1999.nc"), &LoadOptions::new(FieldKind::Scalar)).unwrap_err().to_string();
    assert!(err.contains("pr, tas") && err.contains("variable="), "{err}");
    let opts = LoadOptions { variable: Some("precip".into()), ..LoadOptions::new(FieldKind::Scalar) };
    assert!(
        load_file(&fixture("bcsd_obs_1999.nc"), &opts)
            .unwrap_err()
            .to_string()
            .contains("no gridded variable \"precip\"")
    );
    let bytes = std::fs::read(fixture("bcsd_obs_1999.nc")).unwrap();
    let opts = LoadOptions { variable: Some("tas".into()), ..LoadOptions::new(FieldKind::Scalar) };
    let scratch = tempfile::tempdir().unwrap();
    for len in [4, 64, 700, 3000, 20_000, 200_000, bytes.len() - 1] {
        let err = load_bytes(&bytes[..len], Some("cut.nc"), &opts, scratch.path()).unwrap_err();
        assert!(matches!(err, FieldError::Format { .. }), "{len}: {err}");
    }
    let opts = LoadOptions { time: Some("1999-01-01".into()), ..opts };
    assert!(load_bytes(&bytes, Some("t.nc"), &opts, scratch.path()).unwrap_err().to_string().contains("own time axis"));
    let opts = LoadOptions { max_steps: 6, time: None, ..opts };
    assert!(load_bytes(&bytes, Some("t.nc"), &opts, scratch.path()).unwrap_err().is_too_large());
}

#[test]
fn netcdf_packed_south_up_with_fill_and_0_360_longitudes() {
    let f = load("fields/plume_southup.nc", FieldKind::Scalar, Some("pm25"));
    let times: Vec<String> = f.times().iter().map(format_time).collect();
    assert_eq!(times, ["2024-06-01T00:00:00Z", "2024-06-01T06:00:00Z", "2024-06-01T12:00:00Z"]);
    assert_eq!(f.units(), Some("ug/m3"));
    let e = f.extent();
    assert!(close(e.min_x, -105.55, 1e-5) && close(e.max_x, -105.45, 1e-5), "{e:?}");
    assert!(close(e.min_y, 40.09, 1e-5) && close(e.max_y, 40.17, 1e-5), "{e:?}");
    // raw = step·100 + lat_index·10 + lon_index, value = raw·0.1 + 5; row 0 = lat index 3.
    let v = |s: usize, c, r| f.steps()[s].raster.get(c, r);
    assert!(close(v(0, 0, 0).unwrap(), 8.0, 1e-9));
    assert!(close(v(2, 4, 3).unwrap(), 25.4, 1e-9));
    assert!(close(v(1, 1, 3).unwrap(), 15.1, 1e-9));
    assert_eq!(v(1, 0, 3), None, "raw _FillValue -32768");
    let err = load_file(&fixture("fields/plume_southup.nc"), &LoadOptions::new(FieldKind::Scalar)).unwrap_err();
    assert!(err.to_string().contains("pm25, wind"), "{err}");
}

#[test]
fn utm_points_to_lon_lat_match_pyproj() {
    let wgs = CrsDefinition::wgs84();
    let check = |def: &CrsDefinition, x: f64, y: f64, lon: f64, lat: f64| {
        let (a, b) = Transformer::new(def, &wgs).unwrap().transform(x, y).unwrap();
        assert!(close(a, lon, 1e-8) && close(b, lat, 1e-8), "{}: ({a}, {b}) vs ({lon}, {lat})", def.label());
        let (bx, by) = Transformer::new(&wgs, def).unwrap().transform(lon, lat).unwrap();
        assert!(close(bx, x, 1e-4) && close(by, y, 1e-4), "{}: back ({bx}, {by})", def.label());
    };
    // pyproj 3: Transformer.from_crs(src, "EPSG:4326", always_xy=True).transform(x, y)
    check(&CrsDefinition::from_epsg(32613).unwrap(), 460000.0, 4443000.0, -105.46953976851019, 40.13638093342354);
    check(&CrsDefinition::from_epsg(26912).unwrap(), 320000.0, 4130000.0, -113.030888040469, 37.29921769527188);
    check(&CrsDefinition::from_epsg(32733).unwrap(), 500000.0, 8000000.0, 15.0, -18.088708943127365);
    // User-defined GeoKeys (UTM 12N on GRS 80, no EPSG code) of the NLCD crop; its tiepoint.
    let keys = read_geokeys(&fixture("zion_nlcd2011_userdefined_crop.tif")).unwrap();
    let def = CrsDefinition::from_geokeys(&keys).unwrap().unwrap();
    assert_eq!(def.crs(), Crs::Projected { epsg: None, unit_to_metre: 1.0 });
    check(&def, 317668.4934991513, 4135171.6769430772, -113.05844916312665, 37.34535049433331);
}

#[test]
fn utm_field_reprojected_onto_geographic_scene() {
    let scene = boulder_scene();
    let f = load("boulder_utm13n_f32.tif", FieldKind::Scalar, None);
    assert_eq!(f.crs().label(), "EPSG:32613");
    f.check_overlap(&scene).unwrap();
    // Centre of UTM cell (5, 5), whose value `gdallocationinfo -valonly … 5 5` prints.
    let r = &f.steps()[0].raster;
    let (ux, uy) = r.cell_center(5, 5);
    let (lon, lat) = Transformer::new(f.crs(), scene.crs()).unwrap().transform(ux, uy).unwrap();
    let (v, clamped) = grid_value(&f, &scene, None, lon, lat);
    assert!(close(f64::from(v), 2710.52221679688, 1e-2), "{v}");
    assert_eq!(clamped, None);
    // The default grid covers the scene with cells no coarser than the field's 90 m.
    let spec = f.default_grid_spec(&scene).unwrap();
    assert!(spec.cell_size <= 90.0 && spec.width <= 1024 && spec.height <= 1024, "{spec:?}");
    let grid = f.resample(0, &scene, &spec).unwrap();
    let valid = grid.values.iter().filter(|v| !v.is_nan()).count();
    assert!(valid > 0 && valid < grid.values.len(), "the UTM crop covers part of the scene");
}

#[test]
fn label_checkerboard_shows_palette_colours_per_square() {
    let scene = boulder_scene();
    let f = load("fields/checker_label_utm13n.tif", FieldKind::Label, None);
    assert_eq!(f.classes().iter().map(|c| (c.value, c.count)).collect::<Vec<_>>(), [(1, 32), (2, 32)]);
    let spec = GridSpec::covering(&scene, 10.0, 4096);
    let grid = f.resample(0, &scene, &spec).unwrap();
    let lut = Lut::for_field(&ColorMapSpec::default(), &f).unwrap();
    let to_scene = Transformer::new(f.crs(), scene.crs()).unwrap();
    let tableau = |i: usize| colorous::TABLEAU10[i].as_array();
    for sr in 0..4 {
        for sc in 0..4 {
            // Centre of 100 m square (sc, sr); squares alternate 1, 2 starting with 1.
            let (ux, uy) = (461000.0 + 100.0 * sc as f64 + 50.0, 4445000.0 - 100.0 * sr as f64 - 50.0);
            let (lon, lat) = to_scene.transform(ux, uy).unwrap();
            let (x, y) = scene.frame().to_local(lon, lat);
            let index = grid.value_at(x, y).unwrap();
            let class = 1 + (sr + sc) % 2;
            assert_eq!(f.classes()[index as usize].value, class as i64, "square ({sc}, {sr})");
            assert_eq!(lut.color_of(f64::from(index))[..3], tableau(class - 1));
        }
    }
    // Outside the checkerboard: nodata, drawn transparent.
    assert_eq!(grid.get(0, 0), None);
    assert_eq!(lut.color_of(f64::NAN), [0, 0, 0, 0]);
}

#[test]
fn scalar_ramp_maps_monotonically_and_viridis_ends() {
    let scene = boulder_scene();
    let f = load("fields/ramp_scalar_4326.asc", FieldKind::Scalar, None);
    assert_eq!(f.crs().label(), "EPSG:4326", "from the .prj");
    assert_eq!(f.steps()[0].raster.get(2, 2), None, "NODATA_value");
    assert_eq!(f.value_range(), (0.0, 53.0));
    let lut = Lut::for_field(&ColorMapSpec::default(), &f).unwrap();
    assert_eq!(lut.colors[0], [0x44, 0x01, 0x54, 255], "viridis(0) = #440154");
    assert_eq!(lut.color_of(53.0), [0xfd, 0xe7, 0x25, 255], "viridis(1) = #fde725");
    // Along row 0 (lat 40.135) the values grow with longitude: LUT indices never decrease.
    let mut last = 0;
    for i in 0..=50 {
        let lon = -105.495 + 0.05 * f64::from(i) / 50.0;
        let (v, _) = grid_value(&f, &scene, None, lon, 40.135);
        let index = lut.index_of(f64::from(v)).unwrap();
        assert!(index >= last, "lon {lon}: {index} < {last}");
        last = index;
    }
    assert_eq!(last, lut.index_of(50.0).unwrap());
}

#[test]
fn series_of_geotiffs_interpolates_by_eq_9_4_and_clamps() {
    let scene = boulder_scene();
    let files = [
        (fixture("fields/series_2024-06-11.tif"), "2024-06-11".to_string()),
        (fixture("fields/series_2024-06-01.tif"), "2024-06-01".to_string()),
    ];
    let f = load_series(&files, &LoadOptions::new(FieldKind::Scalar)).unwrap();
    assert_eq!(f.times().iter().map(format_time).collect::<Vec<_>>(), ["2024-06-01T00:00:00Z", "2024-06-11T00:00:00Z"]);
    let r = &f.steps()[0].raster;
    let centre = |c, r_: usize| r.cell_center(c, r_);
    // u = 2.5 days / 10 days = 0.25: cell (0,0) 0 → 10 gives 2.5; cell (1,1) 4 → 22 gives 8.5.
    let (x, y) = centre(0, 0);
    let (v, clamped) = grid_value(&f, &scene, Some("2024-06-03T12:00:00Z"), x, y);
    assert!(close(f64::from(v), 2.5, 1e-5) && clamped.is_none(), "{v}");
    let (x, y) = centre(1, 1);
    assert!(close(f64::from(grid_value(&f, &scene, Some("2024-06-03T12:00:00Z"), x, y).0), 8.5, 1e-5));
    // Midpoint: the mean of both steps, (4 + 22) / 2.
    assert!(close(f64::from(grid_value(&f, &scene, Some("2024-06-06"), x, y).0), 13.0, 1e-5));
    // Nodata in one step with non-zero weight → nodata; at that step's own time too.
    let (x2, y2) = centre(2, 2);
    assert!(grid_value(&f, &scene, Some("2024-06-06"), x2, y2).0.is_nan());
    assert!(close(f64::from(grid_value(&f, &scene, Some("2024-06-11"), x2, y2).0), 34.0, 1e-5));
    // Outside the series: clamped and flagged.
    let (v, clamped) = grid_value(&f, &scene, Some("2024-05-01"), x, y);
    assert_eq!((v, clamped), (4.0, Some(Clamp::Before)));
    let (v, clamped) = grid_value(&f, &scene, Some("2025-01-01T00:00:00+01:00"), x, y);
    assert_eq!((v, clamped), (22.0, Some(Clamp::After)));
}

#[test]
fn label_series_takes_the_nearest_step() {
    let scene = boulder_scene();
    let files = [
        (fixture("fields/series_2024-06-01.tif"), "2024-06-01".to_string()),
        (fixture("fields/series_2024-06-11.tif"), "2024-06-11".to_string()),
    ];
    let f = load_series(&files, &LoadOptions::new(FieldKind::Label)).unwrap();
    let (x, y) = f.steps()[0].raster.cell_center(1, 1);
    let class = |t| f.classes()[grid_value(&f, &scene, Some(t), x, y).0 as usize].value;
    assert_eq!(class("2024-06-03"), 4);
    assert_eq!(class("2024-06-05T23:59:59Z"), 4);
    assert_eq!(class("2024-06-06"), 22, "switches at the midpoint");
    assert_eq!(class("2024-06-09"), 22);
    assert_eq!(f.time_sample(Some(parse_time("2023-01-01").unwrap())).clamped, Some(Clamp::Before));
}

#[test]
fn non_overlapping_field_names_both_extents() {
    let f = load("bcsd_obs_1999.nc", FieldKind::Scalar, Some("tas"));
    let err = f.check_overlap(&boulder_scene()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, FieldError::NoOverlap { .. }));
    assert!(msg.contains("x -85.0000…-74.8750, y 33.0000…37.1250 in EPSG:4326"), "{msg}");
    assert!(msg.contains("x -105.5504…-105.3504"), "{msg}");
    assert!(msg.contains("scene metres"), "{msg}");
}

#[test]
fn missing_crs_is_an_error_unless_given_or_assumed() {
    let text = std::fs::read(fixture("fields/ramp_scalar_4326.asc")).unwrap();
    let scratch = tempfile::tempdir().unwrap();
    let err = load_bytes(&text, Some("ramp.asc"), &LoadOptions::new(FieldKind::Scalar), scratch.path()).unwrap_err();
    assert!(matches!(err, FieldError::Crs(ReprojectError::Missing)), "{err}");
    assert!(err.to_string().contains("no coordinate reference system"), "{err}");
    let scene = boulder_scene();
    let assume = LoadOptions { crs: Some(scene.crs().clone()), ..LoadOptions::new(FieldKind::Scalar) };
    let f = load_bytes(&text, Some("ramp.asc"), &assume, scratch.path()).unwrap();
    f.check_overlap(&scene).unwrap();
    let unsupported = CrsDefinition::parse("EPSG:26712").unwrap_err().to_string();
    assert!(unsupported.contains("EPSG:26712"), "{unsupported}");
    assert_eq!(std::fs::read_dir(scratch.path()).unwrap().count(), 0, "no scratch files left");
}

#[test]
fn user_defined_crs_field_over_a_utm_scene() {
    // The NLCD crop (UTM 12N on GRS 80 by GeoKeys) on a scene in NAD83 / UTM 12N.
    let f = load("zion_nlcd2011_userdefined_crop.tif", FieldKind::Label, None);
    let (cx, cy) = f.extent().center();
    let frame = LocalFrame::new(Crs::Projected { epsg: Some(26912), unit_to_metre: 1.0 }, cx, cy).unwrap();
    let scene =
        SceneGeo::new(frame, CrsDefinition::from_epsg(26912).unwrap(), [-500.0, -500.0], [500.0, 500.0]).unwrap();
    f.check_overlap(&scene).unwrap();
    // Cell (0, 0) holds class 42 and (23, 15) class 41 (gdallocationinfo).
    let r = &f.steps()[0].raster;
    for ((c, row), class) in [((0, 0), 42), ((23, 15), 41)] {
        let (x, y) = r.cell_center(c, row);
        let (v, _) = grid_value(&f, &scene, None, x, y);
        assert_eq!(f.classes()[v as usize].value, class);
    }
    // The file's palette becomes the class colours (`file` colour map).
    let lut = Lut::for_field(&ColorMapSpec { map: Some(ColorMapName::File), ..Default::default() }, &f).unwrap();
    let forest = f.classes().iter().position(|c| c.value == 42).unwrap();
    assert_eq!(Some(lut.colors[forest][..3].to_vec()), f.classes()[forest].color.map(|c| c.to_vec()));
}

#[test]
fn label_legend_png_has_class_swatches() {
    let f = load("fields/checker_label_utm13n.tif", FieldKind::Label, None);
    let mut f = f;
    f.set_class_names(&[(1, "Low hazard".to_string()), (2, "High hazard".to_string())].into()).unwrap();
    let lut = Lut::for_field(&ColorMapSpec::default(), &f).unwrap();
    let legend = Legend::new("Fire hazard", f.kind(), f.units(), f.classes(), &lut);
    let png = legend.to_png().unwrap();
    let img = image::load_from_memory(&png).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (320, 22 + 2 * 18 + 6));
    assert_eq!(legend.png_size(), img.dimensions());
    // Inside the first swatch (x 12…25, y 22…35): Tableau 10 blue #4e79a7.
    assert_eq!(img.get_pixel(18, 28).0, [0x4e, 0x79, 0xa7, 255]);
    assert_eq!(img.get_pixel(18, 28 + 18).0, [0xf2, 0x8e, 0x2c, 255]);
    let json = serde_json::to_value(&legend).unwrap();
    assert_eq!(json["classes"][1]["name"], "High hazard");
    assert_eq!(json["classes"][1]["color"], "#f28e2c");
    assert_eq!(json["colormap"], "tableau10");
}

#[test]
fn table_9_1_warnings() {
    let layers = |id: &str| match id {
        "tas" => Some((FieldKind::Scalar, 0)),
        "hazard" => Some((FieldKind::Label, 2)),
        _ => None,
    };
    let w = validate_mappings(&[Mapping::new("tas", MappingTarget::SilhouetteStyle)], layers).unwrap();
    assert_eq!(w.len(), 1);
    assert_eq!(w[0].severity, Severity::Unsuitable);
    assert!(w[0].message.contains("scalar field → silhouette_style"), "{}", w[0].message);
    let ok = [Mapping::new("tas", MappingTarget::Color), Mapping::new("hazard", MappingTarget::SilhouetteStyle)];
    assert!(validate_mappings(&ok, layers).unwrap().is_empty());
    let w = validate_mappings(&[Mapping::new("tas", MappingTarget::HatchPattern)], layers).unwrap();
    assert_eq!(w[0].severity, Severity::Unsuitable);
}
