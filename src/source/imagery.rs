//! Stage 0, the source: imagery to drape on the terrain, as RGB8 texels placed over an extent of the
//! terrain's world frame (`imagery_rows.rs` reads the files: PNG, JPEG, TIFF and GeoTIFF; a GeoTIFF
//! over GeoTIFF heights is placed by both georeferences, `georef.rs`).
//!
//! Placement is pixel-is-area (docs/guide.md "Imagery"): an image of W x H texels over the extent
//! (west, south, east, north) has texel (i, j) cover x in [west + i dx, west + (i + 1) dx] and y in
//! [north - (j + 1) dy, north - j dy], with dx = (east - west) / W and dy = (north - south) / H; row 0 is
//! the north edge. A plain image spans the height grid's extent, corner sample to corner sample, unless
//! an extent is given. Alpha is read and dropped: the drape is opaque.

use std::path::{Path, PathBuf};

use crate::{Error, Param, Result};

/// Most texels an imagery file may declare by default (2^28, a 16384 x 16384 image): checked against the
/// header before anything is allocated.
pub const DEFAULT_MAX_IMAGERY_TEXELS: u64 = 1 << 28;

/// A rectangle of the terrain's world frame, metres (x east, y north; the height grid's south-west
/// sample is at its origin, (0, 0) unless placed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Extent {
    /// Smallest x.
    pub west: f64,
    /// Smallest y.
    pub south: f64,
    /// Largest x.
    pub east: f64,
    /// Largest y.
    pub north: f64,
}

impl Extent {
    /// An extent from (west, south, east, north), checked: finite, west < east and south < north.
    pub fn new(west: f64, south: f64, east: f64, north: f64) -> Result<Self> {
        let e = Self {
            west,
            south,
            east,
            north,
        };
        if ![west, south, east, north].iter().all(|v| v.is_finite()) {
            return Err(Error::param(
                Param::ImageryExtent,
                format!("{e} is not finite"),
            ));
        }
        if !(west < east && south < north) {
            return Err(Error::param(
                Param::ImageryExtent,
                format!("{e} is empty: needs west < east and south < north"),
            ));
        }
        Ok(e)
    }

    /// Parses `W,S,E,N` (metres, in the terrain's world frame).
    pub fn parse(text: &str) -> Result<Self> {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let values: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
        match values.as_slice() {
            [w, s, e, n] if parts.len() == 4 => Self::new(*w, *s, *e, *n),
            _ => Err(Error::param(
                Param::ImageryExtent,
                format!("`{text}` is not four numbers W,S,E,N"),
            )),
        }
    }

    /// The extent of a height grid of `width` x `height` samples `spacing` metres apart whose south-west
    /// sample is at `origin`: from the corner samples' positions, as a plain image is placed.
    pub fn of_grid(width: u32, height: u32, spacing: f64, origin: (f64, f64)) -> Self {
        Self {
            west: origin.0,
            south: origin.1,
            east: origin.0 + f64::from(width.saturating_sub(1)) * spacing,
            north: origin.1 + f64::from(height.saturating_sub(1)) * spacing,
        }
    }

    /// Width (east - west) and height (north - south), metres.
    pub fn size(&self) -> (f64, f64) {
        (self.east - self.west, self.north - self.south)
    }

    /// The part shared with `other`, or `None` when they share no area.
    pub fn overlap(&self, other: &Extent) -> Option<Extent> {
        let e = Extent {
            west: self.west.max(other.west),
            south: self.south.max(other.south),
            east: self.east.min(other.east),
            north: self.north.min(other.north),
        };
        (e.west < e.east && e.south < e.north).then_some(e)
    }

    /// The four values, (west, south, east, north).
    pub fn to_array(self) -> [f64; 4] {
        [self.west, self.south, self.east, self.north]
    }
}

impl std::fmt::Display for Extent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "west {} south {} east {} north {} m",
            self.west, self.south, self.east, self.north
        )
    }
}

/// How to read and place an imagery file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageryOptions {
    /// Where the image lies; `None`: the height grid's extent, corner to corner.
    pub extent: Option<Extent>,
    /// Most texels the file may declare; checked before allocating.
    pub max_texels: u64,
    /// The stored sample values drawn black and white, (low, high): samples between map linearly onto 0
    /// to 255, those outside are clamped. For imagery whose samples fill little of their type's range
    /// (12-bit or reflectance values in a 16-bit file). `None`: 8-bit samples as they are, 16-bit ones
    /// rounded to 8 bits.
    pub range: Option<(f64, f64)>,
}

/// `range` as [`ImageryOptions::range`] takes it: finite, 0 <= low < high <= 65535.
pub fn check_range((lo, hi): (f64, f64)) -> Result<(f64, f64)> {
    if lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= 65535.0 {
        Ok((lo, hi))
    } else {
        Err(Error::param(
            crate::Param::ImageryRange,
            format!("{lo} to {hi}: give 0 <= low < high <= 65535, in the image's sample values"),
        ))
    }
}

impl Default for ImageryOptions {
    fn default() -> Self {
        Self {
            extent: None,
            max_texels: DEFAULT_MAX_IMAGERY_TEXELS,
            range: None,
        }
    }
}

/// An image placed on the terrain: RGB8 texels, row-major from the north-west corner.
#[derive(Clone, Debug, PartialEq)]
pub struct Imagery {
    path: PathBuf,
    width: u32,
    height: u32,
    texels: Vec<u8>,
    extent: Extent,
}

impl Imagery {
    /// An image from RGB8 texels in memory (row-major from the north-west corner), placed over `extent`,
    /// or over `grid` without one, with [`Imagery::load`]'s checks (`source::imagery_rows` reads files).
    pub fn from_rgb(
        path: &Path,
        width: u32,
        height: u32,
        texels: Vec<u8>,
        grid: &Extent,
        extent: Option<Extent>,
    ) -> Result<Self> {
        check_size(path, width, height)?;
        let expected = u64::from(width) * u64::from(height) * 3;
        if texels.len() as u64 != expected {
            return Err(Error::format(
                path,
                format!(
                    "{} bytes given for {width} x {height} RGB texels ({expected})",
                    texels.len()
                ),
            ));
        }
        Ok(Self {
            path: path.to_path_buf(),
            width,
            height,
            texels,
            extent: place(path, grid, extent)?,
        })
    }

    /// The RGB8 texels, given up.
    pub fn into_texels(self) -> Vec<u8> {
        self.texels
    }

    /// The file it was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Texels (columns, rows).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Where it lies in the terrain's world frame.
    pub fn extent(&self) -> Extent {
        self.extent
    }

    /// Metres per texel, (east-west, north-south).
    pub fn texel_spacing(&self) -> (f64, f64) {
        let (w, h) = self.extent.size();
        (w / f64::from(self.width), h / f64::from(self.height))
    }

    /// The RGB8 texels, row-major from the north-west corner.
    pub fn texels(&self) -> &[u8] {
        &self.texels
    }

    /// The texel at column `x`, row `y` (row 0 north), clamped to the image.
    pub fn texel(&self, x: i64, y: i64) -> [u8; 3] {
        let cx = x.clamp(0, i64::from(self.width) - 1);
        let cy = y.clamp(0, i64::from(self.height) - 1);
        #[expect(
            clippy::cast_possible_truncation,
            reason = "clamped into the image, whose size fits usize (its texels are held)"
        )]
        let i = (cy as usize * self.width as usize + cx as usize) * 3;
        [self.texels[i], self.texels[i + 1], self.texels[i + 2]]
    }
}

/// Refuses a JPEG without an end-of-image marker: the decoder fills a truncated scan with grey instead
/// of failing, so a cut file is caught here (an entropy-coded 0xFF is stuffed with 0x00, so 0xFF 0xD9
/// is a marker wherever it appears).
pub(crate) fn check_jpeg_end(path: &Path) -> Result<()> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
    if bytes.windows(2).any(|w| w == [0xFF, 0xD9]) {
        Ok(())
    } else {
        Err(Error::format(
            path,
            "truncated JPEG: no end-of-image marker",
        ))
    }
}

/// A decoder's error on one line (some end theirs with a newline).
pub(crate) fn one_line(e: &dyn std::fmt::Display) -> String {
    e.to_string().split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Refuses images too small to place: a texel spacing needs two texels each way.
pub(crate) fn check_size(path: &Path, width: u32, height: u32) -> Result<()> {
    if width < 2 || height < 2 {
        return Err(Error::format(
            path,
            format!("{width} x {height} texels: imagery needs at least 2 x 2"),
        ));
    }
    Ok(())
}

/// Where an image lies: `extent`, checked, or the height grid's `grid` without one; refused when it
/// shares no area with the grid.
pub(crate) fn place(path: &Path, grid: &Extent, extent: Option<Extent>) -> Result<Extent> {
    let extent = match extent {
        Some(e) => Extent::new(e.west, e.south, e.east, e.north)?,
        None => *grid,
    };
    if extent.overlap(grid).is_none() {
        return Err(Error::param(
            Param::ImageryExtent,
            format!(
                "{}: the imagery ({extent}) does not overlap the terrain ({grid})",
                path.display()
            ),
        ));
    }
    Ok(extent)
}
