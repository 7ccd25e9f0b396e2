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
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "parts",
        conflicts_with = "parts"
    )]
    out: Option<PathBuf>,
    /// Bake a tile mosaic as a package set in DIR instead of one package: each cell of the tiles'
    /// lattice its own part, baked apart (parts whose tiles have not changed are kept), then a top
    /// package and the index `DIR/clipsat-set.toml`, which `--terrain DIR` opens.
    #[arg(long, value_name = "DIR")]
    parts: Option<PathBuf>,
    /// With --parts: bake cell N's part alone (no top, no index), for a cluster's map step.
    #[arg(long, value_name = "N", requires = "parts", conflicts_with = "finish")]
    cell: Option<usize>,
    /// With --parts: bake the top and write the index, every part baked already (a cluster's last step).
    #[arg(long, requires = "parts")]
    finish: bool,
    /// With --parts: print the set's cells (their count, rectangles, tiles and part files) as JSON and
    /// bake nothing.
    #[arg(long, requires = "parts")]
    list_cells: bool,
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
    if let Some(dir) = &args.parts {
        return run_parts(args, &targs, dir);
    }
    let Some(out) = &args.out else {
        return Err(invalid("give --out FILE or --parts DIR"));
    };
    let (name, mut rows) = targs.rows()?;
    let opts = BakeOptions {
        max_error: args.max_error,
        codec: CodecKind::parse(&args.codec)?,
        tile: args.tile,
        zstd_level: args.zstd_level,
        lod_tables: !args.no_lod_tables,
        ..BakeOptions::default()
    };
    super::ensure_parent(out)?;
    crate::app::progress::bars!(!args.json, bars, report, progress);
    let start = Instant::now();
    // Imagery is opened and placed first, so that imagery refused by its header writes nothing; one found
    // damaged while it is read takes the terrain's package with it.
    let imagery = match &targs.imagery {
        Some(path) => Some(open_imagery(&targs, path, &*rows)?),
        None => None,
    };
    let report = package::bake_source(&mut *rows, out, &opts, progress)?;
    let imagery = match imagery {
        Some(mut im) => {
            let im_out = out.with_extension("clipsat-imagery");
            match bake_imagery_file(&mut im, DEFAULT_QUALITY, 0, true, &im_out, progress) {
                Ok(r) => Some((im_out, r)),
                Err(e) => {
                    let _ = std::fs::remove_file(out);
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
        v["out"] = json!(out.display().to_string());
        v["seconds"] = json!(seconds);
        super::print_json(&v);
        return Ok(());
    }
    outln!("terrain      {name}");
    outln!("package      {}", out.display());
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

/// A refused combination of `bake`'s options.
fn invalid(reason: &str) -> clipsat::Error {
    clipsat::Error::Invalid {
        what: "clipsat bake".into(),
        reason: reason.into(),
    }
}

/// `clipsat bake --parts DIR`: the tile mosaic as a package set (`package::set_bake`).
fn run_parts(args: &BakeArgs, targs: &TerrainArgs, dir: &std::path::Path) -> Result<()> {
    use clipsat::package::set_bake;
    let spec = match targs.spec()? {
        clipsat::source::TerrainSpec::File(p) if clipsat::source::is_mosaic(&p) => p,
        _ => return Err(invalid(
            "--parts bakes a tile mosaic (a folder, list, glob or VRT of tiles) as a package set",
        )),
    };
    // A folder holding a set reads as the set, not as tiles (it had been refused as holding no tile).
    if clipsat::package::set::is_set(&spec) {
        return Err(invalid(&format!(
            "{} is a package set: draw it with --terrain, or bake the tiles it was baked from",
            spec.display()
        )));
    }
    // A set baked into its tiles' folder would turn `--terrain` on that folder from the tiles to the set.
    let same = |a: &std::path::Path, b: &std::path::Path| matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b);
    if spec.is_dir() && same(&spec, dir) {
        return Err(invalid(&format!(
            "--parts {} is the tiles' own folder: give the set a folder of its own",
            dir.display()
        )));
    }
    if targs.imagery.is_some() {
        return Err(invalid(
            "--parts bakes heights alone: bake the imagery with a whole package (--out), or drape it \
             when the set is drawn (--imagery)",
        ));
    }
    let load = targs.load_options()?;
    if load.resample_ew {
        return Err(invalid(
            "--resample-ew resamples the whole mosaic's rows, and a package set keeps the tiles' grid: \
             bake one package for it (--out)",
        ));
    }
    let opts = BakeOptions {
        max_error: args.max_error,
        codec: CodecKind::parse(&args.codec)?,
        tile: args.tile,
        zstd_level: args.zstd_level,
        lod_tables: false,
        ..BakeOptions::default()
    };
    crate::app::progress::bars!(!args.json, bars, report, progress);
    let start = Instant::now();
    let mut plan = set_bake::plan(&spec, &load, &opts, dir)?;
    if args.list_cells {
        let cells: Vec<_> = plan
            .cells
            .iter()
            .zip(&plan.index.parts)
            .enumerate()
            .map(|(n, (c, p))| {
                json!({"cell": n, "rect": c, "part": p.file, "tiles": p.sources,
                       "baked": plan.part_stands(n)})
            })
            .collect();
        super::print_json(&json!({"cells": cells.len(), "tile": plan.index.tile,
            "part_levels": plan.index.part_levels, "list": cells}));
        return Ok(());
    }
    let (what, v) = if let Some(n) = args.cell {
        let r = set_bake::bake_cell(&plan, n, progress)?;
        (
            format!(
                "cell {n}: {} ({} bytes)",
                plan.part_path(n).display(),
                r.bytes
            ),
            json!({"cell": n, "part": plan.part_path(n).display().to_string(), "bytes": r.bytes}),
        )
    } else if args.finish {
        let (bytes, removed) = set_bake::finish(&mut plan, progress)?;
        (
            format!(
                "{} parts and the top: {bytes} bytes ({removed} stale files removed)",
                plan.cells.len()
            ),
            json!({"cells": plan.cells.len(), "bytes": bytes, "removed": removed}),
        )
    } else {
        let r = set_bake::bake_plan(plan, progress)?;
        (
            format!(
                "{} cells, {} baked ({} kept), {} bytes; tiles of {}^2, {} levels a part ({} stale files removed)",
                r.cells,
                r.baked,
                r.cells - r.baked,
                r.bytes,
                r.tile,
                r.part_levels,
                r.removed
            ),
            serde_json::to_value(&r).unwrap_or_default(),
        )
    };
    let seconds = start.elapsed().as_secs_f64();
    if args.json {
        let mut v = v;
        v["set"] = json!(dir
            .join(clipsat::package::set::INDEX_NAME)
            .display()
            .to_string());
        v["seconds"] = json!(seconds);
        super::print_json(&v);
        return Ok(());
    }
    outln!("terrain      {}", spec.display());
    outln!(
        "set          {}",
        dir.join(clipsat::package::set::INDEX_NAME).display()
    );
    outln!("baked        {what}");
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
