//! Stage 1, bake: the LOD tables of docs/design.md "SAT LOD" (error maps, their SATs and max pyramids), after
//! Li et al. 2021 ("SAT paper").
//!
//! # Error maps
//!
//! For clipmap level L (data level k = L - synth_levels), e_L(x, y) = |H_0(x, y) - PL(H_L)(x, y)| at every
//! data sample, with H_L the pyramid level the ring holds ([`Pyramid::at`]) and PL its piecewise-linear
//! surface split along the (i, j)-(i+1, j+1) diagonal, the triangulation the renderer draws and
//! [`crate::plan::clipmap`]'s z_c uses. e is computed in f64 and stored as f32; every bound below is about these
//! f32 values. E_L is their maximum. Rings finer than the data (synthesised) and the data level itself have
//! no error against the data. The transition morph is not modelled: a morphing vertex lies between levels L
//! and L + 1.
//!
//! The per-frame selection over these tables is [`crate::plan::lod`].

use std::fmt;
use std::str::FromStr;

use crate::bake::lod_record::{sum_upper, Coder};
use crate::bake::mapped::Mapping;
use crate::bake::pyramid::Pyramid;
use crate::bake::sat::{pow_unit, Sat};
use crate::{Error, Result};

pub use crate::bake::lod_record::LevelRecords;
pub use crate::bake::range_max::RangeMax;

/// The exponent p of the SFAMF estimate (docs/design.md "SAT LOD" 3-4), fixed from `clipsat tune-p`.
///
/// Measured with `clipsat tune-p` (gles3-mid blocks, m = 32, 10 levels, 12321 block-level pairs), ratio to
/// the exact block max, "zero" = blocks whose rounded-down estimate is 0 (below the quantum floor):
///
/// ```text
/// terrain                    p   est mean  est p01  est=0   cons mean  cons p99  cons max
/// procedural 1025^2 @ 30 m   4   0.537     0.161      1     2.52       5.10       7.24
///                            8   0.610     0.000    656     1.99      11.8      125
/// ps_height_1k @ 160 m       4   0.486     0.213      0     2.94       6.51      10.7
///                            8   0.584     0.000    229     1.56       2.87       7.73
/// ```
///
/// p = 8 has the best mean estimate, but 2-5 % of blocks fall under the 2^-43 quantum ((e/E)^8 for
/// e < E/41) and estimate 0; p = 4 keeps every estimate above 0.16 of the truth in 99 % of blocks and the
/// conservative bound within 11x. Larger p only gets worse on both terrains. (The cons columns predate the
/// coarse max-pyramid cap of [`LodMode::SatConservative`], which can only lower them.)
pub const P: u32 = 4;

/// Safety factors that keep estimate <= exact <= conservative through the f64 roundings of the power
/// chain (relative error below (p + 8) 2^-53 < 1e-14 for p <= 64).
const DOWN: f64 = 1.0 - 1.0 / (1u64 << 36) as f64;
const UP: f64 = 1.0 + 1.0 / (1u64 << 36) as f64;

/// How each block of the terrain chooses its level ([`crate::FrameOptions::lod`]): by its ring
/// (distance LOD), or, in the SAT modes, the coarsest level whose screen-space error bound stays under
/// [`crate::TerrainRenderer::set_sat_lod_px`], with the block's object-space error judged as each mode
/// says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LodMode {
    /// No SAT: every block is drawn at its own ring's level (plain geometry clipmap).
    Distance,
    /// The SFAMF estimate M = E (mean (e/E)^p)^(1/p), never above the true max (the SAT paper's choice).
    Sat,
    /// min(E, N^(1/p) M, C): never below the true max. C is the max pyramid's value over the at most
    /// 2 x 2 coarse cells covering the block (`RangeMax::max_coarse`, O(1)): each of the three is an
    /// upper bound, and C is the tight one where the error is spread over the block (there N^(1/p) M is
    /// up to N^(1/p) = 5.7 times the max for p = 4 and a 32 x 32 block).
    SatConservative,
    /// The true max over the block, from a max pyramid (the accuracy reference).
    Exact,
}

impl LodMode {
    /// The names [`LodMode::from_str`] accepts.
    #[doc(hidden)]
    pub const NAMES: [&'static str; 4] = ["distance", "sat", "sat-conservative", "exact"];
    /// Every mode, in the order of [`LodMode::NAMES`].
    #[doc(hidden)]
    pub const ALL: [LodMode; 4] = [
        LodMode::Distance,
        LodMode::Sat,
        LodMode::SatConservative,
        LodMode::Exact,
    ];
}

impl FromStr for LodMode {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        match text {
            "distance" => Ok(Self::Distance),
            "sat" => Ok(Self::Sat),
            "sat-conservative" => Ok(Self::SatConservative),
            "exact" => Ok(Self::Exact),
            _ => Err(Error::Invalid {
                what: "LOD mode".into(),
                reason: format!("`{text}` is not one of {}", Self::NAMES.join(", ")),
            }),
        }
    }
}

impl fmt::Display for LodMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Distance => "distance",
            Self::Sat => "sat",
            Self::SatConservative => "sat-conservative",
            Self::Exact => "exact",
        })
    }
}

/// The error map of data level `k` (k >= 1; level 0 is the data and has none): W x H f32, row-major.
///
/// Rows are computed in parallel; each sample is a pure function of the pyramid, so the result does not
/// depend on the thread count.
pub fn error_map(pyramid: &Pyramid, k: u32) -> Vec<f32> {
    let l0 = pyramid.level(0);
    let (w, h) = (l0.width() as usize, l0.height() as usize);
    let mut out = vec![0.0f32; w * h];
    if k == 0 {
        return out;
    }
    let k = k.min(40);
    let threads = std::thread::available_parallelism()
        .map_or(1, usize::from)
        .min(16);
    let rows_per = h.div_ceil(threads);
    std::thread::scope(|s| {
        for (ci, chunk) in out.chunks_mut(rows_per * w).enumerate() {
            s.spawn(move || {
                for (r, row) in chunk.chunks_mut(w).enumerate() {
                    let y = ci * rows_per + r;
                    for (x, o) in row.iter_mut().enumerate() {
                        *o = sample_error(pyramid, k, x as i64, y as i64);
                    }
                }
            });
        }
    });
    out
}

/// e at data sample (x, y) against data level k's piecewise-linear surface (k <= 40; measurement code such
/// as [`crate::measure::screen_error`] reads it per sample instead of keeping an error map).
#[inline]
pub fn sample_error(pyramid: &Pyramid, k: u32, x: i64, y: i64) -> f32 {
    let z = |a: i64, b: i64| f64::from(pyramid.at(k, a, b));
    let h0 = f64::from(pyramid.level(0).at_clamped(x, y));
    error_from(z, h0, k, x, y)
}

/// [`sample_error`] from level k's heights `z(i, j)` (metres, clamped as [`Pyramid::at`] clamps) and
/// the data height `h0` at (x, y): the one formula, so a streamed bake ([`crate::package::lod_stream`])
/// computes the same f32 bits as one over a resident pyramid.
#[inline]
#[expect(
    clippy::cast_possible_truncation,
    reason = "the error is stored as f32, rounded once"
)]
pub(crate) fn error_from(z: impl Fn(i64, i64) -> f64, h0: f64, k: u32, x: i64, y: i64) -> f32 {
    let step = 1i64 << k;
    let (i, j) = (x >> k, y >> k);
    let inv = 1.0 / step as f64;
    let fx = (x & (step - 1)) as f64 * inv;
    let fy = (y & (step - 1)) as f64 * inv;
    let z00 = z(i, j);
    // The (i, j)-(i+1, j+1) diagonal: fx >= fy is the triangle (i,j),(i+1,j),(i+1,j+1).
    let pl = if fx == 0.0 && fy == 0.0 {
        z00
    } else if fx >= fy {
        let (z10, z11) = (z(i + 1, j), z(i + 1, j + 1));
        z00 + fx * (z10 - z00) + fy * (z11 - z10)
    } else {
        let (z01, z11) = (z(i, j + 1), z(i + 1, j + 1));
        z00 + fy * (z01 - z00) + fx * (z11 - z01)
    };
    (h0 - pl).abs() as f32
}

/// One block's object-space error at one level, metres: estimate <= exact <= conservative.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BlockError {
    /// The SFAMF estimate E (mean (e/E)^p)^(1/p), from the SAT sum rounded down.
    pub estimate: f64,
    /// The true maximum.
    pub exact: f64,
    /// min(E, N^(1/p) M, C), from the SAT sum rounded up ([`LodMode::SatConservative`]).
    pub conservative: f64,
}

/// The tables of one data level: E, the SAT of (e/E)^p and the max pyramid of e. None where E = 0.
///
/// # Resolution
///
/// Built by [`LevelTables::build_level`], data level k's tables live at level k's resolution (cell side
/// 2^k data samples, `shift` = k), about 4^-k of a full-resolution table (docs/design.md "SAT LOD": a block
/// drawn at level k covers whole level-k cells, so its box is aligned to level k's lattice). They are
/// decoded from the level's compact records ([`crate::bake::lod_record`], two bytes a cell, what a
/// package stores), the one definition every path uses:
///
/// - the max pyramid holds each **closed** cell's [c 2^k, (c + 1) 2^k]^2 (both edges, as the triangles of
///   level k cover them) max error rounded up to its code, so the max over a lattice-aligned inclusive
///   box is at least the true one and within one code step (2^(1/16)) of it, or at the codes' floor;
/// - the SAT sums each **half-open** cell's [c 2^k, (c + 1) 2^k)^2 decoded lower sum of the quantised
///   (e/E)^p ([`Sat`] with `cell` = 2^k), never above the cell's true sum; the true sum of a box is
///   below [`crate::bake::lod_record::sum_upper`] of it.
///
/// A query box [x0, x1) x [y0, y1) of data samples (inclusive last sample x1 - 1) is widened to the
/// closed cells that cover it, the region level k's geometry draws over it: for a lattice-aligned box
/// that is the box itself. Then `exact` is the decoded max over the widened box (>= its true max);
/// `estimate` is the p-mean of the lower sums over the half-open cells' samples (a subset of the widened
/// box: still <= the true max); `conservative` adds to the upper sum the far edge column and row (which
/// the half-open cells leave out), each sample bounded by (M/E)^p with M the edge's decoded max: still >=
/// the true max. [`LevelTables::build`] (`shift` = 0) keeps the full-resolution tables of the per-sample
/// quantised values, uncoded (one cell per sample), for tools and tests that compare against them.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelTables {
    e_max: f32,
    shift: u32,
    tables: Option<(Sat, RangeMax)>,
}

/// The closed cells covering an inclusive sample box and what the query needs of them.
struct Cells {
    /// Closed cells [ca, cb] x [ra, rb] (inclusive).
    ca: u32,
    cb: u32,
    ra: u32,
    rb: u32,
    /// The half-open SAT box [x0, x1) x [y0, y1) inside the widened box.
    sat: (u32, u32, u32, u32),
    /// Samples in the SAT box: the estimate's mean is over them (a subset of the widened box, so that
    /// mean never exceeds the widened box's max).
    n_sat: f64,
    /// Samples on the far edge column and row the SAT box leaves out (0 when at the grid's end).
    edge_col: f64,
    edge_row: f64,
}

/// Bounds the closed-cell indices covering inclusive samples [a, b] of an axis of `len` samples at shift
/// `s`: cells [ca, cb] of `count`, the SAT end (half-open) and the inclusive last sample they cover.
fn axis_cells(a: u32, b: u32, len: u32, s: u32, count: u32) -> (u32, u32, u32, u32) {
    if s == 0 {
        return (a, b, b + 1, b);
    }
    let ca = (a >> s).min(count - 1);
    let cb = ((b >> s) + u32::from(b & ((1 << s) - 1) != 0))
        .saturating_sub(1)
        .clamp(ca, count - 1);
    let end = (cb + 1) << s;
    (ca, cb, end.min(len), end.min(len - 1))
}

/// Closed cells per axis of `len` samples at shift `s`: the last closed cell ends on the last sample.
pub(crate) fn closed_count(len: u32, s: u32) -> u32 {
    if s == 0 {
        len
    } else {
        (len - 1).div_ceil(1 << s).max(1)
    }
}

impl LevelTables {
    /// Builds the full-resolution tables (one cell per sample, `shift` 0): the SAT of (e/E)^p (quantum
    /// 2^-[`Sat::max_frac_bits`]) and the max pyramid of `errors`.
    ///
    /// An error that is not a finite non-negative number (heights near `f32::MAX` overflow the error map
    /// to infinity) is an [`Error::Terrain`] naming the sample: E_L and every (e/E)^p would be meaningless.
    pub fn build(width: u32, height: u32, errors: Vec<f32>, p: u32) -> Result<Self> {
        if let Some(i) = errors.iter().position(|e| !(e.is_finite() && *e >= 0.0)) {
            let w = width.max(1) as usize;
            return Err(bad_error(i % w, i / w, errors[i]));
        }
        // Every error is finite, so the fold is the true maximum (f32::max would skip a NaN).
        let e_max = errors.iter().copied().fold(0.0f32, f32::max);
        if e_max <= 0.0 {
            return Ok(Self::zero());
        }
        let q = Sat::max_frac_bits(u64::from(width) * u64::from(height));
        let inv = 1.0 / f64::from(e_max);
        let sat = Sat::build(width, height, 1, q, |x, y| {
            let e = errors[y as usize * width as usize + x as usize];
            pow_unit(f64::from(e) * inv, p).min(1.0)
        })?;
        Ok(Self {
            e_max,
            shift: 0,
            tables: Some((sat, RangeMax::build(width, height, errors))),
        })
    }

    /// A level without error (the data level, or a flat terrain).
    pub fn zero() -> Self {
        Self {
            e_max: 0.0,
            shift: 0,
            tables: None,
        }
    }

    /// Builds data level `k`'s tables at level k's resolution (see the type's docs) straight from the
    /// pyramid, without a full-resolution error map: its compact records ([`LevelRecords::build`]),
    /// decoded into the query structures ([`LevelTables::from_records`]), as every path builds them.
    ///
    /// Errors as [`LevelTables::build`].
    pub fn build_level(pyramid: &Pyramid, k: u32, p: u32) -> Result<Self> {
        let l0 = pyramid.level(0);
        match LevelRecords::build(pyramid, k, p)? {
            None => Ok(Self::zero()),
            Some(rec) => Self::from_records(l0.width(), l0.height(), p, &rec),
        }
    }

    /// The query structures of one level's records ([`crate::bake::lod_record`]): the SAT of the decoded
    /// lower sums and the max pyramid of the decoded maxima.
    ///
    /// Errors: records whose sizes do not fit the grid ([`Error::Invalid`]).
    pub fn from_records(width: u32, height: u32, p: u32, rec: &LevelRecords) -> Result<Self> {
        let s = rec.k.min(30);
        let (cw, ch) = (closed_count(width, s), closed_count(height, s));
        let (sw, sh) = (width.div_ceil(1 << s), height.div_ceil(1 << s));
        let fits = rec.max.len() as u64 == u64::from(cw) * u64::from(ch)
            && rec.mean.len() as u64 == u64::from(sw) * u64::from(sh);
        if !(fits && rec.e_max.is_finite() && rec.e_max > 0.0) {
            return Err(Error::Invalid {
                what: "LOD records".into(),
                reason: format!("level {} records do not fit {width} x {height}", rec.k),
            });
        }
        let q = Sat::max_frac_bits(u64::from(width) * u64::from(height));
        let coder = Coder::new(rec.e_max, p, q, s, width, height);
        let maxima: Vec<f32> = rec.max.iter().map(|&c| coder.max_decode(c)).collect();
        let mut sums = vec![0u64; rec.mean.len()];
        for (cy, (codes, lower)) in (0u32..).zip(
            rec.mean
                .chunks(sw as usize)
                .zip(sums.chunks_mut(sw as usize)),
        ) {
            let r = cy.min(ch - 1) as usize * cw as usize;
            coder.decode_mean_row(cy, codes, &maxima[r..r + cw as usize], lower);
        }
        let sat = Sat::from_cell_sums(width, height, 1 << s, q, sums)?;
        Ok(Self {
            e_max: rec.e_max,
            shift: s,
            tables: Some((sat, RangeMax::build(cw, ch, maxima))),
        })
    }

    /// Rebuilds from a cached SAT and closed-cell maxima (see [`crate::bake`]) at `shift`.
    pub fn from_parts(e_max: f32, shift: u32, tables: Option<(Sat, RangeMax)>) -> Self {
        Self {
            e_max,
            shift,
            tables,
        }
    }

    /// E_L, the level's largest error, metres.
    pub fn e_max(&self) -> f32 {
        self.e_max
    }

    /// log2 of the cell side in data samples (data level k's tables: k; full resolution: 0).
    pub fn shift(&self) -> u32 {
        self.shift
    }

    /// Closed cells per row and rows at `shift` over a `width x height` grid: the max pyramid's size.
    pub fn closed_cells(width: u32, height: u32, shift: u32) -> (u32, u32) {
        (closed_count(width, shift), closed_count(height, shift))
    }

    /// The SAT and max pyramid (None when the level has no error).
    pub fn tables(&self) -> Option<&(Sat, RangeMax)> {
        self.tables.as_ref()
    }

    /// Bytes the tables hold (SAT entries and the max pyramid).
    pub fn memory_bytes(&self) -> u64 {
        self.tables
            .as_ref()
            .map_or(0, |(sat, max)| sat.memory_bytes() + max.memory_bytes())
    }

    /// Bytes the tables hold in owned memory (0 when they borrow a mapped cache file).
    pub fn owned_bytes(&self) -> u64 {
        self.tables
            .as_ref()
            .map_or(0, |(sat, max)| sat.owned_bytes() + max.owned_bytes())
    }

    /// The closed cells covering data samples [x0, x1) x [y0, y1) (non-empty, inside the grid).
    fn cells(&self, sat: &Sat, max: &RangeMax, x0: u32, y0: u32, x1: u32, y1: u32) -> Cells {
        let s = self.shift;
        let (cw, ch) = max.size();
        let (w, h) = (sat.width(), sat.height());
        let (ca, cb, xe, xl) = axis_cells(x0, x1 - 1, w, s, cw);
        let (ra, rb, ye, yl) = axis_cells(y0, y1 - 1, h, s, ch);
        let (sx, sy) = (
            if s == 0 { x0 } else { ca << s },
            if s == 0 { y0 } else { ra << s },
        );
        let (nx, ny) = (f64::from(xl - sx + 1), f64::from(yl - sy + 1));
        Cells {
            ca,
            cb,
            ra,
            rb,
            sat: (sx, sy, xe, ye),
            n_sat: f64::from(xe - sx) * f64::from(ye - sy),
            edge_col: if xe <= xl { ny } else { 0.0 },
            edge_row: if ye <= yl { nx } else { 0.0 },
        }
    }

    /// Whether the tables are built from compact records ([`crate::bake::lod_record`]: every level-
    /// resolution table, `shift` > 0), whose SAT holds lower sums, or per-sample quantised values (the
    /// full-resolution reference, `shift` 0).
    pub fn coded(&self) -> bool {
        self.shift > 0
    }

    /// A certain enclosure [lo, hi] of the sum of (e/E)^p over the SAT box of `c`.
    fn sum_bounds(&self, sat: &Sat, c: &Cells) -> (f64, f64) {
        let (x0, y0, x1, y1) = c.sat;
        if !self.coded() {
            return sat.box_bounds(x0, y0, x1, y1);
        }
        // The decoded lower sums: a lower bound as they are (rounded down once more into f64).
        let raw = sat.box_sum_raw(x0, y0, x1, y1);
        let n = u64::from(x1 - x0) * u64::from(y1 - y0);
        #[expect(clippy::cast_precision_loss, reason = "u64 to f64, then nudged down")]
        let lo = raw as f64 * sat.quantum() * (1.0 - f64::EPSILON);
        (lo, sum_upper(raw, n, sat.quantum()))
    }

    /// The upper end of the sum of (e/E)^p over the widened box: the SAT's, plus the far edges bounded by
    /// their maxima.
    fn sum_hi(&self, p: u32, sat: &Sat, max: &RangeMax, c: &Cells) -> (f64, f64) {
        let (lo, mut hi) = self.sum_bounds(sat, c);
        let inv = 1.0 / f64::from(self.e_max);
        // pow_unit is within p ulps of the power: 2^-40 more covers it and the sum's roundings.
        let bound = |m: f32| pow_unit(f64::from(m) * inv, p).min(1.0) * EDGE_UP;
        if c.edge_col > 0.0 {
            hi += c.edge_col * bound(max.max(c.cb, c.ra, c.cb + 1, c.rb + 1));
        }
        if c.edge_row > 0.0 {
            hi += c.edge_row * bound(max.max(c.ca, c.rb, c.cb + 1, c.rb + 1));
        }
        (lo, hi)
    }

    /// The error over data samples [x0, x1) x [y0, y1) (non-empty, inside the grid), with exponent `p`.
    pub fn block(&self, p: u32, x0: u32, y0: u32, x1: u32, y1: u32) -> BlockError {
        let Some((sat, max)) = &self.tables else {
            return BlockError::default();
        };
        let c = self.cells(sat, max, x0, y0, x1, y1);
        let e = f64::from(self.e_max);
        let (lo, hi) = self.sum_hi(p, sat, max, &c);
        let inv_p = 1.0 / f64::from(p);
        // SFAMF (SAT paper section 4): the p-mean never exceeds the max, the p-sum never falls below it.
        BlockError {
            estimate: e * (lo / c.n_sat).min(1.0).powf(inv_p) * DOWN,
            exact: f64::from(max.max(c.ca, c.ra, c.cb + 1, c.rb + 1)),
            conservative: (e * hi.powf(inv_p) * UP)
                .min(e)
                .min(f64::from(max.max_coarse(c.ca, c.ra, c.cb + 1, c.rb + 1))),
        }
    }

    /// The object-space error of the block under `mode` (`Distance` has none: 0).
    pub fn eta(&self, mode: LodMode, p: u32, x0: u32, y0: u32, x1: u32, y1: u32) -> f64 {
        let Some((sat, max)) = &self.tables else {
            return 0.0;
        };
        if mode == LodMode::Distance {
            return 0.0;
        }
        let c = self.cells(sat, max, x0, y0, x1, y1);
        let e = f64::from(self.e_max);
        let inv_p = 1.0 / f64::from(p);
        match mode {
            LodMode::Distance => 0.0,
            LodMode::Exact => f64::from(max.max(c.ca, c.ra, c.cb + 1, c.rb + 1)),
            LodMode::Sat => {
                let (lo, _) = self.sum_bounds(sat, &c);
                e * (lo / c.n_sat).min(1.0).powf(inv_p) * DOWN
            }
            LodMode::SatConservative => {
                let (_, hi) = self.sum_hi(p, sat, max, &c);
                // Also never below the max: the coarse cells of the max pyramid over the box.
                let coarse = max.max_coarse(c.ca, c.ra, c.cb + 1, c.rb + 1);
                (e * hi.powf(inv_p) * UP).min(e).min(f64::from(coarse))
            }
        }
    }
}

impl LevelRecords {
    /// Data level `k`'s records straight from the pyramid (None where k = 0 or E = 0): one pass for the
    /// closed cells' maxima (and E), one for the half-open cells' quantised sums, rows of cells in
    /// parallel; then the codes ([`Coder`]).
    ///
    /// An error that is not a finite non-negative number is an [`Error::Terrain`] naming the sample.
    pub fn build(pyramid: &Pyramid, k: u32, p: u32) -> Result<Option<Self>> {
        let l0 = pyramid.level(0);
        let (w, h) = (l0.width(), l0.height());
        let (s, ke) = (k.min(30), k.min(40));
        if k == 0 {
            return Ok(None);
        }
        let (cw, ch) = (closed_count(w, s), closed_count(h, s));
        // Pass 1: the closed cells' maxima; a non-finite error is refused, naming its sample.
        let mut maxima = vec![0.0f32; cw as usize * ch as usize];
        let bad = par_cell_rows(&mut maxima, cw as usize, |cy, row| {
            let y0 = cy << s;
            for y in y0..=(y0 + (1 << s)).min(h - 1) {
                for x in 0..w {
                    let e = sample_error(pyramid, ke, i64::from(x), i64::from(y));
                    if !(e.is_finite() && e >= 0.0) {
                        return Some((x, y, e));
                    }
                    // Sample x lies in closed cell x >> s and, on a lattice line, in the one before.
                    let c = (x >> s) as usize;
                    if let Some(m) = row.get_mut(c) {
                        *m = m.max(e);
                    }
                    if c > 0 && x & ((1 << s) - 1) == 0 {
                        row[c - 1] = row[c - 1].max(e);
                    }
                }
            }
            None
        });
        if let Some((x, y, e)) = bad {
            return Err(bad_error(x as usize, y as usize, e));
        }
        let e_max = maxima.iter().copied().fold(0.0f32, f32::max);
        if e_max <= 0.0 {
            return Ok(None);
        }
        // Pass 2: the half-open cells' sums of the quantised (e/E)^p (the same integers as a full table).
        let q = Sat::max_frac_bits(u64::from(w) * u64::from(h));
        let inv = 1.0 / f64::from(e_max);
        let (sw, sh) = (w.div_ceil(1 << s), h.div_ceil(1 << s));
        let mut sums = vec![0u64; sw as usize * sh as usize];
        par_cell_rows(&mut sums, sw as usize, |cy, row| {
            let y0 = cy << s;
            for y in y0..(y0 + (1 << s)).min(h) {
                for x in 0..w {
                    let e = sample_error(pyramid, ke, i64::from(x), i64::from(y));
                    let v = pow_unit(f64::from(e) * inv, p).min(1.0);
                    let c = (x >> s) as usize;
                    row[c] = row[c].wrapping_add(Sat::quantise_up(v, q, x, y));
                }
            }
            None
        });
        let coder = Coder::new(e_max, p, q, s, w, h);
        let mut max = vec![0u8; maxima.len()];
        coder.code_max_row(&mut maxima, &mut max);
        let mut mean = vec![0u8; sums.len()];
        let mut lower = vec![0u64; sw as usize];
        for (cy, (row, codes)) in
            (0u32..).zip(sums.chunks(sw as usize).zip(mean.chunks_mut(sw as usize)))
        {
            let r = cy.min(ch - 1) as usize * cw as usize;
            coder.code_mean_row(cy, row, &maxima[r..r + cw as usize], codes, &mut lower);
        }
        Ok(Some(Self {
            k,
            e_max,
            max,
            mean,
        }))
    }
}

/// Covers pow_unit's p ulps and the f64 roundings of the edge terms of [`LevelTables::block`].
const EDGE_UP: f64 = 1.0 + 1.0 / (1u64 << 40) as f64;

pub(crate) fn bad_error(x: usize, y: usize, e: f32) -> Error {
    Error::terrain(format!(
        "the SAT LOD error at column {x}, row {y} is {e}: the heights are too large for f32 \
         arithmetic (their differences overflow); scale them down, or use distance LOD"
    ))
}

/// Runs `f(cell_row, row)` over the rows of a row-major grid `cols` wide, rows split across threads; the
/// first `Some` any row returns (lowest row first) is the result. Each row is a pure function of its
/// index, so the grid does not depend on the thread count.
fn par_cell_rows<T: Send>(
    grid: &mut [T],
    cols: usize,
    f: impl Fn(u32, &mut [T]) -> Option<(u32, u32, f32)> + Sync,
) -> Option<(u32, u32, f32)> {
    let rows = grid.len() / cols.max(1);
    let threads = std::thread::available_parallelism()
        .map_or(1, usize::from)
        .clamp(1, 16);
    let per = rows.div_ceil(threads).max(1);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> = grid
            .chunks_mut(per * cols)
            .enumerate()
            .map(|(ci, chunk)| {
                s.spawn(move || {
                    chunk.chunks_mut(cols).enumerate().find_map(|(r, row)| {
                        f(u32::try_from(ci * per + r).expect("rows fit u32"), row)
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .filter_map(|h| h.join().expect("a table row panicked"))
            .next()
    })
}

/// Refuses, with [`Error::Terrain`], heights whose range does not fit an f32 (highest minus lowest
/// overflows, as with heights near `f32::MAX` of both signs): every LOD error and bound would be infinite.
pub fn check_height_range(pyramid: &Pyramid) -> Result<()> {
    let (lo, hi) = pyramid
        .level(0)
        .heights()
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &z| {
            (a.min(z), b.max(z))
        });
    if (hi - lo).is_finite() {
        Ok(())
    } else {
        Err(Error::terrain(format!(
            "heights span {lo:e} .. {hi:e} m, a range too large for f32 arithmetic (it overflows); \
             scale them down, or use distance LOD"
        )))
    }
}

/// Every level's tables over one terrain: index k is data level k (clipmap level k + synth_levels).
#[derive(Clone, Debug)]
pub struct LodTables {
    /// The exponent the SATs were built with.
    pub p: u32,
    /// Data grid width and height, samples.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Per data level, finest (the data, no error) first.
    pub levels: Vec<LevelTables>,
    /// The cache file the tables borrow from, if read through a map ([`crate::bake`]).
    pub mapping: Option<Mapping>,
}

/// Equal tables answer every query alike, wherever they live.
impl PartialEq for LodTables {
    fn eq(&self, other: &Self) -> bool {
        (self.p, self.width, self.height) == (other.p, other.width, other.height)
            && self.levels == other.levels
    }
}

impl LodTables {
    /// Builds every data level's tables from scratch (no cache; [`crate::bake`] caches), calling
    /// `progress(k)` as level k starts.
    ///
    /// Heights whose range does not fit an f32 are an [`Error::Terrain`] ([`check_height_range`]).
    pub fn build(
        pyramid: &Pyramid,
        data_levels: u32,
        p: u32,
        mut progress: impl FnMut(u32),
    ) -> Result<Self> {
        let l0 = pyramid.level(0);
        let (w, h) = (l0.width(), l0.height());
        check_height_range(pyramid)?;
        let mut levels = Vec::with_capacity(data_levels as usize);
        for k in 0..data_levels {
            progress(k);
            levels.push(LevelTables::build_level(pyramid, k, p)?);
        }
        Ok(Self {
            p,
            width: w,
            height: h,
            levels,
            mapping: None,
        })
    }

    /// Bytes every level's tables hold.
    pub fn memory_bytes(&self) -> u64 {
        self.levels.iter().map(LevelTables::memory_bytes).sum()
    }

    /// Bytes of the tables held in owned memory: 0 for tables read through a map, whose pages are faulted
    /// in by the queries and dropped by [`LodTables::trim`].
    pub fn owned_bytes(&self) -> u64 {
        self.levels.iter().map(LevelTables::owned_bytes).sum()
    }

    /// Whether the tables borrow a mapped cache file.
    pub fn is_mapped(&self) -> bool {
        self.mapping.is_some()
    }

    /// Drops the table pages the queries so far touched from the resident set (mapped tables; nothing
    /// otherwise). The selector does not call it per frame (a frame would fault the same pages in again):
    /// [`LodTables::limit_resident`] bounds them instead.
    pub fn trim(&self) {
        if let Some(m) = &self.mapping {
            m.trim();
        }
    }

    /// Faults in the mapped tables' smallest grids now, smallest first, while their pages fit `bytes`
    /// (charged against the resident limit as the queries' pages are): the coarse levels' SATs and every
    /// level's coarse max-pyramid levels, which every frame's block selection reads (algorithm 1 starts
    /// from the coarsest level). A first frame would otherwise spend much of its plan time faulting them
    /// in (half of it, in a profile of a 4097^2 terrain's; docs/plan-time.md). Nothing for tables in
    /// memory; the answers are the same bytes either way.
    pub fn prime(&self, bytes: u64) {
        let Some(m) = &self.mapping else {
            return;
        };
        let allowance = bytes / crate::bake::mapped::PAGE_BYTES;
        let mut grids: Vec<(usize, usize)> = Vec::new();
        for (sat, max) in self.levels.iter().filter_map(|l| l.tables.as_ref()) {
            let ranges = std::iter::once(sat.grid().mapped_range())
                .chain(max.levels().iter().map(|g| g.mapped_range()));
            grids.extend(ranges.flatten().map(|(offset, len)| (len, offset)));
        }
        grids.sort_unstable();
        for (len, offset) in grids {
            if !m.prime(offset, len, allowance) {
                break;
            }
        }
    }

    /// Holds at most `bytes` of the mapped tables' pages resident ([`Mapping::limit_resident`]: the
    /// queries trim the map as they go once their pages would pass it); nothing for tables in memory.
    /// The budget is [`crate::profile::CpuSplit::lod_tables`].
    pub fn limit_resident(&self, bytes: u64) {
        if let Some(m) = &self.mapping {
            m.limit_resident(bytes);
        }
    }

    /// The resident limit and the trims it forced (None for tables in memory).
    pub fn resident_stats(&self) -> Option<crate::bake::mapped::ResidentStats> {
        self.mapping.as_ref().map(Mapping::resident_stats)
    }

    /// The tables of data level `k`, or None past the last baked level.
    pub fn level(&self, k: u32) -> Option<&LevelTables> {
        self.levels.get(k as usize)
    }

    /// The data-sample box [x0, x1) x [y0, y1) covering level-0 lattice vertices [a, b] x [c, d] (inclusive),
    /// with `synth` rings finer than the data, clamped to the grid (never empty).
    pub fn data_box(&self, synth: u32, a: i64, c: i64, b: i64, d: i64) -> (u32, u32, u32, u32) {
        let s = synth.min(40);
        let clampx = |v: i64| u32::try_from(v.clamp(0, i64::from(self.width) - 1)).unwrap_or(0);
        let clampy = |v: i64| u32::try_from(v.clamp(0, i64::from(self.height) - 1)).unwrap_or(0);
        let (x0, x1) = (clampx(a >> s), clampx(ceil_shr(b, s)));
        let (y0, y1) = (clampy(c >> s), clampy(ceil_shr(d, s)));
        (x0, y0, x1 + 1, y1 + 1)
    }
}

/// `v / 2^s` rounded up.
pub(crate) fn ceil_shr(v: i64, s: u32) -> i64 {
    -((-v) >> s)
}
