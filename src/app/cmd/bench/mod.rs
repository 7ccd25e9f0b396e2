//! `clipsat bench lod`: measures the per-frame LOD stage and the renderer across estimators and error bounds
//! on the shared terrains, and writes a Markdown table and a plot. A measurement tool: it allocates freely
//! and reads the wall clock (its timings are not part of any hash).

use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Subcommand};
use clipsat::clipmap::{Clipmap, ClipmapOptions};
use clipsat::flight::{Flight, Path};
use clipsat::gpu::brute::BruteForce;
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::lod::{LodFrame, LodMode};
use clipsat::plot::{LinePlot, Series};
use clipsat::renderer::{self, FrameOptions, Renderer};
use clipsat::source::{self, LoadOptions};
use clipsat::{Error, Heightmap, Profile, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::ProfileArgs;

#[derive(Args, Debug)]
pub(crate) struct BenchArgs {
    #[command(subcommand)]
    what: BenchWhat,
}

#[derive(Subcommand, Debug)]
enum BenchWhat {
    /// SAT LOD against distance LOD: triangles, LOD time, render time, measured screen error and image
    /// RMSE against the brute-force render, for epsilon 0.5 .. 8 px and every estimator.
    Lod(BenchLodArgs),
    /// Every benchmark on the procedural terrain and each shared terrain present: LOD, shading, update
    /// budget against speed and memory per profile, as DIR/report.md with PNG plots beside it.
    All(super::bench_all::BenchAllArgs),
    /// SG shading: patches {2x4, 4x8, 8x16} x effects {diffuse, +visibility, +specular}: ms per frame
    /// against basic shading, RMSE and max error against the CPU reference.
    Shading(BenchShadingArgs),
}

#[derive(Args, Debug)]
pub(crate) struct BenchShadingArgs {
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output folder for shading.md and shading.png.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Timed frames per configuration (after one warm-up frame).
    #[arg(long, value_name = "N", default_value_t = 3)]
    frames: u32,
    /// Image size, WxH pixels.
    #[arg(long, value_name = "WxH", default_value = "320x180")]
    size: String,
    /// GL context: strict, gl or auto.
    #[arg(long, value_name = "auto|strict|gl", default_value = "auto")]
    gpu: String,
}

#[derive(Args, Debug)]
struct BenchLodArgs {
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output folder for lod.md and lod.png.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Frames of a figure-8 flight per terrain.
    #[arg(long, value_name = "N", default_value_t = 12)]
    pub(crate) frames: u32,
    /// Image size, WxH pixels.
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// GL context: strict, gl or auto.
    #[arg(long, value_name = "auto|strict|gl", default_value = "auto")]
    gpu: String,
}

pub(crate) const EPSILONS: [f32; 5] = [0.5, 1.0, 2.0, 4.0, 8.0];

/// The benchmark terrains: shared file, spacing and height scale overrides (PNG needs both).
const TERRAINS: [(&str, Option<f32>, Option<f32>); 3] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
];

/// One (terrain, epsilon, estimator) of the LOD measurement.
#[derive(Clone, Debug)]
pub(crate) struct LodResult {
    pub(crate) terrain: String,
    pub(crate) epsilon: f32,
    pub(crate) mode: LodMode,
    pub(crate) acc: Acc,
}

/// Sums over the frames of one (terrain, epsilon, mode).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Acc {
    frames: u32,
    pub(crate) triangles: f64,
    pub(crate) lod_us: f64,
    pub(crate) render_ms: f64,
    pub(crate) max_error_px: f64,
    /// The largest over the frames of the error on blocks that got their wanted level (not clamped).
    pub(crate) max_error_unclamped_px: f64,
    pub(crate) frames_over: u32,
    pub(crate) rmse: f64,
    pub(crate) clamped: f64,
}

pub(crate) fn run(args: &BenchArgs) -> Result<()> {
    match &args.what {
        BenchWhat::Lod(a) => run_lod(a),
        BenchWhat::All(a) => super::bench_all::run(a),
        BenchWhat::Shading(a) => {
            let report = run_shading(a)?;
            outln!("{}", report.markdown);
            outln!(
                "{} configurations measured, {} terrains skipped; wrote {}",
                report.rows.len(),
                report.skipped.len(),
                a.out.join("shading.md").display()
            );
            Ok(())
        }
    }
}

fn run_lod(args: &BenchLodArgs) -> Result<()> {
    let mode: GpuMode = args.gpu.parse()?;
    if args.frames == 0 {
        return Err(Error::Arg {
            arg: "--frames".into(),
            reason: "0: bench at least 1 frame".into(),
        });
    }
    let profile = args.profile.load()?;
    let (w, h) = match &args.size {
        Some(text) => parse_size(text)?,
        None => (profile.view.width, profile.view.height),
    };
    let profile = lod_profile(profile, w, h);
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot create the output folder", e))?;
    let gpu = Gpu::new(mode)?;
    let bar = ProgressBar::new(TERRAINS.len() as u64 * lod_steps(args.frames));
    if let Ok(style) =
        ProgressStyle::with_template("bench lod {bar:30} {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }
    let mut results: Vec<LodResult> = Vec::new();
    let mut skipped = Vec::new();
    for (name, spacing, scale) in TERRAINS {
        let path = clipsat::data_dir().join(name);
        if !path.exists() {
            skipped.push(format!("{name} (missing)"));
            bar.inc(lod_steps(args.frames));
            continue;
        }
        bar.set_message(name);
        let hm = source::load(
            &path,
            &LoadOptions {
                spacing,
                height_scale: scale,
                ..Default::default()
            },
        )?;
        results.extend(measure_lod(&gpu, &profile, name, &hm, args.frames, &bar)?);
    }
    bar.finish_and_clear();
    let md = args.out.join("lod.md");
    let mut text = format!(
        "# clipsat bench lod\n\nProfile {}, {} frames of a figure-8 flight per terrain at {w}x{h}, full update \
         budget. {LOD_TABLE_NOTE}\n\n",
        profile.name, args.frames
    );
    if !skipped.is_empty() {
        text.push_str(&format!("Skipped: {}.\n\n", skipped.join(", ")));
    }
    text.push_str(&lod_table(&results, true));
    std::fs::write(&md, text).map_err(|e| Error::io(&md, "cannot write", e))?;
    let png = args.out.join("lod.png");
    lod_plot(&results, "clipsat bench lod: triangles per frame", &png)?;
    outln!("{}\n{}", md.display(), png.display());
    for png in lod_cost_plots(&results, &args.out)? {
        outln!("{}", png.display());
    }
    Ok(())
}

/// What the LOD table's columns mean (shared by `bench lod` and `bench all`).
pub(crate) const LOD_TABLE_NOTE: &str = "Means per frame, except max screen error (the largest over the frames) \
    and frames over epsilon (measured max screen error > epsilon; `renderer::screen_error`: |H_0 - PL(H_L)| \
    projected at each data sample in the frustum, clamped blocks included). Unclamped max: the same over the \
    blocks drawn at the level they wanted, i.e. the estimator's own error without what the clip margin \
    cannot hold (for distance, every block). LOD time: `Lod::select` alone (0 \
    for distance, which selects nothing). Render time: upload, draw and readback on this machine's GL driver. \
    RMSE: RGB, 0..255, every pixel, against the brute-force render.";

/// The profile the LOD measurements use: `w` x `h` pixels and every frame fully updated (the comparison is
/// about LOD, not the update budget).
pub(crate) fn lod_profile(mut profile: Profile, w: u32, h: u32) -> Profile {
    profile.view.width = w;
    profile.view.height = h;
    profile.budget.update_samples_per_frame = u32::MAX;
    profile
}

/// Progress steps [`measure_lod`] takes for one terrain.
pub(crate) fn lod_steps(frames: u32) -> u64 {
    u64::from(frames) * (EPSILONS.len() * LodMode::ALL.len()) as u64
}

/// Flies `frames` frames of a figure-8 over one terrain and measures every (epsilon, estimator): the one
/// LOD measurement `bench lod` and `bench all` share. `profile` comes from [`lod_profile`].
pub(crate) fn measure_lod(
    gpu: &Gpu,
    profile: &Profile,
    name: &str,
    hm: &Heightmap,
    frames: u32,
    bar: &ProgressBar,
) -> Result<Vec<LodResult>> {
    let (w, h) = (profile.view.width, profile.view.height);
    let mut clipmap = Clipmap::new(hm, profile, ClipmapOptions::default())?;
    let mut r = Renderer::new(gpu, profile, &clipmap)?;
    let mut lod = super::render::lod_for(hm, profile, &clipmap, false)?;
    let mut brute = BruteForce::new(gpu, hm)?;
    let flight = Flight::new(Path::Figure8, 0.004 * hm.extent_m().0.max(1.0), hm)?
        .with_fov_y_deg(f64::from(profile.view.fov_y_deg));
    let mut spare = LodFrame::new_boxed();
    let mut accs = vec![Acc::default(); EPSILONS.len() * LodMode::ALL.len()];
    for f in 0..u64::from(frames) {
        let camera = flight.camera(f);
        clipmap.update(camera.eye)?;
        let truth = brute.render(&camera, w, h)?;
        for (ci, acc) in accs.iter_mut().enumerate() {
            let eps = EPSILONS[ci / LodMode::ALL.len()];
            let mode = LodMode::ALL[ci % LodMode::ALL.len()];
            lod.set_epsilon_px(f64::from(eps));
            let t = Instant::now();
            if mode != LodMode::Distance {
                lod.select(clipmap.frame(), &camera, mode, &mut spare)?;
            }
            let lod_us = t.elapsed().as_secs_f64() * 1e6;
            let opts = FrameOptions {
                lod: mode,
                epsilon_px: Some(eps),
                ..FrameOptions::default()
            };
            if mode != LodMode::Distance && r.lod().is_none() {
                r.set_lod(lod.clone());
            }
            let t = Instant::now();
            let frame = renderer::render_frame(&mut r, &clipmap, &camera, &opts)?;
            let render_ms = t.elapsed().as_secs_f64() * 1e3;
            let err = renderer::screen_error(&r, &clipmap, &camera, &lod);
            acc.frames += 1;
            acc.triangles += frame.stats.triangles as f64;
            acc.lod_us += lod_us;
            acc.render_ms += render_ms;
            acc.max_error_px = acc.max_error_px.max(err.max_px);
            acc.max_error_unclamped_px = acc.max_error_unclamped_px.max(err.max_px_unclamped);
            acc.frames_over += u32::from(err.max_px > f64::from(eps));
            acc.rmse += renderer::image_rmse(&frame.image, &truth.image).unwrap_or(f64::NAN);
            acc.clamped += f64::from(frame.stats.blocks_clamped);
            bar.inc(1);
        }
    }
    Ok(accs
        .into_iter()
        .enumerate()
        .map(|(ci, acc)| LodResult {
            terrain: name.to_string(),
            epsilon: EPSILONS[ci / LodMode::ALL.len()],
            mode: LodMode::ALL[ci % LodMode::ALL.len()],
            acc,
        })
        .collect())
}

/// The LOD results as a Markdown table. With `ratios`, render time is also given as a ratio to distance LOD
/// on the same terrain and epsilon, and LOD time as a ratio to `exact` (baselines measured in the same run).
pub(crate) fn lod_table(results: &[LodResult], ratios: bool) -> String {
    let mut s = String::from(
        "| terrain | epsilon px | LOD | triangles | LOD us | render ms | max screen error px | unclamped max px | \
         frames over eps | blocks clamped | RMSE |",
    );
    if ratios {
        s.push_str(" LOD time / exact | render time / distance |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    } else {
        s.push_str("\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    }
    let base = |r: &LodResult, mode: LodMode| {
        results
            .iter()
            .find(|b| b.terrain == r.terrain && b.epsilon == r.epsilon && b.mode == mode)
            .map(|b| b.acc)
    };
    for r in results {
        let a = &r.acc;
        let n = f64::from(a.frames.max(1));
        s.push_str(&format!(
            "| {} | {} | {} | {:.0} | {:.1} | {:.1} | {:.3} | {:.3} | {:.0} % | {:.1} | {:.2} |",
            r.terrain,
            r.epsilon,
            r.mode,
            a.triangles / n,
            a.lod_us / n,
            a.render_ms / n,
            a.max_error_px,
            a.max_error_unclamped_px,
            100.0 * f64::from(a.frames_over) / n,
            a.clamped / n,
            a.rmse / n,
        ));
        if ratios {
            let lod_ratio = match base(r, LodMode::Exact) {
                Some(b) if r.mode != LodMode::Distance && b.lod_us > 0.0 => {
                    format!("{:.2}", a.lod_us / b.lod_us)
                }
                _ => "-".to_string(),
            };
            let render_ratio = match base(r, LodMode::Distance) {
                Some(b) if b.render_ms > 0.0 => format!("{:.2}", a.render_ms / b.render_ms),
                _ => "-".to_string(),
            };
            s.push_str(&format!(" {lod_ratio} | {render_ratio} |"));
        }
        s.push('\n');
    }
    s
}

/// Plots triangles per frame against epsilon, one line per (terrain, estimator).
/// What accuracy costs in time: per terrain, render ms per frame against the measured max screen error, one
/// line per estimator through epsilon 0.5 .. 8. Writes `lod-time-<terrain>.png` files and returns them.
pub(crate) fn lod_cost_plots(results: &[LodResult], dir: &std::path::Path) -> Result<Vec<PathBuf>> {
    let mut names: Vec<&str> = results.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    let mut out = Vec::new();
    for name in names {
        let series = LodMode::ALL
            .iter()
            .zip(MODE_COLORS)
            .map(|(mode, color)| Series {
                name: mode.to_string(),
                points: results
                    .iter()
                    .filter(|r| r.terrain == name && r.mode == *mode)
                    .map(|r| {
                        let n = f64::from(r.acc.frames.max(1));
                        (r.acc.max_error_px, r.acc.render_ms / n)
                    })
                    .collect(),
                color,
                right_axis: false,
            })
            .collect();
        let short = name.split(['_', '.']).next().unwrap_or(name);
        let png = dir.join(format!("lod-time-{short}.png"));
        LinePlot {
            title: format!("{name}: time against measured error, epsilon 0.5 .. 8"),
            x_label: "max screen error (px)".into(),
            y_label: "render ms / frame".into(),
            y2_label: String::new(),
            x_log: true,
            series,
        }
        .write_png(&png, 960, 600)?;
        out.push(png);
    }
    Ok(out)
}

/// Plot colour per entry of [`LodMode::ALL`].
const MODE_COLORS: [[u8; 3]; 4] = [
    [120, 120, 120],
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
];

pub(crate) fn lod_plot(results: &[LodResult], title: &str, out: &std::path::Path) -> Result<()> {
    let mut series = Vec::new();
    let mut names: Vec<&str> = results.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    for name in names {
        for (mi, mode) in LodMode::ALL.iter().enumerate() {
            let points = results
                .iter()
                .filter(|r| r.terrain == name && r.mode == *mode)
                .map(|r| {
                    (
                        f64::from(r.epsilon),
                        r.acc.triangles / f64::from(r.acc.frames.max(1)),
                    )
                })
                .collect();
            let short = name.split(['_', '.']).next().unwrap_or(name);
            series.push(Series {
                name: format!("{short} {mode}"),
                points,
                color: MODE_COLORS[mi],
                right_axis: false,
            });
        }
    }
    LinePlot {
        title: title.into(),
        x_label: "epsilon (px)".into(),
        y_label: "triangles".into(),
        y2_label: String::new(),
        x_log: true,
        series,
    }
    .write_png(out, 960, 600)
}

pub(crate) fn parse_size(text: &str) -> Result<(u32, u32)> {
    let bad = || Error::Arg {
        arg: "--size".into(),
        reason: format!("`{text}` is not WxH pixels (1..=2048 each)"),
    };
    let (a, b) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let p = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=2048).contains(v))
            .ok_or_else(bad)
    };
    Ok((p(a)?, p(b)?))
}

/// The effect sets of `bench shading`, cumulative: (label, visibility, specular).
const SHADING_EFFECTS: [(&str, bool, bool); 3] = [
    ("diffuse", false, false),
    ("+visibility", true, false),
    ("+specular", true, true),
];

/// One measured configuration of `bench shading`.
#[derive(Clone, Debug)]
pub(crate) struct ShadingRow {
    pub(crate) terrain: String,
    pub(crate) patches: clipsat::shading::Patches,
    pub(crate) effects: &'static str,
    pub(crate) ms: f64,
    pub(crate) basic_ms: f64,
    pub(crate) rmse: f64,
    pub(crate) max: f64,
    pub(crate) pixels: usize,
}

/// What `bench shading` measured: the rows, the terrains skipped and the Markdown written.
#[derive(Clone, Debug)]
pub(crate) struct ShadingReport {
    pub(crate) rows: Vec<ShadingRow>,
    pub(crate) skipped: Vec<String>,
    pub(crate) markdown: String,
}

/// Mean ms of `frames` renders (after one untimed warm-up: shader compilation).
fn time_frames(
    r: &mut Renderer<'_>,
    clipmap: &Clipmap,
    camera: &clipsat::Camera,
    frames: u32,
) -> Result<(f64, clipsat::gpu::readback::Image)> {
    let opts = FrameOptions::default();
    let mut image = renderer::render_frame(r, clipmap, camera, &opts)?.image;
    let t0 = Instant::now();
    for _ in 0..frames {
        image = renderer::render_frame(r, clipmap, camera, &opts)?.image;
    }
    Ok((t0.elapsed().as_secs_f64() * 1e3 / f64::from(frames), image))
}

/// `clipsat bench shading`: the procedural terrain, Puget Sound and Big Tujunga (a missing file is skipped
/// with a printed reason; under CI=true it is an error), one view each (the default camera), the evening
/// scene without fog. Writes DIR/shading.md and DIR/shading.png and returns the report.
pub(crate) fn run_shading(args: &BenchShadingArgs) -> Result<ShadingReport> {
    let mode: GpuMode = args.gpu.parse()?;
    let size = parse_size(&args.size)?;
    if args.frames == 0 {
        return Err(Error::Arg {
            arg: "--frames".into(),
            reason: "0: bench at least 1 frame".into(),
        });
    }
    let profile = args.profile.load()?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot create the output folder", e))?;
    let gpu = Gpu::new(mode)?;
    let (terrains, skipped) = shading_terrains(true)?;
    let bar = ProgressBar::new(shading_steps(terrains.len()));
    if let Ok(style) =
        ProgressStyle::with_template("bench shading {bar:30} {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }
    let rows = measure_shading(&gpu, &profile, &terrains, size, args.frames, &bar)?;
    bar.finish_and_clear();
    let md = shading_markdown(&rows, &skipped, &gpu, &profile, size, args.frames);
    let md_path = args.out.join("shading.md");
    std::fs::write(&md_path, &md).map_err(|e| Error::io(&md_path, "cannot write", e))?;
    shading_plot(&rows, &args.out.join("shading.png"))?;
    Ok(ShadingReport {
        rows,
        skipped,
        markdown: md,
    })
}

/// Named terrains to measure, and the names of those skipped because their file is missing.
pub(crate) type NamedTerrains = (Vec<(String, Heightmap)>, Vec<String>);

/// The terrains `bench shading` measures: the 257 x 257 procedural terrain, then (when `shared`) Puget
/// Sound and Big Tujunga. A missing shared file is skipped with a printed reason, or an error under
/// CI=true. Returns the terrains and the names skipped.
pub(crate) fn shading_terrains(shared: bool) -> Result<NamedTerrains> {
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    let mut terrains = vec![(
        "procedural-257".to_string(),
        source::procedural::generate(&source::procedural::ProceduralParams {
            size: 257,
            ..Default::default()
        })?,
    )];
    let mut skipped = Vec::new();
    if !shared {
        return Ok((terrains, skipped));
    }
    for (name, spacing, scale) in [TERRAINS[0], TERRAINS[2]] {
        let path = clipsat::data_dir().join(name);
        if !path.exists() {
            if ci {
                return Err(Error::Arg {
                    arg: "bench shading".into(),
                    reason: format!("{} is missing (CI=true)", path.display()),
                });
            }
            eprintln!(
                "bench shading: skipping {name}: {} is missing",
                path.display()
            );
            skipped.push(name.to_string());
            continue;
        }
        let hm = source::load(
            &path,
            &LoadOptions {
                spacing,
                height_scale: scale,
                ..Default::default()
            },
        )?;
        terrains.push((name.to_string(), hm));
    }
    Ok((terrains, skipped))
}

/// Progress steps of [`measure_shading`] over `terrains` terrains.
pub(crate) fn shading_steps(terrains: usize) -> u64 {
    (terrains * SHADING_EFFECTS.len() * clipsat::shading::Patches::ALL.len()) as u64
}

/// Measures every (terrain, effects, patches) at `size`: ms per frame against basic shading in the same
/// run, and the error against the CPU reference.
pub(crate) fn measure_shading(
    gpu: &Gpu,
    profile: &Profile,
    terrains: &[(String, Heightmap)],
    (w, h): (u32, u32),
    frames: u32,
    bar: &ProgressBar,
) -> Result<Vec<ShadingRow>> {
    use clipsat::gpu::sat_textures::ShadingBake;
    use clipsat::scene::{Needs, Scene};
    use clipsat::shading::Patches;

    let mut profile = profile.clone();
    profile.view.width = w;
    profile.view.height = h;
    let mut base = Scene::load("evening")?;
    base.effects.fog = false;
    base.fog = None;
    let max_side = gpu.device().limits().max_texture_dimension_2d;
    let mut rows = Vec::new();
    for (name, hm) in terrains {
        bar.set_message(format!("shading {name}"));
        let camera = clipsat::Camera::default_for(hm)?;
        let mut clipmap = Clipmap::new(hm, &profile, ClipmapOptions::default())?;
        // Fill every level at the eye.
        for _ in 0..10_000 {
            let frame = clipmap.update(camera.eye)?;
            if frame.stale_levels == 0 && clipmap.pending_samples(camera.eye) == 0 {
                break;
            }
        }
        let mut r = Renderer::new(gpu, &profile, &clipmap)?;
        let (basic_ms, _) = time_frames(&mut r, &clipmap, &camera, frames)?;
        let bake_vis = ShadingBake::bake(
            hm,
            &Needs {
                bake_horizons: true,
                ..Needs::default()
            },
            clipsat::horizon::DEFAULT_AZIMUTHS,
            max_side,
        )?;
        let bake_plain = ShadingBake::bake(hm, &Needs::default(), 8, max_side)?;
        for (label, vis, spec) in SHADING_EFFECTS {
            let mut scene = base.clone();
            scene.effects.visibility = vis;
            scene.effects.specular = spec;
            let reference = super::sg::reference(hm, &camera, (w, h), &scene);
            for patches in Patches::ALL {
                let bake = if vis { &bake_vis } else { &bake_plain };
                r.set_sg_baked(hm, &scene, patches, bake)?;
                let (ms, image) = time_frames(&mut r, &clipmap, &camera, frames)?;
                let e = reference.error(&image, super::sg::sky_rgba8());
                rows.push(ShadingRow {
                    terrain: name.clone(),
                    patches,
                    effects: label,
                    ms,
                    basic_ms,
                    rmse: e.rmse,
                    max: e.max,
                    pixels: e.pixels,
                });
                bar.inc(1);
            }
        }
    }
    Ok(rows)
}

/// The Markdown table of [`measure_shading`]'s rows, with what was measured and how.
pub(crate) fn shading_markdown(
    rows: &[ShadingRow],
    skipped: &[String],
    gpu: &Gpu,
    profile: &Profile,
    (w, h): (u32, u32),
    frames: u32,
) -> String {
    let mut md = format!(
        "# clipsat bench shading\n\nSG shading on {}, {w}x{h}, profile {}, the evening scene \
         without fog, default camera; ms per frame (upload + draw + readback, mean of {frames} after a \
         warm-up) and its ratio to basic shading in the same run; RMSE and max error (display-encoded, \
         0..1) against the CPU reference (`shading::reference`: ray-cast hit, exact footprint normals, \
         horizons marched at 64 azimuths, 96 x 192 quadrature) on a {g} x {g} pixel grid.\n\n\
         | terrain | patches | effects | ms | x basic | RMSE | max error | pixels |\n\
         |---|---|---|---|---|---|---|---|\n",
        gpu.report().name,
        profile.name,
        g = super::sg::REF_GRID,
    );
    for row in rows {
        md.push_str(&format!(
            "| {} | {} | {} | {:.1} | {:.2} | {:.4} | {:.4} | {} |\n",
            row.terrain,
            row.patches.label(),
            row.effects,
            row.ms,
            row.ms / row.basic_ms.max(1e-9),
            row.rmse,
            row.max,
            row.pixels
        ));
    }
    if !skipped.is_empty() {
        md.push_str(&format!("\nSkipped (missing): {}\n", skipped.join(", ")));
    }
    md
}

/// RMSE against time per frame (as a multiple of basic shading), one line per (terrain, effects) through
/// the patch counts.
pub(crate) fn shading_plot(rows: &[ShadingRow], path: &std::path::Path) -> Result<()> {
    let colours = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [127, 127, 127],
        [188, 189, 34],
    ];
    let mut names: Vec<&str> = rows.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    let mut series = Vec::new();
    for name in names {
        for (label, _, _) in SHADING_EFFECTS {
            let points = rows
                .iter()
                .filter(|r| r.terrain == name && r.effects == label)
                .map(|r| (r.ms / r.basic_ms.max(1e-9), r.rmse))
                .collect();
            series.push(Series {
                name: format!("{name} {label}"),
                points,
                color: colours[series.len() % colours.len()],
                right_axis: false,
            });
        }
    }
    LinePlot {
        title: "clipsat bench shading: 2x4, 4x8, 8x16 patches".into(),
        x_label: "time per frame / basic shading".into(),
        y_label: "RMSE vs CPU reference".into(),
        y2_label: String::new(),
        x_log: false,
        series,
    }
    .write_png(path, 960, 600)
}
