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

/// Runs `f` over every data row `y0 .. y1` of every level into the level's [`RowOut`]s, in jobs of a run
/// of [`JOB_ROWS`] rows of one level, each core taking the next job as it comes free
/// ([`crate::package::deal`]): the cores finish together even while the fold of the band before takes
/// a share of one of them, and each row's result depends on the row alone. The jobs come a run of rows
/// at a time, every level's share of it in turn, so a core reads the same heights from its own cache.
/// Returns what `beside` returns, run on this thread meanwhile.
pub(super) fn par_rows<T>(
    levels: Vec<(RowView<'_>, &mut Vec<RowOut>)>,
    (h0, width): (&[f32], u32),
    (y0, y1): (u32, u32),
    f: &(impl Fn(&RowView<'_>, &[f32], u32, &mut Vec<f32>, &mut RowOut) + Sync),
    beside: impl FnOnce() -> T,
) -> T {
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
    let mut jobs: Vec<Job<'_, '_>> = Vec::new();
    for _ in 0..chunks {
        jobs.extend(per_level.iter_mut().filter_map(Iterator::next));
    }
    // Each worker's errors of a row, reused from job to job.
    let mut scratch: Vec<Vec<f32>> = (0..crate::package::threads()).map(|_| Vec::new()).collect();
    let run = |errs: &mut Vec<f32>, _: usize, job: &mut Job<'_, '_>| {
        let (view, first, chunk) = job;
        for (y, out) in (*first..).zip(chunk.iter_mut()) {
            f(view, band_row(h0, width, y - y0), y, errs, out);
        }
        Ok::<(), std::convert::Infallible>(())
    };
    let what = "a LOD table row thread panicked";
    let (Ok(()), b) = crate::package::deal::deal(&mut jobs, &mut scratch, run, beside, what);
    b
}

/// A job of [`par_rows`]: a level, the first of a run of rows, and the rows' results.
type Job<'v, 'o> = (RowView<'v>, u32, &'o mut [RowOut]);
