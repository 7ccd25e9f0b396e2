//! Stage 2, the per-frame plan: the CPU twin of the surface a plan draws: the height at a point of the
//! blocks, pool cells and stitched units drawn there, read from the data pyramid (the resident pyramid or
//! a streamed terrain's cached tiles, through [`Clipmap::data_height`]). The hole measurement
//! (`measure/holes.rs`) traces rays against it; `TerrainRenderer::drawn_height_at` answers with it.

use crate::plan::clipmap::{morph_alpha, Clipmap};
use crate::plan::cull::DrawKind;
use crate::plan::detail::stitch;
use crate::plan::frame::Rect;
use crate::plan::frame_plan::FramePlan;

/// The drawn surface above a level-0 lattice point ([`drawn_height`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drawn {
    /// The highest height drawn there, metres.
    Height(f64),
    /// No block or pool cell draws the point.
    Nothing,
    /// A sample the drawn surface needs is not readable: a streamed terrain whose tile has left the
    /// cache (a measurement never decodes).
    Unread,
}

/// The height of the surface `draws` draw at level-0 lattice point (u, v) (fractional), the highest where
/// several blocks meet there (their skirts close the step between them).
/// Each block or pool cell is its level's piecewise-linear surface of the data pyramid, split along the
/// (i, j)-(i+1, j+1) diagonal, as `clipmap.wgsl` draws it (SAT LOD draws do not morph; a pool tile holds
/// its level's pyramid samples), and a stitched cell its units' surface ([`stitch::height`]), read
/// through [`Clipmap::data_height`]: the resident pyramid, or a streamed terrain's tile cache. With GC
/// 6.2's morph on (distance LOD), a ring block's vertices take the ring's (z, z_c) texels blended by
/// their [`morph_alpha`], as the vertex shader does.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    reason = "lattice cells of points in the view, far below 2^53"
)]
pub fn drawn_height(
    clipmap: &Clipmap,
    plan: &FramePlan,
    block_quads: u32,
    u: f64,
    v: f64,
) -> Drawn {
    let synth = clipmap.synth_levels();
    let mut best = Drawn::Nothing;
    let mut keep = |h: f64| {
        best = Drawn::Height(match best {
            Drawn::Height(b) => b.max(h),
            _ => h,
        });
    };
    // GC 6.2's morph (distance LOD's ring blocks; SAT LOD and pool cells never morph).
    let morph = plan.globals().params[0];
    for (idx, d) in plan
        .draws()
        .iter()
        .enumerate()
        .filter(|(_, d)| d.kind.surface())
    {
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
        if d.stitch != 0 {
            // A stitched cell: the unit under the point, through the stitch rule.
            let mask = &plan.detail().masks[usize::from(d.stitch) - 1];
            let (ua, ub) = stitch::units(&d.bounds);
            let a = (((x - c.x0 as f64) / 2.0).floor() as i64).clamp(0, i64::from(ua) - 1);
            let b = (((y - c.y0 as f64) / 2.0).floor() as i64).clamp(0, i64::from(ub) - 1);
            let (ux, uy) = (c.x0 + 2 * a, c.y0 + 2 * b);
            let mut zs = [[0.0f64; 3]; 3];
            let mut zcs = [[0.0f64; 3]; 3];
            for j in 0..3 {
                for i in 0..3 {
                    let (p, q) = (ux + i as i64, uy + j as i64);
                    let Some(z) = clipmap.data_height(k, p, q) else {
                        return Drawn::Unread;
                    };
                    zs[j][i] = f64::from(z);
                    if i % 2 == 0 && j % 2 == 0 {
                        let Some(zc) = clipmap.data_height(k + 1, p >> 1, q >> 1) else {
                            return Drawn::Unread;
                        };
                        zcs[j][i] = f64::from(zc);
                    }
                }
            }
            let h = stitch::height(
                stitch::unit_flags(mask, ua, ub, a, b),
                stitch::coarse(mask, ua, ub, a, b),
                &|i, j| zs[j as usize][i as usize],
                &|i, j| zcs[j as usize][i as usize],
                x - ux as f64,
                y - uy as f64,
            );
            if let Some(h) = h {
                keep(h);
            }
            continue;
        }
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let morphed = (morph != 0.0 && d.kind == DrawKind::Block).then(|| {
            (
                plan.draw_uniform(idx),
                clipmap.frame().levels[d.level as usize].active,
            )
        });
        let z = |a: i64, b: i64| match &morphed {
            // The vertex shader's height: the ring's (z, z_c) texel blended by the vertex's alpha,
            // in f32 as `twin::clipmap::cpu_vertex` computes it.
            Some((du, active)) => {
                let [z, zc] = clipmap.ring(d.level).get(a, b);
                let rel = Rect {
                    x0: 0,
                    y0: 0,
                    w: active.w,
                    h: active.h,
                };
                #[expect(
                    clippy::cast_sign_loss,
                    reason = "n is stored exactly as a positive f32"
                )]
                let n = du.morph_w[1] as u32;
                let alpha = morph_alpha(
                    (a - active.x0) as f32,
                    (b - active.y0) as f32,
                    [du.morph[0], du.morph[1]],
                    &rel,
                    n,
                ) * morph;
                Some(f64::from((1.0 - alpha) * z + alpha * zc))
            }
            None => clipmap.data_height(k, a, b).map(f64::from),
        };
        let (Some(z00), Some(z10), Some(z11), Some(z01)) =
            (z(i, j), z(i + 1, j), z(i + 1, j + 1), z(i, j + 1))
        else {
            return Drawn::Unread;
        };
        let h = if fx >= fy {
            z00 + fx * (z10 - z00) + fy * (z11 - z10)
        } else {
            z00 + fx * (z11 - z01) + fy * (z01 - z00)
        };
        keep(h);
    }
    best
}
