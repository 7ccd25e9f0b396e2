//! Stage 2, the per-frame plan: the detail pool's refinement (issue 15). Which cells a clamped block is
//! drawn with: a quadtree over space and level, split minimax-first under the pool's slots and the
//! frame's draws and triangles. Pure, deterministic and allocation-free.

use crate::plan::detail::{DetailBudget, DetailView, TileKey, DETAIL_CAPACITY};
use crate::plan::frame::Rect;
use crate::plan::lod::{LodFrame, MAX_LOD_BLOCKS};
use crate::{Error, Result};

/// Most cells one plan draws from the pool. Each is at least one draw, so `budget.max_draws` binds first
/// on every shipped profile; past it a split does not fit.
pub const MAX_DETAIL_CELLS: usize = 1024;

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
    /// Its screen-space bound, pixels.
    pub(super) bound: f64,
    /// Its block's wanted level: no cell is split finer.
    pub(super) wanted: u32,
    /// Its split does not fit.
    frozen: bool,
}

impl Cell {
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
    /// Scratch: one split's new cells.
    new: Box<heapless::Vec<Cell, { DETAIL_CAPACITY + 1 }>>,
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
    /// that level instead, drawn as a quarter of its tile. So a block goes fine only where its error
    /// needs it, and a cell whose split meets epsilon costs a quarter of a tile's triangles per quarter.
    /// A cell that meets epsilon or reached its block's wanted level is not split.
    pub(super) fn refine(
        &mut self,
        view: &DetailView<'_>,
        lod: &LodFrame,
        bound_at: &dyn Fn(u32, (i64, i64, i64, i64)) -> f64,
        budget: &DetailBudget,
        quads: u32,
        slots: usize,
    ) -> Result<()> {
        let eps = view.epsilon_px;
        let (mut draws, mut triangles) = (i64::from(budget.draws), budget.triangles);
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
            self.new.clear();
            let fitted = self.split(view, lod, bound_at, unit, quads)?;
            // What the split adds: its new tiles, draws and triangles less the cell it replaces.
            let mut new_keys = 0usize;
            for (i, c) in self.new.iter().enumerate() {
                let seen = self.new[..i].iter().any(|o| o.key == c.key);
                if !seen && !self.keys.iter().any(|(k, _)| *k == c.key) {
                    new_keys += 1;
                }
            }
            let n = self.new.len();
            let mut add_t: u64 = self
                .new
                .iter()
                .map(|c| budget.cell_triangles(&c.bounds))
                .sum();
            let (mut add_d, mut freed, mut removed) = (
                i64::try_from(n).expect("n <= capacity") * i64::from(budget.tile_draws),
                0,
                0,
            );
            let sub_t = match unit {
                Unit::Block(k) => {
                    // Its ring draws leave the list (plan_detail's final check still holds the budget).
                    add_d += i64::from(budget.margin.0);
                    add_t += budget.margin.1;
                    self.cands[k].credit
                }
                Unit::Cell(j) => {
                    let old = self.cells[j];
                    add_d -= i64::from(budget.tile_draws);
                    removed = 1;
                    let only = self.keys.iter().any(|(k, r)| *k == old.key && *r == 1);
                    if only && !self.new.iter().any(|c| c.key == old.key) {
                        freed = 1;
                    }
                    budget.cell_triangles(&old.bounds)
                }
            };
            let fits = fitted
                && n > 0
                && self.keys.len() + new_keys - freed <= slots
                && self.cells.len() + n - removed <= MAX_DETAIL_CELLS
                && add_d <= draws
                && add_t <= triangles + sub_t;
            if !fits {
                match unit {
                    Unit::Block(k) => self.cands[k].frozen = true,
                    Unit::Cell(j) => self.cells[j].frozen = true,
                }
                continue;
            }
            draws -= add_d;
            triangles = triangles + sub_t - add_t;
            match unit {
                Unit::Block(k) => self.cands[k].refined = true,
                Unit::Cell(j) => {
                    let old = self.cells.swap_remove(j);
                    self.release(&old.key);
                }
            }
            for i in 0..n {
                let c = self.new[i];
                self.cells
                    .push(c)
                    .expect("checked against MAX_DETAIL_CELLS");
                match self.keys.iter_mut().find(|(k, _)| *k == c.key) {
                    Some((_, r)) => *r += 1,
                    None => self
                        .keys
                        .push((c.key, 1))
                        .expect("checked against the slots"),
                }
            }
        }
        Ok(())
    }

    fn release(&mut self, key: &TileKey) {
        if let Some(i) = self.keys.iter().position(|(k, _)| k == key) {
            self.keys[i].1 -= 1;
            if self.keys[i].1 == 0 {
                self.keys.swap_remove(i);
            }
        }
    }

    /// Writes `unit`'s split into `self.new`; false when it has more cells than the scratch holds.
    fn split(
        &mut self,
        view: &DetailView<'_>,
        lod: &LodFrame,
        bound_at: &dyn Fn(u32, (i64, i64, i64, i64)) -> f64,
        unit: Unit,
        quads: u32,
    ) -> Result<bool> {
        let eps = view.epsilon_px;
        let q = i64::from(quads);
        // A finer cell `key` over `fine` (vertices of level key.level), or the same square one level
        // coarser when that level's bound there already meets epsilon.
        let child = |block: u16, wanted: u32, key: TileKey, fine: Rect| -> Cell {
            let coarse = key.level + 1;
            let bx = level0_box(key.level, &fine);
            let kept = bound_at(coarse, bx);
            if kept <= eps {
                let bounds = halve(&fine);
                Cell {
                    block,
                    key: TileKey {
                        level: coarse,
                        cx: bounds.x0.div_euclid(q),
                        cy: bounds.y0.div_euclid(q),
                    },
                    bounds,
                    bound: kept,
                    wanted,
                    frozen: false,
                }
            } else {
                Cell {
                    block,
                    key,
                    bounds: fine,
                    bound: bound_at(key.level, bx),
                    wanted,
                    frozen: false,
                }
            }
        };
        let new = &mut self.new;
        let mut room = true;
        match unit {
            Unit::Block(k) => {
                let c = self.cands[k];
                let b = lod.blocks[usize::from(c.block)];
                view.cells(&b, c.clamped - 1, quads, |key, fine| {
                    room = new.push(child(c.block, c.wanted, key, fine)).is_ok();
                    Ok(room)
                })?;
            }
            Unit::Cell(j) => {
                let p = self.cells[j];
                let (k, pw) = (p.key.level - 1, double(&p.bounds));
                for dy in 0..2 {
                    for dx in 0..2 {
                        let (cx, cy) = (2 * p.key.cx + dx, 2 * p.key.cy + dy);
                        let cell =
                            Rect::from_bounds(cx * q, cy * q, (cx + 1) * q + 1, (cy + 1) * q + 1);
                        let fine = cell.intersect(&pw);
                        if fine.w >= 2 && fine.h >= 2 && view.visible(k, &fine) {
                            let key = TileKey { level: k, cx, cy };
                            // At most 4 quarters: the scratch holds more.
                            room &= new.push(child(p.block, p.wanted, key, fine)).is_ok();
                        }
                    }
                }
            }
        }
        Ok(room)
    }
}
