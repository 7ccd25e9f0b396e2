//! `clipsat view`, the closing summary: the window's ms per frame and, for `--frames N`, the headless
//! `render` path timed in the same run at the same size, camera and options.
//!
//! The headless path is what the view did per frame before it presented through a surface: update, plan,
//! draw into the offscreen target of the strict context, read the image back and hash it
//! ([`render_frame`]). The old view then also scaled that image into a softbuffer window, so the ratio
//! of the two is a lower bound of what presenting without read-back saves.

use std::time::Instant;

use clipsat::gpu::headless::{render_frame, FrameOptions, Offscreen, OffscreenOptions};
use clipsat::gpu::{Gpu, GpuMode};
use clipsat::package::{Package, TileCache};
use clipsat::plan::camera::Camera;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::frame_plan::LodSetup;
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::shading::debug_view::DebugView;
use clipsat::source::Heightmap;
use clipsat::Result;
use serde_json::json;

use super::super::args::arg_error;
use super::super::render::lod_for;
use super::super::sg::{self, SgChoice};

/// Frame times of one path, ms.
#[derive(Clone, Copy, Debug)]
pub(super) struct Times {
    /// Frames timed.
    pub(super) frames: usize,
    pub(super) mean: f64,
    pub(super) median: f64,
    /// The first frame (pipelines compile, levels fill), not in the mean.
    pub(super) first: f64,
    /// CPU time of the whole process (every thread: llvmpipe's rasterizer threads too) per timed frame,
    /// ms: less sensitive than wall time to other work on a shared machine. None off Linux.
    pub(super) cpu: Option<f64>,
}

/// The CPU time this process has used, all threads, user + system, ms (`/proc/self/stat`, in the kernel's
/// fixed USER_HZ of 100 ticks a second). None where that file does not exist.
pub(super) fn cpu_ms() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The fields after the command name, which is in parentheses and may hold spaces: state is field 3,
    // utime 14 and stime 15.
    let mut fields = stat.get(stat.rfind(')')? + 1..)?.split_whitespace();
    let utime: u64 = fields.nth(11)?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((utime + stime) as f64 * 10.0)
}

impl Times {
    /// The mean and median of `steady`, with the `first` frame beside them; None when `steady` is empty.
    pub(super) fn of(first: f64, steady: &[f64], cpu: Option<f64>) -> Option<Self> {
        if steady.is_empty() {
            return None;
        }
        let mean = steady.iter().sum::<f64>() / steady.len() as f64;
        let mut sorted = steady.to_vec();
        sorted.sort_by(f64::total_cmp);
        Some(Self {
            frames: steady.len(),
            mean,
            median: sorted[sorted.len() / 2],
            first,
            cpu,
        })
    }

    pub(super) fn json(&self) -> serde_json::Value {
        json!({
            "frames": self.frames,
            "mean_ms": round2(self.mean),
            "median_ms": round2(self.median),
            "first_ms": round2(self.first),
            "cpu_ms_per_frame": self.cpu.map(round2),
        })
    }
}

/// The headless `render` path of the same view, timed.
pub(super) struct Headless {
    /// GL_VERSION and GL_RENDERER of the headless context.
    pub(super) context: String,
    /// update + plan + draw + read-back + hash per frame.
    pub(super) times: Times,
}

/// What the view drew, for [`headless`] to draw the same.
pub(super) struct Same<'a> {
    /// The terrain, or a streamed terrain's coarse stand-in.
    pub(super) hm: &'a Heightmap,
    /// The package the view streamed, streamed again here.
    pub(super) package: Option<&'a std::path::Path>,
    /// The profile with the window's size as its viewport.
    pub(super) profile: &'a Profile,
    pub(super) camera: &'a Camera,
    pub(super) opts: &'a FrameOptions,
    pub(super) lod: LodMode,
    pub(super) debug: DebugView,
    /// The SG choice when the view drew SG shading.
    pub(super) sg: Option<&'a SgChoice>,
}

/// Renders `frames` frames of the same view headless (a fresh context of `mode`, as `clipsat render`
/// makes) after filling the clipmap as `render` does, and times each.
pub(super) fn headless(same: &Same<'_>, mode: GpuMode, frames: u32) -> Result<Headless> {
    let gpu = Gpu::new(mode)?;
    let mut clipmap = match same.package {
        Some(p) => Clipmap::streamed(Package::open(p)?, same.profile, ClipmapOptions::default())?,
        None => Clipmap::new(same.hm, same.profile, ClipmapOptions::default())?,
    };
    // As `render`: update until nothing is stale or pending at the eye (bounded).
    clipmap.fill_at(same.camera.eye, 10_000)?;
    let lod = if same.lod == LodMode::Distance {
        None
    } else {
        Some(lod_for(same.hm, same.profile, &clipmap, true, true)?)
    };
    let baked = same
        .sg
        .map(|c| {
            c.bake(
                same.profile,
                same.hm,
                clipmap.tile_cache().map(TileCache::package),
            )
        })
        .transpose()?;
    let mut r = Offscreen::new(
        &gpu,
        same.profile,
        &clipmap,
        OffscreenOptions {
            lod: LodSetup::new(same.lod, lod)?,
            shading: sg::shading(same.sg, baked.as_ref()),
            debug: same.debug,
        },
    )?;
    let mut ms = Vec::with_capacity(frames as usize);
    let mut cpu_after_first = None;
    for _ in 0..frames {
        let t = Instant::now();
        clipmap.update(same.camera.eye)?;
        render_frame(&mut r, &clipmap, same.camera, same.opts)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        if ms.len() == 1 {
            cpu_after_first = cpu_ms();
        }
    }
    let cpu = per_frame(cpu_after_first, cpu_ms(), ms.len() - 1);
    let times = Times::of(ms[0], &ms[1..], cpu)
        .ok_or_else(|| arg_error("--frames", "needs at least 2 frames to time"))?;
    let report = gpu.report();
    Ok(Headless {
        context: format!("{}, {}", report.gl_version, report.name),
        times,
    })
}

/// CPU ms per frame between two [`cpu_ms`] readings `frames` frames apart.
pub(super) fn per_frame(from: Option<f64>, to: Option<f64>, frames: usize) -> Option<f64> {
    Some((to? - from?) / frames.max(1) as f64)
}

pub(super) fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}
