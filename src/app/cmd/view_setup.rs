//! App: what `clipsat view` takes from its flags, and the headless `render` path it is timed against.
//!
//! The window (`app/cmd/view/`) draws through the public API only. This file turns the flags into
//! public values (a [`clipsat::Profile`] with the window's size, a [`clipsat::Terrain`], the start
//! camera) and holds the one thing the view measures through the stages: `--frames N` times the
//! headless path of `clipsat render` (the strict offscreen context, draw, read-back and hash) at the
//! same view. That path is a test instrument, not part of what an engine embeds.

use clipsat::gpu::headless::{
    render_frame, FrameOptions as HeadlessOptions, Offscreen, OffscreenOptions,
};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::package::TileCache;
use clipsat::plan::camera::{parse_vec3, Camera as StageCamera};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::frame_plan::LodSetup;
use clipsat::shading::scene::Scene;
use clipsat::shading::Patches;
use clipsat::{DebugView, FrameOptions, LodMode, Result, Terrain};

use super::args::{arg_error, GpuArg, Size, StreamArgs};
use super::render::{lod_for, open_terrain};
use super::sg::{self, SgChoice, ShadingArgs};
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
/// the clipmap filled at the eye first, as `render` does), calling `each` with every frame's ms
/// (update + plan + draw + read-back + hash). Returns the context: GL_VERSION and GL_RENDERER.
pub(crate) fn time_headless(
    view: &HeadlessView<'_>,
    gpu: GpuArg,
    frames: u32,
    mut each: impl FnMut(f64),
) -> Result<String> {
    let mut profile = view.profile.load()?;
    (profile.view.width, profile.view.height) = view.size;
    let (_, hm, package, _) = open_terrain(view.terrain, view.stream.streams(None)?, false)?;
    let camera = StageCamera::new(view.eye.into(), view.target.into(), view.fov_y_deg)?
        .with_clip(view.near_far.0, view.near_far.1)?;
    let gpu = Gpu::new(GpuMode::from(gpu))?;
    let mut clipmap = match package {
        Some(p) => Clipmap::streamed(p, &profile, ClipmapOptions::default())?,
        None => Clipmap::new(&hm, &profile, ClipmapOptions::default())?,
    };
    clipmap.fill_at(camera.eye, 10_000)?;
    let lod_mode: LodMode = view.options.lod;
    let lod = match lod_mode {
        LodMode::Distance => None,
        _ => Some(lod_for(&hm, &profile, &clipmap, true, true)?),
    };
    let choice = view
        .sg
        .as_ref()
        .map(|s| -> Result<SgChoice> {
            let mut scene = Scene::load(s.scene)?;
            scene.effects.visibility &= s.visibility;
            scene.effects.specular &= s.specular;
            scene.effects.fog &= s.fog;
            Ok(SgChoice {
                scene,
                patches: Patches::default(),
                shadows: s.visibility,
            })
        })
        .transpose()?;
    let baked = choice
        .as_ref()
        .map(|c| c.bake(&profile, &hm, clipmap.tile_cache().map(TileCache::package)))
        .transpose()?;
    let debug: DebugView = view.options.debug;
    let mut r = Offscreen::new(
        &gpu,
        &profile,
        &clipmap,
        OffscreenOptions {
            lod: LodSetup::new(lod_mode, lod)?,
            shading: sg::shading(choice.as_ref(), baked.as_ref()),
            debug,
        },
    )?;
    let opts = HeadlessOptions {
        morph: view.options.morph,
        cull: view.options.cull,
        epsilon_px: Some(view.epsilon_px),
        ..HeadlessOptions::default()
    };
    for _ in 0..frames {
        let t = std::time::Instant::now();
        clipmap.update(camera.eye)?;
        render_frame(&mut r, &clipmap, &camera, &opts)?;
        each(t.elapsed().as_secs_f64() * 1e3);
    }
    let report = gpu.report();
    Ok(format!("{}, {}", report.gl_version, report.name))
}
