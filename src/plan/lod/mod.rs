//! Stage 2, the per-frame plan: allocation-free block LOD selection (docs/design.md "SAT LOD", after Li et al.
//! 2021, "SAT paper", algorithm 1) over the tables [`crate::bake::lod_tables`] bakes.
//!
//! # Blocks
//!
//! The LOD block of ring l is a cell of a fixed world grid: m x m quads of level l (m = `profile.block_m()`),
//! cell (c, r) covering level-l vertices [c m, (c + 1) m] x [r m, (r + 1) m], i.e. level-0 lattice
//! multiples of m 2^l, so coarser levels up to l + log2 m have samples on its corners. Each frame, ring l
//! contributes the cells that meet its active region (clipped to it) and are not wholly inside the finer
//! ring's active region (the hole). The renderer draws each block at its chosen level, covering the clipped
//! cell; skirts hide the cracks (docs/design.md "SAT LOD" 7). A full ring of n = 4m - 1 vertices meets at most
//! 6 x 6 cells, so a frame has at most 36 L blocks, and selection is O(blocks x levels).

/// Defined beside the tables whose estimators it chooses.
pub use crate::bake::lod_tables::LodMode;
use crate::bake::lod_tables::{ceil_shr, LodTables};
use crate::plan::camera::{BoxScale, Camera};
use crate::plan::frame::{Frame, Rect, MAX_LEVELS};
use crate::{Error, Result};

mod bound;
mod cache;
pub use bound::{BoundView, LatticeBox};
use bound::Split;
use cache::{EtaCache, SelectCache, Selected};

/// Capacity of a frame's block list; the profile's `max_draws` is the limit actually enforced.
pub const MAX_LOD_BLOCKS: usize = 4096;

/// One block of a frame and the level it is drawn at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockLod {
    /// The ring whose render region the block belongs to.
    pub ring: u32,
    /// The block's vertices in ring `ring`'s lattice (a cell of the fixed grid, clipped to the active region).
    pub rect: Rect,
    /// The level it is drawn at.
    pub level: u32,
    /// The level the error bound asked for, before clamping to the held data.
    pub wanted: u32,
    /// The object-space error of `level` over the block under the frame's mode, metres.
    pub eta_m: f32,
    /// The screen-space bound of `level`, pixels.
    pub bound_px: f32,
}

/// The LOD part of a frame: blocks and the levels they are drawn at. Fixed-capacity: allocation-free.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LodFrame {
    /// Blocks, ring by ring (finest first), row-major cells within a ring.
    pub blocks: heapless::Vec<BlockLod, MAX_LOD_BLOCKS>,
    /// Blocks whose wanted level is finer than any level whose held data covers them: the error the memory
    /// budget cannot pay for.
    pub blocks_clamped: u32,
    /// Blocks drawn coarser than their own ring.
    pub blocks_coarser: u32,
    /// Blocks drawn finer than their own ring.
    pub blocks_finer: u32,
}

impl LodFrame {
    /// A frame with no blocks (boxed: the block list is large).
    pub fn new_boxed() -> Box<Self> {
        Box::default()
    }

    /// The block-to-level part of the frame hash (for the frame record).
    pub fn hash_into(&self, h: &mut crate::hash::Hash64) {
        h.write_u64(self.blocks.len() as u64);
        for b in &self.blocks {
            h.write_u32(b.ring);
            h.write_i64(b.rect.x0);
            h.write_i64(b.rect.y0);
            h.write_u32(b.rect.w);
            h.write_u32(b.rect.h);
            h.write_u32(b.level);
        }
        h.write_u32(self.blocks_clamped);
    }
}

/// The per-frame LOD selector: SAT paper algorithm 1 over the fixed block grid, with the clamp to the
/// held data. Built once; [`Lod::select`] allocates nothing. It may move to another thread (`Send`), but
/// is not shared between threads (`Sync`): its cache of object-space errors fills through `&self`.
#[derive(Clone, Debug)]
pub struct Lod {
    tables: LodTables,
    levels: u32,
    synth: u32,
    m: u32,
    g0: f64,
    /// World x of level-0 lattice column 0 (the west edge), metres.
    x_left: f64,
    /// World y of level-0 lattice row 0 (the north edge), metres.
    y_top: f64,
    z_range: (f64, f64),
    epsilon_px: f64,
    /// The viewport (width, height), pixels.
    view: (u32, u32),
    max_blocks: usize,
    /// The object-space errors asked so far, kept across frames ([`EtaCache`]).
    etas: EtaCache,
    /// Each block's last selection, by view ([`SelectCache`]).
    selected: SelectCache,
    /// The view of the last selection ([`Lod::view_key`]): the camera moves while it changes.
    last_view: std::cell::Cell<u64>,
    /// The viewport of the last selection.
    last_viewport: std::cell::Cell<(u32, u32)>,
    /// Bound evaluations so far: boxes and sub-boxes whose object-space error was read and projected
    /// (the plan's work, counted the same on every machine).
    evaluations: std::cell::Cell<u64>,
    /// How many more may be made ([`Lod::set_allowance`]; `u64::MAX`: no limit).
    allowance: std::cell::Cell<u64>,
}

// A selector can be built on one thread and planned on another (the planner's check is beside it).
const _: () = {
    const fn send<T: Send>() {}
    send::<Lod>();
};

impl Lod {
    /// A selector for a clipmap of `profile` over the terrain the tables were built from.
    ///
    /// `g0` is the level-0 spacing, `corner` the world (x, y) of lattice point (0, 0) (the north-west data
    /// sample), `z_range` the terrain's height range (the blocks' vertical extent, so the closest point is
    /// never farther than the true one).
    pub fn new(
        tables: LodTables,
        profile: &crate::profile::Profile,
        synth: u32,
        g0: f64,
        corner: (f64, f64),
        z_range: (f64, f64),
    ) -> Self {
        let (x_left, y_top) = corner;
        Self {
            tables,
            levels: profile.clipmap.levels.min(crate::profile::MAX_LEVELS),
            synth,
            m: profile.block_m(),
            g0,
            x_left,
            y_top,
            z_range,
            epsilon_px: f64::from(profile.view.epsilon_px),
            view: (profile.view.width, profile.view.height),
            max_blocks: (profile.budget.max_draws as usize).min(MAX_LOD_BLOCKS),
            etas: EtaCache::default(),
            selected: SelectCache::default(),
            last_view: std::cell::Cell::new(0),
            last_viewport: std::cell::Cell::new((0, 0)),
            evaluations: std::cell::Cell::new(0),
            allowance: std::cell::Cell::new(u64::MAX),
        }
    }

    /// A selector for `clipmap`'s geometry (its level-0 spacing, synthesised rings and terrain placement;
    /// `terrain` places the grid and may be a streamed package's coarse stand-in, whose rows line up with
    /// the data's; the height range is the clipmap's data range).
    pub fn for_clipmap(
        tables: LodTables,
        profile: &crate::profile::Profile,
        clipmap: &crate::plan::clipmap::Clipmap,
        terrain: &crate::source::Heightmap,
    ) -> Self {
        // The data's range (a streamed package's header has it; `terrain` may be a coarse stand-in).
        let (lo, hi) = clipmap.data_range();
        // Heightmap::grid_to_world: sample (0, 0) sits at origin + (0, (rows - 1) s).
        let (ox, oy) = terrain.origin();
        let y_top = oy + f64::from(terrain.height() - 1) * f64::from(terrain.spacing());
        Self::new(
            tables,
            profile,
            clipmap.synth_levels(),
            clipmap.g0(),
            (ox, y_top),
            (f64::from(lo), f64::from(hi)),
        )
    }

    /// Sets the screen-space error bound epsilon, pixels (the profile's `view.epsilon_px` until set).
    pub fn set_epsilon_px(&mut self, epsilon_px: f64) {
        self.epsilon_px = epsilon_px;
    }

    /// Sets the viewport the bound is measured in, pixels (the profile's `view` until set).
    pub fn set_view(&mut self, view: (u32, u32)) {
        self.view = view;
    }

    /// The viewport the bound is measured in, pixels.
    pub fn viewport(&self) -> (u32, u32) {
        self.view
    }

    /// The screen-space error bound epsilon, pixels.
    pub fn epsilon_px(&self) -> f64 {
        self.epsilon_px
    }

    /// Rings finer than the data (clipmap level = data level + this).
    pub fn synth_levels(&self) -> u32 {
        self.synth
    }

    /// Bound evaluations this selector has made: each box or sub-box whose object-space error a bound
    /// read and projected (a split box counts its sub-boxes read): a count of the plan's work that does
    /// not depend on the machine.
    pub fn evaluations(&self) -> u64 {
        self.evaluations.get()
    }

    /// Lets the next bounds make at most `n` evaluations ([`Lod::evaluations`]; `u64::MAX`: no limit). A
    /// bound that would make one more returns NaN (nothing kept of it): what holds the detail pool's
    /// refinement to its budget. The selection runs with no limit.
    pub fn set_allowance(&self, n: u64) {
        self.allowance.set(n);
    }

    /// Evaluations left of the allowance ([`Lod::set_allowance`]).
    pub fn allowance(&self) -> u64 {
        self.allowance.get()
    }

    /// Counts one evaluation; false (nothing counted) when the allowance is spent.
    fn charge(&self) -> bool {
        let left = self.allowance.get();
        if left == 0 {
            return false;
        }
        if left != u64::MAX {
            self.allowance.set(left - 1);
        }
        self.evaluations.set(self.evaluations.get() + 1);
        true
    }

    /// The baked tables.
    pub fn tables(&self) -> &LodTables {
        &self.tables
    }

    /// World x of level-0 lattice column `a`, metres.
    fn world_x(&self, a: i64) -> f64 {
        #[expect(
            clippy::cast_precision_loss,
            reason = "lattice coordinates below 2^48 are exact in f64"
        )]
        let a = a as f64;
        self.x_left + a * self.g0
    }

    /// World y of level-0 lattice row `c`, metres.
    fn world_y(&self, c: i64) -> f64 {
        #[expect(
            clippy::cast_precision_loss,
            reason = "lattice coordinates below 2^48 are exact in f64"
        )]
        let c = c as f64;
        self.y_top - c * self.g0
    }

    /// The screen-space bound of `level` over the level-0 lattice box [a, b] x [c, d] (inclusive vertices)
    /// seen from `camera` under `mode`: what [`Lod::select`] tests per block, asked by the detail pool of
    /// its cells. Infinite for a level past the baked ones or finer than the data.
    ///
    /// SAT paper eq. 6 over the whole box: how far the object error eta moves any visible point of the
    /// box ([`crate::plan::camera::VerticalScale::box_max`]), tightened by splitting: the box is cut
    /// on `level`'s lattice into up to [`SPLIT`] x [`SPLIT`] sub-boxes, and the
    /// largest of their own bounds is taken when smaller. Every sample lies in some sub-box, whose error
    /// bounds its error and whose scale bounds its scale, so the split is still an upper bound of every
    /// visible sample's projected error, and under `sat-conservative` the p-sum of a sub-box counts fewer
    /// samples (its N^(1/p) slack shrinks) and its scale is smaller.
    ///
    /// Design deviation (docs/design.md "SAT LOD" 5 projects a segment of +/- eta, length 2 eta, at the closest
    /// point with the on-axis scale): a sample whose drawn height is off by e <= eta moves on the screen
    /// by the projection of one segment of length e (from its true height to its drawn one), so the
    /// bound is one-sided; and the scale is the true projection's, which off the screen's axis exceeds
    /// the on-axis focal length over distance (by up to 1 / cos^2 of the angle), so the design's factor
    /// 2 was not a bound at the screen's corners while it doubled the error everywhere else.
    pub fn box_bound_px(
        &self,
        camera: &Camera,
        mode: LodMode,
        level: u32,
        bx: (i64, i64, i64, i64),
    ) -> f64 {
        self.box_bound_past(camera, mode, level, bx, f64::INFINITY)
    }

    /// [`Lod::box_bound_px`] where it exceeds `eps`, unless the deeper split of the threshold test
    /// (the selection's test at `eps`: every sub-box over `eps` is cut again on the level's lattice,
    /// down to single quads) shows the box meets `eps`; then that tighter bound (<= `eps`). What the
    /// detail pool ranks and decides its cells with: the same test the selection makes at `eps`, and the
    /// whole-split value for the ranking of the cells that miss it.
    pub fn box_bound_at_eps(
        &self,
        camera: &Camera,
        mode: LodMode,
        level: u32,
        bx: (i64, i64, i64, i64),
        eps: f64,
    ) -> f64 {
        self.bound_at_eps_in(&self.bound_view(camera), mode, level, bx, eps)
    }

    /// [`Lod::box_bound_px`] when `limit` is infinite; otherwise a value that is at most `limit` exactly
    /// when the bound is, the bound here cutting each sub-box over `limit` again, up to [`SPLIT_DEPTH`]
    /// times: the whole box's bound once it meets `limit` (no sub-box read), or the largest sub-box bound
    /// so far once that exceeds it. All the selection needs of a level it tests against epsilon, and what
    /// the detail pool asks where only meeting epsilon matters: with `limit` epsilon it is at most epsilon
    /// exactly when [`Lod::box_bound_at_eps`] is (its sub-boxes are those of the whole split, each at
    /// most as large, and it reads every one the whole split reads until one exceeds epsilon).
    pub fn box_bound_past(
        &self,
        camera: &Camera,
        mode: LodMode,
        level: u32,
        bx: (i64, i64, i64, i64),
        limit: f64,
    ) -> f64 {
        self.bound_in(&self.bound_view(camera), mode, level, bx, limit)
    }

    /// Chooses every block's level for `frame` seen from `camera` (SAT paper algorithm 1): from the coarsest
    /// level to the finest, the first whose bound is <= epsilon; then the nearest level whose clip region
    /// covers the block. A block seen in the same view as when last selected keeps that selection's
    /// bounds (a cache of each block's selection by view). Writes `out`; allocation-free. Fails with [`Error::Capacity`] past
    /// `profile.budget.max_draws` blocks.
    pub fn select(
        &self,
        frame: &Frame,
        camera: &Camera,
        mode: LodMode,
        out: &mut LodFrame,
    ) -> Result<()> {
        // Mapped tables keep the pages the queries read while they fit the profile's share
        // (`LodTables::limit_resident`, which trims them before they pass it): not trimmed every frame,
        // which made every frame fault the same pages in again (an eighth of a SAT LOD flight's plan time).
        out.blocks.clear();
        out.blocks_clamped = 0;
        out.blocks_coarser = 0;
        out.blocks_finer = 0;
        let v = self.bound_view(camera);
        let view = cache::view_key(camera, self.view, self.epsilon_px, mode);
        let levels = frame.levels.len().min(self.levels as usize);
        let m = i64::from(self.m);
        for l in 0..levels {
            let a = frame.levels[l].active;
            if a.is_empty() {
                continue;
            }
            let l32 = u32::try_from(l).expect("level < MAX_LEVELS");
            // The hole: the finer ring's active vertices, in this ring's lattice (its corners are even).
            let hole = match l.checked_sub(1).map(|f| frame.levels[f].active) {
                Some(f) if !f.is_empty() => Rect::from_bounds(
                    f.x0 >> 1,
                    f.y0 >> 1,
                    ((f.x1() - 1) >> 1) + 1,
                    ((f.y1() - 1) >> 1) + 1,
                ),
                _ => Rect::EMPTY,
            };
            let (ax1, ay1) = (a.x1() - 1, a.y1() - 1);
            // The last block's wanted level: where a block new to this ring starts its search while the
            // camera moves.
            let mut near: Option<u32> = None;
            for cy in a.y0.div_euclid(m)..=(ay1 - 1).div_euclid(m) {
                for cx in a.x0.div_euclid(m)..=(ax1 - 1).div_euclid(m) {
                    let r = Rect::from_bounds(
                        (cx * m).max(a.x0),
                        (cy * m).max(a.y0),
                        ((cx + 1) * m).min(ax1) + 1,
                        ((cy + 1) * m).min(ay1) + 1,
                    );
                    if r.w < 2 || r.h < 2 || hole.contains(&r) {
                        continue;
                    }
                    let b = self.choose(frame, &v, (view, near), mode, (l32, (cx, cy)), r);
                    near = Some(b.wanted);
                    if b.wanted < b.level {
                        out.blocks_clamped += 1;
                    }
                    if b.level > l32 {
                        out.blocks_coarser += 1;
                    } else if b.level < l32 {
                        out.blocks_finer += 1;
                    }
                    if out.blocks.len() >= self.max_blocks {
                        return Err(Error::Capacity {
                            what: "LOD blocks (profile budget.max_draws)",
                            capacity: self.max_blocks,
                        });
                    }
                    out.blocks.push(b).map_err(|_| Error::Capacity {
                        what: "LOD blocks",
                        capacity: MAX_LOD_BLOCKS,
                    })?;
                }
            }
        }
        self.last_view.set(view);
        self.last_viewport.set(self.view);
        Ok(())
    }

    /// One block: algorithm 1, then the clamp. The block's own scale and its cut on the levels' lattices
    /// are computed once for every level the descent tests (the cut is the same for the levels whose
    /// lattice lines fall on the block's quarter points).
    fn choose(
        &self,
        frame: &Frame,
        v: &BoundView,
        (view, near): (u64, Option<u32>),
        mode: LodMode,
        (ring, cell): (u32, (i64, i64)),
        r: Rect,
    ) -> BlockLod {
        // Level-0 lattice box of the block (inclusive vertices).
        let (a, c, b, d) = (
            r.x0 << ring,
            r.y0 << ring,
            (r.x1() - 1) << ring,
            (r.y1() - 1) << ring,
        );
        let bx = (a, c, b, d);
        let levels = u32::try_from(frame.levels.len()).expect("levels < MAX_LEVELS");
        let kept = self.selected.get(view, ring, cell, &r, levels);
        let mut whole: Option<BoxScale> = None;
        let eps = self.epsilon_px;
        // Moving: a block keeps its last wanted level without reading the tables while that level's
        // bound over the whole block, its error capped by the max pyramid (kept with the selection, so
        // one product in the new view: [`Lod::cap_bound_in`]'s bound), still meets epsilon, and its scale
        // has not shrunk enough to let it go coarser. Rescaling the last threshold test's value by the
        // block's change of scale instead is no bound: the sub-box that decided it can change scale
        // faster than the block (a far block while the view turns). A new viewport is not a move:
        // every block is tested in it.
        let moving = self.last_view.get() != view && self.last_viewport.get() == self.view;
        let mut cut = Split::default();
        let held = match kept {
            Some(_) => None,
            None if !moving || mode == LodMode::Distance => None,
            None => self
                .selected
                .last(ring, cell, levels)
                .filter(|e| e.rect == r)
                .and_then(|e| {
                    let now = *whole.get_or_insert_with(|| self.box_scale(v, bx));
                    let k = now.per_metre() / e.scale;
                    if !(e.scale > 0.0 && k >= 1.0 / KEEP_BAND) {
                        return None;
                    }
                    // The whole block's capped bound first (one product), then its sub-boxes' errors
                    // at their new scales (no table read).
                    let mut bound = now.px(e.cap);
                    if bound > eps || bound.is_nan() {
                        bound = bound.min(self.held_bound(v, e.wanted, bx, &e.subs, &mut cut));
                    }
                    (bound <= eps).then_some((e, bound))
                }),
        };
        let mut scale_of = |lod: &Self| *whole.get_or_insert_with(|| lod.box_scale(v, bx));
        // The threshold test of one level, and the value of the last one that met epsilon.
        let mut met_at: Option<(u32, f64)> = None;
        // The sub-boxes' errors the last test that met epsilon read (kept with the selection).
        let mut met_subs: SubErrors = [f64::INFINITY; SPLIT * SPLIT];
        let mut test = |lod: &Self, level: u32| -> bool {
            let s = scale_of(lod);
            let t = lod.bound_deep(v, mode, level, bx, eps, SPLIT_DEPTH, Some(s), Some(&mut cut));
            if t <= eps {
                met_at = Some((level, t));
                met_subs = cut.etas;
            }
            t <= eps
        };
        let top = levels.max(self.synth + 1);
        let wanted = match (kept, held) {
            (Some(e), _) | (None, Some((e, _))) => e.wanted,
            (None, None) if mode == LodMode::Distance => ring,
            (None, None) => match self
                .selected
                .last(ring, cell, levels)
                .map(|e| e.wanted)
                .or(near.filter(|_| moving && self.last_view.get() != 0))
            {
                // Seen in another view (or, new while the camera moves, beside a block just selected):
                // the search starts at that wanted level and ends at the coarsest level of the run of
                // levels meeting epsilon it finds there. That is algorithm 1's level wherever the bound
                // grows with the level, and never a coarser one: a level it takes meets epsilon, and the
                // first from the coarsest that does is at least as coarse.
                Some(w) => {
                    let w = w.clamp(self.synth, top - 1);
                    if test(self, w) {
                        (w + 1..top).take_while(|&l| test(self, l)).last().unwrap_or(w)
                    } else {
                        (self.synth..w).rev().find(|&l| test(self, l)).unwrap_or(self.synth)
                    }
                }
                // Algorithm 1: from the coarsest level, the first that meets epsilon.
                None => (self.synth..levels)
                    .rev()
                    .find(|&l| test(self, l))
                    .unwrap_or(self.synth),
            },
        };
        let covers = |level: u32| -> bool {
            let lf = &frame.levels[level as usize];
            let box_l = Rect::from_bounds(
                a >> level,
                c >> level,
                ceil_shr(b, level) + 1,
                ceil_shr(d, level) + 1,
            );
            !lf.clip.is_empty() && lf.clip.contains(&box_l)
        };
        let level = if covers(wanted) {
            wanted
        } else {
            ((wanted + 1)..levels)
                .find(|&l| covers(l))
                .or_else(|| (0..wanted).rev().find(|&l| covers(l)))
                .unwrap_or(ring)
        };
        let (eta, bound) = match (kept, met_at) {
            _ if mode == LodMode::Distance => (0.0, 0.0),
            (Some(e), _) if e.level == level => (e.eta, e.bound),
            // Held: the whole block's capped bound at the level it wanted and is drawn at.
            (None, _) if held.is_some_and(|(e, _)| e.level == level && e.wanted == level) => {
                let (e, bound) = held.expect("checked");
                (e.eta, bound)
            }
            // Drawn at the level the search took: its threshold test's value is a bound (<= epsilon).
            (_, Some((l, t))) if l == level => (self.eta(mode, level, bx).unwrap_or(f64::INFINITY), t),
            _ => {
                // Past the baked levels: unknown error, never chosen by the bound.
                let eta = self.eta(mode, level, bx).unwrap_or(f64::INFINITY);
                let s = scale_of(self);
                let bound = self.bound_deep(v, mode, level, bx, f64::INFINITY, SPLIT_DEPTH, Some(s), Some(&mut cut));
                (eta, bound)
            }
        };
        if mode != LodMode::Distance && held.is_none() {
            let (scale, cap, subs) = match kept {
                Some(e) => (e.scale, e.cap, e.subs),
                None => {
                    let cap = self.eta_cap(mode, wanted, bx).unwrap_or(f64::INFINITY);
                    let subs = match met_at {
                        Some((l, _)) if l == wanted => met_subs.map(|e| e.min(cap)),
                        _ => [cap; SPLIT * SPLIT],
                    };
                    (scale_of(self).per_metre(), cap, subs)
                }
            };
            self.selected.put(Selected {
                cap,
                view,
                ring,
                cell,
                rect: r,
                levels,
                wanted,
                level,
                eta,
                bound,
                scale,
                subs,
            });
        }
        #[expect(clippy::cast_possible_truncation, reason = "reported in f32")]
        BlockLod {
            ring,
            rect: r,
            level,
            wanted,
            eta_m: eta as f32,
            bound_px: bound as f32,
        }
    }
}

/// While the camera moves, a block keeps its last level as long as its scale has not shrunk by more than
/// this factor (it could then take a coarser one) nor grown enough to take its last bound at that level
/// past epsilon (docs/plan-time.md): only the blocks whose screen scale changed that much are tested
/// again. A still camera tests every block kept that way again in its next frame.
pub const KEEP_BAND: f64 = 1.125;

/// Sub-boxes per side [`Lod::box_bound_px`] splits a box into (on the tested level's lattice).
pub const SPLIT: usize = 4;

/// Upper bounds of a level's object-space error over each sub-box of a block's cut, in the cut's order:
/// view-independent, so a later view bounds the block at that level from them and the sub-boxes' new
/// scales alone (`Lod::held_bound`).
type SubErrors = [f64; SPLIT * SPLIT];

/// How many more times the threshold test (the selection's, at epsilon) cuts a sub-box whose bound
/// exceeds epsilon into [`SPLIT`] x [`SPLIT`] parts: 4 x 4, then 16 x 16 and 64 x 64 where needed (a
/// block of 32 quads reaches single quads). A box decided by its whole bound or by one sub-box past the
/// limit reads no more; the cost is in the boxes near epsilon, which the deeper cut is for (the
/// detail pool at 4 x 4 alone the pool refined tiles that the measured error did not need, and ran out of slots).
pub const SPLIT_DEPTH: u32 = 2;

/// A sub-box is cut again only when its bound is within this factor of the limit: one further past it
/// is not expected to meet it, and its test then stops at once. (Puget Sound at 2 px, gles3-mid: the
/// cells the pool refined that the measured error did not need had 4 x 4 bounds mostly 3-10 % over the
/// measured maximum at the coarser level. Cutting every sub-box again, SPLIT 16, cost 6.5x the plan
/// time of a 610-frame fly; this ratio, 1.45x.)
pub const DEEP_RATIO: f64 = 1.5;

/// The most blocks one frame of `profile` can have: at most 6 x 6 cells meet a ring's active region.
pub fn max_blocks_per_frame(profile: &crate::profile::Profile) -> usize {
    36 * (profile.clipmap.levels as usize).min(MAX_LEVELS)
}
