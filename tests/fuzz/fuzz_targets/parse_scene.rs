//! Fuzz target: `Scene::parse` refuses any text with an error, never panics.
#![no_main]

#[path = "targets.rs"]
#[expect(dead_code, reason = "each binary runs one target of the shared set")]
mod targets;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = targets::parse_scene(data);
});
