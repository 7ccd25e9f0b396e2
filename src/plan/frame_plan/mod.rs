//! Stage 2, the per-frame plan as a value: [`Planner::plan`] turns (clipmap frame, camera, per-frame
//! [`PlanParams`]) into a [`FramePlan`]: the texture rectangles to upload, the SAT LOD level of every block,
//! the draw list, the draw calls with their index ranges (a run of detail pool cells is one instanced call),
//! the packed uniforms (`Globals`, one `DrawUniform` slot per call and one `PoolCell` per pool cell), and a
//! 64-bit hash of all of it.
//!
//! Pure and allocation-free: a `FramePlan` is allocated once ([`Planner::new_plan`], capacity from the
//! profile) and refilled each frame; overflow is [`Error::Capacity`]. The LOD mode is fixed when the
//! planner is built ([`LodSetup`]), so a SAT mode without its tables is a construction error. The GPU
//! stage ([`crate::gpu::renderer::Renderer`]) only uploads and draws what the plan says.

use std::ops::Range;

use bytemuck::Zeroable;

use crate::hash::Hash64;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawKind, DrawList, DrawParams, DrawStats, MAX_DRAWS};
use crate::plan::detail::{stitch, DetailFrame, DetailPool};
use crate::plan::fragment::{FragmentPath, FragmentPaths};
use crate::plan::lod::{Lod, LodFrame, LodMode};
use crate::plan::mesh;
use crate::plan::uniforms::{
    data_extent_rel, detail_draw_uniform, draw_uniform, lod_draw_uniform, shading_levels, to_f32x4,
    DrawUniform, Globals, PoolCell,
};
use crate::plan::uploads::UploadList;

mod pool;
mod units;
use crate::profile::DRAW_SLOT_BYTES;
use crate::shading::basic::BasicShading;
use crate::{Error, Result};
use crate::plan::camera::Camera;
use crate::profile::Profile;

/// [`DRAW_SLOT_BYTES`] as a slice stride.
#[expect(clippy::cast_possible_truncation, reason = "256 fits every usize")]
pub const SLOT: usize = DRAW_SLOT_BYTES as usize;

/// Width of the vertex-probe target, pixels (`Globals::params` z).
pub const PROBE_WIDTH: u32 = 64;

/// Per-frame switches (vello's `RenderParams`; the fixed choices are in [`LodSetup`] and the renderer's
/// options).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanParams {
    /// GC 6.2 transition morphing (off: every vertex takes its own level's z). SAT modes never morph.
    pub morph: bool,
    /// Frustum culling of blocks (off: every block is drawn).
    pub cull: bool,
    /// Skirts on level boundaries (off only to show the cracks they close).
    pub skirts: bool,
    /// The SAT modes' screen-space error bound, pixels; None: the profile's `view.epsilon_px`.
    pub epsilon_px: Option<f32>,
    /// The viewport drawn into, pixels (width, height); None: the profile's `view`. A window's resize
    /// changes only this: the aspect and the LOD's pixel scale follow, nothing is rebuilt.
    pub viewport: Option<(u32, u32)>,
}

impl Default for PlanParams {
    fn default() -> Self {
        Self {
            morph: true,
            cull: true,
            skirts: true,
            epsilon_px: None,
            viewport: None,
        }
    }
}

/// How blocks choose their level, fixed for a planner's life.
#[derive(Clone, Debug, Default)]
pub enum LodSetup {
    /// Each ring at its own level (the plain geometry clipmap).
    #[default]
    Distance,
    /// A SAT LOD mode with the selector holding its tables ([`Lod::for_clipmap`]).
    Sat(LodMode, Lod),
}

impl LodSetup {
    /// `mode`, with `lod` the tables a SAT mode needs; a SAT mode without them is an error.
    pub fn new(mode: LodMode, lod: Option<Lod>) -> Result<Self> {
        match (mode, lod) {
            (LodMode::Distance, _) => Ok(Self::Distance),
            (mode, Some(lod)) => Ok(Self::Sat(mode, lod)),
            (mode, None) => Err(Error::Invalid {
                what: "LOD mode".into(),
                reason: format!("`{mode}` needs the SAT LOD tables (Lod::for_clipmap)"),
            }),
        }
    }

    /// The mode.
    pub fn mode(&self) -> LodMode {
        match self {
            Self::Distance => LodMode::Distance,
            Self::Sat(mode, _) => *mode,
        }
    }
}

/// One draw call of a plan: which mesh, which part of its index buffer, and which of the plan's draws it
/// draws: one, or a run of detail pool cells of one level, mesh range and program drawn instanced (issue
/// 15), one instance per cell, each cell's own fields read from the cell buffer ([`PoolCell`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlannedDraw {
    /// The mesh.
    pub kind: DrawKind,
    /// Indices drawn.
    pub indices: Range<u32>,
    /// The fragment program it is recorded with.
    pub fragment: FragmentPath,
    /// The draws of [`FramePlan::draws`] it draws.
    pub draws: Range<u32>,
    /// The pool cells ([`FramePlan::pool_cells`]) it draws, one instance each; empty: one instance, not
    /// a pool draw.
    pub cells: Range<u32>,
}

impl PlannedDraw {
    /// Instances it draws.
    pub fn instances(&self) -> u32 {
        (self.cells.end - self.cells.start).max(1)
    }
}

/// What a plan holds, in numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanStats {
    /// Draw calls (a run of pool cells is one instanced call).
    pub draws: u32,
    /// Detail pool cells drawn, as instances of the pool's calls.
    pub pool_cells: u32,
    /// Blocks drawn, culled, and skirts drawn.
    pub cull: DrawStats,
    /// Triangles submitted (the zero-area ones of clamped blocks included).
    pub triangles: u64,
    /// Upload rectangles.
    pub uploads: u32,
    /// Texels (samples) they cover.
    pub upload_samples: u64,
    /// SAT modes: blocks whose drawn pieces (the block less the finer ring's hole) meet the view
    /// frustum and whose wanted level is finer than the held data, rings and detail pool, or whose pool
    /// cells miss epsilon (by their stale estimates while the camera moves); 0 in distance mode.
    pub blocks_clamped: u32,
    /// SAT modes: the largest screen-space bound, pixels, that those blocks are drawn at: a block drawn
    /// from its ring, its bound at that level as the selection holds it; a block drawn from the pool, the
    /// bounds of its cells that miss epsilon (rescaled estimates while the camera moves). 0 when none is
    /// clamped: the error the plan could not yet pay for, reported beside their count. Infinite where a
    /// block is drawn at a level past the SAT LOD tables' (a ring the update has not yet brought finer
    /// data to, as after a jump): its error is not known.
    pub unmet_px: f32,
    /// SAT modes: blocks drawn from the detail pool at their wanted level.
    pub blocks_from_pool: u32,
    /// Detail pool slots holding a tile after this plan.
    pub detail_tiles_resident: u32,
    /// Distinct detail tiles this plan's pool cells read.
    pub detail_tiles_needed: u32,
    /// Detail tiles written this plan.
    pub detail_uploads: u32,
    /// Samples they hold (charged to the same per-frame budget as the rings, after them).
    pub detail_samples_updated: u64,
    /// SAT modes: screen-space bounds this plan evaluated (selection and detail pool together,
    /// [`Lod::evaluations`]): its work, counted the same on every machine.
    pub bound_evaluations: u64,
    /// SAT modes: the bound evaluations the detail pool's refinement spent (at most
    /// `budget.refine_bounds_per_frame`).
    pub refine_evaluations: u64,
    /// SAT modes: the refinement stopped at its budget with work left (a still camera's next plans
    /// refine further).
    pub refining: bool,
    /// SAT modes: distinct pool tiles the plan's cells read that no slot holds yet.
    pub detail_tiles_waiting: u32,
}

/// One frame's plan; see the module doc. Allocated once by [`Planner::new_plan`], refilled per frame.
#[derive(Clone, Debug)]
pub struct FramePlan {
    frame_index: Option<u64>,
    since: Option<u64>,
    uploads: UploadList,
    lod: Box<LodFrame>,
    detail: Box<DetailFrame>,
    draws: Box<DrawList>,
    ranges: Box<heapless::Vec<PlannedDraw, MAX_DRAWS>>,
    /// Allocated once with [`Profile::pool_cell_capacity`] records; never grown (a full buffer is an
    /// [`Error::Capacity`]).
    cells: Vec<PoolCell>,
    slots: Vec<u8>,
    globals: Globals,
    stats: PlanStats,
    /// The hash of the stitched pool cells' records, compact: each cell's own record, rectangle and
    /// unit mask, from which its units' records follow (`units.rs`).
    stitched_hash: u64,
    hash: u64,
}

impl FramePlan {
    /// The clipmap frame planned (None before the first plan).
    pub fn frame_index(&self) -> Option<u64> {
        self.frame_index
    }

    /// The frame whose plan the previous one was (None: the uploads cover everything ever written).
    pub fn since(&self) -> Option<u64> {
        self.since
    }

    /// The texture rectangles written since the previous plan: the union of the frames in between.
    pub fn uploads(&self) -> &[crate::plan::frame::Upload] {
        &self.uploads
    }

    /// The SAT LOD level of every block (empty in distance mode).
    pub fn lod_frame(&self) -> &LodFrame {
        &self.lod
    }

    /// The detail pool part: tiles to write, what every slot holds, the blocks it serves.
    pub fn detail(&self) -> &DetailFrame {
        &self.detail
    }

    /// The draw list, finest level first, then the detail pool's cells: one entry per block piece,
    /// skirt or pool cell (what is drawn where; the draw calls are [`FramePlan::planned`]).
    pub fn draws(&self) -> &DrawList {
        &self.draws
    }

    /// The draw calls: each one's mesh, index range, program and the draws it covers (a run of pool
    /// cells is one instanced call). `budget.max_draws` bounds their number.
    pub fn planned(&self) -> &[PlannedDraw] {
        &self.ranges
    }

    /// The pool cells' per-instance fields, in draw order (the cell buffer's contents).
    pub fn pool_cells(&self) -> &[PoolCell] {
        &self.cells
    }

    /// The draw call of draw `i` and its instance there; None for a stitched cell, whose units are
    /// instances of several calls.
    pub fn call_of(&self, i: usize) -> Option<(usize, u32)> {
        if self.draws.get(i).is_some_and(|d| d.stitch != 0) {
            return None;
        }
        let i = u32::try_from(i).ok()?;
        self.ranges
            .iter()
            .position(|c| c.draws.contains(&i))
            .map(|k| (k, i - self.ranges[k].draws.start))
    }

    /// The uniforms the vertices of draw `i` see: its call's slot, with a pool cell's own fields put
    /// over it as the vertex shader's `draw_of` does ([`PoolCell::over`]).
    ///
    /// # Panics
    /// When `i` is past the draw list or a stitched cell ([`FramePlan::call_of`]).
    pub fn draw_uniform(&self, i: usize) -> DrawUniform {
        let (k, instance) = self
            .call_of(i)
            .expect("a draw within the plan, not a stitched cell");
        self.instance_uniform(k, instance)
    }

    /// The uniforms the vertices of instance `instance` of call `k` see: the call's slot, with a pool
    /// cell's (or stitched unit's) own fields put over it as `draw_of` does.
    ///
    /// # Panics
    /// When `k` is past the calls.
    pub fn instance_uniform(&self, k: usize, instance: u32) -> DrawUniform {
        let at = k * SLOT;
        let slot: DrawUniform =
            bytemuck::pod_read_unaligned(&self.slots[at..at + std::mem::size_of::<DrawUniform>()]);
        let c = &self.ranges[k];
        if c.cells.is_empty() {
            slot
        } else {
            self.cells[(c.cells.start + instance) as usize].over(&slot)
        }
    }

    /// The draw slots' bytes: one [`DRAW_SLOT_BYTES`] slot per draw call.
    pub fn slot_bytes(&self) -> &[u8] {
        &self.slots[..self.ranges.len() * SLOT]
    }

    /// The cell buffer's bytes: one [`PoolCell`] per pool cell.
    pub fn cell_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.cells)
    }

    /// The global uniforms.
    pub fn globals(&self) -> &Globals {
        &self.globals
    }

    /// The numbers.
    pub fn stats(&self) -> PlanStats {
        self.stats
    }

    /// Hash of the whole plan: frame, uploads, LOD levels, draws, uniform bytes.
    pub fn hash(&self) -> u64 {
        self.hash
    }

    fn compute_hash(&self) -> u64 {
        let mut h = Hash64::new();
        h.write_u64(self.frame_index.map_or(u64::MAX, |i| i));
        h.write_u64(self.since.map_or(u64::MAX, |i| i));
        h.write_u64(self.uploads.len() as u64);
        for u in &self.uploads {
            for v in [u.level, u.tex_x, u.tex_y, u.w, u.h] {
                h.write_u32(v);
            }
        }
        self.lod.hash_into(&mut h);
        self.detail.hash_into(&mut h);
        h.write_u64(self.ranges.len() as u64);
        for d in self.ranges.iter() {
            h.write_u32(d.kind as u32);
            h.write_u32(d.indices.start);
            h.write_u32(d.indices.end);
            h.write_u32(d.fragment as u32);
            h.write_u32(d.draws.start);
            h.write_u32(d.draws.end);
            h.write_u32(d.cells.start);
            h.write_u32(d.cells.end);
        }
        h.write_bytes(self.slot_bytes());
        // Pool cell records: those of whole cells as they are (the first ones); a stitched cell's units
        // through the cell's record and mask (hashing every unit's record was a tenth of a SAT LOD
        // plan's time). A plan without stitched cells hashes as it always did.
        let whole = self
            .ranges
            .iter()
            .find(|d| matches!(d.kind, DrawKind::PoolUnit | DrawKind::PoolUnitSkirt))
            .map_or(self.cells.len(), |d| d.cells.start as usize);
        h.write_bytes(bytemuck::cast_slice(&self.cells[..whole]));
        if whole < self.cells.len() {
            h.write_u64(self.stitched_hash);
        }
        h.write_bytes(bytemuck::bytes_of(&self.globals));
        h.finish()
    }
}

// A planner can be built on one thread and planned on another.
const _: () = {
    const fn send<T: Send>() {}
    send::<Planner>();
};

/// Builds [`FramePlan`]s for one clipmap and profile; holds the LOD selector and the sizes the plan needs.
#[derive(Clone, Debug)]
pub struct Planner {
    lod: LodSetup,
    /// The profile's `view.epsilon_px`: a frame's bound when its [`PlanParams::epsilon_px`] gives none.
    /// The one place a frame's epsilon comes from is [`PlanParams`]; the selector takes it each frame.
    profile_epsilon: f64,
    n: u32,
    size: u32,
    block_quads: u32,
    skirt_indices: u32,
    max_draws: u32,
    max_triangles: u32,
    /// Pool cell records a plan holds ([`Profile::pool_cell_capacity`]).
    cell_capacity: usize,
    /// The profile's viewport (width, height), pixels: the default of [`PlanParams::viewport`].
    view: (u32, u32),
    skirt_floor: f32,
    /// The data's last sample in level-0 lattice units (east, south).
    data_lattice: (f64, f64),
    shading: BasicShading,
    probe_size: [u32; 2],
    /// The clipmap frame of the last plan.
    last: Option<u64>,
    /// The detail pool's CPU state (SAT modes).
    pool: DetailPool,
    /// Per LOD block: the triangles its ring draws take in the clamped draw list (the pool's credit
    /// when it refines the block; allocated once).
    ring_triangles: Box<[u64]>,
    /// The terrain's height range (m).
    z_range: (f32, f32),
    update_budget: u32,
    /// The culled ring tiles' height ranges, kept while their texels are unchanged.
    heights: crate::plan::heights::TileHeights,
    /// Bound evaluations the detail pool's refinement may spend a frame
    /// (`budget.refine_bounds_per_frame`).
    refine_budget: u32,
}

/// Refuses a profile whose `budget.max_draws` exceeds the draw calls a frame plan (and the renderer's
/// uniform slots) can hold, [`MAX_DRAWS`].
pub fn check_draw_capacity(profile: &Profile) -> Result<()> {
    if profile.budget.max_draws as usize > MAX_DRAWS {
        return Err(Error::config(
            &profile.name,
            "budget.max_draws",
            format!(
                "{} exceeds the renderer's fixed capacity {MAX_DRAWS}",
                profile.budget.max_draws
            ),
        ));
    }
    Ok(())
}

impl Planner {
    /// A planner for `clipmap` (built from `profile`) drawn into a `profile.view` viewport.
    pub fn new(profile: &Profile, clipmap: &Clipmap, lod: LodSetup) -> Result<Self> {
        let c = &profile.clipmap;
        if clipmap.n() != c.n
            || clipmap.levels() != c.levels
            || clipmap.ring(0).size() != profile.clip_size()
        {
            return Err(Error::config(
                &profile.name,
                "clipmap",
                "the clipmap was built from a different profile",
            ));
        }
        check_draw_capacity(profile)?;
        let block_quads = profile.block_m();
        let skirt_indices = 4 * (c.n + 1) * 6;
        let block_vertices = (block_quads + 1) * (block_quads + 1);
        let skirt_vertices = 2 * (4 * (c.n + 1) + 1);
        let probe_rows = block_vertices.max(skirt_vertices).div_ceil(PROBE_WIDTH);

        // Shading and skirt floor from the data (pyramid level 0 is the terrain itself).
        let (lo, hi) = clipmap.data_range();
        let (width, height) = clipmap.data_size();
        let synth = f64::from(1u32 << clipmap.synth_levels());
        let spacing = clipmap.g0() * synth;
        let data_lattice = (f64::from(width - 1) * synth, f64::from(height - 1) * synth);
        let diagonal = f64::from(width).hypot(f64::from(height)) * spacing;
        #[expect(
            clippy::cast_possible_truncation,
            reason = "the level-0 spacing as an f32 metre offset"
        )]
        let skirt_floor = lo - (0.5 * (hi - lo)).max(10.0 * clipmap.g0() as f32);
        Ok(Self {
            lod,
            profile_epsilon: f64::from(profile.view.epsilon_px),
            n: c.n,
            size: profile.clip_size(),
            block_quads,
            skirt_indices,
            max_draws: profile.budget.max_draws,
            max_triangles: profile.budget.max_triangles,
            cell_capacity: profile.pool_cell_capacity(),
            view: (profile.view.width, profile.view.height),
            skirt_floor,
            data_lattice,
            shading: BasicShading::for_terrain((lo, hi), diagonal, clipmap.data_mean_slope()),
            probe_size: [PROBE_WIDTH, probe_rows],
            last: None,
            pool: DetailPool::new(profile),
            ring_triangles: vec![0; crate::plan::lod::MAX_LOD_BLOCKS].into_boxed_slice(),
            z_range: (lo, hi),
            update_budget: profile.budget.update_samples_per_frame,
            refine_budget: profile.budget.refine_bounds_per_frame,
            heights: crate::plan::heights::TileHeights::default(),
        })
    }

    /// An empty plan with this planner's capacity (the only allocation; reuse it every frame).
    pub fn new_plan(&self) -> FramePlan {
        let mut draws: Box<DrawList> = Box::default();
        draws.clear();
        FramePlan {
            frame_index: None,
            since: None,
            uploads: UploadList::new(),
            lod: LodFrame::new_boxed(),
            detail: Box::default(),
            draws,
            ranges: Box::default(),
            cells: Vec::with_capacity(self.cell_capacity),
            slots: vec![0; self.max_draws as usize * SLOT],
            globals: Globals::zeroed(),
            stats: PlanStats::default(),
            stitched_hash: 0,
            hash: 0,
        }
    }

    /// The LOD mode, fixed at construction.
    pub fn lod_mode(&self) -> LodMode {
        self.lod.mode()
    }

    /// The SAT LOD selector, in the SAT modes.
    pub fn lod(&self) -> Option<&Lod> {
        match &self.lod {
            LodSetup::Sat(_, l) => Some(l),
            LodSetup::Distance => None,
        }
    }

    /// The basic shading parameters (the brute-force reference of the same terrain uses the same).
    pub fn shading(&self) -> BasicShading {
        self.shading
    }

    /// Size of the vertex-probe target, pixels (`Globals::params` zw).
    pub fn probe_size(&self) -> [u32; 2] {
        self.probe_size
    }

    /// Forgets the previous plan: the next one uploads everything ever written (a new renderer).
    pub fn restart(&mut self) {
        self.last = None;
        self.pool.restart();
    }

    /// The detail pool's CPU state.
    pub fn detail_pool(&self) -> &DetailPool {
        &self.pool
    }

    /// The part of its mesh's index buffer draw `d` draws.
    pub fn index_range(&self, d: &cull::Draw) -> Range<u32> {
        match d.kind {
            DrawKind::Block => 0..mesh::block_prefix(d.quads.min(self.block_quads)),
            DrawKind::Skirt => 0..self.skirt_indices,
            DrawKind::TileSkirt => mesh::skirt_loop_range(self.block_quads, d.quads),
            DrawKind::PoolCell => mesh::pool_cell_range(self.pool.quads(), d.quads),
            // Call kinds only (`units.rs`): no draw-list entry has them; a stitched cell (a `PoolCell`
            // entry) is counted by `Planner::triangles`.
            DrawKind::PoolUnit | DrawKind::PoolUnitSkirt => 0..0,
        }
    }

    /// The error of a plan whose pool cell records fill the cell buffer.
    fn cells_full(&self) -> Error {
        Error::Capacity {
            what: "pool cell records per frame (Profile::pool_cell_capacity)",
            capacity: self.cell_capacity,
        }
    }

    /// Triangles of a draw list, a stitched cell counted by its units (`masks`: the plan's,
    /// [`DetailFrame::masks`]).
    fn triangles(&self, draws: &DrawList, masks: &[stitch::Mask]) -> u64 {
        draws
            .iter()
            .map(|d| {
                if d.stitch == 0 {
                    self.triangles_of(d)
                } else {
                    let (ua, ub) = stitch::units(&d.bounds);
                    stitch::triangles(&masks[usize::from(d.stitch) - 1], ua, ub)
                }
            })
            .sum()
    }

    /// Triangles of draw `d` (a pool cell: its instance's).
    fn triangles_of(&self, d: &cull::Draw) -> u64 {
        let r = self.index_range(d);
        u64::from((r.end - r.start) / 3)
    }

    /// Plans `clipmap`'s last frame seen from `camera` into `out` (refilled; allocation-free). The
    /// uploads are every rectangle written since the frame of this planner's previous plan.
    pub fn plan(
        &mut self,
        clipmap: &Clipmap,
        camera: &Camera,
        params: &PlanParams,
        out: &mut FramePlan,
    ) -> Result<()> {
        let frame = clipmap.frame();
        out.frame_index = Some(frame.index);
        let new_frame = self.last != Some(frame.index);
        if new_frame {
            clipmap.upload_stamps().since(self.last, &mut out.uploads)?;
            out.since = self.last;
        } else {
            // The same clipmap frame again: the GPU already holds its rectangles.
            out.uploads.clear();
            out.since = self.last;
        }
        let view = params.viewport.unwrap_or(self.view);
        if view.0 == 0 || view.1 == 0 {
            return Err(Error::Invalid {
                what: "PlanParams::viewport".into(),
                reason: format!("{} x {} pixels is empty", view.0, view.1),
            });
        }
        let aspect = f64::from(view.0) / f64::from(view.1);
        let extent = data_extent_rel(clipmap, camera, self.data_lattice);
        let dp = DrawParams {
            block_quads: self.block_quads,
            max_draws: self.max_draws,
            cull: params.cull,
            skirts: params.skirts,
            aspect,
            extent,
        };
        out.lod.blocks.clear();
        out.detail.served.clear();
        let evaluated = self.lod().map_or(0, Lod::evaluations);
        let sat = match &mut self.lod {
            LodSetup::Sat(mode, lod) => {
                lod.set_epsilon_px(params.epsilon_px.map_or(self.profile_epsilon, f64::from));
                lod.set_view(view);
                lod.select(frame, camera, *mode, &mut out.lod)?;
                true
            }
            LodSetup::Distance => false,
        };
        let morph = params.morph && !sat;
        let paths = FragmentPaths::new(
            clipmap,
            clipmap.eye_lattice(camera.eye),
            morph,
            self.block_quads,
            self.data_lattice,
            extent,
        );
        let cull = if sat {
            let base = cull::build_lod_draws(
                clipmap,
                camera,
                &dp,
                &out.lod,
                &[],
                &self.heights,
                &mut out.draws,
            )?;
            self.plan_detail(clipmap, camera, &dp, &paths, new_frame, out)?
                .unwrap_or(base)
        } else {
            out.detail.uploads.clear();
            out.detail.samples_updated = 0;
            cull::build_draws(clipmap, camera, &dp, &mut out.draws)?
        };
        let (blocks_clamped, unmet_px) = if sat {
            self.visible_clamped(clipmap, camera, aspect, out)
        } else {
            (0, 0.0)
        };
        out.ranges.clear();
        out.cells.clear();
        out.stitched_hash = 0;
        // A plan made by `new_plan` has the room; a clone or another planner's plan gets it once here.
        if out.cells.capacity() < self.cell_capacity {
            out.cells.reserve_exact(self.cell_capacity);
        }
        let mut triangles = 0u64;
        let calls = (self.max_draws as usize).min(MAX_DRAWS);
        let over = || Error::Capacity {
            what: "draw calls per frame (budget.max_draws)",
            capacity: calls,
        };
        for (k, d) in out.draws.iter().enumerate() {
            if d.stitch != 0 {
                // Stitched cells come last (`sort_pool_runs`), drawn by unit below.
                break;
            }
            let at = u32::try_from(k).expect("draws <= MAX_DRAWS");
            let indices = self.index_range(d);
            triangles += u64::from((indices.end - indices.start) / 3);
            let fragment = paths.path(d);
            let (u, cells) = if let Some(slot) = d.pool {
                let key =
                    out.detail.resident[usize::from(slot)].expect("a pool draw's slot is resident");
                let first = key.first_sample(self.pool.quads());
                let place = self.pool.atlas().place(u32::from(slot));
                let u =
                    detail_draw_uniform(clipmap, camera, d, place, first, self.pool.side(), self.n);
                let c = u32::try_from(out.cells.len()).expect("cells < 2^32");
                if out.cells.len() >= self.cell_capacity {
                    return Err(self.cells_full());
                }
                out.cells.push(PoolCell::of(&u));
                // The previous call's run goes on: same level, mesh range and program.
                if let Some(last) = out.ranges.last_mut() {
                    let prev = &out.draws[last.draws.start as usize];
                    if !last.cells.is_empty()
                        && prev.level == d.level
                        && last.kind == d.kind
                        && last.indices == indices
                        && last.fragment == fragment
                    {
                        last.draws.end = at + 1;
                        last.cells.end = c + 1;
                        continue;
                    }
                }
                (u, c..c + 1)
            } else if sat {
                (
                    lod_draw_uniform(clipmap, camera, d, self.n, self.size),
                    0..0,
                )
            } else {
                (draw_uniform(clipmap, camera, d, self.n, self.size), 0..0)
            };
            let slot = out.ranges.len();
            if slot >= calls {
                return Err(over());
            }
            out.slots[slot * SLOT..slot * SLOT + std::mem::size_of::<DrawUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
            out.ranges
                .push(PlannedDraw {
                    kind: d.kind,
                    indices,
                    fragment,
                    draws: at..at + 1,
                    cells,
                })
                .map_err(|_| over())?;
        }
        triangles += self.plan_units(clipmap, camera, &paths, params.skirts, out)?;
        if triangles > u64::from(self.max_triangles) {
            return Err(Error::Capacity {
                what: "triangles per frame (budget.max_triangles)",
                capacity: self.max_triangles as usize,
            });
        }
        #[expect(clippy::cast_precision_loss, reason = "probe sizes are small")]
        let probe = [self.probe_size[0] as f32, self.probe_size[1] as f32];
        let (levels, level_info) = shading_levels(clipmap, camera, self.size);
        out.globals = Globals {
            view_proj: camera.view_proj_relative(aspect).to_cols_array(),
            shading: self.shading,
            params: [
                // SAT modes draw each block's own level unmorphed (skirts close the level changes), so the
                // surface is the PL(H_L) the error bound is about.
                if morph { 1.0 } else { 0.0 },
                self.skirt_floor,
                probe[0],
                probe[1],
            ],
            extent: to_f32x4(extent),
            levels,
            level_info,
        };
        out.stats = PlanStats {
            draws: u32::try_from(out.ranges.len()).expect("calls <= MAX_DRAWS"),
            pool_cells: u32::try_from(out.cells.len()).expect("cells < 2^32"),
            cull,
            triangles,
            uploads: u32::try_from(out.uploads.len()).expect("uploads <= MAX_PLAN_UPLOADS"),
            upload_samples: out
                .uploads
                .iter()
                .map(|u| u64::from(u.w) * u64::from(u.h))
                .sum(),
            blocks_clamped,
            unmet_px,
            blocks_from_pool: u32::try_from(out.detail.served.len())
                .expect("served <= MAX_LOD_BLOCKS"),
            detail_tiles_resident: out.detail.tiles_resident(),
            detail_tiles_needed: out.detail.tiles_needed,
            detail_uploads: u32::try_from(out.detail.uploads.len())
                .expect("uploads <= DETAIL_CAPACITY"),
            detail_samples_updated: out.detail.samples_updated,
            bound_evaluations: self.lod().map_or(0, Lod::evaluations) - evaluated,
            refine_evaluations: if sat { out.detail.refine_evaluations } else { 0 },
            refining: sat && out.detail.refining,
            detail_tiles_waiting: if sat { out.detail.tiles_waiting } else { 0 },
        };
        out.hash = out.compute_hash();
        self.last = Some(frame.index);
        Ok(())
    }
}

#[cfg(test)]
mod tests;
