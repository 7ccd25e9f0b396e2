//! Stage 2, the per-frame plan: the detail pool's refinement (issue 15). Which cells a clamped block is
//! drawn with: a quadtree over space and level, split minimax-first under the pool's slots and the
//! frame's draws and triangles. Pure, deterministic and allocation-free.

use crate::plan::detail::{
    cell_quads, stitch, BoundAt, DetailBudget, DetailView, TileKey, DETAIL_CAPACITY,
};
use crate::plan::frame::Rect;
use crate::plan::lod::{LodFrame, MAX_LOD_BLOCKS};
use crate::{Error, Result};

/// Most cells one plan draws from the pool; past it a split does not fit. Cells are instances of a few
/// instanced draws (one per level and cell size), so triangles bind first on every shipped profile.
pub const MAX_DETAIL_CELLS: usize = crate::profile::MAX_POOL_CELLS;

/// Most distinct (level, cell quads) pairs the cells take, each one instanced draw; past it a split does
/// not fit.
const MAX_CELL_GROUPS: usize = 256;

/// The smallest piece a split cuts a cell into, in quads of the finer level: a part of a cell goes one
/// level finer only where the coarser level misses epsilon over a piece this small.
const MIN_SUB_QUADS: u32 = 8;

/// A clamped block while the pool plans it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cand {
    pub(super) block: u16,
    /// The level the selection clamped it to.
    pub(super) clamped: u32,
    /// The level its bound asked for (no cell of it goes finer).
    pub(super) wanted: u32,
    /// Its screen-space bound at `clamped`, pixels.
    pub(super) bound: f64,
    /// How far that bound exceeds epsilon (bound / epsilon): the fill order.
    pub(super) need: f64,
    /// Triangles its own ring draws take in the frame's clamped draw list (freed when it is refined).
    pub(super) credit: u64,
    /// Drawn from pool cells instead of its ring.
    pub(super) refined: bool,
    /// Its cells do not fit.
    frozen: bool,
}

/// One square a refined block is drawn with: part of a tile's cell, clipped to the block's piece.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cell {
    /// The block (index in the LOD frame).
    pub(super) block: u16,
    /// The tile it reads (its level is the cell's).
    pub(super) key: TileKey,
    /// Its vertices in its level's lattice: the whole tile cell or a quarter of it, clipped to the piece.
    pub(super) bounds: Rect,
    /// Its screen-space bound, pixels (NaN in a split's scratch until the split is taken; a cell kept
    /// one level coarser holds a value that only says it meets epsilon).
    pub(super) bound: f64,
    /// Its block's wanted level: no cell is split finer.
    pub(super) wanted: u32,
    /// Its split does not fit.
    frozen: bool,
    /// Drawn stitched ([`stitch`]): which of its units are one quad of the next coarser level (none:
    /// drawn whole).
    pub(super) coarse: stitch::Mask,
}

impl Cell {
    /// Per-instance records it takes: one drawn whole; stitched, one per unit and per unit side on its
    /// border.
    pub(super) fn instances(&self) -> usize {
        if stitch::any(&self.coarse) {
            let (ua, ub) = stitch::units(&self.bounds);
            (ua * ub + 2 * (ua + ub)) as usize
        } else {
            1
        }
    }

    /// Triangles it draws: stitched when some unit is coarse, else whole.
    pub(super) fn triangles(&self, budget: &DetailBudget) -> u64 {
        if stitch::any(&self.coarse) {
            let (ua, ub) = stitch::units(&self.bounds);
            stitch::triangles(&self.coarse, ua, ub)
        } else {
            budget.cell_triangles(&self.bounds)
        }
    }

    /// Whether it is drawn at a level whose bound meets epsilon (or at its block's wanted level).
    pub(super) fn met(&self, eps: f64) -> bool {
        self.bound <= eps || self.key.level <= self.wanted
    }
}

/// The frame's quadtrees: the clamped blocks, the cells of the refined ones and the tiles they read.
#[derive(Clone, Debug, Default)]
pub(super) struct Quadtree {
    pub(super) cands: Box<heapless::Vec<Cand, MAX_LOD_BLOCKS>>,
    pub(super) cells: Box<heapless::Vec<Cell, MAX_DETAIL_CELLS>>,
    /// The distinct tiles the cells read, with how many cells read each (one slot each).
    pub(super) keys: Box<heapless::Vec<(TileKey, u32), DETAIL_CAPACITY>>,
    /// The cells' (level, quads) pairs, with how many cells take each: one instanced draw each.
    groups: heapless::Vec<((u32, u32), u32), MAX_CELL_GROUPS>,
    /// Scratch: one split's new cells (whole quarters, then the one taken).
    new: Box<Scratch>,
    /// Scratch: the same split's cut.
    cut: Box<Scratch>,
    /// The frame's bounds asked so far.
    memo: Memo,
    /// Per-instance records its cells take ([`Cell::instances`]).
    instances: usize,
}

/// One split's new cells.
type Scratch = heapless::Vec<Cell, { DETAIL_CAPACITY + 1 }>;

/// Entries of [`Memo`]'s table (a power of two).
const MEMO_SLOTS: usize = 1 << 13;

/// Probes per look-up: past them a bound is computed and not kept.
const MEMO_PROBES: usize = 8;

/// A bound asked of `bound_at` this plan.
#[derive(Clone, Copy, Debug, Default)]
struct MemoEntry {
    /// The plan that wrote it (0: never).
    generation: u32,
    level: u32,
    bx: (i64, i64, i64, i64),
    exact: bool,
    value: f64,
}

/// The bounds one plan asked of `bound_at` (a pure function of the frame's view), by level and box: a
/// split weighs whole quarters against the cut, whose first tests are the same, and a cell's parts are
/// tested again as the cut recurses. A fixed open-addressed table, emptied by a new generation (no
/// clearing per frame); a bound that finds no room is computed again when asked again, so every value
/// is `bound_at`'s, bit for bit.
#[derive(Clone, Debug)]
struct Memo {
    generation: u32,
    table: Box<[MemoEntry]>,
}

impl Default for Memo {
    fn default() -> Self {
        Self {
            generation: 0,
            table: vec![MemoEntry::default(); MEMO_SLOTS].into_boxed_slice(),
        }
    }
}

impl Memo {
    /// Forgets every bound (a new plan: another view).
    fn next(&mut self) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.table.fill(MemoEntry::default());
            self.generation = 1;
        }
    }

    /// `bound_at(level, bx)`, computed once per plan where the table has room.
    fn get(
        &mut self,
        bound_at: &BoundAt<'_>,
        level: u32,
        bx: (i64, i64, i64, i64),
        exact: bool,
    ) -> f64 {
        #[expect(clippy::cast_sign_loss, reason = "hash mixing: only the bits matter")]
        let h = {
            let mut h =
                (u64::from(level) << 1 | u64::from(exact)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            for v in [bx.0, bx.1, bx.2, bx.3] {
                h = (h ^ v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            }
            (h >> 32) as usize
        };
        for i in 0..MEMO_PROBES {
            let e = &mut self.table[(h + i) & (MEMO_SLOTS - 1)];
            if e.generation != self.generation {
                let value = bound_at(level, bx, exact);
                *e = MemoEntry {
                    generation: self.generation,
                    level,
                    bx,
                    exact,
                    value,
                };
                return value;
            }
            if e.level == level && e.bx == bx && e.exact == exact {
                return e.value;
            }
        }
        bound_at(level, bx, exact)
    }
}

/// A cell's level-0 lattice box (inclusive vertices) from its vertices `r` in level `level`'s lattice.
pub(super) fn level0_box(level: u32, r: &Rect) -> (i64, i64, i64, i64) {
    (
        r.x0 << level,
        r.y0 << level,
        (r.x1() - 1) << level,
        (r.y1() - 1) << level,
    )
}

/// The same vertices one level coarser (`r`'s corners are even: exact).
fn halve(r: &Rect) -> Rect {
    Rect::from_bounds(
        r.x0 >> 1,
        r.y0 >> 1,
        ((r.x1() - 1) >> 1) + 1,
        ((r.y1() - 1) >> 1) + 1,
    )
}

/// The same vertices one level finer.
fn double(r: &Rect) -> Rect {
    Rect::from_bounds(
        r.x0 << 1,
        r.y0 << 1,
        ((r.x1() - 1) << 1) + 1,
        ((r.y1() - 1) << 1) + 1,
    )
}

/// What the refinement splits next.
#[derive(Clone, Copy)]
enum Unit {
    /// A clamped block (drawn from its ring).
    Block(usize),
    /// A cell.
    Cell(usize),
}

impl Quadtree {
    /// Collects the clamped blocks of `lod` (none when the pool has no slots); `ring_triangles[i]`: the
    /// triangles block i's ring draws take (0 past its end).
    pub(super) fn start(
        &mut self,
        lod: &LodFrame,
        eps: f64,
        slots: usize,
        ring_triangles: &[u64],
    ) -> Result<()> {
        self.cands.clear();
        self.cells.clear();
        self.keys.clear();
        self.groups.clear();
        self.instances = 0;
        if slots == 0 {
            return Ok(());
        }
        for (i, b) in lod.blocks.iter().enumerate() {
            if b.wanted < b.level && b.wanted < b.ring {
                self.cands
                    .push(Cand {
                        block: u16::try_from(i).expect("blocks <= MAX_LOD_BLOCKS"),
                        clamped: b.level,
                        wanted: b.wanted,
                        bound: f64::from(b.bound_px),
                        need: f64::from(b.bound_px) / eps,
                        credit: ring_triangles.get(i).copied().unwrap_or(0),
                        refined: false,
                        frozen: false,
                    })
                    .map_err(|_| Error::Capacity {
                        what: "clamped blocks",
                        capacity: MAX_LOD_BLOCKS,
                    })?;
            }
        }
        Ok(())
    }

    /// Splits minimax-first: the block or cell whose bound is largest is split while its new cells fit
    /// `slots` tiles and `budget`'s draws and triangles, until none can. A split covers its unit with
    /// the cells of the next finer level (a block: its clamped level's, over the block's piece; a cell:
    /// its four quarters); a quarter whose bound at the unit's own level already meets epsilon stays at
    /// that level instead, drawn as a quarter of its tile. A finer piece costs 4x the triangles of the
    /// same ground one level coarser, so a split may also cut a quarter that misses epsilon again (down
    /// to [`MIN_SUB_QUADS`] finer quads) where some of its parts would meet it ([`emit`]): fewer
    /// triangles, more cells (instances; a draw only per new pair of level and cell quads). Each split
    /// takes whichever of the two (whole quarters or the cut) uses the smaller share of what is left of
    /// its scarcer budget. A cell that meets epsilon or reached its block's wanted level is not split.
    pub(super) fn refine(
        &mut self,
        view: &DetailView<'_>,
        lod: &LodFrame,
        bound_at: &BoundAt<'_>,
        budget: &DetailBudget,
        quads: u32,
        slots: usize,
    ) -> Result<()> {
        let eps = view.epsilon_px;
        let (mut draws, mut triangles) = (i64::from(budget.draws), budget.triangles);
        self.memo.next();
        loop {
            // The largest bound still splittable (blocks first, then cells; first on ties).
            let mut pick: Option<(f64, Unit)> = None;
            for (k, c) in self.cands.iter().enumerate() {
                if !c.refined && !c.frozen && pick.is_none_or(|(b, _)| c.bound > b) {
                    pick = Some((c.bound, Unit::Block(k)));
                }
            }
            for (j, c) in self.cells.iter().enumerate() {
                if !c.frozen && !c.met(eps) && pick.is_none_or(|(b, _)| c.bound > b) {
                    pick = Some((c.bound, Unit::Cell(j)));
                }
            }
            let Some((_, unit)) = pick else { break };
            // Two ways to split: whole quarters (fewest cells, slots and pairs of level and quads) or the
            // finest cut (only the parts that miss epsilon one level coarser go finer, so fewest
            // triangles). The one that takes the
            // smaller share of what is left of its scarcer budget is taken (whole quarters on ties).
            // Whole quarters into `self.new`, the cut (when finer than a quarter) into `self.cut`.
            let cuts = [quads, MIN_SUB_QUADS.min(quads)];
            let mut best: Option<(f64, bool, (i64, u64, u64))> = None;
            for (n, min) in cuts.into_iter().enumerate() {
                let is_cut = n == 1;
                if is_cut && cuts[1] == quads {
                    break;
                }
                let fitted = self.split(
                    view,
                    lod,
                    bound_at,
                    unit,
                    (quads, budget.stitch),
                    min,
                    is_cut,
                )?;
                let new = if is_cut { &self.cut } else { &self.new };
                let cost = self.cost(new, unit, budget, slots).filter(|_| fitted);
                // Where whole quarters are bound by draws (they start new instanced draws), the cut is
                // not made: its smaller pieces start as many pairs of (level, quads) or more (a
                // pruning, nearly always right; the cut is then not weighed).
                let mut draw_bound = cost.is_some_and(|(d, _, _)| d > draws);
                if let Some((d, t, sub)) =
                    cost.filter(|&(d, t, sub)| d <= draws && t <= triangles + sub)
                {
                    #[expect(
                        clippy::cast_precision_loss,
                        reason = "draw and triangle budgets are far below 2^52"
                    )]
                    let (dshare, tshare) = (
                        d.max(0) as f64 / draws.max(1) as f64,
                        t.saturating_sub(sub) as f64 / triangles.max(1) as f64,
                    );
                    let share = dshare.max(tshare);
                    draw_bound = dshare >= tshare;
                    if best.is_none_or(|(b, _, _)| share < b) {
                        best = Some((share, is_cut, (d, t, sub)));
                    }
                }
                if draw_bound {
                    break;
                }
            }
            let fit = best.map(|(_, is_cut, cost)| {
                if is_cut {
                    core::mem::swap(&mut self.new, &mut self.cut);
                }
                cost
            });
            let Some((add_d, add_t, sub_t)) = fit else {
                match unit {
                    Unit::Block(k) => self.cands[k].frozen = true,
                    Unit::Cell(j) => self.cells[j].frozen = true,
                }
                continue;
            };
            let n = self.new.len();
            draws -= add_d;
            triangles = triangles + sub_t - add_t;
            match unit {
                Unit::Block(k) => self.cands[k].refined = true,
                Unit::Cell(j) => {
                    let old = self.cells.swap_remove(j);
                    self.instances -= old.instances();
                    count_out(&mut self.keys, &old.key);
                    count_out(&mut self.groups, &group(&old));
                }
            }
            for i in 0..n {
                let mut c = self.new[i];
                if c.bound.is_nan() {
                    let bx = level0_box(c.key.level, &c.bounds);
                    c.bound = self.memo.get(bound_at, c.key.level, bx, true);
                }
                self.instances += c.instances();
                self.cells
                    .push(c)
                    .expect("checked against MAX_DETAIL_CELLS");
                let keyed = count_in(&mut self.keys, c.key);
                let grouped = count_in(&mut self.groups, group(&c));
                assert!(
                    keyed && grouped,
                    "checked against the slots and MAX_CELL_GROUPS"
                );
            }
        }
        Ok(())
    }

    /// What the split in `new` adds: (draws, triangles, triangles it frees), None when it has no cells
    /// or its tiles or cells do not fit.
    fn cost(
        &self,
        new: &Scratch,
        unit: Unit,
        budget: &DetailBudget,
        slots: usize,
    ) -> Option<(i64, u64, u64)> {
        let new_keys = unseen(new, |c| c.key, &self.keys);
        let n = new.len();
        let add_t: u64 = new.iter().map(|c| c.triangles(budget)).sum();
        // One instanced draw per (level, cell quads): a cell adds a draw only when it starts a pair.
        let new_groups = unseen(new, group, &self.groups);
        let (mut freed, mut removed, mut gone, mut dropped) = (0, 0, 0, 0);
        let mut add_d = i64::try_from(new_groups).expect("groups <= capacity");
        let sub_t = match unit {
            Unit::Block(k) => {
                // Its ring draws leave the list (plan_detail's final check still holds the budget).
                add_d += i64::from(budget.margin);
                self.cands[k].credit
            }
            Unit::Cell(j) => {
                let old = self.cells[j];
                let g = group(&old);
                if is_last(&self.groups, &g) && !new.iter().any(|c| group(c) == g) {
                    add_d -= 1;
                    gone = 1;
                }
                removed = 1;
                dropped = old.instances();
                if is_last(&self.keys, &old.key) && !new.iter().any(|c| c.key == old.key) {
                    freed = 1;
                }
                old.triangles(budget)
            }
        };
        let added: usize = new.iter().map(Cell::instances).sum();
        let fits = n > 0
            && self.instances + added - dropped <= budget.instances
            && self.keys.len() + new_keys - freed <= slots
            && self.cells.len() + n - removed <= MAX_DETAIL_CELLS
            && self.groups.len() + new_groups - gone <= MAX_CELL_GROUPS;
        fits.then_some((add_d, add_t, sub_t))
    }

    /// Writes `unit`'s split into `self.cut` when `to_cut`, else `self.new`; false when it has more cells
    /// than the scratch holds. `min_quads`: the smallest piece, in quads of the finer level, that a part
    /// of the split is cut into so that only where the coarser level misses epsilon goes finer ([`emit`]).
    #[expect(
        clippy::too_many_arguments,
        reason = "the split's inputs and which scratch it fills"
    )]
    fn split(
        &mut self,
        view: &DetailView<'_>,
        lod: &LodFrame,
        bound_at: &BoundAt<'_>,
        unit: Unit,
        (quads, stitched): (u32, bool),
        min_quads: u32,
        to_cut: bool,
    ) -> Result<bool> {
        let new = if to_cut { &mut self.cut } else { &mut self.new };
        new.clear();
        let memo = &mut self.memo;
        let bound_at = &mut |level: u32, bx: (i64, i64, i64, i64), exact: bool| {
            memo.get(bound_at, level, bx, exact)
        };
        let mut room = true;
        match unit {
            Unit::Block(k) => {
                let c = self.cands[k];
                let b = lod.blocks[usize::from(c.block)];
                view.cells(&b, c.clamped - 1, quads, |key, fine| {
                    let at = Piece {
                        block: c.block,
                        wanted: c.wanted,
                        level: key.level,
                        stitched,
                    };
                    room = emit(new, view, bound_at, &at, quads, min_quads, fine);
                    Ok(room)
                })?;
            }
            Unit::Cell(j) => {
                let p = self.cells[j];
                let q = i64::from(quads);
                let (k, pw) = (p.key.level - 1, double(&p.bounds));
                for dy in 0..2 {
                    for dx in 0..2 {
                        let (cx, cy) = (2 * p.key.cx + dx, 2 * p.key.cy + dy);
                        let cell =
                            Rect::from_bounds(cx * q, cy * q, (cx + 1) * q + 1, (cy + 1) * q + 1);
                        let fine = cell.intersect(&pw);
                        if fine.w >= 2 && fine.h >= 2 && view.visible(k, &fine) {
                            let at = Piece {
                                block: p.block,
                                wanted: p.wanted,
                                level: k,
                                stitched,
                            };
                            room &= emit(new, view, bound_at, &at, quads, min_quads, fine);
                        }
                    }
                }
            }
        }
        Ok(room)
    }
}

/// Counts one more `k` in `counts` (a distinct key with how many take it); false when a new key finds
/// no room.
fn count_in<K: PartialEq, const N: usize>(counts: &mut heapless::Vec<(K, u32), N>, k: K) -> bool {
    match counts.iter_mut().find(|(c, _)| *c == k) {
        Some((_, r)) => {
            *r += 1;
            true
        }
        None => counts.push((k, 1)).is_ok(),
    }
}

/// Counts one `k` fewer in `counts`, dropping it at none.
fn count_out<K: PartialEq, const N: usize>(counts: &mut heapless::Vec<(K, u32), N>, k: &K) {
    if let Some(i) = counts.iter().position(|(c, _)| c == k) {
        counts[i].1 -= 1;
        if counts[i].1 == 0 {
            counts.swap_remove(i);
        }
    }
}

/// Whether exactly one taker of `k` is counted in `counts`.
fn is_last<K: PartialEq>(counts: &[(K, u32)], k: &K) -> bool {
    counts.iter().any(|(c, r)| c == k && *r == 1)
}

/// How many distinct keys (`key` of each cell of `new`) are not counted in `counts` yet.
fn unseen<K: PartialEq>(new: &Scratch, key: impl Fn(&Cell) -> K, counts: &[(K, u32)]) -> usize {
    let mut n = 0;
    for (i, c) in new.iter().enumerate() {
        let k = key(c);
        if !new[..i].iter().any(|o| key(o) == k) && !counts.iter().any(|(c, _)| *c == k) {
            n += 1;
        }
    }
    n
}

/// The instanced draw a cell is one instance of: its level and quads ([`cell_quads`]).
fn group(c: &Cell) -> (u32, u32) {
    (c.key.level, cell_quads(&c.bounds))
}

/// Whose cells a split makes, and at which (finer) level.
struct Piece {
    block: u16,
    wanted: u32,
    level: u32,
    /// Cells are drawn stitched ([`DetailBudget::stitch`]).
    stitched: bool,
}

/// The cell over `r` (vertices of `at.level`) in the tile of `at.level` holding it.
fn cell_at(at: &Piece, level: u32, r: Rect, bound: f64, quads: u32) -> Cell {
    let q = i64::from(quads);
    Cell {
        block: at.block,
        key: TileKey {
            level,
            cx: r.x0.div_euclid(q),
            cy: r.y0.div_euclid(q),
        },
        bounds: r,
        bound,
        wanted: at.wanted,
        frozen: false,
        coarse: [0; stitch::MAX_UNITS as usize],
    }
}

/// The even cut of `lo..=hi` (vertices) into two halves of at least `min` quads each, if any.
fn cut(lo: i64, hi: i64, min: i64) -> Option<i64> {
    let mid = lo + (((hi - lo) / 2) & !1);
    (mid - lo >= min && hi - mid >= min).then_some(mid)
}

/// Pushes the cells that draw `fine` (vertices of `at.level`, even corners, inside one tile cell) onto
/// `new`: one cell one level coarser (half the vertices, a quarter of the triangles) where that level's
/// bound already meets epsilon over it; else, when some quarter of it (halves cut on even vertices, at
/// least `min_quads` quads) would meet it one level coarser, those quarters each the same way; else one
/// cell at `at.level`. Every cell's bound is its own box's (an upper bound, as the whole square's). False
/// when the scratch is full.
fn emit(
    new: &mut Scratch,
    view: &DetailView<'_>,
    bound_at: &mut dyn FnMut(u32, (i64, i64, i64, i64), bool) -> f64,
    at: &Piece,
    quads: u32,
    min_quads: u32,
    fine: Rect,
) -> bool {
    let eps = view.epsilon_px;
    let coarse = at.level + 1;
    // Only whether it meets epsilon is asked: a kept cell's bound is not ranked (it is met).
    let kept = bound_at(coarse, level0_box(at.level, &fine), false);
    if kept <= eps {
        let r = halve(&fine);
        let mut c = cell_at(at, coarse, r, kept, quads);
        if at.stitched {
            c.coarse = coarse_units(view, bound_at, coarse, &r, eps);
        }
        return new.push(c).is_ok();
    }
    let min = i64::from(min_quads);
    let (x1, y1) = (fine.x1() - 1, fine.y1() - 1);
    let (mx, my) = (cut(fine.x0, x1, min), cut(fine.y0, y1, min));
    if mx.is_some() || my.is_some() {
        let xs = match mx {
            Some(m) => [(fine.x0, m), (m, x1)],
            None => [(fine.x0, x1), (0, -1)],
        };
        let ys = match my {
            Some(m) => [(fine.y0, m), (m, y1)],
            None => [(fine.y0, y1), (0, -1)],
        };
        let mut parts: [Option<Rect>; 4] = [None; 4];
        let mut any = false;
        for (i, &(ya, yb)) in ys.iter().enumerate() {
            for (j, &(xa, xb)) in xs.iter().enumerate() {
                if xb <= xa || yb <= ya {
                    continue;
                }
                let r = Rect::from_bounds(xa, ya, xb + 1, yb + 1);
                if !view.visible(at.level, &r) {
                    continue;
                }
                any |= bound_at(coarse, level0_box(at.level, &r), false) <= eps;
                parts[i * 2 + j] = Some(r);
            }
        }
        if any {
            return parts
                .into_iter()
                .flatten()
                .all(|r| emit(new, view, bound_at, at, quads, min_quads, r));
        }
    }
    // Its bound is asked once the split is taken (`Quadtree::refine`): a split not taken needs none.
    let mut c = cell_at(at, at.level, fine, f64::NAN, quads);
    if at.stitched {
        c.coarse = coarse_units(view, bound_at, at.level, &fine, eps);
    }
    new.push(c).is_ok()
}

/// The units of a cell over `r` (vertices of `level`) drawn as one quad of the next coarser level
/// ([`stitch`]): those whose coarser bound meets epsilon (or out of view) and whose neighbours' at their
/// sides does too ([`stitch::erode`]). None when `r`'s corners are not on the coarser lattice.
fn coarse_units(
    view: &DetailView<'_>,
    bound_at: &mut dyn FnMut(u32, (i64, i64, i64, i64), bool) -> f64,
    level: u32,
    r: &Rect,
    eps: f64,
) -> stitch::Mask {
    let mut mask: stitch::Mask = [0; stitch::MAX_UNITS as usize];
    let even = r.x0 % 2 == 0 && r.y0 % 2 == 0 && r.w % 2 == 1 && r.h % 2 == 1;
    if !even {
        return mask;
    }
    let (ua, ub) = stitch::units(r);
    for b in 0..ub.min(stitch::MAX_UNITS) {
        for a in 0..ua.min(stitch::MAX_UNITS) {
            let (x, y) = (r.x0 + 2 * i64::from(a), r.y0 + 2 * i64::from(b));
            let u = Rect::from_bounds(x, y, x + 3, y + 3);
            if !view.visible(level, &u) || bound_at(level + 1, level0_box(level, &u), false) <= eps
            {
                mask[b as usize] |= 1 << a;
            }
        }
    }
    stitch::erode(&mask, ua, ub)
}
