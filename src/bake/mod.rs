//! Stage 1, bake: everything computed once per terrain before the first frame.
//!
//! - [`pyramid`]: the height pyramid (GC section 4);
//! - [`sat`]: summed-area tables in exact fixed point;
//! - [`lod_tables`]: the SAT LOD error maps, their SATs and max pyramids (design.md "SAT LOD");
//! - [`horizon`]: horizon angles for SG visibility (SAT paper section 5);
//! - this file: the LOD tables' disk cache, keyed by a content hash.
//!
//! # The cache
//!
//! The cache folder is `$CLIPSAT_CACHE` when set, else `target/clipsat-cache` under the current folder
//! (inside the build tree, so `cargo clean` clears it and nothing leaks into the user's home). A file is
//! `lod-<key>.bin`, the key a 64-bit [`Hash64`] of the terrain (size, spacing, every height's bits) and the
//! parameters (format version, p, quantum bits, level count, synthesised rings, g_0).
//!
//! Layout, little-endian: magic `CSATLOD1`, version, key, p, width, height, levels, quantum bits; per level
//! k E_L (f32), a has-tables flag, then (if set) the closed cells' maximum errors (f32 per cell) and the SAT
//! (u64 per entry), both at level k's resolution ([`LevelTables`]: cells of 2^k samples);
//! last, a [`Hash64`] of every byte before it. A file whose magic, version, key, sizes or trailing hash do
//! not match is rebaked and overwritten, never trusted and never a panic. Files are written to a temporary
//! name and renamed, so a killed bake leaves no half file under the real name.

pub mod horizon;
pub mod lod_tables;
pub mod pyramid;
pub mod sat;

use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};

use crate::bake::lod_tables::{LevelTables, LodTables, RangeMax};
use crate::bake::pyramid::Pyramid;
use crate::bake::sat::Sat;
use crate::hash::{hex, Hash64};
use crate::{Error, Heightmap, Result};

const MAGIC: &[u8; 8] = b"CSATLOD1";
/// Bumped whenever the layout or the meaning of a baked number changes.
pub const FORMAT_VERSION: u32 = 2;

/// The default cache folder: `$CLIPSAT_CACHE`, else `target/clipsat-cache`.
pub fn default_cache_dir() -> PathBuf {
    std::env::var_os("CLIPSAT_CACHE")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target/clipsat-cache"))
}

/// What the bake parameters are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeParams {
    /// SFAMF exponent p.
    pub p: u32,
    /// Clipmap levels (rings).
    pub levels: u32,
    /// Rings finer than the data.
    pub synth_levels: u32,
    /// Level-0 spacing, metres.
    pub g0: f64,
}

impl BakeParams {
    /// Data levels to bake: the rings at or coarser than the data.
    pub fn data_levels(&self) -> u32 {
        self.levels.saturating_sub(self.synth_levels).max(1)
    }
}

/// How the tables were obtained.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from a valid cache file.
    Hit,
    /// No cache file: baked and written.
    Baked,
    /// A cache file existed but was refused (the reason); baked and overwritten.
    Rebaked(String),
    /// Baked; the cache could not be written (the reason). The tables are still good.
    NotCached(String),
}

/// The cache key of a terrain and parameters.
pub fn cache_key(terrain: &Heightmap, params: &BakeParams) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(FORMAT_VERSION);
    h.write_u32(terrain.width());
    h.write_u32(terrain.height());
    h.write_f32(terrain.spacing());
    h.write_bytes(bytemuck::cast_slice::<f32, u8>(terrain.heights()));
    h.write_u32(params.p);
    h.write_u32(Sat::max_frac_bits(
        u64::from(terrain.width()) * u64::from(terrain.height()),
    ));
    h.write_u32(params.levels);
    h.write_u32(params.synth_levels);
    h.write_u64(params.g0.to_bits());
    h.finish()
}

/// The cache file for a key in `dir`.
pub fn cache_path(dir: &Path, key: u64) -> PathBuf {
    dir.join(format!("lod-{}.bin", hex(key)))
}

/// The LOD tables of `terrain`: read from `dir`'s cache when a valid file is there, else baked (with a
/// progress bar on stderr when `progress`) and written.
pub fn bake_lod(
    terrain: &Heightmap,
    pyramid: &Pyramid,
    params: &BakeParams,
    dir: &Path,
    progress: bool,
) -> Result<(LodTables, CacheOutcome)> {
    // Before the cache: a table cached by an older build must not let an unusable terrain through.
    crate::bake::lod_tables::check_height_range(pyramid)?;
    let key = cache_key(terrain, params);
    let path = cache_path(dir, key);
    let refused = match std::fs::read(&path) {
        Ok(bytes) => match decode(&bytes, key, params) {
            Ok(t) => return Ok((t, CacheOutcome::Hit)),
            Err(reason) => Some(reason),
        },
        Err(_) => None,
    };
    let tables = bake_uncached(pyramid, params, progress)?;
    let outcome = match write_atomic(&path, &encode(&tables, key)) {
        Err(e) => CacheOutcome::NotCached(e.to_string()),
        Ok(()) => match refused {
            Some(r) => CacheOutcome::Rebaked(r),
            None => CacheOutcome::Baked,
        },
    };
    Ok((tables, outcome))
}

/// Bakes without the cache, with an optional progress bar (one step per level).
pub fn bake_uncached(pyramid: &Pyramid, params: &BakeParams, progress: bool) -> Result<LodTables> {
    let n = params.data_levels();
    let bar = if progress {
        let b = ProgressBar::new(u64::from(n));
        if let Ok(style) =
            ProgressStyle::with_template("baking LOD tables {bar:30} level {pos}/{len} {elapsed}")
        {
            b.set_style(style);
        }
        b
    } else {
        ProgressBar::hidden()
    };
    let tables = LodTables::build(pyramid, n, params.p, |k| bar.set_position(u64::from(k)))?;
    bar.finish_and_clear();
    Ok(tables)
}

pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
    }
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|e| Error::io(&tmp, "cannot write", e))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, "cannot rename into place", e))
}

fn encode(t: &LodTables, key: u64) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    let frac = Sat::max_frac_bits(u64::from(t.width) * u64::from(t.height));
    let levels = u32::try_from(t.levels.len()).expect("levels fit u32");
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&key.to_le_bytes());
    for w in [t.p, t.width, t.height, levels, frac] {
        out.extend_from_slice(&w.to_le_bytes());
    }
    for l in &t.levels {
        out.extend_from_slice(&l.e_max().to_le_bytes());
        match l.tables() {
            None => out.extend_from_slice(&0u32.to_le_bytes()),
            Some((sat, max)) => {
                out.extend_from_slice(&1u32.to_le_bytes());
                out.reserve(max.values().len() * 4 + sat.table().len() * 8);
                for v in max.values() {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                for v in sat.table() {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
    seal(&mut out);
    out
}

/// A little-endian reader that refuses to run past the end.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    /// Whether every byte has been read.
    pub(crate) fn done(&self) -> bool {
        self.at == self.bytes.len()
    }

    pub(crate) fn take(&mut self, n: usize) -> std::result::Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| format!("truncated at byte {}", self.at))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    pub(crate) fn u32(&mut self) -> std::result::Result<u32, String> {
        let mut w = [0u8; 4];
        w.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(w))
    }

    pub(crate) fn u64(&mut self) -> std::result::Result<u64, String> {
        let mut w = [0u8; 8];
        w.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(w))
    }
}

/// Appends the trailing [`Hash64`] of every byte so far (the last 8 bytes of every cache file).
pub(crate) fn seal(out: &mut Vec<u8>) {
    let mut h = Hash64::new();
    h.write_bytes(out);
    out.extend_from_slice(&h.finish().to_le_bytes());
}

/// Checks a cache file's magic and trailing hash ([`seal`]); a reader just past the magic, over the body.
pub(crate) fn unseal<'a>(
    bytes: &'a [u8],
    magic: &[u8; 8],
    what: &str,
) -> std::result::Result<Reader<'a>, String> {
    if bytes.len() < 8 + 8 || &bytes[..8] != magic {
        return Err(format!("not a clipsat {what} cache file (bad magic)"));
    }
    let (body, trailer) = bytes.split_at(bytes.len() - 8);
    let mut h = Hash64::new();
    h.write_bytes(body);
    let mut t = [0u8; 8];
    t.copy_from_slice(trailer);
    if h.finish() != u64::from_le_bytes(t) {
        return Err("content hash mismatch (corrupted file)".into());
    }
    Ok(Reader { bytes: body, at: 8 })
}

fn decode(bytes: &[u8], key: u64, params: &BakeParams) -> std::result::Result<LodTables, String> {
    let mut r = unseal(bytes, MAGIC, "LOD")?;
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(format!(
            "format version {version}, expected {FORMAT_VERSION}"
        ));
    }
    let file_key = r.u64()?;
    if file_key != key {
        return Err(format!("key {} does not match {}", hex(file_key), hex(key)));
    }
    let (p, width, height, levels, frac) = (r.u32()?, r.u32()?, r.u32()?, r.u32()?, r.u32()?);
    let n = u64::from(width) * u64::from(height);
    if p != params.p || levels != params.data_levels() || n == 0 || frac != Sat::max_frac_bits(n) {
        return Err("parameters in the header do not match".into());
    }
    let mut out = Vec::with_capacity(levels as usize);
    for k in 0..levels {
        let shift = k.min(30);
        let (cw, ch) = LevelTables::closed_cells(width, height, shift);
        let cells = usize::try_from(u64::from(cw) * u64::from(ch)).map_err(|_| "grid too large")?;
        let cell = 1u32 << shift;
        let entries = u64::from(width.div_ceil(cell)) * u64::from(height.div_ceil(cell));
        let entries = usize::try_from(entries).map_err(|_| "grid too large")?;
        let e_max = f32::from_bits(r.u32()?);
        let has = r.u32()?;
        let tables = match has {
            0 => None,
            1 => {
                let errs: Vec<f32> = r
                    .take(cells.checked_mul(4).ok_or("size overflow")?)?
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                let sat: Vec<u64> = r
                    .take(entries.checked_mul(8).ok_or("size overflow")?)?
                    .chunks_exact(8)
                    .map(|c| {
                        let mut w = [0u8; 8];
                        w.copy_from_slice(c);
                        u64::from_le_bytes(w)
                    })
                    .collect();
                if !(e_max.is_finite() && e_max > 0.0)
                    || errs
                        .iter()
                        .any(|e| !(e.is_finite() && *e >= 0.0 && *e <= e_max))
                {
                    return Err("error map values out of range".into());
                }
                let sat =
                    Sat::from_parts(width, height, cell, frac, sat).map_err(|e| e.to_string())?;
                Some((sat, RangeMax::build(cw, ch, errs)))
            }
            _ => return Err(format!("bad has-tables flag {has}")),
        };
        let shift = if tables.is_some() { shift } else { 0 };
        out.push(LevelTables::from_parts(e_max, shift, tables));
    }
    if !r.done() {
        return Err("trailing bytes".into());
    }
    Ok(LodTables {
        p,
        width,
        height,
        levels: out,
    })
}
