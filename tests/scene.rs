//! Scene file loading, terrain and vegetation placement (SPEC S1, S2, S5).

use landsketch::gis::{Crs, GeoTransform, Raster};
use landsketch::scene::terrain::Terrain;
use landsketch::scene::vegetation::{PlacementRule, PlantInstance, place, place_reporting};
use landsketch::scene::{Scene, SceneError};
use std::path::{Path, PathBuf};

const SAMPLE: &str = "data/boulder/scene.toml";

/// A projected raster of `n` × `n` cells of `cell` metres whose values come from `value(col, row)`.
fn raster(n: usize, cell: f64, nodata: Option<f64>, value: impl Fn(usize, usize) -> f64) -> Raster {
    Raster {
        width: n,
        height: n,
        data: (0..n * n).map(|i| value(i % n, i / n)).collect(),
        nodata,
        transform: GeoTransform { origin_x: 500_000.0, origin_y: 4_400_500.0, cell_width: cell, cell_height: cell },
        crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
        palette: None,
    }
}

/// 500 m × 500 m sloping terrain (10 m cells) with a nodata corner in the south-east, and
/// land cover of 5 m cells: class 4 in the west half, 6 in the east, nodata in the north-west
/// quarter.
fn fixture() -> (Terrain, Raster) {
    let dem = raster(50, 10.0, Some(-9999.0), |c, r| if c >= 40 && r >= 40 { -9999.0 } else { 100.0 + c as f64 });
    let landcover = raster(100, 5.0, Some(0.0), |c, r| match (c < 50, r < 50) {
        (true, true) => 0.0,
        (true, false) => 4.0,
        (false, _) => 6.0,
    });
    (Terrain::new(dem, [0.8; 3]).expect("terrain"), landcover)
}

fn rule(class: i64, density: f64) -> PlacementRule {
    PlacementRule { class, species: 0, density_per_ha: density, min_spacing: 2.0, scale: [0.8, 1.2] }
}

fn within(p: &PlantInstance, x: (f32, f32), y: (f32, f32)) -> bool {
    (x.0..x.1).contains(&p.position[0]) && (y.0..y.1).contains(&p.position[1])
}

#[test]
fn placement_is_deterministic_for_a_seed() {
    let (terrain, landcover) = fixture();
    let a = place(&terrain, &landcover, &[rule(4, 50.0)], 7, 100_000).unwrap();
    let b = place(&terrain, &landcover, &[rule(4, 50.0)], 7, 100_000).unwrap();
    let c = place(&terrain, &landcover, &[rule(4, 50.0)], 8, 100_000).unwrap();
    assert!(!a.is_empty());
    assert_eq!(a, b);
    assert_ne!(a, c);
}

#[test]
fn placement_reports_its_progress_within_the_layer() {
    let (terrain, landcover) = fixture();
    let reported = std::cell::RefCell::new(Vec::new());
    let rules = [rule(4, 50.0), rule(3, 20.0)];
    let placed = place_reporting(&terrain, &landcover, &rules, 7, 100_000, &|f| reported.borrow_mut().push(f)).unwrap();
    assert_eq!(placed, place(&terrain, &landcover, &rules, 7, 100_000).unwrap(), "reporting changes nothing");
    let reported = reported.into_inner();
    assert!(reported.len() > 20, "many steps within one layer: {reported:?}");
    assert!(reported.windows(2).all(|w| w[0] < w[1]), "rising: {reported:?}");
    assert_eq!((reported[0], reported[reported.len() - 1]), (0.0, 1.0));
}

#[test]
fn density_matches_the_rule_within_ten_percent() {
    let (terrain, landcover) = fixture();
    for density in [20.0, 50.0, 150.0] {
        let plants = place(&terrain, &landcover, &[rule(4, density)], 3, 100_000).unwrap();
        // A window fully inside class 4 and away from nodata: x −240..−20, y −240..−20 (4.84 ha).
        let inside = plants.iter().filter(|p| within(p, (-240.0, -20.0), (-240.0, -20.0))).count() as f64;
        let expected = density * 220.0 * 220.0 / 10_000.0;
        assert!((inside - expected).abs() <= 0.1 * expected, "density {density}: {inside} plants, expected {expected}");
    }
}

#[test]
fn plants_follow_class_nodata_and_terrain() {
    let (terrain, landcover) = fixture();
    let plants = place(&terrain, &landcover, &[rule(4, 80.0)], 1, 100_000).unwrap();
    for p in &plants {
        let [x, y, z] = p.position;
        // Class 4 only lies west of the centre line and south of the nodata quarter.
        assert!(x < 0.5 && y < 0.5, "plant at {x},{y} outside the class-4 quarter");
        let ground = terrain.height_at(f64::from(x), f64::from(y)).expect("plant stands on valid terrain");
        assert!((f64::from(z) - ground).abs() < 1e-3, "plant z {z} vs ground {ground}");
        assert!((0.8..=1.2).contains(&p.scale));
        assert!((0.0..std::f32::consts::TAU).contains(&p.rotation));
    }
    // The east half is class 6 and the DEM's south-east corner is nodata: a class-6 rule
    // places plants, but none on the nodata corner (x > 145, y < −145).
    let east = place(&terrain, &landcover, &[rule(6, 80.0)], 1, 100_000).unwrap();
    assert!(east.len() > 500);
    assert!(east.iter().all(|p| p.position[0] > -0.5));
    assert!(!east.iter().any(|p| within(p, (150.0, 250.0), (-250.0, -150.0))));
}

#[test]
fn minimum_spacing_is_respected_across_rules() {
    let (terrain, landcover) = fixture();
    let rules =
        [PlacementRule { min_spacing: 6.0, ..rule(4, 200.0) }, PlacementRule { min_spacing: 6.0, ..rule(4, 200.0) }];
    let plants = place(&terrain, &landcover, &rules, 5, 100_000).unwrap();
    for (i, a) in plants.iter().enumerate() {
        for b in &plants[i + 1..] {
            let d = (a.position[0] - b.position[0]).hypot(a.position[1] - b.position[1]);
            assert!(d >= 6.0 - 1e-3, "plants {d} m apart");
        }
    }
}

#[test]
fn too_many_plants_is_an_error_not_a_truncation() {
    let (terrain, landcover) = fixture();
    let err = place(&terrain, &landcover, &[rule(4, 100.0)], 1, 10).unwrap_err().to_string();
    assert!(err.contains("more than 10 plants"), "{err}");
}

#[test]
fn landcover_in_another_crs_is_rejected() {
    let (terrain, mut landcover) = fixture();
    landcover.crs = Crs::Geographic { epsg: Some(4326) };
    let err = place(&terrain, &landcover, &[rule(4, 10.0)], 1, 1000).unwrap_err().to_string();
    assert!(err.contains("CRS"), "{err}");
}

#[test]
fn terrain_mesh_has_unit_normals_and_skips_nodata() {
    let (terrain, _) = fixture();
    let mesh = &terrain.mesh;
    assert_eq!(mesh.positions.len(), 2500);
    // 49 × 49 quads minus the 10 × 10 that touch the nodata corner.
    assert_eq!(mesh.triangle_count(), 2 * (49 * 49 - 100));
    for n in &mesh.normals {
        assert!((glam::Vec3::from(*n).length() - 1.0).abs() < 1e-4);
    }
    // The DEM rises 1 m per 10 m eastwards: the normal leans west by atan(0.1).
    let n = glam::Vec3::from(mesh.normals[25 * 50 + 10]);
    assert!((n.x - (-0.1 / 1.01f32.sqrt())).abs() < 1e-4 && n.y.abs() < 1e-4, "{n:?}");
    // Heights in metres, positions in the local frame centred on the DEM.
    // The origin lies between columns 24 and 25 (heights 124 and 125).
    assert!((terrain.height_at(0.0, 0.0).unwrap() - 124.5).abs() < 1e-9);
}

#[test]
fn sample_scene_loads_with_two_layers() {
    let scene = Scene::load(Path::new(SAMPLE)).unwrap();
    assert_eq!(scene.layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>(), ["existing", "planned"]);
    assert!(scene.layers.iter().all(|l| l.plants.len() > 100));
    assert_eq!(scene.species.len(), 5);
    // The default camera stands 1.7 m above the terrain.
    let [x, y, z] = scene.default_camera.position;
    let ground = scene.terrain.height_at(f64::from(x), f64::from(y)).unwrap();
    assert!((f64::from(z) - ground - 1.7).abs() < 1e-3);
    // The DEM crop spans about 28 × 3″ of longitude and 22 × 3″ of latitude near 40.1° N.
    let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
    assert!(((x1 - x0) - 27.0 * 3.0 / 3600.0 * 85_300.0).abs() < 30.0, "{}", x1 - x0);
    assert!(((y1 - y0) - 21.0 * 3.0 / 3600.0 * 111_030.0).abs() < 30.0, "{}", y1 - y0);
}

/// Writes a copy of the sample scene with absolute paths, edited by `edit`, into a temp dir.
fn edited_sample(edit: impl Fn(String) -> String) -> (tempfile::TempDir, PathBuf) {
    let data = std::fs::canonicalize("data/boulder").unwrap();
    let text = std::fs::read_to_string(SAMPLE).unwrap();
    let text = text
        .replace("dem = \"", &format!("dem = \"{}/", data.display()))
        .replace("landcover = \"", &format!("landcover = \"{}/", data.display()))
        .replace("model = \"../", &format!("model = \"{}/../", data.display()));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, edit(text)).unwrap();
    (dir, path)
}

fn load_error(edit: impl Fn(String) -> String) -> String {
    let (_dir, path) = edited_sample(edit);
    match Scene::load(&path) {
        Ok(_) => panic!("scene loaded despite the edit"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn edited_copy_of_the_sample_still_loads() {
    let (_dir, path) = edited_sample(|t| t);
    assert!(Scene::load(&path).is_ok());
}

#[test]
fn scene_file_errors_name_file_and_problem() {
    let unknown = load_error(|t| t.replace("[sun]", "[sun]\ncolour = \"gold\""));
    assert!(unknown.contains("scene.toml") && unknown.contains("colour"), "{unknown}");

    let wrong_type = load_error(|t| {
        let line = t.lines().find(|l| l.starts_with("density =")).unwrap().to_owned();
        t.replacen(&line, "density = \"lots\"", 1)
    });
    assert!(wrong_type.contains("scene.toml") && wrong_type.contains("density"), "{wrong_type}");

    let species = load_error(|t| t.replacen("species = \"pine\"", "species = \"palm\"", 1));
    assert!(species.contains("palm") && species.contains("existing"), "{species}");

    let both = load_error(|t| t.replace("procedural = \"broadleaf\"", "procedural = \"broadleaf\"\nmodel = \"x.glb\""));
    assert!(both.contains("oak") && both.contains("exactly one"), "{both}");

    let missing_dem = load_error(|t| t.replace("dem.tif", "nowhere.tif"));
    assert!(missing_dem.contains("nowhere.tif"), "{missing_dem}");

    let missing_model = load_error(|t| t.replace("PineTree_1_textured.gltf", "Palm.gltf"));
    assert!(missing_model.contains("Palm.gltf"), "{missing_model}");

    let camera = load_error(|t| t.replace("position = [205.0, 185.0]", "position = [90000.0, 0.0]"));
    assert!(camera.contains("outside the terrain"), "{camera}");
    // A z read as a height above the ground puts the eye under it.
    let buried = load_error(|t| t.replace("position = [205.0, 185.0]", "position = [205.0, 185.0]\nz = 40.0"));
    assert!(buried.contains("below the terrain") && buried.contains("eye_height"), "{buried}");

    let plan = load_error(|t| t.replace("plan_layer = \"planned\"", "plan_layer = \"proposed\""));
    assert!(plan.contains("about.plan_layer") && plan.contains("proposed") && plan.contains("planned"), "{plan}");
    let about = load_error(|t| t.replace("[about]", "[about]\nsubtitle = \"x\""));
    assert!(about.contains("subtitle"), "{about}");
}

#[test]
fn a_text_file_is_not_a_dem() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("fake.tif");
    std::fs::write(&fake, "hello, not a TIFF").unwrap();
    let err = load_error(|t| {
        t.replace(
            &format!("{}/dem.tif", std::fs::canonicalize("data/boulder").unwrap().display()),
            &fake.display().to_string(),
        )
    });
    assert!(err.contains("fake.tif") && err.to_lowercase().contains("tiff"), "{err}");
    assert!(matches!(Scene::load(Path::new("data/boulder/missing.toml")), Err(SceneError::Io { .. })));
}

#[test]
fn render_takes_a_named_viewpoint_and_writes_jpeg_by_extension() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = |viewpoint: &str, out: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
            .args(["render", "--scene", SAMPLE, "--viewpoint", viewpoint, "--width", "64", "--height", "48"])
            .arg("--out")
            .arg(out)
            .output()
            .expect("run landsketch render")
    };
    // The sample's "Plan" viewpoint is a plan view: the same picture as `--plan` with its
    // centre, width and heading.
    let jpeg = dir.path().join("plan.jpg");
    let output = run("Plan", &jpeg);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let bytes = std::fs::read(&jpeg).expect("the JPEG");
    assert_eq!(&bytes[..2], &[0xFF, 0xD8], "a JPEG by the file's extension");
    let image = image::load_from_memory(&bytes).expect("decodes");
    assert_eq!((image.width(), image.height()), (64, 48));
    let png = dir.path().join("plan.png");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["render", "--scene", SAMPLE, "--plan", "-270,187,600", "--yaw", "0", "--width", "64", "--height", "48"])
        .arg("--out")
        .arg(&png)
        .output()
        .expect("run landsketch render --plan");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let by_flags = image::open(&png).expect("the PNG").to_rgb8();
    let by_viewpoint = image.to_rgb8();
    let close = by_flags
        .pixels()
        .zip(by_viewpoint.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0).all(|(x, y)| x.abs_diff(y) < 48))
        .count();
    assert!(
        close as f64 > 0.9 * f64::from(64 * 48),
        "the viewpoint's camera is the plan view's ({close} close pixels)"
    );
    // An unknown name is an error listing the scene's viewpoints.
    let output = run("Nowhere", &dir.path().join("x.png"));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success() && stderr.contains("\"Nowhere\"") && stderr.contains("\"Bird's-eye\""),
        "{stderr}"
    );
}

#[test]
fn render_takes_level_of_detail_thresholds_and_refuses_bad_ones() {
    let dir = tempfile::tempdir().expect("temp dir");
    let render = |lod: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
            .args(["render", "--scene", SAMPLE, "--width", "48", "--height", "32", "--no-cache", "--lod", lod])
            .arg("--out")
            .arg(dir.path().join("lod.png"))
            .output()
            .expect("run landsketch render")
    };
    let output = render(r#"{"hlp_px": 100, "full_px": 400}"#);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    for (lod, says) in [(r#"{"hlp_px": 1000}"#, "hlp_px <= full_px"), (r#"{"hlp": 1}"#, "unknown field `hlp`")] {
        let output = render(lod);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success() && stderr.contains(says), "--lod {lod}: {stderr}");
    }
}

#[test]
fn a_cli_error_is_a_message_naming_the_file_not_a_debug_dump() {
    let dir = tempfile::tempdir().expect("temp dir");
    let missing = dir.path().join("no such scene.toml");
    // Even with backtraces asked for in the environment (a developer's shell), a user reads a
    // message: what failed, on which file, why, once.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["render", "--scene"])
        .arg(&missing)
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("run landsketch render");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    let error = stderr.lines().find(|l| l.starts_with("Error: ")).unwrap_or_else(|| panic!("no error line: {stderr}"));
    assert!(error.contains(&missing.display().to_string()) && error.contains("cannot read scene file"), "{error}");
    assert_eq!(stderr.matches("No such file or directory").count(), 1, "the cause once: {stderr}");
    assert!(!stderr.contains("backtrace") && !stderr.contains("Caused by") && !stderr.contains("  0: "), "{stderr}");
    // A cause the message does not quote follows it.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["render", "--scene", SAMPLE, "--lod", r#"{"hlp": 1}"#])
        .output()
        .expect("run landsketch render");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("Error: --lod {\"hlp\": 1}: invalid JSON\n  caused by: unknown field `hlp`"), "{stderr}");
    // A style object with a field that is not a style field: the field is named, and the
    // message does not claim the object is not one.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["render", "--scene", SAMPLE, "--style", r#"{"mass_outline": 0}"#])
        .output()
        .expect("run landsketch render");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("Error: invalid style (a JSON object of style fields): {\"mass_outline\": 0}"), "{stderr}");
    assert!(stderr.contains("unknown field `mass_outline`") && !stderr.contains("expected an object"), "{stderr}");
    // An elevation under the ground (the sample's ground at the origin lies 2,340 m up) would draw
    // blank paper: the flag is named with what it gave.
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"))
        .args(["render", "--scene", SAMPLE, "--pos", "0,0,100"])
        .output()
        .expect("run landsketch render");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("Error: --pos 0,0,100: the eye is below the terrain"), "{stderr}");
}

#[test]
fn bench_lays_its_style_fields_over_every_preset_and_refuses_a_field_that_is_not_one() {
    let bench = |style: Option<&str>| {
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_landsketch"));
        command.args(["bench", "--scene", SAMPLE, "--plants", "100", "--styles", "full_npr,half_npr"]);
        command.args(["--frames", "1", "--width", "96", "--height", "64", "--no-cache", "--json"]);
        if let Some(style) = style {
            command.args(["--style", style]);
        }
        command.output().expect("run landsketch bench")
    };
    // Whether each preset's frames ran the creases pass (the terrain's ridge and valley lines).
    let creases = |output: &std::process::Output| -> Vec<bool> {
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("a JSON report");
        let styles = report["scenes"][0]["styles"].as_array().expect("styles").clone();
        let names: Vec<&str> = styles.iter().map(|s| s["style"].as_str().unwrap_or_default()).collect();
        assert_eq!(names, ["full_npr", "half_npr"]);
        styles.iter().map(|s| s["passes_ms"].get("creases").is_some()).collect()
    };
    assert_eq!(creases(&bench(None)), [true, true], "both presets draw the terrain's creases");
    assert_eq!(creases(&bench(Some(r#"{"terrain_creases": 0}"#))), [false, false], "the field reaches both presets");
    let output = bench(Some(r#"{"terrain_crease": 0}"#));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && stderr.contains("unknown field `terrain_crease`"), "{stderr}");
}
