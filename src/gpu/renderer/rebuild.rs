//! Stage 3, the GPU: the renderer made again on a new device after its own was lost (an Android app sent
//! to the background loses its GL context), from what it keeps in CPU memory: the profile, the target
//! formats, the SG scene and its CPU bake. Nothing is baked or read from a package; the new textures are
//! empty until the next [`Renderer::prepare`] re-sends every ring, pool tile and SG table texel in full.

use super::frame::write_detail_tile;
use super::{Renderer, RendererOptions, SgShading, Shading};
use crate::plan::clipmap::Clipmap;
use crate::plan::detail::fill_tile;
use crate::plan::frame_plan::FramePlan;
use crate::profile::Profile;
use crate::shading::debug_view::DebugView;
use crate::{Error, Result};

impl Renderer {
    /// The profile it was built for.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// A renderer like this one on `device` (a new device, this one's being lost): the same profile,
    /// target formats, sample count, debug view and shading (the SG scene, its sky table and the level
    /// tables' CPU bake, all kept by this renderer), draped imagery's objects when this one has
    /// them, and the same SG effects and switches. Creates every GPU object again, as
    /// [`Renderer::new`] does; its textures hold nothing yet: it knows no frame, so the next
    /// [`Renderer::prepare`] sends every ring, pool tile and SG table texel of the plan in full. This
    /// renderer is left as it was (drop it).
    pub fn rebuild(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Renderer> {
        self.rebuild_with(device, queue, self.debug)
    }

    /// [`Renderer::rebuild`] with another debug view (the debug view is fixed per renderer: it is part of
    /// every program).
    pub fn rebuild_with(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        debug: DebugView,
    ) -> Result<Renderer> {
        let shading = match &self.sg {
            // The scene as drawn: visibility as bound, fog as fitted (both idempotent in SgState::new).
            Some(sg) => Shading::Sg(SgShading {
                scene: &sg.scene,
                patches: sg.variant.patches,
                bake: sg.tables.bake(),
                omit: sg.variant.omit,
            }),
            None => Shading::Basic,
        };
        // Every field named (no `..Default::default()`): a new option must be carried over here too.
        let options = RendererOptions {
            color_format: self.targets.color,
            depth_format: self.targets.depth,
            reverse_z: self.targets.compare == wgpu::CompareFunction::Greater,
            sample_count: self.targets.samples,
            shading,
            debug,
        };
        // The sky table is the scene's, kept: integrating it again is most of the CPU work.
        let sky = self.sg.as_ref().map(|sg| &sg.sky);
        let mut new = Renderer::build(device, queue, &options, &self.profile, sky)?;
        // Imagery before the effects: its SG programs are of the variant drawn when it was enabled.
        if let Some(i) = &self.imagery {
            new.enable_imagery(device, i.ring, i.levels, i.format)?;
        }
        if let Some(sg) = &self.sg {
            let mut effects = sg.scene.effects;
            effects.visibility = sg.variant.visibility;
            effects.specular = sg.variant.specular;
            effects.fog = sg.variant.fog;
            new.set_sg_effects(device, effects)?;
        }
        new.sg_enabled = self.sg_enabled;
        Ok(new)
    }

    /// Sends every tile the detail pool holds after `plan` (the last plan prepared, on the lost device)
    /// from `clipmap`'s source, so that the next plan's pool uploads follow on. A tile whose package tiles
    /// a streamed terrain's cache has evicted since it was filled is decoded again first, past the frame's
    /// budget, one tile at a time (the only package reads of a rebuild). Returns the tiles that needed
    /// it. Refused if the cache cannot hold even one tile's package tiles.
    pub fn resend_detail(
        &mut self,
        queue: &wgpu::Queue,
        clipmap: &mut Clipmap,
        plan: &FramePlan,
    ) -> Result<u32> {
        let d = plan.detail();
        let quads = self.detail_quads;
        let mut decoded = 0;
        for (slot, key) in (0u32..).zip(&d.resident) {
            let Some(key) = key else { continue };
            if !fill_tile(&*clipmap, key, quads, &mut self.detail_staging) {
                let ready = clipmap.decode_now(key.level, &key.samples(quads))?
                    && fill_tile(&*clipmap, key, quads, &mut self.detail_staging);
                if !ready {
                    return Err(Error::Invalid {
                        what: "detail pool tile".into(),
                        reason: format!(
                            "level {} cell ({}, {}): the tile cache cannot hold its package tiles",
                            key.level, key.cx, key.cy
                        ),
                    });
                }
                decoded += 1;
            }
            write_detail_tile(queue, &self.detail, self.detail_atlas, &self.detail_staging, slot);
        }
        self.detail_synced = Some(d.seq);
        Ok(decoded)
    }
}
