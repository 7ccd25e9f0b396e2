//! Stage 1b, the package: a package set's bake (`clipsat bake --parts DIR`, `docs/guide.md` "Package
//! sets"). The input tiles' lattice is cut into cells, one a tile for SRTM-like tiles; each cell is baked
//! into its own part from the tiles that reach it alone ([`bake_cell`], any order, on any machine), then
//! the top from the parts' level K and the index ([`finish`]). A part's file name holds its key (what it
//! was baked from and how), so a bake again skips the parts whose key stands: a changed, added or removed
//! tile bakes its cells again, and the top.

use std::path::{Path, PathBuf};

use super::set::{Index, PartEntry, INDEX_FORMAT, INDEX_NAME};
use super::write::{bake, BakeOptions, BakeReport, FLOAT_MAX_ERROR};
use super::Package;
use crate::hash::{hex, Hash64};
use crate::progress::Progress;
use crate::source::{Heightmap, LoadOptions};
use crate::{Error, Result};

/// Most levels a part holds below the top: a level-K tile covers 2^K tiles of level 0 a side, and a cell's
/// origin must be a whole number of them.
pub const MAX_K: u32 = 4;

/// Tile sides a set may choose, when the cells' size does not allow the one asked for.
const TILE_RANGE: (u32, u32) = (16, 256);

/// What a set's bake does: the cells, their sources and keys, and the parameters all parts share.
#[derive(Clone, Debug)]
pub struct SetPlan {
    /// The tiles as given (a folder, list, glob or VRT).
    pub spec: PathBuf,
    /// The set's folder.
    pub dir: PathBuf,
    /// How the tiles are read.
    pub load: LoadOptions,
    /// The bake options every part and the top use (tile, codec, bound, quantum).
    pub opts: BakeOptions,
    /// The index, its parts' files and keys filled in.
    pub index: Index,
    /// Each cell's grid rectangle, (x0, y0, x1, y1) inclusive, row-major like the index's parts.
    pub cells: Vec<[u32; 4]>,
}

/// What [`bake_set`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SetReport {
    /// Cells in the set.
    pub cells: usize,
    /// Cells baked this time (the others' parts stood).
    pub baked: usize,
    /// Parts removed (stale keys).
    pub removed: usize,
    /// Bytes of every part and the top.
    pub bytes: u64,
    /// Tile side and levels per part the set chose.
    pub tile: u32,
    /// Levels each part holds.
    pub part_levels: u32,
}

/// Plans the set of the tile mosaic `spec` in `dir`: the cells, the tile side and levels per part, the
/// quantum (by the tiles' sample types), and each part's key.
pub fn plan(spec: &Path, load: &LoadOptions, opts: &BakeOptions, dir: &Path) -> Result<SetPlan> {
    if load.resample_ew {
        return Err(Error::format(
            spec,
            "a package set keeps the tiles' grid, and resampling the rows east-west resamples the whole \
             mosaic's: bake the mosaic into one package for it",
        ));
    }
    let (grid, tiles) = crate::source::mosaic_cells(spec, load)?;
    let mut columns: Vec<u32> = tiles.iter().map(|t| t.1[0]).collect();
    let mut rows: Vec<u32> = tiles.iter().map(|t| t.1[1]).collect();
    for v in [&mut columns, &mut rows] {
        v.sort_unstable();
        v.dedup();
    }
    // Tiles' first samples at 0 on both axes: the grid starts at the north-west-most sample.
    let g = columns
        .iter()
        .chain(&rows)
        .filter(|&&s| s > 0)
        .fold(0u32, |a, &b| gcd(a, b));
    let side = grid.width.min(grid.height);
    let (tile, k) = choose_tile(g, opts.tile, side).ok_or_else(|| {
        // A grid too small for the tile side at any k is refused for it, whatever its tiles' starts: it
        // had said they start every 0 samples (one cell), or every 32 samples, which no side divides
        // (16 x 2 does).
        let small = u64::from(opts.tile) << 3 >= u64::from(side);
        let why = match (small, g) {
            (true, 0) => format!(
                "its tiles make one cell of {} x {} samples, too small for parts of {}-sample tiles (a \
                 side of more than {} samples): a package set needs a coarser level above its parts",
                grid.width,
                grid.height,
                opts.tile,
                u64::from(opts.tile) << 3
            ),
            (true, _) => format!(
                "its grid of {} x {} samples is too small for parts of {}-sample tiles (a side of more \
                 than {} samples): a package set needs a coarser level above its parts",
                grid.width,
                grid.height,
                opts.tile,
                u64::from(opts.tile) << 3
            ),
            _ => format!(
                "its tiles start every {g} samples, which no tile side from {} to {} times 2^k (k from \
                 1 to {MAX_K}) divides: a package set needs cells a whole number of level-k tiles",
                TILE_RANGE.0, TILE_RANGE.1
            ),
        };
        Error::format(spec, format!("{why}; bake the mosaic into one package instead"))
    })?;
    let mut index = Index {
        format: INDEX_FORMAT,
        width: grid.width,
        height: grid.height,
        spacing: grid.spacing,
        origin: grid.origin,
        tile,
        part_levels: k + 1,
        quantum: 0.0,
        lattice: false,
        max_error: 0.0,
        codec: opts.codec.name().to_string(),
        columns,
        rows,
        top: String::new(),
        georef: crate::source::heights_georef(spec),
        parts: Vec::new(),
    };
    let cells: Vec<[u32; 4]> = (0..index.rows.len())
        .flat_map(|j| (0..index.columns.len()).map(move |i| (i, j)))
        .map(|(i, j)| {
            let (x0, y0, x1, y1) = index.cell(i, j);
            [x0, y0, x1, y1]
        })
        .collect();
    // Each cell's part must hold K + 1 levels: at least 2^K + 1 samples a side.
    if let Some(c) = cells
        .iter()
        .find(|c| c[2] - c[0] < 1 << k || c[3] - c[1] < 1 << k)
    {
        return Err(Error::format(
            spec,
            format!(
                "a cell of {} x {} samples is too small for parts of {} levels",
                c[2] - c[0] + 1,
                c[3] - c[1] + 1,
                k + 1
            ),
        ));
    }
    // The quantum and bound, by the tiles' sample types rather than any one cell's samples, so that they
    // do not depend on which tile a bake reads first: the metre lattice for whole-metre tiles at the
    // grid's spacing (a missing tile's fill height and a filled void rounded to it, within the bound),
    // else twice the bound, as one file's bake chooses for float data.
    let whole = crate::source::mosaic_integer_tiles(spec, load)?
        && load.height_offset.fract() == 0.0
        && load.fill_height.is_none_or(|f| f.fract() == 0.0);
    let max_error = opts
        .max_error
        .unwrap_or(if whole { 0.5 } else { FLOAT_MAX_ERROR });
    let (q, lattice) = if whole && 0.5 <= max_error * (1.0 + 1e-9) {
        (1.0, true)
    } else {
        (2.0 * max_error, false)
    };
    index.quantum = q;
    index.lattice = lattice;
    index.max_error = max_error;
    let part_opts = BakeOptions {
        max_error: Some(max_error),
        tile,
        part: k + 1,
        quantum: Some((q, lattice)),
        lod_tables: false,
        ..opts.clone()
    };
    for (n, c) in cells.iter().enumerate() {
        let sources = cell_sources(&tiles, *c, (grid.width - 1, grid.height - 1));
        // Refused here, before any cell is baked: without it the set could never be finished.
        let own = tiles.iter().any(|(p, r)| inside(r, *c) && sources.contains(p));
        if !own && load.fill_height.is_none() {
            return Err(Error::format(
                spec,
                format!(
                    "no tile covers cell {n} (grid columns {} to {}, rows {} to {}): a package set reads \
                     a missing tile's cell as the fill height, and none is given",
                    c[0], c[2], c[1], c[3]
                ),
            ));
        }
        let key = cell_key(&index, &part_opts, load, *c, &sources)?;
        index.parts.push(PartEntry {
            file: super::set::part_file((c[0], c[1]), &key),
            key,
            sources: sources.iter().map(|p| p.display().to_string()).collect(),
        });
    }
    Ok(SetPlan {
        spec: spec.to_path_buf(),
        dir: dir.to_path_buf(),
        load: load.clone(),
        opts: part_opts,
        index,
        cells,
    })
}

/// The tiles inside cell `c`: its last column and row are the next cell's first (unless `last`, the
/// grid's), and its first the last of a tile to the west or north that shares its edge, which the cell
/// does not read. A cell with no tile inside (a missing tile's) reads those that share its first column
/// or row: the mosaic's samples there are theirs, not the fill height.
fn cell_sources(tiles: &[(PathBuf, [u32; 4])], c: [u32; 4], last: (u32, u32)) -> Vec<PathBuf> {
    let ex = if c[2] == last.0 { c[2] } else { c[2] - 1 };
    let ey = if c[3] == last.1 { c[3] } else { c[3] - 1 };
    let own: Vec<PathBuf> = tiles
        .iter()
        .filter(|(_, r)| r[0] <= ex && r[2] > c[0] && r[1] <= ey && r[3] > c[1])
        .map(|(p, _)| p.clone())
        .collect();
    if !own.is_empty() {
        // Tiles coarser than the grid that abut rather than share their edges (Copernicus tiles of 2400
        // columns a degree beside ones of 3600) leave a seam short of the cell's last column or row,
        // which the mosaic reads as linear between their last sample and the next tile's first: the
        // cell reads the tiles east and south that hold those too.
        let reach = |a: usize| own_rects(tiles, &own).map(|r| r[a]).max().unwrap_or(0);
        let seam_x = c[2] != last.0 && reach(2) + 1 < c[2];
        let seam_y = c[3] != last.1 && reach(3) + 1 < c[3];
        if !seam_x && !seam_y {
            return own;
        }
        let next = tiles.iter().filter(|(p, r)| {
            !own.contains(p)
                && ((seam_x && r[0] == c[2]) || (seam_y && r[1] == c[3]))
                && r[0] <= c[2]
                && r[2] >= c[0]
                && r[1] <= c[3]
                && r[3] >= c[1]
        });
        let next: Vec<PathBuf> = next.map(|(p, _)| p.clone()).collect();
        return own.into_iter().chain(next).collect();
    }
    tiles
        .iter()
        .filter(|(_, r)| r[0] <= ex && r[2] >= c[0] && r[1] <= ey && r[3] >= c[1])
        .map(|(p, _)| p.clone())
        .collect()
}

/// The rectangles of the tiles `of`.
fn own_rects<'a>(
    tiles: &'a [(PathBuf, [u32; 4])],
    of: &'a [PathBuf],
) -> impl Iterator<Item = [u32; 4]> + 'a {
    tiles.iter().filter(|(p, _)| of.contains(p)).map(|(_, r)| *r)
}

/// Whether the tile rectangle `r` reaches past cell `c`'s first column and row (a tile of its own, not
/// one that only shares its west or north edge).
fn inside(r: &[u32; 4], c: [u32; 4]) -> bool {
    r[2] > c[0] && r[3] > c[1]
}

/// Each file's path, size and modification time into `h`.
fn stamp_sources(h: &mut Hash64, sources: &[PathBuf]) -> Result<()> {
    for s in sources {
        let meta = std::fs::metadata(s).map_err(|e| Error::io(s, "cannot read", e))?;
        // The file, however it is named (`tiles/x.hgt`, `tiles/./x.hgt`, relative from another folder):
        // the same tiles named another way keep their parts.
        let file = std::fs::canonicalize(s).unwrap_or_else(|_| s.clone());
        h.write_bytes(file.display().to_string().as_bytes());
        super::stamp(h, &meta);
    }
    Ok(())
}

/// The greatest common divisor.
fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The tile side and K for cells that start every `g` samples (0: one cell a side): the largest K up
/// to [`MAX_K`] for which an even side in [`TILE_RANGE`] divides g / 2^K, that side the nearest to
/// `asked`; K also leaves the top a level over the grid's `side`.
fn choose_tile(g: u32, asked: u32, side: u32) -> Option<(u32, u32)> {
    for k in (1..=MAX_K).rev() {
        if u64::from(asked) << (k + 2) >= u64::from(side) {
            continue;
        }
        if g == 0 {
            return Some((asked, k));
        }
        if !g.is_multiple_of(1 << k) {
            continue;
        }
        let m = g >> k;
        let best = (TILE_RANGE.0..=TILE_RANGE.1.min(m))
            .filter(|t| t % 2 == 0 && m.is_multiple_of(*t))
            .min_by_key(|t| t.abs_diff(asked));
        if let Some(t) = best {
            return Some((t, k));
        }
    }
    None
}

/// A part's key: the set's parameters, the cell, and each source's path, size and modification time.
/// Not the grid's size, which a part's bytes do not depend on: tiles added east keep the others' parts.
fn cell_key(
    index: &Index,
    opts: &BakeOptions,
    load: &LoadOptions,
    cell: [u32; 4],
    sources: &[PathBuf],
) -> Result<String> {
    let mut h = Hash64::new();
    h.write_bytes(
        format!(
            "set {INDEX_FORMAT} readers r{} spacing {} tile {} levels {} quantum {} {} bound {} codec {} \
             zstd {} fill {:?} cell {cell:?}",
            crate::source::READ_REVISION,
            index.spacing,
            opts.tile,
            opts.part,
            index.quantum,
            index.lattice,
            index.max_error,
            opts.codec.name(),
            opts.zstd_level,
            load.fill_height,
        )
        .as_bytes(),
    );
    stamp_sources(&mut h, sources)?;
    Ok(hex(h.finish()))
}

impl SetPlan {
    /// The part file of cell `n`.
    pub fn part_path(&self, n: usize) -> PathBuf {
        self.dir.join(&self.index.parts[n].file)
    }

    /// Whether cell `n`'s part is there (a bake writes it whole or not at all, under a name that holds
    /// its key). Opened, not only its first bytes read: a part cut short or with a damaged header (a
    /// disk full, a copy stopped) is baked again rather than failing every bake after by name. Matched
    /// to its cell as the set's reader matches it: another package under its name (a copy gone wrong)
    /// had stood, and the top was made from it past the level's end (a panic) or from the wrong
    /// samples, a set that every bake after kept and no reader opened.
    pub fn part_stands(&self, n: usize) -> bool {
        Package::open(&self.part_path(n))
            .is_ok_and(|p| self.index.fits_part(n, p.header(), self.opts.codec))
    }
}

/// Bakes cell `n` of the plan into its part (the tiles that reach the cell read alone), whether or not
/// one stands.
pub fn bake_cell(plan: &SetPlan, n: usize, progress: Progress<'_>) -> Result<BakeReport> {
    let cell = *plan.cells.get(n).ok_or_else(|| {
        Error::format(
            &plan.spec,
            format!(
                "no cell {n}: the set has {} cells (0 to {})",
                plan.cells.len(),
                plan.cells.len().saturating_sub(1)
            ),
        )
    })?;
    std::fs::create_dir_all(&plan.dir).map_err(|e| Error::io(&plan.dir, "cannot create", e))?;
    let sources: Vec<PathBuf> = plan.index.parts[n]
        .sources
        .iter()
        .map(PathBuf::from)
        .collect();
    let hm = crate::source::mosaic_window(&plan.spec, &plan.load, cell, Some(&sources))?;
    bake(&hm, &plan.part_path(n), &plan.opts, progress)
}

/// Bakes the cells `todo`: one alone on every core, several a cell a core (each thread taking the next
/// cell as it comes free; a part's bytes do not depend on its threads). Returns the error of the first
/// failing cell in `todo`'s order.
fn bake_cells(plan: &SetPlan, todo: &[usize], progress: Progress<'_>) -> Result<()> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let workers = super::threads().min(todo.len());
    if workers <= 1 {
        for &n in todo {
            bake_cell(plan, n, progress)?;
        }
        return Ok(());
    }
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let failed = std::sync::Mutex::new(None::<(usize, Error)>);
    let mut meter = progress.task("baking the package set: cells", todo.len() as u64);
    std::thread::scope(|s| {
        let work = || loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let stop = failed
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .is_some();
            if i >= todo.len() || stop {
                break;
            }
            match super::one_thread(|| bake_cell(plan, todo[i], Progress::default())) {
                Ok(_) => {
                    done.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => {
                    let mut f = failed
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner);
                    if f.as_ref().is_none_or(|(j, _)| i < *j) {
                        *f = Some((i, e));
                    }
                }
            }
        };
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                std::thread::Builder::new()
                    .name("clipsat-set-cell".into())
                    .spawn_scoped(s, work)
            })
            .collect();
        let mut seen = 0;
        while handles
            .iter()
            .any(|h| h.as_ref().is_ok_and(|h| !h.is_finished()))
        {
            let d = done.load(Ordering::Relaxed);
            if d > seen {
                meter.inc((d - seen) as u64);
                seen = d;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        for h in handles {
            match h {
                Ok(h) => {
                    if h.join().is_err() {
                        panic!("a package set's cell thread panicked");
                    }
                }
                // No thread to run on: this one bakes what is left.
                Err(_) => work(),
            }
        }
    });
    match failed
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
    {
        Some((_, e)) => Err(e),
        None => {
            meter.finish();
            Ok(())
        }
    }
}

/// Bakes the top from the parts' level K, writes the index and removes the parts and tops of the folder
/// that the index does not name. Every part must stand. Returns the set's bytes and the files removed.
pub fn finish(plan: &mut SetPlan, progress: Progress<'_>) -> Result<(u64, usize)> {
    // A killed bake's temporaries, whether or not this one bakes anything.
    crate::temp::sweep(&plan.dir);
    let idx = &plan.index;
    let k = idx.part_levels as usize - 1;
    let missing: Vec<usize> = (0..plan.cells.len())
        .filter(|&n| !plan.part_stands(n))
        .collect();
    if let Some(&n) = missing.first() {
        return Err(Error::format(
            plan.part_path(n),
            format!(
                "{} of {} parts are not baked (the first: cell {n}); bake them first",
                missing.len(),
                plan.cells.len()
            ),
        ));
    }
    // Level K of the whole grid, each sample the part's whose cell it starts (the last column and row
    // the last cell's).
    let level = super::format::level_sizes(idx.width, idx.height)[k];
    let (w, h) = (level.0 as usize, level.1 as usize);
    let (nc, nr) = (idx.columns.len(), idx.rows.len());
    // The top's key: its parts' keys, so that it stands while they do.
    let mut top_key = Hash64::new();
    for p in &idx.parts {
        top_key.write_bytes(p.key.as_bytes());
    }
    let top_file = format!("top-{}.clipsat", hex(top_key.finish()));
    let top_path = plan.dir.join(&top_file);
    if !super::is_package(&top_path) {
        let mut heights = vec![0f32; w * h];
        for (n, cell) in plan.cells.iter().enumerate() {
            let (i, j) = (n % nc, n / nc);
            let part = Package::open(&plan.part_path(n))?;
            let units = part.decode_level(k)?;
            let d = part.header().levels[k];
            let (pw, ph) = (d.width as usize, d.height as usize);
            // A cell's last column and row are the next cell's first.
            let own_w = if i + 1 < nc { pw - 1 } else { pw };
            let own_h = if j + 1 < nr { ph - 1 } else { ph };
            let (x0, y0) = ((cell[0] >> k) as usize, (cell[1] >> k) as usize);
            // Checked when it stood (`part_stands`); a part changed since is refused, not read past.
            if x0 + own_w > w || y0 + own_h > h || units.len() < pw * ph {
                return Err(Error::format(
                    part.path(),
                    format!("not cell {n}'s part: its level {k} is {pw} x {ph} samples; bake it again"),
                ));
            }
            for y in 0..own_h {
                for x in 0..own_w {
                    heights[(y0 + y) * w + x0 + x] = part.metres(units[y * pw + x]);
                }
            }
        }
        // Level K + 1, the top's level 0, filtered from level K as one package's pyramid is.
        let (tw, th, heights) = crate::bake::pyramid::coarser(level.0, level.1, heights);
        let top_opts = BakeOptions {
            part: 0,
            quantum: Some((idx.quantum, false)),
            ..plan.opts.clone()
        };
        let scale = f64::from(2u32 << k);
        #[expect(clippy::cast_possible_truncation, reason = "a spacing in metres")]
        let spacing = (f64::from(idx.spacing) * scale) as f32;
        let hm = Heightmap::new(&top_path, tw, th, spacing, heights)?
            .with_origin(idx.origin.0, idx.origin.1);
        bake(&hm, &top_path, &top_opts, progress)?;
    }
    plan.index.top = top_file;
    let text = plan.index.to_text()?;
    let index_path = plan.dir.join(INDEX_NAME);
    // Locked while written, renamed into place: a killed bake's leaves a `.part` the next sweeps.
    let mut tmp = crate::temp::TempFile::create(
        plan.dir.join(format!("{INDEX_NAME}.tmp{}", crate::temp_suffix())),
    )?;
    {
        use std::io::Write;
        tmp.file
            .write_all(text.as_bytes())
            .and_then(|()| tmp.file.sync_all())
            .map_err(|e| Error::io(&tmp.path, "cannot write", e))?;
    }
    tmp.persist(&index_path)?;
    // The parts and tops of earlier bakes that the index does not name.
    let named: Vec<&str> = plan
        .index
        .parts
        .iter()
        .map(|p| p.file.as_str())
        .chain(std::iter::once(plan.index.top.as_str()))
        .collect();
    let mut removed = 0;
    if let Ok(entries) = std::fs::read_dir(&plan.dir) {
        for e in entries.filter_map(std::result::Result::ok) {
            let name = e.file_name().to_string_lossy().to_string();
            let ours = (name.starts_with("part-") || name.starts_with("top-"))
                && name.ends_with(".clipsat");
            if ours && !named.contains(&name.as_str()) && std::fs::remove_file(e.path()).is_ok() {
                removed += 1;
            }
        }
    }
    let bytes = named
        .iter()
        .filter_map(|f| std::fs::metadata(plan.dir.join(f)).ok())
        .map(|m| m.len())
        .sum();
    Ok((bytes, removed))
}

/// Bakes the set of the tile mosaic `spec` into `dir`: every cell whose part does not stand (in the
/// order of the index), then [`finish`].
pub fn bake_set(
    spec: &Path,
    load: &LoadOptions,
    opts: &BakeOptions,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<SetReport> {
    bake_plan(plan(spec, load, opts, dir)?, progress)
}

/// [`bake_set`] of a plan made already.
pub fn bake_plan(mut plan: SetPlan, progress: Progress<'_>) -> Result<SetReport> {
    let todo: Vec<usize> = (0..plan.cells.len())
        .filter(|&n| !plan.part_stands(n))
        .collect();
    bake_cells(&plan, &todo, progress)?;
    let baked = todo.len();
    let (bytes, removed) = finish(&mut plan, progress)?;
    Ok(SetReport {
        cells: plan.cells.len(),
        baked,
        removed,
        bytes,
        tile: plan.index.tile,
        part_levels: plan.index.part_levels,
    })
}
