//! `clipsat fly`'s report: the run's summary statistics, the per-frame CSV and the plot of samples
//! updated against the budget.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path as FsPath;

use crate::app::plot::{LinePlot, Series};
use clipsat::plan::flight::Path;
use clipsat::plan::frame::Frame;
use clipsat::{Error, Result};

use super::super::bench::plan::percentiles;
use super::Row;

/// Summary statistics of a run; percentiles by nearest rank.
pub(super) struct Stats {
    pub(super) samples: [u32; 3],
    pub(super) samples_mean: f64,
    pub(super) triangles: [u32; 3],
    pub(super) over_budget: usize,
    pub(super) max_stale: u32,
    pub(super) frames_stale: usize,
    pub(super) max_disabled: u32,
    /// `Planner::plan`'s wall time per frame, nanoseconds: p50, p99, max.
    pub(super) plan_ns: [u64; 3],
    pub(super) plan_ns_mean: f64,
    /// The same in CPU time (None without a thread clock).
    pub(super) plan_cpu_ns: Option<[u64; 3]>,
    /// Bounds evaluated per frame: p50, p99, max.
    pub(super) evaluations: [u64; 3],
    pub(super) evaluations_mean: f64,
}

impl Stats {
    pub(super) fn of(rows: &[Row], budget: u32) -> Self {
        let n = rows.len().max(1) as f64;
        let total: u64 = rows.iter().map(|r| u64::from(r.samples_updated)).sum();
        let plan_total: u64 = rows.iter().map(|r| r.plan_ns).sum();
        let eval_total: u64 = rows.iter().map(|r| r.bound_evaluations).sum();
        Self {
            samples: percentiles(rows.iter().map(|r| r.samples_updated).collect()),
            samples_mean: total as f64 / n,
            triangles: percentiles(rows.iter().map(|r| r.triangles).collect()),
            over_budget: rows.iter().filter(|r| r.samples_updated > budget).count(),
            max_stale: rows.iter().map(|r| r.stale_levels).max().unwrap_or(0),
            frames_stale: rows.iter().filter(|r| r.stale_levels > 0).count(),
            max_disabled: rows.iter().map(|r| r.disabled_levels).max().unwrap_or(0),
            plan_ns: percentiles(rows.iter().map(|r| r.plan_ns).collect()),
            plan_cpu_ns: rows
                .iter()
                .map(|r| r.plan_cpu_ns)
                .collect::<Option<Vec<u64>>>()
                .map(percentiles),
            plan_ns_mean: plan_total as f64 / n,
            evaluations: percentiles(rows.iter().map(|r| r.bound_evaluations).collect()),
            evaluations_mean: eval_total as f64 / n,
        }
    }
}

pub(super) fn open_csv(path: &FsPath, levels: u32) -> Result<BufWriter<File>> {
    super::super::ensure_parent(path)?;
    let file = File::create(path).map_err(|e| Error::io(path, "cannot create", e))?;
    let mut w = BufWriter::with_capacity(1 << 16, file);
    let mut header = String::from(
        "frame,samples_updated,budget_used,levels_updated,stale_levels,disabled_levels,triangles,hash",
    );
    for l in 0..levels {
        header.push_str(&format!(",active_l{l}"));
    }
    header.push_str(
        ",plan_us,plan_cpu_us,bound_evaluations,refine_evaluations,blocks_clamped,unmet_px,plan_triangles",
    );
    writeln!(w, "{header}").map_err(|e| Error::io(path, "cannot write", e))?;
    Ok(w)
}

/// One CSV row; `write!` into the buffered writer formats in place, without allocating.
pub(super) fn write_row(
    w: &mut impl Write,
    f: &Frame,
    row: Option<&Row>,
    s: clipsat::plan::frame_plan::PlanStats,
) -> std::io::Result<()> {
    let used = f64::from(f.samples_updated) / f64::from(f.budget.max(1));
    write!(
        w,
        "{},{},{used:.4},{},{},{},{},{:016x}",
        f.index,
        f.samples_updated,
        f.levels_updated,
        f.stale_levels,
        f.disabled_levels,
        f.triangles,
        f.hash
    )?;
    for l in &f.levels {
        write!(w, ",{}x{}", l.active.w, l.active.h)?;
    }
    let (us, cpu) = row.map_or((0, None), |r| {
        (r.plan_ns / 1000, r.plan_cpu_ns.map(|c| c / 1000))
    });
    write!(
        w,
        ",{us},{},{},{},{},{:.3},{}",
        cpu.map_or(String::new(), |c| c.to_string()),
        s.bound_evaluations,
        s.refine_evaluations,
        s.blocks_clamped,
        s.unmet_px,
        s.triangles
    )?;
    writeln!(w)
}

pub(super) fn plot(
    rows: &[Row],
    budget: u32,
    profile: &str,
    path: Path,
    out: &FsPath,
) -> Result<()> {
    super::super::ensure_parent(out)?;
    let frame_x = |i: usize| i as f64;
    let plot = LinePlot {
        title: format!("clipsat fly: {path}, profile {profile}"),
        x_label: "frame".into(),
        y_label: "samples updated".into(),
        y2_label: "stale levels".into(),
        x_log: false,
        series: vec![
            Series {
                name: "samples updated".into(),
                points: rows
                    .iter()
                    .enumerate()
                    .map(|(i, r)| (frame_x(i), f64::from(r.samples_updated)))
                    .collect(),
                color: [31, 119, 180],
                right_axis: false,
            },
            Series {
                name: "budget".into(),
                points: vec![
                    (0.0, f64::from(budget)),
                    (frame_x(rows.len().saturating_sub(1)), f64::from(budget)),
                ],
                color: [120, 120, 120],
                right_axis: false,
            },
            Series {
                name: "stale levels".into(),
                points: rows
                    .iter()
                    .enumerate()
                    .map(|(i, r)| (frame_x(i), f64::from(r.stale_levels)))
                    .collect(),
                color: [214, 39, 40],
                right_axis: true,
            },
        ],
    };
    plot.write_png(out, 1200, 600)
}
