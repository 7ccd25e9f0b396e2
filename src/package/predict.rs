//! Stage 1b, the package: the prediction of a height from the coarser level and its decoded neighbours
//! (`docs/package-codec.md`, "Prediction").
//!
//! Heights are integers k in units of the package's quantum. A sample of level l is predicted in two
//! parts, both in exact integer arithmetic so that the encoder and every decoder agree bit for bit:
//!
//! - U, the 4-point subdivision of the reconstructed coarser level k~_{l+1} (GC sections 4 and 7: closed
//!   loop, so quantisation errors do not accumulate down the pyramid), as [`crate::bake::pyramid::predict`]
//!   with one rounding;
//! - a correction, a linear combination with the level's integer weights ([`LevelModel`]) of
//!   [`TAPS`] features: the decoded residual field r = k~ - U at six causal neighbours in the tile
//!   (the LOCO-I / CALIC idea of predicting from the causal template: Weinberger, Seroussi and Sapiro
//!   2000; Wu and Memon 1997) and the differences of U at the eight neighbours from U at the sample
//!   (the coarse level's local shape, which corrects U's fixed interpolation). The weights are fitted per
//!   level and per sample parity by least squares at bake time (least-squares prediction as in Li and
//!   Orchard 2001, "Edge-directed prediction for lossless compression of natural images", but fitted
//!   once per level by the encoder instead of per sample by both sides), stored in the header as
//!   integers over 256.
//!
//! A neighbour outside the tile counts as r = 0 (k~ = U there), so a tile decodes from its own bytes and
//! the coarser level alone.

/// Features per sample: six causal residuals, eight differences of U.
pub const TAPS: usize = 14;

/// The causal residual taps, (dx, dy): W, N, NW, NE, WW, NN.
pub const R_TAPS: [(i32, i32); 6] = [(-1, 0), (0, -1), (-1, -1), (1, -1), (-2, 0), (0, -2)];

/// The U taps, (dx, dy): U there minus U at the sample.
pub const U_TAPS: [(i32, i32); 8] = [
    (1, 0),
    (0, 1),
    (1, 1),
    (-1, 1),
    (-1, 0),
    (0, -1),
    (-1, -1),
    (1, -1),
];

/// Fixed-point weights: a weight w is stored as round(256 w).
pub const WEIGHT_BITS: u32 = 8;

/// Largest |k| a package stores (heights over the quantum), and the clamp of every prediction: sums of
/// features stay far inside i64, reconstructions inside i32.
pub const MAX_UNITS: i64 = 1 << 30;

/// A level's prediction and quantisation: the residual step and the weights per sample parity.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelModel {
    /// The step of the quantised residuals, in quanta (1: lossless at the quantum; 2N + 1: JPEG-LS NEAR).
    pub step: u32,
    /// Weights over 2^WEIGHT_BITS, per parity (x & 1) + 2 (y & 1), per feature.
    pub weights: [[i16; TAPS]; 4],
}

impl LevelModel {
    /// U alone with the given step (no correction).
    pub fn plain(step: u32) -> Self {
        Self {
            step,
            weights: [[0; TAPS]; 4],
        }
    }

    /// The prediction from U and the features of a sample of parity `par`, clamped to [`MAX_UNITS`].
    #[inline]
    pub fn predict(&self, par: usize, u: i64, f: &[i64; TAPS]) -> i64 {
        let w = &self.weights[par & 3];
        let mut s = 0i64;
        for (&wi, &fi) in w.iter().zip(f) {
            s += i64::from(wi) * fi;
        }
        (u + ((s + (1 << (WEIGHT_BITS - 1))) >> WEIGHT_BITS)).clamp(-MAX_UNITS, MAX_UNITS)
    }
}

/// Least-squares accumulation of a level's weights: the normal equations per parity.
#[derive(Clone, Debug)]
pub struct Fit {
    ata: Vec<[[f64; TAPS]; TAPS]>,
    atb: Vec<[f64; TAPS]>,
    n: [u64; 4],
}

impl Default for Fit {
    fn default() -> Self {
        Self {
            ata: vec![[[0.0; TAPS]; TAPS]; 4],
            atb: vec![[0.0; TAPS]; 4],
            n: [0; 4],
        }
    }
}

/// Fewest samples of a parity for which weights are fitted (fewer: U alone).
const MIN_FIT: u64 = 256;

impl Fit {
    /// One sample of parity `par`: its features and its residual y = k - U.
    pub fn add(&mut self, par: usize, f: &[f64; TAPS], y: f64) {
        let (a, b) = (&mut self.ata[par], &mut self.atb[par]);
        for i in 0..TAPS {
            b[i] += f[i] * y;
            for j in i..TAPS {
                a[i][j] += f[i] * f[j];
            }
        }
        self.n[par] += 1;
    }

    /// Parity `par`'s sums taken from `other`: a thread that fitted that parity alone, over the same
    /// samples in the same order, made the same sums.
    pub fn take_parity(&mut self, other: &Self, par: usize) {
        self.ata[par] = other.ata[par];
        self.atb[par] = other.atb[par];
        self.n[par] = other.n[par];
    }

    /// The fitted weights (ridge-regularised normal equations, Gaussian elimination with partial
    /// pivoting), rounded to fixed point and clamped to i16; a parity with too few samples or a singular
    /// system keeps U alone.
    pub fn weights(&self) -> [[i16; TAPS]; 4] {
        let mut out = [[0i16; TAPS]; 4];
        for (p, o) in out.iter_mut().enumerate() {
            if self.n[p] < MIN_FIT {
                continue;
            }
            // The upper triangle mirrored; a small ridge keeps an all-zero feature (a tile edge, a flat
            // level) from making the system singular.
            let mut a = self.ata[p];
            for (i, row) in a.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = self.ata[p][i.min(j)][i.max(j)];
                }
                row[i] += 1e-3 + 1e-6 * row[i];
            }
            if let Some(w) = solve(a, self.atb[p]) {
                for (oi, wi) in o.iter_mut().zip(w) {
                    let v = (wi * f64::from(1u32 << WEIGHT_BITS)).round();
                    #[expect(clippy::cast_possible_truncation, reason = "clamped to i16 first")]
                    let v = v.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16;
                    *oi = v;
                }
            }
        }
        out
    }
}

/// Solves a x = b; `None` when singular or not finite.
fn solve(mut a: [[f64; TAPS]; TAPS], mut b: [f64; TAPS]) -> Option<[f64; TAPS]> {
    for c in 0..TAPS {
        let p = (c..TAPS).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))?;
        a.swap(c, p);
        b.swap(c, p);
        let d = a[c][c];
        if d.abs() < 1e-12 || !d.is_finite() {
            return None;
        }
        let (pivot, bc) = (a[c], b[c]);
        for (r, (row, br)) in a.iter_mut().zip(b.iter_mut()).enumerate() {
            if r != c {
                let f = row[c] / d;
                for (x, &y) in row[c..].iter_mut().zip(&pivot[c..]) {
                    *x -= f * y;
                }
                *br -= f * bc;
            }
        }
    }
    let mut x = [0.0; TAPS];
    for i in 0..TAPS {
        x[i] = b[i] / a[i][i];
        if !x[i].is_finite() {
            return None;
        }
    }
    Some(x)
}

/// U: the fine sample (i, j) predicted from the coarse grid, in quantum units (GC sections 4 and 7).
///
/// Weights (-1, 9, 9, -1) / 16 separably: even positions copy, odd ones interpolate; the sum is kept in
/// units of 1/256 and rounded half up once ((v + 128) div 256, a floor division).
#[inline]
pub fn predict_int(coarse: impl Fn(i64, i64) -> i64, i: i64, j: i64) -> i64 {
    let (ci, cj) = (i >> 1, j >> 1);
    let row = |jj: i64| -> i64 {
        if i & 1 == 0 {
            16 * coarse(ci, jj)
        } else {
            9 * (coarse(ci, jj) + coarse(ci + 1, jj)) - coarse(ci - 1, jj) - coarse(ci + 2, jj)
        }
    };
    let v = if j & 1 == 0 {
        16 * row(cj)
    } else {
        9 * (row(cj) + row(cj + 1)) - row(cj - 1) - row(cj + 2)
    };
    (v + 128).div_euclid(256)
}

/// The fast form of [`predict_int`] over a whole tile: U of the fine rectangle (x0, y0, tw, th), with the
/// coarse samples gathered once through `coarse` (which clamps), then two separable passes.
///
/// Holds its scratch, sized once for tiles of side `tile`; bit-identical to [`predict_int`] (tested).
pub struct Predictor {
    gathered: Vec<i64>,
    rows: Vec<i64>,
    tile: usize,
}

impl Predictor {
    /// Scratch for tiles of up to `tile` x `tile` samples.
    pub fn new(tile: u32) -> Self {
        let t = tile as usize;
        let p = t / 2 + 4;
        Self {
            gathered: vec![0; p * p],
            rows: vec![0; p * t],
            tile: t,
        }
    }

    /// Writes U(coarse) at fine samples x0..x0+tw, y0..y0+th (x0, y0 even) into `out`, row-major.
    ///
    /// Panics if the rectangle is larger than the tile size or `out` is not tw * th (caller bugs).
    pub fn predict(
        &mut self,
        coarse: impl Fn(i64, i64) -> i64,
        (x0, y0): (i64, i64),
        (tw, th): (usize, usize),
        out: &mut [i64],
    ) {
        assert!(
            tw <= self.tile
                && th <= self.tile
                && out.len() == tw * th
                && x0 & 1 == 0
                && y0 & 1 == 0,
            "predict: a {tw} x {th} tile at ({x0}, {y0}) does not fit {} or out",
            self.tile
        );
        // Coarse columns cx0 .. cx0 + pw cover every 4-point stencil of the fine columns.
        let (pw, ph) = (tw / 2 + 4, th / 2 + 4);
        let (cx0, cy0) = ((x0 >> 1) - 1, (y0 >> 1) - 1);
        let g = &mut self.gathered[..pw * ph];
        for (r, row) in g.chunks_exact_mut(pw).enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = coarse(cx0 + c as i64, cy0 + r as i64);
            }
        }
        // Horizontal pass: each coarse row to fine columns, in units of 1/16.
        let h = &mut self.rows[..ph * tw];
        for (grow, hrow) in g.chunks_exact(pw).zip(h.chunks_exact_mut(tw)) {
            for (i, v) in hrow.iter_mut().enumerate() {
                let c = i / 2 + 1;
                *v = if i & 1 == 0 {
                    16 * grow[c]
                } else {
                    9 * (grow[c] + grow[c + 1]) - grow[c - 1] - grow[c + 2]
                };
            }
        }
        // Vertical pass, in units of 1/256, rounded half up (floor of v + 128 over 256).
        for (j, orow) in out.chunks_exact_mut(tw).enumerate() {
            let c = j / 2 + 1;
            let row = |k: usize| &h[k * tw..(k + 1) * tw];
            if j & 1 == 0 {
                for (o, &a) in orow.iter_mut().zip(row(c)) {
                    *o = (16 * a + 128) >> 8;
                }
            } else {
                let (a, b, cc, d) = (row(c - 1), row(c), row(c + 1), row(c + 2));
                for (i, o) in orow.iter_mut().enumerate() {
                    *o = (9 * (b[i] + cc[i]) - a[i] - d[i] + 128) >> 8;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_reproduces_linear_and_copies_even() {
        // A linear ramp in coarse units doubles in fine units: U reproduces it exactly.
        let c = |a: i64, b: i64| 10 * a + 3 * b;
        for j in 0..8 {
            for i in 0..8 {
                let p = predict_int(c, i, j);
                // Fine (i, j) sits at coarse (i/2, j/2): 10 i/2 + 3 j/2, rounded half up.
                assert_eq!(p, (10 * i + 3 * j + 1).div_euclid(2), "at ({i}, {j})");
            }
        }
    }

    #[test]
    fn fast_prediction_matches_reference() {
        let c = |a: i64, b: i64| {
            let (a, b) = (a.clamp(0, 40), b.clamp(0, 30));
            (a * 7919 + b * 104_729) % 2001 - 1000
        };
        let mut p = Predictor::new(16);
        for (x0, y0, tw, th) in [
            (0, 0, 16, 16),
            (16, 32, 16, 7),
            (48, 16, 5, 16),
            (80, 60, 3, 2),
        ] {
            let mut out = vec![0; tw * th];
            p.predict(c, (x0, y0), (tw, th), &mut out);
            for j in 0..th {
                for i in 0..tw {
                    let (fi, fj) = (x0 + i as i64, y0 + j as i64);
                    assert_eq!(out[j * tw + i], predict_int(c, fi, fj), "at ({fi}, {fj})");
                }
            }
        }
    }

    #[test]
    fn fitted_weights_recover_a_linear_rule() {
        // y = 0.5 f0 + 0.25 f6 exactly: the fit finds 128 and 64.
        let mut fit = Fit::default();
        for k in 0..2000i64 {
            let mut f = [0.0; TAPS];
            f[0] = ((k * 7919) % 61 - 30) as f64;
            f[6] = ((k * 104_729) % 37 - 18) as f64;
            f[3] = ((k * 13) % 5) as f64;
            fit.add(1, &f, 0.5 * f[0] + 0.25 * f[6]);
        }
        let w = fit.weights();
        assert_eq!((w[1][0], w[1][6], w[1][3]), (128, 64, 0));
        assert_eq!(w[0], [0; TAPS], "too few samples: U alone");
        let m = LevelModel {
            step: 1,
            weights: w,
        };
        let mut f = [0i64; TAPS];
        f[0] = 10;
        f[6] = -4;
        assert_eq!(m.predict(1, 100, &f), 104);
        f[0] = i64::from(i32::MAX);
        assert_eq!(m.predict(1, 100, &f), MAX_UNITS, "clamped");
    }
}
