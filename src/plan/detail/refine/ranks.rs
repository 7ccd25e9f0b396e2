//! Stage 2, the per-frame plan: the refinement's ranks, one per cell in step with the cells
//! ([`super::Quadtree::rank`]), with the largest of each run of [`RUN`] cells kept beside them. The next
//! split is found by reading the runs' maxima and one run, instead of every cell at every split (a
//! twentieth of a Puget Sound plan at 1 px went to that scan).

use super::MAX_DETAIL_CELLS;

/// Cells a run's maximum covers.
const RUN: usize = 32;

/// Runs over [`MAX_DETAIL_CELLS`].
const RUNS: usize = MAX_DETAIL_CELLS.div_ceil(RUN);

/// The cells' ranks and each run's largest (minus infinity for an empty run; a NaN rank is never the
/// largest, as in [`best_of`]).
#[derive(Clone, Debug)]
pub(super) struct Ranks {
    ranks: heapless::Vec<f64, MAX_DETAIL_CELLS>,
    runs: [f64; RUNS],
}

impl Default for Ranks {
    fn default() -> Self {
        Self {
            ranks: heapless::Vec::new(),
            runs: [f64::NEG_INFINITY; RUNS],
        }
    }
}

/// The largest of `ranks` above minus infinity and the first cell that has it (NaN never counts).
pub(super) fn best_of(ranks: impl Iterator<Item = f64>) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (j, r) in ranks.enumerate() {
        if r > f64::NEG_INFINITY && best.is_none_or(|(b, _)| r > b) {
            best = Some((r, j));
        }
    }
    best
}

impl Ranks {
    pub(super) fn clear(&mut self) {
        self.ranks.clear();
        self.runs.fill(f64::NEG_INFINITY);
    }

    pub(super) fn len(&self) -> usize {
        self.ranks.len()
    }

    /// The ranks, in the cells' order.
    #[cfg(test)]
    pub(super) fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        self.ranks.iter().copied()
    }

    /// Appends the next cell's rank; the rank back when [`MAX_DETAIL_CELLS`] are held.
    pub(super) fn push(&mut self, r: f64) -> Result<(), f64> {
        self.ranks.push(r)?;
        let run = &mut self.runs[(self.ranks.len() - 1) / RUN];
        if r > *run {
            *run = r;
        }
        Ok(())
    }

    /// Cell `j`'s rank is now `r`.
    pub(super) fn set(&mut self, j: usize, r: f64) {
        self.ranks[j] = r;
        self.rerun(j / RUN);
    }

    /// Cell `j` is gone and the last cell takes its place (as the cells do).
    pub(super) fn swap_remove(&mut self, j: usize) {
        self.ranks.swap_remove(j);
        self.rerun(j / RUN);
        self.rerun(self.ranks.len() / RUN);
    }

    /// Run `k`'s largest again.
    fn rerun(&mut self, k: usize) {
        let end = ((k + 1) * RUN).min(self.ranks.len());
        let run = self.ranks.get(k * RUN..end).unwrap_or(&[]);
        self.runs[k] = run.iter().fold(f64::NEG_INFINITY, |m, &r| if r > m { r } else { m });
    }

    /// [`best_of`] the ranks: the first run holding the largest maximum holds the first cell with it.
    pub(super) fn best(&self) -> Option<(f64, usize)> {
        let (m, k) = best_of(self.runs.iter().copied())?;
        let from = k * RUN;
        let at = self.ranks[from..]
            .iter()
            .position(|&r| r == m)
            .expect("a run's maximum is one of its ranks");
        Some((m, from + at))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_best_follows_every_change_as_a_scan_finds_it() {
        let mut r = Ranks::default();
        assert_eq!(r.best(), None);
        let mut x = 12_345u64;
        let mut value = || {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            match x >> 60 {
                0 => f64::NEG_INFINITY,
                1 => f64::NAN,
                2 => f64::INFINITY,
                v => f64::from(u32::try_from((x >> 40) % 7).unwrap()) + f64::from(u32::try_from(v).unwrap()),
            }
        };
        for step in 0..20_000 {
            let n = r.len();
            match step % 5 {
                0 | 1 if n < MAX_DETAIL_CELLS => r.push(value()).unwrap(),
                2 if n > 0 => r.set(step % n, value()),
                3 if n > 0 => r.swap_remove((step * 7) % n),
                _ if step % 997 == 0 => r.clear(),
                _ => {}
            }
            let scan = best_of(r.iter());
            assert_eq!(r.best().map(|(v, j)| (v.to_bits(), j)), scan.map(|(v, j)| (v.to_bits(), j)));
        }
        r.clear();
        for _ in 0..MAX_DETAIL_CELLS {
            r.push(1.0).unwrap();
        }
        assert_eq!(r.push(2.0), Err(2.0));
        assert_eq!(r.best(), Some((1.0, 0)));
    }
}
