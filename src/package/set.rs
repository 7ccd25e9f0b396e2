//! Stage 1b, the package: a package set's index (`docs/guide.md`, "Package sets"). A set is one terrain
//! baked as parts that are baked apart: each cell of the input tiles' lattice its own part (levels 0..=K
//! of the cell, [`super::Header::part`]), and a top package of the coarser levels (level K + 1 filtered
//! from the parts' level K, and up), named by the index. [`super::Package::open`] on the index (or its
//! folder) reads the set as one package (`read.rs`, beside the package that holds its parts): every tile
//! of level k <= K is a tile of one part, since a cell's origin is a whole number of level-K tiles, and
//! every tile above K is the top's.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::format::{CodecKind, Header};
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
        // What a package's header is checked for: the whole terrain's header is made from these before
        // any part is read.
        super::format::check_tile(index.tile).map_err(bad)?;
        super::format::check_grid(index.spacing, index.origin, index.quantum).map_err(bad)?;
        // Imagery over the set is placed by it: a scale of 0 had been refused as the imagery extent
        // option's, which was never given.
        if index.georef.as_ref().is_some_and(|g| !g.usable()) {
            return Err(bad(
                "georef has a corner or pixel size that is not finite, or a size of 0".into(),
            ));
        }
        if !(index.max_error.is_finite() && index.max_error >= 0.0) {
            return Err(bad(format!(
                "error bound {} is not finite and at least 0",
                index.max_error
            )));
        }
        Ok(index)
    }

    /// The index as its file's text.
    pub fn to_text(&self) -> Result<String> {
        let body = toml::to_string(self)
            .map_err(|e| Error::format(Path::new(INDEX_NAME), e.to_string()))?;
        Ok(format!(
            "{MAGIC_LINE}: one terrain baked as parts, each read where the index places it.\n{body}"
        ))
    }

    /// The grid rectangle of part (i, j), (x0, y0, x1, y1) inclusive: to the next part's first column and
    /// row (shared with it), or the grid's last.
    pub fn cell(&self, i: usize, j: usize) -> (u32, u32, u32, u32) {
        let x1 = self.columns.get(i + 1).copied().unwrap_or(self.width - 1);
        let y1 = self.rows.get(j + 1).copied().unwrap_or(self.height - 1);
        (self.columns[i], self.rows[j], x1, y1)
    }

    /// Whether `h` is part `n`'s (row-major) as this index describes it: its cell's size, the set's part
    /// levels, tile side, codec and quantum (a part's header does not say which cell it is). What the
    /// set's reader checks each part for, and what a bake again keeps a part for.
    pub(crate) fn fits_part(&self, n: usize, h: &Header, codec: CodecKind) -> bool {
        let (i, j) = (n % self.columns.len(), n / self.columns.len());
        if j >= self.rows.len() {
            return false;
        }
        let (x0, y0, x1, y1) = self.cell(i, j);
        (h.width, h.height) == (x1 - x0 + 1, y1 - y0 + 1)
            && h.part == self.part_levels
            && h.tile == self.tile
            && h.codec == codec
            && h.quantum.to_bits() == self.quantum.to_bits()
    }
}

/// The file of the part whose cell starts at grid column and row `origin`, baked with `key`: what a bake
/// names it and the index must name it (a part's header does not say which cell it is).
pub fn part_file(origin: (u32, u32), key: &str) -> String {
    format!("part-{}-{}-{key}.clipsat", origin.0, origin.1)
}

/// Whether `path` is a set's index, or a folder that holds one.
pub fn is_set(path: &Path) -> bool {
    crate::source::georef::set_index(path).is_some()
}

/// The index file of the set at `path` (the file, or its folder's index).
pub fn index_path(path: &Path) -> PathBuf {
    crate::source::georef::set_index(path).unwrap_or_else(|| path.to_path_buf())
}
