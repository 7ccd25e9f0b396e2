//! `clipsat render`: one frame, offscreen, to a PNG.
//!
//! By default it draws the geometry clipmap the way an engine does, through the public API: a
//! [`TerrainRenderer`] on the strict context's device, warmed up at the camera (the rings, the colour
//! rings and the detail pool filled under the update budget), then one frame prepared and rendered into
//! offscreen targets, and rendered once more against a magenta clear to count crack pixels. The
//! measurements (cracks, screen error, oracles, the SG reference) read the renderer's stages
//! ([`TerrainRenderer::stages`], a test instrument). `--brute` draws the brute-force full-resolution grid
//! (the ground truth) instead.

use std::time::Instant;

use clap::Args;
use clipsat::bake;
use clipsat::engine::setup;
use clipsat::gpu::brute::BruteForce;
use clipsat::gpu::headless::Targets;
use clipsat::gpu::Gpu;
use clipsat::measure;
use clipsat::package::imagery::ImageryPackage;
use clipsat::package::Package;
use clipsat::plan::camera::parse_vec3;
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::Clipmap;
use clipsat::plan::lod::{Lod, LodMode};
use clipsat::profile::Profile;
use clipsat::shading::debug_view::DebugView;
use clipsat::source::Heightmap;
use clipsat::{hash, RenderOptions, Result, TerrainRenderer};
use glam::DVec3;
use serde_json::json;

use super::args::{arg_error, pixel_size, DebugArg, GpuArgs, LodArgs, Size, StreamArgs};
use super::sg::ShadingArgs;
use super::{ensure_parent, print_json, ProfileArgs, TerrainArgs};

#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    #[command(flatten)]
    shading: ShadingArgs,
    /// Eye position X,Y,Z in metres (x east, y north, z up; the south-west sample is at 0,0).
    /// Default: south of the terrain, 0.45 of its longer side from the point looked at, 28 degrees above
    /// it, looking north (12 degrees east of north), and at least 5 % of that side above the highest peak.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    camera: Option<String>,
    /// The point looked at, X,Y,Z in metres. Default: midway across the terrain, 0.6 of the way north, a
    /// third of the way up its relief.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    look_at: Option<String>,
    /// Vertical field of view in degrees. Default: the profile's.
    #[arg(long, value_name = "DEG")]
    fov: Option<f64>,
    /// Image size, WxH pixels (each side at most 2048, the GLES 3.0 floor). Default: the profile's viewport.
    #[arg(long, value_name = "WxH", value_parser = pixel_size)]
    size: Option<Size>,
    /// Output PNG.
    #[arg(long, value_name = "FILE.png", default_value = "out/frame.png")]
    out: std::path::PathBuf,
    #[command(flatten)]
    gpu: GpuArgs,
    /// Print a machine-readable summary on stdout.
    #[arg(long)]
    json: bool,
    /// Draw the brute-force full-resolution grid (the ground truth) instead of the clipmap.
    #[arg(long)]
    brute: bool,
    /// Clipmap only: also draw the brute-force ground truth and report the image RMSE against it
    /// (`rmse_vs_ground_truth`). Off by default: the reference is bound by the GLES 3.0 buffer limits, which
    /// a full SRTM tile exceeds, and a summary must not fail for a measurement nobody asked for.
    #[arg(long)]
    ground_truth: bool,
    /// With --json: also report `oracle`, the fewest pyramid-quad triangles (and pool tiles beside the
    /// filled rings) any refinement of this frame needs to meet each of these epsilons in the measured
    /// metric (`clipsat::measure::oracle`: a lower bound; reads the whole pyramid once per level).
    #[arg(long, value_delimiter = ',')]
    oracle: Vec<f64>,
    /// With --oracle in a SAT mode: also report `oracle_bound`, the same descent deciding each quad by
    /// the LOD bound instead of its measured error (`clipsat::measure::bound_oracle`): the bound's cost
    /// against `oracle`, and what a refinement that decides each quad by the bound would draw.
    #[arg(long, requires = "oracle")]
    oracle_bound: bool,
    #[command(flatten)]
    stream: StreamArgs,
    /// Clipmap only: disable the GC 6.2 transition morph.
    #[arg(long)]
    no_morph: bool,
    /// Clipmap only: disable frustum culling.
    #[arg(long)]
    no_cull: bool,
    #[command(flatten)]
    lod: LodArgs,
    /// Clipmap only: a debug view.
    #[arg(long, value_enum, value_name = "VIEW", default_value_t = DebugArg::Normal)]
    debug: DebugArg,
}

/// The SAT LOD selector for `clipmap`'s terrain: tables from the bake cache ([`bake::default_cache_dir`]),
/// baked (progress bar on stderr when `progress`) on a miss, and read through a map of the cache file
/// (its pages within the tables' share of the CPU memory, and the SG inputs' share unless `sg`). A
/// streamed clipmap's tables are baked from its decoded package, and `hm` is then the package's coarse
/// stand-in heightmap.
pub(crate) fn lod_for(
    hm: &Heightmap,
    profile: &Profile,
    clipmap: &Clipmap,
    sg: bool,
    progress: bool,
) -> Result<Lod> {
    crate::app::progress::bars!(progress, bars, report, progress);
    setup::sat_lod(
        hm,
        profile,
        clipmap,
        Some(&bake::default_cache_dir()),
        sg,
        progress,
    )
}

/// The terrain a clipmap command draws (`render`, `fly`, `view`): when `stream` (the default, see
/// [`StreamArgs::streams`]), the package `--terrain` names or a plain source's (baked into the cache
/// folder on first use, progress bar on stderr when `progress`), to stream through the profile's tile
/// cache, with the package's coarse stand-in heightmap for the camera; otherwise the terrain loaded whole
/// (`--resident`, and the measurements that read every sample).
pub(crate) fn open_terrain(
    terrain: &TerrainArgs,
    stream: bool,
    progress: bool,
) -> Result<OpenedTerrain> {
    let mut t = terrain.open(stream, progress)?;
    let imagery = t.take_imagery();
    let (name, hm, package) = t.parts();
    Ok((name, hm, package, imagery))
}

/// What [`open_terrain`] opens: the name, the stand-in (or the whole grid), the package streamed and
/// the imagery package draped (`--imagery`).
pub(crate) type OpenedTerrain = (String, Heightmap, Option<Package>, Option<ImageryPackage>);

pub(crate) fn run(args: &RenderArgs) -> Result<()> {
    let mode = args.gpu.mode();
    let lod_mode = args.lod.mode();
    let debug = DebugView::from(args.debug);
    let epsilon = args.lod.epsilon;
    let profile = args.profile.load()?;
    let (size_w, size_h) = match args.size {
        Some(s) => s.pair(),
        None => (profile.view.width, profile.view.height),
    };
    let sg = args.shading.choice(&profile)?;
    // By default the terrain streams through the profile's tile cache (a plain source baked into the
    // cache on first use): nothing terrain-sized stays resident, the camera fits a coarse level, the SAT
    // LOD tables are baked out of core and mapped, and SG's tables are baked from the package level that
    // fits the profile's shading share. The brute-force reference, the oracle and SG's CPU reference read
    // every sample, so they select the resident path themselves; the measured screen error needs
    // `--resident`.
    let needs_all = [
        (args.brute, "--brute"),
        (args.ground_truth, "--ground-truth"),
        (!args.oracle.is_empty(), "--oracle"),
        (args.shading.reference, "--reference"),
    ]
    .into_iter()
    .find_map(|(on, flag)| on.then_some(flag));
    let stream = args.stream.streams(needs_all)?;
    let terrain = args.terrain.open(stream, !args.json)?;
    let camera = camera(args, terrain.heights(), f64::from(profile.view.fov_y_deg))?;

    let gpu = Gpu::new(mode)?;
    if args.brute {
        if args.ground_truth {
            return Err(arg_error(
                "--ground-truth",
                "compares the clipmap with the brute-force render; --brute draws the latter",
            ));
        }
        if sg.is_some() {
            return Err(arg_error(
                "--shading",
                "sg shades the clipmap renderer; --brute has basic shading only",
            ));
        }
        return run_brute(
            args,
            &gpu,
            terrain.name(),
            terrain.heights(),
            &profile,
            &camera,
            (size_w, size_h),
        );
    }
    let mut profile = profile;
    profile.view.width = size_w;
    profile.view.height = size_h;
    let terrain_name = terrain.name().to_owned();
    let streamed = terrain.is_streamed();
    // The clipmap is drawn the way an engine draws it: a `TerrainRenderer` on this context's device,
    // into offscreen targets; the measurements below read its stages (test instruments).
    let t0 = Instant::now();
    let targets = Targets::new(&gpu, size_w, size_h)?;
    let scene = sg
        .as_ref()
        .map(|_| args.shading.scene.clone().unwrap_or_else(|| "noon".into()));
    crate::app::progress::bars!(!args.json, bars, report, progress);
    let mut options = RenderOptions::default()
        .color_format(targets.color_format())
        .depth_format(targets.depth_format())
        .imagery_rgba8(args.terrain.imagery_rgba8)
        .progress(progress);
    if lod_mode != LodMode::Distance {
        options = options.sat_lod_px(epsilon.unwrap_or(profile.view.epsilon_px));
    }
    if let (Some(scene), Some(choice)) = (&scene, &sg) {
        options = options
            .sg_scene(scene)
            .sg_instrument(choice.patches, choice.shadows);
    }
    let mut tr = TerrainRenderer::new(
        gpu.device(),
        gpu.queue(),
        terrain,
        &clipsat::Profile::from_stages(profile.clone()),
        &options,
    )?;
    let mut frame_options = tr.frame_options();
    frame_options.lod = lod_mode;
    frame_options.morph = !args.no_morph;
    frame_options.cull = !args.no_cull;
    frame_options.debug = debug;
    if frame_options != tr.frame_options() {
        tr.set_frame_options(gpu.queue(), frame_options)?;
    }
    let viewport = (size_w, size_h);
    let cam = clipsat::Camera::from_stage(camera);
    // Filled at the still camera until complete (bounded): the rings, the colour rings and, in the SAT
    // modes, the detail pool.
    let fill_frames = tr.warm_up(gpu.queue(), &cam, viewport)?;
    // The error maps of the measured error in distance mode (not measured when streamed: the measurement
    // needs the whole pyramid); the SAT modes measure with their own selector.
    let lod = if lod_mode == LodMode::Distance && args.json && !streamed {
        let st = tr.stages();
        Some(lod_for(
            st.stand_in,
            &profile,
            st.clipmap,
            sg.is_some(),
            false,
        )?)
    } else {
        None
    };
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    let stats = tr.prepare(gpu.queue(), &cam, viewport)?;
    targets.draw("clipmap", clipsat::shading::basic::SKY, |pass| {
        tr.render(pass);
    })?;
    let image = targets.read_image()?;
    let ms = t1.elapsed().as_secs_f64() * 1e3;
    let image_hash = image.hash();
    // The same frame against a clear that no shading produces, for the crack count.
    targets.draw("clipmap, crack clear", measure::CRACK_CLEAR, |pass| {
        tr.render(pass);
    })?;
    let loud = targets.read_image()?;
    let st = tr.stages();
    let ps = st.plan.stats();
    // Clear pixels inside a column's silhouette are holes only where the view ray passes below the drawn
    // surface inside the data (`measure::hole_pixels`, through the resident pyramid or, streamed, the
    // tiles the fill left in the cache); the rest see past the terrain's border.
    let holes = measure::hole_pixels(
        &loud,
        measure::CRACK_CLEAR_RGBA8,
        st.plan,
        st.clipmap,
        &camera,
        profile.block_m(),
    );
    let (candidates, crack_pixels) = (holes.candidates, holes.holes);
    // The measured error of what was drawn. The SAT modes measure with the epsilon they drew at (the
    // planner's selector).
    let lod_used = st.planner.lod().or(lod.as_ref());
    let measured = lod_used
        .filter(|_| !streamed)
        .map(|l| measure::screen_error(st.plan, viewport, st.clipmap, &camera, l));
    let oracle = (!args.oracle.is_empty() && !streamed).then(|| {
        measure::oracle(
            st.clipmap,
            &camera,
            viewport,
            profile.clipmap.levels,
            profile.detail_quads(),
            &args.oracle,
        )
    });
    let oracle_bound = lod_used
        .filter(|_| args.oracle_bound && !streamed)
        .map(|l| {
            measure::bound_oracle(
                st.clipmap,
                &camera,
                viewport,
                profile.clipmap.levels,
                profile.detail_quads(),
                &args.oracle,
                l,
                st.planner.lod_mode(),
            )
        });
    ensure_parent(&args.out)?;
    image.save_png(&args.out)?;
    let reference = match (&sg, args.shading.reference) {
        (Some(sg), true) => {
            let reference = super::sg::reference(
                st.stand_in,
                &camera,
                (size_w, size_h),
                &sg.effective_scene(),
            );
            Some(reference.error(&image, super::sg::sky_rgba8()))
        }
        _ => None,
    };

    let report = gpu.report();
    let cf = st.clipmap.frame();
    // Only on request: the brute-force reference refuses terrains past the GLES 3.0 buffer limits.
    let rmse = if args.ground_truth {
        let truth = BruteForce::new(&gpu, st.stand_in)?.render(&camera, size_w, size_h)?;
        measure::image_rmse(&image, &truth.image)
    } else {
        None
    };
    if args.json {
        let epsilon_used = lod_used.map(Lod::epsilon_px);
        let levels: Vec<_> = cf
            .levels
            .iter()
            .map(|l| {
                json!({
                    "state": format!("{:?}", l.state),
                    "active": [l.active.x0, l.active.y0, l.active.w, l.active.h],
                })
            })
            .collect();
        let shading = json!({
            "shading": if sg.is_some() { "sg" } else { "basic" },
            "scene": sg.as_ref().map(|s| s.scene.name.clone()),
            "patches": sg.as_ref().map(|s| s.patches.label()),
            "shadows": sg.as_ref().map(|s| s.shadows && s.scene.effects.visibility),
            "bound_textures": st.renderer.bound_textures(),
            "baked": st.renderer.baked(),
            // The SG tables' grid: samples per row, rows, and data samples per grid sample.
            "shading_grid": st.renderer.sg_bake().map(|b| [b.width(), b.height(), b.step()]),
            "shading_rmse_vs_reference": reference.map(|e| e.rmse),
            "shading_model_rmse_vs_reference": reference.map(|e| e.model_rmse),
            "shading_max_error_vs_reference": reference.map(|e| e.max),
            "reference_pixels": reference.map(|e| e.pixels),
        });
        let mut out = json!({
            "renderer": "clipmap",
            "terrain": terrain_name,
            "profile": profile.name,
            "adapter": adapter_json(&gpu),
            "width": size_w,
            "height": size_h,
            "camera": camera_json(&camera),
            "fill_frames": fill_frames,
            "streamed": streamed,
            "stale_levels": cf.stale_levels,
            "disabled_levels": cf.disabled_levels,
            "levels": levels,
            "triangles": stats.triangles,
            "draws": stats.draws,
            "lod": lod_mode.to_string(),
            "epsilon_px": epsilon_used,
            "blocks_clamped": stats.blocks_clamped,
            "blocks_from_pool": ps.blocks_from_pool,
            "detail_tiles_resident": ps.detail_tiles_resident,
            "detail_samples_updated": ps.detail_samples_updated,
            "pieces_snapped": ps.cull.pieces_snapped,
            "max_screen_error_px": measured.map(|m| m.max_px),
            "max_screen_error_unclamped_px": measured.map(|m| m.max_px_unclamped),
            "screen_error_samples": measured.map(|m| m.samples),
            "screen_error_stride": measured.map(|m| m.stride),
            "max_screen_error_at": measured.and_then(|m| m.max_at).map(|a| json!({
                "x": a.x, "y": a.y, "level": a.level, "clamped": a.clamped, "pool": a.pool,
            })),
            "rmse_vs_ground_truth": rmse,
            "oracle": oracle.as_deref().map(oracle_json),
            "blocks": ps.cull.blocks,
            "blocks_culled": ps.cull.culled,
            "skirts": ps.cull.skirts,
            "morph": frame_options.morph,
            "cull": frame_options.cull,
            "gpu_bytes": st.renderer.ledger().bytes() + targets.ledger().bytes(),
            "gpu_objects": st.renderer.ledger().count() + targets.ledger().count(),
            "image_hash": hash::hex(image_hash),
            "crack_pixels": crack_pixels,

            "out": args.out.display().to_string(),
            "setup_ms": round2(setup_ms),
            "ms": round2(ms),
        });
        if let (Some(o), serde_json::Value::Object(extra)) = (out.as_object_mut(), shading) {
            o.extend(extra);
            // Outside the literal above, which is at json!'s recursion limit.
            o.insert("unmet_px".into(), json!(stats.unmet_px));
            o.insert(
                "oracle_bound".into(),
                json!(oracle_bound.as_deref().map(oracle_json)),
            );
            // The SAT LOD tables: bytes held in owned memory, and whether they are read through a map.
            o.insert(
                "lod_tables_owned_bytes".into(),
                json!(lod_used.map(|l| l.tables().owned_bytes())),
            );
            o.insert(
                "lod_tables_mapped".into(),
                json!(lod_used.map(|l| l.tables().is_mapped())),
            );
            // Clear pixels inside the silhouette that see past the data's border (not holes).
            o.insert(
                "border_view_pixels".into(),
                json!(candidates - crack_pixels),
            );
            // The frame's plan (LOD selection, the detail pool, culling, uniforms) on the CPU, ms.
            let plan_us = u32::try_from(st.plan_ns / 1000).unwrap_or(u32::MAX);
            o.insert("plan_ms".into(), json!(f64::from(plan_us) / 1000.0));
            // Candidates whose rays were traced: all, or an evenly spaced sample past MAX_TRACED.
            o.insert("crack_pixels_traced".into(), json!(holes.traced));
            o.insert("detail_tiles_needed".into(), json!(ps.detail_tiles_needed));
            o.insert("pool_cells".into(), json!(ps.pool_cells));
            // Draped imagery (`--imagery`): the package and its colour rings.
            o.insert(
                "imagery".into(),
                json!(st.imagery.map(super::imagery::rings_json)),
            );
        }
        print_json(&out);
    } else {
        println!(
            "{}: {size_w}x{size_h}, {} triangles in {} draws (clipmap, {} levels stale), image {}, \
             {crack_pixels} crack pixels, {:.1} ms on {} ({})",
            args.out.display(),
            stats.triangles,
            stats.draws,
            cf.stale_levels,
            hash::hex(image_hash),
            ms,
            report.name,
            report.gl_version,
        );
        if let Some(rings) = st.imagery {
            let s = rings.stats();
            println!(
                "imagery {} ({} x {} texels): {} colour rings, {} stale",
                rings.package().path().display(),
                rings.package().header().width,
                rings.package().header().height,
                rings.level_count(),
                s.stale_levels
            );
        }
        if let Some(e) = reference {
            println!(
                "shading vs CPU reference ({} pixels): rmse {:.4}, max {:.4} (shading model: rmse {:.4})",
                e.pixels, e.rmse, e.max, e.model_rmse
            );
        }
        if let Some(rmse) = rmse {
            println!("image rmse vs the brute-force ground truth: {rmse:.4}");
        }
    }
    Ok(())
}

fn adapter_json(gpu: &Gpu) -> serde_json::Value {
    let report = gpu.report();
    json!({
        "name": report.name,
        "backend": report.backend,
        "gl_version": report.gl_version,
        "driver": report.driver,
        "mode": report.mode,
    })
}

fn camera_json(camera: &Camera) -> serde_json::Value {
    json!({
        "eye": camera.eye.to_array(),
        "look_at": camera.target.to_array(),
        "fov_y_deg": camera.fov_y_deg,
    })
}

fn run_brute(
    args: &RenderArgs,
    gpu: &Gpu,
    terrain_name: &str,
    hm: &Heightmap,
    profile: &Profile,
    camera: &Camera,
    (size_w, size_h): (u32, u32),
) -> Result<()> {
    let t0 = Instant::now();
    let mut brute = BruteForce::new(gpu, hm)?;
    let setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    let frame = brute.render(camera, size_w, size_h)?;
    let ms = t1.elapsed().as_secs_f64() * 1e3;
    ensure_parent(&args.out)?;
    frame.image.save_png(&args.out)?;

    let report = gpu.report();
    if args.json {
        print_json(&json!({
            "renderer": "brute",
            "terrain": terrain_name,
            "profile": profile.name,
            "adapter": adapter_json(gpu),
            "width": size_w,
            "height": size_h,
            "camera": camera_json(camera),
            "triangles": frame.triangles,
            "image_hash": hash::hex(frame.image_hash),
            "out": args.out.display().to_string(),
            "setup_ms": round2(setup_ms),
            "ms": round2(ms),
        }));
    } else {
        outln!(
            "{}: {size_w}x{size_h}, {} triangles (brute force), image {} in {:.1} ms on {} ({})",
            args.out.display(),
            frame.triangles,
            hash::hex(frame.image_hash),
            ms,
            report.name,
            report.gl_version,
        );
    }
    Ok(())
}

/// `render --json`'s record of an oracle's answers, one per epsilon.
fn oracle_json(os: &[measure::Oracle]) -> Vec<serde_json::Value> {
    os.iter()
        .map(|o| {
            json!({
                "epsilon_px": o.epsilon_px,
                "triangles": o.triangles,
                "quads_per_level": o.quads_per_level,
                "quads_outside_rings": o.quads_outside_rings,
                "pool_tiles": o.pool_tiles,
                "pool_tiles_min": o.pool_tiles_min,
                "balanced_triangles": o.balanced_triangles,
                "degenerate_triangles": o.degenerate_triangles,
                "fan_triangles": o.fan.triangles,
                "fan_transition_sides": o.fan.transition_sides,
                "fan_balanced_triangles": o.fan.balanced_triangles,
            })
        })
        .collect()
}

/// The camera the options ask for; missing parts come from [`Camera::default_for`].
fn camera(args: &RenderArgs, hm: &Heightmap, profile_fov: f64) -> Result<Camera> {
    let fov = args.fov.unwrap_or(profile_fov);
    if args.camera.is_none() && args.look_at.is_none() {
        let default = Camera::default_for(hm)?;
        return Camera::new(default.eye, default.target, fov)?.with_clip(default.near, default.far);
    }
    // The default view only where a point is left out (it can fail on extreme terrains that an explicit
    // camera still shows).
    let eye = match &args.camera {
        Some(t) => parse_vec3("--camera", t)?,
        None => Camera::default_for(hm)?.eye,
    };
    let target = match &args.look_at {
        Some(t) => parse_vec3("--look-at", t)?,
        None => Camera::default_for(hm)?.target,
    };
    let camera = Camera::new(eye, target, fov)?;
    // Fit the clip planes to the terrain's bounding box as seen from this eye.
    let (ex, ey) = hm.extent_m();
    let (lo, hi) = hm.range();
    let far = [0.0, ex]
        .into_iter()
        .flat_map(|x| [0.0, ey].map(|y| (x, y)))
        .flat_map(|(x, y)| [lo, hi].map(|z| DVec3::new(x, y, f64::from(z))))
        .map(|corner| corner.distance(eye))
        .fold(0.0, f64::max)
        * 1.1;
    let far = far.max(10.0);
    camera.with_clip((far * 1e-5).max(0.05), far)
}

fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}
