//! Stage 2, the per-frame plan: the detail pool's refinement. Which cells a clamped block is drawn with: a
//! quadtree over space and level, split minimax-first under the pool's slots and the frame's draws and
//! triangles, and under a fixed number of bound evaluations a frame (`budget.refine_bounds_per_frame`).
//! The quadtree carries over from frame to frame (`carry.rs`): a frame starts from the last one's,
//! re-tests what changed screen scale, covers what came into view, and spends what is left of its budget
//! where the error is largest (docs/plan-time.md). Pure, deterministic and allocation-free.

use crate::plan::detail::keymap::KeyMap;
use crate::plan::detail::{
    cell_quads, stitch, DetailBudget, DetailView, PoolBounds, TileKey, DETAIL_CAPACITY,
};
use crate::plan::frame::Rect;
use crate::plan::lod::{LatticeBox, LodFrame, MAX_LOD_BLOCKS};
use crate::Result;

mod carry;
mod mask;
mod memo;
mod split;

use memo::{Asker, Memo};
use split::{resolve_ghost, split_block, split_cell, Outcome, Shape};

/// Most cells one plan draws from the pool; past it a split does not fit. Cells are instances of a few
/// instanced draws (one per level and cell size), so triangles bind first on every shipped profile.
pub const MAX_DETAIL_CELLS: usize = crate::profile::MAX_POOL_CELLS;

/// Most ghosts (parts of a split out of the view) the quadtrees keep; past it a split does not fit.
const MAX_GHOSTS: usize = 2 * MAX_DETAIL_CELLS;

/// Most distinct (level, cell quads) pairs the cells take, each one instanced draw; past it a split does
/// not fit.
const MAX_CELL_GROUPS: usize = 256;

/// The smallest piece a split cuts a cell into, in quads of the finer level: a part of a cell goes one
/// level finer only where the coarser level misses epsilon over a piece this small.
const MIN_SUB_QUADS: u32 = 8;

/// While the camera moves, a stale cell is asked again only when its rescaled bound (or its coarse
/// units') is past this share of epsilon: the others cannot have passed it yet, to first order.
const AT_RISK: f64 = 0.9;

/// How far past epsilon a stale bound, rescaled, may be while the camera moves before it counts as missing
/// it (`Quadtree::limit`): an estimate's margin, not the bound's; a still camera asks every stale bound
/// again and holds it to epsilon.
const MOTION_SLACK: f64 = 1.0 / 32.0;

/// No block (an unused entry of the quadtree's block maps).
const NONE: u16 = u16::MAX;

/// What a clamped block is across frames: its ring, its rectangle and the finer ring's hole in it (its
/// pieces, which its cells cover).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct BlockKey {
    ring: u32,
    rect: Rect,
    hole: Rect,
}

/// A clamped block while the pool plans it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cand {
    /// Its index in the frame's LOD blocks.
    pub(super) block: u16,
    key: BlockKey,
    /// The level the selection clamped it to.
    pub(super) clamped: u32,
    /// The level its bound asked for (no cell of it goes finer).
    pub(super) wanted: u32,
    /// Its screen-space bound at `clamped`, pixels (this frame's).
    pub(super) bound: f64,
    /// How far that bound exceeds epsilon (bound / epsilon): the fill order.
    pub(super) need: f64,
    /// Triangles its own ring draws take in the frame's clamped draw list (freed when it is refined).
    pub(super) credit: u64,
    /// Drawn from pool cells instead of its ring.
    pub(super) refined: bool,
    /// Its cells do not fit (kept until what is left of the budgets grows: `carry.rs`).
    frozen: bool,
    /// Its split has no cell in view (kept while the view stays).
    hidden: bool,
    /// Its box's scale in this frame's view, pixels per metre: what its cells' bounds are rescaled by.
    scale: f64,
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
    /// Its screen-space bound, pixels, in view `view` (NaN in a split's scratch until the split is
    /// taken; a cell kept one level coarser holds a value that only says it meets epsilon).
    pub(super) bound: f64,
    /// Its block's wanted level: no cell is split finer.
    pub(super) wanted: u32,
    /// Its split does not fit (kept until what is left of the budgets grows).
    frozen: bool,
    /// Its split has no cell in view (kept while the view stays).
    hidden: bool,
    /// Drawn stitched ([`stitch`]): which of its units are one quad of the next coarser level (none:
    /// drawn whole).
    pub(super) coarse: stitch::Mask,
    /// The largest bound of a coarse unit's coarser level in view `view` (0: none).
    coarse_bound: f64,
    /// Its units were asked, or it is not drawn stitched (a cell made while the camera moves is drawn
    /// whole until they are: `Quadtree::mask_cell`).
    masked: bool,
    /// The view its bound and units were asked in ([`Quadtree`]'s count of views).
    view: u32,
    /// Its block's scale then ([`Cand::scale`]).
    scale: f64,
    /// Drawn within epsilon (or at its block's wanted level) in this frame's view: fresh, or its
    /// bounds rescaled by its block's change of scale since they were asked.
    pub(super) met: bool,
}

/// What a ghost stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GhostKind {
    /// A part of a split that was out of view: covered through `emit` when it comes into view.
    Part,
    /// A cell that left the view: drawn as it was when it comes back.
    Cell,
}

/// A part of a refined block out of view: not drawn, no tile; when it comes into view the block is not
/// served until it is covered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Ghost {
    pub(super) block: u16,
    pub(super) wanted: u32,
    /// Its level and vertices in that level's lattice.
    pub(super) level: u32,
    pub(super) bounds: Rect,
    pub(super) kind: GhostKind,
    /// In view this frame.
    pub(super) visible: bool,
    /// Its cover does not fit (kept until what is left of the budgets grows).
    frozen: bool,
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
}

/// One split's new cells and ghosts.
#[derive(Clone, Debug, Default)]
pub(super) struct Scratch {
    pub(super) cells: heapless::Vec<Cell, { DETAIL_CAPACITY + 1 }>,
    pub(super) ghosts: heapless::Vec<Ghost, { DETAIL_CAPACITY + 1 }>,
}

impl Scratch {
    fn clear(&mut self) {
        self.cells.clear();
        self.ghosts.clear();
    }
}

/// The frame's quadtrees, carried from frame to frame: the clamped blocks, the cells of the refined ones
/// and the tiles they read.
#[derive(Clone, Debug)]
pub(super) struct Quadtree {
    pub(super) cands: Box<heapless::Vec<Cand, MAX_LOD_BLOCKS>>,
    pub(super) cells: Box<heapless::Vec<Cell, MAX_DETAIL_CELLS>>,
    pub(super) ghosts: Box<heapless::Vec<Ghost, MAX_GHOSTS>>,
    /// The distinct tiles the cells read, with how many cells read each (one slot each).
    pub(super) keys: KeyMap,
    /// The cells' (level, quads) pairs, with how many cells take each: one instanced draw each.
    groups: heapless::Vec<((u32, u32), u32), MAX_CELL_GROUPS>,
    /// Scratch: one split's new cells (whole quarters, then the one taken).
    new: Box<Scratch>,
    /// Scratch: the same split's cut.
    cut: Box<Scratch>,
    /// Scratch: the next frame's blocks while they are matched with the last one's.
    next: Box<heapless::Vec<Cand, MAX_LOD_BLOCKS>>,
    /// Per block of the last LOD frame: its index in this one (`carry.rs`).
    remap: Box<[u16]>,
    /// Per block of the LOD frame: its index in `cands`.
    cand_of: Box<[u16]>,
    /// The bounds asked in the current view.
    memo: Memo,
    /// Scratch: the corners of the cell whose units are asked.
    grid: mask::CornerGrid,
    /// The cells' indices by block, then by index (`settle`).
    by_block: Box<heapless::Vec<u16, MAX_DETAIL_CELLS>>,
    /// Scratch: stale cells in the order they are asked again.
    order: Box<heapless::Vec<(f64, u16), MAX_DETAIL_CELLS>>,
    /// The stitched units' errors, per tile.
    etas: mask::UnitEtas,
    /// Per-instance records its cells take ([`Cell::instances`]).
    instances: usize,
    /// Views seen (a cell's bound is fresh when asked in the current one).
    view: u32,
    /// The current view's key ([`PoolBounds::key`]).
    view_key: u64,
    /// The viewport the quadtrees were refined in.
    viewport: (u32, u32),
    /// A key of everything the refinement's result depends on: the view, the clamped blocks and the
    /// budgets. While it holds, a frame takes up the refinement where the last one stopped.
    inputs: Option<u64>,
    /// The view changed this frame (the camera moves).
    moved: bool,
    /// Some ghost is in view and not frozen (`pick` looks for it).
    seen_ghosts: bool,
    /// What was left of the budgets (triangles, draws, slots, records) when a split last did not fit:
    /// frozen units are tried again once more than that is left (`carry.rs`).
    mark: Option<(u64, i64, usize, usize)>,
    /// Draw calls and triangles left of the frame's budgets.
    draws: i64,
    triangles: u64,
    /// The budget ran out with work left: the region (level, samples) the next split reads, for the
    /// source to make ready ([`crate::plan::detail::DetailFrame::wanted`]).
    pub(super) pending: Option<(u32, Rect)>,
    /// The budget ran out with splits, cover or units left (or, at a still camera, stale bounds): later
    /// frames refine further. A moving camera's refreshes of stale bounds do not count.
    pub(super) refining: bool,
    /// Bound evaluations this frame's refinement spent.
    pub(super) spent: u64,
}

impl Quadtree {
    /// Empty quadtrees for tiles of `quads` quads a side (allocated once).
    pub(super) fn new(quads: u32) -> Self {
        Self {
            cands: Box::default(),
            cells: Box::default(),
            ghosts: Box::default(),
            keys: KeyMap::new(DETAIL_CAPACITY),
            groups: heapless::Vec::new(),
            new: Box::default(),
            cut: Box::default(),
            next: Box::default(),
            remap: vec![NONE; MAX_LOD_BLOCKS].into_boxed_slice(),
            cand_of: vec![NONE; MAX_LOD_BLOCKS].into_boxed_slice(),
            memo: Memo::default(),
            grid: mask::CornerGrid::default(),
            order: Box::default(),
            by_block: Box::default(),
            etas: mask::UnitEtas::new(quads),
            instances: 0,
            view: 0,
            view_key: 0,
            viewport: (0, 0),
            inputs: None,
            moved: false,
            seen_ghosts: false,
            mark: None,
            draws: 0,
            triangles: 0,
            pending: None,
            refining: false,
            spent: 0,
        }
    }
}

/// A cell's level-0 lattice box (inclusive vertices) from its vertices `r` in level `level`'s lattice.
pub(super) fn level0_box(level: u32, r: &Rect) -> LatticeBox {
    (
        r.x0 << level,
        r.y0 << level,
        (r.x1() - 1) << level,
        (r.y1() - 1) << level,
    )
}

/// The same vertices one level finer.
pub(super) fn double(r: &Rect) -> Rect {
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
    /// A ghost come into view.
    Ghost(usize),
}

/// The frame's fixed inputs of a split.
struct Inputs<'a, 'b> {
    view: &'a DetailView<'b>,
    lod: &'a LodFrame,
    budget: &'a DetailBudget,
    quads: u32,
    slots: usize,
}

impl Quadtree {
    /// Refines the clamped blocks of `lod` for this frame (none when the pool has no slots), starting
    /// from the last frame's quadtrees (`carry.rs`), spending at most `evaluations` bound evaluations:
    /// `ring_triangles[i]` is what block i's ring draws take (0 past its end).
    #[expect(
        clippy::too_many_arguments,
        reason = "the refinement's inputs, each a different stage's output"
    )]
    pub(super) fn refine(
        &mut self,
        view: &DetailView<'_>,
        lod: &LodFrame,
        bounds: &PoolBounds<'_>,
        budget: &DetailBudget,
        (quads, slots): (u32, usize),
        ring_triangles: &[u64],
        evaluations: u64,
    ) -> Result<()> {
        let at = Inputs {
            view,
            lod,
            budget,
            quads,
            slots,
        };
        self.pending = None;
        self.memo.next_frame();
        self.etas.next_frame();
        self.carry(&at, bounds, ring_triangles)?;
        // The budget: the selector makes at most this many bound evaluations for the refinement.
        let lod = bounds.lod;
        lod.set_allowance(evaluations);
        self.refining = false;
        let grown = if slots > 0 {
            self.grow(&at, bounds)
        } else {
            Ok(())
        };
        if grown.is_ok() && slots > 0 {
            if self.pending.is_some() {
                self.refining = true;
            } else {
                self.refresh(&at, bounds);
                // A moving camera's refreshes are upkeep that never ends; a still camera's converge.
                self.refining = self.pending.is_some() && !self.moved;
            }
        }
        self.spent = evaluations - lod.allowance();
        lod.set_allowance(u64::MAX);
        grown?;
        self.settle(view.epsilon_px);
        Ok(())
    }

    /// A cell's bound in this frame's view: its own when fresh, else rescaled by its block's change of
    /// scale since it was asked (an estimate: the ranking and the met flag use it until it is asked
    /// again).
    fn now(&self, c: &Cell, value: f64) -> f64 {
        if c.view == self.view {
            return value;
        }
        let k = self.cand_of[usize::from(c.block)];
        let s = self.cands.get(usize::from(k)).map_or(c.scale, |d| d.scale);
        if c.scale > 0.0 && s.is_finite() {
            value * (s / c.scale)
        } else {
            f64::INFINITY
        }
    }

    /// What cell `c`'s bounds are held to now: epsilon where they are fresh; where they are rescaled
    /// estimates, epsilon and [`MOTION_SLACK`] (a bound just under epsilon would otherwise pass it with
    /// every step of a camera moving closer and be asked again every frame).
    fn limit(&self, c: &Cell, eps: f64) -> f64 {
        if c.view == self.view {
            eps
        } else {
            eps * (1.0 + MOTION_SLACK)
        }
    }

    /// Whether cell `c` is drawn within epsilon now: its bound (or its block's wanted level) and its coarse
    /// units', rescaled where stale ([`Quadtree::limit`]).
    fn meets(&self, c: &Cell, eps: f64) -> bool {
        let limit = self.limit(c, eps);
        (self.now(c, c.bound) <= limit || c.key.level <= c.wanted)
            && self.now(c, c.coarse_bound) <= limit
    }

    /// Sets every cell's met flag for this frame, and indexes the cells by block.
    fn settle(&mut self, eps: f64) {
        self.by_block.clear();
        for j in 0..self.cells.len() {
            let m = self.meets(&self.cells[j], eps);
            self.cells[j].met = m;
            let j = u16::try_from(j).expect("cells <= MAX_DETAIL_CELLS");
            self.by_block.push(j).expect("cells <= MAX_DETAIL_CELLS");
        }
        let cells = &self.cells;
        self.by_block
            .sort_unstable_by_key(|&j| (cells[usize::from(j)].block, j));
    }

    /// Block `block`'s cells, in the order they were made (as of the last [`Quadtree::refine`]).
    pub(super) fn cells_of(&self, block: u16) -> impl Iterator<Item = &Cell> + '_ {
        let key = |j: &u16| self.cells[usize::from(*j)].block;
        let lo = self.by_block.partition_point(|j| key(j) < block);
        let hi = self.by_block.partition_point(|j| key(j) <= block);
        self.by_block[lo..hi]
            .iter()
            .map(|&j| &self.cells[usize::from(j)])
    }

    /// Whether block `block` has a part in view not covered yet (it is not served until it has none).
    pub(super) fn uncovered(&self, block: u16) -> bool {
        self.ghosts.iter().any(|g| g.block == block && g.visible)
    }

    /// The scale of a cell's block in this frame's view.
    fn scale_of(&self, block: u16) -> f64 {
        let k = self.cand_of[usize::from(block)];
        self.cands.get(usize::from(k)).map_or(0.0, |c| c.scale)
    }

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
    fn grow(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) -> Result<()> {
        let eps = at.view.epsilon_px;
        let quads = at.quads;
        // Cells made while the camera moved whose units are still to ask, and that will not be split:
        // their units take triangles off the frame before anything else is split.
        if !self.mask_cells(0, at, bounds) {
            return Ok(());
        }
        loop {
            let Some(unit) = self.pick(eps) else {
                return Ok(());
            };
            if let Unit::Cell(j) = unit {
                if self.cells[j].view != self.view {
                    if !self.refresh_cell(j, at, bounds) {
                        self.pending = Some(self.region(unit));
                        return Ok(());
                    }
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
                self.pending = Some(self.region(unit));
                return Ok(());
            }
            let Some((_, is_cut, cost)) = best else {
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
                self.pending = Some(self.region(unit));
                return Ok(());
            }
            let first = self.cells.len() - usize::from(matches!(unit, Unit::Cell(_)));
            self.commit(unit, cost);
            if matches!(unit, Unit::Ghost(_)) {
                self.seen_ghosts = self.ghosts.iter().any(|g| g.visible && !g.frozen);
            }
            if !self.mask_cells(first, at, bounds) {
                return Ok(());
            }
        }
    }

    /// [`Quadtree::mask_cell`] of cells `first..`, in order; false (the region noted) when the budget ran
    /// out.
    fn mask_cells(&mut self, first: usize, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) -> bool {
        for j in first..self.cells.len() {
            if !self.mask_cell(j, at, bounds) {
                self.pending = Some(self.region(Unit::Cell(j)));
                return false;
            }
        }
        true
    }

    /// What is left of the budgets: triangles, draws, slots and records.
    fn free(&self, at: &Inputs<'_, '_>) -> (u64, i64, usize, usize) {
        (
            self.triangles,
            self.draws,
            at.slots.saturating_sub(self.keys.len()),
            at.budget.instances.saturating_sub(self.instances),
        )
    }

    /// Asks the coarse units of cell `j` if it has not had them asked and will not be split (it meets
    /// epsilon, or its split does not fit); false when the budget ran out first (nothing changed). Units
    /// that do not fit the records or triangles left are not taken (the cell stays whole).
    fn mask_cell(
        &mut self,
        j: usize,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
    ) -> bool {
        let c = self.cells[j];
        let eps = at.view.epsilon_px;
        if c.masked || !(c.bound <= eps || c.key.level <= c.wanted || c.frozen) {
            return true;
        }
        let mut ask = Asker {
            memo: &mut self.memo,
            bounds,
            grid: &mut self.grid,
            etas: &mut self.etas,
        };
        let Some((m, worst)) = mask::coarse_units(at.view, &mut ask, c.key.level, &c.bounds, eps)
        else {
            return false;
        };
        let stitched = Cell {
            coarse: m,
            coarse_bound: worst,
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

    /// The unit the refinement splits next: a ghost come into view, else the largest bound still
    /// splittable (blocks first, then cells; first on ties). None when nothing is left.
    fn pick(&self, eps: f64) -> Option<Unit> {
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
        for (j, c) in self.cells.iter().enumerate() {
            if c.frozen || c.hidden || c.key.level <= c.wanted {
                continue;
            }
            let b = self.now(c, c.bound);
            if b > self.limit(c, eps) && pick.is_none_or(|(p, _)| b > p) {
                pick = Some((b, Unit::Cell(j)));
            }
        }
        pick.map(|(_, u)| u)
    }

    /// The region (level, samples) a split of `unit` reads: what the source is asked to make ready
    /// while the budget waits for the next frame.
    fn region(&self, unit: Unit) -> (u32, Rect) {
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
    fn split(
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
            eager: !self.moved,
        };
        Ok(match unit {
            Unit::Block(k) => split_block(new, at.view, &mut ask, at.lod, &self.cands[k], shape)?,
            Unit::Cell(j) => split_cell(new, at.view, &mut ask, &self.cells[j], shape),
            Unit::Ghost(g) => resolve_ghost(new, at.view, &mut ask, &self.ghosts[g], shape),
        })
    }

    /// What the split in `new` adds: (draws, triangles, triangles it frees), None when it has no cells
    /// or its tiles, cells, records or ghosts do not fit.
    fn cost(
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
    fn commit(&mut self, unit: Unit, (add_d, add_t, sub_t): (i64, u64, u64)) {
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

    /// Asks stale cells' bounds and units again in this view, largest (rescaled) bound first, while the
    /// budget lasts: while the camera moves, those whose rescaled bound is within [`AT_RISK`] of epsilon
    /// (the others are kept as they are); at a still camera every one, which it converges with. A cell
    /// whose new units do not fit what is left keeps its old ones and is frozen (not met).
    fn refresh(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) {
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
            if !self.refresh_cell(j, at, bounds) {
                self.pending = Some(self.region(Unit::Cell(j)));
                break;
            }
        }
    }

    /// Asks cell `j`'s bound and coarse units again in this view; false when the budget ran out first
    /// (nothing changed).
    fn refresh_cell(
        &mut self,
        j: usize,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
    ) -> bool {
        let c = self.cells[j];
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
        if at.budget.stitch {
            let units = mask::coarse_units(at.view, &mut ask, c.key.level, &c.bounds, at.view.epsilon_px);
            let Some((m, worst)) = units else {
                return false;
            };
            (fresh.coarse, fresh.coarse_bound, fresh.masked) = (m, worst, true);
        }
        let (old_t, new_t) = (c.triangles(at.budget), fresh.triangles(at.budget));
        let records = self.instances - c.instances() + fresh.instances();
        if new_t > self.triangles + old_t || records > at.budget.instances {
            self.cells[j].frozen = true;
            return true;
        }
        self.triangles = self.triangles + old_t - new_t;
        self.instances = records;
        self.cells[j] = fresh;
        true
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
fn unseen<K: PartialEq>(new: &[Cell], key: impl Fn(&Cell) -> K, counts: &[(K, u32)]) -> usize {
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
