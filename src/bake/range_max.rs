//! Stage 1, bake: the range-maximum pyramid that the SAT LOD tables ([`crate::bake::lod_tables`]) keep
//! beside each level's SAT, for the `exact` bound and the cap of `sat-conservative` (docs/design.md "SAT LOD").

use crate::bake::mapped::Grid;

/// Range maximum over a grid of non-negative f32: a max pyramid (level k+1 = max of 2 x 2 of level k).
///
/// A query peels odd border rows and columns at each level and halves, so it reads O(w + h) cells in the
/// worst case and O(1) levels' worth for boxes aligned to large powers of two. Memory: 4/3 x 4 bytes per
/// sample, and 4 more where the finest level is also kept column by column ([`RangeMax::with_columns`]).
#[derive(Clone, Debug)]
pub struct RangeMax {
    dims: Vec<(u32, u32)>,
    levels: Vec<Grid<f32>>,
    /// The finest level again, column by column (value (x, y) at x h + y), where the pyramid is read from
    /// a cache file: a query one cell wide (the `sat-conservative` bound's far column) peels a whole
    /// column of the finest level, which row by row lies in one 64 KiB window of the mapped file per few
    /// rows and here in one run. Measured on a 7201^2 mosaic's flight: the first frame's plan 8.9 ms
    /// with the rows, most of it faulting their windows in and the trims they forced (docs/plan-time.md).
    columns: Option<Grid<f32>>,
}

/// A column of the finest level spanning at most this many 64 KiB windows of its rows is read from the
/// rows, whose windows other reads near it share. Read from the columns at any length, the steep 1" tile's
/// flights (docs/plan-time.md) held more distinct windows and forced 2-3 trims of the tables' share where
/// the rows forced 0-1; past 2 windows, 1-2; past 8, as with the rows.
const COLUMN_SPAN_WINDOWS: u64 = 8;

/// The levels are the pyramid; the columns only a copy of the finest one, laid out for reading.
impl PartialEq for RangeMax {
    fn eq(&self, other: &Self) -> bool {
        self.dims == other.dims && self.levels == other.levels
    }
}

impl RangeMax {
    /// Builds the pyramid over `values` (`width x height`, row-major); panics on a size mismatch.
    pub fn build(width: u32, height: u32, values: Vec<f32>) -> Self {
        assert_eq!(
            values.len() as u64,
            u64::from(width) * u64::from(height),
            "range-max grid size"
        );
        let dims = Self::dims(width, height);
        let mut levels = vec![values];
        for &(w, h) in &dims[..dims.len() - 1] {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let prev = levels.last().expect("a level");
            let mut next = vec![0.0f32; nw as usize * nh as usize];
            for y in 0..nh as usize {
                for x in 0..nw as usize {
                    let mut m = 0.0f32;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = (2 * x + dx, 2 * y + dy);
                        if sx < w as usize && sy < h as usize {
                            m = m.max(prev[sy * w as usize + sx]);
                        }
                    }
                    next[y * nw as usize + x] = m;
                }
            }
            levels.push(next);
        }
        Self {
            dims,
            levels: levels.into_iter().map(Grid::owned).collect(),
            columns: None,
        }
    }

    /// Each level's (width, height), finest first: halving (rounded up) down to 1 x 1.
    pub fn dims(width: u32, height: u32) -> Vec<(u32, u32)> {
        let mut dims = vec![(width, height)];
        while let Some(&(w, h)) = dims.last() {
            if w <= 1 && h <= 1 {
                break;
            }
            dims.push((w.div_ceil(2), h.div_ceil(2)));
        }
        dims
    }

    /// A pyramid from its levels as [`RangeMax::levels`] returns them (e.g. borrowed from a mapped
    /// cache file); None if their number or sizes do not follow [`RangeMax::dims`] of the first.
    pub fn from_levels(width: u32, height: u32, levels: Vec<Grid<f32>>) -> Option<Self> {
        let dims = Self::dims(width, height);
        let fits = dims.len() == levels.len()
            && dims
                .iter()
                .zip(&levels)
                .all(|(&(w, h), l)| l.len() as u64 == u64::from(w) * u64::from(h));
        fits.then_some(Self {
            dims,
            levels,
            columns: None,
        })
    }

    /// The pyramid with its finest level also read from `columns`, that level column by column (value
    /// (x, y) at x h + y, as [`RangeMax::column_major`] lists them); None if the size is not the level's.
    /// Every answer is the same: the values are the level's.
    pub fn with_columns(mut self, columns: Grid<f32>) -> Option<Self> {
        let (w, h) = self.dims[0];
        (columns.len() as u64 == u64::from(w) * u64::from(h)).then(|| {
            self.columns = Some(columns);
            self
        })
    }

    /// The finest level's values column by column, as a cache file stores them beside the levels.
    pub fn column_major(&self) -> impl Iterator<Item = f32> + '_ {
        let (w, h) = (self.dims[0].0 as usize, self.dims[0].1 as usize);
        let values: &[f32] = &self.levels[0];
        (0..w).flat_map(move |x| (0..h).map(move |y| values[y * w + x]))
    }

    /// The maximum of `m` and the finest level's cells (x, y0 .. y1), read from the columns where held.
    fn column_max(&self, m: f32, x: u32, y0: u32, y1: u32) -> f32 {
        let (w, g) = (self.dims[0].0 as usize, &self.levels[0]);
        let rows_bytes = (y1 - y0) as u64 * w as u64 * 4;
        let cols = match &self.columns {
            Some(cols) if rows_bytes > COLUMN_SPAN_WINDOWS * crate::bake::mapped::PAGE_BYTES => cols,
            _ => {
                return (y0..y1).fold(m, |m, y| {
                    let i = y as usize * w + x as usize;
                    g.touch(i);
                    m.max(g[i])
                });
            }
        };
        let start = x as usize * self.dims[0].1 as usize + y0 as usize;
        let mut m = m;
        cols.for_each_run(start, (y1 - y0) as usize, |run| {
            m = run.iter().fold(m, |m, &v| m.max(v));
        });
        m
    }

    /// Every level, finest first (for caching).
    pub fn levels(&self) -> &[Grid<f32>] {
        &self.levels
    }

    /// Bytes of the levels (and columns) held in owned memory (0 for mapped ones).
    pub fn owned_bytes(&self) -> u64 {
        self.levels.iter().chain(&self.columns).map(Grid::owned_bytes).sum()
    }

    /// The finest level: the values themselves.
    pub fn values(&self) -> &[f32] {
        &self.levels[0]
    }

    /// The finest level's width and height.
    pub fn size(&self) -> (u32, u32) {
        self.dims[0]
    }

    /// Bytes the pyramid holds (its columns included).
    pub fn memory_bytes(&self) -> u64 {
        self.levels.iter().chain(&self.columns).map(|l| l.len() as u64 * 4).sum()
    }

    /// An upper bound of the maximum over [x0, x1) x [y0, y1) (0 for an empty box) read in O(1): the
    /// maximum of the at most 2 x 2 cells of the first pyramid level whose cells cover the box that many
    /// to a side (each cell's value is the maximum over its samples, so over a superset of the box).
    pub fn max_coarse(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> f32 {
        if x0 >= x1 || y0 >= y1 {
            return 0.0;
        }
        let mut j = 0;
        while j + 1 < self.levels.len()
            && (((x1 - 1) >> j) - (x0 >> j) > 1 || ((y1 - 1) >> j) - (y0 >> j) > 1)
        {
            j += 1;
        }
        let (w, h) = self.dims[j];
        let vals = &self.levels[j];
        let mut m = 0.0f32;
        for y in (y0 >> j)..=((y1 - 1) >> j).min(h - 1) {
            for x in (x0 >> j)..=((x1 - 1) >> j).min(w - 1) {
                let i = y as usize * w as usize + x as usize;
                // A mapped grid counts its pages against its resident limit (bake::mapped).
                vals.touch(i);
                m = m.max(vals[i]);
            }
        }
        m
    }

    /// Maximum over [x0, x1) x [y0, y1) (0 for an empty box); panics past the grid.
    pub fn max(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> f32 {
        assert!(
            x1 <= self.dims[0].0 && y1 <= self.dims[0].1,
            "range-max box past the grid"
        );
        let (mut x0, mut y0, mut x1, mut y1) = (x0, y0, x1, y1);
        let mut m = 0.0f32;
        for (k, vals) in self.levels.iter().enumerate() {
            let vals: &[f32] = vals;
            if x0 >= x1 || y0 >= y1 {
                break;
            }
            let grid = &self.levels[k];
            let w = self.dims[k].0 as usize;
            // A mapped grid counts its pages against its resident limit (bake::mapped).
            let at = |x: u32, y: u32| {
                let i = y as usize * w + x as usize;
                grid.touch(i);
                vals[i]
            };
            if k + 1 == self.levels.len() {
                for y in y0..y1 {
                    for x in x0..x1 {
                        m = m.max(at(x, y));
                    }
                }
                break;
            }
            // The finest level's columns from the columns where held ([`RangeMax::column_max`]).
            let column = |m: f32, x: u32| match k {
                0 => self.column_max(m, x, y0, y1),
                _ => (y0..y1).fold(m, |m, y| m.max(at(x, y))),
            };
            if x0 & 1 == 1 {
                m = column(m, x0);
                x0 += 1;
            }
            if x1 & 1 == 1 && x1 > x0 {
                m = column(m, x1 - 1);
                x1 -= 1;
            }
            if y0 & 1 == 1 {
                (x0..x1).for_each(|x| m = m.max(at(x, y0)));
                y0 += 1;
            }
            if y1 & 1 == 1 && y1 > y0 {
                (x0..x1).for_each(|x| m = m.max(at(x, y1 - 1)));
                y1 -= 1;
            }
            (x0, y0, x1, y1) = (x0 / 2, y0 / 2, x1 / 2, y1 / 2);
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of `w` x `h` pseudo-random errors.
    fn grid(w: u32, h: u32) -> Vec<f32> {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        (0..w * h)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 40) as f32 / 1024.0
            })
            .collect()
    }

    /// The maximum over a box by a scan.
    fn scan(values: &[f32], w: u32, (x0, y0, x1, y1): (u32, u32, u32, u32)) -> f32 {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .fold(0.0f32, |m, (x, y)| m.max(values[(y * w + x) as usize]))
    }

    /// A grid wide and tall enough that a column spans more than [`COLUMN_SPAN_WINDOWS`] windows of
    /// its rows, so the columns are read: the same maxima as the rows and a scan.
    #[test]
    fn long_columns_are_read_from_the_columns_alike() {
        let (w, h) = (1031u32, 300u32);
        assert!(u64::from(h) * u64::from(w) * 4 > COLUMN_SPAN_WINDOWS * crate::bake::mapped::PAGE_BYTES);
        let values = grid(w, h);
        let rows = RangeMax::build(w, h, values.clone());
        let both = rows
            .clone()
            .with_columns(Grid::owned(rows.column_major().collect()))
            .expect("the finest level's size");
        for bx in [(0, 0, 1, h), (5, 3, 6, h - 1), (w - 1, 0, w, h), (7, 1, 900, 299), (2, 0, 3, 40)] {
            assert_eq!(rows.max(bx.0, bx.1, bx.2, bx.3), scan(&values, w, bx), "{bx:?}");
            assert_eq!(both.max(bx.0, bx.1, bx.2, bx.3), scan(&values, w, bx), "{bx:?}");
        }
    }

    /// Every box of a grid whose sides are not powers of two, one cell wide and high included, gives a
    /// scan's maximum, with the columns held and without. Its columns are too short to be read from them
    /// ([`COLUMN_SPAN_WINDOWS`]): the rows answer; the next test reads the columns.
    #[test]
    fn columns_give_the_same_maxima() {
        let (w, h) = (13u32, 9u32);
        let values = grid(w, h);
        let rows = RangeMax::build(w, h, values.clone());
        let cols: Vec<f32> = rows.column_major().collect();
        let both = rows
            .clone()
            .with_columns(Grid::owned(cols))
            .expect("the finest level's size");
        assert_eq!(both, rows);
        assert!(rows.clone().with_columns(Grid::owned(vec![0.0; 3])).is_none());
        for y0 in 0..h {
            for y1 in y0 + 1..=h {
                for x0 in 0..w {
                    for x1 in x0 + 1..=w {
                        let scan = scan(&values, w, (x0, y0, x1, y1));
                        assert_eq!(rows.max(x0, y0, x1, y1), scan);
                        assert_eq!(both.max(x0, y0, x1, y1), scan, "({x0}, {y0}) .. ({x1}, {y1})");
                    }
                }
            }
        }
    }
}
