//! `clipsat render`: one frame, offscreen, to a PNG.

use clap::Args;
use clipsat::{Error, Result};

use super::{ProfileArgs, TerrainArgs};

#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output PNG.
    #[arg(long, value_name = "FILE.png", default_value = "out/frame.png")]
    out: std::path::PathBuf,
    /// Print a machine-readable summary on stdout.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: &RenderArgs) -> Result<()> {
    let _ = (&args.terrain, &args.profile, &args.out, args.json);
    Err(Error::Gpu("render is not written yet".into()))
}
