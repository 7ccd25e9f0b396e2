//! Stage 2, the per-frame plan: how the detail pool's quadtrees carry over from one frame to the next.
//! While the view, the clamped blocks and the budgets are the same as the last frame's, the refinement
//! takes up where it stopped (a still camera converges to the refinement of one unbounded frame). When
//! they change, the last frame's quadtrees are the start: a block keeps its cells while it stays clamped
//! with the same rectangle and hole, a cell that left the view becomes a ghost, a ghost that came into
//! view is covered first, a stale cell counts as meeting epsilon only where its object-space caps
//! projected in the new view prove it (else it is asked again, or its proven bound reported), and blocks
//! are let go, least needed first, until what is kept fits this frame's budgets.

use super::{Cand, Ghost, GhostKind, Inputs, Quadtree, NONE};
use super::{BlockKey, Cell};
use crate::hash::Hash64;
use crate::plan::cull;
use crate::plan::detail::{stitch, DetailView, PoolBounds};
use crate::plan::frame::Rect;
use crate::plan::lod::MAX_LOD_BLOCKS;
use crate::{Error, Result};

impl Quadtree {
    /// Starts this frame's refinement from the last frame's quadtrees (see the module doc), in the view of
    /// `bounds`: this frame's, whose key is `frame_key`, or the last frame's when it lags ([`super::Lag`]).
    pub(super) fn carry(
        &mut self,
        at: &Inputs<'_, '_>,
        bounds: &PoolBounds<'_>,
        frame_key: u64,
        ring_triangles: &[u64],
    ) -> Result<()> {
        let view = at.view;
        let eps = view.epsilon_px;
        // A new viewport starts the refinement again (its screen scale is another): coarse and valid
        // at once, as after a jump.
        let viewport = bounds.lod.viewport();
        if self.viewport != viewport {
            self.viewport = viewport;
            self.cands.clear();
            self.cells.clear();
            self.ghosts.clear();
            self.inputs = None;
            self.mark = None;
        }
        // A lagging frame's bounds are the last view's (the memo keeps them), but its frustum is new.
        let fresh_view = !self.lagging && (self.inputs.is_none() || bounds.key != self.view_key);
        let new_frustum = fresh_view || self.lagging;
        // The first view is not a move: its refinement is the one-frame refinement, spread over frames.
        self.moved = self.lagging || (fresh_view && self.inputs.is_some());
        if fresh_view {
            self.view = self.view.wrapping_add(1).max(1);
            self.view_key = bounds.key;
            self.memo.next();
        }
        let b = at.budget;
        let mut h = Hash64::new();
        h.write_u64(frame_key);
        h.write_u64(eps.to_bits());
        for v in [u64::from(b.draws), b.triangles, u64::from(b.margin), u64::from(b.block_quads)] {
            h.write_u64(v);
        }
        h.write_u64(b.instances as u64);
        h.write_u64(u64::from(b.stitch) | u64::from(b.skirts) << 1);
        h.write_u64(u64::from(at.quads));
        h.write_u64(at.slots as u64);
        // This frame's clamped blocks.
        self.next.clear();
        if at.slots > 0 {
            for (i, bl) in at.lod.blocks.iter().enumerate() {
                if !(bl.wanted < bl.level && bl.wanted < bl.ring) {
                    continue;
                }
                let hole = match bl.ring.checked_sub(1) {
                    Some(fl) => cull::hole(&view.frame.levels[fl as usize].active),
                    None => Rect::EMPTY,
                };
                let c = Cand {
                    block: u16::try_from(i).expect("blocks <= MAX_LOD_BLOCKS"),
                    key: BlockKey {
                        ring: bl.ring,
                        rect: bl.rect,
                        hole: hole.intersect(&bl.rect),
                    },
                    clamped: bl.level,
                    wanted: bl.wanted,
                    bound: f64::from(bl.bound_px),
                    need: f64::from(bl.bound_px) / eps,
                    credit: ring_triangles.get(i).copied().unwrap_or(0),
                    refined: false,
                    frozen: false,
                    hidden: false,
                    scale: 0.0,
                    whole: None,
                };
                for v in [u64::from(c.block), u64::from(c.key.ring), u64::from(c.clamped)] {
                    h.write_u64(v);
                }
                for r in [c.key.rect, c.key.hole] {
                    h.write_i64(r.x0);
                    h.write_i64(r.y0);
                    h.write_u32(r.w);
                    h.write_u32(r.h);
                }
                h.write_u64(u64::from(c.wanted));
                h.write_u64(c.credit);
                h.write_u64(c.bound.to_bits());
                self.next.push(c).map_err(|_| Error::Capacity {
                    what: "clamped blocks",
                    capacity: MAX_LOD_BLOCKS,
                })?;
            }
        }
        let inputs = h.finish();
        if self.inputs == Some(inputs) {
            // The same frame again, as far as the refinement can tell: take up where it stopped.
            return Ok(());
        }
        self.inputs = Some(inputs);
        self.rematch(new_frustum);
        self.rescale(at, bounds);
        if new_frustum {
            self.review(at);
        }
        self.prove(bounds, eps);
        self.recount(at);
        self.shed(at);
        self.debug_check_cover();
        // Units frozen for want of room are tried again once more is left than when the last one froze.
        if let Some(m) = self.mark {
            let f = self.free(at);
            if f.0 > m.0 || f.1 > m.1 || f.2 > m.2 || f.3 > m.3 {
                self.thaw();
            }
        }
        Ok(())
    }

    /// Lets every frozen unit be tried again.
    fn thaw(&mut self) {
        self.mark = None;
        for c in self.cands.iter_mut() {
            c.frozen = false;
        }
        for c in self.cells.iter_mut() {
            c.frozen = false;
        }
        for g in self.ghosts.iter_mut() {
            g.frozen = false;
        }
        self.seen_ghosts = self.ghosts.iter().any(|g| g.visible);
    }

    /// Each clamped block's scale in the view of `bounds` ([`Cand::scale`], [`Cand::whole`]).
    fn rescale(&mut self, at: &Inputs<'_, '_>, bounds: &PoolBounds<'_>) {
        for k in 0..self.cands.len() {
            let bl = &at.lod.blocks[usize::from(self.cands[k].block)];
            let s = bounds.box_scale(super::level0_box(bl.ring, &bl.rect));
            (self.cands[k].scale, self.cands[k].whole) = (s.per_metre(), Some(s));
        }
    }

    /// After a lagging frame's refinement ([`super::Lag`]): moves to this frame's view (`own`). Every bound
    /// asked so far is now stale: what its caps prove in this view holds ([`Quadtree::prove`]).
    pub(super) fn catch_up(&mut self, at: &Inputs<'_, '_>, own: &PoolBounds<'_>) {
        self.view = self.view.wrapping_add(1).max(1);
        self.view_key = own.key;
        self.memo.next();
        self.rescale(at, own);
        self.prove(own, at.view.epsilon_px);
    }

    /// Matches this frame's blocks (`self.next`) with the last frame's by [`BlockKey`]: a match keeps
    /// its refinement, its cells and ghosts move to the block's new index; the others' are dropped.
    fn rematch(&mut self, fresh_view: bool) {
        for c in self.cands.iter() {
            self.remap[usize::from(c.block)] = NONE;
        }
        for n in self.next.iter_mut() {
            if let Some(o) = self.cands.iter().find(|o| o.key == n.key) {
                n.refined = o.refined;
                n.frozen = o.frozen;
                n.hidden = o.hidden && !fresh_view;
                self.remap[usize::from(o.block)] = n.block;
            }
        }
        core::mem::swap(&mut self.cands, &mut self.next);
        for c in self.next.iter() {
            self.cand_of[usize::from(c.block)] = NONE;
        }
        for (k, c) in self.cands.iter().enumerate() {
            self.cand_of[usize::from(c.block)] = u16::try_from(k).expect("cands <= MAX_LOD_BLOCKS");
        }
        let (remap, cands, cand_of) = (&self.remap, &self.cands, &self.cand_of);
        let moved = |block: u16| -> Option<(u16, u32)> {
            let n = remap[usize::from(block)];
            let k = *cand_of.get(usize::from(n))?;
            cands.get(usize::from(k)).map(|c| (n, c.wanted))
        };
        retain(&mut self.cells, |c: &mut Cell| match moved(c.block) {
            Some((n, wanted)) => {
                (c.block, c.wanted) = (n, wanted);
                c.hidden &= !fresh_view;
                true
            }
            None => false,
        });
        retain(&mut self.ghosts, |g: &mut Ghost| match moved(g.block) {
            Some((n, wanted)) => {
                (g.block, g.wanted) = (n, wanted);
                true
            }
            None => false,
        });
        // The last frame's indices are stale now.
        for c in self.next.iter() {
            self.remap[usize::from(c.block)] = NONE;
        }
    }

    /// A new view: cells that left it become ghosts (their tiles and triangles free), ghosts say whether
    /// they are in it, and a stitched cell whose units drawn coarse because they were out of view may be
    /// in it draws them fine ([`super::Cell::unseen`]: no bound was read of them; fine, they are within
    /// the cell's own bound) until its units are asked again.
    fn review(&mut self, at: &Inputs<'_, '_>) {
        let view = at.view;
        let mut j = 0;
        while j < self.cells.len() {
            let c = self.cells[j];
            if view.visible(c.key.level, &c.bounds) || self.ghosts.is_full() {
                if stitch::any(&c.unseen) {
                    if let Some((coarse, unseen)) = come_into_view(&c, view) {
                        self.cells[j] = Cell {
                            coarse,
                            unseen,
                            masked: false,
                            ..c
                        };
                    }
                }
                j += 1;
                continue;
            }
            let g = Ghost {
                block: c.block,
                wanted: c.wanted,
                level: c.key.level,
                bounds: c.bounds,
                kind: GhostKind::Cell,
                visible: false,
                frozen: false,
            };
            self.ghosts.push(g).expect("checked: not full");
            self.cells.remove(j);
        }
        for g in self.ghosts.iter_mut() {
            g.visible = view.visible(g.level, &g.bounds);
        }
        self.seen_ghosts = self.ghosts.iter().any(|g| g.visible && !g.frozen);
    }

    /// Counts what the cells take (tiles, draws, records) and what is left of the frame's draws and
    /// triangles; a refined block with nothing left of its quadtree is not refined.
    fn recount(&mut self, at: &Inputs<'_, '_>) {
        self.keys.clear();
        self.groups.clear();
        self.instances = 0;
        let mut has = [false; MAX_LOD_BLOCKS];
        let mut grouped = true;
        for c in self.cells.iter() {
            has[usize::from(c.block)] = true;
            self.instances += c.instances();
            grouped &= self.keys.count_in(c.key) && super::grow::count_in(&mut self.groups, super::grow::group(c));
        }
        for g in self.ghosts.iter() {
            has[usize::from(g.block)] = true;
        }
        let b = at.budget;
        let mut draws = i64::from(b.draws) - i64::try_from(self.groups.len()).unwrap_or(i64::MAX);
        let mut triangles = u128::from(b.triangles);
        for c in self.cands.iter_mut() {
            c.refined &= has[usize::from(c.block)];
            if c.refined {
                draws -= i64::from(b.margin);
                triangles += u128::from(c.credit);
            }
        }
        let used: u128 = self.cells.iter().map(|c| u128::from(c.triangles(b))).sum();
        self.draws = if grouped { draws } else { -1 };
        // Past the budget: `shed` lets blocks go until it fits.
        self.triangles = u64::try_from(triangles.saturating_sub(used)).unwrap_or(u64::MAX);
        if used > triangles {
            self.draws = -1;
        }
    }

    /// Lets the least needed refined blocks go until what is kept fits this frame's budgets.
    fn shed(&mut self, at: &Inputs<'_, '_>) {
        loop {
            let over = self.draws < 0
                || self.instances > at.budget.instances
                || self.keys.len() > at.slots;
            if !over {
                return;
            }
            let least = self
                .cands
                .iter()
                .enumerate()
                .filter(|(_, c)| c.refined)
                .min_by(|(i, a), (j, b)| a.need.total_cmp(&b.need).then(j.cmp(i)))
                .map(|(k, _)| k);
            let Some(k) = least else { return };
            let block = self.cands[k].block;
            self.cands[k].refined = false;
            retain(&mut self.cells, |c: &mut Cell| c.block != block);
            retain(&mut self.ghosts, |g: &mut Ghost| g.block != block);
            self.recount(at);
        }
    }
}

/// Where some of cell `c`'s units drawn coarse while out of view ([`super::Cell::unseen`]) may be in
/// `view`: its coarse units less those (a row's at a time, the row's span of them tested) and those
/// beside them (a coarse unit beside a fine one blends into it: [`stitch::erode`]), and the ones still out
/// of view. The rest's coarser bound was read (`coarse_bound`). None where none may be in view.
fn come_into_view(c: &Cell, view: &DetailView<'_>) -> Option<(stitch::Mask, stitch::Mask)> {
    let (ua, ub) = stitch::units(&c.bounds);
    let (ua, ub) = (ua.min(stitch::MAX_UNITS), ub.min(stitch::MAX_UNITS));
    let span = |b: usize, row: u32| {
        let (a0, a1) = (row.trailing_zeros(), 32 - row.leading_zeros());
        let x = |a: u32| c.bounds.x0 + 2 * i64::from(a);
        let y = c.bounds.y0 + 2 * i64::try_from(b).unwrap_or(0);
        Rect::from_bounds(x(a0), y, x(a1) + 1, y + 3)
    };
    // All rows' span first: most frames none of them is in view.
    let (mut lo, mut hi, mut any) = (u32::MAX, 0u32, 0u32);
    let (mut first, mut last) = (usize::MAX, 0usize);
    for (b, &row) in c.unseen.iter().enumerate().take(ub as usize).filter(|(_, r)| **r != 0) {
        (lo, hi, any) = (lo.min(row.trailing_zeros()), hi.max(32 - row.leading_zeros()), any | row);
        (first, last) = (first.min(b), b);
    }
    if any == 0 {
        return None;
    }
    let whole = span(first, (1u32 << lo) | (1u32 << (hi - 1)));
    let whole = Rect::from_bounds(whole.x0, whole.y0, whole.x1(), span(last, 1).y1());
    if !view.visible(c.key.level, &whole) {
        return None;
    }
    let (mut coarse, mut unseen) = (c.coarse, c.unseen);
    let mut cleared = false;
    for b in first..=last {
        let row = unseen[b];
        if row != 0 && view.visible(c.key.level, &span(b, row)) {
            coarse[b] &= !row;
            unseen[b] = 0;
            cleared = true;
        }
    }
    if !cleared {
        return None;
    }
    let coarse = stitch::erode(&coarse, ua, ub);
    for (u, k) in unseen.iter_mut().zip(&coarse) {
        *u &= k;
    }
    Some((coarse, unseen))
}

/// Keeps the entries of `v` for which `keep` says true (it may change them), in order.
fn retain<T: Copy, const N: usize>(v: &mut heapless::Vec<T, N>, mut keep: impl FnMut(&mut T) -> bool) {
    let mut w = 0;
    for r in 0..v.len() {
        let mut x = v[r];
        if keep(&mut x) {
            v[w] = x;
            w += 1;
        }
    }
    v.truncate(w);
}
