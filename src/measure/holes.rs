//! Measurements of drawn frames: which crack candidates (clear pixels inside a column's silhouette,
//! [`crate::measure::crack_pixels`]) are holes in the drawn surface, through a CPU twin of it.
//!
//! A column-rule candidate is not always a hole. The fragment shader cuts every level at the data's
//! border (`outside_data`), and two blocks or pool cells at different levels end there at different
//! heights (each level's own surface; skirts close the step inside the data). Where a farther, higher
//! stretch of the border stands over a nearer, lower one, a pixel column tilted by the camera's pitch can
//! see past the terrain's edge between them: clear is right there, a notch in the silhouette no wider
//! than the step. A hole is a clear pixel whose view ray passes below the drawn surface while inside the
//! data.

use glam::{DMat4, DVec3, DVec4, Mat4};

use crate::gpu::readback::Image;
use crate::plan::camera::Camera;
use crate::plan::clipmap::Clipmap;
pub use crate::plan::drawn::{drawn_height, Drawn};
use crate::plan::frame_plan::FramePlan;

/// Most candidates [`hole_pixels`] traces (each trace walks the whole view ray); past it, an evenly
/// spaced sample of this many is traced and the holes are scaled to all candidates.
pub const MAX_TRACED: u64 = 4096;

/// Whether the view ray through pixel (x, y) of a `view`-sized frame planned as `plan` passes below the
/// surface its draws draw while inside the data (inset as `outside_data` insets the border cut), having
/// been above it there first: a clear pixel there is a hole. A ray that leaves the data through its side
/// above the surface sees past the terrain's edge, and one from an eye outside the data that enters
/// through its side below the surface sees where a solid terrain's side would be (the shader's
/// `through_side` hides skirts there): neither is a hole. Walks the ray in steps of an eighth of the
/// level-0 spacing. A ray that meets a sample it cannot read ([`Drawn::Unread`]: streamed, its tile has
/// left the cache) counts as below: a pixel that cannot be cleared is a hole.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    reason = "the step count is capped at 10^6"
)]
pub fn ray_below_drawn_surface(
    plan: &FramePlan,
    view: (u32, u32),
    clipmap: &Clipmap,
    camera: &Camera,
    block_quads: u32,
    (x, y): (u32, u32),
) -> bool {
    let g = plan.globals();
    let (w, h) = view;
    let inv: DMat4 = Mat4::from_cols_array(&g.view_proj).as_dmat4().inverse();
    let nx = (f64::from(x) + 0.5) / f64::from(w) * 2.0 - 1.0;
    let ny = 1.0 - (f64::from(y) + 0.5) / f64::from(h) * 2.0;
    let a = inv * DVec4::new(nx, ny, 0.0, 1.0);
    let b = inv * DVec4::new(nx, ny, 1.0, 1.0);
    let (a, b): (DVec3, DVec3) = (a.truncate() / a.w, b.truncate() / b.w);
    let e = g.extent.map(f64::from);
    let tol = crate::plan::fragment::border_inset_m(e)
        + 4.0e-6 * e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (lo, hi) = ([e[0] + tol, e[1] + tol], [e[2] - tol, e[3] - tol]);
    let (eu, ev) = clipmap.eye_lattice(camera.eye);
    let g0 = clipmap.g0();
    let steps = ((b - a).length() / (g0 / 8.0)).ceil().min(1.0e6) as u32;
    let mut above = false;
    for i in 0..=steps {
        let p = a + (b - a) * (f64::from(i) / f64::from(steps.max(1)));
        if !(0..2).all(|k| p[k] >= lo[k] && p[k] <= hi[k]) {
            continue;
        }
        let z = match drawn_height(clipmap, plan, block_quads, eu + p.x / g0, ev - p.y / g0) {
            Drawn::Height(z) => z,
            Drawn::Nothing => continue,
            Drawn::Unread => return true,
        };
        if camera.eye.z + p.z >= z {
            above = true;
        } else {
            // Below: a hole if the ray came from above the surface inside the data; entering through the
            // data's side below it, it sees where a solid terrain's side would be (`through_side`).
            return above;
        }
    }
    false
}

/// What [`hole_pixels`] found among a frame's crack candidates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Holes {
    /// Crack candidates: clear pixels between terrain pixels of a column ([`crate::measure::crack_pixels`]).
    pub candidates: u64,
    /// Candidates traced: all of them, or an evenly spaced [`MAX_TRACED`] of more.
    pub traced: u64,
    /// Holes among the candidates: exact when every candidate was traced; otherwise the traced holes
    /// scaled to all candidates, rounded, and at least 1 when any traced candidate is a hole.
    pub holes: u64,
}

/// The crack candidates of `image` (pixels of colour `clear` between terrain pixels of a column, as
/// [`crate::measure::crack_pixels`] counts them) whose view ray passes below the drawn surface inside the
/// data ([`ray_below_drawn_surface`]): the holes. Past [`MAX_TRACED`] candidates, an evenly spaced sample
/// of them is traced and the count scaled ([`Holes::holes`]).
pub fn hole_pixels(
    image: &Image,
    clear: [u8; 4],
    plan: &FramePlan,
    clipmap: &Clipmap,
    camera: &Camera,
    block_quads: u32,
) -> Holes {
    let candidates = crate::measure::crack_pixels(image, clear);
    let stride = candidates.div_ceil(MAX_TRACED).max(1);
    let (mut found, mut traced) = (0u64, 0u64);
    for (x, y) in crate::measure::image::crack_candidates(image, clear)
        .step_by(usize::try_from(stride).unwrap_or(usize::MAX))
    {
        traced += 1;
        if ray_below_drawn_surface(
            plan,
            (image.width, image.height),
            clipmap,
            camera,
            block_quads,
            (x, y),
        ) {
            found += 1;
        }
    }
    Holes {
        candidates,
        traced,
        holes: scaled_holes(found, traced, candidates),
    }
}

/// `found` holes among `traced` of `candidates` scaled to all of them, rounded to nearest: exact when every
/// candidate was traced, and never below `found` (candidates are at least the traced ones), so one traced
/// hole is never scaled to none.
fn scaled_holes(found: u64, traced: u64, candidates: u64) -> u64 {
    (found * candidates + traced / 2) / traced.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_holes_scale_to_all_candidates() {
        assert_eq!(scaled_holes(0, 4096, 14_431), 0);
        assert_eq!(scaled_holes(7, 7, 7), 7);
        assert_eq!(
            scaled_holes(4096, 4096, 14_431),
            14_431,
            "all traced are holes"
        );
        assert_eq!(scaled_holes(1, 4096, 14_431), 4, "3.5 rounds up");
        assert_eq!(
            scaled_holes(1, 4096, 4097),
            1,
            "one traced hole is never scaled to 0"
        );
        // The stride hole_pixels uses traces at most MAX_TRACED candidates.
        for n in [1, 4095, 4096, 4097, 14_431, 1 << 21] {
            let stride = u64::div_ceil(n, MAX_TRACED).max(1);
            assert!(n.div_ceil(stride) <= MAX_TRACED, "{n} candidates");
        }
    }
}
