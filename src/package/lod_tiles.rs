//! Stage 1b, the package: the SAT LOD records' tiles.
//!
//! Data level k's records ([`crate::bake::lod_record`]: a max code per closed cell, a mean code per
//! half-open cell, at level k's resolution) are cut into tiles of `tile x tile` cells, the grid of the
//! half-open cells (which has the closed cells' grid inside it, plus at most one more row and column).
//! A tile's payload is two streams of the package codec ([`Encoder`], one i32 per code, each byte offset
//! by -128 so it zigzags into one byte plane): the tile's max codes row-major, then its mean codes, the
//! first stream's length before them (u32, little-endian). The codes go as they are: differences from a
//! neighbour measured 4-9 % larger ([`crate::bake::lod_record`]).
//!
//! Two streams, not one, because the two codes follow different distributions and zstd codes a block's
//! literals with one Huffman table: one stream cost 15-17 % more (record tiles of levels 2 and up, at
//! `--max-error 0.5`, B/sample: Big Tujunga 0.117 against 0.100, n07 0.109 against 0.093, Puget Sound
//! 1k 0.125 against 0.109; every level: 0.439 against 0.374 on Big Tujunga). Tiles of 128 cells would
//! save 1 % more, 256 cells 1-7 % (one stream) and nothing (two).

use std::fs::File;

use super::planes::{Decoder, Encoder};

/// One record level's cell grids and tile grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordGrid {
    /// The data level.
    pub k: u32,
    /// Closed cells per row (max codes).
    pub cw: u32,
    /// Closed cell rows.
    pub ch: u32,
    /// Half-open cells per row (mean codes).
    pub sw: u32,
    /// Half-open cell rows.
    pub sh: u32,
    /// Cells per tile side.
    pub tile: u32,
    /// Tiles per row.
    pub tiles_x: u32,
    /// Tile rows.
    pub tiles_y: u32,
}

impl RecordGrid {
    /// Data level `k`'s grid over a `width x height` terrain, `tile` cells a tile side.
    pub fn new(width: u32, height: u32, k: u32, tile: u32) -> Self {
        let s = k.min(30);
        let closed = |len: u32| (len - 1).div_ceil(1 << s).max(1);
        let (sw, sh) = (width.div_ceil(1 << s), height.div_ceil(1 << s));
        Self {
            k,
            cw: closed(width),
            ch: closed(height),
            sw,
            sh,
            tile,
            tiles_x: sw.div_ceil(tile),
            tiles_y: sh.div_ceil(tile),
        }
    }

    /// Tiles in the level.
    pub fn tiles(&self) -> usize {
        self.tiles_x as usize * self.tiles_y as usize
    }

    /// The closed cells (x0, y0, w, h) of tile (tx, ty); empty where the tile is past them.
    pub fn max_rect(&self, tx: u32, ty: u32) -> (u32, u32, u32, u32) {
        rect(self.cw, self.ch, self.tile, tx, ty)
    }

    /// The half-open cells (x0, y0, w, h) of tile (tx, ty).
    pub fn mean_rect(&self, tx: u32, ty: u32) -> (u32, u32, u32, u32) {
        rect(self.sw, self.sh, self.tile, tx, ty)
    }
}

fn rect(w: u32, h: u32, tile: u32, tx: u32, ty: u32) -> (u32, u32, u32, u32) {
    let (x0, y0) = (tx * tile, ty * tile);
    (
        x0,
        y0,
        w.saturating_sub(x0).min(tile),
        h.saturating_sub(y0).min(tile),
    )
}

/// A tile's payload from its max codes and mean codes, row-major.
pub fn encode_tile(
    enc: &mut Encoder,
    max: &[u8],
    mean: &[u8],
    scratch: &mut Vec<i32>,
) -> std::io::Result<Vec<u8>> {
    let mut stream = |codes: &[u8]| {
        scratch.clear();
        scratch.extend(codes.iter().map(|&c| i32::from(c) - 128));
        enc.encode(scratch)
    };
    let first = stream(max)?;
    let second = stream(mean)?;
    let len = u32::try_from(first.len()).map_err(std::io::Error::other)?;
    let mut out = Vec::with_capacity(4 + first.len() + second.len());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&first);
    out.extend_from_slice(&second);
    Ok(out)
}

/// Decodes a payload into the tile's max codes and mean codes; the reason on failure (a payload that
/// does not decode to exactly the tile's cells, or a value outside a byte).
pub fn decode_tile(
    dec: &mut Decoder,
    payload: &[u8],
    max: &mut [u8],
    mean: &mut [u8],
    scratch: &mut Vec<i32>,
) -> Result<(), &'static str> {
    let (len, rest) = payload
        .split_first_chunk::<4>()
        .ok_or("record tile shorter than its stream length")?;
    let len = usize::try_from(u32::from_le_bytes(*len)).map_err(|_| "stream length too large")?;
    if len > rest.len() {
        return Err("record tile's first stream runs past its end");
    }
    let (first, second) = rest.split_at(len);
    for (stream, codes) in [(first, max), (second, mean)] {
        scratch.clear();
        scratch.resize(codes.len(), 0);
        dec.decode(stream, scratch)?;
        for (c, &v) in codes.iter_mut().zip(scratch.iter()) {
            *c = u8::try_from(v + 128).map_err(|_| "a code outside a byte")?;
        }
    }
    Ok(())
}

/// A level's records gathered a tile row of cells at a time, coded into record tiles
/// ([`crate::package::lod_tiles`]) and appended to a spool file; the tiles' lengths and CRC-32s kept.
pub(crate) struct RecordRows {
    grid: RecordGrid,
    /// The current tile row's max code rows (closed cells per row each) and mean code rows.
    max: Vec<u8>,
    mean: Vec<u8>,
    enc: Encoder,
    scratch: Vec<i32>,
    tile_max: Vec<u8>,
    tile_mean: Vec<u8>,
    spool: std::io::BufWriter<File>,
    /// Per tile so far: (offset in the spool, length, CRC-32).
    pub(crate) entries: Vec<(u64, u32, u32)>,
    at: u64,
}

impl RecordRows {
    /// Records of `grid` coded with `enc`, spooled to `spool`.
    pub(crate) fn new(grid: RecordGrid, enc: Encoder, spool: File) -> Self {
        Self {
            grid,
            max: Vec::new(),
            mean: Vec::new(),
            enc,
            scratch: Vec::new(),
            tile_max: Vec::new(),
            tile_mean: Vec::new(),
            spool: std::io::BufWriter::new(spool),
            entries: Vec::with_capacity(grid.tiles()),
            at: 0,
        }
    }

    /// Closed row's codes, in order.
    pub(crate) fn push_max(&mut self, codes: &[u8]) {
        self.max.extend_from_slice(codes);
    }

    /// Half-open row `r`'s codes, in order (after the closed row that contains it); a finished tile row
    /// is coded and spooled.
    pub(crate) fn push_mean(&mut self, r: u32, codes: &[u8]) -> std::io::Result<()> {
        self.mean.extend_from_slice(codes);
        let g = self.grid;
        if (r + 1).is_multiple_of(g.tile) || r + 1 == g.sh {
            self.flush_tile_row(r / g.tile)?;
        }
        Ok(())
    }

    /// Codes tile row `ty` from the gathered rows.
    fn flush_tile_row(&mut self, ty: u32) -> std::io::Result<()> {
        let g = self.grid;
        for tx in 0..g.tiles_x {
            let (mx, _, mw, _) = g.max_rect(tx, ty);
            let (nx, _, nw, _) = g.mean_rect(tx, ty);
            self.tile_max.clear();
            for row in self.max.chunks(g.cw as usize) {
                self.tile_max
                    .extend_from_slice(&row[mx.min(g.cw) as usize..(mx + mw) as usize]);
            }
            self.tile_mean.clear();
            for row in self.mean.chunks(g.sw as usize) {
                self.tile_mean
                    .extend_from_slice(&row[nx as usize..(nx + nw) as usize]);
            }
            let payload = encode_tile(
                &mut self.enc,
                &self.tile_max,
                &self.tile_mean,
                &mut self.scratch,
            )?;
            std::io::Write::write_all(&mut self.spool, &payload)?;
            let len = u32::try_from(payload.len()).expect("a record tile is under 4 GiB");
            self.entries.push((self.at, len, crc32fast::hash(&payload)));
            self.at += u64::from(len);
        }
        self.max.clear();
        self.mean.clear();
        Ok(())
    }

    /// A level without error: every code 0, each tile row coded as such.
    pub(crate) fn zeros(&mut self) -> std::io::Result<()> {
        let g = self.grid;
        for ty in 0..g.tiles_y {
            let (_, my, _, mh) = g.max_rect(0, ty);
            let (_, _, _, nh) = g.mean_rect(0, ty);
            self.max = vec![0; (g.cw * mh.min(g.ch.saturating_sub(my))) as usize];
            self.mean = vec![0; (g.sw * nh) as usize];
            self.flush_tile_row(ty)?;
        }
        Ok(())
    }

    /// Flushes the spool; the entries.
    pub(crate) fn finish(mut self) -> std::io::Result<Vec<(u64, u32, u32)>> {
        std::io::Write::flush(&mut self.spool)?;
        Ok(self.entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::package::CodecKind;

    #[test]
    fn record_tiles_round_trip() {
        let max: Vec<u8> = (0..60u8).map(|i| i.wrapping_mul(37)).collect();
        let mean: Vec<u8> = (0..64u8).map(|i| 255 - i.wrapping_mul(11)).collect();
        let mut enc = Encoder::new(CodecKind::Zstd, 3).unwrap();
        let mut scratch = Vec::new();
        let payload = encode_tile(&mut enc, &max, &mean, &mut scratch).unwrap();
        let mut dec = Decoder::new(CodecKind::Zstd, 4096).unwrap();
        let (mut m, mut n) = (vec![0u8; 60], vec![0u8; 64]);
        decode_tile(&mut dec, &payload, &mut m, &mut n, &mut scratch).unwrap();
        assert_eq!((&m, &n), (&max, &mean));
        // A tile past the closed cells (no max codes) round-trips too.
        let payload = encode_tile(&mut enc, &[], &mean, &mut scratch).unwrap();
        let mut n = vec![0u8; 64];
        decode_tile(&mut dec, &payload, &mut [], &mut n, &mut scratch).unwrap();
        assert_eq!(n, mean);
        // A damaged stream length or a cut payload is an error, never a panic.
        for cut in [0, 3, 4, payload.len() - 1] {
            assert!(decode_tile(&mut dec, &payload[..cut], &mut [], &mut n, &mut scratch).is_err());
        }
        let mut bad = payload.clone();
        bad[3] = 0xff;
        assert!(decode_tile(&mut dec, &bad, &mut [], &mut n, &mut scratch).is_err());
        let g = RecordGrid::new(1025, 1025, 1, 64);
        assert_eq!((g.cw, g.ch, g.sw, g.sh, g.tiles_x), (512, 512, 513, 513, 9));
        assert_eq!(g.max_rect(8, 0), (512, 0, 0, 64));
        assert_eq!(g.mean_rect(8, 8), (512, 512, 1, 1));
    }
}
