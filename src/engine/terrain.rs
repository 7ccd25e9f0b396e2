//! The embedding API: a terrain to draw, from source (stage 0) to a streamed package (stage 1b). A plain
//! file is baked into a package in the caller's cache folder on first use and streamed from there; a
//! package is streamed as it is; without a cache folder the terrain is held whole in memory.

use std::path::{Path, PathBuf};

use crate::hash::Hash64;
use crate::package::imagery::{ImageryPackage, DEFAULT_QUALITY};
use crate::package::imagery_bake::{bake_imagery_rows, cached_imagery};
use crate::package::{self, Package};
use crate::progress::Progress;
use crate::source::procedural::{self, ProceduralParams};
use crate::source::georef::{georef_extent, GeoRef};
use crate::source::imagery::{Extent, ImageryOptions};
use crate::source::imagery_rows::ImageryRows;
use crate::source::{self, Heightmap, LoadOptions, RowSource, TerrainSpec};
use crate::{Camera, Error, Param, Result};

/// Most samples of the package level a streamed terrain's stand-in holds (1 Mi: 4 MiB of f32): the
/// terrain's rough shape for cameras and clearance, never the drawn heights.
const STAND_IN_SAMPLES: u64 = 1 << 20;

/// How to open a terrain.
#[derive(Clone, Debug, Default)]
#[non_exhaustive]
pub struct TerrainOptions<'a> {
    /// The folder that keeps what is baked once per terrain: the package a plain file streams from, the
    /// SAT LOD tables and SG's shading tables. None: a plain file is loaded whole into memory, and the
    /// tables are baked at every start.
    pub cache_dir: Option<PathBuf>,
    /// Hold the whole terrain in memory even with a cache folder (a package is decoded whole).
    pub resident: bool,
    /// Sample spacing in metres, overriding (or supplying) the file's own: PNG and raw files have none.
    pub spacing_m: Option<f32>,
    /// Metres per stored unit of a grey PNG (default 0.1 for 16-bit, 1 for 8-bit).
    pub height_scale: Option<f32>,
    /// Metres added to every height after scaling.
    pub height_offset: f32,
    /// A stored sample value that marks voids (NaN matches NaN), for a file that declares none or
    /// another; voids are filled from their neighbours.
    pub nodata: Option<f64>,
    /// For a mosaic of tiles (a folder, a `.txt` list or a glob pattern given as the path): the height,
    /// metres, of samples no tile has data for (missing tiles, voids). None: they are no data, filled from
    /// their neighbours as a single file's voids are (the mosaic is then read whole to bake).
    pub fill_height: Option<f32>,
    /// Where the first bake of a plain file reports its progress.
    pub progress: Progress<'a>,
    /// An image to drape on the terrain: a PNG or JPEG (8- or 16-bit grey, RGB, RGBA or palette; alpha
    /// is dropped), baked into an imagery package (a colour pyramid in JPEG tiles) in the cache folder on
    /// first use, or an imagery package as `clipsat bake` writes it.
    pub imagery: Option<PathBuf>,
    /// The most samples a terrain file may declare before it is refused ([`crate::Error::TooLarge`],
    /// before anything is allocated); None: 2^30 (4 GiB of f32 heights).
    pub max_samples: Option<u64>,
    /// The most texels an imagery file may declare before it is refused (before anything is allocated);
    /// None: the default limit.
    pub max_imagery_texels: Option<u64>,
    /// Where the imagery lies, (west, south, east, north) metres in the terrain's frame (x east, y north,
    /// the south-west sample at the origin); `None`: the height grid's extent, corner sample to corner
    /// sample. Texels are areas: texel (i, j) of W x H covers 1/W of the width and 1/H of the height.
    pub imagery_extent: Option<[f64; 4]>,
    /// The imagery's stored sample values drawn black and white, (low, high), mapped linearly onto 0 to
    /// 255 (for 12-bit or reflectance values in a 16-bit file, which would draw nearly black); None: 8-bit
    /// samples as they are, 16-bit ones rounded to 8 bits.
    pub imagery_range: Option<(f64, f64)>,
}

/// A terrain ready to draw: a package streamed through the profile's tile cache, or a height grid held
/// whole. Give it to [`crate::TerrainRenderer::new`].
#[derive(Debug)]
pub struct Terrain {
    name: String,
    /// The whole grid (resident), or a coarse level of the package (streamed): its shape and placement.
    stand_in: Heightmap,
    package: Option<Package>,
    cache_dir: Option<PathBuf>,
    imagery: Option<ImageryPackage>,
    /// The heights' source file (not a package), whose georeference places GeoTIFF imagery.
    source: Option<PathBuf>,
}

impl Terrain {
    /// Opens a terrain file: a `.clipsat` package, or any source clipsat reads (PNG, GeoTIFF, SRTM
    /// `.hgt`, DTED, ESRI ASCII and binary grids, gridded XYZ), told by its extension or magic number; or
    /// a mosaic of SRTM `.hgt` and GeoTIFF tiles read as one terrain: a folder of them, a `.txt` list
    /// (one path a line, relative to the list), a GDAL `.vrt` mosaic of them or a glob pattern
    /// (`tiles/N5*.hgt`).
    /// With a `cache_dir`, a plain file is baked into a package there on first use (keyed by its path,
    /// size, modification time and sidecars) and streamed; without one it is held whole.
    /// [`Terrain::open_with`] takes the other options.
    pub fn open(path: impl AsRef<Path>, cache_dir: Option<&Path>) -> Result<Self> {
        Self::open_with(
            path,
            &TerrainOptions {
                cache_dir: cache_dir.map(Path::to_path_buf),
                ..TerrainOptions::default()
            },
        )
    }

    /// [`Terrain::open`] with every option: the spacing, heights' scale and offset, a nodata value, a
    /// progress callback for the first bake, or the whole terrain held in memory.
    pub fn open_with(path: impl AsRef<Path>, options: &TerrainOptions<'_>) -> Result<Self> {
        let load = LoadOptions {
            spacing: options.spacing_m,
            height_scale: options.height_scale,
            height_offset: options.height_offset,
            nodata: options.nodata,
            fill_height: options.fill_height,
            max_samples: options
                .max_samples
                .unwrap_or(LoadOptions::default().max_samples),
            ..LoadOptions::default()
        };
        let mut terrain = Self::open_spec(
            &TerrainSpec::File(path.as_ref().to_path_buf()),
            &load,
            options.cache_dir.as_deref(),
            options.resident,
            options.progress,
        )?;
        if let Some(imagery) = &options.imagery {
            let extent = options
                .imagery_extent
                .map(|[w, s, e, n]| Extent::new(w, s, e, n))
                .transpose()?;
            let opts = ImageryOptions {
                extent,
                max_texels: options
                    .max_imagery_texels
                    .unwrap_or(ImageryOptions::default().max_texels),
                range: options
                    .imagery_range
                    .map(crate::source::imagery::check_range)
                    .transpose()?,
            };
            terrain.attach_imagery(imagery, &opts, options.progress)?;
        }
        Ok(terrain)
    }

    /// Bakes `path` into a package in `options.cache_dir` (and its imagery, when `options.imagery` names
    /// one, into an imagery package there), reporting through `options.progress`, and returns the
    /// package's path: the explicit step an engine runs on a worker thread before its first frame (or
    /// at install time). A terrain baked once is not baked again: `bake` then, and
    /// [`Terrain::open_with`] with the same options, find the package and return at once (a package is
    /// mapped, its header checked and a coarse level of at most 1 Mi samples decoded; its tiles are
    /// checked as they are read). A `.clipsat` package is returned as it is. Refused without a cache
    /// folder, or with `resident` set.
    pub fn bake(path: impl AsRef<Path>, options: &TerrainOptions<'_>) -> Result<PathBuf> {
        if options.cache_dir.is_none() || options.resident {
            return Err(Error::Invalid {
                what: "Terrain::bake".into(),
                reason: "a bake needs TerrainOptions::cache_dir, and a streamed terrain (not resident)"
                    .into(),
            });
        }
        let terrain = Self::open_with(path, options)?;
        terrain
            .package
            .map(|p| p.path().to_path_buf())
            .ok_or_else(|| Error::Invalid {
                what: "Terrain::bake".into(),
                reason: "the terrain was not baked into a package".into(),
            })
    }

    /// The built-in procedural terrain: `size` x `size` samples (2^k + 1, 3 ..= 16385) `spacing_m` metres
    /// apart; the same seed gives the same terrain bit for bit. With a `cache_dir` it is baked into a
    /// package there on first use and streamed, as a file would be.
    pub fn procedural(
        seed: u64,
        size: u32,
        spacing_m: f32,
        cache_dir: Option<&Path>,
    ) -> Result<Self> {
        let p = ProceduralParams {
            seed,
            size,
            spacing: spacing_m,
        };
        Self::open_spec(
            &TerrainSpec::Procedural(p),
            &LoadOptions::default(),
            cache_dir,
            false,
            Progress::default(),
        )
    }

    /// A terrain from heights in memory: `width` x `height` samples, row-major from the north-west
    /// corner, `spacing_m` metres apart, held whole. A `cache_dir` keeps its SAT LOD and SG tables.
    pub fn from_heights(
        width: u32,
        height: u32,
        spacing_m: f32,
        heights: Vec<f32>,
        cache_dir: Option<&Path>,
    ) -> Result<Self> {
        let hm = Heightmap::new(Path::new("<memory>"), width, height, spacing_m, heights)?;
        Ok(Self::whole(format!("heights {width} x {height}"), hm, cache_dir))
    }

    /// Its name in reports: the path as given, or the procedural terrain's parameters.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Samples (columns, rows) of the data.
    pub fn size(&self) -> (u32, u32) {
        match &self.package {
            Some(p) => (p.header().width, p.header().height),
            None => (self.stand_in.width(), self.stand_in.height()),
        }
    }

    /// The distance between neighbouring samples of the data, metres (x and y alike).
    pub fn spacing_m(&self) -> f32 {
        match &self.package {
            Some(p) => p.header().spacing,
            None => self.stand_in.spacing(),
        }
    }

    /// The lowest and highest height, metres.
    pub fn height_range(&self) -> (f32, f32) {
        match &self.package {
            Some(p) => p.header().range,
            None => self.stand_in.range(),
        }
    }

    /// The height under world (x, y), metres, bilinear and clamped at the border: from the whole grid, or
    /// from a streamed terrain's coarse stand-in of at most 1 Mi samples (its rough shape: keep a camera
    /// clear of it with a margin). The data's own height at full resolution is
    /// [`crate::TerrainRenderer::height_at`].
    pub fn coarse_height_at(&self, x: f64, y: f64) -> f32 {
        self.stand_in.height_at_world(x, y)
    }

    /// Whether the terrain streams from a package (else it is held whole).
    pub fn is_streamed(&self) -> bool {
        self.package.is_some()
    }

    /// An oblique view across the whole terrain from the south, with clip planes fitted to it, and a
    /// vertical field of view of 60 degrees: the view `clipsat render` draws by default.
    pub fn default_camera(&self) -> Result<Camera> {
        crate::plan::camera::Camera::default_for(&self.stand_in).map(Camera)
    }

    /// Opens what `spec` names with `load`'s reading options; see [`Terrain::open`].
    pub(crate) fn open_spec(
        spec: &TerrainSpec,
        load: &LoadOptions,
        cache_dir: Option<&Path>,
        resident: bool,
        progress: Progress<'_>,
    ) -> Result<Self> {
        let name = match spec {
            TerrainSpec::Procedural(p) => format!("procedural(seed={}, size={})", p.seed, p.size),
            TerrainSpec::File(path) => path.display().to_string(),
        };
        let given = match spec {
            TerrainSpec::File(path) if package::is_package(path) => Some(Package::open(path)?),
            _ => None,
        };
        let package = match (given, cache_dir) {
            (Some(p), _) if resident => {
                return Ok(Self::whole(name, p.to_heightmap()?, cache_dir));
            }
            (Some(p), _) => p,
            (None, Some(dir)) if !resident => cached_package(spec, load, dir, progress)?,
            (None, _) => {
                let hm = match spec {
                    TerrainSpec::Procedural(p) => procedural::generate(p)?,
                    TerrainSpec::File(path) => source::load(path, load)?,
                };
                let mut t = Self::whole(name, hm, cache_dir);
                t.source = source_file(spec);
                return Ok(t);
            }
        };
        Ok(Self {
            name,
            stand_in: package.coarse_heightmap(STAND_IN_SAMPLES)?,
            package: Some(package),
            cache_dir: cache_dir.map(Path::to_path_buf),
            imagery: None,
            source: source_file(spec),
        })
    }

    fn whole(name: String, hm: Heightmap, cache_dir: Option<&Path>) -> Self {
        Self {
            name,
            stand_in: hm,
            package: None,
            cache_dir: cache_dir.map(Path::to_path_buf),
            imagery: None,
            source: None,
        }
    }

    /// Whether imagery is draped on it ([`TerrainOptions::imagery`]).
    pub fn has_imagery(&self) -> bool {
        self.imagery.is_some()
    }

    /// Takes the imagery package out (before [`Terrain::into_parts`]).
    pub(crate) fn take_imagery_package(&mut self) -> Option<ImageryPackage> {
        self.imagery.take()
    }

    /// The height grid's extent in its world frame, corner sample to corner sample: where a plain image
    /// is placed.
    fn grid_extent(&self) -> Extent {
        match &self.package {
            Some(p) => {
                let h = p.header();
                Extent::of_grid(h.width, h.height, f64::from(h.spacing), h.origin)
            }
            None => Extent::of_grid(
                self.stand_in.width(),
                self.stand_in.height(),
                f64::from(self.stand_in.spacing()),
                self.stand_in.origin(),
            ),
        }
    }

    /// Drapes the imagery at `path` (an image, or an imagery package) on the terrain: an image is baked
    /// into an imagery package in the cache folder on first use (keyed by the file's path, size and
    /// modification time, `options` and the grid's extent), or in memory without a cache folder. An
    /// imagery package keeps the extent it was baked with, so `options.extent` is refused with one.
    pub(crate) fn attach_imagery(
        &mut self,
        path: &Path,
        options: &ImageryOptions,
        progress: Progress<'_>,
    ) -> Result<()> {
        let grid = self.grid_extent();
        let package = if ImageryPackage::is_imagery_package(path) {
            if options.extent.is_some() {
                return Err(Error::param(
                    Param::ImageryExtent,
                    format!(
                        "{}: an imagery package keeps the extent it was baked with",
                        path.display()
                    ),
                ));
            }
            ImageryPackage::open(path)?
        } else {
            // A GeoTIFF, or an image with a world file, over georeferenced heights (a GeoTIFF, an `.hgt`
            // tile, a mosaic): placed by both
            // georeferences (unless an extent is given).
            let georef = match (options.extent, self.source.as_deref().and_then(source::heights_georef)) {
                (None, Some(heights)) => match GeoRef::of_imagery(path)? {
                    Some(image) => {
                        let (spacing, origin, columns) = match &self.package {
                            Some(p) => {
                                let h = p.header();
                                (f64::from(h.spacing), h.origin, h.width)
                            }
                            None => (
                                f64::from(self.stand_in.spacing()),
                                self.stand_in.origin(),
                                self.stand_in.width(),
                            ),
                        };
                        Some(georef_extent(path, &heights, &image, spacing, origin, columns)?)
                    }
                    None => None,
                },
                _ => None,
            };
            let placed = ImageryOptions {
                extent: georef.or(options.extent),
                ..*options
            };
            let options = &placed;
            let key = imagery_key(path, &grid, options)?;
            let open = || ImageryRows::open(path, &grid, options);
            match &self.cache_dir {
                Some(dir) => cached_imagery(dir, key, open, progress)?,
                None => {
                    let mut out = std::io::Cursor::new(Vec::new());
                    bake_imagery_rows(&mut open()?, DEFAULT_QUALITY, key, false, &mut out, progress)?;
                    ImageryPackage::from_bytes(path, out.into_inner())?
                }
            }
        };
        let extent = package.header().extent;
        if extent.overlap(&grid).is_none() {
            return Err(Error::param(
                Param::ImageryExtent,
                format!(
                    "{}: the imagery ({extent}) does not overlap the terrain ({grid})",
                    path.display()
                ),
            ));
        }
        self.imagery = Some(package);
        Ok(())
    }

    /// The cache folder the terrain was opened with.
    pub(crate) fn cache_dir(&self) -> Option<&Path> {
        self.cache_dir.as_deref()
    }

    /// The parts: name, stand-in (or the whole grid), the package streamed.
    pub(crate) fn into_parts(self) -> (String, Heightmap, Option<Package>) {
        (self.name, self.stand_in, self.package)
    }
}

#[cfg(feature = "internals")]
impl Terrain {
    /// [`Terrain::open`] for what `spec` names with every reading option ([`LoadOptions`]).
    pub fn from_spec(
        spec: &TerrainSpec,
        load: &LoadOptions,
        cache_dir: Option<&Path>,
        resident: bool,
        progress: Progress<'_>,
    ) -> Result<Self> {
        Self::open_spec(spec, load, cache_dir, resident, progress)
    }

    /// The whole grid, or a streamed terrain's coarse stand-in.
    pub fn heights(&self) -> &Heightmap {
        &self.stand_in
    }

    /// The parts: name, stand-in (or the whole grid), the package streamed.
    pub fn parts(self) -> (String, Heightmap, Option<Package>) {
        self.into_parts()
    }

    /// [`TerrainOptions::imagery`] for a terrain opened by [`Terrain::from_spec`], with every option
    /// ([`ImageryOptions`]), a bake's progress reported to `progress`.
    pub fn with_imagery(
        mut self,
        path: &Path,
        options: &ImageryOptions,
        progress: Progress<'_>,
    ) -> Result<Self> {
        self.attach_imagery(path, options, progress)?;
        Ok(self)
    }

    /// The imagery package draped on it, if any.
    pub fn imagery(&self) -> Option<&ImageryPackage> {
        self.imagery.as_ref()
    }

    /// Takes the imagery package out (before [`Terrain::parts`]).
    pub fn take_imagery(&mut self) -> Option<ImageryPackage> {
        self.take_imagery_package()
    }
}

/// The file a spec names, unless it is a package (whose source is not known).
fn source_file(spec: &TerrainSpec) -> Option<PathBuf> {
    match spec {
        TerrainSpec::File(path) if !package::is_package(path) => Some(path.clone()),
        _ => None,
    }
}

/// The cache key of an image draped on a grid of `grid`'s extent with `options`: the file's path, size
/// and modification time, the extent, the format version, the tile coder and the readers' revision.
fn imagery_key(path: &Path, grid: &Extent, options: &ImageryOptions) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, "cannot read", e))?;
    let mut h = Hash64::new();
    // Images drawn with their own levels keep the keys they had before a range could be given.
    let options = format!("{options:?}").replace(", range: None", "");
    h.write_bytes(format!("imagery {} {options} {grid:?} q{DEFAULT_QUALITY}", path.display()).as_bytes());
    h.write_u64(u64::from(crate::package::imagery::VERSION));
    // How the tiles are coded and the file read: a package baked before may hold tiles the decoder
    // misreads, a JPEG upside down or long texels, so it is baked again.
    h.write_bytes(crate::package::imagery::TILE_CODER.as_bytes());
    h.write_u32(source::READ_REVISION);
    package::stamp(&mut h, &meta);
    Ok(h.finish())
}

/// The package of a plain source in `dir`, baked there on first use ([`package::cached`]) and found by
/// later runs without reading the source: keyed by what `spec` names, `load`'s options, the readers'
/// revision ([`source::READ_REVISION`]) and, for a file, its size and modification time and those of the
/// sidecars its loader reads.
fn cached_package(
    spec: &TerrainSpec,
    load: &LoadOptions,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<Package> {
    let key = package_key(spec, load, source::READ_REVISION)?;
    let (path, baked) = package::cached(
        dir,
        key,
        || -> Result<Box<dyn RowSource>> {
            Ok(match spec {
                TerrainSpec::Procedural(p) => Box::new(procedural::Rows::new(p)?),
                TerrainSpec::File(path) => source::open_rows(path, load)?,
            })
        },
        progress,
    )?;
    // The same source's package from the last readers' revision is stale now: drop it, so the cache
    // folder does not keep one per revision (best effort, as for older formats).
    if let Some(last) = source::READ_REVISION.checked_sub(1).filter(|_| baked) {
        let old = package_key(spec, load, last)?;
        let _ = std::fs::remove_file(package::write::cached_file(dir, old, package::format::VERSION));
    }
    Package::open(&path)
}

/// [`cached_package`]'s key for the readers' revision `revision` (0: before revisions were counted).
fn package_key(spec: &TerrainSpec, load: &LoadOptions, revision: u32) -> Result<u64> {
    let mut h = Hash64::new();
    let mut key = format!("{spec:?} {load:?}");
    // The packages baked before `fill_height` existed keep their keys: it is named only when set.
    if load.fill_height.is_none() {
        key = key.replace(", fill_height: None", "");
    }
    if revision > 0 {
        key.push_str(&format!(" readers r{revision}"));
    }
    h.write_bytes(key.as_bytes());
    if let TerrainSpec::File(path) = spec {
        let stamp = |meta: &std::fs::Metadata, h: &mut Hash64| package::stamp(h, meta);
        // Each file it reads (a mosaic's tiles and list), and the sidecars a loader reads its layout or
        // spacing from (a world file, a .prj, an ESRI .hdr): editing one bakes again.
        let mosaic = source::is_mosaic(path);
        for file in source::input_files(path)? {
            let meta = std::fs::metadata(&file).map_err(|e| Error::io(&file, "cannot read", e))?;
            if mosaic {
                h.write_bytes(file.display().to_string().as_bytes());
            }
            stamp(&meta, &mut h);
            for ext in ["tfw", "TFW", "tifw", "tiffw", "prj", "hdr"] {
                match std::fs::metadata(file.with_extension(ext)) {
                    Ok(meta) => stamp(&meta, &mut h),
                    Err(_) => h.write_u64(0),
                }
            }
        }
    }
    Ok(h.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A package cached under the last readers' revision is not found by this one: the source is baked
    /// again under a new key and the stale file removed.
    #[test]
    fn a_package_of_the_last_readers_revision_is_baked_again_and_dropped() {
        let dir = std::env::temp_dir().join(format!("clipsat-readers-rev-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let spec = TerrainSpec::Procedural(ProceduralParams {
            size: 33,
            ..ProceduralParams::default()
        });
        let load = LoadOptions::default();
        let now = package_key(&spec, &load, source::READ_REVISION).expect("key");
        let last = package_key(&spec, &load, source::READ_REVISION - 1).expect("key");
        assert_ne!(now, last);
        let stale = package::write::cached_file(&dir, last, package::format::VERSION);
        std::fs::write(&stale, b"a package of the last revision").expect("stale file");
        let pkg = cached_package(&spec, &load, &dir, Progress::default()).expect("package");
        assert_eq!(pkg.header().width, 33);
        assert!(!stale.exists(), "the last revision's package is dropped");
        assert!(package::write::cached_file(&dir, now, package::format::VERSION).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
