//! Stage 0, the source read a band of rows at a time: what the out-of-core bake (stage 1b) streams from,
//! so that no terrain-sized buffer is needed to bake a package.

use std::borrow::Borrow;
use std::path::{Path, PathBuf};

use crate::{Error, Result};
use crate::source::Heightmap;

/// What a [`RowSource`] says of itself.
#[derive(Clone, Debug)]
pub struct RowGrid {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Sample spacing, metres (N-S; the grid is drawn with square cells of it).
    pub spacing: f32,
    /// The source's E-W spacing, metres ([`Heightmap::ew_spacing`]).
    pub ew_spacing: f32,
    /// World position of the south-west sample, metres ([`Heightmap::origin`]).
    pub origin: (f64, f64),
    /// What errors name: the file, or a description.
    pub path: PathBuf,
}

/// A terrain read top to bottom in bands of whole rows (row 0 north, like [`Heightmap`]).
pub trait RowSource {
    /// Its size, spacing, origin and name.
    fn grid(&self) -> &RowGrid;
    /// Fills `out`, a whole number of rows, with the rows from `y0` on; an error if they run past the
    /// last row or `out` is not whole rows.
    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()>;

    /// Samples per row.
    fn width(&self) -> u32 {
        self.grid().width
    }
    /// Rows.
    fn height(&self) -> u32 {
        self.grid().height
    }
    /// Sample spacing, metres.
    fn spacing(&self) -> f32 {
        self.grid().spacing
    }
    /// World position of the south-west sample, metres ([`Heightmap::origin`]).
    fn origin(&self) -> (f64, f64) {
        self.grid().origin
    }
    /// What errors name: the file, or a description.
    fn path(&self) -> &Path {
        &self.grid().path
    }
}

/// Reads `buf.len()` bytes of `file` (named `path` in errors) from byte `at`: a file shorter than its
/// header said when checked (truncated since) is a size mismatch.
pub(crate) fn read_exact_at(
    file: &mut std::fs::File,
    path: &Path,
    at: u64,
    buf: &mut [u8],
) -> Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    file.seek(SeekFrom::Start(at))
        .and_then(|_| file.read_exact(buf))
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => Error::SizeMismatch {
                path: path.into(),
                actual: at,
                expected: "the length when first checked".into(),
            },
            _ => Error::io(path, "cannot read", e),
        })
}

/// Checks that `out` is whole rows of `src` starting at `y0`, inside the terrain (a caller bug otherwise,
/// reported as an error rather than a panic since sources are user input).
pub(crate) fn check_band(src: &(impl RowSource + ?Sized), y0: u32, out: &[f32]) -> Result<()> {
    let w = src.width() as usize;
    let rows = out.len() / w.max(1);
    if w == 0 || !out.len().is_multiple_of(w) || y0 as usize + rows > src.height() as usize {
        return Err(Error::format(
            src.path(),
            format!(
                "a band of {} samples from row {y0} is not whole rows inside {} x {}",
                out.len(),
                src.width(),
                src.height()
            ),
        ));
    }
    Ok(())
}

/// A terrain already in memory, owned or borrowed, read in bands (loaders that decode whole files, and
/// tests).
#[derive(Debug)]
pub struct Resident<H> {
    hm: H,
    grid: RowGrid,
}

impl<H: Borrow<Heightmap>> Resident<H> {
    /// The rows of `hm`.
    pub fn new(hm: H) -> Self {
        let h = hm.borrow();
        let grid = RowGrid {
            width: h.width(),
            height: h.height(),
            spacing: h.spacing(),
            ew_spacing: h.ew_spacing(),
            origin: h.origin(),
            path: PathBuf::from("<heightmap>"),
        };
        Self { hm, grid }
    }
}

impl<H: Borrow<Heightmap>> RowSource for Resident<H> {
    fn grid(&self) -> &RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        let start = y0 as usize * self.grid.width as usize;
        out.copy_from_slice(&self.hm.borrow().heights()[start..start + out.len()]);
        Ok(())
    }
}

impl<T: RowSource + ?Sized> RowSource for Box<T> {
    fn grid(&self) -> &RowGrid {
        (**self).grid()
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        (**self).read_rows(y0, out)
    }
}

/// A source whose rows are resampled to square cells of its N-S spacing as they are read
/// ([`crate::source::LoadOptions::resample_ew`]): the same rows [`crate::source::load`] resamples.
pub(crate) struct ResampledEw {
    inner: Box<dyn RowSource>,
    grid: RowGrid,
    /// The inner source's rows of the band being read (grown to the largest band asked, then kept).
    band: Vec<f32>,
}

impl ResampledEw {
    /// Wraps `inner`, or gives it back where its cells are square already.
    pub(crate) fn new(inner: Box<dyn RowSource>) -> std::result::Result<Self, Box<dyn RowSource>> {
        let g = inner.grid();
        let Some((width, ew_spacing)) = super::resampled_width(g.width, g.spacing, g.ew_spacing)
        else {
            return Err(inner);
        };
        let grid = RowGrid {
            width,
            ew_spacing,
            ..g.clone()
        };
        Ok(Self {
            inner,
            grid,
            band: Vec::new(),
        })
    }
}

impl RowSource for ResampledEw {
    fn grid(&self) -> &RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        let (w, w2) = (self.inner.width() as usize, self.grid.width as usize);
        let rows = out.len() / w2;
        self.band.resize(rows * w, 0.0);
        self.inner.read_rows(y0, &mut self.band)?;
        for (src, dst) in self.band.chunks_exact(w).zip(out.chunks_exact_mut(w2)) {
            super::resample_row(src, dst);
        }
        Ok(())
    }
}
