//! Stage 2, the per-frame plan: one split of the detail pool's refinement. A clamped block is covered by
//! the cells of the next finer level, a cell by its four quarters; a part whose bound one level coarser
//! already meets epsilon stays there, and a part that misses it may be cut smaller ([`emit`]). Parts out
//! of the view are kept as ghosts (not drawn, no tile), to be covered when they come into view.

use super::memo::Asker;
use super::{double, level0_box, Cand, Cell, Ghost, GhostKind, Scratch};
use crate::plan::detail::{stitch, DetailView, TileKey};
use crate::plan::frame::Rect;
use crate::plan::lod::LodFrame;
use crate::Result;

/// What a split asked: it fits the scratch, it does not, or the frame's refinement budget ran out
/// before it was known (nothing is kept of it but its bounds, in the memo).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    Room,
    Full,
    Budget,
}

/// The shape of a split's cells: tile quads, the smallest cut, and whether they are drawn stitched
/// ([`crate::plan::detail::DetailBudget::stitch`]; their units are asked by the caller, `grow.rs`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Shape {
    pub(super) quads: u32,
    /// The smallest piece a part is cut into, in quads of the finer level.
    pub(super) min_quads: u32,
    pub(super) stitch: bool,
}

/// Whose cells a split makes, and at which (finer) level.
pub(super) struct Piece {
    pub(super) block: u16,
    pub(super) wanted: u32,
    pub(super) level: u32,
    pub(super) shape: Shape,
}

/// The cell over `r` (vertices of `level`) in the tile of `level` holding it (its units not asked).
pub(super) fn cell_at(at: &Piece, level: u32, r: Rect, bound: f64) -> Cell {
    let q = i64::from(at.shape.quads);
    Cell {
        block: at.block,
        key: TileKey {
            level,
            cx: r.x0.div_euclid(q),
            cy: r.y0.div_euclid(q),
        },
        bounds: r,
        bound,
        wanted: at.wanted,
        frozen: false,
        hidden: false,
        coarse: [0; stitch::MAX_UNITS as usize],
        coarse_bound: 0.0,
        unseen: [0; stitch::MAX_UNITS as usize],
        masked: !at.shape.stitch,
        view: 0,
        scale: 0.0,
        cap: [f64::INFINITY; 4],
        coarse_cap: [0.0; 4],
        proof: (f64::INFINITY, f64::INFINITY),
        met: false,
    }
}

/// The even cut of `lo..=hi` (vertices) into two halves of at least `min` quads each, if any.
fn cut(lo: i64, hi: i64, min: i64) -> Option<i64> {
    let mid = lo + (((hi - lo) / 2) & !1);
    (mid - lo >= min && hi - mid >= min).then_some(mid)
}

/// The same vertices one level coarser (`r`'s corners are even: exact).
pub(super) fn halve(r: &Rect) -> Rect {
    Rect::from_bounds(
        r.x0 >> 1,
        r.y0 >> 1,
        ((r.x1() - 1) >> 1) + 1,
        ((r.y1() - 1) >> 1) + 1,
    )
}

/// Writes block `c`'s split into `new`: the visible cells of level `c.clamped - 1` over the block's piece
/// (each through [`emit`]), the others as ghosts.
pub(super) fn split_block(
    new: &mut Scratch,
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    lod: &LodFrame,
    c: &Cand,
    shape: Shape,
) -> Result<Outcome> {
    let b = lod.blocks[usize::from(c.block)];
    let mut out = Outcome::Room;
    view.cells(&b, c.clamped - 1, shape.quads, |key, fine, visible| {
        if !visible {
            out = ghost(new, c.block, c.wanted, key.level, fine);
            return Ok(out == Outcome::Room);
        }
        let at = Piece {
            block: c.block,
            wanted: c.wanted,
            level: key.level,
            shape,
        };
        out = emit(new, view, ask, &at, fine);
        Ok(out == Outcome::Room)
    })?;
    Ok(out)
}

/// Writes cell `p`'s split into `new`: its four quarters one level finer (each through [`emit`]), the
/// ones out of view as ghosts.
pub(super) fn split_cell(
    new: &mut Scratch,
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    p: &Cell,
    shape: Shape,
) -> Outcome {
    let q = i64::from(shape.quads);
    let (k, pw) = (p.key.level - 1, double(&p.bounds));
    for dy in 0..2 {
        for dx in 0..2 {
            let (cx, cy) = (2 * p.key.cx + dx, 2 * p.key.cy + dy);
            let cell = Rect::from_bounds(cx * q, cy * q, (cx + 1) * q + 1, (cy + 1) * q + 1);
            let fine = cell.intersect(&pw);
            if fine.w < 2 || fine.h < 2 {
                continue;
            }
            let out = if view.visible(k, &fine) {
                let at = Piece {
                    block: p.block,
                    wanted: p.wanted,
                    level: k,
                    shape,
                };
                emit(new, view, ask, &at, fine)
            } else {
                ghost(new, p.block, p.wanted, k, fine)
            };
            if out != Outcome::Room {
                return out;
            }
        }
    }
    Outcome::Room
}

/// Writes what covers ghost `g` (now in view) into `new`: the part of a split it stands for, through
/// [`emit`], or the cell that left the view, as it was (its bound and units asked again).
pub(super) fn resolve_ghost(
    new: &mut Scratch,
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    g: &Ghost,
    shape: Shape,
) -> Outcome {
    let at = Piece {
        block: g.block,
        wanted: g.wanted,
        level: g.level,
        shape,
    };
    match g.kind {
        GhostKind::Part => emit(new, view, ask, &at, g.bounds),
        GhostKind::Cell => {
            let bx = level0_box(g.level, &g.bounds);
            let Some(bound) = ask.ranked(g.level, bx) else {
                return Outcome::Budget;
            };
            push(new, cell_at(&at, g.level, g.bounds, bound))
        }
    }
}

/// Pushes a ghost for part `fine` of level `level` onto `new`.
fn ghost(new: &mut Scratch, block: u16, wanted: u32, level: u32, fine: Rect) -> Outcome {
    let g = Ghost {
        block,
        wanted,
        level,
        bounds: fine,
        kind: GhostKind::Part,
        visible: false,
        frozen: false,
    };
    if new.ghosts.push(g).is_ok() {
        Outcome::Room
    } else {
        Outcome::Full
    }
}

fn push(new: &mut Scratch, c: Cell) -> Outcome {
    if new.cells.push(c).is_ok() {
        Outcome::Room
    } else {
        Outcome::Full
    }
}

/// Pushes the cells that draw `fine` (vertices of `at.level`, even corners, inside one tile cell) onto
/// `new`: one cell one level coarser (half the vertices, a quarter of the triangles) where that level's
/// bound already meets epsilon over it; else, when some quarter of it (halves cut on even vertices, at
/// least `min_quads` quads) would meet it one level coarser, those quarters each the same way (the ones
/// out of view as ghosts); else one cell at `at.level`. Every cell's bound is its own box's (an upper
/// bound, as the whole square's).
fn emit(
    new: &mut Scratch,
    view: &DetailView<'_>,
    ask: &mut Asker<'_, '_>,
    at: &Piece,
    fine: Rect,
) -> Outcome {
    let eps = view.epsilon_px;
    let coarse = at.level + 1;
    // Only whether it meets epsilon is asked: a kept cell's bound is not ranked (it is met).
    let Some(kept) = ask.bound(coarse, level0_box(at.level, &fine)) else {
        return Outcome::Budget;
    };
    if kept <= eps {
        return push(new, cell_at(at, coarse, halve(&fine), kept));
    }
    let min = i64::from(at.shape.min_quads);
    let (x1, y1) = (fine.x1() - 1, fine.y1() - 1);
    let (mx, my) = (cut(fine.x0, x1, min), cut(fine.y0, y1, min));
    if mx.is_some() || my.is_some() {
        let xs = match mx {
            Some(m) => [(fine.x0, m), (m, x1)],
            None => [(fine.x0, x1), (0, -1)],
        };
        let ys = match my {
            Some(m) => [(fine.y0, m), (m, y1)],
            None => [(fine.y0, y1), (0, -1)],
        };
        // Each part, and whether it is in view.
        let mut parts: [Option<(Rect, bool)>; 4] = [None; 4];
        let mut any = false;
        for (i, &(ya, yb)) in ys.iter().enumerate() {
            for (j, &(xa, xb)) in xs.iter().enumerate() {
                if xb <= xa || yb <= ya {
                    continue;
                }
                let r = Rect::from_bounds(xa, ya, xb + 1, yb + 1);
                if !view.visible(at.level, &r) {
                    parts[i * 2 + j] = Some((r, false));
                    continue;
                }
                let Some(b) = ask.bound(coarse, level0_box(at.level, &r)) else {
                    return Outcome::Budget;
                };
                any |= b <= eps;
                parts[i * 2 + j] = Some((r, true));
            }
        }
        if any {
            for (r, visible) in parts.into_iter().flatten() {
                let out = if visible {
                    emit(new, view, ask, at, r)
                } else {
                    ghost(new, at.block, at.wanted, at.level, r)
                };
                if out != Outcome::Room {
                    return out;
                }
            }
            return Outcome::Room;
        }
    }
    // Its bound is asked once the split is taken (`Quadtree::refine`): a split not taken needs none.
    push(new, cell_at(at, at.level, fine, f64::NAN))
}
