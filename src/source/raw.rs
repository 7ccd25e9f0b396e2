//! Stage 0, the source: headerless raw height files (little-endian u16 or f32, dimensions given).

use std::path::Path;

use super::{check_size, to_f32, LoadOptions, RawFormat, RowSource, DEFAULT_SPACING_M};
use crate::{Error, Param, Result};
use crate::source::Heightmap;

/// Loads a raw file laid out as [`LoadOptions::raw`] says; its length must match exactly.
///
/// u16 samples are scaled by [`LoadOptions::height_scale`] (default 0.1 m, as for 16-bit PNG); f32
/// samples are metres. Both get [`LoadOptions::height_offset`]. Spacing: [`LoadOptions::spacing`], else
/// [`DEFAULT_SPACING_M`].
pub(super) fn load(path: &Path, len: u64, opts: &LoadOptions) -> Result<Heightmap> {
    let mut rows = Rows::open(path, len, opts)?;
    let (w, h) = (rows.layout.width, rows.layout.height);
    let mut heights = super::zeroed_samples(path, w as usize * h as usize)?;
    rows.read_rows(0, &mut heights)?;
    let filled = if opts.nodata.is_some() {
        super::fill_voids(path, w as usize, &mut heights)?
    } else {
        0
    };
    Ok(Heightmap::new(path, w, h, rows.grid.spacing, heights)?.with_voids_filled(filled))
}

/// A raw file read a band of rows at a time by positioned reads (the out-of-core bake's source); the
/// samples are the ones [`load`] gives.
pub(super) struct Rows {
    file: std::fs::File,
    grid: super::RowGrid,
    layout: super::RawLayout,
    bytes_per: u64,
    scale: f64,
    offset: f32,
    /// [`LoadOptions::nodata`]: matching samples come back NaN.
    nodata: Option<f64>,
    bytes: Vec<u8>,
}

impl Rows {
    /// Opens a raw file of `len` bytes laid out as [`LoadOptions::raw`] says; its length must match.
    pub(super) fn open(path: &Path, len: u64, opts: &LoadOptions) -> Result<Self> {
        let Some(layout) = opts.raw else {
            return Err(Error::format(
                path,
                format!(
                    "a raw file has no header: give its dimensions and sample format with `{}`",
                    Param::RawLayout
                ),
            ));
        };
        let samples = check_size(path, layout.width.into(), layout.height.into(), opts)?;
        let (bytes_per, name) = match layout.format {
            RawFormat::U16 => (2u64, "u16"),
            RawFormat::F32 => (4u64, "f32"),
        };
        let expected = samples as u64 * bytes_per;
        if len != expected {
            return Err(Error::SizeMismatch {
                path: path.into(),
                actual: len,
                expected: format!(
                    "{expected} bytes ({} x {} {name})",
                    layout.width, layout.height
                ),
            });
        }
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
        Ok(Self {
            file,
            grid: super::RowGrid {
                width: layout.width,
                height: layout.height,
                spacing: opts.spacing.unwrap_or(DEFAULT_SPACING_M),
                ew_spacing: opts.spacing.unwrap_or(DEFAULT_SPACING_M),
                origin: (0.0, 0.0),
                path: path.into(),
            },
            layout,
            bytes_per,
            scale: opts.height_scale.map_or(0.1, f64::from),
            offset: opts.height_offset,
            nodata: opts.nodata,
            bytes: Vec::new(),
        })
    }
}

impl super::RowSource for Rows {
    fn grid(&self) -> &super::RowGrid {
        &self.grid
    }

    fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
        super::check_band(self, y0, out)?;
        let at = u64::from(y0) * u64::from(self.layout.width) * self.bytes_per;
        let per = if self.bytes_per == 2 { 2 } else { 4 };
        self.bytes.resize(out.len() * per, 0);
        super::rows::read_exact_at(&mut self.file, &self.grid.path, at, &mut self.bytes)?;
        let nodata = self.nodata;
        let width = self.layout.width as usize;
        match self.layout.format {
            RawFormat::U16 => {
                let off = f64::from(self.offset);
                for (o, c) in out.iter_mut().zip(self.bytes.chunks_exact(2)) {
                    let v = f64::from(u16::from_le_bytes([c[0], c[1]]));
                    *o = if super::is_nodata(nodata, v) {
                        f32::NAN
                    } else {
                        to_f32(v * self.scale + off)
                    };
                }
            }
            // Non-finite samples stay so, and the bake (or `Heightmap::new`) refuses them with their
            // position; with a nodata value they are refused here, before voids are filled.
            RawFormat::F32 => {
                for (i, (o, c)) in out.iter_mut().zip(self.bytes.chunks_exact(4)).enumerate() {
                    let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                    *o = match nodata {
                        // f64 sum rounded once to f32: the bits of `v + offset` in f32.
                        Some(_) => super::height(
                            &self.grid.path,
                            f64::from(v),
                            super::is_nodata(nodata, f64::from(v)),
                            1.0,
                            f64::from(self.offset),
                            (i % width, i / width + y0 as usize),
                        )?,
                        None => v + self.offset,
                    };
                }
            }
        }
        Ok(())
    }
}
