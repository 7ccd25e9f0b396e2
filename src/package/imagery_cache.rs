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
//! decoded residual, so it needs its parent tile's RGB8. Where the slots hold RGB8 (RGBA8 rings) the
//! parent is a tile of the cache like any other, decoded into a slot of the same LRU (it is a tile of
//! the next coarser ring too) and kept from eviction for the frame. Where they hold blocks, a small fixed
//! LRU of [`PARENT_SLOTS`] RGB8 parent tiles keeps them, allocated with the slots and counted in
//! [`ImageryCache::bytes`] and [`ImageryCache::min_bytes`]. A parent's decode is charged like any
//! tile's and counted in the stats; when the budget pays for the parent but not the child, the parent
//! stays and the fetch answers `None`: the next frame's fetch finds it and decodes the child, so a
//! budget of one tile a frame still makes progress.

use super::color_blocks::{tile_bytes, BlockEncoder, ColorFormat};
use super::imagery::ImageryPackage;
use crate::{Error, Result};

/// Marks an empty slot or a tile with no slot.
const NONE: u32 = u32::MAX;

/// Parent tiles kept for residual tiles where the slots hold blocks. A ring's leading edge (`ring`
/// texels long) crosses at most `ring / tile + 1` tiles of its level, which lie under at most
/// `ceil(ring / (2 tile)) + 1` parent tiles: 2 for `gles3-low`'s and `gles3-mid`'s rings (256, 512), 3
/// for `desktop`'s (1024); 4 hold an edge's parents and the next one a diagonal move brings. Where the
/// slots hold RGB8 the parents share them instead: on `gles3-low` (10 slots) four more RGB8 tiles would
/// take four slots, and a flight over a 16384^2 image found its rings stale in 1979 frames of 2000
/// instead of 1218 (docs/guide.md "The colour rings").
pub const PARENT_SLOTS: usize = 4;

/// Where a residual tile's parent is held: a slot of the cache (RGB8 slots) or the parent LRU.
#[derive(Clone, Copy)]
enum ParentAt {
    Slot(usize),
    Kept(usize),
}

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
    /// residual levels and where the slots hold RGB8 (the parents are tiles of the slots).
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
    /// tile and encoder, the parent tiles of a package with residual levels in blocks, and the fewest
    /// slots ([`ImageryCache::min_slots`]).
    pub fn min_bytes(package: &ImageryPackage, format: ColorFormat) -> u64 {
        let t = package.header().tile;
        let scratch = if format.is_block() {
            3 * u64::from(t) * u64::from(t) + BlockEncoder::new(format, t).bytes()
        } else {
            0
        };
        4 * package.header().tiles.len() as u64
            + scratch
            + Self::parent_bytes(package, format)
            + Self::min_slots(package, format) * Self::format_slot_bytes(package, format)
    }

    /// The fewest slots a cache takes: one, or two where a residual tile's parent shares the slots
    /// (RGB8 slots), so that a parent and its child fit in one frame.
    pub fn min_slots(package: &ImageryPackage, format: ColorFormat) -> u64 {
        if package.header().has_residuals() && !format.is_block() {
            2
        } else {
            1
        }
    }

    /// Bytes of the parent LRU a cache for `package` in `format` keeps: [`PARENT_SLOTS`] RGB8 tiles
    /// where it has residual levels and its slots hold blocks, else none.
    pub fn parent_bytes(package: &ImageryPackage, format: ColorFormat) -> u64 {
        if package.header().has_residuals() && format.is_block() {
            PARENT_SLOTS as u64 * Self::slot_bytes(package)
        } else {
            0
        }
    }

    /// A cache of as many slots as `budget` bytes pay for after the tile map (at least
    /// [`ImageryCache::min_slots`], at most one a tile of the package), all allocated now, holding RGB8
    /// tiles (for RGBA8 rings).
    pub fn new(package: ImageryPackage, budget: u64) -> Result<Self> {
        Self::with_format(package, budget, ColorFormat::Rgba8)
    }

    /// [`ImageryCache::new`] for rings in `format`: a block format's slots hold blocks, and the scratch
    /// tile, the encoder's and the parent LRU come out of `budget` first.
    pub fn with_format(package: ImageryPackage, budget: u64, format: ColorFormat) -> Result<Self> {
        let tiles = package.header().tiles.len();
        let t = package.header().tile;
        let encoder = BlockEncoder::new(format, t);
        let scratch = if format.is_block() {
            vec![0; 3 * t as usize * t as usize]
        } else {
            Vec::new()
        };
        let map_bytes = 4 * tiles as u64
            + scratch.len() as u64
            + encoder.bytes()
            + Self::parent_bytes(&package, format);
        let slot = Self::format_slot_bytes(&package, format);
        let count = budget.saturating_sub(map_bytes) / slot;
        if count < Self::min_slots(&package, format) {
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
        let parent_count = if Self::parent_bytes(&package, format) > 0 {
            PARENT_SLOTS
        } else {
            0
        };
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
        // The parent first: where it shares the slots it is kept from this fetch's eviction.
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
        let Some(victim) = self.victim() else {
            self.stats.refused += 1;
            return Ok(None);
        };
        if texels > *budget || *decodes == 0 {
            // A parent decoded now stays for the next frame's fetch.
            self.stats.refused += 1;
            return Ok(None);
        }
        self.unmap(victim);
        let s = &mut self.slots[victim];
        // The slot's texels are taken out while the parent (perhaps another slot) is read, and put back
        // before any error returns; taking a Vec allocates nothing.
        let mut out = std::mem::take(&mut s.texels);
        let parent_rgb = parent.map(|p| match p {
            ParentAt::Slot(i) => &self.slots[i].texels[..],
            ParentAt::Kept(i) => &self.parents[i].texels[..],
        });
        let decoded = if self.format.is_block() {
            decode_child(&self.package, (level, tx, ty), parent_rgb, &mut self.scratch)
                .and_then(|()| self.encoder.encode(&self.scratch, w, h, &mut out[..n]))
        } else {
            decode_child(&self.package, (level, tx, ty), parent_rgb, &mut out)
        };
        let s = &mut self.slots[victim];
        s.texels = out;
        decoded?;
        s.tile = u32::try_from(tile).unwrap_or(NONE);
        s.used = self.frame;
        self.map[tile] = u32::try_from(victim).unwrap_or(NONE);
        *budget -= texels;
        *decodes -= 1;
        self.stats.decoded += 1;
        self.stats.decoded_texels += texels;
        Ok(Some((w, h, &s.texels[..n])))
    }

    /// Empties slot `i`: the tile it held, if any, is evicted.
    fn unmap(&mut self, i: usize) {
        let s = &mut self.slots[i];
        if s.tile != NONE {
            self.map[s.tile as usize] = NONE;
            self.stats.evictions += 1;
        }
        s.tile = NONE;
    }

    /// The slot to decode into: least recently used, never one used this frame.
    fn victim(&self) -> Option<usize> {
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.tile == NONE || s.used < self.frame)
            .min_by_key(|(i, s)| (s.tile != NONE, s.used, *i))
            .map(|(i, _)| i)
    }

    /// Where tile (ptx, pty) of level `pl`, a residual tile's parent, is held as RGB8, made resident when
    /// `budget` and `decodes` pay for its decode (and, in RGB8 slots, a slot is free this frame); `None`
    /// when they cannot. A parent in the slots is marked used this frame, so the child's fetch keeps it.
    fn parent(
        &mut self,
        pl: usize,
        ptx: u32,
        pty: u32,
        budget: &mut u64,
        decodes: &mut u32,
    ) -> Result<Option<ParentAt>> {
        let l = &self.package.header().levels[pl];
        let tile = u32::try_from(l.first_tile + (pty * l.tiles_x + ptx) as usize).unwrap_or(NONE);
        let Some((w, h)) = self.package.tile_size(pl, ptx, pty) else {
            return Ok(None);
        };
        let texels = u64::from(w) * u64::from(h);
        let shared = !self.format.is_block();
        if shared {
            let held = self.map[tile as usize];
            if held != NONE {
                self.slots[held as usize].used = self.frame;
                return Ok(Some(ParentAt::Slot(held as usize)));
            }
        } else if let Some(i) = self.parents.iter().position(|p| p.tile == tile) {
            self.parents[i].used = self.frame;
            return Ok(Some(ParentAt::Kept(i)));
        }
        // Least recently used (by frame, then slot), never a slot used this frame: the same parents
        // stay run to run.
        let place = if shared {
            self.victim()
        } else {
            (0..self.parents.len()).min_by_key(|&i| {
                let p = &self.parents[i];
                (p.tile != NONE, p.used, i)
            })
        };
        let Some(i) = place else {
            return Ok(None);
        };
        if texels > *budget || *decodes == 0 {
            return Ok(None);
        }
        if shared {
            self.unmap(i);
        }
        let p = if shared { &mut self.slots[i] } else { &mut self.parents[i] };
        p.tile = NONE;
        self.package.decode_tile(pl, ptx, pty, &mut p.texels)?;
        p.tile = tile;
        p.used = self.frame;
        if shared {
            self.map[tile as usize] = u32::try_from(i).unwrap_or(NONE);
        }
        *budget -= texels;
        *decodes -= 1;
        self.stats.decoded += 1;
        self.stats.decoded_texels += texels;
        self.stats.parents += 1;
        Ok(Some(if shared {
            ParentAt::Slot(i)
        } else {
            ParentAt::Kept(i)
        }))
    }
}

/// Decodes tile (level, tx, ty) into `rgb` as the level's texels: a residual tile's prediction from
/// `parent` (its parent tile's RGB8) added.
fn decode_child(
    package: &ImageryPackage,
    (level, tx, ty): (usize, u32, u32),
    parent: Option<&[u8]>,
    rgb: &mut [u8],
) -> Result<()> {
    package.decode_tile(level, tx, ty, rgb)?;
    if let Some(p) = parent {
        package.add_prediction(level, tx, ty, p, rgb)?;
    }
    Ok(())
}
