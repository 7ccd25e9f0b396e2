//! `clipsat view`, the closing summary: the window's ms per frame and, for `--frames N`, the headless
//! `render` path timed in the same run at the same size, camera and options.
//!
//! The headless path is what the view did per frame before it presented through a surface: update, plan,
//! draw into the offscreen target of the strict context, read the image back and hash it. The old view
//! then also scaled that image into a softbuffer window, so the ratio of the two is a lower bound of
//! what presenting without read-back saves. That path is drawn through the stages, a test instrument
//! outside the public API, by `app/cmd/view_setup.rs` ([`time_headless`]); this file only keeps the
//! times.

use clipsat::Result;
use serde_json::json;

use super::super::args::{arg_error, GpuArg};
use super::super::view_setup::{time_headless, HeadlessView};

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

/// Renders `frames` frames of the same view headless (a fresh context of `gpu`, as `clipsat render`
/// makes) after filling the clipmap as `render` does, and times each.
pub(super) fn headless(view: &HeadlessView<'_>, gpu: GpuArg, frames: u32) -> Result<Headless> {
    let mut ms = Vec::with_capacity(frames as usize);
    let mut cpu_after_first = None;
    let context = time_headless(view, gpu, frames, |t| {
        ms.push(t);
        if ms.len() == 1 {
            cpu_after_first = cpu_ms();
        }
    })?;
    let cpu = per_frame(cpu_after_first, cpu_ms(), ms.len().saturating_sub(1));
    let times = ms
        .split_first()
        .and_then(|(first, rest)| Times::of(*first, rest, cpu))
        .ok_or_else(|| arg_error("--frames", "needs at least 2 frames to time"))?;
    Ok(Headless { context, times })
}

/// CPU ms per frame between two [`cpu_ms`] readings `frames` frames apart.
pub(super) fn per_frame(from: Option<f64>, to: Option<f64>, frames: usize) -> Option<f64> {
    Some((to? - from?) / frames.max(1) as f64)
}

pub(super) fn round2(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}
