//! Stage 0, the source: a mosaic's tiles read a band of rows at a time as one [`RowSource`], through at
//! most [`MAX_OPEN_TILES`] open tile readers.
//!
//! What it holds: the tiles' placements (a path and a few numbers each), and for each open reader its
//! file, two cached tile rows and, for a GeoTIFF, one decoded row of strips or tiles (the whole tile for
//! a tile stored as one strip). A reader is closed once the bands have passed its tile, so the readers
//! open are those of the tiles across the band. The band itself is the caller's.

use std::path::Path;

use super::{Layout, GRID_TOLERANCE};
use crate::source::rows::{check_band, read_exact_at};
use crate::source::{is_nodata, LoadOptions, RowGrid, RowSource};
use crate::{Error, Result};

/// The most tile readers open at once; the least recently used is closed to open another.
pub const MAX_OPEN_TILES: usize = 16;

/// Rows a band the mosaic is scanned and loaded in.
pub(super) const BAND_ROWS: u32 = 64;

/// SRTM's void marker.
const HGT_VOID: i16 = -32768;

/// A mosaic of tiles read as one grid: a sample is the first tile's, in the layout's order, that has data
/// there (a tile of the finest spacing at its own sample, a coarser one interpolated bilinearly); where
/// none has, it is [`LoadOptions::fill_height`], or no data (NaN).
pub(crate) struct Mosaic {
    layout: Layout,
    opts: LoadOptions,
    open: Vec<Open>,
    clock: u64,
    /// Whether no-data samples are an error (a mosaic streamed once found to have none).
    refuse: bool,
    /// For each tile coarser E-W than the grid across the band being read: its east sample column's
    /// values at the band's rows (NaN off the tile), for the seam past it ([`Mosaic::join_seams`]).
    east: Vec<(usize, Vec<f32>)>,
}

/// An open tile reader and the two tile rows it read last.
struct Open {
    tile: usize,
    reader: Box<dyn RowSource>,
    rows: [(Option<u32>, Vec<f32>); 2],
    used: u64,
}

impl Mosaic {
    pub(super) fn new(layout: Layout, opts: &LoadOptions) -> Self {
        Self {
            layout,
            opts: opts.clone(),
            open: Vec::new(),
            clock: 0,
            refuse: false,
            east: Vec::new(),
        }
    }

    /// Reads every row once: whether any sample has no data (no tile's data and no fill height).
    pub(super) fn has_no_data(&mut self) -> Result<bool> {
        let (w, h) = (self.layout.grid.width, self.layout.grid.height);
        let mut band = vec![0.0f32; w as usize * BAND_ROWS.min(h) as usize];
        let mut y0 = 0;
        while y0 < h {
            let rows = BAND_ROWS.min(h - y0) as usize;
            let band = &mut band[..rows * w as usize];
            self.read_rows(y0, band)?;
            if band.iter().any(|v| v.is_nan()) {
                return Ok(true);
            }
            y0 += BAND_ROWS;
        }
        Ok(false)
    }

    /// From now on a sample with no data is an error (the tiles changed since [`Mosaic::has_no_data`]).
    pub(super) fn refuse_no_data(&mut self) {
        self.refuse = true;
    }

    /// The slot of tile `tile`'s reader, opened (closing the least recently used) where it is not.
    fn reader(&mut self, tile: usize) -> Result<usize> {
        self.clock += 1;
        if let Some(i) = self.open.iter().position(|o| o.tile == tile) {
            self.open[i].used = self.clock;
            return Ok(i);
        }
        let meta = &self.layout.tiles[tile].meta;
        let reader: Box<dyn RowSource> = if meta.hgt {
            Box::new(HgtRows::open(&meta.path, meta.size.0, self.opts.nodata)?)
        } else {
            let opts = LoadOptions {
                spacing: Some(1.0),
                ..self.opts.clone()
            };
            crate::source::tiff::open_tile_rows(&meta.path, &opts)?
        };
        if (reader.width(), reader.height()) != meta.size {
            return Err(Error::format(
                &meta.path,
                format!(
                    "the tile is {} x {} samples now, {} x {} when the mosaic was opened",
                    reader.width(),
                    reader.height(),
                    meta.size.0,
                    meta.size.1
                ),
            ));
        }
        let open = Open {
            tile,
            reader,
            rows: [(None, Vec::new()), (None, Vec::new())],
            used: self.clock,
        };
        if self.open.len() < MAX_OPEN_TILES {
            self.open.push(open);
            return Ok(self.open.len() - 1);
        }
        let lru = (0..self.open.len())
            .min_by_key(|&i| self.open[i].used)
            .unwrap_or(0);
        self.open[lru] = open;
        Ok(lru)
    }

    /// Writes tile `t`'s samples into the no-data samples (NaN) of `out`, whole rows from `y0`.
    fn fill_from(&mut self, t: usize, y0: u32, out: &mut [f32]) -> Result<()> {
        let w = self.layout.grid.width as usize;
        let rows = u32::try_from(out.len() / w).unwrap_or(u32::MAX);
        let p = &self.layout.tiles[t];
        let (first, last) = (y0.max(p.row0), (y0 + rows - 1).min(p.row1));
        if first > last {
            return Ok(());
        }
        let p = p.clone();
        let slot = self.reader(t)?;
        let open = &mut self.open[slot];
        let (tw, th) = p.meta.size;
        // The east sample column of a tile coarser E-W than the grid lies inside the grid's last step
        // before the next tile (`join_seams`).
        let mut east = (p.k.0 > 1.0 + GRID_TOLERANCE).then(|| vec![f32::NAN; rows as usize]);
        for y in first..=last {
            let row = &mut out[(y - y0) as usize * w..(y - y0 + 1) as usize * w];
            let cols = &mut row[p.col0 as usize..=p.col1 as usize];
            let (r0, fr) = split(f64::from(y - p.row0) / p.k.1, th);
            let a = open.row(r0, None)?;
            if p.k == (1.0, 1.0) {
                let src = &open.rows[a].1;
                for (dst, &v) in cols.iter_mut().zip(src) {
                    if dst.is_nan() {
                        *dst = v;
                    }
                }
                continue;
            }
            let b = if fr > 0.0 {
                Some(open.row(r0 + 1, Some(r0))?)
            } else {
                None
            };
            let top = &open.rows[a].1;
            let bottom = b.map(|b| open.rows[b].1.as_slice());
            if let Some(east) = east.as_mut() {
                east[(y - y0) as usize] = bilinear(top, bottom, (tw - 1) as usize, 0.0, fr);
            }
            for (x, dst) in cols.iter_mut().enumerate() {
                if !dst.is_nan() {
                    continue;
                }
                #[expect(clippy::cast_precision_loss, reason = "a column below 2^32")]
                let (c0, fc) = split(x as f64 / p.k.0, tw);
                *dst = bilinear(top, bottom, c0 as usize, fc, fr);
            }
        }
        if let Some(east) = east {
            self.east.push((t, east));
        }
        Ok(())
    }

    /// Fills the seams east of tiles coarser E-W than the grid that do not share their east column with
    /// the next tile (Copernicus DEM tiles of 2400 columns a degree beside ones of 3600, each starting on
    /// its degree line): the grid's columns between such a tile's east sample and the next tile's first
    /// one, linear between the two, where no tile's box reaches ([`seam`]: with no next sample, the
    /// tile's east sample within its pixel). Without it they were no data, a column of `fill_height` (a
    /// trench of 0 m along every tile's east edge) or of filled voids.
    fn join_seams(&mut self, y0: u32, out: &mut [f32]) {
        let w = self.layout.grid.width as usize;
        let rows = u32::try_from(out.len() / w).unwrap_or(u32::MAX);
        let east = std::mem::take(&mut self.east);
        for (t, east) in &east {
            let p = &self.layout.tiles[*t];
            let last = f64::from(p.col0) + f64::from(p.meta.size.0 - 1) * p.k.0;
            let (cn, end) = past(last, p.k.0, self.layout.grid.width);
            let cols = (p.col1.saturating_add(1), to_u32(end));
            let boxes = self.others(*t, cols, (y0, y0.saturating_add(rows)));
            for ((row, &e), y) in out.chunks_exact_mut(w).zip(east).zip(y0..) {
                let right = cn.map_or(f32::NAN, |cn| row[cn]);
                let gap = row.iter_mut().enumerate().take(end).skip(p.col1 as usize + 1);
                for (c, v) in gap.filter(|(c, v)| v.is_nan() && !inside(&boxes, to_u32(*c), y)) {
                    #[expect(clippy::cast_precision_loss, reason = "a column below 2^32")]
                    let f = (c as f64 - last) / p.k.0;
                    *v = seam(e, right, f);
                }
            }
        }
        self.east = east;
        self.east.clear();
    }

    /// As [`Mosaic::join_seams`] down the columns: fills the rows south of tiles coarser N-S than the
    /// grid that share no edge row with the tile below (a Copernicus GLO-90 tile, 1200 rows a degree,
    /// among GLO-30 ones of 3600), linear between the tile's south row and the grid's row where its next
    /// one would lie (read for it), and the few samples past both its east and south samples linear
    /// along their row between the samples either side.
    fn join_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        let (w, h) = (self.layout.grid.width as usize, self.layout.grid.height);
        let band_end = y0.saturating_add(u32::try_from(out.len() / w).unwrap_or(u32::MAX));
        for t in 0..self.layout.tiles.len() {
            let p = &self.layout.tiles[t];
            if p.k.1 <= 1.0 + GRID_TOLERANCE {
                continue;
            }
            let last = f64::from(p.row0) + f64::from(p.meta.size.1 - 1) * p.k.1;
            let (rn, end) = past(last, p.k.1, h);
            let (first, end) = (y0.max(p.row1.saturating_add(1)), band_end.min(to_u32(end)));
            if first >= end {
                continue;
            }
            let p = p.clone();
            let (tw, th) = p.meta.size;
            let lastc = f64::from(p.col0) + f64::from(tw - 1) * p.k.0;
            let (cn, cend) = past(lastc, p.k.0, self.layout.grid.width);
            let boxes = self.others(t, (p.col0, to_u32(cend)), (first, end));
            let slot = self.reader(t)?;
            let i = self.open[slot].row(th - 1, None)?;
            let south = self.open[slot].rows[i].1.clone();
            let mut below = vec![f32::NAN; w];
            if let Some(rn) = rn {
                self.raw_row(to_u32(rn), &mut below)?;
            }
            for y in first..end {
                let f = (f64::from(y) - last) / p.k.1;
                let row = &mut out[(y - y0) as usize * w..][..w];
                let free = |c: usize, v: f32| v.is_nan() && !inside(&boxes, to_u32(c), y);
                for (x, c) in (p.col0 as usize..=p.col1 as usize).enumerate() {
                    if free(c, row[c]) {
                        #[expect(clippy::cast_precision_loss, reason = "a column below 2^32")]
                        let (c0, fc) = split(x as f64 / p.k.0, tw);
                        let top = bilinear(&south, None, c0 as usize, fc, 0.0);
                        row[c] = seam(top, below[c], f);
                    }
                }
                // The corner past both: along the row, between the tile's last column and the next
                // sample east.
                let left = row[p.col1 as usize];
                let right = cn.map_or(f32::NAN, |cn| row[cn]);
                #[expect(clippy::cast_precision_loss, reason = "a column below 2^32")]
                let span = cn.map_or(1.0, |cn| (cn - p.col1 as usize) as f64);
                let corner = row.iter_mut().enumerate().take(cend).skip(p.col1 as usize + 1);
                for (c, v) in corner.filter(|(c, v)| free(*c, **v)) {
                    #[expect(clippy::cast_precision_loss, reason = "a column below 2^32")]
                    let (fc, fe) = ((c - p.col1 as usize) as f64 / span, (c as f64 - lastc) / p.k.0);
                    *v = if right.is_nan() {
                        seam(left, right, fe)
                    } else {
                        seam(left, right, fc)
                    };
                }
            }
        }
        Ok(())
    }

    /// The boxes (first and last column, first and last row) of the tiles other than `t` that reach
    /// into columns `cols` and rows `rows` (half-open): a sample inside one is that tile's, a void of it
    /// where it has no data, not a seam.
    fn others(&self, t: usize, cols: (u32, u32), rows: (u32, u32)) -> Vec<[u32; 4]> {
        let tiles = self.layout.tiles.iter().enumerate();
        tiles
            .filter(|(i, o)| {
                *i != t && o.col0 < cols.1 && o.col1 >= cols.0 && o.row0 < rows.1 && o.row1 >= rows.0
            })
            .map(|(_, o)| [o.col0, o.col1, o.row0, o.row1])
            .collect()
    }

    /// Grid row `y` as the tiles and the E-W seams give it (no N-S seam, no fill height): the row below
    /// a seam, read for it.
    fn raw_row(&mut self, y: u32, row: &mut [f32]) -> Result<()> {
        row.fill(f32::NAN);
        self.east.clear();
        for t in 0..self.layout.tiles.len() {
            self.fill_from(t, y, row)?;
        }
        self.join_seams(y, row);
        Ok(())
    }
}

/// Whether grid sample (`c`, `y`) lies in one of `boxes` ([`Mosaic::others`]).
fn inside(boxes: &[[u32; 4]], c: u32, y: u32) -> bool {
    boxes
        .iter()
        .any(|b| (b[0]..=b[1]).contains(&c) && (b[2]..=b[3]).contains(&y))
}

/// `v` as a grid index, which is below 2^32.
fn to_u32(v: usize) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

/// A seam's sample `f` of the way from a tile's edge sample `a` to the next sample `b`: linear between
/// them; with no next sample (NaN: the mosaic's edge, a missing tile, a void), `a` inside its pixel
/// (half its step past it), else no data.
fn seam(a: f32, b: f32, f: f64) -> f32 {
    if !b.is_nan() {
        return crate::source::to_f32(f64::from(a) * (1.0 - f) + f64::from(b) * f);
    }
    if f <= 0.5 + GRID_TOLERANCE {
        a
    } else {
        f32::NAN
    }
}

/// Where the sample after a coarse tile's last one (at grid position `last`, `k` grid steps a tile
/// step) would lie on an axis of `n` grid points: its grid index, where it lies on one inside the grid
/// (the next tile's first sample, where tiles abut), and the end (exclusive) of the grid points before
/// it.
fn past(last: f64, k: f64, n: u32) -> (Option<usize>, usize) {
    let next = last + k;
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a non-negative grid position, at most the grid's size"
    )]
    let at = |v: f64| (v as usize).min(n as usize);
    let on = (next - next.round()).abs() <= GRID_TOLERANCE && next.round() < f64::from(n);
    if on {
        (Some(at(next.round())), at(next.round()))
    } else {
        (None, at((next - GRID_TOLERANCE).ceil()))
    }
}

/// `t` split into a whole tile step below `n - 1` and the fraction past it.
fn split(t: f64, n: u32) -> (u32, f64) {
    let last = n - 1;
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a non-negative position inside the tile"
    )]
    let i = (t.floor() as u32).min(last);
    let f = t - f64::from(i);
    // A position on the last sample (within rounding) is that sample.
    if i == last || f < 1e-9 {
        (i, 0.0)
    } else {
        (i, f)
    }
}

/// The bilinear sample at column `c + fc` between row `top` and row `bottom` (weight `fr`); no data (NaN)
/// where a sample it weighs is.
fn bilinear(top: &[f32], bottom: Option<&[f32]>, c: usize, fc: f64, fr: f64) -> f32 {
    let row = |r: &[f32]| -> f64 {
        let a = f64::from(r[c]);
        if fc > 0.0 {
            a * (1.0 - fc) + f64::from(r[c + 1]) * fc
        } else {
            a
        }
    };
    let v = match bottom {
        Some(b) if fr > 0.0 => row(top) * (1.0 - fr) + row(b) * fr,
        _ => row(top),
    };
    crate::source::to_f32(v)
}

impl Open {
    /// The slot of tile row `r`, read where neither slot holds it, into the slot not holding `keep`.
    fn row(&mut self, r: u32, keep: Option<u32>) -> Result<usize> {
        if let Some(i) = self.rows.iter().position(|(at, _)| *at == Some(r)) {
            return Ok(i);
        }
        let i = usize::from(self.rows[0].0.is_some() && self.rows[0].0 == keep);
        let w = self.reader.width() as usize;
        let (at, buf) = &mut self.rows[i];
        buf.resize(w, 0.0);
        *at = None;
        self.reader.read_rows(r, buf)?;
        *at = Some(r);
        Ok(i)
    }
}

impl RowSource for Mosaic {
    fn grid(&self) -> &RowGrid {
        &self.layout.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        if out.is_empty() {
            return Ok(());
        }
        out.fill(f32::NAN);
        self.east.clear();
        for t in 0..self.layout.tiles.len() {
            self.fill_from(t, y0, out)?;
        }
        self.join_seams(y0, out);
        self.join_rows(y0, out)?;
        let w = self.layout.grid.width as usize;
        // Bands come top to bottom: a tile above the next band is closed (opened again if asked).
        let next = u64::from(y0) + (out.len() / w) as u64;
        let tiles = &self.layout.tiles;
        self.open.retain(|o| u64::from(tiles[o.tile].row1) >= next);
        if let Some(fill) = self.opts.fill_height {
            out.iter_mut().filter(|v| v.is_nan()).for_each(|v| *v = fill);
        } else if self.refuse {
            if let Some(i) = out.iter().position(|v| v.is_nan()) {
                return Err(Error::format(
                    &self.layout.grid.path,
                    format!(
                        "no data at sample ({}, {}): a tile changed since the mosaic was opened",
                        i % w,
                        y0 as usize + i / w
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// An SRTM `.hgt` tile read by positioned reads, its voids (and [`LoadOptions::nodata`]) NaN.
struct HgtRows {
    file: std::fs::File,
    grid: RowGrid,
    nodata: Option<f64>,
    bytes: Vec<u8>,
}

impl HgtRows {
    fn open(path: &Path, side: u32, nodata: Option<f64>) -> Result<Self> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open tile", e))?;
        Ok(Self {
            file,
            grid: RowGrid {
                width: side,
                height: side,
                spacing: 1.0,
                ew_spacing: 1.0,
                origin: (0.0, 0.0),
                path: path.into(),
            },
            nodata,
            bytes: Vec::new(),
        })
    }
}

impl RowSource for HgtRows {
    fn grid(&self) -> &RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        self.bytes.resize(out.len() * 2, 0);
        let at = u64::from(y0) * u64::from(self.grid.width) * 2;
        read_exact_at(&mut self.file, &self.grid.path, at, &mut self.bytes)?;
        for (dst, c) in out.iter_mut().zip(self.bytes.chunks_exact(2)) {
            *dst = match i16::from_be_bytes([c[0], c[1]]) {
                HGT_VOID => f32::NAN,
                v if is_nodata(self.nodata, f64::from(v)) => f32::NAN,
                v => f32::from(v),
            };
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_split_into_steps() {
        assert_eq!(split(2.0, 5), (2, 0.0));
        assert_eq!(split(2.5, 5), (2, 0.5));
        assert_eq!(split(4.0, 5), (4, 0.0));
        assert_eq!(bilinear(&[0.0, 4.0], Some(&[8.0, 12.0]), 0, 0.5, 0.5), 6.0);
        assert!(bilinear(&[f32::NAN, 4.0], None, 0, 0.25, 0.0).is_nan());
    }
}
