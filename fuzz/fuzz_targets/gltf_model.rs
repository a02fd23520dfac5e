//! Fuzz target `gltf_model`: see [`inputs::gltf_model`].
#![no_main]

#[path = "../inputs.rs"]
#[allow(dead_code)] // each target calls one of the shared entry points
mod inputs;

libfuzzer_sys::fuzz_target!(|data: &[u8]| inputs::gltf_model(data));
