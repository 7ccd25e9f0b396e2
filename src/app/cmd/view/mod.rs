//! `clipsat view`: an interactive fly-through window (winit), the front end of the whole pipeline.
//!
//! Each frame runs exactly what the frame hashes are made of: the clipmap update under the budget, the
//! frame plan, then the embeddable [`clipsat::gpu::renderer::Renderer`] drawing into the render pass of
//! the window's own wgpu surface ([`present`]). The view is a caller of the library like
//! `examples/own_device.rs`: it makes its instance (wgpu's GL backend on the X11 display through EGL,
//! OpenGL ES 3.0 where Mesa gives it), the surface, device and depth target itself, and nothing is read
//! back. The context it got is printed on stdout and shown, with the stats line, in the window title.
//! `--frames N` draws N frames without input and times them against the headless `render` path in the
//! same run ([`measure`]).
//! The input -> camera state machine is [`crate::app::view_keys::ViewState`]; this file only maps winit events.

mod measure;
mod present;

use std::time::{Duration, Instant};

use crate::app::cmd::args::arg_error;
use crate::app::view_keys::{Action, Move, Shading, ShadingSwitches, ViewState};
use clap::Args;
use clipsat::bake::horizon::DEFAULT_AZIMUTHS;
use clipsat::gpu::renderer::{self as gpu_renderer, RendererOptions, SgShading};
use clipsat::gpu::shaders::SgOmit;
use clipsat::gpu::GpuMode;
use clipsat::package::shading_sats::ShadingBake;
use clipsat::plan::camera::parse_vec3;
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::frame_plan::{FramePlan, LodSetup, PlanParams, Planner};
use clipsat::plan::lod::Lod;
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::shading::debug_view::DebugView;
use clipsat::shading::scene::Scene;
use clipsat::shading::Patches;
use clipsat::source::Heightmap;
use clipsat::{Error, Result};
use serde_json::json;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::WindowId;

use super::args::{pixel_size, DebugArg, GpuArgs, LodArgs, Size, StreamArgs};
use super::render::lod_for;
use super::sg::ShadingArgs;
use super::{ProfileArgs, TerrainArgs};
use clipsat::plan::color_rings::ColorRings;
use measure::{round2, Times};
use present::{window_error, Presented, Presenter};

#[derive(Args, Debug)]
pub(crate) struct ViewArgs {
    #[command(flatten)]
    terrain: TerrainArgs,
    #[command(flatten)]
    profile: ProfileArgs,
    #[command(flatten)]
    shading: ShadingArgs,
    /// Start position X,Y,Z in metres. Default: as `render`'s default camera.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    camera: Option<String>,
    /// Rendered image size, WxH pixels (the window scales it). Default: the profile's viewport.
    #[arg(long, value_name = "WxH", value_parser = pixel_size)]
    size: Option<Size>,
    #[command(flatten)]
    gpu: GpuArgs,
    #[command(flatten)]
    stream: StreamArgs,
    /// Flight speed, m/s (shift: 5x). Default: a twentieth of the terrain's size per second.
    #[arg(long, value_name = "M/S")]
    speed: Option<f64>,
    #[command(flatten)]
    lod: LodArgs,
    /// Initial view (key V cycles).
    #[arg(long, value_enum, value_name = "VIEW", default_value_t = DebugArg::Normal)]
    debug: DebugArg,
    /// Close the window after this many seconds (scripted runs and tests).
    #[arg(long, value_name = "SECS")]
    exit_after: Option<f64>,
    /// Measure: draw N frames from the start camera without input, close the window, then time N
    /// frames of the headless `render` path (draw + read-back) at the same size in the same run.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..))]
    frames: Option<u32>,
    /// The closing summary (frame times, context, the headless comparison) as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Frame times kept for the closing summary.
const FRAME_LOG: usize = 1 << 16;

/// The keys, printed at start.
const HELP: &str = "keys: WASD fly, E/space up, Q/C down, shift fast, arrows or left-drag look, \
L lod mode, [ ] epsilon, M morph, K cull, V view (normal/levels/wireframe), \
1 basic/SG shading, 2 visibility, 3 specular, 4 fog, Esc quit";

pub(crate) fn run(args: &ViewArgs) -> Result<()> {
    let mode = args.gpu.mode();
    let lod = args.lod.mode();
    let debug = DebugView::from(args.debug);
    let epsilon = args.lod.epsilon;
    let mut profile = args.profile.load()?;
    if let Some(s) = args.size {
        (profile.view.width, profile.view.height) = s.pair();
    }
    if args.shading.reference {
        return Err(arg_error(
            "--reference",
            "applies to render and fly, not view",
        ));
    }
    // The terrain streams through the profile's tile cache by default (a plain source baked into the
    // cache on first use), as `render` streams it: the camera and the ground under it come from the
    // package's coarse stand-in. --resident loads it whole.
    let (terrain_name, hm, package, imagery) =
        super::render::open_terrain(&args.terrain, args.stream.streams(None)?, true)?;
    // Draped imagery's colour rings, their CPU share taken from the budget before the heights'.
    let imagery = match imagery {
        Some(p) => {
            super::imagery::check_profile(&mut profile)?;
            Some(ColorRings::new(p, &profile.imagery)?)
        }
        None => None,
    };
    // The data's own spacing (the stand-in's is coarser): the eye's clearance above the ground.
    let spacing = package
        .as_ref()
        .map_or_else(|| hm.spacing(), |p| p.header().spacing);
    let mut camera = Camera::default_for(&hm)?;
    if let Some(text) = &args.camera {
        let eye = parse_vec3("--camera", text)?;
        camera = Camera::new(eye, eye + camera.forward(), camera.fov_y_deg)?
            .with_clip(camera.near, camera.far)?;
    }
    camera.fov_y_deg = f64::from(profile.view.fov_y_deg);
    let (ex, ey) = hm.extent_m();
    let speed = args.speed.unwrap_or(0.05 * ex.max(ey)).max(1e-3);
    let mut state = ViewState::new(&camera, speed, epsilon.unwrap_or(profile.view.epsilon_px));
    state.lod = lod;
    state.debug = debug;
    // Key 1 switches SG on and off, so the scene is loaded either way (checked against the profile when
    // SG is first switched on).
    let sg = args.shading.choice(&profile)?;
    let (scene, patches) = match &sg {
        Some(c) => {
            state.shading = ShadingSwitches::from_scene(&c.scene, true);
            state.shading.visibility &= c.shadows;
            (c.scene.clone(), c.patches)
        }
        None => {
            let scene = Scene::load("noon")?;
            state.shading = ShadingSwitches::from_scene(&scene, false);
            (scene, Patches::default())
        }
    };

    let clipmap = match package {
        Some(p) => Clipmap::streamed(p, &profile, ClipmapOptions::default())?,
        None => Clipmap::new(&hm, &profile, ClipmapOptions::default())?,
    };
    let streamed = clipmap.tile_cache().is_some();
    let planner = Planner::new(&profile, &clipmap, LodSetup::Distance)?;
    let plan = planner.new_plan();
    // The renderer starts with the basic shading.
    let applied = ShadingSwitches {
        sg: false,
        ..state.shading
    };
    // Before the event loop, its threads and any GL context: Mesa reads these once.
    present::ask_for_gles(mode);
    let event_loop = EventLoop::new().map_err(|e| window_error("cannot open the event loop", e))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let instance = present::instance(mode, &event_loop);
    eprintln!("clipsat view: {terrain_name}, profile {}", profile.name);
    if args.frames.is_none() {
        eprintln!("{HELP}");
    }
    let mut app = App {
        hm: &hm,
        profile: profile.clone(),
        mode,
        json: args.json,
        instance,
        clipmap,
        planner,
        plan,
        built: (LodMode::Distance, DebugView::Normal),
        lod: None,
        state,
        scene,
        patches,
        bake: None,
        applied,
        sg_built: None,
        clearance: (2.0 * f64::from(spacing)).max(30.0),
        window: None,
        context: None,
        drag: None,
        last: None,
        started: None,
        exit_after: args.exit_after.map(Duration::from_secs_f64),
        frames_left: args.frames,
        frame_ms: Vec::with_capacity(FRAME_LOG),
        frame_cpu: Vec::with_capacity(args.frames.map_or(0, |n| n as usize)),
        settled_at: None,
        frames: 0,
        last_ms: 0.0,
        titled: None,
        error: None,
        imagery,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| window_error("event loop", e))?;
    if let Some(e) = app.error {
        return Err(e);
    }
    // The window's device and surface go before the headless context is made.
    let (width, height) = app
        .window
        .take()
        .map_or((0, 0), |p| (p.config.width, p.config.height));
    let (context, gles30) = app.context.clone().unwrap_or_default();
    let package = app
        .clipmap
        .tile_cache()
        .map(|c| c.package().path().to_path_buf());
    // With --frames, time the frames from the first one that found the clipmap filled (the others paid
    // the fill under the budget); interactively, every frame after the first.
    let from = match args.frames {
        Some(_) => app.settled_at.unwrap_or(app.frame_ms.len()).max(1),
        None => 1,
    };
    let from = from.min(app.frame_ms.len());
    // CPU time from the end of the frame before `from` to the end of the last.
    let cpu = measure::per_frame(
        app.frame_cpu.get(from.wrapping_sub(1)).copied().flatten(),
        app.frame_cpu.last().copied().flatten(),
        app.frame_cpu.len().saturating_sub(from),
    );
    let window = app
        .frame_ms
        .first()
        .and_then(|&first| Times::of(first, &app.frame_ms[from..], cpu));
    let headless = match args.frames {
        Some(n) if width > 0 => {
            profile.view.width = width;
            profile.view.height = height;
            let camera = app.state.camera()?;
            let opts = app.state.frame_options();
            eprintln!("clipsat view: timing {n} frames of the headless render path at {width}x{height}...");
            let same = measure::Same {
                hm: &hm,
                package: package.as_deref(),
                profile: &profile,
                camera: &camera,
                opts: &opts,
                lod: app.state.lod,
                debug: app.state.debug,
                sg: sg.as_ref().filter(|_| app.applied.sg),
            };
            Some(measure::headless(&same, mode, n)?)
        }
        _ => None,
    };
    let ratio = |f: fn(&Times) -> Option<f64>| match (&window, &headless) {
        (Some(w), Some(h)) => f(&h.times)
            .zip(f(w).filter(|&v| v > 0.0))
            .map(|(h, w)| h / w),
        _ => None,
    };
    let ratio_mean = ratio(|t| Some(t.mean));
    let ratio_median = ratio(|t| Some(t.median));
    let ratio_cpu = ratio(|t| t.cpu);
    if args.json {
        super::print_json(&json!({
            "terrain": terrain_name,
            "streamed": streamed,
            "profile": profile.name,
            "width": width,
            "height": height,
            "frames": app.frames,
            "window": {
                "context": context,
                "gles30": gles30,
                "path": "update + plan + prepare + draw into the surface's pass + present, no read-back",
                "fill_frames": from,
                "times": window.map(|t| t.json()),
            },
            "headless_render": headless.as_ref().map(|h| json!({
                "context": h.context,
                "path": "update + plan + draw offscreen + read-back + hash (clipsat render's frame)",
                "times": h.times.json(),
            })),
            "headless_over_window_mean": ratio_mean.map(round2),
            "headless_over_window_median": ratio_median.map(round2),
            "headless_over_window_cpu": ratio_cpu.map(round2),
        }));
        return Ok(());
    }
    if let Some(t) = window {
        outln!(
            "frames {}, {width}x{height} on {context}: ms/frame of {} (update + plan + prepare + render + present, no read-back) mean {:.1}, median {:.1}, first {:.1}{}",
            app.frames, t.frames, t.mean, t.median, t.first, cpu_text(t.cpu)
        );
    }
    if let (Some(h), Some(mean), Some(median)) = (&headless, ratio_mean, ratio_median) {
        outln!(
            "headless render at {width}x{height} on {}: ms/frame of {} (update + plan + draw + read-back + hash) mean {:.1}, median {:.1}{}; headless / window: {mean:.2} (mean), {median:.2} (median){}",
            h.context, h.times.frames, h.times.mean, h.times.median, cpu_text(h.times.cpu),
            ratio_cpu.map_or_else(String::new, |r| format!(", {r:.2} (CPU)"))
        );
    }
    Ok(())
}

/// ", CPU N ms/frame" when the CPU time is known.
fn cpu_text(cpu: Option<f64>) -> String {
    cpu.map_or_else(String::new, |c| format!(", CPU {c:.1} ms/frame"))
}

struct App<'a> {
    hm: &'a Heightmap,
    /// The profile; its viewport follows the window's size.
    profile: Profile,
    mode: GpuMode,
    /// `--json`: the summary is JSON.
    json: bool,
    instance: wgpu::Instance,
    clipmap: Clipmap,
    planner: Planner,
    /// The frame plan, reused every frame.
    plan: FramePlan,
    /// The LOD mode and debug view the renderer was built with.
    built: (LodMode, DebugView),
    /// The SAT LOD tables, loaded when a SAT mode is first chosen.
    lod: Option<Lod>,
    state: ViewState,
    /// The SG scene the shading switches apply to, and its patch count.
    scene: Scene,
    patches: Patches,
    /// The shading SATs, baked when SG is first switched on (again if visibility is switched on later).
    bake: Option<ShadingBake>,
    /// The switches the renderer is set up for.
    applied: ShadingSwitches,
    /// The effects (with `sg` on) the renderer's SG tables were built for, if it has them: the basic/SG
    /// key and the effect keys within these then only switch it (`Renderer::set_sg_enabled`,
    /// `Renderer::set_sg_effects`), creating no table.
    sg_built: Option<ShadingSwitches>,
    clearance: f64,
    window: Option<Presenter>,
    /// The window's GL context (GL_VERSION, GL_RENDERER) and whether it is OpenGL ES 3.0.
    context: Option<(String, bool)>,
    /// The cursor position while the left button is held (mouse-look).
    drag: Option<(f64, f64)>,
    last: Option<Instant>,
    started: Option<Instant>,
    exit_after: Option<Duration>,
    /// `--frames`: frames still to draw.
    frames_left: Option<u32>,
    /// The first [`FRAME_LOG`] frame times, ms (preallocated: a long session does not grow it).
    frame_ms: Vec<f64>,
    /// With `--frames`: the process's CPU time at the end of each frame, ms ([`measure::cpu_ms`]).
    frame_cpu: Vec<Option<f64>>,
    /// The index in `frame_ms` of the first frame that updated no samples and left no level stale.
    settled_at: Option<usize>,
    /// Frames shown.
    frames: u64,
    /// The last frame's time, ms.
    last_ms: f64,
    /// When the title (the stats line) was last set: a few times a second, not every frame.
    titled: Option<Instant>,
    /// The first error, returned when the event loop ends.
    error: Option<Error>,
    /// Draped imagery's colour rings (`--imagery`).
    imagery: Option<ColorRings>,
}

impl App<'_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let mut p = Presenter::open(&self.instance, event_loop, &self.profile, self.mode)?;
        let kind = if p.gles30 {
            "OpenGL ES 3.0"
        } else {
            "not OpenGL ES 3.0"
        };
        // On stdout unless the summary is JSON (stdout is then one JSON document).
        if self.json {
            eprintln!("clipsat view: context {} ({kind})", p.context);
        } else {
            outln!("clipsat view: context {} ({kind})", p.context);
        }
        eprintln!(
            "clipsat view: presenting through a wgpu surface on {}",
            p.context
        );
        let size = p.window.inner_size();
        self.context = Some((p.context.clone(), p.gles30));
        if let Some(rings) = &mut self.imagery {
            p.enable_imagery(rings)?;
        }
        self.window = Some(p);
        self.resize(size.width, size.height);
        Ok(())
    }

    /// The window's new size: the surface, the depth target and the planner's aspect follow.
    fn resize(&mut self, width: u32, height: u32) {
        let Some(p) = self.window.as_mut() else {
            return;
        };
        if width == 0 || height == 0 {
            return;
        }
        if (p.config.width, p.config.height) != (width, height) {
            p.resize(width, height);
        }
        // The next plans' viewport (nothing is rebuilt).
        (self.profile.view.width, self.profile.view.height) = (width, height);
    }

    /// One frame: fly, update the clipmap, plan, prepare, draw into the surface's pass, present.
    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let t0 = Instant::now();
        let dt = self.last.map_or(0.0, |t| (t0 - t).as_secs_f64().min(0.25));
        self.last = Some(t0);
        self.state.step(dt);
        // The drawn surface under the eye (it can lie above the data while coarse rings fill), else the data.
        let eye = self.state.eye;
        let ground = self.clipmap.surface_height(eye).map_or_else(
            || f64::from(self.hm.height_at_world(eye.x, eye.y)),
            f64::from,
        );
        self.state.keep_above(ground, self.clearance);
        let camera = self.state.camera()?;
        let frame = self.clipmap.update(camera.eye)?;
        let (samples, stale) = (frame.samples_updated, frame.stale_levels);
        if self.state.lod != LodMode::Distance && self.lod.is_none() {
            eprintln!("clipsat view: loading the SAT LOD tables (baked once, then cached)...");
            // SG may be switched on while the view runs: the tables keep to their own share.
            self.lod = Some(lod_for(self.hm, &self.profile, &self.clipmap, true, true)?);
        }
        self.sync_shading()?;
        let opts = self.state.frame_options();
        let params = PlanParams {
            viewport: Some((self.profile.view.width, self.profile.view.height)),
            ..opts.plan_params()
        };
        self.planner
            .plan(&self.clipmap, &camera, &params, &mut self.plan)?;
        self.clipmap.request_samples(&self.plan.detail().wanted);
        let Some(p) = self.window.as_mut() else {
            return Ok(());
        };
        if let Some(rings) = &mut self.imagery {
            rings.update(camera.eye.x, camera.eye.y)?;
            p.prepare_imagery(rings, (camera.eye.x, camera.eye.y))?;
        }
        if let Presented::Skipped = p.draw(&self.clipmap, &self.plan, opts.clear)? {
            return Ok(());
        }
        // The previous frame's whole time (this one's is not known until it is presented).
        let ms = if self.frames == 0 {
            t0.elapsed().as_secs_f64() * 1e3
        } else {
            self.last_ms
        };
        // The stats line, in the window title (no read-back, no text drawn into the frame).
        if self
            .titled
            .is_none_or(|t| t.elapsed() >= Duration::from_millis(250))
        {
            let title = format!(
                "clipsat view | tri {} samples {} stale {} {:.1} ms | {} | {} | {}",
                self.plan.stats().triangles,
                samples,
                stale,
                ms,
                self.state.describe(),
                self.state.describe_shading(),
                p.context
            );
            p.window.set_title(&title);
            self.titled = Some(Instant::now());
        }
        let elapsed = t0.elapsed().as_secs_f64() * 1e3;
        if self.frame_ms.len() < FRAME_LOG {
            if samples == 0 && stale == 0 && self.settled_at.is_none() {
                self.settled_at = Some(self.frame_ms.len());
            }
            self.frame_ms.push(elapsed);
        }
        if self.frames_left.is_some() && self.frame_cpu.len() < self.frame_cpu.capacity() {
            self.frame_cpu.push(measure::cpu_ms());
        }
        self.last_ms = elapsed;
        self.frames += 1;
        if let Some(left) = self.frames_left.as_mut() {
            *left = left.saturating_sub(1);
            if *left == 0 {
                event_loop.exit();
            }
        }
        Ok(())
    }

    /// Sets the renderer up for the shading switches when a key changed them: bake what the scene now
    /// needs (once, through the cache), bind and compile its variant. A switch to effects the profile
    /// does not allow is refused with the reason, and the switches go back to what is drawn.
    fn sync_shading(&mut self) -> Result<()> {
        let want = self.state.shading;
        let built = (self.state.lod, self.state.debug);
        if want == self.applied && built == self.built {
            return Ok(());
        }
        if self.window.is_none() {
            return Ok(());
        }
        // SG on or off, and effects within those the renderer's SG tables were built for: a switch, not a
        // rebuild (the SG tables are created once, never again on a toggle).
        // Fog without the scene's parameters is no effect (`ShadingSwitches::apply`).
        let effective = ShadingSwitches {
            fog: want.fog && self.scene.fog.is_some(),
            ..want
        };
        if built == self.built && self.sg_built.is_some_and(|b| effective.within(&b)) {
            if let Some(p) = self.window.as_mut() {
                if let Some(scene) = want.apply(&self.scene) {
                    p.set_sg_effects(scene.effects)?;
                }
                p.renderer.set_sg_enabled(want.sg);
            }
            eprintln!(
                "clipsat view: SG shading {} (switched: nothing baked, no table created)",
                effective.label()
            );
            self.applied = want;
            return Ok(());
        }
        let lod = LodSetup::new(self.state.lod, self.lod.clone())?;
        match want.apply(&self.scene) {
            None => {
                self.rebuild(lod, gpu_renderer::Shading::Basic)?;
                self.sg_built = None;
            }
            Some(wanted) => {
                if let Err(e) = wanted.check_profile(&wanted.name, &self.profile) {
                    // Refuse the key, keep what is drawn.
                    eprintln!("clipsat view: switch refused: {e}");
                    self.state.shading = self.applied;
                    return Ok(());
                }
                // Built for the scene's own effects too (as far as the profile allows), so that the
                // effect keys switch within them afterwards instead of building again.
                let union = want.union(&ShadingSwitches::from_scene(&self.scene, true));
                let scene = union
                    .apply(&self.scene)
                    .filter(|s| s.check_profile(&s.name, &self.profile).is_ok())
                    .unwrap_or_else(|| wanted.clone());
                let needs = scene.needs();
                let stale = self
                    .bake
                    .as_ref()
                    .is_none_or(|b| needs.bake_horizons && b.azimuths() == 0);
                if stale {
                    eprintln!(
                        "clipsat view: baking the shading SATs for `{}`...",
                        scene.name
                    );
                    // A streamed terrain's from the package level that fits the shading share.
                    let (max_bytes, dir) = (
                        self.profile.cpu_split().shading,
                        clipsat::bake::default_cache_dir(),
                    );
                    crate::app::progress::bars!(true, bars, report, progress);
                    let (bake, outcome) = match self.clipmap.tile_cache() {
                        Some(c) => ShadingBake::bake_package_cached(
                            c.package(),
                            &needs,
                            DEFAULT_AZIMUTHS,
                            max_bytes,
                            &dir,
                            progress,
                        )?,
                        None => ShadingBake::bake_cached(
                            self.hm,
                            &needs,
                            DEFAULT_AZIMUTHS,
                            max_bytes,
                            &dir,
                            progress,
                        )?,
                    };
                    eprintln!("clipsat view: shading SATs {outcome:?}");
                    self.bake = Some(bake);
                }
                let bake = self.bake.take();
                let built = match &bake {
                    Some(b) => self.rebuild(
                        lod,
                        gpu_renderer::Shading::Sg(SgShading {
                            scene: &scene,
                            patches: self.patches,
                            bake: b,
                            omit: SgOmit::None,
                        }),
                    ),
                    None => Ok(()),
                };
                self.bake = bake;
                built?;
                if let Some(p) = self.window.as_mut() {
                    p.set_sg_effects(wanted.effects)?;
                }
                self.sg_built = Some(ShadingSwitches::from_scene(&scene, true));
            }
        }
        self.applied = want;
        self.built = (self.state.lod, self.state.debug);
        Ok(())
    }

    /// Builds the planner and renderer again for a new LOD mode, debug view or shading (they are fixed
    /// per renderer; a window size is only the plans' viewport).
    fn rebuild(&mut self, lod: LodSetup, shading: gpu_renderer::Shading<'_>) -> Result<()> {
        let Some(p) = self.window.as_mut() else {
            return Ok(());
        };
        self.planner = Planner::new(&self.profile, &self.clipmap, lod)?;
        self.plan = self.planner.new_plan();
        p.rebuild(
            RendererOptions {
                shading,
                debug: self.state.debug,
                ..RendererOptions::default()
            },
            &self.profile,
        )?;
        match &mut self.imagery {
            Some(rings) => p.enable_imagery(rings),
            None => Ok(()),
        }
    }
}

fn flight_key(code: KeyCode) -> Option<Move> {
    Some(match code {
        KeyCode::KeyW => Move::Forward,
        KeyCode::KeyS => Move::Back,
        KeyCode::KeyA => Move::Left,
        KeyCode::KeyD => Move::Right,
        KeyCode::KeyE | KeyCode::Space => Move::Up,
        KeyCode::KeyQ | KeyCode::KeyC => Move::Down,
        KeyCode::ArrowLeft => Move::TurnLeft,
        KeyCode::ArrowRight => Move::TurnRight,
        KeyCode::ArrowUp => Move::LookUp,
        KeyCode::ArrowDown => Move::LookDown,
        KeyCode::ShiftLeft | KeyCode::ShiftRight => Move::Fast,
        _ => return None,
    })
}

fn action_key(code: KeyCode) -> Option<Action> {
    Some(match code {
        KeyCode::KeyL => Action::CycleLod,
        KeyCode::BracketRight => Action::EpsilonUp,
        KeyCode::BracketLeft => Action::EpsilonDown,
        KeyCode::KeyM => Action::ToggleMorph,
        KeyCode::KeyK => Action::ToggleCull,
        KeyCode::KeyV => Action::CycleDebug,
        KeyCode::Digit1 => Action::Toggle(Shading::Sg),
        KeyCode::Digit2 => Action::Toggle(Shading::Visibility),
        KeyCode::Digit3 => Action::Toggle(Shading::Specular),
        KeyCode::Digit4 => Action::Toggle(Shading::Fog),
        _ => return None,
    })
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_none() {
            if let Err(e) = self.open(event_loop) {
                self.fail(event_loop, e);
            }
            self.started = Some(Instant::now());
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => self.resize(size.width, size.height),
            WindowEvent::Focused(false) => self.state.release_all(),
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                let pressed = event.state == ElementState::Pressed;
                if code == KeyCode::Escape && pressed {
                    event_loop.exit();
                } else if let Some(m) = flight_key(code) {
                    self.state.key(m, pressed);
                } else if let Some(a) = action_key(code).filter(|_| pressed && !event.repeat) {
                    self.state.action(a);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.drag = (state == ElementState::Pressed).then_some((f64::NAN, f64::NAN));
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let Some((x, y)) = self.drag {
                    if x.is_finite() {
                        self.state.look(position.x - x, position.y - y);
                    }
                    self.drag = Some((position.x, position.y));
                }
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.frame(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if let (Some(t), Some(limit)) = (self.started, self.exit_after) {
            if t.elapsed() >= limit {
                event_loop.exit();
                return;
            }
        }
        if let Some(w) = &self.window {
            w.window.request_redraw();
        }
    }
}
