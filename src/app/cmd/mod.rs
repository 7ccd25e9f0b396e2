//! Subcommands of the `clipsat` binary, and the options they share.

/// `println!` that stops quietly when stdout is closed (`clipsat ... | head`) instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

pub(crate) mod args;
pub(crate) mod bake;
pub(crate) mod bench;
pub(crate) mod fly;
pub(crate) mod hashes;
pub(crate) mod imagery;
pub(crate) mod info;
pub(crate) mod render;
pub(crate) mod selftest;
pub(crate) mod sg;
pub(crate) mod tune_p;
#[cfg(feature = "view")]
pub(crate) mod view;
#[cfg(feature = "view")]
pub(crate) mod view_setup;

use args::{arg_error, Size};
use clap::{Args, ValueEnum};
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::source::{
    self, procedural::ProceduralParams, LoadOptions, RawFormat, RawLayout, TerrainSpec,
};
use clipsat::{Error, Result};

/// Options that choose and read a terrain.
#[derive(Args, Clone, Debug, Default)]
pub(crate) struct TerrainArgs {
    /// Terrain file (.png, .tif, .hgt, DTED .dt0/.dt1/.dt2, ESRI .asc and .flt/.bil grids, gridded .xyz,
    /// .raw/.r16/.f32, a `.clipsat` package), a mosaic of .hgt and GeoTIFF tiles (a folder, a .txt list
    /// of paths, a GDAL .vrt, or a quoted glob like 'tiles/N5*.hgt') or
    /// `procedural[:seed=S,size=N,spacing=M]`.
    /// Default: the built-in procedural terrain.
    #[arg(long, value_name = "T")]
    pub(crate) terrain: Option<String>,
    /// Sample spacing in metres, overriding the file's own (needed for PNG and raw files; default 30).
    #[arg(long, value_name = "M")]
    pub(crate) spacing: Option<f32>,
    /// Metres per stored unit for PNG and raw u16 files (default 0.1 for 16-bit, 1 for 8-bit).
    #[arg(long, value_name = "S")]
    pub(crate) height_scale: Option<f32>,
    /// Metres added to every height after scaling.
    #[arg(
        long,
        value_name = "M",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub(crate) height_offset: f32,
    /// Raw file dimensions, WxH samples.
    #[arg(long, value_name = "WxH")]
    pub(crate) raw_size: Option<Size>,
    /// Raw file sample type, little-endian. Default: u16.
    #[arg(long, value_enum)]
    pub(crate) raw_format: Option<RawFormatArg>,
    /// Refuse files declaring more samples than this (checked before allocating).
    #[arg(long, value_name = "N", default_value_t = source::DEFAULT_MAX_SAMPLES)]
    pub(crate) max_samples: u64,
    /// How a PNG holds heights: grey (also RGB/RGBA with equal channels), terrain-rgb (Mapbox:
    /// -10000 + (R 65536 + G 256 + B) 0.1 m) or terrarium (R 256 + G + B / 256 - 32768 m).
    #[arg(long, value_name = "ENCODING", value_enum, default_value_t = PngEncodingArg::Grey)]
    pub(crate) png_encoding: PngEncodingArg,
    /// Draw a geographic grid (an SRTM .hgt, a DTED cell, a GeoTIFF, ASCII or binary grid in degrees, a
    /// mosaic of them) to scale: resample each
    /// row to square cells of its N-S spacing. Without it such a grid is drawn with square cells,
    /// stretched E-W by its N-S / E-W spacing (`clipsat info` shows it: 1.86x at 57.5 N).
    #[arg(long)]
    pub(crate) resample_ew: bool,
    /// A stored sample value that marks voids (filled from their neighbours), for a file that declares
    /// none or another: `nan`, -9999, 0... Compared before --height-scale and --height-offset (a PNG's
    /// grey level, or a web-map encoding's metres).
    #[arg(long, value_name = "V", allow_negative_numbers = true)]
    pub(crate) nodata: Option<f64>,
    /// For a mosaic of tiles (a folder, a .txt list or a quoted glob pattern as --terrain): the height in
    /// metres of samples no tile has data for (missing tiles, voids). Default: no data, filled from
    /// their neighbours (the mosaic is then loaded whole).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub(crate) fill_height: Option<f32>,
    /// Imagery to drape on the terrain: a PNG, JPEG, TIFF or GeoTIFF (grey, RGB, RGBA or palette; alpha is
    /// dropped; a GeoTIFF over georeferenced heights is placed by both georeferences), baked
    /// into an imagery package in the cache folder on first use, or an imagery package from `clipsat bake
    /// --imagery`. A plain image spans the height grid's extent, corner sample to corner sample, each
    /// texel an area (see --imagery-extent).
    #[arg(long, value_name = "FILE")]
    pub(crate) imagery: Option<std::path::PathBuf>,
    /// Where the imagery lies: west,south,east,north in metres in the terrain's frame (x east, y north, the
    /// south-west sample at 0,0). Default: the height grid's extent.
    #[arg(
        long,
        value_name = "W,S,E,N",
        requires = "imagery",
        allow_hyphen_values = true
    )]
    pub(crate) imagery_extent: Option<String>,
    /// Draw the imagery's colour rings in RGBA8 (4 bytes a texel) even where the device has BC or ETC2
    /// texture compression, whose blocks (0.5 byte a texel) they take otherwise
    /// (`RenderOptions::imagery_rgba8`).
    #[arg(long, requires = "imagery")]
    pub(crate) imagery_rgba8: bool,
    /// Refuse imagery declaring more texels than this (checked before allocating).
    #[arg(long, value_name = "N", default_value_t = source::imagery::DEFAULT_MAX_IMAGERY_TEXELS)]
    pub(crate) max_imagery_texels: u64,
    /// The imagery's stored sample values drawn black and white, LO,HI: mapped linearly onto 0..255, for
    /// imagery whose samples fill little of their type (12-bit or reflectance values in a 16-bit file,
    /// which draw nearly black otherwise). Default: 8-bit samples as they are, 16-bit rounded to 8 bits.
    #[arg(long, value_name = "LO,HI", requires = "imagery")]
    pub(crate) imagery_range: Option<String>,
}

/// `--png-encoding`, the command line's name for [`source::PngEncoding`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum PngEncodingArg {
    /// Grey values (RGB/RGBA with equal channels count as grey).
    #[default]
    Grey,
    /// Mapbox Terrain-RGB.
    TerrainRgb,
    /// Terrarium.
    Terrarium,
}

impl From<PngEncodingArg> for source::PngEncoding {
    fn from(a: PngEncodingArg) -> Self {
        match a {
            PngEncodingArg::Grey => Self::Grey,
            PngEncodingArg::TerrainRgb => Self::TerrainRgb,
            PngEncodingArg::Terrarium => Self::Terrarium,
        }
    }
}

impl TerrainArgs {
    /// What `--terrain` names.
    pub(crate) fn spec(&self) -> Result<TerrainSpec> {
        TerrainSpec::parse(self.terrain.as_deref().unwrap_or("procedural"))
            .map_err(args::flag("--terrain"))
    }

    /// The package `--terrain` names, opened and validated, or `None` for any other source.
    pub(crate) fn package(&self) -> Result<Option<clipsat::package::Package>> {
        match self.spec()? {
            TerrainSpec::File(path) if clipsat::package::is_package(&path) => {
                Ok(Some(clipsat::package::Package::open(&path)?))
            }
            _ => Ok(None),
        }
    }

    /// The terrain these options name, opened by the library ([`clipsat::Terrain`]): when `stream`, the
    /// package `--terrain` names or a plain source's, baked with the default options into the cache
    /// folder ([`clipsat::bake::default_cache_dir`]) on first use and found there later without loading
    /// the source (a progress bar on stderr while baking when `progress`), to stream; otherwise loaded
    /// whole (a package decoded).
    pub(crate) fn open(&self, stream: bool, progress: bool) -> Result<clipsat::Terrain> {
        let spec = match self.spec()? {
            TerrainSpec::Procedural(p) => TerrainSpec::Procedural(ProceduralParams {
                spacing: self.spacing.unwrap_or(p.spacing),
                ..p
            }),
            file => file,
        };
        crate::app::progress::bars!(progress, bars, report, progress);
        let terrain = clipsat::Terrain::from_spec(
            &spec,
            &self.load_options()?,
            Some(&clipsat::bake::default_cache_dir()),
            !stream,
            progress,
        )
        .map_err(|e| match e {
            // The default quantum cannot hold this terrain's range (`clipsat bake --max-error` can).
            Error::Param {
                param: clipsat::Param::MaxError,
                reason,
            } => arg_error(
                "--terrain",
                format!(
                    "cannot bake it into a package to stream with the default quantum ({reason}); \
                     --resident loads it whole, or bake it with a coarser `clipsat bake --max-error`"
                ),
            ),
            // The procedural terrain's parameters come in `--terrain`'s words.
            e @ Error::Invalid { .. } if matches!(spec, TerrainSpec::Procedural(_)) => {
                args::flag("--terrain")(e)
            }
            other => other,
        })?;
        match &self.imagery {
            Some(path) => terrain.with_imagery(path, &self.imagery_options()?, progress),
            None => Ok(terrain),
        }
    }

    /// How to read and place `--imagery`.
    pub(crate) fn imagery_options(&self) -> Result<source::imagery::ImageryOptions> {
        Ok(source::imagery::ImageryOptions {
            extent: self
                .imagery_extent
                .as_deref()
                .map(source::imagery::Extent::parse)
                .transpose()?,
            max_texels: self.max_imagery_texels,
            range: self
                .imagery_range
                .as_deref()
                .map(|t| {
                    let v: Vec<f64> = t.split(',').filter_map(|x| x.trim().parse().ok()).collect();
                    match v[..] {
                        [lo, hi] if t.split(',').count() == 2 => {
                            source::imagery::check_range((lo, hi))
                        }
                        _ => Err(Error::param(
                            clipsat::Param::ImageryRange,
                            format!("`{t}` is not two numbers LO,HI"),
                        )),
                    }
                })
                .transpose()?,
        })
    }

    /// The terrain's name in reports: a file's path as given (a package's too), or the procedural
    /// terrain's parameters.
    pub(crate) fn name(&self) -> Result<String> {
        Ok(match self.spec()? {
            TerrainSpec::Procedural(p) => format!("procedural(seed={}, size={})", p.seed, p.size),
            TerrainSpec::File(path) => path.display().to_string(),
        })
    }

    /// The terrain these options name as rows for the out-of-core bake: the procedural terrain is
    /// generated a band at a time, files are opened by [`source::open_rows`] (raw files read a band at a
    /// time), and a package is decoded whole.
    pub(crate) fn rows(&self) -> Result<(String, Box<dyn source::RowSource>)> {
        if self.package()?.is_none() {
            match self.spec()? {
                TerrainSpec::Procedural(p) => {
                    let p = ProceduralParams {
                        spacing: self.spacing.unwrap_or(p.spacing),
                        ..p
                    };
                    return Ok((
                        self.name()?,
                        Box::new(
                            source::procedural::Rows::new(&p).map_err(args::flag("--terrain"))?,
                        ),
                    ));
                }
                TerrainSpec::File(path) => {
                    let rows = source::open_rows(&path, &self.load_options()?)?;
                    return Ok((path.display().to_string(), rows));
                }
            }
        }
        let (name, hm) = self.load()?;
        Ok((name, Box::new(source::Resident::new(hm))))
    }

    /// Loads the terrain these options name; a package is decoded whole (the resident path).
    pub(crate) fn load(&self) -> Result<(String, Heightmap)> {
        if let Some(p) = self.package()? {
            return Ok((p.path().display().to_string(), p.to_heightmap()?));
        }
        let spec = self.spec()?;
        let opts = self.load_options()?;
        match spec {
            TerrainSpec::Procedural(p) => {
                let p = ProceduralParams {
                    spacing: self.spacing.unwrap_or(p.spacing),
                    ..p
                };
                Ok((
                    self.name()?,
                    source::procedural::generate(&p).map_err(args::flag("--terrain"))?,
                ))
            }
            TerrainSpec::File(path) => {
                Ok((path.display().to_string(), source::load(&path, &opts)?))
            }
        }
    }

    /// How to read a terrain file, from these options.
    pub(crate) fn load_options(&self) -> Result<LoadOptions> {
        let raw = match (&self.raw_size, &self.raw_format) {
            (None, None) => None,
            (Some(size), format) => Some(RawLayout {
                width: size.width,
                height: size.height,
                format: match format.unwrap_or(RawFormatArg::U16) {
                    RawFormatArg::U16 => RawFormat::U16,
                    RawFormatArg::F32 => RawFormat::F32,
                },
            }),
            (None, Some(_)) => return Err(arg_error("--raw-format", "needs --raw-size WxH too")),
        };
        let opts = LoadOptions {
            spacing: self.spacing,
            height_scale: self.height_scale,
            height_offset: self.height_offset,
            raw,
            max_samples: self.max_samples,
            png_encoding: self.png_encoding.into(),
            resample_ew: self.resample_ew,
            nodata: self.nodata,
            fill_height: self.fill_height,
        };
        Ok(opts)
    }
}

/// `--raw-format`: the raw file's sample type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(crate) enum RawFormatArg {
    /// Unsigned 16-bit.
    U16,
    /// 32-bit float.
    F32,
}

/// The `--profile` option.
#[derive(Args, Clone, Debug)]
pub(crate) struct ProfileArgs {
    /// Budget profile: a shipped name (gles3-low, gles3-mid, desktop) or a path to a TOML file.
    #[arg(long, value_name = "P", default_value = clipsat::profile::DEFAULT_PROFILE)]
    pub(crate) profile: String,
}

impl ProfileArgs {
    pub(crate) fn load(&self) -> Result<Profile> {
        Profile::load(&self.profile).map_err(args::flag("--profile"))
    }
}

/// Writes `value` as pretty JSON on stdout.
pub(crate) fn print_json(value: &serde_json::Value) {
    outln!(
        "{}",
        serde_json::to_string_pretty(value).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    );
}

/// Creates the parent folder of an output file.
pub(crate) fn ensure_parent(path: &std::path::Path) -> Result<()> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))
        }
        _ => Ok(()),
    }
}
