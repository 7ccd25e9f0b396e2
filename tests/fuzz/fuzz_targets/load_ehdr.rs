//! Fuzz target: the ESRI binary grid loader (`source::load` on a `.bil`/`.flt` with its `.hdr`) must refuse bad headers and grids without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_ehdr(data);
});
