//! Stage 1b, the package: a single-file, compressed, tiled terrain (GC section 7) and its fixed tile cache.
//!
//! - [`format`](mod@format): the header (magic, version, dimensions, spacing, origin, quantum, codec,
//!   tile table with per-tile offsets and CRC-32s).
//! - [`codec`]: the integer 4-point prediction U and the tile codec (zigzag byte planes under zstd or lz4).
//! - [`write`](mod@write): `clipsat bake`, source rows -> residual pyramid quantised with one absolute step,
//!   out of core (the levels spilled to temporary files by `spill`).
//! - [`lod_tiles`]: the SAT LOD records' tiles (two bytes a cell of each data level, issue 13).
//! - [`read`]: validated reading through a memory map; damaged files are errors naming the tile.
//! - [`cache`]: the tile cache allocated once from `budget.cpu_memory_bytes`, decoding under a sample budget.

pub mod cache;
pub mod codec;
pub mod format;
pub mod lod_tiles;
pub mod read;
mod spill;
pub mod write;

pub use cache::{CacheSplit, CacheStats, TileCache};
pub use format::{CodecKind, Header};
pub use read::{is_package, Package, TileDecoder};
pub use write::{bake, bake_source, cached, default_max_error, BakeOptions, BakeReport};
