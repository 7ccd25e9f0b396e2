//! Stage 2, the per-frame plan: how the detail pool's refinement asks bounds. Every box or sub-box whose
//! error a bound reads and projects is one evaluation of the frame's refinement budget (the selector's
//! allowance, [`crate::plan::lod::Lod::set_allowance`]: a count, never a clock); a bound the budget stops
//! halfway is NaN and kept nowhere. The bounds asked in the current view are kept ([`Memo`]) while the
//! view does not change, across frames, so a split the budget cut short is taken up again next frame
//! without asking its bounds twice.

use super::corners::{CornerGrid, UnitEtas};
use crate::plan::camera::Corner;
use crate::plan::detail::PoolBounds;
use crate::plan::lod::LatticeBox;

/// What a bound is asked as ([`Asker`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Kind {
    /// Whether the box meets epsilon (a threshold test: any value on the right side of epsilon).
    #[default]
    Meets,
    /// The whole split's value ([`crate::plan::lod::Lod::bound_in`] with no limit).
    Full,
    /// A group of stitched units: their error capped by the max pyramid
    /// ([`crate::plan::lod::Lod::cap_bound_with_corners`]).
    Group,
    /// The same with the error capped by the largest of its units' own.
    Capped,
}

/// Entries of [`Memo`]'s table (a power of two).
const MEMO_SLOTS: usize = 1 << 14;

/// Probes per look-up: past them a bound is computed and not kept.
const MEMO_PROBES: usize = 8;

/// A bound asked in one view.
#[derive(Clone, Copy, Debug, Default)]
struct MemoEntry {
    /// The last frame that asked it ([`Memo::frame`]).
    used: u32,
    level: u32,
    bx: LatticeBox,
    kind: Kind,
    value: f64,
}

/// The bounds asked in the current view (each a pure function of the view), by level, box and kind: a
/// split weighs whole quarters against the cut, whose first tests are the same, a cell's parts are tested
/// again as the cut recurses, and a split the budget stopped is asked again next frame. A fixed
/// open-addressed table, emptied by a new generation (no clearing per view). A full probe sequence gives
/// its least recently asked entry to the new bound, unless that was asked this frame too: what a split
/// the budget stopped asked stays for the next frame, which asks it again first, so a split that needs
/// more than one frame's budget still ends. A bound that finds no room is computed again when asked
/// again, so every value is the bound's own, bit for bit.
#[derive(Clone, Debug)]
pub(super) struct Memo {
    generation: u32,
    /// Counts the frames (plans) that asked bounds.
    frame: u32,
    /// Each entry's view (0: never), apart from the entries: a moving camera's view is new every frame,
    /// so nearly every probe ends on an entry of another view: reading 64 KiB of these, not the entries'
    /// 900 KiB, took that load from 6 % of a flight's samples to under 1 % (docs/plan-time.md).
    generations: Box<[u32]>,
    table: Box<[MemoEntry]>,
}

impl Default for Memo {
    fn default() -> Self {
        Self {
            generation: 1,
            frame: 1,
            generations: vec![0; MEMO_SLOTS].into_boxed_slice(),
            table: vec![MemoEntry::default(); MEMO_SLOTS].into_boxed_slice(),
        }
    }
}

impl Memo {
    /// A new frame: the bounds the last one asked may now give their entries to new ones.
    pub(super) fn next_frame(&mut self) {
        self.frame = self.frame.wrapping_add(1).max(1);
    }

    /// The current view's generation (what [`Memo::resume`] takes back).
    pub(super) fn generation(&self) -> u32 {
        self.generation
    }

    /// Goes back to an earlier view's generation, `g`, whose entries are kept where no later view's took
    /// their place (a lagging refinement: `refine/mod.rs`, `Lag`). No generation after `g` may hold an
    /// entry: [`Memo::next`] gives its number out again, and the entry would be read as the new view's.
    pub(super) fn resume(&mut self, g: u32) {
        self.generation = g;
    }

    /// Forgets every bound (another view).
    pub(super) fn next(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.generations.fill(0);
            self.generation = 1;
        }
    }

    /// `compute()`, the bound of `kind` at `level` over `bx`, looked up first; None (nothing kept) when
    /// it is NaN: the budget ran out while it was computed.
    fn get(
        &mut self,
        level: u32,
        bx: LatticeBox,
        kind: Kind,
        compute: impl FnOnce() -> f64,
    ) -> Option<f64> {
        #[expect(
            clippy::cast_sign_loss,
            clippy::cast_possible_truncation,
            reason = "hash mixing: only the bits matter"
        )]
        let h = crate::plan::slot_hash(&[
            u64::from(level) << 2 | kind as u64,
            bx.0 as u64,
            bx.1 as u64,
            bx.2 as u64,
            bx.3 as u64,
        ]) as usize;
        let mut free = None;
        let mut oldest: Option<(u32, usize)> = None;
        for i in 0..MEMO_PROBES {
            let at = (h + i) & (MEMO_SLOTS - 1);
            if self.generations[at] != self.generation {
                free = Some(at);
                break;
            }
            let e = &mut self.table[at];
            if e.level == level && e.bx == bx && e.kind == kind {
                e.used = self.frame;
                return Some(e.value);
            }
            // Frames since it was asked (wrapping): the larger, the older.
            let age = self.frame.wrapping_sub(e.used);
            if age > 0 && oldest.is_none_or(|(a, _)| age > a) {
                oldest = Some((age, at));
            }
        }
        let value = compute();
        if value.is_nan() {
            return None;
        }
        if let Some(at) = free.or(oldest.map(|(_, at)| at)) {
            self.generations[at] = self.generation;
            self.table[at] = MemoEntry {
                used: self.frame,
                level,
                bx,
                kind,
                value,
            };
        }
        Some(value)
    }
}

/// The refinement's way to its bounds this frame: the view's bounds, through the memo, under the budget.
/// Each method is None when the budget is spent.
pub(super) struct Asker<'q, 'b> {
    pub(super) memo: &'q mut Memo,
    pub(super) bounds: &'q PoolBounds<'b>,
    /// The corners of the cell whose units are asked.
    pub(super) grid: &'q mut CornerGrid,
    /// The units' errors, per tile.
    pub(super) etas: &'q mut UnitEtas,
}

impl Asker<'_, '_> {
    /// `level`'s bound over `bx`, a threshold test at epsilon: a value at most epsilon exactly when the
    /// bound is.
    pub(super) fn bound(&mut self, level: u32, bx: LatticeBox) -> Option<f64> {
        let b = self.bounds;
        self.memo
            .get(level, bx, Kind::Meets, || b.meets(level, bx))
    }

    /// `level`'s bound over `bx` to rank a cell by: the threshold test's value where the box meets
    /// epsilon (all that is asked of a cell that meets it), else the whole split's
    /// ([`crate::plan::lod::Lod::bound_at_eps_in`]'s value there, bit for bit).
    pub(super) fn ranked(&mut self, level: u32, bx: LatticeBox) -> Option<f64> {
        let t = self.bound(level, bx)?;
        if t <= self.bounds.eps {
            return Some(t);
        }
        let b = self.bounds;
        self.memo.get(level, bx, Kind::Full, || {
            b.lod
                .bound_in(&b.view, b.mode, level, bx, f64::INFINITY)
        })
    }

    /// [`Asker::bound`] of a stitched unit (one quad of `level`, not split) whose corners are known, its
    /// error kept in `etas` at `at` (tile slot, unit): a threshold test.
    pub(super) fn unit(
        &mut self,
        level: u32,
        bx: LatticeBox,
        corners: &[Corner; 8],
        (slot, unit): (usize, (usize, usize)),
    ) -> Option<f64> {
        let eta = self.unit_eta(level, bx, (slot, unit))?;
        let b = self.bounds;
        self.memo.get(level, bx, Kind::Meets, || {
            let eta = Some(eta).filter(|e| e.is_finite());
            b.lod.unit_bound(&b.view, b.mode, bx, corners, eta)
        })
    }

    /// A stitched unit's error at `level` (one quad, box `bx`), kept in `etas` at `at` (tile slot, unit):
    /// read the first time (one evaluation). Infinite where no table holds the level; None when the
    /// budget ran out.
    pub(super) fn unit_eta(
        &mut self,
        level: u32,
        bx: LatticeBox,
        (slot, unit): (usize, (usize, usize)),
    ) -> Option<f64> {
        let b = self.bounds;
        self.etas
            .get(slot, unit, || b.lod.read_eta(b.mode, level, bx))
    }

    /// The bound of `level` over group box `bx` whose corners are known, with its units' largest error
    /// `cap`: at least every unit's own bound.
    pub(super) fn capped(
        &mut self,
        level: u32,
        bx: LatticeBox,
        corners: &[Corner; 8],
        cap: f64,
    ) -> Option<f64> {
        let b = self.bounds;
        self.memo.get(level, bx, Kind::Capped, || {
            let eta = Some(cap).filter(|e| e.is_finite());
            b.lod.unit_bound(&b.view, b.mode, bx, corners, eta)
        })
    }

    /// An upper bound of the bound of `level` over every box inside `bx`, whose corners are known
    /// ([`crate::plan::lod::Lod::cap_bound_with_corners`]).
    pub(super) fn group(&mut self, level: u32, bx: LatticeBox, corners: &[Corner; 8]) -> Option<f64> {
        let b = self.bounds;
        self.memo.get(level, bx, Kind::Group, || {
            b.lod
                .cap_bound_with_corners(&b.view, b.mode, level, bx, corners)
        })
    }
}
