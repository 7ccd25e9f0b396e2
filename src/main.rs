//! The `clipsat` command line. Each subcommand lives in `src/app/cmd/`; the library does the work.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod app;

use app::cmd;

/// Fixed-budget terrain rendering for OpenGL ES 3.0 class GPUs.
#[derive(Parser)]
#[command(name = "clipsat", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a terrain into a package: the compressed, tiled residual pyramid streamed at runtime.
    Bake(cmd::bake::BakeArgs),
    /// Benchmarks: `bench lod` compares the LOD estimators across error bounds on the shared terrains; `bench
    /// all` writes one report of every measurement. They load the whole terrain (they measure against every
    /// sample); only the memory section's `render` runs stream.
    Bench(cmd::bench::BenchArgs),
    /// Fly a camera path on the CPU: per-frame clipmap updates under the budget, statistics and hashes.
    /// Streams the terrain (a plain source baked into the cache on first use); --resident loads it whole.
    Fly(cmd::fly::FlyArgs),
    /// Describe a terrain: size, spacing, height range, voids, and the GPU memory each shipped profile needs.
    Info(cmd::info::InfoArgs),
    /// Render one frame offscreen to a PNG. Streams the terrain (a plain source baked into the cache on
    /// first use); --resident loads it whole.
    Render(cmd::render::RenderArgs),
    /// Check this machine's GPU draws clipsat correctly (adapter, frames against the CPU twin, border,
    /// read-back); exits 1 when a check fails.
    Selftest(cmd::selftest::SelftestArgs),
    /// Tune the SAT LOD exponent p: estimate and bound errors against the exact block maximum, per p.
    /// Loads the whole terrain (it measures against every sample).
    TuneP(cmd::tune_p::TunePArgs),
    /// Fly interactively in a window: WASD and mouse-look, keys for the LOD mode, epsilon and debug views.
    #[cfg(feature = "view")]
    View(cmd::view::ViewArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Bake(args) => cmd::bake::run(&args),
        Command::Bench(args) => cmd::bench::run(&args),
        Command::Fly(args) => cmd::fly::run(&args),
        Command::Info(args) => cmd::info::run(&args),
        Command::Render(args) => cmd::render::run(&args),
        Command::Selftest(args) => cmd::selftest::run(&args),
        Command::TuneP(args) => cmd::tune_p::run(&args),
        #[cfg(feature = "view")]
        Command::View(args) => cmd::view::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let top = cmd::args::cli_message(&e);
            eprintln!("error: {top}");
            let mut source = std::error::Error::source(&e);
            while let Some(s) = source {
                // Most variants already quote their cause in their message; print only what is new.
                let text = s.to_string();
                if !top.contains(&text) {
                    eprintln!("  caused by: {text}");
                }
                source = s.source();
            }
            ExitCode::from(2)
        }
    }
}
