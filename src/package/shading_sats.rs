//! Stage 1b, baked from the package (or a held grid): the shading SATs - the normal SAT and the horizon SATs (SAT paper section 5,
//! algorithm 2) - kept in CPU memory only. The renderer never uploads them: it fills fixed per-level
//! tables of the clipmap's ring size from them ([`ShadingBake::level_texel`], `gpu/renderer/sg_tables.rs`),
//! so its GPU memory does not grow with the terrain (docs/design.md "Memory model").
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
//! Size: the grid is the finest pyramid level ([`crate::bake::pyramid`], the package's own levels when
//! streamed) whose tables fit a byte budget, the profile's [`crate::profile::CpuSplit::shading`] share of
//! `budget.cpu_memory_bytes` ([`grid_bytes`]: the tables at the bytes per texel they take, and the grid's
//! heights while they are baked), so the inputs are a fixed size whatever the terrain. Level k's sample
//! (i, j) sits on data sample (i 2^k, j 2^k), and [`ShadingBake::step`] = 2^k maps data samples to it.
//! A package's level is decoded alone ([`crate::package::Package::decode_level`]: it and its coarser
//! levels, nothing finer), so a streamed terrain's bake holds no full-resolution heightmap.
//!
//! The tables are written row by row as running sums (a SAT entry is the one above it plus its row's
//! prefix, wrapping in u32: the low 32 bits of the exact u64 sums), so the bake holds nothing but the
//! grid and the tables; the cache file is written and read through buffers, never as a whole in memory.

use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use crate::bake::horizon::{self, MAX_AZIMUTHS};
use crate::bake::pyramid::Pyramid;
use crate::bake::sat::Sat;
use crate::bake::CacheOutcome;
use crate::hash::{hex, Hash64};
use crate::package::format::level_sizes;
use crate::package::Package;
use crate::progress::Progress;
use crate::shading::scene::Needs;
use crate::{Error, Result};
use crate::source::Heightmap;

const SHADING_MAGIC: &[u8; 8] = b"CSATSHD1";
/// Bumped whenever the shading cache layout or the meaning of a baked number changes (2: the grid level
/// in the key, the data's size and spacing in the header, a CRC-32 trailer read as it streams).
const SHADING_FORMAT_VERSION: u32 = 2;
/// The cache file's header: magic, version, key, then 7 u32s.
const HEADER_BYTES: usize = 8 + 4 + 8 + 7 * 4;

/// Bytes per shading-grid sample besides the tables while they are baked: the grid's f32 heights, and
/// while a package's level is decoded its coarser level (a quarter of the samples, 4 bytes each).
pub const GRID_HEIGHT_BYTES: u64 = 5;

/// Bytes a `w x h` shading grid takes with `azimuths` horizons (0: none): its padded tables, (w + 1)
/// x (h + 1) texels of 4 u32 for the normal SAT and 4 u32 per 4 horizon SATs, and [`GRID_HEIGHT_BYTES`]
/// per sample. Saturates, never wraps.
pub fn grid_bytes(w: u32, h: u32, azimuths: u32) -> u64 {
    let texels = (u64::from(w) + 1).saturating_mul(u64::from(h) + 1);
    let per_texel = 16 * (1 + u64::from(azimuths.div_ceil(4)));
    texels
        .saturating_mul(per_texel)
        .saturating_add((u64::from(w) * u64::from(h)).saturating_mul(GRID_HEIGHT_BYTES))
}

/// The finest of the pyramid levels `sizes` (finest first) whose [`grid_bytes`] fit `max_bytes`.
pub fn grid_level(sizes: &[(u32, u32)], azimuths: u32, max_bytes: u64) -> Result<usize> {
    sizes
        .iter()
        .position(|&(w, h)| grid_bytes(w, h, azimuths) <= max_bytes)
        .ok_or(Error::Capacity {
            what: "shading grid bytes (CpuSplit::shading)",
            capacity: usize::try_from(max_bytes).unwrap_or(usize::MAX),
        })
}

/// The azimuths a bake of `needs` holds (0 without visibility) and the grid level [`grid_level`] picks
/// among `sizes`, after checking `azimuths`: what every bake and cache key starts from.
fn grid_choice(
    sizes: &[(u32, u32)],
    needs: &Needs,
    azimuths: u32,
    max_bytes: u64,
) -> Result<(u32, usize)> {
    check_azimuths(azimuths)?;
    let d = if needs.bake_horizons { azimuths } else { 0 };
    Ok((d, grid_level(sizes, d, max_bytes)?))
}

/// The pyramid level sizes a package holds, finest first.
fn package_sizes(package: &Package) -> Vec<(u32, u32)> {
    package
        .header()
        .levels
        .iter()
        .map(|l| (l.width, l.height))
        .collect()
}

fn check_azimuths(azimuths: u32) -> Result<()> {
    if azimuths == 0 || azimuths > MAX_AZIMUTHS || !azimuths.is_multiple_of(4) {
        return Err(Error::Invalid {
            what: "azimuths".into(),
            reason: format!("{azimuths} is not a multiple of 4 in 4..={MAX_AZIMUTHS}"),
        });
    }
    Ok(())
}

/// The parameters every cache key hashes after the terrain's identity: what is baked, and on which level.
fn key_params(h: &mut Hash64, needs: &Needs, azimuths: u32, level: usize) {
    h.write_u32(u32::from(needs.bake_horizons));
    h.write_u32(azimuths);
    h.write_u64(level as u64);
    h.write_u32(SAT_FRAC_BITS);
    h.write_u64(horizon::DEFAULT_MAX_SAMPLES.to_bits());
}

/// The shading cache key of a resident terrain: its content and every parameter that changes the tables.
fn shading_cache_key(hm: &Heightmap, needs: &Needs, azimuths: u32, level: usize) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(SHADING_FORMAT_VERSION);
    h.write_u32(hm.width());
    h.write_u32(hm.height());
    h.write_f32(hm.spacing());
    h.write_bytes(bytemuck::cast_slice::<f32, u8>(hm.heights()));
    key_params(&mut h, needs, azimuths, level);
    h.finish()
}

/// The shading cache key of a package: its header (every tile's offset and CRC-32) and the parameters.
fn package_cache_key(package: &Package, needs: &Needs, azimuths: u32, level: usize) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(SHADING_FORMAT_VERSION);
    h.write_bytes(b"package");
    h.write_bytes(&package.header().to_bytes());
    key_params(&mut h, needs, azimuths, level);
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
    /// The data's (level 0's) samples per row and rows, and its spacing in metres: the extent the fog
    /// fits and the spacing the shader's footprint uses, without the terrain at hand.
    data: (u32, u32),
    spacing: f32,
    /// (width + 1) x (height + 1) texels, 4 u32 each: (n + 1) / 2 per normal component, 0. Shared: the
    /// renderer keeps the bake to fill its per-level tables ([`ShadingBake::level_texel`]).
    normal: Arc<[u32]>,
    /// Layers of (width + 1) x (height + 1) texels, 4 azimuths each: (a + pi/2) / pi.
    horizon: Arc<[u32]>,
    baked: Vec<&'static str>,
}

impl ShadingBake {
    /// Bakes what `needs` asks for on the finest level of `hm` whose tables fit `max_bytes`
    /// ([`grid_level`]): always the normal SAT; the horizons ([`horizon::texel_horizons`], `azimuths`
    /// of them) and their SATs only when `needs.bake_horizons`.
    pub fn bake(
        hm: &Heightmap,
        needs: &Needs,
        azimuths: u32,
        max_bytes: u64,
        progress: Progress<'_>,
    ) -> Result<Self> {
        let (d, k) = grid_choice(
            &level_sizes(hm.width(), hm.height()),
            needs,
            azimuths,
            max_bytes,
        )?;
        let data = (hm.width(), hm.height());
        if k == 0 {
            return Self::bake_grid(hm, 1, d, data, hm.spacing(), progress);
        }
        let pyramid = Pyramid::build(hm);
        if k >= pyramid.len() {
            return Err(Error::Capacity {
                what: "shading grid level (pyramid levels)",
                capacity: pyramid.len(),
            });
        }
        let l = pyramid.level(k);
        let step = 1u32 << k;
        #[expect(clippy::cast_precision_loss, reason = "a power of two below 2^32")]
        let spacing = hm.spacing() * step as f32;
        let grid = Heightmap::new(
            Path::new("shading grid"),
            l.width(),
            l.height(),
            spacing,
            l.heights().to_vec(),
        )?;
        drop(pyramid);
        Self::bake_grid(&grid, step, d, data, hm.spacing(), progress)
    }

    /// [`ShadingBake::bake`] out of core from a package: the grid is the package's own finest level whose
    /// tables fit `max_bytes`, decoded alone (with its coarser levels, never level 0 unless it fits).
    pub fn bake_package(
        package: &Package,
        needs: &Needs,
        azimuths: u32,
        max_bytes: u64,
        progress: Progress<'_>,
    ) -> Result<Self> {
        let (d, k) = grid_choice(&package_sizes(package), needs, azimuths, max_bytes)?;
        let h = package.header();
        let dims = h.levels[k];
        let step = 1u32 << k;
        // In place: the quantum units become metres in the same allocation.
        let heights: Vec<f32> = package
            .decode_level(k)?
            .into_iter()
            .map(|v| package.metres(v))
            .collect();
        #[expect(clippy::cast_precision_loss, reason = "a power of two below 2^32")]
        let spacing = h.spacing * step as f32;
        let grid = Heightmap::new(package.path(), dims.width, dims.height, spacing, heights)?;
        Self::bake_grid(&grid, step, d, (h.width, h.height), h.spacing, progress)
    }

    /// The tables of `grid` (level log2(`step`) of the data), `d` horizons (0: none), written row by row.
    fn bake_grid(
        grid: &Heightmap,
        step: u32,
        d: u32,
        data: (u32, u32),
        spacing: f32,
        progress: Progress<'_>,
    ) -> Result<Self> {
        let (w, h) = (grid.width(), grid.height());
        let pw = w as usize + 1;
        let texels = pw * (h as usize + 1);
        let du = d as usize;
        let (mut normal_arc, mut horizon_arc) =
            (zeroed(texels * 4), zeroed(du.div_ceil(4) * texels * 4));
        let normal = unique(&mut normal_arc);
        let horizon = unique(&mut horizon_arc);
        // The horizons' march is the slow part; the normals alone take a moment.
        let mut meter = (d > 0).then(|| progress.task("baking horizons, rows", u64::from(h)));
        // Quantised up to 2^-20 as Sat::build does; a u32 of at most 2^20.
        let quantum = |v: f64, x: u32, y: u32| -> u32 {
            let q = Sat::quantise_up(v.clamp(0.0, 1.0), SAT_FRAC_BITS, x, y);
            u32::try_from(q).expect("a value in [0, 1] is at most 2^20 quanta")
        };
        let mut angles = [0.0f32; MAX_AZIMUTHS as usize];
        for y in 0..h {
            let mut run = [0u32; 3];
            let mut hrun = [0u32; MAX_AZIMUTHS as usize];
            for x in 0..w {
                // Entry (x + 1, y + 1) is the one above it plus row y's prefix through x.
                let at = ((y as usize + 1) * pw + x as usize + 1) * 4;
                let above = at - pw * 4;
                let n = horizon::texel_normal(grid, x, y);
                for c in 0..3 {
                    run[c] = run[c].wrapping_add(quantum((n[c] + 1.0) * 0.5, x, y));
                    normal[at + c] = normal[above + c].wrapping_add(run[c]);
                }
                if du == 0 {
                    continue;
                }
                horizon::texel_horizons(
                    grid,
                    x,
                    y,
                    horizon::DEFAULT_MAX_SAMPLES,
                    &mut angles[..du],
                );
                for (k, &a) in angles[..du].iter().enumerate() {
                    hrun[k] = hrun[k].wrapping_add(quantum((f64::from(a) + FRAC_PI_2) / PI, x, y));
                    let layer = (k / 4) * texels * 4 + k % 4;
                    horizon[layer + at] = horizon[layer + above].wrapping_add(hrun[k]);
                }
            }
            if let Some(m) = &mut meter {
                m.inc(1);
            }
        }
        if let Some(m) = &mut meter {
            m.finish();
        }
        Ok(Self {
            width: w,
            height: h,
            step,
            azimuths: d,
            data,
            spacing,
            normal: normal_arc,
            horizon: horizon_arc,
            baked: baked_names(d),
        })
    }

    /// [`ShadingBake::bake`] through the disk cache in `dir` ([`crate::bake::default_cache_dir`]): a
    /// valid `shading-<key>.bin` is read, else the tables are baked and written. The key hashes the
    /// terrain (size, spacing, every height's bits), every bake parameter and the grid's level; a damaged
    /// or mismatched file is rebaked, never trusted.
    pub fn bake_cached(
        hm: &Heightmap,
        needs: &Needs,
        azimuths: u32,
        max_bytes: u64,
        dir: &Path,
        progress: Progress<'_>,
    ) -> Result<(Self, CacheOutcome)> {
        let (_, k) = grid_choice(
            &level_sizes(hm.width(), hm.height()),
            needs,
            azimuths,
            max_bytes,
        )?;
        let key = shading_cache_key(hm, needs, azimuths, k);
        Self::cached(key, needs, dir, || {
            Self::bake(hm, needs, azimuths, max_bytes, progress)
        })
    }

    /// [`ShadingBake::bake_package`] through the disk cache, keyed by the package's header (every tile's
    /// CRC-32), the parameters and the grid's level.
    pub fn bake_package_cached(
        package: &Package,
        needs: &Needs,
        azimuths: u32,
        max_bytes: u64,
        dir: &Path,
        progress: Progress<'_>,
    ) -> Result<(Self, CacheOutcome)> {
        let (_, k) = grid_choice(&package_sizes(package), needs, azimuths, max_bytes)?;
        let key = package_cache_key(package, needs, azimuths, k);
        Self::cached(key, needs, dir, || {
            Self::bake_package(package, needs, azimuths, max_bytes, progress)
        })
    }

    /// The cache file of `key` in `dir`, else `bake` and write it.
    fn cached(
        key: u64,
        needs: &Needs,
        dir: &Path,
        bake: impl FnOnce() -> Result<Self>,
    ) -> Result<(Self, CacheOutcome)> {
        let path = dir.join(format!("shading-{}.bin", hex(key)));
        let refused = match std::fs::File::open(&path) {
            Ok(file) => match Self::read(file, key, needs.bake_horizons) {
                Ok(b) => return Ok((b, CacheOutcome::Hit)),
                Err(reason) => Some(reason),
            },
            Err(_) => None,
        };
        let bake = bake()?;
        let outcome = match bake.write(&path, key) {
            Err(e) => CacheOutcome::NotCached(e.to_string()),
            Ok(()) => refused.map_or(CacheOutcome::Baked, CacheOutcome::Rebaked),
        };
        Ok((bake, outcome))
    }

    /// Writes the cache file through a buffer, atomically (a temporary file renamed into place). Layout,
    /// little-endian: magic `CSATSHD1`, format version, key, width, height, step, azimuths, the data's
    /// width and height, its spacing's bits, the normal table, the horizon table (u32 each), and a CRC-32
    /// of every byte before it.
    fn write(&self, path: &Path, key: u64) -> Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
        }
        let tmp = path.with_extension(format!("tmp{}", crate::temp_suffix()));
        let io = |e| Error::io(&tmp, "cannot write", e);
        let file = std::fs::File::create(&tmp).map_err(io)?;
        let mut out = Crc32Writer {
            inner: BufWriter::with_capacity(1 << 16, file),
            crc: crc32fast::Hasher::new(),
        };
        let mut head = Vec::with_capacity(HEADER_BYTES);
        head.extend_from_slice(SHADING_MAGIC);
        head.extend_from_slice(&SHADING_FORMAT_VERSION.to_le_bytes());
        head.extend_from_slice(&key.to_le_bytes());
        let (dw, dh) = self.data;
        for w in [
            self.width,
            self.height,
            self.step,
            self.azimuths,
            dw,
            dh,
            self.spacing.to_bits(),
        ] {
            head.extend_from_slice(&w.to_le_bytes());
        }
        out.write_all(&head).map_err(io)?;
        let mut chunk = Vec::with_capacity(1 << 16);
        for part in self
            .normal
            .chunks(1 << 14)
            .chain(self.horizon.chunks(1 << 14))
        {
            chunk.clear();
            chunk.extend(part.iter().flat_map(|v| v.to_le_bytes()));
            out.write_all(&chunk).map_err(io)?;
        }
        let crc = out.crc.clone().finalize();
        let mut file = out.inner;
        file.write_all(&crc.to_le_bytes()).map_err(io)?;
        file.flush().map_err(io)?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, "cannot rename into place", e))
    }

    /// Reads a cache file through a buffer straight into the tables, checking the CRC-32 as it goes.
    fn read(file: std::fs::File, key: u64, horizons: bool) -> std::result::Result<Self, String> {
        let len = file.metadata().map_err(|e| e.to_string())?.len();
        let mut r = BufReader::with_capacity(1 << 16, file);
        let mut crc = crc32fast::Hasher::new();
        let mut head = [0u8; HEADER_BYTES];
        r.read_exact(&mut head)
            .map_err(|_| "shorter than its header".to_string())?;
        crc.update(&head);
        if &head[..8] != SHADING_MAGIC {
            return Err("not a clipsat shading cache file (bad magic)".into());
        }
        let word = |i: usize| u32::from_le_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
        let version = word(8);
        if version != SHADING_FORMAT_VERSION {
            return Err(format!(
                "format version {version}, expected {SHADING_FORMAT_VERSION}"
            ));
        }
        if u64::from(word(12)) | u64::from(word(16)) << 32 != key {
            return Err("key does not match".into());
        }
        let [width, height, step, azimuths, dw, dh, spacing] =
            std::array::from_fn(|i| word(20 + 4 * i));
        if width == 0 || height == 0 || dw == 0 || dh == 0 || !step.is_power_of_two() {
            return Err("sizes in the header are out of range".into());
        }
        if azimuths > MAX_AZIMUTHS || !azimuths.is_multiple_of(4) || horizons != (azimuths > 0) {
            return Err("horizon tables do not match the key".into());
        }
        let texels = (u64::from(width) + 1) * (u64::from(height) + 1);
        let words = texels * 4 * (1 + u64::from(azimuths / 4));
        if len != HEADER_BYTES as u64 + words * 4 + 4 {
            return Err(format!(
                "{len} bytes, expected {}",
                HEADER_BYTES as u64 + words * 4 + 4
            ));
        }
        let mut buf = vec![0u8; 1 << 16];
        let mut table = |n: u64| -> std::result::Result<Arc<[u32]>, String> {
            let mut arc = zeroed(usize::try_from(n).map_err(|_| "size overflow")?);
            for part in unique(&mut arc).chunks_mut(buf.len() / 4) {
                let bytes = &mut buf[..part.len() * 4];
                r.read_exact(bytes).map_err(|e| e.to_string())?;
                crc.update(bytes);
                for (v, c) in part.iter_mut().zip(bytes.chunks_exact(4)) {
                    *v = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                }
            }
            Ok(arc)
        };
        let normal = table(texels * 4)?;
        let horizon = table(texels * 4 * u64::from(azimuths / 4))?;
        let mut trailer = [0u8; 4];
        r.read_exact(&mut trailer).map_err(|e| e.to_string())?;
        if crc.finalize() != u32::from_le_bytes(trailer) {
            return Err("checksum mismatch (corrupted file)".into());
        }
        Ok(Self {
            width,
            height,
            step,
            azimuths,
            data: (dw, dh),
            spacing: f32::from_bits(spacing),
            normal,
            horizon,
            baked: baked_names(azimuths),
        })
    }

    /// The data's spacing, metres (level 0's, whatever the grid's level).
    pub fn data_spacing(&self) -> f32 {
        self.spacing
    }

    /// The data's extent east and north, metres, as [`Heightmap::extent_m`] gives it.
    pub fn data_extent_m(&self) -> (f64, f64) {
        let s = f64::from(self.spacing);
        (
            f64::from(self.data.0.saturating_sub(1)) * s,
            f64::from(self.data.1.saturating_sub(1)) * s,
        )
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

/// A shared table of `n` zeros, allocated once where it lives (a `Vec` turned into an `Arc` would be
/// copied, holding the table twice for a moment).
fn zeroed(n: usize) -> Arc<[u32]> {
    std::iter::repeat_n(0u32, n).collect()
}

/// The table [`zeroed`] just made, to fill.
fn unique(table: &mut Arc<[u32]>) -> &mut [u32] {
    Arc::get_mut(table).expect("a table just made has no other owner")
}

/// The maps a bake with `d` horizons holds, by name.
fn baked_names(d: u32) -> Vec<&'static str> {
    let mut baked = vec!["normal_sat"];
    if d > 0 {
        baked.extend(["horizons", "horizon_sat"]);
    }
    baked
}

/// A writer that checksums what passes through it.
struct Crc32Writer<W> {
    inner: W,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Crc32Writer<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.crc.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
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
        let (first, outcome) =
            ShadingBake::bake_cached(&hm, &needs, 8, u64::MAX, &dir, Progress::default()).expect("bake");
        assert_eq!(outcome, CacheOutcome::Baked);
        let (again, outcome) =
            ShadingBake::bake_cached(&hm, &needs, 8, u64::MAX, &dir, Progress::default()).expect("hit");
        assert_eq!(outcome, CacheOutcome::Hit);
        assert_eq!(again, first);
        // Another parameter is another file; no horizons reads back no horizons.
        let (plain, outcome) =
            ShadingBake::bake_cached(&hm, &Needs::default(), 8, u64::MAX, &dir, Progress::default()).expect("plain");
        assert_eq!((outcome, plain.azimuths()), (CacheOutcome::Baked, 0));
        assert_eq!(plain.baked(), ["normal_sat"]);
        // A flipped byte fails the trailing hash: rebaked, same tables.
        let path = dir.join(format!(
            "shading-{}.bin",
            hex(shading_cache_key(&hm, &needs, 8, 0))
        ));
        let mut bytes = std::fs::read(&path).expect("cache file");
        bytes[40] ^= 1;
        std::fs::write(&path, &bytes).expect("damage");
        let (fixed, outcome) =
            ShadingBake::bake_cached(&hm, &needs, 8, u64::MAX, &dir, Progress::default()).expect("rebake");
        assert!(matches!(outcome, CacheOutcome::Rebaked(_)), "{outcome:?}");
        assert_eq!(fixed, first);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
