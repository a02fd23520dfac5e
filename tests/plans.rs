//! GIS inputs as planners have them (issue 20): a land cover in another CRS than its DEM,
//! vector plans (GeoJSON planting areas, hedgerows, single plants; CSV tree inventories),
//! polygons rasterized as land cover, and bad vector input.

use std::path::{Path, PathBuf};

use landsketch::gis::{Crs, CrsDefinition, GeoTransform, Raster, Transformer, load_raster, write_geotiff_f32};
use landsketch::scene::terrain::Terrain;
use landsketch::scene::vegetation::{PlacementRule, PlantInstance, place_in};
use landsketch::scene::{Scene, SceneError};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/test").join(name)
}

/// A DEM of `n` × `n` cells of `cell` CRS units whose north-west corner is (`x0`, `y0`),
/// gently sloping east, written as a GeoTIFF.
fn write_dem(path: &Path, crs: Crs, x0: f64, y0: f64, cell: f64, n: usize) {
    let dem = Raster {
        width: n,
        height: n,
        data: (0..n * n).map(|i| 100.0 + (i % n) as f64 * 0.1).collect(),
        nodata: None,
        transform: GeoTransform { origin_x: x0, origin_y: y0, cell_width: cell, cell_height: cell },
        crs,
        palette: None,
    };
    write_geotiff_f32(path, &dem).unwrap();
}

const SPECIES: &str = r#"
[species.oak]
procedural = "broadleaf"
[species.hawthorn]
procedural = "shrub"
[species.pine]
procedural = "conifer"
"#;

/// A scene file in `dir` on `dem` with `layers` (TOML) appended.
fn scene(dir: &Path, dem: &Path, layers: &str) -> PathBuf {
    let text = format!(
        "name = \"plan test\"\n[terrain]\ndem = \"{}\"\n[camera]\nposition = [0.0, 0.0]\nyaw = 0.0\n{SPECIES}\n{layers}",
        dem.display()
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn load(path: &Path) -> Scene {
    Scene::load(path).unwrap_or_else(|e| panic!("{e}"))
}

fn load_err(path: &Path) -> String {
    match Scene::load(path) {
        Ok(_) => panic!("scene loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn landcover_in_another_crs_places_the_same_plants_as_sampled_in_its_own() {
    // NLCD (EPSG:26912, ≈ 31.5 m cells) under a DEM in WGS 84 lon/lat over 2 × 2 km of Zion.
    let nlcd_path = fixture("zion_nlcd2011_simplified.tif");
    let nlcd = load_raster(&nlcd_path).unwrap();
    let utm = CrsDefinition::from_epsg(26912).unwrap();
    let wgs = CrsDefinition::wgs84();
    let (cx, cy) = nlcd.extent().center();
    let (lon, lat) = Transformer::new(&utm, &wgs).unwrap().transform(cx, cy).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let dem_path = dir.path().join("dem.tif");
    let cell = 0.0003; // ≈ 33 m × 25 m
    write_dem(&dem_path, Crs::Geographic { epsg: Some(4326) }, lon - 0.012, lat + 0.009, cell, 80);
    let layer = format!(
        "[[layers]]\nname = \"existing\"\nlandcover = \"{}\"\nseed = 4\n[[layers.rules]]\nclass = 4\nspecies = \"hawthorn\"\ndensity = 8.0\n",
        nlcd_path.display()
    );
    let scene = load(&scene(dir.path(), &dem_path, &layer));
    let warped = &scene.layers[0].plants;

    // Reference: every candidate point taken to EPSG:26912 and looked up in the NLCD itself.
    let terrain = Terrain::new(load_raster(&dem_path).unwrap(), [0.8; 3]).unwrap();
    let to_utm = Transformer::new(&wgs, &utm).unwrap();
    let class_at = |p: [f64; 2]| {
        let (x, y) = terrain.frame.to_crs(p[0], p[1]);
        let (ux, uy) = to_utm.transform(x, y)?;
        nlcd.sample_nearest(ux, uy).map(|c| c.round() as i64)
    };
    let hawthorn = scene.species.iter().position(|s| s.name == "hawthorn").unwrap();
    let rule = PlacementRule { class: 4, species: hawthorn, density_per_ha: 8.0, min_spacing: 0.0, scale: [1.0, 1.0] };
    let direct = place_in(&terrain, terrain.bounds(), &class_at, &[rule], 4, 100_000, &|_| {}).unwrap();
    assert!(direct.len() > 100, "{} forest plants", direct.len());

    // Plants found in one set but not the other stand within one NLCD cell of a class change.
    let same = |a: &PlantInstance, b: &PlantInstance| {
        (a.position[0] - b.position[0]).abs() < 1e-3 && (a.position[1] - b.position[1]).abs() < 1e-3
    };
    let near_boundary = |p: &PlantInstance| {
        let (x, y) = terrain.frame.to_crs(f64::from(p.position[0]), f64::from(p.position[1]));
        let (ux, uy) = to_utm.transform(x, y).unwrap();
        let d = nlcd.transform.cell_width;
        // The 3 × 3 cells around it (diagonal neighbours included).
        let classes: Vec<Option<f64>> = (-1..=1)
            .flat_map(|i| (-1..=1).map(move |j| (f64::from(i) * d, f64::from(j) * d)))
            .map(|(dx, dy)| nlcd.sample_nearest(ux + dx, uy + dy))
            .collect();
        classes.contains(&Some(4.0)) && classes.iter().any(|c| *c != Some(4.0))
    };
    let only_warped: Vec<_> = warped.iter().filter(|a| !direct.iter().any(|b| same(a, b))).collect();
    let only_direct: Vec<_> = direct.iter().filter(|b| !warped.iter().any(|a| same(a, b))).collect();
    for p in only_warped.iter().chain(&only_direct) {
        assert!(near_boundary(p), "plant at {:?} is more than a cell from any class boundary", p.position);
    }
    // NLCD forest is fragmented at its 31.5 m cells, so many candidates stand within a cell
    // of a boundary; resampling moves a boundary by up to half a resampled cell, so about one
    // plant in six changes (measured 377 of 2409). A shifted or mis-scaled land cover would
    // change far more, and fail the boundary test above.
    let differ = only_warped.len() + only_direct.len();
    assert!(differ * 4 < direct.len(), "{differ} of {} plants differ", direct.len());
}

/// A 400 m × 400 m DEM in British National Grid at E 321 000–321 400, N 129 000–129 400
/// (Kingston St Mary), 4 m cells. Its local frame's origin is E 321 200, N 129 200.
fn bng_dem(dir: &Path) -> PathBuf {
    let path = dir.join("dem.tif");
    write_dem(&path, Crs::Projected { epsg: Some(27700), unit_to_metre: 1.0 }, 321_000.0, 129_400.0, 4.0, 100);
    path
}

const ORIGIN: (f64, f64) = (321_200.0, 129_200.0);

/// `[E, N]` corners in British National Grid → a GeoJSON ring in WGS 84 (RFC 7946).
fn ring_wgs84(corners: &[(f64, f64)]) -> String {
    let t = Transformer::new(&CrsDefinition::from_epsg(27700).unwrap(), &CrsDefinition::wgs84()).unwrap();
    let pts: Vec<String> = corners
        .iter()
        .chain(corners.first())
        .map(|&(e, n)| {
            let (lon, lat) = t.transform(e, n).unwrap();
            format!("[{lon:.9}, {lat:.9}]")
        })
        .collect();
    format!("[[{}]]", pts.join(", "))
}

fn feature(geometry: &str, properties: &str) -> String {
    format!(r#"{{"type": "Feature", "geometry": {geometry}, "properties": {{{properties}}}}}"#)
}

/// GeoJSON point features at (E, N) with a species under `species_key` and a `height`.
fn point_features(points: &[(f64, f64, &str, f64)], species_key: &str) -> Vec<String> {
    points
        .iter()
        .map(|(e, n, s, h)| {
            feature(
                &format!(r#"{{"type": "Point", "coordinates": [{e}, {n}]}}"#),
                &format!(r#""{species_key}": "{s}", "height": {h}"#),
            )
        })
        .collect()
}

fn collection(features: &[String], crs: Option<u32>) -> String {
    let crs = crs.map_or(String::new(), |c| {
        format!(r#""crs": {{"type": "name", "properties": {{"name": "urn:ogc:def:crs:EPSG::{c}"}}}}, "#)
    });
    format!(r#"{{"type": "FeatureCollection", {crs}"features": [{}]}}"#, features.join(", "))
}

/// Whether (x, y) is inside the polygon `corners` (E, N) shifted to the local frame.
fn inside(corners: &[(f64, f64)], x: f64, y: f64) -> bool {
    let pts: Vec<(f64, f64)> = corners.iter().map(|&(e, n)| (e - ORIGIN.0, n - ORIGIN.1)).collect();
    let mut c = false;
    for i in 0..pts.len() {
        let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
        if (a.1 > y) != (b.1 > y) && x < a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1) {
            c = !c;
        }
    }
    c
}

const WOOD: [(f64, f64); 5] = [
    (321_050.0, 129_050.0),
    (321_250.0, 129_060.0),
    (321_300.0, 129_200.0),
    (321_150.0, 129_300.0),
    (321_040.0, 129_180.0),
];

fn polygon_area(corners: &[(f64, f64)]) -> f64 {
    0.5 * (0..corners.len())
        .map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<f64>()
        .abs()
}

fn plan_scene(dir: &Path, plans: &str, seed: u64) -> PathBuf {
    let dem = bng_dem(dir);
    scene(dir, &dem, &format!("[[layers]]\nname = \"planned\"\nseed = {seed}\n{plans}"))
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn planting_polygon_in_wgs84_fills_the_polygon_at_its_density() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(
        dir.path(),
        "wood.geojson",
        &collection(
            &[feature(
                &format!(r#"{{"type": "Polygon", "coordinates": {}}}"#, ring_wgs84(&WOOD)),
                r#""species": "oak", "density": 150"#,
            )],
            None,
        ),
    );
    let plans = format!("[[layers.plans]]\nkind = \"areas\"\nfile = \"{}\"\nmin_spacing = 2.0\n", file.display());
    let a = load(&plan_scene(dir.path(), &plans, 1));
    let plants = &a.layers[0].plants;
    let oak = a.species.iter().position(|s| s.name == "oak").unwrap();
    for p in plants {
        let (x, y) = (f64::from(p.position[0]), f64::from(p.position[1]));
        assert!(inside(&WOOD, x, y), "plant at ({x}, {y}) outside the polygon");
        assert_eq!(p.species, oak);
        let ground = a.terrain.height_at(x, y).unwrap();
        assert!((f64::from(p.position[2]) - ground).abs() < 1e-3);
    }
    let expected = 150.0 * polygon_area(&WOOD) / 10_000.0;
    let n = plants.len() as f64;
    assert!((n - expected).abs() < 0.15 * expected, "{n} plants, expected about {expected}");
    // Deterministic per seed.
    let again = load(&plan_scene(dir.path(), &plans, 1));
    assert_eq!(&again.layers[0].plants, plants);
    let other = load(&plan_scene(dir.path(), &plans, 2));
    assert_ne!(&other.layers[0].plants, plants);
}

#[test]
fn hedgerow_line_with_a_crs_member_places_rows_along_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = ((321_050.0, 129_050.0), (321_350.0, 129_130.0));
    let line = format!(r#"{{"type": "LineString", "coordinates": [[{}, {}], [{}, {}]]}}"#, a.0, a.1, b.0, b.1);
    let file =
        write(dir.path(), "hedges.geojson", &collection(&[feature(&line, r#""species": "hawthorn""#)], Some(27700)));
    let plans = format!(
        "[[layers.plans]]\nkind = \"hedgerows\"\nfile = \"{}\"\nspacing = 0.8\nrows = 2\nrow_spacing = 0.6\n",
        file.display()
    );
    let scene = load(&plan_scene(dir.path(), &plans, 3));
    let plants = &scene.layers[0].plants;
    let (ax, ay, bx, by) = (a.0 - ORIGIN.0, a.1 - ORIGIN.1, b.0 - ORIGIN.0, b.1 - ORIGIN.1);
    let len = (bx - ax).hypot(by - ay);
    let expected = 2.0 * (len / 0.8).floor();
    assert!((plants.len() as f64 - expected).abs() <= 2.0, "{} plants, expected {expected}", plants.len());
    let (mut left, mut right) = (0usize, 0usize);
    for p in plants {
        let (x, y) = (f64::from(p.position[0]), f64::from(p.position[1]));
        // Signed distance from the line and position along it.
        let across = ((bx - ax) * (y - ay) - (by - ay) * (x - ax)) / len;
        let along = ((bx - ax) * (x - ax) + (by - ay) * (y - ay)) / len;
        assert!((across.abs() - 0.3).abs() <= 0.061, "plant {across} m from the line");
        assert!((-0.1..=len + 0.1).contains(&along));
        if across > 0.0 { left += 1 } else { right += 1 }
    }
    assert!(left.abs_diff(right) <= 1, "rows of {left} and {right}");
    assert_eq!(load(&plan_scene(dir.path(), &plans, 3)).layers[0].plants, *plants);
}

#[test]
fn points_and_csv_inventories_place_plants_at_the_features() {
    let dir = tempfile::tempdir().unwrap();
    // GeoJSON points in BNG with species and height; a CSV with x, y in BNG and one with lon, lat.
    let pts = [(321_100.0, 129_100.0, "OAK", 18.0), (321_300.0, 129_250.0, "pine", 12.0)];
    let geojson = write(dir.path(), "trees.geojson", &collection(&point_features(&pts, "Tree_speci"), Some(27700)));
    let csv = write(
        dir.path(),
        "inventory.csv",
        "id,x,y,species,height\n1,321150.5,129350.25,\"oak\",9.5\n2,321390,129010,hawthorn,\n",
    );
    let (lon, lat) = Transformer::new(&CrsDefinition::from_epsg(27700).unwrap(), &CrsDefinition::wgs84())
        .unwrap()
        .transform(321_020.0, 129_380.0)
        .unwrap();
    let lonlat = write(dir.path(), "gps.csv", &format!("lat,lon,species,crown\n{lat:.9},{lon:.9},oak,6\n"));
    let plans = format!(
        "[[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\nspecies_property = \"Tree_speci\"\nspecies_map = {{ OAK = \"oak\" }}\n\
         [[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\nscale = [0.9, 1.1]\n\
         [[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\n",
        geojson.display(),
        csv.display(),
        lonlat.display()
    );
    let scene = load(&plan_scene(dir.path(), &plans, 5));
    let plants = &scene.layers[0].plants;
    assert_eq!(plants.len(), 5);
    let species = |name: &str| scene.species.iter().position(|s| s.name == name).unwrap();
    let expect = [
        (321_100.0, 129_100.0, "oak", Some(18.0)),
        (321_300.0, 129_250.0, "pine", Some(12.0)),
        (321_150.5, 129_350.25, "oak", Some(9.5)),
        (321_390.0, 129_010.0, "hawthorn", None),
        (321_020.0, 129_380.0, "oak", None),
    ];
    for (p, (e, n, s, h)) in plants.iter().zip(expect) {
        assert!((f64::from(p.position[0]) - (e - ORIGIN.0)).abs() < 2e-3, "{p:?} vs E {e}");
        assert!((f64::from(p.position[1]) - (n - ORIGIN.1)).abs() < 2e-3, "{p:?} vs N {n}");
        assert_eq!(p.species, species(s));
        let model = &scene.species[p.species].model;
        if let Some(h) = h {
            assert!((p.scale * model.height() - h as f32).abs() < 1e-3, "scale {} for height {h}", p.scale);
        }
    }
    // No height: the plan's scale range; the crown diameter of 6 m sets the last one's width.
    assert!((0.9..=1.1).contains(&plants[3].scale));
    let (lo, hi) = scene.species[species("oak")].model.bounds();
    let width = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    assert!((plants[4].scale * width - 6.0).abs() < 1e-3);
}

/// British National Grid as QGIS and ArcGIS write it in a `.prj` (ESRI WKT, no EPSG code).
const BNG_PRJ: &str = r#"PROJCS["OSGB_1936_British_National_Grid",GEOGCS["GCS_OSGB 1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0],UNIT["Degree",0.017453292519943295]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",49],PARAMETER["central_meridian",-2],PARAMETER["scale_factor",0.9996012717],PARAMETER["false_easting",400000],PARAMETER["false_northing",-100000],UNIT["Meter",1]]"#;

/// Writes `shapes` with a `species` text and a `height` number per feature as the Shapefile
/// `name` (`.shp`, `.shx`, `.dbf`) in `dir`, with a `.prj` of British National Grid if `prj`.
fn write_shapefile(dir: &Path, name: &str, shapes: &[(geo::Geometry<f64>, &str, f64)], prj: bool) -> PathBuf {
    use shapefile::dbase::{FieldValue, Record, TableWriterBuilder};
    let path = dir.join(name);
    let table = TableWriterBuilder::new().add_character_field("species".try_into().unwrap(), 20).add_numeric_field(
        "height".try_into().unwrap(),
        10,
        2,
    );
    let mut writer = shapefile::Writer::from_path(&path, table).unwrap();
    for (geometry, species, height) in shapes {
        let mut record = Record::default();
        record.insert("species".into(), FieldValue::Character(Some(species.to_string())));
        record.insert("height".into(), FieldValue::Numeric(Some(*height)));
        match shapefile::Shape::try_from(geometry.clone()).unwrap() {
            shapefile::Shape::Polygon(s) => writer.write_shape_and_record(&s, &record).unwrap(),
            shapefile::Shape::Polyline(s) => writer.write_shape_and_record(&s, &record).unwrap(),
            shapefile::Shape::Point(s) => writer.write_shape_and_record(&s, &record).unwrap(),
            other => panic!("no writer for {other}"),
        }
    }
    drop(writer);
    if prj {
        std::fs::write(path.with_extension("prj"), BNG_PRJ).unwrap();
    }
    path
}

#[test]
fn shapefile_plans_place_the_same_plants_as_the_same_features_in_geojson() {
    let dir = tempfile::tempdir().unwrap();
    let polygon = geo::Geometry::Polygon(geo::Polygon::new(
        WOOD.iter().map(|&(e, n)| geo::coord! { x: e, y: n }).collect(),
        vec![],
    ));
    let (a, b) = ((321_050.0, 129_050.0), (321_350.0, 129_130.0));
    let hedge = geo::Geometry::LineString(vec![geo::coord! { x: a.0, y: a.1 }, geo::coord! { x: b.0, y: b.1 }].into());
    let trees = [(321_100.0, 129_100.0, "OAK", 18.0), (321_300.0, 129_250.0, "pine", 12.0)];
    let areas = write_shapefile(dir.path(), "wood.shp", &[(polygon, "oak", 0.0)], true);
    let lines = write_shapefile(dir.path(), "hedges.shp", &[(hedge, "hawthorn", 0.0)], true);
    let points: Vec<_> =
        trees.iter().map(|&(e, n, s, h)| (geo::Geometry::Point(geo::Point::new(e, n)), s, h)).collect();
    let points = write_shapefile(dir.path(), "trees.shp", &points, true);
    let plans = |areas: &Path, lines: &Path, points: &Path| {
        format!(
            "[[layers.plans]]\nkind = \"areas\"\nfile = \"{}\"\ndensity = 150\nmin_spacing = 2.0\n\
             [[layers.plans]]\nkind = \"hedgerows\"\nfile = \"{}\"\nspacing = 0.8\nrows = 2\nrow_spacing = 0.6\n\
             [[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\nspecies_map = {{ OAK = \"oak\" }}\n",
            areas.display(),
            lines.display(),
            points.display()
        )
    };
    let from_shp = load(&plan_scene(dir.path(), &plans(&areas, &lines, &points), 7));
    // The same features as GeoJSON in British National Grid (a `crs` member).
    let ring: Vec<String> = WOOD.iter().chain(WOOD.first()).map(|(e, n)| format!("[{e}, {n}]")).collect();
    let wood = write(
        dir.path(),
        "wood.geojson",
        &collection(
            &[feature(
                &format!(r#"{{"type": "Polygon", "coordinates": [[{}]]}}"#, ring.join(", ")),
                r#""species": "oak""#,
            )],
            Some(27700),
        ),
    );
    let line = format!(r#"{{"type": "LineString", "coordinates": [[{}, {}], [{}, {}]]}}"#, a.0, a.1, b.0, b.1);
    let hedges =
        write(dir.path(), "hedges.geojson", &collection(&[feature(&line, r#""species": "hawthorn""#)], Some(27700)));
    let points_json = write(dir.path(), "trees.geojson", &collection(&point_features(&trees, "species"), Some(27700)));
    let from_json = load(&plan_scene(dir.path(), &plans(&wood, &hedges, &points_json), 7));
    let (shp, json) = (&from_shp.layers[0].plants, &from_json.layers[0].plants);
    assert!(shp.len() > 100, "{} plants", shp.len());
    assert_eq!(shp.len(), json.len());
    for (p, q) in shp.iter().zip(json) {
        assert_eq!(p.species, q.species);
        assert!(
            (p.position[0] - q.position[0]).abs() < 1e-3 && (p.position[1] - q.position[1]).abs() < 1e-3,
            "{p:?} vs {q:?}"
        );
        assert!((p.scale - q.scale).abs() < 1e-4);
    }
    // The tree points' heights come from the `.dbf`.
    let oak = from_shp.species.iter().position(|s| s.name == "oak").unwrap();
    let last = &shp[shp.len() - 2];
    assert_eq!(last.species, oak);
    assert!((last.scale * from_shp.species[oak].model.height() - 18.0).abs() < 1e-3);

    // Without a `.prj` the file's CRS must be given; with `crs` it loads.
    let bare = write_shapefile(
        dir.path(),
        "bare.shp",
        &[(geo::Geometry::Point(geo::Point::new(321_100.0, 129_100.0)), "oak", 9.0)],
        false,
    );
    let one = |extra: &str| format!("[[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\n{extra}", bare.display());
    let err = load_err(&plan_scene(dir.path(), &one(""), 1));
    assert!(err.contains("bare.shp") && err.contains("bare.prj") && err.contains("crs"), "{err}");
    let scene = load(&plan_scene(dir.path(), &one("crs = \"EPSG:27700\"\n"), 1));
    assert!((f64::from(scene.layers[0].plants[0].position[0]) - (321_100.0 - ORIGIN.0)).abs() < 1e-3);
    // A `.shp` without its `.dbf`, and one that is not a Shapefile, are refused by name.
    std::fs::remove_file(bare.with_extension("dbf")).unwrap();
    let err = load_err(&plan_scene(dir.path(), &one("crs = \"EPSG:27700\"\n"), 1));
    assert!(err.contains("bare.dbf"), "{err}");
    let junk = write(dir.path(), "junk.shp", "not a shapefile");
    std::fs::write(junk.with_extension("dbf"), "").unwrap();
    let err = load_err(&plan_scene(
        dir.path(),
        &format!("[[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\ncrs = \"EPSG:27700\"\n", junk.display()),
        1,
    ));
    assert!(err.contains("junk.shp") && err.contains("Shapefile"), "{err}");
}

#[test]
fn polygons_rasterized_as_landcover_drive_rules() {
    let dir = tempfile::tempdir().unwrap();
    let zones = write(
        dir.path(),
        "zones.geojson",
        &collection(
            &[feature(&format!(r#"{{"type": "Polygon", "coordinates": {}}}"#, ring_wgs84(&WOOD)), r#""class": 4"#)],
            None,
        ),
    );
    let layers = format!(
        "landcover = \"{}\"\n[layers.landcover_options]\ncell = 2.0\n[[layers.rules]]\nclass = 4\nspecies = \"pine\"\ndensity = 60.0\n",
        zones.display()
    );
    let scene = load(&plan_scene(dir.path(), &layers, 1));
    let plants = &scene.layers[0].plants;
    assert!(plants.len() > 100);
    // Within one 2 m cell of the polygon.
    for p in plants {
        let (x, y) = (f64::from(p.position[0]), f64::from(p.position[1]));
        let near = [(0.0, 0.0), (2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (0.0, -2.0)]
            .iter()
            .any(|(dx, dy)| inside(&WOOD, x + dx, y + dy));
        assert!(near, "plant at ({x}, {y}) away from the polygon");
    }
}

#[test]
fn bad_vector_input_names_the_file_and_the_feature() {
    let dir = tempfile::tempdir().unwrap();
    let areas = |file: &Path| {
        format!("[[layers.plans]]\nkind = \"areas\"\nfile = \"{}\"\nspecies = \"oak\"\ndensity = 50\n", file.display())
    };
    let poly = |corners: &[(f64, f64)]| format!(r#"{{"type": "Polygon", "coordinates": {}}}"#, ring_wgs84(corners));

    let not_json = write(dir.path(), "notes.geojson", "woodland along the brook");
    let err = load_err(&plan_scene(dir.path(), &areas(&not_json), 1));
    assert!(err.contains("notes.geojson") && err.contains("not GeoJSON"), "{err}");

    let not_geojson = write(dir.path(), "list.geojson", r#"{"trees": [1, 2]}"#);
    let err = load_err(&plan_scene(dir.path(), &areas(&not_geojson), 1));
    assert!(err.contains("list.geojson") && err.contains("not GeoJSON"), "{err}");

    let far = [(330_000.0, 140_000.0), (330_100.0, 140_000.0), (330_100.0, 140_100.0)];
    let outside =
        write(dir.path(), "outside.geojson", &collection(&[feature(&poly(&WOOD), ""), feature(&poly(&far), "")], None));
    let err = load_err(&plan_scene(dir.path(), &areas(&outside), 1));
    assert!(err.contains("outside.geojson: feature 1") && err.contains("does not overlap the terrain"), "{err}");

    let bowtie = [(321_050.0, 129_050.0), (321_150.0, 129_150.0), (321_150.0, 129_050.0), (321_050.0, 129_150.0)];
    let crossed = write(
        dir.path(),
        "crossed.geojson",
        &collection(&[feature(&poly(&WOOD), ""), feature(&poly(&bowtie), "")], None),
    );
    let err = load_err(&plan_scene(dir.path(), &areas(&crossed), 1));
    assert!(err.contains("crossed.geojson: feature 1") && err.contains("self-intersection"), "{err}");

    let palm = write(dir.path(), "palm.geojson", &collection(&[feature(&poly(&WOOD), r#""species": "palm""#)], None));
    let err = load_err(&plan_scene(dir.path(), &areas(&palm), 1));
    assert!(err.contains("palm.geojson: feature 0") && err.contains("unknown species 'palm'"), "{err}");

    let undefined = write(dir.path(), "undefined.geojson", &collection(&[feature(&poly(&WOOD), "")], Some(99999)));
    let err = load_err(&plan_scene(dir.path(), &areas(&undefined), 1));
    assert!(err.contains("undefined.geojson") && err.contains("EPSG:99999"), "{err}");

    // Projected coordinates in a file without crs member are not taken for lon/lat.
    let square = r#"{"type": "Polygon", "coordinates": [[[321050, 129050], [321150, 129050], [321150, 129150], [321050, 129050]]]}"#;
    let bng = write(dir.path(), "bng.geojson", &collection(&[feature(square, "")], None));
    let err = load_err(&plan_scene(dir.path(), &areas(&bng), 1));
    assert!(err.contains("bng.geojson: feature 0") && err.contains("longitude/latitude"), "{err}");

    let csv = write(dir.path(), "bad.csv", "x,y,species\n321100,north,oak\n");
    let err = load_err(&plan_scene(
        dir.path(),
        &format!("[[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\n", csv.display()),
        1,
    ));
    assert!(err.contains("bad.csv: feature 0") && err.contains("\"north\""), "{err}");

    // A layer with neither land cover nor plans.
    let dem = bng_dem(dir.path());
    let err = load_err(&scene(dir.path(), &dem, "[[layers]]\nname = \"empty\"\n"));
    assert!(err.contains("empty") && err.contains("plans"), "{err}");
    assert!(matches!(Scene::load(&dir.path().join("missing.toml")), Err(SceneError::Io { .. })));
}

#[test]
fn a_large_dem_is_cropped_to_the_scene_extent_and_averaged_down_to_max_cells() {
    let dir = tempfile::tempdir().unwrap();
    // 400 × 400 cells of 1 m in British National Grid, heights 100 + 0.1 per column eastwards.
    let dem = dir.path().join("lidar.tif");
    write_dem(&dem, Crs::Projected { epsg: Some(27700), unit_to_metre: 1.0 }, 321_000.0, 129_400.0, 1.0, 400);
    let with = |terrain: &str| {
        let text = format!(
            "name = \"large\"\n[terrain]\ndem = \"{}\"\n{terrain}\n[camera]\nposition = [0.0, 0.0]\nyaw = 0.0\n",
            dem.display()
        );
        write(dir.path(), "large.toml", &text)
    };
    // The village's 200 m × 200 m, at most 10,000 cells: 200 × 200 cells averaged by 2.
    let scene = load(&with("extent = [321100, 129100, 321300, 129300]\nmax_cells = 10000"));
    let grid = &scene.terrain.dem;
    assert_eq!((grid.width, grid.height), (100, 100));
    assert_eq!(
        (grid.transform.cell_width, grid.transform.origin_x, grid.transform.origin_y),
        (2.0, 321_100.0, 129_300.0)
    );
    assert_eq!(scene.terrain.frame.origin_crs(), (321_200.0, 129_200.0));
    // A plane stays the plane: the height at a point is the DEM's there.
    for (e, n) in [(321_150.0, 129_250.0), (321_201.0, 129_199.0), (321_290.0, 129_110.0)] {
        let h = scene.terrain.height_at(e - 321_200.0, n - 129_200.0).unwrap();
        let expected = 100.0 + 0.1 * (e - 321_000.0 - 0.5);
        assert!((h - expected).abs() < 1e-4, "height {h} at E {e}, expected {expected}");
    }
    // Without a crop the whole tile, averaged by 4 to fit.
    let whole = load(&with("max_cells = 10000"));
    assert_eq!(
        (whole.terrain.dem.width, whole.terrain.dem.height, whole.terrain.dem.transform.cell_width),
        (100, 100, 4.0)
    );
    // The default keeps a DEM of up to 2048 × 2048 cells as it is.
    assert_eq!(load(&with("")).terrain.dem.width, 400);
    // Bad windows and limits are refused naming the key (and the DEM).
    let err = load_err(&with("extent = [0, 0, 10, 10]"));
    assert!(err.contains("terrain.extent") && err.contains("lidar.tif") && err.contains("does not overlap"), "{err}");
    let err = load_err(&with("extent = [321300, 129100, 321100, 129300]"));
    assert!(err.contains("terrain.extent") && err.contains("min < max"), "{err}");
    let err = load_err(&with("max_cells = 1"));
    assert!(err.contains("terrain.max_cells"), "{err}");
}

/// The shared Kingston St Mary data (tests only; see ../shared/data/SOURCES.md for licences).
fn shared(name: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kingston_st_mary").join(name);
    p.exists().then_some(p)
}

#[test]
fn real_tree_preservation_orders_on_the_real_lidar_dtm() {
    let (Some(dtm), Some(tpo)) = (shared("dtm_1m.tif"), shared("tpo_trees.wgs84.geojson")) else {
        eprintln!("../shared/data/kingston_st_mary not present; skipped");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // The register's species as written (typos and notes included) → the scene's species;
    // trees without a species get the plan's `species`.
    let broadleaf = [
        "OAK",
        "ACER",
        "BEECH",
        "SYCAMORE",
        "ASH",
        "MACROCARRA",
        "PAPERBARK MAPLE",
        "MULLBERRY",
        "POPLAR",
        "CORK OAK",
        "HORSE CHESTNUT",
    ];
    let conifer = [
        "CEDAR",
        "CEDAR OF LEBANON",
        "FIR",
        "PINE",
        "CYPRESS",
        "WELLINGTONIA",
        "PINE - DEAD 3 NEW TREES PLANTED",
        "MONKEY PUZZLE - CROSSED OUT 7/7/97",
        "FIR - CROSSED OUT 7/7/97",
        "SCOTS PINE",
        "YEW",
    ];
    let map: Vec<String> = broadleaf
        .iter()
        .map(|s| format!("\"{s}\" = \"oak\""))
        .chain(conifer.iter().map(|s| format!("\"{s}\" = \"pine\"")))
        .collect();
    let layers = format!(
        "[[layers]]\nname = \"protected\"\n[[layers.plans]]\nkind = \"plants\"\nfile = \"{}\"\nspecies = \"oak\"\n\
         species_property = \"Tree_speci\"\nspecies_map = {{ {} }}\n",
        tpo.display(),
        map.join(", ")
    );
    let village = load(&scene(dir.path(), &dtm, &layers));
    assert_eq!(village.terrain.frame.crs().epsg(), Some(27700));
    let plants = &village.layers[0].plants;
    // All 52 protected trees lie on the 1.8 km × 1.8 km tile.
    assert_eq!(plants.len(), 52);
    let pine = village.species.iter().position(|s| s.name == "pine").unwrap();
    assert_eq!(plants.iter().filter(|p| p.species == pine).count(), conifer.len() + 1, "CEDAR twice");
    // The shapefile gives the same trees in British National Grid (ogr2ogr wrote the WGS 84
    // copy): every placed tree stands within 5 m (a Helmert shift against OSTN15) of one.
    let bng = shapefile_points(&shared("tpo_trees.shp").unwrap());
    assert_eq!(bng.len(), 52);
    let (ox, oy) = village.terrain.frame.origin_crs();
    for p in plants {
        let (e, n) = (f64::from(p.position[0]) + ox, f64::from(p.position[1]) + oy);
        let d = bng.iter().map(|(x, y)| (x - e).hypot(y - n)).fold(f64::INFINITY, f64::min);
        assert!(d < 5.0, "tree at E {e:.1}, N {n:.1} is {d:.1} m from the shapefile's nearest");
    }
    // The shapefile itself as the plan (`.prj` in ESRI WKT, species from the `.dbf`): the same
    // 52 trees at the shapefile's points, each of the species the GeoJSON copy gave it.
    let layers = layers.replace(&tpo.display().to_string(), &shared("tpo_trees.shp").unwrap().display().to_string());
    let from_shp = load(&scene(dir.path(), &dtm, &layers));
    let shp_plants = &from_shp.layers[0].plants;
    assert_eq!(shp_plants.len(), 52);
    for (p, &(x, y)) in shp_plants.iter().zip(&bng) {
        let (e, n) = (f64::from(p.position[0]) + ox, f64::from(p.position[1]) + oy);
        assert!(
            (e - x).abs() < 0.01 && (n - y).abs() < 0.01,
            "tree at E {e:.2}, N {n:.2}, shapefile E {x:.2}, N {y:.2}"
        );
        let nearest = plants
            .iter()
            .min_by(|a, b| {
                let d = |q: &&PlantInstance| (q.position[0] - p.position[0]).hypot(q.position[1] - p.position[1]);
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        assert_eq!(nearest.species, p.species);
    }
}

/// The points of a Shapefile of type Point (ESRI Shapefile Technical Description, 1998).
fn shapefile_points(path: &Path) -> Vec<(f64, f64)> {
    let bytes = std::fs::read(path).unwrap();
    let mut out = Vec::new();
    let mut pos = 100;
    while pos + 8 + 20 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize * 2;
        let rec = &bytes[pos + 8..pos + 8 + len];
        if i32::from_le_bytes(rec[0..4].try_into().unwrap()) == 1 {
            let x = f64::from_le_bytes(rec[4..12].try_into().unwrap());
            let y = f64::from_le_bytes(rec[12..20].try_into().unwrap());
            out.push((x, y));
        }
        pos += 8 + len;
    }
    out
}

#[test]
fn geojson_label_polygons_upload_as_a_label_field() {
    use landsketch::fields::{FieldFormat, FieldKind, LoadOptions, load_bytes};
    // Two fields of the Boulder foothills drawn in WGS 84, classes 3 and 7.
    let square = |x0: f64, y0: f64, class: u32| {
        feature(
            &format!(
                r#"{{"type": "Polygon", "coordinates": [[[{x0}, {y0}], [{}, {y0}], [{}, {}], [{x0}, {}], [{x0}, {y0}]]]}}"#,
                x0 + 0.01,
                x0 + 0.01,
                y0 + 0.01,
                y0 + 0.01
            ),
            &format!(r#""class": {class}"#),
        )
    };
    let text = collection(&[square(-105.50, 40.10, 3), square(-105.48, 40.10, 7)], None);
    assert_eq!(FieldFormat::detect(text.as_bytes(), Some("zones.geojson")).unwrap(), FieldFormat::GeoJson);
    let scratch = tempfile::tempdir().unwrap();
    let f = load_bytes(text.as_bytes(), Some("zones.geojson"), &LoadOptions::new(FieldKind::Label), scratch.path())
        .unwrap();
    assert_eq!(f.crs().crs().epsg(), Some(4326));
    assert_eq!(f.sample(0, -105.495, 40.105), Some(3.0));
    assert_eq!(f.sample(0, -105.475, 40.105), Some(7.0));
    assert_eq!(f.sample(0, -105.485, 40.105), None, "between the polygons");
    // A scalar GeoJSON, a missing property and JSON that is not GeoJSON are refused by name.
    let scalar =
        load_bytes(text.as_bytes(), Some("zones.geojson"), &LoadOptions::new(FieldKind::Scalar), scratch.path());
    assert!(scalar.unwrap_err().to_string().contains("kind=label"));
    let other = LoadOptions { variable: Some("zone".into()), ..LoadOptions::new(FieldKind::Label) };
    let err = load_bytes(text.as_bytes(), Some("zones.geojson"), &other, scratch.path()).unwrap_err().to_string();
    assert!(err.contains("zones.geojson") && err.contains("feature 0") && err.contains("'zone'"), "{err}");
    let err = load_bytes(br#"{"trees": 1}"#, Some("t.geojson"), &LoadOptions::new(FieldKind::Label), scratch.path())
        .unwrap_err();
    assert!(err.to_string().contains("t.geojson") && err.to_string().contains("not GeoJSON"), "{err}");
}
