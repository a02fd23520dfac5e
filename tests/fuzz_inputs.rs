//! Replays the fuzz targets' inputs in every `cargo test`: the inputs the fuzzer found and kept
//! (`fuzz/regressions/<target>/`) and the seed corpora (the real files in `data/`), through the
//! same entry points the fuzz targets call (`fuzz/inputs.rs`), then a few seconds of mutations
//! of the seeds per target. A parser that panics on one of them fails here without nightly or
//! cargo-fuzz.

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
            assert!(std::panic::catch_unwind(|| run(&input)).is_ok(), "{target} panicked on {}", path.display());
        }
    }
}

/// Bytes a mutation writes: zero, the ends and middle of a byte, and length-field-like u32s.
const INTERESTING: [u32; 9] = [0, 0xff, 0x7f, 0x80, 0xffff, 0x8000, 0x7fff_ffff, 0xffff_ffff, 0x0100_0000];

/// A mutation smoke run of every target without nightly, on top of its seed corpus: up to
/// 20,000 inputs or 2 s per target (fewer on a slow or busy machine), each a seed with one to
/// four mutations (a bit flipped; a byte inserted, deleted or overwritten with an interesting
/// value; a u32 written in either byte order; truncation; a splice of two seeds; a duplicated
/// chunk), half of them within the first 256 bytes, where the headers are. The PRNG
/// (xorshift64) has a fixed seed per target, so the n-th input of a target is always the same.
/// A panicking input is written to `$CARGO_TARGET_TMPDIR/fuzz-smoke/` and named in the failure,
/// to be moved to `fuzz/regressions/<target>/`.
#[test]
fn every_fuzz_target_survives_a_mutation_smoke() {
    for (index, (target, run)) in inputs::TARGETS.into_iter().enumerate() {
        let seeds: Vec<Vec<u8>> = seeds(target).iter().map(|p| std::fs::read(p).expect("a seed")).collect();
        let mut state = 0x9e37_79b9_7f4a_7c15_u64 ^ index as u64;
        let mut below = |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n.max(1) as u64) as usize
        };
        let start = std::time::Instant::now();
        for count in 0..20_000 {
            if start.elapsed().as_secs_f32() > 2.0 {
                break;
            }
            let mut input = seeds[below(seeds.len())].clone();
            for _ in 0..=below(4) {
                let len = input.len();
                let at = if below(2) == 0 { below(len.min(256) + 1) } else { below(len + 1) };
                let value = INTERESTING[below(INTERESTING.len())];
                match below(8) {
                    0 if at < len => input[at] ^= 1 << below(8),
                    1 => input.insert(at, value as u8),
                    2 if at < len => _ = input.remove(at),
                    3 if at < len => input[at] = value as u8,
                    4 => {
                        let bytes = if below(2) == 0 { value.to_le_bytes() } else { value.to_be_bytes() };
                        input.splice(at..(at + 4).min(len), bytes);
                    }
                    5 => input.truncate(at),
                    6 => {
                        let other = &seeds[below(seeds.len())];
                        input.truncate(at);
                        input.extend_from_slice(&other[below(other.len() + 1)..]);
                    }
                    7 => {
                        let chunk = input[at..at + below(len - at + 1).min(4096)].to_vec();
                        input.splice(at..at, chunk);
                    }
                    _ => {}
                }
            }
            if std::panic::catch_unwind(|| run(&input)).is_err() {
                let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-smoke");
                let path = dir.join(format!("{target}-{count}"));
                std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, &input)).expect("the input kept");
                panic!("{target} panicked on mutated input {count}, kept in {}", path.display());
            }
        }
    }
}
