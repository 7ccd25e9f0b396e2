//! Measurements: the restricted quadtree a quad-grain mesh needs, on the CPU, for the
//! oracle's counts and as a tested statement of the stitching rule. Not the frame path.
//!
//! Leaves are pyramid quads (k, c, r): quad (c, r) of data level k, drawn as its level's two triangles split
//! along the (i, j)-(i+1, j+1) diagonal (docs/design.md "SAT LOD" 1). [`balance`] splits leaves until quads that
//! meet at a side or a corner differ by at most one level. Then [`stitch`] closes every level change
//! without a skirt or a new vertex: at a corner P of a level-k leaf that a level-(k+1) leaf touches,
//! - P on level k+1's lattice is one of that leaf's corners: P takes level k+1's height there (the
//!   coarser surface, z_c in GC's terms);
//! - P odd along one axis is the midpoint of that leaf's edge: P collapses onto the edge's end one step
//!   toward -x (or -y), with that end's level-(k+1) height. Both fine leaves along the edge move P to the
//!   same end, so the coarse edge is met by the same two vertices from both sides (no T-junction), one
//!   fine triangle degenerates to a segment and its neighbour's grows over it.
//!
//! The tests check the rule on random balanced quadtrees: every point is covered once, no triangle turns
//! over, no vertex lies inside another triangle's edge, and every vertex position has one height source:
//! watertight, with no skirt.

use std::collections::HashSet;

/// A leaf: (data level k, column c, row r) of level k's quads.
pub(crate) type Node = (usize, i64, i64);

/// The four quads of level k - 1 under node (k, c, r).
pub(crate) fn children((k, c, r): Node) -> impl Iterator<Item = Node> {
    [(0, 0), (1, 0), (0, 1), (1, 1)]
        .into_iter()
        .map(move |(dc, dr)| (k - 1, 2 * c + dc, 2 * r + dr))
}

/// The leaf covering quad (k, c, r) at level k or coarser (up to `top`), if any.
fn covering(leaves: &HashSet<Node>, top: usize, (k, c, r): Node) -> Option<Node> {
    (k..=top).find_map(|j| {
        let s = j - k;
        let n = (j, c >> s, r >> s);
        leaves.contains(&n).then_some(n)
    })
}

/// Splits every leaf that is two or more levels coarser than a leaf meeting it at a side or a corner
/// (its children that `keep` refuses, such as those outside the frustum, are dropped), until none is.
/// `top`: the coarsest level a leaf may have.
pub(crate) fn balance(leaves: &mut HashSet<Node>, top: usize, keep: impl Fn(Node) -> bool) {
    let mut work: Vec<Node> = leaves.iter().copied().collect();
    work.sort_unstable();
    while let Some((k, c, r)) = work.pop() {
        if !leaves.contains(&(k, c, r)) {
            continue;
        }
        for dr in -1..=1 {
            for dc in -1..=1 {
                let Some(n) = covering(leaves, top, (k, c + dc, r + dr)) else {
                    continue;
                };
                if n.0 >= k + 2 {
                    leaves.remove(&n);
                    for ch in children(n).filter(|&ch| keep(ch)) {
                        leaves.insert(ch);
                        work.push(ch);
                    }
                    work.push((k, c, r));
                }
            }
        }
    }
}

/// A stitched triangle's vertex: where it is (level-0 lattice) and whose height it takes (level, lattice
/// point of that level).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Corner {
    pub(crate) at: (i64, i64),
    pub(crate) height: (usize, i64, i64),
}

/// Whether stitching collapsed triangle `t` to a segment (two corners moved onto one point).
pub(crate) fn collapsed(t: &[Corner; 3]) -> bool {
    t[0].at == t[1].at || t[1].at == t[2].at || t[0].at == t[2].at
}

/// The triangles of balanced `leaves` (levels up to `top`) with every level change stitched as the module
/// says: two per leaf, in its level's diagonal split, counter-clockwise in (x east, y south) lattice terms
/// up to the collapses.
pub(crate) fn stitch(leaves: &HashSet<Node>, top: usize) -> Vec<[Corner; 3]> {
    let mut sorted: Vec<Node> = leaves.iter().copied().collect();
    sorted.sort_unstable();
    let corner = |k: usize, p: (i64, i64)| -> Corner {
        // The coarsest leaf among the four level-k quads around P.
        let m = [(-1, -1), (0, -1), (-1, 0), (0, 0)]
            .into_iter()
            .filter_map(|(dc, dr)| covering(leaves, top, (k, p.0 + dc, p.1 + dr)))
            .map(|n| n.0)
            .max()
            .unwrap_or(k);
        assert!(m <= k + 1, "stitch needs a balanced quadtree");
        if m == k {
            return Corner {
                at: (p.0 << k, p.1 << k),
                height: (k, p.0, p.1),
            };
        }
        let q = match (p.0 & 1, p.1 & 1) {
            (0, 0) => p,
            (1, 0) => (p.0 - 1, p.1),
            (0, 1) => (p.0, p.1 - 1),
            _ => unreachable!("the centre of a level-(k+1) quad touched by a leaf of that level"),
        };
        Corner {
            at: (q.0 << k, q.1 << k),
            height: (k + 1, q.0 >> 1, q.1 >> 1),
        }
    };
    let mut out = Vec::with_capacity(2 * sorted.len());
    for (k, c, r) in sorted {
        let [v00, v10, v11, v01] =
            [(c, r), (c + 1, r), (c + 1, r + 1), (c, r + 1)].map(|p| corner(k, p));
        out.push([v00, v10, v11]);
        out.push([v00, v11, v01]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the signed area of triangle abc in lattice units (every leaf's triangles are positive).
    fn area2(a: (i64, i64), b: (i64, i64), c: (i64, i64)) -> i64 {
        (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
    }

    /// A random balanced quadtree over a 4 x 4 grid of level-`top` quads, split at random places.
    fn random_tree(seed: u64, top: usize) -> HashSet<Node> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            s >> 33
        };
        let mut leaves: HashSet<Node> = (0..4)
            .flat_map(|r| (0..4).map(move |c| (top, c, r)))
            .collect();
        for _ in 0..40 {
            let mut v: Vec<Node> = leaves.iter().copied().filter(|n| n.0 > 0).collect();
            if v.is_empty() {
                break;
            }
            v.sort_unstable();
            let n = v[usize::try_from(next()).expect("31-bit draws") % v.len()];
            leaves.remove(&n);
            leaves.extend(children(n));
        }
        balance(&mut leaves, top, |_| true);
        leaves
    }

    #[test]
    fn stitched_level_changes_tile_the_plane_with_one_height_per_vertex() {
        let top = 4;
        let side = 4i64 << top;
        for seed in 0..40 {
            let leaves = random_tree(seed, top);
            // Balanced: no two leaves meeting at a side or corner differ by two levels.
            for &(k, c, r) in &leaves {
                for (dc, dr) in [
                    (-1, -1),
                    (0, -1),
                    (1, -1),
                    (-1, 0),
                    (1, 0),
                    (-1, 1),
                    (0, 1),
                    (1, 1),
                ] {
                    if let Some(n) = covering(&leaves, top, (k, c + dc, r + dr)) {
                        assert!(n.0 <= k + 1, "seed {seed}: {:?} next to {n:?}", (k, c, r));
                    }
                }
            }
            let tris = stitch(&leaves, top);
            assert!(
                tris.iter().any(collapsed),
                "seed {seed}: no level change was stitched"
            );
            let levels: HashSet<usize> = leaves.iter().map(|n| n.0).collect();
            assert!(levels.len() >= 3, "seed {seed}: too few levels to test");
            // One height source per vertex position.
            let mut source = std::collections::HashMap::new();
            for v in tris.iter().flatten() {
                let h = *source.entry(v.at).or_insert(v.height);
                assert_eq!(h, v.height, "seed {seed}: two heights at {:?}", v.at);
            }
            // No triangle turns over or stands on edge: either it keeps its sign or two of its corners
            // coincide (the collapsed one).
            for t in &tris {
                let a = area2(t[0].at, t[1].at, t[2].at);
                assert!(
                    a > 0 || (a == 0 && collapsed(t)),
                    "seed {seed}: {t:?} has area {a}"
                );
            }
            // No T-junction: no vertex lies inside another triangle's edge, where its height would part
            // from the edge's.
            let verts: Vec<(i64, i64)> = source.keys().copied().collect();
            for t in &tris {
                for (a, b) in [(t[0].at, t[1].at), (t[1].at, t[2].at), (t[2].at, t[0].at)] {
                    for &v in &verts {
                        let on_line = area2(a, b, v) == 0;
                        let inside = (v.0 - a.0) * (b.0 - v.0) + (v.1 - a.1) * (b.1 - v.1) > 0;
                        assert!(
                            !(on_line && inside && v != a && v != b),
                            "seed {seed}: vertex {v:?} inside edge {a:?}-{b:?}"
                        );
                    }
                }
            }
            // Every point covered exactly once: the centres of a grid finer than level 0, nudged off
            // every lattice line and diagonal.
            let pts: Vec<(f64, f64)> = (0..side * 2)
                .flat_map(|y| {
                    (0..side * 2).map(move |x| (x as f64 * 0.5 + 0.13, y as f64 * 0.5 + 0.29))
                })
                .collect();
            let mut count = vec![0u8; pts.len()];
            for t in &tris {
                let [a, b, c] = t.map(|v| (v.at.0 as f64, v.at.1 as f64));
                let (x0, x1) = (a.0.min(b.0).min(c.0), a.0.max(b.0).max(c.0));
                let (y0, y1) = (a.1.min(b.1).min(c.1), a.1.max(b.1).max(c.1));
                for (i, &(x, y)) in pts.iter().enumerate() {
                    if x < x0 || x > x1 || y < y0 || y > y1 {
                        continue;
                    }
                    let s = |p: (f64, f64), q: (f64, f64)| {
                        (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0)
                    };
                    let (s0, s1, s2) = (s(a, b), s(b, c), s(c, a));
                    if (s0 < 0.0 && s1 < 0.0 && s2 < 0.0) || (s0 > 0.0 && s1 > 0.0 && s2 > 0.0) {
                        count[i] += 1;
                    }
                }
            }
            let bad = count.iter().filter(|&&n| n != 1).count();
            assert_eq!(bad, 0, "seed {seed}: {bad} points not covered exactly once");
        }
    }
}
