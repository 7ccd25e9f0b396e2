//! Stage 1, bake: the rows' share of the SAT LOD tables' out-of-core bake ([`super`]): what a data row
//! of a level computes from the level's band and the row's level-0 heights alone (its errors, their
//! largest, its cells' maxima and sums), and those rows shared among the cores.

use crate::bake::lod_tables::error_from;
use crate::bake::sat::{pow_unit, Sat};

/// One data row's share of a level's work that reads only the level's band and the row, done for every
/// level's rows of a band in parallel ([`par_rows`]): sweep 1's largest error and first bad one, sweep
/// 2's closed cells' maxima and half-open cells' sums over the row.
#[derive(Default)]
pub(super) struct RowOut {
    pub(super) e_max: f32,
    pub(super) bad: Option<(u32, u32, f32)>,
    pub(super) rowmax: Vec<f32>,
    pub(super) sums: Vec<u64>,
}

/// What a data row's work reads of a level (`Level::view`).
#[derive(Clone, Copy)]
pub(super) struct RowView<'a> {
    pub(super) band: &'a [f64],
    pub(super) j0: i64,
    pub(super) row_len: usize,
    pub(super) ke: u32,
    pub(super) s: u32,
    pub(super) cw: u32,
    pub(super) sw: u32,
    pub(super) p: u32,
    pub(super) q: u32,
    pub(super) inv: f64,
}

impl RowView<'_> {
    /// Sample errors of data row `y` (level-0 heights `h0`) into `out`, or the first non-finite one.
    fn row_errors(&self, h0: &[f32], y: u32, out: &mut [f32]) -> Option<(u32, u32, f32)> {
        let j = i64::from(y >> self.ke);
        let base = usize::try_from(j - self.j0).expect("the band holds row j") * self.row_len;
        let (r0, r1) = self.band[base..base + 2 * self.row_len].split_at(self.row_len);
        let z = |a: i64, b: i64| {
            let a = usize::try_from(a).expect("a level-k column, 0 or more");
            if b == j {
                r0[a]
            } else {
                r1[a]
            }
        };
        for (x, (o, &h)) in (0u32..).zip(out.iter_mut().zip(h0)) {
            let e = error_from(z, f64::from(h), self.ke, i64::from(x), i64::from(y));
            if !(e.is_finite() && e >= 0.0) {
                return Some((x, y, e));
            }
            *o = e;
        }
        None
    }

    /// Sweep 1's share of row `y`: its largest error, or its first bad one.
    pub(super) fn row_max(&self, h0: &[f32], y: u32, errs: &mut Vec<f32>, out: &mut RowOut) {
        errs.resize(h0.len(), 0.0);
        out.bad = self.row_errors(h0, y, errs);
        out.e_max = errs.iter().copied().fold(0.0, f32::max);
    }

    /// Sweep 2's share of row `y`: the closed cells' maxima of the row (sample x lies in cell x >> s
    /// and, on a lattice line, in the one before, as `LevelTables::build_level`) and the half-open
    /// cells' sums of its quantised (e/E)^p.
    pub(super) fn row_cells(&self, h0: &[f32], y: u32, errs: &mut Vec<f32>, out: &mut RowOut) {
        errs.resize(h0.len(), 0.0);
        let bad = self.row_errors(h0, y, errs);
        assert!(bad.is_none(), "sweep 1 refused every bad error");
        let (s, mask) = (self.s, (1u32 << self.s) - 1);
        out.rowmax.clear();
        out.rowmax.resize(self.cw as usize, 0.0);
        out.sums.clear();
        out.sums.resize(self.sw as usize, 0);
        for (x, &e) in (0u32..).zip(errs.iter()) {
            let c = (x >> s) as usize;
            if let Some(m) = out.rowmax.get_mut(c) {
                *m = m.max(e);
            }
            if c > 0 && x & mask == 0 {
                out.rowmax[c - 1] = out.rowmax[c - 1].max(e);
            }
            let v = pow_unit(f64::from(e) * self.inv, self.p).min(1.0);
            out.sums[c] = out.sums[c].wrapping_add(Sat::quantise_up(v, self.q, x, y));
        }
    }
}

/// Row `r` of a band of level-0 heights `width` wide.
pub(super) fn band_row(h0: &[f32], width: u32, r: u32) -> &[f32] {
    let w = width as usize;
    &h0[r as usize * w..(r as usize + 1) * w]
}

/// Data rows a job of [`par_rows`] takes of one level.
const JOB_ROWS: usize = 8;

/// Runs `f` over every data row `y0 .. y1` of every level into the level's [`RowOut`]s, the band's rows
/// dealt in runs of [`JOB_ROWS`] among the cores, each run at every level: every row costs about the same
/// at every level (an error a sample), so the cores are loaded evenly whatever the number of levels, and
/// each row's result depends on the row alone.
pub(super) fn par_rows(
    levels: Vec<(RowView<'_>, &mut Vec<RowOut>)>,
    (h0, width): (&[f32], u32),
    (y0, y1): (u32, u32),
    f: &(impl Fn(&RowView<'_>, &[f32], u32, &mut Vec<f32>, &mut RowOut) + Sync),
) {
    let rows = (y1 - y0) as usize;
    let chunks = rows.div_ceil(JOB_ROWS);
    let mut per_level: Vec<_> = levels
        .into_iter()
        .map(|(view, o)| {
            o.resize_with(rows, RowOut::default);
            (y0..)
                .step_by(JOB_ROWS)
                .zip(o.chunks_mut(JOB_ROWS))
                .map(move |(first, chunk)| (view, first, chunk))
        })
        .collect();
    // Run by run of rows, every level's share of a run after the other: a core reads its runs of the
    // band's heights once for all the levels, from its own cache.
    let mut jobs: Vec<(RowView<'_>, u32, &mut [RowOut])> = Vec::new();
    for _ in 0..chunks {
        jobs.extend(per_level.iter_mut().filter_map(Iterator::next));
    }
    {
        let run = |share: Vec<(RowView<'_>, u32, &mut [RowOut])>| {
            let mut errs = Vec::new();
            for (view, first, chunk) in share {
                for (y, out) in (first..).zip(chunk.iter_mut()) {
                    f(&view, band_row(h0, width, y - y0), y, &mut errs, out);
                }
            }
        };
        let threads = crate::package::threads().min(jobs.len());
        if threads <= 1 {
            run(jobs);
        } else {
            // Each core a run of the band's rows at every level (so the same work each, and its own
            // heights): jobs come a run of rows at a time.
            let per_run = jobs.len().div_ceil(chunks.max(1));
            let runs = threads.min(chunks).max(1);
            let mut shares: Vec<Vec<_>> = (0..runs).map(|_| Vec::new()).collect();
            for (i, job) in jobs.into_iter().enumerate() {
                shares[(i / per_run) * runs / chunks.max(1)].push(job);
            }
            let run = &run;
            std::thread::scope(|s| {
                for share in shares {
                    s.spawn(move || run(share));
                }
            });
        }
    }
}
