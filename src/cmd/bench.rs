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
use clipsat::{Error, Result};
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
    frames: u32,
    /// Image size, WxH pixels; default: the profile's viewport, the size its epsilon is meant for
    /// (screen-space error scales with the image height).
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// GL context: strict, gl or auto.
    #[arg(long, value_name = "auto|strict|gl", default_value = "auto")]
    gpu: String,
}

const EPSILONS: [f32; 5] = [0.5, 1.0, 2.0, 4.0, 8.0];
const MODES: [LodMode; 4] = [
    LodMode::Distance,
    LodMode::Sat,
    LodMode::SatConservative,
    LodMode::Exact,
];

/// Plot colour per entry of [`MODES`].
const MODE_COLORS: [[u8; 3]; 4] = [
    [120, 120, 120],
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
];

/// The benchmark terrains: shared file, spacing and height scale overrides (PNG needs both).
const TERRAINS: [(&str, Option<f32>, Option<f32>); 3] = [
    ("ps_height_1k.png", Some(160.0), Some(0.1)),
    ("n07_w006_3arc_v2.tif", None, None),
    ("srtm_bigtujunga30m_utm11.tif", None, None),
];

/// Sums over the frames of one (terrain, epsilon, mode).
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    frames: u32,
    triangles: f64,
    lod_us: f64,
    render_ms: f64,
    max_error_px: f64,
    frames_over: u32,
    rmse: f64,
    clamped: f64,
}

pub(crate) fn run(args: &BenchArgs) -> Result<()> {
    match &args.what {
        BenchWhat::Lod(a) => run_lod(a),
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
    let mut profile = args.profile.load()?;
    let (w, h) = match &args.size {
        Some(text) => parse_size(text)?,
        None => (profile.view.width, profile.view.height),
    };
    profile.view.width = w;
    profile.view.height = h;
    // Every frame fully updated: the comparison is about LOD, not the update budget.
    profile.budget.update_samples_per_frame = u32::MAX;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot create the output folder", e))?;
    let gpu = Gpu::new(mode)?;
    let configs = (EPSILONS.len() * MODES.len()) as u64;
    let bar = ProgressBar::new(TERRAINS.len() as u64 * u64::from(args.frames) * configs);
    if let Ok(style) =
        ProgressStyle::with_template("bench lod {bar:30} {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }
    let mut results: Vec<(String, f32, LodMode, Acc)> = Vec::new();
    let mut skipped = Vec::new();
    for (name, spacing, scale) in TERRAINS {
        let path = clipsat::data_dir().join(name);
        if !path.exists() {
            skipped.push(format!("{name} (missing)"));
            bar.inc(u64::from(args.frames) * configs);
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
        let mut clipmap = Clipmap::new(&hm, &profile, ClipmapOptions::default())?;
        let mut r = Renderer::new(&gpu, &profile, &clipmap)?;
        let mut lod = super::render::lod_for(&hm, &profile, &clipmap, false)?;
        let mut brute = BruteForce::new(&gpu, &hm)?;
        let flight = Flight::new(Path::Figure8, 0.004 * hm.extent_m().0.max(1.0), &hm)?
            .with_fov_y_deg(f64::from(profile.view.fov_y_deg));
        let mut spare = LodFrame::new_boxed();
        let mut accs = vec![Acc::default(); EPSILONS.len() * MODES.len()];
        for f in 0..u64::from(args.frames) {
            let camera = flight.camera(f);
            clipmap.update(camera.eye)?;
            let truth = brute.render(&camera, w, h)?;
            for (ci, acc) in accs.iter_mut().enumerate() {
                let eps = EPSILONS[ci / MODES.len()];
                let mode = MODES[ci % MODES.len()];
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
                acc.frames_over += u32::from(err.max_px > f64::from(eps));
                acc.rmse += renderer::image_rmse(&frame.image, &truth.image).unwrap_or(f64::NAN);
                acc.clamped += f64::from(frame.stats.blocks_clamped);
                bar.inc(1);
            }
        }
        for (ci, acc) in accs.into_iter().enumerate() {
            results.push((
                name.to_string(),
                EPSILONS[ci / MODES.len()],
                MODES[ci % MODES.len()],
                acc,
            ));
        }
    }
    bar.finish_and_clear();
    let md = args.out.join("lod.md");
    std::fs::write(&md, table(&results, &skipped, args, &profile.name, (w, h)))
        .map_err(|e| Error::io(&md, "cannot write", e))?;
    let png = args.out.join("lod.png");
    plot(&results, &png)?;
    outln!("{}\n{}", md.display(), png.display());
    for png in plot_cost(&results, &args.out)? {
        outln!("{}", png.display());
    }
    Ok(())
}

fn table(
    results: &[(String, f32, LodMode, Acc)],
    skipped: &[String],
    args: &BenchLodArgs,
    profile: &str,
    (w, h): (u32, u32),
) -> String {
    let mut s = format!(
        "# clipsat bench lod\n\nProfile {profile}, {} frames of a figure-8 flight per terrain at {w}x{h}, full update \
         budget. Means per frame, except max screen error (the largest over the frames) and frames over epsilon \
         (measured max screen error > epsilon; `renderer::screen_error`: |H_0 - PL(H_L)| projected at each data \
         sample in the frustum, clamped blocks included). LOD time: `Lod::select` alone (0 for distance, which \
         selects nothing). Render time: upload, draw and readback on this machine's GL driver. RMSE: RGB, \
         0..255, every pixel, against the brute-force render.\n\n",
        args.frames
    );
    if !skipped.is_empty() {
        s.push_str(&format!("Skipped: {}.\n\n", skipped.join(", ")));
    }
    s.push_str(
        "| terrain | epsilon px | LOD | triangles | LOD us | render ms | render / distance | max screen error px | \
         frames over eps | blocks clamped | RMSE |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for (name, eps, mode, a) in results {
        let n = f64::from(a.frames.max(1));
        // The ratio to the distance row of the same terrain and epsilon, measured in the same run.
        let base = results
            .iter()
            .find(|r| r.0 == *name && r.1 == *eps && r.2 == LodMode::Distance)
            .map_or(f64::NAN, |r| r.3.render_ms / f64::from(r.3.frames.max(1)));
        s.push_str(&format!(
            "| {name} | {eps} | {mode} | {:.0} | {:.1} | {:.1} | {:.2} | {:.3} | {:.0} % | {:.1} | {:.2} |\n",
            a.triangles / n,
            a.lod_us / n,
            a.render_ms / n,
            a.render_ms / n / base,
            a.max_error_px,
            100.0 * f64::from(a.frames_over) / n,
            a.clamped / n,
            a.rmse / n,
        ));
    }
    s
}

fn plot(results: &[(String, f32, LodMode, Acc)], out: &std::path::Path) -> Result<()> {
    let mut series = Vec::new();
    let mut names: Vec<&str> = results.iter().map(|r| r.0.as_str()).collect();
    names.dedup();
    for name in names {
        for (mi, mode) in MODES.iter().enumerate() {
            let points = results
                .iter()
                .filter(|r| r.0 == name && r.2 == *mode)
                .map(|r| (f64::from(r.1), r.3.triangles / f64::from(r.3.frames.max(1))))
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
        title: "clipsat bench lod: triangles per frame".into(),
        x_label: "epsilon (px)".into(),
        y_label: "triangles".into(),
        y2_label: String::new(),
        x_log: true,
        series,
    }
    .write_png(out, 960, 600)
}

/// What accuracy costs in time: per terrain, render ms per frame against the measured max screen error, one
/// line per estimator through epsilon 0.5 .. 8 (`lod-time-<terrain>.png`).
fn plot_cost(
    results: &[(String, f32, LodMode, Acc)],
    dir: &std::path::Path,
) -> Result<Vec<PathBuf>> {
    let mut names: Vec<&str> = results.iter().map(|r| r.0.as_str()).collect();
    names.dedup();
    let mut out = Vec::new();
    for name in names {
        let series = MODES
            .iter()
            .zip(MODE_COLORS)
            .map(|(mode, color)| Series {
                name: mode.to_string(),
                points: results
                    .iter()
                    .filter(|r| r.0 == name && r.2 == *mode)
                    .map(|r| {
                        let n = f64::from(r.3.frames.max(1));
                        (r.3.max_error_px, r.3.render_ms / n)
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

fn parse_size(text: &str) -> Result<(u32, u32)> {
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
