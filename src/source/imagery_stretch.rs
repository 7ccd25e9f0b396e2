//! Stage 0, the source: imagery whose texels are far from square over its extent, read with its long
//! side's texels cut into near-square ones (docs/guide.md "Imagery", placement), for the colour rings,
//! which are square in texels (`plan/color_rings.rs`). `imagery_rows.rs` reads the file's rows.

use std::path::Path;

use super::imagery::Extent;
use crate::{Error, Result};

/// An image whose texels are at least twice as long one way as the other over its extent (a 257 x 4099
/// image over a square terrain), read with its long side's texels cut into `k` (the nearest whole factor
/// of the ratio), linearly interpolated between the file's texel centres and clamped at its edges.
/// The colour rings are square in texels: over such an image a ring held only its short span of the
/// fine axis, and the pixels past it fell to coarser rings whose texels on the coarse axis are 2^l times
/// the file's (a 30 m pixel drawn from 640 m texels of a 40 m image); near-square texels keep each ring
/// at the image's own resolution both ways.
pub(super) struct Stretch {
    /// Factors (columns, rows), one of them 1.
    k: (u32, u32),
    /// Size once resampled (columns, rows).
    size: (u32, u32),
    /// The next resampled row.
    next: u32,
    /// The next row of the file.
    file_next: u32,
    /// The file's last two rows read (RGB8), row r in `rows[r % 2]`: the two a resampled row blends.
    rows: [Vec<u8>; 2],
}

impl Stretch {
    /// The stretch of a `width` x `height` image over `extent`, or `None`: where its texels are at least
    /// twice as long one way as the other, the long way cut into the nearest whole factor of the ratio,
    /// as far as `max_texels` allows (none below a factor of 2).
    pub(super) fn new(width: u32, height: u32, extent: &Extent, max_texels: u64) -> Option<Box<Self>> {
        let (ew, eh) = extent.size();
        let ratio = (ew / f64::from(width)) / (eh / f64::from(height));
        if !ratio.is_finite() || ratio <= 0.0 {
            return None;
        }
        let long = ratio.max(1.0 / ratio);
        if long < 2.0 {
            return None;
        }
        let room = max_texels.checked_div(u64::from(width) * u64::from(height)).unwrap_or(0);
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a finite ratio of at least 2, rounded and capped to u32"
        )]
        let k = (long.round().min(f64::from(u32::MAX)) as u64).min(room);
        let k = u32::try_from(k).ok().filter(|&k| k >= 2)?;
        let (k, size) = if ratio > 1.0 {
            ((k, 1), (width.checked_mul(k)?, height))
        } else {
            ((1, k), (width, height.checked_mul(k)?))
        };
        Some(Box::new(Self {
            k,
            size,
            next: 0,
            file_next: 0,
            rows: [Vec::new(), Vec::new()],
        }))
    }

    /// Texels (columns, rows) once resampled.
    pub(super) fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The next resampled row.
    pub(super) fn next(&self) -> u32 {
        self.next
    }

    /// The next `out.len() / (3 width)` resampled rows of the file at `path` of `file` texels, whose rows
    /// `read_file` gives in order: each the linear blend of the two file rows about its centre, each of
    /// those resampled along the row the same way. Refused as
    /// [`ImageryRows::read_rows`](super::imagery_rows::ImageryRows::read_rows) refuses.
    pub(super) fn read(
        &mut self,
        path: &Path,
        (width, height): (u32, u32),
        out: &mut [u8],
        read_file: &mut dyn FnMut(&mut [u8]) -> Result<()>,
    ) -> Result<()> {
        let w = self.size.0 as usize * 3;
        let rows = out.len().checked_div(w).unwrap_or(0);
        let end = u64::from(self.next) + rows as u64;
        if rows * w != out.len() || end > u64::from(self.size.1) {
            return Err(Error::format(
                path,
                format!(
                    "{} bytes asked from row {}: whole rows of {w} bytes up to row {} are read",
                    out.len(),
                    self.next,
                    self.size.1
                ),
            ));
        }
        let (kx, ky) = (u64::from(self.k.0), u64::from(self.k.1));
        let den = 4 * kx * ky;
        for (y, orow) in (u64::from(self.next)..).zip(out.chunks_exact_mut(w)) {
            let (j0, fy) = centre_tap(y, ky, height);
            let j1 = (j0 + 1).min(height - 1);
            // The file's rows up to j1, read in order: the two slots then hold j0 and j1.
            while self.file_next <= j1 {
                let slot = (self.file_next % 2) as usize;
                self.rows[slot].resize(width as usize * 3, 0);
                read_file(&mut self.rows[slot])?;
                self.file_next += 1;
            }
            let (r0, r1) = (&self.rows[(j0 % 2) as usize], &self.rows[(j1 % 2) as usize]);
            for (x, o) in (0u64..).zip(orow.chunks_exact_mut(3)) {
                let (i0, fx) = centre_tap(x, kx, width);
                let i1 = (i0 + 1).min(width - 1);
                let (a, b) = (i0 as usize * 3, i1 as usize * 3);
                for (c, v) in o.iter_mut().enumerate() {
                    let along = |r: &[u8]| u64::from(r[a + c]) * (2 * kx - fx) + u64::from(r[b + c]) * fx;
                    let sum = along(r0) * (2 * ky - fy) + along(r1) * fy;
                    *v = u8::try_from((sum + den / 2) / den).unwrap_or(u8::MAX);
                }
            }
        }
        self.next = u32::try_from(end).unwrap_or(self.size.1);
        Ok(())
    }
}

/// Where resampled texel `i` of a side cut `k` ways samples the file's `n` texels: the file texel at or
/// before its centre and the next one's weight in 2k-ths (centres aligned: (i + 1/2) / k - 1/2), clamped
/// at the ends.
fn centre_tap(i: u64, k: u64, n: u32) -> (u32, u64) {
    if 2 * i + 1 < k {
        return (0, 0);
    }
    let at = 2 * i + 1 - k;
    match u32::try_from(at / (2 * k)) {
        Ok(j) if j + 1 < n => (j, at % (2 * k)),
        _ => (n - 1, 0),
    }
}
