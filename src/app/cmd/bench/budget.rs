//! `clipsat bench all`'s update budget section: a straight flight at multiples of the speed the
//! profile's update budget sustains, counting what the budget updates and leaves stale (GC section 5).

use std::fmt::Write as _;
use std::path::Path as FsPath;
use std::time::Instant;

use crate::app::plot::{LinePlot, Series};
use clipsat::plan::clipmap::{Clipmap, ClipmapOptions};
use clipsat::plan::flight::{Flight, Path};
use clipsat::profile::Profile;
use clipsat::source::Heightmap;
use clipsat::Result;
use indicatif::ProgressBar;

use super::common::COLORS;

/// One (terrain, speed) of the budget section.
pub(super) struct BudgetRow {
    pub(super) terrain: String,
    pub(super) multiple: f64,
    pub(super) speed_m: f64,
    pub(super) samples_mean: f64,
    pub(super) samples_max: u32,
    pub(super) over_budget: usize,
    pub(super) stale_mean: f64,
    pub(super) stale_max: u32,
    pub(super) frames_stale: usize,
    pub(super) update_us: f64,
}

/// Flies a straight line over `hm` at multiples of the speed the profile's update budget sustains and
/// counts what the budget updates and leaves stale (GC section 5).
pub(super) fn measure_budget(
    profile: &Profile,
    name: &str,
    hm: &Heightmap,
    (speeds, fly_frames): (&[f64], u64),
    bar: &ProgressBar,
) -> Result<Vec<BudgetRow>> {
    let mut rows = Vec::new();
    let b = profile.budget.update_samples_per_frame;
    for &multiple in speeds {
        let mut clipmap = Clipmap::new(hm, profile, ClipmapOptions::default())?;
        let v = multiple * sustained_speed(profile, clipmap.g0());
        let flight =
            Flight::new(Path::Straight, v, hm)?.with_fov_y_deg(f64::from(profile.view.fov_y_deg));
        // The initial fill (frame 0's eye, updated until every level is current: several frames under
        // the budget) is not flight; the statistics start at frame 1.
        let eye0 = flight.camera(0).eye;
        clipmap.fill_at(eye0, 10_000)?;
        bar.inc(1);
        let (mut samples, mut samples_max, mut over) = (0u64, 0u32, 0usize);
        let (mut stale, mut stale_max, mut frames_stale) = (0u64, 0u32, 0usize);
        let mut update_s = 0.0;
        for f in 1..fly_frames {
            let eye = flight.camera(f).eye;
            let t = Instant::now();
            let frame = clipmap.update(eye)?;
            update_s += t.elapsed().as_secs_f64();
            samples += u64::from(frame.samples_updated);
            samples_max = samples_max.max(frame.samples_updated);
            over += usize::from(frame.samples_updated > b);
            stale += u64::from(frame.stale_levels);
            stale_max = stale_max.max(frame.stale_levels);
            frames_stale += usize::from(frame.stale_levels > 0);
            bar.inc(1);
        }
        let n = (fly_frames.saturating_sub(1)).max(1) as f64;
        rows.push(BudgetRow {
            terrain: name.to_string(),
            multiple,
            speed_m: v,
            samples_mean: samples as f64 / n,
            samples_max,
            over_budget: over,
            stale_mean: stale as f64 / n,
            stale_max,
            frames_stale,
            update_us: update_s * 1e6 / n,
        });
    }
    Ok(rows)
}

/// v* = B g0 / (2 s): a straight move of v metres per frame along one axis makes level l fill s v / g_l
/// samples (GC section 5), and the sum over levels stays under 2 s v / g0, so v* is about the speed the
/// budget B keeps up with.
fn sustained_speed(profile: &Profile, g0: f64) -> f64 {
    f64::from(profile.budget.update_samples_per_frame) * g0
        / (2.0 * f64::from(profile.clip_size().max(1)))
}

pub(super) fn budget_section(
    out: &FsPath,
    rows: &[BudgetRow],
    fly_frames: u64,
    machine: &str,
    profile: &Profile,
) -> Result<String> {
    let png = "budget.png";
    let mut names: Vec<&str> = rows.iter().map(|r| r.terrain.as_str()).collect();
    names.dedup();
    let mut series = Vec::new();
    for (i, t) in names.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let short = t.split(['_', '.']).next().unwrap_or(t);
        let of = |f: &dyn Fn(&BudgetRow) -> f64| {
            rows.iter()
                .filter(|r| r.terrain == *t)
                .map(|r| (r.multiple, f(r)))
                .collect::<Vec<_>>()
        };
        series.push(Series {
            name: format!("{short} samples"),
            points: of(&|r| r.samples_mean),
            color,
            right_axis: false,
        });
        series.push(Series {
            name: format!("{short} stale"),
            points: of(&|r| r.stale_mean),
            color: color.map(|c| c / 2 + 120),
            right_axis: true,
        });
    }
    LinePlot {
        title: "Updates and stale levels vs speed".into(),
        x_label: "speed / v*".into(),
        y_label: "samples / frame".into(),
        y2_label: "stale levels / frame".into(),
        x_log: true,
        series,
    }
    .write_png(&out.join(png), 960, 480)?;

    let mut s = String::from("## Budget: samples updated and stale levels against speed\n\n");
    let _ = writeln!(
        s,
        "Profile {} (n {}, {} levels, clip size s = {}, budget B = {} samples/frame). A straight flight \
         (`--path straight`, the terrain's diagonal, back and forth) of {} frames per speed; the initial fill \
         (frame 0's eye, updated until every level is current) is left out. Speeds are multiples of v* = B g0 / (2 s), the first-order speed the \
         budget sustains (GC section 5: a level of spacing g_l moving v m/frame along one axis fills \
         s v / g_l samples). The diagonal path needs both axes, so stale levels may start just below 1x. \
         Update time: `Clipmap::update` alone, baseline the 1x speed on the same terrain in this run.\n",
        profile.name,
        profile.clipmap.n,
        profile.clipmap.levels,
        profile.clip_size(),
        profile.budget.update_samples_per_frame,
        fly_frames,
    );
    let _ = writeln!(
        s,
        "![samples updated and stale levels against speed]({png})\n\n*Figure: mean samples updated (left \
         axis) and mean stale levels (right axis, lighter) per frame against speed / v*. {}*\n",
        machine
    );
    let _ = writeln!(s, "*Table: {}*\n", machine);
    s.push_str(
        "| terrain | speed / v* | m/frame | samples mean | samples max | frames over B | stale levels mean | \
         stale max | frames with stale | update us | update time / 1x |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let base = rows
            .iter()
            .find(|b| b.terrain == r.terrain && b.multiple == 1.0)
            .map(|b| b.update_us);
        let ratio = match base {
            Some(b) if b > 0.0 => format!("{:.2}", r.update_us / b),
            _ => "-".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} | {:.0} | {} | {} | {:.2} | {} | {} | {:.0} | {ratio} |",
            r.terrain,
            r.multiple,
            r.speed_m,
            r.samples_mean,
            r.samples_max,
            r.over_budget,
            r.stale_mean,
            r.stale_max,
            r.frames_stale,
            r.update_us,
        );
    }
    s.push('\n');
    Ok(s)
}
