//! `clipsat fly`: the per-frame plan without a GPU. Flies a camera path, updates the clipmap every frame
//! under the profile's budget, checks GC section 5's constraints, and reports per-frame statistics and hashes.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;

use clap::Args;
use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::Gpu;
use clipsat::hash::{hex, Hash64};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame_plan::{LodSetup, PlanParams, Planner};
use clipsat::plan::lod::{Lod, LodMode};
use clipsat::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use super::args::{arg_error, flag, pixel_size, GpuArgs, LodArgs, Size, StreamArgs};
use super::bench::plan::{timed_frame, Settling};
use super::hashes::{self, HashFile};
use super::{ProfileArgs, TerrainArgs};

/// The path flown when none is named.
mod report;

use report::{open_csv, plot, write_row, Stats};

const DEFAULT_PATH: &str = "figure8";

#[derive(Args, Debug)]
pub(crate) struct FlyArgs {
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    #[command(flatten)]
    shading: super::sg::ShadingArgs,
    /// Camera path: straight, circle, figure8, dive, teleport or teleport:K (jump every K frames).
    #[arg(long, value_name = "NAME", default_value = DEFAULT_PATH)]
    path: String,
    /// Speed along the path, metres per frame.
    #[arg(
        long,
        value_name = "M",
        default_value_t = 50.0,
        allow_negative_numbers = true
    )]
    speed: f64,
    /// Frames to fly.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 600,
        allow_negative_numbers = true
    )]
    frames: i64,
    /// Rings finer than the data, synthesised (GC section 8).
    #[arg(long, value_name = "N", default_value_t = 0)]
    synth_levels: u32,
    /// Write one CSV row per frame here.
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    /// Plot samples updated and stale levels against the frame, as PNG.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Print a machine-readable summary on stdout (and no progress bar).
    #[arg(long)]
    json: bool,
    /// Also render every K-th frame (see --render-every) with the clipmap renderer into DIR as PNGs, and
    /// report each one's image hash (DIR/image_hashes.txt, and in --json).
    #[arg(long, value_name = "DIR")]
    render: Option<PathBuf>,
    /// With --render: render frames 0, K, 2K, ...
    #[arg(long, value_name = "K", default_value_t = 10)]
    render_every: u64,
    /// The viewport, WxH pixels: the plan's (SAT LOD measures its error in these pixels) and, with
    /// --render, the images'. Default: the profile's viewport.
    #[arg(long, value_name = "WxH", value_parser = pixel_size)]
    size: Option<Size>,
    #[command(flatten)]
    stream: StreamArgs,
    /// With --render: the GL context.
    #[command(flatten)]
    gpu: GpuArgs,
    /// SAT modes: measure the whole frame's screen error (`render --json`'s measure: every visible data
    /// sample's projected error as drawn) on frames K, 2K, ... of the flight; reads the whole terrain
    /// (selects --resident).
    #[arg(long, value_name = "K")]
    error_every: Option<u64>,
    /// Write every frame's hash here, one `frame<TAB>hash` line each, under a header naming the run.
    #[arg(long, value_name = "FILE")]
    hash_out: Option<PathBuf>,
    /// Fly again and compare every frame's hash with FILE (written by --hash-out for the same run); exit 1
    /// at the first frame that differs.
    #[arg(long, value_name = "FILE")]
    check: Option<PathBuf>,
    #[command(flatten)]
    lod: LodArgs,
}

/// What the statistics keep of one frame.
#[derive(Clone, Copy, Debug)]
struct Row {
    /// Wall time of `Planner::plan`, nanoseconds (measured in the run; the only clock in `fly`).
    plan_ns: u64,
    /// The CPU time this thread spent in it (None without a thread clock): less the time others took.
    plan_cpu_ns: Option<u64>,
    /// Screen-space bounds the plan evaluated (its work, the same on every machine).
    bound_evaluations: u64,
    samples_updated: u32,
    stale_levels: u32,
    disabled_levels: u32,
    /// Triangles drawn: the plan's (SAT LOD's selection, the pool, culling), not the rings' count.
    triangles: u32,
}

pub(crate) fn run(args: &FlyArgs) -> Result<()> {
    let path: Path = args.path.parse().map_err(flag("--path"))?;
    let frames = u64::try_from(args.frames)
        .ok()
        .filter(|&f| f > 0)
        .ok_or_else(|| arg_error("--frames", format!("{}: fly at least 1 frame", args.frames)))?;
    let lod_mode = args.lod.mode();
    let epsilon = args.lod.epsilon;
    let mut profile = args.profile.load()?;
    let sg = args.shading.choice(&profile)?;
    if sg.is_some() && args.render.is_none() {
        return Err(arg_error(
            "--shading",
            "sg shading needs --render DIR (fly simulates without a GPU otherwise)",
        ));
    }
    // Synthesis only when the scene asks for it: an SG scene without `effects.synthesis`
    // gets no synthesised rings, and so no noise table.
    if let Some(choice) = sg.as_ref().filter(|c| !c.scene.effects.synthesis) {
        if args.synth_levels > 0 {
            return Err(arg_error(
                "--synth-levels",
                format!(
                    "scene {} does not declare effects.synthesis",
                    choice.scene.name
                ),
            ));
        }
    }
    // Synthesised rings are a feature the profile affords or not, whatever the shading.
    if args.synth_levels > 0 && !profile.allows(clipsat::profile::Feature::Synthesis) {
        return Err(arg_error(
            "--synth-levels",
            format!(
                "profile `{}` does not allow shading feature \"synthesis\" (it allows {:?})",
                profile.name, profile.shading.features
            ),
        ));
    }
    let opts = ClipmapOptions {
        synth_levels: args.synth_levels,
    };
    // The terrain streams through the profile's tile cache by default (a plain source baked into the
    // cache on first use), rendered or not, as `render` streams it; the camera path follows a coarse
    // level of it. SG's CPU reference reads every sample, so --reference loads it whole, as --resident;
    // so does --synth-levels (the synthesised rings are built from the resident pyramid).
    if args.error_every == Some(0) {
        return Err(arg_error("--error-every", "must be at least 1"));
    }
    if args.error_every.is_some() && lod_mode == LodMode::Distance {
        return Err(arg_error(
            "--error-every",
            "measures a SAT mode's frames (give --lod sat, sat-conservative or exact)",
        ));
    }
    let needs_all = [
        (args.shading.reference, "--reference"),
        (args.synth_levels > 0, "--synth-levels"),
        (args.error_every.is_some(), "--error-every"),
    ]
    .into_iter()
    .find_map(|(on, flag)| on.then_some(flag));
    let stream = args.stream.streams(needs_all)?;
    let (terrain_name, hm, package, imagery) =
        super::render::open_terrain(&args.terrain, stream, !args.json)?;
    let mut colour = super::imagery::FlyColour::new(imagery, &mut profile)?;
    let streamed = package.is_some();
    let mut clipmap = match package {
        Some(p) => Clipmap::streamed(p, &profile, opts)?,
        None => Clipmap::new(&hm, &profile, opts)?,
    };
    let flight = Flight::new(path, args.speed, &hm)
        .map_err(|e| match &e {
            Error::Invalid { what, .. } if what == "flight speed" => flag("--speed")(e),
            _ => flag("--path")(e),
        })?
        .with_fov_y_deg(f64::from(profile.view.fov_y_deg));

    // A streamed clipmap's tables are baked from its package and read through a map.
    let lod = match lod_mode {
        LodMode::Distance => None,
        _ => Some(super::render::lod_for(
            &hm,
            &profile,
            &clipmap,
            sg.is_some(),
            !args.json,
        )?),
    };
    // The mapped tables' resident limit, for the report.
    let table_map = lod.as_ref().and_then(|l| l.tables().mapping.clone());
    // Every frame is planned (the SAT modes' block levels go into the frame hash); the plan is allocated
    // here, once.
    let mut planner = Planner::new(&profile, &clipmap, LodSetup::new(lod_mode, lod)?)?;
    let mut plan = planner.new_plan();
    let plan_params = PlanParams {
        epsilon_px: epsilon,
        // --size is the viewport the plan's LOD measures pixels in, as well as the rendered image's.
        viewport: args.size.map(Size::pair),
        ..PlanParams::default()
    };
    let mut blocks_clamped_max = 0u32;
    // SAT modes: per jump of the path (frame 0 counts as one), the frames until the plan settles.
    let mut settling = Settling::default();
    // --error-every: per sampled frame, (frame, max px, max px over unclamped blocks).
    let mut errors: Vec<(u64, f64, f64)> = Vec::new();
    // The detail pool (SAT modes): samples written per frame (max), and the last frame's state.
    let mut detail_samples_max = 0u64;
    let mut detail_samples_total = 0u64;

    // Every buffer the loop writes to is sized here; the loop itself allocates nothing.
    let mut rows: Vec<Row> = Vec::new();
    let cap = usize::try_from(frames).unwrap_or(usize::MAX);
    rows.try_reserve_exact(cap).map_err(|_| {
        arg_error(
            "--frames",
            format!("{frames}: too many frames to keep statistics for"),
        )
    })?;
    let mut csv = match &args.csv {
        Some(p) => Some((p, open_csv(p, clipmap.levels())?)),
        None => None,
    };
    let progress = if args.json || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let pb = ProgressBar::new(frames);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {per_sec}, eta {eta}")
        {
            pb.set_style(style);
        }
        pb
    };

    // Rendering (optional) reads every image back, so it allocates per rendered frame; the planning above
    // does not.
    let gpu = match &args.render {
        Some(dir) => {
            if args.render_every == 0 {
                return Err(arg_error("--render-every", "must be at least 1"));
            }
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
            Some(Gpu::new(args.gpu.mode())?)
        }
        None => None,
    };
    let mut render_profile = profile.clone();
    if let Some(size) = args.size {
        (render_profile.view.width, render_profile.view.height) = size.pair();
    }
    // A streamed terrain's SG tables are baked from the package level that fits the shading share.
    let package = clipmap
        .tile_cache()
        .map(clipsat::package::TileCache::package);
    let baked = match (&gpu, &sg) {
        (Some(_), Some(sg)) => Some(sg.bake(&profile, &hm, package)?),
        _ => None,
    };
    let shading = super::sg::shading(sg.as_ref(), baked.as_ref());
    // The rendered frames draw the plain geometry clipmap (distance LOD) at the render size.
    let mut renderer = match &gpu {
        Some(gpu) => Some(Offscreen::new(
            gpu,
            &render_profile,
            &clipmap,
            OffscreenOptions {
                shading,
                ..OffscreenOptions::default()
            },
        )?),
        None => None,
    };
    // Samples uploaded per rendered frame (the union of the frames since the last one), and whole-texture
    // refills after the first rendered frame.
    let mut upload_samples_max = 0u64;
    let mut full_uploads = 0u32;
    // Reference errors of the rendered frames (--reference): (sum of squared RMSEs, max error, frames).
    let mut ref_acc = (0.0f64, 0.0f64, 0u32);
    let mut renders: Vec<(u64, u64)> = match &args.render {
        Some(_) => {
            Vec::with_capacity(usize::try_from(frames / args.render_every.max(1) + 1).unwrap_or(0))
        }
        None => Vec::new(),
    };
    // Frame-hash file: the header is checked before flying, the hashes as they come.
    let params = [
        ("terrain", terrain_name.clone()),
        // Streamed heights are the package's (quantised), and the terrain hash is its stand-in's.
        ("streamed", streamed.to_string()),
        ("terrain_hash", hashes::terrain_hash(&hm)),
        ("profile", profile.name.clone()),
        // The profile's values (a TOML may keep a shipped profile's name) and the plan's viewport (SAT
        // LOD measures its pixels): either changes the plans, so a file of another is another run.
        ("profile_hash", hashes::profile_hash(&profile)?),
        (
            "viewport",
            format!(
                "{}x{}",
                render_profile.view.width, render_profile.view.height
            ),
        ),
        ("path", path.to_string()),
        ("speed", args.speed.to_string()),
        ("frames", frames.to_string()),
        ("synth_levels", args.synth_levels.to_string()),
        ("lod", lod_mode.to_string()),
        (
            "epsilon",
            args.lod
                .epsilon
                .map_or_else(|| "profile".to_string(), |e| e.to_string()),
        ),
    ];
    let expected: Option<HashFile> = match &args.check {
        Some(p) => {
            let file = hashes::read(p)?;
            file.check_params(p, &params)?;
            Some(file)
        }
        None => None,
    };
    let mut frame_hashes: Vec<u64> = Vec::new();
    if args.hash_out.is_some() {
        frame_hashes.try_reserve_exact(cap).map_err(|_| {
            arg_error(
                "--frames",
                format!("{frames}: too many frames to keep hashes for"),
            )
        })?;
    }
    let mut mismatch = None;

    let mut run_hash = Hash64::new();
    // Every frame's plan hash (`FramePlan::hash`: uploads, LOD levels, draws, uniforms and pool cells).
    let mut plan_hashes = Hash64::new();
    let mut violations = 0u64;
    let mut final_hash = 0;
    // Largest fill + package decode of one frame, in samples (the decode is 0 for a resident pyramid).
    let mut max_work = 0u32;
    for f in 0..frames {
        let camera = flight.camera(f);
        // The frame's CPU side as `TerrainRenderer::prepare` runs it: update, plan, the pool's requests.
        let (plan_ns, plan_cpu_ns) =
            timed_frame(&mut clipmap, &mut planner, &camera, &plan_params, &mut plan)?;
        if let (Some(k), Some(lod)) = (args.error_every, planner.lod()) {
            // Frames K, 2K, ...: frame 0 draws what one update filled (the flight's start).
            if f > 0 && f % k == 0 {
                let view = plan_params
                    .viewport
                    .unwrap_or((profile.view.width, profile.view.height));
                let e = clipsat::measure::screen_error(&plan, view, &clipmap, &camera, lod);
                errors.push((f, e.max_px, e.max_px_unclamped));
            }
        }
        let frame = clipmap.frame();
        let frame_hash = match lod_mode {
            LodMode::Distance => frame.hash,
            _ => {
                blocks_clamped_max = blocks_clamped_max.max(plan.stats().blocks_clamped);
                settling.frame(f, flight.jumps_at(f), &plan, &clipmap);
                let mut h = Hash64::new();
                h.write_u64(frame.hash);
                plan.lod_frame().hash_into(&mut h);
                plan.detail().hash_into(&mut h);
                h.finish()
            }
        };
        let frame_hash = colour.frame(camera.eye, frame_hash)?;
        if args.hash_out.is_some() {
            frame_hashes.push(frame_hash);
        }
        if let Some(e) = &expected {
            let want = usize::try_from(f).ok().and_then(|i| e.hashes.get(i));
            if want != Some(&frame_hash) {
                mismatch = Some((f, want.copied(), frame_hash));
                break;
            }
        }
        run_hash.write_u64(frame_hash);
        plan_hashes.write_u64(plan.hash());
        final_hash = frame_hash;
        rows.push(Row {
            plan_ns,
            plan_cpu_ns,
            bound_evaluations: plan.stats().bound_evaluations,
            samples_updated: frame.samples_updated,
            stale_levels: frame.stale_levels,
            disabled_levels: frame.disabled_levels,
            triangles: u32::try_from(plan.stats().triangles).unwrap_or(u32::MAX),
        });
        if let Some((p, w)) = &mut csv {
            let last = rows.last().copied();
            write_row(w, frame, last.as_ref(), plan.stats())
                .map_err(|e| Error::io(*p, "cannot write", e))?;
        }
        let updated = rows.last().map_or(0, |r| r.samples_updated);
        let detail = u32::try_from(plan.stats().detail_samples_updated).unwrap_or(u32::MAX);
        detail_samples_max = detail_samples_max.max(u64::from(detail));
        detail_samples_total += u64::from(detail);
        // The pool spends what the fill and decode left of the same budget.
        max_work = max_work.max(updated + clipmap.decoded_samples() + detail);
        if let Err(v) = clipmap.check_constraints() {
            if violations == 0 {
                eprintln!("frame {f}: {v}");
            }
            violations += 1;
        }
        if let (Some(r), Some(dir)) = (&mut renderer, &args.render) {
            if f % args.render_every == 0 {
                let out = render_frame(r, &clipmap, &camera, &FrameOptions::default())?;
                upload_samples_max = upload_samples_max.max(out.stats.upload_samples);
                if out.stats.full_upload && f > 0 {
                    full_uploads += 1;
                }
                out.image.save_png(&dir.join(format!("frame_{f:06}.png")))?;
                renders.push((f, out.image_hash));
                if let (Some(sg), true) = (&sg, args.shading.reference) {
                    let size = (render_profile.view.width, render_profile.view.height);
                    let e = super::sg::reference(&hm, &camera, size, &sg.effective_scene())
                        .error(&out.image, super::sg::sky_rgba8());
                    ref_acc = (
                        ref_acc.0 + e.rmse * e.rmse,
                        ref_acc.1.max(e.max),
                        ref_acc.2 + 1,
                    );
                }
            }
        }
        if f % 64 == 0 {
            progress.set_position(f);
        }
    }
    progress.finish_and_clear();
    if let Some(dir) = &args.render {
        let path = dir.join("image_hashes.txt");
        let mut text = format!(
            "# clipsat fly image hashes: {terrain_name}, profile {}, {path_name} at {} m/frame, {}x{}\n",
            profile.name, args.speed, render_profile.view.width, render_profile.view.height,
            path_name = args.path,
        );
        for (f, h) in &renders {
            text.push_str(&format!("{f}\t{}\n", hex(*h)));
        }
        std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
    }
    if let Some((p, mut w)) = csv {
        w.flush().map_err(|e| Error::io(p, "cannot write", e))?;
    }
    if let Some((f, want, got)) = mismatch {
        // A failed check is a result, not an error in the input: exit 1, as `cmp` and `diff` do (and no
        // partial --hash-out file).
        let want = want.map_or_else(|| "nothing".to_owned(), hex);
        eprintln!("check failed: frame {f}: expected {want}, got {}", hex(got));
        std::process::exit(1);
    }
    if let Some(p) = &args.hash_out {
        hashes::write(p, &params, &frame_hashes)?;
    }

    let budget = profile.budget.update_samples_per_frame;
    let stats = Stats::of(&rows, budget);
    if let Some(p) = &args.plot {
        plot(&rows, budget, &profile.name, path, p)?;
    }
    if args.json {
        let stream = json!({
            "max_fill_plus_decode_samples": max_work,
            "tile_cache": clipmap.tile_cache().map(|c| json!({ "split": c.split(), "stats": c.stats() })),
            "lod_tables": table_map.as_ref().map(clipsat::bake::mapped::Mapping::resident_stats),
        });
        // The detail pool's fields (json! of the whole summary would pass the macro recursion limit).
        let pool = json!({
            "blocks_clamped": plan.stats().blocks_clamped,
            "blocks_from_pool": plan.stats().blocks_from_pool,
            "pool_cells": plan.stats().pool_cells,
            "detail_tiles_resident": plan.stats().detail_tiles_resident,
            "detail_tiles_needed": plan.stats().detail_tiles_needed,
            "detail_samples_updated": detail_samples_total,
            "detail_samples_updated_max": detail_samples_max,
        });
        // The plan's cost per frame, measured in the run (wall time) and counted (bounds evaluated).
        settling.finish();
        let recover = &settling.legs;
        let settled: Vec<u64> = recover.iter().flatten().map(|r| r.0).collect();
        let eps = planner.lod().map(Lod::epsilon_px);
        let screen_error = (!errors.is_empty()).then(|| {
            let most =
                |pick: fn(&(u64, f64, f64)) -> f64| errors.iter().map(pick).fold(0.0, f64::max);
            let over = eps.map_or(0, |e| errors.iter().filter(|r| r.1 > 1.05 * e).count());
            json!({
                "frames": errors.len(),
                "every": args.error_every,
                "max_px": most(|r| r.1),
                "max_px_unclamped": most(|r| r.2),
                "frames_over_1_05_eps": over,
                "per_frame": errors
                    .iter()
                    .map(|&(f, m, u)| json!({ "frame": f, "max_px": m, "max_px_unclamped": u }))
                    .collect::<Vec<_>>(),
            })
        });
        let plan_cost = json!({
            "screen_error_sampled": screen_error,
            "jumps": recover.len(),
            "settle_frames": recover.iter().map(|r| r.map(|r| r.0)).collect::<Vec<_>>(),
            "settle_blocks_clamped": recover.iter().map(|r| r.map(|r| r.1)).collect::<Vec<_>>(),
            "settle_frames_max": settled.iter().max(),
            "jumps_not_settled": recover.iter().filter(|r| r.is_none()).count(),
            "met_frames": settling.met,
            "leg_end_unmet_px": settling.end_unmet_px,
            "unmet_px_max": settling.unmet_px_max,
            "frames_unmet_px_unknown": settling.frames_unmet_unknown,
            "plan_run_hash": hex(plan_hashes.finish()),
            "plan_ms_p50": stats.plan_ns[0] as f64 / 1e6,
            "plan_ms_p99": stats.plan_ns[1] as f64 / 1e6,
            "plan_ms_max": stats.plan_ns[2] as f64 / 1e6,
            "plan_ms_mean": stats.plan_ns_mean / 1e6,
            "plan_cpu_ms_p50": stats.plan_cpu_ns.map(|p| p[0] as f64 / 1e6),
            "plan_cpu_ms_p99": stats.plan_cpu_ns.map(|p| p[1] as f64 / 1e6),
            "plan_cpu_ms_max": stats.plan_cpu_ns.map(|p| p[2] as f64 / 1e6),
            "bound_evaluations_p50": stats.evaluations[0],
            "bound_evaluations_p99": stats.evaluations[1],
            "bound_evaluations_max": stats.evaluations[2],
            "bound_evaluations_mean": stats.evaluations_mean,
        });
        let mut out = json!({
            "stream": stream,
            "terrain": terrain_name,
            "profile": profile.name,
            "path": path.to_string(),
            "speed": args.speed,
            "frames": frames,
            "synth_levels": args.synth_levels,
            "levels": clipmap.levels(),
            "g0_m": clipmap.g0(),
            "budget": budget,
            "lod": lod_mode.to_string(),
            "epsilon_px": planner.lod().map(Lod::epsilon_px),
            "upload_samples_max": renderer.as_ref().map(|_| upload_samples_max),
            "full_uploads_after_first": renderer.as_ref().map(|_| full_uploads),
            "blocks_clamped_max": blocks_clamped_max,
            "final_hash": hex(final_hash),
            "run_hash": hex(run_hash.finish()),
            "frames_over_budget": stats.over_budget,
            "max_stale_levels": stats.max_stale,
            "frames_with_stale_levels": stats.frames_stale,
            "max_disabled_levels": stats.max_disabled,
            "constraint_violations": violations,
            "samples_updated_p50": stats.samples[0],
            "samples_updated_p99": stats.samples[1],
            "samples_updated_max": stats.samples[2],
            "samples_updated_mean": stats.samples_mean,
            "triangles_p50": stats.triangles[0],
            "triangles_max": stats.triangles[2],
            "csv": args.csv.as_ref().map(|p| p.display().to_string()),
            "plot": args.plot.as_ref().map(|p| p.display().to_string()),
            "render_dir": args.render.as_ref().map(|p| p.display().to_string()),
            "renders": renders
                .iter()
                .map(|(f, h)| json!({ "frame": f, "image_hash": hex(*h) }))
                .collect::<Vec<_>>(),
            "shading": if sg.is_some() { "sg" } else { "basic" },
            "scene": sg.as_ref().map(|s| s.scene.name.clone()),
            "patches": sg.as_ref().map(|s| s.patches.label()),
            "bound_textures": renderer.as_ref().map(|r| r.bound_textures().to_vec()),
            "baked": renderer.as_ref().map(|r| r.baked().to_vec()),
            "shading_rmse_vs_reference": (ref_acc.2 > 0)
                .then(|| (ref_acc.0 / f64::from(ref_acc.2)).sqrt()),
            "shading_max_error_vs_reference": (ref_acc.2 > 0).then_some(ref_acc.1),
            "hash_out": args.hash_out.as_ref().map(|p| p.display().to_string()),
            "checked_against": args.check.as_ref().map(|p| p.display().to_string()),
        });
        if let (Some(o), serde_json::Value::Object(cost)) = (out.as_object_mut(), plan_cost) {
            o.extend(cost);
        }
        if let (Some(o), serde_json::Value::Object(extra)) = (out.as_object_mut(), pool) {
            o.extend(extra);
            // Streamed through the tile cache (`stream.tile_cache`), as `render` says it.
            o.insert("streamed".into(), json!(streamed));
        }
        colour.annotate(&mut out);
        super::print_json(&out);
    } else {
        outln!("terrain      {terrain_name}");
        outln!(
            "profile      {} (n {}, {} levels, g0 {} m, budget {budget} samples/frame)",
            profile.name,
            profile.clipmap.n,
            clipmap.levels(),
            clipmap.g0()
        );
        outln!(
            "flight       {path} at {} m/frame, {frames} frames",
            args.speed
        );
        if let Some(c) = clipmap.tile_cache() {
            let (sp, st) = (c.split(), c.stats());
            outln!(
                "streamed     {} tile slots ({:.1} MiB of {:.1}); {} tiles decoded ({} samples), {} hits, \
                 {} evictions, {} refused; fill + decode max {max_work} samples/frame",
                sp.slot_count,
                sp.slots as f64 / 1048576.0,
                sp.budget as f64 / 1048576.0,
                st.decoded,
                st.decoded_samples,
                st.hits,
                st.evictions,
                st.refused
            );
        }
        if let Some(m) = &table_map {
            let r = m.resident_stats();
            outln!(
                "LOD tables   mapped, at most {:.1} MiB of their pages resident ({} trims forced)",
                r.limit_bytes as f64 / 1048576.0,
                r.forced_trims
            );
        }
        outln!("                        p50        p99        max");
        let [a, b, c] = stats.samples;
        outln!("samples      {a:>14} {b:>10} {c:>10}");
        let [a, b, c] = stats.triangles;
        outln!("triangles    {a:>14} {b:>10} {c:>10}");
        let [a, b, c] = stats.plan_ns.map(|v| v as f64 / 1e6);
        outln!("plan ms      {a:>14.3} {b:>10.3} {c:>10.3}");
        if let Some(p) = stats.plan_cpu_ns {
            let [a, b, c] = p.map(|v| v as f64 / 1e6);
            outln!("plan cpu ms  {a:>14.3} {b:>10.3} {c:>10.3}");
        }
        let [a, b, c] = stats.evaluations;
        outln!("bounds       {a:>14} {b:>10} {c:>10}");
        outln!(
            "stale levels max {} ({} frames with any), disabled max {}",
            stats.max_stale,
            stats.frames_stale,
            stats.max_disabled
        );
        outln!(
            "over budget  {} frames; constraint violations {violations}",
            stats.over_budget
        );
        outln!("{}final hash   {}", colour.line(), hex(final_hash));
        if let (Some(dir), Some((f, h))) = (&args.render, renders.last()) {
            outln!(
                "rendered     {} frames into {} (frame {f}: image {})",
                renders.len(),
                dir.display(),
                hex(*h)
            );
        }
        if let Some(p) = &args.check {
            outln!("check        {frames} frames match {}", p.display());
        }
    }
    Ok(())
}
