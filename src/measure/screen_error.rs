//! Measurements: the screen-space error of a drawn frame against the data (docs/design.md "SAT LOD" 1). Not
//! the frame path.

use crate::bake::lod_tables::sample_error;
use crate::plan::camera::Camera;
use crate::plan::clipmap::Clipmap;
use crate::plan::cull;
use crate::plan::detail::stitch;
use crate::plan::frame_plan::FramePlan;
use crate::plan::lod::Lod;

/// The measured screen-space error of a drawn frame ([`screen_error`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScreenError {
    /// The largest projected vertical error over the measured samples, pixels.
    pub max_px: f64,
    /// The same over blocks whose selected level was not clamped to the held data (the ones the error
    /// bound is a promise about; equal to `max_px` in distance mode).
    pub max_px_unclamped: f64,
    /// Data samples measured (inside the frustum).
    pub samples: u64,
    /// Every `stride`-th sample in x and y was measured (1: all).
    pub stride: u32,
    /// Where `max_px` is: the data sample (column, row), the clipmap level drawn there, and whether that
    /// draw was clamped and whether it came from the detail pool.
    pub max_at: Option<MaxAt>,
}

/// The sample of a frame's largest measured error ([`ScreenError::max_at`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MaxAt {
    /// Data column.
    pub x: u32,
    /// Data row.
    pub y: u32,
    /// The clipmap level drawn there.
    pub level: u32,
    /// The draw's level was clamped to the held data.
    pub clamped: bool,
    /// The draw read a detail pool tile.
    pub pool: bool,
}

/// Most data samples [`screen_error`] visits; past it, it subsamples with a uniform stride.
pub const SCREEN_ERROR_SAMPLES: u64 = 1 << 22;

/// Measures a planned frame's screen-space error in a `view` (width, height) viewport (a measurement, not
/// the frame path): for each data sample
/// under a drawn block of level L, the error map value e_L = |H_0 - PL(H_L)| (docs/design.md "SAT LOD" 1, from
/// `lod`'s tables) projected on the screen at that sample, [`crate::plan::camera::VerticalScale::px`]
/// (the true projection of a vertical segment of length e there, in the longer direction), for samples
/// inside the view frustum. The GC 6.2 morph of distance mode is not modelled (its vertices lie between levels L
/// and L + 1). Visits at most [`SCREEN_ERROR_SAMPLES`] samples (a uniform stride past it).
pub fn screen_error(
    plan: &FramePlan,
    view: (u32, u32),
    clipmap: &Clipmap,
    camera: &Camera,
    lod: &Lod,
) -> ScreenError {
    let tables = lod.tables();
    let synth = lod.synth_levels();
    let data = clipmap.pyramid().level(0);
    let spacing = clipmap.g0() * f64::from(1u32 << clipmap.synth_levels());
    let (w, h) = view;
    let frustum = cull::Frustum::new(camera, f64::from(w) / f64::from(h));
    let scale = camera.vertical_scale(view);
    // The data's last sample in level-0 lattice units.
    let last = (
        i64::from(data.width() - 1) << clipmap.synth_levels(),
        i64::from(data.height() - 1) << clipmap.synth_levels(),
    );
    let boxes = || {
        plan.draws()
            .iter()
            .filter(|d| d.kind.surface() && d.stitch == 0)
            .filter_map(move |d| {
                // In the fine lattice: a snapped tile is its level's surface cut at the piece's edge, so
                // its level's error map over the covered samples is exact.
                let c = d.covered(d.quads.max(1));
                let (l, f) = (d.level, d.fine);
                let (a, cc, b, dd) = (c.x0 << f, c.y0 << f, (c.x1() - 1) << f, (c.y1() - 1) << f);
                // Geometry past the data collapses onto its border (not a surface to measure): a block
                // that meets the data only on its border line draws no area there.
                let inside = b > 0 && dd > 0 && a < last.0 && cc < last.1;
                inside.then(|| {
                    (
                        l,
                        (d.clamped, d.pool.is_some()),
                        tables.data_box(synth, a, cc, b, dd),
                    )
                })
            })
    };
    let total: u64 = boxes()
        .map(|(_, _, (x0, y0, x1, y1))| u64::from(x1 - x0) * u64::from(y1 - y0))
        .sum();
    let mut stride = 1u32;
    while total / u64::from(stride * stride) > SCREEN_ERROR_SAMPLES {
        stride += 1;
    }
    let mut out = ScreenError {
        stride,
        ..ScreenError::default()
    };
    let (ox, oy) = clipmap.origin();
    let top = oy + f64::from(data.height() - 1) * spacing;
    // Visits the samples of data box `bx` in the frustum, aligned to the stride so overlapping boxes
    // visit the same samples; `err(x, y, h0)` is the vertical error drawn there (h0: the data height).
    let visit = |out: &mut ScreenError,
                 (x0, y0, x1, y1): (u32, u32, u32, u32),
                 (level, clamped, pool): (u32, bool, bool),
                 err: &dyn Fn(u32, u32, f64) -> f64| {
        for y in (y0.next_multiple_of(stride)..y1).step_by(stride as usize) {
            for x in (x0.next_multiple_of(stride)..x1).step_by(stride as usize) {
                let h0 = f64::from(data.at_clamped(i64::from(x), i64::from(y)));
                let rel = glam::DVec3::new(
                    ox + f64::from(x) * spacing - camera.eye.x,
                    top - f64::from(y) * spacing - camera.eye.y,
                    h0 - camera.eye.z,
                );
                if !frustum.intersects(rel, rel) {
                    continue;
                }
                let e = err(x, y, h0);
                out.samples += 1;
                let px = scale.px(rel, e);
                if px > out.max_px {
                    out.max_px = px;
                    out.max_at = Some(MaxAt {
                        x,
                        y,
                        level,
                        clamped,
                        pool,
                    });
                }
                if !clamped {
                    out.max_px_unclamped = out.max_px_unclamped.max(px);
                }
            }
        }
    };
    let pyramid = clipmap.pyramid();
    for (l, (clamped, pool), bx) in boxes() {
        // The tables hold level-resolution maxima: the per-sample error comes from the pyramid.
        let k = l
            .checked_sub(synth)
            .filter(|&k| tables.level(k).is_some_and(|t| t.tables().is_some()));
        let Some(k) = k else {
            // The data level or finer: no error against the data.
            continue;
        };
        visit(&mut out, bx, (l, clamped, pool), &|x, y, _| {
            f64::from(sample_error(pyramid, k.min(40), x.into(), y.into()))
        });
    }
    // Stitched pool cells, unit by unit: a coarse unit is level k + 1's surface and a plain fan level
    // k's (their error maps); a fan whose corners read z_c or whose midpoints collapse is measured
    // against the data through the stitched surface itself (`stitch::height`).
    let masks = &plan.detail().masks;
    for d in plan.draws().iter().filter(|d| d.stitch != 0) {
        let (l, clamped) = (d.level, d.clamped);
        let Some(k) = l.checked_sub(synth) else {
            continue;
        };
        let mask = &masks[usize::from(d.stitch) - 1];
        let (ua, ub) = stitch::units(&d.bounds);
        for b in 0..i64::from(ub) {
            for a in 0..i64::from(ua) {
                let coarse = stitch::coarse(mask, ua, ub, a, b);
                let flags = stitch::unit_flags(mask, ua, ub, a, b);
                let (ux, uy) = (d.bounds.x0 + 2 * a, d.bounds.y0 + 2 * b);
                let (p0, q0, p1, q1) = (ux << l, uy << l, (ux + 2) << l, (uy + 2) << l);
                if !(p1 > 0 && q1 > 0 && p0 < last.0 && q0 < last.1) {
                    continue;
                }
                let z =
                    |i: u32, j: u32| f64::from(pyramid.at(k, ux + i64::from(i), uy + i64::from(j)));
                let zc = |i: u32, j: u32| {
                    f64::from(pyramid.at(k + 1, (ux + i64::from(i)) >> 1, (uy + i64::from(j)) >> 1))
                };
                let unit = f64::from(1u32 << k);
                let bx = tables.data_box(synth, p0, q0, p1, q1);
                visit(
                    &mut out,
                    bx,
                    (l + u32::from(coarse), clamped, true),
                    &|x, y, h0| {
                        if coarse {
                            f64::from(sample_error(pyramid, k + 1, x.into(), y.into()))
                        } else if flags == 0 {
                            f64::from(sample_error(pyramid, k, x.into(), y.into()))
                        } else {
                            #[expect(
                                clippy::cast_precision_loss,
                                reason = "lattice offsets in a unit are small"
                            )]
                            let (fx, fy) = (
                                (i64::from(x) - (ux << k)) as f64 / unit,
                                (i64::from(y) - (uy << k)) as f64 / unit,
                            );
                            stitch::height(flags, false, &z, &zc, fx, fy)
                                .map_or(0.0, |h| (h0 - h).abs())
                        }
                    },
                );
            }
        }
    }
    out
}
