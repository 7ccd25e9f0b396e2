//! Stage 2, the per-frame plan: which texture rectangles the GPU copy of the rings still lacks.
//!
//! Every clipmap frame writes full-height column strips and full-width row strips of each toroidal ring
//! ([`crate::plan::budget`]). [`UploadStamps`] remembers, per level, the last frame that wrote each texel
//! column and row. A plan built for frame i after a plan for frame j then uploads the union of the strips
//! written in frames j + 1 ..= i, never more than those frames updated: the GPU copy stays equal to the CPU
//! rings when frames are skipped without refilling whole levels.

use crate::plan::frame::{Upload, MAX_LEVELS};
use crate::{Error, Result};

/// Runs of columns (and of rows) kept per level before neighbouring runs are joined.
pub const RUNS_PER_AXIS: usize = 4;

/// Most rectangles one plan uploads: [`RUNS_PER_AXIS`] column and row runs per level.
pub const MAX_PLAN_UPLOADS: usize = 2 * RUNS_PER_AXIS * MAX_LEVELS;

/// A plan's upload rectangles.
pub type UploadList = heapless::Vec<Upload, MAX_PLAN_UPLOADS>;

/// Per level, per texel column and row: 1 + the index of the last frame that wrote it (0: never).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct UploadStamps {
    size: u32,
    levels: u32,
    cols: Vec<u64>,
    rows: Vec<u64>,
    /// Per level, the strips written so far: equal counts mean no stamp of the level changed between.
    writes: Vec<u64>,
}

impl UploadStamps {
    /// Stamps for `levels` rings of side `size`, none written (allocated once).
    pub fn new(levels: u32, size: u32) -> Self {
        let n = levels as usize * size as usize;
        Self {
            size,
            levels,
            cols: vec![0; n],
            rows: vec![0; n],
            writes: vec![0; levels as usize],
        }
    }

    /// The latest stamp of the texel columns of lattice columns `x0..x1` and the texel rows of lattice
    /// rows `y0..y1` of `level` (toroidal): a texel of that rectangle written after a frame has its
    /// column or its row stamped later (every write is a whole column or row strip), so the rectangle is
    /// unchanged since the frame whose stamp this was.
    pub fn latest(&self, level: u32, (x0, x1): (i64, i64), (y0, y1): (i64, i64)) -> u64 {
        let s = i64::from(self.size.max(1));
        let base = level as usize * self.size as usize;
        let mut m = 0;
        for (stamps, lo, hi) in [(&self.cols, x0, x1), (&self.rows, y0, y1)] {
            // One remainder, then the run walks the torus: at most two contiguous slices.
            #[expect(clippy::cast_possible_truncation, reason = "rem_euclid by the side")]
            let start = lo.rem_euclid(s) as usize;
            #[expect(clippy::cast_possible_truncation, reason = "at most the side")]
            let n = (hi.min(lo + s) - lo).max(0) as usize;
            let side = self.size.max(1) as usize;
            let first = n.min(side - start);
            let run = |from: usize, len: usize| {
                stamps
                    .get(base + from..base + from + len)
                    .map_or(u64::MAX, |r| r.iter().copied().max().unwrap_or(0))
            };
            m = m.max(run(start, first)).max(run(0, n - first));
        }
        m
    }

    /// Records frame `index`'s uploads.
    pub fn note(&mut self, index: u64, uploads: &[Upload]) {
        let s = self.size as usize;
        for u in uploads {
            let base = u.level as usize * s;
            // A strip spanning the ring's height is a column strip; anything else spans its width.
            let (stamps, start, len) = if u.h == self.size && u.w < self.size {
                (&mut self.cols, u.tex_x, u.w)
            } else {
                (&mut self.rows, u.tex_y, u.h)
            };
            let at = base + start as usize;
            stamps[at..at + len as usize].fill(index + 1);
            self.writes[u.level as usize] += 1;
        }
    }

    /// Strips written to `level` so far ([`UploadStamps::note`]): while it stays the same, so do the
    /// level's stamps, and a tile's [`UploadStamps::latest`] need not be read again.
    pub fn writes(&self, level: u32) -> u64 {
        self.writes.get(level as usize).copied().unwrap_or(u64::MAX)
    }

    /// The rectangles written after frame `since` (every written one when `None`), into `out` (cleared
    /// first). A level whose every column was written is one whole-layer rectangle; otherwise its written
    /// columns and rows, in runs (more than [`RUNS_PER_AXIS`] runs join across the gap before them, which
    /// re-sends unchanged texels). Allocation-free.
    pub fn since(&self, since: Option<u64>, out: &mut UploadList) -> Result<()> {
        out.clear();
        let after = since.map_or(1, |i| i + 2);
        let s = self.size as usize;
        for level in 0..self.levels {
            let base = level as usize * s;
            let cols = runs(&self.cols[base..base + s], after);
            let rows = runs(&self.rows[base..base + s], after);
            let mut push = |u: Upload| {
                out.push(u).map_err(|_| Error::Capacity {
                    what: "plan uploads",
                    capacity: MAX_PLAN_UPLOADS,
                })
            };
            if cols.len() == 1 && cols[0] == (0, self.size) {
                push(whole(level, self.size))?;
                continue;
            }
            if rows.len() == 1 && rows[0] == (0, self.size) {
                push(whole(level, self.size))?;
                continue;
            }
            for &(x, w) in &cols {
                push(Upload {
                    level,
                    tex_x: x,
                    tex_y: 0,
                    w,
                    h: self.size,
                })?;
            }
            for &(y, h) in &rows {
                push(Upload {
                    level,
                    tex_x: 0,
                    tex_y: y,
                    w: self.size,
                    h,
                })?;
            }
        }
        Ok(())
    }
}

fn whole(level: u32, size: u32) -> Upload {
    Upload {
        level,
        tex_x: 0,
        tex_y: 0,
        w: size,
        h: size,
    }
}

/// Runs (start, length) of stamps >= `after` (>= 1), at most [`RUNS_PER_AXIS`].
fn runs(stamps: &[u64], after: u64) -> heapless::Vec<(u32, u32), RUNS_PER_AXIS> {
    let mut out: heapless::Vec<(u32, u32), RUNS_PER_AXIS> = heapless::Vec::new();
    let mut start = None;
    let close = |out: &mut heapless::Vec<(u32, u32), RUNS_PER_AXIS>, a: usize, b: usize| {
        let (a, b) = (
            u32::try_from(a).expect("ring side fits u32"),
            u32::try_from(b).expect("ring side fits u32"),
        );
        if out.is_full() {
            let last = out.last_mut().expect("a full list has a last run");
            last.1 = b - last.0;
        } else {
            out.push((a, b - a)).expect("not full");
        }
    };
    for (i, &t) in stamps.iter().enumerate() {
        match (t >= after, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                close(&mut out, a, i);
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        close(&mut out, a, stamps.len());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn up(level: u32, tex_x: u32, tex_y: u32, w: u32, h: u32) -> Upload {
        Upload {
            level,
            tex_x,
            tex_y,
            w,
            h,
        }
    }

    #[test]
    fn union_of_skipped_frames() {
        let mut s = UploadStamps::new(2, 16);
        s.note(0, &[up(0, 0, 0, 16, 16), up(1, 0, 0, 16, 16)]);
        let mut out = UploadList::new();
        s.since(None, &mut out).expect("fits");
        assert_eq!(out.as_slice(), [up(0, 0, 0, 16, 16), up(1, 0, 0, 16, 16)]);
        s.note(1, &[up(0, 3, 0, 2, 16)]);
        s.note(2, &[up(0, 5, 0, 1, 16), up(0, 0, 7, 16, 2)]);
        s.since(Some(0), &mut out).expect("fits");
        assert_eq!(out.as_slice(), [up(0, 3, 0, 3, 16), up(0, 0, 7, 16, 2)]);
        s.since(Some(1), &mut out).expect("fits");
        assert_eq!(out.as_slice(), [up(0, 5, 0, 1, 16), up(0, 0, 7, 16, 2)]);
        s.since(Some(2), &mut out).expect("fits");
        assert!(out.is_empty());
    }

    #[test]
    fn many_runs_join() {
        let mut s = UploadStamps::new(1, 32);
        for (k, x) in [0u32, 4, 8, 12, 16, 20].into_iter().enumerate() {
            s.note(k as u64 + 1, &[up(0, x, 0, 1, 32)]);
        }
        let mut out = UploadList::new();
        s.since(Some(0), &mut out).expect("fits");
        assert_eq!(out.len(), RUNS_PER_AXIS);
        assert_eq!(out[3], up(0, 12, 0, 9, 32));
    }
}
