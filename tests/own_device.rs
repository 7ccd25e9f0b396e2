//! `examples/own_device.rs`: a streamed terrain with SAT LOD drawn into a caller's own wgpu device and
//! render pass, through a resize, with the public API only. Without the example's own draw, each frame's
//! image hash equals `clipsat render --gpu gl` of the same view at that size (with `CLIPSAT_GPU=vulkan`,
//! both on wgpu's Vulkan backend); with it, the orange triangle shows in the top-left corner and nothing
//! else changes.
//!
//! Its own test binary: the example's wgpu GL instance closes the process's EGL display when it drops,
//! which other GPU tests running beside it in one process would not survive.

use std::path::Path;
use std::process::Command;

use clipsat::hash::{hash_bytes, hex};

#[expect(
    dead_code,
    reason = "the example's main is not called here, only its render"
)]
#[path = "../examples/own_device.rs"]
mod own_device;

/// The sizes the example draws, the second after a "resize".
const SIZES: [(u32, u32); 2] = [(320, 180), (200, 200)];

#[test]
fn own_device_matches_clipsat_render_through_a_resize() {
    // Under `.ci/run`'s Vulkan passes (`WGPU_VALIDATION=1 WGPU_DEBUG=1`, `CLIPSAT_VALIDATION_LOG`) the
    // example's own instance asks for the validation layer, whose reports reach the run's file.
    clipsat::gpu::validation::install_from_env();
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("own_device_cache");
    let plain = own_device::render(&cache, &SIZES, false).expect("own device renders");
    // The same backend as the example's device: wgpu's GL, or (`CLIPSAT_GPU=vulkan`, which `--gpu auto`
    // reads) its Vulkan.
    let vulkan = std::env::var("CLIPSAT_GPU").is_ok_and(|v| v.trim() == "vulkan");
    let gpu = if vulkan { "auto" } else { "gl" };
    for (&(w, h), (fw, fh, rgba)) in SIZES.iter().zip(&plain) {
        assert_eq!((w, h), (*fw, *fh));
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("own_device_{w}x{h}.png"));
        let cli = Command::new(env!("CARGO_BIN_EXE_clipsat"))
            .env("CLIPSAT_CACHE", &cache)
            .args([
                "render",
                "--gpu",
                gpu,
                "--terrain",
                "procedural:size=257",
                "--profile",
                "gles3-low",
                "--lod",
                "sat-conservative",
                "--epsilon",
                "1",
                "--size",
                &format!("{w}x{h}"),
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
        let want = hex(hash_bytes(rgba));
        assert!(
            stdout.contains(&format!("image {want}")),
            "{w}x{h}: own device image {want}, clipsat render --gpu {gpu}: {stdout}"
        );
    }

    let own = own_device::render(&cache, &SIZES[..1], true).expect("own device renders");
    let ((w, h, own), (_, _, plain)) = (&own[0], &plain[0]);
    assert_ne!(own, plain, "the own draw is not visible");
    let pixel = |rgba: &[u8], x: u32, y: u32| {
        let i = ((y * w + x) * 4) as usize;
        [rgba[i], rgba[i + 1], rgba[i + 2]]
    };
    let [r, g, b] = pixel(own, 10, 10);
    assert!(
        r == 255 && (127..=128).contains(&g) && b == 0,
        "the triangle's colour: {:?}",
        pixel(own, 10, 10)
    );
    // Only the triangle's corner differs: x < 20 % of the width, y < 25 % of the height.
    let mut differing = 0;
    for y in 0..*h {
        for x in 0..*w {
            if pixel(own, x, y) != pixel(plain, x, y) {
                differing += 1;
                assert!(
                    x < w / 5 && y < h / 4,
                    "pixel ({x}, {y}) changed outside the triangle"
                );
            }
        }
    }
    assert!(differing > 100, "{differing} triangle pixels");
}

/// The smallest embedding names at most five clipsat types, all from the crate's root (the public API):
/// the example's one `use clipsat::{..}` line, and no other `clipsat::` path.
#[test]
fn own_device_example_uses_five_root_types() {
    let text = include_str!("../examples/own_device.rs");
    let code: Vec<&str> = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect();
    let uses: Vec<&&str> = code.iter().filter(|l| l.contains("clipsat::")).collect();
    assert_eq!(uses.len(), 1, "one use line: {uses:?}");
    let list = uses[0]
        .trim()
        .strip_prefix("use clipsat::{")
        .and_then(|l| l.strip_suffix("};"))
        .unwrap_or_else(|| panic!("a root import: {}", uses[0]));
    let types: Vec<&str> = list.split(',').map(str::trim).collect();
    assert!(types.len() <= 5, "{} clipsat types: {types:?}", types.len());
    assert!(
        types.iter().all(|t| !t.contains("::")),
        "root types only: {types:?}"
    );
}
