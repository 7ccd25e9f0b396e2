//! Stage 2, the per-frame plan: SAT LOD's screen-space bound of a lattice box (SAT paper eq. 6, after
//! Li et al. 2021), split on the tested level's lattice, and what one frame's bounds share: the camera's
//! projection of vertical segments ([`BoundView`], once a frame) and a box's cut into sub-boxes with their
//! scales ([`Split`], once for every level whose lattice cuts the box alike). Pure, allocation-free.

use glam::DVec3;

use super::{Lod, LodMode, SubErrors, DEEP_RATIO, SPLIT, SPLIT_DEPTH};
use crate::plan::camera::{BoxScale, Camera, Corner, VerticalScale};

/// What every bound of one frame shares: how its camera projects vertical segments in its viewport
/// ([`VerticalScale`]) and the eye. Computed once a frame ([`Lod::bound_view`]); computed once a box it
/// was a seventh of a SAT LOD flight's plan time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundView {
    scale: VerticalScale,
    eye: DVec3,
}

/// A level-0 lattice box (inclusive vertices): (x0, y0, x1, y1).
pub type LatticeBox = (i64, i64, i64, i64);

/// A box cut on a level's lattice into up to [`SPLIT`] x [`SPLIT`] sub-boxes, each with its scale: what
/// the split bound reads of the camera. It depends on the cut points only, not on the level, so the
/// selection's descent from coarse to fine computes it once for all the levels that cut a block alike.
#[derive(Clone, Debug, Default)]
pub(super) struct Split {
    xs: heapless::Vec<i64, { SPLIT + 1 }>,
    ys: heapless::Vec<i64, { SPLIT + 1 }>,
    /// Each sub-box's scale and box (x0, y0, x1, y1).
    subs: heapless::Vec<(BoxScale, [i64; 4]), { SPLIT * SPLIT }>,
    /// What the last bound read through this cut ([`Lod::bound_deep`]) knows of each sub-box's error at
    /// its level: the sub-box's own where it was read, else the whole box's (which bounds it too).
    pub(super) etas: SubErrors,
}

impl Lod {
    /// What the bounds of a frame seen from `camera` share (in this selector's viewport).
    pub fn bound_view(&self, camera: &Camera) -> BoundView {
        BoundView {
            scale: camera.vertical_scale(self.view),
            eye: camera.eye,
        }
    }

    /// The point of level-0 lattice vertex (x, y) at height `z`, relative to the eye.
    fn rel(&self, v: &BoundView, x: i64, y: i64, z: f64) -> DVec3 {
        DVec3::new(self.world_x(x), self.world_y(y), z) - v.eye
    }

    /// The scale of box `bx` over the terrain's height range ([`VerticalScale::box_max`]): how far an
    /// object-space error moves a visible point of it, at most.
    pub fn box_scale(&self, v: &BoundView, (a, c, b, d): LatticeBox) -> BoxScale {
        // World y falls as the lattice row grows: row d is the box's south edge.
        v.scale.box_max(
            self.rel(v, a, d, self.z_range.0),
            self.rel(v, b, c, self.z_range.1),
        )
    }

    /// The object-space error of `level` under `mode` over `bx` ([`crate::bake::lod_tables::LevelTables::eta`],
    /// through the selector's cache); None for a level past the baked ones or finer than the data.
    pub(super) fn eta(&self, mode: LodMode, level: u32, (a, c, b, d): LatticeBox) -> Option<f64> {
        let k = level.checked_sub(self.synth)?;
        let t = self.tables.level(k)?;
        let (x0, y0, x1, y1) = self.tables.data_box(self.synth, a, c, b, d);
        Some(self.etas.get(k, mode, [x0, y0, x1, y1], || {
            t.eta(mode, self.tables.p, x0, y0, x1, y1)
        }))
    }

    /// An upper bound of the object-space error of `level` under `mode` over every box inside `bx`, read
    /// in O(1) from the level's max pyramid: E_L capped by the maximum over the pyramid cells covering
    /// `bx`. Every estimator is at most both over a box (the conservative bound is capped by its own
    /// covering cells, which lie under these; the estimate and the exact maximum are at most the maximum),
    /// so a group of boxes whose bound with this error meets epsilon has every box's own bound meet it.
    /// None where no table holds the level; 0 in distance mode.
    pub fn eta_cap(&self, mode: LodMode, level: u32, (a, c, b, d): LatticeBox) -> Option<f64> {
        let k = level.checked_sub(self.synth)?;
        let t = self.tables.level(k)?;
        if mode == LodMode::Distance {
            return Some(0.0);
        }
        let Some((_, max)) = t.tables() else {
            return Some(0.0);
        };
        let (x0, y0, x1, y1) = self.tables.data_box(self.synth, a, c, b, d);
        // The closed cells over samples [x0, x1 - 1]: a superset of those any query inside reads.
        let s = t.shift().min(31);
        let (cw, ch) = max.size();
        let (ca, cb) = ((x0 >> s).min(cw - 1), ((x1 - 1) >> s).min(cw - 1));
        let (ra, rb) = ((y0 >> s).min(ch - 1), ((y1 - 1) >> s).min(ch - 1));
        let m = f64::from(max.max_coarse(ca, ra, cb + 1, rb + 1));
        Some(m.min(f64::from(t.e_max())))
    }

    /// An upper bound of `level`'s bound over every box inside `bx` (one bound evaluation): `bx`'s scale
    /// with the error capped by the max pyramid ([`Lod::eta_cap`]). A box inside has a smaller scale
    /// (its corners' images lie in the hull of `bx`'s, it is no nearer) and a smaller error, so its own
    /// bound is at most this, up to rounding. Infinite for a level no table holds.
    pub fn cap_bound_in(&self, v: &BoundView, mode: LodMode, level: u32, bx: LatticeBox) -> f64 {
        if !self.charge() {
            return f64::NAN;
        }
        match self.eta_cap(mode, level, bx) {
            None => f64::INFINITY,
            Some(0.0) => 0.0,
            Some(e) => self.box_scale(v, bx).px(e),
        }
    }

    /// What a box's scale reads of its corner at level-0 lattice vertex (x, y), at the terrain's highest
    /// height when `top`, else its lowest ([`VerticalScale::corner`]): boxes that share corners (a cell's
    /// stitched units and their groups) compute each once.
    pub fn corner(&self, v: &BoundView, x: i64, y: i64, top: bool) -> Corner {
        let z = if top { self.z_range.1 } else { self.z_range.0 };
        v.scale.corner(self.rel(v, x, y, z))
    }

    /// The scale of `bx` from its eight corners ([`Lod::corner`], in any order): [`Lod::box_scale`], bit
    /// for bit (boxes that share corners project each once).
    pub fn scale_of_corners(&self, v: &BoundView, (a, c, b, d): LatticeBox, corners: &[Corner; 8]) -> BoxScale {
        let lo = self.rel(v, a, d, self.z_range.0);
        let hi = self.rel(v, b, c, self.z_range.1);
        v.scale.box_of(corners, DVec3::ZERO.clamp(lo, hi).length())
    }

    /// [`Lod::bound_in`] of `bx` whose eight corners are known ([`Lod::corner`]): the same value.
    pub fn bound_with_corners(
        &self,
        v: &BoundView,
        mode: LodMode,
        level: u32,
        bx: LatticeBox,
        limit: f64,
        corners: &[Corner; 8],
    ) -> f64 {
        let whole = self.scale_of_corners(v, bx, corners);
        self.bound_deep(v, mode, level, bx, limit, SPLIT_DEPTH, Some(whole), None)
    }

    /// The object-space error of `level` under `mode` over `bx` (None: no table holds the level): what a
    /// stitched unit's bound projects, for a caller that keeps it ([`Lod::unit_bound`]).
    pub fn eta_of(&self, mode: LodMode, level: u32, bx: LatticeBox) -> Option<f64> {
        self.eta(mode, level, bx)
    }

    /// [`Lod::eta_of`] counted as one bound evaluation (a stitched unit's error, read once and kept by
    /// the caller); None when the allowance is spent.
    pub fn read_eta(&self, mode: LodMode, level: u32, bx: LatticeBox) -> Option<Option<f64>> {
        self.charge().then(|| self.eta(mode, level, bx))
    }

    /// [`Lod::bound_with_corners`] of a box that is not split (a stitched unit, one quad of `level`),
    /// whose error `eta` ([`Lod::eta_of`]) is known: the same value (one bound evaluation).
    pub fn unit_bound(
        &self,
        v: &BoundView,
        mode: LodMode,
        bx: LatticeBox,
        corners: &[Corner; 8],
        eta: Option<f64>,
    ) -> f64 {
        if !self.charge() {
            return f64::NAN;
        }
        match eta {
            None => f64::INFINITY,
            Some(e) if e == 0.0 || mode == LodMode::Distance => 0.0,
            Some(e) => self.scale_of_corners(v, bx, corners).px(e),
        }
    }

    /// [`Lod::cap_bound_in`] of `bx` whose eight corners are known: the same value.
    pub fn cap_bound_with_corners(
        &self,
        v: &BoundView,
        mode: LodMode,
        level: u32,
        bx: LatticeBox,
        corners: &[Corner; 8],
    ) -> f64 {
        if !self.charge() {
            return f64::NAN;
        }
        match self.eta_cap(mode, level, bx) {
            None => f64::INFINITY,
            Some(0.0) => 0.0,
            Some(e) => self.scale_of_corners(v, bx, corners).px(e),
        }
    }

    /// A key of everything the bounds of a frame seen from `camera` in `mode` depend on besides the
    /// box: the camera, the viewport and epsilon, bit for bit (never 0). Equal keys, equal bounds.
    pub fn view_key(&self, camera: &Camera, mode: LodMode) -> u64 {
        super::cache::view_key(camera, self.view, self.epsilon_px, mode)
    }

    /// [`Lod::box_bound_past`] in the frame `v` (NaN where the allowance ran out first).
    pub fn bound_in(
        &self,
        v: &BoundView,
        mode: LodMode,
        level: u32,
        bx: LatticeBox,
        limit: f64,
    ) -> f64 {
        self.bound_deep(v, mode, level, bx, limit, SPLIT_DEPTH, None, None)
    }

    /// [`Lod::box_bound_at_eps`] in the frame `v`.
    pub fn bound_at_eps_in(
        &self,
        v: &BoundView,
        mode: LodMode,
        level: u32,
        bx: LatticeBox,
        eps: f64,
    ) -> f64 {
        let whole = self.bound_in(v, mode, level, bx, f64::INFINITY);
        if whole <= eps || whole.is_nan() {
            return whole;
        }
        let t = self.bound_in(v, mode, level, bx, eps);
        if t <= eps || t.is_nan() {
            t
        } else {
            whole
        }
    }

    /// The cut of `bx` on `level`'s lattice and its sub-boxes' scales (reused from `cached` when that cut
    /// is the same).
    pub(super) fn split<'s>(
        &self,
        v: &BoundView,
        (a, c, b, d): LatticeBox,
        level: u32,
        cached: &'s mut Split,
    ) -> &'s mut Split {
        let (xs, ys) = (split_points(a, b, level), split_points(c, d, level));
        if cached.xs == xs && cached.ys == ys && !cached.subs.is_empty() {
            return cached;
        }
        let (nx, ny) = (xs.len() - 1, ys.len() - 1);
        // The corners of the split grid, each computed once (sub-boxes share them): [row][column][z].
        let mut grid = [[[Corner::default(); 2]; SPLIT + 1]; SPLIT + 1];
        for (row, &y) in grid.iter_mut().zip(&ys) {
            for (cell, &x) in row.iter_mut().zip(&xs) {
                for (k, z) in [self.z_range.0, self.z_range.1].into_iter().enumerate() {
                    cell[k] = v.scale.corner(self.rel(v, x, y, z));
                }
            }
        }
        cached.subs.clear();
        for j in 0..ny {
            for i in 0..nx {
                // Sub-box (i..=i + 1, j..=j + 1) of the grid: its scale from its eight corners.
                let (g00, g10, g01, g11) =
                    (grid[j][i], grid[j][i + 1], grid[j + 1][i], grid[j + 1][i + 1]);
                let corners = [
                    g00[0], g10[0], g01[0], g11[0], g00[1], g10[1], g01[1], g11[1],
                ];
                let lo = self.rel(v, xs[i], ys[j + 1], self.z_range.0);
                let hi = self.rel(v, xs[i + 1], ys[j], self.z_range.1);
                let bs = v.scale.box_of(&corners, DVec3::ZERO.clamp(lo, hi).length());
                cached
                    .subs
                    .push((bs, [xs[i], ys[j], xs[i + 1], ys[j + 1]]))
                    .expect("SPLIT x SPLIT sub-boxes");
            }
        }
        cached.xs = xs;
        cached.ys = ys;
        cached
    }

    /// The bound of `bx` at `level` with `depth` more cuts allowed of a sub-box whose bound exceeds a
    /// finite `limit` (the threshold test only: an infinite `limit` reads one level of sub-boxes).
    /// `whole`: the box's own scale, when known; `cut`: a cut to read and keep (the selection's, shared by
    /// the levels it tests), else one is made here.
    #[expect(
        clippy::too_many_arguments,
        reason = "the bound's inputs and the two things a caller may share between bounds"
    )]
    pub(super) fn bound_deep(
        &self,
        v: &BoundView,
        mode: LodMode,
        level: u32,
        bx: LatticeBox,
        limit: f64,
        depth: u32,
        whole: Option<BoxScale>,
        cut: Option<&mut Split>,
    ) -> f64 {
        let Some(eta) = self.eta(mode, level, bx) else {
            return f64::INFINITY;
        };
        let mut cut = cut;
        if let Some(k) = cut.as_deref_mut() {
            k.etas = [eta; SPLIT * SPLIT];
        }
        if eta == 0.0 || mode == LodMode::Distance {
            return 0.0;
        }
        if !self.charge() {
            return f64::NAN;
        }
        let (a, c, b, d) = bx;
        let whole = whole.unwrap_or_else(|| self.box_scale(v, bx)).px(eta);
        let (nx, ny) = (
            split_points(a, b, level).len() - 1,
            split_points(c, d, level).len() - 1,
        );
        if (nx <= 1 && ny <= 1) || (limit.is_finite() && whole <= limit) {
            return whole;
        }
        let mut own = Split::default();
        let split = self.split(v, bx, level, cut.unwrap_or(&mut own));
        split.etas = [eta; SPLIT * SPLIT];
        // Sub-boxes by their cap first: a sub-box's bound is at most its bound for the whole box's error
        // (which bounds its samples too; the bound grows with the error), so once that is below the
        // largest bound so far its own error need not be read.
        let mut subs: heapless::Vec<(f64, usize), { SPLIT * SPLIT }> = heapless::Vec::new();
        for (i, (bs, _)) in split.subs.iter().enumerate() {
            subs.push((bs.px(eta), i)).expect("SPLIT x SPLIT sub-boxes");
        }
        subs.sort_unstable_by(|u, w| w.0.total_cmp(&u.0).then(u.1.cmp(&w.1)));
        let mut worst = 0.0f64;
        for &(cap, i) in &subs {
            if cap <= worst || worst > limit {
                break;
            }
            let (bs, [sa, sc, sb, sd]) = split.subs[i];
            let sub_box = (sa, sc, sb, sd);
            if !self.charge() {
                return f64::NAN;
            }
            let sub = self.eta(mode, level, sub_box).unwrap_or(eta).min(eta);
            split.etas[i] = sub;
            let mut val = bs.px(sub);
            if val > limit && val <= DEEP_RATIO * limit && depth > 0 {
                // Over the threshold: cut this sub-box again (each of its parts bounds its own samples,
                // so the largest of theirs is still a bound; past the limit it only has to stay past).
                let deep = self.bound_deep(v, mode, level, sub_box, limit, depth - 1, Some(bs), None);
                if deep.is_nan() {
                    return f64::NAN;
                }
                val = val.min(deep);
            }
            worst = worst.max(val);
        }
        worst.min(whole)
    }

    /// The bound of a block `bx` at `level` in the view `v` from what an earlier view's threshold test
    /// read of its sub-boxes' errors there (`etas`, in the order of the block's cut at `level`): the
    /// largest sub-box's error times its scale now, the cut's scales and no table read.
    /// Every sample of the block lies in a sub-box whose error bounds its own, so it is an upper bound
    /// of the block's projected error, as the split bound is; the errors being the same in every view,
    /// only the scales change.
    pub(super) fn held_bound(
        &self,
        v: &BoundView,
        level: u32,
        bx: LatticeBox,
        etas: &SubErrors,
        cut: &mut Split,
    ) -> f64 {
        let split = self.split(v, bx, level, cut);
        split
            .subs
            .iter()
            .zip(etas)
            .map(|((bs, _), &e)| bs.px(e))
            .fold(0.0, |m, p| if p.is_nan() { f64::INFINITY } else { m.max(p) })
    }
}

/// Up to [`SPLIT`] + 1 cut points from `lo` to `hi` (level-0 lattice), the inner ones on `level`'s lattice
/// (multiples of 2^level), strictly increasing; just [lo, hi] when the span holds no inner lattice line.
pub(super) fn split_points(lo: i64, hi: i64, level: u32) -> heapless::Vec<i64, { SPLIT + 1 }> {
    let mut out = heapless::Vec::new();
    let step = 1i64 << level.min(62);
    out.push(lo).expect("SPLIT + 1 points");
    let n = i64::try_from(SPLIT).expect("SPLIT is small");
    for i in 1..n {
        let t = (lo + (hi - lo) * i / n).div_euclid(step) * step;
        if t > *out.last().unwrap_or(&lo) && t < hi {
            out.push(t).expect("SPLIT + 1 points");
        }
    }
    out.push(hi).expect("SPLIT + 1 points");
    out
}
