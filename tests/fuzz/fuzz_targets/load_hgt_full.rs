//! Fuzz target: the HGT loader past its size check (the input repeated to a whole 1201 x 1201 tile).
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_hgt_full(data);
});
