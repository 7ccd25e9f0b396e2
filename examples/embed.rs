//! Embedding clipsat headless, the whole pipeline in one page: load a terrain (the built-in procedural one,
//! or the file named on the command line), build a clipmap and an offscreen renderer from a profile, render
//! three frames along a short flight, and print each frame's clipmap hash, plan hash and image hash.
//!
//! The offscreen renderer plans each frame ([`clipsat::plan::frame_plan::Planner`] into a
//! [`clipsat::plan::frame_plan::FramePlan`], a value), prepares it on the GPU and reads the image back.
//! It reaches into the stages (`clipsat::gpu::headless`, `clipsat::plan`), which are the crate's internal
//! API: public only with the `internals` feature (examples and tests get it), not covered by semver. An
//! engine uses the root types instead: `examples/own_device.rs` draws a terrain into a wgpu device and
//! render pass of its own with them.
//!
//! ```sh
//! cargo run --release --example embed                      # procedural terrain
//! cargo run --release --example embed -- path/to/N57E011.hgt
//! ```

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::hash::hex;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::source::{self, procedural, LoadOptions};
use clipsat::Result;

/// The (clipmap frame hash, plan hash, image hash) of three frames 100 m apart along a figure-8 over
/// `terrain`, rendered with the `gles3-low` profile at 320 x 180 pixels.
pub(crate) fn three_frames(terrain: &Heightmap) -> Result<[(u64, u64, u64); 3]> {
    let mut profile = Profile::load("gles3-low")?;
    (profile.view.width, profile.view.height) = (320, 180);
    let gpu = Gpu::new(GpuMode::Auto)?;
    let mut clipmap = Clipmap::new(terrain, &profile, ClipmapOptions::default())?;
    // The LOD mode and shading are fixed here (the default: distance LOD, basic shading).
    let mut renderer = Offscreen::new(&gpu, &profile, &clipmap, OffscreenOptions::default())?;
    let flight = Flight::new(Path::Figure8, 100.0, terrain)?;
    let mut out = [(0, 0, 0); 3];
    for (f, slot) in (0u64..).zip(out.iter_mut()) {
        let camera = flight.camera(f);
        // The CPU clipmap update: which samples to update under the budget, and the frame record's hash.
        let frame_hash = clipmap.update(camera.eye)?.hash;
        // The frame plan (uploads, LOD, draws, uniforms), then the GPU: upload, draw, read the image back.
        let frame = render_frame(&mut renderer, &clipmap, &camera, &FrameOptions::default())?;
        *slot = (frame_hash, renderer.plan().hash(), frame.image_hash);
    }
    Ok(out)
}

fn main() -> std::process::ExitCode {
    let terrain = match std::env::args_os().nth(1) {
        Some(path) => source::load(std::path::Path::new(&path), &LoadOptions::default()),
        None => procedural::generate(&procedural::ProceduralParams::default()),
    };
    match terrain.and_then(|t| three_frames(&t)) {
        Ok(frames) => {
            for (f, (clip, plan, image)) in frames.iter().enumerate() {
                println!(
                    "frame {f}: clipmap {} plan {} image {}",
                    hex(*clip),
                    hex(*plan),
                    hex(*image)
                );
            }
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
