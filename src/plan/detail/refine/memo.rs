//! Stage 2, the per-frame plan: how the detail pool's refinement asks bounds. Every bound it computes is
//! one evaluation of the frame's refinement budget ([`Work`], a count, never a clock); the bounds asked
//! in the current view are kept ([`Memo`]) while the view does not change, across frames, so a split the
//! budget cut short is taken up again next frame without asking its bounds twice.

use crate::plan::detail::PoolBounds;
use crate::plan::lod::LatticeBox;

/// The frame's refinement budget: bound evaluations left and spent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Work {
    left: u64,
    used: u64,
}

impl Work {
    /// `budget` evaluations to spend.
    pub(crate) fn new(budget: u64) -> Self {
        Self {
            left: budget,
            used: 0,
        }
    }

    /// Takes one evaluation; None when the budget is spent (nothing is taken).
    pub(crate) fn take(&mut self) -> Option<()> {
        self.left = self.left.checked_sub(1)?;
        self.used += 1;
        Some(())
    }

    /// Evaluations spent.
    pub(crate) fn used(&self) -> u64 {
        self.used
    }

    /// Whether none is left.
    #[cfg(test)]
    pub(crate) fn spent(&self) -> bool {
        self.left == 0
    }
}

/// What a bound is asked as ([`Asker`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Kind {
    /// Whether the box meets epsilon (a threshold test: any value on the right side of epsilon).
    #[default]
    Meets,
    /// The ranking value ([`crate::plan::lod::Lod::bound_at_eps_in`]).
    Exact,
    /// A group of stitched units: their error capped by the max pyramid ([`PoolBounds::group`]).
    Group,
}

/// Entries of [`Memo`]'s table (a power of two).
const MEMO_SLOTS: usize = 1 << 14;

/// Probes per look-up: past them a bound is computed and not kept.
const MEMO_PROBES: usize = 8;

/// A bound asked in one view.
#[derive(Clone, Copy, Debug, Default)]
struct MemoEntry {
    /// The view it was asked in (0: never).
    generation: u32,
    level: u32,
    bx: LatticeBox,
    kind: Kind,
    value: f64,
}

/// The bounds asked in the current view (each a pure function of the view), by level, box and kind: a
/// split weighs whole quarters against the cut, whose first tests are the same, a cell's parts are tested
/// again as the cut recurses, and a split the budget stopped is asked again next frame. A fixed
/// open-addressed table, emptied by a new generation (no clearing per view); a bound that finds no room is
/// computed again when asked again, so every value is the bound's own, bit for bit.
#[derive(Clone, Debug)]
pub(super) struct Memo {
    generation: u32,
    table: Box<[MemoEntry]>,
}

impl Default for Memo {
    fn default() -> Self {
        Self {
            generation: 1,
            table: vec![MemoEntry::default(); MEMO_SLOTS].into_boxed_slice(),
        }
    }
}

impl Memo {
    /// Forgets every bound (another view).
    pub(super) fn next(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.table.fill(MemoEntry::default());
            self.generation = 1;
        }
    }

    /// `compute()`, the bound of `kind` at `level` over `bx`, looked up first; one evaluation of `work`
    /// when computed, None (nothing computed) when that is spent.
    fn get(
        &mut self,
        work: &mut Work,
        level: u32,
        bx: LatticeBox,
        kind: Kind,
        compute: impl FnOnce() -> f64,
    ) -> Option<f64> {
        #[expect(clippy::cast_sign_loss, reason = "hash mixing: only the bits matter")]
        let h = {
            let mut h = (u64::from(level) << 2 | kind as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            for v in [bx.0, bx.1, bx.2, bx.3] {
                h = (h ^ v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            }
            (h >> 32) as usize
        };
        let mut free = None;
        for i in 0..MEMO_PROBES {
            let at = (h + i) & (MEMO_SLOTS - 1);
            let e = &self.table[at];
            if e.generation != self.generation {
                free = Some(at);
                break;
            }
            if e.level == level && e.bx == bx && e.kind == kind {
                return Some(e.value);
            }
        }
        work.take()?;
        let value = compute();
        if let Some(at) = free {
            self.table[at] = MemoEntry {
                generation: self.generation,
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
    pub(super) work: &'q mut Work,
    pub(super) bounds: &'q PoolBounds<'b>,
}

impl Asker<'_, '_> {
    /// `level`'s bound over `bx`: with `exact` the ranking value, else a threshold test at epsilon.
    pub(super) fn bound(&mut self, level: u32, bx: LatticeBox, exact: bool) -> Option<f64> {
        let b = self.bounds;
        let kind = if exact { Kind::Exact } else { Kind::Meets };
        self.memo
            .get(self.work, level, bx, kind, || b.at(level, bx, exact))
    }

    /// An upper bound of the bound of `level` over every box inside `bx` ([`PoolBounds::group`]).
    pub(super) fn group(&mut self, level: u32, bx: LatticeBox) -> Option<f64> {
        let b = self.bounds;
        self.memo
            .get(self.work, level, bx, Kind::Group, || b.group(level, bx))
    }
}
