//! Fuzz target `upload`: see [`inputs::upload`].
#![no_main]

#[path = "../inputs.rs"]
#[allow(dead_code)] // each target calls one of the shared entry points
mod inputs;

libfuzzer_sys::fuzz_target!(|data: &[u8]| inputs::upload(data));
