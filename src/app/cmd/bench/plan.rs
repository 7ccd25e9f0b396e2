//! `clipsat bench`'s and `fly`'s plan time: `Planner::plan` timed in the run (the wall clock and this
//! thread's CPU clock around each call), the bound evaluations each plan made (its work, the same on
//! every machine), the frames until a plan settles after each jump of a flight, and the whole frame's
//! measured screen error on sampled frames. A measurement tool: it allocates and reads clocks (nothing it
//! measures goes into a hash). docs/plan-time.md says what each number is.

use std::fmt::Write as _;
use std::time::Instant;

use clipsat::engine::setup;
use clipsat::measure::screen_error;
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::plan::frame_plan::{FramePlan, LodSetup, PlanParams, Planner};
use clipsat::plan::lod::LodMode;
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::Result;

/// This thread's CPU time, nanoseconds (`CLOCK_THREAD_CPUTIME_ID`); None where unavailable. Beside the
/// wall clock, it tells the plan's own time from the time a loaded machine's scheduler gave others.
#[cfg(all(target_os = "linux", target_pointer_width = "64"))]
pub(crate) fn thread_cpu_ns() -> Option<u64> {
    #[repr(C)]
    struct Timespec {
        tv_sec: i64,
        tv_nsec: i64,
    }
    extern "C" {
        fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut t = Timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec (two 64-bit fields on 64-bit Linux) through a valid,
    // exclusive pointer and reads nothing else.
    let rc = unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut t) };
    let secs = u64::try_from(t.tv_sec).ok()?;
    let nanos = u64::try_from(t.tv_nsec).ok()?;
    (rc == 0).then(|| secs * 1_000_000_000 + nanos)
}

/// No thread clock here.
#[cfg(not(all(target_os = "linux", target_pointer_width = "64")))]
pub(crate) fn thread_cpu_ns() -> Option<u64> {
    None
}

/// p50, p99 and max of `v` by nearest rank (the default when empty).
pub(crate) fn percentiles<T: Copy + Ord + Default>(mut v: Vec<T>) -> [T; 3] {
    v.sort_unstable();
    let at = |percent: usize| {
        let rank = (percent * v.len()).div_ceil(100);
        v.get(rank.max(1) - 1).copied().unwrap_or_default()
    };
    [at(50), at(99), v.last().copied().unwrap_or_default()]
}

/// One frame's CPU side ([`setup::frame_cpu`]: the update, the plan, the pool's requests), its plan
/// timed: wall and, where the thread has a clock, CPU nanoseconds.
pub(crate) fn timed_frame(
    clipmap: &mut Clipmap,
    planner: &mut Planner,
    camera: &clipsat::plan::camera::Camera,
    params: &PlanParams,
    plan: &mut FramePlan,
) -> Result<(u64, Option<u64>)> {
    setup::frame_cpu(clipmap, planner, camera, params, plan, |plan| {
        let (t, cpu) = (Instant::now(), thread_cpu_ns());
        plan()?;
        let wall = u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX);
        Ok((
            wall,
            thread_cpu_ns().zip(cpu).map(|(b, a)| b.saturating_sub(a)),
        ))
    })
}

/// Per jump of a flight (frame 0 counts as one): the frames until the plan settled (no ring stale, no
/// refinement work its budget stopped, every pool tile its cells read resident) and the blocks then
/// clamped; None when the next jump or the end came first. Beside it, per leg (a jump to the next): the
/// first frame whose plan meets epsilon over every block in view (`PlanStats::unmet_px` 0) and the
/// bound the leg's last frame misses epsilon by; over the flight, the largest known such bound and the
/// frames where it was not known (a block drawn at a level past the LOD tables').
#[derive(Clone, Debug, Default)]
pub(crate) struct Settling {
    since: Option<u64>,
    start: u64,
    pub(crate) legs: Vec<Option<(u64, u32)>>,
    pub(crate) met: Vec<Option<u64>>,
    pub(crate) end_unmet_px: Vec<f32>,
    pub(crate) unmet_px_max: f32,
    pub(crate) frames_unmet_unknown: u64,
}

impl Settling {
    /// Frame `f`: whether the path jumped to it, and the plan and clipmap after it.
    pub(crate) fn frame(&mut self, f: u64, jumped: bool, plan: &FramePlan, clipmap: &Clipmap) {
        if f == 0 || jumped {
            if self.since.is_some() {
                self.legs.push(None);
            }
            self.since = Some(f);
            self.start = f;
            self.met.push(None);
            self.end_unmet_px.push(0.0);
        }
        let s = plan.stats();
        if let Some(m) = self
            .met
            .last_mut()
            .filter(|m| m.is_none() && s.unmet_px == 0.0)
        {
            *m = Some(f - self.start);
        }
        if let Some(e) = self.end_unmet_px.last_mut() {
            *e = s.unmet_px;
        }
        if s.unmet_px.is_finite() {
            self.unmet_px_max = self.unmet_px_max.max(s.unmet_px);
        } else {
            self.frames_unmet_unknown += 1;
        }
        let settled =
            clipmap.frame().stale_levels == 0 && !s.refining && s.detail_tiles_waiting == 0;
        if let Some(j) = self.since.filter(|_| settled) {
            self.legs.push(Some((f - j, s.blocks_clamped)));
            self.since = None;
        }
    }

    /// The flight ended.
    pub(crate) fn finish(&mut self) {
        if self.since.take().is_some() {
            self.legs.push(None);
        }
    }
}

/// One terrain and epsilon of the plan-time section.
#[derive(Clone, Debug)]
pub(crate) struct PlanRow {
    pub(crate) terrain: String,
    pub(crate) epsilon: f64,
    /// Wall ms per frame over the figure-8 flight: p50, p99, max.
    pub(crate) wall_ms: [f64; 3],
    /// The same in this thread's CPU time, where there is a thread clock.
    pub(crate) cpu_ms: Option<[f64; 3]>,
    /// Bound evaluations per frame: p50, p99, max; and the refinement's alone.
    pub(crate) evaluations: [u64; 3],
    pub(crate) refine: [u64; 3],
    /// Largest measured whole-frame error on sampled frames, px: over every block, over the unclamped.
    pub(crate) error_px: (f64, f64),
    /// The teleport flight's frames to settle per jump, and the blocks then clamped.
    pub(crate) settle: Vec<Option<(u64, u32)>>,
    /// Per leg of the teleport flight: the first frame whose plan meets epsilon everywhere in view, and
    /// the bound the leg's last frame misses it by ([`Settling`]).
    pub(crate) met: Vec<Option<u64>>,
    pub(crate) end_unmet_px: Vec<f32>,
}

/// What a plan-time run flies.
pub(crate) struct PlanRun {
    /// Figure-8 frames (teleport frames: four legs of 60).
    pub(crate) frames: u64,
    /// Measure the screen error on every `error_every`-th figure-8 frame.
    pub(crate) error_every: u64,
}

/// `sat-conservative` at `epsilon` on `hm`: a figure-8 flight timed frame by frame (the profile's
/// viewport), its screen error measured on sampled frames, and a teleport flight (a jump every 60 frames,
/// 1 m/frame between) for the frames to settle.
pub(crate) fn measure_plan(
    profile: &Profile,
    name: &str,
    hm: &Heightmap,
    epsilon: f64,
    run: &PlanRun,
) -> Result<PlanRow> {
    #[expect(clippy::cast_possible_truncation, reason = "epsilon is a few pixels")]
    let params = PlanParams {
        epsilon_px: Some(epsilon as f32),
        ..PlanParams::default()
    };
    let view = (profile.view.width, profile.view.height);
    let fly = |path: Path, speed: f64, frames: u64, error_every: u64| -> Result<_> {
        let mut clipmap = Clipmap::new(hm, profile, ClipmapOptions::default())?;
        let lod = crate::app::cmd::render::lod_for(hm, profile, &clipmap, false, false)?;
        let mut planner = Planner::new(
            profile,
            &clipmap,
            LodSetup::new(LodMode::SatConservative, Some(lod))?,
        )?;
        let mut plan = planner.new_plan();
        let flight =
            Flight::new(path, speed, hm)?.with_fov_y_deg(f64::from(profile.view.fov_y_deg));
        let (mut wall, mut cpu, mut evals, mut refine) = (vec![], vec![], vec![], vec![]);
        let (mut error, mut settle) = ((0.0f64, 0.0f64), Settling::default());
        for f in 0..frames {
            let camera = flight.camera(f);
            let (w, c) = timed_frame(&mut clipmap, &mut planner, &camera, &params, &mut plan)?;
            wall.push(w);
            cpu.push(c);
            evals.push(plan.stats().bound_evaluations);
            refine.push(plan.stats().refine_evaluations);
            settle.frame(f, flight.jumps_at(f), &plan, &clipmap);
            if let Some(lod) = planner
                .lod()
                .filter(|_| error_every > 0 && f % error_every == 0)
            {
                let e = screen_error(&plan, view, &clipmap, &camera, lod);
                error = (error.0.max(e.max_px), error.1.max(e.max_px_unclamped));
            }
        }
        settle.finish();
        let ms = |v: [u64; 3]| v.map(|n| n as f64 / 1e6);
        let cpu = cpu
            .into_iter()
            .collect::<Option<Vec<u64>>>()
            .map(|c| ms(percentiles(c)));
        Ok((
            ms(percentiles(wall)),
            cpu,
            percentiles(evals),
            percentiles(refine),
            error,
            settle,
        ))
    };
    let (wall_ms, cpu_ms, evaluations, refine, error_px, _) =
        fly(Path::Figure8, 50.0, run.frames, run.error_every)?;
    let (.., teleport) = fly(Path::Teleport { every: 60 }, 1.0, 240, 0)?;
    Ok(PlanRow {
        terrain: name.to_string(),
        epsilon,
        wall_ms,
        cpu_ms,
        evaluations,
        refine,
        error_px,
        settle: teleport.legs,
        met: teleport.met,
        end_unmet_px: teleport.end_unmet_px,
    })
}

/// The plan-time section of `bench all`'s report.
pub(crate) fn plan_section(
    rows: &[PlanRow],
    profile: &Profile,
    machine: &str,
    run: &PlanRun,
) -> String {
    let mut s = String::from("## Plan time\n\n");
    let _ = write!(
        s,
        "`Planner::plan` per frame, timed in the run (wall clock, and the thread's CPU time in brackets), \
         `sat-conservative`, profile {} ({}x{}, refinement budget {} bound evaluations a frame), a \
         {}-frame figure-8 flight at 50 m/frame over each terrain held resident; the bound evaluations a \
         plan made (boxes and sub-boxes whose error it read and projected: selection and refinement, then \
         the refinement's alone); the whole frame's measured screen error on frames {every}, 2 x {every}, ... (over \
         every block, and over the blocks the held data could pay for); and a teleport flight (a jump every 60 \
         frames, 1 m/frame between) for the frames from each jump until the plan settles, with the blocks \
         clamped then, and until its plan first meets epsilon everywhere in view (`-`: not within the leg, \
         with the bound the leg's last frame misses it by). {machine}\n\n\
         | terrain | epsilon | p50 ms | p99 ms | max ms | bounds p50 / p99 / max | refinement p50 / p99 / max \
         | error px: frame / unclamped | settle frames (clamped) | epsilon met after |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
        profile.name,
        profile.view.width,
        profile.view.height,
        profile.budget.refine_bounds_per_frame,
        run.frames,
        every = run.error_every,
    );
    for r in rows {
        let t = |i: usize| match r.cpu_ms {
            Some(c) => format!("{:.3} ({:.3})", r.wall_ms[i], c[i]),
            None => format!("{:.3}", r.wall_ms[i]),
        };
        let settle: Vec<String> = r
            .settle
            .iter()
            .map(|l| match l {
                Some((f, c)) => format!("{f} ({c})"),
                None => "-".into(),
            })
            .collect();
        let met: Vec<String> = r
            .met
            .iter()
            .zip(&r.end_unmet_px)
            .map(|(m, u)| match m {
                Some(f) => f.to_string(),
                None => format!("- ({u:.2} px)"),
            })
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} / {} / {} | {} / {} / {} | {:.2} / {:.2} | {} | {} |",
            r.terrain,
            r.epsilon,
            t(0),
            t(1),
            t(2),
            r.evaluations[0],
            r.evaluations[1],
            r.evaluations[2],
            r.refine[0],
            r.refine[1],
            r.refine[2],
            r.error_px.0,
            r.error_px.1,
            settle.join(", "),
            met.join(", "),
        );
    }
    s.push('\n');
    s
}
