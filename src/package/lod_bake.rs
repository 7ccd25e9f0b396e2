//! Stage 1, bake: a package's SAT LOD records, the compact tables [`crate::bake::lod_record`]
//! defines, in the package itself.
//!
//! - [`bake_records`]: `clipsat bake` computes them out of core from the package it has just written
//!   ([`crate::package::lod_stream`]'s two sweeps: the package read a band of tiles at a time), each level's finished
//!   tile rows coded ([`crate::package::lod_tiles`]) and spooled to a file beside the package, which the
//!   writer then appends.
//!   Data levels 1 ..= [`DERIVED_LEVELS`] keep only their E: their records are not stored (format 3).
//! - [`tables_from_records`]: at run time the mapped LOD cache file ([`crate::bake`], keyed as before) is
//!   built from the record tiles, one tile row of cells at a time, without computing an error, and the
//!   derived levels from the heights (lod_stream's second sweep with the stored E, out of core as the
//!   bake): the same bytes `lod_stream::bake_to_file` writes from the heights (both decode
//!   the same records), so every level chosen and every frame hash is the same either way.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::bake::lod_record::Coder;
use crate::package::lod_stream::{lay_out_file, write_tables, Level, Sweep};
use crate::bake::sat::Sat;
use crate::bake::BakeParams;
use crate::package::codec::{Decoder, Encoder};
use crate::package::lod_tiles::{RecordGrid, RecordRows};
use crate::package::{CodecKind, Package};
use crate::progress::Progress;
use crate::{Error, Result};

/// Data levels a package's records cover: 1 ..= this, every data level a profile of at most
/// [`crate::profile::MAX_LEVELS`] rings can ask for.
pub const RECORD_LEVELS: u32 = crate::profile::MAX_LEVELS - 1;

/// Data levels 1 ..= this keep only their E in the package: their records are derived from the heights
/// when the tables are built ([`tables_from_records`]).
///
/// Level 1 has a record pair for every 4 samples, three quarters of the records' bytes (0.30-0.38
/// B/sample on the shared land terrains at `--max-error 0.5`; its codes carry 4.4 and 4.1 bits on Big
/// Tujunga at order 0, 3.9 and 4.0 given their neighbours), and its errors are one sweep over levels 0
/// and 1; level 2 would save a fifth as much for the same sweep again.
pub const DERIVED_LEVELS: u32 = 1;

/// One level's record tiles, spooled.
#[derive(Debug)]
pub struct SpooledLevel {
    /// The data level.
    pub k: u32,
    /// E_k, metres.
    pub e_max: f32,
    /// The spool file.
    pub path: PathBuf,
    /// Per tile: (offset in the spool, length, CRC-32).
    pub entries: Vec<(u64, u32, u32)>,
    /// Whether its tiles were spooled (false for the derived levels: E alone, no spool file).
    pub stored: bool,
}

/// The records of data levels 1 ..= `levels` of `package` (exponent `p`) in record tiles of `tile`
/// cells coded with `codec`, each level's spooled to a file named after `spool` (removed by the caller;
/// removed here on an error). Out of core: [`crate::package::lod_stream`]'s band sweeps, O(width) per level.
///
/// Errors: the package's I/O and damaged tiles, a non-finite error (naming its sample), the spools' I/O.
pub fn bake_records(
    package: &Package,
    p: u32,
    levels: u32,
    (tile, codec, zstd_level): (u32, CodecKind, i32),
    spool: &Path,
    progress: Progress<'_>,
) -> Result<Vec<SpooledLevel>> {
    let suffix = crate::temp_suffix();
    let paths: Vec<PathBuf> = (1..=levels)
        .map(|k| spool.with_extension(format!("lod{k}.tmp{suffix}")))
        .collect();
    let out = spool_levels(
        package,
        p,
        levels,
        (tile, codec, zstd_level),
        &paths,
        progress,
    );
    if out.is_err() {
        for path in &paths {
            let _ = std::fs::remove_file(path);
        }
    }
    out
}

/// [`bake_records`] into the spool files `paths` (one per level, created here; the caller removes them).
pub(crate) fn spool_levels(
    package: &Package,
    p: u32,
    levels: u32,
    (tile, codec, zstd_level): (u32, CodecKind, i32),
    paths: &[PathBuf],
    progress: Progress<'_>,
) -> Result<Vec<SpooledLevel>> {
    let mut sw = Sweep::new(package, p, 1..levels + 1, progress)?;
    sw.sweep_e()?;
    let (width, height) = (sw.width, sw.height);
    // The derived levels keep their E only: no tables swept, no tiles.
    let derived = DERIVED_LEVELS.min(levels) as usize;
    let mut out: Vec<SpooledLevel> = sw
        .levels
        .drain(..derived)
        .zip(paths)
        .map(|(lv, path)| SpooledLevel {
            k: lv.k,
            e_max: lv.e_max,
            path: path.clone(),
            entries: Vec::new(),
            stored: false,
        })
        .collect();
    let paths = &paths[derived..];
    let mut zero = Vec::new();
    for (lv, path) in sw.levels.iter_mut().zip(paths) {
        let io = |e| Error::io(path, "cannot write", e);
        let file = File::create(path).map_err(io)?;
        let enc = Encoder::new(codec, zstd_level).map_err(io)?;
        let mut rec = RecordRows::new(RecordGrid::new(width, height, lv.k, tile), enc, file);
        if lv.has_tables() {
            lv.lay_out(width, height, 0);
            lv.records = Some(rec);
        } else {
            rec.zeros().map_err(io)?;
            zero.push((lv.k, rec.finish().map_err(io)?));
        }
    }
    if let Some(first) = paths.first() {
        sw.sweep_tables(None, first)?;
    }
    sw.meter.finish();
    for (lv, path) in sw.levels.iter_mut().zip(paths) {
        let entries = match lv.records.take() {
            Some(rec) => rec
                .finish()
                .map_err(|e| Error::io(path, "cannot write", e))?,
            None => zero
                .iter()
                .find(|(k, _)| *k == lv.k)
                .map(|(_, e)| e.clone())
                .unwrap_or_default(),
        };
        out.push(SpooledLevel {
            k: lv.k,
            e_max: lv.e_max,
            path: path.clone(),
            entries,
            stored: true,
        });
    }
    Ok(out)
}

/// Whether `package`'s records can build the tables of `params` (the same exponent, every data level).
pub fn records_cover(package: &Package, params: &BakeParams) -> bool {
    package.header().lod.as_ref().is_some_and(|l| {
        l.p == params.p && l.levels.len() as u64 + 1 >= u64::from(params.data_levels())
    })
}

/// Writes the LOD cache file of `params` at `path` under `key` from `package`'s record tiles (checked
/// by [`records_cover`]), one tile row of cells at a time per level: the same bytes
/// `lod_stream::bake_to_file` writes. A damaged record tile is an error naming its level and tile.
pub fn tables_from_records(
    package: &Package,
    params: &BakeParams,
    key: u64,
    path: &Path,
) -> Result<()> {
    let header = package.header();
    let lod = header
        .lod
        .as_ref()
        .filter(|_| records_cover(package, params))
        .ok_or_else(|| {
            Error::format(
                package.path(),
                "the package's LOD tables do not cover the profile",
            )
        })?;
    let (width, height) = (header.width, header.height);
    let p = params.p;
    let n = params.data_levels();
    // Levels without record tiles are swept from the heights (lod_stream's second sweep, E from the
    // header): the tables `clipsat bake` would have coded, so the file is the same either way.
    let derived = lod.derived.min(n.saturating_sub(1));
    let mut sweep = if derived > 0 {
        Some(Sweep::new(package, p, 1..derived + 1, Progress::default())?)
    } else {
        None
    };
    let mut levels: Vec<Level> = sweep
        .as_mut()
        .map(|sw| std::mem::take(&mut sw.levels))
        .unwrap_or_default();
    levels.extend((derived + 1..n).map(|k| Level::new(k, width, p)));
    for lv in &mut levels {
        lv.e_max = lod.level(lv.k).map_or(0.0, |l| l.e_max);
    }
    let layout = lay_out_file(&mut levels, p, width, height, key);
    let mut levels_stored = levels.split_off(derived as usize);
    if let Some(sw) = sweep.as_mut() {
        sw.levels = levels;
    }
    let guard = crate::temp::TempFile::create(path.with_extension(format!("tmp{}", crate::temp_suffix())))?;
    let tmp = guard.path.clone();
    let q = Sat::max_frac_bits(u64::from(width) * u64::from(height));
    let tile = lod.tile();
    let written = write_tables(&tmp, &layout, |file| {
        if let Some(sw) = sweep.as_mut() {
            sw.sweep_tables(Some(file), &tmp)?;
        }
        let mut dec = Decoder::new(header.codec, tile as usize * tile as usize)
            .map_err(|e| Error::io(package.path(), "cannot start the tile decoder", e))?;
        for lv in levels_stored.iter_mut().filter(|l| l.has_tables()) {
            let coder = Coder::new(lv.e_max, p, q, lv.k.min(30), width, height);
            level_from_records(package, lv, &coder, tile, &mut dec, file).map_err(|e| match e {
                Fail::Io(e) => Error::io(&tmp, "cannot write", e),
                Fail::Package(e) => e,
            })?;
        }
        Ok(())
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    guard.persist(path)
}

/// Why a level's tables could not be written: the cache file or the package.
enum Fail {
    Io(std::io::Error),
    Package(Error),
}

/// One level's tables from its record tiles, a tile row at a time: each closed row's maxima decoded and
/// written into the max pyramid, then each half-open row's lower sums into the SAT.
fn level_from_records(
    package: &Package,
    lv: &mut Level,
    coder: &Coder,
    tile: u32,
    dec: &mut Decoder,
    file: &File,
) -> std::result::Result<(), Fail> {
    let g = RecordGrid::new(package.header().width, package.header().height, lv.k, tile);
    let (cw, sw) = (g.cw as usize, g.sw as usize);
    let t = tile as usize;
    let (mut max_rows, mut mean_rows) = (vec![0u8; t * cw], vec![0u8; t * sw]);
    let (mut tmax, mut tmean, mut scratch) = (vec![0u8; t * t], vec![0u8; t * t], Vec::new());
    let mut codes = vec![0u8; sw];
    for ty in 0..g.tiles_y {
        for tx in 0..g.tiles_x {
            let (mx, _, mw, mh) = g.max_rect(tx, ty);
            let (nx, _, nw, nh) = g.mean_rect(tx, ty);
            let (mn, nn) = ((mw * mh) as usize, (nw * nh) as usize);
            package
                .decode_record_tile(
                    dec,
                    lv.k,
                    (tx, ty),
                    &mut tmax[..mn],
                    &mut tmean[..nn],
                    &mut scratch,
                )
                .map_err(Fail::Package)?;
            for (j, row) in tmax[..mn].chunks(mw.max(1) as usize).enumerate() {
                let at = j * cw + mx as usize;
                max_rows[at..at + row.len()].copy_from_slice(row);
            }
            for (j, row) in tmean[..nn].chunks(nw.max(1) as usize).enumerate() {
                let at = j * sw + nx as usize;
                mean_rows[at..at + row.len()].copy_from_slice(row);
            }
        }
        let (_, my, _, mh) = g.max_rect(0, ty);
        let (_, ny, _, nh) = g.mean_rect(0, ty);
        for j in 0..nh {
            let r = ny + j;
            if r >= my && r < my + mh {
                let row = &max_rows[(r - my) as usize * cw..][..cw];
                for (a, &c) in lv.acc.iter_mut().zip(row) {
                    *a = coder.max_decode(c);
                }
                lv.cur = r;
                lv.emit_closed(Some(file)).map_err(Fail::Io)?;
            }
            codes.copy_from_slice(&mean_rows[j as usize * sw..][..sw]);
            let mut lower = std::mem::take(&mut lv.lower);
            coder.decode_mean_row(r, &codes, &lv.dmax, &mut lower);
            lv.lower = lower;
            lv.write_sat_row(file, r).map_err(Fail::Io)?;
        }
    }
    Ok(())
}

/// The records' tiles of every level, for [`crate::package::lod_stream`]'s callers that report them.
pub fn record_bytes(levels: &[SpooledLevel]) -> u64 {
    levels
        .iter()
        .flat_map(|l| l.entries.iter())
        .map(|e| u64::from(e.1))
        .sum()
}
