//! `clipsat info`: what a terrain is, and what each shipped profile would need to render it.

use clap::Args;
use clipsat::profile::SHIPPED;
use clipsat::{Profile, Result};
use serde_json::json;

use super::TerrainArgs;

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
}

pub(crate) fn run(args: &InfoArgs) -> Result<()> {
    let mut targs = args.terrain.clone();
    if let Some(t) = &args.terrain_pos {
        targs.terrain = Some(t.clone());
    }
    let (name, hm) = targs.load()?;
    let (lo, hi) = hm.range();
    let (ex, ey) = hm.extent_m();
    let mut profiles = Vec::new();
    for (pname, _) in SHIPPED {
        let p = Profile::load(pname)?;
        let f = p.footprint();
        // Finest ring spacing that still shows the whole terrain in the coarsest ring.
        let coarsest_span_m = f64::from(p.clipmap.n - 1)
            * f64::from(hm.spacing())
            * f64::from(1u32 << (p.clipmap.levels - 1));
        profiles.push(json!({
            "profile": pname,
            "gpu_bytes": f.total(),
            "gpu_budget_bytes": p.budget.gpu_memory_bytes,
            "parts": f,
            "coarsest_ring_span_m": coarsest_span_m,
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
            "profiles": profiles,
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
    outln!("heights   {lo:.1} .. {hi:.1} m");
    outln!("voids     {} filled", hm.voids_filled());
    outln!("profile     GPU memory needed / budget    coarsest ring span");
    for p in &profiles {
        outln!(
            "{:<11} {:>9.2} MiB / {:>7.1} MiB    {:>8.1} km",
            p["profile"].as_str().unwrap_or("?"),
            p["gpu_bytes"].as_f64().unwrap_or(0.0) / 1048576.0,
            p["gpu_budget_bytes"].as_f64().unwrap_or(0.0) / 1048576.0,
            p["coarsest_ring_span_m"].as_f64().unwrap_or(0.0) / 1e3,
        );
    }
    Ok(())
}
