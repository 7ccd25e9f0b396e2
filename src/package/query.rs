//! Stage 1b, the package: exact queries of the data's full-resolution surface (level 0), for picking and
//! collision: the bilinear height at a point and the first hit of a ray ([`crate::package::ray`]).
//!
//! The surface is the bilinear interpolation of level 0's samples ([`bilinear`], the one definition every
//! query uses). Its samples come from a held grid ([`ResidentGrid`]) or from a package through a small
//! tile cache of its own ([`QueryTiles`]: a [`TileCache`] allocated once, never the rings' cache, so a
//! query changes no frame), with each level-0 tile's height range kept once known, for the ray's skips.

use crate::package::{Package, TileCache};
use crate::source::Heightmap;
use crate::{Error, Result};

/// The side, in samples, of the tiles a resident grid keeps height ranges for (a package's own tiles are
/// used for a streamed terrain).
pub const RESIDENT_TILE: u32 = 64;

/// The bilinear height of a cell with corner heights `z00` (i, j), `z10` (i + 1, j), `z01` (i, j + 1) and
/// `z11` (i + 1, j + 1) at fractions (`fx`, `fy`) in [0, 1]: in f64, a = z00 + fx (z10 - z00),
/// b = z01 + fx (z11 - z01), a + fy (b - a). The one definition of the queried surface.
#[inline]
pub fn bilinear(z00: f64, z10: f64, z01: f64, z11: f64, fx: f64, fy: f64) -> f64 {
    let a = z00 + fx * (z10 - z00);
    let b = z01 + fx * (z11 - z01);
    a + fy * (b - a)
}

/// The cell (i, j) and the fractions (fx, fy) of grid point (u, v) (column, row; fractional) in a grid of
/// `w` x `h` samples, or None outside [0, w - 1] x [0, h - 1] (or not finite). The last column's and row's
/// points take the cell before them (fraction 1).
pub fn cell_of(w: u32, h: u32, u: f64, v: f64) -> Option<(u32, u32, f64, f64)> {
    let (wm, hm) = (f64::from(w.saturating_sub(1)), f64::from(h.saturating_sub(1)));
    if !(u >= 0.0 && v >= 0.0 && u <= wm && v <= hm) {
        return None;
    }
    let last = |n: u32| f64::from(n.saturating_sub(2));
    let (i, j) = (u.floor().min(last(w)), v.floor().min(last(h)));
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "floors of coordinates checked inside 0 ..= width - 2, which is u32"
    )]
    Some((i as u32, j as u32, u - i, v - j))
}

/// The level-0 samples a query reads: a grid held whole or a package's tiles decoded on demand, with the
/// height range of each of its tiles (of side [`Level0::tile_side`]).
pub trait Level0 {
    /// Samples (columns, rows).
    fn size(&self) -> (u32, u32);
    /// The side of the tiles [`Level0::tile_range`] answers for, samples.
    fn tile_side(&self) -> u32;
    /// Lowest and highest height of the whole grid, metres (a bound: no sample lies outside it).
    fn range(&self) -> (f64, f64);
    /// Sample (i, j), metres, clamped to the grid.
    fn sample(&mut self, i: u32, j: u32) -> Result<f32>;
    /// The four corners of cell (i, j) (clamped): (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1).
    fn corners(&mut self, i: u32, j: u32) -> Result<[f64; 4]> {
        Ok([
            f64::from(self.sample(i, j)?),
            f64::from(self.sample(i + 1, j)?),
            f64::from(self.sample(i, j + 1)?),
            f64::from(self.sample(i + 1, j + 1)?),
        ])
    }
    /// Lowest and highest sample of tile (tx, ty), metres.
    fn tile_range(&mut self, tx: u32, ty: u32) -> Result<(f64, f64)>;
    /// Starts a query: a cache keeps the tiles it reads until the next one, as far as its slots allow.
    fn begin(&mut self) {}
}

/// The bilinear height of `grid` at grid point (u, v) ([`bilinear`] over [`cell_of`]'s cell), or None
/// outside the grid.
pub fn height(grid: &mut impl Level0, u: f64, v: f64) -> Result<Option<f64>> {
    let (w, h) = grid.size();
    let Some((i, j, fx, fy)) = cell_of(w, h, u, v) else {
        return Ok(None);
    };
    let [z00, z10, z01, z11] = grid.corners(i, j)?;
    Ok(Some(bilinear(z00, z10, z01, z11, fx, fy)))
}

/// Height ranges of a held grid's tiles of side [`RESIDENT_TILE`], computed once.
#[derive(Clone, Debug)]
pub struct GridRanges {
    tiles_x: u32,
    ranges: Vec<[f32; 2]>,
    range: (f64, f64),
}

impl GridRanges {
    /// The ranges of `hm`'s tiles (8 bytes a tile of [`RESIDENT_TILE`]^2 samples).
    pub fn new(hm: &Heightmap) -> Self {
        let (w, h) = (hm.width(), hm.height());
        let (tx, ty) = (w.div_ceil(RESIDENT_TILE), h.div_ceil(RESIDENT_TILE));
        let mut ranges = vec![[f32::INFINITY, f32::NEG_INFINITY]; tx as usize * ty as usize];
        for (j, row) in hm.heights().chunks_exact(w as usize).enumerate() {
            let base = j / RESIDENT_TILE as usize * tx as usize;
            for (t, seg) in row.chunks(RESIDENT_TILE as usize).enumerate() {
                let r = &mut ranges[base + t];
                for &z in seg {
                    r[0] = r[0].min(z);
                    r[1] = r[1].max(z);
                }
            }
        }
        let (lo, hi) = hm.range();
        Self {
            tiles_x: tx,
            ranges,
            range: (f64::from(lo), f64::from(hi)),
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        8 * self.ranges.len() as u64
    }
}

/// A held grid and its tiles' ranges, as [`Level0`].
#[derive(Debug)]
pub struct ResidentGrid<'a> {
    /// The grid.
    pub grid: &'a Heightmap,
    /// Its tiles' ranges ([`GridRanges::new`] of the same grid).
    pub ranges: &'a GridRanges,
}

impl Level0 for ResidentGrid<'_> {
    fn size(&self) -> (u32, u32) {
        (self.grid.width(), self.grid.height())
    }

    fn tile_side(&self) -> u32 {
        RESIDENT_TILE
    }

    fn range(&self) -> (f64, f64) {
        self.ranges.range
    }

    #[inline]
    fn sample(&mut self, i: u32, j: u32) -> Result<f32> {
        let (w, h) = (self.grid.width(), self.grid.height());
        Ok(self.grid.at(i.min(w - 1), j.min(h - 1)))
    }

    #[inline]
    fn corners(&mut self, i: u32, j: u32) -> Result<[f64; 4]> {
        let (w, h) = (self.grid.width() as usize, self.grid.height() as usize);
        let z = self.grid.heights();
        let (i0, j0) = ((i as usize).min(w - 1), (j as usize).min(h - 1));
        let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
        Ok([
            f64::from(z[j0 * w + i0]),
            f64::from(z[j0 * w + i1]),
            f64::from(z[j1 * w + i0]),
            f64::from(z[j1 * w + i1]),
        ])
    }

    fn tile_range(&mut self, tx: u32, ty: u32) -> Result<(f64, f64)> {
        let r = self
            .ranges
            .ranges
            .get(ty as usize * self.ranges.tiles_x as usize + tx as usize)
            .ok_or_else(|| Error::Invalid {
                what: "query tile".into(),
                reason: format!("({tx}, {ty}) is outside the grid"),
            })?;
        Ok((f64::from(r[0]), f64::from(r[1])))
    }
}

/// A package's level 0 read through a tile cache of its own, allocated once: a miss decodes the tile (and
/// the coarser tiles its prediction reads); the height range of each level-0 tile decoded once is kept
/// (8 bytes a tile) for the ray's skips.
#[derive(Debug)]
pub struct QueryTiles {
    cache: TileCache,
    /// Per level-0 tile, (lowest, highest) in quantum units; (1, 0) while not known.
    ranges: Vec<[i32; 2]>,
    /// Level 0's tiles per row.
    tiles_x: u32,
    range: (f64, f64),
    bytes: u64,
}

impl QueryTiles {
    /// The query cache of `package` in `budget` bytes (the profile `profile`'s query share): the tile
    /// ranges, then the cache's header, map, decoder and slots. Refused when the budget leaves the cache
    /// fewer slots than any tile's decode needs ([`TileCache::new`]).
    pub fn new(package: Package, budget: u64, profile: &str) -> Result<Self> {
        let h = package.header();
        let l0 = h.levels[0];
        let tiles = u64::from(l0.tiles_x) * u64::from(l0.tiles_y);
        let range_bytes = 8 * tiles;
        // No sample decodes outside the source's range by more than the stated bound.
        let slack = h.max_error + 1e-6 * f64::from(h.range.0.abs().max(h.range.1.abs()));
        let range = (f64::from(h.range.0) - slack, f64::from(h.range.1) + slack);
        let tiles_x = l0.tiles_x;
        let n = usize::try_from(tiles).map_err(|_| Error::Invalid {
            what: "query cache".into(),
            reason: format!("{tiles} tiles do not fit in memory"),
        })?;
        let cache = TileCache::new(package, budget.saturating_sub(range_bytes), profile)?;
        let s = cache.split();
        Ok(Self {
            cache,
            ranges: vec![[1, 0]; n],
            tiles_x,
            range,
            bytes: range_bytes + s.header + s.map + s.decoder + s.slots,
        })
    }

    /// Bytes held: the tile ranges and the cache (within the budget given to [`QueryTiles::new`]).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// The cache's counters (hits, tiles decoded).
    pub fn stats(&self) -> crate::package::CacheStats {
        self.cache.stats()
    }

    /// Makes level-0 tile (tx, ty) resident, decoding it if it is not (a query is never refused for its
    /// budget; with every slot used by this query, the query's earlier tiles are let go).
    fn fetch(&mut self, tx: u32, ty: u32) -> Result<()> {
        let mut budget = u64::MAX;
        if self.cache.fetch(0, tx, ty, &mut budget)? {
            return Ok(());
        }
        self.cache.begin_frame();
        let mut budget = u64::MAX;
        if self.cache.fetch(0, tx, ty, &mut budget)? {
            return Ok(());
        }
        Err(Error::Invalid {
            what: "query cache".into(),
            reason: format!("no slot for level-0 tile ({tx}, {ty})"),
        })
    }

    #[inline]
    fn units(&mut self, i: u32, j: u32) -> Result<i32> {
        let (i, j) = (i64::from(i), i64::from(j));
        if let Some(k) = self.cache.units(0, i, j) {
            return Ok(k);
        }
        let h = self.cache.package().header();
        let l0 = h.levels[0];
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped into the level, which is u32"
        )]
        let (x, y) = (
            i.clamp(0, i64::from(l0.width) - 1) as u32,
            j.clamp(0, i64::from(l0.height) - 1) as u32,
        );
        let t = h.tile;
        self.fetch(x / t, y / t)?;
        self.cache.units(0, i, j).ok_or_else(|| Error::Invalid {
            what: "query cache".into(),
            reason: format!("sample ({x}, {y}) not resident after its decode"),
        })
    }
}

impl Level0 for QueryTiles {
    fn size(&self) -> (u32, u32) {
        let h = self.cache.package().header();
        (h.width, h.height)
    }

    fn tile_side(&self) -> u32 {
        self.cache.package().header().tile
    }

    fn range(&self) -> (f64, f64) {
        self.range
    }

    #[inline]
    fn sample(&mut self, i: u32, j: u32) -> Result<f32> {
        let k = self.units(i, j)?;
        Ok(self.cache.package().metres(k))
    }

    fn begin(&mut self) {
        self.cache.begin_frame();
    }

    /// Two row reads of one tile where the cell lies inside it (most cells), else four samples.
    #[inline]
    fn corners(&mut self, i: u32, j: u32) -> Result<[f64; 4]> {
        let (w, h) = self.size();
        let t = self.cache.package().header().tile;
        if i + 1 < w && j + 1 < h && i % t + 1 < t && j % t + 1 < t {
            if let (Some((x0, r0)), Some((_, r1))) = (
                self.cache.row_segment(0, i, j),
                self.cache.row_segment(0, i, j + 1),
            ) {
                let a = (i - x0) as usize;
                let p = self.cache.package();
                let m = |k: i32| f64::from(p.metres(k));
                return Ok([m(r0[a]), m(r0[a + 1]), m(r1[a]), m(r1[a + 1])]);
            }
        }
        Ok([
            f64::from(self.sample(i, j)?),
            f64::from(self.sample(i + 1, j)?),
            f64::from(self.sample(i, j + 1)?),
            f64::from(self.sample(i + 1, j + 1)?),
        ])
    }

    fn tile_range(&mut self, tx: u32, ty: u32) -> Result<(f64, f64)> {
        let at = ty as usize * self.tiles_x as usize + tx as usize;
        let known = *self.ranges.get(at).ok_or_else(|| Error::Invalid {
            what: "query tile".into(),
            reason: format!("({tx}, {ty}) is outside level 0"),
        })?;
        let [lo, hi] = if known[0] <= known[1] {
            known
        } else {
            self.fetch(tx, ty)?;
            let tile = self.cache.tile(0, tx, ty).ok_or_else(|| Error::Invalid {
                what: "query cache".into(),
                reason: format!("level-0 tile ({tx}, {ty}) not resident after its decode"),
            })?;
            let r = tile
                .iter()
                .fold([i32::MAX, i32::MIN], |[a, b], &k| [a.min(k), b.max(k)]);
            self.ranges[at] = r;
            r
        };
        let p = self.cache.package();
        Ok((f64::from(p.metres(lo)), f64::from(p.metres(hi))))
    }
}
