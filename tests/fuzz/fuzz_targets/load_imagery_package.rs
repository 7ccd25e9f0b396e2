//! Fuzz target: the imagery package reader (`package::imagery::ImageryPackage`, header and tiles) must refuse bad bytes without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_imagery_package(data);
});
