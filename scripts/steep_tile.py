#!/usr/bin/env python3
"""A steep 1" SRTM tile for plan-time measurements (docs/plan-time.md, "A steep 1-arc-second tile"): a
16-bit grey PNG of heights (Big Tujunga's `srtm_bigtujunga30m_utm11_u16dm.png`, 30 m SRTM of the San
Gabriel Mountains, decimetres) mirrored about its edges until it fills 3601 x 3601 samples, written as an
SRTM `.hgt` (big-endian int16 metres, rounded), so every sample is real steep 30 m terrain and the mirror
lines add no seam. Name the output like an SRTM tile (`N34W119.hgt`) so that it reads as one.
Standard library only.
Usage: scripts/steep_tile.py IN_U16.png METRES_PER_UNIT OUT.hgt   (Big Tujunga's PNG: 0.1)"""
import struct
import sys
import zlib

SIDE = 3601


def chunks(data):
    at = 8
    while at < len(data):
        (n,) = struct.unpack(">I", data[at:at + 4])
        yield data[at + 4:at + 8], data[at + 8:at + 8 + n]
        at += 12 + n


def read_grey16(path):
    """The PNG's rows as lists of unsigned 16-bit values (16-bit grey, non-interlaced only)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    idat, w, h = b"", 0, 0
    for kind, body in chunks(data):
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (16, 0, 0):
                sys.exit(f"{path}: 16-bit grey, non-interlaced PNGs only")
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    bpp, stride, rows, prev = 2, w * 2, [], bytearray(w * 2)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], (prev[i - bpp] if i >= bpp else 0)
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(list(struct.unpack(f">{w}H", bytes(line))))
        prev = line
    return w, h, rows


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
