//! Fuzz target: the tiff loader (`source::load` on a `x.tif` file) must refuse bad bytes without panicking.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load_as("x.tif", data, &common::small());
});
