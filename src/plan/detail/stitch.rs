//! Stage 2, the per-frame plan: stitched pool cells. A cell of level k is drawn in units, each
//! one quad of level k + 1 (2 x 2 quads of level k): a unit whose level-(k + 1) bound meets epsilon is that
//! one coarse quad (2 triangles), the others the four fine quads (8 triangles). Two levels meet inside a
//! cell with no skirt and no new vertex, by the rule `measure/stitch.rs` tests on whole quadtrees: a
//! corner a coarse unit touches takes the coarser level's height (GC section 3's z_c, which the pool tile
//! holds beside z), and a fine unit's edge midpoint facing a coarse unit collapses onto that edge's end
//! toward -x or -y. Every vertex of a cell is placed from the cell's one tile anchor, so vertices that
//! units share match bit for bit. The cell's border hangs a skirt under each unit's side there, through
//! the same vertex rule, to meet other cells and the rings as whole cells do. Pure CPU; the vertex
//! shader's `stitch_local` is [`local`]'s twin.

use crate::plan::frame::Rect;
use crate::plan::mesh::UnitMesh;

/// Most units per cell side: a 64-quad tile (the largest a profile allows is the block side m <= 64).
pub const MAX_UNITS: u32 = 32;

/// Which units of a cell are coarse: bit a of row b is unit (a, b).
pub type Mask = [u32; MAX_UNITS as usize];

/// The units (columns, rows) of a cell over vertex rectangle `r`: 2 x 2 quads each (its corners are
/// even).
pub fn units(r: &Rect) -> (u32, u32) {
    ((r.w - 1) / 2, (r.h - 1) / 2)
}

/// Flag bit: a fine unit's side s midpoint collapses (s: 0 -y, 1 +x, 2 +y, 3 -x; bits 0..4).
pub const COLLAPSE: u16 = 1;
/// Flag bit: corner c reads z_c (c: 0 (0, 0), 1 (2, 0), 2 (2, 2), 3 (0, 2); bits 4..8).
pub const ZC: u16 = 1 << 4;

/// Whether unit (a, b) is coarse; false outside the mask's `ua x ub` units.
pub fn coarse(mask: &Mask, ua: u32, ub: u32, a: i64, b: i64) -> bool {
    (0..i64::from(ua)).contains(&a)
        && usize::try_from(b)
            .ok()
            .filter(|&b| b < ub as usize)
            .and_then(|b| mask.get(b))
            .is_some_and(|row| row >> a & 1 == 1)
}

/// The vertex flags of unit (a, b) of a cell of `ua x ub` units: the sides whose neighbour in the cell is
/// coarse (a fine unit's midpoints there collapse) and the corners some coarse unit of the cell touches
/// (they read z_c). A coarse unit's corners all read z_c.
pub fn unit_flags(mask: &Mask, ua: u32, ub: u32, a: i64, b: i64) -> u16 {
    let c = |x: i64, y: i64| coarse(mask, ua, ub, x, y);
    if c(a, b) {
        return 0xf * ZC;
    }
    let mut f = 0;
    for (s, (dx, dy)) in [(0, -1), (1, 0), (0, 1), (-1, 0)].into_iter().enumerate() {
        if c(a + dx, b + dy) {
            f |= COLLAPSE << s;
        }
    }
    // Corner (cx, cy) in units is touched by the units (cx - 1 ..= cx, cy - 1 ..= cy).
    for (k, (cx, cy)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
        let (x, y) = (a + cx, b + cy);
        if c(x - 1, y - 1) || c(x, y - 1) || c(x - 1, y) || c(x, y) {
            f |= ZC << k;
        }
    }
    f
}

/// The vertex flags of one row of a cell's units at once ([`unit_flags`], bit for bit), from the
/// mask's rows as bit sets: a unit's neighbours are the row's bits shifted by one and the rows above and
/// below. The stitched cells' records are written every frame, one per unit.
#[derive(Clone, Copy, Debug)]
pub struct RowFlags {
    row: u32,
    /// Per side s, the bits of the units whose neighbour there is coarse.
    sides: [u32; 4],
    /// Per corner k, the bits of the units a coarse unit touches there.
    corners: [u32; 4],
}

impl RowFlags {
    /// Row `b` of a cell of `ua x ub` units with coarse units `mask`.
    pub fn of(mask: &Mask, ua: u32, ub: u32, b: u32) -> Self {
        let full = if ua >= 32 { u32::MAX } else { (1u32 << ua) - 1 };
        let at = |y: i64| -> u32 {
            usize::try_from(y)
                .ok()
                .filter(|&y| y < ub as usize)
                .and_then(|y| mask.get(y))
                .map_or(0, |r| r & full)
        };
        let b = i64::from(b);
        let (u, r, d) = (at(b - 1), at(b), at(b + 1));
        // Bit a of p(x) is unit a's or a - 1's; of q(x), a's or a + 1's.
        let p = |x: u32| x | x << 1;
        let q = |x: u32| x | x >> 1;
        Self {
            row: r,
            sides: [u, r >> 1, d, r << 1],
            corners: [p(u) | p(r), q(u) | q(r), q(r) | q(d), p(r) | p(d)],
        }
    }

    /// Whether unit a is coarse.
    pub fn coarse(&self, a: u32) -> bool {
        self.row >> a & 1 == 1
    }

    /// Unit a's flags ([`unit_flags`]).
    pub fn flags(&self, a: u32) -> u16 {
        if self.coarse(a) {
            return 0xf * ZC;
        }
        let mut f = 0u16;
        for s in 0..4 {
            f |= u16::from(self.sides[s] >> a & 1 == 1) * (COLLAPSE << s);
            f |= u16::from(self.corners[s] >> a & 1 == 1) * (ZC << s);
        }
        f
    }
}

/// The vertex rule (the twin of `stitch_local` in `shaders_gles/clipmap.wgsl`): mesh vertex (x, y) of a
/// unit (0..=2 each) with `flags` goes to lattice offset (x', y') in the unit, reading z_c when true.
pub fn local(flags: u16, x: u32, y: u32) -> (u32, u32, bool) {
    let (mut x, mut y) = (x, y);
    let bit = |s: u32| flags & (COLLAPSE << s) != 0;
    if y == 0 && x == 1 && bit(0) {
        x = 0;
    } else if x == 2 && y == 1 && bit(1) {
        y = 0;
    } else if y == 2 && x == 1 && bit(2) {
        x = 0;
    } else if x == 0 && y == 1 && bit(3) {
        y = 0;
    }
    let corner = match (x, y) {
        (0, 0) => Some(0),
        (2, 0) => Some(1),
        (2, 2) => Some(2),
        (0, 2) => Some(3),
        _ => None,
    };
    let zc = corner.is_some_and(|k| flags & (ZC << k) != 0);
    (x, y, zc)
}

/// The triangles of unit mesh `m` in the unit's lattice (before [`local`]), as the pool cell mesh draws
/// them: the fan's four quads and the coarse quad split along the (i, j)-(i+1, j+1) diagonal.
pub fn surface_triangles(m: UnitMesh) -> &'static [[(u32, u32); 3]] {
    const FAN: [[(u32, u32); 3]; 8] = [
        [(0, 0), (0, 1), (1, 1)],
        [(0, 0), (1, 1), (1, 0)],
        [(1, 0), (1, 1), (2, 1)],
        [(1, 0), (2, 1), (2, 0)],
        [(0, 1), (0, 2), (1, 2)],
        [(0, 1), (1, 2), (1, 1)],
        [(1, 1), (1, 2), (2, 2)],
        [(1, 1), (2, 2), (2, 1)],
    ];
    const COARSE: [[(u32, u32); 3]; 2] = [[(0, 0), (0, 2), (2, 2)], [(0, 0), (2, 2), (2, 0)]];
    match m {
        UnitMesh::Fan => &FAN,
        UnitMesh::Coarse => &COARSE,
        UnitMesh::Skirt { .. } => &[],
    }
}

/// Triangles a stitched cell of `ua x ub` units draws: 2 per coarse unit, 8 per fine one, and under each
/// unit side on the cell's border a skirt of 2 triangles per segment (1 segment coarse, 2 fine).
pub fn triangles(mask: &Mask, ua: u32, ub: u32) -> u64 {
    // Every unit fine, less 6 + 2 x (its border sides) for each coarse one, counted a row at a time
    // (the planner asks this of every cell every frame; a unit loop was 2 % of a SAT plan).
    let (ua, ub) = (ua.min(MAX_UNITS), ub.min(MAX_UNITS));
    if ua == 0 || ub == 0 {
        return 0;
    }
    let (n, sides) = (u64::from(ua) * u64::from(ub), 2 * u64::from(ua) + 2 * u64::from(ub));
    let bits = u32::MAX >> (MAX_UNITS - ua);
    let rows = &mask[..ub as usize];
    let count = |r: u32| u64::from((r & bits).count_ones());
    let coarse: u64 = rows.iter().map(|&r| count(r)).sum();
    let coarse_border: u64 = rows
        .iter()
        .map(|&r| u64::from(r & 1) + u64::from(r >> (ua - 1) & 1))
        .sum::<u64>()
        + count(rows[0])
        + count(rows[rows.len() - 1]);
    8 * n + 4 * sides - 6 * coarse - 2 * coarse_border
}

/// The units of `meets` (those whose coarser level meets epsilon) whose neighbours in the cell at their
/// sides are in `meets` too: the ones drawn coarse. A fine unit beside a coarse one reads z_c at the two
/// corners they share and its midpoint there collapses, so its surface near that side is the coarser
/// level's; keeping coarse units away from fine units whose coarser level misses epsilon keeps that blend
/// within it (measured: without this, 1.23 px on Puget Sound at epsilon 1; a unit touching a coarse one
/// only at a corner, one z_c vertex, stays within it).
pub fn erode(meets: &Mask, ua: u32, ub: u32) -> Mask {
    let mut out: Mask = [0; MAX_UNITS as usize];
    for (b, row) in out.iter_mut().enumerate().take(ub as usize) {
        let b = i64::try_from(b).expect("b < MAX_UNITS");
        for a in 0..i64::from(ua) {
            let sides_meet = [(0, -1), (1, 0), (0, 1), (-1, 0)]
                .into_iter()
                .all(|(dx, dy)| {
                    let (x, y) = (a + dx, b + dy);
                    let inside = (0..i64::from(ua)).contains(&x) && (0..i64::from(ub)).contains(&y);
                    !inside || coarse(meets, ua, ub, x, y)
                });
            if coarse(meets, ua, ub, a, b) && sides_meet {
                *row |= 1 << a;
            }
        }
    }
    out
}

/// Whether any unit of the mask is coarse (the cell is drawn stitched, else whole).
pub fn any(mask: &Mask) -> bool {
    mask.iter().any(|&r| r != 0)
}

/// The height of a unit's drawn surface at (x, y) in its lattice units (0..=2 each): the mesh's triangle
/// there through [`local`], its vertices' heights from `z` and `zc` (lattice offset in the unit). None
/// outside the unit. The CPU twin of what a stitched unit draws, for the measurements.
pub fn height(
    flags: u16,
    coarse_unit: bool,
    z: &dyn Fn(u32, u32) -> f64,
    zc: &dyn Fn(u32, u32) -> f64,
    x: f64,
    y: f64,
) -> Option<f64> {
    let m = if coarse_unit {
        UnitMesh::Coarse
    } else {
        UnitMesh::Fan
    };
    for t in surface_triangles(m) {
        let v = t.map(|(a, b)| {
            let (a, b, c) = local(flags, a, b);
            let h = if c { zc(a, b) } else { z(a, b) };
            (f64::from(a), f64::from(b), h)
        });
        let area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[2].0 - v[0].0) * (v[1].1 - v[0].1);
        if area == 0.0 {
            continue;
        }
        let w1 = ((x - v[0].0) * (v[2].1 - v[0].1) - (v[2].0 - v[0].0) * (y - v[0].1)) / area;
        let w2 = ((v[1].0 - v[0].0) * (y - v[0].1) - (x - v[0].0) * (v[1].1 - v[0].1)) / area;
        let w0 = 1.0 - w1 - w2;
        let eps = -1e-9;
        if w0 >= eps && w1 >= eps && w2 >= eps {
            return Some(w0 * v[0].2 + w1 * v[1].2 + w2 * v[2].2);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// A small deterministic generator (tests only).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 33) as u32
        }
    }

    /// Every stitched triangle of a cell, in the cell's lattice (x, y, height) with heights from random
    /// z and z_c, and the skirt segments' tops.
    #[expect(clippy::type_complexity, reason = "test geometry")]
    fn cell_geometry(
        mask: &Mask,
        ua: u32,
        ub: u32,
        seed: u64,
    ) -> (Vec<[(i64, i64, u64); 3]>, Vec<[(i64, i64, u64); 2]>) {
        let mut rng = Lcg(seed);
        let (w, h) = (2 * ua as usize + 1, 2 * ub as usize + 1);
        let z: Vec<u64> = (0..w * h).map(|_| u64::from(rng.next())).collect();
        let zc: Vec<u64> = (0..w * h).map(|_| u64::from(rng.next())).collect();
        let mut tris = Vec::new();
        let mut skirts = Vec::new();
        for b in 0..ub {
            for a in 0..ua {
                let c = coarse(mask, ua, ub, a.into(), b.into());
                let f = unit_flags(mask, ua, ub, a.into(), b.into());
                let place = |(x, y): (u32, u32)| {
                    let (x, y, r) = local(f, x, y);
                    let (px, py) = ((2 * a + x) as usize, (2 * b + y) as usize);
                    let k = py * w + px;
                    (px as i64, py as i64, if r { zc[k] } else { z[k] })
                };
                let m = if c { UnitMesh::Coarse } else { UnitMesh::Fan };
                for t in surface_triangles(m) {
                    tris.push(t.map(place));
                }
                // Skirt tops along each border side: the side's corners and (fine) midpoint.
                let sides = [
                    (b == 0, [(0, 0), (1, 0), (2, 0)]),
                    (a + 1 == ua, [(2, 0), (2, 1), (2, 2)]),
                    (b + 1 == ub, [(2, 2), (1, 2), (0, 2)]),
                    (a == 0, [(0, 2), (0, 1), (0, 0)]),
                ];
                for (on, p) in sides {
                    if !on {
                        continue;
                    }
                    if c {
                        skirts.push([place(p[0]), place(p[2])]);
                    } else {
                        skirts.push([place(p[0]), place(p[1])]);
                        skirts.push([place(p[1]), place(p[2])]);
                    }
                }
            }
        }
        (tris, skirts)
    }

    fn cross(a: (i64, i64), b: (i64, i64), c: (i64, i64)) -> i64 {
        (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1)
    }

    #[test]
    fn stitched_cells_are_watertight() {
        let mut rng = Lcg(7);
        for round in 0..60u64 {
            let (ua, ub) = (1 + rng.next() % 8, 1 + rng.next() % 8);
            let mut mask: Mask = [0; MAX_UNITS as usize];
            let p = rng.next() % 4;
            for row in mask.iter_mut().take(ub as usize) {
                for a in 0..ua {
                    if rng.next() % 4 < p {
                        *row |= 1 << a;
                    }
                }
            }
            let (tris, skirts) = cell_geometry(&mask, ua, ub, round);
            // Drawn triangles (degenerate ones included) are what `triangles` counts.
            assert_eq!(
                tris.len() as u64 + 2 * skirts.len() as u64,
                triangles(&mask, ua, ub),
                "round {round}"
            );
            let live: Vec<_> = tris
                .iter()
                .filter(|t| cross((t[0].0, t[0].1), (t[1].0, t[1].1), (t[2].0, t[2].1)) != 0)
                .collect();
            // None turns over: the mesh's winding is kept.
            let sign = cross(
                (live[0][0].0, live[0][0].1),
                (live[0][1].0, live[0][1].1),
                (live[0][2].0, live[0][2].1),
            )
            .signum();
            for t in &live {
                let s = cross((t[0].0, t[0].1), (t[1].0, t[1].1), (t[2].0, t[2].1));
                assert_eq!(s.signum(), sign, "round {round}: {t:?} turned over");
            }
            // Four points in every lattice square (in 1/16 units, off every line of slope 0, 1/2, 1, 2
            // or their negatives through lattice points, which hold every edge) lie in one triangle each.
            for ly in 0..(2 * i64::from(ub)) {
                for lx in 0..(2 * i64::from(ua)) {
                    for (ox, oy) in [(3, 5), (11, 13), (7, 3), (12, 9)] {
                        let pt = (16 * lx + ox, 16 * ly + oy);
                        let inside = live
                            .iter()
                            .filter(|t| {
                                let v = t.map(|(x, y, _)| (16 * x, 16 * y));
                                let s = cross(v[0], v[1], v[2]).signum();
                                (0..3).all(|i| cross(v[i], v[(i + 1) % 3], pt).signum() == s)
                            })
                            .count();
                        assert_eq!(
                            inside, 1,
                            "round {round}: point {pt:?} (/16) covered {inside}x"
                        );
                    }
                }
            }
            // One height per vertex position, and no vertex inside another triangle's edge.
            let mut heights = HashMap::new();
            for t in &live {
                for &(x, y, z) in t.iter() {
                    assert_eq!(
                        *heights.entry((x, y)).or_insert(z),
                        z,
                        "round {round}: ({x}, {y}) has two heights"
                    );
                }
            }
            for t in &live {
                for i in 0..3 {
                    let (a, b) = ((t[i].0, t[i].1), (t[(i + 1) % 3].0, t[(i + 1) % 3].1));
                    for &(x, y) in heights.keys() {
                        let on = cross(a, b, (x, y)) == 0
                            && (x - a.0) * (x - b.0) + (y - a.1) * (y - b.1) < 0;
                        assert!(
                            !on,
                            "round {round}: T-junction at ({x}, {y}) on {a:?}-{b:?}"
                        );
                    }
                }
            }
            // The skirt tops are the surface's border edges, end for end with their heights.
            type Edge = ((i64, i64), (i64, i64));
            let mut border: HashMap<Edge, u32> = HashMap::new();
            for t in &live {
                for i in 0..3 {
                    let (a, b) = ((t[i].0, t[i].1), (t[(i + 1) % 3].0, t[(i + 1) % 3].1));
                    *border.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            let mut outer: Vec<_> = border
                .into_iter()
                .filter(|&(_, n)| n == 1)
                .map(|(e, _)| e)
                .collect();
            let mut tops: Vec<_> = skirts
                .iter()
                .filter(|s| (s[0].0, s[0].1) != (s[1].0, s[1].1))
                .map(|s| {
                    for &(x, y, z) in s {
                        assert_eq!(
                            heights[&(x, y)],
                            z,
                            "round {round}: skirt top off the surface"
                        );
                    }
                    let (a, b) = ((s[0].0, s[0].1), (s[1].0, s[1].1));
                    (a.min(b), a.max(b))
                })
                .collect();
            outer.sort_unstable();
            tops.sort_unstable();
            assert_eq!(outer, tops, "round {round}: skirts and border edges differ");
        }
    }

    #[test]
    fn row_flags_are_unit_flags() {
        let mut rng = Lcg(11);
        for _ in 0..200 {
            let (ua, ub) = (1 + rng.next() % 32, 1 + rng.next() % 32);
            let mut mask: Mask = [0; MAX_UNITS as usize];
            for row in mask.iter_mut().take(ub as usize) {
                *row = rng.next() & if ua == 32 { u32::MAX } else { (1 << ua) - 1 };
            }
            for b in 0..ub {
                let r = RowFlags::of(&mask, ua, ub, b);
                for a in 0..ua {
                    let want = unit_flags(&mask, ua, ub, a.into(), b.into());
                    assert_eq!(r.flags(a), want, "unit ({a}, {b}) of {ua} x {ub}");
                    assert_eq!(r.coarse(a), coarse(&mask, ua, ub, a.into(), b.into()));
                }
            }
        }
    }

    #[test]
    fn triangles_counts_every_unit() {
        // The unit-by-unit count it replaced: 2 a coarse unit, 8 a fine one, and 2 or 4 a border side.
        let by_units = |mask: &Mask, ua: u32, ub: u32| -> u64 {
            let mut t = 0;
            for b in 0..i64::from(ub) {
                for a in 0..i64::from(ua) {
                    let border = u64::from(a == 0)
                        + u64::from(b == 0)
                        + u64::from(a + 1 == i64::from(ua))
                        + u64::from(b + 1 == i64::from(ub));
                    t += if coarse(mask, ua, ub, a, b) { 2 + 2 * border } else { 8 + 4 * border };
                }
            }
            t
        };
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..500 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let [b0, b1, ..] = x.to_le_bytes();
            let (ua, ub) = (1 + u32::from(b0 % 32), 1 + u32::from(b1 % 32));
            let mut mask: Mask = [0; MAX_UNITS as usize];
            for (k, row) in (0u32..).zip(mask.iter_mut()) {
                let [l0, l1, l2, l3, ..] = (x.rotate_left(k * 7) ^ (x >> (k % 13))).to_le_bytes();
                *row = u32::from_le_bytes([l0, l1, l2, l3]);
            }
            assert_eq!(triangles(&mask, ua, ub), by_units(&mask, ua, ub), "{ua} x {ub}");
        }
        assert_eq!(triangles(&[0; MAX_UNITS as usize], 0, 5), 0);
    }

    #[test]
    fn height_follows_the_stitched_triangles() {
        let z = |x: u32, y: u32| f64::from(x * 10 + y);
        let zc = |x: u32, y: u32| f64::from(x * 100 + y * 1000);
        // A coarse unit is the coarser quad through its corners' z_c, split along the diagonal.
        let f = unit_flags(&[1; MAX_UNITS as usize], 1, 1, 0, 0);
        assert_eq!(f, 0xf0);
        assert_eq!(height(f, true, &z, &zc, 2.0, 0.0), Some(200.0));
        assert_eq!(height(f, true, &z, &zc, 1.0, 1.0), Some(1100.0));
        // A fan keeps its centre's z; with no flags it is level k's surface.
        assert_eq!(height(0xff, false, &z, &zc, 1.0, 1.0), Some(11.0));
        assert_eq!(height(0, false, &z, &zc, 2.0, 1.0), Some(21.0));
        // Side 1 collapsed: (2, 1) moved onto (2, 0), so the side is the straight edge to (2, 2)'s z_c.
        assert_eq!(
            height(COLLAPSE << 1 | ZC << 1 | ZC << 2, false, &z, &zc, 2.0, 1.0),
            Some(1200.0)
        );
        assert_eq!(height(0, false, &z, &zc, 2.5, 1.0), None);
    }

    #[test]
    fn unit_meshes_are_the_stitch_rule_s_triangles() {
        use crate::plan::mesh::{pool_cells, pool_unit_range};
        let p = pool_cells(8);
        let tri = |r: std::ops::Range<u32>| -> Vec<[(u32, u32, u16); 3]> {
            p.indices[r.start as usize..r.end as usize]
                .chunks_exact(3)
                .map(|t| {
                    [t[0], t[1], t[2]].map(|i| {
                        let v = p.vertices[usize::from(i)];
                        (u32::from(v[0]), u32::from(v[1]), v[2])
                    })
                })
                .collect()
        };
        for m in [UnitMesh::Fan, UnitMesh::Coarse] {
            let got: Vec<[(u32, u32); 3]> = tri(pool_unit_range(8, m))
                .iter()
                .map(|t| t.map(|(x, y, _)| (x, y)))
                .collect();
            assert_eq!(got, surface_triangles(m), "{m:?}");
        }
        let sides = [(0, 0), (2, 0), (2, 2), (0, 2), (0, 0)];
        for side in 0..4u8 {
            for coarse in [false, true] {
                let ts = tri(pool_unit_range(8, UnitMesh::Skirt { side, coarse }));
                assert_eq!(ts.len(), if coarse { 2 } else { 4 });
                let (a, b) = (sides[usize::from(side)], sides[usize::from(side) + 1]);
                for t in &ts {
                    for &(x, y, _) in t {
                        // On the side's segment, and a coarse skirt only at its corners.
                        let on = (x == a.0 && x == b.0) || (y == a.1 && y == b.1);
                        assert!(on, "side {side}: ({x}, {y})");
                        assert!(!coarse || (x, y) == a || (x, y) == b);
                    }
                    // Every triangle hangs from the top to the floor.
                    assert!(t.iter().any(|v| v.2 == 0) && t.iter().any(|v| v.2 == 1));
                }
            }
        }
    }
}
