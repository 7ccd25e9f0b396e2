//! Stage 2, the per-frame plan: what SAT LOD's selector keeps between frames, in tables allocated once
//! with it. Each holds values of pure functions, so a hit gives the computed bits: the object-space
//! errors by table level, mode and data box ([`EtaCache`]), and each block's selection by view
//! ([`SelectCache`]: a block whose screen scale has not changed keeps its level without a bound read).

use std::cell::Cell;

use super::LodMode;
use crate::plan::frame::Rect;
use crate::plan::slot_hash;

/// Entries of [`EtaCache`] (a power of two): 32 bytes each, 1 MiB, allocated once with the selector.
const ETA_SLOTS: usize = 1 << 15;

/// One cached object-space error: table level `k`, mode and data box (x0, y0, x1, y1).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct EtaEntry {
    /// k + 1 (0: empty).
    k: u16,
    mode: u8,
    bx: [u32; 4],
    value: f64,
}

/// The object-space errors ([`crate::bake::lod_tables::LevelTables::eta`]) the selection and the detail
/// pool have asked, by table level, mode and data box. They are a pure function of the tables, which a
/// selector never changes, while the camera only changes how they project: blocks and pool cells sit on
/// fixed lattices, so the same boxes are asked frame after frame. A direct-mapped table (a colliding box
/// replaces the entry), so every value is the tables' own, bit for bit; interior mutability keeps the
/// selector's methods `&self`. Allocated once; a look-up allocates nothing.
#[derive(Clone, Debug)]
pub(super) struct EtaCache(Box<[Cell<EtaEntry>]>);

impl Default for EtaCache {
    fn default() -> Self {
        Self(vec![Cell::new(EtaEntry::default()); ETA_SLOTS].into_boxed_slice())
    }
}

impl EtaCache {
    /// `compute()`, the error of table level `k` under `mode` over data box `bx`, looked up first.
    pub(super) fn get(&self, k: u32, mode: LodMode, bx: [u32; 4], compute: impl FnOnce() -> f64) -> f64 {
        let key_k = u16::try_from(k + 1).unwrap_or(u16::MAX);
        let mode_id = mode as u8;
        let h = slot_hash(&[
            u64::from(key_k) << 8 | u64::from(mode_id),
            u64::from(bx[0]) << 32 | u64::from(bx[1]),
            u64::from(bx[2]) << 32 | u64::from(bx[3]),
        ]);
        let slot = &self.0[usize::try_from(h).unwrap_or(0) & (ETA_SLOTS - 1)];
        let e = slot.get();
        if e.k == key_k && e.mode == mode_id && e.bx == bx {
            return e.value;
        }
        let value = compute();
        slot.set(EtaEntry {
            k: key_k,
            mode: mode_id,
            bx,
            value,
        });
        value
    }
}

/// Grid cells per side of one ring's share of [`SelectCache`]: a ring's active region meets at most 6
/// consecutive cells per side ([`super::max_blocks_per_frame`]), so cells taken modulo 8 never collide.
const SELECT_SIDE: usize = 8;

/// Entries of [`SelectCache`]: one per ring and grid cell modulo [`SELECT_SIDE`].
const SELECT_SLOTS: usize = crate::plan::frame::MAX_LEVELS * SELECT_SIDE * SELECT_SIDE;

/// One block's selection in one view: what [`super::Lod::select`] computed for it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Selected {
    /// The view it was computed in ([`view_key`]; 0: empty).
    pub(super) view: u64,
    pub(super) ring: u32,
    /// Its column and row in the ring's grid of blocks.
    pub(super) cell: (i64, i64),
    pub(super) rect: Rect,
    /// The frame's levels when computed (the descent starts at the coarsest).
    pub(super) levels: u32,
    /// The level the bound asked for.
    pub(super) wanted: u32,
    /// The level whose error and bound follow (the level drawn when computed).
    pub(super) level: u32,
    pub(super) eta: f64,
    pub(super) bound: f64,
    /// The block's scale then, pixels per metre of error ([`crate::plan::camera::BoxScale::per_metre`]).
    pub(super) scale: f64,
    /// The wanted level's error capped over the whole block ([`super::Lod::eta_cap`]): view-independent,
    /// so that its bound in a later view is one product (what holds a block while the camera moves).
    pub(super) cap: f64,
    /// The wanted level's error over each sub-box of the block's cut, as its threshold test read them
    /// (each capped by `cap`; `cap` throughout where the test did not meet epsilon at that level): what
    /// holds a block whose whole-block bound no longer meets epsilon ([`super::Lod::held_bound`]).
    pub(super) subs: super::SubErrors,
}

/// Each block's last selection, by ring and grid cell: a block seen in the same view (camera, viewport,
/// epsilon and mode bit for bit, so every bound of it is the same) with the same rectangle takes its
/// wanted level, error and bound from here instead of reading bounds; one seen in another view, or
/// clipped otherwise, starts its search from the level kept here. Direct-mapped (a colliding block replaces the entry), so
/// every value is the selection's own; interior mutability keeps the selector's methods `&self`.
#[derive(Clone, Debug)]
pub(super) struct SelectCache(Box<[Cell<Selected>]>);

impl Default for SelectCache {
    fn default() -> Self {
        Self(vec![Cell::new(Selected::default()); SELECT_SLOTS].into_boxed_slice())
    }
}

impl SelectCache {
    /// The entry of the block in cell `cell` (its column and row in the ring's block grid) of `ring`:
    /// the cell's column and row modulo [`SELECT_SIDE`], so the blocks of one frame never evict each
    /// other (a hashed slot let a frame's 200 blocks evict about 20 of theirs each frame, each then
    /// searched from the coarsest level again).
    fn slot(&self, ring: u32, cell: (i64, i64)) -> &Cell<Selected> {
        let side = SELECT_SIDE as i64;
        #[expect(clippy::cast_possible_truncation, reason = "rem_euclid of a small positive modulus")]
        let (x, y) = (cell.0.rem_euclid(side) as usize, cell.1.rem_euclid(side) as usize);
        let r = ring as usize % crate::plan::frame::MAX_LEVELS;
        &self.0[(r * SELECT_SIDE + y) * SELECT_SIDE + x]
    }

    /// Block (`ring`, `rect`, in grid cell `cell`)'s selection in view `view` with `levels` levels, if
    /// kept.
    pub(super) fn get(
        &self,
        view: u64,
        ring: u32,
        cell: (i64, i64),
        rect: &Rect,
        levels: u32,
    ) -> Option<Selected> {
        self.last(ring, cell, levels)
            .filter(|e| e.view == view && e.rect == *rect)
    }

    /// The last selection of a block in grid cell `cell` of `ring` with `levels` levels, in whatever
    /// view and clipping of the cell.
    pub(super) fn last(&self, ring: u32, cell: (i64, i64), levels: u32) -> Option<Selected> {
        let e = self.slot(ring, cell).get();
        (e.view != 0 && e.ring == ring && e.cell == cell && e.levels == levels).then_some(e)
    }

    /// Keeps `e`.
    pub(super) fn put(&self, e: Selected) {
        self.slot(e.ring, e.cell).set(e);
    }
}

/// A key of everything a block's bounds depend on besides the block: the camera, the viewport, epsilon
/// and the mode, bit for bit (never 0).
pub(super) fn view_key(
    camera: &crate::plan::camera::Camera,
    view: (u32, u32),
    epsilon_px: f64,
    mode: LodMode,
) -> u64 {
    let mut h = crate::hash::Hash64::new();
    for v in [camera.eye, camera.target] {
        for c in v.to_array() {
            h.write_u64(c.to_bits());
        }
    }
    for c in [camera.fov_y_deg, camera.near, camera.far, epsilon_px] {
        h.write_u64(c.to_bits());
    }
    h.write_u32(view.0);
    h.write_u32(view.1);
    h.write_u32(mode as u32);
    h.finish() | 1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every block of a frame keeps its entry: the cells of any 6 x 6 window of every ring (at any
    /// offset, negative ones included) take distinct slots, so a frame's blocks never evict each other.
    #[test]
    fn a_frames_blocks_never_evict_each_other() {
        let cache = SelectCache::default();
        for (ox, oy) in [(0i64, 0i64), (-3, 5), (1_000_003, -77), (-8, -8)] {
            let cells = |ring: u32| {
                (0..6i64).flat_map(move |j| (0..6i64).map(move |i| (ring, (ox + i, oy + j))))
            };
            let all = || (0..crate::profile::MAX_LEVELS).flat_map(cells);
            for (ring, cell) in all() {
                cache.put(Selected {
                    view: 1,
                    ring,
                    cell,
                    levels: 9,
                    wanted: ring,
                    ..Selected::default()
                });
            }
            for (ring, cell) in all() {
                let e = cache.last(ring, cell, 9).expect("kept");
                assert_eq!((e.ring, e.cell, e.wanted), (ring, cell, ring));
            }
        }
    }
}
