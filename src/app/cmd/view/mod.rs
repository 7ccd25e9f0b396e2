//! `clipsat view`: an interactive fly-through window (winit), a caller of the public API.
//!
//! The view draws like `examples/own_device.rs`: a [`clipsat::TerrainRenderer`] built on the window's own
//! wgpu device, `prepare` with the frame's [`clipsat::Camera`] and viewport, `render` into the surface's
//! pass ([`present`]). It makes its instance (wgpu's GL backend on the X11 display through EGL, OpenGL
//! ES 3.0 where Mesa gives it), the surface, device and depth target itself, and nothing is read back.
//! Its keys are the renderer's per-frame options ([`clipsat::FrameOptions`],
//! `TerrainRenderer::set_sat_lod_px`); key 1 on a renderer built without SG builds it again with the
//! scene. The context it got is printed on stdout and shown, with the stats line, in the window title.
//! `--frames N` draws N frames without input and times them against the headless `render` path in the
//! same run ([`measure`]; that path, a test instrument, is drawn through the stages by
//! `app/cmd/view_setup.rs`). The input -> camera state machine is
//! [`crate::app::view_keys::ViewState`]; this file only maps winit events.

mod measure;
mod present;

use std::time::{Duration, Instant};

use crate::app::view_keys::{Action, Move, Shading, ViewState};
use clap::Args;
use clipsat::{DebugView, Error, FrameOptions, LodMode, Profile, RenderOptions, Result, Terrain};
use glam::DVec3;
use serde_json::json;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::WindowId;

use super::args::{pixel_size, DebugArg, GpuArg, GpuArgs, LodArgs, Size, StreamArgs};
use super::sg::ShadingArgs;
use super::view_setup::{self, HeadlessSg, HeadlessView};
use super::{ProfileArgs, TerrainArgs};
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

/// The sky the frame is cleared to (the colour `clipsat render` clears to).
const SKY: [f64; 4] = [0.63, 0.76, 0.90, 1.0];

/// The scene key 1 switches to when the view started with the basic shading.
const DEFAULT_SCENE: &str = "noon";

/// The keys, printed at start.
const HELP: &str = "keys: WASD fly, E/space up, Q/C down, shift fast, arrows or left-drag look, \
L lod mode, [ ] epsilon, M morph, K cull, V view (normal/levels/wireframe), \
1 basic/SG shading, 2 visibility, 3 specular, 4 fog, Esc quit";

pub(crate) fn run(args: &ViewArgs) -> Result<()> {
    let mode = args.gpu.gpu;
    let start = view_setup::start(
        &args.profile,
        args.size,
        &args.terrain,
        &args.stream,
        &args.shading,
        args.camera.as_deref(),
    )?;
    let epsilon = args.lod.epsilon.unwrap_or(start.epsilon_px);
    let (ex, ey) = start.extent_m;
    let speed = args.speed.unwrap_or(0.05 * ex.max(ey)).max(1e-3);
    let (eye, target) = (DVec3::from(start.eye), DVec3::from(start.target));
    let mut state = ViewState::new(
        eye,
        (target - eye).normalize_or(DVec3::X),
        start.fov_y_deg,
        start.near_far,
        speed,
        epsilon,
    );
    state.lod = args.lod.mode();
    state.debug = DebugView::from(args.debug);
    state.shading.sg = start.sg.is_some();
    let shadows = start.sg.as_ref().is_none_or(|(_, shadows)| *shadows);
    state.shading.visibility &= shadows;
    let terrain_name = start.terrain.name().to_string();
    let streamed = start.terrain.is_streamed();
    // Before the event loop, its threads and any GL context: Mesa reads these once.
    present::ask_for_gles(mode);
    let event_loop = EventLoop::new().map_err(|e| window_error("cannot open the event loop", e))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let instance = present::instance(mode, &event_loop);
    eprintln!(
        "clipsat view: {terrain_name}, profile {}",
        start.profile.name()
    );
    if args.frames.is_none() {
        eprintln!("{HELP}");
    }
    let mut app = App {
        args,
        profile: start.profile.clone(),
        size: start.size,
        mode,
        instance,
        terrain: Some(start.terrain),
        scene: start
            .sg
            .as_ref()
            .map_or_else(|| DEFAULT_SCENE.to_string(), |(s, _)| s.clone()),
        sg_built: start.sg.is_some(),
        sat_loaded: false,
        applied: FrameOptions::default(),
        state,
        clearance: (2.0 * f64::from(start.spacing_m)).max(30.0),
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
            let s = &app.state;
            let o = app.applied;
            eprintln!("clipsat view: timing {n} frames of the headless render path at {width}x{height}...");
            let view = HeadlessView {
                terrain: &args.terrain,
                stream: &args.stream,
                profile: &args.profile,
                size: (width, height),
                eye: s.eye.to_array(),
                target: (s.eye + s.forward()).to_array(),
                fov_y_deg: s.fov_y_deg,
                near_far: s.near_far,
                options: o,
                epsilon_px: s.epsilon_px,
                sg: o.sg.then_some(HeadlessSg {
                    scene: &app.scene,
                    visibility: o.visibility,
                    specular: o.specular,
                    fog: o.fog,
                }),
            };
            Some(measure::headless(&view, mode, n)?)
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
            "profile": app.profile.name(),
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
    args: &'a ViewArgs,
    /// The profile (the renderer sizes everything from it; the window's size is each frame's viewport).
    profile: Profile,
    /// The window's first size.
    size: (u32, u32),
    mode: GpuArg,
    instance: wgpu::Instance,
    /// The terrain, until the window's renderer takes it.
    terrain: Option<Terrain>,
    /// The SG scene: the one drawn, or the one key 1 switches to.
    scene: String,
    /// Whether the renderer was built with the SG scene (else key 1 builds it again with it).
    sg_built: bool,
    /// Whether a SAT mode was drawn yet (its tables are loaded then, once).
    sat_loaded: bool,
    /// The frame options the renderer draws with.
    applied: FrameOptions,
    state: ViewState,
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
}

impl App<'_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    /// The options the renderer is built with: SG with the scene when `sg`, SAT LOD at the state's bound
    /// when a SAT mode is drawn.
    fn render_options(&self, sg: bool) -> RenderOptions<'_> {
        render_options(
            sg.then_some(self.scene.as_str()),
            &self.state,
            self.args.terrain.imagery_rgba8,
        )
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let Some(terrain) = self.terrain.take() else {
            return Ok(());
        };
        if self.state.lod != LodMode::Distance {
            eprintln!("clipsat view: loading the SAT LOD tables (baked once, then cached)...");
            self.sat_loaded = true;
        }
        let options = self.render_options(self.sg_built);
        let p = Presenter::open(
            &self.instance,
            event_loop,
            self.size,
            self.mode,
            (terrain, &self.profile, options),
        )?;
        let kind = if p.gles30 {
            "OpenGL ES 3.0"
        } else {
            "not OpenGL ES 3.0"
        };
        // On stdout unless the summary is JSON (stdout is then one JSON document).
        if self.args.json {
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
        self.applied = p.renderer.frame_options();
        self.mask_effects();
        self.window = Some(p);
        self.resize(size.width, size.height);
        Ok(())
    }

    /// The window's new size: the surface and the depth target follow (the renderer takes each frame's
    /// viewport, nothing is rebuilt).
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
    }

    /// One frame: fly, set the keys' options, prepare (update, plan, uploads), draw into the surface's
    /// pass, present.
    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let t0 = Instant::now();
        let dt = self.last.map_or(0.0, |t| (t0 - t).as_secs_f64().min(0.25));
        self.last = Some(t0);
        self.state.step(dt);
        self.sync_options()?;
        let Some(p) = self.window.as_mut() else {
            return Ok(());
        };
        // The drawn surface under the eye (it can lie above the data while coarse rings fill), else the
        // data's height there.
        let eye = self.state.eye;
        let ground = match p.renderer.surface_height(&self.state.camera()?) {
            Some(z) => Some(f64::from(z)),
            None => p.renderer.height_at(eye.x, eye.y)?,
        };
        if let Some(ground) = ground {
            self.state.keep_above(ground, self.clearance);
        }
        let camera = self.state.camera()?;
        let stats = match p.draw(&camera, SKY)? {
            Presented::Shown(stats) => stats,
            Presented::Skipped => return Ok(()),
        };
        let (samples, stale) = (stats.samples_updated, stats.stale_levels);
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
                stats.triangles,
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

    /// Gives the renderer the options the keys changed: SAT LOD's bound, and the frame options (a switch;
    /// a new LOD mode or debug view makes the renderer's GPU side again). SG on a renderer built without
    /// it builds the renderer again with the scene (the terrain opened again: a package already baked
    /// opens at once). A switch the renderer refuses (an effect the scene lacks, a scene the profile does
    /// not allow) is printed with the reason, and the keys go back to what is drawn.
    fn sync_options(&mut self) -> Result<()> {
        if self.state.shading.sg && !self.sg_built {
            self.build_sg()?;
        }
        let want = self.state.frame_options(self.applied);
        let Some(p) = self.window.as_mut() else {
            return Ok(());
        };
        if want != self.applied {
            if want.lod != LodMode::Distance && !self.sat_loaded {
                eprintln!("clipsat view: loading the SAT LOD tables (baked once, then cached)...");
                self.sat_loaded = true;
            }
            let set = p.set_frame_options(want);
            let drawn = p.renderer.frame_options();
            match set {
                Ok(()) => {
                    // Switches of the SG shading a renderer was built with (a basic renderer has none).
                    if self.sg_built
                        && (want.sg, want.visibility, want.specular, want.fog)
                            != (
                                self.applied.sg,
                                self.applied.visibility,
                                self.applied.specular,
                                self.applied.fog,
                            )
                    {
                        eprintln!(
                            "clipsat view: SG shading {} (switched: nothing baked, no table created)",
                            sg_label(&drawn)
                        );
                    }
                    self.applied = want;
                }
                Err(e @ Error::Invalid { .. }) => {
                    eprintln!("clipsat view: switch refused: {e}");
                    self.take_back();
                }
                Err(e) => return Err(e),
            }
        }
        let eps = self.state.epsilon_px;
        if let Some(p) = self.window.as_mut() {
            if self.applied.lod != LodMode::Distance && p.renderer.sat_lod_px() != Some(eps) {
                p.renderer.set_sat_lod_px(eps)?;
            }
        }
        Ok(())
    }

    /// The keys' SG effects within those of the renderer just built (the scene's own): a start or a key
    /// 1 does not ask for an effect the scene leaves out.
    fn mask_effects(&mut self) {
        let (a, s) = (self.applied, &mut self.state.shading);
        s.visibility &= a.visibility;
        s.specular &= a.specular;
        s.fog &= a.fog;
    }

    /// The keys' switches back to what the renderer draws.
    fn take_back(&mut self) {
        let a = self.applied;
        let s = &mut self.state;
        (s.lod, s.morph, s.cull, s.debug) = (a.lod, a.morph, a.cull, a.debug);
        (
            s.shading.sg,
            s.shading.visibility,
            s.shading.specular,
            s.shading.fog,
        ) = (a.sg, a.visibility, a.specular, a.fog);
    }

    /// Builds the renderer again with the SG scene (key 1 on a renderer built with the basic shading),
    /// the other options carried over. Refused (the profile does not allow the scene): the renderer
    /// drawn is kept and the key goes back.
    fn build_sg(&mut self) -> Result<()> {
        if self.window.is_none() {
            return Ok(());
        }
        eprintln!(
            "clipsat view: baking the shading SATs for `{}` (once, then cached), the renderer built again with them...",
            self.scene
        );
        let terrain = self
            .args
            .terrain
            .open(self.args.stream.streams(None)?, true)?;
        let options = render_options(
            Some(self.scene.as_str()),
            &self.state,
            self.args.terrain.imagery_rgba8,
        );
        let built = match self.window.as_mut() {
            Some(p) => p.rebuild(terrain, &self.profile, options),
            None => Ok(()),
        };
        match built {
            Ok(()) => {
                self.sg_built = true;
                if let Some(p) = self.window.as_ref() {
                    // The new renderer's options: the scene's effects, to be set from the keys next.
                    self.applied = p.renderer.frame_options();
                }
                self.mask_effects();
                Ok(())
            }
            Err(e) if matches!(e, Error::Invalid { .. } | Error::Config { .. }) => {
                eprintln!("clipsat view: switch refused: {e}");
                self.state.shading.sg = false;
                Ok(())
            }
            Err(e) => Err(e),
        }
    }
}

/// The options a renderer is built with: SG with `scene`, SAT LOD at the state's bound when a SAT mode
/// is drawn (its other options are set after, [`App::sync_options`]), the imagery in RGBA8 on request.
fn render_options<'a>(
    scene: Option<&'a str>,
    state: &ViewState,
    imagery_rgba8: bool,
) -> RenderOptions<'a> {
    let mut o = RenderOptions::default().imagery_rgba8(imagery_rgba8);
    if let Some(scene) = scene {
        o = o.sg_scene(scene);
    }
    if state.lod != LodMode::Distance {
        o = o.sat_lod_px(state.epsilon_px);
    }
    o
}

/// The SG switches drawn, for the log: `off`, or `on` and each effect on or off.
fn sg_label(o: &FrameOptions) -> String {
    let on_off = |b: bool| if b { "on" } else { "off" };
    if !o.sg {
        return "off".to_string();
    }
    format!(
        "on (vis {}, spec {}, fog {})",
        on_off(o.visibility),
        on_off(o.specular),
        on_off(o.fog)
    )
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
