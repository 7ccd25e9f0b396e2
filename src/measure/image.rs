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
    let mut cracks = 0;
    for x in 0..image.width {
        let is_clear = |y: u32| image.pixel(x, y) == clear;
        let Some(top) = (0..image.height).find(|&y| !is_clear(y)) else {
            continue;
        };
        let bottom = (0..image.height)
            .rev()
            .find(|&y| !is_clear(y))
            .expect("a non-clear pixel exists");
        cracks += (top..=bottom).filter(|&y| is_clear(y)).count() as u64;
    }
    cracks
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
