//! Stage 1b, the package: the on-disk layout of a `.clipsat` file, its header and tile table.
//!
//! All fields are little-endian. The header (magic to header checksum) is followed by the tiles' payloads:
//!
//! ```text
//! magic "CLIPSAT\0" | version u32 | header_len u32
//! width u32 | height u32 | spacing f32 | origin_x f64 | origin_y f64
//! quantum f64 | max_error f64 | lowest f32 | highest f32 | codec u32 | tile u32 | levels u32
//! per level:  width u32 | height u32 | step u32 | weights 4 x 14 i16   (the level's prediction model)
//! tables_len u32 | rANS tables (tables_len bytes; 0 unless the codec is rans)
//! per tile (levels fine to coarse, tiles row-major):  offset u64 | len u32 | crc32 u32
//! lod_levels u32 | lod_p u32 | lod_tile u32 | lod_derived u32   (all 0: no SAT LOD records)
//! per record level k = 1 ..= lod_levels:  e_max f32
//! per record tile (levels k = lod_derived + 1 up, tiles row-major):  offset u64 | len u32 | crc32 u32
//! header crc32 u32 (over every byte before it)
//! ```
//!
//! A height tile's payload is its residual symbols ([`super::codec`]): the rANS part's length, the rANS
//! part and the raw bits, or for lz4 and zstd one byte (the count of byte planes, 1..=4) then the codec's
//! stream of the planes. `docs/package-codec.md` describes the format in full.
//! The record tiles ([`super::lod_tiles`]) hold the SAT LOD tables' compact records
//! ([`crate::bake::lod_record`]) for data levels lod_derived + 1 ..= lod_levels under exponent lod_p, in
//! tiles of lod_tile x lod_tile cells, after the height tiles; data levels 1 ..= lod_derived keep only
//! their E, their records derived from the heights when the tables are built
//! ([`crate::package::lod_bake`]). Version 3 added lod_derived and codes a record tile's max and mean
//! codes as two streams; version 4 (this one) predicts each height from the coarser level and its decoded
//! neighbours with per-level weights, quantises with a per-level step, and adds the rANS codec. An older
//! package is refused with a request to bake it again, never misread.
//! Everything read back is validated before use: a damaged file is an [`Error::Format`] naming the field or
//! the tile, never a panic.

use std::path::Path;

pub use super::kind::CodecKind;
use super::lod_tiles::RecordGrid;
use super::predict::{LevelModel, TAPS};
use super::rans::Tables;
use crate::{Error, Result};

/// The first 8 bytes of every package.
pub const MAGIC: [u8; 8] = *b"CLIPSAT\0";

/// The format version this build reads and writes for a whole package.
pub const VERSION: u32 = 4;

/// The format version of a package set's part ([`Header::part`]): version 4 and a `part u32` after
/// `levels`. A whole package is still written as version 4, byte for byte as before.
pub const PART_VERSION: u32 = 5;

/// Most record levels a header may list (data levels 1 ..= this; a profile has at most 16 levels).
pub const MAX_LOD_LEVELS: u32 = 40;

/// Bytes of one tile-table entry (offset u64, len u32, crc32 u32).
const TILE_ENTRY: usize = 16;

/// Bytes of the records' fixed fields (lod_levels, lod_p, lod_tile, lod_derived).
const LOD_FIXED: usize = 16;

/// Bytes of one level's entry: width, height, step, weights.
const LEVEL_ENTRY: usize = 12 + 2 * 4 * TAPS;

/// Bytes before the per-level table.
const FIXED: usize = 8 + 4 + 4 + 4 + 4 + 4 + 8 + 8 + 8 + 8 + 4 + 4 + 4 + 4 + 4;

/// Dimensions of one pyramid level and its tile grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelDims {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Tiles per row, ceil(width / tile).
    pub tiles_x: u32,
    /// Tile rows, ceil(height / tile).
    pub tiles_y: u32,
    /// Index of this level's first tile in the tile table.
    pub first_tile: usize,
}

/// Where one tile's payload lies and its checksum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TileEntry {
    /// Byte offset of the payload in the file.
    pub offset: u64,
    /// Payload length in bytes.
    pub len: u32,
    /// CRC-32 (IEEE) of the payload.
    pub crc: u32,
}

/// A package's header: the terrain's geometry, the quantisation, the codec and the tile table.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Level-0 samples per row.
    pub width: u32,
    /// Level-0 rows.
    pub height: u32,
    /// Level-0 sample spacing, metres.
    pub spacing: f32,
    /// World position of the south-west sample, metres ([`crate::source::Heightmap::origin`]).
    pub origin: (f64, f64),
    /// The unit of the stored integers, metres: heights are `quantum * k` (each level's residuals are
    /// quantised in steps of [`LevelModel::step`] quanta).
    pub quantum: f64,
    /// The error bound the bake was asked for, metres: every level of the decoded pyramid is within it.
    pub max_error: f64,
    /// Lowest and highest decoded level-0 height, metres (for shading ramps without decoding the data).
    pub range: (f32, f32),
    /// Tile codec.
    pub codec: CodecKind,
    /// Tile side, samples (every level uses the same).
    pub tile: u32,
    /// Levels, finest first.
    pub levels: Vec<LevelDims>,
    /// Every tile, levels finest first, row-major within a level.
    pub tiles: Vec<TileEntry>,
    /// The SAT LOD records' tiles, if the package holds them.
    pub lod: Option<LodIndex>,
    /// Each level's prediction weights and residual step, finest first.
    pub models: Vec<LevelModel>,
    /// The rANS tables (the `rans` codec only).
    pub tables: Option<Tables>,
    /// 0 for a whole package. A package set's part ([`super::set`]) stores this many levels, the finest
    /// ones, the last coded with U = 0 (the set's top package holds the coarser ones), and U reads the
    /// coarser level short of its last row and column: those lie on the next part's edge, which the set
    /// takes from that part.
    pub part: u32,
    /// Bytes a package set's open parts and top hold beyond this header (their headers, tile tables and
    /// rANS lookup tables), for memory budgets; 0 for one file. Not stored.
    pub set_bytes: u64,
}

/// Where a package's SAT LOD records lie ([`super::lod_tiles`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LodIndex {
    /// The SFAMF exponent the records were coded with.
    pub p: u32,
    /// Record levels, data level 1 first.
    pub levels: Vec<LodLevel>,
    /// Data levels 1 ..= this have no record tiles (their records are derived from the heights).
    pub derived: u32,
    /// Every stored record tile, levels in order, row-major within a level.
    pub tiles: Vec<TileEntry>,
}

/// One record level: its grids, E and its first tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodLevel {
    /// The cell and tile grids.
    pub grid: RecordGrid,
    /// E_k, metres (0: the level has no error; its codes are all 0).
    pub e_max: f32,
    /// Index of its first tile in [`LodIndex::tiles`].
    pub first_tile: usize,
    /// Whether its record tiles are stored (false: derived from the heights, no tiles).
    pub stored: bool,
}

impl LodIndex {
    /// An index for data levels 1 ..= `levels` of a `width x height` terrain in tiles of `tile` cells,
    /// levels 1 ..= `derived` without tiles, with every E and tile entry zero (filled in by the writer).
    pub fn new(width: u32, height: u32, p: u32, levels: u32, tile: u32, derived: u32) -> Self {
        let mut first = 0usize;
        let derived = derived.min(levels);
        let levels = (1..=levels)
            .map(|k| {
                let grid = RecordGrid::new(width, height, k, tile);
                let stored = k > derived;
                let l = LodLevel {
                    grid,
                    e_max: 0.0,
                    first_tile: first,
                    stored,
                };
                if stored {
                    first += grid.tiles();
                }
                l
            })
            .collect();
        Self {
            p,
            levels,
            derived,
            tiles: vec![TileEntry::default(); first],
        }
    }

    /// Record level `k` (1 ..= levels).
    pub fn level(&self, k: u32) -> Option<&LodLevel> {
        self.levels.get(usize::try_from(k).ok()?.checked_sub(1)?)
    }

    /// The cell side of a record tile.
    pub fn tile(&self) -> u32 {
        self.levels.first().map_or(0, |l| l.grid.tile)
    }
}

/// What a package's grid must be where a file gives it (a header, or a package set's index, from which
/// the whole terrain's header is made): a finite, positive spacing and quantum and a finite origin. The
/// reason where it is not.
pub(crate) fn check_grid(
    spacing: f32,
    origin: (f64, f64),
    quantum: f64,
) -> std::result::Result<(), String> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(format!("spacing {spacing} is not finite and positive"));
    }
    if !(origin.0.is_finite() && origin.1.is_finite()) {
        return Err("origin is not finite".into());
    }
    if !(quantum.is_finite() && quantum > 0.0) {
        return Err(format!("quantum {quantum} is not finite and positive"));
    }
    Ok(())
}

/// A package's tile side where a file gives it ([`check_grid`]): even, in 4..=4096.
pub(crate) fn check_tile(tile: u32) -> std::result::Result<(), String> {
    if !(4..=4096).contains(&tile) || !tile.is_multiple_of(2) {
        return Err(format!("tile side {tile} is not an even size in 4..=4096"));
    }
    Ok(())
}

/// The pyramid's level sizes for a `width x height` terrain: halving (w - 1)/2 + 1 until both sides are at
/// most 4, as [`crate::bake::pyramid::Pyramid::build`] does.
pub fn level_sizes(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(width, height)];
    let (mut w, mut h) = (width, height);
    while w > 4 || h > 4 {
        w = (w - 1).div_ceil(2) + 1;
        h = (h - 1).div_ceil(2) + 1;
        sizes.push((w, h));
    }
    sizes
}

impl Header {
    /// A header for the given geometry with an empty tile table (offsets filled in by the writer).
    pub fn new(
        width: u32,
        height: u32,
        spacing: f32,
        origin: (f64, f64),
        quantum: f64,
        codec: CodecKind,
        tile: u32,
    ) -> Self {
        let mut levels = Vec::new();
        let mut first = 0usize;
        let sizes = level_sizes(width, height);
        let models = vec![LevelModel::plain(1); sizes.len()];
        for (w, h) in sizes {
            let (tx, ty) = (w.div_ceil(tile), h.div_ceil(tile));
            levels.push(LevelDims {
                width: w,
                height: h,
                tiles_x: tx,
                tiles_y: ty,
                first_tile: first,
            });
            first += tx as usize * ty as usize;
        }
        Self {
            width,
            height,
            spacing,
            origin,
            quantum,
            max_error: quantum * 0.5,
            range: (0.0, 0.0),
            codec,
            tile,
            levels,
            tiles: vec![
                TileEntry {
                    offset: 0,
                    len: 0,
                    crc: 0
                };
                first
            ],
            lod: None,
            models,
            tables: None,
            part: 0,
            set_bytes: 0,
        }
    }

    /// This header made a part's ([`Header::part`]): its finest `levels` levels.
    #[must_use]
    pub fn into_part(mut self, levels: u32) -> Self {
        let keep = (levels as usize).clamp(1, self.levels.len());
        let tiles = self.levels.get(keep).map_or(self.tiles.len(), |l| l.first_tile);
        self.levels.truncate(keep);
        self.models.truncate(keep);
        self.tiles.truncate(tiles);
        self.part = u32::try_from(keep).expect("under 32 levels");
        self
    }

    /// The largest coarse sample U may read in each axis for a tile of `level` (the coarser level's last
    /// index, or one short of it in a part).
    pub fn u_reach(&self, level: usize) -> (i64, i64) {
        let c = &self.levels[level + 1];
        let short = i64::from(self.part > 0);
        (
            (i64::from(c.width) - 1 - short).max(0),
            (i64::from(c.height) - 1 - short).max(0),
        )
    }

    /// Bytes the header takes in the file, including its checksum.
    pub fn byte_len(&self) -> usize {
        let lod = self
            .lod
            .as_ref()
            .map_or(0, |l| 4 * l.levels.len() + TILE_ENTRY * l.tiles.len());
        let tables = self.tables.as_ref().map_or(0, Tables::byte_len);
        FIXED
            + if self.part > 0 { 4 } else { 0 }
            + LEVEL_ENTRY * self.levels.len()
            + 4
            + tables
            + TILE_ENTRY * self.tiles.len()
            + LOD_FIXED
            + lod
            + 4
    }

    /// Bytes an open package holds for this header: the header, its parsed tile table, the rANS tables'
    /// lookup form, and a set's parts ([`Header::set_bytes`]).
    pub fn resident_bytes(&self) -> u64 {
        let tables = if self.tables.is_some() {
            super::rans::DecodeTables::BYTES
        } else {
            0
        };
        self.byte_len() as u64 + 16 * self.tiles.len() as u64 + tables + self.set_bytes
    }

    /// Bytes of the height tiles' payloads (the pyramid).
    pub fn pyramid_bytes(&self) -> u64 {
        self.tiles.iter().map(|t| u64::from(t.len)).sum()
    }

    /// Bytes of the SAT LOD record tiles' payloads (0 without records).
    pub fn lod_bytes(&self) -> u64 {
        self.lod
            .as_ref()
            .map_or(0, |l| l.tiles.iter().map(|t| u64::from(t.len)).sum())
    }

    /// Level-0 samples.
    pub fn samples(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// The header as bytes, checksum last.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.byte_len());
        b.extend_from_slice(&MAGIC);
        let version = if self.part > 0 { PART_VERSION } else { VERSION };
        b.extend_from_slice(&version.to_le_bytes());
        let len = u32::try_from(self.byte_len()).expect("a header over 4 GiB is refused at bake");
        b.extend_from_slice(&len.to_le_bytes());
        b.extend_from_slice(&self.width.to_le_bytes());
        b.extend_from_slice(&self.height.to_le_bytes());
        b.extend_from_slice(&self.spacing.to_le_bytes());
        b.extend_from_slice(&self.origin.0.to_le_bytes());
        b.extend_from_slice(&self.origin.1.to_le_bytes());
        b.extend_from_slice(&self.quantum.to_le_bytes());
        b.extend_from_slice(&self.max_error.to_le_bytes());
        b.extend_from_slice(&self.range.0.to_le_bytes());
        b.extend_from_slice(&self.range.1.to_le_bytes());
        b.extend_from_slice(&self.codec.code().to_le_bytes());
        b.extend_from_slice(&self.tile.to_le_bytes());
        let nl =
            u32::try_from(self.levels.len()).expect("a u32 side halves to 4 in under 32 levels");
        b.extend_from_slice(&nl.to_le_bytes());
        if self.part > 0 {
            b.extend_from_slice(&self.part.to_le_bytes());
        }
        for (l, m) in self.levels.iter().zip(&self.models) {
            b.extend_from_slice(&l.width.to_le_bytes());
            b.extend_from_slice(&l.height.to_le_bytes());
            b.extend_from_slice(&m.step.to_le_bytes());
            for w in m.weights.iter().flatten() {
                b.extend_from_slice(&w.to_le_bytes());
            }
        }
        let tables = self
            .tables
            .as_ref()
            .map(Tables::to_bytes)
            .unwrap_or_default();
        let tl = u32::try_from(tables.len()).expect("the tables are a few KiB");
        b.extend_from_slice(&tl.to_le_bytes());
        b.extend_from_slice(&tables);
        let entry = |b: &mut Vec<u8>, t: &TileEntry| {
            b.extend_from_slice(&t.offset.to_le_bytes());
            b.extend_from_slice(&t.len.to_le_bytes());
            b.extend_from_slice(&t.crc.to_le_bytes());
        };
        for t in &self.tiles {
            entry(&mut b, t);
        }
        match &self.lod {
            None => b.extend_from_slice(&[0u8; LOD_FIXED]),
            Some(l) => {
                let n = u32::try_from(l.levels.len()).expect("at most MAX_LOD_LEVELS");
                for w in [n, l.p, l.tile(), l.derived] {
                    b.extend_from_slice(&w.to_le_bytes());
                }
                for lv in &l.levels {
                    b.extend_from_slice(&lv.e_max.to_le_bytes());
                }
                for t in &l.tiles {
                    entry(&mut b, t);
                }
            }
        }
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Parses and validates a header from the start of a file of `file_len` bytes.
    ///
    /// Checks the magic, version, header checksum, every dimension against the pyramid they imply, and that
    /// every tile lies after the header and inside the file.
    pub fn parse(path: &Path, bytes: &[u8], file_len: u64) -> Result<Self> {
        let bad = |reason: String| Error::format(path, format!("package header: {reason}"));
        let mut r = Reader { bytes, at: 0 };
        let magic = r
            .take(8)
            .ok_or_else(|| bad("file shorter than the magic".into()))?;
        if magic != MAGIC {
            return Err(bad("not a clipsat package (bad magic)".into()));
        }
        let version = r.u32().ok_or_else(|| bad("truncated".into()))?;
        if version != VERSION && version != PART_VERSION {
            let again = if version < VERSION {
                " (an older package format): bake it again with `clipsat bake`"
            } else {
                ""
            };
            return Err(bad(format!(
                "version {version}, this build reads version {VERSION}{again}"
            )));
        }
        let len = r.u32().ok_or_else(|| bad("truncated".into()))? as usize;
        if len > bytes.len() || len < FIXED + 4 {
            return Err(bad(format!(
                "header length {len} does not fit the file's {} bytes",
                bytes.len()
            )));
        }
        let stored = u32::from_le_bytes(
            bytes[len - 4..len]
                .try_into()
                .expect("a 4-byte slice converts"),
        );
        if crc32fast::hash(&bytes[..len - 4]) != stored {
            return Err(bad("header checksum mismatch (damaged header)".into()));
        }
        let trunc = || bad("truncated".into());
        let width = r.u32().ok_or_else(trunc)?;
        let height = r.u32().ok_or_else(trunc)?;
        let spacing = r.f32().ok_or_else(trunc)?;
        let origin = (r.f64().ok_or_else(trunc)?, r.f64().ok_or_else(trunc)?);
        let quantum = r.f64().ok_or_else(trunc)?;
        let max_error = r.f64().ok_or_else(trunc)?;
        let range = (r.f32().ok_or_else(trunc)?, r.f32().ok_or_else(trunc)?);
        let code = r.u32().ok_or_else(trunc)?;
        let tile = r.u32().ok_or_else(trunc)?;
        let nl = r.u32().ok_or_else(trunc)?;
        let part = if version == PART_VERSION {
            let p = r.u32().ok_or_else(trunc)?;
            if p == 0 || p != nl {
                return Err(bad(format!("a part of {p} levels lists {nl}")));
            }
            p
        } else {
            0
        };
        if width < 2 || height < 2 {
            return Err(bad(format!(
                "{width} x {height} samples: need at least 2 x 2"
            )));
        }
        check_grid(spacing, origin, quantum).map_err(&bad)?;
        if !(range.0.is_finite() && range.1.is_finite() && range.0 <= range.1) {
            return Err(bad(format!(
                "height range {range:?} is not finite and ordered"
            )));
        }
        let codec =
            CodecKind::from_code(code).ok_or_else(|| bad(format!("unknown codec {code}")))?;
        check_tile(tile).map_err(&bad)?;
        let mut sizes = level_sizes(width, height);
        if part > 0 && (part as usize) < sizes.len() {
            sizes.truncate(part as usize);
        }
        if nl as usize != sizes.len() {
            return Err(bad(format!(
                "{nl} levels, a {width} x {height} pyramid has {}",
                sizes.len()
            )));
        }
        let mut models = Vec::with_capacity(sizes.len());
        for (k, &(ew, eh)) in sizes.iter().enumerate() {
            let (w, hh) = (r.u32().ok_or_else(trunc)?, r.u32().ok_or_else(trunc)?);
            if (w, hh) != (ew, eh) {
                return Err(bad(format!(
                    "level {k} is {w} x {hh}, expected {ew} x {eh}"
                )));
            }
            let step = r.u32().ok_or_else(trunc)?;
            if !(1..=1 << 20).contains(&step) {
                return Err(bad(format!("level {k}: residual step {step} out of range")));
            }
            let mut m = LevelModel::plain(step);
            for w in m.weights.iter_mut().flatten() {
                *w = i16::from_le_bytes(
                    r.take(2)
                        .ok_or_else(trunc)?
                        .try_into()
                        .map_err(|_| trunc())?,
                );
            }
            models.push(m);
        }
        let tl = r.u32().ok_or_else(trunc)? as usize;
        let tables = if tl == 0 {
            None
        } else {
            let tb = r.take(tl).ok_or_else(trunc)?;
            let (t, used) = Tables::parse(tb).map_err(&bad)?;
            if used != tl {
                return Err(bad(format!("rANS tables take {used} of their {tl} bytes")));
            }
            Some(t)
        };
        if (codec == CodecKind::Rans) != tables.is_some() {
            return Err(bad(format!(
                "codec {} with{} rANS tables",
                codec.name(),
                if tables.is_some() { "" } else { "out" }
            )));
        }
        // The tile table's size follows from the dimensions; check it against the stored length before
        // allocating anything of that size (a damaged width cannot ask for gigabytes).
        let count: u64 = sizes
            .iter()
            .map(|&(w, hh)| u64::from(w.div_ceil(tile)) * u64::from(hh.div_ceil(tile)))
            .sum();
        let base = r.at as u64 + TILE_ENTRY as u64 * count;
        // The records' fields follow the height tiles' table (all inside the checksummed header).
        let lod_at = usize::try_from(base).map_err(|_| trunc())?;
        let mut lr = Reader {
            bytes: &bytes[..len],
            at: lod_at,
        };
        let (lod_n, lod_p, lod_tile, lod_derived) = (
            lr.u32().ok_or_else(trunc)?,
            lr.u32().ok_or_else(trunc)?,
            lr.u32().ok_or_else(trunc)?,
            lr.u32().ok_or_else(trunc)?,
        );
        if lod_n > MAX_LOD_LEVELS
            || lod_derived > lod_n
            || (lod_n > 0 && !(1..=4096).contains(&lod_tile))
        {
            return Err(bad(format!(
                "{lod_n} LOD record levels ({lod_derived} derived) in tiles of {lod_tile} cells: \
                 out of range"
            )));
        }
        let mut lod =
            (lod_n > 0).then(|| LodIndex::new(width, height, lod_p, lod_n, lod_tile, lod_derived));
        let lod_len = lod.as_ref().map_or(0, |l| {
            4 * l.levels.len() as u64 + TILE_ENTRY as u64 * l.tiles.len() as u64
        });
        let need = base + (LOD_FIXED + 4) as u64 + lod_len;
        if need != len as u64 {
            return Err(bad(format!(
                "header length {len}, a {width} x {height} package in {tile}-sample tiles needs {need}"
            )));
        }
        let mut h = Self::new(width, height, spacing, origin, quantum, codec, tile);
        if part > 0 {
            h = h.into_part(part);
        }
        h.max_error = max_error;
        h.range = range;
        h.models = models;
        h.tables = tables;
        if let Some(l) = &mut lod {
            for lv in &mut l.levels {
                lv.e_max = lr.f32().ok_or_else(trunc)?;
                if !(lv.e_max.is_finite() && lv.e_max >= 0.0) {
                    return Err(bad(format!(
                        "LOD record level {}: E {} is not a finite error",
                        lv.grid.k, lv.e_max
                    )));
                }
            }
            for t in &mut l.tiles {
                *t = TileEntry {
                    offset: lr.u64().ok_or_else(trunc)?,
                    len: lr.u32().ok_or_else(trunc)?,
                    crc: lr.u32().ok_or_else(trunc)?,
                };
            }
        }
        for t in h.tiles.iter_mut() {
            let offset = r.u64().ok_or_else(trunc)?;
            let tlen = r.u32().ok_or_else(trunc)?;
            let crc = r.u32().ok_or_else(trunc)?;
            *t = TileEntry {
                offset,
                len: tlen,
                crc,
            };
        }
        for (k, l) in h.levels.iter().enumerate() {
            for ty in 0..l.tiles_y {
                for tx in 0..l.tiles_x {
                    let t = h.tiles[l.first_tile + (ty * l.tiles_x + tx) as usize];
                    let end = t.offset.checked_add(u64::from(t.len));
                    if t.offset < len as u64 || t.len < 2 || end.is_none_or(|e| e > file_len) {
                        return Err(Error::format(
                            path,
                            format!(
                                "level {k} tile ({tx}, {ty}): bytes {}..+{} lie outside the file's \
                                 {file_len} bytes of tile data (truncated file?)",
                                t.offset, t.len
                            ),
                        ));
                    }
                }
            }
        }
        if let Some(l) = &lod {
            for lv in l.levels.iter().filter(|lv| lv.stored) {
                let g = lv.grid;
                for i in 0..g.tiles() {
                    let t = l.tiles[lv.first_tile + i];
                    let end = t.offset.checked_add(u64::from(t.len));
                    if t.offset < len as u64 || t.len < 2 || end.is_none_or(|e| e > file_len) {
                        return Err(Error::format(
                            path,
                            format!(
                                "LOD table level {} tile ({}, {}): bytes {}..+{} lie outside the \
                                 file's {file_len} bytes of tile data (truncated file?)",
                                g.k,
                                i % g.tiles_x as usize,
                                i / g.tiles_x as usize,
                                t.offset,
                                t.len
                            ),
                        ));
                    }
                }
            }
        }
        h.lod = lod;
        Ok(h)
    }

    /// The header's length as stored in its first 16 bytes, for reading the rest; `None` if not a package.
    pub fn peek_len(bytes: &[u8]) -> Option<usize> {
        if bytes.len() < 16 || bytes[..8] != MAGIC {
            return None;
        }
        Some(u32::from_le_bytes(bytes[12..16].try_into().ok()?) as usize)
    }

    /// Tile (tx, ty) of level `level`: its entry, or `None` outside the level's tile grid.
    pub fn tile(&self, level: usize, tx: u32, ty: u32) -> Option<TileEntry> {
        let l = self.levels.get(level)?;
        (tx < l.tiles_x && ty < l.tiles_y)
            .then(|| self.tiles[l.first_tile + (ty * l.tiles_x + tx) as usize])
    }

    /// The sample rectangle (x0, y0, w, h) of tile (tx, ty) of `level`: edge tiles are cropped to the level.
    pub fn tile_rect(&self, level: usize, tx: u32, ty: u32) -> (u32, u32, u32, u32) {
        let l = &self.levels[level];
        let (x0, y0) = (tx * self.tile, ty * self.tile);
        (
            x0,
            y0,
            self.tile.min(l.width - x0),
            self.tile.min(l.height - y0),
        )
    }
}

/// A cursor over little-endian fields.
pub(super) struct Reader<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) at: usize,
}

impl<'a> Reader<'a> {
    pub(super) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    pub(super) fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    pub(super) fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    pub(super) fn f32(&mut self) -> Option<f32> {
        Some(f32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    pub(super) fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}
