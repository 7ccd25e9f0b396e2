//! Stage 1b, the package: the bake's coding of the spilled pyramid, coarse to fine, out of core
//! (`docs/package-codec.md`, "The bake").
//!
//! Per level, two passes over its spilled rows, a tile row at a time: the first fits the level's
//! prediction weights ([`super::predict::Fit`]) on the source values, the second quantises every tile in
//! closed loop ([`super::codec::quantise`]), writes the reconstructed rows to a temporary file (what the
//! next finer level is predicted from, exactly as the decoder will have it), the tiles' symbols to
//! another, and counts the symbols' tokens per context. Once every level is done the rANS tables are
//! known, and a third pass codes the stored symbols tile by tile. The working set is a tile row of a
//! level and of its coarser level; the temporary files are removed when dropped.

use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use super::codec::{self, Encoder, Predictor, TileScratch, U_BORDER, U_BORDER_U32};
use super::format::{CodecKind, Header};
use super::predict::{Fit, LevelModel, R_TAPS, TAPS, U_TAPS};
use super::rans::{Counts, Tables};
use super::spill::{Spilled, TempFile};
use crate::{Error, Param, Result};

/// Most samples of a level the weights are fitted on: past it, every n-th tile row (the fit converges
/// long before, and the bake's time stays linear in the samples with a small constant).
const FIT_SAMPLES: u64 = 1 << 22;

/// How the levels are quantised: the quantum (metres) and whether level 0 is on its lattice.
#[derive(Clone, Copy, Debug)]
pub(super) struct Quantiser {
    /// The quantum q, metres.
    pub(super) q: f64,
    /// Level 0's samples are integers over q (the source's own lattice).
    pub(super) lattice: bool,
}

impl Quantiser {
    /// Level `lk`'s target: its height over the quantum, rounded to the lattice at level 0 when on it.
    fn target(&self, lk: usize, h: f32) -> f64 {
        let t = f64::from(h) / self.q;
        if lk == 0 && self.lattice {
            t.round()
        } else {
            t
        }
    }
}

/// The coded pyramid: each level's model and symbol file, the token counts, the level-0 error.
pub(super) struct Coded {
    /// Models, finest first.
    pub(super) models: Vec<LevelModel>,
    /// Per level, finest first: the tiles' symbols, row-major tile order, each tile's symbols (i32,
    /// row-major) then their contexts (u8).
    syms: Vec<TempFile>,
    /// Token counts over every tile (for the rANS tables).
    pub(super) counts: Counts,
    /// Sum of squared level-0 errors, metres^2.
    pub(super) sq: f64,
    /// Largest level-0 error, metres.
    pub(super) worst: f64,
    /// Largest error of a coarser level against its filtered heights, metres.
    pub(super) worst_coarse: f64,
    /// Lowest and highest reconstructed level-0 value, quanta.
    lo_hi: (i32, i32),
    /// Level 0's reconstruction, kept to be removed with the rest ([`super::spill::Removing`]).
    _recon: Option<TempFile>,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, "cannot use a temporary file", e)
}

/// The coarser level's reconstructed rows under a tile row's stencils, and their first row.
struct CoarseRows {
    rows: Vec<i32>,
    first: i64,
    width: i64,
    height: i64,
    /// The last column and row U reads ([`Header::u_reach`]).
    reach: (i64, i64),
}

impl CoarseRows {
    fn at(&self, a: i64, b: i64) -> i64 {
        if self.width == 0 {
            return 0;
        }
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped into the level and the band read"
        )]
        let (x, y, w) = (
            a.clamp(0, self.reach.0) as usize,
            (b.clamp(0, self.reach.1) - self.first) as usize,
            self.width as usize,
        );
        i64::from(self.rows[y * w + x])
    }
}

/// Reads the rows of the reconstructed level in `file` (width `w`, height `h`) that the tile row at
/// `y0` of height `th` reads through its stencils.
fn coarse_rows(
    file: &mut TempFile,
    (w, h): (u32, u32),
    (y0, th): (u32, u32),
    out: &mut CoarseRows,
) -> Result<()> {
    let (_, cy0, _, cy1) = super::read::coarse_rect((0, y0), (2, th));
    let last = i64::from(h) - 1;
    let (a, b) = (cy0.clamp(0, last), (cy1 - 1).clamp(0, last));
    #[expect(
        clippy::cast_sign_loss,
        clippy::cast_possible_truncation,
        reason = "clamped into the level"
    )]
    let (a32, n) = (a as u64, (b - a + 1) as usize);
    out.rows.resize(n * w as usize, 0);
    file.file
        .seek(SeekFrom::Start(a32 * u64::from(w) * 4))
        .and_then(|_| {
            file.file
                .read_exact(bytemuck::cast_slice_mut(&mut out.rows))
        })
        .map_err(io(&file.path))?;
    out.first = a;
    out.width = i64::from(w);
    out.height = i64::from(h);
    out.reach = (i64::from(w) - 1, i64::from(h) - 1);
    Ok(())
}

/// U over the tile at (x0, y0), tw x th, and its border, into `u`; zero at the coarsest level.
fn u_tile(
    predictor: &mut Predictor,
    coarse: Option<&CoarseRows>,
    (x0, y0): (u32, u32),
    (tw, th): (usize, usize),
    u: &mut Vec<i64>,
) {
    let (uw, uh) = (tw + 2 * U_BORDER, th + 2 * U_BORDER);
    u.resize(uw * uh, 0);
    match coarse {
        None => u.fill(0),
        Some(c) => {
            let b = U_BORDER as i64;
            predictor.predict(
                |a, bb| c.at(a, bb),
                (i64::from(x0) - b, i64::from(y0) - b),
                (uw, uh),
                u,
            );
        }
    }
}

/// Adds a tile's open-loop samples to the fit: the features as [`codec`] computes them, from the
/// targets instead of the reconstruction. With a step over 1 the neighbours are the targets rounded to
/// the step's grid, so the weights are fitted to neighbours as noisy as the decoder's (fitted on exact
/// neighbours they amplify the quantisation noise: N57E011 at 2 m cost 0.074 B/sample, 0.057 this way).
/// Only the samples whose parity (x & 1) + 2 (y & 1) is set in `parities` are added.
fn fit_tile(
    fit: &mut Fit,
    u: &[i64],
    t: &[f64],
    step: u32,
    (tw, th): (usize, usize),
    parities: u8,
) {
    let s = f64::from(step.max(1));
    let near = |v: f64| if step > 1 { (v / s).round() * s } else { v };
    let uw = tw + 2 * U_BORDER;
    #[expect(clippy::cast_precision_loss, reason = "|U| <= 2^31 is exact in f64")]
    let uat = |i: i64, j: i64| -> f64 {
        #[expect(
            clippy::cast_sign_loss,
            clippy::cast_possible_truncation,
            reason = "inside the bordered tile"
        )]
        let at = (j + U_BORDER as i64) as usize * uw + (i + U_BORDER as i64) as usize;
        u[at] as f64
    };
    #[expect(clippy::cast_possible_wrap, reason = "tile sides are at most 4096")]
    let (tw64, th64) = (tw as i64, th as i64);
    for j in 0..th64 {
        if parities & (0b11 << (2 * (j & 1))) == 0 {
            continue;
        }
        for i in 0..tw64 {
            #[expect(
                clippy::cast_sign_loss,
                clippy::cast_possible_truncation,
                reason = "a parity"
            )]
            let par = ((i & 1) | ((j & 1) << 1)) as usize;
            if parities & (1 << par) == 0 {
                continue;
            }
            let r = |di: i32, dj: i32| -> f64 {
                let (ii, jj) = (i + i64::from(di), j + i64::from(dj));
                if ii < 0 || jj < 0 || ii >= tw64 || jj >= th64 {
                    return 0.0;
                }
                #[expect(
                    clippy::cast_sign_loss,
                    clippy::cast_possible_truncation,
                    reason = "inside the tile"
                )]
                let at = jj as usize * tw + ii as usize;
                near(t[at]) - uat(ii, jj)
            };
            let mut f = [0.0; TAPS];
            for (fk, &(dx, dy)) in f.iter_mut().zip(&R_TAPS) {
                *fk = r(dx, dy);
            }
            let u0 = uat(i, j);
            for (fk, &(dx, dy)) in f[R_TAPS.len()..].iter_mut().zip(&U_TAPS) {
                *fk = uat(i + i64::from(dx), j + i64::from(dy)) - u0;
            }
            #[expect(
                clippy::cast_sign_loss,
                clippy::cast_possible_truncation,
                reason = "inside the tile"
            )]
            let at = j as usize * tw + i as usize;
            fit.add(par, &f, t[at] - u0);
        }
    }
}

/// One thread's working set for the closed-loop pass: its predictor and scratch, made once per bake, and
/// the symbols, contexts and reconstruction of the tiles of a row it took, tile after tile.
struct Worker {
    /// Its place among the workers.
    id: usize,
    predictor: Predictor,
    scratch: TileScratch,
    u: Vec<i64>,
    tv: Vec<f64>,
    syms: Vec<i32>,
    ctxs: Vec<u8>,
    rec: Vec<i32>,
    counts: Counts,
    /// The reconstruction's errors against the source over the row's tiles it took.
    errors: RunErrors,
    /// Pass 1: the sums of the parities it fits.
    fit: Fit,
}

/// Tiles' errors against the source: the largest error (metres), and the lowest and highest
/// reconstructed value (quanta).
#[derive(Default)]
struct RunErrors {
    worst: f64,
    lo_hi: (i32, i32),
}

impl Worker {
    fn new(id: usize, tile: u32) -> Self {
        Self {
            id,
            predictor: Predictor::new(tile + 2 * U_BORDER_U32),
            scratch: TileScratch::new(tile),
            u: Vec::new(),
            tv: Vec::new(),
            syms: Vec::new(),
            ctxs: Vec::new(),
            rec: Vec::new(),
            counts: Counts::default(),
            errors: RunErrors::default(),
            fit: Fit::default(),
        }
    }
}

/// One tile row of a level: what every tile of it reads, in the fitting pass and in the closed loop.
struct RowInputs<'a> {
    header: &'a Header,
    lk: usize,
    y0: u32,
    th: usize,
    /// The row's source rows, the level's width each.
    band: &'a [f32],
    coarse: Option<&'a CoarseRows>,
    quant: Quantiser,
}

impl RowInputs<'_> {
    /// Tile `tx` of the row into the worker: its prediction U (`wk.u`) and its samples' targets (`wk.tv`);
    /// returns the tile's first column and width.
    fn tile(&self, wk: &mut Worker, tx: u32) -> (u32, usize) {
        let (lk, thu) = (self.lk, self.th);
        let w = self.header.levels[lk].width as usize;
        let (x0, _, tw, _) = self.header.tile_rect(lk, tx, 0);
        let tw = tw as usize;
        u_tile(&mut wk.predictor, self.coarse, (x0, self.y0), (tw, thu), &mut wk.u);
        wk.tv.clear();
        for r in 0..thu {
            let row = &self.band[r * w + x0 as usize..r * w + x0 as usize + tw];
            wk.tv.extend(row.iter().map(|&h| self.quant.target(lk, h)));
        }
        (x0, tw)
    }

    /// Adds the row's samples of the parities in `parities` to the worker's fit, tile by tile in order.
    fn fit(&self, wk: &mut Worker, step: u32, parities: u8) {
        for tx in 0..self.header.levels[self.lk].tiles_x {
            let (_, tw) = self.tile(wk, tx);
            fit_tile(&mut wk.fit, &wk.u, &wk.tv, step, (tw, self.th), parities);
        }
    }
}

/// One tile row of a level in the closed-loop pass: its inputs, its row number and the level's model.
struct TileRow<'a> {
    inputs: RowInputs<'a>,
    ty: u32,
    model: &'a LevelModel,
}

/// Where a tile of the row being coded went: the worker that coded it, where its values start in that
/// worker's buffers, and its sum of squared errors (metres^2).
#[derive(Clone, Copy, Default)]
struct TileSlot {
    worker: usize,
    at: usize,
    sq: f64,
}

impl TileRow<'_> {
    /// Quantises the row's tiles in closed loop, each worker taking the next tile as it comes free
    /// ([`super::deal`]: a tile reads only the coarser level and its own values, so its symbols do not
    /// depend on which worker made them), each tile's slot in `slots` saying where it went: the first error
    /// in tile order, and what `beside` returns, run on this thread meanwhile.
    fn code<T>(
        &self,
        workers: &mut [Worker],
        slots: &mut Vec<TileSlot>,
        beside: impl FnOnce() -> T,
    ) -> (Result<()>, T) {
        let tiles = self.inputs.header.levels[self.inputs.lk].tiles_x;
        slots.clear();
        slots.resize(tiles as usize, TileSlot::default());
        for wk in workers.iter_mut() {
            wk.syms.clear();
            wk.ctxs.clear();
            wk.rec.clear();
            wk.errors.worst = 0.0;
            wk.errors.lo_hi = (i32::MAX, i32::MIN);
        }
        super::deal::deal(
            slots,
            workers,
            |wk, tx, slot| self.code_tile(wk, tx, slot),
            beside,
            "a tile coding thread panicked",
        )
    }

    /// Tile `tx` of the row, appended to the worker's buffers; `slot` says where.
    fn code_tile(&self, wk: &mut Worker, tx: usize, slot: &mut TileSlot) -> Result<()> {
        let row = &self.inputs;
        let (lk, ty, thu) = (row.lk, self.ty, row.th);
        let w = row.header.levels[lk].width as usize;
        let tx = u32::try_from(tx).expect("tile columns fit u32");
        let (x0, tw) = row.tile(wk, tx);
        let (at, nn) = (wk.syms.len(), tw * thu);
        wk.syms.resize(at + nn, 0);
        wk.ctxs.resize(at + nn, 0);
        wk.rec.resize(at + nn, 0);
        codec::quantise(
            self.model,
            &wk.u,
            (tw, thu),
            &wk.tv,
            &mut wk.scratch,
            (&mut wk.syms[at..], &mut wk.ctxs[at..]),
            &mut wk.rec[at..],
        )
        .map_err(|e| {
            Error::param(
                Param::MaxError,
                format!("{} m: level {lk} tile ({tx}, {ty}): {e}", row.header.max_error),
            )
        })?;
        codec::count(&mut wk.counts, &wk.syms[at..], &wk.ctxs[at..]);
        let mut sq = 0.0;
        for (r, rec) in wk.rec[at..].chunks_exact(tw).enumerate() {
            let src = &row.band[r * w + x0 as usize..r * w + x0 as usize + tw];
            for (&k, &h) in rec.iter().zip(src) {
                #[expect(clippy::cast_possible_truncation, reason = "heights are f32")]
                let dec = (f64::from(k) * row.quant.q) as f32;
                let e = f64::from(dec) - f64::from(h);
                sq += e * e;
                let er = &mut wk.errors;
                er.worst = er.worst.max(e.abs());
                er.lo_hi = (er.lo_hi.0.min(k), er.lo_hi.1.max(k));
            }
        }
        *slot = TileSlot {
            worker: wk.id,
            at,
            sq,
        };
        Ok(())
    }
}

/// Codes every level of `spilled` as `header` lays it out, with the residual steps `steps` (finest
/// first), keeping temporary files beside `near`.
pub(super) fn code_levels(
    spilled: &mut Spilled,
    header: &Header,
    quant: Quantiser,
    steps: &[u32],
    near: &Path,
) -> Result<Coded> {
    let n = header.levels.len();
    assert!(
        spilled.len() >= n,
        "the header's levels are the spilled pyramid's finest"
    );
    let tile = header.tile;
    let (mut band, mut band_next) = (Vec::new(), Vec::new());
    let mut slots = Vec::new();
    let mut workers: Vec<Worker> = (0..super::threads()).map(|id| Worker::new(id, tile)).collect();
    let new_coarse = || CoarseRows {
        rows: Vec::new(),
        first: 0,
        width: 0,
        height: 0,
        reach: (0, 0),
    };
    let (mut coarse, mut coarse_next) = (new_coarse(), new_coarse());
    let mut coded = Coded {
        models: vec![LevelModel::plain(1); n],
        syms: Vec::with_capacity(n),
        counts: Counts::default(),
        sq: 0.0,
        worst: 0.0,
        worst_coarse: 0.0,
        lo_hi: (i32::MAX, i32::MIN),
        _recon: None,
    };
    let mut files: Vec<Option<TempFile>> = (0..n).map(|_| None).collect();
    let mut recon_prev: Option<TempFile> = None;
    for lk in (0..n).rev() {
        let dims = header.levels[lk];
        let w = dims.width as usize;
        let cdims = header.levels.get(lk + 1).map(|c| (c.width, c.height));
        let rows_of = |ty: u32| -> (u32, u32) {
            let (_, y0, _, th) = header.tile_rect(lk, 0, ty);
            (y0, th)
        };
        // Pass 1: the weights. Each fitting thread sums the samples of its own parities in the order one
        // thread would, so the sums (and the weights) do not depend on the number of threads.
        let fitters = workers.len().clamp(1, 4);
        let owner = |par: usize| par * fitters / 4;
        for wk in &mut workers {
            wk.fit = Fit::default();
        }
        let stride = (u64::from(dims.width) * u64::from(dims.height)).div_ceil(FIT_SAMPLES);
        let stride = u32::try_from(stride).unwrap_or(u32::MAX).max(1);
        for ty in (0..dims.tiles_y).step_by(stride as usize) {
            let (y0, th) = rows_of(ty);
            band.resize(th as usize * w, 0.0f32);
            spilled.read_rows(lk, y0, &mut band)?;
            if let (Some(f), Some(cd)) = (recon_prev.as_mut(), cdims) {
                coarse_rows(f, cd, (y0, th), &mut coarse)?;
                coarse.reach = header.u_reach(lk);
            }
            let row = RowInputs {
                header,
                lk,
                y0,
                th: th as usize,
                band: &band,
                coarse: cdims.map(|_| &coarse),
                quant,
            };
            let step = steps[lk];
            let mine = |t: usize| -> u8 { (0..4).filter(|&p| owner(p) == t).map(|p| 1u8 << p).sum() };
            if fitters == 1 {
                row.fit(&mut workers[0], step, 0b1111);
            } else {
                std::thread::scope(|s| {
                    for (t, wk) in workers[..fitters].iter_mut().enumerate() {
                        let row = &row;
                        s.spawn(move || row.fit(wk, step, mine(t)));
                    }
                });
            }
        }
        let mut fit = Fit::default();
        for par in 0..4 {
            fit.take_parity(&workers[owner(par)].fit, par);
        }
        let model = LevelModel {
            step: steps[lk],
            weights: fit.weights(),
        };
        // Pass 2: closed loop, symbols and reconstruction, the tiles of a row shared among the workers.
        let tmp = |what: &str| {
            TempFile::create(near.with_extension(format!("{what}{lk}.tmp{}", crate::temp_suffix())))
        };
        let recon_file = tmp("recon")?;
        let sym_file = tmp("syms")?;
        {
            let mut rw = BufWriter::with_capacity(1 << 16, &recon_file.file);
            let mut sw = BufWriter::with_capacity(1 << 16, &sym_file.file);
            // The row coded last, waiting to be written: its reconstruction, and its tiles' symbols then
            // contexts in tile order.
            let (mut rows_out, mut syms_out) = (Vec::<i32>::new(), Vec::<u8>::new());
            let mut write = |rows_out: &[i32], syms_out: &[u8]| -> Result<()> {
                sw.write_all(syms_out).map_err(io(&sym_file.path))?;
                rw.write_all(bytemuck::cast_slice(rows_out))
                    .map_err(io(&recon_file.path))
            };
            let mut read = |ty: u32, band: &mut Vec<f32>, coarse: &mut CoarseRows| -> Result<()> {
                let (y0, th) = rows_of(ty);
                band.resize(th as usize * w, 0.0f32);
                spilled.read_rows(lk, y0, band)?;
                if let (Some(f), Some(cd)) = (recon_prev.as_mut(), cdims) {
                    coarse_rows(f, cd, (y0, th), coarse)?;
                    coarse.reach = header.u_reach(lk);
                }
                Ok(())
            };
            // Row ty + 1 is read and row ty - 1 written on this thread while the workers code row ty;
            // errors are reported in the order one thread doing them in turn would meet them.
            let mut read_next = read(0, &mut band, &mut coarse);
            for ty in 0..dims.tiles_y {
                if let Err(e) = std::mem::replace(&mut read_next, Ok(())) {
                    write(&rows_out, &syms_out)?;
                    return Err(e);
                }
                let (y0, th) = rows_of(ty);
                let thu = th as usize;
                let row = TileRow {
                    inputs: RowInputs {
                        header,
                        lk,
                        y0,
                        th: thu,
                        band: &band,
                        coarse: cdims.map(|_| &coarse),
                        quant,
                    },
                    ty,
                    model: &model,
                };
                let (coded_row, (wrote, read_row)) = row.code(&mut workers, &mut slots, || {
                    let wrote = write(&rows_out, &syms_out);
                    let read_row = if ty + 1 < dims.tiles_y {
                        read(ty + 1, &mut band_next, &mut coarse_next)
                    } else {
                        Ok(())
                    };
                    (wrote, read_row)
                });
                wrote?;
                coded_row?;
                read_next = read_row;
                // The tiles in order, as one thread would have written them.
                rows_out.resize(thu * w, 0i32);
                syms_out.clear();
                for (tx, slot) in (0u32..).zip(&slots) {
                    let (wk, at) = (&workers[slot.worker], slot.at);
                    let (x0, _, tw, _) = header.tile_rect(lk, tx, ty);
                    let (tw, nn) = (tw as usize, tw as usize * thu);
                    syms_out.extend_from_slice(bytemuck::cast_slice(&wk.syms[at..at + nn]));
                    syms_out.extend_from_slice(&wk.ctxs[at..at + nn]);
                    for r in 0..thu {
                        let o = r * w + x0 as usize;
                        rows_out[o..o + tw].copy_from_slice(&wk.rec[at + r * tw..at + (r + 1) * tw]);
                    }
                }
                for wk in &workers {
                    let e = &wk.errors;
                    if lk == 0 {
                        coded.lo_hi = (coded.lo_hi.0.min(e.lo_hi.0), coded.lo_hi.1.max(e.lo_hi.1));
                        coded.worst = coded.worst.max(e.worst);
                    } else {
                        coded.worst_coarse = coded.worst_coarse.max(e.worst);
                    }
                }
                if lk == 0 {
                    // Tile by tile in tile order, whatever the number of workers.
                    coded.sq = slots.iter().fold(coded.sq, |a, t| a + t.sq);
                }
                std::mem::swap(&mut band, &mut band_next);
                std::mem::swap(&mut coarse, &mut coarse_next);
            }
            write(&rows_out, &syms_out)?;
            rw.flush().map_err(io(&recon_file.path))?;
            sw.flush().map_err(io(&sym_file.path))?;
        }
        coded.models[lk] = model;
        files[lk] = Some(sym_file);
        recon_prev = Some(recon_file);
    }
    // Integer counts: their sum does not depend on which worker counted a tile.
    for wk in &workers {
        for (all, one) in coded.counts.0.iter_mut().zip(&wk.counts.0) {
            for (a, b) in all.iter_mut().zip(one) {
                *a += b;
            }
        }
    }
    coded.syms = files.into_iter().flatten().collect();
    coded._recon = recon_prev;
    Ok(coded)
}

impl Coded {
    /// The decoded level 0's lowest and highest height, metres, for a quantum of `q` metres.
    pub(super) fn range(&self, q: f64) -> (f32, f32) {
        #[expect(clippy::cast_possible_truncation, reason = "heights are f32")]
        let m = |k: i32| (f64::from(k) * q) as f32;
        (m(self.lo_hi.0), m(self.lo_hi.1))
    }

    /// The rANS tables of the counted symbols.
    pub(super) fn tables(&self) -> Tables {
        codec::tables(&self.counts)
    }

    /// Codes the stored symbols, coarse to fine and a tile row at a time: `f` gets (level, ty, the row's
    /// payloads left to right). `tables` for rANS, else the byte-plane `encoders` (one per thread).
    pub(super) fn write_tiles(
        &mut self,
        header: &Header,
        encoders: &mut [Encoder],
        mut f: impl FnMut(usize, u32, &[Vec<u8>]) -> Result<()>,
    ) -> Result<()> {
        let tables = header.tables.as_ref();
        for lk in (0..header.levels.len()).rev() {
            let dims = header.levels[lk];
            let file = &mut self.syms[lk];
            file.file.seek(SeekFrom::Start(0)).map_err(io(&file.path))?;
            let mut rd = BufReader::with_capacity(1 << 16, &file.file);
            let path = &file.path;
            // Tile row ty's symbols, read into the buffers of the row before last.
            let mut read = |ty: u32, tiles: &mut Vec<(Vec<i32>, Vec<u8>)>| -> Result<()> {
                tiles.resize_with(dims.tiles_x as usize, Default::default);
                for (tx, (s, c)) in (0..dims.tiles_x).zip(tiles.iter_mut()) {
                    let (_, _, tw, th) = header.tile_rect(lk, tx, ty);
                    let n = tw as usize * th as usize;
                    s.resize(n, 0);
                    c.resize(n, 0);
                    rd.read_exact(bytemuck::cast_slice_mut(s))
                        .and_then(|()| rd.read_exact(c))
                        .map_err(io(path))?;
                }
                Ok(())
            };
            let (mut tiles, mut next) = (Vec::new(), Vec::new());
            read(0, &mut tiles)?;
            // The next row is read on this thread while the row is coded; errors in the order one
            // thread doing them in turn would meet them.
            for ty in 0..dims.tiles_y {
                let (payloads, read_next) = encode_row(tables, encoders, &tiles, || {
                    if ty + 1 < dims.tiles_y {
                        read(ty + 1, &mut next)
                    } else {
                        Ok(())
                    }
                });
                let payloads =
                    payloads.map_err(|e| Error::io(path, "cannot compress a tile", e))?;
                f(lk, ty, &payloads)?;
                read_next?;
                std::mem::swap(&mut tiles, &mut next);
            }
        }
        Ok(())
    }

    /// Every tile's symbols, coarse to fine: `f(level, (tx, ty), symbols)` (a measurement aid's entry).
    pub(super) fn each_tile(
        &mut self,
        header: &Header,
        mut f: impl FnMut(usize, (u32, u32), &[i32]) -> Result<()>,
    ) -> Result<()> {
        for lk in (0..header.levels.len()).rev() {
            let dims = header.levels[lk];
            let file = &mut self.syms[lk];
            file.file.seek(SeekFrom::Start(0)).map_err(io(&file.path))?;
            let mut rd = BufReader::new(&file.file);
            for ty in 0..dims.tiles_y {
                for tx in 0..dims.tiles_x {
                    let (_, _, tw, th) = header.tile_rect(lk, tx, ty);
                    let n = tw as usize * th as usize;
                    let (mut s, mut c) = (vec![0i32; n], vec![0u8; n]);
                    rd.read_exact(bytemuck::cast_slice_mut(&mut s))
                        .and_then(|()| rd.read_exact(&mut c))
                        .map_err(io(&file.path))?;
                    f(lk, (tx, ty), &s)?;
                }
            }
        }
        Ok(())
    }
}

/// A tile row's payloads, in order, coded in parallel (each encoder taking the next tile as it comes
/// free, [`super::deal`]: a payload does not depend on which thread made it), and what `beside` returns,
/// run on this thread meanwhile.
fn encode_row<T>(
    tables: Option<&Tables>,
    encoders: &mut [Encoder],
    tiles: &[(Vec<i32>, Vec<u8>)],
    beside: impl FnOnce() -> T,
) -> (std::io::Result<Vec<Vec<u8>>>, T) {
    let mut payloads = vec![Vec::new(); tiles.len()];
    let encode = |enc: &mut Encoder, i: usize, out: &mut Vec<u8>| {
        let (syms, ctxs) = &tiles[i];
        *out = match tables {
            Some(t) => codec::encode_rans(t, syms, ctxs),
            None => codec::encode_planes(enc, syms)?,
        };
        Ok(())
    };
    let (r, b) = super::deal::deal(
        &mut payloads,
        encoders,
        encode,
        beside,
        "a tile encoder thread panicked",
    );
    (r.map(|()| payloads), b)
}

/// The residual steps of each level, finest first: level 0 on its lattice gets the odd step 2N + 1 with
/// N = floor(E / q) (JPEG-LS NEAR: integer errors of at most N quanta), every other level (filtered,
/// real-valued) the largest step whose half fits E.
pub(super) fn steps(levels: usize, quant: Quantiser, max_error: f64) -> Vec<u32> {
    // A hair of slack: E / q is an exact integer (or half) in metres but not always in binary.
    let ratio = max_error / quant.q + 1e-9;
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "small positive ratios, clamped"
    )]
    let coarse = ((2.0 * ratio).floor().clamp(1.0, f64::from(1u32 << 20))) as u32;
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "small positive ratios, clamped"
    )]
    let near = (ratio.floor().clamp(0.0, f64::from(1u32 << 19))) as u32;
    (0..levels)
        .map(|lk| {
            if lk == 0 && quant.lattice {
                2 * near + 1
            } else {
                coarse
            }
        })
        .collect()
}

/// Whether the codec is the rANS one (tables needed before the tiles).
pub(super) fn needs_tables(codec: CodecKind) -> bool {
    codec == CodecKind::Rans
}
