//! Stage 2, the per-frame plan: the GC section 6.2 transition morph weight of a ring vertex.

use crate::plan::frame::Rect;

/// The morph weight alpha of GC section 6.2 for a vertex of one level.
///
/// All quantities are in that level's lattice units: `(x, y)` the vertex, `viewer` the eye's (x, y)
/// projected into the level, `active` the level's active region (x_min = active.x0, x_max = active.x1() - 1),
/// `n` the ring size. With w = n / 10:
///
/// ```text
/// alpha_x = clamp((|x - v_x| - ((x_max - x_min) / 2 - w - 1)) / w, 0, 1)
/// alpha   = max(alpha_x, alpha_y)
/// ```
///
/// so alpha is 0 in the interior and reaches 1 over the last w samples before the outer boundary, where the
/// vertex takes the coarser level's surface z_c: z' = (1 - alpha) z + alpha z_c. The vertex shader mirrors
/// this expression in f32 operation for operation.
pub fn morph_alpha(x: f32, y: f32, viewer: [f32; 2], active: &Rect, n: u32) -> f32 {
    #[expect(
        clippy::cast_precision_loss,
        reason = "active widths are at most 2048, exact in f32"
    )]
    let (half_x, half_y) = ((active.w as f32 - 1.0) * 0.5, (active.h as f32 - 1.0) * 0.5);
    #[expect(clippy::cast_precision_loss, reason = "n < 2048, exact in f32")]
    let w = n as f32 / 10.0;
    let ax = (((x - viewer[0]).abs() - (half_x - w - 1.0)) / w).clamp(0.0, 1.0);
    let ay = (((y - viewer[1]).abs() - (half_y - w - 1.0)) / w).clamp(0.0, 1.0);
    ax.max(ay)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morph_alpha_interior_boundary_continuous() {
        let n = 63;
        let a = Rect {
            x0: 0,
            y0: 0,
            w: n,
            h: n,
        };
        let v = [31.0, 31.0];
        assert_eq!(morph_alpha(31.0, 31.0, v, &a, n), 0.0);
        assert_eq!(morph_alpha(20.0, 40.0, v, &a, n), 0.0);
        assert_eq!(morph_alpha(0.0, 31.0, v, &a, n), 1.0);
        assert_eq!(morph_alpha(31.0, 62.0, v, &a, n), 1.0);
        // Continuous: Lipschitz 1/w along a line from the centre to the edge.
        let mut prev = 0.0;
        for k in 0..=620 {
            let x = 31.0 + k as f32 * 0.05;
            let al = morph_alpha(x, 31.0, v, &a, n);
            assert!((al - prev).abs() <= 0.05 / 6.3 + 1e-5, "jump at x = {x}");
            assert!(al >= prev);
            prev = al;
        }
    }
}
