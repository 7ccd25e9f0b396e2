//! Fuzz target: the ESRI ASCII grid loader (`source::load` on a `.asc` file) must refuse bad text without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_asc(data);
});
