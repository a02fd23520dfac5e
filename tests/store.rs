//! A2 persistence: the layer store in a data directory — uploads, listing, reopening,
//! atomic writes, deletion, name sanitising, limits and bad uploads that leave the store
//! unchanged. Fixtures: `data/test/` (see `data/test/README.md`).

use std::fs;
use std::path::{Path, PathBuf};

use landsketch::fields::{ColorMapSpec, FieldKind, SceneGeo, parse_time};
use landsketch::gis::read_geotiff;
use landsketch::scene::terrain::Terrain;
use landsketch::store::{Store, StoreError, StoreLimits, UploadRequest};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/test").join(name)
}

fn bytes(name: &str) -> Vec<u8> {
    fs::read(fixture(name)).unwrap()
}

fn boulder_scene() -> SceneGeo {
    let dem = read_geotiff(&fixture("boulder_SRTMGL3_derived.tif")).unwrap();
    SceneGeo::from_terrain(&Terrain::new(dem, [0.8; 3]).unwrap()).unwrap()
}

fn request(name: &str, kind: FieldKind) -> UploadRequest {
    UploadRequest { name: name.into(), kind: Some(kind), ..Default::default() }
}

/// Every file under `dir`, relative, sorted.
fn tree(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p.clone());
            }
            out.push(p.strip_prefix(dir).unwrap().display().to_string());
        }
    }
    out.sort();
    out
}

#[test]
fn upload_list_get_and_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let store = Store::open(dir.path()).unwrap();
    assert!(store.list().is_empty());
    let req = UploadRequest {
        filename: Some("checker.tif".into()),
        classes: Some("1=Low hazard,2=High hazard".into()),
        ..request("Fire hazard", FieldKind::Label)
    };
    let meta = store.add_upload(&bytes("fields/checker_label_utm13n.tif"), &req, &scene).unwrap();
    assert!(meta.id.starts_with("fire-hazard-"), "{}", meta.id);
    assert_eq!((meta.kind, meta.crs.as_str(), meta.source.as_str()), (FieldKind::Label, "EPSG:32613", "checker.tif"));
    assert_eq!(meta.extent, [461000.0, 4444600.0, 461400.0, 4445000.0]);
    assert_eq!((meta.min, meta.max), (1.0, 2.0));
    let classes: Vec<_> = meta.classes.iter().map(|c| (c.value, c.count, c.name.as_deref())).collect();
    assert_eq!(classes, [(1, 32, Some("Low hazard")), (2, 32, Some("High hazard"))]);
    assert_eq!(meta.steps.len(), 1);
    assert!(meta.steps[0].time.is_none() && meta.times().is_empty());
    assert!(meta.scene_extent.is_some());
    parse_time(&meta.created).unwrap();

    let nc = UploadRequest {
        filename: Some("plume.nc".into()),
        variable: Some("pm25".into()),
        ..request("PM2.5 plume", FieldKind::Scalar)
    };
    let plume = store.add_upload(&bytes("fields/plume_southup.nc"), &nc, &scene).unwrap();
    assert_eq!(plume.times(), ["2024-06-01T00:00:00Z", "2024-06-01T06:00:00Z", "2024-06-01T12:00:00Z"]);
    assert_eq!(plume.units.as_deref(), Some("ug/m3"));
    assert!((plume.max - 28.4).abs() < 1e-4, "{}", plume.max);

    let names: Vec<String> = store.list().into_iter().map(|m| m.name).collect();
    assert_eq!(names, ["Fire hazard", "PM2.5 plume"]);
    let before_field = store.field(&plume.id).unwrap();
    drop(store);

    let reopened = Store::open(dir.path()).unwrap();
    assert_eq!(reopened.list().len(), 2);
    assert_eq!(reopened.get(&meta.id).unwrap(), meta);
    let field = reopened.field(&plume.id).unwrap();
    assert_eq!(field.times(), before_field.times());
    for (a, b) in field.steps().iter().zip(before_field.steps()) {
        assert_eq!(a.raster.data.len(), b.raster.data.len());
        for (x, y) in a.raster.data.iter().zip(&b.raster.data) {
            assert!(x.is_nan() && y.is_nan() || (x - y).abs() < 1e-6, "{x} {y}");
        }
    }
    let label = reopened.field(&meta.id).unwrap();
    assert_eq!(label.classes()[1].name.as_deref(), Some("High hazard"));

    // Legend of a stored layer: PNG and JSON.
    let legend = reopened.legend(&meta.id, &ColorMapSpec::default()).unwrap();
    let png = image::load_from_memory(&legend.to_png().unwrap()).unwrap().to_rgba8();
    assert_eq!(png.dimensions(), (320, 64));
    assert_eq!(png.get_pixel(18, 28).0, [0x4e, 0x79, 0xa7, 255]);
    let json = serde_json::to_value(reopened.legend(&plume.id, &ColorMapSpec::default()).unwrap()).unwrap();
    assert_eq!(json["units"], "ug/m3");
    assert_eq!(json["stops"][0], "#440154");
}

#[test]
fn series_steps_append_to_a_layer() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let store = Store::open(dir.path()).unwrap();
    let step = |file: &str, time: Option<&str>| UploadRequest {
        time: time.map(str::to_string),
        filename: Some(file.into()),
        ..request("Soil moisture", FieldKind::Scalar)
    };
    let first =
        store.add_upload(&bytes("fields/series_2024-06-11.tif"), &step("b.tif", Some("2024-06-11")), &scene).unwrap();
    let both =
        store.add_upload(&bytes("fields/series_2024-06-01.tif"), &step("a.tif", Some("2024-06-01")), &scene).unwrap();
    assert_eq!(both.id, first.id);
    assert_eq!(both.times(), ["2024-06-01T00:00:00Z", "2024-06-11T00:00:00Z"]);
    assert_eq!((both.min, both.max), (0.0, 34.0));
    assert_eq!(store.list().len(), 1);
    // The same time again, or a step without time, is refused; the layer is unchanged.
    let dup = store
        .add_upload(&bytes("fields/series_2024-06-01.tif"), &step("a.tif", Some("2024-06-01")), &scene)
        .unwrap_err();
    assert_eq!(dup.status(), 409, "{dup}");
    assert!(dup.to_string().contains("appears twice"), "{dup}");
    let untimed = store.add_upload(&bytes("fields/series_2024-06-01.tif"), &step("a.tif", None), &scene).unwrap_err();
    assert_eq!(untimed.status(), 409, "{untimed}");
    let label = UploadRequest { kind: Some(FieldKind::Label), ..step("a.tif", Some("2024-07-01")) };
    assert_eq!(store.add_upload(&bytes("fields/series_2024-06-01.tif"), &label, &scene).unwrap_err().status(), 409);
    assert_eq!(store.get(&first.id).unwrap(), both);
    let files = fs::read_dir(dir.path().join("layers").join(&first.id)).unwrap().count();
    assert_eq!(files, 3, "meta.json and two step files");
    let reopened = Store::open(dir.path()).unwrap();
    let f = reopened.field(&first.id).unwrap();
    let t = parse_time("2024-06-06").unwrap();
    assert_eq!(f.time_sample(Some(t)).weight, 0.5);
}

#[test]
fn interrupted_writes_are_cleaned_and_never_listed() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let id = {
        let store = Store::open(dir.path()).unwrap();
        let req = UploadRequest { time: Some("2024-06-01".into()), ..request("ramp", FieldKind::Scalar) };
        store.add_upload(&bytes("fields/series_2024-06-01.tif"), &req, &scene).unwrap().id
    };
    // Simulate crashes: a staged layer in tmp/, a half-written file, an orphan step in a
    // layer, a layer directory whose meta.json never arrived, and a garbage meta.json.
    let root = dir.path();
    fs::create_dir_all(root.join("tmp/new-half-0123/")).unwrap();
    fs::write(root.join("tmp/new-half-0123/step-00aa.f32"), [0u8; 12]).unwrap();
    fs::write(root.join("tmp/upload-1-0.tif"), b"II*\0").unwrap();
    fs::write(root.join("layers").join(&id).join("step-00ff.f32"), [0u8; 36]).unwrap();
    fs::write(root.join("layers").join(&id).join(".meta.json.tmp-1"), b"{").unwrap();
    fs::create_dir_all(root.join("layers/half-layer-00000000")).unwrap();
    fs::write(root.join("layers/half-layer-00000000/step-0001.f32"), [0u8; 36]).unwrap();
    fs::create_dir_all(root.join("layers/bad-meta-00000000")).unwrap();
    fs::write(root.join("layers/bad-meta-00000000/meta.json"), b"{\"format\": 1, \"id\"").unwrap();

    let store = Store::open(root).unwrap();
    let listed: Vec<String> = store.list().into_iter().map(|m| m.id).collect();
    assert_eq!(listed, std::slice::from_ref(&id));
    assert_eq!(tree(&root.join("tmp")), Vec::<String>::new(), "tmp/ emptied");
    let layer_files = tree(&root.join("layers").join(&id));
    assert_eq!(layer_files.len(), 2, "{layer_files:?}");
    assert!(layer_files.contains(&"meta.json".to_string()));
    assert!(store.field(&id).is_ok());
    assert_eq!(store.get("half-layer-00000000").unwrap_err().status(), 404);
}

#[test]
fn delete_and_unknown_ids() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let store = Store::open(dir.path()).unwrap();
    let meta =
        store.add_upload(&bytes("fields/checker_label_utm13n.tif"), &request("a", FieldKind::Label), &scene).unwrap();
    let other =
        store.add_upload(&bytes("fields/checker_label_utm13n.tif"), &request("b", FieldKind::Label), &scene).unwrap();
    assert_eq!(store.delete(&meta.id).unwrap(), meta);
    assert_eq!(store.get(&meta.id).unwrap_err().status(), 404);
    assert_eq!(store.delete(&meta.id).unwrap_err().status(), 404);
    assert!(!dir.path().join("layers").join(&meta.id).exists());
    for bad in ["../layers", "", "../../etc/passwd", "A", "b"] {
        assert!(matches!(store.get(bad), Err(StoreError::NotFound { .. })), "{bad}");
        assert!(matches!(store.field(bad), Err(StoreError::NotFound { .. })), "{bad}");
    }
    drop(store);
    let reopened = Store::open(dir.path()).unwrap();
    assert_eq!(reopened.list().into_iter().map(|m| m.id).collect::<Vec<_>>(), [other.id]);
}

#[test]
fn names_never_reach_paths() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let store = Store::open(dir.path().join("data").as_path()).unwrap();
    let meta = store
        .add_upload(&bytes("fields/checker_label_utm13n.tif"), &request("../../etc/passwd", FieldKind::Label), &scene)
        .unwrap();
    assert_eq!(meta.name, "../../etc/passwd");
    assert!(meta.id.starts_with("etc-passwd-") && !meta.id.contains('/') && !meta.id.contains('.'), "{}", meta.id);
    let outside: Vec<String> = tree(dir.path()).into_iter().filter(|p| !p.starts_with("data")).collect();
    assert!(outside.is_empty(), "{outside:?}");
    assert!(dir.path().join("data/layers").join(&meta.id).join("meta.json").exists());
    for bad in ["", "   ", "a\u{0}b", "line\nbreak"] {
        let err = store.add_upload(&bytes("fields/checker_label_utm13n.tif"), &request(bad, FieldKind::Label), &scene);
        assert_eq!(err.unwrap_err().status(), 422, "{bad:?}");
    }
}

#[test]
fn bad_uploads_leave_the_store_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let scene = boulder_scene();
    let limits = StoreLimits { max_upload_bytes: 300_000, max_cells: 1 << 20, ..StoreLimits::default() };
    let store = Store::open_with_limits(dir.path(), limits).unwrap();
    store.add_upload(&bytes("fields/checker_label_utm13n.tif"), &request("keep", FieldKind::Label), &scene).unwrap();
    let before = tree(dir.path());
    let listed = store.list();

    let tif = bytes("fields/series_2024-06-01.tif");
    let huge_header = tiff_header(100_000, 100_000);
    let cases: Vec<(&str, Vec<u8>, UploadRequest, u16, &str)> = vec![
        ("garbage", b"this is not a raster".to_vec(), request("g", FieldKind::Scalar), 422, "not a TIFF"),
        ("truncated tiff", tif[..tif.len() / 2].to_vec(), request("t", FieldKind::Scalar), 422, "t.tif"),
        ("enormous by header", huge_header, request("h", FieldKind::Scalar), 413, "100000 × 100000"),
        ("too many bytes", vec![0u8; 300_001], request("b", FieldKind::Scalar), 413, "upload"),
        ("no kind", tif.clone(), UploadRequest { name: "k".into(), ..Default::default() }, 422, "kind"),
        (
            "label of floats",
            bytes("boulder_crop_f32_fpredict.tif"),
            request("f", FieldKind::Label),
            422,
            "at most 64 classes",
        ),
        (
            "bad crs",
            tif.clone(),
            UploadRequest { crs: Some("EPSG:26712".into()), ..request("c", FieldKind::Scalar) },
            422,
            "EPSG:26712",
        ),
        (
            "asc without crs",
            bytes("fields/ramp_scalar_4326.asc"),
            request("a", FieldKind::Scalar),
            422,
            "no coordinate reference system",
        ),
        (
            "bad time",
            tif.clone(),
            UploadRequest { time: Some("June".into()), ..request("d", FieldKind::Scalar) },
            422,
            "June",
        ),
        (
            "outside the scene",
            bytes("bcsd_obs_1999.nc"),
            UploadRequest { variable: Some("tas".into()), ..request("n", FieldKind::Scalar) },
            422,
            "-105.5504",
        ),
        ("netcdf4", b"\x89HDF\r\n\x1a\nrest".to_vec(), request("h5", FieldKind::Scalar), 422, "NetCDF-4"),
        (
            "classes on scalar",
            tif.clone(),
            UploadRequest { classes: Some("1=a".into()), ..request("s", FieldKind::Scalar) },
            422,
            "label",
        ),
    ];
    for (what, body, mut req, status, text) in cases {
        req.filename.get_or_insert_with(|| format!("{}.tif", req.name));
        let err = store.add_upload(&body, &req, &scene).unwrap_err();
        assert_eq!(err.status(), status, "{what}: {err}");
        assert!(err.to_string().contains(text), "{what}: {err}");
        assert_eq!(tree(dir.path()), before, "{what}: files changed");
        assert_eq!(store.list(), listed, "{what}: listing changed");
    }
    // The ASCII grid works with an explicit CRS or the scene's.
    let asc = bytes("fields/ramp_scalar_4326.asc");
    let ok = UploadRequest { crs: Some("scene".into()), ..request("ramp", FieldKind::Scalar) };
    assert_eq!(store.add_upload(&asc, &ok, &scene).unwrap().crs, "EPSG:4326");
    let ok = UploadRequest { crs: Some("EPSG:4326".into()), ..request("ramp 2", FieldKind::Scalar) };
    assert!(store.add_upload(&asc, &ok, &scene).is_ok());
}

/// A little-endian TIFF whose header announces `w × h` 8-bit cells and holds no image data.
fn tiff_header(w: u32, h: u32) -> Vec<u8> {
    let mut b = b"II*\0\x08\0\0\0".to_vec();
    let entries: [(u16, u16, u32); 8] = [
        (256, 4, w),
        (257, 4, h),
        (258, 3, 8),
        (259, 3, 1),
        (262, 3, 1),
        (273, 4, 200),
        (278, 4, h),
        (279, 4, w.saturating_mul(h)),
    ];
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        if ty == 3 {
            b.extend_from_slice(&(value as u16).to_le_bytes());
            b.extend_from_slice(&[0, 0]);
        } else {
            b.extend_from_slice(&value.to_le_bytes());
        }
    }
    b.extend_from_slice(&[0; 4]);
    b
}

/// A scalar field of one `side` × `side` step at `2024-06-<day>` covering the sample DEM,
/// every cell `day`.
fn big_step(side: usize, day: u32) -> landsketch::fields::Field {
    use landsketch::fields::{Field, FieldStep};
    use landsketch::gis::{CrsDefinition, GeoTransform, Raster};
    let dem = read_geotiff(&fixture("boulder_SRTMGL3_derived.tif")).unwrap();
    let e = dem.extent();
    let raster = Raster {
        width: side,
        height: side,
        data: vec![f64::from(day); side * side],
        nodata: None,
        transform: GeoTransform {
            origin_x: e.min_x,
            origin_y: e.max_y,
            cell_width: (e.max_x - e.min_x) / side as f64,
            cell_height: (e.max_y - e.min_y) / side as f64,
        },
        crs: dem.crs,
        palette: None,
    };
    let time = Some(parse_time(&format!("2024-06-{day:02}T00:00:00Z")).unwrap());
    let crs = CrsDefinition::from_crs(&dem.crs).unwrap();
    Field::new(FieldKind::Scalar, crs, None, vec![FieldStep { time, raster }]).unwrap()
}

/// D7: a writer holds no lock that readers need. While a 64 MB time step is appended
/// (written and fsynced) to a series of two such steps, listings and lookups answer at
/// once instead of waiting for the append, which no longer reads the stored steps.
#[test]
fn reads_do_not_wait_for_a_large_append() {
    const SIDE: usize = 4096;
    let dir = tempfile::tempdir().unwrap();
    let scene = std::sync::Arc::new(boulder_scene());
    let store = std::sync::Arc::new(Store::open(dir.path()).unwrap());
    for day in 1..=2 {
        store.add_field("Big", big_step(SIDE, day), "big.tif", &scene).unwrap();
    }
    let third = big_step(SIDE, 3);
    let writer = {
        let (store, scene) = (store.clone(), scene.clone());
        std::thread::spawn(move || store.add_field("Big", third, "big.tif", &scene))
    };
    let mut slowest = std::time::Duration::ZERO;
    let mut reads = 0;
    while !writer.is_finished() {
        let started = std::time::Instant::now();
        assert_eq!(store.list().len(), 1);
        assert!(store.find_by_name("Big").is_some());
        slowest = slowest.max(started.elapsed());
        reads += 1;
    }
    let meta = writer.join().unwrap().unwrap();
    assert_eq!(meta.steps.len(), 3);
    assert_eq!((meta.min, meta.max), (1.0, 3.0));
    assert_eq!(store.field(&meta.id).unwrap().steps().len(), 3, "every step reads back");
    // Milliseconds even on a loaded machine; the old lock was held for the whole append.
    assert!(reads > 0 && slowest < std::time::Duration::from_millis(500), "{reads} reads, slowest {slowest:?}");
}
