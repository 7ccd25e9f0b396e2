//! The embedding API's test instruments (the `internals` feature): a [`TerrainRenderer`]'s stages read
//! by the measurements that `clipsat render` reports beside its frame (cracks, screen error, oracles,
//! the SG and imagery reports). Not part of what an engine embeds, and not covered by semver.

use super::{RenderOptions, TerrainRenderer};
use crate::gpu::renderer::Renderer;
use crate::plan::clipmap::Clipmap;
use crate::plan::color_rings::ColorRings;
use crate::plan::frame_plan::{FramePlan, Planner};
use crate::shading::Patches;
use crate::source::Heightmap;

/// A renderer's stages as the last [`TerrainRenderer::prepare`] left them.
#[derive(Clone, Copy, Debug)]
#[non_exhaustive]
pub struct Stages<'a> {
    /// The clipmap: its rings, the detail pool and, streamed, the package's tile cache.
    pub clipmap: &'a Clipmap,
    /// The planner, with the SAT LOD selector of a SAT mode.
    pub planner: &'a Planner,
    /// The last frame's plan.
    pub plan: &'a FramePlan,
    /// The GPU side.
    pub renderer: &'a Renderer,
    /// Draped imagery's colour rings.
    pub imagery: Option<&'a ColorRings>,
    /// The whole grid, or a streamed terrain's coarse stand-in.
    pub stand_in: &'a Heightmap,
    /// Wall time of the last frame's plan, nanoseconds.
    pub plan_ns: u64,
}

impl TerrainRenderer {
    /// The stages, for a measurement of the last frame.
    pub fn stages(&self) -> Stages<'_> {
        Stages {
            clipmap: &self.clipmap,
            planner: &self.planner,
            plan: &self.plan,
            renderer: &self.renderer,
            imagery: self.imagery.as_ref(),
            stand_in: &self.stand_in,
            plan_ns: self.plan_ns,
        }
    }
}

impl RenderOptions<'_> {
    /// SG integrated over `patches` per lobe, and with `shadows` off the scene's visibility dropped (no
    /// horizon bake): what `clipsat render --patches`, `--no-shadows` measure.
    #[must_use]
    pub fn sg_instrument(mut self, patches: Patches, shadows: bool) -> Self {
        self.sg_patches = patches;
        self.sg_shadows = shadows;
        self
    }
}
