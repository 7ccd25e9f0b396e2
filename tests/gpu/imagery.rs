//! Draped imagery on the GPU: a frame with imagery against its CPU twin
//! (`twin::imagery`, `twin::frame::compare_imagery`) within the tolerance of the basic and SG frames,
//! the GPU memory it adds, and a frame without imagery untouched by it. Headless on the strict OpenGL
//! ES 3.0 context (llvmpipe), or with `CLIPSAT_GPU=vulkan` on lavapipe: `cargo test --test gpu imagery::`.

use std::path::Path;

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::renderer::{Shading, ShadingProbe};
use clipsat::gpu::Gpu;
use clipsat::package::imagery::ImageryPackage;
use clipsat::package::imagery_bake::bake_imagery;
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::color_rings::{ColorRings, FADE_FRAMES};
use clipsat::plan::frame_plan::LodSetup;
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::shading::debug_view::DebugView;
use clipsat::source::imagery::{Extent, Imagery};
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::source::Heightmap;
use clipsat::twin::frame::compare_imagery;
use clipsat::twin::imagery::ImageryTwin;

/// The strict GLES 3.0 context, or the backend `CLIPSAT_GPU` names.
fn gpu() -> Gpu {
    crate::render_support::strict()
}

fn terrain() -> Heightmap {
    generate(&ProceduralParams {
        size: 257,
        ..ProceduralParams::default()
    })
    .expect("procedural terrain")
}

/// An image of 600 x 600 texels over the terrain's extent (finer than its 257 samples): smooth
/// gradients with stripes and a checker, so every level and every tap shows.
fn imagery(hm: &Heightmap) -> ImageryPackage {
    imagery_of(hm, 600)
}

/// [`imagery`]'s pattern at `n` x `n` texels.
fn imagery_of(hm: &Heightmap, n: u32) -> ImageryPackage {
    let mut texels = Vec::with_capacity((n * n * 3) as usize);
    for y in 0..n {
        for x in 0..n {
            let byte = |v: u32| u8::try_from(v % 256).expect("a byte");
            let checker = if (x / 24 + y / 24) % 2 == 0 { 60 } else { 0 };
            texels.extend_from_slice(&[
                byte(x * 255 / n),
                byte(y * 200 / n + checker),
                byte((x + 3 * y) % 97 + 90),
            ]);
        }
    }
    let (w, h) = (hm.width(), hm.height());
    let grid = Extent::of_grid(w, h, f64::from(hm.spacing()), hm.origin());
    let im =
        Imagery::from_rgb(Path::new("<test image>"), n, n, texels, &grid, None).expect("image");
    let (bytes, _) = bake_imagery(&im, 90, 1).expect("bake");
    ImageryPackage::from_bytes(Path::new("<test image>"), bytes).expect("package")
}

fn profile() -> Profile {
    let mut p = Profile::load("gles3-low").expect("profile");
    p.view.width = 192;
    p.view.height = 108;
    p.budget.update_samples_per_frame = u32::MAX;
    p
}

#[test]
fn imagery_frame_matches_its_twin() {
    imagery_frame_check(600, Some("procedural-imagery"));
}

/// An image of one level (at most 256 texels a side): its rings' array texture has a spare layer, as
/// one of six levels has, else wgpu's GL backend made it a plain 2D texture (a cube map for six), which
/// the shader read as one grey.
#[test]
fn a_one_level_image_is_drawn() {
    imagery_frame_check(200, None);
}

/// Images of one level, 16 and 32 texels a side, against the twin: drawn whole up to the image's edge
/// (their outer 4.5 texels had taken the terrain's colour; `tests/cpu/imagery_small.rs`).
#[test]
fn small_images_are_drawn() {
    imagery_frame_check(16, None);
    imagery_frame_check(32, None);
}

fn imagery_frame_check(n: u32, golden_view: Option<&str>) {
    let gpu = gpu();
    let hm = terrain();
    let p = profile();
    let mut cm = Clipmap::new(&hm, &p, ClipmapOptions::default()).expect("clipmap");
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let options = || OffscreenOptions {
        lod: LodSetup::new(LodMode::Distance, None).expect("lod"),
        shading: Shading::Basic,
        debug: DebugView::Normal,
    };
    let opts = FrameOptions::default();
    // The same frame without imagery first: what imagery must leave alone.
    let mut plain = Offscreen::new(&gpu, &p, &cm, options()).expect("renderer");
    let before = render_frame(&mut plain, &cm, &cam, &opts)
        .expect("frame")
        .image;
    let plain_bytes = plain.renderer().ledger().bytes();

    let mut r = Offscreen::new(&gpu, &p, &cm, options()).expect("renderer");
    let mut rings = ColorRings::new(imagery_of(&hm, n), &p.imagery).expect("rings");
    r.renderer_mut()
        .enable_imagery(
            gpu.device(),
            rings.ring(),
            rings.level_count(),
            rings.format(),
        )
        .expect("imagery");
    // The colour rings and the uniform, nothing else.
    let ring = u64::from(rings.ring());
    let layers = u64::from(clipsat::profile::ImageryBudget::layers(rings.level_count()));
    assert_eq!(
        r.renderer().ledger().bytes() - plain_bytes,
        ring * ring * layers * 4 + 12 * 64 + 32
    );
    assert!(layers * ring * ring * 4 <= p.imagery_gpu_bytes());
    let (x, y) = (cam.eye.x, cam.eye.y);
    let mut frames = 0;
    let mut settled = None;
    while settled.is_none_or(|s| frames < s + FADE_FRAMES) {
        frames += 1;
        assert!(frames < 300, "the colour rings never settle");
        let s = rings.update(x, y).expect("colour update");
        assert!(s.texels <= u64::from(p.imagery.texels_per_frame));
        r.renderer()
            .prepare_imagery(gpu.queue(), &rings, (x, y))
            .expect("upload");
        if s.stale_levels == 0 && settled.is_none() {
            settled = Some(frames);
        }
    }
    let probe = ShadingProbe::new(&r).expect("probe");
    let image = render_frame(&mut r, &cm, &cam, &opts).expect("frame").image;
    let probed = probe.capture(&r).expect("capture");
    let twin = ImageryTwin::new(&rings, x, y).expect("twin");
    let clear = clipsat::twin::border::clear_rgba8(opts.clear);
    let report = compare_imagery(&image, &probed, clear, &r.shading(), &twin);
    println!("imagery twin: {report:?}");
    assert!(report.pixels > 192 * 108 / 4, "{report:?}");
    assert!(
        report.passes(),
        "the imagery frame is not its twin's: {report:?}"
    );
    if let Some(view) = golden_view {
        golden(&gpu, view, &image);
    }
    // The imagery shows: most terrain pixels differ from the plain frame's.
    let differ = before
        .rgba
        .chunks(4)
        .zip(image.rgba.chunks(4))
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(p, q)| p.abs_diff(*q) > 8))
        .count();
    assert!(
        differ as u64 > report.pixels / 2,
        "{differ} of {} pixels changed",
        report.pixels
    );
    // And the renderer without imagery still draws its frame bit for bit.
    let again = render_frame(&mut plain, &cm, &cam, &opts)
        .expect("frame")
        .image;
    assert_eq!(again.rgba, before.rgba);
}

/// Warm-frame cost with and without imagery, basic shading, 1920 x 1080 on gles3-mid, the same run
/// (`cargo test --test gpu imagery::cost -- --ignored --nocapture`): the goal is at most 1.3x.
#[test]
#[ignore = "a measurement: cargo test --test gpu imagery::cost -- --ignored --nocapture"]
fn cost_with_and_without_imagery() {
    let gpu = gpu();
    let hm = generate(&ProceduralParams::default()).expect("terrain");
    let mut p = Profile::load("gles3-mid").expect("profile");
    p.view.width = 1920;
    p.view.height = 1080;
    let mut cm = Clipmap::new(&hm, &p, ClipmapOptions::default()).expect("clipmap");
    let cam = Camera::default_for(&hm).expect("camera");
    for _ in 0..64 {
        cm.update(cam.eye).expect("update");
    }
    let options = || OffscreenOptions {
        lod: LodSetup::new(LodMode::Distance, None).expect("lod"),
        shading: Shading::Basic,
        debug: DebugView::Normal,
    };
    let opts = FrameOptions::default();
    let mut plain = Offscreen::new(&gpu, &p, &cm, options()).expect("renderer");
    let mut draped = Offscreen::new(&gpu, &p, &cm, options()).expect("renderer");
    let mut rings = ColorRings::new(imagery(&hm), &p.imagery).expect("rings");
    draped
        .renderer_mut()
        .enable_imagery(
            gpu.device(),
            rings.ring(),
            rings.level_count(),
            rings.format(),
        )
        .expect("imagery");
    for _ in 0..64 {
        rings.update(cam.eye.x, cam.eye.y).expect("update");
        draped
            .renderer()
            .prepare_imagery(gpu.queue(), &rings, (cam.eye.x, cam.eye.y))
            .expect("upload");
    }
    let time = |r: &mut Offscreen<'_>| {
        render_frame(r, &cm, &cam, &opts).expect("warm-up");
        let t = std::time::Instant::now();
        for _ in 0..5 {
            render_frame(r, &cm, &cam, &opts).expect("frame");
        }
        t.elapsed().as_secs_f64() * 1e3 / 5.0
    };
    let (a, b, a2, b2) = (
        time(&mut plain),
        time(&mut draped),
        time(&mut plain),
        time(&mut draped),
    );
    let (a, b) = (a.min(a2), b.min(b2));
    println!(
        "basic: {a:.1} ms, basic + imagery: {b:.1} ms, ratio {:.2}",
        b / a
    );
    // SG (noon: diffuse, sun and sky) with and without imagery, the same run.
    let scene = clipsat::shading::scene::Scene::load("noon").expect("scene");
    let sg = |imagery: bool| {
        let mut r = Offscreen::with_sg(
            &gpu,
            &p,
            &cm,
            &hm,
            &scene,
            clipsat::shading::Patches::P4x8,
            false,
        )
        .expect("sg");
        if imagery {
            r.renderer_mut()
                .enable_imagery(
                    gpu.device(),
                    rings.ring(),
                    rings.level_count(),
                    rings.format(),
                )
                .expect("imagery");
            r.renderer()
                .prepare_imagery(gpu.queue(), &rings, (cam.eye.x, cam.eye.y))
                .expect("upload");
        }
        r
    };
    let (mut sg_plain, mut sg_draped) = (sg(false), sg(true));
    let (a, b, a2, b2) = (
        time(&mut sg_plain),
        time(&mut sg_draped),
        time(&mut sg_plain),
        time(&mut sg_draped),
    );
    let (a, b) = (a.min(a2), b.min(b2));
    println!("sg: {a:.1} ms, sg + imagery: {b:.1} ms, ratio {:.2}", b / a);
}

/// Fidelity against a reference drape (the goal): Puget Sound and Grand Canyon from the default
/// camera, rings filled; each terrain pixel's reference albedo is the source image (uncompressed,
/// full resolution) averaged over 8 x 8 bilinear samples of the pixel's footprint square (the probe's
/// side, the larger ground step of the pixel), lit as the frame is; PSNR over terrain pixels. Needs the
/// shared data: `cargo test --test gpu imagery::fidelity -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement on the shared data: cargo test --test gpu imagery::fidelity -- --ignored --nocapture"]
#[expect(
    clippy::cast_possible_truncation,
    reason = "bilinear fractions as f32; texel indices of a test image, clamped on lookup"
)]
fn fidelity_against_a_reference_drape() {
    let gpu = gpu();
    for (heights, image, spacing, scale) in [
        ("ps_height_1k.png", "imagery/ps_texture_1k.png", 160.0, None),
        (
            "imagery/gcanyon_elev_1200.png",
            "imagery/gcanyon_color_1024.png",
            60.0,
            Some(10.0),
        ),
    ] {
        let dir = clipsat::data_dir();
        if !dir.join(heights).is_file() || !dir.join(image).is_file() {
            eprintln!("skipping: shared data missing in {}", dir.display());
            continue;
        }
        let load = clipsat::source::LoadOptions {
            spacing: Some(spacing),
            height_scale: scale,
            ..clipsat::source::LoadOptions::default()
        };
        let hm = clipsat::source::load(&dir.join(heights), &load).expect("heights");
        let grid = Extent::of_grid(
            hm.width(),
            hm.height(),
            f64::from(hm.spacing()),
            hm.origin(),
        );
        let src = Imagery::load(&dir.join(image), &grid, &Default::default()).expect("image");
        // The format's own PSNR on the source image: level 0 encoded in 256^2 tiles and decoded.
        use clipsat::package::color_blocks::ColorFormat;
        let features = gpu.device().features();
        let blocks: Vec<ColorFormat> = [
            (ColorFormat::Bc1, wgpu::Features::TEXTURE_COMPRESSION_BC),
            (
                ColorFormat::Etc2Rgb8,
                wgpu::Features::TEXTURE_COMPRESSION_ETC2,
            ),
        ]
        .into_iter()
        .filter(|(_, f)| features.contains(*f))
        .map(|(c, _)| c)
        .collect();
        for &device_format in &blocks {
            let r = clipsat::package::color_blocks::round_trip(device_format, &src, 256)
                .expect("round trip");
            println!(
                "{image}: {} on the source image: PSNR {:.2} dB ({:.2} ms to encode a 256^2 tile)",
                device_format.name(),
                r.psnr(),
                r.encode_secs * 1000.0 / f64::from(r.tiles)
            );
        }
        // The package's tiles as stored in RGBA8 and in each block format the device has, and at JPEG
        // quality 100 (near the source: the renderer's own loss).
        let q = clipsat::package::imagery::DEFAULT_QUALITY;
        let runs = std::iter::once((q, ColorFormat::Rgba8))
            .chain(blocks.iter().map(|f| (q, *f)))
            .chain(std::iter::once((100, ColorFormat::Rgba8)));
        for (quality, format) in runs {
            let (bytes, _) = bake_imagery(&src, quality, 0).expect("bake");
            let pkg = ImageryPackage::from_bytes(Path::new(image), bytes).expect("package");
            let mut p = Profile::load("gles3-mid").expect("profile");
            p.view.width = 1920;
            p.view.height = 1080;
            p.budget.update_samples_per_frame = u32::MAX;
            let mut cm = Clipmap::new(&hm, &p, ClipmapOptions::default()).expect("clipmap");
            let cam = Camera::default_for(&hm).expect("camera");
            cm.update(cam.eye).expect("update");
            let mut r = Offscreen::new(
                &gpu,
                &p,
                &cm,
                OffscreenOptions {
                    lod: LodSetup::new(LodMode::Distance, None).expect("lod"),
                    shading: Shading::Basic,
                    debug: DebugView::Normal,
                },
            )
            .expect("renderer");
            let mut rings = ColorRings::with_format(pkg, &p.imagery, format).expect("rings");
            r.renderer_mut()
                .enable_imagery(
                    gpu.device(),
                    rings.ring(),
                    rings.level_count(),
                    rings.format(),
                )
                .expect("imagery");
            for _ in 0..64 {
                rings.update(cam.eye.x, cam.eye.y).expect("update");
                r.renderer()
                    .prepare_imagery(gpu.queue(), &rings, (cam.eye.x, cam.eye.y))
                    .expect("upload");
            }
            let probe = ShadingProbe::new(&r).expect("probe");
            let opts = FrameOptions::default();
            let frame = render_frame(&mut r, &cm, &cam, &opts).expect("frame").image;
            let probed = probe.capture(&r).expect("capture");
            let s = r.shading();
            let (dx, dy) = src.texel_spacing();
            let e = src.extent();
            // The source, bilinear at world (x, y), display-encoded, 0..1.
            let at = |x: f64, y: f64| -> glam::Vec3 {
                let u = (x - e.west) / dx - 0.5;
                let v = (e.north - y) / dy - 0.5;
                let (u0, v0) = (u.floor(), v.floor());
                let (fu, fv) = ((u - u0) as f32, (v - v0) as f32);
                let t = |i: f64, j: f64| {
                    let c = src.texel(i as i64, j as i64);
                    glam::Vec3::new(f32::from(c[0]), f32::from(c[1]), f32::from(c[2])) / 255.0
                };
                let a = t(u0, v0) * (1.0 - fu) + t(u0 + 1.0, v0) * fu;
                let b = t(u0, v0 + 1.0) * (1.0 - fu) + t(u0 + 1.0, v0 + 1.0) * fu;
                a * (1.0 - fv) + b * fv
            };
            let (mut sq, mut n) = (0.0f64, 0u64);
            for (i, (pos, q)) in probed.position.iter().zip(&probed.inputs).enumerate() {
                let Some(pos) = pos else { continue };
                let (x, y) = (cam.eye.x + f64::from(pos[0]), cam.eye.y + f64::from(pos[1]));
                let side = f64::from(pos[3]);
                let mut sum = glam::Vec3::ZERO;
                for k in 0..64 {
                    let (a, b) = (f64::from(k % 8) + 0.5, f64::from(k / 8) + 0.5);
                    sum += at(x + (a / 8.0 - 0.5) * side, y + (b / 8.0 - 0.5) * side);
                }
                let m = sum / 64.0;
                let albedo = glam::Vec3::new(m.x.powf(2.2), m.y.powf(2.2), m.z.powf(2.2));
                let rel = glam::Vec3::new(pos[0], pos[1], pos[2]);
                let want = clipsat::twin::frame::basic_lit(
                    albedo,
                    glam::Vec3::new(q[1], q[2], q[3]),
                    rel.length(),
                    &s,
                );
                let got = &frame.rgba[i * 4..i * 4 + 3];
                for (w, g) in [want.x, want.y, want.z].iter().zip(got) {
                    let d = f64::from(w * 255.0) - f64::from(*g);
                    sq += d * d;
                }
                n += 3;
            }
            let psnr = 10.0 * (255.0f64 * 255.0 / (sq / n as f64)).log10();
            println!(
            "{image}, tiles at JPEG quality {quality} (whole levels {}), rings in {}: PSNR {psnr:.2} dB over {} terrain pixels (1920 x 1080, gles3-mid)",
                clipsat::package::imagery::whole_quality(quality),
                format.name(),
                n / 3
        );
        }
    }
}

/// The embedding API: `TerrainOptions::imagery` bakes the image into the cache folder and the
/// `TerrainRenderer` draws it: its colour rings in the GPU bytes, their uploads in each frame's plan hash
/// (the same run to run).
#[test]
fn the_embedding_api_drapes_imagery() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("imagery-embed");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch");
    let heights = dir.join("heights.png");
    image::GrayImage::from_fn(129, 129, |x, y| {
        image::Luma([u8::try_from((x * 3 + y * 5) % 200).expect("byte")])
    })
    .save(&heights)
    .expect("heights");
    let photo = dir.join("photo.jpg");
    image::RgbImage::from_fn(300, 300, |x, y| {
        image::Rgb([
            u8::try_from(x % 256).expect("byte"),
            u8::try_from(y % 256).expect("byte"),
            90,
        ])
    })
    .save(&photo)
    .expect("photo");
    let gpu = gpu();
    let profile = clipsat::Profile::load("gles3-low").expect("profile");
    let open = |imagery: Option<&Path>| {
        let options = clipsat::TerrainOptions::default()
            .cache_dir(dir.join("cache"))
            .spacing_m(20.0);
        let options = match imagery {
            Some(path) => options.imagery(path),
            None => options,
        };
        clipsat::Terrain::open_with(&heights, &options).expect("terrain")
    };
    let run = |imagery: Option<&Path>, rgba8: bool| {
        let options = clipsat::RenderOptions::default().imagery_rgba8(rgba8);
        let terrain = open(imagery);
        assert_eq!(terrain.has_imagery(), imagery.is_some());
        let cam = terrain.default_camera().expect("camera");
        let mut r =
            clipsat::TerrainRenderer::new(gpu.device(), gpu.queue(), terrain, &profile, &options)
                .expect("renderer");
        r.warm_up(gpu.queue(), &cam, (160, 90)).expect("warm up");
        let hashes: Vec<u64> = (0..3)
            .map(|_| {
                r.prepare(gpu.queue(), &cam, (160, 90))
                    .expect("frame")
                    .plan_hash
            })
            .collect();
        (r.gpu_bytes(), hashes)
    };
    let (plain_bytes, plain) = run(None, false);
    let (bytes, draped) = run(Some(&photo), true);
    let ring = u64::from(profile.get().imagery.ring);
    // A 300^2 image has two levels (300, 150): two rings, RGBA8 when asked for.
    assert_eq!(bytes - plain_bytes, ring * ring * 2 * 4 + 12 * 64 + 32);
    assert_ne!(plain, draped);
    assert_eq!(
        run(Some(&photo), true).1,
        draped,
        "the same hashes run to run"
    );
    // The device's own format: 0.5 byte a texel where it has BC or ETC2, the same hashes run to run.
    let block = clipsat::gpu::renderer::Renderer::imagery_format(gpu.device(), false).is_block();
    let (bytes, compressed) = run(Some(&photo), false);
    let per_16 = if block { 8 } else { 64 };
    assert_eq!(
        bytes - plain_bytes,
        ring * ring * 2 * per_16 / 16 + 12 * 64 + 32
    );
    assert_eq!(
        run(Some(&photo), false).1,
        compressed,
        "the same hashes run to run"
    );
}

/// The exact image hash of an imagery frame on this driver against `tests/goldens/imagery_hashes.txt`
/// (lines `adapter|driver<TAB>view<TAB>hash`; a driver with no line is checked by the twin alone), and a
/// reference PNG beside it. `CLIPSAT_BLESS=1` records this driver's hash and the PNG.
fn golden(gpu: &Gpu, view: &str, image: &clipsat::gpu::readback::Image) {
    let report = gpu.report();
    let key = format!("{}|{}", report.name, report.driver);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/goldens");
    let path = dir.join("imagery_hashes.txt");
    let text = std::fs::read_to_string(&path).unwrap_or_default();
    let mut lines: Vec<String> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(str::to_string)
        .collect();
    let hash = clipsat::hash::hex(image.hash());
    let prefix = format!("{key}\t{view}\t");
    if std::env::var_os("CLIPSAT_BLESS").is_some_and(|v| v == "1") {
        lines.retain(|l| !l.starts_with(&prefix));
        lines.push(format!("{prefix}{hash}"));
        lines.sort();
        let head = "# Exact image hashes of imagery frames per driver: adapter|driver<TAB>view<TAB>hash (tests/gpu/imagery.rs).\n";
        std::fs::write(&path, head.to_string() + &lines.join("\n") + "\n").expect("write hashes");
        image
            .save_png(&dir.join(format!("{view}.png")))
            .expect("write golden");
        return;
    }
    if let Some(line) = lines.iter().find(|l| l.starts_with(&prefix)) {
        assert_eq!(
            &line[prefix.len()..],
            hash,
            "{view}: the image hash on {key} changed"
        );
    }
}

/// Draped imagery under SG shading (evening: visibility, specular, fog): the diffuse term scaled by the
/// imagery's albedo over the scene's k_d, against the SG twin so scaled (`compare_sg_imagery`), within
/// the same tolerance as the SG frames.
#[test]
fn sg_imagery_frame_matches_its_twin() {
    use clipsat::shading::scene::Scene;
    use clipsat::shading::{Patches, TexelLighting};
    use clipsat::twin::frame::{compare_sg_imagery, SgDrawn};
    let gpu = gpu();
    let hm = terrain();
    let mut p = profile();
    p.view.width = 160;
    p.view.height = 90;
    p.shading.features.push(clipsat::profile::Feature::Sg);
    let mut cm = Clipmap::new(&hm, &p, ClipmapOptions::default()).expect("clipmap");
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let scene = Scene::load("evening").expect("scene");
    let share = p.cpu_split().shading;
    let (_, bake) = clipsat::gpu::headless::sg_bake(share, &hm, &scene, true).expect("bake");
    let mut r = Offscreen::with_sg(&gpu, &p, &cm, &hm, &scene, Patches::P4x8, true).expect("sg");
    let mut rings = ColorRings::new(imagery(&hm), &p.imagery).expect("rings");
    r.renderer_mut()
        .enable_imagery(
            gpu.device(),
            rings.ring(),
            rings.level_count(),
            rings.format(),
        )
        .expect("imagery");
    let (x, y) = (cam.eye.x, cam.eye.y);
    for _ in 0..40 {
        rings.update(x, y).expect("colour update");
        r.renderer()
            .prepare_imagery(gpu.queue(), &rings, (x, y))
            .expect("upload");
    }
    let opts = FrameOptions::default();
    let probe = ShadingProbe::new(&r).expect("probe");
    let image = render_frame(&mut r, &cm, &cam, &opts).expect("frame").image;
    let probed = probe.capture(&r).expect("capture");
    let twin = ImageryTwin::new(&rings, x, y).expect("twin");
    let (drawn, sky, spacing) = r.renderer().sg_drawn().expect("SG");
    let lighting = TexelLighting::new(&drawn);
    let d = SgDrawn {
        scene: &drawn,
        sky,
        lighting: &lighting,
        bake: &bake,
        data_spacing: spacing,
    };
    let clear = clipsat::twin::border::clear_rgba8(opts.clear);
    let report = compare_sg_imagery(&image, &probed, clear, r.globals(), &cm, &d, &twin);
    println!("sg imagery twin: {report:?}");
    assert!(report.pixels > 160 * 90 / 3, "{report:?}");
    assert!(
        report.passes(),
        "the SG imagery frame is not its twin's: {report:?}"
    );
}

/// `twin::imagery_check::check_frame`, the check `clipsat selftest` runs, passes on this device.
#[test]
fn the_selftest_check_passes() {
    let gpu = gpu();
    let mut p = profile();
    (p.view.width, p.view.height) = (160, 90);
    let (report, _) =
        clipsat::twin::imagery_check::check_frame(&gpu, &terrain(), &p).expect("check");
    assert!(
        report.passes() && report.pixels > 160 * 90 / 3,
        "{report:?}"
    );
}

/// The colour rings in the device's block formats (BC1 where it has BC, ETC2 RGB8 where it has ETC2;
/// `Renderer::imagery_format` picks the first): the frame against its twin (which reads the blocks'
/// decoded colours) within the same tolerance, the rings' GPU bytes 0.5 a texel in the ledger, and the
/// image and the rings' hashes the same run to run. A device with neither is reported and skipped.
#[test]
fn block_format_imagery_matches_its_twin() {
    use clipsat::gpu::renderer::Renderer;
    use clipsat::package::color_blocks::ColorFormat;
    let gpu = gpu();
    let features = gpu.device().features();
    println!("adapter features: {:?}", gpu.adapter().features());
    let chosen = Renderer::imagery_format(gpu.device(), false);
    let report = gpu.report();
    println!(
        "{} ({}): TEXTURE_COMPRESSION_BC {}, TEXTURE_COMPRESSION_ETC2 {}, imagery format {}",
        report.name,
        report.driver,
        features.contains(wgpu::Features::TEXTURE_COMPRESSION_BC),
        features.contains(wgpu::Features::TEXTURE_COMPRESSION_ETC2),
        chosen.name()
    );
    assert_eq!(
        Renderer::imagery_format(gpu.device(), true),
        ColorFormat::Rgba8
    );
    let formats = [
        (ColorFormat::Bc1, wgpu::Features::TEXTURE_COMPRESSION_BC),
        (
            ColorFormat::Etc2Rgb8,
            wgpu::Features::TEXTURE_COMPRESSION_ETC2,
        ),
    ];
    let hm = terrain();
    let mut p = profile();
    (p.view.width, p.view.height) = (160, 90);
    let mut cm = Clipmap::new(&hm, &p, ClipmapOptions::default()).expect("clipmap");
    let cam = Camera::default_for(&hm).expect("camera");
    cm.update(cam.eye).expect("update");
    let opts = FrameOptions::default();
    let options = || OffscreenOptions {
        lod: LodSetup::new(LodMode::Distance, None).expect("lod"),
        shading: Shading::Basic,
        debug: DebugView::Normal,
    };
    let plain_bytes = Offscreen::new(&gpu, &p, &cm, options())
        .expect("renderer")
        .renderer()
        .ledger()
        .bytes();
    let (x, y) = (cam.eye.x, cam.eye.y);
    for (format, _) in formats.iter().filter(|(_, f)| features.contains(*f)) {
        let run = || {
            let mut r = Offscreen::new(&gpu, &p, &cm, options()).expect("renderer");
            let mut rings =
                ColorRings::with_format(imagery(&hm), &p.imagery, *format).expect("rings");
            r.renderer_mut()
                .enable_imagery(gpu.device(), rings.ring(), rings.level_count(), *format)
                .expect("imagery");
            let ring = u64::from(rings.ring());
            assert_eq!(
                r.renderer().ledger().bytes() - plain_bytes,
                ring * ring * u64::from(rings.level_count()) / 2 + 12 * 64 + 32,
                "{format:?}: 0.5 byte a texel"
            );
            let mut hash = 0u64;
            for _ in 0..40 {
                hash ^= rings.update(x, y).expect("colour update").hash;
                r.renderer()
                    .prepare_imagery(gpu.queue(), &rings, (x, y))
                    .expect("upload");
            }
            let probe = ShadingProbe::new(&r).expect("probe");
            let image = render_frame(&mut r, &cm, &cam, &opts).expect("frame").image;
            let probed = probe.capture(&r).expect("capture");
            let twin = ImageryTwin::new(&rings, x, y).expect("twin");
            let clear = clipsat::twin::border::clear_rgba8(opts.clear);
            let report = compare_imagery(&image, &probed, clear, &r.shading(), &twin);
            (report, image.hash(), hash)
        };
        let (report, image, rings) = run();
        println!("{format:?} imagery twin: {report:?}");
        assert!(report.pixels > 160 * 90 / 3, "{format:?}: {report:?}");
        assert!(
            report.passes(),
            "{format:?}: the imagery frame is not its twin's: {report:?}"
        );
        // Run to run, in the format the device takes (the other one's blocks are checked on the CPU).
        if *format == chosen {
            let (_, image2, rings2) = run();
            assert_eq!((image, rings), (image2, rings2), "{format:?}: run to run");
        }
    }
}
