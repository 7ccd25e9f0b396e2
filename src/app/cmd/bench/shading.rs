//! `clipsat bench shading`: SG shading against basic shading and the CPU reference, per patch count and
//! effect set. A measurement tool: it allocates freely and reads the wall clock.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::renderer::{SgShading, Shading};
use clipsat::gpu::shaders::SgOmit;
use clipsat::gpu::Gpu;
use clipsat::package::shading_sats::ShadingBake;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::profile::Profile;
use clipsat::shading::scene::{Needs, Scene};
use clipsat::shading::Patches;
use clipsat::source::Heightmap;
use clipsat::source::{self, LoadOptions};
use clipsat::Progress;
use clipsat::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};

use super::common::{SHARED, TERRAINS};
use crate::app::cmd::args::{arg_error, pixel_size, GpuArgs, Size};
use crate::app::cmd::ProfileArgs;
use crate::app::plot::{LinePlot, Series};

#[derive(Args, Debug)]
pub(crate) struct BenchShadingArgs {
    #[command(flatten)]
    profile: ProfileArgs,
    /// Output folder for shading.md and shading.png.
    #[arg(long, value_name = "DIR")]
    pub(super) out: PathBuf,
    /// Timed frames per configuration (after one warm-up frame).
    #[arg(long, value_name = "N", default_value_t = 3)]
    frames: u32,
    /// Image size, WxH pixels.
    #[arg(long, value_name = "WxH", value_parser = pixel_size, default_value = "320x180")]
    size: Size,
    /// Every shared terrain (as `bench all`), not only Puget Sound and Big Tujunga.
    #[arg(long)]
    all_terrains: bool,
    /// Only the terrains whose name contains this (repeatable; e.g. `--terrain N57E011 --terrain ps_`):
    /// for iterating on one terrain.
    #[arg(long = "terrain", value_name = "NAME")]
    only: Vec<String>,
    /// Only the 4 x 8 breakdown and the scenes (noon, evening, overcast), not the patch-count table.
    #[arg(long)]
    breakdown_only: bool,
    /// Print the report as JSON instead of Markdown.
    #[arg(long)]
    pub(super) json: bool,
    #[command(flatten)]
    gpu: GpuArgs,
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
    /// The shading model's part of `rmse` (`sg::RefError::model_rmse`).
    pub(crate) model_rmse: f64,
}

/// What `bench shading` measured: the rows, the per-term breakdown, the terrains skipped and the Markdown
/// written.
#[derive(Clone, Debug)]
pub(crate) struct ShadingReport {
    pub(crate) rows: Vec<ShadingRow>,
    pub(crate) breakdown: Vec<BreakdownRow>,
    pub(crate) skipped: Vec<String>,
    pub(crate) markdown: String,
}

/// One scene rendered at 4 x 8 as shipped (noon, evening with its fog, overcast): ms and error against the
/// CPU reference.
#[derive(Clone, Debug)]
pub(crate) struct SceneRun {
    pub(crate) scene: &'static str,
    pub(crate) ms: f64,
    pub(crate) rmse: f64,
    pub(crate) max: f64,
    /// The shading model's part of `rmse` (`sg::RefError::model_rmse`).
    pub(crate) model_rmse: f64,
}

/// Where the SG fragment time goes on one terrain, at 4 x 8, the evening scene without fog: the time of
/// the full shading, of variants leaving out one term each ([`SgOmit`]), and of the effect sets; all in
/// the same run as basic shading.
#[derive(Clone, Debug)]
pub(crate) struct BreakdownRow {
    pub(crate) terrain: String,
    pub(crate) basic_ms: f64,
    /// Diffuse, +visibility, +specular (the full shading).
    pub(crate) effects_ms: [f64; 3],
    /// The full shading with one term left out, per [`SgOmit::TERMS`].
    pub(crate) omitted_ms: [f64; 3],
    pub(crate) scenes: Vec<SceneRun>,
}

impl BreakdownRow {
    /// Each term's cost in ms: footprint fetch, vMF, light + sky tables (full minus the variant without
    /// it), visibility (+visibility minus diffuse), specular (+specular minus +visibility).
    pub(crate) fn term_ms(&self) -> [(&'static str, f64); 5] {
        let full = self.effects_ms[2];
        [
            (SgOmit::TERMS[0].label(), full - self.omitted_ms[0]),
            (SgOmit::TERMS[1].label(), full - self.omitted_ms[1]),
            (SgOmit::TERMS[2].label(), full - self.omitted_ms[2]),
            ("visibility", self.effects_ms[1] - self.effects_ms[0]),
            ("specular", self.effects_ms[2] - self.effects_ms[1]),
        ]
    }

    /// A scene's time over basic shading's.
    pub(crate) fn ratio(&self, ms: f64) -> f64 {
        ms / self.basic_ms.max(1e-9)
    }
}

/// Mean ms of `frames` renders (after one untimed warm-up: shader compilation).
fn time_frames(
    r: &mut Offscreen<'_>,
    clipmap: &Clipmap,
    camera: &clipsat::plan::camera::Camera,
    frames: u32,
) -> Result<(f64, clipsat::gpu::readback::Image)> {
    let opts = FrameOptions::default();
    let mut image = render_frame(r, clipmap, camera, &opts)?.image;
    let t0 = Instant::now();
    for _ in 0..frames {
        image = render_frame(r, clipmap, camera, &opts)?.image;
    }
    Ok((t0.elapsed().as_secs_f64() * 1e3 / f64::from(frames), image))
}

/// `clipsat bench shading`: the procedural terrain, Puget Sound and Big Tujunga (a missing file is skipped
/// with a printed reason; under CI=true it is an error), one view each (the default camera), the evening
/// scene without fog. Writes DIR/shading.md and DIR/shading.png and returns the report.
pub(crate) fn run_shading(args: &BenchShadingArgs) -> Result<ShadingReport> {
    let mode = args.gpu.mode();
    let size = args.size.pair();
    if args.frames == 0 {
        return Err(arg_error("--frames", "0: bench at least 1 frame"));
    }
    let profile = args.profile.load()?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| Error::io(&args.out, "cannot create the output folder", e))?;
    let gpu = Gpu::new(mode)?;
    let (terrains, skipped) = if args.all_terrains {
        all_shared_terrains()?
    } else {
        shading_terrains(true)?
    };
    let terrains: Vec<(String, Heightmap)> = if args.only.is_empty() {
        terrains
    } else {
        terrains
            .into_iter()
            .filter(|(name, _)| args.only.iter().any(|o| name.contains(o.as_str())))
            .collect()
    };
    if terrains.is_empty() {
        return Err(arg_error("--terrain", "no terrain of this run matches"));
    }
    let matrix_steps = if args.breakdown_only {
        0
    } else {
        shading_steps(terrains.len(), Patches::ALL.len())
    };
    let bar = ProgressBar::new(matrix_steps + breakdown_steps(terrains.len()));
    if let Ok(style) =
        ProgressStyle::with_template("bench shading {bar:30} {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }
    let breakdown = measure_breakdown(&gpu, &profile, &terrains, size, args.frames, &bar)?;
    let rows = if args.breakdown_only {
        Vec::new()
    } else {
        measure_shading(
            &gpu,
            &profile,
            &terrains,
            &ShadingRun {
                size,
                frames: args.frames,
                quality: crate::app::cmd::sg::RefQuality::FULL,
                patches: &Patches::ALL,
            },
            &bar,
        )?
    };
    bar.finish_and_clear();
    let mut md = breakdown_markdown(&breakdown, &gpu, &profile, size, args.frames);
    if !rows.is_empty() {
        md.push('\n');
        md.push_str(&shading_markdown(
            &rows,
            &skipped,
            &gpu,
            &profile,
            size,
            args.frames,
        ));
    }
    let md_path = args.out.join("shading.md");
    std::fs::write(&md_path, &md).map_err(|e| Error::io(&md_path, "cannot write", e))?;
    if !rows.is_empty() {
        shading_plot(&rows, &args.out.join("shading.png"))?;
    }
    Ok(ShadingReport {
        rows,
        breakdown,
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
    let mut out = (
        vec![(
            "procedural-257".to_string(),
            source::procedural::generate(&source::procedural::ProceduralParams {
                size: 257,
                ..Default::default()
            })?,
        )],
        Vec::new(),
    );
    if shared {
        add_shared(&[TERRAINS[0], TERRAINS[2]], &mut out)?;
    }
    Ok(out)
}

/// Loads each of `list` (file, spacing and height scale overrides) from the shared data folder into `out`;
/// a missing file is skipped with a printed reason, or an error under CI=true.
fn add_shared(list: &[(&str, Option<f32>, Option<f32>)], out: &mut NamedTerrains) -> Result<()> {
    let ci = std::env::var("CI").is_ok_and(|v| v == "true");
    for &(name, spacing, scale) in list {
        let path = clipsat::data_dir().join(name);
        if !path.exists() {
            if ci {
                return Err(arg_error(
                    "bench shading",
                    format!("{} is missing (CI=true)", path.display()),
                ));
            }
            eprintln!(
                "bench shading: skipping {name}: {} is missing",
                path.display()
            );
            out.1.push(name.to_string());
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
        out.0.push((name.to_string(), hm));
    }
    Ok(())
}

/// Progress steps of [`measure_shading`] over `terrains` terrains.
pub(crate) fn shading_steps(terrains: usize, patches: usize) -> u64 {
    (terrains * SHADING_EFFECTS.len() * patches) as u64
}

/// What one shading measurement covers: image size, timed frames per configuration, the CPU
/// reference's sampling, and the patch counts compared (each builds its own SG renderer).
pub(crate) struct ShadingRun<'a> {
    pub(crate) size: (u32, u32),
    pub(crate) frames: u32,
    pub(crate) quality: crate::app::cmd::sg::RefQuality,
    pub(crate) patches: &'a [Patches],
}

/// Measures every (terrain, effects, patches) at `size`: ms per frame against basic shading in the same
/// run, and the error against the CPU reference.
pub(crate) fn measure_shading(
    gpu: &Gpu,
    profile: &Profile,
    terrains: &[(String, Heightmap)],
    run: &ShadingRun<'_>,
    bar: &ProgressBar,
) -> Result<Vec<ShadingRow>> {
    let (w, h) = run.size;
    let (frames, quality) = (run.frames, run.quality);
    let mut profile = profile.clone();
    profile.view.width = w;
    profile.view.height = h;
    let mut base = Scene::load("evening")?;
    base.effects.fog = false;
    base.fog = None;
    // The grid the bench always measured on (a 2048-texel side at most), whatever the profile's shading
    // share: it compares the shading model, not the budget.
    let max_side = clipsat::package::shading_sats::grid_bytes(
        2047,
        2047,
        clipsat::bake::horizon::DEFAULT_AZIMUTHS,
    );
    let mut rows = Vec::new();
    for (name, hm) in terrains {
        bar.set_message(format!("shading {name}"));
        let camera = clipsat::plan::camera::Camera::default_for(hm)?;
        let mut clipmap = Clipmap::new(hm, &profile, ClipmapOptions::default())?;
        // Fill every level at the eye.
        clipmap.fill_at(camera.eye, 10_000)?;
        let mut r = Offscreen::new(gpu, &profile, &clipmap, OffscreenOptions::default())?;
        let (basic_ms, _) = time_frames(&mut r, &clipmap, &camera, frames)?;
        drop(r);
        let bake_vis = ShadingBake::bake(
            hm,
            &Needs {
                bake_horizons: true,
                ..Needs::default()
            },
            clipsat::bake::horizon::DEFAULT_AZIMUTHS,
            max_side,
            Progress::default(),
        )?;
        let bake_plain =
            ShadingBake::bake(hm, &Needs::default(), 8, max_side, Progress::default())?;
        for (label, vis, spec) in SHADING_EFFECTS {
            let mut scene = base.clone();
            scene.effects.visibility = vis;
            scene.effects.specular = spec;
            let reference = crate::app::cmd::sg::reference_at(hm, &camera, (w, h), &scene, quality);
            for &patches in run.patches {
                let bake = if vis { &bake_vis } else { &bake_plain };
                let mut r = Offscreen::new(
                    gpu,
                    &profile,
                    &clipmap,
                    OffscreenOptions {
                        shading: Shading::Sg(SgShading {
                            scene: &scene,
                            patches,
                            bake,
                            omit: SgOmit::None,
                        }),
                        ..OffscreenOptions::default()
                    },
                )?;
                let (ms, image) = time_frames(&mut r, &clipmap, &camera, frames)?;
                let e = reference.error(&image, crate::app::cmd::sg::sky_rgba8());
                rows.push(ShadingRow {
                    terrain: name.clone(),
                    patches,
                    effects: label,
                    ms,
                    basic_ms,
                    rmse: e.rmse,
                    max: e.max,
                    pixels: e.pixels,
                    model_rmse: e.model_rmse,
                });
                bar.inc(1);
            }
        }
    }
    Ok(rows)
}

/// The shared terrains of `bench all` (each present one; a missing one is skipped, or an error under
/// CI=true), after the procedural terrain.
fn all_shared_terrains() -> Result<NamedTerrains> {
    let mut out = shading_terrains(false)?;
    add_shared(&SHARED, &mut out)?;
    Ok(out)
}

/// The scenes of the breakdown, as shipped.
const SCENES: [&str; 3] = ["noon", "evening", "overcast"];

/// Progress steps of [`measure_breakdown`] over `terrains` terrains.
pub(crate) fn breakdown_steps(terrains: usize) -> u64 {
    (terrains * (1 + SHADING_EFFECTS.len() + SgOmit::TERMS.len() + SCENES.len())) as u64
}

/// Fills every level of a clipmap at the camera's eye.
fn filled_clipmap(
    hm: &Heightmap,
    profile: &Profile,
    camera: &clipsat::plan::camera::Camera,
) -> Result<Clipmap> {
    let mut clipmap = Clipmap::new(hm, profile, ClipmapOptions::default())?;
    clipmap.fill_at(camera.eye, 10_000)?;
    Ok(clipmap)
}

/// One SG configuration's ms per frame and image.
#[expect(clippy::too_many_arguments, reason = "one configuration of the bench")]
fn time_sg(
    gpu: &Gpu,
    profile: &Profile,
    clipmap: &Clipmap,
    camera: &clipsat::plan::camera::Camera,
    scene: &Scene,
    bake: &ShadingBake,
    omit: SgOmit,
    frames: u32,
) -> Result<(f64, clipsat::gpu::readback::Image)> {
    let mut r = Offscreen::new(
        gpu,
        profile,
        clipmap,
        OffscreenOptions {
            shading: Shading::Sg(SgShading {
                scene,
                patches: Patches::P4x8,
                bake,
                omit,
            }),
            ..OffscreenOptions::default()
        },
    )?;
    time_frames(&mut r, clipmap, camera, frames)
}

/// The per-term breakdown at 4 x 8 and the shipped scenes against basic shading, every terrain, in one
/// run: see [`BreakdownRow`]. Errors are against the CPU reference of the same view.
pub(crate) fn measure_breakdown(
    gpu: &Gpu,
    profile: &Profile,
    terrains: &[(String, Heightmap)],
    (w, h): (u32, u32),
    frames: u32,
    bar: &ProgressBar,
) -> Result<Vec<BreakdownRow>> {
    let mut profile = profile.clone();
    profile.view.width = w;
    profile.view.height = h;
    // The grid the bench always measured on (a 2048-texel side at most), whatever the profile's shading
    // share: it compares the shading model, not the budget.
    let max_side = clipsat::package::shading_sats::grid_bytes(
        2047,
        2047,
        clipsat::bake::horizon::DEFAULT_AZIMUTHS,
    );
    let mut out = Vec::new();
    for (name, hm) in terrains {
        bar.set_message(format!("breakdown {name}"));
        let camera = clipsat::plan::camera::Camera::default_for(hm)?;
        let clipmap = filled_clipmap(hm, &profile, &camera)?;
        let mut r = Offscreen::new(gpu, &profile, &clipmap, OffscreenOptions::default())?;
        let (basic_ms, _) = time_frames(&mut r, &clipmap, &camera, frames)?;
        drop(r);
        bar.inc(1);
        let bake_vis = ShadingBake::bake(
            hm,
            &Needs {
                bake_horizons: true,
                ..Needs::default()
            },
            clipsat::bake::horizon::DEFAULT_AZIMUTHS,
            max_side,
            Progress::default(),
        )?;
        let bake_plain =
            ShadingBake::bake(hm, &Needs::default(), 8, max_side, Progress::default())?;
        let mut evening = Scene::load("evening")?;
        evening.effects.fog = false;
        evening.fog = None;
        let mut effects_ms = [0.0; 3];
        for (k, (_, vis, spec)) in SHADING_EFFECTS.into_iter().enumerate() {
            let mut scene = evening.clone();
            scene.effects.visibility = vis;
            scene.effects.specular = spec;
            let bake = if vis { &bake_vis } else { &bake_plain };
            let t = time_sg(
                gpu,
                &profile,
                &clipmap,
                &camera,
                &scene,
                bake,
                SgOmit::None,
                frames,
            )?;
            effects_ms[k] = t.0;
            bar.inc(1);
        }
        let mut omitted_ms = [0.0; 3];
        for (k, omit) in SgOmit::TERMS.into_iter().enumerate() {
            let t = time_sg(
                gpu, &profile, &clipmap, &camera, &evening, &bake_vis, omit, frames,
            )?;
            omitted_ms[k] = t.0;
            bar.inc(1);
        }
        let mut scenes = Vec::new();
        for scene_name in SCENES {
            let scene = Scene::load(scene_name)?;
            let bake = if scene.effects.visibility {
                &bake_vis
            } else {
                &bake_plain
            };
            let (ms, image) = time_sg(
                gpu,
                &profile,
                &clipmap,
                &camera,
                &scene,
                bake,
                SgOmit::None,
                frames,
            )?;
            let reference = crate::app::cmd::sg::reference(hm, &camera, (w, h), &scene);
            let e = reference.error(&image, crate::app::cmd::sg::sky_rgba8());
            scenes.push(SceneRun {
                scene: scene_name,
                ms,
                rmse: e.rmse,
                max: e.max,
                model_rmse: e.model_rmse,
            });
            bar.inc(1);
        }
        out.push(BreakdownRow {
            terrain: name.clone(),
            basic_ms,
            effects_ms,
            omitted_ms,
            scenes,
        });
    }
    Ok(out)
}

/// The Markdown of [`measure_breakdown`]: the scenes against basic shading and the reference, then the
/// per-term costs.
pub(crate) fn breakdown_markdown(
    rows: &[BreakdownRow],
    gpu: &Gpu,
    profile: &Profile,
    (w, h): (u32, u32),
    frames: u32,
) -> String {
    let mut md = format!(
        "# clipsat bench shading: cost and error at 4 x 8\n\nSG shading on {}, {w}x{h}, profile {}, \
         default camera, 4 x 8 patches; ms per frame (upload + draw + readback, mean of {frames} after a \
         warm-up), its ratio to basic shading in the same run, RMSE (display-encoded, 0..1) against the \
         CPU reference on a {g} x {g} pixel grid, and in brackets the shading model's part of it (the \
         CPU twin of the shader given the reference's own inputs; the rest is the clipmap's resolution: \
         far pixels read rings coarser than their footprint).\n\n\
         | terrain | basic ms | noon ms (x basic) | RMSE (model) | evening ms (x basic) | RMSE (model) | overcast ms (x basic) | RMSE (model) |\n\
         |---|---|---|---|---|---|---|---|\n",
        gpu.report().name,
        profile.name,
        g = crate::app::cmd::sg::REF_GRID,
    );
    for row in rows {
        md.push_str(&format!("| {} | {:.1} |", row.terrain, row.basic_ms));
        for s in &row.scenes {
            md.push_str(&format!(
                " {:.1} ({:.2}x) | {:.4} ({:.4}) |",
                s.ms,
                row.ratio(s.ms),
                s.rmse,
                s.model_rmse
            ));
        }
        md.push('\n');
    }
    md.push_str(
        "\n**Per-term breakdown** (the evening scene without fog, visibility and specular on): the \
         full shading's ms and ratio to basic, then each term's cost in ms, measured as the time it \
         saves when left out (footprint: the normal table fetch, r from the mesh normal instead; vMF: a \
         single normal; tables: the light table (with visibility, the view-independent shading per \
         texel) left out, each lobe one direction, unshadowed; visibility: +visibility minus diffuse \
         (the light table read instead of the suns' and the sky table's integration, so it can save \
         time); specular: +specular minus +visibility). Negative values are timing noise.\n\n\
         | terrain | full ms (x basic) | diffuse ms (x basic) |",
    );
    for (label, _) in rows.first().map(BreakdownRow::term_ms).unwrap_or_default() {
        md.push_str(&format!(" {label} |"));
    }
    md.push_str("\n|---|---|---|---|---|---|---|---|\n");
    for row in rows {
        md.push_str(&format!(
            "| {} | {:.1} ({:.2}x) | {:.1} ({:.2}x) |",
            row.terrain,
            row.effects_ms[2],
            row.ratio(row.effects_ms[2]),
            row.effects_ms[0],
            row.ratio(row.effects_ms[0])
        ));
        for (_, ms) in row.term_ms() {
            md.push_str(&format!(" {ms:.1} |"));
        }
        md.push('\n');
    }
    md
}

/// The report as JSON: the breakdown rows (with each term's cost) and the patch-count rows.
pub(crate) fn shading_json(report: &ShadingReport) -> serde_json::Value {
    let breakdown: Vec<serde_json::Value> = report
        .breakdown
        .iter()
        .map(|b| {
            let terms: serde_json::Map<String, serde_json::Value> = b
                .term_ms()
                .iter()
                .map(|(k, v)| ((*k).to_string(), serde_json::json!(v)))
                .collect();
            let scenes: Vec<serde_json::Value> = b
                .scenes
                .iter()
                .map(|s| {
                    serde_json::json!({
                        "scene": s.scene,
                        "ms": s.ms,
                        "x_basic": b.ratio(s.ms),
                        "rmse_vs_reference": s.rmse,
                        "model_rmse_vs_reference": s.model_rmse,
                        "max_error": s.max,
                    })
                })
                .collect();
            serde_json::json!({
                "terrain": b.terrain,
                "basic_ms": b.basic_ms,
                "diffuse_ms": b.effects_ms[0],
                "visibility_ms": b.effects_ms[1],
                "full_ms": b.effects_ms[2],
                "full_x_basic": b.ratio(b.effects_ms[2]),
                "term_ms": terms,
                "scenes": scenes,
            })
        })
        .collect();
    let rows: Vec<serde_json::Value> = report
        .rows
        .iter()
        .map(|r| {
            serde_json::json!({
                "terrain": r.terrain,
                "patches": r.patches.label(),
                "effects": r.effects,
                "ms": r.ms,
                "basic_ms": r.basic_ms,
                "rmse_vs_reference": r.rmse,
                "model_rmse_vs_reference": r.model_rmse,
                "max_error": r.max,
                "pixels": r.pixels,
            })
        })
        .collect();
    serde_json::json!({
        "breakdown": breakdown,
        "rows": rows,
        "skipped": report.skipped,
    })
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
         horizons marched at 64 azimuths, 96 x 192 quadrature) on a {g} x {g} pixel grid; model RMSE: \
         the CPU twin of the shader (4 x 8) given the reference's own inputs against the reference, the \
         shading model's part of the error.\n\n\
         | terrain | patches | effects | ms | x basic | RMSE | max error | pixels | model RMSE |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        gpu.report().name,
        profile.name,
        g = crate::app::cmd::sg::REF_GRID,
    );
    for row in rows {
        md.push_str(&format!(
            "| {} | {} | {} | {:.1} | {:.2} | {:.4} | {:.4} | {} | {:.4} |\n",
            row.terrain,
            row.patches.label(),
            row.effects,
            row.ms,
            row.ms / row.basic_ms.max(1e-9),
            row.rmse,
            row.max,
            row.pixels,
            row.model_rmse
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
