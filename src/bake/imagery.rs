//! Stage 1, the bake: the imagery's colour pyramid, GC section 3's "additional images" at their own
//! resolution. Level 0 is the image; each coarser level's texel is the box mean of the 2 x 2 texels of
//! the finer level under it (texel spacing doubles), so a level's texel is the mean of the source over
//! its area. A side of odd length repeats its last texel: the coarser level reaches up to one fine texel
//! past the image's east and south edges, with the edge's colour (docs/guide.md "Imagery").

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
}
