//! `clipsat bench`: the measurement subcommands. `lod.rs` measures the LOD stage, `shading.rs` the SG
//! shading, `imagery.rs` draped imagery's cost through the public renderer, `memory.rs` the terrain package and resident set, `budget.rs` the update budget against
//! speed, `plan.rs` the plan's time per frame (also `fly`'s), `all.rs` runs them and the GPU memory
//! measurement into one report; `common.rs` holds what they share. Dependencies go one way: `all` uses
//! the others, never the reverse.

mod all;
mod budget;
mod common;
mod imagery;
mod lod;
mod memory;
pub(crate) mod plan;
mod shading;

use clap::{Args, Subcommand};
use clipsat::Result;

use lod::BenchLodArgs;
use shading::BenchShadingArgs;

#[derive(Args, Debug)]
pub(crate) struct BenchArgs {
    #[command(subcommand)]
    what: BenchWhat,
}

#[derive(Subcommand, Debug)]
enum BenchWhat {
    /// SAT LOD against distance LOD: triangles, LOD time, render time, measured screen error and image
    /// RMSE against the brute-force render, for epsilon 0.5 .. 8 px and every estimator.
    Lod(BenchLodArgs),
    /// Every benchmark on the procedural terrain and each shared terrain present: LOD, shading, update
    /// budget against speed and memory per profile, as DIR/report.md with PNG plots beside it.
    All(all::BenchAllArgs),
    /// SG shading: patches {2x4, 4x8, 8x16} x effects {diffuse, +visibility, +specular}: ms per frame
    /// against basic shading, RMSE and max error against the CPU reference.
    Shading(BenchShadingArgs),
    /// Draped imagery's cost: basic shading and SG, each without and with the terrain's `--imagery`,
    /// drawn through `TerrainRenderer`: ms per frame and the ratios, measured in the same run.
    Imagery(imagery::BenchImageryArgs),
}

pub(crate) fn run(args: &BenchArgs) -> Result<()> {
    match &args.what {
        BenchWhat::Lod(a) => lod::run_lod(a),
        BenchWhat::All(a) => all::run(a),
        BenchWhat::Imagery(a) => imagery::run(a),
        BenchWhat::Shading(a) => {
            let report = shading::run_shading(a)?;
            if a.json {
                crate::app::cmd::print_json(&shading::shading_json(&report));
                return Ok(());
            }
            outln!("{}", report.markdown);
            outln!(
                "{} configurations measured, {} terrains skipped; wrote {}",
                report.rows.len(),
                report.skipped.len(),
                a.out.join("shading.md").display()
            );
            Ok(())
        }
    }
}
