//! Stage 2, the per-frame plan: the draw calls of stitched pool cells (issue 15,
//! [`crate::plan::detail::stitch`]). A stitched cell is one entry of the draw list; its units are
//! instances of the pool's instanced calls, one call per run of cells of one level and program and unit
//! mesh, each unit a [`PoolCell`] record carrying its vertex flags.

use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{self, DrawKind, MAX_DRAWS};
use crate::plan::detail::stitch;
use crate::plan::fragment::FragmentPaths;
use crate::plan::frame::Rect;
use crate::plan::frame_plan::{FramePlan, PlannedDraw, Planner, SLOT};
use crate::plan::mesh::{self, UnitMesh};
use crate::plan::uniforms::{detail_draw_uniform, DrawUniform, PoolCell};
use crate::{Error, Result};
use crate::plan::camera::Camera;

/// Every unit mesh, in the order a run's calls draw them: surfaces, then the skirts.
const UNIT_MESHES: [UnitMesh; 10] = [
    UnitMesh::Fan,
    UnitMesh::Coarse,
    UnitMesh::Skirt {
        side: 0,
        coarse: false,
    },
    UnitMesh::Skirt {
        side: 0,
        coarse: true,
    },
    UnitMesh::Skirt {
        side: 1,
        coarse: false,
    },
    UnitMesh::Skirt {
        side: 1,
        coarse: true,
    },
    UnitMesh::Skirt {
        side: 2,
        coarse: false,
    },
    UnitMesh::Skirt {
        side: 2,
        coarse: true,
    },
    UnitMesh::Skirt {
        side: 3,
        coarse: false,
    },
    UnitMesh::Skirt {
        side: 3,
        coarse: true,
    },
];

/// Calls a run of stitched cells of one level and program may take: one per unit mesh.
pub(super) const CALLS_PER_RUN: u32 = 10;
const _: () = assert!(UNIT_MESHES.len() == CALLS_PER_RUN as usize);

/// Whether unit (a, b) of a cell of `ua x ub` units is drawn with mesh `m`.
fn draws_with(m: UnitMesh, coarse: bool, (a, b): (u32, u32), (ua, ub): (u32, u32)) -> bool {
    match m {
        UnitMesh::Fan => !coarse,
        UnitMesh::Coarse => coarse,
        UnitMesh::Skirt { side, coarse: c } => {
            c == coarse
                && match side {
                    0 => b == 0,
                    1 => a + 1 == ua,
                    2 => b + 1 == ub,
                    _ => a == 0,
                }
        }
    }
}

impl Planner {
    /// Appends the calls of the draw list's stitched cells (its tail, `sort_pool_runs`): per run of
    /// cells of one level and program, one instanced call per unit mesh its units use (skirts only with
    /// `skirts`), one instance per unit. Returns their triangles.
    pub(super) fn plan_units(
        &self,
        clipmap: &Clipmap,
        camera: &Camera,
        paths: &FragmentPaths,
        skirts: bool,
        out: &mut FramePlan,
    ) -> Result<u64> {
        let n = out.draws.len();
        let first = out.draws.iter().position(|d| d.stitch != 0).unwrap_or(n);
        let calls = (self.max_draws as usize).min(MAX_DRAWS);
        let quads = self.pool.quads();
        let mut triangles = 0u64;
        let mut i = first;
        while i < n {
            let (level, path) = (out.draws[i].level, paths.path(&out.draws[i]));
            let mut j = i + 1;
            while j < n && out.draws[j].level == level && paths.path(&out.draws[j]) == path {
                j += 1;
            }
            for m in UNIT_MESHES {
                if !skirts && matches!(m, UnitMesh::Skirt { .. }) {
                    continue;
                }
                let c0 = out.cells.len();
                let mut slot_uniform: Option<DrawUniform> = None;
                for k in i..j {
                    let d = out.draws[k];
                    let mask = out.detail.masks[usize::from(d.stitch) - 1];
                    let slot = d.pool.expect("a stitched cell reads a pool slot");
                    let key = out.detail.resident[usize::from(slot)]
                        .expect("a pool draw's slot is resident");
                    let first_sample = key.first_sample(quads);
                    let place = self.pool.atlas().place(u32::from(slot));
                    let units = stitch::units(&d.bounds);
                    for b in 0..units.1 {
                        for a in 0..units.0 {
                            let (ai, bi) = (i64::from(a), i64::from(b));
                            let coarse = stitch::coarse(&mask, units.0, units.1, ai, bi);
                            if !draws_with(m, coarse, (a, b), units) {
                                continue;
                            }
                            let (x, y) = (d.bounds.x0 + 2 * ai, d.bounds.y0 + 2 * bi);
                            let unit = cull::Draw {
                                origin: [x, y],
                                bounds: Rect::from_bounds(x, y, x + 3, y + 3),
                                quads: 2,
                                ..d
                            };
                            let mut u = detail_draw_uniform(
                                clipmap,
                                camera,
                                &unit,
                                place,
                                first_sample,
                                self.pool.side(),
                                self.n,
                            );
                            // The unit's vertex flags (`stitch_local` in the shader).
                            u.fine[2] =
                                i32::from(stitch::unit_flags(&mask, units.0, units.1, ai, bi));
                            if out.cells.len() >= self.cell_capacity {
                                return Err(self.cells_full());
                            }
                            out.cells.push(PoolCell::of(&u));
                            slot_uniform.get_or_insert(u);
                        }
                    }
                }
                let Some(u) = slot_uniform else {
                    continue;
                };
                let s = out.ranges.len();
                if s >= calls {
                    return Err(Error::Capacity {
                        what: "draw calls per frame (budget.max_draws)",
                        capacity: calls,
                    });
                }
                out.slots[s * SLOT..s * SLOT + std::mem::size_of::<DrawUniform>()]
                    .copy_from_slice(bytemuck::bytes_of(&u));
                let indices = mesh::pool_unit_range(quads, m);
                let instances = out.cells.len() - c0;
                triangles += instances as u64 * u64::from((indices.end - indices.start) / 3);
                let to_u32 = |v: usize| u32::try_from(v).expect("below 2^32");
                out.ranges
                    .push(PlannedDraw {
                        kind: if matches!(m, UnitMesh::Skirt { .. }) {
                            DrawKind::PoolUnitSkirt
                        } else {
                            DrawKind::PoolUnit
                        },
                        indices,
                        fragment: path,
                        draws: to_u32(i)..to_u32(j),
                        cells: to_u32(c0)..to_u32(out.cells.len()),
                    })
                    .map_err(|_| Error::Capacity {
                        what: "draw calls per frame (budget.max_draws)",
                        capacity: calls,
                    })?;
            }
            i = j;
        }
        Ok(triangles)
    }
}
