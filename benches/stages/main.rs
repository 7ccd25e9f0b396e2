//! Criterion benchmarks of the CPU stages in one binary (one link and one criterion instantiation instead
//! of three in CI's build): the per-frame plan (`update`), SAT LOD selection and table building (`lod`),
//! and package decoding (`package`). Every stage, or one by its groups' names (a regex):
//!
//! ```text
//! cargo bench --bench stages
//! cargo bench --bench stages -- lod_
//! cargo bench --bench stages -- "decode_|cache_|stream_fill"
//! cargo bench --bench stages -- "refill|fly_puget"
//! cargo bench --bench stages -- codec_
//! ```

mod codec;
mod lod;
mod package;
mod update;

criterion::criterion_main!(
    update::benches,
    lod::benches,
    package::benches,
    codec::benches
);
