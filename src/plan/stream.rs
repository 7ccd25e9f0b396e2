//! Stage 2, the per-frame plan: where the rings' heights come from, the resident pyramid or a package
//! streamed through its fixed tile cache (GC section 7: decode only what the update fills).
//!
//! A streamed level is filled only once every tile its bands read (level k, and level k + 1 for z_c) is
//! resident. Decoding is charged in samples against the same per-frame budget as the fill; a level whose
//! tiles are not resident yet stays stale like a budget overrun, and the frame never waits. The detail
//! pool's requests ([`HeightSource::prefetch`]) are decoded after the rings, under what they leave.

use crate::bake::pyramid::Pyramid;
use crate::package::TileCache;
use crate::plan::frame::Rect;
use crate::Result;

/// The heights a clipmap is filled from.
#[derive(Debug)]
pub enum HeightSource {
    /// The whole pyramid in memory (plain sources).
    Resident(Pyramid),
    /// A package, decoded tile by tile into a cache allocated once.
    Streamed(Box<TileCache>),
}

impl HeightSource {
    /// Height of pyramid level `k` at (i, j) as [`Pyramid::at`]: clamped to the data, the coarsest level
    /// decimated beyond it. Streamed: the tile must be resident ([`HeightSource::ensure_bands`] ran).
    #[inline]
    pub fn at(&self, k: u32, i: i64, j: i64) -> f32 {
        self.try_at(k, i, j)
            .expect("a streamed tile is made resident before its samples are read")
    }

    /// [`HeightSource::at`] where the sample can be read now: always for a resident pyramid; streamed,
    /// when its tile is resident in the cache (None otherwise). For measurements, which may not decode.
    #[inline]
    pub fn try_at(&self, k: u32, i: i64, j: i64) -> Option<f32> {
        match self {
            Self::Resident(p) => Some(p.at(k, i, j)),
            Self::Streamed(c) => {
                let (k, i, j) = coarsest_decimated(c, k, i, j);
                c.height(k, i, j)
            }
        }
    }

    /// Starts a frame (pins the tiles it uses in the cache).
    pub fn begin_frame(&mut self) {
        if let Self::Streamed(c) = self {
            c.begin_frame();
        }
    }

    /// Makes resident every tile that filling `bands` of data level `k` reads: level k under the bands and
    /// level k + 1 under their coarse stencil (z_c). Charges decoded samples to `budget`; `Ok(false)` when
    /// they are not all resident this frame. Always ready for a resident pyramid.
    pub fn ensure_bands(&mut self, k: u32, bands: &[Rect], budget: &mut u64) -> Result<bool> {
        let Self::Streamed(c) = self else {
            return Ok(true);
        };
        let mut ready = true;
        for b in bands {
            let (x0, y0, x1, y1) = (b.x0, b.y0, b.x1(), b.y1());
            for (kk, rect) in [
                (k, (x0, y0, x1, y1)),
                (
                    k + 1,
                    ((x0 >> 1) - 1, (y0 >> 1) - 1, (x1 >> 1) + 2, (y1 >> 1) + 2),
                ),
            ] {
                let last = c.package().header().levels.len() - 1;
                let level = (kk as usize).min(last);
                // Past the coarsest level every sample reads the coarsest level's single tile row.
                let rect = if kk as usize > last {
                    (0, 0, i64::MAX, i64::MAX)
                } else {
                    rect
                };
                ready &= c.ensure_rect(level, rect, budget)?;
                if !ready {
                    return Ok(false);
                }
            }
        }
        Ok(ready)
    }

    /// Whether samples `rect` of pyramid level `k` can be read now ([`HeightSource::at`]): always for a
    /// resident pyramid; streamed, when every tile under them is resident (past the coarsest stored level,
    /// the coarsest level's samples they decimate).
    pub fn rect_ready(&self, k: u32, rect: &Rect) -> bool {
        match self {
            Self::Resident(_) => true,
            Self::Streamed(c) => {
                let (level, r) = stored_rect(c, k, rect);
                c.rect_resident(level, r)
            }
        }
    }

    /// Makes resident the tiles under each of `requests` (pyramid level, samples), in order, while
    /// `budget` (samples) lasts; stops at the first that cannot be decoded this frame (the rest wait).
    /// Returns the samples decoded (0 for a resident pyramid). The detail pool's tiles.
    pub fn prefetch(&mut self, requests: &[(u32, Rect)], budget: u32) -> Result<u32> {
        let Self::Streamed(c) = self else {
            return Ok(0);
        };
        let mut left = u64::from(budget);
        for (k, rect) in requests {
            let (level, r) = stored_rect(c, *k, rect);
            if !c.ensure_rect(level, r, &mut left)? {
                break;
            }
        }
        Ok(budget - u32::try_from(left).expect("at most the budget"))
    }

    /// The data's level 0 bilinearly at fractional grid (u, v), clamped at the edges: the pyramid's, or
    /// the finest resident level of the cache (0 when nothing is resident yet).
    pub fn ground(&self, u: f64, v: f64) -> f64 {
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        #[expect(
            clippy::cast_possible_truncation,
            reason = "floor of a finite coordinate; clamped on lookup"
        )]
        let (iu, iv) = (u0 as i64, v0 as i64);
        let bilinear =
            |at: &dyn Fn(i64, i64) -> f64, (iu, iv): (i64, i64), (fu, fv): (f64, f64)| {
                let a = at(iu, iv) * (1.0 - fu) + at(iu + 1, iv) * fu;
                let b = at(iu, iv + 1) * (1.0 - fu) + at(iu + 1, iv + 1) * fu;
                a * (1.0 - fv) + b * fv
            };
        match self {
            Self::Resident(p) => {
                let l0 = p.level(0);
                bilinear(&|a, b| f64::from(l0.at_clamped(a, b)), (iu, iv), (fu, fv))
            }
            Self::Streamed(c) => {
                for k in 0..c.package().header().levels.len() {
                    let s = f64::from(1u32 << k);
                    let (x, y) = (u / s, v / s);
                    let (x0, y0) = (x.floor(), y.floor());
                    #[expect(
                        clippy::cast_possible_truncation,
                        reason = "floor of a finite coordinate; clamped on lookup"
                    )]
                    let (ix, iy) = (x0 as i64, y0 as i64);
                    let resident = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .all(|&(di, dj)| c.units(k, ix + di, iy + dj).is_some());
                    if resident {
                        let at = |a: i64, b: i64| f64::from(c.height(k, a, b).unwrap_or(0.0));
                        return bilinear(&at, (ix, iy), (x - x0, y - y0));
                    }
                }
                0.0
            }
        }
    }
}

/// Reads one row of a streamed level left to right as [`HeightSource::at`] does (clamped to the level, in
/// metres through [`crate::package::Package::metres`], so bit for bit the same heights): the tile row under
/// the cursor is looked up once per tile instead of once per sample, the hot path of decode plus fill (a
/// lookup per sample, with its two divisions by the tile side, was 41 % of a desktop refill).
pub struct RowReader<'a> {
    cache: &'a TileCache,
    level: usize,
    /// The row, clamped to the level.
    y: u32,
    /// The level's last column.
    last: i64,
    /// Columns [x0, x0 + seg.len()) of the row, resident under the cursor.
    x0: i64,
    seg: &'a [i32],
}

impl<'a> RowReader<'a> {
    /// Height at column `i` of the row (clamped). Panics if its tile is not resident (the caller ran
    /// [`HeightSource::ensure_bands`] first), as [`HeightSource::at`] does.
    #[inline]
    pub fn get(&mut self, i: i64) -> f32 {
        let x = i.clamp(0, self.last);
        let mut off = x - self.x0;
        if off < 0 || off >= self.seg.len() as i64 {
            #[expect(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "clamped into the level, whose width is a u32"
            )]
            let (x0, seg) = self
                .cache
                .row_segment(self.level, x as u32, self.y)
                .expect("a streamed tile is made resident before its samples are read");
            (self.x0, self.seg) = (i64::from(x0), seg);
            off = x - self.x0;
        }
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "0 <= off < the segment's length"
        )]
        self.cache.package().metres(self.seg[off as usize])
    }
}

impl HeightSource {
    /// A [`RowReader`] over row `j` (clamped) of stored level `k` of a streamed source; None for a
    /// resident pyramid or past the coarsest stored level (decimated), where [`HeightSource::at`] serves.
    pub fn row(&self, k: u32, j: i64) -> Option<RowReader<'_>> {
        let Self::Streamed(c) = self else {
            return None;
        };
        let levels = &c.package().header().levels;
        let l = levels.get(k as usize)?;
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped into the level, whose height is a u32"
        )]
        let y = j.clamp(0, i64::from(l.height) - 1) as u32;
        Some(RowReader {
            cache: c,
            level: k as usize,
            y,
            last: i64::from(l.width) - 1,
            x0: 0,
            seg: &[],
        })
    }
}

/// Pyramid level `k` past the coarsest stored level reads the coarsest at (i 2^s, j 2^s), as [`Pyramid::at`].
fn coarsest_decimated(c: &TileCache, k: u32, i: i64, j: i64) -> (usize, i64, i64) {
    let last = c.package().header().levels.len() - 1;
    let k = k as usize;
    if k <= last {
        return (k, i, j);
    }
    let s = u32::try_from(k - last).unwrap_or(63).min(40);
    (last, i.saturating_mul(1 << s), j.saturating_mul(1 << s))
}

/// Samples `rect` of pyramid level `k` as a stored level's sample range (x0, y0, x1, y1): past the
/// coarsest stored level, the coarsest level's samples they decimate ([`coarsest_decimated`]).
fn stored_rect(c: &TileCache, k: u32, rect: &Rect) -> (usize, (i64, i64, i64, i64)) {
    let (level, x0, y0) = coarsest_decimated(c, k, rect.x0, rect.y0);
    let (_, x1, y1) = coarsest_decimated(c, k, rect.x1() - 1, rect.y1() - 1);
    (level, (x0, y0, x1 + 1, y1 + 1))
}
