//! Stage 0, the source: a (Geo)TIFF's georeference (ModelPixelScale, ModelTiepoint and the GeoKeys that
//! name its coordinate system and raster type), or an image's world file, for placing draped imagery
//! against the heights' own georeference (docs/guide.md "Imagery").

use std::io::BufReader;
use std::path::Path;

use tiff::decoder::Decoder;
use tiff::tags::Tag;

use super::imagery::Extent;
use crate::{Error, Param, Result};

/// GTRasterTypeGeoKey: 1 pixel-is-area (the default), 2 pixel-is-point.
const RASTER_TYPE_KEY: u16 = 1025;
/// GTModelTypeGeoKey: 1 projected, 2 geographic.
const MODEL_TYPE_KEY: u16 = 1024;
/// GeographicTypeGeoKey and ProjectedCSTypeGeoKey: the coordinate system's EPSG code.
const GEOGRAPHIC_KEY: u16 = 2048;
const PROJECTED_KEY: u16 = 3072;
const CRS_KEYS: [u16; 2] = [GEOGRAPHIC_KEY, PROJECTED_KEY];

/// Where a TIFF's pixels lie in its model space.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GeoRef {
    /// Pixels (columns, rows).
    pub size: (u32, u32),
    /// Model units per pixel, (x, y).
    pub scale: (f64, f64),
    /// The model position of pixel corner (0, 0), (x, y): the tiepoint moved to the raster's corner.
    pub corner: (f64, f64),
    /// The coordinate system's key and EPSG code (projected, else geographic), where the file names one:
    /// a projected file's own projection, never the geographic system a user-defined projection (GDAL's
    /// 32767, an Albers or Lambert grid without an EPSG code) is based on.
    pub crs: Option<(u16, u16)>,
    /// Whether the model is geographic (GTModelTypeGeoKey 2) or projected (1), where the file says.
    pub geographic: Option<bool>,
}

/// The index file's name in a package set's folder (`package::set`), which keeps the georeference of the
/// tiles it was baked from (its `georef` table) for placing imagery over the set.
pub const SET_INDEX_NAME: &str = "clipsat-set.toml";

/// The first line of a package set's index.
pub const SET_INDEX_MAGIC: &str = "# clipsat package set";

/// A package set's index file for `path` (the file, or the folder that holds it), if it is one.
pub fn set_index(path: &Path) -> Option<std::path::PathBuf> {
    let file = if path.is_dir() {
        path.join(SET_INDEX_NAME)
    } else {
        path.to_path_buf()
    };
    use std::io::Read;
    let mut head = [0u8; SET_INDEX_MAGIC.len()];
    // Not a FIFO or device, which opening would wait on or read without end.
    if !file.is_file() {
        return None;
    }
    std::fs::File::open(&file)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| head == SET_INDEX_MAGIC.as_bytes())
        .then_some(file)
}

impl GeoRef {
    /// The georeference a package set's index keeps (`None` where its tiles had none, or where it is not
    /// [`GeoRef::usable`]: a damaged index).
    pub fn of_set(path: &Path) -> Option<Self> {
        #[derive(serde::Deserialize)]
        struct Only {
            georef: Option<GeoRef>,
        }
        let text = std::fs::read_to_string(set_index(path)?).ok()?;
        toml::from_str::<Only>(&text)
            .ok()?
            .georef
            .filter(Self::usable)
    }

    /// Whether imagery can be placed by it: a finite corner, finite and positive pixel sizes, pixels.
    pub fn usable(&self) -> bool {
        let (sx, sy) = self.scale;
        sx.is_finite()
            && sy.is_finite()
            && sx > 0.0
            && sy > 0.0
            && self.corner.0.is_finite()
            && self.corner.1.is_finite()
            && self.size.0 > 0
            && self.size.1 > 0
    }
    /// The georeference of the TIFF at `path`, or `None` for a file that is not a TIFF or has no
    /// ModelPixelScale and ModelTiepoint (a rotated or unusable one is `None` too).
    pub fn read(path: &Path) -> Option<Self> {
        // Not a FIFO or device, which opening would wait on or read without end.
        if !path.is_file() {
            return None;
        }
        let file = std::fs::File::open(path).ok()?;
        let mut dec = Decoder::new(BufReader::new(file)).ok()?;
        let size = dec.dimensions().ok()?;
        let f64s = |dec: &mut Decoder<_>, tag| -> Option<Vec<f64>> {
            dec.find_tag(tag).ok().flatten()?.into_f64_vec().ok()
        };
        let scale = f64s(&mut dec, Tag::ModelPixelScaleTag)?;
        let tie = f64s(&mut dec, Tag::ModelTiepointTag)?;
        let keys: Vec<u16> = dec
            .find_tag(Tag::GeoKeyDirectoryTag)
            .ok()
            .flatten()
            .and_then(|v| v.into_u16_vec().ok())
            .unwrap_or_default();
        let key = |k: u16| {
            keys.get(4..)?
                .chunks_exact(4)
                .find(|e| e[0] == k && e[1] == 0)
                .map(|e| e[3])
        };
        let (sx, sy) = (*scale.first()?, *scale.get(1)?);
        if !(sx.is_finite() && sy.is_finite() && sx > 0.0 && sy > 0.0) || tie.len() < 6 {
            return None;
        }
        // Pixel-is-point: the tiepoint names a pixel's centre; the corner is half a pixel before it.
        let half = if key(RASTER_TYPE_KEY) == Some(2) { 0.5 } else { 0.0 };
        let corner = (
            tie[3] - (tie[0] + half) * sx,
            tie[4] + (tie[1] + half) * sy,
        );
        if !(corner.0.is_finite() && corner.1.is_finite()) {
            return None;
        }
        let named = |k: u16| key(k).filter(|&v| v != 0 && v != 32767).map(|v| (k, v));
        let geographic = match key(MODEL_TYPE_KEY) {
            Some(1) => Some(false),
            Some(2) => Some(true),
            _ => None,
        };
        let crs = match geographic {
            Some(false) => named(PROJECTED_KEY),
            Some(true) => named(GEOGRAPHIC_KEY),
            None => CRS_KEYS.iter().rev().find_map(|&k| named(k)),
        };
        Some(Self {
            size,
            scale: (sx, sy),
            corner,
            crs,
            geographic,
        })
    }
}

/// The sidecar names a world file of `path` may have, in the order looked for: the extension's first and
/// last letters and `w` (`.jgw`, `.pgw`, `.tfw`), the extension and `w` (`.jpgw`, `.tifw`), `.wld`.
fn world_file_names(path: &Path) -> Vec<std::path::PathBuf> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default();
    let mut names = Vec::with_capacity(3);
    if let (Some(a), Some(b)) = (ext.chars().next(), ext.chars().last()) {
        if ext.len() >= 2 {
            names.push(path.with_extension(format!("{a}{b}w")));
        }
        names.push(path.with_extension(format!("{ext}w")));
    }
    names.push(path.with_extension("wld"));
    names
}

/// The six numbers of the ESRI world file `wf` (`.tfw`, `.jgw`, `.pgw`, `.wld`), one a line: x pixel size,
/// the two rotation terms, y pixel size (negative: rows run south), and the x and y of the north-west
/// pixel's centre. Not six numbers is an error naming the file.
pub(crate) fn world_file_numbers(wf: &Path) -> Result<[f64; 6]> {
    let text = std::fs::read_to_string(wf).map_err(|e| Error::io(wf, "cannot read world file", e))?;
    let v: Vec<f64> = text
        .split_whitespace()
        .map(str::parse::<f64>)
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::format(wf, "a world file holds six numbers, one a line"))?;
    <[f64; 6]>::try_from(v.as_slice()).map_err(|_| {
        Error::format(wf, format!("a world file holds six numbers, this one {}", v.len()))
    })
}

/// An image's georeference from its world file `wf` ([`world_file_numbers`]) and its coordinate
/// system's kind from a `.prj` beside the image `path` (WKT: `GEOGCS`/`GEOGCRS` geographic,
/// `PROJCS`/`PROJCRS` projected). `size` is the image's pixels. A world file that rotates or mirrors
/// the image is an error naming it.
fn world_file(path: &Path, wf: &Path, size: (u32, u32)) -> Result<GeoRef> {
    let v = world_file_numbers(wf)?;
    let [a, d, b, e, c, f] = v;
    if !v.iter().all(|x| x.is_finite()) || b != 0.0 || d != 0.0 || a <= 0.0 || e >= 0.0 {
        return Err(Error::format(
            wf,
            format!(
                "rotates or mirrors the image (x size {a}, rotations {d} and {b}, y size {e}): only \
                 north-up images are placed; warp it north up (gdalwarp)"
            ),
        ));
    }
    let prj = std::fs::read_to_string(path.with_extension("prj")).unwrap_or_default();
    let head = prj.trim_start();
    let geographic = if head.starts_with("GEOGCS") || head.starts_with("GEOGCRS") {
        Some(true)
    } else if head.starts_with("PROJCS") || head.starts_with("PROJCRS") {
        Some(false)
    } else {
        None
    };
    Ok(GeoRef {
        size,
        scale: (a, -e),
        // (c, f) is the north-west pixel's centre; its corner is half a pixel west and north.
        corner: (c - 0.5 * a, f - 0.5 * e),
        crs: None,
        geographic,
    })
}

impl GeoRef {
    /// An imagery file's georeference: its GeoTIFF tags ([`GeoRef::read`]), else its world file (a JPEG,
    /// PNG or TIFF orthophoto's `.jgw`, `.pgw`, `.tfw` or `.wld`, in the heights' coordinate system unless a
    /// `.prj` beside it says geographic or projected otherwise), else `None`. A damaged world file is an
    /// error.
    pub fn of_imagery(path: &Path) -> Result<Option<Self>> {
        if let Some(g) = Self::read(path) {
            return Ok(Some(g));
        }
        let Some(wf) = world_file_names(path).into_iter().find(|p| p.is_file()) else {
            return Ok(None);
        };
        let size = image::ImageReader::open(path)
            .and_then(image::ImageReader::with_guessed_format)
            .map_err(|e| Error::io(path, "cannot read", e))?
            .into_dimensions()
            .map_err(|e| Error::format(path, format!("cannot read the image header: {e}")))?;
        world_file(path, &wf, size).map(Some)
    }
}

/// The extent in the terrain's world frame of imagery georeferenced by `image`, over heights
/// georeferenced by `heights` and drawn `spacing` metres a sample, `columns` samples a row, with their
/// south-west sample at `origin`: model coordinates are mapped through the heights' own grid (sample
/// centres at their pixels' centres), so a geographic grid maps as it is drawn. Where the drawn rows have
/// other than the file's columns (`--resample-ew`: the file's column c drawn at c (columns - 1) /
/// (file columns - 1), `source::resample_row`), the E-W mapping follows them. Refused when the two name
/// different coordinate systems. Geographic imagery a whole turn of longitude from the heights (given
/// in -180..180 over a mosaic across the antimeridian, or in 0..360) is placed where it lies on the globe.
pub fn georef_extent(
    path: &Path,
    heights: &GeoRef,
    image: &GeoRef,
    spacing: f64,
    origin: (f64, f64),
    columns: u32,
) -> Result<Extent> {
    if let (Some(a), Some(b)) = (heights.crs, image.crs) {
        if a != b {
            return Err(Error::param(
                Param::ImageryExtent,
                format!(
                    "{}: the imagery's georeference is in another coordinate system (EPSG {}) than \
                     the heights' (EPSG {}); reproject one of them, or place the image by this option, \
                     in the heights' metres",
                    path.display(),
                    b.1,
                    a.1
                ),
            ));
        }
    }
    if let (Some(h), Some(i)) = (heights.geographic, image.geographic) {
        if h != i {
            let kind = |g: bool| if g { "geographic (degrees)" } else { "projected" };
            return Err(Error::param(
                Param::ImageryExtent,
                format!(
                    "{}: the imagery's georeference is {} and the heights' {}; reproject one of them, \
                     or place the image by this option, in the heights' metres",
                    path.display(),
                    kind(i),
                    kind(h)
                ),
            ));
        }
    }
    // Longitudes a whole turn apart are one place: imagery given in -180..180 over heights across the
    // antimeridian (a mosaic's longitudes run on past 180 E there), or given in 0..360, is moved by the
    // turns that bring its middle nearest the heights'.
    let mut image = *image;
    let (west, north) = image.corner;
    let (east, south) = (
        west + f64::from(image.size.0) * image.scale.0,
        north - f64::from(image.size.1) * image.scale.1,
    );
    // An image that does not say what it is (a world file without a .prj) only where its numbers can
    // be degrees: a projected one stays where its metres put it.
    let degrees = (-540.0..=540.0).contains(&west)
        && (-540.0..=540.0).contains(&east)
        && (-90.0..=90.0).contains(&south)
        && (-90.0..=90.0).contains(&north);
    let geographic = image.geographic.unwrap_or(degrees);
    if heights.geographic == Some(true) && geographic {
        let middle = |g: &GeoRef| g.corner.0 + 0.5 * f64::from(g.size.0) * g.scale.0;
        let turns = ((middle(heights) - middle(&image)) / 360.0).round();
        if turns.is_finite() && turns != 0.0 {
            image.corner.0 += turns * 360.0;
        }
    }
    let (hsx, hsy) = heights.scale;
    // The heights' south-west sample, at the centre of its pixel.
    let sw = (
        heights.corner.0 + 0.5 * hsx,
        heights.corner.1 - (f64::from(heights.size.1) - 0.5) * hsy,
    );
    // Metres a file column is drawn E-W: `spacing`, or the resampled rows' share of it.
    let ew = if heights.size.0 > 1 && columns > 1 {
        spacing * f64::from(columns - 1) / f64::from(heights.size.0 - 1)
    } else {
        spacing
    };
    let world = |mx: f64, my: f64| {
        (
            origin.0 + (mx - sw.0) / hsx * ew,
            origin.1 + (my - sw.1) / hsy * spacing,
        )
    };
    let (west, north) = world(image.corner.0, image.corner.1);
    let (east, south) = world(
        image.corner.0 + f64::from(image.size.0) * image.scale.0,
        image.corner.1 - f64::from(image.size.1) * image.scale.1,
    );
    Extent::new(west, south, east, north)
}
