//! Stage 1b, the package: the fixed tile cache, allocated once from `budget.cpu_memory_bytes`.
//!
//! The cache holds decoded tiles (heights in quantum units) of any level, for the rings' fill and the
//! detail pool's tiles alike. Fetching a tile decodes it from
//! the package (GC section 7: residual + U of the coarser level, whose tiles are fetched first) and is
//! charged in samples against the caller's per-frame budget: a fetch the budget cannot pay for, or one with
//! no free slot (every slot used this frame), returns `false` and the caller falls back as for a budget
//! overrun. Nothing allocates after [`TileCache::new`]; eviction is least-recently-used by frame stamp, so
//! for a given flight and budget the resident set, and every frame hash, is the same run to run.

use super::read::{Package, TileDecoder};
use crate::{Error, Result};

/// Marks an empty slot or a tile with no slot.
const NONE: u32 = u32::MAX;

/// One cache slot: a tile's decoded samples and what it holds.
#[derive(Debug)]
struct Slot {
    /// Global tile index (the header's tile table order), or [`NONE`].
    tile: u32,
    /// Frame stamp of the last use; a slot stamped this frame is never evicted.
    used: u64,
    /// Samples, tw * th row-major (the buffer is always tile * tile long).
    data: Vec<i32>,
}

/// Counters since the cache was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CacheStats {
    /// Fetches answered from the cache.
    pub hits: u64,
    /// Tiles decoded.
    pub decoded: u64,
    /// Samples decoded.
    pub decoded_samples: u64,
    /// Tiles evicted to make room.
    pub evictions: u64,
    /// Fetches refused: over the budget or no free slot.
    pub refused: u64,
}

/// How a cache's bytes are split (for `clipsat info`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct CacheSplit {
    /// The budget, `budget.cpu_memory_bytes`.
    pub budget: u64,
    /// The parsed header and tile table.
    pub header: u64,
    /// The tile -> slot map (4 bytes per tile of the package).
    pub map: u64,
    /// Decoder scratch.
    pub decoder: u64,
    /// Tile slots.
    pub slots: u64,
    /// Number of slots.
    pub slot_count: u64,
}

impl CacheSplit {
    /// The budget that leaves `slots` tile slots for a package with this header ([`CacheSplit::plan`]
    /// inverted): for a caller that sizes its cache by what it reads, such as the LOD tables' bake.
    pub fn budget_for_slots(header: &super::format::Header, slots: u64) -> u64 {
        let t = u64::from(header.tile);
        let head = header.resident_bytes();
        let fixed = head + 4 * header.tiles.len() as u64 + TileDecoder::bytes(header.tile);
        fixed + slots * (4 * t * t + std::mem::size_of::<Slot>() as u64)
    }

    /// The split of `budget` bytes for a package with this header: fixed parts first, the rest in slots,
    /// at most one slot per tile of the package (a small package does not hold a large budget's slots
    /// it could never fill: 257^2 streamed on desktop touched 88 MiB more than loaded whole).
    pub fn plan(header: &super::format::Header, budget: u64) -> Self {
        let t = u64::from(header.tile);
        let head = header.resident_bytes();
        let map = 4 * header.tiles.len() as u64;
        let decoder = TileDecoder::bytes(header.tile);
        let slot = 4 * t * t + std::mem::size_of::<Slot>() as u64;
        let left = budget.saturating_sub(head + map + decoder);
        let slot_count = (left / slot).min(header.tiles.len() as u64);
        Self {
            budget,
            header: head,
            map,
            decoder,
            slots: slot_count * slot,
            slot_count,
        }
    }
}


/// The resident tiles of one package, in a fixed number of slots.
pub struct TileCache {
    package: Package,
    decoder: TileDecoder,
    slots: Vec<Slot>,
    map: Vec<u32>,
    frame: u64,
    stats: CacheStats,
    split: CacheSplit,
}

impl std::fmt::Debug for TileCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TileCache")
            .field("package", &self.package)
            .field("split", &self.split)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// The fewest slots a cache may have: a 3 x 3 neighbourhood per level, enough to decode any tile.
pub const MIN_SLOTS: u64 = 9;

impl TileCache {
    /// A cache for `package` in `budget` bytes (`budget.cpu_memory_bytes` of the profile named
    /// `profile`); every slot is allocated here, none later.
    pub fn new(package: Package, budget: u64, profile: &str) -> Result<Self> {
        let split = CacheSplit::plan(package.header(), budget);
        let levels = package.header().levels.len() as u64;
        // Every tile resident also decodes any tile.
        let need = (MIN_SLOTS * levels).min(package.header().tiles.len() as u64);
        if split.slot_count < need {
            return Err(Error::config(
                profile,
                "budget.cpu_memory_bytes",
                format!(
                    "{budget} bytes leave {} tile slots for {}; the package needs at least {need} \
                     ({MIN_SLOTS} per level)",
                    split.slot_count,
                    package.path().display()
                ),
            ));
        }
        let t = package.header().tile as usize;
        let count = usize::try_from(split.slot_count).map_err(|_| {
            Error::config(
                profile,
                "budget.cpu_memory_bytes",
                "too many slots for memory",
            )
        })?;
        let slots = (0..count)
            .map(|_| Slot {
                tile: NONE,
                used: 0,
                data: vec![0; t * t],
            })
            .collect();
        let decoder = package.tile_decoder()?;
        let map = vec![NONE; package.header().tiles.len()];
        Ok(Self {
            package,
            decoder,
            slots,
            map,
            frame: 1,
            stats: CacheStats::default(),
            split,
        })
    }

    /// The package.
    pub fn package(&self) -> &Package {
        &self.package
    }

    /// How the budget is split.
    pub fn split(&self) -> CacheSplit {
        self.split
    }

    /// Counters since the cache was made.
    pub fn stats(&self) -> CacheStats {
        self.stats
    }

    /// Starts a frame: tiles used from now on are pinned until the next call.
    pub fn begin_frame(&mut self) {
        self.frame += 1;
    }

    /// Global index of tile (tx, ty) of `level`; panics outside the grid (a caller bug).
    fn index(&self, level: usize, tx: u32, ty: u32) -> usize {
        let l = &self.package.header().levels[level];
        assert!(
            tx < l.tiles_x && ty < l.tiles_y,
            "tile ({tx}, {ty}) outside level {level}"
        );
        l.first_tile + (ty * l.tiles_x + tx) as usize
    }

    /// The decoded samples of tile (tx, ty) of `level` (tw * th, row-major, quantum units), if resident.
    pub fn tile(&self, level: usize, tx: u32, ty: u32) -> Option<&[i32]> {
        let s = self.map[self.index(level, tx, ty)];
        if s == NONE {
            return None;
        }
        let (_, _, tw, th) = self.package.header().tile_rect(level, tx, ty);
        Some(&self.slots[s as usize].data[..(tw * th) as usize])
    }

    /// The resident part of row `y` of `level` in the tile holding sample (x, y) (both inside the level):
    /// the tile's first column and that row's samples across the tile; `None` if the tile is not resident.
    /// Sequential readers look a tile up once per tile row instead of once per sample
    /// ([`crate::plan::stream::RowReader`]).
    pub fn row_segment(&self, level: usize, x: u32, y: u32) -> Option<(u32, &[i32])> {
        let h = self.package.header();
        let l = &h.levels[level];
        let (tx, ty) = (x / h.tile, y / h.tile);
        let s = self.map[l.first_tile + (ty * l.tiles_x + tx) as usize];
        if s == NONE {
            return None;
        }
        let x0 = tx * h.tile;
        let tw = h.tile.min(l.width - x0);
        let at = ((y - ty * h.tile) * tw) as usize;
        Some((x0, &self.slots[s as usize].data[at..at + tw as usize]))
    }

    /// Sample (i, j) of `level` in quantum units, clamped to the level's edges; `None` if its tile is not
    /// resident.
    #[inline]
    pub fn units(&self, level: usize, i: i64, j: i64) -> Option<i32> {
        units_in(&self.package, &self.map, &self.slots, level, i, j)
    }

    /// Sample (i, j) of `level` in metres, clamped; `None` if not resident.
    #[inline]
    pub fn height(&self, level: usize, i: i64, j: i64) -> Option<f32> {
        self.units(level, i, j).map(|k| self.package.metres(k))
    }

    /// Makes every tile of `level` covering samples x0..x1, y0..y1 (clamped to the level) resident,
    /// decoding what is missing while `budget` (samples) lasts. `Ok(false)`: not all resident this frame.
    pub fn ensure_rect(
        &mut self,
        level: usize,
        (x0, y0, x1, y1): (i64, i64, i64, i64),
        budget: &mut u64,
    ) -> Result<bool> {
        let (tx0, tx1, ty0, ty1) = self.tile_span(level, (x0, y0, x1, y1));
        let mut all = true;
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                all &= self.fetch(level, tx, ty, budget)?;
            }
        }
        Ok(all)
    }

    /// The tiles of `level` covering samples x0..x1, y0..y1 clamped to the level: inclusive tile columns
    /// (tx0, tx1) and rows (ty0, ty1).
    fn tile_span(
        &self,
        level: usize,
        (x0, y0, x1, y1): (i64, i64, i64, i64),
    ) -> (u32, u32, u32, u32) {
        let h = self.package.header();
        let l = h.levels[level];
        let t = i64::from(h.tile);
        let clamp_x = |x: i64| x.clamp(0, i64::from(l.width) - 1);
        let clamp_y = |y: i64| y.clamp(0, i64::from(l.height) - 1);
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped sample coordinates over the tile side are u32 tile indices"
        )]
        (
            (clamp_x(x0) / t) as u32,
            (clamp_x(x1 - 1) / t) as u32,
            (clamp_y(y0) / t) as u32,
            (clamp_y(y1 - 1) / t) as u32,
        )
    }

    /// Whether every tile of `level` covering samples x0..x1, y0..y1 (clamped to the level) is resident
    /// now, as [`TileCache::ensure_rect`] would find them (nothing decoded, nothing stamped).
    pub fn rect_resident(&self, level: usize, (x0, y0, x1, y1): (i64, i64, i64, i64)) -> bool {
        let (tx0, tx1, ty0, ty1) = self.tile_span(level, (x0, y0, x1, y1));
        (ty0..=ty1).all(|ty| (tx0..=tx1).all(|tx| self.map[self.index(level, tx, ty)] != NONE))
    }

    /// Makes tile (tx, ty) of `level` resident: a hit is free; a miss first fetches the coarser tiles its
    /// prediction reads, then decodes, charged tw * th samples. `Ok(false)` when the budget or the free
    /// slots do not allow it this frame (nothing half-done is left behind).
    pub fn fetch(&mut self, level: usize, tx: u32, ty: u32, budget: &mut u64) -> Result<bool> {
        let idx = self.index(level, tx, ty);
        let s = self.map[idx];
        if s != NONE {
            self.slots[s as usize].used = self.frame;
            self.stats.hits += 1;
            return Ok(true);
        }
        let h = self.package.header();
        let (x0, y0, tw, th) = h.tile_rect(level, tx, ty);
        let cost = u64::from(tw) * u64::from(th);
        let coarsest = level + 1 == h.levels.len();
        if cost > *budget {
            self.stats.refused += 1;
            return Ok(false);
        }
        if !coarsest {
            // The 4-point stencils of this tile and its border read these coarse samples.
            let rect = super::read::coarse_rect((x0, y0), (tw, th));
            if !self.ensure_rect(level + 1, rect, budget)? || cost > *budget {
                self.stats.refused += 1;
                return Ok(false);
            }
        }
        let Some(slot) = self.victim() else {
            self.stats.refused += 1;
            return Ok(false);
        };
        self.unmap(slot);
        let mut data = std::mem::take(&mut self.slots[slot].data);
        let result = {
            let (package, map, slots) = (&self.package, &self.map, &self.slots);
            let coarse = |a: i64, b: i64| -> i64 {
                let k = units_in(package, map, slots, level + 1, a, b)
                    .expect("the coarser tiles were made resident before decoding");
                i64::from(k)
            };
            package.decode_tile(&mut self.decoder, level, (tx, ty), coarse, &mut data)
        };
        self.slots[slot].data = data;
        self.slots[slot].tile = NONE;
        result?;
        let idx32 = u32::try_from(idx).expect("tile indices fit u32 (the map is sized by them)");
        self.slots[slot].tile = idx32;
        self.slots[slot].used = self.frame;
        self.map[idx] = u32::try_from(slot).expect("slot counts fit u32");
        *budget -= cost;
        self.stats.decoded += 1;
        self.stats.decoded_samples += cost;
        Ok(true)
    }

    /// [`TileCache::ensure_rect`] with no budget and one decoder per thread, for the LOD tables' bake: the
    /// coarser tiles the rectangle's prediction reads first, then its missing tiles decoded in parallel,
    /// each decoder taking the next tile as it comes free (`package::deal`: a tile's samples do not depend
    /// on which decoder made them, and each reads only the coarser level, resident before any starts).
    /// `Ok(false)` when the slots cannot hold them, as there; damage is the first damaged tile's error in
    /// tile order.
    pub fn ensure_rect_parallel(
        &mut self,
        level: usize,
        rect: (i64, i64, i64, i64),
        decoders: &mut [TileDecoder],
    ) -> Result<bool> {
        let (tx0, tx1, ty0, ty1) = self.tile_span(level, rect);
        let mut jobs = Vec::new();
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let idx = self.index(level, tx, ty);
                match self.map[idx] {
                    NONE => jobs.push((idx, tx, ty, NONE, Vec::new())),
                    s => {
                        self.slots[s as usize].used = self.frame;
                        self.stats.hits += 1;
                    }
                }
            }
        }
        if jobs.is_empty() {
            return Ok(true);
        }
        let h = self.package.header();
        if level + 1 < h.levels.len() {
            let (x0, y0, _, _) = h.tile_rect(level, tx0, ty0);
            let (x1, y1, w1, h1) = h.tile_rect(level, tx1, ty1);
            let coarse = super::read::coarse_rect((x0, y0), (x1 + w1 - x0, y1 + h1 - y0));
            if !self.ensure_rect_parallel(level + 1, coarse, decoders)? {
                return Ok(false);
            }
        }
        // Each tile's slot, reserved (stamped, holding the tile) but not mapped until it is decoded.
        for job in &mut jobs {
            let Some(slot) = self.victim() else {
                self.release(&mut jobs);
                self.stats.refused += 1;
                return Ok(false);
            };
            self.unmap(slot);
            let s = &mut self.slots[slot];
            s.tile = u32::try_from(job.0).expect("tile indices fit u32 (the map is sized by them)");
            s.used = self.frame;
            job.3 = u32::try_from(slot).expect("slot counts fit u32");
            job.4 = std::mem::take(&mut s.data);
        }
        let result = {
            let (package, map, slots) = (&self.package, &self.map, &self.slots);
            let decode = |dec: &mut TileDecoder, _: usize, job: &mut (usize, u32, u32, u32, Vec<i32>)| {
                let coarse = |a: i64, b: i64| -> i64 {
                    let k = units_in(package, map, slots, level + 1, a, b)
                        .expect("the coarser tiles were made resident before decoding");
                    i64::from(k)
                };
                package.decode_tile(dec, level, (job.1, job.2), coarse, &mut job.4)
            };
            super::deal::deal(&mut jobs, decoders, decode, || (), "a tile decoding thread panicked").0
        };
        if let Err(e) = result {
            self.release(&mut jobs);
            return Err(e);
        }
        for (idx, tx, ty, slot, data) in jobs {
            let (_, _, tw, th) = self.package.header().tile_rect(level, tx, ty);
            let cost = u64::from(tw) * u64::from(th);
            self.slots[slot as usize].data = data;
            self.map[idx] = slot;
            self.stats.decoded += 1;
            self.stats.decoded_samples += cost;
        }
        Ok(true)
    }

    /// Evicts the tile `slot` holds, if any: it is no longer resident.
    fn unmap(&mut self, slot: usize) {
        let old = self.slots[slot].tile;
        if old != NONE {
            self.map[old as usize] = NONE;
            self.stats.evictions += 1;
        }
    }

    /// Gives reserved slots back empty, with their buffers.
    fn release(&mut self, jobs: &mut [(usize, u32, u32, u32, Vec<i32>)]) {
        for (_, _, _, slot, data) in jobs.iter_mut() {
            if *slot != NONE {
                let s = &mut self.slots[*slot as usize];
                s.data = std::mem::take(data);
                s.tile = NONE;
                s.used = 0;
            }
        }
    }

    /// The least recently used slot not used this frame (empty slots first, lowest index on ties).
    fn victim(&self) -> Option<usize> {
        let mut best: Option<(u64, usize)> = None;
        for (i, s) in self.slots.iter().enumerate() {
            if s.used == self.frame && s.tile != NONE {
                continue;
            }
            let key = if s.tile == NONE { 0 } else { s.used };
            if best.is_none_or(|(k, _)| key < k) {
                best = Some((key, i));
            }
        }
        best.map(|(_, i)| i)
    }
}

/// [`TileCache::units`] over the cache's parts, so a decode can read coarse tiles while writing a slot.
#[inline]
fn units_in(
    package: &Package,
    map: &[u32],
    slots: &[Slot],
    level: usize,
    i: i64,
    j: i64,
) -> Option<i32> {
    let h = package.header();
    let l = &h.levels[level];
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "clamped into 0..width and 0..height, which are u32"
    )]
    let (x, y) = (
        i.clamp(0, i64::from(l.width) - 1) as u32,
        j.clamp(0, i64::from(l.height) - 1) as u32,
    );
    let (tx, ty) = (x / h.tile, y / h.tile);
    let s = map[l.first_tile + (ty * l.tiles_x + tx) as usize];
    if s == NONE {
        return None;
    }
    let tw = h.tile.min(l.width - tx * h.tile);
    let at = (y - ty * h.tile) * tw + (x - tx * h.tile);
    Some(slots[s as usize].data[at as usize])
}
