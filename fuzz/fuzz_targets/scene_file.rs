//! Fuzz target `scene_file`: see [`inputs::scene_file`].
#![no_main]

#[path = "../inputs.rs"]
#[allow(dead_code)] // each target calls one of the shared entry points
mod inputs;

libfuzzer_sys::fuzz_target!(|data: &[u8]| inputs::scene_file(data));
