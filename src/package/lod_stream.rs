//! Stage 1, bake: a package's SAT LOD tables baked out of core, straight into the LOD cache
//! file ([`crate::bake`], format 5), without decoding the whole pyramid.
//!
//! The tables are those of [`crate::bake::lod_tables::LevelTables::build_level`] (data level k at level k's resolution: the closed
//! cells' maximum error, its max pyramid, and the SAT of the half-open cells' quantised (e/E)^p), and the
//! file is byte for byte the one [`crate::bake`] writes from a resident pyramid, so every answer and every
//! frame hash is unchanged. What changes is how they are computed:
//!
//! - the package is read one band of level-0 tile rows at a time through a [`TileCache`] sized by the
//!   terrain's width (the band's tiles, the coarser tiles their prediction reads, and the level-k rows
//!   the band's errors read), and its mapped pages are dropped every 16 MiB of it read (estimated);
//! - two sweeps over the bands: the first finds every level's E (and refuses a non-finite error, naming
//!   its sample); the second computes each sample's error once more for every level, folds it into the
//!   closed cells' maxima and the half-open cells' sums of the current cell row, and writes each finished
//!   row where it lies in the file (the layout is known once every E is): a SAT row is the previous SAT
//!   row plus the row's running sum, and each max-pyramid row is written as soon as its two finer rows are;
//! - within a band, every level's rows are shared among the cores in runs of rows (a row's errors,
//!   closed cells' maxima and half-open cells' sums read only the band), then each level folds its rows
//!   in order (its state is its own), on a thread of its own while the next band is loaded and its rows
//!   worked (`bands`);
//! - last, the CRC-32 trailer over the file read back in chunks, and the rename into place.
//!
//! Memory: O(width) per level (a few rows, and a band's rows of cells), plus the tile cache, one band of
//! level-0 heights and at most about 16 MiB of the package's mapped pages; nothing grows with the
//! terrain's height, and nothing terrain-sized is held.

use std::fs::File;
use std::path::Path;


use crate::bake::lod_record::Coder;
use crate::bake::lod_tables::{bad_error, closed_count, RangeMax};
use crate::bake::sat::Sat;
use crate::bake::BakeParams;
use crate::package::lod_tiles::RecordRows;
use crate::package::read::TileDecoder;
use crate::package::{CacheSplit, Package, TileCache};
use crate::progress::{Meter, Progress};
use crate::{Error, Result};

mod bands;
mod file;
mod rows;
use file::write_at;
pub(super) use file::{lay_out_file, write_tables};
use rows::{RowOut, RowView};

/// The package's bytes (an estimate: its size over the bands) the sweeps read between two drops of its
/// mapped pages ([`Package::trim`]).
const TRIM_BYTES: u64 = 16 << 20;

/// One data level's streaming state (k >= 1).
pub(super) struct Level {
    /// Data level and its shifts: `s` for cells (k capped at 30), `ke` for the error (k capped at 40).
    pub(super) k: u32,
    s: u32,
    ke: u32,
    /// Values per level-k row buffer: level-k samples 0 ..= ((width - 1) >> ke) + 1.
    row_len: usize,
    /// E, and the first non-finite error met (sweep 1).
    pub(super) e_max: f32,
    bad: Option<(u32, u32, f32)>,
    /// Sweep 2 only (tables present): closed cells per row and rows, half-open cells per row.
    pub(super) cw: u32,
    pub(super) ch: u32,
    pub(super) sw: u32,
    /// The current closed cell row and its maxima so far.
    pub(super) cur: u32,
    pub(super) acc: Vec<f32>,
    /// The current half-open cell row's sums, and the last SAT row written.
    sums: Vec<u64>,
    sat_row: Vec<u64>,
    /// Max pyramid: level sizes, byte offsets, and each coarser level's pending row.
    dims: Vec<(u32, u32)>,
    max_off: Vec<u64>,
    pend: Vec<Vec<f32>>,
    sat_off: u64,
    /// The SFAMF exponent, quantum bits and 1 / E.
    p: u32,
    q: u32,
    inv: f64,
    /// Little-endian bytes of a row being written.
    bytes: Vec<u8>,
    /// The level's record coder, and its codes of the current rows ([`crate::bake::lod_record`]).
    pub(super) coder: Option<Coder>,
    max_codes: Vec<u8>,
    mean_codes: Vec<u8>,
    /// The last closed row's decoded maxima and its index.
    pub(super) dmax: Vec<f32>,
    dmax_row: Option<u32>,
    /// A finished half-open row's sums waiting for its closed row, its index, and its decoded sums.
    held: Vec<u64>,
    pending: Option<u32>,
    pub(super) lower: Vec<u64>,
    /// The records' tiles, when the bake writes them ([`bake_records`]).
    pub(super) records: Option<RecordRows>,
}

impl Level {
    pub(super) fn new(k: u32, width: u32, p: u32) -> Self {
        let ke = k.min(40);
        Self {
            k,
            s: k.min(30),
            ke,
            row_len: ((width - 1) >> ke) as usize + 2,
            e_max: 0.0,
            bad: None,
            cw: 0,
            ch: 0,
            sw: 0,
            cur: 0,
            acc: Vec::new(),
            sums: Vec::new(),
            sat_row: Vec::new(),
            dims: Vec::new(),
            max_off: Vec::new(),
            pend: Vec::new(),
            sat_off: 0,
            p,
            q: 0,
            inv: 0.0,
            bytes: Vec::new(),
            coder: None,
            max_codes: Vec::new(),
            mean_codes: Vec::new(),
            dmax: Vec::new(),
            dmax_row: None,
            held: Vec::new(),
            pending: None,
            lower: Vec::new(),
            records: None,
        }
    }

    /// Whether sweep 2 builds tables for this level (E > 0).
    pub(super) fn has_tables(&self) -> bool {
        self.e_max > 0.0
    }

    /// Sizes the sweep-2 state once E is known, with the level's offsets in the file from `at` (the
    /// byte just past its has-tables flag); returns the byte past its tables.
    pub(super) fn lay_out(&mut self, width: u32, height: u32, at: u64) -> u64 {
        let s = self.s;
        (self.cw, self.ch) = (closed_count(width, s), closed_count(height, s));
        self.sw = width.div_ceil(1 << s);
        let sh = height.div_ceil(1 << s);
        self.q = Sat::max_frac_bits(u64::from(width) * u64::from(height));
        self.inv = 1.0 / f64::from(self.e_max);
        self.acc = vec![0.0; self.cw as usize];
        self.sums = vec![0; self.sw as usize];
        self.sat_row = vec![0; self.sw as usize];
        self.coder = Some(Coder::new(self.e_max, self.p, self.q, s, width, height));
        self.max_codes = vec![0; self.cw as usize];
        self.dmax = vec![0.0; self.cw as usize];
        self.mean_codes = vec![0; self.sw as usize];
        self.held = vec![0; self.sw as usize];
        self.lower = vec![0; self.sw as usize];
        let mut at = at.next_multiple_of(8);
        self.sat_off = at;
        at += u64::from(self.sw) * u64::from(sh) * 8;
        self.dims = RangeMax::dims(self.cw, self.ch);
        for &(w, h) in &self.dims {
            self.max_off.push(at);
            at += u64::from(w) * u64::from(h) * 4;
            self.pend.push(vec![0.0; w as usize]);
        }
        at
    }

    /// What the rows' work reads of the level but its band: its shifts, cells and constants (fixed for a
    /// sweep), the band left empty.
    fn shape(&self) -> RowView<'static> {
        RowView {
            band: &[],
            j0: 0,
            row_len: self.row_len,
            ke: self.ke,
            s: self.s,
            cw: self.cw,
            sw: self.sw,
            p: self.p,
            q: self.q,
            inv: self.inv,
        }
    }

    /// Sweep 1 over the band's rows (from its first): E and the first bad error, in row order.
    fn sweep_max(&mut self, outs: &[RowOut]) {
        for o in outs {
            if self.bad.is_some() {
                return;
            }
            if o.bad.is_some() {
                self.bad = o.bad;
                return;
            }
            // Errors are finite and >= +0 (an absolute value), so the maximum is the same in any order.
            self.e_max = self.e_max.max(o.e_max);
        }
    }

    /// Sweep 2 over one data row (`height` rows in all) from its cells' maxima and sums (`out`): finished
    /// rows written.
    fn sweep_tables(
        &mut self,
        file: Option<&File>,
        out: &RowOut,
        y: u32,
        height: u32,
    ) -> std::io::Result<()> {
        let (s, mask) = (self.s, (1u32 << self.s) - 1);
        // Wrapping sums: the row's partial sums added at once are the same as sample by sample.
        for (sum, &v) in self.sums.iter_mut().zip(&out.sums) {
            *sum = sum.wrapping_add(v);
        }
        let rowmax = &out.rowmax;
        // Closed cell row `cur` covers rows cur 2^s ..= (cur + 1) 2^s: a row on the lattice ends it.
        if y >> s == self.cur + 1 {
            fold_max(&mut self.acc, rowmax);
            self.close_row(file)?;
            self.cur += 1;
            self.acc.copy_from_slice(rowmax);
        } else if y == 0 {
            self.acc.copy_from_slice(rowmax);
        } else {
            fold_max(&mut self.acc, rowmax);
        }
        if y + 1 == height && self.cur < self.ch {
            self.close_row(file)?;
        }
        // Half-open cell row y >> s ends on its last row or the grid's; it is coded against the decoded
        // maxima of the closed row that contains it, which ends one data row later (or has ended).
        if (y + 1) & mask == 0 || y + 1 == height {
            std::mem::swap(&mut self.held, &mut self.sums);
            self.sums.fill(0);
            self.pending = Some(y >> s);
            self.flush_mean(file)?;
        }
        Ok(())
    }

    /// Codes closed cell row `cur` (in `acc`: its maxima rounded up to their codes' values, kept as the
    /// reference of the half-open row it contains), writes its max-pyramid rows, and codes the pending
    /// half-open row if it was waiting for it.
    fn close_row(&mut self, file: Option<&File>) -> std::io::Result<()> {
        let coder = self.coder.expect("laid out");
        coder.code_max_row(&mut self.acc, &mut self.max_codes);
        if let Some(rec) = &mut self.records {
            rec.push_max(&self.max_codes);
        }
        self.emit_closed(file)?;
        self.flush_mean(file)
    }

    /// Keeps closed row `cur`'s decoded maxima (in `acc`) as the reference of its half-open row and
    /// writes its max-pyramid rows (with a file).
    pub(super) fn emit_closed(&mut self, file: Option<&File>) -> std::io::Result<()> {
        self.dmax.copy_from_slice(&self.acc);
        self.dmax_row = Some(self.cur);
        match file {
            Some(f) => self.emit_max(f),
            None => Ok(()),
        }
    }

    /// Codes the pending half-open row once its closed row's decoded maxima are known, and writes the
    /// SAT row of its decoded lower sums (the previous SAT row plus the row's running sum).
    fn flush_mean(&mut self, file: Option<&File>) -> std::io::Result<()> {
        let Some(r) = self.pending else {
            return Ok(());
        };
        if self.dmax_row != Some(r.min(self.ch - 1)) {
            return Ok(());
        }
        let coder = self.coder.expect("laid out");
        coder.code_mean_row(
            r,
            &self.held,
            &self.dmax,
            &mut self.mean_codes,
            &mut self.lower,
        );
        self.pending = None;
        if let Some(rec) = &mut self.records {
            rec.push_mean(r, &self.mean_codes)?;
        }
        match file {
            Some(f) => self.write_sat_row(f, r),
            None => Ok(()),
        }
    }

    /// Writes half-open row `r`'s SAT row from its decoded lower sums (`lower`): the previous SAT row
    /// plus the row's running sum.
    pub(super) fn write_sat_row(&mut self, file: &File, r: u32) -> std::io::Result<()> {
        let mut run = 0u64;
        for (sat, low) in self.sat_row.iter_mut().zip(&self.lower) {
            run = run.wrapping_add(*low);
            *sat = sat.wrapping_add(run);
        }
        let off = self.sat_off + u64::from(r) * u64::from(self.sw) * 8;
        self.bytes.clear();
        self.bytes
            .extend(self.sat_row.iter().flat_map(|v| v.to_le_bytes()));
        write_at(file, off, &self.bytes)
    }

    /// Writes closed cell row `cur` (in `acc`) as max-pyramid level 0's row, and every coarser row it
    /// finishes (level j + 1's row r / 2 is the 2 x 2 maxima of level j's rows r - 1 and r, in
    /// [`RangeMax::build`]'s order).
    fn emit_max(&mut self, file: &File) -> std::io::Result<()> {
        let mut row = std::mem::take(&mut self.acc);
        let (mut j, mut r) = (0usize, self.cur);
        let result = loop {
            let (w, h) = self.dims[j];
            self.bytes.clear();
            self.bytes.extend(row.iter().flat_map(|v| v.to_le_bytes()));
            let off = self.max_off[j] + u64::from(r) * u64::from(w) * 4;
            if let Err(e) = write_at(file, off, &self.bytes) {
                break Err(e);
            }
            if j + 1 == self.dims.len() {
                break Ok(());
            }
            let pend = &mut self.pend[j + 1];
            for (x, p) in pend.iter_mut().enumerate() {
                let mut m = if r % 2 == 0 { 0.0f32 } else { *p };
                m = m.max(row[2 * x]);
                if let Some(&v) = row.get(2 * x + 1) {
                    m = m.max(v);
                }
                *p = m;
            }
            if r % 2 == 0 && r + 1 < h {
                break Ok(());
            }
            // Level j + 1's row r / 2 is done: write it next (its buffer swapped in, level j's kept).
            let done = std::mem::take(&mut self.pend[j + 1]);
            if j == 0 {
                self.acc = row;
            } else {
                self.pend[j] = row;
            }
            row = done;
            j += 1;
            r /= 2;
        };
        // Put the last buffer written back where it belongs.
        if j == 0 {
            self.acc = row;
        } else {
            self.pend[j] = row;
        }
        result
    }
}

fn fold_max(acc: &mut [f32], row: &[f32]) {
    for (a, &v) in acc.iter_mut().zip(row) {
        *a = a.max(v);
    }
}

/// The two sweeps' state over a package: its band cache and decoders, and the levels.
pub(super) struct Sweep<'p> {
    pub(super) cache: TileCache,
    /// One tile decoder per thread, for the bands' tiles.
    decoders: Vec<TileDecoder>,
    pub(super) levels: Vec<Level>,
    pub(super) meter: Meter<'p>,
    pub(super) width: u32,
    pub(super) height: u32,
    bands: u32,
    last: u32,
    /// The package's bytes a band reads on average, and those read since its pages were last dropped.
    band_bytes: u64,
    untrimmed: u64,
}

impl<'p> Sweep<'p> {
    /// A sweep of data levels `ks` over `package` (exponent `p`), with a progress bar of two passes.
    pub(super) fn new(
        package: &Package,
        p: u32,
        ks: std::ops::Range<u32>,
        progress: Progress<'p>,
    ) -> Result<Self> {
        let header = package.header().clone();
        let (width, height) = (header.width, header.height);
        let last = u32::try_from(header.levels.len() - 1).expect("levels fit u32");
        // A cache of its own over the same file: every tile a band reads, pinned for the band.
        let reopened = Package::open(package.path())?;
        if reopened.header() != &header {
            return Err(Error::format(
                package.path(),
                "the package changed while its LOD tables were baked",
            ));
        }
        let decoders = (0..super::threads())
            .map(|_| reopened.tile_decoder().map(TileDecoder::sweeping))
            .collect::<Result<Vec<_>>>()?;
        let per_row: u64 = header.levels.iter().map(|l| u64::from(l.tiles_x)).sum();
        let slots = 4 * per_row + crate::package::cache::MIN_SLOTS * u64::from(last + 1);
        let cache = TileCache::new(
            reopened,
            CacheSplit::budget_for_slots(&header, slots),
            "the LOD tables' bake",
        )?;
        let bands = height.div_ceil(header.tile);
        Ok(Self {
            cache,
            decoders,
            levels: ks.map(|k| Level::new(k, width, p)).collect(),
            meter: progress.task("baking LOD tables, bands", 2 * u64::from(bands)),
            width,
            height,
            bands,
            last,
            band_bytes: package.file_bytes().div_ceil(u64::from(bands.max(1))),
            untrimmed: 0,
        })
    }

    /// Sweep 1: every level's E; the first non-finite error is an [`Error::Terrain`] naming its sample.
    pub(super) fn sweep_e(&mut self) -> Result<()> {
        let what = self.cache.package().path().to_path_buf();
        self.sweep_bands(
            |_| true,
            |v: &RowView<'_>, h0: &[f32], y, errs: &mut Vec<f32>, out: &mut RowOut| v.row_max(h0, y, errs, out),
            |lv, outs, _| {
                lv.sweep_max(outs);
                Ok(())
            },
            |e| Error::io(&what, "cannot bake", e),
        )?;
        if let Some((x, y, e)) = self.levels.iter().find_map(|l| l.bad) {
            return Err(bad_error(x as usize, y as usize, e));
        }
        Ok(())
    }

    /// Sweep 2 over the levels with tables, each data row handed to [`Level::sweep_tables`] with `file`.
    pub(super) fn sweep_tables(&mut self, file: Option<&File>, what: &Path) -> Result<()> {
        let height = self.height;
        self.sweep_bands(
            Level::has_tables,
            |v: &RowView<'_>, h0: &[f32], y, errs: &mut Vec<f32>, out: &mut RowOut| v.row_cells(h0, y, errs, out),
            |lv, outs, y0| {
                (y0..)
                    .zip(outs)
                    .try_for_each(|(y, out)| lv.sweep_tables(file, out, y, height))
            },
            |e| Error::io(what, "cannot write", e),
        )
    }

}

/// Bakes `package`'s LOD tables for `params` into the cache file `path` under `key` (written to a
/// temporary name and renamed, as every cache file), reporting to `progress`.
///
/// Errors: the package's I/O and damaged tiles (naming the tile), a non-finite error (naming its sample,
/// as [`LevelTables::build_level`]), and the file's writes.
///
/// [`LevelTables::build_level`]: crate::bake::lod_tables::LevelTables::build_level
pub(crate) fn bake_to_file(
    package: &Package,
    params: &BakeParams,
    key: u64,
    path: &Path,
    progress: Progress<'_>,
) -> Result<()> {
    let n = params.data_levels();
    let mut sw = Sweep::new(package, params.p, 1..n, progress)?;
    sw.sweep_e()?;
    let layout = lay_out_file(&mut sw.levels, params.p, sw.width, sw.height, key);
    let guard = crate::temp::TempFile::create(path.with_extension(format!("tmp{}", crate::temp_suffix())))?;
    let tmp = guard.path.clone();
    // Sweep 2: the tables, each finished row written in place.
    let written = write_tables(&tmp, &layout, |file| {
        sw.sweep_tables(Some(file), &tmp)
    });
    sw.meter.finish();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    guard.persist(path)
}

