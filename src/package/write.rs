//! Stage 1b, the package: the bake, heightmap -> quantised residual pyramid in compressed tiles (GC section 7).
//!
//! The pyramid is the project's own (binomial filter D, [`crate::bake::pyramid::Pyramid`]). Heights are
//! stored as integers over one quantum q (the source's own lattice where the bound allows, else twice
//! the bound), each level's prediction errors quantised with that level's step so that every level of
//! the decoded pyramid is within the bound whichever level a ring shows (GC section 7: one bound for all
//! levels). Coarse to fine, each level is predicted from the coarser level as the decoder reconstructs
//! it and from its own decoded neighbours (`levels.rs`, `docs/package-codec.md`): the arithmetic is
//! exact, so the decoder rebuilds every level exactly as the encoder did.

use std::io::Write;
use std::path::Path;

use super::codec::Encoder;
use super::format::{CodecKind, Header, TileEntry};
use super::levels::{self, Quantiser};
use super::spill::{on_lattice, Removing, Spilled, TempFile};
use crate::progress::Progress;
use crate::source::{Resident, RowSource};
use crate::{Error, Param, Result};
use crate::source::Heightmap;

/// Default tile side, samples: 64 x 64 = 4096 samples fits the smallest profile's per-frame update budget
/// (gles3-low, 8192 samples), so a tile can always be decoded inside one frame.
pub const DEFAULT_TILE: u32 = 64;

/// Default zstd level: 19 is 3-10% smaller than level 3 on the shared terrains (Puget Sound 1k 1.62 vs
/// 1.70 B/sample, Kossou 0.56 vs 0.62; `clipsat bake --zstd-level`); the bake time is paid once and zstd
/// decodes at the same speed whatever the level.
pub const DEFAULT_ZSTD_LEVEL: i32 = 19;

/// The default error bound for a float source whose samples sit on no decimal lattice, metres: a 1 cm
/// quantum. It is below the vertical accuracy of any DEM (airborne lidar is ~5-10 cm RMSE), ten times finer
/// than the decimetre PNGs, and f32 itself only resolves ~0.25 mm at 4000 m.
pub const FLOAT_MAX_ERROR: f64 = 0.005;

/// Largest |k| stored: heights / q must fit well inside i32 so the prediction sums cannot overflow.
const MAX_UNITS: f64 = (1u64 << 30) as f64;

/// How to bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    /// The absolute error bound, metres (the quantum is twice it); `None`: [`default_max_error`].
    pub max_error: Option<f64>,
    /// Tile codec.
    pub codec: CodecKind,
    /// Tile side, samples (even, 4..=4096).
    pub tile: u32,
    /// zstd compression level (1..=22).
    pub zstd_level: i32,
    /// Whether to store the SAT LOD records (on by default). Without them a package still
    /// works: its LOD tables are computed from the heights on first use.
    pub lod_tables: bool,
    /// 0: a whole package. Else a package set's part of this many levels ([`Header::part`]), without
    /// SAT LOD records (a set's tables are computed from its heights).
    pub part: u32,
    /// The quantum and whether level 0 is on its lattice, when a package set fixes them for all its
    /// parts; `None`: from the source and the bound.
    pub quantum: Option<(f64, bool)>,
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self {
            max_error: None,
            codec: CodecKind::Rans,
            tile: DEFAULT_TILE,
            zstd_level: DEFAULT_ZSTD_LEVEL,
            lod_tables: true,
            part: 0,
            quantum: None,
        }
    }
}

/// What a bake wrote and how close it is to the source.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BakeReport {
    /// Bytes of the whole file.
    pub bytes: u64,
    /// Bytes of the tile payloads alone (the pyramid).
    pub tile_bytes: u64,
    /// Bytes of the SAT LOD record tiles (0 without them).
    pub lod_table_bytes: u64,
    /// tile_bytes / samples.
    pub pyramid_bytes_per_sample: f64,
    /// lod_table_bytes / samples.
    pub lod_table_bytes_per_sample: f64,
    /// Level-0 samples.
    pub samples: u64,
    /// bytes / samples.
    pub bytes_per_sample: f64,
    /// The quantum q, metres (the unit of the stored integers).
    pub quantum: f64,
    /// Whether level 0 was stored on the quantum's lattice (the source's own integers).
    pub lattice: bool,
    /// The bound asked for, metres.
    pub max_error_bound: f64,
    /// Largest |decoded - filtered height| over the coarser levels, metres (within the bound too).
    pub coarse_max_error: f64,
    /// RMS of (decoded level 0 - source), metres.
    pub rms_error: f64,
    /// Largest |decoded level 0 - source|, metres.
    pub max_error: f64,
    /// Levels stored.
    pub levels: usize,
    /// Tiles stored.
    pub tiles: usize,
    /// Codec.
    pub codec: CodecKind,
    /// Tile side.
    pub tile: u32,
    /// Each level's height tiles, finest first.
    pub level_bytes: Vec<LevelBytes>,
}

/// One level's share of the pyramid.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LevelBytes {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The residual step, quanta.
    pub step: u32,
    /// Bytes of the level's tiles.
    pub bytes: u64,
    /// bytes / the level's own samples.
    pub bytes_per_sample: f64,
    /// bytes / level-0 samples (the levels' shares add up to the pyramid's).
    pub bytes_per_level0_sample: f64,
}

/// The source's own quantum, if its samples sit on one: 1 m (integer metres: .hgt, int16 GeoTIFF) or 0.1 m
/// (decimetre u16 PNGs); `None` for float data.
pub fn source_quantum(terrain: &Heightmap) -> Option<f64> {
    [1.0, 0.1]
        .into_iter()
        .find(|&q| terrain.heights().iter().all(|&h| on_lattice(h, q)))
}

/// The default [`BakeOptions::max_error`]: half the source's own quantum (lossless in effect), or [`FLOAT_MAX_ERROR`].
pub fn default_max_error(terrain: &Heightmap) -> f64 {
    source_quantum(terrain).map_or(FLOAT_MAX_ERROR, |q| q * 0.5)
}

/// Bakes `terrain` into the package file `out` ([`bake_source`] over the heightmap's rows).
pub fn bake(
    terrain: &Heightmap,
    out: &Path,
    opts: &BakeOptions,
    progress: Progress<'_>,
) -> Result<BakeReport> {
    bake_source(&mut Resident::new(terrain), out, opts, progress)
}

/// Bakes a source read in bands of rows into the package file `out`, out of core: the pyramid is built
/// band by band and spilled to temporary files beside `out` (`package::spill`, removed afterwards), then
/// coded coarse to fine one tile row at a time. The working set is a few rows per level and one tile row
/// of the finest level, whatever the number of rows. `progress` counts source rows, then tiles.
///
/// The package is written under a temporary name beside `out` and renamed into place as the last step:
/// `out` is never a partial file. Every temporary is locked while the bake lives (`crate::temp`), and a
/// bake first removes those that a killed bake left beside `out`. A bake that is stopped starts again from
/// the source: a package is one file, made whole or not at all.
pub fn bake_source(
    src: &mut (impl RowSource + ?Sized),
    out: &Path,
    opts: &BakeOptions,
    progress: Progress<'_>,
) -> Result<BakeReport> {
    if let Some(m) = opts.max_error {
        check_max_error(m)?;
    }
    if !(4..=4096).contains(&opts.tile) || !opts.tile.is_multiple_of(2) {
        return Err(Error::param(
            Param::Tile,
            format!("{} is not an even size in 4..=4096", opts.tile),
        ));
    }
    let mut encoders = (0..super::threads())
        .map(|_| Encoder::new(opts.codec, opts.zstd_level))
        .collect::<std::io::Result<Vec<_>>>()
        .map_err(|e| Error::io(out, "cannot start the tile encoder", e))?;
    crate::temp::sweep(folder_of(out));
    let heights = TempFile::create(out.with_extension(format!("tmp{}", crate::temp_suffix())))?;
    let file = heights
        .file
        .try_clone()
        .map_err(|e| Error::io(&heights.path, "cannot open", e))?;
    let mut meter = progress.task("baking the terrain package: reading the source, rows", 0);
    let mut spilled = Spilled::build(src, out, &mut meter)?;
    let max_error = opts.max_error.unwrap_or_else(|| {
        [1.0, 0.1]
            .into_iter()
            .zip(spilled.on_lattice)
            .find(|&(_, ok)| ok)
            .map_or(FLOAT_MAX_ERROR, |(q, _)| q * 0.5)
    });
    check_max_error(max_error)?;
    // The quantum: the source's own lattice where the bound allows it (near-lossless steps over it), else
    // twice the bound (real-valued data, rounded once).
    let quant = if let Some((q, lattice)) = opts.quantum {
        Quantiser { q, lattice }
    } else {
        [1.0, 0.1]
        .into_iter()
        .zip(spilled.on_lattice)
        .find(|&(q, ok)| ok && q * 0.5 <= max_error * (1.0 + 1e-9))
        .map_or(
            Quantiser {
                q: 2.0 * max_error,
                lattice: false,
            },
            |(q, _)| Quantiser { q, lattice: true },
        )
    };
    let q = quant.q;
    let (lo, hi) = spilled.range;
    let units = f64::from(lo.abs().max(hi.abs())) / q;
    if units >= MAX_UNITS {
        return Err(Error::param(
            Param::MaxError,
            format!(
                "{max_error} m is too fine for heights up to {} m (at most 2^30 steps)",
                lo.abs().max(hi.abs())
            ),
        ));
    }
    let mut header = Header::new(
        src.width(),
        src.height(),
        src.spacing(),
        src.origin(),
        q,
        opts.codec,
        opts.tile,
    );
    if opts.part > 0 {
        header = header.into_part(opts.part);
    }
    header.max_error = max_error;
    let steps = levels::steps(header.levels.len(), quant, max_error);
    let mut coded = levels::code_levels(&mut spilled, &header, quant, &steps, out)?;
    let mut removing = Removing::default();
    removing.beside(spilled);
    // The decoded level 0's range.
    header.range = coded.range(q);
    header.models.clone_from(&coded.models);
    if levels::needs_tables(opts.codec) {
        header.tables = Some(coded.tables());
    }
    let mut file = std::io::BufWriter::new(file);
    // Reserve the header; the tile table is written over it at the end.
    let head_len = header.byte_len();
    file.write_all(&vec![0u8; head_len])
        .map_err(|e| Error::io(out, "cannot write", e))?;
    let mut offset = head_len as u64;
    let mut table = header.tiles.clone();
    meter.next(
        "baking the terrain package: coding tiles",
        table.len() as u64,
    );
    coded.write_tiles(&header, &mut encoders, |lk, ty, payloads| {
        let dims = header.levels[lk];
        for (tx, payload) in payloads.iter().enumerate() {
            file.write_all(payload)
                .map_err(|e| Error::io(out, "cannot write", e))?;
            let len = u32::try_from(payload.len()).expect("a tile payload is under 4 GiB");
            table[dims.first_tile + (ty * dims.tiles_x) as usize + tx] = TileEntry {
                offset,
                len,
                crc: crc32fast::hash(payload),
            };
            offset += u64::from(len);
        }
        meter.inc(payloads.len() as u64);
        Ok(())
    })?;
    let (sq, worst, coarse_worst) = (coded.sq, coded.worst, coded.worst_coarse);
    removing.beside(coded);
    header.tiles = table;
    let samples = header.samples();
    #[expect(clippy::cast_precision_loss, reason = "ratios for reports")]
    let level_bytes = header
        .levels
        .iter()
        .zip(&header.models)
        .map(|(d, m)| {
            let n = d.tiles_x as usize * d.tiles_y as usize;
            let bytes: u64 = header.tiles[d.first_tile..d.first_tile + n]
                .iter()
                .map(|t| u64::from(t.len))
                .sum();
            let own = u64::from(d.width) * u64::from(d.height);
            LevelBytes {
                width: d.width,
                height: d.height,
                step: m.step,
                bytes,
                bytes_per_sample: bytes as f64 / own as f64,
                bytes_per_level0_sample: bytes as f64 / samples as f64,
            }
        })
        .collect();
    let bytes = header.to_bytes();
    let mut file = file
        .into_inner()
        .map_err(|e| Error::io(out, "cannot write", e.into_error()))?;
    use std::io::Seek;
    file.seek(std::io::SeekFrom::Start(0))
        .and_then(|_| file.write_all(&bytes))
        .and_then(|()| file.sync_all())
        .map_err(|e| Error::io(out, "cannot write", e))?;
    meter.finish();
    drop(file);
    let (bytes, lod_bytes) = if opts.lod_tables && opts.part == 0 {
        let (lod, whole) = add_lod_records(&heights.path, out, opts, progress)?;
        whole.persist(out)?;
        (offset + lod.0, lod.1)
    } else {
        heights.persist(out)?;
        (offset, 0)
    };
    #[expect(clippy::cast_precision_loss, reason = "a ratio for reports")]
    Ok(BakeReport {
        bytes,
        tile_bytes: offset - head_len as u64,
        lod_table_bytes: lod_bytes,
        pyramid_bytes_per_sample: (offset - head_len as u64) as f64 / samples as f64,
        lod_table_bytes_per_sample: lod_bytes as f64 / samples as f64,
        samples,
        bytes_per_sample: bytes as f64 / samples as f64,
        quantum: q,
        lattice: quant.lattice,
        max_error_bound: max_error,
        coarse_max_error: coarse_worst,
        rms_error: (sq / samples as f64).sqrt(),
        max_error: worst,
        levels: header.levels.len(),
        tiles: header.tiles.len(),
        codec: opts.codec,
        tile: opts.tile,
        level_bytes,
    })
}

/// The folder `path` is in (the current one for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Adds the SAT LOD records to the package just written at `heights` (a temporary name of `out`):
/// computed out of core from it ([`crate::package::lod_bake::bake_records`], each level's tiles spooled
/// beside `out`), then the file is written again with the records' table in its header (the height
/// tiles' offsets moved by the header's growth, their bytes copied as they are) and the record tiles
/// after the height tiles, to another temporary file, returned for the caller to rename into place.
/// Returns (bytes added, record tile bytes) and that file.
fn add_lod_records(
    heights: &Path,
    out: &Path,
    opts: &BakeOptions,
    progress: Progress<'_>,
) -> Result<((u64, u64), TempFile)> {
    use crate::package::lod_bake::{spool_levels, RECORD_LEVELS};
    use crate::bake::lod_tables::P;
    let pkg = super::read::Package::open(heights)?;
    let suffix = crate::temp_suffix();
    let spools = (1..=RECORD_LEVELS)
        .map(|k| TempFile::create(out.with_extension(format!("lod{k}.tmp{suffix}"))))
        .collect::<Result<Vec<_>>>()?;
    let paths: Vec<std::path::PathBuf> = spools.iter().map(|t| t.path.clone()).collect();
    let spooled = spool_levels(
        &pkg,
        P,
        RECORD_LEVELS,
        (opts.tile, opts.codec, opts.zstd_level),
        &paths,
        progress,
    )?;
    let old = pkg.header().clone();
    let file_len = pkg.file_bytes();
    drop(pkg);
    let whole = TempFile::create(out.with_extension(format!("records{}", crate::temp_suffix())))?;
    let written = rewrite_with_records(heights, &whole.path, old, file_len, &spooled)?;
    drop(spools);
    Ok((written, whole))
}

/// [`add_lod_records`]'s second write: `out`'s header with the records' table, its height tiles, then
/// the spooled record tiles, into `tmp`.
fn rewrite_with_records(
    out: &Path,
    tmp: &Path,
    old: Header,
    file_len: u64,
    spooled: &[crate::package::lod_bake::SpooledLevel],
) -> Result<(u64, u64)> {
    use std::io::{Read, Seek};
    let old_len = old.byte_len() as u64;
    let mut header = old;
    let levels = u32::try_from(spooled.len()).expect("at most MAX_LOD_LEVELS");
    let mut idx = super::format::LodIndex::new(
        header.width,
        header.height,
        crate::bake::lod_tables::P,
        levels,
        header.tile,
        crate::package::lod_bake::DERIVED_LEVELS,
    );
    for (lv, sp) in idx.levels.iter_mut().zip(spooled) {
        lv.e_max = sp.e_max;
    }
    header.lod = Some(idx);
    let delta = header.byte_len() as u64 - old_len;
    for t in &mut header.tiles {
        t.offset += delta;
    }
    let mut at = file_len + delta;
    let mut lod_bytes = 0u64;
    if let Some(idx) = header.lod.as_mut() {
        for (lv, sp) in idx.levels.iter().zip(spooled).filter(|(lv, _)| lv.stored) {
            assert_eq!(
                sp.entries.len(),
                lv.grid.tiles(),
                "a spooled level has every tile of its grid"
            );
            let mut level_bytes = 0u64;
            for (i, &(off, len, crc)) in sp.entries.iter().enumerate() {
                idx.tiles[lv.first_tile + i] = TileEntry {
                    offset: at + off,
                    len,
                    crc,
                };
                level_bytes = level_bytes.max(off + u64::from(len));
            }
            at += level_bytes;
            lod_bytes += level_bytes;
        }
    }
    let io = |e| Error::io(tmp, "cannot write", e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(tmp).map_err(io)?);
    w.write_all(&header.to_bytes()).map_err(io)?;
    let mut src = std::fs::File::open(out).map_err(|e| Error::io(out, "cannot open", e))?;
    src.seek(std::io::SeekFrom::Start(old_len))
        .map_err(|e| Error::io(out, "cannot read", e))?;
    let copied = std::io::copy(&mut src.take(file_len - old_len), &mut w)
        .map_err(|e| Error::io(out, "cannot read", e))?;
    if copied != file_len - old_len {
        return Err(Error::format(
            out,
            "the package shrank while its LOD tables were baked",
        ));
    }
    // The derived levels spooled nothing (their E is in the header).
    for sp in spooled.iter().filter(|sp| sp.stored) {
        let mut f =
            std::fs::File::open(&sp.path).map_err(|e| Error::io(&sp.path, "cannot open", e))?;
        std::io::copy(&mut f, &mut w).map_err(io)?;
    }
    let f = w.into_inner().map_err(|e| io(e.into_error()))?;
    f.sync_all().map_err(io)?;
    Ok((delta + lod_bytes, lod_bytes))
}

/// Refuses a bound that is not finite and positive.
fn check_max_error(max_error: f64) -> Result<()> {
    if max_error.is_finite() && max_error > 0.0 {
        Ok(())
    } else {
        Err(Error::param(
            Param::MaxError,
            format!("{max_error} m must be finite and positive"),
        ))
    }
}

/// The residual symbols of the package `header` describes for `terrain` (its quantum and each level's
/// step; the weights are fitted here as the bake fits them), coarse to fine, each tile handed to `f` as
/// (level, (tx, ty), symbols row-major); returns (sum of squared, largest) level-0 errors in metres. The
/// pyramid is spilled to temporary files in the system's temporary folder (a measurement aid's entry;
/// [`bake_source`] is the bake).
pub fn residual_tiles(
    terrain: &Heightmap,
    header: &Header,
    f: impl FnMut(usize, (u32, u32), &[i32]) -> Result<()>,
) -> Result<(f64, f64)> {
    let near = std::env::temp_dir().join(format!("clipsat-residuals-{}", crate::temp_suffix()));
    let mut spilled = Spilled::build(
        &mut Resident::new(terrain),
        &near,
        &mut Progress::default().task("spilling the pyramid", 0),
    )?;
    let quant = Quantiser {
        q: header.quantum,
        lattice: source_quantum(terrain).is_some_and(|s| (s - header.quantum).abs() < 1e-12),
    };
    let steps: Vec<u32> = header.models.iter().map(|m| m.step).collect();
    let mut coded = levels::code_levels(&mut spilled, header, quant, &steps, &near)?;
    coded.each_tile(header, f)?;
    Ok((coded.sq, coded.worst))
}

/// The file [`cached`] keeps the package of `key` in, in format `version`.
pub(crate) fn cached_file(dir: &Path, key: u64, version: u32) -> std::path::PathBuf {
    dir.join(format!("terrain-{}-v{version}.clipsat", crate::hash::hex(key)))
}

/// The package of a plain source in the cache folder `dir`, baked with the default options on first use:
/// `terrain-<key>.clipsat`, `key` naming the source (the caller hashes what identifies it: its path,
/// size, modification time and load options, or a procedural terrain's parameters) so that a later run
/// finds it without loading the source. `load` runs only on a miss. A file that does not open as a valid
/// package is baked again; the bake goes to a temporary name renamed into place ([`bake_source`]), so a
/// killed bake leaves no half file, and every call first removes the temporaries a killed bake left in
/// `dir` (those no live bake holds: `crate::temp`). Returns the path and whether it was baked now.
pub fn cached<S: RowSource + ?Sized>(
    dir: &Path,
    key: u64,
    load: impl FnOnce() -> Result<Box<S>>,
    progress: Progress<'_>,
) -> Result<(std::path::PathBuf, bool)> {
    let named = |v: u32| cached_file(dir, key, v);
    let path = named(super::format::VERSION);
    crate::temp::sweep(dir);
    if super::read::Package::open(&path).is_ok() {
        return Ok((path, false));
    }
    let mut terrain = load()?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
    bake_source(&mut *terrain, &path, &BakeOptions::default(), progress)?;
    // The same terrain's packages of older formats are refused now: drop them, so the cache folder does
    // not grow with every format change (best effort: a file another process holds stays).
    for v in 1..super::format::VERSION {
        let _ = std::fs::remove_file(named(v));
    }
    Ok((path, true))
}
