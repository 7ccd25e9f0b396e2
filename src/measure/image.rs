//! Measurements on read-back images: cracks (clear colour inside the silhouette) and RMSE between two
//! images.

use crate::gpu::readback::Image;

/// The loud clear colour of crack measurements: pure magenta, a colour the shading never makes.
pub const CRACK_CLEAR: [f64; 4] = [1.0, 0.0, 1.0, 1.0];

/// [`CRACK_CLEAR`] as RGBA8.
pub const CRACK_CLEAR_RGBA8: [u8; 4] = [255, 0, 255, 255];

/// Clear-colour pixels inside the terrain's silhouette: in each pixel column, the pixels of colour `clear`
/// lying between the lowest and the highest pixel of any other colour. A watertight render has none.
pub fn crack_pixels(image: &Image, clear: [u8; 4]) -> u64 {
    crack_candidates(image, clear).count() as u64
}

/// The (x, y) of the pixels [`crack_pixels`] counts, column by column, top to bottom (the column rule;
/// [`crate::measure::hole_pixels`] traces them).
pub(crate) fn crack_candidates(
    image: &Image,
    clear: [u8; 4],
) -> impl Iterator<Item = (u32, u32)> + '_ {
    (0..image.width).flat_map(move |x| {
        let is_clear = move |y: u32| image.pixel(x, y) == clear;
        let top = (0..image.height).find(|&y| !is_clear(y));
        // An empty column has no top, and then no bottom: the range below is empty.
        let bottom = (0..image.height).rev().find(|&y| !is_clear(y));
        let rows = match (top, bottom) {
            (Some(t), Some(b)) => t..b + 1,
            _ => 0..0,
        };
        rows.filter(move |&y| is_clear(y)).map(move |y| (x, y))
    })
}

/// Root-mean-square difference of two RGBA8 images of the same size over every pixel and the R, G, B
/// channels, in 0..255 units (None when the sizes differ).
pub fn image_rmse(a: &Image, b: &Image) -> Option<f64> {
    if a.width != b.width || a.height != b.height || a.rgba.len() != b.rgba.len() {
        return None;
    }
    let (mut sum, mut n) = (0.0f64, 0u64);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for c in 0..3 {
            let d = f64::from(p[c]) - f64::from(q[c]);
            sum += d * d;
            n += 1;
        }
    }
    Some(if n == 0 { 0.0 } else { (sum / n as f64).sqrt() })
}
