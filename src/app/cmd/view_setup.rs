//! App: what `clipsat view` takes from its flags, and the headless `render` path it is timed against.
//!
//! The window (`app/cmd/view/`) draws through the public API only. This file turns the flags into
//! public values (a [`clipsat::Profile`] with the window's size, a [`clipsat::Terrain`], the start
//! camera) and times, for `--frames N`, the headless path of `clipsat render` at the same view: the same
//! [`TerrainRenderer`] drawn into offscreen targets of the strict context, read back and hashed.

use clipsat::gpu::headless::Targets;
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::plan::camera::parse_vec3;
use clipsat::shading::Patches;
use clipsat::{Camera, FrameOptions, LodMode, RenderOptions, Result, Terrain, TerrainRenderer};

use super::args::{arg_error, GpuArg, Size, StreamArgs};
use super::sg::ShadingArgs;
use super::{ProfileArgs, TerrainArgs};

/// The view's start: the profile, its viewport and the terrain opened through the public API.
pub(crate) struct ViewStart {
    /// The profile, its viewport set to `--size` when given.
    pub(crate) profile: clipsat::Profile,
    /// The window's first size (the profile's viewport).
    pub(crate) size: (u32, u32),
    /// The profile's vertical field of view, degrees.
    pub(crate) fov_y_deg: f64,
    /// The profile's SAT LOD error bound, pixels.
    pub(crate) epsilon_px: f32,
    /// The terrain, streamed through a package in the cache folder unless `--resident`.
    pub(crate) terrain: Terrain,
    /// The start camera: eye and target, metres, and the clip planes.
    pub(crate) eye: [f64; 3],
    pub(crate) target: [f64; 3],
    pub(crate) near_far: (f64, f64),
    /// The data's sample spacing, metres (a streamed terrain's own, not its stand-in's).
    pub(crate) spacing_m: f32,
    /// The terrain's extent, metres.
    pub(crate) extent_m: (f64, f64),
    /// `--shading sg`: the scene (a shipped name or a file) and whether its visibility is kept
    /// (`--no-shadows` drops it).
    pub(crate) sg: Option<(String, bool)>,
}

/// Opens the profile and the terrain the flags name, and the start camera (`--camera`, else the
/// terrain's default view).
pub(crate) fn start(
    profile: &ProfileArgs,
    size: Option<Size>,
    terrain: &TerrainArgs,
    stream: &StreamArgs,
    shading: &ShadingArgs,
    camera: Option<&str>,
) -> Result<ViewStart> {
    let mut p = profile.load()?;
    if let Some(s) = size {
        (p.view.width, p.view.height) = s.pair();
    }
    if shading.reference {
        return Err(arg_error(
            "--reference",
            "applies to render and fly, not view",
        ));
    }
    let sg = shading.choice(&p)?;
    if sg.as_ref().is_some_and(|c| c.patches != Patches::default()) {
        return Err(arg_error(
            "--patches",
            "applies to render and fly; view draws SG with the default patches",
        ));
    }
    let sg = sg.map(|c| {
        (
            shading.scene.clone().unwrap_or_else(|| "noon".into()),
            c.shadows,
        )
    });
    let terrain = terrain.open(stream.streams(None)?, true)?;
    let c = terrain.default_camera()?;
    let c = c.get();
    let (eye, target) = match camera {
        Some(text) => {
            let eye = parse_vec3("--camera", text)?;
            (eye, eye + c.forward())
        }
        None => (c.eye, c.target),
    };
    let (w, h) = terrain.size();
    let spacing_m = terrain.spacing_m();
    Ok(ViewStart {
        size: (p.view.width, p.view.height),
        fov_y_deg: f64::from(p.view.fov_y_deg),
        epsilon_px: p.view.epsilon_px,
        profile: clipsat::Profile::from_stages(p),
        terrain,
        eye: eye.to_array(),
        target: target.to_array(),
        near_far: (c.near, c.far),
        spacing_m,
        extent_m: (
            f64::from(w.saturating_sub(1)) * f64::from(spacing_m),
            f64::from(h.saturating_sub(1)) * f64::from(spacing_m),
        ),
        sg,
    })
}

/// The SG shading the view drew, for the headless path to draw the same.
pub(crate) struct HeadlessSg<'a> {
    /// The scene's name or file.
    pub(crate) scene: &'a str,
    /// The effects switched on.
    pub(crate) visibility: bool,
    pub(crate) specular: bool,
    pub(crate) fog: bool,
}

/// The view's last frame, for the headless path to draw again.
pub(crate) struct HeadlessView<'a> {
    pub(crate) terrain: &'a TerrainArgs,
    pub(crate) stream: &'a StreamArgs,
    pub(crate) profile: &'a ProfileArgs,
    /// The window's size.
    pub(crate) size: (u32, u32),
    pub(crate) eye: [f64; 3],
    pub(crate) target: [f64; 3],
    pub(crate) fov_y_deg: f64,
    pub(crate) near_far: (f64, f64),
    pub(crate) options: FrameOptions,
    pub(crate) epsilon_px: f32,
    pub(crate) sg: Option<HeadlessSg<'a>>,
}

/// Draws `frames` frames of `view` through `clipsat render`'s headless path (a fresh context of `gpu`,
/// a [`TerrainRenderer`] filled at the eye first, as `render` does), calling `each` with every frame's ms
/// (update + plan + draw + read-back + hash). Returns the context: GL_VERSION and GL_RENDERER.
pub(crate) fn time_headless(
    view: &HeadlessView<'_>,
    gpu: GpuArg,
    frames: u32,
    mut each: impl FnMut(f64),
) -> Result<String> {
    let mut profile = view.profile.load()?;
    (profile.view.width, profile.view.height) = view.size;
    let terrain = view.terrain.open(view.stream.streams(None)?, false)?;
    let camera = Camera::look_at(view.eye, view.target, view.fov_y_deg)?
        .with_clip(view.near_far.0, view.near_far.1)?;
    let gpu = Gpu::new(GpuMode::from(gpu))?;
    let targets = Targets::new(&gpu, view.size.0, view.size.1)?;
    let mut options = RenderOptions::default()
        .color_format(targets.color_format())
        .depth_format(targets.depth_format())
        .imagery_rgba8(view.terrain.imagery_rgba8);
    if view.options.lod != LodMode::Distance {
        options = options.sat_lod_px(view.epsilon_px);
    }
    if let Some(sg) = &view.sg {
        options = options.sg_scene(sg.scene);
    }
    let mut renderer = TerrainRenderer::new(
        gpu.device(),
        gpu.queue(),
        terrain,
        &clipsat::Profile::from_stages(profile),
        &options,
    )?;
    let mut drawn = view.options;
    if let Some(sg) = &view.sg {
        drawn.visibility = sg.visibility;
        drawn.specular = sg.specular;
        drawn.fog = sg.fog;
    }
    if drawn != renderer.frame_options() {
        renderer.set_frame_options(gpu.queue(), drawn)?;
    }
    renderer.warm_up(gpu.queue(), &camera, view.size)?;
    for _ in 0..frames {
        let t = std::time::Instant::now();
        renderer.prepare(gpu.queue(), &camera, view.size)?;
        targets.draw("clipmap", clipsat::shading::basic::SKY, |pass| {
            renderer.render(pass);
        })?;
        targets.read_image()?.hash();
        each(t.elapsed().as_secs_f64() * 1e3);
    }
    let report = gpu.report();
    Ok(format!("{}, {}", report.gl_version, report.name))
}
