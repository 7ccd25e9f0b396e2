//! The embedding API's set-up steps, shared with the `clipsat` binary: the SAT LOD selector and SG's
//! shading tables baked (stage 1) through a cache folder, and the detail pool's warm-up (stage 2).

use std::path::Path;

use glam::DVec3;

use crate::bake::horizon::DEFAULT_AZIMUTHS;
use crate::bake::{self, lod_tables, BakeParams};
use crate::package::shading_sats::ShadingBake;
use crate::package::Package;
use crate::plan::clipmap::Clipmap;
use crate::plan::camera::Camera;
use crate::plan::frame_plan::{FramePlan, PlanParams, Planner};
use crate::plan::lod::Lod;
use crate::profile::Profile;
use crate::progress::Progress;
use crate::shading::scene::Scene;
use crate::source::Heightmap;
use crate::{Error, Result};

/// Most clipmap updates a warm-up runs to fill every level at a still eye.
pub const MAX_FILL_FRAMES: u32 = 10_000;

/// Most frames a warm-up lets the detail pool fill at a still camera after the rings (a pool whose
/// wanted tiles outnumber its slots stops writing once every slot is needed). Each frame refines within
/// the profile's budget of bound evaluations, so a fine epsilon on a rough terrain takes a few hundred.
pub const MAX_POOL_FRAMES: u32 = 1024;

/// A frame's CPU side (stage 2), the steps and their order that [`crate::TerrainRenderer::prepare`] runs
/// before its uploads, and `clipsat fly` and `bench` run without a GPU: the clipmap's budgeted update at
/// the eye, the plan (run by `time`, which may time it and returns what it measured), then the detail
/// pool's tiles the plan waits for, requested from the next update (a streamed package decodes them after
/// the rings).
pub fn frame_cpu<T>(
    clipmap: &mut Clipmap,
    planner: &mut Planner,
    camera: &Camera,
    params: &PlanParams,
    plan: &mut FramePlan,
    time: impl FnOnce(&mut dyn FnMut() -> Result<()>) -> Result<T>,
) -> Result<T> {
    clipmap.update(camera.eye)?;
    let measured = time(&mut || planner.plan(clipmap, camera, params, plan))?;
    clipmap.request_samples(&plan.detail().wanted);
    Ok(measured)
}

/// The mapped SAT LOD tables faulted in when they are opened: one in this many bytes of their resident
/// share ([`crate::bake::lod_tables::LodTables::prime`]). Half: the other half is left to the frames'
/// own queries, so that the first frames do not pass the limit and trim what was primed.
const PRIME_SHARE: u64 = 2;

/// The SAT LOD selector for `clipmap`'s terrain. Its tables are read from `cache` (baked there, reporting
/// to `progress`, on a miss) through a map whose resident pages stay within the profile's share of
/// `budget.cpu_memory_bytes` (with the SG shading inputs' share too unless `sg`, the frames draw SG:
/// [`crate::profile::CpuSplit::lod_tables_with`]); without a cache folder a resident terrain's are baked
/// in memory. A streamed clipmap's tables are baked from its package out of core, and `stand_in` is then
/// the package's coarse stand-in, which places the grid.
pub fn sat_lod(
    stand_in: &Heightmap,
    profile: &Profile,
    clipmap: &Clipmap,
    cache: Option<&Path>,
    sg: bool,
    progress: Progress<'_>,
) -> Result<Lod> {
    let params = BakeParams {
        p: lod_tables::P,
        levels: profile.clipmap.levels,
        synth_levels: clipmap.synth_levels(),
        g0: clipmap.g0(),
    };
    let tables = match (clipmap.tile_cache(), cache) {
        (Some(c), Some(dir)) => crate::package::lod_cache::bake_lod_package(c.package(), &params, dir, progress)?.0,
        (Some(_), None) => {
            return Err(Error::Invalid {
                what: "TerrainOptions::cache_dir".into(),
                reason: "a streamed terrain's SAT LOD tables are baked out of core into the cache \
                         folder: give one"
                    .into(),
            })
        }
        (None, Some(dir)) => {
            bake::bake_lod_mapped(stand_in, clipmap.pyramid(), &params, dir, progress)?.0
        }
        (None, None) => {
            lod_tables::check_height_range(clipmap.pyramid())?;
            bake::bake_uncached(clipmap.pyramid(), &params, progress)?
        }
    };
    // The mapped tables' pages held resident: their share of budget.cpu_memory_bytes.
    let share = profile.cpu_split().lod_tables_with(sg);
    tables.limit_resident(share);
    // Half the share faulted in now, smallest tables first; the frames' own queries keep the other half.
    tables.prime(share / PRIME_SHARE);
    Ok(Lod::for_clipmap(tables, profile, clipmap, stand_in))
}

/// The tables SG shading needs for `scene` (visibility dropped unless `shadows`), on the finest grid
/// whose tables fit the profile's shading share of `budget.cpu_memory_bytes`: from `package` out of core
/// when the terrain streams, else from `terrain`; through `cache` when given (baked there on a miss),
/// else baked now. Bakes only what the scene needs. Returns the scene as drawn.
pub fn sg_tables(
    profile: &Profile,
    terrain: &Heightmap,
    package: Option<&Package>,
    scene: &Scene,
    shadows: bool,
    cache: Option<&Path>,
    progress: Progress<'_>,
) -> Result<(Scene, ShadingBake)> {
    let max_bytes = profile.cpu_split().shading;
    let mut scene = scene.clone();
    scene.effects.visibility &= shadows;
    let needs = scene.needs();
    let d = DEFAULT_AZIMUTHS;
    let bake = match (package, cache) {
        (Some(p), Some(dir)) => {
            ShadingBake::bake_package_cached(p, &needs, d, max_bytes, dir, progress)?.0
        }
        (Some(p), None) => ShadingBake::bake_package(p, &needs, d, max_bytes, progress)?,
        (None, Some(dir)) => {
            ShadingBake::bake_cached(terrain, &needs, d, max_bytes, dir, progress)?.0
        }
        (None, None) => ShadingBake::bake(terrain, &needs, d, max_bytes, progress)?,
    };
    Ok((scene, bake))
}

/// One step of the detail pool's warm-up at a still `eye`, after a frame planned as `plan` wrote `wrote`
/// detail tiles: true when the pool is as full as it gets (nothing written, nothing wanted); else the
/// clipmap is asked for the samples the plan wants (a streamed package decodes them) and updated, and
/// the caller plans and uploads the next frame.
pub fn pool_step(clipmap: &mut Clipmap, eye: DVec3, plan: &FramePlan, wrote: u32) -> Result<bool> {
    let wanted = &plan.detail().wanted;
    if wrote == 0 && wanted.is_empty() {
        return Ok(true);
    }
    clipmap.request_samples(wanted);
    clipmap.update(eye)?;
    Ok(false)
}

/// The profile a terrain with draped imagery is drawn with: `profile` allowing the feature `imagery`,
/// with the colour rings' GPU bytes within `budget.gpu_memory_bytes` beside [`Profile::footprint`], and
/// the imagery's CPU share (tile cache and staging) taken out of `budget.cpu_memory_bytes` before it is
/// split for the heights, so that the two together stay within the budget.
pub fn imagery_profile(profile: &Profile) -> Result<Profile> {
    use crate::profile::Feature;
    let bad = |field: &str, reason: String| Err(Error::config(&profile.name, field, reason));
    if !profile.allows(Feature::Imagery) {
        return bad(
            "shading.features",
            "draping imagery needs the feature \"imagery\"".into(),
        );
    }
    profile.imagery.validate(&profile.name)?;
    let need = profile.footprint().total() + profile.imagery.gpu_bytes();
    if need > profile.budget.gpu_memory_bytes {
        return bad(
            "budget.gpu_memory_bytes",
            format!(
                "the profile with its colour rings needs {need} bytes of GPU memory but the budget is {}",
                profile.budget.gpu_memory_bytes
            ),
        );
    }
    let mut p = profile.clone();
    let Some(left) = p.budget.cpu_memory_bytes.checked_sub(p.imagery.cpu_bytes()) else {
        return bad(
            "budget.cpu_memory_bytes",
            format!(
                "{} bytes do not hold the imagery's tile cache and staging ({} bytes)",
                p.budget.cpu_memory_bytes,
                p.imagery.cpu_bytes()
            ),
        );
    };
    p.budget.cpu_memory_bytes = left;
    p.validate(&profile.name)?;
    Ok(p)
}
