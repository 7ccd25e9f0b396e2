//! Stage 2, the per-frame plan: which of the clipmap renderer's four fragment programs each draw needs
//! (pure CPU, allocation-free).
//!
//! `shaders_gles/clipmap.wgsl` shades a pixel from the finest ring holding it (GC section 6's normal maps,
//! computed from the rings) only where the block is drawn coarser than that ring, and tests skirts against
//! the data's side. Most blocks need neither: under distance LOD a block of level l lies outside level
//! l - 1's active region, where GC 6.2's alpha is 1 and the finer data's share is 0. A GPU skips such work
//! with a branch; llvmpipe, the CI renderer and a software fallback on many devices, runs both sides of a
//! branch under an execution mask, so the unused paths cost as much as used ones (measured on Puget Sound at
//! 1280x800: the ring reads and the skirt test took 3/4 of the frame). The plan therefore gives each draw
//! the cheapest program that renders the same pixels: [`FragmentPath::Plain`] where this module proves that
//! `fs_ring_data` would keep the vertex values at every pixel, bit for bit, and [`FragmentPath::Interior`]
//! where, besides, no pixel lies outside the data, so the program has no `discard` and the rasteriser can
//! reject hidden fragments before shading them.

use crate::plan::clipmap::Clipmap;
use crate::plan::cull::{Draw, DrawKind};
use crate::plan::frame::Rect;

/// The fragment program a draw is recorded with; each is an entry point of `clipmap.wgsl`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum FragmentPath {
    /// `fs_interior`: the drawn vertices' height and normal, for a block inside the data's border. With
    /// no `discard` a GPU can test depth before shading (it turns early depth off for programs that can
    /// discard); on llvmpipe this measured no faster than [`FragmentPath::Plain`].
    Interior = 0,
    /// `fs_plain`: the same, cut at the data's border.
    Plain = 1,
    /// `fs_ring_data`: the finer rings' data under blocks drawn coarser than the data held there.
    RingData = 2,
    /// `fs_skirt`: the ring data and the test that hides skirts seen through the data's side.
    Skirt = 3,
}

/// How many fragment programs there are.
pub const FRAGMENT_PATHS: usize = 4;

/// One ring's regions in level-0 lattice units, as `fs_ring_data` tests them.
#[derive(Clone, Copy, Debug)]
struct HeldLevel {
    /// Where `level_holds` is true: [lo, hi) per axis; `None` for a ring that holds nothing.
    holds: Option<([f64; 2], [f64; 2])>,
    /// Where GC 6.2's alpha is below 1 (the finer data has a share): |X - eye| < reach per axis.
    reach: [f64; 2],
}

/// The rings of one frame as [`FragmentPaths::path`] needs them, computed once per plan.
#[derive(Clone, Copy, Debug)]
pub struct FragmentPaths {
    levels: [HeldLevel; crate::profile::MAX_LEVELS as usize],
    count: usize,
    eye: (f64, f64),
    morph: bool,
    block_quads: u32,
    /// Where `outside_data` is false at every pixel, level-0 lattice units: [lo, hi] per axis.
    interior: ([f64; 2], [f64; 2]),
}

/// A fragment's lattice position is computed in f32 on the GPU; regions are widened by this many cells of
/// their level so rounding can only make a draw take the ring-data program, never the plain one wrongly.
const SLACK_CELLS: f64 = 0.5;

/// The fixed part of `outside_data`'s inset of the data's border (`clipmap.wgsl`), metres, for the data's
/// eye-relative extent `extent` (x min, y min, x max, y max): 2 cm, or a ten-thousandth of the data's
/// narrower side where that is less (a terrain under 200 m across), so that a terrain of centimetre or
/// finer spacing keeps its border samples and is drawn at all. The shader adds 4e-6 of the extent's
/// largest coordinate for f32 rounding.
pub fn border_inset_m(extent: [f64; 4]) -> f64 {
    (1.0e-4 * (extent[2] - extent[0]).min(extent[3] - extent[1])).clamp(0.0, 0.02)
}

impl FragmentPaths {
    /// The rings of `clipmap`'s last frame seen from the eye at level-0 lattice point `eye`; `morph`: the
    /// plan morphs (GC 6.2), so the finer data fades with each ring's alpha. The data spans level-0
    /// lattice [0, `data_lattice`], `extent` metres around the eye (`Globals::extent`).
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48 and widths below 2^12, exact in f64"
    )]
    pub fn new(
        clipmap: &Clipmap,
        eye: (f64, f64),
        morph: bool,
        block_quads: u32,
        data_lattice: (f64, f64),
        extent: [f64; 4],
    ) -> Self {
        // outside_data's inset (m) plus f32 rounding of eye-relative positions, generously, in lattice
        // units.
        let far = extent.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        let inset =
            (border_inset_m(extent) + 4.0e-6 * far + 1.0e-5 * far + 1.0e-3) / clipmap.g0() + 0.01;
        let interior = (
            [inset, data_lattice.0 - inset],
            [inset, data_lattice.1 - inset],
        );
        let mut levels = [HeldLevel {
            holds: None,
            reach: [0.0; 2],
        }; crate::profile::MAX_LEVELS as usize];
        let count = clipmap.frame().levels.len().min(levels.len());
        for (l, (slot, lf)) in levels.iter_mut().zip(&clipmap.frame().levels).enumerate() {
            let k = f64::from(1u32 << l);
            let c = lf.clip;
            // level_holds: cell i in [1, width - 3], so the lattice coordinate u in [1, width - 2).
            if !c.is_empty() && c.w >= 4 && c.h >= 4 {
                let axis = |x0: i64, w: u32| {
                    [
                        (x0 as f64 + 1.0 - SLACK_CELLS) * k,
                        (x0 as f64 + f64::from(w) - 2.0 + SLACK_CELLS) * k,
                    ]
                };
                slot.holds = Some((axis(c.x0, c.w), axis(c.y0, c.h)));
            }
            // shade_morph_alpha is 1 where |u - viewer| >= (active width - 1) / 2 - 1 on either axis; a
            // level that draws nothing has alpha 1 everywhere.
            let a = lf.active;
            slot.reach = if a.is_empty() {
                [0.0; 2]
            } else {
                [
                    ((f64::from(a.w) - 1.0) * 0.5 - 1.0 + SLACK_CELLS) * k,
                    ((f64::from(a.h) - 1.0) * 0.5 - 1.0 + SLACK_CELLS) * k,
                ]
            };
        }
        Self {
            levels,
            count,
            eye,
            morph,
            block_quads,
            interior,
        }
    }

    /// The program for draw `d`: skirts always test the data's side; a block takes the ring-data program
    /// when some finer ring could give a pixel of it a share: the finest ring holding a pixel, if finer
    /// than the block, shades it with share (edge blend) x (1 - morph x alpha), and where that share is
    /// below 1 a ring between it and the block may supply the base. So a block is plain when no ring finer
    /// than it holds any of its footprint where that ring's alpha is below 1 (or anywhere, unmorphed), and
    /// no ring two or more levels finer holds any of it.
    #[expect(
        clippy::cast_precision_loss,
        reason = "lattice coordinates are below 2^48, exact in f64"
    )]
    pub fn path(&self, d: &Draw) -> FragmentPath {
        if d.kind != DrawKind::Block {
            return FragmentPath::Skirt;
        }
        let r: Rect = d.covered(self.block_quads);
        if r.is_empty() {
            return FragmentPath::Interior;
        }
        let f = f64::from(1u32 << d.fine);
        let fx = [r.x0 as f64 * f, (r.x0 as f64 + f64::from(r.w) - 1.0) * f];
        let fy = [r.y0 as f64 * f, (r.y0 as f64 + f64::from(r.h) - 1.0) * f];
        let (ix, iy) = self.interior;
        let inside = |a: [f64; 2], b: [f64; 2]| a[0] > b[0] && a[1] < b[1];
        let plain = if inside(fx, ix) && inside(fy, iy) {
            FragmentPath::Interior
        } else {
            FragmentPath::Plain
        };
        let meets = |a: [f64; 2], b: [f64; 2]| a[0] < b[1] && a[1] > b[0];
        let finer = (d.level as usize).min(self.count);
        for (k, lv) in self.levels[..finer].iter().enumerate() {
            let Some((hx, hy)) = lv.holds else { continue };
            if !(meets(fx, hx) && meets(fy, hy)) {
                continue;
            }
            // Two or more levels finer: a base ring may lie between it and the block.
            if k + 1 < d.level as usize || !self.morph {
                return FragmentPath::RingData;
            }
            let ax = [self.eye.0 - lv.reach[0], self.eye.0 + lv.reach[0]];
            let ay = [self.eye.1 - lv.reach[1], self.eye.1 + lv.reach[1]];
            if meets(fx, ax) && meets(fy, ay) {
                return FragmentPath::RingData;
            }
        }
        plain
    }
}

#[cfg(test)]
mod tests {
    use super::border_inset_m;

    /// 2 cm on a terrain 200 m or more across (the shared terrains' frames keep their hashes), a
    /// ten-thousandth of the narrower side below: a tenth of a cell on a 0.1 mm grid of 1000 samples.
    #[test]
    fn border_inset_scales_with_a_small_terrain() {
        assert_eq!(border_inset_m([-5.0, -300.0, 395.0, 100.0]), 0.02);
        assert_eq!(border_inset_m([-1.0e5, -1.0e5, 1.0e5, 1.0e5]), 0.02);
        let tiny = border_inset_m([-0.05, -0.01, 0.05, 0.09]);
        assert!((tiny - 1.0e-5).abs() < 1.0e-12, "{tiny}");
        assert!(border_inset_m([0.0, 0.0, 30.0, 29_970.0]) < 0.0031, "a 2-sample wide strip");
    }
}
