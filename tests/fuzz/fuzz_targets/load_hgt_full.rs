//! Fuzz target: the HGT loader past its size check. The input is repeated to a whole 3 arc-second tile
//! (1201 x 1201 big-endian i16), so the decoder and the void filling see fuzzed samples.
#![no_main]

#[path = "common.rs"]
mod common;

/// Bytes of a 1201 x 1201 HGT tile.
const TILE: usize = 1201 * 1201 * 2;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if data.is_empty() {
        return;
    }
    let tile: Vec<u8> = data.iter().copied().cycle().take(TILE).collect();
    common::load_as("N45E006.hgt", &tile, &common::small());
});
