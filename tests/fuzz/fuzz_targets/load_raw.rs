//! Fuzz target: the raw loader; the first 5 bytes pick the layout, the rest is the file.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_raw(data);
});
