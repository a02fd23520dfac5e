//! Replays the fuzz targets' inputs in every `cargo test`: the inputs the fuzzer found and kept
//! (`fuzz/regressions/<target>/`) and the seed corpora (the real files in `data/`), through the
//! same entry points the fuzz targets call (`fuzz/inputs.rs`). A parser that panics on one of
//! them fails here without nightly or cargo-fuzz.

#[path = "../fuzz/inputs.rs"]
mod inputs;

use std::path::{Path, PathBuf};

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else { return found };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(files(&path));
        } else {
            found.push(path);
        }
    }
    found.sort();
    found
}

/// The seed corpus of a target: the files in `data/` it reads in real use, and the hand-written
/// ones in `fuzz/seeds/<target>/`.
fn seeds(target: &str) -> Vec<PathBuf> {
    let with_ext = |dir: &str, exts: &[&str]| -> Vec<PathBuf> {
        files(Path::new(dir))
            .into_iter()
            .filter(|p| p.extension().and_then(|e| e.to_str()).is_some_and(|e| exts.contains(&e)))
            .collect()
    };
    let mut seeds = match target {
        "upload" => with_ext("data/test", &["tif", "asc", "nc", "geojson"]),
        "art_map" => with_ext("data/artmaps", &["png"]),
        "scene_file" => with_ext("data", &["toml"]),
        "gltf_model" => with_ext("data", &["glb", "gltf"]),
        _ => Vec::new(),
    };
    seeds.extend(files(&Path::new("fuzz/seeds").join(target)));
    seeds
}

#[test]
fn every_fuzz_target_survives_its_seeds_and_found_inputs() {
    for (target, run) in inputs::TARGETS {
        let seeds = seeds(target);
        assert!(!seeds.is_empty(), "the target {target} has seeds");
        for path in seeds.iter().chain(&files(&Path::new("fuzz/regressions").join(target))) {
            let input = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            run(&input);
        }
    }
}
