//! Stage 1 (bake: error maps, their SATs and max pyramids) and stage 2 (per-frame, allocation-free block
//! LOD selection) of design.md "SAT LOD", after Li et al. 2021 ("SAT paper").
//!
//! # Error maps
//!
//! For clipmap level L (data level k = L - synth_levels), e_L(x, y) = |H_0(x, y) - PL(H_L)(x, y)| at every
//! data sample, with H_L the pyramid level the ring holds ([`Pyramid::at`]) and PL its piecewise-linear
//! surface split along the (i, j)-(i+1, j+1) diagonal, the triangulation the renderer draws and
//! [`crate::clipmap`]'s z_c uses. e is computed in f64 and stored as f32; every bound below is about these
//! f32 values. E_L is their maximum. Rings finer than the data (synthesised) and the data level itself have
//! no error against the data. The transition morph is not modelled: a morphing vertex lies between levels L
//! and L + 1.
//!
//! # Blocks
//!
//! The LOD block of ring l is a cell of a fixed world grid: m x m quads of level l (m = `profile.block_m()`),
//! cell (c, r) covering level-l vertices [c m, (c + 1) m] x [r m, (r + 1) m], i.e. level-0 lattice
//! multiples of m 2^l, so coarser levels up to l + log2 m have samples on its corners. Each frame, ring l
//! contributes the cells that meet its active region (clipped to it) and are not wholly inside the finer
//! ring's active region (the hole). The renderer draws each block at its chosen level, covering the clipped
//! cell; skirts hide the cracks (design.md "SAT LOD" 7). A full ring of n = 4m - 1 vertices meets at most
//! 6 x 6 cells, so a frame has at most 36 L blocks, and selection is O(blocks x levels).

use std::fmt;
use std::str::FromStr;

use crate::camera::Camera;
use crate::frame::{Frame, Rect, MAX_LEVELS};
use crate::pyramid::Pyramid;
use crate::sat::{pow_unit, Sat};
use crate::{Error, Result};

/// The exponent p of the SFAMF estimate (design.md "SAT LOD" 3-4), fixed from `clipsat tune-p`.
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
/// conservative bound within 11x. Larger p only gets worse on both terrains.
pub const P: u32 = 4;

/// Capacity of a frame's block list; the profile's `max_draws` is the limit actually enforced.
pub const MAX_LOD_BLOCKS: usize = 4096;

/// Safety factors that keep estimate <= exact <= conservative through the f64 roundings of the power
/// chain (relative error below (p + 8) 2^-53 < 1e-14 for p <= 64).
const DOWN: f64 = 1.0 - 1.0 / (1u64 << 36) as f64;
const UP: f64 = 1.0 + 1.0 / (1u64 << 36) as f64;

/// How a block's object-space error is judged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LodMode {
    /// No SAT: every block is drawn at its own ring's level (plain geometry clipmap).
    Distance,
    /// The SFAMF estimate M = E (mean (e/E)^p)^(1/p), never above the true max (the SAT paper's choice).
    Sat,
    /// min(E, N^(1/p) M): never below the true max.
    SatConservative,
    /// The true max over the block, from a max pyramid (the accuracy reference).
    Exact,
}

impl LodMode {
    /// The names [`LodMode::from_str`] accepts.
    pub const NAMES: [&'static str; 4] = ["distance", "sat", "sat-conservative", "exact"];
    /// Every mode, in the order of [`LodMode::NAMES`].
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
            _ => Err(Error::Arg {
                arg: "--lod".into(),
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

/// e at data sample (x, y) against data level k's piecewise-linear surface.
#[inline]
#[expect(
    clippy::cast_possible_truncation,
    reason = "the error is stored as f32, rounded once"
)]
fn sample_error(pyramid: &Pyramid, k: u32, x: i64, y: i64) -> f32 {
    let step = 1i64 << k;
    let (i, j) = (x >> k, y >> k);
    let inv = 1.0 / step as f64;
    let fx = (x & (step - 1)) as f64 * inv;
    let fy = (y & (step - 1)) as f64 * inv;
    let z = |a: i64, b: i64| f64::from(pyramid.at(k, a, b));
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
    let h0 = f64::from(pyramid.level(0).at_clamped(x, y));
    (h0 - pl).abs() as f32
}

/// Range maximum over a grid of non-negative f32: a max pyramid (level k+1 = max of 2 x 2 of level k).
///
/// A query peels odd border rows and columns at each level and halves, so it reads O(w + h) cells in the
/// worst case and O(1) levels' worth for boxes aligned to large powers of two. Memory: 4/3 x 4 bytes per
/// sample.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeMax {
    dims: Vec<(u32, u32)>,
    levels: Vec<Vec<f32>>,
}

impl RangeMax {
    /// Builds the pyramid over `values` (`width x height`, row-major); panics on a size mismatch.
    pub fn build(width: u32, height: u32, values: Vec<f32>) -> Self {
        assert_eq!(
            values.len() as u64,
            u64::from(width) * u64::from(height),
            "range-max grid size"
        );
        let mut dims = vec![(width, height)];
        let mut levels = vec![values];
        while let Some(&(w, h)) = dims.last() {
            if w <= 1 && h <= 1 {
                break;
            }
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let prev = levels.last().expect("a level");
            let mut next = vec![0.0f32; nw as usize * nh as usize];
            for y in 0..nh as usize {
                for x in 0..nw as usize {
                    let mut m = 0.0f32;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = (2 * x + dx, 2 * y + dy);
                        if sx < w as usize && sy < h as usize {
                            m = m.max(prev[sy * w as usize + sx]);
                        }
                    }
                    next[y * nw as usize + x] = m;
                }
            }
            dims.push((nw, nh));
            levels.push(next);
        }
        Self { dims, levels }
    }

    /// The finest level: the values themselves.
    pub fn values(&self) -> &[f32] {
        &self.levels[0]
    }

    /// Maximum over [x0, x1) x [y0, y1) (0 for an empty box); panics past the grid.
    pub fn max(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> f32 {
        assert!(
            x1 <= self.dims[0].0 && y1 <= self.dims[0].1,
            "range-max box past the grid"
        );
        let (mut x0, mut y0, mut x1, mut y1) = (x0, y0, x1, y1);
        let mut m = 0.0f32;
        for (k, vals) in self.levels.iter().enumerate() {
            if x0 >= x1 || y0 >= y1 {
                break;
            }
            let w = self.dims[k].0 as usize;
            let at = |x: u32, y: u32| vals[y as usize * w + x as usize];
            if k + 1 == self.levels.len() {
                for y in y0..y1 {
                    for x in x0..x1 {
                        m = m.max(at(x, y));
                    }
                }
                break;
            }
            if x0 & 1 == 1 {
                (y0..y1).for_each(|y| m = m.max(at(x0, y)));
                x0 += 1;
            }
            if x1 & 1 == 1 && x1 > x0 {
                (y0..y1).for_each(|y| m = m.max(at(x1 - 1, y)));
                x1 -= 1;
            }
            if y0 & 1 == 1 {
                (x0..x1).for_each(|x| m = m.max(at(x, y0)));
                y0 += 1;
            }
            if y1 & 1 == 1 && y1 > y0 {
                (x0..x1).for_each(|x| m = m.max(at(x, y1 - 1)));
                y1 -= 1;
            }
            (x0, y0, x1, y1) = (x0 / 2, y0 / 2, x1 / 2, y1 / 2);
        }
        m
    }
}

/// One block's object-space error at one level, metres: estimate <= exact <= conservative.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BlockError {
    /// The SFAMF estimate E (mean (e/E)^p)^(1/p), from the SAT sum rounded down.
    pub estimate: f64,
    /// The true maximum.
    pub exact: f64,
    /// min(E, N^(1/p) M), from the SAT sum rounded up.
    pub conservative: f64,
}

/// The tables of one data level: E, the SAT of (e/E)^p and the max pyramid of e. None where E = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelTables {
    e_max: f32,
    tables: Option<(Sat, RangeMax)>,
}

impl LevelTables {
    /// Builds the SAT of (e/E)^p (quantum 2^-[`Sat::max_frac_bits`]) and the max pyramid of `errors`.
    pub fn build(width: u32, height: u32, errors: Vec<f32>, p: u32) -> Result<Self> {
        let e_max = errors.iter().copied().fold(0.0f32, f32::max);
        if e_max <= 0.0 {
            return Ok(Self {
                e_max: 0.0,
                tables: None,
            });
        }
        let q = Sat::max_frac_bits(u64::from(width) * u64::from(height));
        let inv = 1.0 / f64::from(e_max);
        let sat = Sat::build(width, height, 1, q, |x, y| {
            let e = errors[y as usize * width as usize + x as usize];
            pow_unit(f64::from(e) * inv, p).min(1.0)
        })?;
        Ok(Self {
            e_max,
            tables: Some((sat, RangeMax::build(width, height, errors))),
        })
    }

    /// Rebuilds from a cached SAT and error map (see [`crate::bake`]).
    pub fn from_parts(e_max: f32, tables: Option<(Sat, RangeMax)>) -> Self {
        Self { e_max, tables }
    }

    /// E_L, the level's largest error, metres.
    pub fn e_max(&self) -> f32 {
        self.e_max
    }

    /// The SAT and max pyramid (None when the level has no error).
    pub fn tables(&self) -> Option<&(Sat, RangeMax)> {
        self.tables.as_ref()
    }

    /// The error over data samples [x0, x1) x [y0, y1) (non-empty, inside the grid), with exponent `p`.
    pub fn block(&self, p: u32, x0: u32, y0: u32, x1: u32, y1: u32) -> BlockError {
        let Some((sat, max)) = &self.tables else {
            return BlockError::default();
        };
        let e = f64::from(self.e_max);
        let n = f64::from(x1 - x0) * f64::from(y1 - y0);
        let (lo, hi) = sat.box_bounds(x0, y0, x1, y1);
        let inv_p = 1.0 / f64::from(p);
        // SFAMF (SAT paper section 4): the p-mean never exceeds the max, the p-sum never falls below it.
        let estimate = e * (lo / n).min(1.0).powf(inv_p) * DOWN;
        let conservative = (e * hi.powf(inv_p) * UP).min(e);
        BlockError {
            estimate,
            exact: f64::from(max.max(x0, y0, x1, y1)),
            conservative,
        }
    }

    /// The object-space error of the block under `mode` (`Distance` has none: 0).
    pub fn eta(&self, mode: LodMode, p: u32, x0: u32, y0: u32, x1: u32, y1: u32) -> f64 {
        let Some((sat, max)) = &self.tables else {
            return 0.0;
        };
        let e = f64::from(self.e_max);
        let inv_p = 1.0 / f64::from(p);
        match mode {
            LodMode::Distance => 0.0,
            LodMode::Exact => f64::from(max.max(x0, y0, x1, y1)),
            LodMode::Sat => {
                let n = f64::from(x1 - x0) * f64::from(y1 - y0);
                let (lo, _) = sat.box_bounds(x0, y0, x1, y1);
                e * (lo / n).min(1.0).powf(inv_p) * DOWN
            }
            LodMode::SatConservative => {
                let (_, hi) = sat.box_bounds(x0, y0, x1, y1);
                (e * hi.powf(inv_p) * UP).min(e)
            }
        }
    }
}

/// Every level's tables over one terrain: index k is data level k (clipmap level k + synth_levels).
#[derive(Clone, Debug, PartialEq)]
pub struct LodTables {
    /// The exponent the SATs were built with.
    pub p: u32,
    /// Data grid width and height, samples.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Per data level, finest (the data, no error) first.
    pub levels: Vec<LevelTables>,
}

impl LodTables {
    /// Builds every data level's tables from scratch (no cache; [`crate::bake`] caches), calling
    /// `progress(k)` as level k starts.
    pub fn build(
        pyramid: &Pyramid,
        data_levels: u32,
        p: u32,
        mut progress: impl FnMut(u32),
    ) -> Result<Self> {
        let l0 = pyramid.level(0);
        let (w, h) = (l0.width(), l0.height());
        let mut levels = Vec::with_capacity(data_levels as usize);
        for k in 0..data_levels {
            progress(k);
            let errors = error_map(pyramid, k);
            levels.push(LevelTables::build(w, h, errors, p)?);
        }
        Ok(Self {
            p,
            width: w,
            height: h,
            levels,
        })
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

fn ceil_shr(v: i64, s: u32) -> i64 {
    -((-v) >> s)
}

/// One block of a frame and the level it is drawn at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockLod {
    /// The ring whose render region the block belongs to.
    pub ring: u32,
    /// The block's vertices in ring `ring`'s lattice (a cell of the fixed grid, clipped to the active region).
    pub rect: Rect,
    /// The level it is drawn at.
    pub level: u32,
    /// The level the error bound asked for, before clamping to the held data.
    pub wanted: u32,
    /// The object-space error of `level` over the block under the frame's mode, metres.
    pub eta_m: f32,
    /// The screen-space bound of `level`, pixels.
    pub bound_px: f32,
}

/// The LOD part of a frame: blocks and the levels they are drawn at. Fixed-capacity: allocation-free.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LodFrame {
    /// Blocks, ring by ring (finest first), row-major cells within a ring.
    pub blocks: heapless::Vec<BlockLod, MAX_LOD_BLOCKS>,
    /// Blocks whose wanted level is finer than any level whose held data covers them: the error the memory
    /// budget cannot pay for.
    pub blocks_clamped: u32,
    /// Blocks drawn coarser than their own ring.
    pub blocks_coarser: u32,
    /// Blocks drawn finer than their own ring.
    pub blocks_finer: u32,
}

impl LodFrame {
    /// A frame with no blocks (boxed: the block list is large).
    pub fn new_boxed() -> Box<Self> {
        Box::default()
    }

    /// The block-to-level part of the frame hash (for the frame record).
    pub fn hash_into(&self, h: &mut crate::hash::Hash64) {
        h.write_u64(self.blocks.len() as u64);
        for b in &self.blocks {
            h.write_u32(b.ring);
            h.write_i64(b.rect.x0);
            h.write_i64(b.rect.y0);
            h.write_u32(b.rect.w);
            h.write_u32(b.rect.h);
            h.write_u32(b.level);
        }
        h.write_u32(self.blocks_clamped);
    }
}

/// The per-frame LOD selector: SAT paper algorithm 1 over the fixed block grid, with the clamp to the
/// held data. Built once; [`Lod::select`] allocates nothing.
#[derive(Clone, Debug)]
pub struct Lod {
    tables: LodTables,
    levels: u32,
    synth: u32,
    m: u32,
    g0: f64,
    /// World x of level-0 lattice column 0 (the west edge), metres.
    x_left: f64,
    /// World y of level-0 lattice row 0 (the north edge), metres.
    y_top: f64,
    z_range: (f64, f64),
    epsilon_px: f64,
    view_height: u32,
    max_blocks: usize,
}

impl Lod {
    /// A selector for a clipmap of `profile` over the terrain the tables were built from.
    ///
    /// `g0` is the level-0 spacing, `corner` the world (x, y) of lattice point (0, 0) (the north-west data
    /// sample), `z_range` the terrain's height range (the blocks' vertical extent, so the closest point is
    /// never farther than the true one).
    pub fn new(
        tables: LodTables,
        profile: &crate::Profile,
        synth: u32,
        g0: f64,
        corner: (f64, f64),
        z_range: (f64, f64),
    ) -> Self {
        let (x_left, y_top) = corner;
        Self {
            tables,
            levels: profile.clipmap.levels.min(crate::profile::MAX_LEVELS),
            synth,
            m: profile.block_m(),
            g0,
            x_left,
            y_top,
            z_range,
            epsilon_px: f64::from(profile.view.epsilon_px),
            view_height: profile.view.height,
            max_blocks: (profile.budget.max_draws as usize).min(MAX_LOD_BLOCKS),
        }
    }

    /// A selector for `clipmap`'s geometry (its level-0 spacing, synthesised rings and terrain placement).
    pub fn for_clipmap(
        tables: LodTables,
        profile: &crate::Profile,
        clipmap: &crate::clipmap::Clipmap,
        terrain: &crate::Heightmap,
    ) -> Self {
        let (lo, hi) = terrain.range();
        // Heightmap::grid_to_world: sample (0, 0) sits at origin + (0, (rows - 1) s).
        let (ox, oy) = terrain.origin();
        let y_top = oy + f64::from(terrain.height() - 1) * f64::from(terrain.spacing());
        Self::new(
            tables,
            profile,
            clipmap.synth_levels(),
            clipmap.g0(),
            (ox, y_top),
            (f64::from(lo), f64::from(hi)),
        )
    }

    /// Sets the screen-space error bound epsilon, pixels (the profile's `view.epsilon_px` until set).
    pub fn set_epsilon_px(&mut self, epsilon_px: f64) {
        self.epsilon_px = epsilon_px;
    }

    /// The screen-space error bound epsilon, pixels.
    pub fn epsilon_px(&self) -> f64 {
        self.epsilon_px
    }

    /// Rings finer than the data (clipmap level = data level + this).
    pub fn synth_levels(&self) -> u32 {
        self.synth
    }

    /// The baked tables.
    pub fn tables(&self) -> &LodTables {
        &self.tables
    }

    /// The screen-space bound of an object-space error `eta` at distance `dist`, pixels (SAT paper eq. 6): a
    /// vertical segment of +/- eta at the block's closest point, projected on the viewport.
    pub fn bound_px(&self, camera: &Camera, eta: f64, dist: f64) -> f64 {
        2.0 * eta * camera.pixels_per_metre(dist, self.view_height)
    }

    /// The distance from the eye to the closest point of a level-0 lattice box [a, b] x [c, d] (inclusive
    /// vertices), its height spanning the terrain's range.
    fn closest_distance(&self, camera: &Camera, a: i64, c: i64, b: i64, d: i64) -> f64 {
        let g = self.g0;
        #[expect(
            clippy::cast_precision_loss,
            reason = "lattice coordinates below 2^48 are exact in f64"
        )]
        let (x0, x1, yn, ys) = (
            self.x_left + a as f64 * g,
            self.x_left + b as f64 * g,
            self.y_top - c as f64 * g,
            self.y_top - d as f64 * g,
        );
        let e = camera.eye;
        let px = e.x.clamp(x0, x1);
        let py = e.y.clamp(ys, yn);
        let pz = e.z.clamp(self.z_range.0, self.z_range.1);
        ((px - e.x).powi(2) + (py - e.y).powi(2) + (pz - e.z).powi(2)).sqrt()
    }

    /// Chooses every block's level for `frame` seen from `camera` (SAT paper algorithm 1): from the coarsest
    /// level to the finest, the first whose bound is <= epsilon; then the nearest level whose clip region
    /// covers the block. Writes `out`; allocation-free. Fails with [`Error::Capacity`] past
    /// `profile.budget.max_draws` blocks.
    pub fn select(
        &self,
        frame: &Frame,
        camera: &Camera,
        mode: LodMode,
        out: &mut LodFrame,
    ) -> Result<()> {
        out.blocks.clear();
        out.blocks_clamped = 0;
        out.blocks_coarser = 0;
        out.blocks_finer = 0;
        let levels = frame.levels.len().min(self.levels as usize);
        let m = i64::from(self.m);
        for l in 0..levels {
            let a = frame.levels[l].active;
            if a.is_empty() {
                continue;
            }
            let l32 = u32::try_from(l).expect("level < MAX_LEVELS");
            // The hole: the finer ring's active vertices, in this ring's lattice (its corners are even).
            let hole = match l.checked_sub(1).map(|f| frame.levels[f].active) {
                Some(f) if !f.is_empty() => Rect::from_bounds(
                    f.x0 >> 1,
                    f.y0 >> 1,
                    ((f.x1() - 1) >> 1) + 1,
                    ((f.y1() - 1) >> 1) + 1,
                ),
                _ => Rect::EMPTY,
            };
            let (ax1, ay1) = (a.x1() - 1, a.y1() - 1);
            for cy in a.y0.div_euclid(m)..=(ay1 - 1).div_euclid(m) {
                for cx in a.x0.div_euclid(m)..=(ax1 - 1).div_euclid(m) {
                    let r = Rect::from_bounds(
                        (cx * m).max(a.x0),
                        (cy * m).max(a.y0),
                        ((cx + 1) * m).min(ax1) + 1,
                        ((cy + 1) * m).min(ay1) + 1,
                    );
                    if r.w < 2 || r.h < 2 || hole.contains(&r) {
                        continue;
                    }
                    let b = self.choose(frame, camera, mode, l32, r);
                    if b.wanted < b.level {
                        out.blocks_clamped += 1;
                    }
                    if b.level > l32 {
                        out.blocks_coarser += 1;
                    } else if b.level < l32 {
                        out.blocks_finer += 1;
                    }
                    if out.blocks.len() >= self.max_blocks {
                        return Err(Error::Capacity {
                            what: "LOD blocks (profile budget.max_draws)",
                            capacity: self.max_blocks,
                        });
                    }
                    out.blocks.push(b).map_err(|_| Error::Capacity {
                        what: "LOD blocks",
                        capacity: MAX_LOD_BLOCKS,
                    })?;
                }
            }
        }
        Ok(())
    }

    /// One block: algorithm 1, then the clamp.
    fn choose(
        &self,
        frame: &Frame,
        camera: &Camera,
        mode: LodMode,
        ring: u32,
        r: Rect,
    ) -> BlockLod {
        // Level-0 lattice box of the block (inclusive vertices).
        let (a, c, b, d) = (
            r.x0 << ring,
            r.y0 << ring,
            (r.x1() - 1) << ring,
            (r.y1() - 1) << ring,
        );
        let dist = self.closest_distance(camera, a, c, b, d);
        let (x0, y0, x1, y1) = self.tables.data_box(self.synth, a, c, b, d);
        let eta_of = |level: u32| -> f64 {
            match level
                .checked_sub(self.synth)
                .and_then(|k| self.tables.level(k))
            {
                Some(t) => t.eta(mode, self.tables.p, x0, y0, x1, y1),
                // Past the baked levels: unknown error, never chosen by the bound.
                None => f64::INFINITY,
            }
        };
        let levels = u32::try_from(frame.levels.len()).expect("levels < MAX_LEVELS");
        let mut wanted = ring;
        if mode != LodMode::Distance {
            wanted = self.synth;
            for level in (self.synth..levels).rev() {
                if self.bound_px(camera, eta_of(level), dist) <= self.epsilon_px {
                    wanted = level;
                    break;
                }
            }
        }
        let covers = |level: u32| -> bool {
            let lf = &frame.levels[level as usize];
            let box_l = Rect::from_bounds(
                a >> level,
                c >> level,
                ceil_shr(b, level) + 1,
                ceil_shr(d, level) + 1,
            );
            !lf.clip.is_empty() && lf.clip.contains(&box_l)
        };
        let level = if covers(wanted) {
            wanted
        } else {
            ((wanted + 1)..levels)
                .find(|&l| covers(l))
                .or_else(|| (0..wanted).rev().find(|&l| covers(l)))
                .unwrap_or(ring)
        };
        let eta = if mode == LodMode::Distance {
            0.0
        } else {
            eta_of(level)
        };
        #[expect(clippy::cast_possible_truncation, reason = "reported in f32")]
        BlockLod {
            ring,
            rect: r,
            level,
            wanted,
            eta_m: eta as f32,
            bound_px: self.bound_px(camera, eta, dist) as f32,
        }
    }
}

/// The most blocks one frame of `profile` can have: at most 6 x 6 cells meet a ring's active region.
pub fn max_blocks_per_frame(profile: &crate::Profile) -> usize {
    36 * (profile.clipmap.levels as usize).min(MAX_LEVELS)
}
