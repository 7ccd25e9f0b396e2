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
//!
//! A residual tile (`imagery.rs`: even levels but the coarsest) is its parent's upsample plus the
//! decoded residual, so it needs its parent tile's RGB8: a small fixed LRU of [`PARENT_SLOTS`] parent
//! tiles, allocated with the slots and counted in [`ImageryCache::bytes`] and
//! [`ImageryCache::min_bytes`], keeps them (a parent already held in an RGB8 slot is copied, not decoded
//! again). A parent's decode is charged like any tile's and counted in the stats; when the budget pays for
//! the parent but not the child, the parent stays and the fetch answers `None`: the next frame's fetch
//! finds it and decodes the child, so a budget of one tile a frame still makes progress.

use super::color_blocks::{tile_bytes, BlockEncoder, ColorFormat};
use super::imagery::ImageryPackage;
use crate::{Error, Result};

/// Marks an empty slot or a tile with no slot.
const NONE: u32 = u32::MAX;

/// Parent tiles kept for residual tiles. A ring's leading edge (`ring` texels long) crosses at most
/// `ring / tile + 1` tiles of its level, which lie under at most `ceil(ring / (2 tile)) + 1` parent
/// tiles: 2 for `gles3-low`'s and `gles3-mid`'s rings (256, 512), 3 for `desktop`'s (1024); 4 hold an
/// edge's parents and the next one a diagonal move brings. The rings fill coarse to fine, so a parent is
/// usually in an RGB8 slot already and is copied, not decoded.
pub const PARENT_SLOTS: usize = 4;

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
    /// Parent tiles decoded for residual tiles (counted in `decoded` too).
    pub parents: u64,
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
    /// Parent tiles (RGB8) of residual tiles, least recently used first out; empty for a package without
    /// residual levels.
    parents: Vec<Slot>,
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
    /// tile and encoder, the parent tiles of a package with residual levels, and one slot.
    pub fn min_bytes(package: &ImageryPackage, format: ColorFormat) -> u64 {
        let t = package.header().tile;
        let scratch = if format.is_block() {
            3 * u64::from(t) * u64::from(t) + BlockEncoder::new(format, t).bytes()
        } else {
            0
        };
        4 * package.header().tiles.len() as u64
            + scratch
            + Self::parent_bytes(package)
            + Self::format_slot_bytes(package, format)
    }

    /// Bytes of the parent tiles a cache for `package` keeps: [`PARENT_SLOTS`] RGB8 tiles where it has
    /// residual levels, else none.
    pub fn parent_bytes(package: &ImageryPackage) -> u64 {
        if package.header().has_residuals() {
            PARENT_SLOTS as u64 * Self::slot_bytes(package)
        } else {
            0
        }
    }

    /// A cache of as many slots as `budget` bytes pay for after the tile map and the parent tiles (at
    /// least 1, at most one a tile of the package), all allocated now, holding RGB8 tiles (for RGBA8
    /// rings).
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
        let map_bytes =
            4 * tiles as u64 + scratch.len() as u64 + encoder.bytes() + Self::parent_bytes(&package);
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
        let parent_count = if package.header().has_residuals() { PARENT_SLOTS } else { 0 };
        let parents = (0..parent_count)
            .map(|_| Slot {
                tile: NONE,
                used: 0,
                texels: vec![0; 3 * t as usize * t as usize],
            })
            .collect();
        Ok(Self {
            package,
            format,
            scratch,
            encoder,
            slots,
            parents,
            map: vec![NONE; tiles],
            frame: 0,
            stats: ImageryCacheStats::default(),
        })
    }

    /// The package it decodes from.
    pub fn package(&self) -> &ImageryPackage {
        &self.package
    }

    /// Bytes it holds: the slots, the parent tiles, the tile map, and for a block format the scratch
    /// tile and the encoder's.
    pub fn bytes(&self) -> u64 {
        self.slots.len() as u64 * Self::format_slot_bytes(&self.package, self.format)
            + self.parents.len() as u64 * Self::slot_bytes(&self.package)
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

    /// Tile (tx, ty) of `level` as (width, height, RGB8 texels or, for a block format, its blocks),
    /// decoded now when not resident and `budget` (texels left this frame) pays for it (then reduced by
    /// its texels, and by its parent's where a residual tile's parent is decoded too); `None` when the
    /// budget or the slots cannot take it. Damage in the package is an error.
    pub fn fetch(
        &mut self,
        level: usize,
        tx: u32,
        ty: u32,
        budget: &mut u64,
    ) -> Result<Option<(u32, u32, &[u8])>> {
        let mut decodes = u32::MAX;
        self.fetch_counted(level, tx, ty, budget, &mut decodes)
    }

    /// [`ImageryCache::fetch`] under a budget of `decodes` JPEG decodes as well (reduced by each, a
    /// residual tile's parent's included): the colour rings' tiles a frame.
    pub fn fetch_counted(
        &mut self,
        level: usize,
        tx: u32,
        ty: u32,
        budget: &mut u64,
        decodes: &mut u32,
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
        let Some(victim) = victim else {
            self.stats.refused += 1;
            return Ok(None);
        };
        let parent = match self.package.parent_of(level, tx, ty) {
            Some((pl, ptx, pty)) => match self.parent(pl, ptx, pty, budget, decodes)? {
                Some(p) => Some(p),
                None => {
                    self.stats.refused += 1;
                    return Ok(None);
                }
            },
            None => None,
        };
        if texels > *budget || *decodes == 0 {
            // A parent decoded now stays for the next frame's fetch.
            self.stats.refused += 1;
            return Ok(None);
        }
        let s = &mut self.slots[victim];
        if s.tile != NONE {
            self.map[s.tile as usize] = NONE;
            self.stats.evictions += 1;
        }
        s.tile = NONE;
        let rgb = if self.format.is_block() { &mut self.scratch } else { &mut s.texels };
        self.package.decode_tile(level, tx, ty, rgb)?;
        if let Some(p) = parent {
            self.package.add_prediction(level, tx, ty, &self.parents[p].texels, rgb)?;
        }
        if self.format.is_block() {
            self.encoder.encode(&self.scratch, w, h, &mut s.texels[..n])?;
        }
        s.tile = u32::try_from(tile).unwrap_or(NONE);
        s.used = self.frame;
        self.map[tile] = u32::try_from(victim).unwrap_or(NONE);
        *budget -= texels;
        *decodes -= 1;
        self.stats.decoded += 1;
        self.stats.decoded_texels += texels;
        Ok(Some((w, h, &s.texels[..n])))
    }

    /// The parent slot holding tile (ptx, pty) of level `pl` (RGB8), made resident when `budget` and
    /// `decodes` pay for its decode (an RGB8 slot holding it is copied, free); `None` when they cannot.
    fn parent(
        &mut self,
        pl: usize,
        ptx: u32,
        pty: u32,
        budget: &mut u64,
        decodes: &mut u32,
    ) -> Result<Option<usize>> {
        let l = &self.package.header().levels[pl];
        let tile = u32::try_from(l.first_tile + (pty * l.tiles_x + ptx) as usize).unwrap_or(NONE);
        if let Some(i) = self.parents.iter().position(|p| p.tile == tile) {
            self.parents[i].used = self.frame;
            return Ok(Some(i));
        }
        let Some((w, h)) = self.package.tile_size(pl, ptx, pty) else {
            return Ok(None);
        };
        // Least recently used (by frame, then slot): the same parents stay run to run.
        let Some(i) = (0..self.parents.len()).min_by_key(|&i| {
            let p = &self.parents[i];
            (p.tile != NONE, p.used, i)
        }) else {
            return Ok(None);
        };
        let n = 3 * w as usize * h as usize;
        let held = self.map[tile as usize];
        let p = &mut self.parents[i];
        if held != NONE && !self.format.is_block() {
            p.texels[..n].copy_from_slice(&self.slots[held as usize].texels[..n]);
        } else {
            let texels = u64::from(w) * u64::from(h);
            if texels > *budget || *decodes == 0 {
                return Ok(None);
            }
            p.tile = NONE;
            self.package.decode_tile(pl, ptx, pty, &mut p.texels)?;
            *budget -= texels;
            *decodes -= 1;
            self.stats.decoded += 1;
            self.stats.decoded_texels += texels;
            self.stats.parents += 1;
        }
        p.tile = tile;
        p.used = self.frame;
        Ok(Some(i))
    }
}
