//! Stage 1, bake: everything computed once per terrain before the first frame.
//!
//! - [`pyramid`]: the height pyramid (GC section 4);
//! - [`sat`]: summed-area tables in exact fixed point;
//! - [`lod_tables`]: the SAT LOD error maps, their SATs and max pyramids (docs/design.md "SAT LOD");
//! - [`lod_record`]: the compact per-cell records every path builds the tables from;
//! - [`horizon`]: horizon angles for SG visibility (SAT paper section 5);
//! - [`imagery`](mod@imagery): the imagery's colour pyramid (GC section 3, "additional images");
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
//! k E_L (f32), a has-tables flag, then (if set) zero padding to a multiple of 8 bytes, the SAT (u64 per
//! entry) and every level of the max pyramid over the closed cells' maximum errors (f32 per cell, finest
//! first), at level k's resolution ([`LevelTables`]: cells of 2^k samples); then, for each level with
//! tables, the finest max-pyramid level again column by column (f32, value (x, y) at x h + y: a query
//! one cell wide reads one run, [`RangeMax::with_columns`]); zero padding to a multiple of 8; last, the
//! CRC-32 of every byte before it (as a u64). A file whose magic, version, key, sizes or
//! checksum do not match is rebaked and overwritten, never trusted and never a panic. Files are written to
//! a temporary name and renamed, so a killed bake leaves no half file under the real name, and a file
//! another process has mapped is never rewritten in place.
//!
//! A valid file is read through a read-only memory map ([`mapped`]): the tables borrow their ranges of it,
//! so a large terrain's tables (about 6 B per sample: 300 MB for a 7201^2 mosaic) are never copied into
//! memory, and the pages the queries touch are held within the profile's share
//! ([`LodTables::limit_resident`]). Tables baked in this process stay in memory; [`bake_lod_mapped`]
//! re-reads them from the file it wrote.

pub mod horizon;
pub mod imagery;
pub mod lod_record;
pub mod lod_tables;
pub mod mapped;
pub mod pyramid;
pub mod range_max;
pub mod sat;

use std::path::{Path, PathBuf};


use crate::bake::lod_tables::{LevelTables, LodTables, RangeMax};
use crate::bake::mapped::{Grid, Mapping};
use crate::bake::pyramid::Pyramid;
use crate::bake::sat::Sat;
use crate::hash::{hex, Hash64};
use crate::progress::Progress;
use crate::{Error, Result};
use crate::source::Heightmap;

pub(crate) const MAGIC: &[u8; 8] = b"CSATLOD1";
/// Bumped whenever the layout or the meaning of a baked number changes.
pub const FORMAT_VERSION: u32 = 5;

/// The cache folder of the binary and the tests: `$CLIPSAT_CACHE`, else `target/clipsat-cache`. The
/// library itself never picks a folder: its callers pass one.
#[cfg(feature = "internals")]
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
    cache_key_of_version(terrain, params, FORMAT_VERSION)
}

/// [`cache_key`] as format `version` made it.
fn cache_key_of_version(terrain: &Heightmap, params: &BakeParams, version: u32) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(version);
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

/// Removes the same tables' file of the last format (its key from `key_of` the version), refused now: a
/// format change does not leave every terrain's old tables in the cache folder. Best effort: a file
/// another process holds stays.
pub(crate) fn remove_last_format(dir: &Path, key_of: impl Fn(u32) -> u64) {
    if let Some(v) = FORMAT_VERSION.checked_sub(1).filter(|&v| v > 0) {
        let _ = std::fs::remove_file(cache_path(dir, key_of(v)));
    }
}

/// The LOD tables of `terrain`: read from `dir`'s cache when a valid file is there, else baked (reporting to
/// `progress`) and written.
pub fn bake_lod(
    terrain: &Heightmap,
    pyramid: &Pyramid,
    params: &BakeParams,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<(LodTables, CacheOutcome)> {
    // Before the cache: a table cached by an older build must not let an unusable terrain through.
    crate::bake::lod_tables::check_height_range(pyramid)?;
    let key = cache_key(terrain, params);
    let baked = bake_lod_keyed(
        key,
        || Ok(std::borrow::Cow::Borrowed(pyramid)),
        params,
        dir,
        progress,
    )?;
    if matches!(baked.1, CacheOutcome::Baked | CacheOutcome::Rebaked(_)) {
        remove_last_format(dir, |v| cache_key_of_version(terrain, params, v));
    }
    Ok(baked)
}

/// The tables of the cache file at `path` read through a map: None when there is no file, the reason
/// when it is refused.
pub(crate) fn read_cached(
    path: &Path,
    key: u64,
    params: &BakeParams,
) -> Option<std::result::Result<LodTables, String>> {
    let file = std::fs::File::open(path).ok()?;
    Some(
        Mapping::new(&file)
            .map_err(|e| e.to_string())
            .and_then(|map| decode(&map, key, params)),
    )
}

/// Runs `bake` (a cached bake); when it baked and wrote the file, drops the tables it holds in memory and
/// runs it again without progress, which then reads them through the file's map. The outcome is the first
/// run's.
fn mapped(
    bake: impl Fn(Progress<'_>) -> Result<(LodTables, CacheOutcome)>,
    progress: Progress<'_>,
) -> Result<(LodTables, CacheOutcome)> {
    let (tables, outcome) = bake(progress)?;
    if tables.is_mapped() || matches!(outcome, CacheOutcome::NotCached(_)) {
        return Ok((tables, outcome));
    }
    drop(tables);
    let (again, _) = bake(Progress::default())?;
    Ok((again, outcome))
}

/// The cache lookup and bake under `key`; `pyramid` is asked for only on a miss.
fn bake_lod_keyed<'a>(
    key: u64,
    pyramid: impl FnOnce() -> Result<std::borrow::Cow<'a, Pyramid>>,
    params: &BakeParams,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<(LodTables, CacheOutcome)> {
    let path = cache_path(dir, key);
    let refused = match std::fs::File::open(&path) {
        Ok(file) => match Mapping::new(&file)
            .map_err(|e| e.to_string())
            .and_then(|map| decode(&map, key, params))
        {
            Ok(t) => return Ok((t, CacheOutcome::Hit)),
            Err(reason) => Some(reason),
        },
        Err(_) => None,
    };
    crate::temp::sweep(dir);
    let pyramid = pyramid()?;
    crate::bake::lod_tables::check_height_range(&pyramid)?;
    let tables = bake_uncached(&pyramid, params, progress)?;
    drop(pyramid);
    let outcome = match write_atomic(&path, &encode(&tables, key)) {
        Err(e) => CacheOutcome::NotCached(e.to_string()),
        Ok(()) => match refused {
            Some(r) => CacheOutcome::Rebaked(r),
            None => CacheOutcome::Baked,
        },
    };
    Ok((tables, outcome))
}

/// [`bake_lod`], then on a bake the tables are dropped and read back through the file's map, so that only
/// the pages a query touches stay resident (nothing terrain-sized in memory after the bake). Falls back to
/// the baked tables when the file cannot be written.
pub fn bake_lod_mapped(
    terrain: &Heightmap,
    pyramid: &Pyramid,
    params: &BakeParams,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<(LodTables, CacheOutcome)> {
    mapped(
        |progress| bake_lod(terrain, pyramid, params, dir, progress),
        progress,
    )
}

/// Bakes without the cache, reporting one step per level to `progress`.
pub fn bake_uncached(
    pyramid: &Pyramid,
    params: &BakeParams,
    progress: Progress<'_>,
) -> Result<LodTables> {
    let n = params.data_levels();
    let mut meter = progress.task("baking LOD tables, levels", u64::from(n));
    let tables = LodTables::build(pyramid, n, params.p, |k| meter.set_done(u64::from(k)))?;
    meter.finish();
    Ok(tables)
}

pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
    }
    let tmp =
        crate::temp::TempFile::create(path.with_extension(format!("tmp{}", crate::temp_suffix())))?;
    std::io::Write::write_all(&mut &tmp.file, bytes)
        .map_err(|e| Error::io(&tmp.path, "cannot write", e))?;
    tmp.persist(path)
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
                pad8(&mut out);
                out.reserve(
                    sat.table().len() * 8
                        + max.levels().iter().map(|g| g.len() * 4).sum::<usize>()
                        + max.values().len() * 4,
                );
                for v in sat.table() {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                for g in max.levels() {
                    for v in g.iter() {
                        out.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
    }
    for (_, max) in t.levels.iter().filter_map(LevelTables::tables) {
        for v in max.column_major() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    pad8(&mut out);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&u64::from(crc).to_le_bytes());
    out
}

/// Zero bytes up to the next multiple of 8 (the SAT's u64 entries are read in place from the map).
fn pad8(out: &mut Vec<u8>) {
    out.resize(out.len().next_multiple_of(8), 0);
}

/// Bytes checked (and then trimmed from the resident set) at a time when a mapped cache file is verified.
const VERIFY_CHUNK: usize = 4 << 20;

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

/// Reads a cache file through a read-only map: the CRC-32 trailer is checked over the whole body in
/// chunks whose pages are dropped from the resident set as soon as they are checked, then the tables
/// borrow their ranges of the map ([`mapped::Grid`]), so nothing terrain-sized is copied into memory.
fn decode(map: &Mapping, key: u64, params: &BakeParams) -> std::result::Result<LodTables, String> {
    let bytes = map.bytes();
    if bytes.len() < 16 || &bytes[..8] != MAGIC || !bytes.len().is_multiple_of(8) {
        return Err("not a clipsat LOD cache file (bad magic or length)".into());
    }
    let body_len = bytes.len() - 8;
    let mut crc = crc32fast::Hasher::new();
    for at in (0..body_len).step_by(VERIFY_CHUNK) {
        let end = (at + VERIFY_CHUNK).min(body_len);
        crc.update(&bytes[at..end]);
        map.trim_range(at, end - at);
    }
    let mut t = [0u8; 8];
    t.copy_from_slice(&bytes[body_len..]);
    if u64::from(crc.finalize()) != u64::from_le_bytes(t) {
        return Err("content checksum mismatch (corrupted file)".into());
    }
    let mut r = Reader {
        bytes: &bytes[..body_len],
        at: 8,
    };
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
        let cell = 1u32 << shift;
        let entries = u64::from(width.div_ceil(cell)) * u64::from(height.div_ceil(cell));
        let entries = usize::try_from(entries).map_err(|_| "grid too large")?;
        let e_max = f32::from_bits(r.u32()?);
        let has = r.u32()?;
        let tables = match has {
            0 => None,
            1 => {
                r.take(r.at.next_multiple_of(8) - r.at)?;
                let sat = grid::<u64>(map, &mut r, entries)?;
                let mut maxima = Vec::new();
                for (w, h) in RangeMax::dims(cw, ch) {
                    let cells = usize::try_from(u64::from(w) * u64::from(h))
                        .map_err(|_| "grid too large")?;
                    maxima.push(grid::<f32>(map, &mut r, cells)?);
                }
                if !(e_max.is_finite() && e_max > 0.0) {
                    return Err("error map values out of range".into());
                }
                // The finest maxima bound every query's exact answer: check them (a pass over a quarter
                // of the level's cells or fewer), trimming as the checksum pass did.
                if !in_range(map, &maxima[0], e_max) {
                    return Err("error map values out of range".into());
                }
                let sat =
                    Sat::from_grid(width, height, cell, frac, sat).map_err(|e| e.to_string())?;
                let max = RangeMax::from_levels(cw, ch, maxima).ok_or("bad max pyramid sizes")?;
                Some((sat, max))
            }
            _ => return Err(format!("bad has-tables flag {has}")),
        };
        let shift = if tables.is_some() { shift } else { 0 };
        out.push((e_max, shift, tables));
    }
    // Each level's finest maxima again, column by column, checked as the rows are.
    let mut levels_out = Vec::with_capacity(out.len());
    for (e_max, shift, tables) in out {
        let tables = match tables {
            None => None,
            Some((sat, max)) => {
                let (cw, ch) = max.size();
                let columns = grid::<f32>(map, &mut r, cw as usize * ch as usize)?;
                if !in_range(map, &columns, e_max) {
                    return Err("error map values out of range".into());
                }
                Some((sat, max.with_columns(columns).ok_or("bad max pyramid sizes")?))
            }
        };
        levels_out.push(LevelTables::from_parts(e_max, shift, tables));
    }
    r.take(r.at.next_multiple_of(8) - r.at)?;
    if !r.done() {
        return Err("trailing bytes".into());
    }
    Ok(LodTables {
        p,
        width,
        height,
        levels: levels_out,
        mapping: Some(map.clone()),
    })
}

/// `len` values of `T` at the reader's position, borrowed from the map (read into memory on a platform
/// where they cannot be borrowed).
fn grid<T: bytemuck::Pod>(
    map: &Mapping,
    r: &mut Reader<'_>,
    len: usize,
) -> std::result::Result<Grid<T>, String> {
    let at = r.at;
    let bytes = r.take(
        len.checked_mul(std::mem::size_of::<T>())
            .ok_or("size overflow")?,
    )?;
    Ok(Grid::mapped(map, at, len).unwrap_or_else(|| {
        Grid::owned(
            bytes
                .chunks_exact(std::mem::size_of::<T>())
                .map(bytemuck::pod_read_unaligned)
                .collect(),
        )
    }))
}

/// Whether every value of `g` is a finite error in [0, e_max]; mapped pages are trimmed as they are read.
fn in_range(map: &Mapping, g: &Grid<f32>, e_max: f32) -> bool {
    let base = g.as_ptr() as usize;
    let start = base.wrapping_sub(map.bytes().as_ptr() as usize);
    g.chunks(VERIFY_CHUNK / 4).enumerate().all(|(i, c)| {
        let ok = c.iter().all(|e| e.is_finite() && *e >= 0.0 && *e <= e_max);
        if g.is_mapped() {
            map.trim_range(start + i * VERIFY_CHUNK, c.len() * 4);
        }
        ok
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bake under this format removes the same tables' file of the last format, and no other file.
    #[test]
    fn a_bake_removes_the_last_formats_file() {
        let heights: Vec<f32> = (0..33 * 17).map(|i| (i * 7 % 31) as f32).collect();
        let hm = Heightmap::new(Path::new("test"), 33, 17, 10.0, heights).expect("terrain");
        let params = BakeParams {
            p: 8,
            levels: 4,
            synth_levels: 0,
            g0: 10.0,
        };
        let dir = std::env::temp_dir().join(format!("clipsat-last-format-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("folder");
        let last = cache_path(&dir, cache_key_of_version(&hm, &params, FORMAT_VERSION - 1));
        let other = dir.join("lod-0000000000000001.bin");
        for f in [&last, &other] {
            std::fs::write(f, b"an older file").expect("write");
        }
        let pyramid = Pyramid::build(&hm);
        let (_, outcome) = bake_lod(&hm, &pyramid, &params, &dir, Progress::default()).expect("bake");
        assert_eq!(outcome, CacheOutcome::Baked);
        assert!(!last.exists(), "the last format's file is removed");
        assert!(other.exists(), "another file stays");
        assert!(cache_path(&dir, cache_key(&hm, &params)).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
