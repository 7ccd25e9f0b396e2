//! The embedding API: the per-frame options of a [`TerrainRenderer`] (LOD mode, morph, culling, debug
//! view, SG shading and its effects), set between frames without building the renderer again: the
//! plan's switches (stage 2) and the GPU side's programs (stage 3).

use super::{setup, TerrainRenderer};
use crate::bake::lod_tables::LodMode;
use crate::gpu::scope::scoped;
use crate::plan::frame_plan::{LodSetup, Planner};
use crate::plan::lod::Lod;
use crate::progress::Progress;
use crate::shading::debug_view::DebugView;
use crate::{Error, Result};

/// What a [`TerrainRenderer`] draws each frame, switched between frames with
/// [`TerrainRenderer::set_frame_options`] (no rebuild by the caller). Read the current options with
/// [`TerrainRenderer::frame_options`], change fields, set them back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct FrameOptions {
    /// How blocks choose their level. A SAT mode on a renderer built with distance LOD loads (or bakes,
    /// through the terrain's cache folder) the SAT LOD tables when it is first set; its error bound is
    /// then the profile's until [`TerrainRenderer::set_sat_lod_px`] sets one. Default: `SatConservative`
    /// with [`crate::RenderOptions::sat_lod_px`], else `Distance`.
    pub lod: LodMode,
    /// The geometry clipmap's transition morph between rings (distance LOD; the SAT modes never morph).
    /// Default on.
    pub morph: bool,
    /// Frustum culling of blocks (off: every block is drawn). Default on.
    pub cull: bool,
    /// The shading, or a debug view of the LOD (each block in its level's colour, or its lattice lines).
    /// Default `Normal`.
    pub debug: DebugView,
    /// SG shading (on a renderer built with [`crate::RenderOptions::sg_scene`]) or the basic shading.
    /// Default: on with a scene.
    pub sg: bool,
    /// SG: horizon visibility (soft terrain shadows), if the scene has it. Default: the scene's.
    pub visibility: bool,
    /// SG: specular, if the scene has it. Default: the scene's.
    pub specular: bool,
    /// SG: distance fog, if the scene has it; no effect (drawn and read back off) where the scene gives
    /// no fog parameters. Default: the scene's.
    pub fog: bool,
}

impl Default for FrameOptions {
    /// Distance LOD, morph and culling on, the basic shading.
    fn default() -> Self {
        Self::initial(LodMode::Distance, None)
    }
}

impl FrameOptions {
    /// The options a renderer starts with: `lod` as built, `sg` on with a scene of these `effects`.
    pub(super) fn initial(lod: LodMode, sg: Option<crate::shading::scene::Effects>) -> Self {
        Self {
            lod,
            morph: true,
            cull: true,
            debug: DebugView::Normal,
            sg: sg.is_some(),
            visibility: sg.is_some_and(|e| e.visibility),
            specular: sg.is_some_and(|e| e.specular),
            fog: sg.is_some_and(|e| e.fog),
        }
    }
}

impl TerrainRenderer {
    /// The options the next frame draws with.
    pub fn frame_options(&self) -> FrameOptions {
        self.frame
    }

    /// Draws with `options` from the next [`TerrainRenderer::prepare`] on ([`FrameOptions::fog`] reads
    /// back off where the scene has no fog parameters). Morph, culling, SG on or off
    /// and SG's effects are switches (a set of effects drawn for the first time compiles its programs).
    /// A new LOD mode or debug view makes the GPU side again on the renderer's device, as
    /// [`TerrainRenderer::rebuild`] does (nothing is baked but a SAT mode's tables the first time, and
    /// the next frame uploads the rings in full). Refused: SG on a renderer built without a scene, an SG
    /// effect the scene does not have. An error, refused or from the GPU (`Error::Gpu`) or the SAT LOD
    /// tables' bake, changes nothing: the renderer draws as before.
    pub fn set_frame_options(&mut self, queue: &wgpu::Queue, options: FrameOptions) -> Result<()> {
        let invalid = |reason: String| Error::Invalid {
            what: "TerrainRenderer::set_frame_options".into(),
            reason,
        };
        // Everything that can fail runs first, on new objects; the renderer changes only once all of it
        // has succeeded, so a refused or failed switch leaves it drawing as before.
        let effects = match self.sg_effects {
            None if options.sg => {
                return Err(invalid(
                    "SG shading needs a scene (RenderOptions::sg_scene was None)".into(),
                ))
            }
            None => None,
            Some(built) => {
                let mut effects = built;
                // Fog without the scene's parameters draws nothing: no effect, not refused.
                let fog = options.fog && self.sg_fog;
                (effects.visibility, effects.specular, effects.fog) =
                    (options.visibility, options.specular, fog);
                for (on, has, name) in [
                    (effects.visibility, built.visibility, "visibility"),
                    (effects.specular, built.specular, "specular"),
                    (effects.fog, built.fog, "fog"),
                ] {
                    if on && !has {
                        return Err(invalid(format!("the SG scene has no {name}")));
                    }
                }
                Some(effects)
            }
        };
        let old = self.frame;
        let planner = if options.lod == old.lod {
            None
        } else {
            Some(self.planner_for(options.lod)?)
        };
        let device = self.device.clone();
        let rebuilt = if options.lod != old.lod || options.debug != old.debug {
            let mut renderer = scoped(&device, "switching the LOD mode or debug view", || {
                self.renderer.rebuild_with(&device, queue, options.debug)
            })?;
            if let Some(effects) = effects {
                scoped(&device, "switching the SG effects", || {
                    renderer.set_sg_effects(&device, effects)
                })?;
            }
            let plan = planner.as_ref().map_or(&self.plan, |(_, plan, _)| plan);
            scoped(&device, "sending the detail pool again", || {
                renderer.resend_detail(queue, &mut self.clipmap, plan)
            })?;
            // Draped imagery's rings into the new texture, as they are (no refill, no fade).
            if let Some(rings) = &self.imagery {
                scoped(&device, "sending the imagery's rings again", || {
                    renderer.restore_imagery(queue, rings)
                })?;
            }
            Some(renderer)
        } else {
            if let Some(effects) = effects {
                scoped(&device, "switching the SG effects", || {
                    self.renderer.set_sg_effects(&device, effects)
                })?;
            }
            None
        };
        if let Some((planner, plan, tables)) = planner {
            self.planner = planner;
            self.plan = plan;
            self.lod_tables = tables;
        }
        if let Some(renderer) = rebuilt {
            self.renderer = renderer;
        }
        if effects.is_some() {
            self.renderer.set_sg_enabled(options.sg);
        }
        self.params.morph = options.morph;
        self.params.cull = options.cull;
        self.frame = FrameOptions {
            fog: options.fog && self.sg_fog,
            ..options
        };
        Ok(())
    }

    /// A new planner for `mode` and its first plan, with the SAT LOD tables to keep: the ones held, or
    /// loaded the first time a SAT mode needs them.
    fn planner_for(
        &self,
        mode: LodMode,
    ) -> Result<(Planner, crate::plan::frame_plan::FramePlan, Option<Lod>)> {
        let mut tables = self.planner.lod().cloned().or_else(|| self.lod_tables.clone());
        if mode != LodMode::Distance && tables.is_none() {
            tables = Some(setup::sat_lod(
                &self.stand_in,
                self.renderer.profile(),
                &self.clipmap,
                self.cache.as_deref(),
                self.sg_effects.is_some(),
                Progress::default(),
            )?);
        }
        let setup = match mode {
            LodMode::Distance => LodSetup::Distance,
            m => LodSetup::new(m, tables.clone())?,
        };
        let planner = Planner::new(self.renderer.profile(), &self.clipmap, setup)?;
        let plan = planner.new_plan();
        Ok((planner, plan, tables))
    }
}
