//! Fuzz target: the gridded XYZ loader (`source::load` on a `.xyz` file) must refuse bad text without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_xyz(data);
});
