//! Stage 1, the bake: the imagery's colour pyramid, GC section 3's "additional images" at their own
//! resolution. Level 0 is the image; each coarser level's texel is the box mean of the 2 x 2 texels of
//! the finer level under it (texel spacing doubles), so a level's texel is the mean of the source over
//! its area. A side of odd length repeats its last texel: the coarser level reaches up to one fine texel
//! past the image's east and south edges, with the edge's colour (docs/guide.md "Imagery").
//!
//! The package stores every even level but the coarsest as a residual against the level above
//! (alternating: the odd levels are stored whole), a Laplacian pyramid (Burt & Adelson 1983) closed on
//! the decoded parent as GC's compressed pyramid is (Losasso & Hoppe 2004, section 7): [`up_at`] is the
//! prediction, a bilinear 2x upsample of one parent tile in integers, so the bake and the runtime agree
//! bit for bit.

/// The coarsest level's longest side is at most this many texels: one tile of the package.
pub const COARSEST_SIDE: u32 = 256;

/// One level of the colour pyramid: RGB8 texels, row-major from the north-west corner.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ColorLevel {
    /// Texel columns.
    pub width: u32,
    /// Texel rows.
    pub height: u32,
    /// RGB8, `width * height * 3` bytes.
    pub texels: Vec<u8>,
}

impl ColorLevel {
    /// The next coarser level: each texel the rounded mean of the 2 x 2 texels under it (the last
    /// column or row repeated where a side is odd).
    pub fn coarser(&self) -> ColorLevel {
        let mut texels = Vec::new();
        halve_rows(&self.texels, self.width, self.height, &mut texels);
        ColorLevel {
            width: self.width.div_ceil(2).max(1),
            height: self.height.div_ceil(2).max(1),
            texels,
        }
    }
}

/// Appends to `out` the coarser rows of a band of `rows` RGB8 rows `width` texels wide: each texel the
/// rounded mean of the 2 x 2 texels under it, the last column repeated where `width` is odd and the band's
/// last row where `rows` is odd. A band that starts at an even row of its level and is followed by more
/// rows has an even count, so halving a level band by band gives [`ColorLevel::coarser`]'s texels.
pub fn halve_rows(texels: &[u8], width: u32, rows: u32, out: &mut Vec<u8>) {
    let w = width.div_ceil(2).max(1) as usize;
    let h = rows.div_ceil(2) as usize;
    let (fw, fh) = (width as usize, rows as usize);
    out.reserve(w * h * 3);
    for y in 0..h {
        let y0 = (2 * y).min(fh - 1);
        let y1 = (2 * y + 1).min(fh - 1);
        for x in 0..w {
            let x0 = (2 * x).min(fw - 1);
            let x1 = (2 * x + 1).min(fw - 1);
            for c in 0..3 {
                let at = |xx: usize, yy: usize| u16::from(texels[(yy * fw + xx) * 3 + c]);
                let sum = at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1);
                out.push(u8::try_from((sum + 2) / 4).unwrap_or(255));
            }
        }
    }
}

/// How many levels a pyramid over `width` x `height` texels has: halved until the longest side is at most
/// [`COARSEST_SIDE`] (level 0 included, so at least 1).
pub fn level_count(width: u32, height: u32) -> u32 {
    let mut side = width.max(height);
    let mut levels = 1;
    while side > COARSEST_SIDE {
        side = side.div_ceil(2);
        levels += 1;
    }
    levels
}

/// The sizes of every level, finest first.
pub fn level_sizes(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(width, height)];
    for _ in 1..level_count(width, height) {
        let (w, h) = sizes[sizes.len() - 1];
        sizes.push((w.div_ceil(2), h.div_ceil(2)));
    }
    sizes
}

/// One decoded parent tile, a prediction's source: RGB8 rows `stride` texels apart, `width` x `height`
/// of them the tile's.
#[derive(Clone, Copy, Debug)]
pub struct Parent<'a> {
    /// RGB8 texels, row-major.
    pub texels: &'a [u8],
    /// Texels from one row to the next.
    pub stride: usize,
    /// Texel columns of the tile.
    pub width: u32,
    /// Texel rows of the tile.
    pub height: u32,
}

/// The parent tile's bilinear 2x upsample at texel (x, y) of the doubled tile, channel `c`: texel
/// centres aligned (a fine texel lies a quarter of a coarse texel from its parent's centre), so the
/// weights are 9/16 for the parent, 3/16 for each of its two nearest neighbours toward the fine texel and
/// 1/16 for the diagonal one, rounded: (9a + 3b + 3c + d + 8) >> 4. Neighbours past the tile's border
/// are clamped to it: a fine tile depends on its parent tile alone. A weighted mean of 8-bit values, so
/// 0..=255; integers, so the same on every machine.
#[inline]
pub fn up_at(p: &Parent<'_>, x: u32, y: u32, c: usize) -> i32 {
    let (i, j) = ((x / 2).min(p.width - 1), (y / 2).min(p.height - 1));
    let i2 = if x.is_multiple_of(2) { i.saturating_sub(1) } else { (i + 1).min(p.width - 1) };
    let j2 = if y.is_multiple_of(2) { j.saturating_sub(1) } else { (j + 1).min(p.height - 1) };
    let at = |xx: u32, yy: u32| i32::from(p.texels[(yy as usize * p.stride + xx as usize) * 3 + c]);
    (9 * at(i, j) + 3 * at(i2, j) + 3 * at(i, j2) + at(i2, j2) + 8) >> 4
}

/// The offset of a level's residual against its prediction: a residual of 0 is stored as 128.
const MID: i32 = 128;

/// Turns `texels` (RGB8, `w` x `h` packed) at (ox, oy) of `parent`'s doubled tile into residuals
/// against the prediction: `clamp(texel - up + 128, 0, 255)`.
pub fn to_residual(parent: &Parent<'_>, ox: u32, oy: u32, w: u32, h: u32, texels: &mut [u8]) {
    each_predicted(parent, ox, oy, w, h, texels, |t, p| t - p + MID);
}

/// Turns decoded residuals (RGB8, `w` x `h` packed) at (ox, oy) of `parent`'s doubled tile back into
/// texels: `clamp(up + residual - 128, 0, 255)`.
pub fn from_residual(parent: &Parent<'_>, ox: u32, oy: u32, w: u32, h: u32, texels: &mut [u8]) {
    each_predicted(parent, ox, oy, w, h, texels, |r, p| p + r - MID);
}

/// Replaces each of `w` x `h` texels by `f(texel, prediction)` clamped to 8 bits.
fn each_predicted(
    parent: &Parent<'_>,
    ox: u32,
    oy: u32,
    w: u32,
    h: u32,
    texels: &mut [u8],
    f: impl Fn(i32, i32) -> i32,
) {
    for y in 0..h {
        for x in 0..w {
            let at = (y as usize * w as usize + x as usize) * 3;
            for c in 0..3 {
                let p = up_at(parent, ox + x, oy + y, c);
                let v = f(i32::from(texels[at + c]), p).clamp(0, 255);
                texels[at + c] = u8::try_from(v).unwrap_or(u8::MAX);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mean_of_two_by_two() {
        let l = ColorLevel {
            width: 3,
            height: 2,
            texels: vec![
                0, 0, 0, 4, 8, 12, 100, 100, 100, //
                8, 8, 8, 4, 0, 255, 200, 0, 50,
            ],
        };
        let c = l.coarser();
        assert_eq!((c.width, c.height), (2, 1));
        // (0 + 4 + 8 + 4 + 2) / 4 = 4, (0 + 8 + 8 + 0 + 2) / 4 = 4, (0 + 12 + 8 + 255 + 2) / 4 = 69.
        assert_eq!(&c.texels[..3], &[4, 4, 69]);
        // The odd column repeats: (100 + 100 + 200 + 200 + 2) / 4 = 150.
        assert_eq!(&c.texels[3..6], &[150, 50, 75]);
    }

    #[test]
    fn levels_until_one_tile() {
        assert_eq!(level_count(2, 2), 1);
        assert_eq!(level_count(256, 100), 1);
        assert_eq!(level_count(257, 3), 2);
        assert_eq!(level_count(1024, 1024), 3);
        assert_eq!(
            level_sizes(1025, 7),
            vec![(1025, 7), (513, 4), (257, 2), (129, 1)]
        );
    }

    #[test]
    fn up_keeps_constants_and_ramps() {
        // A constant parent predicts the constant everywhere, the clamped borders included.
        let flat = vec![77u8; 5 * 4 * 3];
        let p = Parent { texels: &flat, stride: 5, width: 5, height: 4 };
        for y in 0..8 {
            for x in 0..10 {
                assert_eq!(up_at(&p, x, y, 1), 77);
            }
        }
        // A ramp of 16 per coarse texel stays a ramp of 4 per fine texel inside the tile: the fine
        // texel 2i + 1 lies a quarter of a coarse texel east of i's centre.
        let ramp: Vec<u8> = (0..4u8).flat_map(|_| (0..4u8).flat_map(|i| [16 * i + 8; 3])).collect();
        let p = Parent { texels: &ramp, stride: 4, width: 4, height: 4 };
        let row: Vec<i32> = (0..8).map(|x| up_at(&p, x, 3, 0)).collect();
        assert_eq!(row, vec![8, 12, 20, 28, 36, 44, 52, 56]);
        // Residuals against the prediction invert exactly where nothing clamps.
        let mut t: Vec<u8> = (0..8 * 8 * 3u8).map(|v| v % 60 + 40).collect();
        let src = t.clone();
        to_residual(&p, 0, 0, 8, 8, &mut t);
        from_residual(&p, 0, 0, 8, 8, &mut t);
        assert_eq!(t, src);
        // A quadrant of the doubled tile, read through a stride wider than the tile.
        let mut wide = vec![0u8; 6 * 4 * 3];
        for y in 0..4 {
            wide[y * 18..y * 18 + 12].copy_from_slice(&ramp[y * 12..y * 12 + 12]);
        }
        let q = Parent { texels: &wide, stride: 6, width: 4, height: 4 };
        assert_eq!(up_at(&q, 5, 2, 0), up_at(&p, 5, 2, 0));
    }
}
