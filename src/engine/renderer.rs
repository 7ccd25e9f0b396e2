//! The embedding API: the terrain drawn on the caller's device into the caller's render pass. Each frame
//! runs the stages in order: the clipmap's budgeted update and the plan (stage 2, CPU, allocation-free),
//! the uploads and the draws (stage 3).

use crate::bake::lod_tables::LodMode;
use crate::gpu::renderer::{Renderer, RendererOptions, SgShading, Shading};
use crate::gpu::shaders::SgOmit;
use crate::plan::clipmap::{Clipmap, ClipmapOptions};
use crate::plan::color_rings::{ColorRings, FADE_FRAMES};
use crate::plan::frame_plan::{FramePlan, LodSetup, PlanParams, Planner};
use crate::progress::Progress;
use crate::shading::scene::Scene;
use crate::shading::Patches;
use crate::{Camera, Error, Profile, Result, Terrain};

use super::setup;

mod frame_options;
#[cfg(feature = "internals")]
mod instrument;
mod recover;

pub use frame_options::FrameOptions;
#[cfg(feature = "internals")]
pub use instrument::Stages;

/// What a [`TerrainRenderer`] is built with: the caller's target formats, and the choices fixed for its
/// life. The default is basic shading with distance LOD into `Rgba8Unorm` / `Depth32Float`.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub struct RenderOptions<'a> {
    /// The colour attachment's format in the caller's pass. The terrain's colours are display-encoded
    /// (gamma 2.2): a linear-format target (`Rgba8Unorm`, `Bgra8Unorm`) stores them as they are; an sRGB
    /// target (`*Srgb`) is given the linear values whose sRGB encoding they are, so both store the same
    /// bytes (within one level of rounding).
    pub color_format: wgpu::TextureFormat,
    /// The depth attachment's format: `Depth32Float`, `Depth24Plus` or `Depth24PlusStencil8` (the
    /// terrain leaves the stencil alone).
    pub depth_format: wgpu::TextureFormat,
    /// Reverse-Z: the terrain depth-tests with `Greater` and the caller clears depth to 0; otherwise
    /// `Less`, cleared to 1. Every frame's camera must agree ([`Camera::with_reverse_z`]).
    pub reverse_z: bool,
    /// The pass's sample count.
    pub sample_count: u32,
    /// SAT LOD at this screen-space error bound, pixels: each block takes the coarsest level whose
    /// conservative error bound stays under it, refined from a detail pool where the rings are too coarse.
    /// None: each ring at its own level (distance LOD). The first frame's mode: another is set between
    /// frames with [`TerrainRenderer::set_frame_options`] ([`crate::FrameOptions::lod`]).
    pub sat_lod_px: Option<f32>,
    /// SG shading of a scene: a shipped name (`noon`, `evening`, `overcast`) or a scene TOML file. None:
    /// basic shading only. With a scene, SG and its effects (within the scene's) are switched between
    /// frames with [`TerrainRenderer::set_frame_options`].
    pub sg_scene: Option<&'a str>,
    /// Where the set-up's bakes (SAT LOD tables, SG tables) report their progress.
    pub progress: Progress<'a>,
    /// SG's patches per lobe (a measurement's choice, `RenderOptions::sg_instrument`).
    pub(crate) sg_patches: Patches,
    /// Whether SG's visibility is baked and drawn (off: the scene's visibility dropped, no horizons).
    pub(crate) sg_shadows: bool,
    /// Draped imagery's colour rings in RGBA8 (4 bytes a texel) even where the device has BC or ETC2
    /// texture compression, whose blocks (0.5 byte a texel) it takes otherwise.
    pub imagery_rgba8: bool,
}

impl Default for RenderOptions<'_> {
    fn default() -> Self {
        Self {
            color_format: wgpu::TextureFormat::Rgba8Unorm,
            depth_format: wgpu::TextureFormat::Depth32Float,
            reverse_z: false,
            sample_count: 1,
            sat_lod_px: None,
            sg_scene: None,
            progress: Progress::default(),
            sg_patches: Patches::default(),
            sg_shadows: true,
            imagery_rgba8: false,
        }
    }
}

/// Refuses a device whose limits are below what `profile` creates: its textures' sides (the rings,
/// the detail pool's layers, the SG sky table) and array layers.
fn check_limits(limits: &wgpu::Limits, profile: &crate::profile::Profile) -> Result<()> {
    let side = profile
        .clip_size()
        .max(profile.detail_atlas().layer_side())
        .max(crate::profile::SG_SKY_SIDE);
    let layers = profile
        .height_layers()
        .max(profile.detail_layers())
        .max(crate::profile::SG_SKY_LAYERS);
    for (limit, needed, available) in [
        (
            "max_texture_dimension_2d",
            side,
            limits.max_texture_dimension_2d,
        ),
        (
            "max_texture_array_layers",
            layers,
            limits.max_texture_array_layers,
        ),
    ] {
        if needed > available {
            return Err(Error::Unsupported {
                limit,
                needed: u64::from(needed),
                available: u64::from(available),
            });
        }
    }
    Ok(())
}

/// What one frame did, within the profile's budget.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct FrameStats {
    /// Draw calls recorded.
    pub draws: u32,
    /// Triangles drawn.
    pub triangles: u64,
    /// Height samples the clipmap's update wrote (at most the profile's update budget).
    pub samples_updated: u32,
    /// Rings still short of their place around the eye (a fast flight outruns the budget).
    pub stale_levels: u32,
    /// SAT LOD: visible blocks drawn coarser than the error bound asks (the data, memory or the frame's
    /// budgets not yet at hand).
    pub blocks_clamped: u32,
    /// SAT LOD: the largest screen-space error bound, pixels, those blocks are drawn at: what the frame
    /// misses epsilon by (0 when it meets it everywhere in view). While the camera moves, a detail pool
    /// cell's bound not asked again this frame is its last one rescaled by its block's change of scale (an
    /// estimate, up to 1/32 past epsilon while moving). Infinite while a block is
    /// drawn at a level past the SAT LOD tables' (just after a jump), whose error is not known.
    pub unmet_px: f32,
    /// The plan's 64-bit hash: the same terrain, profile, options and cameras give the same hashes on
    /// every machine.
    pub plan_hash: u64,
}

/// A terrain drawn on the caller's wgpu device (the GLES 3.0 downlevel limits suffice) into the caller's
/// render pass, the egui-wgpu way: [`TerrainRenderer::prepare`] each frame, then
/// [`TerrainRenderer::render`] into a pass. Everything is allocated by [`TerrainRenderer::new`], from the
/// profile; a frame allocates nothing.
#[derive(Debug)]
pub struct TerrainRenderer {
    /// The terrain's name in reports.
    name: String,
    /// The whole grid, or a streamed terrain's coarse stand-in (the clipmap holds its package).
    pub(super) stand_in: crate::source::Heightmap,
    pub(super) clipmap: Clipmap,
    planner: Planner,
    pub(super) plan: FramePlan,
    renderer: Renderer,
    params: PlanParams,
    /// Draped imagery's colour rings ([`crate::TerrainOptions::imagery`]).
    imagery: Option<ColorRings>,
    /// The depth convention of the pipelines ([`RenderOptions::reverse_z`]).
    reverse_z: bool,
    /// The caller's device the GPU objects live on (a handle): its error scopes catch each frame's
    /// errors ([`TerrainRenderer::prepare`]); [`TerrainRenderer::rebuild`] replaces it.
    device: wgpu::Device,
    /// The exact queries' state (`engine/query.rs`) and the block side m of the profile.
    pub(super) queries: super::query_state::Queries,
    pub(super) block_quads: u32,
    /// What the frames draw ([`TerrainRenderer::set_frame_options`]).
    frame: FrameOptions,
    /// The SG scene's effects the renderer was built with (None: basic shading only).
    sg_effects: Option<crate::shading::scene::Effects>,
    /// Whether that scene gives fog parameters ([`FrameOptions::fog`] has no effect without them).
    sg_fog: bool,
    /// The SAT LOD tables, once loaded, kept while distance LOD is drawn.
    lod_tables: Option<crate::plan::lod::Lod>,
    /// The terrain's cache folder, where a SAT mode set later bakes its tables.
    cache: Option<std::path::PathBuf>,
    /// The last frame's plan time, nanoseconds (a measurement's, `TerrainRenderer::stages`).
    plan_ns: u64,
}

impl TerrainRenderer {
    /// Builds the CPU state and every GPU object for `terrain` under `profile`: the clipmap, the planner
    /// and, as `options` choose, the SAT LOD tables and SG's shading tables (baked into the terrain's
    /// cache folder on first use). Refuses a device below the profile's needs
    /// ([`Error::Unsupported`]), a scene the profile does not allow, and a SAT LOD bound that is not
    /// positive.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        terrain: Terrain,
        profile: &Profile,
        options: &RenderOptions<'_>,
    ) -> Result<Self> {
        let profile = &profile.0;
        if let Some(px) = options.sat_lod_px {
            if !(px.is_finite() && px > 0.0) {
                return Err(Error::Invalid {
                    what: "RenderOptions::sat_lod_px".into(),
                    reason: format!("{px} px is not a positive error bound"),
                });
            }
        }
        let cache = terrain.cache_dir().map(std::path::Path::to_path_buf);
        let mut terrain = terrain;
        let imagery = terrain.take_imagery_package();
        // Draped imagery, on a profile that allows it: its tile cache and staging come out of the CPU
        // budget before the heights' split.
        let with_imagery;
        let profile = match &imagery {
            Some(_) => {
                with_imagery = setup::imagery_profile(profile)?;
                &with_imagery
            }
            None => profile,
        };
        let mut imagery = imagery
            .map(|p| {
                let format = Renderer::imagery_format(device, options.imagery_rgba8);
                ColorRings::with_format(p, &profile.imagery, format)
            })
            .transpose()?;
        let (name, stand_in, package) = terrain.into_parts();
        let clipmap = match package {
            Some(p) => Clipmap::streamed(p, profile, ClipmapOptions::default())?,
            None => Clipmap::new(&stand_in, profile, ClipmapOptions::default())?,
        };
        let queries = super::query_state::Queries::new(&clipmap, &stand_in, profile)?;
        let lod = match options.sat_lod_px {
            // The bound itself is a per-frame parameter (`params` below, [`Self::set_sat_lod_px`]).
            Some(_) => {
                let lod = setup::sat_lod(
                    &stand_in,
                    profile,
                    &clipmap,
                    cache.as_deref(),
                    options.sg_scene.is_some(),
                    options.progress,
                )?;
                LodSetup::new(LodMode::SatConservative, Some(lod))?
            }
            None => LodSetup::Distance,
        };
        let sg = match options.sg_scene {
            Some(name) => {
                let mut scene = Scene::load(name)?;
                scene.effects.visibility &= options.sg_shadows;
                scene.check_profile(name, profile)?;
                Some(setup::sg_tables(
                    profile,
                    &stand_in,
                    clipmap.tile_cache().map(crate::package::TileCache::package),
                    &scene,
                    options.sg_shadows,
                    cache.as_deref(),
                    options.progress,
                )?)
            }
            None => None,
        };
        let shading = match &sg {
            Some((scene, bake)) => Shading::Sg(SgShading {
                scene,
                patches: options.sg_patches,
                bake,
                omit: SgOmit::None,
            }),
            None => Shading::Basic,
        };
        let planner = Planner::new(profile, &clipmap, lod)?;
        let plan = planner.new_plan();
        check_limits(&device.limits(), profile)?;
        // Validation and out-of-memory errors of the set-up come back as errors, not as the device's
        // uncaptured-error handler (which panics by default).
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let renderer = Renderer::new(
            device,
            queue,
            &RendererOptions {
                color_format: options.color_format,
                depth_format: options.depth_format,
                reverse_z: options.reverse_z,
                sample_count: options.sample_count,
                shading,
                ..RendererOptions::default()
            },
            profile,
        )
        .and_then(|mut r| {
            if let Some(rings) = &imagery {
                r.enable_imagery(device, rings.ring(), rings.level_count(), rings.format())?;
            }
            Ok(r)
        });
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = v.or(o) {
            return Err(Error::Gpu {
                action: "creating the terrain renderer".into(),
                source: Some(Box::new(e)),
            });
        }
        let renderer = renderer?;
        let lod_mode = if options.sat_lod_px.is_some() {
            LodMode::SatConservative
        } else {
            LodMode::Distance
        };
        let sg_effects = sg.as_ref().map(|(scene, _)| scene.effects);
        let sg_fog = sg.as_ref().is_some_and(|(scene, _)| scene.fog.is_some());
        Ok(Self {
            name,
            stand_in,
            clipmap,
            planner,
            plan,
            renderer,
            params: PlanParams {
                epsilon_px: options.sat_lod_px,
                ..PlanParams::default()
            },
            imagery: imagery.take(),
            reverse_z: options.reverse_z,
            device: device.clone(),
            queries,
            block_quads: profile.block_m(),
            frame: FrameOptions::initial(lod_mode, sg_effects),
            sg_effects,
            sg_fog,
            lod_tables: None,
            cache,
            plan_ns: 0,
        })
    }

    /// Refuses a camera whose depth convention is not the pipelines', or whose projection's aspect is not
    /// the viewport's.
    fn check_camera(&self, camera: &Camera, viewport: (u32, u32)) -> Result<()> {
        let c = &camera.0;
        if c.reverse_z != self.reverse_z {
            return Err(Error::camera(format!(
                "the camera's depth is {}, the renderer's {} (RenderOptions::reverse_z)",
                if c.reverse_z { "reverse-Z" } else { "conventional" },
                if self.reverse_z { "reverse-Z" } else { "conventional" },
            )));
        }
        if let Some(a) = c.aspect {
            let v = f64::from(viewport.0) / f64::from(viewport.1.max(1));
            if (a / v - 1.0).abs() > 1e-3 {
                return Err(Error::camera(format!(
                    "the projection's aspect {a:.4} is not the viewport's {v:.4} ({} x {})",
                    viewport.0, viewport.1
                )));
            }
        }
        Ok(())
    }

    /// Fills the clipmap (and, with SAT LOD, the detail pool) for `camera` in a `viewport` of (width,
    /// height) pixels, frame by frame under the update budget, uploaded through `queue`: what to run
    /// before the first frame and after a jump, so that the next frame is drawn complete. A flight needs
    /// no warm-up: each frame's update fills what it can, coarse levels first. Returns the frames it took.
    pub fn warm_up(
        &mut self,
        queue: &wgpu::Queue,
        camera: &Camera,
        viewport: (u32, u32),
    ) -> Result<u32> {
        self.check_camera(camera, viewport)?;
        let eye = camera.0.eye;
        self.params.viewport = Some(viewport);
        let mut frames = self.clipmap.fill_at(eye, setup::MAX_FILL_FRAMES)?;
        if let Some(rings) = &mut self.imagery {
            // The colour rings until whole, and while the last fade in (bounded).
            let mut settled = None;
            for f in 0..setup::MAX_FILL_FRAMES {
                let s = rings.update(eye.x, eye.y)?;
                recover::scoped_imagery(&self.device, &self.renderer, queue, rings, (eye.x, eye.y))?;
                if s.stale_levels == 0 && settled.is_none() {
                    settled = Some(f);
                }
                if settled.is_some_and(|s| u64::from(f) >= u64::from(s) + FADE_FRAMES) {
                    break;
                }
            }
        }
        if self.planner.lod().is_some() {
            for _ in 0..setup::MAX_POOL_FRAMES {
                frames += 1;
                self.planner
                    .plan(&self.clipmap, &camera.0, &self.params, &mut self.plan)?;
                recover::scoped_prepare(
                    &self.device,
                    &mut self.renderer,
                    queue,
                    &self.clipmap,
                    &self.plan,
                )?;
                let wrote = self.plan.stats().detail_uploads;
                if setup::pool_step(&mut self.clipmap, eye, &self.plan, wrote)? {
                    break;
                }
            }
        }
        Ok(frames)
    }

    /// One frame seen from `camera` in a viewport of `viewport` (width, height) pixels: the clipmap's
    /// update under the budget, the plan, and its uploads through `queue`. Then record it with
    /// [`TerrainRenderer::render`]. A new viewport size (a resize) needs nothing else.
    ///
    /// The uploads run inside wgpu error scopes on the renderer's device: a wgpu error of them
    /// (validation, out of memory, internal) is [`Error::Gpu`], with wgpu's error as its source, and never
    /// reaches the device's uncaptured-error handler, which stays the caller's. On a lost device wgpu
    /// reports no error (see [`TerrainRenderer::rebuild`]).
    pub fn prepare(
        &mut self,
        queue: &wgpu::Queue,
        camera: &Camera,
        viewport: (u32, u32),
    ) -> Result<FrameStats> {
        self.check_camera(camera, viewport)?;
        self.params.viewport = Some(viewport);
        self.plan_ns = setup::frame_cpu(
            &mut self.clipmap,
            &mut self.planner,
            &camera.0,
            &self.params,
            &mut self.plan,
            |plan| {
                let t = std::time::Instant::now();
                plan()?;
                Ok(u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX))
            },
        )?;
        let frame = self.clipmap.frame();
        let (samples_updated, stale_levels) = (frame.samples_updated, frame.stale_levels);
        recover::scoped_prepare(
            &self.device,
            &mut self.renderer,
            queue,
            &self.clipmap,
            &self.plan,
        )?;
        // Draped imagery: its rings' update and uploads, their hash folded into the plan's.
        let mut plan_hash = self.plan.hash();
        if let Some(rings) = &mut self.imagery {
            let eye = camera.0.eye;
            let c = rings.update(eye.x, eye.y)?;
            recover::scoped_imagery(&self.device, &self.renderer, queue, rings, (eye.x, eye.y))?;
            let mut h = crate::hash::Hash64::new();
            h.write_u64(plan_hash);
            h.write_u64(c.hash);
            plan_hash = h.finish();
        }
        let s = self.plan.stats();
        Ok(FrameStats {
            draws: s.draws,
            triangles: s.triangles,
            samples_updated,
            stale_levels,
            blocks_clamped: s.blocks_clamped,
            unmet_px: s.unmet_px,
            plan_hash,
        })
    }

    /// Records the prepared frame into the caller's pass (its colour and depth attachments of the
    /// formats given at construction); sets its own pipelines and bindings.
    ///
    /// The caller's pass is the caller's to validate: wgpu reports an error of the recorded draws when
    /// the caller finishes its command encoder (a few at the recording call), to the error scopes open
    /// then, else to the device's uncaptured-error handler (wgpu's default one panics). To have them as
    /// values, push error scopes (validation, out of memory) before the pass and pop them after
    /// `CommandEncoder::finish` and `Queue::submit`, or set a handler with
    /// [`wgpu::Device::on_uncaptured_error`].
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.renderer.render(pass);
    }

    /// Sets SAT LOD's screen-space error bound, pixels, from the next frame on (no rebuild): the bound
    /// a frame is drawn within, traded against triangles and plan time. Refused while the renderer draws
    /// distance LOD ([`FrameOptions::lod`]) and for a bound that is not positive.
    pub fn set_sat_lod_px(&mut self, px: f32) -> Result<()> {
        if self.planner.lod().is_none() {
            return Err(Error::Invalid {
                what: "TerrainRenderer::set_sat_lod_px".into(),
                reason: "the renderer draws distance LOD (FrameOptions::lod)".into(),
            });
        }
        if !(px.is_finite() && px > 0.0) {
            return Err(Error::Invalid {
                what: "TerrainRenderer::set_sat_lod_px".into(),
                reason: format!("{px} px is not a positive error bound"),
            });
        }
        self.params.epsilon_px = Some(px);
        Ok(())
    }

    /// SAT LOD's screen-space error bound, pixels (None: distance LOD). A SAT mode set with
    /// [`TerrainRenderer::set_frame_options`] on a renderer built with distance LOD draws at the
    /// profile's bound until one is set.
    pub fn sat_lod_px(&self) -> Option<f32> {
        self.planner.lod().map(|_| {
            self.params
                .epsilon_px
                .unwrap_or(self.renderer.profile().view.epsilon_px)
        })
    }

    /// The terrain's name ([`Terrain::name`]).
    pub fn terrain_name(&self) -> &str {
        &self.name
    }

    /// The height of the surface drawn under the camera's eye, metres (None before the rings reach it):
    /// what keeps a flying camera above the ground.
    pub fn surface_height(&self, camera: &Camera) -> Option<f32> {
        self.clipmap.surface_height(camera.0.eye)
    }

    /// Bytes of GPU memory the renderer holds (fixed at construction).
    pub fn gpu_bytes(&self) -> u64 {
        self.renderer.ledger().bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device below the profile is refused with the limit, what the profile needs and what it has.
    #[test]
    fn a_device_below_the_profile_is_unsupported() {
        let profile = crate::profile::Profile::load("gles3-mid").expect("shipped profile");
        let floor = wgpu::Limits::downlevel_webgl2_defaults();
        assert!(check_limits(&floor, &profile).is_ok(), "the GLES 3.0 floor");
        let few = wgpu::Limits {
            max_texture_array_layers: 4,
            ..floor.clone()
        };
        match check_limits(&few, &profile) {
            Err(Error::Unsupported {
                limit: "max_texture_array_layers",
                needed,
                available: 4,
            }) => assert!(needed > 4),
            other => panic!("{other:?}"),
        }
        let small = wgpu::Limits {
            max_texture_dimension_2d: 64,
            ..floor
        };
        assert!(matches!(
            check_limits(&small, &profile),
            Err(Error::Unsupported {
                limit: "max_texture_dimension_2d",
                ..
            })
        ));
    }
}
