//! A lost device, through the public API on a caller's own device: a 30-frame flight over the streamed
//! procedural terrain loses its device at frame 10 (`wgpu::Device::destroy`, reported to the caller's
//! device-lost callback), and the same `TerrainRenderer` is rebuilt on a new device and flies on. Every
//! frame after the loss has the same plan hash and the same image bytes as an uninterrupted flight, for
//! distance LOD with basic shading, for SAT LOD with SG shading, and with draped imagery whose rings are
//! still filling when the device is lost; the rebuild bakes nothing (the cache folder is unchanged) and
//! decodes no package tile (the tile cache's counters are unchanged by it, and equal the uninterrupted
//! flight's at the end; the imagery's rings are decoded again from its package, outside its tile cache).
//! With draped imagery, a warm-up after the rebuild also draws the frame drawn before the loss.
//!
//! Also: a GPU error of clipsat's work comes back as `Error::Gpu` through its error scopes, and a frame
//! on a lost device is no error and no panic. `rebuild_cost_against_new` (ignored, a measurement) times
//! the rebuild against `TerrainRenderer::new` with the package and tables in the cache folder:
//! `cargo test --test lost_device cost -- --ignored --nocapture` (with `MESA_SHADER_CACHE_DISABLE=true`
//! for cold shader compilation on Mesa).
//!
//! Its own test binary: it makes and drops its own wgpu devices (see tests/own_device.rs).

#![expect(
    clippy::duplicate_mod,
    reason = "the example and this test both load the examples' shared wgpu helpers (examples/support)"
)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use clipsat::gpu::renderer::ObjectKind;
use clipsat::{Camera, Profile, RenderOptions, Terrain, TerrainRenderer};

#[expect(
    dead_code,
    reason = "only the example's targets, pass and read-back are used here"
)]
#[path = "../examples/own_device.rs"]
mod own_device;

#[expect(dead_code, reason = "only the adapter and its devices are used here")]
#[path = "../examples/support/mod.rs"]
mod support;

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const SIZE: (u32, u32) = (160, 120);
const FRAMES: u64 = 30;
const LOST_AT: u64 = 10;

/// The wgpu instance and adapter kept for the test's devices: the GL backend on the GLES 3.0 limits (or
/// Vulkan with `CLIPSAT_GPU=vulkan`), as `examples/own_device.rs` makes them. Both devices of a flight
/// come from one adapter (a wgpu GL instance dropped beside a live one would close its EGL display).
struct Adapter {
    _instance: wgpu::Instance,
    adapter: wgpu::Adapter,
}

impl Adapter {
    fn new() -> Self {
        let (instance, adapter) = support::own_adapter().expect("an adapter");
        Self {
            _instance: instance,
            adapter,
        }
    }

    /// A new device and its queue.
    fn device(&self) -> (wgpu::Device, wgpu::Queue) {
        support::device_on(&self.adapter).expect("a device")
    }
}

/// Records `renderer`'s prepared frame into a pass of new targets on `device` and submits it.
fn draw(renderer: &TerrainRenderer, device: &wgpu::Device, queue: &wgpu::Queue) -> wgpu::Texture {
    let color = own_device::target(device, COLOR, SIZE.0, SIZE.1, true);
    let depth = own_device::target(
        device,
        wgpu::TextureFormat::Depth32Float,
        SIZE.0,
        SIZE.1,
        false,
    );
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = own_device::begin_pass(&mut encoder, &color, &depth);
        renderer.render(&mut pass);
    }
    queue.submit([encoder.finish()]);
    color
}

/// One flight's choices.
struct Case {
    name: &'static str,
    /// A shipped profile, or `gles3-low+sg`: gles3-low allowing SG shading.
    profile: &'static str,
    sat_lod_px: Option<f32>,
    sg_scene: Option<&'static str>,
    /// Drape an image (a gradient and a checkerboard) on the terrain.
    imagery: bool,
}

/// What a flight gave: per frame its plan hash and image bytes, the tile cache's counters at the end,
/// and (interrupted) the first prepare after the rebuild: the rings, pool tiles and SG tables re-sent in
/// full.
struct Flown {
    frames: Vec<(u64, Vec<u8>)>,
    decoded: u64,
    resend: Option<Duration>,
}

/// The camera of frame `f`: the terrain's default camera moved 45 m a frame along x and 20 along y.
fn camera(start: &Camera, f: u64) -> Camera {
    let step = [45.0 * f as f64, 20.0 * f as f64, 0.0];
    let [ex, ey, ez] = start.eye();
    let [tx, ty, tz] = start.target();
    Camera::look_at(
        [ex + step[0], ey + step[1], ez],
        [tx + step[0], ty + step[1], tz],
        60.0,
    )
    .expect("camera")
}

/// A shipped profile, or `gles3-low+sg`: gles3-low with the feature `sg` (a small SG flight).
fn profile(name: &str) -> Profile {
    match name {
        "gles3-low+sg" => {
            let text = include_str!("../profiles/gles3-low.toml");
            let allowed = r#"features = ["basic", "fog", "imagery"]"#;
            assert!(text.contains(allowed), "gles3-low's features changed");
            let text = text.replace(allowed, r#"features = ["basic", "sg", "fog", "imagery"]"#);
            Profile::from_toml(name, &text).expect("gles3-low with SG")
        }
        _ => Profile::load(name).expect("profile"),
    }
}

/// Every file of `dir` (recursively) with its size and modification time.
fn listing(dir: &Path) -> Vec<(PathBuf, u64, std::time::SystemTime)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("cache folder") {
            let e = e.expect("entry");
            let meta = e.metadata().expect("metadata");
            if meta.is_dir() {
                stack.push(e.path());
            } else {
                out.push((e.path(), meta.len(), meta.modified().expect("mtime")));
            }
        }
    }
    out.sort();
    out
}

/// Flies `case` for [`FRAMES`] frames; with `lose`, destroys the device after frame `LOST_AT - 1` and
/// rebuilds the renderer on a new one.
fn fly(adapter: &Adapter, cache: &Path, case: &Case, lose: bool) -> Flown {
    let (mut device, mut queue) = adapter.device();
    let lost = Arc::new(AtomicU32::new(u32::MAX));
    let flag = Arc::clone(&lost);
    // The engine's callback: clipsat sets none.
    device.set_device_lost_callback(move |reason, _| {
        flag.store(reason as u32, Ordering::SeqCst);
    });
    let profile = profile(case.profile);
    let mut terrain = Terrain::procedural(1, 257, 30.0, Some(cache)).expect("terrain");
    let start = terrain.default_camera().expect("camera");
    if case.imagery {
        terrain = Terrain::open_with(
            package_in(cache),
            &clipsat::TerrainOptions::default()
                .cache_dir(cache)
                .imagery(imagery_png(cache)),
        )
        .expect("terrain with imagery");
    }
    let mut options = RenderOptions::default().color_format(COLOR);
    options.sat_lod_px = case.sat_lod_px;
    options.sg_scene = case.sg_scene;
    let mut renderer =
        TerrainRenderer::new(&device, &queue, terrain, &profile, &options).expect("renderer");
    let mut frames = Vec::new();
    let mut resend = None;
    for f in 0..FRAMES {
        let mut prepare_after = None;
        if lose && f == LOST_AT {
            device.destroy();
            let _ = device.poll(wgpu::PollType::Poll);
            assert_eq!(
                lost.load(Ordering::SeqCst),
                wgpu::DeviceLostReason::Destroyed as u32,
                "{}: the device-lost callback",
                case.name
            );
            // A new device, and the renderer's GPU side rebuilt on it.
            (device, queue) = adapter.device();
            let folder = listing(cache);
            let before = renderer.tile_cache_stats().expect("a streamed terrain");
            renderer.rebuild(&device, &queue).expect("rebuild");
            assert_eq!(listing(cache), folder, "{}: the rebuild baked", case.name);
            let after = renderer.tile_cache_stats().expect("a streamed terrain");
            assert_eq!(
                (after.decoded, after.hits),
                (before.decoded, before.hits),
                "{}: the rebuild read the package",
                case.name
            );
            prepare_after = Some(Instant::now());
        }
        let stats = renderer
            .prepare(&queue, &camera(&start, f), SIZE)
            .expect("prepare");
        if let Some(t) = prepare_after {
            resend = Some(t.elapsed());
        }
        let color = draw(&renderer, &device, &queue);
        let rgba = own_device::read_back(&device, &queue, &color).expect("read-back");
        frames.push((stats.plan_hash, rgba));
    }
    let decoded = renderer.tile_cache_stats().expect("streamed").decoded;
    Flown {
        frames,
        decoded,
        resend,
    }
}

/// The procedural terrain's package in the cache folder (baked by its first open).
fn package_in(cache: &Path) -> PathBuf {
    std::fs::read_dir(cache)
        .expect("cache folder")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "clipsat"))
        .expect("the package in the cache folder")
}

/// A 256 x 256 gradient and checkerboard to drape, written beside the cache folder.
fn imagery_png(cache: &Path) -> PathBuf {
    let path = cache.with_extension("imagery.png");
    if path.exists() {
        return path;
    }
    image::RgbImage::from_fn(256, 256, |x, y| {
        image::Rgb([
            u8::try_from(x).expect("a byte"),
            u8::try_from(y).expect("a byte"),
            if (x / 32 + y / 32) % 2 == 0 { 255 } else { 0 },
        ])
    })
    .save(&path)
    .expect("imagery.png");
    path
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

#[test]
fn a_lost_device_is_rebuilt_and_the_flight_goes_on_unchanged() {
    let adapter = Adapter::new();
    let cases = [
        Case {
            name: "distance LOD, basic shading",
            profile: "gles3-low",
            sat_lod_px: None,
            sg_scene: None,
            imagery: false,
        },
        Case {
            name: "SAT LOD 1 px, SG shading (noon)",
            profile: "gles3-low+sg",
            sat_lod_px: Some(1.0),
            sg_scene: Some("noon"),
            imagery: false,
        },
        // The loss at frame 10 falls while the colour rings are still filling from cold.
        Case {
            name: "distance LOD, basic shading, draped imagery",
            profile: "gles3-low",
            sat_lod_px: None,
            sg_scene: None,
            imagery: true,
        },
    ];
    for case in &cases {
        let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lost_device_cache");
        // The uninterrupted flight first: it bakes the package and tables on first use, so `new` of the
        // interrupted one finds them in the cache folder.
        let whole = fly(&adapter, &cache, case, false);
        let lost = fly(&adapter, &cache, case, true);
        for (f, (a, b)) in whole.frames.iter().zip(&lost.frames).enumerate() {
            assert_eq!(a.0, b.0, "{}: frame {f}'s plan hash", case.name);
            assert!(a.1 == b.1, "{}: frame {f}'s image differs", case.name);
        }
        assert!(
            whole.frames.windows(2).any(|w| w[0].1 != w[1].1),
            "{}: the flight's frames should change",
            case.name
        );
        assert_eq!(
            lost.decoded, whole.decoded,
            "{}: package tiles decoded over the flight",
            case.name
        );
        println!(
            "{}: the first prepare after the rebuild (everything re-sent) took {:.1} ms; package tiles \
             decoded over each flight: {} (0 by the rebuild)",
            case.name,
            ms(lost.resend.expect("rebuilt")),
            lost.decoded,
        );
    }
}

#[test]
fn a_gpu_error_is_returned_and_a_lost_device_is_no_panic() {
    let adapter = Adapter::new();
    let (device, queue) = adapter.device();
    // The engine's handler: clipsat's error scopes take the errors of its own work before it sees them.
    device.on_uncaptured_error(Arc::new(|e| panic!("uncaptured: {e}")));
    let caught = clipsat::gpu::scope::scoped(&device, "a misaligned buffer", || {
        let _ = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: 3,
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
        Ok(())
    });
    assert!(
        matches!(
            &caught,
            Err(clipsat::Error::Gpu {
                source: Some(_),
                ..
            })
        ),
        "{caught:?}"
    );
    // A lost device: frames are no error and no panic (wgpu drops the lost device's errors).
    let profile = Profile::load("gles3-low").expect("profile");
    let terrain = Terrain::procedural(1, 65, 30.0, None).expect("terrain");
    let camera = terrain.default_camera().expect("camera");
    let mut renderer =
        TerrainRenderer::new(&device, &queue, terrain, &profile, &Default::default())
            .expect("renderer");
    renderer.prepare(&queue, &camera, SIZE).expect("a frame");
    device.destroy();
    renderer
        .prepare(&queue, &camera, SIZE)
        .expect("a frame on a lost device");
    draw(&renderer, &device, &queue);
    // And it is rebuilt on a new device.
    let (device, queue) = adapter.device();
    renderer.rebuild(&device, &queue).expect("rebuild");
    renderer
        .prepare(&queue, &camera, SIZE)
        .expect("a frame after");
}

/// The rebuild's cost against `TerrainRenderer::new`'s with the package and tables already in the cache
/// folder, the fastest of seven each (interleaved) on one device, and where each spends its time: the GPU objects
/// (render pipelines: the shaders' translation to GLSL, compilation and linking; shader modules: WGSL
/// parsed and validated) and the rest (for `new`: the clipmap, planner, SAT LOD and SG tables opened from
/// the cache; for a rebuild: SG's sky table integrated again and its bake copied).
#[test]
#[ignore = "a measurement: cargo test --test lost_device cost -- --ignored --nocapture"]
fn rebuild_cost_against_new() {
    let adapter = Adapter::new();
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lost_device_cache");
    let cases = [
        Case {
            name: "gles3-low, distance LOD, basic shading",
            profile: "gles3-low",
            sat_lod_px: None,
            sg_scene: None,
            imagery: false,
        },
        Case {
            name: "gles3-mid, SAT LOD 1 px, SG shading (noon)",
            profile: "gles3-mid",
            sat_lod_px: Some(1.0),
            sg_scene: Some("noon"),
            imagery: false,
        },
    ];
    const RUNS: usize = 7;
    for case in &cases {
        let (device, queue) = adapter.device();
        let profile = profile(case.profile);
        let mut options = RenderOptions::default().color_format(COLOR);
        options.sat_lod_px = case.sat_lod_px;
        options.sg_scene = case.sg_scene;
        let open = || Terrain::procedural(1, 257, 30.0, Some(&cache)).expect("terrain");
        // The first one bakes what the cache folder lacks, and compiles what the driver has not cached.
        let mut renderer =
            TerrainRenderer::new(&device, &queue, open(), &profile, &options).expect("renderer");
        let mut best_new = (
            Duration::MAX,
            Duration::ZERO,
            Duration::ZERO,
            Duration::ZERO,
        );
        let mut best_rebuild = best_new;
        // Interleaved, so that both see the same load.
        for _ in 0..RUNS {
            let terrain = open();
            let t = Instant::now();
            let r = TerrainRenderer::new(&device, &queue, terrain, &profile, &options)
                .expect("renderer");
            let took = t.elapsed();
            if took < best_new.0 {
                let l = r.gpu_ledger();
                best_new = (
                    took,
                    l.total_creation_time(),
                    l.creation_time(ObjectKind::RenderPipeline),
                    l.creation_time(ObjectKind::ShaderModule),
                );
            }
            drop(r);
            let t = Instant::now();
            renderer.rebuild(&device, &queue).expect("rebuild");
            let took = t.elapsed();
            if took < best_rebuild.0 {
                let l = renderer.gpu_ledger();
                best_rebuild = (
                    took,
                    l.total_creation_time(),
                    l.creation_time(ObjectKind::RenderPipeline),
                    l.creation_time(ObjectKind::ShaderModule),
                );
            }
        }
        let line =
            |(took, objects, pipelines, modules): (Duration, Duration, Duration, Duration)| {
                format!(
                "{:.1} ms (GPU objects {:.1} ms: render pipelines {:.1}, shader modules {:.1}, \
                 the rest of the objects {:.1}; not GPU objects {:.1})",
                ms(took),
                ms(objects),
                ms(pipelines),
                ms(modules),
                ms(objects.saturating_sub(pipelines + modules)),
                ms(took.saturating_sub(objects)),
            )
            };
        println!(
            "{}, fastest of {RUNS}: TerrainRenderer::new {}; rebuild {}; rebuild / new {:.2}",
            case.name,
            line(best_new),
            line(best_rebuild),
            best_rebuild.0.as_secs_f64() / best_new.0.as_secs_f64(),
        );
    }
}

/// Draped imagery through a lost device: its colour rings keep no CPU copy, so after the rebuild they
/// refill under the imagery budget; a warm-up at the same still camera then draws the frame drawn before
/// the loss, byte for byte. On Vulkan (lavapipe) the frame differs if the rings are not refilled; on
/// wgpu's GL backend the two devices share one GL context, and the new colour texture was seen to hold
/// the old one's texels, so only the Vulkan passes of `.ci/run` (which run this test) tell.
#[test]
fn imagery_refills_after_a_rebuild() {
    // Under `.ci/run`'s Vulkan passes the validation layer's reports reach the run's file.
    clipsat::gpu::validation::install_from_env();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("lost_device_imagery");
    std::fs::create_dir_all(&dir).expect("folder");
    // A 256 x 256 gradient and checkerboard draped on the procedural terrain's package (baked into the
    // cache folder by the first open).
    let cache = dir.join("cache");
    let start = Terrain::procedural(1, 257, 30.0, Some(&cache))
        .expect("terrain")
        .default_camera()
        .expect("camera");
    let package = std::fs::read_dir(&cache)
        .expect("cache folder")
        .map(|e| e.expect("entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "clipsat"))
        .expect("the package in the cache folder");
    let colours = dir.join("imagery.png");
    image::RgbImage::from_fn(256, 256, |x, y| {
        image::Rgb([
            u8::try_from(x).expect("a byte"),
            u8::try_from(y).expect("a byte"),
            if (x / 32 + y / 32) % 2 == 0 { 255 } else { 0 },
        ])
    })
    .save(&colours)
    .expect("imagery.png");
    let terrain = Terrain::open_with(
        &package,
        &clipsat::TerrainOptions::default()
            .cache_dir(cache.clone())
            .imagery(colours),
    )
    .expect("terrain with imagery");
    let camera = camera(&start, 5);
    let adapter = Adapter::new();
    let (device, queue) = adapter.device();
    let options = RenderOptions::default().color_format(COLOR);
    let mut renderer =
        TerrainRenderer::new(&device, &queue, terrain, &profile("gles3-low"), &options)
            .expect("renderer");
    let frame = |renderer: &mut TerrainRenderer, device: &wgpu::Device, queue: &wgpu::Queue| {
        renderer.warm_up(queue, &camera, SIZE).expect("warm-up");
        renderer.prepare(queue, &camera, SIZE).expect("prepare");
        let color = draw(renderer, device, queue);
        own_device::read_back(device, queue, &color).expect("read-back")
    };
    let before = frame(&mut renderer, &device, &queue);
    device.destroy();
    let (device, queue) = adapter.device();
    renderer.rebuild(&device, &queue).expect("rebuild");
    let after = frame(&mut renderer, &device, &queue);
    assert!(
        before == after,
        "the frame after the rebuild and warm-up differs"
    );
    // The imagery shows: the same frame without it differs.
    let plain = Terrain::open_with(
        &package,
        &clipsat::TerrainOptions::default().cache_dir(cache.clone()),
    )
    .expect("terrain");
    let mut plain = TerrainRenderer::new(&device, &queue, plain, &profile("gles3-low"), &options)
        .expect("renderer");
    let plain = frame(&mut plain, &device, &queue);
    let differ = plain
        .chunks_exact(4)
        .zip(after.chunks_exact(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(differ > 1000, "{differ} pixels show the imagery");
}
