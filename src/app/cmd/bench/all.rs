//! `clipsat bench all`: one report of what accuracy costs (LOD, shading, update budget, memory) on the
//! procedural terrain and every shared terrain present, as DIR/report.md with PNG plots beside it. A
//! measurement tool: it allocates freely and reads the wall clock (its timings are not part of any hash).

use std::fmt::Write as _;
use std::path::{Path as FsPath, PathBuf};
use std::time::Instant;

use crate::app::cmd::sg::RefQuality;
use clap::Args;
use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::Gpu;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::shading::Patches;
use clipsat::source::procedural::{self, ProceduralParams};
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use clipsat::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::budget::{self, BudgetRow};
use super::common::{mib, SHARED};
use super::plan::{self, PlanRow, PlanRun};
use super::{lod, memory, shading};
use crate::app::cmd::args::GpuArgs;
use crate::app::cmd::ProfileArgs;
use lod::LodResult;

#[derive(Args, Debug)]
pub(crate) struct BenchAllArgs {
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output folder for report.md and its PNG plots.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// A small run for tests: the procedural terrain only (257 x 257), one LOD frame, small images, a coarse
    /// shading reference (8^2 pixels, 32 x 64 directions).
    #[arg(long)]
    quick: bool,
    #[command(flatten)]
    gpu: GpuArgs,
}

/// Flight speeds of the budget section, as multiples of the speed the update budget sustains.
const SPEEDS_FULL: [f64; 7] = [0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0];
const SPEEDS_QUICK: [f64; 4] = [0.25, 1.0, 4.0, 16.0];

/// How big a run is.
struct Plan {
    procedural: ProceduralParams,
    shared: bool,
    lod_frames: u32,
    size: (u32, u32),
    speeds: &'static [f64],
    fly_frames: u64,
    /// Image size and timed frames of the shading section.
    shading_size: (u32, u32),
    shading_frames: u32,
    /// How finely the shading section's CPU reference samples.
    shading_ref: RefQuality,
    /// The patch counts the shading section compares (every one builds its own SG renderer).
    shading_patches: &'static [Patches],
    /// The plan-time section's flights.
    plan_run: PlanRun,
}

impl Plan {
    fn new(quick: bool) -> Self {
        if quick {
            Self {
                procedural: ProceduralParams {
                    size: 257,
                    ..ProceduralParams::default()
                },
                shared: false,
                lod_frames: 1,
                size: (160, 90),
                speeds: &SPEEDS_QUICK,
                fly_frames: 24,
                shading_size: (160, 90),
                shading_frames: 1,
                shading_ref: RefQuality::QUICK,
                shading_patches: &[Patches::P4x8],
                plan_run: PlanRun {
                    frames: 24,
                    error_every: 12,
                },
            }
        } else {
            Self {
                procedural: ProceduralParams::default(),
                shared: true,
                lod_frames: 12,
                size: (320, 180),
                speeds: &SPEEDS_FULL,
                fly_frames: 300,
                shading_size: (320, 180),
                shading_frames: 3,
                shading_ref: RefQuality::FULL,
                shading_patches: &Patches::ALL,
                plan_run: PlanRun {
                    frames: 200,
                    error_every: 20,
                },
            }
        }
    }
}

/// The machine and adapter every figure states.
struct Machine {
    cpu: String,
    cores: usize,
    adapter: String,
}

impl Machine {
    fn detect(gpu: &Gpu) -> Self {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|t| {
                t.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, v)| v.trim().to_string())
            })
            .unwrap_or_else(|| "unknown CPU".to_string());
        let cores = std::thread::available_parallelism().map_or(1, usize::from);
        let r = gpu.report();
        Self {
            cpu,
            cores,
            adapter: format!("{} ({}, {} {})", r.name, r.driver, r.backend, r.mode),
        }
    }

    fn line(&self) -> String {
        format!(
            "Measured on {}, {} cores available; adapter {}.",
            self.cpu, self.cores, self.adapter
        )
    }
}

/// One profile of the memory section.
struct MemoryRow {
    profile: String,
    budget: u64,
    footprint: clipsat::profile::Footprint,
    ledger: u64,
    objects: usize,
    peak_rss: Option<u64>,
}

pub(crate) fn run(args: &BenchAllArgs) -> Result<()> {
    let plan = Plan::new(args.quick);
    let mode = args.gpu.mode();
    let profile = args.profile.load()?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot create the output folder", e))?;
    let gpu = Gpu::new(mode)?;
    let machine = Machine::detect(&gpu);

    let mut terrains: Vec<(String, Heightmap)> = vec![(
        format!("procedural-{}", plan.procedural.size),
        procedural::generate(&plan.procedural)?,
    )];
    // How a child `render` loads each terrain (the memory section's peak RSS).
    let mut specs: Vec<memory::TerrainSpec> = vec![(
        terrains[0].0.clone(),
        vec![
            "--terrain".into(),
            format!(
                "procedural:seed={},size={},spacing={}",
                plan.procedural.seed, plan.procedural.size, plan.procedural.spacing
            ),
        ],
    )];
    let mut skipped = Vec::new();
    if plan.shared {
        for (name, spacing, scale) in SHARED {
            let path = clipsat::data_dir().join(name);
            if !path.exists() {
                outln!("skip {name}: not in {}", clipsat::data_dir().display());
                skipped.push(format!("{name} (missing)"));
                continue;
            }
            let opts = LoadOptions {
                spacing,
                height_scale: scale,
                ..Default::default()
            };
            terrains.push((name.to_string(), source::load(&path, &opts)?));
            let mut args = vec!["--terrain".to_string(), path.display().to_string()];
            args.extend(spacing.map(|s| format!("--spacing={s}")));
            args.extend(scale.map(|s| format!("--height-scale={s}")));
            specs.push((name.to_string(), args));
        }
    } else {
        outln!("skip the shared terrains: --quick measures the procedural terrain only");
        skipped.push("every shared terrain (--quick)".to_string());
    }

    let (shading_terrains, shading_skipped) = shading::shading_terrains(plan.shared)?;
    let shipped = clipsat::profile::SHIPPED.len() as u64;
    let steps = shipped
        + shading::shading_steps(shading_terrains.len(), plan.shading_patches.len())
        + terrains.len() as u64
            * (lod::lod_steps(plan.lod_frames) + plan.speeds.len() as u64 * plan.fly_frames)
        + memory::steps(terrains.len(), specs.len());
    let bar = ProgressBar::new(steps);
    if let Ok(style) =
        ProgressStyle::with_template("bench all {bar:30} {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }

    let t0 = Instant::now();
    // Memory first: the process peak RSS then grows by one profile at a time.
    bar.set_message("memory");
    let memory = measure_memory(&gpu, &terrains[0].1, plan.size, &bar)?;
    let mut sections = vec![("memory", t0.elapsed().as_secs_f64())];

    let lod_profile = lod::lod_profile(profile.clone(), plan.size.0, plan.size.1);
    let mut lod: Vec<LodResult> = Vec::new();
    for (name, hm) in &terrains {
        bar.set_message(format!("lod {name}"));
        lod.extend(lod::measure_lod(
            &gpu,
            &lod_profile,
            name,
            hm,
            plan.lod_frames,
            &bar,
        )?);
    }

    sections.push(("lod", t0.elapsed().as_secs_f64()));
    let shading = shading::measure_shading(
        &gpu,
        &profile,
        &shading_terrains,
        &shading::ShadingRun {
            size: plan.shading_size,
            frames: plan.shading_frames,
            quality: plan.shading_ref,
            patches: plan.shading_patches,
        },
        &bar,
    )?;

    sections.push(("shading", t0.elapsed().as_secs_f64()));
    let mut budget = Vec::new();
    for (name, hm) in &terrains {
        bar.set_message(format!("budget {name}"));
        budget.extend(budget::measure_budget(
            &profile,
            name,
            hm,
            (plan.speeds, plan.fly_frames),
            &bar,
        )?);
    }
    sections.push(("budget", t0.elapsed().as_secs_f64()));
    let mut plan_rows = Vec::new();
    for (name, hm) in &terrains {
        for eps in [1.0, 2.0, 4.0] {
            bar.set_message(format!("plan time {name} {eps} px"));
            plan_rows.push(plan::measure_plan(&profile, name, hm, eps, &plan.plan_run)?);
        }
    }
    sections.push(("plan time", t0.elapsed().as_secs_f64()));
    let scratch = memory::scratch(&args.out)?;
    let terrain_memory = memory::measure(
        &terrains,
        &specs,
        &args.profile.profile,
        plan.size,
        if args.quick { 1 } else { 3 },
        &scratch,
        &bar,
    )?;
    let _ = std::fs::remove_dir_all(&scratch);
    bar.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    sections.push(("terrain memory", wall_s));

    let out = &args.out;
    let mut md = String::new();
    let _ = writeln!(md, "# clipsat bench all\n");
    let _ = writeln!(
        md,
        "{}\n\nProfile {} ({} run). Terrains: {}.{} The whole run took {wall_s:.0} s; every timing below \
         is also given as a ratio to a baseline measured in the same run, which carries across machines \
         better than milliseconds do.\n",
        machine.line(),
        profile.name,
        if args.quick { "--quick" } else { "full" },
        terrains
            .iter()
            .map(|(n, hm)| format!("{n} ({} x {})", hm.width(), hm.height()))
            .collect::<Vec<_>>()
            .join(", "),
        if skipped.is_empty() {
            String::new()
        } else {
            format!(" Skipped: {}.", skipped.join(", "))
        },
    );
    // Where the run's time went, section by section (the cumulative marks above, differenced).
    let mut prev = 0.0;
    let spent: Vec<String> = sections
        .iter()
        .map(|&(name, at)| {
            let d = at - prev;
            prev = at;
            format!("{name} {d:.1} s")
        })
        .collect();
    let _ = writeln!(md, "Time per section: {}.\n", spent.join(", "));
    md.push_str(&headline(
        &lod, &shading, &budget, &plan_rows, &memory, &profile,
    ));
    md.push_str(&lod_section(out, &lod, &plan, &machine, &profile)?);
    md.push_str(&shading_section(
        out,
        &shading,
        &shading_skipped,
        &plan,
        &machine,
    )?);
    md.push_str(&budget::budget_section(
        out,
        &budget,
        plan.fly_frames,
        &machine.line(),
        &profile,
    )?);
    md.push_str(&plan::plan_section(
        &plan_rows,
        &profile,
        &machine.line(),
        &plan.plan_run,
    ));
    md.push_str(&memory_section(&memory, &machine));
    md.push_str(&memory::section(
        &terrain_memory,
        &machine.line(),
        profile.budget.cpu_memory_bytes,
    ));
    let report = out.join("report.md");
    std::fs::write(&report, md).map_err(|e| Error::io(&report, "cannot write", e))?;
    outln!("{}", report.display());
    Ok(())
}

/// The headline: SAT against distance LOD at 1 px, SG shading at 4x8 patches, the fastest speed without
/// stale levels, the memory of each profile.
fn headline(
    lod: &[LodResult],
    shading: &[shading::ShadingRow],
    budget: &[BudgetRow],
    plan_rows: &[PlanRow],
    memory: &[MemoryRow],
    p: &Profile,
) -> String {
    let mut s = String::from("## Headline\n\n");
    let mut names: Vec<&str> = lod.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    let find = |t: &str, mode: LodMode| {
        lod.iter()
            .find(|r| r.terrain == t && r.epsilon == 1.0 && r.mode == mode)
    };
    s.push_str(
        "At epsilon = 1 px, per terrain: SAT LOD (`sat`, the paper's estimate) against distance LOD (each ring \
         at its own level), and the measured worst screen error of each: over the whole frame, and over the \
         unclamped blocks only (those drawn at the level they wanted; the rest is what the clip margin \
         cannot hold); and `sat-conservative`'s plan time per frame in a figure-8 flight (p99 and max, ms, \
         the plan-time section below).\n\n| terrain | triangles sat / distance | render time sat / distance | max error px: \
         distance | sat | sat-conservative | exact | unclamped: sat | sat-conservative | exact | plan ms p99 / max |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for t in names {
        let (Some(d), Some(sat), Some(c), Some(x)) = (
            find(t, LodMode::Distance),
            find(t, LodMode::Sat),
            find(t, LodMode::SatConservative),
            find(t, LodMode::Exact),
        ) else {
            continue;
        };
        let time = plan_rows
            .iter()
            .find(|r| r.terrain == t && r.epsilon == 1.0)
            .map_or("-".to_string(), |r| {
                format!("{:.3} / {:.3}", r.wall_ms[1], r.wall_ms[2])
            });
        let _ = writeln!(
            s,
            "| {t} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {time} |",
            sat.acc.triangles / d.acc.triangles.max(1.0),
            sat.acc.render_ms / d.acc.render_ms.max(f64::MIN_POSITIVE),
            d.acc.max_error_px,
            sat.acc.max_error_px,
            c.acc.max_error_px,
            x.acc.max_error_px,
            sat.acc.max_error_unclamped_px,
            c.acc.max_error_unclamped_px,
            x.acc.max_error_unclamped_px,
        );
    }
    let parts: Vec<String> = shading
        .iter()
        .filter(|r| r.patches == clipsat::shading::Patches::P4x8 && r.effects == "+specular")
        .map(|r| {
            format!(
                "{} {:.1}x basic, RMSE {:.4} (model {:.4})",
                r.terrain,
                r.ms / r.basic_ms.max(1e-9),
                r.rmse,
                r.model_rmse
            )
        })
        .collect();
    if !parts.is_empty() {
        let _ = write!(
            s,
            "\nSG shading, 4x8 patches with visibility and specular, time against basic shading and RMSE \
             (0..1) against the CPU reference: {}.\n",
            parts.join(", ")
        );
    }
    let mut names: Vec<&str> = budget.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    let _ = write!(
        s,
        "\nUpdate budget ({} samples/frame, profile {}): the fastest flight with no stale level, as a multiple \
         of the sustained speed v* (see below): ",
        p.budget.update_samples_per_frame, p.name
    );
    let slowest = budget
        .iter()
        .map(|r| r.multiple)
        .fold(f64::INFINITY, f64::min);
    let parts: Vec<String> = names
        .iter()
        .map(|t| {
            let best = budget
                .iter()
                .filter(|r| r.terrain == *t && r.frames_stale == 0)
                .map(|r| r.multiple)
                .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))));
            match best {
                Some(m) => format!("{t} {m}x"),
                None => format!("{t} stale even at the slowest, {}x", slowest),
            }
        })
        .collect();
    s.push_str(&parts.join(", "));
    s.push_str(".\n\nGPU memory (renderer ledger) per shipped profile: ");
    let parts: Vec<String> = memory
        .iter()
        .map(|m| format!("{} {}", m.profile, mib(m.ledger)))
        .collect();
    s.push_str(&parts.join(", "));
    s.push_str(".\n\n");
    s
}

fn lod_section(
    out: &FsPath,
    lod: &[LodResult],
    plan: &Plan,
    machine: &Machine,
    profile: &Profile,
) -> Result<String> {
    let png = "lod.png";
    lod::lod_plot(lod, "LOD: triangles per frame", &out.join(png))?;
    let mut s = String::from("## LOD: triangles, time and error against epsilon\n\n");
    let _ = writeln!(
        s,
        "Profile {}, {} frames of a figure-8 flight per terrain at {}x{} px, full update budget (`bench lod`'s \
         measurement). {} Baselines, per terrain and epsilon in this run: LOD time against `exact` (the max \
         range query), render time against `distance`.\n",
        profile.name,
        plan.lod_frames,
        plan.size.0,
        plan.size.1,
        lod::LOD_TABLE_NOTE
    );
    let _ = writeln!(
        s,
        "![triangles per frame against epsilon]({png})\n\n*Figure: triangles per frame against epsilon, per \
         terrain and estimator. {}*\n",
        machine.line()
    );
    for png in lod::lod_cost_plots(lod, out)? {
        let name = png.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        let _ = writeln!(
            s,
            "![render time against measured error]({name})\n\n*Figure: render ms per frame against the \
             measured max screen error, one line per estimator through epsilon 0.5 .. 8. {}*\n",
            machine.line()
        );
    }
    let _ = writeln!(s, "*Table: {}*\n", machine.line());
    s.push_str(&lod::lod_table(lod, true));
    s.push('\n');
    Ok(s)
}

/// The shading section: SG error against the CPU reference and cost against basic shading, per patch
/// count and effect set (`bench shading`'s measurement).
fn shading_section(
    out: &FsPath,
    rows: &[shading::ShadingRow],
    skipped: &[String],
    plan: &Plan,
    machine: &Machine,
) -> Result<String> {
    let png = "shading.png";
    shading::shading_plot(rows, &out.join(png))?;
    let mut s = String::from("## Shading: error against patch count\n\n");
    let _ = writeln!(
        s,
        "Reduced SG shading (evening scene, no fog, default camera) at {}x{} px, {} timed frame(s) per \
         configuration: ms per frame and its ratio to basic shading measured in the same run (baseline), and \
         RMSE / max error (display-encoded, 0..1) against the CPU reference `shading::reference` on a {g} x \
         {g} pixel grid.{}\n",
        plan.shading_size.0,
        plan.shading_size.1,
        plan.shading_frames,
        if skipped.is_empty() {
            String::new()
        } else {
            format!(" Skipped: {}.", skipped.join(", "))
        },
        g = crate::app::cmd::sg::REF_GRID,
    );
    let _ = writeln!(
        s,
        "![RMSE against time per frame]({png})\n\n*Figure: RMSE against time per frame / basic shading, one \
         line per terrain and effect set through 2x4, 4x8 and 8x16 patches. {}*\n",
        machine.line()
    );
    let _ = writeln!(
        s,
        "*Table: {}*\n\n| terrain | patches | effects | ms | x basic | RMSE | max error |\n\
         |---|---|---|---|---|---|---|",
        machine.line()
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.2} | {:.4} | {:.4} |",
            r.terrain,
            r.patches.label(),
            r.effects,
            r.ms,
            r.ms / r.basic_ms.max(1e-9),
            r.rmse,
            r.max
        );
    }
    s.push('\n');
    Ok(s)
}

/// Builds each shipped profile's clipmap and renderer on `hm`, renders one frame, and records the profile's
/// planned footprint, the renderer ledger and the process peak RSS after it.
fn measure_memory(
    gpu: &Gpu,
    hm: &Heightmap,
    size: (u32, u32),
    bar: &ProgressBar,
) -> Result<Vec<MemoryRow>> {
    let mut rows = Vec::new();
    for (name, _) in clipsat::profile::SHIPPED {
        let mut p = Profile::load(name)?;
        (p.view.width, p.view.height) = size;
        let mut clipmap = Clipmap::new(hm, &p, ClipmapOptions::default())?;
        let camera = Flight::new(Path::Figure8, 50.0, hm)?
            .with_fov_y_deg(f64::from(p.view.fov_y_deg))
            .camera(0);
        clipmap.update(camera.eye)?;
        let mut r = Offscreen::new(gpu, &p, &clipmap, OffscreenOptions::default())?;
        render_frame(&mut r, &clipmap, &camera, &FrameOptions::default())?;
        rows.push(MemoryRow {
            profile: p.name.clone(),
            budget: p.budget.gpu_memory_bytes,
            footprint: p.footprint(),
            ledger: r.ledger().bytes(),
            objects: r.ledger().count(),
            peak_rss: peak_rss(),
        });
        bar.inc(1);
    }
    Ok(rows)
}

fn memory_section(rows: &[MemoryRow], machine: &Machine) -> String {
    let mut s = String::from("## Memory: peak per profile\n\n");
    let _ = writeln!(
        s,
        "Each shipped profile's clipmap and renderer built on the procedural terrain (viewport shrunk to this \
         run's image size), one frame rendered. Footprint: the profile's planned GPU bytes \
         (`Profile::footprint`); ledger: the bytes the renderer actually created (`Offscreen::ledger`), \
         to compare with the footprint; peak RSS: the process's VmHWM after that profile, so it includes \
         the profiles before it (measured in profile order, first thing in the run).\n\n*Table: {}*\n",
        machine.line()
    );
    s.push_str(
        "| profile | GPU budget | footprint | heights | meshes | targets | uniforms | ledger | objects | \
         process peak RSS |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for m in rows {
        let f = &m.footprint;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            m.profile,
            mib(m.budget),
            mib(f.total()),
            mib(f.heights),
            mib(f.meshes),
            mib(f.targets),
            mib(f.uniforms),
            mib(m.ledger),
            m.objects,
            m.peak_rss.map_or_else(|| "-".to_string(), mib),
        );
    }
    s.push('\n');
    s
}

/// The process's peak resident set (VmHWM in /proc/self/status), bytes; None off Linux.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
