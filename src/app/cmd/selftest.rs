//! `clipsat selftest`: whether this machine's GPU draws clipsat correctly, check by check, before a user
//! trusts a new phone or board (docs/real-drivers.md). Each frame is compared with its CPU twin within
//! what GLES 3.0 allows a conformant driver (`clipsat::twin::frame`), not with another driver's pixels.
//! Exits 0 when every check passes, 1 when one fails (2 for a bad command line, as every command).

use std::path::Path;
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use clipsat::bake::{bake_lod, default_cache_dir, BakeParams};
use clipsat::gpu::headless::{render_frame, sg_bake, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::readback::Image;
use clipsat::gpu::renderer::{ShadingProbe, VertexProbe};
use clipsat::gpu::{floor, Gpu, GpuMode};
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::cull::DrawKind;
use clipsat::plan::frame_plan::LodSetup;
use clipsat::plan::lod::{Lod, LodMode};
use clipsat::plan::mesh;
use clipsat::profile::{Feature, Profile};
use clipsat::shading::scene::Scene;
use clipsat::shading::{Patches, TexelLighting};
use clipsat::source::procedural::{generate, ProceduralParams};
use clipsat::source::Heightmap;
use clipsat::twin::frame::{compare_basic, compare_sg, SgDrawn, TwinReport};
use clipsat::twin::{border, clipmap as vertex_twin};
use clipsat::{Progress, Result};
use glam::DVec3;
use serde::Serialize;

/// `--gpu` of the self-test: which device it checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum SelftestGpu {
    /// `CLIPSAT_GPU` if set, else a strict OpenGL ES 3.0 context, else wgpu's GL backend.
    #[default]
    Auto,
    /// A real OpenGL ES 3.0 context (EGL).
    Strict,
    /// wgpu's own GL backend.
    Gl,
    /// wgpu's Vulkan backend, on the same GLES 3.0 limits.
    Vulkan,
}

/// `clipsat selftest`.
#[derive(Args, Debug)]
pub(crate) struct SelftestArgs {
    /// The device checked.
    #[arg(long, value_enum, default_value_t = SelftestGpu::Auto)]
    gpu: SelftestGpu,
    /// Frames drawn and read back for the frame-time check.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    frames: u32,
    /// The report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Also writes the frames compared with their CPU twins to this folder as PNG (`basic.png`,
    /// `sg.png`, `pool.png`, `imagery.png`): with the JSON, what to send when a check fails on a device.
    #[arg(long, value_name = "DIR")]
    images: Option<std::path::PathBuf>,
}

/// One check's outcome.
#[derive(Clone, Debug, Serialize)]
struct Check {
    name: &'static str,
    ok: bool,
    detail: String,
    /// The check's measurements by name, for a device farm to group and compare failures.
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    figures: serde_json::Map<String, serde_json::Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    twin: Option<TwinReport>,
    /// The frame's PNG, with `--images`.
    #[serde(skip_serializing_if = "Option::is_none")]
    image: Option<String>,
}

impl Check {
    fn new(name: &'static str, ok: bool, detail: String) -> Self {
        Self {
            name,
            ok,
            detail,
            figures: serde_json::Map::new(),
            twin: None,
            image: None,
        }
    }

    /// Adds measurements to the check's figures.
    fn with(mut self, figures: &[(&str, f64)]) -> Self {
        for (k, v) in figures {
            self.figures.insert((*k).to_string(), serde_json::json!(v));
        }
        self
    }

    /// A frame's comparison with its twin.
    fn frame(name: &'static str, report: TwinReport, note: &str) -> Self {
        let detail = format!(
            "{} pixels against the CPU twin: mean {:.2} levels, max {:.1}, {} past {} levels{}{note}",
            report.pixels,
            report.mean_levels,
            report.max_levels,
            report.outliers,
            clipsat::twin::frame::LEVELS,
            if report.r_outliers > 0 || report.max_r_error > 0.0 {
                format!(
                    "; SG inputs off by {:.1e} at most ({} pixels past tolerance)",
                    report.max_r_error, report.r_outliers
                )
            } else {
                String::new()
            },
        );
        Self {
            name,
            ok: report.passes(),
            detail,
            figures: serde_json::Map::new(),
            twin: Some(report),
            image: None,
        }
    }

    /// With a folder, writes the frame there as `{stem}.png` and names it in the check.
    fn saved(mut self, image: &Image, dir: Option<&Path>, stem: &str) -> Result<Self> {
        if let Some(dir) = dir {
            let path = dir.join(format!("{stem}.png"));
            image.save_png(&path)?;
            self.image = Some(path.display().to_string());
        }
        Ok(self)
    }

    /// A check that could not run: failed, with the error.
    fn error(name: &'static str, e: &clipsat::Error) -> Self {
        let mut text = format!("error: {e}");
        let mut source = std::error::Error::source(e);
        while let Some(s) = source {
            let t = s.to_string();
            if !text.contains(&t) {
                text.push_str(&format!(": {t}"));
            }
            source = s.source();
        }
        Self::new(name, false, text)
    }
}

/// Runs the checks, prints the report and exits 1 when one failed.
pub(crate) fn run(args: &SelftestArgs) -> Result<()> {
    let mode = match args.gpu {
        SelftestGpu::Auto => GpuMode::Auto,
        SelftestGpu::Strict => GpuMode::Strict,
        SelftestGpu::Gl => GpuMode::Gl,
        SelftestGpu::Vulkan => GpuMode::Vulkan,
    };
    let t0 = Instant::now();
    let (adapter, checks) = match Gpu::new(mode) {
        Ok(gpu) => {
            let adapter = serde_json::to_value(gpu.report()).unwrap_or_default();
            (adapter, checks(&gpu, args.frames, args.images.as_deref()))
        }
        Err(e) => (serde_json::Value::Null, vec![Check::error("adapter", &e)]),
    };
    let passed = checks.iter().all(|c| c.ok);
    if args.json {
        let v = serde_json::json!({
            "clipsat": env!("CARGO_PKG_VERSION"),
            "os": std::env::consts::OS,
            "arch": std::env::consts::ARCH,
            "adapter": adapter,
            "checks": checks,
            "passed": passed,
            "seconds": t0.elapsed().as_secs_f64(),
        });
        outln!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
    } else {
        if let Some(a) = adapter.as_object() {
            let field = |k: &str| a.get(k).and_then(|v| v.as_str()).unwrap_or("?").to_string();
            outln!(
                "device: {}, driver {} ({}, {}, {})",
                field("name"),
                field("driver"),
                field("backend"),
                field("gl_version"),
                field("mode")
            );
        }
        for c in &checks {
            outln!(
                "{} {}: {}",
                if c.ok { "ok  " } else { "FAIL" },
                c.name,
                c.detail
            );
        }
        outln!(
            "{} in {:.1} s",
            if passed {
                "passed: this device draws clipsat correctly"
            } else {
                "FAILED: this device does not draw clipsat correctly (docs/real-drivers.md)"
            },
            t0.elapsed().as_secs_f64()
        );
    }
    if !passed {
        use std::io::Write as _;
        let _ = std::io::stdout().flush();
        std::process::exit(1);
    }
    Ok(())
}

/// The checks after the adapter's: each returns its own outcome, an error included.
fn checks(gpu: &Gpu, frames: u32, images: Option<&Path>) -> Vec<Check> {
    let floor = floor::check(gpu.adapter());
    let short = floor::shortfalls(&floor);
    let mut out = vec![Check::new(
        "adapter",
        short.is_empty(),
        if short.is_empty() {
            format!(
                "the GLES 3.0 limits and {} texture formats with their usages",
                floor.len() - 1
            )
        } else {
            short.join("; ")
        },
    )];
    if let Some(dir) = images {
        if let Err(e) = std::fs::create_dir_all(dir) {
            out.push(Check::error(
                "images",
                &clipsat::Error::io(dir, "creating the images folder", e),
            ));
            return out;
        }
    }
    let hm = match generate(&ProceduralParams {
        size: 257,
        ..ProceduralParams::default()
    }) {
        Ok(hm) => hm,
        Err(e) => {
            out.push(Check::error("terrain", &e));
            return out;
        }
    };
    let runs: [(&'static str, &dyn Fn() -> Result<Check>); 7] = [
        ("vertices", &|| vertices(gpu, &hm)),
        ("basic frame", &|| basic_frame(gpu, &hm, images)),
        ("SG frame", &|| sg_frame(gpu, &hm, images)),
        ("detail-pool frame", &|| pool_frame(gpu, &hm, images)),
        ("imagery frame", &|| imagery_frame(gpu, &hm, images)),
        ("border", &|| border_check(gpu, &hm)),
        ("read-back and frame times", &|| {
            frame_times(gpu, &hm, frames)
        }),
    ];
    for (name, check) in runs {
        let t = Instant::now();
        let c = check().unwrap_or_else(|e| Check::error(name, &e));
        out.push(c.with(&[("seconds", t.elapsed().as_secs_f64())]));
    }
    out
}

/// gles3-low at 160 x 90, SG allowed, updates unbounded (each frame holds its rings whole).
fn profile(detail_tiles: Option<u32>) -> Result<Profile> {
    let mut p = Profile::load("gles3-low")?;
    (p.view.width, p.view.height) = (160, 90);
    p.budget.update_samples_per_frame = u32::MAX;
    p.shading.features.push(Feature::Sg);
    if let Some(t) = detail_tiles {
        p.budget.detail_tiles = t;
    }
    p.validate("selftest")?;
    Ok(p)
}

/// A low camera over the terrain's middle, looking ahead and down: blocks that want finer data than the
/// rings hold near it (the detail pool's).
fn low_camera(hm: &Heightmap) -> Result<Camera> {
    let (ox, oy) = hm.origin();
    let (ex, ey) = hm.extent_m();
    let (x, y) = (ox + 0.35 * ex, oy + 0.4 * ey);
    let (u, v) = hm.world_to_grid(x, y);
    let ground = clipsat::bake::horizon::height_bilinear(hm, u, v);
    let eye = DVec3::new(x, y, ground.max(0.0) + 120.0);
    Camera::new(eye, eye + DVec3::new(1.0, 0.3, -0.35), 60.0)?.with_clip(2.0, 6.0e5)
}

fn clipmap_at(hm: &Heightmap, p: &Profile, eye: DVec3) -> Result<Clipmap> {
    let mut cm = Clipmap::new(hm, p, ClipmapOptions::default())?;
    cm.update(eye)?;
    Ok(cm)
}

/// The vertex shader against its CPU twin (`twin::clipmap`) on every draw of a distance-LOD frame: each
/// vertex within the bound conformant highp arithmetic allows.
fn vertices(gpu: &Gpu, hm: &Heightmap) -> Result<Check> {
    let p = profile(None)?;
    let cam = low_camera(hm)?;
    let cm = clipmap_at(hm, &p, cam.eye)?;
    let mut r = Offscreen::new(gpu, &p, &cm, OffscreenOptions::default())?;
    let probe = VertexProbe::new(&r)?;
    render_frame(&mut r, &cm, &cam, &FrameOptions::default())?;
    let (w, h) = r.size();
    let (mut worst, mut checked) = (0.0f64, 0u64);
    for k in 0..r.draws().len() {
        let d = r.draws()[k];
        let m = match d.kind {
            DrawKind::Block => mesh::block(p.block_m()),
            DrawKind::Skirt => mesh::skirt(p.clipmap.n + 1),
            DrawKind::TileSkirt => mesh::skirt_loops(p.block_m()),
            // Distance LOD draws no pool cells.
            _ => continue,
        };
        let u = r.draw_uniform(k);
        for (v, g) in m.vertices.iter().zip(probe.capture(&r, k)?) {
            let c = vertex_twin::cpu_vertex(r.globals(), &u, cm.ring(d.level), *v);
            let Some(b) = vertex_twin::pixel_bound(c.clip, c.clip_bound, w, h) else {
                continue;
            };
            if c.clip[3] <= 1.0 {
                continue;
            }
            let px = |a: f32, wc: f32, side: u32| f64::from(a / wc) * f64::from(side) * 0.5;
            let e = [
                (px(g[0], g[3], w) - px(c.clip[0], c.clip[3], w)).abs() / b[0],
                (px(g[1], g[3], h) - px(c.clip[1], c.clip[3], h)).abs() / b[1],
            ];
            worst = worst.max(e[0]).max(e[1]);
            checked += 1;
        }
    }
    #[expect(clippy::cast_precision_loss, reason = "a vertex count far below 2^52")]
    let figures = [("vertices", checked as f64), ("worst_of_bound", worst)];
    Ok(Check::new(
        "vertices",
        checked > 1000 && worst <= 1.0,
        format!(
            "{checked} vertices against the CPU twin: at most {worst:.2} of what conformant highp \
             arithmetic allows"
        ),
    )
    .with(&figures))
}

/// A basic-shading frame (distance LOD, ring data under coarser blocks) against its twin.
fn basic_frame(gpu: &Gpu, hm: &Heightmap, images: Option<&Path>) -> Result<Check> {
    let p = profile(None)?;
    let cam = Camera::default_for(hm)?;
    let cm = clipmap_at(hm, &p, cam.eye)?;
    let mut r = Offscreen::new(gpu, &p, &cm, OffscreenOptions::default())?;
    let probe = ShadingProbe::new(&r)?;
    let image = render_frame(&mut r, &cm, &cam, &FrameOptions::default())?.image;
    let probed = probe.capture(&r)?;
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    Check::frame(
        "basic frame",
        compare_basic(&image, &probed, clear, &r.shading()),
        "",
    )
    .saved(&image, images, "basic")
}

/// An SG frame (evening: visibility, specular, fog; 4 x 8 patches) against its twin: what the shader read
/// from the per-level tables, and the colour.
fn sg_frame(gpu: &Gpu, hm: &Heightmap, images: Option<&Path>) -> Result<Check> {
    let p = profile(None)?;
    let cam = Camera::default_for(hm)?;
    let cm = clipmap_at(hm, &p, cam.eye)?;
    let scene = Scene::load("evening")?;
    let (_, bake) = sg_bake(p.cpu_split().shading, hm, &scene, true)?;
    let mut r = Offscreen::with_sg(gpu, &p, &cm, hm, &scene, Patches::P4x8, true)?;
    let probe = ShadingProbe::new(&r)?;
    let image = render_frame(&mut r, &cm, &cam, &FrameOptions::default())?.image;
    let probed = probe.capture(&r)?;
    let Some((drawn, sky, spacing)) = r.renderer().sg_drawn() else {
        return Ok(Check::new(
            "SG frame",
            false,
            "the renderer draws no SG".into(),
        ));
    };
    let lighting = TexelLighting::new(&drawn);
    let d = SgDrawn {
        scene: &drawn,
        sky,
        lighting: &lighting,
        bake: &bake,
        data_spacing: spacing,
    };
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    let report = compare_sg(&image, &probed, clear, r.globals(), &cm, &d);
    Check::frame("SG frame", report, "").saved(&image, images, "sg")
}

/// A SAT LOD frame at 0.5 px, low over the terrain, drawing detail pool cells, against its twin.
fn pool_frame(gpu: &Gpu, hm: &Heightmap, images: Option<&Path>) -> Result<Check> {
    let p = profile(Some(300))?;
    let cam = low_camera(hm)?;
    let mut cm = clipmap_at(hm, &p, cam.eye)?;
    let params = BakeParams {
        p: clipsat::bake::lod_tables::P,
        levels: p.clipmap.levels,
        synth_levels: cm.synth_levels(),
        g0: cm.g0(),
    };
    let (tables, _) = bake_lod(
        hm,
        cm.pyramid(),
        &params,
        &default_cache_dir(),
        Progress::default(),
    )?;
    let lod = Lod::for_clipmap(tables, &p, &cm, hm);
    let options = OffscreenOptions {
        lod: LodSetup::new(LodMode::Sat, Some(lod))?,
        ..OffscreenOptions::default()
    };
    let mut r = Offscreen::new(gpu, &p, &cm, options)?;
    let opts = FrameOptions {
        epsilon_px: Some(0.5),
        ..FrameOptions::default()
    };
    // The pool fills from what the rings leave of each frame's budget.
    for _ in 0..8 {
        cm.update(cam.eye)?;
        r.frame(&cm, &cam, &opts)?;
    }
    let probe = ShadingProbe::new(&r)?;
    let image = render_frame(&mut r, &cm, &cam, &opts)?.image;
    let probed = probe.capture(&r)?;
    let cells = r.plan().stats().pool_cells;
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    let mut check = Check::frame(
        "detail-pool frame",
        compare_basic(&image, &probed, clear, &r.shading()),
        &format!("; {cells} pool cells drawn"),
    );
    check.ok &= cells > 0;
    check
        .with(&[("pool_cells", f64::from(cells))])
        .saved(&image, images, "pool")
}

/// A basic frame with draped imagery (the colour rings, filled and faded in) against its twin.
fn imagery_frame(gpu: &Gpu, hm: &Heightmap, images: Option<&Path>) -> Result<Check> {
    let (report, image) = clipsat::twin::imagery_check::check_frame(gpu, hm, &profile(None)?)?;
    Check::frame("imagery frame", report, "").saved(&image, images, "imagery")
}

/// Seen from outside and low, nothing is drawn where no ray within a pixel meets the data (the CPU's
/// rays, `twin::border`): no curtain below the data's edge, with distance and SAT LOD.
fn border_check(gpu: &Gpu, hm: &Heightmap) -> Result<Check> {
    let p = profile(None)?;
    let (ox, oy) = hm.origin();
    let (ex, ey) = hm.extent_m();
    let (lo, hi) = hm.range();
    let eye = DVec3::new(
        ox + 0.5 * ex,
        oy - 0.3 * ey,
        f64::from(hi) + 0.1 * f64::from(hi - lo),
    );
    let target = DVec3::new(ox + 0.5 * ex, oy + 0.6 * ey, f64::from(lo));
    let cam = Camera::new(eye, target, 60.0)?.with_clip(2.0, 6.0e5)?;
    let cm = clipmap_at(hm, &p, cam.eye)?;
    let (w, h) = (p.view.width, p.view.height);
    let coverage = border::data_coverage(hm, &cam, w, h);
    let seen = coverage.iter().filter(|c| **c).count();
    let clear = border::clear_rgba8(FrameOptions::default().clear);
    let mut r = Offscreen::new(gpu, &p, &cm, OffscreenOptions::default())?;
    let image = render_frame(&mut r, &cm, &cam, &FrameOptions::default())?.image;
    let curtains = border::curtain_pixels(&image, clear, &coverage);
    #[expect(clippy::cast_precision_loss, reason = "pixel counts far below 2^52")]
    let figures = [
        ("curtain_pixels", curtains as f64),
        ("data_pixels", seen as f64),
    ];
    Ok(Check::new(
        "border",
        curtains <= 20 && seen > 0,
        format!("{curtains} pixels drawn where no ray meets the data ({seen} pixels see it)"),
    )
    .with(&figures))
}

/// `frames` frames along a short path, each planned, uploaded, drawn and read back: none may hang (a
/// read-back waits up to `CLIPSAT_GPU_WAIT_S`, 60 s by default), and the times are reported.
fn frame_times(gpu: &Gpu, hm: &Heightmap, frames: u32) -> Result<Check> {
    let p = profile(None)?;
    let start = low_camera(hm)?;
    let mut cm = Clipmap::new(hm, &p, ClipmapOptions::default())?;
    let mut r = Offscreen::new(gpu, &p, &cm, OffscreenOptions::default())?;
    let opts = FrameOptions::default();
    let (mut total, mut worst, mut read) = (Duration::ZERO, Duration::ZERO, Duration::ZERO);
    for i in 0..frames {
        let eye = start.eye + DVec3::new(20.0 * f64::from(i), 6.0 * f64::from(i), 0.0);
        let cam =
            Camera::new(eye, eye + DVec3::new(1.0, 0.3, -0.35), 60.0)?.with_clip(2.0, 6.0e5)?;
        cm.update(cam.eye)?;
        let t = Instant::now();
        r.frame(&cm, &cam, &opts)?;
        let t_read = Instant::now();
        r.read_image()?;
        read = read.max(t_read.elapsed());
        let dt = t.elapsed();
        total += dt;
        worst = worst.max(dt);
    }
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    Ok(Check::new(
        "read-back and frame times",
        true,
        format!(
            "{frames} frames at {}x{}: mean {:.1} ms, max {:.1} ms (plan, upload, draw, read-back); \
             longest read-back {:.1} ms",
            p.view.width,
            p.view.height,
            ms(total) / f64::from(frames),
            ms(worst),
            ms(read)
        ),
    )
    .with(&[
        ("frames", f64::from(frames)),
        ("mean_ms", ms(total) / f64::from(frames)),
        ("max_ms", ms(worst)),
        ("max_read_back_ms", ms(read)),
    ]))
}
