//! Stage 1, bake: the bands of the SAT LOD tables' out-of-core bake ([`super`]): each band's tiles made
//! resident and its rows copied out of the cache, its rows' work shared among the cores, and the levels'
//! fold of the band before it on a thread of its own meanwhile.
//!
//! A level's fold (its cells' rows closed, coded and written in order) reads only the rows' results, and
//! the rows' work only the band's copied rows, so band b - 1 is folded and band b + 1 decoded and copied
//! while band b's rows are worked: a core is not left idle while one thread copies a band out of the
//! cache, decodes its last tile or folds the finest level, and each level still folds its rows in order,
//! so nothing baked depends on the thread count.

use super::rows::{par_rows, RowOut, RowView};
use super::{Level, Sweep, TRIM_BYTES};
use crate::package::read::TileDecoder;
use crate::package::TileCache;
use crate::{Error, Result};

/// One band as the rows' work reads it: its data rows, their level-0 heights, and each swept level's
/// rows `j0 ..` (`row_len` values each, metres as f64, clamped as `Pyramid::at`).
#[derive(Default)]
struct Band {
    y0: u32,
    y1: u32,
    h0: Vec<f32>,
    levels: Vec<(Vec<f64>, i64)>,
}

impl Sweep<'_> {
    /// One pass over the terrain a band of level-0 tile rows at a time: each band decoded once, then for
    /// every level `pick` takes, `row(level, row heights, y, scratch, out)` for each of the band's rows
    /// (every level's rows shared among the cores, [`par_rows`]), then `fold(level, outs, y0)` over them
    /// in order, level after level on a thread of its own while the next band is worked and the one after
    /// it loaded (`err` makes its errors). Errors come in the order one thread doing it all in turn meets
    /// them.
    pub(super) fn sweep_bands(
        &mut self,
        pick: impl Fn(&Level) -> bool,
        row: impl Fn(&RowView<'_>, &[f32], u32, &mut Vec<f32>, &mut RowOut) + Sync,
        fold: impl Fn(&mut Level, &[RowOut], u32) -> std::io::Result<()> + Sync,
        err: impl Fn(std::io::Error) -> Error,
    ) -> Result<()> {
        let Sweep {
            cache,
            decoders,
            levels,
            meter,
            width,
            bands,
            last,
            band_bytes,
            untrimmed,
            ..
        } = self;
        let (width, bands, last) = (*width, *bands, *last);
        let mut picked: Vec<&mut Level> = levels.iter_mut().filter(|l| pick(l)).collect();
        // What the rows' work reads of each level (fixed for the sweep), apart from the levels' states,
        // which the fold changes meanwhile.
        let shapes: Vec<(u32, RowView<'static>)> =
            picked.iter().map(|l| (l.k, l.shape())).collect();
        let new_band = || {
            let mut b = Band::default();
            b.levels.resize_with(shapes.len(), Default::default);
            b
        };
        // The band whose rows are worked, and the next one, loaded meanwhile.
        let (mut band, mut next) = (new_band(), new_band());
        let mut load = |b: u32, band: &mut Band| -> Result<()> {
            load_band(cache, decoders, &shapes, b, last, band)?;
            // The package's mapped pages are dropped once the bands since the last time read about
            // TRIM_BYTES of it, and after the last band: dropping them costs every core a TLB flush, too
            // much for each band of a small package, and the pages held stay under a fixed bound.
            *untrimmed += *band_bytes;
            if *untrimmed >= TRIM_BYTES || b + 1 == bands {
                cache.package().trim();
                *untrimmed = 0;
            }
            Ok(())
        };
        // The rows' results of the band being worked, and of the one being folded.
        let mut outs: Vec<Vec<RowOut>> = shapes.iter().map(|_| Vec::new()).collect();
        let mut folding: Vec<Vec<RowOut>> = shapes.iter().map(|_| Vec::new()).collect();
        let mut loaded = (bands > 0).then(|| load(0, &mut band));
        let (mut b, mut to_fold) = (0, None);
        loop {
            // Band b's rows are worked (if it loaded) while band b - 1 is folded and band b + 1 loaded.
            let (work, failed) = match loaded.take() {
                Some(Ok(())) => (true, None),
                Some(Err(e)) => (false, Some(e)),
                None => (false, None),
            };
            let (folded, next_loaded) = std::thread::scope(|s| {
                let side = to_fold.map(|y0| {
                    let (picked, folding, fold) = (&mut picked, &folding, &fold);
                    s.spawn(move || {
                        picked
                            .iter_mut()
                            .zip(folding)
                            .try_for_each(|(lv, o)| fold(lv, o, y0))
                    })
                });
                let next_loaded = if work {
                    let views = shapes.iter().zip(&band.levels).map(|(&(_, shape), (rows, j0))| {
                        RowView {
                            band: rows,
                            j0: *j0,
                            ..shape
                        }
                    });
                    let (next, load) = (&mut next, &mut load);
                    par_rows(
                        views.zip(outs.iter_mut()).collect(),
                        (&band.h0, width),
                        (band.y0, band.y1),
                        &row,
                        || (b + 1 < bands).then(|| load(b + 1, next)),
                    )
                } else {
                    None
                };
                let folded = side.map(|h| {
                    h.join()
                        .unwrap_or_else(|_| panic!("a LOD table level's fold panicked"))
                });
                (folded, next_loaded)
            });
            // In band order: band b - 1's fold, then band b's load (its rows cannot fail).
            if let Some(folded) = folded {
                folded.map_err(&err)?;
                meter.inc(1);
            }
            if let Some(e) = failed {
                return Err(e);
            }
            if !work {
                break;
            }
            to_fold = Some(band.y0);
            std::mem::swap(&mut outs, &mut folding);
            std::mem::swap(&mut band, &mut next);
            loaded = next_loaded;
            b += 1;
        }
        Ok(())
    }
}

/// Level k's height at (a, b) as [`crate::bake::pyramid::Pyramid::at`] reads it, from the cache.
fn height(cache: &TileCache, last: u32, k: u32, a: i64, b: i64) -> f64 {
    let (level, a, b) = if k <= last {
        (k, a, b)
    } else {
        let s = (k - last).min(40);
        (last, a.saturating_mul(1 << s), b.saturating_mul(1 << s))
    };
    let h = cache
        .height(level as usize, a, b)
        .expect("the band's tiles were made resident before reading them");
    f64::from(h)
}

/// Copies the level-k rows band rows `y0 .. y1` read (j = y >> ke and j + 1) out of the cache into
/// `rows`; returns the first, j0.
fn level_rows(
    cache: &TileCache,
    last: u32,
    (k, v): (u32, &RowView<'_>),
    (y0, y1): (u32, u32),
    rows: &mut Vec<f64>,
) -> i64 {
    let (j0, j1) = (i64::from(y0 >> v.ke), i64::from((y1 - 1) >> v.ke) + 1);
    rows.clear();
    if k > last {
        for b in j0..=j1 {
            for a in 0..v.row_len as i64 {
                rows.push(height(cache, last, k, a, b));
            }
        }
        return j0;
    }
    // A data level: whole tile rows at a time, clamped to its edges as `height` reads them.
    let level = k as usize;
    let d = cache.package().header().levels[level];
    for b in j0..=j1 {
        let y = u32::try_from(b.clamp(0, i64::from(d.height) - 1)).expect("clamped into the level");
        let start = rows.len();
        let mut x = 0;
        while x < d.width && rows.len() - start < v.row_len {
            let (_, seg) = cache
                .row_segment(level, x, y)
                .expect("the band's tiles were made resident before reading them");
            let seg = &seg[..seg.len().min(v.row_len - (rows.len() - start))];
            rows.extend(seg.iter().map(|&h| f64::from(cache.package().metres(h))));
            x += u32::try_from(seg.len()).expect("a tile row fits u32");
        }
        let edge = rows[rows.len() - 1];
        rows.resize(start + v.row_len, edge);
    }
    j0
}

/// Makes band `b`'s tiles resident (level-0 tile row `b`, and each level's rows its errors read), and
/// copies its level-0 heights and each level's rows into `band`.
fn load_band(
    cache: &mut TileCache,
    decoders: &mut [TileDecoder],
    shapes: &[(u32, RowView<'static>)],
    b: u32,
    last: u32,
    band: &mut Band,
) -> Result<()> {
    let header = cache.package().header().clone();
    let (width, t) = (header.width, header.tile);
    let y0 = b * t;
    let y1 = (y0 + t).min(header.height);
    cache.begin_frame();
    let mut all = cache.ensure_rect_parallel(
        0,
        (0, i64::from(y0), i64::from(width), i64::from(y1)),
        decoders,
    )?;
    for &(k, v) in shapes {
        let (level, rect) = if k <= last {
            let d = header.levels[k as usize];
            let j0 = i64::from(y0 >> v.ke);
            let j1 = i64::from((y1 - 1) >> v.ke) + 2;
            (k, (0, j0, i64::from(d.width), j1))
        } else {
            let d = header.levels[last as usize];
            (last, (0, 0, i64::from(d.width), i64::from(d.height)))
        };
        all &= cache.ensure_rect_parallel(level as usize, rect, decoders)?;
    }
    assert!(
        all,
        "the bake's tile cache holds a band's tiles (sized from the widths)"
    );
    band.h0.clear();
    for y in y0..y1 {
        let mut x = 0;
        while x < width {
            let (x0, seg) = cache
                .row_segment(0, x, y)
                .expect("the band's level-0 tiles are resident");
            debug_assert_eq!(x0, x);
            band.h0.extend(seg.iter().map(|&v| cache.package().metres(v)));
            x += u32::try_from(seg.len()).expect("a tile row fits u32");
        }
    }
    for (&(k, v), (rows, j0)) in shapes.iter().zip(&mut band.levels) {
        *j0 = level_rows(cache, last, (k, &v), (y0, y1), rows);
    }
    (band.y0, band.y1) = (y0, y1);
    Ok(())
}
