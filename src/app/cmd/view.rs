//! `clipsat view`: an interactive fly-through window (winit), the front end of the whole pipeline.
//!
//! Each frame runs exactly what the frame hashes are made of: the clipmap update under the budget, then
//! the strict GLES 3.0 `Offscreen` renderer and its readback; the stats line is stamped into that image
//! on the CPU ([`crate::app::plot::stamp_text`]) and it is presented with softbuffer. No GPU surface is
//! involved, so the window works wherever the offscreen renderer does (Xvfb + Mesa llvmpipe included).
//! The input -> camera state machine is [`crate::app::view_keys::ViewState`]; this file only maps winit events.

use std::num::NonZeroU32;
use std::rc::Rc;
use std::time::{Duration, Instant};

use crate::app::cmd::args::arg_error;
use crate::app::plot::{stamp_text, stamp_width};
use crate::app::view_keys::{Action, Move, Shading, ShadingSwitches, ViewState};
use clap::Args;
use clipsat::bake::horizon::DEFAULT_AZIMUTHS;
use clipsat::gpu::headless::{render_frame, Offscreen, OffscreenOptions};
use clipsat::gpu::readback::Image;
use clipsat::gpu::renderer::{self as gpu_renderer, SgShading};
use clipsat::gpu::sat_textures::ShadingBake;
use clipsat::gpu::Gpu;
use clipsat::plan::camera::parse_vec3;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::frame_plan::LodSetup;
use clipsat::plan::lod::Lod;
use clipsat::plan::lod::LodMode;
use clipsat::shading::debug_view::DebugView;
use clipsat::shading::scene::Scene;
use clipsat::shading::Patches;
use clipsat::{Camera, Error, Heightmap, Profile, Result};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use super::args::{pixel_size, DebugArg, GpuArgs, LodArgs, Size};
use super::render::lod_for;
use super::sg::ShadingArgs;
use super::{ProfileArgs, TerrainArgs};

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
    let (terrain_name, hm) = args.terrain.load()?;
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
    if args.shading.reference {
        return Err(arg_error(
            "--reference",
            "applies to render and fly, not view",
        ));
    }
    // Key 1 switches SG on and off, so the scene is loaded either way (checked against the profile when
    // SG is first switched on).
    let (scene, patches) = match args.shading.choice(&profile)? {
        Some(c) => {
            state.shading = ShadingSwitches::from_scene(&c.scene, true);
            state.shading.visibility &= c.shadows;
            (c.scene, c.patches)
        }
        None => {
            let scene = Scene::load("noon")?;
            state.shading = ShadingSwitches::from_scene(&scene, false);
            (scene, Patches::default())
        }
    };

    let gpu = Gpu::new(mode)?;
    let clipmap = Clipmap::new(&hm, &profile, ClipmapOptions::default())?;
    let renderer = Offscreen::new(&gpu, &profile, &clipmap, OffscreenOptions::default())?;
    let max_texture_side = gpu.device().limits().max_texture_dimension_2d;
    // The renderer starts with the basic shading.
    let applied = ShadingSwitches {
        sg: false,
        ..state.shading
    };
    let event_loop = EventLoop::new().map_err(|e| window_error("cannot open the event loop", e))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    eprintln!(
        "clipsat view: {terrain_name}, profile {}, {}",
        profile.name,
        gpu_name(&gpu)
    );
    eprintln!("{HELP}");
    let mut app = App {
        hm: &hm,
        profile: &profile,
        gpu: &gpu,
        clipmap,
        renderer,
        built: (LodMode::Distance, DebugView::Normal),
        lod: None,
        state,
        scene,
        patches,
        max_texture_side,
        bake: None,
        applied,
        clearance: (2.0 * f64::from(hm.spacing())).max(30.0),
        window: None,
        drag: None,
        last: None,
        started: None,
        exit_after: args.exit_after.map(Duration::from_secs_f64),
        frame_ms: Vec::with_capacity(FRAME_LOG),
        frames: 0,
        last_ms: 0.0,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| window_error("event loop", e))?;
    if let Some(e) = app.error {
        return Err(e);
    }
    if !app.frame_ms.is_empty() {
        let (n, frames) = (app.frame_ms.len(), app.frames);
        // The first frame fills every level and compiles the pipeline: report the rest.
        let steady = if n > 1 {
            &app.frame_ms[1..]
        } else {
            &app.frame_ms[..]
        };
        let mean = steady.iter().sum::<f64>() / steady.len() as f64;
        let mut sorted = steady.to_vec();
        sorted.sort_by(f64::total_cmp);
        outln!(
            "frames {frames}, ms/frame of the first {n} (update + render + readback + present) mean {mean:.1}, median {:.1}, first {:.1}",
            sorted[sorted.len() / 2],
            app.frame_ms[0]
        );
    }
    Ok(())
}

fn gpu_name(gpu: &Gpu) -> String {
    let r = gpu.report();
    format!("{}, {}", r.name, r.gl_version)
}

fn window_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::Gpu(format!("clipsat view: {what}: {e}"))
}

/// The window and its softbuffer surface.
struct Presenter {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
    // Kept alive as long as the surface.
    _context: softbuffer::Context<Rc<Window>>,
}

struct App<'a, 'g> {
    hm: &'a Heightmap,
    profile: &'a Profile,
    gpu: &'g Gpu,
    clipmap: Clipmap,
    renderer: Offscreen<'g>,
    /// The LOD mode and debug view the renderer was built with.
    built: (LodMode, DebugView),
    /// The SAT LOD tables, loaded when a SAT mode is first chosen.
    lod: Option<Lod>,
    state: ViewState,
    /// The SG scene the shading switches apply to, and its patch count.
    scene: Scene,
    patches: Patches,
    max_texture_side: u32,
    /// The shading SATs, baked when SG is first switched on (again if visibility is switched on later).
    bake: Option<ShadingBake>,
    /// The switches the renderer is set up for.
    applied: ShadingSwitches,
    clearance: f64,
    window: Option<Presenter>,
    /// The cursor position while the left button is held (mouse-look).
    drag: Option<(f64, f64)>,
    last: Option<Instant>,
    started: Option<Instant>,
    exit_after: Option<Duration>,
    /// The first [`FRAME_LOG`] frame times, ms (preallocated: a long session does not grow it).
    frame_ms: Vec<f64>,
    /// Frames shown.
    frames: u64,
    /// The last frame's time, ms.
    last_ms: f64,
    error: Option<Error>,
}

impl App<'_, '_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let (w, h) = (self.profile.view.width, self.profile.view.height);
        let attrs = Window::default_attributes()
            .with_title("clipsat view")
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Rc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| window_error("cannot create the window", e))?,
        );
        let context = softbuffer::Context::new(window.clone())
            .map_err(|e| window_error("softbuffer context", e))?;
        let surface = softbuffer::Surface::new(&context, window.clone())
            .map_err(|e| window_error("softbuffer surface", e))?;
        // Without a window manager (Xvfb) nothing else gives the window the keyboard.
        window.focus_window();
        self.window = Some(Presenter {
            window,
            surface,
            _context: context,
        });
        Ok(())
    }

    /// One frame: fly, update the clipmap, render, stamp the stats, present.
    fn frame(&mut self) -> Result<()> {
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
            self.lod = Some(lod_for(self.hm, self.profile, &self.clipmap, true)?);
        }
        self.sync_shading()?;
        let opts = self.state.frame_options();
        let mut out = render_frame(&mut self.renderer, &self.clipmap, &camera, &opts)?;
        // The previous frame's whole time (this one's is not known until it is presented).
        let ms = if self.frames == 0 {
            t0.elapsed().as_secs_f64() * 1e3
        } else {
            self.last_ms
        };
        let lines = [
            format!(
                "tri {}  samples {}  stale {}  {:.1} ms",
                out.stats.triangles, samples, stale, ms
            ),
            self.state.describe(),
            self.state.describe_shading(),
        ];
        overlay(&mut out.image, &lines);
        self.present(&out.image)?;
        if self.frame_ms.len() < FRAME_LOG {
            self.frame_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        self.last_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.frames += 1;
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
        let lod = LodSetup::new(self.state.lod, self.lod.clone())?;
        match want.apply(&self.scene) {
            None => self.rebuild(lod, gpu_renderer::Shading::Basic)?,
            Some(scene) => {
                if let Err(e) = scene.check_profile(&scene.name, self.profile) {
                    // Refuse the key, keep what is drawn.
                    eprintln!("clipsat view: switch refused: {e}");
                    self.state.shading = self.applied;
                    return Ok(());
                }
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
                    let (bake, outcome) = ShadingBake::bake_cached(
                        self.hm,
                        &needs,
                        DEFAULT_AZIMUTHS,
                        self.max_texture_side,
                        &clipsat::bake::default_cache_dir(),
                    )?;
                    eprintln!("clipsat view: shading SATs {outcome:?}");
                    self.bake = Some(bake);
                }
                let bake = self.bake.take();
                let built = match &bake {
                    Some(b) => self.rebuild(
                        lod,
                        gpu_renderer::Shading::Sg(SgShading {
                            terrain: self.hm,
                            scene: &scene,
                            patches: self.patches,
                            bake: b,
                        }),
                    ),
                    None => Ok(()),
                };
                self.bake = bake;
                built?;
            }
        }
        self.applied = want;
        self.built = (self.state.lod, self.state.debug);
        Ok(())
    }

    /// Builds the renderer again for a new LOD mode, debug view or shading (they are fixed per renderer).
    fn rebuild(&mut self, lod: LodSetup, shading: gpu_renderer::Shading<'_>) -> Result<()> {
        self.renderer = Offscreen::new(
            self.gpu,
            self.profile,
            &self.clipmap,
            OffscreenOptions {
                lod,
                shading,
                debug: self.state.debug,
            },
        )?;
        Ok(())
    }

    fn present(&mut self, image: &Image) -> Result<()> {
        let Some(w) = self.window.as_mut() else {
            return Ok(());
        };
        let size = w.window.inner_size();
        let (Some(ww), Some(wh)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height))
        else {
            return Ok(());
        };
        w.surface
            .resize(ww, wh)
            .map_err(|e| window_error("softbuffer resize", e))?;
        let mut buf = w
            .surface
            .buffer_mut()
            .map_err(|e| window_error("softbuffer buffer", e))?;
        // Nearest-neighbour scale of the rendered image onto the window.
        let (iw, ih) = (image.width as usize, image.height as usize);
        let (ww, wh) = (size.width as usize, size.height as usize);
        for y in 0..wh {
            let sy = y * ih / wh;
            let row = &image.rgba[sy * iw * 4..(sy + 1) * iw * 4];
            for x in 0..ww {
                let p = &row[x * iw / ww * 4..][..3];
                buf[y * ww + x] = u32::from(p[0]) << 16 | u32::from(p[1]) << 8 | u32::from(p[2]);
            }
        }
        buf.present()
            .map_err(|e| window_error("softbuffer present", e))?;
        Ok(())
    }
}

/// Stamps `lines` at the top-left of `image` over a dark band.
fn overlay(image: &mut Image, lines: &[String]) {
    const SCALE: i32 = 2;
    const LINE: i32 = 9 * SCALE;
    let width = lines
        .iter()
        .map(|l| stamp_width(l, SCALE))
        .max()
        .unwrap_or(0)
        + 8;
    let height = LINE * i32::try_from(lines.len()).unwrap_or(0) + 6;
    let (iw, ih) = (image.width as usize, image.height as usize);
    for y in 0..usize::try_from(height).unwrap_or(0).min(ih) {
        for x in 0..usize::try_from(width).unwrap_or(0).min(iw) {
            let p = &mut image.rgba[(y * iw + x) * 4..][..3];
            for c in p {
                *c /= 3;
            }
        }
    }
    for (line, y) in lines.iter().zip((4..).step_by(LINE as usize)) {
        stamp_text(
            &mut image.rgba,
            image.width,
            (4, y),
            SCALE,
            line,
            [255, 255, 255, 255],
        );
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

impl ApplicationHandler for App<'_, '_> {
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
                if let Err(e) = self.frame() {
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
