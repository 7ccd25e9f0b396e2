//! Fuzz target: a terrain package (`Package::open` and decoding) refuses damaged bytes without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_package(data);
});
