//! Fuzz target `art_map`: see [`inputs::art_map`].
#![no_main]

#[path = "../inputs.rs"]
#[allow(dead_code)] // each target calls one of the shared entry points
mod inputs;

libfuzzer_sys::fuzz_target!(|data: &[u8]| inputs::art_map(data));
