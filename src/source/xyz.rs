//! Stage 0, the source: gridded XYZ text (`.xyz`, GDAL's XYZ driver, as many LiDAR tools export it): one
//! `x y z` point per line on a regular grid.

use std::path::Path;

use super::{check_size, fill_voids, height, LoadOptions};
use crate::{Error, Result};
use crate::source::Heightmap;

/// How far from a lattice point (in cells) a point may lie and still count as on the grid: the text
/// rounds coordinates (1/3 m written to the millimetre is off by 0.0015 cells).
const ON_GRID: f64 = 0.05;

/// Most grid cells a point may stand for: past it the grid would be mostly voids.
const MAX_CELLS_PER_POINT: u64 = 16;

/// The points of `path`, each as (line number, x, y, z), to `f`; a first line that is not numbers is a
/// header and skipped. Fields are split by spaces, tabs, commas or semicolons.
fn points(path: &Path, mut f: impl FnMut(u64, f64, f64, f64) -> Result<()>) -> Result<()> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "cannot open", e))?;
    let mut reader = std::io::BufReader::new(file);
    let mut line = String::new();
    let mut n = 0u64;
    while super::asc::next_line(path, &mut reader, &mut line, &mut n)? {
        let mut fields = line
            .split(|c: char| c.is_ascii_whitespace() || c == ',' || c == ';')
            .filter(|w| !w.is_empty());
        let words = [fields.next(), fields.next(), fields.next()];
        let [Some(x), Some(y), Some(z)] = words else {
            if words[0].is_none() || n == 1 {
                continue;
            }
            return Err(Error::format(
                path,
                format!("line {n}: expected `x y z`, found `{}`", line.trim()),
            ));
        };
        let num = |w: &str| w.parse::<f64>().ok();
        match (num(x), num(y), num(z)) {
            (Some(x), Some(y), Some(z)) if x.is_finite() && y.is_finite() => f(n, x, y, z)?,
            _ if n == 1 => {}
            _ => {
                return Err(Error::format(
                    path,
                    format!("line {n}: `{}` is not three numbers", line.trim()),
                ))
            }
        }
    }
    Ok(())
}

/// Loads a gridded XYZ file in two passes over the text (never held whole): the first finds the grid
/// (extent, and the spacing as the smallest step between neighbouring points along x and between rows),
/// the second places each point on it. Points may come in any order; a grid cell no point names is a
/// void, filled from its neighbours and counted. A point off the grid, or a second point on one cell, is
/// refused naming its line. The spacing is in degrees where a `.prj` beside the file is geographic, as for
/// ASCII grids; [`LoadOptions::spacing`] overrides it. Heights are metres times
/// [`LoadOptions::height_scale`] (1 by default) plus the offset.
pub(super) fn load(path: &Path, opts: &LoadOptions) -> Result<Heightmap> {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let (mut dx, mut dy) = (f64::MAX, f64::MAX);
    let mut prev: Option<(f64, f64)> = None;
    let mut count = 0u64;
    points(path, |_, x, y, _| {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        if let Some((px, py)) = prev {
            let (sx, sy) = ((x - px).abs(), (y - py).abs());
            if sx > 0.0 {
                dx = dx.min(sx);
            }
            if sy > 0.0 {
                dy = dy.min(sy);
            }
        }
        prev = Some((x, y));
        count += 1;
        Ok(())
    })?;
    if count < 4 || dx == f64::MAX || dy == f64::MAX {
        return Err(Error::format(
            path,
            format!("{count} points that do not span two rows and two columns: not a grid"),
        ));
    }
    let cells = |lo: f64, hi: f64, d: f64| ((hi - lo) / d).round() + 1.0;
    let (w, h) = (cells(x0, x1, dx), cells(y0, y1, dy));
    if !(w.is_finite() && h.is_finite() && w < 1e9 && h < 1e9) {
        return Err(Error::format(path, "the points span no finite grid"));
    }
    // The smallest step may carry the text's rounding; the extent over the cell count does not add it up.
    let (dx, dy) = ((x1 - x0) / (w - 1.0), (y1 - y0) / (h - 1.0));
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "positive whole numbers under 1e9"
    )]
    let (w, h) = (w as u64, h as u64);
    let samples = check_size(path, w, h, opts)?;
    // A grid mostly of voids is not what the points describe (a stray point, or steps written with
    // uneven rounding): refused before it is allocated.
    if samples as u64 > count.saturating_mul(MAX_CELLS_PER_POINT) {
        return Err(Error::format(
            path,
            format!(
                "{count} points would span {w} x {h} cells of {dx} x {dy}: more than \
                 {MAX_CELLS_PER_POINT} cells a point is not a grid (a stray point, or uneven steps?)"
            ),
        ));
    }
    let mut heights = vec![f32::NAN; samples];
    let mut filled = vec![false; samples];
    let (scale, offset) = (
        opts.height_scale.map_or(1.0, f64::from),
        f64::from(opts.height_offset),
    );
    let width = usize::try_from(w).unwrap_or(usize::MAX);
    points(path, |n, x, y, z| {
        let (u, v) = ((x - x0) / dx, (y1 - y) / dy);
        let (cu, cv) = (u.round(), v.round());
        if (u - cu).abs() > ON_GRID || (v - cv).abs() > ON_GRID {
            return Err(Error::format(
                path,
                format!(
                    "line {n}: point ({x}, {y}) is off the grid of {dx} x {dy} cells from ({x0}, {y1})"
                ),
            ));
        }
        #[expect(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "rounded and inside the extent the first pass found"
        )]
        let i = cv as usize * width + cu as usize;
        if filled[i] {
            return Err(Error::format(
                path,
                format!("line {n}: a second point at ({x}, {y})"),
            ));
        }
        filled[i] = true;
        let void = super::is_nodata(opts.nodata, z);
        heights[i] = height(path, z, void, scale, offset, (i % width, i / width))?;
        Ok(())
    })?;
    drop(filled);
    let voids = fill_voids(path, width, &mut heights)?;
    let (spacing, ew) = match opts.spacing {
        Some(s) => (s, s),
        None => super::asc::spacing(path, (dx, dy), Some((y0, true)), h)?,
    };
    let err = |_| Error::format(path, "the grid does not fit 32 bits a side");
    let size = (u32::try_from(w).map_err(err)?, u32::try_from(h).map_err(err)?);
    // The points are sample centres.
    let ll = (Some((x0, true)), Some((y0, true)));
    Ok(Heightmap::new(path, size.0, size.1, spacing, heights)?
        .with_voids_filled(voids)
        .with_ew_spacing(ew)
        .with_geo(super::asc::geo_extent(path, (dx, dy), ll, size)))
}
