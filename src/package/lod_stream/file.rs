//! Stage 1, bake: the LOD cache file ([`crate::bake`], format 5) as the out-of-core bakes write it: its
//! layout once every level's E is known, the header and flags, the finest max-pyramid level's columns
//! (transposed from its rows once they are written) and the CRC-32 trailer.

use std::fs::File;
use std::path::Path;

use super::Level;
use crate::bake::sat::Sat;
use crate::bake::{FORMAT_VERSION, MAGIC};
use crate::{Error, Result};

/// Bytes read at a time for the trailing checksum.
const CRC_CHUNK: usize = 4 << 20;

/// Bytes of the finest max-pyramid level's rows read at a time to write its columns (at least 8 rows).
const COLUMN_BLOCK: usize = 2 << 20;

/// Where one level's finest max-pyramid level lies by rows and by columns, and its size in cells.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Columns {
    rows_at: u64,
    columns_at: u64,
    width: u32,
    height: u32,
}

/// The cache file's layout: the header, each level's E and has-tables flag as bytes at their offsets,
/// the body's length, and each level's columns to write.
pub(crate) struct FileLayout {
    head: Vec<u8>,
    flags: Vec<(u64, Vec<u8>)>,
    body: u64,
    columns: Vec<Columns>,
}

/// The cache file's layout once every level's E (so its has-tables flag) is known; each level with
/// tables is laid out.
pub(crate) fn lay_out_file(
    levels: &mut [Level],
    p: u32,
    width: u32,
    height: u32,
    key: u64,
) -> FileLayout {
    let n = u32::try_from(levels.len() + 1).expect("levels fit u32");
    let mut head = Vec::new();
    head.extend_from_slice(MAGIC);
    head.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    head.extend_from_slice(&key.to_le_bytes());
    let frac = Sat::max_frac_bits(u64::from(width) * u64::from(height));
    for w in [p, width, height, n, frac] {
        head.extend_from_slice(&w.to_le_bytes());
    }
    // Data level 0 has no error.
    head.extend_from_slice(&0f32.to_le_bytes());
    head.extend_from_slice(&0u32.to_le_bytes());
    let mut at = head.len() as u64;
    let mut flags = Vec::new();
    let mut columns = Vec::new();
    for lv in levels.iter_mut() {
        let mut b = lv.e_max.to_le_bytes().to_vec();
        b.extend_from_slice(&u32::from(lv.has_tables()).to_le_bytes());
        flags.push((at, b));
        at += 8;
        if lv.has_tables() {
            at = lv.lay_out(width, height, at);
        }
    }
    // The columns after every level, so the levels lie where format 4 put them.
    for lv in levels.iter().filter(|l| l.has_tables()) {
        columns.push(Columns {
            rows_at: lv.max_off[0],
            columns_at: at,
            width: lv.cw,
            height: lv.ch,
        });
        at += u64::from(lv.cw) * u64::from(lv.ch) * 4;
    }
    FileLayout {
        head,
        flags,
        body: at.next_multiple_of(8),
        columns,
    }
}

/// Creates `tmp` of `layout`'s length and 8 bytes more (zeros: every padding), writes the header and the
/// levels' flags, runs `tables`, writes each level's columns from its rows, then the CRC-32 of the body
/// read back in chunks.
pub(crate) fn write_tables(
    tmp: &Path,
    layout: &FileLayout,
    tables: impl FnOnce(&File) -> Result<()>,
) -> Result<()> {
    use std::io::{Read, Seek};
    if let Some(dir) = tmp.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create folder", e))?;
    }
    let io = |e| Error::io(tmp, "cannot write", e);
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(tmp)
        .map_err(io)?;
    file.set_len(layout.body + 8).map_err(io)?;
    write_at(&file, 0, &layout.head).map_err(io)?;
    for (at, b) in &layout.flags {
        write_at(&file, *at, b).map_err(io)?;
    }
    tables(&file)?;
    for c in &layout.columns {
        write_columns(&file, c).map_err(io)?;
    }
    // From the start: Windows' positioned reads and writes move the file's cursor.
    (&file).seek(std::io::SeekFrom::Start(0)).map_err(io)?;
    let mut crc = crc32fast::Hasher::new();
    let mut buf = vec![0u8; CRC_CHUNK];
    let mut reader = std::io::BufReader::new(&file).take(layout.body);
    loop {
        let got = reader.read(&mut buf).map_err(io)?;
        if got == 0 {
            break;
        }
        crc.update(&buf[..got]);
    }
    write_at(&file, layout.body, &u64::from(crc.finalize()).to_le_bytes()).map_err(io)
}

/// Writes `c`'s columns (value (x, y) at x h + y) from its rows, already in the file: a block of rows
/// read at a time, then each column's run of that block written where it lies. O(width) writes per
/// block and about [`COLUMN_BLOCK`] bytes held twice, whatever the terrain's height.
fn write_columns(file: &File, c: &Columns) -> std::io::Result<()> {
    let (w, h) = (c.width as usize, c.height as usize);
    let rows = (COLUMN_BLOCK / (4 * w.max(1))).clamp(8, h.max(8));
    let mut block = vec![0u8; rows * w * 4];
    let mut run = Vec::with_capacity(rows * 4);
    for y0 in (0..h).step_by(rows) {
        let n = rows.min(h - y0);
        let bytes = &mut block[..n * w * 4];
        read_at(file, c.rows_at + (y0 * w * 4) as u64, bytes)?;
        for x in 0..w {
            run.clear();
            for y in 0..n {
                run.extend_from_slice(&bytes[(y * w + x) * 4..][..4]);
            }
            write_at(file, c.columns_at + ((x * h + y0) * 4) as u64, &run)?;
        }
    }
    Ok(())
}

/// Fills `bytes` from byte `offset` of `file` (positioned).
fn read_at(file: &File, offset: u64, bytes: &mut [u8]) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, bytes, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0usize;
        while done < bytes.len() {
            let n = std::os::windows::fs::FileExt::seek_read(
                file,
                &mut bytes[done..],
                offset + done as u64,
            )?;
            if n == 0 {
                return Err(std::io::ErrorKind::UnexpectedEof.into());
            }
            done += n;
        }
        Ok(())
    }
}

/// Writes `bytes` at byte `offset` of `file` (positioned: the levels' rows land in any order).
pub(super) fn write_at(file: &File, offset: u64, bytes: &[u8]) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::write_all_at(file, bytes, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0usize;
        while done < bytes.len() {
            let n = std::os::windows::fs::FileExt::seek_write(
                file,
                &bytes[done..],
                offset + done as u64,
            )?;
            if n == 0 {
                return Err(std::io::ErrorKind::WriteZero.into());
            }
            done += n;
        }
        Ok(())
    }
}
