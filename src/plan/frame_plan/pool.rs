//! Stage 2, the per-frame plan as a value: the detail pool's part of a SAT plan: the pool
//! planned under what the rings and the clamped draw list leave, the draw list rebuilt with the served
//! blocks' cells, sorted into runs that are one instanced call each.

use super::{FramePlan, LodSetup, Planner};
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawKind, DrawParams, DrawStats, MAX_DRAWS};
use crate::plan::detail::{DetailBudget, DetailPool, DetailView, PoolBounds};
use crate::plan::fragment::FragmentPaths;
use crate::{Error, Result};
use crate::plan::camera::Camera;

/// Sorts the pool cells `pool` (the tail of a draw list) into runs of one level, mesh and fragment
/// program, so each run is one instanced draw call, and returns how many runs there are. Unstable but
/// total order (the cell's place breaks ties), so allocation-free and deterministic.
fn sort_pool_runs(pool: &mut [cull::Draw], paths: &FragmentPaths) -> u32 {
    // Whole cells first, in runs of one level, mesh and program; then the stitched cells, in runs of one
    // level and program (their units' calls, `units.rs`, take up to one per unit mesh).
    let key = |d: &cull::Draw| {
        let stitched = d.stitch != 0;
        (
            stitched,
            d.level,
            d.kind as u32,
            if stitched { 0 } else { d.quads },
            paths.path(d) as u32,
            d.bounds.y0,
            d.bounds.x0,
            d.pool,
        )
    };
    pool.sort_unstable_by_key(key);
    let run = |d: &cull::Draw| {
        let stitched = d.stitch != 0;
        (
            stitched,
            d.level,
            d.kind,
            if stitched { 0 } else { d.quads },
            paths.path(d),
        )
    };
    let mut runs = 0;
    for (i, d) in pool.iter().enumerate() {
        if i == 0 || run(&pool[i - 1]) != run(d) {
            runs += if d.stitch != 0 {
                super::units::CALLS_PER_RUN
            } else {
                1
            };
        }
    }
    runs
}

/// Whether ring draw `d` of the clamped draw list is one of block `b`'s (`cull::build_lod_draws` draws
/// each piece of a block at its level, in its ring's lattice or, tiled exactly, in the level's): a block
/// or tile skirt at `b`'s level whose bounds lie in `b`'s rectangle in that lattice. The pool's credit
/// for refining `b`; plan_detail's final check holds the budget whatever it is.
fn block_draws(b: &crate::plan::lod::BlockLod, d: &cull::Draw) -> bool {
    if d.pool.is_some() || d.kind == DrawKind::Skirt || d.level != b.level || d.fine < b.ring {
        return false;
    }
    let s = d.fine - b.ring;
    let r = &b.rect;
    let up = |v: i64| -((-v) >> s);
    let rect = crate::plan::frame::Rect::from_bounds(
        r.x0 >> s,
        r.y0 >> s,
        up(r.x1() - 1) + 1,
        up(r.y1() - 1) + 1,
    );
    rect.contains(&d.bounds)
}

impl Planner {
    /// The detail pool's part of a SAT plan, after the clamped draw list `out.draws` is built:
    /// plans the pool under what the rings left of the sample budget and what the clamped list left of
    /// the draw and triangle budgets, then rebuilds the draw list with the served blocks from the pool,
    /// dropping the least-needed served block until it fits. None: nothing served, the list stands.
    pub(super) fn plan_detail(
        &mut self,
        clipmap: &Clipmap,
        camera: &Camera,
        dp: &DrawParams,
        paths: &FragmentPaths,
        new_frame: bool,
        out: &mut FramePlan,
    ) -> Result<Option<DrawStats>> {
        let frame = clipmap.frame();
        let frustum = cull::Frustum::new(camera, dp.aspect);
        let epsilon_px = self
            .lod()
            .map_or(self.profile_epsilon, crate::plan::lod::Lod::epsilon_px);
        let view = self.detail_view(clipmap, camera, &frustum, epsilon_px);
        let base_draws = u32::try_from(out.draws.len()).expect("draws <= MAX_DRAWS");
        let base_triangles = self.triangles(&out.draws, &[]);
        // The rings' fill (and a package's decoding) comes first: the pool gets what is left.
        let spent = u64::from(frame.samples_updated) + u64::from(clipmap.decoded_samples());
        let budget = DetailBudget {
            new_frame,
            samples: u64::from(self.update_budget).saturating_sub(spent),
            draws: self.max_draws.saturating_sub(base_draws),
            triangles: u64::from(self.max_triangles).saturating_sub(base_triangles),
            skirts: dp.skirts,
            block_quads: self.block_quads,
            // A neighbour drawn at its ring gains up to one skirt per piece: its draw is kept, not its
            // triangles. The final check below holds the triangle budget whatever the refinement
            // spends, dropping the last served block where the skirts do not fit; keeping four tile
            // skirts a block left Big Tujunga at 1.34 px with 14,358 triangles unspent, none 1.04 px.
            margin: 4,
            // Stitched cells need the unit meshes (cells of 2 quads or more).
            stitch: self.pool.quads() >= 2,
            instances: self.cell_capacity,
        };
        // A cell's bound at its level: the selection's own test over the cell's box, in the frame's view.
        let LodSetup::Sat(mode, lod) = &self.lod else {
            return Ok(None);
        };
        let bounds = PoolBounds {
            lod,
            view: lod.bound_view(camera),
            key: lod.view_key(camera, *mode),
            mode: *mode,
            eps: epsilon_px,
        };
        self.ring_triangles.fill(0);
        for (i, b) in out.lod.blocks.iter().enumerate() {
            if b.wanted < b.level && b.wanted < b.ring {
                self.ring_triangles[i] = out
                    .draws
                    .iter()
                    .filter(|d| block_draws(b, d))
                    .map(|d| self.triangles_of(d))
                    .sum();
            }
        }
        self.pool.plan(
            clipmap,
            &view,
            &mut out.lod,
            &bounds,
            &budget,
            &self.ring_triangles,
            u64::from(self.refine_budget),
            &mut out.detail,
        )?;
        if out.detail.served.is_empty() {
            return Ok(None);
        }
        loop {
            let built = cull::build_lod_draws(
                clipmap,
                camera,
                dp,
                &out.lod,
                &out.detail.served,
                &self.heights,
                &mut out.draws,
            )
            .and_then(|mut stats| {
                let rings = out.draws.len();
                let pool =
                    self.pool
                        .push_draws(&mut out.detail, dp.skirts, MAX_DRAWS, &mut out.draws)?;
                stats.blocks += pool;
                stats.skirts += if dp.skirts { pool } else { 0 };
                let runs = sort_pool_runs(&mut out.draws[rings..], paths);
                Ok((stats, rings, runs))
            });
            let fits = match &built {
                Ok((_, rings, runs)) => {
                    self.triangles(&out.draws, &out.detail.masks) <= u64::from(self.max_triangles)
                        && *rings as u64 + u64::from(*runs) <= u64::from(self.max_draws)
                }
                Err(Error::Capacity { .. }) => false,
                Err(_) => true,
            };
            if fits {
                return built.map(|(stats, _, _)| Some(stats));
            }
            if !DetailPool::unserve_last(&mut out.lod, &mut out.detail) {
                // Nothing left to drop: the clamped list alone (it fit before).
                return cull::build_lod_draws(
                    clipmap,
                    camera,
                    dp,
                    &out.lod,
                    &[],
                    &self.heights,
                    &mut out.draws,
                )
                    .map(Some);
            }
        }
    }

    /// What the detail pool sees of this frame from `camera` through `frustum`, at `epsilon_px`.
    fn detail_view<'a>(
        &self,
        clipmap: &'a Clipmap,
        camera: &Camera,
        frustum: &'a cull::Frustum,
        epsilon_px: f64,
    ) -> DetailView<'a> {
        DetailView {
            frame: clipmap.frame(),
            frustum,
            eye_l: clipmap.eye_lattice(camera.eye),
            eye_z: camera.eye.z,
            g0: clipmap.g0(),
            z_range: self.z_range,
            data_lattice: self.data_lattice,
            epsilon_px,
        }
    }

    /// The clamped blocks whose pieces (the block less the finer ring's hole, what it draws) meet the view
    /// frustum (the ones whose error shows): [`LodFrame`]'s `blocks_clamped` less those out of view,
    /// which the pool never refines. A block the pool serves counts when one of its cells misses epsilon.
    /// With it, the largest bound those blocks are drawn at ([`PlanStats::unmet_px`]).
    ///
    /// [`PlanStats::unmet_px`]: super::PlanStats::unmet_px
    /// [`LodFrame`]: crate::plan::lod::LodFrame
    pub(super) fn visible_clamped(
        &self,
        clipmap: &Clipmap,
        camera: &Camera,
        aspect: f64,
        out: &FramePlan,
    ) -> (u32, f32) {
        let frustum = cull::Frustum::new(camera, aspect);
        let view = self.detail_view(clipmap, camera, &frustum, 0.0);
        let d = &out.detail;
        let (mut n, mut unmet) = (0u32, 0.0f32);
        for (i, b) in out.lod.blocks.iter().enumerate() {
            // Whether it misses epsilon, and by how much: its pool cells' bounds, or its own at the level
            // it is drawn at.
            let (clamped, miss) = match d.served.iter().position(|&(j, _)| usize::from(j) == i) {
                Some(k) => {
                    let u = d.served_unmet.get(k).copied().unwrap_or(f32::INFINITY);
                    (u != 0.0, u)
                }
                None => (b.wanted < b.level, b.bound_px),
            };
            // What the block draws is its pieces: the part under the finer ring's hole is that ring's.
            let hole = match b.ring.checked_sub(1) {
                Some(f) => cull::hole(&clipmap.frame().levels[f as usize].active),
                None => crate::plan::frame::Rect::EMPTY,
            };
            let shown = || {
                cull::block_pieces(&b.rect, &hole)
                    .iter()
                    .any(|p| view.visible(b.ring, p))
            };
            if clamped && shown() {
                n += 1;
                unmet = unmet.max(miss);
            }
        }
        (n, unmet)
    }
}
