//! Stage 1, the bake: the shading SATs - the normal SAT and the horizon SATs (SAT paper section 5,
//! algorithm 2) - kept in CPU memory only. The renderer never uploads them: it fills fixed per-level
//! tables of the clipmap's ring size from them ([`ShadingBake::level_texel`], `gpu/renderer/sg_tables.rs`),
//! so its GPU memory does not grow with the terrain (issue 16, "Memory").
//!
//! Format: wrapping u32 fixed point with Q = [`SAT_FRAC_BITS`] = 20 fractional bits, four channels per
//! RGBA32UI texel (integer textures, read with `textureLoad`: GLES 3.0 filters neither integer nor float
//! textures). Measured by `tests/cpu/shading.rs gpu_sat_format_error` on a 1024^2 grid, boxes of 1 to 64^2
//! samples: max error of a box mean 4.4e-7, against 1.7e-4 for RGBA32F with the global mean subtracted and
//! 4.5e-3 for plain RGBA32F. Sums wrap mod 2^32, and a corner difference is exact as long as the box's
//! sum stays below 2^32: values are <= 1, so a box of at most [`MAX_BOX_SIDE`]^2 = 63^2 samples
//! (63^2 2^20 < 2^32; 64^2 of ones would wrap to 0) is always exact; [`ShadingBake::level_texel`] caps its boxes there.
//!
//! Each table is padded with a zero row and column: entry (x, y) = sum over samples [0, x) x [0, y), so a
//! box at the border needs no branch. The tables are the low 32 bits of [`crate::bake::sat::Sat`]'s exact u64
//! sums (the same quantisation up, to a multiple of 2^-20).
//!
//! Size: the grid's side is capped at `max_side` (callers pass the GLES 3.0 texture side, 2048, which
//! bounds the bake's CPU memory and time). A terrain whose padded table would be larger is baked on the
//! first pyramid level ([`crate::bake::pyramid`]) that fits: level k's sample (i, j) sits on data sample
//! (i 2^k, j 2^k), and [`ShadingBake::step`] = 2^k maps data samples to it.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use crate::bake::horizon::{self, MAX_AZIMUTHS};
use crate::bake::pyramid::Pyramid;
use crate::bake::sat::Sat;
use crate::bake::{seal, unseal, write_atomic, CacheOutcome};
use crate::hash::{hex, Hash64};
use crate::shading::scene::Needs;
use crate::{Error, Heightmap, Result};

const SHADING_MAGIC: &[u8; 8] = b"CSATSHD1";
/// Bumped whenever the shading cache layout or the meaning of a baked number changes.
const SHADING_FORMAT_VERSION: u32 = 1;

/// The shading cache key: the terrain's content and every parameter that changes the tables.
fn shading_cache_key(hm: &Heightmap, needs: &Needs, azimuths: u32, max_side: u32) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(SHADING_FORMAT_VERSION);
    h.write_u32(hm.width());
    h.write_u32(hm.height());
    h.write_f32(hm.spacing());
    h.write_bytes(bytemuck::cast_slice::<f32, u8>(hm.heights()));
    h.write_u32(u32::from(needs.bake_horizons));
    h.write_u32(azimuths);
    h.write_u32(max_side);
    h.write_u32(SAT_FRAC_BITS);
    h.write_u64(horizon::DEFAULT_MAX_SAMPLES.to_bits());
    h.finish()
}

/// Fractional bits of the GPU SATs.
pub const SAT_FRAC_BITS: u32 = 20;
/// Largest footprint box side, samples, whose wrapping u32 sum is always exact.
pub const MAX_BOX_SIDE: u32 = 63;

/// The shading tables baked for a scene, as the GPU textures hold them.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadingBake {
    width: u32,
    height: u32,
    step: u32,
    azimuths: u32,
    /// (width + 1) x (height + 1) texels, 4 u32 each: (n + 1) / 2 per normal component, 0. Shared: the
    /// renderer keeps the bake to fill its per-level tables ([`ShadingBake::level_texel`]).
    normal: Arc<[u32]>,
    /// Layers of (width + 1) x (height + 1) texels, 4 azimuths each: (a + pi/2) / pi.
    horizon: Arc<[u32]>,
    baked: Vec<&'static str>,
}

/// The padded wrapping-u32 table of a u64 SAT: entry (x + 1, y + 1) is the inclusive sum at (x, y).
fn padded(sat: &Sat, w: u32, h: u32, out: &mut [u32], channel: usize) {
    let t = sat.table();
    for y in 0..h as usize {
        for x in 0..w as usize {
            let at = ((y + 1) * (w as usize + 1) + x + 1) * 4 + channel;
            #[expect(
                clippy::cast_possible_truncation,
                reason = "sums mod 2^32: box differences stay exact below 2^32 (module docs)"
            )]
            let low = t[y * w as usize + x] as u32;
            out[at] = low;
        }
    }
}

impl ShadingBake {
    /// Bakes what `needs` asks for on the finest level of `hm` whose padded tables fit `max_side` texels:
    /// always the normal SAT; the horizons ([`horizon::bake`], `azimuths` of them) and their SATs only when
    /// `needs.bake_horizons`.
    pub fn bake(hm: &Heightmap, needs: &Needs, azimuths: u32, max_side: u32) -> Result<Self> {
        if azimuths == 0 || azimuths > MAX_AZIMUTHS || !azimuths.is_multiple_of(4) {
            return Err(Error::Invalid {
                what: "azimuths".into(),
                reason: format!("{azimuths} is not a multiple of 4 in 4..={MAX_AZIMUTHS}"),
            });
        }
        let mut level = None;
        let mut step = 1u32;
        if hm.width() + 1 > max_side || hm.height() + 1 > max_side {
            let pyramid = Pyramid::build(hm);
            for k in 1..pyramid.len() {
                let l = pyramid.level(k);
                step *= 2;
                if l.width() < max_side && l.height() < max_side {
                    level = Some(Heightmap::new(
                        Path::new("shading grid"),
                        l.width(),
                        l.height(),
                        hm.spacing() * step as f32,
                        l.heights().to_vec(),
                    )?);
                    break;
                }
            }
            if level.is_none() {
                return Err(Error::Capacity {
                    what: "shading SAT side (max_texture_dimension_2d)",
                    capacity: max_side as usize,
                });
            }
        }
        let grid = level.as_ref().unwrap_or(hm);
        let (w, h) = (grid.width(), grid.height());
        let texels = (w as usize + 1) * (h as usize + 1);
        let normals: Vec<glam::DVec3> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| horizon::texel_normal(grid, x, y))
            .collect();
        let at = |x: u32, y: u32| y as usize * w as usize + x as usize;
        let mut normal = vec![0u32; texels * 4];
        for c in [0usize, 1, 2] {
            let sat = Sat::build(w, h, 1, SAT_FRAC_BITS, |x, y| {
                ((normals[at(x, y)][c] + 1.0) * 0.5).clamp(0.0, 1.0)
            })?;
            padded(&sat, w, h, &mut normal, c);
        }
        let mut baked = vec!["normal_sat"];
        let mut horizon = Vec::new();
        let mut d = 0;
        if needs.bake_horizons {
            let hz = horizon::bake(grid, azimuths, horizon::DEFAULT_MAX_SAMPLES)?;
            d = azimuths;
            let layers = d.div_ceil(4) as usize;
            horizon = vec![0u32; layers * texels * 4];
            for k in 0..d as usize {
                let sat = Sat::build(w, h, 1, SAT_FRAC_BITS, |x, y| {
                    ((f64::from(hz.at(x, y)[k]) + std::f64::consts::FRAC_PI_2)
                        / std::f64::consts::PI)
                        .clamp(0.0, 1.0)
                })?;
                let layer = &mut horizon[(k / 4) * texels * 4..(k / 4 + 1) * texels * 4];
                padded(&sat, w, h, layer, k % 4);
            }
            baked.extend(["horizons", "horizon_sat"]);
        }
        Ok(Self {
            width: w,
            height: h,
            step,
            azimuths: d,
            normal: normal.into(),
            horizon: horizon.into(),
            baked,
        })
    }

    /// [`ShadingBake::bake`] through the disk cache in `dir` ([`crate::bake::default_cache_dir`]): a
    /// valid `shading-<key>.bin` is read, else the tables are baked and written. The key hashes the
    /// terrain (size, spacing, every height's bits) and every bake parameter; a damaged or mismatched
    /// file is rebaked, never trusted. Layout, little-endian: magic `CSATSHD1`, format version, key,
    /// width, height, step, azimuths, the normal table, the horizon table (u32 each), a trailing hash.
    pub fn bake_cached(
        hm: &Heightmap,
        needs: &Needs,
        azimuths: u32,
        max_side: u32,
        dir: &Path,
    ) -> Result<(Self, CacheOutcome)> {
        let key = shading_cache_key(hm, needs, azimuths, max_side);
        let path = dir.join(format!("shading-{}.bin", hex(key)));
        let refused = match std::fs::read(&path) {
            Ok(bytes) => match Self::decode(&bytes, key, needs.bake_horizons) {
                Ok(b) => return Ok((b, CacheOutcome::Hit)),
                Err(reason) => Some(reason),
            },
            Err(_) => None,
        };
        let bake = Self::bake(hm, needs, azimuths, max_side)?;
        let outcome = match write_atomic(&path, &bake.encode(key)) {
            Err(e) => CacheOutcome::NotCached(e.to_string()),
            Ok(()) => refused.map_or(CacheOutcome::Baked, CacheOutcome::Rebaked),
        };
        Ok((bake, outcome))
    }

    fn encode(&self, key: u64) -> Vec<u8> {
        let mut out = Vec::with_capacity(48 + 4 * (self.normal.len() + self.horizon.len()));
        out.extend_from_slice(SHADING_MAGIC);
        out.extend_from_slice(&SHADING_FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&key.to_le_bytes());
        for w in [self.width, self.height, self.step, self.azimuths] {
            out.extend_from_slice(&w.to_le_bytes());
        }
        for v in self.normal.iter().chain(self.horizon.iter()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        seal(&mut out);
        out
    }

    fn decode(bytes: &[u8], key: u64, horizons: bool) -> std::result::Result<Self, String> {
        let mut r = unseal(bytes, SHADING_MAGIC, "shading")?;
        let version = r.u32()?;
        if version != SHADING_FORMAT_VERSION {
            return Err(format!(
                "format version {version}, expected {SHADING_FORMAT_VERSION}"
            ));
        }
        if r.u64()? != key {
            return Err("key does not match".into());
        }
        let (width, height, step, azimuths) = (r.u32()?, r.u32()?, r.u32()?, r.u32()?);
        if width == 0 || height == 0 || !step.is_power_of_two() || azimuths > MAX_AZIMUTHS {
            return Err("sizes in the header are out of range".into());
        }
        if horizons != (azimuths > 0) {
            return Err("horizon tables do not match the key".into());
        }
        let texels = (width as usize + 1) * (height as usize + 1);
        let mut table = |n: usize| -> std::result::Result<Vec<u32>, String> {
            let bytes = r.take(n.checked_mul(4).ok_or("size overflow")?)?;
            Ok(bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect())
        };
        let normal = table(texels * 4)?;
        let horizon = table(azimuths.div_ceil(4) as usize * texels * 4)?;
        if !r.done() {
            return Err("trailing bytes".into());
        }
        let mut baked = vec!["normal_sat"];
        if azimuths > 0 {
            baked.extend(["horizons", "horizon_sat"]);
        }
        Ok(Self {
            width,
            height,
            step,
            azimuths,
            normal: normal.into(),
            horizon: horizon.into(),
            baked,
        })
    }

    /// Shading-grid samples per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Shading-grid rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Data samples per shading-grid sample (1 unless the terrain exceeds the texture side).
    pub fn step(&self) -> u32 {
        self.step
    }

    /// D, the horizon azimuths baked (0: none).
    pub fn azimuths(&self) -> u32 {
        self.azimuths
    }

    /// The maps baked, by name: `normal_sat`, and `horizons`, `horizon_sat` when visibility is on.
    pub fn baked(&self) -> &[&'static str] {
        &self.baked
    }

    /// The CPU twin of the shader's footprint fetch: mean normal r and the D mean horizon angles over the
    /// inclusive box [lo, hi] (clamped to the grid, side capped at [`MAX_BOX_SIDE`]), in the shader's f32
    /// operations.
    pub fn box_mean(&self, lo: (u32, u32), hi: (u32, u32)) -> (Vec3, heapless::Vec<f32, 16>) {
        let b = self.clamp_box(lo, hi);
        (self.normal_mean(b), self.horizon_mean(b))
    }

    /// [`ShadingBake::box_mean`]'s box: clamped to the grid, the side capped at [`MAX_BOX_SIDE`].
    fn clamp_box(&self, lo: (u32, u32), hi: (u32, u32)) -> ((u32, u32), (u32, u32)) {
        let lo = (lo.0.min(self.width - 1), lo.1.min(self.height - 1));
        let hi = (
            hi.0.clamp(lo.0, (lo.0 + MAX_BOX_SIDE - 1).min(self.width - 1)),
            hi.1.clamp(lo.1, (lo.1 + MAX_BOX_SIDE - 1).min(self.height - 1)),
        );
        (lo, hi)
    }

    /// The wrapping sum of channel `c` of padded table `table` over clamped box `b`, and 1 / (its
    /// texel count x 2^20).
    #[expect(clippy::cast_precision_loss, reason = "as the shader: f32(u32)")]
    fn box_sum(&self, table: &[u32], c: usize, (lo, hi): ((u32, u32), (u32, u32))) -> (u32, f32) {
        let pw = self.width as usize + 1;
        let e = |x: u32, y: u32| table[(y as usize * pw + x as usize) * 4 + c];
        let sum = e(hi.0 + 1, hi.1 + 1)
            .wrapping_sub(e(lo.0, hi.1 + 1))
            .wrapping_sub(e(hi.0 + 1, lo.1))
            .wrapping_add(e(lo.0, lo.1));
        let count = ((hi.0 - lo.0 + 1) * (hi.1 - lo.1 + 1)) as f32;
        (sum, 1.0 / (count * 1_048_576.0))
    }

    /// The mean normal r over clamped box `b`.
    #[expect(clippy::cast_precision_loss, reason = "as the shader: f32(u32)")]
    fn normal_mean(&self, b: ((u32, u32), (u32, u32))) -> Vec3 {
        let c = |k| self.box_sum(&self.normal, k, b);
        let ((x, q), (y, _), (z, _)) = (c(0), c(1), c(2));
        Vec3::new(x as f32, y as f32, z as f32) * q * 2.0 - Vec3::ONE
    }

    /// The D mean horizon angles over clamped box `b` (empty without horizons).
    #[expect(clippy::cast_precision_loss, reason = "as the shader: f32(u32)")]
    fn horizon_mean(&self, b: ((u32, u32), (u32, u32))) -> heapless::Vec<f32, 16> {
        let texels = (self.width as usize + 1) * (self.height as usize + 1);
        let mut hz = heapless::Vec::new();
        for k in 0..self.azimuths as usize {
            let layer = &self.horizon[(k / 4) * texels * 4..(k / 4 + 1) * texels * 4];
            let (sum, q) = self.box_sum(layer, k % 4, b);
            let a = sum as f32 * q * std::f32::consts::PI - std::f32::consts::FRAC_PI_2;
            // D <= MAX_AZIMUTHS = 16, the capacity.
            let _ = hz.push(a);
        }
        hz
    }

    /// The CPU twin of one texel of the renderer's per-level shading tables (`gpu/renderer/sg_tables.rs`):
    /// the inputs of lattice sample (i, j) of a ring `data_level` levels coarser than the data (negative:
    /// a synthesised ring finer than the data, which takes the nearest data sample's). A ring sample
    /// (i, j) sits on data sample (i 2^k, j 2^k) (`bake::pyramid`). Its r is the [`ShadingBake::box_mean`]
    /// of the box of side 2^k + 1 data samples centred there: neighbouring texels' boxes share their
    /// edges, so the bilinear interpolation between them is a tent filter of the data's normals about
    /// 2^(k+1) samples wide, the SAT paper's footprint box for a pixel of that size. Boxes are capped at
    /// [`MAX_BOX_SIDE`] samples, as the reference's footprint is; at the border they are clamped into
    /// the grid. Its horizon angles are the sample's own, not a box mean: the shader interpolates them
    /// between samples 2^k apart, and a box mean over 2^k + 1 samples lowered the horizons of rough
    /// terrain further (measured: `render --reference` of Puget Sound, evening, desktop, 640x360: RMSE
    /// 0.0381 with point horizons against 0.0436 with box means; 0.0322 for the old whole-terrain SATs).
    pub fn level_texel(&self, data_level: i32, i: i64, j: i64) -> (Vec3, heapless::Vec<f32, 16>) {
        let step = i64::from(self.step);
        let (x, y, span) = if data_level >= 0 {
            let k = data_level.unsigned_abs().min(40);
            (
                i.saturating_mul(1 << k),
                j.saturating_mul(1 << k),
                1i64 << k,
            )
        } else {
            let k = data_level.unsigned_abs().min(40);
            (i.div_euclid(1 << k), j.div_euclid(1 << k), 1)
        };
        // Nearest shading-grid sample, and the box's half side in grid samples.
        let (cx, cy) = (
            (x + step / 2).div_euclid(step),
            (y + step / 2).div_euclid(step),
        );
        let half = (span / step / 2).min(i64::from(MAX_BOX_SIDE - 1) / 2);
        let clamp = |v: i64, n: u32| -> u32 {
            u32::try_from(v.clamp(0, i64::from(n) - 1)).expect("clamped into the grid")
        };
        let r = self.normal_mean(self.clamp_box(
            (clamp(cx - half, self.width), clamp(cy - half, self.height)),
            (clamp(cx + half, self.width), clamp(cy + half, self.height)),
        ));
        let at = (clamp(cx, self.width), clamp(cy, self.height));
        (r, self.horizon_mean(self.clamp_box(at, at)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::procedural::{generate, ProceduralParams};

    #[test]
    fn cache_round_trips_and_refuses_damage() {
        let hm = generate(&ProceduralParams {
            size: 33,
            ..Default::default()
        })
        .expect("terrain");
        let dir =
            std::env::temp_dir().join(format!("clipsat-shading-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let needs = Needs {
            bake_horizons: true,
            ..Needs::default()
        };
        let (first, outcome) = ShadingBake::bake_cached(&hm, &needs, 8, 2048, &dir).expect("bake");
        assert_eq!(outcome, CacheOutcome::Baked);
        let (again, outcome) = ShadingBake::bake_cached(&hm, &needs, 8, 2048, &dir).expect("hit");
        assert_eq!(outcome, CacheOutcome::Hit);
        assert_eq!(again, first);
        // Another parameter is another file; no horizons reads back no horizons.
        let (plain, outcome) =
            ShadingBake::bake_cached(&hm, &Needs::default(), 8, 2048, &dir).expect("plain");
        assert_eq!((outcome, plain.azimuths()), (CacheOutcome::Baked, 0));
        assert_eq!(plain.baked(), ["normal_sat"]);
        // A flipped byte fails the trailing hash: rebaked, same tables.
        let path = dir.join(format!(
            "shading-{}.bin",
            hex(shading_cache_key(&hm, &needs, 8, 2048))
        ));
        let mut bytes = std::fs::read(&path).expect("cache file");
        bytes[40] ^= 1;
        std::fs::write(&path, &bytes).expect("damage");
        let (fixed, outcome) =
            ShadingBake::bake_cached(&hm, &needs, 8, 2048, &dir).expect("rebake");
        assert!(matches!(outcome, CacheOutcome::Rebaked(_)), "{outcome:?}");
        assert_eq!(fixed, first);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
