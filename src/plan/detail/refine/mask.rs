//! Stage 2, the per-frame plan: which units of a stitched pool cell are drawn one level coarser
//! ([`crate::plan::detail::stitch`]), tested a group of units before single units. A group's bound with
//! its error capped by the level's max pyramid is at least each unit's own bound, so a group that meets
//! epsilon has every unit meet it, and a group out of view has every unit out of view: only the groups
//! that miss are cut into quarters, down to single units, each tested as before. Most of a cell meets
//! epsilon or misses it together, so a cell of 16 x 16 units costs a few tests instead of 256.

use super::level0_box;
use super::memo::Asker;
use crate::plan::detail::{stitch, DetailView};
use crate::plan::frame::Rect;

/// A group meets epsilon when its bound is below epsilon by this factor: the bound of a unit inside it
/// is at most the group's in exact arithmetic (a larger box, a larger error), and this leaves room for
/// the roundings of the two computations (relative 1e-15).
const GROUP_MARGIN: f64 = 1.0 - 1.0e-9;

/// The units of a cell over `r` (vertices of `level`) drawn as one quad of the next coarser level: those
/// whose coarser bound meets epsilon (or out of view) and whose neighbours' at their sides does too
/// ([`stitch::erode`]), with the largest coarser bound read of the ones that meet it (0 if none: what a
/// later view rescales to see whether the mask still holds). None when `r`'s corners are not on the
/// coarser lattice gives no coarse unit. None: the frame's refinement budget ran out.
pub(super) fn coarse_units(
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    level: u32,
    r: &Rect,
    eps: f64,
) -> Option<(stitch::Mask, f64)> {
    let mut meets: stitch::Mask = [0; stitch::MAX_UNITS as usize];
    let even = r.x0 % 2 == 0 && r.y0 % 2 == 0 && r.w % 2 == 1 && r.h % 2 == 1;
    if !even {
        return Some((meets, 0.0));
    }
    let (ua, ub) = stitch::units(r);
    let units = (ua.min(stitch::MAX_UNITS), ub.min(stitch::MAX_UNITS));
    let side = units.0.max(units.1).next_power_of_two();
    let mut worst = 0.0f64;
    let mut g = Groups {
        view,
        level,
        r,
        eps,
        units,
        meets: &mut meets,
        worst: &mut worst,
    };
    g.test(ask, 0, 0, side)?;
    Some((stitch::erode(&meets, ua, ub), worst))
}

/// One cell's group tests.
struct Groups<'a, 'v> {
    view: &'a DetailView<'v>,
    level: u32,
    r: &'a Rect,
    eps: f64,
    units: (u32, u32),
    meets: &'a mut stitch::Mask,
    worst: &'a mut f64,
}

impl Groups<'_, '_> {
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
        let bx = level0_box(self.level, &g);
        if side == 1 {
            // One unit: its own bound, as every unit was tested before groups.
            if !self.view.visible(self.level, &g) {
                self.mark(a0, b0, a1, b1);
                return Some(());
            }
            let v = ask.bound(self.level + 1, bx, false)?;
            if v <= self.eps {
                *self.worst = self.worst.max(v);
                self.mark(a0, b0, a1, b1);
            }
            return Some(());
        }
        if !self.view.visible(self.level, &g) {
            self.mark(a0, b0, a1, b1);
            return Some(());
        }
        let v = ask.group(self.level + 1, bx)?;
        if v <= self.eps * GROUP_MARGIN {
            *self.worst = self.worst.max(v);
            self.mark(a0, b0, a1, b1);
            return Some(());
        }
        let h = side / 2;
        for (da, db) in [(0, 0), (h, 0), (0, h), (h, h)] {
            self.test(ask, a0 + da, b0 + db, h)?;
        }
        Some(())
    }

    /// Marks units [a0, a1) x [b0, b1) as meeting epsilon one level coarser.
    fn mark(&mut self, a0: u32, b0: u32, a1: u32, b1: u32) {
        let bits = if a1 - a0 >= 32 {
            u32::MAX
        } else {
            ((1u32 << (a1 - a0)) - 1) << a0
        };
        for row in &mut self.meets[b0 as usize..b1 as usize] {
            *row |= bits;
        }
    }
}
