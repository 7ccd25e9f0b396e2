//! Stage 2, the per-frame plan: the refinement's coverage invariant, checked in debug builds. A refined
//! block is drawn from its cells alone, with ghosts standing for its parts out of view, so together they
//! must cover the block minus the finer ring's hole exactly once: a gap is a hole in the terrain, an
//! overlap a z-fighting seam.

use super::{level0_box, Quadtree};
use crate::plan::cull;
use crate::plan::frame::Rect;

impl Quadtree {
    /// Asserts (debug builds only) that the cells and ghosts of every refined block cover its pieces
    /// once: their quads sum to the pieces' and no two of them share a quad.
    pub(super) fn debug_check_cover(&self) {
        if !cfg!(debug_assertions) {
            return;
        }
        // Level-0 quads under vertex rectangle `r` of `level`.
        let quads = |level: u32, r: &Rect| -> u64 {
            (u64::from(r.w.saturating_sub(1)) * u64::from(r.h.saturating_sub(1))) << (2 * level)
        };
        for c in self.cands.iter().filter(|c| c.refined) {
            let k = &c.key;
            let want: u64 = cull::block_pieces(&k.rect, &k.hole)
                .iter()
                .map(|p| quads(k.ring, p))
                .sum();
            let parts = self
                .cells
                .iter()
                .filter(|x| x.block == c.block)
                .map(|x| (x.key.level, x.bounds))
                .chain(
                    self.ghosts
                        .iter()
                        .filter(|g| g.block == c.block)
                        .map(|g| (g.level, g.bounds)),
                );
            let have: u64 = parts.clone().map(|(l, r)| quads(l, &r)).sum();
            assert_eq!(
                have, want,
                "block {} ({k:?}): its cells and ghosts cover {have} of its {want} quads",
                c.block
            );
            for (i, (la, a)) in parts.clone().enumerate() {
                let a0 = level0_box(la, &a);
                for (lb, b) in parts.clone().skip(i + 1) {
                    let b0 = level0_box(lb, &b);
                    let overlap =
                        a0.0.max(b0.0) < a0.2.min(b0.2) && a0.1.max(b0.1) < a0.3.min(b0.3);
                    assert!(!overlap, "block {}: cells {la} {a:?} and {lb} {b:?} overlap", c.block);
                }
            }
        }
    }
}
