//! Embedding clipsat, the whole pipeline in one page: load a terrain (the built-in procedural one, or the
//! file named on the command line), build a clipmap and a renderer from a profile, render three frames along
//! a short flight, and print each frame's plan hash and image hash.
//!
//! ```sh
//! cargo run --release --example embed                      # procedural terrain
//! cargo run --release --example embed -- ../shared/data/N57E011.hgt
//! ```

use clipsat::gpu::renderer::{render_frame, FrameOptions, Renderer};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::hash::hex;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::source::{self, procedural, LoadOptions};
use clipsat::{Heightmap, Profile, Result};

/// The (frame hash, image hash) of three frames 100 m apart along a figure-8 over `terrain`, rendered with
/// the `gles3-low` profile at 320 x 180 pixels.
pub(crate) fn three_frames(terrain: &Heightmap) -> Result<[(u64, u64); 3]> {
    let mut profile = Profile::load("gles3-low")?;
    (profile.view.width, profile.view.height) = (320, 180);
    let gpu = Gpu::new(GpuMode::Auto)?;
    let mut clipmap = Clipmap::new(terrain, &profile, ClipmapOptions::default())?;
    let mut renderer = Renderer::new(&gpu, &profile, &clipmap)?;
    let flight = Flight::new(Path::Figure8, 100.0, terrain)?;
    let mut out = [(0, 0); 3];
    for (f, slot) in (0u64..).zip(out.iter_mut()) {
        let camera = flight.camera(f);
        // The CPU plan: which samples to update under the budget, and the frame record's hash.
        let frame_hash = clipmap.update(camera.eye)?.hash;
        // The GPU: upload the plan's rectangles, draw, read the image back.
        let frame = render_frame(&mut renderer, &clipmap, &camera, &FrameOptions::default())?;
        *slot = (frame_hash, frame.image_hash);
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
            for (f, (plan, image)) in frames.iter().enumerate() {
                println!("frame {f}: plan {} image {}", hex(*plan), hex(*image));
            }
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
