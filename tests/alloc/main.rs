//! The allocation test binary: installs a counting `#[global_allocator]` (`counting_alloc`), so it stays
//! apart from the other test binaries. Counting is per thread, so its tests may run in parallel.

#[path = "../counting_alloc/mod.rs"]
mod counting_alloc;

mod color;
mod plan;
mod query;
mod stream;
mod update;
