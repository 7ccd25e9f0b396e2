//! `examples/own_device.rs`: the terrain drawn into a caller's own wgpu device and render pass. Without
//! the example's own draw, its image hash equals `clipsat render --gpu gl` of the same view; with it, the
//! orange triangle shows in the top-left corner and nothing else changes.
//!
//! Its own test binary: the example's wgpu GL instance closes the process's EGL display when it drops,
//! which other GPU tests running beside it in one process would not survive.

use std::process::Command;

use clipsat::source::procedural::{generate, ProceduralParams};

#[expect(
    dead_code,
    reason = "the example's main is not called here, only its render"
)]
#[path = "../examples/own_device.rs"]
mod own_device;

#[test]
fn own_device_matches_clipsat_render_gl() {
    let terrain = generate(&ProceduralParams {
        size: 257,
        ..ProceduralParams::default()
    })
    .expect("procedural terrain");
    let plain = own_device::render(&terrain, 320, 180, false).expect("own device renders");
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("own_device_cli.png");
    let cli = Command::new(env!("CARGO_BIN_EXE_clipsat"))
        .args([
            "render",
            "--gpu",
            "gl",
            // The example draws the terrain loaded whole, as --resident does (render streams by default).
            "--resident",
            "--terrain",
            "procedural:size=257",
            "--profile",
            "gles3-low",
            "--size",
            "320x180",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("clipsat runs");
    assert!(
        cli.status.success(),
        "clipsat render: {}",
        String::from_utf8_lossy(&cli.stderr)
    );
    let stdout = String::from_utf8_lossy(&cli.stdout);
    let want = clipsat::hash::hex(plain.hash());
    assert!(
        stdout.contains(&format!("image {want}")),
        "own device image {want}, clipsat render --gpu gl: {stdout}"
    );

    let own = own_device::render(&terrain, 320, 180, true).expect("own device renders");
    assert_ne!(own.hash(), plain.hash(), "the own draw is not visible");
    let [r, g, b, _] = own.pixel(10, 10);
    assert!(
        r == 255 && (127..=128).contains(&g) && b == 0,
        "the triangle's colour: {:?}",
        own.pixel(10, 10)
    );
    // Only the triangle's corner differs: x < 20 % of the width, y < 25 % of the height.
    let mut differing = 0;
    for y in 0..own.height {
        for x in 0..own.width {
            if own.pixel(x, y) != plain.pixel(x, y) {
                differing += 1;
                assert!(
                    x < own.width / 5 && y < own.height / 4,
                    "pixel ({x}, {y}) changed outside the triangle"
                );
            }
        }
    }
    assert!(differing > 100, "{differing} triangle pixels");
}
