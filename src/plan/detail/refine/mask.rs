//! Stage 2, the per-frame plan: which units of a stitched pool cell are drawn one level coarser
//! ([`crate::plan::detail::stitch`]), tested a group of units before single units. A group's bound with
//! its error capped by the level's max pyramid is at least each unit's own bound, so a group that meets
//! epsilon has every unit meet it, and a group out of view has every unit out of view: only the groups
//! that miss are cut into quarters, down to single units, each tested as before. Most of a cell meets
//! epsilon or misses it together, so a cell of 16 x 16 units costs a few tests instead of 256. The units
//! and groups of a cell share their corners ([`CornerGrid`]), each projected once.

use super::level0_box;
use super::corners::SIDE;
use super::memo::Asker;
use crate::plan::camera::Corner;
use crate::plan::detail::{stitch, DetailView};
use crate::plan::frame::Rect;

/// A group meets epsilon when its bound is below epsilon by this factor: the bound of a unit inside it
/// is at most the group's in exact arithmetic (a larger box, a larger error), and this leaves room for
/// the roundings of the two computations (relative 1e-15).
const GROUP_MARGIN: f64 = 1.0 - 1.0e-9;

/// What [`coarse_units`] finds of a cell's units.
#[derive(Clone, Copy, Debug)]
pub(super) struct Units {
    /// The units drawn one level coarser.
    pub(super) coarse: stitch::Mask,
    /// The largest coarser bound read of the ones that meet epsilon (0 if none).
    pub(super) worst: f64,
    /// The coarse units marked because they were out of view, whose bound was not read (a later view in
    /// which they may be visible draws them fine, `carry.rs`).
    pub(super) unseen: stitch::Mask,
    /// Per quarter of the cell (`super::quarters`): the largest object-space error (metres) of the coarse
    /// units in view there one level coarser (a unit's own, or its group's: `super::object_error`),
    /// view-independent, so that its product with the quarter's scale in a later view bounds them there
    /// (`Quadtree::prove`).
    pub(super) cap: [f64; 4],
}

/// The units of a cell over `r` (vertices of `level`) drawn as one quad of the next coarser level: those
/// whose coarser bound meets epsilon (or out of view) and whose neighbours' at their sides does too
/// ([`stitch::erode`]), with what [`Units`] says of them. A cell whose corners are not on the coarser
/// lattice has none. `rough` (a moving view): groups are tested with the max pyramid's cap only and down
/// to 2 x 2 units, never unit by unit (a unit that would meet epsilon alone in a group that misses stays
/// fine: more triangles, never more error; a still view asks the units again one by one). None: the
/// frame's refinement budget ran out.
pub(super) fn coarse_units(
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    level: u32,
    r: &Rect,
    (eps, rough): (f64, bool),
) -> Option<Units> {
    let mut meets: stitch::Mask = [0; stitch::MAX_UNITS as usize];
    let even = r.x0 % 2 == 0 && r.y0 % 2 == 0 && r.w % 2 == 1 && r.h % 2 == 1;
    if !even {
        return Some(Units {
            coarse: meets,
            worst: 0.0,
            unseen: meets,
            cap: [0.0; 4],
        });
    }
    let (ua, ub) = stitch::units(r);
    let units = (ua.min(stitch::MAX_UNITS), ub.min(stitch::MAX_UNITS));
    let side = units.0.max(units.1).next_power_of_two();
    let (mut worst, mut cap) = (0.0f64, [0.0f64; 4]);
    let mut unseen: stitch::Mask = [0; stitch::MAX_UNITS as usize];
    ask.grid.begin();
    // The cell's tile, and the cell's first unit in it.
    let q = 2 * ask.etas.side as i64;
    let (cx, cy) = (r.x0.div_euclid(q), r.y0.div_euclid(q));
    let tile = ask.etas.slot(level, cx, cy);
    #[expect(clippy::cast_sign_loss, clippy::cast_possible_truncation, reason = "inside the tile")]
    let first = (((r.x0 - cx * q) / 2) as usize, ((r.y0 - cy * q) / 2) as usize);
    let mut g = Groups {
        view,
        level,
        r,
        eps,
        units,
        halves: (ua / 2, ub / 2),
        tile: (tile, first),
        rough,
        meets: &mut meets,
        worst: &mut worst,
        cap: &mut cap,
        unseen: &mut unseen,
    };
    g.test(ask, 0, 0, side)?;
    let coarse = stitch::erode(&meets, ua, ub);
    for (u, c) in unseen.iter_mut().zip(&coarse) {
        *u &= c;
    }
    Some(Units {
        coarse,
        worst,
        unseen,
        cap,
    })
}

/// One cell's group tests.
struct Groups<'a, 'v> {
    view: &'a DetailView<'v>,
    level: u32,
    r: &'a Rect,
    eps: f64,
    units: (u32, u32),
    /// The cell's tile slot in [`UnitEtas`] and its first unit there.
    tile: (usize, (usize, usize)),
    /// Groups only, capped by the max pyramid, down to 2 x 2 units ([`coarse_units`]).
    rough: bool,
    meets: &'a mut stitch::Mask,
    worst: &'a mut f64,
    /// The cell's halves in units (`super::quarters`: 0, not cut).
    halves: (u32, u32),
    /// The largest object-space error the marked units' bounds projected, per quarter ([`Units::cap`]).
    cap: &'a mut [f64; 4],
    /// The units marked out of view ([`coarse_units`]).
    unseen: &'a mut stitch::Mask,
}

impl Groups<'_, '_> {
    /// The level-0 lattice vertex of unit corner (a, b).
    fn vertex(&self, a: u32, b: u32) -> (i64, i64) {
        (
            (self.r.x0 + 2 * i64::from(a)) << self.level,
            (self.r.y0 + 2 * i64::from(b)) << self.level,
        )
    }

    /// The eight corners of the box from unit corner (a0, b0) to (a1, b1).
    fn corners(&self, ask: &mut Asker<'_, '_>, (a0, b0): (u32, u32), (a1, b1): (u32, u32)) -> [Corner; 8] {
        let mut out = [Corner::default(); 8];
        for (k, (a, b)) in [(a0, b0), (a1, b0), (a0, b1), (a1, b1)].into_iter().enumerate() {
            let i = b as usize * SIDE + a as usize;
            let stamp = ask.grid.stamp;
            if ask.grid.at[i].0 != stamp {
                let (x, y) = self.vertex(a, b);
                let lod = ask.bounds.lod;
                let v = &ask.bounds.view;
                ask.grid.at[i] = (stamp, [lod.corner(v, x, y, false), lod.corner(v, x, y, true)]);
            }
            let [lo, hi] = ask.grid.at[i].1;
            out[k] = lo;
            out[k + 4] = hi;
        }
        out
    }

    /// The level-0 lattice box of unit (a, b).
    fn unit_box(&self, a: u32, b: u32) -> (i64, i64, i64, i64) {
        let (x, y) = (self.r.x0 + 2 * i64::from(a), self.r.y0 + 2 * i64::from(b));
        level0_box(self.level, &Rect::from_bounds(x, y, x + 3, y + 3))
    }

    /// The largest error of units [a0, a1) x [b0, b1) one level coarser (each read once per tile,
    /// [`UnitEtas`]); None when the budget ran out.
    fn cap(&self, ask: &mut Asker<'_, '_>, (a0, b0): (u32, u32), (a1, b1): (u32, u32)) -> Option<f64> {
        let (slot, (fa, fb)) = self.tile;
        let mut m = 0.0f64;
        for b in b0..b1 {
            for a in a0..a1 {
                let e = ask.unit_eta(self.level + 1, self.unit_box(a, b), (slot, (fa + a as usize, fb + b as usize)))?;
                m = m.max(e);
            }
        }
        Some(m)
    }

    /// Marks the units of group (a0.., b0..) of `side` units a side that meet epsilon one level coarser.
    fn test(&mut self, ask: &mut Asker<'_, '_>, a0: u32, b0: u32, side: u32) -> Option<()> {
        let (ua, ub) = self.units;
        if a0 >= ua || b0 >= ub {
            return Some(());
        }
        let (a1, b1) = ((a0 + side).min(ua), (b0 + side).min(ub));
        let x = |a: u32| self.r.x0 + 2 * i64::from(a);
        let y = |b: u32| self.r.y0 + 2 * i64::from(b);
        let g = Rect::from_bounds(x(a0), y(b0), x(a1) + 1, y(b1) + 1);
        if !self.view.visible(self.level, &g) {
            mark(self.unseen, a0, b0, a1, b1);
            mark(self.meets, a0, b0, a1, b1);
            return Some(());
        }
        let bx = level0_box(self.level, &g);
        if side == 1 {
            // One unit: its own bound, as every unit was tested before groups.
            let corners = self.corners(ask, (a0, b0), (a1, b1));
            let (slot, (fa, fb)) = self.tile;
            let at = (slot, (fa + a0 as usize, fb + b0 as usize));
            let v = ask.unit(self.level + 1, bx, &corners, at)?;
            if v <= self.eps {
                // Its error, read by `unit` and kept: no evaluation.
                let e = ask.unit_eta(self.level + 1, bx, at)?;
                self.marked(v, e, (a0, b0, a1, b1));
            }
            return Some(());
        }
        let corners = self.corners(ask, (a0, b0), (a1, b1));
        // First the error capped by the max pyramid (no unit read), then by the units' own errors.
        let v = ask.group(self.level + 1, bx, &corners)?;
        if v <= self.eps * GROUP_MARGIN {
            // An error that bounds its units' (a table read, no projection): at most the one it projected.
            let e = super::object_error(ask.bounds, self.level + 1, bx);
            self.marked(v, e, (a0, b0, a1, b1));
            return Some(());
        }
        if self.rough {
            if side <= 2 {
                return Some(());
            }
        } else {
            let cap = self.cap(ask, (a0, b0), (a1, b1))?;
            let v = ask.capped(self.level + 1, bx, &corners, cap)?;
            if v <= self.eps * GROUP_MARGIN {
                self.marked(v, cap, (a0, b0, a1, b1));
                return Some(());
            }
        }
        let h = side / 2;
        for (da, db) in [(0, 0), (h, 0), (0, h), (h, h)] {
            self.test(ask, a0 + da, b0 + db, h)?;
        }
        Some(())
    }

    /// Marks units [a0, a1) x [b0, b1), in view, as drawn one level coarser: their bound `v` projected
    /// the error `eta`.
    fn marked(&mut self, v: f64, eta: f64, (a0, b0, a1, b1): (u32, u32, u32, u32)) {
        *self.worst = self.worst.max(v);
        let (x, y) = (halves(a0, a1, self.halves.0), halves(b0, b1, self.halves.1));
        for (i, cap) in self.cap.iter_mut().enumerate() {
            if x[i & 1] && y[i >> 1] {
                *cap = cap.max(eta);
            }
        }
        self.mark(a0, b0, a1, b1);
    }

    /// Marks units [a0, a1) x [b0, b1) as drawn one level coarser.
    fn mark(&mut self, a0: u32, b0: u32, a1: u32, b1: u32) {
        mark(self.meets, a0, b0, a1, b1);
    }
}

/// Sets the bits of units [a0, a1) x [b0, b1) in `m`.
fn mark(m: &mut stitch::Mask, a0: u32, b0: u32, a1: u32, b1: u32) {
    let bits = if a1 - a0 >= 32 {
        u32::MAX
    } else {
        ((1u32 << (a1 - a0)) - 1) << a0
    };
    for row in &mut m[b0 as usize..b1 as usize] {
        *row |= bits;
    }
}

/// Which halves of a cell's side (`super::quarters`, cut after `h` units; 0: not cut, both halves are the
/// whole side) hold units [a0, a1): each unit lies wholly in one of those flagged.
fn halves(a0: u32, a1: u32, h: u32) -> [bool; 2] {
    [h == 0 || a0 < h, h == 0 || a1 > h]
}

#[cfg(test)]
mod tests {
    use super::{halves, stitch};
    use super::super::quarters;
    use crate::plan::frame::Rect;

    /// Every unit of a cell lies in a quarter whose coarse cap it is counted in, and the quarters cover
    /// the cell: what makes a cell's proven bound a bound (`Quadtree::prove`).
    #[test]
    fn a_cells_units_lie_in_the_quarters_they_are_counted_in() {
        for level in [0, 3] {
            for x0 in [-6i64, 0, 2, 34] {
                for w in 2..=35u32 {
                    let r = Rect { x0, y0: 0, w, h: w };
                    let q = quarters(level, &r);
                    let (ua, _) = stitch::units(&r);
                    let (xl, yl) = ((r.x1() - 1) << level, (r.y1() - 1) << level);
                    assert_eq!((q[0].0, q[1].2, q[0].1, q[2].3), (x0 << level, xl, 0, yl), "{w}");
                    assert!(q[0].2 >= q[1].0 && q[0].3 >= q[2].1, "{w}: the halves leave a gap");
                    for a in 0..ua {
                        let (lo, hi) = ((x0 + 2 * i64::from(a)) << level, (x0 + 2 * i64::from(a) + 2) << level);
                        let ok = halves(a, a + 1, ua / 2)
                            .into_iter()
                            .zip([q[0], q[1]])
                            .any(|(f, b)| f && b.0 <= lo && hi <= b.2);
                        assert!(ok, "width {w}, unit {a}: in no half it is counted in");
                    }
                }
            }
        }
    }
}
