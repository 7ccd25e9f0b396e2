//! Stage 1, bake: the compact per-cell record of a data level's SAT LOD tables, the one
//! definition every path builds its tables from (the resident bake [`LevelTables::build_level`], the
//! streamed bake [`crate::package::lod_stream`], and the package's table tiles).
//!
//! # The record
//!
//! Data level k >= 1 keeps, at level k's resolution (cells of 2^k samples, [`LevelTables`]), two bytes a
//! cell instead of the 12 of a u64 SAT entry and an f32 maximum:
//!
//! - **max code** (per closed cell [c 2^k, (c + 1) 2^k]^2): the cell's maximum error e on a log scale
//!   relative to E_k, [`MAX_STEPS`] codes an octave, **rounded up**: code c in 1..=255 decodes to
//!   E 2^((c - 255) / 16) (code 255 is E itself), 0 means exactly zero. The decoded maximum is never
//!   below the true one and, above the floor E 2^(-254/16) = E / 60,000, within one step (2^(1/16),
//!   4.4 %) of it; below the floor it decodes to the floor.
//! - **mean code** (per half-open cell [c 2^k, (c + 1) 2^k)^2): the cell's sum of quantised (e/E)^p as a
//!   ratio to the most its n samples can hold under the decoded maximum of the closed cell that contains
//!   it, n (M/E)^p, on a log scale of [`MEAN_STEPS`] codes an octave, **rounded down**: code c in 0..=254
//!   decodes to the ratio 2^(-c / 4), 255 to 0. The decoded sum (in SAT quanta, floored) is never above
//!   the cell's true sum, and the true sum is below 2^(1/4) times the decoded one plus two quanta a
//!   sample (plus 2^-63.5 a sample for code 255): [`sum_upper`].
//!
//! Why a ratio to the decoded maximum rather than a code relative to E: the mean of (e/E)^p spans p times
//! as many octaves as e (64 for p = 4 over e/E >= 2^-16), too many for one byte at a useful step, while
//! its ratio to the cell's own maximum spans a few octaves in most cells (a level-1 cell of 4 samples:
//! 2 octaves mostly), so the codes repeat more, which the package's compression rewards, and one byte
//! covers 63.5 octaves.
//!
//! The steps were chosen by the package's size (`clipsat bake --max-error 0.5 --json`, record tiles
//! alone, B/sample, n07 / Big Tujunga): mean codes at 8 an octave 0.457 / 0.490, at 4 an octave 0.412 /
//! 0.439 (the estimate M = E mean^(1/p) within 2^(1/16), 4.4 %, where 8 kept 2.2 %); max codes at 8 an
//! octave would save 0.011 / 0.019 more but round `exact` up by 9 %. Both grids coded as they are:
//! differences from the left neighbour cost 7-9 % (max codes) and 4-8 % (mean codes) more.
//!
//! The query structures are built from the records ([`Coder`]): the u64 SAT of the decoded lower sums in
//! the existing fixed point ([`crate::bake::sat`]) and the max pyramid of the decoded maxima. So `sat`
//! stays <= the true block maximum (its sum is a lower bound), `sat-conservative` >= it (its sum is
//! [`sum_upper`] and its cap the decoded maxima), and `exact` >= it, within one max-code step (or the
//! floor). Every number decodes by multiplications by constants and powers of two only (no libm), so a
//! package decodes to the same bits on every platform, and the encoder checks each code against the
//! decoder itself.
//!
//! [`LevelTables`]: crate::bake::lod_tables::LevelTables
//! [`LevelTables::build_level`]: crate::bake::lod_tables::LevelTables::build_level

use crate::bake::sat::pow_unit;

/// Max-error codes per octave.
pub const MAX_STEPS: u32 = 16;
/// Mean-ratio codes per octave.
pub const MEAN_STEPS: u32 = 4;

/// 2^(-i/16), i = 0..16 (nearest f64; every use is checked by the encoder against the decoder).
const FRAC16: [f64; 16] = [
    1.0,
    0.957_603_280_698_573_7,
    0.917_004_043_204_671_2,
    0.878_126_080_186_649_7,
    0.840_896_415_253_714_5,
    0.805_245_165_974_627_1,
    0.771_105_412_703_970_4,
    0.738_413_072_969_749_7,
    std::f64::consts::FRAC_1_SQRT_2,
    0.677_127_773_468_446_3,
    0.648_419_777_325_504_8,
    0.620_928_906_036_742,
    0.594_603_557_501_360_5,
    0.569_394_317_378_345_8,
    0.545_253_866_332_628_8,
    0.522_136_891_213_706_9,
];

/// 2^(1/4) (1 + 2^-40): one mean-code step, with room for the f64 roundings of the decode.
const MEAN_STEP_UP: f64 = 1.189_207_115_002_721 * (1.0 + 1.0 / (1u64 << 40) as f64);

/// The ratio below which a cell's mean code is 255 (decoded 0): 2^(-254/4), rounded up.
const MEAN_FLOOR: f64 = 7.666_467_083_416_871e-20 * (1.0 + 1.0 / (1u64 << 40) as f64);

/// 2^-o for o < 1023, exactly (built from the exponent bits).
fn pow2_neg(o: u32) -> f64 {
    f64::from_bits(u64::from(1023 - o.min(1022)) << 52)
}

/// 2^(-d/16).
fn step16(d: u32) -> f64 {
    FRAC16[(d % 16) as usize] * pow2_neg(d / 16)
}

/// The mean ratio code `c` decodes to (0 for 255).
fn mean_ratio(c: u8) -> f64 {
    if c == u8::MAX {
        0.0
    } else {
        step16(4 * u32::from(c))
    }
}

/// The smallest code in `lo..=hi` for which `ok` holds, `ok` monotone (false then true); `hi` if none.
fn first(mut lo: u8, mut hi: u8, ok: impl Fn(u8) -> bool) -> u8 {
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if ok(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    hi
}

/// Data level k's records (k >= 1, E > 0): the closed cells' max codes (row-major, closed cells per row
/// x rows) and the half-open cells' mean codes (half-open cells per row x rows), at level k's resolution.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelRecords {
    /// The data level.
    pub k: u32,
    /// E_k, metres (> 0).
    pub e_max: f32,
    /// Max codes, one per closed cell.
    pub max: Vec<u8>,
    /// Mean codes, one per half-open cell.
    pub mean: Vec<u8>,
}

/// One level's coder: encodes the closed cells' maxima and the half-open cells' sums and decodes them
/// into what the query structures hold.
#[derive(Clone, Copy, Debug)]
pub struct Coder {
    e_max: f32,
    /// 1 / E, as the sums' per-sample values are computed ([`crate::bake::lod_tables`]).
    inv: f64,
    p: u32,
    /// 2^Q, the SAT's quanta per unit.
    scale: f64,
    /// Cell shift and the data grid.
    s: u32,
    width: u32,
    height: u32,
}

impl Coder {
    /// The coder of a level with largest error `e_max` (> 0), exponent `p`, SAT quantum 2^-`frac_bits`,
    /// cells of 2^`s` samples over a `width x height` grid.
    pub fn new(e_max: f32, p: u32, frac_bits: u32, s: u32, width: u32, height: u32) -> Self {
        Self {
            e_max,
            inv: 1.0 / f64::from(e_max),
            p,
            scale: pow2_neg(0) / pow2_neg(frac_bits.min(62)),
            s,
            width,
            height,
        }
    }

    /// The maximum error code `c` decodes to, metres (never above E).
    #[expect(
        clippy::cast_possible_truncation,
        reason = "decoded maxima are f32, rounded once (the encoder checks the rounded value)"
    )]
    pub fn max_decode(&self, c: u8) -> f32 {
        if c == 0 {
            return 0.0;
        }
        ((f64::from(self.e_max) * step16(u32::from(u8::MAX - c))) as f32).min(self.e_max)
    }

    /// The smallest code whose decoded maximum is at least `e` (0 for e <= 0; `e` <= E).
    pub fn max_code(&self, e: f32) -> u8 {
        if e.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return 0;
        }
        first(1, u8::MAX, |c| self.max_decode(c) >= e)
    }

    /// Rounds a row of closed-cell maxima up to their codes' decoded values, writing the codes.
    pub fn code_max_row(&self, maxima: &mut [f32], codes: &mut [u8]) {
        for (m, c) in maxima.iter_mut().zip(codes.iter_mut()) {
            *c = self.max_code(*m);
            *m = self.max_decode(*c);
        }
    }

    /// n (M/E)^p 2^Q for a cell of `n` samples under decoded maximum `m`: the largest sum it can hold.
    #[expect(
        clippy::cast_precision_loss,
        reason = "n < 2^53 samples per cell is exact"
    )]
    fn cell_scale(&self, n: u64, m: f32) -> f64 {
        n as f64 * pow_unit(f64::from(m) * self.inv, self.p).min(1.0) * self.scale
    }

    /// The lower sum, in quanta, that mean code `c` decodes to in a cell of reference `scale`.
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a non-negative product below 2^64 (the cell's largest sum), floored"
    )]
    fn lower(c: u8, scale: f64) -> u64 {
        (scale * mean_ratio(c)).floor() as u64
    }

    /// Samples in half-open cell (cx, cy).
    fn cell_samples(&self, cx: u32, cy: u32) -> u64 {
        let side = |c: u32, len: u32| u64::from(((c + 1) << self.s).min(len) - (c << self.s));
        side(cx, self.width) * side(cy, self.height)
    }

    /// Codes half-open cell row `cy`: `sums` are the cells' sums of quantised (e/E)^p (quanta),
    /// `dmax` the decoded maxima of the closed cell row that contains it (row min(cy, rows - 1)). Writes
    /// each cell's code and the lower sum it decodes to.
    pub fn code_mean_row(
        &self,
        cy: u32,
        sums: &[u64],
        dmax: &[f32],
        codes: &mut [u8],
        lower: &mut [u64],
    ) {
        for (cx, ((&sum, c), d)) in
            (0u32..).zip(sums.iter().zip(codes.iter_mut()).zip(lower.iter_mut()))
        {
            let n = self.cell_samples(cx, cy);
            let m = dmax[(cx as usize).min(dmax.len() - 1)];
            let scale = self.cell_scale(n, m);
            // A lower bound of the true sum: each nonzero sample was rounded up by under one quantum.
            let target = sum.saturating_sub(n);
            *c = first(0, u8::MAX, |c| Self::lower(c, scale) <= target);
            *d = Self::lower(*c, scale);
        }
    }

    /// Decodes half-open cell row `cy`'s mean codes into lower sums (as [`Coder::code_mean_row`] wrote).
    pub fn decode_mean_row(&self, cy: u32, codes: &[u8], dmax: &[f32], lower: &mut [u64]) {
        for (cx, (&c, d)) in (0u32..).zip(codes.iter().zip(lower.iter_mut())) {
            let m = dmax[(cx as usize).min(dmax.len() - 1)];
            *d = Self::lower(c, self.cell_scale(self.cell_samples(cx, cy), m));
        }
    }
}

/// An upper bound of the sum of (e/E)^p over a box of `n` samples whose cells' decoded lower sums add up
/// to `raw` quanta of `quantum` (see the module docs: per cell, the true sum is below 2^(1/4) (lower + 1)
/// + n quanta, and below n 2^-63.5 + n quanta where the code is 255).
#[expect(
    clippy::cast_precision_loss,
    reason = "u64 to f64 once; the relative 2^-40 covers it"
)]
pub fn sum_upper(raw: u64, n: u64, quantum: f64) -> f64 {
    let up = 1.0 + 1.0 / (1u64 << 40) as f64;
    (MEAN_STEP_UP * raw as f64 * quantum + n as f64 * ((MEAN_STEP_UP + 1.0) * quantum + MEAN_FLOOR))
        * up
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants_match_their_powers() {
        for (i, f) in FRAC16.iter().enumerate() {
            let want = (-(i as f64) / 16.0).exp2();
            assert!((f - want).abs() <= 2.0 * f64::EPSILON, "{i}");
        }
        assert!(MEAN_STEP_UP >= 0.25f64.exp2());
        assert!(MEAN_FLOOR >= (-254.0f64 / 4.0).exp2());
        assert_eq!(pow2_neg(3), 0.125);
    }

    #[test]
    fn max_codes_round_up_within_a_step() {
        let c = Coder::new(100.0, 4, 40, 1, 9, 9);
        assert_eq!(c.max_code(0.0), 0);
        assert_eq!(c.max_decode(0), 0.0);
        assert_eq!(c.max_code(100.0), 255);
        assert_eq!(c.max_decode(255), 100.0);
        for e in [1e-9f32, 1e-3, 0.01, 0.5, 1.0, 3.3, 49.9, 99.99] {
            let d = c.max_decode(c.max_code(e));
            assert!(d >= e, "{e} -> {d}");
            let floor = 100.0 * (-254.0f32 / 16.0).exp2();
            assert!(d <= (e * 1.045).max(floor * 1.001), "{e} -> {d}");
        }
    }

    #[test]
    fn mean_codes_round_down() {
        let c = Coder::new(10.0, 4, 40, 1, 8, 8);
        let dmax = [10.0f32, 5.0, 2.5, 0.0];
        let one = 1u64 << 40;
        let sums = [4 * one, one / 8, one / 1000, 0];
        let (mut codes, mut lower) = ([0u8; 4], [0u64; 4]);
        c.code_mean_row(0, &sums, &dmax, &mut codes, &mut lower);
        let mut again = [0u64; 4];
        c.decode_mean_row(0, &codes, &dmax, &mut again);
        assert_eq!(lower, again);
        for i in 0..4 {
            assert!(
                lower[i] <= sums[i].saturating_sub(4),
                "{i}: {lower:?} {sums:?}"
            );
            let hi = sum_upper(lower[i], 4, 1.0);
            assert!(hi >= sums[i] as f64, "{i}: {hi} < {}", sums[i]);
        }
        assert!(codes[0] <= 1, "{codes:?}");
    }
}
