//! Measurements: a lower bound on what any refinement of a frame needs to meet the screen-space error bound
//! in the measured metric of [`crate::measure::screen_error`] (the whole-frame error the detail pool is held to). Not the frame
//! path: it reads the whole pyramid.
//!
//! The oracle draws the terrain with pyramid quads only: a quad of data level k covers the closed samples
//! [i 2^k, (i + 1) 2^k] x [j 2^k, (j + 1) 2^k], and its two triangles are level k's piecewise-linear surface
//! there (docs/design.md "SAT LOD" 1), so its error at each sample is e_k exactly, whatever its neighbours are.
//! From the coarsest baked level down, a quad is kept when its largest measured error over its in-frustum
//! samples, [`crate::plan::camera::VerticalScale::px`] of e_k at the sample, is <= epsilon, and split into
//! its four children otherwise. Splitting never makes fewer triangles, so the kept quads are the fewest
//! triangles any triangulation made of pyramid quads can have. The renderer draws m x m quads of one level
//! per block or pool cell, plus skirts, so it needs at least this many. Quads outside the frustum cost
//! nothing here.
//!
//! [`bound_oracle`] runs the same descent with a LOD bound ([`crate::plan::lod::Lod::box_bound_px`] of each
//! quad) in place of the measured error: what a refinement that decides each quad by the bound would need.
//! Its distance from [`oracle`] is the bound's cost; the renderer's distance from it is the cost of
//! deciding whole cells and pieces instead of quads.
//!
//! Kept quads at a level whose ring does not hold them (outside that ring's clip region) need pool tiles:
//! their distinct tile cells (`detail_tile_quads` quads a side) are a lower bound on the pool's tiles for
//! a pool whose tiles are those cells.

use crate::bake::lod_tables::sample_error;
use crate::plan::camera::px_of_parts;
use crate::plan::camera::Camera;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull;
use crate::plan::frame::Rect;
use crate::plan::lod::{Lod, LodMode};

use super::stitch;

/// What the oracle needs to meet epsilon ([`oracle`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Oracle {
    /// The bound, pixels.
    pub epsilon_px: f64,
    /// Triangles of the kept quads (two each).
    pub triangles: u64,
    /// Kept quads per clipmap level (finest first).
    pub quads_per_level: Vec<u64>,
    /// Kept quads outside their level's ring clip region (the pool must hold them).
    pub quads_outside_rings: u64,
    /// Distinct pool tile cells those quads lie in (each drawn at its own level).
    pub pool_tiles: u64,
    /// The fewest pool tiles that hold those quads when any of them may also be drawn finer (at any level
    /// down to the data) or in pieces from several tiles: a lower bound on the slots of any
    /// pool of `detail_tile_quads`-quad cells that draws no place coarser than its oracle level.
    pub pool_tiles_min: u64,
    /// Triangles of the kept quads once balanced as a restricted quadtree (quads meeting at a side or a
    /// corner differ by at most one level, split where they do not) and stitched without skirts
    /// (`measure/stitch.rs`): what a mesh that changes level per quad needs.
    pub balanced_triangles: u64,
    /// Of those, the triangles the stitching collapses to a segment (still drawn, so still counted).
    pub degenerate_triangles: u64,
    /// The same descent at the grain of 2 x 2-quad fans ([`FanGrain`]).
    pub fan: FanGrain,
}

/// What a mesh of 2 x 2-quad fans needs ([`oracle`]'s descent at that grain): each node is a quad of
/// level k >= 1 drawn as the 2 x 2 quads of level k - 1 under it (8 triangles), kept when level k - 1
/// meets epsilon over the node's closed box (level 0 always does), split into its 4 children otherwise.
/// The descent starts at the quads of the coarsest level. This is the grain a restricted quadtree of fans
/// changes level at (single quads can change level too: `measure/stitch.rs`, the oracle's
/// `balanced_triangles`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FanGrain {
    /// Triangles of the kept fans (8 each).
    pub triangles: u64,
    /// Fan sides whose same-level neighbour is not kept (a level change, or the frustum's edge): what a
    /// mesh closing level changes with skirts hangs a skirt on (4 triangles a side with 2-quad sides).
    pub transition_sides: u64,
    /// Triangles once the fans are balanced (a restricted quadtree: fans meeting at a side or a corner
    /// differ by at most one level, split where they do not), which stitching a level change by
    /// dropping a midpoint needs.
    pub balanced_triangles: u64,
}

/// Per data level: the largest measured error over each closed quad's in-frustum samples (negative: no
/// sample of the quad is in the frustum).
struct LevelErrors {
    cols: usize,
    rows: usize,
    max_px: Vec<f32>,
}

impl LevelErrors {
    /// Quad (c, r)'s measured error, where it has a sample in the frustum.
    fn at(&self, (c, r): (i64, i64)) -> Option<f32> {
        let (c, r) = (usize::try_from(c).ok()?, usize::try_from(r).ok()?);
        (c < self.cols && r < self.rows)
            .then(|| self.max_px[r * self.cols + c])
            .filter(|&e| e >= 0.0)
    }
}

/// The fewest pyramid quads that meet each of `epsilons` over the frustum of `camera` in a viewport
/// `view` (width, height), and the pool tiles they need beside `clipmap`'s current rings (`tile_quads`:
/// the profile's `detail_tile_quads`). `levels`: the clipmap's levels (the coarsest quad is one of the
/// last one's). Visits every data sample once per data level.
pub fn oracle(
    clipmap: &Clipmap,
    camera: &Camera,
    view: (u32, u32),
    levels: u32,
    tile_quads: u32,
    epsilons: &[f64],
) -> Vec<Oracle> {
    descend(clipmap, camera, view, levels, tile_quads, epsilons, None)
}

/// [`oracle`] with `lod`'s bound in `mode` for each quad in the frustum ([`Lod::box_bound_px`] of the
/// quad's level-0 lattice box at its clipmap level) in place of its measured error: the fewest pyramid
/// quads a refinement deciding each quad by that bound needs.
#[expect(
    clippy::too_many_arguments,
    reason = "the oracle's inputs and the bound's"
)]
pub fn bound_oracle(
    clipmap: &Clipmap,
    camera: &Camera,
    view: (u32, u32),
    levels: u32,
    tile_quads: u32,
    epsilons: &[f64],
    lod: &Lod,
    mode: LodMode,
) -> Vec<Oracle> {
    let bound = |level: u32, bx: (i64, i64, i64, i64)| lod.box_bound_px(camera, mode, level, bx);
    descend(
        clipmap,
        camera,
        view,
        levels,
        tile_quads,
        epsilons,
        Some(&bound),
    )
}

/// A quad's error in pixels from its clipmap level and level-0 lattice box (x0, y0, x1, y1).
type QuadBound<'a> = dyn Fn(u32, (i64, i64, i64, i64)) -> f64 + 'a;

/// The descent of [`oracle`] and [`bound_oracle`]: a quad's error is its measured one, or `bound` of its
/// clipmap level and level-0 lattice box where given (quads with no sample in the frustum are skipped
/// either way; a level-0 quad is always kept).
fn descend(
    clipmap: &Clipmap,
    camera: &Camera,
    view: (u32, u32),
    levels: u32,
    tile_quads: u32,
    epsilons: &[f64],
    bound: Option<&QuadBound<'_>>,
) -> Vec<Oracle> {
    let pyr = clipmap.pyramid();
    let data = pyr.level(0);
    let (w, h) = (data.width(), data.height());
    let synth = clipmap.synth_levels();
    let spacing = clipmap.g0() * f64::from(1u32 << synth);
    let frustum = cull::Frustum::new(camera, f64::from(view.0) / f64::from(view.1));
    let scale = camera.vertical_scale(view);
    let (ox, oy) = clipmap.origin();
    let top = oy + f64::from(h - 1) * spacing;
    let data_levels = levels.saturating_sub(synth).clamp(1, 31);
    // Per sample: its measured scale (VerticalScale::parts), or negative outside the frustum.
    let mut ppm = vec![(0.0f32, 0.0f32); w as usize * h as usize];
    for y in 0..h {
        for x in 0..w {
            let z = f64::from(data.at_clamped(i64::from(x), i64::from(y)));
            let rel = glam::DVec3::new(
                ox + f64::from(x) * spacing - camera.eye.x,
                top - f64::from(y) * spacing - camera.eye.y,
                z - camera.eye.z,
            );
            #[expect(clippy::cast_possible_truncation, reason = "a scale, f32 is plenty")]
            let s = if frustum.intersects(rel, rel) {
                let (s, c) = scale.parts(rel);
                (s as f32, c as f32)
            } else {
                (-1.0, 0.0)
            };
            ppm[(y * w + x) as usize] = s;
        }
    }
    let errs: Vec<LevelErrors> = (0..data_levels)
        .map(|k| {
            let side = 1u32 << k;
            let cols = (w - 1).div_ceil(side).max(1) as usize;
            let rows = (h - 1).div_ceil(side).max(1) as usize;
            let mut max_px = vec![-1.0f32; cols * rows];
            for y in 0..h {
                for x in 0..w {
                    let (s, c) = ppm[(y * w + x) as usize];
                    if s < 0.0 {
                        continue;
                    }
                    #[expect(clippy::cast_possible_truncation, reason = "pixels, f32 is plenty")]
                    let e = if k == 0 {
                        0.0
                    } else {
                        let e = sample_error(pyr, k, i64::from(x), i64::from(y));
                        px_of_parts(f64::from(s), f64::from(c), f64::from(e)) as f32
                    };
                    // A sample on a lattice line lies in the quads on both sides of it.
                    let (ci, ri) = ((x >> k) as usize, (y >> k) as usize);
                    let on_x = x & (side - 1) == 0 && ci > 0;
                    let on_y = y & (side - 1) == 0 && ri > 0;
                    for (c, r) in [
                        (Some(ci), Some(ri)),
                        (on_x.then(|| ci - 1), Some(ri)),
                        (Some(ci), on_y.then(|| ri - 1)),
                        (on_x.then(|| ci - 1), on_y.then(|| ri - 1)),
                    ] {
                        if let (Some(c), Some(r)) = (c, r) {
                            if c < cols && r < rows {
                                let m = &mut max_px[r * cols + c];
                                *m = m.max(e);
                            }
                        }
                    }
                }
            }
            LevelErrors { cols, rows, max_px }
        })
        .collect();
    let frame = clipmap.frame();
    epsilons
        .iter()
        .map(|&eps| {
            let mut o = Oracle {
                epsilon_px: eps,
                quads_per_level: vec![0; levels as usize],
                ..Oracle::default()
            };
            let mut tiles: Vec<(u32, i64, i64)> = Vec::new();
            let mut kept: std::collections::HashSet<stitch::Node> = Default::default();
            // Pool-held quads as (level, level-0 lattice box).
            let mut needs: Vec<(u32, [i64; 4])> = Vec::new();
            let top_k = data_levels - 1;
            let t = &errs[top_k as usize];
            let mut stack: Vec<(u32, usize, usize)> = (0..t.rows)
                .flat_map(|r| (0..t.cols).map(move |c| (top_k, c, r)))
                .collect();
            while let Some((k, c, r)) = stack.pop() {
                let le = &errs[k as usize];
                let measured = le.max_px[r * le.cols + c];
                if measured < 0.0 {
                    continue;
                }
                let m = match bound {
                    Some(f) if k > 0 => {
                        let s0 = 1i64 << (k + synth);
                        let (i, j) = (c as i64, r as i64);
                        f(k + synth, (i * s0, j * s0, (i + 1) * s0, (j + 1) * s0))
                    }
                    _ => f64::from(measured),
                };
                if k == 0 || m <= eps {
                    let l = k + synth;
                    o.triangles += 2;
                    kept.insert((k as usize, c as i64, r as i64));
                    o.quads_per_level[l as usize] += 1;
                    let (i, j) = (c as i64, r as i64);
                    let clip = frame.levels.get(l as usize).map(|lf| lf.clip);
                    let held = clip.is_some_and(|cl| {
                        !cl.is_empty() && cl.contains(&Rect::from_bounds(i, j, i + 2, j + 2))
                    });
                    if !held {
                        o.quads_outside_rings += 1;
                        let q = i64::from(tile_quads.max(1));
                        tiles.push((l, i.div_euclid(q), j.div_euclid(q)));
                        let s0 = 1i64 << l;
                        needs.push((l, [i * s0, j * s0, (i + 1) * s0, (j + 1) * s0]));
                    }
                    continue;
                }
                let fine = &errs[k as usize - 1];
                for (dc, dr) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (fc, fr) = (2 * c + dc, 2 * r + dr);
                    if fc < fine.cols && fr < fine.rows {
                        stack.push((k - 1, fc, fr));
                    }
                }
            }
            o.fan = fan_grain(&errs, bound, synth, eps);
            stitch::balance(&mut kept, top_k as usize, |(k, c, r)| {
                errs[k].at((c, r)).is_some()
            });
            let stitched = stitch::stitch(&kept, top_k as usize);
            o.balanced_triangles = stitched.len() as u64;
            o.degenerate_triangles =
                stitched.iter().filter(|t| stitch::collapsed(t)).count() as u64;
            tiles.sort_unstable();
            tiles.dedup();
            o.pool_tiles = tiles.len() as u64;
            o.pool_tiles_min = min_tiles(&needs, levels.saturating_sub(1), tile_quads.max(1));
            o
        })
        .collect()
}

/// [`FanGrain`] of the descent's per-quad errors `errs` (measured, or `bound` of each node's box at its
/// drawn level where given) at `eps`.
fn fan_grain(
    errs: &[LevelErrors],
    bound: Option<&QuadBound<'_>>,
    synth: u32,
    eps: f64,
) -> FanGrain {
    let top = errs.len() - 1;
    if top == 0 {
        return FanGrain::default();
    }
    // Node (k, c, r) is quad (c, r) of level k, in the frustum where it has a sample there.
    let in_frustum = |(k, c, r): stitch::Node| errs[k].at((c, r)).is_some();
    let mut leaves: std::collections::HashSet<stitch::Node> = Default::default();
    let t = &errs[top];
    let (cols, rows) = (
        i64::try_from(t.cols).expect("a level's quads fit i64"),
        i64::try_from(t.rows).expect("a level's quads fit i64"),
    );
    let mut stack: Vec<stitch::Node> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (top, c, r)))
        .collect();
    while let Some((k, c, r)) = stack.pop() {
        if !in_frustum((k, c, r)) {
            continue;
        }
        // The error of level k - 1 over the node.
        let e = if k == 1 {
            0.0
        } else if let Some(f) = bound {
            let l = u32::try_from(k).expect("levels <= 31") + synth;
            let s0 = 1i64 << l;
            f(l - 1, (c * s0, r * s0, (c + 1) * s0, (r + 1) * s0))
        } else {
            stitch::children((k, c, r))
                .filter_map(|(j, a, b)| errs[j].at((a, b)))
                .fold(0.0f64, |m, e| m.max(f64::from(e)))
        };
        if e <= eps {
            leaves.insert((k, c, r));
        } else {
            stack.extend(stitch::children((k, c, r)));
        }
    }
    let mut out = FanGrain {
        triangles: 8 * leaves.len() as u64,
        ..FanGrain::default()
    };
    for &(k, c, r) in &leaves {
        for (dc, dr) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
            if !leaves.contains(&(k, c + dc, r + dr)) {
                out.transition_sides += 1;
            }
        }
    }
    stitch::balance(&mut leaves, top, in_frustum);
    out.balanced_triangles = 8 * leaves.len() as u64;
    out
}

/// The fewest tile cells (`q` quads a side, quadtree-aligned, any level <= `top`) that hold every need
/// (level, level-0 lattice box) at a level at most its own, tiles of different levels free to overlap and
/// a need free to be drawn in pieces from several tiles: a quadtree search with, per cell, the choice of
/// holding it as one tile (serving every need there at its level or coarser) or not, memoised on (cell,
/// the coarsest need level still unserved).
fn min_tiles(needs: &[(u32, [i64; 4])], top: u32, q: u32) -> u64 {
    type Memo = std::collections::HashMap<(u32, i64, i64, u32), u64>;
    fn cost(needs: &[&(u32, [i64; 4])], t: u32, r: [i64; 4], tau: u32, memo: &mut Memo) -> u64 {
        // The needs in this cell still unserved (level below tau).
        let open: Vec<&(u32, [i64; 4])> = needs
            .iter()
            .copied()
            .filter(|(l, b)| *l < tau && b[0] < r[2] && b[2] > r[0] && b[1] < r[3] && b[3] > r[1])
            .collect();
        if open.is_empty() {
            return 0;
        }
        if t == 0 {
            return 1;
        }
        if let Some(&c) = memo.get(&(t, r[0], r[1], tau)) {
            return c;
        }
        let (mx, my) = ((r[0] + r[2]) / 2, (r[1] + r[3]) / 2);
        let kids = [
            [r[0], r[1], mx, my],
            [mx, r[1], r[2], my],
            [r[0], my, mx, r[3]],
            [mx, my, r[2], r[3]],
        ];
        let skip: u64 = kids.iter().map(|&c| cost(&open, t - 1, c, tau, memo)).sum();
        let best = if tau > t {
            let hold = 1 + kids
                .iter()
                .map(|&c| cost(&open, t - 1, c, t, memo))
                .sum::<u64>();
            skip.min(hold)
        } else {
            skip
        };
        memo.insert((t, r[0], r[1], tau), best);
        best
    }
    let side = i64::from(q) << top;
    let mut roots: Vec<(i64, i64)> = needs
        .iter()
        .flat_map(|(_, b)| {
            let (c0, c1) = (b[0].div_euclid(side), (b[2] - 1).div_euclid(side));
            let (r0, r1) = (b[1].div_euclid(side), (b[3] - 1).div_euclid(side));
            (r0..=r1).flat_map(move |r| (c0..=c1).map(move |c| (c, r)))
        })
        .collect();
    roots.sort_unstable();
    roots.dedup();
    let all: Vec<&(u32, [i64; 4])> = needs.iter().collect();
    let mut memo = Memo::new();
    roots
        .into_iter()
        .map(|(c, r)| {
            let cell = [c * side, r * side, (c + 1) * side, (r + 1) * side];
            cost(&all, top, cell, u32::MAX, &mut memo)
        })
        .sum()
}
