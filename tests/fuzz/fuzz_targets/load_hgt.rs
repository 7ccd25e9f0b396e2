//! Fuzz target: the hgt loader (`source::load` on a `N45E006.hgt` file) must refuse bad bytes without panicking.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load_as("N45E006.hgt", data, &common::small());
});
