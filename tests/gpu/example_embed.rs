//! `examples/embed.rs` (the minimal embedding) builds, and its three frames hash the same on every run and
//! the same as the library's own render path over the same camera.

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::profile::Profile;
use clipsat::source::procedural::{generate, ProceduralParams};

#[expect(
    dead_code,
    reason = "the example's main is not called here, only its three_frames"
)]
#[path = "../../examples/embed.rs"]
mod embed;

#[test]
fn embed_example_hashes_are_deterministic_and_match_the_library() {
    let terrain = generate(&ProceduralParams {
        size: 257,
        ..ProceduralParams::default()
    })
    .expect("procedural terrain");
    let first = embed::three_frames(&terrain).expect("embed example renders");
    let second = embed::three_frames(&terrain).expect("embed example renders again");
    assert_eq!(first, second, "the example's hashes changed between runs");

    // The same three frames written out against the library directly: plan and image hashes agree.
    let mut profile = Profile::load("gles3-low").expect("shipped profile");
    (profile.view.width, profile.view.height) = (320, 180);
    let gpu = Gpu::new(GpuMode::Auto).expect("GPU");
    let mut clipmap = Clipmap::new(&terrain, &profile, ClipmapOptions::default()).expect("clipmap");
    let mut renderer =
        Offscreen::new(&gpu, &profile, &clipmap, OffscreenOptions::default()).expect("renderer");
    let flight = Flight::new(Path::Figure8, 100.0, &terrain).expect("flight");
    for (f, want) in (0u64..).zip(first) {
        let camera = flight.camera(f);
        let clip = clipmap.update(camera.eye).expect("update").hash;
        let image = render_frame(&mut renderer, &clipmap, &camera, &FrameOptions::default())
            .expect("render")
            .image_hash;
        let plan = renderer.plan().hash();
        assert_eq!(
            (clip, plan, image),
            want,
            "frame {f} differs from the example's"
        );
    }
    assert!(
        first.windows(2).all(|w| w[0] != w[1]),
        "three frames along a moving path should differ: {first:?}"
    );
}
