//! Stage 1b, the package: the first hit of a ray on the data's bilinear surface ([`crate::package::query`]),
//! for picking and collision.
//!
//! The ray is clipped to the grid's box (its columns, rows and height range), then walked tile by tile
//! (a 2D DDA over the tiles whose ranges [`Level0::tile_range`] keeps): a tile whose cells' heights (its
//! range and its east, south and south-east neighbours', which hold its cells' far corners) the ray's
//! height over the tile misses is skipped whole. Inside a tile the walk goes cell by cell, skips a cell
//! whose four corners the ray passes above or below, and intersects the rest exactly: along the ray the
//! bilinear patch is a quadratic in the distance, solved in closed form (bisected where rounding hides a
//! sign change).

use crate::package::query::Level0;
use crate::Result;

/// A ray's hit: the distance along the (normalised) direction, the point and the surface's upward unit
/// normal there, in the grid's frame (u east in columns, v south in rows, heights in metres) converted by
/// the caller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridHit {
    /// Distance from the origin, in the units of the ray's parameter.
    pub t: f64,
    /// The cell hit.
    pub cell: (u32, u32),
    /// Fractions (s, t) in the cell at the hit.
    pub frac: (f64, f64),
    /// d height / d u and d height / d v at the hit, metres per sample.
    pub slope: (f64, f64),
}

/// A ray in grid units: position (u, v, z) + t (du, dv, dz), for t in [t0, t1].
#[derive(Clone, Copy, Debug)]
pub struct GridRay {
    /// Origin (column, row, metres).
    pub o: [f64; 3],
    /// Direction per unit of t (columns, rows, metres).
    pub d: [f64; 3],
    /// The parameter's range.
    pub t: (f64, f64),
}

impl GridRay {
    #[inline]
    fn at(&self, t: f64, k: usize) -> f64 {
        self.o[k] + t * self.d[k]
    }

    /// The ray clipped to [lo, hi] on each axis (slab test), or None when it misses the box.
    fn clip(mut self, lo: [f64; 3], hi: [f64; 3]) -> Option<Self> {
        for k in 0..3 {
            if self.d[k] == 0.0 {
                if self.o[k] < lo[k] || self.o[k] > hi[k] {
                    return None;
                }
                continue;
            }
            let a = (lo[k] - self.o[k]) / self.d[k];
            let b = (hi[k] - self.o[k]) / self.d[k];
            self.t.0 = self.t.0.max(a.min(b));
            self.t.1 = self.t.1.min(a.max(b));
        }
        (self.t.0 <= self.t.1).then_some(self)
    }

    /// The ray's lowest and highest height over [a, b].
    #[inline]
    fn z_range(&self, a: f64, b: f64) -> (f64, f64) {
        let (za, zb) = (self.at(a, 2), self.at(b, 2));
        (za.min(zb), za.max(zb))
    }
}

/// Calls `f` with each cell of side `s` (grid units) the ray crosses over [t0, t1] in order, with the
/// parameter range inside it, cells clamped to columns `xr` and rows `yr` (inclusive); stops at the first
/// `Some`.
fn walk<R>(
    ray: &GridRay,
    (t0, t1): (f64, f64),
    s: f64,
    xr: (i64, i64),
    yr: (i64, i64),
    mut f: impl FnMut(i64, i64, f64, f64) -> Result<Option<R>>,
) -> Result<Option<R>> {
    #[expect(
        clippy::cast_possible_truncation,
        reason = "floors of points inside the clipped grid, clamped to the cell range"
    )]
    let cell = |x: f64, r: (i64, i64)| ((x / s).floor() as i64).clamp(r.0, r.1);
    let (mut ci, mut cj) = (cell(ray.at(t0, 0), xr), cell(ray.at(t0, 1), yr));
    let [du, dv, _] = ray.d;
    #[expect(clippy::cast_precision_loss, reason = "cell indices far below 2^53")]
    let next = |c: i64, d: f64, o: f64| -> f64 {
        if d > 0.0 {
            ((c + 1) as f64 * s - o) / d
        } else if d < 0.0 {
            (c as f64 * s - o) / d
        } else {
            f64::INFINITY
        }
    };
    let mut ta = t0;
    loop {
        let (nx, ny) = (next(ci, du, ray.o[0]), next(cj, dv, ray.o[1]));
        let tb = nx.min(ny).min(t1).max(ta);
        if let Some(r) = f(ci, cj, ta, tb)? {
            return Ok(Some(r));
        }
        if tb >= t1 {
            return Ok(None);
        }
        if nx <= ny {
            ci += if du > 0.0 { 1 } else { -1 };
        } else {
            cj += if dv > 0.0 { 1 } else { -1 };
        }
        if ci < xr.0 || ci > xr.1 || cj < yr.0 || cj > yr.1 {
            return Ok(None);
        }
        ta = tb;
    }
}

/// The first hit of `ray` on `grid`'s bilinear surface, or None within its parameter range.
pub fn raycast(grid: &mut impl Level0, ray: &GridRay) -> Result<Option<GridHit>> {
    let (w, h) = grid.size();
    if w < 2 || h < 2 {
        return Ok(None);
    }
    let (zlo, zhi) = grid.range();
    // A little past the heights' range, so a hit on the lowest or highest sample is not clipped away by
    // the rounding of the slab's bounds.
    let m = 1e-6 * (1.0 + zlo.abs().max(zhi.abs()));
    let lo = [0.0, 0.0, zlo - m];
    let hi = [f64::from(w - 1), f64::from(h - 1), zhi + m];
    let Some(ray) = ray.clip(lo, hi) else {
        return Ok(None);
    };
    let t = grid.tile_side();
    let (cw, ch) = (i64::from(w - 1), i64::from(h - 1));
    let ti = i64::from(t);
    let (txn, tyn) = ((cw - 1) / ti, (ch - 1) / ti);
    walk(
        &ray,
        ray.t,
        f64::from(t),
        (0, txn),
        (0, tyn),
        |tx, ty, a, b| {
            let (rlo, rhi) = ray.z_range(a, b);
            // The tile's cells reach one sample into the tiles east, south and south-east.
            let (mut zlo, mut zhi) = (f64::INFINITY, f64::NEG_INFINITY);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (x, y) = (tx + dx, ty + dy);
                let last = |c: i64, n: i64| c * ti <= n;
                if (dx == 0 || last(x, cw)) && (dy == 0 || last(y, ch)) {
                    #[expect(
                        clippy::cast_possible_truncation,
                        clippy::cast_sign_loss,
                        reason = "tile indices inside the grid's, which are u32"
                    )]
                    let (l, u) = grid.tile_range(x as u32, y as u32)?;
                    zlo = zlo.min(l);
                    zhi = zhi.max(u);
                }
            }
            if rhi < zlo || rlo > zhi {
                return Ok(None);
            }
            let xr = (tx * ti, ((tx + 1) * ti).min(cw) - 1);
            let yr = (ty * ti, ((ty + 1) * ti).min(ch) - 1);
            walk(&ray, (a, b), 1.0, xr, yr, |i, j, ca, cb| {
                #[expect(
                    clippy::cast_possible_truncation,
                    clippy::cast_sign_loss,
                    reason = "cell indices inside the grid's, which are u32"
                )]
                let (i, j) = (i as u32, j as u32);
                let z = grid.corners(i, j)?;
                let (rlo, rhi) = ray.z_range(ca, cb);
                let zlo = z[0].min(z[1]).min(z[2].min(z[3]));
                let zhi = z[0].max(z[1]).max(z[2].max(z[3]));
                if rhi < zlo || rlo > zhi {
                    return Ok(None);
                }
                Ok(cell_hit(&ray, (i, j), z, ca, cb))
            })
        },
    )
}

/// The first point in [a, b] where `ray` meets the bilinear patch of cell (i, j) with corners `z`
/// ((i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)).
fn cell_hit(ray: &GridRay, (i, j): (u32, u32), z: [f64; 4], a: f64, b: f64) -> Option<GridHit> {
    let [z00, z10, z01, z11] = z;
    let (pb, pc, pd) = (z10 - z00, z01 - z00, z11 - z10 - z01 + z00);
    let s0 = ray.at(a, 0) - f64::from(i);
    let t0 = ray.at(a, 1) - f64::from(j);
    let [su, tv, dz] = ray.d;
    // f(x) = z(a + x) - h(s0 + su x, t0 + tv x) = qa x^2 + qb x + qc.
    let qa = -pd * su * tv;
    let qb = dz - (pb * su + pc * tv + pd * (s0 * tv + t0 * su));
    let qc = ray.at(a, 2) - (z00 + pb * s0 + pc * t0 + pd * s0 * t0);
    let len = b - a;
    let f = |x: f64| (qa * x + qb) * x + qc;
    let eps = 1e-9 * (1.0 + len);
    let mut best: Option<f64> = None;
    let mut take = |x: f64| {
        if x.is_finite() && x >= -eps && x <= len + eps && best.is_none_or(|b| x < b) {
            best = Some(x.clamp(0.0, len));
        }
    };
    if qc == 0.0 {
        take(0.0);
    }
    let scale = qb.abs().max(qc.abs()).max(1e-300);
    if qa.abs() <= 1e-14 * scale {
        if qb != 0.0 {
            take(-qc / qb);
        }
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            if q != 0.0 {
                take(q / qa);
                take(qc / q);
            } else {
                take(0.0);
            }
        }
    }
    if best.is_none() && (f(0.0) >= 0.0) != (f(len) >= 0.0) {
        // A sign change whose root rounding hid: bisect it.
        let (mut lo, mut hi) = (0.0, len);
        let below = f(0.0) < 0.0;
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if (f(mid) < 0.0) == below {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        best = Some(0.5 * (lo + hi));
    }
    let x = best?;
    let (s, t) = (s0 + su * x, t0 + tv * x);
    Some(GridHit {
        t: a + x,
        cell: (i, j),
        frac: (s, t),
        slope: (pb + pd * t, pc + pd * s),
    })
}
