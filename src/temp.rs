//! Stage 1b, the bake's files: the temporary files a bake writes beside what it makes (the package, its
//! spilled levels and spools, the LOD tables' cache file), each held under an exclusive lock while its
//! writer lives, and the sweep that removes those whose writer is gone.
//!
//! A killed bake (`kill -9`, out of memory, a lost machine) cannot remove its temporaries. Each is named
//! `<name>.<tag><pid>-<n>.part` ([`crate::temp_suffix`]) and its writer holds an exclusive advisory lock on
//! it (`flock` on Unix) from its creation until it is renamed into place or removed; the system drops the
//! lock when the process ends, however it ends. A later run ([`sweep`], at the start of every bake and
//! every cached open) removes a `.part` file only while it holds that lock itself: proof that no writer
//! holds it. A live writer's file is never removed, whichever process or machine (over a file system
//! with locks) sweeps, and a pid reused by another process changes nothing. The sweep never reads a
//! temporary: only a file renamed into place is used, and that rename is the bake's last step.
//!
//! Off Unix, nothing is locked and nothing is swept (a byte-range lock there would also block the
//! writer's own other handles).

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The ending of every temporary file this module makes: the sweep looks at no other file.
const PART: &str = ".part";

/// Tries to give a new temporary name before giving up (another name is tried only when a sweep took
/// the file between its creation and its lock).
const TRIES: u32 = 8;

/// A temporary file, locked while it lives, removed when dropped unless [`TempFile::persist`]ed.
pub(crate) struct TempFile {
    pub(crate) file: File,
    pub(crate) path: PathBuf,
    /// Renamed into place: nothing to remove.
    kept: bool,
}

impl TempFile {
    /// Creates (truncating) and locks `<base>.part`, opened to read and write, and its folder if missing.
    /// `base` should end in [`crate::temp_suffix`] (`name.tmp<pid>-<n>`), so that no other writer uses it
    /// and [`sweep`] knows it.
    pub(crate) fn create(base: PathBuf) -> Result<Self> {
        if let Some(dir) = base.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
        }
        let mut base = base.into_os_string();
        base.push(PART);
        let path = PathBuf::from(base);
        let mut last = None;
        for i in 0..TRIES {
            // A later try: a sweep removed the last one before it was locked; the counter gives a new name.
            let path = if i == 0 {
                path.clone()
            } else {
                let mut p = path.clone().into_os_string();
                p.push(format!(".{}", crate::temp_suffix()));
                p.push(PART);
                PathBuf::from(p)
            };
            let file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(true)
                .open(&path)
                .map_err(|e| Error::io(&path, "cannot create a temporary file", e))?;
            if lock(&file, &path)? {
                return Ok(Self {
                    file,
                    path,
                    kept: false,
                });
            }
            last = Some(path);
        }
        Err(Error::io(
            last.unwrap_or(path),
            "cannot lock a temporary file",
            std::io::Error::from(std::io::ErrorKind::WouldBlock),
        ))
    }

    /// Renames the file to `to` (atomically, replacing it), the writer's last step.
    pub(crate) fn persist(mut self, to: &Path) -> Result<()> {
        std::fs::rename(&self.path, to)
            .map_err(|e| Error::io(to, "cannot rename into place", e))?;
        self.kept = true;
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.kept {
            // Best effort: drop cannot report, and a later sweep removes what is left.
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Locks `file`, just created at `path`, and checks that `path` is still it: false where a sweep took the
/// file between its creation and this lock (it held the lock, or removed the file first).
#[cfg(unix)]
fn lock(file: &File, path: &Path) -> Result<bool> {
    use std::os::unix::fs::MetadataExt;
    match try_lock(file) {
        Ok(true) => {}
        Ok(false) => return Ok(false),
        Err(e) => return Err(Error::io(path, "cannot lock a temporary file", e)),
    }
    let held = file
        .metadata()
        .map_err(|e| Error::io(path, "cannot read a temporary file's metadata", e))?;
    Ok(std::fs::metadata(path).is_ok_and(|m| m.dev() == held.dev() && m.ino() == held.ino()))
}

/// Takes an exclusive `flock` on `file` without waiting: false where another open file holds one (in
/// this process or another). The lock goes with the open file: closing it, or the process ending in any
/// way, releases it. (`File::try_lock` is stable from Rust 1.89, past this crate's rust-version.)
#[cfg(unix)]
fn try_lock(file: &File) -> std::io::Result<bool> {
    use std::os::fd::AsRawFd;
    extern "C" {
        fn flock(fd: i32, operation: i32) -> i32;
    }
    // The same values on Linux, the BSDs and macOS.
    const LOCK_EX: i32 = 2;
    const LOCK_NB: i32 = 4;
    // SAFETY: flock reads an open descriptor that `file` owns for the call's length, and no memory.
    let rc = unsafe { flock(file.as_raw_fd(), LOCK_EX | LOCK_NB) };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.kind() == std::io::ErrorKind::WouldBlock {
        Ok(false)
    } else {
        Err(e)
    }
}

#[cfg(not(unix))]
fn lock(_file: &File, _path: &Path) -> Result<bool> {
    Ok(true)
}

/// Whether `name` is one of this module's temporaries: `<anything>.<tag><pid>-<n>.part`.
fn is_temp(name: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    let Some(stem) = name.strip_suffix(PART) else {
        return false;
    };
    let Some((head, n)) = stem.rsplit_once('-') else {
        return false;
    };
    let pid_len = head.bytes().rev().take_while(u8::is_ascii_digit).count();
    let (rest, pid) = head.split_at(head.len() - pid_len);
    digits(n) && digits(pid) && rest.contains('.')
}

/// Removes the temporaries in `dir` that no live writer holds ([`TempFile`]); returns how many. Best
/// effort: a file it cannot open, lock or remove stays.
#[cfg(unix)]
pub(crate) fn sweep(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for e in entries.filter_map(std::result::Result::ok) {
        if !e.file_name().to_str().is_some_and(is_temp) || !e.file_type().is_ok_and(|t| t.is_file())
        {
            continue;
        }
        let path = e.path();
        let Ok(file) = File::open(&path) else {
            continue;
        };
        // Held: its writer lives. Taken: no process holds it, and none can take it while this one does
        // (a writer that created it but had not locked it yet finds it gone and takes another name).
        if try_lock(&file).is_ok_and(|held| held) && std::fs::remove_file(&path).is_ok() {
            removed += 1;
        }
    }
    removed
}

#[cfg(not(unix))]
pub(crate) fn sweep(_dir: &Path) -> usize {
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_known_and_others_are_not() {
        for t in [
            "terrain-ab-v5.tmp123-0.part",
            "terrain-ab-v5.level3.tmp99-12.part",
            "x.clipsat.records7-1.part",
            "lod-ab.tmp1-2.part.3-4.part",
        ] {
            assert!(is_temp(t), "{t}");
        }
        for t in [
            "terrain-ab-v5.clipsat",
            "terrain-ab-v5.tmp123-0",
            "movie.part",
            "a-1.part",
            "x.tmp-1.part",
            "x.tmp1-.part",
            "x.tmp1-a.part",
        ] {
            assert!(!is_temp(t), "{t}");
        }
    }

    /// A held temporary survives a sweep; one whose writer is gone (no lock) is removed; other files stay.
    #[cfg(unix)]
    #[test]
    fn a_sweep_removes_dead_temporaries_and_never_a_live_one() {
        let dir = std::env::temp_dir().join(format!("clipsat-sweep-{}", crate::temp_suffix()));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let live =
            TempFile::create(dir.join(format!("a.tmp{}", crate::temp_suffix()))).expect("create");
        let dead = dir.join("b.tmp4194305-0.part");
        let other = dir.join("c.clipsat");
        std::fs::write(&dead, b"partial").expect("write");
        std::fs::write(&other, b"kept").expect("write");
        assert_eq!(sweep(&dir), 1);
        assert!(live.path.exists() && !dead.exists() && other.exists());
        let kept = dir.join("a.clipsat");
        live.persist(&kept).expect("persist");
        let gone =
            TempFile::create(dir.join(format!("d.tmp{}", crate::temp_suffix()))).expect("create");
        let gone_path = gone.path.clone();
        drop(gone);
        assert!(kept.exists() && !gone_path.exists());
        assert_eq!(sweep(&dir), 0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
