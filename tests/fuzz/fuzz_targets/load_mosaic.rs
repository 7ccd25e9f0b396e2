//! Fuzz target: a tile mosaic's list or GDAL VRT (`source::load` on `x.txt` or `x.vrt` beside two small
//! tiles) must refuse bad bytes without panicking.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::load_mosaic(data);
});
