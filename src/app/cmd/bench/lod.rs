//! `clipsat bench lod`: measures the per-frame LOD stage and the renderer across estimators and error bounds
//! on the shared terrains, and writes a Markdown table and a plot. A measurement tool: it allocates freely
//! and reads the wall clock (its timings are not part of any hash).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use clipsat::gpu::brute::BruteForce;
use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::Gpu;
use clipsat::measure;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame_plan::LodSetup;
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use clipsat::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::common::TERRAINS;
use crate::app::cmd::args::{arg_error, pixel_size, GpuArgs, Size};
use crate::app::cmd::ProfileArgs;
use crate::app::plot::{LinePlot, Series};

#[derive(Args, Debug)]
pub(super) struct BenchLodArgs {
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output folder for lod.md and lod.png.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Frames of a figure-8 flight per terrain.
    #[arg(long, value_name = "N", default_value_t = 12)]
    pub(crate) frames: u32,
    /// Image size, WxH pixels.
    #[arg(long, value_name = "WxH", value_parser = pixel_size)]
    size: Option<Size>,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub(crate) const EPSILONS: [f32; 5] = [0.5, 1.0, 2.0, 4.0, 8.0];

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
    /// Blocks drawn from the detail pool, summed over the frames.
    pub(crate) from_pool: f64,
    /// Detail pool tiles resident, summed over the frames.
    pub(crate) pool_tiles: f64,
}

pub(super) fn run_lod(args: &BenchLodArgs) -> Result<()> {
    let mode = args.gpu.mode();
    if args.frames == 0 {
        return Err(arg_error("--frames", "0: bench at least 1 frame"));
    }
    let profile = args.profile.load()?;
    let (w, h) = match args.size {
        Some(size) => size.pair(),
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
    and frames over epsilon (measured max screen error > epsilon; `measure::screen_error`: |H_0 - PL(H_L)| \
    projected at each data sample in the frustum, clamped blocks included). Unclamped max: the same over the \
    blocks drawn at the level they wanted, i.e. the estimator's own error without what the clip margin \
    cannot hold (for distance, every block). LOD time: the frame plan (`Planner::plan`: selection, culling, uniforms; \
    for distance, which selects nothing). Render time: upload, draw and readback on this machine's GL driver. \
    Blocks from pool / pool tiles: SAT blocks drawn from the detail pool (at their wanted level or a finer \
    one than the rings hold) and the pool's resident tiles (blocks clamped counts those still \
    short of their wanted level). \
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
    let lod = crate::app::cmd::render::lod_for(hm, profile, &clipmap, false, false)?;
    // One renderer per LOD mode (the mode is fixed when a renderer is built).
    let mut renderers = LodMode::ALL
        .iter()
        .map(|&mode| {
            Offscreen::new(
                gpu,
                profile,
                &clipmap,
                OffscreenOptions {
                    lod: LodSetup::new(mode, Some(lod.clone()))?,
                    ..OffscreenOptions::default()
                },
            )
        })
        .collect::<Result<Vec<_>>>()?;
    let mut brute = BruteForce::new(gpu, hm)?;
    let flight = Flight::new(Path::Figure8, 0.004 * hm.extent_m().0.max(1.0), hm)?
        .with_fov_y_deg(f64::from(profile.view.fov_y_deg));
    let mut accs = vec![Acc::default(); EPSILONS.len() * LodMode::ALL.len()];
    for f in 0..u64::from(frames) {
        let camera = flight.camera(f);
        clipmap.update(camera.eye)?;
        let truth = brute.render(&camera, w, h)?;
        for (ci, acc) in accs.iter_mut().enumerate() {
            let eps = EPSILONS[ci / LodMode::ALL.len()];
            let mode = LodMode::ALL[ci % LodMode::ALL.len()];
            let r = &mut renderers[ci % LodMode::ALL.len()];
            debug_assert_eq!(r.lod_mode(), mode);
            let opts = FrameOptions {
                epsilon_px: Some(eps),
                ..FrameOptions::default()
            };
            let t = Instant::now();
            let frame = render_frame(r, &clipmap, &camera, &opts)?;
            let render_ms = t.elapsed().as_secs_f64() * 1e3;
            #[expect(
                clippy::cast_precision_loss,
                reason = "plan times are far below 2^52 ns"
            )]
            let lod_us = frame.stats.plan_ns as f64 * 1e-3;
            let err = measure::screen_error(r.plan(), r.size(), &clipmap, &camera, &lod);
            acc.frames += 1;
            acc.triangles += frame.stats.triangles as f64;
            acc.lod_us += lod_us;
            acc.render_ms += render_ms;
            acc.max_error_px = acc.max_error_px.max(err.max_px);
            acc.max_error_unclamped_px = acc.max_error_unclamped_px.max(err.max_px_unclamped);
            acc.frames_over += u32::from(err.max_px > f64::from(eps));
            acc.rmse += measure::image_rmse(&frame.image, &truth.image).unwrap_or(f64::NAN);
            acc.clamped += f64::from(frame.stats.blocks_clamped);
            acc.from_pool += f64::from(frame.stats.blocks_from_pool);
            acc.pool_tiles += f64::from(frame.stats.detail_tiles_resident);
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
         frames over eps | blocks clamped | blocks from pool | pool tiles | RMSE |",
    );
    if ratios {
        s.push_str(" LOD time / exact | render time / distance |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    } else {
        s.push_str("\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
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
            "| {} | {} | {} | {:.0} | {:.1} | {:.1} | {:.3} | {:.3} | {:.0} % | {:.1} | {:.1} | {:.0} | {:.2} |",
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
            a.from_pool / n,
            a.pool_tiles / n,
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
