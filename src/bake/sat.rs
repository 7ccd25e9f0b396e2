//! Stage 1, bake: summed-area tables in exact u64 fixed point (docs/design.md "SAT LOD" 2 and 4; Li et al. 2021).
//!
//! A generic SAT over a `width x height` grid of values in [0, 1], answering box sums in O(1) (four
//! lookups). Used for the LOD error SATs of (e_L / E_L)^p ([`crate::bake::lod_tables`]), and meant for the normal and
//! visibility SATs too (map each channel into [0, 1] first, e.g. (n + 1) / 2).
//!
//! # Representation, and why
//!
//! Each value v is quantised **up** to an integer q = ceil(v 2^Q) (Q = [`Sat::frac_bits`], the quantum is
//! 2^-Q), and the table holds inclusive prefix sums of q in `u64` with wrapping arithmetic. A box sum is a
//! corner difference computed modulo 2^64, which is the exact integer sum of the box's q whenever that sum
//! is below 2^64; [`Sat::build`] refuses a Q for which the whole grid's sum could reach 2^64
//! (N 2^Q >= 2^64 for N samples), so **every box sum is exact integer arithmetic**, however large the grid.
//! The only error is the quantisation, one-sided and bounded per sample:
//!
//! ```text
//! 0 <= box_sum - sum(v) < n 2^-Q      (n = samples in the box; exactly 0 for samples with v = 0)
//! ```
//!
//! plus one f64 rounding (relative 2^-53) when the integer is turned into a float by [`Sat::box_sum`].
//! [`Sat::box_bounds`] returns a certain enclosure [lo, hi] of sum(v). Rounding up means a nonzero sample
//! never vanishes: a one-sample needle whose (e/E)^p underflows still adds one quantum to its box, which is
//! what keeps a conservative bound conservative.
//!
//! The alternatives, measured against the 16385^2 case of docs/design.md:
//!
//! - a raw f32 SAT reaches 2.7e8 with a 24-bit mantissa (ulp 16 at the top): corner differences of a small
//!   block lose every digit;
//! - an f64 SAT keeps about 1e-7 absolute there, but the error of a corner difference grows with the
//!   position in the grid, not with the box, so a box of tiny values far from the origin is still noise;
//! - tiled local prefix sums or a mean-offset SAT (Hensley et al. 2005) shrink the magnitudes but keep a
//!   floating-point, position-dependent error.
//!
//! The u64 fixed point has a position-independent error, exact integer differences, and a guaranteed
//! direction of rounding; its price is the quantum: with [`Sat::max_frac_bits`], Q = 63 - floor(log2 N), so
//! 2^-43 for a 1025^2 grid and 2^-35 for 16385^2. `tests/cpu/sat.rs` measures the error against f64 and exact
//! integer brute-force sums.
//!
//! # Memory
//!
//! 8 bytes per table entry. With `cell = 1` that is 8 bytes per sample: 8.4 MB for 1025^2, 134 MB for
//! 4097^2, 2.1 GB for 16385^2 (too much per level). A `cell = c > 1` table sums c x c cells and answers
//! only cell-aligned boxes, in 8 / c^2 bytes per sample (16385^2 with c = 16: 8.4 MB); the quantisation is
//! still per sample, so the error bound above is unchanged.

use crate::bake::mapped::Grid;
use crate::{Error, Result};

/// A summed-area table of values in [0, 1], in exact u64 fixed point (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sat {
    /// Samples per row and rows.
    samples_w: u32,
    samples_h: u32,
    /// Cell side, in samples; the table has one entry per cell.
    cell: u32,
    /// Table entries per row and rows (cells, the last ones possibly partial).
    cols: u32,
    rows: u32,
    frac_bits: u32,
    /// Inclusive prefix sums over cells, row-major, wrapping.
    table: Grid<u64>,
}

/// x^p for x in [0, 1], by repeated squaring in f64: no libm call (bit-identical everywhere), no trap.
///
/// x <= 0 (or NaN) gives 0; x >= 1 gives 1. A positive x whose power underflows gives `f64::MIN_POSITIVE`
/// instead of 0, so a nonzero error is never lost before quantisation (which rounds it up to one quantum).
/// The result is within p ulps (relative p 2^-53) of the true power.
pub fn pow_unit(x: f64, p: u32) -> f64 {
    // NaN fails `x > 0` and lands here too.
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let (mut base, mut e, mut acc) = (x, p, 1.0f64);
    while e > 0 {
        if e & 1 == 1 {
            acc *= base;
        }
        base *= base;
        e >>= 1;
    }
    acc.max(f64::MIN_POSITIVE)
}

impl Sat {
    /// The finest quantum that keeps every box sum of an N-sample grid of values <= 1 below 2^64:
    /// Q = 63 - floor(log2 N), capped at 62.
    pub fn max_frac_bits(samples: u64) -> u32 {
        (63 - samples.max(1).ilog2()).min(62)
    }

    /// Builds the table of `f(x, y)` for every sample (x in 0..width, y in 0..height), each quantised up to a
    /// multiple of 2^-`frac_bits`, summed over `cell x cell` cells.
    ///
    /// Errors: an empty grid, `cell == 0`, or `frac_bits` too fine for the grid (N 2^Q >= 2^64, see
    /// [`Sat::max_frac_bits`]). Panics if `f` returns a value outside [0, 1] or NaN: the caller's
    /// normalisation is broken.
    pub fn build(
        width: u32,
        height: u32,
        cell: u32,
        frac_bits: u32,
        f: impl Fn(u32, u32) -> f64,
    ) -> Result<Self> {
        let n = u64::from(width) * u64::from(height);
        if n == 0 || cell == 0 {
            return Err(Error::Invalid {
                what: "sat size".into(),
                reason: format!("{width} x {height} samples in cells of {cell}: nothing to sum"),
            });
        }
        if frac_bits > Self::max_frac_bits(n) {
            return Err(Error::Invalid {
                what: "sat frac_bits".into(),
                reason: format!(
                    "2^-{frac_bits} is too fine for {n} samples: sums could reach 2^64 (at most {} bits)",
                    Self::max_frac_bits(n)
                ),
            });
        }
        let cols = width.div_ceil(cell);
        let rows = height.div_ceil(cell);
        let scale = pow2(frac_bits);
        let mut sums = vec![0u64; cols as usize * rows as usize];
        for (cy, cell_row) in (0..rows).zip(sums.chunks_mut(cols as usize)) {
            for y in cy * cell..((cy + 1) * cell).min(height) {
                for (cx, acc) in cell_row.iter_mut().enumerate() {
                    let cx = u32::try_from(cx).expect("cols fit u32");
                    for x in cx * cell..((cx + 1) * cell).min(width) {
                        let v = f(x, y);
                        *acc = acc.wrapping_add(quantise(v, scale, x, y));
                    }
                }
            }
        }
        Self::from_cell_sums(width, height, cell, frac_bits, sums)
    }

    /// Builds the table from each cell's sum of quantised values (in quanta, as [`Sat::quantise_up`] gives
    /// them), row-major over the `width.div_ceil(cell) x height.div_ceil(cell)` cells: the same table
    /// [`Sat::build`] makes, for callers that sum the cells themselves (in parallel, or one tile at a time).
    ///
    /// Errors as [`Sat::from_parts`].
    pub fn from_cell_sums(
        width: u32,
        height: u32,
        cell: u32,
        frac_bits: u32,
        mut sums: Vec<u64>,
    ) -> Result<Self> {
        let cols = width.div_ceil(cell.max(1)) as usize;
        // Inclusive prefix in place: row prefix plus the row above (wrapping: exact below 2^64).
        for i in 0..sums.len() {
            let (cx, cy) = (i % cols, i / cols);
            let left = if cx > 0 { sums[i - 1] } else { 0 };
            let above = if cy > 0 { sums[i - cols] } else { 0 };
            let diag = if cx > 0 && cy > 0 {
                sums[i - cols - 1]
            } else {
                0
            };
            sums[i] = sums[i]
                .wrapping_add(left)
                .wrapping_add(above)
                .wrapping_sub(diag);
        }
        Self::from_parts(width, height, cell, frac_bits, sums)
    }

    /// ceil(v 2^`frac_bits`) for v in [0, 1]: one sample's quantised value, in quanta. Panics outside
    /// [0, 1] or on NaN (a broken normalisation), naming the sample (x, y).
    #[inline]
    pub fn quantise_up(v: f64, frac_bits: u32, x: u32, y: u32) -> u64 {
        quantise(v, pow2(frac_bits.min(62)), x, y)
    }

    /// Rebuilds a table from its parts (as [`Sat::table`] and the accessors return them), e.g. from a
    /// cache file; errors if the table length does not match the grid.
    pub fn from_parts(
        width: u32,
        height: u32,
        cell: u32,
        frac_bits: u32,
        table: Vec<u64>,
    ) -> Result<Self> {
        Self::from_grid(width, height, cell, frac_bits, Grid::owned(table))
    }

    /// [`Sat::from_parts`] over a table that may live in a memory-mapped cache file
    /// ([`crate::bake::mapped`]).
    pub fn from_grid(
        width: u32,
        height: u32,
        cell: u32,
        frac_bits: u32,
        table: Grid<u64>,
    ) -> Result<Self> {
        let n = u64::from(width) * u64::from(height);
        if n == 0 || cell == 0 || frac_bits > Self::max_frac_bits(n) {
            return Err(Error::Invalid {
                what: "sat parts".into(),
                reason: format!("{width} x {height}, cell {cell}, 2^-{frac_bits}: invalid"),
            });
        }
        let (cols, rows) = (width.div_ceil(cell), height.div_ceil(cell));
        if table.len() as u64 != u64::from(cols) * u64::from(rows) {
            return Err(Error::Invalid {
                what: "sat parts".into(),
                reason: format!("{} entries for {cols} x {rows} cells", table.len()),
            });
        }
        Ok(Self {
            samples_w: width,
            samples_h: height,
            cell,
            cols,
            rows,
            frac_bits,
            table,
        })
    }

    /// Samples per row.
    pub fn width(&self) -> u32 {
        self.samples_w
    }

    /// Rows of samples.
    pub fn height(&self) -> u32 {
        self.samples_h
    }

    /// Cell side in samples (1: every box is answerable).
    pub fn cell(&self) -> u32 {
        self.cell
    }

    /// Q: values are quantised up to multiples of 2^-Q.
    pub fn frac_bits(&self) -> u32 {
        self.frac_bits
    }

    /// The quantum 2^-Q.
    pub fn quantum(&self) -> f64 {
        (0.5f64).powi(i32::try_from(self.frac_bits).expect("frac_bits <= 62"))
    }

    /// The raw inclusive prefix sums over cells, row-major (for caching).
    pub fn table(&self) -> &[u64] {
        &self.table
    }

    /// The table as stored (owned, or borrowed from a mapped cache file).
    pub fn grid(&self) -> &Grid<u64> {
        &self.table
    }

    /// Bytes the table takes.
    pub fn memory_bytes(&self) -> u64 {
        self.table.len() as u64 * 8
    }

    /// Bytes of the table held in owned memory (0 when it borrows a mapped cache file).
    pub fn owned_bytes(&self) -> u64 {
        self.table.owned_bytes()
    }

    #[inline]
    fn prefix(&self, cx: u32, cy: u32) -> u64 {
        // Prefix over cells [0, cx) x [0, cy).
        if cx == 0 || cy == 0 {
            0
        } else {
            let i = (cy - 1) as usize * self.cols as usize + (cx - 1) as usize;
            // A mapped table counts its pages against its resident limit (bake::mapped).
            self.table.touch(i);
            self.table[i]
        }
    }

    /// The cell index of a box edge, which must be on a cell boundary or at the grid's end.
    #[inline]
    fn edge(&self, s: u32, end: u32, axis: &str) -> u32 {
        assert!(
            s <= end && (s.is_multiple_of(self.cell) || s == end),
            "SAT box {axis} edge {s} is off the {}-sample cell grid or past {end}",
            self.cell
        );
        s.div_ceil(self.cell)
    }

    /// The exact sum of the quantised values (in quanta) over samples [x0, x1) x [y0, y1).
    ///
    /// Panics if the box is reversed, past the grid, or (for `cell > 1`) off the cell grid: a caller bug.
    #[inline]
    pub fn box_sum_raw(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> u64 {
        assert!(x0 <= x1 && y0 <= y1, "SAT box is reversed");
        let (a, b) = (
            self.edge(x0, self.samples_w, "x"),
            self.edge(x1, self.samples_w, "x"),
        );
        let (c, d) = (
            self.edge(y0, self.samples_h, "y"),
            self.edge(y1, self.samples_h, "y"),
        );
        debug_assert!(b <= self.cols && d <= self.rows);
        // Modular arithmetic: exact because the true sum is below 2^64 (checked in `build`).
        self.prefix(b, d)
            .wrapping_sub(self.prefix(a, d))
            .wrapping_sub(self.prefix(b, c))
            .wrapping_add(self.prefix(a, c))
    }

    /// The sum of the quantised values over [x0, x1) x [y0, y1), as f64 (relative error 2^-53 from the
    /// conversion on top of the one-sided quantisation: sum(v) <= result (1 + 2^-53)).
    #[inline]
    #[expect(
        clippy::cast_precision_loss,
        reason = "the u64 is rounded to f64 once; the error is documented"
    )]
    pub fn box_sum(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> f64 {
        self.box_sum_raw(x0, y0, x1, y1) as f64 * self.quantum()
    }

    /// A certain enclosure [lo, hi] of the sum of the original values over [x0, x1) x [y0, y1).
    ///
    /// hi rounds the quantised sum up; lo subtracts one quantum per sample (the most rounding up can add)
    /// and rounds down, clamped at 0.
    #[inline]
    #[expect(
        clippy::cast_precision_loss,
        reason = "u64 to f64, then nudged one ulp outward"
    )]
    pub fn box_bounds(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> (f64, f64) {
        let raw = self.box_sum_raw(x0, y0, x1, y1);
        let n = u64::from(x1 - x0) * u64::from(y1 - y0);
        let q = self.quantum();
        let hi = next_up(raw as f64) * q;
        let lo = next_down(raw.saturating_sub(n) as f64).max(0.0) * q;
        (lo, hi)
    }
}

/// ceil(v 2^Q) for v in [0, 1]; `scale` = 2^Q, so the product is exact and the ceiling is the only rounding.
#[inline]
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_precision_loss,
    reason = "v in [0, 1] and scale <= 2^62: the ceiling is a non-negative integer below 2^64"
)]
fn quantise(v: f64, scale: f64, x: u32, y: u32) -> u64 {
    assert!(
        (0.0..=1.0).contains(&v),
        "SAT value {v} at sample ({x}, {y}) is outside [0, 1] (or NaN): normalise before building"
    );
    // The ceiling without the libm call `f64::ceil` is on the x86-64 baseline (no SSE4.1), a sixth of
    // a bake's time with `powi`'s: the conversion truncates, and it is exact, as is `t as f64`, below
    // 2^53; from 2^53 on every f64 is an integer and t equals it.
    let p = v * scale;
    let t = p as u64;
    t + u64::from((t as f64) < p)
}

/// 2^`bits` (at most 63), exactly, without `powi`'s libm call.
#[expect(
    clippy::cast_precision_loss,
    reason = "a power of two is exact in f64"
)]
fn pow2(bits: u32) -> f64 {
    (1u64 << bits) as f64
}

/// The next f64 above a finite non-negative `v`.
fn next_up(v: f64) -> f64 {
    if v == 0.0 {
        f64::from_bits(1)
    } else {
        f64::from_bits(v.to_bits() + 1)
    }
}

/// The next f64 below a finite non-negative `v` (0 stays 0).
fn next_down(v: f64) -> f64 {
    if v == 0.0 {
        0.0
    } else {
        f64::from_bits(v.to_bits() - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the libm ceiling of a value in [0, 2^62], as `quantise` was"
    )]
    fn quantise_is_the_ceiling() {
        let mut x = 0x9e37_79b9_7f4a_7c15_u64;
        for q in [0, 1, 20, 31, 52, 53, 54, 62] {
            assert_eq!(pow2(q), 2.0f64.powi(i32::try_from(q).expect("q")));
            let mut cases = vec![0.0, 1.0, 0.5, f64::MIN_POSITIVE, 1.0 - f64::EPSILON / 2.0];
            for _ in 0..20_000 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Values in [0, 1) over many magnitudes, and multiples of the quantum.
                let v = f64::from_bits((0x3c0 + (x >> 52) % 0x3f) << 52 | (x & ((1 << 52) - 1)));
                cases.push(v);
                cases.push((v * pow2(q)).floor() / pow2(q));
            }
            for v in cases.into_iter().filter(|v| (0.0..=1.0).contains(v)) {
                assert_eq!(quantise(v, pow2(q), 0, 0), (v * pow2(q)).ceil() as u64, "{v} at Q {q}");
            }
        }
    }

    #[test]
    fn small_exact() {
        let f = |x: u32, y: u32| f64::from(x + 3 * y) / 64.0;
        let sat = Sat::build(7, 5, 1, 20, f).expect("sat");
        for (x0, y0, x1, y1) in [(0, 0, 7, 5), (1, 2, 4, 5), (3, 3, 3, 4), (6, 4, 7, 5)] {
            let mut s = 0.0;
            for y in y0..y1 {
                for x in x0..x1 {
                    s += f(x, y);
                }
            }
            assert_eq!(sat.box_sum(x0, y0, x1, y1), s);
        }
        let cells = Sat::build(7, 5, 2, 20, f).expect("sat");
        assert_eq!(cells.box_sum(2, 0, 7, 4), sat.box_sum(2, 0, 7, 4));
        assert_eq!(cells.box_sum(0, 0, 7, 5), sat.box_sum(0, 0, 7, 5));
    }

    #[test]
    fn pow_unit_edges() {
        assert_eq!(pow_unit(0.0, 64), 0.0);
        assert_eq!(pow_unit(f64::NAN, 2), 0.0);
        assert_eq!(pow_unit(1.0, 64), 1.0);
        assert_eq!(pow_unit(0.5, 2), 0.25);
        assert_eq!(pow_unit(1e-10, 64), f64::MIN_POSITIVE);
        assert_eq!(pow_unit(0.5, 64), (0.5f64).powi(64));
    }
}
