//! Stage 2, the per-frame plan: the draw calls of stitched pool cells
//! ([`crate::plan::detail::stitch`]). A stitched cell is one entry of the draw list; its units are
//! instances of the pool's instanced calls, one call per run of cells of one level and program and unit
//! mesh, each unit a [`PoolCell`] record carrying its vertex flags.

use crate::hash::Hash64;
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

/// The index in [`UNIT_MESHES`] of a unit's surface mesh.
fn surface(coarse: bool) -> usize {
    usize::from(coarse)
}

/// The index in [`UNIT_MESHES`] of a unit's skirt under side `side`.
fn skirt(side: usize, coarse: bool) -> usize {
    2 + 2 * side + usize::from(coarse)
}

/// The sides of unit (a, b) of a cell of `ua x ub` units on the cell's border (0 -y, 1 +x, 2 +y, 3 -x).
fn border((a, b): (u32, u32), (ua, ub): (u32, u32)) -> [bool; 4] {
    [b == 0, a + 1 == ua, b + 1 == ub, a == 0]
}

/// Per unit mesh, the units of stitched cell `d` drawn with it (skirts only with `skirts`).
fn unit_counts(mask: &stitch::Mask, d: &cull::Draw, skirts: bool) -> [usize; 10] {
    let mut n = [0usize; 10];
    let (ua, ub) = stitch::units(&d.bounds);
    let full = if ua >= 32 { u32::MAX } else { (1u32 << ua) - 1 };
    let ones = |x: u32| x.count_ones() as usize;
    let (last, first) = (1u32 << ua.saturating_sub(1), 1u32);
    for b in 0..ub {
        let row = mask.get(b as usize).map_or(0, |r| r & full);
        n[surface(true)] += ones(row);
        n[surface(false)] += ua as usize - ones(row);
        if skirts {
            // Sides 0 and 2 take a whole border row; sides 1 and 3 the row's last and first unit.
            for (side, on) in [(0, b == 0), (2, b + 1 == ub)] {
                if on {
                    n[skirt(side, true)] += ones(row);
                    n[skirt(side, false)] += ua as usize - ones(row);
                }
            }
            for (side, bit) in [(1, last), (3, first)] {
                n[skirt(side, row & bit != 0)] += 1;
            }
        }
    }
    n
}

impl Planner {
    /// Appends the calls of the draw list's stitched cells (its tail, `sort_pool_runs`): per run of
    /// cells of one level and program, one instanced call per unit mesh its units use (skirts only with
    /// `skirts`), one instance per unit, in the order of the run's cells and their units. One pass counts
    /// each mesh's units, one writes every record in its place: a unit's record is its cell's (one tile
    /// anchor, one slot) with its own origin, clamp rectangle and vertex flags. Returns their triangles.
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
        let too_many_calls = || Error::Capacity {
            what: "draw calls per frame (budget.max_draws)",
            capacity: calls,
        };
        let mut triangles = 0u64;
        // The hash of the stitched cells' records: each cell's own record, rectangle and mask (its
        // units' records are these, placed per unit).
        let mut h = Hash64::new();
        let mut i = first;
        while i < n {
            let (level, path) = (out.draws[i].level, paths.path(&out.draws[i]));
            let mut j = i + 1;
            while j < n && out.draws[j].level == level && paths.path(&out.draws[j]) == path {
                j += 1;
            }
            // Pass 1: each mesh's units in the run, so each call's records are one range.
            let mut count = [0usize; 10];
            for k in i..j {
                let d = out.draws[k];
                let c = unit_counts(&out.detail.masks[usize::from(d.stitch) - 1], &d, skirts);
                for (t, c) in count.iter_mut().zip(c) {
                    *t += c;
                }
            }
            let c0 = out.cells.len();
            let total: usize = count.iter().sum();
            if c0 + total > self.cell_capacity {
                return Err(self.cells_full());
            }
            let mut at = [0usize; 10];
            let mut next = c0;
            for (a, c) in at.iter_mut().zip(count) {
                *a = next;
                next += c;
            }
            // Within the capacity the plan was allocated with: no reallocation.
            out.cells.resize(c0 + total, PoolCell::default());
            // The first unit of each mesh, whose whole uniform is its call's slot.
            let mut first_unit: [Option<(usize, i64, i64, u16)>; 10] = [None; 10];
            // Pass 2: every unit's record in its mesh's range.
            for k in i..j {
                let d = out.draws[k];
                let mask = out.detail.masks[usize::from(d.stitch) - 1];
                let slot = d.pool.expect("a stitched cell reads a pool slot");
                let key = out.detail.resident[usize::from(slot)]
                    .expect("a pool draw's slot is resident");
                let (ax, ay) = key.first_sample(quads);
                let place = self.pool.atlas().place(u32::from(slot));
                let base = PoolCell::of(&detail_draw_uniform(
                    clipmap,
                    camera,
                    &d,
                    place,
                    (ax, ay),
                    self.pool.side(),
                    self.n,
                ));
                let units = stitch::units(&d.bounds);
                h.write_bytes(bytemuck::bytes_of(&base));
                h.write_u32(u32::from(slot));
                for v in [d.bounds.x0, d.bounds.y0, i64::from(d.bounds.w), i64::from(d.bounds.h)] {
                    h.write_i64(v);
                }
                for row in &mask[..units.1 as usize] {
                    h.write_u32(*row);
                }
                #[expect(
                    clippy::cast_possible_truncation,
                    reason = "tile-relative lattice offsets are below the tile side"
                )]
                let rel = |v: i64, o: i64| (v - o) as i32;
                for b in 0..units.1 {
                    let row = stitch::RowFlags::of(&mask, units.0, units.1, b);
                    for a in 0..units.0 {
                        let (ai, bi) = (i64::from(a), i64::from(b));
                        let coarse = row.coarse(a);
                        let flags = row.flags(a);
                        let (x, y) = (d.bounds.x0 + 2 * ai, d.bounds.y0 + 2 * bi);
                        let record = PoolCell {
                            origin: [rel(x, ax), rel(y, ay), base.origin[2], i32::from(flags)],
                            bounds: [rel(x, ax), rel(y, ay), rel(x + 2, ax), rel(y + 2, ay)],
                            ..base
                        };
                        let mut put = |m: usize| {
                            out.cells[at[m]] = record;
                            at[m] += 1;
                            first_unit[m].get_or_insert((k, x, y, flags));
                        };
                        put(surface(coarse));
                        if skirts {
                            for (side, on) in border((a, b), units).into_iter().enumerate() {
                                if on {
                                    put(skirt(side, coarse));
                                }
                            }
                        }
                    }
                }
            }
            let mut start = c0;
            for (mi, m) in UNIT_MESHES.into_iter().enumerate() {
                let Some((k, x, y, flags)) = first_unit[mi] else {
                    continue;
                };
                let d = out.draws[k];
                let slot = d.pool.expect("a stitched cell reads a pool slot");
                let key =
                    out.detail.resident[usize::from(slot)].expect("a pool draw's slot is resident");
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
                    self.pool.atlas().place(u32::from(slot)),
                    key.first_sample(quads),
                    self.pool.side(),
                    self.n,
                );
                // The unit's vertex flags (`stitch_local` in the shader).
                u.fine[2] = i32::from(flags);
                let s = out.ranges.len();
                if s >= calls {
                    return Err(too_many_calls());
                }
                out.slots[s * SLOT..s * SLOT + std::mem::size_of::<DrawUniform>()]
                    .copy_from_slice(bytemuck::bytes_of(&u));
                let indices = mesh::pool_unit_range(quads, m);
                let instances = count[mi];
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
                        cells: to_u32(start)..to_u32(start + instances),
                    })
                    .map_err(|_| too_many_calls())?;
                start += instances;
            }
            i = j;
        }
        out.stitched_hash = h.finish();
        Ok(triangles)
    }
}
