//! Fuzz target: the DTED loader (`source::load` on a `.dt1` cell) must refuse bad headers and records without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_dted(data);
});
