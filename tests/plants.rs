//! Plant models: glTF loading (real sample files) and procedural plants.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use landsketch::scene::gltf_loader::load_gltf;
use landsketch::scene::plant::{ModelError, PartKind, PlantModel};
use landsketch::scene::procedural::{ProceduralKind, procedural_plant};

fn data(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(relative)
}

fn load(relative: &str) -> PlantModel {
    let path = data(relative);
    load_gltf(&path).unwrap_or_else(|e| panic!("{e}"))
}

const BOX_GLTF: &str = "test/gltf/BoxTextured-glTF/BoxTextured.gltf";

#[test]
fn box_textured_glb_and_gltf_load_the_same_geometry() {
    let glb = load("test/gltf/BoxTextured.glb");
    let gltf = load(BOX_GLTF);
    for model in [&glb, &gltf] {
        assert_eq!(model.triangle_count(), 12);
        assert_eq!(model.parts.len(), 1);
        let part = &model.parts[0];
        assert_eq!(part.kind, PartKind::Wood, "opaque material named 'Texture'");
        assert_eq!(part.material.alpha_cutoff, None);
        let texture = part.material.texture.as_ref().expect("texture");
        // CesiumLogoFlat.png is a 211 × 211 palette PNG.
        assert_eq!(texture.dimensions(), (211, 211));
        assert_eq!(model.bounds().0[2], 0.0);
        // A unit cube.
        assert!((model.height() - 1.0).abs() < 1e-5);
        assert_eq!(part.mesh.normals.len(), part.mesh.positions.len());
        assert_eq!(part.mesh.uvs.len(), part.mesh.positions.len());
    }
    assert_eq!(glb.parts[0].mesh, gltf.parts[0].mesh);
    assert_eq!(glb.parts[0].material.texture, gltf.parts[0].material.texture);
}

#[test]
fn normal_tree_splits_foliage_and_wood() {
    let tree = load("models/quaternius/NormalTree_1_textured.gltf");
    assert_eq!(tree.name, "NormalTree_1_textured");
    assert_eq!(tree.triangle_count(), 8_520);
    assert_eq!(tree.triangle_count_of(PartKind::Foliage), 3_728);
    assert_eq!(tree.triangle_count_of(PartKind::Wood), 4_792);
    for part in tree.parts_of(PartKind::Foliage) {
        assert_eq!(part.material.alpha_cutoff, Some(0.5));
        assert!(part.material.double_sided);
        let leaves = part.material.texture.as_ref().expect("leaf texture");
        assert_eq!(leaves.dimensions(), (256, 256));
        let transparent = leaves.pixels().filter(|p| p[3] < 128).count() as f64;
        let fraction = transparent / f64::from(256 * 256);
        assert!((0.5..0.8).contains(&fraction), "≈ 65 % transparent: {fraction}");
    }
    for part in tree.parts_of(PartKind::Wood) {
        assert_eq!(part.material.alpha_cutoff, None);
        // The bark PNG is 16-bit RGBA, converted to 8 bits.
        let bark = part.material.texture.as_ref().expect("bark texture");
        assert_eq!(bark.dimensions(), (256, 256));
        assert!(bark.pixels().any(|p| p[0] != bark.get_pixel(0, 0)[0]));
    }
    let (lo, hi) = tree.bounds();
    assert_eq!(lo[2], 0.0);
    assert!((tree.height() - 6.9).abs() < 0.3, "height {}", tree.height());
    // y-up → z-up is (x, y, z) → (x, −z, y): the file's z range [−1.498, 1.246] becomes y ∈
    // [−1.246, 1.498], its x range is kept.
    assert!((hi[1] - 1.498).abs() < 1e-3 && (lo[1] + 1.246).abs() < 1e-3);
    assert!((lo[0] + 2.131).abs() < 1e-3 && (hi[0] - 1.920).abs() < 1e-3);
    for part in &tree.parts {
        for normal in &part.mesh.normals {
            let length = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
            assert!((length - 1.0).abs() < 1e-3);
        }
    }
}

#[test]
fn untextured_pine_is_classified_by_material_name() {
    let pine = load("models/quaternius/PineTree_1.gltf");
    assert_eq!(pine.triangle_count(), 2_128);
    assert_eq!(pine.parts.len(), 2);
    for part in &pine.parts {
        let expected = match part.material.name.as_str() {
            "PineTree_Leaves" => PartKind::Foliage,
            "PineTree_Bark" => PartKind::Wood,
            other => panic!("unexpected material {other}"),
        };
        assert_eq!(part.kind, expected);
        assert!(part.material.texture.is_none());
        assert_eq!(part.material.alpha_cutoff, None);
    }
    assert!(pine.triangle_count_of(PartKind::Foliage) > 0);
    assert!(pine.triangle_count_of(PartKind::Wood) > 0);
}

#[test]
fn centred_bush_is_rebased_onto_the_ground() {
    let bush = load("models/quaternius/Bush_Small.gltf");
    assert_eq!(bush.triangle_count(), 190);
    assert_eq!(bush.bounds().0[2], 0.0);
    assert!(bush.height() > 0.5);
    assert!(bush.parts.iter().all(|part| part.kind == PartKind::Foliage));
}

#[test]
fn missing_buffer_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let source = data("test/gltf/BoxTextured-glTF");
    std::fs::copy(source.join("BoxTextured.gltf"), dir.path().join("Box.gltf")).unwrap();
    std::fs::copy(source.join("CesiumLogoFlat.png"), dir.path().join("CesiumLogoFlat.png")).unwrap();
    let error = load_gltf(&dir.path().join("Box.gltf")).unwrap_err();
    assert!(
        matches!(&error, ModelError::MissingBuffer { index: 0, uri, .. } if uri == "BoxTextured0.bin"),
        "{error:?}"
    );
    let message = error.to_string();
    assert!(message.contains("Box.gltf") && message.contains("buffer 0"));
    assert!(message.contains("BoxTextured0.bin"), "{message}");
}

#[test]
fn missing_texture_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let source = data("test/gltf/BoxTextured-glTF");
    for file in ["BoxTextured.gltf", "BoxTextured0.bin"] {
        std::fs::copy(source.join(file), dir.path().join(file)).unwrap();
    }
    let error = load_gltf(&dir.path().join("BoxTextured.gltf")).unwrap_err();
    assert!(matches!(error, ModelError::Image { index: 0, .. }), "{error:?}");
    assert!(error.to_string().contains("CesiumLogoFlat.png"), "{error}");
}

#[test]
fn non_gltf_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let text = dir.path().join("notes.gltf");
    std::fs::write(&text, "this is not a model").unwrap();
    let error = load_gltf(&text).unwrap_err();
    assert!(matches!(error, ModelError::NotGltf { .. }), "{error:?}");
    assert!(error.to_string().contains("notes.gltf: not a glTF file"));

    let png = data("models/quaternius/Textures/Bush_Leaves.png");
    assert!(matches!(load_gltf(&png), Err(ModelError::NotGltf { .. })));

    let json = dir.path().join("other.json");
    std::fs::write(&json, r#"{"type": "FeatureCollection"}"#).unwrap();
    let error = load_gltf(&json).unwrap_err();
    assert!(matches!(error, ModelError::Gltf { .. }), "{error:?}");
    assert!(error.to_string().contains("other.json: cannot read glTF"));

    let missing = dir.path().join("gone.glb");
    let error = load_gltf(&missing).unwrap_err();
    assert!(matches!(error, ModelError::Read { .. }), "{error:?}");
    assert!(error.to_string().contains("gone.glb: cannot read file"));
}

/// Writes a variant of BoxTextured.gltf (next to a copy of its .bin and .png) after `edit`.
fn edited_box(dir: &Path, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    let source = data("test/gltf/BoxTextured-glTF");
    for file in ["BoxTextured0.bin", "CesiumLogoFlat.png"] {
        std::fs::copy(source.join(file), dir.join(file)).unwrap();
    }
    let text = std::fs::read_to_string(source.join("BoxTextured.gltf")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut json);
    let path = dir.join("edited.gltf");
    std::fs::write(&path, json.to_string()).unwrap();
    path
}

#[test]
fn materials_sharing_an_image_share_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    let path = edited_box(dir.path(), |json| {
        let mut leaves = json["materials"][0].clone();
        leaves["name"] = "Leaves".into();
        json["materials"].as_array_mut().unwrap().push(leaves);
        let mut primitive = json["meshes"][0]["primitives"][0].clone();
        primitive["material"] = 1.into();
        json["meshes"][0]["primitives"].as_array_mut().unwrap().push(primitive);
    });
    let model = load_gltf(&path).unwrap();
    assert_eq!(model.parts.len(), 2);
    assert_eq!(model.triangle_count(), 24);
    assert_eq!(model.triangle_count_of(PartKind::Foliage), 12);
    let [a, b] = [0, 1].map(|i| model.parts[i].material.texture.clone().unwrap());
    assert!(Arc::ptr_eq(&a, &b));
}

#[test]
fn line_primitives_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let with_lines = edited_box(dir.path(), |json| {
        let mut lines = json["meshes"][0]["primitives"][0].clone();
        lines["mode"] = 1.into();
        json["meshes"][0]["primitives"].as_array_mut().unwrap().push(lines);
    });
    assert_eq!(load_gltf(&with_lines).unwrap().triangle_count(), 12);

    let only_lines = edited_box(dir.path(), |json| json["meshes"][0]["primitives"][0]["mode"] = 1.into());
    let error = load_gltf(&only_lines).unwrap_err();
    assert!(matches!(error, ModelError::NoGeometry { .. }), "{error:?}");
    assert!(error.to_string().ends_with("edited.gltf: no triangle geometry"));
}

#[test]
fn missing_normals_are_computed_and_missing_uvs_are_zero() {
    let dir = tempfile::tempdir().unwrap();
    let path = edited_box(dir.path(), |json| {
        let attributes = json["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap();
        attributes.remove("NORMAL");
        attributes.remove("TEXCOORD_0");
    });
    let model = load_gltf(&path).unwrap();
    let mesh = &model.parts[0].mesh;
    assert_eq!(model.triangle_count(), 12);
    assert!(mesh.uvs.iter().all(|uv| *uv == [0.0, 0.0]));
    // The box has separate vertices per face, so smooth normals are the face normals: each
    // is an axis direction pointing away from the box centre.
    let (lo, hi) = model.bounds();
    let centre: [f32; 3] = std::array::from_fn(|k| (lo[k] + hi[k]) / 2.0);
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        let length = n.iter().map(|c| c * c).sum::<f32>().sqrt();
        assert!((length - 1.0).abs() < 1e-5);
        assert!(n.iter().filter(|c| c.abs() > 0.999).count() == 1, "{n:?}");
        let outward: f32 = (0..3).map(|k| n[k] * (p[k] - centre[k])).sum();
        assert!(outward > 0.0);
    }
}

#[test]
fn procedural_plants_are_deterministic_and_plausible() {
    for (kind, heights) in [
        (ProceduralKind::Broadleaf, 8.0..12.5),
        (ProceduralKind::Conifer, 11.0..16.5),
        (ProceduralKind::Shrub, 1.1..2.0),
    ] {
        let plant = procedural_plant(kind, 7);
        let again = procedural_plant(kind, 7);
        let other = procedural_plant(kind, 8);
        assert_eq!(plant.parts.len(), again.parts.len());
        for (a, b) in plant.parts.iter().zip(&again.parts) {
            assert_eq!(a.mesh, b.mesh, "{kind:?}: same seed, same model");
        }
        assert_ne!(plant.parts[1].mesh.positions, other.parts[1].mesh.positions, "{kind:?}: different seeds differ");

        assert!(plant.triangle_count_of(PartKind::Wood) > 0, "{kind:?}");
        assert!(plant.triangle_count_of(PartKind::Foliage) > 0, "{kind:?}");
        assert!(plant.triangle_count() <= 3_000, "{kind:?}");
        assert!(heights.contains(&plant.height()), "{kind:?}: {}", plant.height());
        let (lo, hi) = plant.bounds();
        assert_eq!(lo[2], 0.0);
        // Crowns are about as wide as the plant is tall (shrubs a bit wider).
        let width = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        assert!((0.3..1.5).contains(&(width / plant.height())), "{kind:?}: {width}");

        for part in &plant.parts {
            let mesh = &part.mesh;
            assert_eq!(mesh.normals.len(), mesh.positions.len());
            assert_eq!(mesh.uvs.len(), mesh.positions.len());
            for normal in &mesh.normals {
                let length = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
                assert!((length - 1.0).abs() < 1e-4, "{kind:?}: {normal:?}");
            }
            assert!(mesh.indices.iter().all(|&i| (i as usize) < mesh.positions.len()));
        }
        let foliage = plant.parts_of(PartKind::Foliage).next().unwrap();
        assert_eq!(foliage.material.alpha_cutoff, Some(0.5));
        let texture = foliage.material.texture.as_ref().expect("leaf texture");
        assert!(texture.pixels().any(|p| p[3] == 0) && texture.pixels().any(|p| p[3] == 255));
        // Leaf cards: four vertices and two triangles each.
        assert_eq!(foliage.mesh.positions.len(), 2 * foliage.mesh.triangle_count());
        // The trunk stands at the origin.
        let wood = plant.parts_of(PartKind::Wood).next().unwrap();
        let base = wood.mesh.positions[0];
        assert!(base[0].hypot(base[1]) < 0.5, "{kind:?}: trunk base {base:?}");
    }
}
