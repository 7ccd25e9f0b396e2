//! Fuzz target: the png loader (`source::load` on a `x.png` file) must refuse bad bytes without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_png(data);
});
