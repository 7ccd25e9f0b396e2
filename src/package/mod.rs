//! Stage 1b, the package: a single-file, compressed, tiled terrain (GC section 7) and its fixed tile cache.
//!
//! - [`format`](mod@format): the header (magic, version, dimensions, spacing, origin, quantum, codec,
//!   each level's prediction weights and residual step, the rANS tables, the tile table with per-tile
//!   offsets and CRC-32s).
//! - [`predict`]: the prediction of a sample from the coarser level (U) and its decoded neighbours.
//! - [`codec`]: one tile's coding: near-lossless quantisation in closed loop, then [`rans`] or the
//!   byte planes of [`planes`] under zstd or lz4 (`docs/package-codec.md`).
//! - [`write`](mod@write): `clipsat bake`, source rows -> coded pyramid, out of core (the levels spilled
//!   to temporary files by `spill`, coded coarse to fine by `levels`).
//! - [`lod_tiles`]: the SAT LOD records' tiles (two bytes a cell of each data level); [`lod_bake`] the
//!   records baked into the package and read back into the LOD tables' cache file; [`lod_stream`] the
//!   same tables baked out of core from the heights; [`lod_cache`] the package's tables through the cache.
//! - [`shading_sats`]: SG's shading SATs (normals, horizons), baked from a level of the package (or a
//!   held grid) within the profile's shading share, and their cache file.
//! - [`read`]: validated reading through a memory map; damaged files are errors naming the tile.
//! - [`cache`]: the tile cache allocated once from `budget.cpu_memory_bytes`, decoding under a sample budget.
//! - [`query`]: exact queries of level 0's bilinear surface (a held grid, or the package through a query
//!   cache of its own); [`ray`]: a ray's first hit on it, walked tile by tile, then cell by cell.
//! - [`imagery`](mod@imagery): the imagery package, the colour pyramid in JPEG tiles beside a terrain
//!   package; [`imagery_bake`] its bake, out of core; [`imagery_cache`] its tile cache, allocated once,
//!   decoding under a texel budget.

pub mod cache;
pub mod codec;
pub mod color_blocks;
mod deal;
pub mod etc2;
mod etc2_planar;
mod etc2_th;
pub mod format;
pub mod imagery;
pub mod imagery_bake;
pub mod imagery_cache;
pub mod kind;
mod levels;
pub mod lod_bake;
pub mod lod_cache;
pub mod lod_stream;
pub mod lod_tiles;
pub mod planes;
pub mod predict;
pub mod query;
pub mod rans;
pub mod ray;
pub mod read;
pub mod set;
pub mod set_bake;
pub mod shading_sats;
mod spill;
pub mod write;

pub use cache::{CacheSplit, CacheStats, TileCache};
pub use format::{CodecKind, Header};
pub use read::{is_package, Package, TileDecoder};
pub use write::{
    bake, bake_source, cached, default_max_error, BakeOptions, BakeReport, LevelBytes,
};

/// Threads a bake codes and decodes tiles on, the process's cores (its CPU affinity) up to 8: every tile
/// is coded or decoded from the same inputs whichever thread does it, so nothing baked depends on it.
pub(crate) fn threads() -> usize {
    if ONE_THREAD.with(std::cell::Cell::get) {
        return 1;
    }
    std::thread::available_parallelism()
        .map_or(1, usize::from)
        .min(8)
}

/// A file's size and modification time into a cache key `h`: what keys a package, an imagery package or
/// a package set's part to the files it was baked from (editing one bakes again).
pub(crate) fn stamp(h: &mut crate::hash::Hash64, meta: &std::fs::Metadata) {
    h.write_u64(meta.len());
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
    h.write_u64(mtime.map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)));
}

thread_local! {
    /// Set while this thread bakes one of several packages that run side by side ([`one_thread`]).
    static ONE_THREAD: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` with [`threads`] at 1 on this thread: a package set's cells baked a cell a core.
pub(crate) fn one_thread<R>(f: impl FnOnce() -> R) -> R {
    ONE_THREAD.with(|c| c.set(true));
    let r = f();
    ONE_THREAD.with(|c| c.set(false));
    r
}
