//! Stage 1, bake: the height pyramid of GC section 4 - filtered levels, the 4-point prediction U, residuals.
//!
//! Level 0 is the data; level k+1 = D(level k). Sample (i, j) of level k sits on data sample (i 2^k, j 2^k).
//! Beyond the data's edges every level is clamped: the terrain extends flat.

use crate::source::Heightmap;

/// The downsampling filter D: the 5-tap binomial [1, 4, 6, 4, 1] / 16, evaluated at even samples.
///
/// Why not plain decimation: GC section 4 builds the pyramid with a low-pass filter so coarse rings do not
/// alias (a decimated ridge line pops as the viewer moves). The binomial kernel is the cheapest one that
/// reproduces linear functions exactly and has a small second moment (1 sample^2), so the residuals
/// r_k = level_k - U(level_{k+1}) of a smooth surface stay O(h^2 f'') small.
const D_WEIGHTS: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// One pyramid level: a row-major grid, row 0 north, like [`Heightmap`].
#[derive(Clone, Debug, PartialEq)]
pub struct PyramidLevel {
    width: u32,
    height: u32,
    heights: Vec<f32>,
}

impl PyramidLevel {
    /// Samples per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// All samples, row-major.
    pub fn heights(&self) -> &[f32] {
        &self.heights
    }

    /// The sample at (i, j), clamped to the level's edge.
    #[inline]
    #[expect(
        clippy::cast_possible_truncation,
        reason = "clamped into 0..width and 0..height, which are u32"
    )]
    pub fn at_clamped(&self, i: i64, j: i64) -> f32 {
        let x = i.clamp(0, i64::from(self.width) - 1) as usize;
        let y = j.clamp(0, i64::from(self.height) - 1) as usize;
        self.heights[y * self.width as usize + x]
    }
}

/// The height pyramid, finest (the data) first, down to at most 4 x 4 samples.
#[derive(Clone, Debug, PartialEq)]
pub struct Pyramid {
    levels: Vec<PyramidLevel>,
}

impl Pyramid {
    /// Builds every level from the terrain (allocates; a bake-time step).
    pub fn build(terrain: &Heightmap) -> Self {
        let mut levels = vec![PyramidLevel {
            width: terrain.width(),
            height: terrain.height(),
            heights: terrain.heights().to_vec(),
        }];
        loop {
            let last = levels.last().expect("pyramid has a level");
            if last.width <= 4 && last.height <= 4 {
                break;
            }
            let next = downsample(last);
            levels.push(next);
        }
        Self { levels }
    }

    /// A pyramid from levels decoded elsewhere (a package's, [`crate::package::Package::to_pyramid`]),
    /// each `(width, height, heights)` row-major, finest first; panics if a level's samples do not match
    /// its size or there is none (a caller bug).
    pub fn from_levels(levels: Vec<(u32, u32, Vec<f32>)>) -> Self {
        assert!(!levels.is_empty(), "a pyramid has a level");
        let levels = levels
            .into_iter()
            .map(|(width, height, heights)| {
                assert_eq!(
                    heights.len() as u64,
                    u64::from(width) * u64::from(height),
                    "pyramid level size"
                );
                PyramidLevel {
                    width,
                    height,
                    heights,
                }
            })
            .collect();
        Self { levels }
    }

    /// Number of levels.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Never true: the data itself is level 0.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Level `k`; panics past the coarsest.
    pub fn level(&self, k: usize) -> &PyramidLevel {
        &self.levels[k]
    }

    /// The height of level `k` at its sample (i, j), for any k: past the coarsest level the coarsest is
    /// sampled at the same spot (decimated), and coordinates are clamped to the data.
    #[inline]
    pub fn at(&self, k: u32, i: i64, j: i64) -> f32 {
        let last = self.levels.len() - 1;
        let k = k as usize;
        if k <= last {
            self.levels[k].at_clamped(i, j)
        } else {
            // Beyond the coarsest level: sample it at the same place. Shifts stay small (< 64) since
            // k < MAX_LEVELS + synthesised levels.
            let s = u32::try_from(k - last).unwrap_or(63).min(40);
            self.levels[last].at_clamped(i.saturating_mul(1 << s), j.saturating_mul(1 << s))
        }
    }

    /// The residual r_k(i, j) = level_k(i, j) - U(level_{k+1})(i, j) (GC section 4), for k < len - 1.
    pub fn residual(&self, k: usize, i: i64, j: i64) -> f32 {
        let coarse = &self.levels[k + 1];
        self.levels[k].at_clamped(i, j) - predict(|a, b| coarse.at_clamped(a, b), i, j)
    }

    /// Standard deviation of the residuals of level `k` over all its samples, for k < len - 1 (else 0).
    pub fn residual_std(&self, k: usize) -> f64 {
        if k + 1 >= self.levels.len() {
            return 0.0;
        }
        let l = &self.levels[k];
        let (mut sum, mut sum2, mut count) = (0.0f64, 0.0f64, 0.0f64);
        for j in 0..i64::from(l.height) {
            for i in 0..i64::from(l.width) {
                let r = f64::from(self.residual(k, i, j));
                sum += r;
                sum2 += r * r;
                count += 1.0;
            }
        }
        let mean = sum / count;
        (sum2 / count - mean * mean).max(0.0).sqrt()
    }
}

/// The next coarser level of a `width` x `height` level (row-major), as [`Pyramid::build`] filters it:
/// its size and heights (a package set's top, built from its parts' coarsest level).
pub fn coarser(width: u32, height: u32, heights: Vec<f32>) -> (u32, u32, Vec<f32>) {
    let next = downsample(&PyramidLevel {
        width,
        height,
        heights,
    });
    (next.width, next.height, next.heights)
}

/// D: level k -> level k+1, separable binomial filter at the even samples, clamped at the edges.
#[expect(
    clippy::cast_possible_truncation,
    reason = "heights are stored as f32; the f64 sum is rounded once"
)]
fn downsample(fine: &PyramidLevel) -> PyramidLevel {
    let w = (fine.width - 1).div_ceil(2) + 1;
    let h = (fine.height - 1).div_ceil(2) + 1;
    // Horizontal pass: w x fine.height, in f64.
    let mut tmp = vec![0.0f64; w as usize * fine.height as usize];
    for y in 0..i64::from(fine.height) {
        for x in 0..i64::from(w) {
            let mut s = 0.0;
            for (t, wt) in D_WEIGHTS.iter().enumerate() {
                s += wt * f64::from(fine.at_clamped(2 * x + t as i64 - 2, y));
            }
            tmp[y as usize * w as usize + x as usize] = s;
        }
    }
    let fh = i64::from(fine.height) - 1;
    let mut heights = vec![0.0f32; w as usize * h as usize];
    for y in 0..i64::from(h) {
        for x in 0..w as usize {
            let mut s = 0.0;
            for (t, wt) in D_WEIGHTS.iter().enumerate() {
                let yy = (2 * y + t as i64 - 2).clamp(0, fh) as usize;
                s += wt * tmp[yy * w as usize + x];
            }
            heights[y as usize * w as usize + x] = s as f32;
        }
    }
    PyramidLevel {
        width: w,
        height: h,
        heights,
    }
}

/// The 4-point interpolatory rule at an odd position: (-a + 9 b + 9 c - d) / 16 (GC section 4).
#[inline]
fn four_point(a: f64, b: f64, c: f64, d: f64) -> f64 {
    (9.0 * (b + c) - (a + d)) * (1.0 / 16.0)
}

/// U: the fine sample (i, j) predicted from the coarse grid `coarse` (GC section 4).
///
/// Separable, tensor-product 4-point interpolatory subdivision with weights (-1/16, 9/16, 9/16, -1/16):
/// even positions copy the coarse sample, odd positions are predicted; at odd-odd positions the rows are
/// predicted in x first, then the result in y. Arithmetic is f64 with one rounding to f32 at the end, in a
/// fixed order, so the result is the same bits on every platform.
#[inline]
#[expect(
    clippy::cast_possible_truncation,
    reason = "the prediction is stored as f32; the f64 value is rounded once"
)]
pub fn predict(coarse: impl Fn(i64, i64) -> f32, i: i64, j: i64) -> f32 {
    // Arithmetic shifts are floor divisions, right for negative coordinates too.
    let (ci, cj) = (i >> 1, j >> 1);
    let row = |jj: i64| -> f64 {
        if i & 1 == 0 {
            f64::from(coarse(ci, jj))
        } else {
            four_point(
                f64::from(coarse(ci - 1, jj)),
                f64::from(coarse(ci, jj)),
                f64::from(coarse(ci + 1, jj)),
                f64::from(coarse(ci + 2, jj)),
            )
        }
    };
    let v = if j & 1 == 0 {
        row(cj)
    } else {
        four_point(row(cj - 1), row(cj), row(cj + 1), row(cj + 2))
    };
    v as f32
}
