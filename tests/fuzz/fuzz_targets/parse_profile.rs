//! Fuzz target: `Profile::parse` must refuse any text with an error, never panic; what it accepts must be
//! usable (footprint and sizes computed without overflow).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(p) = clipsat::Profile::parse("fuzz", text) {
        let _ = p.footprint().total();
        let _ = p.clip_size();
        let _ = p.block_m();
        let _ = p.height_layers();
    }
});
