//! Fuzz target: the png loader (`source::load` on a `x.png` file) must refuse bad bytes without panicking.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load_as("x.png", data, &common::small());
});
