//! Stage 0, the source read a band of rows at a time: what the out-of-core bake (stage 1b) streams from,
//! so that no terrain-sized buffer is needed to bake a package.

use std::path::Path;

use crate::{Error, Heightmap, Result};

/// A terrain read top to bottom in bands of whole rows (row 0 north, like [`Heightmap`]).
pub trait RowSource {
    /// Samples per row.
    fn width(&self) -> u32;
    /// Rows.
    fn height(&self) -> u32;
    /// Sample spacing, metres.
    fn spacing(&self) -> f32;
    /// World position of the south-west sample, metres ([`Heightmap::origin`]).
    fn origin(&self) -> (f64, f64);
    /// What errors name: the file, or a description.
    fn path(&self) -> &Path;
    /// Fills `out`, a whole number of rows, with the rows from `y0` on; an error if they run past the
    /// last row or `out` is not whole rows.
    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()>;
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

/// A terrain already in memory, read in bands (loaders that decode whole files, and tests).
impl RowSource for Heightmap {
    fn width(&self) -> u32 {
        Heightmap::width(self)
    }

    fn height(&self) -> u32 {
        Heightmap::height(self)
    }

    fn spacing(&self) -> f32 {
        Heightmap::spacing(self)
    }

    fn origin(&self) -> (f64, f64) {
        Heightmap::origin(self)
    }

    fn path(&self) -> &Path {
        Path::new("<heightmap>")
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        let start = y0 as usize * Heightmap::width(self) as usize;
        out.copy_from_slice(&self.heights()[start..start + out.len()]);
        Ok(())
    }
}

/// A borrowed terrain in memory.
impl RowSource for &Heightmap {
    fn width(&self) -> u32 {
        Heightmap::width(self)
    }

    fn height(&self) -> u32 {
        Heightmap::height(self)
    }

    fn spacing(&self) -> f32 {
        Heightmap::spacing(self)
    }

    fn origin(&self) -> (f64, f64) {
        Heightmap::origin(self)
    }

    fn path(&self) -> &Path {
        Path::new("<heightmap>")
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        check_band(self, y0, out)?;
        let start = y0 as usize * Heightmap::width(self) as usize;
        out.copy_from_slice(&self.heights()[start..start + out.len()]);
        Ok(())
    }
}

impl<T: RowSource + ?Sized> RowSource for Box<T> {
    fn width(&self) -> u32 {
        (**self).width()
    }

    fn height(&self) -> u32 {
        (**self).height()
    }

    fn spacing(&self) -> f32 {
        (**self).spacing()
    }

    fn origin(&self) -> (f64, f64) {
        (**self).origin()
    }

    fn path(&self) -> &Path {
        (**self).path()
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        (**self).read_rows(y0, out)
    }
}
