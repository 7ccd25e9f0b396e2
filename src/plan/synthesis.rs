//! Stage 2, the per-frame fill below the data's resolution: fractal detail synthesis (GC section 8).
//!
//! A ring finer than the data gets z = U(coarser ring) + sigma_l * noise(l, i, j). The noise is a fixed
//! 50 x 50 table of unit Gaussian samples (GC section 8 uses a 50 x 50 table too), looked up through a hash
//! of the lattice coordinates, so the fill is a pure function of (level, i, j) with no visible tiling.

use crate::bake::pyramid::predict;

/// Side of the noise table.
pub const NOISE_SIDE: usize = 50;

/// The seed of the shipped noise table; changing it changes every synthesised height (and frame hashes).
pub const NOISE_SEED: u64 = 0x6C69_7073_6174_0008;

/// A fixed table of deterministic, zero-mean, unit-variance Gaussian-like samples.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseTable {
    values: [f32; NOISE_SIDE * NOISE_SIDE],
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl NoiseTable {
    /// The table for `seed`.
    ///
    /// Each entry is an Irwin-Hall sum of 12 uniforms minus 6 (mean 0, variance 1, very close to a Gaussian),
    /// then the table is normalised to mean 0 and standard deviation 1. This uses only +, -, *, / and sqrt,
    /// which IEEE 754 rounds exactly, so the table is the same bits everywhere - Box-Muller's ln and cos
    /// would depend on the platform's libm.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "the table is stored as f32"
    )]
    pub fn new(seed: u64) -> Self {
        let mut state = seed;
        let mut raw = [0.0f64; NOISE_SIDE * NOISE_SIDE];
        for v in raw.iter_mut() {
            let mut s = 0.0;
            for _ in 0..12 {
                // 53 random bits -> [0, 1), exactly representable.
                s += (splitmix64(&mut state) >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
            }
            *v = s - 6.0;
        }
        let n = raw.len() as f64;
        let mean = raw.iter().sum::<f64>() / n;
        let var = raw.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
        let inv_sd = 1.0 / var.sqrt();
        let mut values = [0.0f32; NOISE_SIDE * NOISE_SIDE];
        for (o, v) in values.iter_mut().zip(raw) {
            *o = ((v - mean) * inv_sd) as f32;
        }
        Self { values }
    }

    /// All entries, row-major.
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// The noise at level-`level` lattice sample (i, j): a table entry picked by a hash of (level, i, j).
    #[inline]
    #[expect(
        clippy::cast_possible_truncation,
        reason = "the index is reduced modulo the table size first"
    )]
    pub fn at(&self, level: u32, i: i64, j: i64) -> f32 {
        let mut z = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ u64::from(level).wrapping_mul(0x1656_67B1_9E37_79F9);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        self.values[(z % (NOISE_SIDE * NOISE_SIDE) as u64) as usize]
    }
}

impl Default for NoiseTable {
    fn default() -> Self {
        Self::new(NOISE_SEED)
    }
}

/// Per-octave decay of the residual deviation used when the data cannot tell it (flat or tiny terrains).
const DEFAULT_DECAY: f64 = 0.5;

/// The noise amplitude sigma for each synthesised ring, finest first: `synth_levels` values.
///
/// `residual_std[k]` is the residual deviation of pyramid level k (k = 0 the data). Synthesised ring l sits
/// d = synth_levels - l octaves below the data; following GC section 8 the detail continues the data's own
/// fractal statistics: sigma_{-d} = sigma_0 r^d with r = sigma_0 / sigma_1, the measured octave-to-octave
/// ratio, clamped to [0.25, 0.75] so a smooth or noisy data set cannot make the synthesis vanish or explode.
#[expect(clippy::cast_possible_truncation, reason = "sigma is used in f32")]
pub fn extrapolate_sigmas(residual_std: &[f64], synth_levels: u32) -> Vec<f32> {
    let s0 = residual_std.first().copied().unwrap_or(0.0);
    let s1 = residual_std.get(1).copied().unwrap_or(0.0);
    let r = if s1 > 0.0 {
        (s0 / s1).clamp(0.25, 0.75)
    } else {
        DEFAULT_DECAY
    };
    (0..synth_levels)
        .map(|l| {
            let d = synth_levels - l;
            (s0 * r.powi(i32::try_from(d).unwrap_or(i32::MAX))) as f32
        })
        .collect()
}

/// A synthesised height at level-`level` sample (i, j): U of the coarser ring plus scaled table noise.
///
/// `coarse` is the next coarser ring's z at its own lattice coordinates. Pure: the same inputs give the
/// same bits, whether `coarse` reads the ring's toroidal storage or evaluates it directly.
#[inline]
pub fn synthesize(
    coarse: impl Fn(i64, i64) -> f32,
    noise: &NoiseTable,
    sigma: f32,
    level: u32,
    i: i64,
    j: i64,
) -> f32 {
    predict(coarse, i, j) + sigma * noise.at(level, i, j)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_normalised_and_fixed() {
        let t = NoiseTable::default();
        let n = t.values().len() as f64;
        let mean = t.values().iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let var = t
            .values()
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n;
        assert!(mean.abs() < 1e-6, "mean {mean}");
        assert!((var - 1.0).abs() < 1e-5, "variance {var}");
        assert_eq!(t, NoiseTable::default());
        // The hash spreads neighbouring lattice samples over the table.
        assert_ne!(t.at(0, 0, 0), t.at(0, 1, 0));
        assert_ne!(t.at(0, 0, 0), t.at(1, 0, 0));
    }

    #[test]
    fn sigmas_decay() {
        let s = extrapolate_sigmas(&[2.0, 4.0, 8.0], 2);
        assert_eq!(s, vec![0.5, 1.0]);
        assert_eq!(extrapolate_sigmas(&[0.0, 0.0], 1), vec![0.0]);
    }
}
