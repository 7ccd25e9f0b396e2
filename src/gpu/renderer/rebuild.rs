//! Stage 3, the GPU: the renderer made again on a new device after its own was lost (an Android app sent
//! to the background loses its GL context), from what it keeps in CPU memory: the profile, the target
//! formats, the SG scene and its CPU bake. Nothing is baked or read from a package; the new textures are
//! empty until the next [`Renderer::prepare`] re-sends every ring, pool tile and SG table texel in full.

use super::{Renderer, RendererOptions, SgShading, Shading};
use crate::profile::Profile;
use crate::Result;

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
            sample_count: self.targets.samples,
            shading,
            debug: self.debug,
        };
        // The sky table is the scene's, kept: integrating it again is most of the CPU work.
        let sky = self.sg.as_ref().map(|sg| &sg.sky);
        let mut new = Renderer::build(device, queue, &options, &self.profile, sky)?;
        // Imagery before the effects: its SG programs are of the variant drawn when it was enabled.
        if let Some(i) = &self.imagery {
            new.enable_imagery(device, i.ring, i.levels)?;
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
}
