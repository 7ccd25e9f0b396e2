//! Stage 2, the per-frame plan: the detail pool (docs/design.md "SAT LOD" 6). The rings hold data by
//! distance, SAT LOD wants it by error: a block whose wanted level is finer than any ring holding it is
//! clamped. The pool is a fixed set of height tiles (`budget.detail_tiles`, packed into GPU array layers
//! by [`DetailAtlas`]), one tile per cell of a level's fixed grid (`detail_tile_quads` quads a side, plus
//! a one-sample border for normals). Each frame [`DetailPool::plan`] refines the clamped blocks as
//! quadtrees of such cells and quarter cells, largest bound first, under the slots, draw calls and
//! triangles (`refine.rs`; the cells of one level and size are one instanced call); fills their tiles
//! most-needed first with what is left of the per-frame sample budget after the rings (coarse-to-fine
//! ring fill stays first), evicts the least recently needed tile, and serves a block from the pool once all
//! its tiles are resident. Pure, deterministic and allocation-free.
//!
//! Tiles come through [`DetailSource`], the same heights the ring fill writes ([`Clipmap::sample`]): the
//! resident pyramid, or a streamed package's tile cache. A tile whose source samples are not resident
//! waits (the plan never blocks): [`DetailFrame::wanted`] lists them, most needed first, and the caller
//! hands them to [`Clipmap::request_samples`], whose next update decodes them after the rings under the
//! same per-frame sample budget.

use glam::DVec3;

use crate::hash::Hash64;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, Draw, DrawKind, DrawList, Frustum};
use crate::plan::frame::{Frame, Rect};
use crate::plan::lod::{BlockLod, BoundView, LatticeBox, Lod, LodFrame, LodMode, MAX_LOD_BLOCKS};
use crate::plan::mesh;

pub mod keymap;
mod refine;
pub mod stitch;
use crate::profile::{DetailAtlas, MAX_DETAIL_TILES};
use crate::{Error, Result};
use crate::profile::Profile;
use refine::Quadtree;
pub use refine::MAX_DETAIL_CELLS;

/// Capacity of the pool's fixed collections; the profile's `budget.detail_tiles` is the limit enforced.
pub const DETAIL_CAPACITY: usize = MAX_DETAIL_TILES as usize;

/// How the pool asks the frame's bounds: the SAT LOD selector's, in the frame's view.
#[derive(Clone, Copy, Debug)]
pub struct PoolBounds<'a> {
    /// The selector (its tables and its count of evaluations).
    pub lod: &'a Lod,
    /// The frame's view ([`Lod::bound_view`]).
    pub view: BoundView,
    /// A key of the view, bit for bit ([`Lod::view_key`]): the same key, the same bounds.
    pub key: u64,
    /// The SAT mode.
    pub mode: LodMode,
    /// The screen-space error bound, pixels.
    pub eps: f64,
}

impl PoolBounds<'_> {
    /// `level`'s screen-space bound over `bx` as a threshold test at epsilon: a value at most epsilon
    /// exactly when the bound is ([`Lod::bound_in`]; NaN where the refinement's budget ran out).
    pub fn meets(&self, level: u32, bx: LatticeBox) -> f64 {
        self.lod.bound_in(&self.view, self.mode, level, bx, self.eps)
    }

    /// How many pixels a metre of error moves a point of `bx` at most, to first order: what a stale
    /// bound is rescaled by.
    pub fn scale(&self, bx: LatticeBox) -> f64 {
        self.box_scale(bx).per_metre()
    }

    /// The scale of `bx` in this view ([`Lod::box_scale`]): its product with an object-space error over
    /// the box bounds that error's pixels.
    pub fn box_scale(&self, bx: LatticeBox) -> crate::plan::camera::BoxScale {
        self.lod.box_scale(&self.view, bx)
    }
}

/// One pool tile: cell (cx, cy) of level `level`'s grid of `detail_tile_quads`-quad cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileKey {
    /// The level (its lattice and spacing), at least the data level.
    pub level: u32,
    /// Cell column: vertices cx q ..= (cx + 1) q of the level's lattice.
    pub cx: i64,
    /// Cell row.
    pub cy: i64,
}

impl TileKey {
    /// The level lattice point of the tile's first held sample (the border's corner).
    pub fn first_sample(&self, quads: u32) -> (i64, i64) {
        let q = i64::from(quads);
        (self.cx * q - 1, self.cy * q - 1)
    }

    /// The level lattice samples the tile holds: (quads + 3)^2 from [`TileKey::first_sample`].
    pub fn samples(&self, quads: u32) -> Rect {
        let (x0, y0) = self.first_sample(quads);
        Rect {
            x0,
            y0,
            w: quads + 3,
            h: quads + 3,
        }
    }
}

/// A tile written into a pool slot this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DetailUpload {
    /// The slot ([`DetailAtlas::place`] says where it lies).
    pub slot: u32,
    /// What it now holds.
    pub key: TileKey,
}

/// Where pool tiles come from: the same heights the ring fill writes.
pub trait DetailSource {
    /// Whether samples `rect` of `level` can be read now (a streamed source: its tiles are resident).
    fn detail_ready(&self, level: u32, rect: &Rect) -> bool;
    /// (z, z_c) of `level` at its lattice point (i, j), bit for bit what that ring would hold: its
    /// height and the next coarser level's surface there (GC section 3's z_c; at even points the coarser
    /// sample itself, what a stitched cell's coarse quads read).
    fn detail_sample(&self, level: u32, i: i64, j: i64) -> [f32; 2];
}

impl DetailSource for Clipmap {
    fn detail_ready(&self, level: u32, rect: &Rect) -> bool {
        // Synthesised rings (resident pyramids only) are computed from the data level below them; z_c
        // reads the next coarser level under the rectangle's coarse stencil.
        let synth = self.synth_levels();
        let coarse = Rect::from_bounds(
            rect.x0 >> 1,
            rect.y0 >> 1,
            ((rect.x1() - 1) >> 1) + 2,
            ((rect.y1() - 1) >> 1) + 2,
        );
        self.source_ready(level.saturating_sub(synth), rect)
            && (level + 1 >= self.levels()
                || self.source_ready((level + 1).saturating_sub(synth), &coarse))
    }

    fn detail_sample(&self, level: u32, i: i64, j: i64) -> [f32; 2] {
        self.sample(level, i, j)
    }
}

/// Writes tile `key`'s `side x side` texels (side = quads + 3, row-major, border included), each (z, z_c)
/// as the rings hold them ([`DetailSource::detail_sample`]), into `out`; false (nothing written) when its
/// source samples are not resident now (a streamed package's tiles evicted since the plan that filled it:
/// only a renderer re-sending a missed plan's tiles meets this).
pub fn fill_tile(src: &impl DetailSource, key: &TileKey, quads: u32, out: &mut [[f32; 2]]) -> bool {
    let side = quads as usize + 3;
    assert!(
        out.len() >= side * side,
        "a tile buffer holds side^2 texels"
    );
    if !src.detail_ready(key.level, &key.samples(quads)) {
        return false;
    }
    let (i0, j0) = key.first_sample(quads);
    for (r, row) in out.chunks_exact_mut(side).take(side).enumerate() {
        for (c, z) in row.iter_mut().enumerate() {
            *z = src.detail_sample(key.level, i0 + c as i64, j0 + r as i64);
        }
    }
    true
}

/// The pool part of a [`crate::plan::frame_plan::FramePlan`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DetailFrame {
    /// Tiles to write this frame.
    pub uploads: heapless::Vec<DetailUpload, DETAIL_CAPACITY>,
    /// What every slot holds after this plan (a renderer that missed plans re-sends these).
    pub resident: heapless::Vec<Option<TileKey>, DETAIL_CAPACITY>,
    /// Blocks drawn from the pool: (index in the LOD frame, the level the selection had clamped it to).
    pub served: heapless::Vec<(u16, u32), MAX_LOD_BLOCKS>,
    /// Per served block: the largest screen-space bound, pixels, of its cells that miss epsilon (rescaled
    /// estimates where stale); 0 when every cell meets epsilon or its wanted level (the block no longer
    /// counts as clamped).
    pub served_unmet: heapless::Vec<f32, MAX_LOD_BLOCKS>,
    /// The coarse units of each cell drawn stitched ([`stitch`]), in draw-list order: a stitched cell's
    /// draw holds 1 + its index ([`Draw::stitch`]).
    pub masks: Box<heapless::Vec<stitch::Mask, MAX_DETAIL_CELLS>>,
    /// Samples the uploads write.
    pub samples_updated: u64,
    /// Tiles this plan wanted but whose source samples were not resident yet (a streamed package), as
    /// (level, samples), most needed first, and, while the refinement has splits left ([`Self::refining`]),
    /// the region its next split reads: for [`Clipmap::request_samples`], which decodes what is not
    /// resident ahead (a warm-up also goes on while this is not empty). Not hashed: the frame's uploads
    /// and resident tiles say what it drew.
    pub wanted: heapless::Vec<(u32, Rect), DETAIL_CAPACITY>,
    /// Distinct tiles this plan's pool cells read (what the frame needs; resident slots may also hold
    /// tiles no longer needed).
    pub tiles_needed: u32,
    /// This plan's number in its planner's chain.
    pub seq: u64,
    /// The previous plan's number (None: the first plan; the GPU holds nothing).
    pub prev: Option<u64>,
    /// The refinement stopped at its budget (`budget.refine_bounds_per_frame`) with splits left: the
    /// next plans of a still camera refine further. Not hashed.
    pub refining: bool,
    /// Bound evaluations the refinement spent (at most the budget). Not hashed.
    pub refine_evaluations: u64,
    /// Distinct tiles this plan's pool cells read that no slot holds yet (their blocks wait). Not hashed.
    pub tiles_waiting: u32,
}

impl DetailFrame {
    /// Slots holding a tile.
    pub fn tiles_resident(&self) -> u32 {
        u32::try_from(self.resident.iter().filter(|k| k.is_some()).count())
            .expect("slots <= DETAIL_CAPACITY")
    }

    /// The pool part of the frame hash.
    pub fn hash_into(&self, h: &mut Hash64) {
        h.write_u64(self.uploads.len() as u64);
        for u in &self.uploads {
            h.write_u32(u.slot);
            write_key(h, &u.key);
        }
        h.write_u64(self.resident.len() as u64);
        for k in &self.resident {
            match k {
                Some(k) => write_key(h, k),
                None => h.write_u32(u32::MAX),
            }
        }
        h.write_u64(self.served.len() as u64);
        for &(i, l) in &self.served {
            h.write_u32(u32::from(i));
            h.write_u32(l);
        }
    }
}

fn write_key(h: &mut Hash64, k: &TileKey) {
    h.write_u32(k.level);
    h.write_i64(k.cx);
    h.write_i64(k.cy);
}

/// What the pool may spend this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DetailBudget {
    /// A new clipmap frame: the pool clock advances and `samples` may be spent (a frame planned again
    /// spends nothing).
    pub new_frame: bool,
    /// Samples left of the per-frame update budget after the rings.
    pub samples: u64,
    /// Draw calls left of `budget.max_draws` after the clamped draw list (the pool's cells of one level
    /// and size are one instanced call).
    pub draws: u32,
    /// Triangles left of `budget.max_triangles` after it.
    pub triangles: u64,
    /// Skirts are on: each cell hangs its tile skirt, in the same draw ([`DrawKind::PoolCell`]).
    pub skirts: bool,
    /// The block side m: the widest skirt loop (`mesh::skirt_loop_range`).
    pub block_quads: u32,
    /// Draws kept per served block for the skirts its neighbours then need (their triangles are not
    /// kept back: the plan's final check holds the triangle budget, dropping the last served block where
    /// they do not fit).
    pub margin: u32,
    /// Cells are drawn stitched ([`stitch`]): each unit whose next coarser level meets epsilon is one
    /// coarse quad, and a cell costs [`stitch::triangles`].
    pub stitch: bool,
    /// Per-instance records the plan's cell buffer holds: a whole cell takes one, a stitched cell one
    /// per unit and per unit side on its border.
    pub instances: usize,
}

impl DetailBudget {
    /// Triangles of a cell drawn over `bounds` (its vertices): the top-left k x k quads of the block mesh
    /// (k: the longer side, [`cell_quads`]) and, with skirts, the smallest skirt loop around them.
    pub fn cell_triangles(&self, bounds: &Rect) -> u64 {
        let k = cell_quads(bounds);
        let mut t = u64::from(mesh::block_prefix(k) / 3);
        if self.skirts {
            let r = mesh::skirt_loop_range(self.block_quads, k);
            t += u64::from((r.end - r.start) / 3);
        }
        t
    }
}

/// Quads a cell over `bounds` is drawn with: a k x k square of the block mesh from the bounds' corner
/// (k: the longer side), so a cell clipped to its block's piece draws no degenerate rows beyond it.
pub fn cell_quads(bounds: &Rect) -> u32 {
    bounds.w.max(bounds.h).saturating_sub(1)
}

/// Where the frame's pool tiles are seen from: what decides which cells of a block are needed.
#[derive(Clone, Copy, Debug)]
pub struct DetailView<'a> {
    /// The clipmap frame (active regions, for the blocks' pieces).
    pub frame: &'a Frame,
    /// The view frustum.
    pub frustum: &'a Frustum,
    /// The eye in level-0 lattice units.
    pub eye_l: (f64, f64),
    /// The eye's height (m).
    pub eye_z: f64,
    /// Level-0 spacing (m).
    pub g0: f64,
    /// The terrain's height range (m): every tile's vertical extent.
    pub z_range: (f32, f32),
    /// The data's last sample in level-0 lattice units (east, south).
    pub data_lattice: (f64, f64),
    /// The screen-space error bound, pixels (the ranking's unit).
    pub epsilon_px: f64,
}

impl DetailView<'_> {
    /// Whether lattice rectangle `r` of `level` meets the data and the frustum (over the terrain's height
    /// range, so a tile's test does not depend on its samples).
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48"
    )]
    pub(crate) fn visible(&self, level: u32, r: &Rect) -> bool {
        let k = f64::from(1u32 << level);
        let (x0, x1) = (r.x0 as f64 * k, (r.x1() - 1) as f64 * k);
        let (y0, y1) = (r.y0 as f64 * k, (r.y1() - 1) as f64 * k);
        let (lx, ly) = self.data_lattice;
        if x1 <= 0.0 || y1 <= 0.0 || x0 >= lx || y0 >= ly {
            return false;
        }
        let (x0, x1, y0, y1) = (x0.max(0.0), x1.min(lx), y0.max(0.0), y1.min(ly));
        let g = self.g0;
        let lo = DVec3::new(
            (x0 - self.eye_l.0) * g,
            -(y1 - self.eye_l.1) * g,
            f64::from(self.z_range.0) - self.eye_z - 0.01,
        );
        let hi = DVec3::new(
            (x1 - self.eye_l.0) * g,
            -(y0 - self.eye_l.1) * g,
            f64::from(self.z_range.1) - self.eye_z + 0.01,
        );
        self.frustum.intersects(lo, hi)
    }

    /// Calls `f` with every cell of level `w` (finer than `b`'s ring) over the block minus the finer
    /// ring's active region, the vertices of that level the cell draws there and whether it is in view;
    /// stops when `f` says false.
    fn cells(
        &self,
        b: &BlockLod,
        w: u32,
        quads: u32,
        mut f: impl FnMut(TileKey, Rect, bool) -> Result<bool>,
    ) -> Result<()> {
        let shift = b.ring - w;
        let q = i64::from(quads);
        let hole = match b.ring.checked_sub(1) {
            Some(fl) => cull::hole(&self.frame.levels[fl as usize].active),
            None => Rect::EMPTY,
        };
        for p in cull::block_pieces(&b.rect, &hole) {
            // Exact: a finer level's lattice meets every vertex of the ring's.
            let pw = Rect::from_bounds(
                p.x0 << shift,
                p.y0 << shift,
                ((p.x1() - 1) << shift) + 1,
                ((p.y1() - 1) << shift) + 1,
            );
            let piece_visible = self.visible(w, &pw);
            for cy in pw.y0.div_euclid(q)..=(pw.y1() - 2).div_euclid(q) {
                for cx in pw.x0.div_euclid(q)..=(pw.x1() - 2).div_euclid(q) {
                    let cell =
                        Rect::from_bounds(cx * q, cy * q, (cx + 1) * q + 1, (cy + 1) * q + 1);
                    let bounds = cell.intersect(&pw);
                    if bounds.w < 2 || bounds.h < 2 {
                        continue;
                    }
                    let visible = piece_visible && self.visible(w, &bounds);
                    if !f(TileKey { level: w, cx, cy }, bounds, visible)? {
                        return Ok(());
                    }
                }
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Slot {
    key: Option<TileKey>,
    /// The pool clock when a served or candidate block last needed it.
    needed: u64,
}

/// The pool's CPU state: which tile each slot holds and when it was last needed. Built once from the
/// profile; [`DetailPool::plan`] allocates nothing.
#[derive(Clone, Debug)]
pub struct DetailPool {
    quads: u32,
    side: u32,
    atlas: DetailAtlas,
    slots: heapless::Vec<Slot, DETAIL_CAPACITY>,
    /// Advances once per clipmap frame planned.
    clock: u64,
    /// Plans made (the renderer's sync chain).
    seq: u64,
    /// The clamped blocks and the cells they are drawn with, carried from frame to frame (and kept for
    /// [`DetailPool::push_draws`]).
    tree: Quadtree,
    /// Which slot holds each resident tile.
    slot_of: keymap::KeyMap,
    /// Scratch: the clamped blocks in fill order (indices into the quadtree's).
    order: Box<heapless::Vec<u16, MAX_LOD_BLOCKS>>,
    /// The last plan's epsilon, pixels.
    eps: f64,
}

impl DetailPool {
    /// An empty pool of `profile`'s size (a validated profile).
    pub fn new(profile: &Profile) -> Self {
        let mut slots = heapless::Vec::new();
        for _ in 0..(profile.budget.detail_tiles as usize).min(DETAIL_CAPACITY) {
            slots
                .push(Slot::default())
                .expect("tiles <= DETAIL_CAPACITY");
        }
        Self {
            quads: profile.detail_quads(),
            side: profile.detail_side(),
            atlas: profile.detail_atlas(),
            slots,
            clock: 0,
            seq: 0,
            tree: Quadtree::new(profile.detail_quads()),
            order: Box::default(),
            slot_of: keymap::KeyMap::new(DETAIL_CAPACITY),
            eps: 0.0,
        }
    }

    /// Quads per tile side.
    pub fn quads(&self) -> u32 {
        self.quads
    }

    /// Samples per tile side (border included).
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Where each slot lies in the pool texture.
    pub fn atlas(&self) -> DetailAtlas {
        self.atlas
    }

    /// Slots (`budget.detail_tiles`).
    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    /// Forgets every tile (a new renderer holds none).
    pub fn restart(&mut self) {
        for s in &mut self.slots {
            *s = Slot::default();
        }
        self.slot_of.clear();
        self.tree = Quadtree::new(self.quads);
        self.clock = 0;
        self.seq = 0;
    }

    fn find(&self, key: &TileKey) -> Option<usize> {
        self.slot_of.get(key).map(|s| s as usize)
    }

    /// The slot to fill next: an empty one, else the least recently needed one not needed this frame
    /// (lowest index on ties, so the choice is deterministic).
    fn victim(&self) -> Option<usize> {
        if let Some(i) = self.slots.iter().position(|s| s.key.is_none()) {
            return Some(i);
        }
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| s.needed < self.clock)
            .min_by_key(|(i, s)| (s.needed, *i))
            .map(|(i, _)| i)
    }

    /// Plans the pool for one frame. The clamped blocks are refined as quadtrees over space and level,
    /// carried over from the last frame (`refine/`: the largest bound is split first while its cells fit
    /// the slots, draws and triangles left and `evaluations` bound evaluations last; `bounds` gives a
    /// level's bound over a level-0 lattice box). The tiles their cells read are then filled most-needed
    /// first (by the block's bound / epsilon at the clamped level) under `budget.samples` (spent only
    /// when `budget.new_frame`: a clipmap frame planned again spends nothing), and each block whose tiles
    /// are all resident and whose parts in view are all covered is served: its level in `lod` becomes its
    /// finest cell's, and `lod.blocks_clamped` drops when every cell meets epsilon. A refined block's own
    /// ring draws, `ring_triangles[i]` for block i, go back to `budget.triangles`. Writes `out`.
    #[expect(
        clippy::too_many_arguments,
        reason = "the plan's inputs, each a different stage's output"
    )]
    pub fn plan(
        &mut self,
        src: &impl DetailSource,
        view: &DetailView<'_>,
        lod: &mut LodFrame,
        bounds: &PoolBounds<'_>,
        budget: &DetailBudget,
        ring_triangles: &[u64],
        evaluations: u64,
        out: &mut DetailFrame,
    ) -> Result<()> {
        out.uploads.clear();
        out.served.clear();
        out.served_unmet.clear();
        out.samples_updated = 0;
        out.wanted.clear();
        out.tiles_needed = 0;
        out.prev = (self.seq > 0).then_some(self.seq);
        self.seq += 1;
        out.seq = self.seq;
        if budget.new_frame {
            self.clock += 1;
        }
        let cap = self.slots.len();
        let eps = view.epsilon_px;
        self.eps = eps;
        self.tree.refine(
            view,
            lod,
            bounds,
            budget,
            (self.quads, cap),
            ring_triangles,
            evaluations,
        )?;
        out.refining = self.tree.refining;
        out.refine_evaluations = self.tree.spent;
        out.tiles_needed = u32::try_from(self.tree.keys.len()).expect("keys <= DETAIL_CAPACITY");
        // Every resident tile needed this frame is kept before any slot is refilled.
        let clock = self.clock;
        for (key, _) in self.tree.keys.iter() {
            if let Some(s) = self.find(&key) {
                self.slots[s].needed = clock;
            }
        }
        // Fill most-needed first: by the clamped bound / epsilon, then block order.
        let cands = &self.tree.cands;
        self.order.clear();
        for k in 0..cands.len() {
            self.order
                .push(u16::try_from(k).expect("cands <= MAX_LOD_BLOCKS"))
                .expect("cands <= MAX_LOD_BLOCKS");
        }
        self.order.sort_unstable_by(|&a, &b| {
            let (a, b) = (&cands[usize::from(a)], &cands[usize::from(b)]);
            b.need.total_cmp(&a.need).then(a.block.cmp(&b.block))
        });
        let tile_samples = u64::from(self.side) * u64::from(self.side);
        let mut samples = if budget.new_frame { budget.samples } else { 0 };
        for r in 0..self.order.len() {
            let c = self.tree.cands[usize::from(self.order[r])];
            if !c.refined {
                continue;
            }
            // A part in view not covered yet: the block is drawn from its ring until it is.
            let (mut missing, mut unmet, mut finest) = (u32::from(self.tree.uncovered(c.block)), 0.0f64, c.clamped);
            for l in self.tree.cells_of(c.block) {
                let l = *l;
                unmet = unmet.max(self.tree.unmet_px(&l));
                finest = finest.min(l.key.level);
                if self.find(&l.key).is_some() {
                    continue;
                }
                let rect = l.key.samples(self.quads);
                if !src.detail_ready(l.key.level, &rect) {
                    // Waits for its source; asked for once per plan, in fill order.
                    if !out.wanted.contains(&(l.key.level, rect)) {
                        let _ = out.wanted.push((l.key.level, rect));
                    }
                    missing += 1;
                    continue;
                }
                let victim = (samples >= tile_samples).then(|| self.victim()).flatten();
                let Some(s) = victim else {
                    missing += 1;
                    continue;
                };
                if let Some(old) = self.slots[s].key {
                    self.slot_of.remove(&old);
                }
                self.slots[s] = Slot {
                    key: Some(l.key),
                    needed: clock,
                };
                self.slot_of
                    .insert(l.key, u32::try_from(s).expect("slots <= DETAIL_CAPACITY"));
                samples -= tile_samples;
                out.samples_updated += tile_samples;
                let slot = u32::try_from(s).expect("slots <= DETAIL_CAPACITY");
                // One upload per slot: a slot refilled within the frame keeps its last tile.
                if let Some(u) = out.uploads.iter_mut().find(|u| u.slot == slot) {
                    u.key = l.key;
                } else {
                    out.uploads
                        .push(DetailUpload { slot, key: l.key })
                        .map_err(|_| Error::Capacity {
                            what: "detail uploads per frame",
                            capacity: DETAIL_CAPACITY,
                        })?;
                }
            }
            if missing == 0 {
                out.served
                    .push((c.block, c.clamped))
                    .map_err(|_| Error::Capacity {
                        what: "blocks served by the detail pool",
                        capacity: MAX_LOD_BLOCKS,
                    })?;
                #[expect(clippy::cast_possible_truncation, reason = "reported in f32")]
                out.served_unmet.push(unmet as f32).map_err(|_| Error::Capacity {
                    what: "blocks served by the detail pool",
                    capacity: MAX_LOD_BLOCKS,
                })?;
                lod.blocks[usize::from(c.block)].level = finest;
                if unmet == 0.0 {
                    lod.blocks_clamped -= 1;
                }
            }
        }
        // The refinement has splits left for later frames: the region the next one reads, so that a
        // streamed source decodes it ahead and a warm-up knows the pool is not done.
        if let Some(next) = self.tree.pending.filter(|_| self.tree.refining) {
            if !out.wanted.contains(&next) {
                let _ = out.wanted.push(next);
            }
        }
        out.resident.clear();
        for s in &self.slots {
            out.resident.push(s.key).expect("slots <= DETAIL_CAPACITY");
        }
        let waiting = self
            .tree
            .keys
            .iter()
            .filter(|(k, _)| self.find(k).is_none())
            .count();
        out.tiles_waiting = u32::try_from(waiting).expect("keys <= DETAIL_CAPACITY");
        Ok(())
    }

    /// Stops serving the last block `out` serves (its draws did not fit): its level in `lod` goes back to
    /// the clamped one. False when none is served.
    pub fn unserve_last(lod: &mut LodFrame, out: &mut DetailFrame) -> bool {
        match out.served.pop() {
            Some((i, level)) => {
                if out.served_unmet.pop().is_some_and(|u| u == 0.0) {
                    lod.blocks_clamped += 1;
                }
                lod.blocks[usize::from(i)].level = level;
                true
            }
            None => false,
        }
    }

    /// Appends the draws of every block `frame` serves: one per cell of its quadtree (a tile of the
    /// cell's level, q x q quads, clamped to the block's piece, reading its pool slot), with the cell's tile
    /// skirt in the same draw ([`DrawKind::PoolCell`]) when `skirts` (cells meet their neighbours at other
    /// levels). The plan draws the cells of one level and size as one instanced call. A list longer than
    /// `cap` is an [`Error::Capacity`].
    pub fn push_draws(
        &self,
        frame: &mut DetailFrame,
        skirts: bool,
        cap: usize,
        out: &mut DrawList,
    ) -> Result<u32> {
        let mut blocks = 0;
        frame.masks.clear();
        for &(i, _) in &frame.served {
            for l in self.tree.cells_of(i) {
                let slot = self
                    .find(&l.key)
                    .expect("a served block's cells are resident");
                let stitched = stitch::any(&l.coarse);
                let stitch = if stitched {
                    frame
                        .masks
                        .push(l.coarse)
                        .expect("cells <= MAX_DETAIL_CELLS");
                    u16::try_from(frame.masks.len()).expect("cells <= MAX_DETAIL_CELLS")
                } else {
                    0
                };
                let d = Draw {
                    level: l.key.level,
                    kind: if skirts || stitched {
                        DrawKind::PoolCell
                    } else {
                        DrawKind::Block
                    },
                    origin: [l.bounds.x0, l.bounds.y0],
                    bounds: l.bounds,
                    fine: l.key.level,
                    quads: cell_quads(&l.bounds),
                    clamped: !l.met,
                    pool: Some(u16::try_from(slot).expect("slots <= DETAIL_CAPACITY")),
                    stitch,
                };
                cull::push_capped(out, d, cap)?;
                blocks += 1;
            }
        }
        Ok(blocks)
    }
}
