//! CRS coverage (issue 20): EPSG codes from the EPSG table, WKT by authority and by name,
//! user-facing names, datum shifts — checked against published coordinates:
//!
//! - IOGP Guidance Note 7-2 (*Coordinate Conversions and Transformations including Formulas*,
//!   IOGP Publication 373-7-2) worked examples: Transverse Mercator (OSGB 1936 / British
//!   National Grid), Popular Visualisation Pseudo Mercator (WGS 84 / Pseudo-Mercator),
//!   Lambert Azimuthal Equal Area (ETRS89 / LAEA Europe), Oblique Stereographic (Amersfoort /
//!   RD New);
//! - Snyder, *Map Projections — A Working Manual* (USGS PP 1395, 1987), p. 292: the Albers
//!   example with the standard parallels of NAD83 / Conus Albers;
//! - the national grids' defining points (the projection origins published with each CRS:
//!   Bern for LV95, Amersfoort for RD, 3°E 46.5°N for Lambert-93) and swisstopo's example of
//!   its approximate WGS 84 ↔ LV95 formulas (E 2 700 000, N 1 100 000 ↔ 8°43′49.79″ E,
//!   46°02′38.87″ N);
//! - for Transverse Mercator grids (UTM, Gauss-Krüger), points on the central meridian, whose
//!   northing is k0 times the meridian arc — computed here with GN 7-2's series, independently
//!   of the projection code.

use landsketch::gis::{Crs, CrsDefinition, ReprojectError, Transformer};

fn def(text: &str) -> CrsDefinition {
    CrsDefinition::parse(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

fn transform(from: &str, to: &str, x: f64, y: f64) -> (f64, f64) {
    Transformer::new(&def(from), &def(to)).unwrap().transform(x, y).unwrap_or_else(|| panic!("{from} → {to}"))
}

fn dms(d: f64, m: f64, s: f64) -> f64 {
    d + m / 60.0 + s / 3600.0
}

#[track_caller]
fn assert_close(got: (f64, f64), want: (f64, f64), tol: f64) {
    let (dx, dy) = (got.0 - want.0, got.1 - want.1);
    assert!(
        dx.abs() <= tol && dy.abs() <= tol,
        "got {got:?}, published {want:?} (off by {dx:.4}, {dy:.4}; tolerance {tol})"
    );
}

/// Meridian arc from the equator to latitude `lat` (degrees) on an ellipsoid of semi-major
/// axis `a` and inverse flattening `rf` (GN 7-2, Transverse Mercator, the series for M).
fn meridian_arc(a: f64, rf: f64, lat: f64) -> f64 {
    let f = 1.0 / rf;
    let e2 = f * (2.0 - f);
    let (e4, e6) = (e2 * e2, e2 * e2 * e2);
    let p = lat.to_radians();
    a * ((1.0 - e2 / 4.0 - 3.0 * e4 / 64.0 - 5.0 * e6 / 256.0) * p
        - (3.0 * e2 / 8.0 + 3.0 * e4 / 32.0 + 45.0 * e6 / 1024.0) * (2.0 * p).sin()
        + (15.0 * e4 / 256.0 + 45.0 * e6 / 1024.0) * (4.0 * p).sin()
        - (35.0 * e6 / 3072.0) * (6.0 * p).sin())
}

const GRS80: (f64, f64) = (6_378_137.0, 298.257_222_101);
const WGS84: (f64, f64) = (6_378_137.0, 298.257_223_563);
const BESSEL: (f64, f64) = (6_377_397.155, 299.152_812_8);

#[test]
fn guidance_note_7_2_examples() {
    // Transverse Mercator: OSGB 1936 50°30'N 0°30'E → E 577 274.99, N 69 740.50.
    assert_close(transform("EPSG:4277", "EPSG:27700", 0.5, 50.5), (577_274.99, 69_740.50), 0.02);
    // Pseudo-Mercator: 24°22'54.433"N 100°20'W → E −11 169 055.58, N 2 800 000.00.
    let lat = dms(24.0, 22.0, 54.433);
    assert_close(
        transform("EPSG:4326", "EPSG:3857", -dms(100.0, 20.0, 0.0), lat),
        (-11_169_055.58, 2_800_000.00),
        0.01,
    );
    // LAEA Europe: ETRS89 50°N 5°E → E 3 962 799.45, N 2 999 718.85.
    assert_close(transform("EPSG:4258", "EPSG:3035", 5.0, 50.0), (3_962_799.45, 2_999_718.85), 0.01);
    // Oblique Stereographic, RD New: Amersfoort 53°N 6°E → E 196 105.283, N 557 057.739.
    assert_close(transform("EPSG:4289", "EPSG:28992", 6.0, 53.0), (196_105.283, 557_057.739), 0.01);
    // And back.
    assert_close(transform("EPSG:28992", "EPSG:4289", 196_105.283, 557_057.739), (6.0, 53.0), 1e-7);
}

#[test]
fn snyder_albers_example_with_conus_albers_parameters() {
    // EPSG:5070's own parameters, on Snyder's Clarke 1866 ellipsoid: 35°N 75°W → x 1 885 472.7,
    // y 1 535 925.0 m.
    let conus = def("EPSG:5070");
    assert!(conus.proj_string().contains("+lat_1=29.5") && conus.proj_string().contains("+lat_2=45.5"));
    let clarke = conus.proj_string().replace("+datum=NAD83", "+ellps=clrk66");
    let geog = CrsDefinition::from_proj_string("+proj=longlat +ellps=clrk66 +no_defs").unwrap();
    let t = Transformer::new(&geog, &CrsDefinition::from_proj_string(&clarke).unwrap()).unwrap();
    assert_close(t.transform(-75.0, 35.0).unwrap(), (1_885_472.7, 1_535_925.0), 0.1);
    // On its own datum the Conus Albers origin (23°N 96°W) is (0, 0).
    assert_close(transform("EPSG:4269", "EPSG:5070", -96.0, 23.0), (0.0, 0.0), 0.01);
}

#[test]
fn national_grid_origins() {
    // CH1903+ / LV95: the old observatory of Bern, 46°57'08.66"N 7°26'22.50"E, is E 2 600 000, N 1 200 000.
    let bern = (dms(7.0, 26.0, 22.50), dms(46.0, 57.0, 8.66));
    assert_close(transform("EPSG:4150", "EPSG:2056", bern.0, bern.1), (2_600_000.0, 1_200_000.0), 0.01);
    // Amersfoort / RD New: the Amersfoort tower, 52°09'22.178"N 5°23'15.500"E, is x 155 000, y 463 000.
    let amersfoort = (dms(5.0, 23.0, 15.5), dms(52.0, 9.0, 22.178));
    assert_close(transform("EPSG:4289", "EPSG:28992", amersfoort.0, amersfoort.1), (155_000.0, 463_000.0), 0.01);
    // RGF93 / Lambert-93: 3°E 46.5°N is E 700 000, N 6 600 000.
    assert_close(transform("EPSG:4171", "EPSG:2154", 3.0, 46.5), (700_000.0, 6_600_000.0), 0.01);
}

#[test]
fn transverse_mercator_grids_on_their_central_meridian() {
    let north = |e: (f64, f64), lat: f64, k0: f64| k0 * meridian_arc(e.0, e.1, lat);
    // ETRS89 / UTM 32N, NAD83 / UTM 12N, WGS 84 / UTM 17S, DHDN / Gauss-Krüger zone 3.
    assert_close(transform("EPSG:4258", "EPSG:25832", 9.0, 50.0), (500_000.0, north(GRS80, 50.0, 0.9996)), 0.005);
    assert_close(transform("EPSG:4258", "EPSG:25833", 15.0, 52.5), (500_000.0, north(GRS80, 52.5, 0.9996)), 0.005);
    assert_close(transform("EPSG:4269", "EPSG:26912", -111.0, 40.0), (500_000.0, north(GRS80, 40.0, 0.9996)), 0.005);
    let south = 10_000_000.0 - north(WGS84, 2.0, 0.9996);
    assert_close(transform("EPSG:4326", "EPSG:32717", -81.0, -2.0), (500_000.0, south), 0.005);
    assert_close(transform("EPSG:4314", "EPSG:31467", 9.0, 50.0), (3_500_000.0, north(BESSEL, 50.0, 1.0)), 0.005);
    // British National Grid: the true origin 49°N 2°W is E 400 000, N −100 000.
    assert_close(transform("EPSG:4277", "EPSG:27700", -2.0, 49.0), (400_000.0, -100_000.0), 0.005);
}

#[test]
fn datum_shifts_by_helmert_parameters() {
    // swisstopo's example for its approximate formulas (accurate to about a metre); the
    // table's 3-parameter shift CH1903+ → WGS 84 is of the same order.
    let (lon, lat) = (dms(8.0, 43.0, 49.79), dms(46.0, 2.0, 38.87));
    assert_close(transform("EPSG:4326", "EPSG:2056", lon, lat), (2_700_000.0, 1_100_000.0), 1.0);
    // The same point in CH1903+ lon/lat differs from WGS 84 by the datum shift (about 100 m
    // on the ground), so the shift is applied, not dropped.
    let on_bessel = transform("EPSG:4150", "EPSG:2056", lon, lat);
    let shift = (on_bessel.0 - 2_700_000.0).hypot(on_bessel.1 - 1_100_000.0);
    assert!((50.0..200.0).contains(&shift), "CH1903+ vs WGS 84 differ by {shift} m");
    // OSGB36: the 7-parameter Helmert of the table moves points by ~100 m against WGS 84.
    let a = transform("EPSG:4326", "EPSG:27700", -3.1, 51.06);
    let b = transform("EPSG:4277", "EPSG:27700", -3.1, 51.06);
    let shift = (a.0 - b.0).hypot(a.1 - b.1);
    assert!((50.0..200.0).contains(&shift), "OSGB36 vs WGS 84 differ by {shift} m");
}

#[test]
fn names_shown_to_users() {
    assert_eq!(def("EPSG:2056").to_string(), "EPSG:2056 (CH1903+ / LV95)");
    assert_eq!(def("EPSG:2056").label(), "EPSG:2056");
    assert_eq!(def("EPSG:27700").crs().to_string(), "EPSG:27700 (OSGB 1936 / British National Grid)");
    assert_eq!(
        Crs::Projected { epsg: Some(26912), unit_to_metre: 1.0 }.to_string(),
        "EPSG:26912 (NAD83 / UTM zone 12N)"
    );
    // What Display writes parses back; URNs and CRS84 as GeoJSON writes them.
    for text in ["EPSG:2056 (CH1903+ / LV95)", "urn:ogc:def:crs:EPSG::2056", "epsg:2056"] {
        assert_eq!(text.parse::<Crs>().unwrap().epsg(), Some(2056), "{text}");
    }
    assert_eq!(def("urn:ogc:def:crs:OGC:1.3:CRS84"), CrsDefinition::wgs84());
    // Units of the table: US survey feet.
    let ft = def("EPSG:2227").crs();
    assert!(
        matches!(ft, Crs::Projected { unit_to_metre, .. } if (unit_to_metre - 1200.0 / 3937.0).abs() < 1e-12),
        "{ft:?}"
    );
}

#[test]
fn codes_without_a_usable_definition_are_explained() {
    let err = CrsDefinition::parse("EPSG:99999").unwrap_err();
    assert!(matches!(err, ReprojectError::Unsupported { .. }));
    assert!(err.to_string().contains("EPSG:99999") && err.to_string().contains("EPSG table"), "{err}");
    // NAD27 needs the NADCON/NTv2 grids.
    let err = CrsDefinition::parse("EPSG:26712").unwrap_err();
    assert!(err.to_string().contains("EPSG:26712 (NAD27 / UTM zone 12N)") && err.to_string().contains("grid"), "{err}");
    // Geocentric CRSs are not planar.
    assert!(CrsDefinition::parse("EPSG:4978").is_err());
    assert!(CrsDefinition::parse("ESRI:102003").unwrap_err().to_string().contains("only EPSG codes"));
}

#[test]
fn wkt_without_authority_is_matched_by_name() {
    // The ESRI .prj QGIS writes for British National Grid (as the Kingston St Mary shapefiles).
    let esri = r#"PROJCS["OSGB_1936_British_National_Grid",GEOGCS["GCS_OSGB 1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0],UNIT["Degree",0.017453292519943295]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",49],PARAMETER["central_meridian",-2],PARAMETER["scale_factor",0.9996012717],PARAMETER["false_easting",400000],PARAMETER["false_northing",-100000],UNIT["Meter",1]]"#;
    assert_eq!(CrsDefinition::from_wkt(esri).unwrap().crs().epsg(), Some(27700));
    let swiss = r#"PROJCS["CH1903+_LV95",GEOGCS["GCS_CH1903+",DATUM["D_CH1903+",SPHEROID["Bessel_1841",6377397.155,299.1528128]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Hotine_Oblique_Mercator_Azimuth_Center"],UNIT["Meter",1.0]]"#;
    assert_eq!(CrsDefinition::parse(swiss).unwrap().crs().epsg(), Some(2056));
    // A name in another unit than its EPSG namesake is not taken for it.
    let feet = esri.replace(r#"UNIT["Meter",1]]"#, r#"UNIT["Foot",0.3048]]"#);
    assert_eq!(Crs::from_wkt(&feet).unwrap().epsg(), None);
}
