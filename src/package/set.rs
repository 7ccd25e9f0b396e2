//! Stage 1b, the package: a package set, one terrain baked as parts that are baked apart
//! (`docs/guide.md`, "Package sets"): each cell of the input tiles' lattice its own part (levels 0..=K of
//! the cell, [`Header::part`]), and a top package of the coarser levels (level K + 1 filtered from the
//! parts' level K, and up),
//! named by an index file. [`super::Package::open`] on the index (or its folder) reads the set as one
//! package: every tile of level k <= K is a tile of one part, since a cell's origin is a whole number of
//! level-K tiles, and every tile above K is the top's.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::format::{CodecKind, Header};
use super::predict::LevelModel;
use super::read::{Package, TileDecoder};
use crate::{Error, Result};

/// The index file's name in a set's folder.
pub const INDEX_NAME: &str = crate::source::georef::SET_INDEX_NAME;

/// The index file's first line, which tells a set's index from any other file.
pub const MAGIC_LINE: &str = crate::source::georef::SET_INDEX_MAGIC;

/// The index format this build reads and writes.
pub const INDEX_FORMAT: u32 = 1;

/// A set's index: the terrain's grid, how its parts were baked, and every part.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Index {
    /// [`INDEX_FORMAT`].
    pub format: u32,
    /// Level-0 samples per row and rows of the whole terrain.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Level-0 sample spacing, metres.
    pub spacing: f32,
    /// World position of the south-west sample, metres.
    pub origin: (f64, f64),
    /// Tile side, samples (every part's and the top's).
    pub tile: u32,
    /// Levels each part holds (K + 1); the top holds level K + 1 up.
    pub part_levels: u32,
    /// The quantum, metres, and whether level 0 is on its lattice: the same in every part.
    pub quantum: f64,
    /// Level 0 on the quantum's lattice.
    pub lattice: bool,
    /// The bound every level is within, metres.
    pub max_error: f64,
    /// What the quantum was chosen from (the first cell's tiles and the options), hashed: a bake again
    /// with the same takes the quantum from here instead of reading the cell.
    #[serde(default)]
    pub quantum_key: String,
    /// The tile codec's name.
    pub codec: String,
    /// The grid column where each column of parts starts, ascending from 0.
    pub columns: Vec<u32>,
    /// The grid row where each row of parts starts, ascending from 0.
    pub rows: Vec<u32>,
    /// The top package's file, relative to the index.
    pub top: String,
    /// The tiles' georeference over the whole grid (for imagery placed by its own), if they had one.
    #[serde(default)]
    pub georef: Option<crate::source::georef::GeoRef>,
    /// Every part, row-major (`rows.len()` rows of `columns.len()`).
    pub parts: Vec<PartEntry>,
}

/// One part in the index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartEntry {
    /// Its file, relative to the index.
    pub file: String,
    /// What it was baked from and how, hashed: the part is baked again when it changes.
    pub key: String,
    /// The input tiles it read, as given.
    pub sources: Vec<String>,
}

impl Index {
    /// The index at `path`, checked for the shape its fields imply.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "cannot read", e))?;
        let bad = |reason: String| Error::format(path, format!("package set index: {reason}"));
        let index: Self = toml::from_str(&text).map_err(|e| bad(e.to_string()))?;
        if index.format != INDEX_FORMAT {
            return Err(bad(format!(
                "format {}, this build reads format {INDEX_FORMAT}: bake the set again",
                index.format
            )));
        }
        let starts = |v: &[u32], n: u32| {
            v.first() == Some(&0) && v.windows(2).all(|w| w[0] < w[1]) && v.last() < Some(&n)
        };
        if !starts(&index.columns, index.width) || !starts(&index.rows, index.height) {
            return Err(bad("part columns or rows do not start at 0 and ascend inside the grid".into()));
        }
        if index.parts.len() != index.columns.len() * index.rows.len() {
            return Err(bad(format!(
                "{} parts for {} x {} cells",
                index.parts.len(),
                index.columns.len(),
                index.rows.len()
            )));
        }
        if index.part_levels == 0 {
            return Err(bad("parts of 0 levels".into()));
        }
        Ok(index)
    }

    /// The index as its file's text.
    pub fn to_text(&self) -> Result<String> {
        let body = toml::to_string(self)
            .map_err(|e| Error::format(Path::new(INDEX_NAME), e.to_string()))?;
        Ok(format!(
            "{MAGIC_LINE}: one terrain baked as parts (clipsat bake --parts); open it with --terrain.\n{body}"
        ))
    }

    /// The grid rectangle of part (i, j), (x0, y0, x1, y1) inclusive: to the next part's first column and
    /// row (shared with it), or the grid's last.
    pub fn cell(&self, i: usize, j: usize) -> (u32, u32, u32, u32) {
        let x1 = self.columns.get(i + 1).copied().unwrap_or(self.width - 1);
        let y1 = self.rows.get(j + 1).copied().unwrap_or(self.height - 1);
        (self.columns[i], self.rows[j], x1, y1)
    }
}

/// Whether `path` is a set's index, or a folder that holds one.
pub fn is_set(path: &Path) -> bool {
    crate::source::georef::set_index(path).is_some()
}

/// The index file of the set at `path` (the file, or its folder's index).
pub fn index_path(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(INDEX_NAME)
    } else {
        path.to_path_buf()
    }
}

/// An open set: its parts and top, and where each level's tiles are.
pub(super) struct Parts {
    /// Levels the parts hold (K + 1).
    part_levels: usize,
    /// Part column starts and part row starts, grid samples.
    columns: Vec<u32>,
    rows: Vec<u32>,
    tile: u32,
    parts: Vec<Package>,
    top: Package,
}

/// Where a tile of the set lies.
enum Route {
    /// Tile (tx, ty) of part `p`, whose origin at the coarser level is (cx, cy).
    Part {
        p: usize,
        tile: (u32, u32),
        coarse: (i64, i64),
    },
    /// The top's level.
    Top(usize),
}

impl Parts {
    /// Opens the set at `path` (an index or its folder): every part and the top, checked against the
    /// index and each other. Returns the whole terrain's header and the parts.
    pub(super) fn open(path: &Path) -> Result<(Header, Self)> {
        let index_file = index_path(path);
        let index = Index::read(&index_file)?;
        let dir = index_file.parent().unwrap_or(Path::new("."));
        let bad = |reason: String| Error::format(&index_file, format!("package set: {reason}"));
        let codec = CodecKind::parse(&index.codec)?;
        let mut world = Header::new(
            index.width,
            index.height,
            index.spacing,
            index.origin,
            index.quantum,
            codec,
            index.tile,
        );
        let k = index.part_levels as usize - 1;
        if k + 1 >= world.levels.len() {
            return Err(bad(format!(
                "parts of {} levels leave no level to a top over {} levels",
                index.part_levels,
                world.levels.len()
            )));
        }
        let level_tile = u64::from(index.tile) << k;
        for &s in index.columns.iter().chain(&index.rows) {
            if u64::from(s) % level_tile != 0 {
                return Err(bad(format!(
                    "a part starts at {s}, not a multiple of {level_tile} (a level-{k} tile)"
                )));
            }
        }
        let top = Package::open(&dir.join(&index.top))?;
        let kd = world.levels[k + 1];
        let th = top.header();
        if (th.width, th.height) != (kd.width, kd.height)
            || th.levels.len() + k + 1 != world.levels.len()
            || th.tile != index.tile
            || th.codec != codec
            || th.quantum.to_bits() != index.quantum.to_bits()
            || th.part != 0
        {
            return Err(Error::format(
                top.path(),
                format!(
                    "not this set's top: {} x {} in {} levels of {}-sample tiles, the set's level {} is \
                     {} x {} (bake the set again)",
                    th.width,
                    th.height,
                    th.levels.len(),
                    th.tile,
                    k + 1,
                    kd.width,
                    kd.height
                ),
            ));
        }
        let mut parts = Vec::with_capacity(index.parts.len());
        let mut range = (f32::INFINITY, f32::NEG_INFINITY);
        for (n, entry) in index.parts.iter().enumerate() {
            let (i, j) = (n % index.columns.len(), n / index.columns.len());
            let (x0, y0, x1, y1) = index.cell(i, j);
            let p = Package::open(&dir.join(&entry.file))?;
            let h = p.header();
            if (h.width, h.height) != (x1 - x0 + 1, y1 - y0 + 1)
                || h.part != index.part_levels
                || h.tile != index.tile
                || h.codec != codec
                || h.quantum.to_bits() != index.quantum.to_bits()
            {
                return Err(Error::format(
                    p.path(),
                    format!(
                        "not part ({i}, {j}) of this set: {} x {} samples, {} levels (part {}), expected \
                         {} x {}, {} levels (bake the set again)",
                        h.width,
                        h.height,
                        h.levels.len(),
                        h.part,
                        x1 - x0 + 1,
                        y1 - y0 + 1,
                        index.part_levels
                    ),
                ));
            }
            range = (range.0.min(h.range.0), range.1.max(h.range.1));
            parts.push(p);
        }
        world.max_error = index.max_error;
        world.set_bytes = parts
            .iter()
            .chain(std::iter::once(&top))
            .map(|p| super::cache::file_head_bytes(p.header()))
            .sum();
        world.range = range;
        world.models = (0..world.levels.len())
            .map(|l| {
                if l <= k {
                    LevelModel::plain(parts[0].header().models[l].step)
                } else {
                    th.models[l - k - 1].clone()
                }
            })
            .collect();
        let set = Self {
            part_levels: k + 1,
            columns: index.columns,
            rows: index.rows,
            tile: index.tile,
            parts,
            top,
        };
        for (l, d) in world.levels.clone().iter().enumerate() {
            for ty in 0..d.tiles_y {
                for tx in 0..d.tiles_x {
                    let entry = match set.route(l, tx, ty) {
                        Route::Part { p, tile, .. } => set.parts[p].header().tile(l, tile.0, tile.1),
                        Route::Top(j) => set.top.header().tile(j, tx, ty),
                    };
                    world.tiles[d.first_tile + (ty * d.tiles_x + tx) as usize] = entry
                        .ok_or_else(|| bad(format!("level {l} tile ({tx}, {ty}) is in no part")))?;
                }
            }
        }
        Ok((world, set))
    }

    /// The part or top level that holds tile (tx, ty) of `level`.
    fn route(&self, level: usize, tx: u32, ty: u32) -> Route {
        if level >= self.part_levels {
            return Route::Top(level - self.part_levels);
        }
        let t = u64::from(self.tile) << level;
        // The last part whose first tile is at or before the tile's.
        let find = |starts: &[u32], at: u32| {
            starts
                .partition_point(|&s| u64::from(s) / t <= u64::from(at))
                .saturating_sub(1)
        };
        let (i, j) = (find(&self.columns, tx), find(&self.rows, ty));
        #[expect(clippy::cast_possible_truncation, reason = "a tile index under the level's")]
        let (fx, fy) = (
            (u64::from(self.columns[i]) / t) as u32,
            (u64::from(self.rows[j]) / t) as u32,
        );
        let shift = level + 1;
        Route::Part {
            p: j * self.columns.len() + i,
            tile: (tx - fx, ty - fy),
            coarse: (
                i64::from(self.columns[i] >> shift),
                i64::from(self.rows[j] >> shift),
            ),
        }
    }

    /// [`Package::decode_tile`] of the set: the tile decoded by its part (its coarser level read from
    /// the whole terrain's, at the part's place) or by the top.
    pub(super) fn decode_tile(
        &self,
        scratch: &mut TileDecoder,
        level: usize,
        (tx, ty): (u32, u32),
        coarse: impl Fn(i64, i64) -> i64,
        out: &mut [i32],
    ) -> Result<()> {
        match self.route(level, tx, ty) {
            Route::Top(j) => self.top.decode_own(scratch, j, (tx, ty), coarse, out),
            Route::Part { p, tile, coarse: (cx, cy) } => self.parts[p].decode_own(
                scratch,
                level,
                tile,
                |i, j| coarse(cx + i.max(0), cy + j.max(0)),
                out,
            ),
        }
    }

    /// Bytes of every file of the set.
    pub(super) fn file_bytes(&self) -> u64 {
        self.parts
            .iter()
            .chain(std::iter::once(&self.top))
            .map(Package::file_bytes)
            .sum()
    }

    /// [`Package::trim`] of every file.
    pub(super) fn trim(&self) {
        for p in self.parts.iter().chain(std::iter::once(&self.top)) {
            p.trim();
        }
    }
}
