//! Stage 2, the per-frame plan: the detail pool's refinement. Which cells a clamped block is drawn with: a
//! quadtree over space and level, split minimax-first under the pool's slots and the frame's draws and
//! triangles, and under a fixed number of bound evaluations a frame (`budget.refine_bounds_per_frame`).
//! The quadtree carries over from frame to frame (`carry.rs`): a frame starts from the last one's,
//! re-tests what changed screen scale, covers what came into view, and spends what is left of its budget
//! where the error is largest (docs/plan-time.md). Pure, deterministic and allocation-free.

use crate::plan::detail::keymap::KeyMap;
use crate::plan::detail::{
    stitch, DetailBudget, DetailView, PoolBounds, TileKey, DETAIL_CAPACITY,
};
use crate::plan::camera::{BoxScale, Corner};
use crate::plan::frame::Rect;
use crate::plan::lod::{BoundView, LatticeBox, LodFrame, LodMode, KEEP_BAND, MAX_LOD_BLOCKS};
use crate::Result;

mod carry;
mod check;
mod grow;
mod corners;
mod mask;
mod memo;
mod ranks;
mod split;
mod upkeep;

use memo::Memo;

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
    /// The same box's scale whole: what proves its cells' bounds first ([`Quadtree::prove`]).
    whole: Option<BoxScale>,
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
    /// Its coarse units marked because they were out of view `view`: their coarser bound was never
    /// asked, so `coarse_bound` says nothing of them. A later view in which they may be visible draws
    /// them fine until the cell's units are asked again (`carry.rs`).
    unseen: stitch::Mask,
    /// Its units were asked, or it is not drawn stitched (a cell made while the camera moves is drawn
    /// whole until they are: `Quadtree::mask_cell`).
    masked: bool,
    /// The view its bound and units were asked in ([`Quadtree`]'s count of views).
    view: u32,
    /// Its block's scale then ([`Cand::scale`]).
    scale: f64,
    /// Per quarter of it ([`quarters`]): its level's object-space error there ([`object_error`]), metres:
    /// at least every data sample's, in any view.
    cap: [f64; 4],
    /// Per quarter: the largest object-space error its coarse units in view there were drawn on
    /// ([`mask::Units::cap`]).
    coarse_cap: [f64; 4],
    /// Where its bounds are stale: this view's bounds of its own level and of its coarse units, from
    /// `cap` and `coarse_cap` ([`Quadtree::prove`]; 0 where they do not count).
    proof: (f64, f64),
    /// Drawn within epsilon (or at its block's wanted level) in this frame's view: by its bounds where
    /// they are fresh, else by its proven ones (`proof`).
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

    /// The fewest triangles it can draw: every unit coarse where it can be stitched, else whole.
    pub(super) fn fewest_triangles(&self, budget: &DetailBudget) -> u64 {
        let r = &self.bounds;
        let even = r.x0 % 2 == 0 && r.y0 % 2 == 0 && r.w % 2 == 1 && r.h % 2 == 1;
        if budget.stitch && even {
            let (ua, ub) = stitch::units(r);
            let all: stitch::Mask = [u32::MAX; stitch::MAX_UNITS as usize];
            stitch::triangles(&all, ua, ub).min(budget.cell_triangles(r))
        } else {
            budget.cell_triangles(r)
        }
    }

    /// Whether its units are still to ask and it will not be split (it meets epsilon, is at its block's
    /// wanted level or is frozen): drawn whole until they are.
    pub(super) fn waits_for_units(&self, eps: f64) -> bool {
        !self.masked && (self.bound <= eps || self.key.level <= self.wanted || self.frozen)
    }

    /// The same cell with its units `u` asked ([`mask::coarse_units`]).
    fn with_units(self, u: &mask::Units) -> Self {
        Self {
            coarse: u.coarse,
            coarse_bound: u.worst,
            unseen: u.unseen,
            coarse_cap: u.cap,
            masked: true,
            ..self
        }
    }

    /// Its bounds of its own level (0 at its block's wanted level: no cell goes finer) and of its coarse
    /// units over its quarters `q` (a set of them, bits 0..4) from their object-space caps and a scale `s`
    /// of a box holding them: bounds in `s`'s view.
    fn proven(&self, s: &BoxScale, q: usize) -> (f64, f64) {
        let px = |e: f64| {
            if e == 0.0 {
                0.0
            } else if e.is_finite() {
                s.px(e)
            } else {
                f64::INFINITY
            }
        };
        let most = |caps: &[f64; 4]| (0..4).filter(|i| q >> i & 1 == 1).fold(0.0f64, |m, i| m.max(caps[i]));
        let own = if self.key.level > self.wanted {
            px(most(&self.cap))
        } else {
            0.0
        };
        let coarse = if stitch::any(&self.coarse) {
            px(most(&self.coarse_cap))
        } else {
            0.0
        };
        (own, coarse)
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
    /// While the refinement grows: each cell's rank ([`Quadtree::rank`]), in step with `cells`, so
    /// that picking the next split reads one number a run of cells and the cells of one run.
    ranks: Box<ranks::Ranks>,
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
    grid: corners::CornerGrid,
    /// The cells' indices by block, then by index (`settle`).
    by_block: Box<heapless::Vec<u16, MAX_DETAIL_CELLS>>,
    /// Scratch: stale cells in the order they are asked again.
    order: Box<heapless::Vec<(f64, u16), MAX_DETAIL_CELLS>>,
    /// The stitched units' errors, per tile.
    etas: corners::UnitEtas,
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
    /// The view of the last frame, when the camera moved in it and the budget stopped its refinement with
    /// work left (a split, a cover or units): the next frame, if the camera moved again, refines in it
    /// first ([`Lag`]).
    lag: Option<Lag>,
    /// This frame refines in the last frame's view ([`Quadtree::lag`]), then moves to its own.
    lagging: bool,
    /// Splits this frame's refinement took.
    taken: u32,
    /// The budget stopped this frame's refinement within a split (its bounds asked in part).
    mid_split: bool,
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
            ranks: Box::default(),
            ghosts: Box::default(),
            keys: KeyMap::new(DETAIL_CAPACITY),
            groups: heapless::Vec::new(),
            new: Box::default(),
            cut: Box::default(),
            next: Box::default(),
            remap: vec![NONE; MAX_LOD_BLOCKS].into_boxed_slice(),
            cand_of: vec![NONE; MAX_LOD_BLOCKS].into_boxed_slice(),
            memo: Memo::default(),
            grid: corners::CornerGrid::default(),
            order: Box::default(),
            by_block: Box::default(),
            etas: corners::UnitEtas::new(quads),
            instances: 0,
            view: 0,
            view_key: 0,
            viewport: (0, 0),
            inputs: None,
            moved: false,
            lag: None,
            lagging: false,
            taken: 0,
            mid_split: false,
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

/// A cell's quarters, whose caps it keeps ([`Cell::cap`]): its vertices `r` (of `level`) cut in halves
/// on each axis at the even vertex that leaves every stitched unit (2 x 2 quads from the corner) wholly
/// in one half, as level-0 lattice boxes, x half first then y half ((0, 0), (1, 0), (0, 1), (1, 1)). A
/// side of fewer than two units is not cut: both its halves are the whole side.
pub(super) fn quarters(level: u32, r: &Rect) -> [LatticeBox; 4] {
    let (ua, ub) = stitch::units(r);
    let halves = |lo: i64, hi: i64, units: u32| {
        let mid = lo + 2 * i64::from(units / 2);
        if units < 2 {
            [(lo, hi), (lo, hi)]
        } else {
            [(lo, mid), (mid, hi)]
        }
    };
    let (xs, ys) = (halves(r.x0, r.x1() - 1, ua), halves(r.y0, r.y1() - 1, ub));
    let mut out = [(0, 0, 0, 0); 4];
    for (i, o) in out.iter_mut().enumerate() {
        let ((x0, x1), (y0, y1)) = (xs[i & 1], ys[i >> 1]);
        *o = (x0 << level, y0 << level, x1 << level, y1 << level);
    }
    out
}

/// The scales of cell `c`'s quarters ([`quarters`]) in the view of `bounds`, each
/// [`crate::plan::lod::Lod::box_scale`] bit for bit, from the 3 x 3 lattice points they share, each
/// projected once (18 corners instead of 32).
fn quarter_scales(bounds: &PoolBounds<'_>, c: &Cell) -> [BoxScale; 4] {
    let (lod, v) = (bounds.lod, &bounds.view);
    let boxes = quarters(c.key.level, &c.bounds);
    let mut seen = [((i64::MIN, i64::MIN), [Corner::default(); 2]); 9];
    let mut n = 0;
    core::array::from_fn(|q| {
        let (a, y0, b, y1) = boxes[q];
        let mut k = [Corner::default(); 8];
        for (i, p) in [(a, y0), (b, y0), (a, y1), (b, y1)].into_iter().enumerate() {
            let at = match seen[..n].iter().find(|s| s.0 == p) {
                Some(s) => s.1,
                None => {
                    let at = [lod.corner(v, p.0, p.1, false), lod.corner(v, p.0, p.1, true)];
                    // At most 3 x 3 points: the halves share their cut.
                    seen[n.min(8)] = (p, at);
                    n = (n + 1).min(9);
                    at
                }
            };
            (k[i], k[i + 4]) = (at[0], at[1]);
        }
        lod.scale_of_corners(v, (a, y0, b, y1), &k)
    })
}

/// An object-space error (metres) of `level` over `bx` that bounds every data sample's there, in any
/// view: what a cell keeps per quarter to prove its bound in later views ([`Cell::cap`]). The
/// conservative and exact modes' own error over the box is such a bound (a p-sum of the samples' errors
/// is at least their largest); the estimate of `Sat` is not, and takes the max pyramid's cap, at least
/// every estimate inside the box ([`crate::plan::lod::Lod::eta_cap`]). Infinite where no table holds
/// the level.
pub(super) fn object_error(bounds: &PoolBounds<'_>, level: u32, bx: LatticeBox) -> f64 {
    let e = match bounds.mode {
        LodMode::SatConservative | LodMode::Exact => bounds.lod.eta_of(bounds.mode, level, bx),
        LodMode::Sat | LodMode::Distance => bounds.lod.eta_cap(bounds.mode, level, bx),
    };
    e.unwrap_or(f64::INFINITY)
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Unit {
    /// A clamped block (drawn from its ring).
    Block(usize),
    /// A cell.
    Cell(usize),
    /// A ghost come into view.
    Ghost(usize),
}

/// A view a frame's refinement may take up again in the next frame ([`Quadtree::lag`]). While the camera
/// moves, every frame is a new view, and the bounds asked in one are kept only while it lasts ([`Memo`]):
/// a split the budget stopped started again from nothing in the next view, so a split costing more than
/// the budget never ended, and a frame's last split was asked for nothing. Counted in a flight (Puget
/// Sound at 1 px, gles3-mid, teleport legs), 82 of 240 frames spent their whole budget that way without
/// taking one split. Now the next frame first goes on in the last one's view, where the bounds it asked
/// are kept, and then moves to its own: the cells it made are that view's, rescaled to this one as every
/// stale cell is. A frame that lagged lags the next only when the budget stopped it within a split and it
/// took none (a split costing more than a frame's budget goes on, over as many frames as it needs, up to
/// [`MAX_LAG`]); otherwise the next frame is its own view, so the refinement's view is one frame old every
/// other frame while it has work left. Only a view [`near`] this frame's is taken up: never across a jump.
#[derive(Clone, Copy, Debug)]
struct Lag {
    view: BoundView,
    key: u64,
    /// The refinement's count of views and the memo's generation then.
    id: u32,
    generation: u32,
    /// Frames since it was this frame's view.
    age: u32,
    /// What the view's key also holds, checked apart: a view of another epsilon or viewport is never
    /// taken up. (The SAT mode is the planner's, fixed.)
    eps: f64,
    viewport: (u32, u32),
}

/// The most frames a refinement's view lags the camera by ([`Lag`]): past it a split still unfinished is
/// asked again from nothing in the frame's own view. The teleport goal's 30 frames.
const MAX_LAG: u32 = 30;

/// Whether the view of `then` is near enough to `now`'s for bounds asked in it to stand for this frame's
/// by their first-order rescaling: every clamped block of `lod` (the refinement's candidates) has a scale
/// within [`KEEP_BAND`] of its scale now, the band in which the selection keeps a moving block's level.
/// A jump is not: after a teleport, cells made in the last view and rescaled to this one were drawn as
/// meeting epsilon at 1.57 px (Puget Sound at 1 px, third leg).
fn near(then: &PoolBounds<'_>, now: &PoolBounds<'_>, lod: &LodFrame) -> bool {
    lod.blocks
        .iter()
        .filter(|b| b.wanted < b.level && b.wanted < b.ring)
        .all(|b| {
            let bx = level0_box(b.ring, &b.rect);
            let k = then.scale(bx) / now.scale(bx);
            (1.0 / KEEP_BAND..=KEEP_BAND).contains(&k)
        })
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
        // The last frame's view, where it stopped with work left, when the camera has moved since.
        let lag = self.lag.take().filter(|l| {
            l.key != bounds.key
                && l.eps.to_bits() == bounds.eps.to_bits()
                && l.viewport == bounds.lod.viewport()
        });
        let own = bounds;
        let frozen = lag
            .map(|l| PoolBounds {
                view: l.view,
                key: l.key,
                ..*own
            })
            .filter(|f| near(f, own, lod));
        let lagged = lag.filter(|_| frozen.is_some());
        self.lagging = lagged.is_some();
        if let Some(l) = lagged {
            // Back in that view (after a lagging frame's catch-up, which asked nothing in its own).
            self.view = l.id;
            self.view_key = l.key;
            self.memo.resume(l.generation);
        }
        (self.taken, self.mid_split) = (0, false);
        let bounds = frozen.as_ref().unwrap_or(own);
        self.carry(&at, bounds, own.key, ring_triangles)?;
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
        // The next frame goes on in this view, or, where this frame lagged and took no split, in the same
        // earlier view.
        let next = match lagged {
            Some(l) if self.taken == 0 && self.mid_split && l.age < MAX_LAG => Some(Lag {
                age: l.age + 1,
                ..l
            }),
            Some(_) => None,
            None => Some(Lag {
                view: own.view,
                key: own.key,
                id: self.view,
                generation: self.memo.generation(),
                age: 1,
                eps: own.eps,
                viewport: own.lod.viewport(),
            }),
        };
        self.lag = next.filter(|_| self.moved && self.refining);
        if self.lagging {
            self.catch_up(&at, own);
        }
        self.settle(view.epsilon_px);
        self.debug_check_cover();
        Ok(())
    }

    /// A cell's bound in this frame's view: its own when fresh, else rescaled by its block's change of
    /// scale since it was asked. An estimate, not a bound (the sub-box that decides a cell's bound can
    /// change scale faster than its block): it ranks stale cells, and never says one meets epsilon
    /// ([`Quadtree::prove`] does).
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

    /// Proves the stale cells' bounds in this view (`bounds`'s), each [`Cell::proof`]: its quarters'
    /// errors projected with its block's box scale (kept for the frame, one product a cell) or, where that
    /// misses epsilon, each with its quarter's own box scale (four box scales). Each quarter's error bounds
    /// every data sample's there ([`object_error`]) and a box inside another has a smaller scale, so both
    /// are bounds of what the cell draws in this view. What this does not prove is asked again
    /// (`upkeep.rs`) or reported (`unmet_px`).
    pub(super) fn prove(&mut self, bounds: &PoolBounds<'_>, eps: f64) {
        for j in 0..self.cells.len() {
            if self.cells[j].view != self.view {
                let p = self.proof_of(&self.cells[j], bounds, eps);
                self.cells[j].proof = p;
            }
        }
    }

    /// [`Quadtree::prove`] of cell `c`.
    pub(super) fn proof_of(&self, c: &Cell, bounds: &PoolBounds<'_>, eps: f64) -> (f64, f64) {
        let k = self.cand_of[usize::from(c.block)];
        let whole = self.cands.get(usize::from(k)).and_then(|d| d.whole);
        let p = whole.map_or((f64::INFINITY, f64::INFINITY), |s| c.proven(&s, 0b1111));
        if p.0.max(p.1) <= eps {
            return p;
        }
        let mut q = (0.0f64, 0.0f64);
        for (i, s) in quarter_scales(bounds, c).iter().enumerate() {
            let r = c.proven(s, 1 << i);
            q = (q.0.max(r.0), q.1.max(r.1));
        }
        (p.0.min(q.0), p.1.min(q.1))
    }

    /// Whether cell `c` is drawn within epsilon now: its bound (or its block's wanted level) and its coarse
    /// units' where they are fresh, else its proven ones ([`Quadtree::prove`]).
    fn meets(&self, c: &Cell, eps: f64) -> bool {
        if c.view == self.view {
            (c.bound <= eps || c.key.level <= c.wanted) && c.coarse_bound <= eps
        } else {
            c.proof.0 <= eps && c.proof.1 <= eps
        }
    }

    /// What cell `c` misses epsilon by in this frame's view: 0 when it is drawn within epsilon (its met
    /// flag), else the largest of its bound and its coarse units' bound, proven ones where stale (the
    /// bound of its wanted level does not count: no cell goes finer). Infinite where no bound is held.
    pub(super) fn unmet_px(&self, c: &Cell) -> f64 {
        if c.met {
            return 0.0;
        }
        let b = if c.view == self.view {
            let own = if c.key.level > c.wanted { c.bound } else { 0.0 };
            own.max(c.coarse_bound)
        } else {
            c.proof.0.max(c.proof.1)
        };
        if b > 0.0 {
            b
        } else {
            f64::INFINITY
        }
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
}
