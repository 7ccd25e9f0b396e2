//! Fuzz target: the imagery reader (`source::imagery::Imagery::load` on a PNG or JPEG) must refuse bad bytes without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_imagery(data);
});
