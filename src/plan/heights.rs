//! Stage 2, the per-frame plan: the height range of each ring tile the SAT LOD draw list culls, kept
//! from frame to frame while none of the tile's texels is written. The rings are written in whole column
//! and row strips, each stamped with its frame ([`crate::plan::uploads::UploadStamps`]), so a tile whose
//! columns and rows carry no later stamp than when its range was read holds the same texels: reading
//! 2 (w + h) stamps replaces reading 2 w h texels. A fixed table allocated with the planner.

use std::cell::Cell;

use crate::plan::clipmap::Clipmap;
use crate::plan::frame::Rect;

/// Entries of the table (a power of two; a frame draws a few hundred tiles).
const SLOTS: usize = 1 << 12;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Entry {
    /// The clipmap read (0: empty).
    clipmap: u64,
    level: u32,
    tile: Rect,
    /// The latest stamp of the tile's columns and rows when read.
    stamp: u64,
    /// The level's [`crate::plan::uploads::UploadStamps::writes`] when last checked: while it is the
    /// same, no stamp is read.
    writes: u64,
    range: (f32, f32),
}

/// Each tile's (level, lattice rectangle) lowest and highest z and z_c, by clipmap, kept while its
/// texels are unchanged. Direct-mapped (a colliding tile replaces the entry), so every value is
/// [`crate::plan::cull`]'s own reading of the texels, bit for bit.
#[derive(Clone, Debug)]
pub struct TileHeights(Box<[Cell<Entry>]>);

impl Default for TileHeights {
    fn default() -> Self {
        Self(vec![Cell::new(Entry::default()); SLOTS].into_boxed_slice())
    }
}

impl TileHeights {
    /// The lowest and highest of z and z_c over `tile` of ring `level`, read by `read` when not kept.
    pub fn range(
        &self,
        clipmap: &Clipmap,
        level: u32,
        tile: &Rect,
        read: impl FnOnce() -> (f32, f32),
    ) -> (f32, f32) {
        let stamps = clipmap.upload_stamps();
        let writes = stamps.writes(level);
        #[expect(clippy::cast_sign_loss, reason = "hash mixing: only the bits matter")]
        let h = crate::plan::slot_hash(&[
            u64::from(level),
            tile.x0 as u64,
            tile.y0 as u64,
            u64::from(tile.w) << 32 | u64::from(tile.h),
        ]);
        let slot = &self.0[usize::try_from(h).unwrap_or(0) & (SLOTS - 1)];
        let mut e = slot.get();
        let same_tile = e.clipmap == clipmap.id() && e.level == level && e.tile == *tile;
        // No strip of the level written since the entry was checked: its stamps are as they were.
        if same_tile && e.writes == writes {
            return e.range;
        }
        let stamp = stamps.latest(level, (tile.x0, tile.x1()), (tile.y0, tile.y1()));
        if same_tile && e.stamp == stamp {
            e.writes = writes;
            slot.set(e);
            return e.range;
        }
        let range = read();
        slot.set(Entry {
            clipmap: clipmap.id(),
            level,
            tile: *tile,
            stamp,
            writes,
            range,
        });
        range
    }
}
