//! Stage 1b, the package: the imagery tile cache, allocated once from a share of
//! `budget.cpu_memory_bytes`, decoding colour tiles under a per-frame texel budget.
//!
//! As the height tile cache (`cache.rs`): a fetch decodes a tile into a fixed slot and is charged in
//! texels against the caller's budget; one the budget cannot pay for, or with no free slot (every slot
//! used this frame), answers `None` and the caller falls back to a coarser level. Eviction is
//! least-recently-used by frame stamp, so the resident set is the same run to run. The slots' bytes
//! depend on the budget and the tile side alone, never on the image's size.
//!
//! For rings in a block format ([`ColorFormat`]: BC1, ETC2 RGB8) a slot holds the tile's blocks, encoded
//! right after the JPEG decode into one scratch tile (the decode and the encode are the fetch's cost,
//! charged in texels as before); the scratch and the encoder's are allocated with the slots and counted
//! in [`ImageryCache::bytes`].

use super::color_blocks::{tile_bytes, BlockEncoder, ColorFormat};
use super::imagery::ImageryPackage;
use crate::{Error, Result};

/// Marks an empty slot or a tile with no slot.
const NONE: u32 = u32::MAX;

/// One slot: a decoded tile (RGB8, or its blocks) and what it holds.
#[derive(Debug)]
struct Slot {
    tile: u32,
    used: u64,
    texels: Vec<u8>,
}

/// Counters since the cache was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ImageryCacheStats {
    /// Fetches answered from the cache.
    pub hits: u64,
    /// Tiles decoded.
    pub decoded: u64,
    /// Texels decoded.
    pub decoded_texels: u64,
    /// Tiles evicted to make room.
    pub evictions: u64,
    /// Fetches refused: over the budget or no free slot.
    pub refused: u64,
}

/// The decoded colour tiles of one imagery package, in a fixed number of slots.
#[derive(Debug)]
pub struct ImageryCache {
    package: ImageryPackage,
    format: ColorFormat,
    /// A tile decoded before it is encoded into a slot's blocks (empty for RGBA8).
    scratch: Vec<u8>,
    encoder: BlockEncoder,
    slots: Vec<Slot>,
    /// Tile index -> slot, [`NONE`] where not resident.
    map: Vec<u32>,
    frame: u64,
    stats: ImageryCacheStats,
}

impl ImageryCache {
    /// Bytes of one slot for `package`: a tile's RGB8 texels and the slot's record.
    pub fn slot_bytes(package: &ImageryPackage) -> u64 {
        Self::format_slot_bytes(package, ColorFormat::Rgba8)
    }

    /// Bytes of one slot for `package` in `format`: a tile (RGB8 texels, or its blocks) and the slot's
    /// record.
    pub fn format_slot_bytes(package: &ImageryPackage, format: ColorFormat) -> u64 {
        let t = package.header().tile;
        tile_bytes(format, t, t) + std::mem::size_of::<Slot>() as u64
    }

    /// The least budget a cache for `package` in `format` takes: the tile map, a block format's scratch
    /// tile and encoder, and one slot.
    pub fn min_bytes(package: &ImageryPackage, format: ColorFormat) -> u64 {
        let t = package.header().tile;
        let scratch = if format.is_block() {
            3 * u64::from(t) * u64::from(t) + BlockEncoder::new(format, t).bytes()
        } else {
            0
        };
        4 * package.header().tiles.len() as u64 + scratch + Self::format_slot_bytes(package, format)
    }

    /// A cache of as many slots as `budget` bytes pay for after the tile map (at least 1, at most one a
    /// tile of the package), all allocated now, holding RGB8 tiles (for RGBA8 rings).
    pub fn new(package: ImageryPackage, budget: u64) -> Result<Self> {
        Self::with_format(package, budget, ColorFormat::Rgba8)
    }

    /// [`ImageryCache::new`] for rings in `format`: a block format's slots hold blocks, and the scratch
    /// tile and the encoder's come out of `budget` first.
    pub fn with_format(package: ImageryPackage, budget: u64, format: ColorFormat) -> Result<Self> {
        let tiles = package.header().tiles.len();
        let t = package.header().tile;
        let encoder = BlockEncoder::new(format, t);
        let scratch = if format.is_block() {
            vec![0; 3 * t as usize * t as usize]
        } else {
            Vec::new()
        };
        let map_bytes = 4 * tiles as u64 + scratch.len() as u64 + encoder.bytes();
        let slot = Self::format_slot_bytes(&package, format);
        let count = budget.saturating_sub(map_bytes) / slot;
        if count == 0 {
            return Err(Error::Capacity {
                what: "imagery tile cache (slots in the profile's imagery share)",
                capacity: 0,
            });
        }
        let count = usize::try_from(count).unwrap_or(usize::MAX).min(tiles);
        let per_slot = usize::try_from(tile_bytes(format, t, t)).unwrap_or(usize::MAX);
        let slots = (0..count)
            .map(|_| Slot {
                tile: NONE,
                used: 0,
                texels: vec![0; per_slot],
            })
            .collect();
        Ok(Self {
            package,
            format,
            scratch,
            encoder,
            slots,
            map: vec![NONE; tiles],
            frame: 0,
            stats: ImageryCacheStats::default(),
        })
    }

    /// The package it decodes from.
    pub fn package(&self) -> &ImageryPackage {
        &self.package
    }

    /// Bytes it holds: the slots, the tile map, and for a block format the scratch tile and the
    /// encoder's.
    pub fn bytes(&self) -> u64 {
        self.slots.len() as u64 * Self::format_slot_bytes(&self.package, self.format)
            + 4 * self.map.len() as u64
            + self.scratch.len() as u64
            + self.encoder.bytes()
    }

    /// The format its tiles are held in.
    pub fn format(&self) -> ColorFormat {
        self.format
    }

    /// Number of slots.
    pub fn slot_count(&self) -> usize {
        self.slots.len()
    }

    /// Counters since it was made.
    pub fn stats(&self) -> ImageryCacheStats {
        self.stats
    }

    /// Starts a frame: slots used from now on are kept until the next frame.
    pub fn begin_frame(&mut self) {
        self.frame += 1;
    }

    /// Tile (tx, ty) of `level` as (width, height, RGB8 texels or, for a block format, its blocks), decoded now when not resident and
    /// `budget` (texels left this frame) pays for it (then reduced by its texels); `None` when the budget
    /// or the slots cannot take it. Damage in the package is an error.
    pub fn fetch(
        &mut self,
        level: usize,
        tx: u32,
        ty: u32,
        budget: &mut u64,
    ) -> Result<Option<(u32, u32, &[u8])>> {
        let Some((w, h)) = self.package.tile_size(level, tx, ty) else {
            return Ok(None);
        };
        let l = &self.package.header().levels[level];
        let tile = l.first_tile + (ty * l.tiles_x + tx) as usize;
        let n = usize::try_from(tile_bytes(self.format, w, h)).unwrap_or(usize::MAX);
        let slot = self.map[tile];
        if slot != NONE {
            self.stats.hits += 1;
            let s = &mut self.slots[slot as usize];
            s.used = self.frame;
            return Ok(Some((w, h, &s.texels[..n])));
        }
        let texels = u64::from(w) * u64::from(h);
        // Least recently used, never one used this frame.
        let victim = self
            .slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.tile == NONE || s.used < self.frame)
            .min_by_key(|(i, s)| (s.tile != NONE, s.used, *i))
            .map(|(i, _)| i);
        let (Some(victim), true) = (victim, texels <= *budget) else {
            self.stats.refused += 1;
            return Ok(None);
        };
        let s = &mut self.slots[victim];
        if s.tile != NONE {
            self.map[s.tile as usize] = NONE;
            self.stats.evictions += 1;
        }
        s.tile = NONE;
        if self.format.is_block() {
            self.package.decode_tile(level, tx, ty, &mut self.scratch)?;
            self.encoder.encode(&self.scratch, w, h, &mut s.texels[..n])?;
        } else {
            self.package.decode_tile(level, tx, ty, &mut s.texels)?;
        }
        s.tile = u32::try_from(tile).unwrap_or(NONE);
        s.used = self.frame;
        self.map[tile] = u32::try_from(victim).unwrap_or(NONE);
        *budget -= texels;
        self.stats.decoded += 1;
        self.stats.decoded_texels += texels;
        Ok(Some((w, h, &s.texels[..n])))
    }
}
