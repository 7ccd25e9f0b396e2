//! Stage 1, bake: read-only grids of baked numbers, held in memory or read through a memory-mapped cache
//! file (the SAT LOD tables of a large terrain are not kept resident).
//!
//! A [`Grid`] is a slice of plain numbers. Baked in this process it owns a `Vec`; read back from the LOD
//! cache ([`crate::bake`]) it borrows a range of the file's read-only map, so only the pages a query
//! touches are ever in memory. [`Mapping::trim`] hands the touched pages back to the kernel (they stay in
//! its page cache, outside the process's resident set): a caller that trims once per frame holds at most
//! one frame's worth of table pages, whatever the terrain's size. The answers are the same bytes either
//! way, so every bound and every frame hash is unchanged by where a grid lives.

use std::ops::Deref;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Slots of the table of pages counted since the last trim (direct-mapped by page number): a page seen
/// again is not counted again unless another page took its slot (then it is counted twice, which only
/// over-counts).
const SEEN: usize = 4096;

/// The unit the resident limit counts in: 64 KiB, aligned. A read fault on a file map makes resident not
/// one page but the aligned window around it whose pages the kernel's page cache holds (Linux's
/// fault-around, 64 KiB by default, which the random-access advice does not turn off): measured, a 16385^2
/// flight held 17-24 MB of table pages where 4 KiB units counted 7.8 MiB.
pub const PAGE_BYTES: u64 = 1 << PAGE_SHIFT;
const PAGE_SHIFT: u32 = 16;

/// A read-only memory map shared by the grids that borrow it, with an optional limit on the pages its
/// readers may hold resident ([`Mapping::limit_resident`]).
#[derive(Clone)]
pub struct Mapping(Arc<Shared>);

struct Shared {
    map: memmap2::Mmap,
    /// Most pages held between trims (0: no limit).
    limit: AtomicU64,
    /// Pages counted since the last trim: at least the distinct pages touched.
    charged: AtomicU64,
    /// The page numbers counted since the last trim, by page number modulo [`SEEN`] (`u64::MAX`: none).
    seen: Box<[AtomicU64]>,
    /// Trims forced by the limit (not counting the callers' own [`Mapping::trim`]s).
    forced: AtomicU64,
}

impl std::fmt::Debug for Mapping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Mapping({} bytes)", self.0.map.len())
    }
}

/// What a [`Mapping`]'s resident limit did (for reports).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ResidentStats {
    /// The limit, bytes (0: none).
    pub limit_bytes: u64,
    /// Trims the limit forced between the callers' own.
    pub forced_trims: u64,
}

impl Mapping {
    /// Maps `file` read-only.
    ///
    /// The caller must not let the file change while mapped: the cache writes a new file under a
    /// temporary name and renames it, so a mapped file is never rewritten in place.
    pub fn new(file: &std::fs::File) -> std::io::Result<Self> {
        // SAFETY: read-only and private; the cache replaces files by rename, never in place (see above),
        // and a file truncated underneath by another process is outside what any reader can defend against.
        let map = unsafe { memmap2::Mmap::map(file) }?;
        // Queries read a few scattered entries: no readahead of neighbouring pages, which would multiply
        // the pages a frame holds (fault-around still maps the cached pages of a 64 KiB window: PAGE_BYTES).
        // Advice only; ignored where unsupported.
        #[cfg(unix)]
        let _ = map.advise(memmap2::Advice::Random);
        Ok(Self(Arc::new(Shared {
            map,
            limit: AtomicU64::new(0),
            charged: AtomicU64::new(0),
            seen: (0..SEEN).map(|_| AtomicU64::new(u64::MAX)).collect(),
            forced: AtomicU64::new(0),
        })))
    }

    /// The mapped bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.0.map
    }

    /// Holds at most `bytes` of this map's pages resident (rounded down to whole pages, at least one; a
    /// new map has no limit): the readers [`Mapping::touch`] each value before reading it, which counts
    /// the distinct pages read since the last trim, and once they would pass the limit the map is trimmed
    /// first. A budget carved from `budget.cpu_memory_bytes` ([`crate::profile::CpuSplit::lod_tables`]).
    pub fn limit_resident(&self, bytes: u64) {
        self.0
            .limit
            .store((bytes / PAGE_BYTES).max(1), Ordering::Relaxed);
    }

    /// The limit and what it did.
    pub fn resident_stats(&self) -> ResidentStats {
        ResidentStats {
            limit_bytes: self.0.limit.load(Ordering::Relaxed) * PAGE_BYTES,
            forced_trims: self.0.forced.load(Ordering::Relaxed),
        }
    }

    /// Counts the page of byte `offset` against the limit before a reader reads it (once per page between
    /// trims), trimming every page first when it would pass the limit: the pages held never exceed it.
    #[inline]
    pub fn touch(&self, offset: usize) {
        let limit = self.0.limit.load(Ordering::Relaxed);
        if limit == 0 {
            return;
        }
        let page = offset >> PAGE_SHIFT;
        let slot = &self.0.seen[page % SEEN];
        let page = page as u64;
        if slot.load(Ordering::Relaxed) == page {
            return;
        }
        if self.0.charged.fetch_add(1, Ordering::Relaxed) + 1 > limit {
            self.trim();
            self.0.charged.store(1, Ordering::Relaxed);
            self.0.forced.fetch_add(1, Ordering::Relaxed);
        }
        slot.store(page, Ordering::Relaxed);
    }

    /// Faults in the pages of `offset .. offset + len` now (clamped to the map), each 64 KiB window
    /// charged against the resident limit as a reader's would be: load-time work that a frame would
    /// otherwise do in its first queries. Nothing is read, and false returned, when the windows would
    /// bring the pages charged since the last trim past `allowance` windows (or past the limit).
    pub fn prime(&self, offset: usize, len: usize, allowance: u64) -> bool {
        let end = offset.saturating_add(len).min(self.0.map.len());
        if end <= offset {
            return true;
        }
        let (first, last) = (offset >> PAGE_SHIFT, (end - 1) >> PAGE_SHIFT);
        let windows = (last - first + 1) as u64;
        let limit = self.0.limit.load(Ordering::Relaxed);
        let charged = self.0.charged.load(Ordering::Relaxed);
        let cap = if limit == 0 { allowance } else { allowance.min(limit) };
        if charged.saturating_add(windows) > cap {
            return false;
        }
        let bytes = &self.0.map[..];
        let mut x = 0u8;
        for w in first..=last {
            self.touch(w << PAGE_SHIFT);
            // A read in every 4 KiB page of the window: fault-around maps only the pages already in the
            // page cache, so each page is read once to have all of them mapped.
            let (a, b) = (w << PAGE_SHIFT, ((w + 1) << PAGE_SHIFT).min(bytes.len()));
            for at in (a..b).step_by(4096) {
                x ^= bytes[at];
            }
        }
        std::hint::black_box(x);
        true
    }

    /// Drops the pages of `offset .. offset + len` from this process's resident set (the next read faults
    /// them back in from the kernel's page cache; the contents are unchanged). Best effort: a platform
    /// without the advice keeps the pages.
    pub fn trim_range(&self, offset: usize, len: usize) {
        drop_resident(&self.0.map, offset, len);
    }

    /// Drops every page of the map from the resident set ([`Mapping::trim_range`]); the pages charged
    /// against the limit start again from 0.
    pub fn trim(&self) {
        self.trim_range(0, self.0.map.len());
        if self.0.limit.load(Ordering::Relaxed) != 0 {
            self.0.charged.store(0, Ordering::Relaxed);
            for s in self.0.seen.iter() {
                s.store(u64::MAX, Ordering::Relaxed);
            }
        }
    }
}

#[derive(Clone)]
enum Store<T> {
    Owned(Vec<T>),
    /// `len` values from byte `offset` of the map (aligned for `T`; checked when made).
    Mapped {
        map: Mapping,
        offset: usize,
        len: usize,
    },
}

/// A read-only slice of plain numbers, owned or borrowed from a [`Mapping`].
#[derive(Clone)]
pub struct Grid<T: bytemuck::Pod> {
    store: Store<T>,
}

impl<T: bytemuck::Pod> Grid<T> {
    /// A grid that owns its values.
    pub fn owned(values: Vec<T>) -> Self {
        Self {
            store: Store::Owned(values),
        }
    }

    /// `len` values of `T` stored little-endian at byte `offset` of `map`; None if the range is past the
    /// map or misaligned for `T` (then the caller reads the values into an owned grid instead), or on a
    /// big-endian target (the bytes are little-endian).
    pub fn mapped(map: &Mapping, offset: usize, len: usize) -> Option<Self> {
        if cfg!(target_endian = "big") {
            return None;
        }
        let end = len
            .checked_mul(std::mem::size_of::<T>())
            .and_then(|b| b.checked_add(offset))?;
        let bytes = map.bytes().get(offset..end)?;
        bytemuck::try_cast_slice::<u8, T>(bytes).ok()?;
        Some(Self {
            store: Store::Mapped {
                map: map.clone(),
                offset,
                len,
            },
        })
    }

    /// Counts the page of value `index` against the map's resident limit before it is read
    /// ([`Mapping::touch`]); free for an owned grid.
    #[inline]
    pub fn touch(&self, index: usize) {
        if let Store::Mapped { map, offset, .. } = &self.store {
            map.touch(offset + index * std::mem::size_of::<T>());
        }
    }

    /// Calls `f` on the values `index .. index + len` in runs that each lie in one 64 KiB window of the
    /// map, each window counted ([`Mapping::touch`]) just before its run is read, as [`Grid::touch`] of
    /// every value would (one run for an owned grid).
    pub fn for_each_run(&self, index: usize, len: usize, mut f: impl FnMut(&[T])) {
        let values = &self[index..index + len];
        let Store::Mapped { map, offset, .. } = &self.store else {
            f(values);
            return;
        };
        let size = std::mem::size_of::<T>();
        let mut at = 0;
        while at < len {
            let byte = offset + (index + at) * size;
            map.touch(byte);
            let window_end = ((byte >> PAGE_SHIFT) + 1) << PAGE_SHIFT;
            let n = ((window_end - byte).div_ceil(size)).min(len - at);
            f(&values[at..at + n]);
            at += n;
        }
    }

    /// The byte range (offset, length) of the map the values live in (None for an owned grid).
    pub fn mapped_range(&self) -> Option<(usize, usize)> {
        match &self.store {
            Store::Mapped { offset, len, .. } => Some((*offset, *len * std::mem::size_of::<T>())),
            Store::Owned(_) => None,
        }
    }

    /// Whether the values live in a map rather than in memory this grid owns.
    pub fn is_mapped(&self) -> bool {
        matches!(self.store, Store::Mapped { .. })
    }

    /// Bytes this grid holds in owned memory (0 when mapped: its pages are the kernel's, faulted in on
    /// use and trimmed by the map's owner).
    pub fn owned_bytes(&self) -> u64 {
        match &self.store {
            Store::Owned(v) => (v.len() * std::mem::size_of::<T>()) as u64,
            Store::Mapped { .. } => 0,
        }
    }
}

impl<T: bytemuck::Pod> Deref for Grid<T> {
    type Target = [T];

    #[inline]
    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Owned(v) => v,
            Store::Mapped { map, offset, len } => bytemuck::cast_slice(
                &map.bytes()[*offset..*offset + *len * std::mem::size_of::<T>()],
            ),
        }
    }
}

impl<T: bytemuck::Pod + PartialEq> PartialEq for Grid<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl<T: bytemuck::Pod + Eq> Eq for Grid<T> {}

impl<T: bytemuck::Pod> std::fmt::Debug for Grid<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = if self.is_mapped() { "mapped" } else { "owned" };
        write!(f, "Grid({} values, {kind})", self.len())
    }
}

/// Drops the pages a read of bytes `offset .. offset + len` made resident: the aligned windows of
/// [`PAGE_BYTES`] around them, since a read fault maps the cached pages of its whole window, other tiles'
/// bytes included, which nothing would drop otherwise. Shared by the packages' tile reads.
pub(crate) fn drop_read(map: &memmap2::Mmap, offset: usize, len: usize) {
    let w = usize::try_from(PAGE_BYTES).unwrap_or(usize::MAX);
    let start = offset - offset % w;
    let end = offset.saturating_add(len).saturating_add(w - 1) / w * w;
    drop_resident(map, start, end - start);
}

/// Drops the pages of `offset .. offset + len` (clamped to the map) from this process's resident set; the
/// next read faults them back in from the kernel's page cache, unchanged. Best effort: a platform without
/// the advice keeps the pages. Shared by the LOD tables' map and the package's.
pub(crate) fn drop_resident(map: &memmap2::Mmap, offset: usize, len: usize) {
    #[cfg(unix)]
    {
        let end = offset.saturating_add(len).min(map.len());
        if end > offset {
            // SAFETY: MADV_DONTNEED on a read-only, file-backed private map only discards clean pages,
            // which are re-read from the file: no byte a slice of the map shows can change.
            let _ = unsafe {
                map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, offset, end - offset)
            };
        }
    }
    #[cfg(not(unix))]
    let _ = (map, offset, len);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapped_grid_reads_the_file_and_refuses_bad_ranges() {
        let dir = std::env::temp_dir().join(format!("clipsat-mapped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("grid.bin");
        let values: Vec<u64> = (0..100).map(|i| i * 7 + 1).collect();
        let mut bytes = vec![0u8; 8];
        bytes.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        std::fs::write(&path, &bytes).unwrap();
        let map = Mapping::new(&std::fs::File::open(&path).unwrap()).unwrap();
        let g = Grid::<u64>::mapped(&map, 8, 100).unwrap();
        assert!(g.is_mapped());
        assert_eq!(&*g, &values[..]);
        assert_eq!(g, Grid::owned(values.clone()));
        assert_eq!(g.owned_bytes(), 0);
        map.trim();
        assert_eq!(&*g, &values[..], "trimming never changes the bytes");
        // The resident limit: distinct pages past it trim (and count), the bytes never change.
        map.limit_resident(2 * PAGE_BYTES);
        assert_eq!(map.resident_stats().limit_bytes, 2 * PAGE_BYTES);
        let per_page = (PAGE_BYTES / 8) as usize;
        g.touch(0);
        g.touch(1);
        g.touch(0);
        assert_eq!(map.resident_stats().forced_trims, 0, "one page so far");
        // Values 0 .. 100 span the map's first page (the grid starts at byte 8): a second page needs a
        // longer map, so count pages of a bigger grid.
        let big: Vec<u64> = (0..4 * per_page as u64).collect();
        let mut bytes = vec![0u8; 8];
        bytes.extend(big.iter().flat_map(|v| v.to_le_bytes()));
        let path2 = dir.join("grid2.bin");
        std::fs::write(&path2, &bytes).unwrap();
        let map2 = Mapping::new(&std::fs::File::open(&path2).unwrap()).unwrap();
        let g2 = Grid::<u64>::mapped(&map2, 8, big.len()).unwrap();
        map2.limit_resident(2 * PAGE_BYTES);
        g2.touch(0);
        g2.touch(per_page);
        g2.touch(per_page + 1);
        assert_eq!(map2.resident_stats().forced_trims, 0, "two pages");
        g2.touch(3 * per_page);
        assert_eq!(
            map2.resident_stats().forced_trims,
            1,
            "a third page trims first"
        );
        map2.trim();
        g2.touch(0);
        g2.touch(2 * per_page);
        assert_eq!(
            map2.resident_stats().forced_trims,
            1,
            "a trim starts the count again"
        );
        assert_eq!(&*g2, &big[..]);
        // Runs: every value once, in order, each run in one window, each window counted as touched.
        map2.trim();
        let mut seen = Vec::new();
        g2.for_each_run(per_page - 3, per_page + 5, |run| {
            assert!(run.len() <= per_page);
            seen.extend_from_slice(run);
        });
        assert_eq!(seen, &big[per_page - 3..2 * per_page + 2]);
        assert_eq!(
            map2.resident_stats().forced_trims,
            2,
            "the runs' three windows pass the limit of two: one trim"
        );
        drop(g2);
        assert_eq!(&*g, &values[..]);
        Grid::owned(values.clone()).touch(7);
        assert!(Grid::<u64>::mapped(&map, 4, 10).is_none(), "misaligned");
        assert!(Grid::<u64>::mapped(&map, 8, 101).is_none(), "past the end");
        drop(g);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn priming_charges_its_windows_and_stops_at_the_allowance() {
        let dir = std::env::temp_dir().join(format!("clipsat-prime-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("grid.bin");
        let per_page = (PAGE_BYTES / 8) as usize;
        let big: Vec<u64> = (0..4 * per_page as u64).collect();
        let bytes: Vec<u8> = big.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(&path, &bytes).unwrap();
        let map = Mapping::new(&std::fs::File::open(&path).unwrap()).unwrap();
        let g = Grid::<u64>::mapped(&map, 0, big.len()).unwrap();
        let (offset, len) = g.mapped_range().unwrap();
        assert_eq!((offset, len), (0, bytes.len()));
        assert!(Grid::owned(vec![1u64]).mapped_range().is_none());
        map.limit_resident(3 * PAGE_BYTES);
        // Four windows do not fit an allowance of two, nor the limit of three: nothing is charged.
        assert!(!map.prime(0, len, 2));
        assert!(!map.prime(0, len, 10));
        assert!(map.prime(0, len / 2, 2), "the first two windows");
        // The two windows are charged: a third fits the limit, a fourth trims first.
        g.touch(2 * per_page);
        assert_eq!(map.resident_stats().forced_trims, 0);
        g.touch(3 * per_page);
        assert_eq!(map.resident_stats().forced_trims, 1);
        assert!(map.prime(len, 8, 1), "an empty range primes nothing");
        assert_eq!(&*g, &big[..], "priming never changes the bytes");
        drop(g);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
