//! `clipsat info`: what a terrain is, and what each shipped profile would need to render it.

use clap::Args;
use clipsat::package::imagery::ImageryPackage;
use clipsat::profile::Profile;
use clipsat::profile::SHIPPED;
use clipsat::Result;
use serde_json::json;

use super::TerrainArgs;

mod projection;

#[derive(Args, Debug)]
pub(crate) struct InfoArgs {
    /// Terrain file or `procedural[:...]` (same as --terrain).
    #[arg(value_name = "TERRAIN")]
    terrain_pos: Option<String>,
    #[command(flatten)]
    terrain: TerrainArgs,
    /// Print a machine-readable summary on stdout.
    #[arg(long)]
    json: bool,
    /// For a terrain in degrees (an SRTM tile, a geographic GeoTIFF or grid, a mosaic of them): write a
    /// PNG plot of how far the one metric frame it is drawn in is from true lengths, E-W and N-S, across
    /// its latitudes (and, for scale, E-W for the same extent elsewhere). Refused for other terrains.
    #[arg(long, value_name = "FILE.png")]
    plot_projection: Option<std::path::PathBuf>,
}

pub(crate) fn run(args: &InfoArgs) -> Result<()> {
    let mut targs = args.terrain.clone();
    if let Some(t) = &args.terrain_pos {
        targs.terrain = Some(t.clone());
    }
    // An imagery package alone (`clipsat bake --imagery` writes one beside the terrain's).
    if let Some(t) = targs.terrain.as_deref() {
        let path = std::path::Path::new(t);
        if ImageryPackage::is_imagery_package(path) {
            refuse_plot(args, "an imagery package")?;
            let p = ImageryPackage::open(path)?;
            if args.json {
                super::print_json(&super::imagery::imagery_json(&p));
            } else {
                super::imagery::print_imagery(&p);
            }
            return Ok(());
        }
    }
    // `--imagery`: checked, placed on this terrain and baked into the cache, then described.
    let imagery = match &targs.imagery {
        Some(_) => targs.open(false, false)?.take_imagery(),
        None => None,
    };
    if let Some(pkg) = targs.package()? {
        refuse_plot(args, "a package, in metres already")?;
        if let (Some(p), false) = (&imagery, args.json) {
            super::imagery::print_imagery(p);
        }
        return package_info(&pkg, args.json);
    }
    let (name, hm) = Summary::of(&targs)?;
    if let Some(out) = &args.plot_projection {
        let geo = hm.geo().ok_or_else(|| {
            not_geographic("in metres (projected, a plain image, or given `--spacing`)")
        })?;
        projection::plot(geo, out)?;
    }
    let (lo, hi) = hm.range();
    let (ex, ey) = hm.extent_m();
    let mut profiles = Vec::new();
    for (pname, _) in SHIPPED {
        let p = Profile::load(pname).map_err(super::args::flag("--profile"))?;
        let f = p.footprint();
        // Finest ring spacing that still shows the whole terrain in the coarsest ring.
        let coarsest_span_m = f64::from(p.clipmap.n - 1)
            * f64::from(hm.spacing())
            * f64::from(1u32 << (p.clipmap.levels - 1));
        profiles.push(json!({
            "profile": pname,
            "cpu_budget_bytes": p.budget.cpu_memory_bytes,
            "cpu_split": p.cpu_split(),
            "gpu_bytes": f.total(),
            "gpu_budget_bytes": p.budget.gpu_memory_bytes,
            "parts": f,
            "coarsest_ring_span_m": coarsest_span_m,
            "detail_tiles": p.budget.detail_tiles,
            "detail_tile_samples": p.detail_side(),
            // SG shading's per-level tables, on top of `gpu_bytes` (fixed by the profile, whatever the
            // terrain): normals only, and with visibility's horizon tables.
            "sg_bytes": p.sg_table_bytes(0),
            "sg_visibility_bytes": p.sg_table_bytes(clipsat::bake::horizon::DEFAULT_AZIMUTHS),
            // Draped imagery's colour rings (GPU) and tile cache plus staging (CPU), where allowed.
            "imagery_gpu_bytes": p.imagery_gpu_bytes(),
            "imagery_cpu_bytes": p.allows(clipsat::profile::Feature::Imagery).then(|| p.imagery.cpu_bytes()),
        }));
    }
    if args.json {
        super::print_json(&json!({
            "terrain": name,
            "width": hm.width(),
            "height": hm.height(),
            "spacing_m": hm.spacing(),
            "extent_m": [ex, ey],
            "min_m": lo,
            "max_m": hi,
            "voids_filled": hm.voids_filled(),
            "ew_spacing_m": hm.ew_spacing(),
            "ew_stretch": hm.ew_stretch(),
            "geographic": hm.geo().map(projection::json),
            "profiles": profiles,
            "imagery": imagery.as_ref().map(super::imagery::imagery_json),
        }));
        return Ok(());
    }
    outln!("terrain   {name}");
    outln!(
        "samples   {} x {} at {} m ({:.1} x {:.1} km)",
        hm.width(),
        hm.height(),
        hm.spacing(),
        ex / 1e3,
        ey / 1e3
    );
    if (hm.ew_stretch() - 1.0).abs() > clipsat::source::SQUARE_CELLS_TOLERANCE {
        outln!(
            "cells     {:.1} m E-W against {} m N-S: drawn {:.2}x wide with square cells \
             (--resample-ew draws it to scale)",
            hm.ew_spacing(),
            hm.spacing(),
            hm.ew_stretch()
        );
    }
    if let Some(g) = hm.geo() {
        projection::print(g, hm.ew_stretch());
    }
    outln!("heights   {lo:.1} .. {hi:.1} m");
    outln!("voids     {} filled", hm.voids_filled());
    if let Some(p) = &imagery {
        super::imagery::print_imagery(p);
    }
    // What render, fly and view do with it: the split below is what they hold once it streams.
    outln!(
        "streamed  render, fly and view bake it into a package in {} on first use and stream it \
         (--resident: loaded whole); `clipsat bake` writes the package elsewhere",
        clipsat::bake::default_cache_dir().display()
    );
    outln!(
        "profile     GPU memory needed / budget    coarsest ring span   CPU budget: rings + tile cache + queries + LOD tables + SG inputs   \
         detail pool                 SG tables (+ visibility)"
    );
    for p in &profiles {
        let mib = |v: &serde_json::Value| v.as_f64().unwrap_or(0.0) / 1048576.0;
        outln!(
            "{:<11} {:>9.2} MiB / {:>7.1} MiB    {:>8.1} km          {:>6.1} MiB: {:.2} + {:.2} + {:.2} + {:.2} + {:.2} MiB   \
             {} tiles of {}^2 ({:.2} MiB)   {:.2} MiB ({:.2} MiB)",
            p["profile"].as_str().unwrap_or("?"),
            mib(&p["gpu_bytes"]),
            mib(&p["gpu_budget_bytes"]),
            p["coarsest_ring_span_m"].as_f64().unwrap_or(0.0) / 1e3,
            mib(&p["cpu_budget_bytes"]),
            mib(&p["cpu_split"]["rings"]),
            mib(&p["cpu_split"]["tile_cache"]),
            mib(&p["cpu_split"]["queries"]),
            mib(&p["cpu_split"]["lod_tables"]),
            mib(&p["cpu_split"]["shading"]),
            p["detail_tiles"],
            p["detail_tile_samples"],
            mib(&p["parts"]["detail"]),
            mib(&p["sg_bytes"]),
            mib(&p["sg_visibility_bytes"]),
        );
    }
    if imagery.is_some() {
        // What the drape adds to each profile's need above: its rings on the GPU, and its cache taken
        // from the CPU budget before the rest is split (`engine::setup`).
        for p in &profiles {
            let name = p["profile"].as_str().unwrap_or("?");
            let mib = |v: &serde_json::Value| v.as_f64().unwrap_or(0.0) / 1048576.0;
            match p["imagery_cpu_bytes"].as_f64() {
                Some(cpu) => outln!(
                    "{name:<11} with imagery: colour rings {:.2} MiB more GPU memory ({:.2} of {:.1} MiB), \
                     its tile cache and staging {:.2} MiB taken from the CPU budget before the split above",
                    mib(&p["imagery_gpu_bytes"]),
                    mib(&p["gpu_bytes"]) + mib(&p["imagery_gpu_bytes"]),
                    mib(&p["gpu_budget_bytes"]),
                    cpu / 1048576.0,
                ),
                None => outln!("{name:<11} with imagery: not allowed (no shading feature \"imagery\")"),
            }
        }
    }
    Ok(())
}

/// Refuses `--plot-projection` for `what`, a terrain that is not in degrees.
fn refuse_plot(args: &InfoArgs, what: &str) -> Result<()> {
    match args.plot_projection {
        Some(_) => Err(not_geographic(what)),
        None => Ok(()),
    }
}

fn not_geographic(what: &str) -> clipsat::Error {
    super::args::arg_error(
        "--plot-projection",
        format!(
            "the terrain is {what}: only a terrain in degrees (an SRTM .hgt named like N57E011, a \
             geographic GeoTIFF, grid or DTED cell, a mosaic of them) is drawn in an equirectangular \
             frame; nothing written"
        ),
    )
}

/// `clipsat info` on a package: its header, read without decoding, and how each shipped profile's
/// `budget.cpu_memory_bytes` splits into the rings, the cache's fixed parts and its tile slots.
fn package_info(pkg: &clipsat::package::Package, as_json: bool) -> Result<()> {
    let h = pkg.header();
    let bytes = pkg.file_bytes();
    #[expect(clippy::cast_precision_loss, reason = "a ratio for display")]
    let per_sample = bytes as f64 / h.samples() as f64;
    // The file's split: the height pyramid's tiles and the SAT LOD records' tiles.
    let (pyramid, lod) = (h.pyramid_bytes(), h.lod_bytes());
    #[expect(clippy::cast_precision_loss, reason = "ratios for display")]
    let (pyramid_ps, lod_ps) = (
        pyramid as f64 / h.samples() as f64,
        lod as f64 / h.samples() as f64,
    );
    let lod_levels = h.lod.as_ref().map_or(0, |l| l.levels.len());
    let mut profiles = Vec::new();
    for (pname, _) in SHIPPED {
        let p = Profile::load(pname)?;
        let cpu = p.cpu_split();
        let cache = clipsat::package::CacheSplit::plan(h, cpu.tile_cache);
        profiles.push(json!({
            "profile": pname,
            "cpu_budget_bytes": p.budget.cpu_memory_bytes,
            "rings_bytes": cpu.rings,
            "tile_cache": cache,
            "lod_tables_bytes": cpu.lod_tables,
            "shading_bytes": cpu.shading,
        }));
    }
    // A package set's composition, from its index.
    let set = clipsat::package::set::is_set(pkg.path())
        .then(|| clipsat::package::set::Index::read(&clipsat::package::set::index_path(pkg.path())))
        .transpose()?;
    let set_json = set.as_ref().map(|i| {
        json!({
            "parts": i.parts.len(),
            "columns": i.columns.len(),
            "rows": i.rows.len(),
            "part_levels": i.part_levels,
            "top": i.top,
        })
    });
    if as_json {
        super::print_json(&json!({
            "package": pkg.path().display().to_string(),
            "set": set_json,
            "width": h.width,
            "height": h.height,
            "spacing_m": h.spacing,
            "origin_m": [h.origin.0, h.origin.1],
            "quantum_m": h.quantum,
            "max_error_m": h.max_error,
            "codec": h.codec,
            "tile": h.tile,
            "levels": h.levels.len(),
            "tiles": h.tiles.len(),
            "bytes": bytes,
            "bytes_per_sample": per_sample,
            "pyramid_bytes": pyramid,
            "pyramid_bytes_per_sample": pyramid_ps,
            "lod_table_bytes": lod,
            "lod_table_bytes_per_sample": lod_ps,
            "lod_table_levels": lod_levels,
            "profiles": profiles,
        }));
        return Ok(());
    }
    outln!("package   {}", pkg.path().display());
    if let Some(i) = &set {
        outln!(
            "set       {} parts ({} x {} cells), each levels 0..={}; the top {} levels {}..={}; SAT LOD \
             tables built from the heights on first use",
            i.parts.len(),
            i.columns.len(),
            i.rows.len(),
            i.part_levels - 1,
            i.top,
            i.part_levels,
            h.levels.len() - 1
        );
    }
    outln!(
        "samples   {} x {} at {} m, {} levels, {} tiles of {}^2 ({})",
        h.width,
        h.height,
        h.spacing,
        h.levels.len(),
        h.tiles.len(),
        h.tile,
        h.codec.name()
    );
    outln!(
        "size      {bytes} bytes, {per_sample:.4} bytes/sample; quantum {} m (max error {} m)",
        h.quantum,
        h.max_error
    );
    outln!(
        "split     pyramid {pyramid} bytes ({pyramid_ps:.4} bytes/sample), SAT LOD tables {lod} bytes \
         ({lod_ps:.4} bytes/sample, data levels 1..={lod_levels})"
    );
    outln!(
        "profile     CPU budget = rings + cache (header + tile map + decoder + slots) + LOD table pages + SG inputs"
    );
    for p in &profiles {
        let mib = |v: &serde_json::Value| v.as_f64().unwrap_or(0.0) / 1048576.0;
        let c = &p["tile_cache"];
        outln!(
            "{:<11} {:>6.1} MiB = {:.2} + ({:.2} + {:.2} + {:.2} + {:.2} MiB: {} slots) + {:.2} + {:.2} MiB",
            p["profile"].as_str().unwrap_or("?"),
            mib(&p["cpu_budget_bytes"]),
            mib(&p["rings_bytes"]),
            mib(&c["header"]),
            mib(&c["map"]),
            mib(&c["decoder"]),
            mib(&c["slots"]),
            c["slot_count"],
            mib(&p["lod_tables_bytes"]),
            mib(&p["shading_bytes"])
        );
    }
    Ok(())
}

/// What `info` shows of a terrain: a loaded one's, or, for a tile mosaic that streams (every sample has
/// data or `--fill-height` gives one), what a pass over its rows finds, a band at a time, so that a
/// mosaic of any size is described in the memory of a few bands (loaded whole, a 2 x 2 mosaic of 1"
/// tiles holds 207 MB).
struct Summary {
    width: u32,
    height: u32,
    spacing: f32,
    ew_spacing: f32,
    range: (f32, f32),
    voids_filled: u64,
    geo: Option<clipsat::source::GeoExtent>,
}

impl Summary {
    fn of(targs: &super::TerrainArgs) -> Result<(String, Self)> {
        if let clipsat::source::TerrainSpec::File(path) = targs.spec()? {
            let opts = targs.load_options()?;
            if clipsat::source::is_mosaic(&path) && opts.fill_height.is_some() {
                let mut rows = clipsat::source::open_rows(&path, &opts)?;
                let g = rows.grid().clone();
                let w = g.width as usize;
                let band_rows = (4 << 20) / (4 * w).max(1) + 1;
                let mut band = vec![0.0f32; w * band_rows.min(g.height as usize)];
                let mut range = (f32::INFINITY, f32::NEG_INFINITY);
                let mut y = 0u32;
                while y < g.height {
                    let n = (g.height - y).min(u32::try_from(band_rows).unwrap_or(u32::MAX));
                    let part = &mut band[..w * n as usize];
                    rows.read_rows(y, part)?;
                    range = part
                        .iter()
                        .fold(range, |(lo, hi), &h| (lo.min(h), hi.max(h)));
                    y += n;
                }
                let summary = Self {
                    width: g.width,
                    height: g.height,
                    spacing: g.spacing,
                    ew_spacing: g.ew_spacing,
                    range,
                    voids_filled: 0,
                    geo: clipsat::source::mosaic_geo(&path, &opts)?,
                };
                return Ok((path.display().to_string(), summary));
            }
        }
        let (name, hm) = targs.load()?;
        let summary = Self {
            width: hm.width(),
            height: hm.height(),
            spacing: hm.spacing(),
            ew_spacing: hm.ew_spacing(),
            range: hm.range(),
            voids_filled: hm.voids_filled(),
            geo: hm.geo().copied(),
        };
        Ok((name, summary))
    }

    fn width(&self) -> u32 {
        self.width
    }

    fn height(&self) -> u32 {
        self.height
    }

    fn spacing(&self) -> f32 {
        self.spacing
    }

    fn ew_spacing(&self) -> f32 {
        self.ew_spacing
    }

    fn range(&self) -> (f32, f32) {
        self.range
    }

    fn voids_filled(&self) -> u64 {
        self.voids_filled
    }

    fn geo(&self) -> Option<&clipsat::source::GeoExtent> {
        self.geo.as_ref()
    }

    /// As [`clipsat::source::Heightmap::ew_stretch`].
    fn ew_stretch(&self) -> f64 {
        f64::from(self.spacing) / f64::from(self.ew_spacing)
    }

    /// As [`clipsat::source::Heightmap::extent_m`].
    fn extent_m(&self) -> (f64, f64) {
        (
            f64::from(self.width - 1) * f64::from(self.spacing),
            f64::from(self.height - 1) * f64::from(self.spacing),
        )
    }
}
