//! `clipsat bake`: writes a terrain package (stage 1b), the GC section 7 residual pyramid in compressed tiles
//! and the SAT LOD tables' compact records.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use clipsat::package::imagery::DEFAULT_QUALITY;
use clipsat::package::imagery_bake::bake_imagery_file;
use clipsat::package::{self, BakeOptions, CodecKind};
use clipsat::source::georef::{georef_extent, GeoRef};
use clipsat::source::imagery::Extent;
use clipsat::source::imagery_rows::ImageryRows;
use clipsat::source::RowSource;
use clipsat::Result;
use serde_json::json;

use super::TerrainArgs;

#[derive(Args, Debug)]
pub(crate) struct BakeArgs {
    /// Terrain file or `procedural[:...]` (same as --terrain).
    #[arg(value_name = "TERRAIN")]
    terrain_pos: Option<String>,
    #[command(flatten)]
    terrain: TerrainArgs,
    /// The package to write (`.clipsat` by convention).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Largest absolute height error, metres. Default: half the source's own step (0.5 m for integer
    /// metres, 0.05 m for decimetres), or 0.005 m for float sources.
    #[arg(long, value_name = "M")]
    max_error: Option<f64>,
    /// Tile codec: rans, zstd or lz4.
    #[arg(long, value_name = "C", default_value = "rans")]
    codec: String,
    /// Tile side, samples (even).
    #[arg(long, value_name = "N", default_value_t = package::write::DEFAULT_TILE)]
    tile: u32,
    /// zstd level, 1..=22.
    #[arg(long, value_name = "L", default_value_t = package::write::DEFAULT_ZSTD_LEVEL)]
    zstd_level: i32,
    /// Leave out the SAT LOD tables (they are then computed from the heights on first use).
    #[arg(long)]
    no_lod_tables: bool,
    /// Print a machine-readable report on stdout.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &BakeArgs) -> Result<()> {
    let mut targs = args.terrain.clone();
    if let Some(t) = &args.terrain_pos {
        targs.terrain = Some(t.clone());
    }
    let (name, mut rows) = targs.rows()?;
    let opts = BakeOptions {
        max_error: args.max_error,
        codec: CodecKind::parse(&args.codec)?,
        tile: args.tile,
        zstd_level: args.zstd_level,
        lod_tables: !args.no_lod_tables,
    };
    super::ensure_parent(&args.out)?;
    crate::app::progress::bars!(!args.json, bars, report, progress);
    let start = Instant::now();
    // Imagery is opened and placed first, so that imagery refused by its header writes nothing; one found
    // damaged while it is read takes the terrain's package with it.
    let imagery = match &targs.imagery {
        Some(path) => Some(open_imagery(&targs, path, &*rows)?),
        None => None,
    };
    let report = package::bake_source(&mut *rows, &args.out, &opts, progress)?;
    let imagery = match imagery {
        Some(mut im) => {
            let out = args.out.with_extension("clipsat-imagery");
            match bake_imagery_file(&mut im, DEFAULT_QUALITY, 0, true, &out, progress) {
                Ok(r) => Some((out, r)),
                Err(e) => {
                    let _ = std::fs::remove_file(&args.out);
                    return Err(e);
                }
            }
        }
        None => None,
    };
    let seconds = start.elapsed().as_secs_f64();
    if args.json {
        let mut v = serde_json::to_value(&report).unwrap_or_default();
        if let Some((out, r)) = &imagery {
            let mut i = serde_json::to_value(r).unwrap_or_default();
            i["out"] = json!(out.display().to_string());
            v["imagery"] = i;
        }
        v["terrain"] = json!(name);
        v["out"] = json!(args.out.display().to_string());
        v["seconds"] = json!(seconds);
        super::print_json(&v);
        return Ok(());
    }
    outln!("terrain      {name}");
    outln!("package      {}", args.out.display());
    outln!(
        "size         {} bytes, {:.4} bytes/sample ({} samples, {} levels, {} tiles of {}^2, {})",
        report.bytes,
        report.bytes_per_sample,
        report.samples,
        report.levels,
        report.tiles,
        report.tile,
        report.codec.name()
    );
    outln!(
        "split        pyramid {:.4} bytes/sample, SAT LOD tables {:.4} bytes/sample",
        report.pyramid_bytes_per_sample,
        report.lod_table_bytes_per_sample
    );
    outln!(
        "error        rms {:.4} m, max {:.4} m (bound {} m, quantum {} m)",
        report.rms_error,
        report.max_error,
        report.max_error_bound,
        report.quantum
    );
    if let Some((out, r)) = &imagery {
        outln!(
            "imagery      {}: {} bytes, {:.4} bytes/texel ({:.4} at level 0, {} texels, {} levels, {} tiles), \
             PSNR {:.2} dB",
            out.display(),
            r.bytes,
            r.bytes_per_texel,
            r.level0_bytes_per_texel,
            r.texels,
            r.levels,
            r.tiles,
            r.psnr_db
        );
    }
    outln!("time         {seconds:.2} s");
    Ok(())
}

/// `--imagery` opened and placed on the heights `rows` will give: over the grid's extent, corner sample to
/// corner sample, unless `--imagery-extent` says otherwise.
fn open_imagery(
    targs: &TerrainArgs,
    path: &std::path::Path,
    rows: &dyn RowSource,
) -> Result<ImageryRows> {
    let g = rows.grid();
    let grid = Extent::of_grid(g.width, g.height, f64::from(g.spacing), g.origin);
    let mut options = targs.imagery_options()?;
    // A GeoTIFF, or an image with a world file, over georeferenced heights (a GeoTIFF, an `.hgt` tile, a
    // mosaic): placed by both
    // georeferences (unless an extent is given).
    if let (None, clipsat::source::TerrainSpec::File(heights)) = (options.extent, targs.spec()?) {
        if let (Some(h), Some(i)) = (
            clipsat::source::heights_georef(&heights),
            GeoRef::of_imagery(path)?,
        ) {
            let spacing = f64::from(g.spacing);
            options.extent = Some(georef_extent(path, &h, &i, spacing, g.origin, g.width)?);
        }
    }
    ImageryRows::open(path, &grid, &options)
}
