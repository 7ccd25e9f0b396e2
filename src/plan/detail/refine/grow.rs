//! Stage 2, the per-frame plan: the detail pool's refinement grows its quadtrees minimax-first: ghosts
//! come into view are covered first, then the largest bound still splittable is split, whole quarters or
//! the finest cut, whichever takes the smaller share of its scarcer budget, while the slots, draws,
//! triangles, records and the frame's bound evaluations last.

use super::mask;
use super::memo::Asker;
use super::ranks;
use super::upkeep::Ask;
use super::split::{resolve_ghost, split_block, split_cell, Outcome, Shape};
use super::{
    double, level0_box, object_error, quarters, Cell, GhostKind, Inputs, Quadtree, Scratch, Unit, MAX_CELL_GROUPS,
    MAX_DETAIL_CELLS, MAX_GHOSTS, MIN_SUB_QUADS,
};
use crate::plan::detail::{cell_quads, DetailBudget, PoolBounds};
use crate::plan::frame::Rect;
use crate::Result;

impl Quadtree {
    /// Splits minimax-first: the block or cell whose bound is largest is split while its new cells fit
    /// `slots` tiles and `budget`'s draws and triangles, until none can or the frame's evaluations are
    /// spent. Ghosts come into view are covered first (their blocks are not served until then); a cell
    /// whose bound is stale is asked again before it is split. A split covers its unit with the cells of
    /// the next finer level (a block: its clamped level's, over the block's piece; a cell: its four
    /// quarters); a quarter whose bound at the unit's own level already meets epsilon stays at that level
    /// instead, drawn as a quarter of its tile. A finer piece costs 4x the triangles of the same ground
    /// one level coarser, so a split may also cut a quarter that misses epsilon again (down to
    /// [`MIN_SUB_QUADS`] finer quads) where some of its parts would meet it (`split.rs`): fewer triangles,
    /// more cells (instances; a draw only per new pair of level and cell quads). Each split takes
    /// whichever of the two (whole quarters or the cut) uses the smaller share of what is left of its
    /// scarcer budget. A cell that meets epsilon or reached its block's wanted level is not split.
    pub(super) fn grow(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) -> Result<()> {
        let eps = at.view.epsilon_px;
        let quads = at.quads;
        // A still camera asks the units still to ask (cells made while the camera moved) before anything
        // else is split, as the one-frame refinement does ([`Quadtree::lazy`]).
        if !self.lazy() && !self.mask_cells(0, at, bounds) {
            return Ok(());
        }
        self.ranks.clear();
        for j in 0..self.cells.len() {
            let r = self.rank(&self.cells[j], eps);
            self.ranks.push(r).expect("ranks hold MAX_DETAIL_CELLS");
        }
        loop {
            let Some(unit) = self.pick(eps) else {
                // Nothing left to split: the units still to ask take what is left of the budget.
                self.mask_cells(0, at, bounds);
                return Ok(());
            };
            if let Unit::Cell(j) = unit {
                if self.cells[j].view != self.view {
                    let ask = if self.lazy() { Ask::Whole } else { Ask::Units };
                    if !self.refresh_cell(j, at, bounds, ask) {
                        self.mid_split = true;
                        self.pending = Some(self.region(unit));
                        return Ok(());
                    }
                    let r = self.rank(&self.cells[j], eps);
                    self.ranks.set(j, r);
                    continue;
                }
            }
            // Two ways to split: whole quarters (fewest cells, slots and pairs of level and quads) or the
            // finest cut (only the parts that miss epsilon one level coarser go finer, so fewest
            // triangles). The one that takes the smaller share of what is left of its scarcer budget is
            // taken (whole quarters on ties). Whole quarters into `self.new`, the cut (when finer than a
            // quarter) into `self.cut`.
            let whole_only = matches!(unit, Unit::Ghost(g) if self.ghosts[g].kind == GhostKind::Cell);
            let cuts = [quads, MIN_SUB_QUADS.min(quads)];
            let mut best: Option<(f64, bool, (i64, u64, u64))> = None;
            let mut out_of_budget = false;
            let mut empty = true;
            for (n, min) in cuts.into_iter().enumerate() {
                let is_cut = n == 1;
                if is_cut && (cuts[1] == quads || whole_only) {
                    break;
                }
                let outcome = self.split(at, bounds, unit, min, is_cut)?;
                if outcome == Outcome::Budget {
                    out_of_budget = true;
                    break;
                }
                let new = if is_cut { &self.cut } else { &self.new };
                empty &= new.cells.is_empty();
                let cost = self
                    .cost(new, unit, at.budget, at.slots)
                    .filter(|_| outcome == Outcome::Room);
                // Where whole quarters are bound by draws (they start new instanced draws), the cut is
                // not made: its smaller pieces start as many pairs of (level, quads) or more (a
                // pruning, nearly always right; the cut is then not weighed).
                let mut draw_bound = cost.is_some_and(|(d, _, _)| d > self.draws);
                if let Some((d, t, sub)) =
                    cost.filter(|&(d, t, sub)| d <= self.draws && t <= self.triangles + sub)
                {
                    #[expect(
                        clippy::cast_precision_loss,
                        reason = "draw and triangle budgets are far below 2^52"
                    )]
                    let (dshare, tshare) = (
                        d.max(0) as f64 / self.draws.max(1) as f64,
                        t.saturating_sub(sub) as f64 / self.triangles.max(1) as f64,
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
            if out_of_budget {
                self.mid_split = true;
                self.pending = Some(self.region(unit));
                return Ok(());
            }
            let Some((_, is_cut, cost)) = best else {
                // Out of room with units still to ask: their triangles first, then the split again.
                if !empty && self.unmasked(at) {
                    if !self.mask_cells(0, at, bounds) {
                        return Ok(());
                    }
                    continue;
                }
                // Nothing in view: hidden while the view stays; else frozen until more is left.
                if !empty {
                    self.mark = Some(self.free(at));
                }
                match unit {
                    Unit::Block(k) if empty => self.cands[k].hidden = true,
                    Unit::Cell(j) if empty => self.cells[j].hidden = true,
                    Unit::Block(k) => self.cands[k].frozen = true,
                    Unit::Cell(j) => {
                        // Not split: drawn as it is, with its units.
                        self.cells[j].frozen = true;
                        if !self.mask_cell(j, at, bounds) {
                            self.pending = Some(self.region(unit));
                            return Ok(());
                        }
                    }
                    Unit::Ghost(g) => self.ghosts[g].frozen = true,
                }
                if let Unit::Cell(j) = unit {
                    let r = self.rank(&self.cells[j], eps);
                    self.ranks.set(j, r);
                }
                continue;
            };
            if is_cut {
                core::mem::swap(&mut self.new, &mut self.cut);
            }
            // The new cells' own bounds, asked before anything is taken (the budget may end here).
            let mut ask = Asker {
                memo: &mut self.memo,
                bounds,
                grid: &mut self.grid,
                etas: &mut self.etas,
            };
            let mut asked = true;
            for c in &mut self.new.cells {
                if c.bound.is_nan() {
                    match ask.ranked(c.key.level, level0_box(c.key.level, &c.bounds)) {
                        Some(b) => c.bound = b,
                        None => {
                            asked = false;
                            break;
                        }
                    }
                }
            }
            if !asked {
                self.mid_split = true;
                self.pending = Some(self.region(unit));
                return Ok(());
            }
            // What proves them in later views ([`Quadtree::prove`]): a table read a quarter, no projection.
            for c in &mut self.new.cells {
                for (cap, bx) in c.cap.iter_mut().zip(quarters(c.key.level, &c.bounds)) {
                    *cap = object_error(bounds, c.key.level, bx);
                }
            }
            let first = self.cells.len() - usize::from(matches!(unit, Unit::Cell(_)));
            self.commit(unit, cost);
            // The ranks follow the cells: the split cell's place taken by the last, the new ones after.
            if let Unit::Cell(j) = unit {
                self.ranks.swap_remove(j);
            }
            for j in self.ranks.len()..self.cells.len() {
                let r = self.rank(&self.cells[j], eps);
                self.ranks.push(r).expect("ranks hold MAX_DETAIL_CELLS");
            }
            if matches!(unit, Unit::Ghost(_)) {
                self.seen_ghosts = self.ghosts.iter().any(|g| g.visible && !g.frozen);
            }
            if !self.lazy() && !self.mask_cells(first, at, bounds) {
                return Ok(());
            }
        }
    }

    /// While the camera moves, cells that will not be split are drawn whole and their units asked later:
    /// when a split lacks room (their triangles come back first), or when nothing is left to split. The
    /// evaluations go to the largest errors first. A whole cell is drawn at its own bound, within epsilon
    /// as its stitched form is, with more triangles and one record. Asking every unit as soon as fewer
    /// than a quarter of the triangles were left spent whole frames on units that freed little (Big
    /// Tujunga at 2 px after a teleport: 1000 evaluations for 11 000 triangles, every other frame).
    fn lazy(&self) -> bool {
        self.moved
    }

    /// Whether some cell that will not be split still has its units to ask (and they may save room).
    fn unmasked(&self, at: &Inputs<'_, '_>) -> bool {
        let eps = at.view.epsilon_px;
        // A still camera asks them first thing in the frame.
        self.moved && self.cells.iter().any(|c| c.waits_for_units(eps))
    }

    /// [`Quadtree::mask_cell`] of cells `first..`, in order; false (the region noted) when the budget ran
    /// out.
    pub(super) fn mask_cells(&mut self, first: usize, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) -> bool {
        for j in first..self.cells.len() {
            if !self.mask_cell(j, at, bounds) {
                self.pending = Some(self.region(Unit::Cell(j)));
                return false;
            }
        }
        true
    }

    /// What is left of the budgets: triangles, draws, slots and records.
    pub(super) fn free(&self, at: &Inputs<'_, '_>) -> (u64, i64, usize, usize) {
        (
            self.triangles,
            self.draws,
            at.slots.saturating_sub(self.keys.len()),
            at.budget.instances.saturating_sub(self.instances),
        )
    }

    /// The unit the refinement splits next: a ghost come into view, else the largest bound still
    /// splittable (blocks first, then cells; first on ties). None when nothing is left. The cells' bounds
    /// are read from `ranks`; debug builds check them against the cells.
    pub(super) fn pick(&self, eps: f64) -> Option<Unit> {
        let pick = self.pick_among(self.ranks.best());
        debug_assert_eq!(
            pick,
            self.pick_among(ranks::best_of(self.cells.iter().map(|c| self.rank(c, eps)))),
            "the cells' ranks are out of step"
        );
        pick
    }

    /// [`Quadtree::pick`] with the cells' largest rank ([`Quadtree::rank`]) and the first cell with it.
    fn pick_among(&self, best: Option<(f64, usize)>) -> Option<Unit> {
        if self.seen_ghosts {
            if let Some(g) = self.ghosts.iter().position(|g| g.visible && !g.frozen) {
                return Some(Unit::Ghost(g));
            }
        }
        let mut pick: Option<(f64, Unit)> = None;
        for (k, c) in self.cands.iter().enumerate() {
            if !c.refined && !c.frozen && !c.hidden && pick.is_none_or(|(b, _)| c.bound > b) {
                pick = Some((c.bound, Unit::Block(k)));
            }
        }
        if let Some((r, j)) = best {
            if pick.is_none_or(|(p, _)| r > p) {
                pick = Some((r, Unit::Cell(j)));
            }
        }
        pick.map(|(_, u)| u)
    }

    /// A cell's rank in [`Quadtree::pick`]: its bound now (rescaled where stale) where it may be split
    /// and misses epsilon (stale: its caps do not prove its own level meets it, [`Quadtree::prove`]),
    /// else minus infinity. A stale cell whose rescaled bound meets epsilon but is not proven is asked
    /// again after the splits (`upkeep.rs`), with its units where they are not proven either.
    pub(super) fn rank(&self, c: &Cell, eps: f64) -> f64 {
        if c.frozen || c.hidden || c.key.level <= c.wanted || (c.view != self.view && c.proof.0 <= eps) {
            return f64::NEG_INFINITY;
        }
        let b = self.now(c, c.bound);
        if b > eps {
            b
        } else {
            f64::NEG_INFINITY
        }
    }


    /// The region (level, samples) a split of `unit` reads: what the source is asked to make ready
    /// while the budget waits for the next frame.
    pub(super) fn region(&self, unit: Unit) -> (u32, Rect) {
        let (level, r) = match unit {
            Unit::Block(k) => {
                let c = &self.cands[k];
                let shift = c.key.ring - (c.clamped - 1);
                let r = &c.key.rect;
                (
                    c.clamped - 1,
                    Rect::from_bounds(
                        r.x0 << shift,
                        r.y0 << shift,
                        ((r.x1() - 1) << shift) + 1,
                        ((r.y1() - 1) << shift) + 1,
                    ),
                )
            }
            Unit::Cell(j) => {
                let c = &self.cells[j];
                match c.key.level.checked_sub(1) {
                    Some(finer) => (finer, double(&c.bounds)),
                    None => (c.key.level, c.bounds),
                }
            }
            Unit::Ghost(g) => (self.ghosts[g].level, self.ghosts[g].bounds),
        };
        // With the tiles' one-sample border.
        (
            level,
            Rect::from_bounds(r.x0 - 1, r.y0 - 1, r.x1() + 1, r.y1() + 1),
        )
    }

    /// Writes `unit`'s split into `self.cut` when `to_cut`, else `self.new`. `min_quads`: the smallest
    /// piece, in quads of the finer level, that a part of the split is cut into.
    pub(super) fn split(
        &mut self,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
        unit: Unit,
        min_quads: u32,
        to_cut: bool,
    ) -> Result<Outcome> {
        let new = if to_cut {
            &mut self.cut
        } else {
            &mut self.new
        };
        new.clear();
        let mut ask = Asker {
            memo: &mut self.memo,
            bounds,
            grid: &mut self.grid,
            etas: &mut self.etas,
        };
        let shape = Shape {
            quads: at.quads,
            min_quads,
            stitch: at.budget.stitch,
        };
        let out = match unit {
            Unit::Block(k) => split_block(new, at.view, &mut ask, at.lod, &self.cands[k], shape)?,
            Unit::Cell(j) => split_cell(new, at.view, &mut ask, &self.cells[j], shape),
            Unit::Ghost(g) => resolve_ghost(new, at.view, &mut ask, &self.ghosts[g], shape),
        };
        // A still view asks the new cells' units within the split, as the one-frame refinement does
        // (they weigh in its cost); a moving view once the split is taken (`mask_cell`). A split that
        // would not fit even with every unit coarse (its fewest triangles) does not fit with any units:
        // they are not asked.
        if out != Outcome::Room || self.moved || !at.budget.stitch {
            return Ok(out);
        }
        let new = if to_cut { &self.cut } else { &self.new };
        let fewest: u64 = new.cells.iter().map(|c| c.fewest_triangles(at.budget)).sum();
        let cheapest = self
            .cost(new, unit, at.budget, at.slots)
            .is_some_and(|(d, _, sub)| d <= self.draws && fewest <= self.triangles + sub);
        if !cheapest {
            return Ok(out);
        }
        let new = if to_cut {
            &mut self.cut
        } else {
            &mut self.new
        };
        let mut ask = Asker {
            memo: &mut self.memo,
            bounds,
            grid: &mut self.grid,
            etas: &mut self.etas,
        };
        let eps = at.view.epsilon_px;
        for c in &mut new.cells {
            let Some(units) = mask::coarse_units(at.view, &mut ask, c.key.level, &c.bounds, (eps, false)) else {
                return Ok(Outcome::Budget);
            };
            *c = c.with_units(&units);
        }
        Ok(out)
    }

    /// What the split in `new` adds: (draws, triangles, triangles it frees), None when it has no cells
    /// or its tiles, cells, records or ghosts do not fit.
    pub(super) fn cost(
        &self,
        new: &Scratch,
        unit: Unit,
        budget: &DetailBudget,
        slots: usize,
    ) -> Option<(i64, u64, u64)> {
        let cells = &new.cells;
        let new_keys = cells
            .iter()
            .enumerate()
            .filter(|&(i, c)| {
                !cells[..i].iter().any(|o| o.key == c.key) && self.keys.get(&c.key).is_none()
            })
            .count();
        let n = cells.len();
        let add_t: u64 = cells.iter().map(|c| c.triangles(budget)).sum();
        // One instanced draw per (level, cell quads): a cell adds a draw only when it starts a pair.
        let new_groups = unseen(cells, group, &self.groups);
        let (mut freed, mut removed, mut gone, mut dropped, mut ghost_gone) = (0, 0, 0, 0, 0);
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
                if is_last(&self.groups, &g) && !cells.iter().any(|c| group(c) == g) {
                    add_d -= 1;
                    gone = 1;
                }
                removed = 1;
                dropped = old.instances();
                if self.keys.get(&old.key) == Some(1) && !cells.iter().any(|c| c.key == old.key) {
                    freed = 1;
                }
                old.triangles(budget)
            }
            Unit::Ghost(_) => {
                ghost_gone = 1;
                0
            }
        };
        let added: usize = cells.iter().map(Cell::instances).sum();
        let fits = n > 0
            && self.instances + added - dropped <= budget.instances
            && self.keys.len() + new_keys - freed <= slots
            && self.cells.len() + n - removed <= MAX_DETAIL_CELLS
            && self.groups.len() + new_groups - gone <= MAX_CELL_GROUPS
            && self.ghosts.len() + new.ghosts.len() - ghost_gone <= MAX_GHOSTS;
        fits.then_some((add_d, add_t, sub_t))
    }

    /// Takes the split in `self.new` of `unit`, which adds `cost` ([`Quadtree::cost`]).
    pub(super) fn commit(&mut self, unit: Unit, (add_d, add_t, sub_t): (i64, u64, u64)) {
        self.taken += 1;
        self.draws -= add_d;
        self.triangles = self.triangles + sub_t - add_t;
        let block = match unit {
            Unit::Block(k) => {
                self.cands[k].refined = true;
                self.cands[k].block
            }
            Unit::Cell(j) => {
                let old = self.cells.swap_remove(j);
                self.instances -= old.instances();
                self.keys.count_out(&old.key);
                count_out(&mut self.groups, &group(&old));
                old.block
            }
            Unit::Ghost(g) => self.ghosts.swap_remove(g).block,
        };
        let (view, scale) = (self.view, self.scale_of(block));
        for i in 0..self.new.cells.len() {
            let mut c = self.new.cells[i];
            (c.view, c.scale) = (view, scale);
            self.instances += c.instances();
            self.cells
                .push(c)
                .expect("checked against MAX_DETAIL_CELLS");
            let keyed = self.keys.count_in(c.key);
            let grouped = count_in(&mut self.groups, group(&c));
            assert!(
                keyed && grouped,
                "checked against the slots and MAX_CELL_GROUPS"
            );
        }
        for g in &self.new.ghosts {
            self.ghosts.push(*g).expect("checked against MAX_GHOSTS");
        }
    }
}

/// Counts one more `k` in `counts` (a distinct key with how many take it); false when a new key finds
/// no room.
pub(super) fn count_in<K: PartialEq, const N: usize>(counts: &mut heapless::Vec<(K, u32), N>, k: K) -> bool {
    match counts.iter_mut().find(|(c, _)| *c == k) {
        Some((_, r)) => {
            *r += 1;
            true
        }
        None => counts.push((k, 1)).is_ok(),
    }
}

/// Counts one `k` fewer in `counts`, dropping it at none.
pub(super) fn count_out<K: PartialEq, const N: usize>(counts: &mut heapless::Vec<(K, u32), N>, k: &K) {
    if let Some(i) = counts.iter().position(|(c, _)| c == k) {
        counts[i].1 -= 1;
        if counts[i].1 == 0 {
            counts.swap_remove(i);
        }
    }
}

/// Whether exactly one taker of `k` is counted in `counts`.
pub(super) fn is_last<K: PartialEq>(counts: &[(K, u32)], k: &K) -> bool {
    counts.iter().any(|(c, r)| c == k && *r == 1)
}

/// How many distinct keys (`key` of each cell of `new`) are not counted in `counts` yet.
pub(super) fn unseen<K: PartialEq>(new: &[Cell], key: impl Fn(&Cell) -> K, counts: &[(K, u32)]) -> usize {
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
pub(super) fn group(c: &Cell) -> (u32, u32) {
    (c.key.level, cell_quads(&c.bounds))
}
