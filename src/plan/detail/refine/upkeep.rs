//! Stage 2, the per-frame plan: the detail pool's refinement keeps what it drew in step with the view:
//! a cell made while the camera moved asks its stitched units once it will not be split, and stale cells
//! ask their bounds and units again, largest first (while the camera moves, only those near epsilon).

use super::mask;
use super::memo::Asker;
use super::{level0_box, Cell, Inputs, Quadtree, Unit, AT_RISK};
use crate::plan::detail::{stitch, PoolBounds};

impl Quadtree {
    /// Asks the coarse units of cell `j` if it has not had them asked and will not be split (it meets
    /// epsilon, or its split does not fit); false when the budget ran out first (nothing changed). Units
    /// that do not fit the records or triangles left are not taken (the cell stays whole).
    pub(super) fn mask_cell(
        &mut self,
        j: usize,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
    ) -> bool {
        let c = self.cells[j];
        let moved = self.moved;
        let eps = at.view.epsilon_px;
        if !c.waits_for_units(eps) {
            return true;
        }
        let mut ask = Asker {
            memo: &mut self.memo,
            bounds,
            grid: &mut self.grid,
            etas: &mut self.etas,
        };
        let Some((m, worst, unseen)) = mask::coarse_units(at.view, &mut ask, c.key.level, &c.bounds, (eps, moved))
        else {
            return false;
        };
        let stitched = Cell {
            coarse: m,
            coarse_bound: worst,
            unseen,
            masked: true,
            ..c
        };
        let (old_t, new_t) = (c.triangles(at.budget), stitched.triangles(at.budget));
        let records = self.instances - c.instances() + stitched.instances();
        self.cells[j] = if new_t <= self.triangles + old_t && records <= at.budget.instances {
            self.triangles = self.triangles + old_t - new_t;
            self.instances = records;
            stitched
        } else {
            Cell { masked: true, ..c }
        };
        true
    }

    /// Asks stale cells' bounds and units again in this view, largest (rescaled) bound first, while the
    /// budget lasts: while the camera moves, those whose rescaled bound is within [`AT_RISK`] of epsilon
    /// (the others are kept as they are); at a still camera every one, which it converges with. A cell
    /// whose new units do not fit what is left keeps its old ones and is frozen (not met).
    pub(super) fn refresh(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) {
        let floor = if self.moved {
            AT_RISK * at.view.epsilon_px
        } else {
            f64::NEG_INFINITY
        };
        // The stale cells, largest first (a refresh changes no cell's place).
        self.order.clear();
        for j in 0..self.cells.len() {
            let c = &self.cells[j];
            let b = self.now(c, c.bound.max(c.coarse_bound));
            if c.view != self.view && !c.frozen && b > floor {
                let j = u16::try_from(j).expect("cells <= MAX_DETAIL_CELLS");
                self.order.push((b, j)).expect("cells <= MAX_DETAIL_CELLS");
            }
        }
        self.order
            .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for i in 0..self.order.len() {
            let j = usize::from(self.order[i].1);
            if !self.refresh_cell(j, at, bounds, false) {
                self.pending = Some(self.region(Unit::Cell(j)));
                break;
            }
        }
    }

    /// Asks cell `j`'s bound and coarse units again in this view; false when the budget ran out first
    /// (nothing changed). `lazy` ([`Quadtree::lazy`]: the camera moves): only the bound is asked and the
    /// cell is drawn whole, its units asked later, where the whole cell fits what is left. The refinement
    /// refreshes a cell to split it next, most often: its units would be asked for nothing.
    pub(super) fn refresh_cell(
        &mut self,
        j: usize,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
        lazy: bool,
    ) -> bool {
        let c = self.cells[j];
        let moved = self.moved;
        let scale = self.scale_of(c.block);
        let mut ask = Asker {
            memo: &mut self.memo,
            bounds,
            grid: &mut self.grid,
            etas: &mut self.etas,
        };
        let Some(bound) = ask.ranked(c.key.level, level0_box(c.key.level, &c.bounds)) else {
            return false;
        };
        let mut fresh = Cell {
            bound,
            view: self.view,
            scale,
            ..c
        };
        // What is left for the cell's own draw: the frame's triangles and records with its current form's
        // given back.
        let room = self.triangles + c.triangles(at.budget);
        let records = |f: &Cell| self.instances - c.instances() + f.instances();
        let fits = |f: &Cell| f.triangles(at.budget) <= room && records(f) <= at.budget.instances;
        if at.budget.stitch {
            let whole = Cell {
                coarse: [0; stitch::MAX_UNITS as usize],
                coarse_bound: 0.0,
                unseen: [0; stitch::MAX_UNITS as usize],
                masked: false,
                ..fresh
            };
            if lazy && fits(&whole) {
                fresh = whole;
            } else {
                let units = mask::coarse_units(
                    at.view,
                    &mut ask,
                    c.key.level,
                    &c.bounds,
                    (at.view.epsilon_px, moved),
                );
                let Some((m, worst, unseen)) = units else {
                    return false;
                };
                (fresh.coarse, fresh.coarse_bound, fresh.unseen, fresh.masked) = (m, worst, unseen, true);
            }
        }
        if !fits(&fresh) {
            self.cells[j].frozen = true;
            return true;
        }
        self.triangles = room - fresh.triangles(at.budget);
        self.instances = records(&fresh);
        self.cells[j] = fresh;
        true
    }
}
