//! Stage 1b, the package: the out-of-core bake's first pass. The source is read in bands of rows and every
//! pyramid level (D, the binomial filter of [`crate::bake::pyramid`], GC section 4) is built row by row and
//! spilled to a temporary file, so the working set is a band plus five filtered rows per level.
//!
//! Bit-identical to [`crate::bake::pyramid::Pyramid::build`]: level k+1's row y is the same f64 sums, in the
//! same order, of the same five horizontally filtered rows 2y-2 ..= 2y+2 (clamped) of level k.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use super::format::level_sizes;
use crate::progress::Meter;
use crate::source::RowSource;
use crate::{Error, Result};

/// Rows read from the source at a time.
const BAND_ROWS: u32 = 64;

/// Bands the reader may read ahead of the filtering thread: a source reads in bursts (a GeoTIFF a strip
/// of rows at a time, 278 rows in SRTM's 1801^2 tiles), and with one band ahead the filtering thread
/// waited out each burst. 4 bands were the quickest on the 16-tile mosaic of `docs/guide.md`'s "Tile
/// mosaics" (its read 0.51 s with 1, 0.45 with 3, 0.33 with 4, 0.40 with 6, on 2 cores): 5 bands of
/// rows held, O(width).
const AHEAD: usize = 4;

/// The binomial weights of D ([1, 4, 6, 4, 1] / 16), as `bake::pyramid` applies them.
const D_WEIGHTS: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// A temporary file beside the package, locked while it lives and removed when dropped.
pub(super) use crate::temp::TempFile;

/// One level in progress: its file, and D's state (the five latest horizontally filtered finer rows).
struct Level {
    width: u32,
    height: u32,
    out: std::io::BufWriter<File>,
    tmp: TempFile,
    /// Ring of 5 rows of `width` f64: finer row r at slot r % 5 (unused at level 0).
    ring: Vec<f64>,
    /// The next row of this level to produce.
    next: u32,
    /// Scratch for the row being produced.
    row: Vec<f32>,
}

/// Temporary files removed on a thread of their own: the last close of a spilled file of hundreds of
/// MiB frees its pages for tens of milliseconds of one core, which the bake's other threads use
/// meanwhile. Joined when dropped, so the files are gone when the bake returns, whichever way it does.
#[derive(Default)]
pub(super) struct Removing(Vec<std::thread::JoinHandle<()>>);

impl Removing {
    /// Drops `what` (its temporary files) beside the caller, or here if no thread can be started.
    pub(super) fn beside<T: Send + 'static>(&mut self, what: T) {
        // A failed spawn drops the closure, and `what` with it, here.
        if let Ok(h) = std::thread::Builder::new().spawn(move || drop(what)) {
            self.0.push(h);
        }
    }
}

impl Drop for Removing {
    fn drop(&mut self) {
        for h in self.0.drain(..) {
            // A panic there is a file left for a later sweep to remove.
            let _ = h.join();
        }
    }
}

/// Every pyramid level of a source, spilled to temporary files next to the package (removed on drop),
/// with what the bake needs to know about the source.
pub(super) struct Spilled {
    levels: Vec<(u32, u32, TempFile)>,
    /// Lowest and highest source sample, metres.
    pub(super) range: (f32, f32),
    /// Whether every source sample sits on the 1 m / 0.1 m lattice ([`super::write::source_quantum`]).
    pub(super) on_lattice: [bool; 2],
}

/// Whether `h` sits on the lattice of step `q` (the test of [`super::write::source_quantum`]).
pub(super) fn on_lattice(h: f32, q: f64) -> bool {
    let k = round_half_away(f64::from(h) / q);
    #[expect(
        clippy::cast_possible_truncation,
        reason = "compared in f32, as stored"
    )]
    let back = (k * q) as f32;
    (back - h).abs() <= 2.0 * f32::EPSILON * h.abs().max(1.0)
}

/// `x.round()`, bit for bit but the sign of a zero, without the libm call that `f64::round` is on the
/// x86-64 baseline (no SSE4.1): the bake tests every source sample against two lattices, and the calls
/// were 3 % of a bake's time, all of it on the thread that reads the source.
pub(super) fn round_half_away(x: f64) -> f64 {
    // Past 2^52 every f64 is an integer (and a NaN or infinity is returned as it is).
    if x.abs() >= 4_503_599_627_370_496.0 || !x.is_finite() {
        return x;
    }
    #[expect(
        clippy::cast_possible_truncation,
        clippy::cast_precision_loss,
        reason = "|x| < 2^52: the conversion truncates exactly and the integer is exact in f64"
    )]
    let t = x as i64 as f64;
    // x - t is exact (|x - t| < 1 and both lie within 2^52).
    if (x - t).abs() >= 0.5 {
        t + x.signum()
    } else {
        t
    }
}

/// What the source's samples so far say: all finite, their range, and the lattices they sit on.
struct Checked {
    path: std::path::PathBuf,
    width: u32,
    range: (f32, f32),
    lattice: [bool; 2],
}

impl Checked {
    /// Band `band` (whole rows from `y0`), checked sample by sample in row order: the first non-finite one
    /// is the error.
    fn band(&mut self, y0: u32, band: &[f32]) -> Result<()> {
        for (y, row) in (y0..).zip(band.chunks_exact(self.width as usize)) {
            for (x, &v) in (0u32..).zip(row) {
                if !v.is_finite() {
                    return Err(Error::NonFinite {
                        path: self.path.clone(),
                        x,
                        y,
                        value: v,
                    });
                }
                self.range = (self.range.0.min(v), self.range.1.max(v));
                // An integer is on both lattices (`integral`), so only the others are tested.
                if (self.lattice[0] || self.lattice[1]) && !integral(v) {
                    for (ok, q) in self.lattice.iter_mut().zip([1.0, 0.1]) {
                        *ok = *ok && on_lattice(v, q);
                    }
                }
            }
        }
        Ok(())
    }
}

/// Whether `h` is an integer of at most 2^24 in magnitude, which [`on_lattice`] finds on both lattices
/// (a conversion instead of its two divisions and roundings). For q = 1, round(h) = h and back = h. For
/// q = 0.1, h / 0.1 lies within 3e-8 of the integer 10 h (|10 h| <= 1.7e8; 0.1 is 1 + 5.6e-17 times
/// one tenth, plus one rounding), so k = 10 h; k 0.1 lies within 2e-16 |h| of h, so it rounds to the f32
/// h itself (its neighbours are 2^-24 |h| away at least) and the difference is 0.
fn integral(h: f32) -> bool {
    #[expect(
        clippy::cast_possible_truncation,
        reason = "|h| <= 2^24: the conversion is exact for an integer, and truncates any other"
    )]
    let i = h as i32;
    #[expect(
        clippy::cast_precision_loss,
        reason = "|i| <= 2^24 is exact in f32"
    )]
    let back = i as f32;
    h.abs() <= 16_777_216.0 && back == h
}

impl Spilled {
    /// Reads `src` top to bottom and spills every level, advancing `meter` by source rows.
    pub(super) fn build(
        src: &mut (impl RowSource + ?Sized),
        near: &Path,
        meter: &mut Meter<'_>,
    ) -> Result<Self> {
        let (w, h) = (src.width(), src.height());
        if w < 2 || h < 2 {
            return Err(Error::format(
                src.path(),
                format!("{w} x {h} samples: need at least 2 x 2"),
            ));
        }
        let mut levels = Vec::new();
        for (l, (lw, lh)) in level_sizes(w, h).into_iter().enumerate() {
            let tmp = TempFile::create(
                near.with_extension(format!("level{l}.tmp{}", crate::temp_suffix())),
            )?;
            let file = tmp
                .file
                .try_clone()
                .map_err(|e| Error::io(&tmp.path, "cannot open", e))?;
            levels.push(Level {
                width: lw,
                height: lh,
                out: std::io::BufWriter::with_capacity(1 << 16, file),
                tmp,
                ring: if l == 0 {
                    Vec::new()
                } else {
                    vec![0.0; 5 * lw as usize]
                },
                next: 0,
                row: vec![0.0; lw as usize],
            });
        }
        let mut checked = Checked {
            path: src.path().to_path_buf(),
            width: w,
            range: (f32::INFINITY, f32::NEG_INFINITY),
            lattice: [true; 2],
        };
        meter.set_total(u64::from(h));
        // The source is read on this thread while a second one filters the band read before (the reader
        // need not be Send); bands go over in order and come back to be refilled. Each band's first half
        // is checked here and its second half there (the reading costs more than the filtering), so a
        // non-finite sample is still met in row order: the worker checks its half before filtering any of
        // the band, and the reader's error is in a band after every band the worker took.
        let band_len = w as usize * BAND_ROWS.min(h) as usize;
        let (to_work, work_in) = std::sync::mpsc::sync_channel::<(u32, Vec<f32>)>(AHEAD);
        let (to_read, read_in) = std::sync::mpsc::channel::<Vec<f32>>();
        let mut checked_there = Checked {
            path: checked.path.clone(),
            ..checked
        };
        // The rows of a band checked here: the first half (of at most BAND_ROWS, a u32).
        let half = |band: &[f32]| u32::try_from(band.len() / w as usize / 2).unwrap_or(u32::MAX);
        let (read, worked) = std::thread::scope(|s| {
            let (levels, there) = (&mut levels, &mut checked_there);
            // Moved in, so that the reader's waits end when the worker stops.
            let worker = s.spawn(move || {
                for (y0, band) in work_in {
                    let rows = half(&band);
                    there.band(y0 + rows, &band[rows as usize * w as usize..])?;
                    for (y, row) in (y0..).zip(band.chunks_exact(w as usize)) {
                        feed(levels, 0, y, row)?;
                    }
                    // The reader may have stopped (an error): then the band is not wanted back.
                    let _ = to_read.send(band);
                }
                Ok(())
            });
            let mut spare = vec![vec![0.0f32; band_len]; AHEAD + 1];
            let mut y0 = 0;
            let read = loop {
                if y0 >= h {
                    break Ok(());
                }
                let mut band = match spare.pop() {
                    Some(b) => b,
                    // The worker stopped (its error is reported below) or returns the band it is done with.
                    None => match read_in.recv() {
                        Ok(b) => b,
                        Err(_) => break Ok(()),
                    },
                };
                let rows = BAND_ROWS.min(h - y0);
                band.resize(rows as usize * w as usize, 0.0);
                if let Err(e) = src
                    .read_rows(y0, &mut band)
                    .and_then(|()| checked.band(y0, &band[..half(&band) as usize * w as usize]))
                {
                    break Err(e);
                }
                if to_work.send((y0, band)).is_err() {
                    break Ok(());
                }
                y0 += rows;
                meter.inc(u64::from(rows));
            };
            drop(to_work);
            let worked = worker
                .join()
                .unwrap_or_else(|_| panic!("the pyramid's filtering thread panicked"));
            (read, worked)
        });
        // The worker's error first: it is in a band read before the reader's.
        worked?;
        read?;
        let range = (
            checked.range.0.min(checked_there.range.0),
            checked.range.1.max(checked_there.range.1),
        );
        let lattice = [0, 1].map(|i| checked.lattice[i] && checked_there.lattice[i]);
        let mut done = Vec::with_capacity(levels.len());
        for l in levels {
            assert_eq!(l.next, l.height, "every row of every level was produced");
            l.out
                .into_inner()
                .map_err(|e| Error::io(&l.tmp.path, "cannot write", e.into_error()))?;
            done.push((l.width, l.height, l.tmp));
        }
        Ok(Self {
            levels: done,
            range,
            on_lattice: lattice,
        })
    }

    /// Number of levels.
    pub(super) fn len(&self) -> usize {
        self.levels.len()
    }

    /// Rows `y0..` of level `l` into `out` (whole rows).
    pub(super) fn read_rows(&mut self, l: usize, y0: u32, out: &mut [f32]) -> Result<()> {
        let (w, _, tmp) = &mut self.levels[l];
        let at = u64::from(y0) * u64::from(*w) * 4;
        tmp.file
            .seek(SeekFrom::Start(at))
            .and_then(|_| tmp.file.read_exact(bytemuck::cast_slice_mut(out)))
            .map_err(|e| Error::io(&tmp.path, "cannot read a temporary level file", e))
    }
}

/// Row `y` of level `l` is done: write it, and hand it to D for level l + 1 (recursively down the pyramid).
#[expect(
    clippy::cast_possible_truncation,
    reason = "coordinates clamped into a row or a level, whose sizes are usize and u32"
)]
fn feed(levels: &mut [Level], l: usize, y: u32, row: &[f32]) -> Result<()> {
    {
        let lv = &mut levels[l];
        lv.out
            .write_all(bytemuck::cast_slice(row))
            .map_err(|e| Error::io(&lv.tmp.path, "cannot write", e))?;
        if l == 0 {
            lv.next = y + 1;
        }
    }
    let Some(coarse) = levels.get_mut(l + 1) else {
        return Ok(());
    };
    // Horizontal pass of D into the ring (the f64 sums of `bake::pyramid::downsample`).
    let cw = coarse.width as usize;
    let fw = i64::try_from(row.len()).expect("a row fits i64");
    let slot = (y % 5) as usize;
    for (x, s) in coarse.ring[slot * cw..(slot + 1) * cw]
        .iter_mut()
        .enumerate()
    {
        let mut sum = 0.0;
        for (t, wt) in D_WEIGHTS.iter().enumerate() {
            let xx = (2 * x as i64 + t as i64 - 2).clamp(0, fw - 1) as usize;
            sum += wt * f64::from(row[xx]);
        }
        *s = sum;
    }
    // Vertical pass: coarse row cy needs finer rows up to 2 cy + 2 (clamped to the last one).
    let fh = i64::from(levels[l].height);
    loop {
        let coarse = &mut levels[l + 1];
        let cy = coarse.next;
        if cy >= coarse.height || (2 * i64::from(cy) + 2).min(fh - 1) > i64::from(y) {
            return Ok(());
        }
        let mut out = std::mem::take(&mut coarse.row);
        for (x, o) in out.iter_mut().enumerate() {
            let mut sum = 0.0;
            for (t, wt) in D_WEIGHTS.iter().enumerate() {
                let yy = (2 * i64::from(cy) + t as i64 - 2).clamp(0, fh - 1);
                sum += wt * coarse.ring[(yy % 5) as usize * cw + x];
            }
            #[expect(
                clippy::cast_possible_truncation,
                reason = "heights are stored as f32; the f64 sum is rounded once"
            )]
            let v = sum as f32;
            *o = v;
        }
        coarse.next = cy + 1;
        let r = feed(levels, l + 1, cy, &out);
        levels[l + 1].row = out;
        r?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Progress;
    use crate::bake::pyramid::Pyramid;
    use crate::source::Heightmap;

    #[test]
    fn round_half_away_is_round() {
        let mut x = 0x1234_5678_9abc_def0_u64;
        let mut cases = vec![0.5, -0.5, 1.5, -2.5, 0.49999999999999994, 4_503_599_627_370_495.5, 1e300, -0.3];
        for _ in 0..100_000 {
            // xorshift: values over many magnitudes, and halves.
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            // Magnitudes 2^-15 to 2^65, either sign.
            let exponent = 0x3f0 + (x >> 52) % 0x50;
            let v = f64::from_bits((exponent << 52) | (x & ((1 << 52) - 1)));
            let v = if x & 1 == 0 { v } else { -v };
            cases.push(v);
            cases.push((v * 2.0).round() / 2.0);
        }
        for v in cases {
            let (a, b) = (super::round_half_away(v), v.round());
            assert!(a == b, "{v}: {a} against {b}");
        }
    }

    #[test]
    fn integers_are_on_both_lattices() {
        // `integral` stands for the two lattice tests on every integer up to 2^24 (checked here over a
        // range of them and at the largest), and never says yes to anything else.
        let ends = (16_777_216 - 100_000..=16_777_216).chain(0..=300_000);
        for i in ends {
            #[expect(clippy::cast_precision_loss, reason = "test values up to 2^24, exact")]
            for v in [i as f32, -(i as f32)] {
                assert!(integral(v), "{v}");
                assert!(on_lattice(v, 1.0) && on_lattice(v, 0.1), "{v}");
            }
        }
        for v in [0.5f32, -0.1, 1e-30, 16_777_218.0, f32::NAN, f32::INFINITY, 3.000_000_2] {
            assert!(!integral(v), "{v}");
        }
    }

    /// Rows of a function of (x, y), for the checks' tests.
    struct Rows {
        grid: crate::source::RowGrid,
        f: fn(u32, u32) -> f32,
    }

    impl RowSource for Rows {
        fn grid(&self) -> &crate::source::RowGrid {
            &self.grid
        }
        fn read_rows(&mut self, y0: u32, out: &mut [f32]) -> Result<()> {
            let w = self.grid.width;
            for (y, row) in (y0..).zip(out.chunks_exact_mut(w as usize)) {
                for (x, v) in (0..).zip(row) {
                    *v = (self.f)(x, y);
                }
            }
            Ok(())
        }
    }

    #[test]
    fn checks_meet_the_first_bad_sample_in_row_order_and_every_value() {
        // Each band's first half is checked by the reader, its second half by the filtering thread.
        type Heights = fn(u32, u32) -> f32;
        let cases: [(Heights, Option<(u32, u32)>); 4] = [
            (|x, y| if (x, y) == (5, 40) || (x, y) == (3, 70) { f32::NAN } else { 1.0 }, Some((5, 40))),
            (|x, y| if (x, y) == (5, 40) || (x, y) == (3, 10) { f32::NAN } else { 1.0 }, Some((3, 10))),
            (|x, y| if (x, y) == (7, 100) || (x, y) == (1, 130) { f32::INFINITY } else { 1.0 }, Some((7, 100))),
            (|x, y| if (x, y) == (3, 40) { 1000.5 } else { -2.0 }, None),
        ];
        let dir = std::env::temp_dir().join(format!("clipsat-checks-{}", std::process::id()));
        for (f, bad) in cases {
            let grid = crate::source::RowGrid {
                width: 9,
                height: 200,
                spacing: 1.0,
                ew_spacing: 1.0,
                origin: (0.0, 0.0),
                path: Path::new("t").into(),
            };
            let got = Spilled::build(
                &mut Rows { grid, f },
                &dir,
                &mut Progress::default().task("checks test", 0),
            );
            match (got, bad) {
                (Err(Error::NonFinite { x, y, .. }), Some(xy)) => assert_eq!((x, y), xy),
                (Ok(s), None) => {
                    assert_eq!(s.range, (-2.0, 1000.5));
                    assert_eq!(s.on_lattice, [false, true]);
                }
                (other, _) => panic!("expected {bad:?}, got {:?}", other.err()),
            }
        }
    }

    #[test]
    fn spilled_levels_are_the_pyramid_bit_for_bit() {
        for (w, h) in [(2, 2), (5, 3), (67, 130), (129, 129), (200, 77)] {
            let heights: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = (f64::from(i % w), f64::from(i / w));
                    #[expect(clippy::cast_possible_truncation, reason = "test data")]
                    let v =
                        ((x * 0.37).sin() * 40.0 + (y * 0.21).cos() * 25.0 + x * y * 0.01) as f32;
                    v
                })
                .collect();
            let hm = Heightmap::new(Path::new("t"), w, h, 1.0, heights).unwrap();
            let dir =
                std::env::temp_dir().join(format!("clipsat-spill-{}-{w}x{h}", std::process::id()));
            let mut s = Spilled::build(
                &mut crate::source::Resident::new(&hm),
                &dir,
                &mut Progress::default().task("spill test", 0),
            )
            .unwrap();
            let p = Pyramid::build(&hm);
            assert_eq!(s.len(), p.len());
            for l in 0..p.len() {
                let lv = p.level(l);
                let mut got = vec![0.0f32; lv.heights().len()];
                s.read_rows(l, 0, &mut got).unwrap();
                assert!(
                    got.iter()
                        .zip(lv.heights())
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{w} x {h} level {l}"
                );
            }
            assert_eq!(s.range, hm.range());
        }
    }
}
