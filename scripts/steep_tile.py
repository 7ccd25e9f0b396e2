#!/usr/bin/env python3
"""A steep 1" SRTM tile for plan-time measurements (docs/plan-time.md, "A steep 1-arc-second tile"): a
16-bit grey PNG of heights (Big Tujunga's `srtm_bigtujunga30m_utm11_u16dm.png`, 30 m SRTM of the San
Gabriel Mountains, decimetres) mirrored about its edges until it fills 3601 x 3601 samples, written as an
SRTM `.hgt` (big-endian int16 metres, rounded), so every sample is real steep 30 m terrain and the mirror
lines add no seam. Name the output like an SRTM tile (`N34W119.hgt`) so that it reads as one.
Standard library only (`png_rows.py` beside it).
Usage: scripts/steep_tile.py IN_U16.png METRES_PER_UNIT OUT.hgt   (Big Tujunga's PNG: 0.1)"""
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from png_rows import read_rows  # noqa: E402

SIDE = 3601


def read_grey16(path):
    """The PNG's rows as lists of unsigned 16-bit values (16-bit grey, non-interlaced only)."""
    w, h, rows = read_rows(path, 16, 0, 2)
    return w, h, [list(struct.unpack(f">{w}H", r)) for r in rows]


def mirrored(n, m):
    """Indices 0..n-1 folded into 0..m-1 by reflection about the edges (m >= 2)."""
    period = 2 * (m - 1)
    return [i % period if i % period < m else period - i % period for i in range(n)]


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    src, scale, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
    w, h, rows = read_grey16(src)
    if w < 2 or h < 2:
        sys.exit(f"{src}: {w} x {h} samples, need at least 2 x 2")
    xs = mirrored(SIDE, w)
    cache = {}
    with open(out, "wb") as f:
        for y in mirrored(SIDE, h):
            if y not in cache:
                row = rows[y]
                cache[y] = struct.pack(f">{SIDE}h", *(round(row[x] * scale) for x in xs))
            f.write(cache[y])


if __name__ == "__main__":
    main()
