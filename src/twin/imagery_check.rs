//! CPU twins of the shaders: the imagery frame check, one call that drapes a synthetic image on a
//! terrain, draws it on a device and compares it with its twin (`clipsat selftest`, `tests/gpu/imagery.rs`).

use crate::Result;

/// A frame with draped imagery against its twin, on `gpu`, for `clipsat selftest` and the tests: `hm`
/// from its default camera under `profile` (basic shading), draped with a synthetic 384^2 image over
/// its extent (gradients and a checker: every ring and tap shows), the rings filled and faded in, the
/// frame compared pixel by pixel with [`super::imagery::ImageryTwin`] through the shading probe
/// ([`super::frame::compare_imagery`]).
pub fn check_frame(
    gpu: &crate::gpu::Gpu,
    hm: &crate::source::Heightmap,
    profile: &crate::profile::Profile,
) -> Result<(super::frame::TwinReport, crate::gpu::readback::Image)> {
    use crate::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
    use crate::gpu::renderer::ShadingProbe;
    use crate::package::imagery::ImageryPackage;
    use crate::package::imagery_bake::bake_imagery;
    use crate::source::imagery::{Extent, Imagery};
    let n = 384u32;
    let mut texels = Vec::with_capacity((n * n * 3) as usize);
    for y in 0..n {
        for x in 0..n {
            let checker = if (x / 16 + y / 16) % 2 == 0 { 50 } else { 0 };
            let byte = |v: u32| u8::try_from(v % 256).unwrap_or(0);
            texels.extend_from_slice(&[
                byte(x * 255 / n),
                byte(y * 200 / n + checker),
                byte(x + y),
            ]);
        }
    }
    let grid = Extent::of_grid(
        hm.width(),
        hm.height(),
        f64::from(hm.spacing()),
        hm.origin(),
    );
    let path = std::path::Path::new("<selftest image>");
    let image = Imagery::from_rgb(path, n, n, texels, &grid, None)?;
    let (bytes, _) = bake_imagery(&image, crate::package::imagery::DEFAULT_QUALITY, 0)?;
    let profile = crate::engine::setup::imagery_profile(profile)?;
    let camera = crate::plan::camera::Camera::default_for(hm)?;
    let mut clipmap = crate::plan::clipmap::Clipmap::new(hm, &profile, Default::default())?;
    clipmap.fill_at(camera.eye, crate::engine::setup::MAX_FILL_FRAMES)?;
    let mut r = Offscreen::new(gpu, &profile, &clipmap, OffscreenOptions::default())?;
    let format = crate::gpu::renderer::Renderer::imagery_format(gpu.device(), false);
    let mut rings = crate::plan::color_rings::ColorRings::with_format(
        ImageryPackage::from_bytes(path, bytes)?,
        &profile.imagery,
        format,
    )?;
    r.renderer_mut().enable_imagery(
        gpu.device(),
        rings.ring(),
        rings.level_count(),
        rings.format(),
    )?;
    let (x, y) = (camera.eye.x, camera.eye.y);
    let mut settled = None;
    for frame in 0..256u64 {
        let s = rings.update(x, y)?;
        r.renderer().prepare_imagery(gpu.queue(), &rings, (x, y))?;
        if s.stale_levels == 0 && settled.is_none() {
            settled = Some(frame);
        }
        if settled.is_some_and(|s| frame >= s + crate::plan::color_rings::FADE_FRAMES) {
            break;
        }
    }
    let probe = ShadingProbe::new(&r)?;
    let opts = FrameOptions::default();
    let frame = render_frame(&mut r, &clipmap, &camera, &opts)?.image;
    let probed = probe.capture(&r)?;
    let twin = super::imagery::ImageryTwin::new(&rings, x, y)?;
    let clear = super::border::clear_rgba8(opts.clear);
    let report = super::frame::compare_imagery(&frame, &probed, clear, &r.shading(), &twin);
    Ok((report, frame))
}
