//! Stage 0, the source: a regular grid of heights in metres, whatever file or generator it came from.

use std::path::Path;

use super::GeoExtent;
use crate::{Error, Result};

/// Most samples [`Heightmap::typical_range`] reads.
const TYPICAL_SAMPLES: usize = 1 << 16;

/// A north-up, row-major grid of heights in metres on square cells of `spacing` metres.
///
/// Every sample is finite: constructors refuse NaN and infinities, so later stages need not check.
#[derive(Clone, Debug, PartialEq)]
pub struct Heightmap {
    width: u32,
    height: u32,
    spacing: f32,
    /// The source's E-W spacing (metres): `spacing` but for geographic grids, whose E-W degrees are
    /// shorter than their N-S ones away from the equator. The grid is drawn with square cells of
    /// `spacing`, so E-W at `spacing / ew_spacing` times its size unless resampled
    /// ([`crate::source::LoadOptions::resample_ew`]).
    ew_spacing: f32,
    heights: Vec<f32>,
    voids_filled: u64,
    /// World position (x east, y north, metres) of the south-west corner sample; (0, 0) unless placed.
    origin: (f64, f64),
    /// Where a grid read in degrees lies on the globe (None for projected and plain-image sources).
    geo: Option<GeoExtent>,
}

impl Heightmap {
    /// A heightmap of `width` x `height` samples; `heights` is row-major, row 0 the northernmost.
    ///
    /// `origin` names where the samples came from, for error messages.
    pub fn new(
        origin: &Path,
        width: u32,
        height: u32,
        spacing: f32,
        heights: Vec<f32>,
    ) -> Result<Self> {
        if width < 2 || height < 2 {
            return Err(Error::format(
                origin,
                format!("{width} x {height} samples: need at least 2 x 2"),
            ));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(Error::format(
                origin,
                format!("sample spacing {spacing} m: must be finite and positive"),
            ));
        }
        let expected = u64::from(width) * u64::from(height);
        if heights.len() as u64 != expected {
            return Err(Error::format(
                origin,
                format!(
                    "{} samples given for {width} x {height} = {expected}",
                    heights.len()
                ),
            ));
        }
        if let Some(i) = heights.iter().position(|h| !h.is_finite()) {
            let (x, y) = (i % width as usize, i / width as usize);
            return Err(Error::NonFinite {
                path: origin.into(),
                x: u32::try_from(x).unwrap_or(u32::MAX),
                y: u32::try_from(y).unwrap_or(u32::MAX),
                value: heights[i],
            });
        }
        Ok(Self {
            width,
            height,
            spacing,
            ew_spacing: spacing,
            heights,
            voids_filled: 0,
            origin: (0.0, 0.0),
            geo: None,
        })
    }

    /// Records where a grid read in degrees lies on the globe ([`Heightmap::geo`]).
    #[must_use]
    pub fn with_geo(mut self, geo: Option<GeoExtent>) -> Self {
        self.geo = geo;
        self
    }

    /// Where the grid lies on the globe, for a source in degrees whose metres the loader took at its
    /// middle row (not with [`crate::source::LoadOptions::spacing`]); None otherwise.
    pub fn geo(&self) -> Option<&GeoExtent> {
        self.geo.as_ref()
    }

    /// Records the source's E-W spacing, metres ([`Heightmap::ew_spacing`]); a value that is not finite
    /// and positive keeps square cells.
    #[must_use]
    pub fn with_ew_spacing(mut self, ew: f32) -> Self {
        if ew.is_finite() && ew > 0.0 {
            self.ew_spacing = ew;
        }
        self
    }

    /// The source's E-W spacing, metres: [`Heightmap::spacing`] unless the source's cells are not square
    /// in metres (a geographic grid away from the equator).
    pub fn ew_spacing(&self) -> f32 {
        self.ew_spacing
    }

    /// How many times its true E-W size the terrain is drawn (`spacing / ew_spacing`): 1 for square
    /// cells, 1.86 for an SRTM tile at 57.5 N.
    pub fn ew_stretch(&self) -> f64 {
        f64::from(self.spacing) / f64::from(self.ew_spacing)
    }

    /// Records how many void samples the loader filled.
    #[must_use]
    pub fn with_voids_filled(mut self, voids: u64) -> Self {
        self.voids_filled = voids;
        self
    }

    /// Places the terrain in the world: its south-west corner sample at (`x`, `y`) metres instead of the
    /// origin. Every stage maps world to grid through [`Heightmap::world_to_grid`] (in f64, the offset
    /// subtracted first), so a terrain 1e6 m out renders like one at the origin. Panics on a non-finite
    /// offset (a caller bug).
    #[must_use]
    pub fn with_origin(mut self, x: f64, y: f64) -> Self {
        assert!(
            x.is_finite() && y.is_finite(),
            "terrain origin ({x}, {y}) must be finite"
        );
        self.origin = (x, y);
        self
    }

    /// World position of the south-west corner sample, metres.
    pub fn origin(&self) -> (f64, f64) {
        self.origin
    }

    /// Samples per row.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Distance between neighbouring samples, metres.
    pub fn spacing(&self) -> f32 {
        self.spacing
    }

    /// All samples, row-major.
    pub fn heights(&self) -> &[f32] {
        &self.heights
    }

    /// Void samples the loader filled (SRTM -32768, GeoTIFF nodata).
    pub fn voids_filled(&self) -> u64 {
        self.voids_filled
    }

    /// The sample at column `x`, row `y`. Panics outside the grid (a caller bug, not bad input).
    pub fn at(&self, x: u32, y: u32) -> f32 {
        assert!(
            x < self.width && y < self.height,
            "heightmap sample ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        self.heights[y as usize * self.width as usize + x as usize]
    }

    /// The sample at integer grid coordinates, clamped to the edge: the terrain extends flat beyond its border.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "clamped into 0..width and 0..height, which are u32"
    )]
    pub fn at_clamped(&self, x: i64, y: i64) -> f32 {
        let xc = x.clamp(0, i64::from(self.width) - 1) as usize;
        let yc = y.clamp(0, i64::from(self.height) - 1) as usize;
        self.heights[yc * self.width as usize + xc]
    }

    /// Lowest and highest sample, metres.
    pub fn range(&self) -> (f32, f32) {
        self.heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            })
    }

    /// The terrain's typical relief, metres: the 1st and 99th percentiles of its heights, so a few
    /// outliers (an untagged void at -32768, a mast, a spike) do not stretch it. Read from an evenly
    /// strided subsample of at most 65,536 samples (deterministic; one allocation, not per
    /// frame).
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "ranks of at most TYPICAL_SAMPLES samples"
    )]
    pub fn typical_range(&self) -> (f32, f32) {
        let stride = self.heights.len().div_ceil(TYPICAL_SAMPLES).max(1);
        let mut s: Vec<f32> = self.heights.iter().step_by(stride).copied().collect();
        let last = s.len().saturating_sub(1);
        let rank = |q: f64| ((last as f64) * q).round() as usize;
        let (lo_at, hi_at) = (rank(0.01), rank(0.99));
        let lo = *s.select_nth_unstable_by(lo_at, f32::total_cmp).1;
        let hi = *s.select_nth_unstable_by(hi_at, f32::total_cmp).1;
        (lo, hi)
    }

    /// World position (x east, y north, metres) of grid sample column `u`, row `v`: x = x0 + u s,
    /// y = y0 + (rows - 1 - v) s, with (x0, y0) the [`Heightmap::origin`].
    ///
    /// Row 0 is the north edge; the south-west corner sample sits at the origin, (0, 0) by default.
    pub fn grid_to_world(&self, u: f64, v: f64) -> (f64, f64) {
        let s = f64::from(self.spacing);
        (
            self.origin.0 + u * s,
            self.origin.1 + (f64::from(self.height - 1) - v) * s,
        )
    }

    /// Inverse of [`Heightmap::grid_to_world`]: fractional column and row of a world position.
    pub fn world_to_grid(&self, x: f64, y: f64) -> (f64, f64) {
        let s = f64::from(self.spacing);
        (
            (x - self.origin.0) / s,
            f64::from(self.height - 1) - (y - self.origin.1) / s,
        )
    }

    /// Height at a world position by bilinear interpolation, clamped at the border.
    #[expect(
        clippy::cast_possible_truncation,
        reason = "fractions in [0, 1) as f32; floors are clamped on lookup"
    )]
    pub fn height_at_world(&self, x: f64, y: f64) -> f32 {
        let (u, v) = self.world_to_grid(x, y);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - u0) as f32, (v - v0) as f32);
        let (iu, iv) = (u0 as i64, v0 as i64);
        let a = self.at_clamped(iu, iv) * (1.0 - fu) + self.at_clamped(iu + 1, iv) * fu;
        let b = self.at_clamped(iu, iv + 1) * (1.0 - fu) + self.at_clamped(iu + 1, iv + 1) * fu;
        a * (1.0 - fv) + b * fv
    }

    /// Extent in metres, (east-west, north-south).
    pub fn extent_m(&self) -> (f64, f64) {
        (
            f64::from(self.width - 1) * f64::from(self.spacing),
            f64::from(self.height - 1) * f64::from(self.spacing),
        )
    }
}
