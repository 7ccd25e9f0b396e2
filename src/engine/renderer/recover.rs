//! The embedding API: a frame's GPU errors returned to the caller, and the terrain renderer's GPU side
//! rebuilt on a new device after a lost one (stage 3 again from the kept CPU state of stages 1 and 2).

use super::{check_limits, TerrainRenderer};
use crate::gpu::renderer::Renderer;
use crate::gpu::scope::scoped;
use crate::plan::clipmap::Clipmap;
use crate::plan::color_rings::ColorRings;
use crate::plan::frame_plan::FramePlan;
use crate::Result;

impl TerrainRenderer {
    /// Builds the renderer's GPU side again on `device` and `queue` after the device it was built on was
    /// lost (an Android app sent to the background loses its GL context; the engine makes a new device
    /// when it comes back), from the state it keeps in CPU memory. Nothing is baked and nothing is read
    /// from the terrain's cache folder: the clipmap's rings, the detail pool, the SAT LOD tables, SG's
    /// shading tables and the plan stay as they are, and the buffers, textures and pipelines are created
    /// again (shader compilation and pipeline creation are most of the cost). The detail pool's tiles are
    /// sent again now, from the package tiles the tile cache holds (with SAT LOD on a streamed terrain, a
    /// pool tile whose package tiles the cache has evicted since it was filled is decoded again: the only
    /// package reads of a rebuild). The next [`TerrainRenderer::prepare`] then uploads the rings and the
    /// SG tables in full from their CPU copies, so frames go on as if the device had not been lost: the
    /// same plans and images. Draped imagery's colour rings keep no CPU copy of their texels: every texel
    /// they hold is decoded again from the imagery package now (its tiles under the rings, outside the
    /// frame's budget and the tile cache, whose state the next frames depend on).
    ///
    /// How to notice the loss: wgpu reports it to the callback set with
    /// [`wgpu::Device::set_device_lost_callback`], which belongs to the engine (clipsat sets none), with
    /// [`wgpu::DeviceLostReason::Unknown`] for a lost context (`Destroyed` after
    /// [`wgpu::Device::destroy`]). wgpu drops the errors of a lost device's work, so `prepare` and
    /// `render` go on without failing and draw nothing. Let the callback set a flag that the render loop
    /// reads; once it is set, make a new device and call this before the next `prepare`.
    ///
    /// Refuses a device below the profile's needs ([`crate::Error::Unsupported`]); a wgpu error while
    /// creating the objects is [`crate::Error::Gpu`]. On an error the renderer is left as it was, and can
    /// be rebuilt again on another device.
    pub fn rebuild(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<()> {
        check_limits(&device.limits(), self.renderer.profile())?;
        let mut renderer = scoped(
            device,
            "rebuilding the terrain renderer on a new device",
            || self.renderer.rebuild(device, queue),
        )?;
        // The detail pool's tiles, now: the next plan's pool uploads follow on from them.
        scoped(device, "sending the detail pool again", || {
            renderer.resend_detail(queue, &mut self.clipmap, &self.plan)
        })?;
        // Draped imagery's rings, now: every texel they hold, decoded again from the imagery package.
        if let Some(rings) = &self.imagery {
            scoped(device, "sending the imagery's rings again", || {
                renderer.restore_imagery(queue, rings)
            })?;
        }
        self.renderer = renderer;
        self.device = device.clone();
        Ok(())
    }

    /// The package tile cache's counters (tiles decoded, hits), for a streamed terrain: what the frames
    /// and a [`TerrainRenderer::rebuild`] read of the package.
    #[cfg(feature = "internals")]
    pub fn tile_cache_stats(&self) -> Option<crate::package::CacheStats> {
        self.clipmap.tile_cache().map(crate::package::TileCache::stats)
    }

    /// Creation time of the GPU objects, by kind ([`crate::gpu::renderer::Ledger::creation_time`]):
    /// where [`TerrainRenderer::new`] and [`TerrainRenderer::rebuild`] spend their GPU time.
    #[cfg(feature = "internals")]
    pub fn gpu_ledger(&self) -> &crate::gpu::renderer::Ledger {
        self.renderer.ledger()
    }
}

/// [`Renderer::prepare`] inside error scopes on `device`: a validation or out-of-memory error of the
/// frame's uploads comes back as [`crate::Error::Gpu`].
pub(super) fn scoped_prepare(
    device: &wgpu::Device,
    renderer: &mut Renderer,
    queue: &wgpu::Queue,
    clipmap: &Clipmap,
    plan: &FramePlan,
) -> Result<()> {
    scoped(device, "uploading the terrain's frame", || {
        renderer.prepare(queue, clipmap, plan).map(|_| ())
    })
}

/// [`Renderer::prepare_imagery`] inside error scopes on `device`.
pub(super) fn scoped_imagery(
    device: &wgpu::Device,
    renderer: &Renderer,
    queue: &wgpu::Queue,
    rings: &ColorRings,
    eye: (f64, f64),
) -> Result<()> {
    scoped(device, "uploading the imagery's frame", || {
        renderer.prepare_imagery(queue, rings, eye)
    })
}
