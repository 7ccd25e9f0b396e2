//! `examples/own_device.rs`: a streamed terrain with SAT LOD drawn into a caller's own wgpu device and
//! render pass, through a resize, with the public API only. Without the example's own draw, each frame's
//! image hash equals `clipsat render --gpu gl` of the same view at that size (with `CLIPSAT_GPU=vulkan`,
//! both on wgpu's Vulkan backend); with it, the orange triangle shows in the top-left corner and nothing
//! else changes. Also: `FrameOptions` switched between frames on one renderer (a SAT mode, a debug view,
//! culling off) and back draw the first frame's pixels again.
//!
//! Its own test binary: the example's wgpu GL instance closes the process's EGL display when it drops,
//! which other GPU tests running beside it in one process would not survive.

#![expect(
    clippy::duplicate_mod,
    reason = "both examples load their shared wgpu helpers (examples/support)"
)]

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
    let _one = ONE_INSTANCE.lock().unwrap_or_else(|e| e.into_inner());
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
    root_types(include_str!("../examples/own_device.rs"), 5);
}

/// The engine's example (its camera, reverse-Z, sRGB, a mesh of its own and a ray query) names at most
/// six.
#[test]
fn engine_example_uses_six_root_types() {
    root_types(include_str!("../examples/engine.rs"), 6);
}

/// `text`'s one `use clipsat::{..}` line names at most `most` root types, and no other `clipsat::` path.
fn root_types(text: &str, most: usize) {
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
    assert!(
        types.len() <= most,
        "{} clipsat types: {types:?}",
        types.len()
    );
    assert!(
        types.iter().all(|t| !t.contains("::")),
        "root types only: {types:?}"
    );
}

#[expect(
    dead_code,
    reason = "the example's main is not called here, only its render"
)]
#[path = "../examples/engine.rs"]
mod engine;

/// One wgpu GL instance at a time in this process (each closes the EGL display when it drops).
static ONE_INSTANCE: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Terrain pixels (neither frame is the sky) of two frames: the mean and largest difference of the
/// largest channel in levels of 255, the share of pixels past 2 levels, and the pixels compared.
fn difference(a: &[u8], b: &[u8], sky: [u8; 3]) -> (f64, u8, f64, usize) {
    let near_sky = |p: &[u8]| (0..3).all(|c| p[c].abs_diff(sky[c]) <= 1);
    let (mut sum, mut max, mut past, mut n) = (0u64, 0u8, 0usize, 0usize);
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        if near_sky(p) && near_sky(q) {
            continue;
        }
        let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        sum += u64::from(d);
        max = max.max(d);
        past += usize::from(d > 2);
        n += 1;
    }
    (
        sum as f64 / n.max(1) as f64,
        max,
        past as f64 / n.max(1) as f64,
        n,
    )
}

/// The engine's frame in each of the four combinations of depth (conventional, reverse-Z with an
/// infinite far plane) and colour target (linear, sRGB), and with the depth formats an engine's pass
/// uses, draws the same image as conventional depth into a linear target, within the frame twin's
/// tolerance (`twin::frame`: a mean of at most 1 level, at most 1 % of the pixels past 2).
#[test]
fn depth_conventions_and_colour_targets_draw_the_same_image() {
    let _one = ONE_INSTANCE.lock().unwrap_or_else(|e| e.into_inner());
    clipsat::gpu::validation::install_from_env();
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("own_device_cache");
    let size = (240, 135);
    let base = engine::Setup {
        reverse_z: false,
        srgb: false,
        depth: wgpu::TextureFormat::Depth32Float,
        marker: false,
    };
    let engine::Frame {
        pixels: (_, _, want),
        camera,
        ..
    } = engine::render(&cache, size, base).expect("engine frame");
    let sky = [161, 194, 230];
    let mut setups = Vec::new();
    // Every combination but the base's own (drawn above).
    for (reverse_z, srgb) in [(false, true), (true, false), (true, true)] {
        setups.push(engine::Setup {
            reverse_z,
            srgb,
            ..base
        });
    }
    for depth in [
        wgpu::TextureFormat::Depth24Plus,
        wgpu::TextureFormat::Depth24PlusStencil8,
    ] {
        setups.push(engine::Setup {
            depth,
            reverse_z: true,
            srgb: true,
            ..base
        });
    }
    let mut report = Vec::new();
    for setup in setups {
        let engine::Frame {
            pixels: (_, _, got),
            camera: c,
            ..
        } = engine::render(&cache, size, setup).expect("engine frame");
        assert_eq!(
            c.eye(),
            camera.eye(),
            "{setup:?}: the same eye from the matrices"
        );
        let (mean, max, past, n) = difference(&want, &got, sky);
        report.push(format!(
            "{setup:?}: mean {mean:.3}, max {max}, past 2: {past:.4} of {n}"
        ));
        assert!(n > 10_000, "{setup:?}: {n} terrain pixels");
        assert!(
            mean <= 1.0 && past <= 0.01,
            "{setup:?} against conventional depth into a linear target: mean {mean:.3} levels, \
             max {max}, {:.2} % past 2 levels",
            past * 100.0
        );
    }
    println!("{}", report.join("\n"));
}

/// The entry distance of the ray `o + t d` into the octahedron |p - c|_1 <= r (the marker; it is the same
/// set in the terrain's frame as in the engine's y-up world, the rotation between them taking axes to
/// axes): the slab method over its eight faces.
fn octahedron_entry(o: glam::DVec3, d: glam::DVec3, c: glam::DVec3, r: f64) -> Option<f64> {
    let (mut enter, mut exit) = (0.0f64, f64::INFINITY);
    for f in 0..8 {
        let sign = |bit: u32| if f & bit == 0 { 1.0 } else { -1.0 };
        let n = glam::DVec3::new(sign(1), sign(2), sign(4));
        // n . (o + t d - c) <= r
        let (a, b) = (n.dot(d), r - n.dot(o - c));
        if a.abs() < 1e-15 {
            if b < 0.0 {
                return None;
            }
        } else if a > 0.0 {
            exit = exit.min(b / a);
        } else {
            enter = enter.max(b / a);
        }
    }
    (enter <= exit).then_some(enter)
}

/// The example's marker, drawn by the engine in the same pass with shared reverse-Z depth into an sRGB
/// target, shows exactly where the CPU's ray test says the terrain does not hide it: for each pixel, the
/// ray through its centre meets the marker (an octahedron, exactly) before or after the terrain
/// (`TerrainRenderer::raycast`, the data's bilinear surface). Pixels within one pixel of a change of
/// that classification (the marker's silhouette and the terrain's line across it) are left out: there
/// the drawn surface, within SAT LOD's 1 px bound of the data, may fall either side.
#[test]
fn the_marker_is_hidden_exactly_where_the_terrain_is_in_front() {
    let _one = ONE_INSTANCE.lock().unwrap_or_else(|e| e.into_inner());
    clipsat::gpu::validation::install_from_env();
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("own_device_cache");
    let size = (480, 270);
    let setup = engine::Setup {
        reverse_z: true,
        srgb: true,
        depth: wgpu::TextureFormat::Depth32Float,
        marker: true,
    };
    let mut frame = engine::render(&cache, size, setup).expect("engine frame");
    let centre = glam::DVec3::from(frame.marker.expect("the centre ray meets the terrain"));
    let m = glam::DMat4::from_cols_array_2d(&frame.camera.projection_matrix(size))
        * glam::DMat4::from_cols_array_2d(&frame.camera.view_matrix());
    let inv = m.inverse();
    let eye = glam::DVec3::from(frame.camera.eye());
    let (w, h) = size;
    // 0: the ray misses the marker; 1: it meets the marker first; 2: the terrain first.
    let mut class = vec![0u8; (w * h) as usize];
    for py in 0..h {
        for px in 0..w {
            let x = 2.0 * (f64::from(px) + 0.5) / f64::from(w) - 1.0;
            let y = 1.0 - 2.0 * (f64::from(py) + 0.5) / f64::from(h);
            let p = inv.project_point3(glam::DVec3::new(x, y, 0.5));
            let d = (p - eye).normalize();
            let Some(t) = octahedron_entry(eye, d, centre, engine::MARKER_M) else {
                continue;
            };
            let hidden = frame
                .renderer
                .raycast(eye.to_array(), d.to_array(), t)
                .expect("raycast")
                .is_some();
            class[(py * w + px) as usize] = if hidden { 2 } else { 1 };
        }
    }
    let (_, _, rgba) = &frame.pixels;
    // The marker's colour (1, 0.5, 0) as an sRGB target stores it.
    let orange = |i: usize| {
        let p = &rgba[i * 4..i * 4 + 3];
        p[0] >= 253 && p[1].abs_diff(188) <= 2 && p[2] <= 2
    };
    let (mut checked, mut shown, mut hidden, mut wrong) = (0, 0, 0, Vec::new());
    for py in 1..h - 1 {
        for px in 1..w - 1 {
            let i = (py * w + px) as usize;
            let c = class[i];
            let uniform = (-1i32..=1).all(|dy| {
                (-1i32..=1).all(|dx| {
                    let j = ((py as i32 + dy) * w as i32 + px as i32 + dx) as usize;
                    class[j] == c
                })
            });
            if c == 0 || !uniform {
                continue;
            }
            checked += 1;
            match (c, orange(i)) {
                (1, true) => shown += 1,
                (2, false) => hidden += 1,
                _ => wrong.push((px, py, c)),
            }
        }
    }
    println!(
        "marker pixels checked {checked}: shown {shown}, hidden {hidden}, wrong {}",
        wrong.len()
    );
    assert!(
        shown > 50 && hidden > 50,
        "shown {shown}, hidden {hidden}: the view no longer tests both"
    );
    for &(px, py, _) in &wrong {
        for dy in -3i32..=3 {
            let row: String = (-3i32..=3)
                .map(|dx| {
                    let j = ((py as i32 + dy) * w as i32 + px as i32 + dx) as usize;
                    let o = if orange(j) { "o" } else { "." };
                    format!("{}{o} ", class[j])
                })
                .collect();
            println!("{row}");
        }
    }
    assert!(
        wrong.is_empty(),
        "{} pixels differ from the ray test: {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(20)]
    );
}

/// The per-frame options through the public API, on one renderer: a SAT mode and a debug view change
/// the frame, culling off draws more, switching back draws the first frame's pixels again, and a switch
/// the renderer cannot make is refused with nothing changed.
#[test]
fn frame_options_switch_between_frames_and_back() {
    use clipsat::{DebugView, Error, FrameStats, LodMode, RenderOptions, Terrain, TerrainRenderer};
    let _one = ONE_INSTANCE.lock().unwrap_or_else(|e| e.into_inner());
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("own_device_cache");
    let (device, queue) = own_device::own_device().expect("own device");
    let profile = clipsat::Profile::load("gles3-low").expect("shipped profile");
    let terrain = Terrain::procedural(1, 257, 30.0, Some(&cache)).expect("terrain");
    let camera = terrain.default_camera().expect("camera");
    let options = RenderOptions::default();
    let mut r =
        TerrainRenderer::new(&device, &queue, terrain, &profile, &options).expect("renderer");
    let (w, h) = (160, 120);
    let color = own_device::target(&device, options.color_format, w, h, true);
    let depth = own_device::target(&device, options.depth_format, w, h, false);
    let frame = |r: &mut TerrainRenderer| -> (FrameStats, Vec<u8>) {
        r.warm_up(&queue, &camera, (w, h)).expect("warm-up");
        let stats = r.prepare(&queue, &camera, (w, h)).expect("prepare");
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = own_device::begin_pass(&mut encoder, &color, &depth);
            r.render(&mut pass);
        }
        queue.submit([encoder.finish()]);
        let image = own_device::read_back(&device, &queue, &color).expect("read-back");
        (stats, image)
    };
    let first = r.frame_options();
    assert_eq!(
        (first.lod, first.debug, first.sg, first.morph, first.cull),
        (LodMode::Distance, DebugView::Normal, false, true, true)
    );
    assert_eq!(r.sat_lod_px(), None);
    let (base, base_image) = frame(&mut r);

    let mut o = first;
    o.lod = LodMode::SatConservative;
    r.set_frame_options(&queue, o).expect("a SAT mode");
    assert!(r.sat_lod_px().is_some(), "the profile's bound");
    r.set_sat_lod_px(4.0).expect("a bound");
    let (sat, sat_image) = frame(&mut r);
    assert_ne!(sat.triangles, base.triangles, "SAT LOD drew the rings");
    assert_ne!(sat_image, base_image);

    o.lod = LodMode::Distance;
    o.debug = DebugView::Levels;
    r.set_frame_options(&queue, o).expect("the level view");
    assert!(r.set_sat_lod_px(1.0).is_err(), "distance LOD has no bound");
    let (levels, levels_image) = frame(&mut r);
    assert_eq!(levels.triangles, base.triangles);
    assert_ne!(levels_image, base_image, "the level view drew the shading");

    o.debug = DebugView::Normal;
    o.cull = false;
    r.set_frame_options(&queue, o).expect("culling off");
    let (unculled, _) = frame(&mut r);
    assert!(unculled.triangles > base.triangles, "culling off culled");

    o.cull = true;
    r.set_frame_options(&queue, o)
        .expect("back to the first options");
    assert_eq!(r.frame_options(), first);
    let (again, again_image) = frame(&mut r);
    assert_eq!(again.triangles, base.triangles);
    assert!(
        again_image == base_image,
        "back to the first options: another image"
    );

    // SG on a renderer built without a scene: refused, nothing changed.
    let mut sg = first;
    sg.sg = true;
    assert!(matches!(
        r.set_frame_options(&queue, sg),
        Err(Error::Invalid { .. })
    ));
    assert_eq!(r.frame_options(), first);
}
