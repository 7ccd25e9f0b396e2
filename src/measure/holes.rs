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
use crate::plan::clipmap::Clipmap;
use crate::plan::cull::DrawList;
use crate::plan::frame_plan::FramePlan;
use crate::Camera;

/// Most candidates [`hole_pixels`] traces; any beyond count as holes unchecked (a frame with that many
/// is broken anyway, and each trace walks the whole view ray).
pub const MAX_TRACED: u64 = 4096;

/// The height of the surface `draws` draw at level-0 lattice point (u, v) (fractional), the highest where
/// several blocks meet there (their skirts close the step between them); None where no block draws it.
/// Each block or pool cell is its level's piecewise-linear surface of the data pyramid, split along the
/// (i, j)-(i+1, j+1) diagonal, as `clipmap.wgsl` draws it (SAT LOD draws do not morph; a pool tile holds
/// its level's pyramid samples). Needs the resident pyramid.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "lattice cells of points in the view, far below 2^53"
)]
pub fn drawn_height(
    clipmap: &Clipmap,
    draws: &DrawList,
    block_quads: u32,
    u: f64,
    v: f64,
) -> Option<f64> {
    let synth = clipmap.synth_levels();
    let pyramid = clipmap.pyramid();
    let mut best: Option<f64> = None;
    for d in draws.iter().filter(|d| d.kind.surface()) {
        let c = d.covered(block_quads);
        let f = f64::from(1u32 << d.fine);
        let inside = u >= c.x0 as f64 * f
            && u <= (c.x1() - 1) as f64 * f
            && v >= c.y0 as f64 * f
            && v <= (c.y1() - 1) as f64 * f;
        let Some(k) = d.level.checked_sub(synth).filter(|_| inside) else {
            continue;
        };
        let s = f64::from(1u32 << d.level);
        let (x, y) = (u / s, v / s);
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let z = |a: i64, b: i64| f64::from(pyramid.at(k, a, b));
        let h = if fx >= fy {
            z(i, j) + fx * (z(i + 1, j) - z(i, j)) + fy * (z(i + 1, j + 1) - z(i + 1, j))
        } else {
            z(i, j) + fx * (z(i + 1, j + 1) - z(i, j + 1)) + fy * (z(i, j + 1) - z(i, j))
        };
        best = Some(best.map_or(h, |b: f64| b.max(h)));
    }
    best
}

/// Whether the view ray through pixel (x, y) of a `view`-sized frame planned as `plan` passes below the
/// surface its draws draw while inside the data (inset as `outside_data` insets the border cut), having
/// been above it there first: a clear pixel there is a hole. A ray that leaves the data through its side
/// above the surface sees past the terrain's edge, and one from an eye outside the data that enters
/// through its side below the surface sees where a solid terrain's side would be (the shader's
/// `through_side` hides skirts there): neither is a hole. Walks the ray in steps of an eighth of the
/// level-0 spacing. Needs the resident pyramid.
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
    let tol = 0.02 + 4.0e-6 * e.iter().fold(0.0f64, |m, v| m.max(v.abs()));
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
        let Some(z) = drawn_height(
            clipmap,
            plan.draws(),
            block_quads,
            eu + p.x / g0,
            ev - p.y / g0,
        ) else {
            continue;
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

/// The crack candidates of `image` (pixels of colour `clear` between terrain pixels of a column, as
/// [`crate::measure::crack_pixels`] counts them) whose view ray passes below the drawn surface inside the
/// data ([`ray_below_drawn_surface`]): the holes. Candidates past the first [`MAX_TRACED`] count as holes.
pub fn hole_pixels(
    image: &Image,
    clear: [u8; 4],
    plan: &FramePlan,
    clipmap: &Clipmap,
    camera: &Camera,
    block_quads: u32,
) -> u64 {
    let (mut holes, mut traced) = (0u64, 0u64);
    for (x, y) in crate::measure::image::crack_candidates(image, clear) {
        traced += 1;
        if traced > MAX_TRACED
            || ray_below_drawn_surface(
                plan,
                (image.width, image.height),
                clipmap,
                camera,
                block_quads,
                (x, y),
            )
        {
            holes += 1;
        }
    }
    holes
}
