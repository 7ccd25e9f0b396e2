//! Stage 2, the per-frame plan: what the stitched-unit tests of a pool cell keep while they run: the
//! projected corners of one cell's units ([`CornerGrid`]) and the units' errors per pool tile
//! ([`UnitEtas`]). Apart from the tests themselves (`mask.rs`) so that the bound memo's asker
//! (`memo.rs`) can hold them without a cycle.

use crate::plan::camera::Corner;
use crate::plan::detail::keymap::KeyMap;
use crate::plan::detail::{stitch, TileKey};

/// Unit corners a cell side has at most.
pub(super) const SIDE: usize = stitch::MAX_UNITS as usize + 1;

/// The projected corners of one cell's units ([`crate::plan::lod::Lod::corner`]), computed when first
/// read: a scratch allocated once with the quadtree, emptied per cell by a new stamp.
#[derive(Clone, Debug)]
pub(super) struct CornerGrid {
    pub(super) stamp: u32,
    /// Per unit corner (row-major, [`SIDE`] a row): the stamp it was computed under, and its corner at
    /// the terrain's lowest and highest height.
    pub(super) at: Box<[(u32, [Corner; 2])]>,
}

impl Default for CornerGrid {
    fn default() -> Self {
        Self {
            stamp: 0,
            at: vec![(0, [Corner::default(); 2]); SIDE * SIDE].into_boxed_slice(),
        }
    }
}

impl CornerGrid {
    /// Forgets every corner (another cell).
    pub(super) fn begin(&mut self) {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.at.fill((0, [Corner::default(); 2]));
            self.stamp = 1;
        }
    }
}

/// Tiles whose units' errors [`UnitEtas`] keeps.
const ETA_TILES: usize = 256;

/// The object-space errors of stitched units, per pool tile: unit (a, b) of tile (level k, cx, cy) is
/// one quad of level k + 1, whose error is a pure function of the tables, read once and kept for every
/// later mask of the tile (a mask of a moving view asks them again) and for its groups' exact caps (the
/// largest of their units'). Allocated once with the quadtree; the least recently used tile gives its
/// room to a new one.
#[derive(Clone, Debug)]
pub(super) struct UnitEtas {
    /// Units per tile side.
    pub(super) side: usize,
    /// Per tile slot: (level, cx, cy) and the frame it was last read (0: empty).
    keys: Box<[(u32, i64, i64, u32)]>,
    /// Which slot holds each tile.
    slot_of: KeyMap,
    /// `side^2` errors per slot, row-major; NaN: not read yet; infinite: no table holds the level.
    vals: Box<[f64]>,
    frame: u32,
}

impl UnitEtas {
    /// A table for tiles of `quads` quads a side.
    pub(super) fn new(quads: u32) -> Self {
        let side = (quads as usize / 2).clamp(1, stitch::MAX_UNITS as usize);
        Self {
            side,
            keys: vec![(0, 0, 0, 0); ETA_TILES].into_boxed_slice(),
            slot_of: KeyMap::new(ETA_TILES),
            vals: vec![f64::NAN; ETA_TILES * side * side].into_boxed_slice(),
            frame: 1,
        }
    }

    /// A new frame: tiles read since may give their room.
    pub(super) fn next_frame(&mut self) {
        self.frame = self.frame.wrapping_add(1).max(1);
    }

    /// The slot of tile (`level`, `cx`, `cy`), emptied for it if it was not kept: an empty slot, else
    /// the least recently read (the first on ties).
    pub(super) fn slot(&mut self, level: u32, cx: i64, cy: i64) -> usize {
        let frame = self.frame;
        let key = TileKey { level, cx, cy };
        if let Some(i) = self.slot_of.get(&key) {
            let i = i as usize;
            self.keys[i].3 = frame;
            return i;
        }
        let i = match self.keys.iter().position(|k| k.3 == 0) {
            Some(i) => i,
            None => {
                let mut best = (0u32, 0usize);
                for (i, k) in self.keys.iter().enumerate() {
                    let age = frame.wrapping_sub(k.3);
                    if i == 0 || age > best.0 {
                        best = (age, i);
                    }
                }
                best.1
            }
        };
        let old = self.keys[i];
        if old.3 != 0 {
            self.slot_of.remove(&TileKey {
                level: old.0,
                cx: old.1,
                cy: old.2,
            });
        }
        self.keys[i] = (level, cx, cy, frame);
        self.slot_of
            .insert(key, u32::try_from(i).expect("ETA_TILES < 2^32"));
        let n = self.side * self.side;
        self.vals[i * n..(i + 1) * n].fill(f64::NAN);
        i
    }

    /// Unit (a, b)'s error in tile slot `slot` (infinite: no table holds its level), read by `read` the
    /// first time; None when `read` says the budget ran out (nothing kept).
    pub(super) fn get(
        &mut self,
        slot: usize,
        (a, b): (usize, usize),
        read: impl FnOnce() -> Option<Option<f64>>,
    ) -> Option<f64> {
        let n = self.side * self.side;
        let i = slot * n + (b * self.side + a).min(n - 1);
        if self.vals[i].is_nan() {
            self.vals[i] = read()?.unwrap_or(f64::INFINITY);
        }
        Some(self.vals[i])
    }
}

