//! Stage 2, the per-frame plan: the detail pool's refinement keeps what it drew in step with the view:
//! a cell made while the camera moved asks its stitched units once it will not be split, and stale cells
//! ask their bounds and units again, largest first (while the camera moves, only those whose caps do not
//! prove epsilon in the new view: `Quadtree::prove`).

use super::mask;
use super::memo::Asker;
use super::{level0_box, Cell, Inputs, Quadtree, Unit};
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
        let Some(units) = mask::coarse_units(at.view, &mut ask, c.key.level, &c.bounds, (eps, moved)) else {
            return false;
        };
        let mut stitched = c.with_units(&units);
        if stitched.view != self.view {
            // Its own bound is stale: its units' proven bound goes with it (`Quadtree::prove`).
            stitched.proof = self.proof_of(&stitched, bounds, eps);
        }
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

    /// Asks stale cells' bounds and units again in this view while the budget lasts: while the camera
    /// moves, those whose caps do not prove epsilon in it ([`Quadtree::prove`]; the others meet it), the
    /// largest proven bound first, each cell's own bound alone where its units' is proven; at a still
    /// camera every one, largest rescaled bound first, which it converges with. A cell whose new units do
    /// not fit what is left keeps its old ones and is frozen (not met).
    pub(super) fn refresh(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) {
        let eps = at.view.epsilon_px;
        // The stale cells, largest first (a refresh changes no cell's place).
        self.order.clear();
        for j in 0..self.cells.len() {
            let c = &self.cells[j];
            let b = if self.moved {
                c.proof.0.max(c.proof.1)
            } else {
                self.now(c, c.bound.max(c.coarse_bound))
            };
            if c.view != self.view && !c.frozen && (!self.moved || b > eps) {
                let j = u16::try_from(j).expect("cells <= MAX_DETAIL_CELLS");
                self.order.push((b, j)).expect("cells <= MAX_DETAIL_CELLS");
            }
        }
        self.order
            .sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for i in 0..self.order.len() {
            let j = usize::from(self.order[i].1);
            let ask = if self.moved && self.cells[j].proof.1 <= eps {
                Ask::Bound
            } else {
                Ask::Units
            };
            if !self.refresh_cell(j, at, bounds, ask) {
                self.pending = Some(self.region(Unit::Cell(j)));
                break;
            }
        }
    }

    /// Asks cell `j`'s bound again in this view, and what `ask` says of its units; false when the budget
    /// ran out first (nothing changed).
    pub(super) fn refresh_cell(
        &mut self,
        j: usize,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
        ask_units: Ask,
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
        if ask_units == Ask::Bound {
            // Its units as they are, at the bound their caps prove in this view (at most epsilon).
            self.cells[j] = Cell {
                coarse_bound: c.proof.1,
                ..fresh
            };
            return true;
        }
        // What is left for the cell's own draw: the frame's triangles and records with its current form's
        // given back.
        let room = self.triangles + c.triangles(at.budget);
        let records = |f: &Cell| self.instances - c.instances() + f.instances();
        let fits = |f: &Cell| f.triangles(at.budget) <= room && records(f) <= at.budget.instances;
        if at.budget.stitch {
            let whole = Cell {
                coarse: [0; stitch::MAX_UNITS as usize],
                coarse_bound: 0.0,
                coarse_cap: [0.0; 4],
                unseen: [0; stitch::MAX_UNITS as usize],
                masked: false,
                ..fresh
            };
            if ask_units == Ask::Whole && fits(&whole) {
                fresh = whole;
            } else {
                let units = mask::coarse_units(
                    at.view,
                    &mut ask,
                    c.key.level,
                    &c.bounds,
                    (at.view.epsilon_px, moved),
                );
                let Some(units) = units else {
                    return false;
                };
                fresh = fresh.with_units(&units);
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

/// What [`Quadtree::refresh_cell`] asks of a cell's units besides its bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Ask {
    /// Nothing: the cell is drawn whole, its units asked later, where the whole cell fits what is left
    /// (the camera moves, [`Quadtree::lazy`]: the refinement refreshes a cell to split it next, most
    /// often, and its units would be asked for nothing).
    Whole,
    /// Its units again.
    Units,
    /// Nothing: they are kept, their caps proving epsilon in this view ([`Quadtree::prove`]).
    Bound,
}
