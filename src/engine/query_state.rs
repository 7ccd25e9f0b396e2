//! The embedding API: the exact queries' state, allocated once with a [`crate::TerrainRenderer`]: a held
//! grid's tile ranges, or a streamed terrain's query cache (`engine/query.rs` answers the queries).

use crate::package::query::{GridRanges, QueryTiles};
use crate::package::Package;
use crate::plan::clipmap::Clipmap;
use crate::source::Heightmap;
use crate::Result;

/// The queries' state, allocated once with the renderer.
#[derive(Debug)]
pub(crate) enum Queries {
    /// A grid held whole (the renderer's own copy of it) and its tiles' ranges.
    Resident(GridRanges),
    /// A package read through the query cache, or why the profile's share could not hold it.
    Streamed {
        tiles: Box<QueryTiles>,
        /// World (x, y) of the south-west sample, spacing (m), rows.
        frame: ((f64, f64), f64, u32),
    },
    /// Why a streamed terrain has no query cache (the profile's share is too small for its package).
    Unavailable(String),
}

impl Queries {
    /// The query state for the renderer of `clipmap` (filled from `grid` when it is held whole), under
    /// `profile`'s query share.
    pub(crate) fn new(
        clipmap: &Clipmap,
        grid: &Heightmap,
        profile: &crate::profile::Profile,
    ) -> Result<Self> {
        let Some(cache) = clipmap.tile_cache() else {
            return Ok(Self::Resident(GridRanges::new(grid)));
        };
        // The same file, mapped again: its own header and tile cache, apart from the rings'.
        let package = Package::open(cache.package().path())?;
        let h = package.header();
        let frame = (h.origin, f64::from(h.spacing), h.height);
        Ok(
            match QueryTiles::new(package, profile.cpu_split().queries, &profile.name) {
                Ok(tiles) => Self::Streamed {
                    tiles: Box::new(tiles),
                    frame,
                },
                Err(e) => Self::Unavailable(e.to_string()),
            },
        )
    }

    /// Bytes the queries hold beside the terrain (the tile ranges, and a streamed terrain's query cache).
    pub(crate) fn bytes(&self) -> u64 {
        match self {
            Self::Resident(r) => r.bytes(),
            Self::Streamed { tiles, .. } => tiles.bytes(),
            Self::Unavailable(_) => 0,
        }
    }
}

/// World (x, y) to grid (column, row) for a terrain whose south-west sample is at `origin`, `spacing`
/// metres apart, `rows` rows.
pub(crate) fn to_grid((origin, spacing, rows): ((f64, f64), f64, u32), x: f64, y: f64) -> (f64, f64) {
    (
        (x - origin.0) / spacing,
        f64::from(rows.saturating_sub(1)) - (y - origin.1) / spacing,
    )
}

