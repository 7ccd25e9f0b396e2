//! Fuzz target: the raw loader. The first 5 bytes pick the layout (width, height, u16 or f32), the rest is
//! the file.
#![no_main]

#[path = "common.rs"]
mod common;

use clipsat::source::{LoadOptions, RawFormat, RawLayout};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((head, body)) = data.split_first_chunk::<5>() else {
        return;
    };
    let opts = LoadOptions {
        raw: Some(RawLayout {
            width: u32::from(u16::from_le_bytes([head[0], head[1]])),
            height: u32::from(u16::from_le_bytes([head[2], head[3]])),
            format: if head[4] & 1 == 0 {
                RawFormat::U16
            } else {
                RawFormat::F32
            },
        }),
        ..common::small()
    };
    common::load_as("x.raw", body, &opts);
});
