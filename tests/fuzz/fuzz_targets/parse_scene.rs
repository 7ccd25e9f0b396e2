//! Fuzz target: `Scene::parse` must refuse any text with an error, never panic; an accepted scene must
//! answer `needs()` and `features()`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(s) = clipsat::shading::scene::Scene::parse("fuzz", text) {
        let _ = s.needs();
        let _ = s.features();
    }
});
