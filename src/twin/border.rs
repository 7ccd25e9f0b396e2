//! CPU twin of what a frame must cover at the data's border (`outside_data` and `through_side` in
//! `shaders_gles/clipmap.wgsl`): the pixels whose view ray meets the terrain inside the data's extent,
//! marched on the CPU through the bilinear heights. A frame that draws a pixel none of whose rays within a
//! pixel meets the data draws a curtain: a skirt below the data's edge, or a ring past it. Independent of
//! any GPU reference, so it holds on any driver (docs/real-drivers.md).

use glam::{DVec3, Vec4};

use crate::bake::horizon::height_bilinear;
use crate::gpu::readback::Image;
use crate::plan::camera::Camera;
use crate::source::Heightmap;

/// Which pixels of a `width` x `height` view of `hm` from `camera` see the terrain inside the data's
/// extent: row-major, `true` where the ray through the pixel's centre meets the bilinear surface before
/// it leaves the data's box (extent x height range) or passes the far plane, crossing it from above or
/// from below.
pub fn data_coverage(hm: &Heightmap, camera: &Camera, width: u32, height: u32) -> Vec<bool> {
    let aspect = f64::from(width) / f64::from(height);
    let inv = camera.view_proj_relative(aspect).inverse();
    let (lo, hi) = hm.range();
    let (ox, oy) = hm.origin();
    let (ex, ey) = hm.extent_m();
    let bounds = (
        DVec3::new(ox, oy, f64::from(lo)),
        DVec3::new(ox + ex, oy + ey, f64::from(hi)),
    );
    let mut out = Vec::with_capacity(width as usize * height as usize);
    for py in 0..height {
        for px in 0..width {
            #[expect(clippy::cast_possible_truncation, reason = "NDC in [-1, 1]")]
            let ndc = (
                ((f64::from(px) + 0.5) / f64::from(width) * 2.0 - 1.0) as f32,
                (1.0 - (f64::from(py) + 0.5) / f64::from(height) * 2.0) as f32,
            );
            let p = inv * Vec4::new(ndc.0, ndc.1, 0.5, 1.0);
            let dir = (p.truncate() / p.w).as_dvec3().normalize();
            out.push(hits(hm, camera.eye, dir, bounds, camera.far));
        }
    }
    out
}

/// Whether the ray from `eye` along unit `dir` meets the bilinear surface of `hm` inside `bounds` (the
/// data's box) within `far`: the ray is clipped to the box, then marched in quarter-sample steps.
fn hits(hm: &Heightmap, eye: DVec3, dir: DVec3, bounds: (DVec3, DVec3), far: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, far);
    for a in 0..3 {
        let (o, d, lo, hi) = (eye[a], dir[a], bounds.0[a], bounds.1[a]);
        if d.abs() < 1e-12 {
            if o < lo || o > hi {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((lo - o) / d, (hi - o) / d);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    if t0 > t1 {
        return false;
    }
    let step = f64::from(hm.spacing()) * 0.25;
    let above = |t: f64| {
        let p = eye + dir * t;
        let (u, v) = hm.world_to_grid(p.x, p.y);
        p.z > height_bilinear(hm, u, v)
    };
    // The surface is met where the ray crosses it, from above or (having entered through the data's
    // side, below the edge) from below, as the surface drawn double-sided is seen; a ray that enters
    // below the edge and leaves without crossing sees nothing of the data.
    let start = above(t0);
    let mut t = t0 + step;
    while t <= t1 {
        if above(t) != start {
            return true;
        }
        t += step;
    }
    above(t1) != start
}

/// Pixels `image` draws where neither the pixel's ray nor any of its 8 neighbours' meets the data
/// (`coverage` from [`data_coverage`] of the same view): curtains, with the silhouette's one-pixel
/// rasterisation band left out. A pixel within one level per channel of `clear` (the clear colour's
/// RGBA8 value: a driver may round the clear colour either way, GLES 3.0 section 2.1.6.1) is not drawn.
pub fn curtain_pixels(image: &Image, clear: [u8; 4], coverage: &[bool]) -> u64 {
    let (w, h) = (image.width as usize, image.height as usize);
    assert_eq!(coverage.len(), w * h, "coverage of another view size");
    let mut n = 0;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let p = &image.rgba[i * 4..i * 4 + 4];
            if p.iter().zip(clear).all(|(a, b)| a.abs_diff(b) <= 1) {
                continue;
            }
            let near = (y.saturating_sub(1)..(y + 2).min(h))
                .any(|yy| (x.saturating_sub(1)..(x + 2).min(w)).any(|xx| coverage[yy * w + xx]));
            n += u64::from(!near);
        }
    }
    n
}

/// The RGBA8 value of a display-encoded clear colour, rounded to nearest.
#[expect(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    reason = "colours clamped to [0, 1], as bytes"
)]
pub fn clear_rgba8(clear: [f64; 4]) -> [u8; 4] {
    clear.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}
